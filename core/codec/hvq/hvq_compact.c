/* core/codec/hvq/hvq_compact.c - the compact form of hvq (magic "HVQ2", codec "hvqc",
 * cdvr/hvq.h): the same blocks, means and codebooks as the hashed form, stored as zstd-coded
 * sections (delta-coded means, a non-zero-block bitmap with the index list, byte-planed
 * codebooks, a sorted delta-coded residual list); its writer, checker and decoder. */
#include "codec/hvq/hvq_internal.h"

#include <stdlib.h>
#include <string.h>
#include <zstd.h>

#define HVQ2_ZSTD_LEVEL 19

static const char *const section_names[HVQ_SECTIONS] = {
    "means", "bitmap", "indices", "codebook 1", "codebook 2", "residual positions",
    "residual values"};

/* ---- sections ------------------------------------------------------------------------------- */

cdvr_status hvq_sections_alloc(hvq_sections *s, const hvq_layout *L, size_t nnz, uint32_t n1,
                               uint32_t n2, cdvr_error *err)
{
    memset(s, 0, sizeof *s);
    s->size[HVQ_SEC_MEANS] = (size_t)L->nblocks;
    s->size[HVQ_SEC_BITMAP] = (size_t)((L->nblocks + 7) / 8);
    s->size[HVQ_SEC_INDEX] = nnz * (L->w1 + L->w2);
    s->size[HVQ_SEC_CB1] = 16u * (size_t)n1;
    s->size[HVQ_SEC_CB2] = 128u * (size_t)n2;
    s->cap[HVQ_SEC_RESPOS] = s->cap[HVQ_SEC_RESVAL] = 4096;
    for (int i = 0; i < HVQ_SECTIONS; i++) {
        if (i != HVQ_SEC_RESPOS && i != HVQ_SEC_RESVAL)
            s->cap[i] = s->size[i];
        s->raw[i] = calloc(s->cap[i] ? s->cap[i] : 1, 1);
        if (!s->raw[i])
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for the %s (%zu "
                                  "bytes)", section_names[i], s->cap[i]);
    }
    return CDVR_OK;
}

void hvq_sections_free(hvq_sections *s)
{
    for (int i = 0; i < HVQ_SECTIONS; i++)
        free(s->raw[i]);
    memset(s, 0, sizeof *s);
}

/* Byte planes: all low bytes, then (w = 2) all high bytes. */
static void put_planes16(uint8_t *dst, const uint16_t *v, size_t n, unsigned w)
{
    for (size_t i = 0; i < n; i++) {
        dst[i] = (uint8_t)v[i];
        if (w == 2)
            dst[n + i] = (uint8_t)(v[i] >> 8);
    }
}

void hvq_sections_put_indices(hvq_sections *s, const uint16_t *i1, const uint16_t *i2,
                              size_t nnz, unsigned w1, unsigned w2)
{
    put_planes16(s->raw[HVQ_SEC_INDEX], i1, nnz, w1);
    put_planes16(s->raw[HVQ_SEC_INDEX] + nnz * w1, i2, nnz, w2);
}

void hvq_sections_put_codebooks(hvq_sections *s, const int16_t *cb1, uint32_t n1,
                                const int16_t *cb2, uint32_t n2)
{
    put_planes16(s->raw[HVQ_SEC_CB1], (const uint16_t *)cb1, 8u * (size_t)n1, 2);
    put_planes16(s->raw[HVQ_SEC_CB2], (const uint16_t *)cb2, 64u * (size_t)n2, 2);
}

static int reserve(hvq_sections *s, int sec, size_t more)
{
    if (s->size[sec] + more <= s->cap[sec])
        return 1;
    size_t cap = 2 * s->cap[sec] + more;
    uint8_t *p = realloc(s->raw[sec], cap);
    if (!p)
        return 0;
    s->raw[sec] = p;
    s->cap[sec] = cap;
    return 1;
}

int hvq_sections_put_residual(hvq_sections *s, uint64_t delta, int q)
{
    if (!reserve(s, HVQ_SEC_RESPOS, 10) || !reserve(s, HVQ_SEC_RESVAL, 2))
        return 0;
    uint8_t *p = s->raw[HVQ_SEC_RESPOS] + s->size[HVQ_SEC_RESPOS];
    size_t n = 0;
    do { /* LEB128 */
        p[n++] = (uint8_t)((delta & 0x7F) | (delta >= 0x80 ? 0x80 : 0));
        delta >>= 7;
    } while (delta);
    s->size[HVQ_SEC_RESPOS] += n;
    uint32_t zz = q < 0 ? 2u * (uint32_t)(-q) - 1u : 2u * (uint32_t)q; /* zigzag */
    uint8_t *v = s->raw[HVQ_SEC_RESVAL] + s->size[HVQ_SEC_RESVAL];
    v[0] = (uint8_t)zz;
    if (s->wq == 2)
        v[1] = (uint8_t)(zz >> 8);
    s->size[HVQ_SEC_RESVAL] += s->wq;
    s->nres++;
    return 1;
}

/* ---- writer --------------------------------------------------------------------------------- */

/* zstd at HVQ2_ZSTD_LEVEL with a content checksum (a flipped byte fails the decode). */
static ZSTD_CCtx *zstd_context(void)
{
    ZSTD_CCtx *z = ZSTD_createCCtx();
    if (z && (ZSTD_isError(ZSTD_CCtx_setParameter(z, ZSTD_c_compressionLevel, HVQ2_ZSTD_LEVEL)) ||
              ZSTD_isError(ZSTD_CCtx_setParameter(z, ZSTD_c_checksumFlag, 1)))) {
        ZSTD_freeCCtx(z);
        z = NULL;
    }
    return z;
}

/* ---- header ----------------------------------------------------------------------------------- */

static size_t put_leb(uint8_t *p, uint64_t v)
{
    size_t n = 0;
    do {
        p[n++] = (uint8_t)((v & 0x7F) | (v >= 0x80 ? 0x80 : 0));
        v >>= 7;
    } while (v);
    return n;
}

/* 0 when the field runs past end or past 64 bits. */
static int get_leb(const uint8_t **p, const uint8_t *end, uint64_t *v)
{
    *v = 0;
    for (int shift = 0; *p < end && shift < 64; shift += 7) {
        uint8_t b = *(*p)++;
        if (shift == 63 && (b & 0x7E))
            return 0;
        *v |= (uint64_t)(b & 0x7F) << shift;
        if (!(b & 0x80))
            return 1;
    }
    return 0;
}

size_t hvq2_header_write(hvq2_header *h, uint8_t *out)
{
    uint64_t f[9 + HVQ_SECTIONS] = {h->dims[0], h->dims[1], h->dims[2], h->n1, h->n2,
                                     h->residual, h->flags, h->nres, h->respos_bytes};
    memcpy(f + 9, h->csize, sizeof h->csize);
    memcpy(out, "HVQ2", 4);
    size_t at = 4;
    for (size_t i = 0; i < 9 + HVQ_SECTIONS; i++)
        at += put_leb(out + at, f[i]);
    if (h->flags & HVQ2_FLAG_SHARED) {
        hvq_wr64(out + at, h->id);
        at += 8;
    }
    h->bytes = at;
    return at;
}

int hvq2_header_read(const uint8_t *in, size_t n, hvq2_header *h)
{
    memset(h, 0, sizeof *h);
    if (n < 4 || memcmp(in, "HVQ2", 4) != 0)
        return 0;
    const uint8_t *p = in + 4, *end = in + n;
    uint64_t f[9 + HVQ_SECTIONS];
    for (size_t i = 0; i < 9 + HVQ_SECTIONS; i++)
        if (!get_leb(&p, end, &f[i]))
            return 0;
    memcpy(h->dims, f, sizeof h->dims);
    h->n1 = f[3];
    h->n2 = f[4];
    h->residual = f[5];
    h->flags = f[6];
    h->nres = f[7];
    h->respos_bytes = f[8];
    memcpy(h->csize, f + 9, sizeof h->csize);
    if (h->flags & HVQ2_FLAG_SHARED) {
        if (end - p < 8)
            return 0;
        h->id = hvq_rd64(p);
        p += 8;
    }
    h->bytes = (size_t)(p - in);
    return 1;
}

/* ---- writer (continued) ----------------------------------------------------------------------- */

cdvr_status hvq_compact_write(const hvq_sections *s, const size_t dims[3], uint32_t n1,
                              uint32_t n2, uint32_t residual, uint64_t shared_id, uint8_t *out,
                              size_t out_cap, size_t *out_bytes, cdvr_hvq_stats *stats,
                              cdvr_error *err)
{
    hvq2_header h = {.dims = {dims[0], dims[1], dims[2]}, .n1 = n1, .n2 = n2,
                     .residual = residual, .flags = shared_id ? HVQ2_FLAG_SHARED : 0,
                     .nres = s->nres, .respos_bytes = s->size[HVQ_SEC_RESPOS], .id = shared_id};
    uint8_t *packed[HVQ_SECTIONS] = {NULL};
    ZSTD_CCtx *z = zstd_context();
    cdvr_status st = z ? CDVR_OK : cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: cannot set up zstd");
    size_t total = 0;
    for (int i = 0; st == CDVR_OK && i < HVQ_SECTIONS; i++) {
        if (!s->size[i])
            continue;
        size_t cap = ZSTD_compressBound(s->size[i]);
        packed[i] = malloc(cap);
        size_t c = packed[i] ? ZSTD_compress2(z, packed[i], cap, s->raw[i], s->size[i]) : 0;
        if (!packed[i] || ZSTD_isError(c))
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: cannot compress the %s",
                                section_names[i]);
        else
            h.csize[i] = c;
        total += h.csize[i];
    }
    ZSTD_freeCCtx(z);
    uint8_t head[HVQ2_HEADER_MAX];
    size_t hb = st == CDVR_OK ? hvq2_header_write(&h, head) : 0;
    if (st == CDVR_OK && !out) { /* a size query */
        *out_bytes = hb + total;
        stats = NULL;
    } else if (st == CDVR_OK && (total > out_cap || hb > out_cap - total))
        st = cdvr_error_set(err, CDVR_ERR_ARG, "hvq: the payload needs %zu bytes, the buffer has "
                            "%zu", hb + total, out_cap);
    else if (st == CDVR_OK) {
        memcpy(out, head, hb);
        size_t at = hb;
        for (int i = 0; i < HVQ_SECTIONS; i++) {
            if (h.csize[i])
                memcpy(out + at, packed[i], (size_t)h.csize[i]);
            at += (size_t)h.csize[i];
        }
        *out_bytes = at;
    }
    for (int i = 0; i < HVQ_SECTIONS; i++)
        free(packed[i]);
    if (st == CDVR_OK && stats) {
        memset(stats, 0, sizeof *stats);
        stats->header = hb;
        stats->means = (size_t)h.csize[HVQ_SEC_MEANS];
        stats->indices = (size_t)(h.csize[HVQ_SEC_BITMAP] + h.csize[HVQ_SEC_INDEX]);
        stats->codebook1 = (size_t)h.csize[HVQ_SEC_CB1];
        stats->codebook2 = (size_t)h.csize[HVQ_SEC_CB2];
        stats->residuals = (size_t)(h.csize[HVQ_SEC_RESPOS] + h.csize[HVQ_SEC_RESVAL]);
        stats->blocks = s->size[HVQ_SEC_MEANS];
        stats->zero_blocks = stats->blocks - s->size[HVQ_SEC_INDEX] /
                                                 (hvq_index_width(n1) + hvq_index_width(n2));
        stats->residual_voxels = (size_t)s->nres;
        stats->codebook1_entries = n1;
        stats->codebook2_entries = n2;
        stats->residual = residual;
    }
    return st;
}

/* Worst-case compact payload: the header and each section's zstd bound at its largest. */
cdvr_status cdvr_hvq_compact_bound(const cdvr_hvq_params *p, const size_t dims[3],
                                   size_t *bytes, cdvr_error *err)
{
    size_t voxels = 1;
    for (int a = 0; a < 3; a++)
        if (dims[a] == 0 || dims[a] > UINT32_MAX || !cdvr_size_mul(voxels, dims[a], &voxels))
            return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: dims %zux%zux%zu (each 1..2^32-1, "
                                  "their product below 2^64)", dims[0], dims[1], dims[2]);
    const uint64_t d64[3] = {dims[0], dims[1], dims[2]};
    hvq_layout L;
    hvq_layout_get(d64, p->k1, hvq_k2_max(p->k2), &L);
    if (voxels > SIZE_MAX / 16)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: the compact bound of %zux%zux%zu "
                              "overflows size_t", dims[0], dims[1], dims[2]);
    size_t nb = (size_t)L.nblocks, raw[HVQ_SECTIONS] = {
        nb, (nb + 7) / 8, nb * 4, 16u * (size_t)p->k1, 128u * (size_t)hvq_k2_max(p->k2),
        voxels * 10,
        voxels * 2};
    size_t total = HVQ2_HEADER_MAX;
    for (int i = 0; i < HVQ_SECTIONS; i++)
        total += ZSTD_compressBound(raw[i]);
    *bytes = total;
    return CDVR_OK;
}

/* ---- reader --------------------------------------------------------------------------------- */

/* A checked compact payload, its sections decompressed. */
typedef struct hvq2_view {
    uint64_t dims[3], nvox, nnz;
    uint32_t n1, n2, residual;
    hvq_layout L;
    hvq_sections s;
    size_t csize[HVQ_SECTIONS];
    int16_t *cb1, *cb2;
    const int16_t *c1, *c2;  /* the codebooks in use: own (cb1, cb2) or the variant's */
    uint64_t core[3], skip[3]; /* the block grid's extent and origin (hvq2_core, hvq2_skip) */
    uint64_t respos_bytes;
    size_t header_bytes;
    int shared;
} hvq2_view;

static void view2_free(hvq2_view *v)
{
    hvq_sections_free(&v->s);
    free(v->cb1);
    free(v->cb2);
}

static cdvr_status corrupt(cdvr_error *err, const char *what)
{
    return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: %s", what);
}

static cdvr_status open_header(hvq2_view *v, const cdvr_hvq_params *p,
                               const cdvr_hvq_codebooks *shared, const uint8_t *in, size_t bytes,
                               cdvr_error *err)
{
    hvq2_header h;
    if (!hvq2_header_read(in, bytes, &h))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload of %zu bytes: no "
                              "\"HVQ2\" header", bytes);
    if (h.dims[0] != v->dims[0] || h.dims[1] != v->dims[1] || h.dims[2] != v->dims[2])
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: dims %llux%llux%llu, "
                              "the chunk has %llux%llux%llu", (unsigned long long)h.dims[0],
                              (unsigned long long)h.dims[1], (unsigned long long)h.dims[2],
                              (unsigned long long)v->dims[0], (unsigned long long)v->dims[1],
                              (unsigned long long)v->dims[2]);
    uint32_t k1 = p ? p->k1 : CDVR_HVQ_K_MAX, k2 = p ? hvq_k2_max(p->k2) : CDVR_HVQ_K_MAX;
    if (h.n1 > k1 || h.n2 > k2 || h.n1 > CDVR_HVQ_K_MAX || h.n2 > CDVR_HVQ_K_MAX ||
        (h.n1 == 0) != (h.n2 == 0))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: codebooks of %llu "
                              "and %llu entries (at most %u and %u, both 0 or neither)",
                              (unsigned long long)h.n1, (unsigned long long)h.n2, k1, k2);
    v->n1 = (uint32_t)h.n1;
    v->n2 = (uint32_t)h.n2;
    if (h.residual > 255 || (h.flags & ~(uint64_t)HVQ2_FLAG_SHARED) ||
        ((h.flags & HVQ2_FLAG_SHARED) && h.id == 0))
        return corrupt(err, "residual above 255, unknown flags, or a shared-codebook id of 0");
    v->residual = (uint32_t)h.residual;
    v->shared = (h.flags & HVQ2_FLAG_SHARED) != 0;
    if (v->shared && (!shared || shared->id != h.id))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: coded with the shared "
                              "codebooks %016llx, %s", (unsigned long long)h.id,
                              shared ? "other codebooks given" : "none given (the variant's "
                              "codebooks are missing)");
    if (v->shared && (v->n1 != shared->n1 || v->n2 != shared->n2))
        return corrupt(err, "codebook sizes other than the shared codebooks'");
    v->s.nres = h.nres;
    v->s.wq = v->residual == 0 ? 2 : 1;
    if (h.nres > v->nvox || h.respos_bytes > 10 * h.nres)
        return corrupt(err, "more residual voxels than voxels, or a residual position list "
                       "longer than 10 bytes a voxel");
    v->respos_bytes = h.respos_bytes;
    v->header_bytes = h.bytes;
    uint64_t at = h.bytes;
    for (int i = 0; i < HVQ_SECTIONS; i++) {
        if (h.csize[i] > bytes - at)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: the %s (%llu "
                                  "bytes) run past its end", section_names[i],
                                  (unsigned long long)h.csize[i]);
        v->csize[i] = (size_t)h.csize[i];
        at += v->csize[i];
    }
    if (at != bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload of %zu bytes: its "
                              "sections end at byte %llu", bytes, (unsigned long long)at);
    return CDVR_OK;
}

/* Decompresses section i (raw size v->s.size[i]) from src. */
static cdvr_status inflate(hvq2_view *v, int i, const uint8_t *src, cdvr_error *err)
{
    size_t want = v->s.size[i];
    if (want == 0 && v->csize[i] == 0)
        return CDVR_OK;
    /* zstd inflates at most ~32768:1 (RLE blocks): a bound before allocating */
    if (want == 0 || v->csize[i] == 0 || want / 32768 > v->csize[i] ||
        ZSTD_getFrameContentSize(src, v->csize[i]) != (unsigned long long)want)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: the %s should "
                              "hold %zu bytes, their %zu compressed bytes do not say so",
                              section_names[i], want, v->csize[i]);
    v->s.raw[i] = malloc(want);
    if (!v->s.raw[i])
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for the %s (%zu bytes)",
                              section_names[i], want);
    size_t got = ZSTD_decompress(v->s.raw[i], want, src, v->csize[i]);
    if (ZSTD_isError(got) || got != want)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: the %s do not "
                              "inflate to %zu bytes (%s)", section_names[i], want,
                              ZSTD_isError(got) ? ZSTD_getErrorName(got) : "wrong size");
    return CDVR_OK;
}

static size_t src_offset(const hvq2_view *v, int i)
{
    size_t at = v->header_bytes;
    for (int j = 0; j < i; j++)
        at += v->csize[j];
    return at;
}

static unsigned get16(const uint8_t *planes, size_t n, size_t i, unsigned w)
{
    return planes[i] | (w == 2 ? (unsigned)planes[n + i] << 8 : 0u);
}

/* Bitmap (no bits past the blocks), indices below the codebook sizes. */
static cdvr_status check_blocks(hvq2_view *v, cdvr_error *err)
{
    const uint8_t *bm = v->s.raw[HVQ_SEC_BITMAP];
    uint64_t nnz = 0;
    for (uint64_t b = 0; b < v->L.nblocks; b++)
        nnz += bm[b >> 3] >> (b & 7) & 1;
    if ((v->L.nblocks & 7) && bm[v->L.nblocks >> 3] >> (v->L.nblocks & 7))
        return corrupt(err, "bitmap bits past the last block");
    if (nnz && v->n1 == 0)
        return corrupt(err, "non-zero blocks without codebooks");
    if (!nnz && v->n1 && !v->shared)
        return corrupt(err, "codebooks without non-zero blocks");
    v->nnz = nnz;
    return CDVR_OK;
}

static cdvr_status check_indices(const hvq2_view *v, cdvr_error *err)
{
    const uint8_t *ix = v->s.raw[HVQ_SEC_INDEX];
    size_t n = (size_t)v->nnz;
    for (size_t k = 0; k < n; k++)
        if (get16(ix, n, k, v->L.w1) >= v->n1 || get16(ix + n * v->L.w1, n, k, v->L.w2) >= v->n2)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq compact payload: block %zu of "
                                  "the index list holds an index past its codebook", k);
    return CDVR_OK;
}

/* Residual positions: nres LEB128 deltas, each position below the voxel count, exactly the
 * section's bytes. */
static cdvr_status check_residuals(const hvq2_view *v, cdvr_error *err)
{
    const uint8_t *p = v->s.raw[HVQ_SEC_RESPOS];
    size_t n = v->s.size[HVQ_SEC_RESPOS], at = 0;
    uint64_t next = 0;
    for (uint64_t r = 0; r < v->s.nres; r++) {
        uint64_t delta = 0;
        for (int shift = 0;; shift += 7) {
            if (at >= n || shift > 56)
                return corrupt(err, "a residual position runs past its list");
            delta |= (uint64_t)(p[at] & 0x7F) << shift;
            if (!(p[at++] & 0x80))
                break;
        }
        if (delta >= v->nvox - next)
            return corrupt(err, "a residual position past the last voxel");
        next += delta + 1;
    }
    if (at != n)
        return corrupt(err, "bytes after the last residual position");
    return CDVR_OK;
}

static cdvr_status codebooks_unplane(hvq2_view *v, cdvr_error *err)
{
    size_t e1 = 8u * (size_t)v->n1, e2 = 64u * (size_t)v->n2;
    v->cb1 = malloc((e1 ? e1 : 1) * sizeof *v->cb1);
    v->cb2 = malloc((e2 ? e2 : 1) * sizeof *v->cb2);
    if (!v->cb1 || !v->cb2)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for the codebooks");
    for (size_t i = 0; i < e1; i++)
        v->cb1[i] = (int16_t)(uint16_t)get16(v->s.raw[HVQ_SEC_CB1], e1, i, 2);
    for (size_t i = 0; i < e2; i++)
        v->cb2[i] = (int16_t)(uint16_t)get16(v->s.raw[HVQ_SEC_CB2], e2, i, 2);
    return CDVR_OK;
}

static cdvr_status view2_open(hvq2_view *v, const cdvr_hvq_params *p,
                              const cdvr_hvq_codebooks *shared, const size_t dims[3],
                              const uint8_t *in, size_t bytes, cdvr_error *err)
{
    memset(v, 0, sizeof *v);
    v->nvox = 1;
    for (int a = 0; a < 3; a++) {
        if (dims[a] == 0 || dims[a] > UINT32_MAX)
            return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: dims %zux%zux%zu (each 1..2^32-1)",
                                  dims[0], dims[1], dims[2]);
        v->dims[a] = dims[a];
        v->nvox *= dims[a];
    }
    if (!in && bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: NULL payload of %zu bytes", bytes);
    cdvr_status s = open_header(v, p, shared, in, bytes, err);
    if (s != CDVR_OK)
        return s;
    const uint64_t core[3] = {hvq2_core((size_t)v->dims[0]), hvq2_core((size_t)v->dims[1]),
                              hvq2_core((size_t)v->dims[2])};
    hvq_layout_get(core, v->n1, v->n2, &v->L);
    for (int a = 0; a < 3; a++) {
        v->core[a] = core[a];
        v->skip[a] = v->dims[a] - core[a];
    }
    /* raw section sizes: from the dims, the header and the bitmap */
    v->s.size[HVQ_SEC_MEANS] = (size_t)v->L.nblocks;
    v->s.size[HVQ_SEC_BITMAP] = (size_t)((v->L.nblocks + 7) / 8);
    v->s.size[HVQ_SEC_CB1] = v->shared ? 0 : 16u * (size_t)v->n1;
    v->s.size[HVQ_SEC_CB2] = v->shared ? 0 : 128u * (size_t)v->n2;
    v->s.size[HVQ_SEC_RESPOS] = (size_t)v->respos_bytes;
    v->s.size[HVQ_SEC_RESVAL] = (size_t)v->s.nres * v->s.wq;
    int order[] = {HVQ_SEC_BITMAP, HVQ_SEC_MEANS, HVQ_SEC_CB1, HVQ_SEC_CB2, HVQ_SEC_RESPOS,
                   HVQ_SEC_RESVAL};
    for (size_t i = 0; s == CDVR_OK && i < sizeof order / sizeof *order; i++) {
        s = inflate(v, order[i], in + src_offset(v, order[i]), err);
        if (s == CDVR_OK && order[i] == HVQ_SEC_BITMAP && v->s.size[HVQ_SEC_BITMAP]) {
            s = check_blocks(v, err);
            v->s.size[HVQ_SEC_INDEX] = (size_t)v->nnz * (v->L.w1 + v->L.w2);
            if (s == CDVR_OK)
                s = inflate(v, HVQ_SEC_INDEX, in + src_offset(v, HVQ_SEC_INDEX), err);
        }
    }
    if (s == CDVR_OK)
        s = check_indices(v, err);
    if (s == CDVR_OK)
        s = check_residuals(v, err);
    if (s == CDVR_OK && !v->shared)
        s = codebooks_unplane(v, err);
    v->c1 = v->shared ? shared->c1 : v->cb1;
    v->c2 = v->shared ? shared->c2 : v->cb2;
    return s;
}

cdvr_status cdvr_hvq_compact_check(const cdvr_hvq_params *p, const cdvr_hvq_codebooks *shared,
                                   const size_t dims[3], const uint8_t *payload, size_t bytes,
                                   cdvr_hvq_stats *stats, cdvr_error *err)
{
    hvq2_view v;
    cdvr_status s = view2_open(&v, p, shared, dims, payload, bytes, err);
    if (s == CDVR_OK && stats) {
        memset(stats, 0, sizeof *stats);
        stats->header = v.header_bytes;
        stats->means = v.csize[HVQ_SEC_MEANS];
        stats->indices = v.csize[HVQ_SEC_BITMAP] + v.csize[HVQ_SEC_INDEX];
        stats->codebook1 = v.csize[HVQ_SEC_CB1];
        stats->codebook2 = v.csize[HVQ_SEC_CB2];
        stats->residuals = v.csize[HVQ_SEC_RESPOS] + v.csize[HVQ_SEC_RESVAL];
        stats->blocks = (size_t)v.L.nblocks;
        stats->zero_blocks = (size_t)(v.L.nblocks - v.nnz);
        stats->residual_voxels = (size_t)v.s.nres;
        stats->codebook1_entries = v.n1;
        stats->codebook2_entries = v.n2;
        stats->residual = v.residual;
    }
    view2_free(&v);
    return s;
}

/* ---- decode --------------------------------------------------------------------------------- */

static void decode_blocks(const hvq2_view *v, uint8_t *out)
{
    const uint8_t *md = v->s.raw[HVQ_SEC_MEANS], *bm = v->s.raw[HVQ_SEC_BITMAP];
    const uint8_t *ix = v->s.raw[HVQ_SEC_INDEX];
    size_t n = (size_t)v->nnz, k = 0;
    uint64_t X = v->dims[0], Y = v->dims[1], b = 0;
    uint64_t CX = v->core[0], CY = v->core[1], CZ = v->core[2];
    uint64_t OX = v->skip[0], OY = v->skip[1], OZ = v->skip[2];
    uint8_t mean = 0;
    for (uint64_t bz = 0; bz < v->L.nbz; bz++)
        for (uint64_t by = 0; by < v->L.nby; by++)
            for (uint64_t bx = 0; bx < v->L.nbx; bx++, b++) {
                mean = (uint8_t)(mean + md[b]);
                const int16_t *c1 = NULL, *c2 = NULL;
                if (bm[b >> 3] >> (b & 7) & 1) {
                    c1 = v->c1 + 8u * get16(ix, n, k, v->L.w1);
                    c2 = v->c2 + 64u * get16(ix + n * v->L.w1, n, k, v->L.w2);
                    k++;
                }
                unsigned ex = CX - 4 * bx < 4 ? (unsigned)(CX - 4 * bx) : 4;
                unsigned ey = CY - 4 * by < 4 ? (unsigned)(CY - 4 * by) : 4;
                unsigned ez = CZ - 4 * bz < 4 ? (unsigned)(CZ - 4 * bz) : 4;
                for (unsigned z = 0; z < ez; z++)
                    for (unsigned y = 0; y < ey; y++) {
                        uint8_t *row = out + (OX + 4 * bx) +
                                       X * ((OY + 4 * by + y) + Y * (OZ + 4 * bz + z));
                        if (!c1) {
                            memset(row, mean, ex);
                            continue;
                        }
                        for (unsigned x = 0; x < ex; x++) {
                            int val = mean + c1[(x >> 1) + 2 * (y >> 1) + 4 * (z >> 1)] +
                                      c2[x + 4 * y + 16 * z];
                            row[x] = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
                        }
                    }
            }
}

/* The planes before the core: copies of the first core plane, x then y then z (so an edge or
 * corner voxel takes its nearest core voxel's value). */
static void fill_skipped(const hvq2_view *v, uint8_t *out)
{
    uint64_t X = v->dims[0], Y = v->dims[1], Z = v->dims[2];
    if (v->skip[0])
        for (uint64_t z = v->skip[2]; z < Z; z++)
            for (uint64_t y = v->skip[1]; y < Y; y++)
                out[X * (y + Y * z)] = out[1 + X * (y + Y * z)];
    if (v->skip[1])
        for (uint64_t z = v->skip[2]; z < Z; z++)
            memcpy(out + X * Y * z, out + X * (1 + Y * z), (size_t)X);
    if (v->skip[2])
        memcpy(out, out + X * Y, (size_t)(X * Y));
}

static void apply_residuals2(const hvq2_view *v, uint8_t *out)
{
    const uint8_t *p = v->s.raw[HVQ_SEC_RESPOS], *q = v->s.raw[HVQ_SEC_RESVAL];
    int step = 2 * (int)v->residual + 1;
    uint64_t next = 0;
    size_t at = 0;
    for (uint64_t r = 0; r < v->s.nres; r++) {
        uint64_t delta = 0;
        for (int shift = 0;; shift += 7) {
            delta |= (uint64_t)(p[at] & 0x7F) << shift;
            if (!(p[at++] & 0x80))
                break;
        }
        uint64_t pos = next + delta;
        next = pos + 1;
        uint32_t zz = v->s.wq == 2 ? hvq_rd16(q + 2 * r) : q[r];
        int k = zz & 1 ? -(int)((zz + 1) >> 1) : (int)(zz >> 1);
        int val = out[pos] + k * step;
        out[pos] = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
    }
}

cdvr_status cdvr_hvq_compact_decode(const cdvr_hvq_params *p, const cdvr_hvq_codebooks *shared,
                                    const size_t dims[3], const uint8_t *payload, size_t bytes,
                                    uint8_t *out, cdvr_error *err)
{
    hvq2_view v;
    cdvr_status s = view2_open(&v, p, shared, dims, payload, bytes, err);
    if (s == CDVR_OK) {
        decode_blocks(&v, out);
        fill_skipped(&v, out);
        apply_residuals2(&v, out);
    }
    view2_free(&v);
    return s;
}

/* ---- shared codebooks ------------------------------------------------------------------------ */

#define HVQS_HEADER_BYTES 24u


cdvr_status hvq_shared_write(const int16_t *cb1, uint32_t n1, const int16_t *cb2, uint32_t n2,
                             uint8_t **blob, size_t *bytes, cdvr_error *err)
{
    size_t raw = 16u * (size_t)n1 + 128u * (size_t)n2;
    uint8_t *planes = malloc(raw ? raw : 1);
    size_t cap = HVQS_HEADER_BYTES + ZSTD_compressBound(raw);
    uint8_t *out = malloc(cap);
    ZSTD_CCtx *z = zstd_context();
    cdvr_status s = CDVR_OK;
    if (!planes || !out || !z)
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for shared codebooks");
    size_t c = 0;
    if (s == CDVR_OK) {
        put_planes16(planes, (const uint16_t *)cb1, 8u * (size_t)n1, 2);
        put_planes16(planes + 16u * (size_t)n1, (const uint16_t *)cb2, 64u * (size_t)n2, 2);
        memset(out, 0, HVQS_HEADER_BYTES);
        memcpy(out, "HVQS", 4);
        hvq_wr32(out + 4, n1);
        hvq_wr32(out + 8, n2);
        if (raw)
            c = ZSTD_compress2(z, out + HVQS_HEADER_BYTES, cap - HVQS_HEADER_BYTES, planes, raw);
        if (ZSTD_isError(c))
            s = cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: zstd: %s", ZSTD_getErrorName(c));
        else
            hvq_wr64(out + 16, c);
    }
    ZSTD_freeCCtx(z);
    free(planes);
    if (s != CDVR_OK) {
        free(out);
        return s;
    }
    *blob = out;
    *bytes = HVQS_HEADER_BYTES + c;
    return CDVR_OK;
}

void cdvr_hvq_codebooks_free(cdvr_hvq_codebooks *cb)
{
    free(cb->c1);
    free(cb->c2);
    memset(cb, 0, sizeof *cb);
}

cdvr_status cdvr_hvq_shared_open(const cdvr_hvq_params *p, const uint8_t *blob, size_t bytes,
                                 cdvr_hvq_codebooks *cb, cdvr_error *err)
{
    memset(cb, 0, sizeof *cb);
    if (!blob || bytes < HVQS_HEADER_BYTES || memcmp(blob, "HVQS", 4) != 0 ||
        hvq_rd32(blob + 12) != 0)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq shared codebooks of %zu bytes: no "
                              "\"HVQS\" header", bytes);
    uint32_t n1 = hvq_rd32(blob + 4), n2 = hvq_rd32(blob + 8);
    uint32_t k1 = p ? p->k1 : CDVR_HVQ_K_MAX, k2 = p ? hvq_k2_max(p->k2) : CDVR_HVQ_K_MAX;
    if (n1 > k1 || n2 > k2 || n1 > CDVR_HVQ_K_MAX || n2 > CDVR_HVQ_K_MAX || (n1 == 0) != (n2 == 0) ||
        hvq_rd64(blob + 16) != bytes - HVQS_HEADER_BYTES)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq shared codebooks: %u and %u entries "
                              "(at most %u, %u), %llu compressed bytes of %zu", n1, n2, k1, k2,
                              (unsigned long long)hvq_rd64(blob + 16),
                              bytes - HVQS_HEADER_BYTES);
    size_t raw = 16u * (size_t)n1 + 128u * (size_t)n2;
    uint8_t *planes = malloc(raw ? raw : 1);
    cb->c1 = malloc(sizeof *cb->c1 * (8u * (size_t)n1 + 1));
    cb->c2 = malloc(sizeof *cb->c2 * (64u * (size_t)n2 + 1));
    cdvr_status s = CDVR_OK;
    if (!planes || !cb->c1 || !cb->c2)
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for shared codebooks");
    if (s == CDVR_OK && raw) {
        size_t got = ZSTD_decompress(planes, raw, blob + HVQS_HEADER_BYTES,
                                     bytes - HVQS_HEADER_BYTES);
        if (ZSTD_isError(got) || got != raw)
            s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq shared codebooks do not inflate to "
                               "%zu bytes", raw);
    } else if (s == CDVR_OK && bytes != HVQS_HEADER_BYTES) {
        s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq shared codebooks: empty, with data");
    }
    if (s == CDVR_OK) {
        for (size_t i = 0; i < 8u * (size_t)n1; i++)
            cb->c1[i] = (int16_t)(uint16_t)get16(planes, 8u * (size_t)n1, i, 2);
        for (size_t i = 0; i < 64u * (size_t)n2; i++)
            cb->c2[i] = (int16_t)(uint16_t)get16(planes + 16u * (size_t)n1, 64u * (size_t)n2, i, 2);
        cb->n1 = n1;
        cb->n2 = n2;
        cb->id = cdvr_shared_id(blob, bytes);
    }
    free(planes);
    if (s != CDVR_OK)
        cdvr_hvq_codebooks_free(cb);
    return s;
}
