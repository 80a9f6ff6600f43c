"""Model.fit and Model.morph refuse a body in the wrong unit as `bodymodel fit` does (issue 40): a
model built in a second from bent cylinders of a body's size, in metres (build --scale 1000)."""
import numpy as np
import pytest

import bodymodel
from conftest import cli_error_line


def cylinder(radius, height, bend, segments=12, stacks=10):
    """A closed cylinder along +y (mm), its top bent about z: V (n, 3), F (m, 3) int32."""
    ring = [(radius * np.cos(2 * np.pi * s / segments), height * k / stacks, radius * np.sin(2 * np.pi * s / segments))
            for k in range(stacks + 1) for s in range(segments)]
    V = np.array(ring + [(0, 0, 0), (0, height, 0)], float)
    idx = lambda k, s: k * segments + s % segments
    F = []
    for k in range(stacks):
        for s in range(segments):
            F += [(idx(k, s), idx(k + 1, s), idx(k, s + 1)), (idx(k, s + 1), idx(k + 1, s), idx(k + 1, s + 1))]
    bottom, top = len(V) - 2, len(V) - 1
    for s in range(segments):
        F += [(bottom, idx(0, s), idx(0, s + 1)), (top, idx(stacks, s + 1), idx(stacks, s))]
    w = np.clip((V[:, 1] - 0.5 * height) / (0.2 * height), 0, 1) * bend
    up = V[:, 1] > 0.5 * height
    x, y = V[:, 0].copy(), V[:, 1] - 0.5 * height
    V[up, 0] = (x * np.cos(w) - y * np.sin(w))[up]
    V[up, 1] = (x * np.sin(w) + y * np.cos(w))[up] + 0.5 * height
    return V, np.array(F, dtype=np.int32)


@pytest.fixture(scope="module")
def metres_model(tmp_path_factory, cli):
    d = tmp_path_factory.mktemp("units")
    (d / "reg").mkdir()
    rows = ["mesh,subject,pose"]
    for s in range(4):
        for p in range(2):
            V, F = cylinder(100 + 12 * s, 1500 + 60 * (s % 3), 0.25 * p - 0.1 * (s % 2))
            bodymodel.write_mesh(str(d / "reg" / f"c{s}_{p}.ply"), V / 1000.0, F)
            rows.append(f"c{s}_{p},s{s},p{p}")
    (d / "subjects.csv").write_text("\n".join(rows) + "\n")
    cli(f"build {d / 'reg'} --subjects {d / 'subjects.csv'} --standard-pose p0 --scale 1000 --full-variance 1 "
        f"--out {d / 'm.npz'}")
    return d


def test_fit_refuses_a_body_in_the_wrong_unit_as_the_cli(metres_model, cli):
    d = metres_model
    model = bodymodel.Model.load(str(d / "m.npz"))
    V, F = cylinder(118, 1560, 0.1)
    bodymodel.write_mesh(str(d / "mm.ply"), V, F)
    # Millimetres against a model built from metres: the model's --scale 1000 makes it 1.5 km.
    msg = cli_error_line(cli(f"fit {d / 'm.npz'} --in {d / 'mm.ply'} --out {d / 'x.ply'}", check=False))
    with pytest.raises(bodymodel.InputError) as e:
        model.fit(V)
    assert "mm tall" in str(e.value) and "use --scale 1 " in str(e.value)
    assert str(e.value).replace("V:", "", 1) == msg.replace(f"'{d / 'mm.ply'}':", "", 1)
    with pytest.raises(bodymodel.InputError, match="one point"):
        model.fit(np.zeros_like(V), scale=1)
    # The same body in metres, as the model expects, passes the check (and fits).
    Vf, s = model.fit(V / 1000.0, iterations=2)
    assert Vf.shape == V.shape
    # morph and predict_labels take mm: metres are refused.
    with pytest.raises(bodymodel.InputError, match="must be in millimetres"):
        model.morph(V / 1000.0, height_cm=160)
    with pytest.raises(bodymodel.InputError, match="must be in millimetres"):
        model.predict_labels(V / 1000.0)
