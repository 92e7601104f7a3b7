"""Each timing figure of the fault table (docs/firmware.md) pinned by behaviour: the figures below are
written out by hand from docs/firmware.md, never read from the build, and each test fails if the
firmware's constant moves by one step either way (one tick for what is counted in ticks,
one microsecond or millisecond for what is timed in them).

| documented figure | test |
|---|---|
| the IMU: no usable sample for 5 ticks | test_imu_fault_after_five_stale_ticks |
| the IMU set up again every second | test_faulty_imu_is_set_up_again_after_one_second |
| link silent for 1 s | test_link_silence_parks_after_one_second |
| a partial LLCP frame idle 50 ms is dropped | test_partial_frame_is_dropped_after_the_frame_gap |
| servo tracking: more than 8 units off, 0.25 s | test_tracking_fault_after_a_quarter_second, test_tracking_counts_from_the_last_reading_that_tracked |
| ... moving toward it at less than a quarter of what its speed allows | test_tracking_needs_a_quarter_of_what_the_speed_allows |
| a servo read unanswered after one retry | test_servo_timeout_after_one_retry |
| tick late: no tick for 1.5 periods | test_late_tick_is_run_from_the_clock_at_one_and_a_half_periods |
| clock still for 3 ticks | test_stalled_clock_cuts_power_after_three_ticks |
| the watchdog fed only while healthy: a tick within two periods, the clock moving | test_the_watchdog_is_fed_only_while_ticks_run_and_the_clock_moves, test_a_stalled_clock_starves_the_watchdog |
| ticks_missed, a heartbeat every 0.5 s, the fault LED | the last three tests |
"""
import math

import pytest

from invariants import Invariants
from simboard_tools import FAULT, IDS, MODEL, PARK_UNITS, BusLog, ready, run_until, servo_c, speed_register
from test_fault_injection import TARGET, engaged_board, set_position
from uavarm.link import llcp, messages
from uavarm.sim import ax12_sim
from uavarm.sim.board import SimBoard, baud_register

# The documented figures, by hand.
TICK_US = 10_000                 # 100 Hz sample rate
IMU_STALE_TICKS = 5
IMU_RETRY_S = 1.0
LINK_SILENCE_US = 1_000_000
FRAME_GAP_MS = 50
TRACK_TOL_UNITS = 8
TRACK_FAULT_US = 250_000
SERVO_READ_RETRIES = 1
TICK_LATE_US = 15_000            # 1.5 periods
CLOCK_STALL_TICKS = 3
WATCHDOG_US = 250_000            # the independent watchdog's period (docs/board-project.md)


def step_until(board, cond, limit_s, dt_us=None):
    """Main-loop passes until cond(); the number of passes, or None."""
    for n in range(round(limit_s * 1e6 / (dt_us or board.poll_us))):
        if cond():
            return n
        board.step(dt_us or board.poll_us)
    return None


# ---------------------------------------------------------------- IMU

@pytest.mark.parametrize("lost", [IMU_STALE_TICKS - 1, IMU_STALE_TICKS])
def test_imu_fault_after_five_stale_ticks(lost):
    """The IMU stops answering for exactly `lost` tick reads while engaged: 4 leave the arm
    engaged with no imu fault at any moment; the 5th makes it an IMU fault and the arm
    disengages."""
    board, _ = engaged_board()
    errors = board.app.imu_errors
    board.hp.imu_present = False
    flagged = False
    while board.app.imu_errors < errors + lost:
        board.step(board.poll_us)
        flagged |= bool(board.lib.app_faults(board.app) & FAULT["imu"])
    board.hp.imu_present = True
    for _ in range(2 * TICK_US // board.poll_us):
        board.step(board.poll_us)
        flagged |= bool(board.lib.app_faults(board.app) & FAULT["imu"])
    assert flagged == (lost >= IMU_STALE_TICKS)
    assert bool(board.app.engaged) == (lost < IMU_STALE_TICKS)


def test_faulty_imu_is_set_up_again_after_one_second():
    """A brown-out leaves the MPU-6050 asleep: the chip is woken one second after the tick
    that made it an IMU fault (to the tick)."""
    board, _ = engaged_board()
    board.imu.power_on()
    assert step_until(board, lambda: board.lib.app_faults(board.app) & FAULT["imu"], 0.2) is not None
    t_fault = board.time
    assert step_until(board, lambda: not board.imu.asleep, 1.5) is not None
    assert abs((board.time - t_fault) - IMU_RETRY_S) <= 0.5 * TICK_US / 1e6


# ---------------------------------------------------------------- link

def test_link_silence_parks_after_one_second():
    """No frame after the last set_position: still engaged 1 s after it, disengaged with
    link_lost within one main-loop pass after that."""
    board, _ = engaged_board()
    set_position(board, TARGET)
    board.step(board.poll_us)
    last = board.app.last_frame_us
    assert step_until(board, lambda: not board.app.engaged, 1.5) is not None
    silent_us = (board.hp.now_us - last) & 0xFFFFFFFF
    assert LINK_SILENCE_US < silent_us <= LINK_SILENCE_US + board.poll_us
    assert board.app.link_lost


@pytest.mark.parametrize("idle_ms, kept", [(FRAME_GAP_MS, True), (FRAME_GAP_MS + 1, False)])
def test_partial_frame_is_dropped_after_the_frame_gap(idle_ms, kept):
    """Half a frame, then the rest `idle_ms` later (whole milliseconds of the board's clock):
    after 50 ms the frame is still taken, after 51 it is dropped (a timeout)."""
    board = SimBoard(MODEL)
    board.run(0.1)
    frame = llcp.encode(messages.encode("engage", on=0))
    ok, timeouts = board.app.link.frames_ok, board.app.link.timeouts
    board.send_bytes(frame[:3])
    board.run(idle_ms / 1000)
    board.send_bytes(frame[3:])
    board.run(0.002)
    assert (board.app.link.frames_ok - ok, board.app.link.timeouts - timeouts) == ((1, 0) if kept else (0, 1))


# ---------------------------------------------------------------- servos

def tracking_watch(app_lib):
    ffi, lib = app_lib
    track, bus = ffi.new("track_t *"), ffi.new("sbus_t *")
    lib.track_reset(track)
    return ffi, lib, track, bus


def reading(lib, track, bus, t_us, pos, goal=500, speed=100, servo=0):
    """One status reading of `servo` at t_us: the shaft at pos, goal and speed sent."""
    bus.goal[servo], bus.speed[servo] = goal, speed
    bus.servo[servo].present_position = pos
    bus.servo[servo].reads += 1
    bus.status_reads += 1
    bus.last_read = servo
    return lib.track_update(track, bus, t_us)


@pytest.fixture(scope="module")
def app_lib():
    from uavarm.build import firmware
    return firmware.default()


def test_tracking_fault_after_a_quarter_second(app_lib):
    """A shaft on its goal, then standing still 9 units from it: the fault stands once its
    readings have not tracked for 0.25 s since the last one that did, to the microsecond;
    8 units off is tracking."""
    off = 500 - TRACK_TOL_UNITS - 1
    _, lib, track, bus = tracking_watch(app_lib)
    assert not reading(lib, track, bus, 0, 500)
    assert not reading(lib, track, bus, TICK_US, 500)
    assert not reading(lib, track, bus, TICK_US + TRACK_FAULT_US - 1, off)
    assert reading(lib, track, bus, TICK_US + TRACK_FAULT_US, off)
    _, lib, track, bus = tracking_watch(app_lib)
    for k in range(60):
        assert not reading(lib, track, bus, k * TICK_US, 500 - TRACK_TOL_UNITS)


def test_tracking_fault_clears_after_a_quarter_second_of_tracking(app_lib):
    """A standing fault clears once the readings have tracked for 0.25 s in a row (counted
    from the last one that did not), to the microsecond."""
    off = 500 - TRACK_TOL_UNITS - 1
    _, lib, track, bus = tracking_watch(app_lib)
    for k in range(30):
        reading(lib, track, bus, k * TICK_US, off)
    t = 30 * TICK_US
    assert reading(lib, track, bus, t, off)                                   # standing, not tracking
    assert reading(lib, track, bus, t + TRACK_FAULT_US - 1, 500)              # tracking for 1 us short
    assert not reading(lib, track, bus, t + TRACK_FAULT_US, 500)              # cleared


def test_a_standing_fault_does_not_clear_on_a_slip_after_some_tracking(app_lib):
    """A standing fault, then 0.1 s of tracking and one reading off again: the fault still
    stands (it clears only after 0.25 s of tracking in a row), and 0.25 s of tracking later it
    clears."""
    off = 500 - TRACK_TOL_UNITS - 1
    _, lib, track, bus = tracking_watch(app_lib)
    for k in range(30):
        reading(lib, track, bus, k * TICK_US, off)
    t = 30 * TICK_US
    assert reading(lib, track, bus, t, off)
    for k in range(1, 11):                                                   # tracking for 0.1 s
        assert reading(lib, track, bus, t + k * TICK_US, 500)
    t += 11 * TICK_US
    assert reading(lib, track, bus, t, off)                                  # slipped: still standing
    assert reading(lib, track, bus, t + TRACK_FAULT_US - 1, 500)
    assert not reading(lib, track, bus, t + TRACK_FAULT_US, 500)


def test_a_shaft_coming_a_quarter_of_the_way_each_reading_tracks(app_lib):
    """A shaft always 12 units behind a goal that moves on, coming 3 units nearer (a quarter
    of the distance left; Moving Speed 600 allows 13.6 units a reading) at every reading:
    tracking, never a fault; 2 units (less than a quarter) is not."""
    for step, tracking in ((3, True), (2, False)):
        _, lib, track, bus = tracking_watch(app_lib)
        fault = False
        for k in range(60):
            fault |= bool(reading(lib, track, bus, k * TICK_US, 100 + step * k, goal=100 + step * (k - 1) + 12,
                                  speed=600))
        assert fault == (not tracking), step


def test_tracking_counts_only_readings_in_a_row(app_lib):
    """Not tracking for 0.2 s, one reading that tracks, 0.2 s more not tracking: no fault
    (0.25 s in a row were never reached)."""
    off, on = 500 - TRACK_TOL_UNITS - 1, 500
    _, lib, track, bus = tracking_watch(app_lib)
    poses = [on] + [off] * 20 + [on] + [off] * 20
    assert not any(reading(lib, track, bus, k * TICK_US, pos) for k, pos in enumerate(poses))


def test_tracking_counts_from_the_last_reading_that_tracked(app_lib):
    """A shaft that held its goal and slips 10 units away between two readings, then stays:
    the fault stands 0.25 s after the last reading on the goal, not later."""
    _, lib, track, bus = tracking_watch(app_lib)
    faults = [reading(lib, track, bus, k * TICK_US, 500 if k < 2 else 490) for k in range(30)]
    assert faults.index(True) == 1 + TRACK_FAULT_US // TICK_US


def test_readings_of_two_servos_in_one_look_are_both_judged(app_lib):
    """Two servos read between two looks (servo 1 standing 9 units off its goal, servo 0
    on its goal and read last): servo 1's readings count too, the fault stands after 0.25 s."""
    _, lib, track, bus = tracking_watch(app_lib)
    faults = []
    for k in range(40):
        for servo, pos in ((1, 500 - TRACK_TOL_UNITS - 1), (0, 500)):
            bus.goal[servo], bus.speed[servo] = 500, 100
            bus.servo[servo].present_position = pos
            bus.servo[servo].reads += 1
            bus.status_reads += 1
            bus.last_read = servo
        faults.append(lib.track_update(track, bus, k * TICK_US))
    assert faults.index(True) == TRACK_FAULT_US // TICK_US


def test_the_first_reading_is_not_judged(app_lib):
    """The first reading after a reset (1 s after it, 70 units below its goal) has nothing to
    be compared with: no fault, and the next ones, coming nearer at full speed, track."""
    _, lib, track, bus = tracking_watch(app_lib)
    for k in range(30):
        assert not reading(lib, track, bus, 1_000_000 + k * TICK_US, 20 + 2 * k, goal=90, speed=100)


# AX-12A e-Manual: Moving Speed 0.111 rpm per unit; 1023 position units over 300 deg
UNITS_PER_S_PER_SPEED = 0.111 * 360 / 60 * 1023 / 300


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("dt_us, tracking", [(17_547, True), (17_701, False)])
def test_tracking_needs_a_quarter_of_what_the_speed_allows(app_lib, dt_us, tracking, direction):
    """A shaft 60 units from its goal (below it or above it) comes 1 unit nearer at each
    reading, at Moving Speed 100: readings 17.547 ms apart, a quarter of what the speed allows is 0.996 units, so it
    tracks for ever; 17.701 ms apart it is 1.005 units, so it does not, and the fault stands
    after 0.25 s."""
    for dt, below in ((17_547, True), (17_701, False)):
        assert (0.25 * 100 * UNITS_PER_S_PER_SPEED * dt * 1e-6 < 1) == below
    _, lib, track, bus = tracking_watch(app_lib)
    fault = False
    for k in range(40):
        fault |= bool(reading(lib, track, bus, k * dt_us, 500 - direction * (60 - k), goal=500, speed=100))
    assert fault == (not tracking)


def test_a_shaft_further_behind_than_the_motion_allows_does_not_track(app_lib):
    """Further than MODEL_SERVO_GAP_MAX from its goal (twice the model file's response lag at
    the working speed, and a working step: servo_track.h), a shaft does not track however
    fast it comes nearer: the fault stands after 0.25 s of such readings; nearer, the same
    pace tracks."""
    working = speed_register(MODEL.working_speed_rpm) * UNITS_PER_S_PER_SPEED
    gap_max = math.ceil(working * (2 * MODEL.servo_response_lag + TICK_US * 1e-6))
    for gap, faulty in ((gap_max + 30, True), (gap_max - 30, False)):
        _, lib, track, bus = tracking_watch(app_lib)
        fault = False
        for k in range(27):   # 10 ms apart, 1 unit nearer each: 0.26 s
            fault |= bool(reading(lib, track, bus, k * TICK_US, 500 - (gap - k), goal=500, speed=100))
        assert fault == faulty, gap


class ShyServo(ax12_sim.AX12):
    """An AX-12A that leaves the next `skip` READ instructions unanswered."""
    skip = 0

    def _answers(self, inst):
        if inst == ax12_sim.INST_READ and self.skip > 0:
            self.skip -= 1
            return False
        return super()._answers(inst)


@pytest.mark.parametrize("missed", [SERVO_READ_RETRIES, SERVO_READ_RETRIES + 1])
def test_servo_timeout_after_one_retry(missed):
    """Servo 2 leaves `missed` reads in a row unanswered: one is made up by the retry (no
    servo_timeout at any moment); two make it a timeout."""
    servos = [(ShyServo if k == 1 else ax12_sim.AX12)(s.id, position=float(round(PARK_UNITS[k])),
                                                    table={"baud_rate": baud_register(MODEL.servo_baud)})
              for k, s in enumerate(MODEL.servos)]
    board = SimBoard(MODEL, servos=servos)
    inv = Invariants(board, BusLog(board))
    board.send("enable", on=1)
    assert inv.run_until(lambda: ready(board), 1.0) is not None
    board.bus.servo(IDS[1]).skip = missed
    failed = False
    for _ in range(round(0.2 * 1e6 / board.poll_us)):
        board.step(board.poll_us)
        failed |= bool(servo_c(board, 1).failed)
    assert board.bus.servo(IDS[1]).skip == 0
    assert failed == (missed > SERVO_READ_RETRIES)


class ShyStatusServo(ax12_sim.AX12):
    """An AX-12A that leaves the next `skip` status READs (from Moving Speed, register 32: the
    running reads, not the configuration's) unanswered."""
    skip = 0

    def _on_packet(self, pkt):
        if pkt[2] == self.id and pkt[4] == ax12_sim.INST_READ and pkt[5] == 32 and self.skip > 0:
            self.skip -= 1
            return None
        return super()._on_packet(pkt)


def test_the_first_reads_after_a_power_cycle_keep_their_retry():
    """Disabled and enabled again, each servo leaves its first status read unanswered: the
    retry makes up for it, as for any read (a retry count left over from before the power
    cut would not)."""
    servos = [ShyStatusServo(s.id, position=float(round(PARK_UNITS[k])), table={"baud_rate": baud_register(MODEL.servo_baud)})
              for k, s in enumerate(MODEL.servos)]
    board = SimBoard(MODEL, servos=servos)
    board.send("enable", on=1)
    assert run_until(board, lambda: ready(board), 1.0) is not None
    board.app.bus.read_attempt = SERVO_READ_RETRIES      # as a cut in the middle of a retry leaves it
    board.send("enable", on=0)
    board.run(0.1)
    for s in servos:
        s.skip = SERVO_READ_RETRIES
    board.send("enable", on=1)
    failed = False
    for _ in range(round(0.5 * 1e6 / board.poll_us)):
        board.step(board.poll_us)
        failed |= any(servo_c(board, k).failed for k in range(3))
    assert [s.skip for s in servos] == [0, 0, 0] and not failed


# ---------------------------------------------------------------- the tick and the clock

def test_late_tick_is_run_from_the_clock_at_one_and_a_half_periods():
    """The tick interrupt stops: each tick is then run from the clock at the first main-loop
    pass after 1.5 periods have passed since the last (main-loop passes 1 us apart near
    that moment, so one microsecond either way shows)."""
    board, _ = engaged_board()
    board.tick_interrupt = False
    runs = []
    for _ in range(3):
        last = board.app.last_tick_us
        since = lambda: (board.hp.now_us - last) & 0xFFFFFFFF     # noqa: E731
        while since() < TICK_LATE_US - 2 * board.poll_us:
            board.step(board.poll_us)
        assert board.app.last_tick_us == last
        assert step_until(board, lambda: board.app.last_tick_us != last, 0.001, dt_us=1) is not None
        runs.append((board.app.last_tick_us - last) & 0xFFFFFFFF)
    assert runs == [TICK_LATE_US + 1] * 3      # the watch saw 1.5 periods; the next pass ran it
    assert board.app.ticks_late >= 3


def test_stalled_clock_cuts_power_after_three_ticks():
    """The microsecond clock stops between two ticks: the first tick after sees it moved
    from the tick before; the next three see it still, and the third cuts the servo
    supply."""
    board, _ = engaged_board()
    board.step(TICK_US // 2)
    board.clock_frozen = True
    ticks = board.app.ticks_run
    assert step_until(board, lambda: not board.servo_power, 0.2) is not None
    assert board.app.ticks_run - ticks == 1 + CLOCK_STALL_TICKS


class Watchdog:
    """The board's main loop as main() runs it: the independent watchdog (its own clock, the
    simulated time here) fed after every pass in which app_healthy() says the loop is
    healthy; `starved` is the longest time it went unfed."""

    def __init__(self, board):
        self.board, self.fed_at, self.starved = board, board.now_us, 0

    def step(self, dt_us):
        self.board.step(dt_us)
        if self.board.lib.app_healthy(self.board.app):
            self.fed_at = self.board.now_us
        self.starved = max(self.starved, self.board.now_us - self.fed_at)

    def run(self, seconds):
        for _ in range(round(seconds * 1e6 / self.board.poll_us)):
            self.step(self.board.poll_us)


def test_the_watchdog_is_fed_only_while_ticks_run_and_the_clock_moves():
    """An engaged board is healthy at every main-loop pass for 2 s; then the loop's last tick
    is two periods old at the clock (the clock read after a tick moved on by hand, no pass
    run between): healthy one microsecond before, not at two periods."""
    board, _ = engaged_board()
    dog = Watchdog(board)
    dog.run(2.0)
    assert dog.starved <= board.poll_us
    last, now = board.app.last_tick_us, board.hp.now_us
    board.hp.now_us = (last + 2 * TICK_US - 1) & 0xFFFFFFFF
    assert board.lib.app_healthy(board.app)
    board.hp.now_us = (last + 2 * TICK_US) & 0xFFFFFFFF
    assert not board.lib.app_healthy(board.app)
    board.hp.now_us = now


def test_a_stalled_clock_starves_the_watchdog():
    """The microsecond clock stops: from the first tick that sees it still, the loop is not
    healthy, so the watchdog goes unfed and resets the chip (fed, it would keep a board
    whose every timeout has stopped)."""
    board, _ = engaged_board()
    dog = Watchdog(board)
    dog.run(0.1)
    board.clock_frozen = True
    board.step(TICK_US // 2)
    dog.fed_at = board.now_us
    ticks = board.app.ticks_run
    dog.run(0.2 + TICK_US / 1e6)
    assert board.app.ticks_run - ticks >= 1
    assert board.now_us - dog.fed_at >= 0.2e6, "fed while the clock stood still"
    dog.run(WATCHDOG_US / 1e6)
    assert dog.starved > WATCHDOG_US


# ---------------------------------------------------------------- counters, heartbeat, LEDs

HEARTBEAT_US = round(MODEL.heartbeat_period * 1e6)   # documented: a heartbeat every link.heartbeat_period
LED_TICKS = 10                   # the LEDs are for people: within ten ticks (0.1 s) is soon enough


def test_tick_requests_the_main_loop_missed_are_counted():
    """Three tick requests before one main-loop pass: one tick runs, two are counted in
    ticks_missed."""
    board = SimBoard(MODEL)
    board.run(0.1)
    missed = board.app.ticks_missed
    board.tick_interrupt = False
    for _ in range(3):
        board.lib.app_request_tick(board.app)
    board.step(board.poll_us)
    assert board.app.ticks_missed - missed == 2


def test_heartbeats_come_every_period_to_the_main_loop_pass():
    """The k-th heartbeat leaves in the first main-loop pass at or after k x link.heartbeat_period."""
    board = SimBoard(MODEL)
    board.run(2.05)
    assert [round(t * 1e6) for t in board.heartbeat_times[:4]] == [HEARTBEAT_US * k for k in range(1, 5)]


def test_the_fault_led_follows_a_fault_within_ten_ticks():
    """The IMU stops answering on a disabled board: the fault LED lights within ten ticks
    of the fault standing (and the power LED stays off)."""
    board = SimBoard(MODEL)
    board.run(0.3)
    assert not board.hp.led[1]
    board.hp.imu_present = False
    assert step_until(board, lambda: board.lib.app_faults(board.app) & FAULT["imu"], 0.2) is not None
    assert step_until(board, lambda: board.hp.led[1], (LED_TICKS + 1) * TICK_US / 1e6) is not None
    assert not board.hp.led[0]
