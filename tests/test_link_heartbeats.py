"""The drone side trusts only fresh heartbeats: the newest of a batch, none queued longer than
half a second, sequence gaps and board restarts counted; a command is judged only by the
heartbeats the board sent after it took it. Heartbeats are built from the message table
and framed by LLCP, as the board sends them; the port is a stand-in that hands out what is
queued."""
import math

import pytest

from uavarm.link import llcp, messages
from uavarm.link import ArmLink, CommandRefused, HeartbeatAge, LinkGarbled, LinkLate, LinkSilent
from uavarm.link.client import COMMAND_PING_SEQ, CONFIRM_S, KEEP_ALIVE_S, RestartWatch
from uavarm.model import config

PERIOD = config.load().heartbeat_period
HOUR_MS = 3_600_000
NOT_ENABLED, SERVO_FAULT = (1, 3)


def heartbeat(seq, uptime_ms, **given):
    fields = {name: 0 for name, _ in messages.BY_NAME["heartbeat"].fields}
    fields.update(seq=seq, uptime_ms=uptime_ms, **given)
    return llcp.encode(messages.encode("heartbeat", **fields))


class QueuedPort:
    """A serial port whose reads hand out the queued reads one at a time (b"": nothing yet)."""

    def __init__(self, *reads):
        self.reads = list(reads)
        self.written = []

    def read(self, n):
        return self.reads.pop(0)[:n] if self.reads else b""

    def write(self, data):
        self.written.append(data)
        return len(data)

    def flush(self):
        pass

    def close(self):
        pass


def test_refusal_codes_used_here_are_the_tables():
    names = [name for name, _ in messages.REFUSALS]
    assert (names.index("not_enabled"), names.index("servo_fault")) == (NOT_ENABLED, SERVO_FAULT)


def test_a_port_opened_after_an_hour_gives_the_newest_heartbeat_only():
    queued = b"".join(heartbeat(i, i * 300_000, engaged=int(i < 12)) for i in range(13))
    arm = ArmLink(QueuedPort(queued), silence=0.2)
    hb = arm.status()
    assert (hb["seq"], hb["uptime_ms"], hb["engaged"]) == (12, HOUR_MS, 0)
    assert arm.age.stale == 12
    assert [h["seq"] for h in arm.heartbeats] == [12]


def pong(seq):
    return llcp.encode(messages.encode("pong", seq=seq, stamp_us=0, arrived_us=0))


def written(port, name):
    """The fields of each `name` frame written to a stand-in port."""
    return [f for n, f in sent_frames(port) if n == name]


def test_an_engage_refused_now_is_not_confirmed_by_queued_engaged_heartbeats():
    old = b"".join(heartbeat(i, i * 300_000, enabled=1, engaged=1) for i in range(12))
    now = heartbeat(12, HOUR_MS, enabled=1, engaged=0, refusal=SERVO_FAULT, faults=1)
    later = heartbeat(13, HOUR_MS + 40, enabled=1, engaged=0, refusal=SERVO_FAULT, faults=1)
    arm = ArmLink(QueuedPort(old + now, b"", pong(COMMAND_PING_SEQ) + later), silence=0.2)
    with pytest.raises(CommandRefused, match="engage refused: .*servo does not answer.*servo_timeout"):
        arm.engage()


def test_a_command_is_judged_only_by_heartbeats_after_the_pong_that_follows_it():
    """A heartbeat the board sent before it took the command (here: no refusal, engaged) does
    not judge it, however late it is read: only those after the pong of the ping sent behind
    the command do. The board takes frames in order, so that pong says it took the command."""
    before = heartbeat(1, 1_000, enabled=1, engaged=1)
    after = heartbeat(2, 1_040, enabled=1, engaged=0, refusal=NOT_ENABLED)
    port = QueuedPort(before, b"", pong(COMMAND_PING_SEQ) + after)
    arm = ArmLink(port, clock=Clock(step=0.001))
    with pytest.raises(CommandRefused, match="torque refused"):
        arm.torque(False)
    assert [n for n, _ in sent_frames(port)] == ["torque", "ping"]
    assert written(port, "ping")[0]["seq"] == COMMAND_PING_SEQ


class PingingBoard(QueuedPort):
    """A board on `clock`: a heartbeat every 40 ms of it (engaged from `engaged_at` s), and a
    pong for each ping written, after the heartbeats sent before it, unless its seq is lost."""

    def __init__(self, clock, engaged_at, lose=()):
        super().__init__()
        self.clock, self.start, self.sent, self.out = clock, clock.t, 0, b""
        self.engaged_at, self.lose = engaged_at, set(lose)

    def _catch_up(self):
        while (self.sent + 1) * 0.040 <= self.clock.t - self.start:
            self.sent += 1
            self.out += heartbeat(self.sent, 40 * self.sent, enabled=1,
                                  engaged=int(self.sent * 0.040 >= self.engaged_at))

    def write(self, data):
        self._catch_up()
        for name, f in frames_of(data):
            if name == "ping" and f["seq"] not in self.lose:
                self.out += pong(f["seq"])
        return super().write(data)

    def read(self, n):
        self._catch_up()
        out, self.out = self.out, b""
        return out


def test_a_lost_pong_is_asked_again_and_a_command_shown_within_a_second_is_confirmed():
    """The first ping's answer never comes (lost to noise): after PING_AGAIN_S a second ping
    goes, its pong comes, and the heartbeats after it judge the engage, shown about 0.6 s of
    the board's time later (the arm was parking first)."""
    clock = Clock(step=0.002)
    board = PingingBoard(clock, engaged_at=0.9, lose={COMMAND_PING_SEQ})
    arm = ArmLink(board, clock=clock)
    arm.next_heartbeat()
    hb = arm.engage()
    assert hb["engaged"] == 1 and hb["seq"] == 23            # the first at or after 0.9 s: 23 x 40 ms
    assert [p["seq"] for p in written(board, "ping")] == [COMMAND_PING_SEQ, COMMAND_PING_SEQ + 1]


def test_a_command_not_shown_within_a_second_of_the_boards_time_is_refused():
    clock = Clock(step=0.002)
    board = PingingBoard(clock, engaged_at=math.inf)
    arm = ArmLink(board, clock=clock)
    with pytest.raises(CommandRefused, match="engage 1 not taken"):
        arm.engage()
    first = next(hb for hb in arm.heartbeats if hb["frame"] > 1)      # frame 1: the pong
    assert arm.heartbeats[-1]["uptime_ms"] - first["uptime_ms"] == 1_000 * CONFIRM_S


def test_a_heartbeat_delivered_late_is_dropped_and_counted():
    age = HeartbeatAge(stale_after=0.5)
    fresh = age.fresh([{"seq": 0, "uptime_ms": 10_000}], now=100.0)
    assert [hb["age"] for hb in fresh] == [0.0]
    # seq 1 sent at uptime 10.5 s but read 1.2 s later than the board's clock allows
    assert age.fresh([{"seq": 1, "uptime_ms": 10_500}], now=101.7) == []
    assert age.stale == 1
    # a heartbeat on time (30 ms of USB latency) is kept, aged by the latency less the drift allowance
    kept = age.fresh([{"seq": 2, "uptime_ms": 12_000}], now=102.03)
    assert [hb["seq"] for hb in kept] == [2]
    assert kept[0]["age"] == pytest.approx(0.03 - HeartbeatAge.DRIFT * 2.03, abs=1e-9)


def test_clocks_apart_by_1000_ppm_do_not_age_fresh_heartbeats():
    age = HeartbeatAge(stale_after=0.5)
    kept = 0
    for i in range(7200):                       # an hour; the board's clock runs 0.1 % slow
        uptime_s = i * 0.5
        kept += len(age.fresh([{"seq": i, "uptime_ms": round(uptime_s * 1000)}], now=uptime_s * 1.001))
    assert (kept, age.stale) == (7200, 0)


def test_sequence_gaps_and_restarts_are_counted_and_a_restart_starts_the_ages_over():
    age = HeartbeatAge(stale_after=0.5)
    age.fresh([{"seq": 0, "uptime_ms": 5_000}, {"seq": 1, "uptime_ms": 5_500}], now=50.5)
    age.fresh([{"seq": 4, "uptime_ms": 7_000}], now=52.0)
    assert (age.lost, age.restarts) == (2, 0)
    # the board restarted 10 s later: its uptime is back near zero, every heartbeat is fresh
    kept = age.fresh([{"seq": 0, "uptime_ms": 300}], now=62.3)
    assert (age.lost, age.restarts, len(kept)) == (2, 1, 1)


def test_sequence_and_uptime_wrap_are_not_restarts():
    age = HeartbeatAge(stale_after=0.5)
    age.fresh([{"seq": 0xFFFF, "uptime_ms": 0xFFFF_FF00}], now=10.0)
    kept = age.fresh([{"seq": 0, "uptime_ms": 0x0000_00F4}], now=10.5)
    assert (age.lost, age.restarts, len(kept)) == (0, 0, 1)


class Clock:
    """This computer's clock for a client under test: it moves `step` s at every reading, so
    a wait of N s takes N / step readings and no real time."""

    def __init__(self, step=0.01):
        self.t, self.step = 100.0, step

    def __call__(self):
        self.t += self.step
        return self.t


class SlowBoard(QueuedPort):
    """A port on a board whose clock runs at `rate` times ours (a simulated board behind
    real time): a heartbeat every period of its time, readable as soon as it is sent."""

    def __init__(self, clock, rate):
        super().__init__()
        self.clock, self.rate, self.start, self.sent = clock, rate, clock.t, 0

    def read(self, n):
        board_s = (self.clock.t - self.start) * self.rate
        if board_s < (self.sent + 1) * PERIOD:
            return b""
        self.sent += 1
        return heartbeat(self.sent, round(self.sent * PERIOD * 1000))


def test_a_board_whose_clock_runs_slow_is_not_late_while_the_port_is_read():
    """A board whose clock runs at 0.4 times this computer's (a simulated board behind real
    time on a busy machine), its port read every 20 ms: its clock says each heartbeat comes
    later than the one before, but none can have waited longer than since the last read:
    every one is fresh."""
    clock = Clock()
    arm = ArmLink(SlowBoard(clock, rate=0.4), clock=clock)
    seqs = [arm.next_heartbeat()["seq"] for _ in range(12)]
    assert seqs == list(range(1, 13)) and arm.age.stale == 0


def test_late_heartbeats_are_told_from_garbled_bytes_and_silence():
    """The same board's port read only every 0.8 s: its heartbeats, older than half a second
    by then, come but none is trusted; the client says so (LinkLate, how late), not "wrong baud
    or device" (bytes that are no frame) nor "no heartbeat" (nothing at all)."""
    clock = Clock(step=0.4)                  # two readings a poll
    arm = ArmLink(SlowBoard(clock, rate=0.4), clock=clock, silence=3.0)
    arm.next_heartbeat()
    with pytest.raises(LinkLate, match=r"heartbeat\(s\) in 3\.0 s but each too late to trust \(the last "
                                       r"[\d.]+ s old, more than 0.5 s\): this computer reads the port "
                                       r"too seldom"):
        for _ in range(10):
            arm.next_heartbeat()
    assert arm.age.stale >= 1
    with pytest.raises(LinkGarbled, match="no valid heartbeat.*wrong baud or device"):
        ArmLink(QueuedPort(b"hello, this is not LLCP " * 4), clock=Clock()).next_heartbeat()
    with pytest.raises(LinkSilent, match="no heartbeat for 1.5 s: is the board powered") as silent:
        ArmLink(QueuedPort(), clock=Clock()).next_heartbeat()
    assert type(silent.value) is LinkSilent


# ---------------------------------------------------------------- keep-alive and restarts

def frames_of(data: bytes) -> list[tuple[str, dict]]:
    """The messages in `data`, decoded as the board would."""
    decoder = llcp.Decoder(expected_len=lambda i: messages.BY_ID[i].size if i in messages.BY_ID else -1)
    return [messages.decode(p) for p in decoder.feed(data, 0.0)]


def sent_frames(port) -> list[tuple[str, dict]]:
    """The messages written to a stand-in port."""
    return frames_of(b"".join(port.written))


def test_kept_alive_the_polls_repeat_the_set_position_and_a_ping_is_none():
    """Within kept_alive every poll repeats the heartbeat's set position once nothing (a ping
    does not count: it keeps nothing alive on the board) was sent for KEEP_ALIVE_S; outside
    it, nothing is sent."""
    clock = Clock(step=0.001)
    port = QueuedPort(heartbeat(0, 1_000, enabled=1, set_x=60.0, set_y=20.0, set_z=-120.0))
    arm = ArmLink(port, clock=clock)
    for _ in range(500):
        arm.poll()
    assert port.written == []
    pings, end = 0, clock.t + 2.0
    with arm.kept_alive():
        while clock.t < end:                         # 2 s of this clock, a ping before each poll
            arm.ping(pings)
            pings += 1
            arm.poll()
    frames = sent_frames(port)
    keep = [f for name, f in frames if name == "set_position"]
    assert len([1 for name, _ in frames if name == "ping"]) == pings
    assert round(2.0 / KEEP_ALIVE_S) - 1 <= len(keep) <= round(2.0 / KEEP_ALIVE_S) + 1
    assert all((f["x"], f["y"], f["z"]) == (60.0, 20.0, -120.0) for f in keep)
    port.written.clear()
    arm.poll()
    assert arm.keep_alive_every is None and port.written == []


RESET = {name: k for k, (name, _) in enumerate(messages.RESET_CAUSES)}


def board_hb(uptime_ms, enabled=1, engaged=0, cause="power_on", last_fault=0):
    return {"uptime_ms": uptime_ms, "enabled": enabled, "engaged": engaged, "reset_cause": RESET[cause],
            "last_fault": last_fault}


@pytest.mark.parametrize("before, after, told", [
    (board_hb(60_000, engaged=1), board_hb(700, enabled=0, cause="watchdog"), "reset cause watchdog"),
    (board_hb(60_000), board_hb(700, enabled=0, cause="watchdog", last_fault=3), "watchdog after a HardFault"),
    (board_hb(60_000), board_hb(700, enabled=0, cause="window_watchdog"), "reset cause window_watchdog"),
    (board_hb(60_000), board_hb(700, enabled=0, cause="brown_out", last_fault=5), "brown_out after a BusFault"),
    (board_hb(60_000, enabled=0), board_hb(700, enabled=0, cause="watchdog"), None),      # not enabled
    (board_hb(60_000), board_hb(700, enabled=0, cause="pin"), None),                      # the reset button
    (board_hb(60_000), board_hb(700, enabled=0, cause="power_on"), None),
    (board_hb(60_000, cause="watchdog"), board_hb(60_500, cause="watchdog"), None),       # no restart
    (board_hb(0xFFFF_FF00, cause="watchdog"), board_hb(0xF4, cause="watchdog"), None),    # uptime wrap
])
def test_a_restart_while_enabled_after_a_watchdog_reset_or_a_fault_is_told(before, after, told):
    watch = RestartWatch()
    assert watch.check(before) is None
    text = watch.check(after)
    if told is None:
        assert text is None and watch.count == 0
    else:
        assert told in text and "while enabled" in text and "limp" in text and watch.count == 1
        assert ("it was engaged" in text) == bool(before["engaged"])
        assert watch.check(dict(after, uptime_ms=after["uptime_ms"] + 500)) is None     # told once
