"""Meshes, measurements and the encoding: each binding against its CLI verb and round trips."""
import json
import threading

import numpy as np
import pytest

import bodymodel
from conftest import bend, cli_error_line, icosphere


def test_mesh_round_trip_obj_ply(tmp_path, sphere):
    V, F = sphere
    for name in ("s.ply", "s.obj"):
        bodymodel.write_mesh(str(tmp_path / name), V, F)
        V2, F2 = bodymodel.read_mesh(str(tmp_path / name))
        assert V2.dtype == np.float64 and V2.shape == V.shape
        assert F2.dtype == np.int32 and np.array_equal(F2, F)
        # PLY stores float32, OBJ 9 significant digits: both round-trip to float32 precision.
        assert np.abs(V2 - V).max() <= 1e-7 * np.abs(V).max()


def test_read_off(tmp_path, sphere):
    V, F = sphere
    lines = ["OFF", f"{len(V)} {len(F)} 0"] + [" ".join(repr(float(x)) for x in v) for v in V]
    lines += [f"3 {a} {b} {c}" for a, b, c in F]
    (tmp_path / "s.off").write_text("\n".join(lines) + "\n")
    V2, F2 = bodymodel.read_mesh(str(tmp_path / "s.off"))
    assert np.array_equal(V2, V) and np.array_equal(F2, F)


def test_errors_carry_the_cli_message(tmp_path, cli):
    bad = tmp_path / "bad.obj"
    bad.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n")
    with pytest.raises(bodymodel.InputError) as e:
        bodymodel.read_mesh(str(bad))
    assert str(e.value) == cli_error_line(cli(f"measure {bad}", check=False))
    assert isinstance(e.value, ValueError)
    with pytest.raises(bodymodel.InputError, match="cannot read .*missing.ply.*no such file"):
        bodymodel.read_mesh(str(tmp_path / "missing.ply"))


def test_bad_arrays_raise_clearly(sphere):
    V, F = sphere
    with pytest.raises(bodymodel.InputError, match=r"V: expected an \(n, 3\) array of positions, got shape \(.*, 2\)"):
        bodymodel.measure(V[:, :2], F)
    Vn = V.copy()
    Vn[5, 1] = np.nan
    with pytest.raises(bodymodel.InputError, match="V: NaN at row 5, column 1"):
        bodymodel.measure(Vn, F)
    with pytest.raises(bodymodel.InputError, match="integer vertex indices, got dtype float64"):
        bodymodel.measure(V, F.astype(float))
    with pytest.raises(bodymodel.InputError, match="vertex index"):
        bodymodel.measure(V, F + len(V))
    with pytest.raises(bodymodel.InputError, match="expected a numeric array"):
        bodymodel.measure("not an array", F)
    # Other dtypes and layouts convert exactly: int64 faces, float32 / Fortran-ordered vertices, lists.
    ref = bodymodel.measure(V, F)
    assert bodymodel.measure(np.asfortranarray(V), F.astype(np.int64))["volume_l"] == ref["volume_l"]
    assert bodymodel.measure(V.tolist(), F.tolist())["volume_l"] == ref["volume_l"]
    V32 = V.astype(np.float32)
    assert bodymodel.measure(V32, F)["volume_l"] == bodymodel.measure(V32.astype(np.float64), F)["volume_l"]


def test_measure_matches_cli_and_the_sphere(tmp_path, sphere, cli):
    V, F = sphere
    m = bodymodel.measure(V, F)
    # The icosphere's volume is a little below the ball's (4/3 π r³ with r = 100 mm).
    assert 0.9 * 4 / 3 * np.pi < m["volume_l"] < 4 / 3 * np.pi
    assert abs(m["height_cm"] - 20.0) < 1e-9
    path = tmp_path / "s.ply"
    bodymodel.write_mesh(str(path), V, F)
    Vf, Ff = bodymodel.read_mesh(str(path))
    j = json.loads(cli(f"measure {path} --json").stdout)
    mf = bodymodel.measure(Vf, Ff)
    for k in ("height_cm", "volume_l", "weight_kg", "neck_cm", "chest_cm", "waist_cm", "hips_cm"):
        assert abs(mf[k] - j[k]) <= 1e-9 * max(1.0, abs(j[k])), k


def test_measure_nhanes_columns_match_the_cli(tmp_path, sphere, cli):
    V, F = bodymodel.makehuman_body()
    path = tmp_path / "body.ply"
    bodymodel.write_mesh(str(path), V, F)
    Vf, Ff = bodymodel.read_mesh(str(path))
    j = json.loads(cli(f"measure {path} --standard nhanes --json").stdout)
    m = bodymodel.measure(Vf, Ff, standard="nhanes")
    assert sorted(m) == sorted(j) and "BMXWAIST" in m
    for k in j:
        assert abs(m[k] - j[k]) <= 1e-9 * max(1.0, abs(j[k])), k
    with pytest.raises(bodymodel.InputError, match="template's topology"):
        bodymodel.measure(*sphere, standard="nhanes")


def test_decode_of_encode_round_trip(sphere):
    V, F = sphere
    X = bend(V)
    e = bodymodel.encode(X, F, V)
    assert e.shape == (15 * len(F),)
    Y = bodymodel.decode(e, F, V)
    # Decoded meshes are aligned to the template: compare after the rigid fit of X onto Y.
    diag = np.linalg.norm(np.ptp(X, axis=0))
    Xc, Yc = X - X.mean(0), Y - Y.mean(0)
    U, _, Wt = np.linalg.svd(Xc.T @ Yc)
    D = np.diag([1, 1, np.sign(np.linalg.det(U @ Wt))])
    assert np.abs(Xc @ (U @ D @ Wt) - Yc).max() <= 1e-6 * diag


def test_encode_decode_match_the_cli(tmp_path, sphere, cli):
    V, F = sphere
    bodymodel.write_mesh(str(tmp_path / "rest.ply"), V, F)
    bodymodel.write_mesh(str(tmp_path / "bent.ply"), bend(V), F)
    cli(f"encode {tmp_path / 'rest.ply'} {tmp_path / 'bent.ply'} --out {tmp_path / 'e.npz'}")
    z = np.load(tmp_path / "e.npz")
    rest, Fr = bodymodel.read_mesh(str(tmp_path / "rest.ply"))
    bent, _ = bodymodel.read_mesh(str(tmp_path / "bent.ply"))
    dec = bodymodel.Decoder(rest, Fr)
    for row, X in zip(z["encodings"], (rest, bent)):
        assert np.abs(dec.encode(X, mean=z["mean"]) - row).max() <= 1e-9
    cli(f"decode {tmp_path / 'e.npz'} --out {tmp_path / 'dec'} --format ply")
    out = [tmp_path / "dec" / "rest.ply", tmp_path / "dec" / "bent.ply"]   # named after the inputs
    for row, f in zip(z["encodings"], out):
        Y = dec.decode(row, mean=z["mean"])
        # Same decode, written the same way: byte-identical files.
        bodymodel.write_mesh(str(tmp_path / "py.ply"), Y, Fr)
        assert (tmp_path / "py.ply").read_bytes() == f.read_bytes()


def test_decoder_concurrent_calls_match_sequential(sphere):
    V, F = sphere
    dec = bodymodel.Decoder(V, F)
    e = [dec.encode(bend(V, a)) for a in (0.2, 0.5, 0.9, 1.2)]
    blends = [0.5 * (e[i] + e[(i + 1) % 4]) for i in range(4)]   # not realisable: a real solve
    ref = [dec.decode(b) for b in blends]
    got = [None] * 4
    threads = [threading.Thread(target=lambda i=i: got.__setitem__(i, dec.decode(blends[i]))) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for a, b in zip(ref, got):
        assert np.array_equal(a, b)


def test_decoder_rejects_bad_encodings(sphere):
    V, F = sphere
    dec = bodymodel.Decoder(V, F)
    with pytest.raises(bodymodel.InputError, match="encoding: 10 values, the template needs"):
        dec.decode(np.zeros(10))
    e = dec.encode(V)
    e[7] = np.inf
    with pytest.raises(bodymodel.InputError, match="encoding: infinity at row 7"):
        dec.decode(e)
    with pytest.raises(bodymodel.InputError, match="unknown option 'tolerance'"):
        bodymodel.Decoder(V, F, tolerance=1)


def test_makehuman_body_and_measure_match_the_cli(tmp_path, cli):
    V, F = bodymodel.makehuman_body(gender=1.0, height=0.6)
    assert V.shape == (13380, 3) and F.shape == (26756, 3)
    cli(f"makehuman-body --gender 1 --height 0.6 --out {tmp_path / 'b.ply'}")
    bodymodel.write_mesh(str(tmp_path / "py.ply"), V, F)
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()
    j = json.loads(cli(f"measure {tmp_path / 'b.ply'} --sex male --json").stdout)
    Vf, Ff = bodymodel.read_mesh(str(tmp_path / "b.ply"))
    m = bodymodel.measure(Vf, Ff, sex="male")
    for k, v in j.items():
        if k in m:
            assert abs(m[k] - v) <= 1e-9 * max(1.0, abs(v)), k
    assert 150 < m["height_cm"] < 210
    with pytest.raises(bodymodel.InputError, match="gender"):
        bodymodel.makehuman_body(gender=1.5)


def test_measure_ansur2_columns_match_the_cli(tmp_path, sphere, cli):
    V, F = bodymodel.makehuman_body(gender=1.0)
    path = tmp_path / "body.ply"
    bodymodel.write_mesh(str(path), V, F)
    Vf, Ff = bodymodel.read_mesh(str(path))
    j = json.loads(cli(f"measure {path} --standard ansur2 --json").stdout)
    m = bodymodel.measure(Vf, Ff, standard="ansur2")
    assert list(m) == list(j) and len(m) == 23 and "chestcircumference" in m and "span" in m
    for k in j:
        assert abs(m[k] - j[k]) <= 1e-9 * max(1.0, abs(j[k])), k
    assert 1600 < m["stature"] < 1900 and 40 < m["weightkg"] < 120  # mm and kg
    with pytest.raises(bodymodel.InputError, match="template's topology"):
        bodymodel.measure(*sphere, standard="ansur2")
    ball = tmp_path / "ball.ply"
    bodymodel.write_mesh(str(ball), *sphere)
    r = cli(f"measure {ball} --standard ansur2", check=False)
    assert r.returncode == 2 and r.stdout == ""
    assert "ball.ply" in cli_error_line(r) and "template's topology" in cli_error_line(r)
