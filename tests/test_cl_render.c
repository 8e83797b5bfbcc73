/* tests/test_cl_render.c - the ray-cast kernel against the CPU reference (cdvr_render_cpu):
 * image PSNR >= 50 dB for axis-parallel, 45-degree, inside-the-volume and orthographic views
 * on the engine CT and on synthetic volumes; empty-space skipping on vs off changes no pixel
 * by more than 0.5/255 and takes fewer samples (also over a sparse volume, where rays jump
 * over large empty regions, and over compact blobs, where rays start and stop at the box
 * around the visible bricks); without skipping the sample counts equal the CPU's; zero/full
 * opacity, tiny and huge steps; odd image sizes; oriented volumes (oblique, mirrored, sheared);
 * the voxel layouts (a frame's voxels, its tiled copy on a second render, 64-bit indices)
 * give the same pixels and samples, also on volumes one voxel thick in x or y; misuse errors. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/camera.h"
#include "cdvr/compare.h"
#include "cdvr/device.h"
#include "cdvr/render.h"
#include "cdvr/store.h"
#include "cdvr/tf.h"
#include "cdvr/volume.h"
#include "check.h"

#if CDVR_HAVE_OPENCL
#include "render/cl/cl_internal.h" /* the stream's host copy of its min/max grid */

#define IMAGE_SIZE 128

typedef struct scene {
    const cdvr_volume *vol;
    cdvr_cl_stream *stream;
    cdvr_tf tf;
    cdvr_camera cam;
    double step;
    const char *name;
} scene;

static void make_tf(cdvr_tf *tf, const cdvr_tf_point *pts, size_t n)
{
    cdvr_error err;
    cdvr_status st = cdvr_tf_init(tf, pts, n, 0.0, &err);
    CHECK_OK(st, err);
}

static cdvr_status upload_volume(cdvr_cl *cl, const cdvr_volume *vol, cdvr_cl_stream **out,
                                 cdvr_error *err)
{
    cdvr_status st = cdvr_cl_stream_create(cl, vol->dims, out, err);
    if (!st)
        st = cdvr_cl_upload_frames(*out, vol->data, 1, err);
    return st;
}

/* An image of NaN pixels (cdvr_image_create_unset, then filled): a render into it must write
 * every pixel, or the comparisons below fail. */
static cdvr_status nan_image(int width, int height, cdvr_image **out, cdvr_error *err)
{
    cdvr_status st = cdvr_image_create_unset(width, height, out, err);
    for (size_t i = 0; !st && i < 4 * (size_t)width * (size_t)height; i++)
        (*out)->rgba[i] = NAN;
    return st;
}

/* Pixels of img that still hold a NaN. */
static size_t unwritten(const cdvr_image *img)
{
    size_t n = 0, pixels = (size_t)img->width * (size_t)img->height;
    for (size_t i = 0; i < pixels; i++)
        n += isnan(img->rgba[4 * i]) || isnan(img->rgba[4 * i + 1]) ||
             isnan(img->rgba[4 * i + 2]) || isnan(img->rgba[4 * i + 3]);
    return n;
}

/* Renders sc on the device into an image of NaNs; NULL on failure (recorded). */
static cdvr_image *render_cl(const scene *sc, int skipping, uint64_t *samples)
{
    cdvr_error err;
    cdvr_image *img = NULL;
    cdvr_render_opts opts = {.tf = &sc->tf, .camera = &sc->cam, .step = sc->step};
    cdvr_cl_set_skipping(sc->stream, skipping);
    cdvr_status st = nan_image(sc->cam.width, sc->cam.height, &img, &err);
    if (!st)
        st = cdvr_cl_setup(sc->stream, 0, &sc->tf, &err);
    if (!st)
        st = cdvr_cl_render(sc->stream, 0, &opts, sc->vol->spacing, sc->vol->origin, sc->vol->direction, img, &err);
    CHECK(st == CDVR_OK, "%s: cl render: %s", sc->name, err.msg);
    if (st) {
        cdvr_image_free(img);
        return NULL;
    }
    *samples = cdvr_cl_last_samples(sc->stream);
    CHECK(unwritten(img) == 0, "%s: %zu pixels not written (skipping %d)", sc->name,
          unwritten(img), skipping);
    return img;
}

static double compare(const cdvr_image *a, const cdvr_image *b, double *maxerr)
{
    cdvr_compare_result res;
    cdvr_error err;
    cdvr_status st = cdvr_compare_images(a, b, &res, &err);
    CHECK_OK(st, err);
    *maxerr = res.maxerr;
    return res.psnr;
}

/* Device (skipping on and off) against the CPU reference. Returns the CPU image's mean alpha
 * so callers can make sure the scene is not empty. */
static double check_scene(const scene *sc)
{
    cdvr_error err;
    cdvr_image *ref = NULL;
    cdvr_render_opts opts = {.tf = &sc->tf, .camera = &sc->cam, .step = sc->step};
    cdvr_status st = cdvr_render_cpu(sc->vol, 0, &opts, &ref, &err);
    CHECK_OK(st, err);
    uint64_t on_samples = 0, off_samples = 0;
    cdvr_image *on = render_cl(sc, 1, &on_samples), *off = render_cl(sc, 0, &off_samples);
    double mean_alpha = 0, maxerr = 0;
    if (ref && on && off) {
        double psnr = compare(on, ref, &maxerr);
        printf("%-28s psnr %6.1f dB  maxerr %.3f  samples cpu %llu cl %llu (skip off %llu)\n",
               sc->name, psnr, maxerr, (unsigned long long)opts.samples,
               (unsigned long long)on_samples, (unsigned long long)off_samples);
        CHECK(psnr >= 50.0, "%s: device vs cpu PSNR %.2f dB < 50", sc->name, psnr);
        compare(on, off, &maxerr);
        CHECK(maxerr <= 0.5, "%s: skipping on/off differ by %.3f/255", sc->name, maxerr);
        CHECK(on_samples <= off_samples, "%s: skipping took more samples", sc->name);
        CHECK(off_samples == opts.samples, "%s: %llu samples without skipping, cpu %llu",
              sc->name, (unsigned long long)off_samples, (unsigned long long)opts.samples);
        for (int i = 0; i < ref->width * ref->height; i++)
            mean_alpha += ref->rgba[4 * i + 3];
        mean_alpha /= ref->width * ref->height;
    }
    cdvr_image_free(ref);
    cdvr_image_free(on);
    cdvr_image_free(off);
    return mean_alpha;
}

static void look(cdvr_camera *cam, const double eye[3], const double center[3], const double up[3])
{
    memset(cam, 0, sizeof *cam);
    memcpy(cam->eye, eye, sizeof cam->eye);
    memcpy(cam->center, center, sizeof cam->center);
    memcpy(cam->up, up, sizeof cam->up);
    cam->fov = 30;
    cam->width = cam->height = IMAGE_SIZE;
}

static void volume_centre(const cdvr_volume *vol, double c[3], double *extent)
{
    *extent = 0;
    for (int a = 0; a < 3; a++) {
        double len = (double)(vol->dims[a] - 1) * vol->spacing[a];
        c[a] = vol->origin[a] + 0.5 * len;
        *extent = fmax(*extent, len);
    }
}

static void engine_scenes(cdvr_cl *cl, const char *data)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/ct/engine_256x256x128_u8.nrrd", data);
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load_nrrd(path, &vol, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    scene sc = {.vol = vol, .step = 0};
    st = upload_volume(cl, vol, &sc.stream, &err);
    CHECK_OK(st, err);
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {70, 0, 0, 0, 0}, {110, .9, .6, .3, .05},
                                 {200, 1, 1, .9, .4}, {255, 1, 1, 1, .9}};
    make_tf(&sc.tf, pts, sizeof pts / sizeof *pts);
    double c[3], ext, up[3] = {0, 0, 1};
    volume_centre(vol, c, &ext);
    if (!st) {
        double eye[3] = {c[0], c[1] - 2.5 * ext, c[2]};
        look(&sc.cam, eye, c, up);
        sc.name = "engine axis-parallel";
        CHECK(check_scene(&sc) > 0.05, "engine axis view is empty");
        cdvr_camera_orbit(&sc.cam, c, up, 2.5 * ext, 45, 45);
        sc.name = "engine 45 degrees";
        CHECK(check_scene(&sc) > 0.05, "engine 45 view is empty");
        double inside[3] = {c[0] + 10, c[1] - 20, c[2] + 5};
        look(&sc.cam, inside, c, up);
        sc.cam.fov = 70;
        sc.name = "engine camera inside";
        CHECK(check_scene(&sc) > 0.05, "engine inside view is empty");
        look(&sc.cam, eye, c, up);
        sc.cam.orthographic = 1;
        sc.cam.ortho_height = 1.1 * ext;
        sc.name = "engine orthographic axis";
        CHECK(check_scene(&sc) > 0.05, "engine orthographic view is empty");
        size_t visible, total;
        cdvr_cl_brick_counts(sc.stream, &visible, &total);
        CHECK(visible > 0 && visible < total, "engine bricks visible %zu of %zu", visible, total);
    }
    cdvr_cl_stream_free(sc.stream);
    cdvr_volume_free(vol);
}

/* The ray caster's voxel layouts give the same image: the first render reads the frame's
 * voxels (layout 0), a render of the same frame again reads its tiled copy and its quad copy
 * (layout 1, CDVR_CL_QUADS=1: the stream grows by 5 bytes per voxel, in whole pages; layout 2:
 * the device's default), and 64-bit voxel indices (CDVR_CL_LONG_INDEX=1, layout 3) read the
 * voxels too; so do the copies without the gradient copy (CDVR_CL_GRADS=0, layout 4) and the
 * tiled copy without the quad copy (CDVR_CL_QUADS=0, layout 5). A render that shades takes its
 * gradients from the gradient copy (4 bytes more per voxel of the tiled copy) in layouts 1, 2
 * and 5: the same image within float rounding (>= 120 dB; a wrong difference or weight costs
 * far more). */
static void check_layouts_look(cdvr_cl *cl, const cdvr_volume *vol, const scene *sc,
                               const cdvr_look *look, const char *look_name)
{
    enum { LAYOUTS = 6 };
    cdvr_error err;
    cdvr_image *img[LAYOUTS] = {NULL};
    uint64_t samples[LAYOUTS] = {0}, bytes[2] = {0, 0};
    cdvr_render_opts opts = {.tf = &sc->tf, .camera = &sc->cam, .step = sc->step, .look = *look};
    size_t n = (size_t)sc->cam.width * (size_t)sc->cam.height;
    int grads = look->shade.enabled || look->gradient_opacity.npoints > 0;
    for (int k = 0; k < LAYOUTS; k++) {
        if (k == 1)
            setenv("CDVR_CL_QUADS", "1", 1);
        if (k == 3)
            setenv("CDVR_CL_LONG_INDEX", "1", 1);
        if (k == 4)
            setenv("CDVR_CL_GRADS", "0", 1);
        if (k == 5)
            setenv("CDVR_CL_QUADS", "0", 1);
        cdvr_cl_stream *s = NULL;
        cdvr_status st = upload_volume(cl, vol, &s, &err);
        for (int rep = 0; !st && rep <= (k < 3 ? k : 1); rep++) {
            cdvr_image_free(img[k]);
            img[k] = NULL;
            st = nan_image(sc->cam.width, sc->cam.height, &img[k], &err);
            if (!st)
                st = cdvr_cl_setup(s, 0, &sc->tf, &err);
            if (!st)
                st = cdvr_cl_render(s, 0, &opts, vol->spacing, vol->origin, vol->direction,
                                    img[k], &err);
            if (!st && k == 1)
                bytes[rep] = cdvr_cl_stream_bytes(s);
        }
        CHECK(st == CDVR_OK, "%s, %s: layout %d: %s", sc->name, look_name, k, err.msg);
        CHECK(!img[k] || unwritten(img[k]) == 0, "%s, %s: layout %d: pixels not written",
              sc->name, look_name, k);
        samples[k] = s ? cdvr_cl_last_samples(s) : 0;
        cdvr_cl_stream_free(s);
        unsetenv("CDVR_CL_LONG_INDEX");
        unsetenv("CDVR_CL_GRADS");
        unsetenv("CDVR_CL_QUADS");
    }
    size_t tiled = 1; /* the copy fills whole pages of 16^3 (kernels/common/cl_shared.h) */
    for (int a = 0; a < 3; a++)
        tiled *= (vol->dims[a] + 15) / 16 * 16;
    size_t copies = tiled * (grads ? 9 : 5);
    CHECK(bytes[1] == bytes[0] + copies, "%s, %s: copies of %zu voxels (%zu in pages): stream "
          "%llu -> %llu bytes", sc->name, look_name, cdvr_volume_voxels(vol), tiled,
          (unsigned long long)bytes[0], (unsigned long long)bytes[1]);
    for (int k = 1; k < LAYOUTS; k++) {
        int same = img[0] && img[k] &&
                   memcmp(img[0]->rgba, img[k]->rgba, 4 * sizeof(float) * n) == 0;
        double maxerr = 0, psnr = same || !img[0] || !img[k] ? INFINITY
                                                             : compare(img[0], img[k], &maxerr);
        int copied = grads && (k == 1 || k == 2 || k == 5);
        CHECK((same || (copied && psnr >= 120.0)) && samples[k] == samples[0],
              "%s, %s: layout %d differs from the voxels' image (%.1f dB)", sc->name, look_name,
              k, psnr);
    }
    for (int k = 0; k < LAYOUTS; k++)
        cdvr_image_free(img[k]);
}

/* check_layouts_look for every blend mode, with shading and gradient opacity (the tiled
 * copy's gradient reads its 32 voxels from 12 tile rows, raycast.cl central_tiled; max, min
 * and average skip dull blocks of bricks). */
static void check_layouts(cdvr_cl *cl, const cdvr_volume *vol, const scene *sc)
{
    cdvr_look plain = {0}, shaded = {0}, go = {0}, max = {0}, min = {0}, avg = {0}, iso = {0};
    cdvr_shading_default(&shaded.shade);
    go.shade = shaded.shade;
    go.gradient_opacity.npoints = 2;
    go.gradient_opacity.magnitude[0] = 2;
    go.gradient_opacity.magnitude[1] = 40;
    go.gradient_opacity.factor[0] = 0.1;
    go.gradient_opacity.factor[1] = 1;
    max.blend = CDVR_BLEND_MAX;
    min.blend = CDVR_BLEND_MIN;
    avg.blend = CDVR_BLEND_AVERAGE;
    iso.blend = CDVR_BLEND_ISO;
    iso.iso_value = 140;
    iso.shade = shaded.shade;
    const struct { const cdvr_look *look; const char *name; } looks[] = {
        {&plain, "composite"}, {&shaded, "shaded"}, {&go, "gradient opacity"}, {&max, "max"},
        {&min, "min"}, {&avg, "average"}, {&iso, "iso shaded"}};
    for (size_t i = 0; i < sizeof looks / sizeof *looks; i++)
        check_layouts_look(cl, vol, sc, looks[i].look, looks[i].name);
}

static void synthetic_scenes(cdvr_cl *cl)
{
    cdvr_generate_opts gen = {{40, 33, 27}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_status st = cdvr_volume_generate("ml", &gen, &vol, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    vol->spacing[0] = 1.5;
    vol->spacing[2] = 0.7;
    vol->origin[1] = -3;
    scene sc = {.vol = vol};
    st = upload_volume(cl, vol, &sc.stream, &err);
    CHECK_OK(st, err);
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {120, 0, 0, 0, 0}, {160, .2, .7, 1, .2},
                                 {255, 1, .3, .1, .7}};
    make_tf(&sc.tf, pts, sizeof pts / sizeof *pts);
    double c[3], ext, up[3] = {0, 1, 0};
    volume_centre(vol, c, &ext);
    const struct { double az, el, step; const char *name; } views[] = {
        {0, 0, 0, "ml axis-parallel"}, {45, 30, 0, "ml 45 degrees"},
        {20, 10, 0.07, "ml tiny step"}, {60, -20, 6.0, "ml huge step"}};
    for (size_t i = 0; i < sizeof views / sizeof *views && !st; i++) {
        double zup[3] = {0, 0, 1};
        look(&sc.cam, c, c, up);
        cdvr_camera_orbit(&sc.cam, c, i == 0 ? up : zup, 2.2 * ext, views[i].az, views[i].el);
        sc.step = views[i].step;
        sc.name = views[i].name;
        CHECK(check_scene(&sc) > 0.02, "%s is empty", sc.name);
        check_layouts(cl, vol, &sc);
    }
    /* flat volumes: the copies' clamped neighbours along x, y and z */
    static const size_t flat[3][3] = {{1, 9, 7}, {8, 1, 6}, {9, 7, 1}};
    static const char *const flat_names[3] = {"flat in x", "flat in y", "flat in z"};
    for (int f = 0; f < 3; f++) {
        cdvr_generate_opts g2 = {{flat[f][0], flat[f][1], flat[f][2]}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
        cdvr_volume *thin = NULL;
        if (cdvr_volume_generate("ml", &g2, &thin, &err) == CDVR_OK) {
            scene ts = sc;
            double tc[3], te, tup[3] = {0, 0, 1};
            volume_centre(thin, tc, &te);
            look(&ts.cam, tc, tc, tup);
            cdvr_camera_orbit(&ts.cam, tc, tup, 3 * te + 5, 35 + 40 * f, 25);
            ts.step = 0.3;
            ts.name = flat_names[f];
            check_layouts(cl, thin, &ts);
        }
        cdvr_volume_free(thin);
    }
    /* zero opacity everywhere: nothing visible, every brick skipped */
    const cdvr_tf_point clear[] = {{0, 1, 1, 1, 0}, {255, 1, 1, 1, 0}};
    make_tf(&sc.tf, clear, 2);
    sc.step = 0;
    sc.name = "ml zero opacity";
    CHECK(check_scene(&sc) == 0.0, "zero opacity TF shows something");
    size_t visible = 1, total = 0;
    cdvr_cl_brick_counts(sc.stream, &visible, &total);
    size_t B = cdvr_cl_brick_edge();
    size_t expect = ((40 + B - 1) / B) * ((33 + B - 1) / B) * ((27 + B - 1) / B);
    CHECK(visible == 0 && total == expect, "zero opacity: %zu of %zu bricks visible (grid %zu)",
          visible, total, expect);
    const cdvr_tf_point opaque[] = {{0, .5, .5, .5, 1}, {255, 1, 1, 1, 1}};
    make_tf(&sc.tf, opaque, 2);
    sc.name = "ml full opacity";
    CHECK(check_scene(&sc) > 0.1, "full opacity TF shows nothing");
    cdvr_cl_stream_free(sc.stream);
    cdvr_volume_free(vol);
}

/* Oriented volumes (render.h step 0): an oblique, mirrored direction and a shear, perspective
 * and orthographic, against the CPU reference. */
static void oriented_scenes(cdvr_cl *cl)
{
    cdvr_generate_opts gen = {{37, 29, 21}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_status st = cdvr_volume_generate("ml", &gen, &vol, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    const double c30 = cos(M_PI / 6), s30 = sin(M_PI / 6);
    const double rotated[9] = {c30, -s30, 0, -s30, -c30, 0, 0, 0, 1}; /* rotation, y mirrored */
    const double sheared[9] = {1, 0.4, 0, 0, 1, 0, 0.2, 0, -1};
    vol->spacing[0] = 1.3;
    vol->spacing[2] = 2.1;
    vol->origin[0] = -40, vol->origin[1] = 17, vol->origin[2] = 5;
    scene sc = {.vol = vol};
    st = upload_volume(cl, vol, &sc.stream, &err);
    CHECK_OK(st, err);
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {110, 0, 0, 0, 0}, {170, .3, .8, 1, .25},
                                 {255, 1, .4, .1, .8}};
    make_tf(&sc.tf, pts, sizeof pts / sizeof *pts);
    const double *dirs[2] = {rotated, sheared};
    const char *names[2][2] = {{"oblique mirrored", "oblique mirrored ortho"},
                               {"sheared", "sheared ortho"}};
    for (int d = 0; d < 2 && !st; d++) {
        memcpy(vol->direction, dirs[d], sizeof vol->direction);
        double lo[3], hi[3], c[3], ext = 0, up[3] = {0, 0, 1};
        cdvr_volume_bounds(vol, lo, hi);
        for (int a = 0; a < 3; a++) {
            c[a] = 0.5 * (lo[a] + hi[a]);
            ext = fmax(ext, hi[a] - lo[a]);
        }
        for (int ortho = 0; ortho < 2; ortho++) {
            look(&sc.cam, c, c, up);
            cdvr_camera_orbit(&sc.cam, c, up, 2.2 * ext, 35 + 50 * ortho, 25);
            sc.cam.orthographic = ortho;
            sc.cam.ortho_height = 1.2 * ext;
            sc.name = names[d][ortho];
            CHECK(check_scene(&sc) > 0.02, "%s is empty", sc.name);
        }
    }
    cdvr_cl_stream_free(sc.stream);
    cdvr_volume_free(vol);
}

/* A few isolated bright voxels in an empty volume: rays jump over large empty cubes of bricks
 * (distance map) and must still land on every visible brick, from several directions. */
static void sparse_scenes(cdvr_cl *cl)
{
    size_t dims[3] = {61, 47, 53};
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_status st = cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &vol, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    const int points[][3] = {{30, 23, 26}, {3, 5, 7}, {57, 40, 50}, {12, 44, 31}, {48, 9, 14},
                             {31, 23, 26}, {0, 0, 0}, {60, 46, 52}, {22, 30, 45}};
    for (size_t i = 0; i < sizeof points / sizeof *points; i++)
        ((uint8_t *)vol->data)[points[i][0] + dims[0] * (points[i][1] + dims[1] * (size_t)points[i][2])] = 255;
    scene sc = {.vol = vol};
    st = upload_volume(cl, vol, &sc.stream, &err);
    CHECK_OK(st, err);
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {40, 0, 0, 0, 0}, {255, 1, .8, .2, 1}};
    make_tf(&sc.tf, pts, sizeof pts / sizeof *pts);
    double c[3], ext, up[3] = {0, 0, 1};
    volume_centre(vol, c, &ext);
    const struct { double az, el; } views[] = {{0, 0}, {33, 21}, {145, -38}, {260, 60}};
    for (size_t i = 0; i < sizeof views / sizeof *views && !st; i++) {
        look(&sc.cam, c, c, up);
        cdvr_camera_orbit(&sc.cam, c, up, 1.6 * ext, views[i].az, views[i].el);
        sc.name = "sparse points";
        CHECK(check_scene(&sc) > 0.0, "sparse view %zu is empty", i);
    }
    cdvr_cl_stream_free(sc.stream);
    cdvr_volume_free(vol);
}

/* Fills the voxel box [lo, hi] (inclusive) of vol with value. */
static void fill_box(cdvr_volume *vol, const size_t lo[3], const size_t hi[3], uint8_t value)
{
    for (size_t z = lo[2]; z <= hi[2]; z++)
        for (size_t y = lo[1]; y <= hi[1]; y++)
            for (size_t x = lo[0]; x <= hi[0]; x++)
                ((uint8_t *)vol->data)[x + vol->dims[0] * (y + vol->dims[1] * z)] = value;
}

/* Visible voxels in compact blocks: rays start and stop at the box around the visible bricks,
 * which lies inside the grid (faces at brick boundaries) or touches one of its faces (that
 * face at infinity). Odd image sizes leave packets of rays partly outside the image. */
static void blob_scenes(cdvr_cl *cl)
{
    size_t dims[3] = {61, 47, 53};
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_status st = cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &vol, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    vol->spacing[1] = 1.3;
    /* blocks filling whole bricks: the first and last samples inside the box are visible */
    const size_t lo[2][3] = {{20, 12, 28}, {0, 28, 8}}, hi[2][3] = {{31, 23, 35}, {7, 35, 15}};
    const uint8_t value[2] = {200, 120};
    const double view[][2] = {{0, 0}, {90, 0}, {37, 24}, {200, -65}};
    for (int blob = 0; blob < 2; blob++) {
        fill_box(vol, lo[blob], hi[blob], value[blob]);
        scene sc = {.vol = vol};
        st = upload_volume(cl, vol, &sc.stream, &err);
        CHECK_OK(st, err);
        const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {60, 0, 0, 0, 0}, {255, 1, .6, .3, .4}};
        make_tf(&sc.tf, pts, sizeof pts / sizeof *pts);
        double c[3], ext, up[3] = {0, 0, 1};
        volume_centre(vol, c, &ext);
        for (size_t i = 0; i < sizeof view / sizeof *view && !st; i++) {
            look(&sc.cam, c, c, up);
            cdvr_camera_orbit(&sc.cam, c, up, 1.8 * ext, view[i][0], view[i][1]);
            sc.cam.width = 101 - 2 * (int)i;
            sc.cam.height = 77 + (int)i;
            sc.name = blob ? "blob at a face" : "blob inside";
            CHECK(check_scene(&sc) > 0.005, "%s view %zu is empty", sc.name, i);
        }
        cdvr_cl_stream_free(sc.stream);
    }
    cdvr_volume_free(vol);
}

/* Renders `look` of sc's volume on a new stream of cl twice (the first render reads the
 * voxels, the second the tiled and quad copies) into out[0] and out[1], with their sample
 * counts; the images stay NULL on failure (recorded). */
static void render_look_twice(cdvr_cl *cl, const scene *sc, const cdvr_look *look,
                              cdvr_image *out[2], uint64_t samples[2])
{
    cdvr_error err;
    cdvr_cl_stream *s = NULL;
    cdvr_render_opts opts = {.tf = &sc->tf, .camera = &sc->cam, .step = sc->step, .look = *look};
    cdvr_status st = upload_volume(cl, sc->vol, &s, &err);
    for (int rep = 0; rep < 2; rep++) {
        out[rep] = NULL;
        samples[rep] = 0;
        if (!st)
            st = nan_image(sc->cam.width, sc->cam.height, &out[rep], &err);
        if (!st)
            st = cdvr_cl_setup(s, 0, &sc->tf, &err);
        if (!st)
            st = cdvr_cl_render(s, 0, &opts, sc->vol->spacing, sc->vol->origin,
                                sc->vol->direction, out[rep], &err);
        CHECK(st == CDVR_OK, "%s: render %d: %s", sc->name, rep, err.msg);
        if (st) {
            cdvr_image_free(out[rep]);
            out[rep] = NULL;
        } else {
            samples[rep] = cdvr_cl_last_samples(s);
            CHECK(unwritten(out[rep]) == 0, "%s: render %d: pixels not written", sc->name, rep);
        }
    }
    cdvr_cl_stream_free(s);
}

/* Average's leaps (raycast.cl, zero_leap): a packet skips the samples where all its rays lie
 * in cubes of zero bricks. Blocks of noise with gaps of zeros 2 to 14 voxels wide between
 * them, in a volume whose edges are not whole bricks, one block against three far faces;
 * images small enough that a packet's rays spread over more than a brick, and larger ones;
 * axis-parallel (rays still along two axes) and oblique views; whole and fractional steps.
 * With the leaps and without (CDVR_CL_LEAPS=0) the image must be the same bit for bit on the
 * voxels and on the copies, the leaps may only drop samples and must drop some, and the image
 * must match the CPU's within float rounding. */
static void average_leap_scenes(cdvr_cl *cl)
{
    size_t dims[3] = {61, 47, 53};
    cdvr_volume *vol;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &vol, &err) != CDVR_OK) {
        CHECK(0, "leaps volume: %s", err.msg);
        return;
    }
    const size_t lo[4][3] = {{5, 4, 3}, {23, 4, 3}, {39, 10, 10}, {58, 20, 40}};
    const size_t hi[4][3] = {{20, 40, 50}, {30, 40, 50}, {45, 30, 45}, {60, 46, 52}};
    uint32_t seed = 12345;
    for (int b = 0; b < 4; b++)
        for (size_t z = lo[b][2]; z <= hi[b][2]; z++)
            for (size_t y = lo[b][1]; y <= hi[b][1]; y++)
                for (size_t x = lo[b][0]; x <= hi[b][0]; x++) {
                    seed = seed * 1664525u + 1013904223u;
                    ((uint8_t *)vol->data)[x + dims[0] * (y + dims[1] * z)] =
                        (uint8_t)(1 + (seed >> 24) % 255);
                }
    vol->spacing[2] = 1.2;
    scene sc = {.vol = vol, .name = "average leaps"};
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {255, 1, .8, .4, 1}};
    make_tf(&sc.tf, pts, 2);
    cdvr_look avg = {0};
    avg.blend = CDVR_BLEND_AVERAGE;
    double c[3], ext, up[3] = {0, 0, 1};
    volume_centre(vol, c, &ext);
    const double views[][2] = {{0, 0}, {90, 0}, {33, 21}, {145, -38}, {260, 60}};
    const int sizes[][2] = {{23, 19}, {64, 64}, {128, 96}};
    const double steps[] = {0.5, 1.3};
    uint64_t with_leaps = 0, without = 0;
    for (size_t v = 0; v < sizeof views / sizeof *views; v++)
        for (size_t z = 0; z < sizeof sizes / sizeof *sizes; z++)
            for (size_t k = 0; k < sizeof steps / sizeof *steps; k++) {
                look(&sc.cam, c, c, up);
                cdvr_camera_orbit(&sc.cam, c, up, 1.7 * ext, views[v][0], views[v][1]);
                sc.cam.width = sizes[z][0];
                sc.cam.height = sizes[z][1];
                sc.step = steps[k];
                cdvr_image *on[2], *off[2], *ref = NULL;
                uint64_t n_on[2], n_off[2];
                render_look_twice(cl, &sc, &avg, on, n_on);
                setenv("CDVR_CL_LEAPS", "0", 1);
                render_look_twice(cl, &sc, &avg, off, n_off);
                unsetenv("CDVR_CL_LEAPS");
                size_t bytes = 4 * sizeof(float) * (size_t)sc.cam.width * sc.cam.height;
                for (int rep = 0; rep < 2; rep++) {
                    CHECK(on[rep] && off[rep] && !memcmp(on[rep]->rgba, off[rep]->rgba, bytes),
                          "leaps: view %zu, %dx%d, step %g, render %d: the image changed", v,
                          sc.cam.width, sc.cam.height, sc.step, rep);
                    CHECK(n_on[rep] <= n_off[rep], "leaps: view %zu, %dx%d, step %g, render %d: "
                          "%llu samples, %llu without", v, sc.cam.width, sc.cam.height, sc.step,
                          rep, (unsigned long long)n_on[rep], (unsigned long long)n_off[rep]);
                    with_leaps += n_on[rep];
                    without += n_off[rep];
                }
                cdvr_render_opts opts = {.tf = &sc.tf, .camera = &sc.cam, .step = sc.step,
                                         .look = avg};
                CHECK_OK(cdvr_render_cpu(vol, 0, &opts, &ref, &err), err);
                double maxerr = 0;
                if (ref && on[1]) {
                    double psnr = compare(on[1], ref, &maxerr);
                    CHECK(psnr >= 80.0, "leaps: view %zu, %dx%d, step %g: cl against cpu "
                          "%.1f dB", v, sc.cam.width, sc.cam.height, sc.step, psnr);
                }
                cdvr_image_free(ref);
                for (int rep = 0; rep < 2; rep++) {
                    cdvr_image_free(on[rep]);
                    cdvr_image_free(off[rep]);
                }
            }
    printf("average leaps: %llu samples read, %llu without the leaps\n",
           (unsigned long long)with_leaps, (unsigned long long)without);
    CHECK(with_leaps < without - without / 10, "leaps: %llu samples read, %llu without (the "
          "scenes must leave gaps to leap)", (unsigned long long)with_leaps,
          (unsigned long long)without);
    cdvr_volume_free(vol);
}

static void misuse(cdvr_cl *cl)
{
    size_t dims[3] = {8, 8, 8};
    cdvr_cl_stream *s;
    cdvr_error err;
    cdvr_image *img = NULL;
    cdvr_camera cam = {{0, -30, 4}, {4, 4, 4}, {0, 0, 1}, 30, 16, 16, 0, 0};
    cdvr_tf tf;
    const cdvr_tf_point pts[] = {{0, 1, 1, 1, .5}, {255, 1, 1, 1, .5}};
    make_tf(&tf, pts, 2);
    cdvr_render_opts opts = {.tf = &tf, .camera = &cam};
    double spacing[3] = {1, 1, 1}, origin[3] = {0, 0, 0};
    cdvr_status st = cdvr_cl_stream_create(cl, dims, &s, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    cdvr_image_create(16, 16, &img, &err);
    st = cdvr_cl_setup(s, 0, &tf, &err);
    CHECK(st == CDVR_ERR_ARG, "setup before decode: status %d", (int)st);
    st = cdvr_cl_render(s, 0, &opts, spacing, origin, NULL, img, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "setup"), "render before setup: %s", err.msg);
    uint8_t zeros[512] = {0};
    st = cdvr_cl_upload_frames(s, zeros, 1, &err);
    if (!st)
        st = cdvr_cl_setup(s, 0, &tf, &err);
    CHECK_OK(st, err);
    cam.width = 17;
    st = cdvr_cl_render(s, 0, &opts, spacing, origin, NULL, img, &err);
    CHECK(st == CDVR_ERR_ARG, "image/camera size mismatch: status %d", (int)st);
    cam.width = 16;
    spacing[1] = 0;
    st = cdvr_cl_render(s, 0, &opts, spacing, origin, NULL, img, &err);
    CHECK(st == CDVR_ERR_ARG, "zero spacing: status %d", (int)st);
    spacing[1] = 1;
    memcpy(cam.center, cam.eye, sizeof cam.eye);
    st = cdvr_cl_render(s, 0, &opts, spacing, origin, NULL, img, &err);
    CHECK(st == CDVR_ERR_ARG, "eye == center: status %d", (int)st);
    cdvr_image_free(img);
    cdvr_cl_stream_free(s);
}

static void minmax_grids_once(cdvr_cl *cl)
{
    static const size_t dims[][3] = {{37, 29, 23}, {64, 64, 64}, {9, 5, 4}, {1, 7, 3},
                                     {130, 66, 17}, {8, 8, 8}, {12, 5, 9}};
    cdvr_tf tf;
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {255, 1, 1, 1, 1}};
    make_tf(&tf, pts, 2);
    uint32_t seed = 12345;
    for (size_t k = 0; k < sizeof dims / sizeof dims[0]; k++) {
        const size_t *d = dims[k];
        size_t n = d[0] * d[1] * d[2];
        uint8_t *voxels = malloc(n);
        for (size_t i = 0; i < n; i++) {
            seed = seed * 1664525u + 1013904223u;
            voxels[i] = (i / 97) % 3 == 0 ? (uint8_t)(40 + (i / 97) % 7) : (uint8_t)(seed >> 24);
        }
        cdvr_cl_stream *s = NULL;
        cdvr_error err;
        cdvr_skip_grid host;
        cdvr_status st = cdvr_cl_stream_create(cl, d, &s, &err);
        if (!st)
            st = cdvr_cl_upload_frames(s, voxels, 1, &err);
        if (!st)
            st = cdvr_cl_setup(s, 0, &tf, &err);
        CHECK_OK(st, err);
        st = cdvr_skip_grid_init(&host, d, CDVR_CL_BRICK_SHIFT, &err);
        if (!st)
            st = cdvr_skip_minmax_from_frame(&host, voxels, &err);
        CHECK_OK(st, err);
        if (s && s->grid.minmax && host.minmax) {
            size_t differ = 0;
            for (size_t b = 0; b < 2 * host.nbricks; b++)
                differ += s->grid.minmax[b] != host.minmax[b];
            CHECK(differ == 0 && s->grid.nbricks == host.nbricks,
                  "%zux%zux%zu: %zu of %zu min/max bytes differ from the host's", d[0], d[1],
                  d[2], differ, 2 * host.nbricks);
        }
        cdvr_skip_grid_free(&host);
        cdvr_cl_stream_free(s);
        free(voxels);
    }
}

/* The device's brick min/max grid (bricks.cl, brick_minmax: a whole brick and its apron read
 * by rows, edge bricks voxel by voxel; on a CPU device by default the host's ranges of the
 * mapped frame, cl_render.c host_minmax, so the kernel runs with CDVR_CL_HOST_MINMAX=0) equals
 * the host's (cdvr_skip_minmax_from_frame, the definition) on noise with runs of constants, at
 * dims that leave partial bricks, rows too short for the row reads and volumes one brick or
 * one voxel thick. */
static void minmax_grids(cdvr_cl *cl)
{
    for (int kernel = 0; kernel < 2; kernel++) {
        if (kernel)
            setenv("CDVR_CL_HOST_MINMAX", "0", 1);
        minmax_grids_once(cl);
        unsetenv("CDVR_CL_HOST_MINMAX");
    }
}

int main(void)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        return check_opencl_unavailable(err.msg);
    }
    const char *data = check_shared_data();
    if (data)
        engine_scenes(cl, data);
    minmax_grids(cl);
    synthetic_scenes(cl);
    oriented_scenes(cl);
    sparse_scenes(cl);
    blob_scenes(cl);
    average_leap_scenes(cl);
    misuse(cl);
    cdvr_cl_close(cl);
    if (!data) {
        printf("skip: CDVR_SHARED_DATA not set (synthetic part: %d failed)\n", check_failed_count);
        return check_failed_count ? 1 : 77;
    }
    return check_finish();
}

#else
CHECK_SKIPPED_MAIN("built without OpenCL")
#endif
