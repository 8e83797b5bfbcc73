/* core/store/store.c - the .cdv store: format, reader, and the metadata writer used by encode.c.
 *
 * Layout, format version 1. All integers little endian, fixed width; f64 = IEEE-754 binary64
 * little endian. Every field is written and read one by one (no struct dumps).
 *
 *  HEADER (152 bytes, at offset 0)
 *     0  u8[8] magic "CDVR\0STR"
 *     8  u32   format version (1)
 *    12  u32   header bytes (152)
 *    16  u64   meta bytes M = 152 + 96 * nvariants + 64 * total chunks
 *    24  u64[3] dims x, y, z (each >= 1)
 *    48  u64   timesteps (>= 1)
 *    56  f64[3] spacing
 *    80  f64[3] origin
 *   104  f64   quantisation window lo
 *   112  f64   quantisation window hi (>= lo)
 *   120  u32   source type (cdvr_type before quantisation)
 *   124  u32   nvariants (1 .. 256)
 *   128  u64   total chunks (all variants)
 *   136  u64   data offset (M + 4: first byte after the metadata CRC)
 *   144  u64   file bytes (size of the whole file)
 *  VARIANT TABLE (nvariants records of 96 bytes, from offset 152)
 *     0  u8[32] name, NUL padded (non-empty, NUL-terminated, unique in the store)
 *    32  u32   codec id (0 raw, 1 pvtc)
 *    36  u32   encoder (0 lsq, 1 bbox)
 *    40  u32   stage 2 (0 none, 1 lzo)
 *    44  u32   reserved, 0
 *    48  u32   S, u32 T, u32 pack (default parameters; raw: 0 0 0)
 *    60  u32   reserved, 0
 *    64  u64   nchunks (>= 1)
 *    72  f64   lzo_min_saving used at encode time
 *    80  f64   psnr (volume PSNR at encode time, peak 255; +Inf if lossless)
 *    88  f64   maxerr
 *  CHUNK INDEX (64 bytes per chunk; variant 1's chunks, then variant 2's, ...)
 *     0  u64   t0 (first timestep, from 0)
 *     8  u64   count (timesteps covered; pack time: 1..T, else 1)
 *    16  u32   S, u32 T, u32 pack (this chunk's parameters; raw: 0 0 0)
 *    28  u32   stage-2 flag (1: stored bytes are LZO1X of the payload)
 *    32  u64   offset of the stored bytes
 *    40  u64   stored bytes
 *    48  u64   payload bytes (= PVTC geometry chunk_bytes, or X*Y*Z for raw)
 *    56  u32   CRC-32C of the stored bytes
 *    60  u32   reserved, 0
 *  u32 CRC-32C of bytes [0, M)  (at offset M)
 *  CHUNK DATA from the data offset, in index order, non-overlapping, up to file bytes.
 *
 * The chunks of a variant cover timesteps 0 .. timesteps-1 in order without gaps.
 */
#include "store_format.h"

#include "codec/stage2/stage2.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- little-endian field codec ---------------------------------------------------------- */

typedef struct wcursor {
    uint8_t *p;
} wcursor;

static void put_u32(wcursor *w, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        *w->p++ = (uint8_t)(v >> (8 * i));
}

static void put_u64(wcursor *w, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        *w->p++ = (uint8_t)(v >> (8 * i));
}

static void put_f64(wcursor *w, double d)
{
    uint64_t v;
    memcpy(&v, &d, sizeof v);
    put_u64(w, v);
}

static void put_bytes(wcursor *w, const void *src, size_t n)
{
    memcpy(w->p, src, n);
    w->p += n;
}

/* Reads never pass `end`: callers size the buffer before parsing, and get_* return 0 past it. */
typedef struct rcursor {
    const uint8_t *p, *end;
} rcursor;

static uint64_t get_le(rcursor *r, int nbytes)
{
    if (r->end - r->p < nbytes) {
        r->p = r->end;
        return 0;
    }
    uint64_t v = 0;
    for (int i = 0; i < nbytes; i++)
        v |= (uint64_t)r->p[i] << (8 * i);
    r->p += nbytes;
    return v;
}

static uint32_t get_u32(rcursor *r) { return (uint32_t)get_le(r, 4); }
static uint64_t get_u64(rcursor *r) { return get_le(r, 8); }

static double get_f64(rcursor *r)
{
    uint64_t v = get_u64(r);
    double d;
    memcpy(&d, &v, sizeof d);
    return d;
}

/* ---- shared helpers --------------------------------------------------------------------- */

uint64_t cdvr_store_meta_bytes(size_t nvariants, size_t nchunks)
{
    size_t v, c, sum;
    if (!cdvr_size_mul(nvariants, CDVR_STORE_VARIANT_BYTES, &v) ||
        !cdvr_size_mul(nchunks, CDVR_STORE_CHUNK_BYTES, &c) || !cdvr_size_add(v, c, &sum) ||
        !cdvr_size_add(sum, CDVR_STORE_HEADER_BYTES, &sum) || sum > SIZE_MAX - 4)
        return 0;
    return (uint64_t)sum;
}

cdvr_status cdvr_store_alloc(size_t nvariants, size_t nchunks, const char *path,
                             cdvr_store **out, cdvr_error *err)
{
    cdvr_store *st = calloc(1, sizeof *st);
    if (st) {
        st->fd = -1;
        st->path = strdup(path);
        st->variants = calloc(nvariants ? nvariants : 1, sizeof *st->variants);
        st->lzo_min_saving = calloc(nvariants ? nvariants : 1, sizeof *st->lzo_min_saving);
        st->chunk_first = calloc(nvariants ? nvariants : 1, sizeof *st->chunk_first);
        st->chunks = calloc(nchunks ? nchunks : 1, sizeof *st->chunks);
    }
    if (!st || !st->path || !st->variants || !st->lzo_min_saving || !st->chunk_first ||
        !st->chunks) {
        cdvr_store_close(st);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for %zu variants, %zu chunks",
                              path, nvariants, nchunks);
    }
    st->info.nvariants = nvariants;
    st->nchunks_total = nchunks;
    *out = st;
    return CDVR_OK;
}

void cdvr_store_default_name(cdvr_codec_id codec, const cdvr_pvtc_params *p,
                             char name[CDVR_NAME_MAX])
{
    if (codec == CDVR_CODEC_PVTC)
        snprintf(name, CDVR_NAME_MAX, "S%dT%d%s", p->S, p->T, p->pack == CDVR_PACK_SPACE ? "s" : "");
    else
        snprintf(name, CDVR_NAME_MAX, "%s", codec == CDVR_CODEC_RAW ? "raw" : "plugin");
}

cdvr_status cdvr_store_payload_bytes(cdvr_codec_id codec, const cdvr_pvtc_params *params,
                                     const size_t dims[3], size_t *bytes, cdvr_error *err)
{
    if (codec == CDVR_CODEC_RAW) {
        size_t xy;
        if (!cdvr_size_mul(dims[0], dims[1], &xy) || !cdvr_size_mul(xy, dims[2], bytes))
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "dims overflow size_t");
        return CDVR_OK;
    }
    if (codec != CDVR_CODEC_PVTC)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "codec id %d is not supported",
                              (int)codec);
    if (params->pack != CDVR_PACK_TIME && params->pack != CDVR_PACK_SPACE)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pack %d is not time (0) or space (1)",
                              (int)params->pack);
    cdvr_pvtc_geometry geom;
    cdvr_status s = cdvr_pvtc_geometry_get(params, dims, &geom, err);
    if (s == CDVR_OK)
        *bytes = geom.chunk_bytes;
    return s;
}

cdvr_status cdvr_store_decode_payload(cdvr_codec_id codec, const cdvr_pvtc_params *params,
                                      const size_t dims[3], const uint8_t *payload,
                                      size_t payload_bytes, uint8_t *const *frames,
                                      size_t count, cdvr_error *err)
{
    if (codec == CDVR_CODEC_PVTC)
        return cdvr_pvtc_decode_chunk(params, dims, payload, payload_bytes, frames, count, err);
    size_t need;
    cdvr_status s = cdvr_store_payload_bytes(codec, params, dims, &need, err);
    if (s != CDVR_OK)
        return s;
    if (count != 1 || need != payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "raw chunk of %zu bytes, %zu frames: "
                              "expected %zu bytes, 1 frame", payload_bytes, count, need);
    memcpy(frames[0], payload, need);
    return CDVR_OK;
}

/* ---- metadata writer -------------------------------------------------------------------- */

static void put_name(wcursor *w, const char *name)
{
    char padded[CDVR_NAME_MAX] = {0};
    size_t n = strnlen(name, CDVR_NAME_MAX - 1);
    memcpy(padded, name, n);
    put_bytes(w, padded, sizeof padded);
}

static void put_params(wcursor *w, cdvr_codec_id codec, const cdvr_pvtc_params *p)
{
    int pvtc = codec == CDVR_CODEC_PVTC;
    put_u32(w, pvtc ? (uint32_t)p->S : 0);
    put_u32(w, pvtc ? (uint32_t)p->T : 0);
    put_u32(w, pvtc ? (uint32_t)p->pack : 0);
}

static void put_header(wcursor *w, const cdvr_store *st, uint64_t meta)
{
    const cdvr_store_info *in = &st->info;
    put_bytes(w, CDVR_STORE_MAGIC, 8);
    put_u32(w, CDVR_STORE_VERSION);
    put_u32(w, CDVR_STORE_HEADER_BYTES);
    put_u64(w, meta);
    for (int i = 0; i < 3; i++)
        put_u64(w, in->dims[i]);
    put_u64(w, in->timesteps);
    for (int i = 0; i < 3; i++)
        put_f64(w, in->spacing[i]);
    for (int i = 0; i < 3; i++)
        put_f64(w, in->origin[i]);
    put_f64(w, in->qlo);
    put_f64(w, in->qhi);
    put_u32(w, (uint32_t)in->source_type);
    put_u32(w, (uint32_t)in->nvariants);
    put_u64(w, st->nchunks_total);
    put_u64(w, meta + 4);
    put_u64(w, in->file_bytes);
}

static void put_variant(wcursor *w, const cdvr_variant_info *v, double lzo_min_saving)
{
    put_name(w, v->name);
    put_u32(w, (uint32_t)v->codec);
    put_u32(w, (uint32_t)v->encoder);
    put_u32(w, (uint32_t)v->stage2);
    put_u32(w, 0);
    put_params(w, v->codec, &v->pvtc);
    put_u32(w, 0);
    put_u64(w, v->nchunks);
    put_f64(w, lzo_min_saving);
    put_f64(w, v->psnr);
    put_f64(w, v->maxerr);
}

static void put_chunk(wcursor *w, cdvr_codec_id codec, const cdvr_chunk_info *c)
{
    put_u64(w, c->t0);
    put_u64(w, c->count);
    put_params(w, codec, &c->pvtc);
    put_u32(w, c->stage2 ? 1u : 0u);
    put_u64(w, c->offset);
    put_u64(w, c->stored_bytes);
    put_u64(w, c->payload_bytes);
    put_u32(w, c->crc32c);
    put_u32(w, 0);
}

void cdvr_store_serialize_meta(const cdvr_store *st, uint8_t *buf)
{
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    wcursor w = {buf};
    put_header(&w, st, meta);
    for (size_t v = 0; v < st->info.nvariants; v++)
        put_variant(&w, &st->variants[v], st->lzo_min_saving[v]);
    for (size_t v = 0; v < st->info.nvariants; v++)
        for (size_t c = 0; c < st->variants[v].nchunks; c++)
            put_chunk(&w, st->variants[v].codec, &st->chunks[st->chunk_first[v] + c]);
    wcursor crc = {buf + meta};
    put_u32(&crc, cdvr_crc32c(0, buf, (size_t)meta));
}

/* ---- reader: open and validate ---------------------------------------------------------- */

static cdvr_status read_at(int fd, uint8_t *buf, size_t n, uint64_t offset, size_t *got)
{
    size_t done = 0;
    while (done < n) {
        ssize_t r = pread(fd, buf + done, n - done, (off_t)(offset + done));
        if (r < 0 && errno == EINTR)
            continue;
        if (r < 0)
            return CDVR_ERR_IO;
        if (r == 0)
            break;
        done += (size_t)r;
    }
    *got = done;
    return CDVR_OK;
}

typedef struct header_fields {
    uint64_t meta, dims[3], timesteps, nchunks, data_offset, file_bytes;
    uint32_t version, header_bytes, source_type, nvariants;
    double spacing[3], origin[3], qlo, qhi;
} header_fields;

static void parse_header(const uint8_t *buf, header_fields *h)
{
    rcursor r = {buf + 8, buf + CDVR_STORE_HEADER_BYTES};
    h->version = get_u32(&r);
    h->header_bytes = get_u32(&r);
    h->meta = get_u64(&r);
    for (int i = 0; i < 3; i++)
        h->dims[i] = get_u64(&r);
    h->timesteps = get_u64(&r);
    for (int i = 0; i < 3; i++)
        h->spacing[i] = get_f64(&r);
    for (int i = 0; i < 3; i++)
        h->origin[i] = get_f64(&r);
    h->qlo = get_f64(&r);
    h->qhi = get_f64(&r);
    h->source_type = get_u32(&r);
    h->nvariants = get_u32(&r);
    h->nchunks = get_u64(&r);
    h->data_offset = get_u64(&r);
    h->file_bytes = get_u64(&r);
}

static cdvr_status check_header_sizes(const char *path, const header_fields *h,
                                      uint64_t file_size, cdvr_error *err)
{
    if (h->version != CDVR_STORE_VERSION)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: store format version %u, this cdvr "
                              "reads version %u", path, h->version, CDVR_STORE_VERSION);
    if (h->header_bytes != CDVR_STORE_HEADER_BYTES)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: header size %u, expected %u", path,
                              h->header_bytes, CDVR_STORE_HEADER_BYTES);
    if (h->nvariants < 1 || h->nvariants > CDVR_STORE_MAX_VARIANTS)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: %u variants (must be 1..%u)", path,
                              h->nvariants, CDVR_STORE_MAX_VARIANTS);
    uint64_t meta = h->nchunks > file_size ? 0 : cdvr_store_meta_bytes(h->nvariants,
                                                                       (size_t)h->nchunks);
    if (meta == 0 || meta != h->meta || h->data_offset != meta + 4)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: header sizes disagree (%u variants, "
                              "%llu chunks, meta %llu bytes, data at %llu)", path, h->nvariants,
                              (unsigned long long)h->nchunks, (unsigned long long)h->meta,
                              (unsigned long long)h->data_offset);
    if (h->file_bytes != file_size)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: file has %llu bytes, header says %llu "
                              "(truncated or appended?)", path, (unsigned long long)file_size,
                              (unsigned long long)h->file_bytes);
    if (h->data_offset > file_size)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: metadata (%llu bytes) runs past the "
                              "end of the file (%llu bytes)", path,
                              (unsigned long long)h->data_offset, (unsigned long long)file_size);
    return CDVR_OK;
}

static int finite3(const double *a)
{
    return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
}

static cdvr_status check_header_values(const char *path, const header_fields *h,
                                       cdvr_store_info *info, cdvr_error *err)
{
    size_t voxels = 1, raw;
    for (int i = 0; i < 3; i++)
        if (h->dims[i] == 0 || h->dims[i] > SIZE_MAX ||
            !cdvr_size_mul(voxels, (size_t)h->dims[i], &voxels))
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: bad dims %llux%llux%llu", path,
                                  (unsigned long long)h->dims[0], (unsigned long long)h->dims[1],
                                  (unsigned long long)h->dims[2]);
    if (h->timesteps == 0 || h->timesteps > SIZE_MAX ||
        !cdvr_size_mul(voxels, (size_t)h->timesteps, &raw))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: bad timestep count %llu", path,
                              (unsigned long long)h->timesteps);
    if (!finite3(h->spacing) || !finite3(h->origin) || !isfinite(h->qlo) || !isfinite(h->qhi) ||
        h->qhi < h->qlo)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: spacing, origin or window not finite "
                              "(or window hi < lo)", path);
    if (h->source_type > CDVR_TYPE_F32)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: unknown source type %u", path,
                              h->source_type);
    for (int i = 0; i < 3; i++) {
        info->dims[i] = (size_t)h->dims[i];
        info->spacing[i] = h->spacing[i];
        info->origin[i] = h->origin[i];
    }
    info->timesteps = (size_t)h->timesteps;
    info->qlo = h->qlo;
    info->qhi = h->qhi;
    info->source_type = (cdvr_type)h->source_type;
    info->nvariants = h->nvariants;
    info->raw_bytes = (uint64_t)raw;
    info->file_bytes = h->file_bytes;
    return CDVR_OK;
}

static cdvr_status parse_variant(const cdvr_store *st, rcursor *r, size_t v, uint64_t *nchunks,
                                 cdvr_error *err)
{
    cdvr_variant_info *vi = &st->variants[v];
    memcpy(vi->name, r->p, CDVR_NAME_MAX);
    r->p += CDVR_NAME_MAX;
    uint32_t codec = get_u32(r), encoder = get_u32(r), stage2 = get_u32(r), res1 = get_u32(r);
    uint32_t S = get_u32(r), T = get_u32(r), pack = get_u32(r), res2 = get_u32(r);
    *nchunks = get_u64(r);
    st->lzo_min_saving[v] = get_f64(r);
    vi->psnr = get_f64(r);
    vi->maxerr = get_f64(r);
    if (memchr(vi->name, 0, CDVR_NAME_MAX) == NULL || vi->name[0] == '\0')
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %zu: bad name", st->path, v + 1);
    if ((codec != CDVR_CODEC_RAW && codec != CDVR_CODEC_PVTC) || encoder > CDVR_ENCODER_BBOX ||
        stage2 > CDVR_STAGE2_LZO || res1 || res2 || pack > CDVR_PACK_SPACE || S > 8 || T > 8)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: bad codec %u, encoder %u, "
                              "stage2 %u or parameters S%u T%u pack %u", st->path, vi->name,
                              codec, encoder, stage2, S, T, pack);
    if (*nchunks == 0 || isnan(vi->psnr) || vi->psnr < 0 || !(vi->maxerr >= 0 && vi->maxerr <= 255))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: bad chunk count, psnr or "
                              "maxerr", st->path, vi->name);
    for (size_t i = 0; i < v; i++)
        if (strcmp(st->variants[i].name, vi->name) == 0)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant name %s appears twice",
                                  st->path, vi->name);
    vi->codec = (cdvr_codec_id)codec;
    snprintf(vi->codec_name, sizeof vi->codec_name, "%s", codec == CDVR_CODEC_RAW ? "raw" : "pvtc");
    vi->encoder = (cdvr_pvtc_encoder)encoder;
    vi->stage2 = (cdvr_stage2)stage2;
    vi->pvtc = (cdvr_pvtc_params){(int)S, (int)T, (cdvr_pack)pack};
    vi->nchunks = (size_t)*nchunks;
    return CDVR_OK;
}

/* Checks one chunk record against the variant, the time coverage and the file layout. */
static cdvr_status check_chunk(const cdvr_store *st, size_t v, size_t c, size_t next_t0,
                               uint64_t data_start, cdvr_error *err)
{
    const cdvr_variant_info *vi = &st->variants[v];
    const cdvr_chunk_info *ci = &st->chunks[st->chunk_first[v] + c];
    char pre[CDVR_ERRMSG_MAX / 2];
    snprintf(pre, sizeof pre, "%s: variant %s chunk %zu", st->path, vi->name, c + 1);
    if (ci->t0 != next_t0 || ci->count == 0 || ci->count > st->info.timesteps - ci->t0)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: covers timesteps %zu+%zu, expected "
                              "to start at %zu of %zu", pre, ci->t0 + 1, ci->count, next_t0 + 1,
                              st->info.timesteps);
    size_t payload;
    cdvr_error perr;
    if (cdvr_store_payload_bytes(vi->codec, &ci->pvtc, st->info.dims, &payload, &perr) != CDVR_OK)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: %s", pre, perr.msg);
    size_t max_count = vi->codec == CDVR_CODEC_PVTC && ci->pvtc.pack == CDVR_PACK_TIME
                           ? (size_t)ci->pvtc.T : 1;
    if (ci->count > max_count)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: %zu timesteps, at most %zu fit",
                              pre, ci->count, max_count);
    if (ci->payload_bytes != payload)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: payload %llu bytes, parameters give "
                              "%zu", pre, (unsigned long long)ci->payload_bytes, payload);
    if (ci->stage2 ? (vi->stage2 != CDVR_STAGE2_LZO || ci->stored_bytes >= ci->payload_bytes ||
                      ci->stored_bytes == 0)
                   : ci->stored_bytes != ci->payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: stored %llu bytes with stage-2 flag "
                              "%d does not fit payload %llu", pre,
                              (unsigned long long)ci->stored_bytes, ci->stage2,
                              (unsigned long long)ci->payload_bytes);
    if (ci->offset < data_start || ci->offset > st->info.file_bytes ||
        ci->stored_bytes > st->info.file_bytes - ci->offset)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: bytes %llu..%llu overlap another chunk "
                              "or lie outside the data (%llu..%llu)", pre,
                              (unsigned long long)ci->offset,
                              (unsigned long long)(ci->offset + ci->stored_bytes),
                              (unsigned long long)data_start,
                              (unsigned long long)st->info.file_bytes);
    return CDVR_OK;
}

static void parse_chunk(rcursor *r, cdvr_chunk_info *ci, uint32_t *reserved)
{
    ci->t0 = (size_t)get_u64(r);
    ci->count = (size_t)get_u64(r);
    uint32_t S = get_u32(r), T = get_u32(r), pack = get_u32(r), flag = get_u32(r);
    ci->pvtc = (cdvr_pvtc_params){(int)(S & 0xff), (int)(T & 0xff), (cdvr_pack)(pack & 1)};
    *reserved = (S | T) >> 8 | (pack >> 1) | (flag >> 1);
    ci->stage2 = (int)(flag & 1);
    ci->offset = get_u64(r);
    ci->stored_bytes = get_u64(r);
    ci->payload_bytes = get_u64(r);
    ci->crc32c = get_u32(r);
    *reserved |= get_u32(r);
}

static cdvr_status parse_tables(cdvr_store *st, const uint8_t *meta, size_t meta_bytes,
                                cdvr_error *err)
{
    rcursor r = {meta + CDVR_STORE_HEADER_BYTES, meta + meta_bytes};
    size_t first = 0;
    for (size_t v = 0; v < st->info.nvariants; v++) {
        uint64_t n;
        cdvr_status s = parse_variant(st, &r, v, &n, err);
        if (s != CDVR_OK)
            return s;
        if (n > st->nchunks_total - first)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: %llu chunks, more than "
                                  "the header's total", st->path, st->variants[v].name,
                                  (unsigned long long)n);
        st->chunk_first[v] = first;
        first += (size_t)n;
    }
    if (first != st->nchunks_total)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variants hold %zu chunks, header says "
                              "%zu", st->path, first, st->nchunks_total);
    uint64_t data_end = meta_bytes + 4;
    for (size_t v = 0; v < st->info.nvariants; v++) {
        cdvr_variant_info *vi = &st->variants[v];
        size_t next_t0 = 0;
        for (size_t c = 0; c < vi->nchunks; c++) {
            cdvr_chunk_info *ci = &st->chunks[st->chunk_first[v] + c];
            uint32_t reserved;
            parse_chunk(&r, ci, &reserved);
            if (reserved)
                return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s chunk %zu: reserved "
                                      "bits set", st->path, vi->name, c + 1);
            cdvr_status s = check_chunk(st, v, c, next_t0, data_end, err);
            if (s != CDVR_OK)
                return s;
            next_t0 = ci->t0 + ci->count;
            data_end = ci->offset + ci->stored_bytes;
            vi->bytes += ci->stored_bytes;
            vi->payload_bytes += ci->payload_bytes;
        }
        if (next_t0 != st->info.timesteps)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s covers %zu of %zu "
                                  "timesteps", st->path, vi->name, next_t0, st->info.timesteps);
        if (vi->codec == CDVR_CODEC_PVTC)
            vi->pvtc = st->chunks[st->chunk_first[v]].pvtc;
    }
    return CDVR_OK;
}

static cdvr_status open_header(cdvr_store *st, uint64_t file_size, header_fields *h,
                               cdvr_error *err)
{
    uint8_t hdr[CDVR_STORE_HEADER_BYTES];
    size_t got = 0;
    if (read_at(st->fd, hdr, sizeof hdr, 0, &got) != CDVR_OK)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot read: %s", st->path, strerror(errno));
    if (got < 8 || memcmp(hdr, CDVR_STORE_MAGIC, 8) != 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not a cdvr store (bad magic)", st->path);
    if (got < sizeof hdr)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: truncated header (%zu of %u bytes)",
                              st->path, got, CDVR_STORE_HEADER_BYTES);
    parse_header(hdr, h);
    return check_header_sizes(st->path, h, file_size, err);
}

static cdvr_status open_tables(cdvr_store *st, const header_fields *h, cdvr_error *err)
{
    size_t meta = (size_t)h->meta;
    uint8_t *buf = malloc(meta + 4);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for %zu bytes of tables",
                              st->path, meta + 4);
    size_t got = 0;
    cdvr_status s = read_at(st->fd, buf, meta + 4, 0, &got);
    if (s != CDVR_OK || got != meta + 4) {
        free(buf);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot read the tables", st->path);
    }
    rcursor r = {buf + meta, buf + meta + 4};
    uint32_t stored = get_u32(&r), computed = cdvr_crc32c(0, buf, meta);
    if (stored != computed)
        s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: header/index CRC-32C mismatch (stored "
                           "0x%08x, computed 0x%08x)", st->path, stored, computed);
    else if ((s = check_header_values(st->path, h, &st->info, err)) == CDVR_OK)
        s = parse_tables(st, buf, meta, err);
    free(buf);
    return s;
}

cdvr_status cdvr_store_open(const char *path, cdvr_store **out, cdvr_error *err)
{
    *out = NULL;
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat sb;
    if (fstat(fd, &sb) != 0 || !S_ISREG(sb.st_mode)) {
        close(fd);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: not a regular file", path);
    }
    header_fields h = {0};
    cdvr_store probe = {.path = (char *)path, .fd = fd};
    cdvr_status s = open_header(&probe, (uint64_t)sb.st_size, &h, err);
    cdvr_store *st = NULL;
    if (s == CDVR_OK)
        s = cdvr_store_alloc(h.nvariants, (size_t)h.nchunks, path, &st, err);
    if (s != CDVR_OK) {
        close(fd);
        return s;
    }
    st->fd = fd;
    s = open_tables(st, &h, err);
    if (s != CDVR_OK) {
        cdvr_store_close(st);
        return s;
    }
    *out = st;
    return CDVR_OK;
}

void cdvr_store_close(cdvr_store *st)
{
    if (!st)
        return;
    if (st->fd >= 0)
        close(st->fd);
    free(st->path);
    free(st->variants);
    free(st->lzo_min_saving);
    free(st->chunk_first);
    free(st->chunks);
    free(st);
}

/* ---- accessors -------------------------------------------------------------------------- */

const char *cdvr_store_path(const cdvr_store *st) { return st->path; }

const cdvr_store_info *cdvr_store_get_info(const cdvr_store *st) { return &st->info; }

const cdvr_variant_info *cdvr_store_variant(const cdvr_store *st, size_t v)
{
    return v < st->info.nvariants ? &st->variants[v] : NULL;
}

int cdvr_store_find_variant(const cdvr_store *st, const char *name)
{
    for (size_t v = 0; v < st->info.nvariants; v++)
        if (strcmp(st->variants[v].name, name) == 0)
            return (int)v;
    return -1;
}

const cdvr_chunk_info *cdvr_store_chunk(const cdvr_store *st, size_t v, size_t c)
{
    if (v >= st->info.nvariants || c >= st->variants[v].nchunks)
        return NULL;
    return &st->chunks[st->chunk_first[v] + c];
}

size_t cdvr_store_chunk_for_time(const cdvr_store *st, size_t v, size_t t)
{
    if (v >= st->info.nvariants || t >= st->info.timesteps)
        return (size_t)-1;
    const cdvr_chunk_info *ch = &st->chunks[st->chunk_first[v]];
    size_t lo = 0, hi = st->variants[v].nchunks; /* chunks are sorted by t0 and contiguous */
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (ch[mid].t0 <= t)
            lo = mid;
        else
            hi = mid;
    }
    return lo;
}

/* ---- reading chunks --------------------------------------------------------------------- */

static cdvr_status chunk_lookup(const cdvr_store *st, size_t v, size_t c,
                                const cdvr_chunk_info **ci, cdvr_error *err)
{
    *ci = cdvr_store_chunk(st, v, c);
    if (!*ci)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no chunk %zu in variant %zu", st->path,
                              c + 1, v + 1);
    return CDVR_OK;
}

cdvr_status cdvr_store_read_chunk(const cdvr_store *st, size_t v, size_t c, uint8_t *buf,
                                  cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    const char *name = st->variants[v].name;
    size_t got = 0;
    if (read_at(st->fd, buf, (size_t)ci->stored_bytes, ci->offset, &got) != CDVR_OK)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: variant %s chunk %zu: read failed: %s",
                              st->path, name, c + 1, strerror(errno));
    if (got != ci->stored_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s chunk %zu: truncated "
                              "(%zu of %llu bytes)", st->path, name, c + 1, got,
                              (unsigned long long)ci->stored_bytes);
    uint32_t crc = cdvr_crc32c(0, buf, got);
    if (crc != ci->crc32c)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s chunk %zu: CRC-32C mismatch "
                              "(index 0x%08x, data 0x%08x)", st->path, name, c + 1, ci->crc32c,
                              crc);
    return CDVR_OK;
}

void cdvr_store_drop_cache(const cdvr_store *st, size_t v, size_t c)
{
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    if (ci)
        (void)posix_fadvise(st->fd, (off_t)ci->offset, (off_t)ci->stored_bytes,
                            POSIX_FADV_DONTNEED);
}

cdvr_status cdvr_store_unpack_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *stored, uint8_t *out, cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    if (!ci->stage2) {
        memcpy(out, stored, (size_t)ci->payload_bytes);
        return CDVR_OK;
    }
    cdvr_error lerr;
    if (cdvr_lzo_decompress(stored, (size_t)ci->stored_bytes, out, (size_t)ci->payload_bytes,
                            &lerr) != CDVR_OK)
        return cdvr_error_set(err, lerr.status, "%s: variant %s chunk %zu: %s", st->path,
                              st->variants[v].name, c + 1, lerr.msg);
    return CDVR_OK;
}

cdvr_status cdvr_store_decode_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *payload, uint8_t *const *frames,
                                    cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    cdvr_error derr;
    if (cdvr_store_decode_payload(st->variants[v].codec, &ci->pvtc, st->info.dims, payload,
                                  (size_t)ci->payload_bytes, frames, ci->count, &derr) != CDVR_OK)
        return cdvr_error_set(err, derr.status, "%s: variant %s chunk %zu: %s", st->path,
                              st->variants[v].name, c + 1, derr.msg);
    return CDVR_OK;
}

/* Reads and unpacks chunk c; *payload is malloc'd (payload_bytes). */
cdvr_status cdvr_store_load_payload(const cdvr_store *st, size_t v, size_t c, uint8_t **payload,
                                    cdvr_error *err)
{
    *payload = NULL;
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    if (!ci)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no chunk %zu in variant %zu", st->path, c + 1, v + 1);
    if (ci->stored_bytes > SIZE_MAX || ci->payload_bytes > SIZE_MAX)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: chunk %zu too large", st->path, c + 1);
    uint8_t *stored = malloc(ci->stored_bytes ? (size_t)ci->stored_bytes : 1);
    *payload = malloc(ci->payload_bytes ? (size_t)ci->payload_bytes : 1);
    cdvr_status s = (!stored || !*payload)
                        ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for chunk %zu",
                                         st->path, c + 1)
                        : cdvr_store_read_chunk(st, v, c, stored, err);
    if (s == CDVR_OK)
        s = cdvr_store_unpack_chunk(st, v, c, stored, *payload, err);
    free(stored);
    if (s != CDVR_OK) {
        free(*payload);
        *payload = NULL;
    }
    return s;
}

cdvr_status cdvr_store_decode(const cdvr_store *st, size_t v, size_t t, cdvr_volume **out,
                              cdvr_error *err)
{
    *out = NULL;
    size_t c = cdvr_store_chunk_for_time(st, v, t);
    if (c == (size_t)-1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no timestep %zu in variant %zu (%zu "
                              "timesteps, %zu variants)", st->path, t + 1, v + 1,
                              st->info.timesteps, st->info.nvariants);
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    size_t k = t - ci->t0, voxels = (size_t)(st->info.raw_bytes / st->info.timesteps), scratch_n;
    uint8_t *payload = NULL, *scratch = NULL;
    uint8_t *frames[8];
    cdvr_volume *vol = NULL;
    cdvr_status s = cdvr_store_load_payload(st, v, c, &payload, err);
    if (s == CDVR_OK)
        s = cdvr_volume_create(st->info.dims, 1, CDVR_TYPE_U8, &vol, err);
    if (s == CDVR_OK && (!cdvr_size_mul(voxels, ci->count, &scratch_n) ||
                         !(scratch = malloc(scratch_n))))
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory to decode", st->path);
    if (s == CDVR_OK) {
        for (size_t i = 0; i < ci->count; i++)
            frames[i] = i == k ? (uint8_t *)vol->data : scratch + i * voxels;
        s = cdvr_store_decode_chunk(st, v, c, payload, frames, err);
    }
    free(payload);
    free(scratch);
    if (s != CDVR_OK) {
        cdvr_volume_free(vol);
        return s;
    }
    for (int i = 0; i < 3; i++) {
        vol->spacing[i] = st->info.spacing[i];
        vol->origin[i] = st->info.origin[i];
    }
    *out = vol;
    return CDVR_OK;
}
