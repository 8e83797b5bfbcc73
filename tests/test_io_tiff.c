/* tests/test_io_tiff.c - the TIFF loader (core/io/io_tiff.c): multi-page files written here with
 * libtiff - 8, 16, 32 and 64-bit integer and float pages, strips (several, a partial last one)
 * and tiles (partial at the edges), uncompressed and deflate, odd dims - load voxel for voxel
 * through cdvr_volume_load (pages are z slices) and the probe agrees without reading them; ImageJ
 * files give their spacing (1/XResolution, 1/YResolution, spacing=) and frames= as timesteps;
 * uint32 and float64 become float32 with the window computed in double; pages that differ, RGB
 * pages, a header claiming more pixels than the file holds and a FIFO are refused naming the
 * file. Stacks (cdvr/tiff.h): a directory and a glob pattern of one file per slice (one with two
 * pages) load in natural order (s2 before s10), dot files and other names skipped; a slice of
 * another size, an empty directory and a pattern matching nothing are refused. */
#include "check.h"
#include "cdvr/format.h"
#include "cdvr/tiff.h"
#include "cdvr/volume.h"

#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>

static char tmpdir[] = "/tmp/cdvr_test_io_tiff_XXXXXX";

typedef struct tcase {
    const char *label;
    uint16_t bits, fmt;
    uint32_t w, h, pages;
    int tiled, deflate;
    const char *imagej; /* ImageDescription or NULL */
} tcase;

static double value(const tcase *c, size_t i)
{
    if (c->fmt == SAMPLEFORMAT_IEEEFP)
        return c->bits == 32 ? (double)(float)(0.25 * (double)i - 7.5) : 1e33 * ((double)i - 3) + 0.5; /* within f32 */
    if (c->fmt == SAMPLEFORMAT_INT)
        return c->bits == 16 ? (double)((long)(i * 131) % 60000 - 30000) : (double)(i % 200) - 100;
    return c->bits == 8 ? (double)(i * 7 % 256) : c->bits == 16 ? (double)(i * 977 % 65536)
                                                                 : (double)(4000000000u - i * 3);
}

static void put(const tcase *c, uint8_t *p, double v)
{
    if (c->fmt == SAMPLEFORMAT_IEEEFP && c->bits == 32) { float f = (float)v; memcpy(p, &f, 4); }
    else if (c->fmt == SAMPLEFORMAT_IEEEFP) memcpy(p, &v, 8);
    else if (c->bits == 8) { int8_t x = (int8_t)v; uint8_t u = (uint8_t)v; *p = c->fmt == SAMPLEFORMAT_INT ? (uint8_t)x : u; }
    else if (c->bits == 16 && c->fmt == SAMPLEFORMAT_INT) { int16_t x = (int16_t)v; memcpy(p, &x, 2); }
    else if (c->bits == 16) { uint16_t x = (uint16_t)v; memcpy(p, &x, 2); }
    else { uint32_t x = (uint32_t)v; memcpy(p, &x, 4); }
}

static int write_tiff(const char *path, const tcase *c)
{
    TIFF *t = TIFFOpen(path, "w");
    if (!t)
        return 0;
    size_t es = c->bits / 8;
    uint8_t *page = malloc((size_t)c->w * c->h * es), *tile = malloc(16 * 16 * es);
    for (uint32_t p = 0; p < c->pages; p++) {
        TIFFSetField(t, TIFFTAG_IMAGEWIDTH, c->w);
        TIFFSetField(t, TIFFTAG_IMAGELENGTH, c->h);
        TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, c->bits);
        TIFFSetField(t, TIFFTAG_SAMPLEFORMAT, c->fmt);
        TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
        TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
        TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
        TIFFSetField(t, TIFFTAG_COMPRESSION, c->deflate ? COMPRESSION_ADOBE_DEFLATE : COMPRESSION_NONE);
        if (c->imagej && p == 0) {
            TIFFSetField(t, TIFFTAG_IMAGEDESCRIPTION, c->imagej);
            TIFFSetField(t, TIFFTAG_XRESOLUTION, 4.0f);
            TIFFSetField(t, TIFFTAG_YRESOLUTION, 2.0f);
            TIFFSetField(t, TIFFTAG_RESOLUTIONUNIT, RESUNIT_NONE);
        }
        if (c->pages > 1) {
            TIFFSetField(t, TIFFTAG_SUBFILETYPE, FILETYPE_PAGE);
            TIFFSetField(t, TIFFTAG_PAGENUMBER, p, c->pages);
        }
        for (size_t i = 0; i < (size_t)c->w * c->h; i++)
            put(c, page + i * es, value(c, p * (size_t)c->w * c->h + i));
        if (c->tiled) {
            TIFFSetField(t, TIFFTAG_TILEWIDTH, 16);
            TIFFSetField(t, TIFFTAG_TILELENGTH, 16);
            for (uint32_t y = 0; y < c->h; y += 16)
                for (uint32_t x = 0; x < c->w; x += 16) {
                    memset(tile, 0, 16 * 16 * es);
                    for (uint32_t r = 0; r < 16 && y + r < c->h; r++)
                        for (uint32_t q = 0; q < 16 && x + q < c->w; q++)
                            memcpy(tile + (r * 16 + q) * es, page + ((y + r) * c->w + x + q) * es, es);
                    TIFFWriteTile(t, tile, x, y, 0, 0);
                }
        } else {
            TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, 2);
            for (uint32_t y = 0; y < c->h; y++)
                TIFFWriteScanline(t, page + (size_t)y * c->w * es, y, 0);
        }
        TIFFWriteDirectory(t);
    }
    TIFFClose(t);
    free(page);
    free(tile);
    return 1;
}

static void check_case(const tcase *c, size_t timesteps, const double spacing[3])
{
    char path[256];
    snprintf(path, sizeof path, "%s/c.tif", tmpdir);
    CHECK(write_tiff(path, c), "%s: write", c->label);
    cdvr_volume *vol = NULL, head;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK(st == CDVR_OK, "%s: %s", c->label, err.msg);
    if (st != CDVR_OK)
        return;
    size_t z = c->pages / timesteps, n = (size_t)c->w * c->h * c->pages, bad = 0;
    CHECK(vol->dims[0] == c->w && vol->dims[1] == c->h && vol->dims[2] == z &&
          vol->timesteps == timesteps, "%s: dims %zux%zux%zu x %zu", c->label, vol->dims[0],
          vol->dims[1], vol->dims[2], vol->timesteps);
    int converted = c->bits >= 32 && !(c->bits == 32 && c->fmt == SAMPLEFORMAT_IEEEFP);
    for (size_t i = 0; i < n && vol->dims[2] == z; i++) {
        double want = converted ? (double)(float)value(c, i) : value(c, i);
        bad += cdvr_volume_get(vol, i % c->w, i / c->w % c->h, i / ((size_t)c->w * c->h) % z,
                               i / ((size_t)c->w * c->h * z)) != want;
    }
    CHECK(bad == 0, "%s: %zu voxels differ", c->label, bad);
    for (int a = 0; a < 3; a++)
        CHECK(fabs(vol->spacing[a] - spacing[a]) < 1e-6, "%s: spacing[%d] %g", c->label, a,
              vol->spacing[a]);
    if (converted) {
        double w[2], lo = 1e308, hi = -1e308;
        for (size_t i = 0; i < n; i++)
            lo = fmin(lo, value(c, i)), hi = fmax(hi, value(c, i));
        cdvr_volume_window(vol, w);
        CHECK(w[0] == lo && w[1] == hi, "%s: window [%.17g, %.17g]", c->label, w[0], w[1]);
    }
    st = cdvr_volume_probe(path, NULL, &head, &err);
    CHECK(st == CDVR_OK && memcmp(head.dims, vol->dims, sizeof head.dims) == 0 &&
          head.timesteps == vol->timesteps && head.type == vol->type &&
          memcmp(head.spacing, vol->spacing, sizeof head.spacing) == 0,
          "%s: the probe differs: %s", c->label, err.msg);
    cdvr_volume_free(vol);
}

static void expect_refused(const char *label, const char *path, const char *needle)
{
    cdvr_volume *vol = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK(st != CDVR_OK && vol == NULL && strstr(err.msg, path) && strstr(err.msg, needle),
          "%s: status %d: %s", label, (int)st, err.msg);
    cdvr_volume_free(vol);
}

static void test_hostile(void)
{
    char path[256];
    snprintf(path, sizeof path, "%s/h.tif", tmpdir);
    /* 100000 x 100000 pixels of 16 bits declared, 10 bytes of strip written */
    TIFF *t = TIFFOpen(path, "w");
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, 100000);
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, 100000);
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
    TIFFSetField(t, TIFFTAG_ROWSPERSTRIP, 100000);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
    uint8_t ten[10] = {0};
    TIFFWriteRawStrip(t, 0, ten, 10);
    TIFFClose(t);
    expect_refused("pixels beyond the file", path, "cannot hold them");
    /* pages that differ */
    tcase a = {"a", 8, SAMPLEFORMAT_UINT, 7, 5, 1, 0, 0, NULL};
    t = TIFFOpen(path, "w");
    for (int p = 0; p < 2; p++) {
        uint8_t row[8] = {0};
        TIFFSetField(t, TIFFTAG_IMAGEWIDTH, p ? 8 : 7);
        TIFFSetField(t, TIFFTAG_IMAGELENGTH, 5);
        TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 8);
        TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
        TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
        for (uint32_t y = 0; y < 5; y++)
            TIFFWriteScanline(t, row, y, 0);
        TIFFWriteDirectory(t);
    }
    TIFFClose(t);
    (void)a;
    expect_refused("pages differ", path, "must agree");
    /* RGB */
    t = TIFFOpen(path, "w");
    uint8_t rgb[3 * 4] = {0};
    TIFFSetField(t, TIFFTAG_IMAGEWIDTH, 4);
    TIFFSetField(t, TIFFTAG_IMAGELENGTH, 1);
    TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 8);
    TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 3);
    TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB);
    TIFFSetField(t, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFWriteScanline(t, rgb, 0, 0);
    TIFFClose(t);
    expect_refused("rgb", path, "one sample");
    /* not a TIFF; a FIFO */
    FILE *f = fopen(path, "wb");
    fputs("II*\0garbage", f);
    fclose(f);
    expect_refused("garbage", path, "TIFF");
    snprintf(path, sizeof path, "%s/fifo.tif", tmpdir);
    CHECK(mkfifo(path, 0600) == 0, "mkfifo");
    expect_refused("fifo", path, "regular");
    unlink(path);
}

/* Slices s1, s2 (two pages), s10 of 6x4 u16, each page a constant: its slice number. */
static void test_stack(void)
{
    char dir[256], path[512], pattern[512];
    snprintf(dir, sizeof dir, "%s/stack", tmpdir);
    mkdir(dir, 0700);
    const struct { const char *name; uint32_t pages, w; } files[] = {
        {"s10.tif", 1, 6}, {"s1.tif", 1, 6}, {"s2.tiff", 2, 6}, {".s0.tif", 1, 3}};
    uint16_t first_value[] = {4, 1, 2, 0};
    for (int f = 0; f < 4; f++) {
        snprintf(path, sizeof path, "%s/%s", dir, files[f].name);
        TIFF *t = TIFFOpen(path, "w");
        for (uint32_t p = 0; p < files[f].pages; p++) {
            uint16_t row[6];
            for (int i = 0; i < 6; i++)
                row[i] = (uint16_t)(first_value[f] + p);
            TIFFSetField(t, TIFFTAG_IMAGEWIDTH, files[f].w);
            TIFFSetField(t, TIFFTAG_IMAGELENGTH, 4);
            TIFFSetField(t, TIFFTAG_BITSPERSAMPLE, 16);
            TIFFSetField(t, TIFFTAG_SAMPLESPERPIXEL, 1);
            TIFFSetField(t, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
            for (uint32_t y = 0; y < 4; y++)
                TIFFWriteScanline(t, row, y, 0);
            TIFFWriteDirectory(t);
        }
        TIFFClose(t);
    }
    snprintf(path, sizeof path, "%s/notes.txt", dir);
    FILE *nf = fopen(path, "w");
    fputs("not a slice", nf);
    fclose(nf);
    snprintf(pattern, sizeof pattern, "%s/s*.tif*", dir);
    const char *wheres[] = {dir, pattern};
    for (int k = 0; k < 2; k++) {
        cdvr_volume *vol = NULL, head;
        cdvr_error err;
        size_t nfiles = 0;
        cdvr_status st = cdvr_tiff_probe_stack(wheres[k], &head, &nfiles, &err);
        CHECK(st == CDVR_OK && head.dims[0] == 6 && head.dims[1] == 4 && head.dims[2] == 4 &&
              nfiles == 3 && head.type == CDVR_TYPE_U16, "stack probe %s: %s", wheres[k],
              err.msg);
        st = cdvr_tiff_load_stack(wheres[k], &vol, &err);
        CHECK(st == CDVR_OK, "stack %s: %s", wheres[k], err.msg);
        if (st == CDVR_OK) {
            int ordered = vol->dims[2] == 4;
            for (size_t z = 0; ordered && z < 4; z++)
                ordered = cdvr_volume_get(vol, 5, 3, z, 0) == (double)(z + 1);
            CHECK(ordered, "stack %s: slices not in natural order", wheres[k]);
            cdvr_volume_free(vol);
        }
    }
    /* a slice of another size; an empty directory; a pattern matching nothing */
    cdvr_volume *vol = NULL;
    cdvr_error err;
    snprintf(path, sizeof path, "%s/s3.tif", dir);
    char src[512];
    snprintf(src, sizeof src, "%s/.s0.tif", dir);
    CHECK(rename(src, path) == 0, "rename");
    cdvr_status st = cdvr_tiff_load_stack(dir, &vol, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "s3.tif") && strstr(err.msg, "must agree"),
          "stack of mixed sizes: %s", err.msg);
    snprintf(path, sizeof path, "%s/empty", tmpdir);
    mkdir(path, 0700);
    st = cdvr_tiff_load_stack(path, &vol, &err);
    CHECK(st == CDVR_ERR_FORMAT && strstr(err.msg, "no .tif"), "empty dir: %s", err.msg);
    snprintf(path, sizeof path, "%s/none_*.tif", tmpdir);
    st = cdvr_tiff_load_stack(path, &vol, &err);
    CHECK(st != CDVR_OK && vol == NULL && strstr(err.msg, "no file matches"), "no match: %s",
          err.msg);
}

int main(void)
{
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    CHECK(cdvr_format_find("tiff") != NULL, "tiff format registered");
    const double unit[3] = {1, 1, 1}, ij[3] = {0.25, 0.5, 2.5};
    const tcase cases[] = {
        {"u8 strips", 8, SAMPLEFORMAT_UINT, 17, 5, 3, 0, 0, NULL},
        {"u16 strips ImageJ", 16, SAMPLEFORMAT_UINT, 17, 5, 3, 0, 0,
         "ImageJ=1.53t\nimages=3\nslices=3\nunit=micron\nspacing=2.5\nloop=false\n"},
        {"i16 strips deflate", 16, SAMPLEFORMAT_INT, 9, 7, 4, 0, 1, NULL},
        {"i8 tiles", 8, SAMPLEFORMAT_INT, 33, 20, 2, 1, 0, NULL},
        {"f32 tiles deflate", 32, SAMPLEFORMAT_IEEEFP, 33, 20, 2, 1, 1, NULL},
        {"u32 strips", 32, SAMPLEFORMAT_UINT, 5, 3, 2, 0, 0, NULL},
        {"f64 tiles", 64, SAMPLEFORMAT_IEEEFP, 17, 17, 2, 1, 0, NULL},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        check_case(&cases[i], 1, cases[i].imagej ? ij : unit);
    const tcase frames = {"ImageJ frames", 16, SAMPLEFORMAT_UINT, 7, 5, 6, 0, 0,
                          "ImageJ=1.53t\nimages=6\nslices=3\nframes=2\nhyperstack=true\n"
                          "spacing=2.5\n"};
    check_case(&frames, 2, ij);
    test_hostile();
    test_stack();
    char cmd[512];
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmpdir);
    CHECK(system(cmd) == 0, "cleanup");
    return check_finish();
}
