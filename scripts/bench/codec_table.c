/* scripts/bench/codec_table.c - every codec through the codec table (cdvr/codec.h) on real
 * data, in one run: bits per voxel, volume PSNR, max error, encode and decode MB/s (single
 * thread, medians of REPS), and the decode time against two baselines timed in the same
 * repetitions: memcpy of the same output and PVTC S4T3 (time packing where the data has
 * timesteps, space packing otherwise; time-packed variants are left out for a single volume).
 * Ratios are medians of per-repetition ratios. Built and run by scripts/bench/codec_table.sh.
 *
 *   codec_table PLUGIN_DIR DATA_DIR [REPS]
 *
 * Data: ct/engine_256x256x128_u8.nrrd (one volume, u8 as stored) and viscous fingers
 * timesteps 69..71 (64^3 f32), quantised together to u8 over [0, their max] (three
 * timesteps so that PVTC's time packing has a real group; zfp and space packing code each
 * timestep alone). CSV on stdout; progress on stderr when it is a terminal.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "cdvr/codec.h"
#include "cdvr/plugin.h"
#include "cdvr/timing.h"
#include "cdvr/volume.h"

typedef struct bench_variant {
    const char *codec;
    const char *keys[2], *values[2];
    size_t nkeys;
} bench_variant;

static const bench_variant VARIANTS[] = {
    {"raw", {NULL}, {NULL}, 0},
    {"pvtc", {"S", "pack"}, {"4", "time"}, 2},   {"pvtc", {"S", "pack"}, {"1", "time"}, 2},
    {"pvtc", {"S", "pack"}, {"4", "space"}, 2},  {"pvtc", {"S", "pack"}, {"1", "space"}, 2},
    {"zfp", {"rate"}, {"0.5"}, 1},               {"zfp", {"rate"}, {"1"}, 1},
    {"zfp", {"rate"}, {"2"}, 1},                 {"zfp", {"rate"}, {"4"}, 1},
};
#define NVARIANTS (sizeof VARIANTS / sizeof VARIANTS[0])

static void progress(const char *fmt, const char *a, const char *b)
{
    if (isatty(STDERR_FILENO))
        fprintf(stderr, fmt, a, b);
}

/* The encoded series: chunk c covers timesteps c*T .. (c+1)*T-1 (the last repeats its last
 * real timestep). */
typedef struct encoded {
    cdvr_codec_shape shape;
    size_t nchunks;
    uint8_t **payload;
    size_t *bytes, total_bytes;
} encoded;

static void encoded_free(encoded *e)
{
    for (size_t c = 0; e->payload && c < e->nchunks; c++)
        free(e->payload[c]);
    free(e->payload);
    free(e->bytes);
}

static int encode_all(const cdvr_codec *codec, const cdvr_codec_params *p, const cdvr_volume *vol,
                      encoded *e, double *seconds)
{
    cdvr_error err;
    if (cdvr_codec_shape_of(codec, p, vol->dims, &e->shape, &err) != CDVR_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 0;
    }
    size_t T = e->shape.timesteps, nt = vol->timesteps;
    e->nchunks = (nt + T - 1) / T;
    e->payload = calloc(e->nchunks, sizeof *e->payload);
    e->bytes = calloc(e->nchunks, sizeof *e->bytes);
    e->total_bytes = 0;
    if (!e->payload || !e->bytes || T > 4)
        return 0;
    double t0 = cdvr_now_ms() * 1e-3;
    for (size_t c = 0; c < e->nchunks; c++) {
        const uint8_t *frames[4];
        size_t count = nt - c * T < T ? nt - c * T : T;
        for (size_t k = 0; k < T; k++)
            frames[k] = cdvr_volume_frame(vol, c * T + (k < count ? k : count - 1));
        if (!(e->payload[c] = malloc(e->shape.bound_bytes)) ||
            codec->encode(p, vol->dims, frames, count, e->payload[c], e->shape.bound_bytes,
                          &e->bytes[c], &err) != CDVR_OK) {
            fprintf(stderr, "encode: %s\n", err.msg);
            return 0;
        }
        e->total_bytes += e->bytes[c];
    }
    *seconds = cdvr_now_ms() * 1e-3 - t0;
    return 1;
}

static int decode_all(const cdvr_codec *codec, const cdvr_codec_params *p, const cdvr_volume *vol,
                      const encoded *e, cdvr_volume *out)
{
    size_t T = e->shape.timesteps, nt = vol->timesteps;
    for (size_t c = 0; c < e->nchunks; c++) {
        uint8_t *frames[4];
        size_t count = nt - c * T < T ? nt - c * T : T;
        for (size_t k = 0; k < count; k++)
            frames[k] = cdvr_volume_frame(out, c * T + k);
        cdvr_error err;
        if (codec->decode(p, vol->dims, e->payload[c], e->bytes[c], frames, count, &err) !=
            CDVR_OK) {
            fprintf(stderr, "decode: %s\n", err.msg);
            return 0;
        }
    }
    return 1;
}

static void error_of(const cdvr_volume *a, const cdvr_volume *b, double *psnr, int *max_err)
{
    size_t n = cdvr_volume_voxels(a) * a->timesteps;
    const uint8_t *x = a->data, *y = b->data;
    double sse = 0;
    *max_err = 0;
    for (size_t i = 0; i < n; i++) {
        int d = abs((int)x[i] - (int)y[i]);
        sse += (double)d * d;
        if (d > *max_err)
            *max_err = d;
    }
    *psnr = sse == 0 ? INFINITY : 10 * log10(255.0 * 255.0 / (sse / (double)n));
}

/* Seconds of one whole-series decode, or of memcpy of the same bytes (codec NULL). */
static double time_once(const cdvr_codec *codec, const cdvr_codec_params *p,
                        const cdvr_volume *vol, const encoded *e, cdvr_volume *out)
{
    double t0 = cdvr_now_ms() * 1e-3;
    if (codec)
        decode_all(codec, p, vol, e, out);
    else
        memcpy(out->data, vol->data, cdvr_volume_voxels(vol) * vol->timesteps);
    return cdvr_now_ms() * 1e-3 - t0;
}

/* One variant, encoded and checked once, then timed. */
typedef struct bench_row {
    const bench_variant *bv;
    const cdvr_codec *codec;
    cdvr_codec_params params;
    encoded enc;
    char variant[CDVR_VARIANT_NAME_MAX];
    double bpv, psnr, encode_s;
    int max_err;
} bench_row;

/* Encodes (median of 3 runs), decodes once for the error; 0 when the codec is missing or
 * fails. */
static int prepare(const bench_variant *bv, const cdvr_volume *vol, cdvr_volume *out,
                   bench_row *row)
{
    cdvr_error err;
    row->bv = bv;
    row->codec = cdvr_codec_find(bv->codec);
    if (!row->codec) {
        fprintf(stderr, "codec %s not loaded, skipped\n", bv->codec);
        return 0;
    }
    if (cdvr_codec_params_parse(row->codec, bv->keys, bv->values, bv->nkeys, &row->params,
                                &err) != CDVR_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 0;
    }
    row->codec->variant_name(&row->params, row->variant, sizeof row->variant);
    progress("%s %s\n", "codec_table: encode", row->variant);
    double enc[3];
    int ok = 1;
    for (int r = 0; ok && r < 3; r++) {
        encoded_free(&row->enc);
        memset(&row->enc, 0, sizeof row->enc);
        ok = encode_all(row->codec, &row->params, vol, &row->enc, &enc[r]);
    }
    if (!ok || !decode_all(row->codec, &row->params, vol, &row->enc, out))
        return 0;
    error_of(vol, out, &row->psnr, &row->max_err);
    row->encode_s = cdvr_median(enc, 3);
    row->bpv = 8.0 * (double)row->enc.total_bytes /
               (double)(cdvr_volume_voxels(vol) * vol->timesteps);
    return 1;
}

/* Decode timing paired with the baselines: each repetition decodes the variant, the PVTC
 * S4T3 baseline and memcpy back to back, so that load from other processes hits all three
 * alike; the ratios are medians of the per-repetition ratios. */
static void time_row(const bench_row *row, const bench_row *base, const cdvr_volume *vol,
                     cdvr_volume *out, int reps, const char *name)
{
    double t[64], vs_base[64], vs_mem[64];
    for (int r = 0; r < reps; r++) {
        double tb = base ? time_once(base->codec, &base->params, vol, &base->enc, out) : 0;
        t[r] = time_once(row->codec, &row->params, vol, &row->enc, out);
        double tm = time_once(NULL, NULL, vol, NULL, out);
        vs_base[r] = base ? t[r] / tb : NAN;
        vs_mem[r] = t[r] / tm;
    }
    double dec = cdvr_median(t, (size_t)reps), mb = (double)(cdvr_volume_voxels(vol) * vol->timesteps) / 1e6;
    printf("%s,%s,%zu,%.4f,%.2f,%d,%.1f,%.1f,%.3f,%.3f,%.2f,%.2f\n", name, row->variant,
           row->enc.shape.timesteps, row->bpv, row->psnr, row->max_err, mb / row->encode_s,
           mb / dec, 1e3 * dec / (double)row->enc.nchunks, 1e3 * dec / (double)vol->timesteps,
           cdvr_median(vs_mem, (size_t)reps), base ? cdvr_median(vs_base, (size_t)reps) : NAN);
}

static void run_dataset(const char *name, const cdvr_volume *vol, int reps)
{
    cdvr_volume *out = NULL;
    cdvr_error err;
    if (cdvr_volume_create(vol->dims, vol->timesteps, CDVR_TYPE_U8, &out, &err) != CDVR_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return;
    }
    /* The PVTC S4T3 baseline: time packing when there is a group of timesteps. */
    const char *base_pack = vol->timesteps >= 3 ? "time" : "space";
    bench_row rows[NVARIANTS];
    memset(rows, 0, sizeof rows);
    size_t nrows = 0;
    const bench_row *base = NULL;
    for (size_t v = 0; v < NVARIANTS; v++) {
        const bench_variant *bv = &VARIANTS[v];
        if (strcmp(bv->codec, "pvtc") == 0 && strcmp(bv->values[1], "time") == 0 &&
            vol->timesteps < 3)
            continue; /* time packing of one volume would code three copies of it */
        if (!prepare(bv, vol, out, &rows[nrows])) {
            encoded_free(&rows[nrows].enc);
            memset(&rows[nrows], 0, sizeof rows[nrows]);
            continue;
        }
        if (strcmp(bv->codec, "pvtc") == 0 && strcmp(bv->values[0], "4") == 0 &&
            strcmp(bv->values[1], base_pack) == 0)
            base = &rows[nrows];
        nrows++;
    }
    for (size_t r = 0; r < nrows; r++) {
        progress("%s %s\n", "codec_table: decode", rows[r].variant);
        time_row(&rows[r], base, vol, out, reps, name);
    }
    for (size_t r = 0; r < nrows; r++)
        encoded_free(&rows[r].enc);
    cdvr_volume_free(out);
}

static cdvr_volume *load_vf(const char *data)
{
    char paths[3][1024];
    const char *ptrs[3];
    for (int i = 0; i < 3; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/series/viscousfingers/vf_t%03d.nrrd", data, 69 + i);
        ptrs[i] = paths[i];
    }
    cdvr_volume *vf = NULL, *q = NULL;
    cdvr_error err;
    double lo, hi;
    if (cdvr_volume_load_series(ptrs, 3, NULL, &vf, &err) != CDVR_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return NULL;
    }
    cdvr_volume_range(vf, &lo, &hi);
    if (cdvr_volume_quantize(vf, 0.0, hi, &q, NULL, &err) != CDVR_OK)
        fprintf(stderr, "%s\n", err.msg);
    cdvr_volume_free(vf);
    return q;
}

int main(int argc, char **argv)
{
    if (argc < 3) {
        fprintf(stderr, "usage: codec_table PLUGIN_DIR DATA_DIR [REPS]\n");
        return 2;
    }
    int reps = argc > 3 ? atoi(argv[3]) : 15;
    if (reps < 1 || reps > 64)
        reps = 9;
    cdvr_plugin_load_dirs(argv[1], NULL, NULL);
    char path[1024];
    snprintf(path, sizeof path, "%s/ct/engine_256x256x128_u8.nrrd", argv[2]);
    cdvr_volume *ct = NULL;
    cdvr_error err;
    if (cdvr_volume_load(path, NULL, &ct, &err) != CDVR_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 1;
    }
    if (ct->type != CDVR_TYPE_U8) {
        fprintf(stderr, "%s: expected u8 voxels\n", path);
        return 1;
    }
    cdvr_volume *vf = load_vf(argv[2]);
    printf("data,variant,timesteps_per_chunk,bpv,psnr_db,max_err,encode_MBps,decode_MBps,"
           "decode_ms_per_chunk,decode_ms_per_timestep,decode_vs_memcpy,decode_vs_S4T3\n");
    run_dataset("engine_256x256x128", ct, reps);
    if (vf)
        run_dataset("viscousfingers_t69-71_64^3", vf, reps);
    cdvr_volume_free(ct);
    cdvr_volume_free(vf);
    return vf ? 0 : 1;
}
