"""LLCP message layouts: the generated C and the Python codec against ctypes' packed
little-endian C structs (what the MRS peer's compiler lays out), and each other."""
import ctypes
import math
import struct

import pytest
from hypothesis import given, settings, strategies as st

from uavarm.link import messages
from uavarm.model.messages import MESSAGES, TX_MAX_PAYLOAD

CTYPES = {"u8": ctypes.c_uint8, "u16": ctypes.c_uint16, "i16": ctypes.c_int16, "u32": ctypes.c_uint32,
          "i32": ctypes.c_int32, "f32": ctypes.c_float}
RANGES = {"u8": st.integers(0, 255), "u16": st.integers(0, 65535), "i16": st.integers(-2**15, 2**15 - 1),
          "u32": st.integers(0, 2**32 - 1),
          "i32": st.integers(-2**31, 2**31 - 1),
          "f32": st.floats(width=32, allow_nan=False)}


def packed_struct(msg):
    class S(ctypes.LittleEndianStructure):
        _pack_ = 1
        _fields_ = [("id", ctypes.c_uint8)] + [(n, CTYPES[t]) for n, t in msg.fields]
    return S


def c_pack(gen, msg, values):
    ffi, lib = gen
    m = ffi.new(f"msg_{msg.name}_t *", values)
    buf = ffi.new("uint8_t[]", 200)
    n = getattr(lib, f"msg_{msg.name}_pack")(m, buf, 200)
    return bytes(ffi.buffer(buf, n))


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_layout_matches_packed_c_struct(gen, msg, data):
    values = {n: data.draw(RANGES[t]) for n, t in msg.fields}
    want = bytes(packed_struct(msg)(msg.id, **values))
    assert messages.encode(msg.name, **values) == want
    assert c_pack(gen, msg, values) == want
    name, decoded = messages.decode(want)
    assert name == msg.name
    ffi, lib = gen
    out = ffi.new(f"msg_{msg.name}_t *")
    assert getattr(lib, f"msg_{msg.name}_unpack")(want, len(want), out)
    for n, t in msg.fields:
        if t == "f32":
            assert struct.pack("<f", getattr(out, n)) == struct.pack("<f", values[n])
            assert struct.pack("<f", decoded[n]) == struct.pack("<f", values[n])
        else:
            assert getattr(out, n) == values[n] == decoded[n]


def test_set_position_bytes_by_hand():
    """x = 1.0 is 0x3F800000, little-endian; y = -2.0 is 0xC0000000."""
    payload = messages.encode("set_position", x=1.0, y=-2.0, z=0.0)
    assert payload == bytes([0x12, 0, 0, 0x80, 0x3F, 0, 0, 0, 0xC0, 0, 0, 0, 0])


def test_imu_raw_bytes_by_hand():
    """Signed 16-bit counts little-endian on the wire: -2 is FE FF, 16384 is 00 40."""
    payload = messages.encode("imu_raw", seq=1, stamp_us=0x01020304, ax=-2, ay=16384, az=0, temperature=-1,
                              gx=1, gy=-32768, gz=32767, fresh=1)
    assert payload == bytes([0x21, 1, 0, 4, 3, 2, 1, 0xFE, 0xFF, 0, 0x40, 0, 0, 0xFF, 0xFF, 1, 0,
                             0, 0x80, 0xFF, 0x7F, 1])


def test_expected_lengths_and_unknown_ids(gen):
    ffi, lib = gen
    sizes = {m.id: m.size for m in MESSAGES}
    for i in range(256):
        assert lib.msg_expected_len(i) == sizes.get(i, -1)


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: m.name)
def test_unpack_refuses_wrong_length_or_id(gen, msg):
    ffi, lib = gen
    good = bytes(packed_struct(msg)(msg.id))
    out = ffi.new(f"msg_{msg.name}_t *")
    unpack = getattr(lib, f"msg_{msg.name}_unpack")
    assert unpack(good, len(good), out)
    assert not unpack(good + b"\0", len(good) + 1, out)
    assert not unpack(good[:-1], len(good) - 1, out)
    assert not unpack(bytes([msg.id ^ 0x80]) + good[1:], len(good), out)
    with pytest.raises(messages.MessageError):
        messages.decode(good[:-1])
    assert c_pack(gen, msg, {}) == good
    ffi2 = ffi.new("uint8_t[]", msg.size - 1)
    assert getattr(lib, f"msg_{msg.name}_pack")(ffi.new(f"msg_{msg.name}_t *"), ffi2, msg.size - 1) == 0


def test_device_messages_fit_the_ros_peer():
    for msg in MESSAGES:
        if msg.direction == "to_drone":
            assert msg.size <= TX_MAX_PAYLOAD


def test_codec_errors_are_clear():
    with pytest.raises(messages.MessageError, match="unknown message"):
        messages.encode("fly", on=1)
    with pytest.raises(messages.MessageError, match="needs fields"):
        messages.encode("set_position", x=1.0)
    with pytest.raises(messages.MessageError, match="unknown message id"):
        messages.decode(b"\x99")
    assert math.isnan(messages.decode(messages.encode("set_position", x=math.nan, y=0.0, z=0.0))[1]["x"])


HEARTBEAT_BY_HAND = bytes([
    0x20,                               # id: heartbeat
    0x02, 0x01,                         # seq 0x0102, little-endian
    0x06, 0x05, 0x04, 0x03,             # uptime_ms 0x03040506
    0x01,                               # enabled
    0x00,                               # engaged
    0x01,                               # unreachable
    0x05,                               # state: holding
    0x07,                               # refusal: not_finite
    0x01, 0x0C,                         # faults 0x0C01: servo_timeout, servo_reset, timing
    0x04, 0x20, 0x40,                   # servo1..3_error: overheating, overload, instruction
    0x00, 0x00, 0x80, 0x3F,             # set_x 1.0 (0x3F800000)
    0x00, 0x00, 0x00, 0xC0,             # set_y -2.0 (0xC0000000)
    0x00, 0x00, 0xF0, 0xC2,             # set_z -120.0 (0xC2F00000)
    0x00, 0x00, 0x00, 0x3F,             # q1 0.5 (0x3F000000)
    0x00, 0x00, 0x80, 0xBE,             # q2 -0.25 (0xBE800000)
    0x00, 0x00, 0xC8, 0x42,             # q3 100.0 (0x42C80000)
    0x11, 0x10,                         # link_frames_ok 0x1011
    0x13, 0x12,                         # link_errors 0x1213
    0x15, 0x14,                         # link_echoes 0x1415
    0x17, 0x16,                         # servo_timeouts 0x1617
    0x19, 0x18,                         # servo_resets 0x1819
    0x1B, 0x1A,                         # ticks_late 0x1A1B
    0x1D, 0x1C,                         # ticks_missed 0x1C1D
    0x03,                               # bus_state: running
    0x02,                               # reset_cause: brown_out
    0x03,                               # last_fault: exception 3, HardFault
    0x00, 0x03, 0x00, 0x00,             # firmware 0x000300
    0x3E, 0xD4, 0xED, 0xBE,             # model 0xBEEDD43E
    0x5F, 0x2A, 0x05, 0x04,             # servo1: 9.5 V, 42 deg C, load 0x0405
    0x60, 0x2B, 0x06, 0x05,             # servo2: 9.6 V, 43 deg C, load 0x0506
    0x61, 0x2C, 0x07, 0x06,             # servo3: 9.7 V, 44 deg C, load 0x0607
    0x05,                               # lagging_joints: joints 1 and 3
    0x06,                               # estimate_sources: the drone's attitude and velocity
    0x00, 0x00, 0x00, 0x3F,             # p1 0.5 (float32 0x3F000000)
    0x00, 0x00, 0x00, 0xC0,             # p2 -2.0 (0xC0000000)
    0x00, 0x00, 0x80, 0x3F,             # p3 1.0 (0x3F800000)
])
HEARTBEAT_VALUES = dict(
    seq=0x0102, uptime_ms=0x03040506, enabled=1, engaged=0, unreachable=1, state=5, refusal=7, faults=0x0C01,
    servo1_error=0x04, servo2_error=0x20, servo3_error=0x40, set_x=1.0, set_y=-2.0, set_z=-120.0,
    q1=0.5, q2=-0.25, q3=100.0, link_frames_ok=0x1011, link_errors=0x1213, link_echoes=0x1415,
    servo_timeouts=0x1617, servo_resets=0x1819, ticks_late=0x1A1B, ticks_missed=0x1C1D, bus_state=3,
    reset_cause=2, last_fault=3, firmware=0x000300, model=0xBEEDD43E,
    servo1_voltage=95, servo1_temperature=42, servo1_load=0x0405,
    servo2_voltage=96, servo2_temperature=43, servo2_load=0x0506,
    servo3_voltage=97, servo3_temperature=44, servo3_load=0x0607, lagging_joints=0x05,
    estimate_sources=0x06, p1=0.5, p2=-2.0, p3=1.0)


def test_heartbeat_bytes_by_hand(gen):
    """The heartbeat laid out field by field by hand (id 0x20, then each field packed
    little-endian in the documented order, 92 bytes): the C packs exactly these bytes, the C
    and the Python codec read them back as the values, the Python codec writes them."""
    ffi, lib = gen
    assert len(HEARTBEAT_BY_HAND) == 92
    assert c_pack(gen, messages.BY_ID[0x20], HEARTBEAT_VALUES) == HEARTBEAT_BY_HAND
    assert messages.encode("heartbeat", **HEARTBEAT_VALUES) == HEARTBEAT_BY_HAND
    assert messages.decode(HEARTBEAT_BY_HAND) == ("heartbeat", HEARTBEAT_VALUES)
    out = ffi.new("msg_heartbeat_t *")
    assert lib.msg_heartbeat_unpack(HEARTBEAT_BY_HAND, len(HEARTBEAT_BY_HAND), out)
    assert {n: getattr(out, n) for n in HEARTBEAT_VALUES} == HEARTBEAT_VALUES
    assert not lib.msg_heartbeat_unpack(HEARTBEAT_BY_HAND[:-1], 91, out)
