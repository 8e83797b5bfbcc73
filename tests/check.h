/* tests/check.h - minimal assertion helpers for the C unit tests (ctest runs each binary).
 * CHECK(cond, fmt, ...) records a failure and continues; the test's main returns
 * check_finish(), which prints "N passed, N failed" and returns nonzero on any failure. */
#ifndef CDVR_TESTS_CHECK_H
#define CDVR_TESTS_CHECK_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int check_passed_count = 0, check_failed_count = 0;

#define CHECK(cond, ...)                                                                  \
    do {                                                                                  \
        if (cond) {                                                                       \
            check_passed_count++;                                                         \
        } else {                                                                          \
            check_failed_count++;                                                         \
            fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__, #cond);      \
            fprintf(stderr, __VA_ARGS__);                                                 \
            fputc('\n', stderr);                                                          \
        }                                                                                 \
    } while (0)

#define CHECK_OK(status, err) CHECK((status) == CDVR_OK, "status %d: %s", (int)(status), (err).msg)

static inline int check_finish(void)
{
    printf("%d passed, %d failed\n", check_passed_count, check_failed_count);
    return check_failed_count ? 1 : 0;
}

/* The exit status of a test whose OpenCL device could not be opened (why: the reason): 77,
 * skipped, unless CDVR_REQUIRE_OPENCL is set (scripts/setup.sh sets it where it installed
 * PoCL): then 1, so a kernel that no longer builds fails the suite instead of skipping it. */
static inline int check_opencl_unavailable(const char *why)
{
    const char *required = getenv("CDVR_REQUIRE_OPENCL");
    if (required && *required && strcmp(required, "0") != 0) {
        printf("FAIL: OpenCL required (CDVR_REQUIRE_OPENCL) but not available: %s\n", why);
        return 1;
    }
    printf("skip: no OpenCL device: %s\n", why);
    return 77;
}

/* The main() of a test whose subject this build leaves out (why: "built without OpenCL"):
 * says so and exits 77, skipped. */
#define CHECK_SKIPPED_MAIN(why)                                                                   \
    int main(void)                                                                                \
    {                                                                                             \
        printf("skip: %s\n", why);                                                                \
        return 77;                                                                                \
    }

/* Directory of ../shared/data (env CDVR_SHARED_DATA), or NULL. */
static inline const char *check_shared_data(void)
{
    const char *dir = getenv("CDVR_SHARED_DATA");
    return (dir && *dir) ? dir : NULL;
}

#endif
