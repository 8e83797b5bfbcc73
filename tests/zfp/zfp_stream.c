/* tests/zfp/zfp_stream.c - the zfp plugin's payload and values are what its header comment
 * (plugins/zfp/zfp_codec.c) defines, checked against zfp's own high-level API: the payload is
 * byte for byte zfp_compress's headerless fixed-rate stream of the int32 field
 * (v - 128) * 2^23, trimmed to ceil(bits / 8) bytes, and decoding gives zfp_decompress's
 * int32 values mapped by clamp(floor((i + 2^22) / 2^23) + 128, 0, 255). Built only with the
 * zfp plugin (the top-level CMakeLists.txt links it to libzfp). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <zfp.h>

#include "cdvr/codec.h"
#include "cdvr/plugin.h"
#include "check.h"

static uint8_t reference_u8(int32_t i)
{
    int64_t v = ((int64_t)i + (1 << 22)) / (1 << 23); /* truncates toward zero ... */
    if ((int64_t)i + (1 << 22) < 0 && ((int64_t)i + (1 << 22)) % (1 << 23) != 0)
        v -= 1;                                         /* ... so step down to the floor */
    v += 128;
    return (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
}

/* The plugin's payload of frame v at rate (a new buffer; *p its parameters, *bytes its size;
 * *bound the shape's bound). */
static uint8_t *encode_frame(const cdvr_codec *zfp, const char *rate, const size_t dims[3],
                             const uint8_t *v, cdvr_codec_params *p, size_t *bytes, size_t *bound)
{
    cdvr_codec_shape shape;
    cdvr_error err;
    const char *k[1] = {"rate"}, *val[1] = {rate};
    CHECK_OK(cdvr_codec_params_parse(zfp, k, val, 1, p, &err), err);
    CHECK_OK(cdvr_codec_shape_of(zfp, p, dims, &shape, &err), err);
    uint8_t *payload = malloc(shape.bound_bytes);
    const uint8_t *in[1] = {v};
    *bytes = 0;
    *bound = shape.bound_bytes;
    CHECK_OK(zfp->encode(p, dims, in, 1, payload, shape.bound_bytes, bytes, &err), err);
    return payload;
}

static void check_one(const cdvr_codec *zfp, const char *rate, const size_t dims[3], int pattern)
{
    size_t n = dims[0] * dims[1] * dims[2];
    uint8_t *v = malloc(n), *mine = malloc(n);
    int32_t *field = malloc(n * sizeof *field), *back = malloc(n * sizeof *back);
    uint32_t h = 12345u + (uint32_t)pattern;
    for (size_t i = 0; i < n; i++) {
        h ^= h << 13, h ^= h >> 17, h ^= h << 5;
        v[i] = pattern == 0 ? (uint8_t)h : pattern == 1 ? (uint8_t)(i * 3 + i / dims[0]) : 0;
        field[i] = ((int32_t)v[i] - 128) * (1 << 23);
    }
    /* zfp's way */
    zfp_field *f = zfp_field_3d(field, zfp_type_int32, dims[0], dims[1], dims[2]);
    zfp_field *g = zfp_field_3d(back, zfp_type_int32, dims[0], dims[1], dims[2]);
    zfp_stream *zs = zfp_stream_open(NULL);
    zfp_stream_set_rate(zs, atof(rate), zfp_type_int32, 3, zfp_false);
    size_t cap = zfp_stream_maximum_size(zs, f);
    uint8_t *ref = calloc(1, cap);
    bitstream *bs = stream_open(ref, cap);
    zfp_stream_set_bit_stream(zs, bs);
    zfp_stream_rewind(zs);
    size_t ref_bytes = zfp_compress(zs, f);
    zfp_stream_rewind(zs);
    size_t ok_dec = zfp_decompress(zs, g);
    /* the plugin's way, through the codec table */
    cdvr_codec_params p;
    cdvr_error err;
    size_t bytes, bound;
    uint8_t *payload = encode_frame(zfp, rate, dims, v, &p, &bytes, &bound);
    uint8_t *out[1] = {mine};
    CHECK_OK(zfp->decode(&p, dims, payload, bytes, out, 1, &err), err);
    CHECK(cap == bound, "bound %zu, zfp_stream_maximum_size %zu", bound, cap);
    CHECK(ok_dec && bytes <= ref_bytes && ref_bytes - bytes < stream_word_bits / 8 + 1 &&
              memcmp(payload, ref, bytes) == 0,
          "rate %s %zux%zux%zu pattern %d: payload (%zu bytes) is not zfp_compress's (%zu)", rate,
          dims[0], dims[1], dims[2], pattern, bytes, ref_bytes);
    for (size_t i = bytes; i < ref_bytes; i++)
        CHECK(ref[i] == 0, "zfp padding byte %zu is %u", i, ref[i]);
    size_t differ = 0;
    for (size_t i = 0; i < n; i++)
        differ += mine[i] != reference_u8(back[i]);
    CHECK(differ == 0, "rate %s %zux%zux%zu pattern %d: %zu voxels differ from zfp_decompress + "
          "the documented mapping", rate, dims[0], dims[1], dims[2], pattern, differ);
    stream_close(bs);
    zfp_stream_close(zs);
    zfp_field_free(f);
    zfp_field_free(g);
    free(ref);
    free(payload);
    free(v);
    free(mine);
    free(field);
    free(back);
}

/* The decode on several threads (slabs of z block rows, each seeking to its first block) gives
 * the serial decode's bytes, for rates whose blocks end inside a byte too. */
static void check_parallel(const cdvr_codec *zfp, const char *rate, const size_t dims[3])
{
    size_t n = dims[0] * dims[1] * dims[2];
    uint8_t *v = malloc(n), *serial = malloc(n), *par = malloc(n);
    uint32_t h = 777u;
    for (size_t i = 0; i < n; i++) {
        h ^= h << 13, h ^= h >> 17, h ^= h << 5;
        v[i] = (uint8_t)((i % dims[0]) * 5 + (h & 15));
    }
    cdvr_codec_params p;
    cdvr_error err;
    size_t bytes, bound;
    uint8_t *payload = encode_frame(zfp, rate, dims, v, &p, &bytes, &bound);
    uint8_t *out[1] = {serial};
    setenv("CDVR_ZFP_THREADS", "1", 1);
    CHECK_OK(zfp->decode(&p, dims, payload, bytes, out, 1, &err), err);
    static const char *const threads[] = {"2", "3", "7", "64", "1000"};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        setenv("CDVR_ZFP_THREADS", threads[t], 1);
        memset(par, 0xA5, n);
        out[0] = par;
        CHECK_OK(zfp->decode(&p, dims, payload, bytes, out, 1, &err), err);
        CHECK(memcmp(par, serial, n) == 0, "rate %s %zux%zux%zu: %s threads decode differently "
              "from one", rate, dims[0], dims[1], dims[2], threads[t]);
    }
    unsetenv("CDVR_ZFP_THREADS");
    out[0] = par;
    CHECK_OK(zfp->decode(&p, dims, payload, bytes, out, 1, &err), err); /* automatic count */
    CHECK(memcmp(par, serial, n) == 0, "rate %s: the automatic thread count differs", rate);
    free(payload);
    free(v);
    free(serial);
    free(par);
}

/* decode_cells (codec.h) against decode: every voxel of a needed cell, in both layouts (the
 * tiled one through cdvr_tiled_offset, with the tiles' voxels past the frame's edge repeating
 * its last voxel), for cells of 4 and 8 voxels and a need pattern that leaves cells out; the
 * other voxels keep what the frame held. */
static void check_cells(const cdvr_codec *zfp, const char *rate, const size_t dims[3])
{
    size_t n = dims[0] * dims[1] * dims[2], tb = cdvr_tiled_bytes(dims);
    uint8_t *v = malloc(n), *whole = malloc(n), *lin = malloc(n), *tiles = malloc(tb);
    for (size_t i = 0; i < n; i++)
        v[i] = (uint8_t)((i % dims[0]) * 3 + (i / dims[0] % dims[1]) * 7 + i / (dims[0] * dims[1]));
    cdvr_codec_params p;
    cdvr_error err;
    size_t bytes, bound;
    uint8_t *payload = encode_frame(zfp, rate, dims, v, &p, &bytes, &bound);
    uint8_t *out[1] = {whole};
    CHECK_OK(zfp->decode(&p, dims, payload, bytes, out, 1, &err), err);
    CHECK(zfp->decode_cells != NULL && zfp->decodes_in_parallel, "zfp: decode_cells, parallel");
    for (unsigned log2 = 2; zfp->decode_cells && log2 <= 3; log2++) {
        size_t c[3], cells = 1;
        for (int a = 0; a < 3; a++)
            cells *= c[a] = ((dims[a] - 1) >> log2) + 1;
        uint8_t *need = malloc(cells);
        for (size_t i = 0; i < cells; i++)
            need[i] = (uint8_t)(i % 3 != 1);
        memset(lin, 0x5A, n);
        memset(tiles, 0x5A, tb);
        CHECK_OK(zfp->decode_cells(&p, dims, payload, bytes, lin, CDVR_LAYOUT_LINEAR, need, log2,
                                   &err), err);
        CHECK_OK(zfp->decode_cells(&p, dims, payload, bytes, tiles, CDVR_LAYOUT_TILED, need, log2,
                                   &err), err);
        size_t bad_lin = 0, bad_tiled = 0, bad_pad = 0, kept = 0;
        for (size_t z = 0; z < dims[2]; z++)
            for (size_t y = 0; y < dims[1]; y++)
                for (size_t x = 0; x < dims[0]; x++) {
                    size_t i = x + dims[0] * (y + dims[1] * z);
                    int needed = need[(x >> log2) + c[0] * ((y >> log2) + c[1] * (z >> log2))];
                    uint8_t t = tiles[cdvr_tiled_offset(dims, x, y, z)];
                    bad_lin += needed && lin[i] != whole[i];
                    bad_tiled += needed && t != whole[i];
                    kept += !needed && lin[i] == 0x5A;
                }
        /* the padding of each decoded edge tile: the frame's last voxel along the axis */
        for (size_t z = 0; z < (dims[2] + 3) / 4 * 4; z++)
            for (size_t y = 0; y < (dims[1] + 3) / 4 * 4; y++)
                for (size_t x = 0; x < (dims[0] + 3) / 4 * 4; x++) {
                    size_t sx = x < dims[0] ? x : dims[0] - 1, sy = y < dims[1] ? y : dims[1] - 1;
                    size_t sz = z < dims[2] ? z : dims[2] - 1;
                    if ((x < dims[0] && y < dims[1] && z < dims[2]) ||
                        !need[(sx >> log2) + c[0] * ((sy >> log2) + c[1] * (sz >> log2))])
                        continue;
                    bad_pad += tiles[cdvr_tiled_offset(dims, x, y, z)] !=
                               whole[sx + dims[0] * (sy + dims[1] * sz)];
                }
        CHECK(bad_lin == 0 && bad_tiled == 0 && bad_pad == 0 && (kept > 0 || log2 == 3),
              "rate %s %zux%zux%zu cells of %u: %zu linear and %zu tiled voxels differ from "
              "decode, %zu padding voxels wrong, %zu voxels of cells not needed kept",
              rate, dims[0], dims[1], dims[2], 1u << log2, bad_lin, bad_tiled, bad_pad, kept);
        free(need);
    }
    free(payload);
    free(v);
    free(whole);
    free(lin);
    free(tiles);
}

int main(void)
{
    const char *bin = getenv("CDVR_BINARY_DIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/plugins/cdvr_zfp.so", bin && *bin ? bin : ".");
    const cdvr_codec *zfp = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_plugin_load(path, &zfp, &err), err);
    if (!zfp)
        return check_finish();
    static const size_t dims[][3] = {{1, 1, 1}, {5, 3, 7}, {33, 17, 9}, {64, 8, 4}};
    static const char *const rates[] = {"0.015625", "0.5", "1", "1.515625", "2", "4", "16"};
    for (size_t d = 0; d < sizeof dims / sizeof dims[0]; d++)
        for (size_t r = 0; r < sizeof rates / sizeof rates[0]; r++)
            for (int pattern = 0; pattern < 3; pattern++)
                check_one(zfp, rates[r], dims[d], pattern);
    static const size_t pdims[][3] = {{37, 21, 45}, {128, 64, 96}, {4, 4, 4}};
    static const char *const prates[] = {"0.5", "1.515625", "2", "16"};
    for (size_t d = 0; d < sizeof pdims / sizeof pdims[0]; d++)
        for (size_t r = 0; r < sizeof prates / sizeof prates[0]; r++)
            check_parallel(zfp, prates[r], pdims[d]);
    static const size_t cdims[][3] = {{37, 21, 45}, {16, 16, 16}, {5, 70, 3}};
    for (size_t d = 0; d < sizeof cdims / sizeof cdims[0]; d++)
        check_cells(zfp, "1", cdims[d]);
    /* the mapping's rounding and clamping at its edges */
    CHECK(reference_u8(0) == 128 && reference_u8((1 << 22) - 1) == 128 &&
              reference_u8(1 << 22) == 129 && reference_u8(-(1 << 22)) == 128 &&
              reference_u8(-(1 << 22) - 1) == 127 && reference_u8(INT32_MIN) == 0 &&
              reference_u8(INT32_MAX) == 255,
          "reference mapping");
    return check_finish();
}
