/* cdvr/brick_cache.h - the brick cache and level of detail (DESIGN.md section 15).
 *
 * A cache renders one variant of a store (with or without coarser levels, store.h) from
 * decoded bricks held in a pool of bounded size. Per frame (cdvr_brick_cache_frame) it picks a
 * level for every level-0 brick, makes those bricks resident (decoding a missing one on the
 * host with the store's C decoder; least recently used bricks out while the cache would pass
 * the budget) and lays out a payload the renderer reads voxel by voxel through a page table:
 *
 *   level choice: for brick b with world box B (the brick's voxel box under the store's
 *   index-to-world map, its axis-aligned bounds) and the camera, d = distance from the eye
 *   to the nearest point of B (0 inside), p = 2 d tan(fov / 2) / height the world size of a
 *   pixel there (orthographic: ortho_height / height), s = the smallest voxel spacing of level
 *   0; the level is the largest l < levels with s 2^l <= lod_error p (0 when lod_error is 0).
 *   Budget: while the bricks chosen need more bytes than the budget, the brick that adds least
 *   not yet at the coarsest level goes one level coarser (one level per brick per round): first
 *   the bricks the TF leaves transparent (no code of the range recorded for the brick's chunk
 *   has opacity), then the others farthest first; when even every brick at the coarsest level does not fit, the frame fails
 *   (CDVR_ERR_NOMEM naming the bytes it needs). Every brick always has a level: no holes.
 *   Level l of brick b is the level-l brick holding the level-l voxel nearest b's centre.
 *
 *   payload (u32 little endian words, then bytes):
 *     header (CDVR_BRICK_CACHE_HEADER_WORDS words): 0 magic 0x43425243, 1..3 the level-0 brick
 *     grid bx by bz, 4 byte offset of the pool, 5 byte offset of the page table, 6 words per
 *     page-table entry (CDVR_BRICK_CACHE_ENTRY_WORDS), 7 zero; then X + Y + Z words, the
 *     level-0 brick along each axis of each voxel coordinate (the owner rule of cdvr/bricks.h);
 *     the page table: per level-0 brick (x fastest) 16 words: 0 pool byte offset of its
 *     brick, 1 level l, 2..4 first voxel lo[3] and 5..7 dims d[3] of the level-l brick
 *     (level-l voxel coordinates), 8..10 first and 11..13 end (exclusive) of the level-0
 *     brick's cells: the trilinear cells (lower corner x0) whose eight voxels the march reads
 *     from this brick, [lo0, lo0 + d0 - 1) per axis of its level-0 box (lo0, d0), [0, 1) on
 *     an axis of one voxel; 14, 15 zero; the pool: the bricks' voxels, then
 *     CDVR_BRICK_CACHE_PAD zero bytes (the march reads voxel pairs).
 *   fetch of level-0 voxel (x, y, z) (cdvr_brick_cache_fetch; kernels/render/brick_cache.cl
 *   is bit-exact with it): the owner brick's entry; level 0: the voxel itself; level l > 0:
 *   per axis c0 = clamp((x >> l) - lo, 0, d - 1), c1 = min(c0 + 1, d - 1), weights
 *   2^l - (x & (2^l - 1)) and x & (2^l - 1); v = (sum of the 8 weight products times voxels +
 *   2^(3l-1)) >> 3l (trilinear at x / 2^l, rounded half up, integers only). With every brick
 *   at level 0 it returns exactly the assembled volume (cdvr_store_decode), so a render
 *   through the cache equals the dense render bit for bit. The CPU reference renders this
 *   fetch (a dense frame of it), and the OpenCL ray caster with fetch="sample".
 *
 *   The brick march (kernels/render/raycast.cl with CDVR_BRICK_CACHE, the OpenCL default):
 *   the composite blend walks, per ray, the level-0 bricks the ray crosses front to back and
 *   reads each brick's entry once. Samples keep the dense render's global sequence (render.h:
 *   sample i of the full segments at grid position g0 + i dg, the shorter last segment after
 *   them). The brick of a sample is the one owning voxel x0 + 1 per axis (x0 the sample's
 *   lower trilinear corner, clamped as the dense render clamps it; x0 on an axis of one
 *   voxel): thanks to the one-voxel overlap of bricks its box holds all eight voxels of the
 *   cell, so trilinear stays local to the brick. A lane looks up the brick of its current
 *   sample i when it enters it and takes its run: the samples up to where the ray leaves the
 *   brick's cells ([lo0, end) per axis, exit parameter ceil((face - g0) / dg) in samples; a
 *   sample whose corner is outside the brick anyway, by float rounding, ends the run and is
 *   looked up again).
 *     level 0: the sample reads its eight voxels from the brick with the dense render's
 *     corner, weights and mix order: the same bits as the dense render.
 *     level l > 0: the run is taken in groups of k = min(2^l, samples left in the run) level-0
 *     samples (groups start where the run starts; a run ends at the brick's exit, or at the
 *     end of a visible cube of the empty-space skipping); a group is one sample at the
 *     group's middle, m = i + (k - 1) / 2, at level-l grid position gl = g(m) / 2^l,
 *     trilinear in the level-l brick: c = floor(gl) - lo per axis, corners clamp(c, 0, d - 1)
 *     and clamp(c + 1, 0, d - 1), weight of the upper corner gl - floor(gl); classified like
 *     every sample, with its alpha corrected for the k segments it stands for:
 *     alpha' = 1 - (1 - alpha)^k (alpha the step-corrected table's, render.h; the same as
 *     correcting the per-unit alpha for k * step). So a level-l brick costs 2^-l of the samples
 *     of level 0.
 *     Empty space: the skip grid (cdvr/skip.h, range bricks of 2^CDVR_RANGE_SHIFT) gets per
 *     range brick the union of the value ranges (over the voxels its samples read) of the
 *     cache bricks its samples read (cdvr_brick_cache_skip_grid); a coarse brick's range only
 *     where level 0 has a value the TF leaves visible in the range brick (the store's range
 *     tables; every range brick counts when the store has none). A coarse sample counts only
 *     in a visible range brick (one the TF leaves invisible adds nothing: the tent filter
 *     spreads values into empty space, which the full render does not show), so invisible
 *     cubes are jumped as in the dense render, exactly: at level 0 every value read there has
 *     zero opacity, and coarse samples there count for nothing.
 *     Single samples (the shorter last segment, the six of a gradient for shading and
 *     gradient opacity, the max, min, average and iso blends) read through the brick of
 *     their own cell, one page-table look-up each, as level-0 and coarse samples above, with
 *     the level-0 step.
 *     Overlap voxels: a lossy codec decodes a brick's overlap (its lower apron) on its own;
 *     a level-0 brick's apron takes its owners' voxels once they are resident at level 0, so
 *     level-0 samples read exactly the assembled frame.
 *   With every brick at level 0 the march gives the dense render's image bit for bit, for
 *   every blend, shading and skipping; with coarser bricks it differs from the CPU reference
 *   (which renders the fetch above: upsampled voxels at the level-0 step), and skipping on and
 *   off can differ where runs start (groups start there): test_brick_cache and
 *   lua_test_brick_cache report the PSNR.
 *
 * The fetch reaches the renderers as a fetch-mode codec table (cdvr_brick_cache_codec: the
 * OpenCL ray caster's fetch hook; its C decoder is the fetch over every voxel, which is what
 * the CPU reference renders). Not thread-safe: one thread per cache (in the asynchronous
 * mode the cache's own worker thread decodes alongside; the calls stay one thread's).
 */
#ifndef CDVR_BRICK_CACHE_H
#define CDVR_BRICK_CACHE_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/camera.h"
#include "cdvr/codec.h"
#include "cdvr/error.h"
#include "cdvr/skip.h"
#include "cdvr/store.h"
#include "cdvr/tf.h"

#define CDVR_BRICK_CACHE_MAGIC 0x43425243u
#define CDVR_BRICK_CACHE_HEADER_WORDS 8
#define CDVR_BRICK_CACHE_ENTRY_WORDS 16
#define CDVR_BRICK_CACHE_PAD 16 /* zero bytes after the pool */
/* The smallest payload the fetch reads: a header and one entry. */
#define CDVR_BRICK_CACHE_MIN_BYTES (4 * (CDVR_BRICK_CACHE_HEADER_WORDS + CDVR_BRICK_CACHE_ENTRY_WORDS))
/* Byte 0 of the cache codec's parameters (cdvr_codec_params): 1 for the brick march, 0 for
 * the per-voxel fetch (raycast.cl reads it from the kernel's parameter blob). */
#define CDVR_BRICK_CACHE_PARAM_MARCH 0

typedef struct cdvr_brick_cache cdvr_brick_cache;

/* What the last frame took. */
typedef struct cdvr_brick_cache_stats {
    size_t levels;                               /* the store's levels */
    size_t bricks_at[CDVR_STORE_MAX_LEVELS];     /* level-0 bricks rendered at each level */
    size_t decoded;                              /* bricks decoded for the frame (on the
                                                    calling thread) */
    size_t coarser;                              /* async: level-0 bricks rendered at a level
                                                    coarser than chosen (not yet resident) */
    size_t pending;                              /* async: bricks queued or being decoded by
                                                    the worker after the frame */
    uint64_t requested_bytes;                    /* async: voxel bytes the frame queued (this
                                                    frame's missing bricks, then the next
                                                    timestep's): at most the budget less the
                                                    pinned coarsest level */
    size_t arrived;                              /* async: bricks the worker decoded that
                                                    became resident for the frame */
    size_t evicted;                              /* bricks dropped for the frame */
    uint64_t resident_bytes;                     /* voxel bytes of the bricks the frame uses */
    uint64_t cache_bytes;                        /* voxel bytes the cache holds (<= budget) */
    uint64_t budget_bytes;                       /* the budget kept to (asked for, capped) */
    uint64_t payload_bytes;                      /* the payload: tables + resident bricks */
    size_t dense_bricks;                         /* level-0 bricks cdvr_brick_cache_dense
                                                    assembled (the others were in place) */
    double decode_ms, layout_ms;
} cdvr_brick_cache_stats;

/* A cache of variant v of st (st must outlive it) holding at most budget_bytes of voxels,
 * capped at what the payload's 32-bit pool offsets reach (4 GiB less the tables): a larger
 * budget renders coarser, not fails. */
cdvr_status cdvr_brick_cache_create(const cdvr_store *st, size_t v, uint64_t budget_bytes,
                                    cdvr_brick_cache **out, cdvr_error *err);
void cdvr_brick_cache_free(cdvr_brick_cache *c);
/* 1 if the cache serves variant v of st with this budget. */
int cdvr_brick_cache_serves(const cdvr_brick_cache *c, const cdvr_store *st, size_t v,
                            uint64_t budget_bytes);
/* Timestep t for camera cam and TF tf (its table over the store's window, or NULL) at
 * lod_error pixels (>= 0): the level choice, residency and payload above; *payload (valid
 * until the next call) and *bytes. */
cdvr_status cdvr_brick_cache_frame(cdvr_brick_cache *c, size_t t, const cdvr_camera *cam,
                                   const cdvr_tf *tf, double lod_error,
                                   const uint8_t **payload, size_t *bytes, cdvr_error *err);
/* Asynchronous residency (on = 1; 0 returns to the synchronous mode above). The coarsest
 * level of every brick of the frame's timestep is decoded in the frame when missing and kept
 * resident (pinned; it never leaves while the timestep is shown); the level choice above works
 * within the budget less those bytes (bricks at the coarsest level cost nothing more). Per
 * brick the frame uses the chosen level when it is resident, else the finest resident coarser
 * level (the pinned one at worst: never a hole), and queues the chosen one for a worker
 * thread (its own, started here), which decodes with the store's C decoder; the queue holds
 * only the last frame's requests (older ones not started are dropped). A decoded brick
 * becomes resident at the start of the next frame (so a frame depends only on what had
 * arrived when it started), least recently used entries out while it would pass the budget;
 * one that finds no room is dropped. A worker's decode error fails the next frame. Fails
 * (CDVR_ERR_NOMEM) when the coarsest level alone passes the budget. */
cdvr_status cdvr_brick_cache_set_async(cdvr_brick_cache *c, int on, cdvr_error *err);
/* Asynchronous mode: the timestep the frame after the next cdvr_brick_cache_frame will show
 * (playback). That next call queues, after its own missing bricks, t_next's coarsest level and
 * its bricks at the levels it chose, those not resident, so the worker decodes the next
 * timestep while this one renders (without it a new timestep starts at its coarsest level).
 * Applies to that one call; (size_t)-1: none. */
void cdvr_brick_cache_set_next(cdvr_brick_cache *c, size_t t_next);
/* Blocks until the worker has decoded every brick queued (nothing when synchronous). */
void cdvr_brick_cache_wait(cdvr_brick_cache *c);
/* Bricks queued, being decoded or decoded and not yet resident (0 when synchronous). */
size_t cdvr_brick_cache_pending(cdvr_brick_cache *c);
void cdvr_brick_cache_get_stats(const cdvr_brick_cache *c, cdvr_brick_cache_stats *out);
/* The last frame as a dense frame of the store's dims in memory the cache holds (page
 * aligned, valid until the next call or the cache's end): exactly cdvr_brick_cache_fetch at
 * every voxel, level-0 bricks copied row by row. Renderers take it on a CPU device when the
 * dense frame fits the budget: there the page-table fetch per sample costs 10-20x a dense
 * read (raycast_method.c, player.c). Only the level-0 bricks whose entry (timestep, level,
 * brick) changed since the frame last assembled are assembled again (each writes just the
 * voxels it owns, so the frame is the same; stats dense_bricks): a camera that moves changes
 * the levels of a few bricks. */
cdvr_status cdvr_brick_cache_dense(cdvr_brick_cache *c, const uint8_t **frame, cdvr_error *err);

/* The skip grid g (of the store's dims; cdvr_skip_grid_init) for the last frame's march and
 * tf (or NULL): per range brick the union of the value ranges of the cache bricks its samples
 * read, a coarse brick's only where the TF leaves a value of level 0's range there visible
 * (the store's range tables; see the brick march above); marks g's minmax changed. */
cdvr_status cdvr_brick_cache_skip_minmax(cdvr_brick_cache *c, cdvr_skip_grid *g,
                                         const cdvr_tf *tf, cdvr_error *err);

/* The skip grid of the last frame, bricks of 2^shift (cdvr_brick_cache_skip_minmax's ranges,
 * coarse bricks' only where level 0 is visible when level0_visible: the composite march; the
 * max and min blends need every range) with its flags for tf, in memory the cache holds (valid
 * until the next call or the cache's end); it is made again only when the frame's bricks, the
 * set of TF entries with opacity or level0_visible changed. */
cdvr_status cdvr_brick_cache_skip_grid(cdvr_brick_cache *c, unsigned shift, const cdvr_tf *tf,
                                       int level0_visible, const cdvr_skip_grid **out,
                                       cdvr_error *err);

/* The fetch above on a payload of n bytes (reads outside it are clamped inside). */
uint8_t cdvr_brick_cache_fetch(const uint8_t *payload, size_t n, const size_t dims[3], size_t x,
                               size_t y, size_t z);
/* The fetch-mode codec table of cache payloads (not registered: renderers get it here). */
const cdvr_codec *cdvr_brick_cache_codec(void);

#endif
