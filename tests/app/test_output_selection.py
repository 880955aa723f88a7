"""The results file's chosen elements (`simulation: {output: {bodies, joints, forces,
measures}}`, `--output-bodies`, `--output-joints`, `--output-forces`, `--output-measures`;
docs/results-file.md, "Chosen elements") through the program, on models/fourbar.yaml
(crank, coupler, rocker; joints j_crank, j_left, j_right, j_rocker; measures crank_angle,
rocker_angle):

- a run with chosen elements writes their datasets only, each equal to the whole file's
  (the same run otherwise), /q, /v, /a, /lambda and the energies whole and equal, and
  the attributes output_bodies, ... name the choice (absent when every element is
  written);
- the model file's key is read, overridden by the command line (`all`), written back by
  `convert`; an element the model lacks is refused with the file and line (model file)
  or the option (command line), exit 2 and no results file;
- `mbdae view` draws a body without /bodies/NAME from its columns of /q: the page's
  bodies are the whole file's page's;
- the Python package's options["output.bodies"], ... (lists of names or "all") give the
  program's file; unknown names are refused.
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from pendulum_app import run, run_ok, simulate  # noqa: E402

MODELS = os.environ["MBDAE_APP_MODELS"]
FOURBAR = os.path.join(MODELS, "fourbar.yaml")
SIMULATION = "simulation:\n"


def datasets(f):
    out = []
    f.visit(lambda name: out.append(name) if hasattr(f[name], "shape") else None)
    return sorted(out)


def strings(values):
    return [v.decode() if isinstance(v, bytes) else str(v) for v in values]


def test_chosen_elements_only_and_equal_to_the_whole_file(tmp_path):
    with simulate(tmp_path, FOURBAR, "all.h5") as full, \
            simulate(tmp_path, FOURBAR, "some.h5",
                     ["--output-bodies", "coupler", "--output-joints", "j_left,j_right",
                      "--output-measures", "none"]) as some:
        assert list(full["bodies"]) == ["coupler", "crank", "rocker"]
        assert list(some["bodies"]) == ["coupler"]
        assert list(some["joints"]) == ["j_left", "j_right"]
        assert list(some["measures"]) == []
        assert len(full["measures"]) == 2
        for key in ("output_bodies", "output_joints", "output_forces", "output_measures"):
            assert key not in full.attrs
        assert strings(some.attrs["output_bodies"]) == ["coupler"]
        assert strings(some.attrs["output_joints"]) == ["j_left", "j_right"]
        assert strings(some.attrs["output_measures"]) == []
        assert "output_forces" not in some.attrs
        kept = datasets(some)
        assert set(kept) < set(datasets(full))
        assert "bodies/coupler/angular_velocity" in kept and "joints/j_right/torque" in kept
        assert "q" in kept and "lambda" in kept and "energy/kinetic" in kept
        for name in kept:
            if some[name].dtype.kind == "f":
                assert np.array_equal(some[name][()], full[name][()]), name
        assert some["time"].shape == full["time"].shape == (11,)  # t_end 0.5, rows every 0.05


def test_model_file_key_override_and_convert(tmp_path):
    text = open(FOURBAR).read()
    assert text.count(SIMULATION) == 1
    text = text.replace(SIMULATION, SIMULATION + "  output: {bodies: [rocker, crank], joints: []}\n")
    (tmp_path / "m.yaml").write_text(text)
    with simulate(tmp_path, "m.yaml", "m.h5") as f:
        assert list(f["bodies"]) == ["crank", "rocker"]
        assert list(f["joints"]) == []
        assert len(f["measures"]) == 2
        assert strings(f.attrs["output_bodies"]) == ["rocker", "crank"]
    with simulate(tmp_path, "m.yaml", "o.h5", ["--output-bodies", "all"]) as f:
        assert list(f["bodies"]) == ["coupler", "crank", "rocker"]
        assert "output_bodies" not in f.attrs and list(f["joints"]) == []
    run_ok(["convert", "m.yaml", "-o", "c.yaml"], tmp_path)
    converted = (tmp_path / "c.yaml").read_text()
    assert '    bodies: ["rocker", "crank"]\n    joints: []\n' in converted
    with simulate(tmp_path, "c.yaml", "c.h5") as f:
        assert list(f["bodies"]) == ["crank", "rocker"] and list(f["joints"]) == []


def test_unknown_elements_are_refused_before_anything_is_written(tmp_path):
    p = run(["simulate", FOURBAR, "-o", "x.h5", "--output-joints", "j_left,j_middle"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert "output joints: the model has no joint named 'j_middle'" in p.stderr, p.stderr
    assert not (tmp_path / "x.h5").exists()
    p = run(["simulate", FOURBAR, "-o", "x.h5", "--output-bodies", "crank,,rocker"], tmp_path)
    assert p.returncode == 2 and "--output-bodies: empty name" in p.stderr, p.stderr
    text = open(FOURBAR).read().replace(SIMULATION, SIMULATION + "  output: {measures: [crank]}\n")
    line = text[:text.index("  output:")].count("\n") + 1
    (tmp_path / "bad.yaml").write_text(text)
    p = run(["simulate", "bad.yaml", "-o", "x.h5"], tmp_path)
    assert p.returncode == 2, p.stderr
    assert "bad.yaml:%d:" % line in p.stderr, p.stderr
    assert "output measures: no measure named 'crank'" in p.stderr, p.stderr
    assert not (tmp_path / "x.h5").exists()


def page_bodies(path):
    """The bodies (name, positions, orientations) of the page `mbdae view` wrote."""
    html = open(path).read()
    start = html.index('"bodies":[') + len('"bodies":')
    bodies, _ = json.JSONDecoder().raw_decode(html[start:])
    return bodies


def test_view_draws_bodies_from_q(tmp_path):
    with simulate(tmp_path, FOURBAR, "all.h5"):
        pass
    with simulate(tmp_path, FOURBAR, "none.h5", ["--output-bodies", "none"]) as f:
        assert list(f["bodies"]) == []
    run_ok(["view", "all.h5", "-o", "all.html"], tmp_path)
    run_ok(["view", "none.h5", "-o", "none.html"], tmp_path)
    full, drawn = page_bodies(tmp_path / "all.html"), page_bodies(tmp_path / "none.html")
    assert [b["name"] for b in drawn] == ["crank", "coupler", "rocker"]
    assert len(drawn[1]["p"]) == 3 * 11 and len(drawn[1]["q"]) == 4 * 11
    assert drawn == full


def test_python_options(tmp_path):
    """options["output.bodies"] etc.: a list of names or "all", read back alike; the
    written file as the program's with the same choice; unknown names refused."""
    import h5py
    import mbdae
    with simulate(tmp_path, FOURBAR, "cli.h5", ["--output-bodies", "rocker", "--output-joints", "none"]):
        pass
    with mbdae.Model(FOURBAR) as m:
        assert m.options["output.bodies"] == "all"
        m.options["output.bodies"] = ["rocker"]
        m.options["output.joints"] = []
        assert m.options["output.bodies"] == ["rocker"]
        assert m.options["output.joints"] == []
        assert m.options["output.measures"] == "all"
        for key, value, what in (("output.joints", ["j_crank", "j_none"], "no joint named 'j_none'"),
                                 ("output.forces", "a,,b", "expected all, none or comma-separated names")):
            try:
                m.options[key] = value
                raise AssertionError("%s = %r accepted" % (key, value))
            except mbdae.Error as e:
                assert what in str(e), str(e)
        assert m.options["output.joints"] == []
        m.solve()
        m.write_results(tmp_path / "py.h5")
    with h5py.File(tmp_path / "py.h5", "r") as f, h5py.File(tmp_path / "cli.h5", "r") as g:
        assert list(f["bodies"]) == list(g["bodies"]) == ["rocker"]
        assert list(f["joints"]) == list(g["joints"]) == []
        assert strings(f.attrs["output_bodies"]) == ["rocker"]
        assert np.allclose(f["bodies/rocker/position"][()], g["bodies/rocker/position"][()],
                           rtol=0, atol=1e-12)
