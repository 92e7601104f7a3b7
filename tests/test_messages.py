"""LLCP message layouts: the generated C and the Python codec against ctypes' packed
little-endian C structs (what the MRS peer's compiler lays out), and each other."""
import ctypes
import math
import struct

import pytest
from hypothesis import given, settings, strategies as st

from uavarm import messages
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
