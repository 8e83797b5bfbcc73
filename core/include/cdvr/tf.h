/* cdvr/tf.h - transfer functions in data units (ParaView / VTK convention).
 *
 * Control points (value, r, g, b, a) with r, g, b, a in [0, 1], sorted by value; the function
 * is piecewise linear between points and constant outside them (VTK's vtkPiecewiseFunction /
 * vtkColorTransferFunction with clamping); at a repeated value the later point wins, so two
 * points at one value make a step. `a` is the opacity of a segment of length `unit` (world
 * units).
 *
 * Point values are data values (Hounsfield units, densities, ...: any finite number), or,
 * for a normalised TF (`normalized`, what the presets of share/tf are), fractions in [0, 1] of
 * the value window of the data the TF is applied to.
 *
 * Renderers classify 8-bit codes: a frame is a u8 volume whose code q stands for the data
 * value lo + q*(hi - lo)/255 over the series' value window [lo, hi] (volume.h: the range of
 * the whole series, or the quantisation window of a store). The 256-entry table is the
 * function sampled at those values:
 *     table[i] = TF(x_i),  x_i = lo + (hi - lo) * i / 255  (i = 0..254, in double), x_255 = hi
 * for a TF in data units, and table[i] = TF(i / 255) for a normalised TF (the same table for
 * every window: a normalised TF follows the data's window, like a ParaView preset). Between
 * entries renderers interpolate linearly (render.h step 4), which is exact when every control
 * point falls on an x_i. cdvr_tf_init builds the table over [0, 255], where x_i = i: a u8
 * volume loaded from a file has that window, so its codes are its values.
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
    int normalized;       /* 1: point values are fractions of the data's window */
    double unit;          /* opacity unit length in world units; 0 -> one voxel spacing */
    double window[2];     /* the value window the table was built over */
    float table[256][4];  /* r, g, b, a (straight, a = opacity per `unit`) */
} cdvr_tf;

/* Builds tf from npoints control points in data units (any order; sorted here, stable; values
 * finite, colours and alpha in [0, 1]). The table spans the window [0, 255]. */
cdvr_status cdvr_tf_init(cdvr_tf *tf, const cdvr_tf_point *points, size_t npoints,
                         double unit, cdvr_error *err);
/* The same for a normalised TF: point values in [0, 1] of the data's window. */
cdvr_status cdvr_tf_init_normalized(cdvr_tf *tf, const cdvr_tf_point *points, size_t npoints,
                                    double unit, cdvr_error *err);
/* Rebuilds the table over the value window [lo, hi] (finite, lo <= hi; lo == hi gives every
 * entry TF(lo)), by the formula above. */
cdvr_status cdvr_tf_set_window(cdvr_tf *tf, double lo, double hi, cdvr_error *err);
/* Turns a normalised TF into one in data units over [lo, hi]: each point value p becomes
 * lo + p*(hi - lo) (ParaView's "rescale preset to a range"); the table is rebuilt over
 * [lo, hi]. A TF already in data units is an error. */
cdvr_status cdvr_tf_rescale(cdvr_tf *tf, double lo, double hi, cdvr_error *err);
/* The function itself at value v (data units; a fraction of the window when normalised). */
void cdvr_tf_eval(const cdvr_tf *tf, double v, float out[4]);
/* Table entry interpolated at fractional code v in [0,255] (clamped). */
void cdvr_tf_lookup(const cdvr_tf *tf, float v, float out[4]);

#endif
