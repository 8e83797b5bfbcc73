/* core/render/render_check.c (cdvr_render_opts_check): render work is bounded. A step below
 * 1/64 of the smallest voxel spacing, a step that puts more than 2^24 samples on the box's
 * diagonal, a non-finite or negative step or unit, and a NaN or negative term_alpha are
 * refused with the option, its value and the limit named; the limit itself and the defaults
 * pass. Every renderer gets the check: the CPU ray caster, splatting, OpenCL and GL slicing
 * (where a device or display exists here) and the player refuse step = 1e-6 at once instead of
 * rendering for ever (an alarm ends the test if one does not), and the player refuses rates of
 * 1e-300. */
#include <math.h>
#include <signal.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/device.h"
#include "cdvr/codec.h"
#include "cdvr/gl.h"
#include "cdvr/player.h"
#include "cdvr/render.h"
#include "cdvr/splat.h"
#include "cdvr/store.h"
#include "check.h"

static void check_refused(const cdvr_volume *v, cdvr_render_opts o, const char *what, const char *words)
{
    cdvr_error err;
    cdvr_status s = cdvr_render_opts_check(v, &o, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, words), "%s refused naming \"%s\": %s", what, words,
          s ? err.msg : "accepted");
}

static void check_accepted(const cdvr_volume *v, cdvr_render_opts o, const char *what)
{
    cdvr_error err;
    CHECK_OK(cdvr_render_opts_check(v, &o, &err), err);
    (void)what;
}

static void check_function(void)
{
    cdvr_volume v = {.dims = {64, 64, 64}, .timesteps = 1, .spacing = {1, 2, 0.5}};
    cdvr_render_opts o = {0};
    check_accepted(&v, o, "defaults");
    o.step = 0.5 / 64;
    check_accepted(&v, o, "the limit itself");
    o.step = 0.5 / 64 * 0.999;
    check_refused(&v, o, "just below the limit", "below 1/64 of the smallest voxel spacing 0.5");
    o.step = 1e-6;
    check_refused(&v, o, "step 1e-6", "step 1e-06 is below 1/64");
    check_refused(&v, o, "step 1e-6 (limit named)", "the limit: step >= 0.0078125");
    o.step = INFINITY;
    check_refused(&v, o, "step inf", "step inf must be finite");
    o.step = NAN;
    check_refused(&v, o, "step NaN", "step nan must be finite");
    o.step = -1;
    check_refused(&v, o, "step -1", "step -1 must be finite and >= 0");
    o.step = 1e300;
    check_accepted(&v, o, "a step longer than the box (one segment)");
    o.step = 0;
    o.unit = INFINITY;
    check_refused(&v, o, "unit inf", "unit inf");
    o.unit = 0;
    o.term_alpha = NAN;
    check_refused(&v, o, "term_alpha NaN", "term_alpha nan");
    o.term_alpha = 5;
    check_accepted(&v, o, "term_alpha >= 1 (no early termination)");
    o.term_alpha = 0;
    /* very anisotropic spacing: the smallest spacing allows a step that is 2^24+ samples long */
    cdvr_volume flat = {.dims = {4096, 4096, 2}, .timesteps = 1, .spacing = {1, 1, 1e-6}};
    check_refused(&flat, o, "2^24 samples along the diagonal", "per ray");
    cdvr_volume bad = {.dims = {4, 4, 4}, .timesteps = 1, .spacing = {1, 0, 1}};
    check_refused(&bad, o, "spacing 0", "spacing 0 (axis 1)");
    /* a clipped render checks the whole volume's box */
    cdvr_render_clip clip = {.whole_dims = {4096, 4096, 2}};
    cdvr_volume part = {.dims = {2, 2, 2}, .timesteps = 1, .spacing = {1, 1, 1e-6}};
    o.clip = &clip;
    check_refused(&part, o, "clip: the whole box's diagonal", "per ray");
}

static cdvr_volume *make_volume(void)
{
    size_t dims[3] = {16, 16, 16};
    cdvr_volume *v = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 2, CDVR_TYPE_U8, &v, &err), err);
    if (v)
        for (size_t i = 0; i < 16 * 16 * 16 * 2; i++)
            ((unsigned char *)v->data)[i] = (unsigned char)(i * 7);
    return v;
}

static cdvr_camera make_camera(void)
{
    cdvr_camera cam = {.eye = {40, 30, 20}, .center = {7.5, 7.5, 7.5}, .up = {0, 0, 1}, .fov = 30,
                       .width = 32, .height = 32};
    return cam;
}

/* Each renderer refuses step = 1e-6 at once (before this, the CPU path rendered for ever). */
static void check_renderers(const cdvr_volume *v, const cdvr_tf *tf, const cdvr_camera *cam)
{
    cdvr_error err;
    cdvr_image *img = NULL;
    cdvr_render_opts o = {.tf = tf, .camera = cam, .step = 1e-6};
    CHECK(cdvr_render_cpu(v, 0, &o, &img, &err) == CDVR_ERR_ARG && strstr(err.msg, "below 1/64") && !img,
          "cpu refuses step 1e-6: %s", err.msg);
    cdvr_splat_opts so = {.tf = tf, .camera = cam, .unit = NAN};
    CHECK(cdvr_render_splat(v, 0, &so, &img, &err) == CDVR_ERR_ARG && strstr(err.msg, "unit nan") && !img,
          "splat refuses unit NaN: %s", err.msg);
#if CDVR_HAVE_GL
    cdvr_gl *gl = NULL;
    if (cdvr_gl_create(&gl, &err) == CDVR_OK) {
        CHECK(cdvr_gl_slice(gl, v, 0, &o, 0, NULL, &img, &err) == CDVR_ERR_ARG && strstr(err.msg, "below 1/64"),
              "GL slicing refuses step 1e-6: %s", err.msg);
        cdvr_gl_free(gl);
    } else {
        printf("note: no GL here (%s): GL slicing not checked\n", err.msg);
    }
#endif
#if CDVR_HAVE_OPENCL
    cdvr_cl *cl = NULL;
    cdvr_cl_stream *s = NULL;
    if (cdvr_cl_open(&cl, &err) == CDVR_OK) {
        cdvr_status st = cdvr_cl_stream_create(cl, v->dims, &s, &err);
        if (st == CDVR_OK)
            st = cdvr_cl_upload_frames(s, v->data, 1, &err);
        if (st == CDVR_OK)
            st = cdvr_cl_setup(s, 0, tf, &err);
        if (st == CDVR_OK)
            st = cdvr_image_create(cam->width, cam->height, &img, &err);
        CHECK_OK(st, err);
        if (st == CDVR_OK)
            CHECK(cdvr_cl_render(s, 0, &o, v->spacing, v->origin, v->direction, img, &err) == CDVR_ERR_ARG &&
                      strstr(err.msg, "below 1/64"),
                  "OpenCL refuses step 1e-6: %s", err.msg);
        cdvr_image_free(img);
        img = NULL;
        cdvr_cl_stream_free(s);
        cdvr_cl_close(cl);
    } else {
        printf("note: no OpenCL device here (%s): cdvr_cl_render not checked\n", err.msg);
    }
#endif
}

/* The player refuses step 1e-6 and rates of 1e-300 when it is made. */
static void check_player(const cdvr_volume *v, const cdvr_tf *tf, const cdvr_camera *cam)
{
    char path[] = "render_check_XXXXXX.cdv";
    int fd = mkstemps(path, 4);
    CHECK(fd >= 0, "mkstemps");
    close(fd);
    cdvr_variant_spec vs = {.codec = cdvr_codec_find("raw"), .lzo_min_saving = -1};
    vs.codec->params_default(&vs.params);
    cdvr_encode_opts eo = {.variants = &vs, .nvariants = 1, .qlo = 0, .qhi = 255, .source_type = CDVR_TYPE_U8};
    cdvr_error err;
    cdvr_store *st = NULL;
    cdvr_status s = cdvr_store_encode(v, &eo, path, &err);
    if (s == CDVR_OK)
        s = cdvr_store_open(path, &st, &err);
    CHECK_OK(s, err);
    if (s != CDVR_OK) {
        unlink(path);
        return;
    }
    struct { double step, read_mbps, pace_fps; const char *words; } cases[] = {
        {1e-6, 0, 0, "player: step 1e-06 is below 1/64"},
        {0, 1e-300, 0, "read_mbps 1e-300 outside 0.001"},
        {0, 0, 1e-300, "pace_fps 1e-300 outside 0.001"},
        {0, NAN, 0, "read_mbps nan"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        cdvr_player_opts po = {.store = st, .tf = tf, .camera = *cam, .step = cases[i].step,
                               .read_mbps = cases[i].read_mbps, .pace_fps = cases[i].pace_fps};
        cdvr_player *p = NULL;
        s = cdvr_player_create(&po, &p, &err);
        CHECK(s == CDVR_ERR_ARG && !p && strstr(err.msg, cases[i].words), "player refuses \"%s\": %s",
              cases[i].words, s ? err.msg : "accepted");
        cdvr_player_free(p);
    }
    cdvr_player_opts ok = {.store = st, .tf = tf, .camera = *cam, .read_mbps = 1e-3, .pace_fps = 1e-3};
    cdvr_player *p = NULL;
    CHECK_OK(cdvr_player_create(&ok, &p, &err), err);
    cdvr_player_free(p);
    cdvr_store_close(st);
    unlink(path);
}

int main(void)
{
    alarm(120); /* a renderer that does not refuse would run for ever: end the test instead */
    check_function();
    cdvr_volume *v = make_volume();
    cdvr_tf tf;
    cdvr_error err;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {255, 1, 1, 1, 0.5}};
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 0.0, &err), err);
    cdvr_camera cam = make_camera();
    if (v) {
        check_renderers(v, &tf, &cam);
        check_player(v, &tf, &cam);
    }
    cdvr_volume_free(v);
    return check_finish();
}
