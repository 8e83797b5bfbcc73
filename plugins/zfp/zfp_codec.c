/* plugins/zfp/zfp_codec.c - the "zfp" codec plugin: zfp 1.0 (LLNL; Debian libzfp-dev) in
 * fixed-rate mode on u8 volumes, one timestep per chunk, decoded on the CPU (cl_mode NONE:
 * the player uploads the decoded frame).
 *
 * Codec id 0x7A667000 = 2053533696 (the ASCII tag "zfp\0", below 2^31).
 *
 * Parameter: rate, bits per voxel, a multiple of 1/64 from 1/64 to 16 (zfp's fixed-rate step
 * in 3-D is one bit per 4x4x4 block; rates that are not a multiple are refused with the two
 * nearest). Default 2. Variant name "zfp" + rate printed with %.10g: zfp0.5, zfp1, zfp2, zfp4.
 * Parameter blob (little endian, unused bytes 0):
 *    0  u32  maxbits   bits per 4x4x4 block = 64 * rate, 1 .. 1024
 *    4  u32  zfp_codec the zfp stream format version the payload was written with
 *                      (zfp_codec_version, 5 for zfp 1.0); decode refuses another version
 *
 * Values (this is the definition; the C code below implements exactly it):
 *    in:  each u8 voxel v becomes the int32 i = (v - 128) * 2^23 (zfp's own u8 promotion,
 *         zfp_promote_uint8_to_int32), so the field spans [-2^30, 2^30) as zfp's integer
 *         path expects. int32 rather than float: no per-block exponent to pay for (9 of the
 *         32 bits of a block at rate 0.5), and zfp's integer path is pure integer arithmetic,
 *         so the decode is the same on every machine.
 *    out: the decoded int32 i gives v = clamp(floor((i + 2^22) / 2^23) + 128, 0, 255)
 *         (round half up, then clamp; zfp's zfp_demote_int32_to_uint8 truncates instead,
 *         which would bias every voxel by -1/2 on average).
 * Payload: the field of dims X x Y x Z (x fastest) compressed as zfp_compress does in serial
 * fixed-rate mode with zfp_stream_set_rate(rate, zfp_type_int32, 3, no alignment): 4x4x4
 * blocks in x, then y, then z order, partial blocks padded by zfp, each block exactly maxbits
 * bits, no zfp header. zfp's bit stream fills each byte from its least significant bit, so
 * the payload is those nblocks * maxbits bits, LSB first, in ceil(nblocks * maxbits / 8)
 * bytes (zero padding bits at the end): exactly what Debian's zfp (8-bit stream words)
 * writes. A zfp built with wider stream words writes the same bytes on a little-endian host
 * plus padding to its word; this plugin trims or pads it and swaps bytes on big-endian hosts,
 * so stores are the same everywhere. The bound the encoder allocates is zfp's own
 * zfp_stream_maximum_size for the field. Decode refuses a payload of any other size
 * (CDVR_ERR_CORRUPT); any bits of the right size decode to some volume (zfp reads exactly
 * nblocks * maxbits bits, values are clamped).
 *
 * Error behaviour: fixed rate, so the error depends on the data. A higher rate keeps a longer
 * prefix of each block's embedded bit-plane code, so from rate 0.5 up the error shrinks as the
 * rate grows (tests/test_codec.c checks 0.5 < 1 < 2 < 4). Below about 0.25 a block keeps only
 * the top bit planes of its coefficients (negabinary), whose truncation can overshoot: there
 * the error is not monotone in the rate (rate 1/64 decodes everything to 128, which may beat
 * 1/32). Constant 4x4x4 blocks decode exactly at rate >= 0.5 (not below). Noise needs about
 * 16 bits per voxel to come back exactly; nothing guarantees losslessness at any rate.
 *
 * Threads: every function works on its own zfp_stream and buffers; zfp's serial code keeps no
 * global state, so chunks may be encoded and decoded in parallel. One chunk is decoded on
 * several threads too: fixed rate puts block k at bit k * maxbits, so each thread opens its
 * own zfp stream on the (read-only) payload, takes z block rows in turn, seeks to each row's
 * first block (stream_rseek) and decodes it into its own part of the frame: the same bytes as
 * the serial decode for any thread count. decode_cells (codec.h) seeks past the blocks that
 * meet no needed cell the same way. Threads: CDVR_ZFP_THREADS when set to a number > 0
 * (at most one per z block row), else one per online core, each given at least 4096 blocks
 * (smaller frames decode on the calling thread). Encode stays serial (the encode pool runs
 * chunks in parallel).
 */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <zfp.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "cdvr/plugin.h"

#define ZFP_CODEC_ID 0x7A667000u
#define MAXBITS_MAX 1024u /* rate 16 */
#define SHIFT 23          /* i = (v - 128) << SHIFT */

enum { OFF_MAXBITS = 0, OFF_ZFP_CODEC = 4, USED_BYTES = 8 };

static const cdvr_codec_param_doc zfp_params[] = {
    {"rate", "2", "bits per voxel, a multiple of 1/64 from 1/64 to 16 (zfp fixed-rate mode)"},
    {NULL, NULL, NULL}};

static void zfpc_default(cdvr_codec_params *p)
{
    memset(p, 0, sizeof *p);
    cdvr_params_set_u32(p, OFF_MAXBITS, 2 * 64);
    cdvr_params_set_u32(p, OFF_ZFP_CODEC, (uint32_t)zfp_codec_version);
}

static cdvr_status zfpc_set(cdvr_codec_params *p, const char *key, const char *value,
                            cdvr_error *err)
{
    if (strcmp(key, "rate") != 0)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: unknown parameter '%s' "
                                 "(parameters: rate)", key);
    char *end;
    double rate = strtod(value, &end);
    if (!*value || *end || !isfinite(rate) || rate < 1.0 / 64 || rate > MAXBITS_MAX / 64.0)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: rate = '%s', must be a number "
                                 "of bits per voxel from 1/64 (0.015625) to %g", value,
                                 MAXBITS_MAX / 64.0);
    double bits = rate * 64;
    if (bits != floor(bits)) {
        double lo = floor(bits) / 64, hi = ceil(bits) / 64;
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: rate = '%s' is not a multiple "
                                 "of 1/64 (zfp's fixed-rate step in 3-D); nearest: %.10g or "
                                 "%.10g", value, lo < 1.0 / 64 ? hi : lo, hi);
    }
    cdvr_params_set_u32(p, OFF_MAXBITS, (uint32_t)bits);
    return CDVR_OK;
}

static int zfpc_get(const cdvr_codec_params *p, const char *key, char *out, size_t n)
{
    if (strcmp(key, "rate") != 0)
        return -1;
    snprintf(out, n, "%.10g", cdvr_params_get_u32(p, OFF_MAXBITS) / 64.0);
    return 0;
}

static cdvr_status zfpc_check(const cdvr_codec_params *p, cdvr_error *err)
{
    uint32_t maxbits = cdvr_params_get_u32(p, OFF_MAXBITS);
    uint32_t version = cdvr_params_get_u32(p, OFF_ZFP_CODEC);
    if (maxbits < 1 || maxbits > MAXBITS_MAX)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: %u bits per block (rate %g) is "
                                 "outside 1..%u", maxbits, maxbits / 64.0, MAXBITS_MAX);
    if (version != zfp_codec_version)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: data written with zfp stream "
                                 "format %u, this zfp (%s) reads format %u", version,
                                 zfp_version_string, zfp_codec_version);
    if (stream_word_bits != 8 && stream_word_bits != 16 && stream_word_bits != 32 &&
        stream_word_bits != 64)
        return cdvr_plugin_error(err, CDVR_ERR_UNSUPPORTED, "codec zfp: this zfp was built with "
                                 "%zu-bit stream words (8, 16, 32 or 64 supported)",
                                 stream_word_bits);
    for (size_t i = USED_BYTES; i < CDVR_CODEC_PARAMS_MAX; i++)
        if (p->bytes[i])
            return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: unused parameter byte %zu "
                                     "is %u", i, p->bytes[i]);
    return CDVR_OK;
}

static void zfpc_name(const cdvr_codec_params *p, char *name, size_t n)
{
    snprintf(name, n, "zfp%.10g", cdvr_params_get_u32(p, OFF_MAXBITS) / 64.0);
}

/* ---- geometry ------------------------------------------------------------------------------ */

typedef struct zfpc_geometry {
    size_t blocks[3];
    size_t nblocks;
    size_t payload_bytes;  /* ceil(nblocks * maxbits / 8) */
    size_t stream_bytes;   /* what zfp reads or writes: payload rounded up to its word */
    unsigned maxbits;
} zfpc_geometry;

static int mul_ok(size_t a, size_t b, size_t *out)
{
    if (a && b > SIZE_MAX / a)
        return 0;
    *out = a * b;
    return 1;
}

static cdvr_status geometry(const cdvr_codec_params *p, const size_t dims[3], zfpc_geometry *g,
                            cdvr_error *err)
{
    cdvr_status s = zfpc_check(p, err);
    if (s != CDVR_OK)
        return s;
    g->maxbits = cdvr_params_get_u32(p, OFF_MAXBITS);
    size_t n = 1, bits;
    for (int a = 0; a < 3; a++) {
        if (dims[a] < 1)
            return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: dims %zux%zux%zu", dims[0],
                                     dims[1], dims[2]);
        g->blocks[a] = dims[a] / 4 + (dims[a] % 4 != 0);
        if (!mul_ok(n, g->blocks[a], &n))
            n = SIZE_MAX; /* caught below */
    }
    /* With room for what zfp_stream_maximum_size adds: header bits, rounding to a word. */
    if (n == SIZE_MAX || !mul_ok(n, g->maxbits, &bits) || bits > SIZE_MAX - 4096)
        return cdvr_plugin_error(err, CDVR_ERR_NOMEM, "codec zfp: dims %zux%zux%zu overflow "
                                 "size_t", dims[0], dims[1], dims[2]);
    g->nblocks = n;
    g->payload_bytes = (bits + 7) / 8;
    g->stream_bytes = (bits + stream_word_bits - 1) / stream_word_bits * (stream_word_bits / 8);
    return CDVR_OK;
}

/* A zfp stream in fixed-rate mode for int32 3-D blocks of maxbits bits, not yet attached to a
 * bit stream; NULL when out of memory. */
static zfp_stream *open_stream(unsigned maxbits)
{
    zfp_stream *zfp = zfp_stream_open(NULL);
    if (!zfp)
        return NULL;
    double rate = zfp_stream_set_rate(zfp, maxbits / 64.0, zfp_type_int32, 3, zfp_false);
    if (rate != maxbits / 64.0) { /* cannot happen for maxbits in 1..1024 */
        zfp_stream_close(zfp);
        return NULL;
    }
    return zfp;
}

static cdvr_status zfpc_shape(const cdvr_codec_params *p, const size_t dims[3],
                              cdvr_codec_shape *out, cdvr_error *err)
{
    zfpc_geometry g;
    cdvr_status s = geometry(p, dims, &g, err);
    if (s != CDVR_OK)
        return s;
    zfp_stream *zfp = open_stream(g.maxbits);
    zfp_field *field = zfp_field_3d(NULL, zfp_type_int32, dims[0], dims[1], dims[2]);
    if (!zfp || !field) {
        zfp_stream_close(zfp);
        zfp_field_free(field);
        return cdvr_plugin_error(err, CDVR_ERR_NOMEM, "codec zfp: out of memory");
    }
    out->timesteps = 1;
    out->payload_bytes = g.payload_bytes;
    out->bound_bytes = zfp_stream_maximum_size(zfp, field);
    if (out->bound_bytes < g.payload_bytes) /* never with zfp 1.0: it adds the header bits */
        out->bound_bytes = g.payload_bytes;
    zfp_field_free(field);
    zfp_stream_close(zfp);
    return CDVR_OK;
}

/* ---- the payload against zfp's stream words -------------------------------------------------
 * zfp reads and writes whole native words of stream_word_bits (8 on Debian). With wider words
 * the payload goes through a copy: aligned, padded to a whole word, bytes swapped within each
 * word on a big-endian host. */

static int host_little_endian(void)
{
    const uint16_t one = 1;
    uint8_t first;
    memcpy(&first, &one, 1);
    return first == 1;
}

static int needs_copy(const zfpc_geometry *g, const void *p)
{
    size_t word = stream_word_bits / 8;
    return word > 1 && (g->stream_bytes != g->payload_bytes || (uintptr_t)p % word != 0 ||
                        !host_little_endian());
}

/* Byte i of the payload is byte stream_index(i) of zfp's word buffer: the same on a
 * little-endian host, mirrored inside its word on a big-endian one. */
static size_t stream_index(size_t i)
{
    size_t word = stream_word_bits / 8;
    return host_little_endian() ? i : i - i % word + (word - 1 - i % word);
}

/* ---- encode and decode --------------------------------------------------------------------- */

/* Block extent along one axis: 4, or what is left at the edge. */
static size_t extent(size_t dim, size_t block)
{
    size_t left = dim - 4 * block;
    return left < 4 ? left : 4;
}

static void encode_blocks(zfp_stream *zfp, const zfpc_geometry *g, const size_t dims[3],
                          const uint8_t *frame)
{
    const size_t X = dims[0], XY = dims[0] * dims[1];
    int32_t blk[64];
    for (size_t bz = 0; bz < g->blocks[2]; bz++)
        for (size_t by = 0; by < g->blocks[1]; by++)
            for (size_t bx = 0; bx < g->blocks[0]; bx++) {
                size_t nx = extent(dims[0], bx), ny = extent(dims[1], by);
                size_t nz = extent(dims[2], bz);
                const uint8_t *src = frame + 4 * bx + X * 4 * by + XY * 4 * bz;
                for (size_t z = 0; z < nz; z++)
                    for (size_t y = 0; y < ny; y++)
                        for (size_t x = 0; x < nx; x++)
                            blk[x + 4 * y + 16 * z] =
                                ((int32_t)src[x + X * y + XY * z] - 128) * (1 << SHIFT);
                if (nx == 4 && ny == 4 && nz == 4)
                    zfp_encode_block_int32_3(zfp, blk);
                else
                    zfp_encode_partial_block_strided_int32_3(zfp, blk, nx, ny, nz, 1, 4, 16);
            }
}

/* The definition of the way back: clamp(floor((i + 2^22) / 2^23) + 128, 0, 255), in 32 bits
 * (block_to_u8 does it 16 at a time): u = i + 2^31 as unsigned, floor(u / 2^22) =
 * floor(i / 2^22) + 512, and floor((floor(a) + 1) / 2) = floor((a + 1) / 2) for any real a,
 * so ((u >> 22) + 1) >> 1 is floor((i + 2^22) / 2^23) + 256. Equal to the 64-bit form
 * (i + 2^22 + 2^31) >> 23, minus 128, at every int32 (checked over all 2^32). */
static uint8_t to_u8(int32_t i)
{
    int v = (int)(((((uint32_t)i ^ 0x80000000u) >> (SHIFT - 1)) + 1) >> 1) - 128;
    return (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
}

/* to_u8 of the block's 64 values into out. With SSE2: 16 at a time, to_u8's shifts in 32-bit
 * lanes give floor((i + 2^22) / 2^23) + 256 in 0 .. 512, less 256 - 128 that is -128 .. 384,
 * which packs to 16 bits without saturating; the pack to unsigned bytes then is the clamp.
 * The same byte as to_u8 for every int32 (checked over all 2^32), at 24 against 42 ns per
 * block (the compiler's own vectorisation of to_u8 emulates the clamp with compares). */
static void block_to_u8(const int32_t blk[64], uint8_t out[64])
{
#ifdef __SSE2__
    const __m128i sign = _mm_set1_epi32((int)0x80000000u), one = _mm_set1_epi32(1);
    const __m128i bias = _mm_set1_epi32(128);
    for (int q = 0; q < 4; q++) {
        __m128i v[4];
        for (int k = 0; k < 4; k++) {
            __m128i x = _mm_loadu_si128((const __m128i *)(blk + 16 * q + 4 * k));
            x = _mm_srli_epi32(_mm_xor_si128(x, sign), SHIFT - 1);
            v[k] = _mm_sub_epi32(_mm_srli_epi32(_mm_add_epi32(x, one), 1), bias);
        }
        __m128i words = _mm_packus_epi16(_mm_packs_epi32(v[0], v[1]), _mm_packs_epi32(v[2], v[3]));
        _mm_storeu_si128((__m128i *)(out + 16 * q), words);
    }
#else
    for (size_t k = 0; k < 64; k++)
        out[k] = to_u8(blk[k]);
#endif
}

/* A whole decoded block into the frame at dst (rows of X, slices of XY): constant bounds,
 * so the copies unroll (a fifth of the decode's time went to the general copy below). */
static void store_block(const int32_t blk[64], uint8_t *dst, size_t X, size_t XY)
{
    uint8_t v[64];
    block_to_u8(blk, v);
    for (size_t z = 0; z < 4; z++)
        for (size_t y = 0; y < 4; y++)
            memcpy(dst + X * y + XY * z, v + 4 * y + 16 * z, 4);
}

/* A whole decoded block as the tile at dst (codec.h, CDVR_LAYOUT_TILED: the block's own
 * order). */
static void store_tile(const int32_t blk[64], uint8_t *dst)
{
    block_to_u8(blk, dst);
}

/* Decodes z block row bz (all of it, or with cells the blocks that meet a needed cell),
 * seeking the stream to each block that follows a skipped one (fixed rate: block k starts at
 * bit k * maxbits). */
static void decode_row(zfp_stream *zfp, const zfpc_geometry *g, const size_t dims[3],
                       uint8_t *frame, unsigned layout, size_t bz, const cdvr_cells *cells)
{
    const size_t X = dims[0], XY = dims[0] * dims[1];
    int32_t blk[64];
    bitstream *bs = zfp_stream_bit_stream(zfp);
    size_t k = bz * g->blocks[0] * g->blocks[1]; /* the block's index in the stream */
    stream_rseek(bs, (bitstream_offset)k * g->maxbits);
    int positioned = 1; /* the stream is at block k */
    for (size_t by = 0; by < g->blocks[1]; by++)
        for (size_t bx = 0; bx < g->blocks[0]; bx++, k++) {
            size_t at[3] = {4 * bx, 4 * by, 4 * bz};
            size_t n[3] = {extent(dims[0], bx), extent(dims[1], by), extent(dims[2], bz)};
            if (cells && !cdvr_cells_meet(cells, at, n)) {
                positioned = 0;
                continue;
            }
            if (!positioned)
                stream_rseek(bs, (bitstream_offset)k * g->maxbits);
            positioned = 1;
            if (n[0] == 4 && n[1] == 4 && n[2] == 4) { /* the hot cases, converted in place */
                zfp_decode_block_int32_3(zfp, blk);
                if (layout == CDVR_LAYOUT_LINEAR)
                    store_block(blk, frame + 4 * bx + X * 4 * by + XY * 4 * bz, X, XY);
                else
                    store_tile(blk, frame + cdvr_tiled_offset(dims, at[0], at[1], at[2]));
                continue;
            }
            /* a block cut by the frame's edge (the values past it: 0, never stored) */
            memset(blk, 0, sizeof blk);
            zfp_decode_partial_block_strided_int32_3(zfp, blk, n[0], n[1], n[2], 1, 4, 16);
            uint8_t vals[64];
            for (size_t i = 0; i < 64; i++)
                vals[i] = to_u8(blk[i]);
            cdvr_block_store(frame, dims, layout, at, n, vals);
        }
}

/* Attaches a bit stream over buf (bytes, a multiple of 8) to a new fixed-rate zfp stream. */
static zfp_stream *open_on(unsigned maxbits, void *buf, size_t bytes, bitstream **bs)
{
    zfp_stream *zfp = open_stream(maxbits);
    *bs = zfp ? stream_open(buf, bytes) : NULL;
    if (!*bs) {
        zfp_stream_close(zfp);
        return NULL;
    }
    zfp_stream_set_bit_stream(zfp, *bs);
    zfp_stream_rewind(zfp);
    return zfp;
}

/* ---- parallel decode ------------------------------------------------------------------------ */

#define MAX_DECODE_THREADS 64
#define MIN_BLOCKS_PER_THREAD 4096

typedef struct row_job {
    const zfpc_geometry *g;
    const size_t *dims;
    uint8_t *buf, *frame;
    unsigned layout;         /* codec.h: CDVR_LAYOUT_LINEAR or CDVR_LAYOUT_TILED */
    const cdvr_cells *cells; /* NULL: every block */
    atomic_size_t *next_row; /* shared: the next z block row to take */
    int ok;
} row_job;

/* One decode thread: its own zfp stream on the payload, z block rows taken in turn from the
 * shared counter until none are left (rows differ in cost when only some blocks are
 * needed). */
static void *row_main(void *arg)
{
    row_job *j = arg;
    bitstream *bs = NULL;
    zfp_stream *zfp = open_on(j->g->maxbits, j->buf, j->g->stream_bytes, &bs);
    j->ok = zfp != NULL;
    for (size_t bz; zfp && (bz = atomic_fetch_add(j->next_row, 1)) < j->g->blocks[2];)
        decode_row(zfp, j->g, j->dims, j->frame, j->layout, bz, j->cells);
    zfp_stream_close(zfp);
    stream_close(bs);
    return NULL;
}

static size_t decode_threads(const zfpc_geometry *g)
{
    size_t rows = g->blocks[2], n = 0;
    const char *env = getenv("CDVR_ZFP_THREADS");
    char *end = NULL;
    long e = env ? strtol(env, &end, 10) : 0;
    if (env && end != env && *end == '\0' && e > 0) {
        n = (size_t)e;
    } else {
        long c = sysconf(_SC_NPROCESSORS_ONLN);
        size_t blocks = g->blocks[0] * g->blocks[1] * rows;
        n = c > 0 ? (size_t)c : 1;
        if (n > blocks / MIN_BLOCKS_PER_THREAD)
            n = blocks / MIN_BLOCKS_PER_THREAD;
    }
    n = n > rows ? rows : n;
    n = n > MAX_DECODE_THREADS ? MAX_DECODE_THREADS : n;
    return n ? n : 1;
}

/* Decodes the payload buf (the blocks that meet a needed cell, or all when cells is NULL) into
 * frame on decode_threads() threads; 0 when out of memory. */
static int decode_parallel(const zfpc_geometry *g, const size_t dims[3], uint8_t *buf,
                           uint8_t *frame, unsigned layout, const cdvr_cells *cells)
{
    size_t nt = decode_threads(g), started = 1;
    atomic_size_t next_row;
    atomic_init(&next_row, 0);
    row_job jobs[MAX_DECODE_THREADS];
    pthread_t tids[MAX_DECODE_THREADS];
    for (size_t k = 0; k < nt; k++)
        jobs[k] = (row_job){g, dims, buf, frame, layout, cells, &next_row, 0};
    for (size_t k = 1; k < nt; k++) {
        if (pthread_create(&tids[k], NULL, row_main, &jobs[k]) != 0)
            break;
        started++;
    }
    row_main(&jobs[0]); /* the caller too: it also takes what no thread started for */
    int ok = jobs[0].ok;
    for (size_t k = 1; k < started; k++) {
        pthread_join(tids[k], NULL);
        ok &= jobs[k].ok;
    }
    return ok;
}

static cdvr_status zfpc_encode(const cdvr_codec_params *p, const size_t dims[3],
                               const uint8_t *const *frames, size_t count, uint8_t *out,
                               size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    zfpc_geometry g;
    cdvr_status s = geometry(p, dims, &g, err);
    if (s != CDVR_OK)
        return s;
    if (count != 1 || out_cap < g.payload_bytes)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: %zu frames into %zu bytes (1 "
                                 "frame, %zu bytes expected)", count, out_cap, g.payload_bytes);
    int copy = needs_copy(&g, out);
    uint8_t *buf = copy ? malloc(g.stream_bytes) : out;
    bitstream *bs = NULL;
    zfp_stream *zfp = buf ? open_on(g.maxbits, buf, g.stream_bytes, &bs) : NULL;
    if (!zfp) {
        if (copy)
            free(buf);
        return cdvr_plugin_error(err, CDVR_ERR_NOMEM, "codec zfp: out of memory");
    }
    encode_blocks(zfp, &g, dims, frames[0]);
    zfp_stream_flush(zfp);
    size_t written = zfp_stream_compressed_size(zfp);
    zfp_stream_close(zfp);
    stream_close(bs);
    if (copy) {
        for (size_t i = 0; i < g.payload_bytes; i++)
            out[i] = buf[stream_index(i)];
        free(buf);
    }
    if (written != g.stream_bytes) /* zfp broke fixed-rate mode: never with zfp 1.0 */
        return cdvr_plugin_error(err, CDVR_ERR_UNSUPPORTED, "codec zfp: zfp wrote %zu bytes, "
                                 "fixed rate needs %zu", written, g.stream_bytes);
    *out_bytes = g.payload_bytes;
    return CDVR_OK;
}

/* decode and decode_cells (cells NULL: the whole frame). */
static cdvr_status decode_frame(const cdvr_codec_params *p, const size_t dims[3],
                                const uint8_t *in, size_t in_bytes, uint8_t *frame,
                                unsigned layout, const cdvr_cells *cells, cdvr_error *err)
{
    zfpc_geometry g;
    cdvr_status s = geometry(p, dims, &g, err);
    if (s != CDVR_OK)
        return s;
    if (in_bytes != g.payload_bytes)
        return cdvr_plugin_error(err, CDVR_ERR_CORRUPT, "codec zfp: chunk of %zu bytes, rate %g "
                                 "on %zux%zux%zu needs %zu", in_bytes, g.maxbits / 64.0,
                                 dims[0], dims[1], dims[2], g.payload_bytes);
    int copy = needs_copy(&g, in);
    uint8_t *buf = copy ? calloc(1, g.stream_bytes) : (uint8_t *)(uintptr_t)in;
    for (size_t i = 0; copy && buf && i < in_bytes; i++)
        buf[stream_index(i)] = in[i];
    int ok = buf && decode_parallel(&g, dims, buf, frame, layout, cells);
    if (copy)
        free(buf);
    return ok ? CDVR_OK : cdvr_plugin_error(err, CDVR_ERR_NOMEM, "codec zfp: out of memory");
}

static cdvr_status zfpc_decode(const cdvr_codec_params *p, const size_t dims[3],
                               const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                               size_t count, cdvr_error *err)
{
    if (count != 1)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: %zu frames asked of a chunk of "
                                 "1", count);
    return decode_frame(p, dims, in, in_bytes, frames[0], CDVR_LAYOUT_LINEAR, NULL, err);
}

/* Only the blocks that hold a voxel of a needed cell (a skipped block's voxels keep what the
 * frame held). */
static cdvr_status zfpc_decode_cells(const cdvr_codec_params *p, const size_t dims[3],
                                     const uint8_t *in, size_t in_bytes, uint8_t *frame,
                                     unsigned layout, const uint8_t *need, unsigned cell_log2,
                                     cdvr_error *err)
{
    if (cell_log2 > 30 || (layout != CDVR_LAYOUT_LINEAR && layout != CDVR_LAYOUT_TILED))
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec zfp: cells of 2^%u voxels, layout %u",
                                 cell_log2, layout);
    cdvr_cells cells = cdvr_cells_of(need, cell_log2, dims);
    return decode_frame(p, dims, in, in_bytes, frame, layout, &cells, err);
}

static const cdvr_codec zfp_codec = {
    .name = "zfp",
    .id = ZFP_CODEC_ID,
    .description = "zfp " ZFP_VERSION_STRING " fixed-rate (plugin): u8 as int32, 4x4x4 blocks of "
                   "64*rate bits, one timestep per chunk, CPU decode",
    .params = zfp_params,
    .params_default = zfpc_default,
    .params_set = zfpc_set,
    .params_get = zfpc_get,
    .params_check = zfpc_check,
    .variant_name = zfpc_name,
    .shape = zfpc_shape,
    .encode = zfpc_encode,
    .decode = zfpc_decode,
    .cl_mode = CDVR_CODEC_CL_NONE,
    .decode_cells = zfpc_decode_cells,
    .decodes_in_parallel = 1,
};

static const cdvr_plugin_info zfp_plugin = {.abi = CDVR_PLUGIN_ABI, .codec = &zfp_codec};

CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void);
CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void)
{
    return &zfp_plugin;
}
