/* core/io/io_vtk.c - legacy VTK files (.vtk), DATASET STRUCTURED_POINTS (format "vtk";
 * cdvr/vti.h names an array). VTK is C++, so this header reader is ours (and fuzzed).
 *
 * File layout (VTK's "File Formats" document, versions 2.0 to 5.1):
 *   # vtk DataFile Version x.y          line 1
 *   title                               line 2 (anything, up to 256 bytes)
 *   ASCII | BINARY                      line 3
 *   DATASET STRUCTURED_POINTS
 *   DIMENSIONS nx ny nz                 then, in any order: ORIGIN x y z, SPACING sx sy sz (or
 *                                       ASPECT_RATIO), DIRECTION d0..d8 (row-major, optional)
 *   POINT_DATA n                        n = nx*ny*nz
 *   SCALARS name type [components]      one or more arrays; each but the chosen one skipped
 *   LOOKUP_TABLE table                  (optional) then the n values: ASCII numbers, or BINARY
 *                                       big-endian values right after this line's newline
 * Types: bit is refused; unsigned_char, char, (unsigned_)short, (unsigned_)int, (unsigned_)long
 * (64 bits), vtktypeint64, vtktypeuint64, float, double. World of voxel (i,j,k) = ORIGIN +
 * DIRECTION * ((i,j,k) * SPACING). */
#include "cdvr/vti.h"
#include "cdvr/format.h"
#include "io_common.h"
#include "volume_io.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define LINE_MAX_BYTES 1024

typedef struct vtk_parse {
    const char *path, *want;
    const cdvr_raw_opts *opts; /* the load options (the f32 rule), or NULL */
    cdvr_error *err;
    const cdvr_io_map *map;
    size_t pos; /* next byte of the file */
    int binary;
    size_t dims[3], points;
    double origin[3], spacing[3], dir[9];
    char name[128];
    cdvr_io_etype type;
    size_t data_at; /* first byte of the chosen array's values */
} vtk_parse;

/* The next line (without its newline) into line; 0 at the end of the file or when too long. */
static int next_line(vtk_parse *v, char line[LINE_MAX_BYTES])
{
    const uint8_t *p = v->map->p;
    size_t n = v->map->n, k = 0;
    if (v->pos >= n)
        return 0;
    while (v->pos < n && p[v->pos] != '\n') {
        if (k == LINE_MAX_BYTES - 1)
            return 0;
        line[k++] = (char)p[v->pos++];
    }
    v->pos += v->pos < n; /* the newline */
    if (k && line[k - 1] == '\r')
        k--;
    line[k] = 0;
    return 1;
}

/* The next line that is not blank. */
static int next_content(vtk_parse *v, char line[LINE_MAX_BYTES])
{
    while (next_line(v, line)) {
        const char *s = line;
        while (isspace((unsigned char)*s))
            s++;
        if (*s)
            return 1;
    }
    return 0;
}

static cdvr_status bad(const vtk_parse *v, const char *what, const char *line)
{
    return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: legacy VTK: %s ('%.80s')", v->path, what,
                          line);
}

static int parse_type(const char *s, cdvr_io_etype *t)
{
    static const struct { const char *name; cdvr_io_etype t; } types[] = {
        {"unsigned_char", CDVR_IO_U8}, {"char", CDVR_IO_I8}, {"signed_char", CDVR_IO_I8},
        {"unsigned_short", CDVR_IO_U16}, {"short", CDVR_IO_I16}, {"unsigned_int", CDVR_IO_U32},
        {"int", CDVR_IO_I32}, {"unsigned_long", CDVR_IO_U64}, {"long", CDVR_IO_I64},
        {"vtktypeuint64", CDVR_IO_U64}, {"vtktypeint64", CDVR_IO_I64}, {"float", CDVR_IO_F32},
        {"double", CDVR_IO_F64}};
    for (size_t i = 0; i < sizeof types / sizeof *types; i++)
        if (strcasecmp(s, types[i].name) == 0) {
            *t = types[i].t;
            return 1;
        }
    return 0;
}

/* Past the values of an array of count elements of type t (not the chosen one). */
static int skip_values(vtk_parse *v, size_t count, cdvr_io_etype t)
{
    if (v->binary) {
        size_t bytes;
        if (!cdvr_size_mul(count, cdvr_io_etype_size(t), &bytes) || bytes > v->map->n - v->pos)
            return 0;
        v->pos += bytes;
        return 1;
    }
    double x;
    for (size_t i = 0; i < count; i++)
        if (!cdvr_io_ascii_number(v->map->p, v->map->n, &v->pos, &x))
            return 0;
    return 1;
}

/* The header up to the chosen array's values (v->data_at). */
static cdvr_status vtk_header(vtk_parse *v)
{
    char line[LINE_MAX_BYTES], word[64], arg[128], type[64];
    if (!next_line(v, line) || strncmp(line, "# vtk DataFile Version", 22) != 0)
        return bad(v, "line 1 is not '# vtk DataFile Version'", v->map->n ? line : "");
    if (!next_line(v, line) || !next_content(v, line))
        return bad(v, "no ASCII or BINARY line", "");
    if (sscanf(line, "%63s", word) != 1 || (strcasecmp(word, "ASCII") != 0 &&
                                            strcasecmp(word, "BINARY") != 0))
        return bad(v, "line 3 is neither ASCII nor BINARY", line);
    v->binary = strcasecmp(word, "BINARY") == 0;
    if (!next_content(v, line) || sscanf(line, "%63s %127s", word, arg) != 2 ||
        strcasecmp(word, "DATASET") != 0)
        return bad(v, "no DATASET line", line);
    if (strcasecmp(arg, "STRUCTURED_POINTS") != 0)
        return cdvr_error_set(v->err, CDVR_ERR_UNSUPPORTED, "%s: legacy VTK DATASET %s is not "
                              "supported (cdvr reads STRUCTURED_POINTS)", v->path, arg);
    v->spacing[0] = v->spacing[1] = v->spacing[2] = 1;
    v->dir[0] = v->dir[4] = v->dir[8] = 1;
    int in_point = 0;
    while (next_content(v, line)) {
        const char *rest = line;
        while (isspace((unsigned char)*rest))
            rest++;
        if (sscanf(rest, "%63s", word) != 1)
            continue;
        rest += strlen(word);
        if (strcasecmp(word, "DIMENSIONS") == 0) {
            double d[3];
            if (!cdvr_io_parse_doubles(rest, d, 3))
                return bad(v, "DIMENSIONS is not 3 numbers", line);
            for (int i = 0; i < 3; i++) {
                if (!(d[i] >= 1 && d[i] <= 1e9 && d[i] == floor(d[i])))
                    return bad(v, "DIMENSIONS are not positive integers", line);
                v->dims[i] = (size_t)d[i];
            }
        } else if (strcasecmp(word, "ORIGIN") == 0) {
            if (!cdvr_io_parse_doubles(rest, v->origin, 3))
                return bad(v, "ORIGIN is not 3 finite numbers", line);
        } else if (strcasecmp(word, "SPACING") == 0 || strcasecmp(word, "ASPECT_RATIO") == 0) {
            if (!cdvr_io_parse_doubles(rest, v->spacing, 3) || !(v->spacing[0] > 0) ||
                !(v->spacing[1] > 0) || !(v->spacing[2] > 0))
                return bad(v, "SPACING is not 3 positive numbers", line);
        } else if (strcasecmp(word, "DIRECTION") == 0) {
            if (!cdvr_io_parse_doubles(rest, v->dir, 9))
                return bad(v, "DIRECTION is not 9 finite numbers", line);
        } else if (strcasecmp(word, "POINT_DATA") == 0) {
            double n;
            if (!v->dims[0])
                return bad(v, "POINT_DATA before DIMENSIONS", line);
            v->points = v->dims[0] * v->dims[1] * v->dims[2]; /* each <= 1e9: no overflow */
            if (!cdvr_io_parse_doubles(rest, &n, 1) || n != (double)v->points)
                return bad(v, "POINT_DATA is not the DIMENSIONS' product", line);
            in_point = 1;
        } else if (strcasecmp(word, "SCALARS") == 0 && in_point) {
            int comps = 1;
            int got = sscanf(rest, "%127s %63s %d", arg, type, &comps);
            cdvr_io_etype t;
            if (got < 2 || !parse_type(type, &t))
                return bad(v, "SCALARS has no name or a type cdvr does not read", line);
            size_t at = v->pos;
            char look[LINE_MAX_BYTES];
            if (next_content(v, look) && strncasecmp(look, "LOOKUP_TABLE", 12) == 0)
                at = v->pos;
            v->pos = at;
            int chosen = v->want ? strcmp(arg, v->want) == 0 : 1;
            if (chosen && comps != 1)
                return cdvr_error_set(v->err, CDVR_ERR_UNSUPPORTED, "%s: legacy VTK: SCALARS "
                                      "'%s' has %d components (cdvr reads scalars)", v->path,
                                      arg, comps);
            if (chosen) {
                snprintf(v->name, sizeof v->name, "%s", arg);
                v->type = t;
                v->data_at = v->pos;
                return CDVR_OK;
            }
            if (comps < 1 || comps > 16 || !skip_values(v, v->points * (size_t)comps, t))
                return bad(v, "an array before the chosen one is cut", line);
        } else if (strcasecmp(word, "CELL_DATA") == 0 || strcasecmp(word, "FIELD") == 0 ||
                   strcasecmp(word, "VECTORS") == 0 || strcasecmp(word, "NORMALS") == 0 ||
                   strcasecmp(word, "TENSORS") == 0 || strcasecmp(word, "COLOR_SCALARS") == 0 ||
                   strcasecmp(word, "TEXTURE_COORDINATES") == 0) {
            return cdvr_error_set(v->err, CDVR_ERR_UNSUPPORTED, "%s: legacy VTK: %s before the "
                                  "%s%s%s scalars is not supported", v->path, word,
                                  v->want ? "array '" : "point-data", v->want ? v->want : "",
                                  v->want ? "'" : "");
        } else
            return bad(v, "unknown keyword", line);
    }
    if (!v->dims[0])
        return bad(v, "no DIMENSIONS", "");
    return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: legacy VTK: no point-data SCALARS%s%s%s",
                          v->path, v->want ? " named '" : "", v->want ? v->want : "",
                          v->want ? "'" : "");
}

static cdvr_status vtk_geometry(const vtk_parse *v, cdvr_volume *head)
{
    memcpy(head->dims, v->dims, sizeof head->dims);
    head->timesteps = 1;
    cdvr_io_set_type(head, v->type);
    memcpy(head->spacing, v->spacing, sizeof head->spacing);
    memcpy(head->origin, v->origin, sizeof head->origin);
    return cdvr_io_set_direction(v->path, "DIRECTION", v->dir, head, v->err);
}

static cdvr_status vtk_voxels(vtk_parse *v, cdvr_volume *vol)
{
    size_t count = v->points, esize = cdvr_io_etype_size(v->type);
    cdvr_io_range range;
    cdvr_io_range_init(&range, v->opts);
    if (v->binary) {
        if (count > (v->map->n - v->data_at) / esize)
            return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: legacy VTK: SCALARS '%s' need "
                                  "%zu bytes, the file holds %zu after the header", v->path,
                                  v->name, count * esize, v->map->n - v->data_at);
        cdvr_io_store(vol, 0, v->map->p + v->data_at, v->type, 1, count, &range);
    } else {
        size_t pos = v->data_at;
        double x;
        for (size_t i = 0; i < count; i++) {
            if (!cdvr_io_ascii_number(v->map->p, v->map->n, &pos, &x))
                return cdvr_error_set(v->err, CDVR_ERR_FORMAT, "%s: legacy VTK: SCALARS '%s': "
                                      "value %zu of %zu is missing or not a number", v->path,
                                      v->name, i, count);
            cdvr_io_store_double(vol, i, x, &range);
        }
    }
    return cdvr_io_finish(vol, v->type, &range, v->path, "legacy VTK", v->err);
}

static void fill_info(const vtk_parse *v, cdvr_vti_info *info)
{
    if (!info)
        return;
    snprintf(info->array, sizeof info->array, "%s", v->name);
    snprintf(info->file_type, sizeof info->file_type, "%s", cdvr_io_etype_name(v->type));
    info->converted = cdvr_io_etype_converted(v->type);
}

cdvr_status cdvr_vtk_legacy_probe(const char *path, const char *array, cdvr_volume *head,
                                  cdvr_vti_info *info, cdvr_error *err)
{
    cdvr_io_map map;
    cdvr_status st = cdvr_io_map_open(path, &map, err);
    if (st != CDVR_OK)
        return st;
    vtk_parse v = {.path = path, .want = array, .err = err, .map = &map};
    st = vtk_header(&v);
    if (st == CDVR_OK)
        st = vtk_geometry(&v, head);
    if (st == CDVR_OK)
        fill_info(&v, info);
    cdvr_io_map_close(&map);
    return st;
}

cdvr_status cdvr_vtk_legacy_load(const char *path, const char *array, const cdvr_raw_opts *opts,
                                 cdvr_volume **out, cdvr_vti_info *info, cdvr_error *err)
{
    *out = NULL;
    cdvr_io_map map;
    cdvr_status st = cdvr_io_map_open(path, &map, err);
    if (st != CDVR_OK)
        return st;
    vtk_parse v = {.path = path, .want = array, .opts = opts, .err = err, .map = &map};
    cdvr_volume head = {.spacing = {1, 1, 1}}, *vol = NULL;
    st = vtk_header(&v);
    if (st == CDVR_OK)
        st = vtk_geometry(&v, &head);
    if (st == CDVR_OK && v.binary &&
        v.points > (map.n - v.data_at) / cdvr_io_etype_size(v.type)) /* before allocating */
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: legacy VTK: SCALARS '%s' need %zu bytes, "
                            "the file holds %zu after the header", path, v.name,
                            v.points * cdvr_io_etype_size(v.type), map.n - v.data_at);
    if (st == CDVR_OK && !v.binary && v.points > (map.n - v.data_at + 1) / 2)
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: legacy VTK: SCALARS '%s': %zu ASCII "
                            "values cannot fit in the %zu bytes after the header", path, v.name,
                            v.points, map.n - v.data_at);
    if (st == CDVR_OK)
        st = cdvr_volume_create(head.dims, 1, head.type, &vol, err);
    if (st == CDVR_OK) {
        memcpy(vol->spacing, head.spacing, sizeof head.spacing);
        memcpy(vol->origin, head.origin, sizeof head.origin);
        memcpy(vol->direction, head.direction, sizeof head.direction);
        st = vtk_voxels(&v, vol);
    }
    if (st == CDVR_OK) {
        fill_info(&v, info);
        *out = vol;
    } else
        cdvr_volume_free(vol);
    cdvr_io_map_close(&map);
    return st;
}

/* ---- format table ------------------------------------------------------------------------ */

/* The array the load option select= names (cdvr_raw_opts.select), or NULL: the default. */
static const char *selected_array(const cdvr_raw_opts *opts)
{
    return opts && opts->select && opts->select[0] ? opts->select : NULL;
}

static int vtk_magic(const uint8_t *head, size_t n)
{
    static const char key[] = "# vtk DataFile Version";
    return n >= sizeof key - 1 && memcmp(head, key, sizeof key - 1) == 0;
}

static cdvr_status vtk_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                             cdvr_error *err)
{
    return cdvr_vtk_legacy_probe(path, selected_array(opts), head, NULL, err);
}

static cdvr_status vtk_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                            cdvr_error *err)
{
    return cdvr_vtk_legacy_load(path, selected_array(opts), opts, out, NULL, err);
}

static const char *const vtk_suffixes[] = {".vtk", NULL};

const cdvr_format cdvr_format_vtk = {
    .name = "vtk",
    .description = "legacy VTK STRUCTURED_POINTS, ASCII or BINARY, the first point-data "
                   "SCALARS or select= (64-bit and int32 types as float32, window in double)",
    .suffixes = vtk_suffixes,
    .magic = vtk_magic,
    .probe = vtk_probe,
    .load = vtk_load,
};
