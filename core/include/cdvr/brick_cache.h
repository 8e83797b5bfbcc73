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
 *     0 magic 0x43425243, 1..3 the level-0 brick grid bx by bz, 4 byte offset of the pool,
 *     5 byte offset of the page table, from byte 24: X + Y + Z words, the level-0 brick along
 *     each axis of each voxel coordinate (the owner rule of cdvr/bricks.h); the page table: per
 *     level-0 brick 8 words: pool byte offset of its brick, level l, first voxel lo[3] and dims
 *     d[3] of the level-l brick (level-l voxel coordinates); the pool: the bricks' voxels.
 *   fetch of level-0 voxel (x, y, z) (cdvr_brick_cache_fetch; kernels/render/brick_cache.cl
 *   is bit-exact with it): the owner brick's entry; level 0: the voxel itself; level l > 0:
 *   per axis c0 = clamp((x >> l) - lo, 0, d - 1), c1 = min(c0 + 1, d - 1), weights
 *   2^l - (x & (2^l - 1)) and x & (2^l - 1); v = (sum of the 8 weight products times voxels +
 *   2^(3l-1)) >> 3l (trilinear at x / 2^l, rounded half up, integers only). With every brick
 *   at level 0 it returns exactly the assembled volume (cdvr_store_decode), so a render
 *   through the cache equals the dense render bit for bit.
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
#include "cdvr/store.h"
#include "cdvr/tf.h"

#define CDVR_BRICK_CACHE_MAGIC 0x43425243u

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
    size_t arrived;                              /* async: bricks the worker decoded that
                                                    became resident for the frame */
    size_t evicted;                              /* bricks dropped for the frame */
    uint64_t resident_bytes;                     /* voxel bytes of the bricks the frame uses */
    uint64_t cache_bytes;                        /* voxel bytes the cache holds (<= budget) */
    uint64_t payload_bytes;                      /* the payload: tables + resident bricks */
    size_t dense_bricks;                         /* level-0 bricks cdvr_brick_cache_dense
                                                    assembled (the others were in place) */
    double decode_ms, layout_ms;
} cdvr_brick_cache_stats;

/* A cache of variant v of st (st must outlive it) holding at most budget_bytes of voxels. */
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

/* The fetch above on a payload of n bytes (reads outside it are clamped inside). */
uint8_t cdvr_brick_cache_fetch(const uint8_t *payload, size_t n, const size_t dims[3], size_t x,
                               size_t y, size_t z);
/* The fetch-mode codec table of cache payloads (not registered: renderers get it here). */
const cdvr_codec *cdvr_brick_cache_codec(void);

#endif
