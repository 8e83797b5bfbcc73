/* core/store/levels.c - multi-resolution stores (store.h, DESIGN.md section 15): the level rule
 * and filter, the encode driver, the level directory and the reader of the levels.
 *
 * File layout of a store with N >= 2 levels (format version 2; header fields 236 and 240,
 * store.c). Level 0 is the store as ever (header, tables, chunks), followed by levels 1 ..
 * N-1, each a complete store image (its own header, tables and chunks, offsets relative to its
 * own first byte), then the level directory, the last bytes of the file:
 *     u32    nvariants (the same in every level)
 *     per level l = 1 .. N-1:
 *       u64  offset of the level's store image (from the file's first byte)
 *       u64  bytes of the image
 *       per variant: f64 PSNR, f64 max error against level 0 (store.h)
 *     u32    CRC-32C of the directory bytes before it
 * The images lie after every extent of level 0, in level order, without overlap, before the
 * directory. Readers older than levels refuse such a file (reserved header bits set).
 */
#include "store_format.h"

#include "cdvr/atomicfile.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- geometry and filter ---------------------------------------------------------------- */

void cdvr_level_dims(const size_t dims[3], size_t level, size_t out[3])
{
    for (int a = 0; a < 3; a++) {
        size_t n = dims[a];
        for (size_t l = 0; l < level; l++)
            n = n > 1 ? n / 2 + 1 : 1; /* ceil((n - 1) / 2) + 1 */
        out[a] = n;
    }
}

static size_t clampi(long i, size_t n)
{
    return i < 0 ? 0 : (size_t)i >= n ? n - 1 : (size_t)i;
}

/* One level down: the (1 2 1)/4 tent per axis at voxel 2i (store.h), exact in integers. acc
 * holds dout[0] * dout[1] u32; ix holds 3 * dout[0] indices. */
static void downsample(const uint8_t *in, const size_t din[3], uint8_t *out,
                       const size_t dout[3], uint32_t *acc, size_t *ix)
{
    size_t plane = dout[0] * dout[1];
    for (size_t i = 0; i < dout[0]; i++)
        for (int d = 0; d < 3; d++)
            ix[3 * i + d] = clampi(2 * (long)i + d - 1, din[0]);
    for (size_t k = 0; k < dout[2]; k++) {
        memset(acc, 0, plane * sizeof *acc);
        for (int dz = 0; dz < 3; dz++) {
            size_t z = clampi(2 * (long)k + dz - 1, din[2]);
            for (size_t j = 0; j < dout[1]; j++) {
                uint32_t *a = acc + j * dout[0];
                for (int dy = 0; dy < 3; dy++) {
                    size_t y = clampi(2 * (long)j + dy - 1, din[1]);
                    const uint8_t *row = in + (z * din[1] + y) * din[0];
                    uint32_t w = (dz == 1 ? 2u : 1u) * (dy == 1 ? 2u : 1u);
                    for (size_t i = 0; i < dout[0]; i++) {
                        const size_t *x = ix + 3 * i;
                        a[i] += w * ((uint32_t)row[x[0]] + 2u * row[x[1]] + row[x[2]]);
                    }
                }
            }
        }
        uint8_t *o = out + k * plane;
        for (size_t p = 0; p < plane; p++)
            o[p] = (uint8_t)((acc[p] + 32u) >> 6);
    }
}

/* ---- a level as a frame source ---------------------------------------------------------- */

typedef struct level_source {
    const cdvr_encode_source *src;
    size_t level;
    size_t dims[CDVR_STORE_MAX_LEVELS][3];
    uint8_t *frame0, *tmp[2]; /* level 0 frame; two buffers for levels in between */
    uint32_t *acc;
    size_t *ix;
} level_source;

static size_t voxels_of(const size_t d[3])
{
    return d[0] * d[1] * d[2];
}

static void level_source_free(level_source *ls)
{
    free(ls->frame0);
    free(ls->tmp[0]);
    free(ls->tmp[1]);
    free(ls->acc);
    free(ls->ix);
}

static cdvr_status level_source_init(level_source *ls, const cdvr_encode_source *src,
                                     size_t level, cdvr_error *err)
{
    memset(ls, 0, sizeof *ls);
    ls->src = src;
    ls->level = level;
    for (size_t l = 0; l <= level; l++)
        cdvr_level_dims(src->dims, l, ls->dims[l]);
    size_t v1 = level ? voxels_of(ls->dims[1]) : 1;
    ls->frame0 = malloc(voxels_of(src->dims));
    ls->tmp[0] = malloc(v1);
    ls->tmp[1] = malloc(v1);
    ls->acc = malloc(v1 / (level ? ls->dims[1][2] : 1) * sizeof *ls->acc);
    ls->ix = malloc(3 * (level ? ls->dims[1][0] : 1) * sizeof *ls->ix);
    if (!ls->frame0 || !ls->tmp[0] || !ls->tmp[1] || !ls->acc || !ls->ix) {
        level_source_free(ls);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "levels: no memory for the frames of level %zu",
                              level);
    }
    return CDVR_OK;
}

/* Level `level` of timestep t into out (voxels of dims[level]); frame0 keeps level 0. */
static cdvr_status level_frame(void *ud, size_t t, uint8_t *out, cdvr_error *err)
{
    level_source *ls = ud;
    const uint8_t *cur = ls->frame0;
    cdvr_status s = ls->src->frame(ls->src->frame_ud, t, ls->frame0, err);
    for (size_t l = 1; s == CDVR_OK && l <= ls->level; l++) {
        uint8_t *dst = l == ls->level ? out : ls->tmp[l & 1];
        downsample(cur, ls->dims[l - 1], dst, ls->dims[l], ls->acc, ls->ix);
        cur = dst;
    }
    return s;
}

/* ---- error against level 0 -------------------------------------------------------------- */

/* Adds the squared error and max error of the level-`level` frame c (dims cd), upsampled
 * trilinearly (level-0 voxel x at x / 2^level, in float), against the level-0 frame f0. */
static void level_error(const uint8_t *f0, const size_t d0[3], const uint8_t *c,
                        const size_t cd[3], size_t level, double *sse, double *maxerr)
{
    float scale = 1.0f / (float)(1u << level);
    for (size_t z = 0; z < d0[2]; z++) {
        float gz = (float)z * scale;
        size_t z0 = (size_t)gz, z1 = z0 + 1 < cd[2] ? z0 + 1 : z0;
        float fz = gz - (float)z0;
        for (size_t y = 0; y < d0[1]; y++) {
            float gy = (float)y * scale;
            size_t y0 = (size_t)gy, y1 = y0 + 1 < cd[1] ? y0 + 1 : y0;
            float fy = gy - (float)y0;
            const uint8_t *r00 = c + (z0 * cd[1] + y0) * cd[0], *r01 = c + (z0 * cd[1] + y1) * cd[0];
            const uint8_t *r10 = c + (z1 * cd[1] + y0) * cd[0], *r11 = c + (z1 * cd[1] + y1) * cd[0];
            const uint8_t *ref = f0 + (z * d0[1] + y) * d0[0];
            double row_sse = 0;
            for (size_t x = 0; x < d0[0]; x++) {
                float gx = (float)x * scale;
                size_t x0 = (size_t)gx, x1 = x0 + 1 < cd[0] ? x0 + 1 : x0;
                float fx = gx - (float)x0;
                float a = r00[x0] + fx * ((float)r00[x1] - r00[x0]);
                float b = r01[x0] + fx * ((float)r01[x1] - r01[x0]);
                float e = r10[x0] + fx * ((float)r10[x1] - r10[x0]);
                float g = r11[x0] + fx * ((float)r11[x1] - r11[x0]);
                float ab = a + fy * (b - a), eg = e + fy * (g - e);
                float v = ab + fz * (eg - ab);
                double diff = (double)v - ref[x];
                row_sse += diff * diff;
                if (fabs(diff) > *maxerr)
                    *maxerr = fabs(diff);
            }
            *sse += row_sse;
        }
    }
}

static double psnr_of(double sse, double n)
{
    return sse > 0 ? 10.0 * log10(255.0 * 255.0 * n / sse) : INFINITY;
}

/* One pass over the source: every level's decoded frames of every variant against level 0. */
static cdvr_status measure_levels(const cdvr_encode_source *src, cdvr_store *const *lv,
                                  size_t nlevels, size_t nvariants, double *psnr,
                                  double *maxerr, cdvr_error *err)
{
    size_t n = nlevels * nvariants;
    double *sse = calloc(n, sizeof *sse);
    uint8_t *f0 = malloc(voxels_of(src->dims));
    cdvr_status s = !sse || !f0 ? cdvr_error_set(err, CDVR_ERR_NOMEM, "levels: no memory") : CDVR_OK;
    for (size_t i = 0; i < n; i++)
        maxerr[i] = 0;
    for (size_t t = 0; s == CDVR_OK && t < src->timesteps; t++) {
        s = src->frame(src->frame_ud, t, f0, err);
        for (size_t l = 1; s == CDVR_OK && l < nlevels; l++)
            for (size_t v = 0; s == CDVR_OK && v < nvariants; v++) {
                cdvr_volume *dec = NULL;
                s = cdvr_store_decode(lv[l], v, t, &dec, err);
                if (s == CDVR_OK)
                    level_error(f0, src->dims, dec->data, dec->dims, l, &sse[l * nvariants + v],
                                &maxerr[l * nvariants + v]);
                cdvr_volume_free(dec);
            }
    }
    double total = (double)voxels_of(src->dims) * (double)src->timesteps;
    for (size_t i = 0; i < n; i++)
        psnr[i] = psnr_of(sse[i], total);
    free(sse);
    free(f0);
    return s;
}

/* ---- the encode driver ------------------------------------------------------------------ */

typedef struct level_build {
    size_t nlevels, nvariants;
    char (*tmp)[4096];           /* per level: its temporary store file */
    cdvr_store **stores;         /* per level: the temporary store, opened */
    cdvr_variant_spec *specs;    /* scratch for one level's variants */
    double *psnr, *maxerr;       /* [level][variant] */
} level_build;

static void build_free(level_build *b)
{
    for (size_t l = 0; b->stores && l < b->nlevels; l++)
        cdvr_store_close(b->stores[l]);
    for (size_t l = 0; b->tmp && l < b->nlevels; l++)
        if (b->tmp[l][0])
            unlink(b->tmp[l]);
    free(b->tmp);
    free(b->stores);
    free(b->specs);
    free(b->psnr);
    free(b->maxerr);
}

/* Encodes level l into b->tmp[l] and opens it. */
static cdvr_status encode_level(level_build *b, const cdvr_encode_source *src,
                                const cdvr_encode_opts *opts, const char *path, size_t l,
                                cdvr_error *err)
{
    cdvr_encode_opts o = *opts;
    o.levels = 0;
    o.level_variants = NULL;
    snprintf(b->tmp[l], sizeof b->tmp[l], "%s.level%zu.%ld.tmp", path, l, (long)getpid());
    if (l == 0) {
        cdvr_status s = cdvr_store_encode_source(src, &o, b->tmp[0], err);
        return s == CDVR_OK ? cdvr_store_open(b->tmp[0], &b->stores[0], err) : s;
    }
    level_source ls;
    cdvr_status s = level_source_init(&ls, src, l, err);
    if (s != CDVR_OK)
        return s;
    cdvr_encode_source ls_src = *src;
    memcpy(ls_src.dims, ls.dims[l], sizeof ls_src.dims);
    for (int a = 0; a < 3; a++)
        ls_src.spacing[a] = src->spacing[a] * (double)(1u << l);
    ls_src.frame = level_frame;
    ls_src.frame_ud = &ls;
    {
        const cdvr_variant_spec *from = opts->level_variants && opts->level_variants[l - 1]
                                            ? opts->level_variants[l - 1] : opts->variants;
        memcpy(b->specs, from, opts->nvariants * sizeof *b->specs);
        for (size_t v = 0; v < opts->nvariants; v++) /* level 0's names */
            memcpy(b->specs[v].name, cdvr_store_variant(b->stores[0], v)->name, CDVR_NAME_MAX);
        o.variants = b->specs;
        o.schedule = NULL; /* schedules and progress follow level 0 */
        o.progress = NULL;
        for (int a = 0; a < 3; a++) {
            size_t cells = ls.dims[l][a] > 1 ? ls.dims[l][a] - 1 : 1;
            o.bricks[a] = opts->bricks[a] == 0 ? 1 : opts->bricks[a] < cells ? opts->bricks[a] : cells;
        }
    }
    s = cdvr_store_encode_source(&ls_src, &o, b->tmp[l], err);
    level_source_free(&ls);
    if (s == CDVR_OK)
        s = cdvr_store_open(b->tmp[l], &b->stores[l], err);
    return s;
}

static cdvr_status copy_file_range_to(FILE *out, const char *from, uint64_t offset,
                                      uint64_t bytes, const char *path, cdvr_error *err)
{
    FILE *in = fopen(from, "rb");
    if (!in || fseeko(in, (off_t)offset, SEEK_SET) != 0) {
        if (in)
            fclose(in);
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot read back a level: %s", path,
                              strerror(errno));
    }
    char buf[1 << 16];
    cdvr_status s = CDVR_OK;
    while (bytes > 0 && s == CDVR_OK) {
        size_t n = bytes < sizeof buf ? (size_t)bytes : sizeof buf;
        if (fread(buf, 1, n, in) != n || fwrite(buf, 1, n, out) != n)
            s = cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot copy a level: %s", path,
                               strerror(errno));
        bytes -= n;
    }
    fclose(in);
    return s;
}

static void put_u32le(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void put_u64le(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void put_f64le(uint8_t *p, double d)
{
    uint64_t v;
    memcpy(&v, &d, sizeof v);
    put_u64le(p, v);
}

static size_t directory_bytes(size_t nlevels, size_t nvariants)
{
    return 4 + (nlevels - 1) * (16 + 16 * nvariants) + 4;
}

/* Writes level 0 (with the level fields set) + the images of levels 1.. + the directory. */
static cdvr_status assemble(level_build *b, const char *path, cdvr_error *err)
{
    cdvr_store *st0 = b->stores[0];
    uint64_t *offset = calloc(b->nlevels, sizeof *offset);
    size_t dbytes = directory_bytes(b->nlevels, b->nvariants);
    uint64_t meta = cdvr_store_meta_bytes(st0->info.nvariants, st0->nchunks_total);
    uint8_t *metabuf = malloc((size_t)meta + 4), *dir = calloc(1, dbytes);
    cdvr_status s = !offset || !metabuf || !dir
                        ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", path) : CDVR_OK;
    uint64_t end = st0->info.file_bytes;
    for (size_t l = 1; s == CDVR_OK && l < b->nlevels; l++) {
        offset[l] = end;
        end += b->stores[l]->info.file_bytes;
    }
    if (s == CDVR_OK) {
        uint8_t *p = dir;
        put_u32le(p, (uint32_t)b->nvariants);
        p += 4;
        for (size_t l = 1; l < b->nlevels; l++) {
            put_u64le(p, offset[l]);
            put_u64le(p + 8, b->stores[l]->info.file_bytes);
            p += 16;
            for (size_t v = 0; v < b->nvariants; v++, p += 16) {
                put_f64le(p, b->psnr[l * b->nvariants + v]);
                put_f64le(p + 8, b->maxerr[l * b->nvariants + v]);
            }
        }
        put_u32le(p, cdvr_crc32c(0, dir, dbytes - 4));
        st0->info.nlevels = b->nlevels;
        st0->levels_offset = end;
        st0->info.file_bytes = end + dbytes;
        cdvr_store_serialize_meta(st0, metabuf);
    }
    cdvr_atomic_file af;
    if (s == CDVR_OK)
        s = cdvr_atomic_open(&af, path, err);
    if (s == CDVR_OK) {
        int failed = fwrite(metabuf, 1, (size_t)meta + 4, af.f) != (size_t)meta + 4;
        cdvr_error cerr;
        cdvr_status c = CDVR_OK;
        if (!failed)
            c = copy_file_range_to(af.f, b->tmp[0], meta + 4, offset[1] - (meta + 4), path, &cerr);
        for (size_t l = 1; !failed && c == CDVR_OK && l < b->nlevels; l++)
            c = copy_file_range_to(af.f, b->tmp[l], 0, b->stores[l]->info.file_bytes, path, &cerr);
        failed |= c != CDVR_OK || fwrite(dir, 1, dbytes, af.f) != dbytes;
        s = cdvr_atomic_commit(&af, failed, err);
        if (c != CDVR_OK)
            s = cdvr_error_set(err, c, "%s", cerr.msg);
    }
    free(offset);
    free(metabuf);
    free(dir);
    return s;
}

cdvr_status cdvr_store_encode_levels(const cdvr_encode_source *src, const cdvr_encode_opts *opts,
                                     const char *path, cdvr_error *err)
{
    size_t n = opts->levels;
    if (n > CDVR_STORE_MAX_LEVELS || !path || !opts->variants || opts->nvariants == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: levels = %zu (1..%d) or no variants",
                              path ? path : "encode", n, CDVR_STORE_MAX_LEVELS);
    level_build b = {.nlevels = n, .nvariants = opts->nvariants};
    b.tmp = calloc(n, sizeof *b.tmp);
    b.stores = calloc(n, sizeof *b.stores);
    b.specs = calloc(opts->nvariants, sizeof *b.specs);
    b.psnr = calloc(n * opts->nvariants, sizeof *b.psnr);
    b.maxerr = calloc(n * opts->nvariants, sizeof *b.maxerr);
    cdvr_status s = !b.tmp || !b.stores || !b.specs || !b.psnr || !b.maxerr
                        ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", path) : CDVR_OK;
    for (size_t l = 0; s == CDVR_OK && l < n; l++)
        s = encode_level(&b, src, opts, path, l, err);
    if (s == CDVR_OK)
        s = measure_levels(src, b.stores, n, opts->nvariants, b.psnr, b.maxerr, err);
    if (s == CDVR_OK)
        s = assemble(&b, path, err);
    build_free(&b);
    return s;
}

/* ---- the reader ------------------------------------------------------------------------- */

static uint32_t get_u32le(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get_u64le(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 0; i < 8; i++)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

static double get_f64le(const uint8_t *p)
{
    uint64_t v = get_u64le(p);
    double d;
    memcpy(&d, &v, sizeof d);
    return d;
}

/* End of level 0's extents: chunks and range tables. */
static uint64_t level0_end(const cdvr_store *st)
{
    uint64_t end = cdvr_store_meta_bytes(st->info.nvariants, st->nchunks_total) + 4;
    for (size_t c = 0; c < st->nchunks_total; c++) {
        const cdvr_chunk_info *ci = &st->chunks[c];
        if (ci->offset + ci->stored_bytes > end)
            end = ci->offset + ci->stored_bytes;
        if (ci->ranges_stored_bytes && ci->ranges_offset + ci->ranges_stored_bytes > end)
            end = ci->ranges_offset + ci->ranges_stored_bytes;
    }
    return end;
}

/* Level l as a store of its own: checks it agrees with level 0. */
static cdvr_status open_one(const cdvr_store *st, size_t l, uint64_t offset, uint64_t bytes,
                            cdvr_store **out, cdvr_error *err)
{
    char name[4200];
    snprintf(name, sizeof name, "%s (level %zu)", st->path, l);
    int fd = dup(st->fd);
    if (fd < 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: %s", name, strerror(errno));
    cdvr_status s = cdvr_store_open_at(name, fd, st->base + offset, bytes, out, err);
    if (s != CDVR_OK)
        return s;
    const cdvr_store_info *a = &st->info, *b = &(*out)->info;
    size_t dims[3];
    cdvr_level_dims(a->dims, l, dims);
    int ok = b->nlevels == 1 && b->timesteps == a->timesteps && b->nvariants == a->nvariants &&
             b->qlo == a->qlo && b->qhi == a->qhi && !memcmp(b->dims, dims, sizeof dims);
    for (size_t v = 0; ok && v < a->nvariants; v++)
        ok = strcmp(st->variants[v].name, (*out)->variants[v].name) == 0;
    if (!ok) {
        cdvr_store_close(*out);
        *out = NULL;
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: does not match level 0 (dims, "
                              "timesteps, window or variants)", name);
    }
    return CDVR_OK;
}

cdvr_status cdvr_store_open_levels(cdvr_store *st, uint32_t nlevels, uint64_t offset,
                                   cdvr_error *err)
{
    size_t nv = st->info.nvariants, dbytes = directory_bytes(nlevels, nv);
    if (offset + dbytes != st->info.file_bytes)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: level directory at %llu is not the "
                              "end of the file", st->path, (unsigned long long)offset);
    uint8_t *dir = malloc(dbytes);
    st->levels = calloc(nlevels, sizeof *st->levels);
    st->level_psnr = calloc((size_t)nlevels * nv, sizeof *st->level_psnr);
    st->level_maxerr = calloc((size_t)nlevels * nv, sizeof *st->level_maxerr);
    st->level_bytes = calloc(nlevels, sizeof *st->level_bytes);
    cdvr_status s = !dir || !st->levels || !st->level_psnr || !st->level_maxerr ||
                            !st->level_bytes
                        ? cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory", st->path)
                        : cdvr_store_read_bytes(st, dir, dbytes, offset, err);
    if (s == CDVR_OK && (cdvr_crc32c(0, dir, dbytes - 4) != get_u32le(dir + dbytes - 4) ||
                         get_u32le(dir) != nv))
        s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: level directory CRC-32C or variant count "
                           "mismatch", st->path);
    st->info.nlevels = nlevels;
    st->levels_offset = offset;
    for (size_t v = 0; v < nv; v++) {
        st->level_psnr[v] = st->variants[v].psnr;
        st->level_maxerr[v] = st->variants[v].maxerr;
    }
    uint64_t end = level0_end(st);
    st->level_bytes[0] = end;
    const uint8_t *p = dir + 4;
    for (size_t l = 1; s == CDVR_OK && l < nlevels; l++) {
        uint64_t at = get_u64le(p), bytes = get_u64le(p + 8);
        p += 16;
        if (at < end || bytes > offset - at)
            s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "%s: level %zu at %llu (%llu bytes) "
                               "overlaps", st->path, l, (unsigned long long)at,
                               (unsigned long long)bytes);
        for (size_t v = 0; v < nv; v++, p += 16) {
            st->level_psnr[l * nv + v] = get_f64le(p);
            st->level_maxerr[l * nv + v] = get_f64le(p + 8);
        }
        if (s == CDVR_OK)
            s = open_one(st, l, at, bytes, &st->levels[l], err);
        st->level_bytes[l] = bytes;
        end = at + bytes;
    }
    free(dir);
    return s;
}

void cdvr_store_close_levels(cdvr_store *st)
{
    for (size_t l = 1; st->levels && l < st->info.nlevels; l++)
        cdvr_store_close(st->levels[l]);
    free(st->levels);
    free(st->level_psnr);
    free(st->level_maxerr);
    free(st->level_bytes);
    st->levels = NULL;
}

const cdvr_store *cdvr_store_level(const cdvr_store *st, size_t level)
{
    if (level == 0)
        return st;
    return st->levels && level < st->info.nlevels ? st->levels[level] : NULL;
}

void cdvr_store_level_error(const cdvr_store *st, size_t level, size_t v, double *psnr,
                            double *maxerr)
{
    size_t nv = st->info.nvariants;
    *psnr = NAN;
    *maxerr = NAN;
    if (v >= nv || level >= st->info.nlevels)
        return;
    if (!st->levels) {
        *psnr = st->variants[v].psnr;
        *maxerr = st->variants[v].maxerr;
        return;
    }
    *psnr = st->level_psnr[level * nv + v];
    *maxerr = st->level_maxerr[level * nv + v];
}

cdvr_status cdvr_store_open_level(const cdvr_store *st, size_t level, cdvr_store **out,
                                  cdvr_error *err)
{
    *out = NULL;
    if (level >= st->info.nlevels)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no level %zu (levels 0..%zu)", st->path,
                              level, st->info.nlevels - 1);
    if (level == 0) {
        int fd = dup(st->fd);
        struct stat sb;
        if (fd < 0 || fstat(fd, &sb) != 0) {
            if (fd >= 0)
                close(fd);
            return cdvr_error_set(err, CDVR_ERR_IO, "%s: %s", st->path, strerror(errno));
        }
        return cdvr_store_open_at(st->path, fd, st->base, st->info.file_bytes, out, err);
    }
    const cdvr_store *lv = st->levels[level];
    return open_one(st, level, lv->base - st->base, lv->info.file_bytes, out, err);
}
