/* core/store/encode.c - the encode driver: u8 series -> .cdv store (cdvr_store_encode*, store.h).
 *
 * Two passes. The plan pass resolves each variant (codec, parameters, name) and calls the
 * schedule once per chunk group to fix every group's parameters and timestep count, so the
 * size of the metadata is known. The write pass walks the series forward in time: it asks
 * the frame source for each timestep once, keeps only the frames that groups still in
 * flight need, and encodes the group of whichever variant ends first (all bricks of it),
 * applies stage 2 where it pays (or, for AUTO, the stage 2 of the smallest modelled read +
 * unpack time, store.h), writes the stored bytes after the metadata, decodes the
 * payload again to measure the variant's volume PSNR and max error (peak 255, as
 * cdvr_compare; each voxel counted once, in the brick that owns it) and the chunk's value
 * range, and reports progress. Finally the metadata goes to offset 0, the file is fsync'ed
 * and renamed over the final name (cdvr_atomic_file); on any failure it is removed.
 */
#include "cdvr/atomicfile.h"
#include "cdvr/bricks.h"
#include "cdvr/memory.h"
#include "store_format.h"

#include "codec/stage2/stage2.h"
#include "cdvr/timing.h"

#include <errno.h>
#include <pthread.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define MAX_CHUNK_TIMESTEPS 64

typedef struct chunk_list {
    cdvr_chunk_info *items;
    size_t n, cap;
} chunk_list;

static cdvr_status chunk_list_push(chunk_list *l, const cdvr_chunk_info *ci, cdvr_error *err)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 64, bytes;
        if (!cdvr_size_mul(cap, sizeof *l->items, &bytes))
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "encode: too many chunks");
        cdvr_chunk_info *items = realloc(l->items, bytes);
        if (!items)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "encode: no memory for the chunk index");
        l->items = items;
        l->cap = cap;
    }
    l->items[l->n++] = *ci;
    return CDVR_OK;
}

/* ---- plan pass -------------------------------------------------------------------------- */

static cdvr_status resolve_variant(const char *path, const cdvr_variant_spec *spec,
                                   cdvr_variant_info *vi, cdvr_error *err)
{
    if (!spec->codec)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: a variant has no codec", path);
    if ((unsigned)spec->stage2 > CDVR_STAGE2_AUTO)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: bad stage2 %d (none, lzo, lz4, zstd or "
                              "auto)", path, (int)spec->stage2);
    /* AUTO without a rate: 0 until model_read_rate fills in the filesystem's */
    double mbps = spec->stage2_read_mbps != 0 ? spec->stage2_read_mbps
                  : spec->stage2 == CDVR_STAGE2_AUTO ? 0 : CDVR_STAGE2_READ_MBPS;
    size_t segment = spec->stage2_segment ? spec->stage2_segment : CDVR_STAGE2_SEGMENT;
    if (!(mbps >= 0 && mbps < 1e12))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: stage2_read_mbps %g must be > 0", path,
                              spec->stage2_read_mbps);
    if (segment < CDVR_STAGE2_SEGMENT_MIN || segment > CDVR_STAGE2_SEGMENT_MAX)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: stage2_segment %zu is not in %u..%u", path,
                              segment, CDVR_STAGE2_SEGMENT_MIN, CDVR_STAGE2_SEGMENT_MAX);
    double saving = spec->lzo_min_saving < 0 ? CDVR_LZO_MIN_SAVING : spec->lzo_min_saving;
    if (!(saving <= 1.0))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: lzo_min_saving %g is not in [0, 1]", path,
                              spec->lzo_min_saving);
    if (memchr(spec->name, 0, CDVR_NAME_MAX) == NULL)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: variant name longer than %d bytes", path,
                              CDVR_NAME_MAX - 1);
    cdvr_error perr;
    if (spec->codec->params_check(&spec->params, &perr) != CDVR_OK)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: %s", path, perr.msg);
    memset(vi, 0, sizeof *vi);
    if (spec->name[0])
        memcpy(vi->name, spec->name, CDVR_NAME_MAX);
    else
        spec->codec->variant_name(&spec->params, vi->name, sizeof vi->name);
    vi->codec = spec->codec;
    vi->codec_id = spec->codec->id;
    snprintf(vi->codec_name, sizeof vi->codec_name, "%s", spec->codec->name);
    vi->params = spec->params;
    vi->stage2 = spec->stage2;
    vi->lzo_min_saving = saving;
    vi->stage2_read_mbps = mbps;
    vi->stage2_segment = segment;
    return CDVR_OK;
}

/* Timesteps per chunk of one group with params (the same for every brick). */
static cdvr_status group_timesteps(const cdvr_variant_info *vi, const cdvr_codec_params *params,
                                   const cdvr_store_info *info, size_t *out, cdvr_error *err)
{
    for (size_t b = 0; b < info->nbricks; b++) {
        size_t lo[3], dims[3];
        cdvr_store_brick_box(info, b, lo, dims);
        cdvr_codec_shape shape;
        cdvr_status s = cdvr_codec_shape_of(vi->codec, params, dims, &shape, err);
        if (s != CDVR_OK)
            return s;
        if (shape.timesteps > MAX_CHUNK_TIMESTEPS || (b > 0 && shape.timesteps != *out))
            return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "codec %s: %zu timesteps per chunk "
                                  "(at most %d, the same for every brick)", vi->codec->name,
                                  shape.timesteps, MAX_CHUNK_TIMESTEPS);
        *out = shape.timesteps;
    }
    return CDVR_OK;
}

static cdvr_status plan_variant(const cdvr_encode_opts *opts, const cdvr_store_info *info,
                                size_t v, cdvr_variant_info *vi, chunk_list *chunks,
                                const char *path, cdvr_error *err)
{
    size_t t0 = 0;
    while (t0 < info->timesteps) {
        cdvr_codec_params params = vi->params;
        cdvr_status s = CDVR_OK;
        if (opts->schedule)
            s = opts->schedule(opts->schedule_ud, v, t0, &params, err);
        size_t per_chunk = 1;
        cdvr_error perr;
        if (s == CDVR_OK && group_timesteps(vi, &params, info, &per_chunk, &perr) != CDVR_OK)
            s = cdvr_error_set(err, perr.status, "%s: variant %s, timestep %zu: %s", path,
                               vi->name, t0 + 1, perr.msg);
        if (s != CDVR_OK)
            return s;
        size_t left = info->timesteps - t0;
        for (size_t b = 0; b < info->nbricks; b++) {
            cdvr_chunk_info ci = {.t0 = t0, .count = left < per_chunk ? left : per_chunk,
                                  .brick = b, .codec_id = vi->codec_id, .codec = vi->codec,
                                  .params = params};
            if ((s = chunk_list_push(chunks, &ci, err)) != CDVR_OK)
                return s;
        }
        t0 += left < per_chunk ? left : per_chunk;
        vi->ngroups++;
        vi->nchunks += info->nbricks;
    }
    return CDVR_OK;
}

static cdvr_status check_opts(const cdvr_encode_source *src, const cdvr_encode_opts *opts,
                              const char *path, cdvr_error *err)
{
    if (!src || !src->frame || !opts || !path || !*path)
        return cdvr_error_set(err, CDVR_ERR_ARG, "encode: source, options and path are required");
    size_t voxels = 1;
    for (int i = 0; i < 3; i++)
        if (src->dims[i] == 0 || !cdvr_size_mul(voxels, src->dims[i], &voxels))
            return cdvr_error_set(err, CDVR_ERR_ARG, "%s: bad dims %zux%zux%zu", path,
                                  src->dims[0], src->dims[1], src->dims[2]);
    if (src->timesteps == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no timesteps to encode", path);
    if (opts->nvariants < 1 || opts->nvariants > CDVR_STORE_MAX_VARIANTS || !opts->variants)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: %zu variants (must be 1..%u)", path,
                              opts->nvariants, CDVR_STORE_MAX_VARIANTS);
    if (opts->range_shift != 0 &&
        (opts->range_shift < CDVR_RANGE_SHIFT || opts->range_shift > CDVR_RANGE_SHIFT_MAX))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: range bricks of 2^%u voxels (must be 2^%d "
                              "..2^%d)", path, opts->range_shift, CDVR_RANGE_SHIFT,
                              CDVR_RANGE_SHIFT_MAX);
    if (!isfinite(opts->qlo) || !isfinite(opts->qhi) || opts->qhi < opts->qlo ||
        (unsigned)opts->source_type > CDVR_TYPE_F32)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: bad quantisation window [%g, %g] or "
                              "source type", path, opts->qlo, opts->qhi);
    for (int i = 0; i < 3; i++)
        if (!(src->spacing[i] > 0) || !isfinite(src->spacing[i]) || !isfinite(src->origin[i]))
            return cdvr_error_set(err, CDVR_ERR_ARG, "%s: spacing must be positive and origin "
                                  "finite (axis %d: %g, %g)", path, i, src->spacing[i],
                                  src->origin[i]);
    for (int i = 0; i < 9; i++)
        if (!isfinite(src->direction[i]))
            return cdvr_error_set(err, CDVR_ERR_ARG, "%s: direction matrix not finite", path);
    return CDVR_OK;
}

static cdvr_status fill_header(cdvr_store_info *in, const cdvr_encode_source *src,
                               const cdvr_encode_opts *opts, const char *path, cdvr_error *err)
{
    size_t nbricks = 1, lo[3], bd[3];
    for (int i = 0; i < 3; i++) {
        in->dims[i] = src->dims[i];
        in->spacing[i] = src->spacing[i];
        in->origin[i] = src->origin[i];
        in->bricks[i] = opts->bricks[i] ? opts->bricks[i] : 1;
        nbricks = in->bricks[i] > CDVR_STORE_MAX_BRICKS ? CDVR_STORE_MAX_BRICKS + 1
                                                         : nbricks * in->bricks[i];
    }
    if (nbricks > CDVR_STORE_MAX_BRICKS || !cdvr_brick_box(in->dims, in->bricks, 0, lo, bd))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: bricks %zux%zux%zu do not fit dims "
                              "%zux%zux%zu (at most one brick per cell along each axis, %d "
                              "bricks in all)", path, in->bricks[0], in->bricks[1],
                              in->bricks[2], in->dims[0], in->dims[1], in->dims[2],
                              CDVR_STORE_MAX_BRICKS);
    memcpy(in->direction, src->direction, sizeof in->direction);
    in->version = CDVR_STORE_VERSION;
    in->nbricks = nbricks;
    in->timesteps = src->timesteps;
    in->qlo = opts->qlo;
    in->qhi = opts->qhi;
    in->source_type = opts->source_type;
    in->raw_bytes = (uint64_t)(src->dims[0] * src->dims[1] * src->dims[2]) * src->timesteps;
    return CDVR_OK;
}

/* Builds the store description: variants resolved, every chunk planned (offsets not yet). */
static cdvr_status plan_store(const cdvr_encode_source *src, const cdvr_encode_opts *opts,
                              const char *path, cdvr_store **out, cdvr_error *err)
{
    size_t nv = opts->nvariants;
    cdvr_store_info info = {0};
    cdvr_variant_info *vis = calloc(nv, sizeof *vis);
    chunk_list chunks = {0};
    cdvr_status s = vis ? fill_header(&info, src, opts, path, err)
                        : cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", path);
    for (size_t v = 0; s == CDVR_OK && v < nv; v++) {
        s = resolve_variant(path, &opts->variants[v], &vis[v], err);
        for (size_t i = 0; s == CDVR_OK && i < v; i++)
            if (strcmp(vis[i].name, vis[v].name) == 0)
                s = cdvr_error_set(err, CDVR_ERR_ARG, "%s: two variants are called %s", path,
                                   vis[v].name);
        if (s == CDVR_OK)
            s = plan_variant(opts, &info, v, &vis[v], &chunks, path, err);
    }
    cdvr_store *st = NULL;
    if (s == CDVR_OK)
        s = cdvr_store_alloc(nv, chunks.n, path, &st, err);
    if (s == CDVR_OK) {
        info.nvariants = nv;
        st->info = info;
        memcpy(st->variants, vis, nv * sizeof *vis);
        memcpy(st->chunks, chunks.items, chunks.n * sizeof *chunks.items);
        for (size_t v = 1; v < nv; v++)
            st->chunk_first[v] = st->chunk_first[v - 1] + vis[v - 1].nchunks;
        *out = st;
    }
    free(vis);
    free(chunks.items);
    return s;
}

/* ---- write pass: the frame window ------------------------------------------------------- */

/* Frames [first, first + count) of the source, each `voxels` bytes, in a ring of `cap`. */
typedef struct frame_window {
    const cdvr_encode_source *src;
    size_t voxels, cap, first, count;
    uint8_t *ring;
} frame_window;

static const uint8_t *window_frame(const frame_window *w, size_t t)
{
    return w->ring + (t % w->cap) * w->voxels;
}

/* Makes frames [from, to) available (to - from <= cap), dropping frames before from. The
 * source is asked for each timestep once, in increasing order. */
static cdvr_status window_need(frame_window *w, size_t from, size_t to, cdvr_error *err)
{
    if (from < w->first || to - from > w->cap)
        return cdvr_error_set(err, CDVR_ERR_ARG, "encode: frames %zu..%zu requested, window "
                              "holds %zu.. (internal error)", from + 1, to, w->first + 1);
    size_t drop = from - w->first < w->count ? from - w->first : w->count;
    w->first += drop;
    w->count -= drop;
    if (w->count == 0)
        w->first = from;
    while (w->first + w->count < to) {
        size_t t = w->first + w->count;
        cdvr_status s = w->src->frame(w->src->frame_ud, t, w->ring + (t % w->cap) * w->voxels,
                                      err);
        if (s != CDVR_OK)
            return s;
        w->count++;
    }
    return CDVR_OK;
}

/* ---- write pass: chunk jobs ------------------------------------------------------------- */

/* Buffers of one chunk in flight, kept for the next chunk that uses the job. */
typedef struct job_bufs {
    uint8_t *payload, *packed, *bricks, *decoded, *ranges, *ranges_packed, *trial, *sample;
    size_t payload_cap, packed_cap, bricks_cap, decoded_cap, ranges_cap, ranges_packed_cap;
    size_t trial_cap, sample_cap; /* AUTO: a candidate's stored bytes; a chunk's sample */
} job_bufs;

/* One chunk being encoded: the codec runs in nparts parts (encode_part), or in one call, then
 * the chunk is finished: stage 2, CRC, a second decode for the errors and value ranges, and
 * the range table. Everything but the file offsets, which the calling thread assigns in
 * order when it writes the chunk. */
typedef struct chunk_job {
    cdvr_chunk_info *ci;
    size_t variant, timesteps;   /* timesteps: frames given to the codec (padded) */
    size_t lo[3], bd[3];
    cdvr_codec_shape shape;
    const uint8_t *frames[MAX_CHUNK_TIMESTEPS];
    job_bufs bufs;
    size_t nparts, parts_done;   /* parts_done and finished: under the pool's mutex */
    int finished;
    size_t payload_bytes, ranges_bytes;
    unsigned ranges_shift;  /* range bricks of 2^ranges_shift voxels */
    uint64_t sse;                /* squared error over the voxels the brick owns */
    double maxerr;
    cdvr_error err;              /* status != CDVR_OK: the chunk failed */
} chunk_job;

/* Part `part` of a job; part == nparts is its finish. */
typedef struct task {
    chunk_job *job;
    size_t part;
} task;

/* What AUTO models a chunk's playback with: this machine's single-thread unpack rates and
 * the cores the player unpacks on. */
typedef struct s2_model {
    cdvr_s2_rates rates;
    double cores;
} s2_model;

/* The encode pool: worker threads (threads - 1 of them; the calling thread works too while
 * it waits) and one queue of tasks, parts in submission order and finishes in front. */
typedef struct encode_pool {
    pthread_mutex_t mu;
    pthread_cond_t work_cv, done_cv;
    task *queue;                 /* ring of cap tasks from head */
    size_t head, count, cap;
    pthread_t *threads;
    size_t nthreads;
    int stop;
    const cdvr_store *st;
    s2_model s2;                 /* AUTO's model (read once, before the workers start) */
} encode_pool;

static void bufs_free(job_bufs *b)
{
    free(b->payload);
    free(b->packed);
    free(b->bricks);
    free(b->decoded);
    free(b->ranges);
    free(b->ranges_packed);
    free(b->trial);
    free(b->sample);
}

/* First local index along an axis that the brick starting at voxel lo owns: a voxel two
 * bricks share belongs to the lower one, so every brick but the first skips its first voxel. */
static size_t first_owned(size_t lo)
{
    return lo > 0 ? 1 : 0;
}

/* Squared and max error of a decoded brick frame against its source, over owned voxels
 * (integers: the sum is exact whatever the order of the chunks). */
static void measure_frame(const uint8_t *ref, const uint8_t *dec, const size_t lo[3],
                          const size_t bd[3], uint64_t *sse, double *maxerr)
{
    int worst = (int)*maxerr;
    for (size_t z = first_owned(lo[2]); z < bd[2]; z++) {
        for (size_t y = first_owned(lo[1]); y < bd[1]; y++) {
            size_t row = bd[0] * (y + bd[1] * z);
            uint64_t row_sse = 0;
            for (size_t x = first_owned(lo[0]); x < bd[0]; x++) {
                int d = (int)ref[row + x] - (int)dec[row + x];
                d = d < 0 ? -d : d;
                row_sse += (uint64_t)(d * d);
                worst = d > worst ? d : worst;
            }
            *sse += row_sse;
        }
    }
    *maxerr = worst;
}

static void job_fail(encode_pool *pool, chunk_job *job, const cdvr_error *e)
{
    pthread_mutex_lock(&pool->mu);
    if (job->err.status == CDVR_OK)
        job->err = *e;
    pthread_mutex_unlock(&pool->mu);
}

static void run_part(encode_pool *pool, chunk_job *job, size_t part)
{
    const cdvr_store *st = pool->st;
    const cdvr_chunk_info *ci = job->ci;
    cdvr_error cerr, e;
    cdvr_status s;
    if (job->nparts == 1) {
        size_t bytes = 0;
        s = ci->codec->encode(&ci->params, job->bd, job->frames, ci->count, job->bufs.payload,
                              job->shape.bound_bytes, &bytes, &cerr);
        job->payload_bytes = bytes;
    } else {
        s = ci->codec->encode_part(&ci->params, job->bd, job->frames, ci->count, part,
                                   job->nparts, job->bufs.payload, job->shape.bound_bytes,
                                   &cerr); /* payload_bytes: set by prepare_job */
    }
    if (s != CDVR_OK) {
        cdvr_error_set(&e, cerr.status, "%s: variant %s, timestep %zu: %s", st->path,
                       st->variants[job->variant].name, ci->t0 + 1, cerr.msg);
        job_fail(pool, job, &e);
    }
}

/* Decodes the payload again: errors against the source, the chunk's value range and its
 * range table. */
static cdvr_status measure_chunk(const cdvr_store *st, chunk_job *job, cdvr_error *err)
{
    cdvr_chunk_info *ci = job->ci;
    size_t voxels = job->bd[0] * job->bd[1] * job->bd[2];
    uint8_t *frames[MAX_CHUNK_TIMESTEPS];
    for (size_t i = 0; i < ci->count; i++)
        frames[i] = job->bufs.decoded + i * voxels;
    cdvr_status s = ci->codec->decode(&ci->params, job->bd, job->bufs.payload,
                                      job->payload_bytes, frames, ci->count, err);
    uint8_t mn = 255, mx = 0;
    size_t window = job->ranges_bytes / ci->count, own_lo[3], own_bd[3]; /* 0: no table */
    cdvr_store_brick_owned(&st->info, ci->brick, own_lo, own_bd);
    for (size_t i = 0; s == CDVR_OK && i < ci->count; i++) {
        measure_frame(job->frames[i], frames[i], job->lo, job->bd, &job->sse, &job->maxerr);
        for (size_t k = 0; k < voxels; k++) {
            mn = frames[i][k] < mn ? frames[i][k] : mn;
            mx = frames[i][k] > mx ? frames[i][k] : mx;
        }
        const uint8_t *owned = frames[i] + (own_lo[0] - job->lo[0]) +
                               job->bd[0] * ((own_lo[1] - job->lo[1]) +
                                             job->bd[1] * (own_lo[2] - job->lo[2]));
        if (window)
            s = cdvr_range_compute(owned, job->bd[0], job->bd[0] * job->bd[1], st->info.dims,
                               own_lo, own_bd, job->ranges_shift, job->bufs.ranges + i * window,
                               err);
    }
    ci->value_min = mn;
    ci->value_max = mx;
    return s;
}

/* ---- stage 2 of a chunk (store.h) ------------------------------------------------------ */

/* LZO chunks of one segment keep the unsegmented layout of seed-001 stores; everything else
 * with stage 2 is segmented. */
static int s2_segmented(unsigned codec, size_t payload, size_t seg)
{
    return codec != CDVR_S2_LZO || payload > seg;
}

/* Output bytes any stage-2 codec may need for n payload bytes; 0 on overflow. */
static size_t s2_capacity(size_t n, size_t seg)
{
    size_t cap = cdvr_lzo_bound(n);
    for (unsigned c = CDVR_S2_LZO; c < CDVR_S2_CODECS; c++) {
        size_t b = cdvr_s2_bound(c, n, seg);
        if (b == 0)
            return 0;
        cap = b > cap ? b : cap;
    }
    return cap;
}

static cdvr_status s2_pack(unsigned codec, const uint8_t *in, size_t n, size_t seg,
                           uint8_t *out, size_t cap, size_t *out_n, cdvr_error *err)
{
    if (s2_segmented(codec, n, seg))
        return cdvr_s2_pack(codec, in, n, seg, out, cap, out_n, err);
    return cdvr_lzo_compress(in, n, out, cap, out_n, err);
}

/* AUTO models a chunk of more than S2_SAMPLE_EVERY segments from a sample of it: every
 * S2_SAMPLE_EVERY-th segment from the first, whose stored bytes and unpack time are scaled to
 * the chunk; only the chosen codec then packs the whole chunk. Trying every codec on the
 * whole chunk made a raw 256^3 x 60 series encode 2.5x as long as LZO alone (12.8 against
 * 5.2 s). */
#define S2_SAMPLE_EVERY 4

/* The share of the machine AUTO lets stage 2 take, as a factor on its unpack time: 2, at most
 * half, the rest being the render's (issue 25: unzip below half the frame time). */
#define S2_UNPACK_SHARE 2.0

static size_t online_cores(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (size_t)n : 1;
}

/* The segments of payload (seg bytes each, the last one shorter) taken by the sample, copied
 * into out; returns the sample's bytes. */
static size_t s2_sample(const uint8_t *payload, size_t payload_n, size_t seg, uint8_t *out)
{
    size_t n = 0;
    for (size_t at = 0; at < payload_n; at += S2_SAMPLE_EVERY * seg) {
        size_t len = payload_n - at < seg ? payload_n - at : seg;
        memcpy(out + n, payload + at, len);
        n += len;
    }
    return n;
}

/* AUTO (store.h): the modelled time per chunk of every candidate in the pipelined player
 * (NONE: the read alone, the player keeps the stored bytes as the payload; the others: the
 * read of the packed bytes or twice the unpack of the payload on all cores at this machine's
 * rates, whichever is longer) on the chunk or its sample, scaled to the chunk; the smallest
 * ends in bufs.packed (a sampled chunk is packed for it then). Packed sizes are deterministic
 * and the rates are remembered, so the choice does not follow the load. */
static cdvr_status s2_choose(const cdvr_variant_info *vi, const s2_model *model,
                             chunk_job *job, size_t payload, unsigned *codec, size_t *packed,
                             cdvr_error *err)
{
    job_bufs *b = &job->bufs;
    size_t seg = vi->stage2_segment;
    int sampled = payload / seg > S2_SAMPLE_EVERY;
    if (sampled && !cdvr_grow_bytes(&b->sample, &b->sample_cap, payload / S2_SAMPLE_EVERY + seg))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "stage 2: no memory for a sample of a "
                              "%zu-byte chunk", payload);
    const uint8_t *in = sampled ? b->sample : b->payload;
    size_t in_n = sampled ? s2_sample(b->payload, payload, seg, b->sample) : payload;
    double scale = (double)payload / (double)in_n;
    double per_byte_ms = 1.0 / (vi->stage2_read_mbps * 1e3);
    double best = (double)payload * per_byte_ms; /* NONE: the player takes the bytes as read */
    cdvr_status s = CDVR_OK;
    *codec = 0;
    for (unsigned c = CDVR_S2_LZO; c < CDVR_S2_CODECS && s == CDVR_OK; c++) {
        size_t n = 0;
        s = s2_pack(c, in, in_n, seg, b->trial, b->trial_cap, &n, err);
        if (s != CDVR_OK || n >= in_n)
            continue;
        double read_ms = (double)n * scale * per_byte_ms;
        double unpack_ms = S2_UNPACK_SHARE * (double)payload /
                           (model->rates.mbps[c] * 1e3 * model->cores);
        double t = read_ms > unpack_ms ? read_ms : unpack_ms;
        if (t < best) {
            best = t;
            *codec = c;
            if (!sampled) { /* the whole chunk packed: keep it */
                cdvr_swap_buffers(&b->packed, &b->packed_cap, &b->trial, &b->trial_cap);
                *packed = n;
            }
        }
    }
    if (s != CDVR_OK || !*codec || !sampled)
        return s;
    s = s2_pack(*codec, b->payload, payload, seg, b->packed, b->packed_cap, packed, err);
    if (s == CDVR_OK && *packed >= payload) /* the sample shrank, the chunk does not */
        *codec = 0;
    return s;
}

/* Stage 2 of the chunk: ci->stage2, stage2_segmented and stored_bytes; the stored bytes are
 * bufs.packed when stage 2 applies, else bufs.payload. */
static cdvr_status apply_stage2(const cdvr_variant_info *vi, const s2_model *model,
                                chunk_job *job, size_t payload, cdvr_error *err)
{
    cdvr_chunk_info *ci = job->ci;
    unsigned codec = 0;
    size_t packed = 0;
    cdvr_status s = CDVR_OK;
    if (vi->stage2 == CDVR_STAGE2_AUTO) {
        s = s2_choose(vi, model, job, payload, &codec, &packed, err);
    } else if (vi->stage2 != CDVR_STAGE2_NONE) {
        s = s2_pack((unsigned)vi->stage2, job->bufs.payload, payload, vi->stage2_segment,
                    job->bufs.packed, job->bufs.packed_cap, &packed, err);
        codec = s == CDVR_OK && cdvr_lzo_keep(payload, packed, vi->lzo_min_saving)
                    ? (unsigned)vi->stage2 : 0;
    }
    if (s != CDVR_OK)
        return s;
    ci->payload_bytes = payload;
    ci->stage2 = (int)codec;
    ci->stage2_segmented = codec && s2_segmented(codec, payload, vi->stage2_segment);
    ci->stored_bytes = codec ? packed : payload;
    return CDVR_OK;
}

static cdvr_status finish_job(const cdvr_store *st, const s2_model *model, chunk_job *job,
                              cdvr_error *err)
{
    cdvr_chunk_info *ci = job->ci;
    const cdvr_variant_info *vi = &st->variants[job->variant];
    size_t payload = job->payload_bytes, table_packed = 0;
    if (payload == 0 || payload > job->shape.bound_bytes ||
        (job->shape.payload_bytes && payload != job->shape.payload_bytes))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: codec %s wrote %zu bytes (size %zu, bound "
                              "%zu)", st->path, ci->codec->name, payload,
                              job->shape.payload_bytes, job->shape.bound_bytes);
    cdvr_status s = apply_stage2(vi, model, job, payload, err);
    if (s != CDVR_OK)
        return s;
    ci->crc32c = cdvr_crc32c(0, ci->stage2 ? job->bufs.packed : job->bufs.payload,
                             (size_t)ci->stored_bytes);
    s = measure_chunk(st, job, err);
    if (s == CDVR_OK && job->ranges_bytes)
        s = cdvr_range_pack(job->bufs.ranges, job->ranges_bytes, job->bufs.ranges_packed,
                            job->bufs.ranges_packed_cap, &table_packed, err);
    if (s != CDVR_OK || !job->ranges_bytes)
        return s;
    ci->ranges_shift = job->ranges_shift;
    ci->ranges_stage2 = table_packed < job->ranges_bytes ? CDVR_RANGES_PACKED : 0;
    ci->ranges_stored_bytes = ci->ranges_stage2 ? table_packed : job->ranges_bytes;
    ci->ranges_crc32c = cdvr_crc32c(0, ci->ranges_stage2 ? job->bufs.ranges_packed
                                                         : job->bufs.ranges,
                                    (size_t)ci->ranges_stored_bytes);
    return CDVR_OK;
}

static void run_finish(encode_pool *pool, chunk_job *job)
{
    cdvr_error e;
    if (finish_job(pool->st, &pool->s2, job, &e) != CDVR_OK)
        job_fail(pool, job, &e);
}

/* ---- write pass: the pool --------------------------------------------------------------- */

/* Caller holds mu. */
static void push_task(encode_pool *pool, task t, int front)
{
    if (front) {
        pool->head = (pool->head + pool->cap - 1) % pool->cap;
        pool->queue[pool->head] = t;
    } else {
        pool->queue[(pool->head + pool->count) % pool->cap] = t;
    }
    pool->count++;
}

/* Runs one queued task; caller holds mu, which is released while the task runs. */
static void run_one_locked(encode_pool *pool)
{
    task t = pool->queue[pool->head];
    pool->head = (pool->head + 1) % pool->cap;
    pool->count--;
    chunk_job *job = t.job;
    int failed = job->err.status != CDVR_OK;
    pthread_mutex_unlock(&pool->mu);
    if (!failed && t.part < job->nparts)
        run_part(pool, job, t.part);
    else if (!failed)
        run_finish(pool, job);
    pthread_mutex_lock(&pool->mu);
    if (t.part < job->nparts) {
        if (++job->parts_done == job->nparts)
            push_task(pool, (task){job, job->nparts}, 1);
        pthread_cond_signal(&pool->work_cv);
    } else {
        job->finished = 1;
        pthread_cond_broadcast(&pool->done_cv);
    }
}

static void *worker_main(void *arg)
{
    encode_pool *pool = arg;
    pthread_mutex_lock(&pool->mu);
    for (;;) {
        while (!pool->count && !pool->stop)
            pthread_cond_wait(&pool->work_cv, &pool->mu);
        if (pool->stop)
            break;
        run_one_locked(pool);
    }
    pthread_mutex_unlock(&pool->mu);
    return NULL;
}

static cdvr_status pool_start(encode_pool *pool, const cdvr_store *st, size_t threads,
                              size_t queue_cap, cdvr_error *err)
{
    memset(pool, 0, sizeof *pool);
    pool->st = st;
    for (size_t v = 0; v < st->info.nvariants; v++)
        if (st->variants[v].stage2 == CDVR_STAGE2_AUTO) {
            cdvr_status s = cdvr_s2_unpack_rates(&pool->s2.rates, err);
            if (s != CDVR_OK)
                return s;
            pool->s2.cores = (double)online_cores();
            break;
        }
    pool->cap = queue_cap;
    pool->queue = malloc(queue_cap * sizeof *pool->queue);
    pool->threads = malloc((threads ? threads : 1) * sizeof *pool->threads);
    if (!pool->queue || !pool->threads) {
        free(pool->queue);
        free(pool->threads);
        pool->queue = NULL;
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for the encode pool", st->path);
    }
    pthread_mutex_init(&pool->mu, NULL);
    pthread_cond_init(&pool->work_cv, NULL);
    pthread_cond_init(&pool->done_cv, NULL);
    for (size_t i = 1; i < threads; i++) { /* the calling thread is the first */
        if (pthread_create(&pool->threads[pool->nthreads], NULL, worker_main, pool) != 0)
            break; /* fewer threads: same output, only slower */
        pool->nthreads++;
    }
    return CDVR_OK;
}

static void pool_stop(encode_pool *pool)
{
    pthread_mutex_lock(&pool->mu);
    pool->stop = 1;
    pthread_cond_broadcast(&pool->work_cv);
    pthread_mutex_unlock(&pool->mu);
    for (size_t i = 0; i < pool->nthreads; i++)
        pthread_join(pool->threads[i], NULL);
    pthread_mutex_destroy(&pool->mu);
    pthread_cond_destroy(&pool->work_cv);
    pthread_cond_destroy(&pool->done_cv);
    free(pool->queue);
    free(pool->threads);
}

/* Waits until every job of the group is finished, running queued tasks meanwhile. */
static void pool_wait(encode_pool *pool, chunk_job *jobs, size_t njobs)
{
    pthread_mutex_lock(&pool->mu);
    for (size_t j = 0; j < njobs;) {
        if (jobs[j].finished)
            j++;
        else if (pool->count)
            run_one_locked(pool);
        else
            pthread_cond_wait(&pool->done_cv, &pool->mu);
    }
    pthread_mutex_unlock(&pool->mu);
}

/* ---- write pass: time order ------------------------------------------------------------- */

/* Timesteps per chunk of a planned group (its count, or more for a padded last group). */
static size_t planned_timesteps(const cdvr_store *st, const cdvr_chunk_info *ci)
{
    size_t lo[3], bd[3];
    cdvr_codec_shape shape;
    cdvr_store_brick_box(&st->info, ci->brick, lo, bd);
    if (cdvr_codec_shape_of(ci->codec, &ci->params, bd, &shape, NULL) != CDVR_OK)
        return ci->count;
    return shape.timesteps;
}

/* One group in the write order: variant, its first chunk, and the frames [from, to) the
 * window must hold when it is submitted. */
typedef struct group_step {
    size_t variant, first_chunk, from, to;
} group_step;

/* The write order: always the pending group that ends first, so the frames in memory never
 * span more than a few groups. `from` keeps every frame that a group in flight (the depth - 1
 * submitted before, still being encoded) or a later group of any variant will need. Returns
 * the ring capacity the order needs. */
static size_t plan_order(const cdvr_store *st, size_t depth, group_step *order, size_t *n)
{
    size_t nv = st->info.nvariants, nb = st->info.nbricks, count = 0, cap = 1;
    size_t next[CDVR_STORE_MAX_VARIANTS] = {0};
    for (;;) {
        size_t best = nv, best_end = 0, low_t0 = SIZE_MAX;
        for (size_t v = 0; v < nv; v++) {
            if (next[v] == st->variants[v].ngroups)
                continue;
            const cdvr_chunk_info *g = &st->chunks[st->chunk_first[v] + next[v] * nb];
            size_t end = g->t0 + g->count;
            low_t0 = g->t0 < low_t0 ? g->t0 : low_t0;
            if (best == nv || end < best_end) {
                best = v;
                best_end = end;
            }
        }
        if (best == nv)
            break;
        group_step *g = &order[count];
        g->variant = best;
        g->first_chunk = st->chunk_first[best] + next[best] * nb;
        g->to = best_end;
        g->from = low_t0;
        for (size_t k = 1; k < depth && k <= count; k++) {
            size_t t0 = st->chunks[order[count - k].first_chunk].t0;
            g->from = t0 < g->from ? t0 : g->from;
        }
        cap = g->to - g->from > cap ? g->to - g->from : cap;
        next[best]++;
        count++;
    }
    *n = count;
    return cap;
}

typedef struct write_ctx {
    cdvr_store *st;
    const cdvr_encode_source *src;
    const cdvr_encode_opts *opts;
    int fd;
    uint64_t offset;             /* next free byte of the data area */
    uint64_t *sse;               /* per variant */
    double *maxerr;              /* per variant */
    size_t done, threads, depth;
    encode_pool pool;
} write_ctx;

/* Writes at offset of the temporary file; errors name the target the user gave (`target`),
 * not the temporary name (ENOSPC on "big.cdv" is what the user can act on). */
static cdvr_status write_at(int fd, const uint8_t *buf, size_t n, uint64_t offset,
                            const char *target, cdvr_error *err)
{
    size_t done = 0;
    while (done < n) {
        ssize_t w = pwrite(fd, buf + done, n - done, (off_t)(offset + done));
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: write failed: %s", target,
                                  w < 0 ? strerror(errno) : "no progress");
        done += (size_t)w;
    }
    return CDVR_OK;
}

/* Sets up the job of chunk ci (frames from the window, buffers) and returns its task count. */
static cdvr_status prepare_job(write_ctx *wc, const frame_window *win, size_t v,
                               cdvr_chunk_info *ci, size_t timesteps, chunk_job *job,
                               cdvr_error *err)
{
    const cdvr_store *st = wc->st;
    job_bufs bufs = job->bufs;
    memset(job, 0, sizeof *job);
    job->bufs = bufs;
    job->ci = ci;
    job->variant = v;
    job->timesteps = timesteps;
    cdvr_store_brick_box(&st->info, ci->brick, job->lo, job->bd);
    cdvr_status s = cdvr_codec_shape_of(ci->codec, &ci->params, job->bd, &job->shape, err);
    if (s != CDVR_OK)
        return s;
    size_t voxels = job->bd[0] * job->bd[1] * job->bd[2], decoded, window;
    const cdvr_variant_info *vi = &st->variants[v];
    int s2_auto = vi->stage2 == CDVR_STAGE2_AUTO;
    size_t s2_cap = s2_capacity(job->shape.bound_bytes, vi->stage2_segment);
    size_t own_lo[3], own_bd[3];
    cdvr_store_brick_owned(&st->info, ci->brick, own_lo, own_bd);
    job->ranges_shift = wc->opts->range_shift ? wc->opts->range_shift : CDVR_RANGE_SHIFT_DEFAULT;
    window = cdvr_range_window_bytes(st->info.dims, own_lo, own_bd, job->ranges_shift);
    job->ranges_bytes = wc->opts->no_range_tables ? 0 : window * ci->count;
    if (!cdvr_size_mul(voxels, ci->count, &decoded) ||
        !cdvr_grow_bytes(&job->bufs.payload, &job->bufs.payload_cap, job->shape.bound_bytes) ||
        s2_cap == 0 || !cdvr_grow_bytes(&job->bufs.packed, &job->bufs.packed_cap, s2_cap) ||
        (s2_auto && !cdvr_grow_bytes(&job->bufs.trial, &job->bufs.trial_cap, s2_cap)) ||
        !cdvr_grow_bytes(&job->bufs.decoded, &job->bufs.decoded_cap, decoded) ||
        !cdvr_grow_bytes(&job->bufs.ranges, &job->bufs.ranges_cap, job->ranges_bytes) ||
        !cdvr_grow_bytes(&job->bufs.ranges_packed, &job->bufs.ranges_packed_cap,
                         cdvr_range_pack_bound(job->ranges_bytes)) ||
        (st->info.nbricks > 1 &&
         !cdvr_grow_bytes(&job->bufs.bricks, &job->bufs.bricks_cap, decoded)))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for a %zu-byte chunk",
                              st->path, job->shape.bound_bytes);
    for (size_t i = 0; i < timesteps; i++) {
        size_t k = i < ci->count ? i : ci->count - 1; /* pad: repeat the last real timestep */
        const uint8_t *full = window_frame(win, ci->t0 + k);
        if (st->info.nbricks == 1) {
            job->frames[i] = full;
        } else {
            if (i < ci->count)
                cdvr_brick_extract(full, st->info.dims, job->lo, job->bd,
                                   job->bufs.bricks + k * voxels);
            job->frames[i] = job->bufs.bricks + k * voxels;
        }
    }
    size_t parts = wc->threads == 1 ? 1 : 4 * wc->threads;
    job->nparts = ci->codec->encode_part && job->shape.payload_bytes ? parts : 1;
    if (job->nparts > 1)
        job->payload_bytes = job->shape.payload_bytes;
    return CDVR_OK;
}

/* Queues every task of a group's jobs (the calling thread runs them itself with 1 thread). */
static void submit(write_ctx *wc, chunk_job *jobs, size_t njobs)
{
    encode_pool *pool = &wc->pool;
    pthread_mutex_lock(&pool->mu);
    for (size_t j = 0; j < njobs; j++)
        for (size_t p = 0; p < jobs[j].nparts; p++)
            push_task(pool, (task){&jobs[j], p}, 0);
    pthread_cond_broadcast(&pool->work_cv);
    pthread_mutex_unlock(&pool->mu);
}

/* Waits for a group and writes, in brick order, each chunk's range table and stored bytes. */
static cdvr_status write_group(write_ctx *wc, chunk_job *jobs, size_t njobs, cdvr_error *err)
{
    pool_wait(&wc->pool, jobs, njobs);
    cdvr_status s = CDVR_OK;
    for (size_t j = 0; s == CDVR_OK && j < njobs; j++) {
        chunk_job *job = &jobs[j];
        cdvr_chunk_info *ci = job->ci;
        if (job->err.status != CDVR_OK) {
            if (err)
                *err = job->err;
            return job->err.status;
        }
        if (ci->ranges_shift) {
            ci->ranges_offset = wc->offset;
            s = write_at(wc->fd, ci->ranges_stage2 ? job->bufs.ranges_packed : job->bufs.ranges,
                         (size_t)ci->ranges_stored_bytes, ci->ranges_offset, wc->st->path, err);
            wc->offset += ci->ranges_stored_bytes;
        }
        ci->offset = wc->offset;
        if (s == CDVR_OK)
            s = write_at(wc->fd, ci->stage2 ? job->bufs.packed : job->bufs.payload,
                         (size_t)ci->stored_bytes, ci->offset, wc->st->path, err);
        wc->offset += ci->stored_bytes;
        wc->sse[job->variant] += job->sse;
        wc->maxerr[job->variant] = job->maxerr > wc->maxerr[job->variant]
                                       ? job->maxerr : wc->maxerr[job->variant];
        if (s == CDVR_OK && wc->opts->progress)
            wc->opts->progress(wc->opts->progress_ud, ++wc->done, wc->st->nchunks_total);
    }
    return s;
}

/* Encodes every group in the planned order with up to `depth` groups in flight: while the
 * pool encodes them, this thread reads the next frames, then waits for the oldest group
 * (running tasks meanwhile) and writes it. Offsets follow the order, so the file does not
 * depend on the thread count. */
static cdvr_status write_chunks(write_ctx *wc, cdvr_error *err)
{
    cdvr_store *st = wc->st;
    size_t nb = st->info.nbricks, ngroups_total = 0, norder = 0, ring_bytes;
    for (size_t v = 0; v < st->info.nvariants; v++)
        ngroups_total += st->variants[v].ngroups;
    group_step *order = malloc(ngroups_total * sizeof *order);
    chunk_job *jobs = calloc(wc->depth * nb, sizeof *jobs); /* slot k: jobs k*nb .. */
    frame_window win = {.src = wc->src};
    win.voxels = st->info.dims[0] * st->info.dims[1] * st->info.dims[2];
    cdvr_status s = CDVR_OK;
    if (!order || !jobs)
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory to plan %zu groups", st->path,
                           ngroups_total);
    if (s == CDVR_OK) {
        win.cap = plan_order(st, wc->depth, order, &norder);
        if (!cdvr_size_mul(win.voxels, win.cap, &ring_bytes) || !(win.ring = malloc(ring_bytes)))
            s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for %zu frames", st->path,
                               win.cap);
    }
    if (s == CDVR_OK)
        s = pool_start(&wc->pool, st, wc->threads, wc->depth * nb * (4 * wc->threads + 1), err);
    size_t written = 0, submitted = 0;
    for (size_t i = 0; s == CDVR_OK && i < norder; i++) {
        if (i - written == wc->depth) {
            s = write_group(wc, &jobs[(written % wc->depth) * nb], nb, err);
            written++;
        }
        if (s == CDVR_OK)
            s = window_need(&win, order[i].from, order[i].to, err);
        chunk_job *slot = &jobs[(i % wc->depth) * nb];
        size_t timesteps = planned_timesteps(st, &st->chunks[order[i].first_chunk]);
        for (size_t b = 0; s == CDVR_OK && b < nb; b++)
            s = prepare_job(wc, &win, order[i].variant, &st->chunks[order[i].first_chunk + b],
                            timesteps, &slot[b], err);
        if (s == CDVR_OK) {
            submit(wc, slot, nb);
            submitted++;
        }
    }
    for (; written < submitted; written++) { /* on failure: wait, so no task uses freed memory */
        cdvr_error gerr;
        cdvr_status g = write_group(wc, &jobs[(written % wc->depth) * nb], nb, &gerr);
        if (s == CDVR_OK && g != CDVR_OK) {
            s = g;
            if (err)
                *err = gerr;
        }
    }
    if (wc->pool.queue)
        pool_stop(&wc->pool);
    for (size_t j = 0; jobs && j < wc->depth * nb; j++)
        bufs_free(&jobs[j].bufs);
    free(jobs);
    free(order);
    free(win.ring);
    return s;
}

/* Shared blobs (cdvr/codec.h): each variant whose codec wants one is trained on up to
 * SHARED_SAMPLE_FRAMES timesteps spread evenly over the series (t = j*T/n; fewer when they
 * would pass SHARED_SAMPLE_BYTES, at least one), written at the start of the data area and
 * put in the shared-blob table; its chunks get the trained parameters (which name the blob). */
#define SHARED_SAMPLE_FRAMES 4
#define SHARED_SAMPLE_BYTES ((size_t)1 << 30)

static cdvr_status train_variant(write_ctx *wc, cdvr_variant_info *vi, size_t v,
                                 const uint8_t *const *frames, size_t nframes, cdvr_error *err)
{
    cdvr_store *st = wc->st;
    cdvr_codec_params before = vi->params;
    uint8_t *blob = NULL;
    size_t bytes = 0;
    cdvr_status s = cdvr_codec_train_shared(vi->codec, &vi->params, st->info.dims, frames,
                                            nframes, &blob, &bytes, err);
    if (s == CDVR_OK && (bytes == 0 || bytes > UINT32_MAX))
        s = cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: variant %s: a shared blob of %zu "
                           "bytes (1..2^32-1)", st->path, vi->name, bytes);
    if (s == CDVR_OK)
        s = cdvr_shared_put(blob, bytes, &vi->shared_id, err);
    if (s == CDVR_OK)
        s = write_at(wc->fd, blob, bytes, wc->offset, st->path, err);
    if (s == CDVR_OK) {
        vi->shared_offset = wc->offset;
        vi->shared_bytes = bytes;
        wc->offset += bytes;
        for (size_t c = 0; c < vi->nchunks; c++) {
            cdvr_chunk_info *ci = &st->chunks[st->chunk_first[v] + c];
            if (memcmp(&ci->params, &before, sizeof before) == 0)
                ci->params = vi->params;
        }
    }
    free(blob);
    return s;
}

static cdvr_status train_shared(write_ctx *wc, cdvr_error *err)
{
    cdvr_store *st = wc->st;
    size_t voxels = st->info.dims[0] * st->info.dims[1] * st->info.dims[2], nframes = 0;
    uint8_t *frames[SHARED_SAMPLE_FRAMES] = {NULL};
    cdvr_status s = CDVR_OK;
    for (size_t v = 0; s == CDVR_OK && v < st->info.nvariants; v++) {
        cdvr_variant_info *vi = &st->variants[v];
        if (!vi->codec || !cdvr_codec_wants_shared(vi->codec, &vi->params))
            continue;
        size_t want = st->info.timesteps < SHARED_SAMPLE_FRAMES ? st->info.timesteps
                                                                : SHARED_SAMPLE_FRAMES;
        while (want > 1 && voxels > SHARED_SAMPLE_BYTES / want)
            want--;
        for (; s == CDVR_OK && nframes < want; nframes++) {
            frames[nframes] = malloc(voxels);
            s = !frames[nframes]
                    ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for a sample frame",
                                     st->path)
                    : wc->src->frame(wc->src->frame_ud, nframes * st->info.timesteps / want,
                                     frames[nframes], err);
        }
        if (s == CDVR_OK)
            s = train_variant(wc, vi, v, (const uint8_t *const *)frames, nframes, err);
    }
    for (size_t i = 0; i < SHARED_SAMPLE_FRAMES; i++)
        free(frames[i]);
    return s;
}

static cdvr_status write_meta(cdvr_store *st, int fd, const char *target, cdvr_error *err)
{
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    uint8_t *buf = malloc((size_t)meta + 4);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for the index", st->path);
    cdvr_store_serialize_meta(st, buf);
    cdvr_status s = write_at(fd, buf, (size_t)meta + 4, 0, target, err);
    free(buf);
    return s;
}

static void finish_variants(cdvr_store *st, const uint64_t *sse, const double *maxerr)
{
    for (size_t v = 0; v < st->info.nvariants; v++) {
        double mse = (double)sse[v] / (double)st->info.raw_bytes;
        st->variants[v].psnr = mse > 0 ? 10.0 * log10(255.0 * 255.0 / mse) : HUGE_VAL;
        st->variants[v].maxerr = maxerr[v];
    }
}

/* AUTO variants given no read rate model the rate the player will read the store at
 * (cdvr_store_modelled_read_mbps over the rates of the filesystem path is written to,
 * measured once and remembered; CDVR_STAGE2_READ_MBPS where they cannot be measured, e.g.
 * no room for the test file), recorded in the store. */
static void model_read_rate(cdvr_store *st, const char *path)
{
    double mbps = 0;
    for (size_t v = 0; v < st->info.nvariants; v++) {
        if (st->variants[v].stage2_read_mbps != 0)
            continue;
        if (mbps == 0) {
            cdvr_read_rates rates;
            cdvr_error ignored;
            mbps = cdvr_store_read_rates(path, &rates, &ignored) == CDVR_OK
                       ? cdvr_store_modelled_read_mbps(&rates, st->info.raw_bytes,
                                                       cdvr_usable_memory_bytes())
                       : CDVR_STAGE2_READ_MBPS;
        }
        st->variants[v].stage2_read_mbps = mbps;
    }
}

static size_t encode_threads(const cdvr_encode_opts *opts)
{
    size_t n = opts->threads > 0 ? (size_t)opts->threads : online_cores();
    return n > CDVR_ENCODE_MAX_THREADS ? CDVR_ENCODE_MAX_THREADS : n;
}

cdvr_status cdvr_store_encode_source(const cdvr_encode_source *src,
                                     const cdvr_encode_opts *opts, const char *path,
                                     cdvr_error *err)
{
    if (opts && opts->levels > 1) /* a multi-resolution store: levels.c */
        return cdvr_store_encode_levels(src, opts, path, err);
    cdvr_store *st = NULL;
    cdvr_status s = check_opts(src, opts, path, err);
    if (s == CDVR_OK && opts->threads < 0)
        s = cdvr_error_set(err, CDVR_ERR_ARG, "%s: threads %d (0 = one per core)", path,
                           opts->threads);
    if (s == CDVR_OK)
        s = plan_store(src, opts, path, &st, err);
    if (s != CDVR_OK)
        return s;
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    write_ctx wc = {.st = st, .src = src, .opts = opts, .offset = meta + 4};
    wc.threads = encode_threads(opts);
    wc.depth = wc.threads > 1 ? 2 : 1;
    wc.sse = calloc(st->info.nvariants, sizeof *wc.sse);
    wc.maxerr = calloc(st->info.nvariants, sizeof *wc.maxerr);
    cdvr_atomic_file af;
    s = !wc.sse || !wc.maxerr ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", path)
        : meta == 0 ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: index too large", path)
                    : cdvr_atomic_open(&af, path, err);
    if (s != CDVR_OK) {
        free(wc.sse);
        free(wc.maxerr);
        cdvr_store_close(st);
        return s;
    }
    wc.fd = fileno(af.f); /* written with pwrite only: the FILE buffers nothing */
    model_read_rate(st, path);
    s = train_shared(&wc, err);
    if (s == CDVR_OK)
        s = write_chunks(&wc, err);
    if (s == CDVR_OK) {
        st->info.file_bytes = wc.offset;
        finish_variants(st, wc.sse, wc.maxerr);
        s = write_meta(st, wc.fd, st->path, err);
    }
    cdvr_error commit_err;
    cdvr_status c = cdvr_atomic_commit(&af, s != CDVR_OK, &commit_err);
    if (s == CDVR_OK && c != CDVR_OK) {
        s = c;
        if (err)
            *err = commit_err;
    }
    free(wc.sse);
    free(wc.maxerr);
    cdvr_store_close(st);
    return s;
}

/* ---- a volume in memory as the frame source --------------------------------------------- */

static cdvr_status volume_frame(void *ud, size_t t, uint8_t *out, cdvr_error *err)
{
    const cdvr_volume *vol = ud;
    (void)err;
    memcpy(out, cdvr_volume_frame(vol, t), cdvr_volume_frame_bytes(vol));
    return CDVR_OK;
}

cdvr_status cdvr_store_encode(const cdvr_volume *u8, const cdvr_encode_opts *opts,
                              const char *path, cdvr_error *err)
{
    if (!u8)
        return cdvr_error_set(err, CDVR_ERR_ARG, "encode: no volume");
    if (u8->type != CDVR_TYPE_U8)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: encode needs a u8 volume, got %s "
                              "(quantize first)", path ? path : "encode",
                              cdvr_type_name(u8->type));
    cdvr_encode_source src = {.timesteps = u8->timesteps, .frame = volume_frame,
                              .frame_ud = (void *)u8};
    memcpy(src.dims, u8->dims, sizeof src.dims);
    memcpy(src.spacing, u8->spacing, sizeof src.spacing);
    memcpy(src.origin, u8->origin, sizeof src.origin);
    memcpy(src.direction, u8->direction, sizeof src.direction);
    return cdvr_store_encode_source(&src, opts, path, err);
}
