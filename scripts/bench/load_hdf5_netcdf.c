/* scripts/bench/load_hdf5_netcdf.c - load and probe time of one N^3 u16 volume (default 256^3)
 * as NRRD raw, HDF5 contiguous, HDF5 chunked 64^3 + deflate 1 and netCDF-4 (contiguous), all
 * through cdvr_volume_load / cdvr_volume_probe (the format registry). Built and run by
 * load_hdf5_netcdf.sh. The files are written once into DIR (libhdf5, libnetcdf, a NRRD header
 * by hand), read once untimed (so every format is timed from the page cache alike), checked voxel
 * for voxel against the written values, then the formats alternate (A B C D, A B C D, ...) REPS
 * times. Prints one CSV row per format: median load ms, MB/s (file bytes over the median load
 * time), median probe ms, file bytes; and the load average (/proc/loadavg) before and after.
 *
 *   load_hdf5_netcdf DIR [REPS [N]]     (defaults 5, 256)
 */
#include "cdvr/volume.h"

#include <hdf5.h>
#include <netcdf.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
    qsort(v, (size_t)n, sizeof *v, cmp);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static void loadavg(char *out, size_t n)
{
    FILE *f = fopen("/proc/loadavg", "r");
    out[0] = '\0';
    if (f) {
        if (!fgets(out, (int)n, f))
            out[0] = '\0';
        fclose(f);
    }
    out[strcspn(out, "\n")] = '\0';
}

static int h5_write(const char *path, const uint16_t *v, size_t N, int chunked)
{
    hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hsize_t d[3] = {N, N, N}, c[3] = {64, 64, 64};
    hid_t sp = H5Screate_simple(3, d, NULL), dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (chunked) {
        H5Pset_chunk(dcpl, 3, c);
        H5Pset_deflate(dcpl, 1);
    }
    hid_t ds = H5Dcreate2(f, "volume", H5T_STD_U16LE, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    herr_t rc = H5Dwrite(ds, H5T_NATIVE_UINT16, H5S_ALL, H5S_ALL, H5P_DEFAULT, v);
    H5Dclose(ds);
    H5Pclose(dcpl);
    H5Sclose(sp);
    H5Fclose(f);
    return rc >= 0;
}

static int nc_write(const char *path, const uint16_t *v, size_t N)
{
    int nc, d[3], var;
    if (nc_create(path, NC_CLOBBER | NC_NETCDF4, &nc) != NC_NOERR)
        return 0;
    nc_def_dim(nc, "z", N, &d[0]);
    nc_def_dim(nc, "y", N, &d[1]);
    nc_def_dim(nc, "x", N, &d[2]);
    nc_def_var(nc, "volume", NC_USHORT, 3, d, &var);
    nc_def_var_chunking(nc, var, NC_CONTIGUOUS, NULL);
    nc_enddef(nc);
    int rc = nc_put_var_ushort(nc, var, v);
    nc_close(nc);
    return rc == NC_NOERR;
}

static int nrrd_write(const char *path, const uint16_t *v, size_t N)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return 0;
    fprintf(f, "NRRD0004\ntype: uint16\ndimension: 3\nsizes: %zu %zu %zu\nencoding: raw\n"
            "endian: little\n\n", N, N, N);
    size_t n = fwrite(v, 2, N * N * N, f);
    return fclose(f) == 0 && n == N * N * N;
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: load_hdf5_netcdf DIR [REPS [N]]\n");
        return 2;
    }
    const char *dir = argv[1];
    int reps = argc > 2 ? atoi(argv[2]) : 5;
    size_t N = argc > 3 ? (size_t)atoi(argv[3]) : 256;
    if (reps < 1 || reps > 100 || N < 64)
        return 2;
    size_t count = N * N * N;
    uint16_t *v = malloc(count * 2);
    if (!v)
        return 1;
    uint32_t h = 12345;
    for (size_t z = 0, i = 0; z < N; z++)
        for (size_t y = 0; y < N; y++)
            for (size_t x = 0; x < N; x++, i++) { /* smooth field + 6 bits of noise */
                h = h * 1664525u + 1013904223u;
                v[i] = (uint16_t)(((x * 37 + y * 11) ^ (z * 5)) % 2048 * 16 + (h >> 26));
            }
    static const char *const label[] = {"nrrd_raw", "hdf5_contiguous", "hdf5_chunk64_deflate1",
                                        "netcdf4_contiguous"};
    static const char *const file[] = {"v.nrrd", "v_contig.h5", "v_chunked.h5", "v.nc"};
    enum { F = 4 };
    char path[F][4096];
    for (int k = 0; k < F; k++)
        snprintf(path[k], sizeof path[k], "%s/%s", dir, file[k]);
    if (!nrrd_write(path[0], v, N) || !h5_write(path[1], v, N, 0) || !h5_write(path[2], v, N, 1) ||
        !nc_write(path[3], v, N)) {
        fprintf(stderr, "load_hdf5_netcdf: cannot write the files in %s\n", dir);
        return 1;
    }
    double load[F][100], probe[F][100];
    long long bytes[F];
    for (int k = 0; k < F; k++) { /* untimed: page cache, and the voxels checked */
        struct stat sb;
        stat(path[k], &sb);
        bytes[k] = (long long)sb.st_size;
        cdvr_error err;
        cdvr_volume *vol = NULL;
        if (cdvr_volume_load(path[k], NULL, &vol, &err) != CDVR_OK) {
            fprintf(stderr, "%s: %s\n", label[k], err.msg);
            return 1;
        }
        if (vol->type != CDVR_TYPE_U16 || memcmp(vol->data, v, count * 2) != 0) {
            fprintf(stderr, "%s: voxels differ\n", label[k]);
            return 1;
        }
        cdvr_volume_free(vol);
    }
    char la0[128], la1[128];
    loadavg(la0, sizeof la0);
    for (int r = 0; r < reps; r++)
        for (int k = 0; k < F; k++) {
            cdvr_error err;
            cdvr_volume *vol = NULL, head;
            double t0 = now();
            cdvr_status st = cdvr_volume_load(path[k], NULL, &vol, &err);
            double t1 = now();
            st = st == CDVR_OK ? cdvr_volume_probe(path[k], NULL, &head, &err) : st;
            double t2 = now();
            if (st != CDVR_OK) {
                fprintf(stderr, "%s: %s\n", label[k], err.msg);
                return 1;
            }
            cdvr_volume_free(vol);
            load[k][r] = t1 - t0;
            probe[k][r] = t2 - t1;
        }
    loadavg(la1, sizeof la1);
    printf("format,dims,load_ms_median,load_mb_s,probe_ms_median,file_bytes,reps\n");
    for (int k = 0; k < F; k++) {
        double l = median(load[k], reps), p = median(probe[k], reps);
        printf("%s,%zux%zux%zu u16,%.2f,%.0f,%.3f,%lld,%d\n", label[k], N, N, N, 1e3 * l,
               (double)bytes[k] / l / 1e6, 1e3 * p, bytes[k], reps);
    }
    printf("# load average before: %s; after: %s\n", la0, la1);
    free(v);
    return 0;
}
