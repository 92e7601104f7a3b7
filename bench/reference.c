/*
 * Plain reference implementations, the baseline of `make bench`: what the kinematics
 * look like written straight from the textbook (and the thesis) with libm, no code
 * generation. Same inputs and outputs as the generated functions.
 *
 * The geometry is held in a run-time struct (as generic code would hold it), so the
 * comparison also shows what folding the model's numbers in buys. bench/run.py fills
 * the REF_* macros from the model file, so no number is written here.
 */
#include <math.h>
#include <stdint.h>

typedef struct {
    float L1, L2, L3;
    float qmin[3], qmax[3];
    float body_z;
    float leg_angle[REF_NLEGS], leg_half_width, leg_distance;
} ref_arm_t;

static const ref_arm_t ARM = {
    REF_L1, REF_L2, REF_L3, REF_QMIN, REF_QMAX, REF_BODY_Z,
    REF_LEGS, REF_LEG_HALF_WIDTH, REF_LEG_DISTANCE,
};

static void dh_matrix(float theta, float alpha, float r, float d, float T[4][4])
{
    const float ct = cosf(theta), st = sinf(theta), ca = cosf(alpha), sa = sinf(alpha);
    const float M[4][4] = {
        { ct, -st * ca, st * sa, r * ct },
        { st, ct * ca, -ct * sa, r * st },
        { 0.0f, sa, ca, d },
        { 0.0f, 0.0f, 0.0f, 1.0f },
    };
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) T[i][j] = M[i][j];
}

static void matmul(float A[4][4], float B[4][4], float C[4][4])
{
    for (int i = 0; i < 4; ++i)
        for (int j = 0; j < 4; ++j) {
            float s = 0.0f;
            for (int k = 0; k < 4; ++k) s += A[i][k] * B[k][j];
            C[i][j] = s;
        }
}

/* FK by the 4x4 DH chain T1 T2 T3 [0 0 0 1]^T; also returns joint 3 (T1 T2 origin). */
static void ref_fk_points(const float q[3], float j3[3], float ee[3])
{
    const float half_pi = 1.57079633f;
    float T1[4][4], T2[4][4], T3[4][4], T12[4][4], T123[4][4];
    dh_matrix(-q[0], half_pi, 0.0f, -ARM.L1, T1);
    dh_matrix(-half_pi + q[1], 0.0f, ARM.L2, 0.0f, T2);
    dh_matrix(q[2], 0.0f, ARM.L3, 0.0f, T3);
    matmul(T1, T2, T12);
    matmul(T12, T3, T123);
    for (int i = 0; i < 3; ++i) {
        j3[i] = T12[i][3];
        ee[i] = T123[i][3];
    }
}

void ref_fk(const float q[3], float ee[3])
{
    float j3[3];
    ref_fk_points(q, j3, ee);
}

static float wrap_pi(float a)
{
    const float pi = 3.14159265f;
    while (a > pi) a -= 2.0f * pi;
    while (a <= -pi) a += 2.0f * pi;
    return a;
}

/* One textbook solve (thesis eqs. 3.8-3.10, errata applied): plane toward or away,
 * elbow sign; returns 0 if the target is out of reach. */
static int ref_solve(const float p[3], int toward, int elbow, float q[3])
{
    const float rho = sqrtf(p[0] * p[0] + p[1] * p[1]);
    const float u = toward ? rho : -rho, v = -(p[2] + ARM.L1);
    const float r = sqrtf(u * u + v * v);
    const float cg = (r * r + ARM.L2 * ARM.L2 - ARM.L3 * ARM.L3) / (2.0f * r * ARM.L2);
    const float cb = (ARM.L2 * ARM.L2 + ARM.L3 * ARM.L3 - r * r) / (2.0f * ARM.L2 * ARM.L3);
    if (!(cg >= -1.0f && cg <= 1.0f && cb >= -1.0f && cb <= 1.0f)) return 0;
    const float gamma = acosf(cg), beta = acosf(cb);
    const float t1 = atan2f(-p[1], p[0]);
    q[0] = toward ? t1 : wrap_pi(t1 + 3.14159265f);
    q[1] = wrap_pi(atan2f(u, v) - (float)elbow * gamma);
    q[2] = (float)elbow * (3.14159265f - beta);
    return 1;
}

/* 0 ok, 1 unreachable, 2 joint limit, 3 body, 4 leg: checks on the FK of the candidate. */
static int ref_status(const float q[3])
{
    for (int i = 0; i < 3; ++i)
        if (q[i] < ARM.qmin[i] || q[i] > ARM.qmax[i]) return 2;
    float j3[3], ee[3];
    ref_fk_points(q, j3, ee);
    if (!(ee[2] < ARM.body_z && j3[2] < ARM.body_z)) return 3;
    for (int k = 0; k < REF_NLEGS; ++k) {
        const float d = fabsf(wrap_pi(q[0] - ARM.leg_angle[k]));
        if (d <= ARM.leg_half_width || 3.14159265f - d <= ARM.leg_half_width) {
            if (sqrtf(ee[0] * ee[0] + ee[1] * ee[1]) >= ARM.leg_distance ||
                sqrtf(j3[0] * j3[0] + j3[1] * j3[1]) >= ARM.leg_distance) return 4;
        }
    }
    return 0;
}

/* Four separate solves, each checked, then the nearest valid to q_now. */
int ref_ik(const float p[3], const float q_now[3], float q_out[3])
{
    int best = -1;
    float best_d = 0.0f;
    for (int i = 0; i < 4; ++i) {
        float q[3];
        if (!ref_solve(p, i < 2, (i % 2) ? -1 : 1, q) || ref_status(q) != 0) continue;
        float d = 0.0f;
        for (int j = 0; j < 3; ++j) d += (q[j] - q_now[j]) * (q[j] - q_now[j]);
        if (best < 0 || d < best_d) {
            best = i;
            best_d = d;
            for (int j = 0; j < 3; ++j) q_out[j] = q[j];
        }
    }
    return best;
}

/* Direct form I biquad with coefficient arrays, as a generic library would do it. */
static float ref_b[3] = REF_ACCEL_B;
static float ref_a[3] = REF_ACCEL_A;

float ref_biquad_step(float hist[4], float x)
{
    const float y = (ref_b[0] * x + ref_b[1] * hist[0] + ref_b[2] * hist[1]
                     - ref_a[1] * hist[2] - ref_a[2] * hist[3]) / ref_a[0];
    hist[1] = hist[0];
    hist[0] = x;
    hist[3] = hist[2];
    hist[2] = y;
    return y;
}

/* The stabiliser tick written plainly from the thesis (errata applied): raw counts scaled,
 * six DF1 biquads, the complementary filter with libm, the target turned into the base
 * frame, ref_ik, and servo units. State between ticks in a static struct. */
static float ref_gb[3] = REF_GYRO_B;
static float ref_ga[3] = REF_GYRO_A;
static const float mount[3][3] = REF_MOUNT;
static const float units_zero[3] = REF_SERVO_ZERO, units_dir[3] = REF_SERVO_DIR;

static float biquad(const float b[3], const float a[3], float h[4], float x)
{
    const float y = (b[0] * x + b[1] * h[0] + b[2] * h[1] - a[1] * h[2] - a[2] * h[3]) / a[0];
    h[1] = h[0];
    h[0] = x;
    h[3] = h[2];
    h[2] = y;
    return y;
}

static struct {
    int started;
    float acc_h[3][4], gyro_h[3][4];
    float roll, pitch;
    float q[3];
} tick_state;

static int ref_tick(const int32_t raw[6], const float target[3], uint32_t units[3])
{
    float acc_imu[3], gyro_imu[3], acc[3], gyro[3], p[3];
    for (int i = 0; i < 3; ++i) {
        acc_imu[i] = biquad(ref_b, ref_a, tick_state.acc_h[i], (float)raw[i] * REF_ACCEL_SCALE);
        gyro_imu[i] = biquad(ref_gb, ref_ga, tick_state.gyro_h[i], (float)raw[3 + i] * REF_GYRO_SCALE);
    }
    for (int i = 0; i < 3; ++i) {
        acc[i] = mount[i][0] * acc_imu[0] + mount[i][1] * acc_imu[1] + mount[i][2] * acc_imu[2];
        gyro[i] = mount[i][0] * gyro_imu[0] + mount[i][1] * gyro_imu[1] + mount[i][2] * gyro_imu[2];
    }
    const float acc_roll = atan2f(acc[1], acc[2]);
    const float acc_pitch = atan2f(-acc[0], sqrtf(acc[1] * acc[1] + acc[2] * acc[2]));
    if (!tick_state.started) {
        tick_state.roll = acc_roll;
        tick_state.pitch = acc_pitch;
        tick_state.started = 1;
    }
    const float sr = sinf(tick_state.roll), cr = cosf(tick_state.roll);
    const float sp = sinf(tick_state.pitch), cp = cosf(tick_state.pitch);
    const float roll_rate = gyro[0] + (gyro[1] * sr + gyro[2] * cr) * sp / fmaxf(cp, 0.01f);
    const float pitch_rate = gyro[1] * cr - gyro[2] * sr;
    tick_state.roll = REF_W * (tick_state.roll + roll_rate * REF_DT) + (1.0f - REF_W) * acc_roll;
    tick_state.pitch = REF_W * (tick_state.pitch + pitch_rate * REF_DT) + (1.0f - REF_W) * acc_pitch;
    /* p_base = (Ry(pitch) Rx(roll))^T target */
    const float r2 = tick_state.roll, p2 = tick_state.pitch;
    const float Rx[3][3] = { { 1, 0, 0 }, { 0, cosf(r2), -sinf(r2) }, { 0, sinf(r2), cosf(r2) } };
    const float Ry[3][3] = { { cosf(p2), 0, sinf(p2) }, { 0, 1, 0 }, { -sinf(p2), 0, cosf(p2) } };
    float R[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
            R[i][j] = 0.0f;
            for (int k = 0; k < 3; ++k) R[i][j] += Ry[i][k] * Rx[k][j];
        }
    for (int i = 0; i < 3; ++i) p[i] = R[0][i] * target[0] + R[1][i] * target[1] + R[2][i] * target[2];
    float q[3];
    if (ref_ik(p, tick_state.q, q) < 0) return 0;
    for (int i = 0; i < 3; ++i) {
        tick_state.q[i] = q[i];
        units[i] = (uint32_t)lroundf(units_zero[i] + units_dir[i] * q[i] * REF_UNITS_PER_RAD);
    }
    return 1;
}

/* n ticks over raw (n x 6 counts); bench/run.py divides the count by n. */
int ref_run(const int32_t *raw, uint32_t n, const float target[3], uint32_t units[3])
{
    int ok = 1;
    for (uint32_t k = 0; k < n; ++k) ok &= ref_tick(raw + 6 * k, target, units);
    return ok;
}
