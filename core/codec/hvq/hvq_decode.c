/* core/codec/hvq/hvq_decode.c - the hvq decoder, the definition of the codec (cdvr/hvq.h):
 * the payload check, the whole-frame decoder and the per-voxel fetch that the OpenCL fetch
 * (kernels/codec/hvq_fetch.cl) mirrors line for line. */
#include "codec/hvq/hvq_internal.h"
#include "cdvr/codec.h"

#include <stdlib.h>
#include <string.h>

/* ---- check ---------------------------------------------------------------------------------- */

typedef struct hvq_view {
    const uint8_t *p;
    size_t bytes;
    uint64_t dims[3];
    uint32_t n1, n2;
    hvq_layout L;
} hvq_view;

/* Voxel extents of region r. */
static void region_extent(const hvq_view *v, uint64_t r, uint64_t origin[3], unsigned ext[3])
{
    uint64_t idx[3] = {r % v->L.nrx, (r / v->L.nrx) % v->L.nry, r / v->L.nrx / v->L.nry};
    for (int a = 0; a < 3; a++) {
        origin[a] = idx[a] * CDVR_HVQ_REGION;
        uint64_t left = v->dims[a] - origin[a];
        ext[a] = (unsigned)(left < CDVR_HVQ_REGION ? left : CDVR_HVQ_REGION);
    }
}

static cdvr_status check_header(hvq_view *v, const cdvr_hvq_params *p, cdvr_error *err)
{
    if (v->bytes < HVQ_HEADER_BYTES)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload of %zu bytes is shorter than "
                              "its %u-byte header", v->bytes, HVQ_HEADER_BYTES);
    if (memcmp(v->p, "HVQ1", 4) != 0)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: bad magic (not \"HVQ1\")");
    for (int a = 0; a < 3; a++)
        if (hvq_rd32(v->p + 4 + 4 * a) != v->dims[a])
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: dims %ux%ux%u, the "
                                  "chunk has %llux%llux%llu", hvq_rd32(v->p + 4),
                                  hvq_rd32(v->p + 8), hvq_rd32(v->p + 12),
                                  (unsigned long long)v->dims[0],
                                  (unsigned long long)v->dims[1],
                                  (unsigned long long)v->dims[2]);
    v->n1 = hvq_rd32(v->p + 16);
    v->n2 = hvq_rd32(v->p + 20);
    uint32_t k1 = p ? p->k1 : CDVR_HVQ_K_MAX, k2 = p ? p->k2 : CDVR_HVQ_K_MAX;
    if (v->n1 > k1 || v->n2 > k2 || v->n1 > CDVR_HVQ_K_MAX || v->n2 > CDVR_HVQ_K_MAX ||
        (v->n1 == 0) != (v->n2 == 0))
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: codebooks of %u and %u "
                              "entries (at most %u and %u, both 0 or neither)", v->n1, v->n2,
                              k1 < CDVR_HVQ_K_MAX ? k1 : CDVR_HVQ_K_MAX,
                              k2 < CDVR_HVQ_K_MAX ? k2 : CDVR_HVQ_K_MAX);
    if (hvq_rd64(v->p + 24) != 0)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: reserved header bytes are "
                              "not zero");
    /* blocks cannot outnumber the payload's bytes: checked before computing the layout */
    size_t nb = 1;
    for (int a = 0; a < 3; a++)
        if (!cdvr_size_mul(nb, (size_t)((v->dims[a] + 3) / 4), &nb) || nb > v->bytes)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload of %zu bytes cannot "
                                  "hold the block means of %llux%llux%llu", v->bytes,
                                  (unsigned long long)v->dims[0],
                                  (unsigned long long)v->dims[1],
                                  (unsigned long long)v->dims[2]);
    hvq_layout_get(v->dims, v->n1, v->n2, &v->L);
    if (v->L.off_data > v->bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload of %zu bytes ends before its "
                              "region directory does (%llu bytes)", v->bytes,
                              (unsigned long long)v->L.off_data);
    uint64_t pads[2][2] = {{HVQ_HEADER_BYTES + v->L.nblocks, v->L.off_c1},
                           {v->L.off_c2 + 128u * (uint64_t)v->n2, v->L.off_dir}};
    for (int i = 0; i < 2; i++)
        for (uint64_t b = pads[i][0]; b < pads[i][1]; b++)
            if (v->p[b])
                return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: padding byte %llu "
                                      "is not zero", (unsigned long long)b);
    return CDVR_OK;
}

/* One hash of region r (kind 0: index, 1: residual), read from the region directory. */
typedef struct hash_entry {
    uint32_t m, rr, n;
    uint64_t offset, domain;
    unsigned ext[3], slot_bytes;
} hash_entry;

static const char *const hash_names[2] = {"index", "residual"};

static hash_entry hash_entry_of(const hvq_view *v, uint64_t r, int kind)
{
    const uint8_t *dir = v->p + v->L.off_dir + HVQ_DIR_ENTRY_BYTES * r + 16 * kind;
    hash_entry h = {hvq_rd16(dir), hvq_rd16(dir + 2), hvq_rd32(dir + 4), hvq_rd64(dir + 8), 0,
                    {0, 0, 0}, kind == 0 ? 3 + v->L.w1 + v->L.w2 : 4};
    uint64_t origin[3];
    region_extent(v, r, origin, h.ext);
    if (kind == 0)
        for (int a = 0; a < 3; a++)
            h.ext[a] = (h.ext[a] + 3) / 4;
    h.domain = (uint64_t)h.ext[0] * h.ext[1] * h.ext[2];
    return h;
}

/* The place and size of one hash of region r: *at, where its data must start, moved past
 * it. The cheap part of the check, in payload order (check_hash_slots reads the slots). */
static cdvr_status check_hash_place(const hvq_view *v, uint64_t r, int kind, uint64_t *at,
                                    cdvr_error *err)
{
    hash_entry h = hash_entry_of(v, r, kind);
    if (h.offset != *at)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: region %llu %s hash at byte "
                              "%llu, expected %llu", (unsigned long long)r, hash_names[kind],
                              (unsigned long long)h.offset, (unsigned long long)*at);
    if (h.n == 0 || h.m == 0 || h.rr == 0) {
        if (h.n || h.m || h.rr)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: region %llu %s hash of "
                                  "%u keys has sides %u, %u", (unsigned long long)r,
                                  hash_names[kind], h.n, h.m, h.rr);
        return CDVR_OK;
    }
    if (h.m > HVQ_M_MAX || h.rr > HVQ_R_MAX || h.n > h.domain ||
        h.n > (uint64_t)h.m * h.m * h.m)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: region %llu %s hash of %u "
                              "keys with sides %u, %u (at most %llu keys, sides %u, %u)",
                              (unsigned long long)r, hash_names[kind], h.n, h.m, h.rr,
                              (unsigned long long)h.domain, HVQ_M_MAX, HVQ_R_MAX);
    uint64_t size = hvq_psh_data_bytes(h.m, h.rr, h.slot_bytes);
    if (size > v->bytes - *at)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: region %llu %s hash needs "
                              "%llu bytes, %llu left", (unsigned long long)r, hash_names[kind],
                              (unsigned long long)size, (unsigned long long)(v->bytes - *at));
    *at += size;
    return CDVR_OK;
}

/* The contents of one hash whose place check_hash_place checked: offsets below its side,
 * codebook indices inside the codebooks, and as many keys in their own slots as it says. */
static cdvr_status check_hash_slots(const hvq_view *v, uint64_t r, int kind, cdvr_error *err)
{
    hash_entry h = hash_entry_of(v, r, kind);
    if (h.n == 0)
        return CDVR_OK;
    const uint8_t *data = v->p + h.offset;
    unsigned w = hvq_offset_width(h.m);
    uint64_t r3 = (uint64_t)h.rr * h.rr * h.rr, m3 = (uint64_t)h.m * h.m * h.m, found = 0;
    for (uint64_t i = 0; i < 3 * r3; i++)
        if ((w == 1 ? data[i] : hvq_rd16(data + 2 * i)) >= h.m)
            return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: region %llu %s hash: "
                                  "offset entry %llu is not below %u", (unsigned long long)r,
                                  hash_names[kind], (unsigned long long)(i / 3), h.m);
    const uint8_t *slots = data + r3 * 3 * w;
    hvq_psh_map map; /* the offsets are below m: checked above */
    hvq_psh_map_open(&map, data, h.m, h.rr);
    for (uint64_t s = 0; s < m3; s++) {
        const uint8_t *slot = slots + s * h.slot_bytes;
        if (kind == 0) {
            uint32_t i1 = v->L.w1 == 1 ? slot[3] : hvq_rd16(slot + 3);
            uint32_t i2 = v->L.w2 == 1 ? slot[3 + v->L.w1] : hvq_rd16(slot + 3 + v->L.w1);
            if (i1 >= v->n1 || i2 >= v->n2)
                return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: region %llu index "
                                      "hash slot %llu holds indices %u, %u (codebooks of %u, "
                                      "%u)", (unsigned long long)r, (unsigned long long)s, i1,
                                      i2, v->n1, v->n2);
        }
        if (slot[0] < h.ext[0] && slot[1] < h.ext[1] && slot[2] < h.ext[2] &&
            hvq_psh_map_slot(&map, slot[0], slot[1], slot[2]) == s)
            found++;
    }
    if (found != h.n)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload: region %llu %s hash says %u "
                              "keys, its slots hold %llu", (unsigned long long)r,
                              hash_names[kind], h.n, (unsigned long long)found);
    return CDVR_OK;
}

/* check_hash_slots of every hash (item 2 r + kind) on several threads, each item its own
 * status; the error reported is the first hash's in payload order, as on one thread. */
typedef struct slots_job {
    const hvq_view *v;
    cdvr_status *status;
    cdvr_error *errs;
} slots_job;

static void check_slots_item(void *ctx, size_t item)
{
    slots_job *job = ctx;
    job->status[item] = check_hash_slots(job->v, item / 2, (int)(item % 2), &job->errs[item]);
}

static cdvr_status check_all_slots(const hvq_view *v, unsigned threads, cdvr_error *err)
{
    size_t items = 2 * (size_t)v->L.nregions;
    slots_job job = {v, malloc(items * sizeof *job.status), malloc(items * sizeof *job.errs)};
    cdvr_status s = CDVR_OK;
    if (!job.status || !job.errs) {
        for (size_t i = 0; s == CDVR_OK && i < items; i++) /* one at a time, in order */
            s = check_hash_slots(v, i / 2, (int)(i % 2), err);
    } else {
        hvq_parallel_for(threads, items, check_slots_item, &job);
        for (size_t i = 0; s == CDVR_OK && i < items; i++)
            if ((s = job.status[i]) != CDVR_OK)
                *err = job.errs[i];
    }
    free(job.status);
    free(job.errs);
    return s;
}

/* Checks the payload (the header, then every hash's place in payload order, then their slots
 * on `threads` threads) and opens the view of it. */
static cdvr_status view_open(hvq_view *v, const cdvr_hvq_params *p, const size_t dims[3],
                             const uint8_t *payload, size_t bytes, cdvr_hvq_stats *stats,
                             unsigned threads, cdvr_error *err)
{
    memset(v, 0, sizeof *v);
    for (int a = 0; a < 3; a++) {
        if (dims[a] == 0 || dims[a] > UINT32_MAX)
            return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: dims %zux%zux%zu (each 1..2^32-1)",
                                  dims[0], dims[1], dims[2]);
        v->dims[a] = dims[a];
    }
    if (!payload && bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: NULL payload of %zu bytes", bytes);
    v->p = payload;
    v->bytes = bytes;
    cdvr_status s = check_header(v, p, err);
    uint64_t at = v->L.off_data, sizes[2] = {0, 0}, keys[2] = {0, 0};
    for (uint64_t r = 0; s == CDVR_OK && r < v->L.nregions; r++)
        for (int kind = 0; s == CDVR_OK && kind < 2; kind++) {
            uint64_t before = at;
            s = check_hash_place(v, r, kind, &at, err);
            sizes[kind] += at - before;
            keys[kind] += hvq_rd32(v->p + v->L.off_dir + HVQ_DIR_ENTRY_BYTES * r + 16 * kind + 4);
        }
    if (s == CDVR_OK && at != bytes)
        s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "hvq payload of %zu bytes: its parts end at "
                           "byte %llu", bytes, (unsigned long long)at);
    if (s == CDVR_OK)
        s = check_all_slots(v, threads, err);
    if (s == CDVR_OK && stats) {
        memset(stats, 0, sizeof *stats);
        stats->means = (size_t)v->L.nblocks;
        stats->codebook1 = 16u * (size_t)v->n1;
        stats->codebook2 = 128u * (size_t)v->n2;
        stats->index_hash = (size_t)sizes[0];
        stats->residual_hash = (size_t)sizes[1];
        stats->header = bytes - stats->means - stats->codebook1 - stats->codebook2 -
                        stats->index_hash - stats->residual_hash;
        stats->blocks = (size_t)v->L.nblocks;
        stats->zero_blocks = (size_t)(v->L.nblocks - keys[0]);
        stats->residual_voxels = (size_t)keys[1];
        stats->codebook1_entries = v->n1;
        stats->codebook2_entries = v->n2;
        stats->regions = (size_t)v->L.nregions;
    }
    return s;
}

cdvr_status cdvr_hvq_check(const cdvr_hvq_params *p, const size_t dims[3],
                           const uint8_t *payload, size_t bytes, cdvr_hvq_stats *stats,
                           cdvr_error *err)
{
    hvq_view v;
    return view_open(&v, p, dims, payload, bytes, stats, hvq_threads_auto(), err);
}

/* ---- decode --------------------------------------------------------------------------------- */

/* The index hash entry (m, r, data) of region r, half 0 (index) or 1 (residual). */
static const uint8_t *dir_hash(const uint8_t *payload, const hvq_layout *L, uint64_t r, int kind,
                               uint32_t *m, uint32_t *rr)
{
    const uint8_t *dir = payload + L->off_dir + HVQ_DIR_ENTRY_BYTES * r + 16 * kind;
    *m = hvq_rd16(dir);
    *rr = hvq_rd16(dir + 2);
    return payload + hvq_rd64(dir + 8);
}

static unsigned read_index(const uint8_t *p, unsigned w)
{
    return w == 1 ? p[0] : hvq_rd16(p);
}

/* Where decode writes (codec.h decode_cells): the frame in its layout, and when need is set
 * only the blocks and residual voxels of the needed cells. */
typedef struct hvq_target {
    uint8_t *frame;
    unsigned layout;       /* CDVR_LAYOUT_LINEAR or CDVR_LAYOUT_TILED */
    cdvr_cells cells;      /* cells.need NULL: everything */
    size_t dims[3];
} hvq_target;

static int cell_needed(const hvq_target *t, uint64_t x, uint64_t y, uint64_t z)
{
    return cdvr_cells_voxel(&t->cells, (size_t)x, (size_t)y, (size_t)z);
}

/* The 64 values of a block with codewords, x fastest, then y, z: mean + c1[o8] + c2[o64]
 * clamped to 0 .. 255, in one loop of constant count without a branch, which gcc vectorises
 * at -O2 (a per-voxel loop that tested c1 ran scalar). */
static void coded_values(int mean, const uint8_t *c1, const uint8_t *c2, uint8_t vals[64])
{
    int32_t near[8], base[64], word2[64];
    for (int k = 0; k < 8; k++)
        near[k] = mean + hvq_rds16(c1 + 2 * k);
    for (int row = 0; row < 16; row++) { /* row = y + 4 z: codebook-1 entries x >> 1 = 0, 1 */
        const int32_t *e = near + 2 * ((row & 3) >> 1) + 4 * (row >> 3);
        base[4 * row] = base[4 * row + 1] = e[0];
        base[4 * row + 2] = base[4 * row + 3] = e[1];
    }
    for (int k = 0; k < 64; k++)
        word2[k] = hvq_rds16(c2 + 2 * k);
    for (int k = 0; k < 64; k++) {
        int32_t val = base[k] + word2[k];
        vals[k] = (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
    }
}

/* A whole block with codewords into a linear frame: its values, then 16 rows of 4 bytes (the
 * hot case of the whole-frame decode, kept apart so that gcc vectorises coded_values). */
static void write_coded_block(uint8_t *first, size_t X, size_t XY, int mean, const uint8_t *c1,
                              const uint8_t *c2)
{
    uint8_t vals[64];
    coded_values(mean, c1, c2, vals);
    const uint8_t *from = vals;
    for (unsigned z = 0; z < 4; z++, first += XY)
        for (unsigned y = 0; y < 4; y++, from += 4)
            memcpy(first + X * y, from, 4);
}

/* Writes the block's voxels that lie inside the frame (all of the block when it meets a
 * needed cell); index is its region's index hash. */
static void decode_block(const hvq_view *v, const hvq_psh_map *index, uint64_t bx, uint64_t by,
                         uint64_t bz, const hvq_target *t)
{
    const hvq_layout *L = &v->L;
    size_t at[3] = {4 * bx, 4 * by, 4 * bz}, n[3]; /* n: 4 but at the frame's far edges */
    /* cells of a block's 4 voxels or more hold it whole: its one cell's byte */
    if (t->cells.need && t->cells.log2 >= 2 && !cell_needed(t, at[0], at[1], at[2]))
        return;
    for (int a = 0; a < 3; a++)
        n[a] = t->dims[a] - at[a] < 4 ? t->dims[a] - at[a] : 4;
    if (t->cells.need && t->cells.log2 < 2 && !cdvr_cells_meet(&t->cells, at, n))
        return;
    int mean = v->p[HVQ_HEADER_BYTES + bx + L->nbx * (by + L->nby * bz)];
    const uint8_t *hit = hvq_psh_map_find(index, 3 + L->w1 + L->w2, (unsigned)(bx & 63),
                                          (unsigned)(by & 63), (unsigned)(bz & 63));
    const uint8_t *c1 = NULL, *c2 = NULL;
    if (hit) {
        c1 = v->p + L->off_c1 + 16u * read_index(hit, L->w1);
        c2 = v->p + L->off_c2 + 128u * read_index(hit + L->w1, L->w2);
    }
    if (t->layout == CDVR_LAYOUT_LINEAR && n[0] == 4 && n[1] == 4 && n[2] == 4) {
        size_t X = t->dims[0], XY = t->dims[0] * t->dims[1];
        uint8_t *first = t->frame + at[0] + X * at[1] + XY * at[2];
        if (c1) {
            write_coded_block(first, X, XY, mean, c1, c2);
            return;
        }
        for (unsigned z = 0; z < 4; z++, first += XY) /* the mean alone */
            for (unsigned y = 0; y < 4; y++)
                memset(first + X * y, mean, 4);
        return;
    }
    uint8_t vals[64];
    if (c1)
        coded_values(mean, c1, c2, vals);
    else
        memset(vals, mean, 64);
    cdvr_block_store(t->frame, t->dims, t->layout, at, n, vals);
}

/* Voxel (x, y, z) of the frame gets val; in a tiled frame also the copies of it that pad its
 * tile past the frame's edge. */
static void put_voxel(const hvq_target *t, uint64_t x, uint64_t y, uint64_t z, uint8_t val)
{
    const size_t *d = t->dims;
    if (t->layout != CDVR_LAYOUT_TILED) {
        t->frame[x + d[0] * (y + d[1] * z)] = val;
        return;
    }
    uint64_t end[3], at[3] = {x, y, z}; /* past the last voxel: to its tile's end */
    for (int a = 0; a < 3; a++)
        end[a] = at[a] + 1 == d[a] ? (at[a] | 3) + 1 : at[a] + 1;
    for (uint64_t pz = z; pz < end[2]; pz++)
        for (uint64_t py = y; py < end[1]; py++)
            for (uint64_t px = x; px < end[0]; px++)
                t->frame[cdvr_tiled_offset(d, px, py, pz)] = val;
}

/* Residual voxels of region r from its slots [s0, s1) (clamped to the table): every slot
 * whose key maps to itself (the lookup's hits), of the needed cells. */
static void apply_residuals(const hvq_view *v, uint64_t r, uint64_t s0, uint64_t s1,
                            const hvq_target *t)
{
    uint32_t m, rr;
    const uint8_t *data = dir_hash(v->p, &v->L, r, 1, &m, &rr);
    if (m == 0)
        return;
    uint64_t origin[3];
    unsigned ext[3];
    region_extent(v, r, origin, ext);
    uint64_t m3 = (uint64_t)m * m * m;
    hvq_psh_map map;
    hvq_psh_map_open(&map, data, m, rr);
    for (uint64_t s = s0; s < s1 && s < m3; s++) {
        const uint8_t *k = map.slots + 4 * s;
        if (k[0] >= ext[0] || k[1] >= ext[1] || k[2] >= ext[2])
            continue;
        uint64_t x = origin[0] + k[0], y = origin[1] + k[1], z = origin[2] + k[2];
        /* the cell test before the hash's (a lookup against a slot's key hashed) */
        if ((t->cells.need && !cell_needed(t, x, y, z)) ||
            hvq_psh_map_slot(&map, k[0], k[1], k[2]) != s)
            continue;
        if (!t->cells.need && t->layout == CDVR_LAYOUT_LINEAR)
            t->frame[x + v->dims[0] * (y + v->dims[1] * z)] = k[3];
        else
            put_voxel(t, x, y, z, k[3]);
    }
}

/* The whole-frame decode in two parallel passes: the blocks by z slab of blocks, then the
 * residuals by runs of RESIDUAL_RUN hash slots (they overwrite block values, so after every
 * block). Each item writes only its own voxels (slabs do not overlap, and a perfect hash
 * gives each voxel one slot; a tile's padding copies the voxel of its own tile): the same
 * bytes on any number of threads. */
#define RESIDUAL_RUN ((uint64_t)1 << 16)

typedef struct decode_job {
    const hvq_view *v;
    const hvq_target *t;
    uint64_t *first_run; /* per region, its first run's item; nregions + 1 entries */
} decode_job;

static void decode_slab(void *ctx, size_t bz)
{
    const decode_job *job = ctx;
    const hvq_layout *L = &job->v->L;
    const uint64_t side = HVQ_REGION_BLOCKS;
    for (uint64_t ry = 0; ry < L->nry; ry++)
        for (uint64_t rx = 0; rx < L->nrx; rx++) { /* the slab's part of region (rx, ry) */
            uint32_t m, rr;
            hvq_psh_map index;
            const uint8_t *data =
                dir_hash(job->v->p, L, rx + L->nrx * (ry + L->nry * ((uint64_t)bz / side)), 0,
                         &m, &rr);
            hvq_psh_map_open(&index, data, m, rr);
            uint64_t y1 = (ry + 1) * side < L->nby ? (ry + 1) * side : L->nby;
            uint64_t x1 = (rx + 1) * side < L->nbx ? (rx + 1) * side : L->nbx;
            for (uint64_t by = ry * side; by < y1; by++)
                for (uint64_t bx = rx * side; bx < x1; bx++)
                    decode_block(job->v, &index, bx, by, bz, job->t);
        }
}

static void decode_residual_run(void *ctx, size_t item)
{
    const decode_job *job = ctx;
    uint64_t r = 0;
    while (job->first_run[r + 1] <= item)
        r++;
    uint64_t s0 = (item - job->first_run[r]) * RESIDUAL_RUN;
    apply_residuals(job->v, r, s0, s0 + RESIDUAL_RUN, job->t);
}

/* first_run[r]: the item of region r's first run of slots; first_run[nregions]: all runs. */
static void count_runs(const hvq_view *v, uint64_t *first_run)
{
    first_run[0] = 0;
    for (uint64_t r = 0; r < v->L.nregions; r++) {
        uint32_t m, rr;
        dir_hash(v->p, &v->L, r, 1, &m, &rr);
        uint64_t m3 = (uint64_t)m * m * m;
        first_run[r + 1] = first_run[r] + (m3 + RESIDUAL_RUN - 1) / RESIDUAL_RUN;
    }
}

static cdvr_status decode_into(const cdvr_hvq_params *p, const size_t dims[3],
                               const uint8_t *payload, size_t bytes, const hvq_target *t,
                               unsigned threads, cdvr_error *err)
{
    hvq_view v;
    cdvr_status s = view_open(&v, p, dims, payload, bytes, NULL, threads, err);
    if (s != CDVR_OK)
        return s;
    decode_job job = {&v, t, malloc(((size_t)v.L.nregions + 1) * sizeof(uint64_t))};
    if (!job.first_run)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq decode: no memory for %llu regions",
                              (unsigned long long)v.L.nregions);
    hvq_parallel_for(threads, (size_t)v.L.nbz, decode_slab, &job);
    count_runs(&v, job.first_run);
    hvq_parallel_for(threads, (size_t)job.first_run[v.L.nregions], decode_residual_run, &job);
    free(job.first_run);
    return CDVR_OK;
}

cdvr_status hvq_decode_threads(const cdvr_hvq_params *p, const size_t dims[3],
                               const uint8_t *payload, size_t bytes, uint8_t *out,
                               unsigned threads, cdvr_error *err)
{
    hvq_target t = {out, CDVR_LAYOUT_LINEAR, {NULL, 0, {0, 0, 0}}, {dims[0], dims[1], dims[2]}};
    return decode_into(p, dims, payload, bytes, &t, threads, err);
}

cdvr_status hvq_decode_cells_threads(const cdvr_hvq_params *p, const size_t dims[3],
                                     const uint8_t *payload, size_t bytes, uint8_t *frame,
                                     unsigned layout, const uint8_t *need, unsigned cell_log2,
                                     unsigned threads, cdvr_error *err)
{
    if (cell_log2 > 30 || (layout != CDVR_LAYOUT_LINEAR && layout != CDVR_LAYOUT_TILED) || !need)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq decode: cells of 2^%u voxels, layout %u",
                              cell_log2, layout);
    for (int a = 0; a < 3; a++)
        if (dims[a] == 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "hvq decode: dims %zux%zux%zu", dims[0],
                                  dims[1], dims[2]);
    hvq_target t = {frame, layout, cdvr_cells_of(need, cell_log2, dims),
                    {dims[0], dims[1], dims[2]}};
    return decode_into(p, dims, payload, bytes, &t, threads, err);
}

cdvr_status cdvr_hvq_decode(const cdvr_hvq_params *p, const size_t dims[3],
                            const uint8_t *payload, size_t bytes, uint8_t *out, cdvr_error *err)
{
    return hvq_decode_threads(p, dims, payload, bytes, out, hvq_threads_auto(), err);
}

/* ---- per-voxel fetch (kernels/codec/hvq_fetch.cl is the same function) ----------------------- */

uint8_t cdvr_hvq_fetch(const uint8_t *payload, const size_t dims[3], size_t x, size_t y,
                       size_t z)
{
    const uint64_t d64[3] = {dims[0], dims[1], dims[2]};
    hvq_layout L;
    hvq_layout_get(d64, hvq_rd32(payload + 16), hvq_rd32(payload + 20), &L);
    uint64_t region = (x >> 8) + L.nrx * ((y >> 8) + L.nry * (z >> 8));
    uint32_t m, rr;
    const uint8_t *data = dir_hash(payload, &L, region, 1, &m, &rr);
    const uint8_t *hit = hvq_psh_find(data, m, rr, 4, (unsigned)(x & 255), (unsigned)(y & 255),
                                      (unsigned)(z & 255));
    if (hit)
        return hit[0];
    uint64_t bx = x >> 2, by = y >> 2, bz = z >> 2;
    int val = payload[HVQ_HEADER_BYTES + bx + L.nbx * (by + L.nby * bz)];
    data = dir_hash(payload, &L, region, 0, &m, &rr);
    hit = hvq_psh_find(data, m, rr, 3 + L.w1 + L.w2, (unsigned)(bx & 63), (unsigned)(by & 63),
                       (unsigned)(bz & 63));
    if (!hit)
        return (uint8_t)val;
    unsigned o8 = ((x & 3) >> 1) + 2 * ((y & 3) >> 1) + 4 * ((z & 3) >> 1);
    unsigned o64 = (x & 3) + 4 * (y & 3) + 16 * (z & 3);
    val += hvq_rds16(payload + L.off_c1 + 16u * read_index(hit, L.w1) + 2 * o8);
    val += hvq_rds16(payload + L.off_c2 + 128u * read_index(hit + L.w1, L.w2) + 2 * o64);
    return (uint8_t)(val < 0 ? 0 : val > 255 ? 255 : val);
}
