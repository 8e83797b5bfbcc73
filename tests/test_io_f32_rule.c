/* The one rule for values beyond f32 (core/io/volume_io.h, cdvr_raw_opts.f32_overflow_inf),
 * format by format: a float64 volume of 4x3x2 values holding two finite values beyond FLT_MAX
 * (1e300 at voxel (1,2,0), -1e39 at (3,0,1)) is written as NRRD, NIfTI (niftilib), VTI,
 * legacy VTK, MetaImage, TIFF (libtiff), HDF5 (libhdf5) and NetCDF (libnetcdf). Each load
 * without the option is refused naming the file, the first value, its voxel and the option;
 * with it the volume loads, those two voxels are +Inf and -Inf, the others the nearest float,
 * beyond_f32 is 2, the window is the finite range computed in double. A file whose values all
 * fit loads without the option, beyond_f32 0. A series (cdvr_volume_load_series) carries the
 * option and the count of both files. */
#include "check.h"
#include "cdvr/volume.h"

#include <float.h>
#include <hdf5.h>
#include <math.h>
#include <netcdf.h>
#include <nifti1_io.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <tiffio.h>
#include <unistd.h>

#define NX 4
#define NY 3
#define NZ 2
#define N (NX * NY * NZ)
#define HUGE_AT (1 + NX * 2)          /* (1,2,0) */
#define NEG_AT (3 + NX * NY * 1)      /* (3,0,1) */

static char dir_[64];
static double vals[N];

static const char *at(const char *name)
{
    static char p[4][256];
    static int k;
    k = (k + 1) % 4;
    snprintf(p[k], sizeof p[k], "%s/%s", dir_, name);
    return p[k];
}

static void fill(int beyond)
{
    for (int i = 0; i < N; i++)
        vals[i] = 0.1 * i - 1.25;
    if (beyond) {
        vals[HUGE_AT] = 1e300;
        vals[NEG_AT] = -1e39;
    }
}

static void put_file(const char *path, const char *head, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    fputs(head, f);
    if (data)
        fwrite(data, 1, n, f);
    fclose(f);
}

static void write_nrrd(const char *path)
{
    put_file(path, "NRRD0004\ntype: double\ndimension: 3\nsizes: 4 3 2\nendian: little\n"
                   "encoding: raw\n\n", vals, sizeof vals);
}

static void write_mha(const char *path)
{
    put_file(path, "ObjectType = Image\nNDims = 3\nDimSize = 4 3 2\nElementType = MET_DOUBLE\n"
                   "BinaryData = True\nBinaryDataByteOrderMSB = False\nElementDataFile = LOCAL\n",
             vals, sizeof vals);
}

static void write_vtk(const char *path)
{
    char head[256];
    snprintf(head, sizeof head, "# vtk DataFile Version 3.0\nf64\nASCII\nDATASET STRUCTURED_POINTS\n"
             "DIMENSIONS 4 3 2\nSPACING 1 1 1\nORIGIN 0 0 0\nPOINT_DATA %d\nSCALARS v double 1\n"
             "LOOKUP_TABLE default\n", N);
    FILE *f = fopen(path, "w");
    fputs(head, f);
    for (int i = 0; i < N; i++)
        fprintf(f, "%.17g\n", vals[i]);
    fclose(f);
}

static void write_vti(const char *path)
{
    FILE *f = fopen(path, "w");
    fputs("<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" "
          "byte_order=\"LittleEndian\">\n<ImageData WholeExtent=\"0 3 0 2 0 1\" Origin=\"0 0 0\" "
          "Spacing=\"1 1 1\">\n<Piece Extent=\"0 3 0 2 0 1\">\n<PointData Scalars=\"v\">\n"
          "<DataArray type=\"Float64\" Name=\"v\" format=\"ascii\">\n", f);
    for (int i = 0; i < N; i++)
        fprintf(f, "%.17g ", vals[i]);
    fputs("\n</DataArray>\n</PointData>\n</Piece>\n</ImageData>\n</VTKFile>\n", f);
    fclose(f);
}

static void write_nifti(const char *path)
{
    int dims[8] = {3, NX, NY, NZ, 1, 1, 1, 1};
    nifti_image *nim = nifti_make_new_nim(dims, DT_FLOAT64, 1);
    for (int i = 4; i < 8; i++)
        nim->dim[i] = 1;
    nifti_update_dims_from_array(nim);
    memcpy(nim->data, vals, sizeof vals);
    nifti_set_filenames(nim, path, 0, 1);
    nifti_image_write(nim);
    nifti_image_free(nim);
}

static void write_tiff(const char *path)
{
    TIFF *t = TIFFOpen(path, "w");
    for (int z = 0; z < NZ; z++) {
        TIFFSetField(t, TIFFTAG_IMAGEWIDTH, NX);
        TIFFSetField(t, TIFFTAG_IMAGELENGTH, NY);
        TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 64);
        TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_IEEEFP);
        TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
        TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
        TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, NY);
        TIFFSetField(t, TIFFTAG_SUBFILETYPE, FILETYPE_PAGE);
        TIFFSetField(t, TIFFTAG_PAGENUMBER, z, NZ);
        TIFFWriteEncodedStrip(t, 0, vals + z * NX * NY, NX * NY * sizeof(double));
        TIFFWriteDirectory(t);
    }
    TIFFClose(t);
}

static void write_hdf5(const char *path)
{
    hsize_t d[3] = {NZ, NY, NX};
    hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hid_t sp = H5Screate_simple(3, d, NULL);
    hid_t ds = H5Dcreate2(f, "v", H5T_IEEE_F64LE, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    H5Dwrite(ds, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, vals);
    H5Dclose(ds);
    H5Sclose(sp);
    H5Fclose(f);
}

static void write_netcdf(const char *path)
{
    int nc, dz, dy, dx, v;
    nc_create(path, NC_CLOBBER, &nc);
    nc_def_dim(nc, "z", NZ, &dz);
    nc_def_dim(nc, "y", NY, &dy);
    nc_def_dim(nc, "x", NX, &dx);
    int dims[3] = {dz, dy, dx};
    nc_def_var(nc, "v", NC_DOUBLE, 3, dims, &v);
    nc_enddef(nc);
    nc_put_var_double(nc, v, vals);
    nc_close(nc);
}

typedef struct fmt {
    const char *name, *file, *what;
    void (*write)(const char *path);
} fmt;

static const fmt FMTS[] = {
    {"nrrd", "f.nrrd", "NRRD value", write_nrrd},
    {"nifti", "f.nii", "NIfTI value", write_nifti},
    {"vti", "f.vti", "VTK value", write_vti},
    {"vtk", "f.vtk", "legacy VTK value", write_vtk},
    {"mha", "f.mha", "MetaImage value", write_mha},
    {"tiff", "f.tif", "TIFF value", write_tiff},
    {"hdf5", "f.h5", "HDF5 value", write_hdf5},
    {"netcdf", "f.nc", "NetCDF value", write_netcdf},
};

static void check_values(const fmt *f, const cdvr_volume *vol, int beyond)
{
    size_t bad = 0;
    for (int i = 0; i < N; i++) {
        double got = cdvr_volume_get(vol, i % NX, i / NX % NY, i / (NX * NY), 0);
        double want = beyond && i == HUGE_AT ? INFINITY : beyond && i == NEG_AT ? -INFINITY
                                                                                : (float)vals[i];
        bad += got != want;
    }
    CHECK(bad == 0, "%s: %zu voxels differ", f->name, bad);
    double w[2];
    cdvr_volume_window((cdvr_volume *)vol, w);
    double lo = beyond ? -1e39 : vals[0], hi = beyond ? 1e300 : vals[N - 1];
    CHECK(w[0] == lo && w[1] == hi, "%s: window [%g, %g], want [%g, %g]", f->name, w[0], w[1],
          lo, hi);
    CHECK(vol->beyond_f32 == (beyond ? 2u : 0u), "%s: beyond_f32 %llu", f->name,
          (unsigned long long)vol->beyond_f32);
    CHECK(strcmp(vol->source_type, "float64") == 0, "%s: source_type '%s'", f->name,
          vol->source_type);
}

static void check_format(const fmt *f)
{
    const char *path = at(f->file);
    cdvr_volume *vol = NULL;
    cdvr_error err;
    fill(0);
    f->write(path);
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK)
        check_values(f, vol, 0);
    cdvr_volume_free(vol);

    fill(1);
    f->write(path);
    vol = NULL;
    st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK(st == CDVR_ERR_FORMAT && !vol && strstr(err.msg, path) && strstr(err.msg, f->what) &&
              strstr(err.msg, "1e+300") && strstr(err.msg, "voxel (1,2,0) of timestep 0") &&
              strstr(err.msg, "(2 such values)") && strstr(err.msg, "float64") &&
              strstr(err.msg, "f32_overflow"),
          "%s: refused naming file, value, voxel and option: %s", f->name,
          st == CDVR_OK ? "loaded" : err.msg);
    cdvr_volume_free(vol);
    vol = NULL;
    cdvr_raw_opts inf = {.f32_overflow_inf = 1};
    st = cdvr_volume_load(path, &inf, &vol, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK)
        check_values(f, vol, 1);
    cdvr_volume_free(vol);
    /* a series of two such files: the option reaches each load; the counts add up */
    const char *paths[2] = {path, path};
    vol = NULL;
    st = cdvr_volume_load_series(paths, 2, &inf, &vol, &err);
    CHECK(st == CDVR_OK && vol->timesteps == 2 && vol->beyond_f32 == 4 &&
              isinf(cdvr_volume_get(vol, 1, 2, 0, 1)),
          "%s: series with f32_overflow: %s", f->name, st == CDVR_OK ? "wrong values" : err.msg);
    cdvr_volume_free(vol);
    vol = NULL;
    st = cdvr_volume_load_series(paths, 2, NULL, &vol, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "f32_overflow"), "%s: series refused: %s",
          f->name, st == CDVR_OK ? "loaded" : err.msg);
    cdvr_volume_free(vol);
    unlink(path);
}

int main(void)
{
    snprintf(dir_, sizeof dir_, "/tmp/cdvr_f32_rule_XXXXXX");
    if (!mkdtemp(dir_))
        return 1;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    for (size_t i = 0; i < sizeof FMTS / sizeof FMTS[0]; i++)
        check_format(&FMTS[i]);
    rmdir(dir_);
    return check_finish();
}
