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

/* ---- decoding only the cells a render reads -----------------------------------------------
 * A codec that decodes by cells (codec.h decode_cells) can write only the voxels a composite
 * ray cast of a frame reads, given the frame's grid from a store's range tables (flags made):
 * the player and cdvr.render of a store chunk on cl do so (cdvr/visible.h). */

/* The cells (g's bricks) a composite render of g reads: a sample in a visible brick (flag
 * >= 128) reads the voxels of its cell and one voxel past it (trilinear interpolation's upper
 * apron), so the brick and its upper neighbours (d = 0..1 bricks per axis, bricks being at
 * least 4 voxels); with gradients (shading, gradient opacity) the central differences read one
 * voxel more each way (d = -1..1). need: 2 * nbricks bytes, the first half the result (1:
 * needed). Returns the cells needed. */
size_t cdvr_skip_cells_needed(const cdvr_skip_grid *g, int gradients, uint8_t *need);
/* A value for the cells not decoded, so that every sample the ray caster takes in an invisible
 * brick stays transparent as it is with the decoded voxels. Its lanes do sample there (runs end
 * past a brick, lanes sample on unlooked while others sample, skip_to stops short of a cube's
 * exit: raycast.cl), relying on such samples adding nothing; their corners hold the brick's
 * own values (its range) or, where not decoded, the fill. With lo .. hi spanning every
 * invisible brick's range, the fill lo keeps each interpolated value in lo .. hi, transparent
 * when every TF entry there is. Returns 0 when some entry there is visible (a TF transparent
 * in two separate runs of values, say): then the frame must be decoded whole. */
int cdvr_skip_transparent_fill(const cdvr_skip_grid *g, uint8_t *fill);
/* Writes fill into the voxels of a dense frame of g's volume in the cells with need 0 (spans
 * of such cells along x at a time). */
void cdvr_skip_fill_cells(uint8_t *frame, const cdvr_skip_grid *g, const uint8_t *need,
                          uint8_t fill);
/* The same for a tiled frame (codec.h CDVR_LAYOUT_TILED) whose tiles are g's bricks (shift 2):
 * a whole tile per cell. */
void cdvr_skip_fill_tiles(uint8_t *tiles, const cdvr_skip_grid *g, const uint8_t *need,
                          uint8_t fill);
/* After a decode by cells into a dense frame from range tables of bricks coarser than g's:
 * each brick the coarse tables made visible gets its exact range from the frame (its voxels
 * and upper apron were all decoded, cdvr_skip_cells_needed; the other bricks hold the fill,
 * and keep their coarse range), and the flags are made again for tf, so the render skips the
 * bricks only the coarse ranges kept visible: the same image with fewer samples. The frame is
 * ranged on `threads` threads (0: the online cores; cdvr_cpu_brick_ranges). Only when at
 * least 1/16 of the bricks are visible (else g stays as it is: the passes over the frame and
 * the grid would cost more than the samples they save). scratch: 2 * nbricks bytes. On
 * failure (CDVR_ERR_NOMEM) g is unchanged. */
cdvr_status cdvr_skip_refine(cdvr_skip_grid *g, const uint8_t *frame, const cdvr_tf *tf,
                             unsigned threads, uint8_t *scratch, cdvr_error *err);
/* 0 when the environment has CDVR_REFINE=0 (for comparison: the player and cdvr/visible.h
 * then keep the coarse grid), else 1. */
int cdvr_skip_refine_enabled(void);

/* Chessboard distance in bricks from each brick to the nearest brick with seed[b] != 0 (0 for
 * the seeds; at most 255, which also stands for "none"), by the two-pass 26-neighbour
 * chamfer, which is exact for the chessboard metric. */
void cdvr_skip_distance(const uint8_t *seed, uint8_t *dist, const size_t dims[3]);

/* ---- entry distances --------------------------------------------------------------------
 * Where a ray can first meet a visible brick, per screen tile, so the ray caster starts its
 * rays there instead of walking the empty space in front of the data. A ray that starts
 * outside the grid meets a visible brick first at a boundary brick (a visible brick with an
 * invisible or missing 26-neighbour: code 129 or on the grid's border): the entry list holds,
 * per cell of 2^cell_log2 bricks per axis, the grid box (voxel units, with a voxel of margin
 * for rounding) around the cell's boundary bricks. cdvr_skip_entry_tiles projects the boxes
 * with a camera: a tile's value is the least depth along the view axis of any box whose
 * screen footprint (the corners' hull, a pixel of margin) covers one of its pixel centres,
 * divided by the largest cosine of the tile's rays to the view axis: a lower bound of the ray
 * parameter t (world distance along the unit ray) of every visible sample of the tile's
 * rays. Samples before it lie in invisible bricks, so starting there skips only samples that
 * add nothing: the image is unchanged (sample counts may drop: the ray caster casts no ray of
 * a tile whose bound is +inf, not even its empty last segment). */
typedef struct cdvr_skip_entry {
    float *boxes;          /* 6 per box: grid lo x, y, z, hi x, y, z */
    size_t count, capacity;
    size_t vol_dims[3];
    uint64_t version;      /* +1 on each cdvr_skip_entry_make */
} cdvr_skip_entry;

/* The camera and the volume's placement, as the ray caster takes them (render.h): rays from
 * eye (perspective) along normalize(f + (sx aspect r - sy u) tan_half), or from
 * eye + (sx aspect r - sy u) ortho_half_height along f (orthographic), sx, sy the pixel
 * centre in [-1, 1] (y down); f, u, r orthonormal. A grid point g (voxel units) lies at world
 * origin + direction * (g * spacing), direction row-major. */
typedef struct cdvr_skip_view {
    double eye[3], f[3], u[3], r[3];
    double tan_half, aspect, ortho_half_height;
    int orthographic, width, height;
    double origin[3], direction[9], spacing[3];
} cdvr_skip_view;

/* The entry list of g's flags (which must be made) for cells of 2^cell_log2 bricks. */
cdvr_status cdvr_skip_entry_make(cdvr_skip_entry *e, const cdvr_skip_grid *g, unsigned cell_log2,
                                 cdvr_error *err);
void cdvr_skip_entry_free(cdvr_skip_entry *e);
/* Fills tiles (tiles_x * tiles_y, row by row; tile (x, y) holds pixels from
 * (tile_w x, tile_h y)) with the entry bounds of e for view v, +inf where no visible brick can
 * be met. Returns 0 and fills nothing when the bound does not apply: some corner of the volume
 * box is not in front of the eye (a camera inside or beside the volume). */
int cdvr_skip_entry_tiles(const cdvr_skip_entry *e, const cdvr_skip_view *v, int tile_w,
                          int tile_h, size_t tiles_x, size_t tiles_y, float *tiles);
/* The entry tiles as above, and in one pass the exit bounds: an upper bound of t of every
 * visible sample of the tile's rays (the greatest depth of the boxes covering it, divided by
 * the tile's smallest cosine to the view axis), -inf where no visible brick can be met. A
 * ray's last visible sample lies in a boundary brick or before one (the last visible brick it
 * crosses is followed by an invisible one or the grid's border), so samples after the bound
 * lie in invisible bricks. Returns as cdvr_skip_entry_tiles. */
int cdvr_skip_entry_exit_tiles(const cdvr_skip_entry *e, const cdvr_skip_view *v, int tile_w,
                               int tile_h, size_t tiles_x, size_t tiles_y, float *entry,
                               float *exit);

#endif
