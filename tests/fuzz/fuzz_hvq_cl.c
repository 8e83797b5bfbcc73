/* tests/fuzz/fuzz_hvq_cl.c - libFuzzer target for the OpenCL path of the hvq codec: upload and
 * cdvr_cl_decode (core/render/cl/cl_stream.c, which runs the codec's check hook), then the
 * brick min/max and ray-cast kernels reading the payload through hvq_fetch
 * (kernels/codec/hvq_fetch.cl, kernels/render/bricks.cl, raycast.cl), on the CPU OpenCL
 * device (PoCL) or any other. How to run: README.
 *
 * Input: as fuzz_hvq.c (4 header bytes giving dims and parameters, then the payload).
 * Differential checks (FUZZ_ASSERT):
 *  - the device and the CPU decoder agree: both refuse the payload (the device with
 *    CDVR_ERR_CORRUPT and a message naming hvq) or both accept it, and then the device's
 *    fetch-mode image is exactly its image of the CPU-decoded frame uploaded dense;
 *  - the same payload, unchecked (a copy of the hvq table without the check hook), renders
 *    without crashing, and to the same image whether the device buffer holds 0x00 or 0xff
 *    past the payload's end: the fetch never reads outside the payload, whatever it holds
 *    (for a payload the CPU accepts, that image is the checked one).
 * Without an OpenCL device every input is ignored (fuzz_hvq_cl_device() says so). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/camera.h"
#include "cdvr/codec.h"
#include "cdvr/device.h"
#include "cdvr/image.h"
#include "cdvr/render.h"
#include "cdvr/tf.h"
#include "fuzz_common.h"

#if CDVR_HAVE_OPENCL

/* The fuzzing context: the device, opened once, and the unchecked copy of the hvq table. */
static struct {
    int tried;
    cdvr_cl *cl;
    cdvr_codec unchecked;
    cdvr_tf tf;
} hvq_cl_ctx;

/* The device, or NULL when there is none. */
static cdvr_cl *fuzz_hvq_cl_device(void)
{
    if (hvq_cl_ctx.tried)
        return hvq_cl_ctx.cl;
    hvq_cl_ctx.tried = 1;
    cdvr_error err;
    if (cdvr_cl_open(&hvq_cl_ctx.cl, &err) != CDVR_OK) {
        hvq_cl_ctx.cl = NULL;
        return NULL;
    }
    hvq_cl_ctx.unchecked = *cdvr_codec_find("hvq");
    hvq_cl_ctx.unchecked.name = "hvq_unchecked";
    hvq_cl_ctx.unchecked.id = 0x68767155u; /* "Uqvh" */
    hvq_cl_ctx.unchecked.check = NULL;
    FUZZ_ASSERT(cdvr_codec_register(&hvq_cl_ctx.unchecked, &err) == CDVR_OK);
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0.02}, {120, 1, .5, .2, .2}, {255, 1, 1, 1, .9}};
    FUZZ_ASSERT(cdvr_tf_init(&hvq_cl_ctx.tf, pts, 3, 0, &err) == CDVR_OK);
    return hvq_cl_ctx.cl;
}

/* Renders device frame 0 of s (brick min/max, then the ray cast) into a new image. */
static cdvr_image *hvq_cl_render(cdvr_cl_stream *s, const size_t dims[3])
{
    static const double spacing[3] = {1, 1, 1}, origin[3] = {0, 0, 0},
                        direction[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    cdvr_camera cam = {.eye = {-0.6 * (double)dims[0], -0.9 * (double)dims[1],
                               1.7 * (double)dims[2] + 3},
                       .center = {dims[0] / 2.0, dims[1] / 2.0, dims[2] / 2.0},
                       .up = {0, 0, 1}, .fov = 45, .width = 20, .height = 16};
    cdvr_render_opts o = {.tf = &hvq_cl_ctx.tf, .camera = &cam, .step = 0.7};
    cdvr_image *img = NULL;
    cdvr_error err;
    FUZZ_ASSERT(cdvr_image_create(cam.width, cam.height, &img, &err) == CDVR_OK);
    FUZZ_ASSERT(cdvr_cl_setup(s, 0, &hvq_cl_ctx.tf, &err) == CDVR_OK);
    FUZZ_ASSERT(cdvr_cl_render(s, 0, &o, spacing, origin, direction, img, &err) == CDVR_OK);
    return img;
}

static int hvq_cl_same(const cdvr_image *a, const cdvr_image *b)
{
    return a->width == b->width && a->height == b->height &&
           memcmp(a->rgba, b->rgba, (size_t)a->width * a->height * 4 * sizeof *a->rgba) == 0;
}

/* Uploads `fill` bytes of value v (so the buffer holds v past the payload), then the payload,
 * and renders it through the unchecked table. */
static cdvr_image *hvq_cl_unchecked(cdvr_cl_stream *s, const cdvr_codec_params *blob,
                                    const size_t dims[3], const uint8_t *payload, size_t bytes,
                                    uint8_t *filler, size_t fill, uint8_t v)
{
    cdvr_error err;
    memset(filler, v, fill);
    FUZZ_ASSERT(cdvr_cl_upload(s, filler, fill, &err) == CDVR_OK);
    FUZZ_ASSERT(cdvr_cl_upload(s, payload, bytes, &err) == CDVR_OK);
    FUZZ_ASSERT(cdvr_cl_decode(s, &hvq_cl_ctx.unchecked, blob, 1, &err) == CDVR_OK);
    return hvq_cl_render(s, dims);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 5 || !fuzz_hvq_cl_device()) /* the device path refuses an empty payload */
        return 0;
    const cdvr_codec *codec = cdvr_codec_find("hvq");
    size_t dims[3];
    if (data[0] & 1) {
        dims[0] = 257 + data[1] % 8u;
        dims[1] = 1 + data[2] % 4u;
        dims[2] = 1 + data[3] % 4u;
    } else {
        for (int a = 0; a < 3; a++)
            dims[a] = 1 + data[1 + a] % 40u;
    }
    cdvr_codec_params blob;
    cdvr_error err;
    codec->params_default(&blob);
    if (data[0] & 2) {
        FUZZ_ASSERT(codec->params_set(&blob, "k1", "4096", &err) == CDVR_OK);
        FUZZ_ASSERT(codec->params_set(&blob, "k2", "4096", &err) == CDVR_OK);
    }
    size_t voxels = dims[0] * dims[1] * dims[2], bytes = size - 4, fill = bytes + 4096;
    uint8_t *payload = malloc(bytes), *frame = malloc(voxels), *filler = malloc(fill);
    cdvr_cl_stream *s = NULL, *dense = NULL;
    FUZZ_ASSERT(payload && frame && filler);
    memcpy(payload, data + 4, bytes);
    uint8_t *frames[1] = {frame};
    cdvr_status cpu = codec->decode(&blob, dims, payload, bytes, frames, 1, &err);
    FUZZ_ASSERT(cpu == CDVR_OK || cpu == CDVR_ERR_CORRUPT);
    FUZZ_ASSERT(cdvr_cl_stream_create(hvq_cl_ctx.cl, dims, &s, &err) == CDVR_OK);
    cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_SAMPLE); /* the fetch function, not the C decoder */
    FUZZ_ASSERT(cdvr_cl_upload(s, payload, bytes, &err) == CDVR_OK);
    cdvr_status dev = cdvr_cl_decode(s, codec, &blob, 1, &err);
    FUZZ_ASSERT(dev == cpu);
    FUZZ_ASSERT(dev == CDVR_OK || strstr(err.msg, "codec hvq") != NULL);
    FUZZ_OUTCOME(dev == CDVR_OK);
    cdvr_image *checked = NULL;
    if (dev == CDVR_OK) {
        checked = hvq_cl_render(s, dims);
        FUZZ_ASSERT(cdvr_cl_stream_create(hvq_cl_ctx.cl, dims, &dense, &err) == CDVR_OK);
        FUZZ_ASSERT(cdvr_cl_upload_frames(dense, frame, 1, &err) == CDVR_OK);
        cdvr_image *ref = hvq_cl_render(dense, dims);
        FUZZ_ASSERT(hvq_cl_same(checked, ref));
        cdvr_image_free(ref);
    }
    cdvr_image *zeros = hvq_cl_unchecked(s, &blob, dims, payload, bytes, filler, fill, 0x00);
    cdvr_image *ones = hvq_cl_unchecked(s, &blob, dims, payload, bytes, filler, fill, 0xff);
    FUZZ_ASSERT(hvq_cl_same(zeros, ones));
    FUZZ_ASSERT(!checked || hvq_cl_same(zeros, checked));
    cdvr_image_free(zeros);
    cdvr_image_free(ones);
    cdvr_image_free(checked);
    cdvr_cl_stream_free(s);
    cdvr_cl_stream_free(dense);
    free(payload);
    free(frame);
    free(filler);
    return 0;
}

#else

static void *fuzz_hvq_cl_device(void)
{
    return NULL;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    (void)data;
    (void)size;
    return 0;
}

#endif
