/* core/render/cache/brick_cache.c - the brick cache, its level of detail and its fetch
 * (cdvr/brick_cache.h; the OpenCL twin of the fetch is kernels/render/brick_cache.cl). */
#include "cdvr/brick_cache.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/timing.h"

typedef struct far_key {        /* a brick and its distance, for the farthest-first order */
    double dist;
    size_t brick;
} far_key;

typedef struct cache_entry {
    size_t t, level, brick;      /* key: timestep, level, brick of that level */
    uint8_t *voxels;
    size_t bytes;
    size_t lo[3], dims[3];       /* the brick's box at its level */
    uint64_t last_used;          /* frame stamp */
    size_t pool_offset;          /* in the payload of the frame that last used it */
    int pinned;                  /* async: the coarsest level of the frame's timestep */
    int ranged;                  /* vmin, vmax hold the range of the voxels */
    uint8_t vmin, vmax;
    int apron_done;              /* level 0: its lower apron holds its owners' voxels */
    uint8_t *ranges;             /* per range brick over the box (entry_ranges): min, max */
    size_t range_lo[3], range_n[3]; /* those range bricks (level-0 grid), per axis */
} cache_entry;

typedef struct brick_job {       /* async: a brick for the worker, then its decoded voxels */
    size_t t, level, brick;
    cdvr_volume *vol;
    cdvr_error err;
} brick_job;

/* The asynchronous mode's worker (cdvr_brick_cache_set_async). It touches only the jobs under
 * mu and the store (whose decode is thread-safe, store.h); the entries stay the frame
 * thread's. */
typedef struct brick_worker {
    pthread_t thread;
    pthread_mutex_t mu;
    pthread_cond_t work, idle;
    const cdvr_brick_cache *c;
    brick_job *queue, *done;     /* queue[next..nqueued) waiting; done: decoded, not yet taken */
    brick_job *taken;            /* the frame thread's copy of done */
    size_t nqueued, next, ndone;
    brick_job current;           /* the job being decoded when busy */
    int busy, stop;
} brick_worker;

struct cdvr_brick_cache {
    const cdvr_store *st;
    size_t v;
    uint64_t budget;
    uint64_t asked_budget;       /* the budget asked for (budget is it capped: capped_budget) */
    size_t nlevels;
    const cdvr_store *level[CDVR_STORE_MAX_LEVELS];
    size_t dims[3], grid[3], nbricks;
    size_t *owner[3];            /* level 0: voxel coordinate -> brick along the axis */
    size_t *level_owner[CDVR_STORE_MAX_LEVELS][3]; /* the same per level */
    double *dist;                /* per level-0 brick: eye distance of the frame */
    size_t *choice, *order;      /* per level-0 brick: level; bricks farthest first */
    struct far_key *keys;        /* scratch for the order */
    size_t *entry_of;            /* per level-0 brick: its entry this frame */
    cache_entry *entries;
    size_t nentries, cap;
    uint64_t cache_bytes, stamp;
    uint8_t *payload;
    size_t payload_cap, payload_bytes;
    uint8_t *dense;              /* cdvr_brick_cache_dense's frame, or NULL */
    size_t *dense_key;           /* per level-0 brick: t, level, brick of the entry dense holds */
    int dense_valid;             /* dense_key describes dense */
    cdvr_brick_cache_stats stats;
    brick_worker *worker;        /* the asynchronous mode, or NULL */
    uint64_t reserved;           /* async: bytes of the coarsest level (pinned) */
    size_t pinned_t;             /* async: the timestep whose coarsest level is pinned */
    brick_job *requests;         /* async: this frame's missing bricks, then the next
                                    timestep's (at most 3 nbricks) */
    size_t nrequests;
    uint64_t requested_bytes;    /* async: voxel bytes of the requests */
    size_t next_t;               /* async: cdvr_brick_cache_set_next's timestep, or -1 */
    /* cdvr_brick_cache_skip_grid's grid and the frame it was made for: per level-0 brick the
     * (t, level, brick) of its entry, and the count of apron patches then */
    cdvr_skip_grid skip;
    int grid_made;
    size_t *grid_key;
    uint8_t grid_tf[256];        /* the TF entries with opacity the grid was made for */
    int grid_level0_visible;     /* and its level0_visible */
    uint64_t patches, grid_patches;
    /* level 0's ranges of timestep table_t from the store's range tables (bricks of
     * 2^table.shift), for the bricks rendered coarser (level0_table) */
    cdvr_skip_grid table;
    size_t table_t;
    int table_state;             /* 0 not read, 1 read, -1 the store has none */
};

/* ---- the fetch (the definition; brick_cache.cl mirrors it) ------------------------------- */

/* Word i of the payload (little endian), i clamped below the payload's n / 4 words. */
static uint32_t word_at(const uint8_t *p, size_t nw, size_t i)
{
    const uint8_t *q = p + 4 * (i < nw ? i : nw - 1);
    return (uint32_t)q[0] | (uint32_t)q[1] << 8 | (uint32_t)q[2] << 16 | (uint32_t)q[3] << 24;
}

static uint32_t coord_at(size_t x, uint32_t lvl, uint32_t lo, uint32_t d)
{
    long c = (long)(x >> lvl) - (long)lo;
    return c < 0 ? 0 : c > (long)d - 1 ? d - 1 : (uint32_t)c;
}

static size_t min_sz(size_t a, size_t b)
{
    return a < b ? a : b;
}

uint8_t cdvr_brick_cache_fetch(const uint8_t *p, size_t n, const size_t dims[3], size_t x,
                               size_t y, size_t z)
{
    if (n < CDVR_BRICK_CACHE_MIN_BYTES)
        return 0;
    size_t nw = n / 4, X = dims[0], Y = dims[1], o = CDVR_BRICK_CACHE_HEADER_WORDS;
    size_t bi = word_at(p, nw, o + x), bj = word_at(p, nw, o + X + y);
    size_t bk = word_at(p, nw, o + X + Y + z);
    size_t e = min_sz(word_at(p, nw, 5) / 4 +
                          CDVR_BRICK_CACHE_ENTRY_WORDS *
                              (bi + (size_t)word_at(p, nw, 1) * (bj + (size_t)word_at(p, nw, 2) * bk)),
                      nw - CDVR_BRICK_CACHE_ENTRY_WORDS);
    size_t base = (size_t)word_at(p, nw, 4) + word_at(p, nw, e);
    uint32_t lvl = word_at(p, nw, e + 1);
    lvl = lvl < 15 ? lvl : 15;
    uint32_t lo[3], d[3];
    for (int a = 0; a < 3; a++) {
        lo[a] = word_at(p, nw, e + 2 + (size_t)a);
        d[a] = word_at(p, nw, e + 5 + (size_t)a);
        d[a] = d[a] ? d[a] : 1;
    }
    uint32_t cx = coord_at(x, lvl, lo[0], d[0]), cy = coord_at(y, lvl, lo[1], d[1]);
    uint32_t cz = coord_at(z, lvl, lo[2], d[2]);
    if (lvl == 0)
        return p[min_sz(base + cx + (size_t)d[0] * (cy + (size_t)d[1] * cz), n - 1)];
    uint32_t mask = (1u << lvl) - 1u, s = 1u << lvl;
    uint32_t f[3] = {(uint32_t)x & mask, (uint32_t)y & mask, (uint32_t)z & mask};
    uint32_t xs[2] = {cx, cx + 1 < d[0] ? cx + 1 : d[0] - 1};
    uint32_t ys[2] = {cy, cy + 1 < d[1] ? cy + 1 : d[1] - 1};
    uint32_t zs[2] = {cz, cz + 1 < d[2] ? cz + 1 : d[2] - 1};
    uint64_t sum = 0;
    for (int k = 0; k < 2; k++)
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++) {
                uint64_t w = (uint64_t)(i ? f[0] : s - f[0]) * (j ? f[1] : s - f[1]) *
                             (k ? f[2] : s - f[2]);
                size_t at = base + xs[i] + (size_t)d[0] * (ys[j] + (size_t)d[1] * zs[k]);
                sum += w * p[min_sz(at, n - 1)];
            }
    uint32_t shift = 3 * lvl;
    return (uint8_t)((sum + (1ull << (shift - 1))) >> shift);
}

/* ---- the codec table (fetch mode) -------------------------------------------------------- */

static const cdvr_codec_param_doc no_params[] = {{NULL, NULL, NULL}};

static void bc_params_default(cdvr_codec_params *p)
{
    memset(p, 0, sizeof *p);
}

static cdvr_status bc_params_set(cdvr_codec_params *p, const char *key, const char *value,
                                 cdvr_error *err)
{
    (void)p;
    return cdvr_error_set(err, CDVR_ERR_ARG, "brick cache: no parameter '%s' (= '%s')", key,
                          value);
}

static int bc_params_get(const cdvr_codec_params *p, const char *key, char *out, size_t n)
{
    (void)p; (void)key; (void)out; (void)n;
    return -1;
}

static cdvr_status bc_params_check(const cdvr_codec_params *p, cdvr_error *err)
{
    (void)p; (void)err;
    return CDVR_OK;
}

static void bc_variant_name(const cdvr_codec_params *p, char *name, size_t n)
{
    (void)p;
    snprintf(name, n, "cache");
}

static cdvr_status bc_shape(const cdvr_codec_params *p, const size_t dims[3],
                            cdvr_codec_shape *out, cdvr_error *err)
{
    (void)p; (void)dims; (void)err;
    out->timesteps = 1;
    out->payload_bytes = 0;
    out->bound_bytes = (size_t)1 << 62;
    return CDVR_OK;
}

static cdvr_status bc_encode(const cdvr_codec_params *p, const size_t dims[3],
                             const uint8_t *const *frames, size_t count, uint8_t *out,
                             size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    (void)p; (void)dims; (void)frames; (void)count; (void)out; (void)out_cap; (void)out_bytes;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "brick cache: payloads are laid out by "
                          "the cache, not encoded");
}

static cdvr_status bc_decode(const cdvr_codec_params *p, const size_t dims[3], const uint8_t *in,
                             size_t in_bytes, uint8_t *const *frames, size_t count,
                             cdvr_error *err)
{
    (void)p;
    if (count != 1 || in_bytes < CDVR_BRICK_CACHE_MIN_BYTES ||
        word_at(in, in_bytes / 4, 0) != CDVR_BRICK_CACHE_MAGIC)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "brick cache: not a cache payload");
    uint8_t *out = frames[0];
    for (size_t z = 0; z < dims[2]; z++)
        for (size_t y = 0; y < dims[1]; y++)
            for (size_t x = 0; x < dims[0]; x++)
                *out++ = cdvr_brick_cache_fetch(in, in_bytes, dims, x, y, z);
    return CDVR_OK;
}

static const cdvr_codec brick_cache_codec = {
    .name = "brick_cache",
    .id = 0x7fffff01u,
    .description = "decoded bricks behind a page table (the brick cache's payload)",
    .params = no_params,
    .params_default = bc_params_default,
    .params_set = bc_params_set,
    .params_get = bc_params_get,
    .params_check = bc_params_check,
    .variant_name = bc_variant_name,
    .shape = bc_shape,
    .encode = bc_encode,
    .decode = bc_decode,
    .cl_mode = CDVR_CODEC_CL_FETCH,
    .cl_file = "render/brick_cache.cl",
    .cl_function = "brick_cache_fetch",
};

const cdvr_codec *cdvr_brick_cache_codec(void)
{
    return &brick_cache_codec;
}

/* ---- geometry ---------------------------------------------------------------------------- */

/* Per axis: voxel coordinate -> owner brick along the axis, for the store's grid. */
static cdvr_status owner_tables(const cdvr_store_info *in, size_t *tab[3], cdvr_error *err)
{
    size_t stride[3] = {1, in->bricks[0], in->bricks[0] * in->bricks[1]};
    for (int a = 0; a < 3; a++) {
        tab[a] = malloc(in->dims[a] * sizeof *tab[a]);
        if (!tab[a])
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory");
        for (size_t i = 0; i < in->bricks[a]; i++) {
            size_t lo[3], d[3];
            cdvr_store_brick_owned(in, i * stride[a], lo, d);
            for (size_t x = lo[a]; x < lo[a] + d[a] && x < in->dims[a]; x++)
                tab[a][x] = i;
        }
    }
    return CDVR_OK;
}

/* The worker's buffers and itself (NULL: nothing). */
static void worker_free(brick_worker *w)
{
    if (!w)
        return;
    free(w->queue);
    free(w->done);
    free(w->taken);
    free(w);
}

static void worker_stop(cdvr_brick_cache *c);

void cdvr_brick_cache_free(cdvr_brick_cache *c)
{
    if (!c)
        return;
    worker_stop(c);
    free(c->requests);
    for (int a = 0; a < 3; a++)
        free(c->owner[a]);
    for (size_t l = 0; l < CDVR_STORE_MAX_LEVELS; l++)
        for (int a = 0; a < 3; a++)
            free(c->level_owner[l][a]);
    for (size_t i = 0; i < c->nentries; i++) {
        free(c->entries[i].voxels);
        free(c->entries[i].ranges);
    }
    free(c->entries);
    free(c->dist);
    free(c->choice);
    free(c->order);
    free(c->entry_of);
    free(c->keys);
    free(c->payload);
    free(c->dense);
    free(c->dense_key);
    cdvr_skip_grid_free(&c->skip);
    cdvr_skip_grid_free(&c->table);
    free(c->grid_key);
    free(c);
}

/* The budget the cache keeps to: the one asked for, at most what a payload's 32-bit pool
 * offsets reach past the tables (layout): a larger budget renders coarser instead of failing. */
static uint64_t capped_budget(const cdvr_store_info *in, uint64_t asked)
{
    uint64_t axes = (uint64_t)in->dims[0] + in->dims[1] + in->dims[2];
    uint64_t tables = 4 * (CDVR_BRICK_CACHE_HEADER_WORDS + axes) +
                      4 * (uint64_t)CDVR_BRICK_CACHE_ENTRY_WORDS * in->nbricks +
                      CDVR_BRICK_CACHE_PAD;
    uint64_t reach = tables < UINT32_MAX ? UINT32_MAX - tables : 1;
    return asked < reach ? asked : reach;
}

cdvr_status cdvr_brick_cache_create(const cdvr_store *st, size_t v, uint64_t budget_bytes,
                                    cdvr_brick_cache **out, cdvr_error *err)
{
    *out = NULL;
    const cdvr_store_info *in = cdvr_store_get_info(st);
    if (v >= in->nvariants || budget_bytes == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "brick cache: variant %zu of %s, budget %llu "
                              "bytes", v + 1, cdvr_store_path(st),
                              (unsigned long long)budget_bytes);
    cdvr_brick_cache *c = calloc(1, sizeof *c);
    if (!c)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory");
    c->st = st;
    c->v = v;
    c->asked_budget = budget_bytes;
    c->budget = capped_budget(in, budget_bytes);
    c->stats.budget_bytes = c->budget;
    c->nlevels = in->nlevels;
    memcpy(c->dims, in->dims, sizeof c->dims);
    memcpy(c->grid, in->bricks, sizeof c->grid);
    c->nbricks = in->nbricks;
    cdvr_status s = owner_tables(in, c->owner, err);
    for (size_t l = 0; s == CDVR_OK && l < c->nlevels; l++) {
        c->level[l] = cdvr_store_level(st, l);
        s = owner_tables(cdvr_store_get_info(c->level[l]), c->level_owner[l], err);
    }
    c->dist = malloc(c->nbricks * sizeof *c->dist);
    c->choice = malloc(c->nbricks * sizeof *c->choice);
    c->order = malloc(c->nbricks * sizeof *c->order);
    c->entry_of = malloc(c->nbricks * sizeof *c->entry_of);
    c->keys = malloc(c->nbricks * sizeof *c->keys);
    if (s == CDVR_OK && (!c->dist || !c->choice || !c->order || !c->entry_of || !c->keys))
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory");
    if (s != CDVR_OK) {
        cdvr_brick_cache_free(c);
        return s;
    }
    *out = c;
    return CDVR_OK;
}

int cdvr_brick_cache_serves(const cdvr_brick_cache *c, const cdvr_store *st, size_t v,
                            uint64_t budget_bytes)
{
    return c && c->st == st && c->v == v && c->asked_budget == budget_bytes;
}

/* The level-l brick standing for level-0 brick b: the one owning the level-l voxel nearest
 * b's centre. */
static size_t level_brick(const cdvr_brick_cache *c, size_t b, size_t l)
{
    if (l == 0)
        return b;
    const cdvr_store_info *in = cdvr_store_get_info(c->st);
    const cdvr_store_info *li = cdvr_store_get_info(c->level[l]);
    size_t lo[3], d[3], idx[3];
    cdvr_store_brick_owned(in, b, lo, d);
    for (int a = 0; a < 3; a++) {
        size_t centre = (lo[a] + lo[a] + d[a] - 1) / 2, cl = centre >> l;
        idx[a] = c->level_owner[l][a][cl < li->dims[a] ? cl : li->dims[a] - 1];
    }
    return idx[0] + li->bricks[0] * (idx[1] + li->bricks[1] * idx[2]);
}

static size_t brick_bytes(const cdvr_brick_cache *c, size_t b, size_t l)
{
    size_t lo[3], d[3];
    cdvr_store_brick_box(cdvr_store_get_info(c->level[l]), level_brick(c, b, l), lo, d);
    return d[0] * d[1] * d[2];
}

/* What brick b at level l adds to the frame's bytes: in the asynchronous mode the coarsest
 * level is pinned, counted once in c->reserved. */
static size_t level_cost(const cdvr_brick_cache *c, size_t b, size_t l)
{
    return c->worker && l + 1 == c->nlevels ? 0 : brick_bytes(c, b, l);
}

/* Distance from the eye to the world bounds of level-0 brick b. */
static double brick_distance(const cdvr_brick_cache *c, size_t b, const double eye[3])
{
    const cdvr_store_info *in = cdvr_store_get_info(c->st);
    size_t lo[3], d[3];
    cdvr_store_brick_box(in, b, lo, d);
    double mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int corner = 0; corner < 8; corner++) {
        double q[3];
        for (int a = 0; a < 3; a++)
            q[a] = (double)(lo[a] + ((corner >> a) & 1 ? d[a] - 1 : 0)) * in->spacing[a];
        for (int r = 0; r < 3; r++) {
            double w = in->origin[r];
            for (int a = 0; a < 3; a++)
                w += in->direction[3 * r + a] * q[a];
            mn[r] = w < mn[r] ? w : mn[r];
            mx[r] = w > mx[r] ? w : mx[r];
        }
    }
    double s = 0;
    for (int r = 0; r < 3; r++) {
        double g = eye[r] < mn[r] ? mn[r] - eye[r] : eye[r] > mx[r] ? eye[r] - mx[r] : 0;
        s += g * g;
    }
    return sqrt(s);
}

static int farther_first(const void *a, const void *b)
{
    const far_key *x = a, *y = b;
    return x->dist > y->dist ? -1 : x->dist < y->dist ? 1 : (x->brick > y->brick) - (x->brick < y->brick);
}

/* 1 when no code of the brick's chunk at t (its recorded value range, over the brick's box)
 * has opacity under tf: the brick adds nothing to the image. */
static int brick_transparent(const cdvr_brick_cache *c, size_t t, size_t b, const cdvr_tf *tf)
{
    size_t chunk = tf ? cdvr_store_chunk_for(c->st, c->v, t, b) : (size_t)-1;
    const cdvr_chunk_info *ci = chunk != (size_t)-1 ? cdvr_store_chunk(c->st, c->v, chunk) : NULL;
    if (!ci || ci->value_min > ci->value_max)
        return 0;
    for (int i = ci->value_min; i <= ci->value_max; i++)
        if (tf->table[i][3] > 0.0f)
            return 0;
    return 1;
}

/* The level of every level-0 brick (see the header); CDVR_ERR_NOMEM when nothing fits. */
static cdvr_status choose_levels(cdvr_brick_cache *c, size_t t, const cdvr_camera *cam,
                                 const cdvr_tf *tf, double lod_error, cdvr_error *err)
{
    const cdvr_store_info *in = cdvr_store_get_info(c->st);
    double smin = fmin(in->spacing[0], fmin(in->spacing[1], in->spacing[2]));
    double tan_half = tan(cam->fov * 3.14159265358979323846 / 360.0);
    uint64_t total = 0, budget = c->budget - c->reserved; /* async: past the pinned level */
    for (size_t b = 0; b < c->nbricks; b++) {
        c->dist[b] = brick_distance(c, b, cam->eye);
        double pixel = cam->orthographic ? cam->ortho_height / cam->height
                                         : 2.0 * c->dist[b] * tan_half / cam->height;
        size_t l = 0;
        while (lod_error > 0 && l + 1 < c->nlevels &&
               smin * (double)(2u << l) <= lod_error * pixel)
            l++;
        c->choice[b] = l;
        c->keys[b] = (far_key){brick_transparent(c, t, b, tf) ? INFINITY : c->dist[b], b};
        total += level_cost(c, b, l);
    }
    qsort(c->keys, c->nbricks, sizeof *c->keys, farther_first);
    for (size_t i = 0; i < c->nbricks; i++)
        c->order[i] = c->keys[i].brick;
    for (int coarsened = 1; total > budget && coarsened;) {
        coarsened = 0;
        for (size_t i = 0; i < c->nbricks && total > budget; i++) {
            size_t b = c->order[i], l = c->choice[b];
            if (l + 1 >= c->nlevels)
                continue;
            total = total - level_cost(c, b, l) + level_cost(c, b, l + 1);
            c->choice[b] = l + 1;
            coarsened = 1;
        }
    }
    if (total > budget)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: %s needs %.1f MB at its "
                              "coarsest level (%zu levels), the budget is %.1f MB",
                              cdvr_store_path(c->st), (double)total / 1e6, c->nlevels,
                              (double)budget / 1e6);
    return CDVR_OK;
}

/* ---- residency ---------------------------------------------------------------------------- */

static size_t find_entry(const cdvr_brick_cache *c, size_t t, size_t l, size_t brick)
{
    for (size_t i = 0; i < c->nentries; i++)
        if (c->entries[i].t == t && c->entries[i].level == l && c->entries[i].brick == brick)
            return i;
    return (size_t)-1;
}

/* Drops the least recently used entries not used by this frame (nor pinned) until `need` more
 * bytes fit. */
static void make_room(cdvr_brick_cache *c, uint64_t need)
{
    while (c->cache_bytes + need > c->budget) {
        size_t victim = (size_t)-1;
        for (size_t i = 0; i < c->nentries; i++)
            if (c->entries[i].last_used != c->stamp && !c->entries[i].pinned &&
                (victim == (size_t)-1 || c->entries[i].last_used < c->entries[victim].last_used))
                victim = i;
        if (victim == (size_t)-1)
            return;
        c->cache_bytes -= c->entries[victim].bytes;
        free(c->entries[victim].voxels);
        free(c->entries[victim].ranges);
        c->entries[victim] = c->entries[--c->nentries];
        for (size_t b = 0; b < c->nbricks; b++) /* keep this frame's references valid */
            if (c->entry_of[b] == c->nentries)
                c->entry_of[b] = victim;
        c->stats.evicted++;
    }
}

/* Takes over vol's voxels as a new entry for (t, l, brick) at *out. */
static cdvr_status insert_volume(cdvr_brick_cache *c, size_t t, size_t l, size_t brick,
                                 cdvr_volume *vol, size_t *out, cdvr_error *err)
{
    size_t bytes = cdvr_volume_voxels(vol);
    make_room(c, bytes);
    if (c->nentries == c->cap) {
        size_t cap = c->cap ? 2 * c->cap : 64;
        cache_entry *e = realloc(c->entries, cap * sizeof *e);
        if (!e) {
            cdvr_volume_free(vol);
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory");
        }
        c->entries = e;
        c->cap = cap;
    }
    cache_entry *e = &c->entries[c->nentries];
    memset(e, 0, sizeof *e);
    e->t = t;
    e->level = l;
    e->brick = brick;
    e->bytes = bytes;
    e->voxels = vol->data; /* taken over from the volume */
    vol->data = NULL;
    cdvr_volume_free(vol);
    cdvr_store_brick_box(cdvr_store_get_info(c->level[l]), brick, e->lo, e->dims);
    c->cache_bytes += bytes;
    *out = c->nentries++;
    return CDVR_OK;
}

static cdvr_status load_entry(cdvr_brick_cache *c, size_t t, size_t l, size_t brick,
                              size_t *out, cdvr_error *err)
{
    size_t i = find_entry(c, t, l, brick);
    if (i == (size_t)-1) {
        cdvr_volume *vol = NULL;
        double t0 = cdvr_now_ms();
        cdvr_status s = cdvr_store_decode_brick(c->level[l], c->v, t, brick, &vol, err);
        c->stats.decode_ms += cdvr_now_ms() - t0;
        if (s == CDVR_OK)
            s = insert_volume(c, t, l, brick, vol, &i, err);
        if (s != CDVR_OK)
            return s;
        c->stats.decoded++;
    }
    c->entries[i].last_used = c->stamp;
    *out = i;
    return CDVR_OK;
}

/* ---- the asynchronous mode ----------------------------------------------------------------- */

static void *worker_main(void *arg)
{
    brick_worker *w = arg;
    pthread_mutex_lock(&w->mu);
    for (;;) {
        while (!w->stop && w->next == w->nqueued)
            pthread_cond_wait(&w->work, &w->mu);
        if (w->stop)
            break;
        w->current = w->queue[w->next++];
        w->busy = 1;
        pthread_mutex_unlock(&w->mu);
        brick_job job = w->current;
        cdvr_error_clear(&job.err);
        cdvr_store_decode_brick(w->c->level[job.level], w->c->v, job.t, job.brick, &job.vol,
                                &job.err);
        pthread_mutex_lock(&w->mu);
        w->done[w->ndone++] = job; /* room: see cdvr_brick_cache_set_async */
        w->busy = 0;
        pthread_cond_broadcast(&w->idle);
    }
    pthread_mutex_unlock(&w->mu);
    return NULL;
}

static void worker_stop(cdvr_brick_cache *c)
{
    brick_worker *w = c->worker;
    if (!w)
        return;
    pthread_mutex_lock(&w->mu);
    w->stop = 1;
    pthread_cond_broadcast(&w->work);
    pthread_mutex_unlock(&w->mu);
    pthread_join(w->thread, NULL);
    for (size_t i = 0; i < w->ndone; i++)
        cdvr_volume_free(w->done[i].vol);
    pthread_mutex_destroy(&w->mu);
    pthread_cond_destroy(&w->work);
    pthread_cond_destroy(&w->idle);
    worker_free(w);
    c->worker = NULL;
    c->reserved = 0;
    for (size_t i = 0; i < c->nentries; i++)
        c->entries[i].pinned = 0;
}

/* Bytes of the coarsest level's bricks that stand for some level-0 brick. */
static uint64_t coarsest_bytes(const cdvr_brick_cache *c, cdvr_error *err, int *ok)
{
    size_t l = c->nlevels - 1, n = cdvr_store_get_info(c->level[l])->nbricks;
    uint8_t *seen = calloc(n ? n : 1, 1);
    uint64_t bytes = 0;
    *ok = seen != NULL;
    if (!seen) {
        cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory");
        return 0;
    }
    for (size_t b = 0; b < c->nbricks; b++) {
        size_t lb = level_brick(c, b, l);
        if (!seen[lb])
            bytes += brick_bytes(c, b, l);
        seen[lb] = 1;
    }
    free(seen);
    return bytes;
}

cdvr_status cdvr_brick_cache_set_async(cdvr_brick_cache *c, int on, cdvr_error *err)
{
    if (!on || c->worker) {
        if (!on)
            worker_stop(c);
        return CDVR_OK;
    }
    int ok;
    uint64_t reserved = coarsest_bytes(c, err, &ok);
    if (!ok)
        return CDVR_ERR_NOMEM;
    if (reserved > c->budget)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: %s needs %.1f MB for its "
                              "coarsest level (%zu levels, kept resident in the asynchronous "
                              "mode), the budget is %.1f MB", cdvr_store_path(c->st),
                              (double)reserved / 1e6, c->nlevels, (double)c->budget / 1e6);
    /* a queue: the frame's missing bricks, the next timestep's coarsest and chosen ones (at
     * most nbricks each); done between two frames: what finished of the last queue before it
     * was replaced, the job then in flight, and the new queue */
    size_t queue_cap = 3 * c->nbricks, done_cap = 2 * queue_cap + 1;
    brick_worker *w = calloc(1, sizeof *w);
    if (!w || !(w->queue = malloc(queue_cap * sizeof *w->queue)) ||
        !(w->done = malloc(done_cap * sizeof *w->done)) ||
        !(w->taken = malloc(done_cap * sizeof *w->taken)) ||
        (!c->requests && !(c->requests = malloc(queue_cap * sizeof *c->requests)))) {
        worker_free(w);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory");
    }
    w->c = c;
    pthread_mutex_init(&w->mu, NULL);
    pthread_cond_init(&w->work, NULL);
    pthread_cond_init(&w->idle, NULL);
    if (pthread_create(&w->thread, NULL, worker_main, w) != 0) {
        pthread_mutex_destroy(&w->mu);
        pthread_cond_destroy(&w->work);
        pthread_cond_destroy(&w->idle);
        worker_free(w);
        return cdvr_error_set(err, CDVR_ERR_IO, "brick cache: cannot start its worker thread");
    }
    c->worker = w;
    c->reserved = reserved;
    c->pinned_t = (size_t)-1;
    c->next_t = (size_t)-1;
    return CDVR_OK;
}

void cdvr_brick_cache_set_next(cdvr_brick_cache *c, size_t t_next)
{
    c->next_t = t_next;
}

void cdvr_brick_cache_wait(cdvr_brick_cache *c)
{
    brick_worker *w = c->worker;
    if (!w)
        return;
    pthread_mutex_lock(&w->mu);
    while (w->next < w->nqueued || w->busy)
        pthread_cond_wait(&w->idle, &w->mu);
    pthread_mutex_unlock(&w->mu);
}

size_t cdvr_brick_cache_pending(cdvr_brick_cache *c)
{
    brick_worker *w = c->worker;
    if (!w)
        return 0;
    pthread_mutex_lock(&w->mu);
    size_t n = w->nqueued - w->next + (size_t)w->busy + w->ndone;
    pthread_mutex_unlock(&w->mu);
    return n;
}

/* The bricks the worker finished become entries (a brick already resident, or one that finds
 * no room, is dropped); the first error the worker met is the frame's. */
static cdvr_status take_done(cdvr_brick_cache *c, cdvr_error *err)
{
    brick_worker *w = c->worker;
    brick_job *jobs = w->taken;
    pthread_mutex_lock(&w->mu);
    size_t n = w->ndone;
    memcpy(jobs, w->done, n * sizeof *jobs);
    w->ndone = 0;
    pthread_mutex_unlock(&w->mu);
    cdvr_status s = CDVR_OK;
    for (size_t i = 0; i < n; i++) {
        brick_job *j = &jobs[i];
        size_t at;
        if (!j->vol || s != CDVR_OK || find_entry(c, j->t, j->level, j->brick) != (size_t)-1) {
            if (!j->vol && s == CDVR_OK)
                s = cdvr_error_set(err, j->err.status, "%s", j->err.msg);
            cdvr_volume_free(j->vol);
            continue;
        }
        make_room(c, cdvr_volume_voxels(j->vol));
        if (c->cache_bytes + cdvr_volume_voxels(j->vol) > c->budget) {
            cdvr_volume_free(j->vol);
            continue;
        }
        s = insert_volume(c, j->t, j->level, j->brick, j->vol, &at, err);
        if (s == CDVR_OK) {
            c->entries[at].last_used = c->stamp - 1; /* resident, not yet used by a frame */
            c->stats.arrived++;
        }
    }
    return s;
}

/* Pins the coarsest level of timestep t (decoded here when missing: never a hole). */
static cdvr_status pin_coarsest(cdvr_brick_cache *c, size_t t, cdvr_error *err)
{
    size_t l = c->nlevels - 1;
    if (c->pinned_t != t)
        for (size_t i = 0; i < c->nentries; i++)
            c->entries[i].pinned = 0;
    c->pinned_t = t;
    for (size_t b = 0; b < c->nbricks; b++) {
        size_t at;
        cdvr_status s = load_entry(c, t, l, level_brick(c, b, l), &at, err);
        if (s != CDVR_OK)
            return s;
        c->entries[at].pinned = 1;
    }
    return CDVR_OK;
}

/* Queues (t, l, brick) once for the worker, while the bricks queued for this frame fit the
 * budget past the pinned level: what the worker decodes waits outside the budget until the
 * next frame takes it, so that wait is bounded by the budget too (plus the brick in flight). */
static void request(cdvr_brick_cache *c, size_t t, size_t l, size_t brick)
{
    for (size_t i = 0; i < c->nrequests; i++)
        if (c->requests[i].t == t && c->requests[i].level == l && c->requests[i].brick == brick)
            return;
    size_t lo[3], d[3];
    cdvr_store_brick_box(cdvr_store_get_info(c->level[l]), brick, lo, d);
    uint64_t bytes = (uint64_t)d[0] * d[1] * d[2];
    if (c->requested_bytes + bytes > c->budget - c->reserved)
        return;
    c->requested_bytes += bytes;
    c->requests[c->nrequests++] = (brick_job){.t = t, .level = l, .brick = brick};
}

/* The worker's queue becomes this frame's requests (older ones not started are dropped: the
 * view moved on), less the one it is decoding and those it finished. */
static void submit(cdvr_brick_cache *c)
{
    brick_worker *w = c->worker;
    pthread_mutex_lock(&w->mu);
    w->nqueued = w->next = 0;
    for (size_t i = 0; i < c->nrequests; i++) {
        const brick_job *r = &c->requests[i];
        int known = w->busy && w->current.t == r->t && w->current.level == r->level &&
                    w->current.brick == r->brick;
        for (size_t k = 0; !known && k < w->ndone; k++)
            known = w->done[k].t == r->t && w->done[k].level == r->level &&
                    w->done[k].brick == r->brick;
        if (!known)
            w->queue[w->nqueued++] = *r;
    }
    c->stats.pending = w->nqueued + (size_t)w->busy + w->ndone;
    c->stats.requested_bytes = c->requested_bytes;
    pthread_cond_broadcast(&w->work);
    pthread_mutex_unlock(&w->mu);
}

/* After this frame's requests: the next timestep's coarsest level and its bricks at this
 * frame's chosen levels, those not resident (cdvr_brick_cache_set_next; once). */
static void prefetch_next(cdvr_brick_cache *c, size_t t)
{
    size_t next = c->next_t, last = c->nlevels - 1;
    c->next_t = (size_t)-1;
    if (next == (size_t)-1 || next == t || next >= cdvr_store_get_info(c->st)->timesteps)
        return;
    for (int pass = 0; pass < 2; pass++)
        for (size_t b = 0; b < c->nbricks; b++) {
            size_t l = pass == 0 ? last : c->choice[b], lb = level_brick(c, b, l);
            if ((pass == 0 || l != last) && find_entry(c, next, l, lb) == (size_t)-1)
                request(c, next, l, lb);
        }
}

/* Residency of the asynchronous mode: per brick the chosen level when resident, else the
 * finest resident coarser one (the pinned coarsest level at worst); the missing chosen levels
 * go to the worker. */
static cdvr_status residency_async(cdvr_brick_cache *c, size_t t, cdvr_error *err)
{
    cdvr_status s = take_done(c, err);
    if (s == CDVR_OK)
        s = pin_coarsest(c, t, err);
    if (s != CDVR_OK)
        return s;
    c->nrequests = 0;
    c->requested_bytes = 0;
    for (size_t b = 0; b < c->nbricks; b++) {
        size_t want = c->choice[b], l = want, at = (size_t)-1;
        for (; l < c->nlevels; l++)
            if ((at = find_entry(c, t, l, level_brick(c, b, l))) != (size_t)-1)
                break;
        /* l < nlevels: the coarsest level was pinned above */
        c->entries[at].last_used = c->stamp;
        c->entry_of[b] = at;
        c->stats.bricks_at[l]++;
        if (l > want) {
            c->stats.coarser++;
            request(c, t, want, level_brick(c, b, want));
        }
    }
    prefetch_next(c, t);
    submit(c);
    return CDVR_OK;
}

/* ---- the payload ---------------------------------------------------------------------------- */

static void put_word(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

/* The value range of an entry's voxels, once per entry (the skip grid's ranges). */
static void entry_range(cache_entry *e)
{
    if (e->ranged)
        return;
    uint8_t lo = 255, hi = 0;
    for (size_t i = 0; i < e->bytes; i++) {
        lo = e->voxels[i] < lo ? e->voxels[i] : lo;
        hi = e->voxels[i] > hi ? e->voxels[i] : hi;
    }
    e->vmin = lo;
    e->vmax = hi;
    e->ranged = 1;
}

/* Voxel (x, y, z) (level-0 coordinates) of level-0 brick b as its owner decoded it, when
 * the owner is resident at level 0 this frame; NULL otherwise. */
static const uint8_t *owner_voxel(const cdvr_brick_cache *c, size_t x, size_t y, size_t z)
{
    size_t ob = c->owner[0][x] + c->grid[0] * (c->owner[1][y] + c->grid[1] * c->owner[2][z]);
    const cache_entry *o = &c->entries[c->entry_of[ob]];
    if (o->level != 0)
        return NULL;
    return o->voxels + (x - o->lo[0]) + o->dims[0] * ((y - o->lo[1]) + o->dims[1] * (z - o->lo[2]));
}

/* A lossy codec decodes the one-voxel overlap of a brick (its lower apron) on its own: the
 * march reads it, the dense frame the owner's voxel. So a level-0 entry's apron takes its
 * owners' voxels once they are resident at level 0 (then the march at level 0 reads exactly
 * the assembled frame); its ranges are made again when a voxel changed. */
static void patch_apron(cdvr_brick_cache *c, cache_entry *e)
{
    int complete = 1, changed = 0;
    const size_t *lo = e->lo, *d = e->dims;
    for (size_t z = lo[2]; z < lo[2] + d[2]; z++)
        for (size_t y = lo[1]; y < lo[1] + d[1]; y++) {
            int plane = (z == lo[2] && lo[2] > 0) || (y == lo[1] && lo[1] > 0);
            size_t end = plane ? lo[0] + d[0] : lo[0] > 0 ? lo[0] + 1 : lo[0];
            uint8_t *row = e->voxels + d[0] * ((y - lo[1]) + d[1] * (z - lo[2]));
            for (size_t x = lo[0]; x < end; x++) {
                const uint8_t *v = owner_voxel(c, x, y, z);
                if (!v) {
                    complete = 0;
                } else if (row[x - lo[0]] != *v) {
                    row[x - lo[0]] = *v;
                    changed = 1;
                }
            }
        }
    if (changed) {
        free(e->ranges);
        e->ranges = NULL;
        e->ranged = 0;
        c->patches++;
    }
    e->apron_done = complete;
}

/* Page-table entry of level-0 brick b (see the header for the words). */
static void put_entry(const cdvr_brick_cache *c, size_t b, uint8_t *t)
{
    const cache_entry *e = &c->entries[c->entry_of[b]];
    size_t lo0[3], d0[3];
    cdvr_store_brick_box(cdvr_store_get_info(c->st), b, lo0, d0);
    memset(t, 0, 4 * CDVR_BRICK_CACHE_ENTRY_WORDS);
    put_word(t, (uint32_t)e->pool_offset);
    put_word(t + 4, (uint32_t)e->level);
    for (int a = 0; a < 3; a++) {
        put_word(t + 8 + 4 * a, (uint32_t)e->lo[a]);
        put_word(t + 20 + 4 * a, (uint32_t)e->dims[a]);
        put_word(t + 32 + 4 * a, (uint32_t)lo0[a]);
        put_word(t + 44 + 4 * a, (uint32_t)(lo0[a] + (d0[a] > 1 ? d0[a] - 1 : 1)));
    }
}

static cdvr_status layout(cdvr_brick_cache *c, cdvr_error *err)
{
    size_t axes = c->dims[0] + c->dims[1] + c->dims[2];
    size_t table = 4 * (CDVR_BRICK_CACHE_HEADER_WORDS + axes);
    size_t pool = table + 4 * CDVR_BRICK_CACHE_ENTRY_WORDS * c->nbricks, bytes = pool;
    for (size_t i = 0; i < c->nentries; i++)
        if (c->entries[i].last_used == c->stamp) {
            c->entries[i].pool_offset = bytes - pool;
            bytes += c->entries[i].bytes;
        }
    bytes += CDVR_BRICK_CACHE_PAD;
    if (bytes > UINT32_MAX)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: a payload of %zu bytes (the "
                              "page table holds 32-bit offsets)", bytes);
    if (bytes > c->payload_cap) {
        uint8_t *p = realloc(c->payload, bytes);
        if (!p)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory for a payload "
                                  "of %zu bytes", bytes);
        c->payload = p;
        c->payload_cap = bytes;
    }
    uint8_t *p = c->payload;
    memset(p, 0, 4 * CDVR_BRICK_CACHE_HEADER_WORDS);
    put_word(p, CDVR_BRICK_CACHE_MAGIC);
    for (int a = 0; a < 3; a++)
        put_word(p + 4 + 4 * a, (uint32_t)c->grid[a]);
    put_word(p + 16, (uint32_t)pool);
    put_word(p + 20, (uint32_t)table);
    put_word(p + 24, CDVR_BRICK_CACHE_ENTRY_WORDS);
    size_t w = 4 * CDVR_BRICK_CACHE_HEADER_WORDS;
    for (int a = 0; a < 3; a++)
        for (size_t x = 0; x < c->dims[a]; x++, w += 4)
            put_word(p + w, (uint32_t)c->owner[a][x]);
    c->stats.resident_bytes = 0;
    for (size_t b = 0; b < c->nbricks; b++) {
        cache_entry *e = &c->entries[c->entry_of[b]];
        if (e->level == 0 && !e->apron_done)
            patch_apron(c, e);
        put_entry(c, b, p + table + 4 * CDVR_BRICK_CACHE_ENTRY_WORDS * b);
    }
    for (size_t i = 0; i < c->nentries; i++)
        if (c->entries[i].last_used == c->stamp) {
            memcpy(p + pool + c->entries[i].pool_offset, c->entries[i].voxels,
                   c->entries[i].bytes);
            c->stats.resident_bytes += c->entries[i].bytes;
        }
    memset(p + bytes - CDVR_BRICK_CACHE_PAD, 0, CDVR_BRICK_CACHE_PAD);
    c->payload_bytes = bytes;
    return CDVR_OK;
}

cdvr_status cdvr_brick_cache_frame(cdvr_brick_cache *c, size_t t, const cdvr_camera *cam,
                                   const cdvr_tf *tf, double lod_error,
                                   const uint8_t **payload, size_t *bytes, cdvr_error *err)
{
    *payload = NULL;
    *bytes = 0;
    if (!(lod_error >= 0) || !isfinite(lod_error))
        return cdvr_error_set(err, CDVR_ERR_ARG, "brick cache: lod_error %g (>= 0 pixels)",
                              lod_error);
    if (t >= cdvr_store_get_info(c->st)->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "brick cache: no timestep %zu", t + 1);
    memset(&c->stats, 0, sizeof c->stats);
    c->stats.levels = c->nlevels;
    c->stats.budget_bytes = c->budget;
    c->stamp++;
    cdvr_status s = choose_levels(c, t, cam, tf, lod_error, err);
    for (size_t b = 0; b < c->nbricks; b++)
        c->entry_of[b] = (size_t)-1;
    if (s == CDVR_OK && c->worker)
        s = residency_async(c, t, err);
    for (size_t b = 0; s == CDVR_OK && !c->worker && b < c->nbricks; b++) {
        size_t l = c->choice[b];
        s = load_entry(c, t, l, level_brick(c, b, l), &c->entry_of[b], err);
        c->stats.bricks_at[l]++;
    }
    double t0 = cdvr_now_ms();
    if (s == CDVR_OK)
        s = layout(c, err);
    c->stats.layout_ms = cdvr_now_ms() - t0;
    c->stats.cache_bytes = c->cache_bytes;
    c->stats.payload_bytes = c->payload_bytes;
    if (s != CDVR_OK)
        return s;
    *payload = c->payload;
    *bytes = c->payload_bytes;
    return CDVR_OK;
}

void cdvr_brick_cache_get_stats(const cdvr_brick_cache *c, cdvr_brick_cache_stats *out)
{
    *out = c->stats;
}

/* One axis of the coarse fetch (cdvr_brick_cache_fetch) at level-0 coordinate x. */
static void coarse_axis(size_t x, uint32_t lvl, size_t lo, size_t d, uint32_t *c0,
                        uint32_t *c1, uint64_t *w0, uint64_t *w1)
{
    uint32_t s = 1u << lvl, f = (uint32_t)x & (s - 1u);
    *c0 = coord_at(x, lvl, (uint32_t)lo, (uint32_t)d);
    *c1 = *c0 + 1 < d ? *c0 + 1 : (uint32_t)d - 1;
    *w0 = s - f;
    *w1 = f;
}

/* Voxels x0 .. x0 + n - 1 of row (y, z) from a coarse entry: the fetch's formula with the
 * page-table lookups done once (the same integers, so the same bytes). */
static void assemble_row(const cache_entry *e, size_t x0, size_t n, size_t y, size_t z,
                         uint8_t *row)
{
    uint32_t lvl = (uint32_t)(e->level < 15 ? e->level : 15), shift = 3 * lvl;
    uint32_t cy0, cy1, cz0, cz1;
    uint64_t wy0, wy1, wz0, wz1;
    coarse_axis(y, lvl, e->lo[1], e->dims[1], &cy0, &cy1, &wy0, &wy1);
    coarse_axis(z, lvl, e->lo[2], e->dims[2], &cz0, &cz1, &wz0, &wz1);
    const uint8_t *r[4] = {e->voxels + e->dims[0] * (cy0 + e->dims[1] * cz0),
                           e->voxels + e->dims[0] * (cy1 + e->dims[1] * cz0),
                           e->voxels + e->dims[0] * (cy0 + e->dims[1] * cz1),
                           e->voxels + e->dims[0] * (cy1 + e->dims[1] * cz1)};
    uint64_t w[4] = {wy0 * wz0, wy1 * wz0, wy0 * wz1, wy1 * wz1};
    for (size_t x = x0; x < x0 + n; x++) {
        uint32_t cx0, cx1;
        uint64_t wx0, wx1, sum = 0;
        coarse_axis(x, lvl, e->lo[0], e->dims[0], &cx0, &cx1, &wx0, &wx1);
        for (int k = 0; k < 4; k++)
            sum += w[k] * (wx0 * r[k][cx0] + wx1 * r[k][cx1]);
        row[x] = (uint8_t)((sum + (1ull << (shift - 1))) >> shift);
    }
}

/* Level-0 brick b's owned voxels of the dense frame from its entry. */
static void assemble_brick(const cdvr_brick_cache *c, size_t b, uint8_t *frame)
{
    const cdvr_store_info *in = cdvr_store_get_info(c->st);
    size_t X = c->dims[0], Y = c->dims[1];
    const cache_entry *e = &c->entries[c->entry_of[b]];
    size_t lo[3], d[3];
    cdvr_store_brick_owned(in, b, lo, d);
    for (size_t z = lo[2]; z < lo[2] + d[2]; z++)
        for (size_t y = lo[1]; y < lo[1] + d[1]; y++) {
            uint8_t *row = frame + X * (y + Y * z);
            if (e->level == 0) { /* the owned voxels lie inside the brick's box */
                const uint8_t *src = e->voxels + (lo[0] - e->lo[0]) +
                                     e->dims[0] * ((y - e->lo[1]) + e->dims[1] * (z - e->lo[2]));
                memcpy(row + lo[0], src, d[0]);
            } else {
                assemble_row(e, lo[0], d[0], y, z, row);
            }
        }
}

/* Assembles the level-0 bricks whose entry (timestep, level, brick) differs from the one
 * the dense frame holds for them (every brick when it holds none): each brick writes only the
 * voxels it owns, so the frame ends exactly as a whole assembly. Returns how many. */
static size_t assemble_changed(cdvr_brick_cache *c)
{
    size_t n = 0;
    for (size_t b = 0; b < c->nbricks; b++) {
        const cache_entry *e = &c->entries[c->entry_of[b]];
        size_t *k = &c->dense_key[3 * b];
        if (c->dense_valid && k[0] == e->t && k[1] == e->level && k[2] == e->brick)
            continue;
        assemble_brick(c, b, c->dense);
        k[0] = e->t;
        k[1] = e->level;
        k[2] = e->brick;
        n++;
    }
    c->dense_valid = 1;
    return n;
}

cdvr_status cdvr_brick_cache_dense(cdvr_brick_cache *c, const uint8_t **frame, cdvr_error *err)
{
    *frame = NULL;
    if (!c->payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "brick cache: no frame laid out yet");
    if (!c->dense) {
        void *mem = NULL;
        size_t n = c->dims[0] * c->dims[1] * c->dims[2];
        if (posix_memalign(&mem, 4096, n ? n : 1) != 0 ||
            !(c->dense_key = malloc(3 * c->nbricks * sizeof *c->dense_key))) {
            free(mem);
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory for a dense "
                                  "frame of %zu bytes", n);
        }
        c->dense = mem;
        c->dense_valid = 0;
    }
    double t0 = cdvr_now_ms();
    c->stats.dense_bricks = assemble_changed(c);
    c->stats.layout_ms += cdvr_now_ms() - t0;
    *frame = c->dense;
    return CDVR_OK;
}

/* Along one axis of an entry at level l (box lo, d at its level): the range bricks (of
 * 2^shift level-0 cells) over the box, and per range brick s the entry's voxels that a
 * sample in its cells reads, [floor(s 2^shift / 2^l), ceil((s + 1) 2^shift / 2^l)] inside the
 * box (local coordinates), in first[] and last[]. */
static size_t range_axis(size_t lo, size_t d, size_t l, unsigned shift, size_t *s_lo,
                         size_t **first, size_t **last)
{
    size_t a = (lo << l) >> shift, b = ((lo + d - 1) << l) >> shift, n = b - a + 1;
    *s_lo = a;
    *first = malloc(2 * n * sizeof **first);
    if (!*first)
        return 0;
    *last = *first + n;
    for (size_t s = a; s <= b; s++) {
        size_t v0 = (s << shift) >> l, v1 = (((s + 1) << shift) + ((size_t)1 << l) - 1) >> l;
        v0 = v0 < lo ? lo : v0 > lo + d - 1 ? lo + d - 1 : v0;
        v1 = v1 < v0 ? v0 : v1 > lo + d - 1 ? lo + d - 1 : v1;
        (*first)[s - a] = v0 - lo;
        (*last)[s - a] = v1 - lo;
    }
    return n;
}

/* The entry's range per range brick of 2^shift level-0 cells over its box, once per entry
 * (on no memory it keeps none: its whole range stands for every range brick). */
static void entry_ranges(cache_entry *e, unsigned shift)
{
    entry_range(e);
    if (e->ranges)
        return;
    size_t *first[3] = {NULL, NULL, NULL}, *last[3], n[3];
    int ok = 1;
    for (int a = 0; a < 3; a++) {
        n[a] = range_axis(e->lo[a], e->dims[a], e->level, shift, &e->range_lo[a], &first[a],
                          &last[a]);
        ok &= n[a] > 0;
    }
    uint8_t *mm = ok ? malloc(2 * n[0] * n[1] * n[2]) : NULL;
    if (mm) {
        e->ranges = mm;
        memcpy(e->range_n, n, sizeof n);
        size_t X = e->dims[0], XY = e->dims[0] * e->dims[1];
        for (size_t k = 0; k < n[2]; k++)
            for (size_t j = 0; j < n[1]; j++)
                for (size_t i = 0; i < n[0]; i++, mm += 2) {
                    uint8_t lo = 255, hi = 0;
                    for (size_t z = first[2][k]; z <= last[2][k]; z++)
                        for (size_t y = first[1][j]; y <= last[1][j]; y++) {
                            const uint8_t *row = e->voxels + X * y + XY * z;
                            for (size_t x = first[0][i]; x <= last[0][i]; x++) {
                                lo = row[x] < lo ? row[x] : lo;
                                hi = row[x] > hi ? row[x] : hi;
                            }
                        }
                    mm[0] = lo;
                    mm[1] = hi;
                }
    }
    for (int a = 0; a < 3; a++)
        free(first[a]);
}

/* The range of entry e over range brick (x, y, z): its table's, or its whole range. */
static void entry_range_at(const cache_entry *e, size_t x, size_t y, size_t z, uint8_t *lo,
                           uint8_t *hi)
{
    size_t i = x - e->range_lo[0], j = y - e->range_lo[1], k = z - e->range_lo[2];
    if (e->ranges && x >= e->range_lo[0] && y >= e->range_lo[1] && z >= e->range_lo[2] &&
        i < e->range_n[0] && j < e->range_n[1] && k < e->range_n[2]) {
        const uint8_t *mm = e->ranges + 2 * (i + e->range_n[0] * (j + e->range_n[1] * k));
        *lo = mm[0] < *lo ? mm[0] : *lo;
        *hi = mm[1] > *hi ? mm[1] : *hi;
    } else {
        *lo = e->vmin < *lo ? e->vmin : *lo;
        *hi = e->vmax > *hi ? e->vmax : *hi;
    }
}

/* Per range brick s of 2^shift cells along one axis of n voxels: the first and last level-0
 * brick (along the axis) that the march reads for a sample in it, owner(min(x, n - 2) + 1)
 * for its cells x (owner(0) on an axis of one voxel). */
static void skip_axis(const size_t *owner, size_t n, unsigned shift, size_t count, size_t *first,
                      size_t *last)
{
    for (size_t s = 0; s < count; s++) {
        size_t x0 = s << shift, x1 = ((s + 1) << shift) < n ? ((s + 1) << shift) - 1 : n - 1;
        if (n >= 2) {
            x0 = (x0 < n - 2 ? x0 : n - 2) + 1;
            x1 = (x1 < n - 2 ? x1 : n - 2) + 1;
        } else {
            x0 = x1 = 0;
        }
        first[s] = owner[x0];
        last[s] = owner[x1];
    }
}

/* Level 0's range per range brick of timestep t, merged from the range tables the store
 * recorded for every level-0 brick (cdvr/bricks.h: exactly the assembled volume's ranges), once
 * per timestep; table_state -1 when some chunk has none (or tables of different bricks). */
static cdvr_status level0_table(cdvr_brick_cache *c, size_t t, cdvr_error *err)
{
    if (c->table_state != 0 && (c->table_state < 0 || c->table_t == t))
        return CDVR_OK;
    const cdvr_store_info *in = cdvr_store_get_info(c->st);
    unsigned shift = 0;
    for (size_t b = 0; b < c->nbricks; b++) {
        size_t chunk = cdvr_store_chunk_for(c->st, c->v, t, b);
        const cdvr_chunk_info *ci = chunk != (size_t)-1 ? cdvr_store_chunk(c->st, c->v, chunk)
                                                          : NULL;
        if (!ci || !ci->ranges_shift || (shift && ci->ranges_shift != shift)) {
            c->table_state = -1;
            return CDVR_OK;
        }
        shift = ci->ranges_shift;
    }
    if (c->table.minmax && c->table.shift != shift)
        cdvr_skip_grid_free(&c->table);
    if (!c->table.minmax) {
        cdvr_status s = cdvr_skip_grid_init(&c->table, c->dims, shift, err);
        if (s != CDVR_OK)
            return s;
    }
    memset(c->table.minmax, 0, 2 * c->table.nbricks);
    for (size_t i = 0; i < c->table.nbricks; i++)
        c->table.minmax[2 * i] = 255;
    for (size_t b = 0; b < c->nbricks; b++) {
        size_t chunk = cdvr_store_chunk_for(c->st, c->v, t, b);
        const cdvr_chunk_info *ci = cdvr_store_chunk(c->st, c->v, chunk);
        size_t bytes = cdvr_store_ranges_bytes(c->st, c->v, chunk), lo[3], bd[3], g0[3], n[3];
        uint8_t *tab = bytes ? malloc(bytes) : NULL;
        if (!tab)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory for a range "
                                  "table of %zu bytes", bytes);
        cdvr_status s = cdvr_store_read_ranges(c->st, c->v, chunk, tab, err);
        if (s != CDVR_OK) {
            free(tab);
            return s;
        }
        cdvr_store_brick_owned(in, b, lo, bd);
        cdvr_range_window(c->dims, lo, bd, shift, g0, n);
        cdvr_range_merge(tab + (t - ci->t0) * 2 * n[0] * n[1] * n[2], g0, n, c->table.dims,
                         c->table.minmax);
        free(tab);
    }
    c->table_t = t;
    c->table_state = 1;
    return CDVR_OK;
}

/* Level 0's range over the table brick holding range brick (x, y, z) of g. */
static void table_range_at(const cdvr_brick_cache *c, const cdvr_skip_grid *g, size_t x,
                           size_t y, size_t z, uint8_t *lo, uint8_t *hi)
{
    unsigned f = c->table.shift - g->shift;
    const size_t *d = c->table.dims;
    size_t i = x >> f, j = y >> f, k = z >> f;
    const uint8_t *mm = c->table.minmax + 2 * ((i < d[0] ? i : d[0] - 1) +
                                              d[0] * ((j < d[1] ? j : d[1] - 1) +
                                                      d[1] * (k < d[2] ? k : d[2] - 1)));
    *lo = mm[0] < *lo ? mm[0] : *lo;
    *hi = mm[1] > *hi ? mm[1] : *hi;
}

/* 1 when some value of [lo, hi] is visible (prefix: counts of visible TF entries). */
static int range_visible(const int *prefix, uint8_t lo, uint8_t hi)
{
    return lo <= hi && prefix[hi + 1] - prefix[lo] > 0;
}

cdvr_status cdvr_brick_cache_skip_minmax(cdvr_brick_cache *c, cdvr_skip_grid *g,
                                         const cdvr_tf *tf, cdvr_error *err)
{
    if (!c->payload_bytes || memcmp(g->vol_dims, c->dims, sizeof c->dims) != 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "brick cache: no frame laid out, or a skip grid "
                              "of another volume (%zux%zux%zu)", g->vol_dims[0], g->vol_dims[1],
                              g->vol_dims[2]);
    size_t total = g->dims[0] + g->dims[1] + g->dims[2];
    size_t *span = malloc(2 * total * sizeof *span);
    if (!span)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory for the skip ranges");
    size_t *first[3], *last[3];
    for (int a = 0, at = 0; a < 3; at += (int)g->dims[a], a++) {
        first[a] = span + at;
        last[a] = span + total + at;
        skip_axis(c->owner[a], c->dims[a], g->shift, g->dims[a], first[a], last[a]);
    }
    int coarse = 0;
    for (size_t b = 0; b < c->nbricks; b++) {
        entry_ranges(&c->entries[c->entry_of[b]], g->shift);
        coarse |= c->entries[c->entry_of[b]].level > 0;
    }
    cdvr_status s = coarse ? level0_table(c, c->entries[c->entry_of[0]].t, err) : CDVR_OK;
    if (s != CDVR_OK) {
        free(span);
        return s;
    }
    int tables = coarse && tf && c->table_state > 0 && c->table.shift >= g->shift;
    int prefix[257] = {0};
    for (int i = 0; tables && i < 256; i++)
        prefix[i + 1] = prefix[i] + (tf->table[i][3] > 0.0f);
    uint8_t *mm = g->minmax;
    for (size_t z = 0; z < g->dims[2]; z++)
        for (size_t y = 0; y < g->dims[1]; y++)
            for (size_t x = 0; x < g->dims[0]; x++, mm += 2) {
                uint8_t lo = 255, hi = 0;
                for (size_t k = first[2][z]; k <= last[2][z]; k++)
                    for (size_t j = first[1][y]; j <= last[1][y]; j++)
                        for (size_t i = first[0][x]; i <= last[0][x]; i++) {
                            size_t b = i + c->grid[0] * (j + c->grid[1] * k);
                            const cache_entry *e = &c->entries[c->entry_of[b]];
                            uint8_t elo = 255, ehi = 0, tlo = 255, thi = 0;
                            entry_range_at(e, x, y, z, &elo, &ehi);
                            if (e->level > 0 && tables) { /* and level 0 visible there */
                                table_range_at(c, g, x, y, z, &tlo, &thi);
                                if (!range_visible(prefix, tlo, thi))
                                    continue;
                            }
                            lo = elo < lo ? elo : lo;
                            hi = ehi > hi ? ehi : hi;
                        }
                mm[0] = lo;
                mm[1] = hi;
            }
    free(span);
    cdvr_skip_grid_touch(g);
    return CDVR_OK;
}

/* 1 when the skip grid was made for the bricks of this frame (same entries, no apron patched
 * since); records this frame's otherwise. */
static int grid_current(cdvr_brick_cache *c)
{
    int same = c->grid_made && c->patches == c->grid_patches;
    for (size_t b = 0; b < c->nbricks; b++) {
        const cache_entry *e = &c->entries[c->entry_of[b]];
        size_t key[3] = {e->t, e->level, e->brick};
        same = same && memcmp(c->grid_key + 3 * b, key, sizeof key) == 0;
        memcpy(c->grid_key + 3 * b, key, sizeof key);
    }
    c->grid_patches = c->patches;
    return same;
}

cdvr_status cdvr_brick_cache_skip_grid(cdvr_brick_cache *c, unsigned shift, const cdvr_tf *tf,
                                       int level0_visible, const cdvr_skip_grid **out,
                                       cdvr_error *err)
{
    *out = NULL;
    if (!c->payload_bytes || !tf)
        return cdvr_error_set(err, CDVR_ERR_ARG, "brick cache: no frame laid out, or no TF");
    if (!c->grid_key) {
        c->grid_key = malloc(3 * c->nbricks * sizeof *c->grid_key);
        if (!c->grid_key)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick cache: no memory");
    }
    if (c->grid_made && c->skip.shift != shift) {
        cdvr_skip_grid_free(&c->skip);
        c->grid_made = 0;
    }
    if (!c->grid_made) {
        cdvr_status s = cdvr_skip_grid_init(&c->skip, c->dims, shift, err);
        if (s != CDVR_OK)
            return s;
    }
    uint8_t visible[256];
    for (int i = 0; i < 256; i++)
        visible[i] = tf->table[i][3] > 0.0f;
    level0_visible = level0_visible != 0;
    int same_tf = memcmp(visible, c->grid_tf, sizeof visible) == 0 &&
                  level0_visible == c->grid_level0_visible;
    memcpy(c->grid_tf, visible, sizeof visible);
    c->grid_level0_visible = level0_visible;
    if (!grid_current(c) || !same_tf) {
        c->grid_made = 0;
        cdvr_status s = cdvr_brick_cache_skip_minmax(c, &c->skip, level0_visible ? tf : NULL,
                                                     err);
        if (s != CDVR_OK)
            return s;
        c->grid_made = 1;
    }
    cdvr_skip_flags(&c->skip, tf);
    *out = &c->skip;
    return CDVR_OK;
}
