/* core/io/io_mha.c - MetaImage (.mha with its data, .mhd with a detached data file), ITK's
 * format (format "mha"). MetaIO is C++ inside ITK/VTK, so this header reader is ours (fuzzed).
 *
 * Header: text lines "Key = value" (keys compared without regard to case), ending with
 * ElementDataFile, after whose line the data start (LOCAL) unless HeaderSize says where:
 *   ObjectType = Image             NDims = 2 | 3 | 4 (the 4th axis: timesteps)
 *   DimSize = x y z [t]            ElementType = MET_UCHAR | MET_CHAR | MET_USHORT | MET_SHORT |
 *                                  MET_UINT | MET_INT | MET_ULONG | MET_LONG (4 bytes) |
 *                                  MET_ULONG_LONG | MET_LONG_LONG | MET_FLOAT | MET_DOUBLE
 *   ElementSpacing (ElementSize)   Offset (Position, Origin): world of voxel (0,0,0)
 *   TransformMatrix (Rotation, Orientation): NDims x NDims, the direction of index axis 0, then
 *                                  of axis 1, ... (ITK's MetaImageIO: column c of the direction
 *                                  matrix is values c*NDims .. c*NDims+NDims-1)
 *   BinaryDataByteOrderMSB (ElementByteOrderMSB) = True | False
 *   CompressedData = True (zlib or gzip), CompressedDataSize = bytes (optional)
 *   ElementNumberOfChannels = 1    HeaderSize = bytes to skip in a detached data file (LOCAL data
 *                                  start after the header), -1: the data end the file
 *   ElementDataFile = LOCAL | a file name (relative to the header's directory)
 * BinaryData = False (ASCII voxels) and file lists (LIST, patterns) are refused. */
#include "cdvr/format.h"
#include "io_common.h"
#include "volume_io.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define MHA_LINE_MAX 4096
#define MHA_HEADER_MAX (1 << 20) /* a header longer than this is not a MetaImage header */

typedef struct mha_head {
    const char *path;
    cdvr_error *err;
    int ndims, big_endian, compressed, have_type, have_dims;
    size_t dims[4];
    double spacing[4], offset[4], matrix[16];
    cdvr_io_etype type;
    long long header_size;     /* -1: the data end the file */
    unsigned long long csize;  /* CompressedDataSize, 0 when absent */
    char data_file[MHA_LINE_MAX];
    size_t data_at;            /* LOCAL: where the data start in the header file */
    int have_window;           /* CdvrValueWindow (cdvr's key: a u8 volume's value window) */
    double window[2];
} mha_head;

static cdvr_status bad(const mha_head *h, const char *what, const char *line)
{
    return cdvr_error_set(h->err, CDVR_ERR_FORMAT, "%s: MetaImage: %s ('%.80s')", h->path, what,
                          line);
}

static int parse_bool(const char *s, int *v)
{
    if (strcasecmp(s, "True") == 0 || strcmp(s, "1") == 0)
        return *v = 1, 1;
    if (strcasecmp(s, "False") == 0 || strcmp(s, "0") == 0)
        return *v = 0, 1;
    return 0;
}

static int parse_etype(const char *s, cdvr_io_etype *t)
{
    static const struct { const char *name; cdvr_io_etype t; } types[] = {
        {"MET_UCHAR", CDVR_IO_U8}, {"MET_CHAR", CDVR_IO_I8}, {"MET_USHORT", CDVR_IO_U16},
        {"MET_SHORT", CDVR_IO_I16}, {"MET_UINT", CDVR_IO_U32}, {"MET_INT", CDVR_IO_I32},
        {"MET_ULONG", CDVR_IO_U32}, {"MET_LONG", CDVR_IO_I32}, {"MET_ULONG_LONG", CDVR_IO_U64},
        {"MET_LONG_LONG", CDVR_IO_I64}, {"MET_FLOAT", CDVR_IO_F32}, {"MET_DOUBLE", CDVR_IO_F64}};
    for (size_t i = 0; i < sizeof types / sizeof *types; i++)
        if (strcmp(s, types[i].name) == 0)
            return *t = types[i].t, 1;
    return 0;
}

/* n numbers (n <= 16) from s; 0 unless exactly n finite numbers. */
static int numbers(const char *s, double *v, int n)
{
    return n > 0 && n <= 16 && cdvr_io_parse_doubles(s, v, n);
}

/* One "key = value" line; *done at ElementDataFile. */
static cdvr_status mha_key(mha_head *h, const char *key, const char *val, const char *line,
                           int *done)
{
    int n = h->ndims, b;
    double v[16];
    if (strcasecmp(key, "NDims") == 0) {
        if (!numbers(val, v, 1) || !(v[0] >= 2 && v[0] <= 4 && v[0] == floor(v[0])))
            return bad(h, "NDims is not 2, 3 or 4", line);
        h->ndims = (int)v[0];
        for (int i = 0; i < 16; i++)
            h->matrix[i] = i < h->ndims * h->ndims && i % (h->ndims + 1) == 0;
    } else if (strcasecmp(key, "ObjectType") == 0) {
        if (strcasecmp(val, "Image") != 0)
            return bad(h, "ObjectType is not Image", line);
    } else if (!n && strcasecmp(key, "Comment") != 0)
        return bad(h, "a key before NDims", line);
    else if (strcasecmp(key, "DimSize") == 0) {
        if (!numbers(val, v, n))
            return bad(h, "DimSize is not NDims numbers", line);
        for (int i = 0; i < n; i++) {
            if (!(v[i] >= 1 && v[i] <= 1e9 && v[i] == floor(v[i])))
                return bad(h, "DimSize is not positive integers", line);
            h->dims[i] = (size_t)v[i];
        }
        h->have_dims = 1;
    } else if (strcasecmp(key, "ElementSpacing") == 0 || strcasecmp(key, "ElementSize") == 0) {
        if (!numbers(val, h->spacing, n))
            return bad(h, "ElementSpacing is not NDims numbers", line);
        for (int i = 0; i < n && i < 3; i++)
            if (!(h->spacing[i] > 0))
                return bad(h, "ElementSpacing is not positive", line);
    } else if (strcasecmp(key, "Offset") == 0 || strcasecmp(key, "Position") == 0 ||
               strcasecmp(key, "Origin") == 0) {
        if (!numbers(val, h->offset, n))
            return bad(h, "Offset is not NDims numbers", line);
    } else if (strcasecmp(key, "TransformMatrix") == 0 || strcasecmp(key, "Rotation") == 0 ||
               strcasecmp(key, "Orientation") == 0) {
        if (!numbers(val, h->matrix, n * n))
            return bad(h, "TransformMatrix is not NDims x NDims numbers", line);
    } else if (strcasecmp(key, "ElementType") == 0) {
        if (!parse_etype(val, &h->type))
            return bad(h, "ElementType is not a MET_ scalar type cdvr reads", line);
        h->have_type = 1;
    } else if (strcasecmp(key, "BinaryDataByteOrderMSB") == 0 ||
               strcasecmp(key, "ElementByteOrderMSB") == 0) {
        if (!parse_bool(val, &h->big_endian))
            return bad(h, "the byte order is not True or False", line);
    } else if (strcasecmp(key, "BinaryData") == 0) {
        if (!parse_bool(val, &b))
            return bad(h, "BinaryData is not True or False", line);
        if (!b)
            return cdvr_error_set(h->err, CDVR_ERR_UNSUPPORTED, "%s: MetaImage: ASCII data "
                                  "(BinaryData = False) are not supported", h->path);
    } else if (strcasecmp(key, "CompressedData") == 0) {
        if (!parse_bool(val, &h->compressed))
            return bad(h, "CompressedData is not True or False", line);
    } else if (strcasecmp(key, "CompressedDataSize") == 0) {
        if (!numbers(val, v, 1) || !(v[0] >= 0 && v[0] < 1e18 && v[0] == floor(v[0])))
            return bad(h, "CompressedDataSize is not a byte count", line);
        h->csize = (unsigned long long)v[0];
    } else if (strcasecmp(key, "ElementNumberOfChannels") == 0) {
        if (!numbers(val, v, 1) || v[0] != 1)
            return cdvr_error_set(h->err, CDVR_ERR_UNSUPPORTED, "%s: MetaImage: %s channels "
                                  "(cdvr reads scalars)", h->path, val);
    } else if (strcasecmp(key, "HeaderSize") == 0) {
        if (!numbers(val, v, 1) || !(v[0] >= -1 && v[0] < 1e18 && v[0] == floor(v[0])))
            return bad(h, "HeaderSize is not a byte count or -1", line);
        h->header_size = (long long)v[0];
    } else if (strcasecmp(key, "CdvrValueWindow") == 0) {
        if (!numbers(val, h->window, 2))
            return bad(h, "CdvrValueWindow is not two numbers", line);
        h->have_window = 1;
    } else if (strcasecmp(key, "ElementDataFile") == 0) {
        if (!*val)
            return bad(h, "ElementDataFile is empty", line);
        if (strcasecmp(val, "LIST") == 0 || strchr(val, '%'))
            return cdvr_error_set(h->err, CDVR_ERR_UNSUPPORTED, "%s: MetaImage: ElementDataFile "
                                  "'%s' (a list of slice files) is not supported", h->path, val);
        snprintf(h->data_file, sizeof h->data_file, "%s", val);
        *done = 1;
    }
    /* other keys (CenterOfRotation, AnatomicalOrientation, ElementMin, ...) carry nothing here */
    return CDVR_OK;
}

static char *trim(char *s)
{
    while (isspace((unsigned char)*s))
        s++;
    size_t n = strlen(s);
    while (n && isspace((unsigned char)s[n - 1]))
        s[--n] = 0;
    return s;
}

static cdvr_status mha_header(mha_head *h, const cdvr_io_map *map)
{
    size_t pos = 0;
    int done = 0;
    for (int i = 0; i < 4; i++)
        h->spacing[i] = 1;
    while (!done) {
        char line[MHA_LINE_MAX];
        size_t k = 0;
        if (pos >= map->n || pos > MHA_HEADER_MAX)
            return bad(h, pos ? "the header has no ElementDataFile line" : "empty file", "");
        while (pos < map->n && map->p[pos] != '\n') {
            if (k == sizeof line - 1 || map->p[pos] == 0)
                return bad(h, map->p[pos] ? "a header line is too long" : "a NUL in the header", "");
            line[k++] = (char)map->p[pos++];
        }
        pos += pos < map->n;
        line[k] = 0;
        char copy[MHA_LINE_MAX];
        memcpy(copy, line, k + 1);
        char *eq = strchr(copy, '=');
        char *s = trim(copy);
        if (!*s)
            continue;
        if (!eq)
            return bad(h, "a header line is not 'key = value'", line);
        *eq = 0;
        cdvr_status st = mha_key(h, trim(s), trim(eq + 1), line, &done);
        if (st != CDVR_OK)
            return st;
    }
    h->data_at = pos;
    if (!h->have_dims || !h->have_type)
        return bad(h, !h->have_dims ? "no DimSize before ElementDataFile"
                                    : "no ElementType before ElementDataFile", "");
    return CDVR_OK;
}

/* Dims, timesteps and geometry into head. */
static cdvr_status mha_geometry(const mha_head *h, cdvr_volume *head)
{
    int n = h->ndims;
    head->dims[2] = head->timesteps = 1;
    for (int i = 0; i < n; i++)
        if (i < 3)
            head->dims[i] = h->dims[i];
        else
            head->timesteps = h->dims[i];
    cdvr_io_set_type(head, h->type);
    double m[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    for (int c = 0; c < n && c < 3; c++) {
        head->spacing[c] = h->spacing[c];
        head->origin[c] = h->offset[c];
        for (int r = 0; r < n && r < 3; r++)
            m[3 * r + c] = h->matrix[c * n + r]; /* the file lists the axes' directions */
    }
    if (n == 2) { /* the third axis: the normal of the first two */
        m[2] = m[3] * m[7] - m[6] * m[4];
        m[5] = m[6] * m[1] - m[0] * m[7];
        m[8] = m[0] * m[4] - m[3] * m[1];
    }
    size_t bytes;
    if (!cdvr_volume_bytes_for(head->dims, head->timesteps, CDVR_TYPE_F32, &bytes))
        return cdvr_error_set(h->err, CDVR_ERR_FORMAT, "%s: MetaImage: DimSize overflows",
                              h->path);
    cdvr_status st = cdvr_io_set_direction(h->path, "MetaImage TransformMatrix", m, head, h->err);
    if (st == CDVR_OK && head->type == CDVR_TYPE_U8) {
        head->window[0] = 0;
        head->window[1] = 255;
        if (h->have_window)
            cdvr_u8_window_set(head, h->window[0], h->window[1]);
    }
    return st;
}

/* The data file's path (the header's directory + a relative name) into out. */
static cdvr_status data_path(const mha_head *h, char *out, size_t n)
{
    if (strcasecmp(h->data_file, "LOCAL") == 0)
        return snprintf(out, n, "%s", h->path), CDVR_OK;
    const char *slash = strrchr(h->path, '/');
    int dir = h->data_file[0] != '/' && slash ? (int)(slash - h->path + 1) : 0;
    if (snprintf(out, n, "%.*s%s", dir, h->path, h->data_file) >= (int)n)
        return cdvr_error_set(h->err, CDVR_ERR_ARG, "%s: MetaImage: data file name too long",
                              h->path);
    return CDVR_OK;
}

/* The data bytes in the data file's mapping: [*at, *at + *n). */
static cdvr_status data_span(const mha_head *h, const cdvr_io_map *dm, int local, size_t bytes,
                             const char *dpath, size_t *at, size_t *n)
{
    if (h->header_size == -1 && !h->compressed)
        *at = dm->n >= bytes ? dm->n - bytes : dm->n; /* the data end the file */
    else
        *at = local ? h->data_at : h->header_size > 0 ? (size_t)h->header_size : 0;
    if (*at > dm->n)
        return cdvr_error_set(h->err, CDVR_ERR_FORMAT, "%s: MetaImage: the data start at byte "
                              "%zu, past the end of %s (%zu bytes)", h->path, *at, dpath, dm->n);
    *n = dm->n - *at;
    if (h->compressed && h->csize) {
        if (h->csize > *n)
            return cdvr_error_set(h->err, CDVR_ERR_FORMAT, "%s: MetaImage: CompressedDataSize "
                                  "%llu is more than the %zu bytes %s holds", h->path, h->csize,
                                  *n, dpath);
        *n = (size_t)h->csize;
    }
    if (h->compressed ? bytes / 1032 > *n : bytes > *n)
        return cdvr_error_set(h->err, CDVR_ERR_FORMAT, "%s: MetaImage: DimSize %zux%zux%zux%zu of "
                              "%s need %zu bytes, %s holds %zu%s", h->path, h->dims[0],
                              h->dims[1], h->ndims > 2 ? h->dims[2] : 1,
                              h->ndims > 3 ? h->dims[3] : 1, cdvr_io_etype_name(h->type), bytes,
                              dpath, *n, h->compressed ? " (more than zlib can pack)" : "");
    return CDVR_OK;
}

static cdvr_status mha_probe_file(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                                  cdvr_error *err)
{
    (void)opts;
    cdvr_io_map map;
    cdvr_status st = cdvr_io_map_open(path, &map, err);
    if (st != CDVR_OK)
        return st;
    mha_head h = {.path = path, .err = err};
    st = mha_header(&h, &map);
    if (st == CDVR_OK)
        st = mha_geometry(&h, head);
    cdvr_io_map_close(&map);
    return st;
}

static cdvr_status mha_load_file(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                                 cdvr_error *err)
{
    *out = NULL;
    cdvr_io_map map, dmap = {NULL, 0};
    cdvr_status st = cdvr_io_map_open(path, &map, err);
    if (st != CDVR_OK)
        return st;
    mha_head h = {.path = path, .err = err};
    cdvr_volume head = {.spacing = {1, 1, 1}}, *vol = NULL;
    char dpath[4096 + MHA_LINE_MAX];
    st = mha_header(&h, &map);
    if (st == CDVR_OK)
        st = mha_geometry(&h, &head);
    int local = st == CDVR_OK && strcasecmp(h.data_file, "LOCAL") == 0;
    if (st == CDVR_OK)
        st = data_path(&h, dpath, sizeof dpath);
    if (st == CDVR_OK && !local)
        st = cdvr_io_map_open(dpath, &dmap, err);
    const cdvr_io_map *dm = local ? &map : &dmap;
    size_t count = 0, bytes = 0, at = 0, n = 0;
    if (st == CDVR_OK) {
        count = head.dims[0] * head.dims[1] * head.dims[2] * head.timesteps; /* checked */
        bytes = count * cdvr_io_etype_size(h.type);
        st = data_span(&h, dm, local, bytes, dpath, &at, &n);
    }
    if (st == CDVR_OK)
        st = cdvr_volume_create(head.dims, head.timesteps, head.type, &vol, err);
    uint8_t *buf = NULL;
    if (st == CDVR_OK && h.compressed && !(buf = malloc(bytes)))
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (st == CDVR_OK && h.compressed)
        st = cdvr_io_inflate(path, "MetaImage data", dm->p + at, n, buf, bytes, err);
    if (st == CDVR_OK) {
        cdvr_io_range range;
        cdvr_io_range_init(&range, opts);
        memcpy(vol->spacing, head.spacing, sizeof head.spacing);
        memcpy(vol->origin, head.origin, sizeof head.origin);
        memcpy(vol->direction, head.direction, sizeof head.direction);
        if (h.have_window)
            cdvr_u8_window_set(vol, h.window[0], h.window[1]);
        cdvr_io_store(vol, 0, buf ? buf : dm->p + at, h.type, h.big_endian, count, &range);
        st = cdvr_io_finish(vol, h.type, &range, path, "MetaImage", err);
    }
    if (st == CDVR_OK)
        *out = vol;
    else
        cdvr_volume_free(vol);
    free(buf);
    cdvr_io_map_close(&dmap);
    cdvr_io_map_close(&map);
    return st;
}

/* The first key of a MetaImage header (ITK writes ObjectType; NDims may come first). */
static int mha_magic(const uint8_t *head, size_t n)
{
    static const char *const keys[] = {"ObjectType = Image", "NDims = "};
    for (int i = 0; i < 2; i++) {
        size_t k = strlen(keys[i]);
        if (n >= k && memcmp(head, keys[i], k) == 0)
            return 1;
    }
    return 0;
}

static const char *const mha_suffixes[] = {".mha", ".mhd", NULL};

const cdvr_format cdvr_format_mha = {
    .name = "mha",
    .description = "MetaImage (ITK): .mha, or .mhd with a data file; raw or zlib, "
                   "TransformMatrix, 2D to 4D (time); 64-bit and int32 as float32, window in "
                   "double",
    .suffixes = mha_suffixes,
    .magic = mha_magic,
    .probe = mha_probe_file,
    .load = mha_load_file,
};
