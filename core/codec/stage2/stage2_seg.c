/* core/codec/stage2/stage2_seg.c - stage 2 beyond LZO: LZ4 (liblz4) and zstd (libzstd) and the
 * segmented framing of a chunk (stage2.h), unpacked on several threads. */
#include "stage2.h"

#include "cdvr/timing.h"

#include <lz4.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <zstd.h>

const char *cdvr_s2_name(unsigned codec)
{
    static const char *const names[] = {"none", "lzo", "lz4", "zstd"};
    return codec < CDVR_S2_CODECS ? names[codec] : "?";
}

static size_t one_bound(unsigned codec, size_t n)
{
    switch (codec) {
    case CDVR_S2_LZO:
        return cdvr_lzo_bound(n);
    case CDVR_S2_LZ4:
        return n <= (size_t)LZ4_MAX_INPUT_SIZE ? (size_t)LZ4_compressBound((int)n) : 0;
    case CDVR_S2_ZSTD: {
        size_t b = ZSTD_compressBound(n);
        return ZSTD_isError(b) ? 0 : b;
    }
    default:
        return 0;
    }
}

static uint32_t rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void wr32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

size_t cdvr_s2_bound(unsigned codec, size_t n, size_t seg)
{
    if (seg == 0 || seg > UINT32_MAX || n == 0)
        return 0;
    size_t nseg = n / seg + (n % seg != 0), table, total, full = one_bound(codec, seg),
           last = one_bound(codec, n - (nseg - 1) * seg), body;
    if (nseg > UINT32_MAX || full == 0 || last == 0 || full > UINT32_MAX ||
        !cdvr_size_mul(nseg, 4, &table) || !cdvr_size_add(table, 8, &table) ||
        !cdvr_size_mul(nseg - 1, full, &body) || !cdvr_size_add(body, last, &body) ||
        !cdvr_size_add(table, body, &total))
        return 0;
    return total;
}

static cdvr_status compress_one(unsigned codec, const uint8_t *in, size_t n, uint8_t *out,
                                size_t cap, size_t *out_n, cdvr_error *err)
{
    switch (codec) {
    case CDVR_S2_LZO:
        return cdvr_lzo_compress(in, n, out, cap, out_n, err);
    case CDVR_S2_LZ4: {
        if (n > (size_t)LZ4_MAX_INPUT_SIZE || cap > (size_t)INT32_MAX)
            cap = (size_t)INT32_MAX;
        int r = n > (size_t)LZ4_MAX_INPUT_SIZE ? 0
                    : LZ4_compress_default((const char *)in, (char *)out, (int)n, (int)cap);
        if (r <= 0)
            return cdvr_error_set(err, CDVR_ERR_IO, "lz4: compression of %zu bytes failed", n);
        *out_n = (size_t)r;
        return CDVR_OK;
    }
    case CDVR_S2_ZSTD: {
        size_t r = ZSTD_compress(out, cap, in, n, CDVR_ZSTD_LEVEL);
        if (ZSTD_isError(r))
            return cdvr_error_set(err, CDVR_ERR_IO, "zstd: compression of %zu bytes failed: %s",
                                  n, ZSTD_getErrorName(r));
        *out_n = r;
        return CDVR_OK;
    }
    default:
        return cdvr_error_set(err, CDVR_ERR_ARG, "stage 2: unknown codec %u", codec);
    }
}

cdvr_status cdvr_s2_pack(unsigned codec, const uint8_t *in, size_t n, size_t seg, uint8_t *out,
                         size_t out_cap, size_t *out_n, cdvr_error *err)
{
    size_t bound = cdvr_s2_bound(codec, n, seg);
    if (bound == 0 || out_cap < bound)
        return cdvr_error_set(err, CDVR_ERR_ARG, "stage 2 %s: %zu bytes in %zu-byte segments "
                              "need %zu bytes of output, got %zu", cdvr_s2_name(codec), n, seg,
                              bound, out_cap);
    size_t nseg = n / seg + (n % seg != 0), pos = 8 + 4 * nseg;
    wr32(out, (uint32_t)seg);
    wr32(out + 4, (uint32_t)nseg);
    for (size_t i = 0; i < nseg; i++) {
        size_t len = i + 1 < nseg ? seg : n - i * seg, got = 0;
        cdvr_status s = compress_one(codec, in + i * seg, len, out + pos, out_cap - pos, &got,
                                     err);
        if (s != CDVR_OK)
            return s;
        wr32(out + 8 + 4 * i, (uint32_t)got);
        pos += got;
    }
    *out_n = pos;
    return CDVR_OK;
}

cdvr_status cdvr_s2_decompress(unsigned codec, const uint8_t *in, size_t n, uint8_t *out,
                               size_t expect, cdvr_error *err)
{
    switch (codec) {
    case CDVR_S2_LZO:
        return cdvr_lzo_decompress(in, n, out, expect, err);
    case CDVR_S2_LZ4: {
        if (n > (size_t)INT32_MAX || expect > (size_t)INT32_MAX)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "LZ4 sizes too large (%zu -> %zu)", n,
                                  expect);
        int r = LZ4_decompress_safe((const char *)in, (char *)out, (int)n, (int)expect);
        if (r < 0)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "LZ4 data is corrupt");
        if ((size_t)r != expect)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "LZ4 data decodes to %d bytes, "
                                  "expected %zu", r, expect);
        return CDVR_OK;
    }
    case CDVR_S2_ZSTD: {
        size_t r = ZSTD_decompress(out, expect, in, n);
        if (ZSTD_isError(r))
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "zstd data is corrupt (%s)",
                                  ZSTD_getErrorName(r));
        if (r != expect)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "zstd data decodes to %zu bytes, "
                                  "expected %zu", r, expect);
        return CDVR_OK;
    }
    default:
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "unknown stage-2 codec %u", codec);
    }
}

/* ---- parallel unpack -------------------------------------------------------------------- */

typedef struct unpack_job {
    unsigned codec;
    const uint8_t *in;
    const size_t *offsets;   /* nseg + 1: start of each segment in `in`, then the end */
    uint8_t *out;
    size_t seg, nseg, expect;
    size_t stride, first;    /* this thread does segments first, first + stride, ... */
    cdvr_error err;          /* the first failure of this thread, by segment order */
    double cpu_ms;           /* CPU time this share took */
} unpack_job;

static void *unpack_main(void *arg)
{
    unpack_job *j = arg;
    double cpu0 = cdvr_thread_cpu_ms();
    for (size_t i = j->first; i < j->nseg; i += j->stride) {
        size_t len = i + 1 < j->nseg ? j->seg : j->expect - i * j->seg;
        cdvr_error e;
        if (cdvr_s2_decompress(j->codec, j->in + j->offsets[i], j->offsets[i + 1] - j->offsets[i],
                               j->out + i * j->seg, len, &e) != CDVR_OK) {
            cdvr_error_set(&j->err, e.status, "segment %zu of %zu: %s", i + 1, j->nseg, e.msg);
            break;
        }
    }
    j->cpu_ms = cdvr_thread_cpu_ms() - cpu0;
    return NULL;
}

#define MAX_UNPACK_THREADS 64

cdvr_status cdvr_s2_unpack(unsigned codec, const uint8_t *in, size_t n, uint8_t *out,
                           size_t expect, int threads, cdvr_error *err)
{
    double ignored = 0;
    return cdvr_s2_unpack_cpu(codec, in, n, out, expect, threads, &ignored, err);
}

cdvr_status cdvr_s2_unpack_cpu(unsigned codec, const uint8_t *in, size_t n, uint8_t *out,
                               size_t expect, int threads, double *cpu_ms, cdvr_error *err)
{
    if (codec == 0 || codec >= CDVR_S2_CODECS)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "unknown stage-2 codec %u", codec);
    if (n < 8)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "segment table truncated (%zu bytes)", n);
    size_t seg = rd32(in), nseg = rd32(in + 4);
    if (seg == 0 || expect == 0 || nseg != expect / seg + (expect % seg != 0))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "segment table: %zu segments of %zu bytes "
                              "do not make a payload of %zu bytes", nseg, seg, expect);
    if (nseg > (n - 8) / 4)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "segment table of %zu segments is larger "
                              "than the chunk (%zu bytes)", nseg, n);
    size_t *offsets = malloc((nseg + 1) * sizeof *offsets);
    if (!offsets)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "no memory for %zu segments", nseg);
    size_t pos = 8 + 4 * nseg;
    for (size_t i = 0; i < nseg; i++) {
        size_t len = rd32(in + 8 + 4 * i);
        if (len == 0 || len > n - pos) {
            free(offsets);
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "segment table claims more than the "
                                  "chunk: segment %zu of %zu has %zu bytes at %zu, the chunk "
                                  "%zu", i + 1, nseg, len, pos, n);
        }
        offsets[i] = pos;
        pos += len;
    }
    offsets[nseg] = pos;
    if (pos != n) {
        free(offsets);
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "segments end at %zu, the chunk has %zu "
                              "bytes", pos, n);
    }
    size_t nt = threads > 0 ? (size_t)threads : 0;
    if (nt == 0) {
        long c = sysconf(_SC_NPROCESSORS_ONLN);
        nt = c > 0 ? (size_t)c : 1;
    }
    nt = nt > nseg ? nseg : nt;
    nt = nt > MAX_UNPACK_THREADS ? MAX_UNPACK_THREADS : nt;
    unpack_job jobs[MAX_UNPACK_THREADS];
    pthread_t tids[MAX_UNPACK_THREADS];
    size_t started = 1;
    for (size_t k = 0; k < nt; k++) {
        jobs[k] = (unpack_job){.codec = codec, .in = in, .offsets = offsets, .out = out,
                               .seg = seg, .nseg = nseg, .expect = expect, .stride = nt,
                               .first = k};
        cdvr_error_clear(&jobs[k].err);
    }
    for (size_t k = 1; k < nt; k++) {
        if (pthread_create(&tids[k], NULL, unpack_main, &jobs[k]) != 0)
            break;
        started++;
    }
    /* the calling thread runs share 0 and every share no thread could be started for (fewer
     * threads: the same bytes, only slower) */
    for (size_t k = 0; k < nt; k++)
        if (k == 0 || k >= started)
            unpack_main(&jobs[k]);
    for (size_t k = 1; k < started; k++)
        pthread_join(tids[k], NULL);
    free(offsets);
    for (size_t k = 0; k < nt; k++)
        *cpu_ms += jobs[k].cpu_ms;
    for (size_t k = 0; k < nt; k++)
        if (jobs[k].err.status != CDVR_OK) {
            if (err)
                *err = jobs[k].err;
            return jobs[k].err.status;
        }
    return CDVR_OK;
}
