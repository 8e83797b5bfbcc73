/* core/render/render_check.c - the render options every renderer accepts (see render.h:
 * cdvr_render_opts_check): bounded work, each refusal naming the option, its value and the
 * limit. */
#include <math.h>

#include "cdvr/render.h"

static double box_diagonal(const size_t dims[3], const double spacing[3])
{
    double sum = 0.0;
    for (int a = 0; a < 3; a++) {
        double extent = (double)(dims[a] ? dims[a] - 1 : 0) * spacing[a];
        sum += extent * extent;
    }
    return sqrt(sum);
}

cdvr_status cdvr_render_opts_check_box(const size_t dims[3], const double spacing[3],
                                       const cdvr_render_opts *opts, cdvr_error *err)
{
    if (!opts)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: no options");
    double smallest = INFINITY;
    for (int a = 0; a < 3; a++) {
        if (!(spacing[a] > 0.0) || !isfinite(spacing[a]))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "render: spacing %g (axis %d) must be positive and finite",
                                  spacing[a], a);
        smallest = fmin(smallest, spacing[a]);
    }
    double min_step = smallest / CDVR_RENDER_MIN_STEP_DIVISOR;
    if (!isfinite(opts->step) || opts->step < 0.0)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "render: step %g must be finite and >= 0 (0: half the smallest "
                              "spacing)", opts->step);
    if (opts->step > 0.0 && opts->step < min_step)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "render: step %g is below 1/%d of the smallest voxel spacing %g "
                              "(the limit: step >= %g)", opts->step, CDVR_RENDER_MIN_STEP_DIVISOR,
                              smallest, min_step);
    double step = opts->step > 0.0 ? opts->step : 0.5 * smallest;
    double samples = box_diagonal(dims, spacing) / step;
    if (samples > CDVR_RENDER_MAX_RAY_SAMPLES)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "render: step %g gives %.3g samples along the box's diagonal %g "
                              "(the limit: %.0f per ray)", step, samples,
                              box_diagonal(dims, spacing), (double)CDVR_RENDER_MAX_RAY_SAMPLES);
    if (!isfinite(opts->unit) || opts->unit < 0.0)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "render: unit %g must be finite and >= 0 (0: the TF's unit or the "
                              "smallest spacing)", opts->unit);
    if (isnan(opts->term_alpha) || opts->term_alpha < 0.0)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "render: term_alpha %g must be >= 0 (0: 0.99; >= 1: no early "
                              "termination)", opts->term_alpha);
    return CDVR_OK;
}

cdvr_status cdvr_render_opts_check(const cdvr_volume *vol, const cdvr_render_opts *opts,
                                   cdvr_error *err)
{
    if (!vol)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: no volume");
    const size_t *dims = opts && opts->clip ? opts->clip->whole_dims : vol->dims;
    return cdvr_render_opts_check_box(dims, vol->spacing, opts, err);
}
