/* tests/player_frames.h - shared by the player tests that compare every played frame with the
 * render of its timestep decoded alone: a frame callback that keeps each frame's pixels, and
 * that reference render on the cpu or cl device. Include after check.h. */
#ifndef CDVR_TESTS_PLAYER_FRAMES_H
#define CDVR_TESTS_PLAYER_FRAMES_H

#include "cdvr/device.h"
#include "cdvr/player.h"
#include "cdvr/render.h"
#include "cdvr/store.h"

#include <string.h>

/* Frames kept by frame number: frames x px floats (px = width x height x 4). */
typedef struct capture {
    float *pixels;
    size_t frames, px;
} capture;

static cdvr_status keep_frame(void *ud, const cdvr_frame_row *row, const cdvr_image *img,
                              cdvr_error *err)
{
    capture *c = ud;
    (void)err;
    if (img && row->frame < c->frames) /* img NULL: the frame failed (its row says why) */
        memcpy(c->pixels + row->frame * c->px, img->rgba, sizeof(float) * c->px);
    return CDVR_OK;
}

/* Renders timestep t of variant v of st, decoded by itself, with tf and cam into out
 * (cam->width x cam->height x 4 floats); 1 on success (a failure is a CHECK failure). */
static int render_alone(const cdvr_store *st, size_t v, size_t t, cdvr_device_kind device,
                        const cdvr_tf *tf, const cdvr_camera *cam, float *out)
{
    cdvr_volume *vol = NULL;
    cdvr_image *img = NULL;
    cdvr_error err;
    cdvr_error_clear(&err);
    cdvr_render_opts ro = {.tf = tf, .camera = cam};
    int ok = cdvr_store_decode(st, v, t, &vol, &err) == CDVR_OK;
    if (ok && device == CDVR_DEVICE_CPU)
        ok = cdvr_render_cpu(vol, 0, &ro, &img, &err) == CDVR_OK;
#if CDVR_HAVE_OPENCL
    if (ok && device == CDVR_DEVICE_CL) {
        cdvr_cl *cl = NULL;
        cdvr_cl_stream *s = NULL;
        ok = cdvr_cl_open(&cl, &err) == CDVR_OK &&
             cdvr_cl_stream_create(cl, vol->dims, &s, &err) == CDVR_OK &&
             cdvr_cl_upload_frames(s, vol->data, 1, &err) == CDVR_OK &&
             cdvr_cl_setup(s, 0, tf, &err) == CDVR_OK &&
             cdvr_image_create(cam->width, cam->height, &img, &err) == CDVR_OK &&
             cdvr_cl_render(s, 0, &ro, vol->spacing, vol->origin, vol->direction, img,
                            &err) == CDVR_OK;
        cdvr_cl_stream_free(s);
        cdvr_cl_close(cl);
    }
#endif
    CHECK(ok, "reference of timestep %zu: %s", t + 1, err.msg);
    if (ok)
        memcpy(out, img->rgba, sizeof(float) * (size_t)cam->width * cam->height * 4);
    cdvr_image_free(img);
    cdvr_volume_free(vol);
    return ok;
}

#endif
