"""The ROS package as catkin builds it: ros/uavarm_ros copied into a fresh catkin workspace,
`catkin_make` with Debian's catkin and the system Python (as on the robot, no virtualenv),
its messages and services generated for Python and C++, catkin_lint clean; then the arm
brought up from that workspace alone (`roslaunch uavarm_ros arm.launch` on a SITL's port, the
system Python without the toolchain): joint states, TF, services. The node's code is Python
3.8 (Noetic's) by vermin's reading, and runs under a 3.8 interpreter where one is installed.

Oracles: catkin's own build and generators, roslib's message loading, the genpy classes
the node builds at run time (same definition, same MD5), ROS's own tools (rostopic,
rosservice, tf2), vermin."""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import ROOT, SYSTEM_ENV, catkin_workspace, free_port, once_per_run, stop_group
from uavarm.sim.sitl import Sitl

pytestmark = pytest.mark.realtime   # a simulated board in real time: a stage of its own (Makefile)

PACKAGE = ROOT / "ros" / "uavarm_ros"
CLEAN_ENV = SYSTEM_ENV


@pytest.fixture(scope="module")
def workspace(tmp_path_factory):
    return Path(once_per_run(tmp_path_factory, "catkin_ws", lambda folder: str(catkin_workspace(folder))))


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


@pytest.fixture(scope="module")
def launched(workspace, tmp_path_factory):
    """roscore, a SITL (this process) and `roslaunch uavarm_ros arm.launch` from the workspace:
    (workspace, environment for ROS tools there)."""
    home = tmp_path_factory.mktemp("ros_home")
    env = dict(CLEAN_ENV, ROS_MASTER_URI=f"http://127.0.0.1:{free_port()}", ROS_HOME=str(home),
               ROS_LOG_DIR=str(home / "log"), ROS_IP="127.0.0.1", PYTHONUNBUFFERED="1")
    sitl = Sitl(speed=1.0).start()
    port = env["ROS_MASTER_URI"].rsplit(":", 1)[1]
    procs = []
    try:
        for command, log, up in ((f"roscore -p {port}", "roscore.out", "rosparam get /rosdistro"),
                                 (f"roslaunch uavarm_ros arm.launch port:={sitl.device} uav_name:=uav1", "launch.out",
                                  "rosservice list")):
            with open(home / log, "w") as out:
                procs.append(subprocess.Popen(["bash", "-c", f"source devel/setup.bash && exec {command}"],
                                              cwd=workspace, env=env, start_new_session=True, stdout=out,
                                              stderr=subprocess.STDOUT))
            in_workspace(workspace, up, env, until_ok=True)       # the master, then the node's services
        out = in_workspace(workspace, "rosservice list", env, wait_for="/uav1/arm/enable")
        assert "/uav1/arm/enable" in out.stdout, (home / "launch.out").read_text()[-3000:]
        yield workspace, env, home
    finally:
        for proc in reversed(procs):
            stop_group(proc)
        sitl.stop()


def in_workspace(ws, command: str, env=None, wait_for: str | None = None, until_ok: bool = False) -> subprocess.CompletedProcess:
    """`command` in the workspace's environment; with wait_for (or until_ok), repeated (up to
    60 s) until its output shows that text (or it succeeds)."""
    end = time.monotonic() + 60
    while True:
        out = subprocess.run(["bash", "-c", f"source devel/setup.bash && {command}"], cwd=ws, env=env or CLEAN_ENV,
                             capture_output=True, text=True, timeout=120)
        done = (wait_for is None or wait_for in out.stdout) and (not until_ok or out.returncode == 0)
        if done or time.monotonic() > end:
            return out
        time.sleep(1.0)          # (asks again until the node answers; 60 s: a hang guard)


def test_the_workspace_alone_brings_the_arm_up(launched):
    """From the built workspace and the system Python (no toolchain: `import uavarm` fails
    there): the goals of the disabled arm, then its joint states once enabled, with the URDF's
    joint names, the end effector in TF below the drone's
    body frame (MRS's uav1/fcu, the launch file's default parent), and the services answering
    (enable taken)."""
    ws, env, home = launched
    log = lambda: (home / "launch.out").read_text()[-3000:]          # noqa: E731
    out = in_workspace(ws, "/usr/bin/python3 -c 'import uavarm'", env)
    assert out.returncode != 0 and "No module named 'uavarm'" in out.stderr
    out = in_workspace(ws, "rostopic echo -n 1 /uav1/arm/goal_joint_states", env, wait_for="arm_joint1")
    assert all(f"arm_joint{j}" in out.stdout for j in (1, 2, 3)), out.stdout + out.stderr + log()
    out = in_workspace(ws, "rosservice call /uav1/arm/enable true", env)
    assert "success: True" in out.stdout, out.stdout + out.stderr + log()
    out = in_workspace(ws, "rostopic echo -n 1 /uav1/joint_states", env, wait_for="arm_joint1")   # the shafts, read
    assert all(f"arm_joint{j}" in out.stdout for j in (1, 2, 3)), out.stdout + out.stderr + log()
    tf = ("import rospy, tf2_ros; rospy.init_node('tf_check', anonymous=True); b = tf2_ros.Buffer(); "
          "tf2_ros.TransformListener(b); t = b.lookup_transform('uav1/fcu', 'end_effector', rospy.Time(0), "
          "rospy.Duration(20)).transform.translation; print('EE', t.x, t.y, t.z)")
    out = in_workspace(ws, f'/usr/bin/python3 -c "{tf}"', env)
    assert out.returncode == 0 and out.stdout.startswith("EE"), out.stdout + out.stderr + log()
    x, y, z = map(float, out.stdout.split()[1:4])
    assert z < -0.05 and (x * x + y * y) ** 0.5 < 0.3, (x, y, z)     # below the drone, within the arm's reach


LINK_PACKAGE = ROOT / "ros" / "uavarm_ros" / "src" / "uavarm_link"


def test_the_node_is_python_3_8():
    """vermin: no syntax, module or call newer than 3.8 in the node's package; and, where a 3.8
    interpreter is installed, the codec and the framing round-trip a heartbeat under it."""
    vermin = "import sys; from vermin import main; sys.exit(main())"
    out = subprocess.run([sys.executable, "-c", vermin, "-t=3.8-", "--no-tips", "--violations", str(LINK_PACKAGE)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    found = sorted(Path("/root/.pyenv/versions").glob("3.8.*/bin/python")) + sorted(Path("/usr/bin").glob("python3.8"))
    python38 = found[0] if found else None
    if python38 is None:
        return
    check = ("import sys; sys.path.insert(0, sys.argv[1]); from uavarm_link import llcp, messages; "
             "p = messages.encode('ping', seq=7, stamp_us=9); f = llcp.encode(p); "
             "d = llcp.Decoder(gap=0.1, expected_len=lambda i: messages.BY_ID[i].size); "
             "assert [messages.decode(x) for x in d.feed(f, 0.0)] == [('ping', {'seq': 7, 'stamp_us': 9})]; "
             "print(sys.version_info[:2])")
    out = subprocess.run([str(python38), "-c", check, str(LINK_PACKAGE.parent)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "(3, 8)" in out.stdout, out.stdout + out.stderr



def test_the_docs_list_the_debian_packages_ci_installs():
    """docs/ros.md's `apt-get install` line names exactly the ROS 1 packages .ci/run installs
    (the loop over Debian packages there)."""
    import re
    ci = (ROOT / ".ci" / "run").read_text()
    loop = re.search(r"for pkg in (.*?); do", ci, re.S)
    assert loop is not None, ".ci/run: no `for pkg in ...; do` loop"
    ci_packages = set(loop.group(1).replace("\\\n", " ").split())
    docs = (ROOT / "docs" / "ros.md").read_text()
    install = re.search(r"apt-get install (.*?)\n\n", docs, re.S)
    assert install is not None, "docs/ros.md: no apt-get install line"
    doc_packages = set(install.group(1).replace("\\\n", " ").split())
    assert doc_packages == ci_packages, (f"only in docs/ros.md: {sorted(doc_packages - ci_packages)}; "
                                         f"only in .ci/run: {sorted(ci_packages - doc_packages)}")
