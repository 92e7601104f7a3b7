"""`uavarm calibrate servos PORT`: each servo's zero (its units at joint angle 0) and direction,
checked on the arm before anything is written.

1. The servos are powered with the torque off (a bench enable: nothing is driven with the
   model file's values, which may be wrong), or, on an arm already enabled and parked, the
   torque goes off only once the user says the arm is held.
2. The user holds the arm at the zero pose: the servos' readings there are the zeros. The torque
   comes back on holding that pose; each joint is jogged a little and back, and the user says
   which way it went: the directions.
3. A result far from the model file's (a zero more than ZERO_WINDOW_DEG away, a direction
   changed) stops here unless the user allows it (plausible.settle).
4. The verification move: with the new zeros and directions the arm goes slowly (jogs at the
   park speed) through VERIFY's poses, each told in plain words; any "no" discards the result.
   Where gravity pulls hard on a joint that sits near its zero, the sign of its servo's
   load (Present Load; an XM430-W350's Present Current) must be the one the new direction
   predicts (a load too small to tell is said).
5. The arm comes back to the zero pose (where it hangs, verified; after a failed check the user
   holds it first) and the torque and the servo supply go off: the new values are flown only
   once written, regenerated and flashed.

The verification poses and the paths between them (one joint at a time) are clear of the
body and the legs even if every zero is off by ROUTE_SAFE_DEG and every direction is the
wrong way round (checked against the model's own predicates before the arm moves), so a
wrong calibration shows itself without harm."""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import model_edit, plausible
from .fit import CalibrationError
from .guide import TRIES, ask_reading
from ..link import CommandRefused
from ..model import config, messages, pose_tolerance, servo as servo_map, servo_models

ZERO_POSE = ("Hold the arm hanging straight down, joint 1 turned so that raising joint 2 would swing it "
             "towards the drone's front (+x): every joint at 0 deg. Keep it there and press Enter.")
# What a joint does when its angle grows (the DH convention of the model file), from that pose.
DIRECTION_QUESTIONS = (
    "Did joint 1 turn clockwise, seen from above (towards the drone's right, -y)?",
    "Did joint 2 swing the arm forward (towards the drone's front, +x)?",
    "Did joint 3 swing the forearm forward (towards +x)?",
)
JOG_DEG = 6.0                      # enough to see, small enough to be harmless (AX-12A: 20 units)
SPREAD_DEG = 0.6                   # a still joint's readings stay within this (AX-12A: 2 units)
# A zero this far from the model file's is not a careful calibration's refinement of it (a
# servo remounted a spline over is 360/25 = 14.4 deg off; a pose held by eye is within 3).
ZERO_WINDOW_DEG = 15.0
# The verification route stays clear with every zero off by this much (beyond the window, for
# a result the user allowed) and any direction the wrong way round.
ROUTE_SAFE_DEG = 25.0
# A load this small (N m) says nothing of its direction: a holding AX-12A's reading wanders by
# a few units (8 units of its 1023: 0.0117 N m). The firmware streams every servo's load as
# the AX-12A's Present Load word (bit 10 the sense), in the servo's own units: 8 of an
# XL430-W250's Present Load, 3 of an XM430-W350's Present Current (whose 4.1 N m stall makes
# this light arm's loads 5 or 6 units of 2.69 mA).
LOAD_MIN_NM = 8 * servo_models.AX_12A.load_unit_nm
ARRIVE_S = 20.0                    # the slowest verification jog at park speed takes 1.5 s


@dataclass(frozen=True)
class Pose:
    """A verification pose: joint angles (deg), what the user sees there (with {front} or {leg}
    filled in from the model's geometry), and the joint whose Present Load shows its direction
    there (gravity pulls hard on it while it sits at its zero), if any."""
    q_deg: tuple[float, float, float]
    sight: str
    load_joint: int | None = None


VERIFY = (
    Pose((0.0, 0.0, 90.0), "the upper arm still hanging straight down and the forearm level, pointing towards "
                           "the drone's {front}", 2),
    Pose((0.0, 60.0, 0.0), "the whole arm straight, swung up towards the drone's {front}, two thirds of the way "
                           "from hanging to level (60 deg)", 3),
    Pose((45.0, 0.0, 25.0), "the upper arm hanging straight down and the forearm swung out a little (25 deg) "
                            "towards the {leg} landing leg"),
)
ZERO = (0.0, 0.0, 0.0)


def _compass(x: float, y: float) -> str:
    """The base frame's horizontal direction (x front, y left) in words."""
    names = ("front", "front-left", "left", "back-left", "back", "back-right", "right", "front-right")
    return names[round(math.degrees(math.atan2(y, x)) / 45.0) % 8]


def _points(m: config.Model, q_deg) -> np.ndarray:
    """Base-frame positions (mm) of joint 3, the forearm's middle and the end effector."""
    from ..model import kinematics
    j3, ee = kinematics.fk_points(m, at=[math.radians(v) for v in q_deg])
    j3, ee = np.array(j3, float).ravel(), np.array(ee, float).ravel()
    return np.array([j3, (j3 + ee) / 2, ee])


def sight(m: config.Model, pose: Pose) -> str:
    """What the user should see at the pose, its directions named from the model's geometry."""
    ee = _points(m, pose.q_deg)[2]
    legs = [a for a in m.leg_angles if abs((a - pose.q_deg[0] + 180) % 360 - 180) < 1e-6]
    leg = _compass(math.cos(math.radians(legs[0])), -math.sin(math.radians(legs[0]))) if legs else ""
    return pose.sight.format(front=_compass(ee[0], ee[1]), leg=leg)


def holding_sign(m: config.Model, pose: Pose) -> int:
    """The sense (+1: the joint angle's, -1: against it) in which joint pose.load_joint's servo
    must push to hold the pose against gravity, the base level: the links beyond it rise as
    the angle grows (+1) or sink (-1), whatever their masses; 0 if the pose does not tell."""
    j = pose.load_joint - 1
    step = 0.5
    up, down = (list(pose.q_deg) for _ in range(2))
    up[j] += step
    down[j] -= step
    dz = (_points(m, up)[:, 2] - _points(m, down)[:, 2]) / math.radians(2 * step)   # mm per rad
    beyond = dz[1:] if j == 2 else dz                                             # joint 3 carries the forearm only
    if np.all(beyond > -1e-6) and beyond.max() > 10.0:
        return 1
    if np.all(beyond < 1e-6) and beyond.min() < -10.0:
        return -1
    return 0


def load_sense(load: int) -> tuple[int, int]:
    """A load word as the AX-12A's Present Load reads, and as the firmware streams any servo's
    (sense in servo units: +1 the way its position grows (counter-clockwise, bit 10 clear), -1
    the other; magnitude 0-1023)."""
    return (-1 if load & 0x400 else 1), load & 0x3FF


# ---------------------------------------------------------------- the moves, checked first

# From the zero pose through the verification poses and back, one joint moving at a time.
ROUTE = (ZERO, (0.0, 0.0, 90.0), ZERO, (0.0, 60.0, 0.0), ZERO, (0.0, 0.0, 25.0), (45.0, 0.0, 25.0),
         (0.0, 0.0, 25.0), ZERO)


def unsafe_on_route(m: config.Model, window_deg: float = ROUTE_SAFE_DEG) -> str | None:
    """Why the verification route is not clear of the body and legs with every zero off by up
    to window_deg and any direction the wrong way round; None if it is. Each path is taken a
    degree at a time, each step's box of joint errors (window_deg and the half degree to the
    next step) bounded by pose_tolerance's interval arithmetic: a conservative verdict."""
    known = {}      # a box met again (a joint at 0 either way, a path walked back) is not bounded again
    for a, b in zip(ROUTE, ROUTE[1:]):
        for q in np.linspace(a, b, round(max(abs(np.subtract(b, a)))) + 1):
            for ways in itertools.product((1, -1), repeat=3):
                box = tuple(float(v) for v in q * ways)
                if box not in known:
                    known[box] = pose_tolerance.least(m, box, window_deg + 0.5)
                c = known[box]
                if not c.clear:
                    return (f"on the way from {list(a)} to {list(b)} deg, at {[round(float(v), 1) for v in q]} deg "
                            f"with the directions {ways} and the joints off by {list(c.offsets_deg)} deg, "
                            f"{c.part} would be {-c.mm:.1f} mm past the {c.boundary}")
    return None


# ---------------------------------------------------------------- on the arm

def _state(hb: dict) -> str:
    return messages.STATES[hb["state"]][0]


def _zero_pose_units(arm, m: config.Model, ask, seconds: float) -> list[int]:
    """Each servo's position (units) while the user holds the arm at the zero pose."""
    still = int(SPREAD_DEG * _units_per_deg(m))
    for attempt in range(TRIES):
        ask_reading(arm, ask, ZERO_POSE)
        frames = arm.collect("servo_status", seconds)
        by_servo = [[f["position"] for f in frames if f["servo"] == j] for j in range(3)]
        missing = [j + 1 for j, v in enumerate(by_servo) if len(v) < 3]
        if missing:
            raise CalibrationError(f"no readings from the servo of joint(s) {missing}: is it connected and "
                                   "configured (heartbeat servo_timeout)?")
        spread = [max(v) - min(v) for v in by_servo]
        if max(spread) <= still:
            return [round(float(np.mean(v))) for v in by_servo]
        message = (f"the arm moved (joint readings spread {spread} units, still is <= {still}): "
                   "hold it still and take the pose again")
        if attempt == TRIES - 1:
            raise CalibrationError(message)
        print(f"  {message}")
    raise AssertionError("unreachable")


def _latest(arm, field: str, seconds: float = 0.3) -> list[int]:
    """Each servo's newest streamed `field` after `seconds` of readings."""
    frames = arm.collect("servo_status", seconds)
    latest = {}
    for f in frames:
        latest[f["servo"]] = f[field]
    if len(latest) < 3:
        raise CalibrationError(f"no readings from the servo of joint(s) {[j + 1 for j in range(3) if j not in latest]}")
    return [latest[j] for j in range(3)]


def _units_per_deg(m: config.Model) -> float:
    return float(servo_map.units_per_rad(m)) * math.pi / 180


class _Arm:
    """The arm during the verification: jogs to poses in the new calibration's units."""

    def __init__(self, arm, m: config.Model, zeros, directions):
        self.arm, self.zeros, self.directions = arm, zeros, directions
        self.per_deg = _units_per_deg(m)

    def units(self, q_deg) -> list[int]:
        return [round(z + d * q * self.per_deg) for z, d, q in zip(self.zeros, self.directions, q_deg)]

    def go(self, q_deg) -> None:
        """Each joint in turn (joint 1 first) to its angle of q_deg, waiting until it is there."""
        goals = _latest(self.arm, "goal", 0.1)
        for j, target in enumerate(self.units(q_deg)):
            if target != goals[j]:
                try:
                    self.arm.jog(j + 1, units=target - goals[j])
                except CommandRefused as exc:
                    raise CalibrationError(f"the board refused the move to {list(q_deg)} deg ({exc}): the "
                                           "calibration it was built with is far from this one") from None
                end = self.arm.clock() + ARRIVE_S
                while _state(self.arm.next_heartbeat()) != "jogged":
                    if self.arm.clock() > end:
                        raise CalibrationError(f"joint {j + 1} did not reach its verification pose in {ARRIVE_S:g} s")


def _verify(arm, m: config.Model, zeros, directions, confirm) -> None:
    """The verification move; CalibrationError (after the arm is back at the zero pose) on any
    "no" or a load of the wrong sense."""
    mover = _Arm(arm, m, zeros, directions)
    checks = {p.q_deg: p for p in VERIFY}
    at = 0
    try:
        for at in range(1, len(ROUTE)):
            mover.go(ROUTE[at])
            pose = checks.get(ROUTE[at])
            if pose is None:
                continue
            if pose.load_joint:
                _check_load(arm, m, pose, directions)
            if not ask_reading(arm, confirm, f"Is the arm now {sight(m, pose)}?"):
                raise CalibrationError(
                    f"the arm was not {sight(m, pose)}: a zero or a direction is wrong. Nothing written: take "
                    "the zero pose again more carefully (every joint at 0 deg) and watch each jog's direction")
    except CalibrationError:
        for back in reversed(ROUTE[:at]):         # the way it came
            mover.go(back)
        raise


def _check_load(arm, m: config.Model, pose: Pose, directions) -> None:
    j = pose.load_joint
    want = holding_sign(m, pose) * directions[j - 1]
    sense, size = load_sense(_latest(arm, "load")[j - 1])
    least = math.ceil(LOAD_MIN_NM / m.servo_model.load_unit_nm)
    if want == 0:
        print(f"  at {list(pose.q_deg)} deg gravity hardly turns joint {j}: its direction is taken from your answer")
        return
    if size < least:
        print(f"  joint {j}'s servo holds {size} units of load at {list(pose.q_deg)} deg: too little to tell its "
              "direction; taken from your answer")
        return
    if sense != want:
        towards = lambda sense: "higher" if sense > 0 else "lower"
        raise CalibrationError(
            f"at {list(pose.q_deg)} deg joint {j}'s servo holds the arm pushing towards {towards(sense)} units "
            f"({size} units of load), but with direction {directions[j - 1]:+d} it would push towards "
            f"{towards(want)} units: the direction of joint 2 or of joint 3 is wrong. Nothing written: run the "
            "calibration again and watch each jog")
    print(f"  joint {j}'s servo holds against gravity the way direction {directions[j - 1]:+d} says "
          f"({size} units of load)")


def _departures(m: config.Model, zeros, directions) -> list[plausible.Departure]:
    per_deg = _units_per_deg(m)
    out = []
    for name, s, z, d in zip(config.JOINTS, m.servos, zeros, directions):
        if abs(z - s.zero) > ZERO_WINDOW_DEG * per_deg:
            out.append(plausible.Departure(f"servo.{name}.zero", str(s.zero), str(z),
                                           f"a zero more than {ZERO_WINDOW_DEG:g} deg "
                                           f"({ZERO_WINDOW_DEG * per_deg:.0f} units) from the model file's"))
        if d != s.direction:
            out.append(plausible.Departure(f"servo.{name}.direction", f"{s.direction:+d}", f"{d:+d}",
                                           "a direction the other way round from the model file's (a servo "
                                           "mounted reversed?)"))
    return out


def _powered_limp(arm, ask) -> None:
    """The servos powered with the torque off: a disabled arm is enabled limp (nothing driven);
    an enabled one goes limp once the user holds it."""
    hb = arm.next_heartbeat()
    if hb["engaged"]:
        raise CalibrationError("the arm is engaged: disengage it first (`uavarm link PORT disengage`)")
    if not hb["enabled"]:
        try:
            arm.enable(limp=True)
        except CommandRefused as exc:
            raise CalibrationError(f"the servos did not all answer when powered ({exc}): is each connected, with "
                                   "its id and baud set (`uavarm servos setup`)?") from None
    elif _state(hb) != "limp":
        ask_reading(arm, ask, "Hold the arm with one hand: its torque goes off when you press Enter, "
                              "and it would drop.")
        arm.torque(False)


def servos(arm, model_path: Path, ask, confirm, seconds: float = 1.0, allow_unusual: bool = False) -> bool:
    """Zeros and directions, a verification move, then the model file (see the module's text)."""
    m = config.load(model_path)
    jog = round(JOG_DEG * _units_per_deg(m))
    why = unsafe_on_route(m)
    if why:
        raise CalibrationError(f"this model's verification poses are not safe with a calibration that is off: {why}")
    _powered_limp(arm, ask)
    with arm.kept_alive():
        arm.stream(servos=True)
        try:
            units = _zero_pose_units(arm, m, ask, seconds)
            arm.torque(True)                  # held where the hands left it
            directions = []
            for j, question in enumerate(DIRECTION_QUESTIONS, 1):
                arm.jog(j, units=jog)
                directions.append(1 if ask_reading(arm, confirm, question) else -1)
                arm.jog(j, units=-jog)
            for j, (u, d, s) in enumerate(zip(units, directions, m.servos), 1):
                print(f"joint {j}: zero {u} units (was {s.zero}), direction {d:+d} (was {s.direction:+d})")
            plausible.settle(_departures(m, units, directions), allow_unusual, confirm)
            print("The verification move: the arm goes slowly through a few poses with the new values.")
            _verify(arm, m, units, directions, confirm)
        except CalibrationError:
            _rest(arm, ask, hold=True)        # at the zero pose, which may not be where it hangs
            raise
        _rest(arm, ask, hold=False)           # at the zero pose, verified: where it hangs
    values = {}
    for name, u, d in zip(config.JOINTS, units, directions):
        values[f"servo.{name}.zero"] = u
        values[f"servo.{name}.direction"] = d
    return model_edit.write(model_path, values, confirm)


def _rest(arm, ask, hold: bool) -> None:
    """The end of the calibration: torque and servo supply off (the firmware's values are not
    the new ones: nothing is driven with them), once the user holds the arm if asked."""
    arm.stream(servos=False)
    if hold and _state(arm.next_heartbeat()) != "limp":
        ask_reading(arm, ask, "Hold the arm: its torque and the servos' supply go off when you press Enter.")
    arm.disable()
    print("The servos' supply is off. Once the new values are written: `make codegen`, rebuild and flash; "
          "`uavarm link PORT enable` then parks the arm with them.")
