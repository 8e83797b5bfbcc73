/* core/player/player.c - the playback pipeline of player.h.
 *
 * Threads (pipelined): reader (plans a group - decision and cameras handed to the calling
 * thread -, picks its bricks, b1) -> queue -> 1 or 2 unzip workers (b1') -> queue -> calling
 * thread (b2..b5, composite, callbacks). Items carry their planning order (seq): workers take
 * them in that order, may finish out of order, and the calling thread takes them back in
 * order. One mutex and one condition variable guard the queues, the item pool, the decode
 * slots and the planning hand-off; every wait loops on its predicate and on `abort`.
 *
 * Off the calling thread's path, the unzip worker also decodes a group on the host when it
 * is decoded there anyway (cpu device, codecs without device code, bricked stores) or when the
 * cl device decodes that variant faster on the host (its first group, decoded by the device,
 * tells: cdvr_cl_decode_path), into one of nworkers + 1 decode slots (one being rendered, one
 * per worker being filled; handed out in planning order, see acquire_slot), and turns the
 * store's range tables into each frame's skip grid and flags (cdvr/skip.h). The calling
 * thread then hands the slot's frames to the device without a copy and uploads the flags, so
 * the next group's decode and setup overlap the current group's rendering.
 */
#include "cdvr/player.h"
#include "cdvr/brick_cache.h"
#include "cdvr/timing.h"

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#if defined(__linux__)
#include <errno.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#endif

#include "cdvr/bricks.h"
#include "cdvr/memory.h"
#include "cdvr/skip.h"
#include "cdvr/visible.h"

#if CDVR_HAVE_OPENCL
#include "cdvr/device.h"
#endif

#define MAX_UNZIP 2                /* unzip workers at most */
#define MAX_SLOTS (MAX_UNZIP + 1)  /* decode slots: one rendered, one per worker being filled */
#define DEFAULT_BACKGROUND_NICE 5  /* the reader's and unzip workers' nice increment */

/* One chunk of a group: the group's chunk of one brick. */
typedef struct chunk_part {
    size_t chunk;
    int needed;              /* read and decoded (else skipped or outside the region) */
    uint8_t *stored, *payload;
    size_t stored_cap, payload_cap;
    uint8_t *ranges;         /* the chunk's range table (store.h), when the group has grids */
    size_t ranges_cap;
} chunk_part;

/* A chunk group in flight: the chunks of every brick for the same timesteps. The fields up
 * to `cams` are reset for every group. */
typedef struct chunk_item {
    int variant;
    size_t chunk;            /* chunk index of brick 0 of the group */
    size_t t_begin, nframes; /* timesteps t_begin, t_begin + stride, ... to render */
    size_t frame0;           /* frame number of t_begin */
    int group_start;
    char reason[160];
    double lod_error;        /* opts.cache: the brick cache's lod_error for its frames */
    double read_ms, unzip_ms;
    double unzip_cpu_ms;     /* the CPU time of unzip_ms on all its threads */
    double grid_ms;          /* making the frames' skip grids from the range tables (b1g) */
    uint64_t stored_bytes, payload_bytes;
    size_t bricks_read, bricks_region; /* decoded; decoded inside the region */
    int lossless;            /* the variant decodes every voxel exactly (recorded PSNR inf) */
    cdvr_error err;          /* status != OK: the group failed (rows get the error) */
    cdvr_error stop;         /* status != OK: planning failed; the run stops after this item */
    int with_grids;          /* the range tables were read: make the frames' skip grids */
    int slot;                /* decode slot holding the host-decoded frames, or -1 */
    double host_decode_ms;   /* the host decode in the pipeline (b3) */
    size_t seq;              /* planning order in this run: items reach the device in it */
    size_t ngrids;           /* skip grids made for the group's first ngrids frames */
    double decoded_share;    /* of the frames' voxels, the share the host decode wrote */
    int tiled;               /* the slot holds the frame as the ray caster's tiled copy */
    /* kept from group to group */
    cdvr_camera *cams;       /* the camera of each frame (nframes), evaluated at planning */
    size_t cams_cap;
    struct chunk_item *next;
    chunk_part *parts;       /* nbricks */
    cdvr_skip_grid *grids;   /* per frame of the chunk */
    size_t grids_cap;
    cdvr_skip_grid coarse;   /* a frame's grid at the tables' bricks when they are coarser
                                than the device's (coarse.minmax NULL: not allocated) */
    uint8_t *need;           /* decode_cells: the cells to decode, and scratch (2 per brick) */
    size_t need_cap;
} chunk_item;

typedef struct item_queue {
    chunk_item *head, *tail;
    size_t count;
} item_queue;

/* Work handed from the reader to the calling thread (callbacks run only there). */
typedef cdvr_status (*caller_fn)(cdvr_player *p, chunk_item *it, cdvr_error *err);

struct cdvr_player {
    cdvr_player_opts opts;   /* opts.method resolved (never NULL) */
    int on_stream;           /* frames live on the cl stream and the method's render_stream
                                renders them (else frames are decoded on the host and the
                                method's render draws them on its device) */
    cdvr_render_ctx *own_ctx;/* made here when opts.ctx is NULL and the method needs one */
    size_t group_len;
    size_t stride, phase;    /* frames k with k % stride == phase are this player's */
    size_t nbricks;
    size_t region_lo[3], region_hi[3]; /* bricks rendered: a box of the brick grid */
    size_t data_lo[3], data_hi[3];     /* bricks that may be read: the region and, below it,
                                          the bricks owning voxels of its lower faces */
    size_t vox_lo[3], vox_dims[3];     /* the voxels of the data box */
    size_t own_lo[3], own_hi[3];       /* the region's cells: voxels own_lo .. own_hi */
    int *own;                /* scratch (reader): bricks the view needs, per brick */
    size_t voxels;           /* per frame: vox_dims product */
    size_t nregion;          /* bricks in the region */
    int clipped;             /* the region is smaller than the volume */
    double *corners;         /* world corners of each brick's cells: nbricks x 8 x 3 */
    int tf_prefix[257];      /* TF entries with alpha > 0 among 0 .. i-1 */
    size_t stopped_early;    /* frames of the last run not played (end of series, no loop) */

    /* run state */
    size_t first, frames;
    cdvr_frame_row *rows;
    size_t nrows, rows_cap;
    double t_last_frame, t_deadline;

    /* pipeline */
    pthread_mutex_t decode_mu; /* one host decode of a codec that decodes in parallel at a time */
    pthread_mutex_t mu;
    pthread_cond_t cv;
    item_queue free_items, read_q, unzip_q;
    chunk_item *items;
    size_t nitems;
    int reader_done, abort;
    int nworkers, workers_done; /* unzip workers of the run, and those that have ended */
    int background_nice;        /* nice increment of the reader and unzip workers */
    size_t seq_next;         /* reader: seq of the next item planned */
    size_t seq_play;         /* calling thread: seq of the next item to play */
    size_t slot_turn;        /* seq of the next item whose slot request is served */
    unsigned char *turn_passed; /* per seq % nitems: the item needs no slot (turn skipped) */
    int call_state;          /* 0 idle, 1 requested, 2 answered */
    caller_fn call_fn;
    chunk_item *call_item;
    cdvr_error call_err;
    size_t planned;          /* frames planned by the reader (next frame number to plan) */
    int current_variant;
    int have_group;          /* a group has been decided in this run */
    size_t last_group;

    /* host decode (unzip workers, or the calling thread in serial mode) */
    int nslots;              /* nworkers + 1 */
    uint8_t *slots[MAX_SLOTS]; /* decoded frames of a group (vox_dims each), page aligned */
    size_t slot_cap[MAX_SLOTS];
    int slot_busy[MAX_SLOTS];
    uint8_t *brick_frames[MAX_UNZIP]; /* per worker scratch: decoded frames of one brick */
    size_t brick_frames_cap[MAX_UNZIP];
    int *host_decodes;       /* per variant (cl device): its decode is faster on the host */
    struct cdvr_brick_cache *cache; /* opts.cache: the brick cache of the variant playing */
    double lod_error;        /* opts.cache: lod_error of the groups planned from now on
                                (opts.lod_error, or the policy's: cdvr_player_set_lod_error) */
    int *fetch_bulk;         /* per variant (cl device): a fetch-mode codec decodes in bulk
                                on the host (cdvr_cl_fetch_path_for is not SAMPLE) */
#if CDVR_HAVE_OPENCL
    cdvr_cl *cl;
    cdvr_cl_stream *stream;
#endif
};

static void sleep_ms(double ms)
{
    if (ms <= 0)
        return;
    struct timespec ts = {(time_t)(ms / 1e3), (long)((ms - (time_t)(ms / 1e3) * 1e3) * 1e6)};
    while (nanosleep(&ts, &ts) != 0) {
    }
}

static size_t gcd(size_t a, size_t b)
{
    while (b) {
        size_t r = a % b;
        a = b;
        b = r;
    }
    return a;
}

/* Timesteps per chunk of variant v: its codec's chunk shape for brick 0 (the recorded count
 * when the codec is not loaded). */
static size_t chunk_timesteps(const cdvr_store *st, size_t v)
{
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, v, 0);
    if (!ch)
        return 1;
    size_t lo[3], dims[3];
    cdvr_codec_shape shape;
    cdvr_store_brick_box(cdvr_store_get_info(st), 0, lo, dims);
    if (ch->codec && cdvr_codec_shape_of(ch->codec, &ch->params, dims, &shape, NULL) == CDVR_OK)
        return shape.timesteps;
    return ch->count ? ch->count : 1;
}

size_t cdvr_player_group_length(const cdvr_store *st)
{
    size_t len = 1;
    size_t nvar = cdvr_store_get_info(st)->nvariants;
    for (size_t v = 0; v < nvar; v++) {
        size_t n = chunk_timesteps(st, v);
        len = len / gcd(len, n) * n;
    }
    return len;
}

/* ---- queues (caller holds mu) ------------------------------------------------------------ */

static void queue_push(item_queue *q, chunk_item *it)
{
    it->next = NULL;
    if (q->tail)
        q->tail->next = it;
    else
        q->head = it;
    q->tail = it;
    q->count++;
}

static chunk_item *queue_pop(item_queue *q)
{
    chunk_item *it = q->head;
    if (it) {
        q->head = it->next;
        if (!q->head)
            q->tail = NULL;
        q->count--;
    }
    return it;
}

/* Takes the item with sequence number seq out of q, or NULL when it is not there. */
static chunk_item *queue_take_seq(item_queue *q, size_t seq)
{
    chunk_item *prev = NULL;
    for (chunk_item *it = q->head; it; prev = it, it = it->next) {
        if (it->seq != seq)
            continue;
        if (prev)
            prev->next = it->next;
        else
            q->head = it->next;
        if (q->tail == it)
            q->tail = prev;
        q->count--;
        it->next = NULL;
        return it;
    }
    return NULL;
}

/* ---- stage functions -------------------------------------------------------------------- */

/* Runs fn(p, it) on the calling thread: directly when not threaded, else handed over to it
 * (next_ready runs it) while this thread waits. */
static cdvr_status on_caller(cdvr_player *p, int threaded, caller_fn fn, chunk_item *it,
                             cdvr_error *err)
{
    if (!threaded)
        return fn(p, it, err);
    pthread_mutex_lock(&p->mu);
    p->call_fn = fn;
    p->call_item = it;
    p->call_state = 1;
    pthread_cond_broadcast(&p->cv);
    while (p->call_state != 2 && !p->abort)
        pthread_cond_wait(&p->cv, &p->mu);
    cdvr_status st = p->abort ? CDVR_ERR_ARG : p->call_err.status;
    if (p->abort)
        cdvr_error_set(err, CDVR_ERR_ARG, "player: stopped");
    else if (st != CDVR_OK && err)
        *err = p->call_err;
    p->call_state = 0;
    pthread_mutex_unlock(&p->mu);
    return st;
}

/* The variant of the group starting at the item's first timestep (policy, or the current). */
static cdvr_status decide(cdvr_player *p, chunk_item *it, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    size_t t = it->t_begin, nvar = cdvr_store_get_info(st)->nvariants;
    int v = p->current_variant;
    it->reason[0] = '\0';
    if (!p->opts.decide) {
        snprintf(it->reason, sizeof it->reason, "fixed: %s", cdvr_store_variant(st, (size_t)v)->name);
    } else {
        cdvr_status s = p->opts.decide(p->opts.decide_ud, p, t, t / p->group_len, &v, it->reason,
                                       sizeof it->reason, err);
        if (s != CDVR_OK)
            return s;
        if (v < 0 || (size_t)v >= nvar)
            return cdvr_error_set(err, CDVR_ERR_ARG, "%s: policy chose variant %d of %zu",
                                  cdvr_store_path(st), v + 1, nvar);
    }
    p->current_variant = v;
    it->group_start = 1;
    return CDVR_OK;
}

static int grow_cams(chunk_item *it, size_t n)
{
    if (n <= it->cams_cap)
        return 1;
    cdvr_camera *nc = realloc(it->cams, n * sizeof *nc);
    if (!nc)
        return 0;
    it->cams = nc;
    it->cams_cap = n;
    return 1;
}

/* Plans the item whose first frame is it->frame0 (timestep it->t_begin): the decision when
 * it starts a group, its frames (this player's frames of that chunk), and their cameras.
 * Runs where callbacks may run. On a failing callback the item keeps the frames planned
 * before it and the error is returned. */
static cdvr_status plan_item(cdvr_player *p, chunk_item *it, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    size_t t = it->t_begin, group = t / p->group_len;
    if (!p->have_group || t % p->group_len == 0 || group != p->last_group) {
        cdvr_status s = decide(p, it, err);
        if (s != CDVR_OK)
            return s;
        p->have_group = 1;
        p->last_group = group;
    }
    it->variant = p->current_variant;
    it->lod_error = p->lod_error;
    it->chunk = cdvr_store_chunk_for(st, (size_t)it->variant, t, 0);
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, it->chunk);
    size_t in_chunk = (ch->t0 + ch->count - t + p->stride - 1) / p->stride;
    size_t left = (p->frames - it->frame0 + p->stride - 1) / p->stride;
    size_t n = in_chunk < left ? in_chunk : left;
    p->planned = it->frame0 + (n - 1) * p->stride + 1;
    if (!grow_cams(it, n))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: out of memory for cameras");
    for (size_t j = 0; j < n; j++) {
        it->cams[j] = p->opts.camera;
        if (!p->opts.camera_fn)
            continue;
        cdvr_error cerr;
        cdvr_error_clear(&cerr);
        if (p->opts.camera_fn(p->opts.camera_ud, t + j * p->stride, it->frame0 + j * p->stride,
                              &it->cams[j], &cerr) != CDVR_OK) {
            if (cerr.status == CDVR_OK)
                cdvr_error_set(&cerr, CDVR_ERR_ARG, "camera callback failed");
            it->nframes = j;
            if (err)
                *err = cerr;
            return cerr.status;
        }
    }
    it->nframes = n;
    return CDVR_OK;
}

/* Grid position of brick b. */
static void brick_at(const cdvr_player *p, size_t b, size_t at[3])
{
    const size_t *g = cdvr_store_get_info(p->opts.store)->bricks;
    at[0] = b % g[0];
    at[1] = b / g[0] % g[1];
    at[2] = b / (g[0] * g[1]);
}

static int in_box(const cdvr_player *p, size_t b, const size_t lo[3], const size_t hi[3])
{
    size_t at[3];
    brick_at(p, b, at);
    return at[0] >= lo[0] && at[0] < hi[0] && at[1] >= lo[1] && at[1] < hi[1] &&
           at[2] >= lo[2] && at[2] < hi[2];
}

static int in_region(const cdvr_player *p, size_t b)
{
    return in_box(p, b, p->region_lo, p->region_hi);
}

static int in_data(const cdvr_player *p, size_t b)
{
    return in_box(p, b, p->data_lo, p->data_hi);
}

/* Calls fn(p, it, n) for each lower neighbour n of brick b (b - (dx,dy,dz), d in {0,1},
 * not all 0, inside the grid): the bricks owning voxels on b's lower faces. */
static void each_lower(const cdvr_player *p, size_t b, void (*fn)(const cdvr_player *, void *, size_t),
                       void *arg)
{
    const size_t *g = cdvr_store_get_info(p->opts.store)->bricks;
    size_t at[3];
    brick_at(p, b, at);
    for (int d = 1; d < 8; d++) {
        size_t dx = d & 1, dy = d >> 1 & 1, dz = d >> 2 & 1;
        if (dx > at[0] || dy > at[1] || dz > at[2])
            continue;
        fn(p, arg, (at[0] - dx) + g[0] * ((at[1] - dy) + g[1] * (at[2] - dz)));
    }
}

/* Calls fn(p, it, n) for each of the up to 26 neighbours n of brick b inside the grid: with
 * shading the central differences of a sample in b's cells read one voxel beyond them. */
static void each_neighbour(const cdvr_player *p, size_t b,
                           void (*fn)(const cdvr_player *, void *, size_t), void *arg)
{
    const size_t *g = cdvr_store_get_info(p->opts.store)->bricks;
    size_t at[3];
    brick_at(p, b, at);
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                long x = (long)at[0] + dx, y = (long)at[1] + dy, z = (long)at[2] + dz;
                if ((dx | dy | dz) == 0 || x < 0 || y < 0 || z < 0 || (size_t)x >= g[0] ||
                    (size_t)y >= g[1] || (size_t)z >= g[2])
                    continue;
                fn(p, arg, (size_t)x + g[0] * ((size_t)y + g[1] * (size_t)z));
            }
}

static int shades(const cdvr_player *p)
{
    return p->opts.look.shade.enabled || p->opts.look.gradient_opacity.npoints;
}

typedef struct value_hull {
    const chunk_item *it;
    int lo, hi;
} value_hull;

static void widen(const cdvr_player *p, void *arg, size_t n)
{
    value_hull *h = arg;
    const cdvr_chunk_info *ch = cdvr_store_chunk(p->opts.store, (size_t)h->it->variant,
                                                 h->it->chunk + n);
    h->lo = ch->value_min < h->lo ? ch->value_min : h->lo;
    h->hi = ch->value_max > h->hi ? ch->value_max : h->hi;
}

static void mark_needed(const cdvr_player *p, void *arg, size_t n)
{
    (void)p;
    ((chunk_item *)arg)->parts[n].needed = 1;
}

/* Does the view need brick b of the region (player.h)? Its cells read its own voxels and,
 * on its lower faces, voxels its lower neighbours own: their values lie in the chunks'
 * recorded ranges (for a lossless variant every brick holds those voxels' exact values, so
 * its own range suffices). */
static int view_needs(cdvr_player *p, const chunk_item *it, size_t b)
{
    if (!p->opts.brick_skip)
        return 1;
    value_hull h = {it, 255, 0};
    widen(p, &h, b);
    if (!it->lossless)
        each_lower(p, b, widen, &h);
    if (p->opts.look.blend == CDVR_BLEND_COMPOSITE &&
        p->tf_prefix[h.hi + 1] - p->tf_prefix[h.lo] == 0)
        return 0; /* every sample in its cells is transparent (max, min, average and iso see
                     every value: only the view decides for them) */
    for (size_t j = 0; j < it->nframes; j++)
        if (cdvr_camera_sees_box(&it->cams[j], (const double(*)[3])(p->corners + 24 * b)))
            return 1;
    return 0;
}

/* Brick skipping (player.h): which bricks this item reads. The bricks the view needs, and,
 * for a lossy variant, their lower neighbours (the owners of the voxels on their lower faces,
 * whose decoded values the assembled volume holds there). */
static void select_bricks(cdvr_player *p, chunk_item *it)
{
    const cdvr_variant_info *var = cdvr_store_variant(p->opts.store, (size_t)it->variant);
    it->lossless = isinf(var->psnr) && var->psnr > 0;
    for (size_t b = 0; b < p->nbricks; b++) {
        it->parts[b].chunk = it->chunk + b;
        it->parts[b].needed = 0;
        p->own[b] = in_region(p, b) && view_needs(p, it, b);
    }
    for (size_t b = 0; b < p->nbricks; b++) {
        if (!p->own[b])
            continue;
        it->parts[b].needed = 1;
        if (!it->lossless)
            each_lower(p, b, mark_needed, it);
        if (shades(p)) /* the gradient at its faces reads the neighbours' voxels */
            each_neighbour(p, b, mark_needed, it);
    }
    it->bricks_read = it->bricks_region = 0;
    for (size_t b = 0; b < p->nbricks; b++) {
        it->bricks_read += (size_t)it->parts[b].needed;
        it->bricks_region += (size_t)(it->parts[b].needed && in_region(p, b));
    }
    if (p->opts.cache) { /* the brick cache reads and decodes what each frame needs itself */
        for (size_t b = 0; b < p->nbricks; b++)
            it->parts[b].needed = 0;
        it->bricks_read = 0;
    }
}

/* Whether the group's frames get skip grids from the store's range tables: on the cl device
 * with skipping, rendering the whole volume (clipped renders do not skip), every brick read
 * (a skipped brick's fill is not what its table describes: the device computes the grid then),
 * and every chunk with a table of one brick size, the device's or coarser (4^3 in stores
 * written before 2026-12, 8^3 since). */
static int wants_grids(const cdvr_player *p, const chunk_item *it)
{
#if CDVR_HAVE_OPENCL
    if (!p->on_stream || !p->opts.empty_skip || p->clipped ||
        it->bricks_read != p->nbricks)
        return 0;
    const cdvr_chunk_info *c0 = cdvr_store_chunk(p->opts.store, (size_t)it->variant, it->chunk);
    for (size_t b = 0; b < p->nbricks; b++) {
        const cdvr_chunk_info *ch = cdvr_store_chunk(p->opts.store, (size_t)it->variant,
                                                     it->chunk + b);
        if (!ch->ranges_shift || ch->ranges_shift != c0->ranges_shift ||
            ((size_t)1 << ch->ranges_shift) < cdvr_cl_brick_edge())
            return 0;
    }
    return 1;
#else
    (void)p;
    (void)it;
    return 0;
#endif
}

/* b1 of a chunk's range table (read and checked like the chunk). */
static void read_ranges(cdvr_player *p, chunk_item *it, chunk_part *part)
{
    const cdvr_store *st = p->opts.store;
    size_t bytes = cdvr_store_ranges_bytes(st, (size_t)it->variant, part->chunk);
    if (!cdvr_grow_bytes(&part->ranges, &part->ranges_cap, bytes))
        cdvr_error_set(&it->err, CDVR_ERR_NOMEM, "%s: chunk %zu: cannot allocate a %zu-byte "
                       "range table", cdvr_store_path(st), part->chunk + 1, bytes);
    else
        cdvr_store_read_ranges(st, (size_t)it->variant, part->chunk, part->ranges, &it->err);
}

/* Reads (b1) the needed chunks of the item (and their range tables for skip grids). */
static void read_item(cdvr_player *p, chunk_item *it)
{
    const cdvr_store *st = p->opts.store;
    double t0 = cdvr_now_ms();
    it->with_grids = wants_grids(p, it);
    for (size_t b = 0; b < p->nbricks && it->err.status == CDVR_OK; b++) {
        chunk_part *part = &it->parts[b];
        if (!part->needed)
            continue;
        const cdvr_chunk_info *pc = cdvr_store_chunk(st, (size_t)it->variant, part->chunk);
        it->stored_bytes += pc->stored_bytes;
        it->payload_bytes += pc->payload_bytes;
        if (!cdvr_grow_large(&part->stored, &part->stored_cap, pc->stored_bytes)) {
            cdvr_error_set(&it->err, CDVR_ERR_NOMEM, "%s: chunk %zu: cannot allocate %llu bytes",
                           cdvr_store_path(st), part->chunk + 1,
                           (unsigned long long)pc->stored_bytes);
            break;
        }
        if (p->opts.cold)
            cdvr_store_drop_cache(st, (size_t)it->variant, part->chunk);
        cdvr_store_read_chunk(st, (size_t)it->variant, part->chunk, part->stored, &it->err);
        if (it->with_grids && it->err.status == CDVR_OK)
            read_ranges(p, it, part);
        if (p->opts.cold)
            cdvr_store_drop_cache(st, (size_t)it->variant, part->chunk);
    }
    if (p->opts.read_mbps > 0)
        sleep_ms(it->stored_bytes / (p->opts.read_mbps * 1e3) - (cdvr_now_ms() - t0));
    it->read_ms = cdvr_now_ms() - t0;
}

/* Plans the next item of this player and reads it. Returns 0 when every frame is planned, 1
 * otherwise; it->stop is set when planning failed (the run ends after this item). */
static int plan_and_read(cdvr_player *p, chunk_item *it, int threaded)
{
    const cdvr_store_info *info = cdvr_store_get_info(p->opts.store);
    size_t k = p->planned + (p->phase + p->stride - p->planned % p->stride) % p->stride;
    if (k >= p->frames)
        return 0;
    memset(it, 0, offsetof(chunk_item, cams));
    for (size_t b = 0; b < p->nbricks; b++)
        it->parts[b].needed = 0;
    cdvr_error_clear(&it->err);
    cdvr_error_clear(&it->stop);
    it->slot = -1;
    it->seq = p->seq_next++;
    it->frame0 = k;
    it->t_begin = (p->first + k) % info->timesteps;
    int callbacks = p->opts.decide || p->opts.camera_fn;
    on_caller(p, threaded && callbacks, plan_item, it, &it->stop);
    if (it->nframes == 0)
        return 1;
    select_bricks(p, it);
    read_item(p, it);
    return 1;
}

static void prepare(cdvr_player *p, int w, chunk_item *it);
static void pass_turn(cdvr_player *p, const chunk_item *it);

/* b1' of every needed chunk of the group (a chunk without stage 2 swaps its buffers; a
 * segmented one is unpacked on all cores, cdvr_store_unpack_chunk). */
static void unzip_chunks(cdvr_player *p, chunk_item *it)
{
    if (it->err.status != CDVR_OK)
        return;
    const cdvr_store *st = p->opts.store;
    double t0 = cdvr_now_ms();
    it->unzip_cpu_ms = 0;
    for (size_t b = 0; b < p->nbricks && it->err.status == CDVR_OK; b++) {
        chunk_part *part = &it->parts[b];
        if (!part->needed)
            continue;
        const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, part->chunk);
        if (!ch->stage2) { /* the stored bytes are the payload: take the buffer, no copy */
            cdvr_swap_buffers(&part->payload, &part->payload_cap, &part->stored, &part->stored_cap);
            continue;
        }
        if (!cdvr_grow_large(&part->payload, &part->payload_cap, ch->payload_bytes)) {
            cdvr_error_set(&it->err, CDVR_ERR_NOMEM, "%s: chunk %zu: cannot allocate %llu bytes",
                           cdvr_store_path(st), part->chunk + 1,
                           (unsigned long long)ch->payload_bytes);
            break;
        }
        cdvr_store_unpack_chunk_cpu(st, (size_t)it->variant, part->chunk, part->stored,
                                    part->payload, &it->unzip_cpu_ms, &it->err);
    }
    it->unzip_ms = cdvr_now_ms() - t0;
}

/* b1' of the group, then what the pipeline prepares (prepare, below), by unzip worker w. An
 * item that got no decode slot gives up its turn for one. */
static void unzip(cdvr_player *p, int w, chunk_item *it)
{
    unzip_chunks(p, it);
    prepare(p, w, it);
    if (it->slot < 0)
        pass_turn(p, it);
}

/* ---- device (calling thread) ------------------------------------------------------------ */

static cdvr_frame_row *add_row(cdvr_player *p)
{
    if (p->nrows == p->rows_cap) {
        size_t cap = p->rows_cap ? 2 * p->rows_cap : 64;
        cdvr_frame_row *nr = realloc(p->rows, cap * sizeof *nr);
        if (!nr)
            return NULL;
        p->rows = nr;
        p->rows_cap = cap;
    }
    cdvr_frame_row *row = &p->rows[p->nrows++];
    memset(row, 0, sizeof *row);
    return row;
}

static void render_opts_for(const cdvr_player *p, const cdvr_camera *cam, cdvr_render_opts *ro)
{
    memset(ro, 0, sizeof *ro);
    ro->tf = p->opts.tf;
    ro->camera = cam;
    ro->step = p->opts.step;
    ro->unit = p->opts.unit;
    ro->term_alpha = p->opts.term_alpha;
    memcpy(ro->background, p->opts.background, sizeof ro->background);
    ro->threads = p->opts.threads;
    ro->look = p->opts.look;
}

/* Brick b's box relative to the region: first voxel lo (in the region) and dims. */
static void region_box(const cdvr_player *p, size_t b, size_t lo[3], size_t bd[3])
{
    cdvr_store_brick_box(cdvr_store_get_info(p->opts.store), b, lo, bd);
    for (int a = 0; a < 3; a++)
        lo[a] -= p->vox_lo[a];
}

/* Fills brick b's box of the item's count frames (at out) with its value_min. */
static void fill_brick(cdvr_player *p, const chunk_item *it, size_t b, size_t count,
                       uint8_t *out)
{
    const size_t *rd = p->vox_dims;
    size_t lo[3], bd[3];
    region_box(p, b, lo, bd);
    uint8_t value = cdvr_store_chunk(p->opts.store, (size_t)it->variant, it->parts[b].chunk)->value_min;
    for (size_t i = 0; i < count; i++)
        for (size_t z = 0; z < bd[2]; z++)
            for (size_t y = 0; y < bd[1]; y++)
                memset(out + i * p->voxels + lo[0] + rd[0] * ((lo[1] + y) + rd[1] * (lo[2] + z)),
                       value, bd[0]);
}

/* Decodes brick b's chunk into the item's count frames at out (straight into them when the
 * brick is the whole volume). */
static cdvr_status decode_brick(cdvr_player *p, int w, chunk_item *it, size_t b, size_t count,
                                int whole, uint8_t *out, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    size_t lo[3], bd[3], bvox;
    region_box(p, b, lo, bd);
    bvox = bd[0] * bd[1] * bd[2];
    uint8_t *base = out, *frames[64];
    if (!whole) {
        if (!cdvr_grow_bytes(&p->brick_frames[w], &p->brick_frames_cap[w],
                             (uint64_t)bvox * count))
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot allocate a brick",
                                  cdvr_store_path(st));
        base = p->brick_frames[w];
    }
    for (size_t i = 0; i < count; i++)
        frames[i] = base + i * bvox;
    cdvr_status s = cdvr_store_decode_chunk(st, (size_t)it->variant, it->parts[b].chunk,
                                            it->parts[b].payload, frames, err);
    for (size_t i = 0; s == CDVR_OK && !whole && i < count; i++)
        cdvr_brick_place(out + i * p->voxels, p->vox_dims, frames[i], lo, bd);
    return s;
}

/* Decodes the group's needed chunks on the CPU into out (count frames of the data box, room
 * for them); the other bricks of the data box are filled with their value_min. Every voxel gets
 * the value its owner (the lower brick of those sharing it, store.h) gives it, except that
 * for a lossless variant a read brick's decode wins over a skipped brick's fill (the same
 * exact value, where the fill would not be): so the fills go first there, and otherwise
 * fills and decodes go together from the last brick to the first. */
static cdvr_status decode_host(cdvr_player *p, int w, chunk_item *it, size_t count,
                               uint8_t *out, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    if (count > 64)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: chunk %zu: %zu frames (at most 64)",
                              cdvr_store_path(st), it->chunk + 1, count);
    int whole = p->nbricks == 1 && it->parts[0].needed;
    for (size_t b = 0; it->lossless && b < p->nbricks; b++)
        if (in_data(p, b) && !it->parts[b].needed)
            fill_brick(p, it, b, count, out);
    for (size_t b = p->nbricks; b-- > 0;) {
        if (!in_data(p, b))
            continue;
        if (it->parts[b].needed) {
            cdvr_status s = decode_brick(p, w, it, b, count, whole, out, err);
            if (s != CDVR_OK)
                return s;
        } else if (!it->lossless) {
            fill_brick(p, it, b, count, out);
        }
    }
    return CDVR_OK;
}

/* ---- what the pipeline makes before the device needs it --------------------------------- */

/* Whether the group is decoded on the host (by an unzip worker): always on the cpu device;
 * on the cl device for codecs without device code, bricked stores, and decode-mode variants
 * whose first group the device decoded faster on the host. */
static int decodes_on_host(cdvr_player *p, const chunk_item *it)
{
    if (!p->on_stream)
        return 1;
    const cdvr_chunk_info *ch = cdvr_store_chunk(p->opts.store, (size_t)it->variant, it->chunk);
    if (!ch->codec || ch->codec->cl_mode == CDVR_CODEC_CL_NONE || p->nbricks > 1)
        return 1;
    if (ch->codec->cl_mode != CDVR_CODEC_CL_DECODE)
        return p->fetch_bulk[it->variant];
    pthread_mutex_lock(&p->mu);
    int host = p->host_decodes[it->variant];
    pthread_mutex_unlock(&p->mu);
    return host;
}

/* Decode slots are handed out in planning order (slot_turn): an item later than one still
 * waiting for a slot never takes the last free one, so with nworkers + 1 slots the item the
 * calling thread waits for always gets one (the others are held by the item being played and
 * by earlier items). An item that needs none passes its turn (pass_turn). */

/* Moves the turn past the items that passed it (caller holds mu). */
static void advance_turn(cdvr_player *p)
{
    while (p->turn_passed[p->slot_turn % p->nitems]) {
        p->turn_passed[p->slot_turn % p->nitems] = 0;
        p->slot_turn++;
    }
    pthread_cond_broadcast(&p->cv);
}

static void pass_turn(cdvr_player *p, const chunk_item *it)
{
    pthread_mutex_lock(&p->mu);
    p->turn_passed[it->seq % p->nitems] = 1;
    advance_turn(p);
    pthread_mutex_unlock(&p->mu);
}

/* A free decode slot for the item, at its turn (waiting for the calling thread to finish
 * one), or -1 on abort. */
static int acquire_slot(cdvr_player *p, const chunk_item *it)
{
    pthread_mutex_lock(&p->mu);
    int k = -1;
    for (;;) {
        for (int i = 0; i < p->nslots && k < 0 && p->slot_turn == it->seq; i++)
            if (!p->slot_busy[i])
                k = i;
        if (k >= 0 || p->abort)
            break;
        pthread_cond_wait(&p->cv, &p->mu);
    }
    if (k >= 0) {
        p->slot_busy[k] = 1;
        p->slot_turn++;
        advance_turn(p);
    }
    pthread_mutex_unlock(&p->mu);
    return k;
}

static void release_slot(cdvr_player *p, chunk_item *it)
{
    if (it->slot < 0)
        return;
    pthread_mutex_lock(&p->mu);
    p->slot_busy[it->slot] = 0;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    it->slot = -1;
}

/* Room for `need` bytes in slot k (free: nothing else points into it), on huge pages
 * (cdvr/memory.h). */
static int slot_room(cdvr_player *p, int k, size_t need)
{
    const uint8_t *held = p->slots[k];
    if (!cdvr_grow_large(&p->slots[k], &p->slot_cap[k], need))
        return 0;
    if (p->slots[k] != held) /* new: a tiled frame's tiles past the frame's edge stay unwritten */
        memset(p->slots[k], 0, p->slot_cap[k]);
    return 1;
}

/* The skip grid and flags of each frame of the group from the range tables (cdvr/skip.h):
 * the whole volume, every brick read, one brick size in every table, at least the device's
 * (wants_grids). Tables of coarser bricks make their grid and flags at that size (cheap: 8^3
 * bricks are 1/8 of the 4^3 ones) and spread them over the device's grid. */
static cdvr_status make_grids(cdvr_player *p, chunk_item *it, size_t count, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    unsigned shift = cdvr_store_chunk(st, (size_t)it->variant, it->chunk)->ranges_shift;
    if (count > it->grids_cap) {
        cdvr_skip_grid *g = realloc(it->grids, count * sizeof *g);
        if (!g)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: no memory for skip grids");
        it->grids = g;
        for (size_t f = it->grids_cap; f < count; f++) {
            cdvr_status s = cdvr_skip_grid_init(&it->grids[f], info->dims, CDVR_RANGE_SHIFT, err);
            if (s != CDVR_OK)
                return s;
            it->grids_cap = f + 1;
        }
    }
    const uint8_t **tables = malloc(p->nbricks * sizeof *tables);
    if (!tables)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: no memory for skip grids");
    for (size_t b = 0; b < p->nbricks; b++)
        tables[b] = it->parts[b].ranges;
    cdvr_status s = CDVR_OK;
    for (size_t f = 0; s == CDVR_OK && f < count; f++)
        s = cdvr_visible_table_grid(&it->grids[f], &it->coarse, info, shift, tables, f,
                                    p->opts.tf, err);
    free(tables);
    if (s == CDVR_OK)
        it->ngrids = count;
    return s;
}

/* Whether the group's host decode writes only the cells its frame's render reads
 * (opts.decode_whole): a codec that decodes cells, one brick of one timestep, and the ray
 * caster compositing on the cl device with the skip grid made here from the range tables
 * (with_grids), whose visible bricks are the only ones its samples take. Max, min, average
 * and iso read other bricks, other methods every voxel. */
static int decodes_cells(const cdvr_player *p, const chunk_item *it)
{
    return !p->opts.decode_whole && it->with_grids && p->nbricks == 1 && !p->opts.cache &&
           cdvr_store_chunk_decodes_cells(p->opts.store, (size_t)it->variant, it->chunk) &&
           p->opts.look.blend == CDVR_BLEND_COMPOSITE &&
           strcmp(p->opts.method->name, "raycast") == 0;
}

/* Whether a decodes_cells group is decoded as the ray caster's tiled copy (codec.h,
 * CDVR_LAYOUT_TILED), which the device then casts from instead of the dense frame it would
 * never tile for a frame rendered once (cl_render.c): 1.17x faster casts (Viscous fingers
 * 256^3 at 512^2). */
static int decodes_tiled(const cdvr_player *p)
{
#if CDVR_HAVE_OPENCL
    return p->on_stream && cdvr_cl_takes_host_tiles(p->stream, shades(p));
#else
    (void)p;
    return 0;
#endif
}

/* Locks mu unless it is NULL; returns the milliseconds it waited. */
static double serial_begin(pthread_mutex_t *mu)
{
    if (!mu)
        return 0;
    double t0 = cdvr_now_ms();
    pthread_mutex_lock(mu);
    return cdvr_now_ms() - t0;
}

static void serial_end(pthread_mutex_t *mu)
{
    if (mu)
        pthread_mutex_unlock(mu);
}

/* decodes_cells' decode of the group's frame into slot k, its grid made: the cells the render
 * reads (tiled where the stream takes it), fill in the others. Only the codec's decode holds
 * `serial` (when not NULL; *waited: the milliseconds it waited for it). */
static void decode_needed_cells(cdvr_player *p, chunk_item *it, int k, uint8_t fill,
                                pthread_mutex_t *serial, double *waited)
{
    cdvr_skip_grid *g = &it->grids[0];
    if (!cdvr_grow_bytes(&it->need, &it->need_cap, 2 * (uint64_t)g->nbricks)) {
        cdvr_error_set(&it->err, CDVR_ERR_NOMEM, "player: no memory for a %zu-cell mask",
                       g->nbricks);
        return;
    }
    int tiled = decodes_tiled(p) && g->shift == 2; /* cells are tiles */
    unsigned layout = tiled ? CDVR_LAYOUT_TILED : CDVR_LAYOUT_LINEAR;
    const cdvr_store *st = p->opts.store;
    *waited = serial_begin(serial);
    cdvr_status s = cdvr_visible_cells_decode(st, (size_t)it->variant, it->chunk,
                                              it->parts[0].payload, p->slots[k], layout, g,
                                              shades(p), it->need, &it->decoded_share, &it->err);
    serial_end(serial);
    if (s != CDVR_OK)
        return;
    /* a refine on this thread alone: the render runs beside it */
    cdvr_visible_cells_finish(st, (size_t)it->variant, it->chunk, p->slots[k], layout, g,
                              p->opts.tf, fill, 1, it->need);
    it->tiled = tiled;
}

/* A raw chunk of the player's one brick is its frame as it stands (codec/raw: the payload
 * is the dense volume): instead of the copy that raw's decode makes, slot k and the unpacked
 * payload trade buffers (both freed with free(), each big enough for the other's use).
 * Returns 1 when they did. Raw playback of a 256^3 series at 64^2 spent 7% of its CPU in
 * that copy. */
static int slot_takes_raw_payload(cdvr_player *p, chunk_item *it, const cdvr_chunk_info *ch,
                                  int k)
{
    chunk_part *part = &it->parts[0]; /* one brick of p->voxels: the whole region */
    if (!ch->codec || ch->codec->id != CDVR_CODEC_ID_RAW || p->nbricks != 1 || !part->needed ||
        ch->count != 1 || ch->payload_bytes != p->voxels)
        return 0;
    cdvr_swap_buffers(&p->slots[k], &p->slot_cap[k], &part->payload, &part->payload_cap);
    return 1;
}

/* The host decode of the group into slot k: whole frames, or (decodes_cells, and a fill that
 * keeps the render's other samples transparent) after the grid, the cells the render reads.
 * The codec's decode holds `serial` when not NULL; the grid, fill and refine run beside
 * another worker's decode (zfp1 512^2 playback with both around the decode: a worker's grid
 * and fill left a core idle while the frame waited for them). Time waiting for `serial` is
 * not the decode's. */
static void decode_group(cdvr_player *p, int w, chunk_item *it, const cdvr_chunk_info *ch,
                         int k, pthread_mutex_t *serial)
{
    double t0 = cdvr_now_ms();
    uint8_t fill = 0;
    int by_cells = decodes_cells(p, it);
    it->decoded_share = 1;
    it->tiled = 0;
    if (by_cells) { /* the grid first: it says which cells the render reads */
        make_grids(p, it, 1, &it->err);
        it->grid_ms = cdvr_now_ms() - t0;
        t0 = cdvr_now_ms();
        if (it->err.status != CDVR_OK)
            return;
        by_cells = cdvr_skip_transparent_fill(&it->grids[0], &fill);
    }
    double waited = 0;
    if (by_cells) {
        decode_needed_cells(p, it, k, fill, serial, &waited);
    } else if (!slot_takes_raw_payload(p, it, ch, k)) {
        waited = serial_begin(serial);
        decode_host(p, w, it, ch->count, p->slots[k], &it->err);
        serial_end(serial);
    }
    it->host_decode_ms = cdvr_now_ms() - t0 - waited;
}

/* After b1': the host decode into a slot and the skip grids, when they apply. Their time is
 * the group's b3 (host_decode_ms) and b1g (grid_ms). */
static void prepare(cdvr_player *p, int w, chunk_item *it)
{
    it->decoded_share = 0;
    it->tiled = 0;
    it->ngrids = 0;
    if (it->err.status != CDVR_OK || it->nframes == 0 || it->bricks_read == 0)
        return;
    const cdvr_chunk_info *ch = cdvr_store_chunk(p->opts.store, (size_t)it->variant, it->chunk);
    if (decodes_on_host(p, it)) {
        int k = acquire_slot(p, it);
        size_t need;
        if (k < 0) {
            cdvr_error_set(&it->err, CDVR_ERR_ARG, "player: stopped");
            return;
        }
        it->slot = k;
        /* a codec that decodes on all cores: one group at a time (the items take their slots
         * in planning order, so they come here in that order too but for a rare race) */
        int one_at_a_time = ch->codec && ch->codec->decodes_in_parallel;
        int ok = cdvr_size_mul(p->voxels, ch->count, &need);
        if (ok && decodes_cells(p, it) && decodes_tiled(p)) /* whole pages: never less */
            need = cdvr_tiled_bytes(p->vox_dims);
        if (!ok || !slot_room(p, k, need)) {
            cdvr_error_set(&it->err, CDVR_ERR_NOMEM, "%s: chunk %zu: cannot allocate %zu frames",
                           cdvr_store_path(p->opts.store), it->chunk + 1, ch->count);
        } else {
            decode_group(p, w, it, ch, k, one_at_a_time ? &p->decode_mu : NULL);
        }
    }
    if (it->err.status == CDVR_OK && it->with_grids && it->ngrids != ch->count) {
        double t0 = cdvr_now_ms();
        make_grids(p, it, ch->count, &it->err);
        it->grid_ms = cdvr_now_ms() - t0;
    }
}

/* b2 + b3 for one chunk group: frames the pipeline decoded on the host go to the device
 * without a copy where it shares host memory; the others are decoded by the device (and the
 * variant's fastest path is noted for the pipeline). */
static cdvr_status upload_decode(cdvr_player *p, chunk_item *it, double *upload_ms, double *decode_ms,
                                 cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, it->chunk);
    *upload_ms = 0;
    *decode_ms = it->host_decode_ms;
    if (it->slot >= 0) {
#if CDVR_HAVE_OPENCL
        if (p->on_stream) {
            double t0 = cdvr_now_ms();
            cdvr_status s =
                it->tiled ? cdvr_cl_use_host_tiles(p->stream, p->slots[it->slot], err)
                          : cdvr_cl_use_host_frames(p->stream, p->slots[it->slot], ch->count, err);
            *upload_ms = cdvr_now_ms() - t0;
            return s;
        }
#endif
        return CDVR_OK;
    }
#if CDVR_HAVE_OPENCL
    double t0 = cdvr_now_ms();
    cdvr_status s = cdvr_cl_upload(p->stream, it->parts[0].payload, (size_t)ch->payload_bytes,
                                   err);
    double t1 = cdvr_now_ms();
    if (s == CDVR_OK)
        s = cdvr_cl_decode(p->stream, ch->codec, &ch->params, ch->count, err);
    *upload_ms = t1 - t0;
    *decode_ms = cdvr_now_ms() - t1;
    if (s == CDVR_OK && ch->codec->cl_mode == CDVR_CODEC_CL_DECODE) {
        pthread_mutex_lock(&p->mu);
        p->host_decodes[it->variant] = cdvr_cl_last_decode_path(p->stream) == CDVR_CL_DECODE_HOST;
        pthread_mutex_unlock(&p->mu);
    }
    return s;
#else
    (void)ch; /* read by the OpenCL paths only */
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "player: no host decode (internal error)");
#endif
}

/* A transparent frame: nothing of the group was read (every brick skipped). */
static cdvr_status blank_image(const cdvr_player *p, const cdvr_camera *cam, cdvr_image **img,
                               cdvr_error *err)
{
    cdvr_status s = cdvr_image_create(cam->width, cam->height, img, err);
    if (s == CDVR_OK)
        memcpy((*img)->background, p->opts.background, sizeof (*img)->background);
    return s;
}

/* opts.cache: the budget (the device's memory / 4 on cl, 1 GiB on the cpu as cdvr.render's
 * cpu path, raycast_method.c). */
static uint64_t cache_budget(const cdvr_player *p)
{
    if (p->opts.cache_budget_mb > 0)
        return (uint64_t)(p->opts.cache_budget_mb * 1e6);
#if CDVR_HAVE_OPENCL
    if (p->cl) {
        uint64_t quarter = cdvr_cl_get_info(p->cl)->global_mem_bytes / 4;
        return quarter ? quarter : 1;
    }
#endif
    return (uint64_t)1 << 30;
}

/* opts.cache: timestep t's frame in the brick cache of the group's variant (made or remade
 * when the variant changes; asynchronous with opts.cache_async). */
static cdvr_status cache_frame(cdvr_player *p, const chunk_item *it, size_t t,
                               const cdvr_camera *cam, const uint8_t **payload, size_t *bytes,
                               cdvr_error *err)
{
    uint64_t budget = cache_budget(p);
    if (!cdvr_brick_cache_serves(p->cache, p->opts.store, (size_t)it->variant, budget)) {
        cdvr_brick_cache_free(p->cache);
        p->cache = NULL;
        cdvr_status s = cdvr_brick_cache_create(p->opts.store, (size_t)it->variant, budget,
                                                &p->cache, err);
        if (s == CDVR_OK && p->opts.cache_async)
            s = cdvr_brick_cache_set_async(p->cache, 1, err);
        if (s != CDVR_OK) { /* none rather than a synchronous one the next frame would take */
            cdvr_brick_cache_free(p->cache);
            p->cache = NULL;
            return s;
        }
    }
    if (p->opts.cache_async) { /* the worker decodes this player's next timestep meanwhile */
        size_t n = cdvr_store_get_info(p->opts.store)->timesteps, next = t + p->stride;
        cdvr_brick_cache_set_next(p->cache, next < n ? next : p->opts.loop ? next % n
                                                                             : (size_t)-1);
    }
    return cdvr_brick_cache_frame(p->cache, t, cam, p->opts.tf, it->lod_error, payload, bytes,
                                  err);
}

/* The cache's figures of the frame into its row. */
static void cache_row(const cdvr_player *p, const chunk_item *it, cdvr_frame_row *row)
{
    cdvr_brick_cache_stats cs;
    if (!p->cache)
        return;
    cdvr_brick_cache_get_stats(p->cache, &cs);
    row->resident_bytes = cs.resident_bytes;
    row->nlevels = cs.levels;
    memcpy(row->bricks_at, cs.bricks_at, sizeof row->bricks_at);
    row->bricks_coarser = cs.coarser;
    row->bricks_pending = cs.pending;
    row->lod_error = it->lod_error;
}

/* b4 + b5 for timestep t of the current chunk; *img receives the frame. */
#if CDVR_HAVE_OPENCL
/* opts.cache on cl: the cache's frame on the stream as raycast_method.c renders it: the brick
 * march (the payload with the march flag and *grid, the skip grid from the cache's brick
 * ranges), or with fetch="sample" the per-voxel page table, or with fetch="bulk" the cache's
 * dense frame when it fits the budget. */
static cdvr_status load_cached(cdvr_player *p, const chunk_item *it, size_t t,
                               const cdvr_camera *cam, const cdvr_render_opts *ro,
                               const cdvr_skip_grid **grid, cdvr_error *err)
{
    const uint8_t *payload;
    size_t bytes;
    cdvr_codec_params params = {{0}};
    *grid = NULL;
    cdvr_status s = cache_frame(p, it, t, cam, &payload, &bytes, err);
    const cdvr_store_info *in = cdvr_store_get_info(p->opts.store);
    if (s == CDVR_OK && p->opts.fetch_path == CDVR_CL_FETCH_BULK &&
        (uint64_t)in->dims[0] * in->dims[1] * in->dims[2] <= cache_budget(p)) {
        const uint8_t *frame;
        s = cdvr_brick_cache_dense(p->cache, &frame, err);
        return s == CDVR_OK ? cdvr_cl_use_host_frames(p->stream, frame, 1, err) : s;
    }
    int march = p->opts.fetch_path != CDVR_CL_FETCH_SAMPLE;
    params.bytes[CDVR_BRICK_CACHE_PARAM_MARCH] = (unsigned char)march;
    if (s == CDVR_OK)
        s = cdvr_cl_upload(p->stream, payload, bytes, err);
    cdvr_cl_set_fetch_path(p->stream, CDVR_CL_FETCH_SAMPLE); /* the payload as it is */
    if (s == CDVR_OK)
        s = cdvr_cl_decode(p->stream, cdvr_brick_cache_codec(), &params, 1, err);
    cdvr_cl_set_fetch_path(p->stream, (cdvr_cl_fetch_path)p->opts.fetch_path);
    if (s == CDVR_OK && march)
        s = cdvr_brick_cache_skip_grid(p->cache, CDVR_RANGE_SHIFT, ro->tf,
                                       ro->look.blend == CDVR_BLEND_COMPOSITE, grid, err);
    return s;
}
#endif


static cdvr_status setup_render(cdvr_player *p, chunk_item *it, size_t t, const cdvr_camera *cam,
                                cdvr_image **img, double *setup_ms, double *render_ms, cdvr_error *err)
{
    const cdvr_store *st = p->opts.store;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    const cdvr_chunk_info *ch = cdvr_store_chunk(st, (size_t)it->variant, it->chunk);
    size_t f = t - ch->t0; /* frame within the group */
    cdvr_render_opts ro;
    render_opts_for(p, cam, &ro);
    *setup_ms = *render_ms = 0;
    if (it->bricks_region == 0) /* nothing of the region to render: transparent */
        return blank_image(p, cam, img, err);
    cdvr_render_clip clip;
    if (p->clipped) { /* a region of the bricks (sort-last): its cells only, render.h */
        for (int a = 0; a < 3; a++) {
            clip.whole_dims[a] = info->dims[a];
            clip.offset[a] = p->vox_lo[a];
            clip.own_lo[a] = p->own_lo[a];
            clip.own_hi[a] = p->own_hi[a];
        }
        ro.clip = &clip;
    }
#if CDVR_HAVE_OPENCL
    if (p->on_stream) {
        double t0 = cdvr_now_ms();
        const cdvr_skip_grid *grid = f < it->ngrids ? &it->grids[f] : NULL;
        if (p->opts.cache) { /* the cache's payload replaces the group's frames */
            cdvr_status cs = load_cached(p, it, t, cam, &ro, &grid, err);
            if (cs != CDVR_OK)
                return cs;
            f = 0;
        }
        cdvr_status s = cdvr_image_create(cam->width, cam->height, img, err);
        if (s == CDVR_OK)
            s = p->opts.method->render_stream(p->stream, f, grid, &ro, &p->opts.method_params,
                                              info->spacing, info->origin, info->direction,
                                              *img, setup_ms, err);
        *render_ms = cdvr_now_ms() - t0 - *setup_ms;
        return s;
    }
#endif
    cdvr_volume frame = {0};
    memcpy(frame.dims, p->vox_dims, sizeof frame.dims);
    memcpy(frame.spacing, info->spacing, sizeof frame.spacing);
    memcpy(frame.origin, info->origin, sizeof frame.origin);
    memcpy(frame.direction, info->direction, sizeof frame.direction);
    frame.timesteps = 1;
    frame.type = CDVR_TYPE_U8;
    if (!p->opts.cache) /* the cache's dense frame below instead (nothing was read) */
        frame.data = p->slots[it->slot] + f * p->voxels;
    cdvr_render_ctx *ctx = p->opts.ctx ? p->opts.ctx : p->own_ctx;
    double t0 = cdvr_now_ms();
    cdvr_status s = CDVR_OK;
    if (p->opts.cache) { /* the cpu device: the cache's dense frame replaces the group's */
        const uint8_t *payload, *dense = NULL;
        size_t bytes;
        s = cache_frame(p, it, t, cam, &payload, &bytes, err);
        if (s == CDVR_OK)
            s = cdvr_brick_cache_dense(p->cache, &dense, err);
        frame.data = (void *)dense;
        *setup_ms = cdvr_now_ms() - t0;
        t0 = cdvr_now_ms();
    }
    if (s == CDVR_OK)
        s = p->opts.method->render(ctx, p->opts.device, &frame, 0, &ro,
                                           &p->opts.method_params, NULL, img, err);
    *render_ms = cdvr_now_ms() - t0;
    return s;
}

/* Row of frame j (of n) of an item: its share of the group's costs. */
static void fill_row(const cdvr_player *p, cdvr_frame_row *row, const chunk_item *it, size_t j,
                     size_t n)
{
    row->frame = it->frame0 + j * p->stride;
    row->t = it->t_begin + j * p->stride;
    row->variant = it->variant;
    row->rank = p->opts.rank;
    row->read_ms = it->read_ms / n;
    row->unzip_ms = it->unzip_ms / n;
    row->unzip_cpu_ms = it->unzip_cpu_ms / n;
    row->grid_ms = it->grid_ms / n;
    row->bytes = it->stored_bytes / n;
    row->payload_bytes = it->payload_bytes / n;
    row->bricks_read = it->bricks_read;
    row->bricks_skipped = p->nregion - it->bricks_region;
    row->decoded_share = it->decoded_share;
    if (j == 0 && it->group_start) {
        row->group_start = 1;
        memcpy(row->reason, it->reason, sizeof row->reason);
    }
}

/* Shows frame `row` no earlier than its slot in the paced schedule (deadline k = deadline
 * k-1 + 1/pace_fps, so one late frame is caught up by the next; a frame more than one
 * period late restarts the schedule) and records its display interval. */
static void pace_and_show(cdvr_player *p, cdvr_frame_row *row)
{
    double now = cdvr_now_ms();
    if (p->opts.pace_fps > 0) {
        double period = 1e3 / p->opts.pace_fps;
        double deadline = p->t_deadline + period;
        if (now > deadline + period)
            deadline = now;
        sleep_ms(deadline - now);
        p->t_deadline = deadline;
        now = cdvr_now_ms();
    }
    row->interval_ms = now - p->t_last_frame;
    p->t_last_frame = now;
}

/* The composite hook for one frame (player.h); its failure fails the frame. */
static void composite(cdvr_player *p, cdvr_frame_row *row, const cdvr_camera *cam,
                      cdvr_image **img, cdvr_error *ferr)
{
    if (!p->opts.composite)
        return;
    cdvr_error cerr;
    cdvr_error_clear(&cerr);
    row->status = ferr->status;
    double t0 = cdvr_now_ms(), wait = 0;
    cdvr_status s = p->opts.composite(p->opts.composite_ud, row, cam, img, &wait, &cerr);
    row->wait_ms = wait;
    row->composite_ms = cdvr_now_ms() - t0 - wait;
    if (s != CDVR_OK && ferr->status == CDVR_OK) {
        *ferr = cerr;
        if (ferr->status == CDVR_OK)
            cdvr_error_set(ferr, s, "composite failed");
    }
}

/* Annotations of a frame shown (player.h): the TF, the frame's camera and timestep. */
static void annotate_frame(const cdvr_player *p, const cdvr_frame_row *row,
                           const cdvr_camera *cam, cdvr_image *img, cdvr_error *ferr)
{
    cdvr_annotate_opts o = *p->opts.annotate;
    char text[64];
    snprintf(text, sizeof text, "t = %zu / %zu", row->t + 1,
             cdvr_store_get_info(p->opts.store)->timesteps);
    o.tf = p->opts.tf;
    o.camera = cam;
    o.time = p->opts.annotate_time ? text : NULL;
    cdvr_annotate(img, &o, ferr);
}

/* Renders the frames of one item. Returns non-OK only for callback failures (stop the run).
 * frame_ms: the work from the end of the previous chunk's last frame to the end of this
 * chunk's last frame, pacing waits excluded, shared equally by the chunk's frames. */
static cdvr_status consume(cdvr_player *p, chunk_item *it, cdvr_error *err)
{
    size_t n = it->nframes;
    size_t first_row = p->nrows;
    double work_start = p->t_last_frame, work_ms = 0;
    double upload_ms = 0, decode_ms = 0;
    cdvr_error frame_err = it->err;
    if (n == 0)
        return CDVR_OK;
    if (frame_err.status == CDVR_OK && it->bricks_read > 0)
        upload_decode(p, it, &upload_ms, &decode_ms, &frame_err);
    cdvr_status cb = CDVR_OK;
    for (size_t j = 0; j < n && cb == CDVR_OK; j++) {
        cdvr_frame_row *row = add_row(p);
        if (!row)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: cannot grow the frame table");
        fill_row(p, row, it, j, n);
        row->upload_ms = upload_ms / n;
        row->decode_ms = decode_ms / n;
        cdvr_image *img = NULL;
        cdvr_error ferr = frame_err;
        if (ferr.status == CDVR_OK)
            setup_render(p, it, row->t, &it->cams[j], &img, &row->setup_ms, &row->render_ms,
                         &ferr);
#if CDVR_HAVE_OPENCL
        if (ferr.status == CDVR_OK && p->on_stream && it->bricks_region > 0)
            row->samples = cdvr_cl_last_samples(p->stream);
#endif
        if (ferr.status != CDVR_OK) {
            cdvr_image_free(img);
            img = NULL;
        }
        composite(p, row, &it->cams[j], &img, &ferr);
        if (img && ferr.status == CDVR_OK && p->opts.annotate)
            annotate_frame(p, row, &it->cams[j], img, &ferr);
#if CDVR_HAVE_OPENCL
        if (p->stream)
            row->device_bytes = cdvr_cl_stream_bytes(p->stream);
#endif
        if (p->opts.cache)
            cache_row(p, it, row);
        row->status = ferr.status;
        if (ferr.status != CDVR_OK)
            snprintf(row->error, sizeof row->error, "%s", ferr.msg);
        if (p->opts.frame_fn && (ferr.status != CDVR_OK || img)) /* a failed frame too: img NULL */
            cb = p->opts.frame_fn(p->opts.frame_ud, row, ferr.status == CDVR_OK ? img : NULL, err);
        cdvr_image_free(img);
        work_ms += cdvr_now_ms() - work_start;
        pace_and_show(p, row);
        work_start = p->t_last_frame;
    }
    size_t shown = p->nrows - first_row;
    for (size_t i = first_row; i < p->nrows; i++) {
        p->rows[i].frame_ms = work_ms / (double)shown;
        if (p->opts.pace_fps <= 0)
            p->rows[i].interval_ms = p->rows[i].frame_ms;
    }
    return cb;
}

/* Plays an item, then stops the run with its planning error if it has one. */
static cdvr_status play_item(cdvr_player *p, chunk_item *it, cdvr_error *err)
{
    cdvr_status s = consume(p, it, err);
    if (s == CDVR_OK && it->stop.status != CDVR_OK) {
        if (err)
            *err = it->stop;
        s = it->stop.status;
    }
    return s;
}

/* ---- threads ---------------------------------------------------------------------------- */

static chunk_item *take_free(cdvr_player *p)
{
    pthread_mutex_lock(&p->mu);
    while (!p->free_items.head && !p->abort)
        pthread_cond_wait(&p->cv, &p->mu);
    chunk_item *it = p->abort ? NULL : queue_pop(&p->free_items);
    pthread_mutex_unlock(&p->mu);
    return it;
}

static void put(cdvr_player *p, item_queue *q, chunk_item *it)
{
    pthread_mutex_lock(&p->mu);
    queue_push(q, it);
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
}

/* The reader and the unzip workers read and decode ahead of the frame being played; the
 * calling thread and the device's threads render it. When they compete for the cores the
 * frame should win: at the same priority a worker's time slice delays the calling thread's
 * wake-ups and the device's threads (zfp1 512^2 playback on 2 cores: the calling thread
 * once waited 5 ms for a core while the other sat idle). So each background thread lowers
 * its own priority by `increment` (Linux nice values are per thread; threads it starts,
 * such as a codec's decode threads, inherit it). Measured on 2 cores, 8 alternating rounds
 * against the same priority, fps: raw 64^2 1.24x at +5 (+7 1.26x, +10 1.23x); zfp1 512^2
 * (with decode_group's lock around the decode alone) 1.08x at +5 (+3 1.03x, +8 1.06x).
 * Elsewhere, and on failure, the priority stays. */
static void lower_priority(int increment)
{
#if defined(__linux__)
    if (increment <= 0)
        return;
    id_t tid = (id_t)syscall(SYS_gettid);
    errno = 0;
    int now = getpriority(PRIO_PROCESS, tid);
    if (now == -1 && errno != 0)
        return;
    (void)setpriority(PRIO_PROCESS, tid, now + increment > 19 ? 19 : now + increment);
#else
    (void)increment;
#endif
}

static void *reader_main(void *arg)
{
    cdvr_player *p = arg;
    lower_priority(p->background_nice);
    for (;;) {
        chunk_item *it = take_free(p);
        if (!it)
            break;
        if (plan_and_read(p, it, 1) == 0) {
            put(p, &p->free_items, it);
            break;
        }
        put(p, &p->read_q, it);
        if (it->stop.status != CDVR_OK)
            break; /* planning failed: the run ends after this item */
    }
    pthread_mutex_lock(&p->mu);
    p->reader_done = 1;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

typedef struct unzip_worker {
    cdvr_player *p;
    int w;                   /* index: its scratch */
    pthread_t thread;
} unzip_worker;

/* An unzip worker: takes the items in planning order, and hands them over in any order
 * (next_ready restores it). */
static void *unzip_main(void *arg)
{
    cdvr_player *p = ((unzip_worker *)arg)->p;
    int w = ((unzip_worker *)arg)->w;
    lower_priority(p->background_nice);
    for (;;) {
        pthread_mutex_lock(&p->mu);
        while (!p->read_q.head && !p->reader_done && !p->abort)
            pthread_cond_wait(&p->cv, &p->mu);
        chunk_item *it = p->abort ? NULL : queue_pop(&p->read_q);
        pthread_mutex_unlock(&p->mu);
        if (!it)
            break;
        unzip(p, w, it);
        put(p, &p->unzip_q, it);
    }
    pthread_mutex_lock(&p->mu);
    p->workers_done++;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

/* Waits for the next unzipped item in planning order, running the reader's planning
 * requests meanwhile (callbacks run here, on the calling thread). NULL at the end. */
static chunk_item *next_ready(cdvr_player *p)
{
    pthread_mutex_lock(&p->mu);
    for (;;) {
        chunk_item *it = queue_take_seq(&p->unzip_q, p->seq_play);
        if (it) {
            p->seq_play++;
            pthread_mutex_unlock(&p->mu);
            return it;
        }
        if (p->call_state == 1) {
            caller_fn fn = p->call_fn;
            chunk_item *item = p->call_item;
            pthread_mutex_unlock(&p->mu);
            cdvr_error cerr;
            cdvr_error_clear(&cerr);
            fn(p, item, &cerr);
            pthread_mutex_lock(&p->mu);
            p->call_err = cerr;
            p->call_state = 2;
            pthread_cond_broadcast(&p->cv);
            continue;
        }
        if (p->workers_done == p->nworkers || p->abort)
            break;
        pthread_cond_wait(&p->cv, &p->mu);
    }
    pthread_mutex_unlock(&p->mu);
    return NULL;
}

static void abort_run(cdvr_player *p)
{
    pthread_mutex_lock(&p->mu);
    p->abort = 1;
    pthread_cond_broadcast(&p->cv);
    pthread_mutex_unlock(&p->mu);
}

static cdvr_status run_pipelined(cdvr_player *p, cdvr_error *err)
{
    pthread_t reader;
    unzip_worker workers[MAX_UNZIP];
    if (pthread_create(&reader, NULL, reader_main, p) != 0)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: cannot start the reader thread");
    for (int w = 0; w < p->nworkers; w++) {
        workers[w].p = p;
        workers[w].w = w;
        if (pthread_create(&workers[w].thread, NULL, unzip_main, &workers[w]) != 0) {
            abort_run(p);
            pthread_join(reader, NULL);
            while (w-- > 0)
                pthread_join(workers[w].thread, NULL);
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: cannot start unzip thread %d",
                                  w + 1);
        }
    }
    cdvr_status status = CDVR_OK;
    chunk_item *it;
    while ((it = next_ready(p)) != NULL) {
        status = play_item(p, it, err);
        release_slot(p, it);
        put(p, &p->free_items, it);
        if (status != CDVR_OK) {
            abort_run(p);
            break;
        }
    }
    pthread_join(reader, NULL);
    for (int w = 0; w < p->nworkers; w++)
        pthread_join(workers[w].thread, NULL);
    return status;
}

static cdvr_status run_serial(cdvr_player *p, cdvr_error *err)
{
    chunk_item *it = &p->items[0];
    while (plan_and_read(p, it, 0)) {
        unzip(p, 0, it);
        cdvr_status s = play_item(p, it, err);
        release_slot(p, it);
        if (s != CDVR_OK)
            return s;
    }
    return CDVR_OK;
}

/* ---- public ----------------------------------------------------------------------------- */

/* The region of bricks this player reads (opts.region_*), its voxel box and brick count. */
static cdvr_status set_region(cdvr_player *p, cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(p->opts.store);
    int whole = !p->opts.region_hi[0] && !p->opts.region_hi[1] && !p->opts.region_hi[2];
    p->nregion = 1;
    for (int a = 0; a < 3; a++) {
        p->region_lo[a] = whole ? 0 : p->opts.region_lo[a];
        p->region_hi[a] = whole ? info->bricks[a] : p->opts.region_hi[a];
        if (p->region_lo[a] > p->region_hi[a] || p->region_hi[a] > info->bricks[a])
            return cdvr_error_set(err, CDVR_ERR_ARG, "player: brick region %zu..%zu on axis %d "
                                  "is not inside the grid of %zu bricks", p->region_lo[a],
                                  p->region_hi[a], a, info->bricks[a]);
        p->nregion *= p->region_hi[a] - p->region_lo[a];
    }
    if (p->nregion == 0) { /* an empty region: nothing to read, transparent frames */
        for (int a = 0; a < 3; a++) {
            p->data_lo[a] = p->data_hi[a] = p->own_lo[a] = p->own_hi[a] = p->vox_lo[a] = 0;
            p->vox_dims[a] = 1;
        }
        p->voxels = 1;
        p->clipped = 1;
        return CDVR_OK;
    }
    const size_t *g = info->bricks;
    for (int a = 0; a < 3; a++) {
        p->data_lo[a] = p->region_lo[a] ? p->region_lo[a] - 1 : 0;
        p->data_hi[a] = p->region_hi[a];
    }
#define BRICK_INDEX(v) ((v)[0] + g[0] * ((v)[1] + g[1] * (v)[2]))
    size_t last[3] = {p->region_hi[0] - 1, p->region_hi[1] - 1, p->region_hi[2] - 1};
    size_t lo[3], dims[3], llo[3], ldims[3], dlo[3], ddims[3];
    cdvr_store_brick_box(info, BRICK_INDEX(p->region_lo), lo, dims);
    cdvr_store_brick_box(info, BRICK_INDEX(last), llo, ldims);
    cdvr_store_brick_box(info, BRICK_INDEX(p->data_lo), dlo, ddims);
#undef BRICK_INDEX
    p->voxels = 1;
    p->clipped = 0;
    for (int a = 0; a < 3; a++) {
        p->own_lo[a] = lo[a];
        p->own_hi[a] = llo[a] + ldims[a] - 1;
        p->vox_lo[a] = dlo[a];
        p->vox_dims[a] = p->own_hi[a] + 1 - dlo[a];
        p->voxels *= p->vox_dims[a];
        p->clipped |= p->own_lo[a] != 0 || p->own_hi[a] + 1 != info->dims[a];
    }
    return CDVR_OK;
}

/* The environment variable `name` when it is a whole decimal number in lo..hi, else
 * `otherwise`. */
static long env_number(const char *name, long lo, long hi, long otherwise)
{
    const char *env = getenv(name);
    char *end = NULL;
    long n = env ? strtol(env, &end, 10) : 0;
    return !env || end == env || *end != '\0' || n < lo || n > hi ? otherwise : n;
}

/* CDVR_PLAYER_NICE when set to a number in 0..19, else DEFAULT_BACKGROUND_NICE. */
static int background_nice(void)
{
    return (int)env_number("CDVR_PLAYER_NICE", 0, 19, DEFAULT_BACKGROUND_NICE);
}

/* Unzip workers of a pipelined player: `requested` (player.h) when > 0, else
 * CDVR_UNZIP_THREADS when set to a number > 0, else 2 on a machine with 2 or more cores and 1
 * otherwise; at most MAX_UNZIP. */
static int unzip_workers(int requested)
{
    long n = requested;
    if (n <= 0)
        n = env_number("CDVR_UNZIP_THREADS", 1, LONG_MAX,
                       sysconf(_SC_NPROCESSORS_ONLN) >= 2 ? 2 : 1);
    return n > MAX_UNZIP ? MAX_UNZIP : (int)n;
}

/* World positions of the 8 corners of brick b's cells: origin + D * (index * spacing). */
static void brick_corners(const cdvr_store_info *info, size_t b, double out[8][3])
{
    size_t lo[3], dims[3];
    cdvr_store_brick_box(info, b, lo, dims);
    for (int c = 0; c < 8; c++) {
        double q[3];
        for (int a = 0; a < 3; a++)
            q[a] = (double)(lo[a] + ((c >> a) & 1) * (dims[a] - 1)) * info->spacing[a];
        for (int r = 0; r < 3; r++) {
            out[c][r] = info->origin[r];
            for (int a = 0; a < 3; a++)
                out[c][r] += info->direction[3 * r + a] * q[a];
        }
    }
}

/* Bounded work: the render options every renderer checks (render.h) on the store's box, and
 * the rates that pace the run (player.h: CDVR_PLAYER_MIN_READ_MBPS, CDVR_PLAYER_MIN_FPS). */
static cdvr_status check_work_bounds(const cdvr_player_opts *opts, const cdvr_store_info *info,
                                     cdvr_error *err)
{
    cdvr_render_opts ro = {.step = opts->step, .unit = opts->unit, .term_alpha = opts->term_alpha};
    cdvr_error rerr;
    cdvr_status st = cdvr_render_opts_check_box(info->dims, info->spacing, &ro, &rerr);
    if (st != CDVR_OK) {
        const char *why = strncmp(rerr.msg, "render: ", 8) == 0 ? rerr.msg + 8 : rerr.msg;
        return cdvr_error_set(err, st, "player: %s", why);
    }
    if (isnan(opts->read_mbps) || (opts->read_mbps > 0 && opts->read_mbps < CDVR_PLAYER_MIN_READ_MBPS) ||
        opts->read_mbps > CDVR_PLAYER_MAX_RATE)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: read_mbps %g outside %g..%g MB/s (0: no cap)",
                              opts->read_mbps, CDVR_PLAYER_MIN_READ_MBPS, CDVR_PLAYER_MAX_RATE);
    if (isnan(opts->pace_fps) || (opts->pace_fps > 0 && opts->pace_fps < CDVR_PLAYER_MIN_FPS) ||
        opts->pace_fps > CDVR_PLAYER_MAX_RATE)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: pace_fps %g outside %g..%g frames/s (0: no pacing)",
                              opts->pace_fps, CDVR_PLAYER_MIN_FPS, CDVR_PLAYER_MAX_RATE);
    return CDVR_OK;
}

#if CDVR_HAVE_OPENCL
/* Per variant of a fetch-mode codec: whether its groups decode in bulk on the host, by the
 * path remembered for the device (cdvr_cl_fetch_path_for; BULK while none is measured: the
 * player's pipeline does not measure). */
static void choose_fetch_paths(cdvr_player *p)
{
    const cdvr_store_info *info = cdvr_store_get_info(p->opts.store);
    for (size_t v = 0; v < info->nvariants; v++) {
        const cdvr_chunk_info *ch = cdvr_store_chunk(p->opts.store, v, 0);
        if (ch && ch->codec && ch->codec->cl_mode == CDVR_CODEC_CL_FETCH)
            p->fetch_bulk[v] = cdvr_cl_fetch_path_for(p->stream, ch->codec, ch->count) !=
                               CDVR_CL_FETCH_SAMPLE;
    }
}
#endif

cdvr_status cdvr_player_create(const cdvr_player_opts *opts, cdvr_player **out, cdvr_error *err)
{
    *out = NULL;
    if (!opts->store || !opts->tf)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: store and tf are required");
    const cdvr_store_info *info = cdvr_store_get_info(opts->store);
    if (opts->variant < 0 || (size_t)opts->variant >= info->nvariants)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: variant %d out of range 1..%zu", opts->variant + 1, info->nvariants);
    if (cdvr_camera_validate(&opts->camera, err) != CDVR_OK)
        return err ? err->status : CDVR_ERR_ARG;
    const cdvr_render_method *method = opts->method ? opts->method
                                                    : cdvr_render_method_find("raycast");
    if (cdvr_render_method_check_device(method, opts->device, err) != CDVR_OK)
        return err ? err->status : CDVR_ERR_UNSUPPORTED;
    cdvr_status cs = check_work_bounds(opts, info, err);
    if (cs != CDVR_OK)
        return cs;
    cdvr_player *p = calloc(1, sizeof *p);
    if (!p)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: out of memory");
    p->opts = *opts;
    p->opts.method = method;
    if (!opts->method)
        method->params_default(&p->opts.method_params);
    p->on_stream = opts->device == CDVR_DEVICE_CL && method->render_stream != NULL;
    p->lod_error = opts->lod_error;
    if (p->opts.ring <= 0)
        p->opts.ring = 3;
    p->group_len = cdvr_player_group_length(opts->store);
    p->nbricks = info->nbricks;
    p->stride = opts->frame_stride ? opts->frame_stride : 1;
    p->phase = opts->frame_phase % p->stride;
    cdvr_status rs = set_region(p, err);
    if (rs == CDVR_OK && p->clipped &&
        (opts->look.blend != CDVR_BLEND_COMPOSITE || opts->look.shade.enabled ||
         opts->look.gradient_opacity.npoints))
        rs = cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "player: a box of the bricks (sort-last) "
                            "renders only the composite blend mode without shading");
    if (rs == CDVR_OK && opts->cache &&
        (p->clipped || (!p->on_stream && opts->device != CDVR_DEVICE_CPU)))
        rs = cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "player: cache=true renders on the cpu "
                            "device, or on cl with the raycast method, the whole volume (not a "
                            "box of the bricks)");
    if (rs == CDVR_OK && p->clipped && !method->bricks)
        rs = cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "player: method '%s' cannot render a "
                            "box of the bricks (sort-last distribution needs a method that "
                            "honours clipping: raycast)", method->name);
    if (rs != CDVR_OK) {
        free(p);
        return rs;
    }
    p->nitems = (size_t)p->opts.ring * 2 + 1;
    p->items = calloc(p->nitems, sizeof *p->items);
    for (size_t i = 0; p->items && i < p->nitems; i++)
        if (!(p->items[i].parts = calloc(p->nbricks, sizeof *p->items[i].parts)))
            p->nitems = i; /* free what was made, then fail below */
    p->host_decodes = calloc(info->nvariants, sizeof *p->host_decodes);
    p->fetch_bulk = calloc(info->nvariants, sizeof *p->fetch_bulk);
    p->turn_passed = calloc(p->nitems ? p->nitems : 1, 1);
    p->nworkers = p->opts.pipelined ? unzip_workers(p->opts.unzip_threads) : 1;
    p->background_nice = background_nice();
    p->nslots = p->nworkers + 1;
    pthread_mutex_init(&p->mu, NULL);
    pthread_mutex_init(&p->decode_mu, NULL);
    pthread_cond_init(&p->cv, NULL);
    if (!p->items || p->nitems != (size_t)p->opts.ring * 2 + 1 || !p->host_decodes ||
        !p->fetch_bulk || !p->turn_passed) {
        cdvr_player_free(p);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: out of memory");
    }
    p->own = calloc(p->nbricks, sizeof *p->own);
    if (!p->own || !(p->corners = malloc(p->nbricks * 24 * sizeof *p->corners))) {
        cdvr_player_free(p);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "player: out of memory");
    }
    for (size_t b = 0; b < p->nbricks; b++)
        brick_corners(info, b, (double(*)[3])(p->corners + 24 * b));
    if (!p->on_stream && opts->device != CDVR_DEVICE_CPU && !opts->ctx) {
        cdvr_status s = cdvr_render_ctx_create(&p->own_ctx, err);
        if (s != CDVR_OK) {
            cdvr_player_free(p);
            return s;
        }
    }
    if (p->on_stream) {
#if CDVR_HAVE_OPENCL
        cdvr_status s = cdvr_cl_open(&p->cl, err);
        if (s == CDVR_OK)
            s = cdvr_cl_stream_create(p->cl, p->vox_dims, &p->stream, err);
        if (s == CDVR_OK) {
            cdvr_cl_set_skipping(p->stream, opts->empty_skip);
            cdvr_cl_set_fetch_path(p->stream, (cdvr_cl_fetch_path)opts->fetch_path);
            choose_fetch_paths(p);
        }
        if (s != CDVR_OK) {
            cdvr_player_free(p);
            return s;
        }
#else
        cdvr_player_free(p);
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "player: device 'cl': this cdvr was built without OpenCL");
#endif
    }
    *out = p;
    return CDVR_OK;
}

void cdvr_player_free(cdvr_player *p)
{
    if (!p)
        return;
    for (size_t i = 0; p->items && i < p->nitems; i++) {
        for (size_t b = 0; p->items[i].parts && b < p->nbricks; b++) {
            free(p->items[i].parts[b].stored);
            free(p->items[i].parts[b].payload);
            free(p->items[i].parts[b].ranges);
        }
        free(p->items[i].parts);
        free(p->items[i].cams);
        for (size_t f = 0; f < p->items[i].grids_cap; f++)
            cdvr_skip_grid_free(&p->items[i].grids[f]);
        cdvr_skip_grid_free(&p->items[i].coarse);
        free(p->items[i].grids);
        free(p->items[i].need);
    }
    free(p->corners);
    free(p->own);
    free(p->items);
    free(p->rows);
    for (int k = 0; k < MAX_SLOTS; k++)
        free(p->slots[k]);
    for (int w = 0; w < MAX_UNZIP; w++)
        free(p->brick_frames[w]);
    free(p->host_decodes);
    free(p->fetch_bulk);
    free(p->turn_passed);
#if CDVR_HAVE_OPENCL
    cdvr_cl_stream_free(p->stream);
    cdvr_cl_close(p->cl);
#endif
    cdvr_render_ctx_free(p->own_ctx);
    cdvr_brick_cache_free(p->cache);
    pthread_mutex_destroy(&p->mu);
    pthread_mutex_destroy(&p->decode_mu);
    pthread_cond_destroy(&p->cv);
    free(p);
}

cdvr_status cdvr_player_run(cdvr_player *p, size_t first, size_t frames, cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(p->opts.store);
    if (first >= info->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: first timestep %zu out of range 1..%zu", first + 1, info->timesteps);
    size_t left = info->timesteps - first;
    p->stopped_early = !p->opts.loop && frames > left ? frames - left : 0;
    p->first = first;
    p->frames = frames - p->stopped_early;
    p->nrows = 0;
    p->planned = 0;
    p->current_variant = p->opts.variant;
    p->have_group = 0;
    p->reader_done = p->abort = p->workers_done = 0;
    p->seq_next = p->seq_play = p->slot_turn = 0;
    memset(p->turn_passed, 0, p->nitems);
    for (int k = 0; k < MAX_SLOTS; k++) /* items of an earlier run left in flight hold none now */
        p->slot_busy[k] = 0;
    p->call_state = 0;
    p->tf_prefix[0] = 0;
    for (int i = 0; i < 256; i++) /* read at run start: the TF of this run */
        p->tf_prefix[i + 1] = p->tf_prefix[i] + (p->opts.tf->table[i][3] > 0.0f);
    memset(&p->free_items, 0, sizeof p->free_items);
    memset(&p->read_q, 0, sizeof p->read_q);
    memset(&p->unzip_q, 0, sizeof p->unzip_q);
    for (size_t i = 0; i < p->nitems; i++)
        queue_push(&p->free_items, &p->items[i]);
    p->t_last_frame = p->t_deadline = cdvr_now_ms();
    cdvr_error e; /* err may be NULL (error.h): the stages always get a real one */
    cdvr_error_clear(&e);
    cdvr_status s = p->opts.pipelined ? run_pipelined(p, &e) : run_serial(p, &e);
    if (err)
        *err = e;
    return s;
}

cdvr_status cdvr_player_set_lod_error(cdvr_player *p, double lod_error, cdvr_error *err)
{
    if (!(lod_error >= 0) || lod_error > 1e12)
        return cdvr_error_set(err, CDVR_ERR_ARG, "player: lod_error %g (pixels, 0 .. 1e12)",
                              lod_error);
    p->lod_error = lod_error;
    return CDVR_OK;
}

double cdvr_player_lod_error(const cdvr_player *p)
{
    return p->lod_error;
}

size_t cdvr_player_stopped_early(const cdvr_player *p)
{
    return p->stopped_early;
}

const cdvr_frame_row *cdvr_player_rows(const cdvr_player *p, size_t *count)
{
    *count = p->nrows;
    return p->rows;
}

double cdvr_player_fps(const cdvr_player *p)
{
    double *ms = malloc((p->nrows ? p->nrows : 1) * sizeof *ms);
    if (!ms)
        return 0;
    size_t n = 0;
    for (size_t i = 0; i < p->nrows; i++)
        if (p->rows[i].status == CDVR_OK)
            ms[n++] = p->rows[i].interval_ms;
    double med = cdvr_median(ms, n);
    free(ms);
    return med > 0 ? 1000.0 / med : 0;
}
