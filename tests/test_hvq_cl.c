/* tests/test_hvq_cl.c - kernels/codec/hvq_fetch.cl is bit-exact with the C decoder: a program
 * made of the fetch function and a tiny kernel that fetches every voxel, built with the
 * OpenCL API directly, on the hard cases, random volumes, a crop of Colin27 (when
 * CDVR_SHARED_DATA is set) and a hand-made hash with two-byte offsets (m > 256). Skips (77)
 * without an OpenCL platform or device. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/hvq.h"
#include "cdvr/volume.h"
#include "check.h"
#include "codec/hvq/hvq_internal.h"

#if CDVR_HAVE_OPENCL
#include <CL/cl.h>

static const char test_kernels[] =
    "\n__kernel void hvq_fetch_all(__global const uchar *payload, __constant uchar *params,\n"
    "                            int4 dims, __global uchar *out)\n"
    "{\n"
    "    size_t i = get_global_id(0), X = (size_t)dims.x, Y = (size_t)dims.y;\n"
    "    if (i >= X * Y * (size_t)dims.z)\n"
    "        return;\n"
    "    out[i] = hvq_fetch(payload, params, dims, (int)(i % X), (int)(i / X % Y),\n"
    "                       (int)(i / X / Y));\n"
    "}\n"
    "__kernel void hvq_find_keys(__global const uchar *data, ulong n, uint m, uint r,\n"
    "                            uint slot_bytes, __global const uchar *keys,\n"
    "                            __global int *out)\n"
    "{\n"
    "    size_t i = get_global_id(0);\n"
    "    __global const uchar *k = keys + 3 * i;\n"
    "    __global const uchar *v = hvq_find(data, n, 0, m, r, slot_bytes, k[0], k[1], k[2]);\n"
    "    out[i] = v ? (int)v[0] : -1;\n"
    "}\n";

typedef struct cl_env {
    cl_context ctx;
    cl_command_queue q;
    cl_program prog;
    cl_kernel fetch_all, find_keys;
} cl_env;

static uint32_t rng_next(uint32_t *s)
{
    *s ^= *s << 13;
    *s ^= *s >> 17;
    *s ^= *s << 5;
    return *s;
}

static char *read_text(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = n >= 0 ? malloc((size_t)n + sizeof test_kernels + 1) : NULL;
    if (s && fread(s, 1, (size_t)n, f) == (size_t)n)
        memcpy(s + n, test_kernels, sizeof test_kernels);
    else {
        free(s);
        s = NULL;
    }
    fclose(f);
    return s;
}

/* 0 ok, 77 no platform/device, 1 failure (reported). */
static int env_open(cl_env *env)
{
    cl_platform_id plats[8];
    cl_uint nplat = 0;
    cl_device_id dev = NULL;
    if (clGetPlatformIDs(8, plats, &nplat) != CL_SUCCESS || nplat == 0)
        return 77;
    for (cl_uint i = 0; i < nplat && !dev; i++) {
        cl_uint ndev = 0;
        if (clGetDeviceIDs(plats[i], CL_DEVICE_TYPE_ALL, 1, &dev, &ndev) != CL_SUCCESS)
            dev = NULL;
    }
    if (!dev)
        return 77;
    char name[256] = "";
    clGetDeviceInfo(dev, CL_DEVICE_NAME, sizeof name, name, NULL);
    printf("device: %s\n", name);
    const char *src_dir = getenv("CDVR_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/kernels/codec/hvq_fetch.cl", src_dir ? src_dir : "..");
    char *src = read_text(path);
    CHECK(src != NULL, "cannot read %s (set CDVR_SOURCE_DIR)", path);
    if (!src)
        return 1;
    cl_int e;
    env->ctx = clCreateContext(NULL, 1, &dev, NULL, NULL, &e);
    CHECK(e == CL_SUCCESS, "clCreateContext: %d", e);
    env->q = e == CL_SUCCESS ? clCreateCommandQueue(env->ctx, dev, 0, &e) : NULL;
    CHECK(e == CL_SUCCESS, "clCreateCommandQueue: %d", e);
    const char *srcs[1] = {src};
    env->prog = e == CL_SUCCESS ? clCreateProgramWithSource(env->ctx, 1, srcs, NULL, &e) : NULL;
    CHECK(e == CL_SUCCESS, "clCreateProgramWithSource: %d", e);
    free(src);
    if (e != CL_SUCCESS)
        return 1;
    e = clBuildProgram(env->prog, 1, &dev, "-cl-std=CL1.2", NULL, NULL);
    if (e != CL_SUCCESS) {
        size_t n = 0;
        clGetProgramBuildInfo(env->prog, dev, CL_PROGRAM_BUILD_LOG, 0, NULL, &n);
        char *log = malloc(n + 1);
        if (log && clGetProgramBuildInfo(env->prog, dev, CL_PROGRAM_BUILD_LOG, n, log, NULL) ==
                       CL_SUCCESS)
            log[n] = 0;
        CHECK(0, "building %s: error %d, build log:\n%s", path, e, log ? log : "(none)");
        free(log);
        return 1;
    }
    env->fetch_all = clCreateKernel(env->prog, "hvq_fetch_all", &e);
    CHECK(e == CL_SUCCESS, "clCreateKernel hvq_fetch_all: %d", e);
    env->find_keys = clCreateKernel(env->prog, "hvq_find_keys", &e);
    CHECK(e == CL_SUCCESS, "clCreateKernel hvq_find_keys: %d", e);
    return e == CL_SUCCESS ? 0 : 1;
}

static void env_close(cl_env *env)
{
    if (env->fetch_all)
        clReleaseKernel(env->fetch_all);
    if (env->find_keys)
        clReleaseKernel(env->find_keys);
    if (env->prog)
        clReleaseProgram(env->prog);
    if (env->q)
        clReleaseCommandQueue(env->q);
    if (env->ctx)
        clReleaseContext(env->ctx);
}

#define SET_ARG(kernel, kname, i, size, ptr)                                                  \
    do {                                                                                      \
        cl_int e_ = clSetKernelArg(kernel, i, size, ptr);                                     \
        CHECK(e_ == CL_SUCCESS, "clSetKernelArg(%s, argument %d): %d", kname, i, e_);         \
        ok = ok && e_ == CL_SUCCESS;                                                          \
    } while (0)

/* Fetches every voxel of the payload on the device into out. */
static int device_fetch_all(cl_env *env, const uint8_t *payload, size_t bytes,
                            const cdvr_codec_params *params, const size_t d[3], uint8_t *out)
{
    size_t n = d[0] * d[1] * d[2];
    cl_int e1, e2, e3;
    cl_mem pay = clCreateBuffer(env->ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, bytes,
                                (void *)payload, &e1);
    uint8_t pbuf[56]; /* the blob, then the payload's size (cdvr/codec.h) */
    memcpy(pbuf, params->bytes, 48);
    for (int i = 0; i < 8; i++)
        pbuf[48 + i] = (uint8_t)((uint64_t)bytes >> (8 * i));
    cl_mem par = clCreateBuffer(env->ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof pbuf,
                                pbuf, &e2);
    cl_mem res = clCreateBuffer(env->ctx, CL_MEM_WRITE_ONLY, n, NULL, &e3);
    int ok = e1 == CL_SUCCESS && e2 == CL_SUCCESS && e3 == CL_SUCCESS;
    CHECK(ok, "clCreateBuffer: %d %d %d", e1, e2, e3);
    cl_int4 dims = {{(cl_int)d[0], (cl_int)d[1], (cl_int)d[2], 0}};
    if (ok) {
        SET_ARG(env->fetch_all, "hvq_fetch_all", 0, sizeof pay, &pay);
        SET_ARG(env->fetch_all, "hvq_fetch_all", 1, sizeof par, &par);
        SET_ARG(env->fetch_all, "hvq_fetch_all", 2, sizeof dims, &dims);
        SET_ARG(env->fetch_all, "hvq_fetch_all", 3, sizeof res, &res);
    }
    if (ok) {
        cl_int e = clEnqueueNDRangeKernel(env->q, env->fetch_all, 1, NULL, &n, NULL, 0, NULL,
                                          NULL);
        CHECK(e == CL_SUCCESS, "clEnqueueNDRangeKernel(hvq_fetch_all): %d", e);
        if (e == CL_SUCCESS)
            e = clEnqueueReadBuffer(env->q, res, CL_TRUE, 0, n, out, 0, NULL, NULL);
        CHECK(e == CL_SUCCESS, "clEnqueueReadBuffer: %d", e);
        ok = e == CL_SUCCESS;
    }
    if (pay)
        clReleaseMemObject(pay);
    if (par)
        clReleaseMemObject(par);
    if (res)
        clReleaseMemObject(res);
    return ok;
}

/* Encodes frame, decodes it in C, fetches every voxel on the device, compares. Returns the
 * payload's figures. */
static cdvr_hvq_stats compare(cl_env *env, const cdvr_hvq_params *p, const size_t d[3],
                    const uint8_t *frame, const char *what)
{
    size_t n = d[0] * d[1] * d[2], bound, bytes;
    cdvr_error err;
    cdvr_hvq_stats st;
    memset(&st, 0, sizeof st);
    cdvr_status s = cdvr_hvq_bound(p, d, &bound, &err);
    CHECK_OK(s, err);
    uint8_t *payload = s ? NULL : malloc(bound), *ref = malloc(n), *got = malloc(n);
    s = payload ? cdvr_hvq_encode(p, d, frame, 0, payload, bound, &bytes, &st, &err)
                : CDVR_ERR_NOMEM;
    CHECK_OK(s, err);
    if (s == CDVR_OK)
        s = cdvr_hvq_decode(p, d, payload, bytes, ref, &err);
    CHECK_OK(s, err);
    cdvr_codec_params blob;
    cdvr_hvq_params_to_blob(p, &blob);
    memset(got, 0xA5, n);
    if (s == CDVR_OK && device_fetch_all(env, payload, bytes, &blob, d, got)) {
        size_t bad = 0, first = 0;
        for (size_t i = 0; i < n; i++)
            if (got[i] != ref[i] && bad++ == 0)
                first = i;
        CHECK(bad == 0, "%s %zux%zux%zu: %zu of %zu voxels differ, first %zu (device %d, C %d)",
              what, d[0], d[1], d[2], bad, n, first, got[first], ref[first]);
        printf("%s %zux%zux%zu: %zu bytes, %zu zero blocks of %zu, %zu residual voxels, "
               "%zu/%zu entries: %s\n", what, d[0], d[1], d[2], bytes, st.zero_blocks,
               st.blocks, st.residual_voxels, st.codebook1_entries, st.codebook2_entries,
               bad ? "DIFFERENT" : "bit-exact");
    }
    free(payload);
    free(ref);
    free(got);
    return st;
}

static uint8_t *random_volume(const size_t d[3], uint32_t seed, int sparse)
{
    uint8_t *v = malloc(d[0] * d[1] * d[2]);
    for (size_t z = 0, i = 0; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            for (size_t x = 0; x < d[0]; x++, i++) {
                int val = (int)((x * 3 + y * 5 + z * 7) % 200) + (int)(rng_next(&seed) % 31) - 15;
                if (sparse && (x / 8 + y / 8 + z / 8) % 3)
                    val = 0;
                v[i] = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
            }
    return v;
}

static void hard_cases(cl_env *env)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    const size_t one[3] = {1, 1, 1}, odd[3] = {5, 3, 7}, flat[3] = {37, 20, 9};
    uint8_t v1 = 77, *zero = calloc(37 * 20 * 9, 1);
    compare(env, &p, one, &v1, "1x1x1");
    compare(env, &p, flat, zero, "all zero");
    p.grad = 0;
    compare(env, &p, flat, zero, "all zero, grad 0");
    free(zero);
    uint8_t *r = random_volume(odd, 1, 0);
    p.grad = 8;
    compare(env, &p, odd, r, "random");
    free(r);
    const size_t same[3] = {16, 12, 8};
    uint8_t *ident = malloc(16 * 12 * 8);
    for (size_t i = 0; i < 16 * 12 * 8; i++)
        ident[i] = (uint8_t)(17 + 61 * ((i % 16 % 4) ^ (i / 16 % 12 % 4)) + 13 * (i / 192 % 4));
    p.grad = 1;
    compare(env, &p, same, ident, "identical blocks");
    free(ident);
    const size_t noisy[3] = {40, 30, 20};
    uint8_t *noise = malloc(40 * 30 * 20);
    uint32_t seed = 3;
    for (size_t i = 0; i < 40 * 30 * 20; i++)
        noise[i] = (uint8_t)rng_next(&seed);
    p.grad = 4;
    p.residual = 0;
    p.k1 = p.k2 = 16;
    compare(env, &p, noisy, noise, "noise, residual 0");
    free(noise);
}

static void random_volumes(cl_env *env)
{
    const size_t dims[][3] = {{80, 64, 36}, {260, 9, 7}, {9, 300, 5}, {6, 5, 261}};
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    for (size_t i = 0; i < sizeof dims / sizeof *dims; i++) {
        uint8_t *v = random_volume(dims[i], 100u + (uint32_t)i, (int)(i % 2));
        p.grad = (double)(2 * i);
        p.k1 = i == 0 ? 300 : 256; /* 2880 blocks: two-byte indices at both levels */
        p.k2 = i == 0 ? 320 : 256;
        cdvr_hvq_stats st = compare(env, &p, dims[i], v, i % 2 ? "random sparse" : "random");
        CHECK(i != 0 || (st.codebook1_entries > 256 && st.codebook2_entries > 256),
              "the wide case has %zu/%zu entries (two-byte indices need > 256)",
              st.codebook1_entries, st.codebook2_entries);
        free(v);
    }
}

static void colin27_crop(cl_env *env)
{
    const char *data = check_shared_data();
    if (!data) {
        printf("CDVR_SHARED_DATA unset: no Colin27 crop\n");
        return;
    }
    char path[1024];
    snprintf(path, sizeof path, "%s/mri/colin27_t1_301x370x316_u8.nii.gz", data);
    cdvr_volume *vol;
    cdvr_error err;
    cdvr_status s = cdvr_volume_load(path, NULL, &vol, &err);
    CHECK_OK(s, err);
    if (s)
        return;
    /* 280x64x48 from the middle of the brain: two regions along x */
    const size_t d[3] = {280, 64, 48}, o[3] = {10, 150, 130};
    uint8_t *crop = malloc(d[0] * d[1] * d[2]);
    const uint8_t *src = vol->data;
    for (size_t z = 0; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            memcpy(crop + d[0] * (y + d[1] * z),
                   src + o[0] + vol->dims[0] * ((o[1] + y) + vol->dims[1] * (o[2] + z)), d[0]);
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    compare(env, &p, d, crop, "colin27 crop");
    free(crop);
    cdvr_volume_free(vol);
}

/* A hash with m = 257 (two-byte offsets) made by hand: keys in chosen slots, looked up in C
 * and on the device; absent keys miss in both. */
static void wide_offsets(cl_env *env)
{
    const uint32_t m = 257, r = 2;
    const unsigned slot_bytes = 4;
    uint64_t r3 = 8, m3 = (uint64_t)m * m * m, bytes = r3 * 6 + m3 * slot_bytes;
    uint8_t *data = calloc(1, (size_t)bytes);
    const uint8_t keys[][3] = {{0, 0, 0}, {1, 0, 0}, {5, 9, 200}, {255, 254, 253},
                               {128, 1, 7}, {3, 3, 3}, {2, 2, 2}, {255, 255, 255}};
    const uint32_t offsets[8][3] = {{256, 0, 1}, {1, 256, 255}, {300 % 257, 2, 3}, {0, 0, 0},
                                    {100, 200, 256}, {7, 8, 9}, {255, 255, 255}, {1, 1, 1}};
    for (uint64_t e = 0; e < r3; e++)
        for (int a = 0; a < 3; a++)
            hvq_wr16(data + e * 6 + 2 * a, offsets[e][a]);
    uint8_t *slots = data + r3 * 6;
    for (uint64_t s = 0; s < m3; s++) /* "empty" slots: a key that maps elsewhere */
        memcpy(slots + s * slot_bytes, keys[0], 3);
    const int present = 6; /* the first six keys are stored; the last two are absent */
    for (int i = 0; i < present; i++) {
        uint64_t s = hvq_psh_slot(data, m, r, keys[i][0], keys[i][1], keys[i][2]);
        memcpy(slots + s * slot_bytes, keys[i], 3);
        slots[s * slot_bytes + 3] = (uint8_t)(10 + i);
    }
    int ref[8], got[8];
    for (int i = 0; i < 8; i++) {
        const uint8_t *v = hvq_psh_find(data, m, r, slot_bytes, keys[i][0], keys[i][1], keys[i][2]);
        ref[i] = v ? v[0] : -1;
        CHECK(ref[i] == (i < present ? 10 + i : -1), "wide offsets, C: key %d gives %d", i,
              ref[i]);
    }
    cl_int e1, e2, e3;
    cl_mem dbuf = clCreateBuffer(env->ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, (size_t)bytes,
                                 data, &e1);
    cl_mem kbuf = clCreateBuffer(env->ctx, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof keys,
                                 (void *)keys, &e2);
    cl_mem obuf = clCreateBuffer(env->ctx, CL_MEM_WRITE_ONLY, sizeof got, NULL, &e3);
    int ok = e1 == CL_SUCCESS && e2 == CL_SUCCESS && e3 == CL_SUCCESS;
    CHECK(ok, "clCreateBuffer: %d %d %d", e1, e2, e3);
    cl_uint args[3] = {m, r, slot_bytes};
    cl_ulong nbytes = bytes;
    if (ok) {
        SET_ARG(env->find_keys, "hvq_find_keys", 0, sizeof dbuf, &dbuf);
        SET_ARG(env->find_keys, "hvq_find_keys", 1, sizeof nbytes, &nbytes);
        for (int a = 0; a < 3; a++)
            SET_ARG(env->find_keys, "hvq_find_keys", 2 + a, sizeof args[a], &args[a]);
        SET_ARG(env->find_keys, "hvq_find_keys", 5, sizeof kbuf, &kbuf);
        SET_ARG(env->find_keys, "hvq_find_keys", 6, sizeof obuf, &obuf);
    }
    size_t n = 8;
    if (ok) {
        cl_int e = clEnqueueNDRangeKernel(env->q, env->find_keys, 1, NULL, &n, NULL, 0, NULL, NULL);
        if (e == CL_SUCCESS)
            e = clEnqueueReadBuffer(env->q, obuf, CL_TRUE, 0, sizeof got, got, 0, NULL, NULL);
        CHECK(e == CL_SUCCESS, "hvq_find_keys: %d", e);
        if (e == CL_SUCCESS)
            CHECK(memcmp(got, ref, sizeof ref) == 0, "wide offsets: device and C disagree");
    }
    if (dbuf)
        clReleaseMemObject(dbuf);
    if (kbuf)
        clReleaseMemObject(kbuf);
    if (obuf)
        clReleaseMemObject(obuf);
    free(data);
}

int main(void)
{
    cl_env env;
    memset(&env, 0, sizeof env);
    int rc = env_open(&env);
    if (rc == 77) {
        return check_opencl_unavailable("no OpenCL platform or device");
    }
    if (rc == 0) {
        hard_cases(&env);
        random_volumes(&env);
        colin27_crop(&env);
        wide_offsets(&env);
    }
    env_close(&env);
    return check_finish();
}

#else
CHECK_SKIPPED_MAIN("built without OpenCL")
#endif
