/* tests/test_gl_slice.c - 2D-texture slicing through EGL (cdvr/gl.h) against the CPU reference
 * ray caster: an analytic constant box, synthetic and real volumes at matched sampling (ray
 * step = slice spacing, no early termination), the level of detail (fewer texture bytes, image
 * close to the full-resolution slicing), texture reuse, direction matrices, cancellation and bad
 * input. Skips (77) only when no EGL context can be created (or the build has no GL). */
#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>

#include "cdvr/compare.h"
#include "cdvr/gl.h"
#include "cdvr/render.h"
#include "check.h"

static cdvr_tf make_tf(const cdvr_tf_point *p, size_t n)
{
    cdvr_tf tf;
    cdvr_error err;
    cdvr_status st = cdvr_tf_init(&tf, p, n, 0.0, &err);
    CHECK_OK(st, err);
    return tf;
}

static cdvr_camera look(double ex, double ey, double ez, const cdvr_volume *v, int size)
{
    cdvr_camera cam;
    memset(&cam, 0, sizeof cam);
    for (int a = 0; a < 3; a++)
        cam.center[a] = v->origin[a] + 0.5 * (double)(v->dims[a] - 1) * v->spacing[a];
    cam.eye[0] = cam.center[0] + ex;
    cam.eye[1] = cam.center[1] + ey;
    cam.eye[2] = cam.center[2] + ez;
    cam.up[fabs(ez) > fabs(ey) ? 1 : 2] = 1.0;
    cam.fov = 40.0;
    cam.width = cam.height = size;
    return cam;
}

/* PSNR of slicing (lod as given) against the ray caster at step = slice spacing, term off. */
static double slice_vs_ray(cdvr_gl *gl, const cdvr_volume *v, const cdvr_tf *tf,
                           const cdvr_camera *cam, int lod, cdvr_slice_stats *stats)
{
    cdvr_grid g;
    cdvr_grid_of_volume(v, &g);
    cdvr_render_opts o = {0};
    o.tf = tf;
    o.camera = cam;
    o.step = v->spacing[cdvr_slice_axis(&g, cam)];
    o.term_alpha = 1.0;
    cdvr_image *ray = NULL, *sl = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_render_cpu(v, 0, &o, &ray, &err);
    CHECK_OK(st, err);
    st = cdvr_gl_slice(gl, v, 0, &o, lod, stats, &sl, &err);
    CHECK_OK(st, err);
    cdvr_compare_result r = {0, 0, 0};
    if (ray && sl)
        CHECK_OK(cdvr_compare_images(ray, sl, &r, &err), err);
    cdvr_image_free(ray);
    cdvr_image_free(sl);
    return r.psnr;
}

/* A constant box seen along z (orthographic): every pixel's alpha is 1 - (1 - a)^(L/unit) with
 * L = (n - 1) * spacing, the ray caster's analytic case. */
static void test_constant_box(cdvr_gl *gl)
{
    size_t dims[3] = {9, 7, 21};
    cdvr_volume *v;
    CHECK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, NULL) == CDVR_OK, "create");
    memset(v->data, 100, cdvr_volume_frame_bytes(v));
    v->spacing[2] = 0.5;
    cdvr_tf_point p[2] = {{0, 1, 0.5, 0.25, 0.1}, {255, 1, 0.5, 0.25, 0.1}};
    cdvr_tf tf = make_tf(p, 2);
    cdvr_camera cam = look(0, 0, -30, v, 32);
    cam.orthographic = 1;
    cam.ortho_height = 20.0; /* the 8 x 6 box fills the middle of the 32 x 32 image */
    cdvr_render_opts o = {0};
    o.tf = &tf;
    o.camera = &cam;
    cdvr_image *img = NULL;
    cdvr_error err;
    cdvr_slice_stats stats;
    cdvr_status st = cdvr_gl_slice(gl, v, 0, &o, 1, &stats, &img, &err);
    CHECK_OK(st, err);
    if (img) {
        double expect = 1.0 - pow(0.9, 10.0 / 0.5); /* L = 20 * 0.5, unit = min spacing 0.5 */
        const float *c = cdvr_image_pixel(img, 18, 15);
        CHECK(fabs(c[3] - expect) < 1e-4, "box alpha %g, expected %g", c[3], expect);
        CHECK(fabs(c[0] - expect) < 1e-4 && fabs(c[1] - 0.5 * expect) < 1e-4,
              "premultiplied colour %g %g", c[0], c[1]);
        CHECK(cdvr_image_pixel(img, 0, 0)[3] == 0.0f, "outside the box stays clear");
        CHECK(stats.axis == 2 && stats.slices == 21 && stats.texture_bytes == 9 * 7 * 21 &&
                  stats.max_level == 0,
              "stats axis %d slices %zu bytes %llu (orthographic: no LOD)", stats.axis,
              stats.slices, (unsigned long long)stats.texture_bytes);
    }
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

/* Eye inside a constant box with a wide view: every ray's alpha is 1 - (1 - a)^(L/unit) with L
 * its path from the eye to the box, also for rays nearly parallel to the slices that leave
 * through a side face (the slabs are clipped to the box and the eye). */
static void test_inside_box(cdvr_gl *gl)
{
    size_t dims[3] = {40, 33, 27};
    cdvr_volume *v;
    CHECK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, NULL) == CDVR_OK, "create");
    memset(v->data, 128, cdvr_volume_frame_bytes(v));
    cdvr_tf_point p[2] = {{0, 1, 1, 1, 0.02}, {255, 1, 1, 1, 0.02}};
    cdvr_tf tf = make_tf(p, 2);
    cdvr_camera cam = look(2, 3, -4, v, 48);
    cam.fov = 90;
    cdvr_render_opts o = {0};
    o.tf = &tf;
    o.camera = &cam;
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_gl_slice(gl, v, 0, &o, 1, NULL, &img, &err), err);
    double worst = 0.0;
    for (int y = 0; img && y < 48; y += 3)
        for (int x = 0; x < 48; x += 3) {
            double org[3], d[3], t_exit = INFINITY;
            cdvr_camera_ray(&cam, x, y, org, d);
            for (int a = 0; a < 3; a++)
                if (fabs(d[a]) > 1e-12)
                    t_exit = fmin(t_exit, ((d[a] > 0 ? (double)(dims[a] - 1) : 0.0) - org[a]) / d[a]);
            double expect = 1.0 - pow(0.98, t_exit);
            worst = fmax(worst, fabs(cdvr_image_pixel(img, x, y)[3] - expect));
        }
    CHECK(img && worst < 2e-4, "eye inside a constant box: worst alpha error %g", worst);
    cdvr_image_free(img);
    cdvr_volume_free(v);
}

static void test_synthetic(cdvr_gl *gl)
{
    cdvr_generate_opts go;
    memset(&go, 0, sizeof go);
    go.dims[0] = 40;
    go.dims[1] = 33;
    go.dims[2] = 27;
    cdvr_volume *v;
    cdvr_error err;
    CHECK_OK(cdvr_volume_generate("ml", &go, &v, &err), err);
    v->spacing[0] = 1.0;
    v->spacing[1] = 1.2;
    v->spacing[2] = 1.5;
    cdvr_tf_point p[3] = {{0, 0, 0, 0, 0}, {128, 0.2, 0.5, 1, 0.05}, {255, 1, 0.9, 0.6, 0.4}};
    cdvr_tf tf = make_tf(p, 3);
    /* along each axis, oblique, orthographic, and with the eye inside the volume; the floors
     * are the figures measured with llvmpipe less 3 dB (Marschner-Lobb is the hard case for
     * slicing: one sample per slab along rays far from the axis) */
    const double views[][3] = {{0, 0, -90}, {0, 80, 5}, {-85, 3, 2}, {40, -50, 45}};
    const double floors[] = {40.0, 31.0, 34.0, 33.0};
    for (size_t i = 0; i < sizeof views / sizeof views[0]; i++) {
        cdvr_camera cam = look(views[i][0], views[i][1], views[i][2], v, 64);
        cdvr_slice_stats stats;
        double psnr = slice_vs_ray(gl, v, &tf, &cam, 0, &stats);
        printf("ml view %zu: %.2f dB\n", i, psnr);
        CHECK(psnr >= floors[i], "view %zu: slicing vs ray casting %.2f dB", i, psnr);
    }
    cdvr_camera ortho = look(30, -20, -60, v, 64);
    ortho.orthographic = 1;
    ortho.ortho_height = 60;
    double psnr = slice_vs_ray(gl, v, &tf, &ortho, 1, NULL);
    printf("ml orthographic: %.2f dB\n", psnr);
    CHECK(psnr >= 33.0, "orthographic: %.2f dB", psnr);
    cdvr_camera inside = look(2, 3, -4, v, 64);
    inside.fov = 90;
    psnr = slice_vs_ray(gl, v, &tf, &inside, 0, NULL);
    printf("ml eye inside, fov 90: %.2f dB\n", psnr);
    CHECK(psnr >= 25.0, "eye inside the volume: %.2f dB", psnr);
    cdvr_volume_free(v);
}

/* The same scene stored mirrored in x with direction diag(-1, 1, 1) renders the same image. */
static void test_direction(cdvr_gl *gl)
{
    cdvr_generate_opts go;
    memset(&go, 0, sizeof go);
    go.dims[0] = go.dims[1] = go.dims[2] = 24;
    cdvr_volume *a, *b;
    CHECK(cdvr_volume_generate("ml", &go, &a, NULL) == CDVR_OK, "ml");
    CHECK(cdvr_volume_generate("ml", &go, &b, NULL) == CDVR_OK, "ml");
    const uint8_t *src = a->data;
    uint8_t *dst = b->data;
    for (size_t z = 0; z < 24; z++)
        for (size_t y = 0; y < 24; y++)
            for (size_t x = 0; x < 24; x++)
                dst[x + 24 * (y + 24 * z)] = src[(23 - x) + 24 * (y + 24 * z)];
    b->direction[0] = -1.0;
    b->origin[0] = 23.0; /* index 0 of b is index 23 of a: the same world point */
    cdvr_tf_point p[2] = {{0, 0, 0, 0, 0}, {255, 1, 0.7, 0.3, 0.3}};
    cdvr_tf tf = make_tf(p, 2);
    cdvr_camera cam = look(-20, -35, 25, a, 48);
    cdvr_render_opts o = {0};
    o.tf = &tf;
    o.camera = &cam;
    cdvr_image *ia = NULL, *ib = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_gl_slice(gl, a, 0, &o, 0, NULL, &ia, &err), err);
    CHECK_OK(cdvr_gl_slice(gl, b, 0, &o, 0, NULL, &ib, &err), err);
    cdvr_compare_result r = {0, 0, 0};
    if (ia && ib)
        cdvr_compare_images(ia, ib, &r, &err);
    CHECK(r.psnr >= 60.0, "mirrored storage with direction diag(-1,1,1): %.2f dB", r.psnr);
    cdvr_image_free(ia);
    cdvr_image_free(ib);
    cdvr_volume_free(a);
    cdvr_volume_free(b);
}

/* Textures are reused for the same frame and camera, rebuilt when the voxels change. */
static void test_reuse_and_lod(cdvr_gl *gl)
{
    cdvr_generate_opts go;
    memset(&go, 0, sizeof go);
    go.dims[0] = go.dims[1] = go.dims[2] = 64;
    cdvr_volume *v;
    CHECK(cdvr_volume_generate("ml", &go, &v, NULL) == CDVR_OK, "ml");
    cdvr_tf_point p[2] = {{0, 0, 0, 0, 0}, {255, 1, 1, 1, 0.2}};
    cdvr_tf tf = make_tf(p, 2);
    cdvr_camera close = look(0, 3, -40, v, 64); /* 8 voxels before the first slice */
    close.fov = 90;
    cdvr_render_opts o = {0};
    o.tf = &tf;
    o.camera = &close;
    cdvr_slice_stats s1, s2, s3, full;
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_gl_slice(gl, v, 0, &o, 1, &s1, &img, &err), err);
    cdvr_image_free(img);
    CHECK(s1.texture_bytes < s1.full_bytes && s1.max_level >= 2 && s1.min_level == 0,
          "close view: %llu of %llu bytes, levels %d..%d",
          (unsigned long long)s1.texture_bytes, (unsigned long long)s1.full_bytes,
          s1.min_level, s1.max_level);
    CHECK_OK(cdvr_gl_slice(gl, v, 0, &o, 1, &s2, &img, &err), err);
    cdvr_image_free(img);
    CHECK(s2.uploaded_bytes == 0 && s2.texture_bytes == s1.texture_bytes,
          "same frame and camera: nothing uploaded (%llu)", (unsigned long long)s2.uploaded_bytes);
    CHECK_OK(cdvr_gl_slice(gl, v, 0, &o, 0, &full, &img, &err), err);
    cdvr_image_free(img);
    CHECK(full.texture_bytes == full.full_bytes && full.uploaded_bytes > 0 &&
              full.uploaded_bytes < full.full_bytes,
          "lod off: level 0 everywhere, only the coarser slices uploaded (%llu)",
          (unsigned long long)full.uploaded_bytes);
    ((uint8_t *)v->data)[1000] ^= 0x55; /* same dims and pointer, other voxels */
    CHECK_OK(cdvr_gl_slice(gl, v, 0, &o, 0, &s3, &img, &err), err);
    cdvr_image_free(img);
    CHECK(s3.uploaded_bytes == s3.full_bytes, "changed voxels: every slice rebuilt (%llu)",
          (unsigned long long)s3.uploaded_bytes);
    /* LOD image close to the full-resolution slicing, both close to the ray caster */
    double lod = slice_vs_ray(gl, v, &tf, &close, 1, NULL);
    double nolod = slice_vs_ray(gl, v, &tf, &close, 0, NULL);
    CHECK(nolod >= 38.0 && lod >= 28.0, "close view: %.2f dB without LOD, %.2f dB with", nolod,
          lod);
    cdvr_volume_free(v);
}

static void test_cancel_and_errors(cdvr_gl *gl)
{
    size_t dims[3] = {8, 8, 8};
    cdvr_volume *v, *f;
    CHECK(cdvr_volume_create(dims, 2, CDVR_TYPE_U8, &v, NULL) == CDVR_OK, "u8");
    CHECK(cdvr_volume_create(dims, 1, CDVR_TYPE_F32, &f, NULL) == CDVR_OK, "f32");
    cdvr_tf_point p[2] = {{0, 0, 0, 0, 0}, {255, 1, 1, 1, 1}};
    cdvr_tf tf = make_tf(p, 2);
    cdvr_camera cam = look(0, 0, -30, v, 16);
    atomic_int stop;
    atomic_init(&stop, 1);
    cdvr_render_opts o = {0};
    o.tf = &tf;
    o.camera = &cam;
    o.cancel = &stop;
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK(cdvr_gl_slice(gl, v, 0, &o, 1, NULL, &img, &err) == CDVR_ERR_CANCELLED && !img,
          "cancel flag: %s", err.msg);
    o.cancel = NULL;
    CHECK(cdvr_gl_slice(gl, v, 2, &o, 1, NULL, &img, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "timestep"),
          "timestep out of range: %s", err.msg);
    CHECK(cdvr_gl_slice(gl, f, 0, &o, 1, NULL, &img, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "f32"),
          "f32: %s", err.msg);
    cam.fov = 0;
    CHECK(cdvr_gl_slice(gl, v, 0, &o, 1, NULL, &img, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "fov"),
          "bad camera: %s", err.msg);
    cam.fov = 40;
    cam.eye[2] = cam.center[2] + 500; /* volume behind the camera: a clear image */
    cam.center[2] = cam.eye[2] + 10;
    CHECK(cdvr_gl_slice(gl, v, 1, &o, 1, NULL, &img, &err) == CDVR_OK && img &&
              cdvr_image_pixel(img, 8, 8)[3] == 0.0f,
          "volume behind the camera: %s", err.msg);
    cdvr_image_free(img);
    cdvr_volume_free(v);
    cdvr_volume_free(f);
}

/* Real volumes: the floors are the figures measured at these views minus a margin. */
static void test_real(cdvr_gl *gl)
{
    const char *dir = check_shared_data();
    if (!dir) {
        printf("CDVR_SHARED_DATA unset: real-volume checks skipped\n");
        return;
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/ct/engine_256x256x128_u8.nrrd", dir);
    cdvr_volume *engine;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load(path, NULL, &engine, &err);
    CHECK_OK(st, err);
    if (st != CDVR_OK)
        return;
    cdvr_tf_point bone[3] = {{0, 0, 0, 0, 0}, {100, 0.8, 0.6, 0.5, 0.0}, {255, 1, 1, 0.9, 0.6}};
    cdvr_tf tf = make_tf(bone, 3);
    cdvr_camera oblique = look(230, -300, 180, engine, 128);
    double psnr = slice_vs_ray(gl, engine, &tf, &oblique, 1, NULL);
    CHECK(psnr >= 32.0, "engine, oblique view: slicing vs ray casting %.2f dB", psnr);
    /* close view along z (D = half the z extent): the seed's LOD cuts 47% of the bytes */
    cdvr_camera close = look(0, 20, -63.5 - 0.75 * 63.5, engine, 128);
    close.fov = 90;
    cdvr_slice_stats lod, full;
    double lod_psnr = slice_vs_ray(gl, engine, &tf, &close, 1, &lod);
    double full_psnr = slice_vs_ray(gl, engine, &tf, &close, 0, &full);
    CHECK(full_psnr >= 34.0 && lod_psnr >= 30.0, "engine close: %.2f dB, with LOD %.2f dB",
          full_psnr, lod_psnr);
    CHECK(lod.texture_bytes < full.texture_bytes && full.texture_bytes == 256 * 256 * 128,
          "engine close: %llu bytes with LOD, %llu without",
          (unsigned long long)lod.texture_bytes, (unsigned long long)full.texture_bytes);
    printf("engine: oblique %.2f dB; close %.2f dB, LOD %.2f dB, bytes %llu / %llu\n", psnr,
           full_psnr, lod_psnr, (unsigned long long)lod.texture_bytes,
           (unsigned long long)full.texture_bytes);
    cdvr_volume_free(engine);
}

int main(void)
{
    cdvr_gl *gl;
    cdvr_error err;
    cdvr_status st = cdvr_gl_create(&gl, &err);
    if (st != CDVR_OK) {
        printf("skipped: %s\n", err.msg);
        return 77;
    }
    printf("renderer: %s\n", cdvr_gl_renderer(gl));
    test_constant_box(gl);
    test_inside_box(gl);
    test_synthetic(gl);
    test_direction(gl);
    test_reuse_and_lod(gl);
    test_cancel_and_errors(gl);
    test_real(gl);
    cdvr_gl_free(gl);
    return check_finish();
}
