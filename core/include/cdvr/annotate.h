/* cdvr/annotate.h - annotations drawn onto a rendered image: a scalar bar of the transfer
 * function, orientation letters, a title and the timestep, in a bundled bitmap font
 * (cdvr/text.h). The renderers never draw these: a caller (cdvr.render's annotate=, the
 * window, capture, img:annotate) calls cdvr_annotate on the finished image.
 *
 * Layout (W x H image, text scale s = max(1, round(min(W, H) / 256)), margin m = 6 s):
 *   title        top-left at (m, m), scale 2 s
 *   time         bottom-left, its baseline m above the bottom edge
 *   colour bar   right edge: a vertical bar from 45% to 90% of the height, bar width
 *                max(8, W / 32) pixels, its right edge at W - m - (widest tick label) - 5 s;
 *                the left 2/3 of the bar is the TF's colour at each value (opaque), the right
 *                1/3 its opacity as grey (white = the largest opacity in the bar's range, whose
 *                value is printed above the bar as "a<=0.72"); hi at the top. 2 to 6 ticks at
 *                "nice" values (1, 2, 5 x 10^k) labelled in data units, the unit (when given)
 *                above the bar. cdvr_annotate_bar_box returns the bar's rectangle.
 *   letters      one patient-direction label at the middle of each edge: the direction of
 *                screen right, left, up and down in patient terms (cdvr_annotate_letters), the
 *                right one inside the right edge above the bar's top.
 *
 * Orientation: cameras are in world coordinates (DESIGN.md section 6), which are the file's
 * patient coordinates: for a NRRD with `space: left-posterior-superior` (and cdvr's default)
 * +x = L(eft), +y = P(osterior), +z = S(uperior) ("LPS", DICOM's and ITK's convention); a NIfTI
 * file's world is RAS+ (+x = R, +y = A, +z = S): pass space = "RAS". The volume's direction
 * matrix is already in that world (it maps voxel indices into it), so the letters depend only
 * on the camera and the space's letters.
 */
#ifndef CDVR_ANNOTATE_H
#define CDVR_ANNOTATE_H

#include "cdvr/camera.h"
#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/tf.h"

typedef struct cdvr_annotate_opts {
    int colorbar;              /* draw the scalar bar: needs tf */
    const cdvr_tf *tf;         /* its table built over the data's window (cdvr_tf_apply_window) */
    double range[2];           /* data values at the bar's bottom and top; lo == hi (e.g. both
                                  0): tf->window, the range its table spans */
    const char *unit;          /* unit printed above the bar (e.g. "HU"); NULL or "" none */
    int axes;                  /* orientation letters: needs camera */
    const cdvr_camera *camera; /* the camera the image was rendered with */
    const char *space;         /* letters of world +x, +y, +z: "LPS" (NULL: default) or "RAS",
                                  any permutation of one of L/R, P/A, S/I each */
    const char *title;         /* NULL or "": none */
    const char *time;          /* e.g. "t = 3 / 25"; NULL or "": none */
    float color[3];            /* text and tick colour; all 0: white */
} cdvr_annotate_opts;

/* Draws what o asks for onto img. Errors (CDVR_ERR_ARG): colorbar without tf, axes without
 * camera, a bad space string, a camera that is not valid. Nothing asked: img unchanged. */
cdvr_status cdvr_annotate(cdvr_image *img, const cdvr_annotate_opts *o, cdvr_error *err);

/* The patient label of world direction d (need not be unit): the letters of the axes whose
 * component is at least 0.25 of |d|, largest first, at most 3 ("L", "LP", ...; "" for d = 0),
 * with space as in cdvr_annotate_opts. Returns 0, or -1 for a bad space. out holds 4 bytes. */
int cdvr_annotate_letters(const double d[3], const char *space, char out[4]);

/* The colour bar's rectangle [x0, x1) x [y0, y1) on a width x height image (see the layout;
 * the tick labels of tf over range decide its x). */
void cdvr_annotate_bar_box(int width, int height, const cdvr_annotate_opts *o, int box[4]);

#endif
