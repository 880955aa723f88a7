"""mbdae sweep STUDY.yaml (docs/sweeps.md): the program end to end.

The program (MBDAE_EXE, set by CTest to the built mbdae) runs small studies of the
slider-crank (t_end = 0.5 s, 50 HHT steps a run): on a default local cluster and on a
running scheduler (--scheduler); the HDF5 file's layout and numbers (against mbdae.sweep
in this process, bitwise, and the documented draws of numpy's default_rng(seed));
resumption (a rerun runs nothing; runs marked pending are the only ones run again; a
failed run is kept unless --retry-failed; another study in the file is refused); a
SIGKILL in the middle leaves a readable file that a rerun completes; SIGTERM writes the
finished runs and exits 143; bad study files exit 2 with file:line:column and write
nothing; a missing package or interpreter is named (exit 1); the installed tree
(cmake --install) finds its package.
"""

import importlib
import os
import re
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

import mbdae

sw = importlib.import_module("mbdae.sweep")  # the module (mbdae.sweep is the function)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MODEL = os.path.join(ROOT, "verification", "slider_crank", "slider_crank.yaml")
EXE = os.environ.get("MBDAE_EXE", os.path.join(ROOT, "build", "mbdae"))
OPTIONS = {"t_end": 0.5, "integrator": "hht", "hht.step": 0.01, "output_step": 0.01}

STUDY = """\
# a grid in F times a Monte Carlo in k and c
model: {model}
options: {{t_end: 0.5, integrator: hht, hht.step: 0.01, output_step: 0.01}}
parameters:
  F: [1, 2]
  k: {{distribution: normal, mean: 1, std: 0.1}}
  c: {{distribution: uniform, low: 0.5, high: 1.5}}
samples: {samples}
seed: 11
outputs: [objectives, final:xs, series:xs, gradient:G]
wrt: [k, c]
"""


def write(path, text):
    with open(path, "w") as f:
        f.write(text)
    return path


def sweep(*args, env=None, timeout=240):
    e = dict(os.environ)
    e.update(env or {})
    return subprocess.run([EXE, "sweep"] + [str(a) for a in args], capture_output=True,
                          text=True, env=e, timeout=timeout)


@pytest.fixture(scope="module")
def scheduler():
    """The address of a running cluster of one worker process."""
    from distributed import LocalCluster

    cluster = LocalCluster(n_workers=1, processes=True, threads_per_worker=1,
                           dashboard_address=None)
    yield cluster.scheduler_address
    cluster.close()


def expected_parameters(samples):
    rng = np.random.default_rng(11)
    k = rng.normal(1, 0.1, samples)
    c = rng.uniform(0.5, 1.5, samples)
    return {"F": np.repeat([1.0, 2.0], samples), "k": np.tile(k, 2), "c": np.tile(c, 2)}


def test_study_end_to_end_on_a_local_cluster(tmp_path):
    study = write(tmp_path / "mc.yaml", STUDY.format(model=MODEL, samples=3))
    r = sweep(study, "--workers", 2)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "mc.h5"  # the default name
    assert "mbdae: sweep: 6 runs: 6 done, 0 failed; 6 run now" in r.stdout
    assert "mbdae: sweep: 6 of 6 runs (100 %), 0 failed" in r.stderr  # lines: not a terminal
    assert sorted(os.listdir(tmp_path)) == ["mc.h5", "mc.yaml"]  # no temporary left
    with h5py.File(out, "r") as f:
        a = f.attrs
        assert a["kind"] == "mbdae sweep" and a["format"] == 1 and a["runs"] == 6
        assert a["done"] == 6 and a["failed"] == 0 and a["pending"] == 0 and a["complete"]
        assert list(a["parameters"]) == ["F", "k", "c"]
        assert list(a["columns"]) == ["objective:G", "final:xs", "series:xs", "gradient:G:k",
                                      "gradient:G:c"]
        assert a["study_text"] == open(study).read()
        expected = expected_parameters(3)
        for name in ("F", "k", "c"):
            assert np.array_equal(f["parameters"][name][()], expected[name]), name
        assert f["outputs/series:xs"].shape == (6, 51)
        assert [s.decode() for s in f["status"][()]] == ["done"] * 6
        assert [s.decode() for s in f["message"][()]] == [""] * 6
        assert np.all(f["wall_time"][()] > 0)
        assert len(set(s.decode() for s in f["worker"][()])) in (1, 2)
        assert np.array_equal(f["run"][()], np.arange(6))
    # the same numbers as mbdae.sweep in this process
    samples = [dict(zip(("F", "k", "c"), x)) for x in zip(*expected.values())]
    here = mbdae.sweep(MODEL, samples, ["objectives", "final:xs", "series:xs", "gradient:G"],
                       "serial", options=OPTIONS, wrt=["k", "c"])
    back = mbdae.read_sweep(out)
    for c in ("objective:G", "final:xs", "gradient:G:k", "gradient:G:c"):
        assert np.array_equal(back[c].to_numpy(), here[c].to_numpy()), c
    for i in range(6):
        assert np.array_equal(back["series:xs"][i], here["series:xs"][i])
    # F = 2 pushes harder than F = 1: more kinetic energy
    assert (back["objective:G"][3:].to_numpy() > back["objective:G"][:3].to_numpy()).all()


def test_resumption(tmp_path, scheduler):
    text = STUDY.format(model=MODEL, samples=4)
    study = write(tmp_path / "mc.yaml", text)
    out = tmp_path / "out.h5"
    r = sweep(study, "--scheduler", scheduler, "-o", out)
    assert r.returncode == 0, r.stderr
    first = mbdae.read_sweep(out)
    # a rerun runs nothing and leaves the numbers as they were
    r = sweep(study, "--scheduler", scheduler, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "8 runs: 8 done, 0 failed; 0 run now" in r.stdout
    assert "8 of 8 runs are in" in r.stderr
    again = mbdae.read_sweep(out)
    assert again.drop(columns="series:xs").equals(first.drop(columns="series:xs"))
    # runs 2 and 5 pending (as a study killed before them leaves them): only they run
    with h5py.File(out, "r+") as f:
        status = f["status"][()]
        status[[2, 5]] = b"pending"
        f["status"][...] = status
        f["wall_time"][[2, 5]] = np.nan
    r = sweep(study, "--scheduler", scheduler, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "8 runs: 8 done, 0 failed; 2 run now" in r.stdout and "6 taken" in r.stdout
    third = mbdae.read_sweep(out)
    assert (third["status"] == "done").all()
    keep = [0, 1, 3, 4, 6, 7]
    assert np.array_equal(third["wall_time"].to_numpy()[keep],
                          first["wall_time"].to_numpy()[keep])  # not run again
    assert np.array_equal(third["objective:G"].to_numpy(), first["objective:G"].to_numpy())
    # another study (another seed) in the same file: refused, the file untouched
    other = write(tmp_path / "other.yaml", text.replace("seed: 11", "seed: 12"))
    before = open(out, "rb").read()
    r = sweep(other, "--scheduler", scheduler, "-o", out)
    assert r.returncode == 2
    assert "holds the results of another study (the parameter values of run 0 differ)" \
        in r.stderr, r.stderr
    assert open(out, "rb").read() == before


def test_failed_run_exit_3_and_retry(tmp_path, scheduler):
    study = write(tmp_path / "s.yaml", (
        "model: %s\noptions: {t_end: 0.5, integrator: hht, hht.step: 0.01}\n"
        "parameters:\n  c: [1.0, .nan, 0.5]\noutputs: final:xs\n") % MODEL)
    out = tmp_path / "s.h5"
    r = sweep(study, "--scheduler", scheduler, "-o", out)
    assert r.returncode == 3, r.stderr
    # (YAML's .nan has the sign bit set: the library prints it as -nan)
    assert re.search(r"mbdae: run 1 \(c = nan\) failed: parameter 'c': the value must be "
                     r"finite, got -?nan", r.stderr), r.stderr
    f = mbdae.read_sweep(out)
    assert list(f["status"]) == ["done", "failed", "done"]
    assert re.fullmatch(r"parameter 'c': the value must be finite, got -?nan", f["message"][1])
    assert np.isnan(f["final:xs"][1]) and np.isfinite(f["final:xs"][[0, 2]]).all()
    r = sweep(study, "--scheduler", scheduler, "-o", out)
    assert r.returncode == 3 and "0 run now" in r.stdout
    r = sweep(study, "--scheduler", scheduler, "-o", out, "--retry-failed")
    assert r.returncode == 3 and "1 run now" in r.stdout


def start(args):
    return subprocess.Popen([EXE, "sweep"] + [str(a) for a in args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def wait_for_runs(out, proc, at_least, timeout=120):
    """Polls the results file until it records `at_least` finished runs."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        assert proc.poll() is None, proc.communicate()
        if os.path.exists(out):
            with h5py.File(out, "r") as f:
                if f.attrs["done"] >= at_least:
                    return int(f.attrs["done"])
        time.sleep(0.05)
    raise AssertionError("no %d runs in %s after %g s" % (at_least, out, timeout))


def test_killed_study_leaves_a_readable_file(tmp_path, scheduler):
    study = write(tmp_path / "mc.yaml", STUDY.format(model=MODEL, samples=30)
                  .replace("outputs: [objectives, final:xs, series:xs, gradient:G]",
                           "outputs: [final:xs, series:xs]"))
    out = tmp_path / "mc.h5"
    proc = start([study, "--scheduler", scheduler, "--flush-interval", 0, "-o", out])
    wait_for_runs(out, proc, 5)
    proc.kill()  # SIGKILL: no chance to write anything more
    proc.communicate()
    killed_tmp = "mc.h5.%d.tmp" % proc.pid  # left if the kill came during a write
    killed = mbdae.read_sweep(out)  # readable: the last whole file
    done = killed["status"] == "done"
    assert 5 <= done.sum() < 60, done.sum()
    r = sweep(study, "--scheduler", scheduler, "-o", out)
    assert r.returncode == 0, r.stderr
    assert "%d taken from the earlier file" % done.sum() in r.stdout
    full = mbdae.read_sweep(out)
    assert (full["status"] == "done").all()
    assert np.array_equal(full["final:xs"][done].to_numpy(), killed["final:xs"][done].to_numpy())
    # SIGTERM: the finished runs are written, exit 143
    os.unlink(out)
    proc = start([study, "--scheduler", scheduler, "--flush-interval", 0, "-o", out])
    wait_for_runs(out, proc, 3)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "interrupted by SIGTERM" in err
    stopped = mbdae.read_sweep(out)
    assert (stopped["status"] == "done").sum() >= 3
    assert not stopped.attrs["complete"]
    # SIGTERM removes its own temporary file; only the SIGKILLed run's may be there
    assert set(p for p in os.listdir(tmp_path) if p.endswith(".tmp")) <= {killed_tmp}


BAD = [
    ("parameter:\n  k: [1]\noutputs: [final:xs]\n",
     "bad.yaml:2:1: study: unknown key 'parameter'; did you mean 'parameters'?"),
    ("parameters:\n  kk: [1, 2]\noutputs: [final:xs]\n",
     "bad.yaml:3:3: parameters: 'kk' is neither a parameter (did you mean 'k'?)"),
    ("parameters:\n  k: [1, x]\noutputs: [final:xs]\n",
     "bad.yaml:3:10: parameters: k: expected a number, got 'x'"),
    ("parameters:\n  k: {distribution: normal, mean: 1}\nsamples: 3\nseed: 1\n"
     "outputs: [final:xs]\n",
     "bad.yaml:3:6: parameters: k: a normal distribution needs 'std'"),
    ("parameters:\n  k: {distribution: gauss, mean: 1, std: 1}\nsamples: 3\nseed: 1\n"
     "outputs: [final:xs]\n",
     "bad.yaml:3:21: parameters: k: distribution: unknown 'gauss'"),
    ("parameters:\n  k: {distribution: normal, mean: 1, std: 1}\nsamples: 3\n"
     "outputs: [final:xs]\n",
     "bad.yaml:3:3: parameters: k has a distribution: the study needs 'seed:'"),
    ("parameters:\n  k: [1]\noutputs: [final:xs, finl:xs]\n",
     "bad.yaml:4:21: outputs: unknown output 'finl:xs'; did you mean 'final'?"),
    ("parameters:\n  k: [1]\noutputs: [final:x]\n",
     "bad.yaml:4:11: outputs: 'final:x': no measure or coordinate 'x'"),
    ("parameters:\n  k: [1]\noptions: {t_end: -1}\noutputs: [final:xs]\n",
     "bad.yaml:4:18: options: t_end:"),
    ("parameters:\n  k: [1\noutputs: [final:xs]\n", "bad.yaml:4:8: YAML: "),
    ("parameters:\n  k: [1]\n", "bad.yaml:1:1: study: 'outputs:' is missing"),
]


@pytest.mark.parametrize("body,message", BAD)
def test_bad_study_exits_2_with_file_line(tmp_path, monkeypatch, capsys, body, message):
    """In this process, through the function the program runs (sweep.main)."""
    study = write(tmp_path / "bad.yaml", "model: %s\n%s" % (MODEL, body))
    monkeypatch.chdir(tmp_path)
    assert sw.main(["bad.yaml"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("mbdae: error: " + message), err
    assert sorted(os.listdir(tmp_path)) == ["bad.yaml"]  # nothing written
    assert os.path.exists(study)


def test_bad_study_through_the_program(tmp_path):
    write(tmp_path / "bad.yaml", "model: %s\n%s" % (MODEL, BAD[1][0]))
    r = subprocess.run([EXE, "sweep", "bad.yaml"], capture_output=True, text=True,
                       cwd=tmp_path, timeout=120)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert r.stderr.startswith("mbdae: error: " + BAD[1][1]), r.stderr
    assert sorted(os.listdir(tmp_path)) == ["bad.yaml"]
    r = sweep()
    assert r.returncode == 2 and "mbdae: error: sweep: no study file" in r.stderr
    assert "usage: mbdae sweep STUDY.yaml" in r.stderr


def test_command_line_mistakes(tmp_path, capsys):
    def run(*args):
        code = sw.main([str(a) for a in args])
        return code, capsys.readouterr()

    code, out = run("x.yaml", "--workers", "0")
    assert code == 2 and "--workers: expected a whole number >= 1" in out.err
    code, out = run("x.yaml", "--bogus")
    assert code == 2 and "unknown option '--bogus'" in out.err
    code, out = run(tmp_path / "none.yaml")
    assert code == 2 and "none.yaml: cannot open the study file" in out.err
    study = write(tmp_path / "s.yaml", "model: %s\nparameters: {k: 1}\noutputs: final\n"
                  % MODEL)
    code, out = run(study, "-o", study)
    assert code == 2 and "is the study file" in out.err
    code, out = run(study, "-o", MODEL)
    assert code == 2 and "is the model file" in out.err
    code, out = run(study, "-o", tmp_path / "no" / "out.h5")
    assert code == 2 and "cannot write the results file there (no such folder)" in out.err
    write(tmp_path / "x.h5", "not HDF5")
    code, out = run(study, "-o", tmp_path / "x.h5")
    assert code == 2 and "exists and cannot be read" in out.err
    code, out = run("--help")
    assert code == 0 and "--scheduler ADDRESS" in out.out


def test_missing_python_package_or_dask_is_named(tmp_path):
    study = write(tmp_path / "s.yaml", "model: %s\nparameters: {k: [1, 2]}\noutputs: final\n"
                  % MODEL)
    r = sweep(study, env={"MBDAE_PYTHON": str(tmp_path / "no-python")})
    assert r.returncode == 1
    assert "sweep runs in Python: cannot run %s" % (tmp_path / "no-python") in r.stderr
    # an interpreter without numpy (no site-packages): the import failure, named
    wrapper = write(tmp_path / "python-S", "#!/bin/sh\nexec %s -S \"$@\"\n" % sys.executable)
    os.chmod(wrapper, 0o755)
    r = sweep(study, env={"MBDAE_PYTHON": wrapper})
    assert r.returncode == 1
    assert "sweep runs in Python" in r.stderr and "importing it failed" in r.stderr, r.stderr
    # no dask: a module `distributed` that cannot be imported
    fake = tmp_path / "fake"
    fake.mkdir()
    write(fake / "distributed.py", "raise ImportError('No module named distributed')\n")
    r = sweep(study, env={"PYTHONPATH": str(fake)})
    assert r.returncode == 1
    assert "mbdae sweep needs dask and distributed (Debian: apt-get install python3-dask " \
           "python3-distributed)" in r.stderr, r.stderr
    # a program without its package beside it
    lonely = tmp_path / "bin"
    lonely.mkdir()
    shutil.copy(EXE, lonely / "mbdae")
    r = subprocess.run([str(lonely / "mbdae"), "sweep", study], capture_output=True, text=True)
    assert r.returncode == 1
    assert "needs the package mbdae, which is neither in %s/python" % lonely in r.stderr


@pytest.mark.skipif(not os.environ.get("MBDAE_BUILD_DIR"), reason="needs the build tree")
def test_installed_tree_finds_its_package(tmp_path):
    prefix = tmp_path / "prefix"
    subprocess.run([os.environ.get("CMAKE_COMMAND", "cmake"), "--install",
                    os.environ["MBDAE_BUILD_DIR"], "--prefix", str(prefix)], check=True,
                   capture_output=True)
    installed = prefix / "bin" / "mbdae"
    assert (prefix / "lib" / "mbdae" / "python" / "mbdae" / "sweep.py").is_file()
    assert (prefix / "lib" / "mbdae" / "python" / "mbdae" / "libmbdae.so").is_file()
    # the study is checked against the model through the installed package and library
    study = write(tmp_path / "s.yaml", "model: %s\nparameters: {kk: [1, 2]}\noutputs: final\n"
                  % MODEL)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    r = subprocess.run([str(installed), "sweep", str(study)], capture_output=True, text=True,
                       env=env)
    assert r.returncode == 2, r.stderr
    assert "s.yaml:2:14: parameters: 'kk' is neither a parameter" in r.stderr, r.stderr
