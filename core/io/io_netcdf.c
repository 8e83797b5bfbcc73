/* core/io/io_netcdf.c - NetCDF (.nc .nc4 .cdf: classic, 64-bit offset, CDF-5 and netCDF-4)
 * through libnetcdf (format "netcdf", CDVR_FORMAT_SUBPATH).
 *
 * Which variable: FILE:NAME (cdvr/format.h rule 1b; "/group/var" in a netCDF-4 file), else
 * cdvr_raw_opts.select, else the root group's only 3D or 4D numeric variable (several:
 * refused, listing them with their dimensions; a name the file does not hold: refused listing
 * its variables). Naming a variable both ways with different names is refused.
 * Layout: dimensions as NetCDF gives them, slowest first, the last one x (fastest): (z, y, x);
 * the series (timesteps) is the first dimension when it is the unlimited one or is called
 * `time`, so (time, z, y, x) is a series, and (time, y, x) a series of one-slice volumes; a 4D
 * variable's first dimension is always the series. A time or unlimited dimension elsewhere
 * than first is refused (cdvr does not transpose).
 * Geometry: CF coordinate variables (a 1D numeric variable named like its dimension) of the
 * x, y and z dimensions give spacing (the mean step, its sign the direction of that axis) and
 * origin (the first value) when uniform: every step within a relative 1e-6 of the mean step; a
 * non-uniform axis is refused naming the variable and its worst step. Axes without one: unit
 * spacing, origin 0.
 * Values: ubyte, short, ushort and float are kept (u8, i16, u16, f32); byte, int, uint, int64,
 * uint64 and double become f32 with the window computed in double. A variable with
 * _FillValue or missing_value (up to 8 values) becomes f32 and those values NaN; scale_factor
 * and add_offset (CF packing) are applied in double (f32 volume). valid_range, else valid_min /
 * valid_max (CF: in the stored units, before scale_factor) make values outside NaN (f32 volume).
 * Without a name (FILE:NAME or select=), the only 3D/4D variable of the root group and its
 * subgroups (netCDF-4; listed with their group paths when there are several).
 * A classic file shorter than its header implies is refused before any value is read
 * (check_classic_size).
 * probe reads the header and the coordinate variables, never the variable's values. A load
 * checks the claim against cdvr_load_max_bytes(opts) before allocating (and, for the classic
 * formats, which store values uncompressed, against the file's size). The path is checked as
 * a regular file (cdvr/regular_file.h) and the library gets /proc/self/fd/N of that open file.
 * Thread safety: libnetcdf is not thread-safe and calls libhdf5 for netCDF-4 files, so every
 * call holds the library lock of io_hdf5.h (the same one as the HDF5 loader). */
#include "io_hdf5.h"
#include "cdvr/format.h"
#include "io_common.h"
#include "volume_io.h"

#include <limits.h>
#include <math.h>
#include <netcdf.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#define NCV_NAME_MAX 1024
#define NCV_LIST_MAX 300
#define NCV_FILL_MAX 8

typedef struct ncv_ctx {
    const char *file;
    const cdvr_raw_opts *opts; /* the load options (the f32 rule), or NULL */
    cdvr_error *err;
    int ncid;
} ncv_ctx;

typedef struct ncv_var {
    char name[NCV_NAME_MAX];
    int grp, varid, rank, dimids[NC_MAX_VAR_DIMS];
    size_t len[NC_MAX_VAR_DIMS];
    char dname[4][NC_MAX_NAME + 1];
    nc_type type;
    cdvr_io_etype etype;
    int numeric, series;        /* series: the first dimension is the timesteps */
    int nfill, scaled, ranged; /* ranged: valid_range, valid_min or valid_max given */
    double fill[NCV_FILL_MAX], scale, offset;
    double vmin, vmax;         /* the valid range of stored values ([-inf, inf] when none) */
} ncv_var;

static int nc_etype(nc_type t, cdvr_io_etype *e)
{
    switch (t) {
    case NC_BYTE: *e = CDVR_IO_I8; return 1;
    case NC_UBYTE: *e = CDVR_IO_U8; return 1;
    case NC_SHORT: *e = CDVR_IO_I16; return 1;
    case NC_USHORT: *e = CDVR_IO_U16; return 1;
    case NC_INT: *e = CDVR_IO_I32; return 1;
    case NC_UINT: *e = CDVR_IO_U32; return 1;
    case NC_INT64: *e = CDVR_IO_I64; return 1;
    case NC_UINT64: *e = CDVR_IO_U64; return 1;
    case NC_FLOAT: *e = CDVR_IO_F32; return 1;
    case NC_DOUBLE: *e = CDVR_IO_F64; return 1;
    default: return 0;
    }
}

static const char *nc_type_text(nc_type t)
{
    static const char *const names[] = {"none", "byte", "char", "short", "int", "float",
                                        "double", "ubyte", "ushort", "uint", "int64", "uint64",
                                        "string"};
    return t >= 0 && t <= NC_STRING ? names[t] : "user-defined";
}

/* "u(time=2, z=3, y=7, x=5) float" into out. */
static void describe_var(int grp, int varid, char *out, size_t n)
{
    char name[NC_MAX_NAME + 1] = "?";
    int ndims = 0, dimids[NC_MAX_VAR_DIMS];
    nc_type t = NC_NAT;
    out[0] = '\0';
    if (nc_inq_var(grp, varid, name, &t, &ndims, dimids, NULL) != NC_NOERR)
        return;
    size_t len = (size_t)snprintf(out, n, "%s(", name);
    for (int i = 0; i < ndims && len < n; i++) {
        char dn[NC_MAX_NAME + 1] = "?";
        size_t dl = 0;
        nc_inq_dim(grp, dimids[i], dn, &dl);
        len += (size_t)snprintf(out + len, n - len, "%s%s=%zu", i ? ", " : "", dn, dl);
    }
    if (len < n)
        snprintf(out + len, n - len, ") %s", nc_type_text(t));
}

typedef struct ncv_list {
    size_t count;
    int first, first_grp;
    char text[NCV_LIST_MAX + 8];
    size_t len;
} ncv_list;

#define NCV_GROUP_DEPTH 32

/* The variables of group grp and, recursively, its subgroups (netCDF-4; a classic file has
 * only the root), only the 3D/4D numeric ones when only_candidates; a subgroup's variables are
 * listed with their group path ("/g/u(...)"). */
static void list_group(int grp, int depth, int only_candidates, ncv_list *l)
{
    char path[NCV_NAME_MAX] = "";
    size_t plen = 0;
    if (depth > 0 && nc_inq_grpname_full(grp, &plen, NULL) == NC_NOERR && plen < sizeof path)
        nc_inq_grpname_full(grp, NULL, path);
    int nvars = 0;
    nc_inq_nvars(grp, &nvars);
    for (int v = 0; v < nvars; v++) {
        int ndims = 0;
        nc_type t = NC_NAT;
        cdvr_io_etype e;
        if (nc_inq_var(grp, v, NULL, &t, &ndims, NULL, NULL) != NC_NOERR)
            continue;
        if (only_candidates && !((ndims == 3 || ndims == 4) && nc_etype(t, &e)))
            continue;
        char item[2 * NCV_NAME_MAX + 128], d[NCV_NAME_MAX + 120];
        describe_var(grp, v, d, sizeof d);
        snprintf(item, sizeof item, "%s%s%s%s", l->count ? ", " : "", path, depth ? "/" : "", d);
        if (l->count == 0) {
            l->first = v;
            l->first_grp = grp;
        }
        l->count++;
        size_t k = strlen(item);
        if (l->len + k <= NCV_LIST_MAX) {
            memcpy(l->text + l->len, item, k + 1);
            l->len += k;
        } else if (l->len < NCV_LIST_MAX + 4) {
            memcpy(l->text + l->len, ", ...", 6);
            l->len = NCV_LIST_MAX + 4;
        }
    }
    int ngrps = 0;
    if (depth >= NCV_GROUP_DEPTH || nc_inq_grps(grp, &ngrps, NULL) != NC_NOERR || ngrps <= 0)
        return;
    int *ids = malloc((size_t)ngrps * sizeof *ids);
    if (ids && nc_inq_grps(grp, NULL, ids) == NC_NOERR)
        for (int i = 0; i < ngrps; i++)
            list_group(ids[i], depth + 1, only_candidates, l);
    free(ids);
}

static void list_vars(const ncv_ctx *c, int only_candidates, ncv_list *l)
{
    memset(l, 0, sizeof *l);
    l->first = -1;
    list_group(c->ncid, 0, only_candidates, l);
}

static cdvr_status find_var(const ncv_ctx *c, const char *want, ncv_var *v)
{
    ncv_list l;
    v->grp = c->ncid;
    if (!want[0]) {
        list_vars(c, 1, &l);
        if (l.count == 1) { /* in the root group or a subgroup */
            char base[NC_MAX_NAME + 1] = "";
            size_t plen = 0;
            v->grp = l.first_grp;
            v->varid = l.first;
            nc_inq_varname(v->grp, v->varid, base);
            if (v->grp != c->ncid && nc_inq_grpname_full(v->grp, &plen, NULL) == NC_NOERR &&
                plen + strlen(base) + 2 < sizeof v->name) {
                nc_inq_grpname_full(v->grp, NULL, v->name);
                strcat(v->name, "/");
            } else
                v->name[0] = '\0';
            strcat(v->name, base);
            return CDVR_OK;
        }
        if (l.count == 0) {
            list_vars(c, 0, &l);
            return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: no 3D or 4D numeric "
                                  "variable (variables: %s)", c->file, l.count ? l.text : "none");
        }
        return cdvr_error_set(c->err, CDVR_ERR_ARG, "%s: NetCDF: %zu 3D/4D variables, name one "
                              "as FILE:NAME or with select=: %s", c->file, l.count, l.text);
    }
    if (strlen(want) >= NCV_NAME_MAX)
        return cdvr_error_set(c->err, CDVR_ERR_ARG, "%s: NetCDF: variable name too long",
                              c->file);
    snprintf(v->name, sizeof v->name, "%s", want);
    const char *slash = strrchr(want, '/'), *base = slash ? slash + 1 : want;
    int rc = NC_NOERR;
    if (slash) { /* a netCDF-4 group path */
        char group[NCV_NAME_MAX];
        snprintf(group, sizeof group, "%.*s", slash == want ? 1 : (int)(slash - want), want);
        rc = nc_inq_grp_full_ncid(c->ncid, group, &v->grp);
    }
    if (rc == NC_NOERR)
        rc = nc_inq_varid(v->grp, base, &v->varid);
    if (rc != NC_NOERR) {
        list_vars(c, 0, &l);
        return cdvr_error_set(c->err, CDVR_ERR_ARG, "%s: NetCDF: no variable '%s' (%s; "
                              "variables: %s)", c->file, want, nc_strerror(rc),
                              l.count ? l.text : "none");
    }
    return CDVR_OK;
}

static int is_unlimited(int grp, int dimid)
{
    int n = 0, ids[NC_MAX_DIMS];
    if (nc_inq_unlimdims(grp, &n, NULL) != NC_NOERR || n <= 0 || n > NC_MAX_DIMS)
        return 0;
    nc_inq_unlimdims(grp, &n, ids);
    for (int i = 0; i < n; i++)
        if (ids[i] == dimid)
            return 1;
    return 0;
}

/* Attribute key of the variable as up to n_max numbers: 0 absent, 1 read, -1 refused. */
static int att_numbers(const ncv_ctx *c, const ncv_var *v, const char *key, double *out,
                       int n_max, int *n)
{
    nc_type t;
    size_t len;
    if (nc_inq_att(v->grp, v->varid, key, &t, &len) != NC_NOERR)
        return 0;
    cdvr_io_etype e;
    if (!nc_etype(t, &e) || len < 1 || len > (size_t)n_max ||
        nc_get_att_double(v->grp, v->varid, key, out) != NC_NOERR) {
        cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: attribute %s of variable '%s' is "
                       "not 1 to %d numbers (%zu values of %s)", c->file, key, v->name, n_max,
                       len, nc_type_text(t));
        return -1;
    }
    *n = (int)len;
    return 1;
}

/* The coordinate variable of dimension `d` of v (axis a), if any, into spacing / origin. */
static cdvr_status coordinate(const ncv_ctx *c, const ncv_var *v, int d, int a, cdvr_volume *head)
{
    int cv, nd = 0, did = -1;
    nc_type t = NC_NAT;
    cdvr_io_etype e;
    const char *dn = v->dname[d];
    if (nc_inq_varid(v->grp, dn, &cv) != NC_NOERR ||
        nc_inq_var(v->grp, cv, NULL, &t, &nd, NULL, NULL) != NC_NOERR || nd != 1 ||
        nc_inq_vardimid(v->grp, cv, &did) != NC_NOERR || did != v->dimids[d] || !nc_etype(t, &e))
        return CDVR_OK; /* no coordinate variable: unit spacing, origin 0 */
    size_t n = v->len[d], at0 = 0, atn = n - 1, one = 1;
    double first, last;
    if (nc_get_vara_double(v->grp, cv, &at0, &one, &first) != NC_NOERR ||
        nc_get_vara_double(v->grp, cv, &atn, &one, &last) != NC_NOERR)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: coordinate variable '%s' "
                              "cannot be read", c->file, dn);
    if (!isfinite(first) || !isfinite(last))
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: coordinate variable '%s' "
                              "is not finite (%g .. %g)", c->file, dn, first, last);
    head->origin[a] = first;
    if (n < 2)
        return CDVR_OK;
    double mean = (last - first) / (double)(n - 1), worst = 0, worst_step = mean;
    size_t worst_at = 0;
    if (!(mean != 0 && isfinite(mean)))
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: coordinate variable '%s' "
                              "does not advance (%g .. %g over %zu values)", c->file, dn, first,
                              last, n);
    enum { BLOCK = 4096 };
    double buf[BLOCK + 1], prev = first;
    for (size_t i = 1; i < n;) {
        size_t k = n - i < BLOCK ? n - i : BLOCK;
        if (nc_get_vara_double(v->grp, cv, &i, &k, buf) != NC_NOERR)
            return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: coordinate variable "
                                  "'%s' cannot be read", c->file, dn);
        for (size_t j = 0; j < k; j++) {
            double step = buf[j] - prev, dev = fabs(step - mean);
            if (!(dev <= worst)) { /* NaN counts as the worst */
                worst = isnan(dev) ? INFINITY : dev;
                worst_step = step;
                worst_at = i + j - 1;
            }
            prev = buf[j];
        }
        i += k;
    }
    if (worst > 1e-6 * fabs(mean))
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: coordinate variable '%s' is "
                              "not uniform: step %.9g from index %zu to %zu, the mean step is "
                              "%.9g (cdvr needs every step within a relative 1e-6 of it)",
                              c->file, dn, worst_step, worst_at, worst_at + 1, mean);
    head->spacing[a] = fabs(mean);
    head->direction[4 * a] = mean < 0 ? -1 : 1;
    return CDVR_OK;
}

/* ---- the size a classic file's header implies ------------------------------------------------
 * libnetcdf reads a classic (CDF-1, CDF-2 or CDF-5) file that was cut short without complaint
 * (its reads past the end give zeros), so the loader checks the size first: the header as the
 * format encodes it (its length follows from the names, dimensions, attributes and variables
 * libnetcdf reports), then the fixed-size variables (each padded to 4 bytes) and numrecs
 * records (the record variables, each padded, unpadded when there is only one). A file must
 * hold that much (the last item's padding aside); writers that leave free space after the
 * header (h_minfree) only make it larger, so the bound never refuses a whole file. */

typedef struct classic_sizes {
    unsigned long long word; /* NON_NEG: 4, CDF-5 8 */
    unsigned long long header, fixed, record, last_pad;
} classic_sizes;

static unsigned long long pad4(unsigned long long n) { return (n + 3) / 4 * 4; }

static unsigned long long name_bytes(const classic_sizes *z, const char *name)
{
    return z->word + pad4(strlen(name));
}

static size_t type_bytes(nc_type t)
{
    switch (t) {
    case NC_BYTE: case NC_CHAR: case NC_UBYTE: return 1;
    case NC_SHORT: case NC_USHORT: return 2;
    case NC_INT: case NC_UINT: case NC_FLOAT: return 4;
    default: return 8;
    }
}

/* The attribute list of varid (NC_GLOBAL for the file's). */
static int atts_bytes(int nc, int varid, const classic_sizes *z, unsigned long long *out)
{
    int natts = 0;
    if (nc_inq_varnatts(nc, varid, &natts) != NC_NOERR)
        return 0;
    unsigned long long n = 4 + z->word; /* tag and count (ABSENT: ZERO ZERO) */
    for (int i = 0; i < natts; i++) {
        char name[NC_MAX_NAME + 1];
        nc_type t;
        size_t len;
        if (nc_inq_attname(nc, varid, i, name) != NC_NOERR ||
            nc_inq_att(nc, varid, name, &t, &len) != NC_NOERR)
            return 0;
        n += name_bytes(z, name) + 4 + z->word + pad4((unsigned long long)len * type_bytes(t));
    }
    *out = n;
    return 1;
}

static int classic_size(int nc, int format, classic_sizes *z)
{
    memset(z, 0, sizeof *z);
    z->word = format == NC_FORMAT_CDF5 ? 8 : 4;
    int ndims = 0, nvars = 0, unlim = -1;
    size_t numrecs = 0;
    if (nc_inq(nc, &ndims, &nvars, NULL, &unlim) != NC_NOERR)
        return 0;
    if (unlim >= 0 && nc_inq_dimlen(nc, unlim, &numrecs) != NC_NOERR)
        return 0;
    unsigned long long h = 4 + z->word + 4 + z->word, a; /* magic, numrecs, dim list head */
    for (int d = 0; d < ndims; d++) {
        char name[NC_MAX_NAME + 1];
        if (nc_inq_dimname(nc, d, name) != NC_NOERR)
            return 0;
        h += name_bytes(z, name) + z->word;
    }
    if (!atts_bytes(nc, NC_GLOBAL, z, &a))
        return 0;
    h += a + 4 + z->word; /* global attributes, variable list head */
    unsigned long long begin = format == NC_FORMAT_CLASSIC ? 4 : 8, last_fixed = 0, last_rec = 0;
    int nrec = 0;
    for (int v = 0; v < nvars; v++) {
        char name[NC_MAX_NAME + 1];
        nc_type t;
        int nd, dims[NC_MAX_VAR_DIMS];
        if (nc_inq_var(nc, v, name, &t, &nd, dims, NULL) != NC_NOERR || !atts_bytes(nc, v, z, &a))
            return 0;
        h += name_bytes(z, name) + z->word + (unsigned long long)nd * z->word + a + 4 + z->word +
             begin;
        unsigned long long len = type_bytes(t);
        int record = nd > 0 && dims[0] == unlim;
        for (int i = record; i < nd; i++) {
            size_t dl;
            if (nc_inq_dimlen(nc, dims[i], &dl) != NC_NOERR || (dl && len > ULLONG_MAX / 8 / dl))
                return 0;
            len *= dl;
        }
        if (record) {
            nrec++;
            z->record += pad4(len);
            last_rec = len;
        } else {
            z->fixed += pad4(len);
            last_fixed = len;
        }
    }
    /* the file ends with the last record (its last record variable) or the last fixed one;
     * its padding may be missing. One record variable: records packed, no padding. */
    if (nrec == 1)
        z->record = last_rec;
    z->last_pad = nrec && numrecs ? (nrec == 1 ? 0 : pad4(last_rec) - last_rec)
                                  : pad4(last_fixed) - last_fixed;
    z->header = h;
    if (z->record && numrecs > (ULLONG_MAX / 2 - z->fixed - h) / z->record)
        return 0;
    z->record *= numrecs;
    return 1;
}

/* CDVR_ERR_FORMAT when a classic file is shorter than its header implies (truncated). */
static cdvr_status check_classic_size(const ncv_ctx *c, size_t file_bytes)
{
    int format = 0;
    nc_inq_format(c->ncid, &format);
    if (format != NC_FORMAT_CLASSIC && format != NC_FORMAT_64BIT_OFFSET &&
        format != NC_FORMAT_CDF5)
        return CDVR_OK; /* netCDF-4: HDF5 checks its own structure */
    classic_sizes z;
    if (!classic_size(c->ncid, format, &z))
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: the header's sizes cannot "
                              "be told or overflow", c->file);
    unsigned long long need = z.header + z.fixed + z.record;
    if ((unsigned long long)file_bytes + z.last_pad >= need)
        return CDVR_OK;
    return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: the file is truncated: its "
                          "header implies at least %llu bytes (header %llu, fixed-size data "
                          "%llu, records %llu), the file holds %zu", c->file, need, z.header,
                          z.fixed, z.record, file_bytes);
}

/* CF valid_range (two numbers), else valid_min and/or valid_max, in the stored (packed) units:
 * values outside become NaN as missing ones do. A range whose ends are NaN or reversed is
 * refused. (The default range NUG derives from _FillValue alone is not applied.) */
static cdvr_status valid_range(const ncv_ctx *c, ncv_var *v)
{
    double r[2];
    int n = 0, k;
    v->vmin = -INFINITY;
    v->vmax = INFINITY;
    v->ranged = 0;
    if ((k = att_numbers(c, v, "valid_range", r, 2, &n)) < 0)
        return c->err ? c->err->status : CDVR_ERR_FORMAT;
    if (k && n != 2)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable '%s': valid_range "
                              "has %d value, not 2", c->file, v->name, n);
    if (k) {
        v->vmin = r[0];
        v->vmax = r[1];
    } else {
        if ((k = att_numbers(c, v, "valid_min", &v->vmin, 1, &n)) < 0)
            return c->err ? c->err->status : CDVR_ERR_FORMAT;
        v->ranged |= k;
        if ((k = att_numbers(c, v, "valid_max", &v->vmax, 1, &n)) < 0)
            return c->err ? c->err->status : CDVR_ERR_FORMAT;
    }
    v->ranged |= k;
    if (v->ranged && !(v->vmin <= v->vmax))
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable '%s': valid range "
                              "[%g, %g] is empty or not a number", c->file, v->name, v->vmin,
                              v->vmax);
    return CDVR_OK;
}

/* The volume the variable makes into head; v's shape and value attributes. */
static cdvr_status header(const ncv_ctx *c, ncv_var *v, size_t file_bytes, cdvr_volume *head)
{
    char d[NCV_NAME_MAX + 120];
    describe_var(v->grp, v->varid, d, sizeof d);
    if (nc_inq_var(v->grp, v->varid, NULL, &v->type, &v->rank, v->dimids, NULL) != NC_NOERR)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable '%s' cannot be "
                              "read", c->file, v->name);
    if (v->rank != 3 && v->rank != 4)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable %s has %d "
                              "dimensions: cdvr reads 3D (z, y, x), (time, y, x) or 4D (time, z, "
                              "y, x) variables", c->file, d, v->rank);
    if (!(v->numeric = nc_etype(v->type, &v->etype)))
        return cdvr_error_set(c->err, CDVR_ERR_UNSUPPORTED, "%s: NetCDF: variable %s is not "
                              "numeric", c->file, d);
    int times = 0;
    for (int i = 0; i < v->rank; i++) {
        v->dname[i][0] = '\0';
        if (nc_inq_dim(v->grp, v->dimids[i], v->dname[i], &v->len[i]) != NC_NOERR)
            return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable '%s': a "
                                  "dimension cannot be read", c->file, v->name);
        int t = is_unlimited(v->grp, v->dimids[i]) || strcasecmp(v->dname[i], "time") == 0;
        if (t && i > 0)
            return cdvr_error_set(c->err, CDVR_ERR_UNSUPPORTED, "%s: NetCDF: variable %s has "
                                  "its time (or unlimited) dimension '%s' at place %d: cdvr reads "
                                  "the series along the first (slowest) dimension", c->file, d,
                                  v->dname[i], i + 1);
        times |= t;
        if (v->len[i] == 0)
            return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable %s is empty",
                                  c->file, d);
    }
    v->series = v->rank == 4 || times;
    int r = v->rank, s0 = v->series; /* s0: the first spatial dimension */
    head->dims[0] = v->len[r - 1];
    head->dims[1] = v->len[r - 2];
    head->dims[2] = r - s0 == 3 ? v->len[r - 3] : 1;
    head->timesteps = s0 ? v->len[0] : 1;
    /* value attributes */
    int n = 0, k;
    cdvr_status st;
    v->nfill = 0;
    v->scale = 1;
    v->offset = 0;
    v->scaled = 0;
    if ((k = att_numbers(c, v, "_FillValue", v->fill, 1, &n)) < 0)
        return c->err ? c->err->status : CDVR_ERR_FORMAT;
    v->nfill = k ? n : 0;
    if ((k = att_numbers(c, v, "missing_value", v->fill + v->nfill, NCV_FILL_MAX - 1, &n)) < 0)
        return c->err ? c->err->status : CDVR_ERR_FORMAT;
    v->nfill += k ? n : 0;
    if ((k = att_numbers(c, v, "scale_factor", &v->scale, 1, &n)) < 0)
        return c->err ? c->err->status : CDVR_ERR_FORMAT;
    v->scaled |= k;
    if ((k = att_numbers(c, v, "add_offset", &v->offset, 1, &n)) < 0)
        return c->err ? c->err->status : CDVR_ERR_FORMAT;
    v->scaled |= k;
    if ((st = valid_range(c, v)) != CDVR_OK)
        return st;
    if (v->scaled && !(isfinite(v->scale) && isfinite(v->offset)))
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable '%s': scale_factor "
                              "%g / add_offset %g are not finite", c->file, v->name, v->scale,
                              v->offset);
    int convert = cdvr_io_etype_converted(v->etype) || v->nfill || v->scaled || v->ranged;
    cdvr_io_set_type(head, v->etype); /* source_type: the file's type */
    if (convert)
        head->type = CDVR_TYPE_F32; /* fill values or scale/offset: f32 */
    size_t bytes;
    if (!cdvr_volume_bytes_for(head->dims, head->timesteps, CDVR_TYPE_F32, &bytes) ||
        bytes / 4 > SIZE_MAX / 8)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable %s: its size "
                              "overflows", c->file, d);
    int format = 0;
    nc_inq_format(c->ncid, &format);
    unsigned long long raw = (unsigned long long)(bytes / 4) * cdvr_io_etype_size(v->etype);
    if ((format == NC_FORMAT_CLASSIC || format == NC_FORMAT_64BIT_OFFSET ||
         format == NC_FORMAT_CDF5) && raw > file_bytes)
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable %s needs %llu "
                              "bytes, the file holds %zu", c->file, d, raw, file_bytes);
    for (int a = 0; a < 3 && a < r - s0; a++) {
        cdvr_status st = coordinate(c, v, r - 1 - a, a, head);
        if (st != CDVR_OK)
            return st;
    }
    return CDVR_OK;
}

#define SLAB_BYTES ((size_t)64 << 20)

/* The values into vol: kept types in one read; converted ones (and fill values, packing) slab by
 * slab as double. */
static cdvr_status read_values(const ncv_ctx *c, const ncv_var *v, cdvr_volume *vol)
{
    int r = v->rank, rc;
    size_t start[4] = {0}, count[4];
    for (int i = 0; i < r; i++)
        count[i] = v->len[i];
    if (!v->nfill && !v->scaled && !v->ranged && !cdvr_io_etype_converted(v->etype)) {
        rc = nc_get_vara(v->grp, v->varid, start, count, vol->data); /* the volume's type */
        if (rc == NC_NOERR)
            return CDVR_OK;
        return cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable '%s' cannot be "
                              "read: %s", c->file, v->name, nc_strerror(rc));
    }
    size_t plane = vol->dims[0] * vol->dims[1];
    size_t inner = v->len[r - 3], planes = vol->dims[2] * vol->timesteps; /* == product */
    size_t per = SLAB_BYTES / (plane * sizeof(double));
    per = per < 1 ? 1 : per > inner ? inner : per;
    double *buf = malloc(per * plane * sizeof *buf);
    if (!buf)
        return cdvr_error_set(c->err, CDVR_ERR_NOMEM, "%s: out of memory", c->file);
    float *dst = vol->data;
    double lo = INFINITY, hi = -INFINITY;
    cdvr_f32_guard guard;
    cdvr_f32_guard_init(&guard, c->opts);
    cdvr_status st = CDVR_OK;
    for (size_t p = 0; st == CDVR_OK && p < planes;) {
        size_t outer = p / inner, z = p % inner, k = inner - z < per ? inner - z : per;
        if (r == 4) {
            start[0] = outer;
            count[0] = 1;
        }
        start[r - 3] = z;
        count[r - 3] = k;
        rc = nc_get_vara_double(v->grp, v->varid, start, count, buf);
        if (rc != NC_NOERR) {
            st = cdvr_error_set(c->err, CDVR_ERR_FORMAT, "%s: NetCDF: variable '%s' cannot be "
                                "read: %s", c->file, v->name, nc_strerror(rc));
            break;
        }
        for (size_t i = 0, m = k * plane; i < m; i++) {
            double x = buf[i];
            int fill = 0;
            for (int f = 0; f < v->nfill; f++)
                fill |= x == v->fill[f];
            if (fill || x < v->vmin || x > v->vmax) {
                dst[p * plane + i] = NAN;
                continue;
            }
            x = x * v->scale + v->offset;
            if (isfinite(x)) {
                lo = x < lo ? x : lo;
                hi = x > hi ? x : hi;
            }
            dst[p * plane + i] = cdvr_f32_guard_put(&guard, x, p * plane + i);
        }
        p += k;
    }
    free(buf);
    vol->window[0] = lo <= hi ? lo : 0;
    vol->window[1] = lo <= hi ? hi : 0;
    if (st == CDVR_OK)
        st = cdvr_f32_guard_finish(&guard, c->file, v->scaled ? "NetCDF (after scale_factor, "
                                   "add_offset)" : "NetCDF", cdvr_io_etype_name(v->etype), vol,
                                   c->err);
    return st;
}

static cdvr_status ncv_run(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                           cdvr_volume **out, cdvr_error *err)
{
    extern const cdvr_format cdvr_format_netcdf;
    cdvr_subpath sp;
    cdvr_status st = cdvr_subpath_begin(&cdvr_format_netcdf, path, opts, "variable", &sp, err);
    if (st != CDVR_OK)
        return st;
    struct stat sb;
    size_t file_bytes = fstat(sp.fd, &sb) == 0 ? (size_t)sb.st_size : 0;
    ncv_ctx c = {sp.file, opts, err, -1};
    ncv_var *v = calloc(1, sizeof *v);
    cdvr_volume local = *head, *vol = NULL;
    if (!v) {
        cdvr_subpath_done(&sp);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    cdvr_hdf5_lock();
    int rc = nc_open(sp.open, NC_NOWRITE, &c.ncid);
    if (rc != NC_NOERR) {
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not a NetCDF file libnetcdf reads (%s)",
                            sp.file, nc_strerror(rc));
        c.ncid = -1;
    }
    if (st == CDVR_OK)
        st = check_classic_size(&c, file_bytes);
    if (st == CDVR_OK)
        st = find_var(&c, sp.name, v);
    if (st == CDVR_OK)
        st = header(&c, v, file_bytes, &local);
    size_t bytes = 0;
    if (st == CDVR_OK && out) {
        char what[sizeof v->name + 24];
        snprintf(what, sizeof what, "NetCDF: variable '%s'", v->name);
        cdvr_volume_bytes_for(local.dims, local.timesteps, local.type, &bytes); /* checked */
        st = cdvr_load_check_claim(sp.file, what, bytes, opts, err);
    }
    if (st == CDVR_OK && out)
        st = cdvr_volume_create(local.dims, local.timesteps, local.type, &vol, err);
    if (st == CDVR_OK && out)
        st = read_values(&c, v, vol);
    if (c.ncid >= 0)
        nc_close(c.ncid);
    cdvr_hdf5_unlock();
    cdvr_subpath_done(&sp);
    free(v);
    if (st != CDVR_OK) {
        cdvr_volume_free(vol);
        return st;
    }
    if (out) {
        memcpy(vol->spacing, local.spacing, sizeof local.spacing);
        memcpy(vol->origin, local.origin, sizeof local.origin);
        memcpy(vol->direction, local.direction, sizeof local.direction);
        memcpy(vol->source_type, local.source_type, sizeof local.source_type);
        *out = vol;
    } else
        *head = local;
    return CDVR_OK;
}

static cdvr_status ncv_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                             cdvr_error *err)
{
    return ncv_run(path, opts, head, NULL, err);
}

static cdvr_status ncv_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                            cdvr_error *err)
{
    *out = NULL;
    cdvr_volume head;
    cdvr_volume_header_preset(&head);
    return ncv_run(path, opts, &head, out, err);
}

/* Classic (CDF 1), 64-bit offset (CDF 2) and CDF-5 files; netCDF-4 files are HDF5 files
 * (found by their suffix; without one the hdf5 format reads them). */
static int ncv_magic(const uint8_t *head, size_t n)
{
    return n >= 4 && memcmp(head, "CDF", 3) == 0 && (head[3] == 1 || head[3] == 2 ||
                                                    head[3] == 5);
}

static const char *const ncv_suffixes[] = {".nc", ".nc4", ".cdf", NULL};

const cdvr_format cdvr_format_netcdf = {
    .name = "netcdf",
    .description = "NetCDF (libnetcdf; classic and netCDF-4): FILE:VAR, select=, or the only "
                   "3D/4D variable; time or unlimited first dimension as timesteps; uniform CF "
                   "coordinates as spacing/origin; _FillValue/missing_value to NaN and "
                   "scale_factor/add_offset (float32)",
    .suffixes = ncv_suffixes,
    .flags = CDVR_FORMAT_SUBPATH,
    .magic = ncv_magic,
    .probe = ncv_probe,
    .load = ncv_load,
};
