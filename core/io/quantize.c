/* core/io/quantize.c - cdvr_volume_quantize: any volume to u8 over a window [lo, hi]. */
#include "cdvr/series.h"
#include "cdvr/volume.h"

#include <float.h>
#include <math.h>
#include <string.h>

typedef struct window {
    double lo, hi, width; /* width = hi - lo (halved when halve) */
    int halve;            /* (hi - lo) * 255 overflows a double: work on halved values */
} window;

static window make_window(double lo, double hi)
{
    window w = {lo, hi, 0.0, 0};
    if (hi > lo) {
        double width = hi - lo;
        if (!isfinite(width) || !isfinite(width * 255.0)) {
            w.halve = 1;
            width = hi * 0.5 - lo * 0.5;
        }
        w.width = width;
    }
    return w;
}

static uint8_t quantize_value(const window *w, double v, cdvr_quantize_report *r)
{
    if (isnan(v)) {
        r->nan_count++;
        return 0;
    }
    if (isinf(v))
        r->inf_count++;
    if (v < w->lo) {
        r->clipped_low++;
        return 0;
    }
    if (v > w->hi) {
        r->clipped_high++;
        return 255;
    }
    if (w->width == 0.0) /* hi == lo and v == lo */
        return 0;
    double q = w->halve ? floor((v * 0.5 - w->lo * 0.5) / w->width * 255.0 + 0.5)
                        : floor((v - w->lo) * 255.0 / w->width + 0.5);
    return q >= 255.0 ? 255 : q <= 0.0 ? 0 : (uint8_t)q;
}

static double value_at(const void *data, cdvr_type type, size_t i)
{
    switch (type) {
    case CDVR_TYPE_U8: return ((const uint8_t *)data)[i];
    case CDVR_TYPE_U16: return ((const uint16_t *)data)[i];
    case CDVR_TYPE_I16: return ((const int16_t *)data)[i];
    case CDVR_TYPE_F32: return ((const float *)data)[i];
    }
    return 0.0;
}

static cdvr_status check_window(double lo, double hi, cdvr_error *err)
{
    if (!isfinite(lo) || !isfinite(hi) || hi < lo)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "quantize: window [%g, %g] must be finite with lo <= hi", lo, hi);
    return CDVR_OK;
}

cdvr_status cdvr_quantize_values(const void *in, cdvr_type type, size_t count, double lo,
                                 double hi, uint8_t *out, cdvr_quantize_report *report,
                                 cdvr_error *err)
{
    cdvr_quantize_report local = {0};
    cdvr_quantize_report *r = report ? report : &local;
    cdvr_status st = check_window(lo, hi, err);
    if (st != CDVR_OK)
        return st;
    window w = make_window(lo, hi);
    for (size_t i = 0; i < count; i++)
        out[i] = quantize_value(&w, value_at(in, type, i), r);
    return CDVR_OK;
}

cdvr_status cdvr_volume_quantize(const cdvr_volume *in, double lo, double hi, cdvr_volume **out,
                                 cdvr_quantize_report *report, cdvr_error *err)
{
    *out = NULL;
    cdvr_quantize_report local;
    cdvr_quantize_report *r = report ? report : &local;
    memset(r, 0, sizeof *r);
    cdvr_status st = check_window(lo, hi, err);
    if (st != CDVR_OK)
        return st;
    st = cdvr_volume_create(in->dims, in->timesteps, CDVR_TYPE_U8, out, err);
    if (st != CDVR_OK)
        return st;
    memcpy((*out)->spacing, in->spacing, sizeof in->spacing);
    memcpy((*out)->origin, in->origin, sizeof in->origin);
    memcpy((*out)->direction, in->direction, sizeof in->direction);
    (*out)->window[0] = lo;
    (*out)->window[1] = hi;
    return cdvr_quantize_values(in->data, in->type, cdvr_volume_voxels(in) * in->timesteps, lo,
                                hi, (*out)->data, r, err);
}
