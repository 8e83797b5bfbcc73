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

/* ---- stage 2 beyond LZO (stage2_seg.c) ------------------------------------------------------
 * Codecs by the number the chunk index records (store.c): 1 LZO1X-1, 2 LZ4 (LZ4_compress_default),
 * 3 zstd (level CDVR_ZSTD_LEVEL). A segmented stored chunk is the payload cut into segments of
 * seg bytes (the last one shorter), each compressed on its own, behind a segment table:
 *     0  u32     seg: payload bytes per segment (>= 1)
 *     4  u32     n: number of segments, = ceil(payload / seg)
 *     8  u32[n]  stored bytes of each segment (each >= 1)
 *  8+4n  the n compressed segments, back to back; 8 + 4n + their sum = the chunk's stored bytes
 * so a reader unpacks the segments of one chunk on several threads. */
#define CDVR_S2_LZO 1
#define CDVR_S2_LZ4 2
#define CDVR_S2_ZSTD 3
#define CDVR_S2_CODECS 4        /* codec numbers are < this */
#define CDVR_ZSTD_LEVEL 3

/* "none", "lzo", "lz4", "zstd" (codec 0..3), "?" otherwise. */
const char *cdvr_s2_name(unsigned codec);

/* Worst-case bytes of a segmented chunk of n payload bytes cut into seg-byte segments; 0 on
 * overflow or a bad argument. */
size_t cdvr_s2_bound(unsigned codec, size_t n, size_t seg);

/* Compresses in[0..n) into out (out_cap >= cdvr_s2_bound) as a segmented chunk. */
cdvr_status cdvr_s2_pack(unsigned codec, const uint8_t *in, size_t n, size_t seg, uint8_t *out,
                         size_t out_cap, size_t *out_n, cdvr_error *err);

/* Undoes a segmented chunk: in[0..n) -> exactly expect bytes into out, on up to `threads`
 * threads (0: one per online core; never more than the segments). Checks the segment table
 * against n and expect before anything is decoded (a table claiming more than the chunk ->
 * CDVR_ERR_CORRUPT); the output is the same for every thread count. */
cdvr_status cdvr_s2_unpack(unsigned codec, const uint8_t *in, size_t n, uint8_t *out,
                           size_t expect, int threads, cdvr_error *err);
/* The same, adding to *cpu_ms the CPU time all its threads took (cdvr_thread_cpu_ms). */
cdvr_status cdvr_s2_unpack_cpu(unsigned codec, const uint8_t *in, size_t n, uint8_t *out,
                               size_t expect, int threads, double *cpu_ms, cdvr_error *err);

/* Decompresses one unsegmented LZO chunk or one segment of the given codec: exactly expect
 * bytes (CDVR_ERR_CORRUPT otherwise). */
cdvr_status cdvr_s2_decompress(unsigned codec, const uint8_t *in, size_t n, uint8_t *out,
                               size_t expect, cdvr_error *err);

/* ---- this machine's unpack rates (stage2_rates.c) -------------------------------------------
 * mbps[c]: payload MB/s (10^6 bytes) of unpacking codec c (1..3) on one thread, the median of
 * 7 unpacks of a fixed 2 MiB calibration volume (noisy smooth ramps, stage2_rates.c) cut
 * into 1 MiB segments, rounded to 0.1 MB/s. Measured once per machine (CPU model, cdvr
 * version, LZO, LZ4 and zstd versions) and remembered in the cache (cdvr/cache.h); without
 * a cache directory every call measures again (about 0.1 s). mbps[0] is 0. */
typedef struct cdvr_s2_rates {
    double mbps[CDVR_S2_CODECS];
    int from_cache;              /* 1: read from the cache, 0: measured by this call */
} cdvr_s2_rates;

cdvr_status cdvr_s2_unpack_rates(cdvr_s2_rates *out, cdvr_error *err);

/* The rates of a cache entry's content (n bytes, "lzo R lz4 R zstd R", each rate in
 * (0, 1e9) MB/s) into out (from_cache 0): 1, or 0 with out zeroed when it is not that. */
int cdvr_s2_rates_parse(const unsigned char *content, size_t n, cdvr_s2_rates *out);

#endif
