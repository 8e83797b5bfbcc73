/* tests/test_io_netcdf.c - the NetCDF loader (core/io/io_netcdf.c, format "netcdf"), on files
 * written here with libnetcdf: a classic file's short variable T(z=3, y=7, x=5) loads voxel for
 * voxel as the only 3D variable, its uniform CF coordinate variables (x ascending, y
 * descending, z) giving spacing, origin and the direction of y, and the world box they make; a
 * netCDF-4 file's u(time (unlimited)=2, z, y, x) float, chunked with deflate and shuffle, is a
 * series of 2 through FILE:u and select=; _FillValue and missing_value become NaN and
 * scale_factor / add_offset are applied (float32, window in double); a non-uniform coordinate
 * is refused naming the variable and its worst step; several candidates, a name the file
 * lacks, a time dimension that is not first and a conflicting select= are refused naming the
 * variables; a claim above max_bytes is refused before reading; a FIFO is refused without
 * blocking; probe reads the header only (it answers for a netCDF-4 file whose chunk is
 * corrupt, which load refuses); a classic, 64-bit offset or CDF-5 file one byte shorter than
 * its header implies is refused (load and probe), one missing only its last padding loads;
 * valid_range / valid_min / valid_max make stored values outside NaN; without a name, the only
 * 3D variable of a subgroup loads, and several in subgroups are listed with their paths.
 * `test_io_netcdf --write DIR` writes DIR/lua.nc for tests/lua/test_hdf5_netcdf.lua. */
#include "check.h"
#include "cdvr/format.h"
#include "cdvr/volume.h"

#include <hdf5.h>
#include <netcdf.h>
#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[] = "/tmp/cdvr_test_io_netcdf_XXXXXX";

static void at(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", tmpdir, name);
}

#define NC(call)                                                                            \
    do {                                                                                    \
        int rc_ = (call);                                                                   \
        if (rc_ != NC_NOERR) {                                                              \
            fprintf(stderr, "%s:%d: %s: %s\n", __FILE__, __LINE__, #call, nc_strerror(rc_)); \
            exit(1);                                                                        \
        }                                                                                   \
    } while (0)

static short s_value(size_t i) { return (short)((long)(i * 131) % 2000 - 1000); }
static float f_value(size_t i) { return (float)(0.5 * (double)i - 20.25); }

/* T(z, y, x) short with coordinates x = 10 + 0.5 i, y = 100 - 2 j, z = 3 k (xbad: x not
 * uniform). A second 3D variable `extra` when two. */
static void write_classic(const char *path, int xbad, int two)
{
    int nc, dz, dy, dx, vt, vx, vy, vz, ve;
    NC(nc_create(path, NC_CLOBBER, &nc));
    NC(nc_def_dim(nc, "z", 3, &dz));
    NC(nc_def_dim(nc, "y", 7, &dy));
    NC(nc_def_dim(nc, "x", 5, &dx));
    int dims[3] = {dz, dy, dx};
    NC(nc_def_var(nc, "x", NC_DOUBLE, 1, &dx, &vx));
    NC(nc_def_var(nc, "y", NC_FLOAT, 1, &dy, &vy));
    NC(nc_def_var(nc, "z", NC_INT, 1, &dz, &vz));
    NC(nc_def_var(nc, "T", NC_SHORT, 3, dims, &vt));
    if (two)
        NC(nc_def_var(nc, "extra", NC_FLOAT, 3, dims, &ve));
    NC(nc_enddef(nc));
    double x[5];
    float y[7];
    int z[3] = {0, 3, 6};
    for (int i = 0; i < 5; i++)
        x[i] = 10 + 0.5 * i + (xbad && i >= 3 ? 0.25 : 0);
    for (int j = 0; j < 7; j++)
        y[j] = (float)(100 - 2 * j);
    short t[105];
    float e[105];
    for (size_t i = 0; i < 105; i++) {
        t[i] = s_value(i);
        e[i] = (float)i;
    }
    NC(nc_put_var_double(nc, vx, x));
    NC(nc_put_var_float(nc, vy, y));
    NC(nc_put_var_int(nc, vz, z));
    NC(nc_put_var_short(nc, vt, t));
    if (two)
        NC(nc_put_var_float(nc, ve, e));
    NC(nc_close(nc));
}

/* netCDF-4: u(time (unlimited) = 2, z = 3, y = 7, x = 5) float, chunks (1, 2, 3, 4), deflate 1
 * + shuffle; v(z, y, x) short with _FillValue -999, missing_value -998, scale 0.5, offset 10;
 * w(z, time, x) float (time not first). */
static void write_nc4(const char *path)
{
    int nc, dt, dz, dy, dx, vu, vv, vw;
    NC(nc_create(path, NC_CLOBBER | NC_NETCDF4, &nc));
    NC(nc_def_dim(nc, "time", NC_UNLIMITED, &dt));
    NC(nc_def_dim(nc, "z", 3, &dz));
    NC(nc_def_dim(nc, "y", 7, &dy));
    NC(nc_def_dim(nc, "x", 5, &dx));
    int d4[4] = {dt, dz, dy, dx}, d3[3] = {dz, dy, dx}, dw[3] = {dz, dt, dx};
    size_t chunks[4] = {1, 2, 3, 4};
    NC(nc_def_var(nc, "u", NC_FLOAT, 4, d4, &vu));
    NC(nc_def_var_chunking(nc, vu, NC_CHUNKED, chunks));
    NC(nc_def_var_deflate(nc, vu, 1, 1, 1));
    NC(nc_def_var(nc, "v", NC_SHORT, 3, d3, &vv));
    short fill = -999, missing = -998;
    double scale = 0.5, offset = 10;
    NC(nc_def_var_fill(nc, vv, 0, &fill));
    NC(nc_put_att_short(nc, vv, "missing_value", NC_SHORT, 1, &missing));
    NC(nc_put_att_double(nc, vv, "scale_factor", NC_DOUBLE, 1, &scale));
    NC(nc_put_att_double(nc, vv, "add_offset", NC_DOUBLE, 1, &offset));
    NC(nc_def_var(nc, "w", NC_FLOAT, 3, dw, &vw));
    NC(nc_enddef(nc));
    float u[210];
    for (size_t i = 0; i < 210; i++)
        u[i] = f_value(i);
    size_t start[4] = {0, 0, 0, 0}, count[4] = {2, 3, 7, 5};
    NC(nc_put_vara_float(nc, vu, start, count, u));
    short v[105];
    for (size_t i = 0; i < 105; i++)
        v[i] = i % 10 == 3 ? fill : i % 10 == 7 ? missing : s_value(i);
    NC(nc_put_var_short(nc, vv, v));
    size_t cw[3] = {3, 2, 5};
    NC(nc_put_vara_float(nc, vw, start, cw, u));
    NC(nc_close(nc));
}

static void test_classic(void)
{
    char p[512], q[600];
    at(p, sizeof p, "classic.nc");
    write_classic(p, 0, 0);
    cdvr_error err;
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        CHECK(v->dims[0] == 5 && v->dims[1] == 7 && v->dims[2] == 3 && v->timesteps == 1 &&
              v->type == CDVR_TYPE_I16, "dims %zux%zux%zu x%zu type %d", v->dims[0], v->dims[1],
              v->dims[2], v->timesteps, (int)v->type);
        size_t bad = 0;
        for (size_t z = 0; z < 3; z++)
            for (size_t y = 0; y < 7; y++)
                for (size_t x = 0; x < 5; x++)
                    bad += cdvr_volume_get(v, x, y, z, 0) != s_value(x + 5 * (y + 7 * z));
        CHECK(bad == 0, "%zu voxels differ", bad);
        CHECK(v->spacing[0] == 0.5 && v->spacing[1] == 2 && v->spacing[2] == 3 &&
              v->origin[0] == 10 && v->origin[1] == 100 && v->origin[2] == 0 &&
              v->direction[4] == -1 && v->direction[0] == 1 && v->direction[8] == 1,
              "coordinates: spacing %g %g %g origin %g %g %g dy %g", v->spacing[0],
              v->spacing[1], v->spacing[2], v->origin[0], v->origin[1], v->origin[2],
              v->direction[4]);
        double lo[3], hi[3];
        cdvr_volume_bounds(v, lo, hi);
        CHECK(lo[0] == 10 && hi[0] == 12 && lo[1] == 88 && hi[1] == 100 && lo[2] == 0 &&
              hi[2] == 6, "world box %g %g %g .. %g %g %g", lo[0], lo[1], lo[2], hi[0], hi[1],
              hi[2]);
        cdvr_volume_free(v);
    }
    snprintf(q, sizeof q, "%s:T", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK_OK(st, err);
    cdvr_volume_free(v);
    snprintf(q, sizeof q, "%s:nope", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "classic.nc") && strstr(err.msg, "no variable 'nope'")
          && strstr(err.msg, "T(z=3, y=7, x=5) short") && strstr(err.msg, "x(x=5) double"),
          "missing variable refused listing names: %s", err.msg);
    snprintf(q, sizeof q, "%s:x", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "x(x=5)") && strstr(err.msg, "1 dimensions"),
          "1D variable refused: %s", err.msg);
    /* a non-uniform x */
    at(p, sizeof p, "nonuniform.nc");
    write_classic(p, 1, 0);
    st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "nonuniform.nc") && strstr(err.msg, "'x'") &&
          strstr(err.msg, "not uniform") && strstr(err.msg, "step 0.75 from index 2 to 3"),
          "non-uniform coordinate refused: %s", err.msg);
    cdvr_volume head;
    st = cdvr_volume_probe(p, NULL, &head, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "not uniform"), "probe refuses it too");
    /* two candidates */
    at(p, sizeof p, "two.nc");
    write_classic(p, 0, 1);
    st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "two.nc") && strstr(err.msg, "2 3D/4D variables") &&
          strstr(err.msg, "T(z=3") && strstr(err.msg, "extra(z=3"), "two candidates: %s",
          err.msg);
    cdvr_raw_opts o = {.select = "extra"};
    st = cdvr_volume_load(p, &o, &v, &err);
    CHECK(st == CDVR_OK && v->type == CDVR_TYPE_F32 && ((float *)v->data)[104] == 104 &&
          v->spacing[1] == 2, "select=extra: %s", st == CDVR_OK ? "" : err.msg);
    cdvr_volume_free(v);
    snprintf(q, sizeof q, "%s:T", p);
    st = cdvr_volume_load(q, &o, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "'T'") && strstr(err.msg, "'extra'"),
          "path and select= disagree: %s", err.msg);
}

static void test_nc4(void)
{
    char p[512], q[600];
    at(p, sizeof p, "four.nc");
    write_nc4(p);
    cdvr_error err;
    cdvr_volume *v = NULL;
    snprintf(q, sizeof q, "%s:u", p);
    for (int how = 0; how < 2; how++) {
        cdvr_raw_opts o = {.select = "u"};
        cdvr_status st = cdvr_volume_load(how ? p : q, how ? &o : NULL, &v, &err);
        CHECK_OK(st, err);
        if (st != CDVR_OK)
            continue;
        CHECK(v->dims[0] == 5 && v->dims[1] == 7 && v->dims[2] == 3 && v->timesteps == 2 &&
              v->type == CDVR_TYPE_F32 && v->spacing[0] == 1 && v->origin[2] == 0,
              "u: dims %zux%zux%zu x%zu", v->dims[0], v->dims[1], v->dims[2], v->timesteps);
        size_t bad = 0;
        for (size_t i = 0; i < 210; i++)
            bad += ((float *)v->data)[i] != f_value(i);
        CHECK(bad == 0, "u (%s): %zu voxels differ", how ? "select=" : "FILE:u", bad);
        cdvr_volume_free(v);
    }
    /* several candidates: u and v (w is 3D too) */
    cdvr_status st = cdvr_volume_load(p, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "u(time=2, z=3, y=7, x=5) float") &&
          strstr(err.msg, "v(z=3, y=7, x=5) short"), "candidates listed: %s", err.msg);
    /* fill values and packing */
    snprintf(q, sizeof q, "%s:v", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        size_t bad = 0, nans = 0;
        double lo = 1e300, hi = -1e300;
        for (size_t i = 0; i < 105; i++) {
            float got = ((float *)v->data)[i];
            if (i % 10 == 3 || i % 10 == 7) {
                nans += isnan(got);
                continue;
            }
            double want = s_value(i) * 0.5 + 10;
            lo = want < lo ? want : lo;
            hi = want > hi ? want : hi;
            bad += got != (float)want;
        }
        double w[2];
        cdvr_volume_window(v, w);
        CHECK(v->type == CDVR_TYPE_F32 && bad == 0 && nans == 21 && w[0] == lo && w[1] == hi,
              "fill -> NaN (%zu of 21), scale/offset (%zu differ), window [%g, %g]", nans, bad,
              w[0], w[1]);
        CHECK(v->source_type[0] && cdvr_volume_converted(v),
              "the conversion is reported: source_type '%s'", v->source_type);
        cdvr_volume_free(v);
    }
    snprintf(q, sizeof q, "%s:w", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "'time'") && strstr(err.msg, "place 2"),
          "time not first refused: %s", err.msg);
    snprintf(q, sizeof q, "%s:/u", p);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st == CDVR_OK && v->timesteps == 2, "/u (group path): %s",
          st == CDVR_OK ? "" : err.msg);
    cdvr_volume_free(v);
    /* max_bytes */
    cdvr_raw_opts o = {.max_bytes = 800};
    snprintf(q, sizeof q, "%s:u", p);
    st = cdvr_volume_load(q, &o, &v, &err);
    CHECK(st != CDVR_OK && !v && strstr(err.msg, "four.nc") && strstr(err.msg, "'u'") &&
          strstr(err.msg, "840 bytes") && strstr(err.msg, "max_bytes 800"), "claim above max_bytes refused: %s", err.msg);
    const cdvr_format *f = NULL;
    CHECK(cdvr_format_for(p, NULL, &f, &err) == CDVR_OK && f && strcmp(f->name, "netcdf") == 0,
          "netCDF-4 .nc goes to netcdf");
}

static void test_big_claim(void)
{
    char p[512];
    at(p, sizeof p, "big.nc");
    int nc, d[3], v;
    NC(nc_create(p, NC_CLOBBER | NC_NETCDF4, &nc));
    NC(nc_def_dim(nc, "z", 500, &d[0]));
    NC(nc_def_dim(nc, "y", 500, &d[1]));
    NC(nc_def_dim(nc, "x", 500, &d[2]));
    NC(nc_def_var(nc, "big", NC_USHORT, 3, d, &v));
    NC(nc_def_var_deflate(nc, v, 0, 1, 1));
    NC(nc_close(nc));
    cdvr_error err;
    cdvr_volume *vol = NULL, head;
    cdvr_raw_opts o = {.max_bytes = 1 << 20};
    cdvr_status st = cdvr_volume_load(p, &o, &vol, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "250000000 bytes") && strstr(err.msg, "max_bytes"),
          "a 500^3 u16 claim above max_bytes refused: %s", err.msg);
    st = cdvr_volume_probe(p, &o, &head, &err);
    CHECK(st == CDVR_OK && head.dims[2] == 500 && head.type == CDVR_TYPE_U16, "probe of it");
    /* a classic file whose header claims more than it holds: z's length patched 3 -> 2^20 */
    at(p, sizeof p, "claim.nc");
    write_classic(p, 0, 0);
    FILE *fh = fopen(p, "r+b");
    uint8_t hdr[256];
    size_t n = fread(hdr, 1, sizeof hdr, fh), patched = 0;
    static const uint8_t zdim[] = {0, 0, 0, 1, 'z', 0, 0, 0, 0, 0, 0, 3};
    for (size_t i = 0; i + sizeof zdim <= n && !patched; i++)
        if (memcmp(hdr + i, zdim, sizeof zdim) == 0) {
            fseek(fh, (long)(i + 8), SEEK_SET);
            fwrite((uint8_t[]){0, 0x10, 0, 0}, 1, 4, fh);
            patched = 1;
        }
    fclose(fh);
    CHECK(patched, "z's length found in the classic header");
    st = cdvr_volume_load(p, NULL, &vol, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "claim.nc"), "a header claiming more than the file "
          "refused: %s", err.msg);
    /* FIFO */
    at(p, sizeof p, "fifo.nc");
    CHECK(mkfifo(p, 0600) == 0, "mkfifo");
    st = cdvr_volume_load(p, NULL, &vol, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "fifo.nc") && strstr(err.msg, "FIFO"),
          "FIFO refused: %s", err.msg);
    const cdvr_format *f = cdvr_format_find("netcdf");
    char q[600];
    snprintf(q, sizeof q, "%s:u", p);
    st = f ? f->probe(q, NULL, &head, &err) : CDVR_ERR_ARG;
    CHECK(st != CDVR_OK && strstr(err.msg, "FIFO"), "FIFO:u probe refused: %s", err.msg);
}

/* probe reads the header only: a corrupt chunk of u is seen by load only. */
static void test_probe_header_only(void)
{
    char p[512], q[600];
    at(p, sizeof p, "corrupt.nc");
    write_nc4(p);
    hid_t fid = H5Fopen(p, H5F_ACC_RDONLY, H5P_DEFAULT);
    hid_t did = H5Dopen2(fid, "/u", H5P_DEFAULT);
    haddr_t addr = HADDR_UNDEF;
    hsize_t size = 0, off[4];
    unsigned mask;
    hid_t space = H5Dget_space(did);
    H5Dget_chunk_info(did, space, 0, off, &mask, &addr, &size);
    H5Sclose(space);
    H5Dclose(did);
    H5Fclose(fid);
    CHECK(addr != HADDR_UNDEF && size > 4, "chunk 0 found");
    FILE *w = fopen(p, "r+b");
    fseek(w, (long)addr, SEEK_SET);
    for (hsize_t i = 0; i < size; i++)
        fputc(0x5A, w);
    fclose(w);
    cdvr_error err;
    cdvr_volume head, *v = NULL;
    snprintf(q, sizeof q, "%s:u", p);
    cdvr_status st = cdvr_volume_probe(q, NULL, &head, &err);
    CHECK(st == CDVR_OK && head.timesteps == 2 && head.dims[0] == 5,
          "probe with a corrupt chunk: %s", st == CDVR_OK ? "ok" : err.msg);
    st = cdvr_volume_load(q, NULL, &v, &err);
    CHECK(st != CDVR_OK && !v && strstr(err.msg, "corrupt.nc") && strstr(err.msg, "'u'"),
          "load of it refused: %s", err.msg);
}


/* A file of `format` (NC_CLASSIC_MODEL-less flags: 0, NC_64BIT_OFFSET, NC_64BIT_DATA) with a
 * fixed variable f(z=2, y=3, x=4) float, and when recs > 0 an unlimited dimension with nrec
 * record variables r0.. (time, y=3, x=odd) short: the last record variable ends unpadded
 * (3 * odd * 2 bytes is not a multiple of 4) unless it is the only one (records packed). */
static void write_sized(const char *path, int format, size_t recs, int nrec, int odd)
{
    int nc, dt, dz, dy, dx, dxo, v;
    NC(nc_create(path, NC_CLOBBER | format, &nc));
    NC(nc_def_dim(nc, "z", 2, &dz));
    NC(nc_def_dim(nc, "y", 3, &dy));
    NC(nc_def_dim(nc, "x", 4, &dx));
    NC(nc_def_dim(nc, "xo", (size_t)odd, &dxo));
    float title = 1.5f;
    NC(nc_put_att_float(nc, NC_GLOBAL, "some_attribute", NC_FLOAT, 1, &title));
    NC(nc_put_att_text(nc, NC_GLOBAL, "title", 5, "sized"));
    int d3[3] = {dz, dy, dx};
    NC(nc_def_var(nc, "f", NC_FLOAT, 3, d3, &v));
    NC(nc_put_att_text(nc, v, "units", 1, "K"));
    if (recs) {
        NC(nc_def_dim(nc, "time", NC_UNLIMITED, &dt));
        int dr[3] = {dt, dy, dxo};
        for (int k = 0; k < nrec; k++) {
            char name[16];
            snprintf(name, sizeof name, "r%d", k);
            NC(nc_def_var(nc, name, NC_SHORT, 3, dr, &v));
        }
    }
    NC(nc_enddef(nc));
    float f[24];
    for (int i = 0; i < 24; i++)
        f[i] = (float)i;
    NC(nc_put_var_float(nc, 0, f));
    short r[64];
    for (int i = 0; i < 64; i++)
        r[i] = (short)(i + 1);
    for (int k = 0; k < nrec && recs; k++) {
        size_t start[3] = {0, 0, 0}, count[3] = {recs, 3, (size_t)odd};
        NC(nc_put_vara_short(nc, 1 + k, start, count, r));
    }
    NC(nc_close(nc));
}

/* Cuts `cut` bytes off the end of path. */
static void cut_file(const char *path, off_t cut)
{
    struct stat sb;
    CHECK(stat(path, &sb) == 0 && truncate(path, sb.st_size - cut) == 0, "truncate %s", path);
}

static void test_truncated(void)
{
    static const struct {
        const char *name;
        int format, nrec, odd;
        size_t recs;
    } cases[] = {
        {"cdf1 fixed", 0, 0, 5, 0},
        {"cdf2 two records", NC_64BIT_OFFSET, 2, 5, 3},
        {"cdf5 one record (packed)", NC_64BIT_DATA, 1, 5, 3},
        {"cdf1 two records, even", 0, 2, 4, 2},
    };
    char p[512], q[600];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        at(p, sizeof p, "sized.nc");
        write_sized(p, cases[i].format, cases[i].recs, cases[i].nrec, cases[i].odd);
        cdvr_error err;
        cdvr_volume *vol = NULL;
        snprintf(q, sizeof q, "%s:%s", p, cases[i].nrec ? "r0" : "f");
        cdvr_status st = cdvr_volume_load(q, NULL, &vol, &err);
        CHECK(st == CDVR_OK, "%s: the whole file loads: %s", cases[i].name, err.msg);
        if (st == CDVR_OK && cases[i].nrec)
            CHECK(vol->timesteps == cases[i].recs && cdvr_volume_get(vol, 0, 0, 0, 0) == 1 &&
                      cdvr_volume_get(vol, (size_t)cases[i].odd - 1, 2, 0, cases[i].recs - 1) ==
                          (double)(3 * cases[i].odd * cases[i].recs),
                  "%s: record values", cases[i].name);
        cdvr_volume_free(vol);
        /* the last item's padding may be missing (other writers); one byte of data may not */
        int pad = cases[i].nrec == 2 && cases[i].odd % 2 ? 2 : 0;
        if (pad) {
            cut_file(p, pad);
            vol = NULL;
            st = cdvr_volume_load(q, NULL, &vol, &err);
            CHECK(st == CDVR_OK, "%s: without the last padding loads: %s", cases[i].name, err.msg);
            cdvr_volume_free(vol);
        }
        cut_file(p, 1);
        vol = NULL;
        st = cdvr_volume_load(q, NULL, &vol, &err);
        CHECK(st == CDVR_ERR_FORMAT && !vol && strstr(err.msg, "sized.nc") &&
                  strstr(err.msg, "truncated") && strstr(err.msg, "header implies"),
              "%s: one byte short refused: %s", cases[i].name, st == CDVR_OK ? "loaded" : err.msg);
        cdvr_volume_free(vol);
        cdvr_volume head;
        st = cdvr_volume_probe(q, NULL, &head, &err);
        CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "truncated"), "%s: probe refuses too",
              cases[i].name);
        unlink(p);
    }
}

/* valid_range / valid_min / valid_max (stored units, before scale_factor) to NaN, and a
 * variable found in a subgroup when no name is given. */
static void test_valid_and_groups(void)
{
    char p[512];
    at(p, sizeof p, "valid.nc");
    int nc, dz, dy, dx, v, g, h;
    NC(nc_create(p, NC_CLOBBER | NC_NETCDF4, &nc));
    NC(nc_def_dim(nc, "z", 2, &dz));
    NC(nc_def_dim(nc, "y", 3, &dy));
    NC(nc_def_dim(nc, "x", 4, &dx));
    int d3[3] = {dz, dy, dx};
    NC(nc_def_grp(nc, "obs", &g));
    NC(nc_def_grp(g, "deep", &h));
    NC(nc_def_var(h, "a", NC_SHORT, 3, d3, &v)); /* the file's only 3D variable */
    short range[2] = {2, 20};
    double scale = 0.5;
    NC(nc_put_att_short(h, v, "valid_range", NC_SHORT, 2, range));
    NC(nc_put_att_double(h, v, "scale_factor", NC_DOUBLE, 1, &scale));
    int vm, vx;
    NC(nc_def_var(h, "m", NC_FLOAT, 1, &dx, &vm));
    NC(nc_def_var(h, "n", NC_FLOAT, 1, &dx, &vx));
    NC(nc_enddef(nc));
    short a[24];
    for (int i = 0; i < 24; i++)
        a[i] = (short)i;
    NC(nc_put_var_short(h, v, a));
    NC(nc_close(nc));
    cdvr_error err;
    cdvr_volume *vol = NULL;
    cdvr_status st = cdvr_volume_load(p, NULL, &vol, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        size_t bad = 0;
        for (int i = 0; i < 24; i++) {
            double got = cdvr_volume_get(vol, (size_t)i % 4, (size_t)i / 4 % 3, (size_t)i / 12, 0);
            bad += i < 2 || i > 20 ? !isnan(got) : got != 0.5 * i;
        }
        CHECK(bad == 0 && vol->type == CDVR_TYPE_F32, "subgroup /obs/deep/a: valid_range [2, 20] "
              "in stored units, scaled after: %zu voxels differ", bad);
        double w[2];
        cdvr_volume_window(vol, w);
        CHECK(w[0] == 1 && w[1] == 10, "window of the valid values [%g, %g]", w[0], w[1]);
    }
    cdvr_volume_free(vol);
    /* valid_min alone; a valid_max below valid_min refused */
    NC(nc_open(p, NC_WRITE, &nc));
    NC(nc_inq_grp_full_ncid(nc, "/obs/deep", &h));
    NC(nc_inq_varid(h, "a", &v));
    NC(nc_redef(nc));
    NC(nc_del_att(h, v, "valid_range"));
    short lo = 5;
    NC(nc_put_att_short(h, v, "valid_min", NC_SHORT, 1, &lo));
    NC(nc_close(nc));
    vol = NULL;
    st = cdvr_volume_load(p, NULL, &vol, &err);
    CHECK(st == CDVR_OK && isnan(cdvr_volume_get(vol, 0, 1, 0, 0)) &&
              cdvr_volume_get(vol, 1, 1, 0, 0) == 2.5 && cdvr_volume_get(vol, 3, 2, 1, 0) == 11.5,
          "valid_min 5: below NaN, the rest kept");
    cdvr_volume_free(vol);
    NC(nc_open(p, NC_WRITE, &nc));
    NC(nc_inq_grp_full_ncid(nc, "/obs/deep", &h));
    NC(nc_redef(nc));
    short hi = 4;
    NC(nc_put_att_short(h, v, "valid_max", NC_SHORT, 1, &hi));
    NC(nc_close(nc));
    vol = NULL;
    st = cdvr_volume_load(p, NULL, &vol, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "valid range [5, 4]") && strstr(err.msg, "/obs/deep/a"),
          "an empty valid range refused: %s", st == CDVR_OK ? "loaded" : err.msg);
    cdvr_volume_free(vol);
    /* a second 3D variable in another subgroup: several candidates listed with their paths */
    NC(nc_open(p, NC_WRITE, &nc));
    NC(nc_redef(nc));
    NC(nc_inq_dimid(nc, "z", &dz));
    NC(nc_inq_dimid(nc, "y", &dy));
    NC(nc_inq_dimid(nc, "x", &dx));
    int g2, d3b[3] = {dz, dy, dx};
    NC(nc_def_grp(nc, "other", &g2));
    NC(nc_def_var(g2, "b", NC_FLOAT, 3, d3b, &v));
    NC(nc_close(nc));
    vol = NULL;
    st = cdvr_volume_load(p, NULL, &vol, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "/obs/deep/a(") && strstr(err.msg, "/other/b("),
          "two candidates in subgroups listed with their paths: %s", st == CDVR_OK ? "loaded" : err.msg);
    cdvr_volume_free(vol);
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "--write") == 0) { /* tests/lua/test_hdf5_netcdf.lua */
        char p[4096];
        snprintf(p, sizeof p, "%s/lua.nc", argv[2]);
        write_nc4(p);
        snprintf(p, sizeof p, "%s/lua_classic.nc", argv[2]);
        write_classic(p, 0, 0);
        return 0;
    }
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_classic();
    test_nc4();
    test_big_claim();
    test_probe_header_only();
    test_truncated();
    test_valid_and_groups();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
    return check_finish();
}
