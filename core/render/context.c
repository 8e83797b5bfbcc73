/* core/render/context.c - the devices a render uses (cdvr_render_ctx, cdvr/method.h): the
 * OpenCL device with up to CDVR_RENDER_CTX_STREAMS streams, each reused while its frame dims
 * stay the same and knowing what its frame 0 holds (so rendering the same frame twice uploads
 * nothing: the identity and revision of a held volume's frame, else a host copy of the
 * voxels; two volumes rendered in turn keep a stream each), and the EGL slicer; the CPU ray
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

/* One OpenCL stream and what its frame 0 holds. */
typedef struct ctx_slot {
    cdvr_cl_stream *stream;      /* NULL: not made yet */
    size_t dims[3];
    uint8_t *frame_copy;         /* host copy of the voxels of the stream's frame 0, or NULL */
    size_t frame_bytes;
    cdvr_frame_stamp uploaded;   /* a held volume's frame on the stream (vol NULL: none) */
    uint64_t used;               /* the context's tick at its last use (0: never) */
} ctx_slot;

struct cdvr_render_ctx {
    cdvr_cl *cl;
    int cl_failed;               /* cdvr_cl_open failed: cl_error says why */
    cdvr_error cl_error;
    ctx_slot slots[CDVR_RENDER_CTX_STREAMS];
    ctx_slot *current;           /* the slot whose stream was handed out last, or NULL */
    uint64_t tick;
    const cdvr_volume *held[CDVR_RENDER_CTX_HOLDS]; /* cdvr_render_ctx_hold_volume's, or NULL */
    uint64_t held_used[CDVR_RENDER_CTX_HOLDS];      /* tick of each hold (0: none) */
    const cdvr_volume *last_held; /* the volume held last (the CPU skip cache keeps its ranges) */
    uint64_t uploads;            /* frames sent by cdvr_render_ctx_volume_stream */
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

static void slot_forget(ctx_slot *slot)
{
    free(slot->frame_copy);
    slot->frame_copy = NULL;
    slot->frame_bytes = 0;
    memset(&slot->uploaded, 0, sizeof slot->uploaded);
}

void cdvr_render_ctx_forget_frame(cdvr_render_ctx *ctx)
{
    if (ctx->current)
        slot_forget(ctx->current);
}

int cdvr_render_ctx_held_index(const cdvr_render_ctx *ctx, const cdvr_volume *vol)
{
    for (int i = 0; vol && i < CDVR_RENDER_CTX_HOLDS; i++)
        if (ctx->held[i] == vol)
            return i;
    return -1;
}

static void release_at(cdvr_render_ctx *ctx, int i)
{
    const cdvr_volume *old = ctx->held[i];
    if (!old)
        return;
    ctx->held[i] = NULL;
    ctx->held_used[i] = 0;
    /* it may be freed from now on, and another allocated at its address */
    for (int k = 0; k < CDVR_RENDER_CTX_STREAMS; k++)
        if (ctx->slots[k].uploaded.vol == old)
            memset(&ctx->slots[k].uploaded, 0, sizeof ctx->slots[k].uploaded);
    if (ctx->last_held == old) {
        ctx->last_held = NULL;
        cdvr_cpu_skip_cache_hold(ctx->cpu_skip, NULL);
    }
}

int cdvr_render_ctx_hold_volume(cdvr_render_ctx *ctx, const cdvr_volume *vol)
{
    if (!vol) {
        for (int i = 0; i < CDVR_RENDER_CTX_HOLDS; i++)
            release_at(ctx, i);
        return -1;
    }
    int at = cdvr_render_ctx_held_index(ctx, vol);
    if (at < 0) { /* in place of the hold used least recently (or none) */
        at = 0;
        for (int i = 1; i < CDVR_RENDER_CTX_HOLDS; i++)
            if (ctx->held_used[i] < ctx->held_used[at])
                at = i;
        release_at(ctx, at);
        ctx->held[at] = vol;
    }
    ctx->held_used[at] = ++ctx->tick;
    if (ctx->last_held != vol) {
        ctx->last_held = vol;
        cdvr_cpu_skip_cache_hold(ctx->cpu_skip, vol);
    }
    return at;
}

void cdvr_render_ctx_release_volume(cdvr_render_ctx *ctx, const cdvr_volume *vol)
{
    int at = cdvr_render_ctx_held_index(ctx, vol);
    if (at >= 0)
        release_at(ctx, at);
}

uint64_t cdvr_render_ctx_uploads(const cdvr_render_ctx *ctx)
{
    return ctx->uploads;
}

void cdvr_render_ctx_free(cdvr_render_ctx *ctx)
{
    if (!ctx)
        return;
    cdvr_brick_cache_free(ctx->cache);
    free(ctx->cache_path);
    for (int k = 0; k < CDVR_RENDER_CTX_STREAMS; k++) {
        slot_forget(&ctx->slots[k]);
#if CDVR_HAVE_OPENCL
        cdvr_cl_stream_free(ctx->slots[k].stream);
#endif
    }
#if CDVR_HAVE_OPENCL
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
    cdvr_cpu_skip_cache_hold(ctx->cpu_skip, ctx->last_held);
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

/* The slot used least recently (one never used first). */
static ctx_slot *least_recent(cdvr_render_ctx *ctx)
{
    ctx_slot *slot = &ctx->slots[0];
    for (int k = 1; k < CDVR_RENDER_CTX_STREAMS; k++)
        if (ctx->slots[k].used < slot->used)
            slot = &ctx->slots[k];
    return slot;
}

/* The slot with a stream of dims used most recently, or NULL. */
static ctx_slot *recent_of_dims(cdvr_render_ctx *ctx, const size_t dims[3])
{
    ctx_slot *slot = NULL;
    for (int k = 0; k < CDVR_RENDER_CTX_STREAMS; k++) {
        ctx_slot *c = &ctx->slots[k];
        if (c->stream && memcmp(c->dims, dims, sizeof c->dims) == 0 &&
            (!slot || c->used > slot->used))
            slot = c;
    }
    return slot;
}

/* Makes slot's stream one of dims (a new one, its frame unknown, when the dims differ), the
 * context's current one, and *out. */
static cdvr_status use_slot(cdvr_render_ctx *ctx, cdvr_cl *cl, ctx_slot *slot,
                            const size_t dims[3], cdvr_cl_stream **out, cdvr_error *err)
{
    if (!slot->stream || memcmp(slot->dims, dims, sizeof slot->dims) != 0) {
        cdvr_cl_stream_free(slot->stream);
        slot->stream = NULL;
        slot_forget(slot);
        cdvr_status s = cdvr_cl_stream_create(cl, dims, &slot->stream, err);
        if (s != CDVR_OK)
            return s;
        memcpy(slot->dims, dims, sizeof slot->dims);
    }
    slot->used = ++ctx->tick;
    ctx->current = slot;
    *out = slot->stream;
    return CDVR_OK;
}

cdvr_status cdvr_render_ctx_stream(cdvr_render_ctx *ctx, const size_t dims[3],
                                   cdvr_cl_stream **out, cdvr_error *err)
{
    cdvr_cl *cl;
    cdvr_status s = cdvr_render_ctx_cl(ctx, &cl, err);
    if (s != CDVR_OK)
        return s;
    ctx_slot *slot = recent_of_dims(ctx, dims);
    return use_slot(ctx, cl, slot ? slot : least_recent(ctx), dims, out, err);
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

/* 1 when slot's frame 0 is frame t of vol (voxels, bytes). The frame of a held volume is
 * known by its identity and revision (O(1), no host copy); any other volume may have been
 * edited in place (v:set) or freed and another allocated at its address, so its voxels are
 * compared with a host copy of what was uploaded (memcmp is exact and faster than hashing
 * the frame). */
static int slot_has_frame(const ctx_slot *slot, const cdvr_volume *vol, size_t t, int held,
                          const uint8_t *voxels, size_t bytes)
{
    if (!slot->stream || memcmp(slot->dims, vol->dims, sizeof slot->dims) != 0)
        return 0;
    if (held && cdvr_frame_stamp_same(slot->uploaded, cdvr_volume_stamp(vol, t)))
        return 1;
    return slot->frame_copy && slot->frame_bytes == bytes &&
           same_bytes(slot->frame_copy, voxels, bytes);
}

/* Where frame t of vol goes when no stream holds it: the stream of another frame of this
 * held volume, else for a held volume the one used least recently (two held volumes
 * rendered in turn keep a stream each), else the most recently used one of its dims (a
 * volume nobody holds, as the player's, keeps to one stream). */
static ctx_slot *upload_target(cdvr_render_ctx *ctx, const cdvr_volume *vol, int held)
{
    for (int k = 0; held && k < CDVR_RENDER_CTX_STREAMS; k++)
        if (ctx->slots[k].uploaded.vol == vol)
            return &ctx->slots[k];
    ctx_slot *slot = held ? NULL : recent_of_dims(ctx, vol->dims);
    return slot ? slot : least_recent(ctx);
}

cdvr_status cdvr_render_ctx_volume_stream(cdvr_render_ctx *ctx, const cdvr_volume *vol,
                                          size_t t, cdvr_cl_stream **out, cdvr_error *err)
{
    cdvr_cl *cl;
    cdvr_status st = cdvr_render_ctx_cl(ctx, &cl, err);
    if (st != CDVR_OK)
        return st;
    const uint8_t *voxels = cdvr_volume_frame(vol, t);
    size_t bytes = cdvr_volume_voxels(vol);
    int held = cdvr_render_ctx_held_index(ctx, vol) >= 0;
    for (int k = 0; k < CDVR_RENDER_CTX_STREAMS; k++) {
        ctx_slot *slot = &ctx->slots[k];
        if (!slot_has_frame(slot, vol, t, held, voxels, bytes))
            continue;
        if (held && slot->frame_copy) { /* known by identity from now on: no copy needed */
            slot_forget(slot);
            slot->uploaded = cdvr_volume_stamp(vol, t);
        }
        return use_slot(ctx, cl, slot, vol->dims, out, err);
    }
    ctx_slot *slot = upload_target(ctx, vol, held);
    st = use_slot(ctx, cl, slot, vol->dims, out, err);
    if (st != CDVR_OK)
        return st;
    slot_forget(slot);
    st = cdvr_cl_upload_frames(slot->stream, voxels, 1, err);
    if (st != CDVR_OK)
        return st;
    ctx->uploads++;
    if (held) {
        slot->uploaded = cdvr_volume_stamp(vol, t);
        return CDVR_OK;
    }
    slot->frame_copy = malloc(bytes ? bytes : 1);
    if (slot->frame_copy) { /* without a copy the next render uploads again */
        memcpy(slot->frame_copy, voxels, bytes);
        slot->frame_bytes = bytes;
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

cdvr_status cdvr_render_ctx_volume_stream(cdvr_render_ctx *ctx, const cdvr_volume *vol,
                                          size_t t, cdvr_cl_stream **out, cdvr_error *err)
{
    (void)ctx; (void)vol; (void)t;
    *out = NULL;
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
