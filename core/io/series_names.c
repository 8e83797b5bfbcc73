/* core/io/series_names.c - the files of a series given as one string: a directory, a glob
 * pattern, a printf pattern or one name, in natural order (cdvr/series.h). */
#include "cdvr/format.h"
#include "cdvr/series.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <glob.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define SERIES_NAMES_MAX 1000000 /* the limit of cdvr_series_pattern too */

/* Natural order without the tie break: 0 for "t02" and "t2". */
static int natural_value_cmp(const char *a, const char *b)
{
    while (*a && *b) {
        if (isdigit((unsigned char)*a) && isdigit((unsigned char)*b)) {
            while (*a == '0' && isdigit((unsigned char)a[1]))
                a++;
            while (*b == '0' && isdigit((unsigned char)b[1]))
                b++;
            size_t na = 0, nb = 0;
            while (isdigit((unsigned char)a[na]))
                na++;
            while (isdigit((unsigned char)b[nb]))
                nb++;
            if (na != nb)
                return na < nb ? -1 : 1;
            int c = strncmp(a, b, na);
            if (c)
                return c < 0 ? -1 : 1;
            a += na;
            b += nb;
        } else {
            if (*a != *b)
                return (unsigned char)*a < (unsigned char)*b ? -1 : 1;
            a++;
            b++;
        }
    }
    return *a ? 1 : *b ? -1 : 0;
}

int cdvr_series_natural_cmp(const char *a, const char *b)
{
    int c = natural_value_cmp(a, b);
    return c ? c : strcmp(a, b);
}

static int natural_qsort(const void *a, const void *b)
{
    return cdvr_series_natural_cmp(*(char *const *)a, *(char *const *)b);
}

int cdvr_series_is_pattern(const char *s)
{
    for (size_t i = 0; s[i]; i++) {
        if (s[i] != '%')
            continue;
        if (s[i + 1] == '%') {
            i++;
            continue;
        }
        size_t j = i + 1 + (s[i + 1] == '0');
        while (isdigit((unsigned char)s[j]))
            j++;
        if (s[j] && strchr("diu", s[j]))
            return 1;
    }
    return 0;
}

/* A growing list of malloc'd names. */
typedef struct name_list {
    char **items;
    size_t count, cap;
} name_list;

static int list_add(name_list *l, char *name)
{
    if (!name)
        return 0;
    if (l->count == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 16;
        char **items = l->count < SERIES_NAMES_MAX ? realloc(l->items, cap * sizeof *items)
                                                   : NULL;
        if (!items) {
            free(name);
            return 0;
        }
        l->items = items;
        l->cap = cap;
    }
    l->items[l->count++] = name;
    return 1;
}

static char *join(const char *dir, const char *name)
{
    size_t n = strlen(dir), k = strlen(name);
    int slash = n > 0 && dir[n - 1] != '/';
    char *out = malloc(n + (size_t)slash + k + 1);
    if (out) {
        memcpy(out, dir, n);
        if (slash)
            out[n] = '/';
        memcpy(out + n + (size_t)slash, name, k + 1);
    }
    return out;
}

cdvr_status cdvr_series_glob(const char *pattern, char ***out, size_t *n, cdvr_error *err)
{
    *out = NULL;
    *n = 0;
    glob_t g;
    int rc = glob(pattern, GLOB_NOSORT, NULL, &g);
    if (rc == GLOB_NOMATCH)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: no file matches the pattern", pattern);
    if (rc != 0) {
        globfree(&g);
        return cdvr_error_set(err, rc == GLOB_NOSPACE ? CDVR_ERR_NOMEM : CDVR_ERR_IO,
                              "%s: cannot expand the pattern (%s)", pattern,
                              rc == GLOB_NOSPACE ? "out of memory" : "a directory cannot be read");
    }
    if (g.gl_pathc > SERIES_NAMES_MAX) {
        size_t count = g.gl_pathc;
        globfree(&g);
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: %zu files match, more than %d", pattern,
                              count, SERIES_NAMES_MAX);
    }
    name_list l = {NULL, 0, 0};
    int ok = 1;
    for (size_t i = 0; ok && i < g.gl_pathc; i++)
        ok = list_add(&l, strdup(g.gl_pathv[i]));
    globfree(&g);
    if (!ok) {
        cdvr_format_free_paths(l.items, l.count);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", pattern);
    }
    qsort(l.items, l.count, sizeof *l.items, natural_qsort);
    *out = l.items;
    *n = l.count;
    return CDVR_OK;
}

/* ---- directories ----------------------------------------------------------------------------- */

/* What a directory holds, by kind: the files of one format, or the directories one format reads. */
#define KINDS_MAX 16

typedef struct dir_kind {
    const cdvr_format *format;
    int is_dir;
    size_t count;
    char example[64];
} dir_kind;

typedef struct dir_scan {
    dir_kind kinds[KINDS_MAX];
    size_t nkinds;
    size_t other_files, other_dirs;
    char other_example[64];
} dir_scan;

/* The kind of an entry (its format), or NULL when no format reads it. */
static const cdvr_format *entry_format(const char *path, int is_dir)
{
    if (!is_dir)
        return cdvr_format_by_suffix(path);
    const cdvr_format *f = NULL;
    cdvr_error ignored;
    return cdvr_format_for(path, NULL, &f, &ignored) == CDVR_OK ? f : NULL;
}

static dir_kind *kind_of(dir_scan *s, const cdvr_format *f, int is_dir)
{
    for (size_t i = 0; i < s->nkinds; i++)
        if (s->kinds[i].format == f && s->kinds[i].is_dir == is_dir)
            return &s->kinds[i];
    if (s->nkinds == KINDS_MAX)
        return &s->kinds[KINDS_MAX - 1]; /* only the message is less exact */
    dir_kind *k = &s->kinds[s->nkinds++];
    memset(k, 0, sizeof *k);
    k->format = f;
    k->is_dir = is_dir;
    return k;
}

/* Appends printf-formatted text to out (n bytes, *len used). */
static void addf(char *out, size_t n, size_t *len, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;

static void addf(char *out, size_t n, size_t *len, const char *fmt, ...)
{
    if (*len >= n)
        return;
    va_list ap;
    va_start(ap, fmt);
    int k = vsnprintf(out + *len, n - *len, fmt, ap);
    va_end(ap);
    *len = k < 0 ? n : *len + (size_t)k;
}

/* "3 nrrd files (t1.nrrd ...), 2 tiff directories (s1 ...)" */
static void describe(const dir_scan *s, char *out, size_t n)
{
    size_t len = 0;
    out[0] = '\0';
    for (size_t i = 0; i < s->nkinds; i++) {
        const dir_kind *k = &s->kinds[i];
        addf(out, n, &len, "%s%zu %s %s%s (%s%s)", i ? ", " : "", k->count, k->format->name,
             k->is_dir ? "director" : "file", k->is_dir ? (k->count == 1 ? "y" : "ies")
                                                         : (k->count == 1 ? "" : "s"),
             k->example, k->count > 1 ? " ..." : "");
    }
}

/* The kind of a collection file (a format that expands to a list of files, .pvd) in the
 * directory, or NULL: such a file, next to the files it lists, stands for the series. */
static const dir_kind *collection_kind(const dir_scan *s)
{
    for (size_t i = 0; i < s->nkinds; i++)
        if (!s->kinds[i].is_dir && (s->kinds[i].format->expand || s->kinds[i].format->expand_opts))
            return &s->kinds[i];
    return NULL;
}

/* Keeps in l only the files of format f (the collection), freeing the others. */
static void keep_only(name_list *l, const cdvr_format *const *kinds, const unsigned char *dirs,
                      const cdvr_format *f)
{
    size_t kept = 0;
    for (size_t i = 0; i < l->count; i++) {
        if (kinds[i] == f && !dirs[i])
            l->items[kept++] = l->items[i];
        else
            free(l->items[i]);
    }
    l->count = kept;
}

cdvr_status cdvr_series_dir(const char *dir, char ***out, size_t *n, cdvr_error *err)
{
    *out = NULL;
    *n = 0;
    DIR *d = opendir(dir);
    if (!d)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open the directory: %s", dir,
                              strerror(errno));
    dir_scan s;
    memset(&s, 0, sizeof s);
    name_list l = {NULL, 0, 0};
    const cdvr_format **kinds = NULL; /* per entry of l: its format (dirs: flagged below) */
    unsigned char *dirs = NULL;
    size_t cap = 0;
    cdvr_status st = CDVR_OK;
    struct dirent *e;
    while (st == CDVR_OK && (e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.')
            continue; /* hidden files, "." and ".." */
        char *path = join(dir, e->d_name);
        struct stat sb;
        if (!path) {
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", dir);
            break;
        }
        int found = stat(path, &sb) == 0;
        int is_dir = found && S_ISDIR(sb.st_mode), is_file = found && S_ISREG(sb.st_mode);
        const cdvr_format *f = is_dir || is_file ? entry_format(path, is_dir) : NULL;
        if (!f) {
            if (is_dir)
                s.other_dirs++;
            else
                s.other_files++;
            if (!s.other_example[0])
                snprintf(s.other_example, sizeof s.other_example, "%s", e->d_name);
            free(path);
            continue;
        }
        dir_kind *k = kind_of(&s, f, is_dir);
        if (k->count++ == 0)
            snprintf(k->example, sizeof k->example, "%s", e->d_name);
        if (l.count == cap) {
            size_t grown = cap ? 2 * cap : 16;
            const cdvr_format **nk = realloc(kinds, grown * sizeof *nk);
            kinds = nk ? nk : kinds;
            unsigned char *nd = nk ? realloc(dirs, grown) : NULL;
            dirs = nd ? nd : dirs;
            if (!nk || !nd) {
                free(path);
                st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", dir);
                break;
            }
            cap = grown;
        }
        kinds[l.count] = f;
        dirs[l.count] = (unsigned char)is_dir;
        if (!list_add(&l, path))
            st = cdvr_error_set(err, l.count >= SERIES_NAMES_MAX ? CDVR_ERR_ARG : CDVR_ERR_NOMEM,
                                "%s: out of memory or more than %d entries", dir,
                                SERIES_NAMES_MAX);
    }
    closedir(d);
    const dir_kind *coll = collection_kind(&s);
    if (st == CDVR_OK && coll && coll->count > 1)
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the directory holds %zu %s collections "
                            "(%s ...); give the one to load", dir, coll->count,
                            coll->format->name, coll->example);
    else if (st == CDVR_OK && coll)
        keep_only(&l, kinds, dirs, coll->format);
    free(kinds);
    free(dirs);
    if (st == CDVR_OK && coll) {
        /* the collection names the series (its other files are its datasets) */
    } else if (st == CDVR_OK && s.nkinds > 1) {
        char what[CDVR_ERRMSG_MAX / 2];
        describe(&s, what, sizeof what);
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the directory holds several formats: %s; "
                            "a series is of one (give a glob pattern such as %s/*%s)", dir, what,
                            dir, s.kinds[0].is_dir ? "" : s.kinds[0].format->suffixes[0]);
    } else if (st == CDVR_OK && s.nkinds == 0) {
        if (!s.other_files && !s.other_dirs)
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the directory is empty (hidden files "
                                "are skipped): no volume files for a series", dir);
        else
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the directory holds no volume files "
                                "for a series: %zu file%s of no known suffix and %zu "
                                "director%s no format reads (e.g. %s); formats are told by "
                                "suffix (cdvr.formats())", dir, s.other_files,
                                s.other_files == 1 ? "" : "s", s.other_dirs,
                                s.other_dirs == 1 ? "y" : "ies", s.other_example);
    }
    if (st != CDVR_OK) {
        cdvr_format_free_paths(l.items, l.count);
        return st;
    }
    qsort(l.items, l.count, sizeof *l.items, natural_qsort);
    *out = l.items;
    *n = l.count;
    return CDVR_OK;
}

/* ---- one string ------------------------------------------------------------------------------- */

cdvr_status cdvr_series_names(const char *where, long long first, size_t count, char ***out,
                              size_t *n, cdvr_error *err)
{
    *out = NULL;
    *n = 0;
    struct stat sb;
    int exists = stat(where, &sb) == 0;
    if (exists && S_ISDIR(sb.st_mode))
        return cdvr_series_dir(where, out, n, err);
    if (!exists && cdvr_series_is_pattern(where))
        return cdvr_series_pattern(where, first, count, out, n, err);
    if (!exists && strpbrk(where, "*?["))
        return cdvr_series_glob(where, out, n, err);
    char **one = malloc(sizeof *one);
    if (!one || !(one[0] = strdup(where))) {
        free(one);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", where);
    }
    *out = one;
    *n = 1;
    return CDVR_OK;
}

cdvr_status cdvr_series_open_path(const char *where, const cdvr_raw_opts *raw,
                                  cdvr_series **out, cdvr_error *err)
{
    *out = NULL;
    char **names;
    size_t n;
    cdvr_status st = cdvr_series_names(where, 0, 0, &names, &n, err);
    if (st != CDVR_OK)
        return st;
    st = cdvr_series_open((const char *const *)names, n, raw, out, err);
    cdvr_format_free_paths(names, n);
    return st;
}

cdvr_status cdvr_volume_load_series_path(const char *where, const cdvr_raw_opts *raw,
                                         cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    char **names;
    size_t n;
    cdvr_status st = cdvr_series_names(where, 0, 0, &names, &n, err);
    if (st != CDVR_OK)
        return st;
    st = cdvr_volume_load_series((const char *const *)names, n, raw, out, err);
    cdvr_format_free_paths(names, n);
    return st;
}
