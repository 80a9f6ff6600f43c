// Drives the viewer (bodymodel viewer OUT) in headless Chromium over the DevTools protocol
// (--remote-debugging-pipe: no npm package needed) and checks what it draws.
// Usage: node viewer_browser.js VIEWER_DIR SCREENSHOT.png [CHROMIUM]
// Exit 0: every check passed; 1: a check failed (reasons printed); 2: cannot run (reason printed).
'use strict';
const { spawn } = require('child_process');
const fs = require('fs');
const os = require('os');
const path = require('path');

const [dir, shot, chromium = '/usr/bin/chromium'] = process.argv.slice(2);
if (!fs.existsSync(chromium)) { console.log(`skip: ${chromium} not found`); process.exit(2); }
const profile = fs.mkdtempSync(path.join(os.tmpdir(), 'bodymodel-chromium-'));
// SwiftShader: WebGL2 in software, the same on every machine (no GPU in CI).
const proc = spawn(chromium, ['--headless=new', '--remote-debugging-pipe', '--no-sandbox', '--no-first-run',
  '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist',
  '--allow-file-access-from-files', `--user-data-dir=${profile}`, '--window-size=800,700', 'about:blank'],
  { stdio: ['ignore', 'ignore', 'pipe', 'pipe', 'pipe'] });
let stderr = '';
proc.stderr.on('data', (d) => { stderr += d; });
const timer = setTimeout(() => finish(1, ['timed out after 60 s']), 60000);
function finish(code, lines) {
  clearTimeout(timer);
  for (const l of lines) console.log(l);
  try { proc.kill('SIGKILL'); } catch (e) { /* gone */ }
  try { fs.rmSync(profile, { recursive: true, force: true }); } catch (e) { /* best effort */ }
  process.exit(code);
}
proc.on('error', (e) => finish(2, [`skip: cannot start ${chromium}: ${e.message}`]));

let nextId = 1, buf = '';
const pending = new Map();
const events = [];
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
    } else if (msg.method) events.push(msg);
  }
});
function send(method, params = {}, sessionId) {
  const id = nextId++;
  proc.stdio[3].write(JSON.stringify({ id, method, params, sessionId }) + '\0');
  return new Promise((resolve, reject) => pending.set(id, { resolve, reject }));
}
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function main() {
  const check = JSON.parse(fs.readFileSync(path.join(dir, 'check.json'), 'utf8'));
  const { targetId } = await send('Target.createTarget', { url: 'about:blank' });
  const { sessionId } = await send('Target.attachToTarget', { targetId, flatten: true });
  const S = (m, p) => send(m, p, sessionId);
  await S('Runtime.enable');
  await S('Page.enable');
  await S('Emulation.setDeviceMetricsOverride', { width: 800, height: 700, deviceScaleFactor: 1, mobile: false });
  await S('Page.navigate', { url: 'file://' + path.resolve(dir, 'index.html') });
  const evaluate = async (expression) => {
    const r = await S('Runtime.evaluate', { expression, returnByValue: true, awaitPromise: true });
    if (r.exceptionDetails) throw new Error(`${expression}: ${JSON.stringify(r.exceptionDetails).slice(0, 600)}`);
    return r.result.value;
  };
  const t0 = Date.now();
  let ready = false;
  while (Date.now() - t0 < 20000) {
    ready = await evaluate('!!(window.viewerState && window.viewerState.ready && window.viewerState.framesDrawn > 2)').catch(() => false);
    if (ready) break;
    await sleep(100);
  }
  const errors = events.filter((e) => e.method === 'Runtime.exceptionThrown' ||
    (e.method === 'Runtime.consoleAPICalled' && e.params.type === 'error'));
  if (!ready) return [1, ['viewer not ready after 20 s', ...errors.map((e) => JSON.stringify(e.params).slice(0, 400)),
                          stderr.split('\n').filter((l) => /webgl|gl|error/i.test(l)).slice(0, 10).join('\n')]];
  const fails = [], lines = [];
  if (errors.length) fails.push('page errors: ' + errors.map((e) => JSON.stringify(e.params).slice(0, 300)).join(' | '));

  // 1. The animation advances by itself.
  const a = await evaluate('[viewerState.frame, viewerState.framesDrawn]');
  await sleep(600);
  const b = await evaluate('[viewerState.frame, viewerState.framesDrawn]');
  lines.push(`animation: frame ${a[0]} -> ${b[0]}, ${b[1] - a[1]} draws in 0.6 s`);
  if (b[1] <= a[1]) fails.push('no frames drawn in 0.6 s');
  if (b[0] === a[0]) fails.push('the clip frame did not advance in 0.6 s');

  // 2. The body where the C++ evaluator puts it: project its positions with the page's camera.
  const f0 = check.frames[0];
  const cam = await evaluate(`viewerApi.freeze(${f0})`);
  const px = Buffer.from(await evaluate('viewerApi.pixels()'), 'base64');
  const W = cam.width, H = cam.height;
  const body = (x, y) => { const i = 4 * (y * W + x); return px[i] < 245 || px[i + 1] < 245 || px[i + 2] < 245; };
  let bodyPixels = 0, x0 = W, x1 = -1, y0 = H, y1 = -1;
  for (let y = 0; y < H; ++y) for (let x = 0; x < W; ++x) if (body(x, y)) {
    ++bodyPixels; x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
  }
  const P = check.rigs[0].positions[0], m = cam.vp;
  let onBody = 0, n = P.length / 3, px0 = W, px1 = -1, py0 = H, py1 = -1;
  for (let v = 0; v < n; ++v) {
    const X = P[3 * v], Y = P[3 * v + 1], Z = P[3 * v + 2];
    const w = m[3] * X + m[7] * Y + m[11] * Z + m[15];
    const sx = ((m[0] * X + m[4] * Y + m[8] * Z + m[12]) / w * 0.5 + 0.5) * W;
    const sy = ((m[1] * X + m[5] * Y + m[9] * Z + m[13]) / w * 0.5 + 0.5) * H;
    const ix = Math.floor(sx), iy = Math.floor(sy);
    px0 = Math.min(px0, sx); px1 = Math.max(px1, sx); py0 = Math.min(py0, sy); py1 = Math.max(py1, sy);
    let hit = false;
    for (let dy = -1; dy <= 1 && !hit; ++dy) for (let dx = -1; dx <= 1 && !hit; ++dx) {
      const qx = ix + dx, qy = iy + dy;
      hit = qx >= 0 && qy >= 0 && qx < W && qy < H && body(qx, qy);
    }
    onBody += hit;
  }
  const cover = bodyPixels / (W * H), hitFrac = onBody / n;
  const boxErr = Math.max(Math.abs(x0 - px0), Math.abs(x1 - px1), Math.abs(y0 - py0), Math.abs(y1 - py1));
  lines.push(`silhouette: ${bodyPixels} body pixels (${(100 * cover).toFixed(1)} % of ${W}x${H}), ` +
             `${(100 * hitFrac).toFixed(2)} % of the C++ vertices land on them, bounding boxes differ by ${boxErr.toFixed(1)} px`);
  if (cover < 0.02 || cover > 0.8) fails.push(`body covers ${(100 * cover).toFixed(1)} % of the canvas (expected 2-80 %)`);
  if (hitFrac < 0.99) fails.push(`only ${(100 * hitFrac).toFixed(2)} % of the projected C++ vertices fall on drawn pixels`);
  if (boxErr > 3) fails.push(`drawn and projected bounding boxes differ by ${boxErr.toFixed(1)} px (> 3)`);
  const s = await S('Page.captureScreenshot', { format: 'png' });
  fs.writeFileSync(shot, Buffer.from(s.data, 'base64'));
  lines.push(`screenshot: ${shot}`);

  // 3. Drawn frames differ (the pose moves the pixels).
  await evaluate(`viewerApi.freeze(${check.frames[check.frames.length - 1]})`);
  const px2 = Buffer.from(await evaluate('viewerApi.pixels()'), 'base64');
  let changed = 0;
  for (let i = 0; i < px.length; i += 4) changed += px[i] !== px2[i] || px[i + 1] !== px2[i + 1] || px[i + 2] !== px2[i + 2];
  lines.push(`frames ${f0} and ${check.frames[check.frames.length - 1]}: ${changed} pixels differ`);
  if (changed < 50) fails.push('two clip frames draw the same picture');

  // 4. The shader's positions (transform feedback) against the C++ evaluator.
  const tol = 1e-4 * check.height;
  for (let ri = 0; ri < check.rigs.length; ++ri) {
    let worst = 0;
    for (let fi = 0; fi < check.frames.length; ++fi) {
      const g = await evaluate(`viewerApi.readback(${ri}, ${check.frames[fi]})`);
      const c = check.rigs[ri].positions[fi];
      if (g.length !== c.length) { fails.push(`${check.rigs[ri].name}: ${g.length / 3} vertices read back, ${c.length / 3} expected`); continue; }
      for (let v = 0; v < c.length; v += 3)
        worst = Math.max(worst, Math.hypot(g[v] - c[v], g[v + 1] - c[v + 1], g[v + 2] - c[v + 2]));
    }
    lines.push(`shader vs C++ ${check.rigs[ri].name}: largest vertex distance over frames ${check.frames.join(',')} = ` +
               `${worst.toExponential(3)} (${(worst / check.height).toExponential(3)} of the body height; bound 1e-4)`);
    if (!(worst <= tol)) fails.push(`${check.rigs[ri].name}: shader positions differ from C++ by ${worst} > ${tol}`);
  }
  // 5. Error colours: a mesh given with --error-mesh is drawn with the colour map (blue where it
  // matches its reference, red where it is ≥ the scale away) and the legend shows; the rig
  // without its error map is drawn in unsaturated grey.
  const hues = (buf) => {
    let n = 0, blue = 0, red = 0, saturated = 0;
    for (let i = 0; i < buf.length; i += 4) {
      const r = buf[i], g = buf[i + 1], b2 = buf[i + 2];
      if (r >= 245 && g >= 245 && b2 >= 245) continue;
      ++n;
      const mx = Math.max(r, g, b2), mn = Math.min(r, g, b2);
      if (mx > 0 && (mx - mn) / mx > 0.3) ++saturated;
      if (b2 > r + 60 && b2 >= g) ++blue;
      if (r > g + 60 && r > b2 + 60) ++red;
    }
    return { n, blue, red, saturated };
  };
  const grey = hues(px);
  lines.push(`rig without error map: ${grey.saturated} of ${grey.n} body pixels saturated`);
  if (grey.saturated > 0.01 * grey.n) fails.push('the rig without its error map is drawn in colour');
  const meshes = await evaluate('viewerApi.meshes()');
  const ei = meshes.findIndex((x) => x.errors);
  if (ei < 0) fails.push('no mesh with errors in the viewer data');
  else {
    const legend = await evaluate(`viewerApi.show(${ei})`);
    const shown = await evaluate("getComputedStyle(document.getElementById('legend')).display");
    const h = hues(Buffer.from(await evaluate('viewerApi.pixels()'), 'base64'));
    lines.push(`error mesh '${meshes[ei].name}': ${h.n} body pixels, ${(100 * h.blue / h.n).toFixed(1)} % blue, ` +
               `${(100 * h.red / h.n).toFixed(1)} % red; legend ${shown}`);
    if (!legend || shown === 'none') fails.push('the legend is not shown with the error mesh');
    if (h.n < 1000) fails.push('the error mesh is not drawn');
    if (h.blue < 0.05 * h.n || h.red < 0.05 * h.n) fails.push('the error colours (blue to red) do not both appear');
  }
  return [fails.length ? 1 : 0, [...lines, ...fails.map((f) => 'FAIL: ' + f)]];
}
main().then(([code, lines]) => finish(code, lines), (e) => finish(1, ['FAIL: ' + e.stack]));
