/* The fuzzers' own judge of a joint vector, written apart from the code generator: plain
 * geometry of the arm (joint 1 turns a vertical plane about the base axis; in it the upper
 * arm hangs from the shoulder, L1 below the base, at q2 from straight down, the forearm at
 * q2 + q3) and the servo's written facts (ARM_UNITS_PER_DEG: the AX-12A's 1023 position units
 * over 300 degrees, the X-series' 4096 a turn). The arm's numbers come from arm_spec.h, which
 * fuzz/run.py writes from the model file itself (tomllib), not through the generator. */
#ifndef PLAIN_ARM_H
#define PLAIN_ARM_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>

#include "arm_spec.h"

#define PLAIN_PI 3.14159265f
#define PLAIN_DEG (PLAIN_PI / 180.0f)

/* Inside the travel limits, strictly below the body plane (end effector and joint 3), and
 * inside the leg distance wherever the arm's plane is within the half-width of a leg; each
 * boundary loosened by `slack` (rad or mm) for float32 rounding. */
static inline bool plain_pose_safe(const float q[3], float slack)
{
    static const float lo[3] = ARM_JOINT_MIN_DEG, hi[3] = ARM_JOINT_MAX_DEG, legs[] = ARM_LEG_ANGLES_DEG;
    for (int i = 0; i < 3; ++i) {
        if (!(q[i] >= lo[i] * PLAIN_DEG - slack && q[i] <= hi[i] * PLAIN_DEG + slack)) return false;
    }
    const float elbow_rho = ARM_L2 * sinf(q[1]), elbow_z = -ARM_L1 - ARM_L2 * cosf(q[1]);
    const float ee_rho = elbow_rho + ARM_L3 * sinf(q[1] + q[2]), ee_z = elbow_z - ARM_L3 * cosf(q[1] + q[2]);
    if (!(elbow_z < ARM_BODY_Z + slack && ee_z < ARM_BODY_Z + slack)) return false;
    for (unsigned k = 0; k < sizeof legs / sizeof legs[0]; ++k) {
        const float d = fmodf(fabsf(q[0] - legs[k] * PLAIN_DEG), PLAIN_PI);   /* the plane either way round */
        const float off = d < PLAIN_PI - d ? d : PLAIN_PI - d;
        const bool near = off <= ARM_LEG_HALF_WIDTH_DEG * PLAIN_DEG - slack;
        if (near && !(fabsf(elbow_rho) < ARM_LEG_DISTANCE + slack && fabsf(ee_rho) < ARM_LEG_DISTANCE + slack)) {
            return false;
        }
    }
    return true;
}

/* The servo position of joint angle q (rad) of joint i, unrounded: zero + direction x the
 * angle in the servo's units. */
static inline float plain_units(int i, float q)
{
    static const float zero[3] = ARM_SERVO_ZERO, direction[3] = ARM_SERVO_DIRECTION;
    return zero[i] + direction[i] * q / PLAIN_DEG * ARM_UNITS_PER_DEG;
}

#endif
