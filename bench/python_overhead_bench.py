#!/usr/bin/env python3
"""Overhead of the Python module over the C++ it calls, as ratios measured in one process.

    PYTHONPATH=build/python python3 bench/python_overhead_bench.py [--rig char/rig.npz] [--model model.npz]

deform: Rig.deform(M) called from Python (numpy in, numpy out) against Rig.time_native(M), the
same evaluate_rig called in C++ (no conversions), frames alternated so load hits both alike.
Without --rig, an MWE rig is fitted to a MakeHuman body posed by 8 bones (13 380 vertices). The
demo character's rig (MWE, MakeHuman's 163 bones) is the one `bodymodel demo` writes to
OUT/character/rig.npz; its stages alone:

    bodymodel synth-db --subjects 24 --poses-per-subject 2 --seed 1 --out db
    bodymodel build db/truth --db db --out model.npz
    bodymodel character model.npz --where sex=male --where height_cm=185 --seed 3 --out character
    PYTHONPATH=build/python python3 bench/python_overhead_bench.py --rig character/rig.npz --model model.npz
morph: wall time of Model.morph from Python against the C++ morph's own clock (MorphSummary
seconds, measured inside ShapeMorpher::morph_encoding, so the ratio is the cost of the arguments,
the GIL and the returned arrays); needs --model.
"""
import argparse
import time

import numpy as np

import bodymodel


def rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def makehuman_mwe_rig(bones=8, poses=12, seed=1):
    """MWE rig fitted to a MakeHuman body posed by LBS with `bones` height bands (smooth weights)."""
    V, F = bodymodel.makehuman_body()
    y = (V[:, 1] - V[:, 1].min()) / np.ptp(V[:, 1])
    centres = (np.arange(bones) + 0.5) / bones
    W = np.exp(-((y[:, None] - centres[None, :]) * bones) ** 2)
    W /= W.sum(1, keepdims=True)
    rng = np.random.default_rng(seed)
    Ts, Ps = [], []
    Vh = np.hstack([V, np.ones((len(V), 1))])
    for _ in range(poses):
        T = []
        for b in range(bones):
            R = rot(rng.normal(size=3), rng.uniform(0, 0.4))
            c = V.mean(0) + [0, (centres[b] - 0.5) * np.ptp(V[:, 1]), 0]
            T.append(np.hstack([R, (c - R @ c)[:, None]]))
        T = np.array(T)
        Ts.append(T)
        Ps.append(np.einsum("vb,bvj->vj", W, np.einsum("bij,vj->bvi", T, Vh)))
    rig, _ = bodymodel.fit_rig(V, np.array(Ps), np.array(Ts), "mwe", max_influences=4)
    return rig, Ts[0]


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--rig", help="rig .npz (e.g. the demo character's rig)")
    p.add_argument("--model", help="model .npz for the morph ratio")
    p.add_argument("--rounds", type=int, default=15)
    a = p.parse_args()
    if a.rig:
        rig = bodymodel.Rig.load(a.rig)
        rng = np.random.default_rng(2)
        M = np.array([np.hstack([rot(rng.normal(size=3), 0.2), rng.normal(size=(3, 1))]) for _ in range(rig.bone_count)])
    else:
        rig, M = makehuman_mwe_rig()
    # One frame each in turn: evaluate_rig runs on TBB, so on a shared machine a frame takes one or
    # two cores' time depending on the other processes; alternating frame by frame exposes both
    # sides to the same load. The minimum is the frame least disturbed by them.
    py, cc = [], []
    for _ in range(a.rounds * 10):
        t0 = time.perf_counter()
        rig.deform(M)
        py.append(time.perf_counter() - t0)
        cc.append(rig.time_native(M, 1))
    py_ms, cc_ms = 1e3 * np.median(py), 1e3 * np.median(cc)
    print(f"deform ({rig.method}, {len(rig.rest)} vertices, {rig.bone_count} bones, {len(py)} frames each): "
          f"median python {py_ms:.3f} ms, C++ {cc_ms:.3f} ms per frame, ratio {py_ms / cc_ms:.3f}; "
          f"minimum {1e3 * min(py):.3f} / {1e3 * min(cc):.3f} ms, ratio {min(py) / min(cc):.3f}")
    if a.model:
        model = bodymodel.Model.load(a.model)
        V0, _ = model.morph(None, height_cm="keep")
        h = bodymodel.measure(V0, model.faces)["height_cm"]
        ratios = []
        for k in range(max(3, a.rounds // 3)):
            t0 = time.perf_counter()
            # From the mean body (V=None: morph_encoding, whose own clock covers all its work).
            _, s = model.morph(None, height_cm=h + 3 + k % 3, weight_kg="keep")
            ratios.append((time.perf_counter() - t0) / s["seconds"])
        print(f"morph (height +3..5 cm, keep weight): python / C++ wall median ratio {np.median(ratios):.4f}")


if __name__ == "__main__":
    main()
