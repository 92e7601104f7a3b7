/* Test harness: the firmware's target-to-command path over a grid of targets and tilts. */
#include <stddef.h>
#include <stdint.h>

/* cffi:begin */
/* For each tilt (roll, pitch) and each level-frame target: the stabiliser's solve from the
 * parked pose, then the same last checks the application applies before a SYNC_WRITE.
 * q_out[3 k ..] gets the joints that would be commanded, or NaN when none would be;
 * units_out[3 k ..] their servo units. k = tilt * n_targets + target. Returns the number of
 * commands. */
size_t safety_grid(const float *targets, size_t n_targets, const float *tilts, size_t n_tilts,
                   float *q_out, uint16_t *units_out);
/* cffi:end */
