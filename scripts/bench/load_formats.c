/* scripts/bench/load_formats.c - load and probe speed of every exchange format cdvr writes
 * (issue 23's benchmark; run it with scripts/bench/load_formats.sh, which builds it against
 * BUILD_DIR/libcdvr_core.a).
 *
 *   load_formats DIR [N] [REPS]      N: edge of the volume (default 256), REPS (default 5)
 *
 * A deterministic N^3 u16 volume with CT-like structure (air outside an elliptic body, soft
 * tissue with slow variation, bone spheres, a hash noise of +-12 so compression is realistic,
 * not a constant) is saved through cdvr_volume_save as NRRD raw and gzip, NIfTI (.nii, .nii.gz),
 * VTI raw appended and zlib, MetaImage raw and zlib (.mha), and with libtiff as a multi-page
 * TIFF (one page per z slice, uncompressed and Adobe deflate). Each is loaded once and checked
 * voxel for voxel against the source. Then REPS rounds, each visiting the formats in an order
 * rotated by one per round, time cdvr_volume_load (whole volume into memory) and
 * cdvr_volume_probe (header only; the median of 21 calls per visit) of each file. The files are
 * in the page cache (just written): this measures decoding, not the disk.
 * Output (stdout, a table): format, file MB, median load ms, file MB/s (file size / load
 * time), voxel MB/s (volume bytes / load time), load time relative to NRRD raw, median probe
 * us; then the 1-minute load average before and after. Progress on stderr when it is a
 * terminal. Files are written into DIR and removed at the end. */
#define _POSIX_C_SOURCE 200809L
#include "cdvr/volume.h"
#include "cdvr/write.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <time.h>
#include <unistd.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double median(double *v, int n)
{
    for (int i = 1; i < n; i++)
        for (int j = i; j > 0 && v[j - 1] > v[j]; j--) {
            double t = v[j];
            v[j] = v[j - 1];
            v[j - 1] = t;
        }
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static double loadavg(void)
{
    double l = NAN;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (fscanf(f, "%lf", &l) != 1)
            l = NAN;
        fclose(f);
    }
    return l;
}

static uint32_t hash3(uint32_t x, uint32_t y, uint32_t z)
{
    uint32_t h = x * 73856093u ^ y * 19349663u ^ z * 83492791u;
    h ^= h >> 13;
    h *= 0x5bd1e995u;
    h ^= h >> 15;
    return h;
}

static cdvr_volume *make_volume(size_t n)
{
    size_t dims[3] = {n, n, n};
    cdvr_volume *v;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U16, &v, &err) != CDVR_OK) {
        fprintf(stderr, "load_formats: %s\n", err.msg);
        return NULL;
    }
    uint16_t *p = v->data;
    double c = 0.5 * (double)(n - 1);
    const double bones[4][4] = {{0.3, 0.4, 0.5, 0.12}, {0.7, 0.45, 0.4, 0.1},
                                {0.5, 0.7, 0.6, 0.08}, {0.45, 0.3, 0.3, 0.06}};
    for (size_t z = 0; z < n; z++)
        for (size_t y = 0; y < n; y++)
            for (size_t x = 0; x < n; x++) {
                double fx = (double)x / (double)n, fy = (double)y / (double)n,
                       fz = (double)z / (double)n;
                double ex = ((double)x - c) / (0.45 * (double)n),
                       ey = ((double)y - c) / (0.35 * (double)n);
                double val = 0;
                if (ex * ex + ey * ey < 1.0) {
                    val = 1000 + 80 * sin(6.0 * fx) * cos(5.0 * fy) + 40 * sin(9.0 * fz);
                    for (int b = 0; b < 4; b++) {
                        double dx = fx - bones[b][0], dy = fy - bones[b][1], dz = fz - bones[b][2];
                        if (dx * dx + dy * dy + dz * dz < bones[b][3] * bones[b][3])
                            val = 2200 + 400 * b;
                    }
                    val += (double)(hash3((uint32_t)x, (uint32_t)y, (uint32_t)z) % 25) - 12;
                }
                p[x + n * (y + n * z)] = (uint16_t)val;
            }
    v->spacing[0] = v->spacing[1] = 0.7;
    v->spacing[2] = 1.25;
    v->origin[0] = -90;
    v->origin[1] = -90;
    v->origin[2] = 12.5;
    return v;
}

/* A multi-page TIFF of v (one 16-bit page per z slice), compression COMPRESSION_NONE or
 * COMPRESSION_ADOBE_DEFLATE; 0 on failure. */
static int write_tiff(const cdvr_volume *v, const char *path, int compression)
{
    TIFF *t = TIFFOpen(path, "w");
    if (!t)
        return 0;
    const uint16_t *p = v->data;
    size_t X = v->dims[0], Y = v->dims[1];
    int ok = 1;
    for (size_t z = 0; ok && z < v->dims[2]; z++) {
        TIFFSetField(t, TIFFTAG_IMAGEWIDTH, (uint32_t)X);
        TIFFSetField(t, TIFFTAG_IMAGELENGTH, (uint32_t)Y);
        TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
        TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
        TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_UINT);
        TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
        TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(t, TIFFTAG_COMPRESSION, compression);
        TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, (uint32_t)(compression == COMPRESSION_NONE ? Y : 16));
        TIFFSetField(t, TIFFTAG_SUBFILETYPE, FILETYPE_PAGE);
        TIFFSetField(t, TIFFTAG_PAGENUMBER, (uint16_t)z, (uint16_t)v->dims[2]);
        for (size_t y = 0; ok && y < Y; y++)
            ok = TIFFWriteScanline(t, (void *)(p + X * (y + Y * z)), (uint32_t)y, 0) == 1;
        ok = ok && TIFFWriteDirectory(t) == 1;
    }
    TIFFClose(t);
    return ok;
}

typedef struct bench_file {
    const char *label, *name;
    int compress;  /* for cdvr_volume_save; -2: TIFF none, -3: TIFF deflate */
    char path[1024];
    double mb, save_s;
    double load[64], probe[64];
} bench_file;

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: load_formats DIR [N] [REPS]\n");
        return 2;
    }
    const char *dir = argv[1];
    size_t n = argc > 2 ? (size_t)atol(argv[2]) : 256;
    int reps = argc > 3 ? atoi(argv[3]) : 5;
    if (n < 2 || reps < 1 || reps > 64) {
        fprintf(stderr, "load_formats: N >= 2, 1 <= REPS <= 64\n");
        return 2;
    }
    int tty = isatty(2);
    bench_file files[] = {
        {"NRRD raw", "b.nrrd", 0},          {"NRRD gzip", "bz.nrrd", 1},
        {"NIfTI", "b.nii", 0},              {"NIfTI gz", "b.nii.gz", 1},
        {"VTI raw appended", "b.vti", 0},   {"VTI zlib", "bz.vti", 1},
        {"MHA raw", "b.mha", 0},            {"MHA zlib", "bz.mha", 1},
        {"TIFF multi-page", "b.tif", -2},   {"TIFF deflate", "bz.tif", -3},
    };
    const int nf = (int)(sizeof files / sizeof *files);
    double load_before = loadavg();
    if (tty)
        fprintf(stderr, "generating %zu^3 u16...", n);
    cdvr_volume *v = make_volume(n);
    if (!v)
        return 1;
    size_t bytes = cdvr_volume_frame_bytes(v);
    cdvr_error err;
    for (int i = 0; i < nf; i++) {
        bench_file *f = &files[i];
        snprintf(f->path, sizeof f->path, "%s/%s", dir, f->name);
        if (tty)
            fprintf(stderr, "\r\033[Ksaving %s", f->label);
        double t0 = now();
        int ok;
        if (f->compress >= 0) {
            cdvr_save_opts o = {f->compress};
            ok = cdvr_volume_save(v, f->path, &o, &err) == CDVR_OK;
            if (!ok)
                fprintf(stderr, "\nload_formats: %s\n", err.msg);
        } else {
            ok = write_tiff(v, f->path, f->compress == -2 ? COMPRESSION_NONE
                                                          : COMPRESSION_ADOBE_DEFLATE);
            if (!ok)
                fprintf(stderr, "\nload_formats: %s: libtiff cannot write it\n", f->path);
        }
        f->save_s = now() - t0;
        struct stat sb;
        if (!ok || stat(f->path, &sb) != 0)
            return 1;
        f->mb = (double)sb.st_size / 1e6;
        cdvr_volume *back;
        if (cdvr_volume_load(f->path, NULL, &back, &err) != CDVR_OK) {
            fprintf(stderr, "\nload_formats: %s\n", err.msg);
            return 1;
        }
        int same = back->type == v->type && memcmp(back->data, v->data, bytes) == 0;
        cdvr_volume_free(back);
        if (!same) {
            fprintf(stderr, "\nload_formats: %s: the voxels loaded differ from those saved\n",
                    f->path);
            return 1;
        }
    }
    for (int r = 0; r < reps; r++)
        for (int k = 0; k < nf; k++) {
            bench_file *f = &files[(k + r) % nf];
            if (tty)
                fprintf(stderr, "\r\033[Kround %d/%d: %s", r + 1, reps, f->label);
            cdvr_volume *back;
            double t0 = now();
            cdvr_status st = cdvr_volume_load(f->path, NULL, &back, &err);
            f->load[r] = now() - t0;
            if (st != CDVR_OK) {
                fprintf(stderr, "\nload_formats: %s\n", err.msg);
                return 1;
            }
            cdvr_volume_free(back);
            double p[21];
            for (int j = 0; j < 21; j++) {
                cdvr_volume head = {0};
                head.spacing[0] = head.spacing[1] = head.spacing[2] = 1;
                t0 = now();
                st = cdvr_volume_probe(f->path, NULL, &head, &err);
                p[j] = now() - t0;
                if (st != CDVR_OK) {
                    fprintf(stderr, "\nload_formats: %s\n", err.msg);
                    return 1;
                }
            }
            f->probe[r] = median(p, 21);
        }
    if (tty)
        fprintf(stderr, "\r\033[K");
    double load_after = loadavg();
    double ref = median(files[0].load, reps);
    printf("%zu^3 u16 (%.1f MB of voxels), %d rounds in rotated order, medians; page cache warm\n",
           n, (double)bytes / 1e6, reps);
    printf("%-18s %8s %9s %10s %10s %8s %9s %8s\n", "format", "file MB", "load ms", "file MB/s",
           "voxel MB/s", "vs NRRD", "probe us", "save s");
    for (int i = 0; i < nf; i++) {
        bench_file *f = &files[i];
        double l = median(f->load, reps), p = median(f->probe, reps);
        printf("%-18s %8.2f %9.1f %10.0f %10.0f %8.2f %9.1f %8.2f\n", f->label, f->mb, 1e3 * l,
               f->mb / l, (double)bytes / 1e6 / l, l / ref, 1e6 * p, f->save_s);
    }
    printf("load average (1 min): %.2f before, %.2f after\n", load_before, load_after);
    for (int i = 0; i < nf; i++)
        unlink(files[i].path);
    cdvr_volume_free(v);
    return 0;
}
