/* tests/test_render.c - the CPU reference ray caster against the analytic constant-density
 * box of DESIGN.md section 6, hard cases of section 9, symmetry, thread invariance and a
 * real CT volume written as PNG. */
#include "check.h"
#include "cdvr/render.h"
#include "cdvr/skip.h"
#include "render/cpu/brick_range.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static cdvr_volume *make_volume(size_t x, size_t y, size_t z)
{
    size_t dims[3] = {x, y, z};
    cdvr_volume *v = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err), err);
    return v;
}

static cdvr_volume *constant_volume(size_t n, uint8_t value)
{
    cdvr_volume *v = make_volume(n, n, n);
    if (v)
        memset(v->data, value, cdvr_volume_voxels(v));
    return v;
}

static void constant_tf(cdvr_tf *tf, double alpha, double unit)
{
    cdvr_tf_point p = {100, 1, 1, 1, alpha};
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(tf, &p, 1, unit, &err), err);
}

static cdvr_camera camera(const double eye[3], const double center[3], int size)
{
    cdvr_camera cam = {{eye[0], eye[1], eye[2]}, {center[0], center[1], center[2]},
                       {0, 0, 1}, 40.0, size, size, 0, 0.0};
    return cam;
}

static cdvr_render_opts options(const cdvr_tf *tf, const cdvr_camera *cam, double step,
                                double term)
{
    cdvr_render_opts o;
    memset(&o, 0, sizeof o);
    o.tf = tf;
    o.camera = cam;
    o.step = step;
    o.term_alpha = term;
    o.background[3] = 1.0f;
    o.threads = 2;
    return o;
}

static cdvr_image *render(const cdvr_volume *v, cdvr_render_opts *o)
{
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_render_cpu(v, 0, o, &img, &err), err);
    return img;
}

/* Renders v with a and again with every sample taken (no_skip, the one-ray march): the images
 * and samples must be equal bit for bit (what names the case). Returns the unskipped image
 * for the caller's checks of the scene (free it), NULL when a render failed. */
static cdvr_image *render_as_unskipped(const cdvr_volume *v, cdvr_render_opts *a,
                                       const char *what)
{
    cdvr_render_opts b = *a;
    b.no_skip = 1;
    cdvr_image *ia = render(v, a), *ib = render(v, &b);
    if (ia && ib) {
        size_t n = (size_t)ia->width * ia->height * 4;
        CHECK(memcmp(ia->rgba, ib->rgba, n * sizeof(float)) == 0, "%s: the image differs from "
              "the one taking every sample", what);
        CHECK(a->samples == b.samples, "%s: %llu samples, %llu taking every sample", what,
              (unsigned long long)a->samples, (unsigned long long)b.samples);
    }
    cdvr_image_free(ia);
    if (!ia) {
        cdvr_image_free(ib);
        ib = NULL;
    }
    return ib;
}

/* Length of ray o + t d (t >= 0) inside box [lo, hi], in double. */
static double chord_length(const double lo[3], const double hi[3], const double o[3],
                           const double d[3])
{
    double t0 = 0.0, t1 = HUGE_VAL;
    for (int a = 0; a < 3; a++) {
        if (d[a] == 0.0) {
            if (o[a] < lo[a] || o[a] > hi[a])
                return 0.0;
            continue;
        }
        double ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
        t0 = fmax(t0, fmin(ta, tb));
        t1 = fmin(t1, fmax(ta, tb));
    }
    return t1 > t0 ? t1 - t0 : 0.0;
}

/* Every pixel: 1 - A = (1 - alpha)^(L/unit) to 1e-3, colour = A (white, premultiplied).
 * Returns the chord length of the centre pixel. */
static double check_transmittance(const cdvr_volume *v, const cdvr_camera *cam, double alpha,
                                  double unit, double step, const char *what)
{
    cdvr_tf tf;
    constant_tf(&tf, alpha, unit);
    cdvr_render_opts o = options(&tf, cam, step, 2.0);
    cdvr_image *img = render(v, &o);
    if (!img)
        return 0.0;
    double lo[3] = {0, 0, 0}, hi[3], centre = 0.0, worst = 0.0;
    for (int a = 0; a < 3; a++)
        hi[a] = (double)(v->dims[a] - 1);
    for (int y = 0; y < cam->height; y++)
        for (int x = 0; x < cam->width; x++) {
            double ro[3], rd[3];
            cdvr_camera_ray(cam, x, y, ro, rd);
            double L = chord_length(lo, hi, ro, rd);
            const float *p = cdvr_image_pixel(img, x, y);
            double expect = pow(1.0 - alpha, L / unit);
            worst = fmax(worst, fabs((1.0 - p[3]) - expect));
            worst = fmax(worst, fabs(p[0] - p[3]));
            if (x == cam->width / 2 && y == cam->height / 2)
                centre = L;
        }
    CHECK(worst <= 1e-3, "%s, step %g: transmittance off by %g", what, step, worst);
    cdvr_image_free(img);
    return centre;
}

static void test_analytic_box(void)
{
    cdvr_volume *v = constant_volume(16, 100);
    if (!v)
        return;
    const double steps[] = {0.05, 0.37, 1.0, 3.0, 40.0};
    double center[3] = {7.5, 7.5, 7.5};
    for (size_t i = 0; i < sizeof steps / sizeof steps[0]; i++) {
        double s = steps[i];
        /* odd size: the centre pixel's ray is exactly the y axis (x and z components 0) */
        double eye_axis[3] = {7.5, -30, 7.5};
        cdvr_camera cam = camera(eye_axis, center, 9);
        double L = check_transmittance(v, &cam, 0.3, 10.0, s, "axis-parallel");
        CHECK(fabs(L - 15.0) < 1e-9, "axis chord %g", L);
        check_transmittance(v, &cam, 0.3, 1.0, s, "axis-parallel, unit 1");
        cam.orthographic = 1;
        cam.ortho_height = 20.0; /* rays along y, some miss the box entirely */
        check_transmittance(v, &cam, 0.3, 10.0, s, "orthographic");
        double eye_diag[3] = {7.5 - 30, 7.5 - 30, 7.5};
        cam = camera(eye_diag, center, 9);
        L = check_transmittance(v, &cam, 0.3, 10.0, s, "45 degrees");
        CHECK(fabs(L - 15.0 * sqrt(2.0)) < 1e-6, "diagonal chord %g", L);
        double eye_in[3] = {5, 6, 7}, look[3] = {10, 6.2, 7.1};
        cam = camera(eye_in, look, 9);
        cam.fov = 90.0;
        check_transmittance(v, &cam, 0.3, 10.0, s, "camera inside");
    }
    cdvr_volume_free(v);
}

static void test_zero_and_full_opacity(void)
{
    cdvr_volume *v = constant_volume(16, 100);
    if (!v)
        return;
    double eye[3] = {30, -25, 20}, center[3] = {7.5, 7.5, 7.5};
    cdvr_camera cam = camera(eye, center, 24);
    cdvr_tf tf;
    constant_tf(&tf, 0.0, 1.0);
    cdvr_render_opts o = options(&tf, &cam, 0.5, 0.0);
    cdvr_image *img = render(v, &o);
    int nonzero = 0, hits = 0;
    for (int i = 0; img && i < 24 * 24 * 4; i++)
        nonzero += img->rgba[i] != 0.0f;
    CHECK(img && nonzero == 0, "zero-opacity TF left %d nonzero channels", nonzero);
    CHECK(o.samples > 0, "no samples taken");
    cdvr_image_free(img);

    cdvr_tf_point red = {100, 1, 0, 0, 1.0};
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, &red, 1, 1.0, &err), err);
    o = options(&tf, &cam, 0.5, 0.0);
    img = render(v, &o);
    for (int y = 0; img && y < 24; y++)
        for (int x = 0; x < 24; x++) {
            const float *p = cdvr_image_pixel(img, x, y);
            CHECK(p[3] == 0.0f || (p[3] == 1.0f && p[0] == 1.0f && p[1] == 0.0f),
                  "pixel %d,%d = %g %g %g %g", x, y, p[0], p[1], p[2], p[3]);
            hits += p[3] == 1.0f;
        }
    CHECK(hits > 100, "only %d pixels hit the box", hits);
    CHECK(o.samples == (uint64_t)hits, "full opacity took %llu samples for %d rays",
          (unsigned long long)o.samples, hits);
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

/* Deterministic bumpy field: values from a fixed LCG, smoothed by trilinear sampling. */
static cdvr_volume *noise_volume(size_t n)
{
    cdvr_volume *v = make_volume(n, n, n);
    uint32_t state = 12345u;
    for (size_t i = 0; v && i < cdvr_volume_voxels(v); i++) {
        state = state * 1664525u + 1013904223u;
        ((uint8_t *)v->data)[i] = (uint8_t)(state >> 24);
    }
    return v;
}

static void test_early_termination_and_threads(void)
{
    cdvr_volume *v = noise_volume(20);
    if (!v)
        return;
    cdvr_tf_point pts[] = {{0, 0, 0, 1, 0}, {128, 0, 1, 0, 0.2}, {255, 1, 0, 0, 0.9}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 3, 1.0, &err), err);
    double eye[3] = {-20, -30, 25}, center[3] = {9.5, 9.5, 9.5};
    cdvr_camera cam = camera(eye, center, 32);
    cdvr_render_opts full = options(&tf, &cam, 0.3, 2.0), early = options(&tf, &cam, 0.3, 0.0);
    cdvr_image *a = render(v, &full), *b = render(v, &early);
    early.threads = 1;
    cdvr_image *c = render(v, &early);
    early.threads = 5;
    cdvr_image *d = render(v, &early);
    if (a && b && c && d) {
        double worst = 0.0;
        int opaque = 0;
        for (int i = 0; i < 32 * 32 * 4; i++)
            worst = fmax(worst, fabs(a->rgba[i] - b->rgba[i]));
        for (int i = 3; i < 32 * 32 * 4; i += 4)
            opaque += b->rgba[i] >= 0.99f;
        CHECK(worst <= 0.011, "early termination changed a pixel by %g", worst);
        CHECK(opaque > 50, "only %d rays terminated early: test too weak", opaque);
        CHECK(early.samples < full.samples, "early termination saved no samples");
        CHECK(memcmp(b->rgba, c->rgba, 32 * 32 * 4 * sizeof(float)) == 0 &&
                  memcmp(b->rgba, d->rgba, 32 * 32 * 4 * sizeof(float)) == 0,
              "thread count changes the image");
    }
    cdvr_image_free(a);
    cdvr_image_free(b);
    cdvr_image_free(c);
    cdvr_image_free(d);
    cdvr_volume_free(v);
}

static void test_sphere_symmetry(void)
{
    cdvr_volume *v = make_volume(32, 32, 32);
    if (!v)
        return;
    uint8_t *vox = v->data;
    for (int z = 0; z < 32; z++)
        for (int y = 0; y < 32; y++)
            for (int x = 0; x < 32; x++) {
                double r = sqrt((x - 15.5) * (x - 15.5) + (y - 15.5) * (y - 15.5) +
                                (z - 12.0) * (z - 12.0));
                vox[x + 32 * (y + 32 * z)] = r < 11.0 ? (uint8_t)(250 - 20 * r) : 0;
            }
    cdvr_tf_point pts[] = {{20, 0, 0, 0, 0}, {120, 1, 0.5, 0, 0.1}, {250, 1, 1, 1, 0.8}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 3, 1.0, &err), err);
    double eye[3] = {15.5, -50, 30}, center[3] = {15.5, 15.5, 12};
    cdvr_camera cam = camera(eye, center, 32);
    cdvr_render_opts o = options(&tf, &cam, 0.37, 0.0);
    cdvr_image *img = render(v, &o);
    double worst = 0.0, top = 0.0, bottom = 0.0;
    for (int y = 0; img && y < 32; y++)
        for (int x = 0; x < 16; x++) {
            const float *p = cdvr_image_pixel(img, x, y), *q = cdvr_image_pixel(img, 31 - x, y);
            for (int c = 0; c < 4; c++)
                worst = fmax(worst, fabs(p[c] - q[c]));
            if (y < 16)
                top += p[3];
            else
                bottom += p[3];
        }
    CHECK(img && worst < 1e-4, "sphere not left-right symmetric: %g", worst);
    CHECK(top > 1.0 && bottom > 1.0, "sphere not visible: %g %g", top, bottom);
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

/* Image orientation: y down with up = +z, x right = f x u. Content only in the upper (z) and
 * right (x, seen from -y) corner must land in the top-right quadrant. */
static void test_orientation(void)
{
    cdvr_volume *v = make_volume(16, 16, 16);
    if (!v)
        return;
    uint8_t *vox = v->data;
    for (int z = 12; z < 16; z++)
        for (int y = 0; y < 16; y++)
            for (int x = 12; x < 16; x++)
                vox[x + 16 * (y + 16 * z)] = 200;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {200, 1, 1, 1, 0.5}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 1.0, &err), err);
    double eye[3] = {7.5, -40, 7.5}, center[3] = {7.5, 7.5, 7.5};
    cdvr_camera cam = camera(eye, center, 16);
    cdvr_render_opts o = options(&tf, &cam, 0.5, 0.0);
    cdvr_image *img = render(v, &o);
    double quadrant[2][2] = {{0, 0}, {0, 0}};
    for (int y = 0; img && y < 16; y++)
        for (int x = 0; x < 16; x++)
            quadrant[y / 8][x / 8] += cdvr_image_pixel(img, x, y)[3];
    CHECK(quadrant[0][1] > 1.0 && quadrant[0][0] + quadrant[1][0] + quadrant[1][1] < 1e-6,
          "content not top-right: TL %g TR %g BL %g BR %g", quadrant[0][0], quadrant[0][1],
          quadrant[1][0], quadrant[1][1]);
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

static void test_bad_input(void)
{
    cdvr_volume *v = constant_volume(4, 100);
    size_t dims[3] = {4, 4, 4};
    cdvr_volume *f = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_F32, &f, &err), err);
    if (!v || !f)
        return;
    cdvr_tf tf;
    constant_tf(&tf, 0.5, 1.0);
    double eye[3] = {1.5, -10, 1.5}, center[3] = {1.5, 1.5, 1.5};
    cdvr_camera cam = camera(eye, center, 8);
    cdvr_render_opts o = options(&tf, &cam, 0.0, 0.0);
    cdvr_image *img = NULL;
    CHECK(cdvr_render_cpu(f, 0, &o, &img, &err) == CDVR_ERR_ARG && !img, "f32 accepted");
    CHECK(strstr(err.msg, "quantize") != NULL, "message: %s", err.msg);
    CHECK(cdvr_render_cpu(v, 1, &o, &img, &err) == CDVR_ERR_ARG, "timestep 1 of 1 accepted");
    o.step = -1.0;
    CHECK(cdvr_render_cpu(v, 0, &o, &img, &err) == CDVR_ERR_ARG, "negative step accepted");
    o.step = 1e-12;
    CHECK(cdvr_render_cpu(v, 0, &o, &img, &err) == CDVR_ERR_ARG, "absurd step accepted");
    o.step = 0.0;
    cam.fov = 200.0;
    CHECK(cdvr_render_cpu(v, 0, &o, &img, &err) == CDVR_ERR_ARG, "bad camera accepted");
    cam.fov = 40.0;
    v->spacing[1] = 0.0;
    CHECK(cdvr_render_cpu(v, 0, &o, &img, &err) == CDVR_ERR_ARG, "zero spacing accepted");
    v->spacing[1] = 2.0;
    double step, unit, term;
    cdvr_render_resolve(v, &o, &step, &unit, &term);
    CHECK(step == 0.5 && unit == 1.0 && fabs(term - 0.99) < 1e-12, "defaults %g %g %g", step,
          unit, term);
    /* a 1-voxel-thick volume is a flat box: no ray crosses a positive length */
    cdvr_volume *flat = make_volume(4, 4, 1);
    CHECK_OK(cdvr_render_cpu(flat, 0, &o, &img, &err), err);
    cdvr_image_free(img);
    cdvr_volume_free(flat);
    cdvr_volume_free(v);
    cdvr_volume_free(f);
}

static void test_engine_png(void)
{
    const char *dir = check_shared_data();
    if (!dir) {
        printf("CDVR_SHARED_DATA not set: engine render skipped\n");
        return;
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/ct/engine_256x256x128_u8.nrrd", dir);
    cdvr_volume *v = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_load_nrrd(path, &v, &err), err);
    if (!v)
        return;
    /* share/tf/ct_bone.lua: block material faint, dense metal opaque and bright */
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0},         {120, 0.5, 0.3, 0.2, 0},
                           {140, 0.8, 0.6, 0.5, 0.02}, {165, 0.9, 0.8, 0.7, 0.03},
                           {185, 1, 0.95, 0.85, 0.6}, {255, 1, 1, 1, 0.95}};
    cdvr_tf tf;
    CHECK_OK(cdvr_tf_init(&tf, pts, 6, 1.0, &err), err);
    cdvr_camera cam = {{0}, {0}, {0}, 30.0, 256, 256, 0, 0.0};
    double center[3] = {127.5, 127.5, 63.5}, up[3] = {0, 0, 1};
    cdvr_camera_orbit(&cam, center, up, 650.0, -60.0, 25.0);
    cdvr_render_opts o = options(&tf, &cam, 1.0, 0.0);
    o.threads = 0;
    cdvr_image *img = render(v, &o);
    if (img) {
        int empty = 0, solid = 0;
        for (int i = 3; i < 256 * 256 * 4; i += 4) {
            empty += img->rgba[i] == 0.0f;
            solid += img->rgba[i] > 0.5f;
        }
        CHECK(empty > 1000 && solid > 1000, "engine image: %d empty, %d solid pixels", empty,
              solid);
        CHECK_OK(cdvr_image_save_png(img, "test_render_engine.png", &err), err);
        printf("wrote test_render_engine.png (%llu samples)\n", (unsigned long long)o.samples);
    }
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

/* Empty-space skipping and the four-lane march change nothing: blobs of noise and a smooth
 * ramp in a volume of low values, a TF with zero opacity below 60, eyes outside and inside the volume, oblique and
 * axis-parallel rays, composite plain and shaded with gradient opacity, max and min (which jump
 * dull bricks), average, shaded iso (which jumps bricks wholly above or below the iso value),
 * anisotropic spacing: the image and the samples count equal those with opts.no_skip (one
 * ray at a time, every sample), bit for bit, and the scene has empty and visible stretches. */
static void test_skipping_is_exact(void)
{
    cdvr_volume *v = make_volume(45, 38, 33);
    if (!v)
        return;
    v->spacing[0] = 0.8;
    v->spacing[2] = 1.3;
    uint8_t *d = v->data;
    uint32_t state = 777u;
    for (size_t z = 0; z < 33; z++)
        for (size_t y = 0; y < 38; y++)
            for (size_t x = 0; x < 45; x++) {
                state = state * 1664525u + 1013904223u;
                double r1 = hypot(hypot((double)x - 12, (double)y - 10), (double)z - 9);
                double r2 = hypot(hypot((double)x - 33, (double)y - 27), (double)z - 22);
                int inside = r1 < 7.5 || r2 < 5.2 || (x == 40 && y == 5);
                int ramp = y >= 30 && z < 12; /* smooth: narrow brick ranges across iso 100 */
                d[x + 45 * (y + 38 * z)] = inside ? (uint8_t)(state >> 24)
                                           : ramp ? (uint8_t)(40 + 4 * x)
                                                  : (uint8_t)(z & 3);
            }
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {59, 0, 0, 0, 0}, {60, 1, 0.5, 0, 0.05},
                           {255, 0.2, 0.4, 1, 0.9}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 4, 1.0, &err), err);
    double eyes[][3] = {{-40, -55, 70}, {17.5, 18.5, 100}, {20, 20, 20}, {80, 30.3, 10}};
    double center[3] = {17.6, 18.5, 20.8};
    for (int e = 0; e < 4; e++)
        for (int kind = 0; kind < 8; kind++) { /* composite, shaded, max, min, average, iso,
                                                  * shaded without gradient opacity: headlight
                                                  * and power 10, fixed light and power 7.5 */
            int shade = kind == 1 || kind >= 5;
            cdvr_camera cam = camera(eyes[e], center, 48);
            if (e == 1)
                cam.up[0] = 1, cam.up[2] = 0; /* looking down z: rays parallel to it at the centre */
            cdvr_render_opts a = options(&tf, &cam, e == 3 ? 0.37 : 0.5, 0.0);
            if (shade && kind >= 5) {
                cdvr_shading_default(&a.look.shade);
                if (kind == 7) {
                    a.look.shade.specular_power = 7.5;
                    a.look.shade.light_fixed = 1;
                    a.look.shade.light_dir[0] = 0.3, a.look.shade.light_dir[1] = -1;
                    a.look.shade.light_dir[2] = -0.4;
                }
            } else if (shade) { /* with gradient opacity */
                cdvr_shading_default(&a.look.shade);
                a.look.gradient_opacity.npoints = 2;
                a.look.gradient_opacity.magnitude[0] = 0.0;
                a.look.gradient_opacity.factor[0] = 0.2;
                a.look.gradient_opacity.magnitude[1] = 40.0;
                a.look.gradient_opacity.factor[1] = 1.0;
            }
            a.look.blend = kind == 2   ? CDVR_BLEND_MAX
                           : kind == 3 ? CDVR_BLEND_MIN
                           : kind == 4 ? CDVR_BLEND_AVERAGE
                           : kind == 5 ? CDVR_BLEND_ISO
                                       : CDVR_BLEND_COMPOSITE;
            a.look.iso_value = 100.0; /* iso: brick ranges wholly above or below it are jumped */
            char what[64];
            snprintf(what, sizeof what, "eye %d case %d, skipping", e, kind);
            cdvr_image *ib = render_as_unskipped(v, &a, what);
            if (ib) {
                size_t n = (size_t)48 * 48 * 4;
                int lit = 0;
                for (size_t i = 3; i < n; i += 4)
                    lit += ib->rgba[i] > 0.0f;
                if (kind < 3 || kind >= 5) /* min and average are low: little or nothing lit */
                    CHECK(lit > 40 && lit < 48 * 48 - 40, "eye %d case %d: %d pixels lit: scene "
                          "too weak", e, kind, lit);
            }
            cdvr_image_free(ib);
        }
    cdvr_volume_free(v);
}

/* Max and min stop a ray once its extreme is the last code (255 for max, 0 for min): a
 * volume with a saturated cube of 255s and one of 0s in a field of middling noise, seen from
 * two eyes (a row width not a multiple of four, so the one-ray tail runs too), gives the
 * images and samples count of no_skip bit for bit, and some rays do meet each cube. */
static void test_extreme_stops_exact(void)
{
    cdvr_volume *v = make_volume(30, 26, 22);
    if (!v)
        return;
    uint8_t *d = v->data;
    uint32_t state = 4242u;
    for (size_t z = 0, i = 0; z < 22; z++)
        for (size_t y = 0; y < 26; y++)
            for (size_t x = 0; x < 30; x++, i++) {
                state = state * 1664525u + 1013904223u;
                int hot = x >= 6 && x < 13 && y >= 5 && y < 12 && z >= 6 && z < 14;
                int cold = x >= 17 && x < 25 && y >= 14 && y < 21 && z >= 8 && z < 15;
                d[i] = hot ? 255 : cold ? 0 : (uint8_t)(40 + (state >> 26));
            }
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0.2}, {255, 1, 1, 1, 0.9}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 1.0, &err), err);
    double eyes[][3] = {{-30, -40, 50}, {70, 60, -20}}, center[3] = {15, 13, 11};
    for (int e = 0; e < 2; e++)
        for (int blend = 0; blend < 2; blend++) {
            cdvr_camera cam = camera(eyes[e], center, 38);
            cdvr_render_opts a = options(&tf, &cam, e ? 0.45 : 0.5, 0.0);
            a.look.blend = blend ? CDVR_BLEND_MIN : CDVR_BLEND_MAX;
            char what[64];
            snprintf(what, sizeof what, "eye %d blend %d, stopping at the last code", e, blend);
            cdvr_image *ib = render_as_unskipped(v, &a, what);
            if (ib) {
                size_t n = (size_t)38 * 38 * 4;
                int extreme = 0;
                for (size_t i = 3; i < n; i += 4) /* the TF's alpha at 255 (0): 0.9 (0.2) */
                    extreme += ib->rgba[i] == (blend ? 0.2f : 0.9f);
                CHECK(extreme > 20, "eye %d blend %d: only %d rays meet the cube", e, blend,
                      extreme);
            }
            cdvr_image_free(ib);
        }
    cdvr_volume_free(v);
}

/* Max and min rays start from the extreme of the ray above them (render_cpu.c,
 * GUESS_MARGIN): stripes of hot and cold voxels across the rows of the image (4 voxels wide,
 * each about 3 pixel rows), so that many rays lie below (min: above) the guess their
 * neighbour gives and are marched again; the images and samples equal no_skip bit for bit,
 * with rows of 45 pixels (the one-ray tail too). */
static void test_extreme_guess_exact(void)
{
    cdvr_volume *v = make_volume(40, 40, 20);
    if (!v)
        return;
    uint8_t *d = v->data;
    uint32_t state = 99u;
    for (size_t z = 0, i = 0; z < 20; z++)
        for (size_t y = 0; y < 40; y++)
            for (size_t x = 0; x < 40; x++, i++) {
                state = state * 1664525u + 1013904223u;
                int hot = (y / 4) % 2 == 0;
                d[i] = (uint8_t)((hot ? 180 : 70) + (state >> 27)); /* + 0..31 of noise */
            }
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0.2}, {255, 1, 1, 1, 0.9}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 1.0, &err), err);
    double eyes[][3] = {{19.5, 19.5, 90}, {60, -20, 70}}, center[3] = {19.5, 19.5, 9.5};
    for (int e = 0; e < 2; e++)
        for (int blend = 0; blend < 2; blend++) {
            cdvr_camera cam = camera(eyes[e], center, 45);
            if (e == 0)
                cam.up[1] = 1, cam.up[2] = 0; /* looking down z, the stripes across the rows */
            cdvr_render_opts a = options(&tf, &cam, e ? 0.45 : 0.5, 0.0);
            a.look.blend = blend ? CDVR_BLEND_MIN : CDVR_BLEND_MAX;
            char what[64];
            snprintf(what, sizeof what, "eye %d blend %d, starting from the guess", e, blend);
            cdvr_image *ib = render_as_unskipped(v, &a, what);
            if (ib) {
                size_t n = (size_t)45 * 45 * 4;
                int hot = 0, cold = 0;
                for (size_t i = 3; i < n; i += 4) {
                    hot += ib->rgba[i] > 0.6f; /* a hot stripe's codes: >= 180, alpha > 0.69 */
                    cold += ib->rgba[i] > 0.0f && ib->rgba[i] < 0.55f;
                }
                CHECK(e || (hot > 200 && cold > 200), "eye %d blend %d: %d hot, %d cold pixels:"
                      " no stripes", e, blend, hot, cold);
            }
            cdvr_image_free(ib);
        }
    cdvr_volume_free(v);
}

/* Average skips bricks of zeros (their samples add 0 to the sum but count): a volume of zeros
 * with a blob of noise (values 1..255, so a brick of ones is not skipped) and a faint shell
 * of ones around it, large enough for whole cubes of zero bricks: the image and samples
 * count equal no_skip bit for bit. */
static void test_average_skips_zeros_exact(void)
{
    cdvr_volume *v = make_volume(52, 44, 40);
    if (!v)
        return;
    uint8_t *d = v->data;
    uint32_t state = 2718u;
    for (size_t z = 0, i = 0; z < 40; z++)
        for (size_t y = 0; y < 44; y++)
            for (size_t x = 0; x < 52; x++, i++) {
                state = state * 1664525u + 1013904223u;
                double r = hypot(hypot((double)x - 15, (double)y - 14), (double)z - 12);
                d[i] = r < 7.0 ? (uint8_t)(1 + (state >> 24) % 255) : r < 10.0 ? 1 : 0;
            }
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0.1}, {255, 1, 1, 1, 0.9}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 1.0, &err), err);
    double eyes[][3] = {{-40, -50, 60}, {100, 80, 20}}, center[3] = {26, 22, 20};
    for (int e = 0; e < 2; e++) {
        cdvr_camera cam = camera(eyes[e], center, 36);
        cdvr_render_opts a = options(&tf, &cam, e ? 0.6 : 0.5, 0.0);
        a.look.blend = CDVR_BLEND_AVERAGE;
        cdvr_render_opts b = a;
        b.no_skip = 1;
        cdvr_image *ia = render(v, &a), *ib = render(v, &b);
        if (ia && ib) {
            size_t n = (size_t)36 * 36 * 4;
            int lit = 0;
            for (size_t i = 3; i < n; i += 4)
                lit += ib->rgba[i] > 0.1f; /* above the TF's alpha at 0: rays through the blob */
            CHECK(memcmp(ia->rgba, ib->rgba, n * sizeof(float)) == 0,
                  "eye %d: skipping zero bricks changed the average", e);
            CHECK(a.samples == b.samples, "eye %d: %llu samples, %llu without skipping", e,
                  (unsigned long long)a.samples, (unsigned long long)b.samples);
            CHECK(lit > 20 && lit < 36 * 36 - 20, "eye %d: %d rays meet the blob", e, lit);
        }
        cdvr_image_free(ia);
        cdvr_image_free(ib);
    }
    cdvr_volume_free(v);
}

/* Rays along an axis: a camera above the volume looking straight down z, with an odd image
 * width, so the middle pixel's ray has x and y components of exactly 0 (the slab test's
 * axis-parallel branch, taken four rays at a time), and the same from an eye beside the box
 * looking along -y: composite and max equal no_skip bit for bit, and the middle ray hits. */
static void test_axis_rays_exact(void)
{
    cdvr_volume *v = make_volume(21, 19, 17);
    if (!v)
        return;
    uint8_t *d = v->data;
    uint32_t state = 31337u;
    for (size_t i = 0; i < 21 * 19 * 17; i++) {
        state = state * 1664525u + 1013904223u;
        d[i] = (uint8_t)(state >> 24);
    }
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {99, 0, 0, 0, 0}, {100, 1, 0.5, 0, 0.1},
                           {255, 0.2, 0.4, 1, 0.9}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 4, 1.0, &err), err);
    double eyes[][3] = {{10, 9, 60}, {10, 60, 8}}, centers[][3] = {{10, 9, 8}, {10, 9, 8}};
    for (int e = 0; e < 2; e++)
        for (int blend = 0; blend < 2; blend++) {
            cdvr_camera cam = camera(eyes[e], centers[e], 33);
            if (e == 0)
                cam.up[0] = 1, cam.up[2] = 0;
            cdvr_render_opts a = options(&tf, &cam, 0.5, 0.0);
            a.look.blend = blend ? CDVR_BLEND_MAX : CDVR_BLEND_COMPOSITE;
            cdvr_render_opts b = a;
            b.no_skip = 1;
            cdvr_image *ia = render(v, &a), *ib = render(v, &b);
            if (ia && ib) {
                size_t n = (size_t)33 * 33 * 4;
                CHECK(memcmp(ia->rgba, ib->rgba, n * sizeof(float)) == 0,
                      "eye %d blend %d: the four-ray path changed the image", e, blend);
                CHECK(a.samples == b.samples, "eye %d blend %d: %llu samples, %llu without "
                      "skipping", e, blend, (unsigned long long)a.samples,
                      (unsigned long long)b.samples);
                CHECK(cdvr_image_pixel(ib, 16, 16)[3] > 0.0f, "eye %d blend %d: the middle ray "
                      "misses", e, blend);
            }
            cdvr_image_free(ia);
            cdvr_image_free(ib);
        }
    cdvr_volume_free(v);
}

/* Rays whose last segment is empty: n = ceil((t_far - t_near) / step) rounds up past the
 * last whole step when the quotient lies just above an integer, and t_near + (n - 1) step
 * then rounds to t_far (far from the eye the floats are coarse). The definition neither takes
 * nor counts that segment, so a max or min march that jumps to the end, or stops at code 255
 * or 0, must leave it out of its count too. A box of zeros (min stops at its first sample,
 * max jumps the rest) and of 255s, seen from 1000 voxels away down z, at steps a few floats
 * below 19 / m for many m: the images and samples count equal no_skip. */
static void test_extreme_empty_last_segment(void)
{
    cdvr_volume *v = make_volume(20, 20, 20);
    if (!v)
        return;
    cdvr_tf_point pts[] = {{0, 1, 0, 0, 0.5}, {255, 0, 1, 0, 0.5}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 1.0, &err), err);
    double eye[3] = {9.5, 9.5, -990.0}, center[3] = {9.5, 9.5, 9.5};
    cdvr_camera cam = camera(eye, center, 9);
    cam.fov = 0.05;
    cam.up[0] = 1, cam.up[2] = 0;
    for (int fill = 0; fill < 2; fill++) {
        memset(v->data, fill ? 255 : 0, cdvr_volume_voxels(v));
        for (int m = 150; m < 250; m++)
            for (int j = 0; j < 4; j++)
                for (int blend = 0; blend < 2; blend++) {
                    char what[96];
                    snprintf(what, sizeof what, "%s box, %s, step 19/%d less %d floats",
                             fill ? "255" : "zero", blend ? "min" : "max", m, j);
                    float step = 19.0f / (float)m;
                    for (int k = 0; k < j; k++)
                        step = nextafterf(step, 0.0f);
                    cdvr_render_opts a = options(&tf, &cam, step, 0.0);
                    a.look.blend = blend ? CDVR_BLEND_MIN : CDVR_BLEND_MAX;
                    cdvr_image_free(render_as_unskipped(v, &a, what));
                }
    }
    cdvr_volume_free(v);
}

/* One skip cache across a sequence of renders keeps exactly the images of no_skip: the same
 * TF again (flags kept), a TF that makes more entries visible (stale flags would jump the
 * bricks between 60 and 200), iso and max on the same ranges, the first TF again, a voxel edit
 * that puts a visible blob into empty bricks (stale ranges would jump it), max twice with an
 * edit between them (stale widened ranges would jump the new blob), and a volume of other
 * dims. */
static void test_skip_cache_is_exact(void)
{
    cdvr_volume *v = make_volume(40, 36, 30), *w = make_volume(23, 41, 19);
    cdvr_cpu_skip_cache *cache = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_cpu_skip_cache_create(&cache, &err), err);
    if (!v || !w || !cache)
        goto done;
    cdvr_volume *vols[2] = {v, w};
    for (int k = 0; k < 2; k++) {
        cdvr_volume *u = vols[k];
        uint8_t *d = u->data;
        for (size_t z = 0, i = 0; z < u->dims[2]; z++)
            for (size_t y = 0; y < u->dims[1]; y++)
                for (size_t x = 0; x < u->dims[0]; x++, i++) {
                    double r = hypot(hypot((double)x - 12, (double)y - 12), (double)z - 11);
                    d[i] = r < 4.0 ? 240 : r < 9.0 ? (uint8_t)(100 + 10 * (int)(r - 4.0)) : 10;
                }
    }
    cdvr_tf_point hi_pts[] = {{0, 0, 0, 0, 0}, {199, 0, 0, 0, 0}, {200, 1, 1, 1, 0.3},
                              {255, 1, 1, 1, 0.9}};
    cdvr_tf_point lo_pts[] = {{0, 0, 0, 0, 0}, {59, 0, 0, 0, 0}, {60, 1, 0.5, 0, 0.05},
                              {255, 0.2, 0.4, 1, 0.9}};
    cdvr_tf tf_hi, tf_lo;
    CHECK_OK(cdvr_tf_init(&tf_hi, hi_pts, 4, 1.0, &err), err);
    CHECK_OK(cdvr_tf_init(&tf_lo, lo_pts, 4, 1.0, &err), err);
    double eye[3] = {-30, -45, 60}, center[3] = {20, 18, 15};
    cdvr_camera cam = camera(eye, center, 40);
    /* case: 0, 1 tf_hi; 2 tf_lo; 3 iso; 4 max; 5 tf_hi; 6 tf_hi after the edit; 7 max; 8 max
     * after a second edit (stale widened ranges would jump its blob); 9 on w */
    for (int c = 0; c < 10; c++) {
        if (c == 6) /* a visible blob far from the sphere, in bricks that were empty */
            for (size_t z = 22; z < 27; z++)
                for (size_t y = 26; y < 31; y++)
                    for (size_t x = 30; x < 36; x++)
                        ((uint8_t *)v->data)[x + 40 * (y + 36 * z)] = 250;
        if (c == 8) /* a small bright blob between the sphere and the first blob */
            for (size_t z = 16; z < 19; z++)
                for (size_t y = 2; y < 5; y++)
                    for (size_t x = 26; x < 29; x++)
                        ((uint8_t *)v->data)[x + 40 * (y + 36 * z)] = 252;
        cdvr_volume *u = c == 9 ? w : v;
        cdvr_render_opts a = options(c == 2 ? &tf_lo : &tf_hi, &cam, 0.5, 0.0);
        a.look.blend = c == 3                       ? CDVR_BLEND_ISO
                       : c == 4 || c == 7 || c == 8 ? CDVR_BLEND_MAX
                                                    : CDVR_BLEND_COMPOSITE;
        a.look.iso_value = 150.0;
        cdvr_render_opts b = a;
        b.no_skip = 1;
        cdvr_image *ia = NULL, *ib = render(u, &b);
        CHECK_OK(cdvr_render_cpu_cached(u, 0, &a, cache, &ia, &err), err);
        if (ia && ib) {
            size_t n = (size_t)40 * 40 * 4;
            CHECK(memcmp(ia->rgba, ib->rgba, n * sizeof(float)) == 0,
                  "case %d: the cached skip grid changed the image", c);
            CHECK(a.samples == b.samples, "case %d: %llu samples cached, %llu without skipping",
                  c, (unsigned long long)a.samples, (unsigned long long)b.samples);
        }
        cdvr_image_free(ia);
        cdvr_image_free(ib);
    }
done:
    cdvr_cpu_skip_cache_free(cache);
    cdvr_volume_free(v);
    cdvr_volume_free(w);
}

/* The threaded brick ranges equal cdvr_range_compute's (through cdvr_skip_minmax_from_frame)
 * for odd and even sizes, one voxel thick axes, frames of 9-10 M voxels whose dims leave
 * partial bricks and uneven shares, shifts 1..3 and 1..7 threads and the online cores (0). */
static void test_brick_ranges(void)
{
    static const size_t sizes[][3] = {{45, 38, 33}, {33, 17, 1},    {1, 9, 20},     {64, 16, 8},
                                      {70, 3, 5},   {301, 150, 203}, {130, 257, 255}};
    for (size_t k = 0; k < sizeof sizes / sizeof sizes[0]; k++) {
        const size_t *d = sizes[k];
        size_t n = d[0] * d[1] * d[2];
        uint8_t *frame = malloc(n);
        if (!frame)
            return;
        uint32_t state = 99u + (uint32_t)k;
        for (size_t i = 0; i < n; i++) {
            state = state * 1664525u + 1013904223u;
            frame[i] = (uint8_t)(64 + (state >> 26)); /* 64..127: min and max both matter */
        }
        frame[n / 2] = 3;
        frame[n / 3] = 250;
        for (unsigned shift = 1; shift <= 3; shift++) {
            cdvr_skip_grid g;
            cdvr_error err;
            CHECK_OK(cdvr_skip_grid_init(&g, d, shift, &err), err);
            CHECK_OK(cdvr_skip_minmax_from_frame(&g, frame, &err), err);
            uint8_t *mine = malloc(2 * g.nbricks);
            for (int threads = 0; mine && threads <= 7; threads += threads ? 2 : 1) {
                memset(mine, 0xAA, 2 * g.nbricks);
                CHECK_OK(cdvr_cpu_brick_ranges(frame, d, shift, threads, mine, &err), err);
                CHECK(memcmp(mine, g.minmax, 2 * g.nbricks) == 0,
                      "%zux%zux%zu shift %u threads %d: brick ranges differ", d[0], d[1], d[2],
                      shift, threads);
            }
            free(mine);
            cdvr_skip_grid_free(&g);
        }
        free(frame);
    }
}

int main(void)
{
    test_brick_ranges();
    test_skipping_is_exact();
    test_extreme_stops_exact();
    test_extreme_guess_exact();
    test_axis_rays_exact();
    test_extreme_empty_last_segment();
    test_average_skips_zeros_exact();
    test_skip_cache_is_exact();
    test_analytic_box();
    test_zero_and_full_opacity();
    test_early_termination_and_threads();
    test_sphere_symmetry();
    test_orientation();
    test_bad_input();
    test_engine_png();
    return check_finish();
}
