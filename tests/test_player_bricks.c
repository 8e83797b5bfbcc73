/* tests/test_player_bricks.c - brick skipping in the player (player.h): a TF that hides half
 * the volume and cameras that see part of it skip bricks, and skipping changes no pixel
 * (identical images, lossless and lossy variants), serial and pipelined;
 * cameras are evaluated once per frame, when the group is planned; players of the regions of
 * a k-d partition blended in visibility order equal the whole player (what distribute="bricks"
 * does across processes), a frame stride plays its share; the camera box test. */
#include "check.h"

#include "cdvr/compare.h"
#include "cdvr/dist.h"
#include "cdvr/player.h"

#include <string.h>
#include <unistd.h>

#define FRAMES 6
static char tmpdir[256];

/* A smooth series whose values grow along x (low half below 128), with a wave in y, z and t
 * so that lossy codecs have work to do. */
static cdvr_volume *make_series(void)
{
    size_t dims[3] = {41, 29, 23};
    cdvr_volume *v = NULL;
    if (cdvr_volume_create(dims, 4, CDVR_TYPE_U8, &v, NULL) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    for (size_t t = 0; t < 4; t++)
        for (size_t z = 0; z < dims[2]; z++)
            for (size_t y = 0; y < dims[1]; y++)
                for (size_t x = 0; x < dims[0]; x++) {
                    double val = 250.0 * x / (dims[0] - 1) +
                                 4.0 * sin(0.7 * y + 0.5 * z + 0.9 * t);
                    *p++ = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
                }
    return v;
}

static cdvr_store *encode(const cdvr_volume *vol, const char *name, cdvr_error *err)
{
    cdvr_variant_spec vs[2] = {{.codec = cdvr_codec_find("raw")}, {.codec = cdvr_codec_find("pvtc")}};
    for (int i = 0; i < 2; i++) {
        vs[i].codec->params_default(&vs[i].params);
        vs[i].lzo_min_saving = -1;
    }
    cdvr_encode_opts o = {.variants = vs, .nvariants = 2, .qlo = 0, .qhi = 255,
                          .source_type = CDVR_TYPE_U8, .bricks = {4, 2, 2}};
    char path[512];
    snprintf(path, sizeof path, "%s/%s", tmpdir, name);
    cdvr_store *st = NULL;
    if (cdvr_store_encode(vol, &o, path, err) == CDVR_OK)
        cdvr_store_open(path, &st, err);
    return st;
}

typedef struct capture {
    cdvr_image *img[FRAMES];
    cdvr_frame_row row[FRAMES];
    int cam_calls;
    cdvr_camera cam;
} capture;

static cdvr_status keep_frame(void *ud, const cdvr_frame_row *row, const cdvr_image *img,
                              cdvr_error *err)
{
    capture *c = ud;
    if (row->frame >= FRAMES || !img) /* img NULL: the frame failed (its row says why) */
        return CDVR_OK;
    cdvr_image *copy;
    cdvr_status s = cdvr_image_create(img->width, img->height, &copy, err);
    if (s != CDVR_OK)
        return s;
    memcpy(copy->rgba, img->rgba, (size_t)img->width * img->height * 4 * sizeof(float));
    memcpy(copy->background, img->background, sizeof copy->background);
    cdvr_image_free(c->img[row->frame]);
    c->img[row->frame] = copy;
    c->row[row->frame] = *row;
    return CDVR_OK;
}

static cdvr_status count_camera(void *ud, size_t t, size_t frame, cdvr_camera *cam,
                                cdvr_error *err)
{
    (void)t, (void)frame, (void)err;
    capture *c = ud;
    c->cam_calls++;
    *cam = c->cam;
    return CDVR_OK;
}

static void free_capture(capture *c)
{
    for (int i = 0; i < FRAMES; i++)
        cdvr_image_free(c->img[i]);
    memset(c, 0, sizeof *c);
}

/* Plays FRAMES frames of variant v with the camera through a callback. */
static void play(cdvr_store *st, const cdvr_tf *tf, const cdvr_camera *cam, int v, int skip,
                 int pipelined, capture *c)
{
    c->cam = *cam;
    cdvr_player_opts o = {.store = st, .device = CDVR_DEVICE_CPU, .tf = tf, .camera = *cam,
                          .threads = 2, .variant = v, .pipelined = pipelined, .loop = 1,
                          .brick_skip = skip, .camera_fn = count_camera, .camera_ud = c,
                          .frame_fn = keep_frame, .frame_ud = c};
    cdvr_player *p;
    cdvr_error err;
    cdvr_status s = cdvr_player_create(&o, &p, &err);
    CHECK_OK(s, err);
    if (s != CDVR_OK)
        return;
    s = cdvr_player_run(p, 0, FRAMES, &err);
    CHECK_OK(s, err);
    size_t n;
    cdvr_player_rows(p, &n);
    CHECK(n == FRAMES && c->cam_calls == FRAMES, "rows %zu, camera calls %d", n, c->cam_calls);
    cdvr_player_free(p);
}

/* Plays with and without skipping; returns the fewest bricks skipped over the frames and
 * checks the images (lossless variant 0: identical; lossy: >= 50 dB). */
static size_t compare_skip(cdvr_store *st, const cdvr_tf *tf, const cdvr_camera *cam, int v,
                           int pipelined, const char *what)
{
    capture on = {0}, off = {0};
    play(st, tf, cam, v, 1, pipelined, &on);
    play(st, tf, cam, v, 0, pipelined, &off);
    size_t fewest = 16;
    for (int f = 0; f < FRAMES; f++) {
        if (!on.img[f] || !off.img[f]) {
            CHECK(0, "%s: frame %d missing", what, f);
            continue;
        }
        cdvr_compare_result r;
        cdvr_compare_images(on.img[f], off.img[f], &r, NULL);
        /* the samples are those of the render without skipping: the same pixels */
        CHECK(memcmp(on.img[f]->rgba, off.img[f]->rgba,
                     (size_t)cam->width * cam->height * 4 * sizeof(float)) == 0,
              "%s frame %d: skipping changed pixels (psnr %.1f dB)", what, f, r.psnr);
        CHECK(r.psnr >= 50.0, "%s frame %d: %.1f dB against no skipping", what, f, r.psnr);
        CHECK(off.row[f].bricks_read == 16 && off.row[f].bricks_skipped == 0,
              "%s: no skipping reads all 16 bricks (%zu)", what, off.row[f].bricks_read);
        CHECK(on.row[f].bricks_read + on.row[f].bricks_skipped == 16, "%s: brick counts", what);
        if (on.row[f].bricks_skipped < fewest)
            fewest = on.row[f].bricks_skipped;
    }
    free_capture(&on);
    free_capture(&off);
    return fewest;
}

static cdvr_camera camera(double ex, double ey, double ez, double cx, double cy, double cz,
                          double fov)
{
    cdvr_camera c = {{ex, ey, ez}, {cx, cy, cz}, {0, 0, 1}, fov, 48, 40, 0, 0};
    return c;
}

static void test_skipping(void)
{
    cdvr_error err;
    cdvr_volume *vol = make_series();
    cdvr_store *st = vol ? encode(vol, "half.cdv", &err) : NULL;
    CHECK(st != NULL, "encode: %s", err.msg);
    if (!st) {
        cdvr_volume_free(vol);
        return;
    }
    /* hides every value below 135: the low-x half of the volume (x < 21 of 41) */
    cdvr_tf_point half[] = {{0, 0, 0, 0, 0}, {134, 0, 0, 0, 0}, {135, 1, .5, .2, .02},
                            {255, .9, .9, 1, .3}};
    cdvr_tf_point all[] = {{0, .2, .3, .9, .02}, {255, 1, .8, .4, .2}};
    cdvr_tf tf_half, tf_all;
    CHECK_OK(cdvr_tf_init(&tf_half, half, 4, 0, &err), err);
    CHECK_OK(cdvr_tf_init(&tf_all, all, 2, 0, &err), err);
    cdvr_camera outside = camera(20, -70, 40, 20, 14, 11, 30);
    /* inside the volume, in the high half, looking towards +x: the bricks behind are unseen */
    cdvr_camera inside = camera(26, 14, 11, 60, 16, 12, 50);
    for (int v = 0; v < 2; v++)
        for (int pipe = 0; pipe < 2; pipe++) {
            char what[64];
            snprintf(what, sizeof what, "%s %s", v ? "pvtc" : "raw", pipe ? "pipelined" : "serial");
            size_t s = compare_skip(st, &tf_half, &outside, v, pipe, what);

            /* a lossy variant also reads the lower neighbours of the bricks it renders */
            CHECK(s >= (v ? 4u : 8u), "%s: half-hiding TF skips the low bricks (%zu)", what, s);
            s = compare_skip(st, &tf_half, &inside, v, pipe, what);
            CHECK(s >= (v ? 4u : 8u), "%s, camera inside: %zu skipped", what, s);
            s = compare_skip(st, &tf_all, &inside, v, pipe, what);
            CHECK(s >= 4, "%s, camera inside, opaque TF: %zu skipped behind the eye", what, s);
            s = compare_skip(st, &tf_all, &outside, v, pipe, what);
            CHECK(s == 0, "%s: the whole volume in view, nothing hidden: %zu skipped", what, s);
        }
    /* a view that misses the volume: nothing read, a transparent frame */
    capture c = {0};
    cdvr_camera away = camera(20, -70, 40, 20, -140, 40, 20);
    play(st, &tf_all, &away, 0, 1, 1, &c);
    CHECK(c.row[0].bricks_read == 0 && c.row[0].bytes == 0, "nothing read (%zu)",
          c.row[0].bricks_read);
    CHECK(c.img[0] && c.img[0]->rgba[3] == 0.0f, "transparent frame");
    free_capture(&c);
    cdvr_store_close(st);
    cdvr_volume_free(vol);
}

/* Plays frames with opts->region/stride (and the camera callback), capturing them. */
static void play_opts(cdvr_player_opts *o, size_t frames, capture *c)
{
    o->camera_fn = count_camera;
    o->camera_ud = c;
    o->frame_fn = keep_frame;
    o->frame_ud = c;
    cdvr_player *p;
    cdvr_error err;
    cdvr_status s = cdvr_player_create(o, &p, &err);
    CHECK_OK(s, err);
    if (s != CDVR_OK)
        return;
    CHECK_OK(cdvr_player_run(p, 0, frames, &err), err);
    cdvr_player_free(p);
}

/* What distribute="bricks" does, in one process: each part of the k-d partition plays its
 * region of bricks (clipped, lossy variants reading the bricks below), the frames blended in
 * cdvr_dist_order equal the whole player's (early termination off). And distribute="time":
 * a stride and phase play every third frame with the whole sequence's numbers. */
static void test_regions(void)
{
    cdvr_error err;
    cdvr_volume *vol = make_series();
    cdvr_store *st = vol ? encode(vol, "regions.cdv", &err) : NULL;
    CHECK(st != NULL, "encode");
    if (!st) {
        cdvr_volume_free(vol);
        return;
    }
    const cdvr_store_info *info = cdvr_store_get_info(st);
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {60, .2, .3, .9, .05}, {200, 1, .6, .2, .3},
                           {255, 1, 1, 1, .6}};
    cdvr_tf tf;
    CHECK_OK(cdvr_tf_init(&tf, pts, 4, 0, &err), err);
    cdvr_camera cams[2] = {camera(20, -70, 40, 20, 14, 11, 30), camera(26, 14, 11, 60, 16, 12, 50)};
    for (int v = 0; v < 2; v++)
        for (int ci = 0; ci < 2; ci++) {
            cdvr_player_opts base = {.store = st, .device = CDVR_DEVICE_CPU, .tf = &tf,
                                     .camera = cams[ci], .threads = 2, .variant = v,
                                     .pipelined = 1, .loop = 1, .brick_skip = 1,
                                     .term_alpha = 1.0};
            capture whole = {0}, parts[4];
            memset(parts, 0, sizeof parts);
            whole.cam = cams[ci];
            play_opts(&base, 3, &whole);
            for (size_t k = 0; k < 4; k++) {
                cdvr_player_opts o = base;
                parts[k].cam = cams[ci];
                if (!cdvr_dist_partition(info->bricks, 4, k, o.region_lo, o.region_hi)) {
                    memcpy(o.region_lo, info->bricks, sizeof o.region_lo); /* empty region */
                    memcpy(o.region_hi, info->bricks, sizeof o.region_hi);
                }
                play_opts(&o, 3, &parts[k]);
            }
            cdvr_dist_view view;
            cdvr_dist_view_of(info, &cams[ci], &view);
            int order[4];
            cdvr_dist_order(info->dims, info->bricks, 4, &view, order);
            for (int f = 0; f < 3; f++) {
                cdvr_image *blend = NULL;
                if (!whole.img[f] || cdvr_image_create(48, 40, &blend, NULL) != CDVR_OK)
                    continue;
                memcpy(blend->background, whole.img[f]->background, sizeof blend->background);
                for (int k = 0; k < 4; k++) {
                    const cdvr_image *im = parts[order[k]].img[f];
                    for (size_t i = 0; im && i < 48 * 40; i++) {
                        float rest = 1.0f - blend->rgba[4 * i + 3];
                        for (int c = 0; c < 4; c++)
                            blend->rgba[4 * i + c] += rest * im->rgba[4 * i + c];
                    }
                }
                cdvr_compare_result r;
                cdvr_compare_images(blend, whole.img[f], &r, NULL);
                CHECK(r.psnr >= 50.0, "variant %d camera %d frame %d: regions blended %.1f dB",
                      v, ci, f, r.psnr);
                cdvr_image_free(blend);
            }
            free_capture(&whole);
            for (int k = 0; k < 4; k++)
                free_capture(&parts[k]);
        }
    /* a stride: frames 1 and 4 of 0..5, with their own numbers and timesteps */
    capture c = {0};
    c.cam = cams[0];
    cdvr_player_opts o = {.store = st, .device = CDVR_DEVICE_CPU, .tf = &tf, .camera = cams[0],
                          .threads = 2, .pipelined = 1, .loop = 1, .frame_stride = 3,
                          .frame_phase = 1};
    play_opts(&o, FRAMES, &c);
    CHECK(c.cam_calls == 2 && c.img[1] && c.img[4] && !c.img[0] && !c.img[2] && !c.img[3] &&
              !c.img[5], "stride 3 phase 1: frames 1 and 4 (%d camera calls)", c.cam_calls);
    CHECK(c.row[4].t == 0 && c.row[4].frame == 4 && c.row[1].t == 1, "timesteps of the whole run");
    free_capture(&c);
    cdvr_store_close(st);
    cdvr_volume_free(vol);
}

/* Boxes in front, behind, beside and around the eye. */
static void test_sees_box(void)
{
    cdvr_camera cam = camera(0, 0, 0, 1, 0, 0, 60); /* looking along +x, up z */
    double box[8][3];
    struct {
        double lo[3], hi[3];
        int seen;
    } cases[] = {
        {{5, -1, -1}, {6, 1, 1}, 1},     /* straight ahead */
        {{-6, -1, -1}, {-5, 1, 1}, 0},   /* behind */
        {{5, 20, -1}, {6, 21, 1}, 0},    /* far to the left of the view */
        {{5, -1, 10}, {6, 1, 11}, 0},    /* above the view */
        {{-1, -1, -1}, {1, 1, 1}, 1},    /* around the eye */
        {{5, 3.5, -1}, {6, 4, 1}, 1},    /* at the side edge (tan 30 * 48/40 * 6 = 4.16) */
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        for (int c = 0; c < 8; c++)
            for (int a = 0; a < 3; a++)
                box[c][a] = (c >> a) & 1 ? cases[i].hi[a] : cases[i].lo[a];
        CHECK(cdvr_camera_sees_box(&cam, (const double(*)[3])box) == cases[i].seen,
              "box %zu seen %d", i, cases[i].seen);
    }
    cam.orthographic = 1;
    cam.ortho_height = 2;
    double behind[8][3], side[8][3];
    for (int c = 0; c < 8; c++)
        for (int a = 0; a < 3; a++) {
            behind[c][a] = (c >> a) & 1 ? -5 : -6;
            side[c][a] = a == 0 ? ((c & 1) ? 6 : 5) : ((c >> a) & 1 ? 3 : 2);
        }
    CHECK(!cdvr_camera_sees_box(&cam, (const double(*)[3])behind), "ortho: behind");
    CHECK(!cdvr_camera_sees_box(&cam, (const double(*)[3])side), "ortho: beside the parallel view");
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "%s/cdvr_test_player_bricks_XXXXXX",
             getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 1;
    }
    test_sees_box();
    test_skipping();
    test_regions();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmpdir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmpdir);
    return check_finish();
}
