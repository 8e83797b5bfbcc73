/* core/render/annotate.c - scalar bar, orientation letters, title and time on an image
 * (cdvr/annotate.h). */
#include "cdvr/annotate.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cdvr/text.h"

/* ---- layout ------------------------------------------------------------------------------- */

static int text_scale(int width, int height)
{
    int m = width < height ? width : height;
    int s = (int)lround(m / 256.0);
    return s < 1 ? 1 : s;
}

static void bar_range(const cdvr_annotate_opts *o, double r[2])
{
    if (o->range[0] != o->range[1] && isfinite(o->range[0]) && isfinite(o->range[1])) {
        r[0] = o->range[0] < o->range[1] ? o->range[0] : o->range[1];
        r[1] = o->range[0] < o->range[1] ? o->range[1] : o->range[0];
    } else {
        r[0] = o->tf->window[0];
        r[1] = o->tf->window[1];
    }
}

/* Tick values over [lo, hi] at 1, 2, 5 x 10^k steps, 2 to 6 of them; returns the count. */
static int ticks(double lo, double hi, double out[8])
{
    if (!(hi > lo)) {
        out[0] = lo;
        return 1;
    }
    double raw = (hi - lo) / 4.0, mag = pow(10.0, floor(log10(raw))), f = raw / mag;
    double step = mag * (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0);
    int n = 0;
    for (double v = ceil(lo / step - 1e-9) * step; v <= hi + step * 1e-9 && n < 8; v += step)
        out[n++] = fabs(v) < step * 1e-9 ? 0.0 : v;
    return n;
}

static void tick_label(double v, char buf[32])
{
    snprintf(buf, 32, "%.4g", v);
}

static int widest_label(const double *t, int n, int s)
{
    int w = 0;
    char buf[32];
    for (int i = 0; i < n; i++) {
        tick_label(t[i], buf);
        int tw = cdvr_text_width(buf, s);
        w = tw > w ? tw : w;
    }
    return w;
}

void cdvr_annotate_bar_box(int width, int height, const cdvr_annotate_opts *o, int box[4])
{
    int s = text_scale(width, height), m = 6 * s;
    double r[2], t[8];
    bar_range(o, r);
    int n = ticks(r[0], r[1], t);
    int bar_w = width / 32 > 8 ? width / 32 : 8;
    box[2] = width - m - widest_label(t, n, s) - 5 * s; /* x1 */
    box[0] = box[2] - bar_w;
    box[1] = (int)(0.45 * height);
    box[3] = (int)(0.90 * height);
}

/* ---- colour bar --------------------------------------------------------------------------- */

/* TF colour (straight rgb, alpha) at data value v. */
static void tf_at(const cdvr_tf *tf, double v, float out[4])
{
    double w0 = tf->window[0], w1 = tf->window[1];
    float code = w1 > w0 ? (float)((v - w0) / (w1 - w0) * 255.0) : 0.0f;
    cdvr_tf_lookup(tf, code, out);
}

static double row_value(const int box[4], int y, const double r[2])
{
    double f = (y - box[1] + 0.5) / (double)(box[3] - box[1]);
    return r[1] - f * (r[1] - r[0]);
}

static void draw_colorbar(cdvr_image *img, const cdvr_annotate_opts *o, const float fg[3])
{
    int s = text_scale(img->width, img->height);
    int box[4];
    cdvr_annotate_bar_box(img->width, img->height, o, box);
    double r[2], t[8];
    bar_range(o, r);
    float amax = 0.0f, c[4];
    for (int y = box[1]; y < box[3]; y++) {
        tf_at(o->tf, row_value(box, y, r), c);
        amax = c[3] > amax ? c[3] : amax;
    }
    int split = box[0] + (2 * (box[2] - box[0])) / 3;
    for (int y = box[1]; y < box[3]; y++) {
        tf_at(o->tf, row_value(box, y, r), c);
        const float col[4] = {c[0], c[1], c[2], 1.0f};
        float g = amax > 0.0f ? c[3] / amax : 0.0f;
        const float op[4] = {g, g, g, 1.0f};
        cdvr_image_fill_rect(img, box[0], y, split, y + 1, col);
        cdvr_image_fill_rect(img, split, y, box[2], y + 1, op);
    }
    const float frame[4] = {fg[0], fg[1], fg[2], 1.0f};
    cdvr_image_fill_rect(img, box[0] - 1, box[1] - 1, box[2] + 1, box[1], frame);
    cdvr_image_fill_rect(img, box[0] - 1, box[3], box[2] + 1, box[3] + 1, frame);
    cdvr_image_fill_rect(img, box[0] - 1, box[1], box[0], box[3], frame);
    cdvr_image_fill_rect(img, box[2], box[1], box[2] + 1, box[3], frame);
    int n = ticks(r[0], r[1], t);
    char buf[48];
    for (int i = 0; i < n; i++) {
        double f = r[1] > r[0] ? (r[1] - t[i]) / (r[1] - r[0]) : 0.0;
        int y = box[1] + (int)lround(f * (box[3] - box[1] - 1));
        cdvr_image_fill_rect(img, box[2], y, box[2] + 3 * s, y + s, frame);
        tick_label(t[i], buf);
        int th = cdvr_text_height(buf, s);
        cdvr_text_draw(img, box[2] + 5 * s, y - th / 2 + s, buf, s, fg, 1);
    }
    int line = cdvr_text_height("a", s) + s;
    snprintf(buf, sizeof buf, "a<=%.2g", amax);
    cdvr_text_draw(img, box[0], box[1] - line - s, buf, s, fg, 1);
    if (o->unit && *o->unit)
        cdvr_text_draw(img, box[0], box[1] - 2 * line - s, o->unit, s, fg, 1);
}

/* ---- orientation -------------------------------------------------------------------------- */

static char opposite(char c)
{
    switch (c) {
    case 'L': return 'R';
    case 'R': return 'L';
    case 'P': return 'A';
    case 'A': return 'P';
    case 'S': return 'I';
    case 'I': return 'S';
    default: return 0;
    }
}

/* 1 when space is three letters naming each of the L/R, P/A and S/I axes once. */
static int valid_space(const char *space)
{
    if (strlen(space) != 3)
        return 0;
    int seen[3] = {0, 0, 0};
    for (int i = 0; i < 3; i++) {
        const char *axis = strchr("LRPASI", space[i]);
        if (!axis || !space[i])
            return 0;
        seen[(axis - "LRPASI") / 2]++;
    }
    return seen[0] == 1 && seen[1] == 1 && seen[2] == 1;
}

int cdvr_annotate_letters(const double d[3], const char *space, char out[4])
{
    space = space ? space : "LPS";
    out[0] = '\0';
    if (!valid_space(space))
        return -1;
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > 0.0))
        return 0;
    int order[3] = {0, 1, 2};
    for (int i = 0; i < 3; i++) /* by |component|, largest first */
        for (int j = i + 1; j < 3; j++)
            if (fabs(d[order[j]]) > fabs(d[order[i]])) {
                int tmp = order[i];
                order[i] = order[j];
                order[j] = tmp;
            }
    int n = 0;
    for (int i = 0; i < 3; i++) {
        int a = order[i];
        if (fabs(d[a]) >= 0.25 * len)
            out[n++] = d[a] > 0.0 ? space[a] : opposite(space[a]);
    }
    out[n] = '\0';
    return 0;
}

static void draw_letters(cdvr_image *img, const cdvr_annotate_opts *o, const float fg[3],
                         int top_offset)
{
    int W = img->width, H = img->height, s = text_scale(W, H), m = 6 * s, ls = 2 * s;
    double f[3], u[3], r[3];
    cdvr_camera_basis(o->camera, f, u, r);
    const double right[3] = {r[0], r[1], r[2]}, left[3] = {-r[0], -r[1], -r[2]};
    const double up[3] = {u[0], u[1], u[2]}, down[3] = {-u[0], -u[1], -u[2]};
    char lab[4];
    cdvr_annotate_letters(right, o->space, lab);
    cdvr_text_draw(img, W - m - cdvr_text_width(lab, ls), (int)(0.25 * H), lab, ls, fg, 1);
    cdvr_annotate_letters(left, o->space, lab);
    cdvr_text_draw(img, m, H / 2 - cdvr_text_height(lab, ls) / 2, lab, ls, fg, 1);
    cdvr_annotate_letters(up, o->space, lab);
    cdvr_text_draw(img, W / 2 - cdvr_text_width(lab, ls) / 2, m + top_offset, lab, ls, fg, 1);
    cdvr_annotate_letters(down, o->space, lab);
    cdvr_text_draw(img, W / 2 - cdvr_text_width(lab, ls) / 2,
                   H - m - cdvr_text_height(lab, ls) + 2 * s, lab, ls, fg, 1);
}

/* ---- entry -------------------------------------------------------------------------------- */

static cdvr_status check(const cdvr_image *img, const cdvr_annotate_opts *o, cdvr_error *err)
{
    if (!img || !o)
        return cdvr_error_set(err, CDVR_ERR_ARG, "annotate: NULL image or options");
    if (o->colorbar && !o->tf)
        return cdvr_error_set(err, CDVR_ERR_ARG, "annotate: the colour bar needs the TF");
    if (o->axes && !o->camera)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "annotate: orientation letters need the camera");
    if (o->axes && cdvr_camera_validate(o->camera, err) != CDVR_OK)
        return CDVR_ERR_ARG;
    if (o->axes && o->space && !valid_space(o->space))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "annotate: space '%s' must name +x, +y, +z by one of L/R, P/A, S/I "
                              "each (\"LPS\", \"RAS\", ...)",
                              o->space);
    return CDVR_OK;
}

cdvr_status cdvr_annotate(cdvr_image *img, const cdvr_annotate_opts *o, cdvr_error *err)
{
    cdvr_status st = check(img, o, err);
    if (st != CDVR_OK)
        return st;
    float fg[3] = {o->color[0], o->color[1], o->color[2]};
    if (fg[0] == 0.0f && fg[1] == 0.0f && fg[2] == 0.0f)
        fg[0] = fg[1] = fg[2] = 1.0f;
    int s = text_scale(img->width, img->height), m = 6 * s, top = 0;
    if (o->title && *o->title) {
        cdvr_text_draw(img, m, m, o->title, 2 * s, fg, 1);
        top = cdvr_text_height(o->title, 2 * s);
    }
    if (o->time && *o->time)
        cdvr_text_draw(img, m, img->height - m - cdvr_text_height(o->time, s), o->time, s, fg,
                       1);
    if (o->colorbar)
        draw_colorbar(img, o, fg);
    if (o->axes)
        draw_letters(img, o, fg, top);
    return CDVR_OK;
}
