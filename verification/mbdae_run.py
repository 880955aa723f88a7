"""Helpers shared by the verification scripts: find and run the mbdae program, read
its results file (the HDF5 layout of the command-line contract).

The program is taken from, in this order: the --mbdae argument of a script, the
environment variable MBDAE, build/mbdae relative to the repository root.
"""
import os
import subprocess
import sys
import tempfile

import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def find_mbdae(explicit=None):
    path = explicit or os.environ.get("MBDAE") or os.path.join(REPO, "build", "mbdae")
    path = os.path.abspath(path)
    if not (os.path.isfile(path) and os.access(path, os.X_OK)):
        sys.exit("mbdae not found at %s (build it, or pass --mbdae PATH, or set MBDAE)" % path)
    return path


def add_mbdae_argument(parser):
    parser.add_argument("--mbdae", default=None,
                        help="path of the mbdae program (default: $MBDAE, else build/mbdae)")
    parser.add_argument("--keep", action="store_true",
                        help="keep the results files (in a temporary folder, printed)")


class RunError(RuntimeError):
    pass


class Runner:
    """Runs `mbdae simulate` into a private temporary folder."""

    def __init__(self, mbdae, keep=False):
        self.mbdae = mbdae
        self.keep = keep
        self.dir = tempfile.mkdtemp(prefix="mbdae-verif-")
        self.count = 0
        if keep:
            print("results files in", self.dir)

    def simulate(self, model, args=(), name=None, check=True):
        """Runs the model with extra command-line settings; returns the results-file path
        and the process (stdout/stderr captured)."""
        self.count += 1
        out = os.path.join(self.dir, "%s-%03d.h5" % (name or "run", self.count))
        cmd = [self.mbdae, "simulate", model, "-o", out, "--quiet"] + [str(a) for a in args]
        proc = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if check and proc.returncode != 0:
            raise RunError("command failed (exit %d): %s\nstdout:\n%s\nstderr:\n%s" % (
                proc.returncode, " ".join(cmd), proc.stdout, proc.stderr))
        return out, proc

    def cleanup(self):
        if not self.keep:
            for f in os.listdir(self.dir):
                os.remove(os.path.join(self.dir, f))
            os.rmdir(self.dir)


class Results:
    """The datasets and root attributes of a results file, loaded into memory."""

    def __init__(self, path):
        import h5py
        with h5py.File(path, "r") as f:
            self.attrs = {k: _plain(v) for k, v in f.attrs.items()}
            self.time = np.array(f["/time"])
            self.data = {}

            def visit(name, obj):
                if isinstance(obj, h5py.Dataset):
                    self.data["/" + name] = np.array(obj)
            f.visititems(visit)

    def __getitem__(self, key):
        if not key.startswith("/"):
            key = "/" + key
        return self.data[key]

    def has(self, key):
        if not key.startswith("/"):
            key = "/" + key
        return key in self.data

    def at(self, key, t, tol=1e-9):
        """The row of a dataset at the output time t (which must be an output time)."""
        k = int(np.argmin(np.abs(self.time - t)))
        if abs(self.time[k] - t) > tol * max(1.0, abs(t)):
            raise RunError("no output at t = %g (nearest %r)" % (t, self.time[k]))
        return self[key][k]

    def cpu_time(self):
        """Process CPU seconds spent in the integrator (without the output rows)."""
        if "solver_cpu_time" not in self.attrs:
            raise RunError("no solver_cpu_time attribute; attributes: %s" % sorted(self.attrs))
        return float(self.attrs["solver_cpu_time"])

    def wall_time(self):
        for k in ("wall_time", "wall_time_s", "wall_seconds"):
            if k in self.attrs:
                return float(self.attrs[k])
        raise RunError("no wall_time attribute; attributes: %s" % sorted(self.attrs))


def _plain(v):
    if isinstance(v, bytes):
        return v.decode()
    if isinstance(v, np.ndarray) and v.size == 1:
        return v.reshape(()).item()
    if isinstance(v, np.generic):
        return v.item()
    return v


def markdown_table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for r in rows:
        lines.append("| " + " | ".join(str(c) for c in r) + " |")
    return "\n".join(lines) + "\n"


def finish_checks(runner, checks, md_lines, out_dir, summary=None):
    """Ends a verification script: appends the table of `checks` ((text, passed) pairs)
    to `md_lines`, writes them to OUT/results.md, prints one line per check, removes the
    runner's temporary files and returns the exit status (0 when every check passed).

    Also writes OUT/summary.json, which the report (verification/report.py) collects:
    {"checks": [{"text", "passed"}], "figures": [...], "csv": [...], ...} with the
    entries of `summary` (a dict: "title", "figures" and "csv" as file names in OUT,
    "headline" a one-line result, "wp" the work-precision rows, or anything else)."""
    import json
    md = list(md_lines) + ["| check | passed |", "|---|---|"]
    md += ["| %s | %s |" % (text, "yes" if c else "NO") for text, c in checks]
    with open(os.path.join(out_dir, "results.md"), "w") as f:
        f.write("\n".join(md) + "\n")
    data = dict(summary or {})
    data["checks"] = [{"text": text, "passed": bool(c)} for text, c in checks]
    with open(os.path.join(out_dir, "summary.json"), "w") as f:
        json.dump(data, f, indent=1, default=float)
        f.write("\n")
    for text, c in checks:
        print(("ok    " if c else "FAIL  ") + text)
    runner.cleanup()
    return 0 if all(c for _, c in checks) else 1
