/* tests/test_encode_parallel.c - the encode driver on several threads and the range tables it
 * records: a store written with 1, 2, 3, 5 and 8 threads is the same file byte for byte
 * (several variants, a schedule that changes parameters, bricks, a padded last group, the
 * raw codec without encode_part); PVTC's encode_part gives encode's bytes for any number of
 * parts; every chunk's range table equals the ranges computed by definition from its decoded
 * frames (range bricks of 8^3, the default, 4^3 as older stores have them, and 16^3; sizes
 * outside 4^3 .. 64^3 refused), and the tables of a bricked store merge into exactly the
 * ranges of the assembled volume; no_range_tables writes the same chunks without them; a version-2 store without
 * tables still opens. */
#include "check.h"

#include "cdvr/pvtc.h"
#include "store/store_format.h"

#include <stdint.h>
#include <string.h>
#include <unistd.h>

static char tmpdir[256];

static const char *tmp_path(const char *name)
{
    static char bufs[4][512];
    static int next;
    char *buf = bufs[next++ % 4];
    snprintf(buf, sizeof bufs[0], "%s/%s", tmpdir, name);
    return buf;
}

static uint8_t *read_file(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *buf = malloc(size > 0 ? (size_t)size : 1);
    *n = buf ? fread(buf, 1, (size_t)size, f) : 0;
    fclose(f);
    return buf;
}

/* Smooth field with a moving blob, flat zero areas and noise: blocks of every cost. */
static cdvr_volume *make_series(size_t x, size_t y, size_t z, size_t t)
{
    size_t dims[3] = {x, y, z};
    cdvr_volume *v = NULL;
    cdvr_error err;
    if (cdvr_volume_create(dims, t, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    uint32_t seed = 11;
    for (size_t ti = 0; ti < t; ti++)
        for (size_t k = 0; k < z; k++)
            for (size_t j = 0; j < y; j++)
                for (size_t i = 0; i < x; i++) {
                    seed = seed * 1664525u + 1013904223u;
                    long dx = (long)i - (long)(3 + 2 * ti), dy = (long)j - 6, dz = (long)k - 5;
                    long r2 = dx * dx + dy * dy + dz * dz;
                    int val = k < 2 ? 0 : r2 < 30 ? 200 - (int)r2 * 4 : (int)(i * 3 + j);
                    val += (int)(seed >> 29);
                    *p++ = (uint8_t)(val > 255 ? 255 : val);
                }
    return v;
}

static cdvr_variant_spec pvtc_spec(int S, int T, cdvr_pack pack, cdvr_pvtc_encoder enc,
                                   cdvr_stage2 stage2)
{
    cdvr_variant_spec s = {.codec = cdvr_codec_find("pvtc"), .stage2 = stage2,
                           .lzo_min_saving = -1};
    cdvr_pvtc_params p = {S, T, pack};
    cdvr_pvtc_params_to_blob(&p, enc, &s.params);
    return s;
}

/* Every other group of variant 0 switches to the bbox encoder. */
static cdvr_status alternate(void *ud, size_t variant, size_t t0, cdvr_codec_params *params,
                             cdvr_error *err)
{
    (void)ud;
    (void)err;
    if (variant == 0 && (t0 / 3) % 2 == 1)
        cdvr_params_set_u32(params, 12, 1); /* pvtc blob: encoder = bbox */
    return CDVR_OK;
}

static void test_threads_same_bytes(void)
{
    cdvr_volume *u8 = make_series(21, 17, 13, 7); /* odd dims, 7 = 2 groups of 3 + 1 */
    cdvr_variant_spec vs[4] = {pvtc_spec(1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
                               pvtc_spec(4, 2, CDVR_PACK_SPACE, CDVR_ENCODER_LSQ,
                                         CDVR_STAGE2_NONE),
                               pvtc_spec(4, 3, CDVR_PACK_TIME, CDVR_ENCODER_BBOX,
                                         CDVR_STAGE2_LZO),
                               {.codec = cdvr_codec_find("raw"), .stage2 = CDVR_STAGE2_LZO,
                                .lzo_min_saving = 0}};
    vs[3].codec->params_default(&vs[3].params);
    static const size_t grids[2][3] = {{1, 1, 1}, {2, 3, 2}};
    static const int threads[] = {1, 2, 3, 5, 8};
    for (int g = 0; g < 2; g++) {
        uint8_t *first = NULL;
        size_t first_n = 0;
        for (size_t k = 0; k < sizeof threads / sizeof *threads; k++) {
            cdvr_encode_opts o = {.variants = vs, .nvariants = 4, .qlo = 0, .qhi = 255,
                                  .source_type = CDVR_TYPE_U8, .schedule = alternate,
                                  .threads = threads[k]};
            memcpy(o.bricks, grids[g], sizeof o.bricks);
            const char *path = tmp_path("threads.cdv");
            cdvr_error err;
            CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
            size_t n = 0;
            uint8_t *bytes = read_file(path, &n);
            if (!first) {
                first = bytes;
                first_n = n;
                continue;
            }
            CHECK(n == first_n && bytes && memcmp(bytes, first, n) == 0,
                  "grid %d: %d threads wrote a different file (%zu vs %zu bytes)", g,
                  threads[k], n, first_n);
            free(bytes);
        }
        free(first);
    }
    cdvr_volume_free(u8);
}

/* encode_part with 1..9 parts, in reverse order, gives encode's bytes. */
static void test_encode_part(void)
{
    cdvr_volume *u8 = make_series(18, 9, 11, 3);
    const cdvr_codec *pvtc = cdvr_codec_find("pvtc");
    CHECK(pvtc && pvtc->encode_part, "pvtc has encode_part");
    static const int variants[][3] = {{1, 3, 0}, {4, 3, 0}, {1, 2, 1}, {4, 2, 1}};
    for (size_t i = 0; pvtc && i < sizeof variants / sizeof *variants; i++) {
        cdvr_codec_params p;
        cdvr_pvtc_params q = {variants[i][0], variants[i][1], (cdvr_pack)variants[i][2]};
        cdvr_pvtc_params_to_blob(&q, CDVR_ENCODER_LSQ, &p);
        cdvr_codec_shape shape;
        cdvr_error err;
        CHECK_OK(pvtc->shape(&p, u8->dims, &shape, &err), err);
        const uint8_t *frames[3];
        size_t nf = q.pack == CDVR_PACK_TIME ? 3 : 1;
        for (size_t f = 0; f < nf; f++)
            frames[f] = cdvr_volume_frame(u8, f);
        uint8_t *whole = malloc(shape.payload_bytes), *parts = malloc(shape.payload_bytes);
        size_t bytes = 0;
        CHECK_OK(pvtc->encode(&p, u8->dims, frames, nf, whole, shape.payload_bytes, &bytes,
                              &err), err);
        for (size_t nparts = 1; nparts <= 9; nparts++) {
            memset(parts, 0xA5, shape.payload_bytes);
            for (size_t k = nparts; k-- > 0;)
                CHECK_OK(pvtc->encode_part(&p, u8->dims, frames, nf, k, nparts, parts,
                                           shape.payload_bytes, &err), err);
            CHECK(memcmp(whole, parts, shape.payload_bytes) == 0, "S%dT%d pack %d: %zu parts",
                  q.S, q.T, (int)q.pack, nparts);
        }
        cdvr_error err2;
        CHECK(pvtc->encode_part(&p, u8->dims, frames, nf, 3, 3, parts, shape.payload_bytes,
                                &err2) == CDVR_ERR_ARG, "part out of range refused");
        free(whole);
        free(parts);
    }
    cdvr_volume_free(u8);
}

/* Range of range brick (gx, gy, gz) over the voxel box [olo, olo + obd) of a frame holding
 * the box [lo, lo + bd) of a volume of vd voxels (the definition: voxels E g .. E g + E,
 * clamped to the volume, inside the box). */
static void brute_range(const uint8_t *frame, const size_t bd[3], const size_t lo[3],
                        const size_t olo[3], const size_t obd[3], const size_t vd[3],
                        const size_t g[3], unsigned shift, uint8_t out[2])
{
    size_t a[3], b[3], e = (size_t)1 << shift;
    for (int k = 0; k < 3; k++) {
        a[k] = g[k] * e;
        b[k] = g[k] * e + e < vd[k] - 1 ? g[k] * e + e : vd[k] - 1;
        a[k] = a[k] > olo[k] ? a[k] : olo[k];
        b[k] = b[k] < olo[k] + obd[k] - 1 ? b[k] : olo[k] + obd[k] - 1;
    }
    out[0] = 255;
    out[1] = 0;
    for (size_t z = a[2]; z <= b[2]; z++)
        for (size_t y = a[1]; y <= b[1]; y++)
            for (size_t x = a[0]; x <= b[0]; x++) {
                uint8_t v = frame[(x - lo[0]) + bd[0] * ((y - lo[1]) + bd[1] * (z - lo[2]))];
                out[0] = v < out[0] ? v : out[0];
                out[1] = v > out[1] ? v : out[1];
            }
}

/* Each chunk's table against its decoded frames; then, per timestep, the merged tables
 * against the ranges of the assembled volume. */
static void check_ranges(const char *path, unsigned shift)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    const cdvr_store_info *in = cdvr_store_get_info(st);
    size_t grid[3], full_lo[3] = {0, 0, 0};
    cdvr_range_grid(in->dims, shift, grid);
    size_t cells = grid[0] * grid[1] * grid[2], mismatches = 0;
    uint8_t *merged = malloc(2 * cells * in->timesteps), want[2];
    for (size_t v = 0; v < in->nvariants; v++) {
        for (size_t i = 0; i < 2 * cells * in->timesteps; i += 2) {
            merged[i] = 255;
            merged[i + 1] = 0;
        }
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        for (size_t c = 0; c < vi->nchunks; c++) {
            const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
            size_t lo[3], bd[3], olo[3], obd[3], g0[3], n[3];
            size_t table_n = cdvr_store_ranges_bytes(st, v, c);
            cdvr_store_brick_box(in, ci->brick, lo, bd);
            cdvr_store_brick_owned(in, ci->brick, olo, obd);
            cdvr_range_window(in->dims, olo, obd, shift, g0, n);
            CHECK(ci->ranges_shift == shift && table_n == 2 * n[0] * n[1] * n[2] * ci->count,
                  "variant %zu chunk %zu: table of %zu bytes, shift %u", v, c, table_n,
                  ci->ranges_shift);
            uint8_t *table = malloc(table_n ? table_n : 1), *payload = NULL;
            size_t bvox = bd[0] * bd[1] * bd[2];
            uint8_t *dec = malloc(bvox * ci->count), *frames[64];
            for (size_t f = 0; f < ci->count; f++)
                frames[f] = dec + f * bvox;
            CHECK_OK(cdvr_store_read_ranges(st, v, c, table, &err), err);
            CHECK_OK(cdvr_store_load_payload(st, v, c, &payload, &err), err);
            CHECK_OK(cdvr_store_decode_chunk(st, v, c, payload, frames, &err), err);
            for (size_t f = 0; f < ci->count; f++) {
                const uint8_t *t = table + f * 2 * n[0] * n[1] * n[2];
                for (size_t w = 0; w < n[0] * n[1] * n[2]; w++) {
                    size_t g[3] = {g0[0] + w % n[0], g0[1] + w / n[0] % n[1],
                                   g0[2] + w / (n[0] * n[1])};
                    brute_range(frames[f], bd, lo, olo, obd, in->dims, g, shift, want);
                    mismatches += t[2 * w] != want[0] || t[2 * w + 1] != want[1];
                }
                cdvr_range_merge(t, g0, n, grid, merged + 2 * cells * (ci->t0 + f));
            }
            free(table);
            free(payload);
            free(dec);
        }
        for (size_t t = 0; t < in->timesteps; t++) {
            cdvr_volume *d = NULL;
            CHECK_OK(cdvr_store_decode(st, v, t, &d, &err), err);
            for (size_t b = 0; d && b < cells; b++) {
                size_t g[3] = {b % grid[0], b / grid[0] % grid[1], b / (grid[0] * grid[1])};
                brute_range(d->data, in->dims, full_lo, full_lo, in->dims, in->dims, g, shift,
                            want);
                const uint8_t *m = merged + 2 * (cells * t + b);
                mismatches += m[0] != want[0] || m[1] != want[1];
            }
            cdvr_volume_free(d);
        }
    }
    CHECK(mismatches == 0, "%s: %zu ranges differ from the decoded data", path, mismatches);
    free(merged);
    cdvr_store_close(st);
}

static void test_ranges(void)
{
    cdvr_volume *u8 = make_series(23, 9, 14, 5);
    cdvr_variant_spec vs[3] = {pvtc_spec(4, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
                               pvtc_spec(1, 2, CDVR_PACK_SPACE, CDVR_ENCODER_BBOX,
                                         CDVR_STAGE2_NONE),
                               {.codec = cdvr_codec_find("raw"), .lzo_min_saving = -1}};
    vs[2].codec->params_default(&vs[2].params);
    static const size_t grids[3][3] = {{1, 1, 1}, {2, 2, 3}, {5, 1, 2}};
    /* range bricks: the default (8^3), the 4^3 of older stores, 16^3 */
    static const unsigned shifts[3] = {0, CDVR_RANGE_SHIFT, 4};
    for (int g = 0; g < 9; g++) {
        cdvr_encode_opts o = {.variants = vs, .nvariants = 3, .qlo = 0, .qhi = 255,
                              .source_type = CDVR_TYPE_U8, .threads = 2,
                              .range_shift = shifts[g / 3]};
        memcpy(o.bricks, grids[g % 3], sizeof o.bricks);
        const char *path = tmp_path("ranges.cdv");
        cdvr_error err;
        CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
        check_ranges(path, o.range_shift ? o.range_shift : CDVR_RANGE_SHIFT_DEFAULT);
    }
    /* range bricks outside 4^3 .. 64^3 are refused */
    static const unsigned bad_shifts[2] = {1, CDVR_RANGE_SHIFT_MAX + 1};
    for (int k = 0; k < 2; k++) {
        cdvr_encode_opts o = {.variants = vs, .nvariants = 1, .qhi = 255,
                              .range_shift = bad_shifts[k], .bricks = {1, 1, 1}};
        cdvr_error err;
        CHECK(cdvr_store_encode(u8, &o, tmp_path("bad.cdv"), &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "range bricks"), "range shift %u refused: %s", bad_shifts[k],
              err.msg);
    }
    cdvr_volume_free(u8);
    /* a single voxel, and one row: windows of one brick */
    static const size_t tiny[2][3] = {{1, 1, 1}, {9, 1, 1}};
    for (int k = 0; k < 2; k++) {
        cdvr_volume *v = NULL;
        cdvr_error err;
        CHECK_OK(cdvr_volume_create(tiny[k], 2, CDVR_TYPE_U8, &v, &err), err);
        for (size_t i = 0; v && i < tiny[k][0] * 2; i++)
            ((uint8_t *)v->data)[i] = (uint8_t)(37 * i + 5);
        cdvr_encode_opts o = {.variants = vs, .nvariants = 3, .qlo = 0, .qhi = 255,
                              .source_type = CDVR_TYPE_U8};
        const char *path = tmp_path("tiny.cdv");
        CHECK_OK(cdvr_store_encode(v, &o, path, &err), err);
        check_ranges(path, CDVR_RANGE_SHIFT_DEFAULT);
        cdvr_volume_free(v);
    }
}

/* no_range_tables: the same chunks, no tables, a smaller file that reads the same. */
static void test_no_tables(void)
{
    cdvr_volume *u8 = make_series(19, 11, 9, 4);
    cdvr_variant_spec vs = pvtc_spec(1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO);
    cdvr_encode_opts o = {.variants = &vs, .nvariants = 1, .qhi = 255};
    const char *with = tmp_path("with.cdv"), *without = tmp_path("without.cdv");
    cdvr_error err;
    CHECK_OK(cdvr_store_encode(u8, &o, with, &err), err);
    o.no_range_tables = 1;
    CHECK_OK(cdvr_store_encode(u8, &o, without, &err), err);
    cdvr_store *a = NULL, *b = NULL;
    CHECK_OK(cdvr_store_open(with, &a, &err), err);
    CHECK_OK(cdvr_store_open(without, &b, &err), err);
    if (a && b) {
        const cdvr_variant_info *va = cdvr_store_variant(a, 0), *vb = cdvr_store_variant(b, 0);
        CHECK(va->ranges_bytes > 0 && vb->ranges_bytes == 0 && va->bytes == vb->bytes &&
              va->psnr == vb->psnr && cdvr_store_get_info(b)->file_bytes <
              cdvr_store_get_info(a)->file_bytes, "tables: %llu vs %llu bytes",
              (unsigned long long)va->ranges_bytes, (unsigned long long)vb->ranges_bytes);
        for (size_t c = 0; c < va->nchunks; c++) {
            uint8_t *pa = NULL, *pb = NULL;
            CHECK_OK(cdvr_store_load_payload(a, 0, c, &pa, &err), err);
            CHECK_OK(cdvr_store_load_payload(b, 0, c, &pb, &err), err);
            CHECK(pa && pb && cdvr_store_ranges_bytes(b, 0, c) == 0 &&
                  memcmp(pa, pb, (size_t)cdvr_store_chunk(a, 0, c)->payload_bytes) == 0,
                  "chunk %zu", c);
            free(pa);
            free(pb);
        }
    }
    cdvr_store_close(a);
    cdvr_store_close(b);
    unlink(with);
    unlink(without);
    cdvr_volume_free(u8);
}

static void test_bad_threads(void)
{
    cdvr_volume *u8 = make_series(8, 8, 8, 1);
    cdvr_variant_spec vs = pvtc_spec(4, 3, CDVR_PACK_TIME, CDVR_ENCODER_BBOX, CDVR_STAGE2_NONE);
    cdvr_encode_opts o = {.variants = &vs, .nvariants = 1, .qhi = 255, .threads = -1};
    cdvr_error err;
    CHECK(cdvr_store_encode(u8, &o, tmp_path("neg.cdv"), &err) == CDVR_ERR_ARG &&
          strstr(err.msg, "threads"), "negative thread count refused: %s", err.msg);
    cdvr_volume_free(u8);
}

/* A version-2 store written before range tables (bytes 106..127 of every chunk record 0)
 * opens and decodes; its chunks report no table. */
static void test_store_without_tables(void)
{
    cdvr_volume *u8 = make_series(12, 8, 8, 3);
    cdvr_variant_spec vs = pvtc_spec(4, 3, CDVR_PACK_TIME, CDVR_ENCODER_BBOX, CDVR_STAGE2_NONE);
    cdvr_encode_opts o = {.variants = &vs, .nvariants = 1, .qhi = 255};
    const char *path = tmp_path("old.cdv");
    cdvr_error err;
    CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st) {
        cdvr_volume_free(u8);
        return;
    }
    cdvr_volume *want = NULL;
    CHECK_OK(cdvr_store_decode(st, 0, 1, &want, &err), err);
    /* rewrite the metadata as an older writer did: no tables, the same data area */
    size_t nchunks = st->nchunks_total;
    for (size_t c = 0; c < nchunks; c++) {
        cdvr_chunk_info *ci = &st->chunks[c];
        ci->ranges_shift = 0;
        ci->ranges_stage2 = 0;
        ci->ranges_crc32c = 0;
        ci->ranges_offset = ci->ranges_stored_bytes = 0;
    }
    uint64_t meta = cdvr_store_meta_bytes(1, nchunks);
    uint8_t *buf = malloc((size_t)meta + 4);
    cdvr_store_serialize_meta(st, buf);
    cdvr_store_close(st);
    FILE *f = fopen(path, "r+b");
    CHECK(f && fwrite(buf, 1, (size_t)meta + 4, f) == meta + 4, "rewrite metadata");
    if (f)
        fclose(f);
    free(buf);
    st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    cdvr_volume *got = NULL;
    if (st) {
        CHECK(cdvr_store_ranges_bytes(st, 0, 0) == 0, "no table reported");
        uint8_t dummy[2];
        CHECK(cdvr_store_read_ranges(st, 0, 0, dummy, &err) == CDVR_ERR_ARG,
              "reading a missing table is refused");
        CHECK_OK(cdvr_store_decode(st, 0, 1, &got, &err), err);
        CHECK(got && want && memcmp(got->data, want->data, 12 * 8 * 8) == 0,
              "decodes as before");
        cdvr_store_close(st);
    }
    cdvr_volume_free(got);
    cdvr_volume_free(want);
    cdvr_volume_free(u8);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/cdvr_test_encpar_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_threads_same_bytes();
    test_encode_part();
    test_ranges();
    test_no_tables();
    test_bad_threads();
    test_store_without_tables();
    const char *names[] = {"threads.cdv", "ranges.cdv", "tiny.cdv", "old.cdv", "neg.cdv"};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++)
        unlink(tmp_path(names[i]));
    rmdir(tmpdir);
    return check_finish();
}
