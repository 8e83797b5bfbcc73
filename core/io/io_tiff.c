/* core/io/io_tiff.c - TIFF through libtiff (format "tiff"): a multi-page file is a volume, one
 * page per z slice (x fastest, page slowest).
 *
 * Every page must be one sample per pixel of the first page's width, height, bits (8, 16, 32 or
 * 64) and sample format (unsigned, signed, IEEE float); strips or tiles, any compression libtiff
 * decodes. ImageJ files (ImageDescription starting "ImageJ="): x and y spacing are
 * 1/XResolution and 1/YResolution, z spacing "spacing=", and "frames=T" with "slices=Z"
 * (Z * T = pages, no channels) make T timesteps. Other files: unit spacing. Origin 0, direction
 * identity (index x along world +x, rows along +y as VTK's TIFF reader without flipping).
 * Before any voxel is allocated the pages' bytes are checked against the file (uncompressed:
 * the file must hold them; compressed: zlib's largest ratio); libtiff's messages go to a per-call
 * handler, never to stderr, and name the file.
 * Speed: a probe reads page 0's directory and counts the pages by libtiff's walk of the
 * directory offsets (TIFFNumberOfDirectories; no other page's tags); a load reads the
 * directories once, in order (TIFFReadDirectory, never TIFFSetDirectory's walk from the start),
 * checks each page against page 0 as it goes and reads the strips or tiles of a type the volume
 * keeps straight into the volume (a page that differs is refused by the load, not the probe). */
#include "cdvr/format.h"
#include "cdvr/regular_file.h"
#include "cdvr/series.h"
#include "cdvr/tiff.h"
#include "io_common.h"
#include "volume_io.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <glob.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <tiffio.h>
#include <unistd.h>

typedef struct tiff_ctx {
    char msg[256]; /* libtiff's first error */
} tiff_ctx;

static int on_error(TIFF *tif, void *ud, const char *module, const char *fmt, va_list ap)
{
    (void)tif, (void)module;
    tiff_ctx *c = ud;
    if (!c->msg[0])
        vsnprintf(c->msg, sizeof c->msg, fmt, ap);
    return 1;
}

static int on_warning(TIFF *tif, void *ud, const char *module, const char *fmt, va_list ap)
{
    (void)tif, (void)ud, (void)module, (void)fmt, (void)ap;
    return 1; /* unknown tags and the like: not errors */
}

typedef struct tiff_shape {
    uint32_t w, h;
    size_t pages, timesteps;
    cdvr_io_etype type;
    double spacing[3];
    size_t file_bytes;
    int compressed;
    int t_before_z;   /* OME DimensionOrder: page t + T*z holds slice z of frame t */
} tiff_shape;

static cdvr_status tiff_open(const char *path, tiff_ctx *ctx, TIFF **out, size_t *file_bytes,
                             cdvr_error *err)
{
    int fd;
    struct stat sb;
    cdvr_status st = cdvr_open_regular_file(path, &fd, &sb, err);
    if (st != CDVR_OK)
        return st;
    *file_bytes = (size_t)sb.st_size;
    TIFFOpenOptions *o = TIFFOpenOptionsAlloc();
    if (!o) {
        close(fd);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    TIFFOpenOptionsSetErrorHandlerExtR(o, on_error, ctx);
    TIFFOpenOptionsSetWarningHandlerExtR(o, on_warning, ctx);
    TIFFOpenOptionsSetMaxSingleMemAlloc(o, (tmsize_t)1 << 31);
    *out = TIFFFdOpenExt(fd, path, "rm", o); /* m: no mapping; libtiff owns fd now */
    TIFFOpenOptionsFree(o);
    if (!*out) {
        close(fd);
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not a TIFF file libtiff reads: %s", path,
                              ctx->msg[0] ? ctx->msg : "unknown error");
    }
    return CDVR_OK;
}

static int page_type(TIFF *tif, cdvr_io_etype *t)
{
    uint16_t bits = 1, fmt = SAMPLEFORMAT_UINT, spp = 1;
    TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &fmt);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
    if (spp != 1)
        return 0;
    if (fmt == SAMPLEFORMAT_IEEEFP)
        return bits == 32 ? (*t = CDVR_IO_F32, 1) : bits == 64 ? (*t = CDVR_IO_F64, 1) : 0;
    int s = fmt == SAMPLEFORMAT_INT;
    if (fmt != SAMPLEFORMAT_UINT && !s)
        return 0;
    switch (bits) {
    case 8: *t = s ? CDVR_IO_I8 : CDVR_IO_U8; return 1;
    case 16: *t = s ? CDVR_IO_I16 : CDVR_IO_U16; return 1;
    case 32: *t = s ? CDVR_IO_I32 : CDVR_IO_U32; return 1;
    case 64: *t = s ? CDVR_IO_I64 : CDVR_IO_U64; return 1;
    default: return 0;
    }
}

/* The geometry the first page's ImageDescription gives: ImageJ (x, y spacing 1/XResolution,
 * 1/YResolution; spacing=; frames= with slices= as timesteps) or OME-XML (cdvr/tiff.h); an
 * OME-XML description the loader cannot honour is an error. */
static cdvr_status description_geometry(const char *path, TIFF *tif, tiff_shape *s,
                                        cdvr_error *err)
{
    char *desc = NULL;
    if (!TIFFGetField(tif, TIFFTAG_IMAGEDESCRIPTION, &desc) || !desc)
        return CDVR_OK;
    size_t len = strlen(desc);
    cdvr_tiff_desc d;
    if (cdvr_tiff_imagej_parse(desc, len, &d)) {
        float xr = 0, yr = 0;
        if (TIFFGetField(tif, TIFFTAG_XRESOLUTION, &xr) && xr > 0 && 1.0 / xr < 1e30)
            s->spacing[0] = 1.0 / xr;
        if (TIFFGetField(tif, TIFFTAG_YRESOLUTION, &yr) && yr > 0 && 1.0 / yr < 1e30)
            s->spacing[1] = 1.0 / yr;
        if (d.spacing[2] > 0)
            s->spacing[2] = d.spacing[2];
        size_t slices = d.slices ? d.slices : 1;
        if (d.frames > 1 && d.channels <= 1 && slices * d.frames == s->pages) {
            s->timesteps = d.frames;
            s->pages = slices;
        }
        return CDVR_OK;
    }
    if (!strstr(desc, "<OME") && !strstr(desc, ":OME"))
        return CDVR_OK;
    cdvr_status st = cdvr_tiff_ome_parse(path, desc, len, s->pages, &d, err);
    if (st != CDVR_OK)
        return st;
    for (int a = 0; a < 3; a++)
        if (d.spacing[a] > 0)
            s->spacing[a] = d.spacing[a];
    s->timesteps = d.frames;
    s->pages = d.slices;
    s->t_before_z = d.t_before_z && d.frames > 1 && d.slices > 1;
    return CDVR_OK;
}

/* The shape of page `page` (the current directory), checked against page 0's (s->w, s->h,
 * s->type; page 0 sets them). */
static cdvr_status page_shape(const char *path, TIFF *tif, size_t page, tiff_shape *s,
                              cdvr_error *err)
{
    uint32_t w = 0, h = 0;
    uint16_t comp = COMPRESSION_NONE;
    cdvr_io_etype t;
    TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w);
    TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h);
    TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &comp);
    if (!page_type(tif, &t))
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "%s: TIFF page %zu is not one "
                              "sample of 8, 16, 32 or 64 bits (integer or float) per pixel",
                              path, page);
    if (w == 0 || h == 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: TIFF page %zu is empty", path, page);
    if (page == 0) {
        s->w = w;
        s->h = h;
        s->type = t;
    } else if (w != s->w || h != s->h || t != s->type)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: TIFF page %zu is %ux%u %s, page 0 "
                              "%ux%u %s (a volume's pages must agree)", path, page, w, h,
                              cdvr_io_etype_name(t), s->w, s->h, cdvr_io_etype_name(s->type));
    s->compressed |= comp != COMPRESSION_NONE;
    return CDVR_OK;
}

/* The file's shape from page 0 (the current directory) and the page count, which libtiff tells
 * by following the chain of directory offsets without reading the pages' tags: a probe reads one
 * directory. The other pages are checked against page 0 as the load reads them (page_shape);
 * the claim (pages x page 0's bytes) is checked against the file before anything is
 * allocated (a compressed page 0: deflate's maximum ratio, 1032). */
static cdvr_status tiff_shape_of(const char *path, TIFF *tif, tiff_shape *s, cdvr_error *err)
{
    s->spacing[0] = s->spacing[1] = s->spacing[2] = 1;
    s->timesteps = 1;
    cdvr_status st = page_shape(path, tif, 0, s, err);
    if (st != CDVR_OK)
        return st;
    tdir_t n = TIFFNumberOfDirectories(tif);
    if (n == 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: TIFF has no readable page", path);
    if (n > 1000000)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: TIFF has more than 10^6 pages", path);
    s->pages = n;
    unsigned long long total = (unsigned long long)s->w * s->h * cdvr_io_etype_size(s->type) * n;
    unsigned long long room = (unsigned long long)s->file_bytes * (s->compressed ? 1032 : 1);
    if (total > room)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: TIFF pages of %ux%u %s x %zu need %llu "
                              "bytes, the file (%zu bytes%s) cannot hold them", path, s->w, s->h,
                              cdvr_io_etype_name(s->type), s->pages, total, s->file_bytes,
                              s->compressed ? ", compressed" : "");
    return description_geometry(path, tif, s, err);
}

static void tiff_head(const tiff_shape *s, cdvr_volume *head)
{
    head->dims[0] = s->w;
    head->dims[1] = s->h;
    head->dims[2] = s->pages;
    head->timesteps = s->timesteps;
    cdvr_io_set_type(head, s->type);
    memcpy(head->spacing, s->spacing, sizeof s->spacing);
}

static int is_dir(const char *path)
{
    struct stat sb;
    return stat(path, &sb) == 0 && S_ISDIR(sb.st_mode);
}

static cdvr_status tiff_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                              cdvr_error *err)
{
    (void)opts;
    if (is_dir(path)) { /* a stack (accepts_dir) */
        void *data = head->data;
        cdvr_status st = cdvr_tiff_probe_stack(path, head, NULL, err);
        head->data = data;
        return st;
    }
    tiff_ctx ctx = {""};
    TIFF *tif;
    tiff_shape s = {0};
    cdvr_status st = tiff_open(path, &ctx, &tif, &s.file_bytes, err);
    if (st != CDVR_OK)
        return st;
    st = tiff_shape_of(path, tif, &s, err);
    if (st == CDVR_OK)
        tiff_head(&s, head);
    TIFFClose(tif);
    return st;
}

/* One page (directory) into page (w*h elements of esize bytes), from strips or tiles. */
static int read_page(TIFF *tif, const tiff_shape *s, uint8_t *page, uint8_t *tmp, size_t tmp_n)
{
    size_t es = cdvr_io_etype_size(s->type), row = (size_t)s->w * es;
    if (TIFFIsTiled(tif)) {
        uint32_t tw = 0, th = 0;
        TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw);
        TIFFGetField(tif, TIFFTAG_TILELENGTH, &th);
        if (!tw || !th || (size_t)tw * th * es > tmp_n)
            return 0;
        for (uint32_t y = 0; y < s->h; y += th)
            for (uint32_t x = 0; x < s->w; x += tw) {
                if (TIFFReadTile(tif, tmp, x, y, 0, 0) < 0)
                    return 0;
                size_t cw = (size_t)(x + tw <= s->w ? tw : s->w - x) * es;
                for (uint32_t r = 0; r < th && y + r < s->h; r++)
                    memcpy(page + (y + r) * row + (size_t)x * es, tmp + (size_t)r * tw * es, cw);
            }
        return 1;
    }
    uint32_t rps = 0;
    TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rps);
    if (rps == 0 || rps > s->h)
        rps = s->h;
    for (uint32_t y = 0, strip = 0; y < s->h; y += rps, strip++) {
        size_t rows = y + rps <= s->h ? rps : s->h - y;
        if (TIFFReadEncodedStrip(tif, strip, page + (size_t)y * row, (tmsize_t)(rows * row)) < 0)
            return 0;
    }
    return 1;
}

/* The pages of an open file (its shape s; page 0 the current directory) into vol from element
 * `at` on, in one pass over the directories (TIFFReadDirectory: each page's tags read once),
 * each page checked against page 0. A type the volume keeps is read straight into the volume
 * (libtiff gives host byte order); a converted one through a page buffer. */
static cdvr_status tiff_read_pages(const char *path, TIFF *tif, tiff_ctx *ctx,
                                   tiff_shape *s, cdvr_volume *vol, size_t at,
                                   cdvr_io_range *range, cdvr_error *err)
{
    size_t es = cdvr_io_etype_size(s->type), plane = (size_t)s->w * s->h;
    int direct = !cdvr_io_etype_converted(s->type);
    size_t tile_n = 0;
    uint8_t *page = direct ? NULL : malloc(plane * es), *tmp = NULL;
    cdvr_status st = direct || page ? CDVR_OK
                                    : cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    size_t n = s->pages * s->timesteps;
    for (size_t p = 0; st == CDVR_OK && p < n; p++) {
        if (p > 0 && !TIFFReadDirectory(tif)) {
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: TIFF page %zu cannot be read: %s",
                                path, p, ctx->msg[0] ? ctx->msg : "the directory chain ends");
            break;
        }
        if (p > 0 && (st = page_shape(path, tif, p, s, err)) != CDVR_OK)
            break;
        size_t need = TIFFIsTiled(tif) ? (size_t)TIFFTileSize(tif) : 0;
        if (need > tile_n) { /* tiles may differ from page to page */
            free(tmp);
            tile_n = 0;
            if (!(tmp = malloc(need))) {
                st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
                break;
            }
            tile_n = need;
        }
        /* slot of page p: p itself, or with T before Z slice p / T of frame p % T */
        size_t slot = s->t_before_z ? p / s->timesteps + s->pages * (p % s->timesteps) : p;
        uint8_t *dst = direct ? (uint8_t *)vol->data + (at + slot * plane) * es : page;
        if (!read_page(tif, s, dst, tmp, tile_n))
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: TIFF page %zu cannot be read: %s",
                                path, p, ctx->msg[0] ? ctx->msg : "bad strips or tiles");
        else if (!direct)
            cdvr_io_store(vol, at + slot * plane, page, s->type, !cdvr_host_is_little_endian(),
                          plane, range);
    }
    free(page);
    free(tmp);
    return st;
}

static cdvr_status load_stack(const char *where, const cdvr_raw_opts *opts, cdvr_volume **out,
                              cdvr_error *err);

static cdvr_status tiff_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                             cdvr_error *err)
{
    *out = NULL;
    if (is_dir(path))
        return load_stack(path, opts, out, err);
    tiff_ctx ctx = {""};
    TIFF *tif;
    tiff_shape s = {0};
    cdvr_status st = tiff_open(path, &ctx, &tif, &s.file_bytes, err);
    if (st != CDVR_OK)
        return st;
    cdvr_volume head = {.spacing = {1, 1, 1}}, *vol = NULL;
    cdvr_io_range range;
    cdvr_io_range_init(&range, opts);
    st = tiff_shape_of(path, tif, &s, err);
    if (st == CDVR_OK) {
        tiff_head(&s, &head);
        st = cdvr_volume_create(head.dims, head.timesteps, head.type, &vol, err);
    }
    if (st == CDVR_OK)
        st = tiff_read_pages(path, tif, &ctx, &s, vol, 0, &range, err);
    TIFFClose(tif);
    if (st != CDVR_OK) {
        cdvr_volume_free(vol);
        return st;
    }
    memcpy(vol->spacing, head.spacing, sizeof head.spacing);
    st = cdvr_io_finish(vol, s.type, &range, path, "TIFF", err);
    if (st != CDVR_OK) {
        cdvr_volume_free(vol);
        return st;
    }
    *out = vol;
    return CDVR_OK;
}

/* ---- stacks: one file per slice (cdvr/tiff.h) ------------------------------------------- */

static int natural_qsort(const void *a, const void *b)
{
    return cdvr_series_natural_cmp(*(char *const *)a, *(char *const *)b);
}

static int tiff_name(const char *name)
{
    size_t n = strlen(name);
    return name[0] != '.' && ((n > 4 && strcasecmp(name + n - 4, ".tif") == 0) ||
                              (n > 5 && strcasecmp(name + n - 5, ".tiff") == 0));
}

#define STACK_FILES_MAX 100000

/* The files of a directory (its .tif/.tiff) or a glob pattern, in natural order. */
static cdvr_status stack_files(const char *where, char ***out, size_t *count, cdvr_error *err)
{
    struct stat sb;
    *out = NULL;
    *count = 0;
    if (stat(where, &sb) == 0 && S_ISDIR(sb.st_mode)) {
        DIR *d = opendir(where);
        if (!d)
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open the directory: %s", where,
                                  strerror(errno));
        struct dirent *e;
        char **list = NULL;
        size_t n = 0;
        cdvr_status st = CDVR_OK;
        while (st == CDVR_OK && (e = readdir(d)) != NULL) {
            if (!tiff_name(e->d_name))
                continue;
            char **grown = n < STACK_FILES_MAX ? realloc(list, (n + 1) * sizeof *list) : NULL;
            size_t len = strlen(where) + strlen(e->d_name) + 2;
            char *path = grown ? malloc(len) : NULL;
            if (!path) {
                st = n >= STACK_FILES_MAX
                         ? cdvr_error_set(err, CDVR_ERR_ARG, "%s: more than %d TIFF files",
                                          where, STACK_FILES_MAX)
                         : cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", where);
                list = grown ? grown : list;
                break;
            }
            list = grown;
            snprintf(path, len, "%s/%s", where, e->d_name);
            list[n++] = path;
        }
        closedir(d);
        *out = list;
        *count = n;
        if (st == CDVR_OK && n == 0)
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: a directory with no .tif or .tiff "
                                "file", where);
        if (st == CDVR_OK)
            qsort(list, n, sizeof *list, natural_qsort);
        return st;
    }
    glob_t g;
    int rc = glob(where, 0, NULL, &g);
    if (rc != 0) {
        if (rc != GLOB_NOMATCH)
            globfree(&g);
        return cdvr_error_set(err, rc == GLOB_NOMATCH ? CDVR_ERR_IO : CDVR_ERR_NOMEM,
                              "%s: %s", where, rc == GLOB_NOMATCH ? "no file matches (not a "
                              "directory or a pattern of TIFF files)" : "cannot expand the pattern");
    }
    char **list = g.gl_pathc <= STACK_FILES_MAX ? calloc(g.gl_pathc, sizeof *list) : NULL;
    size_t n = 0;
    for (size_t i = 0; list && i < g.gl_pathc; i++)
        if ((list[n] = strdup(g.gl_pathv[i])) != NULL)
            n++;
    size_t want = g.gl_pathc;
    globfree(&g);
    *out = list;
    *count = n;
    if (!list || n != want)
        return cdvr_error_set(err, list ? CDVR_ERR_NOMEM : CDVR_ERR_ARG, "%s: %zu files%s",
                              where, want, list ? ": out of memory" : ": too many");
    qsort(list, n, sizeof *list, natural_qsort);
    return CDVR_OK;
}

static void free_files(char **list, size_t n)
{
    for (size_t i = 0; i < n; i++)
        free(list[i]);
    free(list);
}

/* Opens file i of a stack and takes its shape; every page of it is a slice. */
static cdvr_status stack_open(const char *path, tiff_ctx *ctx, TIFF **tif, tiff_shape *s,
                              cdvr_error *err)
{
    memset(s, 0, sizeof *s);
    cdvr_status st = tiff_open(path, ctx, tif, &s->file_bytes, err);
    if (st != CDVR_OK)
        return st;
    st = tiff_shape_of(path, *tif, s, err);
    s->pages *= s->timesteps; /* a stack's files are slices, not frames */
    s->timesteps = 1;
    s->t_before_z = 0;        /* in the file's page order */
    if (st != CDVR_OK)
        TIFFClose(*tif);
    return st;
}

static cdvr_status stack_shape(char **files, size_t n, tiff_shape *first, size_t *slices,
                               cdvr_error *err)
{
    *slices = 0;
    for (size_t i = 0; i < n; i++) {
        tiff_ctx ctx = {""};
        TIFF *tif;
        tiff_shape s;
        cdvr_status st = stack_open(files[i], &ctx, &tif, &s, err);
        if (st != CDVR_OK)
            return st;
        TIFFClose(tif);
        if (i == 0)
            *first = s;
        else if (s.w != first->w || s.h != first->h || s.type != first->type)
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %ux%u %s, but %s is %ux%u %s (the "
                                  "slices of a stack must agree)", files[i], s.w, s.h,
                                  cdvr_io_etype_name(s.type), files[0], first->w, first->h,
                                  cdvr_io_etype_name(first->type));
        *slices += s.pages;
    }
    return CDVR_OK;
}

cdvr_status cdvr_tiff_probe_stack(const char *where, cdvr_volume *head, size_t *files,
                                  cdvr_error *err)
{
    char **list;
    size_t n, slices;
    tiff_shape first;
    cdvr_status st = stack_files(where, &list, &n, err);
    if (st == CDVR_OK)
        st = stack_shape(list, n, &first, &slices, err);
    if (st == CDVR_OK) {
        memset(head, 0, sizeof *head);
        tiff_head(&first, head);
        head->dims[2] = slices;
        head->timesteps = 1;
        head->direction[0] = head->direction[4] = head->direction[8] = 1;
        if (files)
            *files = n;
    }
    free_files(list, n);
    return st;
}

static cdvr_status load_stack(const char *where, const cdvr_raw_opts *opts, cdvr_volume **out,
                              cdvr_error *err)
{
    *out = NULL;
    cdvr_volume head;
    cdvr_status st = cdvr_tiff_probe_stack(where, &head, NULL, err);
    char **list = NULL;
    size_t n = 0, at = 0;
    cdvr_volume *vol = NULL;
    if (st == CDVR_OK)
        st = stack_files(where, &list, &n, err);
    if (st == CDVR_OK)
        st = cdvr_volume_create(head.dims, 1, head.type, &vol, err);
    cdvr_io_range range;
    cdvr_io_range_init(&range, opts);
    cdvr_io_etype type = CDVR_IO_U8;
    for (size_t i = 0; st == CDVR_OK && i < n; i++) {
        tiff_ctx ctx = {""};
        TIFF *tif;
        tiff_shape s;
        st = stack_open(list[i], &ctx, &tif, &s, err);
        if (st != CDVR_OK)
            break;
        if (s.w != head.dims[0] || s.h != head.dims[1] || at + s.pages > head.dims[2])
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: changed while the stack was read",
                                list[i]);
        else
            st = tiff_read_pages(list[i], tif, &ctx, &s, vol, at * head.dims[0] * head.dims[1],
                                 &range, err);
        at += s.pages;
        type = s.type;
        TIFFClose(tif);
    }
    free_files(list, n);
    if (st != CDVR_OK) {
        cdvr_volume_free(vol);
        return st;
    }
    memcpy(vol->spacing, head.spacing, sizeof head.spacing);
    st = cdvr_io_finish(vol, type, &range, where, "TIFF", err);
    if (st != CDVR_OK) {
        cdvr_volume_free(vol);
        return st;
    }
    *out = vol;
    return CDVR_OK;
}

cdvr_status cdvr_tiff_load_stack(const char *where, cdvr_volume **out, cdvr_error *err)
{
    return load_stack(where, NULL, out, err);
}

/* "II*\0", "MM\0*" (classic) and the BigTIFF forms (43). */
static int tiff_magic(const uint8_t *h, size_t n)
{
    return n >= 4 && ((h[0] == 'I' && h[1] == 'I' && (h[2] == 42 || h[2] == 43) && h[3] == 0) ||
                      (h[0] == 'M' && h[1] == 'M' && h[2] == 0 && (h[3] == 42 || h[3] == 43)));
}

/* A directory holding a .tif or .tiff file (not hidden) is a stack. */
static int tiff_accepts_dir(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    struct dirent *e;
    int found = 0;
    while (!found && (e = readdir(d)) != NULL)
        found = tiff_name(e->d_name);
    closedir(d);
    return found;
}

static const char *const tiff_suffixes[] = {".tif", ".tiff", NULL};

const cdvr_format cdvr_format_tiff = {
    .name = "tiff",
    .description = "TIFF through libtiff: the pages of a multi-page file as z slices, 8 to 64 "
                   "bits integer or float, strips or tiles, ImageJ and OME-TIFF spacing and "
                   "frames; a directory of .tif files as a stack",
    .suffixes = tiff_suffixes,
    .magic = tiff_magic,
    .probe = tiff_probe,
    .load = tiff_load,
    .accepts_dir = tiff_accepts_dir,
};
