/* core/io/io_hdf5.c - HDF5 (.h5 .hdf5 .he5 .hdf) through libhdf5 (format "hdf5",
 * CDVR_FORMAT_SUBPATH).
 *
 * Which dataset: FILE:/group/dataset (cdvr/format.h rule 1b), else cdvr_raw_opts.select, else
 * the file's only 3D or 4D numeric dataset (several: refused, listing their paths and dims; a
 * name the file does not hold: refused, listing the datasets it holds). Naming a dataset both
 * ways with different names is refused. External links, virtual datasets and raw data in
 * external files (other files read through this one) are refused.
 * Layout: a 3D dataset is (z, y, x) in C order (x fastest), so dims are x, y, z as they come; a
 * 4D dataset (t, z, y, x) is a series of t timesteps. Contiguous, chunked and compact storage
 * and any filter libhdf5 has (deflate, shuffle, fletcher32, szip, ...) are read by the library;
 * a filter it lacks is refused naming it.
 * Types: u8, u16, i16 and f32 are kept; i8, i32, u32, i64, u64 and f64 become f32 with the value
 * window computed in double (as the other loaders); other classes (float16, compound, string,
 * enum, ...) are refused.
 * Geometry (attributes, each of numbers, read as double):
 *   element_size_um on the dataset: 3 numbers in the dataset's order z, y, x (ilastik / Fiji's
 *     convention; 4 for a 4D dataset, t first, t ignored) -> spacing x, y, z;
 *   else `spacing` on the dataset, else on its group: 3 numbers x, y, z (cdvr's order);
 *   `origin` on the dataset, else on its group: 3 numbers x, y, z (world of voxel (0,0,0));
 *   none: unit spacing, origin 0 (README). Direction identity. A spacing that is not positive
 *   and finite, or an attribute that is not 3 numbers, is refused naming it and its value.
 * probe reads only the header (the dataset's dataspace, type, creation properties and
 * attributes). A load checks the claim (dims x timesteps x bytes of the volume type) against
 * cdvr_load_max_bytes(opts) before allocating; a contiguous dataset must lie inside the file.
 * The path is checked as a regular file (cdvr/regular_file.h) and the library gets
 * /proc/self/fd/N of that open file, so FIFOs and devices are refused, never waited on.
 * Thread safety: every libhdf5 call holds the one lock of io_hdf5.h (named context
 * `hdf5_library` below); HDF5's error printing is off meanwhile and its error stack becomes
 * the message, which names the file, the dataset and the reason. */
#include "io_hdf5.h"
#include "cdvr/format.h"
#include "cdvr/regular_file.h"
#include "io_common.h"
#include "volume_io.h"

#include <hdf5.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- the library lock (io_hdf5.h) ------------------------------------------------------- */

static struct {
    pthread_mutex_t mu;
    H5E_auto2_t saved_func; /* the error printer in place before the lock, restored at unlock */
    void *saved_data;
} hdf5_library = {PTHREAD_MUTEX_INITIALIZER, NULL, NULL};

void cdvr_hdf5_lock(void)
{
    pthread_mutex_lock(&hdf5_library.mu);
    hdf5_library.saved_func = NULL;
    hdf5_library.saved_data = NULL;
    H5Eget_auto2(H5E_DEFAULT, &hdf5_library.saved_func, &hdf5_library.saved_data);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
}

void cdvr_hdf5_unlock(void)
{
    H5Eclear2(H5E_DEFAULT);
    H5Eset_auto2(H5E_DEFAULT, hdf5_library.saved_func, hdf5_library.saved_data);
    pthread_mutex_unlock(&hdf5_library.mu);
}

typedef struct reason_walk {
    char *out;
    size_t n;
} reason_walk;

static herr_t reason_cb(unsigned n, const H5E_error2_t *e, void *ud)
{
    reason_walk *w = ud;
    if (n == 0 && e) { /* walking upward: the innermost error, where it was detected */
        char minor[128] = "";
        H5Eget_msg(e->min_num, NULL, minor, sizeof minor);
        snprintf(w->out, w->n, "%s%s%s", e->desc ? e->desc : "", minor[0] ? ": " : "", minor);
    }
    return 0;
}

void cdvr_hdf5_reason(char *out, size_t n)
{
    if (!n)
        return;
    out[0] = '\0';
    reason_walk w = {out, n};
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, reason_cb, &w);
    H5Eclear2(H5E_DEFAULT);
    if (!out[0])
        snprintf(out, n, "unknown HDF5 error");
}

/* ---- FILE:NAME and the regular-file check (io_hdf5.h) ------------------------------------ */

cdvr_status cdvr_subpath_begin(const cdvr_format *f, const char *path, const cdvr_raw_opts *opts,
                               const char *what, cdvr_subpath *s, cdvr_error *err)
{
    size_t n = strlen(path) + 1;
    s->fd = -1;
    s->open[0] = '\0';
    s->file = malloc(n);
    s->name = malloc(n);
    if (!s->file || !s->name) {
        cdvr_subpath_done(s);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    cdvr_format_split_subpath(f, path, s->file, s->name, n); /* fits: n is the whole length */
    const char *sel = opts && opts->select && opts->select[0] ? opts->select : NULL;
    if (sel && s->name[0] && strcmp(sel, s->name) != 0) {
        cdvr_status st = cdvr_error_set(err, CDVR_ERR_ARG, "%s: the path names %s '%s' and "
                                        "select= names '%s' (give one)", s->file, what, s->name,
                                        sel);
        cdvr_subpath_done(s);
        return st;
    }
    if (sel && !s->name[0]) {
        char *name = realloc(s->name, strlen(sel) + 1);
        if (!name) {
            cdvr_subpath_done(s);
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
        }
        s->name = strcpy(name, sel);
    }
    cdvr_status st = cdvr_open_regular_file(s->file, &s->fd, NULL, err);
    if (st != CDVR_OK) {
        s->fd = -1;
        cdvr_subpath_done(s);
        return st;
    }
    struct stat sb;
    snprintf(s->open, sizeof s->open, "/proc/self/fd/%d", s->fd);
    if (stat(s->open, &sb) != 0 || !S_ISREG(sb.st_mode))
        snprintf(s->open, sizeof s->open, "%s", strlen(s->file) < sizeof s->open ? s->file : "");
    if (!s->open[0]) {
        cdvr_subpath_done(s);
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: path too long", path);
    }
    return CDVR_OK;
}

void cdvr_subpath_done(cdvr_subpath *s)
{
    if (s->fd >= 0)
        close(s->fd);
    s->fd = -1;
    free(s->file);
    free(s->name);
    s->file = s->name = NULL;
}

/* ---- datasets ------------------------------------------------------------------------------ */

#define H5_NAME_MAX 1024
#define H5_LIST_MAX 300 /* characters of dataset list in a message */

typedef struct h5_ctx {
    const char *file;
    const cdvr_raw_opts *opts; /* the load options (the f32 rule), or NULL */
    cdvr_error *err;
    hid_t fid, lapl, dapl; /* link and dataset access lists that refuse external links */
} h5_ctx;

/* What a dataset is, from its header. */
typedef struct h5_info {
    int rank;
    hsize_t d[H5S_MAX_RANK];
    int numeric;          /* integer or float of a size cdvr reads */
    cdvr_io_etype etype;
    char tname[32];       /* "uint16", "float16", "compound", ... */
} h5_info;

static herr_t deny_elink(const char *parent_file, const char *parent_group,
                         const char *child_file, const char *child_object, unsigned *acc_flags,
                         hid_t fapl, void *ud)
{
    (void)parent_file, (void)parent_group, (void)child_file, (void)child_object, (void)acc_flags,
        (void)fapl, (void)ud;
    return -1; /* an external link opens another file: never followed */
}

static void type_info(hid_t t, h5_info *in)
{
    H5T_class_t c = H5Tget_class(t);
    size_t s = H5Tget_size(t);
    in->numeric = 0;
    if (c == H5T_INTEGER) {
        int sg = H5Tget_sign(t) == H5T_SGN_2;
        static const cdvr_io_etype u[] = {CDVR_IO_U8, CDVR_IO_U16, CDVR_IO_U32, CDVR_IO_U64};
        static const cdvr_io_etype i[] = {CDVR_IO_I8, CDVR_IO_I16, CDVR_IO_I32, CDVR_IO_I64};
        int k = s == 1 ? 0 : s == 2 ? 1 : s == 4 ? 2 : s == 8 ? 3 : -1;
        if (k >= 0) {
            in->numeric = 1;
            in->etype = sg ? i[k] : u[k];
            snprintf(in->tname, sizeof in->tname, "%s", cdvr_io_etype_name(in->etype));
        } else
            snprintf(in->tname, sizeof in->tname, "%s%zu", sg ? "int" : "uint", 8 * s);
    } else if (c == H5T_FLOAT) {
        in->numeric = s == 4 || s == 8;
        in->etype = s == 4 ? CDVR_IO_F32 : CDVR_IO_F64;
        snprintf(in->tname, sizeof in->tname, "float%zu", 8 * s);
    } else {
        static const char *const names[] = {"time", "string", "bitfield", "opaque", "compound",
                                            "reference", "enum", "variable-length", "array"};
        int k = (int)c - (int)H5T_TIME;
        snprintf(in->tname, sizeof in->tname, "%s",
                 k >= 0 && k < (int)(sizeof names / sizeof *names) ? names[k] : "unknown");
    }
}

static int info_of(hid_t did, h5_info *in)
{
    memset(in, 0, sizeof *in);
    hid_t sp = H5Dget_space(did), t = H5Dget_type(did);
    int ok = sp >= 0 && t >= 0;
    if (ok) {
        in->rank = H5Sget_simple_extent_ndims(sp);
        ok = in->rank >= 0 && in->rank <= H5S_MAX_RANK &&
             H5Sget_simple_extent_dims(sp, in->d, NULL) >= 0;
        type_info(t, in);
    }
    if (sp >= 0)
        H5Sclose(sp);
    if (t >= 0)
        H5Tclose(t);
    return ok;
}

static int candidate(const h5_info *in)
{
    return (in->rank == 3 || in->rank == 4) && in->numeric;
}

/* "(3, 7, 5) uint16" into out. */
static void describe_dims(const h5_info *in, char *out, size_t n)
{
    size_t len = 0;
    out[0] = '\0';
    for (int i = 0; i < in->rank && len < n; i++)
        len += (size_t)snprintf(out + len, n - len, "%s%llu", i ? ", " : "(",
                                (unsigned long long)in->d[i]);
    if (len < n)
        snprintf(out + len, n - len, "%s %s", in->rank ? ")" : "(scalar)", in->tname);
}

typedef struct h5_list {
    h5_ctx *c;
    int only_candidates;
    size_t count;          /* datasets listed (all, or the candidates) */
    char first[H5_NAME_MAX];
    char text[H5_LIST_MAX + 8];
    size_t len;
} h5_list;

static void list_add(h5_list *l, const char *name, const h5_info *in)
{
    char dims[96], item[H5_NAME_MAX + 100];
    describe_dims(in, dims, sizeof dims);
    snprintf(item, sizeof item, "%s/%s %s", l->count ? ", " : "", name, dims);
    if (l->count == 0)
        snprintf(l->first, sizeof l->first, "/%s", name);
    l->count++;
    size_t k = strlen(item);
    if (l->len + k <= H5_LIST_MAX) {
        memcpy(l->text + l->len, item, k + 1);
        l->len += k;
    } else if (l->len < H5_LIST_MAX + 4) {
        memcpy(l->text + l->len, ", ...", 6);
        l->len = H5_LIST_MAX + 4;
    }
}

static herr_t visit_cb(hid_t group, const char *name, const H5L_info_t *info, void *ud)
{
    h5_list *l = ud;
    if (info->type != H5L_TYPE_HARD)
        return 0; /* soft and external links: the object is listed where it is */
    hid_t oid = H5Oopen(group, name, l->c->lapl);
    if (oid < 0) {
        H5Eclear2(H5E_DEFAULT);
        return 0;
    }
    h5_info in;
    if (H5Iget_type(oid) == H5I_DATASET && info_of(oid, &in) &&
        (!l->only_candidates || candidate(&in)))
        list_add(l, name, &in);
    H5Oclose(oid);
    return 0;
}

static void list_datasets(h5_ctx *c, int only_candidates, h5_list *l)
{
    memset(l, 0, sizeof *l);
    l->c = c;
    l->only_candidates = only_candidates;
    H5Lvisit(c->fid, H5_INDEX_NAME, H5_ITER_INC, visit_cb, l);
    H5Eclear2(H5E_DEFAULT);
}

/* The dataset to read, opened (*did), its path in name (H5_NAME_MAX). */
static cdvr_status find_dataset(h5_ctx *c, const char *want, hid_t *did, char *name)
{
    h5_list l;
    *did = -1;
    if (!want[0]) {
        list_datasets(c, 1, &l);
        if (l.count == 1) {
            snprintf(name, H5_NAME_MAX, "%s", l.first);
        } else if (l.count == 0) {
            list_datasets(c, 0, &l);
            return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: no 3D or 4D numeric "
                                  "dataset (datasets: %s)", c->file, l.count ? l.text : "none");
        } else
            return cdvr_error_set(c->err, CDVR_ERR_ARG, "%s: HDF5: %zu 3D/4D datasets, name one "
                                  "as FILE:/path or with select=: %s", c->file, l.count, l.text);
    } else if (strlen(want) >= H5_NAME_MAX)
        return cdvr_error_set(c->err, CDVR_ERR_ARG, "%s: HDF5: dataset name too long", c->file);
    else
        snprintf(name, H5_NAME_MAX, "%s", want);
    /* Every prefix must exist (H5Lexists of a path through a missing group is an error). */
    int found = strcmp(name, "/") != 0;
    char prefix[H5_NAME_MAX];
    for (size_t i = 1; found && i <= strlen(name); i++)
        if ((name[i] == '/' || name[i] == '\0') && name[i - 1] != '/') {
            memcpy(prefix, name, i);
            prefix[i] = '\0';
            found = H5Lexists(c->fid, prefix, c->lapl) > 0;
        }
    H5Eclear2(H5E_DEFAULT);
    hid_t oid = found ? H5Oopen(c->fid, name, c->lapl) : -1;
    if (oid < 0) {
        char why[256];
        cdvr_hdf5_reason(why, sizeof why);
        list_datasets(c, 0, &l);
        if (found)
            return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' cannot be "
                                  "opened (%s; external links are not followed)", c->file, name,
                                  why);
        return cdvr_error_set(c->err, CDVR_ERR_ARG, "%s: HDF5: no dataset '%s' (datasets: %s)",
                              c->file, name, l.count ? l.text : "none");
    }
    if (H5Iget_type(oid) != H5I_DATASET) {
        H5Oclose(oid);
        list_datasets(c, 0, &l);
        return cdvr_error_set(c->err, CDVR_ERR_ARG, "%s: HDF5: '%s' is a group, not a dataset "
                              "(datasets: %s)", c->file, name, l.count ? l.text : "none");
    }
    H5Oclose(oid);
    *did = H5Dopen2(c->fid, name, c->dapl);
    if (*did < 0) {
        char why[256];
        cdvr_hdf5_reason(why, sizeof why);
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' cannot be opened: "
                              "%s", c->file, name, why);
    }
    return CDVR_OK;
}

/* ---- attributes ---------------------------------------------------------------------------- */

/* Attribute `key` of obj as n numbers: 0 absent, 1 read, -1 refused (err set). */
static int attr_numbers(h5_ctx *c, hid_t obj, const char *where, const char *dset,
                        const char *key, double *v, int n_min, int n_max, int *n)
{
    if (H5Aexists(obj, key) <= 0) {
        H5Eclear2(H5E_DEFAULT);
        return 0;
    }
    hid_t aid = H5Aopen(obj, key, H5P_DEFAULT);
    hid_t sp = aid >= 0 ? H5Aget_space(aid) : -1, t = aid >= 0 ? H5Aget_type(aid) : -1;
    hssize_t pts = sp >= 0 ? H5Sget_simple_extent_npoints(sp) : -1;
    H5T_class_t cl = t >= 0 ? H5Tget_class(t) : H5T_NO_CLASS;
    int ok = pts >= n_min && pts <= n_max && (cl == H5T_INTEGER || cl == H5T_FLOAT) &&
             H5Aread(aid, H5T_NATIVE_DOUBLE, v) >= 0;
    if (sp >= 0)
        H5Sclose(sp);
    if (t >= 0)
        H5Tclose(t);
    if (aid >= 0)
        H5Aclose(aid);
    H5Eclear2(H5E_DEFAULT);
    if (!ok) {
        cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: attribute %s of %s '%s' is not %d%s "
                       "numbers (it has %lld values%s)", c->file, key, where, dset, n_min,
                       n_max > n_min ? " or more" : "", (long long)pts,
                       cl == H5T_INTEGER || cl == H5T_FLOAT ? "" : ", not numeric");
        return -1;
    }
    *n = (int)pts;
    return 1;
}

/* Spacing and origin of the dataset (see the top of this file) into head. */
static cdvr_status geometry(h5_ctx *c, hid_t did, const char *name, int rank, cdvr_volume *head)
{
    double v[4];
    int n, r;
    char group[H5_NAME_MAX];
    snprintf(group, sizeof group, "%s", name);
    char *slash = strrchr(group, '/');
    if (slash && slash != group)
        *slash = '\0';
    else
        snprintf(group, sizeof group, "/");
    hid_t gid = H5Oopen(c->fid, group, c->lapl);
    H5Eclear2(H5E_DEFAULT);
    cdvr_status st = CDVR_OK;
    const char *spacing_from = NULL;
    r = attr_numbers(c, did, "dataset", name, "element_size_um", v, 3, rank == 4 ? 4 : 3, &n);
    if (r > 0) {
        for (int a = 0; a < 3; a++)
            head->spacing[a] = v[n - 1 - a]; /* z, y, x (t first when 4) */
        spacing_from = "element_size_um";
    }
    if (r == 0 && (r = attr_numbers(c, did, "dataset", name, "spacing", v, 3, 3, &n)) > 0)
        spacing_from = "spacing";
    if (r == 0 && gid >= 0 &&
        (r = attr_numbers(c, gid, "group", group, "spacing", v, 3, 3, &n)) > 0)
        spacing_from = "spacing";
    if (r > 0 && strcmp(spacing_from, "spacing") == 0)
        memcpy(head->spacing, v, 3 * sizeof *v);
    if (r < 0)
        st = c->err ? c->err->status : CDVR_ERR_FORMAT;
    for (int a = 0; st == CDVR_OK && spacing_from && a < 3; a++)
        if (!(head->spacing[a] > 0 && isfinite(head->spacing[a])))
            st = cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: attribute %s of '%s' gives "
                                "spacing %g for axis %c (positive and finite needed)", c->file,
                                spacing_from, name, head->spacing[a], "xyz"[a]);
    if (st == CDVR_OK) {
        r = attr_numbers(c, did, "dataset", name, "origin", v, 3, 3, &n);
        if (r == 0 && gid >= 0)
            r = attr_numbers(c, gid, "group", group, "origin", v, 3, 3, &n);
        if (r < 0)
            st = c->err ? c->err->status : CDVR_ERR_FORMAT;
        for (int a = 0; st == CDVR_OK && r > 0 && a < 3; a++)
            if (!isfinite(v[a]))
                st = cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: attribute origin of "
                                    "'%s' is not finite (%g for axis %c)", c->file, name, v[a],
                                    "xyz"[a]);
            else
                head->origin[a] = v[a];
    }
    if (gid >= 0)
        H5Oclose(gid);
    return st;
}

/* ---- header and voxels ------------------------------------------------------------------- */

static cdvr_status check_storage(h5_ctx *c, hid_t did, const char *name, const h5_info *in,
                                 size_t file_bytes)
{
    hid_t dcpl = H5Dget_create_plist(did);
    if (dcpl < 0)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s': no creation "
                              "properties", c->file, name);
    cdvr_status st = CDVR_OK;
    H5D_layout_t layout = H5Pget_layout(dcpl);
    if (layout == H5D_VIRTUAL)
        st = cdvr_error_set(c->err, CDVR_ERR_UNSUPPORTED, "%s: HDF5: dataset '%s' is a virtual "
                            "dataset (it maps other datasets or files); cdvr does not read those",
                            c->file, name);
    else if (H5Pget_external_count(dcpl) > 0)
        st = cdvr_error_set(c->err, CDVR_ERR_UNSUPPORTED, "%s: HDF5: dataset '%s' keeps its data "
                            "in external files; cdvr does not read those", c->file, name);
    int nf = st == CDVR_OK ? H5Pget_nfilters(dcpl) : 0;
    for (int i = 0; st == CDVR_OK && i < nf; i++) {
        unsigned flags = 0, cd[8];
        size_t ncd = 8;
        char fname[64] = "";
        H5Z_filter_t id = H5Pget_filter2(dcpl, (unsigned)i, &flags, &ncd, cd, sizeof fname,
                                         fname, NULL);
        if (id < 0 || H5Zfilter_avail(id) <= 0)
            st = cdvr_error_set(c->err, CDVR_ERR_UNSUPPORTED, "%s: HDF5: dataset '%s' needs "
                                "filter %d (%s), which this libhdf5 does not have", c->file, name,
                                (int)id, fname[0] ? fname : "unnamed");
    }
    if (st == CDVR_OK && layout == H5D_CONTIGUOUS) {
        haddr_t at = H5Dget_offset(did);
        hsize_t have = H5Dget_storage_size(did);
        unsigned long long need = cdvr_io_etype_size(in->etype);
        for (int i = 0; i < in->rank; i++)
            need *= in->d[i]; /* the caller checked the product */
        if (at != HADDR_UNDEF && (have < need || at > file_bytes || need > file_bytes - at))
            st = cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' needs %llu "
                                "bytes at byte %llu, the file (%zu bytes) does not hold them",
                                c->file, name, need, (unsigned long long)at, file_bytes);
    }
    H5Eclear2(H5E_DEFAULT);
    H5Pclose(dcpl);
    return st;
}

/* The volume the dataset makes (dims, timesteps, type, geometry) into head. */
static cdvr_status header(h5_ctx *c, hid_t did, const char *name, h5_info *in,
                          size_t file_bytes, cdvr_volume *head)
{
    if (!info_of(did, in))
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s': no dataspace",
                              c->file, name);
    char dims[96];
    describe_dims(in, dims, sizeof dims);
    if (in->rank != 3 && in->rank != 4)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' is %s: cdvr "
                              "reads 3D (z, y, x) or 4D (t, z, y, x) datasets", c->file, name,
                              dims);
    if (!in->numeric)
        return cdvr_error_set(c->err, CDVR_ERR_UNSUPPORTED, "%s: HDF5: dataset '%s' is %s: cdvr "
                              "reads integers of 8 to 64 bits and float32/64", c->file, name,
                              dims);
    int r = in->rank;
    head->dims[0] = (size_t)in->d[r - 1];
    head->dims[1] = (size_t)in->d[r - 2];
    head->dims[2] = (size_t)in->d[r - 3];
    head->timesteps = r == 4 ? (size_t)in->d[0] : 1;
    cdvr_io_set_type(head, in->etype); /* type and source_type */
    size_t bytes;
    for (int i = 0; i < r; i++)
        if (in->d[i] == 0 || in->d[i] > SIZE_MAX)
            return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' is %s (an "
                                  "empty or too large axis)", c->file, name, dims);
    if (!cdvr_volume_bytes_for(head->dims, head->timesteps, CDVR_TYPE_F32, &bytes) ||
        bytes / 4 > SIZE_MAX / 8) /* the file's own bytes (up to 8 per value) must count too */
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' is %s: its size "
                              "overflows", c->file, name, dims);
    cdvr_status st = check_storage(c, did, name, in, file_bytes);
    return st == CDVR_OK ? geometry(c, did, name, r, head) : st;
}

static hid_t native_type(cdvr_io_etype t)
{
    switch (t) {
    case CDVR_IO_I8: return H5T_NATIVE_INT8;
    case CDVR_IO_U8: return H5T_NATIVE_UINT8;
    case CDVR_IO_I16: return H5T_NATIVE_INT16;
    case CDVR_IO_U16: return H5T_NATIVE_UINT16;
    case CDVR_IO_I32: return H5T_NATIVE_INT32;
    case CDVR_IO_U32: return H5T_NATIVE_UINT32;
    case CDVR_IO_I64: return H5T_NATIVE_INT64;
    case CDVR_IO_U64: return H5T_NATIVE_UINT64;
    case CDVR_IO_F32: return H5T_NATIVE_FLOAT;
    default: return H5T_NATIVE_DOUBLE;
    }
}

#define SLAB_BYTES ((size_t)64 << 20) /* temporary buffer of a converted type */

/* The voxels into vol: a kept type in one read, a converted one slab by slab (planes of the
 * dataset, t and z flattened) through a buffer of the file's type. */
static cdvr_status read_voxels(h5_ctx *c, hid_t did, const char *name, const h5_info *in,
                               cdvr_volume *vol)
{
    hid_t mt = native_type(in->etype);
    if (!cdvr_io_etype_converted(in->etype)) {
        if (H5Dread(did, mt, H5S_ALL, H5S_ALL, H5P_DEFAULT, vol->data) >= 0)
            return CDVR_OK;
        char why[256];
        cdvr_hdf5_reason(why, sizeof why);
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' cannot be read: "
                              "%s", c->file, name, why);
    }
    int r = in->rank;
    size_t es = cdvr_io_etype_size(in->etype), plane = vol->dims[0] * vol->dims[1];
    size_t Z = vol->dims[2], planes = Z * vol->timesteps;
    size_t per = SLAB_BYTES / (plane * es);
    per = per < 1 ? 1 : per > Z ? Z : per;
    uint8_t *buf = malloc(per * plane * es);
    hid_t fsp = H5Dget_space(did);
    if (!buf || fsp < 0) {
        free(buf);
        if (fsp >= 0)
            H5Sclose(fsp);
        return cdvr_error_set(c->err, CDVR_ERR_NOMEM, "%s: out of memory", c->file);
    }
    cdvr_io_range range;
    cdvr_io_range_init(&range, c->opts);
    cdvr_status st = CDVR_OK;
    for (size_t p = 0; st == CDVR_OK && p < planes;) {
        size_t t = p / Z, z = p % Z, k = Z - z < per ? Z - z : per;
        hsize_t start[4] = {0}, count[4];
        int o = r == 4;
        if (o) {
            start[0] = t;
            count[0] = 1;
        }
        start[o] = z;
        count[o] = k;
        start[o + 1] = start[o + 2] = 0;
        count[o + 1] = vol->dims[1];
        count[o + 2] = vol->dims[0];
        hsize_t mcount = (hsize_t)(k * plane);
        hid_t msp = H5Screate_simple(1, &mcount, NULL);
        if (msp < 0 ||
            H5Sselect_hyperslab(fsp, H5S_SELECT_SET, start, NULL, count, NULL) < 0 ||
            H5Dread(did, mt, msp, fsp, H5P_DEFAULT, buf) < 0) {
            char why[256];
            cdvr_hdf5_reason(why, sizeof why);
            st = cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: HDF5: dataset '%s' cannot be read "
                                "(planes %zu..%zu): %s", c->file, name, p, p + k - 1, why);
        } else
            cdvr_io_store(vol, p * plane, buf, in->etype, !cdvr_host_is_little_endian(),
                          k * plane, &range);
        if (msp >= 0)
            H5Sclose(msp);
        p += k;
    }
    H5Sclose(fsp);
    free(buf);
    if (st == CDVR_OK)
        st = cdvr_io_finish(vol, in->etype, &range, c->file, "HDF5", c->err);
    return st;
}

/* Opens the file and the dataset; probe (out NULL) or load. Holds the library lock. */
static cdvr_status h5_run(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                          cdvr_volume **out, cdvr_error *err)
{
    extern const cdvr_format cdvr_format_hdf5;
    cdvr_subpath sp;
    cdvr_status st = cdvr_subpath_begin(&cdvr_format_hdf5, path, opts, "dataset", &sp, err);
    if (st != CDVR_OK)
        return st;
    struct stat sb;
    size_t file_bytes = fstat(sp.fd, &sb) == 0 ? (size_t)sb.st_size : 0;
    h5_ctx c = {sp.file, opts, err, -1, -1, -1};
    char name[H5_NAME_MAX] = "";
    hid_t fapl = -1, did = -1;
    h5_info in;
    cdvr_volume local = *head, *vol = NULL;
    cdvr_hdf5_lock();
    fapl = H5Pcreate(H5P_FILE_ACCESS);
    c.lapl = H5Pcreate(H5P_LINK_ACCESS);
    c.dapl = H5Pcreate(H5P_DATASET_ACCESS);
    if (fapl < 0 || c.lapl < 0 || c.dapl < 0 || H5Pset_elink_cb(c.lapl, deny_elink, NULL) < 0 ||
        H5Pset_elink_cb(c.dapl, deny_elink, NULL) < 0)
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: HDF5: cannot make property lists",
                            sp.file);
#if H5_VERSION_GE(1, 10, 7)
    if (st == CDVR_OK)
        H5Pset_file_locking(fapl, 0, 1); /* read only: no lock (NFS, read-only media) */
#endif
    if (st == CDVR_OK && (c.fid = H5Fopen(sp.open, H5F_ACC_RDONLY, fapl)) < 0) {
        char why[256];
        cdvr_hdf5_reason(why, sizeof why);
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not an HDF5 file libhdf5 reads (%s)",
                            sp.file, why);
    }
    if (st == CDVR_OK)
        st = find_dataset(&c, sp.name, &did, name);
    if (st == CDVR_OK)
        st = header(&c, did, name, &in, file_bytes, &local);
    size_t bytes = 0;
    if (st == CDVR_OK && out) {
        char what[H5_NAME_MAX + 24];
        snprintf(what, sizeof what, "HDF5: dataset '%s'", name);
        cdvr_volume_bytes_for(local.dims, local.timesteps, local.type, &bytes); /* checked */
        st = cdvr_load_check_claim(sp.file, what, bytes, opts, err);
    }
    if (st == CDVR_OK && out)
        st = cdvr_volume_create(local.dims, local.timesteps, local.type, &vol, err);
    if (st == CDVR_OK && out)
        st = read_voxels(&c, did, name, &in, vol);
    if (did >= 0)
        H5Dclose(did);
    if (c.fid >= 0)
        H5Fclose(c.fid);
    if (c.lapl >= 0)
        H5Pclose(c.lapl);
    if (c.dapl >= 0)
        H5Pclose(c.dapl);
    if (fapl >= 0)
        H5Pclose(fapl);
    cdvr_hdf5_unlock();
    cdvr_subpath_done(&sp);
    if (st != CDVR_OK) {
        cdvr_volume_free(vol);
        return st;
    }
    if (out) {
        memcpy(vol->spacing, local.spacing, sizeof local.spacing);
        memcpy(vol->origin, local.origin, sizeof local.origin);
        *out = vol;
    } else
        *head = local;
    return CDVR_OK;
}

static cdvr_status h5_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                            cdvr_error *err)
{
    return h5_run(path, opts, head, NULL, err);
}

static cdvr_status h5_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                           cdvr_error *err)
{
    *out = NULL;
    cdvr_volume head;
    cdvr_volume_header_preset(&head);
    return h5_run(path, opts, &head, out, err);
}

/* HDF5's signature at byte 0 (a file with a user block has it at 512, 1024, ...: those are
 * found by their suffix). */
static int h5_magic(const uint8_t *head, size_t n)
{
    static const uint8_t sig[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
    return n >= 8 && memcmp(head, sig, 8) == 0;
}

static const char *const h5_suffixes[] = {".h5", ".hdf5", ".he5", ".hdf", NULL};

const cdvr_format cdvr_format_hdf5 = {
    .name = "hdf5",
    .description = "HDF5 (libhdf5): FILE:/group/dataset, select=, or the only 3D/4D dataset; "
                   "(z,y,x) or (t,z,y,x), chunked and compressed; element_size_um or "
                   "spacing/origin attributes, else unit spacing; 64-bit and int32 as float32, "
                   "window in double",
    .suffixes = h5_suffixes,
    .flags = CDVR_FORMAT_SUBPATH,
    .magic = h5_magic,
    .probe = h5_probe,
    .load = h5_load,
};
