/* Test harness: the firmware's command path (app.c's command_servos) over grids of start poses,
 * targets and tilts, its goals sent through the servo driver to servos that lag and slow. */
#include <stddef.h>
#include <stdint.h>

/* cffi:begin */
typedef struct {
    float *goals;          /* 3 per goal sent (rad), in order */
    uint32_t *goal_run;    /* the run of each */
    size_t cap_goals, n_goals;
    float *shafts;         /* 3 per sample of the servos' shafts (units, unrounded): after every 1 ms
                              step in which one moved */
    uint32_t *shaft_run;
    size_t cap_shafts, n_shafts;
    uint32_t refused;      /* runs whose route was refused */
    uint32_t readings;     /* status readings the driver took (each sent goal is followed by one) */
} grid_out_t;

/* The arm at `start` (a safe pose), the board tilted by each (roll, pitch) of `tilts`: for
 * each level-frame target, what the application does from engage on (its goal at the tilt,
 * else as from a level base; a clear route there; following the target) for `ticks` ticks,
 * then disengage (a route back to the park pose) for `ticks` more, its servos' shafts
 * lagging `lag_s` behind their profile at a supply of `volts` (as each servo reports it). A
 * run is one target at one tilt, both phases; out's arrays stop filling at their caps. */
void safety_grid(const float start[3], const float *targets, size_t n_targets, const float *tilts, size_t n_tilts,
                 uint32_t ticks, float lag_s, float volts, grid_out_t *out);
/* One servo of the harness: from `start` (units), goal k and Moving Speed k for the k-th 1 ms
 * step; shafts[k] where the shaft stands after it. */
void servo_model(float lag_s, float volts, const float *goals, const float *speeds, size_t n, float start,
                 float *shafts);
/* cffi:end */
