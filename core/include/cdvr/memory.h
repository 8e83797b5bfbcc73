/* cdvr/memory.h - large buffers on transparent huge pages.
 *
 * A ray caster gathers voxels at random from a volume of tens to thousands of MB: with 4 KiB
 * pages most new voxel rows it reads miss the TLB. Linux backs a range with 2 MiB pages when
 * the system allows it: always, or (the Debian default, "madvise") for ranges marked
 * MADV_HUGEPAGE, as these are. With huge pages off, CDVR_HUGE_PAGES=0 in the environment, or
 * elsewhere, these are ordinary aligned buffers.
 */
#ifndef CDVR_MEMORY_H
#define CDVR_MEMORY_H

#include <stddef.h>
#include <stdint.h>

/* Size and alignment of a huge page (x86-64, and arm64 with 4 KiB base pages). */
#define CDVR_HUGE_PAGE_BYTES ((size_t)2 << 20)

/* A buffer of `bytes` (0 counts as 1), freed with free(): from CDVR_HUGE_PAGE_BYTES up aligned
 * to a huge page and marked for huge pages (unless CDVR_HUGE_PAGES=0), below that aligned to
 * a 4 KiB page. zero: filled with zeros. NULL when out of memory. */
void *cdvr_alloc_large(size_t bytes, int zero);

/* Makes *buf (a buffer freed with free(), or NULL with *cap 0) hold at least `need` bytes,
 * without keeping its contents: a buffer that holds them already stays; else a new one from
 * cdvr_alloc_large replaces it, from a huge page up rounded to whole huge pages (*cap says how
 * many bytes it holds), so a buffer refilled with sizes that differ a little grows rarely. For
 * buffers read into or unpacked into again and again (the player's chunks): on this kind of VM
 * a 4 KiB page fault costs microseconds, and a fresh 16 MB buffer takes 4,096 of them.
 * Returns 1, or 0 when out of memory (the old buffer is kept then). */
int cdvr_grow_large(uint8_t **buf, size_t *cap, uint64_t need);

/* 1 when the mapping that holds p may be backed by huge pages (/proc/self/smaps lists it
 * THPeligible), 0 when not (or no mapping holds p), -1 when the kernel does not say. For
 * tests and diagnostics. */
int cdvr_on_huge_pages(const void *p);

/* The memory this process may fill, page cache included, in bytes: the machine's
 * (_SC_PHYS_PAGES), or less where a control group limits it (a batch job's or a container's
 * memory limit: cdvr_cgroup_memory_limit over /proc/self/cgroup and /sys/fs/cgroup); 0 when
 * unknown. Stage 2's AUTO asks it whether a series fits in the page cache (store.h). */
uint64_t cdvr_usable_memory_bytes(void);

/* The smallest memory limit of the control groups listed in cgroup_file (the format of
 * /proc/self/cgroup) and their ancestors, read under root (the cgroup mount, /sys/fs/cgroup):
 * cgroup v2 ("0::PATH": ROOT/PATH/memory.max and its parents', "max" meaning none) and v1
 * ("N:...memory...:PATH": ROOT/memory/PATH/memory.limit_in_bytes, values of 2^62 and more
 * meaning none). UINT64_MAX when none is set or nothing can be read. For tests: any root. */
uint64_t cdvr_cgroup_memory_limit(const char *cgroup_file, const char *root);

#endif
