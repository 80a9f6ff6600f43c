"""Skinning fits, rigs and metrics; regressors and cross-validation."""
import numpy as np
import pytest

import bodymodel


def cylinder(rings=12, segments=10, length=200.0, radius=20.0):
    """An open tube along +y (mm): V (n, 3), F (m, 3)."""
    V = [(radius * np.cos(2 * np.pi * s / segments), length * r / (rings - 1), radius * np.sin(2 * np.pi * s / segments))
         for r in range(rings) for s in range(segments)]
    F = []
    for r in range(rings - 1):
        for s in range(segments):
            a, b = r * segments + s, r * segments + (s + 1) % segments
            F += [(a, b + segments, b), (a, a + segments, b + segments)]
    return np.array(V), np.array(F, dtype=np.int32)


def rot_z(angle, centre):
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    return np.hstack([R, (centre - R @ centre)[:, None]])


def two_bone_examples(count=6):
    """A tube bent at its middle by two bones; poses made by LBS with smooth true weights."""
    V, F = cylinder()
    w1 = np.clip((V[:, 1] - 70) / 60, 0, 1)           # weight of bone 1 (the upper half)
    W = np.stack([1 - w1, w1], axis=1)
    transforms, poses = [], []
    for p in range(count):
        M0 = rot_z(0.05 * p, np.zeros(3))
        M1 = rot_z(0.05 * p + 0.25 * (p + 1), np.array([0.0, 100.0, 0.0]))
        T = np.stack([M0, M1])
        Vh = np.hstack([V, np.ones((len(V), 1))])
        P = W[:, 0:1] * (Vh @ T[0].T) + W[:, 1:2] * (Vh @ T[1].T)
        transforms.append(T)
        poses.append(P)
    return V, F, np.array(transforms), np.array(poses), W


def write_examples(tmp_path, V, F, transforms, poses):
    bodymodel.write_mesh(str(tmp_path / "rest.ply"), V, F)
    (tmp_path / "poses").mkdir()
    (tmp_path / "T").mkdir()
    for p, (T, P) in enumerate(zip(transforms, poses)):
        bodymodel.write_mesh(str(tmp_path / "poses" / f"p{p:02d}.ply"), P, F)
        # libigl .Tmat: per bone the rows of R^T, then t^T.
        rows = np.concatenate([np.vstack([M[:, :3].T, M[:, 3]]) for M in T])
        np.savetxt(tmp_path / "T" / f"p{p:02d}.Tmat", rows, fmt="%.17g")
    rest, _ = bodymodel.read_mesh(str(tmp_path / "rest.ply"))
    read = [bodymodel.read_mesh(str(f))[0] for f in sorted((tmp_path / "poses").glob("*.ply"))]
    return rest, np.array(read)


@pytest.mark.parametrize("method", ["ssd", "as", "mwe"])
def test_fit_rig_matches_skin_fit(tmp_path, cli, method):
    V, F, T, P, _ = two_bone_examples()
    rest, poses = write_examples(tmp_path, V, F, T, P)
    rig, summary = bodymodel.fit_rig(rest, poses, T, method)
    assert rig.method == method and rig.bone_count == 2
    cli(f"skin fit --rest {tmp_path / 'rest.ply'} --poses {tmp_path / 'poses'} --transforms {tmp_path / 'T'} "
        f"--method {method} --cv none --out {tmp_path / 'rig.npz'}")
    ref = bodymodel.Rig.load(str(tmp_path / "rig.npz"))
    assert np.array_equal(ref.influences, rig.influences)
    assert np.abs(ref.coefficients - rig.coefficients).max() <= 1e-9
    z = np.load(tmp_path / "rig.npz")
    assert np.abs(z["coefficients"] - rig.coefficients).max() <= 1e-9
    # The poses were made by LBS: every method reproduces its training poses closely.
    for Tp, Pp in zip(T, poses):
        assert np.abs(rig.deform(Tp) - Pp).max() < 0.05   # mm; the inputs are float32 PLY


def test_ssd_deform_is_linear_blend_skinning_and_metrics(tmp_path):
    V, F, T, P, W = two_bone_examples()
    rig, _ = bodymodel.fit_rig(V, P, T, "ssd")
    # An unseen pose: deform agrees with LBS computed in numpy from the rig's own weights.
    M = np.stack([rot_z(-0.2, np.zeros(3)), rot_z(0.9, np.array([0.0, 100.0, 0.0]))])
    Wd = np.zeros((len(V), 2))
    for k in range(rig.influences.shape[1]):
        ok = rig.influences[:, k] >= 0
        Wd[ok, rig.influences[ok, k]] += rig.coefficients[ok, k]
    Vh = np.hstack([V, np.ones((len(V), 1))])
    expected = Wd[:, 0:1] * (Vh @ M[0].T) + Wd[:, 1:2] * (Vh @ M[1].T)
    X = rig.deform(M)
    assert np.abs(X - expected).max() <= 1e-9
    # The true weights are recovered (the examples are exact LBS).
    assert np.abs(Wd - W).max() < 1e-3
    truth = W[:, 0:1] * (Vh @ M[0].T) + W[:, 1:2] * (Vh @ M[1].T)
    d = bodymodel.mesh_deviation(X, truth, F)
    assert d["vertex"].shape == (len(V),)
    assert np.allclose(d["vertex"], np.linalg.norm(X - truth, axis=1), atol=1e-12)
    assert np.all(d["geometric"] <= d["vertex"] + 1e-9)
    e = bodymodel.e_rms([X], [truth])
    diag = np.linalg.norm(np.ptp(truth, axis=0))
    assert abs(e - 1000 * np.linalg.norm(X - truth) / (np.sqrt(3 * len(V)) * diag)) <= 1e-12
    # bone maps of the wrong shape or count, NaN
    with pytest.raises(bodymodel.InputError, match=r"expected \(B, 3, 4\) or \(B, 4, 4\)"):
        rig.deform(np.zeros((2, 3, 3)))
    with pytest.raises(bodymodel.InputError, match="3 bones, the rig has 2"):
        rig.deform(np.zeros((3, 3, 4)))
    bad = M.copy()
    bad[1, 0, 3] = np.nan
    with pytest.raises(bodymodel.InputError, match="NaN"):
        rig.deform(bad)
    # save / load round trip
    rig.save(str(tmp_path / "r.npz"), F)
    back = bodymodel.Rig.load(str(tmp_path / "r.npz"))
    assert np.array_equal(back.deform(M), X) and np.array_equal(back.faces, F)


def test_fit_progress_and_cancel():
    V, F, T, P, _ = two_bone_examples()
    seen = []
    bodymodel.fit_rig(V, P, T, "as", progress=lambda f, what: seen.append(f))
    assert seen and all(0 <= f <= 1 for f in seen)
    with pytest.raises(bodymodel.Cancelled):
        bodymodel.fit_rig(V, P, T, "mwe", progress=lambda f, what: False)
    with pytest.raises(ZeroDivisionError):   # an exception in the callback reaches the caller
        bodymodel.fit_rig(V, P, T, "mwe", progress=lambda f, what: 1 / 0)
    with pytest.raises(bodymodel.InputError, match="poses\\[0\\]: 8 vertices"):
        bodymodel.fit_rig(V, [P[0][:8]] * len(T), T, "ssd")


def test_regressors_and_cross_validation():
    rng = np.random.default_rng(3)
    X = rng.normal(size=(60, 4))
    beta = np.array([2.0, -1.0, 0.5, 0.0])
    y = X @ beta + 7.0
    r = bodymodel.Regressor("simple_linear")
    r.fit(X, y)
    assert np.abs(r.predict(X) - y).max() < 1e-8
    assert np.abs(r.gradient(X[0]) - beta).max() < 1e-8
    cv = bodymodel.cross_validate("simple_linear", X, y, folds=5, seed=2)
    assert cv["folds"] == 5 and cv["samples"] == 60 and cv["rmse"] < 1e-8
    # With noise, the held-out predictions are those of a fit on the other folds: recompute them.
    yn = y + rng.normal(scale=0.5, size=60)
    yn[7] = np.nan
    cv = bodymodel.cross_validate("simple_linear", X, yn, folds=5, seed=2)
    assert cv["skipped_missing"] == 1 and 7 not in cv["rows"]
    assert abs(cv["rmse"] - np.sqrt(np.mean((cv["predictions"] - yn[cv["rows"]]) ** 2))) < 1e-12
    assert 0.3 < cv["rmse"] < 0.8
    again = bodymodel.cross_validate("simple_linear", X, yn, folds=5, seed=2)
    assert np.array_equal(again["predictions"], cv["predictions"])
    with pytest.raises(bodymodel.InputError, match="svm|known"):
        bodymodel.Regressor("svm")
    with pytest.raises(bodymodel.InputError, match="call fit"):
        bodymodel.Regressor("svr").predict(X)
    with pytest.raises(bodymodel.InputError):
        r.fit(X, y[:10])
