"""The `uavarm` command: codegen, demo, link (talk to a board), sitl (a simulated board),
sim (the closed-loop simulator's table and plots), workspace (the reachable-region plot)."""
from __future__ import annotations

import argparse
import math
import sys


def demo(args) -> int:
    """The simulated board: enable, go to a target on a tilted board, print heartbeats."""
    from .board import Gravity, SimBoard
    board = SimBoard(motion=Gravity(math.radians(args.roll), math.radians(args.pitch)))
    steps = [(0.0, "enable", {"on": 1}), (1.5, "set_position", dict(zip("xyz", args.target))),
             (1.5, "engage", {"on": 1})]
    for at, name, fields in steps:
        board.run_until_us(round(at * 1e6))
        board.send(name, **fields)
        print(f"{board.time:6.2f} s  -> {name} {fields}")
    shown = 0
    while board.time < args.seconds:
        board.run(0.25)
        board.send("set_position", **dict(zip("xyz", args.target)))   # keeps the link alive
        for hb in board.heartbeats[shown:]:
            print(f"{board.time:6.2f} s  <- {_heartbeat_line(hb)}")
        shown = len(board.heartbeats)
    return 0


def _heartbeat_line(hb) -> str:
    from .messages import REFUSALS, fault_names, fault_vector_name, reset_cause_name, state_name
    q = ", ".join(f"{math.degrees(hb[k]):7.2f}" for k in ("q1", "q2", "q3"))
    refused = f" refused {REFUSALS[hb['refusal']][0]}" if 0 < hb["refusal"] < len(REFUSALS) else ""
    halted = f" after {fault_vector_name(hb['last_fault'])}" if hb["last_fault"] else ""
    return (f"#{hb['seq']} up {hb['uptime_ms'] / 1000:.1f} s {state_name(hb['state'])}{refused} "
            f"(reset: {reset_cause_name(hb['reset_cause'])}{halted}): "
            f"enabled {hb['enabled']} engaged {hb['engaged']} unreachable {hb['unreachable']} "
            f"set ({hb['set_x']:.1f}, {hb['set_y']:.1f}, {hb['set_z']:.1f}) mm joints [{q}] deg "
            f"faults {fault_names(hb['faults'])} servo errors "
            f"{[hb[f'servo{i}_error'] for i in (1, 2, 3)]} link frames {hb['link_frames_ok']} "
            f"link errors {hb['link_errors']} servo timeouts {hb['servo_timeouts']}")


def link(args) -> int:
    from .link import ArmLink, LinkError
    try:
        with ArmLink(args.port, args.baud) as arm:
            if args.action == "monitor":
                while True:
                    hb = arm.next_heartbeat()
                    print(_heartbeat_line(hb), flush=True)
                    if args.keep_alive:
                        arm.keep_alive()
            action = {
                "enable": arm.enable, "disable": arm.disable, "engage": arm.engage,
                "disengage": arm.disengage, "status": arm.next_heartbeat,
                "goto": lambda: arm.set_position(*args.xyz),
                "limp": lambda: arm.torque(False), "stiff": lambda: arm.torque(True),
                "jog": lambda: arm.jog(int(args.xyz[0]), angle=math.radians(args.xyz[1])),
            }[args.action]
            print(_heartbeat_line(action()))
    except LinkError as exc:   # (CommandRefused too: the board's reason)
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        pass
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="uavarm", description="Drone arm toolchain")
    sub = ap.add_subparsers(dest="command", required=True)
    sub.add_parser("codegen", help="regenerate generated/ (same options as python -m uavarm.codegen)",
                   add_help=False)
    d = sub.add_parser("demo", help="run the firmware on the simulated board and print its heartbeats")
    d.add_argument("--target", type=float, nargs=3, default=[60.0, 20.0, -120.0], metavar=("X", "Y", "Z"))
    d.add_argument("--roll", type=float, default=10.0, help="board tilt, degrees")
    d.add_argument("--pitch", type=float, default=-5.0, help="board tilt, degrees")
    d.add_argument("--seconds", type=float, default=4.0)
    lk = sub.add_parser("link", help="command a board (or a SITL) over its serial port")
    lk.add_argument("port", help="serial device, e.g. /dev/ttyACM0 or the path `uavarm sitl` prints")
    lk.add_argument("action", choices=["enable", "disable", "engage", "disengage", "goto", "status", "monitor",
                                       "limp", "stiff", "jog"],
                    help="limp: torque off (positions still read), stiff: torque back on, jog J DEG: joint J "
                         "(1-3) to DEG at park speed; service commands, refused while engaged")
    lk.add_argument("xyz", type=float, nargs="*", metavar="X Y Z", help="goto: target in mm; jog: JOINT DEG")
    lk.add_argument("--baud", type=int, default=115200, help="ignored by USB CDC; for UART adapters")
    lk.add_argument("--no-keep-alive", dest="keep_alive", action="store_false",
                    help="monitor: do not repeat the set position (an engaged arm then parks after the "
                         "link silence timeout)")
    cal = sub.add_parser("calibrate", help="guided calibration over the link, written into the model file")
    cal.add_argument("what", choices=["imu", "mounting", "servos"],
                     help="imu: accelerometer bias and scale (six still positions) and the gyro's offset; "
                          "mounting: the IMU's roll and pitch on the base (drone standing level); servos: "
                          "each servo's zero and direction (the arm held at its zero pose, then small jogs)")
    cal.add_argument("port", help="serial device of the board (or the path `uavarm sitl` prints)")
    cal.add_argument("--model", default=None, help="model file to update (default model/manipulator.toml)")
    cal.add_argument("--seconds", type=float, default=2.0, help="seconds of samples per position")
    cal.add_argument("--yes", action="store_true", help="write the result without asking")
    st = sub.add_parser("sitl", help="run the firmware on a simulated board behind a pseudo-terminal")
    st.add_argument("scenario", nargs="?", default="level",
                    help="level (default), tilt:ROLL,PITCH (deg) or rock:ROLL,PITCH,HZ (bench tilting)")
    st.add_argument("--speed", type=float, default=1.0, help="simulated seconds per real second")
    st.add_argument("--imu", choices=["ideal", "white", "calibrated", "datasheet"], default="white",
                    help="the simulated IMU's errors (datasheet: biases and scale errors to calibrate)")
    st.add_argument("--seed", type=int, default=0, help="draw of the IMU's errors")
    st.add_argument("--imu-mounting", default=None, metavar="ROLL,PITCH,YAW",
                    help="how the simulated IMU really sits on the base (deg), whatever the model file says")
    sm = sub.add_parser("sim", help="closed-loop simulation of a drone scenario: end-effector error table and plots")
    sm.add_argument("scenario", help="bench, hover, manoeuvre, or a scenario file (uavarm/scenarios.py)")
    sm.add_argument("--show", action="store_true",
                    help="print the scenario as a scenario file (with --imu applied) and run nothing")
    sm.add_argument("--estimator", default=None,
                    help="estimator preset: complementary, quaternion, link (default: the model file as it is)")
    sm.add_argument("--set", dest="sets", action="append", default=[], metavar="KEY=VALUE",
                    help="edit a model key for this run, e.g. estimator.complementary_gyro_weight=0.98")
    sm.add_argument("--seconds", type=float, default=60.0, help="scored seconds per seed")
    sm.add_argument("--settle", type=float, default=5.0, help="seconds after engage not scored")
    sm.add_argument("--preflight", type=float, default=10.0,
                    help="seconds on the ground (still, level, motors off) between power-up and the flight")
    sm.add_argument("--seeds", type=int, default=1)
    sm.add_argument("--seed", type=int, default=0, help="first seed")
    sm.add_argument("--imu", choices=["ideal", "white", "calibrated", "datasheet"], default=None,
                    help="IMU error profile (default: the scenario's)")
    sm.add_argument("--link-attitude", choices=["auto", "on", "off"], default="auto",
                    help="send the drone's attitude over the link (auto: when the firmware fuses it)")
    sm.add_argument("--poll-us", type=int, default=250, help="simulated main-loop period")
    sm.add_argument("--jobs", type=int, default=1, help="seeds run in parallel")
    sm.add_argument("--plots", default="build/sim-plots", help="folder for the PNG plots ('' for none)")
    sm.add_argument("--export-log", default=None, metavar="CSV",
                    help="also write the first seed's drone motion as a flight log (the replay format)")
    ws = sub.add_parser("workspace", help="plot the arm's reachable region (side and top views)")
    ws.add_argument("--model", default=None, help="model file (default model/manipulator.toml)")
    ws.add_argument("--out", default="build/workspace.png")
    args, rest = ap.parse_known_args(argv)
    if args.command == "codegen":
        from .codegen.generate import main as codegen_main
        return codegen_main(rest)
    if rest:
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
    if args.command == "link":
        wanted = {"goto": 3, "jog": 2}.get(args.action, 0)
        if len(args.xyz) != wanted:
            ap.error("goto takes exactly X Y Z, jog takes JOINT DEG; the other actions take none")
        if args.action == "jog" and args.xyz[0] not in (1, 2, 3):
            ap.error(f"jog: joint must be 1, 2 or 3, got {args.xyz[0]:g}")
        return link(args)
    if args.command == "sim":
        from .sim_report import sim_command
        if args.seconds <= 0 or args.seeds < 1 or args.settle < 0 or args.preflight < 0 or args.poll_us < 10:
            ap.error("--seconds must be positive, --seeds at least 1, --settle and --preflight not negative, "
                     "--poll-us >= 10")
        return sim_command(args)
    if args.command == "workspace":
        from pathlib import Path
        from .model import config
        from .workspace import plot
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
        if not args.seconds > 0:
            ap.error("--seconds must be positive")
        return command(args)
    if args.command == "sitl":
        from . import sitl
        try:
            sitl.motion_of(args.scenario)
            mounting = sitl.angles_of(args.imu_mounting) if args.imu_mounting else None
        except ValueError as exc:
            ap.error(str(exc))
        return sitl.main(args.scenario, args.speed, imu=args.imu, seed=args.seed, imu_mounting=mounting)
    return demo(args)


if __name__ == "__main__":
    sys.exit(main())
