#include "safety_grid.h"

#include <string.h>

#include "app.h"
#include "kinematics.h"
#include "model_params.h"
#include "motion.h"
#include "servo_map.h"
#include "stabiliser.h"

/* One tick as app.c's command_servos runs it: app_next_goal, then the servo map. */
static void command(motion_t *m, const float *target, bool pinned, float sent[3], float *goals, uint32_t *run,
                    size_t *n, size_t cap, uint32_t run_no)
{
    float q[3];
    uint16_t units[3];
    (void)app_next_goal(m, target, pinned, sent, q);
    if (!servo_joints_to_units(q, units) || *n >= cap) return;
    memcpy(sent, q, sizeof q);
    memcpy(goals + 3 * *n, q, sizeof q);
    run[(*n)++] = run_no;
}

size_t safety_grid(const float start[3], const float *targets, size_t n_targets, const float *tilts, size_t n_tilts,
                   uint32_t ticks, float *goals, uint32_t *run, size_t cap, uint32_t *refused)
{
    static const float park[3] = { MODEL_PARK_Q1, MODEL_PARK_Q2, MODEL_PARK_Q3 };
    stab_t s;
    size_t n = 0;
    uint32_t run_no = 0;
    *refused = 0;
    stab_reset(&s);
    for (size_t t = 0; t < n_tilts; ++t) {
        est_set(&s.attitude, tilts[2 * t], tilts[2 * t + 1]);
        est_attitude_up(&s.attitude, s.up);   /* the estimate's up direction (rate 0) */
        for (size_t i = 0; i < n_targets; ++i, ++run_no) {
            const float *level = targets + 3 * i;
            motion_t m;
            float p[3], sent[3];
            if (!motion_start(&m, start)) return n;
            memcpy(sent, start, sizeof sent);
            /* engage: as app.c's head_for */
            stab_command_point(&s, level, p);
            if (!motion_head_for(&m, p, level)) {
                ++*refused;
                continue;
            }
            for (uint32_t k = 0; k < ticks; ++k) command(&m, p, motion_on_axis(level), sent, goals, run, &n, cap, run_no);
            /* disengage */
            if (!motion_go(&m, park)) {
                ++*refused;
                continue;
            }
            for (uint32_t k = 0; k < ticks; ++k) command(&m, NULL, false, sent, goals, run, &n, cap, run_no);
        }
    }
    return n;
}
