/* tests/test_store.c - the .cdv store: round trips on the hard cases of DESIGN.md section 9,
 * several variants per store, schedules, stage-2 decisions, every corruption, failed writes,
 * the best-variant rule (cdvr_store_best_variant). */
#include "check.h"

#include "cdvr/pvtc.h"
#include "store/store_format.h"

#include <dirent.h>
#include <fcntl.h>
#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[256];

static const char *tmp_path(const char *name)
{
    static char bufs[4][512]; /* a few live at once (good and bad copies of a store) */
    static int next;
    char *buf = bufs[next++ % 4];
    snprintf(buf, sizeof bufs[0], "%s/%s", tmpdir, name);
    return buf;
}

static int file_exists(const char *path)
{
    struct stat sb;
    return stat(path, &sb) == 0;
}

/* Files in tmpdir whose name starts with prefix. */
static int count_files(const char *prefix)
{
    DIR *d = opendir(tmpdir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += strncmp(e->d_name, prefix, strlen(prefix)) == 0;
    if (d)
        closedir(d);
    return n;
}

/* Deterministic content with the hard blocks: constant areas, two values, 0/255 extremes,
 * channels moving in opposite directions over time, and noise. */
static cdvr_volume *make_series(size_t x, size_t y, size_t z, size_t t)
{
    size_t dims[3] = {x, y, z};
    cdvr_volume *v = NULL;
    cdvr_error err;
    if (cdvr_volume_create(dims, t, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    uint32_t seed = 7;
    for (size_t ti = 0; ti < t; ti++)
        for (size_t k = 0; k < z; k++)
            for (size_t j = 0; j < y; j++)
                for (size_t i = 0; i < x; i++) {
                    seed = seed * 1664525u + 1013904223u;
                    uint8_t val;
                    if (k % 4 == 0)
                        val = 77;                                   /* constant */
                    else if (k % 4 == 1)
                        val = ((i + j) % 2) ? 255 : 0;              /* two-valued, extremes */
                    else if (k % 4 == 2)
                        val = (uint8_t)(ti % 2 ? 20 * ti + i : 250 - 20 * ti - j); /* opposite */
                    else
                        val = (uint8_t)(seed >> 24);                /* noise */
                    *p++ = val;
                }
    return v;
}

enum { RAW, PVTC };

static cdvr_pvtc_params pvtc_of(const cdvr_codec_params *blob, cdvr_pvtc_encoder *enc)
{
    cdvr_pvtc_params p;
    cdvr_pvtc_params_from_blob(blob, &p, enc);
    return p;
}

/* Direct reference: encode the group holding t with the pvtc codec and decode frame t. */
static int reference_frame(const cdvr_volume *u8, const cdvr_chunk_info *ci, size_t t,
                           uint8_t *out)
{
    cdvr_pvtc_geometry g;
    cdvr_error err;
    cdvr_pvtc_encoder enc;
    cdvr_pvtc_params pp = pvtc_of(&ci->params, &enc);
    const cdvr_pvtc_params *p = &pp;
    if (cdvr_pvtc_geometry_get(p, u8->dims, &g, &err) != CDVR_OK)
        return 0;
    const uint8_t *in[3];
    for (size_t i = 0; i < g.frames; i++)
        in[i] = cdvr_volume_frame(u8, ci->t0 + (i < ci->count ? i : ci->count - 1));
    uint8_t *bytes = malloc(g.chunk_bytes);
    size_t voxels = cdvr_volume_voxels(u8);
    uint8_t *scratch = malloc(voxels * 3), *frames[3];
    for (size_t i = 0; i < ci->count; i++)
        frames[i] = i == t - ci->t0 ? out : scratch + i * voxels;
    int ok = cdvr_pvtc_encode_chunk(p, enc, u8->dims, in, bytes, &err) == CDVR_OK &&
             cdvr_pvtc_decode_chunk(p, u8->dims, bytes, g.chunk_bytes, frames, ci->count,
                                    &err) == CDVR_OK;
    free(bytes);
    free(scratch);
    return ok;
}

static cdvr_variant_spec spec(const char *name, int codec, int S, int T, cdvr_pack pack,
                              cdvr_pvtc_encoder enc, cdvr_stage2 stage2)
{
    cdvr_variant_spec s = {.codec = cdvr_codec_find(codec == RAW ? "raw" : "pvtc"),
                           .stage2 = stage2, .lzo_min_saving = -1};
    if (codec == RAW) {
        s.codec->params_default(&s.params);
    } else {
        cdvr_pvtc_params p = {S, T, pack};
        cdvr_pvtc_params_to_blob(&p, enc, &s.params);
    }
    snprintf(s.name, sizeof s.name, "%s", name);
    return s;
}

static cdvr_encode_opts opts_for(const cdvr_variant_spec *v, size_t n)
{
    return (cdvr_encode_opts){.variants = v, .nvariants = n, .qlo = 0, .qhi = 255,
                              .source_type = CDVR_TYPE_U8};
}

/* Every timestep of every variant decodes exactly as the direct codec round trip; PSNR and
 * max error match. */
static void check_store_against_codec(const cdvr_store *st, const cdvr_volume *u8,
                                      const char *what)
{
    const cdvr_store_info *in = cdvr_store_get_info(st);
    size_t voxels = cdvr_volume_voxels(u8);
    uint8_t *ref = malloc(voxels);
    for (size_t v = 0; v < in->nvariants; v++) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        double sse = 0, maxerr = 0;
        int same = 1;
        for (size_t t = 0; t < in->timesteps; t++) {
            cdvr_volume *d = NULL;
            cdvr_error err;
            cdvr_status s = cdvr_store_decode(st, v, t, &d, &err);
            CHECK_OK(s, err);
            if (s != CDVR_OK)
                continue;
            const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, cdvr_store_chunk_for_time(st, v, t));
            const uint8_t *orig = cdvr_volume_frame(u8, t);
            if (strcmp(vi->codec_name, "raw") == 0)
                memcpy(ref, orig, voxels);
            else
                CHECK(reference_frame(u8, ci, t, ref), "%s: reference", what);
            same &= memcmp(ref, d->data, voxels) == 0;
            for (size_t k = 0; k < voxels; k++) {
                double e = (double)orig[k] - ((uint8_t *)d->data)[k];
                sse += e * e;
                maxerr = fabs(e) > maxerr ? fabs(e) : maxerr;
            }
            cdvr_volume_free(d);
        }
        CHECK(same, "%s: variant %s decodes differently from the codec", what, vi->name);
        double mse = sse / (double)(voxels * in->timesteps);
        double psnr = mse > 0 ? 10 * log10(255.0 * 255.0 / mse) : HUGE_VAL;
        CHECK(psnr == vi->psnr || fabs(psnr - vi->psnr) < 1e-9, "%s: %s psnr %g vs %g", what,
              vi->name, vi->psnr, psnr);
        CHECK(maxerr == vi->maxerr, "%s: %s maxerr %g vs %g", what, vi->name, vi->maxerr, maxerr);
    }
    free(ref);
}

static void check_chunk_layout(const cdvr_store *st, size_t v, size_t timesteps)
{
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    size_t next = 0;
    for (size_t c = 0; c < vi->nchunks; c++) {
        const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
        cdvr_codec_shape shape;
        size_t group = cdvr_codec_shape_of(ci->codec, &ci->params, cdvr_store_get_info(st)->dims,
                                           &shape, NULL) == CDVR_OK ? shape.timesteps : 0;
        size_t want = timesteps - next < group ? timesteps - next : group;
        CHECK(ci->t0 == next && ci->count == want, "%s chunk %zu: t0 %zu count %zu", vi->name,
              c + 1, ci->t0, ci->count);
        CHECK(cdvr_store_chunk_for_time(st, v, next) == c, "chunk_for_time");
        next += ci->count;
    }
    CHECK(next == timesteps, "%s covers %zu of %zu", vi->name, next, timesteps);
    CHECK(cdvr_store_chunk_for_time(st, v, timesteps) == (size_t)-1, "past the end");
}

static void test_hard_case_round_trips(void)
{
    const size_t dims[][3] = {{1, 1, 1}, {5, 3, 7}, {8, 4, 9}};
    const size_t steps[] = {1, 2, 4, 5};
    cdvr_variant_spec vs[] = {
        spec("", PVTC, 4, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("", PVTC, 1, 2, CDVR_PACK_TIME, CDVR_ENCODER_BBOX, CDVR_STAGE2_NONE),
        spec("", PVTC, 1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE),
        spec("", PVTC, 4, 2, CDVR_PACK_SPACE, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("", PVTC, 1, 3, CDVR_PACK_SPACE, CDVR_ENCODER_BBOX, CDVR_STAGE2_LZO),
        spec("", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
    };
    const char *names[] = {"S4T3", "S1T2", "S1T3", "S4T2s", "S1T3s", "raw"};
    size_t nv = sizeof vs / sizeof *vs;
    cdvr_encode_opts o = opts_for(vs, nv);
    for (size_t d = 0; d < sizeof dims / sizeof *dims; d++)
        for (size_t s = 0; s < sizeof steps / sizeof *steps; s++) {
            char what[64];
            snprintf(what, sizeof what, "%zux%zux%zu x %zu", dims[d][0], dims[d][1], dims[d][2],
                     steps[s]);
            cdvr_volume *u8 = make_series(dims[d][0], dims[d][1], dims[d][2], steps[s]);
            cdvr_error err;
            const char *path = tmp_path("hard.cdv");
            cdvr_status rc = cdvr_store_encode(u8, &o, path, &err);
            CHECK_OK(rc, err);
            cdvr_store *st = NULL;
            if (rc == CDVR_OK)
                CHECK_OK(rc = cdvr_store_open(path, &st, &err), err);
            if (rc == CDVR_OK) {
                const cdvr_store_info *in = cdvr_store_get_info(st);
                CHECK(in->nvariants == nv && in->timesteps == steps[s] &&
                      in->raw_bytes == cdvr_volume_voxels(u8) * steps[s], "%s: info", what);
                for (size_t v = 0; v < nv; v++) {
                    CHECK(cdvr_store_find_variant(st, names[v]) == (int)v, "%s: name %s (got %s)",
                          what, names[v], cdvr_store_variant(st, v)->name);
                    check_chunk_layout(st, v, steps[s]);
                }
                check_store_against_codec(st, u8, what);
                CHECK(isinf(cdvr_store_variant(st, nv - 1)->psnr), "raw is lossless");
                cdvr_store_close(st);
            }
            cdvr_volume_free(u8);
        }
}

typedef struct sched_log {
    size_t calls;
    size_t t0s[64];
} sched_log;

static cdvr_status alternate_T(void *ud, size_t variant, size_t t0, cdvr_codec_params *blob,
                               cdvr_error *err)
{
    (void)err;
    sched_log *log = ud;
    if (variant == 0 && log->calls < 64)
        log->t0s[log->calls++] = t0;
    cdvr_pvtc_encoder enc;
    cdvr_pvtc_params p = pvtc_of(blob, &enc);
    p.T = (t0 / 5) % 2 ? 2 : 3; /* groups at t0 = 0 (T3), 3 (T3), 6 (T2), 8 (T2), 10 (T3) */
    if (t0 >= 12)
        p.S = 1;
    cdvr_pvtc_params_to_blob(&p, enc, blob);
    return CDVR_OK;
}

static void test_schedule(void)
{
    cdvr_variant_spec vs[] = {
        spec("sched", PVTC, 4, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO)};
    cdvr_encode_opts o = opts_for(vs, 1);
    sched_log log = {0};
    o.schedule = alternate_T;
    o.schedule_ud = &log;
    cdvr_volume *u8 = make_series(9, 6, 5, 14);
    cdvr_error err;
    const char *path = tmp_path("sched.cdv");
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    const size_t want_t0[] = {0, 3, 6, 8, 10, 13};
    const int want_T[] = {3, 3, 2, 2, 3, 3}, want_S[] = {4, 4, 4, 4, 4, 1};
    CHECK(log.calls == 6, "schedule called %zu times", log.calls);
    if (st) {
        CHECK(cdvr_store_variant(st, 0)->nchunks == 6, "%zu chunks",
              cdvr_store_variant(st, 0)->nchunks);
        for (size_t c = 0; c < 6 && c < cdvr_store_variant(st, 0)->nchunks; c++) {
            const cdvr_chunk_info *ci = cdvr_store_chunk(st, 0, c);
            cdvr_pvtc_params p = pvtc_of(&ci->params, NULL);
            CHECK(ci->t0 == want_t0[c] && p.T == want_T[c] && p.S == want_S[c] &&
                  log.t0s[c] == want_t0[c], "chunk %zu: t0 %zu S%d T%d", c + 1, ci->t0, p.S,
                  p.T);
        }
        CHECK(cdvr_store_chunk(st, 0, 5)->count == 1, "last group padded");
        check_store_against_codec(st, u8, "schedule");
        cdvr_store_close(st);
    }
    cdvr_volume_free(u8);
}

static void test_stage2_decisions(void)
{
    size_t dims[3] = {32, 32, 8};
    cdvr_volume *flat = NULL, *noise = make_series(32, 32, 8, 3);
    cdvr_error err;
    cdvr_volume_create(dims, 3, CDVR_TYPE_U8, &flat, &err);
    uint8_t *noisy = noise->data;
    uint32_t seed = 99;
    for (size_t i = 0; i < 32 * 32 * 8 * 3; i++) { /* all noise: LZO cannot pay */
        seed = seed * 1664525u + 1013904223u;
        noisy[i] = (uint8_t)(seed >> 24);
    }
    cdvr_variant_spec vs[] = {
        spec("lzo", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("never", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("none", PVTC, 1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE)};
    vs[1].lzo_min_saving = 1.0;
    cdvr_encode_opts o = opts_for(vs, 3);
    const cdvr_volume *inputs[] = {flat, noise};
    for (int k = 0; k < 2; k++) {
        cdvr_store *st = NULL;
        CHECK_OK(cdvr_store_encode(inputs[k], &o, tmp_path("s2.cdv"), &err), err);
        CHECK_OK(cdvr_store_open(tmp_path("s2.cdv"), &st, &err), err);
        if (!st)
            continue;
        for (size_t c = 0; c < 3; c++) {
            const cdvr_chunk_info *lzo = cdvr_store_chunk(st, 0, c);
            CHECK(lzo->stage2 == (k == 0), "input %d chunk %zu: lzo flag %d", k, c + 1, lzo->stage2);
            CHECK(lzo->stage2 ? lzo->stored_bytes <= lzo->payload_bytes * 0.9
                              : lzo->stored_bytes == lzo->payload_bytes, "stored bytes");
            CHECK(!cdvr_store_chunk(st, 1, c)->stage2, "min saving 1.0 never keeps LZO");
        }
        CHECK(!cdvr_store_chunk(st, 2, 0)->stage2, "stage2 none");
        check_store_against_codec(st, inputs[k], "stage2");
        cdvr_store_close(st);
    }
    cdvr_volume_free(flat);
    cdvr_volume_free(noise);
}

static size_t progress_calls, progress_total;

static void count_progress(void *ud, size_t done, size_t total)
{
    (void)ud;
    CHECK(done == progress_calls + 1 && done <= total, "progress %zu/%zu", done, total);
    progress_calls = done;
    progress_total = total;
}

static void test_bad_requests(void)
{
    cdvr_volume *u8 = make_series(4, 4, 4, 3);
    cdvr_error err;
    cdvr_variant_spec dup[] = {
        spec("a", PVTC, 4, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE),
        spec("a", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE)};
    cdvr_encode_opts o = opts_for(dup, 2);
    const char *path = tmp_path("bad.cdv");
    CHECK(cdvr_store_encode(u8, &o, path, &err) == CDVR_ERR_ARG && strstr(err.msg, "a"),
          "duplicate names: %s", err.msg);
    dup[1] = spec("", PVTC, 3, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE);
    CHECK(cdvr_store_encode(u8, &o, path, &err) != CDVR_OK, "S=3 accepted");
    dup[1] = spec("", PVTC, 4, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE);
    CHECK(cdvr_store_encode(u8, &o, path, &err) == CDVR_OK, "S4T3 + a: %s", err.msg);
    o.progress = count_progress;
    progress_calls = 0;
    dup[1] = spec("", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE);
    CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
    CHECK(progress_calls == 4 && progress_total == 4, "progress %zu of %zu", progress_calls,
          progress_total);
    cdvr_volume *f32 = NULL;
    cdvr_volume_create(u8->dims, 1, CDVR_TYPE_F32, &f32, &err);
    CHECK(cdvr_store_encode(f32, &o, path, &err) == CDVR_ERR_ARG, "f32 accepted");
    cdvr_store *st = NULL;
    CHECK(cdvr_store_open(tmp_path("missing.cdv"), &st, &err) == CDVR_ERR_IO && !st, "missing");
    cdvr_volume_free(f32);
    cdvr_volume_free(u8);
    unlink(path);
}

static cdvr_status fail_late(void *ud, size_t variant, size_t t0, cdvr_codec_params *p,
                             cdvr_error *err)
{
    (void)ud;
    (void)p;
    if (variant == 1 && t0 >= 3)
        return cdvr_error_set(err, CDVR_ERR_ARG, "schedule refuses t0 %zu", t0);
    return CDVR_OK;
}

static size_t chunks_seen;

static void fail_in_progress(void *ud, size_t done, size_t total)
{
    (void)total;
    chunks_seen = done;
    *(int *)ud = 1;
}

static void test_failed_writes(void)
{
    cdvr_volume *u8 = make_series(6, 5, 4, 6);
    cdvr_error err;
    cdvr_variant_spec vs[] = {
        spec("", PVTC, 1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("", PVTC, 4, 2, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO)};
    cdvr_encode_opts o = opts_for(vs, 2);
    /* missing directory */
    CHECK(cdvr_store_encode(u8, &o, tmp_path("no/such/dir.cdv"), &err) == CDVR_ERR_IO,
          "missing dir: %s", err.msg);
    /* final name is a directory: the rename fails after everything was written */
    const char *dir = tmp_path("isdir.cdv");
    mkdir(dir, 0755);
    char inner[600];
    snprintf(inner, sizeof inner, "%s/keep", dir);
    fclose(fopen(inner, "w"));
    CHECK(cdvr_store_encode(u8, &o, dir, &err) == CDVR_ERR_IO, "rename over dir: %s", err.msg);
    CHECK(count_files("isdir.cdv.tmp") == 0, "temporary file left behind");
    unlink(inner);
    rmdir(dir);
    /* a schedule error in the middle: nothing under the final name, no temporary */
    const char *path = tmp_path("late.cdv");
    o.schedule = fail_late;
    CHECK(cdvr_store_encode(u8, &o, path, &err) == CDVR_ERR_ARG &&
          strstr(err.msg, "refuses"), "schedule error: %s", err.msg);
    CHECK(!file_exists(path) && count_files("late.cdv") == 0, "partial file after failure");
    /* an existing store survives a failed re-encode unchanged */
    o.schedule = NULL;
    int called = 0;
    o.progress = fail_in_progress;
    o.progress_ud = &called;
    CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
    CHECK(called && chunks_seen == 5, "progress saw %zu chunks", chunks_seen);
    struct stat before, after;
    stat(path, &before);
    o.schedule = fail_late;
    CHECK(cdvr_store_encode(u8, &o, path, &err) != CDVR_OK, "second encode should fail");
    stat(path, &after);
    CHECK(before.st_ino == after.st_ino && before.st_size == after.st_size, "old store replaced");
    CHECK(count_files("late.cdv") == 1, "temporary left behind");
    unlink(path);
    cdvr_volume_free(u8);
}

/* ---- corruption ------------------------------------------------------------------------- */

static uint8_t *read_file(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    fseek(f, 0, SEEK_END);
    *n = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *buf = malloc(*n);
    *n = fread(buf, 1, *n, f);
    fclose(f);
    return buf;
}

static void write_file(const char *path, const uint8_t *buf, size_t n)
{
    FILE *f = fopen(path, "wb");
    fwrite(buf, 1, n, f);
    fclose(f);
}

/* Opens path, reads every range table and decodes everything; returns 1 if any step reported
 * an error. Messages must name the file. */
static int open_and_decode_all(const char *path)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    if (cdvr_store_open(path, &st, &err) != CDVR_OK) {
        CHECK(strstr(err.msg, path) != NULL, "message without the file name: %s", err.msg);
        return 1;
    }
    int failed = 0;
    const cdvr_store_info *in = cdvr_store_get_info(st);
    for (size_t v = 0; v < in->nvariants; v++)
        for (size_t c = 0; c < cdvr_store_variant(st, v)->nchunks; c++) {
            size_t n = cdvr_store_ranges_bytes(st, v, c);
            uint8_t *table = malloc(n ? n : 1);
            if (n && cdvr_store_read_ranges(st, v, c, table, &err) != CDVR_OK) {
                failed = 1;
                CHECK(strstr(err.msg, path) && strstr(err.msg, "range table"), "message: %s",
                      err.msg);
            }
            free(table);
        }
    for (size_t v = 0; v < in->nvariants; v++)
        for (size_t t = 0; t < in->timesteps; t++) {
            cdvr_volume *d = NULL;
            if (cdvr_store_decode(st, v, t, &d, &err) != CDVR_OK) {
                failed = 1;
                CHECK(strstr(err.msg, path) && strstr(err.msg, "chunk"), "message: %s", err.msg);
            }
            cdvr_volume_free(d);
        }
    cdvr_store_close(st);
    return failed;
}

static void test_corruption(void)
{
    cdvr_volume *u8 = make_series(16, 8, 7, 4);
    cdvr_error err;
    cdvr_variant_spec vs[] = {
        spec("", PVTC, 1, 2, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("", PVTC, 4, 3, CDVR_PACK_SPACE, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE),
        spec("", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO)};
    vs[0].lzo_min_saving = 0.0;
    vs[2].lzo_min_saving = 0.0;
    cdvr_encode_opts o = opts_for(vs, 3);
    const char *good = tmp_path("good.cdv");
    CHECK_OK(cdvr_store_encode(u8, &o, good, &err), err);
    size_t n;
    uint8_t *bytes = read_file(good, &n);
    const char *bad = tmp_path("bad.cdv");
    CHECK(open_and_decode_all(good) == 0, "pristine store fails");
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(good, &st, &err), err);
    size_t data_offset = (size_t)cdvr_store_meta_bytes(3, st ? st->nchunks_total : 0) + 4;
    int lzo_chunks = 0;
    for (size_t c = 0; st && c < st->nchunks_total; c++)
        lzo_chunks += st->chunks[c].stage2;
    CHECK(lzo_chunks > 0, "no LZO chunk to corrupt");
    cdvr_store_close(st);
    size_t missed = 0;
    for (size_t i = 0; i < n; i += i < data_offset ? 1 : 3) { /* every metadata byte */
        bytes[i] ^= 0x01;
        write_file(bad, bytes, n);
        missed += !open_and_decode_all(bad);
        bytes[i] ^= 0x01;
    }
    CHECK(missed == 0, "%zu flipped bytes went unnoticed", missed);
    missed = 0;
    for (size_t len = 0; len < n; len++) { /* truncation at every offset */
        write_file(bad, bytes, len);
        missed += !open_and_decode_all(bad);
    }
    CHECK(missed == 0, "%zu truncations went unnoticed", missed);
    write_file(bad, bytes, n);
    FILE *f = fopen(bad, "ab");
    fputc(0, f);
    fclose(f);
    CHECK(open_and_decode_all(bad), "appended byte unnoticed");
    free(bytes);
    cdvr_volume_free(u8);
    unlink(bad);
    unlink(good);
}

/* Forged metadata: random values with a recomputed CRC must be rejected or decode safely
 * (ASan checks that nothing reads or writes out of bounds). */
static void test_forged_metadata(void)
{
    cdvr_volume *u8 = make_series(6, 5, 9, 5);
    cdvr_error err;
    cdvr_variant_spec vs[] = {
        spec("", PVTC, 4, 3, CDVR_PACK_TIME, CDVR_ENCODER_BBOX, CDVR_STAGE2_LZO),
        spec("", PVTC, 1, 2, CDVR_PACK_SPACE, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE)};
    vs[0].lzo_min_saving = 0.0;
    cdvr_encode_opts o = opts_for(vs, 3);
    const char *good = tmp_path("forge.cdv"), *bad = tmp_path("forged.cdv");
    CHECK_OK(cdvr_store_encode(u8, &o, good, &err), err);
    size_t n;
    uint8_t *bytes = read_file(good, &n);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(good, &st, &err), err);
    size_t meta = st ? (size_t)cdvr_store_meta_bytes(3, st->nchunks_total) : 0;
    cdvr_store_close(st);
    const uint8_t values[] = {0x00, 0xff, 0x01, 0x80, 0x7f, 0x03};
    size_t rejected = 0, total = 0;
    for (size_t i = 8; i < meta; i++)
        for (size_t k = 0; k < sizeof values; k++) {
            uint8_t keep = bytes[i];
            if (keep == values[k])
                continue;
            bytes[i] = values[k];
            uint32_t crc = cdvr_crc32c(0, bytes, meta);
            uint8_t old_crc[4];
            memcpy(old_crc, bytes + meta, 4);
            for (int b = 0; b < 4; b++)
                bytes[meta + b] = (uint8_t)(crc >> (8 * b));
            write_file(bad, bytes, n);
            rejected += open_and_decode_all(bad);
            total++;
            bytes[i] = keep;
            memcpy(bytes + meta, old_crc, 4);
        }
    /* psnr/maxerr/lzo_min_saving bytes may take harmless values; everything else must fail */
    CHECK(rejected > total / 2, "only %zu of %zu forged tables rejected", rejected, total);
    free(bytes);
    cdvr_volume_free(u8);
    unlink(bad);
    unlink(good);
}

/* ---- format version 1, bricks, codecs that are not loaded -------------------------------- */

/* tests/data/v1_store.cdv was written by the format-version-1 cdvr (commit fc44fca), with the
 * decoded timesteps of each variant beside it (v1_store_<variant>.u8): it must still open and
 * decode bit for bit. */
static void test_version1(void)
{
    const char *src = getenv("CDVR_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/tests/data/v1_store.cdv", src ? src : "..");
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    const cdvr_store_info *in = cdvr_store_get_info(st);
    CHECK(in->version == 1 && in->dims[0] == 9 && in->dims[1] == 7 && in->dims[2] == 5 &&
              in->timesteps == 5 && in->nvariants == 4 && in->nbricks == 1 &&
              in->direction[0] == 1 && in->direction[4] == 1 && in->direction[8] == 1,
          "v1 header");
    const char *names[] = {"S4T3", "S1T2s", "raw", "S1T3"};
    const double psnr[] = {24.47592375977, 35.761913662352, HUGE_VAL, 36.828793775913};
    for (size_t v = 0; v < 4; v++) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        CHECK(strcmp(vi->name, names[v]) == 0 && vi->codec != NULL, "v1 variant %zu: %s", v,
              vi->name);
        CHECK(isinf(psnr[v]) ? isinf(vi->psnr) : fabs(vi->psnr - psnr[v]) < 1e-9,
              "v1 %s psnr %g", vi->name, vi->psnr);
        char ref_path[1100];
        snprintf(ref_path, sizeof ref_path, "%s/tests/data/v1_store_%s.u8", src ? src : "..",
                 names[v]);
        FILE *f = fopen(ref_path, "rb");
        CHECK(f != NULL, "%s", ref_path);
        uint8_t ref[9 * 7 * 5];
        for (size_t t = 0; f && t < 5; t++) {
            cdvr_volume *d = NULL;
            CHECK(fread(ref, 1, sizeof ref, f) == sizeof ref, "%s short", ref_path);
            CHECK_OK(cdvr_store_decode(st, v, t, &d, &err), err);
            CHECK(d && memcmp(d->data, ref, sizeof ref) == 0, "v1 %s t=%zu differs", names[v],
                  t + 1);
            cdvr_volume_free(d);
        }
        if (f)
            fclose(f);
    }
    cdvr_store_close(st);
}

/* Bricked stores: every brick encoded on its own (with the shared boundary voxel), assembled
 * on decode; raw bricks give back the volume exactly; the recorded PSNR is that of the
 * assembled volumes; reading one brick reads only its chunk. */
static void test_bricks(void)
{
    cdvr_volume *u8 = make_series(13, 9, 11, 5);
    for (size_t i = 0; i < 9; i++)
        u8->direction[i] = i == 1 ? -1 : i == 3 ? 1 : i == 8 ? 1 : 0; /* x->y, y->-x */
    u8->origin[0] = 3.5;
    u8->spacing[2] = 2.25;
    cdvr_variant_spec vs[] = {
        spec("", PVTC, 1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_LZO),
        spec("", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE),
        spec("", PVTC, 4, 2, CDVR_PACK_SPACE, CDVR_ENCODER_BBOX, CDVR_STAGE2_NONE)};
    cdvr_encode_opts o = opts_for(vs, 3);
    o.bricks[0] = 3;
    o.bricks[1] = 2;
    o.bricks[2] = 2;
    cdvr_error err;
    const char *path = tmp_path("bricks.cdv");
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (st) {
        const cdvr_store_info *in = cdvr_store_get_info(st);
        CHECK(in->nbricks == 12 && in->bricks[0] == 3 && in->direction[1] == -1 &&
              in->origin[0] == 3.5 && in->spacing[2] == 2.25, "bricked header");
        size_t lo[3], bd[3];
        cdvr_store_brick_box(in, 2, lo, bd); /* along x: cells 12 / 3 -> 0, 4, 8, 12 */
        CHECK(lo[0] == 8 && bd[0] == 5 && lo[1] == 0 && bd[1] == 5, "brick 3 box %zu+%zu",
              lo[0], bd[0]);
        CHECK(cdvr_store_variant(st, 0)->nchunks == 2 * 12 &&
              cdvr_store_variant(st, 1)->nchunks == 5 * 12, "chunks per variant");
        for (size_t c = 0; c < cdvr_store_variant(st, 1)->nchunks; c++) {
            const cdvr_chunk_info *ci = cdvr_store_chunk(st, 1, c);
            cdvr_store_brick_box(in, ci->brick, lo, bd);
            CHECK(ci->brick == c % 12 && ci->payload_bytes == bd[0] * bd[1] * bd[2],
                  "raw brick chunk %zu", c);
            CHECK(cdvr_store_chunk_for(st, 1, ci->t0, ci->brick) == c, "chunk_for");
        }
        for (size_t v = 0; v < 3; v++) {
            double sse = 0;
            for (size_t t = 0; t < 5; t++) {
                cdvr_volume *d = NULL;
                CHECK_OK(cdvr_store_decode(st, v, t, &d, &err), err);
                if (!d)
                    continue;
                CHECK(d->direction[1] == -1 && d->origin[0] == 3.5, "decoded geometry");
                const uint8_t *orig = cdvr_volume_frame(u8, t), *got = d->data;
                for (size_t k = 0; k < cdvr_volume_voxels(u8); k++)
                    sse += ((double)orig[k] - got[k]) * ((double)orig[k] - got[k]);
                cdvr_volume_free(d);
            }
            double mse = sse / (double)in->raw_bytes;
            double psnr = mse > 0 ? 10 * log10(255.0 * 255.0 / mse) : HUGE_VAL;
            const cdvr_variant_info *vi = cdvr_store_variant(st, v);
            CHECK(v == 1 ? (isinf(vi->psnr) && sse == 0) : fabs(psnr - vi->psnr) < 1e-9,
                  "bricked %s: psnr %g recorded %g", vi->name, psnr, vi->psnr);
        }
        cdvr_store_close(st);
    }
    o.bricks[0] = 13; /* more bricks than cells */
    CHECK(cdvr_store_encode(u8, &o, path, &err) == CDVR_ERR_ARG && strstr(err.msg, "bricks"),
          "too many bricks: %s", err.msg);
    cdvr_volume_free(u8);
    unlink(path);
}

/* A store naming a codec that is not loaded opens, lists it, and fails to decode only that
 * variant, with the message users act on. */
static void test_codec_not_loaded(void)
{
    static cdvr_codec fake;
    fake = *cdvr_codec_find("raw");
    fake.name = "fakeplug";
    fake.id = 4242;
    cdvr_error err;
    CHECK_OK(cdvr_codec_register(&fake, &err), err);
    cdvr_volume *u8 = make_series(6, 5, 4, 3);
    cdvr_variant_spec vs[] = {
        spec("", PVTC, 1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE),
        spec("plug", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE)};
    vs[1].codec = &fake;
    cdvr_encode_opts o = opts_for(vs, 2);
    const char *path = tmp_path("plug.cdv");
    CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
    /* rename the codec in the file (id and name), as if written with a plugin not loaded here */
    size_t n;
    uint8_t *bytes = read_file(path, &n);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    size_t meta = st ? (size_t)cdvr_store_meta_bytes(2, st->nchunks_total) : 0;
    size_t first_chunk = st ? st->chunk_first[1] : 0, nchunks = st ? st->variants[1].nchunks : 0;
    cdvr_store_close(st);
    uint8_t *var = bytes + CDVR_STORE_HEADER_BYTES + CDVR_STORE_VARIANT_BYTES;
    memset(var + 32, 0, 16);
    memcpy(var + 32, "zfpx", 4);
    uint32_t id = 31337;
    for (int b = 0; b < 4; b++)
        var[48 + b] = (uint8_t)(id >> (8 * b));
    for (size_t c = 0; c < nchunks; c++) {
        uint8_t *rec = bytes + CDVR_STORE_HEADER_BYTES + 2 * CDVR_STORE_VARIANT_BYTES +
                       (first_chunk + c) * CDVR_STORE_CHUNK_BYTES;
        for (int b = 0; b < 4; b++)
            rec[20 + b] = (uint8_t)(id >> (8 * b));
    }
    uint32_t crc = cdvr_crc32c(0, bytes, meta);
    for (int b = 0; b < 4; b++)
        bytes[meta + b] = (uint8_t)(crc >> (8 * b));
    const char *renamed = tmp_path("plug2.cdv");
    write_file(renamed, bytes, n);
    CHECK_OK(cdvr_store_open(renamed, &st, &err), err);
    if (st) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, 1);
        CHECK(vi->codec == NULL && strcmp(vi->codec_name, "zfpx") == 0, "listed, not loaded");
        cdvr_volume *d = NULL;
        CHECK_OK(cdvr_store_decode(st, 0, 1, &d, &err), err);
        cdvr_volume_free(d);
        d = NULL;
        CHECK(cdvr_store_decode(st, 1, 1, &d, &err) == CDVR_ERR_UNSUPPORTED && !d &&
                  strstr(err.msg, "codec 'zfpx'") &&
                  strstr(err.msg, "is not loaded (load its plugin: cdvr.plugin.load)") &&
                  strstr(err.msg, renamed),
              "not loaded: %s", err.msg);
        const cdvr_codec *c;
        CHECK(cdvr_store_variant_codec(st, 1, &c, &err) == CDVR_ERR_UNSUPPORTED, "variant codec");
        cdvr_store_close(st);
    }
    free(bytes);
    cdvr_volume_free(u8);
    unlink(path);
    unlink(renamed);
}

/* Encodes u8 with the variants vs into best.cdv and returns cdvr_store_best_variant (-1 on
 * failure). */
static int best_of(const cdvr_volume *u8, const cdvr_variant_spec *vs, size_t n)
{
    cdvr_encode_opts o = opts_for(vs, n);
    cdvr_error err;
    cdvr_store *st = NULL;
    const char *path = tmp_path("best.cdv");
    int best = -1;
    CHECK_OK(cdvr_store_encode(u8, &o, path, &err), err);
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (st) {
        best = cdvr_store_best_variant(st);
        for (size_t v = 0; v < n && best >= 0; v++) /* nothing ranks above it */
            CHECK(cdvr_store_variant(st, v)->psnr <= cdvr_store_variant(st, (size_t)best)->psnr,
                  "variant %zu psnr %g above the best's %g", v + 1, cdvr_store_variant(st, v)->psnr,
                  cdvr_store_variant(st, (size_t)best)->psnr);
        cdvr_store_close(st);
    }
    unlink(path);
    return best;
}

/* The default variant (cdvr_store_best_variant): raw first, then the highest PSNR, ties by
 * more stored bytes, then the lower index; never simply the first variant. */
static void test_best_variant(void)
{
    cdvr_volume *u8 = make_series(16, 12, 12, 6);
    cdvr_variant_spec lossy_first[] = {
        spec("S4T3", PVTC, 4, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE),
        spec("raw", RAW, 0, 0, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE),
        spec("S1T3", PVTC, 1, 3, CDVR_PACK_TIME, CDVR_ENCODER_LSQ, CDVR_STAGE2_NONE)};
    CHECK(best_of(u8, lossy_first, 3) == 1, "raw is the best");
    CHECK(best_of(u8, lossy_first, 1) == 0, "one variant: it");
    cdvr_variant_spec by_psnr[] = {lossy_first[0], lossy_first[2]};
    CHECK(best_of(u8, by_psnr, 2) == 1, "S1T3 measures a higher PSNR than S4T3 here");
    cdvr_variant_spec twins[] = {lossy_first[0], lossy_first[0]};
    snprintf(twins[1].name, sizeof twins[1].name, "again");
    CHECK(best_of(u8, twins, 2) == 0, "equal quality and bytes: the lower index");
    cdvr_volume_free(u8);
    /* a constant series: every PVTC variant is lossless (psnr +inf), so bytes decide */
    u8 = make_series(16, 12, 12, 6);
    memset(u8->data, 77, cdvr_volume_voxels(u8) * u8->timesteps);
    CHECK(best_of(u8, by_psnr, 2) == 1, "lossless tie: more stored bytes (S1T3)");
    cdvr_variant_spec small_last[] = {lossy_first[2], lossy_first[0]};
    CHECK(best_of(u8, small_last, 2) == 0, "lossless tie, other order: S1T3 still");
    cdvr_volume_free(u8);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/cdvr_test_store_XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_hard_case_round_trips();
    test_schedule();
    test_stage2_decisions();
    test_bad_requests();
    test_failed_writes();
    test_corruption();
    test_forged_metadata();
    test_version1();
    test_bricks();
    test_codec_not_loaded();
    test_best_variant();
    const char *left[] = {"hard.cdv", "s2.cdv", "sched.cdv"};
    for (size_t i = 0; i < sizeof left / sizeof *left; i++)
        unlink(tmp_path(left[i]));
    CHECK(rmdir(tmpdir) == 0, "%s: files left behind", tmpdir);
    return check_finish();
}
