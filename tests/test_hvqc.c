/* tests/test_hvqc.c - hvq's compact form (codec "hvqc", cdvr/hvq.h, core/codec/hvq/
 * hvq_compact.c): the codec table; round trips within the residual bound on odd dims, an
 * all-zero frame, noise with residual 0 (two-byte residual values) and residual 255; the
 * compact decode equals the hashed form's everywhere but at residual voxels (same blocks and
 * codebooks) when no axis has 4k+1 voxels (else the compact grid leaves the last plane out); the parts add up; determinism over threads; truncated and mutated payloads;
 * shared codebooks (trained on some frames, used by others and by bricks; refused without
 * them or with others; a corrupt blob) and a bricked two-timestep store with shared=1 that
 * reopens and decodes within the bound, a corrupted shared blob failing the decode; the PSNR
 * target (psnr=): met, within `residual`, the largest threshold that meets it, reported;
 * k2=auto: the smallest payload of the candidate sizes. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/codec.h"
#include "cdvr/hvq.h"
#include "cdvr/store.h"
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

/* Dark noisy background, a bright ball, sharp slabs: zero blocks, VQ blocks, residuals. */
static uint8_t *make_volume(const size_t d[3], uint32_t seed)
{
    uint8_t *v = malloc(d[0] * d[1] * d[2]);
    for (size_t z = 0, i = 0; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            for (size_t x = 0; x < d[0]; x++, i++) {
                double fx = (double)x / d[0], fy = (double)y / d[1], fz = (double)z / d[2];
                double r2 = (fx - 0.5) * (fx - 0.5) + (fy - 0.5) * (fy - 0.5) + (fz - 0.4) * (fz - 0.4);
                int val = r2 > 0.1 ? 10 : (int)(120 + 100 * fx * fy - 60 * fz);
                if (x % 23 < 2)
                    val = 240;
                val += (int)(rng_next(&seed) % 3) - 1;
                v[i] = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
            }
    return v;
}

typedef struct coded {
    uint8_t *bytes;
    size_t n;
    cdvr_hvq_stats stats;
} coded;

static int encode(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *v, int compact,
                  unsigned threads, coded *out)
{
    cdvr_error err;
    size_t bound;
    memset(out, 0, sizeof *out);
    cdvr_status s = compact ? cdvr_hvq_compact_bound(p, d, &bound, &err)
                            : cdvr_hvq_bound(p, d, &bound, &err);
    CHECK_OK(s, err);
    out->bytes = s == CDVR_OK ? malloc(bound) : NULL;
    if (!out->bytes)
        return 0;
    s = compact ? cdvr_hvq_encode_compact(p, NULL, d, v, threads, out->bytes, bound, &out->n,
                                          &out->stats, &err)
                : cdvr_hvq_encode(p, d, v, threads, out->bytes, bound, &out->n, &out->stats,
                                  &err);
    CHECK_OK(s, err);
    return s == CDVR_OK;
}

/* Round trip of both forms; returns the compact form. */
static coded round_trip(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *v,
                        const char *what)
{
    size_t n = d[0] * d[1] * d[2];
    coded c, h, c3;
    if (!encode(p, d, v, 1, 1, &c) || !encode(p, d, v, 0, 1, &h))
        return c;
    uint8_t *dc = malloc(n), *dh = malloc(n);
    cdvr_error err;
    memset(dc, 0xA5, n);
    cdvr_status s = cdvr_hvq_compact_decode(p, NULL, d, c.bytes, c.n, dc, &err);
    CHECK_OK(s, err);
    s = cdvr_hvq_decode(p, d, h.bytes, h.n, dh, &err);
    CHECK_OK(s, err);
    size_t differ = 0;
    int maxerr = 0;
    for (size_t i = 0; i < n; i++) {
        int e = abs(dc[i] - v[i]);
        maxerr = e > maxerr ? e : maxerr;
        differ += dc[i] != dh[i];
    }
    CHECK(maxerr <= (int)p->residual, "%s: max error %d > residual %u", what, maxerr,
          p->residual);
    int same_grid = hvq2_core(d[0]) == d[0] && hvq2_core(d[1]) == d[1] && hvq2_core(d[2]) == d[2];
    CHECK(!same_grid || (differ <= c.stats.residual_voxels &&
                         c.stats.residual_voxels == h.stats.residual_voxels &&
                         c.stats.zero_blocks == h.stats.zero_blocks),
          "%s: %zu voxels differ from the hashed form (%zu/%zu residuals, %zu/%zu zero blocks)",
          what, differ, c.stats.residual_voxels, h.stats.residual_voxels, c.stats.zero_blocks,
          h.stats.zero_blocks);
    cdvr_hvq_stats st;
    s = cdvr_hvq_compact_check(p, NULL, d, c.bytes, c.n, &st, &err);
    CHECK_OK(s, err);
    CHECK(st.header + st.means + st.codebook1 + st.codebook2 + st.indices + st.residuals == c.n &&
              st.residual_voxels == c.stats.residual_voxels &&
              st.zero_blocks == c.stats.zero_blocks && st.indices == c.stats.indices,
          "%s: parts of the check (%zu residuals, %zu zero blocks) and encoder disagree or do "
          "not add up to %zu", what, st.residual_voxels, st.zero_blocks, c.n);
    if (encode(p, d, v, 1, 3, &c3))
        CHECK(c3.n == c.n && memcmp(c3.bytes, c.bytes, c.n) == 0, "%s: 1 and 3 threads differ",
              what);
    free(c3.bytes);
    free(h.bytes);
    free(dc);
    free(dh);
    return c;
}

static void test_table(void)
{
    const cdvr_codec *c = cdvr_codec_find("hvqc");
    CHECK(c && c->id == CDVR_CODEC_ID_HVQC && c->cl_mode == CDVR_CODEC_CL_NONE &&
              cdvr_codec_by_id(CDVR_CODEC_ID_HVQC) == c,
          "hvqc is not registered as id 3, CPU decode");
    if (!c)
        return;
    cdvr_codec_params blob;
    cdvr_error err;
    char name[CDVR_VARIANT_NAME_MAX];
    c->params_default(&blob);
    c->variant_name(&blob, name, sizeof name);
    CHECK(strcmp(name, "hvqc") == 0, "default variant name '%s'", name);
    CHECK_OK(c->params_set(&blob, "residual", "4", &err), err);
    c->variant_name(&blob, name, sizeof name);
    CHECK(strcmp(name, "hvqc_r4") == 0, "variant name '%s'", name);
    cdvr_codec_params shp;
    const char *keys[3] = {"shared", "k2", "residual"}, *values[3] = {"1", "512", "3"};
    CHECK_OK(cdvr_codec_params_parse(c, keys, values, 3, &shp, &err), err);
    c->variant_name(&shp, name, sizeof name);
    CHECK(strcmp(name, "hvqc_r3_k4096x512_s") == 0, "shared set before other keys: '%s'", name);
    const size_t d[3] = {21, 14, 9};
    uint8_t *v = make_volume(d, 3), *out = malloc(21 * 14 * 9);
    cdvr_codec_shape sh;
    CHECK_OK(c->shape(&blob, d, &sh, &err), err);
    uint8_t *payload = malloc(sh.bound_bytes);
    size_t n = 0;
    const uint8_t *frames[1] = {v};
    uint8_t *outs[1] = {out};
    CHECK_OK(c->encode(&blob, d, frames, 1, payload, sh.bound_bytes, &n, &err), err);
    CHECK_OK(c->decode(&blob, d, payload, n, outs, 1, &err), err);
    int maxerr = 0;
    for (size_t i = 0; i < 21 * 14 * 9; i++)
        maxerr = abs(out[i] - v[i]) > maxerr ? abs(out[i] - v[i]) : maxerr;
    CHECK(maxerr <= 4, "through the table: max error %d > 4", maxerr);
    free(payload);
    free(out);
    free(v);
}

static void test_shapes(void)
{
    const size_t dims[][3] = {{1, 1, 1}, {5, 3, 7}, {4, 4, 4}, {2, 9, 1}, {257, 5, 3},
                              {33, 31, 29}};
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    for (size_t i = 0; i < sizeof dims / sizeof *dims; i++) {
        char what[64];
        snprintf(what, sizeof what, "dims %zux%zux%zu", dims[i][0], dims[i][1], dims[i][2]);
        uint8_t *v = make_volume(dims[i], 11u + (uint32_t)i);
        coded c = round_trip(&p, dims[i], v, what);
        free(c.bytes);
        free(v);
    }
}

/* All zero (no non-zero block: empty codebooks and index list), residual 255 (no residual),
 * residual 0 on noise (lossless, two-byte values), wide indices (k above 256). */
static void test_extremes(void)
{
    const size_t d[3] = {40, 30, 20};
    size_t n = 40 * 30 * 20;
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    uint8_t *v = calloc(n, 1);
    coded c = round_trip(&p, d, v, "all zero");
    CHECK(!c.bytes || (c.stats.zero_blocks == c.stats.blocks && c.stats.codebook1 == 0 &&
                       c.stats.residual_voxels == 0 && c.n < 200),
          "all zero: %zu bytes, %zu zero blocks of %zu", c.n, c.stats.zero_blocks,
          c.stats.blocks);
    free(c.bytes);
    free(v);
    v = make_volume(d, 5);
    p.grad = 4;
    p.residual = 255;
    c = round_trip(&p, d, v, "residual 255");
    CHECK(!c.bytes || c.stats.residual_voxels == 0, "residual 255: %zu residual voxels",
          c.stats.residual_voxels);
    free(c.bytes);
    uint32_t seed = 3;
    for (size_t i = 0; i < n; i++)
        v[i] = (uint8_t)rng_next(&seed);
    p.residual = 0;
    p.k1 = p.k2 = 16;
    c = round_trip(&p, d, v, "residual 0 on noise");
    CHECK(!c.bytes || c.stats.residual_voxels > 20000, "noise: %zu residual voxels",
          c.stats.residual_voxels);
    free(c.bytes);
    free(v);
    const size_t w[3] = {64, 64, 48};
    v = make_volume(w, 9);
    for (size_t i = 0; i < 64 * 64 * 48; i += 7)
        v[i] = (uint8_t)(v[i] + rng_next(&seed) % 40);
    cdvr_hvq_params_default(&p);
    p.grad = 1;
    p.k1 = p.k2 = 600;
    c = round_trip(&p, w, v, "wide indices");
    CHECK(!c.bytes || (c.stats.codebook1_entries > 256 && c.stats.codebook2_entries > 256),
          "wide indices: codebooks of %zu and %zu entries", c.stats.codebook1_entries,
          c.stats.codebook2_entries);
    free(c.bytes);
    free(v);
}

static void expect_corrupt(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *b,
                           size_t n, const char *what)
{
    uint8_t *out = malloc(d[0] * d[1] * d[2]);
    cdvr_error err;
    cdvr_status s = cdvr_hvq_compact_decode(p, NULL, d, b, n, out, &err);
    CHECK(s == CDVR_ERR_CORRUPT, "%s: status %d (%s)", what, (int)s, s ? err.msg : "ok");
    free(out);
}

static void test_corrupt(void)
{
    const size_t d[3] = {20, 17, 9};
    uint8_t *v = make_volume(d, 77);
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 2;
    coded c;
    if (!encode(&p, d, v, 1, 1, &c)) {
        free(v);
        return;
    }
    CHECK(c.stats.residual_voxels > 0 && c.stats.codebook1 > 0, "the corrupt-payload volume "
          "has residuals (%zu) and codebooks", c.stats.residual_voxels);
    uint8_t *m = malloc(c.n + HVQ2_HEADER_MAX);
    for (size_t cut = 0; cut < c.n; cut += 1 + cut / 5)
        expect_corrupt(&p, d, c.bytes, cut, "truncated");
    memcpy(m, c.bytes, c.n);
    m[c.n] = 0;
    expect_corrupt(&p, d, m, c.n + 1, "one byte too many");
    hvq2_header h0;
    CHECK(hvq2_header_read(c.bytes, c.n, &h0) && h0.bytes < 40, "compact header of %zu bytes",
          h0.bytes);
#define MUTATE(what, stmt)                                                                    \
    do {                                                                                      \
        memcpy(m, c.bytes, c.n);                                                              \
        stmt;                                                                                 \
        expect_corrupt(&p, d, m, c.n, what);                                                  \
    } while (0)
#define MUTATE_HEADER(what, stmt) /* the header rewritten with a field changed */            \
    do {                                                                                      \
        hvq2_header h = h0;                                                                   \
        stmt;                                                                                 \
        size_t hb = hvq2_header_write(&h, m);                                                 \
        memcpy(m + hb, c.bytes + h0.bytes, c.n - h0.bytes);                                   \
        expect_corrupt(&p, d, m, hb + c.n - h0.bytes, what);                                  \
    } while (0)
    MUTATE("magic", m[3] = '9');
    MUTATE("a field past 64 bits", memset(m + 4, 0xFF, 12));
    MUTATE_HEADER("dims", h.dims[1]++);
    MUTATE_HEADER("n1 above k1", h.n1 = p.k1 + 1);
    MUTATE_HEADER("n2 = 0 alone", h.n2 = 0);
    MUTATE_HEADER("residual above 255", h.residual = 256);
    MUTATE_HEADER("unknown flag", h.flags |= 2);
    MUTATE_HEADER("shared flag, id 0", h.flags |= HVQ2_FLAG_SHARED);
    MUTATE_HEADER("shared flag, no codebooks given", (h.flags |= HVQ2_FLAG_SHARED, h.id = 7));
    MUTATE_HEADER("one residual more", h.nres++);
    MUTATE_HEADER("position list longer", h.respos_bytes++);
    MUTATE_HEADER("section sizes", (h.csize[0]++, h.csize[1]--));
    MUTATE_HEADER("sections past the end", h.csize[HVQ_SECTIONS - 1]++);
    for (int sec = 0; sec < HVQ_SECTIONS; sec++) { /* a byte inside each section (checksums) */
        size_t at = h0.bytes, cs = (size_t)h0.csize[sec];
        for (int j = 0; j < sec; j++)
            at += (size_t)h0.csize[j];
        if (cs > 8)
            MUTATE("a section's byte", m[at + cs / 2] ^= 0x5A);
    }
#undef MUTATE_HEADER
#undef MUTATE
    free(m);
    free(c.bytes);
    free(v);
}


/* ---- shared codebooks ------------------------------------------------------------------------ */

static void test_shared(void)
{
    const size_t d[3] = {36, 28, 20}, sub[3] = {17, 15, 9};
    size_t n = 36 * 28 * 20;
    uint8_t *f0 = make_volume(d, 21), *f1 = make_volume(d, 22), *zero = calloc(n, 1);
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 2;
    p.residual = 6;
    const uint8_t *train[2] = {f0, f1};
    uint8_t *blob = NULL;
    size_t bytes = 0;
    cdvr_error err;
    cdvr_hvq_codebooks cb, other;
    CHECK_OK(cdvr_hvq_train_shared(&p, d, train, 2, 1, &blob, &bytes, &err), err);
    CHECK_OK(cdvr_hvq_shared_open(&p, blob, bytes, &cb, &err), err);
    CHECK(cb.n1 > 0 && cb.n2 > 0 && cb.id == cdvr_shared_id(blob, bytes), "shared codebooks of "
          "%u and %u entries", cb.n1, cb.n2);
    uint8_t *g = make_volume(d, 23), *box = malloc(17 * 15 * 9);
    for (size_t z = 0; z < 9; z++) /* a sub-box, as a brick of the frame */
        for (size_t y = 0; y < 15; y++)
            memcpy(box + 17 * (y + 15 * z), g + 11 + 36 * ((y + 7) + 28 * (z + 5)), 17);
    const uint8_t *frames[3] = {g, zero, box};
    const size_t *dims[3] = {d, d, sub};
    for (int i = 0; i < 3; i++) {
        size_t bound, got, voxels = dims[i][0] * dims[i][1] * dims[i][2];
        CHECK_OK(cdvr_hvq_compact_bound(&p, dims[i], &bound, &err), err);
        uint8_t *out = malloc(bound), *dec = malloc(voxels);
        cdvr_hvq_stats st;
        cdvr_status s = cdvr_hvq_encode_compact(&p, &cb, dims[i], frames[i], 2, out, bound, &got,
                                                &st, &err);
        CHECK_OK(s, err);
        CHECK(s || (st.codebook1 == 0 && st.codebook2 == 0), "frame %d: codebooks in a payload "
              "coded with shared ones", i);
        s = s ? s : cdvr_hvq_compact_decode(&p, &cb, dims[i], out, got, dec, &err);
        CHECK_OK(s, err);
        int maxerr = 0;
        for (size_t k = 0; s == CDVR_OK && k < voxels; k++)
            maxerr = abs(dec[k] - frames[i][k]) > maxerr ? abs(dec[k] - frames[i][k]) : maxerr;
        CHECK(maxerr <= 6, "frame %d with shared codebooks: max error %d > 6", i, maxerr);
        if (s == CDVR_OK && i == 0) {
            s = cdvr_hvq_compact_decode(&p, NULL, dims[i], out, got, dec, &err);
            CHECK(s == CDVR_ERR_CORRUPT && strstr(err.msg, "shared"), "decoded without its "
                  "shared codebooks: status %d (%s)", (int)s, s ? err.msg : "ok");
            other = cb;
            other.id ^= 1;
            s = cdvr_hvq_compact_decode(&p, &other, dims[i], out, got, dec, &err);
            CHECK(s == CDVR_ERR_CORRUPT, "decoded with other codebooks: status %d", (int)s);
        }
        free(out);
        free(dec);
    }
    for (size_t cut = 0; cut < bytes; cut += 1 + cut / 3) {
        cdvr_status s = cdvr_hvq_shared_open(&p, blob, cut, &other, &err);
        CHECK(s == CDVR_ERR_CORRUPT, "shared blob cut to %zu bytes: status %d", cut, (int)s);
    }
    blob[bytes / 2 + 12] ^= 0x33;
    cdvr_status s = cdvr_hvq_shared_open(&p, blob, bytes, &other, &err);
    CHECK(s == CDVR_ERR_CORRUPT, "shared blob with a flipped byte: status %d", (int)s);
    cdvr_hvq_codebooks_free(&cb);
    free(blob);
    free(box);
    free(g);
    free(zero);
    free(f0);
    free(f1);
}

/* A bricked (2x2x1), two-timestep store with hvqc shared=1 and without: reopened, each
 * timestep decodes within the bound; the shared variant keeps no codebook in its chunks; a
 * byte flipped in its shared blob makes its decode fail (and the other variant's still works). */
static void test_shared_store(void)
{
    const size_t d[3] = {40, 36, 24};
    size_t n = 40 * 36 * 24;
    cdvr_volume *vol;
    cdvr_error err;
    if (cdvr_volume_create(d, 2, CDVR_TYPE_U8, &vol, &err) != CDVR_OK) {
        CHECK_OK(CDVR_ERR_NOMEM, err);
        return;
    }
    for (size_t t = 0; t < 2; t++) {
        uint8_t *v = make_volume(d, 31u + (uint32_t)t);
        memcpy(cdvr_volume_frame(vol, t), v, n);
        free(v);
    }
    const cdvr_codec *codec = cdvr_codec_find("hvqc");
    cdvr_variant_spec specs[2];
    memset(specs, 0, sizeof specs);
    const char *keys[2] = {"residual", "shared"}, *values[2][2] = {{"5", "1"}, {"5", "0"}};
    for (int i = 0; i < 2; i++) {
        specs[i].codec = codec;
        CHECK_OK(cdvr_codec_params_parse(codec, keys, values[i], 2, &specs[i].params, &err), err);
    }
    cdvr_encode_opts opts;
    memset(&opts, 0, sizeof opts);
    opts.variants = specs;
    opts.nvariants = 2;
    opts.qlo = 0;
    opts.qhi = 255;
    opts.source_type = CDVR_TYPE_U8;
    opts.bricks[0] = opts.bricks[1] = 2;
    opts.bricks[2] = 1;
    char path[] = "/tmp/cdvr_test_hvqc_XXXXXX";
    int fd = mkstemp(path);
    if (fd >= 0)
        close(fd);
    cdvr_status s = cdvr_store_encode(vol, &opts, path, &err);
    CHECK_OK(s, err);
    cdvr_store *st = NULL;
    uint64_t blob_at = 0;
    if (s == CDVR_OK && cdvr_store_open(path, &st, &err) == CDVR_OK) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, 0);
        blob_at = vi->shared_offset + vi->shared_bytes / 2;
        CHECK(vi->shared_bytes > 0 && cdvr_store_variant(st, 1)->shared_bytes == 0,
              "shared blob bytes %llu and %llu", (unsigned long long)vi->shared_bytes,
              (unsigned long long)cdvr_store_variant(st, 1)->shared_bytes);
        for (size_t v = 0; v < 2; v++)
            for (size_t t = 0; t < 2; t++) {
                cdvr_volume *dec = NULL;
                s = cdvr_store_decode(st, v, t, &dec, &err);
                CHECK_OK(s, err);
                int maxerr = 0;
                const uint8_t *a = cdvr_volume_frame(vol, t), *b = dec ? dec->data : NULL;
                for (size_t k = 0; b && k < n; k++)
                    maxerr = abs(a[k] - b[k]) > maxerr ? abs(a[k] - b[k]) : maxerr;
                CHECK(maxerr <= 5, "store variant %zu t %zu: max error %d > 5", v, t, maxerr);
                cdvr_volume_free(dec);
            }
        cdvr_store_close(st);
    } else {
        CHECK(0, "cannot reopen the store: %s", err.msg);
    }
    FILE *f = blob_at ? fopen(path, "r+b") : NULL;
    if (f) {
        int c = (fseek(f, (long)blob_at, SEEK_SET), fgetc(f));
        fseek(f, (long)blob_at, SEEK_SET);
        fputc(c ^ 0x5A, f);
        fclose(f);
        if (cdvr_store_open(path, &st, &err) == CDVR_OK) {
            cdvr_volume *dec = NULL;
            s = cdvr_store_decode(st, 0, 1, &dec, &err);
            CHECK(s != CDVR_OK, "a corrupt shared blob decodes");
            cdvr_volume_free(dec);
            dec = NULL;
            s = cdvr_store_decode(st, 1, 1, &dec, &err);
            CHECK_OK(s, err);
            cdvr_volume_free(dec);
            cdvr_store_close(st);
        }
    }
    remove(path);
    cdvr_volume_free(vol);
}

/* Squared error sum and max error of a decoded frame. */
static double frame_psnr(const uint8_t *a, const uint8_t *b, size_t n, int *maxerr)
{
    uint64_t sse = 0;
    *maxerr = 0;
    for (size_t i = 0; i < n; i++) {
        int e = abs(a[i] - b[i]);
        sse += (uint64_t)(e * e);
        *maxerr = e > *maxerr ? e : *maxerr;
    }
    return sse ? 10.0 * log10(255.0 * 255.0 * (double)n / (double)sse) : INFINITY;
}

/* Encodes (both forms), decodes; returns the PSNR, fills the max error and the R applied. */
static double coded_psnr(const cdvr_hvq_params *p, const size_t d[3], const uint8_t *v,
                         int compact, int *maxerr, uint32_t *applied)
{
    size_t n = d[0] * d[1] * d[2];
    coded c;
    cdvr_error err;
    *maxerr = 256;
    *applied = 999;
    if (!encode(p, d, v, compact, 2, &c))
        return -1;
    uint8_t *out = malloc(n);
    cdvr_status s = compact ? cdvr_hvq_compact_decode(p, NULL, d, c.bytes, c.n, out, &err)
                            : cdvr_hvq_decode(p, d, c.bytes, c.n, out, &err);
    CHECK_OK(s, err);
    double psnr = s == CDVR_OK ? frame_psnr(out, v, n, maxerr) : -1;
    *applied = c.stats.residual;
    if (compact) { /* the payload records R: the check (st:info "residual") reads it back */
        cdvr_hvq_stats st;
        CHECK_OK(cdvr_hvq_compact_check(p, NULL, d, c.bytes, c.n, &st, &err), err);
        CHECK(st.residual == c.stats.residual, "check reads residual %u, encoder applied %u",
              st.residual, c.stats.residual);
    }
    free(out);
    free(c.bytes);
    return psnr;
}

/* psnr=T: the decoded chunk meets T, stays within `residual`, and R is the largest that does
 * (R+1 without a target misses T); on odd dims with a 4k+1 axis, both forms. */
static void test_quality_target(void)
{
    const size_t d[3] = {37, 30, 21};
    uint8_t *v = make_volume(d, 11);
    /* wider noise than make_volume's: residual errors to trade against PSNR */
    uint32_t seed = 99;
    for (size_t i = 0; i < d[0] * d[1] * d[2]; i++)
        v[i] = (uint8_t)(v[i] < 200 ? v[i] + rng_next(&seed) % 24 : v[i]);
    const double targets[3] = {30, 38, 46};
    int inside = 0;
    for (int compact = 0; compact < 2; compact++)
        for (int t = 0; t < 3; t++) {
            cdvr_hvq_params p;
            cdvr_hvq_params_default(&p);
            p.residual = 20;
            p.k2 = 64;
            cdvr_hvq_params_set_psnr(&p, targets[t]);
            int maxerr;
            uint32_t R;
            double psnr = coded_psnr(&p, d, v, compact, &maxerr, &R);
            CHECK(psnr >= targets[t] && maxerr <= (int)R && R <= p.residual,
                  "form %d, psnr=%g: %.3f dB, max error %d, R %u (cap %u)", compact, targets[t],
                  psnr, maxerr, R, p.residual);
            inside += R > 0 && R < p.residual;
            if (R >= p.residual)
                continue;
            p.psnr = 0;
            p.residual = R + 1;
            int maxerr1;
            uint32_t R1;
            double psnr1 = coded_psnr(&p, d, v, compact, &maxerr1, &R1);
            CHECK(R1 == R + 1 && psnr1 < targets[t], "form %d, psnr=%g: R %u chosen, but R %u "
                  "gives %.3f dB", compact, targets[t], R, R1, psnr1);
        }
    CHECK(inside >= 2, "only %d of 6 targets chose a threshold inside (0, residual)", inside);
    /* the setter and the table: the applied value (0.01 dB steps), the name, the blob */
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    CHECK(cdvr_hvq_params_set_psnr(&p, 43.456) == 43.46 && p.psnr == 43.46 &&
              cdvr_hvq_params_set_psnr(&p, 1e9) == 200 && cdvr_hvq_params_set_psnr(&p, -3) == 0,
          "psnr setter: applied %g", p.psnr);
    const cdvr_codec *c = cdvr_codec_find("hvqc");
    cdvr_codec_params blob;
    cdvr_error err;
    char name[CDVR_VARIANT_NAME_MAX], got[32];
    c->params_default(&blob);
    CHECK_OK(c->params_set(&blob, "shared", "1", &err), err);
    CHECK_OK(c->params_set(&blob, "psnr", "43.456", &err), err);
    CHECK(c->params_get(&blob, "psnr", got, sizeof got) == 0 && strcmp(got, "43.46") == 0 &&
              cdvr_hvqc_wants_shared(&blob),
          "hvqc psnr reads back '%s' (shared %d)", got, cdvr_hvqc_wants_shared(&blob));
    CHECK_OK(c->params_check(&blob, &err), err);
    c->variant_name(&blob, name, sizeof name);
    CHECK(strcmp(name, "hvqc_p43.46_s") == 0, "variant name '%s'", name);
    CHECK(c->params_set(&blob, "psnr", "201", &err) == CDVR_ERR_ARG &&
              c->params_set(&blob, "psnr", "-1", &err) == CDVR_ERR_ARG,
          "psnr out of range accepted");
    const cdvr_codec *h = cdvr_codec_find("hvq");
    h->params_default(&blob);
    CHECK_OK(h->params_set(&blob, "psnr", "40", &err), err);
    CHECK_OK(h->params_check(&blob, &err), err);
    cdvr_hvq_params_from_blob(&blob, &p);
    CHECK(p.psnr == 40, "hvq blob psnr %g", p.psnr);
    free(v);
}

/* k2=auto: the payload is byte for byte the plain encode at the candidate size that gives the
 * smallest payload (the 1-per-8-blocks cap ends the candidates early), decodes within
 * `residual`; the hashed form and shared codebooks refuse it. */
static void test_k2_auto(void)
{
    const size_t d[3] = {64, 60, 44}, n = 64 * 60 * 44;
    uint8_t *v = make_volume(d, 5);
    uint32_t seed = 7;
    for (size_t i = 0; i < n; i++)
        v[i] = (uint8_t)(v[i] < 200 ? v[i] + rng_next(&seed) % 16 : v[i]);
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    p.grad = 2;
    p.residual = 6;
    coded best = {NULL, SIZE_MAX, {0}}, plain, aut;
    const uint32_t sizes[4] = {256, 512, 1024, 2048};
    size_t distinct = 0, last_n2 = 0;
    for (int i = 0; i < 4; i++) {
        p.k2 = sizes[i];
        if (!encode(&p, d, v, 1, 2, &plain))
            return;
        if (plain.stats.codebook2_entries == last_n2) {
            free(plain.bytes);
            break;
        }
        distinct++;
        last_n2 = plain.stats.codebook2_entries;
        if (plain.n < best.n) {
            free(best.bytes);
            best = plain;
        } else {
            free(plain.bytes);
        }
    }
    p.k2 = 0;
    if (!encode(&p, d, v, 1, 2, &aut))
        return;
    CHECK(distinct >= 2 && aut.n == best.n && memcmp(aut.bytes, best.bytes, aut.n) == 0 &&
              aut.stats.codebook2_entries == best.stats.codebook2_entries,
          "k2=auto: %zu bytes (%zu entries), the best of %zu sizes %zu bytes (%zu entries)",
          aut.n, aut.stats.codebook2_entries, distinct, best.n, best.stats.codebook2_entries);
    uint8_t *out = malloc(n);
    cdvr_error err;
    CHECK_OK(cdvr_hvq_compact_decode(&p, NULL, d, aut.bytes, aut.n, out, &err), err);
    int maxerr;
    frame_psnr(out, v, n, &maxerr);
    CHECK(maxerr <= (int)p.residual, "k2=auto: max error %d", maxerr);
    size_t bound = 0, got;
    CHECK_OK(cdvr_hvq_bound(&p, d, &bound, &err), err);
    uint8_t *hashed = malloc(bound);
    CHECK(cdvr_hvq_encode(&p, d, v, 1, hashed, bound, &got, NULL, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "auto"), "the hashed form accepted k2 = auto");
    free(hashed);
    const cdvr_codec *c = cdvr_codec_find("hvqc"), *h = cdvr_codec_find("hvq");
    cdvr_codec_params blob;
    char name[CDVR_VARIANT_NAME_MAX], got_k2[16];
    c->params_default(&blob);
    CHECK_OK(c->params_set(&blob, "k2", "auto", &err), err);
    CHECK_OK(c->params_check(&blob, &err), err);
    c->variant_name(&blob, name, sizeof name);
    CHECK(strcmp(name, "hvqc_k4096xauto") == 0 &&
              c->params_get(&blob, "k2", got_k2, sizeof got_k2) == 0 &&
              strcmp(got_k2, "auto") == 0, "k2=auto: name '%s', reads back '%s'", name, got_k2);
    CHECK_OK(c->params_set(&blob, "shared", "1", &err), err);
    CHECK(c->params_check(&blob, &err) == CDVR_ERR_ARG, "hvqc accepted k2=auto with shared=1");
    h->params_default(&blob);
    CHECK_OK(h->params_set(&blob, "k2", "auto", &err), err);
    CHECK(h->params_check(&blob, &err) == CDVR_ERR_ARG, "hvq accepted k2=auto");
    free(out);
    free(aut.bytes);
    free(best.bytes);
    free(v);
}

int main(void)
{
    test_table();
    test_shapes();
    test_extremes();
    test_corrupt();
    test_shared();
    test_shared_store();
    test_quality_target();
    test_k2_auto();
    return check_finish();
}
