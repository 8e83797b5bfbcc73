/* tests/test_hvq.c - the hvq codec (cdvr/hvq.h) through its codec table and directly: round
 * trips with the error bound of the residual stage, the whole-frame decoder against the
 * per-voxel fetch on every voxel, determinism (twice, 1 vs N threads), the hard cases of
 * DESIGN.md section 9 (all-zero volume, identical blocks / degenerate PCA, fewer distinct
 * vectors than entries, empty k-means clusters, hashes that must grow, odd dims, empty
 * residual hash), perfect-hash properties on random key sets, corrupt payloads. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/codec.h"
#include "cdvr/hvq.h"
#include "cdvr/volume.h"
#include "check.h"
#include "codec/hvq/hvq_internal.h"

static uint32_t rng_next(uint32_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 17;
    *s ^= *s << 5;
    return *s;
}

/* Smooth blobs, a zero background, a sharp edge and some noise: every kind of block. */
static uint8_t *make_volume(const size_t d[3], uint32_t seed)
{
    uint8_t *v = malloc(d[0] * d[1] * d[2]);
    for (size_t z = 0; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            for (size_t x = 0; x < d[0]; x++) {
                double fx = (double)x / d[0], fy = (double)y / d[1], fz = (double)z / d[2];
                double r2 = (fx - 0.5) * (fx - 0.5) + (fy - 0.5) * (fy - 0.5) + (fz - 0.4) * (fz - 0.4);
                int val = r2 > 0.16 ? 0 : (int)(120 + 100 * fx * fy - 60 * fz);
                if (x % 23 < 3)
                    val = 250; /* sharp slabs */
                if (val > 0)
                    val += (int)(rng_next(&seed) % 9) - 4;
                v[x + d[0] * (y + d[1] * z)] = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
            }
    return v;
}

typedef struct encoded {
    uint8_t *bytes;
    size_t n;
    cdvr_hvq_stats stats;
} encoded;

static int encode(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *frame,
                  unsigned threads, encoded *out)
{
    cdvr_error err;
    size_t bound;
    memset(out, 0, sizeof *out);
    cdvr_status s = cdvr_hvq_bound(p, d, &bound, &err);
    CHECK_OK(s, err);
    out->bytes = s == CDVR_OK ? malloc(bound) : NULL;
    if (!out->bytes)
        return 0;
    s = cdvr_hvq_encode(p, d, frame, threads, out->bytes, bound, &out->n, &out->stats, &err);
    CHECK_OK(s, err);
    CHECK(s != CDVR_OK || out->n <= bound, "payload %zu > bound %zu", out->n, bound);
    return s == CDVR_OK;
}

/* decode_cells (hvq_decode_cells_threads) against the whole decode dec: every voxel of a needed
 * cell, residual ones included, in both layouts (tiled through cdvr_tiled_offset, the padding
 * of edge tiles repeating the frame's last voxel), cells of 4 and 8 voxels, every third cell
 * left out; voxels of cells left out keep what the frame held where no needed block covers
 * them. */
static void verify_cells(const cdvr_hvq_params *p, const size_t d[3], const encoded *e,
                         const uint8_t *dec, const char *what)
{
    size_t n = d[0] * d[1] * d[2], tb = cdvr_tiled_bytes(d);
    uint8_t *lin = malloc(n), *tiles = malloc(tb);
    cdvr_error err;
    for (unsigned log2 = 2; lin && tiles && log2 <= 3; log2++) {
        size_t c[3], cells = 1, bad = 0, bad_pad = 0;
        for (int a = 0; a < 3; a++)
            cells *= c[a] = ((d[a] - 1) >> log2) + 1;
        uint8_t *need = malloc(cells);
        for (size_t i = 0; i < cells; i++)
            need[i] = (uint8_t)(i % 3 != 1);
        memset(lin, 0x5A, n);
        memset(tiles, 0x5A, tb);
        CHECK_OK(hvq_decode_cells_threads(p, d, e->bytes, e->n, lin, CDVR_LAYOUT_LINEAR, need,
                                          log2, 3, &err), err);
        CHECK_OK(hvq_decode_cells_threads(p, d, e->bytes, e->n, tiles, CDVR_LAYOUT_TILED, need,
                                          log2, 2, &err), err);
        for (size_t z = 0; z < (d[2] + 3) / 4 * 4; z++)
            for (size_t y = 0; y < (d[1] + 3) / 4 * 4; y++)
                for (size_t x = 0; x < (d[0] + 3) / 4 * 4; x++) {
                    size_t sx = x < d[0] ? x : d[0] - 1, sy = y < d[1] ? y : d[1] - 1;
                    size_t sz = z < d[2] ? z : d[2] - 1, i = sx + d[0] * (sy + d[1] * sz);
                    if (!need[(sx >> log2) + c[0] * ((sy >> log2) + c[1] * (sz >> log2))])
                        continue;
                    uint8_t t = tiles[cdvr_tiled_offset(d, x, y, z)];
                    if (x == sx && y == sy && z == sz)
                        bad += lin[i] != dec[i] || t != dec[i];
                    else
                        bad_pad += t != dec[i];
                }
        CHECK(bad == 0 && bad_pad == 0, "%s: cells of %u: %zu voxels and %zu padding voxels "
              "differ from the whole decode", what, 1u << log2, bad, bad_pad);
        free(need);
    }
    free(lin);
    free(tiles);
}

/* Decodes, checks the error bound, the fetch of every voxel, the check's figures. Returns the
 * largest error (or -1). */
static int verify(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *frame,
                  const encoded *e, const char *what)
{
    size_t n = d[0] * d[1] * d[2], fetch_bad = 0;
    uint8_t *dec = malloc(n);
    cdvr_error err;
    memset(dec, 0xA5, n);
    cdvr_status s = cdvr_hvq_decode(p, d, e->bytes, e->n, dec, &err);
    CHECK_OK(s, err);
    int maxerr = -1;
    if (s == CDVR_OK) {
        maxerr = 0;
        for (size_t z = 0, i = 0; z < d[2]; z++)
            for (size_t y = 0; y < d[1]; y++)
                for (size_t x = 0; x < d[0]; x++, i++) {
                    int err_i = abs(dec[i] - frame[i]);
                    maxerr = err_i > maxerr ? err_i : maxerr;
                    fetch_bad += cdvr_hvq_fetch(e->bytes, d, x, y, z) != dec[i];
                }
        CHECK(maxerr <= (int)p->residual, "%s: max error %d > residual %u", what, maxerr,
              p->residual);
        CHECK(fetch_bad == 0, "%s: %zu voxels fetch differently from the decoder", what,
              fetch_bad);
        uint8_t *again = malloc(n);
        for (unsigned threads = 1; again && threads <= 7; threads += 2) {
            memset(again, 0x5A, n);
            s = hvq_decode_threads(p, d, e->bytes, e->n, again, threads, &err);
            CHECK(s == CDVR_OK && memcmp(again, dec, n) == 0,
                  "%s: decoded on %u threads differently", what, threads);
        }
        free(again);
        verify_cells(p, d, e, dec, what);
    }
    cdvr_hvq_stats st;
    s = cdvr_hvq_check(p, d, e->bytes, e->n, &st, &err);
    CHECK_OK(s, err);
    CHECK(st.header + st.means + st.codebook1 + st.codebook2 + st.index_hash +
                  st.residual_hash == e->n,
          "%s: parts do not add up to %zu bytes", what, e->n);
    CHECK(st.zero_blocks == e->stats.zero_blocks && st.residual_voxels == e->stats.residual_voxels &&
              st.index_hash == e->stats.index_hash && st.residual_hash == e->stats.residual_hash,
          "%s: check and encoder disagree (zero blocks %zu/%zu, residuals %zu/%zu)", what,
          st.zero_blocks, e->stats.zero_blocks, st.residual_voxels, e->stats.residual_voxels);
    free(dec);
    return maxerr;
}

/* Round trip + determinism (encode twice, 1 and 3 threads). */
static encoded round_trip(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *frame,
                          const char *what)
{
    encoded a, b, c;
    if (!encode(p, d, frame, 1, &a))
        return a;
    verify(p, d, frame, &a, what);
    if (encode(p, d, frame, 1, &b))
        CHECK(b.n == a.n && memcmp(a.bytes, b.bytes, a.n) == 0, "%s: two encodes differ", what);
    if (encode(p, d, frame, 3, &c))
        CHECK(c.n == a.n && memcmp(a.bytes, c.bytes, a.n) == 0, "%s: 1 and 3 threads differ",
              what);
    free(b.bytes);
    free(c.bytes);
    return a;
}

/* ---- codec table ------------------------------------------------------------------------- */

static void emit_sum(void *ud, const char *key, double value)
{
    double *sum = ud;
    if (strcmp(key, "blocks") && strcmp(key, "zero_blocks") && strcmp(key, "residual_voxels"))
        sum[0] += value;
    if (strcmp(key, "zero_blocks") == 0)
        sum[1] = value;
}

static void test_table(void)
{
    const cdvr_codec *c = cdvr_codec_find("hvq");
    CHECK(c && c == cdvr_codec_by_id(CDVR_CODEC_ID_HVQ), "hvq is not registered as id 2");
    if (!c)
        return;
    CHECK(c->cl_mode == CDVR_CODEC_CL_FETCH && strcmp(c->cl_file, "codec/hvq_fetch.cl") == 0 &&
              strcmp(c->cl_function, "hvq_fetch") == 0 && c->describe,
          "hvq table: OpenCL fetch mode and describe");
    cdvr_codec_params blob;
    cdvr_error err;
    char name[CDVR_VARIANT_NAME_MAX], text[64];
    cdvr_status s = cdvr_codec_params_parse(c, NULL, NULL, 0, &blob, &err);
    CHECK_OK(s, err);
    c->variant_name(&blob, name, sizeof name);
    CHECK(strcmp(name, "hvq") == 0, "default variant name '%s'", name);
    const char *keys[] = {"grad", "residual", "k1", "k2", "eps", "train"};
    const char *vals[] = {"32.5", "5", "128", "512", "0.002", "0"};
    s = cdvr_codec_params_parse(c, keys, vals, 6, &blob, &err);
    CHECK_OK(s, err);
    c->variant_name(&blob, name, sizeof name);
    CHECK(strcmp(name, "hvq_g32.5_r5_k128x512_e0.002_t0") == 0, "variant name '%s'", name);
    for (int i = 0; i < 6; i++) {
        CHECK(c->params_get(&blob, keys[i], text, sizeof text) == 0, "get %s", keys[i]);
        cdvr_codec_params again = blob;
        s = c->params_set(&again, keys[i], text, &err);
        CHECK(s == CDVR_OK && memcmp(&again, &blob, sizeof blob) == 0, "%s = '%s' does not read "
              "back", keys[i], text);
    }
    CHECK(c->params_get(&blob, "nope", text, sizeof text) == -1, "unknown key get");
    const char *bad[][2] = {{"grad", "-1"}, {"grad", "nan"}, {"grad", "800"}, {"eps", "0"},
                            {"eps", "1"}, {"residual", "256"}, {"residual", "-3"},
                            {"k1", "0"}, {"k2", "4097"}, {"k1", "12x"}, {"train", ""},
                            {"gard", "1"}};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        s = c->params_set(&blob, bad[i][0], bad[i][1], &err);
        CHECK(s == CDVR_ERR_ARG && strstr(err.msg, bad[i][0]), "%s = '%s' accepted (%s)",
              bad[i][0], bad[i][1], err.msg);
    }
    c->params_default(&blob);
    blob.bytes[40] = 1;
    CHECK(c->params_check(&blob, &err) == CDVR_ERR_ARG, "unused parameter byte accepted");
    c->params_default(&blob);
    size_t dims[3] = {5, 3, 7};
    cdvr_codec_shape shape;
    s = cdvr_codec_shape_of(c, &blob, dims, &shape, &err);
    CHECK(s == CDVR_OK && shape.timesteps == 1 && shape.payload_bytes == 0 && shape.bound_bytes,
          "shape 5x3x7: %zu timesteps, %zu bytes, bound %zu", shape.timesteps,
          shape.payload_bytes, shape.bound_bytes);
    size_t huge[3] = {(size_t)1 << 40, (size_t)1 << 40, 4};
    CHECK(cdvr_codec_shape_of(c, &blob, huge, &shape, &err) != CDVR_OK, "absurd dims accepted");
    /* encode/decode/describe through the table */
    uint8_t frame[105], out[105];
    for (int i = 0; i < 105; i++)
        frame[i] = (uint8_t)(i * 37 % 200);
    uint8_t *payload = malloc(shape.bound_bytes);
    const uint8_t *frames[1] = {frame};
    uint8_t *outs[1] = {out};
    size_t bytes = 0;
    s = c->encode(&blob, dims, frames, 1, payload, shape.bound_bytes, &bytes, &err);
    CHECK_OK(s, err);
    s = c->decode(&blob, dims, payload, bytes, outs, 1, &err);
    CHECK_OK(s, err);
    int maxerr = 0;
    for (int i = 0; i < 105; i++)
        maxerr = abs(out[i] - frame[i]) > maxerr ? abs(out[i] - frame[i]) : maxerr;
    CHECK(maxerr <= 10, "table round trip: max error %d", maxerr);
    double sum[2] = {0, -1};
    s = c->describe(&blob, dims, payload, bytes, emit_sum, sum, &err);
    CHECK(s == CDVR_OK && sum[0] == (double)bytes && sum[1] >= 0, "describe: parts %g of %zu "
          "bytes", sum[0], bytes);
    s = c->encode(&blob, dims, frames, 1, payload, bytes - 1, &bytes, &err);
    CHECK(s == CDVR_ERR_ARG, "encode into a short buffer: status %d", (int)s);
    free(payload);
}

/* ---- hard cases ---------------------------------------------------------------------------- */

static void test_all_zero(void)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    const size_t d[3] = {37, 20, 9};
    uint8_t *v = calloc(37 * 20 * 9, 1);
    encoded e = round_trip(&p, d, v, "all zero");
    if (e.bytes) {
        CHECK(e.stats.codebook1_entries == 0 && e.stats.codebook2_entries == 0 &&
                  e.stats.zero_blocks == e.stats.blocks && e.stats.residual_voxels == 0,
              "all zero: %zu/%zu entries, %zu of %zu zero blocks, %zu residuals",
              e.stats.codebook1_entries, e.stats.codebook2_entries, e.stats.zero_blocks,
              e.stats.blocks, e.stats.residual_voxels);
        CHECK(verify(&p, d, v, &e, "all zero") == 0, "all zero decodes with errors");
    }
    free(e.bytes);
    /* grad = 0: even flat blocks are quantised (one all-zero codeword) */
    p.grad = 0;
    e = round_trip(&p, d, v, "all zero, grad 0");
    CHECK(!e.bytes || (e.stats.zero_blocks == 0 && e.stats.codebook1_entries == 1 &&
                       e.stats.codebook2_entries == 1),
          "all zero grad 0: %zu zero blocks, %zu/%zu entries", e.stats.zero_blocks,
          e.stats.codebook1_entries, e.stats.codebook2_entries);
    free(e.bytes);
    free(v);
}

/* Every block holds the same varied pattern: every vector is equal, PCA has nothing to split
 * (zero covariance), one entry per codebook, and the decode is exact. */
static void test_identical_blocks(void)
{
    const size_t d[3] = {16, 12, 8};
    uint8_t *v = malloc(16 * 12 * 8);
    for (size_t i = 0; i < 16 * 12 * 8; i++) {
        size_t x = i % 16, y = i / 16 % 12, z = i / 192;
        v[i] = (uint8_t)(17 + 61 * ((x % 4) ^ (y % 4)) + 13 * (z % 4) + (x % 4 == 3 ? 3 : 0));
    }
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 1;
    encoded e = round_trip(&p, d, v, "identical blocks");
    if (e.bytes) {
        CHECK(e.stats.codebook1_entries == 1 && e.stats.codebook2_entries == 1 &&
                  e.stats.zero_blocks == 0 && e.stats.residual_voxels == 0,
              "identical blocks: %zu/%zu entries, %zu zero blocks, %zu residuals",
              e.stats.codebook1_entries, e.stats.codebook2_entries, e.stats.zero_blocks,
              e.stats.residual_voxels);
        CHECK(verify(&p, d, v, &e, "identical blocks") == 0, "identical blocks not exact");
    }
    free(e.bytes);
    free(v);
}

/* Three distinct block patterns, codebooks of 256: at most three entries each, exact. */
static void test_few_distinct(void)
{
    const size_t d[3] = {24, 8, 12};
    uint8_t *v = malloc(24 * 8 * 12);
    for (size_t i = 0; i < 24 * 8 * 12; i++) {
        size_t x = i % 24, y = i / 24 % 8, z = i / 192, kind = (x / 4 + y / 4 + z / 4) % 3;
        v[i] = (uint8_t)(kind == 0 ? 10 + 50 * (x % 4) : kind == 1 ? 200 - 40 * (z % 4)
                                                               : 90 + 30 * ((x + y + z) % 2));
    }
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 0.5;
    encoded e = round_trip(&p, d, v, "three patterns");
    if (e.bytes) {
        CHECK(e.stats.codebook1_entries <= 3 && e.stats.codebook2_entries <= 3 &&
                  e.stats.residual_voxels == 0,
              "three patterns: %zu/%zu entries, %zu residuals", e.stats.codebook1_entries,
              e.stats.codebook2_entries, e.stats.residual_voxels);
        CHECK(verify(&p, d, v, &e, "three patterns") == 0, "three patterns not exact");
    }
    free(e.bytes);
    free(v);
}

/* LBG started with a centroid no vector is near (empty cluster: re-seeded), and with more
 * centroids than distinct vectors (empty clusters that cannot be re-seeded: dropped). */
static void test_empty_clusters(void)
{
    enum { N = 200, D = 8 };
    int16_t vec[N * D];
    uint32_t seed = 99;
    for (int i = 0; i < N; i++)
        for (int a = 0; a < D; a++)
            vec[i * D + a] = (int16_t)((i % 2 ? 100 : -100) + (int)(rng_next(&seed) % 21) - 10);
    float cent[3 * D];
    for (int a = 0; a < D; a++) {
        cent[a] = 0;          /* between the two groups */
        cent[D + a] = 30000;  /* far from everything: empty at once */
        cent[2 * D + a] = -1; /* next to the first: loses everything */
    }
    unsigned k = 3;
    int64_t sums[3 * D];
    uint64_t counts[3];
    hvq_vq_report rep;
    memset(&rep, 0, sizeof rep);
    cdvr_error err;
    cdvr_status s = hvq_lbg(vec, N, D, cent, &k, 1e-6, 2, sums, counts, &rep, &err);
    CHECK_OK(s, err);
    CHECK(rep.reseeded >= 1 && k == 3, "empty cluster: %u re-seeded, %u entries", rep.reseeded,
          k);
    for (unsigned j = 0; j < k; j++)
        CHECK(counts[j] > 0, "cluster %u is empty at the end", j);
    /* two distinct vectors, four centroids: two must go */
    for (int i = 0; i < N; i++)
        for (int a = 0; a < D; a++)
            vec[i * D + a] = (int16_t)(i % 2 ? 7 : -7);
    float c4[4 * D];
    for (int j = 0; j < 4; j++)
        for (int a = 0; a < D; a++)
            c4[j * D + a] = (float)(j * 1000);
    k = 4;
    memset(&rep, 0, sizeof rep);
    int64_t sums4[4 * D];
    uint64_t counts4[4];
    s = hvq_lbg(vec, N, D, c4, &k, 1e-6, 1, sums4, counts4, &rep, &err);
    CHECK(s == CDVR_OK && k == 2 && rep.dropped == 2 && rep.distortion == 0,
          "two distinct vectors: %u entries, %u dropped, distortion %g", k, rep.dropped,
          rep.distortion);
    /* the whole training: fewer distinct vectors than k */
    int16_t book[256 * D];
    unsigned kout = 0;
    s = hvq_vq_train(vec, N, D, 256, 1, 0.001, 0, 2, book, &kout, &rep, &err);
    CHECK(s == CDVR_OK && kout == 2, "train on 2 distinct vectors: %u entries", kout);
}

static void test_odd_dims(void)
{
    const size_t dims[][3] = {{1, 1, 1}, {5, 3, 7}, {4, 4, 4}, {2, 9, 1}, {257, 5, 3},
                              {3, 262, 6}, {260, 2, 258}};
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 8;
    for (size_t i = 0; i < sizeof dims / sizeof *dims; i++) {
        char what[64];
        snprintf(what, sizeof what, "dims %zux%zux%zu", dims[i][0], dims[i][1], dims[i][2]);
        uint8_t *v = make_volume(dims[i], 7u + (uint32_t)i);
        encoded e = round_trip(&p, dims[i], v, what);
        free(e.bytes);
        free(v);
    }
}

/* A smooth volume with residual 255: no residual voxel, every residual hash empty; and
 * residual 0 on noise: lossless, a dense residual hash. */
static void test_residual_extremes(void)
{
    const size_t d[3] = {40, 30, 20};
    uint8_t *v = make_volume(d, 5);
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 4;
    p.residual = 255;
    encoded e = round_trip(&p, d, v, "residual 255");
    CHECK(!e.bytes || (e.stats.residual_voxels == 0 && e.stats.residual_hash == 0),
          "residual 255: %zu residual voxels, %zu bytes", e.stats.residual_voxels,
          e.stats.residual_hash);
    free(e.bytes);
    uint32_t seed = 3;
    for (size_t i = 0; i < 40 * 30 * 20; i++)
        v[i] = (uint8_t)rng_next(&seed);
    p.residual = 0;
    p.k1 = p.k2 = 16;
    e = round_trip(&p, d, v, "residual 0 on noise");
    CHECK(!e.bytes || (e.stats.residual_voxels > 20000 && verify(&p, d, v, &e, "noise") == 0),
          "noise: %zu residual voxels", e.stats.residual_voxels);
    free(e.bytes);
    free(v);
}

/* Volumes across several regions with every feature; k above 256 (two-byte indices). */
static void test_regions_and_wide_indices(void)
{
    const size_t d[3] = {300, 40, 33};
    uint8_t *v = make_volume(d, 11);
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 2;
    p.k1 = 300;
    p.k2 = 600;
    p.train = 2000;
    encoded e = round_trip(&p, d, v, "300x40x33 k 300x600");
    CHECK(!e.bytes || (e.stats.regions == 2 && e.stats.zero_blocks > 0 &&
                       e.stats.zero_blocks < e.stats.blocks && e.stats.codebook1_entries > 256 &&
                       e.stats.codebook2_entries > 256 &&
                       e.stats.codebook2_entries <= (e.stats.blocks - e.stats.zero_blocks + 7) / 8),
          "regions %zu, zero blocks %zu of %zu, entries %zu/%zu (two-byte indices, at most one "
          "per 8 blocks)", e.stats.regions, e.stats.zero_blocks, e.stats.blocks,
          e.stats.codebook1_entries, e.stats.codebook2_entries);
    free(e.bytes);
    free(v);
}

/* ---- perfect spatial hashes ----------------------------------------------------------------- */

static void check_hash(const uint8_t *keys, size_t n, unsigned extent, const hvq_psh *h,
                       const char *what)
{
    uint8_t *member = calloc((size_t)extent * extent * extent, 1);
    uint8_t *slot_used = calloc((size_t)h->m * h->m * h->m + 1, 1);
    size_t collisions = 0, missing = 0, wrong = 0, false_hits = 0;
    for (size_t i = 0; i < n; i++) {
        const uint8_t *k = keys + 3 * i;
        member[k[0] + extent * (k[1] + (size_t)extent * k[2])] = 1;
        uint64_t s = hvq_psh_slot(h->data, h->m, h->r, k[0], k[1], k[2]);
        collisions += slot_used[s]++ != 0;
        const uint8_t *val = hvq_psh_find(h->data, h->m, h->r, 5, k[0], k[1], k[2]);
        missing += val == NULL;
        wrong += val && (val[0] != (uint8_t)i || val[1] != (uint8_t)(i >> 8));
    }
    for (unsigned z = 0; z < extent; z++)
        for (unsigned y = 0; y < extent; y++)
            for (unsigned x = 0; x < extent; x++)
                if (!member[x + extent * (y + (size_t)extent * z)])
                    false_hits += hvq_psh_find(h->data, h->m, h->r, 5, x, y, z) != NULL;
    hvq_psh_map map;
    hvq_psh_map_open(&map, h->data, h->m, h->r);
    size_t map_differs = 0;
    for (unsigned z = 0; z < extent; z++)
        for (unsigned y = 0; y < extent; y++)
            for (unsigned x = 0; x < extent; x++)
                map_differs += hvq_psh_map_find(&map, 5, x, y, z) !=
                               hvq_psh_find(h->data, h->m, h->r, 5, x, y, z);
    CHECK(map_differs == 0, "%s: hvq_psh_map_find differs from hvq_psh_find at %zu keys", what,
          map_differs);
    uint64_t m3 = (uint64_t)h->m * h->m * h->m;
    CHECK(collisions == 0 && missing == 0 && wrong == 0 && false_hits == 0 && m3 >= n,
          "%s: %zu keys in %u^3 slots (r %u): %zu collisions, %zu missing, %zu wrong values, "
          "%zu absent keys found", what, n, h->m, h->r, collisions, missing, wrong, false_hits);
    free(member);
    free(slot_used);
}

/* hvq_psh_map_slot against hvq_psh_slot on made-up offset tables (every entry below m, as the
 * check requires) for sides across both offset widths, at every key coordinate 0..255 on each
 * axis and at random keys. */
static void test_psh_map(void)
{
    const uint32_t sides[][2] = {{1, 1}, {2, 1}, {3, 2}, {7, 5}, {64, 9}, {255, 16},
                                 {256, 17}, {257, 31}, {600, 101}, {1023, 256}};
    uint32_t seed = 77;
    for (size_t c = 0; c < sizeof sides / sizeof *sides; c++) {
        uint32_t m = sides[c][0], r = sides[c][1];
        unsigned w = hvq_offset_width(m);
        size_t entries = (size_t)r * r * r;
        uint8_t *data = malloc(3 * w * entries);
        for (size_t i = 0; i < 3 * entries; i++) {
            uint32_t off = rng_next(&seed) % m;
            if (w == 1)
                data[i] = (uint8_t)off;
            else
                hvq_wr16(data + 2 * i, off);
        }
        hvq_psh_map map;
        hvq_psh_map_open(&map, data, m, r);
        size_t differs = 0;
        for (unsigned k = 0; k < 256; k++) {
            unsigned kx = k, ky = 255 - k, kz = (k * 37) & 255;
            differs += hvq_psh_map_slot(&map, kx, ky, kz) != hvq_psh_slot(data, m, r, kx, ky, kz);
            differs += hvq_psh_map_slot(&map, kz, kx, ky) != hvq_psh_slot(data, m, r, kz, kx, ky);
        }
        for (int i = 0; i < 20000; i++) {
            unsigned kx = rng_next(&seed) & 255, ky = rng_next(&seed) & 255,
                     kz = rng_next(&seed) & 255;
            differs += hvq_psh_map_slot(&map, kx, ky, kz) != hvq_psh_slot(data, m, r, kx, ky, kz);
        }
        CHECK(differs == 0, "hvq_psh_map_slot: m %u r %u: %zu keys map elsewhere than "
              "hvq_psh_slot", m, r, differs);
        free(data);
    }
}

static void test_hashes(void)
{
    const size_t counts[] = {1, 2, 7, 64, 500, 4000, 30000, 120000, 262144};
    const unsigned extents[] = {1, 64, 64, 64, 64, 64, 64, 64, 64};
    uint32_t seed = 2024;
    for (size_t c = 0; c < sizeof counts / sizeof *counts; c++) {
        size_t n = counts[c];
        unsigned ext = extents[c];
        uint8_t *keys = malloc(3 * n), *vals = malloc(2 * n);
        uint8_t *taken = calloc((size_t)ext * ext * ext, 1);
        for (size_t i = 0; i < n;) {
            uint32_t x = rng_next(&seed) % ext, y = rng_next(&seed) % ext, z = rng_next(&seed) % ext;
            if (n == (size_t)ext * ext * ext) { /* dense: every point */
                x = (uint32_t)(i % ext);
                y = (uint32_t)(i / ext % ext);
                z = (uint32_t)(i / ext / ext);
            } else if (taken[x + ext * (y + ext * z)]++) {
                continue;
            }
            keys[3 * i] = (uint8_t)x;
            keys[3 * i + 1] = (uint8_t)y;
            keys[3 * i + 2] = (uint8_t)z;
            vals[2 * i] = (uint8_t)i;
            vals[2 * i + 1] = (uint8_t)(i >> 8);
            i++;
        }
        hvq_psh h;
        cdvr_error err;
        cdvr_status s = hvq_psh_build(keys, vals, n, 2, HVQ_PSH_ATTEMPTS, &h, &err);
        CHECK_OK(s, err);
        char what[64];
        snprintf(what, sizeof what, "random hash of %zu keys", n);
        if (s == CDVR_OK) {
            uint32_t a = h.m, b = h.r;
            while (b) {
                uint32_t t = a % b;
                a = b;
                b = t;
            }
            CHECK(a == 1, "%s: gcd(m=%u, r=%u) = %u", what, h.m, h.r, a);
            check_hash(keys, n, ext, &h, what);
        }
        hvq_psh_free(&h);
        free(keys);
        free(vals);
        free(taken);
    }
    /* two keys 60 apart along x: every small table puts them in one slot (same h0 and h1)
     * until the schedule grows r; one attempt only: a clear error */
    const uint8_t keys[6] = {0, 0, 0, 60, 0, 0}, vals[4] = {0, 0, 1, 0};
    hvq_psh h;
    cdvr_error err;
    cdvr_status s = hvq_psh_build(keys, vals, 2, 2, HVQ_PSH_ATTEMPTS, &h, &err);
    CHECK(s == CDVR_OK && h.attempts > 1, "twins: status %d after %d attempts", (int)s,
          h.attempts);
    if (s == CDVR_OK)
        check_hash(keys, 2, 64, &h, "twins");
    hvq_psh_free(&h);
    s = hvq_psh_build(keys, vals, 2, 2, 1, &h, &err);
    CHECK(s == CDVR_ERR_UNSUPPORTED && strstr(err.msg, "attempts"), "twins, one attempt: "
          "status %d: %s", (int)s, err.msg);
    hvq_psh_free(&h);
    /* empty set */
    s = hvq_psh_build(keys, vals, 0, 2, HVQ_PSH_ATTEMPTS, &h, &err);
    CHECK(s == CDVR_OK && h.m == 0 && h.bytes == 0 &&
              hvq_psh_find(h.data, h.m, h.r, 5, 0, 0, 0) == NULL,
          "empty hash: m %u, %zu bytes", h.m, h.bytes);
}

/* ---- corrupt payloads ------------------------------------------------------------------------ */

static void expect_corrupt(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *bytes,
                           size_t n, const char *what)
{
    uint8_t *out = malloc(d[0] * d[1] * d[2]);
    cdvr_error err;
    cdvr_status s = cdvr_hvq_decode(p, d, bytes, n, out, &err);
    CHECK(s == CDVR_ERR_CORRUPT, "%s: status %d (%s)", what, (int)s, s ? err.msg : "ok");
    free(out);
}

static void test_corrupt(void)
{
    const size_t d[3] = {20, 17, 9};
    uint8_t *v = make_volume(d, 77);
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 4;
    encoded e;
    if (!encode(&p, d, v, 1, &e)) {
        free(v);
        return;
    }
    uint8_t *m = malloc(e.n + 16);
    const uint64_t d64[3] = {20, 17, 9};
    hvq_layout L;
    hvq_layout_get(d64, hvq_rd32(e.bytes + 16), hvq_rd32(e.bytes + 20), &L);
    for (size_t cut = 0; cut < e.n; cut += 1 + cut / 3)
        expect_corrupt(&p, d, e.bytes, cut, "truncated");
    memcpy(m, e.bytes, e.n);
    m[e.n] = 0;
    expect_corrupt(&p, d, m, e.n + 1, "one byte too many");
#define MUTATE(what, stmt)                                                                    \
    do {                                                                                      \
        memcpy(m, e.bytes, e.n);                                                              \
        stmt;                                                                                 \
        expect_corrupt(&p, d, m, e.n, what);                                                  \
    } while (0)
    MUTATE("magic", m[0] = 'X');
    MUTATE("dims", m[4]++);
    MUTATE("n1 above k1", hvq_wr32(m + 16, 257));
    MUTATE("n1 = 0 alone", hvq_wr32(m + 16, 0));
    MUTATE("reserved", m[27] = 1);
    if (HVQ_HEADER_BYTES + L.nblocks < L.off_c1)
        MUTATE("padding", m[HVQ_HEADER_BYTES + L.nblocks] = 9);
    const uint8_t *dir = e.bytes + L.off_dir;
    uint32_t im = hvq_rd16(dir), ir = hvq_rd16(dir + 2);
    uint64_t ioff = hvq_rd64(dir + 8);
    CHECK(im > 0, "the corrupt-payload volume has an index hash");
    if (im > 0) {
        MUTATE("hash offset", hvq_wr64(m + L.off_dir + 8, ioff + 1));
        MUTATE("key count", hvq_wr32(m + L.off_dir + 4, hvq_rd32(dir + 4) + 1));
        MUTATE("table side", hvq_wr16(m + L.off_dir, im + 1));
        MUTATE("offset >= m", m[ioff] = (uint8_t)im);
        uint64_t slot0 = ioff + (uint64_t)ir * ir * ir * 3;
        MUTATE("index >= n1", m[slot0 + 3] = 0xff);
    }
    /* the slots of every hash are checked on several threads: with both of the region's
     * hashes damaged, the error is the index hash's (the first in the payload) on any number */
    uint32_t rm = hvq_rd16(dir + 16);
    uint64_t roff = hvq_rd64(dir + 24);
    CHECK(rm > 0, "the corrupt-payload volume has a residual hash");
    if (im > 0 && rm > 0) {
        memcpy(m, e.bytes, e.n);
        m[ioff] = (uint8_t)im;
        m[roff] = (uint8_t)rm;
        char first[sizeof(((cdvr_error *)0)->msg)] = "";
        for (unsigned threads = 1; threads <= 4; threads += 3) {
            uint8_t *out = malloc(d[0] * d[1] * d[2]);
            cdvr_error err;
            cdvr_status s = hvq_decode_threads(&p, d, m, e.n, out, threads, &err);
            CHECK(s == CDVR_ERR_CORRUPT && strstr(err.msg, "index hash"),
                  "two damaged hashes on %u threads: status %d (%s)", threads, (int)s,
                  s ? err.msg : "ok");
            if (threads == 1)
                snprintf(first, sizeof first, "%s", err.msg);
            else
                CHECK(strcmp(first, err.msg) == 0, "%u threads: '%s', one thread: '%s'",
                      threads, err.msg, first);
            free(out);
        }
    }
#undef MUTATE
    free(m);
    free(e.bytes);
    free(v);
}

/* ---- real data --------------------------------------------------------------------------------- */

static void test_neghip(void)
{
    const char *data = check_shared_data();
    if (!data)
        return;
    char path[1024];
    snprintf(path, sizeof path, "%s/sim/neghip_66x66x66_u8.nrrd", data);
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_status s = cdvr_volume_load_nrrd(path, &vol, &err);
    CHECK_OK(s, err);
    if (s)
        return;
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    encoded e = round_trip(&p, vol->dims, vol->data, "neghip");
    CHECK(!e.bytes || e.n < cdvr_volume_voxels(vol), "neghip: %zu bytes for %zu voxels", e.n,
          cdvr_volume_voxels(vol));
    free(e.bytes);
    cdvr_volume_free(vol);
}

int main(void)
{
    test_table();
    test_all_zero();
    test_identical_blocks();
    test_few_distinct();
    test_empty_clusters();
    test_odd_dims();
    test_residual_extremes();
    test_regions_and_wide_indices();
    test_psh_map();
    test_hashes();
    test_corrupt();
    test_neghip();
    return check_finish();
}
