"""mbdae.sweep on a LocalCluster of 2 worker processes (docs/sweeps.md).

The study: a Monte Carlo of SUNDIALS' slider-crank (verification/slider_crank) with the
spring stiffness k and the damping c uncertain, 200 runs, cut to t_end = 0.5 s (50 HHT steps) with the
HHT integrator so that a run takes milliseconds. Checked:

- run for run, the numbers of the cluster are bitwise those of 200 runs in this process,
  each on a freshly loaded model (final slider position, largest crank speed, the whole
  slider-position series); on a 2 x 3 grid the objective G, dG/dk and dG/dc of the
  cluster are bitwise those of a serial sweep and of Model.gradient in this process, and
  dG/dc agrees with central differences of swept objectives;
- a run made to fail (a NaN damping) is reported with its message, the other 199 are done;
- each worker loads the model once for the whole study;
- killing a worker process in the middle loses no finished run and the study completes
  (its tasks go to the other worker and the restarted one);
- bad requests are refused before anything runs.
"""

import importlib
import os
import signal

import numpy as np
import pytest

import mbdae

sw = importlib.import_module("mbdae.sweep")  # the module (mbdae.sweep is the function)

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
MODEL = os.path.join(ROOT, "verification", "slider_crank", "slider_crank.yaml")
OPTIONS = {"t_end": 0.5, "integrator": "hht", "hht.step": 1e-2, "output_step": 0.01}
OUTPUTS = ["final:xs", "max:wc", "series:xs"]
RUNS = 200
FAILING = 57  # this run gets c = NaN


def samples():
    rng = np.random.default_rng(2026)
    k = rng.normal(1.0, 0.1, RUNS)
    c = rng.uniform(0.5, 1.5, RUNS)
    out = [{"k": float(a), "c": float(b)} for a, b in zip(k, c)]
    out[FAILING]["c"] = float("nan")
    return out


def run_here(sample):
    """One run in this process on a freshly loaded model: set k and c, solve."""
    with mbdae.Model(MODEL) as m:
        for key, value in OPTIONS.items():
            m.options[key] = value
        m.parameters["k"] = sample["k"]
        m.parameters["c"] = sample["c"]
        m.assemble()
        m.solve()
        xs = m.outputs.measure("xs")
        return {"final:xs": xs[-1], "max:wc": np.max(m.outputs.measure("wc")), "series:xs": xs}


@pytest.fixture(scope="module")
def study():
    s = samples()
    return s, [None if i == FAILING else run_here(x) for i, x in enumerate(s)]


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, processes=True, threads_per_worker=1,
                           dashboard_address=None)
    with Client(cluster) as c:
        yield c
    cluster.close()


def check_against(frame, reference, skip=()):
    for i, ref in enumerate(reference):
        if ref is None or i in skip:
            continue
        row = frame.loc[i]
        assert row["status"] == "done", (i, row["message"])
        for key in ("final:xs", "max:wc"):
            assert row[key] == ref[key], (i, key, row[key], ref[key])  # bitwise
        assert np.array_equal(row["series:xs"], ref["series:xs"]), i


def test_monte_carlo_matches_one_process(client, study):
    s, reference = study
    client.run(lambda: sw._stats.update(loads=0, runs=0))
    frame = mbdae.sweep(MODEL, s, OUTPUTS, client, options=OPTIONS)
    assert list(frame.columns) == ["k", "c", "final:xs", "max:wc", "series:xs", "status",
                                   "message", "wall_time", "worker"]
    assert len(frame) == RUNS and frame.index.name == "run"
    assert np.array_equal(frame["k"], [x["k"] for x in s])
    # the failing run: its message, no numbers; the other 199 done
    assert (frame["status"] == "done").sum() == RUNS - 1
    bad = frame.loc[FAILING]
    assert bad["status"] == "failed"
    assert bad["message"] == "parameter 'c': the value must be finite, got nan", bad["message"]
    assert np.isnan(bad["final:xs"]) and bad["series:xs"] is None
    check_against(frame, reference)
    # the numbers are the slider-crank's: the slider within reach of the crank (rod 2,
    # crank 0.5: 0.5 <= x <= 1.5), every run different
    done = frame[frame["status"] == "done"]
    assert ((done["final:xs"] > 0.5) & (done["final:xs"] < 1.5)).all()
    assert done["final:xs"].nunique() == RUNS - 1
    # both workers ran, each loaded the model once
    stats = client.run(sw._worker_stats)
    assert sum(v["runs"] for v in stats.values()) == RUNS
    assert [v["loads"] for v in stats.values()] == [1, 1], stats
    assert frame["worker"].nunique() == 2


def test_killed_worker_loses_no_finished_run(client, study):
    s, reference = study
    pids = client.run(os.getpid)
    victim = sorted(pids.values())[0]
    seen = {}

    def on_result(run, row):
        seen[run] = row
        if len(seen) == 30:
            os.kill(victim, signal.SIGKILL)

    runs = RUNS // 2  # the first 100 samples (the failing run among them)
    frame = mbdae.sweep(MODEL, s[:runs], OUTPUTS, client, options=OPTIONS,
                        on_result=on_result)
    assert len(seen) == runs
    assert (frame["status"] == "done").sum() == runs - 1, \
        frame[frame["status"] != "done"]["message"].tolist()
    check_against(frame, reference[:runs])
    # the runs the killed worker finished before it died are kept, not run again
    killed = [r for r, row in seen.items() if row["worker"].endswith(":%d" % victim)]
    assert killed, "the killed worker had finished no run before the kill"
    for r in killed:
        assert frame.loc[r, "worker"] == seen[r]["worker"]
    # the scheduler restarted the worker (a new process) or gave its tasks to the other
    assert len(client.run(os.getpid)) >= 1


def test_grid_gradients_serial_and_cluster_agree(client):
    grid = {"k": [0.8, 1.2], "c": [0.5, 1.0, 1.5]}
    outputs = ["gradient:G", "final:xs"]
    frame = mbdae.sweep(MODEL, grid, outputs, client, options=OPTIONS)
    serial = mbdae.sweep(MODEL, grid, outputs, "serial", options=OPTIONS)
    assert list(frame["k"]) == [0.8, 0.8, 0.8, 1.2, 1.2, 1.2]  # last name fastest
    assert list(frame["c"]) == [0.5, 1.0, 1.5] * 2
    cols = ["objective:G", "gradient:G:k", "gradient:G:c", "final:xs"]
    assert [c for c in frame.columns if ":" in c] == cols
    assert (frame["status"] == "done").all()
    assert np.array_equal(frame[cols].to_numpy(), serial[cols].to_numpy())
    with mbdae.Model(MODEL) as m:
        for key, value in OPTIONS.items():
            m.options[key] = value
        m.parameters["k"], m.parameters["c"] = 1.2, 1.0
        g = m.gradient(objectives=["G"], wrt=["k", "c"])
    row = frame.loc[4]
    assert row["gradient:G:k"] == g["G"]["k"] and row["gradient:G:c"] == g["G"]["c"]
    assert row["objective:G"] == g.values["G"]
    # the gradient against central differences of the swept objective: dG/dc
    h = 1e-5
    fd = mbdae.sweep(MODEL, [{"k": 1.2, "c": 1.0 + h}, {"k": 1.2, "c": 1.0 - h}],
                     ["objectives"], "serial", options=OPTIONS)
    dc = (fd["objective:G"][0] - fd["objective:G"][1]) / (2 * h)
    assert abs(dc - row["gradient:G:c"]) < 1e-6 * max(1, abs(dc)), (dc, row["gradient:G:c"])


def test_bad_requests_are_refused_before_running():
    with pytest.raises(mbdae.StudyError, match="unknown output 'finl:xs'; did you mean 'final'"):
        mbdae.sweep(MODEL, {"k": [1]}, ["finl:xs"], "serial")
    with pytest.raises(mbdae.StudyError, match="no measure or coordinate 'x'"):
        mbdae.sweep(MODEL, {"k": [1]}, ["final:x"], "serial")
    with pytest.raises(mbdae.StudyError, match="'kk' is neither a parameter .did you mean 'k'"):
        mbdae.sweep(MODEL, {"kk": [1]}, ["objectives"], "serial")
    with pytest.raises(mbdae.StudyError, match="sample 1 sets c, k; sample 0 sets k"):
        mbdae.sweep(MODEL, [{"k": 1}, {"k": 2, "c": 1}], ["objectives"], "serial")
    with pytest.raises(mbdae.StudyError, match="no objective 'H'"):
        mbdae.sweep(MODEL, {"k": [1]}, ["gradient:H"], "serial")
    with pytest.raises(mbdae.StudyError, match="options: t_end"):
        mbdae.sweep(MODEL, {"k": [1]}, ["objectives"], "serial", options={"t_end": -1})


def test_worker_without_the_model_file_loads_the_shipped_text(tmp_path):
    """A worker on another machine: the model's text travels with the task."""
    path = tmp_path / "model.yaml"
    with open(MODEL) as f:
        text = f.read()
    path.write_text(text)
    plan = sw._Plan(str(path), ["k", "c"], [[1.1, 0.7]], ["final:xs"], OPTIONS)
    here = sw._run(plan.spec, plan.values[0])
    sw._local.models.clear()
    path.unlink()  # as on a machine without the file
    shipped = sw._run(plan.spec, plan.values[0])
    assert shipped["status"] == "done", shipped["message"]
    assert shipped["outputs"]["final:xs"] == here["outputs"]["final:xs"]
    # a worker whose file at that path differs: loads the text as well (same numbers)
    sw._local.models.clear()
    path.write_text(text.replace("k: 1 ", "k: 2 "))
    again = sw._run(plan.spec, plan.values[0])
    assert again["outputs"]["final:xs"] == here["outputs"]["final:xs"]
    # a big model (not shipped) missing on the worker: the run says so
    sw._local.models.clear()
    spec = sw._Spec(plan.spec.path, plan.spec.sha256, None, plan.spec.options, plan.names,
                    plan.outputs, plan.wrt, "adjoint", "k")
    path.unlink()
    failed = sw._run(spec, plan.values[0])
    assert failed["status"] == "failed"
    assert "is not on this worker" in failed["message"], failed["message"]
    sw._local.models.clear()
