/* core/codec/stage2/stage2_lzo.c - LZO1X-1 stage 2 through liblzo2 (see stage2.h). */
#include "stage2.h"

#include <lzo/lzo1x.h>
#include <stdlib.h>

size_t cdvr_lzo_bound(size_t n)
{
    size_t extra = n / 16 + 64 + 3, bound;
    return cdvr_size_add(n, extra, &bound) ? bound : 0;
}

static cdvr_status lzo_ready(cdvr_error *err)
{
    /* lzo_init only checks the library's configuration; it keeps no state we depend on. */
    if (lzo_init() != LZO_E_OK)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "lzo: lzo_init failed");
    return CDVR_OK;
}

cdvr_status cdvr_lzo_compress(const uint8_t *in, size_t n, uint8_t *out, size_t out_cap,
                              size_t *out_n, cdvr_error *err)
{
    size_t bound = cdvr_lzo_bound(n);
    if (bound == 0 || out_cap < bound || n > (size_t)LZO_UINT_MAX)
        return cdvr_error_set(err, CDVR_ERR_ARG, "lzo: %zu bytes need an output buffer of "
                              "%zu bytes, got %zu", n, bound, out_cap);
    cdvr_status st = lzo_ready(err);
    if (st != CDVR_OK)
        return st;
    void *work = malloc(LZO1X_1_MEM_COMPRESS);
    if (!work)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "lzo: no memory for the work buffer");
    lzo_uint len = 0;
    int rc = lzo1x_1_compress(in, (lzo_uint)n, out, &len, work);
    free(work);
    if (rc != LZO_E_OK)
        return cdvr_error_set(err, CDVR_ERR_IO, "lzo: compression failed (code %d)", rc);
    *out_n = (size_t)len;
    return CDVR_OK;
}

cdvr_status cdvr_lzo_decompress(const uint8_t *in, size_t n, uint8_t *out, size_t expect,
                                cdvr_error *err)
{
    if (n > (size_t)LZO_UINT_MAX || expect > (size_t)LZO_UINT_MAX)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "LZO sizes too large (%zu -> %zu)", n,
                              expect);
    cdvr_status st = lzo_ready(err);
    if (st != CDVR_OK)
        return st;
    lzo_uint len = (lzo_uint)expect;
    int rc = lzo1x_decompress_safe(in, (lzo_uint)n, out, &len, NULL);
    if (rc != LZO_E_OK)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "LZO data is corrupt (lzo error %d)", rc);
    if ((size_t)len != expect)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT,
                              "LZO data decodes to %zu bytes, expected %zu", (size_t)len,
                              expect);
    return CDVR_OK;
}

int cdvr_lzo_keep(size_t payload, size_t compressed, double min_saving)
{
    if (compressed >= payload)
        return 0;
    return (double)compressed <= (double)payload * (1.0 - min_saving);
}
