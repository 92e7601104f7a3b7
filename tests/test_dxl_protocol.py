"""Dynamixel Protocol 1.0 packets: the firmware's C builders and status parser.

Oracles:
- the official DynamixelSDK (Protocol1PacketHandler, GroupSyncWrite) run against an
  in-memory port that records what it writes (sdk_capture.CapturePort): every
  instruction packet the C builds must equal the SDK's byte for byte, and the SDK's
  rxPacket must accept every status packet the C parser accepts;
- the AX-12A e-manual's worked examples;
- `status()` below, the status packet written out from the facts file's checksum formula.
"""
from __future__ import annotations

import functools
import subprocess
from pathlib import Path

import dynamixel_sdk as sdk
import pytest
from hypothesis import HealthCheck, assume, given, settings, strategies as st

from guarded_parser import GuardedParser
from sdk_capture import CapturePort, sdk_sync_write
from uavarm.build import cbuild

ROOT = Path(__file__).resolve().parents[1]
INC = ROOT / "firmware_stm32" / "App" / "Inc"
SRC = ROOT / "firmware_stm32" / "App" / "Src" / "dxl_protocol.c"
HDR = INC / "dxl_protocol.h"

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
PH = sdk.Protocol1PacketHandler()


@functools.cache
def dxl():
    return cbuild.load("dxl", [SRC], [HDR], include_dirs=[INC])


def status(id_: int, error: int, params: bytes = b"") -> bytes:
    """A status packet per the facts file: FF FF ID LEN ERR P.. ~(ID+LEN+ERR+P..)."""
    body = bytes([id_, len(params) + 2, error]) + bytes(params)
    return b"\xff\xff" + body + bytes([~sum(body) & 0xFF])


def sdk_tx(call, *args) -> bytes:
    """The bytes an SDK call puts on the wire (nothing answers)."""
    port = CapturePort()
    call(port, *args)
    assert len(port.sent) == 1
    return port.sent[0]


def c_build(name: str, *args, cap: int = 300) -> bytes:
    ffi, lib = dxl()
    buf = ffi.new("uint8_t[]", cap)
    n = getattr(lib, "dxl_build_" + name)(buf, cap, *args)
    return bytes(ffi.buffer(buf, n))


def c_bytes(data):
    ffi, _ = dxl()
    return ffi.new("uint8_t[]", bytes(data) or b"\0"), len(data)


def c_sync(addr, data_len, ids, data, cap=300):
    ffi, _ = dxl()
    return c_build("sync_write", addr, data_len, len(ids), ffi.new("uint8_t[]", list(ids) or [0]),
                   ffi.new("uint8_t[]", bytes(data) or b"\0"), cap=cap)


def c_goal_speed(ids, goals, speeds, cap=300):
    ffi, _ = dxl()
    return c_build("sync_goal_speed", len(ids), ffi.new("uint8_t[]", list(ids) or [0]),
                   ffi.new("uint16_t[]", list(goals) or [0]), ffi.new("uint16_t[]", list(speeds) or [0]),
                   cap=cap)


def c_write(name, id_, addr, data, cap=300):
    ptr, n = c_bytes(data)
    return c_build(name, id_, addr, ptr, n, cap=cap)


class Parser(GuardedParser):
    """The C status parser over a buffer with guard bytes after its `size` usable ones."""

    def __init__(self, size=64):
        super().__init__(*dxl(), "dxl", size)


servo_ids = st.integers(0, 253)
any_ids = st.integers(0, 254)
u8 = st.integers(0, 255)


# ----------------------------------------------------------- constants

def test_constants_match_the_sdk():
    _, lib = dxl()
    assert lib.DXL_BROADCAST_ID == sdk.BROADCAST_ID
    assert lib.DXL_MAX_PACKET_LEN == sdk.protocol1_packet_handler.TXPACKET_MAX_LEN
    for c, s in [("PING", "PING"), ("READ", "READ"), ("WRITE", "WRITE"), ("REG_WRITE", "REG_WRITE"),
                 ("ACTION", "ACTION"), ("RESET", "FACTORY_RESET"), ("SYNC_WRITE", "SYNC_WRITE")]:
        assert getattr(lib, "DXL_INST_" + c) == getattr(sdk, "INST_" + s)
    pairs = [("VOLTAGE", "VOLTAGE"), ("ANGLE_LIMIT", "ANGLE"), ("OVERHEATING", "OVERHEAT"),
             ("RANGE", "RANGE"), ("CHECKSUM", "CHECKSUM"), ("OVERLOAD", "OVERLOAD"),
             ("INSTRUCTION", "INSTRUCTION")]
    for c, s in pairs:
        assert getattr(lib, "DXL_ERR_" + c) == getattr(sdk.protocol1_packet_handler, "ERRBIT_" + s)


# --------------------------------------------- e-manual worked examples

def test_emanual_instruction_examples():
    assert c_build("ping", 1) == bytes.fromhex("FF FF 01 02 01 FB")
    assert c_build("read", 1, 0x2B, 1) == bytes.fromhex("FF FF 01 04 02 2B 01 CC")
    assert c_write("write", 0xFE, 3, [1]) == bytes.fromhex("FF FF FE 04 03 03 01 F6")
    assert c_write("write", 1, 0x0C, [0x64, 0xAA]) == bytes.fromhex("FF FF 01 05 03 0C 64 AA DC")
    assert c_write("reg_write", 1, 0x1E, [0xF4, 0x01]) == bytes.fromhex("FF FF 01 05 04 1E F4 01 E2")
    assert c_build("action", 0xFE) == bytes.fromhex("FF FF FE 02 05 FA")
    assert c_build("reset", 0) == bytes.fromhex("FF FF 00 02 06 F7")
    sync = bytes.fromhex("FF FF FE 0E 83 1E 04 00 10 00 50 01 01 20 02 60 03 67")
    assert c_sync(0x1E, 4, [0, 1], bytes.fromhex("10 00 50 01 20 02 60 03")) == sync
    assert c_goal_speed([0, 1], [0x010, 0x220], [0x150, 0x360]) == sync


@pytest.mark.parametrize("wire, expected", [
    ("FF FF 01 02 00 FC", (1, 0, b"")),               # PING reply
    ("FF FF 01 03 00 20 DB", (1, 0, b"\x20")),        # READ temperature reply: 32 degC
    ("FF FF 00 02 00 FD", (0, 0, b"")),               # RESET reply
    ("FF FF 00 02 08 F5", (0, 8, b"")),               # locked Punch write: Range error
])
def test_emanual_status_examples(wire, expected):
    p = Parser()
    results = p.feed(bytes.fromhex(wire))
    assert results[:-1] == [0] * (len(results) - 1)
    assert results[-1] == p.lib.DXL_PARSE_COMPLETE
    assert p.packet() == expected


# ------------------------------------------------- builders vs the SDK

@SETTINGS
@given(id_=servo_ids)
def test_ping_matches_sdk(id_):
    assert c_build("ping", id_) == sdk_tx(PH.ping, id_)


@SETTINGS
@given(id_=servo_ids, addr=u8, length=st.integers(1, 244))
def test_read_matches_sdk(id_, addr, length):
    assert c_build("read", id_, addr, length) == sdk_tx(PH.readTx, id_, addr, length)


@SETTINGS
@given(id_=any_ids, addr=u8, data=st.binary(min_size=1, max_size=243))
def test_write_and_reg_write_match_sdk(id_, addr, data):
    assert c_write("write", id_, addr, data) == sdk_tx(PH.writeTxOnly, id_, addr, len(data), list(data))
    assert c_write("reg_write", id_, addr, data) == sdk_tx(PH.regWriteTxOnly, id_, addr, len(data), list(data))


@SETTINGS
@given(id_=any_ids, addr=u8, value=st.integers(0, 0xFFFF))
def test_little_endian_writes_match_sdk(id_, addr, value):
    assert c_write("write", id_, addr, [value & 0xFF]) == sdk_tx(PH.write1ByteTxOnly, id_, addr, value & 0xFF)
    assert c_write("write", id_, addr, value.to_bytes(2, "little")) == sdk_tx(PH.write2ByteTxOnly, id_, addr, value)


@SETTINGS
@given(id_=any_ids)
def test_action_matches_sdk(id_):
    assert c_build("action", id_) == sdk_tx(PH.action, id_)


@SETTINGS
@given(id_=servo_ids)
def test_reset_matches_sdk(id_):
    assert c_build("reset", id_) == sdk_tx(PH.factoryReset, id_)


@st.composite
def sync_writes(draw):
    data_len = draw(st.integers(1, 20))
    max_servos = (250 - 8) // (data_len + 1)
    ids = draw(st.lists(servo_ids, min_size=1, max_size=max_servos, unique=True))
    data = draw(st.binary(min_size=data_len * len(ids), max_size=data_len * len(ids)))
    return draw(u8), data_len, ids, data


@SETTINGS
@given(sync_writes())
def test_sync_write_matches_sdk_group_sync_write(args):
    addr, data_len, ids, data = args
    assert c_sync(addr, data_len, ids, data) == sdk_sync_write(PH, addr, data_len, ids, data)


@SETTINGS
@given(st.lists(st.tuples(servo_ids, st.integers(0, 1023), st.integers(0, 2047)),
                min_size=1, max_size=48, unique_by=lambda t: t[0]))
def test_goal_speed_sync_matches_sdk(servos):
    port = CapturePort()
    group = sdk.GroupSyncWrite(port, PH, 30, 4)
    for id_, goal, speed in servos:
        group.addParam(id_, [sdk.DXL_LOBYTE(goal), sdk.DXL_HIBYTE(goal),
                             sdk.DXL_LOBYTE(speed), sdk.DXL_HIBYTE(speed)])
    group.txPacket()
    ids, goals, speeds = zip(*servos)
    assert c_goal_speed(ids, goals, speeds) == port.sent[0]


def test_packet_length_limit_is_the_sdks():
    # 243 data bytes make a 250-byte WRITE, the SDK's largest; one more is refused by both.
    for n, ok in [(243, True), (244, False)]:
        port = CapturePort()
        result = PH.writeTxOnly(port, 1, 0, n, [0] * n)
        assert (result == sdk.COMM_SUCCESS) == ok
        assert (len(c_write("write", 1, 0, bytes(n))) == n + 7) == ok
    # 48 servos of goal + speed fit in one SYNC_WRITE, 49 do not.
    for n, ok in [(48, True), (49, False)]:
        port = CapturePort()
        group = sdk.GroupSyncWrite(port, PH, 30, 4)
        for i in range(n):
            group.addParam(i, [0, 0, 0, 0])
        assert (group.txPacket() == sdk.COMM_SUCCESS) == ok
        assert (len(c_goal_speed(range(n), [0] * n, [0] * n)) > 0) == ok


def test_invalid_arguments_give_zero():
    assert c_build("ping", 255) == b""
    assert c_build("read", 0xFE, 0, 1) == b""        # broadcast READ is never answered
    assert c_build("read", 1, 0, 0) == b""
    assert c_build("read", 1, 0, 245) == b""         # its reply would exceed 250 bytes
    assert c_build("reset", 0xFE) == b""             # broadcast RESET is not allowed
    assert c_write("write", 1, 0, b"") == b""
    assert c_write("write", 255, 0, b"\x01") == b""
    assert c_sync(30, 4, [], b"") == b""
    assert c_sync(30, 0, [1], b"") == b""
    assert c_sync(30, 1, [0xFE], b"\x00") == b""     # entries must name servos
    assert c_goal_speed([1], [1024], [0]) == b""
    assert c_goal_speed([1], [0], [2048]) == b""
    ffi, lib = dxl()
    buf = ffi.new("uint8_t[16]")
    assert lib.dxl_build_ping(ffi.NULL, 16, 1) == 0
    assert lib.dxl_build_write(buf, 16, 1, 0, ffi.NULL, 1) == 0


@SETTINGS
@given(id_=servo_ids, addr=u8, data=st.binary(min_size=1, max_size=40), short=st.integers(1, 6))
def test_too_small_buffer_gives_zero_and_writes_nothing(id_, addr, data, short):
    ffi, lib = dxl()
    ptr, n = c_bytes(data)
    need = n + 7
    buf = ffi.new("uint8_t[]", [0x5A] * need)
    assert lib.dxl_build_write(buf, need - short, id_, addr, ptr, n) == 0
    assert bytes(buf) == b"\x5a" * need
    assert lib.dxl_build_write(buf, need, id_, addr, ptr, n) == need


# ----------------------------------------------------------------- parser

def valid_status(max_params=26):
    return st.builds(status, servo_ids, st.integers(0, 0x7F), st.binary(max_size=max_params))


def no_inner_header(pkt: bytes) -> bool:
    """No FF FF after the packet's own header: nothing inside it can look like a packet."""
    return b"\xff\xff" not in pkt[2:]


def sdk_rx(stream: bytes):
    port = CapturePort(stream)
    return PH.rxPacket(port)


@SETTINGS
@given(pkt=valid_status(max_params=58))
def test_every_valid_status_parses_like_the_sdk(pkt):
    rx, result = sdk_rx(pkt)
    assert result == sdk.COMM_SUCCESS and bytes(rx) == pkt
    p = Parser(size=64)
    assert p.feed(pkt)[-1] == p.lib.DXL_PARSE_COMPLETE
    assert p.packet() == (pkt[2], pkt[4], pkt[5:-1])


@pytest.mark.parametrize("garbage", [
    "FF",                  # a third FF before the ID
    "FF FF FE 02 00 FF",   # ID 0xFE: not a status
    "FF FF FF FF",
    "FF FF 01 FB 00",      # LEN > 250
    "FF FF 01 02 80 7C",   # error byte > 0x7F
    "00 FF 00 FF",
])
def test_resync_cases_agree_with_sdk(garbage):
    good = status(3, 0x20, b"\x12\x34")
    stream = bytes.fromhex(garbage) + good
    rx, result = sdk_rx(stream)
    assert result == sdk.COMM_SUCCESS and bytes(rx) == good
    p = Parser()
    results = p.feed(stream)
    assert results[-1] == p.lib.DXL_PARSE_COMPLETE
    assert results.count(p.lib.DXL_PARSE_COMPLETE) == 1
    assert p.packet() == (3, 0x20, b"\x12\x34")


def test_len_below_two_is_not_a_status():
    # LEN = N + 2 >= 2. The SDK accepts "FF FF 80 01 7E" (7E = ~(80 + 01) sits where its
    # checksum is expected); the firmware must not.
    rx, result = sdk_rx(bytes.fromhex("FF FF 80 01 7E 00"))
    assert result == sdk.COMM_SUCCESS and bytes(rx[:5]) == bytes.fromhex("FF FF 80 01 7E")
    p = Parser()
    results = p.feed(bytes.fromhex("FF FF 80 01 7E  FF FF 01 00 FE 00 00") + status(1, 0))
    assert results.count(p.lib.DXL_PARSE_COMPLETE) == 1
    assert results[-1] == p.lib.DXL_PARSE_COMPLETE and p.packet() == (1, 0, b"")


@SETTINGS
@given(garbage=st.binary(max_size=80), pkt=valid_status())
def test_valid_status_found_after_any_garbage(garbage, pkt):
    assume(no_inner_header(pkt))
    p = Parser(size=32)
    results = p.feed(garbage + pkt)
    assert results[-1] == p.lib.DXL_PARSE_COMPLETE
    assert p.packet() == (pkt[2], pkt[4], pkt[5:-1])
    assert p.guard_intact()


@SETTINGS
@given(pkts=st.lists(st.tuples(valid_status(), st.floats(0, 1)), min_size=1, max_size=4),
       last=valid_status())
def test_truncated_packets_do_not_swallow_the_next(pkts, last):
    assume(no_inner_header(last))
    stream = b"".join(pkt[:max(1, int(cut * (len(pkt) - 1)))] for pkt, cut in pkts)
    p = Parser(size=32)
    results = p.feed(stream + last)
    assert results[-1] == p.lib.DXL_PARSE_COMPLETE
    assert p.packet() == (last[2], last[4], last[5:-1])


@SETTINGS
@given(pkt=valid_status(), where=st.integers(2, 100), flip=st.integers(1, 255))
def test_corrupted_packet_is_rejected(pkt, where, flip):
    where = 2 + where % (len(pkt) - 2)             # ID, LEN, ERR, a parameter or the checksum
    assume(where != 3)                             # a changed LEN is a different packet
    bad = bytearray(pkt)
    bad[where] ^= flip
    assume(bad[2] <= 0xFD and bad[4] <= 0x7F and no_inner_header(bytes(bad)))
    p = Parser(size=32)
    results = p.feed(bad)
    assert p.lib.DXL_PARSE_COMPLETE not in results
    assert results[-1] == p.lib.DXL_PARSE_BAD_CHECKSUM
    # and the parser is ready for the next packet
    assert p.feed(pkt)[-1] == p.lib.DXL_PARSE_COMPLETE


# Bytes that make header-like runs common: FF, small IDs and LENs, the limits 7F/80, FD/FE.
edgy_bytes = st.one_of(st.sampled_from([0xFF, 0xFF, 0xFF, 0, 1, 2, 3, 4, 0x7F, 0x80, 0xFD, 0xFE]), u8)


@settings(SETTINGS, max_examples=300)
@given(chunks=st.lists(st.one_of(st.lists(edgy_bytes, max_size=40).map(bytes),
                                 valid_status(max_params=8)), max_size=12),
       size=st.integers(6, 12))
def test_random_streams_stay_in_bounds(chunks, size):
    # Random bytes with real packets mixed in; a tiny buffer (0..6 parameters).
    data = b"".join(chunks)
    p = Parser(size=size)
    ffi = p.ffi
    start = int(ffi.cast("uintptr_t", p.mem))
    results = set(range(4))
    for i, b in enumerate(data):
        r = p.lib.dxl_parse_byte(p.p, b)
        assert r in results
        assert p.p.len <= size and p.guard_intact()
        if r == p.lib.DXL_PARSE_COMPLETE:
            # Whatever is reported is a well-formed status packet made of the last bytes fed.
            n = p.p.n_params
            offset = int(ffi.cast("uintptr_t", p.p.params)) - start
            assert 5 <= offset and offset + n + 1 <= size
            assert data[i + 1 - (n + 6):i + 1] == status(p.p.id, p.p.error, p.packet()[2])
            assert p.p.id <= 0xFD and p.p.error <= 0x7F


NEED, COMPLETE, BAD, TOO_LONG = 0, 1, 2, 3


def reference_parse(stream: bytes, size: int):
    """The resynchronising rules of dxl_protocol.h, applied by brute force to the whole
    stream: per byte, every start not yet discarded, newest first. Yields (result, packet)
    per byte. A good packet ending on the byte wins (the newest of them); else a bad
    checksum; else a header whose LEN just arrived announcing more than `size` bytes
    (still within the protocol's 250)."""
    base = 0                                      # starts before this were discarded
    for i in range(len(stream)):
        result, packet = NEED, None
        for s in range(i, base - 1, -1):
            b, n = stream[s:i + 1], i + 1 - s
            if b[0] != 0xFF or (n >= 2 and b[1] != 0xFF) or (n >= 3 and b[2] > 0xFD):
                continue
            if n < 4 or b[3] < 2:
                continue
            total = b[3] + 4
            if total > size:
                if n == 4 and total <= 254 and result == NEED:
                    result = TOO_LONG
                continue
            if n < 5 or b[4] > 0x7F or n != total:
                continue
            if ~sum(b[2:-1]) & 0xFF == b[-1]:
                result, packet, base = COMPLETE, (b[2], b[4], bytes(b[5:-1])), s + 1
                break
            result = BAD
        yield result, packet


def overlapping_packets():
    """Streams where packets start inside packets: good, truncated, corrupted and too-long
    packets, headers cut short, and edgy bytes, in any order."""
    def cut(pkt, k):
        return pkt[:max(1, k % len(pkt))]

    def corrupt(pkt, k):
        b = bytearray(pkt)
        b[-1] ^= 1 + k % 255
        return bytes(b)

    piece = st.one_of(
        valid_status(max_params=12),
        st.builds(cut, valid_status(max_params=12), u8),
        st.builds(corrupt, valid_status(max_params=12), u8),
        st.builds(lambda i, n: bytes([0xFF, 0xFF, i, n]), st.integers(0, 0xFD), st.integers(2, 60)),
        st.lists(edgy_bytes, max_size=6).map(bytes),
    )
    return st.lists(piece, max_size=10).map(b"".join)


@settings(SETTINGS, max_examples=400)
@given(stream=overlapping_packets(), size=st.integers(6, 24))
def test_every_byte_does_what_the_written_rules_say(stream, size):
    Parser(size=size).follow(stream, reference_parse(stream, size))


def test_newest_header_wins_when_two_packets_end_together():
    good = status(7, 0, b"\x10\x02")
    # A fake header whose packet takes `good` but its last byte as parameters and that
    # last byte as its checksum; its ID is chosen so that the checksum is right.
    length = len(good) + 1
    id_ = next(i for i in range(0xFE) if ~(i + length + sum(good[:-1])) & 0xFF == good[-1])
    stream = bytes([0xFF, 0xFF, id_, length, 0]) + good
    assert stream[-1] == ~sum(stream[2:-1]) & 0xFF     # both are valid and end together
    p = Parser()
    assert p.feed(stream)[-1] == p.lib.DXL_PARSE_COMPLETE
    assert p.packet() == (7, 0, b"\x10\x02")


def test_reported_packet_discards_what_came_before():
    good = status(7, 0, b"\x10\x02")
    # A fake packet around `good`, completed correctly by three more bytes.
    fake = bytes([0xFF, 0xFF, 5, len(good) + 4, 0]) + good + bytes(2)
    fake += bytes([~sum(fake[2:]) & 0xFF])
    p = Parser()
    results = p.feed(fake)
    end = 5 + len(good)                                      # just after good's last byte
    assert results[end - 1] == p.lib.DXL_PARSE_COMPLETE
    assert p.lib.DXL_PARSE_COMPLETE not in results[end:]
    assert p.packet() == (7, 0, b"\x10\x02")


def test_too_long_is_reported_and_skipped():
    p = Parser(size=10)                            # room for 4 parameters
    long_pkt = status(1, 0, bytes(5))
    results = p.feed(long_pkt)
    assert results[3] == p.lib.DXL_PARSE_TOO_LONG  # at its LEN byte
    assert p.lib.DXL_PARSE_COMPLETE not in results
    assert p.feed(status(2, 0, bytes(4)))[-1] == p.lib.DXL_PARSE_COMPLETE
    assert p.packet() == (2, 0, bytes(4))
    assert p.guard_intact()


def test_reset_forgets_partial_packet():
    p = Parser()
    good = status(1, 0, b"\x07")
    p.feed(good[:4])
    p.lib.dxl_parser_reset(p.p)
    assert p.feed(good[4:]) == [0] * (len(good) - 4)
    assert p.feed(good)[-1] == p.lib.DXL_PARSE_COMPLETE


def test_back_to_back_packets():
    p = Parser(size=16)
    a, b = status(1, 0, b"\x01\x02"), status(2, 4, b"")
    results = p.feed(a + b)
    assert [i for i, r in enumerate(results) if r == p.lib.DXL_PARSE_COMPLETE] == [len(a) - 1, len(a + b) - 1]
    assert p.packet() == (2, 4, b"")


def test_parser_init_checks_its_buffer():
    ffi, lib = dxl()
    p = ffi.new("dxl_parser_t *")
    buf = ffi.new("uint8_t[8]")
    assert lib.dxl_parser_init(p, buf, 5) == -1
    assert lib.dxl_parser_init(p, ffi.NULL, 8) == -1
    assert lib.dxl_parser_init(p, buf, 6) == 0


@pytest.mark.parametrize("bit, field", [
    (sdk.protocol1_packet_handler.ERRBIT_VOLTAGE, "voltage"),
    (sdk.protocol1_packet_handler.ERRBIT_ANGLE, "angle_limit"),
    (sdk.protocol1_packet_handler.ERRBIT_OVERHEAT, "overheating"),
    (sdk.protocol1_packet_handler.ERRBIT_RANGE, "range"),
    (sdk.protocol1_packet_handler.ERRBIT_CHECKSUM, "checksum"),
    (sdk.protocol1_packet_handler.ERRBIT_OVERLOAD, "overload"),
    (sdk.protocol1_packet_handler.ERRBIT_INSTRUCTION, "instruction"),
])
def test_decode_error(bit, field):
    ffi, lib = dxl()
    fields = ["voltage", "angle_limit", "overheating", "range", "checksum", "overload", "instruction"]
    out = ffi.new("dxl_error_flags_t *")
    lib.dxl_decode_error(bit, out)
    assert {f: getattr(out, f) for f in fields} == {f: int(f == field) for f in fields}
    lib.dxl_decode_error(0x7F, out)
    assert all(getattr(out, f) == 1 for f in fields)


# ------------------------------------------------------------ target build

def test_compiles_for_the_target(tmp_path):
    from conftest import require_arm_toolchain
    require_arm_toolchain()
    cmd = ["arm-none-eabi-gcc", *cbuild.TARGET_FLAGS, f"-I{INC}", "-c", str(SRC),
           "-o", str(tmp_path / "dxl_protocol.o")]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
