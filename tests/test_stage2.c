/* tests/test_stage2.c - stage 2 beyond LZO (store.h, core/codec/stage2/stage2.h):
 *   - the segmented framing round-trips bit for bit for LZO, LZ4 and zstd at the segment
 *     boundaries (1 byte, one byte short of a segment, exactly one segment, one byte more,
 *     many segments) and gives the same bytes on 1, 2, 3, 8 threads and the automatic count;
 *   - hostile segment tables (more segments than the chunk holds, a segment running past the
 *     chunk, a wrong count, segment bytes 0, trailing bytes, truncated) are refused, never read
 *     outside the buffers;
 *   - stores with stage 2 none, lzo, lz4, zstd and auto decode exactly as without stage 2
 *     (raw variants give back the volume; 1x1x1 volumes, a chunk of exactly one segment, many
 *     segments), record the codec per chunk and reopen;
 *   - a version-2 store written before this change (tests/data/v2_lzo_store.cdv, by commit
 *     23832e2, with its decoded timesteps beside it) opens and decodes bit for bit;
 *   - a stored chunk whose segment table claims more than the chunk (CRC fixed, so only the
 *     table check can find it) fails with an error naming the file, the chunk and the reason;
 *   - AUTO's unpack rates: measured once, read back from the cache as measured; with rates
 *     remembered that make LZ4 free, AUTO packs with LZ4 only, and two encodes (2 threads,
 *     1 thread) write the same bytes;
 *   - cdvr_store_load_payload_into, its buffers kept over chunks of every stage 2, gives
 *     cdvr_store_load_payload's payload;
 *   - the player plays frames identical to the render of each timestep decoded alone from the
 *     store without stage 2, for none, lzo, lz4, zstd and auto, serial and with 2 workers. */
#include "check.h"
#include "player_frames.h"

#include "codec/stage2/stage2.h"
#include "cdvr/cache.h"
#include "cdvr/pvtc.h"
#include "cdvr/timing.h"
#include "store/store_format.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static void fill(uint8_t *p, size_t n, uint32_t seed)
{
    uint32_t h = seed;
    for (size_t i = 0; i < n; i++) {
        h ^= h << 13, h ^= h >> 17, h ^= h << 5;
        p[i] = (uint8_t)((i / 7) % 13 == 0 ? h : (i / 5) % 3); /* compressible, not trivially */
    }
}

/* ---- the framing ------------------------------------------------------------------------- */

static void check_roundtrip(unsigned codec, size_t n, size_t seg)
{
    uint8_t *in = malloc(n), *out = malloc(n), *out2 = malloc(n);
    fill(in, n, (uint32_t)(n * 31 + seg));
    size_t cap = cdvr_s2_bound(codec, n, seg), got = 0;
    uint8_t *packed = malloc(cap);
    cdvr_error err;
    CHECK(cap > 0, "%s: bound of %zu bytes", cdvr_s2_name(codec), n);
    CHECK_OK(cdvr_s2_pack(codec, in, n, seg, packed, cap, &got, &err), err);
    size_t nseg = n / seg + (n % seg != 0);
    CHECK(got >= 8 + 4 * nseg && got <= cap, "%s: %zu packed bytes", cdvr_s2_name(codec), got);
    static const int threads[] = {1, 2, 3, 8, 0};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        memset(out, 0xA5, n);
        CHECK_OK(cdvr_s2_unpack(codec, packed, got, out, n, threads[t], &err), err);
        CHECK(memcmp(out, in, n) == 0, "%s %zu bytes in %zu-byte segments, %d threads: differs",
              cdvr_s2_name(codec), n, seg, threads[t]);
    }
    /* the CPU time of an unpack adds to what the caller holds, within its wall time on
     * its threads */
    double cpu = 1.5, t0 = cdvr_now_ms();
    memset(out, 0xA5, n);
    CHECK_OK(cdvr_s2_unpack_cpu(codec, packed, got, out, n, 2, &cpu, &err), err);
    double wall = cdvr_now_ms() - t0;
    CHECK(memcmp(out, in, n) == 0 && cpu > 1.5 && cpu - 1.5 <= 2 * wall + 0.05,
          "%s %zu bytes: unpack took %.4f ms of CPU in %.4f ms on 2 threads",
          cdvr_s2_name(codec), n, cpu - 1.5, wall);
    /* the expected size is part of the check: one byte more or less is refused */
    if (n > 1)
        CHECK(cdvr_s2_unpack(codec, packed, got, out2, n - 1, 1, &err) == CDVR_ERR_CORRUPT,
              "%s: a payload one byte short accepted", cdvr_s2_name(codec));
    free(in);
    free(out);
    free(out2);
    free(packed);
}

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void expect_refused(const uint8_t *packed, size_t n, size_t expect, const char *want,
                           const char *what)
{
    uint8_t *out = malloc(expect);
    cdvr_error err;
    cdvr_error_clear(&err);
    cdvr_status s = cdvr_s2_unpack(CDVR_S2_LZ4, packed, n, out, expect, 2, &err);
    CHECK(s == CDVR_ERR_CORRUPT && strstr(err.msg, want), "%s: status %d '%s' (want '%s')",
          what, s, err.msg, want);
    free(out);
}

static void check_hostile_tables(void)
{
    size_t n = 5000, seg = 1000, cap = cdvr_s2_bound(CDVR_S2_LZ4, n, seg), got = 0;
    uint8_t *in = malloc(n), *packed = malloc(cap + 64), *bad = malloc(cap + 64);
    fill(in, n, 7);
    cdvr_error err;
    CHECK_OK(cdvr_s2_pack(CDVR_S2_LZ4, in, n, seg, packed, cap, &got, &err), err);
    memcpy(bad, packed, got);
    put32(bad + 4, 0x40000000u); /* a billion segments in a few kB: before any allocation */
    put32(bad, 1);
    expect_refused(bad, got, 0x40000000u, "larger than the chunk", "huge segment count");
    memcpy(bad, packed, got);
    put32(bad + 8 + 4 * 2, 0xFFFFFFF0u); /* segment 3 runs past the chunk */
    expect_refused(bad, got, n, "claims more than the chunk", "long segment");
    memcpy(bad, packed, got);
    put32(bad + 4, 4); /* 4 segments of 1000 do not make 5000 */
    expect_refused(bad, got, n, "do not make a payload", "wrong count");
    memcpy(bad, packed, got);
    put32(bad, 0);
    expect_refused(bad, got, n, "do not make a payload", "segment bytes 0");
    memcpy(bad, packed, got);
    put32(bad + 8, 0); /* an empty segment */
    expect_refused(bad, got, n, "claims more than the chunk", "empty segment");
    memcpy(bad, packed, got);
    bad[got] = 0;
    expect_refused(bad, got + 1, n, "the chunk has", "a trailing byte");
    expect_refused(packed, 7, n, "truncated", "7 bytes");
    expect_refused(packed, 8 + 4 * 4, n, "larger than the chunk", "table cut short");
    memcpy(bad, packed, got);
    bad[8 + 4 * 5 + 3] ^= 0xFF; /* corrupt LZ4 data inside segment 1 */
    uint8_t *out = malloc(n);
    cdvr_status s = cdvr_s2_unpack(CDVR_S2_LZ4, bad, got, out, n, 3, &err);
    CHECK(s == CDVR_ERR_CORRUPT || s == CDVR_OK, "corrupt LZ4 data: status %d", s);
    /* (never outside the buffers; LZ4 may decode damaged data to other bytes of the size) */
    free(out);
    free(in);
    free(packed);
    free(bad);
}

/* ---- stores ------------------------------------------------------------------------------ */

static char dir[] = "/tmp/cdvr_test_stage2_XXXXXX";

static const char *tmp_path(const char *name)
{
    static char buf[8][256];
    static int k;
    k = (k + 1) % 8;
    snprintf(buf[k], sizeof buf[k], "%s/%s", dir, name);
    return buf[k];
}

static cdvr_volume *make_series(size_t X, size_t Y, size_t Z, size_t T)
{
    size_t dims[3] = {X, Y, Z};
    cdvr_volume *v = NULL;
    cdvr_error err;
    if (cdvr_volume_create(dims, T, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    for (size_t t = 0; t < T; t++)
        for (size_t z = 0; z < Z; z++)
            for (size_t y = 0; y < Y; y++)
                for (size_t x = 0; x < X; x++) {
                    double dx = (double)x - X / 3.0 - t, dy = (double)y - Y / 2.0,
                           dz = (double)z - Z / 2.0;
                    double r = dx * dx + dy * dy + dz * dz;
                    *p++ = (uint8_t)(r < 60 ? 230 - 3 * r : (x * 3 + y + t) % 11 == 0 ? 50 : 0);
                }
    return v;
}

static cdvr_variant_spec raw_spec(cdvr_stage2 s2, size_t seg)
{
    cdvr_variant_spec s = {.codec = cdvr_codec_find("raw"), .stage2 = s2, .lzo_min_saving = 0,
                           .stage2_segment = seg};
    s.codec->params_default(&s.params);
    snprintf(s.name, sizeof s.name, "raw_%s", cdvr_stage2_name(s2));
    return s;
}

static cdvr_variant_spec pvtc_spec(cdvr_stage2 s2, size_t seg)
{
    cdvr_variant_spec s = {.codec = cdvr_codec_find("pvtc"), .stage2 = s2, .lzo_min_saving = 0,
                           .stage2_segment = seg};
    cdvr_pvtc_params pp = {4, 3, CDVR_PACK_TIME};
    cdvr_pvtc_params_to_blob(&pp, CDVR_ENCODER_BBOX, &s.params);
    snprintf(s.name, sizeof s.name, "pvtc_%s", cdvr_stage2_name(s2));
    return s;
}

/* Every variant of a store decodes to the voxels of variant `ref_of[v]` (or the source for a
 * raw variant), at every timestep. */
static void check_store(const char *path, const cdvr_volume *src, size_t nvar,
                        const int *ref_of, const char *what)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    size_t frame = cdvr_volume_frame_bytes(src);
    for (size_t v = 0; v < nvar; v++) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        size_t counted = 0;
        for (int c = 0; c < 4; c++)
            counted += vi->stage2_chunks[c];
        CHECK(counted == vi->nchunks, "%s %s: stage2_chunks", what, vi->name);
        for (size_t c = 0; c < vi->nchunks; c++) {
            const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
            CHECK(vi->stage2 == CDVR_STAGE2_AUTO || ci->stage2 == 0 ||
                      ci->stage2 == (int)vi->stage2,
                  "%s %s chunk %zu: stage 2 %d", what, vi->name, c + 1, ci->stage2);
            CHECK(!ci->stage2 || ci->stored_bytes < ci->payload_bytes, "%s: stage 2 saves",
                  what);
        }
        for (size_t t = 0; t < src->timesteps; t++) {
            cdvr_volume *d = NULL, *r = NULL;
            CHECK_OK(cdvr_store_decode(st, v, t, &d, &err), err);
            if (ref_of[v] >= 0)
                CHECK_OK(cdvr_store_decode(st, (size_t)ref_of[v], t, &r, &err), err);
            const void *want = ref_of[v] >= 0 ? (r ? r->data : NULL) : cdvr_volume_frame(src, t);
            CHECK(d && want && memcmp(d->data, want, frame) == 0, "%s %s t=%zu differs", what,
                  vi->name, t + 1);
            cdvr_volume_free(d);
            cdvr_volume_free(r);
        }
    }
    cdvr_store_close(st);
}

static void encode(const cdvr_volume *vol, const cdvr_variant_spec *vs, size_t n,
                   const char *path, int threads)
{
    cdvr_encode_opts eo = {.variants = vs, .nvariants = n, .qhi = 255, .threads = threads};
    cdvr_error err;
    CHECK_OK(cdvr_store_encode(vol, &eo, path, &err), err);
}

static void check_store_roundtrips(void)
{
    static const cdvr_stage2 all[] = {CDVR_STAGE2_NONE, CDVR_STAGE2_LZO, CDVR_STAGE2_LZ4,
                                      CDVR_STAGE2_ZSTD, CDVR_STAGE2_AUTO};
    /* many segments (raw chunk 9000 bytes in 256-byte segments), pvtc beside it; variant 5+k
     * is pvtc with stage 2 all[k], compared with the pvtc variant without stage 2 */
    cdvr_volume *vol = make_series(30, 20, 15, 5);
    cdvr_variant_spec vs[10];
    int ref_of[10];
    for (int k = 0; k < 5; k++) {
        vs[k] = raw_spec(all[k], 256);
        vs[5 + k] = pvtc_spec(all[k], 256);
        ref_of[k] = -1;
        ref_of[5 + k] = 5;
    }
    const char *path = tmp_path("many.cdv");
    encode(vol, vs, 10, path, 0);
    check_store(path, vol, 10, ref_of, "many segments");
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    for (int k = 1; st && k < 4; k++) {
        const cdvr_chunk_info *ci = cdvr_store_chunk(st, (size_t)k, 0);
        CHECK(ci->stage2 == (int)all[k] && ci->stage2_segmented &&
                  cdvr_store_variant(st, (size_t)k)->stage2_segment == 256,
              "raw %s chunk 1: codec %d segmented %d", cdvr_stage2_name(all[k]), ci->stage2,
              ci->stage2_segmented);
        /* segmented chunks unpack to the same bytes on any thread count */
        uint8_t *stored = malloc(ci->stored_bytes), *a = malloc(ci->payload_bytes),
                *b = malloc(ci->payload_bytes);
        CHECK_OK(cdvr_store_read_chunk(st, (size_t)k, 0, stored, &err), err);
        CHECK_OK(cdvr_store_unpack_chunk_threads(st, (size_t)k, 0, stored, a, 1, &err), err);
        CHECK_OK(cdvr_store_unpack_chunk_threads(st, (size_t)k, 0, stored, b, 5, &err), err);
        CHECK(memcmp(a, b, ci->payload_bytes) == 0, "1 and 5 unpack threads differ");
        free(stored);
        free(a);
        free(b);
    }
    cdvr_store_close(st);
    cdvr_volume_free(vol);

    /* a chunk of 1 byte (1x1x1 raw): nothing to save, stored as is, still decodes */
    vol = make_series(1, 1, 1, 3);
    for (int k = 0; k < 5; k++) {
        vs[k] = raw_spec(all[k], 64);
        ref_of[k] = -1;
    }
    path = tmp_path("one.cdv");
    encode(vol, vs, 5, path, 1);
    check_store(path, vol, 5, ref_of, "1-byte chunks");
    cdvr_volume_free(vol);

    /* exactly one segment: 8x8x8 raw (512 bytes) in 512-byte segments; and one byte more than
     * a segment: 511-byte segments give two */
    vol = make_series(8, 8, 8, 2);
    for (int k = 0; k < 5; k++) {
        vs[k] = raw_spec(all[k], 512);
        vs[5 + k] = raw_spec(all[k], 511);
        snprintf(vs[5 + k].name, sizeof vs[5 + k].name, "raw511_%s", cdvr_stage2_name(all[k]));
        ref_of[k] = ref_of[5 + k] = -1;
    }
    path = tmp_path("exact.cdv");
    encode(vol, vs, 10, path, 2);
    check_store(path, vol, 10, ref_of, "one segment");
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    for (int k = 1; st && k < 4; k++) {
        const cdvr_chunk_info *ci = cdvr_store_chunk(st, (size_t)k, 0);
        if (ci->stage2) {
            uint8_t *stored = malloc(ci->stored_bytes);
            CHECK_OK(cdvr_store_read_chunk(st, (size_t)k, 0, stored, &err), err);
            if (ci->stage2_segmented)
                CHECK(stored[4] == 1 && stored[5] == 0, "%s: one segment",
                      cdvr_stage2_name(all[k]));
            else
                CHECK(all[k] == CDVR_STAGE2_LZO, "only LZO of one segment is unsegmented");
            free(stored);
        }
        ci = cdvr_store_chunk(st, (size_t)(5 + k), 0);
        CHECK(!ci->stage2 || ci->stage2_segmented, "511-byte segments: segmented");
    }
    cdvr_store_close(st);
    cdvr_volume_free(vol);

    /* bad options */
    vol = make_series(4, 4, 4, 1);
    cdvr_variant_spec bad = raw_spec(CDVR_STAGE2_LZ4, 10);
    cdvr_encode_opts eo = {.variants = &bad, .nvariants = 1, .qhi = 255};
    CHECK(cdvr_store_encode(vol, &eo, tmp_path("bad.cdv"), &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "stage2_segment"),
          "segment of 10 bytes: %s", err.msg);
    bad = raw_spec((cdvr_stage2)7, 0);
    CHECK(cdvr_store_encode(vol, &eo, tmp_path("bad.cdv"), &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "lz4"),
          "stage 2 number 7: %s", err.msg);
    bad = raw_spec(CDVR_STAGE2_AUTO, 0);
    bad.stage2_read_mbps = -1;
    CHECK(cdvr_store_encode(vol, &eo, tmp_path("bad.cdv"), &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "stage2_read_mbps"),
          "read rate -1: %s", err.msg);
    cdvr_volume_free(vol);
}

/* ---- AUTO's unpack rates ------------------------------------------------------------------ */

/* The one *.KIND entry in cache_dir into path (its key: the name's stem). */
static int cache_entry(const char *cache_dir, const char *kind, char *path, size_t n,
                       char key[33])
{
    char cmd[600];
    snprintf(cmd, sizeof cmd, "ls '%s' | grep '\\.%s$'", cache_dir, kind);
    FILE *p = popen(cmd, "r");
    char name[128] = "";
    int found = p && fgets(name, sizeof name, p) && strlen(name) == 32 + 1 + strlen(kind) + 1;
    if (p)
        pclose(p);
    if (!found)
        return 0;
    memcpy(key, name, 32);
    key[32] = '\0';
    name[strcspn(name, "\n")] = '\0';
    snprintf(path, n, "%s/%s", cache_dir, name);
    return 1;
}

/* Rates are measured once, then read back equal from the cache; AUTO follows them: with LZ4
 * remembered as free and the others as slow, every chunk that packs at all takes LZ4, and two
 * encodes write the same bytes. */
static void check_rates(void)
{
    char cache_dir[300], entry[400], key[33];
    snprintf(cache_dir, sizeof cache_dir, "%s/cache", dir);
    setenv("CDVR_CACHE_DIR", cache_dir, 1);
    cdvr_s2_rates first, again;
    cdvr_error err;
    CHECK_OK(cdvr_s2_unpack_rates(&first, &err), err);
    CHECK(!first.from_cache, "a new cache: measured");
    for (unsigned c = CDVR_S2_LZO; c < CDVR_S2_CODECS; c++)
        CHECK(first.mbps[c] > 1 && first.mbps[c] < 1e6, "%s: %.1f MB/s", cdvr_s2_name(c),
              first.mbps[c]);
    CHECK_OK(cdvr_s2_unpack_rates(&again, &err), err);
    CHECK(again.from_cache && !memcmp(again.mbps, first.mbps, sizeof first.mbps),
          "read back from the cache as measured");
    if (!cache_entry(cache_dir, "s2rates", entry, sizeof entry, key)) {
        CHECK(0, "no .s2rates entry in %s", cache_dir);
        return;
    }
    const char *forced = "lzo 1.0 lz4 100000000.0 zstd 1.0";
    cdvr_cache_store(entry, key, (const unsigned char *)forced, strlen(forced));
    CHECK_OK(cdvr_s2_unpack_rates(&again, &err), err);
    CHECK(again.from_cache && again.mbps[CDVR_S2_LZ4] == 1e8 && again.mbps[CDVR_S2_LZO] == 1,
          "the remembered rates are the ones used");
    cdvr_volume *vol = make_series(30, 20, 15, 5);
    cdvr_variant_spec vs[2] = {raw_spec(CDVR_STAGE2_AUTO, 256), pvtc_spec(CDVR_STAGE2_AUTO, 256)};
    encode(vol, vs, 2, tmp_path("rates_a.cdv"), 2);
    encode(vol, vs, 2, tmp_path("rates_b.cdv"), 1);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(tmp_path("rates_a.cdv"), &st, &err), err);
    for (size_t v = 0; st && v < 2; v++) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        CHECK(vi->stage2_chunks[CDVR_S2_LZ4] > 0 && vi->stage2_chunks[CDVR_S2_LZO] == 0 &&
                  vi->stage2_chunks[CDVR_S2_ZSTD] == 0,
              "%s: chunks none %zu lz4 %zu (lzo %zu zstd %zu)", vi->name,
              (size_t)vi->stage2_chunks[0], (size_t)vi->stage2_chunks[CDVR_S2_LZ4],
              (size_t)vi->stage2_chunks[CDVR_S2_LZO], (size_t)vi->stage2_chunks[CDVR_S2_ZSTD]);
    }
    cdvr_store_close(st);
    char cmd[700];
    snprintf(cmd, sizeof cmd, "cmp -s '%s' '%s'", tmp_path("rates_a.cdv"), tmp_path("rates_b.cdv"));
    CHECK(system(cmd) == 0, "two AUTO encodes (2 threads, 1 thread) write the same bytes");
    remove(entry);
    cdvr_volume_free(vol);
    unsetenv("CDVR_CACHE_DIR");
}

/* Test files the read-rate measurement left in the test's directory (it unlinks its own). */
static int probe_files_left(void)
{
    char cmd[400];
    snprintf(cmd, sizeof cmd, "ls -A '%s' | grep -c cdvr-read-rate", dir);
    FILE *p = popen(cmd, "r");
    int n = -1;
    if (p && fscanf(p, "%d", &n) != 1)
        n = -1;
    if (p)
        pclose(p);
    return n;
}

/* Stage 2 of each variant of the store at path: chunks stored without it, the rate AUTO
 * recorded. */
static void stored_choice(const char *path, size_t v, size_t *none, size_t *chunks,
                          double *read_mbps)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    *none = *chunks = 0;
    *read_mbps = -1;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    *none = vi->stage2_chunks[0];
    *chunks = vi->nchunks;
    *read_mbps = vi->stage2_read_mbps;
    cdvr_store_close(st);
}

/* AUTO's read side: without a rate it models the rate the player will read at, measured in
 * the store's directory (leaving no file there) and remembered: the page cache's for a
 * series that fits in half the memory (these do), the disk's for one that does not
 * (cdvr_store_modelled_read_mbps); recorded in the store; the choice follows it (1 MB/s:
 * stage 2 wherever it saves; 10^7 MB/s: never). A rate given, or a variant that is not AUTO,
 * is recorded as before. */
static void check_read_rate(void)
{
    char cache_dir[300], entry[400], key[33];
    snprintf(cache_dir, sizeof cache_dir, "%s/cache_read", dir);
    setenv("CDVR_CACHE_DIR", cache_dir, 1);
    cdvr_read_rates first, again;
    cdvr_error err;
    CHECK_OK(cdvr_store_read_rates(tmp_path("any.cdv"), &first, &err), err);
    double rate[2] = {first.disk_mbps, first.cache_mbps};
    for (int k = 0; k < 2; k++) {
        double unit = rate[k] > 0 ? pow(10.0, floor(log10(rate[k])) - 1.0) : 1;
        CHECK(!first.from_cache && rate[k] >= 1 && rate[k] <= 1e7 &&
                  rate[k] / unit == round(rate[k] / unit),
              "measured %s %g MB/s (from the cache: %d), two significant digits",
              k ? "cache" : "disk", rate[k], first.from_cache);
    }
    CHECK(probe_files_left() == 0, "%d test files left in %s", probe_files_left(), dir);
    CHECK_OK(cdvr_store_read_rates(tmp_path("other.cdv"), &again, &err), err);
    CHECK(again.from_cache && again.disk_mbps == first.disk_mbps &&
              again.cache_mbps == first.cache_mbps,
          "the same filesystem: remembered (%d, %g and %g MB/s)", again.from_cache,
          again.disk_mbps, again.cache_mbps);
    CHECK(cdvr_store_read_rates("/nonexistent-cdvr-dir/a.cdv", &again, &err) == CDVR_ERR_IO &&
              strstr(err.msg, "/nonexistent-cdvr-dir") && again.disk_mbps == 0,
          "a missing directory: %s", err.msg);
    cdvr_read_rates two = {.disk_mbps = 300, .cache_mbps = 5000};
    CHECK(cdvr_store_modelled_read_mbps(&two, 1000, 2000) == 5000 &&
              cdvr_store_modelled_read_mbps(&two, 1001, 2000) == 300 &&
              cdvr_store_modelled_read_mbps(&two, 1, 0) == 300,
          "the page cache's rate for a series in half the memory, else the disk's");

    cdvr_volume *vol = make_series(30, 20, 15, 5);
    cdvr_variant_spec vs[3] = {raw_spec(CDVR_STAGE2_AUTO, 256), raw_spec(CDVR_STAGE2_AUTO, 256),
                               raw_spec(CDVR_STAGE2_LZ4, 256)};
    vs[1].stage2_read_mbps = 200;
    snprintf(vs[1].name, sizeof vs[1].name, "raw_auto_200");
    size_t none = 0, chunks = 0;
    double recorded = 0;
    encode(vol, vs, 3, tmp_path("read_rate.cdv"), 0);
    stored_choice(tmp_path("read_rate.cdv"), 0, &none, &chunks, &recorded);
    CHECK(recorded == first.cache_mbps, "AUTO records the page cache's %g MB/s: %g",
          first.cache_mbps, recorded);
    stored_choice(tmp_path("read_rate.cdv"), 1, &none, &chunks, &recorded);
    CHECK(recorded == 200, "a rate given is recorded: %g", recorded);
    stored_choice(tmp_path("read_rate.cdv"), 2, &none, &chunks, &recorded);
    CHECK(recorded == CDVR_STAGE2_READ_MBPS, "lz4: the default recorded: %g", recorded);
    CHECK(probe_files_left() == 0, "%d test files left after the encode", probe_files_left());
    if (!cache_entry(cache_dir, "readrate", entry, sizeof entry, key)) {
        CHECK(0, "no .readrate entry in %s", cache_dir);
    } else {
        static const struct { const char *text; double mbps; int all_none; } remembered[] = {
            {"disk 1e+07 cache 1", 1, 0}, {"disk 1 cache 1e+07", 1e7, 1}};
        for (int d = 0; d < 2; d++) {
            cdvr_cache_store(entry, key, (const unsigned char *)remembered[d].text,
                             strlen(remembered[d].text));
            encode(vol, vs, 1, tmp_path("read_rate.cdv"), 0);
            stored_choice(tmp_path("read_rate.cdv"), 0, &none, &chunks, &recorded);
            CHECK(recorded == remembered[d].mbps && chunks > 0 &&
                      (remembered[d].all_none ? none == chunks : none < chunks),
                  "'%s' remembered: recorded %g, %zu of %zu chunks without stage 2",
                  remembered[d].text, recorded, none, chunks);
        }
        remove(entry);
    }
    cdvr_volume_free(vol);
    unsetenv("CDVR_CACHE_DIR");
}

/* cdvr_store_load_payload_into, with the same two buffers kept over chunks of every variant
 * (stage 2 none and lz4, raw and pvtc, so they grow and shrink in turn), gives the payload
 * of cdvr_store_load_payload. */
static void check_load_into(void)
{
    cdvr_volume *vol = make_series(30, 20, 15, 5);
    cdvr_variant_spec vs[4] = {raw_spec(CDVR_STAGE2_NONE, 256), pvtc_spec(CDVR_STAGE2_LZ4, 256),
                               raw_spec(CDVR_STAGE2_LZ4, 256), pvtc_spec(CDVR_STAGE2_NONE, 256)};
    encode(vol, vs, 4, tmp_path("into.cdv"), 1);
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(tmp_path("into.cdv"), &st, &err), err);
    uint8_t *payload = NULL, *stored = NULL;
    size_t payload_cap = 0, stored_cap = 0, loads = 0;
    for (size_t c = 0; st && c < 3; c++)
        for (size_t v = 0; v < 4; v++) {
            const cdvr_variant_info *vi = cdvr_store_variant(st, v);
            if (c >= vi->nchunks)
                continue;
            uint8_t *fresh = NULL;
            CHECK_OK(cdvr_store_load_payload(st, v, c, &fresh, &err), err);
            CHECK_OK(cdvr_store_load_payload_into(st, v, c, &payload, &payload_cap, &stored,
                                                  &stored_cap, &err), err);
            size_t n = (size_t)cdvr_store_chunk(st, v, c)->payload_bytes;
            CHECK(fresh && payload && payload_cap >= n && memcmp(fresh, payload, n) == 0,
                  "%s chunk %zu: the payload differs", vi->name, c + 1);
            free(fresh);
            loads++;
        }
    CHECK(loads >= 8, "%zu chunks loaded", loads);
    CHECK(stored_cap > 0, "an lz4 chunk used the stored buffer");
    free(payload);
    free(stored);
    cdvr_store_close(st);
    cdvr_volume_free(vol);
}

/* ---- a store from before this change ------------------------------------------------------ */

static void check_old_store(void)
{
    const char *src = getenv("CDVR_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/tests/data/v2_lzo_store.cdv", src ? src : "..");
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    const char *names[] = {"raw", "S4T3", "S1T2"};
    const int lzo[] = {1, 1, 0};
    size_t frame = 24 * 20 * 16;
    uint8_t *ref = malloc(frame);
    for (size_t v = 0; v < 3; v++) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        CHECK(strcmp(vi->name, names[v]) == 0 && vi->stage2 == (cdvr_stage2)lzo[v] &&
                  vi->stage2_segment == 0 && vi->stage2_read_mbps == 0,
              "old store variant %zu: %s stage 2 %d", v + 1, vi->name, vi->stage2);
        for (size_t c = 0; c < vi->nchunks; c++) {
            const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
            CHECK(ci->stage2 == lzo[v] && !ci->stage2_segmented, "old %s chunk %zu: LZO %d",
                  names[v], c + 1, ci->stage2);
        }
        char ref_path[1100];
        snprintf(ref_path, sizeof ref_path, "%s/tests/data/v2_lzo_store_%s.u8", src ? src : "..",
                 names[v]);
        FILE *f = fopen(ref_path, "rb");
        CHECK(f != NULL, "%s", ref_path);
        for (size_t t = 0; f && t < 4; t++) {
            cdvr_volume *d = NULL;
            CHECK(fread(ref, 1, frame, f) == frame, "%s short", ref_path);
            CHECK_OK(cdvr_store_decode(st, v, t, &d, &err), err);
            CHECK(d && memcmp(d->data, ref, frame) == 0, "old %s t=%zu differs", names[v], t + 1);
            cdvr_volume_free(d);
        }
        if (f)
            fclose(f);
    }
    free(ref);
    cdvr_store_close(st);
}

/* ---- a hostile segment table inside a chunk (CRC fixed) ----------------------------------- */

static void check_hostile_store(void)
{
    cdvr_volume *vol = make_series(30, 20, 15, 2);
    cdvr_variant_spec vs[1] = {raw_spec(CDVR_STAGE2_ZSTD, 1024)};
    const char *path = tmp_path("hostile.cdv"), *bad = tmp_path("hostile_bad.cdv");
    encode(vol, vs, 1, path, 1);
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    FILE *in = fopen(path, "rb");
    fseek(in, 0, SEEK_END);
    size_t n = (size_t)ftell(in);
    uint8_t *file = malloc(n);
    rewind(in);
    CHECK(fread(file, 1, n, in) == n, "read %s", path);
    fclose(in);
    cdvr_chunk_info *ci = (cdvr_chunk_info *)cdvr_store_chunk(st, 0, 1);
    CHECK(ci->stage2 == CDVR_S2_ZSTD && ci->stage2_segmented, "zstd chunk");
    uint8_t *bytes = file + ci->offset;
    put32(bytes + 8 + 4 * 3, 0x7FFFFFFFu); /* segment 4 claims 2 GiB */
    ci->crc32c = cdvr_crc32c(0, bytes, (size_t)ci->stored_bytes);
    cdvr_store_serialize_meta(st, file);
    cdvr_store_close(st);
    FILE *out = fopen(bad, "wb");
    CHECK(out && fwrite(file, 1, n, out) == n, "write %s", bad);
    if (out)
        fclose(out);
    free(file);
    CHECK_OK(cdvr_store_open(bad, &st, &err), err); /* the index is fine */
    cdvr_volume *d = NULL;
    if (st) {
        CHECK_OK(cdvr_store_decode(st, 0, 0, &d, &err), err); /* chunk 1 is untouched */
        cdvr_volume_free(d);
        d = NULL;
        cdvr_status s = cdvr_store_decode(st, 0, 1, &d, &err);
        CHECK(s == CDVR_ERR_CORRUPT && strstr(err.msg, bad) && strstr(err.msg, "chunk 2") &&
                  strstr(err.msg, "claims more than the chunk") && strstr(err.msg, "zstd"),
              "segment table past the chunk: status %d '%s'", s, err.msg);
        cdvr_volume_free(d);
        cdvr_store_close(st);
    }
    cdvr_volume_free(vol);
}

/* Index records that claim what the format does not allow are refused at open: a chunk codec
 * number 4 (auto records its choice) or 200, lz4 or zstd unsegmented, none segmented, an LZ4
 * chunk in a variant of zstd, segment bytes below the minimum, a read rate that is NaN. */
static void check_hostile_index(void)
{
    cdvr_volume *vol = make_series(30, 20, 15, 2);
    cdvr_variant_spec vs[1] = {raw_spec(CDVR_STAGE2_LZ4, 1024)};
    const char *path = tmp_path("index.cdv"), *bad = tmp_path("index_bad.cdv");
    encode(vol, vs, 1, path, 1);
    FILE *in = fopen(path, "rb");
    fseek(in, 0, SEEK_END);
    size_t n = (size_t)ftell(in);
    uint8_t *file = malloc(n);
    rewind(in);
    CHECK(fread(file, 1, n, in) == n, "read %s", path);
    fclose(in);
    for (int k = 0; k < 8; k++) {
        cdvr_store *st = NULL;
        cdvr_error err;
        CHECK_OK(cdvr_store_open(path, &st, &err), err);
        if (!st)
            break;
        cdvr_chunk_info *ci = (cdvr_chunk_info *)cdvr_store_chunk(st, 0, 0);
        cdvr_variant_info *vi = (cdvr_variant_info *)cdvr_store_variant(st, 0);
        CHECK(ci->stage2 == CDVR_S2_LZ4, "lz4 chunk");
        switch (k) {
        case 0: ci->stage2 = 4; break;
        case 1: ci->stage2 = 200; break;
        case 2: ci->stage2_segmented = 0; break;
        case 3: ci->stage2 = CDVR_S2_ZSTD; ci->stage2_segmented = 0; break;
        case 4: ci->stage2 = 0; ci->stage2_segmented = 1; break;
        case 5: vi->stage2 = CDVR_STAGE2_ZSTD; break;
        case 6: vi->stage2_segment = 10; break;
        default: vi->stage2_read_mbps = NAN; break;
        }
        cdvr_store_serialize_meta(st, file);
        cdvr_store_close(st);
        FILE *out = fopen(bad, "wb");
        CHECK(out && fwrite(file, 1, n, out) == n, "write %s", bad);
        if (out)
            fclose(out);
        cdvr_status s = cdvr_store_open(bad, &st, &err);
        CHECK(s == CDVR_ERR_CORRUPT && strstr(err.msg, bad), "hostile index %d: status %d '%s'",
              k, s, s == CDVR_OK ? "" : err.msg);
        if (s == CDVR_OK)
            cdvr_store_close(st);
    }
    free(file);
    cdvr_volume_free(vol);
}

/* ---- playback ----------------------------------------------------------------------------- */

#define W 32
#define H 24
#define PX ((size_t)W * H * 4)

static void check_playback(void)
{
    enum { T = 5 };
    cdvr_volume *vol = make_series(30, 20, 15, T);
    static const cdvr_stage2 all[] = {CDVR_STAGE2_NONE, CDVR_STAGE2_LZO, CDVR_STAGE2_LZ4,
                                      CDVR_STAGE2_ZSTD, CDVR_STAGE2_AUTO};
    cdvr_variant_spec vs[10];
    for (int k = 0; k < 5; k++) {
        vs[2 * k] = raw_spec(all[k], 512);
        vs[2 * k + 1] = pvtc_spec(all[k], 512);
    }
    const char *path = tmp_path("play.cdv");
    encode(vol, vs, 10, path, 0);
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    cdvr_tf tf;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {60, 0.2, 0.3, 0.9, 0.05}, {120, 0.9, 0.5, 0.2, 0.3},
                           {255, 1, 1, 1, 0.9}};
    CHECK_OK(cdvr_tf_init(&tf, pts, 4, 0, &err), err);
    cdvr_camera cam = {.eye = {80, -50, 60}, .center = {15, 10, 7.5}, .up = {0, 0, 1},
                       .fov = 30, .width = W, .height = H};
    float *ref = calloc(T * PX, sizeof(float));
    capture cap = {calloc(T * PX, sizeof(float)), T, PX};
    for (int codec = 0; st && codec < 2; codec++) {
        for (size_t t = 0; t < T; t++) /* the variant without stage 2, decoded alone */
            render_alone(st, (size_t)codec, t, CDVR_DEVICE_CPU, &tf, &cam, ref + t * PX);
        for (int k = 0; k < 5; k++) {
            size_t v = (size_t)(2 * k + codec);
            for (int workers = 0; workers <= 2; workers += 2) {
                cdvr_player_opts o = {.store = st, .device = CDVR_DEVICE_CPU, .tf = &tf,
                                      .camera = cam, .variant = (int)v,
                                      .pipelined = workers > 0, .ring = 2,
                                      .unzip_threads = workers, .frame_fn = keep_frame,
                                      .frame_ud = &cap};
                cdvr_player *p = NULL;
                CHECK_OK(cdvr_player_create(&o, &p, &err), err);
                if (!p)
                    continue;
                memset(cap.pixels, 0, sizeof(float) * T * PX);
                CHECK_OK(cdvr_player_run(p, 0, T, &err), err);
                size_t nrows = 0;
                const cdvr_frame_row *rows = cdvr_player_rows(p, &nrows);
                CHECK(nrows == T, "%zu rows", nrows);
                for (size_t i = 0; i < nrows; i++)
                    CHECK(rows[i].status == CDVR_OK &&
                              memcmp(cap.pixels + rows[i].frame * PX, ref + rows[i].t * PX,
                                     sizeof(float) * PX) == 0,
                          "%s, %d workers: frame %zu differs from stage 2 none ('%s')",
                          vs[v].name, workers, i, rows[i].error);
                cdvr_player_free(p);
            }
        }
    }
    free(ref);
    free(cap.pixels);
    cdvr_store_close(st);
    cdvr_volume_free(vol);
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    static const size_t sizes[][2] = {{1, 64},    {63, 64},    {64, 64},     {65, 64},
                                      {6400, 64}, {9999, 100}, {100000, 4096}, {70000, 1 << 20}};
    for (unsigned c = CDVR_S2_LZO; c < CDVR_S2_CODECS; c++)
        for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++)
            check_roundtrip(c, sizes[i][0], sizes[i][1]);
    CHECK(cdvr_s2_bound(CDVR_S2_LZ4, 100, 0) == 0 && cdvr_s2_bound(9, 100, 10) == 0,
          "bad bounds are 0");
    check_hostile_tables();
    check_store_roundtrips();
    check_rates();
    check_read_rate();
    check_load_into();
    check_old_store();
    check_hostile_store();
    check_hostile_index();
    check_playback();
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return check_finish();
}
