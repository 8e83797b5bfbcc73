/* scripts/bench/hvq_bench.c - hvq against PVTC (and any codec loaded from CDVR_PLUGIN_PATH,
 * e.g. zfp) through the codec table, on real volumes. Built and run by hvq_bench.sh (outside
 * the CMake build, against BUILD_DIR/libcdvr_core.a). CSV on stdout, progress on stderr when
 * it is a terminal.
 *
 *   hvq_bench compare DATADIR [RUNS]
 *       Colin27, the engine CT and Colin27 thresholded so that ~85% of voxels are 0, each
 *       with hvq (defaults), hvq as the seed ran it (grad=64 residual=10), PVTC S4T3s and
 *       S1T3s, zfp (when its plugin is loaded) at hvq's bits per voxel rounded to zfp's 1/64
 *       step (the nearest ratio), and every other plugin codec at its defaults: ratio, bits per voxel, volume PSNR,
 *       max error, encode and decode seconds (medians of RUNS, default 3) with memcpy of the
 *       frame as the decode baseline, hvq's zero blocks, residual voxels and part sizes.
 *   hvq_bench sweep FILE LABEL KEY=V1,V2,.. [KEY=..]
 *       hvq over the cartesian product of the given parameter values (1 run each).
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

static void progress(const char *fmt, const char *a, const char *b)
{
    if (isatty(2)) {
        fprintf(stderr, fmt, a, b);
        fflush(stderr);
    }
}

typedef struct dataset {
    const char *name;
    size_t dims[3];
    uint8_t *data;
} dataset;

/* Sums of describe's figures over one payload. */
typedef struct figures {
    double v[16];
    const char *k[16];
    int n;
} figures;

static void figures_emit(void *ud, const char *key, double value)
{
    figures *f = ud;
    if (f->n < 16) {
        f->k[f->n] = key;
        f->v[f->n++] = value;
    }
}

static double figure(const figures *f, const char *key)
{
    for (int i = 0; i < f->n; i++)
        if (strcmp(f->k[i], key) == 0)
            return f->v[i];
    return NAN;
}

static void print_header(void)
{
    printf("dataset,variant,codec,params,voxels,bytes,ratio,bpv,psnr_db,maxerr,encode_s,"
           "decode_s,memcpy_s,decode_over_memcpy,deterministic,zero_blocks,blocks,"
           "residual_voxels,means,codebook1,codebook2,index_hash,residual_hash\n");
}

/* Encodes ds with codec(params) `runs` times, decodes `runs` times, prints one CSV row.
 * Returns the bits per voxel, NAN on failure. */
static double run_variant(const dataset *ds, const char *codec_name, const char *const *keys,
                       const char *const *values, size_t nparams, int runs)
{
    const cdvr_codec *codec = cdvr_codec_find(codec_name);
    if (!codec) {
        fprintf(stderr, "codec %s is not loaded\n", codec_name);
        return NAN;
    }
    cdvr_codec_params blob;
    cdvr_codec_shape shape;
    cdvr_error err;
    if (cdvr_codec_params_parse(codec, keys, values, nparams, &blob, &err) != CDVR_OK ||
        cdvr_codec_shape_of(codec, &blob, ds->dims, &shape, &err) != CDVR_OK) {
        fprintf(stderr, "%s on %s: %s\n", codec_name, ds->name, err.msg);
        return NAN;
    }
    char variant[CDVR_VARIANT_NAME_MAX], ptext[256] = "";
    codec->variant_name(&blob, variant, sizeof variant);
    for (const cdvr_codec_param_doc *d = codec->params; d && d->key; d++) {
        char v[64];
        if (codec->params_get(&blob, d->key, v, sizeof v) == 0)
            snprintf(ptext + strlen(ptext), sizeof ptext - strlen(ptext), "%s%s=%s",
                     ptext[0] ? " " : "", d->key, v);
    }
    size_t n = ds->dims[0] * ds->dims[1] * ds->dims[2];
    const uint8_t **frames = malloc(shape.timesteps * sizeof *frames);
    uint8_t *payload = malloc(shape.bound_bytes), *first = NULL, *out = malloc(n);
    uint8_t *copy = malloc(n);
    for (size_t t = 0; t < shape.timesteps; t++)
        frames[t] = ds->data;
    double enc[16], dec[16], cpy[16];
    size_t bytes = 0, first_bytes = 0;
    int deterministic = 1;
    runs = runs < 1 ? 1 : runs > 16 ? 16 : runs;
    for (int r = 0; r < runs; r++) {
        progress("%s %s: encoding\n", ds->name, variant);
        double t0 = cdvr_now_ms() * 1e-3;
        if (codec->encode(&blob, ds->dims, frames, 1, payload, shape.bound_bytes, &bytes,
                          &err) != CDVR_OK) {
            fprintf(stderr, "%s on %s: %s\n", variant, ds->name, err.msg);
            return NAN;
        }
        enc[r] = cdvr_now_ms() * 1e-3 - t0;
        if (r == 0) {
            first = malloc(bytes);
            memcpy(first, payload, bytes);
            first_bytes = bytes;
        } else {
            deterministic &= bytes == first_bytes && memcmp(first, payload, bytes) == 0;
        }
    }
    uint8_t *outs[1] = {out};
    for (int r = 0; r < runs; r++) {
        double t0 = cdvr_now_ms() * 1e-3;
        if (codec->decode(&blob, ds->dims, payload, bytes, outs, 1, &err) != CDVR_OK) {
            fprintf(stderr, "%s on %s: decode: %s\n", variant, ds->name, err.msg);
            return NAN;
        }
        dec[r] = cdvr_now_ms() * 1e-3 - t0;
        t0 = cdvr_now_ms() * 1e-3;
        memcpy(copy, ds->data, n);
        cpy[r] = cdvr_now_ms() * 1e-3 - t0;
        deterministic &= copy[r % n] == ds->data[r % n]; /* keeps the copy */
    }
    double sse = 0;
    int maxerr = 0;
    for (size_t i = 0; i < n; i++) {
        int e = abs((int)out[i] - (int)ds->data[i]);
        sse += (double)e * e;
        maxerr = e > maxerr ? e : maxerr;
    }
    double psnr = sse > 0 ? 10 * log10(255.0 * 255.0 * (double)n / sse) : INFINITY;
    figures f = {.n = 0};
    if (codec->describe)
        codec->describe(&blob, ds->dims, payload, bytes, figures_emit, &f, &err);
    double dmed = cdvr_median(dec, (size_t)runs), cmed = cdvr_median(cpy, (size_t)runs);
    printf("%s,%s,%s,%s,%zu,%zu,%.3f,%.4f,%.3f,%d,%.3f,%.4f,%.5f,%.1f,%s,%.0f,%.0f,%.0f,%.0f,"
           "%.0f,%.0f,%.0f,%.0f\n",
           ds->name, variant, codec_name, ptext, n, bytes, (double)n / bytes, 8.0 * bytes / n,
           psnr, maxerr, cdvr_median(enc, (size_t)runs), dmed, cmed, dmed / cmed,
           runs > 1 ? (deterministic ? "yes" : "NO") : "-", figure(&f, "zero_blocks"),
           figure(&f, "blocks"), figure(&f, "residual_voxels"), figure(&f, "means"),
           figure(&f, "codebook1"), figure(&f, "codebook2"), figure(&f, "index_hash"),
           figure(&f, "residual_hash"));
    fflush(stdout);
    free(frames);
    free(payload);
    free(first);
    free(out);
    free(copy);
    return 8.0 * bytes / n;
}

static int load_u8(const char *path, const char *name, dataset *ds)
{
    cdvr_volume *vol;
    cdvr_error err;
    if (cdvr_volume_load(path, NULL, &vol, &err) != CDVR_OK) {
        fprintf(stderr, "%s\n", err.msg);
        return 0;
    }
    if (vol->type != CDVR_TYPE_U8 || vol->timesteps != 1) {
        fprintf(stderr, "%s: not one u8 volume\n", path);
        cdvr_volume_free(vol);
        return 0;
    }
    ds->name = name;
    memcpy(ds->dims, vol->dims, sizeof ds->dims);
    size_t n = vol->dims[0] * vol->dims[1] * vol->dims[2];
    ds->data = malloc(n);
    memcpy(ds->data, vol->data, n);
    cdvr_volume_free(vol);
    return 1;
}

/* Copy of src with every voxel below the value at which `zero_fraction` of voxels lie set to
 * 0 (the seed's sparse light-sheet data). Prints the threshold and the fraction reached. */
static void make_sparse(const dataset *src, double zero_fraction, dataset *out)
{
    size_t n = src->dims[0] * src->dims[1] * src->dims[2], hist[256] = {0}, below = 0;
    for (size_t i = 0; i < n; i++)
        hist[src->data[i]]++;
    int t = 0; /* the threshold whose fraction of voxels below it is nearest */
    double best = INFINITY;
    for (int v = 0; v <= 256; v++) {
        double miss = fabs((double)below / (double)n - zero_fraction);
        if (miss < best) {
            best = miss;
            t = v;
        }
        if (v < 256)
            below += hist[v];
    }
    *out = *src;
    out->name = "colin27_sparse85";
    out->data = malloc(n);
    size_t zeros = 0;
    for (size_t i = 0; i < n; i++) {
        out->data[i] = src->data[i] < t ? 0 : src->data[i];
        zeros += out->data[i] == 0;
    }
    fprintf(stderr, "colin27_sparse85: voxels below %d set to 0: %.1f%% zeros\n", t,
            100.0 * zeros / n);
}

static void report_plugin(void *ud, const char *message)
{
    (void)ud;
    fprintf(stderr, "plugin: %s\n", message);
}

static int compare(const char *datadir, int runs)
{
    char path[1024];
    dataset sets[3];
    snprintf(path, sizeof path, "%s/mri/colin27_t1_301x370x316_u8.nii.gz", datadir);
    if (!load_u8(path, "colin27", &sets[0]))
        return 1;
    snprintf(path, sizeof path, "%s/ct/engine_256x256x128_u8.nrrd", datadir);
    if (!load_u8(path, "engine", &sets[1]))
        return 1;
    make_sparse(&sets[0], 0.85, &sets[2]);
    const char *plugins = getenv("CDVR_PLUGIN_PATH");
    if (plugins && *plugins)
        cdvr_plugin_load_dirs(plugins, report_plugin, NULL);
    static const char *seed_k[] = {"grad", "residual"}, *seed_v[] = {"64", "10"};
    static const char *pv_k[] = {"S", "T", "pack"}, *s4_v[] = {"4", "3", "space"},
                      *s1_v[] = {"1", "3", "space"};
    print_header();
    for (int s = 0; s < 3; s++) {
        double bpv = run_variant(&sets[s], "hvq", NULL, NULL, 0, runs);
        run_variant(&sets[s], "hvq", seed_k, seed_v, 2, runs);
        run_variant(&sets[s], "pvtc", pv_k, s4_v, 3, runs);
        run_variant(&sets[s], "pvtc", pv_k, s1_v, 3, runs);
        for (size_t i = 0; i < cdvr_codec_count(); i++) {
            const cdvr_codec *c = cdvr_codec_at(i);
            if (strcmp(c->name, "zfp") == 0 && bpv == bpv) {
                char rate[32];
                const char *zk[] = {"rate"}, *zv[] = {rate};
                snprintf(rate, sizeof rate, "%.6g", fmax(1.0, round(bpv * 64)) / 64);
                run_variant(&sets[s], "zfp", zk, zv, 1, runs);
            } else if (strcmp(c->name, "raw") && strcmp(c->name, "pvtc") && strcmp(c->name, "hvq")) {
                run_variant(&sets[s], c->name, NULL, NULL, 0, runs);
            }
        }
    }
    for (int s = 0; s < 3; s++)
        free(sets[s].data);
    return 0;
}

/* sweep: KEY=V1,V2,... lists, cartesian product, last key fastest. */
static int sweep(const char *file, const char *label, int nlists, char **lists)
{
    dataset ds;
    if (!load_u8(file, label, &ds))
        return 1;
    enum { MAXL = 8, MAXV = 16 };
    char *keys[MAXL], *vals[MAXL][MAXV];
    int nv[MAXL], idx[MAXL] = {0};
    if (nlists > MAXL)
        nlists = MAXL;
    for (int l = 0; l < nlists; l++) {
        char *eq = strchr(lists[l], '=');
        if (!eq) {
            fprintf(stderr, "sweep: '%s' is not KEY=V1,V2,..\n", lists[l]);
            return 1;
        }
        *eq = 0;
        keys[l] = lists[l];
        nv[l] = 0;
        for (char *v = strtok(eq + 1, ","); v && nv[l] < MAXV; v = strtok(NULL, ","))
            vals[l][nv[l]++] = v;
    }
    print_header();
    for (;;) {
        const char *k[MAXL], *v[MAXL];
        for (int l = 0; l < nlists; l++) {
            k[l] = keys[l];
            v[l] = vals[l][idx[l]];
        }
        run_variant(&ds, "hvq", k, v, (size_t)nlists, 1);
        int l = nlists - 1;
        while (l >= 0 && ++idx[l] == nv[l])
            idx[l--] = 0;
        if (l < 0)
            break;
    }
    free(ds.data);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc >= 3 && strcmp(argv[1], "compare") == 0)
        return compare(argv[2], argc > 3 ? atoi(argv[3]) : 3);
    if (argc >= 4 && strcmp(argv[1], "sweep") == 0)
        return sweep(argv[2], argv[3], argc - 4, argv + 4);
    fprintf(stderr, "usage: hvq_bench compare DATADIR [RUNS]\n"
                    "       hvq_bench sweep FILE LABEL KEY=V1,V2,.. [KEY=..]\n");
    return 2;
}
