#!/usr/bin/env python3
"""Correspondence error on the contact regions of FAUST-like meshes (docs/real-registration.md#contacts).

usage: contact_errors.py TRUTH_DIR EVAL_DIR [EVAL_DIR ...] [--near 20] [--far 100]

A truth vertex of a mesh is in a contact region when another vertex of the same mesh lies within
--near mm of it (Euclidean) but more than --far mm away along the surface (Dijkstra over the truth
mesh's edges): two limbs, or a limb and the torso, touching. EVAL_DIR is an `eval-correspondence
--vertex-errors` output (vertices.csv: mean error per truth vertex and mesh, cm). Prints per mesh
the contact vertices, their mean error and the mean elsewhere, for every EVAL_DIR side by side.
Plain Python (no numpy): a spatial hash for the near pairs, a bounded Dijkstra for the far test.
Truth meshes are read in metres (FAUST) and converted to mm.
"""
import csv, heapq, math, os, sys
from collections import defaultdict


def read_off(path):
    with open(path) as f:
        tokens = f.read().split()
    assert tokens[0] == "OFF", path
    nv, nf = int(tokens[1]), int(tokens[2])
    v = [tuple(1000.0 * float(t) for t in tokens[4 + 3 * i:7 + 3 * i]) for i in range(nv)]
    k = 4 + 3 * nv
    faces = []
    for _ in range(nf):
        n = int(tokens[k])
        faces.append([int(t) for t in tokens[k + 1:k + 1 + n]])
        k += 1 + n
    return v, faces


def contact_vertices(v, faces, near, far):
    adj = defaultdict(dict)
    for f in faces:
        for a, b in zip(f, f[1:] + f[:1]):
            d = math.dist(v[a], v[b])
            adj[a][b] = d
            adj[b][a] = d
    cell = defaultdict(list)
    key = lambda p: tuple(int(math.floor(c / near)) for c in p)
    for i, p in enumerate(v):
        cell[key(p)].append(i)
    out = set()
    for i, p in enumerate(v):
        if i in out:
            continue
        kx, ky, kz = key(p)
        cand = [j for dx in (-1, 0, 1) for dy in (-1, 0, 1) for dz in (-1, 0, 1)
                for j in cell.get((kx + dx, ky + dy, kz + dz), ()) if j != i and math.dist(p, v[j]) < near]
        if not cand:
            continue
        # Bounded Dijkstra from i: candidates not reached within `far` are across a contact.
        dist = {i: 0.0}
        heap = [(0.0, i)]
        while heap:
            d, u = heapq.heappop(heap)
            if d > dist.get(u, math.inf) or d > far:
                continue
            for w, l in adj[u].items():
                nd = d + l
                if nd <= far and nd < dist.get(w, math.inf):
                    dist[w] = nd
                    heapq.heappush(heap, (nd, w))
        for j in cand:
            if j not in dist:
                out.add(i)
                out.add(j)
    return out


def main(argv):
    near, far = 20.0, 100.0
    args = []
    it = iter(argv)
    for a in it:
        if a == "--near":
            near = float(next(it))
        elif a == "--far":
            far = float(next(it))
        else:
            args.append(a)
    if len(args) < 2:
        sys.exit(__doc__)
    truth_dir, evals = args[0], args[1:]
    tables = []
    for e in evals:
        with open(os.path.join(e, "vertices.csv")) as f:
            r = csv.reader(f)
            header = next(r)
            cols = list(zip(*[[float(x) for x in row[1:]] for row in r]))
        tables.append(dict(zip(header[1:], cols)))
    meshes = list(tables[0].keys())
    print("mesh,contact_vertices," + ",".join(
        f"contact_cm[{os.path.basename(e.rstrip('/'))}],elsewhere_cm[{os.path.basename(e.rstrip('/'))}]" for e in evals))
    pooled = [[0.0, 0, 0.0, 0] for _ in evals]
    for m in meshes:
        v, faces = read_off(os.path.join(truth_dir, m + ".off"))
        c = contact_vertices(v, faces, near, far)
        row = [m, str(len(c))]
        for k, t in enumerate(tables):
            err = t[m]
            ce = [err[i] for i in c]
            oe = [err[i] for i in range(len(err)) if i not in c]
            pooled[k][0] += sum(ce); pooled[k][1] += len(ce)
            pooled[k][2] += sum(oe); pooled[k][3] += len(oe)
            row += [f"{sum(ce) / len(ce):.3f}" if ce else "", f"{sum(oe) / len(oe):.3f}"]
        print(",".join(row), flush=True)
    row = ["all", str(pooled[0][1])]
    for p in pooled:
        row += [f"{p[0] / p[1]:.3f}" if p[1] else "", f"{p[2] / p[3]:.3f}"]
    print(",".join(row))


if __name__ == "__main__":
    main(sys.argv[1:])
