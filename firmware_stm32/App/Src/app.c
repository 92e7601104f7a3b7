/* The firmware application; see app.h. */
#include "app.h"

#include <math.h>
#include <string.h>

#include "fastmath.h"
#include "imu_mpu6050.h"
#include "messages.h"
#include "model_params.h"
#include "servo_map.h"

static const float PARK[3] = { MODEL_PARK_Q1, MODEL_PARK_Q2, MODEL_PARK_Q3 };

static uint32_t now_us(const app_t *app)
{
    return app->port->time_us(app->port->ctx);
}

/* The IMU answers and gave a usable sample within the last few ticks. */
static bool imu_usable(const app_t *app)
{
    return app->imu_ok && app->imu_stale < APP_IMU_STALE_TICKS;
}

static void try_imu(app_t *app)
{
    app->imu_ok = mpu_init(app->port, MODEL_MPU_ADDRESS);
    app->imu_retry_us = now_us(app);
    stab_reset(&app->stab);
}

void app_init(app_t *app, const port_t *port)
{
    static const uint8_t ids[SBUS_SERVOS] = { MODEL_SERVO1_ID, MODEL_SERVO2_ID, MODEL_SERVO3_ID };
    memset(app, 0, sizeof *app);
    app->port = port;
    llcp_rx_init(&app->link, MODEL_LINK_FRAME_GAP_MS, msg_expected_len);
    sbus_init(&app->bus, port, ids, MODEL_SERVO_BAUD);
    sbus_power(&app->bus, false);
    memcpy(app->q_cmd, PARK, sizeof app->q_cmd);   /* reported until the servos say where they are */
    kin_fk_ee(PARK, app->set_position);   /* engage without a set position holds the park point */
    app->set_on_axis = motion_on_axis(app->set_position);
    app->last_frame_us = app->last_heartbeat_us = app->link_ms_base_us = now_us(app);
    try_imu(app);
}

void app_request_tick(app_t *app)
{
    app->ticks_requested++;
}

/* ------------------------------------------------------------------ commands */

static void show_state(const app_t *app)
{
    app->port->led(app->port->ctx, 0, app->enabled);
    app->port->led(app->port->ctx, 1, app_faults(app) != 0);
}

/* The shafts watched afresh (tracking, behind): the readings before say nothing now. */
static void watch_afresh(app_t *app)
{
    track_reset(&app->track);
    app->behind = 0;
}

/* Servo power on or off; bench (on only): configured with the torque off, never moved by
 * the firmware on its own (app.h). Into or out of the bench while on: configured again, the
 * supply left on. */
static void set_enabled(app_t *app, bool on, bool bench)
{
    if (on == app->enabled && bench == app->bench) return;
    app->enabled = on;
    app->bench = bench;
    app->engaged = false;
    app->motion.started = false;   /* where the arm is comes from the servos' first readings */
    app->motion_refused = false;
    app->parked = false;
    app->jog = false;
    app->start_to = APP_START_PARK;
    if (on) {
        app->servo_config_failed = false;
        app->servo_reset = false;
        app->timing_fault = false;
    }
    watch_afresh(app);   /* readings from before a power cycle say nothing */
    if (bench) sbus_power_limp(&app->bus);
    else sbus_power(&app->bus, on);   /* off: the supply is cut before this returns */
    show_state(app);
}

/* A command refused, and why (the heartbeat's refusal). */
static void refuse(app_t *app, uint8_t why)
{
    app->refused = true;
    app->refusal = why;
}

static void taken(app_t *app)
{
    app->refused = false;
    app->refusal = MSG_REFUSAL_NONE;
}

/* Back to the park pose at park speed, by a route clear of limits, body and legs. */
static void disengage(app_t *app)
{
    app->engaged = false;
    if (app->motion.started && !motion_go(&app->motion, PARK)) app->motion_refused = true;   /* holds */
}

/* Head for target (level frame) at the current tilt, or as from a level base if the tilt
 * puts it out of reach: false (and flagged) if no route there is clear. */
static bool head_for(app_t *app, const float target[3])
{
    float p[3];
    stab_command_point(&app->stab, target, p);
    app->motion_refused = !motion_head_for(&app->motion, p, target);
    return !app->motion_refused;
}

static void on_set_position(app_t *app, const msg_set_position_t *m)
{
    const float p[3] = { m->x, m->y, m->z };
    float q[3];
    if (!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]))) {
        refuse(app, MSG_REFUSAL_NOT_FINITE);
        return;
    }
    /* a repeated set position (keep-alive) changes nothing, not even the last refusal; a new
     * one, engaged and past the park that engage begins with, needs a route now (during that
     * park it is only stored: the arm heads for it once parked, as for the set position
     * engage found) */
    const bool moved = memcmp(p, app->set_position, sizeof p) != 0;
    if (moved) taken(app);
    app->unreachable = !motion_goal_for(&app->motion, p, q);   /* from a level base, with the goals' margin */
    if (app->unreachable) return;
    if (moved && app->engaged && app->parked && !head_for(app, p)) {
        refuse(app, MSG_REFUSAL_NO_ROUTE);
        return;
    }
    memcpy(app->set_position, p, sizeof p);
    app->set_on_axis = motion_on_axis(p);
}

/* ------------------------------------------------------------------ service */

/* Why a service command (jog, torque) is refused now, or MSG_REFUSAL_NONE. */
static uint8_t service_refusal(const app_t *app)
{
    if (app->engaged) return MSG_REFUSAL_ENGAGED;
    if (app->flying) return MSG_REFUSAL_FLYING;
    if (!app->enabled) return MSG_REFUSAL_NOT_ENABLED;
    if (app->bus.state != SBUS_RUNNING) return MSG_REFUSAL_SERVOS_STARTING;
    return MSG_REFUSAL_NONE;
}

/* Torque off: the arm limp where it stands (the supply on, positions still read). */
static void go_limp(app_t *app)
{
    sbus_limp(&app->bus, true);
    app->motion.started = false;   /* moved by hand: starts again from the readings */
    app->parked = app->jog = false;
    watch_afresh(app);
}

/* Torque back on (the servos set up again, holding where they stand); motion then starts
 * from their readings towards start_to. */
static void torque_on(app_t *app, uint8_t start_to)
{
    sbus_limp(&app->bus, false);
    app->start_to = start_to;
    watch_afresh(app);
}

static void on_torque(app_t *app, bool on)
{
    const uint8_t why = service_refusal(app);
    if (why != MSG_REFUSAL_NONE) {
        refuse(app, why);
        return;
    }
    taken(app);
    if (on == app->bus.limp) {
        if (on) torque_on(app, APP_START_HOLD);
        else go_limp(app);
    }
}

/* The pose a jog asks for, from the arm's goal (or, limp, where it stands); false if the
 * joint or value is bad or the pose is not one the arm may rest at. */
static bool jog_pose(const app_t *app, const msg_jog_t *m, float q[3])
{
    uint16_t units[SBUS_SERVOS];
    const unsigned j = (unsigned)m->joint - 1u;
    if (j >= 3u || !isfinite(m->value) || m->mode > 1u) return false;
    if (app->bus.limp) {
        for (int i = 0; i < SBUS_SERVOS; ++i) units[i] = app->bus.servo[i].present_position;
        servo_units_to_joints(units, q);
    } else {
        memcpy(q, app->q_cmd, 3 * sizeof q[0]);
    }
    if (m->mode == 0u) {
        q[j] = m->value;
    } else {
        /* (the servo's own units: 0..1023 on an AX-12A, 0..4095 on an X-series servo) */
        const float units_max = (float)MODEL_DXL_POSITION_MAX;
        if (!(fabsf(m->value) <= units_max) || !servo_joints_to_units(q, units)) return false;
        const float goal = (float)units[j] + roundf(m->value);
        if (goal < 0.0f || goal > units_max) return false;
        units[j] = (uint16_t)goal;
        servo_units_to_joints(units, q);
    }
    return kin_check_move(q, q, MOTION_GOAL_MARGIN) == KIN_OK;
}

static void on_jog(app_t *app, const msg_jog_t *m)
{
    float q[3];
    uint8_t why = service_refusal(app);
    if (why == MSG_REFUSAL_NONE && !app->bus.limp && !app->motion.started) why = MSG_REFUSAL_SERVOS_STARTING;
    if (why == MSG_REFUSAL_NONE && !jog_pose(app, m, q)) why = MSG_REFUSAL_BAD_JOG;
    if (why != MSG_REFUSAL_NONE) {
        refuse(app, why);
        return;
    }
    if (app->bus.limp) {   /* torque on first; the jog starts from where the arm then stands */
        taken(app);
        memcpy(app->jog_goal, q, sizeof q);
        torque_on(app, APP_START_JOG);
        return;
    }
    if (!motion_go(&app->motion, q)) {
        refuse(app, MSG_REFUSAL_BAD_JOG);   /* no clear path there */
        return;
    }
    taken(app);
    app->motion_refused = false;
    app->jog = true;
    app->parked = false;
}

static void on_stream(app_t *app, const msg_stream_t *m)
{
    if (app->engaged) {
        refuse(app, MSG_REFUSAL_ENGAGED);
        return;
    }
    if (app->flying && (m->imu_every != 0u || m->servos != 0u)) {
        refuse(app, MSG_REFUSAL_FLYING);   /* the link is the flight's */
        return;
    }
    taken(app);
    app->stream_imu_every = m->imu_every;
    app->stream_imu_ticks = 0;
    app->stream_servos = m->servos != 0u;
    app->servo_reads_streamed = app->bus.status_reads;   /* from the next reading on */
}

/* ------------------------------------------------------------------ bench and flight */

/* Limp, at or on its way to a jogged or held pose, or about to be (the torque coming back on). */
static bool in_service(const app_t *app)
{
    return app->bus.limp || app->jog || app->start_to != APP_START_PARK;
}

/* Out of a service state: the torque on and to the park pose by a checked route (on the
 * bench, whose calibration is not trusted to park with: limp where it stands); false if the
 * arm was in none. */
static bool end_service(app_t *app)
{
    if (!in_service(app)) return false;
    if (app->bench) {
        if (!app->bus.limp) go_limp(app);
        return true;
    }
    if (app->bus.limp) torque_on(app, APP_START_PARK);   /* (motion starts from the readings) */
    app->start_to = APP_START_PARK;
    if (app->jog) {
        app->jog = false;
        disengage(app);
    }
    return true;
}

/* A message of the drone's flight controller (drone_attitude, drone_velocity) at `now`: the
 * drone may be flying, so no bench: a service state ends and the streams stop. */
static void drone_heard(app_t *app, uint32_t now)
{
    app->flying = true;
    app->last_drone_us = now;
    (void)end_service(app);
    app->stream_imu_every = 0;
    app->stream_servos = false;
}

/* The link silent for its timeout: an engaged arm, or one in a service state, parks with the
 * torque on (whoever held it there is gone). */
static void link_silent(app_t *app)
{
    if (app->engaged) disengage(app);
    else if (!end_service(app)) return;
    app->link_lost = true;
}

/* From the main loop: the drone's messages stopped for the link's silence timeout, no longer
 * flying; every frame stopped that long, link_silent. */
static void watch_link(app_t *app, uint32_t now)
{
    static const uint32_t SILENCE_US = MODEL_LINK_SILENCE_MS * 1000u;
    if (app->flying && now - app->last_drone_us > SILENCE_US) app->flying = false;
    if (now - app->last_frame_us > SILENCE_US) link_silent(app);
}

/* Why engage would be refused now, or MSG_REFUSAL_NONE: it needs the servos configured,
 * answering and error-free, the estimator settled on the IMU's samples and servos that
 * follow their goals. */
static uint8_t not_ready(const app_t *app)
{
    if (!app->enabled) return MSG_REFUSAL_NOT_ENABLED;
    if (!app->motion.started) return MSG_REFUSAL_SERVOS_STARTING;
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        const sbus_servo_t *s = &app->bus.servo[i];
        if (s->failed || s->last_error) return MSG_REFUSAL_SERVO_FAULT;
    }
    if (app->bus.refit || app->bus.refitting) return MSG_REFUSAL_SERVO_FAULT;
    if (!imu_usable(app) || app->stab.samples < MODEL_IMU_SETTLE_SAMPLES) return MSG_REFUSAL_IMU_NOT_READY;
    if (track_fault(&app->track)) return MSG_REFUSAL_SERVO_TRACKING;
    return MSG_REFUSAL_NONE;
}

/* Engage when ready (not_ready). The arm parks first if it has not since enable (the
 * working speed never moves it from where it hung), then heads for the set position by a
 * clear route. */
static void on_engage(app_t *app, bool on)
{
    taken(app);
    if (app->bench) {   /* nothing parks by the model's calibration: engage 0 goes limp */
        if (on) refuse(app, MSG_REFUSAL_BENCH);
        else (void)end_service(app);
        return;
    }
    if (app->bus.limp && app->enabled) {
        torque_on(app, APP_START_PARK);   /* the torque back on first: engage once parked */
        if (on) refuse(app, MSG_REFUSAL_SERVOS_STARTING);
        return;
    }
    if (!on) {
        if (app->engaged || app->jog) disengage(app);
        app->jog = false;
        return;
    }
    if (app->engaged) return;
    const uint8_t why = not_ready(app);
    if (why != MSG_REFUSAL_NONE) {
        refuse(app, why);
        return;
    }
    if (app->jog) {   /* from a jogged pose: park first, as after enable */
        app->jog = false;
        disengage(app);
    }
    if (app->parked && !head_for(app, app->set_position)) {
        refuse(app, MSG_REFUSAL_NO_ROUTE);
        return;
    }
    app->engaged = true;
    app->link_lost = false;
    app->servo_reset = false;
    app->stream_imu_every = 0;   /* the link and the main loop are the flight's */
    app->stream_servos = false;
}

/* enable: 0 off, 1 on (parks), 2 the bench (set_enabled). enable 1 on a running bench parks
 * from where the arm is, the servos left as they are (configured again, a limp servo's stale
 * goal would pull it there as its torque came on), but each set up again first, holding where
 * it stands with the full Torque Limit: the park is with the normal torque. */
static void on_enable(app_t *app, uint8_t on)
{
    const bool bench = on == 2u;
    if (bench && (app->engaged || app->flying)) {
        refuse(app, app->engaged ? MSG_REFUSAL_ENGAGED : MSG_REFUSAL_FLYING);
        return;
    }
    taken(app);
    if (app->bench && on != 0u && !bench && app->bus.state == SBUS_RUNNING) {
        app->bench = false;
        sbus_full_torque(&app->bus);
        app->motion.started = false;   /* from the readings once set up (start_motion) */
        app->parked = app->jog = false;
        torque_on(app, APP_START_PARK);
        return;
    }
    set_enabled(app, on != 0u, bench);
}

static bool send_payload(app_t *app, const uint8_t *payload, size_t len);

/* At once, whatever the state: the round trip is the measurement (a pong the link cannot
 * take is lost, as a ping can be). */
static void send_pong(app_t *app, const msg_ping_t *ping)
{
    const msg_pong_t pong = { .seq = ping->seq, .stamp_us = ping->stamp_us, .arrived_us = now_us(app) };
    uint8_t payload[MSG_PONG_SIZE];
    (void)send_payload(app, payload, msg_pong_pack(&pong, payload, sizeof payload));
}

static void on_frame(app_t *app, const uint8_t *payload, size_t len)
{
    msg_enable_t enable;
    msg_engage_t engage;
    msg_set_position_t set;
    msg_drone_attitude_t attitude;
    msg_drone_velocity_t velocity;
    msg_jog_t jog;
    msg_torque_t torque;
    msg_stream_t stream;
    msg_ping_t ping;
    if (len > 0 && payload[0] == MSG_HEARTBEAT_ID) {
        app->link_echoes++;   /* the board's own output come back: not the drone, not life */
        return;
    }
    if (msg_enable_unpack(payload, len, &enable)) {
        on_enable(app, enable.on);
    } else if (msg_engage_unpack(payload, len, &engage)) {
        on_engage(app, engage.on != 0);
    } else if (msg_set_position_unpack(payload, len, &set)) {
        on_set_position(app, &set);
    } else if (msg_drone_attitude_unpack(payload, len, &attitude)) {
        const uint32_t now = now_us(app);
        app->drone_attitudes++;
        drone_heard(app, now);
        (void)stab_drone_attitude(&app->stab, attitude.seq, attitude.stamp_us, attitude.roll, attitude.pitch, now);
    } else if (msg_drone_velocity_unpack(payload, len, &velocity)) {
        const float v_level[3] = { velocity.vx, velocity.vy, velocity.vz };
        const uint32_t now = now_us(app);
        app->drone_velocities++;
        drone_heard(app, now);
        (void)stab_drone_velocity(&app->stab, velocity.seq, velocity.stamp_us, v_level, now);
    } else if (msg_jog_unpack(payload, len, &jog)) {
        on_jog(app, &jog);
    } else if (msg_torque_unpack(payload, len, &torque)) {
        on_torque(app, torque.on != 0);
    } else if (msg_stream_unpack(payload, len, &stream)) {
        on_stream(app, &stream);
    } else if (msg_ping_unpack(payload, len, &ping)) {
        send_pong(app, &ping);
        return;   /* answered, but no sign of the drone's controller: keeps nothing alive */
    } else {
        app->commands_ignored++;
        return;
    }
    app->last_frame_us = now_us(app);   /* a frame sent to the arm: the link is alive */
}

/* A millisecond clock for the link receiver that wraps at 2^32 ms like llcp.h expects.
 * now_us / 1000 would jump back by 4 294 967 ms when the microsecond clock wraps, so a
 * frame arriving across the wrap would look older than the frame gap and be dropped. */
static uint32_t link_ms(app_t *app)
{
    const uint32_t whole_ms = (now_us(app) - app->link_ms_base_us) / 1000u;
    app->link_ms += whole_ms;
    app->link_ms_base_us += whole_ms * 1000u;
    return app->link_ms;
}

static void read_link(app_t *app)
{
    uint8_t chunk[64];
    size_t n, budget = APP_LINK_BYTES_PER_POLL;   /* the rest waits in the port's buffer */
    while (budget > 0 && (n = app->port->link_read(app->port->ctx, chunk,
                                                    budget < sizeof chunk ? budget : sizeof chunk)) > 0) {
        budget -= n;
        for (size_t i = 0; i < n; ++i) {
            if (llcp_rx_byte(&app->link, (char)chunk[i], link_ms(app)) == LLCP_RX_FRAME) {
                on_frame(app, app->link.payload, app->link.len);
            }
        }
    }
    (void)llcp_rx_poll(&app->link, link_ms(app));
}

/* ------------------------------------------------------------------ tick */

/* A tick without a usable sample: the attitude holds. */
static void imu_stale_tick(app_t *app)
{
    if (app->imu_stale < UINT16_MAX) app->imu_stale++;
    if (app->imu_stale == APP_IMU_STALE_TICKS) app->imu_retry_us = now_us(app);
}

/* A usable sample in *out? */
static bool sample_imu(app_t *app, mpu_sample_t *out)
{
    /* set the chip up again if it is gone or stopped sampling (asleep after a brown-out) */
    if (!imu_usable(app) && now_us(app) - app->imu_retry_us >= APP_IMU_RETRY_MS * 1000u) try_imu(app);
    if (!app->imu_ok) return false;
    if (!mpu_sample(app->port, MODEL_MPU_ADDRESS, out)) {
        app->imu_errors++;
        imu_stale_tick(app);   /* one I2C glitch is no fault; a chip gone is, in a few ticks */
        return false;
    }
    if (app->stream_imu_every && ++app->stream_imu_ticks >= app->stream_imu_every) {
        app->stream_imu_ticks = 0;   /* sent by app_poll, outside the tick */
        memcpy(app->imu_burst, out->burst, sizeof app->imu_burst);
        app->imu_burst_us = now_us(app);
        app->imu_raw_ready = true;
    }
    app->imu_saturated = out->saturated;
    if (!out->fresh || out->saturated) {
        imu_stale_tick(app);   /* no new sample, or one whose true value is unknown */
        return false;
    }
    app->imu_stale = 0;
    app->imu_samples_used++;
    return true;
}

/* ------------------------------------------------------------------ where the shafts may be */

/* A reading is its shaft rounded to a unit, and a goal is rounded to a unit when sent. */
#define ROUNDING (0.5f * MODEL_RAD_PER_UNIT)

/* Servo i stands at its reading q (rad), its goal there. */
static void shaft_stands(app_t *app, unsigned i, float q)
{
    app->shafts[app->shafts_now][0][i] = q - ROUNDING;
    app->shafts[app->shafts_now][1][i] = q + ROUNDING;
}

/* Servo i read since the last tick: its shaft stands between that reading and the goals that
 * may still pull it, the goal in force when it was read and the one before (which the
 * servo's own speed profile may still be on its way from). A shaft moves toward a profile
 * that moves toward its goal, so it stays there as long as the goals move no faster than the
 * servo can (step_cap). Known for a reading taken after the latest command went out, which
 * the tick before noted (before_*); any other reading leaves the span as it is. */
static void shaft_read(app_t *app, unsigned i)
{
    static const float GAP_MAX = (float)MODEL_SERVO_GAP_MAX * MODEL_RAD_PER_UNIT;
    const float r = servo_unit_to_joint(i, (float)app->bus.servo[i].present_position);
    const float a = app->q_cmd[i], b = app->before;
    const bool behind = fabsf(r - a) > GAP_MAX;   /* (servo_track.h) */
    app->behind = (uint8_t)((app->behind & ~(1u << i)) | (unsigned)behind << i);
    if (i != app->before_servo || app->bus.sync_writes - app->before_syncs != 1u) return;
    app->shafts[app->shafts_now][0][i] = fm_minf(r, fm_minf(a, b)) - ROUNDING;
    app->shafts[app->shafts_now][1][i] = fm_maxf(r, fm_maxf(a, b)) + ROUNDING;
}

/* Where the servos are, from their readings at configuration: the arm starts there and
 * parks. Until then (or if that pose is not safe to move from) nothing is commanded. */
static bool start_motion(app_t *app)
{
    uint16_t units[SBUS_SERVOS];
    float q[3];
    if (app->bus.state != SBUS_RUNNING || app->motion_refused || app->bus.refit || app->bus.refitting) return false;
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        if (!app->bus.servo[i].status_valid) return false;
        units[i] = app->bus.servo[i].present_position;
    }
    servo_units_to_joints(units, q);
    if (!motion_start(&app->motion, q)) {
        app->motion_refused = true;   /* a pose we cannot check a way out of: hold it */
        return false;
    }
    memcpy(app->q_cmd, q, sizeof q);
    for (unsigned i = 0; i < 3u; ++i) shaft_stands(app, i, q[i]);
    app->jog = app->start_to != APP_START_PARK;   /* (held or jogged: engage parks first) */
    const float *goal = app->start_to == APP_START_JOG ? app->jog_goal : app->start_to == APP_START_HOLD ? q : PARK;
    app->start_to = APP_START_PARK;
    if (!motion_go(&app->motion, goal)) app->motion_refused = true;
    return true;
}

motion_speed_t app_next_goal(motion_t *mo, const float *target, bool pinned, const float shafts[2][3],
                             float box[2][3], float q[3])
{
    const motion_speed_t speed = motion_tick(mo, target, pinned, q);
    /* Last line of defence, whatever motion.c proposed: every pose between where the shafts
     * may be and the new goal, whichever way the servos take it, passes the generated
     * checks; a refused goal is tried smaller, and the arm holds (the last goal again, which
     * the shafts were already checked on their way to) if none passes. The goal taken may pull
     * the shafts from now on: they may be anywhere in the box checked. */
    while (kin_check_span(shafts, q, MOTION_GOAL_MARGIN, box) != KIN_OK) {
        if (!motion_smaller(mo, q)) {
            memcpy(q, mo->q, 3 * sizeof q[0]);
            memcpy(box, shafts, 6 * sizeof shafts[0][0]);
            break;
        }
    }
    motion_done(mo, q);
    return speed;
}

/* The most a goal may move per tick: what the slowest servo can do at the supply it reports
 * (its no-load speed falls in proportion to Present Voltage); nothing while a shaft is
 * behind its goal (servo_track.h): the goals wait for it. */
static float step_cap(const app_t *app, bool behind)
{
    uint8_t lowest = UINT8_MAX;
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        const uint8_t v = app->bus.servo[i].present_voltage;
        if (v < lowest) lowest = v;
    }
    return behind ? 0.0f : MODEL_STEP_PER_DECIVOLT * (float)lowest;
}

/* This tick's goal, sent with the speed its step was for. */
static void command_servos(app_t *app)
{
    static const uint16_t SPEEDS[3][SBUS_SERVOS] = {
        { MODEL_PARK_SPEED, MODEL_PARK_SPEED, MODEL_PARK_SPEED },
        { MODEL_TRANSIT_SPEED, MODEL_TRANSIT_SPEED, MODEL_TRANSIT_SPEED },
        { MODEL_WORKING_SPEED, MODEL_WORKING_SPEED, MODEL_WORKING_SPEED },
    };
    motion_t *mo = &app->motion;
    if (app->bus.limp) {
        sbus_read(&app->bus);   /* nothing commanded; where the hands put it is read */
        return;
    }
    if (!mo->started && !start_motion(app)) return;
    float p[3], q[3];
    uint16_t units[SBUS_SERVOS];
    const bool following = app->engaged && app->parked;
    if (following) stab_command_point(&app->stab, app->set_position, p);
    for (unsigned fresh = app->track.fresh; fresh != 0u; fresh &= fresh - 1u) {
        shaft_read(app, (unsigned)__builtin_ctz(fresh));   /* (usually one) */
    }
    mo->step_cap = step_cap(app, app->behind != 0);
    const uint8_t now = app->shafts_now;   /* (the span in one buffer, the box after this goal in the other) */
    const motion_speed_t speed = app_next_goal(mo, following ? p : NULL, app->set_on_axis,
                                               (const float (*)[3])app->shafts[now], app->shafts[now ^ 1u], q);
    app->shafts_now = now ^ 1u;
    app->out_of_reach = following && mo->given_up != 0;
    if (!app->parked && mo->arrived && memcmp(mo->aim, PARK, sizeof PARK) == 0) {
        app->parked = true;
        if (app->engaged && !head_for(app, app->set_position)) app->engaged = false;   /* (flagged) */
    }
    if (!servo_joints_to_units(q, units)) return;   /* (limits and NaN, once more) */
    /* the servo read after this command may still be pulled by its goal before it */
    app->before_servo = app->bus.read_index;
    app->before = app->q_cmd[app->before_servo];
    app->before_syncs = app->bus.sync_writes;
    memcpy(app->q_cmd, q, sizeof q);
    sbus_command(&app->bus, units, SPEEDS[speed]);
}

/* Fault bits the heartbeat reports if they stood at any tick since the previous one: they
 * can come and go between two heartbeats (a saturated sample, a short IMU dropout that
 * parked the arm, a servo that stalled for a moment). app_faults()'s imu, imu_saturated and
 * servo_tracking bits, on their own: the whole word is only needed at heartbeats and LEDs. */
static void hold_faults(app_t *app, bool imu_usable_now, bool tracking_fault)
{
    const uint8_t behind = app->behind;
    if (!imu_usable_now) app->faults_since_heartbeat |= MSG_FAULT_IMU;
    if (app->imu_saturated) app->faults_since_heartbeat |= MSG_FAULT_IMU_SATURATED;
    if (tracking_fault) app->faults_since_heartbeat |= MSG_FAULT_SERVO_TRACKING;
    if (behind) {
        app->faults_since_heartbeat |= MSG_FAULT_SERVO_LAGGING;
        app->lagging_since_heartbeat |= behind;
    }
    if (app->motion.blocked) app->faults_since_heartbeat |= MSG_FAULT_MOTION_BLOCKED;
}

/* LEDs are for people: refreshed at a tenth of the tick rate (and at enable / disable). */
#define LED_EVERY_TICKS 10u

/* A servo found reset (servo_bus.c sets it up again, holding where it stands): the arm
 * parks from where it is now, the reset servos where they read, the others at their goals;
 * engage again once it is set up. */
static void watch_resets(app_t *app)
{
    uint16_t units[SBUS_SERVOS];
    float measured[3], q[3];
    if (app->bus.resets == app->servo_resets) return;
    app->servo_resets = app->bus.resets;
    app->servo_reset = true;
    app->engaged = false;
    app->parked = false;
    if (app->bench) {   /* no park by the model's calibration: limp (the reset servos with the rest) */
        go_limp(app);
        return;
    }
    if (!app->motion.started) return;   /* (starts from the readings anyway) */
    for (int i = 0; i < SBUS_SERVOS; ++i) units[i] = app->bus.servo[i].present_position;
    servo_units_to_joints(units, measured);
    for (int i = 0; i < SBUS_SERVOS; ++i) q[i] = app->bus.refit & (1u << i) ? measured[i] : app->q_cmd[i];
    if (!motion_start(&app->motion, q)) {
        app->motion_refused = true;   /* a pose we cannot check a way out of: hold it */
        return;
    }
    memcpy(app->q_cmd, q, sizeof q);
    for (unsigned i = 0; i < 3u; ++i) {
        if (app->bus.refit & (1u << i)) shaft_stands(app, i, q[i]);
    }
    if (!motion_go(&app->motion, PARK)) app->motion_refused = true;
}

static void tick(app_t *app)
{
    mpu_sample_t imu;
    const bool sampled = sample_imu(app, &imu);
    const uint32_t now = now_us(app);   /* after the IMU transfer: the sample's time */
    /* the clock must move from tick to tick, or no timeout works: cut the servo power */
    if (now != app->last_tick_us || app->ticks_run <= 1u) {
        app->clock_stalls = 0;
    } else if (++app->clock_stalls >= APP_CLOCK_STALL_TICKS && app->enabled) {
        set_enabled(app, false, false);
        app->timing_fault = true;
    }
    app->last_tick_us = now;
    if (sampled) stab_sample(&app->stab, imu.accel_g, imu.gyro_rad_s, now, app->engaged);
    const bool tracking = !app->bus.limp && track_update(&app->track, &app->bus, now);
    watch_resets(app);
    const bool usable = imu_usable(app);
    if (app->engaged && (!usable || tracking)) {
        disengage(app);   /* park: no attitude to stabilise with, or a servo not following */
    }
    if (app->enabled) command_servos(app);
    hold_faults(app, usable, tracking);
    if (++app->led_ticks >= LED_EVERY_TICKS) {
        app->led_ticks = 0;
        show_state(app);
    }
}

/* ------------------------------------------------------------------ heartbeat */

uint16_t app_faults(const app_t *app)
{
    uint16_t f = 0;
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        if (app->bus.servo[i].failed) f |= MSG_FAULT_SERVO_TIMEOUT;
        if (app->bus.servo[i].last_error) f |= MSG_FAULT_SERVO_ERROR;
    }
    if (app->servo_config_failed) f |= MSG_FAULT_SERVO_CONFIG;
    if (!imu_usable(app)) f |= MSG_FAULT_IMU;
    if (app->imu_saturated) f |= MSG_FAULT_IMU_SATURATED;
    if (track_fault(&app->track)) f |= MSG_FAULT_SERVO_TRACKING;
    if (app->behind) f |= MSG_FAULT_SERVO_LAGGING;
    if (app->link_lost) f |= MSG_FAULT_LINK_LOST;
    if (app->out_of_reach) f |= MSG_FAULT_OUT_OF_REACH;
    if (app->refused) f |= MSG_FAULT_COMMAND_REFUSED;
    if (app->servo_reset) f |= MSG_FAULT_SERVO_RESET;
    if (app->timing_fault) f |= MSG_FAULT_TIMING;
    if (app->motion_refused || app->motion.blocked) f |= MSG_FAULT_MOTION_BLOCKED;
    if (app->stab.link.rejected) f |= MSG_FAULT_DRONE_ATTITUDE_REJECTED;
    if (app->stab.vel.rejected) f |= MSG_FAULT_DRONE_VELOCITY_REJECTED;
    return f;
}

/* What the arm is doing (MSG_STATE_*). */
static uint8_t arm_state(const app_t *app)
{
    const motion_t *mo = &app->motion;
    if (!app->enabled) return MSG_STATE_OFF;
    if (app->bus.limp && app->bus.state == SBUS_RUNNING) return MSG_STATE_LIMP;   /* (the bench: once configured) */
    if (!mo->started) return MSG_STATE_STARTING;
    if (app->engaged && app->parked) return mo->arrived ? MSG_STATE_HOLDING : MSG_STATE_MOVING;
    if (app->jog) return mo->arrived ? MSG_STATE_JOGGED : MSG_STATE_JOGGING;
    return app->parked && mo->arrived ? MSG_STATE_PARKED : MSG_STATE_PARKING;
}

/* The shafts where the latest status read succeeded, NaN where none did (the supply off, a
 * servo not answering): never the goal in their place. */
static void read_shafts(const app_t *app, float p[3])
{
    uint16_t units[SBUS_SERVOS];
    float measured[3];
    for (int i = 0; i < SBUS_SERVOS; ++i) units[i] = app->bus.servo[i].present_position;
    servo_units_to_joints(units, measured);
    for (int i = 0; i < SBUS_SERVOS; ++i) {
        const sbus_servo_t *s = &app->bus.servo[i];
        p[i] = app->enabled && s->status_valid && !s->failed ? measured[i] : NAN;
    }
}

/* One LLCP frame to the drone (the heartbeat is the longest); false if the link cannot take it now. */
typedef char heartbeat_is_longest[(MSG_HEARTBEAT_SIZE >= MSG_IMU_RAW_SIZE && MSG_HEARTBEAT_SIZE >= MSG_SERVO_STATUS_SIZE) ? 1 : -1];
static bool send_payload(app_t *app, const uint8_t *payload, size_t len)
{
    char frame[LLCP_FRAME_SIZE(MSG_HEARTBEAT_SIZE)];
    const size_t n = llcp_encode_tx(payload, len, frame, sizeof frame);
    return n > 0 && app->port->link_write(app->port->ctx, (const uint8_t *)frame, n);
}

static void send_heartbeat(app_t *app)
{
    const llcp_rx_t *rx = &app->link;
    msg_heartbeat_t hb;
    float p[3];
    uint8_t payload[MSG_HEARTBEAT_SIZE];
    uint32_t timeouts = 0;
    for (int i = 0; i < SBUS_SERVOS; ++i) timeouts += app->bus.servo[i].timeouts;
    read_shafts(app, p);
    hb.seq = app->heartbeat_seq++;
    hb.uptime_ms = link_ms(app);
    hb.enabled = (uint8_t)(app->bench ? 2u : app->enabled ? 1u : 0u);   /* 2: the bench (enable 2) */
    hb.engaged = app->engaged;
    hb.unreachable = app->unreachable;
    hb.state = arm_state(app);
    hb.refusal = app->refusal;
    hb.faults = (uint16_t)(app_faults(app) | app->faults_since_heartbeat);
    hb.servo1_error = app->bus.servo[0].last_error;
    hb.servo2_error = app->bus.servo[1].last_error;
    hb.servo3_error = app->bus.servo[2].last_error;
    hb.set_x = app->set_position[0];
    hb.set_y = app->set_position[1];
    hb.set_z = app->set_position[2];
    hb.q1 = app->q_cmd[0];
    hb.q2 = app->q_cmd[1];
    hb.q3 = app->q_cmd[2];
    /* counters wrap at 16 bits on the wire */
    hb.link_frames_ok = (uint16_t)rx->frames_ok;
    hb.link_errors = (uint16_t)(rx->checksum_errors + rx->hex_errors + rx->length_errors
                                + rx->unknown_ids + rx->timeouts + rx->restarts);
    hb.link_echoes = (uint16_t)app->link_echoes;
    hb.servo_timeouts = (uint16_t)timeouts;
    hb.servo_resets = (uint16_t)app->servo_resets;
    hb.ticks_late = (uint16_t)app->ticks_late;
    hb.ticks_missed = (uint16_t)app->ticks_missed;
    hb.bus_state = (uint8_t)app->bus.state;
    hb.reset_cause = app->reset_cause;
    hb.last_fault = app->last_fault;
    hb.firmware = APP_FIRMWARE_VERSION;
    hb.model = MODEL_SHA32;
    const sbus_servo_t *s = app->bus.servo;
    hb.servo1_voltage = s[0].present_voltage;
    hb.servo1_temperature = s[0].present_temperature;
    hb.servo1_load = s[0].present_load;
    hb.servo2_voltage = s[1].present_voltage;
    hb.servo2_temperature = s[1].present_temperature;
    hb.servo2_load = s[1].present_load;
    hb.servo3_voltage = s[2].present_voltage;
    hb.servo3_temperature = s[2].present_temperature;
    hb.servo3_load = s[2].present_load;
    hb.lagging_joints = (uint8_t)(app->behind | app->lagging_since_heartbeat);
    hb.estimate_sources = stab_sources(&app->stab, now_us(app));
    hb.p1 = p[0];
    hb.p2 = p[1];
    hb.p3 = p[2];
    if (send_payload(app, payload, msg_heartbeat_pack(&hb, payload, sizeof payload))) {
        app->heartbeats_sent++;
        app->faults_since_heartbeat = 0;
        app->lagging_since_heartbeat = 0;
    } else {
        app->heartbeats_dropped++;
    }
}

static int16_t be16(const uint8_t *b)
{
    return (int16_t)(uint16_t)((unsigned)b[0] << 8 | b[1]);
}

/* The service streams, outside the tick: a frame the link cannot take now is dropped. */
static void send_streams(app_t *app)
{
    uint8_t payload[MSG_IMU_RAW_SIZE > MSG_SERVO_STATUS_SIZE ? MSG_IMU_RAW_SIZE : MSG_SERVO_STATUS_SIZE];
    if (app->imu_raw_ready) {
        const uint8_t *b = app->imu_burst + 1;   /* after INT_STATUS: ACCEL_XOUT_H .. GYRO_ZOUT_L */
        const msg_imu_raw_t m = {
            .seq = app->imu_raw_seq++, .stamp_us = app->imu_burst_us,
            .ax = be16(b), .ay = be16(b + 2), .az = be16(b + 4), .temperature = be16(b + 6),
            .gx = be16(b + 8), .gy = be16(b + 10), .gz = be16(b + 12),
            .fresh = (app->imu_burst[0] & MPU_INT_DATA_RDY) != 0u,
        };
        app->imu_raw_ready = false;
        (void)send_payload(app, payload, msg_imu_raw_pack(&m, payload, sizeof payload));
    }
    if (app->stream_servos && app->bus.status_reads != app->servo_reads_streamed) {
        const unsigned i = app->bus.last_read;
        const sbus_servo_t *s = &app->bus.servo[i];
        const msg_servo_status_t m = {
            .seq = app->servo_status_seq++, .stamp_us = now_us(app), .servo = (uint8_t)i,
            .goal = app->bus.goal[i], .position = s->present_position, .speed = s->present_speed,
            .load = s->present_load,
        };
        app->servo_reads_streamed = app->bus.status_reads;
        (void)send_payload(app, payload, msg_servo_status_pack(&m, payload, sizeof payload));
    }
}

/* ------------------------------------------------------------------ main loop */

void app_watch(app_t *app)
{
    /* the tick interrupt late by half a period: the tick runs from the clock */
    if (!app->tick_due && now_us(app) - app->last_tick_us >= MODEL_TICK_US + MODEL_TICK_US / 2u) {
        app->ticks_late++;
        app->faults_since_heartbeat |= MSG_FAULT_TIMING;
        app->tick_due = true;   /* app_poll runs it */
    }
}

bool app_healthy(const app_t *app)
{
    return app->clock_stalls == 0 && now_us(app) - app->last_tick_us < 2u * MODEL_TICK_US;
}

void app_poll(app_t *app)
{
    read_link(app);

    uint32_t requested = app->ticks_requested;
    if (requested != app->ticks_run || app->tick_due) {
        if (requested != app->ticks_run) app->ticks_missed += requested - app->ticks_run - 1u;
        app->ticks_run = requested;
        app->tick_due = false;
        tick(app);
    }

    sbus_poll(&app->bus);
    if (app->bus.state == SBUS_FAILED) {
        set_enabled(app, false, false);        /* a servo that cannot be configured: power off */
        app->servo_config_failed = true;
    }

    const uint32_t now = now_us(app);
    watch_link(app, now);
    if (now - app->last_heartbeat_us >= MODEL_HEARTBEAT_MS * 1000u) {
        app->last_heartbeat_us += MODEL_HEARTBEAT_MS * 1000u;
        if (now - app->last_heartbeat_us >= MODEL_HEARTBEAT_MS * 1000u) app->last_heartbeat_us = now;
        send_heartbeat(app);
    }
    send_streams(app);
}
