"""The `uavarm` command: codegen, demo, link (talk to a board), sitl (a simulated board),
sim (the closed-loop simulator's table and plots), workspace (the reachable-region plot),
servos (new servos' ids and baud, through the board or a Dynamixel adapter)."""
from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

DEMO_ENGAGE_S = 1.5        # `uavarm demo`: set position and engage this long after enable
DEMO_KEEP_ALIVE_S = 0.25   # ... then the set position again at this period
LINE_EVERY_S = 0.5         # demo, monitor: a heartbeat line at most this often by default


class HeartbeatLines:
    """Heartbeats for a person to read: the first of each `every`-second window of their
    times (0: every one), its faults those of all the heartbeats since the last line."""

    def __init__(self, every: float):
        self.every, self.window, self.faults = every, None, 0

    def line(self, at: float, hb: dict) -> str | None:
        self.faults |= hb["faults"]
        window = math.floor(at / self.every + 1e-6) if self.every > 0 else at
        if window == self.window:
            return None
        self.window, faults, self.faults = window, self.faults, 0
        return _heartbeat_line(dict(hb, faults=faults))


def demo(args) -> int:
    """The simulated board: enable, go to a target on a tilted board, print what happens in
    simulated-time order: the commands sent (->) and the heartbeats received (<-)."""
    from .sim.board import Gravity, SimBoard
    _require_current_code()
    board = SimBoard(motion=Gravity(math.radians(args.roll), math.radians(args.pitch)), record=False)
    target = dict(zip("xyz", args.target))
    commands = [(0.0, "enable", {"on": 1}), (DEMO_ENGAGE_S, "set_position", target),
                (DEMO_ENGAGE_S, "engage", {"on": 1})]
    t = DEMO_ENGAGE_S + DEMO_KEEP_ALIVE_S
    while t < args.seconds:      # repeated, unprinted: an engaged arm parks when the link is silent
        commands.append((t, "keep-alive", target))
        t += DEMO_KEEP_ALIVE_S
    shown, lines = -1.0, HeartbeatLines(args.every)

    def run_until(at):
        """Run to `at` s, printing the heartbeats on the way (the board keeps only its latest)."""
        while board.time < at:
            board.run_until_us(round(min(at, board.time + DEMO_KEEP_ALIVE_S) * 1e6))
            print_heartbeats()

    def print_heartbeats():
        nonlocal shown
        for at, hb in zip(board.heartbeat_times, board.heartbeats):
            if at > shown:
                shown = at
                line = lines.line(at, hb)
                if line:
                    print(f"{at:6.2f} s  <- {line}")
    for at, name, fields in commands:
        if at > args.seconds:
            break
        run_until(at)
        if name == "keep-alive":
            board.send("set_position", **fields)
            continue
        board.send(name, **fields)
        print(f"{board.time:6.2f} s  -> {name} {fields}")
    run_until(args.seconds)
    return 0


def _heartbeat_line(hb) -> str:
    from .link.client import bench_note
    from .link.messages import REFUSALS, fault_names, fault_vector_name, reset_cause_name, source_names, state_name
    shafts = ", ".join(f"{math.degrees(hb[k]):7.2f}" for k in ("p1", "p2", "p3"))   # nan: not read
    goals = ", ".join(f"{math.degrees(hb[k]):7.2f}" for k in ("q1", "q2", "q3"))
    refused = f" refused {REFUSALS[hb['refusal']][0]}" if 0 < hb["refusal"] < len(REFUSALS) else ""
    halted = f" after {fault_vector_name(hb['last_fault'])}" if hb["last_fault"] else ""
    return (f"#{hb['seq']} up {hb['uptime_ms'] / 1000:.1f} s {state_name(hb['state'])}{bench_note(hb)}{refused} "
            f"(reset: {reset_cause_name(hb['reset_cause'])}{halted}): "
            f"enabled {hb['enabled']} engaged {hb['engaged']} unreachable {hb['unreachable']} "
            f"set ({hb['set_x']:.1f}, {hb['set_y']:.1f}, {hb['set_z']:.1f}) mm shafts [{shafts}] goals [{goals}] deg "
            f"faults {fault_names(hb['faults'])} estimate from {source_names(hb['estimate_sources'])} servo errors "
            f"{[hb[f'servo{i}_error'] for i in (1, 2, 3)]} link frames {hb['link_frames_ok']} "
            f"link errors {hb['link_errors']} servo timeouts {hb['servo_timeouts']}")


def link(args) -> int:
    from .link import ArmLink, LinkError
    try:
        if args.action == "shell":
            return _shell(args)
        with ArmLink(args.port, args.baud) as arm:
            if args.action == "monitor":
                lines = HeartbeatLines(args.every)
                while True:
                    hb = arm.next_heartbeat()
                    line = lines.line(hb["uptime_ms"] / 1000.0, hb)
                    if line:
                        print(line, flush=True)
                    if args.keep_alive:
                        arm.keep_alive()
            action = {
                "enable": lambda: arm.enable(limp=args.limp), "disable": arm.disable, "engage": arm.engage,
                "disengage": arm.disengage, "status": arm.next_heartbeat,
                "goto": lambda: arm.set_position(*args.xyz),
                "limp": lambda: arm.torque(False), "stiff": lambda: arm.torque(True),
                "jog": lambda: arm.jog(int(args.xyz[0]), angle=math.radians(args.xyz[1])),
            }[args.action]
            print(_heartbeat_line(action()))
    except LinkError as exc:   # (CommandRefused too: the board's reason)
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except OSError as exc:     # (serial.SerialException too) the port went away mid-command
        print(f"error: {args.port}: the serial port failed ({exc}): unplugged, or the SITL stopped?",
              file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        pass
    return 0


def _shell(args) -> int:
    from .link.shell import prompt_lines, run_shell
    if args.script is None and sys.stdin.isatty():
        return run_shell(args.port, args.baud, prompt_lines(), interactive=True, reenable=args.reenable)
    if args.script is None or args.script == "-":
        return run_shell(args.port, args.baud, sys.stdin, interactive=False, reenable=args.reenable)
    try:
        with open(args.script) as f:
            lines = f.readlines()
    except OSError as exc:
        print(f"error: --script {args.script}: {exc.strerror}", file=sys.stderr)
        return 1
    return run_shell(args.port, args.baud, lines, interactive=False, reenable=args.reenable)


def _require_current_code() -> None:
    """Stop if generated/ was not generated from the model file the simulation loads."""
    from .build import generated
    from .model import config
    generated.check_current(config.load())


def _number(ok, what: str):
    """An argparse type: a finite float for which ok(value) holds."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not (math.isfinite(value) and ok(value)):
            raise argparse.ArgumentTypeError(f"{what}, got {text}")
        return value
    return parse


def _integer(lo: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
        if value < lo:
            raise argparse.ArgumentTypeError(f"must be at least {lo}, got {value}")
        return value
    return parse


FINITE = _number(lambda v: True, "must be a finite number")
POSITIVE = _number(lambda v: v > 0, "must be a positive number")
NOT_NEGATIVE = _number(lambda v: v >= 0, "must be a number >= 0")
SUPPLY_VOLTS = _number(lambda v: 6 <= v <= 14, "must be a voltage from 6 to 14 (the servos' supply limits)")
EVERY_HELP = ("print a heartbeat at most every S seconds of the board's clock, with the faults of those "
              "skipped (default: %(default)s; 0: every heartbeat, link.heartbeat_period apart)")


def version() -> str:
    """The package's version and the firmware's (APP_FIRMWARE_VERSION in app.h)."""
    from importlib import metadata
    app_h = Path(__file__).resolve().parents[1] / "firmware_stm32" / "App" / "Inc" / "app.h"
    try:
        package = metadata.version("uavarm")
    except metadata.PackageNotFoundError:
        package = "(not installed)"
    try:
        found = re.search(r"#define APP_FIRMWARE_VERSION 0x([0-9a-fA-F]{6})u", app_h.read_text())
    except OSError:
        found = None
    firmware = ".".join(str(int(found.group(1)[i:i + 2], 16)) for i in (0, 2, 4)) if found else "unknown"
    return f"uavarm {package} (firmware {firmware})"


def parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="uavarm", description="Drone arm toolchain")
    ap.add_argument("--version", action="version", version=version())
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("codegen", help="regenerate generated/ (`uavarm codegen --help` for its options)",
                   add_help=False)
    d = sub.add_parser("demo", help="run the firmware on the simulated board and print its heartbeats")
    d.add_argument("--target", type=FINITE, nargs=3, default=[60.0, 20.0, -120.0], metavar=("X", "Y", "Z"),
                   help="set position, mm, level frame at the arm's base (default: %(default)s)")
    d.add_argument("--roll", type=FINITE, default=10.0, help="board tilt, degrees (default: %(default)s)")
    d.add_argument("--pitch", type=FINITE, default=-5.0, help="board tilt, degrees (default: %(default)s)")
    d.add_argument("--seconds", type=POSITIVE, default=4.0,
                   help=f"simulated seconds to run (default: %(default)s); enable at 0 s, set position and "
                        f"engage at {DEMO_ENGAGE_S} s, the set position repeated every {DEMO_KEEP_ALIVE_S} s")
    d.add_argument("--every", type=NOT_NEGATIVE, default=LINE_EVERY_S, metavar="S", help=EVERY_HELP)
    lk = sub.add_parser("link", help="command a board (or a SITL) over its serial port")
    lk.add_argument("port", help="serial device, e.g. /dev/ttyACM0 or the path `uavarm sitl` prints")
    lk.add_argument("action", choices=["enable", "disable", "engage", "disengage", "goto", "status", "monitor",
                                       "limp", "stiff", "jog", "shell"],
                    help="limp: torque off (positions still read), stiff: torque back on, jog J DEG: joint J "
                         "(1-3) to DEG at park speed (service commands, refused while engaged or while the "
                         "drone's attitude streams; alone, a limp or jogged arm parks once the link has been "
                         "silent for a second); shell: one connection for many commands, typed at a prompt or "
                         "read from --script or standard input (a CSV of targets X,Y,Z[,SECONDS] too), the arm "
                         "kept engaged, limp or jogged in between")
    lk.add_argument("xyz", type=FINITE, nargs="*", metavar="X Y Z",
                    help="goto: target in mm; jog: JOINT DEG (degrees)")
    lk.add_argument("--baud", type=_integer(1), default=115200,
                    help="bit/s, ignored by USB CDC; for UART adapters (default: %(default)s)")
    lk.add_argument("--script", default=None, metavar="FILE",
                    help="shell: commands or targets from FILE ('-': standard input; default: a prompt when "
                         "standard input is a terminal, else standard input)")
    lk.add_argument("--limp", action="store_true",
                    help="enable: the bench, to calibrate the servos (enable 2): power on with the torque off, "
                         "the arm limp where it hangs and never moved by the board on its own (the link silent, "
                         "the drone's messages, disengage: it goes limp); engage is refused until a plain "
                         "enable, which parks it")
    lk.add_argument("--no-reenable", dest="reenable", action="store_false",
                    help="shell: a board that restarts while enabled after a watchdog reset or a fault (it "
                         "comes up limp) is reported but not enabled again (default: enabled again, so it "
                         "parks; never engaged again)")
    lk.add_argument("--every", type=NOT_NEGATIVE, default=LINE_EVERY_S, metavar="S", help="monitor: " + EVERY_HELP)
    lk.add_argument("--no-keep-alive", dest="keep_alive", action="store_false",
                    help="monitor: do not repeat the set position (an engaged arm then parks after the "
                         "link silence timeout)")
    cal = sub.add_parser("calibrate", help="guided calibration over the link, written into the model file")
    cal.add_argument("what", choices=["imu", "mounting", "servos", "lag", "link"],
                     help="imu: accelerometer bias and scale (six still positions), the gyro's offset, "
                          "and its scale (the turns between them); mounting: the IMU's roll and pitch on the "
                          "base (drone standing level); servos: each servo's zero and direction (the arm held "
                          "at its zero pose, then small jogs), checked by a slow move through three poses; "
                          "lag: how far the servos lag their goal (a jog of each joint), and the lead time; "
                          "link: the link's fixed delay from this computer (pings), run on the drone's computer")
    cal.add_argument("port", help="serial device of the board (or the path `uavarm sitl` prints)")
    cal.add_argument("--model", default=None, help="model file to update (default: model/manipulator.toml)")
    cal.add_argument("--seconds", type=POSITIVE, default=None,
                     help="seconds of samples per position, after each jog for lag, of pings for link "
                          "(default: imu 2, mounting 3, servos 1, lag 0.4, link 5)")
    cal.add_argument("--upstream-ms", type=NOT_NEGATIVE, default=None, metavar="MS",
                     help="link: how old the attitude's stamps are when they reach this computer, added to "
                          "what is measured (e.g. the mean of `rostopic delay` on the attitude topic; default 0)")
    cal.add_argument("--yes", action="store_true",
                     help="write the result without asking (not for servos: its questions are what you see)")
    cal.add_argument("--allow-unusual", action="store_true",
                     help="imu, mounting, servos, lag: go on with a result beyond what a calibration usually gives "
                          "(a mounting more than 10 deg from level, an accelerometer far from its last calibration, a "
                          "servo zero more than 15 deg from the model file's or a direction changed, a servo lag "
                          "outside 5-80 ms or a lead time moved more than 30 ms) after a second confirmation "
                          "(none with --yes)")
    st = sub.add_parser("sitl", help="run the firmware on a simulated board behind a pseudo-terminal")
    st.add_argument("scenario", nargs="?", default="level",
                    help="level (default), tilt:ROLL,PITCH (deg) or rock:ROLL,PITCH,HZ (bench tilting)")
    st.add_argument("--speed", type=POSITIVE, default=1.0,
                    help="simulated seconds per real second (default: %(default)s)")
    st.add_argument("--imu", choices=["ideal", "white", "calibrated", "datasheet"], default="white",
                    help="the simulated IMU's errors (datasheet: biases and scale errors to calibrate; "
                         "default: %(default)s)")
    st.add_argument("--seed", type=_integer(0), default=0, help="draw of the IMU's errors (default: %(default)s)")
    st.add_argument("--imu-mounting", default=None, metavar="ROLL,PITCH,YAW",
                    help="how the simulated IMU really sits on the base (deg), whatever the model file says "
                         "(default: as the model file says)")
    st.add_argument("--servo-lag-ms", type=NOT_NEGATIVE, default=None, metavar="MS",
                    help="how far the simulated servos' shafts lag their speed-limited motion (first order; "
                         "default: as the model file's servo.response_lag says)")
    st.add_argument("--supply", type=SUPPLY_VOLTS, default=None, metavar="VOLTS",
                    help="the simulated servos' battery, open circuit (it sags as they move, and their speed "
                         "with it; default: a 3S lithium battery at its nominal 11.1 V)")
    st.add_argument("--link-delay-ms", default="0", metavar="UP[,DOWN]",
                    help="the link's delay to the board and back from it (ms; DOWN as UP if left out; "
                         "default: %(default)s)")
    st.add_argument("--motors-on", action="store_true",
                    help="the propellers' vibration in the IMU (calibrated and datasheet profiles); default: "
                         "off, as on the bench")
    st.add_argument("--servo-zeros", default=None, metavar="U1,U2,U3",
                    help="the units each simulated servo reads with its joint really at 0 deg, whatever the "
                         "model file says (default: as the model file says)")
    st.add_argument("--servo-directions", default=None, metavar="D1,D2,D3",
                    help="+1 or -1 per servo: whether its joint's angle really grows with its units "
                         "(-1: mounted the other way round; default: as the model file says)")
    st.add_argument("--servo-bus", action="store_true",
                    help="instead of the board: a simulated servo bus with one AX-12A as it ships (id 1 at "
                         "1 Mbit/s), as through a Dynamixel adapter, for `uavarm servos setup`")
    sv = sub.add_parser("servos", help="set up new AX-12A servos through the board (CFG0 closed at reset) or a "
                                       "Dynamixel adapter")
    sv.add_argument("action", choices=["setup"],
                    help="setup: give each joint's servo, connected alone, the model file's id and the bus's "
                         "baud rate (each write confirmed, then read back)")
    sv.add_argument("port", help="serial device: the board with CFG0 closed, an adapter (U2D2, USB2Dynamixel), "
                                 "or the path `uavarm sitl --servo-bus` prints")
    sv.add_argument("--model", default=None, help="model file with the ids and baud (default: model/manipulator.toml)")
    sv.add_argument("--timeout", type=POSITIVE, default=0.1,
                    help="seconds to wait for a servo's answer (default: %(default)s)")
    sm = sub.add_parser("sim", help="closed-loop simulation of a drone scenario: end-effector error table and plots")
    sm.add_argument("scenario", help="bench, hover, manoeuvre, or a scenario file (uavarm/sim/scenarios.py)")
    sm.add_argument("--show", action="store_true",
                    help="print the scenario as a scenario file (with --imu applied) and run nothing")
    sm.add_argument("--estimator", default=None,
                    help="estimator preset: complementary, quaternion, imu-velocity, link, link-velocity "
                         "(default: the model file as it is)")
    sm.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                    help="edit a model key for this run, e.g. estimator.accel_gain=0.4 (a key the chosen "
                         "estimator does not use is refused; repeatable; default: none)")
    sm.add_argument("--seconds", type=POSITIVE, default=60.0, help="scored seconds per seed (default: %(default)s)")
    sm.add_argument("--settle", type=NOT_NEGATIVE, default=5.0,
                    help="seconds after engage not scored (default: %(default)s)")
    sm.add_argument("--preflight", type=NOT_NEGATIVE, default=10.0,
                    help="seconds on the ground (still, level, motors off) between power-up and the flight "
                         "(default: %(default)s)")
    sm.add_argument("--servo-lag-ms", type=NOT_NEGATIVE, default=None, metavar="MS",
                    help="how far the simulated servos' shafts lag their speed-limited motion, whatever the model "
                         "file says (first order; default: as the model file's servo.response_lag says)")
    sm.add_argument("--supply", type=SUPPLY_VOLTS, default=None, metavar="VOLTS",
                    help="the simulated servos' battery, open circuit (it sags as they move, and their speed "
                         "with it; default: a 3S lithium battery at its nominal 11.1 V)")
    sm.add_argument("--seeds", type=_integer(1), default=1, help="seeds to run (default: %(default)s)")
    sm.add_argument("--seed", type=_integer(0), default=0, help="first seed (default: %(default)s)")
    sm.add_argument("--imu", choices=["ideal", "white", "calibrated", "datasheet", "ranges"], default=None,
                    help="IMU error profile (default: the scenario's)")
    sm.add_argument("--draw-errors", action="store_true",
                    help="each seed draws the drone's and the IMU's errors across the ranges `make sim-report` "
                         "uses (uavarm/sim/error_ranges.py) instead of the scenario's own")
    sm.add_argument("--link-attitude", choices=["auto", "on", "off"], default="auto",
                    help="send the drone's attitude over the link (auto: when the firmware fuses it; "
                         "default: %(default)s)")
    sm.add_argument("--link-velocity", choices=["auto", "on", "off"], default="auto",
                    help="send the drone's velocity over the link (auto: when the firmware fuses it; "
                         "default: %(default)s)")
    sm.add_argument("--poll-us", type=_integer(10), default=250,
                    help="simulated main-loop period, microseconds (default: %(default)s)")
    sm.add_argument("--jobs", type=_integer(1), default=1, help="seeds run in parallel (default: %(default)s)")
    sm.add_argument("--plots", default="build/sim-plots",
                    help="folder for the PNG plots ('' for none; default: %(default)s)")
    sm.add_argument("--export-log", default=None, metavar="CSV",
                    help="also write the first seed's drone motion as a flight log (the replay format)")
    ws = sub.add_parser("workspace", help="plot the arm's reachable region (side and top views)")
    ws.add_argument("--model", default=None, help="model file (default: model/manipulator.toml)")
    ws.add_argument("--out", default="build/workspace.png", help="PNG file to write (default: %(default)s)")
    return ap


def main(argv=None) -> int:
    """The command; a user error ends it with one line `error: ...` on stderr and exit code 1
    (argparse's own: 2), never a traceback."""
    ap = parser()
    args, rest = ap.parse_known_args(argv)
    if args.command == "codegen":
        from .codegen.generate import main as codegen_main
        return codegen_main(rest, prog="uavarm codegen")
    if rest:
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
    if args.command == "link":
        wanted = {"goto": 3, "jog": 2}.get(args.action, 0)
        if len(args.xyz) != wanted:
            ap.error("goto takes exactly X Y Z, jog takes JOINT DEG; the other actions take none")
        if args.action == "jog" and args.xyz[0] not in (1, 2, 3):
            ap.error(f"jog: joint must be 1, 2 or 3, got {args.xyz[0]:g}")
        if args.script is not None and args.action != "shell":
            ap.error("--script is an option of shell")
    if args.command == "sitl":
        from .sim import sitl
        try:
            sitl.motion_of(args.scenario)
            args.imu_mounting = sitl.angles_of(args.imu_mounting) if args.imu_mounting else None
            args.link_delay = sitl.link_delay_of(args.link_delay_ms)
            args.servo_zeros = args.servo_zeros and sitl.integers_of(
                args.servo_zeros, "servo zeros", range(1024), "0 to 1023")
            args.servo_directions = args.servo_directions and sitl.integers_of(
                args.servo_directions, "servo directions", {1, -1}, "1 or -1")
        except ValueError as exc:
            ap.error(str(exc))
    try:
        return run(args)
    except (ValueError, OSError) as exc:   # model, scenario and generated-code errors; files
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("stopped", file=sys.stderr)
        return 130


def run(args) -> int:
    if args.command == "link":
        return link(args)
    if args.command == "sim":
        from .sim.report import sim_command
        return sim_command(args)
    if args.command == "workspace":
        from .model import config
        from .sim.workspace import plot
        try:
            model = config.load(args.model) if args.model else config.load()
        except config.ModelError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        figures = plot(model, Path(args.out))
        print(f"wrote {args.out} and {Path(args.out).with_suffix('.pdf')}: "
              + ", ".join(f"{k} {v:.1f} mm" for k, v in figures.items()))
        return 0
    if args.command == "calibrate":
        from .calibrate import command
        return command(args)
    if args.command == "servos":
        from .calibrate import servo_setup
        return servo_setup.command(args)
    if args.command == "sitl" and args.servo_bus:
        from .sim import sitl
        return sitl.serve_servo_bus()
    if args.command == "sitl":
        from .sim import sitl
        _require_current_code()
        return sitl.main(args.scenario, args.speed, imu=args.imu, seed=args.seed, imu_mounting=args.imu_mounting,
                         servo_lag=None if args.servo_lag_ms is None else args.servo_lag_ms / 1000,
                         link_delay=args.link_delay, supply=args.supply, servo_zeros=args.servo_zeros,
                         servo_directions=args.servo_directions, motors_on=args.motors_on)
    return demo(args)


if __name__ == "__main__":
    sys.exit(main())
