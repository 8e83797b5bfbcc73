/* tests/test_memory.c - large buffers (cdvr/memory.h): aligned (4 KiB below a huge page, 2 MiB
 * from one up), zero-filled when asked, writable to the last byte, freed with free(); from a
 * huge page up their mapping is eligible for huge pages whenever the system allows them
 * (/sys/kernel/mm/transparent_hugepage/enabled "always" or "madvise", not disabled for the
 * process, CDVR_HUGE_PAGES not 0), and a volume's voxels (cdvr_volume_create) are such a
 * buffer; cdvr_grow_large grows a kept buffer into one. The memory a process may fill: the
 * smallest control-group limit on the way to the root, v1 and v2, over a made-up cgroup tree
 * (cdvr_cgroup_memory_limit), and never more than the machine's (cdvr_usable_memory_bytes). */
#include "check.h"

#include "cdvr/memory.h"
#include "cdvr/volume.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>
#include <unistd.h>

/* The system's transparent huge page mode: 'a' always, 'm' madvise, 'n' never, 0 unknown. */
static char thp_mode(void)
{
    FILE *f = fopen("/sys/kernel/mm/transparent_hugepage/enabled", "r");
    char line[128] = "";
    if (!f)
        return 0;
    if (!fgets(line, sizeof line, f))
        line[0] = '\0';
    fclose(f);
#ifdef PR_GET_THP_DISABLE
    if (prctl(PR_GET_THP_DISABLE, 0, 0, 0, 0) == 1)
        return 'n';
#endif
    return strstr(line, "[always]") ? 'a' : strstr(line, "[madvise]") ? 'm'
         : strstr(line, "[never]")  ? 'n' : 0;
}

/* p's mapping is eligible for huge pages exactly when the system allows them (unchecked where
 * the mode or the kernel's answer is unknown). */
static void expect_huge(const void *p, char mode, const char *what)
{
    int eligible = cdvr_on_huge_pages(p);
    if (mode && eligible >= 0)
        CHECK(eligible == (mode != 'n'), "%s: huge pages %s (mode %c)", what,
              eligible ? "eligible" : "not eligible", mode);
}

static int all_zero(const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (p[i])
            return 0;
    return 1;
}

static void test_sizes(char mode)
{
    const size_t sizes[] = {0, 1, 4095, 4096, CDVR_HUGE_PAGE_BYTES - 1, CDVR_HUGE_PAGE_BYTES,
                            CDVR_HUGE_PAGE_BYTES + 1, 5 * CDVR_HUGE_PAGE_BYTES + 3};
    for (size_t i = 0; i < sizeof sizes / sizeof *sizes; i++) {
        size_t n = sizes[i], align = n >= CDVR_HUGE_PAGE_BYTES ? CDVR_HUGE_PAGE_BYTES : 4096;
        for (int zero = 0; zero <= 1; zero++) {
            uint8_t *p = cdvr_alloc_large(n, zero);
            CHECK(p != NULL, "%zu bytes", n);
            if (!p)
                continue;
            CHECK((uintptr_t)p % align == 0, "%zu bytes at %p: aligned to %zu", n, (void *)p,
                  align);
            if (zero)
                CHECK(all_zero(p, n ? n : 1), "%zu bytes zero-filled", n);
            memset(p, 0xA5, n ? n : 1);
            CHECK(p[n ? n - 1 : 0] == 0xA5, "%zu bytes writable", n);
            if (n >= CDVR_HUGE_PAGE_BYTES)
                expect_huge(p, mode, "a large buffer");
            free(p);
        }
    }
}

/* In madvise mode nothing else is eligible: a stack variable is not. */
static void test_unmarked(char mode)
{
    int local = 0;
    if (mode == 'm')
        CHECK(cdvr_on_huge_pages(&local) != 1, "the stack is not marked");
    CHECK(cdvr_on_huge_pages(NULL) != 1, "no mapping at NULL");
}

/* CDVR_HUGE_PAGES=0: aligned the same, not marked. */
static void test_off(char mode)
{
    setenv("CDVR_HUGE_PAGES", "0", 1);
    uint8_t *p = cdvr_alloc_large(3 * CDVR_HUGE_PAGE_BYTES, 1);
    CHECK(p && (uintptr_t)p % CDVR_HUGE_PAGE_BYTES == 0 && all_zero(p, 3 * CDVR_HUGE_PAGE_BYTES),
          "CDVR_HUGE_PAGES=0: an aligned zeroed buffer");
    if (p && mode == 'm')
        CHECK(cdvr_on_huge_pages(p) != 1, "CDVR_HUGE_PAGES=0: not marked for huge pages");
    free(p);
    unsetenv("CDVR_HUGE_PAGES");
}

static void test_volume(char mode)
{
    const size_t dims[3] = {256, 256, 64}; /* 4 MiB */
    cdvr_volume *vol = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &vol, &err), err);
    if (!vol)
        return;
    CHECK((uintptr_t)vol->data % CDVR_HUGE_PAGE_BYTES == 0, "voxels aligned to a huge page");
    CHECK(all_zero(vol->data, 256 * 256 * 64), "voxels zero");
    expect_huge(vol->data, mode, "a volume's voxels");
    cdvr_volume_free(vol);
}

/* cdvr_grow_large: grows only when asked for more, whole huge pages from one up (small sizes
 * as asked), the new buffer large-aligned, marked and writable; the old one is freed. */
static void test_grow(char mode)
{
    uint8_t *buf = NULL;
    size_t cap = 0;
    CHECK(cdvr_grow_large(&buf, &cap, 0) && buf && cap == 1, "nothing asked: a byte (cap %zu)",
          cap);
    CHECK(cdvr_grow_large(&buf, &cap, 5000) && cap == 5000 && (uintptr_t)buf % 4096 == 0,
          "small: as asked, page aligned (cap %zu)", cap);
    uint8_t *small = buf;
    CHECK(cdvr_grow_large(&buf, &cap, 4000) && buf == small && cap == 5000,
          "less than held: the same buffer");
    const size_t big = 3 * CDVR_HUGE_PAGE_BYTES + 12345;
    CHECK(cdvr_grow_large(&buf, &cap, big) && cap == 4 * CDVR_HUGE_PAGE_BYTES,
          "large: rounded to whole huge pages (cap %zu)", cap);
    CHECK(buf && (uintptr_t)buf % CDVR_HUGE_PAGE_BYTES == 0, "large: aligned to a huge page");
    if (buf) {
        memset(buf, 0xab, cap); /* writable to the end of what cap says */
        CHECK(buf[cap - 1] == 0xab, "last byte written");
        expect_huge(buf, mode, "a grown buffer");
    }
    uint8_t *large = buf;
    CHECK(cdvr_grow_large(&buf, &cap, 4 * CDVR_HUGE_PAGE_BYTES) && buf == large,
          "exactly the capacity: kept");
    CHECK(cdvr_grow_large(&buf, &cap, 4 * CDVR_HUGE_PAGE_BYTES + 1) &&
              cap == 5 * CDVR_HUGE_PAGE_BYTES,
          "one byte more: a huge page more (cap %zu)", cap);
    CHECK(!cdvr_grow_large(&buf, &cap, (uint64_t)SIZE_MAX) && cap == 5 * CDVR_HUGE_PAGE_BYTES &&
              buf,
          "an impossible size fails and keeps the buffer");
    free(buf);
}

static void write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    CHECK(f != NULL, "cannot write %s", path);
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

static void test_cgroup_limit(void)
{
    char root[] = "/tmp/cdvr_test_cgroup_XXXXXX", path[512], cmd[600];
    if (!mkdtemp(root)) {
        CHECK(0, "mkdtemp");
        return;
    }
    snprintf(cmd, sizeof cmd, "mkdir -p '%s/job/step' '%s/memory/slurm/job' '%s/free'", root,
             root, root);
    CHECK(system(cmd) == 0, "%s", cmd);
    /* v2: the job's limit is below its step's "max" and the root's; v1: the memory
     * controller's hierarchy, a parent's limit, "no limit" written as 2^63 - 4096 */
    static const char *const files[][2] = {
        {"job/memory.max", "1073741824\n"},
        {"job/step/memory.max", "max\n"},
        {"memory.max", "4294967296\n"},
        {"free/memory.max", "max\n"},
        {"memory/slurm/job/memory.limit_in_bytes", "9223372036854771712\n"},
        {"memory/slurm/memory.limit_in_bytes", "536870912\n"},
    };
    for (size_t i = 0; i < sizeof files / sizeof *files; i++) {
        snprintf(path, sizeof path, "%s/%s", root, files[i][0]);
        write_text(path, files[i][1]);
    }
    static const struct { const char *cgroup; uint64_t want; } cases[] = {
        {"0::/job/step\n", 1073741824ull},
        {"0::/free\n", 4294967296ull},
        {"4:memory:/slurm/job\n3:cpu:/slurm/job\n0::/free\n", 536870912ull},
        {"7:cpuacct,memory:/slurm/job\n", 536870912ull},
        {"4:cpu:/job\n", UINT64_MAX},
        {"0::/nowhere\n", 4294967296ull},
        {"garbage\n", UINT64_MAX},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char file[512];
        snprintf(file, sizeof file, "%s/cgroup%zu", root, i);
        write_text(file, cases[i].cgroup);
        uint64_t got = cdvr_cgroup_memory_limit(file, root);
        CHECK(got == cases[i].want, "cgroup case %zu: %llu, want %llu", i,
              (unsigned long long)got, (unsigned long long)cases[i].want);
    }
    snprintf(path, sizeof path, "%s/missing", root);
    CHECK(cdvr_cgroup_memory_limit(path, root) == UINT64_MAX, "no cgroup file: no limit");
    snprintf(path, sizeof path, "%s/empty", root);
    CHECK(cdvr_cgroup_memory_limit("/proc/self/cgroup", path) == UINT64_MAX,
          "no cgroup tree: no limit");
    uint64_t usable = cdvr_usable_memory_bytes();
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    CHECK(usable > 0 && usable <= (uint64_t)pages * (uint64_t)size,
          "usable memory %llu within the machine's", (unsigned long long)usable);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", root);
    CHECK(system(cmd) == 0, "%s", cmd);
}

int main(void)
{
    char mode = thp_mode();
    printf("transparent huge pages: %s\n", mode == 'a' ? "always" : mode == 'm' ? "madvise"
                                           : mode == 'n' ? "never" : "unknown");
    test_off(mode); /* first: no range of this process is marked yet */
    test_sizes(mode);
    test_unmarked(mode);
    test_volume(mode);
    test_grow(mode);
    test_cgroup_limit();
    return check_finish();
}
