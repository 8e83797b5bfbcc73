/* core/render/look.c - the blend modes, shading and gradient-opacity options every renderer
 * shares (cdvr/render.h): names and the one check of their values. */
#include "cdvr/render.h"

#include <math.h>
#include <string.h>

static const char *const blend_names[CDVR_BLEND_COUNT] = {"composite", "max", "min", "average",
                                                          "iso"};

const char *cdvr_blend_name(int blend)
{
    return blend >= 0 && blend < CDVR_BLEND_COUNT ? blend_names[blend] : NULL;
}

int cdvr_blend_parse(const char *name)
{
    for (int b = 0; name && b < CDVR_BLEND_COUNT; b++)
        if (strcmp(name, blend_names[b]) == 0)
            return b;
    return -1;
}

static int finite_nonneg(double x)
{
    return isfinite(x) && x >= 0.0;
}

static cdvr_status check_shading(const cdvr_shading *sh, cdvr_error *err)
{
    if (!sh->enabled)
        return CDVR_OK;
    if (!finite_nonneg(sh->ambient) || !finite_nonneg(sh->diffuse) ||
        !finite_nonneg(sh->specular) || !finite_nonneg(sh->specular_power))
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: shading: ambient %g, diffuse %g, "
                              "specular %g and specular_power %g must be finite and >= 0",
                              sh->ambient, sh->diffuse, sh->specular, sh->specular_power);
    if (sh->light_fixed) {
        double len = 0.0;
        for (int a = 0; a < 3; a++)
            len += sh->light_dir[a] * sh->light_dir[a];
        if (!(len > 1e-24) || !isfinite(len))
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: light dir (%g, %g, %g) must be a "
                                  "finite nonzero vector", sh->light_dir[0], sh->light_dir[1],
                                  sh->light_dir[2]);
    }
    return CDVR_OK;
}

static cdvr_status check_gradient_opacity(const cdvr_gradient_opacity *go, cdvr_error *err)
{
    if (go->npoints > CDVR_GRADIENT_OPACITY_MAX)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: gradient_opacity: %zu points, at most %d",
                              go->npoints, CDVR_GRADIENT_OPACITY_MAX);
    for (size_t i = 0; i < go->npoints; i++) {
        if (!finite_nonneg(go->magnitude[i]) || !(go->factor[i] >= 0.0 && go->factor[i] <= 1.0))
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: gradient_opacity point %zu: "
                                  "magnitude %g must be finite and >= 0, opacity %g in [0, 1]",
                                  i + 1, go->magnitude[i], go->factor[i]);
        if (i > 0 && !(go->magnitude[i] >= go->magnitude[i - 1]))
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: gradient_opacity points must be "
                                  "sorted by magnitude (point %zu: %g after %g)", i + 1,
                                  go->magnitude[i], go->magnitude[i - 1]);
    }
    return CDVR_OK;
}

cdvr_status cdvr_render_check_look(const cdvr_render_opts *opts, cdvr_error *err)
{
    if (!cdvr_blend_name(opts->look.blend))
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: unknown blend mode %d", opts->look.blend);
    cdvr_status s = check_shading(&opts->look.shade, err);
    if (s == CDVR_OK)
        s = check_gradient_opacity(&opts->look.gradient_opacity, err);
    if (s != CDVR_OK)
        return s;
    if (opts->look.blend == CDVR_BLEND_ISO) {
        const cdvr_tf *tf = opts->tf;
        if (!isfinite(opts->look.iso_value))
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: iso value %g is not finite",
                                  opts->look.iso_value);
        if (tf && !(tf->window[1] > tf->window[0]))
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: iso needs a value window of nonzero "
                                  "width (the data's window is [%g, %g])", tf->window[0],
                                  tf->window[1]);
        if (!(opts->look.iso_opacity >= 0.0 && opts->look.iso_opacity <= 1.0))
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: iso opacity %g must be in [0, 1]",
                                  opts->look.iso_opacity);
        for (int c = 0; c < 3; c++)
            if (!(opts->look.iso_color[c] >= 0.0f && opts->look.iso_color[c] <= 1.0f))
                return cdvr_error_set(err, CDVR_ERR_ARG, "render: iso color components must be "
                                      "in [0, 1]");
    }
    if (opts->clip && opts->look.blend != CDVR_BLEND_COMPOSITE)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "render: blend mode '%s' cannot be "
                              "rendered in boxes (sort-last bricks composite front to back only)",
                              cdvr_blend_name(opts->look.blend));
    if (opts->clip && (opts->look.shade.enabled || opts->look.gradient_opacity.npoints))
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "render: shading and gradient opacity "
                              "cannot be rendered in boxes yet (central differences reach past "
                              "a box's one-voxel overlap)");
    return CDVR_OK;
}

void cdvr_shading_default(cdvr_shading *sh)
{
    memset(sh, 0, sizeof *sh);
    sh->enabled = 1;
    sh->ambient = CDVR_SHADE_AMBIENT;
    sh->diffuse = CDVR_SHADE_DIFFUSE;
    sh->specular = CDVR_SHADE_SPECULAR;
    sh->specular_power = CDVR_SHADE_SPECULAR_POWER;
}
