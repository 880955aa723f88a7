"""The viewer's screenshots in docs/: the pendulum, Andrews' squeezer and the IFToMM A02
N-four-bar, each simulated, written with `mbdae view` and photographed in headless
Chromium (tests/viewer/chromium.py) at a chosen time with a chosen plot.

    /usr/bin/python3 viewer/screenshots.py --mbdae build/mbdae --out docs
"""
import argparse
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, os.path.join(ROOT, "tests", "viewer"))
from chromium import Browser  # noqa: E402

# name, model, extra simulate options, time shown, plot, joint frames
SHOTS = [
    ("pendulum", "examples/pendulum.yaml", [], 0.6, "measure angle", False),
    ("andrews", "verification/andrews/andrews.yaml", [], 0.012, "measure beta", True),
    ("nfourbar", "verification/nfourbar/nfourbar.yaml", ["--t-end", "5"], 0.45, "measure yB0", False),
]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mbdae", default=os.path.join(ROOT, "build", "mbdae"))
    p.add_argument("--out", default=os.path.join(ROOT, "docs"))
    p.add_argument("--only", nargs="*")
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for name, model, extra, t, plot, frames in SHOTS:
            if a.only and name not in a.only:
                continue
            h5, html = os.path.join(tmp, name + ".h5"), os.path.join(tmp, name + ".html")
            subprocess.run([a.mbdae, "simulate", os.path.join(ROOT, model), "-o", h5, "--quiet"] + extra, check=True)
            subprocess.run([a.mbdae, "view", h5, "-o", html], check=True)
            with Browser(1000, 700) as b:
                b.open("file://" + html)
                b.wait_for("window.mbdaeReady === true", timeout=120)
                assert b.evaluate(f"window.mbdae.selectPlot({plot!r})"), plot
                b.evaluate(f"window.mbdae.setTime({t})")
                if frames:
                    b.evaluate("window.mbdae.setJointFrames(true)")
                b.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
                png = b.screenshot()
            out = os.path.join(a.out, f"viewer-{name}.png")
            with open(out, "wb") as f:
                f.write(png)
            print(out, len(png), "bytes")


if __name__ == "__main__":
    main()
