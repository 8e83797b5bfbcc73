/* cdvr/error.h - status codes and error messages shared by every core module.
 *
 * Every core function that can fail returns a cdvr_status and, on failure,
 * fills a caller-provided cdvr_error whose message names the file, the object
 * and the reason ("engine.nrrd: dims 256x256x128 need 8388608 bytes, file has 100").
 * A NULL cdvr_error pointer is allowed everywhere; the message is then dropped.
 */
#ifndef CDVR_ERROR_H
#define CDVR_ERROR_H

#include <stddef.h>
#include <stdint.h>

#define CDVR_ERRMSG_MAX 512

typedef enum cdvr_status {
    CDVR_OK = 0,
    CDVR_ERR_ARG,         /* bad argument or parameter value */
    CDVR_ERR_IO,          /* file missing, unreadable, short write */
    CDVR_ERR_FORMAT,      /* file readable but not in the expected format */
    CDVR_ERR_CORRUPT,     /* store failed a bounds or CRC check */
    CDVR_ERR_NOMEM,       /* allocation failed or size overflows size_t */
    CDVR_ERR_UNSUPPORTED, /* valid request that this build cannot do */
    CDVR_ERR_DEVICE,      /* OpenCL / GL failure */
    CDVR_ERR_CANCELLED    /* stopped on request (Ctrl-C in the console) */
} cdvr_status;

typedef struct cdvr_error {
    cdvr_status status;
    char msg[CDVR_ERRMSG_MAX];
} cdvr_error;

/* Fills err (if not NULL) with status and a printf-formatted message; returns status. */
cdvr_status cdvr_error_set(cdvr_error *err, cdvr_status status, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Clears err (status CDVR_OK, empty message). */
void cdvr_error_clear(cdvr_error *err);

/* Short name of a status ("io", "corrupt", ...). */
const char *cdvr_status_name(cdvr_status status);

/* Overflow-checked size arithmetic: return 1 and store the result, or 0 on overflow. */
int cdvr_size_mul(size_t a, size_t b, size_t *out);
int cdvr_size_add(size_t a, size_t b, size_t *out);

/* A byte buffer *buf of *cap bytes grown to hold need (realloc: the contents are kept;
 * need 0 allocates one byte): 1 when it holds need bytes, 0 when out of memory or need is
 * past SIZE_MAX (*buf and *cap unchanged). */
int cdvr_grow_bytes(uint8_t **buf, size_t *cap, uint64_t need);
/* Exchanges two such buffers (contents and capacities), no copy. */
void cdvr_swap_buffers(uint8_t **a, size_t *a_cap, uint8_t **b, size_t *b_cap);

#endif
