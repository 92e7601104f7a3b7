"""The ROS 1 node (uavarm.link.ros_node) end to end: a real roscore on a free port, the simulated
board behind a pseudo-terminal (SITL, in this process so its servo power and the frames it
receives can be checked), the node started by `roslaunch uavarm_ros arm.launch` from a fresh
catkin workspace with the system Python (as on the robot: no virtualenv, catkin's message
classes), and its services driven with rospy service proxies. The node keeps the wall clock
(a process of its own), so the SITL runs in real time and the tests wait for what the
board's statuses and the services' answers say, in simulated seconds, never for a time."""
import math
import os
import queue
import subprocess
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from conftest import SYSTEM_ENV, catkin_workspace, free_port, require_ros, stop_group
from oracles import FK_TOL_MM, arm_points
from uavarm.link import llcp, messages
from uavarm.link.arm_core import level_point, level_velocity
from uavarm.link.ros_node import ATTITUDE_TYPES, roll_pitch
from uavarm.model import config
from uavarm.sim.sitl import Sitl

SPEED = 1.0                          # simulated seconds per real second: the node's own pace
TARGET_M = (0.060, 0.020, -0.120)
# simulated s: the bound of a wait that ends at the first status saying what a command or
# event did (a heartbeat every 0.5 s: a hang guard, ten times the few heartbeats it takes)
ANY_STATUS_S = 20.0
pytestmark = [pytest.mark.filterwarnings("ignore:notifyAll:DeprecationWarning"),   # rospy's own
              pytest.mark.realtime]   # a simulated board in real time: a stage of its own (Makefile)


# ------------------------------------------------------------------ without ROS

def test_roll_pitch_of_quaternions_match_scipy():
    rng = np.random.default_rng(7)
    rot = Rotation.random(2000, random_state=rng)
    scale = rng.uniform(0.2, 5.0, 2000)              # not normalised: the node normalises
    want = rot.as_euler("ZYX")                        # yaw, pitch, roll of Rz Ry Rx
    got = np.array([roll_pitch(*(q * s)) for q, s in zip(rot.as_quat(), scale)])
    assert np.abs(got[:, 0] - want[:, 2]).max() < 1e-9
    assert np.abs(got[:, 1] - want[:, 1]).max() < 1e-9
    with pytest.raises(ValueError, match="quaternion"):
        roll_pitch(0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="quaternion"):
        roll_pitch(math.nan, 0.0, 0.0, 1.0)



def test_level_velocity_matches_scipy():
    """The odometry's velocity in the gravity-aligned, heading-following frame: from the child
    (body) frame turned by the attitude, or from the parent frame, then back by the yaw."""
    rng = np.random.default_rng(8)
    rot = Rotation.random(500, random_state=rng)
    v = rng.normal(0.0, 3.0, (500, 3))
    yaw = rot.as_euler("ZYX")[:, 0]
    unyaw = Rotation.from_euler("Z", -yaw[:, None])
    from_body = np.array([level_velocity(tuple(q * 2.0), tuple(u), True) for q, u in zip(rot.as_quat(), v)])
    from_parent = np.array([level_velocity(tuple(q), tuple(u), False) for q, u in zip(rot.as_quat(), v)])
    assert np.abs(from_body - unyaw.apply(rot.apply(v))).max() < 1e-9
    assert np.abs(from_parent - unyaw.apply(v)).max() < 1e-9
    with pytest.raises(ValueError, match="quaternion"):
        level_velocity((0.0, 0.0, 0.0, 0.0), (1.0, 0.0, 0.0), True)


def test_level_point_matches_scipy():
    """A point in the drone's body axes in the level, heading-following frame: turned by the
    attitude (scipy's Z-Y-X rotation), then back by the yaw."""
    rng = np.random.default_rng(9)
    rot = Rotation.random(500, random_state=rng)
    p = rng.normal(0.0, 0.2, (500, 3))
    yaw, pitch, roll = rot.as_euler("ZYX").T
    got = np.array([level_point(r, pt, tuple(u)) for r, pt, u in zip(roll, pitch, p)])
    want = Rotation.from_euler("Z", -yaw[:, None]).apply(rot.apply(p))
    assert np.abs(got - want).max() < 1e-12


def test_the_sign_conventions_written_in_the_docs_hold():
    """docs/ros.md, "Frames and signs": REP 103 body axes (x forward, y left, z up); a drone
    whose nose dips has positive pitch, one whose right side dips has positive roll; the
    same attitude in a flight controller's FRD body frame has the opposite pitch."""
    a = math.radians(12.0)
    nose_down = Rotation.from_rotvec([0.0, a, 0.0])        # about the left axis
    assert nose_down.apply([1.0, 0.0, 0.0])[2] < 0         # the nose points below the horizon
    roll, pitch = roll_pitch(*nose_down.as_quat())
    assert abs(roll) < 1e-12 and abs(pitch - a) < 1e-12
    right_down = Rotation.from_rotvec([a, 0.0, 0.0])       # about the forward axis
    assert right_down.apply([0.0, -1.0, 0.0])[2] < 0       # the right side dips
    roll, pitch = roll_pitch(*right_down.as_quat())
    assert abs(roll - a) < 1e-12 and abs(pitch) < 1e-12
    # FRD body in an NED world (PX4, ArduPilot): the same physical attitude, the frames turned
    # half a turn about x; nose-down is negative pitch there
    flip = Rotation.from_rotvec([math.pi, 0.0, 0.0])
    frd = flip * nose_down * flip.inv()
    assert abs(frd.as_euler("ZYX")[1] + a) < 1e-12


def test_the_status_constants_are_the_firmwares_codes():
    """ArmStatus's STATE_, REFUSAL_ and FAULT_ constants, as genpy builds the message class,
    are the firmware's MSG_STATE_, MSG_REFUSAL_ and MSG_FAULT_ defines (generated/messages.h),
    each one of them and no other."""
    import re
    require_ros()
    from uavarm.link.ros_node import load_interfaces
    msg, _ = load_interfaces()
    header = (Path(__file__).resolve().parents[1] / "generated" / "messages.h").read_text()
    firmware = {name: int(value, 0) for name, value in
                re.findall(r"#define MSG_((?:STATE|REFUSAL|FAULT)_[A-Z0-9_]+) (0x[0-9A-Fa-f]+|\d+)u?\b", header)
                if not name.endswith("_COUNT")}                 # (how many there are, not a code)
    ros = {name: getattr(msg.ArmStatus, name) for name in dir(msg.ArmStatus)
           if re.fullmatch(r"(STATE|REFUSAL|FAULT)_[A-Z0-9_]+", name)}
    assert len(firmware) == len(messages.STATES) + len(messages.REFUSALS) + len(messages.FAULTS)
    assert ros == firmware


# ------------------------------------------------------------------ fixtures

@pytest.fixture(scope="module")
def ros(tmp_path_factory):
    """A roscore on a free port and this process as a ROS node; yields (rospy, msg, srv, env)."""
    rospy = require_ros()
    import rosgraph
    from uavarm.link.ros_node import load_interfaces
    msg, srv = load_interfaces()                      # this process's: generated into build/ros by genpy
    workspace = catkin_workspace(tmp_path_factory.mktemp("catkin_ws"))
    home = tmp_path_factory.mktemp("ros_home")
    uri = f"http://127.0.0.1:{free_port()}"
    env = dict(SYSTEM_ENV, ROS_MASTER_URI=uri, ROS_HOME=str(home), ROS_LOG_DIR=str(home / "log"),
               ROS_IP="127.0.0.1", PYTHONUNBUFFERED="1", UAVARM_WORKSPACE=str(workspace))
    saved = {k: os.environ.get(k) for k in ("ROS_MASTER_URI", "ROS_HOME", "ROS_LOG_DIR", "ROS_IP")}
    os.environ.update({k: env[k] for k in saved})
    core_log = open(home / "roscore.out", "w")
    core = subprocess.Popen(["roscore", "-p", uri.rsplit(":", 1)[1]], env=env, start_new_session=True,
                            stdout=core_log, stderr=subprocess.STDOUT)
    try:
        master, end = rosgraph.Master("/uavarm_test", master_uri=uri), time.monotonic() + 30
        while True:
            try:
                master.getPid()
                break
            except Exception:
                if core.poll() is not None or time.monotonic() > end:
                    pytest.fail(f"roscore did not start:\n{(home / 'roscore.out').read_text()}")
                time.sleep(0.1)                  # (asks again until the master answers; a hang guard)
        rospy.init_node("uavarm_test", anonymous=True, disable_signals=True)
        yield rospy, msg, srv, env
    finally:
        rospy.signal_shutdown("tests done")
        stop_group(core)
        core_log.close()
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


class Tap:
    """Decodes what the simulated board receives, before the firmware does."""

    def __init__(self, board):
        self.decoder = llcp.Decoder(gap=0.1, expected_len=lambda i: messages.BY_ID[i].size
                                    if i in messages.BY_ID else -1)
        self.attitudes = []                           # (time.monotonic(), fields)
        self.velocities = []
        receive = board.send_bytes

        def send_bytes(data):
            for payload in self.decoder.feed(data, time.monotonic()):
                name, fields = messages.decode(payload)
                if name == "drone_attitude":
                    self.attitudes.append((time.monotonic(), fields))
                elif name == "drone_velocity":
                    self.velocities.append((time.monotonic(), fields))
            receive(data)
        board.send_bytes = send_bytes


class Arm:
    """A SITL board, the node launched on its pseudo-terminal, proxies and the status topic."""

    def __init__(self, ros, ns, log_path, **launch_args):
        self.rospy, self.msg, self.srv, env = ros
        rospy = self.rospy
        self.ns, self.log_path = ns, log_path
        self.sitl = Sitl(speed=SPEED)
        self.tap = Tap(self.sitl.board)
        self.sitl.start()
        args = dict(port=self.sitl.device, baud=115200, uav_name=ns, **launch_args)
        self.log_file = open(log_path, "w")
        launch = " ".join(["roslaunch uavarm_ros arm.launch", *(f"{k}:={v}" for k, v in args.items())])
        self.proc = subprocess.Popen(["bash", "-c", f"source {env['UAVARM_WORKSPACE']}/devel/setup.bash && exec {launch}"],
                                     env=env, start_new_session=True, stdout=self.log_file,
                                     stderr=subprocess.STDOUT)
        self.statuses = queue.Queue()
        self.sub = rospy.Subscriber(f"/{ns}/arm/status", self.msg.ArmStatus, self.statuses.put)
        from sensor_msgs.msg import JointState
        self.joint_states = queue.Queue()
        self.joint_sub = rospy.Subscriber(f"/{ns}/joint_states", JointState, self.joint_states.put)
        self.goal_states = queue.Queue()
        self.goal_sub = rospy.Subscriber(f"/{ns}/arm/goal_joint_states", JointState, self.goal_states.put)

    def wait_ready(self):
        from std_srvs.srv import SetBool
        rospy, names = self.rospy, {"enable": SetBool, "engage": SetBool, "set_position": self.srv.SetPosition}
        try:
            for name in names:
                rospy.wait_for_service(f"/{self.ns}/arm/{name}", timeout=60)
        except rospy.ROSException:
            raise AssertionError(f"the node's services did not come up:\n{self.log()}") from None
        self.proxies = {name: rospy.ServiceProxy(f"/{self.ns}/arm/{name}", t) for name, t in names.items()}
        # the node has heard the board before a test commands it (its first status): a command
        # sent earlier waits on the wall clock for heartbeats the node's link has not begun to
        # read, which a busy machine can make late (60 s: a hang guard)
        try:
            self.statuses.get(timeout=60)
        except queue.Empty:
            raise AssertionError(f"no status from the node in 60 s:\n{self.log()}") from None

    def log(self) -> str:
        return Path(self.log_path).read_text(errors="replace")

    def call(self, name, *args):
        """Call a service; statuses from before its answer are dropped."""
        response = self.proxies[name](*args)
        self.drain()
        return response

    def drain(self):
        while True:
            try:
                self.statuses.get_nowait()
            except queue.Empty:
                return

    def wait_status(self, cond, sim_seconds):
        """The first status after now with cond(status), or None once the board's simulated
        clock has run sim_seconds (a hang guard fails the test after ten times that in real
        time, and 30 s: a board that stopped would otherwise seem to hold whatever it held)."""
        end = self.sitl.board.time + sim_seconds
        deadline = time.monotonic() + 10 * sim_seconds / SPEED + 30
        while self.sitl.board.time < end:
            if time.monotonic() > deadline:
                pytest.fail(f"the SITL's board did not run {sim_seconds} s in {10 * sim_seconds / SPEED + 30:.0f} s "
                            "of real time: it stalled")
            try:
                status = self.statuses.get(timeout=0.5)
            except queue.Empty:
                continue
            if cond(status):
                return status
        return None

    def close(self):
        self.sub.unregister()
        self.joint_sub.unregister()
        self.goal_sub.unregister()
        stop_group(self.proc)
        self.log_file.close()
        self.sitl.stop()


@pytest.fixture
def start_arm(ros, tmp_path):
    arms = []

    def start(**launch_args):
        arm = Arm(ros, f"uav{len(arms)}_{os.getpid()}_{time.monotonic_ns() % 10**6}",
                  tmp_path / f"node{len(arms)}.log", **launch_args)
        arms.append(arm)                               # stopped at teardown even if not ready
        arm.wait_ready()
        return arm
    yield start
    for arm in arms:
        arm.close()


def joints(status):
    return np.array(status.joints)


# ------------------------------------------------------------------ with ROS

def test_attitude_message_types():
    """Each ~attitude_type resolves to its class and its orientation (Imu: none when the
    orientation covariance says so, REP 145)."""
    require_ros()
    from uavarm.link.ros_node import attitude_class
    for name in ATTITUDE_TYPES:
        cls, orientation = attitude_class(name)
        assert cls._type == name
        m = cls()
        assert orientation(m) is not None
    imu_cls, orientation = attitude_class("sensor_msgs/Imu")
    m = imu_cls()
    m.orientation_covariance[0] = -1
    assert orientation(m) is None
    with pytest.raises(ValueError, match="attitude_type"):
        attitude_class("std_msgs/String")


def test_engage_refused_until_enabled_then_parked(start_arm):
    m = config.load()
    arm = start_arm()
    status = arm.wait_status(lambda s: True, ANY_STATUS_S)
    assert status is not None and not status.enabled and not status.engaged and status.fault_names == []
    assert status.header.frame_id == "arm_base" and status.attitude_source == "imu"
    assert abs(status.header.stamp.to_sec() - arm.rospy.Time.now().to_sec()) < 5.0
    assert status.reset_cause == "power_on" and status.last_fault == ""
    assert status.state == status.STATE_OFF and status.state_name == "off"
    # unpowered, the servos cannot be read: no shafts, no joint state; the goals beside them
    assert all(math.isnan(q) for q in status.joints)
    assert np.allclose(status.goal_joints, np.radians(m.park_deg), atol=1e-6)
    goals = arm.goal_states.get(timeout=10)
    assert list(goals.name) == ["arm_joint1", "arm_joint2", "arm_joint3"]
    assert np.allclose(goals.position, np.radians(m.park_deg), atol=1e-6)
    assert arm.joint_states.empty(), "a joint state of an arm whose servos were not read"

    r = arm.call("engage", True)
    assert not r.success and "not enabled" in r.message

    r = arm.call("enable", True)
    assert r.success and "enabled 1" in r.message
    park = np.radians(m.park_deg)
    status = arm.wait_status(lambda s: s.enabled and np.abs(joints(s) - park).max() < math.radians(0.5), 8.0)
    assert status is not None, "the parked pose was not reached"
    assert not status.engaged and status.state == status.STATE_PARKED and status.refusal_code == 0
    print(f"parked: joints within {np.degrees(np.abs(joints(status) - park).max()):.3f} deg of park.q")
    # each heartbeat with the shafts read is a JointState of the shafts (the parked one's: by then all three read)
    js = arm.joint_states.get(timeout=10)
    while js.header.stamp < status.header.stamp:
        js = arm.joint_states.get(timeout=10)
    assert list(js.name) == ["arm_joint1", "arm_joint2", "arm_joint3"] and all(map(math.isfinite, js.position))
    # the servos' supply, temperature and load, as they report them (the SITL's 3S battery, 11.1 V)
    assert all(9.0 <= v <= 12.6 for v in status.servo_voltage), status.servo_voltage
    assert all(t > 0 for t in status.servo_temperature) and all(-1 <= f <= 1 for f in status.servo_load)
    assert any(f != 0 for f in status.servo_load), "the parked arm's weight on its servos"
    # the arm's TF from robot_state_publisher: the end effector where the model's FK puts it
    import tf2_ros
    from uavarm.build import firmware
    buffer = tf2_ros.Buffer()
    tf2_ros.TransformListener(buffer)
    t = buffer.lookup_transform("uav_frame", "end_effector", arm.rospy.Time(0), arm.rospy.Duration(10.0))
    ffi, lib = firmware.default()
    ee = ffi.new("float[3]")
    lib.kin_fk_ee([float(v) for v in joints(status)], ee)
    expected = (np.array(m.mount_offset) + np.array(list(ee))) / 1000.0
    got = np.array([t.transform.translation.x, t.transform.translation.y, t.transform.translation.z])
    assert np.abs(got - expected).max() < 1e-4           # m: the parked arm stands still


def test_engage_reaches_the_set_position_and_disable_cuts_power(start_arm):
    m = config.load()
    arm = start_arm()                                  # keep-alive on, no attitude publisher
    assert arm.call("enable", True).success
    r = arm.call("set_position", *TARGET_M)
    assert r.success, r.message
    r = arm.call("engage", True)
    assert r.success and "engaged 1" in r.message
    target = np.array(TARGET_M) * 1000.0

    def at_target(s):
        return s.engaged and np.linalg.norm(arm_points(m, joints(s))[2] - target) <= FK_TOL_MM
    status = arm.wait_status(at_target, 4.0)
    assert status is not None, "the set position was not reached"
    assert np.allclose(status.set_position, TARGET_M, atol=1e-6)
    print(f"engaged: end effector {np.linalg.norm(arm_points(m, joints(status))[2] - target):.3f} mm from the target")

    # the node keeps the engaged arm's link alive by itself (no attitude published)
    held = arm.wait_status(lambda s: not s.engaged or "link_lost" in s.fault_names, 3 * m.link_silence_timeout)
    assert held is None, f"the engaged arm parked: {held}"

    r = arm.call("enable", False)
    assert r.success
    status = arm.wait_status(lambda s: True, ANY_STATUS_S)
    assert not status.enabled and not status.engaged
    assert not arm.sitl.board.servo_power


def test_refusals_and_a_stopped_board_are_answered_with_reasons(start_arm):
    m = config.load()
    arm = start_arm()
    assert arm.call("enable", True).success
    park_point = arm_points(m, np.radians(m.park_deg))[2] / 1000.0

    r = arm.call("set_position", 0.5, 0.0, 0.0)
    assert not r.success and "unreachable" in r.message and "0.5000" in r.message
    status = arm.wait_status(lambda s: True, ANY_STATUS_S)
    assert status.unreachable and np.allclose(status.set_position, park_point, atol=1e-4)

    r = arm.call("set_position", math.nan, 0.0, 0.0)
    assert not r.success and "finite" in r.message
    r = arm.call("set_position", *(v * 1000.0 for v in TARGET_M))    # millimetres by mistake
    assert not r.success and "unreachable" in r.message and "millimetres? the services" in r.message
    r = arm.call("set_position", 0.5, 0.0, 0.0)                         # only out of reach: no such hint
    assert not r.success and "millimetres" not in r.message

    arm.sitl.stop()                                    # the board goes away
    r = arm.call("engage", True)
    assert not r.success and ("serial link lost" in r.message or "no heartbeat" in r.message
                              or "no link" in r.message), r.message
    end = time.monotonic() + 60
    while "serial link lost" not in arm.log() and time.monotonic() < end:
        time.sleep(0.2)                                # (until the node's log says it; a hang guard)
    assert "serial link lost" in arm.log()


def test_attitude_is_forwarded_and_a_cut_link_parks_the_arm(start_arm):
    """keep-alive off: only the forwarded attitude keeps the engaged arm engaged."""
    from nav_msgs.msg import Odometry
    m = config.load()
    arm = start_arm(keep_alive="false")
    rospy = arm.rospy
    roll, pitch, yaw = 0.10, -0.05, 0.7
    x, y, z, w = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    pub = rospy.Publisher(f"/{arm.ns}/estimation_manager/odom_main", Odometry, queue_size=1)
    odom = Odometry()
    odom.pose.pose.orientation.x, odom.pose.pose.orientation.y = x, y
    odom.pose.pose.orientation.z, odom.pose.pose.orientation.w = z, w
    body_velocity = (1.5, -0.5, 0.25)                    # the twist, in the child (body) frame
    odom.twist.twist.linear.x, odom.twist.twist.linear.y, odom.twist.twist.linear.z = body_velocity
    publishing = threading.Event()
    publishing.set()

    def publish():
        while publishing.is_set() and not rospy.is_shutdown():
            odom.header.stamp = rospy.Time.now()
            pub.publish(odom)
            time.sleep(0.01)                             # the drone's odometry, about 100 Hz like odom_main
    feeder = threading.Thread(target=publish, daemon=True)
    feeder.start()
    try:
        end = time.monotonic() + 60
        while not arm.tap.attitudes and time.monotonic() < end:
            time.sleep(0.05)                             # (until the first reaches the board; a hang guard)
        assert arm.tap.attitudes, f"no attitude reached the board:\n{arm.log()}"

        assert arm.call("enable", True).success
        assert arm.call("engage", True).success
        t0, n0 = time.monotonic(), len(arm.tap.attitudes)
        held = arm.wait_status(lambda s: not s.engaged, 3 * m.link_silence_timeout)
        assert held is None, f"the engaged arm parked while the attitude was forwarded: {held}"
        fusing = arm.wait_status(lambda s: s.attitude_source == "drone" and s.velocity_source == "drone", ANY_STATUS_S)
        assert fusing is not None and fusing.header.frame_id == "arm_base"
        window = [f for t, f in arm.tap.attitudes[n0:]]
        rate = len(window) / (time.monotonic() - t0)     # measured, not judged: the machine's load sets it
    finally:
        publishing.clear()
        feeder.join(timeout=5)

    rolls = np.array([f["roll"] for f in window])
    pitches = np.array([f["pitch"] for f in window])
    assert np.abs(rolls - roll).max() < 1e-6 and np.abs(pitches - pitch).max() < 1e-6
    seqs = np.array([f["seq"] for f in window])
    assert np.all(np.diff(seqs) % 65536 == 1), "attitude frames lost or reordered"
    # the velocity: each odometry message once, in the heading-following frame (scipy: the
    # body velocity turned by the attitude, then back by the yaw)
    level = Rotation.from_euler("Z", -yaw).apply(Rotation.from_euler("ZYX", [yaw, pitch, roll]).apply(body_velocity))
    vels = np.array([[f["vx"], f["vy"], f["vz"]] for _, f in arm.tap.velocities])
    assert len(vels) > 50 and np.abs(vels - level).max() < 1e-5, (len(vels), vels[:3], level)
    stamps = np.array([f["stamp_us"] for _, f in arm.tap.velocities])
    assert np.all(np.diff(stamps) % 2 ** 32 > 0), "a velocity forwarded twice"

    # the drone stops sending: the board parks after link.silence_timeout, the node reports it
    status = arm.wait_status(lambda s: not s.engaged, 3 * m.link_silence_timeout)
    assert status is not None, "the arm did not park when the link fell silent"
    assert "link_lost" in status.fault_names and status.enabled and status.attitude_source == "imu"
    assert status.velocity_source == "none"
    assert "forwarding the drone's attitude from /" + arm.ns + "/estimation_manager/odom_main" in arm.log()
    assert "the board runs on its own IMU only" in arm.log()
    assert "no velocity on /" + arm.ns + "/estimation_manager/odom_main" in arm.log()
    end = time.monotonic() + 60
    while "fault link_lost" not in arm.log() and time.monotonic() < end:
        time.sleep(0.1)                                  # (until the node's log says it; a hang guard)
    assert "fault link_lost" in arm.log()
    print(f"attitude forwarded at {rate:.1f} Hz ({len(window)} frames)")


@pytest.mark.parametrize("reenable", [True, False])
def test_a_board_reset_mid_flight_is_an_error_and_by_default_it_is_enabled_again(start_arm, reenable):
    """Engaged, the board's watchdog resets it (it comes up disabled: the arm would hang limp):
    the node logs an error and counts it in unexpected_resets; by default it enables the board
    again, which parks with the torque on, and never engages it; with ~reenable false the
    board stays disabled, its servo supply off."""
    parked = [name for name, _ in messages.STATES].index("parked")
    arm = start_arm(**({} if reenable else {"reenable": "false"}))
    assert arm.call("enable", True).success
    assert arm.call("engage", True).success
    status = arm.wait_status(lambda s: s.engaged, ANY_STATUS_S)
    assert status is not None and status.unexpected_resets == 0
    arm.sitl.reset("watchdog")
    status = arm.wait_status(lambda s: s.unexpected_resets > 0, ANY_STATUS_S)
    assert status is not None, "the restart was not reported"
    assert status.unexpected_resets == 1 and status.reset_cause == "watchdog" and not status.engaged
    if reenable:
        status = arm.wait_status(lambda s: s.enabled and s.state == parked, 10.0)
        assert status is not None, "the board enabled again did not park"
        assert all(s.register("torque_enable") == 1 for s in arm.sitl.board.bus.servos)
        assert arm.wait_status(lambda s: s.engaged or s.unexpected_resets != 1, 2.0) is None
    else:
        assert arm.wait_status(lambda s: s.enabled or s.unexpected_resets != 1, 3.0) is None
        assert not arm.sitl.board.servo_power
    told = "arm: the board restarted while enabled (reset cause watchdog"
    end = time.monotonic() + 60
    while told not in arm.log() and time.monotonic() < end:
        time.sleep(0.1)                                  # (until the node's log says it; a hang guard)
    line = next((line for line in arm.log().splitlines() if told in line), "")
    assert line.startswith("[ERROR]") and "it was engaged" in line, arm.log()
    assert ("enable sent again" in line) == reenable and ("reenable is off" in line) != reenable


def test_a_limp_arm_moved_by_hand_reports_where_its_servos_are(start_arm):
    """Hands move the joints of the unpowered arm: it reports no shafts (none can be read) and
    its last goals as goals, never as joints; powered limp (enable 2, the bench, sent by a
    second program on the port) the status and joint_states say where the hands put them."""
    m = config.load()
    arm = start_arm()
    hand_deg = np.array([0.0, 10.0, -19.0])
    for j, deg in enumerate(hand_deg, 1):
        done = arm.sitl.submit(f"move joint {j} {deg}").result(timeout=30)
        assert "turned by hand" in done, done
    status = arm.wait_status(lambda s: True, 2.0)
    assert status.state == status.STATE_OFF and all(math.isnan(q) for q in status.joints)
    assert np.allclose(status.goal_joints, np.radians(m.park_deg), atol=1e-6)
    assert arm.joint_states.empty()
    with open(arm.sitl.device, "wb", buffering=0) as port:
        port.write(llcp.encode(messages.encode("enable", on=2)))
    limp = arm.wait_status(lambda s: s.state == s.STATE_LIMP and all(map(math.isfinite, s.joints)), 5.0)
    assert limp is not None, f"the bench was not entered:\n{arm.log()}"
    unit_deg = 300.0 / 1023                                 # one AX-12A position unit (e-manual)
    assert np.abs(np.degrees(limp.joints) - hand_deg).max() <= unit_deg, np.degrees(limp.joints)
    assert np.allclose(limp.goal_joints, np.radians(m.park_deg), atol=1e-6)   # no goal sent limp
    while True:                                             # the JointState of that heartbeat
        js = arm.joint_states.get(timeout=10)
        if js.header.stamp == limp.header.stamp:
            break
    assert np.abs(np.degrees(js.position) - hand_deg).max() <= unit_deg
    # the hands move it again: the joints follow
    assert "turned by hand" in arm.sitl.submit("move joint 3 -40").result(timeout=30)
    moved = arm.wait_status(lambda s: abs(math.degrees(s.joints[2]) + 40.0) <= unit_deg, 3.0)
    assert moved is not None and moved.state == moved.STATE_LIMP
    print(f"limp: joints {np.round(np.degrees(limp.joints), 2)} deg where the hands put "
          f"{hand_deg} deg; goals {np.round(np.degrees(limp.goal_joints), 2)} deg")


def test_joint_states_come_with_every_heartbeat(start_arm):
    """One JointState per heartbeat whose shafts were read (stamped with its arrival); the
    rate is the board's heartbeat rate, measured here and printed, not judged."""
    m = config.load()
    arm = start_arm()
    assert arm.call("enable", True).success
    assert arm.wait_status(lambda s: all(map(math.isfinite, s.joints)), 4.0) is not None
    while not arm.joint_states.empty():
        arm.joint_states.get_nowait()
    seqs, stamps = [], []
    while len(seqs) < 50:                                   # 2 s of heartbeats
        status = arm.wait_status(lambda s: True, 2.0)
        assert status is not None
        seqs.append(status.seq)
        stamps.append(status.header.stamp.to_sec())
    time.sleep(0.5)                                         # (the last JointState's delivery)
    js_stamps = []
    while not arm.joint_states.empty():
        js_stamps.append(arm.joint_states.get_nowait().header.stamp.to_sec())
    assert all(t in js_stamps for t in stamps), "a heartbeat without its JointState"
    assert np.all(np.diff(seqs) % 65536 == 1), "heartbeats lost"
    rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
    print(f"joint_states at {rate:.2f} Hz (the heartbeat's period: {m.heartbeat_period} s)")


def test_a_target_stream_in_another_frame_drives_the_arm_there(start_arm):
    """~target points in a frame a static TF offsets and turns from the arm's base: each one,
    transformed, becomes the set position; the goals' end effector by the model's FK ends
    within 1 mm of the last (the shafts' within FK_TOL_MM, a servo unit's rounding and the
    arm's weight; the level drone: no attitude). A point out of reach is refused on ~status as the
    service's is; a frame TF does not know is logged and ignored."""
    import tf2_ros
    from geometry_msgs.msg import PointStamped, TransformStamped
    m = config.load()
    arm = start_arm()
    rospy = arm.rospy
    frame = f"{arm.ns}_tool"
    offset, turn = np.array([0.03, 0.02, -0.10]), Rotation.from_euler("z", 90.0, degrees=True)
    t = TransformStamped()
    t.header.stamp, t.header.frame_id, t.child_frame_id = rospy.Time.now(), "arm_base", frame
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = offset
    (t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
     t.transform.rotation.w) = turn.as_quat()
    broadcaster = tf2_ros.StaticTransformBroadcaster()
    broadcaster.sendTransform(t)
    pub = rospy.Publisher(f"/{arm.ns}/arm/target", PointStamped, queue_size=10)

    def send(base_point, frame_id=frame):
        p = PointStamped()
        p.header.stamp, p.header.frame_id = rospy.Time.now(), frame_id
        p.point.x, p.point.y, p.point.z = turn.inv().apply(np.asarray(base_point) - offset)
        pub.publish(p)

    assert arm.call("enable", True).success
    assert arm.call("engage", True).success
    start = arm_points(m, np.radians(m.park_deg))[2] / 1000.0
    target = np.array(TARGET_M)
    for k in range(1, 21):                                  # 1 s from the park point to the target, 20 Hz
        send(start + (target - start) * k / 20)
        time.sleep(0.05)                                    # (the planner's pace)

    seen = []
    off_mm = lambda q: np.linalg.norm(arm_points(m, np.asarray(q))[2] - target * 1000.0)   # noqa: E731

    def there(s):
        send(target)                                        # (the stream goes on)
        seen.append(s)
        return (np.allclose(s.set_position, target, atol=1e-6) and s.engaged
                and off_mm(s.goal_joints) <= 1.0 and off_mm(s.joints) <= FK_TOL_MM)
    status = arm.wait_status(there, 6.0)
    assert status is not None, f"the streamed target was not reached: last status {seen[-1:]}\n{arm.log()}"
    print(f"target stream: the goals' end effector {off_mm(status.goal_joints):.3f} mm from the last point, "
          f"the shafts' {off_mm(status.joints):.3f} mm")

    send((0.5, 0.0, 0.0))                                   # out of reach
    refused = arm.wait_status(lambda s: s.unreachable, 2.0)
    assert refused is not None and np.allclose(refused.set_position, target, atol=1e-6)
    send(target, frame_id="no_such_frame")
    end = time.monotonic() + 30
    while "~target in 'no_such_frame' ignored" not in arm.log() and time.monotonic() < end:
        time.sleep(0.1)                                     # (until the node's log says it; a hang guard)
    assert "~target in 'no_such_frame' ignored" in arm.log()
