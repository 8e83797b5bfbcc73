/* core/render/cl/cl_device.c - OpenCL device choice, program build with an on-disk binary cache. */
#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "cdvr/cache.h"
#include "cdvr/memory.h"
#include "cdvr/timing.h"
#include "cl_internal.h"

#define MAX_PLATFORMS 16
#define MAX_DEVICES 32
#define BUILD_OPTIONS "-cl-std=CL1.2"

/* The render kernels (after kernels/common/cl_shared.h and, for a fetch-mode codec, its
 * source). */
static const char *const render_files[] = {"render/bricks.cl", "render/raycast.cl"};
#define NRENDER_FILES (sizeof render_files / sizeof *render_files)

const char *cdvr_cl_error_name(cl_int code)
{
    switch (code) {
#define NAME(c) case c: return #c
    NAME(CL_SUCCESS); NAME(CL_DEVICE_NOT_FOUND); NAME(CL_DEVICE_NOT_AVAILABLE);
    NAME(CL_COMPILER_NOT_AVAILABLE); NAME(CL_MEM_OBJECT_ALLOCATION_FAILURE);
    NAME(CL_OUT_OF_RESOURCES); NAME(CL_OUT_OF_HOST_MEMORY);
    NAME(CL_PROFILING_INFO_NOT_AVAILABLE); NAME(CL_MEM_COPY_OVERLAP);
    NAME(CL_IMAGE_FORMAT_MISMATCH); NAME(CL_IMAGE_FORMAT_NOT_SUPPORTED);
    NAME(CL_BUILD_PROGRAM_FAILURE); NAME(CL_MAP_FAILURE); NAME(CL_MISALIGNED_SUB_BUFFER_OFFSET);
    NAME(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST); NAME(CL_COMPILE_PROGRAM_FAILURE);
    NAME(CL_LINKER_NOT_AVAILABLE); NAME(CL_LINK_PROGRAM_FAILURE);
    NAME(CL_DEVICE_PARTITION_FAILED); NAME(CL_KERNEL_ARG_INFO_NOT_AVAILABLE);
    NAME(CL_INVALID_VALUE); NAME(CL_INVALID_DEVICE_TYPE); NAME(CL_INVALID_PLATFORM);
    NAME(CL_INVALID_DEVICE); NAME(CL_INVALID_CONTEXT); NAME(CL_INVALID_QUEUE_PROPERTIES);
    NAME(CL_INVALID_COMMAND_QUEUE); NAME(CL_INVALID_HOST_PTR); NAME(CL_INVALID_MEM_OBJECT);
    NAME(CL_INVALID_IMAGE_FORMAT_DESCRIPTOR); NAME(CL_INVALID_IMAGE_SIZE);
    NAME(CL_INVALID_SAMPLER); NAME(CL_INVALID_BINARY); NAME(CL_INVALID_BUILD_OPTIONS);
    NAME(CL_INVALID_PROGRAM); NAME(CL_INVALID_PROGRAM_EXECUTABLE);
    NAME(CL_INVALID_KERNEL_NAME); NAME(CL_INVALID_KERNEL_DEFINITION); NAME(CL_INVALID_KERNEL);
    NAME(CL_INVALID_ARG_INDEX); NAME(CL_INVALID_ARG_VALUE); NAME(CL_INVALID_ARG_SIZE);
    NAME(CL_INVALID_KERNEL_ARGS); NAME(CL_INVALID_WORK_DIMENSION);
    NAME(CL_INVALID_WORK_GROUP_SIZE); NAME(CL_INVALID_WORK_ITEM_SIZE);
    NAME(CL_INVALID_GLOBAL_OFFSET); NAME(CL_INVALID_EVENT_WAIT_LIST); NAME(CL_INVALID_EVENT);
    NAME(CL_INVALID_OPERATION); NAME(CL_INVALID_GL_OBJECT); NAME(CL_INVALID_BUFFER_SIZE);
    NAME(CL_INVALID_MIP_LEVEL); NAME(CL_INVALID_GLOBAL_WORK_SIZE); NAME(CL_INVALID_PROPERTY);
    NAME(CL_INVALID_IMAGE_DESCRIPTOR); NAME(CL_INVALID_COMPILER_OPTIONS);
    NAME(CL_INVALID_LINKER_OPTIONS); NAME(CL_INVALID_DEVICE_PARTITION_COUNT);
#undef NAME
    case -1001: return "CL_PLATFORM_NOT_FOUND_KHR";
    default: return "unknown OpenCL error";
    }
}

cdvr_status cdvr_cl_check(cl_int code, const char *what, cdvr_error *err)
{
    if (code == CL_SUCCESS)
        return CDVR_OK;
    return cdvr_error_set(err, CDVR_ERR_DEVICE, "OpenCL: %s: %s (%d)", what,
                          cdvr_cl_error_name(code), (int)code);
}

void cdvr_cl_release(cl_mem *mem)
{
    if (*mem)
        clReleaseMemObject(*mem);
    *mem = NULL;
}

static void CL_CALLBACK free_host_storage(cl_mem mem, void *storage)
{
    (void)mem;
    free(storage);
}

/* On a CPU device: a buffer in host memory of our own, from a huge page up marked for huge
 * pages (cdvr/memory.h), freed when the buffer is. PoCL's own allocations have 4 KiB pages. */
static cdvr_status create_on_huge_pages(cdvr_cl *cl, cl_mem *mem, size_t bytes,
                                        cl_mem_flags flags, const char *what, cdvr_error *err)
{
    void *storage = cdvr_alloc_large(bytes, 0);
    if (!storage)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL: %s: %zu bytes of host memory for "
                              "%s", what, bytes, cl->info.device);
    cl_int code;
    *mem = clCreateBuffer(cl->context, flags | CL_MEM_USE_HOST_PTR, bytes, storage, &code);
    if (code == CL_SUCCESS)
        code = clSetMemObjectDestructorCallback(*mem, free_host_storage, storage);
    if (code != CL_SUCCESS) {
        cdvr_cl_release(mem);
        free(storage);
        return cdvr_cl_check(code, what, err);
    }
    return CDVR_OK;
}

/* cdvr_cl_ensure_buffer; on_huge_pages: from a huge page up in our own huge-page storage. */
static cdvr_status ensure(cdvr_cl *cl, cl_mem *mem, size_t *capacity, size_t bytes,
                          cl_mem_flags flags, int on_huge_pages, const char *what,
                          cdvr_error *err)
{
    if (*mem && *capacity >= bytes)
        return CDVR_OK;
    cdvr_cl_release(mem);
    *capacity = 0;
    if (bytes > cl->info.max_alloc_bytes)
        return cdvr_error_set(err, CDVR_ERR_NOMEM,
                              "OpenCL: %s: %zu bytes exceed the device's largest buffer (%llu) on %s",
                              what, bytes, (unsigned long long)cl->info.max_alloc_bytes,
                              cl->info.device);
    cdvr_status st = CDVR_OK;
    if (on_huge_pages && bytes >= CDVR_HUGE_PAGE_BYTES) {
        st = create_on_huge_pages(cl, mem, bytes, flags, what, err);
    } else {
        cl_int code;
        *mem = clCreateBuffer(cl->context, flags, bytes ? bytes : 1, NULL, &code);
        if (code != CL_SUCCESS) {
            *mem = NULL;
            st = cdvr_cl_check(code, what, err);
        }
    }
    if (st == CDVR_OK)
        *capacity = bytes;
    return st;
}

cdvr_status cdvr_cl_ensure_buffer(cdvr_cl *cl, cl_mem *mem, size_t *capacity, size_t bytes,
                                  cl_mem_flags flags, const char *what, cdvr_error *err)
{
    return ensure(cl, mem, capacity, bytes, flags, 0, what, err);
}

cdvr_status cdvr_cl_ensure_gathered(cdvr_cl *cl, cl_mem *mem, size_t *capacity, size_t bytes,
                                    const char *what, cdvr_error *err)
{
    return ensure(cl, mem, capacity, bytes, CL_MEM_READ_WRITE, !cl->info.is_gpu, what, err);
}

/* ---- device choice ---------------------------------------------------------------------- */

typedef struct device_list {
    cl_platform_id platforms[MAX_PLATFORMS];
    cl_uint nplatforms;
    cl_device_id devices[MAX_PLATFORMS][MAX_DEVICES];
    cl_uint ndevices[MAX_PLATFORMS];
} device_list;

static cdvr_status list_devices(device_list *list, cdvr_error *err)
{
    cl_int code = clGetPlatformIDs(MAX_PLATFORMS, list->platforms, &list->nplatforms);
    if (code == -1001 || (code == CL_SUCCESS && list->nplatforms == 0))
        return cdvr_error_set(err, CDVR_ERR_DEVICE,
                              "OpenCL: no platform found (no ICD installed?); use device=\"cpu\"");
    if (cdvr_cl_check(code, "clGetPlatformIDs", err))
        return CDVR_ERR_DEVICE;
    if (list->nplatforms > MAX_PLATFORMS)
        list->nplatforms = MAX_PLATFORMS;
    for (cl_uint p = 0; p < list->nplatforms; p++) {
        code = clGetDeviceIDs(list->platforms[p], CL_DEVICE_TYPE_ALL, MAX_DEVICES,
                              list->devices[p], &list->ndevices[p]);
        if (code != CL_SUCCESS)
            list->ndevices[p] = 0;
        if (list->ndevices[p] > MAX_DEVICES)
            list->ndevices[p] = MAX_DEVICES;
    }
    return CDVR_OK;
}

static cl_device_type device_type(cl_device_id dev)
{
    cl_device_type type = 0;
    clGetDeviceInfo(dev, CL_DEVICE_TYPE, sizeof type, &type, NULL);
    return type;
}

static int contains_nocase(const char *hay, const char *needle)
{
    size_t n = strlen(needle);
    for (; *hay; hay++) {
        size_t i = 0;
        while (i < n && hay[i] && tolower((unsigned char)hay[i]) == tolower((unsigned char)needle[i]))
            i++;
        if (i == n)
            return 1;
    }
    return n == 0;
}

/* Finds the first device of `type` (0 = any) whose name contains `name` (NULL = any). */
static int find_device(const device_list *list, cl_device_type type, const char *name, int *pi,
                       int *di)
{
    for (cl_uint p = 0; p < list->nplatforms; p++)
        for (cl_uint d = 0; d < list->ndevices[p]; d++) {
            cl_device_id dev = list->devices[p][d];
            if (type && !(device_type(dev) & type))
                continue;
            if (name) {
                char devname[256] = "";
                clGetDeviceInfo(dev, CL_DEVICE_NAME, sizeof devname - 1, devname, NULL);
                if (!contains_nocase(devname, name))
                    continue;
            }
            *pi = (int)p;
            *di = (int)d;
            return 1;
        }
    return 0;
}

static cdvr_status choose_device(const device_list *list, const char *want, int *pi, int *di,
                                 cdvr_error *err)
{
    int p, d;
    char extra;
    if (!want || !*want) {
        if (find_device(list, CL_DEVICE_TYPE_GPU, NULL, pi, di) ||
            find_device(list, CL_DEVICE_TYPE_CPU, NULL, pi, di) || find_device(list, 0, NULL, pi, di))
            return CDVR_OK;
        return cdvr_error_set(err, CDVR_ERR_DEVICE, "OpenCL: no device on %u platform(s)",
                              (unsigned)list->nplatforms);
    }
    if (sscanf(want, "%d:%d%c", &p, &d, &extra) == 2) {
        if (p < 0 || (cl_uint)p >= list->nplatforms || d < 0 || (cl_uint)d >= list->ndevices[p])
            return cdvr_error_set(err, CDVR_ERR_DEVICE,
                                  "OpenCL: CDVR_CL_DEVICE=%s: no such platform:device (see clinfo -l)",
                                  want);
        *pi = p;
        *di = d;
        return CDVR_OK;
    }
    int found;
    if (!strcmp(want, "gpu"))
        found = find_device(list, CL_DEVICE_TYPE_GPU, NULL, pi, di);
    else if (!strcmp(want, "cpu"))
        found = find_device(list, CL_DEVICE_TYPE_CPU, NULL, pi, di);
    else
        found = find_device(list, 0, want, pi, di);
    if (!found)
        return cdvr_error_set(err, CDVR_ERR_DEVICE, "OpenCL: CDVR_CL_DEVICE=%s: no matching device",
                              want);
    return CDVR_OK;
}

static void fill_info(cdvr_cl *cl, int pi, int di)
{
    cdvr_cl_info *info = &cl->info;
    cl_uint units = 0;
    cl_ulong mem = 0, alloc = 0;
    clGetPlatformInfo(cl->platform, CL_PLATFORM_NAME, sizeof info->platform - 1, info->platform, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_NAME, sizeof info->device - 1, info->device, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_VERSION, sizeof info->device_version - 1,
                    info->device_version, NULL);
    clGetDeviceInfo(cl->device, CL_DRIVER_VERSION, sizeof info->driver_version - 1,
                    info->driver_version, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_MAX_COMPUTE_UNITS, sizeof units, &units, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_GLOBAL_MEM_SIZE, sizeof mem, &mem, NULL);
    clGetDeviceInfo(cl->device, CL_DEVICE_MAX_MEM_ALLOC_SIZE, sizeof alloc, &alloc, NULL);
    info->is_gpu = (device_type(cl->device) & CL_DEVICE_TYPE_GPU) != 0;
    info->compute_units = units;
    info->global_mem_bytes = mem;
    info->max_alloc_bytes = alloc;
    info->platform_index = pi;
    info->device_index = di;
}

/* ---- kernel sources and the binary cache ------------------------------------------------ */

static cdvr_status read_file(const char *path, char **text, size_t *len, cdvr_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open kernel source: %s", path,
                              strerror(errno));
    char *buf = NULL;
    size_t used = 0, cap = 0, got;
    char chunk[8192];
    while ((got = fread(chunk, 1, sizeof chunk, f)) > 0) {
        if (used + got + 1 > cap) {
            cap = (used + got + 1) * 2;
            char *grown = realloc(buf, cap);
            if (!grown) {
                free(buf);
                fclose(f);
                return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
            }
            buf = grown;
        }
        memcpy(buf + used, chunk, got);
        used += got;
    }
    int failed = ferror(f);
    fclose(f);
    if (failed || !buf) {
        free(buf);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot read kernel source", path);
    }
    buf[used] = '\0';
    *text = buf;
    *len = used;
    return CDVR_OK;
}

static const char *kernel_dir(void)
{
    const char *dir = getenv("CDVR_KERNELS");
    return dir && *dir ? dir : CDVR_KERNEL_DIR;
}

/* Appends text (len bytes) and a newline to *all (*total bytes so far). */
static cdvr_status append_text(char **all, size_t *total, const char *text, size_t len,
                               const char *what, cdvr_error *err)
{
    char *grown = realloc(*all, *total + len + 2);
    if (!grown)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", what);
    *all = grown;
    memcpy(*all + *total, text, len);
    *total += len;
    (*all)[(*total)++] = '\n';
    (*all)[*total] = '\0';
    return CDVR_OK;
}

static cdvr_status append_file(char **all, size_t *total, const char *name, cdvr_error *err)
{
    char path[1024];
    char *text = NULL;
    size_t len = 0;
    snprintf(path, sizeof path, "%s/%s", kernel_dir(), name);
    cdvr_status st = read_file(path, &text, &len, err);
    if (!st)
        st = append_text(all, total, text, len, path, err);
    free(text);
    return st;
}

/* Program source: the shared header, then (optionally) a codec's source, then the given
 * render files. */
static cdvr_status load_sources(const cdvr_codec *codec, const char *const *files, size_t nfiles,
                                char **out, cdvr_error *err)
{
    char *all = NULL;
    size_t total = 0;
    cdvr_status st = append_file(&all, &total, "common/cl_shared.h", err);
    if (!st && codec && codec->cl_source)
        st = append_text(&all, &total, codec->cl_source, strlen(codec->cl_source),
                         codec->name, err);
    else if (!st && codec)
        st = append_file(&all, &total, codec->cl_file, err);
    for (size_t i = 0; !st && i < nfiles; i++)
        st = append_file(&all, &total, files[i], err);
    if (st) {
        free(all);
        return st;
    }
    *out = all;
    return CDVR_OK;
}

/* The cache key of something built or measured for this device. */
static void cache_key(const cdvr_cl *cl, const char *source, const char *options, char key[33])
{
    const char *parts[] = {source, options, cl->info.device, cl->info.driver_version,
                           cl->info.platform, cl->info.device_version};
    cdvr_cache_key(parts, sizeof parts / sizeof *parts, key);
}

static unsigned char *program_binary(cl_program prog, cl_device_id dev, size_t *size)
{
    cl_uint ndev = 0;
    if (clGetProgramInfo(prog, CL_PROGRAM_NUM_DEVICES, sizeof ndev, &ndev, NULL) || ndev != 1)
        return NULL;
    (void)dev;
    if (clGetProgramInfo(prog, CL_PROGRAM_BINARY_SIZES, sizeof *size, size, NULL) || *size == 0)
        return NULL;
    unsigned char *bin = malloc(*size);
    if (bin && clGetProgramInfo(prog, CL_PROGRAM_BINARIES, sizeof bin, &bin, NULL)) {
        free(bin);
        bin = NULL;
    }
    return bin;
}

static cdvr_status build_error(cdvr_cl *cl, cl_program prog, cl_int code, const char *what,
                               cdvr_error *err)
{
    /* the whole build log, cut only where the message itself ends */
    size_t len = 0;
    clGetProgramBuildInfo(prog, cl->device, CL_PROGRAM_BUILD_LOG, 0, NULL, &len);
    char *log = len ? malloc(len + 1) : NULL;
    if (log && clGetProgramBuildInfo(prog, cl->device, CL_PROGRAM_BUILD_LOG, len, log, NULL))
        log[0] = '\0';
    if (log)
        log[len] = '\0';
    cdvr_status st = cdvr_error_set(err, CDVR_ERR_DEVICE, "OpenCL: building %s for %s: %s (%d): "
                                    "%s", what, cl->info.device, cdvr_cl_error_name(code),
                                    (int)code, log ? log : "(no build log)");
    if (log && (!err || strlen(log) > sizeof err->msg / 2))
        fprintf(stderr, "cdvr: OpenCL build log of %s:\n%s\n", what, log);
    free(log);
    return st;
}

static cl_program program_from_binary(cdvr_cl *cl, const unsigned char *bin, size_t size,
                                      const char *options)
{
    cl_int status = CL_SUCCESS, code;
    cl_program prog = clCreateProgramWithBinary(cl->context, 1, &cl->device, &size, &bin,
                                                &status, &code);
    if (code != CL_SUCCESS || status != CL_SUCCESS)
        return NULL;
    if (clBuildProgram(prog, 1, &cl->device, options, NULL, NULL) != CL_SUCCESS) {
        clReleaseProgram(prog);
        return NULL;
    }
    return prog;
}

/* Builds source with options, from the on-disk binary cache when it holds it. */
static cdvr_status build_cached(cdvr_cl *cl, const char *source, const char *options,
                                const char *what, cl_program *out, int *from_cache,
                                char *cache_path, size_t cache_path_size, cdvr_error *err)
{
    char key[33];
    cache_key(cl, source, options, key);
    if (!cdvr_cache_path(key, "clbin", cache_path, cache_path_size))
        cache_path[0] = '\0';
    size_t size = 0;
    unsigned char *bin = cache_path[0] ? cdvr_cache_load(cache_path, key, &size) : NULL;
    *out = NULL;
    if (bin) {
        *out = program_from_binary(cl, bin, size, options);
        free(bin);
    }
    *from_cache = *out != NULL;
    if (*out)
        return CDVR_OK;
    cl_int code;
    cl_program prog = clCreateProgramWithSource(cl->context, 1, &source, NULL, &code);
    if (code != CL_SUCCESS)
        return cdvr_cl_check(code, "clCreateProgramWithSource", err);
    code = clBuildProgram(prog, 1, &cl->device, options, NULL, NULL);
    if (code != CL_SUCCESS) {
        cdvr_status st = build_error(cl, prog, code, what, err);
        clReleaseProgram(prog);
        return st;
    }
    bin = cache_path[0] ? program_binary(prog, cl->device, &size) : NULL;
    if (bin)
        cdvr_cache_store(cache_path, key, bin, size);
    free(bin);
    *out = prog;
    return CDVR_OK;
}

static cdvr_status build_program(cdvr_cl *cl, cdvr_error *err)
{
    double start = cdvr_now_ms();
    char *source = NULL;
    cdvr_status st = load_sources(NULL, render_files, NRENDER_FILES, &source, err);
    if (st)
        return st;
    st = build_cached(cl, source, BUILD_OPTIONS, "the render kernels", &cl->program,
                      &cl->info.from_cache, cl->info.cache_path, sizeof cl->info.cache_path, err);
    free(source);
    cl->info.build_seconds = (cdvr_now_ms() - start) / 1e3;
    return st;
}

static cdvr_status create_kernel(cl_program program, const char *name, cl_kernel *out,
                                 cdvr_error *err);

cdvr_status cdvr_cl_long_index_kernels(cdvr_cl *cl, cl_kernel *bricks, cl_kernel *raycast,
                                       cdvr_error *err)
{
    if (!cl->program_long) {
        char *source = NULL, cache_path[512];
        int from_cache;
        cdvr_status st = load_sources(NULL, render_files, NRENDER_FILES, &source, err);
        if (!st)
            st = build_cached(cl, source, BUILD_OPTIONS " -DCDVR_LONG_INDEX",
                              "the render kernels (64-bit indices)", &cl->program_long,
                              &from_cache, cache_path, sizeof cache_path, err);
        free(source);
        if (!st)
            st = create_kernel(cl->program_long, "brick_minmax", &cl->k_bricks_long, err);
        if (!st)
            st = create_kernel(cl->program_long, "raycast", &cl->k_raycast_long, err);
        if (st)
            return st;
    }
    *bricks = cl->k_bricks_long;
    *raycast = cl->k_raycast_long;
    return CDVR_OK;
}

/* ---- remembered decode and fetch paths, and the frame layout ------------------------------
 * One cache entry per device, codec, kind ("decode" or "fetch") and size class, in the
 * program cache's format, holding the text "NAME A_MS B_MS": for decode "host|kernel
 * KERNEL_MS HOST_MS", for fetch "sample|bulk SAMPLE_MS BULK_MS". Its key covers the codec's
 * kernel source, the device and its driver, and the cdvr version (whose C decoder was
 * measured). The layout (no codec: the render kernels' source) is "layout", size class 0:
 * "dense|tiled DENSE_MS TILED_MS". */

static int choice_path(cdvr_cl *cl, const cdvr_codec *codec, const char *kind,
                       unsigned size_class, char *path, size_t n, char key[33])
{
    char what[96], *source = NULL;
    if ((codec ? load_sources(codec, NULL, 0, &source, NULL)
               : load_sources(NULL, render_files, NRENDER_FILES, &source, NULL)) != CDVR_OK)
        return 0;
    /* the rules' shares too: a record made under another rule is measured again */
    snprintf(what, sizeof what, "%s path, size class %u, cdvr %s, shares %g %g, probes %d",
             kind, size_class, CDVR_VERSION, CDVR_CL_DENSE_SHARE, CDVR_CL_QUADS_SHARE,
             CDVR_CL_PROBES_REVISION);
    cache_key(cl, source, what, key);
    free(source);
    return cdvr_cache_path(key, kind, path, n);
}

/* The remembered choice's name (empty when none) and its two times. */
static void load_choice(cdvr_cl *cl, const cdvr_codec *codec, const char *kind,
                        unsigned size_class, char which[8], double *a_ms, double *b_ms)
{
    char path[512], key[33], text[64];
    size_t size = 0;
    which[0] = '\0';
    if (!choice_path(cl, codec, kind, size_class, path, sizeof path, key))
        return;
    unsigned char *bin = cdvr_cache_load(path, key, &size);
    if (bin && size < sizeof text) {
        memcpy(text, bin, size);
        text[size] = '\0';
        if (sscanf(text, "%7s %lf %lf", which, a_ms, b_ms) != 3)
            which[0] = '\0';
    }
    free(bin);
}

static void store_choice(cdvr_cl *cl, const cdvr_codec *codec, const char *kind,
                         unsigned size_class, const char *which, double a_ms, double b_ms)
{
    char file[512], key[33], text[64];
    if (!choice_path(cl, codec, kind, size_class, file, sizeof file, key))
        return;
    int n = snprintf(text, sizeof text, "%s %.4f %.4f", which, a_ms, b_ms);
    if (n > 0 && (size_t)n < sizeof text)
        cdvr_cache_store(file, key, (const unsigned char *)text, (size_t)n);
}

cdvr_cl_decode_path cdvr_cl_load_decode_choice(cdvr_cl *cl, const cdvr_codec *codec,
                                               unsigned size_class, double *kernel_ms,
                                               double *host_ms)
{
    char which[8];
    load_choice(cl, codec, "decode", size_class, which, kernel_ms, host_ms);
    return !strcmp(which, "host")     ? CDVR_CL_DECODE_HOST
           : !strcmp(which, "kernel") ? CDVR_CL_DECODE_KERNEL
                                      : CDVR_CL_DECODE_AUTO;
}

void cdvr_cl_store_decode_choice(cdvr_cl *cl, const cdvr_codec *codec, unsigned size_class,
                                 cdvr_cl_decode_path path, double kernel_ms, double host_ms)
{
    store_choice(cl, codec, "decode", size_class,
                 path == CDVR_CL_DECODE_HOST ? "host" : "kernel", kernel_ms, host_ms);
}

cdvr_cl_fetch_path cdvr_cl_load_fetch_choice(cdvr_cl *cl, const cdvr_codec *codec,
                                             unsigned size_class, double *sample_ms,
                                             double *bulk_ms)
{
    char which[8];
    load_choice(cl, codec, "fetch", size_class, which, sample_ms, bulk_ms);
    return !strcmp(which, "sample")  ? CDVR_CL_FETCH_SAMPLE
           : !strcmp(which, "bulk") ? CDVR_CL_FETCH_BULK
                                    : CDVR_CL_FETCH_AUTO;
}

void cdvr_cl_store_fetch_choice(cdvr_cl *cl, const cdvr_codec *codec, unsigned size_class,
                                cdvr_cl_fetch_path path, double sample_ms, double bulk_ms)
{
    store_choice(cl, codec, "fetch", size_class,
                 path == CDVR_CL_FETCH_SAMPLE ? "sample" : "bulk", sample_ms, bulk_ms);
}

/* info.dense_frames (cdvr_cl_open): CDVR_CL_TILES=0 or 1, else tiled on a GPU, else what
 * this device measured, remembered or measured now (a failed measurement keeps the tiles). */
static void choose_layout(cdvr_cl *cl)
{
    cdvr_cl_info *info = &cl->info;
    const char *env = getenv("CDVR_CL_TILES");
    info->dense_frames = 0;
    if ((env && *env) || info->is_gpu) {
        info->dense_frames = env && !strcmp(env, "0");
        return;
    }
    char which[8];
    load_choice(cl, NULL, "layout", 0, which, &info->layout_dense_ms, &info->layout_tiled_ms);
    if (!strcmp(which, "dense") || !strcmp(which, "tiled")) {
        info->dense_frames = !strcmp(which, "dense");
        return;
    }
    cdvr_error err;
    double dense_ms, tiled_ms;
    if (cdvr_cl_measure_layouts(cl, &dense_ms, &tiled_ms, &err) != CDVR_OK) {
        info->layout_dense_ms = info->layout_tiled_ms = 0;
        return;
    }
    info->layout_dense_ms = dense_ms;
    info->layout_tiled_ms = tiled_ms;
    info->dense_frames = dense_ms < CDVR_CL_DENSE_SHARE * tiled_ms;
    store_choice(cl, NULL, "layout", 0, info->dense_frames ? "dense" : "tiled", dense_ms,
                 tiled_ms);
}

/* info.quads_max_bytes and still_quads (cdvr_cl_open, after choose_layout): on a CPU device,
 * the large limit where the remembered or measured quad probe cast below CDVR_CL_QUADS_SHARE
 * of the probe without quads (the tiled copy, or dense frames where frames stay dense: then
 * still_quads too; remembered apart, size class 1). CDVR_CL_QUADS (which overrides at render
 * time) or CDVR_CL_TILES set, or a failed measurement keep the default and no still_quads. */
static void choose_quads(cdvr_cl *cl)
{
    cdvr_cl_info *info = &cl->info;
    const char *quads_env = getenv("CDVR_CL_QUADS"), *tiles_env = getenv("CDVR_CL_TILES");
    info->quads_max_bytes = info->is_gpu ? 0 : CDVR_CL_QUADS_MAX_BYTES;
    info->still_quads = 0;
    info->quads_base_ms = info->quads_ms = 0;
    if ((quads_env && *quads_env) || (tiles_env && *tiles_env) || info->is_gpu)
        return;
    unsigned against_dense = info->dense_frames != 0;
    char which[8];
    double base_ms, quads_ms;
    load_choice(cl, NULL, "quads", against_dense, which, &base_ms, &quads_ms);
    if (strcmp(which, "large") && strcmp(which, "small")) {
        cdvr_error err;
        if (cdvr_cl_measure_quads(cl, against_dense, &base_ms, &quads_ms, &err) != CDVR_OK)
            return;
        strcpy(which, quads_ms < CDVR_CL_QUADS_SHARE * base_ms ? "large" : "small");
        store_choice(cl, NULL, "quads", against_dense, which, base_ms, quads_ms);
    }
    info->quads_base_ms = base_ms;
    info->quads_ms = quads_ms;
    if (!strcmp(which, "large")) {
        info->quads_max_bytes = CDVR_CL_QUADS_LARGE_MAX_BYTES;
        info->still_quads = (int)against_dense;
    }
}

static cdvr_status create_kernel(cl_program program, const char *name, cl_kernel *out,
                                cdvr_error *err)
{
    cl_int code;
    *out = clCreateKernel(program, name, &code);
    if (code != CL_SUCCESS) {
        *out = NULL;
        char what[96];
        snprintf(what, sizeof what, "clCreateKernel(%s)", name);
        return cdvr_cl_check(code, what, err);
    }
    return CDVR_OK;
}

static cdvr_status create_context(cdvr_cl *cl, cdvr_error *err)
{
    cl_int code;
    cl_context_properties props[] = {CL_CONTEXT_PLATFORM, (cl_context_properties)cl->platform, 0};
    cl->context = clCreateContext(props, 1, &cl->device, NULL, NULL, &code);
    if (code != CL_SUCCESS) {
        cl->context = NULL;
        return cdvr_cl_check(code, "clCreateContext", err);
    }
    cl->queue = clCreateCommandQueue(cl->context, cl->device, 0, &code);
    if (code != CL_SUCCESS) {
        cl->queue = NULL;
        return cdvr_cl_check(code, "clCreateCommandQueue", err);
    }
    return CDVR_OK;
}

cdvr_status cdvr_cl_open(cdvr_cl **out, cdvr_error *err)
{
    *out = NULL;
    const char *want = getenv("CDVR_CL_DEVICE");
    if (want && !strcmp(want, "none"))
        return cdvr_error_set(err, CDVR_ERR_DEVICE,
                              "OpenCL: disabled by CDVR_CL_DEVICE=none; use device=\"cpu\"");
    device_list *list = calloc(1, sizeof *list);
    cdvr_cl *cl = calloc(1, sizeof *cl);
    int pi = 0, di = 0;
    cdvr_status st = (!list || !cl) ? cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL: out of memory")
                                    : list_devices(list, err);
    if (!st)
        st = choose_device(list, want, &pi, &di, err);
    if (!st) {
        cl->platform = list->platforms[pi];
        cl->device = list->devices[pi][di];
        fill_info(cl, pi, di);
        st = create_context(cl, err);
    }
    free(list);
    if (!st)
        st = build_program(cl, err);
    if (!st)
        st = create_kernel(cl->program, "brick_minmax", &cl->k_bricks, err);
    if (!st)
        st = create_kernel(cl->program, "raycast", &cl->k_raycast, err);
    if (!st)
        st = create_kernel(cl->program, "make_tiles", &cl->k_tiles, err);
    if (!st)
        st = create_kernel(cl->program, "make_grads", &cl->k_grads, err);
    if (!st)
        st = create_kernel(cl->program, "make_quads", &cl->k_quads, err);
    if (st) {
        cdvr_cl_close(cl);
        return st;
    }
    choose_layout(cl);
    choose_quads(cl);
    *out = cl;
    return CDVR_OK;
}

static void release_codec_program(cdvr_cl_codec_program *cp)
{
    cl_kernel *kernels[] = {&cp->k_decode, &cp->k_bricks, &cp->k_raycast};
    for (size_t i = 0; i < 3; i++)
        if (*kernels[i])
            clReleaseKernel(*kernels[i]);
    if (cp->program)
        clReleaseProgram(cp->program);
    memset(cp, 0, sizeof *cp);
}

/* Builds the program of a codec: its decode kernel, or the render kernels over its fetch
 * function (-DCDVR_FETCH=name). */
static cdvr_status build_codec_program(cdvr_cl *cl, const cdvr_codec *codec,
                                       cdvr_cl_codec_program *cp, cdvr_error *err)
{
    int fetch = codec->cl_mode == CDVR_CODEC_CL_FETCH;
    char *source = NULL, options[256], what[96], cache_path[512];
    cdvr_status st = load_sources(codec, render_files, fetch ? NRENDER_FILES : 0, &source, err);
    if (st)
        return st;
    snprintf(options, sizeof options, "%s%s%s", BUILD_OPTIONS, fetch ? " -DCDVR_FETCH=" : "",
             fetch ? codec->cl_function : "");
    snprintf(what, sizeof what, "the %s kernels of codec %s", fetch ? "fetch" : "decode",
             codec->name);
    int from_cache;
    memset(cp, 0, sizeof *cp);
    cp->codec = codec;
    st = build_cached(cl, source, options, what, &cp->program, &from_cache, cache_path,
                      sizeof cache_path, err);
    free(source);
    if (!st && fetch)
        st = create_kernel(cp->program, "brick_minmax", &cp->k_bricks, err);
    if (!st && fetch)
        st = create_kernel(cp->program, "raycast", &cp->k_raycast, err);
    if (!st && !fetch)
        st = create_kernel(cp->program, codec->cl_function, &cp->k_decode, err);
    if (st)
        release_codec_program(cp);
    return st;
}

cdvr_status cdvr_cl_get_codec_program(cdvr_cl *cl, const cdvr_codec *codec,
                                      cdvr_cl_codec_program **out, cdvr_error *err)
{
    *out = NULL;
    if (codec->cl_mode == CDVR_CODEC_CL_NONE)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "OpenCL: codec %s has no device code "
                              "(decode on the CPU, then upload)", codec->name);
    for (size_t i = 0; i < cl->ncodecs; i++)
        if (cl->codecs[i].codec == codec) {
            *out = &cl->codecs[i];
            return CDVR_OK;
        }
    if (cl->ncodecs == CDVR_CL_MAX_CODEC_PROGRAMS)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL: more than %d codec programs",
                              CDVR_CL_MAX_CODEC_PROGRAMS);
    cdvr_status st = build_codec_program(cl, codec, &cl->codecs[cl->ncodecs], err);
    if (st)
        return st;
    *out = &cl->codecs[cl->ncodecs++];
    return CDVR_OK;
}

cdvr_status cdvr_cl_arg(cl_kernel k, const char *name, cl_uint index, size_t size,
                        const void *value, cdvr_error *err)
{
    cl_int code = clSetKernelArg(k, index, size, value);
    if (code == CL_SUCCESS)
        return CDVR_OK;
    return cdvr_error_set(err, CDVR_ERR_DEVICE, "OpenCL: %s argument %u: %s (%d)", name,
                          (unsigned)index, cdvr_cl_error_name(code), (int)code);
}

void cdvr_cl_close(cdvr_cl *cl)
{
    if (!cl)
        return;
    for (size_t i = 0; i < cl->ncodecs; i++)
        release_codec_program(&cl->codecs[i]);
    cl_kernel kernels[] = {cl->k_bricks, cl->k_raycast, cl->k_tiles, cl->k_grads,
                           cl->k_quads, cl->k_bricks_long, cl->k_raycast_long};
    for (size_t i = 0; i < sizeof kernels / sizeof *kernels; i++)
        if (kernels[i])
            clReleaseKernel(kernels[i]);
    if (cl->program)
        clReleaseProgram(cl->program);
    if (cl->program_long)
        clReleaseProgram(cl->program_long);
    if (cl->queue)
        clReleaseCommandQueue(cl->queue);
    if (cl->context)
        clReleaseContext(cl->context);
    free(cl);
}

const char *cdvr_cl_device_name(const cdvr_cl *cl)
{
    return cl->info.device;
}

const cdvr_cl_info *cdvr_cl_get_info(const cdvr_cl *cl)
{
    return &cl->info;
}
