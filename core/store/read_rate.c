/* core/store/read_rate.c - the rates at which a store's filesystem reads (cdvr_store_read_rates,
 * store.h): the read side of stage 2's AUTO model, measured once per filesystem and
 * remembered (cdvr/cache.h), as the unpack side is per machine
 * (core/codec/stage2/stage2_rates.c).
 *
 * Measured the way the player reads a chunk: a 32 MiB file of incompressible bytes is
 * written in the store's directory (unlinked at once, so nothing is left behind) and synced;
 * the disk's rate is that of reading it back with 4 MiB preads after dropping it from the
 * page cache (POSIX_FADV_DONTNEED, as the player's cold mode does), the page cache's that of
 * reading it again while it is cached; three passes each, the median counts, rounded to two
 * significant digits so that small noise does not change what is remembered. Where the
 * filesystem keeps files in memory (tmpfs) the drop does nothing and both are the memory's
 * rate, which is what reads there take. */
#include "cdvr/store.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include "cdvr/cache.h"
#include "cdvr/timing.h"

#define PROBE_BYTES (32u << 20)   /* the test file */
#define PROBE_BLOCK (4u << 20)    /* bytes per write and per pread */
#define PROBE_PASSES 3            /* reads of each kind; the median counts */
#define RATE_MIN 1.0              /* MB/s: the range a remembered rate must lie in */
#define RATE_MAX 1e7
#define RATE_FORMAT "disk %.6g cache %.6g"
#define RATE_SCAN "disk %lf cache %lf"

/* The directory of path ("." when it names none) into dir[n]; 0 when it does not fit. */
static int dir_of(const char *path, char *dir, size_t n)
{
    const char *slash = strrchr(path, '/');
    if (!slash)
        return snprintf(dir, n, ".") < (int)n;
    size_t len = slash == path ? 1 : (size_t)(slash - path); /* "/x" -> "/" */
    if (len >= n)
        return 0;
    memcpy(dir, path, len);
    dir[len] = 0;
    return 1;
}

/* The cache key of the filesystem holding dir: its device, id and size. */
static cdvr_status filesystem_key(const char *dir, char key[33], cdvr_error *err)
{
    struct stat sb;
    struct statvfs vfs;
    if (stat(dir, &sb) != 0 || statvfs(dir, &vfs) != 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot measure its read rate: %s", dir,
                              strerror(errno));
    char dev[64], fsid[32], size[32];
    snprintf(dev, sizeof dev, "%u:%u", major(sb.st_dev), minor(sb.st_dev));
    snprintf(fsid, sizeof fsid, "%lx", (unsigned long)vfs.f_fsid);
    snprintf(size, sizeof size, "%llu",
             (unsigned long long)vfs.f_blocks * (unsigned long long)vfs.f_frsize);
    const char *parts[] = {"store read rates 1", dev, fsid, size};
    cdvr_cache_key(parts, sizeof parts / sizeof *parts, key);
    return CDVR_OK;
}

static cdvr_status write_all(int fd, const uint8_t *buf, size_t n, const char *dir,
                             cdvr_error *err)
{
    while (n > 0) {
        ssize_t w = write(fd, buf, n);
        if (w < 0 && errno == EINTR)
            continue;
        if (w <= 0)
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot measure its read rate: writing "
                                  "a %u MiB test file: %s", dir, PROBE_BYTES >> 20,
                                  w < 0 ? strerror(errno) : "nothing written");
        buf += w;
        n -= (size_t)w;
    }
    return CDVR_OK;
}

/* One read of the whole test file, MB/s (10^6 bytes); cold: dropped from the page cache first. */
static cdvr_status read_pass(int fd, uint8_t *buf, int cold, const char *dir, double *mbps,
                             cdvr_error *err)
{
    if (cold)
        (void)posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
    double t0 = cdvr_now_ms();
    for (size_t at = 0; at < PROBE_BYTES;) {
        ssize_t r = pread(fd, buf, PROBE_BLOCK, (off_t)at);
        if (r < 0 && errno == EINTR)
            continue;
        if (r <= 0)
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot measure its read rate: "
                                  "reading the test file: %s", dir,
                                  r < 0 ? strerror(errno) : "short file");
        at += (size_t)r;
    }
    double ms = cdvr_now_ms() - t0;
    *mbps = PROBE_BYTES / (1e3 * (ms > 1e-3 ? ms : 1e-3));
    return CDVR_OK;
}

/* The median of the passes rounded to two significant digits, in [RATE_MIN, RATE_MAX]. */
static double median_rate(double *pass)
{
    double x = cdvr_median(pass, PROBE_PASSES);
    double unit = pow(10.0, floor(log10(x)) - 1.0);
    x = round(x / unit) * unit;
    return x < RATE_MIN ? RATE_MIN : x > RATE_MAX ? RATE_MAX : x;
}

/* The test file in dir, open in *fd: created (mkstemp's template), unlinked at once so that
 * nothing is left behind, filled with PROBE_BYTES of incompressible bytes (no filesystem or
 * disk shrinks them) and synced. buf: PROBE_BLOCK bytes of scratch. */
static cdvr_status write_probe_file(const char *dir, uint8_t *buf, int *fd, cdvr_error *err)
{
    char name[PATH_MAX];
    if (snprintf(name, sizeof name, "%s/.cdvr-read-rate-XXXXXX", dir) >= (int)sizeof name)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: path too long", dir);
    *fd = mkstemp(name);
    if (*fd < 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot measure its read rate: creating a "
                              "test file: %s", dir, strerror(errno));
    (void)unlink(name); /* gone from the directory; its blocks live until the close */
    (void)fcntl(*fd, F_SETFD, FD_CLOEXEC);
    uint32_t rng = 0x9e3779b9u;
    cdvr_status s = CDVR_OK;
    for (size_t at = 0; s == CDVR_OK && at < PROBE_BYTES; at += PROBE_BLOCK) {
        for (size_t i = 0; i < PROBE_BLOCK; i += 4) {
            rng ^= rng << 13;
            rng ^= rng >> 17;
            rng ^= rng << 5;
            memcpy(buf + i, &rng, 4);
        }
        s = write_all(*fd, buf, PROBE_BLOCK, dir, err);
    }
    if (s == CDVR_OK && fsync(*fd) != 0)
        s = cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot measure its read rate: syncing the "
                           "test file: %s", dir, strerror(errno));
    return s;
}

static cdvr_status measure(const char *dir, cdvr_read_rates *out, cdvr_error *err)
{
    uint8_t *buf = malloc(PROBE_BLOCK);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory to measure its read rate",
                              dir);
    int fd = -1;
    cdvr_status s = write_probe_file(dir, buf, &fd, err);
    double disk[PROBE_PASSES], cache[PROBE_PASSES];
    for (int p = 0; s == CDVR_OK && p < PROBE_PASSES; p++)
        s = read_pass(fd, buf, 1, dir, &disk[p], err);
    for (int p = 0; s == CDVR_OK && p < PROBE_PASSES; p++)
        s = read_pass(fd, buf, 0, dir, &cache[p], err);
    if (fd >= 0)
        close(fd);
    free(buf);
    if (s != CDVR_OK)
        return s;
    out->disk_mbps = median_rate(disk);
    out->cache_mbps = median_rate(cache);
    return CDVR_OK;
}

/* The rates in a cache entry's content into out: 1, or 0 when it holds none. */
static int parse_rates(const unsigned char *content, size_t n, cdvr_read_rates *out)
{
    char text[96];
    double disk = 0, cache = 0;
    if (!content || n == 0 || n >= sizeof text)
        return 0;
    memcpy(text, content, n);
    text[n] = 0;
    if (sscanf(text, RATE_SCAN, &disk, &cache) != 2 || !(disk >= RATE_MIN && disk <= RATE_MAX) ||
        !(cache >= RATE_MIN && cache <= RATE_MAX))
        return 0;
    out->disk_mbps = disk;
    out->cache_mbps = cache;
    return 1;
}

cdvr_status cdvr_store_read_rates(const char *path, cdvr_read_rates *out, cdvr_error *err)
{
    char dir[PATH_MAX], key[33], entry[PATH_MAX], text[96];
    memset(out, 0, sizeof *out);
    if (!path || !dir_of(path, dir, sizeof dir))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: path too long to measure its read rate",
                              path ? path : "(null)");
    cdvr_status s = filesystem_key(dir, key, err);
    if (s != CDVR_OK)
        return s;
    int cached = cdvr_cache_path(key, "readrate", entry, sizeof entry);
    size_t size = 0;
    unsigned char *content = cached ? cdvr_cache_load(entry, key, &size) : NULL;
    out->from_cache = parse_rates(content, size, out);
    free(content);
    if (out->from_cache)
        return CDVR_OK;
    s = measure(dir, out, err);
    if (s != CDVR_OK) {
        memset(out, 0, sizeof *out);
        return s;
    }
    int len = snprintf(text, sizeof text, RATE_FORMAT, out->disk_mbps, out->cache_mbps);
    if (cached && len > 0 && (size_t)len < sizeof text)
        cdvr_cache_store(entry, key, (const unsigned char *)text, (size_t)len);
    return CDVR_OK;
}

double cdvr_store_modelled_read_mbps(const cdvr_read_rates *rates, uint64_t raw_bytes,
                                     uint64_t memory_bytes)
{
    return raw_bytes <= memory_bytes / 2 ? rates->cache_mbps : rates->disk_mbps;
}
