/* core/io/io_nrrd.c - NRRD (.nrrd, .nhdr with detached data) through teem. */
#include "cdvr/volume.h"
#include "volume_io.h"
#include "cdvr/format.h"
#include "io_nrrd.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static double read_i8(const void *p, size_t i) { return ((const signed char *)p)[i]; }
static double read_i32(const void *p, size_t i) { return ((const int32_t *)p)[i]; }
static double read_u32(const void *p, size_t i) { return ((const uint32_t *)p)[i]; }
static double read_i64(const void *p, size_t i) { return (double)((const int64_t *)p)[i]; }
static double read_u64(const void *p, size_t i) { return (double)((const uint64_t *)p)[i]; }
static double read_f64(const void *p, size_t i) { return ((const double *)p)[i]; }

/* The file type name of a teem type (cdvr_volume.source_type). */
static const char *nrrd_file_type(int nrrd_type)
{
    switch (nrrd_type) {
    case nrrdTypeChar: return "int8";
    case nrrdTypeUChar: return "uint8";
    case nrrdTypeShort: return "int16";
    case nrrdTypeUShort: return "uint16";
    case nrrdTypeInt: return "int32";
    case nrrdTypeUInt: return "uint32";
    case nrrdTypeLLong: return "int64";
    case nrrdTypeULLong: return "uint64";
    case nrrdTypeFloat: return "float32";
    case nrrdTypeDouble: return "float64";
    default: return NULL;
    }
}

/* Our type for a teem type; *reader is set when the values must be converted to f32. */
static int map_type(int nrrd_type, cdvr_type *type, cdvr_value_reader *reader)
{
    *reader = NULL;
    *type = CDVR_TYPE_F32;
    switch (nrrd_type) {
    case nrrdTypeUChar: *type = CDVR_TYPE_U8; return 1;
    case nrrdTypeUShort: *type = CDVR_TYPE_U16; return 1;
    case nrrdTypeShort: *type = CDVR_TYPE_I16; return 1;
    case nrrdTypeFloat: return 1;
    case nrrdTypeChar: *reader = read_i8; return 1;
    case nrrdTypeInt: *reader = read_i32; return 1;
    case nrrdTypeUInt: *reader = read_u32; return 1;
    case nrrdTypeLLong: *reader = read_i64; return 1;
    case nrrdTypeULLong: *reader = read_u64; return 1;
    case nrrdTypeDouble: *reader = read_f64; return 1;
    default: return 0;
    }
}

static int scalar_axis_kind(int kind, int allow_list)
{
    switch (kind) {
    case nrrdKindUnknown:
    case nrrdKindDomain:
    case nrrdKindSpace:
    case nrrdKindTime:
    case nrrdKindStub:
    case nrrdKindScalar: return 1;
    case nrrdKindList: return allow_list;
    default: return 0;
    }
}

/* Dims and timesteps of a 2D, 3D or 4D scalar nrrd (a 2D image is one slice). */
static cdvr_status nrrd_shape(const char *path, const Nrrd *nrrd, size_t dims[3], size_t *timesteps,
                              cdvr_error *err)
{
    if (nrrd->dim < 2 || nrrd->dim > 4)
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD has dimension %u; cdvr reads 3D volumes (2D and 4D = 3D + time too)",
                              path, nrrd->dim);
    dims[2] = *timesteps = 1;
    for (unsigned ax = 0; ax < nrrd->dim; ax++) {
        if (!scalar_axis_kind(nrrd->axis[ax].kind, ax == 3))
            return cdvr_error_set(err, CDVR_ERR_FORMAT,
                                  "%s: NRRD axis %u has kind '%s': only scalar volumes are supported",
                                  path, ax, airEnumStr(nrrdKind, nrrd->axis[ax].kind));
        if (ax < 3)
            dims[ax] = nrrd->axis[ax].size;
        else
            *timesteps = nrrd->axis[ax].size;
    }
    return CDVR_OK;
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Geometry of the (up to 3) spatial axes. With a 3D "space" (space or space dimension
 * field): spacing = length of each axis' "space directions" vector, direction column = that
 * vector normalised (negative and oblique directions kept), origin = "space origin". Without
 * a space: "spacings" (a negative spacing is the axis running backwards: direction -1), origin
 * 0. A 2D image (dims[2] = 1) gets the cross product of its two directions as the third. Axes
 * without a direction or spacing ("none", or no such field) keep the identity column and
 * spacing 1. Refused, naming the field and the value: a zero or non-finite direction vector, a
 * spacing given as 0, NaN or infinite, a non-finite space origin, and a singular set of
 * directions (parallel axes). */
/* The named world of a NRRD "space" (3D ones; 3D-time ones too), else "". */
static const char *nrrd_space_name(int space)
{
    switch (space) {
    case nrrdSpaceRightAnteriorSuperior: case nrrdSpaceRightAnteriorSuperiorTime: return "RAS";
    case nrrdSpaceLeftAnteriorSuperior: case nrrdSpaceLeftAnteriorSuperiorTime: return "LAS";
    case nrrdSpaceLeftPosteriorSuperior: case nrrdSpaceLeftPosteriorSuperiorTime: return "LPS";
    default: return "";
    }
}

static cdvr_status nrrd_geometry(const char *path, const Nrrd *nrrd, const NrrdIoState *nio,
                                 cdvr_volume *vol, cdvr_error *err)
{
    cdvr_volume_set_space(vol, nrrd_space_name(nrrd->space));
    unsigned n = nrrd->dim < 3 ? nrrd->dim : 3;
    int has_dir[3] = {0, 0, 0};
    double cols[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (unsigned ax = 0; ax < n; ax++) {
        const double *sd = nrrd->axis[ax].spaceDirection;
        if (nrrd->spaceDim > 0 && nio->seen[nrrdField_space_directions] && !isnan(sd[0])) {
            double len2 = 0;
            int finite = 1;
            for (unsigned r = 0; r < nrrd->spaceDim; r++) {
                finite &= isfinite(sd[r]);
                len2 += sd[r] * sd[r];
            }
            if (!finite || !(len2 > 0) || !isfinite(len2))
                return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD space directions of axis "
                                      "%u is (%g,%g,%g): %s", path, ax, sd[0],
                                      nrrd->spaceDim > 1 ? sd[1] : 0.0,
                                      nrrd->spaceDim > 2 ? sd[2] : 0.0,
                                      finite && len2 == 0 ? "a zero vector" : "not finite");
        }
        double sp = nrrd->axis[ax].spacing;
        if (nio->seen[nrrdField_spacings] && nrrd->spaceDim == 0 && (!isfinite(sp) || sp == 0))
            return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD spacings of axis %u is %g: a "
                                  "spacing must be finite and nonzero", path, ax, sp);
        double spacing = AIR_NAN, direction[NRRD_SPACE_DIM_MAX];
        int status = nrrdSpacingCalculate(nrrd, ax, &spacing, direction);
        if (!isfinite(spacing) || spacing == 0)
            continue;
        if (status == nrrdSpacingStatusDirection && nrrd->spaceDim == 3) {
            vol->spacing[ax] = spacing; /* teem: the vector's length, direction its unit vector */
            for (int r = 0; r < 3; r++)
                cols[ax][r] = direction[r];
            has_dir[ax] = 1;
        } else if (status == nrrdSpacingStatusScalarNoSpace ||
                   status == nrrdSpacingStatusScalarWithSpace ||
                   status == nrrdSpacingStatusDirection) {
            vol->spacing[ax] = fabs(spacing);
            if (spacing < 0 && status != nrrdSpacingStatusDirection)
                cols[ax][ax] = -1.0;
        }
    }
    if (n == 2 && has_dir[0] && has_dir[1]) {
        double c[3];
        cross3(cols[0], cols[1], c);
        double len = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        for (int r = 0; len > 0 && r < 3; r++)
            cols[2][r] = c[r] / len;
    }
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            vol->direction[3 * r + c] = cols[c][r];
    double inv[9];
    if (!cdvr_mat3_inverse(vol->direction, inv))
        return cdvr_error_set(err, CDVR_ERR_FORMAT,
                              "%s: NRRD space directions are degenerate (the axes do not span "
                              "3D space)",
                              path);
    if (nio->seen[nrrdField_space_origin])
        for (unsigned i = 0; i < nrrd->spaceDim && i < 3; i++)
            if (!isfinite(nrrd->spaceOrigin[i]))
                return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD space origin[%u] is %g: "
                                      "not finite", path, i, nrrd->spaceOrigin[i]);
    for (unsigned i = 0; i < nrrd->spaceDim && i < 3; i++)
        if (isfinite(nrrd->spaceOrigin[i]))
            vol->origin[i] = nrrd->spaceOrigin[i];
    return CDVR_OK;
}

/* ---- the data, read once into the volume ---------------------------------------------------- */

static void swap_n(unsigned char *p, size_t count, size_t size)
{
    for (size_t i = 0; i < count; i++, p += size)
        for (size_t a = 0, b = size - 1; a < b; a++, b--) {
            unsigned char t = p[a];
            p[a] = p[b];
            p[b] = t;
        }
}

/* Turns the file's bytes, in pieces of any length, into the volume's values. */
typedef struct value_sink {
    unsigned char *dst;            /* the volume's voxels */
    size_t esize;                  /* bytes per file value */
    int swap;
    cdvr_value_reader reader;      /* NULL: the values are kept as they are */
    uint64_t done, count;          /* values written, values in all */
    unsigned char carry[8];        /* a value split between pieces */
    size_t carry_n;
    const char *path, *tname;
    cdvr_error *err;
    double lo, hi;                 /* range of the converted values, in double */
    cdvr_f32_guard guard;          /* values beyond f32 (volume_io.h) */
} value_sink;

/* n whole values at p (n <= 512 when converting). */
static int put_values(value_sink *k, const unsigned char *p, size_t n)
{
    if (n > k->count - k->done)
        return cdvr_error_set(k->err, CDVR_ERR_FORMAT, "%s: more NRRD data than the header "
                              "claims", k->path) && 0;
    if (!k->reader) {
        unsigned char *d = k->dst + k->done * k->esize;
        memcpy(d, p, n * k->esize);
        if (k->swap)
            swap_n(d, n, k->esize);
        k->done += n;
        return 1;
    }
    uint64_t tmp[512];
    memcpy(tmp, p, n * k->esize);
    if (k->swap)
        swap_n((unsigned char *)tmp, n, k->esize);
    float *d = (float *)k->dst + k->done;
    for (size_t i = 0; i < n; i++) {
        double v = k->reader(tmp, i);
        if (isfinite(v)) {
            k->lo = v < k->lo ? v : k->lo;
            k->hi = v > k->hi ? v : k->hi;
        }
        d[i] = cdvr_f32_guard_put(&k->guard, v, k->done + i);
    }
    k->done += n;
    return 1;
}

static int sink_bytes(void *ud, const unsigned char *p, size_t n)
{
    value_sink *k = ud;
    if (k->carry_n) {
        size_t take = k->esize - k->carry_n < n ? k->esize - k->carry_n : n;
        memcpy(k->carry + k->carry_n, p, take);
        k->carry_n += take;
        p += take;
        n -= take;
        if (k->carry_n < k->esize)
            return 1;
        k->carry_n = 0;
        if (!put_values(k, k->carry, 1))
            return 0;
    }
    size_t whole = n / k->esize, step = k->reader ? 512 : whole ? whole : 1;
    for (size_t i = 0; i < whole; i += step) {
        size_t m = whole - i < step ? whole - i : step;
        if (!put_values(k, p + i * k->esize, m))
            return 0;
    }
    k->carry_n = n - whole * k->esize;
    memcpy(k->carry, p + whole * k->esize, k->carry_n);
    return 1;
}

/* Data of an encoding teem reads (ascii, hex, zrl): teem loads them (after the checks
 * cdvr_nrrd_open made) and the values are copied. */
static cdvr_status load_by_teem(const char *path, value_sink *k, cdvr_error *err)
{
    Nrrd *nrrd = nrrdNew();
    if (!nrrd)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    cdvr_status st = CDVR_OK;
    if (nrrdLoad(nrrd, path, NULL)) {
        char *msg = biffGetDone(NRRD);
        if (msg)
            cdvr_teem_reason(msg);
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: cannot read NRRD: %s", path,
                            msg && *msg ? msg : "unknown teem error");
        free(msg);
    } else if (nrrdElementNumber(nrrd) != k->count || nrrdElementSize(nrrd) != k->esize) {
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: the NRRD file changed while it was read",
                            path);
    } else {
        k->swap = 0; /* teem has put the values in host order */
        if (!sink_bytes(k, nrrd->data, k->count * k->esize))
            st = CDVR_ERR_FORMAT;
    }
    nrrdNuke(nrrd);
    return st;
}

static cdvr_status load_nrrd(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                             cdvr_error *err)
{
    *out = NULL;
    cdvr_nrrd_source *src;
    cdvr_status st = cdvr_nrrd_open(path, opts, 0, &src, err);
    if (st != CDVR_OK)
        return st;
    const Nrrd *nrrd = cdvr_nrrd_header(src);
    cdvr_type type;
    cdvr_value_reader reader;
    size_t dims[3] = {0, 0, 0}, timesteps = 0;
    cdvr_volume head;
    cdvr_volume_header_preset(&head);
    if (!map_type(nrrd->type, &type, &reader))
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD type '%s' is not supported", path,
                            airEnumStr(nrrdType, nrrd->type));
    if (st == CDVR_OK)
        st = nrrd_shape(path, nrrd, dims, &timesteps, err);
    if (st == CDVR_OK)
        st = nrrd_geometry(path, nrrd, cdvr_nrrd_io(src), &head, err);
    if (st == CDVR_OK)
        st = cdvr_volume_create(dims, timesteps, type, out, err);
    if (st == CDVR_OK) {
        memcpy((*out)->spacing, head.spacing, sizeof head.spacing);
        memcpy((*out)->origin, head.origin, sizeof head.origin);
        memcpy((*out)->direction, head.direction, sizeof head.direction);
        memcpy((*out)->space, head.space, sizeof head.space);
        value_sink k = {(*out)->data, nrrdElementSize(nrrd), cdvr_nrrd_swap(src), reader, 0,
                        (uint64_t)cdvr_volume_voxels(*out) * timesteps, {0}, 0, path,
                        airEnumStr(nrrdType, nrrd->type), err, INFINITY, -INFINITY, {0}};
        cdvr_f32_guard_init(&k.guard, opts);
        if (cdvr_nrrd_streamable(src))
            st = cdvr_nrrd_stream(src, sink_bytes, &k, err);
        else
            st = load_by_teem(path, &k, err);
        if (st == CDVR_OK && k.done != k.count)
            st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD data hold %llu of %llu values",
                                path, (unsigned long long)k.done, (unsigned long long)k.count);
        cdvr_volume_set_source_type(*out, nrrd_file_type(nrrd->type));
        if (st == CDVR_OK) /* u8 quantised from [old min, old max] (teem's fields) */
            cdvr_u8_window_set(*out, nrrd->oldMin, nrrd->oldMax);
        if (st == CDVR_OK && reader) { /* converted: the window in double (cdvr/volume.h) */
            (*out)->window[0] = k.lo <= k.hi ? k.lo : 0;
            (*out)->window[1] = k.lo <= k.hi ? k.hi : 0;
            st = cdvr_f32_guard_finish(&k.guard, path, "NRRD", (*out)->source_type, *out, err);
        }
        if (st != CDVR_OK) {
            cdvr_volume_free(*out);
            *out = NULL;
        }
    }
    cdvr_nrrd_close(src);
    return st;
}

cdvr_status cdvr_volume_load_nrrd(const char *path, cdvr_volume **out, cdvr_error *err)
{
    return load_nrrd(path, NULL, out, err);
}

static cdvr_status probe_nrrd(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                              cdvr_error *err)
{
    cdvr_nrrd_source *src;
    cdvr_status st = cdvr_nrrd_open(path, opts, 1, &src, err);
    if (st != CDVR_OK)
        return st;
    const Nrrd *nrrd = cdvr_nrrd_header(src);
    cdvr_value_reader reader;
    if (!map_type(nrrd->type, &head->type, &reader))
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD type '%s' is not supported", path,
                            airEnumStr(nrrdType, nrrd->type));
    if (st == CDVR_OK)
        st = nrrd_shape(path, nrrd, head->dims, &head->timesteps, err);
    if (st == CDVR_OK)
        st = nrrd_geometry(path, nrrd, cdvr_nrrd_io(src), head, err);
    if (st == CDVR_OK) {
        cdvr_volume_set_source_type(head, nrrd_file_type(nrrd->type));
        if (head->type == CDVR_TYPE_U8) { /* codes are values unless old min/max say */
            head->window[0] = 0;
            head->window[1] = 255;
            cdvr_u8_window_set(head, nrrd->oldMin, nrrd->oldMax);
        }
    }
    cdvr_nrrd_close(src);
    return st;
}

cdvr_status cdvr_volume_probe_nrrd(const char *path, cdvr_volume *head, cdvr_error *err)
{
    return probe_nrrd(path, NULL, head, err);
}

/* ---- format table (cdvr/format.h) ----------------------------------------------------------- */

/* "NRRD000" and the version digit (NRRD0001 .. NRRD0005), as teem writes it. */
static int nrrd_magic(const uint8_t *head, size_t n)
{
    return n >= 8 && memcmp(head, "NRRD000", 7) == 0 && head[7] >= '1' && head[7] <= '9';
}

static cdvr_status nrrd_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                              cdvr_error *err)
{
    return probe_nrrd(path, opts, head, err);
}

static cdvr_status nrrd_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                             cdvr_error *err)
{
    return load_nrrd(path, opts, out, err);
}

static const char *const nrrd_suffixes[] = {".nrrd", ".nhdr", NULL};

const cdvr_format cdvr_format_nrrd = {
    .name = "nrrd",
    .description = "NRRD through teem: attached or detached data, raw, ascii, gzip or bzip2; "
                   "3D, or 4D (time)",
    .suffixes = nrrd_suffixes,
    .magic = nrrd_magic,
    .probe = nrrd_probe,
    .load = nrrd_load,
};
