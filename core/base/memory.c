/* core/base/memory.c - large buffers on transparent huge pages, and the memory a process may
 * fill (cdvr/memory.h). */
#include "cdvr/memory.h"

#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

void *cdvr_alloc_large(size_t bytes, int zero)
{
    size_t n = bytes ? bytes : 1;
    int huge = n >= CDVR_HUGE_PAGE_BYTES;
    void *p = NULL;
    if (posix_memalign(&p, huge ? CDVR_HUGE_PAGE_BYTES : 4096, n) != 0)
        return NULL;
#ifdef MADV_HUGEPAGE
    /* whole huge pages only (p is aligned to one); a refusal (huge pages off, an old kernel)
     * leaves an ordinary buffer */
    const char *env = getenv("CDVR_HUGE_PAGES");
    if (huge && !(env && strcmp(env, "0") == 0))
        (void)madvise(p, n - n % CDVR_HUGE_PAGE_BYTES, MADV_HUGEPAGE);
#endif
    if (zero)
        memset(p, 0, n);
    return p;
}

int cdvr_grow_large(uint8_t **buf, size_t *cap, uint64_t need)
{
    if (*buf && need <= *cap)
        return 1;
    if (need > SIZE_MAX - CDVR_HUGE_PAGE_BYTES)
        return 0;
    size_t n = need ? (size_t)need : 1;
    if (n >= CDVR_HUGE_PAGE_BYTES) /* whole huge pages: the rest of the last one is free */
        n += (CDVR_HUGE_PAGE_BYTES - n % CDVR_HUGE_PAGE_BYTES) % CDVR_HUGE_PAGE_BYTES;
    uint8_t *grown = cdvr_alloc_large(n, 0);
    if (!grown)
        return 0;
    free(*buf);
    *buf = grown;
    *cap = n;
    return 1;
}

/* Whether line is an smaps mapping header ("lo-hi perms offset dev inode path", addresses in
 * hex); if so *holds says whether the mapping holds address at. */
static int mapping_header(const char *line, uintptr_t at, int *holds)
{
    unsigned long long lo, hi;
    if (sscanf(line, "%llx-%llx", &lo, &hi) != 2)
        return 0;
    *holds = at >= lo && at < hi;
    return 1;
}

int cdvr_on_huge_pages(const void *p)
{
    FILE *f = fopen("/proc/self/smaps", "r");
    if (!f)
        return -1;
    char line[512];
    int inside = 0, eligible = -1, holds;
    while (fgets(line, sizeof line, f)) {
        if (mapping_header(line, (uintptr_t)p, &holds)) {
            if (inside)
                break;
            inside = holds;
            eligible = inside ? -1 : 0;
        } else if (inside && strncmp(line, "THPeligible:", 12) == 0) {
            eligible = atoi(line + 12) == 1;
            break;
        }
    }
    fclose(f);
    return eligible;
}

/* The limit in file (a number of bytes; "max" or a value of 2^62 and more: none), or
 * UINT64_MAX. */
static uint64_t read_limit(const char *file)
{
    FILE *f = fopen(file, "r");
    char text[64] = "";
    if (!f)
        return UINT64_MAX;
    int got = fgets(text, sizeof text, f) != NULL;
    fclose(f);
    char *end;
    unsigned long long value = got ? strtoull(text, &end, 10) : 0;
    if (!got || end == text || value >= (1ull << 62))
        return UINT64_MAX;
    return (uint64_t)value;
}

/* The smallest limit named `leaf` in dir and its parents up to base (dir starts with base). */
static uint64_t limit_up_to(char *dir, size_t base_len, const char *leaf)
{
    uint64_t limit = UINT64_MAX;
    for (;;) {
        char file[PATH_MAX + 64];
        snprintf(file, sizeof file, "%s/%s", dir, leaf);
        uint64_t here = read_limit(file);
        limit = here < limit ? here : limit;
        char *slash = strrchr(dir, '/');
        if (!slash || (size_t)(slash - dir) < base_len)
            return limit;
        *slash = '\0';
    }
}

uint64_t cdvr_cgroup_memory_limit(const char *cgroup_file, const char *root)
{
    FILE *f = fopen(cgroup_file, "r");
    if (!f)
        return UINT64_MAX;
    uint64_t limit = UINT64_MAX;
    char line[PATH_MAX + 128];
    while (fgets(line, sizeof line, f)) {
        line[strcspn(line, "\n")] = '\0';
        char *controllers = strchr(line, ':');
        char *path = controllers ? strchr(controllers + 1, ':') : NULL;
        if (!path)
            continue;
        *path++ = '\0';        /* line: "ID\0CONTROLLERS\0PATH" */
        *controllers++ = '\0';
        int v2 = strcmp(line, "0") == 0 && controllers[0] == '\0';
        int v1 = !v2 && (strcmp(controllers, "memory") == 0 || strstr(controllers, "memory,") ||
                         strstr(controllers, ",memory"));
        if (!v1 && !v2)
            continue;
        char dir[PATH_MAX];
        int base = snprintf(dir, sizeof dir, "%s%s", root, v1 ? "/memory" : "");
        if (base < 0 || (size_t)base + strlen(path) >= sizeof dir)
            continue;
        snprintf(dir + base, sizeof dir - (size_t)base, "%s", strcmp(path, "/") == 0 ? "" : path);
        uint64_t here = limit_up_to(dir, (size_t)base, v2 ? "memory.max" : "memory.limit_in_bytes");
        limit = here < limit ? here : limit;
    }
    fclose(f);
    return limit;
}

uint64_t cdvr_usable_memory_bytes(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    uint64_t machine = pages > 0 && size > 0 ? (uint64_t)pages * (uint64_t)size : 0;
    uint64_t group = cdvr_cgroup_memory_limit("/proc/self/cgroup", "/sys/fs/cgroup");
    return group < machine ? group : machine;
}
