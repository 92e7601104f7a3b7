"""The ROS package as catkin builds it: ros/uavarm_ros copied into a fresh catkin workspace,
`catkin_make` with Debian's catkin and the system Python (as on the robot, no virtualenv),
its messages and services generated for Python and C++, and catkin_lint clean.

Oracles: catkin's own build and generators, roslib's message loading, and the genpy classes
the node builds at run time (same definition, same MD5)."""
from __future__ import annotations

import os
import shutil
import subprocess

import pytest

from conftest import ROOT, require_catkin

PACKAGE = ROOT / "ros" / "uavarm_ros"
CLEAN_ENV = {"PATH": "/usr/bin:/bin", "HOME": os.environ.get("HOME", "/root")}


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    require_catkin()
    ws = tmp_path_factory.mktemp("catkin_ws")
    shutil.copytree(PACKAGE, ws / "src" / "uavarm_ros")
    out = subprocess.run(["catkin_make", "-DPYTHON_EXECUTABLE=/usr/bin/python3"], cwd=ws, env=CLEAN_ENV,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return ws


def in_workspace(ws, command: str) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", f"source devel/setup.bash && {command}"], cwd=ws, env=CLEAN_ENV,
                          capture_output=True, text=True, timeout=120)


def test_catkin_builds_the_messages_and_services_for_python_and_cpp(workspace):
    assert (workspace / "devel" / "include" / "uavarm_ros" / "ArmStatus.h").exists()
    assert (workspace / "devel" / "include" / "uavarm_ros" / "SetPosition.h").exists()
    out = in_workspace(workspace, "rossrv show uavarm_ros/SetPosition && rosmsg show uavarm_ros/ArmStatus")
    assert out.returncode == 0, out.stderr
    assert "float64 x" in out.stdout and "bool success" in out.stdout and "uint16 seq" in out.stdout


def test_the_catkin_classes_are_the_ones_the_node_builds(workspace, tmp_path):
    """Same definitions: the MD5 sums ROS compares on every connection agree."""
    out = in_workspace(workspace, "/usr/bin/python3 -c 'from uavarm_ros.msg import ArmStatus; "
                                  "from uavarm_ros.srv import SetPosition; print(ArmStatus._md5sum, SetPosition._md5sum)'")
    assert out.returncode == 0, out.stderr
    from uavarm.link import ros_node
    msg, srv = ros_node.load_interfaces(PACKAGE, tmp_path / "genpy")
    assert out.stdout.split() == [msg.ArmStatus._md5sum, srv.SetPosition._md5sum]


def test_catkin_lint_finds_nothing(workspace):
    out = subprocess.run(["catkin_lint", "-W2", "--strict", str(workspace / "src" / "uavarm_ros")], env=CLEAN_ENV,
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0 and "found 0 problems" in out.stdout + out.stderr, out.stdout + out.stderr
