/* core/render/tf.c - piecewise-linear transfer functions (cdvr/tf.h). */
#include "cdvr/tf.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

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

/* The table over [lo, hi]; auto (may be NULL) is the percentile window of an auto_range TF,
 * whose fractions are then of auto rather than of [lo, hi]. */
static void build_table_auto(cdvr_tf *tf, double lo, double hi, const double *autow)
{
    tf->window[0] = lo;
    tf->window[1] = hi;
    for (int i = 0; i < 256; i++) {
        double x = i == 255 ? hi : lo + (hi - lo) * i / 255.0;
        if (tf->normalized && autow) {
            double w = autow[1] - autow[0];
            x = w > 0.0 ? (x - autow[0]) / w : (x >= autow[0] ? 1.0 : 0.0);
            x = x < 0.0 ? 0.0 : x > 1.0 ? 1.0 : x;
        } else if (tf->normalized) {
            x = i / 255.0;
        }
        cdvr_tf_eval(tf, x, tf->table[i]);
    }
}

static void build_table(cdvr_tf *tf, double lo, double hi)
{
    build_table_auto(tf, lo, hi, NULL);
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
    tf->auto_range = 0;
    tf->name[0] = '\0';
    memset(&tf->shade, 0, sizeof tf->shade);
    tf->percentiles[0] = 0.01;
    tf->percentiles[1] = 0.99;
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
    if (tf->normalized && tf->auto_range)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED,
                              "transfer function%s%s: range=\"auto\" needs the data to take its "
                              "percentiles from, which is not at hand here: pin it with "
                              "cdvr.tf(..., {range=\"auto\", volume=v}) or range={lo, hi}",
                              tf->name[0] ? " " : "", tf->name);
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
    tf->auto_range = 0;
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

/* ---- colour maps ---------------------------------------------------------------------------- */

/* Piecewise linear through (xs[k], ys[k][c]) (stride `stride` doubles per point, x first),
 * constant outside; xs increasing. */
static double pwl(const double *pts, size_t n, size_t stride, size_t c, double x)
{
    if (x <= pts[0])
        return pts[c];
    if (x >= pts[(n - 1) * stride])
        return pts[(n - 1) * stride + c];
    size_t k = 0;
    while (pts[(k + 1) * stride] < x)
        k++;
    const double *p = pts + k * stride, *q = p + stride;
    double f = q[0] > p[0] ? (x - p[0]) / (q[0] - p[0]) : 1.0;
    return p[c] + f * (q[c] - p[c]);
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static cdvr_status check_colormap(const double (*cmap)[4], size_t ncmap,
                                  const double (*alpha)[2], size_t nalpha, cdvr_error *err)
{
    if (!cmap || ncmap == 0 || ncmap > CDVR_TF_MAX_POINTS || (nalpha && !alpha))
        return cdvr_error_set(err, CDVR_ERR_ARG, "colour map: %zu colour points (need 1 to %d)",
                              ncmap, CDVR_TF_MAX_POINTS);
    for (size_t i = 0; i < ncmap; i++) {
        if (!in_unit_range(cmap[i][0]) || (i && !(cmap[i][0] > cmap[i - 1][0])))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "colour map: point %zu: x %g must be in [0, 1] and increasing",
                                  i + 1, cmap[i][0]);
    }
    for (size_t i = 0; i < nalpha; i++)
        if (!in_unit_range(alpha[i][0]) || !in_unit_range(alpha[i][1]))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "colour map opacity: point %zu: {x, a} = {%g, %g} must be in "
                                  "[0, 1] (x a fraction of the window)",
                                  i + 1, alpha[i][0], alpha[i][1]);
    return CDVR_OK;
}

cdvr_status cdvr_tf_init_colormap(cdvr_tf *tf, const double (*cmap)[4], size_t ncmap,
                                  const double (*alpha)[2], size_t nalpha, double unit,
                                  cdvr_error *err)
{
    static const double ramp[2][2] = {{0.0, 0.0}, {1.0, 1.0}};
    cdvr_status st = check_colormap(cmap, ncmap, alpha, nalpha, err);
    if (st != CDVR_OK)
        return st;
    if (!nalpha)
        alpha = ramp, nalpha = 2;
    double a[CDVR_TF_MAX_POINTS][2], xs[2 * CDVR_TF_MAX_POINTS];
    if (nalpha > CDVR_TF_MAX_POINTS)
        return cdvr_error_set(err, CDVR_ERR_ARG, "colour map: %zu opacity points (at most %d)",
                              nalpha, CDVR_TF_MAX_POINTS);
    memcpy(a, alpha, nalpha * sizeof a[0]);
    qsort(a, nalpha, sizeof a[0], cmp_double); /* by x (first member) */
    size_t n = 0;
    for (size_t i = 0; i < ncmap; i++)
        xs[n++] = cmap[i][0];
    for (size_t i = 0; i < nalpha; i++)
        xs[n++] = a[i][0];
    qsort(xs, n, sizeof xs[0], cmp_double);
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (m == 0 || xs[i] > xs[m - 1])
            xs[m++] = xs[i];
    if (m > CDVR_TF_MAX_POINTS)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "colour map: %zu points with its opacity's (at most %d)", m,
                              CDVR_TF_MAX_POINTS);
    cdvr_tf_point pts[CDVR_TF_MAX_POINTS];
    for (size_t i = 0; i < m; i++) {
        double x = xs[i];
        pts[i] = (cdvr_tf_point){x, pwl(cmap[0], ncmap, 4, 1, x), pwl(cmap[0], ncmap, 4, 2, x),
                                 pwl(cmap[0], ncmap, 4, 3, x), pwl(a[0], nalpha, 2, 1, x)};
        pts[i].r = pts[i].r < 0 ? 0 : pts[i].r > 1 ? 1 : pts[i].r;
        pts[i].g = pts[i].g < 0 ? 0 : pts[i].g > 1 ? 1 : pts[i].g;
        pts[i].b = pts[i].b < 0 ? 0 : pts[i].b > 1 ? 1 : pts[i].b;
    }
    return cdvr_tf_init_normalized(tf, pts, m, unit, err);
}

/* ---- automatic window ----------------------------------------------------------------------- */

cdvr_status cdvr_tf_percentile_window(const cdvr_volume *u8, size_t t, const double window[2],
                                      double p_lo, double p_hi, double out[2], cdvr_error *err)
{
    if (!u8 || u8->type != CDVR_TYPE_U8 || t >= u8->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: range=\"auto\" needs frame %zu of a u8 volume",
                              t + 1);
    if (!(p_lo >= 0.0 && p_lo < p_hi && p_hi <= 1.0))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: percentiles %g, %g must satisfy "
                              "0 <= lo < hi <= 1",
                              p_lo, p_hi);
    uint64_t hist[256] = {0};
    const uint8_t *v = cdvr_volume_frame(u8, t);
    size_t n = cdvr_volume_voxels(u8);
    for (size_t i = 0; i < n; i++)
        hist[v[i]]++;
    int q[2] = {0, 255}, lo_code = 0, hi_code = 255;
    const double p[2] = {p_lo, p_hi};
    for (int k = 0; k < 2; k++) {
        double need = p[k] * (double)n;
        uint64_t cum = 0;
        for (int c = 0; c < 256; c++) {
            cum += hist[c];
            if ((double)cum >= need && cum > 0) {
                q[k] = c;
                break;
            }
        }
    }
    while (lo_code < 255 && !hist[lo_code])
        lo_code++;
    while (hi_code > 0 && !hist[hi_code])
        hi_code--;
    if (q[1] <= q[0])
        q[0] = lo_code, q[1] = hi_code > lo_code ? hi_code : lo_code;
    for (int k = 0; k < 2; k++)
        out[k] = window[0] + (window[1] - window[0]) * q[k] / 255.0;
    return CDVR_OK;
}

cdvr_status cdvr_tf_apply_window(cdvr_tf *tf, const double window[2], const cdvr_volume *u8,
                                 size_t t, double used[2], cdvr_error *err)
{
    cdvr_status st = check_window(window[0], window[1], "value window", err);
    if (st != CDVR_OK)
        return st;
    double w[2] = {window[0], window[1]};
    if (tf->normalized && tf->auto_range) {
        st = cdvr_tf_percentile_window(u8, t, window, tf->percentiles[0], tf->percentiles[1], w,
                                       err);
        if (st != CDVR_OK)
            return st;
        build_table_auto(tf, window[0], window[1], w);
    } else {
        build_table(tf, window[0], window[1]);
    }
    if (used)
        used[0] = w[0], used[1] = w[1];
    return CDVR_OK;
}

cdvr_status cdvr_tf_rescale_auto(cdvr_tf *tf, const cdvr_volume *vol, size_t t, cdvr_error *err)
{
    if (!tf->normalized)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: range=\"auto\" applies to a normalised TF");
    if (!vol || t >= vol->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "transfer function: range=\"auto\": no frame %zu in the volume",
                              t + 1);
    double window[2], w[2];
    cdvr_volume_window_peek(vol, window);
    const cdvr_volume *u8 = vol;
    cdvr_volume *frame = NULL, *q = NULL;
    size_t ft = t;
    cdvr_status st = CDVR_OK;
    if (vol->type != CDVR_TYPE_U8) {
        st = cdvr_volume_slice_time(vol, t, 1, &frame, err);
        if (st == CDVR_OK)
            st = cdvr_volume_quantize(frame, window[0], window[1], &q, NULL, err);
        u8 = q, ft = 0;
    }
    if (st == CDVR_OK)
        st = cdvr_tf_percentile_window(u8, ft, window, tf->percentiles[0], tf->percentiles[1], w,
                                       err);
    cdvr_volume_free(frame);
    cdvr_volume_free(q);
    if (st != CDVR_OK)
        return st;
    if (w[1] <= w[0])
        w[1] = w[0] + (window[1] > window[0] ? (window[1] - window[0]) / 255.0 : 1.0);
    tf->auto_range = 0;
    return cdvr_tf_rescale(tf, w[0], w[1], err);
}

int cdvr_tf_misses_window(const cdvr_tf *tf, double lo, double hi)
{
    if (tf->normalized)
        return 0;
    float a[4];
    cdvr_tf_eval(tf, lo, a);
    if (a[3] > 0.0f)
        return 0;
    cdvr_tf_eval(tf, hi, a);
    if (a[3] > 0.0f)
        return 0;
    for (size_t i = 0; i < tf->npoints; i++)
        if (tf->points[i].value >= lo && tf->points[i].value <= hi) {
            cdvr_tf_eval(tf, tf->points[i].value, a); /* the right-continuous value */
            if (a[3] > 0.0f || tf->points[i].a > 0.0)
                return 0;
        }
    return 1;
}
