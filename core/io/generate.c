/* core/io/generate.c - synthetic test fields: box, sphere, Marschner-Lobb, ramp. */
#include "cdvr/volume.h"

#include <math.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct field {
    const cdvr_generate_opts *opts;
    size_t dims[3], timesteps;
} field;

/* Voxel index i of n mapped to [-1, 1] (0 for a single voxel). */
static double unit_coord(size_t i, size_t n)
{
    return n > 1 ? -1.0 + 2.0 * (double)i / (double)(n - 1) : 0.0;
}

/* Marschner-Lobb rho(x,y,z) in [0,1]. */
static double marschner_lobb(double x, double y, double z, double fM, double alpha)
{
    double r = sqrt(x * x + y * y);
    double rho_r = cos(2.0 * M_PI * fM * cos(M_PI * r / 2.0));
    return (1.0 - sin(M_PI * z / 2.0) + alpha * (1.0 + rho_r)) / (2.0 * (1.0 + alpha));
}

/* The sphere's centre moves along x from 1/4 to 3/4 of the extent over the timesteps. */
static int inside_sphere(const field *f, size_t x, size_t y, size_t z, size_t t)
{
    double half[3], c[3], p[3] = {(double)x, (double)y, (double)z};
    double min_half = HUGE_VAL;
    for (int i = 0; i < 3; i++) {
        half[i] = (double)(f->dims[i] - 1) / 2.0;
        c[i] = half[i];
        if (half[i] < min_half)
            min_half = half[i];
    }
    if (f->timesteps > 1)
        c[0] = (double)(f->dims[0] - 1) * (0.25 + 0.5 * (double)t / (double)(f->timesteps - 1));
    double radius = f->opts->radius * min_half, d2 = 0.0;
    for (int i = 0; i < 3; i++)
        d2 += (p[i] - c[i]) * (p[i] - c[i]);
    return d2 <= radius * radius;
}

typedef enum { FIELD_BOX, FIELD_SPHERE, FIELD_ML, FIELD_RAMP } field_kind;

/* Value of the field; *scaled is set when it is on a 0..1 scale that u8 maps to 0..255. */
static double field_value(const field *f, field_kind kind, size_t x, size_t y, size_t z, size_t t,
                          int *scaled)
{
    *scaled = 0;
    switch (kind) {
    case FIELD_BOX: return f->opts->value;
    case FIELD_SPHERE: return inside_sphere(f, x, y, z, t) ? f->opts->value : 0.0;
    case FIELD_ML:
        *scaled = 1;
        return marschner_lobb(unit_coord(x, f->dims[0]), unit_coord(y, f->dims[1]),
                              unit_coord(z, f->dims[2]), f->opts->fM, f->opts->alpha);
    case FIELD_RAMP: return f->dims[0] > 1 ? 255.0 * (double)x / (double)(f->dims[0] - 1) : 0.0;
    }
    return 0.0;
}

/* Stores v: f32 as is; integer types round half up and clamp to the type's range. */
static void store_value(cdvr_volume *vol, size_t i, double v)
{
    static const double type_max[] = {255.0, 65535.0, 32767.0};
    static const double type_min[] = {0.0, 0.0, -32768.0};
    if (vol->type == CDVR_TYPE_F32) {
        ((float *)vol->data)[i] = (float)v;
        return;
    }
    double q = floor(v + 0.5);
    q = q > type_max[vol->type] ? type_max[vol->type] : q < type_min[vol->type] ? type_min[vol->type] : q;
    if (vol->type == CDVR_TYPE_U8)
        ((uint8_t *)vol->data)[i] = (uint8_t)q;
    else if (vol->type == CDVR_TYPE_U16)
        ((uint16_t *)vol->data)[i] = (uint16_t)q;
    else
        ((int16_t *)vol->data)[i] = (int16_t)q;
}

static void fill(cdvr_volume *vol, const field *f, field_kind kind)
{
    size_t i = 0;
    for (size_t t = 0; t < f->timesteps; t++)
        for (size_t z = 0; z < f->dims[2]; z++)
            for (size_t y = 0; y < f->dims[1]; y++)
                for (size_t x = 0; x < f->dims[0]; x++, i++) {
                    int scaled;
                    double v = field_value(f, kind, x, y, z, t, &scaled);
                    if (scaled && vol->type != CDVR_TYPE_F32)
                        v *= 255.0;
                    store_value(vol, i, v);
                }
}

static int parse_kind(const char *name, field_kind *kind)
{
    static const char *const names[] = {"box", "sphere", "ml", "ramp"};
    for (int i = 0; i < 4; i++)
        if (strcmp(name, names[i]) == 0) {
            *kind = (field_kind)i;
            return 1;
        }
    return 0;
}

/* Copies opts with the documented defaults filled in (dims 64, value 128 / 255, ...). */
static cdvr_generate_opts with_defaults(const cdvr_generate_opts *in, field_kind kind)
{
    cdvr_generate_opts o;
    memset(&o, 0, sizeof o);
    if (in)
        o = *in;
    for (int i = 0; i < 3; i++)
        if (o.dims[i] == 0)
            o.dims[i] = 64;
    if (o.timesteps == 0)
        o.timesteps = 1;
    if (o.value == 0.0 && (!in || in->value == 0.0))
        o.value = kind == FIELD_SPHERE ? 255.0 : 128.0;
    if (o.radius <= 0.0)
        o.radius = 0.8;
    if (o.fM == 0.0)
        o.fM = 6.0;
    if (o.alpha == 0.0)
        o.alpha = 0.25;
    return o;
}

cdvr_status cdvr_volume_generate(const char *name, const cdvr_generate_opts *opts,
                                 cdvr_volume **out, cdvr_error *err)
{
    *out = NULL;
    field_kind kind;
    if (!parse_kind(name, &kind))
        return cdvr_error_set(err, CDVR_ERR_ARG, "generate: unknown field '%s' (box, sphere, ml, ramp)",
                              name);
    cdvr_generate_opts o = with_defaults(opts, kind);
    if (!isfinite(o.value) || !isfinite(o.radius) || !isfinite(o.fM) || !isfinite(o.alpha) ||
        o.alpha <= -1.0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "generate %s: parameters must be finite (alpha > -1)",
                              name);
    cdvr_status st = cdvr_volume_create(o.dims, o.timesteps, o.type, out, err);
    if (st != CDVR_OK)
        return st;
    field f = {&o, {o.dims[0], o.dims[1], o.dims[2]}, o.timesteps};
    fill(*out, &f, kind);
    return CDVR_OK;
}
