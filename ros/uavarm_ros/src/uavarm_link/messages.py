"""Python codec of the LLCP messages, built from the one table in model/messages.py (as
message_table.py, generated beside this file)."""
from __future__ import annotations

import struct
from typing import NamedTuple, Tuple

from .message_table import FAULTS, REFUSALS, RESET_CAUSES, SOURCES, STATES
from .message_table import MESSAGES as _TABLE

class Message(NamedTuple):
    name: str
    id: int
    direction: str                      # "to_arm" or "to_drone"
    fields: Tuple[Tuple[str, str], ...]
    struct_format: str                  # little-endian, packed: the id byte, then the fields

    @property
    def size(self) -> int:
        """Payload bytes including the id byte."""
        return struct.calcsize(self.struct_format)


MESSAGES = tuple(Message(*row) for row in _TABLE)
BY_NAME = {m.name: m for m in MESSAGES}
BY_ID = {m.id: m for m in MESSAGES}


class MessageError(ValueError):
    """A payload that is not a known message of the right length, or bad fields."""


def encode(name: str, **fields) -> bytes:
    try:
        msg = BY_NAME[name]
    except KeyError:
        raise MessageError(f"unknown message {name!r}; known: {sorted(BY_NAME)}") from None
    names = [f for f, _ in msg.fields]
    if set(fields) != set(names):
        raise MessageError(f"{name} needs fields {names}, got {sorted(fields)}")
    try:
        return struct.pack(msg.struct_format, msg.id, *(fields[f] for f in names))
    except struct.error as exc:
        raise MessageError(f"{name}: {exc}") from None


def decode(payload: bytes) -> tuple[str, dict]:
    if not payload:
        raise MessageError("empty payload")
    msg = BY_ID.get(payload[0])
    if msg is None:
        raise MessageError(f"unknown message id 0x{payload[0]:02X}")
    if len(payload) != msg.size:
        raise MessageError(f"{msg.name}: {len(payload)} bytes, expected {msg.size}")
    values = struct.unpack(msg.struct_format, payload)[1:]
    return msg.name, dict(zip((f for f, _ in msg.fields), values))


def fault_names(bits: int) -> list[str]:
    """The names of the heartbeat fault bits set in `bits`, lowest first."""
    return [name for i, (name, _) in enumerate(FAULTS) if bits >> i & 1]


def source_names(bits: int) -> list[str]:
    """What corrects the attitude estimate: the names of the heartbeat's estimate_sources bits."""
    return [name for i, (name, _) in enumerate(SOURCES) if bits >> i & 1]


def state_name(value: int) -> str:
    """The name of a heartbeat state value (STATES)."""
    return STATES[value][0] if 0 <= value < len(STATES) else f"unknown state {value}"


def refusal_reason(value: int) -> str:
    """What a heartbeat refusal value says (REFUSALS)."""
    return REFUSALS[value][1] if 0 <= value < len(REFUSALS) else f"unknown refusal {value}"


def reset_cause_name(value: int) -> str:
    """The name of a heartbeat reset_cause value (RESET_CAUSES)."""
    return RESET_CAUSES[value][0] if 0 <= value < len(RESET_CAUSES) else f"unknown reset cause {value}"


CORE_EXCEPTIONS = {2: "NMI", 3: "HardFault", 4: "MemManage", 5: "BusFault", 6: "UsageFault"}


def fault_vector_name(number: int) -> str:
    """A Cortex-M exception number as the handler's name: 3 "HardFault", 16 + n "IRQ n"."""
    if number >= 16:
        return f"IRQ {number - 16}"
    return CORE_EXCEPTIONS.get(number, f"exception {number}")
