"""LLCP framing (MRS "low-level communication protocol", hexadecimal mode), drone side.

Written from the wire format, independently of the firmware's C (the tests compare the two):

    b SS P0 P1 ... Pn-1 CC

``SS`` is the payload length n (1..255) as two upper-case hex digits, each payload byte follows
as two upper-case hex digits (P0 is the message id), and ``CC`` is the 8-bit sum of every ASCII
character before it, the ``b`` included, as two hex digits. Anything that is not ``b`` may sit
between frames.

The decoder applies the same rules as the firmware's receiver (firmware_stm32/App/Inc/llcp.h),
which are stricter than MRS's own: upper-case hex only, so ``b`` never occurs inside a frame and
always starts a new one; any other non-hex character or a checksum mismatch drops the frame;
length 0 is ignored; a partial frame is dropped after an idle gap; optionally the length must
match the one expected for the message id.
"""
from __future__ import annotations

import enum
import re
import time
from typing import Callable, Optional

MAX_PAYLOAD = 255
# The MRS ROS node mangles received frames longer than this (it keeps 2 * n in a uint8_t), so
# the device never sends longer ones; the drone may send up to MAX_PAYLOAD.
TX_MAX_PAYLOAD = 127

_HEX = "0123456789ABCDEF"
_START = ord("b")
_HEX_RUN = re.compile(rb"[0-9A-F]*")


def frame_size(n: int) -> int:
    """Characters in a frame of n payload bytes."""
    return 5 + 2 * n


def encode(payload: bytes, max_len: int = MAX_PAYLOAD) -> bytes:
    """The frame carrying payload (1..max_len bytes)."""
    payload = bytes(payload)
    if not 1 <= len(payload) <= min(max_len, MAX_PAYLOAD):
        raise ValueError(f"LLCP payload must be 1..{min(max_len, MAX_PAYLOAD)} bytes, got {len(payload)}")
    body = "b" + "".join(_HEX[x >> 4] + _HEX[x & 15] for x in (len(payload), *payload))
    checksum = sum(body.encode("ascii")) & 0xFF
    return (body + _HEX[checksum >> 4] + _HEX[checksum & 15]).encode("ascii")


class Result(enum.IntEnum):
    """What one received byte did; the ERR_* values mean a frame was dropped."""

    NONE = 0
    FRAME = 1
    ERR_CHECKSUM = 2
    ERR_HEX = 3
    ERR_LENGTH = 4
    ERR_UNKNOWN_ID = 5
    ERR_TIMEOUT = 6
    ERR_RESTART = 7


def _digit(byte: int) -> int:
    """Value of an upper-case hex digit, or -1."""
    if 0x30 <= byte <= 0x39:
        return byte - 0x30
    if 0x41 <= byte <= 0x46:
        return byte - 0x41 + 10
    return -1


class Decoder:
    """Incremental receiver: ``feed(data)`` returns the payloads completed by ``data``.

    gap: idle time (same unit as the ``now`` values passed in; seconds of time.monotonic() by
    default) after which a partial frame is dropped; None never drops.
    expected_len: optional ``f(id) -> int``, the payload length id must have, negative (or None)
    for an unknown id; frames that disagree are dropped.
    Error counts are kept in the attributes named like the firmware's counters.
    """

    def __init__(self, gap: Optional[float] = None,
                 expected_len: Optional[Callable[[int], Optional[int]]] = None):
        self.gap = gap
        self.expected_len = expected_len
        self.payload = b""  # the last delivered frame
        self._chars: Optional[bytearray] = None  # the current frame's characters, None = idle
        self._last: Optional[float] = None
        self.frames_ok = self.checksum_errors = self.hex_errors = 0
        self.length_errors = self.unknown_ids = self.timeouts = self.restarts = 0

    def feed(self, data: bytes, now: Optional[float] = None) -> list[bytes]:
        """Feeds bytes that arrived together at time now; returns the completed payloads."""
        if now is None:
            now = time.monotonic()
        data = bytes(data)
        if not data:
            return []
        self.poll(now)            # (the bytes after the first arrive no later: no gap among them)
        self._last = now
        frames, i = [], 0
        while i < len(data):      # feed_byte's rules, a run of characters at a time
            chars = self._chars
            if chars is None:     # junk up to the next start
                i = data.find(b"b", i)
                if i < 0:
                    break
                self._chars, i = bytearray(b"b"), i + 1
                continue
            need = (3 if len(chars) < 3 else frame_size(int(chars[1:3], 16))) - len(chars)
            run = _HEX_RUN.match(data, i, i + need).end() - i
            chars += data[i:i + run]
            i += run
            if run == need:
                if len(chars) == 3 and int(chars[1:3], 16) == 0:
                    self._chars = None            # length 0 is ignored
                elif len(chars) > 3:
                    self._chars = None
                    if self._complete(chars, int(chars[1:3], 16)) is Result.FRAME:
                        frames.append(self.payload)
            elif i < len(data):   # a character that is not a digit
                if data[i] == _START:
                    self.restarts += 1
                    self._chars = bytearray(b"b")
                else:
                    self._chars = None
                    self.hex_errors += 1
                i += 1
        return frames

    def poll(self, now: Optional[float] = None) -> Result:
        """Drops a partial frame idle for longer than the gap."""
        if now is None:
            now = time.monotonic()
        if self._chars is not None and self.gap is not None and now - self._last > self.gap:
            self._chars = None
            self.timeouts += 1
            return Result.ERR_TIMEOUT
        return Result.NONE

    def feed_byte(self, byte: int, now: float) -> Result:
        result = self.poll(now)
        self._last = now
        if byte == _START:
            if self._chars is not None:
                self.restarts += 1
                result = Result.ERR_RESTART
            self._chars = bytearray(b"b")
            return result
        if self._chars is None:
            return result  # junk between frames
        if _digit(byte) < 0:
            self._chars = None
            self.hex_errors += 1
            return Result.ERR_HEX
        chars = self._chars
        chars.append(byte)
        if len(chars) < 3:
            return Result.NONE
        n = int(chars[1:3], 16)
        if n == 0:
            self._chars = None  # length 0 is ignored
            return Result.NONE
        if len(chars) < frame_size(n):
            return Result.NONE
        self._chars = None
        return self._complete(chars, n)

    def _complete(self, chars: bytearray, n: int) -> Result:
        body, checksum = chars[:-2], int(chars[-2:], 16)
        if sum(body) & 0xFF != checksum:
            self.checksum_errors += 1
            return Result.ERR_CHECKSUM
        payload = bytes.fromhex(body[3:].decode("ascii"))
        if self.expected_len is not None:
            want = self.expected_len(payload[0])
            if want is None or want < 0:
                self.unknown_ids += 1
                return Result.ERR_UNKNOWN_ID
            if want != n:
                self.length_errors += 1
                return Result.ERR_LENGTH
        self.payload = payload
        self.frames_ok += 1
        return Result.FRAME
