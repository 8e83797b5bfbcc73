/* core/codec/pvtc/pvtc_codec.c - the PVTC family as a codec table (cdvr/codec.h).
 *
 * Parameter blob (little endian, unused bytes 0):
 *    0  u32  S        block depth, 1 or 4
 *    4  u32  T        channels per voxel, 2 or 3
 *    8  u32  pack     0 time (PVTC-TE), 1 space (PVTC-SE)
 *   12  u32  encoder  0 lsq (default), 1 bbox
 * Defaults S=4 T=3 pack=time encoder=lsq. The OpenCL decode kernel is kernels/codec/
 * pvtc_decode.cl, one work-item per block. */
#include "cdvr/codec.h"
#include "cdvr/pvtc.h"
#include "pvtc_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { OFF_S = 0, OFF_T = 4, OFF_PACK = 8, OFF_ENCODER = 12, USED_BYTES = 16 };

static const char *const pack_names[] = {"time", "space"};
static const char *const encoder_names[] = {"lsq", "bbox"};

static const cdvr_codec_param_doc pvtc_params[] = {
    {"S", "4", "block depth: 1 or 4 (a 4x4xS region shares one index per voxel)"},
    {"T", "3", "channels packed per voxel: 2 or 3"},
    {"pack", "time", "what the channels are: \"time\" (T timesteps) or \"space\" (T slices)"},
    {"encoder", "lsq", "\"lsq\" (least squares, never worse than bbox) or \"bbox\" (the papers')"},
    {NULL, NULL, NULL}};

void cdvr_pvtc_params_to_blob(const cdvr_pvtc_params *p, cdvr_pvtc_encoder encoder,
                              cdvr_codec_params *blob)
{
    memset(blob, 0, sizeof *blob);
    cdvr_params_set_u32(blob, OFF_S, (uint32_t)p->S);
    cdvr_params_set_u32(blob, OFF_T, (uint32_t)p->T);
    cdvr_params_set_u32(blob, OFF_PACK, (uint32_t)p->pack);
    cdvr_params_set_u32(blob, OFF_ENCODER, (uint32_t)encoder);
}

void cdvr_pvtc_params_from_blob(const cdvr_codec_params *blob, cdvr_pvtc_params *p,
                                cdvr_pvtc_encoder *encoder)
{
    p->S = (int)(cdvr_params_get_u32(blob, OFF_S) & 0xff);
    p->T = (int)(cdvr_params_get_u32(blob, OFF_T) & 0xff);
    p->pack = (cdvr_pack)(cdvr_params_get_u32(blob, OFF_PACK) & 1);
    if (encoder)
        *encoder = (cdvr_pvtc_encoder)(cdvr_params_get_u32(blob, OFF_ENCODER) & 1);
}

static void pvtc_default(cdvr_codec_params *p)
{
    cdvr_pvtc_params d = {4, 3, CDVR_PACK_TIME};
    cdvr_pvtc_params_to_blob(&d, CDVR_ENCODER_LSQ, p);
}

static int parse_choice(const char *value, const char *const names[2])
{
    for (int i = 0; i < 2; i++)
        if (strcmp(value, names[i]) == 0)
            return i;
    return -1;
}

static cdvr_status pvtc_set(cdvr_codec_params *p, const char *key, const char *value,
                            cdvr_error *err)
{
    size_t off;
    int v = -1;
    if (strcmp(key, "S") == 0 || strcmp(key, "T") == 0) {
        char *end;
        long n = strtol(value, &end, 10);
        int ok = *value && !*end && (key[0] == 'S' ? (n == 1 || n == 4) : (n == 2 || n == 3));
        if (!ok)
            return cdvr_error_set(err, CDVR_ERR_ARG, "codec pvtc: %s = '%s', must be %s", key,
                                  value, key[0] == 'S' ? "1 or 4" : "2 or 3");
        off = key[0] == 'S' ? OFF_S : OFF_T;
        v = (int)n;
    } else if (strcmp(key, "pack") == 0 || strcmp(key, "encoder") == 0) {
        int is_pack = key[0] == 'p';
        v = parse_choice(value, is_pack ? pack_names : encoder_names);
        if (v < 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "codec pvtc: %s = '%s', must be %s", key,
                                  value, is_pack ? "\"time\" or \"space\"" : "\"lsq\" or \"bbox\"");
        off = is_pack ? OFF_PACK : OFF_ENCODER;
    } else {
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec pvtc: unknown parameter '%s' "
                              "(parameters: S, T, pack, encoder)", key);
    }
    cdvr_params_set_u32(p, off, (uint32_t)v);
    return CDVR_OK;
}

static int pvtc_get(const cdvr_codec_params *p, const char *key, char *out, size_t n)
{
    uint32_t S = cdvr_params_get_u32(p, OFF_S), T = cdvr_params_get_u32(p, OFF_T);
    uint32_t pack = cdvr_params_get_u32(p, OFF_PACK), enc = cdvr_params_get_u32(p, OFF_ENCODER);
    if (strcmp(key, "S") == 0)
        snprintf(out, n, "%u", S);
    else if (strcmp(key, "T") == 0)
        snprintf(out, n, "%u", T);
    else if (strcmp(key, "pack") == 0)
        snprintf(out, n, "%s", pack_names[pack & 1]);
    else if (strcmp(key, "encoder") == 0)
        snprintf(out, n, "%s", encoder_names[enc & 1]);
    else
        return -1;
    return 0;
}

static cdvr_status pvtc_check(const cdvr_codec_params *p, cdvr_error *err)
{
    uint32_t S = cdvr_params_get_u32(p, OFF_S), T = cdvr_params_get_u32(p, OFF_T);
    uint32_t pack = cdvr_params_get_u32(p, OFF_PACK), enc = cdvr_params_get_u32(p, OFF_ENCODER);
    if ((S != 1 && S != 4) || (T != 2 && T != 3) || pack > 1 || enc > 1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec pvtc: bad parameters S=%u T=%u pack=%u "
                              "encoder=%u (S 1|4, T 2|3, pack 0|1, encoder 0|1)", S, T, pack, enc);
    for (size_t i = USED_BYTES; i < CDVR_CODEC_PARAMS_MAX; i++)
        if (p->bytes[i])
            return cdvr_error_set(err, CDVR_ERR_ARG, "codec pvtc: unused parameter byte %zu is "
                                  "%u", i, p->bytes[i]);
    return CDVR_OK;
}

static void pvtc_name(const cdvr_codec_params *p, char *name, size_t n)
{
    cdvr_pvtc_params q;
    cdvr_pvtc_params_from_blob(p, &q, NULL);
    snprintf(name, n, "S%dT%d%s", q.S, q.T, q.pack == CDVR_PACK_SPACE ? "s" : "");
}

static cdvr_status pvtc_shape(const cdvr_codec_params *p, const size_t dims[3],
                              cdvr_codec_shape *out, cdvr_error *err)
{
    cdvr_pvtc_params q;
    cdvr_pvtc_params_from_blob(p, &q, NULL);
    cdvr_pvtc_geometry g;
    cdvr_status s = cdvr_pvtc_geometry_get(&q, dims, &g, err);
    if (s != CDVR_OK)
        return s;
    out->timesteps = g.frames;
    out->payload_bytes = out->bound_bytes = g.chunk_bytes;
    return CDVR_OK;
}

static cdvr_status pvtc_encode(const cdvr_codec_params *p, const size_t dims[3],
                               const uint8_t *const *frames, size_t count, uint8_t *out,
                               size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    cdvr_pvtc_params q;
    cdvr_pvtc_encoder enc;
    cdvr_pvtc_params_from_blob(p, &q, &enc);
    cdvr_pvtc_geometry g;
    cdvr_status s = cdvr_pvtc_geometry_get(&q, dims, &g, err);
    if (s != CDVR_OK)
        return s;
    if (count < 1 || count > g.frames || out_cap < g.chunk_bytes)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec pvtc: %zu frames (1..%zu) into %zu bytes "
                              "(%zu needed)", count, g.frames, out_cap, g.chunk_bytes);
    s = cdvr_pvtc_encode_chunk(&q, enc, dims, frames, out, err);
    if (s == CDVR_OK)
        *out_bytes = g.chunk_bytes;
    return s;
}

/* Part k of n: blocks [k B / n, (k + 1) B / n) of the chunk's B blocks. */
static cdvr_status pvtc_encode_part(const cdvr_codec_params *p, const size_t dims[3],
                                    const uint8_t *const *frames, size_t count, size_t part,
                                    size_t nparts, uint8_t *out, size_t out_cap,
                                    cdvr_error *err)
{
    cdvr_pvtc_params q;
    cdvr_pvtc_encoder enc;
    cdvr_pvtc_params_from_blob(p, &q, &enc);
    cdvr_pvtc_geometry g;
    cdvr_status s = cdvr_pvtc_geometry_get(&q, dims, &g, err);
    if (s != CDVR_OK)
        return s;
    if (count < 1 || count > g.frames || out_cap < g.chunk_bytes || nparts == 0 ||
        part >= nparts)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec pvtc: %zu frames (1..%zu) into %zu bytes "
                              "(%zu needed), part %zu of %zu", count, g.frames, out_cap,
                              g.chunk_bytes, part, nparts);
    /* part * nblocks cannot overflow for any chunk that fits in memory in 64-bit size_t;
     * split it to stay exact elsewhere too */
    size_t q_blocks = g.nblocks / nparts, r_blocks = g.nblocks % nparts;
    size_t first = part * q_blocks + part * r_blocks / nparts;
    size_t end = (part + 1) * q_blocks + (part + 1) * r_blocks / nparts;
    return pvtc_encode_blocks(&q, enc, dims, frames, first, end - first, out, err);
}

static cdvr_status pvtc_decode(const cdvr_codec_params *p, const size_t dims[3],
                               const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                               size_t count, cdvr_error *err)
{
    cdvr_pvtc_params q;
    cdvr_pvtc_params_from_blob(p, &q, NULL);
    return cdvr_pvtc_decode_chunk(&q, dims, in, in_bytes, frames, count, err);
}

static size_t pvtc_work_items(const cdvr_codec_params *p, const size_t dims[3])
{
    cdvr_pvtc_params q;
    cdvr_pvtc_params_from_blob(p, &q, NULL);
    cdvr_pvtc_geometry g;
    return cdvr_pvtc_geometry_get(&q, dims, &g, NULL) == CDVR_OK ? g.nblocks : 0;
}

const cdvr_codec cdvr_codec_pvtc = {
    .name = "pvtc",
    .id = CDVR_CODEC_ID_PVTC,
    .description = "PVTC block compression (seeds 000/001): 4x4xS blocks, T channels over time "
                   "or space, fixed ratio (4+4S)/(16ST)",
    .params = pvtc_params,
    .params_default = pvtc_default,
    .params_set = pvtc_set,
    .params_get = pvtc_get,
    .params_check = pvtc_check,
    .variant_name = pvtc_name,
    .shape = pvtc_shape,
    .encode = pvtc_encode,
    .decode = pvtc_decode,
    .cl_mode = CDVR_CODEC_CL_DECODE,
    .cl_file = "codec/pvtc_decode.cl",
    .cl_function = "pvtc_decode",
    .cl_work_items = pvtc_work_items,
    .encode_part = pvtc_encode_part,
};
