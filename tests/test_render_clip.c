/* tests/test_render_clip.c - clipped rendering (render.h, cdvr_render_clip), CPU and OpenCL:
 * a volume split into boxes of bricks (cdvr_dist_partition), each box rendered on the whole
 * render's sample grid from its own voxels only (with the one-voxel overlap), and the images
 * blended front to back in cdvr_dist_order equal the render of the whole volume (PSNR >= 50
 * dB; early termination off, so exactly up to float rounding), and the boxes' sample counts
 * add up to the whole render's: no sample is lost or taken twice, also where samples fall
 * exactly on the voxel plane two boxes share (axis rays with step 2 over cuts at odd
 * planes). Cameras outside, inside the volume and orthographic; misuse errors. */
#include "check.h"

#include "cdvr/compare.h"
#include "cdvr/device.h"
#include "cdvr/dist.h"
#include "cdvr/render.h"
#include "cdvr/store.h"

#include <string.h>

#define NPARTS 4
static const size_t grid[3] = {3, 2, 2};

/* 34 x 29 x 23 voxels: along x the cuts of 3 bricks fall on voxel planes 11 and 22. */
static cdvr_volume *make_volume(void)
{
    size_t dims[3] = {34, 29, 23};
    cdvr_volume *v = NULL;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, NULL) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    for (size_t z = 0; z < dims[2]; z++)
        for (size_t y = 0; y < dims[1]; y++)
            for (size_t x = 0; x < dims[0]; x++) {
                double r = sqrt(pow(x - 17.0, 2) + pow(y - 14.0, 2) + pow(z - 11.0, 2));
                *p++ = (uint8_t)(127.5 + 120.0 * cos(r * 0.45) * cos(0.3 * x + 0.2 * z));
            }
    v->origin[0] = -3.0;
    v->spacing[2] = 1.25;
    return v;
}

/* The voxels of part p: its box of bricks; own = its cells, data = its voxels. */
static int part_box(const cdvr_volume *vol, size_t p, cdvr_render_clip *clip, size_t dims[3])
{
    size_t lo[3], hi[3];
    if (!cdvr_dist_partition(grid, NPARTS, p, lo, hi))
        return 0;
    size_t first = lo[0] + grid[0] * (lo[1] + grid[1] * lo[2]);
    size_t last = (hi[0] - 1) + grid[0] * ((hi[1] - 1) + grid[1] * (hi[2] - 1));
    size_t flo[3], fd[3], llo[3], ld[3];
    cdvr_brick_box(vol->dims, grid, first, flo, fd);
    cdvr_brick_box(vol->dims, grid, last, llo, ld);
    for (int a = 0; a < 3; a++) {
        clip->whole_dims[a] = vol->dims[a];
        clip->offset[a] = clip->own_lo[a] = flo[a];
        clip->own_hi[a] = llo[a] + ld[a] - 1;
        dims[a] = clip->own_hi[a] + 1 - flo[a];
    }
    return 1;
}

/* The sub-volume of the box (same origin, spacing and direction: render.h). */
static cdvr_volume *extract(const cdvr_volume *vol, const cdvr_render_clip *clip,
                            const size_t dims[3])
{
    cdvr_volume *sub = NULL;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &sub, NULL) != CDVR_OK)
        return NULL;
    cdvr_brick_extract(vol->data, vol->dims, clip->offset, dims, sub->data);
    memcpy(sub->spacing, vol->spacing, sizeof sub->spacing);
    memcpy(sub->origin, vol->origin, sizeof sub->origin);
    memcpy(sub->direction, vol->direction, sizeof sub->direction);
    return sub;
}

/* out = out over img (out is in front): premultiplied. */
static void blend_behind(cdvr_image *out, const cdvr_image *img)
{
    size_t n = (size_t)out->width * out->height;
    for (size_t i = 0; i < n; i++) {
        float *o = out->rgba + 4 * i, rest = 1.0f - o[3];
        for (int c = 0; c < 4; c++)
            o[c] += rest * img->rgba[4 * i + c];
    }
}

typedef cdvr_status (*render_fn)(const cdvr_volume *vol, cdvr_render_opts *opts,
                                 cdvr_image **out, uint64_t *samples, cdvr_error *err);

static cdvr_status render_cpu(const cdvr_volume *vol, cdvr_render_opts *opts, cdvr_image **out,
                              uint64_t *samples, cdvr_error *err)
{
    cdvr_status s = cdvr_render_cpu(vol, 0, opts, out, err);
    *samples = opts->samples;
    return s;
}

#if CDVR_HAVE_OPENCL
static cdvr_cl *the_cl; /* the test's device, opened once in main */

static cdvr_status render_cl(const cdvr_volume *vol, cdvr_render_opts *opts, cdvr_image **out,
                             uint64_t *samples, cdvr_error *err)
{
    cdvr_cl_stream *s = NULL;
    *out = NULL;
    cdvr_status st = cdvr_cl_stream_create(the_cl, vol->dims, &s, err);
    if (!st) {
        cdvr_cl_set_skipping(s, 0); /* sample counts comparable (clipped renders never skip) */
        st = cdvr_cl_upload_frames(s, vol->data, 1, err);
    }
    if (!st)
        st = cdvr_cl_setup(s, 0, opts->tf, err);
    if (!st)
        st = cdvr_image_create(opts->camera->width, opts->camera->height, out, err);
    if (!st)
        st = cdvr_cl_render(s, 0, opts, vol->spacing, vol->origin, vol->direction, *out, err);
    *samples = s ? cdvr_cl_last_samples(s) : 0;
    cdvr_cl_stream_free(s);
    return st;
}
#endif

static void check_scene(render_fn render, const char *dev, const cdvr_volume *vol,
                        const cdvr_tf *tf, const cdvr_camera *cam, double step, const char *what)
{
    cdvr_error err;
    cdvr_render_opts opts = {.tf = tf, .camera = cam, .step = step, .term_alpha = 1.0,
                             .threads = 2, .background = {0, 0, 0, 1}};
    cdvr_image *whole = NULL, *blend = NULL;
    uint64_t whole_samples = 0, sum = 0;
    CHECK_OK(render(vol, &opts, &whole, &whole_samples, &err), err);
    CHECK_OK(cdvr_image_create(cam->width, cam->height, &blend, &err), err);
    cdvr_store_info info;
    memset(&info, 0, sizeof info);
    memcpy(info.dims, vol->dims, sizeof info.dims);
    memcpy(info.spacing, vol->spacing, sizeof info.spacing);
    memcpy(info.origin, vol->origin, sizeof info.origin);
    memcpy(info.direction, vol->direction, sizeof info.direction);
    cdvr_dist_view view;
    cdvr_dist_view_of(&info, cam, &view);
    int order[NPARTS];
    cdvr_dist_order(vol->dims, grid, NPARTS, &view, order);
    for (int k = 0; k < NPARTS && whole && blend; k++) {
        cdvr_render_clip clip;
        size_t dims[3];
        if (!part_box(vol, (size_t)order[k], &clip, dims))
            continue;
        cdvr_volume *sub = extract(vol, &clip, dims);
        cdvr_image *img = NULL;
        uint64_t samples = 0;
        cdvr_render_opts o = opts;
        o.clip = &clip;
        cdvr_status st = render(sub, &o, &img, &samples, &err);
        CHECK_OK(st, err);
        if (st == CDVR_OK)
            blend_behind(blend, img);
        sum += samples;
        cdvr_image_free(img);
        cdvr_volume_free(sub);
    }
    if (whole && blend) {
        cdvr_compare_result r;
        memcpy(blend->background, whole->background, sizeof blend->background);
        cdvr_compare_images(whole, blend, &r, NULL);
        printf("%-4s %-34s psnr %6.1f dB, samples %llu whole, %llu in boxes\n", dev, what,
               r.psnr, (unsigned long long)whole_samples, (unsigned long long)sum);
        CHECK(r.psnr >= 50.0, "%s %s: boxes blended %.1f dB against the whole render", dev, what,
              r.psnr);
        CHECK(sum == whole_samples, "%s %s: %llu samples in the boxes, %llu whole", dev, what,
              (unsigned long long)sum, (unsigned long long)whole_samples);
        double mean_a = 0;
        for (size_t i = 0; i < (size_t)cam->width * cam->height; i++)
            mean_a += whole->rgba[4 * i + 3];
        CHECK(mean_a > 0.05 * cam->width * cam->height, "%s %s: the scene shows something", dev,
              what);
    }
    cdvr_image_free(whole);
    cdvr_image_free(blend);
}

static void check_all(render_fn render, const char *dev, const cdvr_volume *vol)
{
    cdvr_tf tf;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {80, .1, .3, .9, .02}, {170, .9, .6, .2, .08},
                           {255, 1, 1, 1, .2}};
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 4, 0, &err), err);
    struct {
        cdvr_camera cam;
        double step;
        const char *what;
    } scenes[] = {
        {{{80, -60, 50}, {13.5, 14, 13.75}, {0, 0, 1}, 30, 40, 36, 0, 0}, 0, "outside, default step"},
        {{{15, 12, 10}, {40, 20, 5}, {0, 0, 1}, 80, 40, 36, 0, 0}, 0.37, "inside the volume"},
        {{{-40, 14, 13.75}, {0, 14, 13.75}, {0, 0, 1}, 40, 33, 31, 0, 0}, 2.0,
         "along x, samples on shared planes"},
        {{{13.5, -50, 13.75}, {13.5, 0, 13.75}, {0, 0, 1}, 30, 37, 29, 1, 40}, 0.5,
         "orthographic"},
    };
    for (size_t i = 0; i < sizeof scenes / sizeof *scenes; i++)
        check_scene(render, dev, vol, &tf, &scenes[i].cam, scenes[i].step, scenes[i].what);
    /* an oriented volume (index axes rotated and flipped in the world, render.h step 0) */
    cdvr_volume oriented = *vol;
    static const double D[9] = {0, -1, 0, 0, 0, 1, -1, 0, 0};
    memcpy(oriented.direction, D, sizeof D);
    double mid[3] = {16.5, 14, 11}, c[3];
    cdvr_volume_index_to_world(&oriented, mid, c);
    cdvr_camera cam = {{c[0] + 50, c[1] - 40, c[2] + 30}, {c[0], c[1], c[2]}, {0, 0, 1}, 35, 40,
                       36, 0, 0};
    check_scene(render, dev, &oriented, &tf, &cam, 0, "oriented volume");
}

static void check_misuse(const cdvr_volume *vol)
{
    cdvr_tf tf;
    cdvr_tf_point pts[] = {{0, 1, 1, 1, .1}, {255, 1, 1, 1, .1}};
    cdvr_error err;
    cdvr_tf_init(&tf, pts, 2, 0, &err);
    cdvr_camera cam = {{80, -60, 50}, {13.5, 14, 13.75}, {0, 0, 1}, 30, 8, 8, 0, 0};
    cdvr_render_clip clip = {{34, 29, 23}, {0, 0, 0}, {5, 0, 0}, {40, 28, 22}};
    cdvr_render_opts o = {.tf = &tf, .camera = &cam, .clip = &clip};
    cdvr_image *img = NULL;
    CHECK(cdvr_render_cpu(vol, 0, &o, &img, &err) == CDVR_ERR_ARG && strstr(err.msg, "clip"),
          "owned cells beyond the volume: %s", err.msg);
    clip.own_hi[0] = 20;
    clip.offset[0] = 6; /* the owned cells start before the voxels given */
    CHECK(cdvr_render_cpu(vol, 0, &o, &img, &err) == CDVR_ERR_ARG && strstr(err.msg, "clip"),
          "owned cells outside the voxels: %s", err.msg);
    CHECK(img == NULL, "no image on error");
}

int main(void)
{
    cdvr_volume *vol = make_volume();
    if (!vol)
        return 1;
    check_all(render_cpu, "cpu", vol);
    check_misuse(vol);
#if CDVR_HAVE_OPENCL
    cdvr_error err;
    if (cdvr_cl_open(&the_cl, &err) == CDVR_OK) {
        check_all(render_cl, "cl", vol);
        cdvr_cl_close(the_cl);
    } else {
        printf("no OpenCL device (%s): CPU only\n", err.msg);
    }
#endif
    cdvr_volume_free(vol);
    return check_finish();
}
