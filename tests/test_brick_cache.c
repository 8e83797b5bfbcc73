/* tests/test_brick_cache.c - the brick cache (cdvr/brick_cache.h) on a bricked store with
 * three levels: at lod_error 0 with room for everything its payload decodes (the C fetch over
 * every voxel) to exactly the assembled volume; with coarse levels in play (a far camera, a
 * small budget) the OpenCL fetch (kernels/render/brick_cache.cl) renders exactly the image of
 * the C fetch's volume uploaded dense, and the bulk path's frame is that volume; the LRU keeps
 * the cache within the budget across timesteps; the fetch never reads outside a hostile
 * payload (ASan). OpenCL parts skip without a device. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/brick_cache.h"
#include "cdvr/bricks.h"
#include "cdvr/camera.h"
#include "cdvr/compare.h"
#include "cdvr/device.h"
#include "cdvr/render.h"
#include "cdvr/skip.h"
#include "cdvr/store.h"
#include "cdvr/tf.h"
#include "cdvr/volume.h"
#include "check.h"

static const size_t DIMS[3] = {29, 23, 17};

static cdvr_store *make_store(const char *path)
{
    cdvr_volume *vol;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(DIMS, 2, CDVR_TYPE_U8, &vol, &err), err);
    uint32_t r = 12345;
    for (size_t i = 0; i < 2 * DIMS[0] * DIMS[1] * DIMS[2]; i++) {
        r = r * 1103515245u + 12345u;
        size_t x = i % DIMS[0], y = i / DIMS[0] % DIMS[1];
        ((uint8_t *)vol->data)[i] = (uint8_t)((x * 7 + y * 5 + (r >> 24) % 16) & 0xff);
    }
    cdvr_variant_spec spec = {.codec = cdvr_codec_find("raw")};
    spec.codec->params_default(&spec.params);
    cdvr_encode_opts o = {.variants = &spec, .nvariants = 1, .bricks = {3, 2, 2}, .levels = 3,
                          .threads = 1, .qhi = 255};
    CHECK_OK(cdvr_store_encode(vol, &o, path, &err), err);
    cdvr_volume_free(vol);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    return st;
}

/* The C fetch over every voxel of a payload (the codec's decode). */
static uint8_t *decode_payload(const uint8_t *payload, size_t bytes)
{
    size_t n = DIMS[0] * DIMS[1] * DIMS[2];
    uint8_t *out = malloc(n);
    uint8_t *frames[1] = {out};
    cdvr_codec_params none = {{0}};
    cdvr_error err;
    CHECK_OK(cdvr_brick_cache_codec()->decode(&none, DIMS, payload, bytes, frames, 1, &err), err);
    return out;
}

static cdvr_camera far_camera(void)
{
    cdvr_camera cam = {.eye = {14 + 300, 11 - 40, 8 + 60}, .center = {14, 11, 8},
                       .up = {0, 0, 1}, .fov = 30, .width = 40, .height = 32};
    return cam;
}

static void level0_exact(cdvr_store *st)
{
    cdvr_brick_cache *c;
    cdvr_error err;
    CHECK_OK(cdvr_brick_cache_create(st, 0, 1u << 24, &c, &err), err);
    cdvr_camera cam = far_camera();
    for (size_t t = 0; t < 2; t++) {
        const uint8_t *payload;
        size_t bytes;
        CHECK_OK(cdvr_brick_cache_frame(c, t, &cam, NULL, 0.0, &payload, &bytes, &err), err);
        cdvr_brick_cache_stats s;
        cdvr_brick_cache_get_stats(c, &s);
        CHECK(s.levels == 3 && s.bricks_at[0] == 12, "all bricks at level 0: %zu", s.bricks_at[0]);
        uint8_t *got = decode_payload(payload, bytes);
        cdvr_volume *ref;
        CHECK_OK(cdvr_store_decode(st, 0, t, &ref, &err), err);
        CHECK(memcmp(got, ref->data, cdvr_volume_voxels(ref)) == 0, "t %zu: level 0 exact", t);
        cdvr_volume_free(ref);
        free(got);
    }
    cdvr_brick_cache_free(c);
}

static void lru_budget(cdvr_store *st)
{
    cdvr_brick_cache *c;
    cdvr_error err;
    uint64_t budget = 12000; /* less than one timestep at level 0 (11339 + aprons) */
    CHECK_OK(cdvr_brick_cache_create(st, 0, budget, &c, &err), err);
    cdvr_camera cam = far_camera();
    cam.eye[0] = 40; /* near: level 0 where the budget allows */
    for (int round = 0; round < 2; round++)
        for (size_t t = 0; t < 2; t++) {
            const uint8_t *payload;
            size_t bytes;
            CHECK_OK(cdvr_brick_cache_frame(c, t, &cam, NULL, 0.0, &payload, &bytes, &err), err);
            cdvr_brick_cache_stats s;
            cdvr_brick_cache_get_stats(c, &s);
            CHECK(s.cache_bytes <= budget && s.resident_bytes <= budget,
                  "within the budget: %llu %llu", (unsigned long long)s.cache_bytes,
                  (unsigned long long)s.resident_bytes);
            CHECK(s.bricks_at[0] < 12 && s.bricks_at[0] + s.bricks_at[1] + s.bricks_at[2] == 12,
                  "some bricks coarser, none missing");
            if (round == 1)
                CHECK(s.evicted > 0 && s.decoded > 0, "the other timestep was evicted");
        }
    cdvr_brick_cache_free(c);
    /* a budget past the payload's 32-bit pool offsets is capped, so frames coarsen instead of
     * failing; the cache still serves the budget asked for */
    uint64_t huge = (uint64_t)8 << 30;
    CHECK_OK(cdvr_brick_cache_create(st, 0, huge, &c, &err), err);
    cdvr_brick_cache_stats s;
    cdvr_brick_cache_get_stats(c, &s);
    CHECK(s.budget_bytes < UINT32_MAX && s.budget_bytes > UINT32_MAX - 65536,
          "8 GiB capped below 4 GiB less the tables: %llu", (unsigned long long)s.budget_bytes);
    CHECK(cdvr_brick_cache_serves(c, st, 0, huge) && !cdvr_brick_cache_serves(c, st, 0, budget),
          "serves the budget asked for");
    cdvr_brick_cache_free(c);
}

static void hostile_payloads(void)
{
    uint8_t p[96];
    uint32_t r = 99;
    for (int k = 0; k < 200; k++) {
        for (size_t i = 0; i < sizeof p; i++) {
            r = r * 1103515245u + 12345u;
            p[i] = (uint8_t)(r >> 24);
        }
        for (size_t n = 0; n <= sizeof p; n += 13)
            (void)cdvr_brick_cache_fetch(p, n, DIMS, (size_t)k % DIMS[0], 3, (size_t)k % DIMS[2]);
    }
}

#if CDVR_HAVE_OPENCL
static cdvr_image *render(cdvr_cl_stream *s, const cdvr_tf *tf, const cdvr_camera *cam)
{
    static const double spacing[3] = {1, 1, 1}, origin[3] = {0, 0, 0}, direction[9] = {1, 0, 0,
                                                                                      0, 1, 0,
                                                                                      0, 0, 1};
    cdvr_render_opts o = {.tf = tf, .camera = cam, .step = 0.4};
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_image_create(cam->width, cam->height, &img, &err), err);
    CHECK_OK(cdvr_cl_setup(s, 0, tf, &err), err);
    CHECK_OK(cdvr_cl_render(s, 0, &o, spacing, origin, direction, img, &err), err);
    return img;
}

/* The brick march of a cache payload on a new stream (skip grid from the cache). */
static cdvr_image *render_march(cdvr_cl *cl, cdvr_brick_cache *c, const uint8_t *payload,
                                size_t bytes, int skip, const cdvr_tf *tf,
                                const cdvr_camera *cam, uint64_t *samples)
{
    static const double spacing[3] = {1, 1, 1}, origin[3] = {0, 0, 0}, direction[9] = {1, 0, 0,
                                                                                      0, 1, 0,
                                                                                      0, 0, 1};
    cdvr_render_opts o = {.tf = tf, .camera = cam, .step = 0.4};
    cdvr_error err;
    cdvr_cl_stream *s;
    cdvr_skip_grid g;
    cdvr_image *img = NULL;
    cdvr_codec_params march = {{0}};
    march.bytes[CDVR_BRICK_CACHE_PARAM_MARCH] = 1;
    CHECK_OK(cdvr_cl_stream_create(cl, DIMS, &s, &err), err);
    cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_SAMPLE);
    cdvr_cl_set_skipping(s, skip);
    CHECK_OK(cdvr_cl_upload(s, payload, bytes, &err), err);
    CHECK_OK(cdvr_cl_decode(s, cdvr_brick_cache_codec(), &march, 1, &err), err);
    CHECK_OK(cdvr_skip_grid_init(&g, DIMS, CDVR_RANGE_SHIFT, &err), err);
    CHECK_OK(cdvr_brick_cache_skip_minmax(c, &g, tf, &err), err);
    cdvr_skip_flags(&g, tf);
    CHECK_OK(cdvr_cl_setup_grid(s, 0, tf, &g, &err), err);
    CHECK_OK(cdvr_image_create(cam->width, cam->height, &img, &err), err);
    CHECK_OK(cdvr_cl_render(s, 0, &o, spacing, origin, direction, img, &err), err);
    *samples = cdvr_cl_last_samples(s);
    cdvr_skip_grid_free(&g);
    cdvr_cl_stream_free(s);
    return img;
}

static size_t values_differing(const cdvr_image *a, const cdvr_image *b)
{
    size_t differ = 0, values = (size_t)a->width * a->height * 4;
    for (size_t i = 0; i < values; i++)
        differ += a->rgba[i] != b->rgba[i];
    return differ;
}

/* Hostile payloads through the march on the device: random page tables and pools (the magic
 * word kept) render or fail with an error, never read outside the payload (the kernel clamps
 * every table index and voxel offset; a read past it would fault). */
static void march_hostile(void)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        printf("skip hostile march: %s\n", err.msg);
        return;
    }
    cdvr_tf tf;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {1, 1, 1, 1, 0.5}, {255, 1, 1, 1, 0.5}};
    cdvr_tf_init(&tf, pts, 3, 0, &err);
    cdvr_camera cam = far_camera();
    cdvr_render_opts o = {.tf = &tf, .camera = &cam, .step = 0.4};
    static const double spacing[3] = {1, 1, 1}, origin[3] = {0, 0, 0},
                        direction[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    cdvr_codec_params march = {{0}};
    march.bytes[CDVR_BRICK_CACHE_PARAM_MARCH] = 1;
    uint32_t r = 7;
    int rendered = 0;
    for (int k = 0; k < 12; k++) {
        size_t n = 64 + (size_t)k * 397;
        uint8_t *p = malloc(n);
        for (size_t i = 0; i < n; i++) {
            r = r * 1103515245u + 12345u;
            p[i] = (uint8_t)(r >> (k % 2 ? 24 : 28)); /* odd k: any bytes; even: small ones */
        }
        for (int i = 0; i < 4; i++)
            p[i] = (uint8_t)(CDVR_BRICK_CACHE_MAGIC >> (8 * i));
        cdvr_cl_stream *s;
        CHECK_OK(cdvr_cl_stream_create(cl, DIMS, &s, &err), err);
        cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_SAMPLE);
        cdvr_image *img = NULL;
        cdvr_status st = cdvr_cl_upload(s, p, n, &err);
        if (!st)
            st = cdvr_cl_decode(s, cdvr_brick_cache_codec(), &march, 1, &err);
        if (!st)
            st = cdvr_cl_setup(s, 0, &tf, &err);
        if (!st)
            st = cdvr_image_create(cam.width, cam.height, &img, &err);
        if (!st)
            st = cdvr_cl_render(s, 0, &o, spacing, origin, direction, img, &err);
        CHECK(st == CDVR_OK || err.msg[0], "hostile payload %d: an image or a message", k);
        rendered += st == CDVR_OK;
        cdvr_image_free(img);
        cdvr_cl_stream_free(s);
        free(p);
    }
    printf("hostile march payloads: %d of 12 rendered, the others refused\n", rendered);
    cdvr_cl_close(cl);
}

/* The march with every brick at level 0 renders exactly the dense frame (skipping on and off,
 * two cameras); the cache's skip ranges hold the exact ranges of the level-0 frame; with
 * coarse bricks it stays close to the per-voxel page table and takes fewer samples. */
static void march_matches_dense(cdvr_store *st)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        printf("skip march part: %s\n", err.msg);
        return;
    }
    cdvr_tf tf;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {80, 1, .5, .2, .2}, {255, 1, 1, 1, .8}};
    cdvr_tf_init(&tf, pts, 3, 0, &err);
    cdvr_brick_cache *c;
    CHECK_OK(cdvr_brick_cache_create(st, 0, 1u << 24, &c, &err), err);
    cdvr_camera cams[2] = {far_camera(), far_camera()};
    cams[0].eye[0] = 60;
    cams[1].eye[0] = -20;
    cams[1].eye[1] = 45;
    cams[1].eye[2] = -12;
    for (int k = 0; k < 2; k++) {
        cams[k].width = 48;
        cams[k].height = 40;
        cams[k].fov = 50;
    }
    const uint8_t *payload;
    size_t bytes;
    CHECK_OK(cdvr_brick_cache_frame(c, 1, &cams[0], &tf, 0.0, &payload, &bytes, &err), err);
    uint8_t *volume = decode_payload(payload, bytes);
    cdvr_skip_grid exact, cached;
    CHECK_OK(cdvr_skip_grid_init(&exact, DIMS, CDVR_RANGE_SHIFT, &err), err);
    CHECK_OK(cdvr_skip_grid_init(&cached, DIMS, CDVR_RANGE_SHIFT, &err), err);
    CHECK_OK(cdvr_skip_minmax_from_frame(&exact, volume, &err), err);
    CHECK_OK(cdvr_brick_cache_skip_minmax(c, &cached, &tf, &err), err);
    size_t loose = 0;
    for (size_t b = 0; b < exact.nbricks; b++) {
        CHECK(cached.minmax[2 * b] <= exact.minmax[2 * b] &&
              cached.minmax[2 * b + 1] >= exact.minmax[2 * b + 1],
              "range brick %zu: the cache's range [%d, %d] holds the frame's [%d, %d]", b,
              cached.minmax[2 * b], cached.minmax[2 * b + 1], exact.minmax[2 * b],
              exact.minmax[2 * b + 1]);
        loose += cached.minmax[2 * b] != exact.minmax[2 * b] ||
                 cached.minmax[2 * b + 1] != exact.minmax[2 * b + 1];
    }
    CHECK(loose == 0, "at level 0 the cache's ranges are the frame's exactly (%zu differ)", loose);
    cdvr_skip_grid_free(&exact);
    cdvr_skip_grid_free(&cached);
    cdvr_cl_stream *dense;
    CHECK_OK(cdvr_cl_stream_create(cl, DIMS, &dense, &err), err);
    CHECK_OK(cdvr_cl_upload_frames(dense, volume, 1, &err), err);
    for (int k = 0; k < 2; k++)
        for (int skip = 0; skip < 2; skip++) {
            CHECK_OK(cdvr_brick_cache_frame(c, 1, &cams[k], &tf, 0.0, &payload, &bytes, &err),
                     err);
            uint64_t samples;
            cdvr_cl_set_skipping(dense, skip);
            cdvr_image *a = render_march(cl, c, payload, bytes, skip, &tf, &cams[k], &samples);
            cdvr_image *b = render(dense, &tf, &cams[k]);
            size_t differ = values_differing(a, b);
            CHECK(differ == 0, "camera %d skip %d: the march differs from the dense render in "
                  "%zu values", k, skip, differ);
            CHECK(samples == cdvr_cl_last_samples(dense), "camera %d skip %d: samples %llu "
                  "against %llu", k, skip, (unsigned long long)samples,
                  (unsigned long long)cdvr_cl_last_samples(dense));
            cdvr_image_free(a);
            cdvr_image_free(b);
        }
    free(volume);
    cdvr_cl_stream_free(dense);
    /* the cache's own grid follows the frame's bricks: a level-0 frame, then a coarse one */
    const cdvr_skip_grid *kept;
    cdvr_skip_grid fresh;
    cdvr_camera far2 = far_camera();
    CHECK_OK(cdvr_skip_grid_init(&fresh, DIMS, CDVR_RANGE_SHIFT, &err), err);
    for (int round = 0; round < 3; round++) {
        double lod = round == 1 ? 4.0 : 0.0;
        CHECK_OK(cdvr_brick_cache_frame(c, 1, round == 1 ? &far2 : &cams[0], &tf, lod, &payload,
                                        &bytes, &err), err);
        CHECK_OK(cdvr_brick_cache_skip_grid(c, CDVR_RANGE_SHIFT, &tf, 1, &kept, &err), err);
        CHECK_OK(cdvr_brick_cache_skip_minmax(c, &fresh, &tf, &err), err);
        CHECK(memcmp(kept->minmax, fresh.minmax, 2 * fresh.nbricks) == 0 && kept->flags_valid,
              "round %d: the kept grid holds this frame's ranges", round);
        cdvr_brick_cache_stats rs;
        cdvr_brick_cache_get_stats(c, &rs);
        CHECK((round == 1) == (rs.bricks_at[0] == 0), "round %d: %zu bricks at level 0", round,
              rs.bricks_at[0]);
    }
    cdvr_skip_grid_free(&fresh);
    /* coarse levels: the march against the page table of the same payload */
    cdvr_camera far = far_camera();
    far.width = 48;
    far.height = 40;
    far.fov = 50;
    far.eye[0] = 60;
    CHECK_OK(cdvr_brick_cache_frame(c, 1, &far, &tf, 2.0, &payload, &bytes, &err), err);
    cdvr_brick_cache_stats cs;
    cdvr_brick_cache_get_stats(c, &cs);
    CHECK(cs.bricks_at[1] + cs.bricks_at[2] > 0, "coarse levels in play");
    cdvr_cl_stream *paged;
    cdvr_codec_params none = {{0}};
    CHECK_OK(cdvr_cl_stream_create(cl, DIMS, &paged, &err), err);
    cdvr_cl_set_fetch_path(paged, CDVR_CL_FETCH_SAMPLE);
    CHECK_OK(cdvr_cl_upload(paged, payload, bytes, &err), err);
    CHECK_OK(cdvr_cl_decode(paged, cdvr_brick_cache_codec(), &none, 1, &err), err);
    uint64_t samples;
    cdvr_image *a = render_march(cl, c, payload, bytes, 1, &tf, &far, &samples);
    cdvr_image *b = render(paged, &tf, &far);
    cdvr_compare_result cmp;
    CHECK_OK(cdvr_compare_images(a, b, &cmp, &err), err);
    printf("coarse march against the page table: %.1f dB, samples %llu against %llu\n", cmp.psnr,
           (unsigned long long)samples, (unsigned long long)cdvr_cl_last_samples(paged));
    CHECK(cmp.psnr >= 30, "coarse march against the page table: %.1f dB", cmp.psnr);
    CHECK(samples < cdvr_cl_last_samples(paged), "coarse bricks take fewer samples");
    cdvr_image_free(a);
    cdvr_image_free(b);
    cdvr_cl_stream_free(paged);
    cdvr_brick_cache_free(c);
    cdvr_cl_close(cl);
}

static void device_matches_c(cdvr_store *st)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        printf("skip device part: %s\n", err.msg);
        return;
    }
    cdvr_brick_cache *c;
    CHECK_OK(cdvr_brick_cache_create(st, 0, 6000, &c, &err), err);
    cdvr_camera cam = far_camera();
    cam.eye[0] = 60;
    cam.width = 48;
    cam.height = 40;
    cam.fov = 50;
    const uint8_t *payload;
    size_t bytes;
    CHECK_OK(cdvr_brick_cache_frame(c, 1, &cam, NULL, 1.0, &payload, &bytes, &err), err);
    cdvr_brick_cache_stats s;
    cdvr_brick_cache_get_stats(c, &s);
    CHECK(s.bricks_at[1] + s.bricks_at[2] > 0, "coarse levels in play");
    uint8_t *volume = decode_payload(payload, bytes);
    const uint8_t *dense_frame;
    CHECK_OK(cdvr_brick_cache_dense(c, &dense_frame, &err), err);
    CHECK(memcmp(dense_frame, volume, DIMS[0] * DIMS[1] * DIMS[2]) == 0,
          "the assembled dense frame is the C fetch at every voxel");
    cdvr_tf tf;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {80, 1, .5, .2, .2}, {255, 1, 1, 1, .8}};
    cdvr_tf_init(&tf, pts, 3, 0, &err);
    cdvr_cl_stream *fetch, *dense, *bulk;
    CHECK_OK(cdvr_cl_stream_create(cl, DIMS, &fetch, &err), err);
    CHECK_OK(cdvr_cl_stream_create(cl, DIMS, &dense, &err), err);
    CHECK_OK(cdvr_cl_stream_create(cl, DIMS, &bulk, &err), err);
    cdvr_cl_set_fetch_path(fetch, CDVR_CL_FETCH_SAMPLE);
    cdvr_cl_set_fetch_path(bulk, CDVR_CL_FETCH_BULK);
    cdvr_codec_params none = {{0}};
    CHECK_OK(cdvr_cl_upload(fetch, payload, bytes, &err), err);
    CHECK_OK(cdvr_cl_decode(fetch, cdvr_brick_cache_codec(), &none, 1, &err), err);
    CHECK_OK(cdvr_cl_upload(bulk, payload, bytes, &err), err);
    CHECK_OK(cdvr_cl_decode(bulk, cdvr_brick_cache_codec(), &none, 1, &err), err);
    CHECK_OK(cdvr_cl_upload_frames(dense, volume, 1, &err), err);
    size_t n = DIMS[0] * DIMS[1] * DIMS[2];
    uint8_t *back = malloc(n);
    CHECK_OK(cdvr_cl_download(bulk, 0, back, &err), err);
    CHECK(memcmp(back, volume, n) == 0, "bulk frame is the C fetch's volume");
    free(back);
    for (int skip = 0; skip < 2; skip++) {
        cdvr_cl_set_skipping(fetch, skip);
        cdvr_cl_set_skipping(dense, skip);
        cdvr_image *a = render(fetch, &tf, &cam), *b = render(dense, &tf, &cam);
        size_t differ = 0, values = (size_t)a->width * a->height * 4;
        for (size_t i = 0; i < values; i++)
            differ += a->rgba[i] != b->rgba[i];
        CHECK(differ == 0, "skip %d: the OpenCL fetch differs from the C fetch in %zu of %zu "
              "values", skip, differ, values);
        cdvr_image_free(a);
        cdvr_image_free(b);
    }
    free(volume);
    cdvr_cl_stream_free(fetch);
    cdvr_cl_stream_free(dense);
    cdvr_cl_stream_free(bulk);
    cdvr_brick_cache_free(c);
    cdvr_cl_close(cl);
}
#endif

int main(void)
{
    char path[256];
    snprintf(path, sizeof path, "/tmp/cdvr_test_brick_cache_%ld.cdv", (long)getpid());
    cdvr_store *st = make_store(path);
    if (st) {
        level0_exact(st);
        lru_budget(st);
#if CDVR_HAVE_OPENCL
        device_matches_c(st);
        march_matches_dense(st);
        march_hostile();
#endif
        cdvr_store_close(st);
    }
    hostile_payloads();
    unlink(path);
    return check_finish();
}
