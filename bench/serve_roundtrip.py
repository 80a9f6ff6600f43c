#!/usr/bin/env python3
"""Morph round trip of `bodymodel serve` driven through its HTTP API (standard library only).

Usage: bench/serve_roundtrip.py MODEL.npz [--exe build/bodymodel] [--port 18790] [--changes 10]
Starts the server on loopback, waits for its drag preview, then moves each of height_cm and
weight_kg through --changes slider positions and times the round trip (request sent ->
positions and measured labels parsed) of three kinds of request:
  preview   "quick": what the page sends while a slider is dragged (the first-order preview);
  decode    "quick", "preview": false: the same change decoded exactly (one decode);
  full      what the page sends when the slider is released (measured corrections).
Prints median, p90 and max of each, the ratio to a plain decode of the mean body measured in the
same server (the baseline), where the server's time went (its "timing" answer), and how far the
preview lies from the exact one-decode body (largest vertex distance, mm and % of body height).
Drawing the body in the browser is not included (a few ms in WebGL)."""
import argparse, array, base64, http.client, json, math, os, signal, statistics, subprocess, sys, time

ap = argparse.ArgumentParser()
ap.add_argument('model')
ap.add_argument('--exe', default=os.path.join(os.path.dirname(__file__), '..', 'build', 'bodymodel'))
ap.add_argument('--port', type=int, default=18790)
ap.add_argument('--changes', type=int, default=10)
a = ap.parse_args()
server = subprocess.Popen([a.exe, 'serve', a.model, '--port', str(a.port)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
try:
    for _ in range(600):
        try:
            c = http.client.HTTPConnection('127.0.0.1', a.port, timeout=120)
            c.request('GET', '/api/model')
            labels = {l['name']: l for l in json.loads(c.getresponse().read())['labels']}
            break
        except OSError:
            time.sleep(0.1)
    else:
        sys.exit('server did not start')

    def post(body):
        t0 = time.perf_counter()
        c.request('POST', '/api/body', json.dumps(body), {'Content-Type': 'application/json'})
        r = c.getresponse()
        j = json.loads(r.read())
        if r.status != 200:
            sys.exit(f'{body}: {r.status} {j}')
        return (time.perf_counter() - t0) * 1000, j

    t0 = time.time()
    while not post({'quick': True})[1]['preview']:  # the preview is built after start-up
        if time.time() - t0 > 600:
            sys.exit('the preview was not ready after 600 s')
        time.sleep(0.5)
    print(f'preview ready {time.time() - t0:.0f} s after the server answered')
    base = statistics.median(post({})[0] for _ in range(5))
    names = [n for n in ('height_cm', 'weight_kg') if n in labels]
    requests = [{name: labels[name]['min'] + (labels[name]['max'] - labels[name]['min']) * (k + 0.5) / a.changes}
                for name in names for k in range(a.changes)]
    kinds = {'preview (dragging)': {'quick': True}, 'decode (dragging, --no-preview)': {'quick': True, 'preview': False},
             'full (released)': {}}
    results = {k: [] for k in kinds}
    for req in requests:  # interleaved, so load changes hit every kind alike
        for kind, extra in kinds.items():
            results[kind].append(post({'labels': req, **extra}))
    for kind, rows in results.items():
        times = sorted(ms for ms, _ in rows)
        med = statistics.median(times)
        tm = {k: statistics.median(j['timing'][k] for _, j in rows) for k in rows[0][1]['timing']}
        print(f"{kind}: {len(times)} slider changes, round trip median {med:.1f} ms, p90 {times[int(0.9 * len(times))]:.1f} ms, "
              f"max {times[-1]:.1f} ms; {med / base:.2f}x the mean-body decode ({base:.0f} ms)\n"
              f"    server medians: morph {tm['morph_ms']:.1f} ms ({tm['decodes']:.0f} decodes; last decode "
              f"{tm['last_decode_ms']:.1f} ms: rotation solve {tm['rotation_solve_ms']:.1f}, assemble {tm['assemble_ms']:.1f}, "
              f"orthonormalise {tm['orthonormalise_ms']:.1f}, poisson {tm['poisson_ms']:.1f}), measure {tm['measure_ms']:.1f} ms")

    def floats(j):
        return array.array('f', base64.b64decode(j['positions']))
    dev = []
    for (_, p), (_, d) in zip(results['preview (dragging)'], results['decode (dragging, --no-preview)']):
        P, D = floats(p), floats(d)
        worst = max(math.dist(P[i:i + 3], D[i:i + 3]) for i in range(0, len(P), 3))
        ys = D[1::3]
        dev.append((worst, 100 * worst / (max(ys) - min(ys))))
    dev.sort()
    print(f"preview vs exact decode, largest vertex distance: median {statistics.median(d[0] for d in dev):.2f} mm "
          f"({statistics.median(d[1] for d in dev):.2f} % of the height), max {dev[-1][0]:.2f} mm ({dev[-1][1]:.2f} %)")
finally:
    server.send_signal(signal.SIGTERM)
    server.wait(timeout=60)
