"""LLCP framing: the firmware's C and the drone-side Python codec against the wire format.

The oracle is `ref_frame` below, written from the format as MRS's llcp_prepareMessage()
produces it (the link to the drone): 'b', the length as two upper-case hex digits, every
payload byte as two hex digits, then the 8-bit sum of all characters before it as two hex digits.
The C receiver and the Python decoder are also run side by side on the same streams.
"""
from __future__ import annotations

import functools
import os
import random
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from conftest import require_arm_toolchain, skip_unless_ci
from uavarm.build import cbuild
from uavarm.link import llcp as pyllcp

ROOT = Path(__file__).resolve().parents[1]
INC = ROOT / "firmware_stm32" / "App" / "Inc"
SRC = ROOT / "firmware_stm32" / "App" / "Src" / "llcp.c"
HDR = INC / "llcp.h"

SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def ref_frame(payload: bytes) -> bytes:
    """The wire format, written out independently of both implementations."""
    text = "b" + "%02X" % len(payload) + "".join("%02X" % x for x in payload)
    return (text + "%02X" % (sum(text.encode("ascii")) % 256)).encode("ascii")


@functools.cache
def c_lib():
    return cbuild.load("llcp", [SRC], [HDR], include_dirs=[INC])


@functools.cache
def c_names():
    """C result value -> name shared with pyllcp.Result (also checks both have the same set)."""
    _, lib = c_lib()
    return {getattr(lib, "LLCP_RX_" + r.name): r.name for r in pyllcp.Result}


class CRx:
    """The C receiver with the same interface as the test's view of pyllcp.Decoder."""

    def __init__(self, gap=0, expected=None):
        self.ffi, self.lib = c_lib()
        self.rx = self.ffi.new("llcp_rx_t *")
        # The callback object must outlive the receiver that points at it.
        self._cb = self.ffi.callback("int(uint8_t)", expected) if expected else self.ffi.NULL
        self.lib.llcp_rx_init(self.rx, gap, self._cb)

    def byte(self, b: int, now: int = 0):
        r = c_names()[self.lib.llcp_rx_byte(self.rx, bytes([b]), now)]
        payload = bytes(self.ffi.buffer(self.rx.payload, self.rx.len)) if r == "FRAME" else None
        return r, payload

    def poll(self, now: int) -> str:
        return c_names()[self.lib.llcp_rx_poll(self.rx, now)]

    def counters(self):
        return {k: getattr(self.rx, k) for k in COUNTERS}


class PyRx:
    def __init__(self, gap=0, expected=None):
        # gap 0 means "never" in the C; the Python decoder says None.
        self.dec = pyllcp.Decoder(gap=gap or None, expected_len=expected)

    def byte(self, b: int, now: int = 0):
        r = self.dec.feed_byte(b, now)
        return r.name, (self.dec.payload if r is pyllcp.Result.FRAME else None)

    def poll(self, now: int) -> str:
        return self.dec.poll(now).name

    def counters(self):
        return {k: getattr(self.dec, k) for k in COUNTERS}


COUNTERS = ("frames_ok", "checksum_errors", "hex_errors", "length_errors", "unknown_ids", "timeouts", "restarts")
RECEIVERS = pytest.mark.parametrize("Rx", [CRx, PyRx], ids=["c", "py"])


def run(rx, data: bytes, times=None):
    """Feeds data byte by byte; returns [(index, result name, payload or None)]."""
    return [(i, *rx.byte(b, 0 if times is None else times[i])) for i, b in enumerate(data)]


def delivered(events):
    return [p for _, r, p in events if r == "FRAME"]


def assert_sound(data: bytes, events):
    """Every delivered payload is a genuine frame ending exactly at the byte that delivered it."""
    for i, r, p in events:
        if r == "FRAME":
            f = ref_frame(p)
            assert data[i + 1 - len(f): i + 1] == f, (data, i, p)


junk = st.binary(max_size=12).map(lambda b: b.replace(b"b", b""))  # anything but the start marker
payloads = st.binary(min_size=1, max_size=255)


# ---------------------------------------------------------------- the oracle and the encoders

def test_reference_against_hand_computed_frames():
    # b=0x62, '0'=0x30 ...: 0x62+0x30+0x31+0x30+0x31 = 0x124 -> 0x24
    assert ref_frame(b"\x01") == b"b010124"
    # 0x62+0x30+0x32+0x33+0x34+0x31+0x32 = 0x18E -> 0x8E
    assert ref_frame(b"\x34\x12") == b"b0234128E"
    assert pyllcp.encode(b"\x01") == b"b010124"


def c_encode(payload: bytes, cap=None, tx=False):
    """(return value, whole output buffer); the buffer starts filled with 'x'."""
    ffi, lib = c_lib()
    cap = len(ref_frame(payload)) if cap is None else cap
    out = ffi.new("char[]", cap)
    ffi.memmove(out, b"x" * cap, cap)
    src = ffi.new("uint8_t[]", list(payload) or [0])
    n = (lib.llcp_encode_tx if tx else lib.llcp_encode)(src, len(payload), out, cap)
    return n, ffi.buffer(out, cap)[:]


def test_c_and_python_encoders_match_reference_for_every_length():
    rnd = random.Random(1)
    for n in range(1, 256):
        for payload in (bytes(rnd.randrange(256) for _ in range(n)), bytes(range(256))[-n:], b"\xff" * n):
            frame = ref_frame(payload)
            assert c_encode(payload) == (len(frame), frame)
            assert pyllcp.encode(payload) == frame
            assert len(frame) == pyllcp.frame_size(n)


@SETTINGS
@given(payloads)
def test_encoders_match_reference(payload):
    frame = ref_frame(payload)
    assert c_encode(payload)[1] == frame == pyllcp.encode(payload)


def test_encoder_refuses_and_writes_nothing():
    ffi, lib = c_lib()
    assert lib.LLCP_FRAME_MAX == len(ref_frame(bytes(255)))
    assert c_encode(b"", cap=16) == (0, b"x" * 16)
    assert c_encode(bytes(256), cap=600) == (0, b"x" * 600)
    frame = ref_frame(b"\x07\x08")
    assert c_encode(b"\x07\x08", cap=len(frame) - 1) == (0, b"x" * (len(frame) - 1))
    assert c_encode(b"\x07\x08", cap=len(frame)) == (len(frame), frame)
    # Device -> drone: at most 127 bytes, the MRS ROS node mangles longer frames.
    assert lib.LLCP_TX_MAX_PAYLOAD == pyllcp.TX_MAX_PAYLOAD == 127
    assert c_encode(bytes(127), tx=True)[0] == len(ref_frame(bytes(127)))
    assert c_encode(bytes(128), tx=True, cap=600) == (0, b"x" * 600)
    assert c_encode(bytes(128))[0] == len(ref_frame(bytes(128)))
    for bad in (b"", bytes(256)):
        with pytest.raises(ValueError):
            pyllcp.encode(bad)
    with pytest.raises(ValueError):
        pyllcp.encode(bytes(128), max_len=pyllcp.TX_MAX_PAYLOAD)


# ---------------------------------------------------------------- receiving good streams

@RECEIVERS
@SETTINGS
@given(st.lists(st.tuples(junk, payloads), max_size=6), junk)
def test_receives_every_frame_with_junk_between(Rx, parts, tail):
    data = b"".join(j + ref_frame(p) for j, p in parts) + tail
    rx = Rx()
    events = run(rx, data)
    assert delivered(events) == [p for _, p in parts]
    assert {r for _, r, _ in events} <= {"NONE", "FRAME"}
    assert rx.counters() == dict.fromkeys(COUNTERS, 0) | {"frames_ok": len(parts)}


@SETTINGS
@given(st.lists(st.tuples(junk, payloads), max_size=5), st.data())
def test_python_decoder_is_independent_of_chunking(parts, data):
    stream = b"".join(j + ref_frame(p) for j, p in parts)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    dec = pyllcp.Decoder()
    got = [p for a, b in zip([0] + cuts, cuts + [len(stream)]) for p in dec.feed(stream[a:b], now=0.0)]
    assert got == [p for _, p in parts]


# pieces of a stream rich in what ends or breaks a frame: starts, non-hex characters, frames of
# length 0 and of other lengths than the id expects, bad checksums, cut frames
pieces = st.one_of(payloads.map(ref_frame), st.binary(max_size=6), st.sampled_from([b"b", b"b00", b"b0", b"\n"]),
                   payloads.map(lambda p: ref_frame(p)[:-1] + b"0"), st.text("0123456789ABCDEFb", max_size=8).map(str.encode),
                   st.tuples(payloads, st.integers(0, 600)).map(lambda t: ref_frame(t[0])[:t[1]]))


@SETTINGS
@given(st.lists(pieces, max_size=12), st.data())
def test_python_decoders_feed_is_feed_byte_at_a_time(parts, data):
    """feed() takes a run of characters at a time: the same frames and counters as feeding each
    byte, for any stream, cut anywhere, with gaps that drop partial frames."""
    stream = b"".join(parts)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    times = sorted(data.draw(st.lists(st.sampled_from([0.0, 0.05, 0.2, 0.3, 1.0]), min_size=len(cuts) + 1,
                                      max_size=len(cuts) + 1)))
    expected = lambda i: {0x2A: 3, 0x10: 1}.get(i, -1) if i < 0x80 else None
    bulk, bytewise = (pyllcp.Decoder(gap=0.1, expected_len=expected) for _ in range(2))
    got, want = [], []
    for (a, b), now in zip(zip([0] + cuts, cuts + [len(stream)]), times):
        got += bulk.feed(stream[a:b], now)
        for byte in stream[a:b]:
            if bytewise.feed_byte(byte, now) is pyllcp.Result.FRAME:
                want.append(bytewise.payload)
    assert got == want
    assert [getattr(bulk, k) for k in COUNTERS] == [getattr(bytewise, k) for k in COUNTERS]
    assert bulk._chars == bytewise._chars          # and the same frame part way


# ---------------------------------------------------------------- corrupted frames

SENTINEL = b"\x2a\x00\x99"


def check_corruption(Rx, payload: bytes, pos: int, value: int):
    """One character of a frame replaced, then a good frame: the good frame always arrives, and
    anything else delivered is a real frame inside the corrupted text that only a shortened
    length field or a new 'b' can have produced."""
    frame = bytearray(ref_frame(payload))
    frame[pos] = value
    data = bytes(frame) + b"\n" + ref_frame(SENTINEL)
    events = run(Rx(), data)
    assert_sound(data, events)
    got = delivered(events)
    assert got[-1:] == [SENTINEL] and events[-1][1] == "FRAME"
    size_field = bytes(frame[1:3])
    for p in got[:-1]:
        assert p != payload
        shortened = (pos in (1, 2) and all(ch in b"0123456789ABCDEF" for ch in size_field)
                     and 0 < int(size_field, 16) < len(payload))
        assert shortened or value == ord("b"), (bytes(frame), p)
    return got[:-1]


@RECEIVERS
def test_every_single_character_corruption_of_small_frames(Rx):
    by_chance = []
    for payload in (b"\x01", b"\xab\x00", b"\x10\xfe\x62\x00\x7f"):
        frame = ref_frame(payload)
        for pos in range(len(frame)):
            for value in range(256):
                if value != frame[pos]:
                    by_chance += check_corruption(Rx, payload, pos, value)
    # None of these happens to contain another valid frame; the next test shows the two ways
    # a corrupted frame can.
    assert not by_chance


@RECEIVERS
@SETTINGS
@given(st.binary(min_size=1, max_size=40), st.data())
def test_single_character_corruption(Rx, payload, data):
    frame = ref_frame(payload)
    pos = data.draw(st.integers(0, len(frame) - 1))
    value = data.draw(st.integers(0, 255).filter(lambda v: v != frame[pos]))
    check_corruption(Rx, payload, pos, value)


@RECEIVERS
def test_corruption_that_forms_a_valid_frame_by_chance(Rx):
    # Length 2 -> 1: the second payload byte is read as the checksum of "b01" + "34", and it is
    # exactly that checksum (0x62+0x30+0x31+0x33+0x34 = 0x12A -> 0x2A).
    payload = b"\x34\x2a"
    assert check_corruption(Rx, payload, 2, ord("1")) == [b"\x34"]
    # A 'b' written over a payload digit starts the valid frame "b010124" found in the payload.
    payload = b"\x00\x01\x01\x24"
    assert ref_frame(payload)[5:11] == b"010124"
    assert check_corruption(Rx, payload, 4, ord("b")) == [b"\x01"]


@RECEIVERS
def test_lower_case_hex_is_rejected(Rx):
    # MRS only emits upper-case digits; 'b' must stay the start marker.
    for bad in (b"b01ac" + b"00", b"b010124".replace(b"24", b"2a"), b"b0a" + b"00" * 10 + b"00"):
        rx = Rx()
        events = run(rx, bad + ref_frame(b"\x05"))
        assert delivered(events) == [b"\x05"]
        assert rx.counters()["hex_errors"] == 1


@RECEIVERS
def test_length_zero_is_ignored(Rx):
    # 0x62 + 0x30 + 0x30 = 0xC2
    for prefix in (b"b00C2", b"b00", b"b00\n"):
        rx = Rx()
        assert delivered(run(rx, prefix + ref_frame(b"\x11\x22"))) == [b"\x11\x22"]
        assert rx.counters() == dict.fromkeys(COUNTERS, 0) | {"frames_ok": 1}


@RECEIVERS
def test_truncated_frame_then_valid_frame(Rx):
    first, second = ref_frame(b"\x01\x02\x03"), ref_frame(b"\x04\x05")
    for k in range(1, len(first)):
        for gap in (b"", b"\r\n"):
            rx = Rx()
            data = first[:k] + gap + second
            events = run(rx, data)
            assert delivered(events) == [b"\x04\x05"]
            assert rx.counters()["restarts" if not gap else "hex_errors"] == 1
            if not gap:
                assert events[k][1] == "ERR_RESTART"


@RECEIVERS
def test_stray_b_inside_a_frame(Rx):
    frame, good = ref_frame(b"\x42\x43\x44\x45"), ref_frame(b"\x99")
    for k in range(1, len(frame)):
        data = frame[:k] + b"b" + frame[k:] + good
        events = run(Rx(), data)
        assert_sound(data, events)
        # k == 1 doubles the start marker ("bb04..."): the frame itself is intact.
        assert delivered(events) == ([b"\x42\x43\x44\x45"] if k == 1 else []) + [b"\x99"]


# ---------------------------------------------------------------- idle gap

@RECEIVERS
def test_idle_gap_drops_a_partial_frame(Rx):
    gap = 20
    frame = ref_frame(b"\x10\x20\x30")
    for k in range(1, len(frame)):
        for pause, kept in ((gap, True), (gap + 1, False)):
            rx = Rx(gap=gap)
            times = [1000] * k + [1000 + pause] * (len(frame) - k)
            events = run(rx, frame, times)
            assert delivered(events) == ([b"\x10\x20\x30"] if kept else [])
            assert rx.counters()["timeouts"] == (0 if kept else 1)
            # A whole frame after a long silence is fine: the gap only applies inside a frame.
            assert delivered(run(rx, frame, [10**6] * len(frame))) == [b"\x10\x20\x30"]


@RECEIVERS
def test_idle_gap_with_clock_wrap_and_poll(Rx):
    frame = ref_frame(b"\x01\x02")
    rx = Rx(gap=50)  # 0xFFFFFFF0 -> 5 is 21 ms later, not a gap
    assert delivered(run(rx, frame, [0xFFFFFFF0] * 4 + [5] * (len(frame) - 4))) == [b"\x01\x02"]
    rx = Rx(gap=50)
    run(rx, frame[:5], [0] * 5)
    assert rx.poll(50) == "NONE"
    assert rx.poll(51) == "ERR_TIMEOUT"
    assert rx.poll(52) == "NONE"  # already dropped
    assert delivered(run(rx, frame[5:], [52] * len(frame[5:]))) == []
    assert rx.counters()["timeouts"] == 1
    rx = Rx(gap=0)  # 0 = never
    assert delivered(run(rx, frame, [0, 10**9, 2 * 10**9] + [3 * 10**9] * (len(frame) - 3))) == [b"\x01\x02"]


# ---------------------------------------------------------------- length per message id

@RECEIVERS
def test_length_must_match_message_id(Rx):
    table = {0x10: 3, 0x20: 1}
    rx = Rx(expected=lambda i: table.get(i, -1))
    cases = [(b"\x10\x01\x02", "FRAME"), (b"\x10\x01", "ERR_LENGTH"), (b"\x10\x01\x02\x03", "ERR_LENGTH"),
             (b"\x20", "FRAME"), (b"\x33\x00", "ERR_UNKNOWN_ID")]
    for payload, want in cases:
        events = run(rx, ref_frame(payload))
        assert events[-1][1] == want
        assert [r for _, r, _ in events[:-1]] == ["NONE"] * (len(events) - 1)
    assert rx.counters() == dict.fromkeys(COUNTERS, 0) | {"frames_ok": 2, "length_errors": 2, "unknown_ids": 1}


# ---------------------------------------------------------------- arbitrary streams: C == Python

def piece():
    frames = payloads.map(ref_frame)
    corrupted = st.tuples(st.binary(min_size=1, max_size=30).map(ref_frame), st.integers(0), st.integers(0, 255)).map(
        lambda t: t[0][: t[1] % len(t[0])] + bytes([t[2]]) + t[0][t[1] % len(t[0]) + 1:])
    return st.one_of(frames, corrupted, frames.map(lambda f: f[: len(f) // 2]), junk, st.just(b"b"),
                     st.text("0123456789ABCDEFb", max_size=12).map(str.encode), st.binary(max_size=8))


@SETTINGS
@given(st.lists(st.tuples(piece(), st.integers(0, 40)), max_size=12))
def test_c_and_python_receivers_agree_on_any_stream(pieces):
    data = b"".join(p for p, _ in pieces)
    times, t = [], 0
    for p, dt in pieces:  # every piece arrives dt ms after the previous one
        t += dt
        times += [t] * len(p)
    table = {i: (i % 7) + 1 for i in range(0, 256, 3)}
    for expected in (None, lambda i: table.get(i, -1)):
        c, py = CRx(gap=25, expected=expected), PyRx(gap=25, expected=expected)
        ce, pe = run(c, data, times), run(py, data, times)
        assert ce == pe
        assert c.counters() == py.counters()
        assert_sound(data, ce)


def test_long_random_stream_never_misbehaves():
    rnd = random.Random(20240611)
    alphabet = b"0123456789ABCDEF" * 4 + b"b"
    chunks, sent = [], []
    while sum(map(len, chunks)) < 150_000:
        kind = rnd.random()
        if kind < 0.3:
            p = bytes(rnd.randrange(256) for _ in range(rnd.randint(1, 255)))
            sent.append(p)
            chunks.append(ref_frame(p))
        elif kind < 0.6:
            chunks.append(bytes(rnd.choice(alphabet) for _ in range(rnd.randint(1, 40))))
        else:
            chunks.append(bytes(rnd.randrange(256) for _ in range(rnd.randint(1, 40))))
    data = b"".join(chunks)
    c, py = CRx(), PyRx()
    ce = run(c, data)
    assert ce == run(py, data)
    assert_sound(data, ce)
    counts = c.counters()
    assert counts["frames_ok"] == len(delivered(ce)) > 0
    assert counts == py.counters()
    # Every good frame arrives whatever came before it ('b' restarts): sent is a subsequence.
    got = iter(delivered(ce))
    assert all(any(p == q for q in got) for p in sent)


# ---------------------------------------------------------------- memory safety and the target

ASAN_CHILD = r"""
import random, sys
from uavarm.build import cbuild
from uavarm.link import llcp as pyllcp
inc, src, hdr = sys.argv[1:4]
ffi, lib = cbuild.load("llcp_asan", [src], [hdr], include_dirs=[inc],
                       extra_flags=["-fsanitize=address,undefined", "-fno-sanitize-recover=all",
                                    "-fno-omit-frame-pointer"])
rnd = random.Random(7)
for n in range(1, 256):  # exact-size heap buffers: any overrun is reported
    src_buf = ffi.new("uint8_t[]", [rnd.randrange(256) for _ in range(n)])
    out = ffi.new("char[]", 5 + 2 * n)
    assert lib.llcp_encode(src_buf, n, out, 5 + 2 * n) == 5 + 2 * n
    assert lib.llcp_encode(src_buf, n, out, 4 + 2 * n) == 0
rx = ffi.new("llcp_rx_t *")
lib.llcp_rx_init(rx, 10, ffi.NULL)
alphabet = b"0123456789ABCDEF" * 8 + b"b"
t = 0
for i in range(300_000):
    c = rnd.choice(alphabet) if rnd.random() < 0.9 else rnd.randrange(256)
    t += rnd.choice((0, 0, 0, 1, 30))
    lib.llcp_rx_byte(rx, bytes([c]), t)
# Long frames only: 'b' + "FF" + 255 bytes, repeated, so every payload slot is written.
for k in range(50):
    for ch in b"bFF" + bytes(rnd.choice(alphabet[:16]) for _ in range(600)):
        lib.llcp_rx_byte(rx, bytes([ch]), t)
print("ok", rx.frames_ok, rx.checksum_errors, rx.hex_errors)
"""


def test_receiver_and_encoder_under_address_and_undefined_sanitizers():
    """ASan cannot be dlopen'ed into a running Python; preloading its runtime works."""
    cc = os.environ.get("CC", "cc")
    libs = [subprocess.run([cc, f"-print-file-name={n}"], capture_output=True, text=True).stdout.strip()
            for n in ("libasan.so", "libubsan.so")]
    if not all(os.path.isabs(p) and os.path.exists(p) for p in libs):
        skip_unless_ci("the compiler's ASan/UBSan runtime", "apt-get install gcc (libasan, libubsan)")
    env = dict(os.environ, LD_PRELOAD=":".join(libs), ASAN_OPTIONS="detect_leaks=0",
               PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, "-c", ASAN_CHILD, str(INC), str(SRC), str(HDR)],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert proc.returncode == 0 and proc.stdout.startswith("ok"), proc.stdout + proc.stderr
    assert "runtime error" not in proc.stderr and "Sanitizer" not in proc.stderr, proc.stderr


def test_compiles_for_the_target(tmp_path):
    require_arm_toolchain()
    gcc = shutil.which("arm-none-eabi-gcc")
    proc = subprocess.run([gcc, *cbuild.TARGET_FLAGS, f"-I{INC}", "-c", str(SRC), "-o", str(tmp_path / "llcp.o")],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_cffi_block_is_plain_declarations():
    block = cbuild.cdef_of([HDR])
    assert "#include" not in block and "static" not in block and "inline" not in block
