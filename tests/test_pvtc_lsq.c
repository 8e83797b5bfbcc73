/* tests/test_pvtc_lsq.c - the least-squares PVTC encoder: never worse than bbox on any block
 * (random and structured blocks, every variant), clearly better on smooth and anti-correlated
 * blocks, and better than bbox on real data (viscous fingers) when the shared data is there. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/pvtc.h"
#include "cdvr/volume.h"
#include "check.h"

#define BLOCKS_PER_KIND 300

typedef struct rng { uint32_t state; } rng;

static uint32_t rng_next(rng *r)
{
    r->state = r->state * 1664525u + 1013904223u;
    return r->state >> 8;
}

static int rng_range(rng *r, int lo, int hi)
{
    return lo + (int)(rng_next(r) % (uint32_t)(hi - lo + 1));
}

static uint8_t clamp_u8(int v)
{
    return (uint8_t)(v < 0 ? 0 : v > 255 ? 255 : v);
}

enum block_kind { KIND_UNIFORM, KIND_SMOOTH, KIND_CLUSTERS, KIND_OPPOSITE, KIND_CONSTANT,
                  KIND_SPARSE, KIND_COUNT };
static const char *const KIND_NAME[KIND_COUNT] = {"uniform", "smooth", "clusters", "opposite",
                                                  "constant", "sparse"};

/* Value of channel c at block position (x, y, z) for a block of the given kind; g holds the
 * block's random parameters. */
static uint8_t block_value(int kind, const int g[12], rng *r, int x, int y, int z, int c)
{
    switch (kind) {
    case KIND_UNIFORM: return (uint8_t)rng_range(r, 0, 255);
    case KIND_SMOOTH:
        return clamp_u8(g[c] + g[3 + c] * x + g[6 + c] * y + g[9] * z + rng_range(r, -2, 2));
    case KIND_CLUSTERS: return clamp_u8((((x + y + z) % 3 == 0) ? g[c] : g[3 + c]) +
                                        rng_range(r, -4, 4));
    case KIND_OPPOSITE: {
        int t = g[3] * (x + 4 * y) / 15;
        return clamp_u8(c == 1 ? g[0] - t : g[0] + t - g[1] * c);
    }
    case KIND_CONSTANT: return (uint8_t)g[c];
    default: return (uint8_t)(rng_range(r, 0, 9) == 0 ? g[c] : 0);
    }
}

typedef struct one_block {
    size_t dims[3];
    uint8_t src[3][192], dst[3][192];
    uint8_t chunk[20];
    size_t nframes, nvox;
} one_block;

static void fill_block(const cdvr_pvtc_params *p, int kind, rng *r, one_block *b)
{
    int g[12];
    for (int i = 0; i < 12; i++)
        g[i] = (i < 3) ? rng_range(r, 0, 255) : rng_range(r, -40, 40);
    if (kind == KIND_OPPOSITE) {
        g[0] = rng_range(r, 60, 200);
        g[3] = rng_range(r, 20, 120);
    }
    int space = p->pack == CDVR_PACK_SPACE;
    b->dims[0] = 4;
    b->dims[1] = 4;
    b->dims[2] = (size_t)(p->S * (space ? p->T : 1));
    b->nframes = space ? 1 : (size_t)p->T;
    b->nvox = 16 * b->dims[2];
    for (size_t f = 0; f < b->nframes; f++)
        for (int z = 0; z < (int)b->dims[2]; z++)
            for (int i = 0; i < 16; i++) {
                int zpos = space ? z / p->T : z, c = space ? z % p->T : (int)f;
                b->src[f][16 * z + i] = block_value(kind, g, r, i % 4, i / 4, zpos, c);
            }
}

static uint32_t encode_error(const cdvr_pvtc_params *p, cdvr_pvtc_encoder enc, one_block *b)
{
    const uint8_t *in[3] = {b->src[0], b->src[1], b->src[2]};
    uint8_t *out[3] = {b->dst[0], b->dst[1], b->dst[2]};
    cdvr_error err;
    cdvr_status st = cdvr_pvtc_encode_chunk(p, enc, b->dims, in, b->chunk, &err);
    if (st == CDVR_OK)
        st = cdvr_pvtc_decode_chunk(p, b->dims, b->chunk, 4 + 4 * (size_t)p->S, out, b->nframes,
                                    &err);
    CHECK_OK(st, err);
    uint32_t sse = 0;
    for (size_t f = 0; f < b->nframes; f++)
        for (size_t i = 0; i < b->nvox; i++) {
            int d = (int)b->src[f][i] - (int)b->dst[f][i];
            sse += (uint32_t)(d * d);
        }
    return sse;
}

static void test_never_worse(void)
{
    const cdvr_pvtc_params variants[8] = {
        {1, 3, CDVR_PACK_TIME}, {1, 2, CDVR_PACK_TIME}, {4, 3, CDVR_PACK_TIME},
        {4, 2, CDVR_PACK_TIME}, {1, 3, CDVR_PACK_SPACE}, {1, 2, CDVR_PACK_SPACE},
        {4, 3, CDVR_PACK_SPACE}, {4, 2, CDVR_PACK_SPACE}};
    rng r = {20240611u};
    one_block b;
    for (int v = 0; v < 8; v++) {
        const cdvr_pvtc_params *p = &variants[v];
        for (int kind = 0; kind < KIND_COUNT; kind++) {
            double sum_lsq = 0, sum_bbox = 0;
            int worse = 0;
            for (int n = 0; n < BLOCKS_PER_KIND; n++) {
                fill_block(p, kind, &r, &b);
                uint32_t e_bbox = encode_error(p, CDVR_ENCODER_BBOX, &b);
                uint32_t e_lsq = encode_error(p, CDVR_ENCODER_LSQ, &b);
                worse += e_lsq > e_bbox;
                sum_lsq += e_lsq;
                sum_bbox += e_bbox;
            }
            CHECK(worse == 0, "S%dT%d %s %s: lsq worse than bbox on %d blocks", p->S, p->T,
                  p->pack ? "space" : "time", KIND_NAME[kind], worse);
            /* where bbox is far off the data's line, least squares must gain clearly */
            if (kind == KIND_SMOOTH || kind == KIND_OPPOSITE || kind == KIND_CLUSTERS)
                CHECK(sum_lsq < 0.8 * sum_bbox, "S%dT%d %s %s: lsq %.0f vs bbox %.0f", p->S,
                      p->T, p->pack ? "space" : "time", KIND_NAME[kind], sum_lsq, sum_bbox);
        }
    }
}

/* Squared error of a whole series encoded with S1T3 or S4T3 time packing. */
static double series_mse(const cdvr_volume *q, int S, cdvr_pvtc_encoder enc)
{
    cdvr_pvtc_params p = {S, 3, CDVR_PACK_TIME};
    cdvr_pvtc_geometry g;
    cdvr_error err;
    if (cdvr_pvtc_geometry_get(&p, q->dims, &g, &err) != CDVR_OK)
        return -1;
    size_t n = cdvr_volume_voxels(q);
    uint8_t *chunk = malloc(g.chunk_bytes), *dec = malloc(3 * n);
    double sse = 0;
    for (size_t t0 = 0; t0 < q->timesteps; t0 += 3) {
        const uint8_t *in[3];
        uint8_t *out[3];
        size_t nf = q->timesteps - t0 < 3 ? q->timesteps - t0 : 3;
        for (size_t c = 0; c < 3; c++) {
            in[c] = cdvr_volume_frame(q, t0 + (c < nf ? c : nf - 1));
            out[c] = dec + c * n;
        }
        cdvr_status st = cdvr_pvtc_encode_chunk(&p, enc, q->dims, in, chunk, &err);
        if (st == CDVR_OK)
            st = cdvr_pvtc_decode_chunk(&p, q->dims, chunk, g.chunk_bytes, out, nf, &err);
        CHECK_OK(st, err);
        for (size_t c = 0; c < nf; c++)
            for (size_t i = 0; i < n; i++) {
                double d = (double)in[c][i] - dec[c * n + i];
                sse += d * d;
            }
    }
    free(chunk);
    free(dec);
    return sse / ((double)n * (double)q->timesteps);
}

/* Real data: six viscous-fingers timesteps quantised over [0, max]; lsq must gain >= 1.5 dB (the target). */
static int test_real_data(void)
{
    const char *dir = check_shared_data();
    if (!dir)
        return 0;
    char paths[6][1024];
    const char *ptrs[6];
    for (int i = 0; i < 6; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/series/viscousfingers/vf_t%03d.nrrd", dir,
                 60 + i);
        ptrs[i] = paths[i];
    }
    cdvr_volume *vol = NULL, *q = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load_series(ptrs, 6, NULL, &vol, &err);
    CHECK_OK(st, err);
    if (st != CDVR_OK)
        return 1;
    double lo, hi;
    cdvr_volume_range(vol, &lo, &hi);
    st = cdvr_volume_quantize(vol, 0.0, hi, &q, NULL, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK)
        for (int S = 1; S <= 4; S += 3) {
            double mse_bbox = series_mse(q, S, CDVR_ENCODER_BBOX);
            double mse_lsq = series_mse(q, S, CDVR_ENCODER_LSQ);
            double gain = 10.0 * log10(mse_bbox / mse_lsq);
            printf("viscous fingers t060-065 S%dT3 time: mse bbox %.3f lsq %.3f gain %.2f dB\n",
                   S, mse_bbox, mse_lsq, gain);
            CHECK(mse_lsq > 0 && gain >= 1.5, "S%dT3 gain %.2f dB", S, gain);
        }
    cdvr_volume_free(vol);
    cdvr_volume_free(q);
    return 1;
}

int main(void)
{
    test_never_worse();
    if (!test_real_data())
        printf("CDVR_SHARED_DATA not set: real-data check skipped\n");
    return check_finish();
}
