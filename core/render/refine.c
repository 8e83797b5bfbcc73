/* core/render/refine.c - coarse first, refined when the camera stops (cdvr/refine.h). */
#include "cdvr/refine.h"

#include <string.h>

cdvr_status cdvr_refine_configure(cdvr_refine *r, double lod_error, double moving_lod,
                                  double settle_ms, cdvr_error *err)
{
    if (!(lod_error >= 0) || !(moving_lod >= lod_error) || moving_lod > 1e12 ||
        !(settle_ms >= 0) || settle_ms > 1e9)
        return cdvr_error_set(err, CDVR_ERR_ARG, "refine: lod_error %g, moving_lod %g, "
                              "settle_ms %g (0 <= lod_error <= moving_lod <= 1e12, 0 <= "
                              "settle_ms <= 1e9)", lod_error, moving_lod, settle_ms);
    r->lod_error = lod_error;
    r->moving_lod = moving_lod;
    r->settle_ms = settle_ms;
    return CDVR_OK;
}

cdvr_status cdvr_refine_init(cdvr_refine *r, double lod_error, double moving_lod,
                             double settle_ms, cdvr_error *err)
{
    memset(r, 0, sizeof *r);
    r->moved_ms = -1;
    return cdvr_refine_configure(r, lod_error, moving_lod, settle_ms, err);
}

static int same_camera(const cdvr_camera *a, const cdvr_camera *b)
{
    for (int i = 0; i < 3; i++)
        if (a->eye[i] != b->eye[i] || a->center[i] != b->center[i] || a->up[i] != b->up[i])
            return 0;
    return a->fov == b->fov && a->width == b->width && a->height == b->height &&
           a->orthographic == b->orthographic && a->ortho_height == b->ortho_height;
}

/* The camera moved less than settle_ms before now_ms. */
static int settling(const cdvr_refine *r, double now_ms)
{
    return r->moved_ms >= 0 && now_ms - r->moved_ms < r->settle_ms;
}

double cdvr_refine_frame(cdvr_refine *r, const cdvr_camera *cam, double now_ms)
{
    if (r->have_camera && !same_camera(&r->last, cam))
        r->moved_ms = now_ms;
    int moving = r->have_camera && (r->moved_ms == now_ms || settling(r, now_ms));
    r->last = *cam;
    r->have_camera = 1;
    r->drawn_lod = moving ? r->moving_lod : r->lod_error;
    return r->drawn_lod;
}

int cdvr_refine_due(const cdvr_refine *r, double now_ms)
{
    return r->have_camera && r->drawn_lod != r->lod_error && !settling(r, now_ms);
}
