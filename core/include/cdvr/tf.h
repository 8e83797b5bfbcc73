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
#include "cdvr/volume.h"

#define CDVR_TF_MAX_POINTS 512 /* a 256-entry colour map plus its opacity points */

typedef struct cdvr_tf_point {
    double value, r, g, b, a;
} cdvr_tf_point;

/* Shading settings a preset carries (3D Slicer's presets: VTK volume-property vocabulary), for
 * a shaded renderer to take as its defaults; cdvr_tf_init leaves them absent. */
typedef struct cdvr_tf_shade {
    int present;          /* 1: the preset gave these */
    int on;               /* the preset's shade flag */
    double ambient, diffuse, specular, specular_power;
} cdvr_tf_shade;

typedef struct cdvr_tf {
    size_t npoints;
    cdvr_tf_point points[CDVR_TF_MAX_POINTS];
    int normalized;       /* 1: point values are fractions of the data's window */
    int auto_range;       /* 1 (normalised only): range="auto", the fractions are of the data's
                             percentile window (cdvr_tf_apply_window), not of its whole window */
    double percentiles[2];/* auto_range's percentiles in [0, 1] (default 0.01, 0.99) */
    char name[64];        /* the preset or colour map it came from, "" if none (messages) */
    cdvr_tf_shade shade;  /* a preset's shading settings */
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
 * entry TF(lo)), by the formula above. An auto_range TF is refused (its window needs the data:
 * cdvr_tf_apply_window or cdvr_tf_rescale_auto), so a caller that cannot honour range="auto"
 * says so instead of ignoring it. */
cdvr_status cdvr_tf_set_window(cdvr_tf *tf, double lo, double hi, cdvr_error *err);
/* Turns a normalised TF into one in data units over [lo, hi]: each point value p becomes
 * lo + p*(hi - lo) (ParaView's "rescale preset to a range"); the table is rebuilt over
 * [lo, hi]. A TF already in data units is an error. */
cdvr_status cdvr_tf_rescale(cdvr_tf *tf, double lo, double hi, cdvr_error *err);
/* Colour map + opacity: a normalised TF whose colour is the piecewise-linear map cmap (ncmap
 * points {x, r, g, b}, x in [0, 1] increasing) and whose opacity is the piecewise-linear
 * function of nalpha points {x, a} (x in [0, 1], any order; NULL / 0 = the ramp a = x). The
 * points are the union of both x sets, each function evaluated at the other's points, so the
 * TF equals both exactly; at most CDVR_TF_MAX_POINTS of them. */
cdvr_status cdvr_tf_init_colormap(cdvr_tf *tf, const double (*cmap)[4], size_t ncmap,
                                  const double (*alpha)[2], size_t nalpha, double unit,
                                  cdvr_error *err);
/* Percentile window of frame t of a u8 volume (codes standing for window[0..1], volume.h):
 * out = the data values of the codes at the p_lo and p_hi quantiles of the frame's histogram
 * (the smallest code whose cumulative count reaches p*N). When they coincide (a nearly
 * constant frame) the frame's min and max codes are used instead. 0 <= p_lo < p_hi <= 1. */
cdvr_status cdvr_tf_percentile_window(const cdvr_volume *u8, size_t t,
                                      const double window[2], double p_lo, double p_hi,
                                      double out[2], cdvr_error *err);
/* The table of tf for a frame whose codes span window[0..1]: cdvr_tf_set_window, except for
 * an auto_range TF, whose fractions are then of the percentile window of frame t of u8
 * (cdvr_tf_percentile_window with tf->percentiles): table[i] = TF((x_i - w0) / (w1 - w0)), x_i
 * as above (the fraction clamped to [0, 1]: constant outside). u8 may be NULL for a TF that is
 * not auto_range. Returns the window used in used[0..1] (NULL allowed). */
cdvr_status cdvr_tf_apply_window(cdvr_tf *tf, const double window[2],
                                 const cdvr_volume *u8, size_t t, double used[2],
                                 cdvr_error *err);
/* range="auto" resolved now, for callers that classify many frames (a player): tf's fractions
 * become data values over the percentile window of frame t of vol (tf->percentiles; any type:
 * a frame that is not u8 is quantised over the volume's window first), as cdvr_tf_rescale to
 * that window; the TF is then in data units and no longer auto_range. */
cdvr_status cdvr_tf_rescale_auto(cdvr_tf *tf, const cdvr_volume *vol, size_t t, cdvr_error *err);
/* 1 when a TF in data units shows nothing of data in [lo, hi]: its opacity is 0 at every
 * value of [lo, hi] (it is piecewise linear, so the points inside and both ends decide). 0 for
 * a normalised TF. For the "preset misses the data's range" warning. */
int cdvr_tf_misses_window(const cdvr_tf *tf, double lo, double hi);
/* The function itself at value v (data units; a fraction of the window when normalised). */
void cdvr_tf_eval(const cdvr_tf *tf, double v, float out[4]);
/* Table entry interpolated at fractional code v in [0,255] (clamped). */
void cdvr_tf_lookup(const cdvr_tf *tf, float v, float out[4]);

#endif
