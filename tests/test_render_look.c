/* tests/test_render_look.c - blend modes, shading and gradient opacity of the ray caster
 * (cdvr/render.h), on the CPU reference and the OpenCL device.
 *
 * Proves:
 *  - iso: on a radial ramp (value 255 - 20 r rounded to u8, r in voxels from the centre) the
 *    iso surface of code 75 is the sphere r = R = 9: every pixel whose ray passes within R - 1
 *    of the centre hits it and none beyond R + 1 does; lit by the headlight with ambient 0,
 *    diffuse 1, specular 0, the pixel equals |n.V| = sqrt(1 - (rho/R)^2) (rho: the ray's
 *    distance from the centre) where rho < R - 2, within the bound the rounding allows: each
 *    voxel is off by at most 0.5, so each central difference (and its trilinear blend) by at
 *    most 0.5 codes per voxel, |dG| <= sqrt(3) 0.5 against |G| = 20, and |d(n.V)| <= |dn| <=
 *    |dG| / |G| = 0.043 (curvature adds O(1/R^2) less than that);
 *  - composite shading: an opaque TF above code 76 on the same ramp stops each ray at its first
 *    sample inside the sphere, a quarter voxel from the surface: the same bound plus the
 *    normal's turn over that step, 0.043 + 0.25/R;
 *  - the direction matrix: a ramp along index x with D a rotation taking x to world y is lit
 *    fully by a light travelling along world -y and not at all by one along world x;
 *  - max and min on an axis-aligned slab (30 around, 200 in the slab) give exactly the TF's
 *    entries 200 and 30 (premultiplied), average of a constant volume exactly its entry;
 *  - a constant volume shaded (zero gradient) gives finite pixels: rgb * ambient composited;
 *  - gradient opacity 0 at every magnitude makes the image empty;
 *  - bad options are refused naming them (blend, light, gradient_opacity order, clipping);
 *  - the OpenCL ray caster matches the CPU in every mode at >= 80 dB (on the engine CT when
 *    ../shared/data is present, else on the bundled neghip volume): float rounding gives
 *    116-150 dB, a skip that drops one brick's maximum about 58 dB.
 */
#include "check.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cdvr/compare.h"
#include "cdvr/method.h"
#include "cdvr/render.h"

#define N 40
#define SLOPE 20.0 /* codes per voxel */
#define R 9.0      /* radius of the iso sphere (code 255 - SLOPE R) */
#define BOUND (sqrt(3.0) * 0.5 / SLOPE)

static cdvr_volume *radial_ramp(void)
{
    size_t dims[3] = {N, N, N};
    cdvr_volume *v;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return NULL;
    double c = (N - 1) / 2.0;
    for (size_t z = 0; z < N; z++)
        for (size_t y = 0; y < N; y++)
            for (size_t x = 0; x < N; x++) {
                double r = sqrt((x - c) * (x - c) + (y - c) * (y - c) + (z - c) * (z - c));
                double val = 255.0 - SLOPE * r;
                ((uint8_t *)v->data)[x + N * (y + N * z)] = (uint8_t)(val < 0 ? 0 : lround(val));
            }
    return v;
}

/* Orthographic camera along +z over the whole N^3 box, one pixel per voxel. */
static cdvr_camera along_z(void)
{
    cdvr_camera cam;
    memset(&cam, 0, sizeof cam);
    double c = (N - 1) / 2.0;
    cam.center[0] = cam.center[1] = cam.center[2] = c;
    cam.eye[0] = cam.eye[1] = c;
    cam.eye[2] = -100.0;
    cam.up[1] = -1.0;
    cam.fov = 30.0;
    cam.orthographic = 1;
    cam.ortho_height = N;
    cam.width = cam.height = N;
    return cam;
}

static cdvr_tf tf_of(const cdvr_tf_point *p, size_t n)
{
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, p, n, 1.0, &err), err);
    return tf;
}

static cdvr_shading diffuse_only(void)
{
    cdvr_shading sh;
    cdvr_shading_default(&sh);
    sh.ambient = 0.0;
    sh.diffuse = 1.0;
    sh.specular = 0.0;
    return sh;
}

/* The ray through pixel (x, y) passes at distance rho from the centre (in voxels). */
static double pixel_rho(const cdvr_camera *cam, int x, int y)
{
    double o[3], d[3], c = (N - 1) / 2.0;
    cdvr_camera_ray(cam, x, y, o, d);
    return sqrt((o[0] - c) * (o[0] - c) + (o[1] - c) * (o[1] - c));
}

static void test_iso_sphere(void)
{
    cdvr_volume *v = radial_ramp();
    cdvr_tf_point pts[2] = {{0, 1, 1, 1, 0}, {255, 1, 1, 1, 0}};
    cdvr_tf tf = tf_of(pts, 2);
    cdvr_camera cam = along_z();
    cdvr_render_opts o = {.tf = &tf, .camera = &cam};
    o.look.blend = CDVR_BLEND_ISO;
    o.look.iso_value = 255.0 - SLOPE * R;
    o.look.iso_color_set = 1;
    o.look.iso_color[0] = o.look.iso_color[1] = o.look.iso_color[2] = 1.0f;
    o.look.shade = diffuse_only();
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_render_cpu(v, 0, &o, &img, &err), err);
    double worst = 0.0;
    int missed = 0, extra = 0;
    for (int y = 0; img && y < N; y++)
        for (int x = 0; x < N; x++) {
            const float *px = cdvr_image_pixel(img, x, y);
            double rho = pixel_rho(&cam, x, y);
            missed += rho < R - 1 && px[3] != 1.0f;
            extra += rho > R + 1 && px[3] != 0.0f;
            if (rho < R - 2)
                worst = fmax(worst, fabs(px[0] - sqrt(1.0 - (rho / R) * (rho / R))));
        }
    CHECK(missed == 0 && extra == 0, "iso sphere: %d pixels inside R - 1 missed, %d beyond R + 1 hit",
          missed, extra);
    CHECK(worst < BOUND, "iso sphere: diffuse term off cos(angle) by %.4f (bound %.4f)", worst, BOUND);
    printf("iso sphere: diffuse term within %.4f of cos(angle) (bound %.4f)\n", worst, BOUND);
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

static void test_composite_sphere(void)
{
    cdvr_volume *v = radial_ramp();
    cdvr_tf_point pts[4] = {{0, 1, 1, 1, 0}, {76, 1, 1, 1, 0}, {77, 1, 1, 1, 1}, {255, 1, 1, 1, 1}};
    cdvr_tf tf = tf_of(pts, 4);
    cdvr_camera cam = along_z();
    cdvr_render_opts o = {.tf = &tf, .camera = &cam, .step = 0.25};
    o.look.shade = diffuse_only();
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_render_cpu(v, 0, &o, &img, &err), err);
    double worst = 0.0;
    for (int y = 0; img && y < N; y++)
        for (int x = 0; x < N; x++) {
            double rho = pixel_rho(&cam, x, y);
            if (rho < R - 2)
                worst = fmax(worst, fabs(cdvr_image_pixel(img, x, y)[0] -
                                         sqrt(1.0 - (rho / R) * (rho / R))));
        }
    CHECK(worst < BOUND + 0.25 / R, "composite sphere: diffuse term off cos(angle) by %.4f", worst);
    printf("composite sphere: diffuse term within %.4f of cos(angle) (bound %.4f)\n", worst,
           BOUND + 0.25 / R);
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

/* A ramp along index x (4 x) with D rotating index x onto world y; an iso plane of code 100. */
static void test_direction(void)
{
    size_t dims[3] = {40, 16, 16};
    cdvr_volume *v;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return;
    for (size_t i = 0; i < 40 * 16 * 16; i++)
        ((uint8_t *)v->data)[i] = (uint8_t)(4 * (i % 40));
    double D[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1}; /* column 0 (index x) = world (0, 1, 0) */
    memcpy(v->direction, D, sizeof D);
    cdvr_tf_point pts[2] = {{0, 1, 1, 1, 0}, {255, 1, 1, 1, 0}};
    cdvr_tf tf = tf_of(pts, 2);
    cdvr_camera cam;
    memset(&cam, 0, sizeof cam);
    /* world box: x in [-15, 0], y in [0, 39], z in [0, 15]; look along world -y from y = 80 */
    cam.center[0] = -7.5; cam.center[1] = 20; cam.center[2] = 7.5;
    cam.eye[0] = -7.5; cam.eye[1] = 80; cam.eye[2] = 7.5;
    cam.up[2] = 1;
    cam.fov = 20;
    cam.width = cam.height = 16;
    for (int k = 0; k < 2; k++) {
        cdvr_render_opts o = {.tf = &tf, .camera = &cam};
        o.look.blend = CDVR_BLEND_ISO;
        o.look.iso_value = 100;
        o.look.iso_color_set = 1;
        o.look.iso_color[0] = o.look.iso_color[1] = o.look.iso_color[2] = 1.0f;
        o.look.shade = diffuse_only();
        o.look.shade.light_fixed = 1;
        o.look.shade.light_dir[k == 0 ? 1 : 0] = k == 0 ? -1.0 : 1.0;
        cdvr_image *img = NULL;
        CHECK_OK(cdvr_render_cpu(v, 0, &o, &img, &err), err);
        if (!img)
            continue;
        const float *c = cdvr_image_pixel(img, 8, 8);
        double want = k == 0 ? 1.0 : 0.0;
        CHECK(c[3] == 1.0f && fabs(c[0] - want) < 1e-3,
              "rotated ramp, light along %s: pixel %.4f alpha %.2f, expected %.1f",
              k == 0 ? "-y" : "+x", c[0], c[3], want);
        cdvr_image_free(img);
    }
    cdvr_volume_free(v);
}

static void test_slab_extremes(void)
{
    size_t dims[3] = {16, 16, 24};
    cdvr_volume *v;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return;
    for (size_t z = 0; z < 24; z++)
        memset((uint8_t *)v->data + z * 256, z >= 8 && z <= 15 ? 200 : 30, 256);
    cdvr_tf_point pts[3] = {{0, 0, 0, 0, 0}, {100, 0.2, 0.6, 1.0, 0.3}, {255, 1.0, 0.5, 0.25, 0.9}};
    cdvr_tf tf = tf_of(pts, 3);
    cdvr_camera cam;
    memset(&cam, 0, sizeof cam);
    cam.center[0] = cam.center[1] = 7.5;
    cam.center[2] = 11.5;
    cam.eye[0] = cam.eye[1] = 7.5;
    cam.eye[2] = -60;
    cam.up[1] = 1;
    cam.orthographic = 1;
    cam.ortho_height = 12;
    cam.fov = 30;
    cam.width = cam.height = 12;
    int modes[2] = {CDVR_BLEND_MAX, CDVR_BLEND_MIN}, codes[2] = {200, 30};
    for (int k = 0; k < 2; k++) {
        cdvr_render_opts o = {.tf = &tf, .camera = &cam};
        o.look.blend = modes[k];
        cdvr_image *img = NULL;
        CHECK_OK(cdvr_render_cpu(v, 0, &o, &img, &err), err);
        const float *e = tf.table[codes[k]];
        int wrong = 0;
        for (int i = 0; img && i < 12 * 12; i++) {
            const float *p = img->rgba + 4 * i;
            wrong += p[3] != e[3] || p[0] != e[0] * e[3] || p[1] != e[1] * e[3] || p[2] != e[2] * e[3];
        }
        CHECK(img && wrong == 0, "%s slab: %d pixels differ from the TF at %d", cdvr_blend_name(modes[k]),
              wrong, codes[k]);
        cdvr_image_free(img);
    }
    memset(v->data, 77, 16 * 16 * 24);
    cdvr_render_opts o = {.tf = &tf, .camera = &cam};
    o.look.blend = CDVR_BLEND_AVERAGE;
    cdvr_image *img = NULL;
    CHECK_OK(cdvr_render_cpu(v, 0, &o, &img, &err), err);
    const float *e = tf.table[77];
    CHECK(img && img->rgba[3] == e[3] && img->rgba[0] == e[0] * e[3], "average of a constant 77");
    cdvr_image_free(img);

    /* a constant volume, shaded: zero gradients, finite pixels, ambient only */
    o.look.blend = CDVR_BLEND_COMPOSITE;
    cdvr_shading_default(&o.look.shade);
    CHECK_OK(cdvr_render_cpu(v, 0, &o, &img, &err), err);
    int finite = 1;
    for (int i = 0; img && i < 4 * 12 * 12; i++)
        finite &= isfinite(img->rgba[i]);
    CHECK(img && finite && img->rgba[3] > 0.5f, "constant volume shaded: finite pixels");
    if (img) {
        double expect = e[0] * CDVR_SHADE_AMBIENT, got = img->rgba[0] / img->rgba[3];
        CHECK(fabs(got - expect) < 1e-5, "zero gradient: ambient term only (%g, expected %g)", got, expect);
    }
    cdvr_image_free(img);
    /* gradient opacity 0 everywhere: nothing left */
    o.look.shade.enabled = 0;
    o.look.gradient_opacity.npoints = 1;
    o.look.gradient_opacity.magnitude[0] = 0;
    o.look.gradient_opacity.factor[0] = 0;
    CHECK_OK(cdvr_render_cpu(v, 0, &o, &img, &err), err);
    CHECK(img && img->rgba[3] == 0.0f, "gradient opacity 0: empty image (alpha %g)", img ? img->rgba[3] : -1);
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

static void refused(cdvr_render_opts *o, const cdvr_volume *v, const char *needle)
{
    cdvr_image *img = NULL;
    cdvr_error err;
    cdvr_error_clear(&err);
    cdvr_status s = cdvr_render_cpu(v, 0, o, &img, &err);
    CHECK(s != CDVR_OK && !img && strstr(err.msg, needle), "refused with '%s': got %d '%s'", needle,
          (int)s, err.msg);
    cdvr_image_free(img);
}

static void test_refusals(void)
{
    cdvr_volume *v = radial_ramp();
    cdvr_tf_point pts[2] = {{0, 1, 1, 1, 0}, {255, 1, 1, 1, 1}};
    cdvr_tf tf = tf_of(pts, 2);
    cdvr_camera cam = along_z();
    cdvr_render_opts o = {.tf = &tf, .camera = &cam};
    o.look.blend = 9;
    refused(&o, v, "unknown blend mode 9");
    o.look.blend = CDVR_BLEND_COMPOSITE;
    cdvr_shading_default(&o.look.shade);
    o.look.shade.light_fixed = 1;
    refused(&o, v, "light dir (0, 0, 0)");
    o.look.shade.light_fixed = 0;
    o.look.shade.ambient = -1;
    refused(&o, v, "ambient -1");
    o.look.shade.enabled = 0;
    o.look.gradient_opacity.npoints = 2;
    o.look.gradient_opacity.magnitude[0] = 5;
    o.look.gradient_opacity.magnitude[1] = 1;
    refused(&o, v, "sorted by magnitude");
    o.look.gradient_opacity.npoints = 0;
    cdvr_render_clip clip = {{N, N, N}, {0, 0, 0}, {0, 0, 0}, {N - 1, N - 1, N - 1}};
    o.clip = &clip;
    o.look.blend = CDVR_BLEND_MAX;
    refused(&o, v, "cannot be rendered in boxes");
    cdvr_volume_free(v);
}

/* A perspective camera (z up) on `centre` from centre + dir * ext per axis, size^2 pixels. */
static cdvr_camera oblique_camera(const double centre[3], const double ext[3],
                                  const double dir[3], double fov, int size)
{
    cdvr_camera cam;
    memset(&cam, 0, sizeof cam);
    for (int a = 0; a < 3; a++) {
        cam.center[a] = centre[a];
        cam.eye[a] = centre[a] + dir[a] * ext[a];
    }
    cam.up[2] = 1;
    cam.fov = fov;
    cam.width = cam.height = size;
    return cam;
}

/* Min on the device against the CPU where bricks with a 0 among non-zero voxels sit beside
 * bricks of zeros: a 40^3 volume of 100 with single zeros on a lattice and a slab of zeros
 * (z < 8), seen from above at a slant (some rays cross the slab, some leave before it). The
 * device takes the samples in a brick of one code as that code without reading them
 * (raycast.cl, extreme_step's flat bricks):
 * the images must agree within float rounding (a 0 taken where the brick only holds one: 9 dB),
 * min, max and average (which skips those bricks). */
static void test_cl_zero_bricks(cdvr_render_ctx *ctx)
{
    enum { M = 40 };
    size_t dims[3] = {M, M, M};
    cdvr_volume *v;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err) != CDVR_OK) {
        CHECK(0, "zero bricks volume: %s", err.msg);
        return;
    }
    uint8_t *d = v->data;
    for (size_t z = 0; z < M; z++)
        for (size_t y = 0; y < M; y++)
            for (size_t x = 0; x < M; x++)
                d[x + M * (y + M * z)] =
                    z < 8 || (x % 6 == 3 && y % 6 == 3 && z % 6 == 3) ? 0 : 100;
    cdvr_tf_point pts[3] = {{0, 1, 0, 0, 0.2}, {100, 0, 1, 0, 0.8}, {255, 0, 0, 1, 1}};
    cdvr_tf tf = tf_of(pts, 3);
    double c = (M - 1) / 2.0, centre[3] = {c, c, c}, ext[3] = {M, M, M};
    const double dir[3] = {1.2, -0.9, 1.6};
    cdvr_camera cam = oblique_camera(centre, ext, dir, 40, 96);
    const cdvr_render_method *ray = cdvr_render_method_find("raycast");
    cdvr_method_params p;
    cdvr_render_method_params_parse(ray, NULL, NULL, 0, &p, &err);
    for (int blend = CDVR_BLEND_MIN; blend <= CDVR_BLEND_AVERAGE; blend++) {
        cdvr_render_opts o = {.tf = &tf, .camera = &cam, .step = 0.5};
        o.look.blend = blend;
        cdvr_image *ref = NULL, *img = NULL;
        CHECK_OK(ray->render(ctx, CDVR_DEVICE_CPU, v, 0, &o, &p, NULL, &ref, &err), err);
        for (int rep = 0; rep < 2; rep++) { /* the second reads the tiled copy */
            cdvr_image_free(img);
            img = NULL;
            CHECK_OK(ray->render(ctx, CDVR_DEVICE_CL, v, 0, &o, &p, NULL, &img, &err), err);
        }
        if (!ref || !img) {
            cdvr_image_free(ref);
            cdvr_image_free(img);
            break;
        }
        cdvr_compare_result r;
        CHECK_OK(cdvr_compare_images(ref, img, &r, &err), err);
        size_t n = (size_t)cam.width * cam.height, zeros = 0, others = 0;
        for (size_t i = 0; i < n; i++) { /* pixels of min 0 (red) and of min > 0 (green) */
            zeros += ref->rgba[4 * i] > 0.1f && ref->rgba[4 * i + 1] < 0.05f;
            others += ref->rgba[4 * i + 1] > 0.1f;
        }
        if (blend == CDVR_BLEND_MIN) {
            CHECK(r.psnr >= 80.0, "zero bricks, min: cl against cpu %.2f dB", r.psnr);
            CHECK(zeros > n / 20 && others > n / 20, "zero bricks, min: %zu pixels of 0 and %zu "
                  "above of %zu (the scene must hold both)", zeros, others, n);
        } else {
            CHECK(r.psnr >= 80.0, "zero bricks, %s: cl against cpu %.2f dB",
                  cdvr_blend_name(blend), r.psnr);
        }
        cdvr_image_free(ref);
        cdvr_image_free(img);
    }
    cdvr_volume_free(v);
}

/* The OpenCL ray caster against the CPU in every mode. */
static void test_cl(void)
{
    cdvr_render_ctx *ctx;
    cdvr_error err;
    CHECK_OK(cdvr_render_ctx_create(&ctx, &err), err);
    if (!cdvr_render_ctx_has_cl(ctx)) {
        printf("no OpenCL device: cl checks skipped\n");
        cdvr_render_ctx_free(ctx);
        return;
    }
    test_cl_zero_bricks(ctx);
    const char *dir = check_shared_data(), *src = getenv("CDVR_SOURCE_DIR");
    char path[1024];
    if (dir)
        snprintf(path, sizeof path, "%s/ct/engine_256x256x128_u8.nrrd", dir);
    else
        snprintf(path, sizeof path, "%s/share/data/neghip_66x66x66_u8.nrrd", src ? src : "..");
    cdvr_volume *v;
    if (cdvr_volume_load(path, NULL, &v, &err) != CDVR_OK) {
        CHECK(0, "%s: %s", path, err.msg);
        cdvr_render_ctx_free(ctx);
        return;
    }
    cdvr_tf_point pts[4] = {{0, 0, 0, 0, 0}, {60, 0.3, 0.2, 0.1, 0.0}, {140, 0.9, 0.7, 0.5, 0.4},
                            {255, 1, 1, 0.9, 0.9}};
    cdvr_tf tf = tf_of(pts, 4);
    double ext[3], centre[3];
    for (int a = 0; a < 3; a++) {
        ext[a] = (double)(v->dims[a] - 1) * v->spacing[a];
        centre[a] = v->origin[a] + ext[a] / 2;
    }
    const double view[3] = {1.5, -1.8, 1.2};
    cdvr_camera cam = oblique_camera(centre, ext, view, 35, 128);
    const cdvr_render_method *ray = cdvr_render_method_find("raycast");
    cdvr_method_params p;
    cdvr_render_method_params_parse(ray, NULL, NULL, 0, &p, &err);
    /* "shade": power 10 by repeated squaring on both; "shade+light": specular 0.5, and
     * "shade, power 7.5": powf / pow (render.h) */
    const char *names[] = {"shade", "shade+light", "gradient opacity", "max", "min", "average",
                           "iso", "iso (tf colour, flat)", "shade, power 7.5"};
    for (int k = 0; k < 9; k++) {
        cdvr_look look;
        memset(&look, 0, sizeof look);
        cdvr_shading_default(&look.shade);
        look.shade.enabled = k <= 2 || k == 6 || k == 8;
        if (k == 8) {
            look.shade.specular = 0.6;
            look.shade.specular_power = 7.5;
        }
        if (k == 1) {
            look.shade.light_fixed = 1;
            look.shade.light_dir[0] = 1;
            look.shade.light_dir[1] = 0.5;
            look.shade.light_dir[2] = -1;
            look.shade.specular = 0.5;
        }
        if (k == 2) {
            look.gradient_opacity.npoints = 2;
            look.gradient_opacity.magnitude[1] = 20;
            look.gradient_opacity.factor[1] = 1;
        }
        look.blend = k == 3 ? CDVR_BLEND_MAX : k == 4 ? CDVR_BLEND_MIN : k == 5 ? CDVR_BLEND_AVERAGE
                   : k >= 6 ? CDVR_BLEND_ISO : CDVR_BLEND_COMPOSITE;
        look.iso_value = 120;
        look.iso_color_set = k == 6;
        look.iso_color[0] = 0.9f;
        look.iso_color[1] = 0.8f;
        look.iso_color[2] = 0.6f;
        cdvr_image *a = NULL, *b = NULL;
        cdvr_render_opts oa = {.tf = &tf, .camera = &cam, .look = look};
        cdvr_render_opts ob = oa;
        CHECK_OK(ray->render(ctx, CDVR_DEVICE_CPU, v, 0, &oa, &p, NULL, &a, &err), err);
        CHECK_OK(ray->render(ctx, CDVR_DEVICE_CL, v, 0, &ob, &p, NULL, &b, &err), err);
        if (a && b) {
            cdvr_compare_result r;
            CHECK_OK(cdvr_compare_images(a, b, &r, &err), err);
            CHECK(r.psnr >= 80.0, "%s: cl against cpu %.2f dB", names[k], r.psnr);
            printf("%s: cl against cpu %.2f dB\n", names[k], r.psnr);
        }
        cdvr_image_free(a);
        cdvr_image_free(b);
    }
    cdvr_volume_free(v);
    cdvr_render_ctx_free(ctx);
}

int main(void)
{
    test_iso_sphere();
    test_composite_sphere();
    test_direction();
    test_slab_extremes();
    test_refusals();
    test_cl();
    return check_finish();
}
