/* core/codec/hvq/hvq_codec.c - the hvq codec table (cdvr/codec.h) and its parameters; the
 * format is documented in cdvr/hvq.h. */
#include "cdvr/codec.h"
#include "cdvr/hvq.h"
#include "codec/hvq/hvq_internal.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { OFF_GRAD = 0, OFF_EPS = 8, OFF_RESIDUAL = 16, OFF_K1 = 20, OFF_K2 = 24, OFF_TRAIN = 28,
       USED_BYTES = 32, OFF_PSNR = 36, OFF_SHARED = 32, OFF_SHARED_ID = 40 /* hvqc only */ };
#define PSNR_CENTI_MAX 20000u /* 200 dB */

static const cdvr_codec_param_doc hvq_params[] = {
    {"grad", "8", "zero-block threshold on a block's average gradient (seed eq. 11-12), 0..765"},
    {"residual", "10", "voxels decoded more than this far off are stored exactly, 0..255"},
    {"k1", "4096", "level-1 codebook entries (8-d) at most, 1..4096 (and 1 per 8 blocks)"},
    {"k2", "1024", "level-2 codebook entries (64-d) at most, 1..4096 (and 1 per 8 blocks)"},
    {"eps", "0.01", "LBG stops when the relative distortion change is below this, (0, 1)"},
    {"train", "262144", "training vectors per codebook at most (0: all)"},
    {"psnr", "0", "PSNR target in dB (0.01 steps, 0..200; 0: none): the residual threshold is "
                  "the largest <= residual that keeps the chunk's PSNR >= psnr"},
    {NULL, NULL, NULL}};

void cdvr_hvq_params_default(cdvr_hvq_params *p)
{
    p->grad = 8;
    p->eps = 0.01;
    p->residual = 10;
    p->k1 = 4096;
    p->k2 = 1024;
    p->train = 262144;
    p->psnr = 0;
}

static uint32_t psnr_centi(double db)
{
    if (!(db > 0))
        return 0;
    return db >= PSNR_CENTI_MAX / 100.0 ? PSNR_CENTI_MAX : (uint32_t)lround(db * 100.0);
}

double cdvr_hvq_params_set_psnr(cdvr_hvq_params *p, double db)
{
    p->psnr = psnr_centi(db) / 100.0;
    return p->psnr;
}

void cdvr_hvq_params_to_blob(const cdvr_hvq_params *p, cdvr_codec_params *blob)
{
    memset(blob, 0, sizeof *blob);
    cdvr_params_set_f64(blob, OFF_GRAD, p->grad);
    cdvr_params_set_f64(blob, OFF_EPS, p->eps);
    cdvr_params_set_u32(blob, OFF_RESIDUAL, p->residual);
    cdvr_params_set_u32(blob, OFF_K1, p->k1);
    cdvr_params_set_u32(blob, OFF_K2, p->k2);
    cdvr_params_set_u32(blob, OFF_TRAIN, p->train);
    cdvr_params_set_u32(blob, OFF_PSNR, psnr_centi(p->psnr));
}

void cdvr_hvq_params_from_blob(const cdvr_codec_params *blob, cdvr_hvq_params *p)
{
    p->grad = cdvr_params_get_f64(blob, OFF_GRAD);
    p->eps = cdvr_params_get_f64(blob, OFF_EPS);
    p->residual = cdvr_params_get_u32(blob, OFF_RESIDUAL);
    p->k1 = cdvr_params_get_u32(blob, OFF_K1);
    p->k2 = cdvr_params_get_u32(blob, OFF_K2);
    p->train = cdvr_params_get_u32(blob, OFF_TRAIN);
    p->psnr = cdvr_params_get_u32(blob, OFF_PSNR) / 100.0;
}

cdvr_status cdvr_hvq_params_check(const cdvr_hvq_params *p, cdvr_error *err)
{
    if (!(p->grad >= 0 && p->grad <= 765))
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: grad = %g, must be 0..765", p->grad);
    if (!(p->eps > 0 && p->eps < 1))
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: eps = %g, must be in (0, 1)",
                              p->eps);
    if (p->residual > 255)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: residual = %u, must be 0..255",
                              p->residual);
    if (p->k1 < 1 || p->k1 > CDVR_HVQ_K_MAX || p->k2 > CDVR_HVQ_K_MAX)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: k1 = %u, k2 = %u, each must be "
                              "1..%u (k2 0: auto)", p->k1, p->k2, CDVR_HVQ_K_MAX);
    if (!(p->psnr >= 0 && p->psnr <= PSNR_CENTI_MAX / 100.0))
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: psnr = %g, must be 0..200 dB",
                              p->psnr);
    return CDVR_OK;
}

static void hvq_default(cdvr_codec_params *blob)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_default(&p);
    cdvr_hvq_params_to_blob(&p, blob);
}

static int parse_u32(const char *value, unsigned long max, uint32_t *out)
{
    char *end;
    errno = 0;
    if (!*value || *value == '-' || *value == '+')
        return 0;
    unsigned long long v = strtoull(value, &end, 10);
    if (errno || *end || v > max)
        return 0;
    *out = (uint32_t)v;
    return 1;
}

static int parse_f64(const char *value, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(value, &end);
    if (!*value || errno || *end || !isfinite(v))
        return 0;
    *out = v;
    return 1;
}

static cdvr_status hvq_set(cdvr_codec_params *blob, const char *key, const char *value,
                           cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    int ok;
    const char *want;
    if (strcmp(key, "grad") == 0) {
        ok = parse_f64(value, &p.grad) && p.grad >= 0 && p.grad <= 765;
        want = "a number 0..765";
    } else if (strcmp(key, "eps") == 0) {
        ok = parse_f64(value, &p.eps) && p.eps > 0 && p.eps < 1;
        want = "a number in (0, 1)";
    } else if (strcmp(key, "residual") == 0) {
        ok = parse_u32(value, 255, &p.residual);
        want = "an integer 0..255";
    } else if (strcmp(key, "k2") == 0 && strcmp(value, "auto") == 0) {
        p.k2 = 0; /* the compact form chooses (hvqc_check; the hashed form refuses it) */
        ok = 1;
        want = "";
    } else if (strcmp(key, "k1") == 0 || strcmp(key, "k2") == 0) {
        uint32_t *k = key[1] == '1' ? &p.k1 : &p.k2;
        ok = parse_u32(value, CDVR_HVQ_K_MAX, k) && *k >= 1;
        want = "an integer 1..4096";
    } else if (strcmp(key, "train") == 0) {
        ok = parse_u32(value, UINT32_MAX, &p.train);
        want = "an integer 0..4294967295 (0: all vectors)";
    } else if (strcmp(key, "psnr") == 0) {
        ok = parse_f64(value, &p.psnr) && p.psnr >= 0 && p.psnr <= PSNR_CENTI_MAX / 100.0;
        cdvr_hvq_params_set_psnr(&p, p.psnr);
        want = "a number of dB 0..200 (0: none)";
    } else {
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: unknown parameter '%s' "
                              "(parameters: grad, residual, k1, k2, eps, train, psnr)", key);
    }
    if (!ok)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: %s = '%s', must be %s", key, value,
                              want);
    cdvr_hvq_params_to_blob(&p, blob);
    return CDVR_OK;
}

static int hvq_get(const cdvr_codec_params *blob, const char *key, char *out, size_t n)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    if (strcmp(key, "grad") == 0)
        snprintf(out, n, "%.17g", p.grad);
    else if (strcmp(key, "eps") == 0)
        snprintf(out, n, "%.17g", p.eps);
    else if (strcmp(key, "residual") == 0)
        snprintf(out, n, "%u", p.residual);
    else if (strcmp(key, "k1") == 0)
        snprintf(out, n, "%u", p.k1);
    else if (strcmp(key, "k2") == 0 && p.k2 == 0)
        snprintf(out, n, "auto");
    else if (strcmp(key, "k2") == 0)
        snprintf(out, n, "%u", p.k2);
    else if (strcmp(key, "train") == 0)
        snprintf(out, n, "%u", p.train);
    else if (strcmp(key, "psnr") == 0)
        snprintf(out, n, "%.2f", p.psnr);
    else
        return -1;
    return 0;
}

static cdvr_status hvq_check(const cdvr_codec_params *blob, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    cdvr_status s = cdvr_hvq_params_check(&p, err);
    if (s == CDVR_OK && p.k2 == 0)
        s = cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: k2 = auto is for the compact form "
                           "(codec hvqc)");
    if (s == CDVR_OK && cdvr_params_get_u32(blob, OFF_PSNR) > PSNR_CENTI_MAX)
        s = cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: psnr = %u/100 dB, above 200 dB",
                           cdvr_params_get_u32(blob, OFF_PSNR));
    for (size_t i = USED_BYTES; s == CDVR_OK && i < CDVR_CODEC_PARAMS_MAX; i++)
        if (blob->bytes[i] && (i < OFF_PSNR || i >= OFF_PSNR + 4))
            s = cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: unused parameter byte %zu is %u",
                               i, blob->bytes[i]);
    return s;
}

/* "hvq" for the defaults; otherwise the parameters that differ: hvq_g32_r5_k128x512_e0.01_t0
 * (the compact form: "hvqc..."). */
static void name_with(const char *prefix, const cdvr_codec_params *blob, char *name, size_t n)
{
    cdvr_hvq_params p, d;
    cdvr_hvq_params_from_blob(blob, &p);
    cdvr_hvq_params_default(&d);
    char buf[96];
    int len = snprintf(buf, sizeof buf, "%s", prefix);
    if (p.grad != d.grad)
        len += snprintf(buf + len, sizeof buf - (size_t)len, "_g%.6g", p.grad);
    if (p.residual != d.residual)
        len += snprintf(buf + len, sizeof buf - (size_t)len, "_r%u", p.residual);
    if (p.k1 != d.k1 || p.k2 != d.k2) {
        char k2[16];
        snprintf(k2, sizeof k2, p.k2 ? "%u" : "auto", p.k2);
        len += snprintf(buf + len, sizeof buf - (size_t)len, "_k%ux%s", p.k1, k2);
    }
    if (p.eps != d.eps)
        len += snprintf(buf + len, sizeof buf - (size_t)len, "_e%.3g", p.eps);
    if (p.train != d.train)
        len += snprintf(buf + len, sizeof buf - (size_t)len, "_t%u", p.train);
    if (p.psnr != d.psnr)
        snprintf(buf + len, sizeof buf - (size_t)len, "_p%.5g", p.psnr);
    snprintf(name, n, "%s", buf);
}

static void hvq_name(const cdvr_codec_params *blob, char *name, size_t n)
{
    name_with("hvq", blob, name, n);
}

static cdvr_status hvq_shape(const cdvr_codec_params *blob, const size_t dims[3],
                             cdvr_codec_shape *out, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    size_t bound;
    cdvr_status s = cdvr_hvq_bound(&p, dims, &bound, err);
    if (s != CDVR_OK)
        return s;
    out->timesteps = 1;
    out->payload_bytes = 0; /* data dependent */
    out->bound_bytes = bound;
    return CDVR_OK;
}

static cdvr_status hvq_encode(const cdvr_codec_params *blob, const size_t dims[3],
                              const uint8_t *const *frames, size_t count, uint8_t *out,
                              size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    if (count != 1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: %zu frames for one chunk (1 "
                              "expected)", count);
    return cdvr_hvq_encode(&p, dims, frames[0], 0, out, out_cap, out_bytes, NULL, err);
}

static cdvr_status hvq_decode(const cdvr_codec_params *blob, const size_t dims[3],
                              const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                              size_t count, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    if (count != 1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvq: %zu frames asked of a chunk of 1",
                              count);
    return cdvr_hvq_decode(&p, dims, in, in_bytes, frames[0], err);
}

static cdvr_status hvq_decode_cells(const cdvr_codec_params *blob, const size_t dims[3],
                                    const uint8_t *in, size_t in_bytes, uint8_t *frame,
                                    unsigned layout, const uint8_t *need, unsigned cell_log2,
                                    cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    return hvq_decode_cells_threads(&p, dims, in, in_bytes, frame, layout, need, cell_log2,
                                    hvq_threads_auto(), err);
}

static cdvr_status hvq_describe(const cdvr_codec_params *blob, const size_t dims[3],
                                const uint8_t *payload, size_t bytes,
                                void (*emit)(void *ud, const char *key, double value), void *ud,
                                cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    cdvr_hvq_stats st;
    cdvr_status s = cdvr_hvq_check(&p, dims, payload, bytes, &st, err);
    if (s != CDVR_OK)
        return s;
    emit(ud, "header", (double)st.header);
    emit(ud, "means", (double)st.means);
    emit(ud, "codebook1", (double)st.codebook1);
    emit(ud, "codebook2", (double)st.codebook2);
    emit(ud, "index_hash", (double)st.index_hash);
    emit(ud, "residual_hash", (double)st.residual_hash);
    emit(ud, "blocks", (double)st.blocks);
    emit(ud, "zero_blocks", (double)st.zero_blocks);
    emit(ud, "residual_voxels", (double)st.residual_voxels);
    return CDVR_OK;
}

/* The check before the device (codec.h): the whole-payload check the C decoder runs. */
static cdvr_status hvq_payload_check(const cdvr_codec_params *blob, const size_t dims[3],
                                     const uint8_t *payload, size_t bytes, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    return cdvr_hvq_check(&p, dims, payload, bytes, NULL, err);
}

const cdvr_codec cdvr_codec_hvq = {
    .name = "hvq",
    .id = CDVR_CODEC_ID_HVQ,
    .description = "FCHVQ + perfect spatial hashing (seed 004): 4x4x4 blocks, zero blocks by "
                   "gradient, two-level VQ, sparse residual; rendered in the compressed domain",
    .params = hvq_params,
    .params_default = hvq_default,
    .params_set = hvq_set,
    .params_get = hvq_get,
    .params_check = hvq_check,
    .variant_name = hvq_name,
    .shape = hvq_shape,
    .encode = hvq_encode,
    .decode = hvq_decode,
    .describe = hvq_describe,
    .cl_mode = CDVR_CODEC_CL_FETCH,
    .cl_file = "codec/hvq_fetch.cl",
    .cl_function = "hvq_fetch",
    .check = hvq_payload_check,
    .decode_cells = hvq_decode_cells,
    .decodes_in_parallel = 1,
};

/* ---- "hvqc": the compact form (cdvr/hvq.h), decoded on the CPU ------------------------------
 * Parameters: hvq's, and at byte 32 u32 shared (0 or 1: train one codebook set per variant,
 * cdvr/codec.h "data shared by a variant's chunks"), 36..39 psnr as in hvq, at byte 40 u64 the shared
 * codebooks' id (set by the store encoder after training; 0 when shared is 0 or untrained). */

static const cdvr_codec_param_doc hvqc_params[] = {
    {"grad", "8", "zero-block threshold on a block's average gradient (seed eq. 11-12), 0..765"},
    {"residual", "10", "every voxel decodes within this of the original, 0..255"},
    {"k1", "4096", "level-1 codebook entries (8-d) at most, 1..4096 (and 1 per 8 blocks)"},
    {"k2", "1024", "level-2 codebook entries (64-d) at most, 1..4096 (and 1 per 8 blocks); "
                   "auto: of 256, 512, 1024, 2048 the one giving the smallest payload"},
    {"eps", "0.01", "LBG stops when the relative distortion change is below this, (0, 1)"},
    {"train", "262144", "training vectors per codebook at most (0: all)"},
    {"psnr", "0", "PSNR target in dB (0.01 steps, 0..200; 0: none): the residual threshold is "
                  "the largest <= residual that keeps the chunk's PSNR >= psnr"},
    {"shared", "0", "1: one codebook set per variant, trained on sample timesteps (stores)"},
    {NULL, NULL, NULL}};

static uint64_t shared_id_of(const cdvr_codec_params *blob)
{
    return (uint64_t)cdvr_params_get_u32(blob, OFF_SHARED_ID) |
           (uint64_t)cdvr_params_get_u32(blob, OFF_SHARED_ID + 4) << 32;
}

int cdvr_hvqc_wants_shared(const cdvr_codec_params *blob)
{
    return cdvr_params_get_u32(blob, OFF_SHARED) == 1;
}

static cdvr_status hvqc_set(cdvr_codec_params *blob, const char *key, const char *value,
                            cdvr_error *err)
{
    if (strcmp(key, "shared") != 0) { /* hvq_set rewrites the blob: keep bytes 32.. */
        cdvr_codec_params keep = *blob;
        cdvr_status s = hvq_set(blob, key, value, err);
        memcpy(blob->bytes + OFF_SHARED, keep.bytes + OFF_SHARED, 4);
        memcpy(blob->bytes + OFF_SHARED_ID, keep.bytes + OFF_SHARED_ID, 8);
        return s;
    }
    uint32_t v;
    if (!parse_u32(value, 1, &v))
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvqc: shared = '%s', must be 0 or 1",
                              value);
    cdvr_params_set_u32(blob, OFF_SHARED, v);
    cdvr_params_set_u32(blob, OFF_SHARED_ID, 0);
    cdvr_params_set_u32(blob, OFF_SHARED_ID + 4, 0);
    return CDVR_OK;
}

static int hvqc_get(const cdvr_codec_params *blob, const char *key, char *out, size_t n)
{
    if (strcmp(key, "shared") != 0)
        return hvq_get(blob, key, out, n);
    snprintf(out, n, "%u", cdvr_params_get_u32(blob, OFF_SHARED));
    return 0;
}

static cdvr_status hvqc_check(const cdvr_codec_params *blob, cdvr_error *err)
{
    cdvr_codec_params hvq_part = *blob;
    memset(hvq_part.bytes + OFF_SHARED, 0, 4);
    memset(hvq_part.bytes + OFF_SHARED_ID, 0, 8);
    int k2_auto = cdvr_params_get_u32(blob, OFF_K2) == 0;
    if (k2_auto) /* the compact form's own: hvq_check refuses it for the hashed form */
        cdvr_params_set_u32(&hvq_part, OFF_K2, 1);
    cdvr_status s = hvq_check(&hvq_part, err);
    uint32_t shared = cdvr_params_get_u32(blob, OFF_SHARED);
    if (s == CDVR_OK && k2_auto && shared)
        s = cdvr_error_set(err, CDVR_ERR_ARG, "codec hvqc: k2 = auto with shared = 1 (shared "
                           "codebooks have one size: give k2)");
    if (s == CDVR_OK && (shared > 1 || (shared == 0 && shared_id_of(blob) != 0)))
        s = cdvr_error_set(err, CDVR_ERR_ARG, "codec hvqc: shared = %u with id %016llx (0 or "
                           "1; an id only when 1)", shared,
                           (unsigned long long)shared_id_of(blob));
    return s;
}

static void hvqc_name(const cdvr_codec_params *blob, char *name, size_t n)
{
    char base[CDVR_VARIANT_NAME_MAX];
    name_with("hvqc", blob, base, sizeof base);
    snprintf(name, n, "%s%s", base, cdvr_hvqc_wants_shared(blob) ? "_s" : "");
}

/* The shared codebooks the parameters name (none: cb zeroed, *held 0). */
static cdvr_status open_shared(const cdvr_codec_params *blob, const cdvr_hvq_params *p,
                               cdvr_hvq_codebooks *cb, uint64_t *held, cdvr_error *err)
{
    memset(cb, 0, sizeof *cb);
    *held = 0;
    uint64_t id = shared_id_of(blob);
    if (id == 0)
        return CDVR_OK;
    const uint8_t *bytes;
    size_t n;
    cdvr_status s = cdvr_shared_borrow(id, &bytes, &n, err);
    if (s != CDVR_OK)
        return s;
    *held = id;
    return cdvr_hvq_shared_open(p, bytes, n, cb, err);
}

static void close_shared(cdvr_hvq_codebooks *cb, uint64_t held)
{
    cdvr_hvq_codebooks_free(cb);
    if (held)
        cdvr_shared_drop(held);
}

cdvr_status cdvr_hvqc_train_shared(cdvr_codec_params *blob, const size_t dims[3],
                                   const uint8_t *const *frames, size_t nframes, uint8_t **out,
                                   size_t *bytes, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    cdvr_status s = cdvr_hvq_train_shared(&p, dims, frames, nframes, 0, out, bytes, err);
    if (s == CDVR_OK) {
        uint64_t id = cdvr_shared_id(*out, *bytes);
        cdvr_params_set_u32(blob, OFF_SHARED_ID, (uint32_t)id);
        cdvr_params_set_u32(blob, OFF_SHARED_ID + 4, (uint32_t)(id >> 32));
    }
    return s;
}

static cdvr_status hvqc_shape(const cdvr_codec_params *blob, const size_t dims[3],
                              cdvr_codec_shape *out, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    size_t bound;
    cdvr_status s = cdvr_hvq_compact_bound(&p, dims, &bound, err);
    if (s != CDVR_OK)
        return s;
    out->timesteps = 1;
    out->payload_bytes = 0;
    out->bound_bytes = bound;
    return CDVR_OK;
}

static cdvr_status hvqc_encode(const cdvr_codec_params *blob, const size_t dims[3],
                               const uint8_t *const *frames, size_t count, uint8_t *out,
                               size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    if (count != 1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvqc: %zu frames for one chunk (1 "
                              "expected)", count);
    cdvr_hvq_codebooks cb;
    uint64_t held;
    cdvr_status s = open_shared(blob, &p, &cb, &held, err);
    if (s == CDVR_OK)
        s = cdvr_hvq_encode_compact(&p, held ? &cb : NULL, dims, frames[0], 0, out, out_cap,
                                    out_bytes, NULL, err);
    close_shared(&cb, held);
    return s;
}

static cdvr_status hvqc_decode(const cdvr_codec_params *blob, const size_t dims[3],
                               const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                               size_t count, cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    if (count != 1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec hvqc: %zu frames asked of a chunk of 1",
                              count);
    cdvr_hvq_codebooks cb;
    uint64_t held;
    cdvr_status s = open_shared(blob, &p, &cb, &held, err);
    if (s == CDVR_OK)
        s = cdvr_hvq_compact_decode(&p, held ? &cb : NULL, dims, in, in_bytes, frames[0], err);
    close_shared(&cb, held);
    return s;
}

static cdvr_status hvqc_describe(const cdvr_codec_params *blob, const size_t dims[3],
                                 const uint8_t *payload, size_t bytes,
                                 void (*emit)(void *ud, const char *key, double value), void *ud,
                                 cdvr_error *err)
{
    cdvr_hvq_params p;
    cdvr_hvq_params_from_blob(blob, &p);
    cdvr_hvq_stats st;
    cdvr_hvq_codebooks cb;
    uint64_t held;
    cdvr_status s = open_shared(blob, &p, &cb, &held, err);
    if (s == CDVR_OK)
        s = cdvr_hvq_compact_check(&p, held ? &cb : NULL, dims, payload, bytes, &st, err);
    close_shared(&cb, held);
    if (s != CDVR_OK)
        return s;
    emit(ud, "header", (double)st.header);
    emit(ud, "means", (double)st.means);
    emit(ud, "codebook1", (double)st.codebook1);
    emit(ud, "codebook2", (double)st.codebook2);
    emit(ud, "indices", (double)st.indices);
    emit(ud, "residuals", (double)st.residuals);
    emit(ud, "blocks", (double)st.blocks);
    emit(ud, "zero_blocks", (double)st.zero_blocks);
    emit(ud, "residual_voxels", (double)st.residual_voxels);
    emit(ud, "residual_sum", (double)st.residual); /* st:info() sums over chunks */
    return CDVR_OK;
}

const cdvr_codec cdvr_codec_hvqc = {
    .name = "hvqc",
    .id = CDVR_CODEC_ID_HVQC,
    .description = "hvq in its compact form: the same blocks and codebooks (per chunk, or one set "
                   "per variant with shared=1), zstd-coded means, index list and residual list "
                   "(within `residual`); CPU decode, for stores and the brick cache (the hashed "
                   "form \"hvq\" is for per-sample fetch)",
    .params = hvqc_params,
    .params_default = hvq_default,
    .params_set = hvqc_set,
    .params_get = hvqc_get,
    .params_check = hvqc_check,
    .variant_name = hvqc_name,
    .shape = hvqc_shape,
    .encode = hvqc_encode,
    .decode = hvqc_decode,
    .describe = hvqc_describe,
    .cl_mode = CDVR_CODEC_CL_NONE,
};
