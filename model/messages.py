"""LLCP message layouts, written once: the generator emits the C pack/unpack functions and
uavarm.link.messages builds the Python codec from the same table.

On the wire each payload is the message id followed by the fields as a packed
little-endian C struct (what the MRS llcp peer sends and expects). Device -> drone
payloads stay <= 127 bytes (the ROS peer truncates longer ones).
"""
from __future__ import annotations

from dataclasses import dataclass

# field type -> (C type, struct format character, size in bytes)
TYPES = {
    "u8": ("uint8_t", "B", 1),
    "u16": ("uint16_t", "H", 2),
    "i16": ("int16_t", "h", 2),
    "u32": ("uint32_t", "I", 4),
    "i32": ("int32_t", "i", 4),
    "f32": ("float", "f", 4),
}
TX_MAX_PAYLOAD = 127


@dataclass(frozen=True)
class Message:
    name: str
    id: int
    direction: str            # "to_arm" or "to_drone"
    fields: tuple             # ((name, type), ...)
    doc: str

    @property
    def size(self) -> int:
        """Payload bytes including the id byte."""
        return 1 + sum(TYPES[t][2] for _, t in self.fields)

    @property
    def struct_format(self) -> str:
        return "<B" + "".join(TYPES[t][1] for _, t in self.fields)


MESSAGES = (
    Message("enable", 0x10, "to_arm", (("on", "u8"),),
            "1: servo power on, park and hold; 0: servo power off at once, engage cleared; "
            "2 (bench, for calibrating the servos' zeros and directions; refused while engaged or the drone "
            "flying): servo power on and the servos configured as by 1, but the torque left off, Torque Limit "
            "servo.bench_torque_limit of the maximum (every move on the bench torque-limited) and no goal "
            "sent: the arm hangs limp where it is, its positions still read (the service commands and "
            "streams work). Until enable 1 or 0 the firmware never moves it by the model's calibration on "
            "its own: what would park it (the link silent, a drone_attitude or drone_velocity, engage 0 "
            "from a jogged or held pose, a servo found reset) turns the torque off instead, and engage is "
            "refused (refusal bench). enable 1 then ends the bench: the torque on, the full Torque Limit, and "
            "the arm parks"),
    Message("engage", 0x11, "to_arm", (("on", "u8"),),
            "1 (only while enabled): go to the set position and stabilise; 0: park"),
    Message("set_position", 0x12, "to_arm", (("x", "f32"), ("y", "f32"), ("z", "f32")),
            "end-effector target in mm, gravity-aligned heading-following frame at the arm's base"),
    Message("drone_attitude", 0x13, "to_arm",
            (("seq", "u16"), ("stamp_us", "u32"), ("roll", "f32"), ("pitch", "f32")),
            "the drone's attitude from its flight controller (rad, Z-Y-X Euler) at >= 50 Hz; "
            "seq counts up by one per message, stamp_us is the drone's clock. It keeps the link alive "
            "and marks the drone as flying: a limp or jogged arm parks with the torque on (bench-enabled: goes "
            "limp instead), the streams stop, and the service commands are refused for link.silence_timeout after it; fused when "
            "estimator.drone_attitude is set. "
            "Signs as REP 103 (x forward, y left, z up): roll positive right side down, pitch positive "
            "nose down (a flight controller's FRD pitch with its sign flipped)"),
    Message("jog", 0x14, "to_arm", (("joint", "u8"), ("mode", "u8"), ("value", "f32")),
            "service (enabled, not engaged, the drone not flying): move joint 1-3 at park speed, mode 0 to the angle value "
            "(rad), mode 1 by value servo units from its goal; checked like every move (limits, body, "
            "legs, the swept path). Turns the torque back on if it was off"),
    Message("torque", 0x15, "to_arm", (("on", "u8"),),
            "service (enabled, not engaged, the drone not flying): 0 torque off (limp for positioning by hand; the supply "
            "stays on and positions are still read), 1 torque on, holding where the arm stands"),
    Message("stream", 0x16, "to_arm", (("imu_every", "u8"), ("servos", "u8")),
            "service (not engaged, and to turn one on the drone not flying; engage and the drone's "
            "messages stop it): imu_raw every imu_every ticks (0 off), "
            "servo_status after every status read (servos 1) or not (0)"),
    Message("ping", 0x17, "to_arm", (("seq", "u16"), ("stamp_us", "u32")),
            "answered at once, in any state, with pong (seq and stamp_us given back): the round trip "
            "and the board's time of arrival measure the link's delay (`uavarm calibrate link`). It keeps "
            "nothing alive: alone, an engaged, limp or jogged arm parks after link.silence_timeout (bench-enabled: "
            "goes limp)"),
    Message("drone_velocity", 0x18, "to_arm",
            (("seq", "u16"), ("stamp_us", "u32"), ("vx", "f32"), ("vy", "f32"), ("vz", "f32")),
            "the velocity of the drone's centre of rotation from its odometry (m/s, gravity-aligned "
            "heading-following frame: x forward, y left, z up) at >= 50 Hz; seq and stamp_us as in "
            "drone_attitude (the same clock); it marks the drone as flying as drone_attitude does. Fused when "
            "estimator.drone_velocity is set; refused when "
            "not finite or any component beyond 50 m/s, stale or not newer than the last"),
    Message("heartbeat", 0x20, "to_drone", (
        ("seq", "u16"), ("uptime_ms", "u32"),
        ("enabled", "u8"), ("engaged", "u8"), ("unreachable", "u8"), ("state", "u8"), ("refusal", "u8"),
        ("faults", "u16"),
        ("servo1_error", "u8"), ("servo2_error", "u8"), ("servo3_error", "u8"),
        ("set_x", "f32"), ("set_y", "f32"), ("set_z", "f32"),
        ("q1", "f32"), ("q2", "f32"), ("q3", "f32"),
        ("link_frames_ok", "u16"), ("link_errors", "u16"), ("link_echoes", "u16"), ("servo_timeouts", "u16"),
        ("servo_resets", "u16"), ("ticks_late", "u16"), ("ticks_missed", "u16"),
        ("bus_state", "u8"), ("reset_cause", "u8"), ("last_fault", "u8"), ("firmware", "u32"), ("model", "u32"),
        ("servo1_voltage", "u8"), ("servo1_temperature", "u8"), ("servo1_load", "u16"),
        ("servo2_voltage", "u8"), ("servo2_temperature", "u8"), ("servo2_load", "u16"),
        ("servo3_voltage", "u8"), ("servo3_temperature", "u8"), ("servo3_load", "u16"),
        ("lagging_joints", "u8"), ("estimate_sources", "u8"),
        ("p1", "f32"), ("p2", "f32"), ("p3", "f32"),
    ), "every link.heartbeat_period: sequence number and uptime, enabled (0 off, 1 on, 2 on limp for calibration: "
       "enable 2, the bench), state, set position, the joints' goals q1..q3 (rad, the last commanded), fault flags, "
       "counters, the bus and reset state (with the exception that halted the firmware before it), firmware and model identity, each servo's supply (0.1 V), "
       "temperature (deg C) and load (AX-12A units, bit 10 = direction), the joints whose shaft fell "
       "behind its goal since the last heartbeat (bit 0 = joint 1; faults.servo_lagging), what corrects "
       "the attitude estimate (estimate_sources: SOURCES bits), "
       "and the shafts p1..p3 (rad) as the latest status reads found them, NaN where none succeeded "
       "(the supply off, a servo not answering)"),
    Message("imu_raw", 0x21, "to_drone", (
        ("seq", "u16"), ("stamp_us", "u32"),
        ("ax", "i16"), ("ay", "i16"), ("az", "i16"), ("temperature", "i16"),
        ("gx", "i16"), ("gy", "i16"), ("gz", "i16"), ("fresh", "u8"),
    ), "when streamed: the MPU-6050's registers as read (counts, the IMU's own axes, "
       "ACCEL_XOUT_H..GYRO_ZOUT_L), the board's microsecond time of the read, and whether the "
       "chip had latched a new sample"),
    Message("servo_status", 0x22, "to_drone", (
        ("seq", "u16"), ("stamp_us", "u32"), ("servo", "u8"),
        ("goal", "u16"), ("position", "u16"), ("speed", "u16"), ("load", "u16"),
    ), "when streamed: one servo's status read (servo 0-2; AX-12A units: the goal last sent, "
       "present position, speed and load), with the board's microsecond time of the reply"),
    Message("pong", 0x23, "to_drone", (("seq", "u16"), ("stamp_us", "u32"), ("arrived_us", "u32")),
            "the answer to ping: its seq and stamp_us, and the board's microsecond time when it "
            "arrived (the clock drone_attitude arrivals are timed in)"),
)

# heartbeat.refusal: why the last refused command was refused
REFUSALS = (
    ("none", "nothing refused since the last command taken"),
    ("not_enabled", "engage while the servo power is off"),
    ("servos_starting", "engage while the servos boot and are configured"),
    ("servo_fault", "engage while a servo does not answer, reports an error, or was found reset"),
    ("imu_not_ready", "engage before the IMU has given usable samples for the estimator to settle"),
    ("servo_tracking", "engage while a servo does not follow its goal"),
    ("no_route", "engage or set_position with no clear route there"),
    ("not_finite", "set_position with a NaN or infinite coordinate"),
    ("engaged", "a service command (jog, torque, stream, enable 2) while engaged: disengage first"),
    ("bad_jog", "jog of a joint other than 1-3, by a non-finite value, or to a pose outside the limits, "
                "in the body or a leg, or with no clear path"),
    ("flying", "a service command (torque, jog, a stream on, enable 2) while the drone's attitude or "
               "velocity came within link.silence_timeout: the drone may be flying"),
    ("bench", "engage while the arm was enabled limp for calibration (enable 2): enable it (enable 1, "
              "which parks with the model's calibration) before engaging"),
)

# heartbeat.reset_cause: why the chip last reset (RCC_CSR's flags, read once at start-up)
RESET_CAUSES = (
    ("unknown", "no reset flag was set (e.g. a debugger's reset)"),
    ("power_on", "power-on or power-down reset"),
    ("brown_out", "the MCU's supply fell below the brown-out threshold"),
    ("watchdog", "the independent watchdog: the main loop stopped or stayed unhealthy, or a fault "
                 "halted the firmware (heartbeat.last_fault says which)"),
    ("window_watchdog", "the window watchdog"),
    ("low_power", "low-power management reset"),
    ("software", "a software reset (NVIC_SystemReset, e.g. after flashing)"),
    ("pin", "the NRST pin (reset button)"),
)

# heartbeat.state: what the arm is doing, in order of a session
STATES = (
    ("off", "servo power off"),
    ("starting", "servo power on; the servos boot and are configured: engage is refused"),
    ("parking", "on its way to the park pose at park speed"),
    ("parked", "holding the park pose"),
    ("moving", "engaged: on its way to the set position at transit speed"),
    ("holding", "engaged: at the set position, following the tilt at working speed"),
    ("limp", "service: torque off for positioning by hand; positions are still read"),
    ("jogging", "service: on its way to a jogged pose at park speed"),
    ("jogged", "service: holding a jogged pose"),
)

# Bits of heartbeat.faults, lowest first. Latched ones stay set until the next enable.
FAULTS = (
    ("servo_timeout", "a servo's status read went unanswered after every retry (latest round)"),
    ("servo_error", "a servo's last status packet had an error bit set (see servoN_error)"),
    ("servo_config", "the registers written at enable could not be read back (latched; power cut)"),
    ("imu", "the IMU did not answer, is not an MPU-6050, or gave no usable sample (none new, or full "
            "scale) for several ticks: an engaged arm parks, engage is refused until it is back"),
    ("link_lost", "the link fell silent while engaged, limp or at a jogged pose, so the arm parked with the "
                  "torque on (bench-enabled, enable 2: went or stayed limp instead; latched until engage)"),
    ("out_of_reach", "at the current tilt the set position is out of the branch's reach: the arm holds "
                     "the nearest point it reaches (or its last goal)"),
    ("command_refused", "the last engage or set_position was refused; heartbeat.refusal says why"),
    ("imu_saturated", "an IMU sample since the last heartbeat had an axis at full scale; it was not used"),
    ("servo_tracking", "a servo's shaft has not followed its goal as its speed allows (stuck, drifting "
                       "or limp): an engaged arm parks, engage is refused until it tracks again"),
    ("motion_blocked", "a move would sweep through a joint limit, the body or a leg: a set position or "
                       "engage with no clear route was refused, or a step was stopped and the arm holds"),
    ("servo_reset", "a servo was found with its torque off (a brown-out resets it): configured again, "
                    "an engaged arm parks (latched until engage)"),
    ("timing", "the tick interrupt stopped (ticks are run from the microsecond clock) or the clock "
               "stopped (servo power cut)"),
    ("servo_lagging", "a servo's shaft fell further behind its goal than the motion allows for (slowed by "
                      "its supply or load, or blocked): the goals wait for it; if it does not catch up, "
                      "servo_tracking follows and the arm parks. heartbeat.lagging_joints says which"),
    ("drone_attitude_rejected", "the drone's attitude disagreed with the arm's IMU for longer than the model's "
                                "reject_after: dropped, the estimate goes on without it until it agrees again"),
    ("drone_velocity_rejected", "the drone's velocity disagreed with the arm's IMU for longer than the model's "
                                "reject_after: dropped, the estimate goes on without it until it agrees again"),
)

# Bits of heartbeat.estimate_sources: what corrects the attitude estimate now (the gyro always
# propagates it).
SOURCES = (
    ("accelerometer", "the arm's own accelerometer (neither of the drone's streams is fused)"),
    ("drone_attitude", "the drone's attitude (drone_attitude messages accepted within the link timeout)"),
    ("drone_velocity", "the drone's velocity (drone_velocity messages accepted within the link timeout)"),
)


def wire_types(messages=MESSAGES) -> set[str]:
    """The field types in use, with those their C byte helpers are built from."""
    needs = {"u8": set(), "u16": {"u8"}, "i16": {"u16"}, "u32": {"u16"}, "i32": {"u32"}, "f32": {"u32"}}
    todo = {"u8"} | {t for m in messages for _, t in m.fields}
    used = set()
    while todo:
        t = todo.pop()
        used.add(t)
        todo |= needs[t] - used
    return used


def check(messages=MESSAGES) -> None:
    if len(FAULTS) > 16:
        raise ValueError("heartbeat.faults is 16 bits wide")
    ids = [m.id for m in messages]
    if len(set(ids)) != len(ids):
        raise ValueError(f"message ids must differ: {ids}")
    for m in messages:
        if m.direction == "to_drone" and m.size > TX_MAX_PAYLOAD:
            raise ValueError(f"{m.name}: {m.size} bytes exceeds the {TX_MAX_PAYLOAD}-byte LLCP limit")
        for name, t in m.fields:
            if t not in TYPES:
                raise ValueError(f"{m.name}.{name}: unknown type {t}")
