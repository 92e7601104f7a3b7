/* Test build: the generated kinematics with the followed-branch IK (kin_ik_branch, the one
 * motion.c asks every tick while the arm follows its target) able to return bad poses on
 * demand, so the tests can show that what the firmware checks after the IK, in app.c and
 * the servo map, keeps every one of them off the servo bus. */
#ifndef BAD_IK_H
#define BAD_IK_H

/* cffi:begin */
typedef enum {
    BAD_IK_NONE = 0,         /* the generated IK's own answer */
    BAD_IK_NAN = 1,          /* every joint NaN */
    BAD_IK_LIMIT = 2,        /* the IK's answer with joint 2 past its limit */
    BAD_IK_LEG = 3,          /* reaching out (138.5 mm) in a leg's sector (joint 1 at 45 deg) */
    BAD_IK_BODY = 4,         /* the end effector above the body plane */
    BAD_IK_FAR_BRANCH = 5    /* the IK's answer on the far branch: joint 1 half a turn round,
                                joints 2 and 3 mirrored (the same point, reached backwards) */
} bad_ik_kind_t;

/* From now on kin_ik_branch answers with this kind of pose (and no flags). */
void bad_ik_set(bad_ik_kind_t kind);
/* cffi:end */

#endif
