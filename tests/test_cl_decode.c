/* tests/test_cl_decode.c - codec decode kernels through the codec table (cdvr_cl_decode): the
 * PVTC kernel and the host path (the C decoder into the mapped frames buffer) are bit-exact
 * with cdvr_pvtc_decode_chunk, and so with each other, on every variant, odd dims, random
 * chunks and encoded real data; raw chunks on both paths; the automatic choice on a CPU device
 * is measured once and remembered on disk; host-decoded frames; bad arguments. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/device.h"
#include "cdvr/pvtc.h"
#include "cdvr/store.h"
#include "cdvr/volume.h"
#include "check.h"

#if CDVR_HAVE_OPENCL

static uint32_t next_random(uint32_t *state)
{
    *state = *state * 1664525u + 1013904223u;
    return *state >> 8;
}

static const cdvr_pvtc_params variants[] = {
    {1, 2, CDVR_PACK_TIME}, {1, 3, CDVR_PACK_TIME}, {4, 2, CDVR_PACK_TIME}, {4, 3, CDVR_PACK_TIME},
    {1, 2, CDVR_PACK_SPACE}, {1, 3, CDVR_PACK_SPACE}, {4, 2, CDVR_PACK_SPACE}, {4, 3, CDVR_PACK_SPACE}};
#define NVARIANTS (sizeof variants / sizeof *variants)

/* Decodes `chunk` (nframes frames) with the C decoder, then on the device by the kernel and by
 * the host path, and compares. */
static void compare_decoders(cdvr_cl_stream *s, const cdvr_pvtc_params *p, const size_t dims[3],
                             const uint8_t *chunk, size_t bytes, size_t nframes, const char *what)
{
    size_t voxels = dims[0] * dims[1] * dims[2];
    uint8_t *ref = malloc(voxels * nframes), *got = malloc(voxels);
    uint8_t *frames[3] = {ref, ref + voxels, ref + 2 * voxels};
    cdvr_error err;
    cdvr_status st = cdvr_pvtc_decode_chunk(p, dims, chunk, bytes, frames, nframes, &err);
    CHECK_OK(st, err);
    static const cdvr_cl_decode_path paths[] = {CDVR_CL_DECODE_KERNEL, CDVR_CL_DECODE_HOST};
    for (size_t pi = 0; pi < 2 && st == CDVR_OK; pi++) {
        cdvr_cl_set_decode_path(s, paths[pi]);
        st = cdvr_cl_upload(s, chunk, bytes, &err);
        CHECK_OK(st, err);
        cdvr_codec_params blob;
        cdvr_pvtc_params_to_blob(p, CDVR_ENCODER_LSQ, &blob);
        st = cdvr_cl_decode(s, cdvr_codec_find("pvtc"), &blob, nframes, &err);
        CHECK_OK(st, err);
        CHECK(st || cdvr_cl_last_decode_path(s) == paths[pi], "decode took path %d, not %d",
              (int)cdvr_cl_last_decode_path(s), (int)paths[pi]);
        for (size_t f = 0; f < nframes && st == CDVR_OK; f++) {
            memset(got, 0xA5, voxels);
            st = cdvr_cl_download(s, f, got, &err);
            CHECK_OK(st, err);
            size_t bad = 0, first = 0;
            for (size_t i = 0; i < voxels; i++)
                if (got[i] != frames[f][i] && bad++ == 0)
                    first = i;
            CHECK(bad == 0, "%s S%dT%d%s %zux%zux%zu frame %zu/%zu, %s path: %zu voxels differ, "
                  "first at %zu (device %d, C %d)", what, p->S, p->T,
                  p->pack == CDVR_PACK_SPACE ? "s" : "", dims[0], dims[1], dims[2], f, nframes,
                  pi ? "host" : "kernel", bad, first, got[first], frames[f][first]);
        }
    }
    cdvr_cl_set_decode_path(s, CDVR_CL_DECODE_AUTO);
    free(ref);
    free(got);
}

static void random_chunks(cdvr_cl *cl, const size_t dims[3], uint32_t seed)
{
    cdvr_cl_stream *s;
    cdvr_error err;
    cdvr_status st = cdvr_cl_stream_create(cl, dims, &s, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    for (size_t v = 0; v < NVARIANTS; v++) {
        cdvr_pvtc_geometry geom;
        st = cdvr_pvtc_geometry_get(&variants[v], dims, &geom, &err);
        CHECK_OK(st, err);
        uint8_t *chunk = malloc(geom.chunk_bytes);
        for (size_t i = 0; i < geom.chunk_bytes; i++)
            chunk[i] = (uint8_t)next_random(&seed);
        for (size_t n = 1; n <= geom.frames; n++)
            compare_decoders(s, &variants[v], dims, chunk, geom.chunk_bytes, n, "random");
        free(chunk);
    }
    cdvr_cl_stream_free(s);
}

/* Encodes T frames of `vol` (first timestep shifted per channel) and compares decoders. */
static void encoded_chunks(cdvr_cl *cl, const cdvr_volume *vol, const char *what)
{
    size_t voxels = cdvr_volume_voxels(vol);
    uint8_t *src = cdvr_volume_frame(vol, 0);
    uint8_t *frames_buf = malloc(3 * voxels);
    for (size_t c = 0; c < 3; c++)
        for (size_t i = 0; i < voxels; i++)
            frames_buf[c * voxels + i] = (uint8_t)(c == 1 ? 255 - src[i] : src[(i + 97 * c) % voxels]);
    const uint8_t *frames[3] = {frames_buf, frames_buf + voxels, frames_buf + 2 * voxels};
    cdvr_cl_stream *s;
    cdvr_error err;
    cdvr_status st = cdvr_cl_stream_create(cl, vol->dims, &s, &err);
    CHECK_OK(st, err);
    for (size_t v = 0; v < NVARIANTS && st == CDVR_OK; v++) {
        cdvr_pvtc_geometry geom;
        st = cdvr_pvtc_geometry_get(&variants[v], vol->dims, &geom, &err);
        uint8_t *chunk = malloc(geom.chunk_bytes);
        st = cdvr_pvtc_encode_chunk(&variants[v], CDVR_ENCODER_BBOX, vol->dims, frames, chunk, &err);
        CHECK_OK(st, err);
        if (!st)
            compare_decoders(s, &variants[v], vol->dims, chunk, geom.chunk_bytes, geom.frames, what);
        free(chunk);
    }
    cdvr_cl_stream_free(s);
    free(frames_buf);
}

static void raw_chunks(cdvr_cl *cl)
{
    size_t dims[3] = {5, 3, 7}, voxels = 105;
    uint8_t payload[2 * 105], got[105];
    for (size_t i = 0; i < sizeof payload; i++)
        payload[i] = (uint8_t)(i * 37 + 11);
    cdvr_cl_stream *s;
    cdvr_error err;
    cdvr_status st = cdvr_cl_stream_create(cl, dims, &s, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    const cdvr_codec *raw = cdvr_codec_find("raw"), *pvtc = cdvr_codec_find("pvtc");
    cdvr_codec_params none;
    raw->params_default(&none);
    for (int path = CDVR_CL_DECODE_AUTO; path <= CDVR_CL_DECODE_HOST; path++) {
        cdvr_cl_set_decode_path(s, (cdvr_cl_decode_path)path);
        st = cdvr_cl_upload(s, payload, voxels, &err);
        CHECK_OK(st, err);
        st = cdvr_cl_decode(s, raw, &none, 1, &err);
        CHECK_OK(st, err);
        memset(got, 0, sizeof got);
        st = cdvr_cl_download(s, 0, got, &err);
        CHECK_OK(st, err);
        CHECK(memcmp(got, payload, voxels) == 0, "raw frame differs (path %d)", path);
        CHECK(cdvr_cl_last_decode_path(s) != CDVR_CL_DECODE_AUTO &&
              (path == CDVR_CL_DECODE_AUTO || (int)cdvr_cl_last_decode_path(s) == path),
              "path %d taken as %d", path, (int)cdvr_cl_last_decode_path(s));
    }
    cdvr_cl_set_decode_path(s, CDVR_CL_DECODE_AUTO);
    /* frames decoded on the host */
    st = cdvr_cl_upload_frames(s, payload, 2, &err);
    CHECK_OK(st, err);
    for (size_t f = 0; f < 2; f++) {
        st = cdvr_cl_download(s, f, got, &err);
        CHECK_OK(st, err);
        CHECK(memcmp(got, payload + f * voxels, voxels) == 0, "uploaded frame %zu differs", f);
    }
    CHECK(cdvr_cl_volume_bytes(s) == 2 * voxels, "volume bytes %llu",
          (unsigned long long)cdvr_cl_volume_bytes(s));
    /* misuse: wrong sizes, counts, codecs and frames give errors, not crashes */
    st = cdvr_cl_upload(s, payload, sizeof payload, &err);
    CHECK_OK(st, err);
    st = cdvr_cl_decode(s, raw, &none, 2, &err);
    CHECK(st == CDVR_ERR_ARG, "raw count mismatch: status %d", (int)st);
    st = cdvr_cl_decode(s, raw, &none, 1, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "bytes"), "raw size mismatch: %s", err.msg);
    cdvr_pvtc_params p = {4, 3, CDVR_PACK_TIME};
    cdvr_codec_params blob;
    cdvr_pvtc_params_to_blob(&p, CDVR_ENCODER_LSQ, &blob);
    st = cdvr_cl_decode(s, pvtc, &blob, 1, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "bytes"), "pvtc size mismatch: %s", err.msg);
    p.S = 2;
    cdvr_pvtc_params_to_blob(&p, CDVR_ENCODER_LSQ, &blob);
    st = cdvr_cl_decode(s, pvtc, &blob, 1, &err);
    CHECK(st == CDVR_ERR_ARG, "bad S: status %d", (int)st);
    static cdvr_codec cpu_only;
    cpu_only = *raw;
    cpu_only.name = "cpu_only_test";
    cpu_only.cl_mode = CDVR_CODEC_CL_NONE;
    st = cdvr_cl_upload(s, payload, voxels, &err);
    CHECK_OK(st, err);
    st = cdvr_cl_decode(s, &cpu_only, &none, 1, &err);
    CHECK(st == CDVR_ERR_UNSUPPORTED, "codec without device code: status %d", (int)st);
    st = cdvr_cl_download(s, 0, got, &err);
    CHECK(st == CDVR_ERR_ARG, "download after failed decode: status %d", (int)st);
    st = cdvr_cl_upload(s, payload, 0, &err);
    CHECK(st == CDVR_ERR_ARG, "empty upload: status %d", (int)st);
    size_t huge[3] = {(size_t)1 << 30, (size_t)1 << 30, 4};
    cdvr_cl_stream *bad = NULL;
    st = cdvr_cl_stream_create(cl, huge, &bad, &err);
    CHECK(st != CDVR_OK && bad == NULL, "absurd dims accepted");
    cdvr_cl_stream_free(s);
}

/* The automatic path: on a CPU device the first decode measures both paths and leaves its
 * choice on disk, where a second device context finds it (no measurement: the same path). */
static void remembered_choice(void)
{
    char dir[] = "/tmp/cdvr_test_decode_choice_XXXXXX";
    if (!mkdtemp(dir))
        return;
    const char *old = getenv("CDVR_CACHE_DIR");
    char *saved = old ? strdup(old) : NULL;
    setenv("CDVR_CACHE_DIR", dir, 1);
    size_t dims[3] = {32, 24, 20}, voxels = 32 * 24 * 20;
    cdvr_pvtc_params p = {4, 3, CDVR_PACK_TIME};
    cdvr_codec_params blob;
    cdvr_pvtc_params_to_blob(&p, CDVR_ENCODER_BBOX, &blob);
    cdvr_pvtc_geometry g;
    cdvr_error err;
    cdvr_pvtc_geometry_get(&p, dims, &g, &err);
    uint8_t *chunk = malloc(g.chunk_bytes), *got = malloc(voxels), *ref = malloc(3 * voxels);
    uint32_t seed = 99;
    for (size_t i = 0; i < g.chunk_bytes; i++)
        chunk[i] = (uint8_t)next_random(&seed);
    uint8_t *frames[3] = {ref, ref + voxels, ref + 2 * voxels};
    CHECK_OK(cdvr_pvtc_decode_chunk(&p, dims, chunk, g.chunk_bytes, frames, 3, &err), err);
    cdvr_cl_decode_path first = CDVR_CL_DECODE_AUTO;
    for (int round = 0; round < 2; round++) {
        cdvr_cl *cl = NULL;
        cdvr_cl_stream *s = NULL;
        if (cdvr_cl_open(&cl, &err) || cdvr_cl_stream_create(cl, dims, &s, &err)) {
            cdvr_cl_close(cl);
            break;
        }
        int gpu = cdvr_cl_get_info(cl)->is_gpu;
        cdvr_cl_set_decode_path(s, CDVR_CL_DECODE_AUTO);
        CHECK_OK(cdvr_cl_upload(s, chunk, g.chunk_bytes, &err), err);
        CHECK_OK(cdvr_cl_decode(s, cdvr_codec_find("pvtc"), &blob, 3, &err), err);
        cdvr_cl_decode_path took = cdvr_cl_last_decode_path(s);
        for (size_t f = 0; f < 3; f++) {
            CHECK_OK(cdvr_cl_download(s, f, got, &err), err);
            CHECK(memcmp(got, frames[f], voxels) == 0, "auto path, round %d, frame %zu", round,
                  f);
        }
        CHECK(gpu ? took == CDVR_CL_DECODE_KERNEL : took != CDVR_CL_DECODE_AUTO,
              "auto took %d on a %s", (int)took, gpu ? "GPU" : "CPU");
        if (round == 0)
            first = took;
        else
            CHECK(took == first, "remembered path %d, measured %d", (int)took, (int)first);
        cdvr_cl_stream_free(s);
        cdvr_cl_close(cl);
    }
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    CHECK(system(cmd) == 0, "remove %s", dir);
    if (saved)
        setenv("CDVR_CACHE_DIR", saved, 1);
    else
        unsetenv("CDVR_CACHE_DIR");
    free(saved);
    free(chunk);
    free(got);
    free(ref);
}

int main(void)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        return check_opencl_unavailable(err.msg);
    }
    printf("device: %s\n", cdvr_cl_device_name(cl));
    const size_t dims_list[][3] = {{1, 1, 1}, {5, 3, 7}, {9, 8, 13}, {66, 66, 66}, {4, 4, 24}};
    for (size_t i = 0; i < sizeof dims_list / sizeof *dims_list; i++)
        random_chunks(cl, dims_list[i], 12345u + (uint32_t)i);
    const char *data = check_shared_data();
    if (data) {
        char path[1024];
        snprintf(path, sizeof path, "%s/sim/neghip_66x66x66_u8.nrrd", data);
        cdvr_volume *vol;
        cdvr_status st = cdvr_volume_load_nrrd(path, &vol, &err);
        CHECK_OK(st, err);
        if (!st) {
            encoded_chunks(cl, vol, "neghip");
            cdvr_volume_free(vol);
        }
    }
    cdvr_generate_opts gen = {{9, 8, 13}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
    cdvr_volume *ml;
    if (!cdvr_volume_generate("ml", &gen, &ml, &err)) {
        encoded_chunks(cl, ml, "ml");
        cdvr_volume_free(ml);
    }
    raw_chunks(cl);
    cdvr_cl_close(cl);
    remembered_choice();
    return check_finish();
}

#else
CHECK_SKIPPED_MAIN("built without OpenCL")
#endif
