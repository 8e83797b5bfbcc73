/* core/render/cpu/splat_method.c - the "splat" render method (cdvr/method.h): Gaussian splats
 * ordered by the extended DDA or a sort (splat.h, seed 003), on the CPU. */
#include "cdvr/method.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/splat.h"
#include "cdvr/timing.h"

typedef struct splat_params {
    cdvr_splat_how order;
    int has_threshold;
    double threshold, radius, sigma;
} splat_params;

static const cdvr_method_option splat_options[] = {
    {"order", CDVR_MOPT_CHOICE, "dda", "dda|axis|sort|quicksort",
     "drawing order: the seed's extended DDA (no sort), axis sheets, radix or exact depth sort"},
    {"threshold", CDVR_MOPT_NUMBER, NULL, NULL,
     "draw only voxels whose 8-bit code is above this (default: every voxel with TF opacity > 0)"},
    {"radius", CDVR_MOPT_NUMBER, "2", NULL, "footprint cut-off in voxel spacings (0 < radius <= 16)"},
    {"sigma", CDVR_MOPT_NUMBER, "0.6", NULL, "Gaussian standard deviation in voxel spacings (0 < sigma <= 8)"},
    {NULL, 0, NULL, NULL, NULL}};

static splat_params get_params(const cdvr_method_params *p)
{
    splat_params sp;
    memcpy(&sp, p->bytes, sizeof sp);
    return sp;
}

static void splat_default(cdvr_method_params *p)
{
    splat_params sp = {.order = CDVR_SPLAT_DDA, .radius = CDVR_SPLAT_DEFAULT_RADIUS,
                       .sigma = CDVR_SPLAT_DEFAULT_SIGMA};
    memcpy(p->bytes, &sp, sizeof sp);
}

/* A whole-text number; 0 when value is not one. */
static int parse_number(const char *value, double *out)
{
    char *end;
    errno = 0;
    *out = strtod(value, &end);
    return end != value && *end == '\0' && errno == 0;
}

static cdvr_status splat_set(cdvr_method_params *p, const char *key, const char *value,
                             cdvr_error *err)
{
    splat_params sp = get_params(p);
    double x = 0.0;
    if (strcmp(key, "order") == 0) {
        if (!cdvr_splat_how_parse(value, &sp.order))
            return cdvr_error_set(err, CDVR_ERR_ARG, "splat: option 'order': invalid value '%s' "
                                  "(dda, axis, sort or quicksort)", value);
    } else if (strcmp(key, "threshold") == 0 || strcmp(key, "radius") == 0 ||
               strcmp(key, "sigma") == 0) {
        if (!parse_number(value, &x) || !isfinite(x))
            return cdvr_error_set(err, CDVR_ERR_ARG, "splat: option '%s': a finite number "
                                  "expected, got '%s'", key, value);
        if (key[0] == 't') {
            sp.threshold = x;
            sp.has_threshold = 1;
        } else if (!(x > 0.0)) {
            return cdvr_error_set(err, CDVR_ERR_ARG, "splat: option '%s' must be > 0, got %s",
                                  key, value);
        } else if (key[0] == 'r') {
            sp.radius = x;
        } else {
            sp.sigma = x;
        }
    } else {
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat: unknown option '%s'", key);
    }
    memcpy(p->bytes, &sp, sizeof sp);
    return CDVR_OK;
}

static cdvr_status splat_render(cdvr_render_ctx *ctx, cdvr_device_kind device,
                                const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                                const cdvr_method_params *p, cdvr_render_stats *stats,
                                cdvr_image **out, cdvr_error *err)
{
    (void)ctx;
    (void)device; /* cpu only (the table says so) */
    splat_params sp = get_params(p);
    cdvr_splat_opts o;
    memset(&o, 0, sizeof o);
    o.tf = opts->tf;
    o.camera = opts->camera;
    o.unit = opts->unit;
    o.threads = opts->threads;
    memcpy(o.background, opts->background, sizeof o.background);
    o.order = sp.order;
    o.has_threshold = sp.has_threshold;
    o.threshold = sp.threshold;
    o.radius = sp.radius;
    o.sigma = sp.sigma;
    double start = cdvr_now_ms();
    cdvr_status s = cdvr_render_splat(vol, t, &o, out, err);
    if (s != CDVR_OK)
        return s;
    cdvr_render_stats_number(stats, "ms", cdvr_now_ms() - start);
    cdvr_render_stats_number(stats, "order_ms", o.order_ms);
    cdvr_render_stats_integer(stats, "splats", (long long)o.splats);
    cdvr_render_stats_integer(stats, "fragments", (long long)o.fragments);
    return CDVR_OK;
}

/* 'o' cycles the order (window). */
static int splat_key(const cdvr_method_params *p, int key, const char **option, char *value,
                     size_t n)
{
    if (key != 'o')
        return 0;
    static const cdvr_splat_how cycle[] = {CDVR_SPLAT_DDA, CDVR_SPLAT_AXIS, CDVR_SPLAT_SORT,
                                           CDVR_SPLAT_QUICKSORT};
    size_t count = sizeof cycle / sizeof cycle[0], i = 0;
    cdvr_splat_how order = get_params(p).order;
    while (i < count && cycle[i] != order)
        i++;
    *option = "order";
    snprintf(value, n, "%s", cdvr_splat_how_name(cycle[(i + 1) % count]));
    return 1;
}

static void splat_describe(const cdvr_method_params *p, char *out, size_t n)
{
    snprintf(out, n, "order %s", cdvr_splat_how_name(get_params(p).order));
}

const cdvr_render_method cdvr_method_splat = {
    .name = "splat",
    .description = "Gaussian splatting composited back to front, ordered by the extended DDA "
                   "or a sort (splat.h, seed 003)",
    .devices = CDVR_DEVICE_BIT(CDVR_DEVICE_CPU),
    .blends = CDVR_BLEND_BIT(CDVR_BLEND_COMPOSITE),
    .shading = 0,
    .bricks = 0,
    .distribute = CDVR_METHOD_DIST_TIME,
    .scene_keys = CDVR_SCENE_UNIT | CDVR_SCENE_THREADS,
    .options = splat_options,
    .params_default = splat_default,
    .params_set = splat_set,
    .render = splat_render,
    .window_key = splat_key,
    .describe = splat_describe,
};
