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
