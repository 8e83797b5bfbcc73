/* tests/test_pvtc.c - PVTC geometry and decoder against chunks written byte by byte from the
 * format in DESIGN.md 4.1 (expected voxels computed by hand, not by the codec), bad input,
 * and encode/decode round trips on the hard cases of DESIGN.md 9. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/pvtc.h"
#include "check.h"

#define MAXV 4096

static const cdvr_pvtc_params S1T3_TIME = {1, 3, CDVR_PACK_TIME};
static const cdvr_pvtc_params S1T2_TIME = {1, 2, CDVR_PACK_TIME};
static const cdvr_pvtc_params S4T3_TIME = {4, 3, CDVR_PACK_TIME};
static const cdvr_pvtc_params S4T2_TIME = {4, 2, CDVR_PACK_TIME};
static const cdvr_pvtc_params S1T3_SPACE = {1, 3, CDVR_PACK_SPACE};
static const cdvr_pvtc_params S1T2_SPACE = {1, 2, CDVR_PACK_SPACE};
static const cdvr_pvtc_params S4T3_SPACE = {4, 3, CDVR_PACK_SPACE};
static const cdvr_pvtc_params S4T2_SPACE = {4, 2, CDVR_PACK_SPACE};

/* One block of T = 3 endpoints: U = RGB565 (31, 32, 16) -> (255, 130, 132); D = 0.
 * U word 31<<11 | 32<<5 | 16 = 0xFC10. Palettes by hand:
 *   ch0 a=255 b=0: 255, (510+1)/3=170, (255+1)/3=85, 0
 *   ch1 a=130 b=0: 130, (260+1)/3=87, (130+1)/3=43, 0
 *   ch2 a=132 b=0: 132, (264+1)/3=88, (132+1)/3=44, 0
 * Index word bytes E4 1B 00 FF: row y0 indices 0 1 2 3, y1 3 2 1 0, y2 all 0, y3 all 3. */
static const uint8_t EP_RGB_A[4] = {0x10, 0xFC, 0x00, 0x00};
static const uint8_t WORD_ROWS[4] = {0xE4, 0x1B, 0x00, 0xFF};
static const uint8_t ROW_INDEX[4][4] = {{0, 1, 2, 3}, {3, 2, 1, 0}, {0, 0, 0, 0}, {3, 3, 3, 3}};
static const uint8_t PAL_RGB_A[3][4] = {{255, 170, 85, 0}, {130, 87, 43, 0}, {132, 88, 44, 0}};

/* T = 3 endpoints U = (16, 63, 1) -> (132, 255, 8), D = (0, 1, 31) -> (0, 4, 255).
 * U = 16<<11 | 63<<5 | 1 = 0x87E1, D = 1<<5 | 31 = 0x003F. Palettes by hand:
 *   ch0 a=132 b=0:   132, 265/3=88, 133/3=44, 0
 *   ch1 a=255 b=4:   255, 515/3=171, 264/3=88, 4
 *   ch2 a=8   b=255: 8, 272/3=90, 519/3=173, 255 */
static const uint8_t EP_RGB_B[4] = {0xE1, 0x87, 0x3F, 0x00};
static const uint8_t PAL_RGB_B[3][4] = {{132, 88, 44, 0}, {255, 171, 88, 4}, {8, 90, 173, 255}};

/* T = 2 endpoints U = (10, 0), D = (0, 10): ch0 10, 21/3=7, 11/3=3, 0; ch1 0, 3, 7, 10. */
static const uint8_t EP_TWO_A[4] = {10, 0, 0, 10};
static const uint8_t PAL_TWO_A[2][4] = {{10, 7, 3, 0}, {0, 3, 7, 10}};
/* T = 2 endpoints U = (200, 1), D = (50, 0): ch0 200, 451/3=150, 301/3=100, 50;
 * ch1 1, 3/3=1, 2/3=0, 0. */
static const uint8_t EP_TWO_B[4] = {200, 1, 50, 0};
static const uint8_t PAL_TWO_B[2][4] = {{200, 150, 100, 50}, {1, 1, 0, 0}};
/* Index word where every position of row y has index y: bytes 00 55 AA FF. */
static const uint8_t WORD_BY_ROW[4] = {0x00, 0x55, 0xAA, 0xFF};
/* Four index words for S = 4 where slice z of the block has index z. */
static const uint8_t WORDS_BY_Z[16] = {0x00, 0x00, 0x00, 0x00, 0x55, 0x55, 0x55, 0x55,
                                       0xAA, 0xAA, 0xAA, 0xAA, 0xFF, 0xFF, 0xFF, 0xFF};

typedef struct frames_buf {
    uint8_t data[3][MAXV];
    uint8_t *ptr[3];
} frames_buf;

static void frames_init(frames_buf *fb)
{
    memset(fb->data, 0xCD, sizeof fb->data);
    for (int i = 0; i < 3; i++)
        fb->ptr[i] = fb->data[i];
}

static size_t vox(const size_t d[3], size_t x, size_t y, size_t z)
{
    return x + d[0] * (y + d[1] * z);
}

static int decode(const cdvr_pvtc_params *p, const size_t d[3], const uint8_t *chunk,
                  size_t bytes, frames_buf *fb, size_t nframes)
{
    cdvr_error err;
    frames_init(fb);
    cdvr_status st = cdvr_pvtc_decode_chunk(p, d, chunk, bytes, fb->ptr, nframes, &err);
    CHECK_OK(st, err);
    return st == CDVR_OK;
}

static void test_geometry(void)
{
    struct { cdvr_pvtc_params p; size_t d[3]; size_t bx, by, bz, bytes, frames; } cases[] = {
        {{1, 3, CDVR_PACK_TIME}, {4, 4, 1}, 1, 1, 1, 8, 3},
        {{1, 3, CDVR_PACK_TIME}, {5, 3, 7}, 2, 1, 7, 14 * 8, 3},
        {{4, 3, CDVR_PACK_TIME}, {5, 3, 7}, 2, 1, 2, 4 * 20, 3},
        {{4, 2, CDVR_PACK_TIME}, {1, 1, 1}, 1, 1, 1, 20, 2},
        {{1, 2, CDVR_PACK_SPACE}, {9, 8, 13}, 3, 2, 7, 42 * 8, 1},
        {{4, 3, CDVR_PACK_SPACE}, {5, 3, 7}, 2, 1, 1, 2 * 20, 1},
        {{4, 3, CDVR_PACK_SPACE}, {64, 64, 64}, 16, 16, 6, 1536 * 20, 1},
        {{1, 3, CDVR_PACK_SPACE}, {64, 64, 64}, 16, 16, 22, 5632 * 8, 1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        cdvr_pvtc_geometry g;
        cdvr_error err;
        cdvr_status st = cdvr_pvtc_geometry_get(&cases[i].p, cases[i].d, &g, &err);
        CHECK_OK(st, err);
        CHECK(g.blocks[0] == cases[i].bx && g.blocks[1] == cases[i].by &&
                  g.blocks[2] == cases[i].bz, "case %zu blocks %zux%zux%zu", i, g.blocks[0],
              g.blocks[1], g.blocks[2]);
        CHECK(g.nblocks == cases[i].bx * cases[i].by * cases[i].bz, "case %zu nblocks", i);
        CHECK(g.chunk_bytes == cases[i].bytes, "case %zu bytes %zu", i, g.chunk_bytes);
        CHECK(g.frames == cases[i].frames, "case %zu frames %zu", i, g.frames);
    }
}

static void test_bad_params(void)
{
    cdvr_pvtc_geometry g;
    cdvr_error err;
    size_t d[3] = {4, 4, 4};
    cdvr_pvtc_params bad_s = {2, 3, CDVR_PACK_TIME}, bad_t = {1, 4, CDVR_PACK_TIME};
    cdvr_pvtc_params bad_pack = {1, 3, (cdvr_pack)7};
    CHECK(cdvr_pvtc_geometry_get(&bad_s, d, &g, &err) == CDVR_ERR_ARG, "S=2 accepted");
    CHECK(strstr(err.msg, "S = 2") != NULL, "message: %s", err.msg);
    CHECK(cdvr_pvtc_geometry_get(&bad_t, d, &g, &err) == CDVR_ERR_ARG, "T=4 accepted");
    CHECK(cdvr_pvtc_geometry_get(&bad_pack, d, &g, &err) == CDVR_ERR_ARG, "pack 7 accepted");
    CHECK(cdvr_pvtc_geometry_get(NULL, d, &g, NULL) == CDVR_ERR_ARG, "NULL params accepted");
    size_t zero[3] = {4, 0, 4};
    CHECK(cdvr_pvtc_geometry_get(&S1T3_TIME, zero, &g, &err) == CDVR_ERR_ARG, "zero dim");
    size_t huge[3] = {SIZE_MAX / 2, SIZE_MAX / 2, 2};
    CHECK(cdvr_pvtc_geometry_get(&S1T3_TIME, huge, &g, &err) == CDVR_ERR_NOMEM, "overflow");
    size_t huge2[3] = {SIZE_MAX, 1, 1}; /* blocks fit, block bytes do not */
    CHECK(cdvr_pvtc_geometry_get(&S4T3_TIME, huge2, &g, &err) == CDVR_ERR_NOMEM, "SIZE_MAX x 1");

    uint8_t chunk[8] = {0};
    frames_buf fb;
    frames_init(&fb);
    cdvr_status st = cdvr_pvtc_decode_chunk(&S1T3_TIME, d, chunk, 8, fb.ptr, 3, &err);
    CHECK(st == CDVR_ERR_CORRUPT, "short chunk accepted: %d", (int)st);
    CHECK(strstr(err.msg, "8 bytes") && strstr(err.msg, "4x4x4"), "message: %s", err.msg);
    size_t d1[3] = {4, 4, 1};
    CHECK(cdvr_pvtc_decode_chunk(&S1T3_TIME, d1, chunk, 8, fb.ptr, 4, &err) == CDVR_ERR_ARG,
          "4 frames from T=3");
    CHECK(cdvr_pvtc_decode_chunk(&S1T3_TIME, d1, chunk, 8, fb.ptr, 0, &err) == CDVR_ERR_ARG,
          "0 frames");
    CHECK(cdvr_pvtc_decode_chunk(&S1T3_SPACE, d1, chunk, 8, fb.ptr, 2, &err) == CDVR_ERR_ARG,
          "space with 2 frames");
    CHECK(cdvr_pvtc_decode_chunk(&S1T3_TIME, d1, NULL, 8, fb.ptr, 3, &err) == CDVR_ERR_ARG,
          "NULL input");
    uint8_t *nullframes[3] = {fb.ptr[0], NULL, fb.ptr[2]};
    CHECK(cdvr_pvtc_decode_chunk(&S1T3_TIME, d1, chunk, 8, nullframes, 3, &err) == CDVR_ERR_ARG,
          "NULL frame");
    const uint8_t *cframes[3] = {fb.ptr[0], fb.ptr[1], NULL};
    CHECK(cdvr_pvtc_encode_chunk(&S1T3_TIME, CDVR_ENCODER_LSQ, d1, cframes, chunk, &err) ==
              CDVR_ERR_ARG, "encode with NULL frame");
    CHECK(cdvr_pvtc_encode_chunk(&S1T3_TIME, (cdvr_pvtc_encoder)9, d1, cframes, chunk, &err) ==
              CDVR_ERR_ARG, "unknown encoder");
}

/* S1T3 time, one block 4x4x1: RGB565 bit replication (31->255, 32->130, 16->132), rounding,
 * index bit order within the word; then cropped to 3x2x1. */
static void test_s1t3_time(void)
{
    uint8_t chunk[8];
    memcpy(chunk, EP_RGB_A, 4);
    memcpy(chunk + 4, WORD_ROWS, 4);
    size_t d[3] = {4, 4, 1};
    frames_buf fb;
    if (decode(&S1T3_TIME, d, chunk, 8, &fb, 3))
        for (int c = 0; c < 3; c++)
            for (size_t y = 0; y < 4; y++)
                for (size_t x = 0; x < 4; x++)
                    CHECK(fb.data[c][vox(d, x, y, 0)] == PAL_RGB_A[c][ROW_INDEX[y][x]],
                          "c%d (%zu,%zu) = %d", c, x, y, fb.data[c][vox(d, x, y, 0)]);
    CHECK(fb.data[0][0] == 255 && fb.data[1][0] == 130 && fb.data[2][0] == 132,
          "bit replication %d %d %d", fb.data[0][0], fb.data[1][0], fb.data[2][0]);

    size_t dc[3] = {3, 2, 1};
    if (decode(&S1T3_TIME, dc, chunk, 8, &fb, 2)) {
        for (int c = 0; c < 2; c++)
            for (size_t y = 0; y < 2; y++)
                for (size_t x = 0; x < 3; x++)
                    CHECK(fb.data[c][vox(dc, x, y, 0)] == PAL_RGB_A[c][ROW_INDEX[y][x]],
                          "cropped c%d (%zu,%zu)", c, x, y);
        CHECK(fb.data[0][6] == 0xCD && fb.data[2][0] == 0xCD, "wrote past crop or frame 3");
    }
}

/* S1T2 time, 8x4x1 = two blocks: struct-of-arrays (ep0 ep1 idx0 idx1). */
static void test_s1t2_time(void)
{
    uint8_t chunk[16];
    memcpy(chunk, EP_TWO_A, 4);
    memcpy(chunk + 4, EP_TWO_B, 4);
    memcpy(chunk + 8, WORD_ROWS, 4);
    memcpy(chunk + 12, WORD_BY_ROW, 4);
    size_t d[3] = {8, 4, 1};
    frames_buf fb;
    if (!decode(&S1T2_TIME, d, chunk, 16, &fb, 2))
        return;
    for (int c = 0; c < 2; c++)
        for (size_t y = 0; y < 4; y++)
            for (size_t x = 0; x < 8; x++) {
                int want = x < 4 ? PAL_TWO_A[c][ROW_INDEX[y][x]] : PAL_TWO_B[c][y];
                CHECK(fb.data[c][vox(d, x, y, 0)] == want, "c%d (%zu,%zu) = %d want %d", c, x,
                      y, fb.data[c][vox(d, x, y, 0)], want);
            }
}

/* S4T3 time, 4x4x4 one block: four index words, slice z uses word z. Also cropped to z = 3. */
static void test_s4t3_time(void)
{
    uint8_t chunk[20];
    memcpy(chunk, EP_RGB_B, 4);
    memcpy(chunk + 4, WORDS_BY_Z, 16);
    size_t d[3] = {4, 4, 4};
    frames_buf fb;
    if (decode(&S4T3_TIME, d, chunk, 20, &fb, 3))
        for (int c = 0; c < 3; c++)
            for (size_t z = 0; z < 4; z++)
                for (size_t i = 0; i < 16; i++)
                    CHECK(fb.data[c][16 * z + i] == PAL_RGB_B[c][z], "c%d z%zu i%zu = %d", c, z,
                          i, fb.data[c][16 * z + i]);
    size_t dc[3] = {2, 4, 3};
    if (decode(&S4T3_TIME, dc, chunk, 20, &fb, 3))
        for (int c = 0; c < 3; c++)
            for (size_t z = 0; z < 3; z++)
                CHECK(fb.data[c][vox(dc, 1, 3, z)] == PAL_RGB_B[c][z], "cropped c%d z%zu", c, z);
    CHECK(fb.data[0][24] == 0xCD, "wrote past cropped frame");
}

/* S4T2 time, one block with x-varying indices in slice 0 and a second block along z. */
static void test_s4t2_time(void)
{
    uint8_t chunk[40];
    memcpy(chunk, EP_TWO_A, 4);
    memcpy(chunk + 4, EP_TWO_B, 4);
    memcpy(chunk + 8, WORDS_BY_Z, 16);
    memcpy(chunk + 24, WORD_ROWS, 4); /* block 2, slice 4: row pattern */
    memset(chunk + 28, 0xFF, 12);     /* block 2, slices 5..7: index 3 */
    size_t d[3] = {4, 4, 6};
    frames_buf fb;
    if (!decode(&S4T2_TIME, d, chunk, 40, &fb, 2))
        return;
    for (int c = 0; c < 2; c++) {
        for (size_t z = 0; z < 4; z++)
            CHECK(fb.data[c][vox(d, 2, 1, z)] == PAL_TWO_A[c][z], "c%d z%zu", c, z);
        for (size_t y = 0; y < 4; y++)
            for (size_t x = 0; x < 4; x++)
                CHECK(fb.data[c][vox(d, x, y, 4)] == PAL_TWO_B[c][ROW_INDEX[y][x]],
                      "c%d block 2 (%zu,%zu,4)", c, x, y);
        CHECK(fb.data[c][vox(d, 3, 3, 5)] == PAL_TWO_B[c][3], "c%d z5", c);
    }
    /* first frame only */
    if (decode(&S4T2_TIME, d, chunk, 40, &fb, 1))
        CHECK(fb.data[0][0] == 10 && fb.data[1][0] == 0xCD, "nframes=1 wrote frame 2");
}

/* S1T2 space, 4x4x4: block 0 holds slices 0 (ch0) and 1 (ch1), block 1 slices 2 and 3. */
static void test_s1t2_space(void)
{
    uint8_t chunk[16];
    memcpy(chunk, EP_TWO_A, 4);
    memcpy(chunk + 4, EP_TWO_B, 4);
    memcpy(chunk + 8, WORD_ROWS, 4);
    memcpy(chunk + 12, WORD_BY_ROW, 4);
    size_t d[3] = {4, 4, 4};
    frames_buf fb;
    if (!decode(&S1T2_SPACE, d, chunk, 16, &fb, 1))
        return;
    for (size_t y = 0; y < 4; y++)
        for (size_t x = 0; x < 4; x++) {
            CHECK(fb.data[0][vox(d, x, y, 0)] == PAL_TWO_A[0][ROW_INDEX[y][x]], "s0 (%zu,%zu)",
                  x, y);
            CHECK(fb.data[0][vox(d, x, y, 1)] == PAL_TWO_A[1][ROW_INDEX[y][x]], "s1 (%zu,%zu)",
                  x, y);
            CHECK(fb.data[0][vox(d, x, y, 2)] == PAL_TWO_B[0][y], "s2 (%zu,%zu)", x, y);
            CHECK(fb.data[0][vox(d, x, y, 3)] == PAL_TWO_B[1][y], "s3 (%zu,%zu)", x, y);
        }
}

/* S1T3 space, 4x4x3: the three channels of one block are slices 0, 1, 2. */
static void test_s1t3_space(void)
{
    uint8_t chunk[8];
    memcpy(chunk, EP_RGB_A, 4);
    memcpy(chunk + 4, WORD_ROWS, 4);
    size_t d[3] = {4, 4, 3};
    frames_buf fb;
    if (!decode(&S1T3_SPACE, d, chunk, 8, &fb, 1))
        return;
    for (size_t z = 0; z < 3; z++)
        for (size_t y = 0; y < 4; y++)
            for (size_t x = 0; x < 4; x++)
                CHECK(fb.data[0][vox(d, x, y, z)] == PAL_RGB_A[z][ROW_INDEX[y][x]],
                      "slice %zu (%zu,%zu)", z, x, y);
}

/* S4T3 space: one block spans 12 slices, slice s = 3*zp + c decodes palette c at index zp;
 * with Z = 10 the last two slices are cropped. */
static void test_s4t3_space(void)
{
    uint8_t chunk[20];
    memcpy(chunk, EP_RGB_B, 4);
    memcpy(chunk + 4, WORDS_BY_Z, 16);
    size_t d[3] = {4, 4, 10};
    frames_buf fb;
    if (!decode(&S4T3_SPACE, d, chunk, 20, &fb, 1))
        return;
    for (size_t s = 0; s < 10; s++)
        CHECK(fb.data[0][vox(d, 1, 2, s)] == PAL_RGB_B[s % 3][s / 3], "slice %zu = %d", s,
              fb.data[0][vox(d, 1, 2, s)]);
    CHECK(fb.data[0][160] == 0xCD, "wrote past Z");
}

/* S4T2 space, 4x4x8: slice s = 2*zp + c. */
static void test_s4t2_space(void)
{
    uint8_t chunk[20];
    memcpy(chunk, EP_TWO_B, 4);
    memcpy(chunk + 4, WORDS_BY_Z, 16);
    size_t d[3] = {4, 4, 8};
    frames_buf fb;
    if (!decode(&S4T2_SPACE, d, chunk, 20, &fb, 1))
        return;
    for (size_t s = 0; s < 8; s++)
        CHECK(fb.data[0][vox(d, 3, 0, s)] == PAL_TWO_B[s % 2][s / 2], "slice %zu", s);
}

/* ---- round trips ------------------------------------------------------------------------ */

static const cdvr_pvtc_params *const ALL_VARIANTS[8] = {
    &S1T3_TIME, &S1T2_TIME, &S4T3_TIME, &S4T2_TIME,
    &S1T3_SPACE, &S1T2_SPACE, &S4T3_SPACE, &S4T2_SPACE};

typedef uint8_t (*field_fn)(size_t x, size_t y, size_t z, size_t c);

/* Encodes frames built by fn (c: channel = timestep for time, ignored for space), decodes,
 * returns the max abs error over all frames, or -1 on a failure. */
static int round_trip(const cdvr_pvtc_params *p, cdvr_pvtc_encoder enc, const size_t d[3],
                      size_t ntime, field_fn fn)
{
    cdvr_pvtc_geometry g;
    cdvr_error err;
    if (cdvr_pvtc_geometry_get(p, d, &g, &err) != CDVR_OK)
        return -1;
    size_t n = d[0] * d[1] * d[2], frames_used = p->pack == CDVR_PACK_TIME ? ntime : 1;
    uint8_t *src = malloc(3 * n), *dst = malloc(3 * n), *chunk = malloc(g.chunk_bytes);
    const uint8_t *in[3];
    uint8_t *out[3];
    for (size_t f = 0; f < 3; f++) {
        /* time: timesteps past ntime repeat the last one (the store's job) */
        size_t src_f = f < frames_used ? f : frames_used - 1;
        in[f] = src + n * src_f;
        out[f] = dst + n * f;
        for (size_t z = 0; z < d[2]; z++)
            for (size_t y = 0; y < d[1]; y++)
                for (size_t x = 0; x < d[0]; x++)
                    src[n * f + vox(d, x, y, z)] =
                        fn(x, y, z, p->pack == CDVR_PACK_TIME ? f : z % (size_t)p->T);
    }
    int maxerr = -1;
    cdvr_status st = cdvr_pvtc_encode_chunk(p, enc, d, in, chunk, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        st = cdvr_pvtc_decode_chunk(p, d, chunk, g.chunk_bytes, out, frames_used, &err);
        CHECK_OK(st, err);
    }
    if (st == CDVR_OK) {
        maxerr = 0;
        for (size_t f = 0; f < frames_used; f++)
            for (size_t i = 0; i < n; i++) {
                int e = abs((int)src[n * f + i] - (int)dst[n * f + i]);
                maxerr = e > maxerr ? e : maxerr;
            }
    }
    free(src);
    free(dst);
    free(chunk);
    return maxerr;
}

static uint8_t f_const(size_t x, size_t y, size_t z, size_t c)
{
    (void)x, (void)y, (void)z, (void)c;
    return 200; /* RGB565: 200 is not representable in 5 bits; 3-entry palette reaches it */
}

/* 0/255 with every channel equal: bbox is exact */
static uint8_t f_zero_full(size_t x, size_t y, size_t z, size_t c)
{
    (void)z, (void)c;
    return ((x + y) & 1) ? 255 : 0;
}

/* 0/255 with channel 1 inverted: two points off the diagonal, exact only for lsq */
static uint8_t f_zero_full_crossed(size_t x, size_t y, size_t z, size_t c)
{
    (void)z;
    return ((x + y + (c == 1)) & 1) ? 255 : 0;
}

/* two values per block, the same pair in every channel: exactly representable for T = 2 */
static uint8_t f_two_valued(size_t x, size_t y, size_t z, size_t c)
{
    (void)c, (void)z;
    return ((x * 7 + y * 3) % 5 < 2) ? 37 : 201;
}

/* channels moving in opposite directions along x */
static uint8_t f_opposite(size_t x, size_t y, size_t z, size_t c)
{
    (void)y, (void)z;
    size_t r = (x % 4) * 60;
    return (uint8_t)(c == 1 ? 240 - r : 20 + r);
}

/* a linear ramp along x: 4 evenly spaced levels per block, exactly a palette for T = 2 */
static uint8_t f_ramp(size_t x, size_t y, size_t z, size_t c)
{
    (void)y, (void)z;
    return (uint8_t)(8 * x + 5 * c);
}

static void test_round_trips(void)
{
    const size_t dims[][3] = {{1, 1, 1}, {5, 3, 7}, {4, 4, 4}, {9, 8, 13}};
    const size_t times[] = {1, 2, 3};
    for (int v = 0; v < 8; v++) {
        const cdvr_pvtc_params *p = ALL_VARIANTS[v];
        for (size_t di = 0; di < 4; di++)
            for (size_t ti = 0; ti < 3; ti++) {
                size_t nt = times[ti] > (size_t)p->T ? (size_t)p->T : times[ti];
                for (int enc = 0; enc < 2; enc++) {
                    const char *en = enc ? "bbox" : "lsq";
                    int e = round_trip(p, enc, dims[di], nt, f_const);
                    /* 200: T = 2 exact; 5-bit 25 = 206, 24 = 198 -> (2*198+206+1)/3 = 201 */
                    CHECK(e >= 0 && e <= (p->T == 2 ? 0 : (enc ? 2 : 1)),
                          "S%dT%d %s %s const dims %zu: %d", p->S, p->T,
                          p->pack ? "space" : "time", en, di, e);
                    e = round_trip(p, enc, dims[di], nt, f_zero_full);
                    CHECK(e == 0, "S%dT%d %s %s 0/255 dims %zu: %d", p->S, p->T,
                          p->pack ? "space" : "time", en, di, e);
                }
                int e = round_trip(p, CDVR_ENCODER_LSQ, dims[di], nt, f_zero_full_crossed);
                CHECK(e == 0, "S%dT%d %s lsq crossed 0/255 %zu: %d", p->S, p->T,
                      p->pack ? "space" : "time", di, e);
                e = round_trip(p, CDVR_ENCODER_LSQ, dims[di], nt, f_opposite);
                CHECK(e >= 0 && e <= (p->T == 2 ? 0 : 5), "S%dT%d %s lsq opposite %zu: %d",
                      p->S, p->T, p->pack ? "space" : "time", di, e);
                e = round_trip(p, CDVR_ENCODER_LSQ, dims[di], nt, f_two_valued);
                CHECK(e >= 0 && e <= (p->T == 2 ? 0 : 4), "S%dT%d %s lsq two-valued %zu: %d",
                      p->S, p->T, p->pack ? "space" : "time", di, e);
                e = round_trip(p, CDVR_ENCODER_LSQ, dims[di], nt, f_ramp);
                CHECK(e >= 0 && e <= (p->T == 2 ? 0 : 4), "S%dT%d %s lsq ramp %zu: %d", p->S,
                      p->T, p->pack ? "space" : "time", di, e);
            }
    }
}

/* The value of voxel (x, y, z) of frame f, read straight from DESIGN.md 4.1 one voxel at a time:
 * an independent reference for the decoder (no code shared with core/codec/pvtc). */
static uint8_t reference_voxel(const cdvr_pvtc_params *p, const size_t dims[3], const uint8_t *chunk, size_t x,
                               size_t y, size_t z, size_t f)
{
    size_t S = (size_t)p->S, T = (size_t)p->T, space = p->pack == CDVR_PACK_SPACE;
    size_t zp = space ? z / T : z, c = space ? z % T : f; /* packed position and channel */
    size_t bx = (dims[0] + 3) / 4, by = (dims[1] + 3) / 4;
    size_t bz = space ? (dims[2] + S * T - 1) / (S * T) : (dims[2] + S - 1) / S;
    size_t b = x / 4 + bx * (y / 4 + by * (zp / S)), nblocks = bx * by * bz;
    const uint8_t *ep = chunk + 4 * b;
    unsigned a, d;
    if (T == 3) {
        unsigned u = ep[0] | (unsigned)ep[1] << 8, v = ep[2] | (unsigned)ep[3] << 8;
        static const unsigned shift[3] = {11, 5, 0}, bits[3] = {5, 6, 5};
        unsigned mask = (1u << bits[c]) - 1, ua = (u >> shift[c]) & mask, va = (v >> shift[c]) & mask;
        a = bits[c] == 5 ? (ua << 3 | ua >> 2) : (ua << 2 | ua >> 4);
        d = bits[c] == 5 ? (va << 3 | va >> 2) : (va << 2 | va >> 4);
    } else {
        a = ep[c];
        d = ep[2 + c];
    }
    size_t i = x % 4 + 4 * (y % 4) + 16 * (zp % S);
    const uint8_t *w = chunk + 4 * nblocks + 4 * S * b + 4 * (i / 16);
    uint32_t word = w[0] | (uint32_t)w[1] << 8 | (uint32_t)w[2] << 16 | (uint32_t)w[3] << 24;
    unsigned index = (word >> (2 * (i % 16))) & 3;
    unsigned palette[4] = {a, (2 * a + d + 1) / 3, (a + 2 * d + 1) / 3, d};
    return (uint8_t)palette[index];
}

/* Decoding arbitrary bytes stays in bounds for every variant and odd dims (run under ASan) and
 * gives, voxel by voxel, what the format's definition gives (reference_voxel). */
static void test_decode_random_bytes(void)
{
    const size_t dims[][3] = {{1, 1, 1}, {5, 3, 7}, {9, 8, 13}, {3, 17, 2}};
    uint32_t seed = 12345;
    for (int v = 0; v < 8; v++)
        for (int di = 0; di < 4; di++) {
            const cdvr_pvtc_params *p = ALL_VARIANTS[v];
            const size_t *dm = dims[di];
            cdvr_pvtc_geometry g;
            cdvr_error err;
            cdvr_status st = cdvr_pvtc_geometry_get(p, dm, &g, &err);
            CHECK_OK(st, err);
            size_t n = dm[0] * dm[1] * dm[2];
            size_t zblocks = p->pack == CDVR_PACK_SPACE ? (dm[2] + (size_t)(p->S * p->T) - 1) / (size_t)(p->S * p->T)
                                                        : (dm[2] + (size_t)p->S - 1) / (size_t)p->S;
            CHECK(g.nblocks == (dm[0] + 3) / 4 * ((dm[1] + 3) / 4) * zblocks &&
                      g.chunk_bytes == g.nblocks * (size_t)(4 + 4 * p->S),
                  "S%dT%d %s geometry of %zux%zux%zu", p->S, p->T, p->pack ? "space" : "time", dm[0], dm[1], dm[2]);
            uint8_t *chunk = malloc(g.chunk_bytes), *buf = malloc(3 * n);
            for (size_t i = 0; i < g.chunk_bytes; i++) {
                seed = seed * 1664525u + 1013904223u;
                chunk[i] = (uint8_t)(seed >> 24);
            }
            memset(buf, 0xA5, 3 * n);
            uint8_t *out[3] = {buf, buf + n, buf + 2 * n};
            st = cdvr_pvtc_decode_chunk(p, dm, chunk, g.chunk_bytes, out, g.frames, &err);
            CHECK_OK(st, err);
            size_t wrong = 0, checked = 0;
            for (size_t f = 0; st == CDVR_OK && f < g.frames; f++)
                for (size_t z = 0; z < dm[2]; z++)
                    for (size_t y = 0; y < dm[1]; y++)
                        for (size_t x = 0; x < dm[0]; x++, checked++)
                            wrong += out[f][x + dm[0] * (y + dm[1] * z)] != reference_voxel(p, dm, chunk, x, y, z, f);
            CHECK(st == CDVR_OK && wrong == 0 && checked == g.frames * n,
                  "S%dT%d %s %zux%zux%zu: %zu of %zu voxels differ from the reference decode", p->S, p->T,
                  p->pack ? "space" : "time", dm[0], dm[1], dm[2], wrong, checked);
            free(chunk);
            free(buf);
        }
}

int main(void)
{
    test_geometry();
    test_bad_params();
    test_s1t3_time();
    test_s1t2_time();
    test_s4t3_time();
    test_s4t2_time();
    test_s1t2_space();
    test_s1t3_space();
    test_s4t3_space();
    test_s4t2_space();
    test_round_trips();
    test_decode_random_bytes();
    return check_finish();
}
