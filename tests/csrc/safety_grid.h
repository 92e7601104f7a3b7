/* Test harness: the firmware's command path (app.c's command_servos) over grids of start poses, targets and tilts. */
#include <stddef.h>
#include <stdint.h>

/* cffi:begin */
/* The arm at `start` (a safe pose), the board tilted by each (roll, pitch) of `tilts`: for
 * each level-frame target, what the application does from engage on (its goal at the tilt,
 * else as from a level base; a clear route there; following the target) for `ticks` ticks,
 * then disengage (a route back to the park pose) for `ticks` more. Every goal the
 * application would send, after its last check, goes to goals[3 k ..] with the run's
 * number in run[k] (a run is one target at one tilt, both phases). Stops at `cap` goals.
 * Returns the number of goals written; *refused counts runs whose route was refused. */
size_t safety_grid(const float start[3], const float *targets, size_t n_targets, const float *tilts, size_t n_tilts,
                   uint32_t ticks, float *goals, uint32_t *run, size_t cap, uint32_t *refused);
/* cffi:end */
