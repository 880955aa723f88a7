"""URDF import (mbs/urdf.cc) through the program: what each element becomes, the
refused files (exit 2, the element named, nothing written), convert and simulate.

Run by CTest (tests/urdf/CMakeLists.txt); by hand:
    MBDAE=build/mbdae /usr/bin/python3 -m pytest tests/urdf/test_urdf_import.py
"""

import json
import math
import os
import shutil
import subprocess

import h5py
import numpy as np
import pytest
import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
MBDAE = os.environ.get("MBDAE", os.path.join(ROOT, "build", "mbdae"))
UR20 = os.path.join(ROOT, "examples", "urdf_arm", "ur20.urdf")


def run(*args, cwd=None):
    return subprocess.run([MBDAE, *args], cwd=cwd, capture_output=True, text=True, timeout=120)


INERTIAL = ('<inertial><origin xyz="{x}" rpy="{rpy}"/><mass value="{m}"/>'
            '<inertia ixx="{ixx}" ixy="{ixy}" ixz="{ixz}" iyy="{iyy}" iyz="{iyz}" izz="{izz}"/></inertial>')


def link(name, m=1.0, x="0 0 0", rpy="0 0 0", ixx=0.01, iyy=0.01, izz=0.01, ixy=0, ixz=0, iyz=0):
    if m is None:
        return f'<link name="{name}"/>'
    return (f'<link name="{name}">' + INERTIAL.format(x=x, rpy=rpy, m=m, ixx=ixx, iyy=iyy, izz=izz, ixy=ixy,
                                                      ixz=ixz, iyz=iyz) + '</link>')


def joint(name, parent, child, kind="continuous", xyz="0 0 0", rpy="0 0 0", axis="0 0 1", extra=""):
    limit = '<limit lower="-1" upper="1" effort="10" velocity="2"/>' if kind in ("revolute", "prismatic") else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
            f'<origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>{limit}{extra}</joint>')


def robot(*elements):
    return '<?xml version="1.0"?>\n<robot name="r">\n' + "\n".join(elements) + "\n</robot>\n"


def write(tmp_path, text, name="robot.urdf"):
    path = tmp_path / name
    path.write_text(text)
    return str(path)


# ---- refused files ------------------------------------------------------------------------------

BAD = {
    # name: (urdf, line of the element, element, text of the reason)
    "missing_parent": (robot(link("base", None), link("arm"), joint("j1", "nowhere", "arm")),
                       5, "joint 'j1'", "its parent link 'nowhere' does not exist"),
    "two_parents": (robot(link("base", None), link("a"), link("b"), joint("j1", "base", "a"),
                          joint("j2", "a", "b"), joint("j3", "b", "a")),
                    8, "joint 'j3'", "link 'a' is already the child of joint 'j1'"),
    "cycle": (robot(link("a"), link("b"), link("c"), joint("ja", "c", "a"), joint("jb", "a", "b"),
                    joint("jc", "b", "c")),
              None, "joint 'j", "the joints form a cycle"),
    "zero_mass_with_children": (robot(link("base", None), link("a", None), link("b"), joint("j1", "base", "a"),
                                      joint("j2", "a", "b")),
                                4, "link 'a'", "zero mass with children"),
    "zero_axis": (robot(link("base", None), link("a"), joint("j1", "base", "a", axis="0 0 0")),
                  5, "joint 'j1'", "the axis [0, 0, 0] has zero length"),
}


@pytest.mark.parametrize("case", sorted(BAD))
@pytest.mark.parametrize("command", ["convert", "simulate", "check"])
def test_bad_urdf_exit_2_naming_the_element(tmp_path, case, command):
    text, line, element, reason = BAD[case]
    write(tmp_path, text)
    args = [command, "robot.urdf"] + (["-o", "robot.yaml"] if command == "convert" else []) + ["--quiet"]
    r = run(*args, cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    where = f"robot.urdf:{line}:" if line else "robot.urdf:"
    assert where in r.stderr and element in r.stderr and reason in r.stderr, r.stderr
    # Nothing written: only the URDF is in the folder.
    assert sorted(os.listdir(tmp_path)) == ["robot.urdf"]


def test_massless_leaf_on_a_movable_joint_is_refused(tmp_path):
    write(tmp_path, robot(link("base", None), link("a"), link("tool", None), joint("j1", "base", "a"),
                          joint("j2", "a", "tool")))
    r = run("check", "robot.urdf", cwd=tmp_path)
    assert r.returncode == 2
    assert "link 'tool': zero mass on the continuous joint 'j2'" in r.stderr


# ---- what the elements become ------------------------------------------------------------------


def info(path, *extra):
    r = run("info", path, "--json", *extra)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def converted(tmp_path, path, *extra):
    out = str(tmp_path / "converted.yaml")
    r = run("convert", path, "-o", out, "--quiet", *extra)
    assert r.returncode == 0, r.stderr
    with open(out) as f:
        return yaml.safe_load(f), out


def rotation(e):
    e0, e1, e2, e3 = e
    return np.array([[e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3, 2 * (e1 * e2 - e0 * e3), 2 * (e1 * e3 + e0 * e2)],
                     [2 * (e1 * e2 + e0 * e3), e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3, 2 * (e2 * e3 - e0 * e1)],
                     [2 * (e1 * e3 - e0 * e2), 2 * (e2 * e3 + e0 * e1), e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3]])


def rpy_matrix(r, p, y):
    cx, sx, cy, sy, cz, sz = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_inertia_rotated_to_principal_axes(tmp_path):
    # A tensor with products in an inertial frame turned by rpy, on a link turned by the joint
    # origin's rpy: the body's R diag(I) R^T is the tensor in world axes, and its centre of
    # mass the inertial origin.
    J = np.array([[0.30, 0.02, -0.05], [0.02, 0.25, 0.01], [-0.05, 0.01, 0.12]])
    rpy_i, rpy_j = (0.3, -0.2, 0.5), (0.1, 0.4, -0.7)
    x_i, x_j = np.array([0.1, -0.05, 0.2]), np.array([0.5, 0.0, 1.0])
    text = robot(link("base", None),
                 link("a", m=3.0, x=" ".join(map(str, x_i)), rpy=" ".join(map(str, rpy_i)), ixx=J[0, 0],
                      iyy=J[1, 1], izz=J[2, 2], ixy=J[0, 1], ixz=J[0, 2], iyz=J[1, 2]),
                 joint("j1", "base", "a", xyz=" ".join(map(str, x_j)), rpy=" ".join(map(str, rpy_j))))
    m, _ = converted(tmp_path, write(tmp_path, text))
    body = m["bodies"][0]
    assert body["name"] == "a" and body["mass"] == 3.0
    R = rotation(body["orientation"])
    I = np.diag(body["inertia"])
    R_wl = rpy_matrix(*rpy_j)
    R_wi = R_wl @ rpy_matrix(*rpy_i)
    expected = R_wi @ J @ R_wi.T
    assert np.abs(R @ I @ R.T - expected).max() < 1e-14
    assert np.abs(np.array(body["position"]) - (x_j + R_wl @ x_i)).max() < 1e-15
    # The principal axes stay next to the inertial frame's (the largest diagonal entries).
    assert np.all(np.abs(np.diag(R_wi.T @ R)) > 0.9)


def test_joint_types_limits_and_merged_links(tmp_path):
    text = robot(link("base", None), link("turn"), link("slide"), link("plate"), link("weld"), link("cam", None),
                 link("free"),
                 joint("j_rev", "base", "turn", "revolute", axis="0 1 0"),
                 joint("j_pri", "turn", "slide", "prismatic", axis="1 0 0"),
                 joint("j_pla", "slide", "plate", "planar", axis="0 0 1"),
                 joint("j_fix", "plate", "weld", "fixed"),
                 joint("j_cam", "weld", "cam", "fixed", xyz="0 0 0.1"),
                 joint("j_flo", "weld", "free", "floating"))
    path = write(tmp_path, text)
    i = info(path)
    assert i["bodies"] == ["turn", "slide", "plate", "weld", "free"]
    assert i["joints"] == ["j_rev", "j_pri", "j_pla", "j_fix"]
    # 1 + 1 + 3 + 0 + 6 (floating)
    assert i["counts"]["degrees_of_freedom"] == 11
    assert any("link 'cam' has no mass: merged into 'weld'" in n and "weld.cam" in n for n in i["notes"])
    assert any("joint 'j_flo' (floating)" in n for n in i["notes"])
    m, out = converted(tmp_path, path)
    types = {j["name"]: j["type"] for j in m["joints"]}
    assert types == {"j_rev": "revolute", "j_pri": "prismatic", "j_pla": "planar", "j_fix": "fixed"}
    rev = next(j for j in m["joints"] if j["name"] == "j_rev")
    assert rev["limits"] == {"lower": -1, "upper": 1, "effort": 10, "velocity": 2}
    # The converted file is a model of its own: the same counts.
    assert info(out)["counts"] == i["counts"]


def test_floating_base(tmp_path):
    text = robot(link("base", m=5.0), link("arm"), joint("j1", "base", "arm"))
    path = write(tmp_path, text)
    assert info(path)["counts"]["degrees_of_freedom"] == 1
    assert info(path, "--floating-base")["counts"]["degrees_of_freedom"] == 7
    # A massless root cannot float.
    write(tmp_path, robot(link("base", None), link("arm"), joint("j1", "base", "arm")), "massless.urdf")
    r = run("check", "massless.urdf", "--floating-base", cwd=tmp_path)
    assert r.returncode == 2 and "link 'base': the root link has no mass" in r.stderr


def test_mimic_joint_is_a_gear(tmp_path):
    # The second joint mimics the first: q2 = 2 q1 + 0.1 along a falling motion.
    text = robot(link("base", None), link("a", x="0.3 0 0"), link("b", x="0.2 0 0"),
                 joint("j1", "base", "a", axis="0 1 0"),
                 joint("j2", "a", "b", xyz="0.6 0 0", axis="0 1 0",
                       extra='<mimic joint="j1" multiplier="2" offset="0.1"/>'))
    path = write(tmp_path, text)
    i = info(path)
    assert "j2_mimic" in i["joints"] and i["counts"]["degrees_of_freedom"] == 1
    r = run("simulate", path, "-o", str(tmp_path / "r.h5"), "--t-end", "0.5", "--quiet")
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "r.h5") as f:
        q1, q2 = f["measures/j1_q"][:], f["measures/j2_q"][:]
    assert abs(q2[0] - 0.1) < 1e-12 and abs(q1[0]) < 1e-12
    assert abs(q1[-1]) > 0.3  # it fell
    assert np.abs(q2 - (2 * q1 + 0.1)).max() < 1e-9


def test_ur20_structure():
    i = info(UR20)
    assert i["name"] == "ur20"
    assert i["bodies"] == [f"link_{k}" for k in range(1, 7)]
    assert i["joints"] == [f"joint_{k}" for k in range(1, 7)]
    assert i["counts"]["degrees_of_freedom"] == 6
    assert any("link 'flange' has no mass: merged into 'link_6'" in n for n in i["notes"])


def test_free_fall_agrees_with_the_model_written_by_hand(tmp_path):
    # double_pendulum.yaml is double_pendulum.urdf written by hand (other marker axes, the
    # angles as expressions): the same equations, so the runs agree to rounding (measured
    # 2.4e-13 m over 1 s).
    for name in ("double_pendulum.urdf", "double_pendulum.yaml"):
        shutil.copy(os.path.join(HERE, "models", name), tmp_path)
    runs = {}
    for name in ("double_pendulum.urdf", "double_pendulum.yaml"):
        out = str(tmp_path / (name.replace(".", "_") + ".h5"))
        assert run("simulate", name, "-o", out, "--quiet", cwd=tmp_path).returncode == 0
        with h5py.File(out) as f:
            runs[name] = (f["q"][:], f["q_names"][:])
    (qu, nu), (qy, ny) = runs["double_pendulum.urdf"], runs["double_pendulum.yaml"]
    assert list(nu) == list(ny)
    assert np.abs(qu[-1] - qu[0]).max() > 0.1  # it moved
    assert np.abs(qu - qy).max() < 1e-10


def test_ur20_convert_and_simulate_agree(tmp_path):
    # The converted file (numbers with 15-17 digits, Euler parameters renormalised) against
    # the URDF itself: the same free fall to the integrator's rounding.
    _, out = converted(tmp_path, UR20)
    runs = []
    for path in (UR20, out):
        h5 = str(tmp_path / f"run{len(runs)}.h5")
        r = run("simulate", path, "-o", h5, "--t-end", "0.5", "--quiet")
        assert r.returncode == 0, r.stderr
        with h5py.File(h5) as f:
            runs.append(f["q"][:])
    assert np.abs(runs[0][-1] - runs[0][0]).max() > 0.1
    assert np.abs(runs[0] - runs[1]).max() < 1e-9


# ---- extends: and modify: ----------------------------------------------------------------------

EXTENDED = """format: 1
extends: robot.urdf
modify:
  bodies:
    arm: {mass: 2.5, markers: {tip: {position: [0.4, 0, 0]}}}
  joints:
    j1: {limits: {effort: 7}}
measures:
  - {name: q, type: rotational, i: arm.j1, j: ground.j1, axis: z}
joints:
  - {name: drive, type: motion, measure: q, value: "0.5 * t"}
forces:
  - {name: load, type: force, i: arm.tip, value: [0, 0, -1]}
simulation: {t_end: 0.2, output_step: 0.1}
"""


def test_extends_adds_and_modifies_by_name(tmp_path):
    write(tmp_path, robot(link("base", None), link("arm", x="0.2 0 0"), joint("j1", "base", "arm", axis="0 1 0")))
    ext = write(tmp_path, EXTENDED, "driven.yaml")
    i = info(ext)
    assert i["joints"] == ["j1", "drive"] and i["forces"] == ["load"] and i["counts"]["degrees_of_freedom"] == 0
    m, _ = converted(tmp_path, ext)
    arm = m["bodies"][0]
    assert arm["mass"] == 2.5 and arm["markers"]["tip"]["position"] == [0.4, 0, 0]
    assert m["joints"][0]["limits"] == {"effort": 7, "velocity": 0}
    r = run("simulate", ext, "-o", str(tmp_path / "d.h5"), "--quiet")
    assert r.returncode == 0, r.stderr
    with h5py.File(tmp_path / "d.h5") as f:
        assert abs(f["measures/q"][-1] - 0.1) < 1e-9


@pytest.mark.parametrize("change,where,message", [
    ("modify:\n  bodies:\n    armm: {mass: 1}\n", "driven.yaml:5:5:",
     "modify: no body 'armm' in the extended model; did you mean 'arm'?"),
    ("modify:\n  joints:\n    j2: {limits: {effort: 1}}\n", "driven.yaml:5:5:", "modify: no joint 'j2'"),
    ("modify:\n  bodies:\n    arm: {position: [0, 0, 0]}\n", "driven.yaml:5:11:", "body 'arm': unknown key 'position'"),
])
def test_modify_of_a_missing_name_is_refused(tmp_path, change, where, message):
    write(tmp_path, robot(link("base", None), link("arm", x="0.2 0 0"), joint("j1", "base", "arm", axis="0 1 0")))
    write(tmp_path, "format: 1\nextends: robot.urdf\n" + change, "driven.yaml")
    r = run("check", "driven.yaml", cwd=tmp_path)
    assert r.returncode == 2 and where in r.stderr and message in r.stderr, r.stderr


def test_extends_cycle_and_modify_without_extends(tmp_path):
    write(tmp_path, "format: 1\nextends: b.yaml\n", "a.yaml")
    write(tmp_path, "format: 1\nextends: a.yaml\n", "b.yaml")
    r = run("check", "a.yaml", cwd=tmp_path)
    assert r.returncode == 2 and "extends this file again (a cycle)" in r.stderr
    write(tmp_path, "format: 1\nmodify: {}\n", "c.yaml")
    r = run("check", "c.yaml", cwd=tmp_path)
    assert r.returncode == 2 and "c.yaml:2:1: model: 'modify' changes elements of the model named by 'extends'" in r.stderr


def test_ur20_driven_example(tmp_path):
    # examples/urdf_arm/ur20_driven.yaml: every joint driven, kinematic analysis; the drive
    # torques equal the inverse dynamics of the joint motion (reaction measures vs effort).
    path = os.path.join(ROOT, "examples", "urdf_arm", "ur20_driven.yaml")
    out = str(tmp_path / "d.h5")
    r = run("simulate", path, "-o", out, "--quiet")
    assert r.returncode == 0, r.stderr
    with h5py.File(out) as f:
        q1 = f["measures/q1"][:]
        assert abs(q1[-1] - 1.2) < 1e-12
        assert np.abs(f["joints/drive_2/effort"][:]).max() > 100  # the shoulder holds the arm
        # Joint space in the rows: positions and rates equal the angle measures, and the
        # generalized force of each joint the effort of its drive (measured 1.5e-11 N m of
        # 507 N m).
        for k in range(1, 7):
            g = f["joints/joint_%d" % k]
            assert np.abs(g["position"][:] - f["measures/q%d" % k][:]).max() < 1e-14
            effort = f["joints/drive_%d/effort" % k][:]
            assert np.abs(g["generalized_force"][:] - effort).max() < 1e-10 * max(1.0, np.abs(effort).max())
        assert np.abs(f["joints/joint_2/rate"][:] - f["measures/w2"][:]).max() < 1e-12


def test_joint_space_rows_of_a_fall(tmp_path):
    # A free fall: nothing drives the joints, so they transmit nothing about their axes
    # (measured 3e-10 N m); the angles are continuous.
    text = robot(link("base", None), link("wheel", x="0.3 0 0"), joint("spin", "base", "wheel", axis="0 1 0"))
    path = write(tmp_path, text)
    out = str(tmp_path / "f.h5")
    r = run("simulate", path, "-o", out, "--t-end", "3", "--quiet")
    assert r.returncode == 0, r.stderr
    with h5py.File(out) as f:
        g = f["joints/spin"]
        q, qd, tau = g["position"][:], g["rate"][:], g["generalized_force"][:]
        assert np.abs(tau).max() < 1e-8
        assert np.all(np.abs(np.diff(q)) < 1.0)  # continuous: no jump of 2 pi
        assert np.abs(q).max() > 2.5  # from horizontal it swings to near the other side


def test_visuals_become_the_bodies_shapes(tmp_path):
    # A box visual turned and moved on a link whose inertial frame is moved: the shape's pose
    # in body axes from the centre of mass; a cylinder on the root goes to the ground; an
    # unreadable mesh is a note.
    visual = ('<visual><origin xyz="0.1 0 0" rpy="0 0 1.5707963267948966"/><geometry><box size="0.2 0.1 0.05"/>'
              '</geometry><material name="red"><color rgba="1 0 0 1"/></material></visual>'
              '<visual><geometry><mesh filename="package://nowhere/arm.dae"/></geometry></visual>')
    text = robot('<link name="base"><visual><geometry><cylinder radius="0.1" length="0.3"/></geometry></visual>'
                 '</link>',
                 link("arm", x="0.05 0 0").replace("</link>", visual + "</link>"),
                 joint("j1", "base", "arm", xyz="0 0 1"))
    path = write(tmp_path, text)
    m, _ = converted(tmp_path, path)
    shapes = m["bodies"][0]["visual"]
    shapes = shapes if isinstance(shapes, list) else [shapes]
    assert len(shapes) == 1
    box = shapes[0]
    assert box["shape"] == "box" and box["size"] == [0.2, 0.1, 0.05]
    assert np.abs(np.array(box["position"]) - [0.05, 0, 0]).max() < 1e-15
    assert box["color"][:3] == [1, 0, 0]
    ground = m["ground"]["visual"]
    ground = ground if isinstance(ground, list) else [ground]
    assert ground[0]["shape"] == "cylinder" and ground[0]["radius"] == 0.1
    assert any("arm.dae" in n for n in info(path)["notes"])


def test_joint_rates_and_accelerations_against_closed_form(tmp_path):
    # A revolute joint carrying a prismatic one, both driven in closed form: the rows'
    # position, rate and acceleration against the derivatives of the driving functions
    # (the per-joint formulas of JointSpace::RowValues; kinematic analysis, exact rows).
    write(tmp_path, robot(link("base", None), link("arm", x="0.2 0 0"), link("slider", x="0 0 0.1"),
                          joint("turn", "base", "arm", axis="0 0 1"),
                          joint("slide", "arm", "slider", "prismatic", xyz="0.5 0 0", axis="1 0 0")))
    write(tmp_path, """format: 1
extends: robot.urdf
measures:
  - {name: a, type: rotational, i: arm.turn, j: ground.turn, axis: z}
  - {name: s, type: translational, i: slider.slide, j: arm.slide, component: z}
joints:
  - {name: drive_a, type: motion, measure: a, value: "0.7 * sin(2 * t) + 2 * t"}
  - {name: drive_s, type: motion, measure: s, value: "0.1 * t^2 - 0.05 * t^3"}
simulation: {t_end: 2.0, output_step: 0.05, integrator: kinematic}
""", "driven.yaml")
    out = str(tmp_path / "d.h5")
    r = run("simulate", "driven.yaml", "-o", out, "--quiet", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    with h5py.File(out) as f:
        t = f["time"][:]
        ja, js = f["joints/turn"], f["joints/slide"]
        a = 0.7 * np.sin(2 * t) + 2 * t  # passes pi: the position counts turns
        assert np.abs(ja["position"][:] - a).max() < 1e-10
        assert np.abs(ja["rate"][:] - (1.4 * np.cos(2 * t) + 2)).max() < 1e-10
        assert np.abs(ja["acceleration"][:] - (-2.8 * np.sin(2 * t))).max() < 1e-9
        assert np.abs(js["position"][:] - (0.1 * t**2 - 0.05 * t**3)).max() < 1e-12
        assert np.abs(js["rate"][:] - (0.2 * t - 0.15 * t**2)).max() < 1e-10
        assert np.abs(js["acceleration"][:] - (0.2 - 0.3 * t)).max() < 1e-9
        # The generalized forces are the drives' efforts.
        for j, d in (("turn", "drive_a"), ("slide", "drive_s")):
            e = f["joints/%s/effort" % d][:]
            assert np.abs(f["joints/%s/generalized_force" % j][:] - e).max() < 1e-9 * max(1, np.abs(e).max())


def ur20_by_hand():
    """The UR20 written directly as a model file from its DH and dynamics table, without
    the URDF or the importer: body k in DH frame k at the zero pose (standard DH,
    frame k = frame k-1 Rz(q_k) Tz(d_k) Tx(a_k) Rx(alpha_k), frame 0 the world), its
    centre of mass and inertia tensor as published in that frame, joint k at the origin
    of frame k-1 about its z axis. The table is the one examples/urdf_arm/make_ur20_urdf.py
    cites (Universal Robots' DH parameters article), typed in again here."""
    a = [0, -0.8620, -0.7287, 0, 0, 0]
    d = [0.2363, 0, 0, 0.2010, 0.1593, 0.1543]
    alpha = [np.pi / 2, 0, 0, np.pi / 2, -np.pi / 2, 0]
    mass = [16.343, 29.632, 7.879, 3.054, 3.126, 0.846]
    com = [[0, -0.0610, 0.0062], [0.5226, 0, 0.2098], [0.3234, 0, 0.0604],
           [0, -0.0026, 0.0393], [0, 0.0024, 0.0379], [0, -0.0003, -0.0318]]
    # Ixx, Iyy, Izz, Ixy, Ixz, Iyz (tensor elements, kg m^2)
    inertia = [[0.0887, 0.0763, 0.0842, -0.0001, -0.0001, 0.0072],
               [0.1467, 4.6659, 4.6348, 0.0002, -0.0516, 0.0],
               [0.0261, 0.7576, 0.7533, -0.0001, -0.0290, 0.0],
               [0.0056, 0.0054, 0.0040, 0.0, 0.0, 0.0004],
               [0.0059, 0.0058, 0.0043, 0.0, 0.0, -0.0004],
               [0.0009, 0.0009, 0.0012, 0.0, 0.0, 0.0]]
    R, p = [np.eye(3)], [np.zeros(3)]  # frames 0..6 at the zero pose
    for k in range(6):
        ca, sa = np.cos(alpha[k]), np.sin(alpha[k])
        Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
        p.append(p[k] + R[k] @ np.array([a[k], 0, d[k]]))
        R.append(R[k] @ Rx)
    num = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"  # noqa: E731
    mat = lambda m: "[" + ", ".join(num(r) for r in m) + "]"  # noqa: E731
    lines = ["format: 1", "name: ur20 by hand", "gravity: [0, 0, -9.81]", "bodies:"]
    for k in range(1, 7):
        c = p[k] + R[k] @ np.array(com[k - 1])  # centre of mass, world
        lines += ["  - name: link_%d" % k,
                  "    mass: %r" % mass[k - 1],
                  "    inertia: " + num(inertia[k - 1]),
                  "    position: " + num(c),
                  "    orientation: {matrix: %s}" % mat(R[k]),
                  "    markers:",
                  # joint k: the origin and axes of frame k-1; joint k+1 on this body: frame k's
                  "      J%d: {position: %s, orientation: {matrix: %s}}"
                  % (k, num(R[k].T @ (p[k - 1] - c)), mat(R[k].T @ R[k - 1])),
                  "      J%d: {position: %s}" % (k + 1, num(-np.array(com[k - 1])))]
    lines.append("joints:")
    for k in range(1, 7):
        j = "ground.O" if k == 1 else "link_%d.J%d" % (k - 1, k)
        lines.append("  - {name: joint_%d, type: revolute, i: link_%d.J%d, j: %s}" % (k, k, k, j))
    return "\n".join(lines) + "\n"


def test_ur20_free_fall_agrees_with_the_arm_written_by_hand(tmp_path):
    # The same arm in other body axes (the importer's principal axes against the DH frames)
    # and other markers: the centres of mass of a 0.6 s fall from the stretched zero pose,
    # both runs IDA rtol = atol = 1e-10, agree to the integrator's tolerance (measured
    # 1.8e-9 m while the bodies move up to 1.56 m; one product of inertia of link_2 with
    # the wrong sign in the hand-written file: 3.9e-3 m).
    (tmp_path / "hand.yaml").write_text(ur20_by_hand())
    shutil.copy(UR20, tmp_path)
    runs = {}
    for name in ("ur20.urdf", "hand.yaml"):
        out = str(tmp_path / (name.replace(".", "_") + ".h5"))
        p = run("simulate", name, "-o", out, "--integrator", "ida", "--rtol", "1e-10", "--atol", "1e-10",
                "--t-end", "0.6", "--output-step", "0.01", "--quiet", cwd=tmp_path)
        assert p.returncode == 0, p.stderr
        with h5py.File(out) as f:
            runs[name] = np.stack([f["bodies/link_%d/position" % k][:] for k in range(1, 7)], axis=1)
    u, h = runs["ur20.urdf"], runs["hand.yaml"]
    assert u.shape == h.shape == (61, 6, 3)
    assert np.abs(u[0] - h[0]).max() < 1e-12  # the same pose at t = 0
    assert np.abs(u[-1] - u[0]).max() > 0.5   # it fell (the stretched arm's tip drops)
    assert np.abs(u - h).max() < 1e-7
