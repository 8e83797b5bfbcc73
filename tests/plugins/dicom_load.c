/* tests/plugins/dicom_load.c - the DICOM plugin (plugins/dicom) through cdvr's C API:
 * cdvr_plugin_load of build/plugins/cdvr_dicom.so, then cdvr_volume_load / cdvr_volume_probe of
 * the series tests/plugins/dicom_write.cpp wrote with GDCM (usage: test_dicom_load DIR; run by
 * tests/test_dicom.sh). Proves: a directory is found by accepts_dir and its slices sorted by
 * position whatever the file names; dims (5x7 pixels, 3..9 slices), spacing (PixelSpacing's
 * two values in DICOM order: rows then columns), origin and the oblique direction [r c r x c]
 * as ITK gives them; every voxel value after RescaleSlope/Intercept, as i16 where the header says
 * it fits and f32 otherwise; JPEG-LS decoded to the same voxels; two series in one directory
 * chosen by SeriesInstanceUID or SeriesDescription and refused without select listing both; a
 * .dcm file opens its own series; a description two series share refused (the UID then works);
 * multi-frame files (an Enhanced CT file's frames with their functional groups, a multi-frame
 * secondary capture without geometry) as slices; MONOCHROME1 inverted; a gantry tilt kept as
 * a sheared grid; uneven slices, slices off one line, a missing PixelSpacing, a Rows claim
 * larger than the file, max_bytes,
 * a FIFO, a symlink out of the directory and a directory without DICOM files refused, each
 * naming what is wrong; 48 mutated copies of a slice never end this process (GDCM, which
 * asserts on some of them, runs in the plugin's helper process).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cdvr/format.h"
#include "cdvr/plugin.h"
#include "cdvr/volume.h"
#include "check.h"

static const char *root;

static const char *at(const char *rel)
{
    static char buf[4][4096];
    static int i;
    i = (i + 1) % 4;
    snprintf(buf[i], sizeof buf[i], "%s/%s", root, rel);
    return buf[i];
}

static int near(double a, double b)
{
    return fabs(a - b) <= 1e-6 * (1 + fabs(b));
}

/* The oblique case's geometry (dicom_write.cpp) and values. */
static void check_oblique(const cdvr_volume *v, const char *what)
{
    const double a = 0.5, b = 0.3;
    const double r[3] = {cos(a), sin(a), 0}, c[3] = {-sin(a) * cos(b), cos(a) * cos(b), sin(b)};
    const double n[3] = {r[1] * c[2] - r[2] * c[1], r[2] * c[0] - r[0] * c[2],
                         r[0] * c[1] - r[1] * c[0]};
    CHECK(v->dims[0] == 5 && v->dims[1] == 7 && v->dims[2] == 9 && v->timesteps == 1, "%s dims",
          what);
    CHECK(v->type == CDVR_TYPE_I16, "%s: i16 (slope 2, intercept -1024, 12 bits): %s", what,
          cdvr_type_name(v->type));
    CHECK(near(v->spacing[0], 0.7) && near(v->spacing[1], 0.9) && near(v->spacing[2], 1.3),
          "%s spacing %g %g %g", what, v->spacing[0], v->spacing[1], v->spacing[2]);
    CHECK(near(v->origin[0], -20.5) && near(v->origin[1], 10.25) && near(v->origin[2], 30),
          "%s origin %g %g %g", what, v->origin[0], v->origin[1], v->origin[2]);
    int dir_ok = 1;
    for (int i = 0; i < 3; i++)
        dir_ok &= near(v->direction[3 * i], r[i]) && near(v->direction[3 * i + 1], c[i]) &&
                  near(v->direction[3 * i + 2], n[i]);
    CHECK(dir_ok, "%s direction columns r, c, r x c", what);
    size_t bad = 0;
    for (unsigned k = 0; k < 9; k++)
        for (unsigned y = 0; y < 7; y++)
            for (unsigned x = 0; x < 5; x++) {
                int stored = (int)((3 * (x + 5 * y + 35 * k)) % 4096);
                bad += cdvr_volume_get(v, x, y, k, 0) != 2.0 * stored - 1024;
            }
    CHECK(bad == 0, "%s: %zu voxels differ from 2 * stored - 1024", what, bad);
}

static void test_series(void)
{
    cdvr_error err;
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load(at("oblique"), NULL, &v, &err), err);
    if (v)
        check_oblique(v, "oblique/");
    cdvr_volume_free(v);
    v = NULL;
    cdvr_volume head;
    memset(&head, 0, sizeof head);
    CHECK_OK(cdvr_volume_probe(at("oblique"), NULL, &head, &err), err);
    CHECK(head.dims[2] == 9 && head.type == CDVR_TYPE_I16 && !head.data, "probe");
    CHECK_OK(cdvr_volume_load(at("oblique/f5.dcm"), NULL, &v, &err), err);
    if (v)
        check_oblique(v, "oblique/f5.dcm (its series)");
    cdvr_volume_free(v);
    v = NULL;
    CHECK_OK(cdvr_volume_load(at("jpegls"), NULL, &v, &err), err);
    if (v)
        check_oblique(v, "jpegls/ (JPEG-LS lossless)");
    cdvr_volume_free(v);
    v = NULL;

    CHECK_OK(cdvr_volume_load(at("float"), NULL, &v, &err), err);
    if (v) {
        CHECK(v->type == CDVR_TYPE_F32 && v->dims[2] == 3, "float/: f32 (slope 0.5)");
        size_t bad = 0;
        for (unsigned k = 0; k < 3; k++)
            for (unsigned y = 0; y < 7; y++)
                for (unsigned x = 0; x < 5; x++)
                    bad += cdvr_volume_get(v, x, y, k, 0) != 0.5 * (x + 5 * y + 35 * k) + 0.25;
        CHECK(bad == 0, "float/: %zu voxels differ", bad);
    }
    cdvr_volume_free(v);
}

static void test_select(void)
{
    cdvr_error err;
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_load(at("two"), NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "holds 2 DICOM series") &&
              strstr(err.msg, "1.2.826.0.1.3680043.9.7777.3 'axial' 3 slices 5x7x3") &&
              strstr(err.msg, "1.2.826.0.1.3680043.9.7777.4 'sagittal' 4 slices 6x4x4"),
          "two series without select: %s", err.msg);
    cdvr_raw_opts o;
    memset(&o, 0, sizeof o);
    o.select = "axial";
    CHECK_OK(cdvr_volume_load(at("two"), &o, &v, &err), err);
    if (v) {
        size_t bad = 0;
        for (unsigned k = 0; k < 3; k++)
            for (unsigned y = 0; y < 7; y++)
                for (unsigned x = 0; x < 5; x++)
                    bad += cdvr_volume_get(v, x, y, k, 0) != 100 + x + 5 * y + 35 * k;
        CHECK(v->type == CDVR_TYPE_U16 && v->dims[0] == 5 && v->dims[2] == 3 && bad == 0 &&
                  near(v->spacing[2], 2),
              "select by description: u16, %zu voxels differ", bad);
    }
    cdvr_volume_free(v);
    v = NULL;
    o.select = "1.2.826.0.1.3680043.9.7777.4";
    CHECK_OK(cdvr_volume_load(at("two"), &o, &v, &err), err);
    if (v) {
        size_t bad = 0;
        for (unsigned k = 0; k < 4; k++)
            for (unsigned y = 0; y < 4; y++)
                for (unsigned x = 0; x < 6; x++)
                    bad += cdvr_volume_get(v, x, y, k, 0) != -500 + 7.0 * x + 11 * y + 13 * k;
        /* r = (0,1,0), c = (0,0,-1): n = r x c = (-1,0,0) */
        CHECK(v->type == CDVR_TYPE_I16 && v->dims[0] == 6 && v->dims[1] == 4 &&
                  v->dims[2] == 4 && bad == 0 && near(v->spacing[2], 3) &&
                  near(v->origin[0], 5) && near(v->origin[1], -3) && near(v->origin[2], 8) &&
                  near(v->direction[1], 0) && near(v->direction[3], 1) &&
                  near(v->direction[7], -1) && near(v->direction[2], -1),
              "select by UID: signed i16 sagittal, %zu voxels differ", bad);
    }
    cdvr_volume_free(v);
    v = NULL;
    CHECK_OK(cdvr_volume_load(at("two/s1.dcm"), NULL, &v, &err), err);
    CHECK(v && v->dims[0] == 6 && v->dims[2] == 4, "a .dcm file opens its own series");
    cdvr_volume_free(v);
    v = NULL;
    o.select = "coronal";
    st = cdvr_volume_load(at("two"), &o, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "no DICOM series 'coronal'") &&
              strstr(err.msg, "'axial'") && strstr(err.msg, "'sagittal'"),
          "unknown select: %s", err.msg);
}

/* Multi-frame files, MONOCHROME1 and a gantry tilt (dicom_write.cpp's enhanced/, mfsc/, mono1/,
 * tilt/). */
static void test_frames_and_more(void)
{
    cdvr_error err;
    cdvr_volume *v = NULL;
    /* Enhanced CT: per-frame positions, shared orientation / spacing / rescale */
    CHECK_OK(cdvr_volume_load(at("enhanced"), NULL, &v, &err), err);
    if (v)
        check_oblique(v, "enhanced/ (9 frames of one file)");
    cdvr_volume_free(v);
    v = NULL;
    CHECK_OK(cdvr_volume_load(at("enhanced/multi.dcm"), NULL, &v, &err), err);
    if (v)
        check_oblique(v, "enhanced/multi.dcm");
    cdvr_volume_free(v);
    v = NULL;
    /* a multi-frame secondary capture without geometry: frames stacked 1 mm apart */
    CHECK_OK(cdvr_volume_load(at("mfsc"), NULL, &v, &err), err);
    if (v) {
        size_t bad = 0;
        for (unsigned k = 0; k < 4; k++)
            for (unsigned y = 0; y < 7; y++)
                for (unsigned x = 0; x < 5; x++)
                    bad += cdvr_volume_get(v, x, y, k, 0) != x + 5 * y + 35 * k;
        CHECK(v->type == CDVR_TYPE_U16 && v->dims[2] == 4 && bad == 0 && v->spacing[2] == 1 &&
                  v->origin[0] == 0 && v->direction[0] == 1 && v->direction[8] == 1,
              "mfsc/: 4 frames as slices, identity geometry, %zu voxels differ", bad);
    }
    cdvr_volume_free(v);
    v = NULL;
    /* MONOCHROME1 (12 bits stored): inverted by GDCM's filter as ITK does, then rescaled */
    CHECK_OK(cdvr_volume_load(at("mono1"), NULL, &v, &err), err);
    if (v) {
        size_t bad = 0;
        for (unsigned k = 0; k < 3; k++)
            for (unsigned y = 0; y < 7; y++)
                for (unsigned x = 0; x < 5; x++)
                    bad += cdvr_volume_get(v, x, y, k, 0) !=
                           0.5 * (4095.0 - (x + 5 * y + 35 * k)) + 0.25;
        CHECK(bad == 0, "mono1/: %zu voxels differ from 0.5 (4095 - stored) + 0.25", bad);
    }
    cdvr_volume_free(v);
    v = NULL;
    /* a gantry tilt: slice k shifted 2k mm along the rows, gap 1 along the normal: kept as a
     * sheared grid (third axis along the slice step (2, 0, 1) / sqrt 5, spacing sqrt 5) */
    CHECK_OK(cdvr_volume_load(at("tilt"), NULL, &v, &err), err);
    if (v) {
        double s5 = sqrt(5.0), ijk[3] = {4, 6, 2}, w[3];
        cdvr_volume_index_to_world(v, ijk, w);
        CHECK(near(v->spacing[2], s5) && near(v->direction[2], 2 / s5) &&
                  near(v->direction[5], 0) && near(v->direction[8], 1 / s5) &&
                  near(w[0], 4 + 4) && near(w[1], 6) && near(w[2], 2),
              "tilt/: sheared z axis (%g %g %g), spacing %g, voxel (4,6,2) at %g %g %g",
              v->direction[2], v->direction[5], v->direction[8], v->spacing[2], w[0], w[1], w[2]);
        CHECK(cdvr_volume_get(v, 4, 6, 2, 0) == 0.5 * (4 + 30 + 70) + 0.25, "tilt/ values");
    }
    cdvr_volume_free(v);
}

static void test_refusals(void)
{
    cdvr_error err;
    cdvr_volume *v = NULL;
    cdvr_status st = cdvr_volume_load(at("uneven"), NULL, &v, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "uneven slice spacing") &&
              strstr(err.msg, "f3.dcm and") && strstr(err.msg, "f2.dcm are") &&
              strstr(err.msg, "1.5 mm apart"),
          "uneven (worst gap: the last, slices 2 and 3 in f3 and f2): %s", err.msg);
    st = cdvr_volume_load(at("hostile"), NULL, &v, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "hostile/f1.dcm") &&
              strstr(err.msg, "Rows 7000") && strstr(err.msg, "the file holds"),
          "Rows claiming more than the file: %s", err.msg);
    st = cdvr_volume_load(at("huge"), NULL, &v, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "huge/") && strstr(err.msg, "RescaleSlope 1e+36") &&
              strstr(err.msg, "beyond the range of f32"),
          "a rescale beyond f32 refused: %s", err.msg);
    st = cdvr_volume_load(at("wobble"), NULL, &v, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "wobble/f0.dcm is 2 mm off the line") &&
              strstr(err.msg, "not one evenly tilted stack"),
          "slices not on one line (a shift growing as k^2): %s", err.msg);
    st = cdvr_volume_load(at("notag"), NULL, &v, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "notag/f2.dcm: PixelSpacing (0028,0030) is "
                                          "missing"),
          "missing tag: %s", err.msg);
    cdvr_raw_opts o;
    memset(&o, 0, sizeof o);
    o.select = "dup";
    st = cdvr_volume_load(at("same_desc"), &o, &v, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "2 series have the SeriesDescription 'dup'"),
          "a description two series share: %s", err.msg);
    o.select = "1.2.826.0.1.3680043.9.7777.9";
    CHECK_OK(cdvr_volume_load(at("same_desc"), &o, &v, &err), err);
    CHECK(v && v->type == CDVR_TYPE_U16 && cdvr_volume_get(v, 1, 0, 0, 0) == 101, "then by UID");
    cdvr_volume_free(v);
    v = NULL;
    memset(&o, 0, sizeof o);
    o.max_bytes = 100;
    st = cdvr_volume_load(at("oblique"), &o, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "max_bytes 100"), "max_bytes: %s", err.msg);

    mkdir(at("special"), 0777);
    unlink(at("special/fifo.dcm"));
    CHECK(mkfifo(at("special/fifo.dcm"), 0666) == 0, "mkfifo");
    st = cdvr_volume_load(at("special/fifo.dcm"), NULL, &v, &err);
    CHECK(st != CDVR_OK && strstr(err.msg, "fifo.dcm"), "a FIFO: %s", err.msg);
    mkdir(at("nodicom"), 0777);
    FILE *f = fopen(at("nodicom/readme.txt"), "w");
    if (f) {
        fputs("not DICOM\n", f);
        fclose(f);
    }
    st = cdvr_volume_load(at("nodicom"), NULL, &v, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "is a directory that no format reads") &&
              strstr(err.msg, "dicom"),
          "a directory without DICOM: %s", err.msg);
    /* a symlink out of the directory (to a slice of oblique/) is refused, or read when allowed;
     * the readme beside the slices is skipped */
    mkdir(at("outside"), 0777);
    char target[4096];
    snprintf(target, sizeof target, "%s", at("oblique/f1.dcm"));
    unlink(at("outside/link.dcm"));
    CHECK(symlink(target, at("outside/link.dcm")) == 0, "symlink");
    f = fopen(at("outside/readme.txt"), "w");
    if (f) {
        fputs("not DICOM\n", f);
        fclose(f);
    }
    st = cdvr_volume_load(at("outside"), NULL, &v, &err);
    CHECK(st == CDVR_ERR_IO && strstr(err.msg, "link.dcm lies outside"), "symlink out: %s",
          err.msg);
    memset(&o, 0, sizeof o);
    o.allow_outside = 1;
    CHECK_OK(cdvr_volume_load(at("outside"), &o, &v, &err), err);
    CHECK(v && v->dims[2] == 1 && v->dims[0] == 5, "one slice through allow_outside");
    cdvr_volume_free(v);
}

/* Mutated copies of one slice beside an intact one: every load returns (GDCM runs in the
 * helper process, so its assertions on hostile bytes end only the helper), and an error names
 * the folder or the file. Deterministic (an LCG); the count of helper aborts is printed. */
static void test_mutations(void)
{
    FILE *f = fopen(at("oblique/f1.dcm"), "rb");
    static uint8_t orig[1 << 16], buf[1 << 16];
    size_t n = f ? fread(orig, 1, sizeof orig, f) : 0;
    if (f)
        fclose(f);
    CHECK(n > 200 && n < sizeof orig, "oblique/f1.dcm: %zu bytes", n);
    mkdir(at("mutated"), 0777);
    uint32_t seed = 12345;
    int aborted = 0, loaded = 0, refused = 0;
    for (int it = 0; it < 48 && n > 200; it++) {
        memcpy(buf, orig, n);
        size_t len = n;
        seed = seed * 1664525u + 1013904223u;
        int edits = 1 + (int)(seed >> 29);
        for (int e = 0; e < edits; e++) {
            seed = seed * 1664525u + 1013904223u;
            size_t at_byte = (seed >> 8) % n;
            seed = seed * 1664525u + 1013904223u;
            buf[at_byte] = (uint8_t)(seed >> 24);
        }
        seed = seed * 1664525u + 1013904223u;
        if ((seed >> 28) < 4) /* a quarter cut short */
            len = (seed >> 4) % n;
        FILE *w = fopen(at("mutated/a.dcm"), "wb");
        if (w) {
            fwrite(buf, 1, len, w);
            fclose(w);
        }
        if (it == 0) {
            FILE *in = fopen(at("oblique/f2.dcm"), "rb"), *out = fopen(at("mutated/b.dcm"), "wb");
            size_t k = in ? fread(buf, 1, sizeof buf, in) : 0;
            if (out && k)
                fwrite(buf, 1, k, out);
            if (in)
                fclose(in);
            if (out)
                fclose(out);
        }
        cdvr_error err;
        cdvr_volume *v = NULL;
        cdvr_status st = cdvr_volume_load(at("mutated"), NULL, &v, &err);
        if (st == CDVR_OK)
            loaded++;
        else {
            refused++;
            aborted += strstr(err.msg, "killed by signal") != NULL;
            CHECK(strstr(err.msg, "mutated"), "mutation %d: %s", it, err.msg);
        }
        cdvr_volume_free(v);
    }
    printf("mutated slices: %d loaded, %d refused (%d of them aborted GDCM in the helper)\n",
           loaded, refused, aborted);
}

int main(int argc, char **argv)
{
    if (argc != 2) {
        fprintf(stderr, "usage: test_dicom_load DIR (the output of dicom_write)\n");
        return 2;
    }
    root = argv[1];
    const char *bin = getenv("CDVR_BINARY_DIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/plugins/cdvr_dicom.so", bin && *bin ? bin : ".");
    cdvr_error err;
    const cdvr_plugin_info *info = NULL;
    CHECK_OK(cdvr_plugin_load_info(path, &info, &err), err);
    const cdvr_format *f = cdvr_format_find("dicom");
    CHECK(info && !info->codec && info->formats && info->formats[0] == f && !info->formats[1] &&
              f && f->accepts_dir && f->read && !f->load,
          "the plugin gives the dicom format (read, accepts_dir)");
    if (!f)
        return check_finish();
    CHECK(cdvr_format_by_suffix("x.DCM") == f, "suffix .dcm");
    test_series();
    test_select();
    test_frames_and_more();
    test_refusals();
    test_mutations();
    return check_finish();
}
