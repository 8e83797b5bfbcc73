/* cdvr/bricks.h - brick geometry: how a volume is split into bricks (store bricks) and into the
 * small range bricks that empty-space skipping uses, and the copies between a frame and a brick.
 *
 * Pure geometry on dims and voxel boxes, with no store, codec or renderer behind it: the
 * encoder (core/store/encode.c), the store reader, the player, the skipping grids
 * (core/render/skip.c) and the MPI brick plan all use the same rules from here
 * (core/base/bricks.c, core/base/ranges.c).
 *
 * Store bricks. Along an axis of N voxels split into n bricks, brick i owns the cells
 * [c_i, c_{i+1}) with c_i = floor(i (N-1) / n) and holds the voxels c_i .. c_{i+1}: neighbours
 * share their boundary voxel (the one-voxel overlap trilinear sampling needs), which the lower
 * brick owns (assembled volumes take its value there, and encode-time errors count it there);
 * N = 1 gives one voxel. Bricks are numbered x fastest, then y, then z, from 0.
 *
 * Range bricks. For empty-space skipping the encoder records, per chunk and per timestep of
 * it, the range of the decoded values of each range brick: along each axis of N voxels, range
 * brick g (from 0) holds voxels E*g .. min(E*g + E, N - 1) with E = 2^shift, i.e. its cube plus
 * the upper one-voxel apron trilinear interpolation reads (the ray caster's skipping bricks
 * have shift CDVR_RANGE_SHIFT; stores record 8^3 bricks by default, whose ranges hold those of
 * the eight 4^3 bricks inside, cdvr_range_expand). The volume has ceil(N / E) of them per axis (cdvr_range_grid). The
 * chunk of store brick b holds the window of range bricks that meet the voxels b owns
 * (cdvr_brick_owned; cdvr_range_window), each with its range over those voxels; a whole range
 * brick's range is the smallest min and largest max over the store bricks it meets
 * (cdvr_range_merge), which is exactly its range in the assembled volume. Table layout: per
 * frame of the chunk (count of them), per window brick (x fastest, then y, z), two bytes: min,
 * max.
 */
#ifndef CDVR_BRICKS_H
#define CDVR_BRICKS_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"

#define CDVR_RANGE_SHIFT 2 /* the finest range bricks, 4^3 voxels (plus apron): the ray caster's
                              skipping bricks, and the tables of stores written before 2026-12 */
#define CDVR_RANGE_SHIFT_DEFAULT 3 /* tables the encoder writes by default: 8^3 bricks */
#define CDVR_RANGE_SHIFT_MAX 6     /* 64^3 bricks */
#define CDVR_RANGE_ZSTD_LEVEL 19   /* tables are small: the slowest level costs little */

/* ---- store bricks --------------------------------------------------------------------------- */

/* Voxel box of brick b of a bricks[0] x bricks[1] x bricks[2] grid over vol_dims: first voxel
 * lo[3] and dims[3] (the rule above). Returns 0 (lo, dims unspecified) if the grid is invalid (a
 * count of 0, more bricks than cells along an axis with more than one voxel, more than one
 * brick along an axis of one voxel) or b is not below the brick count. */
int cdvr_brick_box(const size_t vol_dims[3], const size_t bricks[3], size_t b, size_t lo[3],
                   size_t dims[3]);
/* The voxels brick b owns: its box without the first voxel along each axis where it starts
 * after voxel 0 (that one belongs to the brick below). The boxes of all bricks of a grid are
 * disjoint and cover the volume. Returns 0 as cdvr_brick_box does. */
int cdvr_brick_owned(const size_t vol_dims[3], const size_t bricks[3], size_t b, size_t lo[3],
                     size_t dims[3]);

/* Copies a brick's voxels (dims, first voxel lo; x fastest) into a u8 frame of vol_dims. */
void cdvr_brick_place(uint8_t *frame, const size_t vol_dims[3], const uint8_t *brick,
                      const size_t lo[3], const size_t dims[3]);
/* Copies the box (first voxel lo, dims) of a u8 frame of vol_dims out into brick. */
void cdvr_brick_extract(const uint8_t *frame, const size_t vol_dims[3], const size_t lo[3],
                        const size_t dims[3], uint8_t *brick);

/* ---- range bricks --------------------------------------------------------------------------- */

/* Range bricks per axis of a volume. */
void cdvr_range_grid(const size_t vol_dims[3], unsigned shift, size_t n[3]);
/* Window of range bricks meeting the voxel box lo .. lo + bd - 1: first brick g0 and counts n
 * per axis. */
void cdvr_range_window(const size_t vol_dims[3], const size_t lo[3], const size_t bd[3],
                       unsigned shift, size_t g0[3], size_t n[3]);
/* Bytes of one frame's window table: 2 * n0 * n1 * n2. */
size_t cdvr_range_window_bytes(const size_t vol_dims[3], const size_t lo[3],
                               const size_t bd[3], unsigned shift);
/* Window table of one frame of the voxel box (first voxel lo, bd voxels per axis) into out.
 * voxels points at the box's first voxel; rows and planes of the box are row_stride and
 * plane_stride bytes apart. */
cdvr_status cdvr_range_compute(const uint8_t *voxels, size_t row_stride, size_t plane_stride,
                               const size_t vol_dims[3], const size_t lo[3], const size_t bd[3],
                               unsigned shift, uint8_t *out, cdvr_error *err);
/* Folds a window table into the grid's table (2 bytes per brick of the grid, preset to
 * min 255, max 0): min of the mins, max of the maxes. */
void cdvr_range_merge(const uint8_t *window, const size_t g0[3], const size_t n[3],
                      const size_t grid[3], uint8_t *grid_minmax);


/* Compact stored form of a table of n bytes (n even): zstd (level CDVR_RANGE_ZSTD_LEVEL, one
 * frame that records its content size) of its planar form, the n/2 mins then the n/2 widths
 * (max - min) mod 256. out_cap >= cdvr_range_pack_bound(n) (0 on overflow). */
size_t cdvr_range_pack_bound(size_t n);
cdvr_status cdvr_range_pack(const uint8_t *table, size_t n, uint8_t *out, size_t out_cap,
                            size_t *out_n, cdvr_error *err);
/* Undoes cdvr_range_pack: exactly expect bytes into table; anything else (a frame claiming
 * another size, corrupt input) -> CDVR_ERR_CORRUPT. */
cdvr_status cdvr_range_unpack(const uint8_t *in, size_t n, uint8_t *table, size_t expect,
                              cdvr_error *err);

/* A grid table of range bricks 2^factor_log2 times coarser per axis spread over a finer grid:
 * fine brick (x, y, z) takes coarse brick (x, y, z) >> factor_log2. Each fine range brick's
 * voxels (with its apron) lie in its coarse brick's, so its range is widened, never narrowed:
 * skipping with it stays conservative. */
void cdvr_range_expand(const uint8_t *coarse, const size_t coarse_dims[3], unsigned factor_log2,
                       uint8_t *fine, const size_t fine_dims[3]);

#endif
