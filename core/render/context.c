/* core/render/context.c - the devices a render uses (cdvr_render_ctx, cdvr/method.h): the
 * OpenCL device with one stream reused while the frame dims stay the same, what the stream's
 * frame 0 holds (so rendering the same frame twice uploads nothing: the identity and revision
 * of a held volume's frame, else a host copy of the voxels), and the EGL slicer; the CPU ray
 * caster's skip cache. Each is opened on first use; a failed OpenCL open is remembered, so the
 * default device rule asks the driver once. */
#include "cdvr/method.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/brick_cache.h"
#include "cdvr/device.h"
#include "cdvr/gl.h"
#include "cdvr/store.h"
#include "cdvr/visible.h"

struct cdvr_render_ctx {
    cdvr_cl *cl;
    int cl_failed;               /* cdvr_cl_open failed: cl_error says why */
    cdvr_error cl_error;
    cdvr_cl_stream *stream;
    size_t stream_dims[3];
    uint8_t *frame_copy;         /* host copy of the voxels of the stream's frame 0, or NULL */
    size_t frame_bytes;
    const cdvr_volume *held;     /* cdvr_render_ctx_hold_volume's volume, or NULL */
    cdvr_frame_stamp uploaded;   /* the held volume's frame on the stream (vol NULL: none) */
    uint64_t uploads;            /* frames sent by cdvr_render_ctx_upload */
    cdvr_gl *gl;
    cdvr_brick_cache *cache;     /* the brick cache of the last cached store render, or NULL */
    char *cache_path;            /* its store's path and size: a new store at the address of */
    uint64_t cache_file_bytes;   /* a closed one is not taken for it */
    cdvr_cpu_skip_cache *cpu_skip;
    cdvr_visible *visible;       /* frames decoded by visible cells (the stream may read one) */
    uint8_t *payload, *stored;   /* a stored chunk's payload and stored bytes, kept: a new */
    size_t payload_cap, stored_cap; /* buffer costs its page faults at every render */
};

cdvr_status cdvr_render_ctx_create(cdvr_render_ctx **out, cdvr_error *err)
{
    *out = calloc(1, sizeof **out);
    if (!*out)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "render context: out of memory");
    return CDVR_OK;
}

void cdvr_render_ctx_forget_frame(cdvr_render_ctx *ctx)
{
    free(ctx->frame_copy);
    ctx->frame_copy = NULL;
    ctx->frame_bytes = 0;
    memset(&ctx->uploaded, 0, sizeof ctx->uploaded);
}

void cdvr_render_ctx_hold_volume(cdvr_render_ctx *ctx, const cdvr_volume *vol)
{
    if (vol == ctx->held)
        return;
    ctx->held = vol;
    /* the volume held before may be freed from now on, and another allocated at its address */
    memset(&ctx->uploaded, 0, sizeof ctx->uploaded);
    cdvr_cpu_skip_cache_hold(ctx->cpu_skip, vol);
}

const cdvr_volume *cdvr_render_ctx_held(const cdvr_render_ctx *ctx)
{
    return ctx->held;
}

uint64_t cdvr_render_ctx_uploads(const cdvr_render_ctx *ctx)
{
    return ctx->uploads;
}

void cdvr_render_ctx_free(cdvr_render_ctx *ctx)
{
    if (!ctx)
        return;
    cdvr_render_ctx_forget_frame(ctx);
    cdvr_brick_cache_free(ctx->cache);
    free(ctx->cache_path);
#if CDVR_HAVE_OPENCL
    cdvr_cl_stream_free(ctx->stream);
    cdvr_cl_close(ctx->cl);
#endif
    cdvr_visible_free(ctx->visible); /* after the stream, which may use its frame */
    free(ctx->payload);
    free(ctx->stored);
    cdvr_gl_free(ctx->gl);
    cdvr_cpu_skip_cache_free(ctx->cpu_skip);
    free(ctx);
}

cdvr_status cdvr_render_ctx_visible(cdvr_render_ctx *ctx, cdvr_visible **out, cdvr_error *err)
{
    if (!ctx->visible) {
        cdvr_status s = cdvr_visible_create(&ctx->visible, err);
        if (s != CDVR_OK)
            return s;
    }
    *out = ctx->visible;
    return CDVR_OK;
}

cdvr_status cdvr_render_ctx_brick_cache(cdvr_render_ctx *ctx, const cdvr_store *st, size_t v,
                                        uint64_t budget_bytes, cdvr_brick_cache **out,
                                        cdvr_error *err)
{
    const cdvr_store_info *in = cdvr_store_get_info(st);
    if (!cdvr_brick_cache_serves(ctx->cache, st, v, budget_bytes) || !ctx->cache_path ||
        strcmp(ctx->cache_path, cdvr_store_path(st)) != 0 ||
        ctx->cache_file_bytes != in->file_bytes) {
        cdvr_brick_cache_free(ctx->cache);
        free(ctx->cache_path);
        ctx->cache = NULL;
        ctx->cache_path = strdup(cdvr_store_path(st));
        ctx->cache_file_bytes = in->file_bytes;
        if (!ctx->cache_path)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "render context: out of memory");
        cdvr_status s = cdvr_brick_cache_create(st, v, budget_bytes, &ctx->cache, err);
        if (s != CDVR_OK)
            return s;
    }
    *out = ctx->cache;
    return CDVR_OK;
}

cdvr_status cdvr_render_ctx_gl(cdvr_render_ctx *ctx, cdvr_gl **out, cdvr_error *err)
{
    if (!ctx->gl) {
        cdvr_status s = cdvr_gl_create(&ctx->gl, err);
        if (s != CDVR_OK)
            return s;
    }
    *out = ctx->gl;
    return CDVR_OK;
}

cdvr_cpu_skip_cache *cdvr_render_ctx_cpu_skip(cdvr_render_ctx *ctx)
{
    if (!ctx) /* the player renders on the CPU without a context */
        return NULL;
    if (!ctx->cpu_skip && cdvr_cpu_skip_cache_create(&ctx->cpu_skip, NULL) != CDVR_OK)
        ctx->cpu_skip = NULL;
    cdvr_cpu_skip_cache_hold(ctx->cpu_skip, ctx->held);
    return ctx->cpu_skip;
}

#if CDVR_HAVE_OPENCL

cdvr_status cdvr_render_ctx_cl(cdvr_render_ctx *ctx, cdvr_cl **out, cdvr_error *err)
{
    if (!ctx->cl && !ctx->cl_failed && cdvr_cl_open(&ctx->cl, &ctx->cl_error) != CDVR_OK)
        ctx->cl_failed = 1;
    if (ctx->cl_failed) {
        if (err)
            *err = ctx->cl_error;
        return ctx->cl_error.status;
    }
    *out = ctx->cl;
    return CDVR_OK;
}

int cdvr_render_ctx_has_cl(cdvr_render_ctx *ctx)
{
    cdvr_cl *cl;
    return cdvr_render_ctx_cl(ctx, &cl, NULL) == CDVR_OK;
}

cdvr_status cdvr_render_ctx_stream(cdvr_render_ctx *ctx, const size_t dims[3],
                                   cdvr_cl_stream **out, cdvr_error *err)
{
    cdvr_cl *cl;
    cdvr_status s = cdvr_render_ctx_cl(ctx, &cl, err);
    if (s != CDVR_OK)
        return s;
    if (!ctx->stream || memcmp(ctx->stream_dims, dims, sizeof ctx->stream_dims) != 0) {
        cdvr_cl_stream_free(ctx->stream);
        ctx->stream = NULL;
        cdvr_render_ctx_forget_frame(ctx);
        s = cdvr_cl_stream_create(cl, dims, &ctx->stream, err);
        if (s != CDVR_OK)
            return s;
        memcpy(ctx->stream_dims, dims, sizeof ctx->stream_dims);
    }
    *out = ctx->stream;
    return CDVR_OK;
}

/* One half of same_bytes's comparison, on its own thread. */
typedef struct compare_half {
    const uint8_t *a, *b;
    size_t bytes;
    int equal;
} compare_half;

static void *compare_half_run(void *arg)
{
    compare_half *h = arg;
    h->equal = memcmp(h->a, h->b, h->bytes) == 0;
    return NULL;
}

/* memcmp(a, b, bytes) == 0; a large frame is compared in two halves on two threads when the
 * machine has two cores (the comparison is memory-bound: two cores halve it, about 5 ms of a
 * 35 MB frame on each render otherwise). */
static int same_bytes(const uint8_t *a, const uint8_t *b, size_t bytes)
{
    compare_half upper = {a + bytes / 2, b + bytes / 2, bytes - bytes / 2, 0};
    pthread_t thread;
    if (bytes < ((size_t)4 << 20) || sysconf(_SC_NPROCESSORS_ONLN) < 2 ||
        pthread_create(&thread, NULL, compare_half_run, &upper) != 0)
        return memcmp(a, b, bytes) == 0;
    int lower_equal = memcmp(a, b, bytes / 2) == 0;
    pthread_join(thread, NULL);
    return lower_equal && upper.equal;
}

/* The frame of a held volume is known by its identity and revision (O(1), no host copy);
 * any other volume may have been edited in place (v:set) or freed and another allocated at
 * its address, so its voxels are compared with a host copy of what was uploaded (memcmp is
 * exact and faster than hashing the frame). */
cdvr_status cdvr_render_ctx_upload(cdvr_render_ctx *ctx, cdvr_cl_stream *s,
                                   const cdvr_volume *vol, size_t t, cdvr_error *err)
{
    /* the stream's frame 0 is frame t of the held volume at its current revision */
    if (vol == ctx->held && cdvr_frame_stamp_same(ctx->uploaded, cdvr_volume_stamp(vol, t)))
        return CDVR_OK;
    const uint8_t *voxels = cdvr_volume_frame(vol, t);
    size_t bytes = cdvr_volume_voxels(vol);
    int held = vol == ctx->held;
    if (ctx->frame_copy && ctx->frame_bytes == bytes && same_bytes(ctx->frame_copy, voxels, bytes)) {
        if (held) { /* known by identity from now on: the copy is not needed */
            cdvr_render_ctx_forget_frame(ctx);
            ctx->uploaded = cdvr_volume_stamp(vol, t);
        }
        return CDVR_OK;
    }
    cdvr_render_ctx_forget_frame(ctx);
    cdvr_status st = cdvr_cl_upload_frames(s, voxels, 1, err);
    if (st != CDVR_OK)
        return st;
    ctx->uploads++;
    if (held) {
        ctx->uploaded = cdvr_volume_stamp(vol, t);
        return CDVR_OK;
    }
    ctx->frame_copy = malloc(bytes ? bytes : 1);
    if (ctx->frame_copy) { /* without a copy the next render uploads again */
        memcpy(ctx->frame_copy, voxels, bytes);
        ctx->frame_bytes = bytes;
    }
    return CDVR_OK;
}

static cdvr_status decode_on_host(cdvr_cl_stream *s, const cdvr_store *st, size_t v, size_t t,
                                  cdvr_error *err)
{
    cdvr_volume *vol;
    cdvr_status status = cdvr_store_decode(st, v, t, &vol, err);
    if (status != CDVR_OK)
        return status;
    status = cdvr_cl_upload_frames(s, vol->data, 1, err);
    cdvr_volume_free(vol);
    return status;
}

cdvr_status cdvr_render_ctx_load_chunk(cdvr_render_ctx *ctx, const cdvr_store *st, size_t v,
                                       size_t t, cdvr_cl_stream **stream, size_t *frame,
                                       cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    size_t c = cdvr_store_chunk_for_time(st, v, t);
    const cdvr_chunk_info *chunk = c != (size_t)-1 ? cdvr_store_chunk(st, v, c) : NULL;
    if (!chunk)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no variant %d timestep %d",
                              cdvr_store_path(st), (int)v + 1, (int)t + 1);
    const cdvr_codec *codec;
    cdvr_status status = cdvr_store_variant_codec(st, v, &codec, err);
    if (status == CDVR_OK)
        status = cdvr_render_ctx_stream(ctx, info->dims, stream, err);
    if (status != CDVR_OK)
        return status;
    cdvr_render_ctx_forget_frame(ctx); /* the stream's frames are about to be replaced */
    *frame = 0;
    if (info->nbricks > 1 || codec->cl_mode == CDVR_CODEC_CL_NONE)
        return decode_on_host(*stream, st, v, t, err);
    status = cdvr_store_load_payload_into(st, v, c, &ctx->payload, &ctx->payload_cap,
                                          &ctx->stored, &ctx->stored_cap, err);
    if (status != CDVR_OK)
        return status;
    status = cdvr_cl_upload(*stream, ctx->payload, (size_t)chunk->payload_bytes, err);
    if (status == CDVR_OK)
        status = cdvr_cl_decode(*stream, chunk->codec, &chunk->params, chunk->count, err);
    if (status != CDVR_OK) {
        cdvr_error inner = *err;
        return cdvr_error_set(err, status, "%s: variant %s chunk %d: %s", cdvr_store_path(st),
                              cdvr_store_variant(st, v)->name, (int)c + 1, inner.msg);
    }
    *frame = t - chunk->t0;
    return CDVR_OK;
}

#else /* no OpenCL in this build */

static cdvr_status no_cl(cdvr_error *err)
{
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED,
                          "device 'cl': OpenCL support is not built into this cdvr");
}

cdvr_status cdvr_render_ctx_cl(cdvr_render_ctx *ctx, cdvr_cl **out, cdvr_error *err)
{
    (void)ctx;
    *out = NULL;
    return no_cl(err);
}

int cdvr_render_ctx_has_cl(cdvr_render_ctx *ctx)
{
    (void)ctx;
    return 0;
}

cdvr_status cdvr_render_ctx_stream(cdvr_render_ctx *ctx, const size_t dims[3],
                                   cdvr_cl_stream **out, cdvr_error *err)
{
    (void)ctx; (void)dims;
    *out = NULL;
    return no_cl(err);
}

cdvr_status cdvr_render_ctx_upload(cdvr_render_ctx *ctx, cdvr_cl_stream *s,
                                   const cdvr_volume *vol, size_t t, cdvr_error *err)
{
    (void)ctx; (void)s; (void)vol; (void)t;
    return no_cl(err);
}

cdvr_status cdvr_render_ctx_load_chunk(cdvr_render_ctx *ctx, const cdvr_store *st, size_t v,
                                       size_t t, cdvr_cl_stream **stream, size_t *frame,
                                       cdvr_error *err)
{
    (void)ctx; (void)st; (void)v; (void)t;
    *stream = NULL;
    *frame = 0;
    return no_cl(err);
}

#endif
