"""The simulated board's quiet passes: the main-loop passes in which nothing reaches the
simulation's side run in C (uavarm/build/csrc/host_loop.c), the servos' replies wait there
for their passes, and the bus is left alone until a packet is whole.

Oracle: the same board stepped pass by pass in Python (SimBoard.step), every servo byte
delivered and every reply byte taken at the pass it arrives. With a shaft trace the servos
move at every pass in both, so the two runs must agree byte for byte; without one the
servos' motion is integrated over longer intervals, which may move a shaft by a fraction of
a unit, and nothing else. The bus's rule (a reply can be started only by the last byte of a
packet) is checked against the Protocol 1.0 packet layout of the e-manual.
"""
from __future__ import annotations

import pytest

from simboard_tools import MODEL, make_board, split_packets
from uavarm.sim.ax12_sim import AX12, AX12Bus, INST_READ, packet
from uavarm.sim.board import Rocking

TARGET = dict(x=70.0, y=-20.0, z=-95.0)
ELSEWHERE = dict(x=60.0, y=40.0, z=-110.0)


def fly(board, run):
    """Power-up, engage under rocking, two set positions, a servo whose supply dips (its RAM
    reset), disable. Returns the application's whole state (app_t, as bytes) after each
    stretch: every timestamp the firmware took of a reply or a tick is in it."""
    states = []

    def advance(seconds):
        run(seconds)
        states.append(without_pointers(board.ffi, "app_t", bytes(board.ffi.buffer(board.app))))
    board.send("enable", on=1)
    advance(1.2)
    board.send("set_position", **TARGET)
    board.send("engage", on=1)
    for target in (TARGET, ELSEWHERE, TARGET):
        board.send("set_position", **target)
        advance(0.4)
    servo = board.bus.servo(MODEL.servos[1].id)
    servo.power_off()
    servo.power_on()                            # back with its RAM at the power-on values
    board.send("set_position", **TARGET)
    advance(0.5)
    board.send("enable", on=0)
    advance(0.2)
    return states


def pointer_spans(ffi, ctype, base: int = 0):
    """(offset, size) of every pointer in a C type, nested structs and arrays included."""
    t = ffi.typeof(ctype) if isinstance(ctype, str) else ctype
    if t.kind == "pointer":
        yield base, ffi.sizeof(t)
    elif t.kind == "struct":
        for _, f in t.fields:
            yield from pointer_spans(ffi, f.type, base + f.offset)
    elif t.kind == "array":
        for k in range(t.length):
            yield from pointer_spans(ffi, t.item, base + k * ffi.sizeof(t.item))


def without_pointers(ffi, ctype: str, data: bytes) -> bytes:
    """data with its pointers zeroed: they differ from one board's memory to another's."""
    out = bytearray(data)
    for offset, size in pointer_spans(ffi, ctype):
        out[offset:offset + size] = bytes(size)
    return bytes(out)


def pass_by_pass(board):
    def advance(seconds):
        for _ in range(round(seconds * 1e6 / board.poll_us)):
            board.step(board.poll_us)
    return advance


def boards(trace: bool):
    made = []
    for _ in range(2):
        board = make_board(motion=Rocking(0.15, 0.1, 0.7))
        if trace:
            board.shaft_trace = []
        made.append(board)
    return made


def test_with_a_shaft_trace_the_quiet_passes_are_the_pass_by_pass_run_byte_for_byte():
    quick, slow = boards(trace=True)
    assert fly(quick, quick.run) == fly(slow, pass_by_pass(slow))
    assert max(hb["servo_resets"] for hb in slow.heartbeats) == 1, "the run misses its brown-out"
    assert quick.now_us == slow.now_us
    assert bytes(quick.servo_tx) == bytes(slow.servo_tx)
    assert quick.servo_rx_bytes == slow.servo_rx_bytes
    assert bytes(quick.link_out) == bytes(slow.link_out)       # every heartbeat (NaN != NaN: as bytes)
    assert quick.heartbeat_times == slow.heartbeat_times
    assert quick.power_log == slow.power_log
    assert quick.shaft_trace == slow.shaft_trace
    assert len(quick.shaft_trace) == quick.now_us // quick.poll_us
    assert quick.app.ticks_run == slow.app.ticks_run


def test_without_a_trace_only_the_shafts_integration_differs():
    """The same packets (servo, instruction) in the same order, the same heartbeat times,
    the arm where the pass-by-pass run left it to within a unit."""
    quick, slow = boards(trace=False)
    fly(quick, quick.run)
    fly(slow, pass_by_pass(slow))

    def shape(board):
        return [(p[2], p[4]) for p in split_packets(bytes(board.servo_tx))]
    assert shape(quick) == shape(slow)
    assert quick.heartbeat_times == slow.heartbeat_times
    assert [hb["faults"] for hb in quick.heartbeats] == [hb["faults"] for hb in slow.heartbeats]
    for a, b in zip(quick.bus.servos, slow.bus.servos):
        assert a.position == pytest.approx(b.position, abs=1.0)


def read(id_: int) -> bytes:
    return packet(id_, INST_READ, bytes([36, 2]))     # Present Position, 2 bytes


def bus_of(n: int = 2) -> AX12Bus:
    return AX12Bus([AX12(i) for i in range(1, n + 1)])          # (both at the factory 1 Mbps)


def test_a_reply_can_start_only_at_a_packets_last_byte():
    """One packet on a quiet bus: the bus need not be looked at before its last byte, and
    the servo's reply starts a return delay after it. Two packets in one write: every byte
    is due (the bus does not split writes)."""
    bus = bus_of()
    byte = bus.byte_time
    one = read(1)
    bus.write(one)
    assert bus.next_due() == pytest.approx(len(one) * byte)
    assert bus.take_arrivals(float("inf")) == [], "nothing answers before a packet is whole"
    bus.run_until(bus.next_due())
    first = bus.take_arrivals(float("inf"))
    assert len(first) == len(packet(1, 0, b"\0\0"))
    assert first[0][0] == pytest.approx(len(one) * byte + bus.servo(1).return_delay + byte)
    assert bus.next_due() == float("inf")

    start = bus.time
    bus.write(read(1) + read(2))
    assert bus.next_due() == pytest.approx(start + byte)


def test_after_stray_bytes_every_byte_is_due():
    """A servo holding part of a packet can complete it at any byte: until the bus is quiet
    again, every byte counts."""
    bus = bus_of(1)
    bus.write(b"\xff\xff\x01")                    # a header and an id, cut off
    bus.run_until(bus.time + 3 * bus.byte_time)
    start = bus.time
    bus.write(read(1))
    assert bus.next_due() == pytest.approx(start + bus.byte_time)


def test_one_packet_is_what_the_servos_parser_completes_at_the_last_byte():
    """one_packet() against the parser itself: fed a packet byte by byte, receive() answers
    at the last byte only; a cut or doubled packet is not one."""
    pkt = read(1)
    assert AX12.one_packet(pkt) and not AX12.one_packet(pkt[:-1]) and not AX12.one_packet(pkt + pkt)
    servo = AX12(1)
    answers = [servo.receive(b, k * 1e-5) is not None for k, b in enumerate(pkt)]
    assert answers == [False] * (len(pkt) - 1) + [True]
