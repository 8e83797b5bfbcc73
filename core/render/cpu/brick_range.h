/* core/render/cpu/brick_range.h - the value range of every range brick of a dense u8 frame
 * (cdvr/bricks.h: brick g along an axis of N voxels holds voxels E*g .. min(E*g + E, N - 1),
 * E = 2^shift), as cdvr_range_compute gives for the whole frame, on several threads with
 * SSE2 min/max over whole rows. Internal to core: the CPU ray caster's empty-space skipping,
 * the OpenCL set-up of a dense frame on a CPU device (cl_render.c) and the player's refined
 * grids (player.c). */
#ifndef CDVR_RENDER_CPU_BRICK_RANGE_H
#define CDVR_RENDER_CPU_BRICK_RANGE_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"

/* minmax: 2 per brick (min, max), bricks x fastest, ceil(dims / E) per axis. threads: 0 for
 * the online cores (more than there are brick planes are not used; threads that fail to
 * start are replaced by the caller's). Same bytes for any thread count. CDVR_ERR_NOMEM when
 * the row buffers cannot be allocated. */
cdvr_status cdvr_cpu_brick_ranges(const uint8_t *frame, const size_t dims[3], unsigned shift,
                                  int threads, uint8_t *minmax, cdvr_error *err);

#endif
