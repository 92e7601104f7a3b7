/* How the arm moves from one pose to the next: one goal per tick, each a bounded step from
 * the last and checked, as a move, before the bus; routes around what a straight move would
 * sweep through.
 *
 * The arm always heads for an aim: a fixed pose (park, or where a new set position is
 * reached at the tilt) or, while it follows a target, the IK of that target on the branch it
 * is on (kin_ik_branch: joint 1's plane continued, the elbow sign kept, joint 1 held near
 * its axis and kept within a window of the set position's direction, the nearest reachable
 * point when the target is out of reach). A move to a fixed pose goes straight in joint
 * space if that whole path is clear, else by a tuck: joints 2-3 in to the model's tuck (the
 * park pose's, or hanging straight down: inside the leg distance, so joint 1 may turn
 * anywhere), its mirror image or straight down, joint 1 round, then out to the aim; if no
 * way is clear, the move is refused. Each tick's goal is at most one step (the speed in use
 * times the tick, and at most step_cap) from the last, all joints in proportion; the application checks it
 * (kin_check_move), and a step refused is halved twice, then tried for joint 1 alone and
 * for joints 2-3 alone (out of a leg's sector before reaching out), then the arm holds.
 *
 * No HAL, no I/O: app.c feeds it and sends its goals to the servos.
 */
#ifndef MOTION_H
#define MOTION_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Every goal the application sends must be clear with every joint this far (rad) either way
 * (kin_check_move): the arm never rests where the check of where its shafts may be would keep
 * it from moving away again. A shaft at rest reads up to a unit from its goal (its compliance
 * margin) and stands within half a unit of its reading: 1.5 AX-12A units of 300/1023 deg,
 * 0.0077 rad (0.9 mm at full stretch). */
#define MOTION_GOAL_MARGIN 0.0078f

/* cffi:begin */
#define MOTION_LEG_NONE 0          /* no leg in the way of the aim */
#define MOTION_LEG_EDGE 1          /* aimed at a leg sector's edge */
#define MOTION_LEG_INSIDE 2        /* aimed inside a leg's distance, in the target's plane */
#define MOTION_VIAS 2              /* a route's corners before its aim */
#define MOTION_ROUTE_PIECES 512    /* most swept checks one route's planning may take */

typedef struct {
    bool started;                  /* q holds a known pose (motion_start) */
    float q[3];                    /* the last goal: every step is checked from here */
    float aim[3];                  /* the pose the arm heads for */
    float from[3];                 /* the followed branch's angles, which run on past a limit */
    float home;                    /* joint 1 facing the set position level: following stays near it */
    float via[MOTION_VIAS][3];     /* the corners still to pass before the aim, in order */
    uint8_t vias;                  /* corners in via[] */
    uint8_t next_via;              /* the next of them */
    bool arrived;                  /* at the aim since it was set (then following at speed) */
    float elbow;                   /* +1 or -1: the elbow sign of the branch followed */
    bool q1_held;                  /* the target is near joint 1's axis: joint 1 holds */
    uint8_t leg_aim;               /* MOTION_LEG_*: where a target past a leg's reach is aimed */
    unsigned given_up;             /* KIN_BRANCH_* of the latest following */
    float step_cap;                /* the most a goal may move per tick (rad) whatever its speed: what
                                      the servos can do at their supply; 0 holds (the goals wait
                                      for a shaft that fell behind). motion_start: no cap */
    float share;                   /* the latest step's share of the way to its destination */
    uint8_t tries;                 /* smaller steps offered since (motion_smaller) */
    bool blocked;                  /* the latest goal did not move, short of the destination */
    uint32_t tucks;                /* routes that went by the tuck */
} motion_t;

/* The arm is at q (measured, or as commanded last): it holds there. False (and nothing
 * started) if q is not a safe pose. */
bool motion_start(motion_t *m, const float q[3]);
/* The pose that reaches target p_base (base frame, mm) from where the arm is: on the branch
 * it is on (joint 1 kept if the target is on its axis) if that pose is valid, else the valid
 * IK candidate nearest the arm; valid meaning clear by MOTION_GOAL_MARGIN, as every goal
 * must be. False if there is none: the target is out of the arm's workspace. */
bool motion_goal_for(const motion_t *m, const float p_base[3], float goal[3]);
/* Head for the fixed pose goal by a route whose every step is clear; false, and nothing
 * changed, if there is none (or goal is not a safe pose). */
bool motion_go(motion_t *m, const float goal[3]);
/* Head for a new target: the goal that reaches it at the tilt (p_base), or, out of reach
 * there, as from a level base (p_level), by a clear route; false, nothing changed, if none.
 * Following then keeps joint 1 near where it faces the target from a level base. */
bool motion_head_for(motion_t *m, const float p_base[3], const float p_level[3]);
/* Is point p within the model's axis_hold_radius of joint 1's axis? */
bool motion_on_axis(const float p[3]);

typedef enum { MOTION_PARK_SPEED = 0, MOTION_TRANSIT_SPEED = 1, MOTION_WORKING_SPEED = 2 } motion_speed_t;
/* One tick's goal, proposed, and the speed of its step. Following (target not NULL:
 * engaged), the aim is target (tilted base frame, mm) on the current branch: joint 1 holds
 * while the target is near its axis (axis_hold_radius, released beyond axis_release_radius),
 * and always when pinned (a set position on the axis has no direction of its own, so a tilt
 * is made up for in joint 1's plane only); joint 1 stays within the model's follow_window
 * of where the goal put it (further round, the arm reaches in the plane at the window's
 * edge, and goes over to the far side of the axis once the target's plane, faced half a
 * turn over, is within half the window); a target in a landing leg's sector past the leg
 * distance is aimed at the nearer of the sector's edge and the leg distance in its plane
 * (leg_aim), kept until the other is 2 mm nearer; given_up says what was given up
 * (KIN_BRANCH_*). Then one step toward the next
 * corner or the aim, all joints in proportion: at the park speed unless following, the
 * transit speed until the arm is at its aim, then the working speed. The caller checks it
 * (kin_check_move from the last goal, MOTION_GOAL_MARGIN), asks motion_smaller for less
 * while it is refused, and tells motion_done what it sent. */
motion_speed_t motion_tick(motion_t *m, const float *target, bool pinned, float q_next[3]);
/* The step refused: a smaller one in q_next (half, a quarter, then joint 1 alone and joints
 * 2-3 alone); false when there is none left to offer (the arm then holds). */
bool motion_smaller(motion_t *m, float q_next[3]);
/* cffi:end */

/* The corner or aim the arm heads for now. */
static inline const float *motion_destination(const motion_t *m)
{
    return m->next_via < m->vias ? m->via[m->next_via] : m->aim;
}

/* The goal the application sent this tick (the proposal, a smaller step, or the last goal).
 * (Inline: every tick calls it.) */
static inline void motion_done(motion_t *m, const float q[3])
{
    const float *dest = motion_destination(m);
    const bool there = q[0] == dest[0] && q[1] == dest[1] && q[2] == dest[2];
    /* (held on purpose, by a step cap of 0, is not blocked) */
    m->blocked = !there && m->step_cap > 0.0f && q[0] == m->q[0] && q[1] == m->q[1] && q[2] == m->q[2];
    if (there) {
        if (m->next_via < m->vias) m->next_via++;
        else m->arrived = true;
    }
    for (int i = 0; i < 3; ++i) m->q[i] = q[i];
}

#ifdef __cplusplus
}
#endif

#endif /* MOTION_H */
