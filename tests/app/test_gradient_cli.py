"""`mbdae gradient` (shared/spec/sensitivities.md): the JSON and plain output, the
methods against each other, the results file, exit codes of bad input and failed runs.

Model: tests/app/models/gradient_demo.yaml (a block on a spring-damper with a dependent
stiffness parameter and a spline force, a pendulum whose initial angle is a parameter).
Run by CTest (app.gradient_cli) with MBDAE_BIN and MBDAE_APP_MODELS set.
"""
import json
import os
import shutil
import signal
import subprocess
import sys

import h5py
import numpy as np
import pytest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "support"))
from running import signal_keeps_earlier_file, start_until_temporary, temporary_files  # noqa: E402

MBDAE = os.environ.get("MBDAE_BIN", "build/mbdae")
MODELS = os.environ.get("MBDAE_APP_MODELS", "tests/app/models")
MODEL = os.path.join(MODELS, "gradient_demo.yaml")
WRT = "k,c,m,phi0,k2,u[1]"


def run(*args, expect=0):
    p = subprocess.run([MBDAE, "gradient", MODEL, *args], capture_output=True, text=True)
    assert p.returncode == expect, f"exit {p.returncode}\nstdout: {p.stdout}\nstderr: {p.stderr}"
    return p


def gradient(*args):
    d = json.loads(run("--json", *args).stdout)
    return d


def as_array(d):
    objs = list(d["objectives"])
    wrt = list(d["objectives"][objs[0]]["gradient"])
    return np.array([[d["objectives"][o]["gradient"][p] for p in wrt] for o in objs]), objs, wrt


def rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


def test_json_has_the_contract_keys_and_defaults():
    d = gradient("--wrt", "k")
    assert d["method"] == "adjoint" and d["integrator"] == "hht" and d["status"] == "done"
    assert list(d["objectives"]) == ["E", "X", "R"]  # every objective by default
    for key in ("solver_cpu_time", "gradient_cpu_time"):
        assert d[key] >= 0
    # every parameter by default; fd also takes L, which sets marker geometry
    fd = gradient("--method", "fd", "--objective", "E")
    assert list(fd["objectives"]["E"]["gradient"]) == ["k", "c", "m", "L", "phi0", "k2"]
    assert list(fd["fd_steps"]) == ["k", "c", "m", "L", "phi0", "k2"]
    assert fd["fd_steps"]["k"] == pytest.approx(40 * 1e-5, rel=1e-14)
    assert fd["runs"] == 13
    # --wrt-splines adds every ordinate after the parameters
    sp = gradient("--wrt", "k", "--wrt-splines", "--objective", "E")
    assert list(sp["objectives"]["E"]["gradient"]) == ["k"] + [f"u[{i}]" for i in range(5)]


def test_default_wrt_refuses_a_geometry_parameter_by_name():
    # every parameter includes L, which sets marker geometry: the exact methods refuse it,
    # naming the parameter, the element and the line
    p = run("--json", expect=2)
    assert "'L'" in p.stderr and "pivot" in p.stderr and "gradient_demo.yaml" in p.stderr
    assert p.stdout == ""


def test_hht_forward_equals_adjoint_and_fd_agrees():
    adj, objs, wrt = as_array(gradient("--wrt", WRT))
    fwd, _, _ = as_array(gradient("--wrt", WRT, "--method", "forward"))
    fd, _, _ = as_array(gradient("--wrt", WRT, "--method", "fd"))
    # same discretisation: round-off
    assert rel(fwd, adj) < 1e-11
    # central differences of whole runs (step 1e-5 relative): truncation and Newton noise
    assert rel(fd, adj) < 1e-7
    # the dependent parameter k2 = 2 k: dG/dk = 2 dG/dk2 (the chain)
    assert np.allclose(adj[:, wrt.index("k")], 2 * adj[:, wrt.index("k2")], rtol=1e-12, atol=0)
    # phi0 moves the initial state: not zero, and equal to fd
    assert abs(adj[0, wrt.index("phi0")]) > 0.1


def test_adaptive_hht_adjoint_equals_fd_of_replayed_runs():
    args = ("--wrt", "k,c,phi0,u[1]", "--adaptive", "--tolerance", "1e-6", "--objective", "E,X")
    adj, _, _ = as_array(gradient(*args))
    fd = gradient(*args, "--method", "fd")
    assert fd["runs"] == 9
    fdg, _, _ = as_array(fd)
    assert rel(fdg, adj) < 1e-6


def test_ida_forward_and_adjoint_agree_and_refuse_reactions():
    args = ("--wrt", "k,c,phi0,u[1]", "--integrator", "ida", "--rtol", "1e-10", "--atol", "1e-12")
    fwd = gradient(*args, "--method", "forward")
    assert list(fwd["objectives"]) == ["E", "X", "R"]  # forward takes any objective
    adj = gradient(*args, "--objective", "E")
    a, _, _ = as_array(adj)
    f = np.array([[fwd["objectives"][o]["gradient"][p] for p in ("k", "c", "phi0", "u[1]")] for o in ("E",)])
    assert rel(a, f) < 1e-5
    for o in ("E",):
        assert abs(adj["objectives"][o]["value"] - fwd["objectives"][o]["value"]) < 1e-7
    # the IDAS adjoint cannot take objectives over reactions: exit 2 naming them
    p = run(*args, "--json", expect=2)
    assert "objective 'R'" in p.stderr and "'fx'" in p.stderr and "--method forward" in p.stderr


def test_plain_output_has_values_and_a_table():
    out = run("--wrt", "k,u[1]", "--objective", "E").stdout
    lines = out.splitlines()
    assert lines[0].startswith("objective E")
    assert any(line.split()[:1] == ["k"] for line in lines)
    assert any(line.split()[:1] == ["u[1]"] for line in lines)
    assert "method: adjoint" in out
    fd = run("--wrt", "k,u[1]", "--objective", "E", "--method", "fd").stdout
    assert "fd steps" in fd and "k 0.0004" in fd


def test_results_file_holds_the_run_and_the_gradients(tmp_path):
    path = tmp_path / "g.h5"
    d = gradient("--wrt", WRT, "-o", str(path))
    with h5py.File(path, "r") as f:
        assert f.attrs["status"] == "done"
        assert f.attrs["gradient_status"] == "done"
        assert f["time"].shape[0] == 101
        for o, entry in d["objectives"].items():
            g = f["objectives"][o]
            assert g.attrs["value"] == pytest.approx(entry["value"], rel=1e-14)
            names = [n.decode() if isinstance(n, bytes) else n for n in g.attrs["gradient_names"]]
            assert names == list(entry["gradient"])
            assert np.allclose(g["gradient"][:], list(entry["gradient"].values()), rtol=1e-15, atol=0)


@pytest.mark.parametrize("args,needle", [
    (("--wrt", "k,nope"), "'nope'"),
    (("--wrt", "u[9]"), "u[9]"),
    (("--wrt", "k", "--objective", "nope"), "objective 'nope'"),
    (("--wrt", "k,k"), "'k' twice"),
    (("--wrt", "k", "--method", "newton"), "--method"),
])
def test_bad_input_exits_2_and_writes_nothing(tmp_path, args, needle):
    path = tmp_path / "bad.h5"
    p = run(*args, "-o", str(path), expect=2)
    assert "mbdae: error: " in p.stderr and needle in p.stderr, p.stderr
    assert not path.exists()
    assert p.stdout == ""


def test_model_without_objectives_exits_2(tmp_path):
    text = open(MODEL).read().split("objectives:")[0] + "simulation: {t_end: 0.1}\n"
    model = tmp_path / "none.yaml"
    model.write_text(text)
    p = subprocess.run([MBDAE, "gradient", str(model), "--wrt", "k"], capture_output=True, text=True)
    assert p.returncode == 2 and "no objectives" in p.stderr


@pytest.mark.parametrize("method", ["adjoint", "fd"])
def test_failed_run_exits_3_without_a_gradient(tmp_path, method):
    path = tmp_path / "fail.h5"
    p = run("--wrt", "k", "--adaptive", "--tolerance", "1e-30", "--method", method, "--json",
            "-o", str(path), expect=3)
    d = json.loads(p.stdout)
    assert d["status"] == "failed" and d["objectives"] == {} and "failure_reason" in d
    assert "no gradient" in p.stderr
    with h5py.File(path, "r") as f:
        assert f.attrs["status"] == "failed"
        assert "objectives" not in f
    assert tmp_files(tmp_path) == []


def test_objective_over_an_unknown_measure_exits_2_naming_it(tmp_path):
    model = tmp_path / "unknown_measure.yaml"
    model.write_text(open(MODEL).read().replace('integral: "fx^2"', 'integral: "nosuch^2"'))
    out = tmp_path / "u.h5"
    p = subprocess.run([MBDAE, "gradient", str(model), "--wrt", "k", "-o", str(out)],
                       capture_output=True, text=True)
    assert p.returncode == 2
    assert "objective 'R'" in p.stderr and "'nosuch'" in p.stderr and "unknown_measure.yaml:" in p.stderr
    assert not out.exists()


# ---- the results file (-o): written beside it, renamed at the end (docs/cli.md) ----------

tmp_files = temporary_files


def run_in(folder, *args):
    return subprocess.run([MBDAE, "gradient", *args], cwd=folder, capture_output=True, text=True, timeout=120)


def test_an_earlier_results_file_is_replaced_at_the_end(tmp_path):
    out = tmp_path / "g.h5"
    out.write_bytes(b"earlier results")
    run("--wrt", "k", "--quiet", "-o", str(out))
    with h5py.File(out, "r") as f:
        assert f.attrs["status"] == "done" and f.attrs["gradient_status"] == "done"
    assert tmp_files(tmp_path) == []


def test_results_file_is_never_the_model(tmp_path):
    shutil.copy(MODEL, tmp_path / "m.yaml")
    os.symlink("m.yaml", tmp_path / "link.yaml")
    original = (tmp_path / "m.yaml").read_bytes()
    for out in ["m.yaml", "./m.yaml", "link.yaml", str(tmp_path / "m.yaml")]:
        p = run_in(tmp_path, "m.yaml", "--wrt", "k", "-o", out)
        assert p.returncode == 2, (out, p.stderr)
        assert "is the input file" in p.stderr, p.stderr
        assert (tmp_path / "m.yaml").read_bytes() == original
    assert not list(tmp_path.glob("*.h5")) and tmp_files(tmp_path) == []


@pytest.mark.parametrize("out,reason", [
    ("missing_dir/g.h5", "No such file or directory"),
    ("adir", "Is a directory"),
])
def test_unwritable_results_file_says_why(tmp_path, out, reason):
    (tmp_path / "adir").mkdir()
    p = run_in(tmp_path, MODEL, "--wrt", "k", "-o", out)
    assert p.returncode == 2, p.stderr
    assert p.stderr.strip() == "mbdae: error: cannot write the results file '%s': %s" % (out, reason)
    assert tmp_files(tmp_path) == [] and not list(tmp_path.glob("*.h5"))


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_signal_removes_the_temporary_file_and_keeps_the_earlier_one(tmp_path, signum):
    out = tmp_path / "g.h5"
    out.write_bytes(b"earlier results")
    # A forward run of 1e4 s (1e7 steps): still going when the signal comes.
    proc = start_until_temporary([MBDAE, "gradient", MODEL, "--wrt", "k", "--t-end", "1e4",
                                  "--quiet", "-o", str(out)], tmp_path)
    signal_keeps_earlier_file(proc, out, tmp_path, signum, b"earlier results")
