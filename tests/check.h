/* tests/check.h - minimal assertion helpers for the C unit tests (ctest runs each binary).
 * CHECK(cond, fmt, ...) records a failure and continues; the test's main returns
 * check_finish(), which prints "N passed, N failed" and returns nonzero on any failure. */
#ifndef CDVR_TESTS_CHECK_H
#define CDVR_TESTS_CHECK_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

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

/* Directory of ../shared/data (env CDVR_SHARED_DATA), or NULL. */
static inline const char *check_shared_data(void)
{
    const char *dir = getenv("CDVR_SHARED_DATA");
    return (dir && *dir) ? dir : NULL;
}

#endif
