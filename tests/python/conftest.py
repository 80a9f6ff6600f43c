"""Shared fixtures of the Python binding tests: the CLI they are compared with and small inputs.

Run through CTest (tests/CMakeLists.txt sets PYTHONPATH to the build's python folder and
BODYMODEL_EXE to the tool). Tests marked `slow` (a model built or a scan registered with the CLI) carry the CTest
label long; the rest are fast.
"""
import os
import shlex
import subprocess
from pathlib import Path

import numpy as np
import pytest

import bodymodel


def pytest_configure(config):
    config.addinivalue_line("markers", "slow: builds a model or registers a scan with the CLI (CTest label long)")


@pytest.fixture(scope="session")
def exe():
    path = os.environ.get("BODYMODEL_EXE")
    if not path:
        here = Path(bodymodel.__file__).resolve().parent.parent / "bodymodel"
        path = str(here)
    assert Path(path).is_file(), f"bodymodel executable not found at {path} (set BODYMODEL_EXE)"
    return path


@pytest.fixture(scope="session")
def cli(exe):
    """cli("verb args...") -> CompletedProcess (never raises; tests check returncode)."""

    def run(args, check=True):
        r = subprocess.run([exe] + shlex.split(args), capture_output=True, text=True)
        if check and r.returncode != 0:
            raise AssertionError(f"bodymodel {args} failed ({r.returncode}):\n{r.stderr}")
        return r

    return run


def cli_error_line(result):
    """The CLI's one error line, without its 'bodymodel: error: ' prefix."""
    lines = [l for l in result.stderr.splitlines() if l.startswith("bodymodel: error: ")]
    assert result.returncode != 0 and len(lines) == 1, result.stderr
    return lines[0][len("bodymodel: error: "):]


def icosphere(subdivisions=2, radius=100.0):
    """A closed, outward-oriented triangle sphere (mm): V (n, 3) float64, F (m, 3) int32."""
    t = (1 + 5 ** 0.5) / 2
    V = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    F = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5), (2, 4, 11),
         (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    V = [np.array(v, float) / np.linalg.norm(v) for v in V]
    for _ in range(subdivisions):
        cache, F2 = {}, []

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                m = V[a] + V[b]
                V.append(m / np.linalg.norm(m))
                cache[key] = len(V) - 1
            return cache[key]

        for a, b, c in F:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            F2 += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        F = F2
    return np.array(V) * radius, np.array(F, dtype=np.int32)


def bend(V, angle=0.8):
    """A smooth non-rigid deformation of V (bends about the z axis by height), then a rotation."""
    y = V[:, 1] / np.ptp(V[:, 1])
    a = angle * y
    X = V.copy()
    X[:, 0] = V[:, 0] * np.cos(a) - V[:, 1] * np.sin(a)
    X[:, 1] = V[:, 0] * np.sin(a) + V[:, 1] * np.cos(a)
    X[:, 2] *= 1.0 + 0.2 * y
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return X @ R.T + np.array([10.0, -5.0, 3.0])


@pytest.fixture(scope="session")
def sphere():
    return icosphere()


@pytest.fixture(scope="session")
def model_path(tmp_path_factory, cli):
    """A small model built with the CLI from a synthetic database (6 subjects, standard pose)."""
    d = tmp_path_factory.mktemp("model")
    cli(f"synth-db --subjects 6 --poses-per-subject 0 --seed 1 --out {d / 'db'}")
    cli(f"build {d / 'db' / 'truth'} --db {d / 'db'} --out {d / 'model.npz'}")
    return d / "model.npz"
