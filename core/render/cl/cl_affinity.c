/* core/render/cl/cl_affinity.c - PoCL's worker threads pinned where that is safe (cdvr/device.h,
 * cdvr_cl_default_affinity). */
#define _GNU_SOURCE /* sched_getaffinity, CPU_ISSET */
#include <sched.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/device.h"

/* 1 when this process may run on every online CPU and those are CPUs 0 .. n-1: PoCL pins
 * worker i to CPU i for i below its thread count (at most the CPUs it found), and aborts
 * when a pin is refused, as it is outside a restricted CPU set. */
static int runs_on_every_cpu(void)
{
    long online = sysconf(_SC_NPROCESSORS_ONLN), configured = sysconf(_SC_NPROCESSORS_CONF);
    if (online < 1 || online != configured || online > CPU_SETSIZE)
        return 0;
    cpu_set_t allowed;
    CPU_ZERO(&allowed);
    if (sched_getaffinity(0, sizeof allowed, &allowed) != 0 || CPU_COUNT(&allowed) != online)
        return 0;
    for (long cpu = 0; cpu < online; cpu++)
        if (!CPU_ISSET((int)cpu, &allowed))
            return 0;
    return 1;
}

int cdvr_cl_default_affinity(void)
{
    /* a POCL_AFFINITY that a cdvr parent set (children inherit it) is decided afresh: this
       process may run in a CPU set of its own */
    const char *inherited = getenv("CDVR_CL_AFFINITY_SET");
    if (inherited && strcmp(inherited, "1") == 0) {
        unsetenv("POCL_AFFINITY");
        unsetenv("CDVR_CL_AFFINITY_SET");
    }
    const char *own = getenv("CDVR_CL_AFFINITY");
    if (own && strcmp(own, "0") == 0)
        return 0;
    /* the user's own PoCL settings win; a thread count of their choosing may exceed the CPUs */
    if (getenv("POCL_AFFINITY") || getenv("POCL_MAX_PTHREAD_COUNT") ||
        getenv("POCL_PTHREAD_MIN_THREADS") || !runs_on_every_cpu())
        return 0;
    /* putenv with strings of static storage: setenv's copies on the heap made LeakSanitizer's
       tracer crash at exit on a bogus thread-local block (sanitizer CI, lua_test_fetch_probe's
       child, every run; with these strings not once) */
    static char pin[] = "POCL_AFFINITY=1", mark[] = "CDVR_CL_AFFINITY_SET=1";
    return putenv(pin) == 0 && putenv(mark) == 0;
}
