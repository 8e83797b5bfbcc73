/* core/store/encode.c - the encode driver: u8 series -> .cdv store (cdvr_store_encode, store.h).
 *
 * Two passes. The plan pass resolves each variant (defaults, name) and calls the schedule
 * once per group to fix every chunk's parameters and timestep count, so the size of the
 * metadata is known. The write pass encodes each chunk (PVTC or raw), applies stage 2 where it
 * pays, writes the stored bytes after the metadata, decodes the payload again to measure the
 * variant's volume PSNR and max error (peak 255, as cdvr_compare), and reports progress.
 * Finally the metadata goes to offset 0, the file is fsync'ed and renamed over the final name.
 * The file is written under a temporary name (cdvr_atomic_file); on any failure it is removed.
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
                                   cdvr_variant_info *vi, double *min_saving, cdvr_error *err)
{
    if (spec->codec != CDVR_CODEC_RAW && spec->codec != CDVR_CODEC_PVTC)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: codec id %d cannot be encoded "
                              "here (raw, pvtc)", path, (int)spec->codec);
    if ((spec->encoder != CDVR_ENCODER_LSQ && spec->encoder != CDVR_ENCODER_BBOX) ||
        (spec->stage2 != CDVR_STAGE2_NONE && spec->stage2 != CDVR_STAGE2_LZO))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: bad encoder %d or stage2 %d", path,
                              (int)spec->encoder, (int)spec->stage2);
    double saving = spec->lzo_min_saving < 0 ? CDVR_LZO_MIN_SAVING : spec->lzo_min_saving;
    if (!(saving <= 1.0))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: lzo_min_saving %g is not in [0, 1]", path,
                              spec->lzo_min_saving);
    if (memchr(spec->name, 0, CDVR_NAME_MAX) == NULL)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: variant name longer than %d bytes", path,
                              CDVR_NAME_MAX - 1);
    memset(vi, 0, sizeof *vi);
    if (spec->name[0])
        memcpy(vi->name, spec->name, CDVR_NAME_MAX);
    else
        cdvr_store_default_name(spec->codec, &spec->pvtc, vi->name);
    vi->codec = spec->codec;
    snprintf(vi->codec_name, sizeof vi->codec_name, "%s",
             spec->codec == CDVR_CODEC_RAW ? "raw" : "pvtc");
    vi->pvtc = spec->pvtc;
    vi->encoder = spec->encoder;
    vi->stage2 = spec->stage2;
    *min_saving = saving;
    return CDVR_OK;
}

static cdvr_status plan_group(const cdvr_encode_opts *opts, const cdvr_volume *u8, size_t v,
                              size_t t0, const cdvr_variant_info *vi, cdvr_chunk_info *ci,
                              const char *path, cdvr_error *err)
{
    memset(ci, 0, sizeof *ci);
    ci->t0 = t0;
    ci->pvtc = vi->pvtc;
    if (opts->schedule) {
        cdvr_status s = opts->schedule(opts->schedule_ud, v, t0, &ci->pvtc, err);
        if (s != CDVR_OK)
            return s;
    }
    size_t payload;
    cdvr_error perr;
    if (cdvr_store_payload_bytes(vi->codec, &ci->pvtc, u8->dims, &payload, &perr) != CDVR_OK)
        return cdvr_error_set(err, perr.status, "%s: variant %s, timestep %zu: %s", path,
                              vi->name, t0 + 1, perr.msg);
    size_t group = vi->codec == CDVR_CODEC_PVTC && ci->pvtc.pack == CDVR_PACK_TIME
                       ? (size_t)ci->pvtc.T : 1;
    size_t left = u8->timesteps - t0;
    ci->count = left < group ? left : group;
    ci->payload_bytes = payload;
    return CDVR_OK;
}

static cdvr_status plan_variant(const cdvr_encode_opts *opts, const cdvr_volume *u8, size_t v,
                                cdvr_variant_info *vi, chunk_list *chunks, const char *path,
                                cdvr_error *err)
{
    size_t t0 = 0;
    while (t0 < u8->timesteps) {
        cdvr_chunk_info ci;
        cdvr_status s = plan_group(opts, u8, v, t0, vi, &ci, path, err);
        if (s == CDVR_OK)
            s = chunk_list_push(chunks, &ci, err);
        if (s != CDVR_OK)
            return s;
        t0 += ci.count;
        vi->nchunks++;
    }
    return CDVR_OK;
}

static cdvr_status check_opts(const cdvr_volume *u8, const cdvr_encode_opts *opts,
                              const char *path, cdvr_error *err)
{
    if (!u8 || !opts || !path || !*path)
        return cdvr_error_set(err, CDVR_ERR_ARG, "encode: volume, options and path are required");
    if (u8->type != CDVR_TYPE_U8)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: encode needs a u8 volume, got %s "
                              "(quantize first)", path, cdvr_type_name(u8->type));
    if (opts->nvariants < 1 || opts->nvariants > CDVR_STORE_MAX_VARIANTS || !opts->variants)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: %zu variants (must be 1..%u)", path,
                              opts->nvariants, CDVR_STORE_MAX_VARIANTS);
    if (!isfinite(opts->qlo) || !isfinite(opts->qhi) || opts->qhi < opts->qlo ||
        (unsigned)opts->source_type > CDVR_TYPE_F32)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: bad quantisation window [%g, %g] or "
                              "source type", path, opts->qlo, opts->qhi);
    return CDVR_OK;
}

/* Builds the store description: variants resolved, every chunk planned (offsets not yet). */
static cdvr_status plan_store(const cdvr_volume *u8, const cdvr_encode_opts *opts,
                              const char *path, cdvr_store **out, cdvr_error *err)
{
    size_t nv = opts->nvariants;
    cdvr_variant_info *vis = calloc(nv, sizeof *vis);
    double *savings = calloc(nv, sizeof *savings);
    chunk_list chunks = {0};
    cdvr_status s = (vis && savings) ? CDVR_OK
                                     : cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", path);
    for (size_t v = 0; s == CDVR_OK && v < nv; v++) {
        s = resolve_variant(path, &opts->variants[v], &vis[v], &savings[v], err);
        for (size_t i = 0; s == CDVR_OK && i < v; i++)
            if (strcmp(vis[i].name, vis[v].name) == 0)
                s = cdvr_error_set(err, CDVR_ERR_ARG, "%s: two variants are called %s", path,
                                   vis[v].name);
        if (s == CDVR_OK)
            s = plan_variant(opts, u8, v, &vis[v], &chunks, path, err);
    }
    cdvr_store *st = NULL;
    if (s == CDVR_OK)
        s = cdvr_store_alloc(nv, chunks.n, path, &st, err);
    if (s == CDVR_OK) {
        memcpy(st->variants, vis, nv * sizeof *vis);
        memcpy(st->lzo_min_saving, savings, nv * sizeof *savings);
        memcpy(st->chunks, chunks.items, chunks.n * sizeof *chunks.items);
        for (size_t v = 1; v < nv; v++)
            st->chunk_first[v] = st->chunk_first[v - 1] + vis[v - 1].nchunks;
        *out = st;
    }
    free(vis);
    free(savings);
    free(chunks.items);
    return s;
}

/* ---- write pass ------------------------------------------------------------------------- */

static cdvr_status write_at(int fd, const uint8_t *buf, size_t n, uint64_t offset,
                            const char *tmp, cdvr_error *err)
{
    size_t done = 0;
    while (done < n) {
        ssize_t w = pwrite(fd, buf + done, n - done, (off_t)(offset + done));
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: write failed: %s", tmp,
                                  w < 0 ? strerror(errno) : "no progress");
        done += (size_t)w;
    }
    return CDVR_OK;
}

typedef struct chunk_work {
    uint8_t *payload, *packed, *decoded;
    size_t payload_cap, packed_cap, voxels;
    double sse, maxerr;
} chunk_work;

static cdvr_status work_reserve(chunk_work *w, size_t payload, const char *path, cdvr_error *err)
{
    if (payload <= w->payload_cap)
        return CDVR_OK;
    size_t packed = cdvr_lzo_bound(payload);
    uint8_t *p = realloc(w->payload, payload), *q = p ? realloc(w->packed, packed) : NULL;
    if (p)
        w->payload = p;
    if (q)
        w->packed = q;
    if (!p || !q || packed == 0)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for a %zu-byte chunk", path,
                              payload);
    w->payload_cap = payload;
    w->packed_cap = packed;
    return CDVR_OK;
}

static void frame_pointers(const cdvr_volume *u8, const cdvr_chunk_info *ci, size_t n,
                           const uint8_t **frames)
{
    for (size_t i = 0; i < n; i++) {
        size_t t = ci->t0 + (i < ci->count ? i : ci->count - 1); /* pad: repeat the last */
        frames[i] = (const uint8_t *)cdvr_volume_frame(u8, t);
    }
}

static cdvr_status encode_payload(const cdvr_volume *u8, const cdvr_variant_info *vi,
                                  const cdvr_chunk_info *ci, uint8_t *out, cdvr_error *err)
{
    const uint8_t *frames[8];
    if (vi->codec == CDVR_CODEC_RAW) {
        memcpy(out, cdvr_volume_frame(u8, ci->t0), (size_t)ci->payload_bytes);
        return CDVR_OK;
    }
    size_t n = ci->pvtc.pack == CDVR_PACK_TIME ? (size_t)ci->pvtc.T : 1;
    frame_pointers(u8, ci, n, frames);
    return cdvr_pvtc_encode_chunk(&ci->pvtc, vi->encoder, u8->dims, frames, out, err);
}

/* Decodes the payload again and accumulates squared and max error against the input. */
static cdvr_status measure_chunk(const cdvr_volume *u8, const cdvr_variant_info *vi,
                                 const cdvr_chunk_info *ci, chunk_work *w, cdvr_error *err)
{
    uint8_t *frames[8];
    for (size_t i = 0; i < ci->count; i++)
        frames[i] = w->decoded + i * w->voxels;
    cdvr_status s = cdvr_store_decode_payload(vi->codec, &ci->pvtc, u8->dims, w->payload,
                                              (size_t)ci->payload_bytes, frames, ci->count, err);
    if (s != CDVR_OK)
        return s;
    for (size_t i = 0; i < ci->count; i++) {
        const uint8_t *ref = (const uint8_t *)cdvr_volume_frame(u8, ci->t0 + i);
        double sse = 0, maxerr = w->maxerr;
        for (size_t k = 0; k < w->voxels; k++) {
            double d = (double)ref[k] - (double)frames[i][k];
            sse += d * d;
            if (fabs(d) > maxerr)
                maxerr = fabs(d);
        }
        w->sse += sse;
        w->maxerr = maxerr;
    }
    return CDVR_OK;
}

static cdvr_status write_chunk(const cdvr_volume *u8, cdvr_store *st, size_t v,
                               cdvr_chunk_info *ci, uint64_t *offset, chunk_work *w,
                               const char *tmp, cdvr_error *err)
{
    const cdvr_variant_info *vi = &st->variants[v];
    size_t payload = (size_t)ci->payload_bytes, packed = 0;
    cdvr_status s = work_reserve(w, payload, st->path, err);
    if (s == CDVR_OK)
        s = encode_payload(u8, vi, ci, w->payload, err);
    if (s == CDVR_OK && vi->stage2 == CDVR_STAGE2_LZO)
        s = cdvr_lzo_compress(w->payload, payload, w->packed, w->packed_cap, &packed, err);
    if (s != CDVR_OK)
        return s;
    ci->stage2 = vi->stage2 == CDVR_STAGE2_LZO &&
                 cdvr_lzo_keep(payload, packed, st->lzo_min_saving[v]);
    const uint8_t *stored = ci->stage2 ? w->packed : w->payload;
    ci->stored_bytes = ci->stage2 ? packed : payload;
    ci->offset = *offset;
    ci->crc32c = cdvr_crc32c(0, stored, (size_t)ci->stored_bytes);
    s = write_at(st->fd, stored, (size_t)ci->stored_bytes, ci->offset, tmp, err);
    if (s == CDVR_OK)
        s = measure_chunk(u8, vi, ci, w, err);
    *offset += ci->stored_bytes;
    return s;
}

static cdvr_status write_chunks(const cdvr_volume *u8, const cdvr_encode_opts *opts,
                                cdvr_store *st, uint64_t data_offset, const char *tmp,
                                cdvr_error *err)
{
    chunk_work w = {.voxels = cdvr_volume_voxels(u8)};
    size_t decoded_bytes, done = 0;
    cdvr_status s = CDVR_OK;
    if (!cdvr_size_mul(w.voxels, 3, &decoded_bytes) || !(w.decoded = malloc(decoded_bytes)))
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory to measure PSNR", st->path);
    uint64_t offset = data_offset;
    for (size_t v = 0; s == CDVR_OK && v < st->info.nvariants; v++) {
        cdvr_variant_info *vi = &st->variants[v];
        w.sse = 0;
        w.maxerr = 0;
        for (size_t c = 0; s == CDVR_OK && c < vi->nchunks; c++) {
            s = write_chunk(u8, st, v, &st->chunks[st->chunk_first[v] + c], &offset, &w, tmp, err);
            if (s == CDVR_OK && opts->progress)
                opts->progress(opts->progress_ud, ++done, st->nchunks_total);
        }
        double mse = w.sse / (double)st->info.raw_bytes;
        vi->psnr = mse > 0 ? 10.0 * log10(255.0 * 255.0 / mse) : HUGE_VAL;
        vi->maxerr = w.maxerr;
    }
    st->info.file_bytes = offset;
    free(w.payload);
    free(w.packed);
    free(w.decoded);
    return s;
}

static cdvr_status write_meta(cdvr_store *st, const char *tmp, cdvr_error *err)
{
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    uint8_t *buf = malloc((size_t)meta + 4);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for the index", st->path);
    cdvr_store_serialize_meta(st, buf);
    cdvr_status s = write_at(st->fd, buf, (size_t)meta + 4, 0, tmp, err);
    free(buf);
    return s;
}

static void fill_header(cdvr_store *st, const cdvr_volume *u8, const cdvr_encode_opts *opts)
{
    cdvr_store_info *in = &st->info;
    for (int i = 0; i < 3; i++) {
        in->dims[i] = u8->dims[i];
        in->spacing[i] = u8->spacing[i];
        in->origin[i] = u8->origin[i];
    }
    in->timesteps = u8->timesteps;
    in->qlo = opts->qlo;
    in->qhi = opts->qhi;
    in->source_type = opts->source_type;
    in->raw_bytes = (uint64_t)cdvr_volume_voxels(u8) * u8->timesteps;
}

cdvr_status cdvr_store_encode(const cdvr_volume *u8, const cdvr_encode_opts *opts,
                              const char *path, cdvr_error *err)
{
    cdvr_store *st = NULL;
    cdvr_status s = check_opts(u8, opts, path, err);
    if (s == CDVR_OK)
        s = plan_store(u8, opts, path, &st, err);
    if (s != CDVR_OK)
        return s;
    fill_header(st, u8, opts);
    cdvr_atomic_file af;
    s = cdvr_atomic_open(&af, path, err);
    if (s != CDVR_OK) {
        cdvr_store_close(st);
        return s;
    }
    const char *tmp = af.tmp_path;
    st->fd = fileno(af.f); /* written with pwrite only: the FILE buffers nothing */
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    s = meta ? write_chunks(u8, opts, st, meta + 4, tmp, err)
             : cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: index too large", path);
    if (s == CDVR_OK)
        s = write_meta(st, tmp, err);
    st->fd = -1; /* closed by the commit */
    cdvr_error commit_err;
    cdvr_status c = cdvr_atomic_commit(&af, s != CDVR_OK, &commit_err);
    if (s == CDVR_OK && c != CDVR_OK) {
        s = c;
        if (err)
            *err = commit_err;
    }
    cdvr_store_close(st);
    return s;
}
