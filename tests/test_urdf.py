"""The URDF the code generator writes from the model (generated/uavarm_arm.urdf): valid for
urdfdom's check_urdf, and its forward kinematics, computed here from the XML alone (origins
and axes composed with numpy, Rodrigues' rotation), lands the end effector where the
generated C's kin_fk_ee does, to 1 um, on random joint vectors; the limits are the model's."""
from __future__ import annotations

import math
import os
import shutil
import subprocess
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from conftest import ROOT
from uavarm.model import config

URDF = ROOT / "generated" / "uavarm_arm.urdf"


def rotation(axis, angle):
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def chain(root):
    """The joints from uav_frame to end_effector, in order."""
    by_child = {j.find("child").get("link"): j for j in root.iter("joint")}
    joints, link = [], "end_effector"
    while link in by_child:
        j = by_child[link]
        joints.append(j)
        link = j.find("parent").get("link")
    assert link == "uav_frame"
    return joints[::-1]


def fk(root, q):
    """End effector in arm_base's frame (m), joints taken in order of the chain."""
    R, p, angles = np.eye(3), np.zeros(3), iter(q)
    for j in chain(root)[1:]:                                    # from arm_base on
        origin = j.find("origin")
        assert origin.get("rpy") in (None, "0 0 0")
        p = p + R @ np.array([float(v) for v in origin.get("xyz").split()])
        if j.get("type") == "revolute":
            R = R @ rotation([float(v) for v in j.find("axis").get("xyz").split()], next(angles))
    return p


def test_check_urdf_accepts_it():
    if shutil.which("check_urdf") is None:
        if os.environ.get("CI"):
            pytest.fail("check_urdf missing in CI: .ci/run must install liburdfdom-tools")
        pytest.skip("check_urdf not installed (apt-get install liburdfdom-tools)")
    out = subprocess.run(["check_urdf", str(URDF)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "Successfully Parsed XML" in out.stdout, out.stdout + out.stderr


def test_urdf_kinematics_match_the_generated_c(gen):
    ffi, lib = gen
    m = config.load()
    root = ET.parse(URDF).getroot()
    rng = np.random.default_rng(7)
    lo = np.radians([l.min_deg for l in m.limits])
    hi = np.radians([l.max_deg for l in m.limits])
    out = ffi.new("float[3]")
    worst = 0.0
    for q in rng.uniform(lo, hi, (500, 3)):
        lib.kin_fk_ee([float(v) for v in q], out)
        worst = max(worst, np.abs(fk(root, q) * 1000 - np.array(list(out))).max())
    assert worst <= 1e-3                                          # mm: 1 um
    mount = next(j for j in root.iter("joint") if j.get("name") == "arm_mount")
    assert [float(v) * 1000 for v in mount.find("origin").get("xyz").split()] == pytest.approx(m.mount_offset)


def test_urdf_limits_are_the_models():
    m = config.load()
    root = ET.parse(URDF).getroot()
    revolute = [j for j in chain(root) if j.get("type") == "revolute"]
    assert len(revolute) == 3
    for j, lim in zip(revolute, m.limits):
        limit = j.find("limit")
        assert math.degrees(float(limit.get("lower"))) == pytest.approx(lim.min_deg, abs=1e-6)
        assert math.degrees(float(limit.get("upper"))) == pytest.approx(lim.max_deg, abs=1e-6)


def test_the_ros_node_names_the_urdfs_joints():
    from uavarm.link.ros_node import JOINT_NAMES
    root = ET.parse(URDF).getroot()
    assert [j.get("name") for j in chain(root) if j.get("type") == "revolute"] == list(JOINT_NAMES)


# ------------------------------------------------------------------ inertials (no Gazebo here)

MOVING = ("arm_turret", "upper_arm", "forearm")


def inertial(root, link):
    el = root.find(f"link[@name='{link}']/inertial")
    assert el is not None, f"{link}: no inertial"
    i = {k: float(v) for k, v in el.find("inertia").attrib.items()}
    tensor = np.array([[i["ixx"], i["ixy"], i["ixz"]], [i["ixy"], i["iyy"], i["iyz"]], [i["ixz"], i["iyz"], i["izz"]]])
    centre = np.array([float(v) for v in el.find("origin").get("xyz").split()])
    return float(el.find("mass").get("value")), centre, tensor


def test_every_link_that_moves_has_a_physical_inertial_and_a_collision_shape():
    """What a simulator's dynamics needs (checked here without one: no Gazebo is run): each
    link a joint moves has a positive mass and an inertia tensor that a rigid body can have
    (positive definite; each principal moment at most the sum of the other two), and a
    collision shape. urdfdom parses it (test_check_urdf_accepts_it)."""
    root = ET.parse(URDF).getroot()
    for link in ("arm_base",) + MOVING:
        kg, _, tensor = inertial(root, link)
        moments = np.linalg.eigvalsh(tensor)
        assert kg > 0 and moments.min() > 0, (link, kg, moments)
        a, b, c = moments
        assert a <= b + c and b <= a + c and c <= a + b, (link, moments)
        assert root.findall(f"link[@name='{link}']/collision"), f"{link}: no collision shape"
    assert root.find("link[@name='uav_frame']/inertial") is None   # KDL takes no inertia on the root


def test_the_inertials_are_the_model_files_masses():
    """Masses and centres from the model file read here with tomllib (grams, mm from each
    link's joint); each inertia against a sampled cloud of the solids the URDF's comment names
    (an AX-12A a 32 x 50 x 40 mm box, brackets a rod of the link's length and 10 mm radius, the
    tool a 15 mm ball), to 2 %."""
    import tomllib
    raw = tomllib.loads((ROOT / "model" / "manipulator.toml").read_text())
    ms, geo = raw["masses"], raw["geometry"]
    g, mm = (lambda v: v / 1000), (lambda v: v / 1000)
    rng = np.random.default_rng(3)
    n = 400_000

    def box(kg, centre):
        return kg, centre + rng.uniform(-0.5, 0.5, (n, 3)) * [0.032, 0.050, 0.040]

    def rod(kg, length, centre):
        r, t = 0.010 * np.sqrt(rng.uniform(0, 1, n)), rng.uniform(0, 2 * math.pi, n)
        return kg, centre + np.c_[r * np.cos(t), r * np.sin(t), rng.uniform(-length / 2, length / 2, n)]

    def ball(kg, centre):
        v = rng.normal(size=(n, 3))
        v *= (0.015 * rng.uniform(0, 1, n) ** (1 / 3) / np.linalg.norm(v, axis=1))[:, None]
        return kg, centre + v

    down = lambda d: np.array([0.0, 0.0, -d])
    servo = g(ms["servo"])
    parts = {
        "arm_turret": [box(servo, down(mm(geo["L1"])))],
        "upper_arm": [rod(g(ms["upper_arm"]), mm(geo["L2"]), down(mm(ms["upper_arm_com"]))),
                      box(servo, down(mm(geo["L2"])))],
        "forearm": [rod(g(ms["forearm"]), mm(geo["L3"]), down(mm(ms["forearm_com"]))),
                    ball(g(ms["end_effector"]), down(mm(ms["end_effector_com"])))],
    }
    root = ET.parse(URDF).getroot()
    for link, cloud in parts.items():
        kg, centre, tensor = inertial(root, link)
        total = sum(k for k, _ in cloud)
        com = sum(k * pts.mean(axis=0) for k, pts in cloud) / total
        want = np.zeros((3, 3))
        for k, pts in cloud:
            d = pts - com
            want += k * ((d * d).sum(axis=1).mean() * np.eye(3) - (d[:, :, None] * d[:, None, :]).mean(axis=0))
        assert kg == pytest.approx(total, rel=1e-5)
        assert np.abs(centre - com).max() < 2e-4, (link, centre, com)
        assert np.abs(tensor - want).max() <= 0.02 * np.abs(want).max(), (link, tensor, want)
