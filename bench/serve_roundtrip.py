#!/usr/bin/env python3
"""Morph round trip of `bodymodel serve` driven through its HTTP API (standard library only).

Usage: bench/serve_roundtrip.py MODEL.npz [--exe build/bodymodel] [--port 18790] [--changes 10]
Starts the server on loopback, moves each of height_cm and weight_kg through --changes slider
positions (as the page does while dragging: "quick", then released: full), and prints the
median, p90 and max round trip (request sent -> positions and measured labels parsed), and the
ratio to a plain decode of the mean body measured in the same server (the baseline).
Drawing the body in the browser is not included (tens of ms in WebGL)."""
import argparse, http.client, json, os, signal, statistics, subprocess, sys, time

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
        return (time.perf_counter() - t0) * 1000

    post({})  # warm-up
    base = statistics.median(post({}) for _ in range(5))
    for quick in (True, False):
        times = []
        for name in [n for n in ('height_cm', 'weight_kg') if n in labels]:
            l = labels[name]
            for k in range(a.changes):
                v = l['min'] + (l['max'] - l['min']) * (k + 0.5) / a.changes
                times.append(post({'labels': {name: v}, 'quick': quick}))
        times.sort()
        med = statistics.median(times)
        print(f"{'quick (dragging)' if quick else 'full (released)'}: {len(times)} slider changes, round trip median "
              f"{med:.0f} ms, p90 {times[int(0.9 * len(times))]:.0f} ms, max {times[-1]:.0f} ms; "
              f"{med / base:.2f}x the mean-body decode ({base:.0f} ms)")
finally:
    server.send_signal(signal.SIGTERM)
    server.wait(timeout=30)
