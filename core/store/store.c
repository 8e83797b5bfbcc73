/* core/store/store.c - the .cdv store: format, reader, and the metadata writer used by encode.c.
 *
 * Layout, format version 2 (written; version 1 is still read, see parse_v1 below). All
 * integers little endian, fixed width; f64 = IEEE-754 binary64 little endian. Every field is
 * written and read one by one (no struct dumps).
 *
 *  HEADER (256 bytes, at offset 0)
 *     0  u8[8]  magic "CDVR\0STR"
 *     8  u32    format version (2)
 *    12  u32    header bytes (256)
 *    16  u64    meta bytes M = 256 + 160 * nvariants + 128 * total chunks
 *    24  u64[3] dims x, y, z (each >= 1)
 *    48  u64    timesteps (>= 1)
 *    56  f64[3] spacing (> 0)
 *    80  f64[3] origin
 *   104  f64[9] direction, row-major (column c = world direction of index axis c)
 *   176  f64    value window lo (u8 0 stands for lo)
 *   184  f64    value window hi (>= lo; u8 255 stands for hi)
 *   192  u32    source type (cdvr_type before quantisation)
 *   196  u32    nvariants (1 .. 256)
 *   200  u64    total chunks (all variants)
 *   208  u64    data offset (M + 4: first byte after the metadata CRC)
 *   216  u64    file bytes (size of the whole file)
 *   224  u32[3] brick grid bx, by, bz (each >= 1, product <= 4096; cdvr_brick_box)
 *   236  u32    levels: 0 (stores without coarser levels, all stores before them) or
 *               2..CDVR_STORE_MAX_LEVELS (a multi-resolution store, core/store/levels.c)
 *   240  u64    offset of the level directory (0 when levels is 0; levels.c)
 *   248  u32[2] reserved, 0
 *  VARIANT TABLE (nvariants records of 160 bytes, from offset 256)
 *     0  u8[32] name, NUL padded (non-empty, NUL-terminated, unique in the store)
 *    32  u8[16] codec name, NUL padded ([a-z0-9_], 1..15 bytes)
 *    48  u32    codec id
 *    52  u32    stage 2 (0 none, 1 lzo, 2 lz4, 3 zstd, 4 auto: per chunk, see store.h)
 *    56  u64    nchunks (>= 1, a multiple of the bricks per timestep)
 *    64  f64    lzo_min_saving used at encode time
 *    72  f64    psnr (volume PSNR at encode time, peak 255; +Inf if lossless)
 *    80  f64    maxerr
 *    88  u8[48] codec parameter blob given at encode time (cdvr/codec.h)
 *   136  f64    stage-2 read rate in MB/s the auto model used (>= 0; 0: not recorded, as
 *               in stores written before stage 2 beyond LZO, whose bytes 136..159 are 0)
 *   144  u32    stage-2 segment bytes used at encode time (0: not recorded, else
 *               CDVR_STAGE2_SEGMENT_MIN..CDVR_STAGE2_SEGMENT_MAX)
 *   148  u64    offset of the variant's shared blob (cdvr/codec.h: data every chunk of the
 *               variant needs, e.g. hvqc's codebooks), 156: u32 its bytes; both 0 when
 *               there is none (as in every store written before it). The blob lies in the
 *               data area like a chunk (no overlap); its integrity: the chunks' parameters
 *               name it by content id (cdvr_shared_id), so a changed blob decodes nothing.
 *  CHUNK INDEX (128 bytes per chunk; variant 1's chunks, then variant 2's, ...; within a
 *  variant by time group, and within a group by brick)
 *     0  u64    t0 (first timestep, from 0)
 *     8  u64    count (timesteps covered, 1 .. the codec's timesteps per chunk)
 *    16  u32    brick index (from 0, x fastest)
 *    20  u32    codec id
 *    24  u8[48] codec parameter blob of this chunk
 *    72  u32    stage 2 of the chunk: bits 0..7 the codec (0 none: stored bytes = payload;
 *               1 LZO1X-1, 2 LZ4, 3 zstd; never 4: auto records its choice), bit 8 segmented
 *               (the stored bytes are a segment table and independently packed segments,
 *               core/codec/stage2/stage2.h: u32 segment bytes, u32 n, u32[n] stored bytes of
 *               each, the segments; required for lz4 and zstd, optional for lzo, never with
 *               none), other bits 0. Stores before this field grew hold 0 or 1 (LZO, one
 *               block), which read as before.
 *    76  u32    CRC-32C of the stored bytes
 *    80  u64    offset of the stored bytes
 *    88  u64    stored bytes
 *    96  u64    payload bytes (the codec's fixed chunk size, or at most its bound)
 *   104  u8     min, u8 max of the decoded voxels of the chunk's timesteps
 *   106  u8     range table flags: bit 0 present, bit 1 stored as LZO1X, bit 2 stored packed
 *               (cdvr_range_pack: zstd of the planar table; never with bit 1); other bits 0
 *   107  u8     range table shift: range bricks of 2^shift voxels (1..7; 0 when absent; the
 *               encoder writes 2 before 2026-12, since then 3 by default, range_brick=)
 *   108  u32    CRC-32C of the stored range table bytes (0 when absent)
 *   112  u64    offset of the stored range table (0 when absent)
 *   120  u64    stored bytes of the range table (0 when absent)
 *  u32 CRC-32C of bytes [0, M)  (at offset M)
 *  CHUNK DATA from the data offset to file bytes: the stored bytes of each chunk and of its
 *  range table; no two extents overlap (any order; the encoder puts each table right before
 *  its chunk).
 *
 * Range table of a chunk (store.h, "value ranges per range brick"): for each of the chunk's
 * count timesteps, for each range brick of the window that meets the voxels the chunk's brick
 * owns (x fastest, then y, then z), u8 min and u8 max of the decoded voxels of that range
 * brick among them; count * 2 * (window bricks) bytes before LZO. Version 2 stores written
 * before range tables existed have bytes 106..127 all 0 (no table) and stay readable.
 *
 * The groups of a variant cover timesteps 0 .. timesteps-1 in order without gaps; all chunks
 * of a group share t0 and count.
 */
#include "store_format.h"

#include "codec/stage2/stage2.h"
#include "cdvr/memory.h"
#include "cdvr/pvtc.h"
#include "cdvr/regular_file.h"
#include "cdvr/timing.h"

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

static void get_bytes(rcursor *r, void *dst, size_t n)
{
    if ((size_t)(r->end - r->p) < n) {
        memset(dst, 0, n);
        r->p = r->end;
        return;
    }
    memcpy(dst, r->p, n);
    r->p += n;
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

static uint64_t meta_bytes_v1(size_t nvariants, size_t nchunks)
{
    size_t v, c, sum;
    if (!cdvr_size_mul(nvariants, CDVR_STORE_V1_VARIANT_BYTES, &v) ||
        !cdvr_size_mul(nchunks, CDVR_STORE_V1_CHUNK_BYTES, &c) || !cdvr_size_add(v, c, &sum) ||
        !cdvr_size_add(sum, CDVR_STORE_V1_HEADER_BYTES, &sum) || sum > SIZE_MAX - 4)
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
        st->chunk_first = calloc(nvariants ? nvariants : 1, sizeof *st->chunk_first);
        st->chunks = calloc(nchunks ? nchunks : 1, sizeof *st->chunks);
    }
    if (!st || !st->path || !st->variants || !st->chunk_first || !st->chunks) {
        cdvr_store_close(st);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for %zu variants, %zu chunks",
                              path, nvariants, nchunks);
    }
    st->info.nvariants = nvariants;
    st->nchunks_total = nchunks;
    *out = st;
    return CDVR_OK;
}

void cdvr_store_brick_box(const cdvr_store_info *info, size_t b, size_t lo[3], size_t dims[3])
{
    if (!cdvr_brick_box(info->dims, info->bricks, b, lo, dims)) {
        for (int a = 0; a < 3; a++) {
            lo[a] = 0;
            dims[a] = info->dims[a];
        }
    }
}

void cdvr_store_brick_owned(const cdvr_store_info *info, size_t b, size_t lo[3],
                            size_t dims[3])
{
    if (!cdvr_brick_owned(info->dims, info->bricks, b, lo, dims))
        cdvr_store_brick_box(info, b, lo, dims); /* the whole volume */
}

/* ---- metadata writer -------------------------------------------------------------------- */

static void put_name(wcursor *w, const char *name, size_t field)
{
    char padded[CDVR_NAME_MAX] = {0};
    size_t n = strnlen(name, field - 1);
    memcpy(padded, name, n);
    put_bytes(w, padded, field);
}

static void put_zeros(wcursor *w, size_t n)
{
    memset(w->p, 0, n);
    w->p += n;
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
    for (int i = 0; i < 9; i++)
        put_f64(w, in->direction[i]);
    put_f64(w, in->qlo);
    put_f64(w, in->qhi);
    put_u32(w, (uint32_t)in->source_type);
    put_u32(w, (uint32_t)in->nvariants);
    put_u64(w, st->nchunks_total);
    put_u64(w, meta + 4);
    put_u64(w, in->file_bytes);
    for (int i = 0; i < 3; i++)
        put_u32(w, (uint32_t)in->bricks[i]);
    put_u32(w, in->nlevels > 1 ? (uint32_t)in->nlevels : 0u);
    put_u64(w, in->nlevels > 1 ? st->levels_offset : 0u);
    put_zeros(w, 8);
}

static void put_variant(wcursor *w, const cdvr_variant_info *v)
{
    put_name(w, v->name, CDVR_NAME_MAX);
    put_name(w, v->codec_name, CDVR_CODEC_NAME_MAX);
    put_u32(w, v->codec_id);
    put_u32(w, (uint32_t)v->stage2);
    put_u64(w, v->nchunks);
    put_f64(w, v->lzo_min_saving);
    put_f64(w, v->psnr);
    put_f64(w, v->maxerr);
    put_bytes(w, v->params.bytes, CDVR_CODEC_PARAMS_MAX);
    put_f64(w, v->stage2_read_mbps);
    put_u32(w, (uint32_t)v->stage2_segment);
    put_u64(w, v->shared_offset);
    put_u32(w, (uint32_t)v->shared_bytes);
}

static void put_chunk(wcursor *w, const cdvr_chunk_info *c)
{
    put_u64(w, c->t0);
    put_u64(w, c->count);
    put_u32(w, (uint32_t)c->brick);
    put_u32(w, c->codec_id);
    put_bytes(w, c->params.bytes, CDVR_CODEC_PARAMS_MAX);
    put_u32(w, (uint32_t)c->stage2 | (c->stage2_segmented ? 0x100u : 0u));
    put_u32(w, c->crc32c);
    put_u64(w, c->offset);
    put_u64(w, c->stored_bytes);
    put_u64(w, c->payload_bytes);
    *w->p++ = c->value_min;
    *w->p++ = c->value_max;
    int has_ranges = c->ranges_shift != 0;
    static const uint8_t stage2_bits[3] = {0u, 2u, 4u}; /* none, LZO, packed */
    *w->p++ = (uint8_t)(has_ranges ? 1u | stage2_bits[c->ranges_stage2 & 3] : 0u);
    *w->p++ = (uint8_t)c->ranges_shift;
    put_u32(w, has_ranges ? c->ranges_crc32c : 0);
    put_u64(w, has_ranges ? c->ranges_offset : 0);
    put_u64(w, has_ranges ? c->ranges_stored_bytes : 0);
}

void cdvr_store_serialize_meta(const cdvr_store *st, uint8_t *buf)
{
    uint64_t meta = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total);
    wcursor w = {buf};
    put_header(&w, st, meta);
    for (size_t v = 0; v < st->info.nvariants; v++)
        put_variant(&w, &st->variants[v]);
    for (size_t c = 0; c < st->nchunks_total; c++)
        put_chunk(&w, &st->chunks[c]);
    wcursor crc = {buf + meta};
    put_u32(&crc, cdvr_crc32c(0, buf, (size_t)meta));
}

/* ---- reader: header --------------------------------------------------------------------- */

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
    uint32_t version, header_bytes, source_type, nvariants;
    uint64_t meta, dims[3], timesteps, nchunks, data_offset, file_bytes;
    double spacing[3], origin[3], direction[9], qlo, qhi;
    uint32_t bricks[3], reserved;
    uint32_t nlevels;
    uint64_t levels_offset;
} header_fields;

/* Versions 1 and 2 share the first 16 bytes (magic, version, header bytes, meta bytes). */
static void parse_header(const uint8_t *buf, size_t n, header_fields *h)
{
    rcursor r = {buf + 8, buf + n};
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
    memset(h->direction, 0, sizeof h->direction);
    h->direction[0] = h->direction[4] = h->direction[8] = 1;
    if (h->version >= 2)
        for (int i = 0; i < 9; i++)
            h->direction[i] = get_f64(&r);
    h->qlo = get_f64(&r);
    h->qhi = get_f64(&r);
    h->source_type = get_u32(&r);
    h->nvariants = get_u32(&r);
    h->nchunks = get_u64(&r);
    h->data_offset = get_u64(&r);
    h->file_bytes = get_u64(&r);
    h->bricks[0] = h->bricks[1] = h->bricks[2] = 1;
    h->reserved = 0;
    if (h->version >= 2) {
        for (int i = 0; i < 3; i++)
            h->bricks[i] = get_u32(&r);
        h->nlevels = get_u32(&r);
        h->levels_offset = get_u64(&r);
        for (int i = 0; i < 2; i++)
            h->reserved |= get_u32(&r);
    }
}

static size_t header_bytes_of(uint32_t version)
{
    return version == 1 ? CDVR_STORE_V1_HEADER_BYTES : CDVR_STORE_HEADER_BYTES;
}

static cdvr_status check_header_sizes(const char *path, const header_fields *h,
                                      uint64_t file_size, cdvr_error *err)
{
    if (h->version != 1 && h->version != CDVR_STORE_VERSION)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: store format version %u, this cdvr "
                              "reads versions 1 and %u", path, h->version, CDVR_STORE_VERSION);
    if (h->header_bytes != header_bytes_of(h->version))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: header size %u, expected %zu", path,
                              h->header_bytes, header_bytes_of(h->version));
    if (h->nvariants < 1 || h->nvariants > CDVR_STORE_MAX_VARIANTS)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: %u variants (must be 1..%u)", path,
                              h->nvariants, CDVR_STORE_MAX_VARIANTS);
    uint64_t meta = 0;
    if (h->nchunks <= file_size)
        meta = h->version == 1 ? meta_bytes_v1(h->nvariants, (size_t)h->nchunks)
                               : cdvr_store_meta_bytes(h->nvariants, (size_t)h->nchunks);
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

static int all_finite(const double *a, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(a[i]))
            return 0;
    return 1;
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
    if (!all_finite(h->spacing, 3) || !all_finite(h->origin, 3) ||
        !all_finite(h->direction, 9) || !isfinite(h->qlo) || !isfinite(h->qhi) ||
        h->qhi < h->qlo)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: spacing, origin, direction or window "
                              "not finite (or window hi < lo)", path);
    double inv[9]; /* an all-zero matrix would otherwise render as the identity */
    if (!cdvr_mat3_inverse(h->direction, inv))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: direction matrix %g %g %g / %g %g %g / "
                              "%g %g %g is singular (all zero or its columns do not span 3D)",
                              path, h->direction[0], h->direction[1], h->direction[2],
                              h->direction[3], h->direction[4], h->direction[5], h->direction[6],
                              h->direction[7], h->direction[8]);
    if (h->source_type > CDVR_TYPE_F32)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: unknown source type %u", path,
                              h->source_type);
    size_t bricks[3] = {h->bricks[0], h->bricks[1], h->bricks[2]}, lo[3], bd[3];
    size_t dims[3] = {(size_t)h->dims[0], (size_t)h->dims[1], (size_t)h->dims[2]};
    int small = h->bricks[0] <= CDVR_STORE_MAX_BRICKS && h->bricks[1] <= CDVR_STORE_MAX_BRICKS &&
                h->bricks[2] <= CDVR_STORE_MAX_BRICKS;
    size_t nbricks = small ? bricks[0] * bricks[1] * bricks[2] : 0;
    if (h->nlevels == 1 || h->nlevels > CDVR_STORE_MAX_LEVELS ||
        (h->nlevels == 0) != (h->levels_offset == 0) || h->levels_offset > h->file_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: bad level count %u or directory "
                              "offset %llu", path, h->nlevels,
                              (unsigned long long)h->levels_offset);
    if (h->reserved || nbricks == 0 || nbricks > CDVR_STORE_MAX_BRICKS ||
        !cdvr_brick_box(dims, bricks, 0, lo, bd))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: bad brick grid %ux%ux%u for dims "
                              "%llux%llux%llu (or reserved header bits set)", path, h->bricks[0],
                              h->bricks[1], h->bricks[2], (unsigned long long)h->dims[0],
                              (unsigned long long)h->dims[1], (unsigned long long)h->dims[2]);
    info->version = h->version;
    for (int i = 0; i < 3; i++) {
        info->dims[i] = (size_t)h->dims[i];
        info->spacing[i] = h->spacing[i];
        info->origin[i] = h->origin[i];
        info->bricks[i] = bricks[i];
    }
    memcpy(info->direction, h->direction, sizeof info->direction);
    info->nbricks = nbricks;
    info->nlevels = h->nlevels ? h->nlevels : 1;
    info->timesteps = (size_t)h->timesteps;
    info->qlo = h->qlo;
    info->qhi = h->qhi;
    info->source_type = (cdvr_type)h->source_type;
    info->nvariants = h->nvariants;
    info->raw_bytes = (uint64_t)raw;
    info->file_bytes = h->file_bytes;
    return CDVR_OK;
}

/* ---- reader: variant and chunk records ---------------------------------------------------- */

/* Resolves a codec id recorded for a variant or chunk: the loaded codec, or NULL when none
 * has that id; a loaded codec whose name differs from the recorded one is corruption (or a
 * different plugin that took the id). */
static cdvr_status resolve_codec(const cdvr_store *st, const char *what, uint32_t id,
                                 const char *recorded_name, const cdvr_codec **out,
                                 cdvr_error *err)
{
    *out = cdvr_codec_by_id(id);
    if (*out && recorded_name && strcmp((*out)->name, recorded_name) != 0)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: %s: codec id %u is '%s' here, the "
                              "store says '%s'", st->path, what, id, (*out)->name, recorded_name);
    return CDVR_OK;
}

static cdvr_status check_variant_common(const cdvr_store *st, size_t v, uint64_t nchunks,
                                        uint32_t stage2, cdvr_error *err)
{
    cdvr_variant_info *vi = &st->variants[v];
    if (memchr(vi->name, 0, CDVR_NAME_MAX) == NULL || vi->name[0] == '\0')
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %zu: bad name", st->path, v + 1);
    if (stage2 > (st->info.version == 1 ? CDVR_STAGE2_LZO : CDVR_STAGE2_AUTO))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: bad stage 2 %u", st->path,
                              vi->name, stage2);
    if (nchunks == 0 || nchunks % st->info.nbricks || nchunks > st->nchunks_total ||
        isnan(vi->psnr) || vi->psnr < 0 || !(vi->maxerr >= 0 && vi->maxerr <= 255) ||
        !(vi->lzo_min_saving <= 1))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: bad chunk count, psnr, "
                              "maxerr or lzo saving", st->path, vi->name);
    for (size_t i = 0; i < v; i++)
        if (strcmp(st->variants[i].name, vi->name) == 0)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant name %s appears twice",
                                  st->path, vi->name);
    vi->stage2 = (cdvr_stage2)stage2;
    vi->nchunks = (size_t)nchunks;
    vi->ngroups = vi->nchunks / st->info.nbricks;
    if (vi->codec) {
        cdvr_error perr;
        if (vi->codec->params_check(&vi->params, &perr) != CDVR_OK)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: %s", st->path,
                                  vi->name, perr.msg);
    }
    return CDVR_OK;
}

static cdvr_status parse_variant_v2(const cdvr_store *st, rcursor *r, size_t v, cdvr_error *err)
{
    cdvr_variant_info *vi = &st->variants[v];
    get_bytes(r, vi->name, CDVR_NAME_MAX);
    get_bytes(r, vi->codec_name, CDVR_CODEC_NAME_MAX);
    vi->codec_id = get_u32(r);
    uint32_t stage2 = get_u32(r);
    uint64_t nchunks = get_u64(r);
    vi->lzo_min_saving = get_f64(r);
    vi->psnr = get_f64(r);
    vi->maxerr = get_f64(r);
    get_bytes(r, vi->params.bytes, CDVR_CODEC_PARAMS_MAX);
    vi->stage2_read_mbps = get_f64(r);
    uint32_t segment = get_u32(r);
    vi->shared_offset = get_u64(r);
    vi->shared_bytes = get_u32(r);
    if ((vi->shared_offset == 0) != (vi->shared_bytes == 0))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %zu: shared blob at %llu of "
                              "%llu bytes", st->path, v + 1,
                              (unsigned long long)vi->shared_offset,
                              (unsigned long long)vi->shared_bytes);
    if (!(vi->stage2_read_mbps >= 0 && vi->stage2_read_mbps < HUGE_VAL) ||
        (segment && (segment < CDVR_STAGE2_SEGMENT_MIN || segment > CDVR_STAGE2_SEGMENT_MAX)))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %zu: bad stage-2 read rate %g "
                              "or segment bytes %u", st->path, v + 1, vi->stage2_read_mbps,
                              segment);
    vi->stage2_segment = segment;
    if (!memchr(vi->codec_name, 0, CDVR_CODEC_NAME_MAX) ||
        !cdvr_codec_name_valid(vi->codec_name) || memchr(vi->name, 0, CDVR_NAME_MAX) == NULL)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %zu: bad name or codec name",
                              st->path, v + 1);
    char what[CDVR_NAME_MAX + 16];
    snprintf(what, sizeof what, "variant %s", vi->name);
    cdvr_status s = resolve_codec(st, what, vi->codec_id, vi->codec_name, &vi->codec, err);
    return s == CDVR_OK ? check_variant_common(st, v, nchunks, stage2, err) : s;
}

static cdvr_status parse_chunk_v2(const cdvr_store *st, rcursor *r, size_t v,
                                  cdvr_chunk_info *ci, cdvr_error *err)
{
    ci->t0 = (size_t)get_u64(r);
    ci->count = (size_t)get_u64(r);
    ci->brick = get_u32(r);
    ci->codec_id = get_u32(r);
    get_bytes(r, ci->params.bytes, CDVR_CODEC_PARAMS_MAX);
    uint32_t flag = get_u32(r);
    ci->crc32c = get_u32(r);
    ci->offset = get_u64(r);
    ci->stored_bytes = get_u64(r);
    ci->payload_bytes = get_u64(r);
    uint8_t tail[4];
    get_bytes(r, tail, sizeof tail);
    ci->value_min = tail[0];
    ci->value_max = tail[1];
    ci->ranges_crc32c = get_u32(r);
    ci->ranges_offset = get_u64(r);
    ci->ranges_stored_bytes = get_u64(r);
    unsigned s2 = flag & 0xffu, segmented = (flag >> 8) & 1u;
    int reserved = (flag >> 9) != 0 || s2 > CDVR_STAGE2_ZSTD || (s2 == 0 && segmented) ||
                   (s2 > CDVR_STAGE2_LZO && !segmented) || tail[2] > 5 ||
                   (tail[2] & 6) == 6;
    if (tail[2] & 1) {
        ci->ranges_shift = tail[3];
        ci->ranges_stage2 = (tail[2] & 2) ? CDVR_RANGES_LZO
                                          : (tail[2] & 4) ? CDVR_RANGES_PACKED : 0;
        reserved |= tail[3] < 1 || tail[3] > 7 || ci->ranges_stored_bytes == 0;
    } else {
        reserved |= tail[2] != 0 || tail[3] != 0 || ci->ranges_crc32c != 0 ||
                    ci->ranges_offset != 0 || ci->ranges_stored_bytes != 0;
    }
    ci->stage2 = (int)s2;
    ci->stage2_segmented = (int)segmented;
    if (reserved)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: a chunk has reserved "
                              "bits set", st->path, st->variants[v].name);
    const cdvr_variant_info *vi = &st->variants[v];
    if (ci->codec_id != vi->codec_id) /* room in the format; a variant has one codec today */
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: a chunk has codec id %u, "
                              "the variant %u", st->path, vi->name, ci->codec_id, vi->codec_id);
    ci->codec = vi->codec;
    return CDVR_OK;
}

/* Version 1: codec 0 raw, 1 pvtc with S, T, pack and the variant's encoder as fields. */
static void v1_params(uint32_t codec, uint32_t S, uint32_t T, uint32_t pack, uint32_t encoder,
                      cdvr_codec_params *p)
{
    memset(p, 0, sizeof *p);
    if (codec == CDVR_CODEC_ID_PVTC) {
        cdvr_pvtc_params q = {(int)S, (int)T, (cdvr_pack)(pack & 1)};
        cdvr_pvtc_params_to_blob(&q, (cdvr_pvtc_encoder)(encoder & 1), p);
    }
}

static cdvr_status parse_variant_v1(const cdvr_store *st, rcursor *r, size_t v,
                                    uint32_t *encoder, cdvr_error *err)
{
    cdvr_variant_info *vi = &st->variants[v];
    get_bytes(r, vi->name, CDVR_NAME_MAX);
    uint32_t codec = get_u32(r);
    *encoder = get_u32(r);
    uint32_t stage2 = get_u32(r), res1 = get_u32(r);
    uint32_t S = get_u32(r), T = get_u32(r), pack = get_u32(r), res2 = get_u32(r);
    uint64_t nchunks = get_u64(r);
    vi->lzo_min_saving = get_f64(r);
    vi->psnr = get_f64(r);
    vi->maxerr = get_f64(r);
    if ((codec != CDVR_CODEC_ID_RAW && codec != CDVR_CODEC_ID_PVTC) || *encoder > 1 || res1 ||
        res2 || pack > 1 || S > 8 || T > 8)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %zu: bad codec %u, encoder %u "
                              "or parameters S%u T%u pack %u", st->path, v + 1, codec, *encoder,
                              S, T, pack);
    vi->codec_id = codec;
    vi->codec = cdvr_codec_by_id(codec);
    snprintf(vi->codec_name, sizeof vi->codec_name, "%s", vi->codec->name);
    v1_params(codec, S, T, pack, *encoder, &vi->params);
    return check_variant_common(st, v, nchunks, stage2, err);
}

static cdvr_status parse_chunk_v1(const cdvr_store *st, rcursor *r, size_t v,
                                  uint32_t encoder, cdvr_chunk_info *ci, cdvr_error *err)
{
    ci->t0 = (size_t)get_u64(r);
    ci->count = (size_t)get_u64(r);
    uint32_t S = get_u32(r), T = get_u32(r), pack = get_u32(r), flag = get_u32(r);
    ci->offset = get_u64(r);
    ci->stored_bytes = get_u64(r);
    ci->payload_bytes = get_u64(r);
    ci->crc32c = get_u32(r);
    uint32_t reserved = get_u32(r) | (S | T) >> 8 | (pack >> 1) | (flag >> 1);
    if (reserved)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: a chunk has reserved "
                              "bits set", st->path, st->variants[v].name);
    ci->stage2 = (int)(flag & 1);
    ci->brick = 0;
    ci->codec_id = st->variants[v].codec_id;
    ci->codec = st->variants[v].codec;
    v1_params(ci->codec_id, S, T, pack, encoder, &ci->params);
    ci->value_min = 0; /* not recorded in version 1: the full range */
    ci->value_max = 255;
    return CDVR_OK;
}

/* Checks chunk c of variant v: time coverage, brick order, codec parameters and payload size
 * against the codec's shape of the brick (when the codec is loaded), stage 2 and the file. */
static cdvr_status check_chunk(const cdvr_store *st, size_t v, size_t c, size_t next_t0,
                               const cdvr_chunk_info *group_first, cdvr_error *err)
{
    const cdvr_variant_info *vi = &st->variants[v];
    const cdvr_chunk_info *ci = &st->chunks[st->chunk_first[v] + c];
    char pre[CDVR_ERRMSG_MAX / 2];
    snprintf(pre, sizeof pre, "%s: variant %s chunk %zu", st->path, vi->name, c + 1);
    size_t brick = c % st->info.nbricks;
    if (ci->brick != brick || (group_first && (ci->t0 != group_first->t0 ||
                                               ci->count != group_first->count)))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: brick %zu covering timesteps %zu+%zu "
                              "breaks its group (expected brick %zu)", pre, ci->brick + 1,
                              ci->t0 + 1, ci->count, brick + 1);
    if (ci->t0 != next_t0 || ci->count == 0 || ci->count > st->info.timesteps - ci->t0)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: covers timesteps %zu+%zu, expected "
                              "to start at %zu of %zu", pre, ci->t0 + 1, ci->count, next_t0 + 1,
                              st->info.timesteps);
    if (ci->codec) {
        size_t lo[3], dims[3];
        cdvr_store_brick_box(&st->info, brick, lo, dims);
        cdvr_codec_shape shape;
        cdvr_error perr;
        if (cdvr_codec_shape_of(ci->codec, &ci->params, dims, &shape, &perr) != CDVR_OK)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: %s", pre, perr.msg);
        if (ci->count > shape.timesteps)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: %zu timesteps, at most %zu fit",
                                  pre, ci->count, shape.timesteps);
        if (shape.payload_bytes ? ci->payload_bytes != shape.payload_bytes
                                : (ci->payload_bytes == 0 || ci->payload_bytes > shape.bound_bytes))
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: payload %llu bytes, parameters "
                                  "give %zu (bound %zu)", pre,
                                  (unsigned long long)ci->payload_bytes, shape.payload_bytes,
                                  shape.bound_bytes);
    } else if (ci->payload_bytes == 0 || ci->payload_bytes > SIZE_MAX) {
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: payload of %llu bytes", pre,
                              (unsigned long long)ci->payload_bytes);
    }
    if (ci->stage2 ? ((vi->stage2 != (cdvr_stage2)ci->stage2 && vi->stage2 != CDVR_STAGE2_AUTO) ||
                      ci->stored_bytes >= ci->payload_bytes || ci->stored_bytes == 0 ||
                      (ci->stage2_segmented && ci->stored_bytes < 12))
                   : ci->stored_bytes != ci->payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: stored %llu bytes with stage-2 flag "
                              "%d does not fit payload %llu", pre,
                              (unsigned long long)ci->stored_bytes, ci->stage2,
                              (unsigned long long)ci->payload_bytes);
    if (ci->value_min > ci->value_max)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: value range %u..%u", pre,
                              ci->value_min, ci->value_max);
    size_t table = cdvr_store_ranges_bytes(st, v, c);
    if (ci->ranges_shift && (table == 0 || (ci->ranges_stage2
                                                ? ci->ranges_stored_bytes >= table
                                                : ci->ranges_stored_bytes != table)))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: range table of %llu stored bytes "
                              "(stage-2 flag %d) does not fit %zu bytes of ranges", pre,
                              (unsigned long long)ci->ranges_stored_bytes, ci->ranges_stage2,
                              table);
    return CDVR_OK;
}

typedef struct extent {
    uint64_t offset, bytes;
    size_t chunk;
} extent;

static int compare_extents(const void *a, const void *b)
{
    const extent *x = a, *y = b;
    return x->offset < y->offset ? -1 : x->offset > y->offset;
}

/* Every chunk's bytes lie in [data_start, file_bytes) and no two overlap. */
static cdvr_status check_extents(const cdvr_store *st, uint64_t data_start, cdvr_error *err)
{
    size_t n = st->nchunks_total;
    extent *ex = malloc((2 * n + st->info.nvariants + 1) * sizeof *ex);
    if (!ex)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory to check %zu chunks",
                              st->path, n);
    size_t nex = 0;
    for (size_t c = 0; c < n; c++) {
        const cdvr_chunk_info *ci = &st->chunks[c];
        ex[nex++] = (extent){ci->offset, ci->stored_bytes, c};
        if (ci->ranges_shift)
            ex[nex++] = (extent){ci->ranges_offset, ci->ranges_stored_bytes, c};
    }
    for (size_t v = 0; v < st->info.nvariants; v++) /* shared blobs: as the first chunk's */
        if (st->variants[v].shared_bytes)
            ex[nex++] = (extent){st->variants[v].shared_offset, st->variants[v].shared_bytes,
                                 st->chunk_first[v]};
    n = nex;
    qsort(ex, n, sizeof *ex, compare_extents);
    cdvr_status s = CDVR_OK;
    uint64_t end = data_start;
    for (size_t i = 0; i < n && s == CDVR_OK; i++) {
        const extent *e = &ex[i];
        if (e->offset < end || e->offset > st->info.file_bytes ||
            e->bytes > st->info.file_bytes - e->offset) {
            size_t v = 0;
            while (v + 1 < st->info.nvariants && st->chunk_first[v + 1] <= e->chunk)
                v++;
            s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s chunk %zu: bytes "
                               "%llu..%llu (chunk, range table or shared blob) overlap another "
                               "extent or "
                               "lie outside the data "
                               "(%llu..%llu)", st->path, st->variants[v].name,
                               e->chunk - st->chunk_first[v] + 1,
                               (unsigned long long)e->offset,
                               (unsigned long long)(e->offset + e->bytes),
                               (unsigned long long)data_start,
                               (unsigned long long)st->info.file_bytes);
        }
        end = e->offset + e->bytes;
    }
    free(ex);
    return s;
}

static cdvr_status parse_tables(cdvr_store *st, const uint8_t *meta, size_t meta_bytes,
                                cdvr_error *err)
{
    int v1 = st->info.version == 1;
    rcursor r = {meta + header_bytes_of(st->info.version), meta + meta_bytes};
    uint32_t *encoders = calloc(st->info.nvariants, sizeof *encoders);
    if (!encoders)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", st->path);
    size_t first = 0;
    cdvr_status s = CDVR_OK;
    for (size_t v = 0; s == CDVR_OK && v < st->info.nvariants; v++) {
        s = v1 ? parse_variant_v1(st, &r, v, &encoders[v], err) : parse_variant_v2(st, &r, v, err);
        if (s == CDVR_OK && st->variants[v].nchunks > st->nchunks_total - first)
            s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s: %zu chunks, more than the "
                               "header's total", st->path, st->variants[v].name,
                               st->variants[v].nchunks);
        st->chunk_first[v] = first;
        first += s == CDVR_OK ? st->variants[v].nchunks : 0;
    }
    if (s == CDVR_OK && first != st->nchunks_total)
        s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variants hold %zu chunks, header says "
                           "%zu", st->path, first, st->nchunks_total);
    for (size_t v = 0; s == CDVR_OK && v < st->info.nvariants; v++) {
        cdvr_variant_info *vi = &st->variants[v];
        size_t next_t0 = 0;
        const cdvr_chunk_info *group_first = NULL;
        for (size_t c = 0; s == CDVR_OK && c < vi->nchunks; c++) {
            cdvr_chunk_info *ci = &st->chunks[st->chunk_first[v] + c];
            s = v1 ? parse_chunk_v1(st, &r, v, encoders[v], ci, err)
                   : parse_chunk_v2(st, &r, v, ci, err);
            if (s == CDVR_OK)
                s = check_chunk(st, v, c, next_t0, group_first, err);
            if (s != CDVR_OK)
                break;
            group_first = c % st->info.nbricks == 0 ? ci : group_first;
            if ((c + 1) % st->info.nbricks == 0) {
                next_t0 = ci->t0 + ci->count;
                group_first = NULL;
            }
            vi->bytes += ci->stored_bytes;
            vi->payload_bytes += ci->payload_bytes;
            vi->stage2_chunks[ci->stage2 & 3]++;
            vi->ranges_bytes += ci->ranges_stored_bytes;
        }
        if (s == CDVR_OK && next_t0 != st->info.timesteps)
            s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s covers %zu of %zu "
                               "timesteps", st->path, vi->name, next_t0, st->info.timesteps);
    }
    free(encoders);
    if (s == CDVR_OK)
        s = check_extents(st, meta_bytes + 4, err);
    return s;
}

/* ---- reader: open ----------------------------------------------------------------------- */

static cdvr_status open_header(cdvr_store *st, uint64_t file_size, header_fields *h,
                               cdvr_error *err)
{
    uint8_t hdr[CDVR_STORE_HEADER_BYTES];
    size_t got = 0;
    if (read_at(st->fd, hdr, sizeof hdr, st->base, &got) != CDVR_OK)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot read: %s", st->path, strerror(errno));
    if (got < 8 || memcmp(hdr, CDVR_STORE_MAGIC, 8) != 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not a cdvr store (bad magic)", st->path);
    uint32_t version = got >= 12 ? (uint32_t)hdr[8] | (uint32_t)hdr[9] << 8 |
                                       (uint32_t)hdr[10] << 16 | (uint32_t)hdr[11] << 24
                                 : 0;
    size_t need = version == 1 ? CDVR_STORE_V1_HEADER_BYTES : CDVR_STORE_HEADER_BYTES;
    if (got < need && (version == 1 || version == CDVR_STORE_VERSION))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: truncated header (%zu of %zu bytes)",
                              st->path, got, need);
    parse_header(hdr, got < need ? got : need, h);
    return check_header_sizes(st->path, h, file_size, err);
}

/* The variant's shared blob (extent checked) into the shared-blob table. */
static cdvr_status load_shared(cdvr_store *st, cdvr_variant_info *vi, cdvr_error *err)
{
    if (!vi->shared_bytes)
        return CDVR_OK;
    size_t n = (size_t)vi->shared_bytes, got = 0;
    uint8_t *blob = malloc(n);
    if (!blob)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: variant %s: no memory for its shared "
                              "blob of %zu bytes", st->path, vi->name, n);
    cdvr_status s = read_at(st->fd, blob, n, st->base + vi->shared_offset, &got);
    if (s != CDVR_OK || got != n)
        s = cdvr_error_set(err, CDVR_ERR_IO, "%s: variant %s: cannot read its shared blob",
                           st->path, vi->name);
    else
        s = cdvr_shared_put(blob, n, &vi->shared_id, err);
    if (s == CDVR_OK)
        vi->bytes += vi->shared_bytes;
    free(blob);
    return s;
}

static cdvr_status open_tables(cdvr_store *st, const header_fields *h, cdvr_error *err)
{
    size_t meta = (size_t)h->meta;
    uint8_t *buf = malloc(meta + 4);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for %zu bytes of tables",
                              st->path, meta + 4);
    size_t got = 0;
    cdvr_status s = read_at(st->fd, buf, meta + 4, st->base, &got);
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
    for (size_t v = 0; s == CDVR_OK && v < st->info.nvariants; v++)
        s = load_shared(st, &st->variants[v], err);
    return s;
}

cdvr_status cdvr_store_open_at(const char *path, int fd, uint64_t base, uint64_t size,
                               cdvr_store **out, cdvr_error *err)
{
    *out = NULL;
    header_fields h = {0};
    cdvr_store probe = {.path = (char *)path, .fd = fd, .base = base};
    cdvr_status s = open_header(&probe, size, &h, err);
    cdvr_store *st = NULL;
    if (s == CDVR_OK)
        s = cdvr_store_alloc(h.nvariants, (size_t)h.nchunks, path, &st, err);
    if (s != CDVR_OK) {
        close(fd);
        return s;
    }
    st->fd = fd;
    st->base = base;
    st->info.version = h.version;
    st->info.file_bytes = h.file_bytes;
    st->info.nbricks = 1; /* until the header values are checked */
    st->info.nlevels = 1;
    s = open_tables(st, &h, err);
    if (s == CDVR_OK && h.nlevels > 1)
        s = cdvr_store_open_levels(st, h.nlevels, h.levels_offset, err);
    if (s != CDVR_OK) {
        cdvr_store_close(st);
        return s;
    }
    *out = st;
    return CDVR_OK;
}

cdvr_status cdvr_store_read_bytes(const cdvr_store *st, uint8_t *buf, size_t n, uint64_t offset,
                                  cdvr_error *err)
{
    size_t got = 0;
    if (read_at(st->fd, buf, n, st->base + offset, &got) != CDVR_OK || got != n)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: cannot read %zu bytes at %llu",
                              st->path, n, (unsigned long long)offset);
    return CDVR_OK;
}

cdvr_status cdvr_store_open(const char *path, cdvr_store **out, cdvr_error *err)
{
    *out = NULL;
    int fd;
    struct stat sb;
    cdvr_status os = cdvr_open_regular_file(path, &fd, &sb, err); /* never waits on a FIFO */
    if (os != CDVR_OK)
        return os;
    return cdvr_store_open_at(path, fd, 0, (uint64_t)sb.st_size, out, err);
}

void cdvr_store_close(cdvr_store *st)
{
    if (!st)
        return;
    cdvr_store_close_levels(st);
    if (st->fd >= 0)
        close(st->fd);
    for (size_t v = 0; st->variants && v < st->info.nvariants; v++)
        if (st->variants[v].shared_id)
            cdvr_shared_drop(st->variants[v].shared_id);
    free(st->path);
    free(st->variants);
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

/* The quality a variant is ranked by: a raw variant is lossless (+inf), else its recorded
 * PSNR (+inf when lossless; a NaN, never written by the encoder, ranks below everything). */
static double variant_quality(const cdvr_variant_info *var)
{
    if (var->codec_id == CDVR_CODEC_ID_RAW)
        return HUGE_VAL;
    return isnan(var->psnr) ? -HUGE_VAL : var->psnr;
}

int cdvr_store_best_variant(const cdvr_store *st)
{
    int best = 0;
    for (size_t v = 1; v < st->info.nvariants; v++) {
        const cdvr_variant_info *a = &st->variants[v], *b = &st->variants[best];
        double qa = variant_quality(a), qb = variant_quality(b);
        if (qa > qb || (qa == qb && a->bytes > b->bytes))
            best = (int)v;
    }
    return best;
}

const cdvr_chunk_info *cdvr_store_chunk(const cdvr_store *st, size_t v, size_t c)
{
    if (v >= st->info.nvariants || c >= st->variants[v].nchunks)
        return NULL;
    return &st->chunks[st->chunk_first[v] + c];
}

size_t cdvr_store_chunk_for(const cdvr_store *st, size_t v, size_t t, size_t b)
{
    size_t nb = st->info.nbricks;
    if (v >= st->info.nvariants || t >= st->info.timesteps || b >= nb)
        return (size_t)-1;
    const cdvr_chunk_info *ch = &st->chunks[st->chunk_first[v]];
    size_t lo = 0, hi = st->variants[v].ngroups; /* groups are sorted by t0 and contiguous */
    while (hi - lo > 1) {
        size_t mid = lo + (hi - lo) / 2;
        if (ch[mid * nb].t0 <= t)
            lo = mid;
        else
            hi = mid;
    }
    return lo * nb + b;
}

size_t cdvr_store_chunk_for_time(const cdvr_store *st, size_t v, size_t t)
{
    return cdvr_store_chunk_for(st, v, t, 0);
}

static cdvr_status codec_missing(const cdvr_store *st, const char *variant, const char *name,
                                 uint32_t id, cdvr_error *err)
{
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: variant %s: codec '%s' (id %u) is not "
                          "loaded (load its plugin: cdvr.plugin.load)", st->path, variant, name,
                          id);
}

cdvr_status cdvr_store_variant_codec(const cdvr_store *st, size_t v, const cdvr_codec **out,
                                     cdvr_error *err)
{
    *out = NULL;
    if (v >= st->info.nvariants)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no variant %zu", st->path, v + 1);
    const cdvr_variant_info *vi = &st->variants[v];
    if (!vi->codec)
        return codec_missing(st, vi->name, vi->codec_name, vi->codec_id, err);
    *out = vi->codec;
    return CDVR_OK;
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

/* Reads n bytes of chunk c's part `what` ("" for the chunk itself, "range table ") at offset
 * into buf and checks them against the CRC-32C the index records. */
static cdvr_status read_checked(const cdvr_store *st, size_t v, size_t c, const char *what,
                                uint8_t *buf, size_t n, uint64_t offset, uint32_t crc_index,
                                cdvr_error *err)
{
    const char *name = st->variants[v].name;
    size_t got = 0;
    if (read_at(st->fd, buf, n, st->base + offset, &got) != CDVR_OK)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: variant %s chunk %zu: %sread failed: %s",
                              st->path, name, c + 1, what, strerror(errno));
    if (got != n)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s chunk %zu: %struncated "
                              "(%zu of %zu bytes)", st->path, name, c + 1, what, got, n);
    uint32_t crc = cdvr_crc32c(0, buf, got);
    if (crc != crc_index)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: variant %s chunk %zu: %sCRC-32C "
                              "mismatch (index 0x%08x, data 0x%08x)", st->path, name, c + 1, what,
                              crc_index, crc);
    return CDVR_OK;
}

cdvr_status cdvr_store_read_chunk(const cdvr_store *st, size_t v, size_t c, uint8_t *buf,
                                  cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    return read_checked(st, v, c, "", buf, (size_t)ci->stored_bytes, ci->offset, ci->crc32c, err);
}

void cdvr_store_drop_cache(const cdvr_store *st, size_t v, size_t c)
{
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    if (ci)
        (void)posix_fadvise(st->fd, (off_t)(st->base + ci->offset), (off_t)ci->stored_bytes,
                            POSIX_FADV_DONTNEED);
}

const char *cdvr_stage2_name(int stage2)
{
    return stage2 == CDVR_STAGE2_AUTO ? "auto" : cdvr_s2_name((unsigned)stage2);
}

cdvr_status cdvr_stage2_unpack_rates(double mbps[5], int *from_cache, cdvr_error *err)
{
    cdvr_s2_rates r;
    cdvr_status s = cdvr_s2_unpack_rates(&r, err);
    memset(mbps, 0, 5 * sizeof *mbps);
    *from_cache = 0;
    if (s != CDVR_OK)
        return s;
    mbps[CDVR_STAGE2_LZO] = r.mbps[CDVR_S2_LZO];
    mbps[CDVR_STAGE2_LZ4] = r.mbps[CDVR_S2_LZ4];
    mbps[CDVR_STAGE2_ZSTD] = r.mbps[CDVR_S2_ZSTD];
    *from_cache = r.from_cache;
    return CDVR_OK;
}

/* b1' on `threads` threads, adding the CPU time it took to *cpu_ms. */
static cdvr_status unpack_chunk(const cdvr_store *st, size_t v, size_t c, const uint8_t *stored,
                                uint8_t *out, int threads, double *cpu_ms, cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    double cpu0 = cdvr_thread_cpu_ms();
    if (!ci->stage2) {
        memcpy(out, stored, (size_t)ci->payload_bytes);
        *cpu_ms += cdvr_thread_cpu_ms() - cpu0;
        return CDVR_OK;
    }
    cdvr_error lerr;
    if (ci->stage2_segmented) {
        s = cdvr_s2_unpack_cpu((unsigned)ci->stage2, stored, (size_t)ci->stored_bytes, out,
                               (size_t)ci->payload_bytes, threads, cpu_ms, &lerr);
    } else {
        s = cdvr_lzo_decompress(stored, (size_t)ci->stored_bytes, out,
                                (size_t)ci->payload_bytes, &lerr);
        *cpu_ms += cdvr_thread_cpu_ms() - cpu0;
    }
    if (s != CDVR_OK)
        return cdvr_error_set(err, lerr.status, "%s: variant %s chunk %zu: stage 2 %s: %s",
                              st->path, st->variants[v].name, c + 1,
                              cdvr_s2_name((unsigned)ci->stage2), lerr.msg);
    return CDVR_OK;
}

cdvr_status cdvr_store_unpack_chunk_threads(const cdvr_store *st, size_t v, size_t c,
                                            const uint8_t *stored, uint8_t *out, int threads,
                                            cdvr_error *err)
{
    double ignored = 0;
    return unpack_chunk(st, v, c, stored, out, threads, &ignored, err);
}

cdvr_status cdvr_store_unpack_chunk_cpu(const cdvr_store *st, size_t v, size_t c,
                                        const uint8_t *stored, uint8_t *out, double *cpu_ms,
                                        cdvr_error *err)
{
    return unpack_chunk(st, v, c, stored, out, 0, cpu_ms, err);
}

cdvr_status cdvr_store_unpack_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *stored, uint8_t *out, cdvr_error *err)
{
    return cdvr_store_unpack_chunk_threads(st, v, c, stored, out, 0, err);
}

cdvr_status cdvr_store_decode_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *payload, uint8_t *const *frames,
                                    cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    const cdvr_variant_info *vi = &st->variants[v];
    if (!ci->codec) {
        cdvr_error merr;
        codec_missing(st, vi->name, vi->codec_name, ci->codec_id, &merr);
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s (chunk %zu)", merr.msg, c + 1);
    }
    size_t lo[3], dims[3];
    cdvr_store_brick_box(&st->info, ci->brick, lo, dims);
    cdvr_error derr;
    if (ci->codec->decode(&ci->params, dims, payload, (size_t)ci->payload_bytes, frames,
                          ci->count, &derr) != CDVR_OK)
        return cdvr_error_set(err, derr.status, "%s: variant %s chunk %zu: %s", st->path,
                              vi->name, c + 1, derr.msg);
    return CDVR_OK;
}

int cdvr_store_chunk_decodes_cells(const cdvr_store *st, size_t v, size_t c)
{
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    return ci && ci->codec && ci->codec->decode_cells && ci->count == 1;
}

cdvr_status cdvr_store_decode_chunk_cells(const cdvr_store *st, size_t v, size_t c,
                                          const uint8_t *payload, uint8_t *frame,
                                          unsigned layout, const uint8_t *need,
                                          unsigned cell_log2, cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    if (!cdvr_store_chunk_decodes_cells(st, v, c))
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: variant %s chunk %zu: its codec "
                              "does not decode by cells", st->path, st->variants[v].name, c + 1);
    size_t lo[3], dims[3];
    cdvr_store_brick_box(&st->info, ci->brick, lo, dims);
    cdvr_error derr;
    if (ci->codec->decode_cells(&ci->params, dims, payload, (size_t)ci->payload_bytes, frame,
                                layout, need, cell_log2, &derr) != CDVR_OK)
        return cdvr_error_set(err, derr.status, "%s: variant %s chunk %zu: %s", st->path,
                              st->variants[v].name, c + 1, derr.msg);
    return CDVR_OK;
}

size_t cdvr_store_ranges_bytes(const cdvr_store *st, size_t v, size_t c)
{
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    if (!ci || !ci->ranges_shift)
        return 0;
    size_t lo[3], bd[3], per_frame, bytes;
    cdvr_store_brick_owned(&st->info, ci->brick, lo, bd);
    per_frame = cdvr_range_window_bytes(st->info.dims, lo, bd, ci->ranges_shift);
    return cdvr_size_mul(per_frame, ci->count, &bytes) ? bytes : 0;
}

cdvr_status cdvr_store_read_ranges(const cdvr_store *st, size_t v, size_t c, uint8_t *out,
                                   cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    const char *name = st->variants[v].name;
    size_t bytes = cdvr_store_ranges_bytes(st, v, c);
    if (bytes == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: variant %s chunk %zu has no range table",
                              st->path, name, c + 1);
    size_t stored_n = (size_t)ci->ranges_stored_bytes;
    uint8_t *stored = ci->ranges_stage2 ? malloc(stored_n) : out;
    if (!stored)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for a range table", st->path);
    s = read_checked(st, v, c, "range table ", stored, stored_n, ci->ranges_offset,
                     ci->ranges_crc32c, err);
    if (s == CDVR_OK && ci->ranges_stage2) {
        cdvr_error lerr;
        if ((ci->ranges_stage2 == CDVR_RANGES_LZO
                 ? cdvr_lzo_decompress(stored, stored_n, out, bytes, &lerr)
                 : cdvr_range_unpack(stored, stored_n, out, bytes, &lerr)) != CDVR_OK)
            s = cdvr_error_set(err, lerr.status, "%s: variant %s chunk %zu: range table: %s",
                               st->path, name, c + 1, lerr.msg);
    }
    if (stored != out)
        free(stored);
    return s;
}

cdvr_status cdvr_store_load_payload_into(const cdvr_store *st, size_t v, size_t c,
                                         uint8_t **payload, size_t *payload_cap,
                                         uint8_t **stored, size_t *stored_cap, cdvr_error *err)
{
    const cdvr_chunk_info *ci;
    cdvr_status s = chunk_lookup(st, v, c, &ci, err);
    if (s != CDVR_OK)
        return s;
    if (!cdvr_grow_large(payload, payload_cap, ci->payload_bytes) ||
        (ci->stage2 && !cdvr_grow_large(stored, stored_cap, ci->stored_bytes)))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for chunk %zu (%llu bytes)",
                              st->path, c + 1, (unsigned long long)ci->payload_bytes);
    /* without stage 2 the stored bytes are the payload: read them in place */
    s = cdvr_store_read_chunk(st, v, c, ci->stage2 ? *stored : *payload, err);
    if (s == CDVR_OK && ci->stage2)
        s = cdvr_store_unpack_chunk(st, v, c, *stored, *payload, err);
    return s;
}

/* Reads and unpacks chunk c; *payload is malloc'd (payload_bytes). */
cdvr_status cdvr_store_load_payload(const cdvr_store *st, size_t v, size_t c, uint8_t **payload,
                                    cdvr_error *err)
{
    uint8_t *stored = NULL;
    size_t payload_cap = 0, stored_cap = 0;
    *payload = NULL;
    cdvr_status s = cdvr_store_load_payload_into(st, v, c, payload, &payload_cap, &stored,
                                                 &stored_cap, err);
    free(stored);
    if (s != CDVR_OK) {
        free(*payload);
        *payload = NULL;
    }
    return s;
}

/* Decodes brick chunk c (timestep t inside it) into the volume of dims vd at the brick's
 * first voxel minus at[3] (the whole volume: at = 0; the brick alone: at = its lo). */
static cdvr_status decode_brick_into(const cdvr_store *st, size_t v, size_t c, size_t t,
                                     uint8_t *vol, const size_t vd[3], const size_t at[3],
                                     cdvr_error *err)
{
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    size_t lo[3], bd[3], voxels, scratch_n;
    cdvr_store_brick_box(&st->info, ci->brick, lo, bd);
    voxels = bd[0] * bd[1] * bd[2];
    for (int a = 0; a < 3; a++)
        lo[a] -= at[a];
    uint8_t *payload = NULL, *scratch = NULL;
    uint8_t *frames[64];
    if (ci->count > 64)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: chunk %zu holds %zu timesteps "
                              "(at most 64 are supported)", st->path, c + 1, ci->count);
    cdvr_status s = cdvr_store_load_payload(st, v, c, &payload, err);
    if (s == CDVR_OK && (!cdvr_size_mul(voxels, ci->count, &scratch_n) ||
                         !(scratch = malloc(scratch_n ? scratch_n : 1))))
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory to decode", st->path);
    if (s == CDVR_OK) {
        for (size_t i = 0; i < ci->count; i++)
            frames[i] = scratch + i * voxels;
        s = cdvr_store_decode_chunk(st, v, c, payload, frames, err);
    }
    if (s == CDVR_OK)
        cdvr_brick_place(vol, vd, frames[t - ci->t0], lo, bd);
    free(payload);
    free(scratch);
    return s;
}

cdvr_status cdvr_store_decode(const cdvr_store *st, size_t v, size_t t, cdvr_volume **out,
                              cdvr_error *err)
{
    *out = NULL;
    size_t c0 = cdvr_store_chunk_for(st, v, t, 0);
    if (c0 == (size_t)-1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no timestep %zu in variant %zu (%zu "
                              "timesteps, %zu variants)", st->path, t + 1, v + 1,
                              st->info.timesteps, st->info.nvariants);
    cdvr_volume *vol = NULL;
    cdvr_status s = cdvr_volume_create(st->info.dims, 1, CDVR_TYPE_U8, &vol, err);
    /* last brick first: a voxel two bricks share keeps the value of the lower brick, which
     * owns it (the encoder measures each voxel in its owner) */
    static const size_t whole[3] = {0, 0, 0};
    for (size_t b = st->info.nbricks; s == CDVR_OK && b-- > 0;)
        s = decode_brick_into(st, v, c0 + b, t, (uint8_t *)vol->data, st->info.dims, whole, err);
    if (s != CDVR_OK) {
        cdvr_volume_free(vol);
        return s;
    }
    memcpy(vol->spacing, st->info.spacing, sizeof vol->spacing);
    memcpy(vol->origin, st->info.origin, sizeof vol->origin);
    memcpy(vol->direction, st->info.direction, sizeof vol->direction);
    vol->window[0] = st->info.qlo; /* the codes 0..255 stand for the store's value window */
    vol->window[1] = st->info.qhi;
    *out = vol;
    return CDVR_OK;
}

cdvr_status cdvr_store_decode_brick(const cdvr_store *st, size_t v, size_t t, size_t b,
                                    cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    size_t c = cdvr_store_chunk_for(st, v, t, b);
    if (c == (size_t)-1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no brick %zu of timestep %zu in variant "
                              "%zu (%zu bricks, %zu timesteps, %zu variants)", st->path, b + 1,
                              t + 1, v + 1, st->info.nbricks, st->info.timesteps,
                              st->info.nvariants);
    size_t lo[3], bd[3];
    cdvr_store_brick_box(&st->info, b, lo, bd);
    cdvr_volume *vol = NULL;
    cdvr_status s = cdvr_volume_create(bd, 1, CDVR_TYPE_U8, &vol, err);
    if (s == CDVR_OK)
        s = decode_brick_into(st, v, c, t, (uint8_t *)vol->data, bd, lo, err);
    if (s != CDVR_OK) {
        cdvr_volume_free(vol);
        return s;
    }
    const double *D = st->info.direction;
    for (int r = 0; r < 3; r++) {
        vol->spacing[r] = st->info.spacing[r];
        vol->origin[r] = st->info.origin[r];
        for (int k = 0; k < 3; k++) /* origin + D * (lo * spacing) */
            vol->origin[r] += D[3 * r + k] * ((double)lo[k] * st->info.spacing[k]);
    }
    memcpy(vol->direction, D, sizeof vol->direction);
    vol->window[0] = st->info.qlo; /* the codes 0..255 stand for the store's value window */
    vol->window[1] = st->info.qhi;
    *out = vol;
    return CDVR_OK;
}
