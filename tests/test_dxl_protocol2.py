"""Dynamixel Protocol 2.0 packets: the firmware's C builders and status parser.

Oracles:
- the official DynamixelSDK (Protocol2PacketHandler, GroupSyncWrite, GroupSyncRead) run
  against an in-memory port that records what it writes (sdk_capture.CapturePort; its
  byte stuffing put on the wire, see sdk_capture.packet_handler): every
  instruction packet the C builds must equal the SDK's byte for byte, and the SDK's
  rxPacket / readRx must accept every status packet the C parser accepts;
- the Protocol 2.0 e-manual's worked examples;
- `status()` below, the status packet written out from the e-manual's format: byte
  stuffing of the instruction to the last parameter, then LEN, then CRC-16 with polynomial
  0x8005 (`crc16`, bit by bit from the polynomial).
"""
from __future__ import annotations

import functools
import subprocess
from pathlib import Path

import dynamixel_sdk as sdk
import pytest
from dynamixel_sdk import protocol2_packet_handler as p2
from hypothesis import HealthCheck, assume, given, settings, strategies as st

from guarded_parser import GuardedParser
from sdk_capture import CapturePort, packet_handler, sdk_packet, sdk_sync_write
from uavarm.build import cbuild

ROOT = Path(__file__).resolve().parents[1]
INC = ROOT / "firmware_stm32" / "App" / "Inc"
SRC = ROOT / "firmware_stm32" / "App" / "Src" / "dxl_protocol2.c"
HDR = INC / "dxl_protocol2.h"

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
PH = packet_handler(2.0)
HEADER = b"\xff\xff\xfd\x00"


@functools.cache
def dxl2():
    return cbuild.load("dxl2", [SRC], [HDR], include_dirs=[INC])


# ------------------------------------------------- the e-manual's format

def crc16(data: bytes) -> int:
    """CRC-16, polynomial x^16 + x^15 + x^2 + 1 (0x8005), MSB first, initial value 0."""
    crc = 0
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005 if crc & 0x8000 else crc << 1) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """Every FF FF FD gets an FD added after it."""
    out = bytearray()
    for b in body:
        out.append(b)
        if out[-3:] == b"\xff\xff\xfd":
            out.append(0xFD)
    return bytes(out)


def packet(id_: int, body: bytes) -> bytes:
    """Header, ID, LEN, the stuffed instruction..parameters, CRC."""
    stuffed = stuff(body)
    head = HEADER + bytes([id_]) + (len(stuffed) + 2).to_bytes(2, "little")
    return with_crc(head + stuffed)


def with_crc(without: bytes) -> bytes:
    return without + crc16(without).to_bytes(2, "little")


def status(id_: int, error: int, params: bytes = b"") -> bytes:
    return packet(id_, bytes([0x55, error]) + bytes(params))


# ------------------------------------------------------------- C helpers

def c_build(name: str, *args, cap: int = 1100) -> bytes:
    ffi, lib = dxl2()
    buf = ffi.new("uint8_t[]", cap)
    n = getattr(lib, "dxl2_build_" + name)(buf, cap, *args)
    return bytes(ffi.buffer(buf, n))


def c_array(values):
    ffi, _ = dxl2()
    return ffi.new("uint8_t[]", list(values) or [0])


def c_write(id_, addr, data, cap=1100):
    return c_build("write", id_, addr, c_array(data), len(data), cap=cap)


def c_sync_write(addr, data_len, ids, data, cap=1100):
    return c_build("sync_write", addr, data_len, len(ids), c_array(ids), c_array(data), cap=cap)


def c_sync_read(addr, data_len, ids, cap=1100):
    return c_build("sync_read", addr, data_len, len(ids), c_array(ids), cap=cap)


class Parser(GuardedParser):
    """The C status parser over a buffer with guard bytes after its `size` usable ones."""

    def __init__(self, size=64):
        super().__init__(*dxl2(), "dxl2", size)


NEED, COMPLETE, BAD_CRC, TOO_LONG, BAD_STUFFING = range(5)

servo_ids = st.integers(0, 252)
any_ids = st.one_of(servo_ids, st.just(254))
u16 = st.integers(0, 0xFFFF)
# Data rich in FF and FD, so that stuffing is needed often.
edgy = st.one_of(st.sampled_from([0xFF, 0xFF, 0xFD, 0xFD, 0x00]), st.integers(0, 255))


def edgy_data(min_size=0, max_size=40):
    return st.lists(edgy, min_size=min_size, max_size=max_size).map(bytes)


# ----------------------------------------------------------- constants

def test_constants_match_the_sdk():
    _, lib = dxl2()
    assert lib.DXL2_BROADCAST_ID == sdk.BROADCAST_ID
    assert lib.DXL2_MAX_ID == sdk.MAX_ID
    assert lib.DXL2_MAX_PACKET_LEN == p2.TXPACKET_MAX_LEN
    assert lib.DXL2_MAX_LENGTH == p2.RXPACKET_MAX_LEN
    for name in ["PING", "READ", "WRITE", "REBOOT", "STATUS", "SYNC_READ", "SYNC_WRITE"]:
        assert getattr(lib, "DXL2_INST_" + name) == getattr(sdk, "INST_" + name)
    assert lib.DXL2_ERR_ALERT == p2.ERRBIT_ALERT
    for name in ["RESULT_FAIL", "INSTRUCTION", "CRC", "DATA_RANGE", "DATA_LENGTH", "DATA_LIMIT", "ACCESS"]:
        assert getattr(lib, "DXL2_ERRNUM_" + name) == getattr(p2, "ERRNUM_" + name)


# --------------------------------------------- e-manual worked examples

def test_emanual_instruction_examples():
    assert c_build("ping", 1) == bytes.fromhex("FF FF FD 00 01 03 00 01 19 4E")
    assert c_build("ping", 0xFE) == bytes.fromhex("FF FF FD 00 FE 03 00 01 31 42")
    # Present Position (132, 4 bytes) of ID 1
    assert c_build("read", 1, 132, 4) == bytes.fromhex("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15")
    # 512 to Goal Position (116, 4 bytes) of ID 1
    assert c_write(1, 116, (512).to_bytes(4, "little")) == \
        bytes.fromhex("FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89")
    assert c_build("reboot", 1) == bytes.fromhex("FF FF FD 00 01 03 00 08 2F 4E")
    assert c_sync_read(132, 4, [1, 2]) == bytes.fromhex("FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA")
    # Goal Position 150 to ID 1 and 170 to ID 2
    goals = (150).to_bytes(4, "little") + (170).to_bytes(4, "little")
    assert c_sync_write(116, 4, [1, 2], goals) == bytes.fromhex(
        "FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87")


@pytest.mark.parametrize("wire, expected", [
    ("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D", (1, 0, bytes.fromhex("06 04 26"))),   # PING: XM430-W210, fw 38
    ("FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D", (2, 0, bytes.fromhex("06 04 26"))),
    ("FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0", (1, 0, bytes.fromhex("A6 00 00 00"))),  # READ: 166
    ("FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE", (2, 0, bytes.fromhex("1F 08 00 00"))),  # 2079
    ("FF FF FD 00 01 04 00 55 00 A1 0C", (1, 0, b"")),                                    # WRITE reply
    ("FF FF FD 00 01 06 00 55 00 77 00 C3 69", (1, 0, bytes.fromhex("77 00"))),          # 11.9 V
    ("FF FF FD 00 02 05 00 55 00 24 8B A9", (2, 0, b"\x24")),                            # 36 degC
])
def test_emanual_status_examples(wire, expected):
    p = Parser()
    results = p.feed(bytes.fromhex(wire))
    assert results == [NEED] * (len(results) - 1) + [COMPLETE]
    assert p.packet() == expected
    assert status(*expected) == bytes.fromhex(wire)     # the oracle's format agrees too


# ------------------------------------------------------------------ CRC

@SETTINGS
@given(data=st.binary(max_size=300), start=u16)
def test_crc_matches_the_polynomial_and_the_sdk(data, start):
    _, lib = dxl2()
    assert lib.dxl2_crc(0, data, len(data)) == crc16(data) == PH.updateCRC(0, list(data), len(data))
    assert lib.dxl2_crc(start, data, len(data)) == PH.updateCRC(start, list(data), len(data))


@SETTINGS
@given(data=st.binary(min_size=1, max_size=40), start=u16, changed=st.data())
def test_a_crc_summed_from_the_changing_bytes_shares_is_the_sdks(data, start, changed):
    """The CRC of a packet whose changing bytes are set to 0, XOR each such byte's share
    (dxl2_crc_shares: by its value and how many bytes follow it), is the SDK's CRC of the
    packet: how the firmware's SYNC_WRITE and status readings get their CRCs."""
    ffi, lib = dxl2()
    at = changed.draw(st.sets(st.integers(0, len(data) - 1), min_size=1))
    zeroed = bytes(0 if k in at else b for k, b in enumerate(data))
    crc = PH.updateCRC(start, list(zeroed), len(zeroed))
    share = ffi.new("uint16_t[256]")
    for k in at:
        lib.dxl2_crc_shares(share, len(data) - 1 - k)
        crc ^= share[data[k]]
    assert crc == PH.updateCRC(start, list(data), len(data))


# ------------------------------------------------- builders vs the SDK

@SETTINGS
@given(id_=servo_ids)
def test_ping_and_reboot_match_sdk(id_):
    assert c_build("ping", id_) == sdk_packet("ping", id_, protocol=2.0)
    assert c_build("reboot", id_) == sdk_packet("reboot", id_, protocol=2.0)


@SETTINGS
@given(id_=servo_ids, addr=u16, length=st.integers(1, 1020))
def test_read_matches_sdk(id_, addr, length):
    assert c_build("read", id_, addr, length) == sdk_packet("readTx", id_, addr, length, protocol=2.0)


@SETTINGS
@given(id_=any_ids, addr=u16, data=edgy_data(min_size=1, max_size=300))
def test_write_matches_sdk(id_, addr, data):
    assert c_write(id_, addr, data) == sdk_packet("writeTxOnly", id_, addr, len(data), list(data), protocol=2.0)


@SETTINGS
@given(id_=any_ids, addr=u16, value=st.integers(0, 0xFFFFFFFF))
def test_four_byte_write_matches_sdk(id_, addr, value):
    assert c_write(id_, addr, value.to_bytes(4, "little")) == \
        sdk_packet("write4ByteTxOnly", id_, addr, value, protocol=2.0)


def test_stuffing_is_applied_to_parameters():
    # 0xFDFFFF00 to address 0: the data bytes 00 FF FF FD need a stuffed FD; so do
    # address 0xFFFF and data FD (an FF FF FD across the address and the data).
    for addr, data in [(0, bytes.fromhex("00 FF FF FD")), (0xFFFF, b"\xfd"), (0, bytes.fromhex("FF FF FD FD"))]:
        built = c_write(1, addr, data)
        assert built == sdk_packet("writeTxOnly", 1, addr, len(data), list(data), protocol=2.0)
        assert built == packet(1, b"\x03" + addr.to_bytes(2, "little") + data)
        assert b"\xff\xff\xfd\xfd" in built[7:-2]
        assert int.from_bytes(built[5:7], "little") == len(built) - 7


@st.composite
def sync_writes(draw):
    data_len = draw(st.integers(1, 12))
    ids = draw(st.lists(servo_ids, min_size=1, max_size=40, unique=True))
    data = draw(edgy_data(min_size=data_len * len(ids), max_size=data_len * len(ids)))
    return draw(u16), data_len, ids, data


@SETTINGS
@given(sync_writes())
def test_sync_write_matches_sdk_group_sync_write(args):
    addr, data_len, ids, data = args
    assert c_sync_write(addr, data_len, ids, data) == sdk_sync_write(PH, addr, data_len, ids, data)


@SETTINGS
@given(st.lists(st.tuples(servo_ids, st.integers(0, 0xFFFFFFFF)), min_size=1, max_size=20,
                unique_by=lambda t: t[0]))
def test_goal_position_sync_write_matches_sdk(servos):
    # X-series Goal Position: address 116, 4 bytes (a negative goal is its two's complement)
    ids = [id_ for id_, _ in servos]
    data = b"".join(bytes([sdk.DXL_LOBYTE(sdk.DXL_LOWORD(goal)), sdk.DXL_HIBYTE(sdk.DXL_LOWORD(goal)),
                           sdk.DXL_LOBYTE(sdk.DXL_HIWORD(goal)), sdk.DXL_HIBYTE(sdk.DXL_HIWORD(goal))])
                    for _, goal in servos)
    assert c_sync_write(116, 4, ids, b"".join(g.to_bytes(4, "little") for _, g in servos)) == \
        sdk_sync_write(PH, 116, 4, ids, data)


@SETTINGS
@given(addr=u16, data_len=st.integers(1, 1020), ids=st.lists(servo_ids, min_size=1, max_size=60, unique=True))
def test_sync_read_matches_sdk_group_sync_read(addr, data_len, ids):
    port = CapturePort()
    group = sdk.GroupSyncRead(port, PH, addr, data_len)
    for id_ in ids:
        assert group.addParam(id_)
    assert group.txPacket() == sdk.COMM_SUCCESS
    assert c_sync_read(addr, data_len, ids) == port.sent[0]


def test_packet_length_limit_is_the_sdks():
    # 1012 data bytes make a 1024-byte WRITE, the SDK's largest; one more is refused (the
    # SDK's addStuffing raises IndexError there, past its 1024-byte buffer)
    assert c_write(1, 0, bytes(1012)) == sdk_packet("writeTxOnly", 1, 0, 1012, [0] * 1012, protocol=2.0)
    assert len(c_write(1, 0, bytes(1012))) == 1024
    assert c_write(1, 0, bytes(1013)) == b""
    with pytest.raises(IndexError):
        sdk_packet("writeTxOnly", 1, 0, 1013, [0] * 1013, protocol=2.0)
    # stuffing counts: 1011 data bytes stuffed to 1012 make a 1024-byte packet, one more
    # byte is too many
    data = bytes(1008) + b"\xff\xff\xfd"
    built = c_write(1, 0, data)
    assert len(built) == 1024
    assert built == sdk_packet("writeTxOnly", 1, 0, len(data), list(data), protocol=2.0)
    assert c_write(1, 0, b"\x00" + data) == b""


def test_invalid_arguments_give_zero():
    for bad_id in (253, 255):
        assert c_build("ping", bad_id) == b""
        assert c_build("reboot", bad_id) == b""
        assert c_write(bad_id, 0, b"\x01") == b""
    assert c_build("read", 0xFE, 0, 1) == b""        # a broadcast READ is never answered
    assert c_build("read", 1, 0, 0) == b""
    assert c_build("read", 1, 0, 1021) == b""        # its reply would exceed the SDK's LEN limit
    assert c_write(1, 0, b"") == b""
    assert c_sync_write(116, 4, [], b"") == b""
    assert c_sync_write(116, 0, [1], b"") == b""
    assert c_sync_write(116, 1, [0xFE], b"\x00") == b""   # entries must name servos
    assert c_sync_read(132, 4, []) == b""
    assert c_sync_read(132, 0, [1]) == b""
    assert c_sync_read(132, 4, [1, 253]) == b""
    ffi, lib = dxl2()
    buf = ffi.new("uint8_t[32]")
    assert lib.dxl2_build_ping(ffi.NULL, 32, 1) == 0
    assert lib.dxl2_build_write(buf, 32, 1, 0, ffi.NULL, 1) == 0
    assert lib.dxl2_build_sync_write(buf, 32, 0, 1, 1, ffi.NULL, buf) == 0
    assert lib.dxl2_build_sync_write(buf, 32, 0, 1, 1, buf, ffi.NULL) == 0


@SETTINGS
@given(id_=servo_ids, addr=u16, data=edgy_data(min_size=1, max_size=40), short=st.integers(1, 8))
def test_too_small_buffer_gives_zero_and_writes_within_cap(id_, addr, data, short):
    ffi, lib = dxl2()
    need = len(c_write(id_, addr, data))
    buf = ffi.new("uint8_t[]", [0x5A] * need)
    assert lib.dxl2_build_write(buf, need - short, id_, addr, c_array(data), len(data)) == 0
    assert bytes(buf)[need - short:] == b"\x5a" * short
    assert lib.dxl2_build_write(buf, need, id_, addr, c_array(data), len(data)) == need


# ----------------------------------------------------------------- parser

def valid_status(max_params=30):
    return st.builds(status, servo_ids, st.integers(0, 255), edgy_data(max_size=max_params))


def status_parts():
    return st.tuples(servo_ids, st.integers(0, 255), edgy_data(max_size=30))


def sdk_read(stream: bytes, id_: int, length: int):
    return PH.readRx(CapturePort(stream), id_, length)


@SETTINGS
@given(parts=status_parts())
def test_every_valid_status_parses_like_the_sdk(parts):
    id_, error, params = parts
    pkt = status(id_, error, params)
    p = Parser(size=96)
    assert p.feed(pkt)[-1] == COMPLETE
    assert p.packet() == (id_, error, params)
    assert p.guard_intact()
    # the SDK accepts it, and reads the same parameters when none were stuffed (its
    # in-place removeStuffing can lose a byte: see the test below)
    data, result, sdk_error = sdk_read(pkt, id_, len(params))
    assert (result, sdk_error) == (sdk.COMM_SUCCESS, error)
    if stuff(params) == params:
        assert bytes(data) == params


def test_stuffed_status_where_the_sdk_loses_a_byte():
    # Parameters FF FF FD FF FD FD are sent FF FF FD FD FF FD FD. The SDK's removeStuffing
    # reads bytes it has already moved down and drops a second FD; the written rule drops
    # only the added one.
    params = bytes.fromhex("FF FF FD FF FD FD")
    pkt = status(1, 0, params)
    assert pkt[9:-2] == bytes.fromhex("FF FF FD FD FF FD FD")
    p = Parser()
    assert p.feed(pkt)[-1] == COMPLETE and p.packet() == (1, 0, params)
    data, result, _ = sdk_read(pkt, 1, len(params))
    assert result == sdk.COMM_SUCCESS
    assert bytes(data) != params, ("the SDK's removeStuffing keeps every byte now: compare stuffed "
                                   "parameters too in test_every_valid_status_parses_like_the_sdk")


def test_error_byte_is_reported_with_its_alert_bit():
    ffi, lib = dxl2()
    out = ffi.new("dxl2_error_t *")
    for error in (0x00, 0x07, 0x80, 0x84, 0xFF):
        p = Parser()
        assert p.feed(status(3, error, b"\x01"))[-1] == COMPLETE
        assert p.p.error == error
        lib.dxl2_decode_error(p.p.error, out)
        assert (out.hardware_error, out.number) == (error >> 7, error & 0x7F)
        alert = PH.getRxPacketError(error).startswith("[RxPacketError] Hardware error")
        assert bool(out.hardware_error) == alert


def test_parse_bytes_stops_after_a_packet():
    ffi, lib = dxl2()
    p = Parser()
    a, b = status(1, 0, b"\x10"), status(2, 0, b"\x20\x21")
    stream = b"\x00" + a + b
    used = ffi.new("size_t *")
    assert lib.dxl2_parse_bytes(p.p, stream, len(stream), used) == COMPLETE
    assert used[0] == 1 + len(a) and p.packet() == (1, 0, b"\x10")
    rest = stream[used[0]:]
    assert lib.dxl2_parse_bytes(p.p, rest, len(rest), used) == COMPLETE
    assert used[0] == len(b) and p.packet() == (2, 0, b"\x20\x21")
    assert lib.dxl2_parse_bytes(p.p, b"\xff\xff", 2, ffi.NULL) == NEED


# -------------------------------------------------------- corrupted packets

def assert_refused(bad: bytes, expected_last: int, size=96):
    p = Parser(size=size)
    results = p.feed(bad)
    assert COMPLETE not in results, bad.hex(" ")
    assert results[-1] == expected_last, (results, bad.hex(" "))
    # and the parser is ready for the next packet
    good = status(9, 0, b"\x01\x02")
    assert p.feed(good)[-1] == COMPLETE and p.packet() == (9, 0, b"\x01\x02")
    assert p.guard_intact()


def no_inner_header(pkt: bytes) -> bool:
    return HEADER not in pkt[1:]


@SETTINGS
@given(pkt=valid_status(), where=st.integers(0, 10_000), flip=st.integers(1, 255))
def test_bad_crc_is_refused(pkt, where, flip):
    # any byte after LEN (instruction, error, parameters, CRC) changed: the CRC is wrong
    where = 7 + where % (len(pkt) - 7)
    assume(where != 7)                            # a changed instruction is not a status
    bad = bytearray(pkt)
    bad[where] ^= flip
    assume(no_inner_header(bytes(bad)))
    assert_refused(bytes(bad), BAD_CRC)
    assert PH.rxPacket(CapturePort(bytes(bad)), False)[1] == sdk.COMM_RX_CORRUPT


@SETTINGS
@given(parts=status_parts(), k=st.integers(0, 100))
def test_bad_stuffing_is_refused(parts, k):
    # a parameter block with FF FF FD in it, sent without the added FD (CRC and LEN right)
    # (and not followed by an FD, which would make it a stuffed FF FF FD)
    id_, error, params = parts
    k %= len(params) + 1
    assume(params[k:k + 1] != b"\xfd")
    body = bytes([0x55, error]) + params[:k] + b"\xff\xff\xfd" + params[k:]
    bad = with_crc(HEADER + bytes([id_]) + (len(body) + 2).to_bytes(2, "little") + body)
    assume(no_inner_header(bad))
    assert_refused(bad, BAD_STUFFING)


def test_stuffed_fd_missing_at_the_end_is_refused():
    # the parameters end in FF FF FD: the added FD must come before the CRC
    body = bytes.fromhex("55 00 FF FF FD")
    bad = with_crc(HEADER + b"\x01" + (len(body) + 2).to_bytes(2, "little") + body)
    assert_refused(bad, BAD_STUFFING)
    assert status(1, 0, b"\xff\xff\xfd")[7:-2] == bytes.fromhex("55 00 FF FF FD FD")


@pytest.mark.parametrize("id_", [253, 254, 255])
def test_wrong_id_is_refused(id_):
    bad = with_crc(HEADER + bytes([id_]) + bytes.fromhex("05 00 55 00 07"))
    assert_refused(bad, NEED)
    assert PH.rxPacket(CapturePort(bad), False)[1] != sdk.COMM_SUCCESS


@pytest.mark.parametrize("inst", [0x01, 0x02, 0x03, 0x54, 0x56, 0xD5])
def test_wrong_instruction_is_refused(inst):
    bad = with_crc(HEADER + bytes([1, 5, 0, inst]) + bytes.fromhex("00 07"))
    assert_refused(bad, NEED)
    assert PH.rxPacket(CapturePort(bad), False)[1] != sdk.COMM_SUCCESS


def test_reserved_byte_must_be_zero():
    bad = with_crc(b"\xff\xff\xfd\x01" + bytes.fromhex("01 05 00 55 00 07"))
    assert_refused(bad, NEED)


@pytest.mark.parametrize("length", [2, 3])
def test_length_below_four_is_not_a_status(length):
    # as long as LEN says, with the right CRC, but no room for the instruction and error
    bad = with_crc(HEADER + bytes([1, length, 0]) + b"\x55"[:length - 2])
    assert_refused(bad, NEED)


@SETTINGS
@given(pkt=valid_status(), length=st.integers(4, 60))
def test_wrong_length_is_refused(pkt, length):
    # LEN changed, CRC recomputed over the packet as sent: too short or too long a packet
    assume(length != int.from_bytes(pkt[5:7], "little"))
    bad = with_crc(pkt[:5] + length.to_bytes(2, "little") + pkt[7:-2])
    cut = bad[:length + 7]                       # where the changed LEN says it ends
    assume(no_inner_header(bad))
    assume(len(cut) == len(bad) or cut[-2:] != crc16(cut[:-2]).to_bytes(2, "little"))
    p = Parser(size=96)
    results = p.feed(bad)
    assert COMPLETE not in results
    # a packet announced longer swallows nothing that follows: the next packet is found
    good = status(9, 0, b"\x01\x02")
    assert p.feed(good)[-1] == COMPLETE and p.packet() == (9, 0, b"\x01\x02")


def test_too_long_is_reported_and_skipped():
    p = Parser(size=16)                              # room for 5 parameters
    results = p.feed(status(1, 0, bytes(6)))
    assert results[6] == TOO_LONG                    # at its LEN_H byte
    assert COMPLETE not in results
    assert p.feed(status(2, 0, bytes(5)))[-1] == COMPLETE
    assert p.packet() == (2, 0, bytes(5))
    assert p.guard_intact()
    # LEN above the SDK's 1024 is no header at all
    assert Parser(size=16).feed(HEADER + bytes([1]) + (1025).to_bytes(2, "little"))[-1] == NEED


# -------------------------------------------------------- resynchronising

@SETTINGS
@given(garbage=st.binary(max_size=80), pkt=valid_status())
def test_valid_status_found_after_any_garbage(garbage, pkt):
    assume(no_inner_header(pkt))
    p = Parser(size=64)
    results = p.feed(garbage + pkt)
    assert results[-1] == COMPLETE
    assert status(*p.packet()) == pkt
    assert p.guard_intact()
    rx, result = PH.rxPacket(CapturePort(garbage + pkt), False)
    if result == sdk.COMM_SUCCESS:      # the SDK can lose it to a long fake header
        assert rx[4] == pkt[4]


@SETTINGS
@given(pkts=st.lists(st.tuples(valid_status(), st.floats(0, 1)), min_size=1, max_size=4),
       last=valid_status())
def test_truncated_packets_do_not_swallow_the_next(pkts, last):
    assume(no_inner_header(last))
    stream = b"".join(pkt[:max(1, int(cut * (len(pkt) - 1)))] for pkt, cut in pkts)
    p = Parser(size=64)
    results = p.feed(stream + last)
    assert results[-1] == COMPLETE
    assert status(*p.packet()) == last


@settings(SETTINGS, max_examples=300)
@given(chunks=st.lists(st.one_of(edgy_data(max_size=40), valid_status(max_params=8)), max_size=12),
       size=st.integers(11, 24))
def test_random_streams_stay_in_bounds(chunks, size):
    data = b"".join(chunks)
    p = Parser(size=size)
    start = int(p.ffi.cast("uintptr_t", p.mem))
    for i, b in enumerate(data):
        r = p.lib.dxl2_parse_byte(p.p, b)
        assert r in range(5)
        assert p.p.len <= size and p.guard_intact()
        if r == COMPLETE:
            # what is reported is a well-formed status packet made of the last bytes fed
            id_, error, params = p.packet()
            pkt = status(id_, error, params)
            assert data[i + 1 - len(pkt):i + 1] == pkt
            assert PH.rxPacket(CapturePort(pkt), False)[1] == sdk.COMM_SUCCESS
            offset = int(p.ffi.cast("uintptr_t", p.p.params)) - start
            assert 9 <= offset and offset + len(params) <= size and id_ <= 252


def unstuff(raw: bytes):
    """The stuffed part as the servo meant it, or None when an FF FF FD lacks its added FD."""
    out, k = bytearray(), 0
    while k < len(raw):
        out.append(raw[k])
        if raw[k] == 0xFD and k >= 2 and raw[k - 2:k] == b"\xff\xff":
            if raw[k + 1:k + 2] != b"\xfd":
                return None
            k += 1
        k += 1
    return bytes(out)


def reference_parse(stream: bytes, size: int):
    """The resynchronising rules of dxl_protocol2.h, applied by brute force to the whole
    stream: per byte, every start not yet discarded, newest first. Yields (result, packet)
    per byte. A good packet ending on the byte wins (the newest of them); else the last
    bad CRC or bad stuffing met; else a header whose LEN just arrived announcing more than
    `size` bytes (within the SDK's LEN <= 1024)."""
    base = 0                                      # starts before this were discarded
    for i in range(len(stream)):
        result, packet = NEED, None
        for s in range(i, base - 1, -1):
            b, n = stream[s:i + 1], i + 1 - s
            if b[:4] != HEADER[:n] or (n >= 5 and b[4] > 252) or n < 7:
                continue
            length = int.from_bytes(b[5:7], "little")
            if not 4 <= length <= 1024:
                continue
            if length + 7 > size:
                if n == 7 and result == NEED:
                    result = TOO_LONG
                continue
            if n < 8 or b[7] != 0x55 or n != length + 7:
                continue
            body = unstuff(b[7:-2])
            if crc16(b[:-2]) != int.from_bytes(b[-2:], "little"):
                result = BAD_CRC
            elif body is None:
                result = BAD_STUFFING
            else:
                result, packet, base = COMPLETE, (b[4], body[1], body[2:]), i + 1
                break
        yield result, packet


def overlapping_packets():
    """Streams where packets start inside packets: good, truncated, corrupted, badly
    stuffed and too-long packets, headers cut short, and edgy bytes, in any order."""
    def cut(pkt, k):
        return pkt[:max(1, k % len(pkt))]

    def corrupt(pkt, k):
        b = bytearray(pkt)
        b[-1] ^= 1 + k % 255
        return bytes(b)

    def unstuffed(id_, params):
        body = b"\x55\x00" + params + b"\xff\xff\xfd"
        return with_crc(HEADER + bytes([id_]) + (len(body) + 2).to_bytes(2, "little") + body)

    piece = st.one_of(
        valid_status(max_params=12),
        st.builds(status, st.sampled_from([252, 253, 254, 255]), st.integers(0, 255), edgy_data(max_size=6)),
        st.builds(cut, valid_status(max_params=12), st.integers(0, 255)),
        st.builds(corrupt, valid_status(max_params=12), st.integers(0, 255)),
        st.builds(unstuffed, servo_ids, edgy_data(max_size=6)),
        st.builds(lambda i, n: HEADER + bytes([i]) + n.to_bytes(2, "little"), st.integers(0, 255),
                  st.integers(0, 1100)),
        edgy_data(max_size=6),
    )
    return st.lists(piece, max_size=10).map(b"".join)


@settings(SETTINGS, max_examples=400)
@given(stream=overlapping_packets(), size=st.integers(11, 32))
def test_every_byte_does_what_the_written_rules_say(stream, size):
    Parser(size=size).follow(stream, reference_parse(stream, size))


def test_reported_packet_discards_itself():
    # A packet ending in FF FF whose CRC is FD 00: a header straddles its end. What
    # follows would complete a packet from that header; the reported packet's bytes are
    # gone, so nothing does.
    pkt = next(pkt for x in range(256) for y in range(256)
               if (pkt := status(1, 0, bytes([x, y, 0xFF, 0xFF])))[-2:] == b"\xfd\x00")
    assert pkt[-4:] == HEADER
    tail = status(2, 0)[4:]                              # with pkt's last 4 bytes: a good packet
    p = Parser()
    results = p.feed(pkt + tail)
    assert results[len(pkt) - 1] == COMPLETE and p.packet() == (1, 0, bytes(pkt[9:13]))
    assert results[len(pkt):] == [NEED] * len(tail)


def test_back_to_back_packets():
    p = Parser(size=32)
    a, b = status(1, 0, b"\xff\xff\xfd"), status(2, 0x84, b"")
    results = p.feed(a + b)
    assert [i for i, r in enumerate(results) if r == COMPLETE] == [len(a) - 1, len(a + b) - 1]
    assert p.packet() == (2, 0x84, b"")


def test_reset_forgets_partial_packet():
    p = Parser()
    good = status(1, 0, b"\x07")
    p.feed(good[:6])
    p.lib.dxl2_parser_reset(p.p)
    assert p.feed(good[6:]) == [NEED] * (len(good) - 6)
    assert p.feed(good)[-1] == COMPLETE


def test_parser_init_checks_its_buffer():
    ffi, lib = dxl2()
    p = ffi.new("dxl2_parser_t *")
    buf = ffi.new("uint8_t[16]")
    assert lib.dxl2_parser_init(p, buf, 10) == -1
    assert lib.dxl2_parser_init(p, ffi.NULL, 16) == -1
    assert lib.dxl2_parser_init(p, buf, 11) == 0
    assert Parser(size=11).feed(status(4, 0))[-1] == COMPLETE


# ------------------------------------------------------------ target build

def test_compiles_for_the_target(tmp_path):
    from conftest import require_arm_toolchain
    require_arm_toolchain()
    cmd = ["arm-none-eabi-gcc", *cbuild.TARGET_FLAGS, f"-I{INC}", "-c", str(SRC),
           "-o", str(tmp_path / "dxl_protocol2.o")]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
