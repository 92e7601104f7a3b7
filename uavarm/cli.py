"""The `uavarm` command: `uavarm codegen [...]`, `uavarm demo`."""
from __future__ import annotations

import argparse
import math
import sys


def demo(args) -> int:
    """The simulated board: enable, go to a target on a tilted board, print heartbeats."""
    from .board import Gravity, SimBoard
    from .messages import fault_names
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
            q = ", ".join(f"{math.degrees(hb[k]):7.2f}" for k in ("q1", "q2", "q3"))
            print(f"{board.time:6.2f} s  <- enabled {hb['enabled']} engaged {hb['engaged']} "
                  f"unreachable {hb['unreachable']} joints [{q}] deg  faults {fault_names(hb['faults'])}")
        shown = len(board.heartbeats)
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
    args, rest = ap.parse_known_args(argv)
    if args.command == "codegen":
        from .codegen.generate import main as codegen_main
        return codegen_main(rest)
    if rest:
        ap.error(f"unrecognized arguments: {' '.join(rest)}")
    return demo(args)


if __name__ == "__main__":
    sys.exit(main())
