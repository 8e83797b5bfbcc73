/* core/store/encode.c - the encode driver: u8 series -> .cdv store (cdvr_store_encode*, store.h).
 *
 * Two passes. The plan pass resolves each variant (codec, parameters, name) and calls the
 * schedule once per chunk group to fix every group's parameters and timestep count, so the
 * size of the metadata is known. The write pass walks the series forward in time: it asks
 * the frame source for each timestep once, keeps only the frames that groups still in
 * flight need, and encodes the group of whichever variant ends first (all bricks of it),
 * applies stage 2 where it pays, writes the stored bytes after the metadata, decodes the
 * payload again to measure the variant's volume PSNR and max error (peak 255, as
 * cdvr_compare; each voxel counted once, in the brick that owns it) and the chunk's value
 * range, and reports progress. Finally the metadata goes to offset 0, the file is fsync'ed
 * and renamed over the final name (cdvr_atomic_file); on any failure it is removed.
 */
#include "cdvr/atomicfile.h"
#include "store_format.h"

#include "codec/stage2/stage2.h"

#include <errno.h>
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
    if (spec->stage2 != CDVR_STAGE2_NONE && spec->stage2 != CDVR_STAGE2_LZO)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: bad stage2 %d", path, (int)spec->stage2);
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

/* ---- write pass: one chunk -------------------------------------------------------------- */

typedef struct chunk_work {
    uint8_t *payload, *packed, *bricks, *decoded;
    size_t payload_cap, packed_cap, bricks_cap, decoded_cap;
} chunk_work;

static int reserve(uint8_t **buf, size_t *cap, size_t need)
{
    if (need <= *cap)
        return 1;
    uint8_t *nb = realloc(*buf, need ? need : 1);
    if (!nb)
        return 0;
    *buf = nb;
    *cap = need;
    return 1;
}

static void work_free(chunk_work *w)
{
    free(w->payload);
    free(w->packed);
    free(w->bricks);
    free(w->decoded);
}

/* First local index along an axis that the brick starting at voxel lo owns: a voxel two
 * bricks share belongs to the lower one, so every brick but the first skips its first voxel. */
static size_t first_owned(size_t lo)
{
    return lo > 0 ? 1 : 0;
}

typedef struct chunk_error {
    double sse, maxerr;
} chunk_error;

/* Squared and max error of a decoded brick frame against its source, over owned voxels. */
static void measure_frame(const uint8_t *ref, const uint8_t *dec, const size_t lo[3],
                          const size_t bd[3], chunk_error *e)
{
    for (size_t z = first_owned(lo[2]); z < bd[2]; z++) {
        for (size_t y = first_owned(lo[1]); y < bd[1]; y++) {
            size_t row = bd[0] * (y + bd[1] * z);
            double sse = 0;
            for (size_t x = first_owned(lo[0]); x < bd[0]; x++) {
                double d = (double)ref[row + x] - (double)dec[row + x];
                sse += d * d;
                if (fabs(d) > e->maxerr)
                    e->maxerr = fabs(d);
            }
            e->sse += sse;
        }
    }
}

typedef struct write_ctx {
    cdvr_store *st;
    const cdvr_encode_source *src;
    const char *tmp;
    int fd;
    uint64_t offset;             /* next free byte of the data area */
    chunk_work work;
    chunk_error *errors;         /* per variant */
    size_t done;
    const cdvr_encode_opts *opts;
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

/* Source frames of the brick: pointers into the window (one brick) or copies. */
static cdvr_status brick_frames(write_ctx *wc, const frame_window *win, const cdvr_chunk_info *ci,
                                size_t timesteps, const size_t lo[3], const size_t bd[3],
                                const uint8_t **frames, cdvr_error *err)
{
    const cdvr_store_info *in = &wc->st->info;
    size_t voxels = bd[0] * bd[1] * bd[2];
    if (in->nbricks > 1 && !reserve(&wc->work.bricks, &wc->work.bricks_cap, voxels * ci->count))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for a brick", wc->st->path);
    for (size_t i = 0; i < timesteps; i++) {
        size_t k = i < ci->count ? i : ci->count - 1; /* pad: repeat the last real timestep */
        const uint8_t *full = window_frame(win, ci->t0 + k);
        if (in->nbricks == 1) {
            frames[i] = full;
        } else {
            if (i < ci->count)
                cdvr_brick_extract(full, in->dims, lo, bd, wc->work.bricks + k * voxels);
            frames[i] = wc->work.bricks + k * voxels;
        }
    }
    return CDVR_OK;
}

/* Decodes the payload again: error against the source and the value range of the chunk. */
static cdvr_status measure_chunk(write_ctx *wc, size_t v, cdvr_chunk_info *ci,
                                 const uint8_t *const *src, const size_t lo[3],
                                 const size_t bd[3], cdvr_error *err)
{
    size_t voxels = bd[0] * bd[1] * bd[2];
    if (!reserve(&wc->work.decoded, &wc->work.decoded_cap, voxels * ci->count))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory to measure PSNR",
                              wc->st->path);
    uint8_t *frames[MAX_CHUNK_TIMESTEPS];
    for (size_t i = 0; i < ci->count; i++)
        frames[i] = wc->work.decoded + i * voxels;
    size_t vlo[3], vdims[3];
    cdvr_store_brick_box(&wc->st->info, ci->brick, vlo, vdims);
    cdvr_status s = ci->codec->decode(&ci->params, bd, wc->work.payload,
                                      (size_t)ci->payload_bytes, frames, ci->count, err);
    if (s != CDVR_OK)
        return s;
    uint8_t mn = 255, mx = 0;
    for (size_t i = 0; i < ci->count; i++) {
        measure_frame(src[i], frames[i], lo, bd, &wc->errors[v]);
        for (size_t k = 0; k < voxels; k++) {
            mn = frames[i][k] < mn ? frames[i][k] : mn;
            mx = frames[i][k] > mx ? frames[i][k] : mx;
        }
    }
    ci->value_min = mn;
    ci->value_max = mx;
    return CDVR_OK;
}

static cdvr_status write_chunk(write_ctx *wc, const frame_window *win, size_t v,
                               cdvr_chunk_info *ci, size_t timesteps, cdvr_error *err)
{
    cdvr_store *st = wc->st;
    const cdvr_variant_info *vi = &st->variants[v];
    size_t lo[3], bd[3];
    cdvr_store_brick_box(&st->info, ci->brick, lo, bd);
    cdvr_codec_shape shape;
    cdvr_error cerr;
    const uint8_t *frames[MAX_CHUNK_TIMESTEPS];
    cdvr_status s = cdvr_codec_shape_of(ci->codec, &ci->params, bd, &shape, err);
    if (s == CDVR_OK)
        s = brick_frames(wc, win, ci, timesteps, lo, bd, frames, err);
    if (s == CDVR_OK && (!reserve(&wc->work.payload, &wc->work.payload_cap, shape.bound_bytes) ||
                         !reserve(&wc->work.packed, &wc->work.packed_cap,
                                  cdvr_lzo_bound(shape.bound_bytes))))
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for a %zu-byte chunk", st->path,
                           shape.bound_bytes);
    size_t payload = 0, packed = 0;
    if (s == CDVR_OK &&
        ci->codec->encode(&ci->params, bd, frames, ci->count, wc->work.payload,
                          shape.bound_bytes, &payload, &cerr) != CDVR_OK)
        s = cdvr_error_set(err, cerr.status, "%s: variant %s, timestep %zu: %s", st->path,
                           vi->name, ci->t0 + 1, cerr.msg);
    if (s == CDVR_OK && (payload == 0 || payload > shape.bound_bytes ||
                         (shape.payload_bytes && payload != shape.payload_bytes)))
        s = cdvr_error_set(err, CDVR_ERR_ARG, "%s: codec %s wrote %zu bytes (size %zu, bound "
                           "%zu)", st->path, ci->codec->name, payload, shape.payload_bytes,
                           shape.bound_bytes);
    if (s == CDVR_OK && vi->stage2 == CDVR_STAGE2_LZO)
        s = cdvr_lzo_compress(wc->work.payload, payload, wc->work.packed, wc->work.packed_cap,
                              &packed, err);
    if (s != CDVR_OK)
        return s;
    ci->payload_bytes = payload;
    ci->stage2 = vi->stage2 == CDVR_STAGE2_LZO && cdvr_lzo_keep(payload, packed,
                                                                 vi->lzo_min_saving);
    const uint8_t *stored = ci->stage2 ? wc->work.packed : wc->work.payload;
    ci->stored_bytes = ci->stage2 ? packed : payload;
    ci->offset = wc->offset;
    ci->crc32c = cdvr_crc32c(0, stored, (size_t)ci->stored_bytes);
    s = write_at(wc->fd, stored, (size_t)ci->stored_bytes, ci->offset, st->path, err);
    wc->offset += ci->stored_bytes;
    if (s == CDVR_OK)
        s = measure_chunk(wc, v, ci, frames, lo, bd, err);
    if (s == CDVR_OK && wc->opts->progress)
        wc->opts->progress(wc->opts->progress_ud, ++wc->done, st->nchunks_total);
    return s;
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

/* Encodes every group in time order: always the pending group that ends first, so the
 * frames in memory never span more than the longest group. */
static cdvr_status write_chunks(write_ctx *wc, cdvr_error *err)
{
    cdvr_store *st = wc->st;
    size_t nv = st->info.nvariants, nb = st->info.nbricks, span = 1, ring_bytes;
    for (size_t c = 0; c < st->nchunks_total; c++)
        span = st->chunks[c].count > span ? st->chunks[c].count : span;
    frame_window win = {.src = wc->src, .cap = span};
    win.voxels = st->info.dims[0] * st->info.dims[1] * st->info.dims[2];
    size_t *next = calloc(nv, sizeof *next); /* next group per variant */
    cdvr_status s = CDVR_OK;
    if (!next || !cdvr_size_mul(win.voxels, win.cap, &ring_bytes) ||
        !(win.ring = malloc(ring_bytes)))
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for %zu frames", st->path, span);
    while (s == CDVR_OK) {
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
        s = window_need(&win, low_t0, best_end, err);
        size_t first = st->chunk_first[best] + next[best] * nb;
        size_t timesteps = planned_timesteps(st, &st->chunks[first]);
        for (size_t b = 0; s == CDVR_OK && b < nb; b++)
            s = write_chunk(wc, &win, best, &st->chunks[first + b], timesteps, err);
        next[best]++;
    }
    free(next);
    free(win.ring);
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

static void finish_variants(cdvr_store *st, const chunk_error *errors)
{
    for (size_t v = 0; v < st->info.nvariants; v++) {
        double mse = errors[v].sse / (double)st->info.raw_bytes;
        st->variants[v].psnr = mse > 0 ? 10.0 * log10(255.0 * 255.0 / mse) : HUGE_VAL;
        st->variants[v].maxerr = errors[v].maxerr;
    }
}

cdvr_status cdvr_store_encode_source(const cdvr_encode_source *src,
                                     const cdvr_encode_opts *opts, const char *path,
                                     cdvr_error *err)
{
    cdvr_store *st = NULL;
    cdvr_status s = check_opts(src, opts, path, err);
    if (s == CDVR_OK)
        s = plan_store(src, opts, path, &st, err);
    if (s != CDVR_OK)
        return s;
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    write_ctx wc = {.st = st, .src = src, .opts = opts, .offset = meta + 4};
    wc.errors = calloc(st->info.nvariants, sizeof *wc.errors);
    cdvr_atomic_file af;
    s = !wc.errors ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", path)
        : meta == 0 ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: index too large", path)
                    : cdvr_atomic_open(&af, path, err);
    if (s != CDVR_OK) {
        free(wc.errors);
        cdvr_store_close(st);
        return s;
    }
    wc.tmp = af.tmp_path;
    wc.fd = fileno(af.f); /* written with pwrite only: the FILE buffers nothing */
    s = write_chunks(&wc, err);
    if (s == CDVR_OK) {
        st->info.file_bytes = wc.offset;
        finish_variants(st, wc.errors);
        s = write_meta(st, wc.fd, st->path, err);
    }
    cdvr_error commit_err;
    cdvr_status c = cdvr_atomic_commit(&af, s != CDVR_OK, &commit_err);
    if (s == CDVR_OK && c != CDVR_OK) {
        s = c;
        if (err)
            *err = commit_err;
    }
    work_free(&wc.work);
    free(wc.errors);
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
