/* core/io/volume.c - cdvr_volume allocation, access and type helpers. */
#include "cdvr/volume.h"
#include "cdvr/memory.h"
#include "cdvr/regular_file.h"
#include "volume_io.h"

#include <errno.h>
#include <float.h>
#include <stdio.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

size_t cdvr_type_size(cdvr_type type)
{
    switch (type) {
    case CDVR_TYPE_U8: return 1;
    case CDVR_TYPE_U16:
    case CDVR_TYPE_I16: return 2;
    case CDVR_TYPE_F32: return 4;
    }
    return 0;
}

const char *cdvr_type_name(cdvr_type type)
{
    switch (type) {
    case CDVR_TYPE_U8: return "u8";
    case CDVR_TYPE_U16: return "u16";
    case CDVR_TYPE_I16: return "i16";
    case CDVR_TYPE_F32: return "f32";
    }
    return "unknown";
}

int cdvr_type_parse(const char *name, cdvr_type *type)
{
    static const struct { const char *name; cdvr_type type; } names[] = {
        {"u8", CDVR_TYPE_U8},   {"uint8", CDVR_TYPE_U8},    {"uchar", CDVR_TYPE_U8},
        {"u16", CDVR_TYPE_U16}, {"uint16", CDVR_TYPE_U16},  {"ushort", CDVR_TYPE_U16},
        {"i16", CDVR_TYPE_I16}, {"int16", CDVR_TYPE_I16},   {"short", CDVR_TYPE_I16},
        {"f32", CDVR_TYPE_F32}, {"float32", CDVR_TYPE_F32}, {"float", CDVR_TYPE_F32},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        if (strcmp(name, names[i].name) == 0) {
            *type = names[i].type;
            return 1;
        }
    }
    return 0;
}

cdvr_status cdvr_volume_create(const size_t dims[3], size_t timesteps, cdvr_type type,
                               cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    if (dims[0] == 0 || dims[1] == 0 || dims[2] == 0 || timesteps == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "volume %zux%zux%zu with %zu timesteps: dims and timesteps must be positive",
                              dims[0], dims[1], dims[2], timesteps);
    size_t bytes = cdvr_type_size(type);
    if (bytes == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "volume: unknown voxel type %d", (int)type);
    if (!cdvr_size_mul(bytes, dims[0], &bytes) || !cdvr_size_mul(bytes, dims[1], &bytes) ||
        !cdvr_size_mul(bytes, dims[2], &bytes) || !cdvr_size_mul(bytes, timesteps, &bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "volume %zux%zux%zu x %zu timesteps of %s: size overflows",
                              dims[0], dims[1], dims[2], timesteps, cdvr_type_name(type));
    cdvr_volume *vol = calloc(1, sizeof *vol);
    void *data = vol ? cdvr_alloc_large(bytes, 1) : NULL; /* huge pages: cdvr/memory.h */
    if (!data) {
        free(vol);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "volume %zux%zux%zu x %zu timesteps: cannot allocate %zu bytes",
                              dims[0], dims[1], dims[2], timesteps, bytes);
    }
    memcpy(vol->dims, dims, sizeof vol->dims);
    vol->timesteps = timesteps;
    vol->type = type;
    vol->spacing[0] = vol->spacing[1] = vol->spacing[2] = 1.0;
    vol->direction[0] = vol->direction[4] = vol->direction[8] = 1.0;
    vol->window[0] = type == CDVR_TYPE_U8 ? 0.0 : NAN;
    vol->window[1] = type == CDVR_TYPE_U8 ? 255.0 : NAN;
    vol->data = data;
    *out = vol;
    return CDVR_OK;
}

const char *cdvr_type_file_name(cdvr_type type)
{
    static const char *const names[] = {"uint8", "uint16", "int16", "float32"};
    return (unsigned)type < 4 ? names[type] : "?";
}

int cdvr_volume_converted(const cdvr_volume *vol)
{
    return vol->source_type[0] && strncmp(vol->source_type, cdvr_type_file_name(vol->type),
                                          sizeof vol->source_type) != 0;
}

void cdvr_volume_set_space(cdvr_volume *vol, const char *space)
{
    memset(vol->space, 0, sizeof vol->space);
    if (space && (!strcmp(space, "RAS") || !strcmp(space, "LAS") || !strcmp(space, "LPS")))
        memcpy(vol->space, space, 3);
}

void cdvr_volume_set_source_type(cdvr_volume *vol, const char *name)
{
    memset(vol->source_type, 0, sizeof vol->source_type);
    if (name)
        strncpy(vol->source_type, name, sizeof vol->source_type - 1);
}

void cdvr_volume_free(cdvr_volume *vol)
{
    if (vol) {
        free(vol->data);
        free(vol);
    }
}

void cdvr_volume_touch(cdvr_volume *vol)
{
    vol->revision++;
}

cdvr_frame_stamp cdvr_volume_stamp(const cdvr_volume *vol, size_t t)
{
    cdvr_frame_stamp stamp = {vol, cdvr_volume_frame(vol, t), vol->revision};
    return stamp;
}

int cdvr_frame_stamp_same(cdvr_frame_stamp a, cdvr_frame_stamp b)
{
    return a.vol && a.vol == b.vol && a.voxels == b.voxels && a.revision == b.revision;
}

size_t cdvr_volume_voxels(const cdvr_volume *vol)
{
    return vol->dims[0] * vol->dims[1] * vol->dims[2];
}

size_t cdvr_volume_frame_bytes(const cdvr_volume *vol)
{
    return cdvr_volume_voxels(vol) * cdvr_type_size(vol->type);
}

void *cdvr_volume_frame(const cdvr_volume *vol, size_t t)
{
    if (t >= vol->timesteps)
        return NULL;
    return (unsigned char *)vol->data + t * cdvr_volume_frame_bytes(vol);
}

static double value_at(const cdvr_volume *vol, size_t i)
{
    switch (vol->type) {
    case CDVR_TYPE_U8: return ((const uint8_t *)vol->data)[i];
    case CDVR_TYPE_U16: return ((const uint16_t *)vol->data)[i];
    case CDVR_TYPE_I16: return ((const int16_t *)vol->data)[i];
    case CDVR_TYPE_F32: return ((const float *)vol->data)[i];
    }
    return 0.0;
}

double cdvr_volume_get(const cdvr_volume *vol, size_t x, size_t y, size_t z, size_t t)
{
    size_t i = x + vol->dims[0] * (y + vol->dims[1] * (z + vol->dims[2] * t));
    return value_at(vol, i);
}

void cdvr_volume_range(const cdvr_volume *vol, double *lo, double *hi)
{
    size_t n = cdvr_volume_voxels(vol) * vol->timesteps;
    double mn = HUGE_VAL, mx = -HUGE_VAL;
    for (size_t i = 0; i < n; i++) {
        double v = value_at(vol, i);
        if (!isfinite(v))
            continue;
        if (v < mn)
            mn = v;
        if (v > mx)
            mx = v;
    }
    if (mn > mx)
        mn = mx = 0.0;
    *lo = mn;
    *hi = mx;
}

void cdvr_volume_window_peek(const cdvr_volume *vol, double w[2])
{
    if (vol->type == CDVR_TYPE_U8 || (!isnan(vol->window[0]) && !isnan(vol->window[1]))) {
        w[0] = vol->window[0];
        w[1] = vol->window[1];
        return;
    }
    cdvr_volume_range(vol, &w[0], &w[1]);
}

void cdvr_volume_window(cdvr_volume *vol, double w[2])
{
    cdvr_volume_window_peek(vol, w);
    vol->window[0] = w[0];
    vol->window[1] = w[1];
}

/* ---- geometry ---------------------------------------------------------------------------- */

void cdvr_volume_direction(const cdvr_volume *vol, double D[9])
{
    int zero = 1;
    for (int i = 0; i < 9; i++)
        zero &= vol->direction[i] == 0.0;
    for (int i = 0; i < 9; i++)
        D[i] = zero ? (i % 4 == 0 ? 1.0 : 0.0) : vol->direction[i];
}

void cdvr_volume_index_to_world(const cdvr_volume *vol, const double ijk[3], double world[3])
{
    double D[9];
    cdvr_volume_direction(vol, D);
    for (int r = 0; r < 3; r++) {
        world[r] = vol->origin[r];
        for (int c = 0; c < 3; c++)
            world[r] += D[3 * r + c] * ijk[c] * vol->spacing[c];
    }
}

int cdvr_mat3_inverse(const double m[9], double inv[9])
{
    double cof[9];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            int r1 = (r + 1) % 3, r2 = (r + 2) % 3, c1 = (c + 1) % 3, c2 = (c + 2) % 3;
            cof[3 * r + c] = m[3 * r1 + c1] * m[3 * r2 + c2] - m[3 * r1 + c2] * m[3 * r2 + c1];
        }
    double det = m[0] * cof[0] + m[1] * cof[1] + m[2] * cof[2];
    double scale = 1.0;
    for (int c = 0; c < 3; c++)
        scale *= sqrt(m[c] * m[c] + m[3 + c] * m[3 + c] + m[6 + c] * m[6 + c]);
    if (!isfinite(det) || !isfinite(scale) || !(fabs(det) > 1e-12 * scale))
        return 0;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            inv[3 * r + c] = cof[3 * c + r] / det; /* adjugate = transposed cofactors */
    return 1;
}

void cdvr_volume_bounds(const cdvr_volume *vol, double lo[3], double hi[3])
{
    for (int a = 0; a < 3; a++) {
        lo[a] = HUGE_VAL;
        hi[a] = -HUGE_VAL;
    }
    for (int corner = 0; corner < 8; corner++) {
        double ijk[3], world[3];
        for (int a = 0; a < 3; a++)
            ijk[a] = (corner >> a & 1) ? (double)(vol->dims[a] - 1) : 0.0;
        cdvr_volume_index_to_world(vol, ijk, world);
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], world[a]);
            hi[a] = fmax(hi[a], world[a]);
        }
    }
}

cdvr_status cdvr_volume_check_geometry(const cdvr_volume *vol, const char *what, cdvr_error *err)
{
    for (int a = 0; a < 3; a++)
        if (!isfinite(vol->spacing[a]) || vol->spacing[a] <= 0.0 || !isfinite(vol->origin[a]))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "%s: volume spacing %g and origin %g (axis %d) must be finite, "
                                  "spacing positive",
                                  what, vol->spacing[a], vol->origin[a], a);
    double D[9], inv[9];
    cdvr_volume_direction(vol, D);
    if (!cdvr_mat3_inverse(D, inv))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "%s: volume direction matrix [%g %g %g; %g %g %g; %g %g %g] is "
                              "singular or not finite",
                              what, D[0], D[1], D[2], D[3], D[4], D[5], D[6], D[7], D[8]);
    return CDVR_OK;
}

cdvr_status cdvr_volume_slice_time(const cdvr_volume *vol, size_t t0, size_t count,
                                   cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    if (count == 0 || t0 >= vol->timesteps || count > vol->timesteps - t0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "volume: timesteps %zu..%zu out of range 1..%zu",
                              t0 + 1, t0 + count, vol->timesteps);
    cdvr_status st = cdvr_volume_create(vol->dims, count, vol->type, out, err);
    if (st != CDVR_OK)
        return st;
    memcpy((*out)->spacing, vol->spacing, sizeof vol->spacing);
    memcpy((*out)->origin, vol->origin, sizeof vol->origin);
    memcpy((*out)->direction, vol->direction, sizeof vol->direction);
    memcpy((*out)->source_type, vol->source_type, sizeof vol->source_type);
    (*out)->beyond_f32 = vol->beyond_f32;
    memcpy((*out)->space, vol->space, sizeof vol->space);
    cdvr_volume_window_peek(vol, (*out)->window);
    memcpy((*out)->data, cdvr_volume_frame(vol, t0), count * cdvr_volume_frame_bytes(vol));
    return CDVR_OK;
}

/* ---- helpers for the loaders (core/io/volume_io.h) ------------------------------------------- */

int cdvr_volume_bytes_for(const size_t dims[3], size_t timesteps, cdvr_type type, size_t *bytes)
{
    size_t n = cdvr_type_size(type);
    return cdvr_size_mul(n, dims[0], &n) && cdvr_size_mul(n, dims[1], &n) &&
           cdvr_size_mul(n, dims[2], &n) && cdvr_size_mul(n, timesteps, bytes);
}

void cdvr_swap_bytes(void *data, size_t count, size_t elem_size)
{
    unsigned char *p = data;
    for (size_t i = 0; i < count; i++, p += elem_size) {
        for (size_t a = 0, b = elem_size - 1; a < b; a++, b--) {
            unsigned char tmp = p[a];
            p[a] = p[b];
            p[b] = tmp;
        }
    }
}

int cdvr_host_is_little_endian(void)
{
    const uint16_t probe = 1;
    unsigned char first;
    memcpy(&first, &probe, 1);
    return first == 1;
}

float cdvr_double_to_f32(double v)
{
    /* a double outside float's range has no defined conversion in C; saturate to +-Inf */
    if (v > FLT_MAX)
        return INFINITY;
    if (v < -FLT_MAX)
        return -INFINITY;
    return (float)v;
}

void cdvr_u8_window_set(cdvr_volume *vol, double lo, double hi)
{
    if (vol->type == CDVR_TYPE_U8 && isfinite(lo) && isfinite(hi) && lo < hi) {
        vol->window[0] = lo;
        vol->window[1] = hi;
    }
}

int cdvr_u8_window_get(const cdvr_volume *vol, double w[2])
{
    if (vol->type != CDVR_TYPE_U8 || !(vol->window[0] < vol->window[1]) ||
        (vol->window[0] == 0 && vol->window[1] == 255))
        return 0;
    w[0] = vol->window[0];
    w[1] = vol->window[1];
    return 1;
}

void cdvr_f32_guard_init(cdvr_f32_guard *g, const cdvr_raw_opts *opts)
{
    memset(g, 0, sizeof *g);
    g->accept_inf = opts && opts->f32_overflow_inf;
}

cdvr_status cdvr_f32_guard_finish(const cdvr_f32_guard *g, const char *file, const char *what,
                                  const char *source_type, cdvr_volume *vol, cdvr_error *err)
{
    if (!g->beyond || g->accept_inf) {
        vol->beyond_f32 = g->beyond;
        return CDVR_OK;
    }
    size_t plane = vol->dims[0] * vol->dims[1], frame = plane * vol->dims[2];
    uint64_t at = g->first_at, in = frame ? at % frame : 0;
    return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s value %g (%s, voxel (%llu,%llu,%llu) of "
                          "timestep %llu from 0) is beyond the range of f32, the type cdvr loads "
                          "%s as (%llu such value%s); load with f32_overflow = \"inf\" to accept "
                          "them as +-Inf", file, what, g->first, source_type,
                          (unsigned long long)(vol->dims[0] ? in % vol->dims[0] : 0),
                          (unsigned long long)(vol->dims[0] ? in / vol->dims[0] % vol->dims[1] : 0),
                          (unsigned long long)(plane ? in / plane : 0),
                          (unsigned long long)(frame ? at / frame : 0), source_type,
                          (unsigned long long)g->beyond, g->beyond == 1 ? "" : "s");
}

void cdvr_convert_to_f32(float *dst, const void *src, size_t count, cdvr_value_reader read)
{
    for (size_t i = 0; i < count; i++)
        dst[i] = cdvr_double_to_f32(read(src, i));
}

cdvr_status cdvr_check_readable(const char *path, cdvr_error *err)
{
    int fd;
    cdvr_status st = cdvr_open_regular_file(path, &fd, NULL, err);
    if (st == CDVR_OK)
        close(fd);
    return st;
}
