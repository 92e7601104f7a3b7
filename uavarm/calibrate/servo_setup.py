"""`uavarm servos setup PORT`: gives each joint's AX-12A the model file's id and the bus's baud
rate, one servo at a time, through a Dynamixel adapter on PORT: the board itself with CFG0
closed at reset (its servo set-up bridge, docs/board-project.md), a ROBOTIS U2D2 or
USB2Dynamixel with its power hub, or the simulated bus `uavarm sitl --servo-bus` offers.

For each joint: connect its servo alone and press Enter. The servo is looked for as it ships
(id 1 at 1 Mbit/s), with only its id set, and set up; its model number must be the AX-12A's.
Each write, the id and then the Baud Rate register, is asked for first and read back after
(at the new id and baud). A servo already set up is left as it is. Nothing else is written:
`uavarm link PORT enable` configures the rest (limits, return delay, torque) on the board's bus.

Like the calibrations, the procedure takes `ask(text)` and `confirm(question)`, so the tests
run it against the simulated bus as a user at the bench does."""
from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path

from . import dxl
from .dxl import BAUD_RATE, FACTORY_BAUD, FACTORY_ID, ID, MODEL_NUMBER, PING, READ, WRITE, DxlError
from ..model import config


class SetupError(Exception):
    """A servo not found, not an AX-12A, refusing a write or not reading back what was written."""


def _find(bus: dxl.Bus, target_id: int, target_baud: int) -> tuple[int, int] | None:
    """(id, baud) at which the connected servo answers a PING: as shipped, with only its id
    set, or set up; None if it answers at none of them."""
    for servo_id, baud in dict.fromkeys([(FACTORY_ID, FACTORY_BAUD), (target_id, FACTORY_BAUD),
                                         (target_id, target_baud)]):
        bus.set_baud(baud)
        if bus.transact(servo_id, PING) is not None:
            return servo_id, baud
    return None


def _registers(bus: dxl.Bus, servo_id: int) -> tuple[int, int, int]:
    """(model number, ID, Baud Rate register) read from the servo (one READ of addresses 0..4)."""
    status = bus.transact(servo_id, READ, bytes([MODEL_NUMBER, BAUD_RATE + 1]))
    if status is None or status.error or len(status.params) != BAUD_RATE + 1:
        raise SetupError(f"id {servo_id} at {bus.baud} bit/s did not answer a READ of its id and baud rate")
    p = status.params
    return p[0] | p[1] << 8, p[ID], p[BAUD_RATE]


def _write(bus: dxl.Bus, servo_id: int, address: int, value: int) -> None:
    """One WRITE; its status packet (if the servo's Status Return Level sends one, and it comes at
    the baud the bus listens at) must show no error."""
    try:
        status = bus.transact(servo_id, WRITE, bytes([address, value]))
    except DxlError:
        status = None              # after a baud change the answer may come at the new rate
    if status is not None and status.error:
        raise SetupError(f"id {servo_id} refused the write of {value} at address {address} "
                         f"(error bits {status.error:#04x})")
    time.sleep(dxl.EEPROM_WRITE_S)


def setup(port: str, model: config.Model, ask, confirm, timeout: float = 0.1, out=print) -> int:
    """Sets up one servo per joint; returns how many were written to (not already set up)."""
    written = 0
    register = dxl.baud_register(model.servo_baud)
    with contextlib.closing(dxl.Bus(port, FACTORY_BAUD, timeout)) as bus:
        time.sleep(dxl.POWER_UP_S)
        for joint, servo in enumerate(model.servos, 1):
            ask(f"Joint {joint} (id {servo.id}): connect its servo alone to the adapter (the 3-pin cable and "
                f"12 V; the other servos unplugged), then press Enter")
            found = _find(bus, servo.id, model.servo_baud)
            if found is None:
                raise SetupError(f"joint {joint}: no servo answers as id {FACTORY_ID} at {FACTORY_BAUD} bit/s (as "
                                 f"shipped), nor as id {servo.id} at {FACTORY_BAUD} or {model.servo_baud} bit/s: "
                                 "check its 12 V and its cable; a servo set to other values needs a factory reset "
                                 "(Dynamixel Wizard) first")
            servo_id, baud = found
            model_number = _registers(bus, servo_id)[0]
            if model_number != dxl.AX12A_MODEL_NUMBER:
                raise SetupError(f"joint {joint}: id {servo_id} has model number {model_number}, not an AX-12A "
                                 f"({dxl.AX12A_MODEL_NUMBER}): left as it is")
            out(f"  found an AX-12A: id {servo_id} at {baud} bit/s")
            if (servo_id, baud) == (servo.id, model.servo_baud):
                out(f"joint {joint}: already id {servo.id} at {baud} bit/s, left as it is")
                continue
            if servo_id != servo.id:
                if not confirm(f"  write id {servo.id} into it (now id {servo_id})?"):
                    raise SetupError(f"joint {joint}: not written (id {servo_id} at {baud} bit/s)")
                _write(bus, servo_id, ID, servo.id)
                written += 1
                if _registers(bus, servo.id)[1] != servo.id:
                    raise SetupError(f"joint {joint}: id {servo.id} did not read back")
                out(f"  id {servo.id} written and read back")
            if baud != model.servo_baud:
                if not confirm(f"  write baud rate {model.servo_baud} bit/s into it (Baud Rate register "
                               f"{register}; now {baud})?"):
                    raise SetupError(f"joint {joint}: baud rate not written (id {servo.id} at {baud} bit/s)")
                _write(bus, servo.id, BAUD_RATE, register)
                written += 1
                bus.set_baud(model.servo_baud)
                if _registers(bus, servo.id)[1:] != (servo.id, register):
                    raise SetupError(f"joint {joint}: id {servo.id} at {model.servo_baud} bit/s did not read back")
            out(f"joint {joint}: id {servo.id} at {model.servo_baud} bit/s (Baud Rate register {register}), "
                "read back")
    out("Done: connect the servos to the board's bus and `uavarm link PORT enable` (docs/bring-up.md)")
    return written


def command(args) -> int:
    from .guide import terminal_ask, terminal_confirm
    path = Path(args.model) if args.model else config.DEFAULT_MODEL
    try:
        setup(args.port, config.load(path), terminal_ask, terminal_confirm, timeout=args.timeout)
    except (SetupError, DxlError, config.ModelError, OSError) as exc:   # OSError: the port
        print(f"error: {exc}", file=sys.stderr)
        return 1
    except (KeyboardInterrupt, EOFError):
        print("\nstopped", file=sys.stderr)
        return 1
    return 0
