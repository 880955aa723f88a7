#!/usr/bin/env python3
"""Mutation fuzzing of the model loaders (YAML and FreeDyn .fds) through the program.

Each mutated file is a copy of one of the repository's models (examples/, tests/,
verification/, papers/; models that name other files, such as meshes, data files or
user-force libraries, are left out) with one to three random edits: a number replaced
by an extreme or invalid value (1e308, 1e-320, nan, .inf, sqrt(-1), 1/0, ...), a line
deleted, duplicated, swapped or re-indented, the file cut short, YAML punctuation or a
random byte inserted, a name replaced by another name of the file, deep brackets.
Only seed models that pass `mbdae check` unchanged are used. Every file is run twice:

    mbdae check FILE
    mbdae simulate FILE --integrator hht --fixed-step --step 0.005 --t-end 0.01
                        --output-step 0.005 -o OUT.h5 --quiet

A run fails the fuzzing when it is killed by a signal (a crash, an abort, a sanitizer
report with its exit code), exits with a code other than 0, 2 or 3 (1 is "anything
else": an error the program did not classify), exits 2 or 3 without
"mbdae: error: " on stderr, or takes longer than --timeout seconds (a parser hang).
Failing inputs are copied to --out with the command and its output.

The mutations come from one random.Random(--seed): the same seed and count give the
same files, so a failure is reproduced by rerunning with the same arguments.

    python3 tests/fuzz/fuzz_loaders.py --mbdae build/mbdae --count 1500 --seed 11
"""
import argparse
import os
import random
import re
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# Values that a number may be replaced with: extremes, non-finite text, expressions that
# evaluate to NaN or infinity, things that are not numbers at all.
VALUES = [
    "0", "-0", "-1", "1", "3", "1e308", "-1e308", "1e309", "1e-308", "5e-324", "1e-320",
    "1e200", "1e-200", "1e-12", "1e-13", "1e12", "nan", "NaN", ".nan", "inf", "-inf",
    ".inf", "-.inf", "99999999999999999999999999", "0x10", "1e", "--1", "+-2", "1..2",
    "sqrt(-1)", "1/0", "0/0", "log(0)", "exp(1000)", "acos(2)", "pow(0, -1)",
    "step(t, 1, 0, 0, 1)", "atan2(0, 0)", "t", "pi", "'1'", "\"2\"", "[]", "{}", "~",
    "null", "true", "(1", "1)", "((((((((((1))))))))))", "-" * 200 + "1", "2^2^2^2^2^2",
]
PUNCTUATION = list("[]{}:,-#&*!|>'\"%@?`\t") + [": ", "- ", "\n", "  ", "{", "[["]
NUMBER = re.compile(r"(?<![A-Za-z_\d.])[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?(?![A-Za-z_\d])")
NAME = re.compile(r"[A-Za-z_][A-Za-z_0-9]*")


def seeds():
    """The repository's model files that stand alone (they name no other file)."""
    out = []
    for top in ("examples", "tests", "verification", "papers"):
        for folder, dirs, files in os.walk(os.path.join(ROOT, top)):
            dirs.sort()
            for f in sorted(files):
                if not (f.endswith(".yaml") or f.endswith(".fds")):
                    continue
                path = os.path.join(folder, f)
                try:
                    text = open(path, encoding="utf-8").read()
                except (UnicodeDecodeError, OSError):
                    continue
                if f.endswith(".yaml") and not re.search(r"^format:", text, re.M):
                    continue  # not a model file (problem files, settings, ...)
                if re.search(r"\bfile\b|library|FileName|\.csv|\.stl|\.obj", text, re.I):
                    continue
                if len(text) > 20000:
                    continue
                out.append(path)
    return out


def mutate(text, rng):
    """One random edit of text."""
    kind = rng.randrange(10)
    lines = text.split("\n")
    if kind == 0 or kind == 1:  # a number replaced (twice as likely as the others)
        numbers = list(NUMBER.finditer(text))
        if numbers:
            m = rng.choice(numbers)
            return text[:m.start()] + rng.choice(VALUES) + text[m.end():]
    if kind == 2 and len(lines) > 1:  # a line deleted
        del lines[rng.randrange(len(lines))]
        return "\n".join(lines)
    if kind == 3:  # a line duplicated
        k = rng.randrange(len(lines))
        lines.insert(k, lines[k])
        return "\n".join(lines)
    if kind == 4 and len(lines) > 1:  # two lines swapped
        a, b = rng.randrange(len(lines)), rng.randrange(len(lines))
        lines[a], lines[b] = lines[b], lines[a]
        return "\n".join(lines)
    if kind == 5:  # a line re-indented
        k = rng.randrange(len(lines))
        lines[k] = " " * rng.choice([0, 1, 2, 3, 4, 8]) + lines[k].lstrip()
        return "\n".join(lines)
    if kind == 6 and text:  # the file cut short
        return text[:rng.randrange(len(text))]
    if kind == 7:  # punctuation or a random byte inserted
        at = rng.randrange(len(text) + 1)
        piece = rng.choice(PUNCTUATION) if rng.random() < 0.7 else chr(rng.randrange(1, 256))
        return text[:at] + piece + text[at:]
    if kind == 8:  # a name replaced by another name of the file
        names = list(NAME.finditer(text))
        if len(names) > 1:
            m = rng.choice(names)
            return text[:m.start()] + rng.choice(names).group(0) + text[m.end():]
    if kind == 9:  # deep nesting
        at = rng.randrange(len(text) + 1)
        depth = rng.choice([10, 65, 200, 5000])
        piece = rng.choice(["[" * depth, "{a: " * depth, "(" * depth + "1" + ")" * depth, "- " * depth])
        return text[:at] + piece + text[at:]
    # Fall back to a byte flip.
    if not text:
        return "x"
    at = rng.randrange(len(text))
    return text[:at] + chr(rng.randrange(1, 128)) + text[at + 1:]


def run(cmd, cwd, timeout):
    start = time.monotonic()
    try:
        p = subprocess.run(cmd, cwd=cwd, capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, "", "", time.monotonic() - start
    return (p.returncode, p.stdout.decode("utf-8", "replace"), p.stderr.decode("utf-8", "replace"),
            time.monotonic() - start)


def verdict(code, err):
    """'' if the run ended as the program promises, else why not."""
    if code is None:
        return "timeout"
    if code < 0:
        return "killed by signal %d" % -code
    if code not in (0, 2, 3):
        return "exit code %d" % code
    if code != 0 and "mbdae: error: " not in err:
        return "exit code %d without 'mbdae: error: '" % code
    return ""


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mbdae", required=True, help="the mbdae program")
    ap.add_argument("--count", type=int, default=100, help="mutated files (default 100)")
    ap.add_argument("--seed", type=int, default=20261124, help="random seed")
    ap.add_argument("--timeout", type=float, default=20.0, help="seconds per run before it counts as a hang")
    ap.add_argument("--out", default=None, help="folder for failing inputs (default: a temporary folder)")
    args = ap.parse_args()

    args.mbdae = os.path.abspath(args.mbdae)  # the runs happen in a temporary folder
    rng = random.Random(args.seed)
    models = seeds()
    if not models:
        print("fuzz: no seed models found under", ROOT)
        return 1
    # Only models that pass `mbdae check` as they are: a mutation of a valid model
    # reaches further into the loader (and into the run) than one of a refused model.
    models = [m for m in models if run([args.mbdae, "check", m], ROOT, args.timeout)[0] == 0]
    fds_models = [m for m in models if m.endswith(".fds")]
    yaml_models = [m for m in models if not m.endswith(".fds")]
    work = tempfile.mkdtemp(prefix="mbdae-fuzz-")
    out = args.out or os.path.join(work, "failures")
    failures = []
    codes = {}
    runs = 0
    kinds = {"yaml": 0, "fds": 0}
    slowest = (0.0, "")
    start = time.monotonic()
    try:
        for n in range(args.count):
            # A third of the files from the FreeDyn seeds (there are few of them).
            pool = fds_models if fds_models and rng.random() < 1 / 3 else yaml_models
            seed_path = pool[rng.randrange(len(pool))]
            ext = os.path.splitext(seed_path)[1]
            text = open(seed_path, encoding="utf-8").read()
            for _ in range(rng.choice([1, 1, 2, 3])):
                text = mutate(text, rng)
            name = "m%05d%s" % (n, ext)
            path = os.path.join(work, name)
            with open(path, "w", encoding="utf-8", errors="surrogateescape") as f:
                f.write(text)
            kinds[ext[1:]] += 1
            commands = [
                [args.mbdae, "check", name],
                [args.mbdae, "simulate", name, "--integrator", "hht", "--fixed-step", "--step", "0.005",
                 "--t-end", "0.01", "--output-step", "0.005", "-o", "m%05d.h5" % n, "--quiet"],
            ]
            for cmd in commands:
                code, stdout, stderr, seconds = run(cmd, work, args.timeout)
                runs += 1
                codes[code] = codes.get(code, 0) + 1
                if seconds > slowest[0]:
                    slowest = (seconds, " ".join(cmd[1:3]) + " (from " + os.path.relpath(seed_path, ROOT) + ")")
                why = verdict(code, stderr)
                if why:
                    os.makedirs(out, exist_ok=True)
                    shutil.copy(path, os.path.join(out, name))
                    with open(os.path.join(out, name + ".txt"), "w") as f:
                        f.write("seed model: %s\ncommand: %s\nverdict: %s\nstdout:\n%s\nstderr:\n%s\n" %
                                (seed_path, " ".join(cmd), why, stdout, stderr))
                    failures.append("%s: %s: %s (from %s)" % (name, cmd[1], why, os.path.relpath(seed_path, ROOT)))
            h5 = os.path.join(work, "m%05d.h5" % n)
            if os.path.exists(h5):
                os.remove(h5)
            os.remove(path)
    finally:
        elapsed = time.monotonic() - start
    print("fuzz: %d mutated files (%d YAML, %d .fds) from %d seed models (%d .fds), %d runs in %.1f s, seed %d" %
          (args.count, kinds["yaml"], kinds["fds"], len(models), len(fds_models), runs, elapsed, args.seed))
    print("fuzz: exit codes " + ", ".join("%s: %d" % (k, v) for k, v in sorted(codes.items(), key=lambda kv: str(kv[0]))))
    print("fuzz: slowest run %.2f s: %s" % slowest)
    if failures:
        print("fuzz: %d failing runs (inputs in %s):" % (len(failures), out))
        for f in failures:
            print("  " + f)
        return 1
    shutil.rmtree(work, ignore_errors=True)
    print("fuzz: no crash, no hang, every refusal with 'mbdae: error: '")
    return 0


if __name__ == "__main__":
    sys.exit(main())
