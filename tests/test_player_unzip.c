/* tests/test_player_unzip.c - the player's unzip workers (core/player/player.c): with 2
 * workers consecutive chunk groups are unzipped and host-decoded at the same time, each into
 * its own decode slot, and reach the device thread in planning order. Every frame of a
 * pipelined run with 2 workers is byte-identical to the run with 1 worker, to the serial run
 * and to the render of that timestep decoded alone: raw + LZO and PVTC, cpu and cl devices
 * (host decode, where a raw chunk's slot trades buffers with its payload, and decode kernel
 * forced), whole runs, runs stopped inside a group, runs that
 * wrap around, and several runs of one player. A chunk whose LZO stream is corrupt (CRC
 * fixed, so the worker finds it) and one whose bytes fail the CRC (the reader finds it) give
 * error rows naming the chunk and the store, the other frames play, and nothing hangs. On
 * Linux the reader and the workers run at the nice increment CDVR_PLAYER_NICE (default 5)
 * above the caller, which keeps its own. */
#include "check.h"
#include "player_frames.h"

#include "cdvr/device.h"
#include "cdvr/player.h"
#include "cdvr/pvtc.h"
#include "store/store_format.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#if defined(__linux__)
#include <dirent.h>
#include <errno.h>
#include <sys/resource.h>
#endif

#define W 40
#define H 32
#define T 8 /* timesteps: PVTC chunks of 3, so the last group is short */
#define PX ((size_t)W * H * 4)

static cdvr_volume *make_series(void)
{
    size_t dims[3] = {33, 28, 24};
    cdvr_volume *v = NULL;
    cdvr_error err;
    if (cdvr_volume_create(dims, T, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    for (size_t t = 0; t < T; t++)
        for (size_t z = 0; z < dims[2]; z++)
            for (size_t y = 0; y < dims[1]; y++)
                for (size_t x = 0; x < dims[0]; x++) {
                    double dx = (double)x - 9 - 2.0 * t, dy = (double)y - 14, dz = (double)z - 12;
                    double r = dx * dx + dy * dy + dz * dz;
                    *p++ = (uint8_t)(r < 80 ? 230 - 2 * r : (x * 3 + y + t) % 11 == 0 ? 50 : 0);
                }
    return v;
}

static void make_tf(cdvr_tf *tf)
{
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {60, 0.2, 0.3, 0.9, 0.05}, {120, 0.9, 0.5, 0.2, 0.3},
                           {255, 1, 1, 1, 0.9}};
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(tf, pts, 4, 0, &err), err);
}

static cdvr_camera make_camera(void)
{
    cdvr_camera cam = {.eye = {90, -55, 65}, .center = {16, 13.5, 11.5}, .up = {0, 0, 1},
                       .fov = 30, .width = W, .height = H};
    return cam;
}

/* The render of timestep t of variant v decoded by itself, into ref[t] (T frames). */
static void references(const cdvr_store *st, size_t v, cdvr_device_kind device, float *ref)
{
    cdvr_tf tf;
    make_tf(&tf);
    cdvr_camera cam = make_camera();
    for (size_t t = 0; t < T; t++)
        render_alone(st, v, t, device, &tf, &cam, ref + t * PX);
}

/* A player of variant v: serial (workers 0) or pipelined with `workers` unzip workers. */
static cdvr_player *make_player(const cdvr_store *st, size_t v, cdvr_device_kind device,
                                int workers, int loop, const cdvr_tf *tf, capture *cap)
{
    cdvr_player_opts o = {.store = st, .device = device, .tf = tf, .camera = make_camera(),
                          .variant = (int)v, .pipelined = workers > 0, .ring = 2,
                          .unzip_threads = workers, .empty_skip = 1, .loop = loop,
                          .frame_fn = keep_frame, .frame_ud = cap};
    cdvr_player *p = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_player_create(&o, &p, &err), err);
    return p;
}

/* Plays `frames` frames from timestep `first` and checks each against ref (by timestep) and
 * against the frames of other runs with the same first frame (*same, when it holds any);
 * each row's unzip CPU time is above 0 where the chunks have stage 2 (0 where they have
 * none) and within its wall time on all cores. */
static void play_check(cdvr_player *p, capture *cap, size_t first, size_t frames,
                       const float *ref, int stage2, const char *what)
{
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    cdvr_error err;
    memset(cap->pixels, 0, sizeof(float) * PX * cap->frames);
    CHECK_OK(cdvr_player_run(p, first, frames, &err), err);
    size_t nrows = 0;
    const cdvr_frame_row *rows = cdvr_player_rows(p, &nrows);
    CHECK(nrows == frames, "%s: %zu rows for %zu frames", what, nrows, frames);
    for (size_t i = 0; i < nrows; i++) {
        CHECK(rows[i].status == CDVR_OK, "%s: frame %zu: %s", what, i, rows[i].error);
        CHECK(rows[i].frame == i && rows[i].t == (first + i) % T,
              "%s: row %zu is frame %zu, timestep %zu", what, i, rows[i].frame, rows[i].t);
        CHECK(memcmp(cap->pixels + i * PX, ref + rows[i].t * PX, sizeof(float) * PX) == 0,
              "%s: frame %zu (timestep %zu) differs from its render alone", what, i,
              rows[i].t + 1);
        double cpu = rows[i].unzip_cpu_ms, wall = rows[i].unzip_ms;
        CHECK(stage2 ? cpu > 0 && cpu <= wall * (double)(cores > 0 ? cores : 1) + 0.05
                     : cpu == 0,
              "%s: frame %zu: unzip %.4f ms of CPU in %.4f ms (stage 2: %d)", what, i, cpu,
              wall, stage2);
    }
}

/* Runs of variant v on a device with 2 workers, 1 worker and serial, equal to the references
 * (and so to each other): the whole series, stopped inside a group, wrapping around, all on
 * one player (its state is reset between runs). */
static void check_variant(const cdvr_store *st, size_t v, cdvr_device_kind device,
                          const char *dev_name)
{
    float *ref = calloc(T * PX, sizeof(float));
    capture cap = {calloc(2 * T * PX, sizeof(float)), 2 * T, PX};
    cdvr_tf tf;
    make_tf(&tf);
    references(st, v, device, ref);
    static const int workers[] = {2, 1, 0};
    for (int w = 0; w < 3; w++) {
        cdvr_player *p = make_player(st, v, device, workers[w], 1, &tf, &cap);
        if (!p)
            continue;
        static const size_t runs[][2] = {{0, T}, {1, 4}, {0, 2}, {4, 1}, {6, 7}, {2, 2 * T}};
        for (size_t r = 0; r < sizeof runs / sizeof runs[0]; r++) {
            char what[128];
            snprintf(what, sizeof what, "%s, variant %zu, %d workers, first %zu frames %zu",
                     dev_name, v + 1, workers[w], runs[r][0], runs[r][1]);
            play_check(p, &cap, runs[r][0], runs[r][1], ref,
                       cdvr_store_chunk(st, v, 0)->stage2 != 0, what);
        }
        cdvr_player_free(p);
    }
    free(cap.pixels);
    free(ref);
}

/* Copies the store at src to dst and damages chunk c of variant v: with fix_crc, its stored
 * bytes become an invalid LZO stream under a correct CRC (the unzip fails); else one byte is
 * flipped (the read's CRC check fails). */
static int damage(const char *src, const char *dst, size_t v, size_t c, int fix_crc)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(src, &st, &err), err);
    if (!st)
        return 0;
    FILE *in = fopen(src, "rb");
    fseek(in, 0, SEEK_END);
    size_t n = (size_t)ftell(in);
    uint8_t *file = malloc(n);
    rewind(in);
    int ok = fread(file, 1, n, in) == n;
    fclose(in);
    cdvr_chunk_info *ci = (cdvr_chunk_info *)cdvr_store_chunk(st, v, c);
    uint8_t *bytes = file + ci->offset;
    if (fix_crc) {
        CHECK(ci->stage2, "chunk %zu of variant %zu is LZO-packed", c + 1, v + 1);
        for (size_t i = 0; i < ci->stored_bytes; i++)
            bytes[i] = (uint8_t)(0xff - i % 3);
        ci->crc32c = cdvr_crc32c(0, bytes, (size_t)ci->stored_bytes);
        cdvr_store_serialize_meta(st, file); /* the metadata (and its CRC) lead the file */
    } else {
        bytes[ci->stored_bytes / 2] ^= 0x5a;
    }
    cdvr_store_close(st);
    FILE *out = fopen(dst, "wb");
    ok = ok && out && fwrite(file, 1, n, out) == n;
    if (out)
        fclose(out);
    free(file);
    CHECK(ok, "write %s", dst);
    return ok;
}

/* A damaged chunk (timesteps t0 .. t0 + count - 1) in a run with 2 workers: error rows naming
 * chunk c + 1 and the file, the other frames equal their references, and several runs (one
 * stopped early) end. */
static void check_damaged(const char *path, size_t v, size_t c, int fix_crc,
                          cdvr_device_kind device, const char *dev_name, const float *ref)
{
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    capture cap = {calloc(T * PX, sizeof(float)), T, PX};
    cdvr_tf tf;
    make_tf(&tf);
    char chunk[32];
    snprintf(chunk, sizeof chunk, "chunk %zu", c + 1);
    for (int w = 2; w >= 1; w--) {
        cdvr_player *p = make_player(st, v, device, w, 0, &tf, &cap);
        static const size_t runs[][2] = {{0, T}, {0, 4}, {1, 2}};
        for (size_t r = 0; p && r < sizeof runs / sizeof runs[0]; r++) {
            CHECK_OK(cdvr_player_run(p, runs[r][0], runs[r][1], &err), err);
            size_t nrows = 0, failed = 0;
            const cdvr_frame_row *rows = cdvr_player_rows(p, &nrows);
            CHECK(nrows == runs[r][1], "%s damaged (crc %s), %d workers: %zu rows", dev_name,
                  fix_crc ? "fixed" : "bad", w, nrows);
            for (size_t i = 0; i < nrows; i++) {
                int bad = rows[i].t >= ci->t0 && rows[i].t < ci->t0 + ci->count;
                failed += bad;
                if (bad)
                    CHECK(rows[i].status != CDVR_OK && strstr(rows[i].error, chunk) &&
                              strstr(rows[i].error, path),
                          "%s, %d workers: frame %zu of the damaged chunk: status %d '%s'",
                          dev_name, w, i, rows[i].status, rows[i].error);
                else
                    CHECK(rows[i].status == CDVR_OK &&
                              memcmp(cap.pixels + rows[i].frame * PX, ref + rows[i].t * PX,
                                     sizeof(float) * PX) == 0,
                          "%s, %d workers: frame %zu (timestep %zu) '%s'", dev_name, w, i,
                          rows[i].t + 1, rows[i].error);
            }
            CHECK(failed > 0 || runs[r][0] + runs[r][1] <= ci->t0,
                  "%s: the damaged chunk was played", dev_name);
        }
        cdvr_player_free(p);
    }
    free(cap.pixels);
    cdvr_store_close(st);
}

#if defined(__linux__)
/* Threads of this process seen from frame callbacks: the most at nice `lowered` at once, and
 * whether the calling thread ever had another nice than `base`. */
typedef struct nice_watch {
    int base, lowered, most_lowered, caller_moved;
} nice_watch;

static cdvr_status watch_nice(void *ud, const cdvr_frame_row *row, const cdvr_image *img,
                              cdvr_error *err)
{
    nice_watch *w = ud;
    (void)row, (void)img, (void)err;
    errno = 0;
    int caller = getpriority(PRIO_PROCESS, 0); /* Linux: the calling thread's */
    w->caller_moved |= errno == 0 && caller != w->base;
    DIR *d = opendir("/proc/self/task");
    if (!d)
        return CDVR_OK;
    int lowered = 0;
    for (struct dirent *e; (e = readdir(d)) != NULL;) {
        if (e->d_name[0] == '.')
            continue;
        errno = 0;
        int n = getpriority(PRIO_PROCESS, (id_t)atoi(e->d_name));
        lowered += errno == 0 && n == w->lowered;
    }
    closedir(d);
    if (lowered > w->most_lowered)
        w->most_lowered = lowered;
    return CDVR_OK;
}

/* A run of the raw variant on the cpu device with CDVR_PLAYER_NICE `env` (NULL: unset) and
 * `workers` unzip workers (0: serial) has at least `want` threads at the caller's nice +
 * `increment` while it plays (the reader and the workers: with a ring of 2 the reader still
 * waits for buffers at the first frame; threads they start may add to them), and the caller
 * keeps its nice. */
static void check_nice(const cdvr_store *st, const char *env, int workers, int increment,
                       int want)
{
    errno = 0;
    int base = getpriority(PRIO_PROCESS, 0);
    if (errno != 0 || base + increment > 19) {
        printf("nice %d: the background priority cannot be checked\n", base);
        return;
    }
    if (env)
        setenv("CDVR_PLAYER_NICE", env, 1);
    nice_watch w = {.base = base, .lowered = base + increment};
    cdvr_tf tf;
    make_tf(&tf);
    cdvr_player_opts o = {.store = st, .device = CDVR_DEVICE_CPU, .tf = &tf,
                          .camera = make_camera(), .variant = 1, .pipelined = workers > 0,
                          .ring = 2, .unzip_threads = workers, .frame_fn = watch_nice,
                          .frame_ud = &w};
    cdvr_player *p = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_player_create(&o, &p, &err), err);
    if (p)
        CHECK_OK(cdvr_player_run(p, 0, T, &err), err);
    cdvr_player_free(p);
    unsetenv("CDVR_PLAYER_NICE");
    const char *name = env ? env : "unset";
    CHECK(!w.caller_moved, "CDVR_PLAYER_NICE %s, %d workers: the caller's nice moved", name,
          workers);
    if (want == 0)
        CHECK(w.most_lowered == 0, "CDVR_PLAYER_NICE %s, %d workers: %d threads at nice %d",
              name, workers, w.most_lowered, w.lowered);
    else
        CHECK(w.most_lowered >= want,
              "CDVR_PLAYER_NICE %s, %d workers: %d threads at nice %d, want the reader and the "
              "workers (%d)",
              name, workers, w.most_lowered, w.lowered, want);
}
#endif

int main(void)
{
    cdvr_volume *vol = make_series();
    char path[] = "/tmp/cdvr_test_player_unzip_XXXXXX";
    int fd = mkstemp(path);
    if (fd >= 0)
        close(fd);
    char bad[64];
    snprintf(bad, sizeof bad, "%s.bad", path);
    cdvr_variant_spec vs[2] = {{.codec = cdvr_codec_find("pvtc"), .lzo_min_saving = -1},
                               {.codec = cdvr_codec_find("raw"), .stage2 = CDVR_STAGE2_LZO,
                                .lzo_min_saving = 0}};
    cdvr_pvtc_params pp = {4, 3, CDVR_PACK_TIME};
    cdvr_pvtc_params_to_blob(&pp, CDVR_ENCODER_BBOX, &vs[0].params);
    vs[1].codec->params_default(&vs[1].params);
    cdvr_encode_opts eo = {.variants = vs, .nvariants = 2, .qhi = 255};
    cdvr_error err;
    CHECK_OK(cdvr_store_encode(vol, &eo, path, &err), err);
    int have_cl = 0;
#if CDVR_HAVE_OPENCL
    cdvr_cl *probe = NULL;
    have_cl = cdvr_cl_open(&probe, &err) == CDVR_OK;
    cdvr_cl_close(probe);
#endif
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    for (size_t v = 0; st && v < 2; v++) {
        check_variant(st, v, CDVR_DEVICE_CPU, "cpu");
        static const char *const paths[] = {"host", "kernel"};
        for (int k = 0; have_cl && k < 2; k++) {
            setenv("CDVR_CL_DECODE", paths[k], 1);
            char name[32];
            snprintf(name, sizeof name, "cl, %s decode", paths[k]);
            check_variant(st, v, CDVR_DEVICE_CL, name);
            unsetenv("CDVR_CL_DECODE");
        }
    }
#if defined(__linux__)
    if (st) {
        check_nice(st, NULL, 2, 5, 3);
        check_nice(st, "7", 1, 7, 2);
        check_nice(st, "0", 2, 5, 0);
        check_nice(st, NULL, 0, 5, 0);
    }
#endif
    /* damaged raw chunk 4 (timestep 4, a group's first), then PVTC chunk 2 (timesteps 4..6) */
    static const struct { size_t v, c; int fix_crc; } cases[] = {{1, 3, 1}, {1, 3, 0}, {0, 1, 0}};
    for (size_t i = 0; st && i < 3; i++) {
        float *ref = calloc(T * PX, sizeof(float));
        if (!damage(path, bad, cases[i].v, cases[i].c, cases[i].fix_crc)) {
            free(ref);
            continue;
        }
        references(st, cases[i].v, CDVR_DEVICE_CPU, ref);
        check_damaged(bad, cases[i].v, cases[i].c, cases[i].fix_crc, CDVR_DEVICE_CPU, "cpu", ref);
        if (have_cl) {
            setenv("CDVR_CL_DECODE", "host", 1);
            references(st, cases[i].v, CDVR_DEVICE_CL, ref);
            check_damaged(bad, cases[i].v, cases[i].c, cases[i].fix_crc, CDVR_DEVICE_CL, "cl",
                          ref);
            unsetenv("CDVR_CL_DECODE");
        }
        free(ref);
    }
    cdvr_store_close(st);
    unlink(bad);
    unlink(path);
    cdvr_volume_free(vol);
    if (!have_cl)
        printf("no OpenCL device: the cpu device only\n");
    return check_finish();
}
