/* cdvr/skip.h - empty-space skipping on the host: the value range of every range brick of a
 * frame (store.h's range bricks: cubes of 2^shift voxels plus the upper apron trilinear
 * interpolation reads) and, for a transfer function, the per-brick bytes the ray caster walks
 * (kernels/render/raycast.cl). Plain C with no device, so a pipeline thread can prepare the
 * next frame's grid while the current one renders; the OpenCL renderer uploads it
 * (cdvr_cl_setup_grid) or fills it from its own min/max kernel (cdvr_cl_setup).
 *
 * Flags, one byte per brick: a brick is visible when some value in [min, max] has alpha > 0
 * in the TF's table. An invisible brick stores d, its chessboard distance (in bricks, capped
 * at CDVR_SKIP_REACH_MAX) to the nearest visible brick: the cube of bricks within d - 1 of it
 * is all invisible and a ray jumps it in one step. A visible brick stores 128 + d, d its
 * distance to the nearest invisible brick: the cube within d - 1 is all visible and is
 * sampled without further look-ups. Bricks beyond the grid count as invisible. The visible
 * box is the grid-coordinate box (in voxels) around the visible bricks, with faces on the
 * grid's border moved to +-infinity (samples beyond the volume are clamped into the border
 * bricks); lo > hi when nothing is visible. */
#ifndef CDVR_SKIP_H
#define CDVR_SKIP_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/tf.h"

#define CDVR_SKIP_REACH_MAX 127

typedef struct cdvr_skip_grid {
    unsigned shift;               /* bricks of 2^shift voxels */
    size_t vol_dims[3];
    size_t dims[3], nbricks;      /* bricks per axis: ceil(vol_dims / 2^shift) */
    uint8_t *minmax;              /* 2 * nbricks: min, max per brick (x fastest) */
    uint8_t *flags;               /* nbricks (see above) */
    uint8_t *scratch;             /* 2 * nbricks, for the distance transforms */
    uint8_t tf_visible[256];      /* alpha > 0 per TF entry, as the flags were made */
    int flags_valid;              /* flags match minmax and tf_visible */
    size_t bricks_visible;
    float visible_lo[3], visible_hi[3];
} cdvr_skip_grid;

/* Allocates the grid of a volume of vol_dims (minmax left undefined). */
cdvr_status cdvr_skip_grid_init(cdvr_skip_grid *g, const size_t vol_dims[3], unsigned shift,
                                cdvr_error *err);
void cdvr_skip_grid_free(cdvr_skip_grid *g);
/* Marks minmax as changed (its flags are then made again). */
void cdvr_skip_grid_touch(cdvr_skip_grid *g);
/* minmax from a dense u8 frame of vol_dims voxels. */
cdvr_status cdvr_skip_minmax_from_frame(cdvr_skip_grid *g, const uint8_t *frame,
                                        cdvr_error *err);
/* The flags, bricks_visible and visible box for tf, unless they are valid for the same set of
 * TF entries with alpha > 0 already. Returns 1 if the flags were made again. */
int cdvr_skip_flags(cdvr_skip_grid *g, const cdvr_tf *tf);
/* Flags as above from g's ranges for the codes whose visible_entry is not 0 (e.g. the ray
 * caster's iso skipping: the code floor(iso code), cl_render.c) into flags (nbricks bytes),
 * with g->scratch as scratch; g's own flags, count and box stay as they are. */
void cdvr_skip_flags_into(cdvr_skip_grid *g, const uint8_t visible_entry[256], uint8_t *flags);

/* The minmax, flags, bricks_visible and visible box of fine (a grid of the same volume whose
 * bricks are 2^(coarse shift - fine shift) times smaller per axis) from coarse, whose flags
 * must be made: each fine brick takes its coarse brick's range and state, and a distance that
 * is exact for the coarse cube it lies in (so fine is as conservative as coarse: the ray
 * caster skips exactly the samples it would skip with coarse bricks). CDVR_ERR_ARG when the
 * grids do not fit. */
cdvr_status cdvr_skip_grid_expand(const cdvr_skip_grid *coarse, cdvr_skip_grid *fine,
                                  cdvr_error *err);

/* Chessboard distance in bricks from each brick to the nearest brick with seed[b] != 0 (0 for
 * the seeds; at most 255, which also stands for "none"), by the two-pass 26-neighbour
 * chamfer, which is exact for the chessboard metric. */
void cdvr_skip_distance(const uint8_t *seed, uint8_t *dist, const size_t dims[3]);

#endif
