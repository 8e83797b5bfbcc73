/* tests/test_volume.c - core/io/volume.c (create, get, range, slice_time, types) and
 * core/io/generate.c (box, sphere, Marschner-Lobb, ramp). */
#include "check.h"
#include "cdvr/volume.h"

#include <stdint.h>
#include <string.h>

static void test_types(void)
{
    CHECK(cdvr_type_size(CDVR_TYPE_U8) == 1 && cdvr_type_size(CDVR_TYPE_U16) == 2 &&
              cdvr_type_size(CDVR_TYPE_I16) == 2 && cdvr_type_size(CDVR_TYPE_F32) == 4,
          "type sizes");
    cdvr_type t;
    CHECK(cdvr_type_parse("float", &t) && t == CDVR_TYPE_F32, "parse float");
    CHECK(cdvr_type_parse("short", &t) && t == CDVR_TYPE_I16, "parse short");
    CHECK(cdvr_type_parse("u16", &t) && t == CDVR_TYPE_U16, "parse u16");
    CHECK(!cdvr_type_parse("f64", &t), "f64 is not a volume type");
    CHECK(strcmp(cdvr_type_name(CDVR_TYPE_I16), "i16") == 0, "name i16");
}

static void test_create(void)
{
    cdvr_volume *v;
    cdvr_error err;
    size_t dims[3] = {5, 3, 7};
    CHECK_OK(cdvr_volume_create(dims, 2, CDVR_TYPE_U16, &v, &err), err);
    CHECK(cdvr_volume_voxels(v) == 105 && cdvr_volume_frame_bytes(v) == 210, "sizes");
    CHECK(v->spacing[0] == 1 && v->spacing[2] == 1 && v->origin[1] == 0, "default geometry");
    uint16_t *d = v->data;
    int zero = 1;
    for (size_t i = 0; i < 210; i++)
        zero &= d[i] == 0;
    CHECK(zero, "zero filled");
    d[4 + 5 * (2 + 3 * (6 + 7 * 1))] = 4242;
    CHECK(cdvr_volume_get(v, 4, 2, 6, 1) == 4242, "get uses x + X*(y + Y*(z + Z*t))");
    CHECK(cdvr_volume_frame(v, 1) == (char *)v->data + 210 && cdvr_volume_frame(v, 2) == NULL, "frame pointer");
    cdvr_volume_free(v);

    size_t zero_dims[3] = {4, 0, 4};
    CHECK(cdvr_volume_create(zero_dims, 1, CDVR_TYPE_U8, &v, &err) == CDVR_ERR_ARG && !v, "zero dim");
    CHECK(cdvr_volume_create(dims, 0, CDVR_TYPE_U8, &v, &err) == CDVR_ERR_ARG, "zero timesteps");
    size_t huge[3] = {SIZE_MAX / 2, 4, 1};
    CHECK(cdvr_volume_create(huge, 1, CDVR_TYPE_U8, &v, &err) == CDVR_ERR_NOMEM && strstr(err.msg, "overflow"),
          "overflow: %s", err.msg);
}

static void test_range_and_slice(void)
{
    cdvr_volume *v, *s;
    cdvr_error err;
    size_t dims[3] = {2, 2, 1};
    CHECK_OK(cdvr_volume_create(dims, 3, CDVR_TYPE_F32, &v, &err), err);
    float *f = v->data;
    for (int i = 0; i < 12; i++)
        f[i] = (float)i - 3.0f;
    f[0] = NAN;
    f[11] = INFINITY;
    f[5] = -INFINITY;
    double lo, hi;
    cdvr_volume_range(v, &lo, &hi);
    CHECK(lo == -2 && hi == 7, "range ignores NaN and Inf: %g %g", lo, hi);
    v->spacing[1] = 2.5;
    v->origin[2] = -4;
    CHECK_OK(cdvr_volume_slice_time(v, 1, 2, &s, &err), err);
    CHECK(s->timesteps == 2 && cdvr_volume_get(s, 0, 0, 0, 0) == 1 && cdvr_volume_get(s, 0, 1, 0, 1) == 7,
          "slice_time copies frames 2..3");
    CHECK(s->spacing[1] == 2.5 && s->origin[2] == -4, "slice keeps geometry");
    cdvr_volume_free(s);
    CHECK(cdvr_volume_slice_time(v, 2, 2, &s, &err) == CDVR_ERR_ARG && !s, "slice past the end");
    for (int i = 0; i < 12; i++)
        f[i] = NAN;
    cdvr_volume_range(v, &lo, &hi);
    CHECK(lo == 0 && hi == 0, "all NaN range is 0, 0");
    cdvr_volume_free(v);
}

static cdvr_volume *generate(const char *name, cdvr_generate_opts *o)
{
    cdvr_volume *v = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_generate(name, o, &v, &err), err);
    return v;
}

static void test_generate_box_ramp(void)
{
    cdvr_generate_opts o = {{3, 4, 5}, 2, CDVR_TYPE_U8, 77, 0, 0, 0};
    cdvr_volume *v = generate("box", &o);
    double lo, hi;
    cdvr_volume_range(v, &lo, &hi);
    CHECK(v->timesteps == 2 && lo == 77 && hi == 77, "box constant 77: %g %g", lo, hi);
    cdvr_volume_free(v);

    v = generate("box", NULL);
    CHECK(v->dims[0] == 64 && v->dims[2] == 64 && cdvr_volume_get(v, 10, 20, 30, 0) == 128, "box defaults");
    cdvr_volume_free(v);

    cdvr_generate_opts r = {{18, 2, 1}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
    v = generate("ramp", &r);
    CHECK(cdvr_volume_get(v, 0, 1, 0, 0) == 0 && cdvr_volume_get(v, 17, 0, 0, 0) == 255 &&
              cdvr_volume_get(v, 1, 0, 0, 0) == 15 && cdvr_volume_get(v, 9, 1, 0, 0) == 135,
          "ramp = round(255 x / (X-1))");
    cdvr_volume_free(v);
    r.dims[0] = 1;
    v = generate("ramp", &r);
    CHECK(cdvr_volume_get(v, 0, 0, 0, 0) == 0, "ramp of one voxel");
    cdvr_volume_free(v);

    cdvr_volume *bad;
    cdvr_error err;
    CHECK(cdvr_volume_generate("torus", NULL, &bad, &err) == CDVR_ERR_ARG && strstr(err.msg, "torus"),
          "unknown field: %s", err.msg);
}

static void test_generate_sphere(void)
{
    cdvr_generate_opts o = {{21, 21, 21}, 1, CDVR_TYPE_U8, 0, 0.5, 0, 0};
    cdvr_volume *v = generate("sphere", &o);
    CHECK(cdvr_volume_get(v, 10, 10, 10, 0) == 255, "centre inside, default value 255");
    CHECK(cdvr_volume_get(v, 15, 10, 10, 0) == 255 && cdvr_volume_get(v, 16, 10, 10, 0) == 0,
          "radius 0.5 of half extent 10 = 5 voxels");
    CHECK(cdvr_volume_get(v, 0, 0, 0, 0) == 0, "corner outside");
    cdvr_volume_free(v);

    cdvr_generate_opts m = {{21, 21, 21}, 3, CDVR_TYPE_F32, 2.5, 0.2, 0, 0};
    v = generate("sphere", &m);
    /* centre x = 20 * (0.25 + 0.5 t / 2): 5, 10, 15 */
    CHECK(cdvr_volume_get(v, 5, 10, 10, 0) == 2.5f && cdvr_volume_get(v, 15, 10, 10, 0) == 0, "t=1 centre x=5");
    CHECK(cdvr_volume_get(v, 10, 10, 10, 1) == 2.5f && cdvr_volume_get(v, 5, 10, 10, 1) == 0, "t=2 centre x=10");
    CHECK(cdvr_volume_get(v, 15, 10, 10, 2) == 2.5f && cdvr_volume_get(v, 10, 10, 10, 2) == 0, "t=3 centre x=15");
    cdvr_volume_free(v);
}

static double ml_reference(double x, double y, double z)
{
    const double pi = 3.14159265358979323846, fM = 6, alpha = 0.25;
    double r = sqrt(x * x + y * y);
    double rho_r = cos(2 * pi * fM * cos(pi * r / 2));
    return (1 - sin(pi * z / 2) + alpha * (1 + rho_r)) / (2 * (1 + alpha));
}

static void test_generate_ml(void)
{
    cdvr_generate_opts o = {{41, 41, 41}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
    cdvr_volume *v = generate("ml", &o);
    CHECK(cdvr_volume_get(v, 20, 20, 20, 0) == 153, "centre: rho = 0.6 -> 153, got %g",
          cdvr_volume_get(v, 20, 20, 20, 0));
    CHECK(cdvr_volume_get(v, 20, 20, 40, 0) == 51, "top centre: rho = 0.2 -> 51");
    CHECK(cdvr_volume_get(v, 20, 20, 0, 0) == 255, "bottom centre: rho = 1 -> 255");
    int max_diff = 0;
    for (size_t z = 0; z < 41; z += 3)
        for (size_t y = 0; y < 41; y += 5)
            for (size_t x = 0; x < 41; x += 7) {
                double ref = 255 * ml_reference(-1 + x / 20.0, -1 + y / 20.0, -1 + z / 20.0);
                double diff = fabs(cdvr_volume_get(v, x, y, z, 0) - floor(ref + 0.5));
                if (diff > max_diff)
                    max_diff = (int)diff;
            }
    CHECK(max_diff == 0, "u8 ML = round(255 rho) everywhere (max diff %d)", max_diff);
    cdvr_volume_free(v);

    o.type = CDVR_TYPE_F32;
    v = generate("ml", &o);
    CHECK(fabs(cdvr_volume_get(v, 20, 20, 20, 0) - 0.6) < 1e-6, "f32 ML is rho itself");
    CHECK(fabs(cdvr_volume_get(v, 3, 7, 11, 0) - ml_reference(-1 + 3 / 20.0, -1 + 7 / 20.0, -1 + 11 / 20.0)) < 1e-6,
          "f32 ML at (3,7,11)");
    cdvr_volume_free(v);
}

int main(void)
{
    test_types();
    test_create();
    test_range_and_slice();
    test_generate_box_ramp();
    test_generate_sphere();
    test_generate_ml();
    return check_finish();
}
