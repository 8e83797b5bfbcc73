/* core/render/raycast_method.c - the "raycast" render method (cdvr/method.h): the CPU reference
 * ray caster (render.h) and the OpenCL one (device.h), which follows it to 50 dB. */
#include "cdvr/method.h"

#include <string.h>

#include "cdvr/device.h"
#include "cdvr/store.h"
#include "cdvr/timing.h"

typedef struct raycast_params {
    int skip; /* empty-space skipping */
} raycast_params;

static const cdvr_method_option raycast_options[] = {
    {"skip", CDVR_MOPT_BOOLEAN, "true", NULL,
     "empty-space skipping by brick min/max (false: every sample is taken; the image is the same)"},
    {NULL, 0, NULL, NULL, NULL}};

static raycast_params get_params(const cdvr_method_params *p)
{
    raycast_params rp;
    memcpy(&rp, p->bytes, sizeof rp);
    return rp;
}

static void raycast_default(cdvr_method_params *p)
{
    raycast_params rp = {.skip = 1};
    memcpy(p->bytes, &rp, sizeof rp);
}

static cdvr_status raycast_set(cdvr_method_params *p, const char *key, const char *value,
                               cdvr_error *err)
{
    raycast_params rp = get_params(p);
    if (strcmp(key, "skip") != 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "raycast: unknown option '%s'", key);
    if (strcmp(value, "true") == 0)
        rp.skip = 1;
    else if (strcmp(value, "false") == 0)
        rp.skip = 0;
    else
        return cdvr_error_set(err, CDVR_ERR_ARG, "raycast: option 'skip': true or false expected, "
                              "got '%s'", value);
    memcpy(p->bytes, &rp, sizeof rp);
    return CDVR_OK;
}

static cdvr_status render_cpu(cdvr_render_ctx *ctx, const cdvr_volume *vol, size_t t,
                              cdvr_render_opts *opts, cdvr_render_stats *stats,
                              cdvr_image **out, cdvr_error *err)
{
    double start = cdvr_now_ms();
    cdvr_status s = cdvr_render_cpu_cached(vol, t, opts, cdvr_render_ctx_cpu_skip(ctx), out, err);
    if (s != CDVR_OK)
        return s;
    cdvr_render_stats_integer(stats, "samples", (long long)opts->samples);
    cdvr_render_stats_number(stats, "ms", cdvr_now_ms() - start);
    return CDVR_OK;
}

#if CDVR_HAVE_OPENCL

static void cl_stats(cdvr_render_ctx *ctx, cdvr_cl_stream *s, double ms, cdvr_render_stats *stats)
{
    cdvr_cl *cl;
    cdvr_render_ctx_cl(ctx, &cl, NULL);
    cdvr_render_stats_integer(stats, "samples", (long long)cdvr_cl_last_samples(s));
    cdvr_render_stats_number(stats, "ms", ms);
    cdvr_render_stats_string(stats, "device", cdvr_cl_device_name(cl));
    size_t visible, total;
    cdvr_cl_brick_counts(s, &visible, &total);
    cdvr_render_stats_number(stats, "bricks_visible", total ? (double)visible / (double)total : 0.0);
    cdvr_render_stats_integer(stats, "device_bytes", (long long)cdvr_cl_stream_bytes(s));
    cdvr_render_stats_integer(stats, "volume_bytes", (long long)cdvr_cl_volume_bytes(s));
}

/* Setup (b4) and ray cast (b5) of the stream's frame; grid: flags made on the host, or NULL. */
static cdvr_status raycast_stream(cdvr_cl_stream *s, size_t frame, const cdvr_skip_grid *grid,
                                  const cdvr_render_opts *opts, const cdvr_method_params *p,
                                  const double spacing[3], const double origin[3],
                                  const double direction[9], cdvr_image *img, double *setup_ms,
                                  cdvr_error *err)
{
    (void)p; /* the player sets the stream's skipping itself (player.h: empty_skip) */
    double t0 = cdvr_now_ms();
    cdvr_status st = CDVR_ERR_ARG;
    if (grid) /* flags made in the pipeline: upload them */
        st = cdvr_cl_setup_grid(s, frame, opts->tf, grid, err);
    if (st == CDVR_ERR_ARG)
        st = cdvr_cl_setup(s, frame, opts->tf, err);
    if (setup_ms)
        *setup_ms = cdvr_now_ms() - t0;
    if (st == CDVR_OK)
        st = cdvr_cl_render(s, frame, opts, spacing, origin, direction, img, err);
    return st;
}

/* Renders device frame `frame` of s into a new image and reports the device's figures. */
static cdvr_status render_device_frame(cdvr_render_ctx *ctx, cdvr_cl_stream *s, size_t frame,
                                       const cdvr_render_opts *opts, const double spacing[3],
                                       const double origin[3], const double direction[9],
                                       double start, cdvr_render_stats *stats, cdvr_image **out,
                                       cdvr_error *err)
{
    cdvr_status st = cdvr_image_create(opts->camera->width, opts->camera->height, out, err);
    if (st == CDVR_OK)
        st = cdvr_cl_setup(s, frame, opts->tf, err);
    if (st == CDVR_OK)
        st = cdvr_cl_render(s, frame, opts, spacing, origin, direction, *out, err);
    if (st != CDVR_OK) {
        cdvr_image_free(*out);
        *out = NULL;
        return st;
    }
    cl_stats(ctx, s, cdvr_now_ms() - start, stats);
    return CDVR_OK;
}

static cdvr_status render_cl(cdvr_render_ctx *ctx, const cdvr_volume *vol, size_t t,
                             cdvr_render_opts *opts, const cdvr_method_params *p,
                             cdvr_render_stats *stats, cdvr_image **out, cdvr_error *err)
{
    if (vol->type != CDVR_TYPE_U8 || t >= vol->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "raycast on cl: needs a frame of a u8 volume");
    cdvr_cl_stream *s;
    cdvr_status st = cdvr_render_ctx_stream(ctx, vol->dims, &s, err);
    if (st != CDVR_OK)
        return st;
    double start = cdvr_now_ms();
    cdvr_cl_set_skipping(s, get_params(p).skip);
    st = cdvr_render_ctx_upload(ctx, s, vol, t, err);
    if (st != CDVR_OK)
        return st;
    return render_device_frame(ctx, s, 0, opts, vol->spacing, vol->origin, vol->direction, start,
                               stats, out, err);
}

static cdvr_status raycast_store(cdvr_render_ctx *ctx, cdvr_device_kind device,
                                 const cdvr_store *st, size_t v, size_t t, cdvr_render_opts *opts,
                                 const cdvr_method_params *p, cdvr_render_stats *stats,
                                 cdvr_image **out, cdvr_error *err)
{
    if (device != CDVR_DEVICE_CL)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "raycast: a store renders from its "
                              "chunk on cl only (the cpu decodes it first)");
    const cdvr_store_info *info = cdvr_store_get_info(st);
    double start = cdvr_now_ms();
    cdvr_cl_stream *s;
    size_t frame;
    cdvr_status status = cdvr_render_ctx_load_chunk(ctx, st, v, t, &s, &frame, err);
    if (status != CDVR_OK)
        return status;
    cdvr_cl_set_skipping(s, get_params(p).skip);
    return render_device_frame(ctx, s, frame, opts, info->spacing, info->origin, info->direction,
                               start, stats, out, err);
}

#define RAYCAST_STREAM raycast_stream
#define RAYCAST_STORE raycast_store

#else

static cdvr_status render_cl(cdvr_render_ctx *ctx, const cdvr_volume *vol, size_t t,
                             cdvr_render_opts *opts, const cdvr_method_params *p,
                             cdvr_render_stats *stats, cdvr_image **out, cdvr_error *err)
{
    (void)vol; (void)t; (void)opts; (void)p; (void)stats; (void)out;
    cdvr_cl *cl;
    return cdvr_render_ctx_cl(ctx, &cl, err);
}

#define RAYCAST_STREAM NULL
#define RAYCAST_STORE NULL

#endif

static cdvr_status raycast_render(cdvr_render_ctx *ctx, cdvr_device_kind device,
                                  const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                                  const cdvr_method_params *p, cdvr_render_stats *stats,
                                  cdvr_image **out, cdvr_error *err)
{
    if (device == CDVR_DEVICE_CL)
        return render_cl(ctx, vol, t, opts, p, stats, out, err);
    opts->no_skip = !get_params(p).skip;
    return render_cpu(ctx, vol, t, opts, stats, out, err);
}

const cdvr_render_method cdvr_method_raycast = {
    .name = "raycast",
    .description = "ray casting, front-to-back emission-absorption with trilinear samples "
                   "(render.h; the cpu renderer is the reference, cl matches it to 50 dB)",
    .devices = CDVR_DEVICE_BIT(CDVR_DEVICE_CPU) | CDVR_DEVICE_BIT(CDVR_DEVICE_CL),
    .blends = CDVR_BLEND_BIT(CDVR_BLEND_COMPOSITE) | CDVR_BLEND_BIT(CDVR_BLEND_MAX) |
              CDVR_BLEND_BIT(CDVR_BLEND_MIN) | CDVR_BLEND_BIT(CDVR_BLEND_AVERAGE) |
              CDVR_BLEND_BIT(CDVR_BLEND_ISO),
    .shading = 1,
    .bricks = 1,
    .distribute = CDVR_METHOD_DIST_TIME | CDVR_METHOD_DIST_BRICKS,
    .scene_keys = CDVR_SCENE_STEP | CDVR_SCENE_UNIT | CDVR_SCENE_TERM | CDVR_SCENE_THREADS,
    .options = raycast_options,
    .params_default = raycast_default,
    .params_set = raycast_set,
    .render = raycast_render,
    .render_stream = RAYCAST_STREAM,
    .render_store = RAYCAST_STORE,
};
