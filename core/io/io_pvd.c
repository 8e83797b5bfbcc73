/* core/io/io_pvd.c - ParaView data collections (.pvd, format "pvd"): a series of VTK files with
 * their time values, parsed with expat (cdvr/pvd.h). */
#include "cdvr/format.h"
#include "cdvr/pvd.h"
#include "cdvr/series.h"
#include "io_common.h"

#include <errno.h>
#include <expat.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#define PVD_ENTRIES_MAX 1000000
#define PVD_BYTES_MAX ((size_t)64 << 20)

typedef struct pvd_parse {
    const char *path;
    XML_Parser xp;
    cdvr_error *err;
    cdvr_status st;
    int depth, seen_root, in_collection;
    cdvr_pvd_entry *items;
    size_t count, cap;
} pvd_parse;

static const char *attr(const XML_Char **a, const char *name)
{
    for (size_t i = 0; a[i]; i += 2)
        if (strcmp(a[i], name) == 0)
            return a[i + 1];
    return NULL;
}

static void stop(pvd_parse *p, cdvr_status st, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

static void stop(pvd_parse *p, cdvr_status st, const char *fmt, ...)
{
    if (p->st != CDVR_OK)
        return;
    char why[CDVR_ERRMSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    p->st = cdvr_error_set(p->err, st, "%s: %s", p->path, why);
    XML_StopParser(p->xp, XML_FALSE);
}

static int pvd_suffix(const char *name)
{
    size_t n = strlen(name);
    return n >= 4 && strcasecmp(name + n - 4, ".pvd") == 0;
}

/* Records the failure and stops the parse; returns 0 (for `return fail(...)` in int code). */
#define FAIL(...) (stop(__VA_ARGS__), 0)

static int dataset(pvd_parse *p, const XML_Char **a)
{
    size_t i = p->count;
    const char *file = attr(a, "file"), *ts = attr(a, "timestep"), *part = attr(a, "part");
    char *end;
    if (!file || !file[0])
        return FAIL(p, CDVR_ERR_FORMAT, "DataSet %zu has no file=", i);
    if (!ts)
        return FAIL(p, CDVR_ERR_FORMAT, "DataSet %zu (%s) has no timestep=", i, file);
    double t = strtod(ts, &end);
    while (*end == ' ' || *end == '\t')
        end++;
    if (end == ts || *end || !isfinite(t))
        return FAIL(p, CDVR_ERR_FORMAT, "DataSet %zu: timestep=\"%s\" is not a finite number",
                    i, ts);
    if (part && part[0] && strtol(part, &end, 10) != 0)
        return FAIL(p, CDVR_ERR_UNSUPPORTED, "DataSet %zu: part=\"%s\": collections of several "
                    "parts per timestep are not read", i, part);
    if (pvd_suffix(file))
        return FAIL(p, CDVR_ERR_FORMAT, "DataSet %zu names another collection (%s): "
                    "collections do not nest", i, file);
    if (p->count == p->cap) {
        size_t cap = p->cap ? 2 * p->cap : 16;
        cdvr_pvd_entry *items = p->count < PVD_ENTRIES_MAX
                                    ? realloc(p->items, cap * sizeof *items) : NULL;
        if (!items)
            return FAIL(p, p->count < PVD_ENTRIES_MAX ? CDVR_ERR_NOMEM : CDVR_ERR_FORMAT,
                        "more than %d DataSets or out of memory", PVD_ENTRIES_MAX);
        p->items = items;
        p->cap = cap;
    }
    if (!(p->items[i].file = strdup(file)))
        return FAIL(p, CDVR_ERR_NOMEM, "out of memory");
    p->items[i].time = t;
    p->count++;
    return 1;
}

static void XMLCALL on_start(void *ud, const XML_Char *el, const XML_Char **a)
{
    pvd_parse *p = ud;
    int depth = p->depth++;
    if (depth == 0) {
        const char *type = attr(a, "type");
        if (strcmp(el, "VTKFile") != 0 || !type || strcmp(type, "Collection") != 0) {
            stop(p, CDVR_ERR_FORMAT, "not a ParaView collection (the root is <%s>, not "
                 "<VTKFile type=\"Collection\">)", el);
            return;
        }
        p->seen_root = 1;
    } else if (depth == 1 && strcmp(el, "Collection") == 0) {
        p->in_collection = 1;
    } else if (depth == 2 && p->in_collection && strcmp(el, "DataSet") == 0) {
        (void)dataset(p, a);
    }
}

static void XMLCALL on_end(void *ud, const XML_Char *el)
{
    pvd_parse *p = ud;
    (void)el;
    if (--p->depth == 1)
        p->in_collection = 0;
}

static void XMLCALL on_doctype(void *ud, const XML_Char *name, const XML_Char *sys,
                               const XML_Char *pub, int internal)
{
    (void)name, (void)sys, (void)pub, (void)internal;
    stop(ud, CDVR_ERR_FORMAT, "a DOCTYPE is not allowed in a VTK file");
}

void cdvr_pvd_free(cdvr_pvd_entry *entries, size_t n)
{
    for (size_t i = 0; entries && i < n; i++)
        free(entries[i].file);
    free(entries);
}

/* Stable order by time: insertion sort would be quadratic; merge through a copy. */
static void sort_by_time(cdvr_pvd_entry *e, cdvr_pvd_entry *tmp, size_t n)
{
    if (n < 2)
        return;
    size_t h = n / 2;
    sort_by_time(e, tmp, h);
    sort_by_time(e + h, tmp, n - h);
    size_t i = 0, j = h, k = 0;
    while (i < h && j < n)
        tmp[k++] = e[j].time < e[i].time ? e[j++] : e[i++];
    while (i < h)
        tmp[k++] = e[i++];
    while (j < n)
        tmp[k++] = e[j++];
    memcpy(e, tmp, n * sizeof *e);
}

cdvr_status cdvr_pvd_parse(const char *path, const char *text, size_t len, cdvr_pvd_entry **out,
                           size_t *n, cdvr_error *err)
{
    *out = NULL;
    *n = 0;
    if (len > PVD_BYTES_MAX)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: a collection of %zu bytes (more than "
                              "%zu)", path, len, PVD_BYTES_MAX);
    pvd_parse p = {.path = path, .err = err, .st = CDVR_OK};
    if (!(p.xp = XML_ParserCreate(NULL)))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot create an XML parser", path);
    XML_SetUserData(p.xp, &p);
    XML_SetElementHandler(p.xp, on_start, on_end);
    XML_SetStartDoctypeDeclHandler(p.xp, on_doctype);
    enum XML_Status xs = XML_Parse(p.xp, text ? text : "", (int)len, 1);
    if (xs == XML_STATUS_ERROR && p.st == CDVR_OK)
        p.st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: XML error at line %lu: %s", path,
                              (unsigned long)XML_GetCurrentLineNumber(p.xp),
                              XML_ErrorString(XML_GetErrorCode(p.xp)));
    XML_ParserFree(p.xp);
    if (p.st == CDVR_OK && !p.seen_root)
        p.st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not a ParaView collection", path);
    if (p.st == CDVR_OK && p.count == 0)
        p.st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the collection has no DataSet", path);
    cdvr_pvd_entry *tmp = p.st == CDVR_OK ? malloc(p.count * sizeof *tmp) : NULL;
    if (p.st == CDVR_OK && !tmp)
        p.st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (p.st != CDVR_OK) {
        cdvr_pvd_free(p.items, p.count);
        return p.st;
    }
    sort_by_time(p.items, tmp, p.count);
    free(tmp);
    *out = p.items;
    *n = p.count;
    return CDVR_OK;
}

/* The directory of path (realpath'd when confined). */
static cdvr_status dir_of(const char *path, int resolve, char **out, cdvr_error *err)
{
    const char *slash = strrchr(path, '/');
    size_t k = !slash ? 0 : slash == path ? 1 : (size_t)(slash - path);
    char *dir = malloc(k + 2);
    if (!dir)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (k)
        memcpy(dir, path, k);
    else
        dir[k++] = '.';
    dir[k] = '\0';
    if (resolve) {
        char *real = realpath(dir, NULL);
        int e = errno;
        free(dir);
        if (!real)
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: its directory: %s", path, strerror(e));
        dir = real;
    }
    *out = dir;
    return CDVR_OK;
}

/* Entry file resolved against dir (the .pvd's directory as named) and confined to real. */
static cdvr_status resolve(const char *path, const char *dir, const char *real, size_t i,
                           char **file, cdvr_error *err)
{
    const char *name = *file;
    size_t n = strlen(dir) + strlen(name) + 2;
    char *joined = malloc(n);
    if (!joined)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (name[0] == '/')
        snprintf(joined, n, "%s", name);
    else
        snprintf(joined, n, "%s/%s", dir, name);
    if (real) {
        char *r = realpath(joined, NULL);
        if (!r) {
            cdvr_status st = cdvr_error_set(err, CDVR_ERR_IO, "%s: DataSet %zu file %s: %s",
                                            path, i, joined, strerror(errno));
            free(joined);
            return st;
        }
        size_t k = strlen(real);
        int inside = strncmp(r, real, k) == 0 && (r[k] == '/' || (k == 1 && real[0] == '/'));
        if (!inside) {
            cdvr_status st = cdvr_error_set(err, CDVR_ERR_ARG, "%s: DataSet %zu file %s (%s) "
                                            "is outside the collection's directory %s (load "
                                            "option allow_outside=true reads it)", path, i, name,
                                            r, real);
            free(r);
            free(joined);
            return st;
        }
        free(r);
    }
    free(*file);
    *file = joined;
    return CDVR_OK;
}

cdvr_status cdvr_pvd_read(const char *path, const cdvr_raw_opts *opts, cdvr_pvd_entry **out,
                          size_t *n, cdvr_error *err)
{
    *out = NULL;
    *n = 0;
    cdvr_io_map map;
    cdvr_status st = cdvr_io_map_open(path, &map, err);
    if (st != CDVR_OK)
        return st;
    cdvr_pvd_entry *e = NULL;
    size_t count = 0;
    st = cdvr_pvd_parse(path, (const char *)map.p, map.n, &e, &count, err);
    cdvr_io_map_close(&map);
    int confine = !(opts && opts->allow_outside);
    char *dir = NULL, *real = NULL;
    if (st == CDVR_OK)
        st = dir_of(path, 0, &dir, err);
    if (st == CDVR_OK && confine)
        st = dir_of(path, 1, &real, err);
    for (size_t i = 0; st == CDVR_OK && i < count; i++)
        st = resolve(path, dir, real, i, &e[i].file, err);
    free(dir);
    free(real);
    if (st != CDVR_OK) {
        cdvr_pvd_free(e, count);
        return st;
    }
    *out = e;
    *n = count;
    return CDVR_OK;
}

/* ---- format table --------------------------------------------------------------------------- */

cdvr_status cdvr_pvd_expand(const char *path, const cdvr_raw_opts *opts,
                            int (*add)(void *ud, const char *file), void *ud, cdvr_error *err)
{
    cdvr_pvd_entry *e;
    size_t n;
    cdvr_status st = cdvr_pvd_read(path, opts, &e, &n, err);
    if (st != CDVR_OK)
        return st;
    for (size_t i = 0; st == CDVR_OK && i < n; i++)
        if (!add(ud, e[i].file))
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    cdvr_pvd_free(e, n);
    return st;
}

/* The whole collection: its files' headers (dims, type of the first; timesteps of all). */
static cdvr_status pvd_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                             cdvr_error *err)
{
    cdvr_series *s;
    cdvr_status st = cdvr_series_open(&path, 1, opts, &s, err);
    if (st != CDVR_OK)
        return st;
    const cdvr_series_info *in = cdvr_series_get_info(s);
    memcpy(head->dims, in->dims, sizeof head->dims);
    head->timesteps = in->timesteps;
    head->type = in->type;
    memcpy(head->spacing, in->spacing, sizeof head->spacing);
    memcpy(head->origin, in->origin, sizeof head->origin);
    memcpy(head->direction, in->direction, sizeof head->direction);
    memcpy(head->source_type, in->source_type, sizeof head->source_type);
    cdvr_series_close(s);
    return CDVR_OK;
}

static cdvr_status pvd_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                            cdvr_error *err)
{
    return cdvr_volume_load_series(&path, 1, opts, out, err);
}

static int pvd_magic(const uint8_t *head, size_t n)
{
    static const char key[] = "type=\"Collection\"";
    for (size_t i = 0; i + sizeof key - 1 <= n; i++)
        if (memcmp(head + i, key, sizeof key - 1) == 0)
            return 1;
    return 0;
}

static const char *const pvd_suffixes[] = {".pvd", NULL};

const cdvr_format cdvr_format_pvd = {
    .name = "pvd",
    .description = "ParaView collection (.pvd, through expat): the series of its DataSet files "
                   "in timestep order, the time values kept",
    .suffixes = pvd_suffixes,
    .magic = pvd_magic,
    .probe = pvd_probe,
    .load = pvd_load,
    .expand_opts = cdvr_pvd_expand,
};
