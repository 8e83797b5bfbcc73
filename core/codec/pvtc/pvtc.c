/* core/codec/pvtc/pvtc.c - PVTC block codec family (DESIGN.md 4.1): chunk geometry, the reference
 * decoder (the OpenCL kernel must be bit-exact with it), the bbox encoder and the chunk
 * gather/scatter shared by both encoders. The least-squares encoder is in pvtc_lsq.c. */
#include "cdvr/pvtc.h"

#include <stdlib.h>
#include <string.h>

#include "pvtc_internal.h"

/* ---- parameters and geometry ------------------------------------------------------------ */

static const char *pack_name(cdvr_pack pack)
{
    return pack == CDVR_PACK_SPACE ? "space" : "time";
}

static cdvr_status check_params(const cdvr_pvtc_params *params, cdvr_error *err)
{
    if (!params)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc: params is NULL");
    if (params->S != 1 && params->S != 4)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc: S = %d, must be 1 or 4", params->S);
    if (params->T != 2 && params->T != 3)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc: T = %d, must be 2 or 3", params->T);
    if (params->pack != CDVR_PACK_TIME && params->pack != CDVR_PACK_SPACE)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc: pack = %d, must be time or space",
                              (int)params->pack);
    return CDVR_OK;
}

static size_t ceil_div(size_t n, size_t d)
{
    return n / d + (n % d != 0);
}

cdvr_status cdvr_pvtc_geometry_get(const cdvr_pvtc_params *params, const size_t dims[3],
                                   cdvr_pvtc_geometry *geom, cdvr_error *err)
{
    cdvr_status st = check_params(params, err);
    if (st != CDVR_OK)
        return st;
    if (!dims || !geom)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc: dims or geometry is NULL");
    if (dims[0] == 0 || dims[1] == 0 || dims[2] == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc S%dT%d %s: dims %zux%zux%zu have a zero",
                              params->S, params->T, pack_name(params->pack), dims[0], dims[1],
                              dims[2]);
    size_t voxels, zdepth = (size_t)params->S, block_bytes = 4 + 4 * (size_t)params->S;
    if (params->pack == CDVR_PACK_SPACE)
        zdepth *= (size_t)params->T;
    cdvr_pvtc_geometry g;
    g.blocks[0] = ceil_div(dims[0], 4);
    g.blocks[1] = ceil_div(dims[1], 4);
    g.blocks[2] = ceil_div(dims[2], zdepth);
    g.frames = params->pack == CDVR_PACK_TIME ? (size_t)params->T : 1;
    if (!cdvr_size_mul(dims[0], dims[1], &voxels) || !cdvr_size_mul(voxels, dims[2], &voxels) ||
        !cdvr_size_mul(g.blocks[0], g.blocks[1], &g.nblocks) ||
        !cdvr_size_mul(g.nblocks, g.blocks[2], &g.nblocks) ||
        !cdvr_size_mul(g.nblocks, block_bytes, &g.chunk_bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM,
                              "pvtc S%dT%d %s: dims %zux%zux%zu overflow size_t", params->S,
                              params->T, pack_name(params->pack), dims[0], dims[1], dims[2]);
    *geom = g;
    return CDVR_OK;
}

/* ---- endpoint and palette arithmetic ---------------------------------------------------- */

int pvtc_channel_bits(int T, int c)
{
    if (T == 2)
        return 8;
    return c == 1 ? 6 : 5;
}

int pvtc_expand(int bits, int q)
{
    if (bits == 5)
        return (q << 3) | (q >> 2);
    if (bits == 6)
        return (q << 2) | (q >> 4);
    return q;
}

int pvtc_quantize(int bits, int x)
{
    int max = (1 << bits) - 1;
    return (2 * x * max + 255) / 510;
}

void pvtc_palette(int a, int b, int pal[4])
{
    pal[0] = a;
    pal[1] = (2 * a + b + 1) / 3;
    pal[2] = (a + 2 * b + 1) / 3;
    pal[3] = b;
}

static void unpack_endpoints(int T, const uint8_t *ep, int a[3], int b[3])
{
    if (T == 2) {
        a[0] = ep[0];
        a[1] = ep[1];
        b[0] = ep[2];
        b[1] = ep[3];
        return;
    }
    unsigned u = (unsigned)ep[0] | (unsigned)ep[1] << 8;
    unsigned d = (unsigned)ep[2] | (unsigned)ep[3] << 8;
    a[0] = pvtc_expand(5, (int)(u >> 11));
    a[1] = pvtc_expand(6, (int)((u >> 5) & 63));
    a[2] = pvtc_expand(5, (int)(u & 31));
    b[0] = pvtc_expand(5, (int)(d >> 11));
    b[1] = pvtc_expand(6, (int)((d >> 5) & 63));
    b[2] = pvtc_expand(5, (int)(d & 31));
}

static void pack_endpoints(int T, const pvtc_code *code, uint8_t *ep)
{
    if (T == 2) {
        ep[0] = (uint8_t)code->qa[0];
        ep[1] = (uint8_t)code->qa[1];
        ep[2] = (uint8_t)code->qb[0];
        ep[3] = (uint8_t)code->qb[1];
        return;
    }
    unsigned u = (unsigned)(code->qa[0] << 11 | code->qa[1] << 5 | code->qa[2]);
    unsigned d = (unsigned)(code->qb[0] << 11 | code->qb[1] << 5 | code->qb[2]);
    ep[0] = (uint8_t)(u & 0xff);
    ep[1] = (uint8_t)(u >> 8);
    ep[2] = (uint8_t)(d & 0xff);
    ep[3] = (uint8_t)(d >> 8);
}

static uint32_t load_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void store_le32(uint8_t *p, uint32_t w)
{
    p[0] = (uint8_t)w;
    p[1] = (uint8_t)(w >> 8);
    p[2] = (uint8_t)(w >> 16);
    p[3] = (uint8_t)(w >> 24);
}

/* ---- block errors, index assignment, bbox encoder --------------------------------------- */

static void code_palettes(int T, const pvtc_code *code, int pal[3][4])
{
    for (int c = 0; c < T; c++) {
        int bits = pvtc_channel_bits(T, c);
        pvtc_palette(pvtc_expand(bits, code->qa[c]), pvtc_expand(bits, code->qb[c]), pal[c]);
    }
}

uint32_t pvtc_assign_indices(const pvtc_block *blk, pvtc_code *code)
{
    int pal[3][4] = {{0}};
    code_palettes(blk->T, code, pal);
    uint32_t total = 0;
    for (int i = 0; i < blk->npos; i++) {
        int best = 0, best_err = -1;
        for (int k = 0; k < 4; k++) {
            int e = 0;
            for (int c = 0; c < blk->T; c++) {
                int d = (int)blk->v[i][c] - pal[c][k];
                e += d * d;
            }
            if (best_err < 0 || e < best_err) {
                best_err = e;
                best = k;
            }
        }
        code->index[i] = (uint8_t)best;
        total += (uint32_t)best_err;
    }
    return total;
}

uint32_t pvtc_code_error(const pvtc_block *blk, const pvtc_code *code)
{
    int pal[3][4] = {{0}};
    code_palettes(blk->T, code, pal);
    uint32_t total = 0;
    for (int i = 0; i < blk->npos; i++)
        for (int c = 0; c < blk->T; c++) {
            int d = (int)blk->v[i][c] - pal[c][code->index[i]];
            total += (uint32_t)(d * d);
        }
    return total;
}

uint32_t pvtc_encode_block_bbox(const pvtc_block *blk, pvtc_code *code)
{
    for (int c = 0; c < blk->T; c++) {
        int hi = 0, lo = 255;
        for (int i = 0; i < blk->npos; i++) {
            if (blk->v[i][c] > hi)
                hi = blk->v[i][c];
            if (blk->v[i][c] < lo)
                lo = blk->v[i][c];
        }
        int bits = pvtc_channel_bits(blk->T, c);
        code->qa[c] = pvtc_quantize(bits, hi);
        code->qb[c] = pvtc_quantize(bits, lo);
    }
    return pvtc_assign_indices(blk, code);
}

/* ---- chunk layout ------------------------------------------------------------------------ */

/* Where the voxels of one chunk live: channel c of packed z position zp is slice
 * zslice(c, zp) of frame frame_of(c). */
typedef struct chunk_layout {
    size_t dims[3];
    size_t plane;   /* X * Y */
    int S, T, space;
    size_t zdepth;  /* voxel slices one block spans: S (time) or S*T (space) */
    cdvr_pvtc_geometry geom;
} chunk_layout;

static cdvr_status layout_init(const cdvr_pvtc_params *params, const size_t dims[3],
                               chunk_layout *lay, cdvr_error *err)
{
    cdvr_status st = cdvr_pvtc_geometry_get(params, dims, &lay->geom, err);
    if (st != CDVR_OK)
        return st;
    memcpy(lay->dims, dims, sizeof lay->dims);
    lay->plane = dims[0] * dims[1];
    lay->S = params->S;
    lay->T = params->T;
    lay->space = params->pack == CDVR_PACK_SPACE;
    lay->zdepth = (size_t)lay->S * (lay->space ? (size_t)lay->T : 1);
    return CDVR_OK;
}

/* Voxel slice of channel c at packed z position zp (may be >= Z: padding). */
static size_t channel_slice(const chunk_layout *lay, int c, size_t zp)
{
    return lay->space ? (size_t)lay->T * zp + (size_t)c : zp;
}

static size_t channel_frame(const chunk_layout *lay, int c)
{
    return lay->space ? 0 : (size_t)c;
}

/* ---- decoder ----------------------------------------------------------------------------- */

static void block_palettes(int T, const uint8_t *ep, uint8_t pal[3][4])
{
    int a[3], b[3], p[4];
    unpack_endpoints(T, ep, a, b);
    for (int c = 0; c < T; c++) {
        pvtc_palette(a[c], b[c], p);
        for (int k = 0; k < 4; k++)
            pal[c][k] = (uint8_t)p[k];
    }
}

/* Bytes of w broadcast to 8 lanes. */
#define LANES_01 UINT64_C(0x0101010101010101)

/* Spreads 8 2-bit indices (16 bits) into the 8 bytes of a word, index i in byte i. */
static uint64_t spread_indices(uint32_t bits16)
{
    uint64_t x = bits16;
    x = (x | (x << 24)) & UINT64_C(0x000000FF000000FF);
    x = (x | (x << 12)) & UINT64_C(0x000F000F000F000F);
    x = (x | (x << 6)) & UINT64_C(0x0303030303030303);
    return x;
}

static void store_row_pair(uint8_t *row, size_t stride, uint64_t v)
{
    store_le32(row, (uint32_t)v);
    store_le32(row + stride, (uint32_t)(v >> 32));
}

/* Interior block: every voxel is inside the volume. Two rows (8 voxels) at a time without
 * branches or tables: the index bits become byte masks once, shared by the T channels, and
 * each channel's palette is picked by three masked selects (SWAR on 64-bit words). */
static void decode_block_interior(const chunk_layout *lay, const uint8_t pal[3][4],
                                  const uint8_t *words, size_t x0, size_t y0, size_t zp0,
                                  uint8_t *const *frames, int nch)
{
    const size_t X = lay->dims[0];
    uint64_t bcast[3][4];
    for (int c = 0; c < nch; c++)
        for (int k = 0; k < 4; k++)
            bcast[c][k] = pal[c][k] * LANES_01;
    for (int zi = 0; zi < lay->S; zi++) {
        uint32_t w = load_le32(words + 4 * zi);
        for (int half = 0; half < 2; half++) {
            uint64_t idx = spread_indices((w >> (16 * half)) & 0xFFFF);
            uint64_t bit0 = (idx & LANES_01) * 0xFF, bit1 = ((idx >> 1) & LANES_01) * 0xFF;
            size_t y = y0 + 2 * (size_t)half;
            for (int c = 0; c < nch; c++) {
                const uint64_t *P = bcast[c];
                uint64_t lo = P[0] ^ ((P[0] ^ P[1]) & bit0);
                uint64_t hi = P[2] ^ ((P[2] ^ P[3]) & bit0);
                uint8_t *row = frames[channel_frame(lay, c)] +
                               lay->plane * channel_slice(lay, c, zp0 + (size_t)zi) + X * y + x0;
                store_row_pair(row, X, lo ^ ((lo ^ hi) & bit1));
            }
        }
    }
}

/* The reference decoder, one voxel at a time, cropping positions outside the volume
 * (padding): the readable definition that the faster paths must match bit for bit. */
static void decode_block_reference(const chunk_layout *lay, const uint8_t pal[3][4],
                                   const uint8_t *words, size_t x0, size_t y0, size_t zp0,
                                   uint8_t *const *frames, int nch)
{
    const size_t X = lay->dims[0], Y = lay->dims[1], Z = lay->dims[2];
    for (int zi = 0; zi < lay->S; zi++) {
        uint32_t w = load_le32(words + 4 * zi);
        for (int c = 0; c < nch; c++) {
            size_t slice = channel_slice(lay, c, zp0 + (size_t)zi);
            if (slice >= Z)
                continue;
            uint8_t *plane = frames[channel_frame(lay, c)] + lay->plane * slice;
            for (size_t y = 0; y < 4 && y0 + y < Y; y++)
                for (size_t x = 0; x < 4 && x0 + x < X; x++)
                    plane[X * (y0 + y) + x0 + x] = pal[c][(w >> (2 * (x + 4 * y))) & 3];
        }
    }
}

/* Destinations of block row (by, bz), whose voxel rows all lie inside the volume in y and z;
 * its first X / 4 blocks lie wholly inside. */
static void row_job_init(const chunk_layout *lay, const uint8_t *ep, const uint8_t *idx,
                         size_t by, size_t bz, uint8_t *const *frames, int nch,
                         pvtc_row_job *job)
{
    const size_t X = lay->dims[0];
    job->endpoints = ep;
    job->words = idx;
    job->stride = X;
    job->nblocks = X / 4;
    job->S = lay->S;
    job->T = lay->T;
    job->nch = nch;
    for (int zi = 0; zi < lay->S; zi++)
        for (int c = 0; c < nch; c++)
            job->dst[zi][c] = frames[channel_frame(lay, c)] +
                              lay->plane * channel_slice(lay, c, bz * (size_t)lay->S + (size_t)zi) +
                              X * 4 * by;
}

/* Advances job past its first n blocks (AVX2 leaves up to seven for SSSE3's groups of four). */
static void row_job_skip(pvtc_row_job *job, size_t n)
{
    job->endpoints += 4 * n;
    job->words += 4 * (size_t)job->S * n;
    job->nblocks -= n;
    for (int zi = 0; zi < job->S; zi++)
        for (int c = 0; c < job->nch; c++)
            job->dst[zi][c] += 4 * n;
}

/* Decodes one row of blocks (ep, idx: its first block) with the given path: blocks wholly
 * inside the volume go to the fast paths, the rest to the reference. */
static void decode_row(const chunk_layout *lay, const uint8_t *ep, const uint8_t *idx, size_t by,
                       size_t bz, uint8_t *const *frames, int nch, pvtc_decode_path path)
{
    const size_t idx_stride = 4 * (size_t)lay->S, y0 = 4 * by, zp0 = bz * (size_t)lay->S;
    size_t x_inside = 0, done = 0;
    if (path != PVTC_DECODE_REFERENCE && (bz + 1) * lay->zdepth <= lay->dims[2] &&
        y0 + 4 <= lay->dims[1]) {
        x_inside = lay->dims[0] / 4;
        if (path == PVTC_DECODE_SSSE3 || path == PVTC_DECODE_AVX2) {
            pvtc_row_job job;
            row_job_init(lay, ep, idx, by, bz, frames, nch, &job);
            done = path == PVTC_DECODE_AVX2 ? pvtc_decode_row_avx2(&job) : 0;
            row_job_skip(&job, done);
            done += pvtc_decode_row_ssse3(&job);
        }
    }
    uint8_t pal[3][4];
    for (size_t bx = done; bx < lay->geom.blocks[0]; bx++) {
        block_palettes(lay->T, ep + 4 * bx, pal);
        if (bx < x_inside)
            decode_block_interior(lay, pal, idx + idx_stride * bx, 4 * bx, y0, zp0, frames, nch);
        else
            decode_block_reference(lay, pal, idx + idx_stride * bx, 4 * bx, y0, zp0, frames,
                                   nch);
    }
}

static cdvr_status check_decode_args(const chunk_layout *lay, const cdvr_pvtc_params *params,
                                     const uint8_t *in, size_t in_bytes,
                                     uint8_t *const *frames, size_t nframes, cdvr_error *err)
{
    const char *pack = pack_name(params->pack);
    if (!in || !frames)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc S%dT%d %s decode: NULL input or frames",
                              params->S, params->T, pack);
    if (in_bytes != lay->geom.chunk_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT,
                              "pvtc S%dT%d %s decode: chunk has %zu bytes, dims %zux%zux%zu "
                              "need %zu", params->S, params->T, pack, in_bytes, lay->dims[0],
                              lay->dims[1], lay->dims[2], lay->geom.chunk_bytes);
    if (nframes < 1 || nframes > lay->geom.frames)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "pvtc S%dT%d %s decode: %zu frames requested, chunk holds %zu",
                              params->S, params->T, pack, nframes, lay->geom.frames);
    for (size_t f = 0; f < nframes; f++)
        if (!frames[f])
            return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc S%dT%d %s decode: frame %zu is NULL",
                                  params->S, params->T, pack, f);
    return CDVR_OK;
}

static cdvr_status resolve_path(pvtc_decode_path *path, cdvr_error *err)
{
    int ssse3 = pvtc_ssse3_available(), avx2 = ssse3 && pvtc_avx2_available();
    if (*path == PVTC_DECODE_AUTO)
        *path = avx2 ? PVTC_DECODE_AVX2 : ssse3 ? PVTC_DECODE_SSSE3 : PVTC_DECODE_PORTABLE;
    else if ((*path == PVTC_DECODE_SSSE3 && !ssse3) || (*path == PVTC_DECODE_AVX2 && !avx2))
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED,
                              "pvtc decode: the %s path is not available on this CPU or build",
                              *path == PVTC_DECODE_AVX2 ? "AVX2" : "SSSE3");
    else if (*path != PVTC_DECODE_REFERENCE && *path != PVTC_DECODE_PORTABLE &&
             *path != PVTC_DECODE_SSSE3 && *path != PVTC_DECODE_AVX2)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc decode: unknown path %d", (int)*path);
    return CDVR_OK;
}

cdvr_status pvtc_decode_chunk_path(const cdvr_pvtc_params *params, const size_t dims[3],
                                   const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                                   size_t nframes, pvtc_decode_path path, cdvr_error *err)
{
    chunk_layout lay;
    cdvr_status st = resolve_path(&path, err);
    if (st == CDVR_OK)
        st = layout_init(params, dims, &lay, err);
    if (st == CDVR_OK)
        st = check_decode_args(&lay, params, in, in_bytes, frames, nframes, err);
    if (st != CDVR_OK)
        return st;
    const int nch = lay.space ? lay.T : (int)nframes;
    const size_t *nb = lay.geom.blocks, row_idx_bytes = 4 * (size_t)lay.S * nb[0];
    const uint8_t *ep = in, *idx = in + 4 * lay.geom.nblocks;
    for (size_t bz = 0; bz < nb[2]; bz++)
        for (size_t by = 0; by < nb[1]; by++, ep += 4 * nb[0], idx += row_idx_bytes)
            decode_row(&lay, ep, idx, by, bz, frames, nch, path);
    return CDVR_OK;
}

cdvr_status cdvr_pvtc_decode_chunk(const cdvr_pvtc_params *params, const size_t dims[3],
                                   const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                                   size_t nframes, cdvr_error *err)
{
    return pvtc_decode_chunk_path(params, dims, in, in_bytes, frames, nframes, PVTC_DECODE_AUTO,
                                  err);
}

/* ---- encoder: gather, encode, scatter ---------------------------------------------------- */

static size_t clamp_index(size_t v, size_t n)
{
    return v < n ? v : n - 1;
}

/* Voxel slice that pads channel c at packed position zp. Packed positions past the last one
 * repeat it; inside a partly filled last position, a missing channel takes the same channel
 * one packed position back (slice - T), so padding never mixes channels of unrelated slices
 * into a block (the decoder crops padding, so any value is valid; this one costs least). */
static size_t padded_slice(const chunk_layout *lay, int c, size_t zp)
{
    const size_t Z = lay->dims[2], T = (size_t)lay->T;
    if (!lay->space)
        return clamp_index(zp, Z);
    size_t last = (Z - 1) / T;
    size_t slice = T * (zp < last ? zp : last) + (size_t)c;
    if (slice < Z)
        return slice;
    return last > 0 ? slice - T : Z - 1;
}

/* Gathers block (bx, by, bz) with edge replication in x, y and z. */
static void gather_block(const chunk_layout *lay, const uint8_t *const *frames, size_t bx,
                         size_t by, size_t bz, pvtc_block *blk)
{
    const size_t X = lay->dims[0], Y = lay->dims[1];
    blk->T = lay->T;
    blk->npos = 16 * lay->S;
    for (int zi = 0; zi < lay->S; zi++) {
        size_t zp = bz * (size_t)lay->S + (size_t)zi;
        for (int c = 0; c < lay->T; c++) {
            const uint8_t *plane = frames[channel_frame(lay, c)] +
                                   lay->plane * padded_slice(lay, c, zp);
            for (int y = 0; y < 4; y++) {
                const uint8_t *row = plane + X * clamp_index(4 * by + (size_t)y, Y);
                for (int x = 0; x < 4; x++)
                    blk->v[x + 4 * y + 16 * zi][c] = row[clamp_index(4 * bx + (size_t)x, X)];
            }
        }
    }
}

static void scatter_code(int T, int S, const pvtc_code *code, uint8_t *ep, uint8_t *words)
{
    pack_endpoints(T, code, ep);
    for (int zi = 0; zi < S; zi++) {
        uint32_t w = 0;
        for (int i = 0; i < 16; i++)
            w |= (uint32_t)code->index[16 * zi + i] << (2 * i);
        store_le32(words + 4 * zi, w);
    }
}

cdvr_status pvtc_encode_blocks(const cdvr_pvtc_params *params, cdvr_pvtc_encoder encoder,
                               const size_t dims[3], const uint8_t *const *frames,
                               size_t first, size_t count, uint8_t *out, cdvr_error *err)
{
    chunk_layout lay;
    cdvr_status st = layout_init(params, dims, &lay, err);
    if (st != CDVR_OK)
        return st;
    if (encoder != CDVR_ENCODER_LSQ && encoder != CDVR_ENCODER_BBOX)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc encode: unknown encoder %d", (int)encoder);
    if (!frames || !out)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc encode: NULL frames or output");
    if (first > lay.geom.nblocks || count > lay.geom.nblocks - first)
        return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc encode: blocks %zu+%zu of %zu", first,
                              count, lay.geom.nblocks);
    for (size_t f = 0; f < lay.geom.frames; f++)
        if (!frames[f])
            return cdvr_error_set(err, CDVR_ERR_ARG, "pvtc S%dT%d %s encode: frame %zu is NULL",
                                  params->S, params->T, pack_name(params->pack), f);
    const size_t *nb = lay.geom.blocks;
    uint8_t *ep = out + 4 * first, *idx = out + 4 * lay.geom.nblocks + 4 * (size_t)lay.S * first;
    pvtc_block blk;
    pvtc_code code;
    for (size_t b = first; b < first + count; b++, ep += 4, idx += 4 * (size_t)lay.S) {
        size_t bx = b % nb[0], by = b / nb[0] % nb[1], bz = b / (nb[0] * nb[1]);
        gather_block(&lay, frames, bx, by, bz, &blk);
        if (encoder == CDVR_ENCODER_BBOX)
            pvtc_encode_block_bbox(&blk, &code);
        else
            pvtc_encode_block_lsq(&blk, &code);
        scatter_code(lay.T, lay.S, &code, ep, idx);
    }
    return CDVR_OK;
}

cdvr_status cdvr_pvtc_encode_chunk(const cdvr_pvtc_params *params, cdvr_pvtc_encoder encoder,
                                   const size_t dims[3], const uint8_t *const *frames,
                                   uint8_t *out, cdvr_error *err)
{
    cdvr_pvtc_geometry g;
    cdvr_status st = cdvr_pvtc_geometry_get(params, dims, &g, err);
    if (st != CDVR_OK)
        return st;
    return pvtc_encode_blocks(params, encoder, dims, frames, 0, g.nblocks, out, err);
}
