"""The link's delay: the board's answer to ping, the fit alone on exchanges drawn from known
delays, then `uavarm calibrate link` end to end over the link to the SITL, whose link delays
its bytes each way by a "hardware truth" the model file does not know.

Oracles: the ping and pong layouts of the message table and the board's own clock (read
apart from the firmware's answer); delays drawn here (the fit's truth); the SITL's link delay.
"""
from __future__ import annotations


import numpy as np
import pytest

from simboard_tools import make_board, ready, run_until
from test_calibrate import model_copy  # noqa: F401  (fixture)
from uavarm.calibrate import fit, guide
from uavarm.calibrate.fit import CalibrationError
from uavarm.link import ArmLink
from uavarm.model import config
from uavarm.sim.sitl import Sitl

pytestmark = pytest.mark.realtime   # a simulated board in real time: a stage of its own (Makefile)


# ---------------------------------------------------------------- the board's answer

@pytest.mark.parametrize("enabled", [False, True])
def test_the_board_answers_a_ping_at_once_with_its_time_of_arrival(enabled):
    board = make_board(start_us=0xFFFF_F000)           # the board's clock about to wrap
    if enabled:
        board.send("enable", on=1)
        assert run_until(board, lambda: ready(board), 1.0) is not None
    board.run(0.05)
    for seq, stamp in ((7, 0xDEAD_BEEF), (8, 0)):
        before = board.hp.now_us
        board.send("ping", seq=seq, stamp_us=stamp)
        board.run(0.002)
        pong = board.streamed["pong"][-1]
        assert (pong["seq"], pong["stamp_us"]) == (seq, stamp)
        assert (pong["arrived_us"] - before) % 2**32 <= board.poll_us      # the next main-loop pass
    assert len(board.streamed["pong"]) == 2


# ---------------------------------------------------------------- the fit alone

def drawn_exchanges(up, down, n=250, lost=0.04, seed=0, jitter=0.001):
    """Pings every 20 ms: each way the fixed delay plus an exponential excess (mean `jitter`);
    the board's clock offset by an arbitrary amount and wrapping; `lost` of them unanswered.
    (exchanges, sent, the drawn one-way excesses to the board of the answered ones)."""
    rng = np.random.default_rng(seed)
    sent = 100.0 + 0.02 * np.arange(n)
    extra_up, extra_down = rng.exponential(jitter, n), rng.exponential(jitter, n)
    arrive = sent + up + extra_up
    back = arrive + down + extra_down
    board_us = (np.round((arrive - 100.0) * 1e6).astype(np.int64) + 2**32 - 3_000_000) % 2**32
    keep = rng.random(n) >= lost
    exchanges = [(s, b, int(a)) for s, b, a, k in zip(sent, back, board_us, keep) if k]
    return exchanges, n, extra_up[keep]


@pytest.mark.parametrize("up, down", [(0.003, 0.003), (0.010, 0.002)])
def test_the_fit_finds_half_the_quickest_round_trip_and_the_spread(up, down):
    """Half the quickest round trip: the mean of the two ways' fixed delays (exactly the one
    way when they are alike; half their difference off when not), within the quickest
    exchange's own excess; the spread's median and 95th percentile those of the drawn
    excesses to the board."""
    exchanges, sent, extra = drawn_exchanges(up, down)
    d = fit.fit_link_delay(exchanges, sent)
    trips = np.array([b - s for s, b, _ in exchanges])
    assert d.round_trip_min == pytest.approx(trips.min())
    assert d.one_way == pytest.approx((up + down) / 2, abs=0.0002)
    excess = extra - extra.min()
    assert d.spread_p50 == pytest.approx(np.percentile(excess, 50), abs=2e-6)
    assert d.spread_p95 == pytest.approx(np.percentile(excess, 95), abs=2e-6)
    assert (d.answered, d.sent) == (len(exchanges), 250)


def test_the_fit_refuses_a_link_that_drops_pings():
    exchanges, sent, _ = drawn_exchanges(0.003, 0.003, lost=0.2)
    with pytest.raises(CalibrationError, match="pings unanswered"):
        fit.fit_link_delay(exchanges, sent)
    with pytest.raises(CalibrationError, match="0 of 0|unanswered"):
        fit.fit_link_delay([], 0)


# ---------------------------------------------------------------- through the SITL

def sitl_arm(up, down, arm_class=ArmLink):
    """A SITL in real time and a link on its clock: the link delays it adds (simulated time)
    are the truth the calibration measures, however busy the machine."""
    s = Sitl(speed=1.0, link_delay=(up, down)).start()
    return s, arm_class(s.device, clock=s.clock)


@pytest.mark.parametrize("up, down", [(0.010, 0.010), (0.012, 0.004)])
def test_calibrate_link_writes_the_links_delay(model_copy, up, down):  # noqa: F811
    """The SITL's link delays each byte `up` ms to the board and `down` back: the written
    link_delay_min is their mean within 2 ms (the SITL's own 2 ms slices and this computer's
    scheduling add to each round trip; with the ways unlike, the mean is what a round trip
    can tell), the model file's comments kept."""
    s, arm = sitl_arm(up, down)
    try:
        assert guide.link(arm, model_copy, lambda text: None, lambda q: True, seconds=2.0)
    finally:
        arm.close()
        s.stop()
    written = config.load(model_copy).estimator.link_delay_min
    print(f"\nlink {up * 1000:g} ms in, {down * 1000:g} ms out: link_delay_min {written * 1000:.1f} ms")
    assert written == pytest.approx((up + down) / 2, abs=0.002)
    assert "# link_delay_min here is the simulator's link" in model_copy.read_text()


def test_calibrate_link_adds_the_upstream_age_of_the_stamps(model_copy):  # noqa: F811
    s, arm = sitl_arm(0.005, 0.005)
    try:
        assert guide.link(arm, model_copy, lambda text: None, lambda q: True, seconds=1.0, upstream_ms=7.0)
    finally:
        arm.close()
        s.stop()
    assert config.load(model_copy).estimator.link_delay_min == pytest.approx(0.012, abs=0.002)


class DeafToPings(ArmLink):
    """A link to a board whose firmware predates ping: the pings never reach it."""

    def send(self, name, **fields):
        if name != "ping":
            super().send(name, **fields)


@pytest.mark.parametrize("up, arm_class, why", [
    (0.0, DeafToPings, "pings unanswered"),
    (0.16, ArmLink, "not below estimator.link_delay_max"),
])
def test_calibrate_link_refuses_and_leaves_the_model_file(model_copy, up, arm_class, why):  # noqa: F811
    before = model_copy.read_text()
    s, arm = sitl_arm(up, up, arm_class)
    try:
        with pytest.raises(CalibrationError, match=why):
            guide.link(arm, model_copy, lambda text: None, lambda q: True, seconds=1.0)
    finally:
        arm.close()
        s.stop()
    assert model_copy.read_text() == before
