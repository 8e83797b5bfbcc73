/* core/io/format.c - the format registry (cdvr/format.h) and the dispatch of cdvr_volume_load.
 *
 * The registry is the one process-wide table of file formats (a named context: `registry`
 * below), guarded by a mutex because plugins may be loaded while other threads load files. The
 * built-ins are registered on first use (pthread_once). A new built-in format is one file
 * (core/io/io_NAME.c defining `const cdvr_format cdvr_format_NAME`) plus one line in `builtins`
 * below and one name in core/io/CMakeLists.txt. */
#include "cdvr/format.h"
#include "cdvr/names.h"
#include "cdvr/regular_file.h"
#include "volume_io.h"

#include <errno.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

extern const cdvr_format cdvr_format_nrrd;
extern const cdvr_format cdvr_format_nifti;
extern const cdvr_format cdvr_format_raw;
extern const cdvr_format cdvr_format_vti;
extern const cdvr_format cdvr_format_vtk;
extern const cdvr_format cdvr_format_mha;
extern const cdvr_format cdvr_format_tiff;
extern const cdvr_format cdvr_format_hdf5;
extern const cdvr_format cdvr_format_netcdf;
extern const cdvr_format cdvr_format_pvd;

#define REGISTRY_MAX 64

static struct {
    pthread_mutex_t mu;
    pthread_once_t once;
    const cdvr_format *formats[REGISTRY_MAX];
    size_t count;
} registry = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_ONCE_INIT, {NULL}, 0};

static cdvr_status check_table(const cdvr_format *f, cdvr_error *err)
{
    if (!f)
        return cdvr_error_set(err, CDVR_ERR_ARG, "format table is NULL");
    if (!cdvr_name_valid(f->name, CDVR_FORMAT_NAME_MAX))
        return cdvr_error_set(err, CDVR_ERR_ARG, "format name '%s' is not 1..%d characters of "
                              "[a-z0-9_]", f->name ? f->name : "(null)", CDVR_FORMAT_NAME_MAX - 1);
    const char *missing = !f->description ? "description" : !f->suffixes ? "suffixes"
                        : !f->probe ? "probe" : (!f->load && !f->read) ? "load or read" : NULL;
    if (missing)
        return cdvr_error_set(err, CDVR_ERR_ARG, "format '%s': the table has no %s", f->name,
                              missing);
    if (!f->suffixes[0] && !f->magic)
        return cdvr_error_set(err, CDVR_ERR_ARG, "format '%s': the table has neither a suffix "
                              "nor a magic test (nothing could find it)", f->name);
    for (size_t i = 0; f->suffixes[i]; i++)
        if (f->suffixes[i][0] != '.' || !f->suffixes[i][1] || strlen(f->suffixes[i]) > 32)
            return cdvr_error_set(err, CDVR_ERR_ARG, "format '%s': suffix '%s' is not '.' and "
                                  "1..31 characters", f->name, f->suffixes[i]);
    return CDVR_OK;
}

/* The first suffix of a that b has too, or NULL. */
static const char *shared_suffix(const cdvr_format *a, const cdvr_format *b)
{
    for (size_t i = 0; a->suffixes[i]; i++)
        for (size_t j = 0; b->suffixes[j]; j++)
            if (strcasecmp(a->suffixes[i], b->suffixes[j]) == 0)
                return a->suffixes[i];
    return NULL;
}

/* Caller holds registry.mu. */
static cdvr_status add_locked(const cdvr_format *f, cdvr_error *err)
{
    cdvr_status s = check_table(f, err);
    if (s != CDVR_OK)
        return s;
    for (size_t i = 0; i < registry.count; i++) {
        const cdvr_format *o = registry.formats[i];
        const char *suffix;
        if (o == f)
            return CDVR_OK;
        if (strcmp(o->name, f->name) == 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "format '%s' is already registered",
                                  f->name);
        if ((suffix = shared_suffix(f, o)) != NULL)
            return cdvr_error_set(err, CDVR_ERR_ARG, "format '%s': suffix %s is already taken "
                                  "by format '%s'", f->name, suffix, o->name);
    }
    if (registry.count == REGISTRY_MAX)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "format '%s': the registry is full (%d "
                              "formats)", f->name, REGISTRY_MAX);
    registry.formats[registry.count++] = f;
    return CDVR_OK;
}

static void register_builtins(void)
{
    static const cdvr_format *const builtins[] = {&cdvr_format_nrrd, &cdvr_format_nifti,
                                                     &cdvr_format_raw,
                                                     &cdvr_format_vti, &cdvr_format_vtk,
                                                     &cdvr_format_mha, &cdvr_format_tiff,
                                                     &cdvr_format_hdf5, /* io_hdf5.c */
                                                     &cdvr_format_netcdf,
                                                     &cdvr_format_pvd};
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; i < sizeof builtins / sizeof *builtins; i++)
        (void)add_locked(builtins[i], NULL); /* built-ins are valid: test_format checks */
    pthread_mutex_unlock(&registry.mu);
}

static void ensure_builtins(void)
{
    pthread_once(&registry.once, register_builtins);
}

cdvr_status cdvr_format_register(const cdvr_format *format, cdvr_error *err)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    cdvr_status s = add_locked(format, err);
    pthread_mutex_unlock(&registry.mu);
    return s;
}

const cdvr_format *cdvr_format_find(const char *name)
{
    ensure_builtins();
    const cdvr_format *found = NULL;
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; name && !found && i < registry.count; i++)
        if (strcmp(registry.formats[i]->name, name) == 0)
            found = registry.formats[i];
    pthread_mutex_unlock(&registry.mu);
    return found;
}

static int ends_with(const char *path, const char *suffix)
{
    size_t n = strlen(path), k = strlen(suffix);
    return n >= k && strcasecmp(path + n - k, suffix) == 0;
}

const cdvr_format *cdvr_format_by_suffix(const char *path)
{
    ensure_builtins();
    const cdvr_format *found = NULL;
    size_t best = 0;
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; path && i < registry.count; i++)
        for (const char *const *s = registry.formats[i]->suffixes; *s; s++)
            if (strlen(*s) > best && ends_with(path, *s)) {
                best = strlen(*s);
                found = registry.formats[i];
            }
    pthread_mutex_unlock(&registry.mu);
    return found;
}

const cdvr_format *cdvr_format_by_magic(const uint8_t *head, size_t n)
{
    ensure_builtins();
    const cdvr_format *found = NULL;
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; head && !found && i < registry.count; i++)
        if (registry.formats[i]->magic && registry.formats[i]->magic(head, n))
            found = registry.formats[i];
    pthread_mutex_unlock(&registry.mu);
    return found;
}

size_t cdvr_format_count(void)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    size_t n = registry.count;
    pthread_mutex_unlock(&registry.mu);
    return n;
}

const cdvr_format *cdvr_format_at(size_t i)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    const cdvr_format *f = i < registry.count ? registry.formats[i] : NULL;
    pthread_mutex_unlock(&registry.mu);
    return f;
}

/* Appends text to out (n bytes, len used so far); marks a cut with "...". */
static void append(char *out, size_t n, size_t *len, const char *text)
{
    size_t k = strlen(text);
    if (*len + k + 1 > n) {
        if (n >= 4 && *len < n)
            strcpy(out + (n - 4 > *len ? *len : n - 4), "...");
        *len = n;
        return;
    }
    memcpy(out + *len, text, k + 1);
    *len += k;
}

void cdvr_format_list(char *out, size_t n)
{
    if (n == 0)
        return;
    out[0] = '\0';
    size_t len = 0, count = cdvr_format_count();
    for (size_t i = 0; i < count && len < n; i++) {
        const cdvr_format *f = cdvr_format_at(i);
        append(out, n, &len, i ? ", " : "");
        append(out, n, &len, f->name);
        append(out, n, &len, " (");
        for (size_t j = 0; f->suffixes[j]; j++) {
            append(out, n, &len, j ? " " : "");
            append(out, n, &len, f->suffixes[j]);
        }
        if (!f->suffixes[0])
            append(out, n, &len, "by content");
        if (f->flags & CDVR_FORMAT_DESCRIBED)
            append(out, n, &len, ", with dims and type");
        append(out, n, &len, ")");
    }
}

/* ---- load limits ---------------------------------------------------------------------------- */

uint64_t cdvr_load_max_bytes_default(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    if (pages <= 0 || size <= 0)
        return (uint64_t)1 << 40;
    uint64_t half = (uint64_t)pages * (uint64_t)size / 2;
    return half < ((uint64_t)64 << 20) ? (uint64_t)64 << 20 : half;
}

uint64_t cdvr_load_max_bytes(const cdvr_raw_opts *opts)
{
    return opts && opts->max_bytes ? opts->max_bytes : cdvr_load_max_bytes_default();
}

/* ---- dispatch ------------------------------------------------------------------------------- */

/* opts describes a raw file (dims given), rather than only carrying a spacing override. */
static int describes(const cdvr_raw_opts *opts)
{
    return opts && opts->dims[0] > 0;
}

/* The first bytes of path (at most CDVR_FORMAT_MAGIC_MAX); 0 and errno's text in why when it
 * cannot be read. */
static int read_head(const char *path, uint8_t *head, size_t *n, char *why, size_t why_n)
{
    FILE *f;
    cdvr_error e;
    if (cdvr_fopen_regular_file(path, &f, NULL, &e) != CDVR_OK) {
        snprintf(why, why_n, "%s", e.msg);
        return 0;
    }
    *n = fread(head, 1, CDVR_FORMAT_MAGIC_MAX, f);
    int bad = ferror(f);
    fclose(f);
    if (bad)
        snprintf(why, why_n, "%s: read error", path);
    return !bad;
}

/* Rule 0 of cdvr/format.h: the first format that reads the directory, or a refusal naming
 * those that read directories. */
static cdvr_status format_for_dir(const char *path, const cdvr_format **out, cdvr_error *err)
{
    char readers[CDVR_ERRMSG_MAX / 2] = "";
    size_t len = 0, count = cdvr_format_count();
    for (size_t i = 0; i < count; i++) {
        const cdvr_format *f = cdvr_format_at(i);
        if (!f->accepts_dir)
            continue;
        if (f->accepts_dir(path)) {
            *out = f;
            return CDVR_OK;
        }
        append(readers, sizeof readers, &len, len ? ", " : "");
        append(readers, sizeof readers, &len, f->name);
    }
    return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: is a directory that no format reads "
                          "(formats that read directories: %s)", path,
                          readers[0] ? readers : "none");
}

/* Rule 1b: a FILE:NAME path whose FILE ends in a suffix of a CDVR_FORMAT_SUBPATH format and
 * exists. */
static const cdvr_format *format_for_subpath(const char *path)
{
    if (!strchr(path, ':'))
        return NULL;
    size_t count = cdvr_format_count(), n = strlen(path) + 1;
    char *file = malloc(n), *name = malloc(n);
    const cdvr_format *found = NULL;
    struct stat st;
    for (size_t i = 0; file && name && !found && i < count; i++) {
        const cdvr_format *f = cdvr_format_at(i);
        if ((f->flags & CDVR_FORMAT_SUBPATH) &&
            cdvr_format_split_subpath(f, path, file, name, n) && name[0] &&
            stat(file, &st) == 0 && S_ISREG(st.st_mode))
            found = f;
    }
    free(file);
    free(name);
    return found;
}

cdvr_status cdvr_format_for(const char *path, const cdvr_raw_opts *opts,
                            const cdvr_format **out, cdvr_error *err)
{
    struct stat st;
    *out = NULL;
    if (stat(path, &st) == 0 && S_ISDIR(st.st_mode))
        return format_for_dir(path, out, err);
    *out = cdvr_format_by_suffix(path);
    if (!*out)
        *out = format_for_subpath(path);
    if (!*out && describes(opts)) /* any other name with a raw description is read as raw */
        *out = cdvr_format_find("raw");
    if (*out)
        return CDVR_OK;
    uint8_t head[CDVR_FORMAT_MAGIC_MAX];
    size_t n = 0;
    char why[CDVR_ERRMSG_MAX] = "", known[CDVR_ERRMSG_MAX / 2];
    if (read_head(path, head, &n, why, sizeof why) && (*out = cdvr_format_by_magic(head, n)))
        return CDVR_OK;
    cdvr_format_list(known, sizeof known);
    if (why[0])
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: unknown file type (its name has no "
                              "known suffix and it cannot be read: %s); formats known: %s", path,
                              why, known);
    return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: unknown file type (neither its name nor "
                          "its first bytes match a format); formats known: %s", path, known);
}

static void override_spacing(cdvr_volume *vol, const cdvr_raw_opts *opts)
{
    for (int i = 0; opts && i < 3; i++)
        if (opts->spacing[i] > 0)
            vol->spacing[i] = opts->spacing[i];
}

void cdvr_volume_header_preset(cdvr_volume *h)
{
    memset(h, 0, sizeof *h);
    for (int a = 0; a < 3; a++) {
        h->spacing[a] = 1;
        h->direction[4 * a] = 1;
    }
}

cdvr_status cdvr_load_check_claim(const char *file, const char *what, size_t bytes,
                                  const cdvr_raw_opts *opts, cdvr_error *err)
{
    if (bytes <= cdvr_load_max_bytes(opts))
        return CDVR_OK;
    return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s claims %zu bytes of voxels, more than "
                          "max_bytes %llu (a load option; the default is half the physical "
                          "memory)", file, what, bytes,
                          (unsigned long long)cdvr_load_max_bytes(opts));
}

static cdvr_status check_described(const cdvr_format *f, const char *path,
                                   const cdvr_raw_opts *opts, cdvr_error *err)
{
    if ((f->flags & CDVR_FORMAT_DESCRIBED) && !describes(opts))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: a %s file needs its dims and type (and "
                              "endian, header, timesteps)", path, f->name);
    return CDVR_OK;
}

cdvr_status cdvr_format_probe(const cdvr_format *f, const char *path, const cdvr_raw_opts *opts,
                              cdvr_volume *head, cdvr_error *err)
{
    void *data = head->data;
    cdvr_volume_header_preset(head);
    head->data = data;
    cdvr_status st = check_described(f, path, opts, err);
    if (st == CDVR_OK)
        st = f->probe(path, opts, head, err);
    if (st == CDVR_OK)
        override_spacing(head, opts);
    return st;
}

/* A format without load: probe, create, read into the volume's buffer. */
static cdvr_status load_by_read(const cdvr_format *f, const char *path, const cdvr_raw_opts *opts,
                                cdvr_volume **out, cdvr_error *err)
{
    cdvr_volume head;
    cdvr_volume_header_preset(&head);
    cdvr_status st = f->probe(path, opts, &head, err);
    size_t bytes = 0;
    char what[CDVR_FORMAT_NAME_MAX + 16];
    snprintf(what, sizeof what, "format '%s'", f->name);
    if (st == CDVR_OK && cdvr_volume_bytes_for(head.dims, head.timesteps, head.type, &bytes))
        st = cdvr_load_check_claim(path, what, bytes, opts, err);
    if (st == CDVR_OK)
        st = cdvr_volume_create(head.dims, head.timesteps, head.type, out, err);
    if (st != CDVR_OK)
        return st;
    memcpy((*out)->spacing, head.spacing, sizeof head.spacing);
    memcpy((*out)->origin, head.origin, sizeof head.origin);
    memcpy((*out)->direction, head.direction, sizeof head.direction);
    memcpy((*out)->source_type, head.source_type, sizeof head.source_type);
    memcpy((*out)->space, head.space, sizeof head.space);
    st = f->read(path, opts, *out, (*out)->data, err);
    if (st != CDVR_OK) {
        cdvr_volume_free(*out);
        *out = NULL;
    }
    return st;
}

cdvr_status cdvr_format_load(const cdvr_format *f, const char *path, const cdvr_raw_opts *opts,
                             cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    cdvr_status st = check_described(f, path, opts, err);
    if (st == CDVR_OK)
        st = f->load ? f->load(path, opts, out, err) : load_by_read(f, path, opts, out, err);
    if (st == CDVR_OK && !*out)
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: format '%s' loaded no volume", path,
                            f->name);
    if (st == CDVR_OK)
        override_spacing(*out, opts);
    return st;
}

cdvr_status cdvr_volume_load(const char *path, const cdvr_raw_opts *raw, cdvr_volume **out,
                             cdvr_error *err)
{
    *out = NULL;
    const cdvr_format *f;
    cdvr_status st = cdvr_format_for(path, raw, &f, err);
    return st == CDVR_OK ? cdvr_format_load(f, path, raw, out, err) : st;
}

cdvr_status cdvr_volume_probe(const char *path, const cdvr_raw_opts *raw, cdvr_volume *head,
                              cdvr_error *err)
{
    const cdvr_format *f;
    cdvr_status st = cdvr_format_for(path, raw, &f, err);
    return st == CDVR_OK ? cdvr_format_probe(f, path, raw, head, err) : st;
}

/* ---- series expansion ----------------------------------------------------------------------- */

typedef struct path_list {
    char **items;
    size_t count, cap;
    int failed;                  /* an add failed (a format that ignores add's 0 is caught) */
} path_list;

static int add_path(void *ud, const char *file)
{
    path_list *l = ud;
    l->failed |= !file;
    if (!file || l->failed)
        return 0;
    if (l->count == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        char **items = realloc(l->items, cap * sizeof *items);
        if (!items)
            return !(l->failed = 1);
        l->items = items;
        l->cap = cap;
    }
    if (!(l->items[l->count] = strdup(file)))
        return !(l->failed = 1);
    l->count++;
    return 1;
}

void cdvr_format_free_paths(char **paths, size_t count)
{
    for (size_t i = 0; paths && i < count; i++)
        free(paths[i]);
    free(paths);
}

cdvr_status cdvr_format_expand(const char *const *paths, size_t count, const cdvr_raw_opts *opts,
                               char ***out, size_t *out_count, cdvr_error *err)
{
    *out = NULL;
    *out_count = 0;
    path_list l = {NULL, 0, 0, 0};
    cdvr_status st = CDVR_OK;
    for (size_t i = 0; st == CDVR_OK && i < count; i++) {
        const cdvr_format *f = NULL;
        cdvr_error ignored;
        if (cdvr_format_for(paths[i], opts, &f, &ignored) != CDVR_OK ||
            (!f->expand && !f->expand_opts)) {
            if (!add_path(&l, paths[i]))
                st = cdvr_error_set(err, CDVR_ERR_NOMEM, "series: out of memory");
            else
                st = CDVR_OK;
            continue;
        }
        size_t before = l.count;
        st = f->expand_opts ? f->expand_opts(paths[i], opts, add_path, &l, err)
                            : f->expand(paths[i], add_path, &l, err);
        if (st == CDVR_OK && l.failed)
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory for its list of files",
                                paths[i]);
        if (st == CDVR_OK && l.count == before)
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the %s file names no files",
                                paths[i], f->name);
    }
    if (st != CDVR_OK) {
        cdvr_format_free_paths(l.items, l.count);
        return st;
    }
    *out = l.items;
    *out_count = l.count;
    return CDVR_OK;
}
