// Slider change -> new mesh drawn, in headless Chromium on `bodymodel serve`'s own page.
// Usage: node bench/serve_browser_roundtrip.js MODEL.npz [EXE=build/bodymodel] [PORT=18796] [CHROMIUM=/usr/bin/chromium]
// Starts the server, opens its page (WebGL in SwiftShader, as the browser test), waits for the drag
// preview, then moves the height and weight sliders through 10 positions each as a drag does
// ('input' events: the page's quick requests) and, separately, as releases ('change': the full
// morph), timing from the event to the frame drawn with the new body (the first draw after
// the body arrived (the page draws on demand), then a pixel read, which waits for the GPU). Prints medians and p90, and the
// plain API round trip of the same requests from the page (fetch + parse) for comparison.
'use strict';
const { spawn } = require('child_process');
const fs = require('fs');
const os = require('os');
const path = require('path');

const [model, exe = path.join(__dirname, '..', 'build', 'bodymodel'), port = '18796', chromium = '/usr/bin/chromium'] =
  process.argv.slice(2);
if (!model) { console.log('usage: node serve_browser_roundtrip.js MODEL.npz [EXE] [PORT] [CHROMIUM]'); process.exit(2); }
const server = spawn(exe, ['serve', model, '--port', port], { stdio: 'ignore' });
const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'bodymodel-chromium-'));
const proc = spawn(chromium, ['--headless=new', '--remote-debugging-pipe', '--no-sandbox', '--no-first-run',
  '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
  '--no-proxy-server', `--user-data-dir=${profile}`, '--window-size=1000,700', 'about:blank'], { stdio: ['ignore', 'ignore', 'pipe', 'pipe', 'pipe'] });
const timer = setTimeout(() => finish(1, ['timed out after 600 s']), 600000);
function finish(code, lines) {
  clearTimeout(timer);
  for (const l of lines) console.log(l);
  try { proc.kill('SIGKILL'); } catch (e) { /* gone */ }
  try { server.kill('SIGTERM'); } catch (e) { /* gone */ }
  try { fs.rmSync(profile, { recursive: true, force: true }); } catch (e) { /* best effort */ }
  process.exit(code);
}
let nextId = 1, buf = '';
const pending = new Map();
proc.stdio[4].on('data', (d) => {
  buf += d.toString('utf8');
  let i;
  while ((i = buf.indexOf('\0')) >= 0) {
    const msg = JSON.parse(buf.slice(0, i));
    buf = buf.slice(i + 1);
    if (msg.id && pending.has(msg.id)) {
      const { resolve, reject } = pending.get(msg.id);
      pending.delete(msg.id);
      if (msg.error) reject(new Error(JSON.stringify(msg.error))); else resolve(msg.result);
    }
  }
});
function send(method, params = {}, sessionId) {
  const id = nextId++;
  proc.stdio[3].write(JSON.stringify({ id, method, params, sessionId }) + '\0');
  return new Promise((resolve, reject) => pending.set(id, { resolve, reject }));
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const median = (a) => { const s = [...a].sort((x, y) => x - y); return s[Math.floor(s.length / 2)]; };
const p90 = (a) => { const s = [...a].sort((x, y) => x - y); return s[Math.floor(0.9 * s.length)]; };

async function main() {
  const { targetId } = await send('Target.createTarget', { url: 'about:blank' });
  const { sessionId } = await send('Target.attachToTarget', { targetId, flatten: true });
  const S = (m, p) => send(m, p, sessionId);
  await S('Runtime.enable');
  // A page the browser considers hidden gets its timers and tasks throttled: make it the focused,
  // visible one.
  await S('Page.enable');
  await S('Page.bringToFront');
  await S('Emulation.setFocusEmulationEnabled', { enabled: true });
  const evaluate = async (expression) => {
    const r = await S('Runtime.evaluate', { expression, returnByValue: true, awaitPromise: true });
    if (r.exceptionDetails) throw new Error(`${expression.slice(0, 80)}: ${JSON.stringify(r.exceptionDetails).slice(0, 400)}`);
    return r.result.value;
  };
  const t0 = Date.now();
  const http = require('http');
  const up = () => new Promise((resolve) => http.get(`http://127.0.0.1:${port}/api/model`, (r) => { r.resume(); resolve(r.statusCode === 200); })
    .on('error', () => resolve(false)));
  while (!(await up())) {  // the server loads the model first
    if (Date.now() - t0 > 300000) return [1, ['the server did not answer in 300 s']];
    await sleep(200);
  }
  await S('Page.navigate', { url: `http://127.0.0.1:${port}/` });
  let ready = false;
  while (!ready && Date.now() - t0 < 400000) {
    await sleep(200);
    ready = await evaluate('!!(window.serveState && window.serveState.bodies > 0)').catch(() => false);
  }
  if (!ready) return [1, ['the page did not draw a body: ' +
    JSON.stringify(await evaluate("[document.getElementById('status') && document.getElementById('status').textContent, typeof THREE]").catch((e) => String(e)))]];
  // The preview is built in the background after start-up.
  while (!(await evaluate(`fetch('api/body', { method: 'POST', body: '{"quick": true}' }).then((r) => r.json()).then((j) => j.preview)`))) {
    if (Date.now() - t0 > 580000) return [1, ['the preview was not ready']];
    await sleep(500);
  }
  // One slider event, then wait for the body it asked for to be drawn.
  const step = (name, value, event) => evaluate(`(async () => {
    const s = document.getElementById('label-${name}'), before = serveState.bodies, t0 = performance.now();
    s.value = ${value}; s.dispatchEvent(new Event('${event}'));
    while (serveState.drawnBodies <= before) {  // until drawn with the new body
      if (performance.now() - t0 > 60000) throw new Error("no new body drawn in 60 s");
      await new Promise((r) => setTimeout(r, 1));
    }
    const gl = document.getElementById('view').getContext('webgl2'); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
    return performance.now() - t0;
  })()`);
  const api = (body) => evaluate(`(async () => { const t0 = performance.now();
    const j = await (await fetch('api/body', { method: 'POST', body: ${JSON.stringify(JSON.stringify(body))} })).json();
    const e = performance.getEntriesByType('resource').filter((x) => x.name.endsWith('api/body')).pop();
    return [performance.now() - t0, j.preview, e.requestStart - e.startTime, e.responseStart - e.requestStart,
            e.responseEnd - e.responseStart]; })()`);
  const labels = await evaluate(`fetch('api/model').then((r) => r.json()).then((m) => m.labels)`);
  const res = { drag: [], release: [], apiQuick: [], frame: [], queue: [], wait: [], download: [] };
  for (let i = 0; i < 5; ++i)  // one frame of the body: render + a pixel read (waits for the GPU)
    res.frame.push(await evaluate(`(() => { const t0 = performance.now(); draw();
      const gl = document.getElementById('view').getContext('webgl2'); gl.readPixels(0, 0, 1, 1, gl.RGBA, gl.UNSIGNED_BYTE, new Uint8Array(4));
      return performance.now() - t0; })()`));
  for (const name of ['height_cm', 'weight_kg']) {
    const l = labels.find((x) => x.name === name);
    if (!l) continue;
    for (let k = 0; k < 10; ++k) {
      const v = l.min + (l.max - l.min) * (k + 0.5) / 10;
      res.drag.push(await step(name, v, 'input'));
      const a = await api({ labels: { [name]: v }, quick: true });
      res.apiQuick.push(a[0]); res.queue.push(a[2]); res.wait.push(a[3]); res.download.push(a[4]);
      res.release.push(await step(name, v, 'change'));
    }
  }
  const f = (a) => `median ${median(a).toFixed(1)} ms, p90 ${p90(a).toFixed(1)} ms (${a.length})`;
  return [0, [`slider dragged -> new mesh drawn: ${f(res.drag)}`, `slider released -> exact mesh drawn: ${f(res.release)}`,
              `the drag's API request alone (fetch + JSON in the page): ${f(res.apiQuick)}; of which (resource timing) ` +
              `before sending ${median(res.queue).toFixed(1)} ms, waiting for the answer ${median(res.wait).toFixed(1)} ms, ` +
              `receiving it ${median(res.download).toFixed(1)} ms`,
              `one frame drawn (WebGL in SwiftShader, software; ${await evaluate("innerWidth + 'x' + innerHeight")}): ${f(res.frame)}`]];
}
main().then(([code, lines]) => finish(code, lines), (e) => finish(1, ['FAIL: ' + e.stack]));
