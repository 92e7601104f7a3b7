"""motion.c on its own, through the host build: each function's contract in motion.h, checked
pose by pose where the closed-loop tests only see the arm end up right (the final check in
app.c and the following that runs after hide a planner that aims wrong for a tick or takes a
needless detour).

Oracles: plain geometry (tests/oracles.py: the arm's points, the pose check, the followed
branch's IK by the law of cosines), the AX-12A's speed unit (e-manual), and the order of
the smaller steps written in motion.h.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from oracles import arm_points, branch_ik, check_pose, clear_by, textbook_ik
from simboard_tools import MODEL, RPM_PER_SPEED_UNIT, speed_register
from uavarm.build import firmware

FFI, LIB = firmware.default()
PARK = np.radians(MODEL.park_deg)
MARGIN = 0.0078            # rad: motion.h's MOTION_GOAL_MARGIN, which every goal keeps
TOL_RAD = 2e-4             # float32 IK against float64 geometry
TOL_MM = 0.05


def ee(q):
    return arm_points(MODEL, np.asarray(q, dtype=float))[2]


def started(q):
    m = FFI.new("motion_t *")
    assert LIB.motion_start(m, list(map(float, q)))
    return m


def tick(m, target=None, pinned=False):
    q_next = FFI.new("float[3]")
    speed = LIB.motion_tick(m, FFI.NULL if target is None else list(map(float, target)), pinned, q_next)
    return speed, np.array(list(q_next))


def goal_for(m, p):
    goal = FFI.new("float[3]")
    ok = LIB.motion_goal_for(m, list(map(float, p)), goal)
    return ok, np.array(list(goal))


def safe(q, margin=0.0):
    status, clear = check_pose(MODEL, q, margin)
    return status[0] == 0 and clear[0]


def elbow_sign(q):
    return 1.0 if q[2] > 0 else -1.0


def sampled_poses(seed, n, mm=2.0, rad=0.02):
    """Random poses `rad` inside the limits and `mm` clear of body and legs."""
    rng = np.random.default_rng(seed)
    lo = np.radians([l.min_deg for l in MODEL.limits])
    hi = np.radians([l.max_deg for l in MODEL.limits])
    q = rng.uniform(lo, hi, size=(20 * n, 3))
    keep = q[clear_by(MODEL, q, mm, rad)]
    assert len(keep) >= n
    return keep[:n]


STARTS = [PARK, np.radians([100.0, 50.0, 40.0]), np.radians([-120.0, -40.0, -70.0]),
          np.radians([0.0, 30.0, 60.0])]


@pytest.mark.parametrize("q", STARTS, ids=lambda q: "start " + ",".join(f"{d:.0f}" for d in np.degrees(q)))
def test_started_arm_holds_its_pose_and_follows_it_at_working_speed(q):
    """Started at a pose, the arm is at its aim: following the target that pose reaches
    proposes that very pose (no drift, however far round joint 1 is), at the working speed."""
    m = started(q)
    speed, q_next = tick(m, ee(q))
    assert speed == LIB.MOTION_WORKING_SPEED
    np.testing.assert_allclose(q_next, q, atol=TOL_RAD)
    np.testing.assert_allclose(list(m.aim), q, atol=TOL_RAD)


def test_started_arm_follows_a_target_just_outside_the_hold_radius():
    """Beyond axis_hold_radius the target's direction is followed from the start: joint 1
    turns with a target 12 mm off the axis that moves round it (the hold begins only once
    the target comes within the hold radius)."""
    r = 0.5 * (MODEL.motion.axis_hold_radius + MODEL.motion.axis_release_radius)
    target = np.array([r, 0.0, -150.0])
    q, *_ = branch_ik(MODEL, target, [0.0, 0.0, 0.5], 1.0, hold=False)
    assert safe(q, MARGIN)
    m = started(q)
    turned = np.array([r * math.cos(0.2), -r * math.sin(0.2), -150.0])   # joint 1 at +0.2 rad
    _, q_next = tick(m, turned)
    expect, *_ = branch_ik(MODEL, turned, q, 1.0, hold=False)
    assert expect[0] == pytest.approx(0.2, abs=1e-9)
    np.testing.assert_allclose(list(m.aim), expect, atol=TOL_RAD)


def test_a_started_arm_with_no_target_stays_put():
    for q in STARTS:
        m = started(q)
        speed, q_next = tick(m)
        assert speed == LIB.MOTION_PARK_SPEED
        np.testing.assert_array_equal(q_next, np.asarray(q, np.float32))


def test_an_arm_never_started_goes_nowhere():
    m = FFI.new("motion_t *")
    assert not LIB.motion_go(m, list(map(float, PARK)))
    assert not LIB.motion_head_for(m, list(map(float, ee(PARK))), list(map(float, ee(PARK))))


def test_following_turns_joint_1_no_further_than_the_window():
    """A target carried round the axis, 5 deg a tick, to 120 deg from where the goal put
    joint 1: joint 1 stops at follow_window_deg (90) from there, and the arm reaches in that
    plane."""
    q = np.radians([0.0, 40.0, -60.0])
    m = started(q)
    r = math.hypot(*ee(q)[:2])
    for deg in range(5, 125, 5):
        turn = math.radians(deg)
        target = np.array([r * math.cos(turn), -r * math.sin(turn), ee(q)[2]])   # joint 1 at +deg
        tick(m, target)
    window = math.radians(MODEL.motion.follow_window_deg)
    assert m.aim[0] == pytest.approx(window, abs=1e-5)
    assert m.given_up & LIB.KIN_BRANCH_Q1
    expect, *_ = branch_ik(MODEL, target, [window, q[1], q[2]], -1.0, hold=True)
    np.testing.assert_allclose(list(m.aim), expect, atol=TOL_RAD)


def round_axis(deg, r, z):
    """The point r mm from joint 1's axis, at depth z, that joint 1 faces at +deg."""
    a = math.radians(deg)
    return np.array([r * math.cos(a), -r * math.sin(a), z])


def test_a_target_that_crossed_the_axis_is_followed_on_the_far_side():
    """Past the window's edge, the target goes straight across joint 1's axis (3 mm from it:
    joint 1 held) and comes out on the far side, then round toward where the arm started.
    Its plane reached the other way round is then well inside the window: the arm follows
    it there and reaches it, instead of staying at the edge for as long as it stays on the
    far side."""
    q = np.radians([0.0, 40.0, -60.0])
    m = started(q)
    r, z = math.hypot(*ee(q)[:2]), ee(q)[2]
    path = [round_axis(deg, r, z) for deg in range(5, 105, 5)]            # to the edge and past
    a, b = round_axis(100.0, r, z), round_axis(-80.0, r, z)
    side = round_axis(10.0, 3.0, 0.0) * [1, 1, 0]                        # 3 mm off the axis
    path += [a + (b - a) * s + side * math.sin(math.pi * s) for s in np.linspace(0.0, 1.0, 60)]
    path += [round_axis(deg, r, z) for deg in range(-80, -29, 2)]          # round to -30 deg
    for target in path:
        tick(m, target)
    assert m.given_up == 0
    expect, *_ = branch_ik(MODEL, path[-1], [math.radians(-30.0), q[1], q[2]], -1.0, hold=False)
    np.testing.assert_allclose(list(m.aim), expect, atol=TOL_RAD)
    np.testing.assert_allclose(ee(list(m.aim)), path[-1], atol=TOL_MM)


@pytest.mark.parametrize("start, side", [(0.0, 1), (0.0, -1), (20.0, 1), (20.0, -1), (80.0, -1)],
                         ids=lambda v: f"{v:g}" if isinstance(v, float) else ("turning right" if v > 0 else "turning left"))
@pytest.mark.parametrize("past", [-0.2, 0.2])
def test_the_branch_goes_over_once_the_far_plane_is_within_half_the_window(past, side, start):
    """Started with joint 1 at `start` deg and carried round the axis, either way (away from
    joint 1's limit when the window's edge would pass it), to 0.2 deg short of, or past,
    180 - window / 2 (135 deg) from there: short of it the arm reaches at the window's edge;
    past it joint 1 faces the same plane half a turn over (45 deg the other side of where it
    started), reaching the other way."""
    q = np.radians([start, 40.0, -60.0])
    m = started(q)
    r, z = math.hypot(*ee(q)[:2]), ee(q)[2]
    window = MODEL.motion.follow_window_deg
    turn = 180.0 - window / 2 + past
    for deg in list(np.arange(1.0, turn, 1.0)) + [turn]:
        tick(m, round_axis(start + side * deg, r, z))
    if past < 0:
        assert m.aim[0] == pytest.approx(math.radians(start + side * window), abs=1e-5)
        assert m.given_up & LIB.KIN_BRANCH_Q1
    else:
        assert m.aim[0] == pytest.approx(math.radians(start + side * (turn - 180.0)), abs=1e-4) and m.given_up == 0
        np.testing.assert_allclose(ee(list(m.aim)), round_axis(start + side * turn, r, z), atol=TOL_MM)


def test_a_target_circling_the_axis_is_followed_within_the_window_every_turn():
    """A target carried three times round the axis: joint 1 never aims further than the
    window from where the goal put it, and each time the target comes back round to there
    the arm reaches it again (however far round the branch it follows has run)."""
    q = np.radians([0.0, 40.0, -60.0])
    m = started(q)
    r, z = math.hypot(*ee(q)[:2]), ee(q)[2]
    window = math.radians(MODEL.motion.follow_window_deg)
    for turn in range(3):
        for deg in range(5, 365, 5):
            tick(m, round_axis(deg, r, z))
            assert abs(m.aim[0]) <= window + 1e-6
        assert m.given_up == 0, turn
        np.testing.assert_allclose(list(m.aim), q, atol=TOL_RAD)


def test_a_goal_with_the_arm_straight_keeps_the_elbow_it_came_with():
    """joint 3 at exactly 0 belongs to neither elbow: following on from it keeps the sign the
    arm had (here +), so a target just off the straight arm is reached on that side."""
    m = started(np.radians([0.0, 30.0, 60.0]))
    straight = np.radians([0.0, 30.0, 0.0])
    assert LIB.motion_go(m, list(map(float, straight)))
    near = np.radians([0.0, 20.0, 30.0])
    tick(m, ee(near))
    np.testing.assert_allclose(list(m.aim), near, atol=TOL_RAD)


def test_start_refuses_an_unsafe_pose():
    for q in ([0.0, 0.0, math.radians(120.0)], [0.0, math.radians(100.0), math.radians(100.0)], [math.nan, 0.0, 0.0]):
        m = FFI.new("motion_t *")
        assert not LIB.motion_start(m, q)
        assert not m.started


def test_goal_for_reaches_the_target_on_the_arms_branch():
    """A target the arm's own branch reaches, nothing clamped, with room to spare: the goal
    is that branch's pose, and it puts the end effector on the target."""
    found = 0
    for start in STARTS:
        m = started(start)
        for q in sampled_poses(1, 200):
            p = ee(q)
            own, *clamped = branch_ik(MODEL, p, start, elbow_sign(start), hold=False)
            if any(clamped) or not clear_by(MODEL, own, 2.0, 0.02)[0]:
                continue
            found += 1
            ok, goal = goal_for(m, p)
            assert ok, np.degrees(q)
            np.testing.assert_allclose(goal, own, atol=TOL_RAD)
            np.testing.assert_allclose(ee(goal), p, atol=TOL_MM)
    assert found >= 200


def test_goal_for_takes_the_other_branch_where_the_arms_own_cannot_reach():
    """A target whose every pose on the arm's elbow is refused (limit, body, leg) is reached
    on the other elbow: a valid goal, not a refusal."""
    m = started(PARK)
    found = 0
    for q in sampled_poses(2, 3000):
        if elbow_sign(q) == elbow_sign(PARK):
            continue
        p = ee(q)
        own_elbow = [c for c in _textbook_candidates(p) if elbow_sign(c) == elbow_sign(PARK)]
        if any(safe(c, 0.01) or not check_pose(MODEL, c, 0.01)[1][0] for c in own_elbow):
            continue                    # the arm's own elbow has a pose (or one too close to call)
        found += 1
        ok, goal = goal_for(m, p)
        assert ok, np.degrees(q)
        np.testing.assert_allclose(ee(goal), p, atol=TOL_MM)
        assert safe(goal, MARGIN - 1e-4)
    assert found >= 20


def _textbook_candidates(p):
    q, exists = textbook_ik(MODEL, p)
    return [c for c, e in zip(q[0], exists[0]) if e]


def test_goal_for_a_target_out_of_reach_is_refused():
    m = started(PARK)
    for p in ([400.0, 0.0, -100.0], [0.0, 0.0, 50.0], [math.nan, 0.0, -100.0]):
        ok, _ = goal_for(m, p)
        assert not ok, p


def _state(m):
    return bytes(FFI.buffer(m))


def test_head_for_out_of_reach_everywhere_changes_nothing():
    m = started(PARK)
    before = _state(m)
    assert not LIB.motion_head_for(m, [400.0, 0.0, -100.0], [380.0, 0.0, -100.0])
    assert _state(m) == before


def test_head_for_out_of_reach_at_the_tilt_heads_for_the_level_pose():
    """The set position reachable from a level base but not at the tilt: the arm heads for
    its level pose (and follows from there), instead of refusing it."""
    m = started(PARK)
    p_level = ee(np.radians([30.0, 40.0, -60.0]))
    assert LIB.motion_head_for(m, [-200.0, 0.0, -100.0], list(map(float, p_level)))   # 60 mm too far
    np.testing.assert_allclose(ee(list(m.aim)), p_level, atol=TOL_MM)
    assert safe(list(m.aim), MARGIN - 1e-4)


def _route(m, start):
    return [np.asarray(start)] + [np.array(list(m.via[k])) for k in range(m.vias)] + [np.array(list(m.aim))]


def _straight_clear(a, b, samples=400):
    """The joint-space line a -> b, densely sampled, clear by plain geometry."""
    s = np.linspace(0.0, 1.0, samples)[:, None]
    status, _ = check_pose(MODEL, a + s * (b - a))
    return bool(np.all(status == 0))


def test_routes_are_clear_and_straight_where_the_straight_move_is():
    """motion_go: a goal the straight joint-space move reaches clear of everything (with room
    to spare) is headed for directly, no corners; any route it plans is clear end to end;
    a goal it refuses leaves the arm as it was."""
    goals = sampled_poses(3, 40, mm=5.0, rad=0.05)
    straight = tucked = refused = 0
    for start in STARTS:
        for goal in goals:
            m = started(start)
            before = _state(m)
            if not LIB.motion_go(m, list(map(float, goal))):
                refused += 1
                assert _state(m) == before
                continue
            route = _route(m, start)
            np.testing.assert_array_equal(route[-1], goal.astype(np.float32))
            for a, b in zip(route, route[1:]):
                assert _straight_clear(a, b), (np.degrees(a), np.degrees(b))
            roomy = all(safe(start + s * (goal - start), 0.03) for s in np.linspace(0, 1, 200))
            if roomy:
                assert m.vias == 0, "a clear straight move taken by a detour"
                straight += 1
            if m.vias > 0:
                tucked += 1
                _, q_next = tick(m)          # the first step heads for the first corner
                way, step = route[1] - start, q_next - start
                assert np.linalg.norm(np.cross(way, step)) <= 1e-4 * np.linalg.norm(way) * np.linalg.norm(step)
                assert np.dot(way, step) > 0
    assert straight >= 20 and tucked >= 5, (straight, tucked, refused)


def test_a_new_goal_sets_the_branch_that_following_keeps():
    """After motion_go to a pose on the other elbow, following its target stays there."""
    m = started(PARK)
    goal = np.radians([20.0, -30.0, 70.0])
    assert safe(goal, 0.05) and elbow_sign(goal) != elbow_sign(PARK)
    assert LIB.motion_go(m, list(map(float, goal)))
    speed, _ = tick(m, ee(goal))
    assert speed == LIB.MOTION_TRANSIT_SPEED            # not yet at its aim
    np.testing.assert_allclose(list(m.aim), goal, atol=TOL_RAD)


def test_pinned_and_held_targets_keep_joint_1():
    """Pinned (a set position on the axis), joint 1 holds wherever the target goes; unpinned,
    it holds only while the target is within axis_hold_radius of the axis."""
    q = np.radians([10.0, 40.0, -60.0])
    m = started(q)
    away = np.array([60.0, -60.0, -120.0])              # 45 deg round from joint 1
    tick(m, away, pinned=True)
    assert m.aim[0] == pytest.approx(q[0], abs=1e-6)
    expect, *_ = branch_ik(MODEL, away, q, -1.0, hold=True)
    np.testing.assert_allclose(list(m.aim), expect, atol=TOL_RAD)

    m = started(q)
    near = np.array([0.0, 0.5 * MODEL.motion.axis_hold_radius, -150.0])   # 90 deg round, near the axis
    tick(m, near)
    assert m.aim[0] == pytest.approx(q[0], abs=1e-6)
    tick(m, away)
    expect, *_ = branch_ik(MODEL, away, q, -1.0, hold=False)
    assert m.aim[0] == pytest.approx(expect[0], abs=TOL_RAD)


@pytest.mark.parametrize("rho, held", [(0.97, True), (1.03, False)], ids=["inside the release radius", "past it"])
def test_a_held_joint_1_is_released_only_past_the_release_radius(rho, held):
    """Once a target has come within axis_hold_radius (joint 1 held), it must go out past
    axis_release_radius, not only past the hold radius, before joint 1 follows it again:
    a target taken 90 deg round to `rho` x the release radius (beyond the hold radius)."""
    hold, release = MODEL.motion.axis_hold_radius, MODEL.motion.axis_release_radius
    assert hold < rho * release
    q = np.radians([10.0, 40.0, -60.0])
    m = started(q)
    tick(m, round_axis(10.0, 0.5 * hold, -150.0))
    assert m.aim[0] == pytest.approx(q[0], abs=1e-6)
    out = round_axis(100.0, rho * release, -150.0)
    tick(m, out)
    expect, *_ = branch_ik(MODEL, out, q, -1.0, hold=held)
    assert m.aim[0] == pytest.approx(expect[0], abs=TOL_RAD)
    assert held == (m.aim[0] == pytest.approx(q[0], abs=1e-6))


def test_a_target_shaken_about_the_hold_radius_does_not_chatter_joint_1():
    """A target 2 % either side of axis_hold_radius, alternately 60 deg either way round the
    axis (noise on a set position near the axis): joint 1 is held from the first time it
    comes within the hold radius and never turns again."""
    hold = MODEL.motion.axis_hold_radius
    q = np.radians([0.0, 40.0, -60.0])
    m = started(q)
    aims = []
    for k in range(40):
        tick(m, round_axis(60.0 if k % 2 else -60.0, hold * (1.02 if k % 2 else 0.98), -150.0))
        aims.append(m.aim[0])
    assert aims == [aims[0]] * len(aims), np.degrees(aims[:6])
    assert aims[0] == pytest.approx(q[0], abs=1e-6)     # the first target was inside: held at once


def _step_rad(rpm):
    """One tick's step (rad) at a speed, as the servo's Moving Speed register can express it."""
    return speed_register(rpm) * RPM_PER_SPEED_UNIT * 2 * math.pi / 60 / MODEL.sample_rate


@pytest.mark.parametrize("far", [True, False], ids=["step short of the goal", "goal within a step"])
def test_a_refused_step_is_offered_smaller_in_the_written_order(far):
    """motion_tick proposes one step at the park speed, all joints in proportion (or the goal
    itself when within a step); refused, motion_smaller offers half of it, a quarter, joint 1
    alone and joints 2-3 alone (each a whole step of the joints that move), then nothing."""
    start = np.radians([0.0, 60.0, -100.0])
    goal = start + (np.radians([20.0, -15.0, 10.0]) if far else np.array([0.004, -0.003, 0.002]))
    m = started(start)
    assert LIB.motion_go(m, list(map(float, goal)))
    speed, q_next = tick(m)
    assert speed == LIB.MOTION_PARK_SPEED
    d = goal - start
    step = _step_rad(MODEL.park_speed_rpm)
    share = min(1.0, step / np.abs(d).max())
    np.testing.assert_allclose(q_next, start + share * d, atol=2e-6)
    only_1, only_23 = d * [1, 0, 0], d * [0, 1, 1]
    expected = [start + 0.5 * share * d, start + 0.25 * share * d,
                start + min(1.0, step / np.abs(only_1).max()) * only_1,
                start + min(1.0, step / np.abs(only_23).max()) * only_23]
    for k, want in enumerate(expected):
        smaller = FFI.new("float[3]")
        assert LIB.motion_smaller(m, smaller), k
        np.testing.assert_allclose(list(smaller), want, atol=2e-6, err_msg=f"try {k}")
    assert not LIB.motion_smaller(m, FFI.new("float[3]"))


# ---------------------------------------------------------------- targets past a leg's reach

LEG, HW = MODEL.leg_angles[0], MODEL.leg_half_width   # deg: a leg of the model file, its sector's half width
DEPTH = -100.0
# How far (mm) the arm may keep from a place it may be: what the goals' margin on joints 2-3
# moves the end effector (the arm's length times it), and a millimetre for settling and the
# pull-in beyond the margin.
KEEP_OFF_MM = (MODEL.L2 + MODEL.L3) * MARGIN + 1.0


def nearest_allowed(p):
    """Plain geometry: how far p, in a leg's sector past the leg distance, is from where the end
    effector may be: across the sector's nearer edge (its vertical plane), or in p's own plane
    pulled in to the leg distance."""
    q1 = math.atan2(-p[1], p[0])
    rho = math.hypot(p[0], p[1])
    into = math.radians(HW) - abs(q1 - math.radians(LEG))
    assert into > 0 and rho > MODEL.leg_distance
    return min(rho * math.sin(into), rho - MODEL.leg_distance)


def facing(deg, rho):
    """A pose on the elbow-down branch reaching round_axis(deg, rho, DEPTH)."""
    q, *_ = branch_ik(MODEL, round_axis(deg, rho, DEPTH), [math.radians(LEG), 0.5, -1.0], -1.0, hold=False)
    return q


def follow_for(q, target, ticks):
    """The goals app.c would send, tick by tick, following a fixed target from pose q."""
    m = started(q)
    sent, q_next, box = FFI.new("float[3]", list(map(float, q))), FFI.new("float[3]"), FFI.new("float[2][3]")
    goals = []
    for _ in range(ticks):
        LIB.app_next_goal(m, list(map(float, target)), False, [list(sent)] * 2, box, q_next)   # shafts at their goals
        sent[0:3] = list(q_next)
        goals.append(np.array(list(q_next)))
    return m, np.array(goals)


@pytest.mark.parametrize("into_deg", [1.0, 4.0, 7.0, 10.0], ids=lambda d: f"{d:.0f} deg into the sector")
@pytest.mark.parametrize("rho", [101.5, 104.0, 108.0], ids=lambda r: f"{r:.1f} mm out")
@pytest.mark.parametrize("side", [-1.0, 1.0], ids=["from below", "from above"])
def test_a_target_past_a_legs_reach_is_aimed_at_the_nearest_allowed_point(into_deg, rho, side):
    """A fixed target in a leg's sector beyond the leg distance, the arm coming from 15 deg
    outside the sector's edge at the same reach: once settled, the goal is safe and the end effector
    is within KEEP_OFF_MM of the nearest place it may be (the sector's edge or the leg distance,
    whichever is nearer)."""
    edge = LEG + side * HW
    target = round_axis(edge - side * into_deg, rho, DEPTH)
    q0 = facing(edge + side * 15.0, rho)
    assert safe(q0, MARGIN)
    _, goals = follow_for(q0, target, 150)
    assert all(safe(q) for q in goals)
    off = np.linalg.norm(ee(goals[-1]) - target)
    print(f"\n{into_deg:.0f} deg into the sector, {rho:.1f} mm out: {off:.2f} mm off, "
          f"nearest allowed {nearest_allowed(target):.2f} mm")
    assert off <= nearest_allowed(target) + KEEP_OFF_MM


def test_a_target_crossing_a_legs_sector_is_aimed_edge_inside_edge_without_dithering():
    """A target 104 mm out swept across a leg's sector, 0.5 deg a tick: aimed at the edge it
    comes in over, then, deeper in, inside the leg distance (5 mm off instead of up to 18),
    then at the far edge, each once. Held where the edge and the leg distance are about as
    near and shaken +-0.4 deg (+-0.7 mm) tick by tick, the aim does not flip between them."""
    rho = 104.0
    q = facing(LEG - HW - 5.0, rho)
    m = started(q)
    aims = []
    for deg in np.arange(-14.0, 14.5, 0.5):
        tick(m, round_axis(LEG + deg, rho, DEPTH))
        aims.append(m.leg_aim)
    runs = [a for k, a in enumerate(aims) if k == 0 or a != aims[k - 1]]
    assert runs == [LIB.MOTION_LEG_NONE, LIB.MOTION_LEG_EDGE, LIB.MOTION_LEG_INSIDE, LIB.MOTION_LEG_EDGE,
                    LIB.MOTION_LEG_NONE], aims
    even = LEG - HW + math.degrees((rho - MODEL.leg_distance) / rho)   # edge and leg distance about as near
    m = started(q)
    for deg in np.arange(-14.0, -0.4, 0.5):
        tick(m, round_axis(even + deg, rho, DEPTH))
    shaken = set()
    for k in range(60):
        tick(m, round_axis(even + (0.4 if k % 2 else -0.4), rho, DEPTH))
        shaken.add(m.leg_aim)
    assert len(shaken) == 1 and shaken != {LIB.MOTION_LEG_NONE}, shaken


def test_a_target_pulled_inside_the_leg_distance_is_no_longer_aimed_for_a_leg():
    """Aimed at a sector's edge (104 mm out, 3 deg into the sector), the target is pulled in
    to 95 mm: no leg is in the way of the aim any more (MOTION_LEG_NONE), and the arm aims
    at the target itself."""
    rho = 104.0
    m = started(facing(LEG - HW - 5.0, rho))
    for deg in np.arange(-14.0, -HW + 3.5, 0.5):
        tick(m, round_axis(LEG + deg, rho, DEPTH))
    assert m.leg_aim == LIB.MOTION_LEG_EDGE
    inside = round_axis(LEG - HW + 3.0, 95.0, DEPTH)
    tick(m, inside)
    assert m.leg_aim == LIB.MOTION_LEG_NONE
    np.testing.assert_allclose(ee(list(m.aim)), inside, atol=TOL_MM)


@pytest.mark.parametrize("rho", [98.5, 98.7], ids=lambda r: f"{r:.1f} mm out")
def test_a_target_in_a_legs_sector_the_arm_may_reach_is_reached(rho):
    """Just inside the leg distance (the goal's margins clear of it), 5 deg into a leg's
    sector: the target itself, not a point pulled further in."""
    target = round_axis(LEG - HW + 5.0, rho, DEPTH)
    m, goals = follow_for(facing(LEG - HW - 15.0, rho), target, 150)
    assert m.leg_aim == LIB.MOTION_LEG_NONE
    assert np.linalg.norm(ee(goals[-1]) - target) < TOL_MM
