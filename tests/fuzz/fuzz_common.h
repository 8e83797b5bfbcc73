/* tests/fuzz/fuzz_common.h - helpers shared by the libFuzzer targets in tests/fuzz/ (see
 * tests/fuzz/README for how to build and run them). Header-only so that tests/test_fuzz_smoke.c
 * can include every target source into one translation unit. */
#ifndef CDVR_FUZZ_COMMON_H
#define CDVR_FUZZ_COMMON_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* Largest payload or decoded size a target decodes: beyond it an input only asks for memory
 * (a store header may legitimately promise gigabytes), which is not what these targets look
 * for, and libFuzzer would report it as an out-of-memory crash. */
#define FUZZ_MAX_BYTES ((size_t)64 << 20)

/* A differential check failed: crash so that the fuzzer keeps the input. */
#define FUZZ_ASSERT(cond)                                                                  \
    do {                                                                                   \
        if (!(cond)) {                                                                     \
            fprintf(stderr, "%s:%d: fuzz assertion failed: %s\n", __FILE__, __LINE__, #cond); \
            abort();                                                                       \
        }                                                                                  \
    } while (0)

/* What the code under test made of the inputs: each target records whether its input was
 * accepted (opened, decoded, loaded) or rejected with an error. tests/test_fuzz_smoke.c checks
 * that every seed is accepted and that mutants are rejected too; libFuzzer ignores it. The one
 * counting context of the fuzz targets. */
typedef struct fuzz_outcomes {
    size_t accepted, rejected;
} fuzz_outcomes;
static fuzz_outcomes fuzz_outcome_counts;
#define FUZZ_OUTCOME(accepted_)                                                            \
    ((accepted_) ? (void)fuzz_outcome_counts.accepted++ : (void)fuzz_outcome_counts.rejected++)

/* Writes data to a new temporary file whose name ends in suffix; path receives its name
 * (caller unlinks). 0 on failure. */
static inline int fuzz_write_temp(const uint8_t *data, size_t size, const char *suffix,
                                  char path[256])
{
    const char *dir = getenv("TMPDIR");
    int n = snprintf(path, 256, "%s/cdvr_fuzz_XXXXXX%s", dir && *dir ? dir : "/tmp", suffix);
    if (n < 0 || n >= 256)
        return 0;
    int fd = mkstemps(path, (int)strlen(suffix));
    if (fd < 0)
        return 0;
    size_t done = 0;
    while (done < size) {
        ssize_t w = write(fd, data + done, size - done);
        if (w <= 0)
            break;
        done += (size_t)w;
    }
    close(fd);
    if (done != size) {
        unlink(path);
        return 0;
    }
    return 1;
}

static inline uint64_t fuzz_le(const uint8_t *p, int nbytes)
{
    uint64_t v = 0;
    for (int i = 0; i < nbytes; i++)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

static inline void fuzz_put_le(uint8_t *p, uint64_t v, int nbytes)
{
    for (int i = 0; i < nbytes; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

#endif
