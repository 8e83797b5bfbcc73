/* core/codec/hvq/hvq_internal.h - the parts of the hvq codec (cdvr/hvq.h) that tests drive
 * directly: perfect spatial hashes, codebook training, payload layout helpers. */
#ifndef CDVR_HVQ_INTERNAL_H
#define CDVR_HVQ_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/hvq.h"

/* ---- little-endian fields ---------------------------------------------------------------- */

static inline uint32_t hvq_rd16(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8; }
static inline uint32_t hvq_rd32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t hvq_rd64(const uint8_t *p)
{
    return (uint64_t)hvq_rd32(p) | (uint64_t)hvq_rd32(p + 4) << 32;
}
static inline int32_t hvq_rds16(const uint8_t *p) { return (int16_t)(uint16_t)hvq_rd16(p); }
static inline void hvq_wr16(uint8_t *p, uint32_t v) { p[0] = (uint8_t)v; p[1] = (uint8_t)(v >> 8); }
static inline void hvq_wr32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}
static inline void hvq_wr64(uint8_t *p, uint64_t v)
{
    hvq_wr32(p, (uint32_t)v);
    hvq_wr32(p + 4, (uint32_t)(v >> 32));
}

/* ---- payload layout ----------------------------------------------------------------------- */

#define HVQ_HEADER_BYTES 32u
#define HVQ_DIR_ENTRY_BYTES 32u
#define HVQ_REGION_BLOCKS 64u  /* region side in blocks */
#define HVQ_M_MAX 1023u        /* largest table side a payload may have */
#define HVQ_R_MAX 256u         /* largest offset table side */

typedef struct hvq_layout {
    uint64_t nbx, nby, nbz, nblocks;   /* blocks */
    uint64_t nrx, nry, nrz, nregions;  /* regions */
    uint64_t off_c1, off_c2, off_dir, off_data;
    unsigned w1, w2;                   /* index bytes of codebook 1 and 2 */
} hvq_layout;

/* Section offsets for dims and codebook sizes (no overflow for dims < 2^32, n <= K_MAX). */
void hvq_layout_get(const uint64_t dims[3], uint32_t n1, uint32_t n2, hvq_layout *out);

static inline unsigned hvq_index_width(uint32_t entries) { return entries > 256 ? 2u : 1u; }
static inline unsigned hvq_offset_width(uint32_t m) { return m > 256 ? 2u : 1u; }

/* ---- perfect spatial hash ------------------------------------------------------------------ */

#define HVQ_PSH_ATTEMPTS 10
#define HVQ_PSH_RANDOM_TRIES 256

typedef struct hvq_psh {
    uint32_t m, r, n;     /* table side, offset table side, keys */
    unsigned slot_bytes;  /* 3 key bytes + value bytes */
    uint8_t *data;        /* r^3 offset entries (3*w bytes) then m^3 slots; NULL when n = 0 */
    size_t bytes;
    int attempts;         /* attempts the construction took (1 = first) */
} hvq_psh;

/* Bytes of a hash's data for table sides m, r. */
uint64_t hvq_psh_data_bytes(uint32_t m, uint32_t r, unsigned slot_bytes);

/* Table sides of attempt a (0-based) for n > 0 keys whose coordinates are below extent. */
void hvq_psh_sizes(size_t n, unsigned extent, int attempt, uint32_t *m, uint32_t *r);

/* Largest data any attempt can produce for n keys below extent. */
uint64_t hvq_psh_bound(size_t n, unsigned extent, unsigned slot_bytes);

/* Builds the hash of n distinct keys (keys[3*i .. 3*i+2]) with vbytes value bytes each
 * (values[vbytes*i ..]), trying at most max_attempts attempts (1..HVQ_PSH_ATTEMPTS) of the
 * schedule. CDVR_ERR_UNSUPPORTED when none fits, CDVR_ERR_NOMEM. out->data is malloc'd. */
cdvr_status hvq_psh_build(const uint8_t *keys, const uint8_t *values, size_t n, unsigned vbytes,
                          int max_attempts, hvq_psh *out, cdvr_error *err);
void hvq_psh_free(hvq_psh *h);

/* The value bytes of key (kx, ky, kz) in a hash whose data starts at data, or NULL when the
 * key is absent (or m = 0). The data must be a checked hash of these sides. */
const uint8_t *hvq_psh_find(const uint8_t *data, uint32_t m, uint32_t r, unsigned slot_bytes,
                            unsigned kx, unsigned ky, unsigned kz);

/* The slot key (kx, ky, kz) maps to. */
uint64_t hvq_psh_slot(const uint8_t *data, uint32_t m, uint32_t r, unsigned kx, unsigned ky,
                      unsigned kz);

/* A checked hash (every offset entry below m, cdvr_hvq_check) set up for many lookups: the
 * remainders of key coordinates (always below 256: one byte each) by r and by m come from
 * tables, and (key % m + offset) % m is one conditional subtraction since both terms are
 * below m. The same slots as hvq_psh_slot; the check and the whole-frame decode, which hash
 * every slot and every block, spend a third of their time in its divisions otherwise. */
typedef struct hvq_psh_map {
    const uint8_t *offsets;  /* r^3 entries of 3 * w bytes */
    const uint8_t *slots;    /* m^3 slots */
    uint32_t m, r;
    unsigned w;              /* offset bytes: hvq_offset_width(m) */
    uint16_t mod_r[256], mod_m[256];
} hvq_psh_map;

/* Sets h up for the hash at data with sides m, r (m = 0: an empty hash, no lookups). */
void hvq_psh_map_open(hvq_psh_map *h, const uint8_t *data, uint32_t m, uint32_t r);

static inline unsigned hvq_psh_map_offset(const uint8_t *p, unsigned w)
{
    return w == 1 ? p[0] : (unsigned)hvq_rd16(p);
}

/* hvq_psh_slot of key (kx, ky, kz), each below 256. */
static inline uint64_t hvq_psh_map_slot(const hvq_psh_map *h, unsigned kx, unsigned ky,
                                        unsigned kz)
{
    uint64_t e = h->mod_r[kx] + (uint64_t)h->r * (h->mod_r[ky] + (uint64_t)h->r * h->mod_r[kz]);
    const uint8_t *o = h->offsets + e * 3u * h->w;
    unsigned m = h->m;
    unsigned sx = h->mod_m[kx] + hvq_psh_map_offset(o, h->w);
    unsigned sy = h->mod_m[ky] + hvq_psh_map_offset(o + h->w, h->w);
    unsigned sz = h->mod_m[kz] + hvq_psh_map_offset(o + 2 * h->w, h->w);
    sx -= sx >= m ? m : 0;
    sy -= sy >= m ? m : 0;
    sz -= sz >= m ? m : 0;
    return sx + (uint64_t)m * (sy + (uint64_t)m * sz);
}

/* hvq_psh_find of key (kx, ky, kz), each below 256. */
static inline const uint8_t *hvq_psh_map_find(const hvq_psh_map *h, unsigned slot_bytes,
                                              unsigned kx, unsigned ky, unsigned kz)
{
    if (h->m == 0)
        return NULL;
    const uint8_t *slot = h->slots + hvq_psh_map_slot(h, kx, ky, kz) * slot_bytes;
    return (slot[0] == kx && slot[1] == ky && slot[2] == kz) ? slot + 3 : NULL;
}

/* ---- codebook training --------------------------------------------------------------------- */

typedef struct hvq_vq_report {
    unsigned pca_entries;   /* entries after PCA splitting */
    unsigned entries;       /* final entries */
    int lbg_iterations;
    unsigned reseeded;      /* empty clusters re-seeded */
    unsigned dropped;       /* empty clusters dropped */
    double distortion;      /* final LBG distortion (training vectors, float centroids) */
} hvq_vq_report;

/* PCA splitting: at most k float centroids (d <= 64 each) into centroids; *kout entries.
 * threads only share the work (exact integer sums). */
cdvr_status hvq_pca_split(const int16_t *vectors, size_t n, unsigned d, unsigned k,
                          unsigned threads, float *centroids, unsigned *kout, cdvr_error *err);

/* (d: a multiple of 8, at most 64.) LBG from the *k centroids given; may drop empty ones (*k shrinks). sums/counts (k*d int64,
 * k) receive the final clusters' exact sums over the vectors, for rounding. */
cdvr_status hvq_lbg(const int16_t *vectors, size_t n, unsigned d, float *centroids, unsigned *k,
                    double eps, unsigned threads, int64_t *sums, uint64_t *counts,
                    hvq_vq_report *rep, cdvr_error *err);

/* Codebooks have at most ceil(n / HVQ_VECTORS_PER_ENTRY) entries for n vectors. */
#define HVQ_VECTORS_PER_ENTRY 8

/* Whole training (sampling, PCA splitting, LBG, rounding) of at most k entries; codebook
 * receives *kout entries of d int16: round(mean / scale), halves away from zero. */
cdvr_status hvq_vq_train(const int16_t *vectors, size_t n, unsigned d, unsigned k, int scale,
                         double eps, uint32_t train, unsigned threads, int16_t *codebook,
                         unsigned *kout, hvq_vq_report *rep, cdvr_error *err);

/* Nearest codebook entry of each vector: argmin sum (v - scale*c)^2 (exact integers; ties:
 * the lowest index). */
void hvq_vq_assign(const int16_t *vectors, size_t n, unsigned d, const int16_t *codebook,
                   unsigned k, int scale, unsigned threads, uint16_t *index);


/* ---- compact form (HVQ2, cdvr/hvq.h) --------------------------------------------------------- */

enum { HVQ_SEC_MEANS, HVQ_SEC_BITMAP, HVQ_SEC_INDEX, HVQ_SEC_CB1, HVQ_SEC_CB2, HVQ_SEC_RESPOS,
       HVQ_SEC_RESVAL, HVQ_SECTIONS };

/* The compact payload's header: "HVQ2", then unsigned LEB128 fields in this order: the dims,
 * n1, n2, residual, flags, nres, respos_bytes, the sections' compressed sizes; then, when
 * flags has HVQ2_FLAG_SHARED, the shared-codebook id as 8 bytes little endian. */
typedef struct hvq2_header {
    uint64_t dims[3], n1, n2, residual, flags, nres, respos_bytes;
    uint64_t csize[HVQ_SECTIONS];
    uint64_t id;
    size_t bytes;  /* the header's size (read: as found; write: as written) */
} hvq2_header;

#define HVQ2_HEADER_MAX (4u + 10u * (9u + HVQ_SECTIONS) + 8u)

/* Writes h at out (room for HVQ2_HEADER_MAX bytes); returns its size (also in h->bytes). */
size_t hvq2_header_write(hvq2_header *h, uint8_t *out);
/* Reads a header from the n bytes at in; 0 when they do not hold one (no magic, a field
 * running past n or past 64 bits). */
int hvq2_header_read(const uint8_t *in, size_t n, hvq2_header *h);

/* The compact form's block grid covers the core: an axis of n = 4k + 1 >= 5 voxels (a store
 * brick: its owned voxels and the one-voxel overlap below them) leaves its first plane out,
 * decoded as a copy of the plane after it (before residuals), so the blocks of every brick
 * lie on the whole volume's grid. hvq2_skip: the planes left out (0 or 1), hvq2_core: the
 * core's extent. */
/* k2 = 0 ("auto", hvqc): the sizes tried (cdvr/hvq.h), the largest the bound for. */
#define HVQ_K2_AUTO_MAX 2048u
static inline uint32_t hvq_k2_max(uint32_t k2) { return k2 ? k2 : HVQ_K2_AUTO_MAX; }
static inline size_t hvq2_skip(size_t n) { return n >= 5 && n % 4 == 1 ? 1 : 0; }
static inline size_t hvq2_core(size_t n) { return n - hvq2_skip(n); }
#define HVQ2_FLAG_SHARED 1u  /* codebooks are the variant's (cdvr_hvq_codebooks) */

/* The raw (uncompressed) sections of a compact payload. */
typedef struct hvq_sections {
    uint8_t *raw[HVQ_SECTIONS];
    size_t size[HVQ_SECTIONS];  /* bytes in use */
    size_t cap[HVQ_SECTIONS];   /* bytes allocated */
    uint64_t nres;              /* residual voxels */
    unsigned wq;                /* bytes per residual value (2 when R = 0, else 1) */
} hvq_sections;

/* Sections sized for the layout, nnz non-zero blocks and codebooks of n1, n2 entries (means,
 * bitmap zeroed; the residual sections grow as residuals are put). */
cdvr_status hvq_sections_alloc(hvq_sections *s, const hvq_layout *L, size_t nnz, uint32_t n1,
                               uint32_t n2, cdvr_error *err);
void hvq_sections_free(hvq_sections *s);
void hvq_sections_put_indices(hvq_sections *s, const uint16_t *i1, const uint16_t *i2,
                              size_t nnz, unsigned w1, unsigned w2);
void hvq_sections_put_codebooks(hvq_sections *s, const int16_t *cb1, uint32_t n1,
                                const int16_t *cb2, uint32_t n2);
/* Appends one residual: its distance from the previous one's successor and q; 0: no memory. */
int hvq_sections_put_residual(hvq_sections *s, uint64_t delta, int q);
/* Compresses the sections into the payload (layout in cdvr/hvq.h). */
cdvr_status hvq_compact_write(const hvq_sections *s, const size_t dims[3], uint32_t n1,
                              uint32_t n2, uint32_t residual, uint64_t shared_id, uint8_t *out,
                              size_t out_cap, size_t *out_bytes, cdvr_hvq_stats *stats,
                              cdvr_error *err);
/* A shared codebook blob (layout in cdvr/hvq.h) of these codebooks; *blob is malloc'd. */
cdvr_status hvq_shared_write(const int16_t *cb1, uint32_t n1, const int16_t *cb2, uint32_t n2,
                             uint8_t **blob, size_t *bytes, cdvr_error *err);

/* ---- threads -------------------------------------------------------------------------------- */

/* Runs fn(ctx, item) for item in 0..count-1 on up to `threads` threads (items taken in order
 * from a shared counter; fn must write only its own item's results). */
void hvq_parallel_for(unsigned threads, size_t count, void (*fn)(void *ctx, size_t item),
                      void *ctx);
unsigned hvq_threads_auto(void);

/* cdvr_hvq_decode on `threads` threads (cdvr_hvq_decode takes hvq_threads_auto()): the same
 * bytes on any number. */
cdvr_status hvq_decode_threads(const cdvr_hvq_params *p, const size_t dims[3],
                               const uint8_t *payload, size_t bytes, uint8_t *out,
                               unsigned threads, cdvr_error *err);
/* The codec's decode_cells (codec.h) on `threads` threads: the blocks that meet a needed cell
 * and the residual voxels inside one, into a frame of either layout; other voxels keep what
 * they held. The check of the whole payload runs first, as for the whole decode. */
cdvr_status hvq_decode_cells_threads(const cdvr_hvq_params *p, const size_t dims[3],
                                     const uint8_t *payload, size_t bytes, uint8_t *frame,
                                     unsigned layout, const uint8_t *need, unsigned cell_log2,
                                     unsigned threads, cdvr_error *err);

#endif
