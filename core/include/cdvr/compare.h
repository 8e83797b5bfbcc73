/* cdvr/compare.h - error metrics between volumes and between images.
 *
 * mse  = mean of (a - b)^2 over all elements
 * psnr = 10 log10(peak^2 / mse), +Inf (HUGE_VAL) when mse == 0
 * maxerr = max |a - b|
 * Volumes: every voxel of every timestep, values as double; peak = 255 for u8, 65535 for u16,
 *   65535 for i16, and (max - min) of `a`'s finite values for f32. Dims, timesteps and type
 *   must agree.
 * Images: the composited RGB (alpha excluded) in 8-bit units (float * 255, not rounded),
 *   peak 255. Sizes must agree.
 */
#ifndef CDVR_COMPARE_H
#define CDVR_COMPARE_H

#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/volume.h"

typedef struct cdvr_compare_result {
    double mse, psnr, maxerr;
} cdvr_compare_result;

cdvr_status cdvr_compare_volumes(const cdvr_volume *a, const cdvr_volume *b,
                                 cdvr_compare_result *res, cdvr_error *err);
cdvr_status cdvr_compare_images(const cdvr_image *a, const cdvr_image *b,
                                cdvr_compare_result *res, cdvr_error *err);
/* PSNR from mse and peak (HUGE_VAL for mse == 0). */
double cdvr_psnr(double mse, double peak);

#endif
