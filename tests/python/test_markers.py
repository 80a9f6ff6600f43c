"""Marker captures from Python (issue 38): C3D/TRC write → read, clean_markers as `bodymodel
markers clean` does it, and the one-line refusals."""
import json

import numpy as np
import pytest

import bodymodel
from conftest import cli_error_line


def rigid_capture(frames=60, rows=5, cols=6):
    """A curved sheet of markers 60 mm apart turning about y (mm): labels, truth (frames, markers, 3)."""
    u, v = np.meshgrid(np.arange(cols) * 60.0, np.arange(rows) * 60.0)
    ref = np.stack([u.ravel(), v.ravel() + 1000, 0.002 * (u.ravel() - 150) ** 2], axis=1)
    truth = np.empty((frames, len(ref), 3))
    for f in range(frames):
        a = 0.01 * f
        R = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        truth[f] = ref @ R.T + [2.0 * f, 0, 0]
    return [f"M{i}" for i in range(len(ref))], truth


def broken(labels, truth):
    """M5 missing from frame 20; its samples from frame 30 on are the unlabelled piece '*1'."""
    xyz = np.concatenate([truth, np.full((truth.shape[0], 1, 3), np.nan)], axis=1)
    xyz[30:, -1] = truth[30:, 5]
    xyz[20:, 5] = np.nan
    return labels + ["*1"], xyz


@pytest.mark.parametrize("ext", ["c3d", "trc"])
def test_write_then_read_is_exact(tmp_path, ext):
    labels, truth = rigid_capture()
    labels, xyz = broken(labels, truth)
    path = str(tmp_path / f"capture.{ext}")
    bodymodel.write_markers(path, labels, xyz, rate=120, first_frame=5)
    d = bodymodel.read_markers(path)
    assert d["labels"] == labels and d["rate"] == 120 and d["first_frame"] == 5
    assert d["xyz"].shape == xyz.shape
    assert np.array_equal(np.isnan(d["xyz"]), np.isnan(xyz))
    tol = 1e-4 if ext == "c3d" else 0  # C3D stores 32-bit floats
    np.testing.assert_allclose(d["xyz"][~np.isnan(xyz)], xyz[~np.isnan(xyz)], rtol=tol, atol=0)


def test_clean_merges_fills_and_matches_the_cli(tmp_path, cli):
    labels, truth = rigid_capture()
    blabels, xyz = broken(labels, truth)
    cleaned, report = bodymodel.clean_markers(blabels, xyz, rate=120, truth={"labels": labels, "xyz": truth})
    assert cleaned["labels"] == labels
    assert np.isfinite(cleaned["xyz"]).all()
    assert report["merged"] == 1 and report["gaps_left"] == 0
    assert report["evaluation"]["wrong_merges"] == 0
    # A rigid motion: the filled hole follows the truth closely (the smoothing moves samples a little).
    assert np.abs(cleaned["xyz"][20:30, 5] - truth[20:30, 5]).max() < 2.0
    # The CLI on the same capture writes the same trajectories.
    bodymodel.write_markers(str(tmp_path / "capture.trc"), blabels, xyz, rate=120)
    cli(f"markers clean {tmp_path / 'capture.trc'} --out {tmp_path / 'clean.trc'}")
    np.testing.assert_allclose(bodymodel.read_markers(str(tmp_path / "clean.trc"))["xyz"], cleaned["xyz"], atol=1e-9)
    cli_report = json.loads((tmp_path / "clean.json").read_text())
    assert cli_report["merged"] == report["merged"] and cli_report["gaps_filled"] == report["gaps_filled"]


def test_refusals_are_one_line(tmp_path, cli):
    labels, truth = rigid_capture()
    with pytest.raises(bodymodel.InputError, match=r"xyz: expected a \(frames, 30, 3\) array"):
        bodymodel.write_markers(str(tmp_path / "x.trc"), labels, truth[:, :10])
    bad = truth.copy()
    bad[3, 2, 1] = np.nan  # one coordinate of three
    with pytest.raises(bodymodel.InputError, match="frame 4 marker 'M2'"):
        bodymodel.clean_markers(labels, bad)
    (tmp_path / "cut.c3d").write_bytes(b"\x02\x50" + b"\x00" * 100)
    with pytest.raises(bodymodel.InputError) as e:
        bodymodel.read_markers(str(tmp_path / "cut.c3d"))
    assert "\n" not in str(e.value)
    assert str(e.value) == cli_error_line(cli(f"markers clean {tmp_path / 'cut.c3d'} --out {tmp_path / 'o.trc'}", check=False))


@pytest.mark.filterwarnings("ignore:Casting complex values")
def test_hostile_arrays_raise_input_or_type_errors():
    labels, truth = rigid_capture(frames=12)
    rng = np.random.default_rng(1)
    cases = [truth[:0], truth[:, :0], truth[..., :2], truth[0], truth.astype(np.complex128), truth.astype(object),
             truth.astype(np.float32), truth.astype(np.int64), np.full_like(truth, np.nan), np.full_like(truth, np.inf),
             truth * 1e300, [[1.0, "a"], [2.0]], None, "x"]
    for xyz in cases:
        for call in (lambda: bodymodel.clean_markers(labels, xyz),
                     lambda: bodymodel.clean_markers(labels[:3], xyz),
                     lambda: bodymodel.clean_markers(labels, xyz, reference_frame=int(rng.integers(-3, 30))),
                     lambda: bodymodel.write_markers("/nonexistent/dir/x.trc", labels, xyz)):
            try:
                call()
            except (bodymodel.InputError, bodymodel.NumericalError, TypeError, OSError):
                pass
