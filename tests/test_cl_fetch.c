/* tests/test_cl_fetch.c - the ray caster's per-sample fetch hook (cdvr/codec.h, fetch mode):
 * a test codec whose OpenCL code reads raw voxels through a fetch function renders exactly the
 * image of the dense path (same samples, same arithmetic), with and without empty-space
 * skipping, on odd dims and for several frames of a chunk; the device then holds the payload,
 * not dense frames; its frames cannot be downloaded; a broken fetch source gives the build log.
 * The BULK path (cdvr_cl_fetch_path: the codec's C decoder, then the dense render) gives the
 * same images with dense frames on the device, and AUTO takes it on CPU devices only. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/camera.h"
#include "cdvr/codec.h"
#include "cdvr/compare.h"
#include "cdvr/device.h"
#include "cdvr/render.h"
#include "cdvr/tf.h"
#include "cdvr/volume.h"
#include "check.h"

#if CDVR_HAVE_OPENCL

/* The raw codec with 3 frames per chunk, read on the device through rawfetch(). */
static const char fetch_source[] =
    "uchar rawfetch(__global const uchar *payload, __constant uchar *params, int4 dims,\n"
    "               int x, int y, int z)\n"
    "{\n"
    "    return payload[(ulong)x + (ulong)dims.x * ((ulong)y + (ulong)dims.y *\n"
    "                   ((ulong)z + (ulong)dims.z * (ulong)dims.w))];\n"
    "}\n";

static cdvr_status shape3(const cdvr_codec_params *p, const size_t dims[3], cdvr_codec_shape *out,
                          cdvr_error *err)
{
    (void)p;
    (void)err;
    out->timesteps = 3;
    out->payload_bytes = out->bound_bytes = 3 * dims[0] * dims[1] * dims[2];
    return CDVR_OK;
}

static cdvr_status decode3(const cdvr_codec_params *p, const size_t dims[3], const uint8_t *in,
                           size_t in_bytes, uint8_t *const *frames, size_t count, cdvr_error *err)
{
    (void)p;
    size_t voxels = dims[0] * dims[1] * dims[2];
    if (in_bytes != 3 * voxels || count > 3)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "bad chunk");
    for (size_t i = 0; i < count; i++)
        memcpy(frames[i], in + i * voxels, voxels);
    return CDVR_OK;
}

static cdvr_codec make_fetch_codec(const char *name, uint32_t id, const char *source)
{
    cdvr_codec c = *cdvr_codec_find("raw");
    c.name = name;
    c.id = id;
    c.shape = shape3;
    c.decode = decode3;
    c.cl_mode = CDVR_CODEC_CL_FETCH;
    c.cl_file = NULL;
    c.cl_source = source;
    c.cl_function = "rawfetch";
    c.cl_work_items = NULL;
    return c;
}

static cdvr_image *render(cdvr_cl_stream *s, size_t frame, const cdvr_tf *tf,
                          const cdvr_camera *cam, const cdvr_volume *vol)
{
    cdvr_render_opts o = {.tf = tf, .camera = cam, .step = 0.37};
    cdvr_image *img = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_image_create(cam->width, cam->height, &img, &err);
    if (!st)
        st = cdvr_cl_setup(s, frame, tf, &err);
    if (!st)
        st = cdvr_cl_render(s, frame, &o, vol->spacing, vol->origin, vol->direction, img, &err);
    CHECK_OK(st, err);
    if (st) {
        cdvr_image_free(img);
        return NULL;
    }
    return img;
}

static void compare_paths(cdvr_cl *cl, const cdvr_codec *codec, const size_t dims[3],
                          cdvr_cl_fetch_path path)
{
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_generate_opts g = {{dims[0], dims[1], dims[2]}, 3, CDVR_TYPE_U8, 0, 0.6, 0, 0};
    if (cdvr_volume_generate("sphere", &g, &vol, &err) != CDVR_OK)
        return;
    vol->spacing[1] = 1.5;
    cdvr_tf tf;
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {100, 1, .5, .2, .1}, {255, 1, 1, 1, .9}};
    cdvr_tf_init(&tf, pts, 3, 0, &err);
    cdvr_camera cam = {.eye = {-40, -30, 25}, .center = {dims[0] / 2.0, dims[1] * 0.75,
                                                         dims[2] / 2.0},
                       .up = {0, 0, 1}, .fov = 35, .width = 61, .height = 47};
    cdvr_cl_stream *dense = NULL, *fetch = NULL;
    CHECK_OK(cdvr_cl_stream_create(cl, dims, &dense, &err), err);
    CHECK_OK(cdvr_cl_stream_create(cl, dims, &fetch, &err), err);
    cdvr_cl_set_fetch_path(fetch, path);
    size_t voxels = cdvr_volume_voxels(vol);
    cdvr_codec_params none = {{0}};
    cdvr_status st = cdvr_cl_upload_frames(dense, vol->data, 3, &err);
    CHECK_OK(st, err);
    st = cdvr_cl_upload(fetch, vol->data, 3 * voxels, &err);
    CHECK_OK(st, err);
    st = cdvr_cl_decode(fetch, codec, &none, 3, &err);
    CHECK_OK(st, err);
    uint8_t *got = malloc(voxels);
    if (path == CDVR_CL_FETCH_SAMPLE) {
        CHECK(cdvr_cl_volume_bytes(fetch) == 3 * voxels + 48, "fetch mode holds the payload: %llu",
              (unsigned long long)cdvr_cl_volume_bytes(fetch));
        CHECK(cdvr_cl_download(fetch, 0, got, &err) == CDVR_ERR_UNSUPPORTED,
              "download in fetch mode");
    } else {
        CHECK(cdvr_cl_volume_bytes(fetch) == 3 * voxels, "bulk holds dense frames: %llu",
              (unsigned long long)cdvr_cl_volume_bytes(fetch));
        CHECK_OK(cdvr_cl_download(fetch, 2, got, &err), err);
        CHECK(memcmp(got, vol->data + 2 * voxels, voxels) == 0, "bulk frame 2 is the C decode");
    }
    free(got);
    for (int skip = 0; skip < 2; skip++)
        for (size_t f = 0; f < 3 && st == CDVR_OK; f++) {
            cdvr_cl_set_skipping(dense, skip);
            cdvr_cl_set_skipping(fetch, skip);
            cdvr_image *a = render(dense, f, &tf, &cam, vol), *b = render(fetch, f, &tf, &cam, vol);
            if (a && b) {
                size_t n = (size_t)a->width * a->height * 4, differ = 0;
                for (size_t i = 0; i < n; i++)
                    differ += a->rgba[i] != b->rgba[i];
                CHECK(differ == 0, "%zux%zux%zu frame %zu skip %d: %zu of %zu values differ",
                      dims[0], dims[1], dims[2], f, skip, differ, n);
                CHECK(cdvr_cl_last_samples(dense) == cdvr_cl_last_samples(fetch), "samples");
            }
            cdvr_image_free(a);
            cdvr_image_free(b);
        }
    cdvr_cl_stream_free(dense);
    cdvr_cl_stream_free(fetch);
    cdvr_volume_free(vol);
}

int main(void)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        return check_opencl_unavailable(err.msg);
    }
    static cdvr_codec codec, broken;
    codec = make_fetch_codec("rawfetch_test", 90001, fetch_source);
    CHECK_OK(cdvr_codec_register(&codec, &err), err);
    const size_t dims[][3] = {{1, 1, 1}, {5, 3, 7}, {23, 17, 9}};
    for (size_t i = 0; i < 3; i++) {
        compare_paths(cl, &codec, dims[i], CDVR_CL_FETCH_SAMPLE);
        compare_paths(cl, &codec, dims[i], CDVR_CL_FETCH_BULK);
    }
    /* a fetch function that does not compile: the build log is in the message */
    broken = make_fetch_codec("brokenfetch_test", 90002,
                              "uchar rawfetch(__global const uchar *p, __constant uchar *q, "
                              "int4 d, int x, int y, int z) { return no_such_name_q; }\n");
    cdvr_cl_stream *s;
    size_t d[3] = {4, 4, 4};
    uint8_t payload[3 * 64] = {0};
    cdvr_codec_params none = {{0}};
    CHECK_OK(cdvr_cl_stream_create(cl, d, &s, &err), err);
    if (!getenv("CDVR_CL_FETCH")) { /* AUTO: bulk exactly on CPU devices */
        cdvr_cl_fetch_path want = cdvr_cl_get_info(cl)->is_gpu ? CDVR_CL_FETCH_SAMPLE
                                                               : CDVR_CL_FETCH_BULK;
        CHECK(cdvr_cl_fetch_path_of(s) == want, "auto path %d", (int)cdvr_cl_fetch_path_of(s));
    }
    cdvr_cl_set_fetch_path(s, CDVR_CL_FETCH_SAMPLE); /* bulk would never build the source */
    CHECK_OK(cdvr_cl_upload(s, payload, sizeof payload, &err), err);
    cdvr_status st = cdvr_cl_decode(s, &broken, &none, 1, &err);
    CHECK(st == CDVR_ERR_DEVICE && strstr(err.msg, "no_such_name_q") &&
              strstr(err.msg, "brokenfetch_test"), "broken fetch: %s", err.msg);
    cdvr_cl_stream_free(s);
    cdvr_cl_close(cl);
    return check_finish();
}

#else
CHECK_SKIPPED_MAIN("built without OpenCL")
#endif
