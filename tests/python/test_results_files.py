"""Results files from Python (Model.write_results, Model.gradient(results=...),
mbdae.optimize(results=...)) are written as ``mbdae simulate -o`` writes them: into
PATH.PID.tmp beside PATH and renamed over it at the end, so that an earlier file stays
whole until then and after a call that fails; the model (or problem) file is refused
with mbdae.FileError, by any spelling or link; no temporary file is left behind.
"""

import os
import shutil

import h5py
import pytest

import mbdae
from conftest import PENDULUM, ROOT

EARLIER = b"an earlier results file\n"
GRADIENT_MODEL = os.path.join(ROOT, "tests", "api", "models", "gradient_oscillator.yaml")
OPTIMIZE = os.path.join(ROOT, "tests", "optimize")


def temporaries(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def expect_model_file_refused(folder, model, call):
    """`call(path)` with the model file by its name, through "./" and a link: FileError
    naming it, the model unchanged, no temporary file."""
    before = model.read_bytes()
    link = folder / "link.yaml"
    link.symlink_to(model.name)
    for path in (model, folder / "." / model.name, link):
        with pytest.raises(mbdae.FileError, match=r"is the .*%s' itself" % model.name):
            call(path)
    assert model.read_bytes() == before
    assert temporaries(folder) == []
    link.unlink()


def test_write_results_keeps_an_earlier_file_until_complete(tmp_path):
    model = tmp_path / "pendulum.yaml"
    shutil.copy(PENDULUM, model)
    out = tmp_path / "out.h5"
    out.write_bytes(EARLIER)
    with mbdae.Model(str(model)) as m:
        m.options["t_end"] = 0.1
        with pytest.raises(mbdae.OrderError):  # no rows yet
            m.write_results(out)
        assert out.read_bytes() == EARLIER
        m.solve()
        (tmp_path / "sub").mkdir()
        with pytest.raises(mbdae.FileError, match="Is a directory"):
            m.write_results(tmp_path / "sub")
        assert temporaries(tmp_path) == []
        m.write_results(out)
        with h5py.File(out, "r") as f:
            assert f.attrs["status"] == "done"
            assert f["time"][-1] == pytest.approx(0.1, abs=1e-12)
        assert temporaries(tmp_path) == []
        expect_model_file_refused(tmp_path, model, m.write_results)


def test_gradient_keeps_the_earlier_file_when_it_fails(tmp_path):
    model = tmp_path / "oscillator.yaml"
    shutil.copy(GRADIENT_MODEL, model)
    out = tmp_path / "g.h5"
    out.write_bytes(EARLIER)
    with mbdae.Model(str(model)) as m:
        m.options["t_end"] = 0.2
        # A budget below one checkpoint: refused inside the driver, after the results
        # file was set up.
        m.options["gradient.trajectory_memory"] = 1
        with pytest.raises(mbdae.InputError, match="trajectory_memory"):
            m.gradient(wrt=["k"], results=out)
        assert out.read_bytes() == EARLIER
        assert temporaries(tmp_path) == []
        m.options["gradient.trajectory_memory"] = 1e9
        g = m.gradient(wrt=["k"], results=out)
        with h5py.File(out, "r") as f:
            assert f.attrs["status"] == "done"
            assert f["objectives/G"].attrs["value"] == pytest.approx(g.values["G"], rel=1e-12)
        assert temporaries(tmp_path) == []
        expect_model_file_refused(tmp_path, model, lambda p: m.gradient(wrt=["k"], results=p))


def test_optimize_keeps_the_earlier_file_until_the_end(tmp_path):
    shutil.copy(os.path.join(OPTIMIZE, "rotor.yaml"), tmp_path / "rotor.yaml")
    problem = tmp_path / "problem.yaml"
    shutil.copy(os.path.join(OPTIMIZE, "rotor_problem.yaml"), problem)
    out = tmp_path / "o.h5"
    out.write_bytes(EARLIER)
    temporary = tmp_path / ("o.h5.%d.tmp" % os.getpid())
    seen = []

    def watch(i, f, v):
        seen.append((out.read_bytes() == EARLIER, temporary.exists()))
        if i == 1:
            raise KeyboardInterrupt  # as Ctrl-C during the optimisation

    # An exception of the callback: the results file abandoned, the earlier one kept.
    with pytest.raises(KeyboardInterrupt):
        mbdae.optimize(problem, results=out, progress=watch)
    assert seen == [(True, True), (True, True)]
    assert out.read_bytes() == EARLIER
    assert temporaries(tmp_path) == []
    # Stopped by returning True: the final run is written and renamed over it.
    seen.clear()
    r = mbdae.optimize(problem, results=out, progress=lambda i, f, v: watch(0, f, v) or i == 1)
    assert seen == [(True, True), (True, True)]
    assert r.ipopt_status == "User_Requested_Stop" and r.results == os.fspath(out)
    with h5py.File(out, "r") as f:
        assert "optimization" in f
    assert temporaries(tmp_path) == []
    expect_model_file_refused(tmp_path, problem, lambda p: mbdae.optimize(problem, results=p))
    expect_model_file_refused(tmp_path, tmp_path / "rotor.yaml",
                              lambda p: mbdae.optimize(problem, results=p))
