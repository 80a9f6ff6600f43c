"""register_scan against `bodymodel register --scan ID` on one scan of a small synthetic database
(a simulated scan of a MakeHuman body with noisy landmarks; needs MakeHuman's data)."""
import json

import numpy as np
import pytest

import bodymodel


@pytest.fixture(scope="module")
def db(tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("reg") / "db"
    cli(f"synth-db --subjects 1 --poses-per-subject 0 --seed 2 --min-points 20000 --out {d}")
    return d


def scan_of(db):
    sid = (db / "scans.csv").read_text().splitlines()[1].split(",")[0]
    P, N = bodymodel.read_point_cloud(str(db / "scans" / f"{sid}.ply"))
    lm = json.loads((db / "scans" / f"{sid}.landmarks.json").read_text())
    return sid, P, N, lm


# Few non-rigid steps and no shape fit: the test compares the binding with the verb, it does not
# measure registration quality (docs/registration.md does).
FLAGS = "--fast-steps 8 --no-shape-fit --hand-stage off"
KW = dict(fast_steps=8, shape_fit=False, hand_stage=False)


@pytest.mark.slow  # 16 s: a registration by the CLI and one by the binding
def test_register_scan_matches_the_cli(db, tmp_path, cli):
    sid, P, N, lm = scan_of(db)
    cli(f"register {db} --scan {sid} {FLAGS} --out {tmp_path / 'reg'}")
    seen = []
    V, s = bodymodel.register_scan(P, N, landmarks=lm, progress=lambda f, w: seen.append(f), **KW)
    bodymodel.write_mesh(str(tmp_path / "py.ply"), V, s["faces"])
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "reg" / f"{sid}.ply").read_bytes()
    head, row = (tmp_path / "reg" / "registration.csv").read_text().splitlines()[:2]
    csv = dict(zip(head.split(","), row.split(",")))
    assert int(csv["points"]) == s["points"] == len(P) and int(csv["landmarks"]) == s["landmarks"] == len(lm)
    assert int(csv["nonrigid_iterations"]) == s["nonrigid_iterations"] == 8
    # Local folds left as the verb counts them; no untangling without repair_local_folds.
    assert int(csv["local_folds"]) == s["local_folds"] and float(csv["untangle_max_mm"]) == s["untangle_max_mm"] == 0
    for k in ("pose_rms_mm", "data_rms_mm", "landmark_rms_mm", "scale"):
        assert float(csv[k]) == pytest.approx(s[k], abs=1e-4 if k != "scale" else 1e-6), k
    # A registration, not just agreement: the template is on the scan (the synthetic scan's noise
    # is ~1 mm; 8 steps leave a few mm) and its landmarks near their targets.
    assert s["data_rms_mm"] < 10 and s["landmark_rms_mm"] < 20
    assert V.shape == (13380, 3) and s["faces"].shape[1] == 3 and len(s["bone_rotations"]) == len(s["bone_names"])
    assert seen and max(seen) <= 1.0


def test_register_scan_bad_input(db):
    _, P, N, lm = scan_of(db)
    with pytest.raises(bodymodel.InputError, match="landmarks: unknown landmark name 'nose_bridge'"):
        bodymodel.register_scan(P, N, landmarks={"nose_bridge": [0, 0, 0]}, **KW)
    bad = P.copy()
    bad[3, 2] = np.nan
    with pytest.raises(bodymodel.InputError, match="points: NaN at row 3"):
        bodymodel.register_scan(bad, N, landmarks=lm, **KW)
    with pytest.raises(bodymodel.InputError, match="normals: 5 rows"):
        bodymodel.register_scan(P, N[:5], landmarks=lm, **KW)
    with pytest.raises(bodymodel.InputError, match="--fast-steps must be at least 1"):
        bodymodel.register_scan(P, N, landmarks=lm, fast_steps=0)
    with pytest.raises(bodymodel.Cancelled):
        bodymodel.register_scan(P, N, landmarks=lm, progress=lambda f, w: False, **KW)


def test_register_scan_shape_space_file_is_checked(db, tmp_path):
    _, P, N, lm = scan_of(db)
    bad = tmp_path / "space.json"
    bad.write_text('{"format": "something-else"}')
    with pytest.raises(bodymodel.InputError, match="space.json: not a shape-space file"):
        bodymodel.register_scan(P, N, landmarks=lm, shape_space=str(bad), **KW)


def test_register_scan_template(db):
    _, P, N, lm = scan_of(db)
    # The default sliders are the verb's template: the same pose fit; a tall male start is another.
    V0, s0 = bodymodel.register_scan(P, N, landmarks=lm, pose_only=True, **KW)
    V1, s1 = bodymodel.register_scan(P, N, landmarks=lm, template={"gender": 0.5}, pose_only=True, **KW)
    assert np.array_equal(V0, V1) and np.array_equal(s0["rest_template"], s1["rest_template"])
    V2, s2 = bodymodel.register_scan(P, N, landmarks=lm, template={"gender": 1.0, "height": 0.9}, pose_only=True, **KW)
    assert np.abs(s2["rest_template"] - s0["rest_template"]).max() > 10
    with pytest.raises(bodymodel.InputError, match="hight"):
        bodymodel.register_scan(P, N, landmarks=lm, template={"hight": 0.5}, **KW)
