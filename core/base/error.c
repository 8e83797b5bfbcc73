#include "cdvr/error.h"

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

cdvr_status cdvr_error_set(cdvr_error *err, cdvr_status status, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
        err->status = status;
    }
    return status;
}

void cdvr_error_clear(cdvr_error *err)
{
    if (err) {
        err->status = CDVR_OK;
        err->msg[0] = '\0';
    }
}

const char *cdvr_status_name(cdvr_status status)
{
    switch (status) {
    case CDVR_OK: return "ok";
    case CDVR_ERR_ARG: return "argument";
    case CDVR_ERR_IO: return "io";
    case CDVR_ERR_FORMAT: return "format";
    case CDVR_ERR_CORRUPT: return "corrupt";
    case CDVR_ERR_NOMEM: return "nomem";
    case CDVR_ERR_UNSUPPORTED: return "unsupported";
    case CDVR_ERR_DEVICE: return "device";
    case CDVR_ERR_CANCELLED: return "cancelled";
    }
    return "unknown";
}

int cdvr_size_mul(size_t a, size_t b, size_t *out)
{
    if (a != 0 && b > SIZE_MAX / a)
        return 0;
    *out = a * b;
    return 1;
}

int cdvr_size_add(size_t a, size_t b, size_t *out)
{
    if (b > SIZE_MAX - a)
        return 0;
    *out = a + b;
    return 1;
}

int cdvr_grow_bytes(uint8_t **buf, size_t *cap, uint64_t need)
{
    if (need <= *cap && *buf)
        return 1;
    if (need > SIZE_MAX)
        return 0;
    uint8_t *nb = realloc(*buf, need ? (size_t)need : 1);
    if (!nb)
        return 0;
    *buf = nb;
    *cap = (size_t)need;
    return 1;
}

void cdvr_swap_buffers(uint8_t **a, size_t *a_cap, uint8_t **b, size_t *b_cap)
{
    uint8_t *buf = *a;
    size_t cap = *a_cap;
    *a = *b;
    *a_cap = *b_cap;
    *b = buf;
    *b_cap = cap;
}
