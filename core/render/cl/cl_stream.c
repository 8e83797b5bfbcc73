/* core/render/cl/cl_stream.c - device streams: upload (b2), decode (b3) through the codec table
 * (cdvr/codec.h) and download of u8 frames. */
#include <stdio.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/timing.h"
#include "cl_internal.h"

size_t cdvr_cl_brick_edge(void)
{
    return CDVR_CL_BRICK;
}

static size_t ceil_div(size_t a, size_t b)
{
    return a / b + (a % b != 0);
}

static cdvr_cl_decode_path decode_path_from_env(void)
{
    const char *e = getenv("CDVR_CL_DECODE");
    if (e && strcmp(e, "kernel") == 0)
        return CDVR_CL_DECODE_KERNEL;
    if (e && strcmp(e, "host") == 0)
        return CDVR_CL_DECODE_HOST;
    return CDVR_CL_DECODE_AUTO;
}

static cdvr_cl_fetch_path fetch_path_from_env(void)
{
    const char *e = getenv("CDVR_CL_FETCH");
    if (e && strcmp(e, "sample") == 0)
        return CDVR_CL_FETCH_SAMPLE;
    if (e && strcmp(e, "bulk") == 0)
        return CDVR_CL_FETCH_BULK;
    return CDVR_CL_FETCH_AUTO;
}

/* Buffers the host may map: in host memory on CPU devices (maps then cost no copy). */
static cl_mem_flags host_visible(const cdvr_cl *cl, cl_mem_flags flags)
{
    return cl->info.is_gpu ? flags : flags | CL_MEM_ALLOC_HOST_PTR;
}

cdvr_status cdvr_cl_stream_create(cdvr_cl *cl, const size_t dims[3], cdvr_cl_stream **out,
                                  cdvr_error *err)
{
    *out = NULL;
    size_t voxels = 1;
    for (int i = 0; i < 3; i++) {
        if (dims[i] == 0 || dims[i] > 0x7fffffff)
            return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL stream: dims %zux%zux%zu out of range",
                                  dims[0], dims[1], dims[2]);
        if (!cdvr_size_mul(voxels, dims[i], &voxels))
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL stream: dims %zux%zux%zu overflow",
                                  dims[0], dims[1], dims[2]);
    }
    cdvr_cl_stream *s = calloc(1, sizeof *s);
    if (!s)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL stream: out of memory");
    s->cl = cl;
    s->voxels = voxels;
    s->nbricks = 1;
    for (int i = 0; i < 3; i++) {
        s->dims[i] = dims[i];
        s->brick_dims[i] = ceil_div(dims[i], CDVR_CL_BRICK);
        s->nbricks *= s->brick_dims[i];
    }
    s->skipping = 1;
    s->decode_path = decode_path_from_env();
    s->setup_frame = (size_t)-1;
    s->minmax_frame = (size_t)-1;
    s->tiles_frame = s->grads_frame = s->quads_frame = s->last_rendered = (size_t)-1;
    s->nblocks = 1;
    for (int i = 0; i < 3; i++) {
        s->block_dims[i] = ceil_div(s->brick_dims[i], (size_t)1 << CDVR_CL_BLOCK_SHIFT);
        s->nblocks *= s->block_dims[i];
    }
    /* nbricks < voxels: no overflow */
    size_t cap = 0, minmax_bytes = 2 * (s->nbricks + s->nblocks);
    cdvr_status st = cdvr_cl_ensure_buffer(cl, &s->table, &cap, 256 * sizeof(cl_ulong),
                                           CL_MEM_READ_ONLY, "TF table", err);
    if (!st)
        st = cdvr_cl_ensure_buffer(cl, &s->tf_rows, &cap, 256 * 4 * sizeof(float),
                                   CL_MEM_READ_ONLY, "TF rows", err);
    if (!st) /* zeros: dense frames read no parameters, but the argument must be a buffer */
        st = cdvr_cl_ensure_buffer(cl, &s->params, &cap, CDVR_CL_PARAMS_BUFFER_BYTES,
                                   CL_MEM_READ_ONLY, "codec parameters", err);
    if (!st) {
        static const unsigned char zeros[CDVR_CL_PARAMS_BUFFER_BYTES];
        st = cdvr_cl_check(clEnqueueWriteBuffer(cl->queue, s->params, CL_TRUE, 0, sizeof zeros,
                                                zeros, 0, NULL, NULL),
                           "clear codec parameters", err);
    }
    if (!st)
        st = cdvr_cl_ensure_buffer(cl, &s->brick_minmax, &cap, minmax_bytes, CL_MEM_READ_WRITE,
                                   "brick min/max grid", err);
    if (!st)
        st = cdvr_cl_ensure_buffer(cl, &s->brick_visible, &cap, s->nbricks + CDVR_CL_FLAGS_PAD,
                                   CL_MEM_READ_ONLY, "brick flags", err);
    if (!st) /* host copies only once the device has accepted the sizes */
        st = cdvr_skip_grid_init(&s->grid, dims, CDVR_CL_BRICK_SHIFT, err);
    if (st) {
        cdvr_cl_stream_free(s);
        return st;
    }
    *out = s;
    return CDVR_OK;
}

void cdvr_cl_stream_free(cdvr_cl_stream *s)
{
    if (!s)
        return;
    cl_mem *mems[] = {&s->payload, &s->params, &s->frames, &s->host_frames, &s->tiles, &s->grads,
                      &s->quads, &s->table, &s->tf_rows,
                      &s->brick_minmax, &s->brick_visible, &s->iso_flags, &s->zero_flags, &s->image,
                      &s->samples, &s->entry_tiles};
    for (size_t i = 0; i < sizeof mems / sizeof *mems; i++)
        cdvr_cl_release(mems[i]);
    cdvr_skip_grid_free(&s->grid);
    cdvr_skip_entry_free(&s->entry);
    cdvr_skip_entry_free(&s->iso_entry);
    cdvr_skip_entry_free(&s->zero_entry);
    free(s);
}

static void invalidate_frames(cdvr_cl_stream *s)
{
    cdvr_cl_release(&s->host_frames);
    if (s->only_tiles) { /* the caller's memory: never a buffer to reuse */
        cdvr_cl_release(&s->tiles);
        s->tiles_capacity = 0;
        s->only_tiles = 0;
    }
    s->frames_valid = 0;
    s->fetch = NULL;
    s->setup_frame = (size_t)-1;
    s->minmax_frame = (size_t)-1;
    s->minmax_valid = s->blocks_valid = 0;
    s->pending_minmax = NULL;
    s->tiles_frame = s->grads_frame = s->quads_frame = s->last_rendered = (size_t)-1;
}

cdvr_status cdvr_cl_upload(cdvr_cl_stream *s, const void *payload, size_t bytes, cdvr_error *err)
{
    if (!payload || bytes == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL upload: empty payload");
    if (s->fetch) /* the frames were the old payload */
        invalidate_frames(s);
    s->payload_bytes = 0;
    cdvr_status st = cdvr_cl_ensure_buffer(s->cl, &s->payload, &s->payload_capacity, bytes,
                                           host_visible(s->cl, CL_MEM_READ_ONLY),
                                           "chunk payload", err);
    if (st)
        return st;
    cl_int code = clEnqueueWriteBuffer(s->cl->queue, s->payload, CL_TRUE, 0, bytes, payload, 0,
                                       NULL, NULL);
    if (cdvr_cl_check(code, "upload chunk payload", err))
        return CDVR_ERR_DEVICE;
    s->payload_bytes = bytes;
    return CDVR_OK;
}

static cdvr_status ensure_frames(cdvr_cl_stream *s, size_t count, cdvr_error *err)
{
    size_t bytes;
    if (!cdvr_size_mul(s->voxels, count, &bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL decode: %zu frames of %zu voxels overflow",
                              count, s->voxels);
    if (s->frames && s->frame_capacity >= bytes)
        return CDVR_OK;
    return cdvr_cl_ensure_buffer(s->cl, &s->frames, &s->frame_capacity, bytes,
                                 host_visible(s->cl, CL_MEM_READ_WRITE), "decoded frames", err);
}

/* Runs the codec's decode kernel over the uploaded payload into frames 0 .. count-1. */
static cdvr_status run_decode_kernel(cdvr_cl_stream *s, const cdvr_cl_codec_program *cp,
                                     const cdvr_codec_params *params, size_t count,
                                     cdvr_error *err)
{
    cl_kernel k = cp->k_decode;
    const char *name = cp->codec->cl_function;
    size_t global = cp->codec->cl_work_items(params, s->dims);
    if (global == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: codec %s gives no work-items",
                              cp->codec->name);
    cl_ulong bytes = s->payload_bytes;
    cl_uint dims[3] = {(cl_uint)s->dims[0], (cl_uint)s->dims[1], (cl_uint)s->dims[2]};
    cl_uint nframes = (cl_uint)count;
    cdvr_status st = cdvr_cl_arg(k, name, 0, sizeof(cl_mem), &s->payload, err);
    if (!st)
        st = cdvr_cl_arg(k, name, 1, sizeof bytes, &bytes, err);
    if (!st)
        st = cdvr_cl_arg(k, name, 2, sizeof(cl_mem), &s->params, err);
    for (cl_uint i = 0; !st && i < 3; i++)
        st = cdvr_cl_arg(k, name, 3 + i, sizeof(cl_uint), &dims[i], err);
    if (!st)
        st = cdvr_cl_arg(k, name, 6, sizeof nframes, &nframes, err);
    if (!st)
        st = cdvr_cl_arg(k, name, 7, sizeof(cl_mem), &s->frames, err);
    if (st)
        return st;
    cl_int code = clEnqueueNDRangeKernel(s->cl->queue, k, 1, NULL, &global, NULL, 0, NULL, NULL);
    if (!code)
        code = clFinish(s->cl->queue);
    char what[96];
    snprintf(what, sizeof what, "%s kernel", name);
    return cdvr_cl_check(code, what, err);
}

/* The codec's C decoder from the mapped payload into the mapped frames 0 .. count-1. */
static cdvr_status run_host_decode(cdvr_cl_stream *s, const cdvr_codec *codec,
                                   const cdvr_codec_params *params, size_t count,
                                   cdvr_error *err)
{
    cl_command_queue q = s->cl->queue;
    cl_int code;
    size_t bytes = s->voxels * count;
    if (count > 64)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "OpenCL decode on the host: %zu frames "
                              "per chunk (at most 64)", count);
    void *in = clEnqueueMapBuffer(q, s->payload, CL_TRUE, CL_MAP_READ, 0, s->payload_bytes, 0,
                                  NULL, NULL, &code);
    if (code != CL_SUCCESS)
        return cdvr_cl_check(code, "map chunk payload", err);
    void *out = clEnqueueMapBuffer(q, s->frames, CL_TRUE, CL_MAP_WRITE_INVALIDATE_REGION, 0,
                                   bytes, 0, NULL, NULL, &code);
    cdvr_status st = cdvr_cl_check(code, "map decoded frames", err);
    if (!st) {
        uint8_t *frames[64];
        for (size_t f = 0; f < count; f++)
            frames[f] = (uint8_t *)out + f * s->voxels;
        cdvr_error derr;
        if (codec->decode(params, s->dims, in, s->payload_bytes, frames, count, &derr))
            st = cdvr_error_set(err, derr.status, "OpenCL decode on the host: %s", derr.msg);
        cl_int c2 = clEnqueueUnmapMemObject(q, s->frames, out, 0, NULL, NULL);
        if (!st)
            st = cdvr_cl_check(c2, "unmap decoded frames", err);
    }
    cl_int c1 = clEnqueueUnmapMemObject(q, s->payload, in, 0, NULL, NULL);
    cl_int c3 = clFinish(q);
    if (!st)
        st = cdvr_cl_check(c1 ? c1 : c3, "unmap chunk payload", err);
    return st;
}

/* Runs one path and returns its wall time in ms (negative on failure, err set). */
/* floor(log4(decoded bytes of count frames)), capped: the size class of remembered paths. */
static unsigned size_class(const cdvr_cl_stream *s, size_t count)
{
    unsigned cls = 0;
    for (size_t bytes = s->voxels * count; bytes >= 4 && cls + 1 < CDVR_CL_SIZE_CLASSES;
         bytes /= 4)
        cls++;
    return cls;
}

static double timed_decode(cdvr_cl_stream *s, const cdvr_cl_codec_program *cp,
                           cdvr_cl_decode_path path, const cdvr_codec_params *params,
                           size_t count, cdvr_error *err)
{
    double t0 = cdvr_now_ms();
    cdvr_status st = path == CDVR_CL_DECODE_HOST
                         ? run_host_decode(s, cp->codec, params, count, err)
                         : run_decode_kernel(s, cp, params, count, err);
    return st ? -1 : cdvr_now_ms() - t0;
}

/* Which path to take: the one asked for, the kernel off CPU devices, else the faster one for
 * chunks of this size class (decoded bytes, in powers of 4), remembered or measured here on
 * this chunk the first time (the kernel once to warm up, then each path twice, the better of
 * two runs; the frames hold the last run's output). *done is set when the measurement left
 * the frames decoded. */
static cdvr_status choose_path(cdvr_cl_stream *s, cdvr_cl_codec_program *cp,
                               const cdvr_codec_params *params, size_t count,
                               cdvr_cl_decode_path *path, int *done, cdvr_error *err)
{
    *done = 0;
    *path = s->decode_path;
    if (*path != CDVR_CL_DECODE_AUTO)
        return CDVR_OK;
    if (s->cl->info.is_gpu || count > 64) {
        *path = CDVR_CL_DECODE_KERNEL;
        return CDVR_OK;
    }
    unsigned cls = size_class(s, count);
    if (cp->fastest[cls] == CDVR_CL_DECODE_AUTO)
        cp->fastest[cls] = cdvr_cl_load_decode_choice(s->cl, cp->codec, cls, &cp->kernel_ms[cls],
                                                      &cp->host_ms[cls]);
    if (cp->fastest[cls] == CDVR_CL_DECODE_AUTO) {
        double kernel = 1e300, host = 1e300;
        if (timed_decode(s, cp, CDVR_CL_DECODE_KERNEL, params, count, err) < 0)
            return CDVR_ERR_DEVICE;
        for (int rep = 0; rep < 2; rep++) {
            double k = timed_decode(s, cp, CDVR_CL_DECODE_KERNEL, params, count, err);
            double h = timed_decode(s, cp, CDVR_CL_DECODE_HOST, params, count, err);
            if (k < 0 || h < 0)
                return err && err->status ? err->status : CDVR_ERR_DEVICE;
            kernel = k < kernel ? k : kernel;
            host = h < host ? h : host;
        }
        cp->kernel_ms[cls] = kernel;
        cp->host_ms[cls] = host;
        cp->fastest[cls] = host < kernel ? CDVR_CL_DECODE_HOST : CDVR_CL_DECODE_KERNEL;
        cdvr_cl_store_decode_choice(s->cl, cp->codec, cls, cp->fastest[cls], kernel, host);
        *done = 1;
    }
    *path = cp->fastest[cls];
    return CDVR_OK;
}

void cdvr_cl_set_decode_path(cdvr_cl_stream *s, cdvr_cl_decode_path path)
{
    s->decode_path = path;
}

cdvr_cl_decode_path cdvr_cl_last_decode_path(const cdvr_cl_stream *s)
{
    return s->last_decode_path;
}

void cdvr_cl_set_fetch_path(cdvr_cl_stream *s, cdvr_cl_fetch_path path)
{
    s->fetch_path = path;
}

/* The path set on the stream or by the environment; AUTO when neither says. */
static cdvr_cl_fetch_path fetch_path_asked(const cdvr_cl_stream *s)
{
    return s->fetch_path != CDVR_CL_FETCH_AUTO ? s->fetch_path : fetch_path_from_env();
}

cdvr_cl_fetch_path cdvr_cl_fetch_path_of(const cdvr_cl_stream *s)
{
    cdvr_cl_fetch_path asked = fetch_path_asked(s);
    if (asked != CDVR_CL_FETCH_AUTO)
        return asked;
    return s->cl->info.is_gpu ? CDVR_CL_FETCH_SAMPLE : CDVR_CL_FETCH_BULK;
}

/* The device's entry for codec and size class: found, loaded from disk, or NULL when the
 * table is full. */
static cdvr_cl_fetch_choice *fetch_choice(cdvr_cl *cl, const cdvr_codec *codec, unsigned cls)
{
    for (size_t i = 0; i < cl->nfetch_choices; i++)
        if (cl->fetch_choices[i].codec == codec && cl->fetch_choices[i].size_class == cls)
            return &cl->fetch_choices[i];
    if (cl->nfetch_choices == CDVR_CL_MAX_FETCH_CHOICES)
        return NULL;
    cdvr_cl_fetch_choice *c = &cl->fetch_choices[cl->nfetch_choices++];
    *c = (cdvr_cl_fetch_choice){codec, cls, CDVR_CL_FETCH_AUTO, 0, 0};
    c->path = cdvr_cl_load_fetch_choice(cl, codec, cls, &c->sample_ms, &c->bulk_ms);
    return c;
}

cdvr_cl_fetch_path cdvr_cl_fetch_path_for(cdvr_cl_stream *s, const cdvr_codec *codec,
                                          size_t count)
{
    cdvr_cl_fetch_path asked = fetch_path_asked(s);
    if (asked != CDVR_CL_FETCH_AUTO)
        return asked;
    if (s->cl->info.is_gpu)
        return CDVR_CL_FETCH_SAMPLE;
    cdvr_cl_fetch_choice *c = fetch_choice(s->cl, codec, size_class(s, count));
    return c ? c->path : CDVR_CL_FETCH_BULK;
}

void cdvr_cl_remember_fetch_path(cdvr_cl_stream *s, const cdvr_codec *codec, size_t count,
                                 double sample_ms, double bulk_ms)
{
    unsigned cls = size_class(s, count);
    cdvr_cl_fetch_choice *c = fetch_choice(s->cl, codec, cls);
    cdvr_cl_fetch_path faster = sample_ms < bulk_ms ? CDVR_CL_FETCH_SAMPLE : CDVR_CL_FETCH_BULK;
    if (c)
        *c = (cdvr_cl_fetch_choice){codec, cls, faster, sample_ms, bulk_ms};
    cdvr_cl_store_fetch_choice(s->cl, codec, cls, faster, sample_ms, bulk_ms);
}

/* The codec's check hook (cdvr/codec.h) on the uploaded payload, read through a map (no copy
 * on CPU devices, whose payload buffer lives in host memory): a chunk it refuses never
 * reaches a kernel. */
static cdvr_status check_payload(cdvr_cl_stream *s, const cdvr_codec *codec,
                                 const cdvr_codec_params *params, cdvr_error *err)
{
    if (!codec->check)
        return CDVR_OK;
    cl_int code;
    cl_command_queue q = s->cl->queue;
    void *in = clEnqueueMapBuffer(q, s->payload, CL_TRUE, CL_MAP_READ, 0, s->payload_bytes, 0,
                                  NULL, NULL, &code);
    if (code != CL_SUCCESS)
        return cdvr_cl_check(code, "map chunk payload for its check", err);
    cdvr_error cerr;
    cdvr_status st = codec->check(params, s->dims, in, s->payload_bytes, &cerr);
    if (st)
        cdvr_error_set(err, st, "OpenCL decode: codec %s refuses the %zu-byte chunk of "
                       "%zux%zux%zu before the device: %s", codec->name, s->payload_bytes,
                       s->dims[0], s->dims[1], s->dims[2], cerr.msg);
    code = clEnqueueUnmapMemObject(q, s->payload, in, 0, NULL, NULL);
    if (code == CL_SUCCESS)
        code = clFinish(q);
    if (!st)
        st = cdvr_cl_check(code, "unmap chunk payload", err);
    return st;
}

/* The BULK path of a fetch-mode codec: its C decoder (safe on any payload, so no check hook
 * is needed before it) into the dense frames, which the dense kernels then render. */
static cdvr_status decode_fetch_bulk(cdvr_cl_stream *s, const cdvr_codec *codec,
                                     const cdvr_codec_params *params, size_t count,
                                     cdvr_error *err)
{
    cdvr_error inner;
    cdvr_status st = ensure_frames(s, count, &inner);
    if (!st)
        st = run_host_decode(s, codec, params, count, &inner);
    if (st)
        return cdvr_error_set(err, st, "codec %s (bulk decode for the %zux%zux%zu frames): %s",
                              codec->name, s->dims[0], s->dims[1], s->dims[2], inner.msg);
    s->frames_valid = count;
    return CDVR_OK;
}

cdvr_status cdvr_cl_decode(cdvr_cl_stream *s, const cdvr_codec *codec,
                           const cdvr_codec_params *params, size_t count, cdvr_error *err)
{
    invalidate_frames(s);
    if (!codec || !params)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: no codec or parameters");
    if (!s->payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: no chunk uploaded");
    cdvr_codec_shape shape;
    cdvr_status st = cdvr_codec_shape_of(codec, params, s->dims, &shape, err);
    if (st)
        return st;
    if (count == 0 || count > shape.timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: %zu frames requested, a %s "
                              "chunk holds %zu", count, codec->name, shape.timesteps);
    if (shape.payload_bytes ? s->payload_bytes != shape.payload_bytes
                            : s->payload_bytes > shape.bound_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: %s chunk of %zux%zux%zu needs "
                              "%zu bytes, got %zu", codec->name, s->dims[0], s->dims[1],
                              s->dims[2], shape.payload_bytes, s->payload_bytes);
    if (codec->cl_mode == CDVR_CODEC_CL_FETCH &&
        cdvr_cl_fetch_path_for(s, codec, count) != CDVR_CL_FETCH_SAMPLE)
        return decode_fetch_bulk(s, codec, params, count, err);
    st = check_payload(s, codec, params, err);
    if (st)
        return st;
    cdvr_cl_codec_program *cp;
    st = cdvr_cl_get_codec_program(s->cl, codec, &cp, err);
    unsigned char pbuf[CDVR_CL_PARAMS_BUFFER_BYTES];
    memcpy(pbuf, params->bytes, CDVR_CL_PARAMS_BYTES);
    for (int i = 0; i < 8; i++) /* the payload's size, which fetch functions clamp below */
        pbuf[CDVR_CL_PARAMS_BYTES + i] = (unsigned char)((uint64_t)s->payload_bytes >> (8 * i));
    if (!st)
        st = cdvr_cl_check(clEnqueueWriteBuffer(s->cl->queue, s->params, CL_TRUE, 0, sizeof pbuf,
                                                pbuf, 0, NULL, NULL),
                           "upload codec parameters", err);
    if (!st && codec->cl_mode == CDVR_CODEC_CL_DECODE) {
        cdvr_cl_decode_path path = CDVR_CL_DECODE_KERNEL;
        int done = 0;
        st = ensure_frames(s, count, err);
        if (!st)
            st = choose_path(s, cp, params, count, &path, &done, err);
        if (!st && !done)
            st = path == CDVR_CL_DECODE_HOST ? run_host_decode(s, codec, params, count, err)
                                             : run_decode_kernel(s, cp, params, count, err);
        if (!st)
            s->last_decode_path = path;
    }
    if (st)
        return st;
    s->fetch = codec->cl_mode == CDVR_CODEC_CL_FETCH ? cp : NULL;
    s->frames_valid = count;
    return CDVR_OK;
}

cdvr_status cdvr_cl_upload_frames(cdvr_cl_stream *s, const uint8_t *frames, size_t count,
                                  cdvr_error *err)
{
    invalidate_frames(s);
    size_t bytes;
    if (!frames || count == 0 || !cdvr_size_mul(s->voxels, count, &bytes))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL upload: %zu frames", count);
    cdvr_status st = ensure_frames(s, count, err);
    if (!st)
        st = cdvr_cl_check(clEnqueueWriteBuffer(s->cl->queue, s->frames, CL_TRUE, 0, bytes,
                                                frames, 0, NULL, NULL),
                           "upload frames", err);
    if (!st)
        s->frames_valid = count;
    return st;
}

cdvr_status cdvr_cl_use_host_frames(cdvr_cl_stream *s, const uint8_t *frames, size_t count,
                                    cdvr_error *err)
{
    invalidate_frames(s);
    size_t bytes;
    if (!frames || count == 0 || !cdvr_size_mul(s->voxels, count, &bytes))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL frames in host memory: %zu frames", count);
    if (bytes > s->cl->info.max_alloc_bytes)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL: %zu bytes of frames exceed the "
                              "device's largest buffer on %s", bytes, s->cl->info.device);
    cl_int code;
    s->host_frames = clCreateBuffer(s->cl->context, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR, bytes,
                                    (void *)frames, &code);
    if (code != CL_SUCCESS) {
        s->host_frames = NULL;
        return cdvr_cl_check(code, "frames in host memory", err);
    }
    s->frames_valid = count;
    return CDVR_OK;
}

int cdvr_cl_tiles_fit(const cdvr_cl_stream *s)
{
    size_t bytes = cdvr_tiled_bytes(s->dims);
    return bytes && bytes <= INT_MAX && bytes <= s->cl->info.max_alloc_bytes &&
           !cdvr_cl_env_is("CDVR_CL_LONG_INDEX", "1");
}

int cdvr_cl_takes_host_tiles(const cdvr_cl_stream *s, int gradients)
{
    return cdvr_cl_tiles_fit(s) && (!s->cl->info.dense_frames || gradients);
}

cdvr_status cdvr_cl_use_host_tiles(cdvr_cl_stream *s, const uint8_t *tiles, cdvr_error *err)
{
    invalidate_frames(s);
    if (!tiles || !cdvr_cl_tiles_fit(s))
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "OpenCL: a tiled frame of %zux%zux%zu "
                              "is not taken here (cdvr_cl_takes_host_tiles)", s->dims[0],
                              s->dims[1], s->dims[2]);
    cl_int code;
    cl_mem mem = clCreateBuffer(s->cl->context, CL_MEM_READ_ONLY | CL_MEM_USE_HOST_PTR,
                                cdvr_tiled_bytes(s->dims), (void *)tiles, &code);
    if (code != CL_SUCCESS)
        return cdvr_cl_check(code, "tiled frame in host memory", err);
    cdvr_cl_release(&s->tiles);
    s->tiles = mem;
    s->tiles_capacity = 0;
    s->only_tiles = 1;
    s->tiles_frame = 0;
    s->frames_valid = 1;
    return CDVR_OK;
}

uint64_t cdvr_cl_stream_bytes(const cdvr_cl_stream *s)
{
    uint64_t b = (uint64_t)s->payload_capacity + s->frame_capacity + CDVR_CL_PARAMS_BUFFER_BYTES;
    b += s->tiles_capacity + s->grads_capacity + s->quads_capacity;
    b += 256 * sizeof(cl_ulong) + 256 * 4 * sizeof(float); /* TF tables */
    b += 3 * (uint64_t)s->nbricks + 2 * (uint64_t)s->nblocks; /* ranges + flags */
    b += (uint64_t)s->image_pixels * 4 * sizeof(float) + s->sample_slots * sizeof(cl_uint);
    return b;
}

uint64_t cdvr_cl_volume_bytes(const cdvr_cl_stream *s)
{
    if (s->fetch)
        return (uint64_t)s->payload_bytes + CDVR_CL_PARAMS_BYTES;
    return (uint64_t)s->frames_valid * s->voxels;
}

cdvr_status cdvr_cl_download(cdvr_cl_stream *s, size_t frame, uint8_t *out, cdvr_error *err)
{
    if (s->fetch)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "OpenCL download: frames of codec %s "
                              "stay compressed on the device (decode on the CPU instead)",
                              s->fetch->codec->name);
    if (frame >= s->frames_valid || s->only_tiles)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL download: frame %zu not decoded (%zu "
                              "frames%s)", frame, s->frames_valid,
                              s->only_tiles ? ", only a tiled copy" : "");
    cl_int code = clEnqueueReadBuffer(s->cl->queue, cdvr_cl_frames_mem(s), CL_TRUE,
                                      frame * s->voxels, s->voxels, out, 0, NULL, NULL);
    return cdvr_cl_check(code, "download frame", err);
}
