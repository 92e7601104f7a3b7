"""ROS 1 node for the arm board: `launch/arm.launch` of the uavarm_ros package starts it.

Interface (private names, under the node: /<uav_name>/arm/...):

- `~enable`, `~engage` (std_srvs/SetBool, as the MRS system uses) and `~set_position`
  (uavarm_ros/SetPosition: x, y, z in metres, REP 103). Each answers once a heartbeat shows
  the command taken (uavarm.link.ArmLink), or success false with the board's reason: "engage
  refused: the arm is not enabled", "... refused: unreachable ...", "no heartbeat ...".
- `~status` (uavarm_ros/ArmStatus): every fresh heartbeat, at the model's heartbeat rate
  (the link drops those queued longer than half a second; a board restart is logged as a warning, and as an error if it was
  enabled and its watchdog or a fault reset it: it came up limp, `unexpected_resets` counts
  it, and unless `~reenable` is false enable is sent again so that it parks, never engaged). A message of this package
  rather than diagnostic_msgs key/value strings, so consumers get typed fields (flags, joints,
  set position, counters) and the fault bits by name; its header's frame_id is `arm_base`
  (the URDF's), `attitude_source` says whether the drone's attitude is being forwarded
  ("drone") or the board runs on its own IMU only ("imu"), and `velocity_source` whether the
  drone's velocity is ("drone" or "none"; each change is logged). New fault
  bits (for example link_lost when the arm parked after a silent link) are logged as warnings.
- `joint_states` (sensor_msgs/JointState, robot_state_publisher's): at the heartbeat rate,
  the shafts of each heartbeat as the servos' status reads found them, only the joints read (none while the arm
  is disabled: its servos are unpowered), never a goal in their place; `~goal_joint_states`
  the goals beside them.
- `~target` (geometry_msgs/PointStamped): a stream of targets in any frame TF links to
  `arm_base`, transformed there, levelled with the drone's roll and pitch and sent as the set
  position, the latest one at most `~target_rate` (50) times a second (at most the board's
  tick rate); the board's refusals come in `~status` as for the service.
- the drone's attitude (`~attitude_topic`, default `estimation_manager/odom_main`, the MRS UAV
  System's estimated state; `~attitude_type`: nav_msgs/Odometry,
  sensor_msgs/Imu or geometry_msgs/QuaternionStamped): the orientation quaternion as Z-Y-X
  roll and pitch, each message forwarded once with ArmLink.send_attitude by the loop, which
  runs at `~attitude_rate` Hz (default 100, at least 50), while it is fresher than
  `~attitude_timeout` s; a message stamped zero is stamped on arrival (logged once). The board counts
  it as keep-alive, and a firmware built with the link estimator fuses it. With no fresh attitude and `~keep_alive` true, an
  engaged arm is kept alive by repeating its set position every `~keep_alive_period` s.
- the drone's velocity, from the same nav_msgs/Odometry (`~velocity`, default true): the
  twist's linear part, in the message's child frame as nav_msgs defines it (`~velocity_frame`
  "child") or in its parent frame ("parent", for a source that publishes it so), turned into
  the gravity-aligned, heading-following frame with the message's orientation and forwarded
  once per message with ArmLink.send_velocity; a firmware built with drone_velocity fuses it.

Parameters: `~port` (/dev/ttyACM0), `~baud` (115200), the attitude ones above,
`~keep_alive` (true), `~keep_alive_period` (0.2 s; the board parks after 1 s of silence),
`~reenable` (true: enable a board that restarted while enabled, above),
`~parent_frame` (none: the drone's body frame, published as the same place as the URDF's
root `uav_frame`, so the arm hangs in the drone's TF tree).

What it does without ROS is arm_core.ArmCore (the port and its reopening, each loop step,
the status of a heartbeat, the commands); this module adapts it to ROS 1. One thread reads the
port: the main loop polls heartbeats, publishes them and sends the attitude or keep-alive
frames. Service threads send their command and wait for the loop to deliver the heartbeats
that confirm it; every read and write goes through one lock. The port is reopened every
second after an error (a board unplugged, a SITL stopped).

In a catkin workspace the node takes catkin's message classes and needs nothing but rospy,
the ROS message packages and pyserial (Python 3.8, Noetic's, and later). Run from the source
folder (the toolchain's tests), Debian's genpy turns msg/ and srv/ into Python in build/ros,
never committed. This module imports rospy only inside functions, so the link works without
ROS.
"""
from __future__ import annotations

import fcntl
import hashlib
import importlib
import math
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

from .arm_core import JOINT_NAMES, ArmCore, level_point, level_velocity, roll_pitch, rotate
from .client import KEEP_ALIVE_S

PACKAGE = "uavarm_ros"
# the ROS package's folder (this file is its src/uavarm_link/ros_node.py): msg/ and srv/
DEFAULT_PACKAGE_DIR = Path(__file__).resolve().parents[2]
DEBIAN_DIST_PACKAGES = Path("/usr/lib/python3/dist-packages")
# std_msgs/Header.msg and its siblings (Debian's ros-std-msgs): ArmStatus has a Header
STD_MSGS_DEFINITIONS = Path("/usr/share/std_msgs/msg")
# the frame of ArmStatus: the URDF's link at the arm's base; and the URDF's root
STATUS_FRAME = "arm_base"
URDF_ROOT = "uav_frame"
DEFAULT_ATTITUDE_TOPIC = "estimation_manager/odom_main"

# ~attitude_type -> (module, class, the orientation quaternion of a message or None)
ATTITUDE_TYPES = {
    "nav_msgs/Odometry": ("nav_msgs.msg", "Odometry", lambda m: m.pose.pose.orientation),
    # REP 145: orientation_covariance[0] == -1 means the IMU gives no orientation
    "sensor_msgs/Imu": ("sensor_msgs.msg", "Imu",
                        lambda m: None if m.orientation_covariance[0] == -1 else m.orientation),
    "geometry_msgs/QuaternionStamped": ("geometry_msgs.msg", "QuaternionStamped", lambda m: m.quaternion),
}


# ------------------------------------------------------------------ ROS imports and interfaces

def _debian_ros_path() -> bool:
    """Debian's ROS packages are in the system interpreter's dist-packages; a virtual
    environment made from another build of the same Python version (pyenv, for one) does not
    see them. Append that folder (after every other) when the versions match."""
    here = f"python{sys.version_info.major}.{sys.version_info.minor}"
    system = Path("/usr/bin/python3")
    if not ((DEBIAN_DIST_PACKAGES / "rospy").is_dir() and system.exists() and system.resolve().name == here):
        return False
    if str(DEBIAN_DIST_PACKAGES) in sys.path:
        return False
    sys.path.append(str(DEBIAN_DIST_PACKAGES))
    return True


def import_ros():
    """rospy (ImportError when ROS 1 is not installed)."""
    try:
        import rospy
    except ImportError:
        if not _debian_ros_path():
            raise
        import rospy
    return rospy


def build_interfaces(package_dir=DEFAULT_PACKAGE_DIR, build_dir=None) -> Path:
    """Generate the Python classes of the package's msg/*.msg and srv/*.srv with genpy (what
    Debian's genmsg_py.py and gensrv_py.py run) into build_dir/uavarm_ros; again only when the
    sources changed. Returns build_dir, the folder to put on sys.path."""
    import_ros()
    from genpy.generate_initpy import write_modules
    from genpy.generator import MsgGenerator, SrvGenerator

    package_dir = Path(package_dir)
    build_dir = Path(build_dir) if build_dir is not None else default_build_dir(package_dir)
    kinds = (("msg", MsgGenerator(), sorted(package_dir.glob("msg/*.msg"))),
             ("srv", SrvGenerator(), sorted(package_dir.glob("srv/*.srv"))))
    digest = hashlib.sha256()
    for _, _, files in kinds:
        for f in files:
            digest.update(f.name.encode() + b"\0" + f.read_bytes() + b"\0")
    digest = digest.hexdigest()
    out = build_dir / PACKAGE
    build_dir.mkdir(parents=True, exist_ok=True)
    with open(build_dir / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)          # the node and the tests may start together
        stamp = out / ".sources"
        if stamp.exists() and stamp.read_text() == digest:
            return build_dir
        tmp = Path(tempfile.mkdtemp(prefix=".gen-", dir=build_dir))
        search_path = {PACKAGE: [str(package_dir / "msg")], "std_msgs": [str(STD_MSGS_DEFINITIONS)]}
        for kind, generator, files in kinds:
            if not files:
                continue
            if generator.generate_messages(PACKAGE, [str(f) for f in files], str(tmp / kind), search_path):
                shutil.rmtree(tmp, ignore_errors=True)
                raise RuntimeError(f"genpy could not generate {package_dir / kind} (error above)")
            write_modules(str(tmp / kind))
        (tmp / "__init__.py").write_text("")
        stamp_tmp = tmp / ".sources"
        stamp_tmp.write_text(digest)
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    return build_dir


def default_build_dir(package_dir) -> Path:
    """$UAVARM_ROS_BUILD, else build/ros of the repository holding ros/uavarm_ros."""
    env = os.environ.get("UAVARM_ROS_BUILD")
    return Path(env) if env else Path(package_dir).resolve().parents[1] / "build" / "ros"


def load_interfaces(package_dir=DEFAULT_PACKAGE_DIR, build_dir=None):
    """(uavarm_ros.msg, uavarm_ros.srv), generated if needed."""
    path = str(build_interfaces(package_dir, build_dir))
    if path not in sys.path:
        sys.path.insert(0, path)
    importlib.invalidate_caches()
    return importlib.import_module(f"{PACKAGE}.msg"), importlib.import_module(f"{PACKAGE}.srv")


def attitude_class(type_name: str):
    """The message class for ~attitude_type and the function giving a message's quaternion."""
    try:
        module, cls, orientation = ATTITUDE_TYPES[type_name]
    except KeyError:
        raise ValueError(f"~attitude_type {type_name!r}: use one of {sorted(ATTITUDE_TYPES)}") from None
    import_ros()
    return getattr(importlib.import_module(module), cls), orientation


class RosLog:
    """The core's logger on rospy."""

    def __init__(self, rospy):
        self.rospy = rospy

    def info(self, text: str) -> None:
        self.rospy.loginfo(text)

    def warn(self, text: str) -> None:
        self.rospy.logwarn(text)

    def error(self, text: str) -> None:
        self.rospy.logerr(text)

    def warn_every(self, seconds: float, text: str) -> None:
        self.rospy.logwarn_throttle(seconds, text)


class ArmNode:
    """ArmCore on ROS 1: parameters, the attitude topic, the status and joint_states topics,
    the services, the static TF to the drone's body frame."""

    def __init__(self, rospy, msg, srv):
        from sensor_msgs.msg import JointState
        from std_srvs.srv import SetBool, SetBoolResponse
        self.rospy, self.msg, self.srv = rospy, msg, srv
        self._SetBoolResponse = SetBoolResponse
        self.attitude_rate = float(rospy.get_param("~attitude_rate", 100.0))
        if not self.attitude_rate >= 50:
            raise ValueError(f"~attitude_rate must be at least 50 Hz, got {self.attitude_rate}")
        topic = rospy.get_param("~attitude_topic", DEFAULT_ATTITUDE_TOPIC)
        att_type = rospy.get_param("~attitude_type", "nav_msgs/Odometry")
        att_class, self._orientation = attitude_class(att_type)
        frame = rospy.get_param("~velocity_frame", "child")
        if frame not in ("child", "parent"):
            raise ValueError(f"~velocity_frame must be child or parent, got {frame!r}")
        self._velocity_in_body = frame == "child"
        self._velocity = bool(rospy.get_param("~velocity", True)) and att_type == "nav_msgs/Odometry"
        self.core = ArmCore(rospy.get_param("~port", "/dev/ttyACM0"), int(rospy.get_param("~baud", 115200)),
                            RosLog(rospy), self._publish,
                            attitude_timeout=float(rospy.get_param("~attitude_timeout", 0.2)),
                            keep_alive=bool(rospy.get_param("~keep_alive", True)),
                            keep_alive_period=float(rospy.get_param("~keep_alive_period", KEEP_ALIVE_S)),
                            attitude_topic=rospy.resolve_name(topic),
                            reenable=bool(rospy.get_param("~reenable", True)),
                            target_rate=float(rospy.get_param("~target_rate", 50.0)))
        self.status_pub = rospy.Publisher("~status", msg.ArmStatus, queue_size=10)
        self.joint_pub = rospy.Publisher("joint_states", JointState, queue_size=10)   # robot_state_publisher's
        self.goal_pub = rospy.Publisher("~goal_joint_states", JointState, queue_size=10)
        self._joint_state = JointState
        self._attach(rospy.get_param("~parent_frame", ""))
        rospy.Subscriber(topic, att_class, self._on_attitude, queue_size=1)
        self._tilt = None                          # (roll, pitch, when): the drone's latest, for ~target
        self._start_target_stream()
        self.core.open(time.monotonic())
        rospy.Service("~enable", SetBool, self._on_enable)
        rospy.Service("~engage", SetBool, self._on_engage)
        rospy.Service("~set_position", srv.SetPosition, self._on_set_position)
        rospy.loginfo("arm: board on %s, attitude from %s (%s) at %.0f Hz, keep-alive %s",
                      self.core.port, self.core.attitude_topic, att_type, self.attitude_rate,
                      "on" if self.core.keep_alive else "off")

    def _attach(self, parent: str) -> None:
        """The URDF's root (the drone at its centre of rotation, REP 103 axes) as `parent`
        itself, the drone's body frame (the MRS UAV System's <uav_name>/fcu): one TF tree."""
        if not parent:
            return
        import tf2_ros
        from geometry_msgs.msg import TransformStamped
        t = TransformStamped()
        t.header.stamp = self.rospy.Time.now()
        t.header.frame_id, t.child_frame_id = parent, URDF_ROOT
        t.transform.rotation.w = 1.0
        self._static_tf = tf2_ros.StaticTransformBroadcaster()
        self._static_tf.sendTransform(t)

    def _start_target_stream(self) -> None:
        """~target (geometry_msgs/PointStamped): each point, in any frame TF links to the arm's
        base, turned into the set position's level frame and streamed to the board."""
        import tf2_ros
        from geometry_msgs.msg import PointStamped
        self._tf_buffer = tf2_ros.Buffer()
        self._tf_listener = tf2_ros.TransformListener(self._tf_buffer)
        self._tf_errors = (tf2_ros.LookupException, tf2_ros.ConnectivityException, tf2_ros.ExtrapolationException)
        self.rospy.Subscriber("~target", PointStamped, self._on_target, queue_size=1)

    def _on_target(self, message) -> None:
        p = message.point
        try:
            t = self._tf_buffer.lookup_transform(STATUS_FRAME, message.header.frame_id or STATUS_FRAME,
                                                 message.header.stamp, self.rospy.Duration(0.1))
        except self._tf_errors as exc:
            self.rospy.logwarn_throttle(5.0, f"arm: ~target in {message.header.frame_id!r} ignored: {exc}")
            return
        r, d = t.transform.rotation, t.transform.translation
        x, y, z = rotate((r.x, r.y, r.z, r.w), (p.x, p.y, p.z))
        body = (x + d.x, y + d.y, z + d.z)               # in arm_base, which turns with the drone
        tilt = self._tilt
        fresh = tilt is not None and time.monotonic() - tilt[2] <= self.core.attitude_timeout
        self.core.target(*(level_point(tilt[0], tilt[1], body) if fresh else body))

    def spin(self) -> None:
        period = 1.0 / self.attitude_rate
        next_t = time.monotonic()
        while not self.rospy.is_shutdown():
            self.core.step(time.monotonic())
            next_t += period
            delay = next_t - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                next_t = time.monotonic()          # late: skip, never burst
        self.core.close()

    def _publish(self, status: dict) -> None:
        m = self.msg.ArmStatus()
        m.header.stamp, m.header.frame_id = self.rospy.Time.now(), STATUS_FRAME
        for field, value in status.items():
            setattr(m, field, value)
        self.status_pub.publish(m)
        # the shafts the servos could be read for (none, unpowered): never a goal in their place
        read = [(name, q) for name, q in zip(JOINT_NAMES, m.joints) if math.isfinite(q)]
        if read:
            self.joint_pub.publish(self._joints(m.header.stamp, read))
        self.goal_pub.publish(self._joints(m.header.stamp, zip(JOINT_NAMES, m.goal_joints)))

    def _joints(self, stamp, named):
        js = self._joint_state()
        js.header.stamp = stamp
        for name, q in named:
            js.name.append(name)
            js.position.append(q)
        return js

    def _on_attitude(self, message) -> None:
        q = self._orientation(message)
        if q is None:
            self.rospy.logwarn_throttle(10.0, "arm: the attitude topic carries no orientation")
            return
        try:
            roll, pitch = roll_pitch(q.x, q.y, q.z, q.w)
        except ValueError as exc:
            self.rospy.logwarn_throttle(10.0, f"arm: attitude ignored: {exc}")
            return
        stamp = message.header.stamp
        stamp_us = stamp.to_nsec() // 1000 if not stamp.is_zero() else None
        now = time.monotonic()
        self._tilt = (roll, pitch, now)
        self.core.attitude(roll, pitch, stamp_us, now)
        if self._velocity:
            lin = message.twist.twist.linear
            v = level_velocity((q.x, q.y, q.z, q.w), (lin.x, lin.y, lin.z), self._velocity_in_body)
            if all(math.isfinite(c) for c in v):
                self.core.velocity(v, stamp_us, now)
            else:
                self.rospy.logwarn_throttle(10.0, "arm: velocity ignored: not finite")

    def _on_enable(self, req):
        return self._SetBoolResponse(*self.core.enable(bool(req.data)))

    def _on_engage(self, req):
        return self._SetBoolResponse(*self.core.engage(bool(req.data)))

    def _on_set_position(self, req):
        return self.srv.SetPositionResponse(*self.core.set_position(req.x, req.y, req.z))


def interfaces(package_dir=DEFAULT_PACKAGE_DIR):
    """(uavarm_ros.msg, uavarm_ros.srv): catkin's, in a built workspace; else generated now
    (the toolchain's tests run the node from the source folder)."""
    try:
        return importlib.import_module(f"{PACKAGE}.msg"), importlib.import_module(f"{PACKAGE}.srv")
    except ImportError:
        return load_interfaces(package_dir)


def main(argv=None, package_dir=DEFAULT_PACKAGE_DIR) -> int:
    rospy = import_ros()
    msg, srv = interfaces(package_dir)
    rospy.init_node("arm", argv=argv)
    try:
        node = ArmNode(rospy, msg, srv)
    except ValueError as exc:
        rospy.logfatal(f"arm: {exc}")
        return 2
    node.spin()
    return 0
