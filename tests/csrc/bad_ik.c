/* See bad_ik.h. The generated kinematics.c is compiled here with its kin_ik_branch renamed,
 * and kin_ik_branch wraps it. */
#include "bad_ik.h"

#define kin_ik_branch generated_kin_ik_branch
#include "kinematics.c"
#undef kin_ik_branch

unsigned kin_ik_branch(const float p[3], const float from[3], float elbow, bool hold_q1, float q_out[3],
                       float next[3]);

static bad_ik_kind_t bad_kind = BAD_IK_NONE;

void bad_ik_set(bad_ik_kind_t kind)
{
    bad_kind = kind;
}

static float wrapped(float a)
{
    const float pi = 3.14159265f;
    return a > pi ? a - 2.0f * pi : (a < -pi ? a + 2.0f * pi : a);
}

unsigned kin_ik_branch(const float p[3], const float from[3], float elbow, bool hold_q1, float q_out[3],
                       float next[3])
{
    const unsigned flags = generated_kin_ik_branch(p, from, elbow, hold_q1, q_out, next);
    switch (bad_kind) {
    case BAD_IK_NONE:
        return flags;
    case BAD_IK_NAN:
        q_out[0] = q_out[1] = q_out[2] = nanf("");
        break;
    case BAD_IK_LIMIT:
        q_out[1] = 2.3f;
        break;
    case BAD_IK_LEG:
        q_out[0] = 0.78539816f;
        q_out[1] = 1.57079633f;
        q_out[2] = 0.0f;
        break;
    case BAD_IK_BODY:
        q_out[0] = 0.0f;
        q_out[1] = 1.91986218f;
        q_out[2] = 1.04719755f;
        break;
    case BAD_IK_FAR_BRANCH:
        q_out[0] = wrapped(q_out[0] + 3.14159265f);
        q_out[1] = -q_out[1];
        q_out[2] = -q_out[2];
        break;
    }
    return 0u;   /* (next: the generated answer's, so the branch followed stays the true one) */
}
