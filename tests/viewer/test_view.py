"""`mbdae view` (docs/viewer.md): the page in headless Chromium, checked against the results file.

- The pendulum (examples/pendulum.yaml, 2001 rows: drawn every 2nd row) is opened, the
  first frame awaited (window.mbdaeReady), a screenshot taken: the bob's pixels are where
  its position in the results file at that time projects with the page's camera (the
  projection computed here from the camera's position, target, up vector and field of
  view); the plot's curve passes through the measured angle of the results file at 40
  times (within 2 pixels); the cursor is at the current time.
- Moving the slider to the row at t = 0.5 s moves the bob there: its drawn centre equals
  the file's row to 1e-7 m, and its pixels move to the new projection.
- A failed run's file shows its rows up to the failure and says so; a file that is not a
  results file is refused with exit 2.

The browser parts are skipped (with a message) when chromium is not installed
(Debian: apt-get install chromium; scripts/build.sh installs it).
Environment: MBDAE_BIN (the program), MBDAE_EXAMPLES (examples/).
"""
import io
import math
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
from chromium import Browser, find_chromium  # noqa: E402

MBDAE = os.environ.get("MBDAE_BIN", "mbdae")
EXAMPLES = os.environ.get("MBDAE_EXAMPLES", os.path.join(os.path.dirname(__file__), "..", "..", "examples"))
WIDTH, HEIGHT = 1000, 760

needs_chromium = pytest.mark.skipif(find_chromium() is None,
                                    reason="chromium is not installed (apt-get install chromium): "
                                           "the browser checks of the viewer are skipped")


def run(args, cwd):
    return subprocess.run([MBDAE] + args, cwd=cwd, capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def pendulum(tmp_path_factory):
    d = tmp_path_factory.mktemp("pendulum")
    r = run(["simulate", os.path.join(EXAMPLES, "pendulum.yaml"), "-o", str(d / "p.h5"), "--quiet"], d)
    assert r.returncode == 0, r.stderr
    r = run(["view", str(d / "p.h5"), "-o", str(d / "p.html")], d)
    assert r.returncode == 0, r.stderr
    return d


def rgb(png_bytes):
    from PIL import Image
    return np.asarray(Image.open(io.BytesIO(png_bytes)).convert("RGB")).astype(int)


def project(cam, p):
    """Pixel (x, y) of world point p for a perspective camera at cam['position'] looking at
    cam['target'] with cam['up'], vertical field of view cam['fov'] degrees, on the canvas
    rectangle (left, top, width, height)."""
    eye, target, up = (np.array(cam[k], float) for k in ("position", "target", "up"))
    f = target - eye
    f /= np.linalg.norm(f)
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = np.asarray(p, float) - eye
    xc, yc, zc = d @ r, d @ u, d @ f
    t = math.tan(math.radians(cam["fov"]) / 2)
    ndc_x = xc / (zc * t * cam["width"] / cam["height"])
    ndc_y = yc / (zc * t)
    return cam["left"] + (ndc_x + 1) / 2 * cam["width"], cam["top"] + (1 - ndc_y) / 2 * cam["height"]


def orange_fraction(img, x, y, radius):
    """Share of the pixels within `radius` of (x, y) that have the bob's colour (0.85, 0.33,
    0.10) under any shading: red well above green and blue."""
    h, w, _ = img.shape
    ys, xs = np.mgrid[0:h, 0:w]
    disk = (xs - x) ** 2 + (ys - y) ** 2 <= radius ** 2
    px = img[disk]
    orange = (px[:, 0] > 110) & (px[:, 0] - px[:, 2] > 60) & (px[:, 0] - px[:, 1] > 35)
    return orange.mean() if len(px) else 0.0


def row_at(f, t):
    k = int(np.argmin(np.abs(f["time"][:] - t)))
    return k, f["time"][k], f["bodies/bob/position"][k]


@needs_chromium
def test_pendulum_page_draws_the_rows(pendulum):
    f = h5py.File(pendulum / "p.h5", "r")
    with Browser(WIDTH, HEIGHT) as b:
        b.open((pendulum / "p.html").as_uri())
        b.wait_for("window.mbdaeReady === true")
        assert b.evaluate("window.mbdae.frames") == 1001  # 2001 rows, every 2nd drawn
        cam = b.evaluate("window.mbdae.camera()")
        assert b.evaluate("window.mbdae.time()") == 0.0

        # First frame: the bob at its position of the first row.
        img0 = rgb(b.screenshot())
        _, _, p0 = row_at(f, 0.0)
        x0, y0 = project(cam, p0)
        # Radius of the drawn bob in pixels: 0.05 m (1/20 of the model's 1 m) at its distance.
        dist = np.linalg.norm(np.array(cam["position"]) - p0)
        r_px = 0.05 / (dist * math.tan(math.radians(cam["fov"]) / 2)) * cam["height"] / 2
        assert r_px > 6, r_px
        assert orange_fraction(img0, x0, y0, 0.5 * r_px) > 0.9

        # The slider to the row at t = 0.5 s (drawn row 250 = file row 500).
        k, t, p1 = row_at(f, 0.5)
        assert k == 500
        b.evaluate("(() => { const s = document.getElementById('slider'); s.value = 250;"
                   " s.dispatchEvent(new Event('input')); })()")
        assert b.evaluate("window.mbdae.time()") == pytest.approx(t, abs=1e-12)
        drawn = np.array(b.evaluate("window.mbdae.bodyPosition('bob')"))
        assert np.max(np.abs(drawn - p1)) < 1e-7, (drawn, p1)
        assert np.linalg.norm(p1 - p0) > 0.5  # it did move
        b.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        img1 = rgb(b.screenshot())
        x1, y1 = project(cam, p1)
        assert orange_fraction(img1, x1, y1, 0.5 * r_px) > 0.9
        assert orange_fraction(img1, x0, y0, 0.5 * r_px) < 0.1  # gone from the first place

        # setTime goes to the nearest drawn row: t = 1.2345 -> 1.234 (a drawn row, every 2 ms).
        assert b.evaluate("window.mbdae.setTime(1.2345)") == pytest.approx(1.234, abs=1e-12)

        # The plot: the measure `angle` against t, through the file's values.
        assert b.evaluate("window.mbdae.selectPlot('measure angle')")
        b.evaluate("window.mbdae.setTime(0.5)")
        img2 = rgb(b.screenshot())
        plot = b.evaluate("window.mbdae.plot()")
        assert plot["name"] == "measure angle"
        times, angle = f["time"][:], f["measures/angle"][:]
        hits = 0
        samples = np.linspace(0.02, 1.98, 40)
        for ts in samples:
            j = int(np.argmin(np.abs(times - ts)))
            px = plot["left"] + (times[j] - plot["x0"]) / (plot["x1"] - plot["x0"]) * (plot["right"] - plot["left"])
            py = plot["bottom"] - (angle[j] - plot["y0"]) / (plot["y1"] - plot["y0"]) * (plot["bottom"] - plot["top"])
            patch = img2[int(round(py)) - 2:int(round(py)) + 3, int(round(px)) - 2:int(round(px)) + 3]
            blue = (patch[..., 2] > 120) & (patch[..., 2] - patch[..., 0] > 50)
            hits += bool(blue.any())
        assert hits >= 38, f"{hits} of {len(samples)} points of the angle curve drawn where expected"
        # The same check against a wrong curve (the angle shifted by a quarter of the
        # range) mostly fails: the check can tell curves apart.
        wrong = 0
        for ts in samples:
            j = int(np.argmin(np.abs(times - ts)))
            px = plot["left"] + (times[j] - plot["x0"]) / (plot["x1"] - plot["x0"]) * (plot["right"] - plot["left"])
            py = plot["bottom"] - (angle[j] - plot["y0"]) / (plot["y1"] - plot["y0"]) * (plot["bottom"] - plot["top"])
            py += 0.25 * (plot["bottom"] - plot["top"])
            patch = img2[int(round(py)) - 2:int(round(py)) + 3, int(round(px)) - 2:int(round(px)) + 3]
            wrong += bool(((patch[..., 2] > 120) & (patch[..., 2] - patch[..., 0] > 50)).any())
        assert wrong < 15, wrong
        # The cursor (red) at t = 0.5.
        cx = int(round(plot["cursor"]))
        assert abs(plot["cursor"] - (plot["left"] + 0.25 * (plot["right"] - plot["left"]))) < 1.0
        column = img2[int(plot["top"]) + 20:int(plot["bottom"]) - 2, cx - 1:cx + 2]
        red = (column[..., 0] > 150) & (column[..., 1] < 110) & (column[..., 2] < 110)
        assert red.any(axis=1).mean() > 0.8
        assert not b.console, b.console


def test_failed_run_and_not_a_results_file(tmp_path):
    # A run that fails (an unreachable tolerance): exit 3, status failed, rows kept.
    r = run(["simulate", os.path.join(EXAMPLES, "pendulum.yaml"), "-o", str(tmp_path / "failed.h5"),
             "--integrator", "hht", "--adaptive", "--tolerance", "1e-30", "--quiet"], tmp_path)
    assert r.returncode == 3, r.stderr
    with h5py.File(tmp_path / "failed.h5", "r") as f:
        assert f.attrs["status"] == "failed"
        rows = len(f["time"])
        reason = f.attrs["failure_reason"]
    r = run(["view", str(tmp_path / "failed.h5")], tmp_path)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "failed.html").read_text()
    assert '"status":"failed"' in page and f'"rows_total":{rows},' in page

    # Not a results file: the model (YAML), and an HDF5 file without /time.
    r = run(["view", os.path.join(EXAMPLES, "pendulum.yaml"), "-o", str(tmp_path / "x.html")], tmp_path)
    assert r.returncode == 2
    assert "not a results file" in r.stderr and "pendulum.yaml" in r.stderr
    assert not (tmp_path / "x.html").exists()
    with h5py.File(tmp_path / "other.h5", "w") as f:
        f["data"] = np.zeros(3)
    r = run(["view", str(tmp_path / "other.h5")], tmp_path)
    assert r.returncode == 2 and "without the dataset /time" in r.stderr
    r = run(["view", str(tmp_path / "missing.h5")], tmp_path)
    assert r.returncode == 2 and "missing.h5" in r.stderr
    r = run(["view"], tmp_path)
    assert r.returncode == 2 and "usage" in r.stderr

    if find_chromium() is None:
        pytest.skip("chromium is not installed: the failed run's page is not opened")
    with Browser(WIDTH, HEIGHT) as b:
        b.open((tmp_path / "failed.html").as_uri())
        b.wait_for("window.mbdaeReady === true")
        s = b.evaluate("window.mbdae.status()")
        assert s["status"] == "failed" and s["rows"] == rows
        assert "failed at t = " in s["banner"] and f"its {rows} rows up to the failure" in s["banner"]
        assert reason[:20] in s["banner"]


def test_geometry_group_places_the_markers(pendulum):
    """/geometry alone places the pivot: position + R(e) p_pivot is at the origin in every row."""
    with h5py.File(pendulum / "p.h5", "r") as f:
        g = f["geometry"]
        names = list(g["marker_names"].asstr()[:])
        p = g["marker_position"][names.index("bob.pivot")]
        assert list(g["shape_kind"].asstr()[:]) == ["ellipsoid", "cylinder"]
        assert np.allclose(g["shape_size"][0], [0.05, 0.05, 0.05], atol=1e-15)  # a point mass: a sphere of L/20
        pos, e = f["bodies/bob/position"][:], f["bodies/bob/orientation"][:]
        e0, e1, e2, e3 = e.T
        R = np.array([[e0*e0 + e1*e1 - e2*e2 - e3*e3, 2*(e1*e2 - e0*e3), 2*(e1*e3 + e0*e2)],
                      [2*(e1*e2 + e0*e3), e0*e0 - e1*e1 + e2*e2 - e3*e3, 2*(e2*e3 - e0*e1)],
                      [2*(e1*e3 - e0*e2), 2*(e2*e3 + e0*e1), e0*e0 - e1*e1 - e2*e2 + e3*e3]])
        pivot = pos + np.einsum("ijk,j->ki", R, p)
        assert np.max(np.abs(pivot)) < 1e-8
        assert list(g["joint_names"].asstr()[:]) == ["pivot"]
        assert names[g["joint_markers"][0][0]] == "bob.pivot" and names[g["joint_markers"][0][1]] == "ground.O"


def test_mesh_geometry_in_the_results_file_and_the_page(tmp_path):
    """A body whose geometry is a mesh (tests/mbs/models/mesh_body.yaml: box.obj, a 2 x 1 x
    0.5 box centred at (1, 2, 3), scaled by 0.1): /geometry holds its triangles, placed so
    that the box is centred on the body's centre of mass; the page carries them."""
    model = os.path.join(os.path.dirname(__file__), "..", "mbs", "models", "mesh_body.yaml")
    r = run(["simulate", model, "-o", str(tmp_path / "m.h5"), "--t-end", "0.01", "--quiet"], tmp_path)
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "m.h5", "r") as f:
        g = f["geometry"]
        assert list(g["shape_kind"].asstr()[:]) == ["mesh", "mesh"]
        assert list(g["shape_mesh"][:]) == [0, 1]
        v = g["meshes/0/vertices"][:] + g["shape_position"][0]
        assert np.allclose(v.min(axis=0), [-0.1, -0.05, -0.025], atol=1e-14)
        assert np.allclose(v.max(axis=0), [0.1, 0.05, 0.025], atol=1e-14)
        assert g["meshes/0/triangles"].shape == (12, 3)  # 6 quads, fan-triangulated
        assert g["shape_size"][1][0] == 1.0  # the unscaled one: scale 1
    r = run(["view", str(tmp_path / "m.h5")], tmp_path)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "m.html").read_text()
    assert '"meshes":[{"v":[' in page and page.count('"kind":"mesh"') == 2


def test_names_cannot_end_the_pages_script(tmp_path):
    """A model name holding "</script>" is written into the page's data as "<\\/script>":
    the page keeps exactly the script tags of its template."""
    model = open(os.path.join(EXAMPLES, "pendulum.yaml")).read()
    assert "\nname: pendulum\n" in model
    (tmp_path / "m.yaml").write_text(model.replace("\nname: pendulum\n",
                                                   '\nname: "a</script><b>\\"quoted\\""\n'))
    r = run(["simulate", "m.yaml", "-o", "m.h5", "--t-end", "0.01", "--quiet"], tmp_path)
    assert r.returncode == 0, r.stderr
    r = run(["view", "m.h5", "-o", "m.html"], tmp_path)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "m.html").read_text()
    assert '"a<\\/script><b>\\"quoted\\""' in page
    plain = tmp_path / "plain.html"
    r = run(["simulate", os.path.join(EXAMPLES, "pendulum.yaml"), "-o", "p.h5", "--t-end", "0.01",
             "--quiet"], tmp_path)
    assert r.returncode == 0, r.stderr
    r = run(["view", "p.h5", "-o", str(plain)], tmp_path)
    assert r.returncode == 0, r.stderr
    assert page.count("</script>") == plain.read_text().count("</script>")
