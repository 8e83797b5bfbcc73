/* cdvr/tf.h - transfer functions.
 *
 * Control points (value in raw 8-bit units, r, g, b, a in [0,1]) sorted by value; the
 * function is piecewise linear between points and constant outside them (VTK's
 * vtkPiecewiseFunction / vtkColorTransferFunction with clamping). `a` is the opacity of a
 * segment of length `unit` (world units). table[i] is the function at value i, i = 0..255;
 * renderers read it at fractional values by linear interpolation between entries
 * (exact for integer control points).
 */
#ifndef CDVR_TF_H
#define CDVR_TF_H

#include <stddef.h>

#include "cdvr/error.h"

#define CDVR_TF_MAX_POINTS 256

typedef struct cdvr_tf_point {
    double value, r, g, b, a;
} cdvr_tf_point;

typedef struct cdvr_tf {
    size_t npoints;
    cdvr_tf_point points[CDVR_TF_MAX_POINTS];
    double unit;          /* opacity unit length in world units; 0 -> one voxel spacing */
    float table[256][4];  /* r, g, b, a (straight, a = opacity per `unit`) */
} cdvr_tf;

/* Builds tf from npoints control points (any order; sorted here; values clamped to [0,255]
 * are an error if outside; colours and alpha must be in [0,1]). Fills the table. */
cdvr_status cdvr_tf_init(cdvr_tf *tf, const cdvr_tf_point *points, size_t npoints,
                         double unit, cdvr_error *err);
/* Table entry interpolated at fractional value v in [0,255] (clamped). */
void cdvr_tf_lookup(const cdvr_tf *tf, float v, float out[4]);

#endif
