/* core/base/memory.c - large buffers on transparent huge pages (cdvr/memory.h). */
#include "cdvr/memory.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

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
