/* tests/test_cl_affinity.c - cdvr_cl_default_affinity (cdvr/device.h): PoCL's workers are
 * pinned (POCL_AFFINITY=1) only where that is safe: never over the user's own PoCL settings
 * or CDVR_CL_AFFINITY=0, never inside a restricted CPU set (PoCL would pin outside it, or
 * abort), also when a cdvr parent set it (inherited); and once it is set the device opens
 * with PoCL's workers each on one CPU (this process made no OpenCL call before). */
#define _GNU_SOURCE /* sched_setaffinity */
#include <dirent.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/device.h"
#include "check.h"

#if CDVR_HAVE_OPENCL

static const char *pocl_affinity(void)
{
    const char *v = getenv("POCL_AFFINITY");
    return v ? v : "(unset)";
}

/* One refusal: with `name` set to `value`, nothing is set. */
static void refused_with(const char *name, const char *value)
{
    setenv(name, value, 1);
    unsetenv("POCL_AFFINITY");
    CHECK(cdvr_cl_default_affinity() == 0 && !getenv("POCL_AFFINITY"),
          "%s=%s: POCL_AFFINITY %s", name, value, pocl_affinity());
    unsetenv(name);
}

static void user_settings_win(void)
{
    refused_with("CDVR_CL_AFFINITY", "0");
    refused_with("POCL_MAX_PTHREAD_COUNT", "4");
    refused_with("POCL_PTHREAD_MIN_THREADS", "3");
    setenv("POCL_AFFINITY", "0", 1);
    CHECK(cdvr_cl_default_affinity() == 0 && strcmp(pocl_affinity(), "0") == 0,
          "the user's POCL_AFFINITY=0 became %s", pocl_affinity());
    unsetenv("POCL_AFFINITY");
}

/* Inside a CPU set without CPU 0 (or, on one CPU, nothing to test) nothing is set. */
static void restricted_cpu_set(const cpu_set_t *all)
{
    long online = sysconf(_SC_NPROCESSORS_ONLN);
    if (online < 2) {
        printf("one CPU: the restricted set is not tested\n");
        return;
    }
    cpu_set_t last;
    CPU_ZERO(&last);
    CPU_SET((int)online - 1, &last);
    CHECK(sched_setaffinity(0, sizeof last, &last) == 0, "could not restrict to CPU %ld",
          online - 1);
    CHECK(cdvr_cl_default_affinity() == 0 && !getenv("POCL_AFFINITY"),
          "on CPU %ld alone: POCL_AFFINITY %s", online - 1, pocl_affinity());
    CHECK(sched_setaffinity(0, sizeof *all, all) == 0, "could not restore the CPU set");
}

/* Threads of this process whose CPU set is one CPU (PoCL's pinned workers). */
static int pinned_threads(void)
{
    DIR *tasks = opendir("/proc/self/task");
    if (!tasks)
        return -1;
    int pinned = 0;
    for (struct dirent *t; (t = readdir(tasks)) != NULL;) {
        cpu_set_t set;
        CPU_ZERO(&set);
        pid_t tid = (pid_t)atoi(t->d_name);
        if (tid > 0 && sched_getaffinity(tid, sizeof set, &set) == 0 && CPU_COUNT(&set) == 1)
            pinned++;
    }
    closedir(tasks);
    return pinned;
}

int main(void)
{
    unsetenv("CDVR_CL_AFFINITY");
    unsetenv("POCL_MAX_PTHREAD_COUNT");
    unsetenv("POCL_PTHREAD_MIN_THREADS");
    unsetenv("POCL_AFFINITY");
    user_settings_win();
    cpu_set_t all;
    CPU_ZERO(&all);
    CHECK(sched_getaffinity(0, sizeof all, &all) == 0, "sched_getaffinity");
    restricted_cpu_set(&all);
    /* what a cdvr parent set is inherited, and decided afresh in a restricted set */
    setenv("POCL_AFFINITY", "1", 1);
    setenv("CDVR_CL_AFFINITY_SET", "1", 1);
    restricted_cpu_set(&all);
    CHECK(sysconf(_SC_NPROCESSORS_ONLN) < 2 || !getenv("CDVR_CL_AFFINITY_SET"),
          "the inherited mark stayed");
    unsetenv("POCL_AFFINITY");
    unsetenv("CDVR_CL_AFFINITY_SET");
    long online = sysconf(_SC_NPROCESSORS_ONLN);
    int everywhere = CPU_COUNT(&all) == online && online == sysconf(_SC_NPROCESSORS_CONF);
    int set = cdvr_cl_default_affinity();
    if (everywhere) {
        CHECK(set == 1 && strcmp(pocl_affinity(), "1") == 0, "on every CPU: returned %d, %s",
              set, pocl_affinity());
        cdvr_cl_default_affinity(); /* decided afresh: the same */
        CHECK(strcmp(pocl_affinity(), "1") == 0, "a second call left %s", pocl_affinity());
    } else {
        printf("this process may not run on every CPU: pinning is not tested\n");
        CHECK(set == 0 && !getenv("POCL_AFFINITY"), "restricted: %s", pocl_affinity());
    }
    cdvr_cl *cl = NULL;
    cdvr_error err;
    if (cdvr_cl_open(&cl, &err)) {
        check_finish();
        return check_opencl_unavailable(err.msg);
    }
    /* PoCL's CPU device: a worker per compute unit, each on its own CPU once pinned */
    const cdvr_cl_info *info = cdvr_cl_get_info(cl);
    if (everywhere && online > 1 && !info->is_gpu && strstr(info->platform, "Portable"))
        CHECK(pinned_threads() >= (int)info->compute_units,
              "%d threads pinned, %u compute units", pinned_threads(), info->compute_units);
    cdvr_cl_close(cl);
    return check_finish();
}

#else
CHECK_SKIPPED_MAIN("built without OpenCL")
#endif
