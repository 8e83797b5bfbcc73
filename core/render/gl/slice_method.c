/* core/render/gl/slice_method.c - the "slice" render method (cdvr/method.h): object-aligned 2D
 * texture slicing through headless EGL with per-slice level of detail (gl.h, seed 002). In a
 * build without GL the method is listed and its render fails with gl.h's message. */
#include "cdvr/method.h"

#include <stdio.h>
#include <string.h>

#include "cdvr/gl.h"
#include "cdvr/timing.h"

typedef struct slice_params {
    int lod; /* cdvr_lod_mode */
} slice_params;

static const cdvr_method_option slice_options[] = {
    {"lod", CDVR_MOPT_CHOICE, "true", "true|false|seed|screen",
     "per-slice level of detail: true or \"seed\" (seed 002's rule), \"screen\", or false"},
    {NULL, 0, NULL, NULL, NULL}};

static slice_params get_params(const cdvr_method_params *p)
{
    slice_params sp;
    memcpy(&sp, p->bytes, sizeof sp);
    return sp;
}

static void slice_default(cdvr_method_params *p)
{
    slice_params sp = {.lod = CDVR_LOD_SEED};
    memcpy(p->bytes, &sp, sizeof sp);
}

static cdvr_status slice_set(cdvr_method_params *p, const char *key, const char *value,
                             cdvr_error *err)
{
    slice_params sp = get_params(p);
    if (strcmp(key, "lod") != 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "slice: unknown option '%s'", key);
    if (strcmp(value, "true") == 0 || strcmp(value, "seed") == 0)
        sp.lod = CDVR_LOD_SEED;
    else if (strcmp(value, "screen") == 0)
        sp.lod = CDVR_LOD_SCREEN;
    else if (strcmp(value, "false") == 0)
        sp.lod = CDVR_LOD_OFF;
    else
        return cdvr_error_set(err, CDVR_ERR_ARG, "slice: option 'lod': boolean, \"seed\" or "
                              "\"screen\" expected, got %s", value);
    memcpy(p->bytes, &sp, sizeof sp);
    return CDVR_OK;
}

static const char *lod_name(int mode)
{
    return mode == CDVR_LOD_OFF ? "off" : mode == CDVR_LOD_SCREEN ? "screen" : "seed";
}

static void slice_stats(const cdvr_gl *gl, const cdvr_slice_stats *s, int lod, double ms,
                        cdvr_render_stats *stats)
{
    cdvr_render_stats_string(stats, "device", cdvr_gl_renderer(gl));
    cdvr_render_stats_string(stats, "lod", lod_name(lod));
    cdvr_render_stats_number(stats, "ms", ms);
    cdvr_render_stats_number(stats, "upload_ms", s->upload_ms);
    cdvr_render_stats_number(stats, "draw_ms", s->draw_ms);
    cdvr_render_stats_integer(stats, "axis", s->axis + 1);
    cdvr_render_stats_integer(stats, "slices", (long long)s->slices);
    cdvr_render_stats_integer(stats, "min_level", s->min_level);
    cdvr_render_stats_integer(stats, "max_level", s->max_level);
    cdvr_render_stats_number(stats, "nearest", s->nearest);
    cdvr_render_stats_integer(stats, "texture_bytes", (long long)s->texture_bytes);
    cdvr_render_stats_integer(stats, "full_bytes", (long long)s->full_bytes);
    cdvr_render_stats_integer(stats, "uploaded_bytes", (long long)s->uploaded_bytes);
}

static cdvr_status slice_render(cdvr_render_ctx *ctx, cdvr_device_kind device,
                                const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                                const cdvr_method_params *p, cdvr_render_stats *stats,
                                cdvr_image **out, cdvr_error *err)
{
    (void)device; /* gl only (the table says so) */
    cdvr_gl *gl;
    cdvr_status s = cdvr_render_ctx_gl(ctx, &gl, err);
    if (s != CDVR_OK)
        return s;
    int lod = get_params(p).lod;
    double start = cdvr_now_ms();
    cdvr_slice_stats st;
    s = cdvr_gl_slice(gl, vol, t, opts, lod, &st, out, err);
    if (s == CDVR_OK)
        slice_stats(gl, &st, lod, cdvr_now_ms() - start, stats);
    return s;
}

/* 'l' cycles the level of detail: seed, screen, off (window). */
static int slice_key(const cdvr_method_params *p, int key, const char **option, char *value,
                     size_t n)
{
    if (key != 'l')
        return 0;
    int lod = get_params(p).lod;
    *option = "lod";
    snprintf(value, n, "%s", lod == CDVR_LOD_SEED ? "screen" : lod == CDVR_LOD_SCREEN ? "false"
                                                                                     : "seed");
    return 1;
}

static void slice_describe(const cdvr_method_params *p, char *out, size_t n)
{
    snprintf(out, n, "lod %s", lod_name(get_params(p).lod));
}

const cdvr_render_method cdvr_method_slice = {
    .name = "slice",
    .description = "2D-texture slicing through headless EGL, object-aligned slices along the "
                   "axis nearest the view, per-slice level of detail (gl.h, seed 002)",
    .devices = CDVR_DEVICE_BIT(CDVR_DEVICE_GL),
    .blends = CDVR_BLEND_BIT(CDVR_BLEND_COMPOSITE),
    .shading = 0,
    .bricks = 0,
    .distribute = CDVR_METHOD_DIST_TIME,
    .scene_keys = CDVR_SCENE_UNIT,
    .options = slice_options,
    .params_default = slice_default,
    .params_set = slice_set,
    .render = slice_render,
    .window_key = slice_key,
    .describe = slice_describe,
};
