"""The board port's logic without the HAL (firmware_stm32/Board/Src/byte_ring.c,
cdc_link.c), built for the host with the project's strict flags: the servo-bus receive
ring and the USB CDC link queues that keep the port from ever blocking the tick.

Oracles: a Python FIFO (collections.deque) with the same capacity for the ring; for the
link, the bytes the application wrote against the bytes a fake USB stack was handed.
"""
from collections import deque

import pytest
from hypothesis import given, settings, strategies as st

from uavarm.build import cbuild, firmware

BOARD = firmware.FIRMWARE / "Board"


@pytest.fixture(scope="module")
def board_logic():
    sources = [firmware.FIRMWARE / p for p in firmware.source_lists()["BOARD_LOGIC_SOURCES"]]
    return cbuild.load("board_logic", sources, [BOARD / "Inc" / "byte_ring.h", BOARD / "Inc" / "cdc_link.h"],
                       include_dirs=[BOARD / "Inc", firmware.FIRMWARE / "App" / "Inc"])


def new_ring(ffi, lib, size, start=0):
    ring = ffi.new("byte_ring_t *")
    storage = ffi.new("uint8_t[]", size)
    assert lib.byte_ring_init(ring, storage, size)
    ring.head = ring.tail = start          # exercise the free-running indices' wrap
    return ring, storage


@pytest.mark.parametrize("size", [0, 1, 3, 100, 1000])
def test_ring_refuses_a_size_that_is_not_a_power_of_two(board_logic, size):
    ffi, lib = board_logic
    ring = ffi.new("byte_ring_t *")
    assert not lib.byte_ring_init(ring, ffi.new("uint8_t[]", max(size, 1)), size)


ops = st.lists(st.one_of(
    st.tuples(st.just("put"), st.binary(max_size=40)),
    st.tuples(st.just("put_all"), st.binary(max_size=40)),
    st.tuples(st.just("take"), st.integers(0, 40)),
    st.tuples(st.just("clear"), st.none()),
), max_size=60)


@settings(max_examples=300, deadline=None)
@given(ops=ops, start=st.sampled_from([0, 2**32 - 7, 2**31]))
def test_ring_is_a_bounded_fifo_that_counts_what_it_drops(board_logic, ops, start):
    ffi, lib = board_logic
    size = 32
    ring, _keep = new_ring(ffi, lib, size, start)
    model, dropped = deque(), 0
    for op, arg in ops:
        if op == "put":
            fits = min(len(arg), size - len(model))
            assert lib.byte_ring_put(ring, arg, len(arg)) == fits
            model.extend(arg[:fits])
            dropped += len(arg) - fits
        elif op == "put_all":
            ok = len(arg) <= size - len(model)
            assert lib.byte_ring_put_all(ring, arg, len(arg)) == ok
            if ok:
                model.extend(arg)
        elif op == "take":
            out = ffi.new("uint8_t[]", 41)
            n = lib.byte_ring_take(ring, out, arg)
            expect = [model.popleft() for _ in range(min(arg, len(model)))]
            assert bytes(ffi.buffer(out, n)) == bytes(expect)
        else:
            lib.byte_ring_clear(ring)
            model.clear()
        assert lib.byte_ring_used(ring) == len(model)
        assert lib.byte_ring_free(ring) == size - len(model)
        assert ring.dropped == dropped


class FakeUsb:
    """The USB stack as cdc_link sees it: takes one transfer at a time."""

    def __init__(self, ffi, lib):
        self.ffi, self.lib = ffi, lib
        self.answer = lib.CDC_LINK_SENT
        self.transfers = []          # bytes handed over while answering SENT
        self.calls = 0
        self.link = ffi.new("cdc_link_t *")
        self.cb = ffi.callback("cdc_link_result_t(void *, uint8_t *, uint16_t)", self.transmit)
        lib.cdc_link_init(self.link, self.cb, ffi.NULL)

    def transmit(self, ctx, buf, length):
        self.calls += 1
        if self.answer == self.lib.CDC_LINK_SENT:
            self.transfers.append(bytes(self.ffi.buffer(buf, length)))
        return self.answer

    def write(self, data):
        return self.lib.cdc_link_write(self.link, data, len(data))

    def sent(self):
        return b"".join(self.transfers)


def test_link_sends_one_transfer_at_a_time_and_the_next_on_completion(board_logic):
    ffi, lib = board_logic
    usb = FakeUsb(ffi, lib)
    assert usb.write(b"b01AA")
    assert usb.transfers == [b"b01AA"]            # sent at once when the stack is idle
    assert usb.write(b"b01BB") and usb.write(b"b01CC")
    assert usb.transfers == [b"b01AA"]            # in flight: nothing more handed over
    lib.cdc_link_pump(usb.link)
    assert usb.calls == 1
    lib.cdc_link_on_transmit_done(usb.link)
    lib.cdc_link_pump(usb.link)
    assert usb.transfers == [b"b01AA", b"b01BBb01CC"]   # what queued meanwhile, in one transfer


def test_link_retries_when_the_stack_is_busy_or_not_connected(board_logic):
    ffi, lib = board_logic
    usb = FakeUsb(ffi, lib)
    for answer in (lib.CDC_LINK_BUSY, lib.CDC_LINK_FAIL):
        usb.answer = answer
        assert usb.write(b"frame")                # queued, not lost
        lib.cdc_link_pump(usb.link)
        assert usb.transfers == []
        usb.answer = lib.CDC_LINK_SENT
        lib.cdc_link_pump(usb.link)
        assert usb.transfers == [b"frame"]
        usb.transfers.clear()
        lib.cdc_link_on_transmit_done(usb.link)


def test_link_refuses_a_frame_that_does_not_fit_and_never_splits_one(board_logic):
    """No host reading: the queue fills; a heartbeat is then refused whole (the
    application counts it as dropped) instead of blocking or going out truncated."""
    ffi, lib = board_logic
    usb = FakeUsb(ffi, lib)
    usb.answer = lib.CDC_LINK_BUSY
    frame = bytes(range(83))                      # a heartbeat's LLCP frame length
    accepted = 0
    while usb.write(frame):
        accepted += 1
    # the queue plus the transfer waiting for the stack
    assert lib.CDC_LINK_TX_SIZE // len(frame) <= accepted <= \
        (lib.CDC_LINK_TX_SIZE + lib.CDC_LINK_TRANSFER_MAX) // len(frame)
    assert usb.link.frames_refused == 1
    usb.answer = lib.CDC_LINK_SENT
    for _ in range(100):
        lib.cdc_link_pump(usb.link)
        lib.cdc_link_on_transmit_done(usb.link)
    assert usb.sent() == frame * accepted
    assert all(len(t) <= lib.CDC_LINK_TRANSFER_MAX for t in usb.transfers)


def test_a_fresh_connection_drops_what_queued_while_nobody_listened(board_logic):
    ffi, lib = board_logic
    usb = FakeUsb(ffi, lib)
    usb.answer = lib.CDC_LINK_FAIL
    usb.write(b"stale1")
    usb.write(b"stale2")
    lib.cdc_link_on_connect(usb.link)             # USB interrupt: the host configured the port
    usb.answer = lib.CDC_LINK_SENT
    usb.write(b"fresh")
    assert usb.sent() == b"fresh"


def test_a_transfer_lost_to_a_bus_reset_does_not_block_the_link_forever(board_logic):
    ffi, lib = board_logic
    usb = FakeUsb(ffi, lib)
    usb.write(b"lost")                            # in flight, and the bus resets
    lib.cdc_link_on_connect(usb.link)
    usb.write(b"next")
    assert usb.transfers == [b"lost", b"next"]


@settings(max_examples=100, deadline=None)
@given(frames=st.lists(st.binary(min_size=1, max_size=120), max_size=40),
       answers=st.lists(st.sampled_from([0, 1, 2]), min_size=1, max_size=20))
def test_link_delivers_every_accepted_byte_in_order(board_logic, frames, answers):
    ffi, lib = board_logic
    usb = FakeUsb(ffi, lib)
    accepted = []
    for i, frame in enumerate(frames):
        usb.answer = answers[i % len(answers)]
        if usb.write(frame):
            accepted.append(frame)
        if i % 3 == 0:
            lib.cdc_link_on_transmit_done(usb.link)
    usb.answer = lib.CDC_LINK_SENT
    for _ in range(200):
        lib.cdc_link_on_transmit_done(usb.link)
        lib.cdc_link_pump(usb.link)
    assert usb.sent() == b"".join(accepted)


def test_link_receive_keeps_order_and_drops_overflow(board_logic):
    ffi, lib = board_logic
    usb = FakeUsb(ffi, lib)
    packet = bytes(range(64))
    for _ in range(lib.CDC_LINK_RX_SIZE // 64 + 2):          # two packets too many
        lib.cdc_link_on_receive(usb.link, packet, len(packet))
    out = ffi.new("uint8_t[]", 4096)
    n = lib.cdc_link_read(usb.link, out, 4096)
    assert bytes(ffi.buffer(out, n)) == packet * (lib.CDC_LINK_RX_SIZE // 64)
    assert usb.link.rx.dropped == 128


# ------------------------------------------------------------------ the servo set-up bridge's filter

@pytest.fixture(scope="module")
def bridge_lib():
    return cbuild.load("servo_bridge", [BOARD / "Src" / "servo_bridge.c"], [BOARD / "Inc" / "servo_bridge.h"],
                       include_dirs=[BOARD / "Inc", firmware.FIRMWARE / "App" / "Inc"])


def passed(ffi, lib, stream: bytes) -> list[bytes]:
    """The packets the filter lets through, fed stream byte by byte."""
    bridge = ffi.new("servo_bridge_t *")
    lib.servo_bridge_init(bridge)
    out = []
    for byte in stream:
        n = lib.servo_bridge_feed(bridge, byte)
        if n:
            out.append(bytes(ffi.buffer(bridge.packet, n)))
    return out


# Protocol 1.0 (DynamixelSDK's bytes), AX-12A control table: ID at 3, Baud Rate at 4
SET_UP = [("ping", 1), ("ping", 7), ("readTx", 1, 0, 5), ("write1ByteTxOnly", 1, 3, 2),
          ("write1ByteTxOnly", 2, 4, 9)]
NOT_SET_UP = [("write2ByteTxOnly", 1, 30, 512),          # goal position
              ("write1ByteTxOnly", 1, 24, 1),            # torque enable
              ("write2ByteTxOnly", 1, 6, 0),             # CW angle limit
              ("write1ByteTxOnly", 1, 5, 0),             # return delay
              ("write2ByteTxOnly", 1, 3, 0x0902),        # ID and Baud Rate in one two-byte write
              ("write1ByteTxOnly", 254, 3, 5),           # a broadcast write of the ID
              ("regWriteTxOnly", 1, 3, 1, [2]), ("action", 1), ("factoryReset", 1),
              ("syncWriteTxOnly", 30, 2, bytes([1, 0, 2]), 3)]


def test_the_bridge_passes_the_set_up_packets_and_nothing_else(bridge_lib):
    """Each of DynamixelSDK's packets alone, then all in one stream with garbage and a
    corrupted copy of an allowed packet between them: exactly the set-up ones pass, whole."""
    from sdk_capture import sdk_packet
    ffi, lib = bridge_lib
    good = [sdk_packet(*call) for call in SET_UP]
    bad = [sdk_packet(*call) for call in NOT_SET_UP]
    for packet in good:
        assert passed(ffi, lib, packet) == [packet]
    for packet, call in zip(bad, NOT_SET_UP):
        assert passed(ffi, lib, packet) == [], call
    corrupted = good[3][:-1] + bytes([good[3][-1] ^ 1])
    stream = b"\x00\xff\x42".join(bad + [corrupted] + good + bad)
    assert passed(ffi, lib, stream) == good


@settings(max_examples=300, deadline=None)
@given(stream=st.lists(st.one_of(st.binary(max_size=12), st.sampled_from([b"\xff\xff", b"\xff\xff\x01\x04\x03"])),
                       max_size=40).map(b"".join))
def test_whatever_the_host_sends_only_a_set_up_packet_passes(bridge_lib, stream):
    """The filter's promise (servo_bridge.h), checked on each packet it passes: Protocol 1.0
    framing with a right checksum, and a PING, a READ of one servo, or a one-byte WRITE of
    one servo's ID (3) or Baud Rate (4)."""
    ffi, lib = bridge_lib
    for p in passed(ffi, lib, stream):
        assert p[:2] == b"\xff\xff" and len(p) == p[3] + 4 and (~sum(p[2:-1]) & 0xFF) == p[-1]
        servo, inst, params = p[2], p[4], p[5:-1]
        assert (inst == 1 and not params) or (servo != 254 and inst == 2 and len(params) == 2) or \
            (servo != 254 and inst == 3 and len(params) == 2 and params[0] in (3, 4))
