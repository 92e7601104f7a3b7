#include "safety_grid.h"

#include <math.h>

#include "kinematics.h"
#include "model_params.h"
#include "servo_map.h"
#include "stabiliser.h"

size_t safety_grid(const float *targets, size_t n_targets, const float *tilts, size_t n_tilts,
                   float *q_out, uint16_t *units_out)
{
    static const float park[3] = { MODEL_PARK_Q1, MODEL_PARK_Q2, MODEL_PARK_Q3 };
    stab_t s;
    size_t commands = 0;
    stab_reset(&s);
    for (size_t t = 0; t < n_tilts; ++t) {
        est_set(&s.attitude, tilts[2 * t], tilts[2 * t + 1]);
        est_attitude_up(&s.attitude, s.up);   /* the stabiliser solves for its up direction (rate 0) */
        for (size_t i = 0; i < n_targets; ++i) {
            const size_t k = t * n_targets + i;
            float q[3];
            uint16_t units[3];
            q_out[3 * k] = q_out[3 * k + 1] = q_out[3 * k + 2] = NAN;
            if (stab_solve(&s, targets + 3 * i, park, q) != KIN_OK) continue;
            if (kin_check_joints(q) != KIN_OK || !servo_joints_to_units(q, units)) continue;
            for (int j = 0; j < 3; ++j) {
                q_out[3 * k + j] = q[j];
                units_out[3 * k + j] = units[j];
            }
            commands++;
        }
    }
    return commands;
}
