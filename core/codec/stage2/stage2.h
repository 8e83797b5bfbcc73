/* core/codec/stage2/stage2.h - internal: stage 2 of the store (DESIGN.md section 4.2), LZO1X-1 over one
 * chunk's codec payload, and the rule that decides whether a chunk keeps it. */
#ifndef CDVR_STAGE2_H
#define CDVR_STAGE2_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"

/* Worst-case LZO1X output for n input bytes (n + n/16 + 64 + 3); 0 if that overflows. */
size_t cdvr_lzo_bound(size_t n);

/* Compresses in[0..n) into out (out_cap >= cdvr_lzo_bound(n)); *out_n = compressed size. */
cdvr_status cdvr_lzo_compress(const uint8_t *in, size_t n, uint8_t *out, size_t out_cap,
                              size_t *out_n, cdvr_error *err);

/* Decompresses exactly expect bytes into out (lzo1x_decompress_safe: never reads or writes
 * outside the buffers). Anything else (corrupt input, wrong output length) -> CDVR_ERR_CORRUPT
 * with the reason; the caller prefixes file, variant and chunk. */
cdvr_status cdvr_lzo_decompress(const uint8_t *in, size_t n, uint8_t *out, size_t expect,
                                cdvr_error *err);

/* 1 if stage 2 pays: compressed <= payload * (1 - min_saving) (and strictly smaller than the
 * payload, so a stored LZO chunk always saves at least one byte). */
int cdvr_lzo_keep(size_t payload, size_t compressed, double min_saving);

#endif
