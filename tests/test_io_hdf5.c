/* tests/test_io_hdf5.c - the HDF5 loader (core/io/io_hdf5.c, format "hdf5"), on files written
 * here with libhdf5: a contiguous u16 dataset of odd dims 5x7x3 (HDF5 dims (3, 7, 5)) with
 * element_size_um (z, y, x) loads voxel for voxel as the file's only 3D dataset, world box from
 * that spacing; a chunked (odd chunks) deflate + shuffle float 4D (t, z, y, x) dataset in a group
 * loads as a series through FILE:/g/d and select=, spacing from the group's `spacing` and
 * origin from the dataset's `origin` (x, y, z); float64 and int8 become float32 with the window
 * computed in double; several 3D datasets without a name, a name the file lacks, a group, a 2D
 * dataset and a conflicting select= are refused naming the file and the datasets; a dims claim
 * above max_bytes is refused before reading; a FIFO is refused without blocking; probe reads the
 * header only (it succeeds on a file whose chunk is corrupt, which load then refuses naming the
 * dataset); an external link and a file cut short are refused; loads from several threads at
 * once agree (the library lock).
 * `test_io_hdf5 --write DIR` writes DIR/lua.h5 for tests/lua/test_hdf5_netcdf.lua. */
#include "check.h"
#include "cdvr/format.h"
#include "cdvr/volume.h"

#include <hdf5.h>
#include <pthread.h>
#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[] = "/tmp/cdvr_test_io_hdf5_XXXXXX";

static void at(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", tmpdir, name);
}

static uint16_t u16_value(size_t i) { return (uint16_t)((i * 977 + 3) % 65536); }
static float f32_value(size_t i) { return (float)(0.25 * (double)i - 7.5); }

/* A dataset of rank dims (HDF5 order) of file type ftype from data of memory type mtype;
 * chunk (NULL: contiguous), deflate level (< 0: none), shuffle. */
static hid_t dataset(hid_t loc, const char *name, hid_t ftype, int rank, const hsize_t *dims,
                     const hsize_t *chunk, int deflate, int shuffle, hid_t mtype,
                     const void *data)
{
    hid_t sp = H5Screate_simple(rank, dims, NULL), dcpl = H5Pcreate(H5P_DATASET_CREATE);
    if (chunk)
        H5Pset_chunk(dcpl, rank, chunk);
    if (shuffle)
        H5Pset_shuffle(dcpl);
    if (deflate >= 0)
        H5Pset_deflate(dcpl, (unsigned)deflate);
    hid_t did = H5Dcreate2(loc, name, ftype, sp, H5P_DEFAULT, dcpl, H5P_DEFAULT);
    if (data)
        H5Dwrite(did, mtype, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
    H5Pclose(dcpl);
    H5Sclose(sp);
    return did;
}

static void attr(hid_t obj, const char *name, int n, const double *v)
{
    hsize_t d = (hsize_t)n;
    hid_t sp = H5Screate_simple(1, &d, NULL);
    hid_t a = H5Acreate2(obj, name, H5T_IEEE_F64LE, sp, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, H5T_NATIVE_DOUBLE, v);
    H5Aclose(a);
    H5Sclose(sp);
}

/* 5x7x3 u16 (HDF5 (3, 7, 5)), contiguous, element_size_um 3 2 0.5 (z y x). */
static void write_simple(const char *path)
{
    hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hsize_t d[3] = {3, 7, 5};
    uint16_t v[105];
    for (size_t i = 0; i < 105; i++)
        v[i] = u16_value(i);
    hid_t did = dataset(f, "volume", H5T_STD_U16BE, 3, d, NULL, -1, 0, H5T_NATIVE_UINT16, v);
    attr(did, "element_size_um", 3, (double[]){3, 2, 0.5});
    H5Dclose(did);
    hsize_t d1[1] = {4}; /* a 1D dataset: not a candidate */
    H5Dclose(dataset(f, "axis", H5T_NATIVE_DOUBLE, 1, d1, NULL, -1, 0, H5T_NATIVE_DOUBLE,
                     (double[]){1, 2, 3, 4}));
    H5Fclose(f);
}

/* /g/d: (t=2, z=3, y=7, x=5) float, chunks (1, 2, 3, 4), deflate 6 + shuffle; group spacing
 * 1.5 2.5 3.5 (x y z), dataset origin 10 20 30; /g/flat 2D; /other (3, 7, 5) u8 chunked. */
static void write_series(const char *path, int group_spacing)
{
    hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hid_t g = H5Gcreate2(f, "g", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    hsize_t d[4] = {2, 3, 7, 5}, c[4] = {1, 2, 3, 4};
    float v[210];
    for (size_t i = 0; i < 210; i++)
        v[i] = f32_value(i);
    hid_t did = dataset(g, "d", H5T_IEEE_F32LE, 4, d, c, 6, 1, H5T_NATIVE_FLOAT, v);
    attr(did, "origin", 3, (double[]){10, 20, 30});
    if (group_spacing)
        attr(g, "spacing", 3, (double[]){1.5, 2.5, 3.5});
    H5Dclose(did);
    hsize_t d2[2] = {7, 5};
    H5Dclose(dataset(g, "flat", H5T_NATIVE_FLOAT, 2, d2, NULL, -1, 0, H5T_NATIVE_FLOAT, v));
    H5Gclose(g);
    uint8_t b[105];
    for (size_t i = 0; i < 105; i++)
        b[i] = (uint8_t)(i * 7);
    hsize_t d3[3] = {3, 7, 5}, c3[3] = {2, 2, 2};
    H5Dclose(dataset(f, "other", H5T_NATIVE_UINT8, 3, d3, c3, 1, 0, H5T_NATIVE_UINT8, b));
    H5Fclose(f);
}

static void check_u16(const cdvr_volume *v, const char *what)
{
    CHECK(v->dims[0] == 5 && v->dims[1] == 7 && v->dims[2] == 3 && v->timesteps == 1 &&
          v->type == CDVR_TYPE_U16, "%s: dims %zux%zux%zu x%zu type %d", what, v->dims[0],
          v->dims[1], v->dims[2], v->timesteps, (int)v->type);
    size_t bad = 0;
    for (size_t z = 0; z < 3; z++)
        for (size_t y = 0; y < 7; y++)
            for (size_t x = 0; x < 5; x++)
                bad += cdvr_volume_get(v, x, y, z, 0) != u16_value(x + 5 * (y + 7 * z));
    CHECK(bad == 0, "%s: %zu voxels differ", what, bad);
}

static void test_simple(void)
{
    char p[512];
    at(p, sizeof p, "simple.h5");
    write_simple(p);
    cdvr_error err;
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK_OK(st, err);
    if (st != CDVR_OK)
        return;
    check_u16(v, "simple");
    CHECK(v->spacing[0] == 0.5 && v->spacing[1] == 2 && v->spacing[2] == 3,
          "element_size_um z y x -> spacing %g %g %g", v->spacing[0], v->spacing[1],
          v->spacing[2]);
    double lo[3], hi[3];
    cdvr_volume_bounds(v, lo, hi);
    CHECK(lo[0] == 0 && lo[1] == 0 && lo[2] == 0 && hi[0] == 2 && hi[1] == 12 && hi[2] == 6,
          "world box %g %g %g .. %g %g %g", lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
    cdvr_volume_free(v);
    /* the same through FILE:NAME (a name without '/' is relative to the root) */
    char q[600];
    snprintf(q, sizeof q, "%s:volume", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        check_u16(v, "FILE:volume");
        cdvr_volume_free(v);
    }
    const cdvr_format *f = NULL;
    CHECK(cdvr_format_for(q, NULL, &f, &err) == CDVR_OK && f && strcmp(f->name, "hdf5") == 0,
          "FILE:NAME finds hdf5");
    /* a 1D dataset named: refused naming it */
    snprintf(q, sizeof q, "%s:/axis", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "simple.h5") && strstr(err.msg, "/axis") &&
          strstr(err.msg, "3D"), "1D dataset refused: %s", err.msg);
}

static void check_series(const cdvr_volume *v, const char *what)
{
    CHECK(v->dims[0] == 5 && v->dims[1] == 7 && v->dims[2] == 3 && v->timesteps == 2 &&
          v->type == CDVR_TYPE_F32, "%s: dims %zux%zux%zu x%zu type %d", what, v->dims[0],
          v->dims[1], v->dims[2], v->timesteps, (int)v->type);
    size_t bad = 0;
    for (size_t t = 0; t < 2; t++)
        for (size_t z = 0; z < 3; z++)
            for (size_t y = 0; y < 7; y++)
                for (size_t x = 0; x < 5; x++)
                    bad += cdvr_volume_get(v, x, y, z, t) !=
                           f32_value(x + 5 * (y + 7 * (z + 3 * t)));
    CHECK(bad == 0, "%s: %zu voxels differ", what, bad);
    CHECK(v->spacing[0] == 1.5 && v->spacing[1] == 2.5 && v->spacing[2] == 3.5 &&
          v->origin[0] == 10 && v->origin[1] == 20 && v->origin[2] == 30,
          "%s: spacing %g %g %g origin %g %g %g", what, v->spacing[0], v->spacing[1],
          v->spacing[2], v->origin[0], v->origin[1], v->origin[2]);
    double lo[3], hi[3];
    cdvr_volume_bounds(v, lo, hi);
    CHECK(lo[0] == 10 && lo[1] == 20 && lo[2] == 30 && hi[0] == 16 && hi[1] == 35 && hi[2] == 37,
          "%s: world box %g %g %g .. %g %g %g", what, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]);
}

static void test_series(void)
{
    char p[512], q[600];
    at(p, sizeof p, "series.h5");
    write_series(p, 1);
    cdvr_error err;
    cdvr_volume *v = NULL;
    snprintf(q, sizeof q, "%s:/g/d", p);
    cdvr_status st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        check_series(v, "FILE:/g/d");
        cdvr_volume_free(v);
    }
    cdvr_raw_opts o = {.select = "/g/d"};
    st = cdvr_volume_load(p, &o, &v, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        check_series(v, "select=/g/d");
        cdvr_volume_free(v);
    }
    cdvr_volume head;
    st = cdvr_volume_probe(q, NULL, &head, &err);
    CHECK(st == CDVR_OK && head.dims[0] == 5 && head.dims[1] == 7 && head.dims[2] == 3 &&
          head.timesteps == 2 && head.type == CDVR_TYPE_F32 && head.spacing[2] == 3.5 &&
          head.origin[1] == 20, "probe agrees: %s", st == CDVR_OK ? "" : err.msg);
    /* no name: two 3D/4D candidates, refused listing them */
    st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "series.h5") && strstr(err.msg, "/g/d (2, 3, 7, 5)") &&
          strstr(err.msg, "/other (3, 7, 5) uint8") && !strstr(err.msg, "flat"),
          "two candidates refused: %s", err.msg);
    /* a name the file lacks: refused listing what it holds */
    snprintf(q, sizeof q, "%s:/g/nope", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "series.h5") && strstr(err.msg, "no dataset '/g/nope'")
          && strstr(err.msg, "/g/d") && strstr(err.msg, "/g/flat") && strstr(err.msg, "/other"),
          "missing dataset refused listing names: %s", err.msg);
    snprintf(q, sizeof q, "%s:/missing/group/d", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "no dataset '/missing/group/d'"),
          "missing group refused: %s", err.msg);
    snprintf(q, sizeof q, "%s:/g", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "is a group"), "a group refused: %s", err.msg);
    snprintf(q, sizeof q, "%s:/g/flat", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "/g/flat") && strstr(err.msg, "(7, 5) float32"),
          "2D refused: %s", err.msg);
    snprintf(q, sizeof q, "%s:/g/d", p);
    o.select = "/other";
    st = cdvr_volume_load(q, &o, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "/g/d") && strstr(err.msg, "/other"),
          "path and select= disagree: %s", err.msg);
    /* /other: chunked u8 through select= */
    st = cdvr_volume_load(p, &o, &v, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        size_t bad = 0;
        for (size_t i = 0; i < 105; i++)
            bad += ((uint8_t *)v->data)[i] != (uint8_t)(i * 7);
        CHECK(v->type == CDVR_TYPE_U8 && bad == 0 && v->spacing[0] == 1 && v->origin[0] == 0,
              "chunked u8, unit spacing: %zu differ", bad);
        cdvr_volume_free(v);
    }
}

static void test_converted(void)
{
    char p[512];
    at(p, sizeof p, "f64.h5");
    hid_t f = H5Fcreate(p, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hsize_t d[3] = {3, 7, 5}, c[3] = {3, 7, 5};
    double v[105];
    int8_t b[105];
    for (size_t i = 0; i < 105; i++) {
        v[i] = 1e-3 * (double)i + 1.0 / 3.0;
        b[i] = (int8_t)((int)i - 60);
    }
    H5Dclose(dataset(f, "d64", H5T_IEEE_F64BE, 3, d, c, 1, 1, H5T_NATIVE_DOUBLE, v));
    H5Dclose(dataset(f, "i8", H5T_STD_I8LE, 3, d, NULL, -1, 0, H5T_NATIVE_INT8, b));
    H5Fclose(f);
    cdvr_error err;
    cdvr_volume *vol = NULL;
    cdvr_raw_opts o = {.select = "d64"};
    cdvr_status st = cdvr_volume_load(p, &o, &vol, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        size_t bad = 0;
        for (size_t i = 0; i < 105; i++)
            bad += ((float *)vol->data)[i] != (float)v[i];
        double w[2];
        cdvr_volume_window(vol, w);
        CHECK(vol->type == CDVR_TYPE_F32 && bad == 0 && w[0] == v[0] && w[1] == v[104],
              "f64 -> f32, %zu differ, window [%.17g, %.17g] in double", bad, w[0], w[1]);
        CHECK(strcmp(vol->source_type, "float64") == 0 && cdvr_volume_converted(vol),
              "the conversion is reported: source_type '%s'", vol->source_type);
        cdvr_volume_free(vol);
    }
    o.select = "/i8";
    st = cdvr_volume_load(p, &o, &vol, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        size_t bad = 0;
        for (size_t i = 0; i < 105; i++)
            bad += ((float *)vol->data)[i] != (float)b[i];
        CHECK(vol->type == CDVR_TYPE_F32 && bad == 0 && vol->window[0] == -60 &&
              vol->window[1] == 44, "i8 -> f32, %zu differ", bad);
        cdvr_volume_free(vol);
    }
}

static void test_limits(void)
{
    char p[512], q[600];
    at(p, sizeof p, "big.h5");
    hid_t f = H5Fcreate(p, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hsize_t d[3] = {400, 400, 400}, c[3] = {64, 64, 64};
    H5Dclose(dataset(f, "big", H5T_NATIVE_UINT16, 3, d, c, 1, 0, H5T_NATIVE_UINT16, NULL));
    H5Fclose(f);
    struct stat sb;
    stat(p, &sb);
    cdvr_error err;
    cdvr_volume *v = NULL;
    cdvr_raw_opts o = {.max_bytes = 1 << 20};
    cdvr_status st = cdvr_volume_load(p, &o, &v, &err);
    CHECK(st != CDVR_OK && !v && strstr(err.msg, "big.h5") && strstr(err.msg, "'/big'") &&
          strstr(err.msg, "128000000 bytes") && strstr(err.msg, "max_bytes 1048576"),
          "a claim above max_bytes refused (file of %lld bytes): %s", (long long)sb.st_size,
          err.msg);
    cdvr_volume head;
    st = cdvr_volume_probe(p, &o, &head, &err);
    CHECK(st == CDVR_OK && head.dims[0] == 400 && head.type == CDVR_TYPE_U16,
          "probe of it answers: %s", st == CDVR_OK ? "" : err.msg);
    /* a FIFO (named like an HDF5 file) is refused, never waited on */
    at(p, sizeof p, "fifo.h5");
    CHECK(mkfifo(p, 0600) == 0, "mkfifo");
    st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "fifo.h5") && strstr(err.msg, "FIFO"),
          "FIFO refused: %s", err.msg);
    const cdvr_format *h5 = cdvr_format_find("hdf5");
    snprintf(q, sizeof q, "%s:/d", p);
    st = h5 ? h5->load(q, NULL, &v, &err) : CDVR_ERR_ARG;
    CHECK(st != CDVR_OK && strstr(err.msg, "FIFO"), "FIFO:/d refused: %s", err.msg);
    st = h5 ? h5->probe(q, NULL, &head, &err) : CDVR_ERR_ARG;
    CHECK(st != CDVR_OK && strstr(err.msg, "FIFO"), "FIFO probe refused: %s", err.msg);
    /* not an HDF5 file */
    at(p, sizeof p, "junk.h5");
    FILE *j = fopen(p, "wb");
    fputs("not hdf5 at all\n", j);
    fclose(j);
    st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "junk.h5") && strstr(err.msg, "not an HDF5 file"),
          "junk refused: %s", err.msg);
}

/* probe reads the header only: a corrupt chunk is seen by load, not by probe. */
static void test_probe_header_only(void)
{
    char p[512];
    at(p, sizeof p, "corrupt.h5");
    write_series(p, 1);
    hid_t f = H5Fopen(p, H5F_ACC_RDONLY, H5P_DEFAULT);
    hid_t did = H5Dopen2(f, "/g/d", H5P_DEFAULT);
    haddr_t addr = HADDR_UNDEF;
    hsize_t size = 0, off[4];
    unsigned mask;
    hid_t space = H5Dget_space(did);
    H5Dget_chunk_info(did, space, 0, off, &mask, &addr, &size);
    H5Sclose(space);
    H5Dclose(did);
    H5Fclose(f);
    CHECK(addr != HADDR_UNDEF && size > 4, "chunk 0 at %llu, %llu bytes",
          (unsigned long long)addr, (unsigned long long)size);
    FILE *w = fopen(p, "r+b");
    fseek(w, (long)addr, SEEK_SET);
    for (hsize_t i = 0; i < size; i++)
        fputc(0xA5, w);
    fclose(w);
    cdvr_error err;
    cdvr_volume head, *v = NULL;
    char q[600];
    snprintf(q, sizeof q, "%s:/g/d", p);
    cdvr_status st = cdvr_volume_probe(q, NULL, &head, &err);
    CHECK(st == CDVR_OK && head.timesteps == 2 && head.spacing[0] == 1.5,
          "probe of a file with a corrupt chunk: %s", st == CDVR_OK ? "ok" : err.msg);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && !v && strstr(err.msg, "corrupt.h5") && strstr(err.msg, "/g/d") &&
          strstr(err.msg, "cannot be read"), "load of it refused: %s", err.msg);
}

static void test_bad_spacing(void)
{
    char p[512];
    at(p, sizeof p, "badsp.h5");
    hid_t f = H5Fcreate(p, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hsize_t d[3] = {3, 7, 5};
    uint16_t v[105] = {0};
    hid_t did = dataset(f, "d", H5T_NATIVE_UINT16, 3, d, NULL, -1, 0, H5T_NATIVE_UINT16, v);
    attr(did, "spacing", 3, (double[]){1, -2, 1});
    H5Dclose(did);
    did = dataset(f, "e", H5T_NATIVE_UINT16, 3, d, NULL, -1, 0, H5T_NATIVE_UINT16, v);
    attr(did, "element_size_um", 2, (double[]){1, 2});
    H5Dclose(did);
    H5Fclose(f);
    cdvr_error err;
    cdvr_volume *vol = NULL;
    cdvr_raw_opts o = {.select = "/d"};
    cdvr_status st = cdvr_volume_load(p, &o, &vol, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "spacing") && strstr(err.msg, "-2"),
          "negative spacing refused: %s", err.msg);
    o.select = "/e";
    st = cdvr_volume_load(p, &o, &vol, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "element_size_um") && strstr(err.msg, "2 values"),
          "2-number element_size_um refused: %s", err.msg);
}

/* Hostile files: an external link (another file read through this one) and a contiguous
 * dataset cut short. */
static void test_hostile(void)
{
    char p[512], q[600], other[512];
    at(other, sizeof other, "target.h5");
    write_simple(other);
    at(p, sizeof p, "elink.h5");
    hid_t f = H5Fcreate(p, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    H5Lcreate_external(other, "/volume", f, "ext", H5P_DEFAULT, H5P_DEFAULT);
    H5Fclose(f);
    cdvr_error err;
    cdvr_volume *v = NULL;
    snprintf(q, sizeof q, "%s:/ext", p);
    cdvr_status st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && !v && strstr(err.msg, "elink.h5") && strstr(err.msg, "/ext") &&
          strstr(err.msg, "external links are not followed"), "external link refused: %s",
          err.msg);
    st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "no 3D or 4D"), "external link not a candidate: %s",
          err.msg);
    at(p, sizeof p, "cut.h5");
    write_simple(p);
    struct stat sb;
    stat(p, &sb);
    CHECK(truncate(p, sb.st_size - 60) == 0, "truncate");
    st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && !v && strstr(err.msg, "cut.h5"), "a file cut short refused: %s",
          err.msg);
}

typedef struct job {
    const char *path;
    int ok;
} job;

static void *load_job(void *ud)
{
    job *j = ud;
    for (int k = 0; k < 10; k++) {
        cdvr_error err;
        cdvr_volume *v = NULL;
        if (cdvr_volume_load(j->path, NULL, &v, &err) != CDVR_OK)
            return NULL;
        j->ok += v->dims[0] == 5 && ((float *)v->data)[209] == f32_value(209);
        cdvr_volume_free(v);
    }
    return NULL;
}

static void test_threads(void)
{
    char p[512], q[600];
    at(p, sizeof p, "threads.h5");
    write_series(p, 1);
    snprintf(q, sizeof q, "%s:/g/d", p);
    pthread_t th[4];
    job jobs[4];
    for (int i = 0; i < 4; i++) {
        jobs[i] = (job){q, 0};
        pthread_create(&th[i], NULL, load_job, &jobs[i]);
    }
    int ok = 0;
    for (int i = 0; i < 4; i++) {
        pthread_join(th[i], NULL);
        ok += jobs[i].ok;
    }
    CHECK(ok == 40, "4 threads x 10 loads: %d agree", ok);
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--write") == 0) { /* tests/lua/test_hdf5_netcdf.lua */
        char p[4096];
        snprintf(p, sizeof p, "%s/lua.h5", argv[2]);
        write_series(p, 1);
        return 0;
    }
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_simple();
    test_series();
    test_converted();
    test_limits();
    test_probe_header_only();
    test_bad_spacing();
    test_hostile();
    test_threads();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
    return check_finish();
}
