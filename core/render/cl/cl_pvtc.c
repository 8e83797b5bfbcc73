/* core/render/cl/cl_pvtc.c - device streams: upload (b2), decode (b3) and download of u8 frames. */
#include <stdlib.h>
#include <string.h>

#include "cdvr/store.h"
#include "cl_internal.h"

static size_t ceil_div(size_t a, size_t b)
{
    return a / b + (a % b != 0);
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
    s->setup_frame = (size_t)-1;
    s->minmax_frame = (size_t)-1;
    size_t cap = 0, minmax_bytes = 2 * s->nbricks; /* nbricks < voxels: no overflow */
    cdvr_status st = cdvr_cl_ensure_buffer(cl, &s->table, &cap, 256 * 4 * sizeof(float),
                                           CL_MEM_READ_ONLY, "TF table", err);
    if (!st)
        st = cdvr_cl_ensure_buffer(cl, &s->alpha_unit, &cap, 256 * sizeof(float),
                                   CL_MEM_READ_ONLY, "alpha table", err);
    if (!st)
        st = cdvr_cl_ensure_buffer(cl, &s->brick_minmax, &cap, minmax_bytes, CL_MEM_READ_WRITE,
                                   "brick min/max grid", err);
    if (!st)
        st = cdvr_cl_ensure_buffer(cl, &s->brick_visible, &cap, s->nbricks, CL_MEM_READ_ONLY,
                                   "brick flags", err);
    if (!st) { /* host copies only once the device has accepted the sizes */
        s->minmax_host = malloc(minmax_bytes);
        s->flags_host = malloc(s->nbricks);
        if (!s->minmax_host || !s->flags_host)
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL stream: out of memory");
    }
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
    cl_mem *mems[] = {&s->payload, &s->frames, &s->table, &s->alpha_unit,
                      &s->brick_minmax, &s->brick_visible, &s->image, &s->samples};
    for (size_t i = 0; i < sizeof mems / sizeof *mems; i++)
        cdvr_cl_release(mems[i]);
    free(s->minmax_host);
    free(s->flags_host);
    free(s);
}

cdvr_status cdvr_cl_upload(cdvr_cl_stream *s, const void *payload, size_t bytes, cdvr_error *err)
{
    if (!payload || bytes == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL upload: empty payload");
    s->payload_bytes = 0;
    cdvr_status st = cdvr_cl_ensure_buffer(s->cl, &s->payload, &s->payload_capacity, bytes,
                                           CL_MEM_READ_ONLY, "chunk payload", err);
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
    return cdvr_cl_ensure_buffer(s->cl, &s->frames, &s->frame_capacity, bytes, CL_MEM_READ_WRITE,
                                 "decoded frames", err);
}

static cdvr_status decode_raw(cdvr_cl_stream *s, size_t count, cdvr_error *err)
{
    size_t bytes;
    if (!cdvr_size_mul(s->voxels, count, &bytes) || bytes != s->payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "OpenCL decode: raw chunk of %zu bytes is not %zu frames of %zux%zux%zu",
                              s->payload_bytes, count, s->dims[0], s->dims[1], s->dims[2]);
    cl_int code = clEnqueueCopyBuffer(s->cl->queue, s->payload, s->frames, 0, 0, bytes, 0, NULL, NULL);
    if (!code)
        code = clFinish(s->cl->queue);
    return cdvr_cl_check(code, "copy raw frames", err);
}

/* Geometry of a PVTC chunk (pvtc.h), computed here so the device module stands alone. */
static cdvr_status pvtc_blocks(const cdvr_cl_stream *s, const cdvr_pvtc_params *p, size_t count,
                               size_t blocks[3], cdvr_error *err)
{
    if (!p || (p->S != 1 && p->S != 4) || (p->T != 2 && p->T != 3) ||
        (p->pack != CDVR_PACK_TIME && p->pack != CDVR_PACK_SPACE))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: bad PVTC parameters S=%d T=%d pack=%d",
                              p ? p->S : 0, p ? p->T : 0, p ? (int)p->pack : -1);
    size_t max_frames = p->pack == CDVR_PACK_TIME ? (size_t)p->T : 1;
    if (count == 0 || count > max_frames)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: %zu frames requested, chunk holds %zu",
                              count, max_frames);
    size_t zdepth = (size_t)p->S * (p->pack == CDVR_PACK_SPACE ? (size_t)p->T : 1);
    blocks[0] = ceil_div(s->dims[0], 4);
    blocks[1] = ceil_div(s->dims[1], 4);
    blocks[2] = ceil_div(s->dims[2], zdepth);
    size_t nblocks = blocks[0] * blocks[1] * blocks[2], bytes;
    if (nblocks > 0xffffffffu || !cdvr_size_mul(nblocks, 4 + 4 * (size_t)p->S, &bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL decode: chunk too large");
    if (bytes != s->payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "OpenCL decode: PVTC S%dT%d chunk of %zux%zux%zu needs %zu bytes, got %zu",
                              p->S, p->T, s->dims[0], s->dims[1], s->dims[2], bytes, s->payload_bytes);
    return CDVR_OK;
}

static cdvr_status decode_pvtc(cdvr_cl_stream *s, const cdvr_pvtc_params *p, size_t count,
                               cdvr_error *err)
{
    size_t blocks[3] = {0, 0, 0};
    cdvr_status st = pvtc_blocks(s, p, count, blocks, err);
    if (st)
        return st;
    cl_kernel k = s->cl->k_decode;
    cl_uint dims[3] = {(cl_uint)s->dims[0], (cl_uint)s->dims[1], (cl_uint)s->dims[2]};
    cl_uint nb[3] = {(cl_uint)blocks[0], (cl_uint)blocks[1], (cl_uint)blocks[2]};
    cl_int S = p->S, T = p->T, space = p->pack == CDVR_PACK_SPACE;
    cl_uint nframes = (cl_uint)count;
    cl_int code = clSetKernelArg(k, 0, sizeof(cl_mem), &s->payload);
    code |= clSetKernelArg(k, 1, sizeof(cl_mem), &s->frames);
    for (cl_uint i = 0; i < 3; i++) {
        code |= clSetKernelArg(k, 2 + i, sizeof(cl_uint), &dims[i]);
        code |= clSetKernelArg(k, 5 + i, sizeof(cl_uint), &nb[i]);
    }
    code |= clSetKernelArg(k, 8, sizeof S, &S);
    code |= clSetKernelArg(k, 9, sizeof T, &T);
    code |= clSetKernelArg(k, 10, sizeof space, &space);
    code |= clSetKernelArg(k, 11, sizeof nframes, &nframes);
    if (code != CL_SUCCESS)
        return cdvr_cl_check(CL_INVALID_KERNEL_ARGS, "pvtc_decode arguments", err);
    size_t global = blocks[0] * blocks[1] * blocks[2];
    code = clEnqueueNDRangeKernel(s->cl->queue, k, 1, NULL, &global, NULL, 0, NULL, NULL);
    if (!code)
        code = clFinish(s->cl->queue);
    return cdvr_cl_check(code, "pvtc_decode kernel", err);
}

cdvr_status cdvr_cl_decode(cdvr_cl_stream *s, int codec, const cdvr_pvtc_params *p, size_t count,
                           cdvr_error *err)
{
    s->frames_valid = 0;
    s->setup_frame = (size_t)-1;
    s->minmax_frame = (size_t)-1;
    if (!s->payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: no chunk uploaded");
    if (codec != CDVR_CODEC_RAW && codec != CDVR_CODEC_PVTC)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED,
                              "OpenCL decode: codec %d has no device decoder", codec);
    if (count == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL decode: zero frames requested");
    cdvr_status st = ensure_frames(s, count, err);
    if (st)
        return st;
    st = codec == CDVR_CODEC_RAW ? decode_raw(s, count, err) : decode_pvtc(s, p, count, err);
    if (!st)
        s->frames_valid = count;
    return st;
}

cdvr_status cdvr_cl_download(cdvr_cl_stream *s, size_t frame, uint8_t *out, cdvr_error *err)
{
    if (frame >= s->frames_valid)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL download: frame %zu not decoded (%zu frames)",
                              frame, s->frames_valid);
    cl_int code = clEnqueueReadBuffer(s->cl->queue, s->frames, CL_TRUE, frame * s->voxels,
                                      s->voxels, out, 0, NULL, NULL);
    return cdvr_cl_check(code, "download frame", err);
}
