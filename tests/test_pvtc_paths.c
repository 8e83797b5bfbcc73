/* tests/test_pvtc_paths.c - the fast PVTC decoders (portable SWAR, SSSE3, AVX2) are bit-exact with
 * the reference decoder on random chunks of every variant, odd dims (groups of four blocks,
 * groups of eight with SSSE3 leftovers, cropped edges), and every frame count; untouched output stays untouched. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "codec/pvtc/pvtc_internal.h"
#include "cdvr/pvtc.h"
#include "check.h"

#define SENTINEL 0xCD

static const cdvr_pvtc_params VARIANTS[8] = {
    {1, 3, CDVR_PACK_TIME},  {1, 2, CDVR_PACK_TIME},  {4, 3, CDVR_PACK_TIME},
    {4, 2, CDVR_PACK_TIME},  {1, 3, CDVR_PACK_SPACE}, {1, 2, CDVR_PACK_SPACE},
    {4, 3, CDVR_PACK_SPACE}, {4, 2, CDVR_PACK_SPACE}};

/* x (blocks): none whole, one group of four, four + leftover, 4 + 4 + edge (AVX2: 8 + edge),
 * 5 (AVX2 nothing, SSSE3 4 + 1), 8 + 4 + 1 + edge, 16 (two AVX2 groups), 25 + edge; y and z
 * with and without padding for S and S*T. */
static const size_t DIMS[][3] = {{1, 1, 1},   {5, 3, 7},    {9, 8, 13},  {17, 4, 12},
                                 {20, 12, 8}, {35, 9, 26},  {64, 8, 24}, {16, 16, 5},
                                 {54, 8, 12}, {102, 5, 24}};
#define NDIMS (sizeof DIMS / sizeof DIMS[0])

static const char *const PATH_NAME[] = {"auto", "reference", "portable", "ssse3", "avx2"};

typedef struct decoded {
    uint8_t *buf; /* 3 frames */
    uint8_t *frames[3];
} decoded;

static int decoded_init(decoded *d, size_t voxels)
{
    d->buf = malloc(3 * voxels);
    if (!d->buf)
        return 0;
    memset(d->buf, SENTINEL, 3 * voxels);
    for (int f = 0; f < 3; f++)
        d->frames[f] = d->buf + (size_t)f * voxels;
    return 1;
}

static uint32_t lcg(uint32_t *state)
{
    *state = *state * 1664525u + 1013904223u;
    return *state >> 24;
}

/* Decodes chunk with path and compares all three frame buffers with the reference's. */
static void compare_path(const cdvr_pvtc_params *p, const size_t dims[3], const uint8_t *chunk,
                         size_t bytes, size_t nframes, const decoded *ref,
                         pvtc_decode_path path)
{
    size_t voxels = dims[0] * dims[1] * dims[2];
    decoded out;
    if (!decoded_init(&out, voxels)) {
        CHECK(0, "out of memory");
        return;
    }
    cdvr_error err;
    cdvr_status st = pvtc_decode_chunk_path(p, dims, chunk, bytes, out.frames, nframes, path, &err);
    CHECK_OK(st, err);
    size_t first_diff = 3 * voxels;
    for (size_t i = 0; i < 3 * voxels && first_diff == 3 * voxels; i++)
        if (out.buf[i] != ref->buf[i])
            first_diff = i;
    CHECK(first_diff == 3 * voxels,
          "S%dT%d %s dims %zux%zux%zu, %zu frames, %s path: frame %zu voxel %zu is %d, "
          "reference %d", p->S, p->T, p->pack ? "space" : "time", dims[0], dims[1], dims[2],
          nframes, PATH_NAME[path], first_diff / voxels, first_diff % voxels,
          first_diff < 3 * voxels ? out.buf[first_diff] : -1,
          first_diff < 3 * voxels ? ref->buf[first_diff] : -1);
    free(out.buf);
}

static void test_variant_dims(const cdvr_pvtc_params *p, const size_t dims[3], uint32_t *seed,
                              int have_ssse3, int have_avx2)
{
    cdvr_pvtc_geometry g;
    cdvr_error err;
    cdvr_status st = cdvr_pvtc_geometry_get(p, dims, &g, &err);
    CHECK_OK(st, err);
    if (st != CDVR_OK)
        return;
    uint8_t *chunk = malloc(g.chunk_bytes);
    size_t voxels = dims[0] * dims[1] * dims[2];
    for (size_t i = 0; chunk && i < g.chunk_bytes; i++)
        chunk[i] = (uint8_t)lcg(seed);
    for (size_t nframes = 1; chunk && nframes <= g.frames; nframes++) {
        decoded ref;
        if (!decoded_init(&ref, voxels))
            break;
        st = pvtc_decode_chunk_path(p, dims, chunk, g.chunk_bytes, ref.frames, nframes,
                                    PVTC_DECODE_REFERENCE, &err);
        CHECK_OK(st, err);
        for (size_t f = nframes; f < 3; f++) /* frames not asked for are never written */
            CHECK(ref.frames[f][0] == SENTINEL && ref.frames[f][voxels - 1] == SENTINEL,
                  "reference wrote frame %zu of %zu", f, nframes);
        compare_path(p, dims, chunk, g.chunk_bytes, nframes, &ref, PVTC_DECODE_PORTABLE);
        compare_path(p, dims, chunk, g.chunk_bytes, nframes, &ref, PVTC_DECODE_AUTO);
        if (have_ssse3)
            compare_path(p, dims, chunk, g.chunk_bytes, nframes, &ref, PVTC_DECODE_SSSE3);
        if (have_avx2)
            compare_path(p, dims, chunk, g.chunk_bytes, nframes, &ref, PVTC_DECODE_AVX2);
        free(ref.buf);
    }
    free(chunk);
}

/* Every path against hand-computed voxels, so that the comparison cannot pass with every
 * path equally wrong: eight S1T3 blocks in a row (one AVX2 group, two SSSE3 groups), each
 * U = 0xFC10 (255, 130, 132), D = 0, row 0 indices 0 1 2 3 -> channel 0 values 255 170 85 0,
 * row 1 index 0. */
static void test_hand_computed(void)
{
    enum { NBLOCKS = 8, X = 4 * NBLOCKS };
    const cdvr_pvtc_params p = {1, 3, CDVR_PACK_TIME};
    const size_t dims[3] = {X, 4, 1};
    const uint8_t endpoints[4] = {0x10, 0xFC, 0x00, 0x00}, word[4] = {0xE4, 0x00, 0x00, 0x00};
    const uint8_t row0[3][4] = {{255, 170, 85, 0}, {130, 87, 43, 0}, {132, 88, 44, 0}};
    uint8_t chunk[8 * NBLOCKS];
    for (int k = 0; k < NBLOCKS; k++) {
        memcpy(chunk + 4 * k, endpoints, 4);
        memcpy(chunk + 4 * NBLOCKS + 4 * k, word, 4);
    }
    for (int path = PVTC_DECODE_REFERENCE; path <= PVTC_DECODE_AVX2; path++) {
        decoded out;
        cdvr_error err;
        if (!decoded_init(&out, 4 * X))
            return;
        cdvr_status st = pvtc_decode_chunk_path(&p, dims, chunk, sizeof chunk, out.frames, 3,
                                                (pvtc_decode_path)path, &err);
        if (st == CDVR_ERR_UNSUPPORTED) {
            free(out.buf);
            continue;
        }
        CHECK_OK(st, err);
        for (int c = 0; c < 3; c++)
            for (int k = 0; k < NBLOCKS; k++) {
                const uint8_t *v = out.frames[c] + 4 * k;
                CHECK(memcmp(v, row0[c], 4) == 0 && v[X] == row0[c][0] && v[X + 3] == row0[c][0],
                      "%s path: channel %d block %d row 0 is %d %d %d %d", PATH_NAME[path], c, k,
                      v[0], v[1], v[2], v[3]);
            }
        free(out.buf);
    }
}

static void test_bad_path(void)
{
    const cdvr_pvtc_params p = {1, 3, CDVR_PACK_TIME};
    const size_t dims[3] = {4, 4, 1};
    uint8_t chunk[8] = {0}, buf[3][16];
    uint8_t *frames[3] = {buf[0], buf[1], buf[2]};
    cdvr_error err;
    cdvr_status st = pvtc_decode_chunk_path(&p, dims, chunk, 8, frames, 3, (pvtc_decode_path)99,
                                            &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "path"), "unknown path: status %d (%s)",
          (int)st, err.msg);
}

int main(void)
{
    int have_ssse3 = pvtc_ssse3_available();
    int have_avx2 = pvtc_avx2_available();
    if (!have_ssse3)
        printf("SSSE3 path not available here: portable and reference compared only\n");
    if (!have_avx2)
        printf("AVX2 path not available here: not compared\n");
    uint32_t seed = 77u;
    for (int v = 0; v < 8; v++)
        for (size_t d = 0; d < NDIMS; d++)
            test_variant_dims(&VARIANTS[v], DIMS[d], &seed, have_ssse3, have_avx2);
    test_hand_computed();
    test_bad_path();
    return check_finish();
}
