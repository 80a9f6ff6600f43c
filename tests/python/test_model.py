"""The body model: arrays, morph and generate against `bodymodel morph` / `generate` (slow: the
model is built with the CLI from a synthetic database)."""
import json

import numpy as np
import pytest

import bodymodel
from conftest import cli_error_line

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def model(model_path):
    return bodymodel.Model.load(str(model_path))


def test_arrays_match_the_file(model, model_path):
    z = np.load(model_path)
    assert model.label_names == json.loads(str(z["label_names"]))
    assert np.array_equal(model.faces, z["template_faces"])
    assert np.array_equal(model.template_vertices, z["template_vertices"])
    assert np.array_equal(model.components, z["shape_basis"].astype(np.float64))
    assert np.array_equal(model.eigenvalues, z["shape_eigenvalues"])
    assert np.array_equal(model.label_gradients, z["shape_label_gradients"])
    assert np.array_equal(model.labels, z["labels"], equal_nan=True)
    # The file's own recipe (model/model_file.h): offsets + c @ gradients predict a subject's labels.
    h = model.label_names.index("height_cm")
    c = model.coefficients[0]
    V = model.decode(model.shape_mean + model.components @ c)
    assert abs(model.predict_labels(V)[h] - (model.label_offsets[h] + c @ model.label_gradients[:, h])) < 0.05


def test_morph_matches_the_cli(model, model_path, tmp_path, cli):
    body = tmp_path / "body.ply"
    V0 = model.decode(model.shape_mean + model.components @ model.coefficients[1])
    bodymodel.write_mesh(str(body), V0, model.faces)
    Vb, _ = bodymodel.read_mesh(str(body))
    height = bodymodel.measure(Vb, model.faces)["height_cm"]
    cli(f"morph {model_path} --in {body} --set height_cm={height + 5:.3f} --keep weight_kg --out {tmp_path / 'cli.ply'}")
    V, s = model.morph(Vb, height_cm=float(f"{height + 5:.3f}"), weight_kg="keep")
    bodymodel.write_mesh(str(tmp_path / "py.ply"), V, model.faces)
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
    got = {l["label"]: l for l in s["labels"]}
    assert abs(got["height_cm"]["achieved"] - (height + 5)) <= 0.25
    assert abs(bodymodel.measure(V, model.faces)["height_cm"] - (height + 5)) <= 0.25
    with pytest.raises(bodymodel.InputError) as e:
        model.morph(Vb, hight_cm=180)
    assert "hight_cm" in str(e.value) and str(e.value) == \
        cli_error_line(cli(f"morph {model_path} --in {body} --set hight_cm=180 --out {tmp_path / 'x.ply'}", check=False))
    with pytest.raises(bodymodel.InputError, match="vertices|vertex"):
        model.morph(Vb[:100], height_cm=170)


def test_morph_matches_the_cli_where_the_fold_repair_acts(model, model_path, tmp_path, cli):
    # Extreme targets fold a few tiny triangles of the decoded body; the CLI and Python both
    # repair them (model/morph.h morph_body), so the bodies stay byte-identical.
    tried = []
    for label, value in [("weight_kg", 160), ("weight_kg", 35), ("height_cm", 205), ("height_cm", 140)]:
        V, s = model.morph(None, closest=True, **{label: value})
        tried.append((label, value, s["folds_repaired"]))
        if s["folds_repaired"] == 0:
            continue
        cli(f"morph {model_path} --set {label}={value} --closest --out {tmp_path / 'cli.ply'}")
        bodymodel.write_mesh(str(tmp_path / "py.ply"), V, model.faces)
        assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
        return
    pytest.fail(f"no morph folded a triangle for the repair to act on: {tried}")


def test_generate_matches_the_cli(model, model_path, tmp_path, cli):
    bodies = model.generate(2, seed=3, where={"weight_kg": (40, 60)}, measure_girths=False)
    cli(f"generate {model_path} --count 2 --seed 3 --where weight_kg=40..60 --no-girths --format ply "
        f"--out {tmp_path / 'crowd'}")
    files = sorted((tmp_path / "crowd").glob("*.ply"))
    assert len(files) == 2
    for b, f in zip(bodies, files):
        bodymodel.write_mesh(str(tmp_path / "py.ply"), b["V"], model.faces)
        assert (tmp_path / "py.ply").read_bytes() == f.read_bytes()
        assert b["satisfied"] and 40 <= b["measured"]["weight_kg"] <= 60
    seen = []
    model.generate(2, seed=3, progress=lambda f, w: seen.append(f), measure_girths=False)
    assert seen and max(seen) == pytest.approx(1.0)
    with pytest.raises(bodymodel.Cancelled):
        model.generate(3, seed=3, progress=lambda f, w: False)


def test_example_height_sweep_runs(model_path, tmp_path):
    import subprocess
    import sys
    from pathlib import Path

    script = Path(__file__).resolve().parents[2] / "examples" / "height_sweep.py"
    r = subprocess.run([sys.executable, str(script), "--model", str(model_path), "--out", str(tmp_path), "--steps", "3"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "height_sweep.png").stat().st_size > 1000
    rows = np.loadtxt(tmp_path / "height_sweep.csv", delimiter=",", skiprows=1)
    # Each step measures within the morph's tolerance of its target, the weight held within 0.5 kg.
    assert np.abs(rows[:, 1] - rows[:, 0]).max() <= 0.3
    assert np.ptp(rows[:, 2]) <= 0.5


def test_fit_matches_the_cli(model, model_path, tmp_path, cli):
    # A body the model can express (subject 2's coefficients), moved rigidly and perturbed, so the
    # fit has a rigid placement and a residual to find.
    V0 = model.decode(model.shape_mean + model.components @ model.coefficients[2])
    c, s = np.cos(0.2), np.sin(0.2)
    R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    rng = np.random.default_rng(4)
    Y = V0 @ R.T + [30.0, -10.0, 5.0] + rng.normal(scale=0.5, size=V0.shape)
    body = tmp_path / "body.ply"
    bodymodel.write_mesh(str(body), Y, model.faces)
    Yb, _ = bodymodel.read_mesh(str(body))
    cli(f"fit {model_path} --in {body} --components 3 --out {tmp_path / 'cli.ply'}")
    seen = []
    V, s = model.fit(Yb, components=3, progress=lambda f, w: seen.append(f))
    bodymodel.write_mesh(str(tmp_path / "py.ply"), V, model.faces)
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli.ply").read_bytes()
    j = json.loads((tmp_path / "cli.json").read_text())
    assert s["components"] == j["components"] == 3 and s["sub_model"] == j["sub_model"] == "shape"
    np.testing.assert_allclose(s["coefficients"], j["coefficients"], rtol=1e-9, atol=1e-9)
    for k in ("mean", "rms", "p95", "max"):
        assert s["vertex_error_mm"][k] == pytest.approx(j["vertex_error_mm"][k], rel=1e-9, abs=1e-9)
    assert s["iterations"] == j["iterations"] and s["converged"] == j["converged"]
    assert set(s["labels"]) == set(j["labels"])
    for name, lab in j["labels"].items():
        for k, v in lab.items():
            if k != "unit":
                assert s["labels"][name][k] == pytest.approx(v, rel=1e-9, abs=1e-9), (name, k)
    # The fit recovers the body: its per-vertex error is about the 0.5 mm noise, far below the
    # 30 mm offset and 0.2 rad rotation it had to undo.
    assert s["vertex_error"].shape == (len(V),) and np.mean(np.linalg.norm(V - Yb, axis=1)) == \
        pytest.approx(s["vertex_error_mm"]["mean"], rel=1e-6)
    assert s["vertex_error_mm"]["mean"] < 2.0
    assert seen and max(seen) <= 1.0
    with pytest.raises(bodymodel.Cancelled):
        model.fit(Yb, components=3, progress=lambda f, w: False)


def test_fit_bad_input_raises_as_the_cli(model, model_path, tmp_path, cli):
    V0 = model.decode(model.shape_mean)
    # Too few vertices: the CLI's message about the model's template, with V for the file name.
    small = tmp_path / "small.ply"
    F = model.faces[np.all(model.faces < 100, axis=1)]
    bodymodel.write_mesh(str(small), V0[:100], F)
    msg = cli_error_line(cli(f"fit {model_path} --in {small} --out {tmp_path / 'x.ply'}", check=False))
    with pytest.raises(bodymodel.InputError) as e:
        model.fit(V0[:100])
    assert str(e.value).startswith("V: 100 vertices")
    assert str(e.value).split(" but ")[1] == msg.split(" but ")[1]
    bad = V0.copy()
    bad[7, 1] = np.nan
    with pytest.raises(bodymodel.InputError, match="V: NaN at row 7"):
        model.fit(bad)
    with pytest.raises(bodymodel.InputError, match="expected an \\(n, 3\\) array"):
        model.fit(V0[:, :2])
    with pytest.raises(bodymodel.InputError) as e:
        model.fit(V0, components=0)
    assert str(e.value) == cli_error_line(
        cli(f"fit {model_path} --in {tmp_path / 'small.ply'} --components 0 --out {tmp_path / 'x.ply'}", check=False))
    with pytest.raises(bodymodel.InputError, match="--components 999: the shape model"):
        model.fit(V0, components=999)
