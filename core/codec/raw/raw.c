/* core/codec/raw/raw.c - the "raw" codec: one u8 frame per chunk, stored as it is. It takes no
 * parameters (the blob is all zero). */
#include "cdvr/codec.h"

#include <stdio.h>
#include <string.h>

static const cdvr_codec_param_doc raw_params[] = {{NULL, NULL, NULL}};

static void raw_default(cdvr_codec_params *p)
{
    memset(p, 0, sizeof *p);
}

static cdvr_status raw_set(cdvr_codec_params *p, const char *key, const char *value,
                           cdvr_error *err)
{
    (void)p;
    (void)value;
    return cdvr_error_set(err, CDVR_ERR_ARG, "codec raw: unknown parameter '%s' (raw takes "
                          "none)", key);
}

static int raw_get(const cdvr_codec_params *p, const char *key, char *out, size_t n)
{
    (void)p;
    (void)key;
    (void)out;
    (void)n;
    return -1;
}

static cdvr_status raw_check(const cdvr_codec_params *p, cdvr_error *err)
{
    for (size_t i = 0; i < CDVR_CODEC_PARAMS_MAX; i++)
        if (p->bytes[i])
            return cdvr_error_set(err, CDVR_ERR_ARG, "codec raw: parameter byte %zu is %u (raw "
                                  "parameters are all zero)", i, p->bytes[i]);
    return CDVR_OK;
}

static void raw_name(const cdvr_codec_params *p, char *name, size_t n)
{
    (void)p;
    snprintf(name, n, "raw");
}

static cdvr_status raw_shape(const cdvr_codec_params *p, const size_t dims[3],
                             cdvr_codec_shape *out, cdvr_error *err)
{
    (void)p;
    size_t bytes;
    if (!cdvr_size_mul(dims[0], dims[1], &bytes) || !cdvr_size_mul(bytes, dims[2], &bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "dims %zux%zux%zu overflow size_t", dims[0],
                              dims[1], dims[2]);
    out->timesteps = 1;
    out->payload_bytes = out->bound_bytes = bytes;
    return CDVR_OK;
}

static cdvr_status raw_encode(const cdvr_codec_params *p, const size_t dims[3],
                              const uint8_t *const *frames, size_t count, uint8_t *out,
                              size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    cdvr_codec_shape shape = {0};
    cdvr_status s = raw_shape(p, dims, &shape, err);
    if (s != CDVR_OK)
        return s;
    if (count != 1 || out_cap < shape.payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec raw: %zu frames into %zu bytes (1 frame "
                              "of %zu bytes expected)", count, out_cap, shape.payload_bytes);
    memcpy(out, frames[0], shape.payload_bytes);
    *out_bytes = shape.payload_bytes;
    return CDVR_OK;
}

static cdvr_status raw_decode(const cdvr_codec_params *p, const size_t dims[3],
                              const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                              size_t count, cdvr_error *err)
{
    cdvr_codec_shape shape = {0};
    cdvr_status s = raw_shape(p, dims, &shape, err);
    if (s != CDVR_OK)
        return s;
    if (count != 1 || in_bytes != shape.payload_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "raw chunk of %zu bytes, %zu frames: "
                              "expected %zu bytes, 1 frame", in_bytes, count,
                              shape.payload_bytes);
    memcpy(frames[0], in, in_bytes);
    return CDVR_OK;
}

/* On the device a raw chunk is its own decoded frame: the ray caster reads the payload as
 * the dense volume, so the decode "kernel" is a copy (codec/raw_decode.cl). */
static size_t raw_work_items(const cdvr_codec_params *p, const size_t dims[3])
{
    (void)p;
    return (dims[0] * dims[1] * dims[2] + 15) / 16;
}

const cdvr_codec cdvr_codec_raw = {
    .name = "raw",
    .id = CDVR_CODEC_ID_RAW,
    .description = "uncompressed u8 voxels, one timestep per chunk",
    .params = raw_params,
    .params_default = raw_default,
    .params_set = raw_set,
    .params_get = raw_get,
    .params_check = raw_check,
    .variant_name = raw_name,
    .shape = raw_shape,
    .encode = raw_encode,
    .decode = raw_decode,
    .cl_mode = CDVR_CODEC_CL_DECODE,
    .cl_file = "codec/raw_decode.cl",
    .cl_function = "raw_decode",
    .cl_work_items = raw_work_items,
};
