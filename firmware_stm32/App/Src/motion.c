/* How the arm moves from one pose to the next; see motion.h. */
#include "motion.h"

#include <math.h>
#include <string.h>

#include "fastmath.h"
#include "kinematics.h"
#include "model_params.h"

/* Closer than this (mm) to joint 1's axis, a target's direction is rounding noise: a new
 * goal there keeps joint 1 where it is (the park point is 0.01 mm off the axis). */
#define AXIS_EXACT 0.5f

/* A piece of a route this short (rad, largest joint) whose swept box is not clear meets a
 * real obstacle, not the bound's slack. */
#define ROUTE_PIECE_MIN 0.005f

static inline float largest_change(const float a[3], const float b[3])
{
    const float d0 = fabsf(b[0] - a[0]), d1 = fabsf(b[1] - a[1]), d2 = fabsf(b[2] - a[2]);
    const float d01 = d0 > d1 ? d0 : d1;
    return d01 > d2 ? d01 : d2;
}

/* Is the straight joint-space move a -> b clear? Checked piece by piece, each piece as long
 * as its swept box stays clear: halved where it is not, doubled again after one that is. */
static bool path_clear(const float a[3], const float b[3], unsigned *budget)
{
    const float len = largest_change(a, b);   /* (NaN: kin_check_swept refuses it) */
    float from[3], to[3], t = 0.0f, span = 1.0f;
    memcpy(from, a, sizeof from);
    for (;;) {
        if (*budget == 0) return false;
        --*budget;
        const float t_end = t + span;
        for (int i = 0; i < 3; ++i) to[i] = t_end >= 1.0f ? b[i] : a[i] + t_end * (b[i] - a[i]);
        if (kin_check_swept(from, to) == KIN_OK) {
            if (t_end >= 1.0f) return true;
            t = t_end;
            memcpy(from, to, sizeof from);
            if (span < 0.5f) span *= 2.0f;
        } else {
            span *= 0.5f;
            if (span * len < ROUTE_PIECE_MIN) return false;
        }
    }
}

/* Can the arm rest at q and move on from it? */
static bool aim_clear(const float q[3])
{
    return kin_check_move(q, q, MOTION_GOAL_MARGIN) == KIN_OK;
}

bool motion_start(motion_t *m, const float q[3])
{
    memset(m, 0, sizeof *m);
    if (kin_check_joints(q) != KIN_OK) return false;
    memcpy(m->q, q, sizeof m->q);
    memcpy(m->aim, q, sizeof m->aim);
    memcpy(m->from, q, sizeof m->from);
    m->home = q[0];
    m->elbow = q[2] < 0.0f ? -1.0f : 1.0f;
    m->arrived = true;
    m->started = true;
    m->step_cap = MODEL_WORKING_STEP;
    return true;
}

/* The goal for target p continuing from the joints `from`: on their branch (joint 1 kept
 * if p is on its axis) if that is a valid goal, else the valid IK candidate nearest them. */
static bool goal_from(const float from[3], float elbow_now, const float p[3], float goal[3])
{
    const float rho2 = p[0] * p[0] + p[1] * p[1];
    const float elbow = from[2] != 0.0f ? (from[2] > 0.0f ? 1.0f : -1.0f) : elbow_now;
    float next[3];
    if (kin_ik_branch(p, from, elbow, rho2 < AXIS_EXACT * AXIS_EXACT, goal, next) == 0 && aim_clear(goal)) {
        return true;
    }
    return kin_ik_nearest(p, from, goal) == KIN_OK && aim_clear(goal);
}

bool motion_goal_for(const motion_t *m, const float p_base[3], float goal[3])
{
    return goal_from(m->q, m->elbow, p_base, goal);
}

/* A route by a tuck (joints 2-3 in, joint 1 round, out to the goal) in via[]: joints 2-3
 * at the model's tuck, at its mirror image (the other elbow), or hanging straight down. */
static bool tuck_route(const float from[3], const float goal[3], float via[MOTION_VIAS][3], unsigned *budget)
{
    static const float TUCKS[3][2] = { { MODEL_TUCK_Q2, MODEL_TUCK_Q3 }, { -MODEL_TUCK_Q2, -MODEL_TUCK_Q3 }, { 0.0f, 0.0f } };
    for (int t = 0; t < 3; ++t) {
        via[0][0] = from[0];
        via[1][0] = goal[0];
        for (int k = 0; k < 2; ++k) memcpy(&via[k][1], TUCKS[t], sizeof TUCKS[t]);
        if (path_clear(from, via[0], budget) && path_clear(via[0], via[1], budget) && path_clear(via[1], goal, budget)) {
            return true;
        }
    }
    return false;
}

bool motion_go(motion_t *m, const float goal[3])
{
    unsigned budget = MOTION_ROUTE_PIECES;
    float via[MOTION_VIAS][3] = { { 0.0f } };   /* (copied whole into m below, used or not) */
    uint8_t vias = 0;
    if (!m->started) return false;
    if (!path_clear(m->q, goal, &budget)) {
        if (!tuck_route(m->q, goal, via, &budget)) return false;
        vias = 2;
        m->tucks++;
    }
    memcpy(m->via, via, sizeof via);
    m->vias = vias;
    m->next_via = 0;
    memcpy(m->aim, goal, sizeof m->aim);
    memcpy(m->from, goal, sizeof m->from);
    m->home = goal[0];
    if (goal[2] != 0.0f) m->elbow = goal[2] > 0.0f ? 1.0f : -1.0f;
    m->arrived = false;
    return true;
}

bool motion_on_axis(const float p[3])
{
    return p[0] * p[0] + p[1] * p[1] < MODEL_AXIS_HOLD_RADIUS * MODEL_AXIS_HOLD_RADIUS;
}

bool motion_head_for(motion_t *m, const float p_base[3], const float p_level[3])
{
    float goal[3], level[3];
    /* the branch for the set position as from a level base, then its pose at the tilt */
    const bool at_level = goal_from(m->q, m->elbow, p_level, level);
    if (!goal_from(at_level ? level : m->q, m->elbow, p_base, goal)) {
        if (!at_level) return false;
        memcpy(goal, level, sizeof goal);
    }
    if (!motion_go(m, goal)) return false;
    if (at_level) m->home = level[0];   /* the set position's own direction, whatever the tilt now */
    return true;
}

/* Inside a landing leg's sector (joint 1 within its half width, either way round) the arm
 * must keep within the leg distance. A target it may not reach there is aimed at the nearer
 * of two points the arm may hold: at the sector's edge, or in the target's plane pulled in to
 * the leg distance; the one taken is kept until the other is LEG_SWITCH nearer (no flipping
 * between two poses centimetres apart on noise). An aim that is not clear falls back to the
 * other, then to the step checks. */
#define LEG_EDGE (MODEL_LEG_HALF_WIDTH + MOTION_GOAL_MARGIN + 0.0035f)   /* rad from a leg's plane: clear by the
                                                                           goals' margin and 0.2 deg */
/* mm from joint 1's axis: inside the leg distance by what the goals' margin on joints 2 and 3
 * may add to the reach (the arm's length times it) and half a millimetre */
#define LEG_INSIDE (MODEL_LEG_DISTANCE - (MODEL_L2 + MODEL_L3) * MOTION_GOAL_MARGIN - 0.5f)
#define LEG_SWITCH 2.0f                                                /* mm */

#if MODEL_LEG_PLANES > 0
/* Joint 1's angle from the nearest leg's plane, in (-pi/2, pi/2]. */
static float leg_offset(float q1)
{
    static const float PLANES[MODEL_LEG_PLANES] = { MODEL_LEG_PLANE_ANGLES };
    float best = FM_PI;
    for (int k = 0; k < MODEL_LEG_PLANES; ++k) {
        float d = q1 - PLANES[k];
        while (d > 0.5f * FM_PI) d -= FM_PI;
        while (d <= -0.5f * FM_PI) d += FM_PI;
        if (fabsf(d) < fabsf(best)) best = d;
    }
    return best;
}
#endif

/* (Not inlined: the tick's usual case, a target inside the leg distance, stays short.) */
static __attribute__((noinline)) void clear_of_legs(motion_t *m, const float p[3], float rho2)
{
#if MODEL_LEG_PLANES > 0
    const float d = leg_offset(m->aim[0]);
    if (!(fabsf(d) < LEG_EDGE) || aim_clear(m->aim)) {
        m->leg_aim = MOTION_LEG_NONE;
        return;
    }
    const float rho = sqrtf(rho2);
    const float turn = (d > 0.0f ? LEG_EDGE : -LEG_EDGE) - d;   /* to the sector's nearer edge */
    const float to_edge = rho * fabsf(turn);                     /* (sin x ~ x: |x| < 0.2 rad) */
    const float to_inside = rho - LEG_INSIDE;
    uint8_t pick = to_edge < to_inside ? MOTION_LEG_EDGE : MOTION_LEG_INSIDE;
    if (m->leg_aim != MOTION_LEG_NONE && fabsf(to_edge - to_inside) < LEG_SWITCH) pick = m->leg_aim;
    float q[3], unused[3];
    for (int tries = 0; tries < 2; ++tries, pick = MOTION_LEG_EDGE + MOTION_LEG_INSIDE - pick) {
        if (pick == MOTION_LEG_EDGE) {
            const float edge[3] = { m->aim[0] + turn, m->aim[1], m->aim[2] };
            kin_ik_branch(p, edge, m->elbow, true, q, unused);
        } else {
            const float s = LEG_INSIDE / rho;
            const float pulled[3] = { p[0] * s, p[1] * s, p[2] };
            kin_ik_branch(pulled, m->aim, m->elbow, true, q, unused);
        }
        if (aim_clear(q)) {
            memcpy(m->aim, q, sizeof m->aim);
            m->leg_aim = pick;
            return;
        }
    }
    m->leg_aim = MOTION_LEG_NONE;
#else
    (void)p;
    (void)rho2;
    m->leg_aim = MOTION_LEG_NONE;
#endif
}

/* Aim at target p_base on the followed branch (motion.h, motion_tick). */
static inline void follow(motion_t *m, const float p_base[3], bool pinned)
{
    static const float HOLD2 = MODEL_AXIS_HOLD_RADIUS * MODEL_AXIS_HOLD_RADIUS;
    static const float RELEASE2 = MODEL_AXIS_RELEASE_RADIUS * MODEL_AXIS_RELEASE_RADIUS;
    const float rho2 = p_base[0] * p_base[0] + p_base[1] * p_base[1];
    if (m->q1_held ? rho2 > RELEASE2 : rho2 < HOLD2) m->q1_held = !m->q1_held;   /* (NaN: as it was) */
    const bool hold = m->q1_held || pinned;
    /* the branch follows the target (m->from) even where the arm stops short of it */
    m->given_up = kin_ik_branch(p_base, m->from, m->elbow, hold, m->aim, m->from);
    float off = m->from[0] - m->home;
    if (fabsf(off) > MODEL_FOLLOW_WINDOW && fabsf(off) > FM_PI - 0.5f * MODEL_FOLLOW_WINDOW) {
        /* Past the window, and the target's plane reached the other way round (the same
         * plane, joint 1 half a turn over) is well inside it: the branch goes over to that
         * side. Else a target that passed the axis would keep joint 1 at the window's edge
         * for as long as it stays on the far side. */
        const float over[3] = { m->home + off - (off > 0.0f ? FM_PI : -FM_PI), m->from[1], m->from[2] };
        m->given_up = kin_ik_branch(p_base, over, m->elbow, hold, m->aim, m->from);
        off = m->from[0] - m->home;
    }
    if (fabsf(off) > MODEL_FOLLOW_WINDOW) {
        /* further round the axis than the window: reach in the plane at its edge */
        const float edge[3] = { m->home + (off > 0.0f ? MODEL_FOLLOW_WINDOW : -MODEL_FOLLOW_WINDOW), m->from[1], m->from[2] };
        float unused[3];
        m->given_up |= kin_ik_branch(p_base, edge, m->elbow, true, m->aim, unused) | KIN_BRANCH_Q1;
    }
    if (rho2 > LEG_INSIDE * LEG_INSIDE) {   /* (NaN: not) */
        clear_of_legs(m, p_base, rho2);
    } else {
        m->leg_aim = MOTION_LEG_NONE;
    }
}

/* A refused step's other tries, in order: half, a quarter (all joints in proportion); then
 * joint 1 alone and joints 2-3 alone, each a whole step of its own (as far as the speed
 * moves the joints that move), for a step that crosses the edge of a leg's sector while
 * reaching out or in (turn out first, or pull in first). */
static const float TRY_SHARE[4] = { 0.5f, 0.25f, 1.0f, 1.0f };
static const uint8_t TRY_JOINTS[4] = { 7u, 7u, 1u, 6u };

motion_speed_t motion_tick(motion_t *m, const float *target, bool pinned, float q_next[3])
{
    static const float STEP[3] = { MODEL_PARK_STEP, MODEL_TRANSIT_STEP, MODEL_WORKING_STEP };
    motion_speed_t speed = MOTION_PARK_SPEED;
    if (target != NULL) {
        follow(m, target, pinned);
        speed = m->arrived ? MOTION_WORKING_SPEED : MOTION_TRANSIT_SPEED;
    }
    /* one step toward the next corner or the aim, all joints in proportion */
    const float *dest = motion_destination(m);
    const float big = largest_change(m->q, dest), max_step = fm_minf(STEP[speed], m->step_cap);
    m->tries = 0;
    if (big > max_step) {
        m->share = max_step / big;
        for (int i = 0; i < 3; ++i) q_next[i] = m->q[i] + m->share * (dest[i] - m->q[i]);
    } else {
        m->share = 1.0f;
        memcpy(q_next, dest, sizeof m->q);
    }
    return speed;
}

bool motion_smaller(motion_t *m, float q_next[3])
{
    if (m->tries >= 4) return false;
    const float *dest = motion_destination(m);
    const int t = m->tries++;
    float share = m->share * TRY_SHARE[t];
    if (TRY_JOINTS[t] != 7u) {   /* the joints that move, a whole step of their own */
        float part = 0.0f;
        for (int i = 0; i < 3; ++i) {
            if (TRY_JOINTS[t] & (1u << i)) part = fm_maxf(part, fabsf(dest[i] - m->q[i]));
        }
        /* the step was share x the largest change of all (or all of it, share 1) */
        const float step = m->share * largest_change(m->q, dest);
        share = m->share < 1.0f && part > step ? step / part : 1.0f;
    }
    for (int i = 0; i < 3; ++i) q_next[i] = TRY_JOINTS[t] & (1u << i) ? m->q[i] + share * (dest[i] - m->q[i]) : m->q[i];
    return true;
}
