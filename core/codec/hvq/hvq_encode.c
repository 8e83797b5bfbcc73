/* core/codec/hvq/hvq_encode.c - the hvq encoder (cdvr/hvq.h): block classification (seed eq.
 * 11-12), two-level VQ, the per-region perfect spatial hashes of block indices and residual
 * voxels, and the payload writer. */
#include "codec/hvq/hvq_internal.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void hvq_layout_get(const uint64_t dims[3], uint32_t n1, uint32_t n2, hvq_layout *out)
{
    out->nbx = (dims[0] + 3) / 4;
    out->nby = (dims[1] + 3) / 4;
    out->nbz = (dims[2] + 3) / 4;
    out->nblocks = out->nbx * out->nby * out->nbz;
    out->nrx = (dims[0] + CDVR_HVQ_REGION - 1) / CDVR_HVQ_REGION;
    out->nry = (dims[1] + CDVR_HVQ_REGION - 1) / CDVR_HVQ_REGION;
    out->nrz = (dims[2] + CDVR_HVQ_REGION - 1) / CDVR_HVQ_REGION;
    out->nregions = out->nrx * out->nry * out->nrz;
    out->off_c1 = (HVQ_HEADER_BYTES + out->nblocks + 7) & ~(uint64_t)7;
    out->off_c2 = out->off_c1 + 16u * (uint64_t)n1;
    out->off_dir = (out->off_c2 + 128u * (uint64_t)n2 + 7) & ~(uint64_t)7;
    out->off_data = out->off_dir + HVQ_DIR_ENTRY_BYTES * out->nregions;
    out->w1 = hvq_index_width(n1);
    out->w2 = hvq_index_width(n2);
}

/* ---- bound ---------------------------------------------------------------------------------- */

/* Regions along one axis: `full` of side 256 and, when part > 0, one of side part. */
typedef struct axis_regions {
    size_t full, part;
} axis_regions;

static axis_regions axis_split(size_t n)
{
    axis_regions a = {n / CDVR_HVQ_REGION, n % CDVR_HVQ_REGION};
    return a;
}

/* Worst-case hash data of one region of voxel extents e[3]. */
static uint64_t region_bound(const size_t e[3], unsigned index_slot)
{
    uint64_t blocks = 1, voxels = 1;
    unsigned bext = 0, vext = 0;
    for (int a = 0; a < 3; a++) {
        size_t b = (e[a] + 3) / 4;
        blocks *= b;
        voxels *= e[a];
        bext = b > bext ? (unsigned)b : bext;
        vext = e[a] > vext ? (unsigned)e[a] : vext;
    }
    return hvq_psh_bound((size_t)blocks, bext, index_slot) + hvq_psh_bound((size_t)voxels, vext, 4);
}

cdvr_status cdvr_hvq_bound(const cdvr_hvq_params *p, const size_t dims[3], size_t *bytes,
                           cdvr_error *err)
{
    size_t voxels = 1;
    for (int a = 0; a < 3; a++) {
        if (dims[a] == 0 || dims[a] > UINT32_MAX)
            return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: dims %zux%zux%zu (each 1..2^32-1)",
                                  dims[0], dims[1], dims[2]);
        if (!cdvr_size_mul(voxels, dims[a], &voxels))
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: dims %zux%zux%zu overflow size_t",
                                  dims[0], dims[1], dims[2]);
    }
    const uint64_t d64[3] = {dims[0], dims[1], dims[2]};
    uint32_t k1 = p->k1 > CDVR_HVQ_K_MAX ? CDVR_HVQ_K_MAX : p->k1;
    uint32_t k2 = p->k2 > CDVR_HVQ_K_MAX ? CDVR_HVQ_K_MAX : hvq_k2_max(p->k2);
    hvq_layout L;
    hvq_layout_get(d64, k1, k2, &L);
    unsigned index_slot = 3 + L.w1 + L.w2;
    /* every region: at most 8 kinds (full or partial along each axis) */
    axis_regions ax[3] = {axis_split(dims[0]), axis_split(dims[1]), axis_split(dims[2])};
    size_t total = 0;
    int ok = cdvr_size_add((size_t)L.off_data, 0, &total);
    for (int kind = 0; ok && kind < 8; kind++) {
        size_t e[3], count = 1;
        for (int a = 0; a < 3; a++) {
            int partial = (kind >> a) & 1;
            size_t n = partial ? (ax[a].part ? 1 : 0) : ax[a].full;
            e[a] = partial ? ax[a].part : CDVR_HVQ_REGION;
            count *= n;
        }
        if (count == 0)
            continue;
        uint64_t one = region_bound(e, index_slot);
        size_t all;
        ok = one <= SIZE_MAX && cdvr_size_mul(count, (size_t)one, &all) &&
             cdvr_size_add(total, all, &total);
    }
    if (!ok)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: the payload bound for dims "
                              "%zux%zux%zu overflows size_t", dims[0], dims[1], dims[2]);
    *bytes = total;
    return CDVR_OK;
}

/* ---- encoder state -------------------------------------------------------------------------- */

typedef struct hvq_enc {
    const cdvr_hvq_params *p;
    const uint8_t *frame;
    size_t X, Y, Z;       /* the block grid's extent (compact form: the core) */
    size_t SX, SY, SZ;    /* the frame's dims */
    size_t OX, OY, OZ;    /* the core's origin in the frame (compact form: hvq2_skip) */
    unsigned threads;
    hvq_layout L;
    uint8_t *means;       /* per block */
    uint32_t *nz;         /* per block: its number among non-zero blocks, or UINT32_MAX */
    size_t nnz;
    uint32_t *nz_block;   /* per non-zero block: its block number */
    int16_t *l1;          /* nnz x 8: sub-block sums of the residual */
    int16_t *l2;          /* nnz x 64: residual, then residual minus decoded level 1 */
    uint16_t *i1, *i2;
    int16_t *cb1;         /* K_MAX x 8 */
    int16_t *cb2;         /* K_MAX x 64 */
    unsigned n1, n2;
    const cdvr_hvq_codebooks *shared; /* compact form: the variant's codebooks, or NULL */
    uint32_t R;           /* the residual threshold applied (choose_residual) */
    int lbg_iterations[2];
    hvq_psh *ihash, *rhash;  /* per region */
    cdvr_status *rstatus;
    cdvr_error *rerr;
} hvq_enc;

static void enc_free(hvq_enc *e)
{
    for (uint64_t r = 0; e->ihash && r < e->L.nregions; r++) {
        hvq_psh_free(&e->ihash[r]);
        hvq_psh_free(&e->rhash[r]);
    }
    free(e->means);
    free(e->nz);
    free(e->nz_block);
    free(e->l1);
    free(e->l2);
    free(e->i1);
    free(e->i2);
    free(e->cb1);
    free(e->cb2);
    free(e->ihash);
    free(e->rhash);
    free(e->rstatus);
    free(e->rerr);
}

static uint8_t voxel_at(const hvq_enc *e, size_t x, size_t y, size_t z)
{
    x = x < e->X ? x : e->X - 1;
    y = y < e->Y ? y : e->Y - 1;
    z = z < e->Z ? z : e->Z - 1;
    return e->frame[(x + e->OX) + e->SX * ((y + e->OY) + e->SY * (z + e->OZ))];
}

/* The 4x4x4 block (n = 4) or the block plus its +1 neighbours (n = 5), edge-replicated,
 * into c[z][y][x] (x fastest, side n). */
static void load_block(const hvq_enc *e, size_t bx, size_t by, size_t bz, int n, uint8_t *c)
{
    for (int z = 0; z < n; z++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++)
                c[x + n * (y + n * z)] = voxel_at(e, 4 * bx + x, 4 * by + y, 4 * bz + z);
}

/* Item: one row of blocks (by, bz): means and the zero-block test. */
static void classify_row(void *ctx, size_t row)
{
    hvq_enc *e = ctx;
    size_t by = row % e->L.nby, bz = row / e->L.nby;
    uint8_t c[125];
    for (size_t bx = 0; bx < e->L.nbx; bx++) {
        load_block(e, bx, by, bz, 5, c);
        unsigned sum = 0, grad = 0;
        for (int z = 0; z < 4; z++)
            for (int y = 0; y < 4; y++)
                for (int x = 0; x < 4; x++) {
                    int i = x + 5 * (y + 5 * z), f = c[i];
                    sum += (unsigned)f;
                    grad += (unsigned)(abs(c[i + 1] - f) + abs(c[i + 5] - f) + abs(c[i + 25] - f));
                }
        size_t b = bx + e->L.nbx * (by + e->L.nby * bz);
        e->means[b] = (uint8_t)((sum + 32) >> 6);
        e->nz[b] = (double)grad < 64.0 * e->p->grad ? 0 : 1; /* numbered below */
    }
}

/* Item: non-zero block k: residual to the mean (l2) and its 2x2x2 sums (l1). */
static void residual_vectors(void *ctx, size_t k)
{
    hvq_enc *e = ctx;
    size_t b = e->nz_block[k];
    size_t bx = b % e->L.nbx, by = (b / e->L.nbx) % e->L.nby, bz = b / e->L.nbx / e->L.nby;
    uint8_t c[64];
    load_block(e, bx, by, bz, 4, c);
    int16_t *r = e->l2 + k * 64, *s = e->l1 + k * 8;
    memset(s, 0, 8 * sizeof *s);
    for (int i = 0; i < 64; i++) {
        r[i] = (int16_t)(c[i] - e->means[b]);
        s[((i & 3) >> 1) + 2 * ((i >> 2 & 3) >> 1) + 4 * ((i >> 4) >> 1)] += r[i];
    }
}

static cdvr_status classify(hvq_enc *e, cdvr_error *err)
{
    size_t nb = (size_t)e->L.nblocks;
    e->means = malloc(nb);
    e->nz = malloc(nb * sizeof *e->nz);
    if (!e->means || !e->nz)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for %zu blocks", nb);
    hvq_parallel_for(e->threads, (size_t)(e->L.nby * e->L.nbz), classify_row, e);
    size_t nnz = 0;
    for (size_t b = 0; b < nb; b++)
        e->nz[b] = e->nz[b] ? (uint32_t)nnz++ : UINT32_MAX;
    e->nnz = nnz;
    e->nz_block = malloc((nnz ? nnz : 1) * sizeof *e->nz_block);
    e->l1 = malloc((nnz ? nnz : 1) * 8 * sizeof *e->l1);
    e->l2 = malloc((nnz ? nnz : 1) * 64 * sizeof *e->l2);
    e->i1 = malloc((nnz ? nnz : 1) * sizeof *e->i1);
    e->i2 = malloc((nnz ? nnz : 1) * sizeof *e->i2);
    if (!e->nz_block || !e->l1 || !e->l2 || !e->i1 || !e->i2)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for %zu non-zero blocks",
                              nnz);
    for (size_t b = 0; b < nb; b++)
        if (e->nz[b] != UINT32_MAX)
            e->nz_block[e->nz[b]] = (uint32_t)b;
    hvq_parallel_for(e->threads, nnz, residual_vectors, e);
    return CDVR_OK;
}

/* Level-2 vectors: the residual minus the decoded level 1 of each block's entry. */
static void subtract_level1(int16_t *l2, size_t n, const int16_t *cb1, const uint16_t *i1)
{
    for (size_t k = 0; k < n; k++) {
        const int16_t *c = cb1 + (size_t)i1[k] * 8;
        int16_t *r = l2 + k * 64;
        for (int i = 0; i < 64; i++)
            r[i] = (int16_t)(r[i] - c[((i & 3) >> 1) + 2 * ((i >> 2 & 3) >> 1) + 4 * ((i >> 4) >> 1)]);
    }
}

/* Level 2 at codebook size k at most: trains codebook 2 and assigns every block. */
static cdvr_status level2(hvq_enc *e, uint32_t k, cdvr_error *err)
{
    hvq_vq_report rep;
    cdvr_status s = hvq_vq_train(e->l2, e->nnz, 64, k, 1, e->p->eps, e->p->train, e->threads,
                                 e->cb2, &e->n2, &rep, err);
    if (s == CDVR_OK)
        hvq_vq_assign(e->l2, e->nnz, 64, e->cb2, e->n2, 1, e->threads, e->i2);
    e->lbg_iterations[1] = rep.lbg_iterations;
    return s;
}

static cdvr_status quantise(hvq_enc *e, cdvr_error *err)
{
    hvq_vq_report rep;
    e->cb1 = malloc(sizeof *e->cb1 * CDVR_HVQ_K_MAX * 8);
    e->cb2 = malloc(sizeof *e->cb2 * CDVR_HVQ_K_MAX * 64);
    if (!e->cb1 || !e->cb2)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for the codebooks");
    if (e->shared) { /* the variant's codebooks: assignment only */
        e->n1 = e->shared->n1;
        e->n2 = e->shared->n2;
        memcpy(e->cb1, e->shared->c1, sizeof *e->cb1 * 8 * e->n1);
        memcpy(e->cb2, e->shared->c2, sizeof *e->cb2 * 64 * e->n2);
        if (e->n1 == 0) { /* trained on empty frames: every block is a zero block here */
            for (uint64_t b = 0; b < e->L.nblocks; b++)
                e->nz[b] = UINT32_MAX;
            e->nnz = 0;
        }
        hvq_vq_assign(e->l1, e->nnz, 8, e->cb1, e->n1, 8, e->threads, e->i1);
        subtract_level1(e->l2, e->nnz, e->cb1, e->i1);
        hvq_vq_assign(e->l2, e->nnz, 64, e->cb2, e->n2, 1, e->threads, e->i2);
        return CDVR_OK;
    }
    cdvr_status s = hvq_vq_train(e->l1, e->nnz, 8, e->p->k1, 8, e->p->eps, e->p->train,
                                 e->threads, e->cb1, &e->n1, &rep, err);
    if (s != CDVR_OK)
        return s;
    e->lbg_iterations[0] = rep.lbg_iterations;
    hvq_vq_assign(e->l1, e->nnz, 8, e->cb1, e->n1, 8, e->threads, e->i1);
    subtract_level1(e->l2, e->nnz, e->cb1, e->i1);
    return e->p->k2 ? level2(e, e->p->k2, err) : CDVR_OK; /* auto: choose_k2 */
}

/* Voxel value before the residual stage (the decoder's formula). */
static int base_value(const hvq_enc *e, size_t x, size_t y, size_t z)
{
    size_t b = (x >> 2) + e->L.nbx * ((y >> 2) + e->L.nby * (z >> 2));
    int v = e->means[b];
    uint32_t k = e->nz[b];
    if (k != UINT32_MAX) {
        unsigned o8 = ((x & 3) >> 1) + 2 * ((y & 3) >> 1) + 4 * ((z & 3) >> 1);
        unsigned o64 = (x & 3) + 4 * (y & 3) + 16 * (z & 3);
        v += e->cb1[(size_t)e->i1[k] * 8 + o8] + e->cb2[(size_t)e->i2[k] * 64 + o64];
    }
    return v < 0 ? 0 : v > 255 ? 255 : v;
}

/* Frame voxel (x, y, z)'s value before the residual stage: outside the compact form's core,
 * the nearest core voxel's (hvq2_skip; the hashed form's core is the frame). */
static int frame_base(const hvq_enc *e, size_t x, size_t y, size_t z)
{
    return base_value(e, x > e->OX ? x - e->OX : 0, y > e->OY ? y - e->OY : 0,
                      z > e->OZ ? z - e->OZ : 0);
}

/* Squared error of the decoded voxel (base b, original v) at residual threshold R. */
static uint64_t decoded_error2(int b, int v, uint32_t R, int compact)
{
    int d = v - b;
    if ((uint32_t)abs(d) <= R)
        return (uint64_t)(d * d);
    if (!compact)
        return 0; /* the residual hash holds v */
    int step = 2 * (int)R + 1, q = (abs(d) + (int)R) / step;
    int value = b + (d < 0 ? -q : q) * step;
    value = value < 0 ? 0 : value > 255 ? 255 : value;
    return (uint64_t)((value - v) * (value - v));
}

/* The residual threshold (cdvr/hvq.h "Quality target"): p->residual, or under a PSNR target
 * the largest R <= p->residual whose decoded frame meets it, from the exact squared error of
 * each R over the histogram of (base, original) pairs. */
static cdvr_status choose_residual(hvq_enc *e, int compact, cdvr_error *err)
{
    e->R = e->p->residual;
    if (!(e->p->psnr > 0))
        return CDVR_OK;
    uint64_t *pairs = calloc(256 * 256 * 3, sizeof *pairs);
    if (!pairs)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for the PSNR search");
    for (size_t z = 0; z < e->SZ; z++)
        for (size_t y = 0; y < e->SY; y++)
            for (size_t x = 0; x < e->SX; x++)
                pairs[256 * frame_base(e, x, y, z) + e->frame[x + e->SX * (y + e->SY * z)]]++;
    uint64_t *list = pairs + 256 * 256; /* the non-empty pairs: b << 8 | v, then the count */
    size_t used = 0;
    for (unsigned bv = 0; bv < 256 * 256; bv++)
        if (pairs[bv]) {
            list[used++] = bv;
            list[used++] = pairs[bv];
        }
    double voxels = (double)e->SX * (double)e->SY * (double)e->SZ;
    double sse_max = 255.0 * 255.0 * voxels / pow(10.0, e->p->psnr / 10.0);
    for (;; e->R--) {
        uint64_t sse = 0;
        for (size_t i = 0; i < used; i += 2)
            sse += list[i + 1] * decoded_error2((int)(list[i] >> 8), (int)(list[i] & 255),
                                                e->R, compact);
        if (sse == 0 || (double)sse <= sse_max || e->R == 0)
            break;
    }
    free(pairs);
    return CDVR_OK;
}

static void put_index(uint8_t *p, unsigned w, unsigned v)
{
    if (w == 1)
        p[0] = (uint8_t)v;
    else
        hvq_wr16(p, v);
}

/* Keys (3 bytes each) and their values (at most 4 bytes each) of one hash being gathered. */
typedef struct key_list {
    uint8_t *keys, *values;
    size_t n, cap;
} key_list;

/* Room for one more key; 0: out of memory. */
static int key_list_grow(key_list *k)
{
    if (k->n < k->cap)
        return 1;
    size_t cap = k->cap ? 2 * k->cap : 4096;
    uint8_t *keys = realloc(k->keys, 3 * cap);
    if (keys)
        k->keys = keys;
    uint8_t *values = keys ? realloc(k->values, 4 * cap) : NULL;
    if (values)
        k->values = values;
    if (!keys || !values)
        return 0;
    k->cap = cap;
    return 1;
}

static void key_list_put(key_list *k, size_t x, size_t y, size_t z)
{
    k->keys[3 * k->n] = (uint8_t)x;
    k->keys[3 * k->n + 1] = (uint8_t)y;
    k->keys[3 * k->n + 2] = (uint8_t)z;
}

/* Item: region r: its index hash and its residual hash. */
static void build_region(void *ctx, size_t r)
{
    hvq_enc *e = ctx;
    const hvq_layout *L = &e->L;
    size_t rx = r % L->nrx, ry = (r / L->nrx) % L->nry, rz = r / L->nrx / L->nry;
    size_t x0 = rx * CDVR_HVQ_REGION, y0 = ry * CDVR_HVQ_REGION, z0 = rz * CDVR_HVQ_REGION;
    size_t x1 = x0 + CDVR_HVQ_REGION < e->X ? x0 + CDVR_HVQ_REGION : e->X;
    size_t y1 = y0 + CDVR_HVQ_REGION < e->Y ? y0 + CDVR_HVQ_REGION : e->Y;
    size_t z1 = z0 + CDVR_HVQ_REGION < e->Z ? z0 + CDVR_HVQ_REGION : e->Z;
    unsigned vb = L->w1 + L->w2; /* <= 4 */
    key_list k = {NULL, NULL, 0, 0};
    cdvr_status s = CDVR_OK;
    /* index hash: non-zero blocks in z, y, x order, keyed by block coordinates in the region */
    for (size_t bz = z0 / 4; s == CDVR_OK && bz < (z1 + 3) / 4; bz++)
        for (size_t by = y0 / 4; s == CDVR_OK && by < (y1 + 3) / 4; by++)
            for (size_t bx = x0 / 4; s == CDVR_OK && bx < (x1 + 3) / 4; bx++) {
                uint32_t nz = e->nz[bx + L->nbx * (by + L->nby * bz)];
                if (nz == UINT32_MAX)
                    continue;
                if (!key_list_grow(&k)) {
                    s = CDVR_ERR_NOMEM;
                    break;
                }
                key_list_put(&k, bx & 63, by & 63, bz & 63);
                put_index(k.values + (size_t)vb * k.n, L->w1, e->i1[nz]);
                put_index(k.values + (size_t)vb * k.n + L->w1, L->w2, e->i2[nz]);
                k.n++;
            }
    if (s == CDVR_OK)
        s = hvq_psh_build(k.keys, k.values, k.n, vb, HVQ_PSH_ATTEMPTS, &e->ihash[r], &e->rerr[r]);
    /* residual hash: voxels off by more than `residual`, z, y, x order, keyed by voxel
     * coordinates in the region, holding the original value */
    k.n = 0;
    for (size_t z = z0; s == CDVR_OK && z < z1; z++)
        for (size_t y = y0; s == CDVR_OK && y < y1; y++)
            for (size_t x = x0; x < x1; x++) {
                int v = e->frame[x + e->X * (y + e->Y * z)];
                if ((uint32_t)abs(v - base_value(e, x, y, z)) <= e->R)
                    continue;
                if (!key_list_grow(&k)) {
                    s = CDVR_ERR_NOMEM;
                    break;
                }
                key_list_put(&k, x & 255, y & 255, z & 255);
                k.values[k.n++] = (uint8_t)v;
            }
    if (s == CDVR_OK)
        s = hvq_psh_build(k.keys, k.values, k.n, 1, HVQ_PSH_ATTEMPTS, &e->rhash[r], &e->rerr[r]);
    if (s == CDVR_ERR_NOMEM && !e->rerr[r].msg[0])
        cdvr_error_set(&e->rerr[r], s, "out of memory");
    e->rstatus[r] = s;
    free(k.keys);
    free(k.values);
}

static cdvr_status build_regions(hvq_enc *e, cdvr_error *err)
{
    size_t nr = (size_t)e->L.nregions;
    e->ihash = calloc(nr, sizeof *e->ihash);
    e->rhash = calloc(nr, sizeof *e->rhash);
    e->rstatus = calloc(nr, sizeof *e->rstatus);
    e->rerr = calloc(nr, sizeof *e->rerr);
    if (!e->ihash || !e->rhash || !e->rstatus || !e->rerr)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for %zu regions", nr);
    hvq_parallel_for(e->threads, nr, build_region, e);
    for (size_t r = 0; r < nr; r++)
        if (e->rstatus[r] != CDVR_OK)
            return cdvr_error_set(err, e->rstatus[r], "hvq: region %zu,%zu,%zu: %s",
                                  r % e->L.nrx, (r / e->L.nrx) % e->L.nry,
                                  r / e->L.nrx / e->L.nry, e->rerr[r].msg);
    return CDVR_OK;
}

static void write_dir_half(uint8_t *p, const hvq_psh *h, uint64_t offset)
{
    hvq_wr16(p, h->m);
    hvq_wr16(p + 2, h->r);
    hvq_wr32(p + 4, h->n);
    hvq_wr64(p + 8, offset);
}

static cdvr_status write_payload(const hvq_enc *e, uint8_t *out, size_t out_cap,
                                 size_t *out_bytes, cdvr_hvq_stats *stats, cdvr_error *err)
{
    const uint64_t d64[3] = {e->X, e->Y, e->Z};
    hvq_layout L;
    hvq_layout_get(d64, e->n1, e->n2, &L);
    uint64_t total = L.off_data, ibytes = 0, rbytes = 0, rvoxels = 0;
    for (uint64_t r = 0; r < L.nregions; r++) {
        ibytes += e->ihash[r].bytes;
        rbytes += e->rhash[r].bytes;
        rvoxels += e->rhash[r].n;
    }
    total += ibytes + rbytes;
    if (total > out_cap)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: the payload needs %llu bytes, the buffer "
                              "has %zu", (unsigned long long)total, out_cap);
    memset(out, 0, (size_t)L.off_data);
    memcpy(out, "HVQ1", 4);
    hvq_wr32(out + 4, (uint32_t)e->X);
    hvq_wr32(out + 8, (uint32_t)e->Y);
    hvq_wr32(out + 12, (uint32_t)e->Z);
    hvq_wr32(out + 16, e->n1);
    hvq_wr32(out + 20, e->n2);
    memcpy(out + HVQ_HEADER_BYTES, e->means, (size_t)L.nblocks);
    for (size_t i = 0; i < (size_t)e->n1 * 8; i++)
        hvq_wr16(out + L.off_c1 + 2 * i, (uint16_t)e->cb1[i]);
    for (size_t i = 0; i < (size_t)e->n2 * 64; i++)
        hvq_wr16(out + L.off_c2 + 2 * i, (uint16_t)e->cb2[i]);
    uint64_t at = L.off_data;
    for (uint64_t r = 0; r < L.nregions; r++) {
        uint8_t *dir = out + L.off_dir + HVQ_DIR_ENTRY_BYTES * r;
        const hvq_psh *h[2] = {&e->ihash[r], &e->rhash[r]};
        for (int i = 0; i < 2; i++) {
            write_dir_half(dir + 16 * i, h[i], at);
            if (h[i]->bytes)
                memcpy(out + at, h[i]->data, h[i]->bytes);
            at += h[i]->bytes;
        }
    }
    *out_bytes = (size_t)total;
    if (stats) {
        memset(stats, 0, sizeof *stats);
        stats->means = (size_t)L.nblocks;
        stats->codebook1 = 16u * (size_t)e->n1;
        stats->codebook2 = 128u * (size_t)e->n2;
        stats->index_hash = (size_t)ibytes;
        stats->residual_hash = (size_t)rbytes;
        stats->header = (size_t)total - stats->means - stats->codebook1 - stats->codebook2 -
                        stats->index_hash - stats->residual_hash;
        stats->blocks = (size_t)L.nblocks;
        stats->zero_blocks = (size_t)L.nblocks - e->nnz;
        stats->residual_voxels = (size_t)rvoxels;
        stats->codebook1_entries = e->n1;
        stats->codebook2_entries = e->n2;
        stats->regions = (size_t)L.nregions;
        stats->residual = e->R;
        stats->lbg_iterations[0] = e->lbg_iterations[0];
        stats->lbg_iterations[1] = e->lbg_iterations[1];
        for (uint64_t r = 0; r < L.nregions; r++) {
            int most = e->ihash[r].attempts > e->rhash[r].attempts ? e->ihash[r].attempts
                                                                   : e->rhash[r].attempts;
            stats->hash_attempts = most > stats->hash_attempts ? most : stats->hash_attempts;
        }
    }
    return CDVR_OK;
}

/* The stages both forms share: arguments, classification and the two codebooks. */
static cdvr_status encode_common(hvq_enc *e, const cdvr_hvq_params *p,
                                 const cdvr_hvq_codebooks *shared, int compact,
                                 const size_t dims[3], const uint8_t *frame, unsigned threads,
                                 uint8_t *out, size_t *out_bytes, cdvr_error *err)
{
    size_t bound;
    memset(e, 0, sizeof *e);
    e->shared = shared;
    if (!p || !dims || !frame || !out || !out_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: encode with a NULL argument");
    cdvr_status s = cdvr_hvq_params_check(p, err);
    if (s == CDVR_OK)
        s = cdvr_hvq_bound(p, dims, &bound, err); /* validates dims, no overflow below */
    if (s != CDVR_OK)
        return s;
    if ((dims[0] + 3) / 4 * ((dims[1] + 3) / 4) * ((dims[2] + 3) / 4) >= UINT32_MAX)
        return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "hvq: %zux%zux%zu has 2^32 blocks or "
                              "more (encode it in bricks)", dims[0], dims[1], dims[2]);
    e->p = p;
    e->frame = frame;
    e->SX = dims[0];
    e->SY = dims[1];
    e->SZ = dims[2];
    e->OX = compact ? hvq2_skip(dims[0]) : 0;
    e->OY = compact ? hvq2_skip(dims[1]) : 0;
    e->OZ = compact ? hvq2_skip(dims[2]) : 0;
    e->X = dims[0] - e->OX;
    e->Y = dims[1] - e->OY;
    e->Z = dims[2] - e->OZ;
    e->threads = threads ? threads : hvq_threads_auto();
    const uint64_t d64[3] = {e->X, e->Y, e->Z};
    hvq_layout_get(d64, 0, 0, &e->L);
    s = classify(e, err);
    if (s == CDVR_OK)
        s = quantise(e, err);
    if (s == CDVR_OK && !p->k2 && !shared && !compact)
        s = cdvr_error_set(err, CDVR_ERR_ARG, "hvq: k2 = auto is for the compact form (hvqc)");
    if (s == CDVR_OK && (p->k2 || shared)) { /* auto: choose_k2 finishes these */
        hvq_layout_get(d64, e->n1, e->n2, &e->L);
        s = choose_residual(e, compact, err);
    }
    return s;
}

cdvr_status cdvr_hvq_encode(const cdvr_hvq_params *p, const size_t dims[3],
                            const uint8_t *frame, unsigned threads, uint8_t *out,
                            size_t out_cap, size_t *out_bytes, cdvr_hvq_stats *stats,
                            cdvr_error *err)
{
    hvq_enc e;
    cdvr_status s = encode_common(&e, p, NULL, 0, dims, frame, threads, out, out_bytes, err);
    if (s == CDVR_OK)
        s = build_regions(&e, err);
    if (s == CDVR_OK)
        s = write_payload(&e, out, out_cap, out_bytes, stats, err);
    enc_free(&e);
    return s;
}

/* ---- compact form (HVQ2) ---------------------------------------------------------------------- */

/* The compact form's raw sections (hvq_compact_sections) from the encoder's state: the
 * residual stage keeps, for each voxel off by more than R, q = round(d / (2R+1)) of d = v - b
 * (halves away from zero; |d - q(2R+1)| <= R). */
static cdvr_status compact_sections(const hvq_enc *e, hvq_sections *sec, cdvr_error *err)
{
    const hvq_layout *L = &e->L;
    uint32_t R = e->R, step = 2 * R + 1;
    cdvr_status s = hvq_sections_alloc(sec, L, e->nnz, e->shared ? 0 : e->n1,
                                       e->shared ? 0 : e->n2, err);
    if (s != CDVR_OK)
        return s;
    sec->wq = R == 0 ? 2 : 1;
    uint8_t prev = 0;
    for (uint64_t b = 0; b < L->nblocks; b++) {
        sec->raw[HVQ_SEC_MEANS][b] = (uint8_t)(e->means[b] - prev);
        prev = e->means[b];
        if (e->nz[b] != UINT32_MAX)
            sec->raw[HVQ_SEC_BITMAP][b >> 3] |= (uint8_t)(1u << (b & 7));
    }
    hvq_sections_put_indices(sec, e->i1, e->i2, e->nnz, L->w1, L->w2);
    if (!e->shared)
        hvq_sections_put_codebooks(sec, e->cb1, e->n1, e->cb2, e->n2);
    uint64_t last = 0;
    for (size_t z = 0; z < e->SZ; z++)
        for (size_t y = 0; y < e->SY; y++)
            for (size_t x = 0; x < e->SX; x++) {
                uint64_t at = x + e->SX * (y + e->SY * (uint64_t)z);
                int v = e->frame[at];
                /* outside the core: the nearest core voxel's value (hvq2_skip) */
                int d = v - frame_base(e, x, y, z);
                if ((uint32_t)abs(d) <= R)
                    continue;
                int q = (abs(d) + (int)R) / (int)step; /* round(|d| / step), halves up */
                if (!hvq_sections_put_residual(sec, at - last, d < 0 ? -q : q))
                    return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for the "
                                          "residual list");
                last = at + 1;
            }
    return CDVR_OK;
}

/* k2 = auto (cdvr/hvq.h "Codebook size from the data"): level 2 trained at each candidate
 * size, the payload's size measured for each (sections built and compressed), the smallest kept (ties: the
 * smaller size); e ends as after a plain encode at that size. */
static const uint32_t k2_candidates[] = {256, 512, 1024, 2048};

static cdvr_status compact_size(hvq_enc *e, const size_t dims[3], size_t *bytes,
                                cdvr_error *err)
{
    const uint64_t d64[3] = {e->X, e->Y, e->Z};
    hvq_sections sec;
    memset(&sec, 0, sizeof sec);
    hvq_layout_get(d64, e->n1, e->n2, &e->L);
    cdvr_status s = choose_residual(e, 1, err);
    if (s == CDVR_OK)
        s = compact_sections(e, &sec, err);
    if (s == CDVR_OK)
        s = hvq_compact_write(&sec, dims, e->n1, e->n2, e->R, 0, NULL, 0, bytes, NULL, err);
    hvq_sections_free(&sec);
    return s;
}

static cdvr_status choose_k2(hvq_enc *e, const size_t dims[3], cdvr_error *err)
{
    uint16_t *best_i2 = malloc((e->nnz ? e->nnz : 1) * sizeof *best_i2);
    int16_t *best_cb2 = malloc(sizeof *best_cb2 * 64 * HVQ_K2_AUTO_MAX);
    cdvr_status s = best_i2 && best_cb2 ? CDVR_OK :
        cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for the k2 = auto search");
    size_t best = SIZE_MAX, bytes;
    unsigned best_n2 = 0, last_n2 = UINT_MAX;
    int best_lbg = 0;
    for (size_t c = 0; s == CDVR_OK && c < sizeof k2_candidates / sizeof *k2_candidates; c++) {
        s = level2(e, k2_candidates[c], err);
        if (s != CDVR_OK || e->n2 == last_n2) /* the 1-per-8-blocks cap: no larger size */
            break;
        last_n2 = e->n2;
        s = compact_size(e, dims, &bytes, err);
        if (s == CDVR_OK && bytes < best) {
            best = bytes;
            best_n2 = e->n2;
            best_lbg = e->lbg_iterations[1];
            memcpy(best_i2, e->i2, e->nnz * sizeof *best_i2);
            memcpy(best_cb2, e->cb2, sizeof *best_cb2 * 64 * e->n2);
        }
    }
    if (s == CDVR_OK) {
        const uint64_t d64[3] = {e->X, e->Y, e->Z};
        e->n2 = best_n2;
        e->lbg_iterations[1] = best_lbg;
        memcpy(e->i2, best_i2, e->nnz * sizeof *best_i2);
        memcpy(e->cb2, best_cb2, sizeof *best_cb2 * 64 * best_n2);
        hvq_layout_get(d64, e->n1, e->n2, &e->L);
        s = choose_residual(e, 1, err);
    }
    free(best_i2);
    free(best_cb2);
    return s;
}

cdvr_status cdvr_hvq_encode_compact(const cdvr_hvq_params *p, const cdvr_hvq_codebooks *shared,
                                    const size_t dims[3], const uint8_t *frame, unsigned threads,
                                    uint8_t *out, size_t out_cap, size_t *out_bytes,
                                    cdvr_hvq_stats *stats, cdvr_error *err)
{
    hvq_enc e;
    hvq_sections sec;
    memset(&sec, 0, sizeof sec);
    cdvr_status s = encode_common(&e, p, shared, 1, dims, frame, threads, out, out_bytes, err);
    if (s == CDVR_OK && !p->k2 && !shared)
        s = choose_k2(&e, dims, err);
    if (s == CDVR_OK)
        s = compact_sections(&e, &sec, err);
    if (s == CDVR_OK)
        s = hvq_compact_write(&sec, dims, e.n1, e.n2, e.R, shared ? shared->id : 0,
                              out, out_cap, out_bytes, stats, err);
    if (s == CDVR_OK && stats) {
        stats->lbg_iterations[0] = e.lbg_iterations[0];
        stats->lbg_iterations[1] = e.lbg_iterations[1];
    }
    hvq_sections_free(&sec);
    enc_free(&e);
    return s;
}

/* ---- shared codebooks ------------------------------------------------------------------------ */

/* Appends at most `keep` (0: all) of n vectors of d values, evenly spaced (j*n/keep). */
static int append_sample(int16_t **dst, size_t *have, const int16_t *src, size_t n, unsigned d,
                         size_t keep)
{
    size_t m = keep && n > keep ? keep : n;
    int16_t *p = realloc(*dst, sizeof *p * d * (*have + m + 1));
    if (!p)
        return 0;
    *dst = p;
    for (size_t j = 0; j < m; j++)
        memcpy(p + (*have + j) * d, src + (size_t)((uint64_t)j * n / m) * d, sizeof *p * d);
    *have += m;
    return 1;
}

cdvr_status cdvr_hvq_train_shared(const cdvr_hvq_params *p, const size_t dims[3],
                                  const uint8_t *const *frames, size_t nframes, unsigned threads,
                                  uint8_t **blob, size_t *bytes, cdvr_error *err)
{
    *blob = NULL;
    *bytes = 0;
    if (p->k2 == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: shared codebooks with k2 = auto (give k2)");
    if (nframes == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: training shared codebooks on no frame");
    int16_t *l1 = NULL, *l2 = NULL;
    size_t n1v = 0, n2v = 0;
    size_t keep = p->train ? (p->train + nframes - 1) / nframes : 0;
    cdvr_status s = CDVR_OK;
    for (size_t f = 0; s == CDVR_OK && f < nframes; f++) {
        hvq_enc e;
        memset(&e, 0, sizeof e);
        e.p = p;
        e.frame = frames[f];
        e.SX = dims[0];
        e.SY = dims[1];
        e.SZ = dims[2];
        e.OX = hvq2_skip(dims[0]); /* the grid an unbricked compact chunk of dims has */
        e.OY = hvq2_skip(dims[1]);
        e.OZ = hvq2_skip(dims[2]);
        e.X = dims[0] - e.OX;
        e.Y = dims[1] - e.OY;
        e.Z = dims[2] - e.OZ;
        e.threads = threads ? threads : hvq_threads_auto();
        const uint64_t d64[3] = {e.X, e.Y, e.Z};
        hvq_layout_get(d64, 0, 0, &e.L);
        s = classify(&e, err);
        if (s == CDVR_OK && (!append_sample(&l1, &n1v, e.l1, e.nnz, 8, keep) ||
                             !append_sample(&l2, &n2v, e.l2, e.nnz, 64, keep)))
            s = cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for training vectors");
        enc_free(&e);
    }
    hvq_enc t; /* the pooled vectors, trained as one frame's */
    memset(&t, 0, sizeof t);
    t.p = p;
    t.threads = threads ? threads : hvq_threads_auto();
    t.l1 = l1;
    t.l2 = l2;
    t.nnz = n1v;
    t.i1 = malloc((n1v ? n1v : 1) * sizeof *t.i1);
    t.i2 = malloc((n1v ? n1v : 1) * sizeof *t.i2);
    if (s == CDVR_OK && (!t.i1 || !t.i2))
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for training vectors");
    if (s == CDVR_OK)
        s = quantise(&t, err);
    if (s == CDVR_OK)
        s = hvq_shared_write(t.cb1, t.n1, t.cb2, t.n2, blob, bytes, err);
    enc_free(&t); /* frees l1, l2 */
    return s;
}
