/* tests/test_series_dir.c - series from a directory, a glob pattern and a .pvd collection
 * (cdvr/series.h, cdvr/pvd.h), TIFF directories as stacks and OME-TIFF spacing (cdvr/tiff.h),
 * source_type reporting (cdvr/volume.h):
 *  - a directory of t1.nrrd, t2.nrrd, t10.nrrd and the glob "DIR/t*.nrrd" load in natural order
 *    (t1, t2, t10: voxel values per timestep); a hidden file is skipped; a directory of two
 *    formats and an empty directory are refused;
 *  - a .pvd of three .vti files keeps the timestep values; a .pvd naming ../outside.vti is
 *    refused;
 *  - cdvr_volume_load of a directory of TIFF pages is their stack; an OME-TIFF's
 *    PhysicalSizeX/Y/Z (with units) give its spacing;
 *  - a float64 NRRD reports source_type "float64" and cdvr_volume_converted;
 *  - cdvr_volume_load of a directory no format reads says so. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>

#include "cdvr/series.h"
#include "cdvr/volume.h"
#include "check.h"

static char dir[] = "/tmp/cdvr_test_series_dir_XXXXXX";

static const char *tmp(const char *name)
{
    static char paths[8][512];
    static int next;
    char *p = paths[next++ % 8];
    snprintf(p, sizeof paths[0], "%s/%s", dir, name);
    return p;
}

static void write_file(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    CHECK(f && fwrite(data, 1, n, f) == n, "write %s", path);
    if (f)
        fclose(f);
}

static void write_text(const char *path, const char *text)
{
    write_file(path, text, strlen(text));
}

/* A 2x2x2 uchar NRRD with every voxel v. */
static void write_nrrd_u8(const char *path, uint8_t v)
{
    static const char hdr[] = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                              "encoding: raw\n\n";
    uint8_t file[sizeof hdr - 1 + 8];
    memcpy(file, hdr, sizeof hdr - 1);
    memset(file + sizeof hdr - 1, v, 8);
    write_file(path, file, sizeof file);
}

/* A 2x2x2 ASCII .vti of Float32 values v. */
static void write_vti(const char *path, double v)
{
    char text[1024];
    snprintf(text, sizeof text,
             "<?xml version=\"1.0\"?>\n"
             "<VTKFile type=\"ImageData\" version=\"1.0\" byte_order=\"LittleEndian\">\n"
             "  <ImageData WholeExtent=\"0 1 0 1 0 1\" Origin=\"0 0 0\" Spacing=\"1 1 1\">\n"
             "  <Piece Extent=\"0 1 0 1 0 1\">\n    <PointData Scalars=\"a\">\n"
             "      <DataArray type=\"Float32\" Name=\"a\" format=\"ascii\">\n"
             "        %g %g %g %g %g %g %g %g\n      </DataArray>\n"
             "    </PointData>\n    <CellData>\n    </CellData>\n  </Piece>\n  </ImageData>\n"
             "</VTKFile>\n",
             v, v, v, v, v, v, v, v);
    write_text(path, text);
}

static void mkdir_(const char *path)
{
    CHECK(mkdir(path, 0755) == 0, "mkdir %s", path);
}

/* ---- directories and globs ------------------------------------------------------------------ */

static void check_t1_t2_t10(const cdvr_volume *v, const char *what)
{
    CHECK(v && v->timesteps == 3 && v->dims[0] == 2, "%s: 3 timesteps", what);
    if (!v || v->timesteps != 3)
        return;
    CHECK(cdvr_volume_get(v, 1, 1, 1, 0) == 1 && cdvr_volume_get(v, 0, 0, 0, 1) == 2 &&
              cdvr_volume_get(v, 1, 0, 1, 2) == 10,
          "%s: natural order t1, t2, t10 (got %g %g %g)", what, cdvr_volume_get(v, 1, 1, 1, 0),
          cdvr_volume_get(v, 0, 0, 0, 1), cdvr_volume_get(v, 1, 0, 1, 2));
}

static void test_dir_and_glob(void)
{
    mkdir_(tmp("nat"));
    write_nrrd_u8(tmp("nat/t10.nrrd"), 10);
    write_nrrd_u8(tmp("nat/t2.nrrd"), 2);
    write_nrrd_u8(tmp("nat/t1.nrrd"), 1);
    write_nrrd_u8(tmp("nat/.hidden.nrrd"), 99); /* skipped */
    cdvr_error err;
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load_series_path(tmp("nat"), NULL, &v, &err), err);
    check_t1_t2_t10(v, "directory");
    cdvr_volume_free(v);
    v = NULL;
    CHECK_OK(cdvr_volume_load_series_path(tmp("nat/t*.nrrd"), NULL, &v, &err), err);
    check_t1_t2_t10(v, "glob");
    cdvr_volume_free(v);

    char **names = NULL;
    size_t n = 0;
    CHECK_OK(cdvr_series_dir(tmp("nat"), &names, &n, &err), err);
    CHECK(n == 3 && names && strstr(names[0], "t1.nrrd") && strstr(names[2], "t10.nrrd"),
          "cdvr_series_dir: 3 names, hidden skipped, natural order");
    for (size_t i = 0; i < n; i++)
        free(names[i]);
    free(names);

    cdvr_series *s = NULL;
    CHECK_OK(cdvr_series_open_path(tmp("nat"), NULL, &s, &err), err);
    if (s) {
        CHECK(cdvr_series_get_info(s)->timesteps == 3 && cdvr_series_get_info(s)->files == 3,
              "series of the directory: 3 files");
        CHECK(cdvr_series_times(s) == NULL, "no times for a plain directory");
        cdvr_series_close(s);
    }

    CHECK(cdvr_series_natural_cmp("t2", "t10") < 0 && cdvr_series_natural_cmp("t10", "t9") > 0 &&
              cdvr_series_natural_cmp("slice9", "slice10") < 0,
          "natural_cmp");

    /* mixed formats */
    mkdir_(tmp("mixed"));
    write_nrrd_u8(tmp("mixed/a1.nrrd"), 1);
    write_vti(tmp("mixed/a2.vti"), 2);
    v = NULL;
    cdvr_status st = cdvr_volume_load_series_path(tmp("mixed"), NULL, &v, &err);
    CHECK(st != CDVR_OK && v == NULL && strstr(err.msg, "mixed") && strstr(err.msg, "nrrd") &&
              strstr(err.msg, "vti"),
          "mixed formats refused: %s", err.msg);
    cdvr_volume_free(v);

    /* empty */
    mkdir_(tmp("empty"));
    v = NULL;
    st = cdvr_volume_load_series_path(tmp("empty"), NULL, &v, &err);
    CHECK(st != CDVR_OK && v == NULL && strstr(err.msg, "empty"), "empty directory refused: %s",
          err.msg);
    cdvr_volume_free(v);

    /* a glob matching nothing */
    v = NULL;
    st = cdvr_volume_load_series_path(tmp("nat/zz*.nrrd"), NULL, &v, &err);
    CHECK(st != CDVR_OK && v == NULL && strstr(err.msg, "zz*"), "glob matching nothing: %s",
          err.msg);
    cdvr_volume_free(v);
}

/* ---- .pvd ----------------------------------------------------------------------------------- */

static void test_pvd(void)
{
    mkdir_(tmp("pvd"));
    mkdir_(tmp("pvd/run"));
    write_vti(tmp("pvd/run/a.vti"), 3);
    write_vti(tmp("pvd/run/b.vti"), 4);
    write_vti(tmp("pvd/run/c.vti"), 5);
    write_text(tmp("pvd/run.pvd"),
               "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n"
               "  <Collection>\n"
               "    <DataSet timestep=\"1.5\" part=\"0\" file=\"run/b.vti\"/>\n"
               "    <DataSet timestep=\"0.5\" part=\"0\" file=\"run/a.vti\"/>\n"
               "    <DataSet timestep=\"2.5\" part=\"0\" file=\"run/c.vti\"/>\n"
               "  </Collection>\n</VTKFile>\n");
    cdvr_error err;
    cdvr_series *s = NULL;
    CHECK_OK(cdvr_series_open_path(tmp("pvd/run.pvd"), NULL, &s, &err), err);
    if (s) {
        const cdvr_series_info *in = cdvr_series_get_info(s);
        const double *t = cdvr_series_times(s);
        CHECK(in->timesteps == 3 && t && t[0] == 0.5 && t[1] == 1.5 && t[2] == 2.5,
              "pvd times kept (in timestep order)");
        cdvr_volume *v = NULL;
        CHECK_OK(cdvr_series_read(s, 0, 3, &v, &err), err);
        CHECK(v && cdvr_volume_get(v, 0, 0, 0, 0) == 3 && cdvr_volume_get(v, 0, 0, 0, 1) == 4 &&
                  cdvr_volume_get(v, 0, 0, 0, 2) == 5,
              "pvd files in timestep order");
        cdvr_volume_free(v);
        cdvr_series_close(s);
    }
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load_series_path(tmp("pvd/run.pvd"), NULL, &v, &err), err);
    CHECK(v && v->timesteps == 3, "pvd loaded into memory");
    cdvr_volume_free(v);

    /* a directory holding a .pvd next to its .vti files loads through the .pvd (its order and
     * times), not refused as mixed; two .pvd files are refused naming the count */
    mkdir_(tmp("pvddir"));
    write_vti(tmp("pvddir/a.vti"), 3);
    write_vti(tmp("pvddir/b.vti"), 4);
    write_vti(tmp("pvddir/c.vti"), 5);
    write_text(tmp("pvddir/run.pvd"),
               "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n"
               "  <Collection>\n"
               "    <DataSet timestep=\"7\" part=\"0\" file=\"c.vti\"/>\n"
               "    <DataSet timestep=\"9\" part=\"0\" file=\"a.vti\"/>\n"
               "  </Collection>\n</VTKFile>\n");
    s = NULL;
    CHECK_OK(cdvr_series_open_path(tmp("pvddir"), NULL, &s, &err), err);
    if (s) {
        const double *t = cdvr_series_times(s);
        cdvr_volume *w = NULL;
        CHECK_OK(cdvr_series_read(s, 0, 2, &w, &err), err);
        CHECK(cdvr_series_get_info(s)->timesteps == 2 && t && t[0] == 7 && t[1] == 9 && w &&
                  cdvr_volume_get(w, 0, 0, 0, 0) == 5 && cdvr_volume_get(w, 0, 0, 0, 1) == 3,
              "a directory with a .pvd: the .pvd's two datasets in its order, times kept");
        cdvr_volume_free(w);
        cdvr_series_close(s);
    }
    write_text(tmp("pvddir/other.pvd"),
               "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n"
               "  <Collection>\n    <DataSet timestep=\"1\" part=\"0\" file=\"b.vti\"/>\n"
               "  </Collection>\n</VTKFile>\n");
    s = NULL;
    cdvr_status st_two = cdvr_series_open_path(tmp("pvddir"), NULL, &s, &err);
    CHECK(st_two == CDVR_ERR_FORMAT && !s && strstr(err.msg, "2 pvd collections") &&
              strstr(err.msg, "pvddir"), "two .pvd files refused: %s", err.msg);
    cdvr_series_close(s);

    write_vti(tmp("outside.vti"), 7);
    write_text(tmp("pvd/bad.pvd"),
               "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\">\n"
               "  <Collection>\n"
               "    <DataSet timestep=\"0\" part=\"0\" file=\"../outside.vti\"/>\n"
               "  </Collection>\n</VTKFile>\n");
    s = NULL;
    cdvr_status st = cdvr_series_open_path(tmp("pvd/bad.pvd"), NULL, &s, &err);
    CHECK(st != CDVR_OK && s == NULL && strstr(err.msg, "outside.vti"),
          "pvd naming ../outside.vti refused: %s", err.msg);
    cdvr_series_close(s);
    /* allowed when the caller says so (a raw_opts of zero dims only carries the option) */
    cdvr_raw_opts o;
    memset(&o, 0, sizeof o);
    o.allow_outside = 1;
    s = NULL;
    CHECK_OK(cdvr_series_open_path(tmp("pvd/bad.pvd"), &o, &s, &err), err);
    CHECK(s && cdvr_series_get_info(s)->timesteps == 1, "allow_outside opens ../outside.vti");
    cdvr_series_close(s);
}

/* ---- TIFF ----------------------------------------------------------------------------------- */

/* A one-page 4x3 uint16 TIFF with every pixel v, and description desc (may be NULL). */
static void write_tiff_page(const char *path, uint16_t v, const char *desc)
{
    TIFF *t = TIFFOpen(path, "w");
    CHECK(t != NULL, "TIFFOpen %s", path);
    if (!t)
        return;
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, 4);
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, 3);
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
    TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_UINT);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(t, TIFFTAG_COMPRESSION, COMPRESSION_NONE);
    TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, 3);
    if (desc)
        TIFFSetField(t, TIFFTAG_IMAGEDESCRIPTION, desc);
    uint16_t row[4] = {v, v, v, v};
    for (uint32_t y = 0; y < 3; y++)
        TIFFWriteScanline(t, row, y, 0);
    TIFFClose(t);
}

static void test_tiff(void)
{
    mkdir_(tmp("stack"));
    write_tiff_page(tmp("stack/slice10.tif"), 300, NULL);
    write_tiff_page(tmp("stack/slice2.tif"), 200, NULL);
    write_tiff_page(tmp("stack/slice1.tif"), 100, NULL);
    cdvr_error err;
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load(tmp("stack"), NULL, &v, &err), err);
    CHECK(v && v->dims[0] == 4 && v->dims[1] == 3 && v->dims[2] == 3 && v->type == CDVR_TYPE_U16,
          "TIFF directory: a 4x3x3 u16 stack");
    if (v && v->dims[2] == 3)
        CHECK(cdvr_volume_get(v, 0, 0, 0, 0) == 100 && cdvr_volume_get(v, 3, 2, 1, 0) == 200 &&
                  cdvr_volume_get(v, 1, 1, 2, 0) == 300,
              "TIFF directory in natural slice order");
    CHECK(v && strcmp(v->source_type, "uint16") == 0 && !cdvr_volume_converted(v),
          "TIFF stack source_type uint16, not converted");
    cdvr_volume_free(v);

    /* a directory of stack directories: a series, one stack per timestep */
    mkdir_(tmp("lapse"));
    mkdir_(tmp("lapse/t1"));
    mkdir_(tmp("lapse/t2"));
    mkdir_(tmp("lapse/t10"));
    static const char *const sub[3] = {"lapse/t1", "lapse/t2", "lapse/t10"};
    for (int i = 0; i < 3; i++) {
        char name[64];
        for (int z = 0; z < 2; z++) {
            snprintf(name, sizeof name, "%s/s%d.tif", sub[i], z);
            write_tiff_page(tmp(name), (uint16_t)(10 * (i + 1) + z), NULL);
        }
    }
    v = NULL;
    CHECK_OK(cdvr_volume_load_series_path(tmp("lapse"), NULL, &v, &err), err);
    CHECK(v && v->timesteps == 3 && v->dims[2] == 2 && cdvr_volume_get(v, 0, 0, 1, 0) == 11 &&
              cdvr_volume_get(v, 0, 0, 0, 1) == 20 && cdvr_volume_get(v, 0, 0, 1, 2) == 31,
          "a directory of TIFF stack directories: 3 timesteps in natural order");
    cdvr_volume_free(v);

    /* OME-TIFF: 3 pages, PhysicalSize in nm / um / mm */
    static const char ome[] =
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>"
        "<OME xmlns=\"http://www.openmicroscopy.org/Schemas/OME/2016-06\">"
        "<Image ID=\"Image:0\"><Pixels ID=\"Pixels:0\" DimensionOrder=\"XYZCT\" Type=\"uint16\" "
        "SizeX=\"4\" SizeY=\"3\" SizeZ=\"3\" SizeC=\"1\" SizeT=\"1\" "
        "PhysicalSizeX=\"500\" PhysicalSizeXUnit=\"nm\" PhysicalSizeY=\"0.25\" "
        "PhysicalSizeZ=\"0.002\" PhysicalSizeZUnit=\"mm\">"
        "<Channel ID=\"Channel:0:0\" SamplesPerPixel=\"1\"/></Pixels></Image></OME>";
    TIFF *t = TIFFOpen(tmp("cells.ome.tif"), "w");
    CHECK(t != NULL, "TIFFOpen ome");
    for (int p = 0; t && p < 3; p++) {
        TIFFSetField(t, TIFFTAG_IMAGEWIDTH, 4);
        TIFFSetField(t, TIFFTAG_IMAGELENGTH, 3);
        TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
        TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, SAMPLEFORMAT_UINT);
        TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
        TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
        TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, 3);
        if (p == 0)
            TIFFSetField(t, TIFFTAG_IMAGEDESCRIPTION, ome);
        TIFFSetField(t, TIFFTAG_SUBFILETYPE, FILETYPE_PAGE);
        TIFFSetField(t, TIFFTAG_PAGENUMBER, p, 3);
        uint16_t row[4] = {(uint16_t)p, (uint16_t)p, (uint16_t)p, (uint16_t)p};
        for (uint32_t y = 0; y < 3; y++)
            TIFFWriteScanline(t, row, y, 0);
        TIFFWriteDirectory(t);
    }
    if (t)
        TIFFClose(t);
    v = NULL;
    CHECK_OK(cdvr_volume_load(tmp("cells.ome.tif"), NULL, &v, &err), err);
    CHECK(v && v->dims[2] == 3 && fabs(v->spacing[0] - 0.5) < 1e-9 &&
              fabs(v->spacing[1] - 0.25) < 1e-9 && fabs(v->spacing[2] - 2.0) < 1e-9,
          "OME-TIFF spacing in micrometres (got %g %g %g)", v ? v->spacing[0] : 0,
          v ? v->spacing[1] : 0, v ? v->spacing[2] : 0);
    cdvr_volume_free(v);
}

/* ---- source_type ---------------------------------------------------------------------------- */

static void test_source_type(void)
{
    static const char hdr[] = "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 1 1\n"
                              "endian: little\nencoding: raw\n\n";
    unsigned char file[sizeof hdr - 1 + 16];
    memcpy(file, hdr, sizeof hdr - 1);
    double vals[2] = {0.25, 1e10};
    unsigned char *p = file + sizeof hdr - 1;
    for (int i = 0; i < 2; i++) { /* little endian, whatever the host */
        uint64_t b;
        memcpy(&b, &vals[i], 8);
        for (int k = 0; k < 8; k++)
            p[8 * i + k] = (unsigned char)(b >> (8 * k));
    }
    write_file(tmp("f64.nrrd"), file, sizeof file);
    cdvr_error err;
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load(tmp("f64.nrrd"), NULL, &v, &err), err);
    CHECK(v && v->type == CDVR_TYPE_F32 && strcmp(v->source_type, "float64") == 0 &&
              cdvr_volume_converted(v),
          "f64 NRRD: source_type float64, converted (got '%s')", v ? v->source_type : "");
    cdvr_volume_free(v);

    v = NULL;
    write_nrrd_u8(tmp("u8.nrrd"), 5);
    CHECK_OK(cdvr_volume_load(tmp("u8.nrrd"), NULL, &v, &err), err);
    CHECK(v && strcmp(v->source_type, "uint8") == 0 && !cdvr_volume_converted(v),
          "u8 NRRD: source_type uint8, not converted (got '%s')", v ? v->source_type : "");
    cdvr_volume_free(v);

    cdvr_series *s = NULL;
    const char *paths[1] = {tmp("f64.nrrd")};
    CHECK_OK(cdvr_series_open(paths, 1, NULL, &s, &err), err);
    CHECK(s && strcmp(cdvr_series_get_info(s)->source_type, "float64") == 0,
          "series source_type float64");
    cdvr_series_close(s);
}

/* ---- a directory no format reads ------------------------------------------------------------ */

static void test_plain_dir(void)
{
    mkdir_(tmp("plain"));
    write_text(tmp("plain/notes.txt"), "nothing to see\n");
    cdvr_error err;
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_load(tmp("plain"), NULL, &v, &err);
    CHECK(st != CDVR_OK && v == NULL && strstr(err.msg, "is a directory that no format reads") &&
              strstr(err.msg, "plain"),
          "plain directory refused: %s", err.msg);
    cdvr_volume_free(v);
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_dir_and_glob();
    test_pvd();
    test_tiff();
    test_source_type();
    test_plain_dir();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return check_finish();
}
