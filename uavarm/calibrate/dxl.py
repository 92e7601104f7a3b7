"""Dynamixel Protocol 1.0 on a serial port: what `uavarm servos setup` needs to talk to one
servo through a Dynamixel adapter (ROBOTIS U2D2 or USB2Dynamixel, or any half-duplex
USB-serial adapter; an adapter that echoes what it sends is handled too).

Written from the protocol's documentation (ROBOTIS e-Manual, "Protocol 1.0": packet
FF FF ID LENGTH INSTRUCTION|ERROR PARAMETERS CHECKSUM, LENGTH = parameters + 2, CHECKSUM =
~(ID + LENGTH + ... ) & 0xFF) and the AX-12A's control table; tests/test_servo_setup.py holds
the packets to the official DynamixelSDK's."""
from __future__ import annotations

import time
from dataclasses import dataclass

from ..model import servo_models

PING, READ, WRITE = 0x01, 0x02, 0x03
MODEL_NUMBER, ID, BAUD_RATE = 0, 3, 4          # AX-12A control table addresses (EEPROM)
AX12A_MODEL_NUMBER = 12
FACTORY_ID, FACTORY_BAUD = 1, 1_000_000         # an AX-12A as it ships
EEPROM_WRITE_S = 0.05                           # a pause after an EEPROM write before the next instruction
POWER_UP_S = 0.5                                # the board's bridge powers the servos when the port opens


def baud_register(baud: float) -> int:
    """The AX-12A Baud Rate register value n whose 2,000,000 / (n + 1) bit/s is nearest baud
    (the model file's servo.baud is checked to be within the UART's 3 % of one)."""
    return servo_models.baud_register(servo_models.AX_12A, baud)


class DxlError(Exception):
    """The bus gave an answer that is not one servo's status packet."""


def checksum(body: bytes) -> int:
    return ~sum(body) & 0xFF


def instruction(servo_id: int, inst: int, params: bytes = b"") -> bytes:
    body = bytes([servo_id, len(params) + 2, inst]) + bytes(params)
    return b"\xff\xff" + body + bytes([checksum(body)])


@dataclass(frozen=True)
class Status:
    id: int
    error: int          # the servo's error bits (0: none)
    params: bytes


class Bus:
    """One serial port to the servo bus. transact() sends an instruction and returns the
    status packet that answers it, or None when nothing comes within `timeout` seconds."""

    def __init__(self, port: str, baud: int, timeout: float = 0.1):
        import serial                       # pyserial; its SerialException is an OSError
        self.timeout = timeout
        self.serial = serial.Serial(port, baud, timeout=timeout / 10)

    def close(self) -> None:
        self.serial.close()

    @property
    def baud(self) -> int:
        return self.serial.baudrate

    def set_baud(self, baud: int) -> None:
        self.serial.baudrate = baud

    def transact(self, servo_id: int, inst: int, params: bytes = b"") -> Status | None:
        packet = instruction(servo_id, inst, params)
        self.serial.reset_input_buffer()
        self.serial.write(packet)
        self.serial.flush()
        got = bytearray()
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            got += self.serial.read(max(1, self.serial.in_waiting))
            if got[:len(packet)] == packet:          # an adapter that echoes: its own bytes first
                del got[:len(packet)]
            status = _status(got)
            if status is not None:
                if status.id != servo_id:
                    raise DxlError(f"id {status.id} answered an instruction to id {servo_id}")
                return status
        if got:
            raise DxlError(f"a garbled answer from id {servo_id} ({got.hex(' ')}): more than one servo "
                           "with that id, or another baud rate")
        return None


def _status(data: bytes) -> Status | None:
    """The status packet data holds, None if it is still incomplete; DxlError if it is not one."""
    if len(data) < 4:
        if bytes(data[:2]) != b"\xff\xff"[:min(2, len(data))]:
            raise DxlError(f"not a status packet: {bytes(data).hex(' ')}")
        return None
    if data[:2] != b"\xff\xff" or data[3] < 2:
        raise DxlError(f"not a status packet: {bytes(data).hex(' ')}")
    end = 4 + data[3]
    if len(data) < end:
        return None
    body = bytes(data[2:end - 1])
    if checksum(body) != data[end - 1] or len(data) > end:
        raise DxlError(f"a garbled status packet ({bytes(data).hex(' ')}): more than one servo answering?")
    return Status(body[0], body[2], body[3:])
