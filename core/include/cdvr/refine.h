/* cdvr/refine.h - coarse first, refined when the camera stops (the window's level of detail
 * through the brick cache, cdvr/brick_cache.h; issue 26).
 *
 * While the camera moves, frames render at a coarser lod_error (moving_lod); once it has been
 * still for settle_ms, one more frame renders at the requested lod_error. The camera moves
 * when a frame's camera differs from the last frame's in any field (eye, centre, up, fov,
 * projection, size: a resized view re-chooses its levels too). A frame counts as moving when
 * its camera moved, or the last move is less than settle_ms old (a drag that pauses for a few
 * milliseconds stays coarse). The first frame of a state is not moving. A pure state machine
 * over the times and cameras it is given (no clock of its own), so the window's behaviour is
 * testable without a display (tests/test_refine.c).
 */
#ifndef CDVR_REFINE_H
#define CDVR_REFINE_H

#include "cdvr/camera.h"
#include "cdvr/error.h"

typedef struct cdvr_refine {
    double lod_error;  /* the still camera's lod_error (pixels) */
    double moving_lod; /* while the camera moves (>= lod_error) */
    double settle_ms;  /* still this long after the last move: refine */
    int have_camera;   /* a frame was drawn: last, moved_ms and drawn_lod hold */
    cdvr_camera last;  /* the camera of the last frame */
    double moved_ms;   /* when the camera last moved (-1: never) */
    double drawn_lod;  /* the last frame's lod_error */
} cdvr_refine;

/* A state with no frame drawn; CDVR_ERR_ARG unless 0 <= lod_error <= moving_lod <= 1e12 and
 * 0 <= settle_ms <= 1e9. */
cdvr_status cdvr_refine_init(cdvr_refine *r, double lod_error, double moving_lod,
                             double settle_ms, cdvr_error *err);
/* Changes the settings and keeps the camera history (the same checks as init). */
cdvr_status cdvr_refine_configure(cdvr_refine *r, double lod_error, double moving_lod,
                                  double settle_ms, cdvr_error *err);
/* The lod_error of a frame of camera cam drawn at now_ms (moving_lod while moving, above,
 * else lod_error); records the frame. */
double cdvr_refine_frame(cdvr_refine *r, const cdvr_camera *cam, double now_ms);
/* 1 when a frame should be drawn at now_ms to refine: the last frame was drawn at a lod_error
 * other than the requested one and the camera has been still for settle_ms since its last
 * move. */
int cdvr_refine_due(const cdvr_refine *r, double now_ms);

#endif
