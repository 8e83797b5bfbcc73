/* cdvr/player.h - out-of-core playback of a store, one frame per timestep (DESIGN.md §2, §7).
 *
 * Stages per frame (seed 000 Table 4):
 *   b1  read    chunk bytes from disk (pread, CRC check; optional cold cache, bandwidth cap)
 *   b1' unzip   stage-2 decode (LZO, LZ4, zstd; one chunk's segments on all cores) on the CPU
 *   b2  upload  host -> device copy of the chunk payload
 *   b3  decode  decode kernel (or C decoder on the cpu device)
 *   b4  setup   per-frame setup: TF table, brick min/max grid for empty-space skipping
 *   b5  render  ray cast
 * With `pipelined`, b1 runs in a reader thread and b1' in unzip workers, connected to the
 * calling (device) thread by bounded queues of `ring` buffers, so stages overlap. Callbacks
 * (decide, camera) always run on the calling thread: a Lua state is never touched elsewhere.
 * There are `unzip_threads` unzip workers (0: the environment variable CDVR_UNZIP_THREADS
 * when set to a number > 0, else 2 on a machine with 2 or more cores and 1 otherwise; at most
 * 2): consecutive groups are unzipped (and host-decoded, below) at the same time and reach
 * the calling thread in their planning order, so every frame is the same whatever the count.
 * The reader and the unzip workers (and threads they start) run at a nice value 5 above the
 * caller's on Linux (the environment variable CDVR_PLAYER_NICE, 0..19, sets the increment;
 * 0 keeps the caller's), so the frame being rendered gets the cores before the work ahead.
 *
 * A store is read one chunk group at a time: the chunks of the group's timesteps, one per
 * brick (an unbricked store has one brick). On the cl device a chunk is decoded by its
 * codec's kernel (decode mode) or kept compressed and rendered through its fetch function
 * (fetch mode); codecs without OpenCL code, bricked stores, and decode-mode variants that the
 * device decodes faster on the host (a CPU device: cdvr_cl_decode_path, learnt from the
 * variant's first group) are decoded on the host by an unzip worker, into one of the decode
 * slots (one per worker plus the one being rendered; each holds a group's frames of the
 * rendered box, so a second worker costs one slot more: voxels x timesteps per chunk bytes),
 * and handed to the device without a copy where it shares host memory. For stores
 * with range tables (store.h), when the whole volume is rendered and every brick of the group
 * is read, the unzip worker also makes each frame's skip grid and flags (cdvr/skip.h), and b4
 * only uploads them (else the device computes them from the frame). So the next group's
 * decode and setup overlap the current group's rendering. Timings follow the work: b1
 * includes reading the range tables, b1' the unpacking, b1g (grid_ms) making the grids (at
 * the tables' brick size, spread over the device's bricks when those are smaller), b3 the
 * host decode (wherever it ran), b4 what the calling thread still does.
 *
 * Brick skipping ("model only what a scene needs", opts.brick_skip): when a group is planned,
 * a brick is read and decoded only if
 *   - some value in its chunk's recorded range [value_min, value_max] has alpha > 0 under the
 *     TF (else every sample in its cells is transparent; composite only: the other blend
 *     modes see every value), and
 *   - the box of its cells can be seen by the camera of at least one frame of the group
 *     (cdvr_camera_sees_box; no ray of the view crosses it otherwise).
 * With shading (or gradient opacity) the 26 neighbours of each brick read are read too: the
 * central differences at a cell on a brick's face read one voxel into the neighbour, which so
 * holds its real values, as without skipping.
 * A skipped brick's voxels are filled with its value_min (transparent for a TF-skipped
 * brick, never sampled for one out of view), then the read bricks are decoded over them, the
 * lower brick last so it keeps the voxels it owns (store.h). With no brick read the frame is
 * transparent and nothing is rendered. For a lossless variant this changes no sample: the
 * cells of a read brick read only its own voxels, which hold their exact values. For a lossy
 * variant a voxel on a face shared by a read brick and a skipped lower neighbour holds the
 * read brick's decoded value instead of the neighbour's (both approximate the same voxel);
 * that is the only difference. Rows report the group's bricks_read and bricks_skipped.
 *
 * The camera of every frame is evaluated when its chunk group is planned, before the group is
 * read (so the reader knows the view it must cover): the reader hands the planning of a group
 * (policy decision at group boundaries, then camera_fn for each of its frames, in frame
 * order) to the calling thread, exactly as it hands over decisions, and the frames are later
 * rendered with those cameras. camera_fn is called once per frame, up to `ring` groups ahead
 * of the frame being shown. A failing callback stops the run after the frames planned before
 * it are played.
 *
 * Chunk-level costs (b1, b1', b2, b3) are shared equally by the frames of the chunk group (a
 * chunk may hold several timesteps), so per-frame rows add up to the total work.
 * frame_ms is the calling thread's wall time for the frame's chunk (waiting for data, b2..b5,
 * callbacks, from the end of the previous chunk's last frame), shared equally by the chunk's
 * frames, pacing waits excluded: the sustained cost of a frame. With pace_fps > 0
 * (interactive playback with a target frame rate) frames are shown on a fixed schedule of
 * 1/pace_fps and interval_ms is the real time between shown frames; without pacing
 * interval_ms = frame_ms. cdvr_player_fps is 1000 / median(interval_ms).
 */
#ifndef CDVR_PLAYER_H
#define CDVR_PLAYER_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/annotate.h"
#include "cdvr/camera.h"
#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/method.h"
#include "cdvr/render.h"
#include "cdvr/store.h"
#include "cdvr/tf.h"

typedef struct cdvr_frame_row {
    size_t frame;            /* 0-based frame number in this run */
    size_t t;                /* timestep (0-based) */
    int variant;             /* variant index (0-based) */
    double read_ms, unzip_ms, upload_ms, decode_ms, setup_ms, render_ms, frame_ms;
    double unzip_cpu_ms;     /* b1' in CPU time on all its threads: unzip_ms also counts the
                                waits of the low-priority workers for the render's cores */
    double grid_ms;          /* b1g: the skip grid made from the range tables (0 without) */
    uint64_t samples;        /* cl device: samples the ray caster took (0 elsewhere); with
                                empty-space skipping off, all of them: 1 - on/off is the
                                share skipping saves */
    double interval_ms;      /* frame_ms plus the pacing wait */
    uint64_t bytes;          /* stored bytes read, this frame's share */
    uint64_t payload_bytes;  /* bytes after stage 2, this frame's share */
    uint64_t device_bytes;   /* cl device: memory the device stream holds for this frame
                                (compressed payload in fetch mode); 0 on the cpu device */
    double composite_ms;     /* the composite hook (distributed compositing), wait_ms excluded */
    double wait_ms;          /* the composite hook waiting for the other processes' frames */
    size_t bricks_read;      /* bricks read and decoded for this frame's chunk group (0 with
                                opts.cache: the cache reads what it needs itself) */
    size_t bricks_skipped;   /* bricks of the player's region not read (transparent or unseen) */
    double decoded_share;    /* of the frame's voxels, the share the host decode wrote (1: all,
                                0: no host decode; below 1 with opts.decode_whole 0) */
    uint64_t resident_bytes; /* brick cache (opts.cache): voxel bytes of the bricks the frame
                                rendered from; 0 without the cache */
    size_t nlevels;          /* brick cache: the store's levels; bricks_at[l] level-0 bricks */
    size_t bricks_at[16];    /* rendered at level l (CDVR_STORE_MAX_LEVELS entries) */
    size_t bricks_coarser;   /* cache_async: level-0 bricks rendered coarser than their chosen
                                level (not yet resident) */
    size_t bricks_pending;   /* cache_async: bricks the cache's worker still had to decode */
    double lod_error;        /* brick cache: the frame's lod_error (opts.lod_error or the
                                policy's, cdvr_player_set_lod_error) */
    int rank;                /* process that played the frame (cdvr/dist.h; 0 in one process) */
    int group_start;         /* 1 if a policy decision was made for this frame's group */
    char reason[160];        /* the decision's one-line reason (group_start only) */
    cdvr_status status;      /* CDVR_OK, or the failure of this frame */
    char error[CDVR_ERRMSG_MAX];
} cdvr_frame_row;

typedef struct cdvr_player cdvr_player;

/* Called at each group boundary with the next timestep t (0-based) and group index (0-based);
 * sets *variant (0-based) and a one-line reason. The rows so far are cdvr_player_rows(). */
typedef cdvr_status (*cdvr_decide_fn)(void *ud, cdvr_player *player, size_t t, size_t group,
                                      int *variant, char *reason, size_t reason_size,
                                      cdvr_error *err);
/* Called before rendering each frame: fills *cam (width/height preset from the player's
 * camera) for timestep t (0-based) and frame number. */
typedef cdvr_status (*cdvr_camera_fn)(void *ud, size_t t, size_t frame, cdvr_camera *cam,
                                      cdvr_error *err);
/* Called on the calling thread after each frame's render with its row, camera and image
 * (*img NULL when the frame failed here), for every frame, in frame order: may replace *img
 * (freeing the old one), e.g. by the composite of every process's image (cdvr/dist.h), or set
 * it to NULL (nothing to show here). *wait_ms (preset 0) gets the part of its time spent
 * waiting for other processes. A non-OK return fails the frame (its row gets the error); the
 * run goes on. */
typedef cdvr_status (*cdvr_composite_fn)(void *ud, const cdvr_frame_row *row,
                                         const cdvr_camera *cam, cdvr_image **img,
                                         double *wait_ms, cdvr_error *err);
/* Called after each frame with the row and the image (e.g. to write a PNG); may be NULL. A
 * frame that failed (row->status and row->error say why, e.g. a damaged chunk) is passed too,
 * with img NULL, so that a capture never loses a frame silently; a frame the composite hook
 * left without an image here (img NULL, row->status CDVR_OK) is not passed. A non-OK return
 * stops the run with that error (the rows so far are kept). */
typedef cdvr_status (*cdvr_frame_fn)(void *ud, const cdvr_frame_row *row, const cdvr_image *img,
                                     cdvr_error *err);

/* Bounded work (cdvr_player_create refuses other values, naming the limit): read_mbps is 0 (no
 * cap) or CDVR_PLAYER_MIN_READ_MBPS .. CDVR_PLAYER_MAX_RATE (1 kB/s at the slowest); pace_fps
 * is 0 or CDVR_PLAYER_MIN_FPS .. CDVR_PLAYER_MAX_RATE (a frame per 1000 s at the slowest);
 * step, unit and term_alpha as cdvr_render_opts_check on the store's box. */
#define CDVR_PLAYER_MIN_READ_MBPS 1e-3
#define CDVR_PLAYER_MIN_FPS 1e-3
#define CDVR_PLAYER_MAX_RATE 1e9

typedef struct cdvr_player_opts {
    const cdvr_store *store;
    cdvr_device_kind device;     /* one of the method's devices (cdvr/method.h) */
    const cdvr_render_method *method; /* NULL: raycast */
    cdvr_method_params method_params; /* the method's options (all zero with method NULL:
                                         its defaults) */
    cdvr_look look;              /* blend mode, shading, gradient opacity, iso (render.h) */
    const cdvr_annotate_opts *annotate; /* NULL, or drawn onto every frame shown (after the
                                           composite hook) with the player's TF and the frame's
                                           camera; annotate_time adds "t = T / N" */
    int annotate_time;
    cdvr_render_ctx *ctx;        /* devices for methods that render through it (gl, or a cl
                                    method without render_stream); NULL: the player makes its
                                    own when it needs one */
    const cdvr_tf *tf;
    cdvr_camera camera;          /* initial camera (also used when camera_fn is NULL) */
    double step, unit, term_alpha;
    float background[4];
    int threads;                 /* CPU render threads (cpu device), 0 = all */
    int variant;                 /* initial variant (0-based) */
    int pipelined;               /* 1: reader/unzip threads; 0: serial */
    int ring;                    /* queue depth (buffers per queue), default 3 */
    int unzip_threads;           /* unzip workers when pipelined (1..2), 0: automatic (above) */
    int cold;                    /* drop chunks from the page cache (posix_fadvise) */
    double read_mbps;            /* > 0: cap read bandwidth (MB/s, 1e6 bytes) */
    int empty_skip;              /* 1 (default): empty-space skipping on the cl device */
    int decode_whole;            /* 1: host decodes write whole frames; 0 (default): where the
                                    codec decodes cells (codec.h, decode_cells), the cl ray
                                    caster composites from the range tables' skip grid, and the
                                    store is one brick of one timestep per chunk, only the cells
                                    its samples read are decoded */
    int cache;                   /* 1: every frame renders through the brick cache
                                    (cdvr/brick_cache.h; the cl device with a method that renders
                                    streams (raycast), or the cpu device with any method, from
                                    the cache's dense frame; not with a region of the bricks) */
    int cache_async;             /* 1: the cache's asynchronous residency
                                    (cdvr_brick_cache_set_async): a frame never waits for a brick
                                    finer than its coarsest level; frames then depend on timing */
    double cache_budget_mb;      /* its budget (0: a quarter of the cl device's memory, 1 GiB on
                                    the cpu) */
    double lod_error;            /* its level of detail in pixels (cdvr_brick_cache_frame) at
                                    the start; a policy may change it */
    int fetch_path;              /* fetch-mode codecs (hvq) on the cl device: 0 auto, 1 sample,
                                    2 bulk (cdvr_cl_fetch_path, cdvr/device.h); bulk decodes
                                    each group on the host in the pipeline's workers */
    double pace_fps;             /* > 0: show frames no faster than this (interactive pacing) */
    int loop;                    /* 1: wrap around after the last timestep; 0: stop there */
    int brick_skip;              /* 1: skip bricks that are transparent or out of view */
    /* Distribution (filled by cdvr/dist.h; all zero: this process plays everything). */
    size_t frame_stride, frame_phase; /* play only frames k with k % stride == phase (0 -> 1, 0) */
    size_t region_lo[3], region_hi[3];/* render only bricks (i,j,k) of the brick grid with
                                         lo <= (i,j,k) < hi: hi all 0 -> the whole grid; lo ==
                                         hi on an axis -> none (transparent frames). A region
                                         smaller than the grid is rendered clipped to its cells
                                         (render.h, cdvr_render_clip) */
    int rank;                    /* recorded in the rows */
    cdvr_composite_fn composite; /* may be NULL */
    void *composite_ud;
    cdvr_decide_fn decide;       /* NULL: always `variant` */
    void *decide_ud;
    cdvr_camera_fn camera_fn;
    void *camera_ud;
    cdvr_frame_fn frame_fn;
    void *frame_ud;
} cdvr_player_opts;

/* Lowest common multiple of the variants' timesteps per chunk (the group length: policies
 * switch variants only at its multiples). */
size_t cdvr_player_group_length(const cdvr_store *st);

cdvr_status cdvr_player_create(const cdvr_player_opts *opts, cdvr_player **out, cdvr_error *err);
void cdvr_player_free(cdvr_player *p);
/* Plays `frames` frames starting at timestep `first` (0-based). Past the last timestep the
 * run wraps around to timestep 0 when opts.loop is set, and stops there otherwise
 * (cdvr_player_stopped_early tells). With frame_stride N > 1 this player plays only frames
 * k = phase, phase + N, ... of that sequence (frame numbers and timesteps stay those of the
 * whole sequence; a policy is asked when this player's next frame enters a new group). A failed frame (corrupt chunk, ...) gets a row with its
 * status and the run goes on; a failing callback stops the run and returns its error (rows so
 * far are kept). */
cdvr_status cdvr_player_run(cdvr_player *p, size_t first, size_t frames, cdvr_error *err);
/* The brick cache's lod_error (opts.cache) for the groups planned from now on: called by the
 * decide callback it applies to the group it decides (a policy trading level of detail for
 * speed); CDVR_ERR_ARG unless 0 <= lod_error <= 1e12. */
cdvr_status cdvr_player_set_lod_error(cdvr_player *p, double lod_error, cdvr_error *err);
/* The lod_error of the groups planned from now on. */
double cdvr_player_lod_error(const cdvr_player *p);
/* Frames the last run did not play because it reached the last timestep without loop. */
size_t cdvr_player_stopped_early(const cdvr_player *p);
/* Rows of the last run (valid until the next run or free). */
const cdvr_frame_row *cdvr_player_rows(const cdvr_player *p, size_t *count);
/* Achieved frame rate of the last run: 1000 / median(interval_ms) over frames without error. */
double cdvr_player_fps(const cdvr_player *p);

#endif
