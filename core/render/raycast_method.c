/* core/render/raycast_method.c - the "raycast" render method (cdvr/method.h): the CPU reference
 * ray caster (render.h) and the OpenCL one (device.h), which follows it to 50 dB. */
#include "cdvr/method.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/brick_cache.h"
#include "cdvr/bricks.h"
#include "cdvr/device.h"
#include "cdvr/store.h"
#include "cdvr/timing.h"
#include "cdvr/visible.h"

typedef struct raycast_params {
    int skip;  /* empty-space skipping */
    int fetch; /* fetch-mode codecs on cl: 0 auto, 1 sample, 2 bulk (cdvr_cl_fetch_path) */
    int cache; /* a store on cl through the brick cache (cdvr/brick_cache.h) */
    double budget_mb, lod_error;
} raycast_params;

static const char *const fetch_names[] = {"auto", "sample", "bulk"};

static const cdvr_method_option raycast_options[] = {
    {"skip", CDVR_MOPT_BOOLEAN, "true", NULL,
     "empty-space skipping by brick min/max (false: every sample is taken; the image is the same)"},
    {"fetch", CDVR_MOPT_CHOICE, "auto", "auto|sample|bulk",
     "a store of a fetch-mode codec (hvq) on cl: 'sample' reads every sample through the "
     "codec's fetch function, 'bulk' decodes the chunk with its C decoder and renders dense, "
     "'auto' bulk on a CPU device and sample on a GPU (same images)"},
    {"cache", CDVR_MOPT_BOOLEAN, "false", NULL,
     "a store through the brick cache: decoded bricks in a pool of budget_mb, a level per "
     "brick by lod_error (cdvr/brick_cache.h); on cl the ray caster marches brick by brick "
     "(coarse bricks at their own resolution), fetch='sample' reads every voxel through the "
     "page table, fetch='bulk' renders a dense frame assembled from the bricks when it fits "
     "the budget; stats add resident_bytes, payload_bytes, bricks per level and cache_path"},
    {"budget_mb", CDVR_MOPT_NUMBER, "0", NULL,
     "the brick cache's budget in MB (10^6 bytes) of voxels; 0: a quarter of the device's "
     "memory"},
    {"lod_error", CDVR_MOPT_NUMBER, "1", NULL,
     "the brick cache's level of detail: a brick's voxel may project to at most this many "
     "pixels at its nearest point (0: level 0 everywhere, as far as the budget allows)"},
    {NULL, 0, NULL, NULL, NULL}};

static raycast_params get_params(const cdvr_method_params *p)
{
    raycast_params rp;
    memcpy(&rp, p->bytes, sizeof rp);
    return rp;
}

static void raycast_default(cdvr_method_params *p)
{
    raycast_params rp = {.skip = 1, .lod_error = 1.0};
    memcpy(p->bytes, &rp, sizeof rp);
}

static cdvr_status raycast_set(cdvr_method_params *p, const char *key, const char *value,
                               cdvr_error *err)
{
    raycast_params rp = get_params(p);
    if (strcmp(key, "fetch") == 0) {
        for (int i = 0; i < 3; i++)
            if (strcmp(value, fetch_names[i]) == 0) {
                rp.fetch = i;
                memcpy(p->bytes, &rp, sizeof rp);
                return CDVR_OK;
            }
        return cdvr_error_set(err, CDVR_ERR_ARG, "raycast: option 'fetch': auto, sample or bulk "
                              "expected, got '%s'", value);
    }
    if (strcmp(key, "budget_mb") == 0 || strcmp(key, "lod_error") == 0) {
        char *end;
        double x = strtod(value, &end);
        if (end == value || *end || !(x >= 0) || x > 1e12)
            return cdvr_error_set(err, CDVR_ERR_ARG, "raycast: option '%s': a number >= 0 "
                                  "expected, got '%s'", key, value);
        *(key[0] == 'b' ? &rp.budget_mb : &rp.lod_error) = x;
        memcpy(p->bytes, &rp, sizeof rp);
        return CDVR_OK;
    }
    if (strcmp(key, "cache") == 0) {
        if (strcmp(value, "true") != 0 && strcmp(value, "false") != 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "raycast: option 'cache': true or false "
                                  "expected, got '%s'", value);
        rp.cache = strcmp(value, "true") == 0;
        memcpy(p->bytes, &rp, sizeof rp);
        return CDVR_OK;
    }
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

/* The brick cache's figures of its last frame into stats. */
static void cache_stats(const cdvr_brick_cache *bc, cdvr_render_stats *stats)
{
    cdvr_brick_cache_stats cs;
    cdvr_brick_cache_get_stats(bc, &cs);
    cdvr_render_stats_integer(stats, "resident_bytes", (long long)cs.resident_bytes);
    cdvr_render_stats_integer(stats, "cache_bytes", (long long)cs.cache_bytes);
    cdvr_render_stats_integer(stats, "payload_bytes", (long long)cs.payload_bytes);
    cdvr_render_stats_integer(stats, "bricks_decoded", (long long)cs.decoded);
    cdvr_render_stats_number(stats, "cache_decode_ms", cs.decode_ms);
    for (size_t l = 0; l < cs.levels; l++) {
        char key[24];
        snprintf(key, sizeof key, "bricks_level%u", (unsigned)l);
        cdvr_render_stats_integer(stats, key, (long long)cs.bricks_at[l]);
    }
}

/* The CPU reference through the brick cache: the cache's dense frame (cdvr_brick_cache_dense:
 * exactly its C fetch at every voxel, assembled again only where a brick's entry changed;
 * the reference renders dense), then the CPU ray caster. */
static cdvr_status raycast_cached_cpu(cdvr_render_ctx *ctx, const cdvr_store *st, size_t v,
                                      size_t t, cdvr_render_opts *opts,
                                      const raycast_params *rp, cdvr_render_stats *stats,
                                      cdvr_image **out, cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    uint64_t budget = rp->budget_mb > 0 ? (uint64_t)(rp->budget_mb * 1e6) : (uint64_t)1 << 30;
    cdvr_brick_cache *bc;
    const uint8_t *payload, *dense = NULL;
    size_t bytes;
    cdvr_status s = cdvr_render_ctx_brick_cache(ctx, st, v, budget, &bc, err);
    if (s == CDVR_OK)
        s = cdvr_brick_cache_frame(bc, t, opts->camera, opts->tf, rp->lod_error, &payload,
                                   &bytes, err);
    if (s == CDVR_OK)
        s = cdvr_brick_cache_dense(bc, &dense, err);
    if (s != CDVR_OK)
        return s;
    cdvr_volume vol = {.timesteps = 1, .type = CDVR_TYPE_U8, .data = (void *)dense};
    memcpy(vol.dims, info->dims, sizeof vol.dims);
    memcpy(vol.spacing, info->spacing, sizeof vol.spacing);
    memcpy(vol.origin, info->origin, sizeof vol.origin);
    memcpy(vol.direction, info->direction, sizeof vol.direction);
    vol.window[0] = info->qlo;
    vol.window[1] = info->qhi;
    s = render_cpu(ctx, &vol, 0, opts, stats, out, err);
    if (s == CDVR_OK)
        cache_stats(bc, stats);
    return s;
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

/* Renders device frame `frame` of s into a new image, with the skip grid made on the host
 * (NULL: the device's own), and reports the device's figures. */
static cdvr_status render_device_frame(cdvr_render_ctx *ctx, cdvr_cl_stream *s, size_t frame,
                                       const cdvr_skip_grid *grid, const cdvr_render_opts *opts,
                                       const double spacing[3], const double origin[3],
                                       const double direction[9], double start,
                                       cdvr_render_stats *stats, cdvr_image **out,
                                       cdvr_error *err)
{
    /* unset: cdvr_cl_render writes every pixel */
    cdvr_status st = cdvr_image_create_unset(opts->camera->width, opts->camera->height, out, err);
    if (st == CDVR_OK)
        st = grid ? cdvr_cl_setup_grid(s, frame, opts->tf, grid, err)
                  : cdvr_cl_setup(s, frame, opts->tf, err);
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
    double start = cdvr_now_ms();
    uint64_t uploads = cdvr_render_ctx_uploads(ctx);
    cdvr_status st = cdvr_render_ctx_volume_stream(ctx, vol, t, &s, err);
    if (st != CDVR_OK)
        return st;
    cdvr_cl_set_skipping(s, get_params(p).skip);
    st = render_device_frame(ctx, s, 0, NULL, opts, vol->spacing, vol->origin, vol->direction,
                             start, stats, out, err);
    if (st == CDVR_OK) /* 0 when the device held the frame already */
        cdvr_render_stats_integer(stats, "uploaded_bytes",
                                  cdvr_render_ctx_uploads(ctx) != uploads
                                      ? (long long)cdvr_volume_voxels(vol) : 0);
    return st;
}

/* The brick march (cdvr/brick_cache.h) of the cache's frame on s: the payload with the march
 * flag, the skip grid from the cache's brick ranges (cdvr_brick_cache_skip_grid: no pass of
 * the device over the voxels; made again only when the frame's bricks change), then the ray
 * cast into img. */
static cdvr_status march_into(cdvr_brick_cache *bc, cdvr_cl_stream *s, const uint8_t *payload,
                              size_t bytes, const cdvr_store_info *info,
                              const cdvr_render_opts *opts, cdvr_image *img, double *setup_ms,
                              cdvr_error *err)
{
    double t0 = cdvr_now_ms();
    cdvr_codec_params march = {{0}};
    march.bytes[CDVR_BRICK_CACHE_PARAM_MARCH] = 1;
    const cdvr_skip_grid *grid;
    cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_SAMPLE); /* the payload as it is, no dense copy */
    cdvr_status status = cdvr_cl_upload(s, payload, bytes, err);
    if (status == CDVR_OK)
        status = cdvr_cl_decode(s, cdvr_brick_cache_codec(), &march, 1, err);
    if (status == CDVR_OK)
        status = cdvr_brick_cache_skip_grid(bc, CDVR_RANGE_SHIFT, opts->tf,
                                            opts->look.blend == CDVR_BLEND_COMPOSITE, &grid, err);
    if (status == CDVR_OK)
        status = cdvr_cl_setup_grid(s, 0, opts->tf, grid, err);
    *setup_ms = cdvr_now_ms() - t0;
    if (status == CDVR_OK) /* the grid stays until the render (a max or min render reads it) */
        status = cdvr_cl_render(s, 0, opts, info->spacing, info->origin, info->direction, img,
                                err);
    return status;
}

/* march_into a new image, with the device's figures. */
static cdvr_status render_march(cdvr_render_ctx *ctx, cdvr_brick_cache *bc, cdvr_cl_stream *s,
                                const uint8_t *payload, size_t bytes,
                                const cdvr_store_info *info, const cdvr_render_opts *opts,
                                double start, double *setup_ms, cdvr_render_stats *stats,
                                cdvr_image **out, cdvr_error *err)
{
    cdvr_status status = cdvr_image_create_unset(opts->camera->width, opts->camera->height, out,
                                                 err); /* cdvr_cl_render writes every pixel */
    if (status == CDVR_OK)
        status = march_into(bc, s, payload, bytes, info, opts, *out, setup_ms, err);
    if (status != CDVR_OK) {
        cdvr_image_free(*out);
        *out = NULL;
        return status;
    }
    cl_stats(ctx, s, cdvr_now_ms() - start, stats);
    return CDVR_OK;
}

/* The cache's frame as device frame 0 of s: the assembled dense frame (dense), else the
 * payload read voxel by voxel through the page table. */
static cdvr_status load_cached_frame(cdvr_brick_cache *bc, cdvr_cl_stream *s, int dense,
                                     const uint8_t *payload, size_t bytes, cdvr_error *err)
{
    if (dense) {
        const uint8_t *frame;
        cdvr_status status = cdvr_brick_cache_dense(bc, &frame, err);
        return status == CDVR_OK ? cdvr_cl_use_host_frames(s, frame, 1, err) : status;
    }
    cdvr_codec_params none = {{0}};
    cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_SAMPLE); /* the page table, no dense copy */
    cdvr_status status = cdvr_cl_upload(s, payload, bytes, err);
    return status == CDVR_OK ? cdvr_cl_decode(s, cdvr_brick_cache_codec(), &none, 1, err)
                             : status;
}

/* Timestep t of variant v through the context's brick cache (raycast_params.cache): the
 * brick march, or with fetch="sample" the per-voxel fetch through the page table, or with
 * fetch="bulk" a dense frame assembled from the cached bricks when it fits the budget. */
static cdvr_status raycast_cached(cdvr_render_ctx *ctx, const cdvr_store *st, size_t v, size_t t,
                                  cdvr_render_opts *opts, const raycast_params *rp,
                                  cdvr_render_stats *stats, cdvr_image **out, cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    double start = cdvr_now_ms();
    cdvr_cl *cl;
    cdvr_status status = cdvr_render_ctx_cl(ctx, &cl, err);
    if (status != CDVR_OK)
        return status;
    uint64_t budget = rp->budget_mb > 0 ? (uint64_t)(rp->budget_mb * 1e6)
                                        : cdvr_cl_get_info(cl)->global_mem_bytes / 4;
    cdvr_brick_cache *bc;
    const uint8_t *payload;
    size_t bytes;
    cdvr_cl_stream *s;
    double frame_ms = cdvr_now_ms(), setup_ms = 0;
    status = cdvr_render_ctx_brick_cache(ctx, st, v, budget ? budget : 1, &bc, err);
    if (status == CDVR_OK)
        status = cdvr_brick_cache_frame(bc, t, opts->camera, opts->tf, rp->lod_error, &payload,
                                   &bytes, err);
    frame_ms = cdvr_now_ms() - frame_ms;
    if (status == CDVR_OK)
        status = cdvr_render_ctx_stream(ctx, info->dims, &s, err);
    if (status != CDVR_OK)
        return status;
    cdvr_render_ctx_forget_frame(ctx);
    cdvr_cl_set_skipping(s, rp->skip);
    int dense = rp->fetch == CDVR_CL_FETCH_BULK &&
                (uint64_t)info->dims[0] * info->dims[1] * info->dims[2] <= budget;
    int march = !dense && rp->fetch != CDVR_CL_FETCH_SAMPLE;
    if (march) {
        status = render_march(ctx, bc, s, payload, bytes, info, opts, start, &setup_ms, stats,
                              out, err);
    } else {
        status = load_cached_frame(bc, s, dense, payload, bytes, err);
        if (status == CDVR_OK)
            status = render_device_frame(ctx, s, 0, NULL, opts, info->spacing, info->origin,
                                         info->direction, start, stats, out, err);
    }
    if (status == CDVR_OK) {
        cache_stats(bc, stats);
        cdvr_render_stats_string(stats, "cache_path", march ? "march" : dense ? "dense"
                                                                            : "page_table");
        cdvr_render_stats_number(stats, "cache_frame_ms", frame_ms);
        cdvr_render_stats_number(stats, "cache_setup_ms", setup_ms);
    }
    return status;
}

/* Frames in the chunk holding timestep t of variant v (0 when there is none). */
static size_t chunk_frames(const cdvr_store *st, size_t v, size_t t)
{
    size_t c = cdvr_store_chunk_for_time(st, v, t);
    const cdvr_chunk_info *chunk = c != (size_t)-1 ? cdvr_store_chunk(st, v, c) : NULL;
    return chunk ? chunk->count : 0;
}

/* Loads timestep t's chunk into s (its fetch path as set) and renders it. */
static cdvr_status load_and_render(cdvr_render_ctx *ctx, cdvr_cl_stream *s, const cdvr_store *st,
                                   size_t v, size_t t, cdvr_render_opts *opts,
                                   const raycast_params *rp, cdvr_render_stats *stats,
                                   cdvr_image **out, cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    double start = cdvr_now_ms();
    size_t frame;
    cdvr_status status = cdvr_render_ctx_load_chunk(ctx, st, v, t, &s, &frame, err);
    if (status != CDVR_OK)
        return status;
    cdvr_cl_set_skipping(s, rp->skip);
    return render_device_frame(ctx, s, frame, NULL, opts, info->spacing, info->origin,
                               info->direction, start, stats, out, err);
}

/* Whether timestep t's chunk, which the host decodes (a codec without device code, or a
 * fetch-mode codec on its bulk path), is decoded by visible cells (cdvr/visible.h): a
 * composite render with skipping, and range tables of the device's bricks or coarser. */
static int decodes_visible(const cdvr_store *st, size_t v, size_t t, const cdvr_codec *codec,
                           cdvr_cl_fetch_path path, const cdvr_render_opts *opts,
                           const raycast_params *rp)
{
    int on_host = codec->cl_mode == CDVR_CODEC_CL_NONE ||
                  (codec->cl_mode == CDVR_CODEC_CL_FETCH && path == CDVR_CL_FETCH_BULK);
    return on_host && rp->skip && opts->look.blend == CDVR_BLEND_COMPOSITE &&
           cdvr_cl_brick_edge() == 1u << CDVR_RANGE_SHIFT &&
           cdvr_visible_applies(st, v, cdvr_store_chunk_for_time(st, v, t));
}

/* Timestep t's chunk decoded by visible cells into the context's frame, which the stream reads
 * in place, and rendered with the grid made from the store's range table. *applied 0 (nothing
 * rendered) when this TF needs the whole frame decoded (cdvr_visible_decode). A linear frame
 * even where the player decodes tiles (cdvr_cl_takes_host_tiles): its grid is refined, tiles'
 * are not (engine CT hvq shaded at 512^2: 50 against 60 ms, 25% fewer samples). */
static cdvr_status render_visible(cdvr_render_ctx *ctx, cdvr_cl_stream *s, const cdvr_store *st,
                                  size_t v, size_t t, cdvr_render_opts *opts,
                                  cdvr_render_stats *stats, cdvr_image **out, int *applied,
                                  cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    double start = cdvr_now_ms();
    int gradients = opts->look.shade.enabled || opts->look.gradient_opacity.npoints;
    cdvr_visible *vis;
    cdvr_status status = cdvr_render_ctx_visible(ctx, &vis, err);
    if (status == CDVR_OK)
        status = cdvr_visible_decode(vis, st, v, cdvr_store_chunk_for_time(st, v, t), opts->tf,
                                     gradients, applied, err);
    if (status != CDVR_OK || !*applied)
        return status;
    cdvr_render_ctx_forget_frame(ctx); /* the stream's frame is replaced */
    status = cdvr_cl_use_host_frames(s, cdvr_visible_frame(vis), 1, err);
    if (status == CDVR_OK)
        status = render_device_frame(ctx, s, 0, cdvr_visible_grid(vis), opts, info->spacing,
                                     info->origin, info->direction, start, stats, out, err);
    if (status == CDVR_OK)
        cdvr_render_stats_number(stats, "decoded_share", cdvr_visible_share(vis));
    return status;
}

/* The first render of a fetch-mode codec's size class on a CPU device (cdvr_cl_fetch_path
 * AUTO, nothing remembered): the whole frame (load, decode, setup, ray cast) through the
 * per-sample fetch, then through the bulk decoder; the faster path is remembered for the
 * device, and the second image (the same as the first: cdvr/codec.h) is the result. */
static cdvr_status probe_fetch_paths(cdvr_render_ctx *ctx, cdvr_cl_stream *s,
                                     const cdvr_store *st, size_t v, size_t t,
                                     cdvr_render_opts *opts, const raycast_params *rp,
                                     const cdvr_codec *codec, size_t count,
                                     cdvr_render_stats *stats, cdvr_image **out, cdvr_error *err)
{
    cdvr_image *sampled = NULL;
    double t0 = cdvr_now_ms();
    cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_SAMPLE);
    cdvr_status status = load_and_render(ctx, s, st, v, t, opts, rp, stats, &sampled, err);
    double sample_ms = cdvr_now_ms() - t0;
    cdvr_image_free(sampled);
    if (status == CDVR_OK) {
        double t1 = cdvr_now_ms();
        cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_BULK);
        status = load_and_render(ctx, s, st, v, t, opts, rp, stats, out, err);
        double bulk_ms = cdvr_now_ms() - t1;
        if (status == CDVR_OK) {
            cdvr_cl_remember_fetch_path(s, codec, count, sample_ms, bulk_ms);
            cdvr_render_stats_string(stats, "fetch_path", "bulk");
            cdvr_render_stats_number(stats, "fetch_probe_sample_ms", sample_ms);
            cdvr_render_stats_number(stats, "fetch_probe_bulk_ms", bulk_ms);
        }
    }
    cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_AUTO);
    return status;
}

/* A store's chunk on cl: its codec's path (a fetch-mode codec's measured once per device). */
static cdvr_status raycast_store_cl(cdvr_render_ctx *ctx, const cdvr_store *st, size_t v, size_t t,
                                    cdvr_render_opts *opts, const raycast_params *rp,
                                    cdvr_render_stats *stats, cdvr_image **out, cdvr_error *err)
{
    if (rp->cache)
        return raycast_cached(ctx, st, v, t, opts, rp, stats, out, err);
    const cdvr_store_info *info = cdvr_store_get_info(st);
    cdvr_cl_stream *s;
    cdvr_status status = cdvr_render_ctx_stream(ctx, info->dims, &s, err);
    if (status != CDVR_OK)
        return status;
    cdvr_cl_set_fetch_path(s, (cdvr_cl_fetch_path)rp->fetch);
    const cdvr_codec *codec;
    status = cdvr_store_variant_codec(st, v, &codec, err);
    if (status != CDVR_OK)
        return status;
    size_t count = chunk_frames(st, v, t);
    int fetch = codec->cl_mode == CDVR_CODEC_CL_FETCH && count && info->nbricks == 1;
    cdvr_cl_fetch_path path = fetch ? cdvr_cl_fetch_path_for(s, codec, count) : CDVR_CL_FETCH_AUTO;
    if (fetch && path == CDVR_CL_FETCH_AUTO)
        return probe_fetch_paths(ctx, s, st, v, t, opts, rp, codec, count, stats, out, err);
    int applied = 0;
    if (count && decodes_visible(st, v, t, codec, path, opts, rp)) {
        cdvr_cl_set_skipping(s, 1);
        status = render_visible(ctx, s, st, v, t, opts, stats, out, &applied, err);
        if (status != CDVR_OK)
            return status;
    }
    if (!applied)
        status = load_and_render(ctx, s, st, v, t, opts, rp, stats, out, err);
    if (status == CDVR_OK && fetch)
        cdvr_render_stats_string(stats, "fetch_path",
                                 path == CDVR_CL_FETCH_SAMPLE ? "sample" : "bulk");
    return status;
}

#define RAYCAST_STREAM raycast_stream

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

#endif

static cdvr_status raycast_store(cdvr_render_ctx *ctx, cdvr_device_kind device,
                                 const cdvr_store *st, size_t v, size_t t, cdvr_render_opts *opts,
                                 const cdvr_method_params *p, cdvr_render_stats *stats,
                                 cdvr_image **out, cdvr_error *err)
{
    raycast_params rp = get_params(p);
    if (rp.cache && device == CDVR_DEVICE_CPU)
        return raycast_cached_cpu(ctx, st, v, t, opts, &rp, stats, out, err);
#if CDVR_HAVE_OPENCL
    if (device == CDVR_DEVICE_CL)
        return raycast_store_cl(ctx, st, v, t, opts, &rp, stats, out, err);
#endif
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "raycast: a store renders from its chunk "
                          "on cl only (the cpu decodes it first, or renders it through the "
                          "brick cache with cache=true)");
}

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
    .render_store = raycast_store,
};
