/* core/render/compare.c - mse, psnr and max error between volumes and between images. */
#include "cdvr/compare.h"

#include <math.h>
#include <stdint.h>

double cdvr_psnr(double mse, double peak)
{
    if (mse == 0.0)
        return HUGE_VAL;
    return 10.0 * log10(peak * peak / mse);
}

/* Accumulates one element pair; equal values (also equal infinities) and two NaNs count as no
 * error, a NaN against a number as an infinite one. */
static void accumulate(double a, double b, double *sum, double *maxerr)
{
    double d;
    if (a == b || (isnan(a) && isnan(b)))
        d = 0.0;
    else {
        d = fabs(a - b);
        if (isnan(d))
            d = HUGE_VAL;
    }
    *sum += d * d;
    if (d > *maxerr)
        *maxerr = d;
}

static double volume_peak(const cdvr_volume *a)
{
    switch (a->type) {
    case CDVR_TYPE_U8: return 255.0;
    case CDVR_TYPE_U16:
    case CDVR_TYPE_I16: return 65535.0;
    case CDVR_TYPE_F32: {
        double lo, hi;
        cdvr_volume_range(a, &lo, &hi);
        return hi - lo;
    }
    }
    return 255.0;
}

static double element(const cdvr_volume *v, size_t i)
{
    switch (v->type) {
    case CDVR_TYPE_U8: return ((const uint8_t *)v->data)[i];
    case CDVR_TYPE_U16: return ((const uint16_t *)v->data)[i];
    case CDVR_TYPE_I16: return ((const int16_t *)v->data)[i];
    case CDVR_TYPE_F32: return ((const float *)v->data)[i];
    }
    return 0.0;
}

static cdvr_status check_same_shape(const cdvr_volume *a, const cdvr_volume *b,
                                    cdvr_error *err)
{
    if (a->dims[0] != b->dims[0] || a->dims[1] != b->dims[1] || a->dims[2] != b->dims[2] ||
        a->timesteps != b->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "compare: volumes differ in size: %zux%zux%zu x %zu against "
                              "%zux%zux%zu x %zu",
                              a->dims[0], a->dims[1], a->dims[2], a->timesteps, b->dims[0],
                              b->dims[1], b->dims[2], b->timesteps);
    if (a->type != b->type)
        return cdvr_error_set(err, CDVR_ERR_ARG, "compare: volume types differ: %s against %s",
                              cdvr_type_name(a->type), cdvr_type_name(b->type));
    return CDVR_OK;
}

cdvr_status cdvr_compare_volumes(const cdvr_volume *a, const cdvr_volume *b,
                                 cdvr_compare_result *res, cdvr_error *err)
{
    if (!a || !b || !res)
        return cdvr_error_set(err, CDVR_ERR_ARG, "compare: NULL argument");
    cdvr_status st = check_same_shape(a, b, err);
    if (st != CDVR_OK)
        return st;
    size_t count;
    if (!cdvr_size_mul(cdvr_volume_voxels(a), a->timesteps, &count))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "compare: voxel count overflows size_t");
    double sum = 0.0, maxerr = 0.0;
    for (size_t i = 0; i < count; i++)
        accumulate(element(a, i), element(b, i), &sum, &maxerr);
    res->mse = sum / (double)count;
    res->maxerr = maxerr;
    res->psnr = cdvr_psnr(res->mse, volume_peak(a));
    return CDVR_OK;
}

cdvr_status cdvr_compare_images(const cdvr_image *a, const cdvr_image *b,
                                cdvr_compare_result *res, cdvr_error *err)
{
    if (!a || !b || !res)
        return cdvr_error_set(err, CDVR_ERR_ARG, "compare: NULL argument");
    if (a->width != b->width || a->height != b->height)
        return cdvr_error_set(err, CDVR_ERR_ARG, "compare: images differ in size: %dx%d against %dx%d",
                              a->width, a->height, b->width, b->height);
    double sum = 0.0, maxerr = 0.0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            float pa[4], pb[4];
            cdvr_image_composited(a, x, y, pa);
            cdvr_image_composited(b, x, y, pb);
            for (int c = 0; c < 3; c++)
                accumulate(pa[c] * 255.0, pb[c] * 255.0, &sum, &maxerr);
        }
    res->mse = sum / (3.0 * (double)a->width * (double)a->height);
    res->maxerr = maxerr;
    res->psnr = cdvr_psnr(res->mse, 255.0);
    return CDVR_OK;
}
