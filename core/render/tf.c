/* core/render/tf.c - piecewise-linear transfer functions (cdvr/tf.h). */
#include "cdvr/tf.h"

#include <math.h>

static int in_unit_range(double x)
{
    return isfinite(x) && x >= 0.0 && x <= 1.0;
}

static cdvr_status check_point(const cdvr_tf_point *p, size_t index, int normalized,
                               cdvr_error *err)
{
    if (!isfinite(p->value) || (normalized && !in_unit_range(p->value)))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: point %zu: value %g %s", index + 1, p->value,
                              normalized ? "outside [0, 1] (a normalised TF: fractions of the "
                                           "data's value window)"
                                         : "is not finite");
    if (!in_unit_range(p->r) || !in_unit_range(p->g) || !in_unit_range(p->b) ||
        !in_unit_range(p->a))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: point %zu (value %g): r, g, b, a must be in "
                              "[0, 1], got %g, %g, %g, %g",
                              index + 1, p->value, p->r, p->g, p->b, p->a);
    return CDVR_OK;
}

/* Stable insertion sort by value: equal values keep their given order, so a step
 * (two points at one value) stays a step. */
static void sort_points(cdvr_tf_point *pts, size_t n)
{
    for (size_t i = 1; i < n; i++) {
        cdvr_tf_point key = pts[i];
        size_t j = i;
        while (j > 0 && pts[j - 1].value > key.value) {
            pts[j] = pts[j - 1];
            j--;
        }
        pts[j] = key;
    }
}

/* Function value at v: constant outside the points, linear between them; at a repeated
 * value the later point wins (right-continuous). */
void cdvr_tf_eval(const cdvr_tf *tf, double v, float out[4])
{
    const cdvr_tf_point *pts = tf->points;
    size_t n = tf->npoints;
    const cdvr_tf_point *p, *q;
    if (v < pts[0].value) {
        p = q = &pts[0];
    } else if (v >= pts[n - 1].value) {
        p = q = &pts[n - 1];
    } else {
        size_t k = 0; /* largest k with pts[k].value <= v; k < n - 1 here */
        while (pts[k + 1].value <= v)
            k++;
        p = &pts[k];
        q = &pts[k + 1];
    }
    double f = q->value > p->value ? (v - p->value) / (q->value - p->value) : 0.0;
    out[0] = (float)(p->r + f * (q->r - p->r));
    out[1] = (float)(p->g + f * (q->g - p->g));
    out[2] = (float)(p->b + f * (q->b - p->b));
    out[3] = (float)(p->a + f * (q->a - p->a));
}

static void build_table(cdvr_tf *tf, double lo, double hi)
{
    tf->window[0] = lo;
    tf->window[1] = hi;
    for (int i = 0; i < 256; i++) {
        double x;
        if (tf->normalized)
            x = i / 255.0;
        else
            x = i == 255 ? hi : lo + (hi - lo) * i / 255.0;
        cdvr_tf_eval(tf, x, tf->table[i]);
    }
}

static cdvr_status init(cdvr_tf *tf, const cdvr_tf_point *points, size_t npoints, double unit,
                        int normalized, cdvr_error *err)
{
    if (!tf || (!points && npoints))
        return cdvr_error_set(err, CDVR_ERR_ARG, "transfer function: NULL argument");
    if (npoints == 0 || npoints > CDVR_TF_MAX_POINTS)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: %zu control points (need 1 to %d)", npoints,
                              CDVR_TF_MAX_POINTS);
    if (!isfinite(unit) || unit < 0.0)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: unit %g must be >= 0 (0 = one voxel)", unit);
    for (size_t i = 0; i < npoints; i++) {
        cdvr_status st = check_point(&points[i], i, normalized, err);
        if (st != CDVR_OK)
            return st;
    }
    for (size_t i = 0; i < npoints; i++)
        tf->points[i] = points[i];
    tf->npoints = npoints;
    tf->unit = unit;
    tf->normalized = normalized;
    sort_points(tf->points, npoints);
    build_table(tf, 0.0, 255.0);
    return CDVR_OK;
}

cdvr_status cdvr_tf_init(cdvr_tf *tf, const cdvr_tf_point *points, size_t npoints, double unit,
                         cdvr_error *err)
{
    return init(tf, points, npoints, unit, 0, err);
}

cdvr_status cdvr_tf_init_normalized(cdvr_tf *tf, const cdvr_tf_point *points, size_t npoints,
                                    double unit, cdvr_error *err)
{
    return init(tf, points, npoints, unit, 1, err);
}

static cdvr_status check_window(double lo, double hi, const char *what, cdvr_error *err)
{
    if (!isfinite(lo) || !isfinite(hi) || hi < lo)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: %s [%g, %g] must be finite with lo <= hi",
                              what, lo, hi);
    return CDVR_OK;
}

cdvr_status cdvr_tf_set_window(cdvr_tf *tf, double lo, double hi, cdvr_error *err)
{
    cdvr_status st = check_window(lo, hi, "value window", err);
    if (st == CDVR_OK)
        build_table(tf, lo, hi);
    return st;
}

cdvr_status cdvr_tf_rescale(cdvr_tf *tf, double lo, double hi, cdvr_error *err)
{
    cdvr_status st = check_window(lo, hi, "range", err);
    if (st != CDVR_OK)
        return st;
    if (!tf->normalized)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: range applies to a normalised TF (a preset); "
                              "this one is in data units already");
    for (size_t i = 0; i < tf->npoints; i++)
        tf->points[i].value = lo + tf->points[i].value * (hi - lo);
    tf->normalized = 0;
    build_table(tf, lo, hi);
    return CDVR_OK;
}

void cdvr_tf_lookup(const cdvr_tf *tf, float v, float out[4])
{
    if (!(v > 0.0f))
        v = 0.0f; /* also NaN */
    if (v > 255.0f)
        v = 255.0f;
    int i0 = (int)v;
    if (i0 > 254)
        i0 = 254;
    float f = v - (float)i0;
    for (int c = 0; c < 4; c++)
        out[c] = tf->table[i0][c] + f * (tf->table[i0 + 1][c] - tf->table[i0][c]);
}
