/* tests/test_cl_device.c - device choice (CDVR_CL_DEVICE), the on-disk program cache (cold,
 * warm, corrupt, stale), kernel build failures reporting the build log, and a missing kernel
 * directory; the buffers of gathered frame copies (cdvr_cl_ensure_gathered: on a CPU device,
 * from a huge page up, host memory of our own marked for huge pages). Uses a private cache
 * directory and private kernel copies under the build dir. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/device.h"
#include "cdvr/memory.h"
#include "check.h"

#if CDVR_HAVE_OPENCL
#include "render/cl/cl_internal.h" /* cdvr_cl_ensure_gathered */

static cdvr_status open_with(const char *device, cdvr_cl **cl, cdvr_error *err)
{
    if (device)
        setenv("CDVR_CL_DEVICE", device, 1);
    else
        unsetenv("CDVR_CL_DEVICE");
    return cdvr_cl_open(cl, err);
}

static void device_choice(void)
{
    cdvr_cl *cl = NULL;
    cdvr_error err;
    cdvr_status st = open_with("none", &cl, &err);
    CHECK(st == CDVR_ERR_DEVICE && cl == NULL && strstr(err.msg, "CDVR_CL_DEVICE=none"),
          "none: %s", err.msg);
    st = open_with("0:0", &cl, &err);
    CHECK_OK(st, err);
    char name[128] = "";
    if (!st) {
        snprintf(name, sizeof name, "%s", cdvr_cl_device_name(cl));
        CHECK(cdvr_cl_get_info(cl)->platform_index == 0 && cdvr_cl_get_info(cl)->device_index == 0,
              "0:0 picked another device");
        cdvr_cl_close(cl);
    }
    st = open_with("77:3", &cl, &err);
    CHECK(st == CDVR_ERR_DEVICE && strstr(err.msg, "77:3"), "bad index: %s", err.msg);
    st = open_with("no-such-device-xyz", &cl, &err);
    CHECK(st == CDVR_ERR_DEVICE && strstr(err.msg, "no matching"), "bad name: %s", err.msg);
    /* a substring of the real name, in other case, finds it */
    char sub[8] = "";
    for (int i = 0; i < 4 && name[i]; i++)
        sub[i] = (char)(name[i] >= 'a' && name[i] <= 'z' ? name[i] - 32 : name[i]);
    st = open_with(sub, &cl, &err);
    CHECK(st == CDVR_OK && !strcmp(cdvr_cl_device_name(cl), name), "name '%s': %s", sub, err.msg);
    cdvr_cl_close(cl);
    st = open_with(NULL, &cl, &err);
    CHECK_OK(st, err);
    if (!st) {
        const cdvr_cl_info *info = cdvr_cl_get_info(cl);
        printf("default device: %s (%s) on %s, %u compute units\n", info->device,
               info->is_gpu ? "gpu" : "cpu", info->platform, info->compute_units);
        CHECK(info->platform[0] && info->driver_version[0], "info fields empty");
        cdvr_cl_close(cl);
    }
}

static void copy_file(const char *from, const char *to)
{
    FILE *in = fopen(from, "rb"), *out = fopen(to, "wb");
    CHECK(in && out, "copy %s -> %s", from, to);
    char buf[4096];
    size_t n;
    while (in && out && (n = fread(buf, 1, sizeof buf, in)) > 0)
        fwrite(buf, 1, n, out);
    if (in)
        fclose(in);
    if (out)
        fclose(out);
}

static void write_text(const char *path, const char *mode, const char *text)
{
    FILE *f = fopen(path, mode);
    CHECK(f != NULL, "cannot write %s", path);
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

static void corrupt(const char *path)
{
    FILE *f = fopen(path, "r+b");
    CHECK(f != NULL, "cannot open cache file %s", path);
    if (!f)
        return;
    fseek(f, 100, SEEK_SET);
    unsigned char junk[64];
    memset(junk, 0x5A, sizeof junk);
    fwrite(junk, 1, sizeof junk, f);
    fclose(f);
}

/* Opens with the private kernels; checks where the program came from. */
static void open_expect_cache(int expect_cached, const char *what, char *cache_path, size_t n)
{
    cdvr_cl *cl;
    cdvr_error err;
    cdvr_status st = open_with(NULL, &cl, &err);
    CHECK(st == CDVR_OK, "%s: %s", what, err.msg);
    if (st)
        return;
    const cdvr_cl_info *info = cdvr_cl_get_info(cl);
    printf("%-34s build %.3f s, from cache %d\n", what, info->build_seconds, info->from_cache);
    CHECK(info->from_cache == expect_cached, "%s: from_cache %d", what, info->from_cache);
    CHECK(info->cache_path[0] && access(info->cache_path, R_OK) == 0, "%s: no cache file '%s'",
          what, info->cache_path);
    snprintf(cache_path, n, "%s", info->cache_path);
    cdvr_cl_close(cl);
}

static void cache_and_build(const char *src_kernels, const char *work)
{
    char kdir[700], cdir[700], path[800], from[800], cache_path[512] = "";
    snprintf(kdir, sizeof kdir, "%s/kernels", work);
    snprintf(cdir, sizeof cdir, "%s/cache", work);
    char cmd[2400];
    snprintf(cmd, sizeof cmd, "rm -rf '%s' && mkdir -p '%s/common' '%s/render'", work, kdir, kdir);
    CHECK(system(cmd) == 0, "%s", cmd);
    const char *files[] = {"common/cl_shared.h", "render/bricks.cl", "render/raycast.cl"};
    for (int i = 0; i < 3; i++) {
        snprintf(from, sizeof from, "%s/%s", src_kernels, files[i]);
        snprintf(path, sizeof path, "%s/%s", kdir, files[i]);
        copy_file(from, path);
    }
    /* a unique comment makes the source (and so the cache key) new to every run */
    snprintf(path, sizeof path, "%s/render/raycast.cl", kdir);
    char stamp[64];
    snprintf(stamp, sizeof stamp, "\n/* test stamp %ld */\n", (long)getpid());
    write_text(path, "a", stamp);
    setenv("CDVR_KERNELS", kdir, 1);
    setenv("CDVR_CACHE_DIR", cdir, 1);
    open_expect_cache(0, "cold (compile)", cache_path, sizeof cache_path);
    open_expect_cache(1, "warm (cached binary)", cache_path, sizeof cache_path);
    corrupt(cache_path);
    open_expect_cache(0, "corrupt cache entry (rebuilt)", cache_path, sizeof cache_path);
    open_expect_cache(1, "after rebuild (cached again)", cache_path, sizeof cache_path);
    write_text(cache_path, "w", "CDVRCLB1 short");
    open_expect_cache(0, "truncated cache entry (rebuilt)", cache_path, sizeof cache_path);
    /* a changed source has a new key: the old entry is stale and not used */
    write_text(path, "a", "/* changed */\n");
    char old_path[512];
    snprintf(old_path, sizeof old_path, "%s", cache_path);
    open_expect_cache(0, "changed source (new key)", cache_path, sizeof cache_path);
    CHECK(strcmp(old_path, cache_path) != 0, "changed source kept the cache key");

    /* a syntax error: the message carries the compiler's build log */
    write_text(path, "a", "__kernel void broken(__global int *p) { p[0] = undefined_name_q; }\n");
    cdvr_cl *cl = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_cl_open(&cl, &err);
    CHECK(st == CDVR_ERR_DEVICE && cl == NULL && strstr(err.msg, "CL_BUILD_PROGRAM_FAILURE") &&
              strstr(err.msg, "undefined_name_q"),
          "build failure message: %s", err.msg);
    printf("build failure: %.160s...\n", err.msg);
    /* a missing kernel file is named */
    snprintf(path, sizeof path, "%s/render/bricks.cl", kdir);
    remove(path);
    st = cdvr_cl_open(&cl, &err);
    CHECK(st == CDVR_ERR_IO && strstr(err.msg, "bricks.cl"), "missing kernel: %s", err.msg);
    unsetenv("CDVR_KERNELS");
    unsetenv("CDVR_CACHE_DIR");
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", work);
    CHECK(system(cmd) == 0, "%s", cmd);
}

/* Whether the system backs MADV_HUGEPAGE ranges with huge pages ("always" or "madvise") and
 * CDVR_HUGE_PAGES=0 does not turn them off. */
static int huge_pages_on(void)
{
    const char *env = getenv("CDVR_HUGE_PAGES");
    if (env && strcmp(env, "0") == 0)
        return 0;
    FILE *f = fopen("/sys/kernel/mm/transparent_hugepage/enabled", "r");
    char line[128] = "";
    if (f) {
        if (!fgets(line, sizeof line, f))
            line[0] = 0;
        fclose(f);
    }
    return strstr(line, "[always]") || strstr(line, "[madvise]");
}

/* A gathered copy's buffer holds what is written to it, grows and keeps its capacity like
 * any other; on a CPU device one of a huge page or more lies in our own storage, aligned to a
 * huge page and (where the system has them) marked for them; smaller ones and GPU buffers are
 * the driver's. Releasing frees the storage (the sanitizer build's leak check). */
static void gathered_buffers(void)
{
    cdvr_cl *cl = NULL;
    cdvr_error err;
    if (open_with(NULL, &cl, &err) != CDVR_OK)
        return;
    cl_mem mem = NULL;
    size_t cap = 0, small = 4096, big = CDVR_HUGE_PAGE_BYTES * 3 / 2;
    const char *what = "test copy";
    cdvr_status st = cdvr_cl_ensure_gathered(cl, &mem, &cap, small, what, &err);
    CHECK_OK(st, err);
    void *host = NULL;
    CHECK(mem && clGetMemObjectInfo(mem, CL_MEM_HOST_PTR, sizeof host, &host, NULL) ==
                     CL_SUCCESS && !host && cap == small,
          "a page-sized copy is the driver's buffer (host %p, capacity %zu)", host, cap);
    st = cdvr_cl_ensure_gathered(cl, &mem, &cap, big, what, &err);
    CHECK_OK(st, err);
    CHECK(cap == big, "capacity %zu after growing to %zu", cap, big);
    host = NULL;
    CHECK(mem && clGetMemObjectInfo(mem, CL_MEM_HOST_PTR, sizeof host, &host, NULL) ==
                     CL_SUCCESS, "CL_MEM_HOST_PTR");
    if (cl->info.is_gpu) {
        CHECK(host == NULL, "a GPU's copy is the driver's buffer (host %p)", host);
    } else {
        CHECK(host && (uintptr_t)host % CDVR_HUGE_PAGE_BYTES == 0,
              "a CPU device's copy of %zu bytes in huge-page aligned storage (host %p)", big,
              host);
        if (host && huge_pages_on())
            CHECK(cdvr_on_huge_pages(host) != 0, "the copy's storage is marked for huge pages");
    }
    enum { N = 1000 };
    uint32_t in[N], out[N];
    for (uint32_t i = 0; i < N; i++)
        in[i] = i * 2654435761u;
    size_t at = big - sizeof in;
    cl_int code = clEnqueueWriteBuffer(cl->queue, mem, CL_TRUE, at, sizeof in, in, 0, NULL, NULL);
    if (code == CL_SUCCESS)
        code = clEnqueueReadBuffer(cl->queue, mem, CL_TRUE, at, sizeof out, out, 0, NULL, NULL);
    CHECK(code == CL_SUCCESS && memcmp(in, out, sizeof in) == 0,
          "the copy's last bytes read back as written (%s)", cdvr_cl_error_name(code));
    const cl_mem before = mem;
    st = cdvr_cl_ensure_gathered(cl, &mem, &cap, small, what, &err);
    CHECK(st == CDVR_OK && mem == before && cap == big, "a smaller request keeps the buffer");
    cdvr_cl_release(&mem);
    CHECK(mem == NULL, "released");
    st = cdvr_cl_ensure_gathered(cl, &mem, &cap, (size_t)cl->info.max_alloc_bytes + 1, what,
                                 &err);
    CHECK(st == CDVR_ERR_NOMEM && mem == NULL && strstr(err.msg, what),
          "over the device's largest buffer: %s", err.msg);
    cdvr_cl_close(cl);
}

int main(void)
{
    cdvr_cl *cl;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        return check_opencl_unavailable(err.msg);
    }
    cdvr_cl_close(cl);
    device_choice();
    gathered_buffers();
    const char *src = getenv("CDVR_SOURCE_DIR"), *bin = getenv("CDVR_BINARY_DIR");
    char kernels[600], work[600];
    snprintf(kernels, sizeof kernels, "%s/kernels", src ? src : "..");
    snprintf(work, sizeof work, "%s/test_cl_device.tmp", bin ? bin : ".");
    cache_and_build(kernels, work);
    return check_finish();
}

#else
CHECK_SKIPPED_MAIN("built without OpenCL")
#endif
