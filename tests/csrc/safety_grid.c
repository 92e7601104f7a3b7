/* The application's own command path (app.c's command_servos, engage and disengage as
 * app.c does them) on an app_t set up in memory: app.c is compiled into this file so its
 * static functions are reachable; nothing of it is re-implemented here. */
#include "safety_grid.h"

#include "app.c"

/* An enabled, configured arm standing (and commanded) at `start`, parked, the board tilted
 * by (roll, pitch): false if the application would not start from there. */
static bool arm_at(app_t *app, const float start[3], float roll, float pitch)
{
    memset(app, 0, sizeof *app);
    app->enabled = true;
    app->bus.state = SBUS_RUNNING;
    stab_reset(&app->stab);
    est_set(&app->stab.attitude, roll, pitch);
    est_attitude_up(&app->stab.attitude, app->stab.up);   /* the estimate's up direction (rate 0) */
    if (!motion_start(&app->motion, start)) return false;
    memcpy(app->q_cmd, start, sizeof app->q_cmd);
    app->parked = true;
    return true;
}

/* `ticks` of command_servos; each goal it hands the servo bus joins goals[]. */
static void run_ticks(app_t *app, uint32_t ticks, float *goals, uint32_t *run, size_t *n, size_t cap,
                      uint32_t run_no)
{
    for (uint32_t k = 0; k < ticks && *n < cap; ++k) {
        app->bus.command_pending = false;
        command_servos(app);
        if (!app->bus.command_pending) continue;
        memcpy(goals + 3 * *n, app->q_cmd, sizeof app->q_cmd);
        run[(*n)++] = run_no;
    }
}

size_t safety_grid(const float start[3], const float *targets, size_t n_targets, const float *tilts, size_t n_tilts,
                   uint32_t ticks, float *goals, uint32_t *run, size_t cap, uint32_t *refused)
{
    static app_t app;
    size_t n = 0;
    uint32_t run_no = 0;
    *refused = 0;
    for (size_t t = 0; t < n_tilts; ++t) {
        for (size_t i = 0; i < n_targets; ++i, ++run_no) {
            if (!arm_at(&app, start, tilts[2 * t], tilts[2 * t + 1])) return n;
            const float *level = targets + 3 * i;
            memcpy(app.set_position, level, sizeof app.set_position);
            app.set_on_axis = motion_on_axis(level);
            /* engage from parked: as on_engage once the arm is ready */
            if (!head_for(&app, app.set_position)) {
                ++*refused;
                continue;
            }
            app.engaged = true;
            run_ticks(&app, ticks, goals, run, &n, cap, run_no);
            /* engage 0 */
            disengage(&app);
            if (app.motion_refused) {
                ++*refused;
                continue;
            }
            run_ticks(&app, ticks, goals, run, &n, cap, run_no);
        }
    }
    return n;
}
