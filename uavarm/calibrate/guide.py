"""`uavarm calibrate imu|mounting|servos|lag|link PORT`: guided calibrations over the link,
written into the model file. Each step says what to do, waits for Enter, takes the streamed samples
(raw IMU, or servo positions), checks them, and says what it measured; a result that is
implausible or noisy is refused with the reason and the model file is left as it was; an
unusual one (plausible) is written only if allowed and confirmed again. The servos' zeros and
directions, with their verification move, are servo_zero's.

The procedures take `ask(text)` (wait for the user; the terminal's Enter) and
`confirm(question)` (yes or no), so the tests drive them through a simulated board exactly
as a user does on the bench.

The servo and lag calibrations limp and jog the arm: the board takes those only on the bench
(no drone_attitude or drone_velocity for link.silence_timeout: refused as `flying` otherwise)
and parks a limp or jogged arm once the link has been silent that long (a bench-enabled one
goes limp instead), so they keep it alive (ArmLink.kept_alive: the set position repeated, which
marks no flight) and read the link on while the user acts. The lag calibration parks the arm
when done; the servo calibration cuts the servos' supply (the firmware's zeros are not yet the
new ones)."""
from __future__ import annotations

import math
import threading
import time
from pathlib import Path

import numpy as np

from . import fit, model_edit, plausible
from .fit import CalibrationError, Window
from ..model import config

# The six positions: each IMU axis straight up, then straight down (the axes printed on
# the MPU-6050 breakout).
POSITIONS = (
    "flat, the IMU's Z axis up (components up)",
    "upside down, the IMU's Z axis down",
    "on its side, the IMU's X axis up",
    "on its other side, the IMU's X axis down",
    "on an edge, the IMU's Y axis up",
    "on the opposite edge, the IMU's Y axis down",
)
TRIES = 3
SAME_FACE_DEG = 45.0               # the six faces are 90 deg or more apart


def _another_face(windows: list[Window]):
    """A check for a new position: CalibrationError if the board is as at an earlier one (the
    hand did not turn it, or turned it to a face already taken)."""
    def check(w: Window) -> None:
        for k, earlier in enumerate(windows, 1):
            cos = np.dot(w.accel_g, earlier.accel_g) / (np.linalg.norm(w.accel_g) * np.linalg.norm(earlier.accel_g))
            angle = math.degrees(math.acos(min(1.0, max(-1.0, float(cos)))))
            if angle < SAME_FACE_DEG:
                raise CalibrationError(f"the board is as it was at position {k} ({angle:.0f} deg from it): turn it "
                                       "to this position's face")
    return check


def ask_reading(arm, ask, text: str):
    """ask(text) (or a confirm) while the link is read on, so that the rates of the turn the
    user makes meanwhile are all kept (and none pile up unread), and a kept-alive arm stays so;
    its answer."""
    done, answer, failed = threading.Event(), [], []

    def wait():
        try:
            answer.append(ask(text))
        except BaseException as exc:          # (Ctrl-D: EOFError) raised here again
            failed.append(exc)
        finally:
            done.set()
    threading.Thread(target=wait, daemon=True).start()
    while not done.wait(0.005):
        arm.poll()
    if failed:
        raise failed[0]
    return answer[0]


def _take_streamed(arm) -> list[dict]:
    arm.poll()
    frames = list(arm.streamed["imu_raw"])
    arm.streamed["imu_raw"].clear()
    return frames


class _Record:
    """Every imu_raw frame of a calibration, in order, and where each still position's are."""

    def __init__(self):
        self.frames: list[dict] = []
        self.spans: list[tuple[int, int]] = []

    def position(self, arm, model, ask, text: str, seconds: float, check=lambda w: None) -> Window:
        """The still window the user holds after `text` (asked again, up to TRIES, while it is
        not still or check(window) raises CalibrationError)."""
        for attempt in range(TRIES):
            ask_reading(arm, ask, text)
            self.frames += _take_streamed(arm)           # the turn
            first = len(self.frames)
            arm.collect("imu_raw", seconds, keep=True)
            self.frames += _take_streamed(arm)
            try:
                w = fit.window(self.frames[first:], model.accel_range_g, model.gyro_range_dps)
                check(w)
            except CalibrationError as exc:
                if attempt == TRIES - 1:
                    raise
                print(f"  {exc}")
                continue
            self.spans.append((first, len(self.frames)))
            return w
        raise AssertionError("unreachable")

    def turns(self, ups: list[np.ndarray], range_dps: int) -> list[fit.Turn]:
        """The turns between consecutive positions that were streamed whole (a lost frame
        leaves a turn out, said so), each from the middle of one position's samples to the
        middle of the next's: a position's mean up direction is where the board was then,
        and whatever a hand drifted while holding it the gyro saw."""
        out = []
        middle = [(a + b - 1) // 2 for a, b in self.spans]
        for k in range(len(self.spans) - 1):
            part = self.frames[middle[k]:middle[k + 1] + 1]
            seq = np.array([f["seq"] for f in part])
            lost = int(((np.diff(seq) - 1) % 65536).sum())
            if lost:
                print(f"  the turn from position {k + 1} to {k + 2}: {lost} of its IMU samples lost on the link, "
                      "not used")
                continue
            counts = np.array([[f["gx"], f["gy"], f["gz"]] for f in part], dtype=float)
            gyro = counts * config.gyro_dps_per_lsb(range_dps)
            dt = (np.diff(np.array([f["stamp_us"] for f in part], dtype=np.int64)) % 2 ** 32) * 1e-6
            out.append(fit.Turn(gyro, dt, ups[k], ups[k + 1]))
        return out


def imu(arm, model_path: Path, ask, confirm, seconds: float = 2.0, allow_unusual: bool = False) -> bool:
    """Accelerometer bias and scale from six still positions, the gyro's zero-rate offset,
    and its scale and cross-axis sensitivity from the turns between them."""
    model = config.load(model_path)
    record = _Record()
    arm.stream(imu_every=1)
    try:
        windows = []
        for k, where in enumerate(POSITIONS, 1):
            w = record.position(arm, model, ask, f"Position {k}/{len(POSITIONS)}: the board {where}. "
                                                 "Turn it there in one go, hold it still and press Enter.", seconds,
                                check=_another_face(windows))
            print(f"  {w.samples} samples, mean ({w.accel_g[0]:+.3f}, {w.accel_g[1]:+.3f}, {w.accel_g[2]:+.3f}) g")
            windows.append(w)
    finally:
        arm.stream(imu_every=0)
    accel = fit.fit_accel(windows)
    gyro = fit.gyro_bias(windows)
    print(f"accelerometer: bias ({', '.join(f'{b * 1000:+.1f}' for b in accel.bias)}) mg, "
          f"scale ({', '.join(f'{s:.4f}' for s in accel.scale)}), fit rms {accel.residual_g * 1000:.2f} mg over "
          f"{len(windows)} positions")
    print(f"gyro zero-rate offset: ({', '.join(f'{g:+.2f}' for g in gyro)}) deg/s")
    values = {
        "imu.accel_bias": [round(float(b), 4) for b in accel.bias],
        "imu.accel_scale": [round(float(s), 5) for s in accel.scale],
        "imu.gyro_bias_dps": [round(float(g), 3) for g in gyro],
    }
    cal = model.imu_calibration
    unusual = plausible.accelerometer(cal.accel_bias, cal.accel_scale, values["imu.accel_bias"],
                                      values["imu.accel_scale"])
    ups = [(w.accel_g - accel.bias) / accel.scale for w in windows]
    try:
        scale = fit.fit_gyro_scale(record.turns([u / np.linalg.norm(u) for u in ups], model.gyro_range_dps), gyro)
    except CalibrationError as exc:
        print(f"gyro scale not measured, imu.gyro_scale and imu.gyro_cross_axis left as they are: {exc}")
    else:
        print(f"gyro scale ({', '.join(f'{s:.4f}' for s in scale.scale)}), cross-axis sensitivity up to "
              f"{np.abs(scale.cross_axis).max() * 100:.1f} %, fit rms {scale.residual_deg:.3f} deg over "
              f"{scale.turns} turns")
        values["imu.gyro_scale"] = [round(float(s), 5) for s in scale.scale]
        values["imu.gyro_cross_axis"] = [[0.0 if i == j else round(float(c), 4) for j, c in enumerate(row)]
                                         for i, row in enumerate(scale.cross_axis)]
    plausible.settle(unusual, allow_unusual, confirm)
    return model_edit.write(model_path, values, confirm)


def mounting(arm, model_path: Path, ask, confirm, seconds: float = 3.0, uncalibrated_ok: bool = False,
             allow_unusual: bool = False) -> bool:
    """The IMU's roll and pitch on the base, with the drone standing level (the accelerometer
    calibrated first: its bias would read as a tilt; uncalibrated_ok for an ideal IMU)."""
    model = config.load(model_path)
    cal = model.imu_calibration
    if cal == config.ImuCalibration() and not uncalibrated_ok:
        raise CalibrationError("the accelerometer is not calibrated (its bias would read as a tilt of up to "
                               "3 deg): run `uavarm calibrate imu` first")
    arm.stream(imu_every=1)
    try:
        w = _Record().position(arm, model, ask, "Stand the drone level (a spirit level on the frame) with the "
                                                "arm mounted. Press Enter.", seconds)
    finally:
        arm.stream(imu_every=0)
    up = (w.accel_g - np.array(cal.accel_bias)) / np.array(cal.accel_scale)
    if abs(np.linalg.norm(up) - 1.0) > 0.03:
        raise CalibrationError(f"the calibrated accelerometer reads {np.linalg.norm(up):.3f} g at rest, not 1 g: "
                               "run `uavarm calibrate imu` first")
    roll, pitch = fit.mounting_from_gravity(up)
    yaw = model.imu_mounting_rpy_deg[2]
    print(f"IMU on the base: roll {roll:+.2f} deg, pitch {pitch:+.2f} deg (yaw {yaw:+.2f} deg kept: "
          "gravity does not show it)")
    rpy = [round(roll, 2), round(pitch, 2), yaw]
    plausible.settle(plausible.mounting(model.imu_mounting_rpy_deg, *rpy), allow_unusual, confirm)
    return model_edit.write(model_path, {"imu.mounting_rpy": rpy}, confirm)


# Servo lag: each joint jogged this far toward the middle of its travel and back, at the park
# speed; the readings taken for this long after each jog's command.
LAG_JOG_RAD = 0.25                 # 14 deg (49 AX-12A units, 163 XM430-W350 ones): a ramp of a quarter second
LAG_SETTLE_S = 0.4


def _jog_record(arm, joint: int, angle: float, seconds: float):
    """(time s, goal, position) of joint's servo from a jog to `angle` until `seconds` after."""
    arm.collect("servo_status", 0.1)                  # a few readings at rest first
    arm.jog(joint, angle=angle)
    frames = arm.collect("servo_status", seconds, keep=True)
    mine = [f for f in frames if f["servo"] == joint - 1]
    stamps = np.array([f["stamp_us"] for f in mine], dtype=np.int64)
    t = np.concatenate([[0.0], np.cumsum(np.diff(stamps) % 2**32) * 1e-6]) if len(mine) else np.zeros(0)
    return t, np.array([f["goal"] for f in mine], float), np.array([f["position"] for f in mine], float)


def lag(arm, model_path: Path, ask, confirm, seconds: float = LAG_SETTLE_S, allow_unusual: bool = False) -> bool:
    """How far each servo's shaft lags its goal: a jog of each joint and back, fitted as a
    first-order lag with dead time; servo.response_lag set to the joints' mean, and the lead
    time moved by the same difference (it also covers the loop's own delay)."""
    model = config.load(model_path)
    hb = arm.next_heartbeat()
    if not hb["enabled"] or hb["engaged"]:
        raise CalibrationError("the arm must be enabled and not engaged: `uavarm link PORT enable` first")
    ask(f"Each joint will turn {np.degrees(LAG_JOG_RAD):.0f} deg and back at the park speed, one at a time, "
        "with nothing touching the arm. Keep clear and press Enter.")
    q = [hb["p1"], hb["p2"], hb["p3"]]   # the shafts as read
    unread = [j for j, v in enumerate(q, 1) if not np.isfinite(v)]
    if unread:
        servos = " and ".join(f"joint {j}'s servo" for j in unread)
        raise CalibrationError(f"{servos} could not be read (no position): is it plugged in and powered? "
                               "check the servo bus and try again")
    fits = []
    with arm.kept_alive():
        arm.stream(servos=True)
        try:
            for j, limit in enumerate(model.limits, 1):
                middle = np.radians((limit.min_deg + limit.max_deg) / 2)
                out = q[j - 1] + (LAG_JOG_RAD if middle >= q[j - 1] else -LAG_JOG_RAD)
                records = [_jog_record(arm, j, out, seconds), _jog_record(arm, j, q[j - 1], seconds)]
                f = fit.fit_servo_lag(records, j, float(model.servo_model.deg_per_unit))
                print(f"joint {j}: {f.lag * 1000:.1f} ms behind the jog's goal (fit rms {f.rms_units:.2f} units "
                      f"over {sum(len(r[0]) for r in records)} readings)")
                fits.append(f)
        finally:
            arm.stream(servos=False)
        arm.disengage()                   # (from the jogged pose it started at: parks)
    # At the jog's speed the servo's speed limit equals the goal's ramp, so its profile reaches
    # each tick's goal only as the next is sent: one tick of the lag is the jog's, not the
    # servo's (following the tilt, at the working speed, it catches up within the tick).
    tick = 1.0 / model.sample_rate
    measured = max(0.0, float(np.mean([f.lag for f in fits])) - tick)
    lead = max(0.0, model.estimator.lead_time + measured - model.servo_response_lag)
    print(f"servo lag {measured * 1000:.1f} ms (the joints' mean less the {tick * 1000:.0f} ms tick the jog adds; "
          f"was {model.servo_response_lag * 1000:.1f}): lead time "
          f"{lead * 1000:.1f} ms (was {model.estimator.lead_time * 1000:.1f})")
    values = {"servo.response_lag": round(measured, 4), "estimator.lead_time": round(lead, 4)}
    plausible.settle(plausible.servo_lag(model.servo_response_lag, values["servo.response_lag"],
                                         model.estimator.lead_time, values["estimator.lead_time"]),
                     allow_unusual, confirm)
    return model_edit.write(model_path, values, confirm)


LINK_SECONDS = 5.0
PING_RATE_HZ = 50.0


def _round_trips(arm, seconds: float, wait: float) -> tuple[list[tuple[float, float, int]], int]:
    """Pings at PING_RATE_HZ for `seconds`, then `wait` s for the last answers: (sent,
    received, board's arrival us) of each answered one, in the order sent, and how many were
    sent."""
    arm.poll()
    arm.pongs.clear()
    sent = []
    for k in range(max(1, round(seconds * PING_RATE_HZ))):
        sent.append(arm.ping(k))
        while arm.clock() < sent[-1] + 1.0 / PING_RATE_HZ:
            arm.poll()
            time.sleep(0.0005)   # (a poll's interval: the link's clock paces the pings)
    end = arm.clock() + wait
    while arm.clock() < end:
        arm.poll()
        time.sleep(0.0005)
    back = {}
    for pong, received in arm.pongs:
        k = pong["seq"]
        if k < len(sent) and pong["stamp_us"] == int(sent[k] * 1e6) & 0xFFFFFFFF:
            back[k] = (sent[k], received, pong["arrived_us"])
    return [back[k] for k in sorted(back)], len(sent)


def link(arm, model_path: Path, ask, confirm, seconds: float = LINK_SECONDS, upstream_ms: float = 0.0) -> bool:
    """The link's fixed delay from this computer to the board (half the quickest round trip
    of pings the board answers at once), plus `upstream_ms` (how old the attitude's stamps
    already are when they reach this computer): estimator.link_delay_min."""
    model = config.load(model_path)
    arm.next_heartbeat()
    ask(f"The link's delay will be measured for {seconds:g} s ({PING_RATE_HZ:.0f} pings a second); "
        "the arm may be in any state (pings keep nothing alive: an engaged, limp or jogged arm parks). "
        "Press Enter.")
    # long enough for the answers of any link the estimator could use
    exchanges, sent = _round_trips(arm, seconds, wait=2 * model.estimator.link_delay_max + 0.1)
    d = fit.fit_link_delay(exchanges, sent)
    delay = d.one_way + upstream_ms / 1000.0
    print(f"{d.answered} of {d.sent} pings answered; quickest round trip {d.round_trip_min * 1000:.1f} ms, so "
          f"{d.one_way * 1000:.1f} ms each way; one-way spread above it {d.spread_p50 * 1000:.1f} ms median, "
          f"{d.spread_p95 * 1000:.1f} ms at 95 %")
    if upstream_ms:
        print(f"plus {upstream_ms:g} ms before the stamps reach this computer: {delay * 1000:.1f} ms")
    if delay >= model.estimator.link_delay_max:
        raise CalibrationError(f"a link delay of {delay * 1000:.1f} ms is not below estimator.link_delay_max "
                               f"({model.estimator.link_delay_max * 1000:.0f} ms): every drone_attitude would be "
                               "refused as too old; is this the drone's computer, on the board's USB port?")
    print(f"estimator.link_delay_min {delay * 1000:.1f} ms (was {model.estimator.link_delay_min * 1000:.1f})")
    return model_edit.write(model_path, {"estimator.link_delay_min": round(delay, 4)}, confirm)


# The calibrations whose results are checked against plausible's windows (--allow-unusual).
UNUSUAL_CHECKED = ("imu", "mounting", "servos", "lag")


def terminal_ask(text: str) -> None:
    input(text + " ")


def terminal_confirm(question: str) -> bool:
    return input(question + " [y/N] ").strip().lower() in ("y", "yes")


def command(args) -> int:
    import sys
    from ..link import ArmLink, LinkError
    path = Path(args.model) if args.model else config.DEFAULT_MODEL
    confirm = (lambda q: True) if args.yes else terminal_confirm
    if args.upstream_ms is not None and args.what != "link":
        print(f"error: --upstream-ms is for `uavarm calibrate link` only, not {args.what}", file=sys.stderr)
        return 2
    if args.yes and args.what == "servos":
        print("error: --yes is not for `uavarm calibrate servos`: its questions are what you see the arm do",
              file=sys.stderr)
        return 2
    if args.allow_unusual and args.what not in UNUSUAL_CHECKED:
        print(f"error: --allow-unusual is for `uavarm calibrate {'|'.join(UNUSUAL_CHECKED)}` only, not {args.what}",
              file=sys.stderr)
        return 2
    try:
        config.load(path)
        with ArmLink(args.port) as arm:
            arm.next_heartbeat()
            from .servo_zero import servos
            run = {"imu": imu, "mounting": mounting, "servos": servos, "lag": lag, "link": link}[args.what]
            options = {} if args.seconds is None else {"seconds": args.seconds}
            if args.upstream_ms is not None:
                options["upstream_ms"] = args.upstream_ms
            if args.what in UNUSUAL_CHECKED:
                options["allow_unusual"] = args.allow_unusual
            run(arm, path, terminal_ask, confirm, **options)
    except (LinkError, CalibrationError, config.ModelError, OSError) as exc:   # OSError: the port failed
        print(f"error: {exc}", file=sys.stderr)
        print(f"{path}: left as it was", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, EOFError):
        print(f"\nstopped; {path} left as it was", file=sys.stderr)
        return 1
    return 0
