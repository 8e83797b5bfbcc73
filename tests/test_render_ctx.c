/* tests/test_render_ctx.c - what the render context keeps on the OpenCL device between renders
 * (cdvr_render_ctx_volume_stream, cdvr_render_ctx_hold_volume in cdvr/method.h; revision in
 * cdvr/volume.h).
 *
 * Proves, on the raycast method on cl, each image compared bit for bit with the render of a
 * fresh context (which uploads the volume as it is now):
 *  - a held volume rendered twice uploads once (cdvr_render_ctx_uploads, stat uploaded_bytes);
 *  - a voxel written between two renders of a held volume, then cdvr_volume_touch: the second
 *    render uploads, its image changes and equals the fresh one; touch alone uploads again;
 *  - timesteps of a held 4D volume: each t is uploaded when it changes, t again when back;
 *  - cdvr_render_ctx_forget_frame makes the next render upload;
 *  - free and reallocate: hold A, render, hold NULL, free A, make B (maybe at A's address)
 *    with other voxels, hold B and render: B's image; the same without any hold (the memcmp
 *    path), with B held while A is still alive, and with B at A's address for certain (A's
 *    memory given other voxels and revision 0 after hold NULL);
 *  - two held volumes rendered in turn keep a stream each: the second round uploads nothing,
 *    a third volume (other dims) takes the place of the one used least recently, a released
 *    volume is uploaded again;
 *  - a volume not held keeps the memcmp path: a second render uploads nothing, and a write
 *    without touch is still seen.
 * The same free-and-reallocate cases, and an edit of a held volume, on the cpu device (whose
 * skip cache keeps a held volume's brick ranges). The cl part is skipped (77) without an
 * OpenCL device.
 */
#include "check.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "cdvr/compare.h"
#include "cdvr/method.h"
#include "cdvr/render.h"

static const size_t dims[3] = {24, 20, 16};

typedef struct scene {
    cdvr_device_kind device;
    const cdvr_render_method *ray;
    cdvr_method_params params;
    cdvr_tf tf;
    cdvr_camera cam;
} scene;

static void scene_init(scene *sc)
{
    cdvr_error err;
    sc->ray = cdvr_render_method_find("raycast");
    CHECK_OK(cdvr_render_method_params_parse(sc->ray, NULL, NULL, 0, &sc->params, &err), err);
    cdvr_tf_point pts[3] = {{0, 0, 0, 0, 0}, {100, 0, 0, 0, 0}, {255, 1, 0.8, 0.4, 0.9}};
    CHECK_OK(cdvr_tf_init(&sc->tf, pts, 3, 0.0, &err), err);
    CHECK_OK(cdvr_tf_set_window(&sc->tf, 0.0, 255.0, &err), err);
    memset(&sc->cam, 0, sizeof sc->cam);
    double eye[3] = {11.5, -60, 7.5}, center[3] = {11.5, 9.5, 7.5};
    memcpy(sc->cam.eye, eye, sizeof eye);
    memcpy(sc->cam.center, center, sizeof center);
    sc->cam.up[2] = 1.0;
    sc->cam.fov = 30.0;
    sc->cam.width = 48;
    sc->cam.height = 32;
}

/* Frame t of vol on sc->device through ctx; *uploaded gets the stat uploaded_bytes (-1 if
 * missing). */
static cdvr_image *render(cdvr_render_ctx *ctx, scene *sc, const cdvr_volume *vol, size_t t,
                          long long *uploaded)
{
    cdvr_render_opts o = {.tf = &sc->tf, .camera = &sc->cam};
    cdvr_render_stats stats = {0};
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(sc->ray->render(ctx, sc->device, vol, t, &o, &sc->params, &stats, &img, &err),
             err);
    if (uploaded) {
        *uploaded = -1;
        for (size_t k = 0; k < stats.count; k++)
            if (strcmp(stats.items[k].key, "uploaded_bytes") == 0)
                *uploaded = stats.items[k].integer;
    }
    return img;
}

static int same_image(const cdvr_image *a, const cdvr_image *b)
{
    return a && b && a->width == b->width && a->height == b->height &&
           memcmp(a->rgba, b->rgba, sizeof(float) * 4 * (size_t)a->width * (size_t)a->height) == 0;
}

/* img equals the render of a fresh context (frame t of vol as it is now). */
static void check_fresh(scene *sc, const cdvr_image *img, const cdvr_volume *vol, size_t t,
                        const char *what)
{
    cdvr_render_ctx *fresh = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_render_ctx_create(&fresh, &err), err);
    cdvr_image *want = render(fresh, sc, vol, t, NULL);
    CHECK(same_image(img, want), "%s: image differs from a fresh context's render", what);
    cdvr_image_free(want);
    cdvr_render_ctx_free(fresh);
}

/* A u8 volume with one bright 3x3x3 block at (x, y, z) in frame t (others all 0). */
static cdvr_volume *volume_with_block(size_t timesteps, size_t t, size_t x, size_t y, size_t z)
{
    cdvr_volume *vol = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, timesteps, CDVR_TYPE_U8, &vol, &err), err);
    if (!vol)
        return NULL;
    uint8_t *f = cdvr_volume_frame(vol, t);
    for (size_t k = z; k < z + 3; k++)
        for (size_t j = y; j < y + 3; j++)
            memset(f + x + dims[0] * (j + dims[1] * k), 255, 3);
    return vol;
}

static void test_held_edit(cdvr_render_ctx *ctx, scene *sc)
{
    cdvr_volume *vol = volume_with_block(1, 0, 4, 4, 4);
    CHECK(vol && vol->revision == 0, "a new volume has revision 0");
    cdvr_render_ctx_hold_volume(ctx, vol);
    long long up1, up2, up3, up4;
    uint64_t n0 = cdvr_render_ctx_uploads(ctx);
    cdvr_image *first = render(ctx, sc, vol, 0, &up1);
    cdvr_image *again = render(ctx, sc, vol, 0, &up2);
    CHECK(cdvr_render_ctx_uploads(ctx) == n0 + 1, "held volume rendered twice: %llu uploads",
          (unsigned long long)(cdvr_render_ctx_uploads(ctx) - n0));
    CHECK(up1 == (long long)cdvr_volume_voxels(vol) && up2 == 0,
          "uploaded_bytes %lld then %lld", up1, up2);
    CHECK(same_image(first, again), "the second render of a held volume");
    check_fresh(sc, first, vol, 0, "held volume");

    ((uint8_t *)vol->data)[12 + dims[0] * (10 + dims[1] * 8)] = 255; /* one voxel, in place */
    cdvr_volume_touch(vol);
    CHECK(vol->revision == 1, "touch: revision %llu", (unsigned long long)vol->revision);
    cdvr_image *edited = render(ctx, sc, vol, 0, &up3);
    CHECK(up3 == (long long)cdvr_volume_voxels(vol), "edited and touched: uploaded %lld", up3);
    CHECK(!same_image(first, edited), "the edit changed the image");
    check_fresh(sc, edited, vol, 0, "edited held volume");

    cdvr_volume_touch(vol); /* nothing changed, but a new revision: uploads again */
    cdvr_image *touched = render(ctx, sc, vol, 0, &up4);
    CHECK(up4 > 0 && same_image(edited, touched), "touched only: uploaded %lld", up4);

    cdvr_render_ctx_forget_frame(ctx);
    n0 = cdvr_render_ctx_uploads(ctx);
    cdvr_image *forgotten = render(ctx, sc, vol, 0, NULL);
    CHECK(cdvr_render_ctx_uploads(ctx) == n0 + 1, "after forget_frame the frame is uploaded");
    CHECK(same_image(edited, forgotten), "after forget_frame");
    cdvr_render_ctx_hold_volume(ctx, NULL);
    cdvr_image_free(first);
    cdvr_image_free(again);
    cdvr_image_free(edited);
    cdvr_image_free(touched);
    cdvr_image_free(forgotten);
    cdvr_volume_free(vol);
}

static void test_held_timesteps(cdvr_render_ctx *ctx, scene *sc)
{
    cdvr_volume *vol = volume_with_block(2, 1, 14, 10, 8);
    if (!vol)
        return;
    cdvr_render_ctx_hold_volume(ctx, vol);
    size_t order[] = {0, 1, 1, 0};
    uint64_t want[] = {1, 1, 0, 1};
    for (size_t i = 0; i < 4; i++) {
        uint64_t n0 = cdvr_render_ctx_uploads(ctx);
        cdvr_image *img = render(ctx, sc, vol, order[i], NULL);
        CHECK(cdvr_render_ctx_uploads(ctx) - n0 == want[i], "render %zu (t=%zu): %llu uploads",
              i, order[i], (unsigned long long)(cdvr_render_ctx_uploads(ctx) - n0));
        check_fresh(sc, img, vol, order[i], "timestep of a held 4D volume");
        cdvr_image_free(img);
    }
    cdvr_render_ctx_hold_volume(ctx, NULL);
    cdvr_volume_free(vol);
}

/* hold: 0 no hold, 1 hold A then NULL before freeing it, 2 hold B while A is alive, 3 as 1
 * with B certainly at A's address, data too, revision 0 (the allocator need not reuse it:
 * A's own memory is given B's voxels and revision 0, which is all the context can see). */
static void test_reallocate(cdvr_render_ctx *ctx, scene *sc, int hold)
{
    cdvr_volume *a = volume_with_block(1, 0, 4, 4, 4);
    if (!a)
        return;
    if (hold)
        cdvr_render_ctx_hold_volume(ctx, a);
    cdvr_image *ia = render(ctx, sc, a, 0, NULL);
    cdvr_volume *b;
    int same_address;
    if (hold == 3) {
        cdvr_render_ctx_hold_volume(ctx, NULL);
        b = volume_with_block(1, 0, 16, 12, 10);
        if (b) {
            memcpy(a->data, b->data, cdvr_volume_frame_bytes(a));
            cdvr_volume_free(b);
        }
        a->revision = 0;
        b = a;
        same_address = 1;
        cdvr_render_ctx_hold_volume(ctx, b);
    } else if (hold == 2) {
        b = volume_with_block(1, 0, 16, 12, 10);
        same_address = 0;
        cdvr_render_ctx_hold_volume(ctx, b);
        CHECK(cdvr_render_ctx_held_index(ctx, a) >= 0 && cdvr_render_ctx_held_index(ctx, b) >= 0,
              "hold 2: A and B held at once");
        cdvr_render_ctx_release_volume(ctx, a);
        CHECK(cdvr_render_ctx_held_index(ctx, a) < 0, "hold 2: A released");
        cdvr_volume_free(a);
    } else {
        const void *a_at = a, *a_data = a->data;
        if (hold)
            cdvr_render_ctx_hold_volume(ctx, NULL);
        cdvr_volume_free(a);
        b = volume_with_block(1, 0, 16, 12, 10);
        same_address = b && (const void *)b == a_at && b->data == a_data;
        if (hold)
            cdvr_render_ctx_hold_volume(ctx, b);
    }
    if (b) {
        cdvr_image *ib = render(ctx, sc, b, 0, NULL);
        CHECK(!same_image(ia, ib), "hold %d: B renders unlike A", hold);
        char what[80];
        snprintf(what, sizeof what, "hold %d: B after A%s", hold,
                 same_address ? " (at A's address)" : "");
        check_fresh(sc, ib, b, 0, what);
        printf("%s\n", what);
        cdvr_image_free(ib);
    }
    cdvr_render_ctx_hold_volume(ctx, NULL);
    cdvr_image_free(ia);
    cdvr_volume_free(b);
}

/* Frames uploaded by a render of frame 0 of vol, held, whose image must equal a fresh
 * context's. */
static uint64_t held_render(cdvr_render_ctx *ctx, scene *sc, const cdvr_volume *vol,
                            const char *what)
{
    cdvr_render_ctx_hold_volume(ctx, vol);
    uint64_t n0 = cdvr_render_ctx_uploads(ctx);
    cdvr_image *img = render(ctx, sc, vol, 0, NULL);
    check_fresh(sc, img, vol, 0, what);
    cdvr_image_free(img);
    return cdvr_render_ctx_uploads(ctx) - n0;
}

/* Two held volumes rendered in turn keep a stream each (CDVR_RENDER_CTX_STREAMS): A and B
 * of the same dims, then C of other dims in place of the one used least recently; a volume
 * released is uploaded again. */
static void test_two_held(cdvr_render_ctx *ctx, scene *sc)
{
    cdvr_volume *a = volume_with_block(1, 0, 4, 4, 4), *b = volume_with_block(1, 0, 16, 12, 10);
    size_t other[3] = {20, 24, 12};
    cdvr_volume *c = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(other, 1, CDVR_TYPE_U8, &c, &err), err);
    if (!a || !b || !c)
        return;
    memset(c->data, 200, cdvr_volume_frame_bytes(c) / 2);
    const cdvr_volume *order[] = {a, b, a, b, c, b, c, a, a};
    const char *names[] = {"A", "B", "A", "B", "C", "B", "C", "A", "A"};
    /* C takes the hold and stream of A (both used least recently), A then those of B */
    const uint64_t want[] = {1, 1, 0, 0, 1, 0, 0, 1, 0};
    for (size_t i = 0; i < sizeof order / sizeof *order; i++) {
        char what[64];
        snprintf(what, sizeof what, "two held, render %zu (%s)", i + 1, names[i]);
        uint64_t n = held_render(ctx, sc, order[i], what);
        CHECK(n == want[i], "%s: %llu uploads, want %llu", what, (unsigned long long)n,
              (unsigned long long)want[i]);
    }
    CHECK(cdvr_render_ctx_held_index(ctx, b) < 0 && cdvr_render_ctx_held_index(ctx, a) >= 0 &&
              cdvr_render_ctx_held_index(ctx, c) >= 0,
          "held: A and C, B released when A was held again");
    cdvr_render_ctx_release_volume(ctx, a);
    CHECK(cdvr_render_ctx_held_index(ctx, a) < 0, "A released");
    uint64_t n0 = cdvr_render_ctx_uploads(ctx);
    cdvr_image *img = render(ctx, sc, a, 0, NULL);
    CHECK(cdvr_render_ctx_uploads(ctx) == n0 + 1, "A released: uploaded again (%llu)",
          (unsigned long long)(cdvr_render_ctx_uploads(ctx) - n0));
    check_fresh(sc, img, a, 0, "A after its release");
    cdvr_image_free(img);
    cdvr_render_ctx_forget_frame(ctx); /* its copy: test_not_held renders the same voxels */
    cdvr_render_ctx_hold_volume(ctx, NULL);
    CHECK(cdvr_render_ctx_held_index(ctx, c) < 0, "hold NULL releases all");
    cdvr_volume_free(a);
    cdvr_volume_free(b);
    cdvr_volume_free(c);
}

static void test_not_held(cdvr_render_ctx *ctx, scene *sc)
{
    cdvr_volume *vol = volume_with_block(1, 0, 4, 4, 4);
    if (!vol)
        return;
    long long up1, up2, up3;
    cdvr_image *first = render(ctx, sc, vol, 0, &up1);
    cdvr_image *again = render(ctx, sc, vol, 0, &up2);
    CHECK(up1 > 0 && up2 == 0, "not held: uploaded_bytes %lld then %lld", up1, up2);
    ((uint8_t *)vol->data)[12 + dims[0] * (10 + dims[1] * 8)] = 255; /* no touch */
    cdvr_image *edited = render(ctx, sc, vol, 0, &up3);
    CHECK(up3 > 0, "not held: a write without touch is seen (uploaded %lld)", up3);
    CHECK(!same_image(first, edited), "not held: the edit changed the image");
    check_fresh(sc, edited, vol, 0, "edited volume not held");
    cdvr_image_free(first);
    cdvr_image_free(again);
    cdvr_image_free(edited);
    cdvr_volume_free(vol);
}

/* The CPU ray caster's skip cache keeps a held volume's brick ranges (render.h,
 * cdvr_cpu_skip_cache_hold): a voxel written in an empty brick, then touch, must be seen;
 * without touch (the caller broke the promise) the kept ranges may skip it. */
static void test_cpu_held_edit(cdvr_render_ctx *ctx, scene *sc)
{
    cdvr_volume *vol = volume_with_block(1, 0, 4, 4, 4);
    if (!vol)
        return;
    cdvr_render_ctx_hold_volume(ctx, vol);
    cdvr_image *first = render(ctx, sc, vol, 0, NULL);
    uint8_t *f = cdvr_volume_frame(vol, 0);
    for (size_t k = 9; k < 12; k++)
        for (size_t j = 12; j < 15; j++)
            memset(f + 16 + dims[0] * (j + dims[1] * k), 255, 3);
    cdvr_volume_touch(vol);
    cdvr_image *edited = render(ctx, sc, vol, 0, NULL);
    CHECK(!same_image(first, edited), "cpu, held: the touched edit changed the image");
    check_fresh(sc, edited, vol, 0, "cpu, held volume edited and touched");
    cdvr_render_ctx_hold_volume(ctx, NULL);
    cdvr_image_free(first);
    cdvr_image_free(edited);
    cdvr_volume_free(vol);
}

int main(void)
{
    cdvr_render_ctx *ctx = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_render_ctx_create(&ctx, &err), err);
    scene sc;
    scene_init(&sc);
    sc.device = CDVR_DEVICE_CPU; /* the CPU skip cache: held ranges, free and reallocate */
    test_cpu_held_edit(ctx, &sc);
    for (int hold = 0; hold < 4; hold++)
        test_reallocate(ctx, &sc, hold);
    cdvr_cl *cl;
    if (cdvr_render_ctx_cl(ctx, &cl, &err) != CDVR_OK) {
        cdvr_render_ctx_free(ctx);
        int status = check_finish();
        return status ? status : check_opencl_unavailable(err.msg);
    }
    sc.device = CDVR_DEVICE_CL;
    test_held_edit(ctx, &sc);
    test_held_timesteps(ctx, &sc);
    for (int hold = 0; hold < 4; hold++)
        test_reallocate(ctx, &sc, hold);
    test_two_held(ctx, &sc);
    test_not_held(ctx, &sc);
    cdvr_render_ctx_free(ctx);
    return check_finish();
}
