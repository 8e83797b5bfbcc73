/* scripts/bench/pvtc_bench.c - PVTC quality and decode speed (built by bc1_compare.sh against
 * BUILD_DIR/libcdvr_core.a, outside the CMake build).
 *
 *   pvtc_bench prep OUTDIR DATADIR   quantise the viscous-fingers series ([0, max over series])
 *                                    and the ASL 4D NIfTI ([min, max]) to raw u8 files
 *   pvtc_bench psnr RAW X Y Z T      bbox and lsq PSNR of every variant, encode seconds
 *   pvtc_bench speed RAW X Y Z T N   S1T3 time decode vs memcpy of the same output, median
 *                                    of N runs, and the ratio
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "cdvr/pvtc.h"
#include "cdvr/volume.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static int write_u8(const char *path, const cdvr_volume *q)
{
    FILE *f = fopen(path, "wb");
    size_t n = cdvr_volume_voxels(q) * q->timesteps;
    int ok = f && fwrite(q->data, 1, n, f) == n;
    if (f)
        ok = (fclose(f) == 0) && ok;
    printf("%s: %zux%zux%zu x %zu u8%s\n", path, q->dims[0], q->dims[1], q->dims[2],
           q->timesteps, ok ? "" : " WRITE FAILED");
    return ok;
}

static int prep(const char *outdir, const char *datadir)
{
    char paths[60][1024], out[1024];
    const char *ptrs[60];
    for (int i = 0; i < 60; i++) {
        snprintf(paths[i], sizeof paths[i], "%s/series/viscousfingers/vf_t%03d.nrrd", datadir,
                 40 + i);
        ptrs[i] = paths[i];
    }
    cdvr_volume *vf = NULL, *asl = NULL, *q = NULL;
    cdvr_error err;
    double lo, hi;
    if (cdvr_volume_load_series(ptrs, 60, NULL, &vf, &err) != CDVR_OK)
        return fprintf(stderr, "%s\n", err.msg), 0;
    cdvr_volume_range(vf, &lo, &hi);
    if (cdvr_volume_quantize(vf, 0.0, hi, &q, NULL, &err) != CDVR_OK)
        return fprintf(stderr, "%s\n", err.msg), 0;
    snprintf(out, sizeof out, "%s/vf_u8_64x64x64x60.raw", outdir);
    int ok = write_u8(out, q);
    cdvr_volume_free(q);
    cdvr_volume_free(vf);
    snprintf(out, sizeof out, "%s/mri/mpld_asl_64x64x24x25_f32.nii.gz", datadir);
    if (cdvr_volume_load(out, NULL, &asl, &err) != CDVR_OK)
        return fprintf(stderr, "%s\n", err.msg), 0;
    cdvr_volume_range(asl, &lo, &hi);
    if (cdvr_volume_quantize(asl, lo, hi, &q, NULL, &err) != CDVR_OK)
        return fprintf(stderr, "%s\n", err.msg), 0;
    snprintf(out, sizeof out, "%s/asl_u8_64x64x24x25.raw", outdir);
    ok = write_u8(out, q) && ok;
    cdvr_volume_free(q);
    cdvr_volume_free(asl);
    return ok;
}

typedef struct series {
    size_t dims[3], T, n;
    uint8_t *data;
} series;

static int load_raw(const char *path, char **argv, series *s)
{
    for (int i = 0; i < 3; i++)
        s->dims[i] = strtoul(argv[i], NULL, 10);
    s->T = strtoul(argv[3], NULL, 10);
    s->n = s->dims[0] * s->dims[1] * s->dims[2];
    s->data = malloc(s->n * s->T);
    FILE *f = fopen(path, "rb");
    int ok = f && s->data && fread(s->data, 1, s->n * s->T, f) == s->n * s->T;
    if (f)
        fclose(f);
    if (!ok)
        fprintf(stderr, "%s: cannot read %zu bytes\n", path, s->n * s->T);
    return ok;
}

/* Encodes and decodes the whole series with one variant; returns MSE, sets encode seconds. */
static double run_variant(const series *s, const cdvr_pvtc_params *p, cdvr_pvtc_encoder enc,
                          double *enc_s)
{
    cdvr_pvtc_geometry g;
    cdvr_error err;
    cdvr_pvtc_geometry_get(p, s->dims, &g, &err);
    uint8_t *chunk = malloc(g.chunk_bytes), *dec = malloc(3 * s->n);
    size_t group = p->pack == CDVR_PACK_TIME ? (size_t)p->T : 1;
    double sse = 0;
    *enc_s = 0;
    for (size_t t0 = 0; t0 < s->T; t0 += group) {
        size_t nf = s->T - t0 < group ? s->T - t0 : group;
        const uint8_t *in[3];
        uint8_t *out[3];
        for (size_t c = 0; c < 3; c++) {
            in[c] = s->data + s->n * (t0 + (c < nf ? c : nf - 1));
            out[c] = dec + s->n * c;
        }
        double t = now_s();
        if (cdvr_pvtc_encode_chunk(p, enc, s->dims, in, chunk, &err) != CDVR_OK)
            return fprintf(stderr, "%s\n", err.msg), -1;
        *enc_s += now_s() - t;
        if (cdvr_pvtc_decode_chunk(p, s->dims, chunk, g.chunk_bytes, out, nf, &err) != CDVR_OK)
            return fprintf(stderr, "%s\n", err.msg), -1;
        for (size_t c = 0; c < nf; c++)
            for (size_t i = 0; i < s->n; i++) {
                double d = (double)in[c][i] - dec[s->n * c + i];
                sse += d * d;
            }
    }
    free(chunk);
    free(dec);
    return sse / ((double)s->n * s->T);
}

static double psnr(double mse)
{
    return mse > 0 ? 10 * log10(255.0 * 255.0 / mse) : INFINITY;
}

static int report_psnr(const series *s)
{
    const cdvr_pvtc_params v[8] = {{1, 3, CDVR_PACK_TIME}, {4, 3, CDVR_PACK_TIME},
                                   {1, 2, CDVR_PACK_TIME}, {4, 2, CDVR_PACK_TIME},
                                   {1, 3, CDVR_PACK_SPACE}, {4, 3, CDVR_PACK_SPACE},
                                   {1, 2, CDVR_PACK_SPACE}, {4, 2, CDVR_PACK_SPACE}};
    printf("variant,bpv,psnr_bbox,psnr_lsq,gain_db,encode_s_bbox,encode_s_lsq\n");
    for (int i = 0; i < 8; i++) {
        double sb, sl, mb = run_variant(s, &v[i], CDVR_ENCODER_BBOX, &sb);
        double ml = run_variant(s, &v[i], CDVR_ENCODER_LSQ, &sl);
        if (mb < 0 || ml < 0)
            return 0;
        printf("S%dT%d%s,%.3f,%.2f,%.2f,%.2f,%.2f,%.2f\n", v[i].S, v[i].T,
               v[i].pack ? "space" : "time", 8.0 * (4 + 4 * v[i].S) / (16.0 * v[i].S * v[i].T),
               psnr(mb), psnr(ml), 10 * log10(mb / ml), sb, sl);
    }
    return 1;
}

static int report_speed(const series *s, int runs)
{
    cdvr_pvtc_params p = {1, 3, CDVR_PACK_TIME};
    cdvr_pvtc_geometry g;
    cdvr_error err;
    cdvr_pvtc_geometry_get(&p, s->dims, &g, &err);
    uint8_t *chunk = malloc(g.chunk_bytes), *dec = malloc(3 * s->n), *copy = malloc(3 * s->n);
    const uint8_t *in[3] = {s->data, s->data + s->n, s->data + 2 * s->n};
    uint8_t *out[3] = {dec, dec + s->n, dec + 2 * s->n};
    cdvr_pvtc_encode_chunk(&p, CDVR_ENCODER_LSQ, s->dims, in, chunk, &err);
    double *td = malloc(sizeof(double) * runs), *tm = malloc(sizeof(double) * runs);
    const int reps = 20;
    for (int r = 0; r < runs; r++) {
        double t = now_s();
        for (int k = 0; k < reps; k++)
            cdvr_pvtc_decode_chunk(&p, s->dims, chunk, g.chunk_bytes, out, 3, &err);
        td[r] = (now_s() - t) / reps;
        t = now_s();
        for (int k = 0; k < reps; k++) {
            memcpy(copy, s->data + (k & 1), 3 * s->n - 1); /* varying source defeats elision */
            __asm__ volatile("" ::"r"(copy) : "memory");
        }
        tm[r] = (now_s() - t) / reps;
    }
    qsort(td, runs, sizeof *td, cmp_double);
    qsort(tm, runs, sizeof *tm, cmp_double);
    double bytes = 3.0 * s->n, d = td[runs / 2], m = tm[runs / 2];
    printf("S1T3 time decode: %.3f ms/chunk = %.2f GB/s out; memcpy %.3f ms = %.2f GB/s; "
           "ratio %.2f (median of %d)\n", d * 1e3, bytes / d / 1e9, m * 1e3, bytes / m / 1e9,
           m / d, runs);
    /* whole series (output far larger than the caches): all chunks vs one memcpy */
    size_t nchunks = s->T / 3, total = 3 * s->n * nchunks;
    uint8_t *chunks = malloc(g.chunk_bytes * nchunks), *big = malloc(total), *big2 = malloc(total);
    for (size_t k = 0; k < nchunks; k++) {
        const uint8_t *fin[3] = {s->data + s->n * 3 * k, s->data + s->n * (3 * k + 1),
                                 s->data + s->n * (3 * k + 2)};
        cdvr_pvtc_encode_chunk(&p, CDVR_ENCODER_BBOX, s->dims, fin, chunks + k * g.chunk_bytes,
                               &err);
    }
    memset(big, 1, total);
    memset(big2, 2, total);
    for (int r = 0; r < runs; r++) {
        double t = now_s();
        for (size_t k = 0; k < nchunks; k++) {
            uint8_t *o[3] = {big + s->n * 3 * k, big + s->n * (3 * k + 1),
                             big + s->n * (3 * k + 2)};
            cdvr_pvtc_decode_chunk(&p, s->dims, chunks + k * g.chunk_bytes, g.chunk_bytes, o, 3,
                                   &err);
        }
        td[r] = now_s() - t;
        t = now_s();
        memcpy(big2, s->data + (r & 1), total - 1);
        __asm__ volatile("" ::"r"(big2) : "memory");
        tm[r] = now_s() - t;
    }
    qsort(td, runs, sizeof *td, cmp_double);
    qsort(tm, runs, sizeof *tm, cmp_double);
    d = td[runs / 2];
    m = tm[runs / 2];
    printf("S1T3 time decode, %zu chunks (%.1f MB out): %.2f GB/s; memcpy %.2f GB/s; ratio %.2f "
           "(median of %d)\n", nchunks, total / 1e6, total / d / 1e9, total / m / 1e9, m / d,
           runs);
    free(chunks);
    free(big);
    free(big2);
    free(chunk);
    free(dec);
    free(copy);
    free(td);
    free(tm);
    return 1;
}

int main(int argc, char **argv)
{
    if (argc == 4 && !strcmp(argv[1], "prep"))
        return prep(argv[2], argv[3]) ? 0 : 1;
    series s;
    if (argc == 7 && !strcmp(argv[1], "psnr"))
        return load_raw(argv[2], argv + 3, &s) && report_psnr(&s) ? 0 : 1;
    if (argc == 8 && !strcmp(argv[1], "speed"))
        return load_raw(argv[2], argv + 3, &s) && report_speed(&s, atoi(argv[7])) ? 0 : 1;
    fprintf(stderr, "usage: pvtc_bench prep OUTDIR DATADIR | psnr RAW X Y Z T | "
                    "speed RAW X Y Z T RUNS\n");
    return 2;
}
