/* tests/test_refine.c - coarse first, refined when the camera stops (cdvr/refine.h), on a
 * scripted sequence of cameras and times: the first frame renders at the requested lod_error;
 * a moved camera renders at moving_lod, and so does every frame until the camera has been
 * still for settle_ms; then a refine is due, its frame is at lod_error, and nothing more is
 * due; a resize counts as a move; settings are checked. */
#include "cdvr/refine.h"
#include "check.h"

static cdvr_camera camera(double x)
{
    cdvr_camera c = {.eye = {x, 0, 5}, .center = {0, 0, 0}, .up = {0, 1, 0}, .fov = 40,
                     .width = 64, .height = 48};
    return c;
}

int main(void)
{
    cdvr_refine r;
    cdvr_error err;
    CHECK_OK(cdvr_refine_init(&r, 1.0, 8.0, 200.0, &err), err);
    cdvr_camera a = camera(0), b = camera(0.5), c = camera(1.0);
    CHECK(!cdvr_refine_due(&r, 0), "nothing drawn, nothing due");
    CHECK(cdvr_refine_frame(&r, &a, 0) == 1.0, "the first frame: the requested lod_error");
    CHECK(!cdvr_refine_due(&r, 1000), "a still camera: nothing due");
    CHECK(cdvr_refine_frame(&r, &a, 1000) == 1.0, "the same camera: still fine");

    CHECK(cdvr_refine_frame(&r, &b, 1010) == 8.0, "moved: moving_lod");
    CHECK(cdvr_refine_frame(&r, &c, 1030) == 8.0, "moving on: moving_lod");
    CHECK(cdvr_refine_frame(&r, &c, 1100) == 8.0, "a pause shorter than settle_ms: coarse");
    CHECK(!cdvr_refine_due(&r, 1229), "not yet still for 200 ms");
    CHECK(cdvr_refine_due(&r, 1230), "still for 200 ms: a refine is due");
    CHECK(cdvr_refine_frame(&r, &c, 1230) == 1.0, "the refine frame: the requested lod_error");
    CHECK(!cdvr_refine_due(&r, 5000), "refined: nothing more due");

    cdvr_camera wide = c;
    wide.width = 128;
    CHECK(cdvr_refine_frame(&r, &wide, 6000) == 8.0, "a resize counts as a move");
    CHECK(cdvr_refine_due(&r, 6200), "and refines");

    /* new settings keep the history: a coarse frame is due for the new lod_error */
    CHECK_OK(cdvr_refine_configure(&r, 2.0, 4.0, 50.0, &err), err);
    CHECK(cdvr_refine_due(&r, 6300), "the last frame (8) is not at the new lod_error");
    CHECK(cdvr_refine_frame(&r, &wide, 6300) == 2.0, "refined at the new lod_error");

    /* moving_lod == lod_error: coarse-first off, never due */
    CHECK_OK(cdvr_refine_init(&r, 1.0, 1.0, 200.0, &err), err);
    cdvr_refine_frame(&r, &a, 0);
    CHECK(cdvr_refine_frame(&r, &b, 10) == 1.0 && !cdvr_refine_due(&r, 1000), "off");

    /* settle_ms 0: the moving frame is coarse, the next one refines */
    CHECK_OK(cdvr_refine_init(&r, 0.0, 4.0, 0.0, &err), err);
    cdvr_refine_frame(&r, &a, 0);
    CHECK(cdvr_refine_frame(&r, &b, 10) == 4.0 && cdvr_refine_due(&r, 10), "settle 0");

    CHECK(cdvr_refine_init(&r, 2.0, 1.0, 10, &err) == CDVR_ERR_ARG, "moving_lod < lod_error");
    CHECK(cdvr_refine_init(&r, -1.0, 1.0, 10, &err) == CDVR_ERR_ARG, "lod_error < 0");
    CHECK(cdvr_refine_init(&r, 1.0, 2.0, -1, &err) == CDVR_ERR_ARG, "settle_ms < 0");
    return check_finish();
}
