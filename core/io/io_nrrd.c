/* core/io/io_nrrd.c - NRRD (.nrrd, .nhdr with detached data) through teem. */
#include "cdvr/volume.h"
#include "volume_io.h"
#include "cdvr/format.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <teem/nrrd.h>

static double read_i8(const void *p, size_t i) { return ((const signed char *)p)[i]; }
static double read_i32(const void *p, size_t i) { return ((const int32_t *)p)[i]; }
static double read_u32(const void *p, size_t i) { return ((const uint32_t *)p)[i]; }
static double read_i64(const void *p, size_t i) { return (double)((const int64_t *)p)[i]; }
static double read_u64(const void *p, size_t i) { return (double)((const uint64_t *)p)[i]; }
static double read_f64(const void *p, size_t i) { return ((const double *)p)[i]; }

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
 * without a direction keep the identity column; missing or non-finite values keep the
 * defaults (spacing 1, origin 0). A singular set of directions is an error. */
static cdvr_status nrrd_geometry(const char *path, const Nrrd *nrrd, cdvr_volume *vol,
                                 cdvr_error *err)
{
    unsigned n = nrrd->dim < 3 ? nrrd->dim : 3;
    int has_dir[3] = {0, 0, 0};
    double cols[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (unsigned ax = 0; ax < n; ax++) {
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
    for (unsigned i = 0; i < nrrd->spaceDim && i < 3; i++)
        if (isfinite(nrrd->spaceOrigin[i]))
            vol->origin[i] = nrrd->spaceOrigin[i];
    return CDVR_OK;
}

static cdvr_status nrrd_to_volume(const char *path, const Nrrd *nrrd, cdvr_volume **out,
                                  cdvr_error *err)
{
    cdvr_type type;
    cdvr_value_reader reader;
    if (!map_type(nrrd->type, &type, &reader))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD type '%s' is not supported", path,
                              airEnumStr(nrrdType, nrrd->type));
    size_t dims[3] = {0, 0, 0}, timesteps = 0;
    cdvr_status st = nrrd_shape(path, nrrd, dims, &timesteps, err);
    if (st == CDVR_OK)
        st = cdvr_volume_create(dims, timesteps, type, out, err);
    if (st != CDVR_OK)
        return st;
    size_t count = cdvr_volume_voxels(*out) * timesteps;
    if (reader)
        cdvr_convert_to_f32((*out)->data, nrrd->data, count, reader);
    else
        memcpy((*out)->data, nrrd->data, count * cdvr_type_size(type));
    st = nrrd_geometry(path, nrrd, *out, err);
    if (st != CDVR_OK) {
        cdvr_volume_free(*out);
        *out = NULL;
    }
    return st;
}

cdvr_status cdvr_volume_load_nrrd(const char *path, cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    cdvr_status st = cdvr_nrrd_check(path, err);
    if (st != CDVR_OK)
        return st;
    Nrrd *nrrd = nrrdNew();
    if (!nrrd)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (nrrdLoad(nrrd, path, NULL)) {
        char *msg = biffGetDone(NRRD);
        if (msg)
            cdvr_teem_reason(msg);
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: cannot read NRRD: %s", path,
                            msg && *msg ? msg : "unknown teem error");
        free(msg);
        nrrdNuke(nrrd);
        return st;
    }
    st = nrrd_to_volume(path, nrrd, out, err);
    nrrdNuke(nrrd);
    return st;
}

cdvr_status cdvr_volume_probe_nrrd(const char *path, cdvr_volume *head, cdvr_error *err)
{
    cdvr_status st = cdvr_nrrd_check_header(path, err); /* the load's header limit too */
    if (st != CDVR_OK)
        return st;
    Nrrd *nrrd = nrrdNew();
    NrrdIoState *nio = nrrdIoStateNew();
    if (!nrrd || !nio) {
        if (nrrd)
            nrrdNix(nrrd);
        if (nio)
            nrrdIoStateNix(nio);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    nrrdIoStateSet(nio, nrrdIoStateSkipData, AIR_TRUE);
    if (nrrdLoad(nrrd, path, nio)) {
        char *msg = biffGetDone(NRRD);
        if (msg)
            cdvr_teem_reason(msg);
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: cannot read NRRD header: %s", path,
                            msg && *msg ? msg : "unknown teem error");
        free(msg);
    }
    cdvr_value_reader reader;
    if (st == CDVR_OK && !map_type(nrrd->type, &head->type, &reader))
        st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: NRRD type '%s' is not supported", path,
                            airEnumStr(nrrdType, nrrd->type));
    if (st == CDVR_OK)
        st = nrrd_shape(path, nrrd, head->dims, &head->timesteps, err);
    if (st == CDVR_OK)
        st = nrrd_geometry(path, nrrd, head, err);
    nrrdIoStateNix(nio);
    nrrdNuke(nrrd);
    return st;
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
    (void)opts;
    return cdvr_volume_probe_nrrd(path, head, err);
}

static cdvr_status nrrd_load(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                             cdvr_error *err)
{
    (void)opts;
    return cdvr_volume_load_nrrd(path, out, err);
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
