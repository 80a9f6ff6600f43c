#!/usr/bin/env python3
"""Notebook-style example: a model from a synthetic database, one body morphed through a height
sweep at constant weight, and a plot of requested against measured height.

    python3 examples/height_sweep.py --out sweep/              # builds DB and model with the CLI
    python3 examples/height_sweep.py --model model.npz --out sweep/

Writes sweep/height_sweep.png, sweep/height_sweep.csv (target, measured height and weight) and
one mesh per step. Needs the bodymodel module (scripts/setup.sh) and python3-matplotlib.
"""
import argparse
import os
import subprocess
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files, no display
import matplotlib.pyplot as plt
import numpy as np

import bodymodel

p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
p.add_argument("--model", help="an existing model .npz (default: build one with the CLI)")
p.add_argument("--out", default="height_sweep", help="output folder")
p.add_argument("--steps", type=int, default=5)
p.add_argument("--exe", default=os.environ.get("BODYMODEL_EXE", "bodymodel"), help="the bodymodel tool")
a = p.parse_args()
out = Path(a.out)
out.mkdir(parents=True, exist_ok=True)

# 1. A model: 6 synthetic subjects in the standard pose -> `bodymodel build`.
model_path = a.model
if model_path is None:
    subprocess.run([a.exe, "synth-db", "--subjects", "6", "--poses-per-subject", "0", "--out", str(out / "db")], check=True)
    model_path = str(out / "model.npz")
    subprocess.run([a.exe, "build", str(out / "db" / "truth"), "--db", str(out / "db"), "--out", model_path], check=True)
model = bodymodel.Model.load(model_path)
print("labels:", ", ".join(model.label_names))

# 2. The model's mean body, then a height sweep holding the weight.
V0, _ = model.morph(None, height_cm="keep")   # the mean body as it measures
m0 = bodymodel.measure(V0, model.faces)
targets = np.linspace(m0["height_cm"] - 8, m0["height_cm"] + 8, a.steps)
rows = []
for t in targets:
    V, summary = model.morph(V0, height_cm=float(t), weight_kg="keep")
    m = bodymodel.measure(V, model.faces)
    rows.append((t, m["height_cm"], m["weight_kg"]))
    bodymodel.write_mesh(str(out / f"height_{t:.1f}.obj"), V, model.faces)
rows = np.array(rows)
np.savetxt(out / "height_sweep.csv", rows, delimiter=",", header="target_cm,height_cm,weight_kg", comments="", fmt="%.4f")

# 3. The plot: requested vs measured height, and the weight that was held.
fig, ax = plt.subplots(1, 2, figsize=(8, 3.2))
ax[0].plot(rows[:, 0], rows[:, 1], "o-", label="measured")
ax[0].plot(rows[:, 0], rows[:, 0], "k:", label="requested")
ax[0].set(xlabel="requested height (cm)", ylabel="height (cm)")
ax[0].legend()
ax[1].plot(rows[:, 0], rows[:, 2], "o-")
ax[1].set(xlabel="requested height (cm)", ylabel="weight (kg)", ylim=(m0["weight_kg"] - 3, m0["weight_kg"] + 3))
fig.tight_layout()
fig.savefig(out / "height_sweep.png", dpi=100)
print(f"wrote {out / 'height_sweep.png'} and {out / 'height_sweep.csv'}")
