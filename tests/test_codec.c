/* tests/test_codec.c - every codec through one round-trip table, through the codec table
 * (cdvr/codec.h) only: raw, each PVTC variant (S 1|4, T 2|3, pack time|space, encoder
 * lsq|bbox), zfp at rates 0.5, 1, 2, 4 and the example plugin's rle (lossless and 3 bits),
 * the plugins loaded from the build's plugins directory (CDVR_BINARY_DIR). Inputs: dims
 * 1x1x1, 5x3x7, 33x17x9; 1, 2, 4 and 5 timesteps (not multiples of the chunk length); smooth,
 * noise, constant, two-valued and 0/255 fields, all deterministic.
 *
 * Checked for every case: shape and bound consistent (fixed sizes exact, the encoder stays
 * within the bound), lossless codecs exact, lossy ones within their documented behaviour
 * (rle: |error| <= 2^(7-bits); PVTC: bit-exact with the reference decoder, deterministic, lsq
 * never worse than bbox, constant input exact for T=2 and within 4 for T=3; zfp: constant
 * input exact, squared error non-increasing from rate 0.5 to 4 and falling overall), a
 * shorter count decodes the leading frames, and truncated, extended or byte-flipped payloads
 * decode to CDVR_ERR_CORRUPT or a valid volume (the sanitizer build catches any out-of-bounds
 * access). Plus parameter parse/get round trips, variant names, refusals of bad parameter
 * values and blobs, and dims that overflow size_t. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/codec.h"
#include "cdvr/plugin.h"
#include "cdvr/pvtc.h"
#include "check.h"
#include "codec/pvtc/pvtc_internal.h"

#define MAX_T 3
#define MAX_KEYS 4

typedef enum behaviour {
    EXACT,     /* lossless */
    BOUNDED,   /* |error| <= max_err */
    PVTC_REF,  /* PVTC: equal to the reference decoder */
    ZFP_RATE   /* zfp: see check_zfp_rates */
} behaviour;

typedef struct variant_case {
    const char *codec;
    size_t nkeys;
    const char *keys[MAX_KEYS], *values[MAX_KEYS];
    const char *name;  /* expected variant name */
    behaviour kind;
    int max_err;       /* BOUNDED */
} variant_case;

#define PV(S, T, pack, enc, name)                                                                 \
    {"pvtc", 4, {"S", "T", "pack", "encoder"}, {#S, #T, pack, enc}, name, PVTC_REF, 0}

static const variant_case CASES[] = {
    {"raw", 0, {NULL}, {NULL}, "raw", EXACT, 0},
    PV(1, 2, "time", "lsq", "S1T2"),    PV(1, 2, "time", "bbox", "S1T2"),
    PV(1, 3, "time", "lsq", "S1T3"),    PV(1, 3, "time", "bbox", "S1T3"),
    PV(4, 2, "time", "lsq", "S4T2"),    PV(4, 2, "time", "bbox", "S4T2"),
    PV(4, 3, "time", "lsq", "S4T3"),    PV(4, 3, "time", "bbox", "S4T3"),
    PV(1, 2, "space", "lsq", "S1T2s"),  PV(1, 2, "space", "bbox", "S1T2s"),
    PV(1, 3, "space", "lsq", "S1T3s"),  PV(1, 3, "space", "bbox", "S1T3s"),
    PV(4, 2, "space", "lsq", "S4T2s"),  PV(4, 2, "space", "bbox", "S4T2s"),
    PV(4, 3, "space", "lsq", "S4T3s"),  PV(4, 3, "space", "bbox", "S4T3s"),
    {"zfp", 1, {"rate"}, {"0.5"}, "zfp0.5", ZFP_RATE, 0},
    {"zfp", 1, {"rate"}, {"1"}, "zfp1", ZFP_RATE, 0},
    {"zfp", 1, {"rate"}, {"2"}, "zfp2", ZFP_RATE, 0},
    {"zfp", 1, {"rate"}, {"4"}, "zfp4", ZFP_RATE, 0},
    {"rle", 0, {NULL}, {NULL}, "rle8", EXACT, 0},
    {"rle", 1, {"bits"}, {"3"}, "rle3", BOUNDED, 16},
};
#define NCASES (sizeof CASES / sizeof CASES[0])
#define NZFP 4

static const size_t DIMS[][3] = {{1, 1, 1}, {5, 3, 7}, {33, 17, 9}};
static const size_t NTIMES[] = {1, 2, 4, 5};
enum { SMOOTH, NOISE, CONSTANT, TWO_VALUED, ZERO_255, NPATTERNS };
static const char *const PATTERN_NAME[] = {"smooth", "noise", "constant", "two-valued", "0/255"};
#define CONSTANT_VALUE 77

/* ---- inputs ---------------------------------------------------------------------------------- */

static uint32_t hash32(uint32_t x)
{
    x ^= x >> 16;
    x *= 0x7feb352dU;
    x ^= x >> 15;
    x *= 0x846ca68bU;
    x ^= x >> 16;
    return x;
}

static uint8_t pattern_value(int pattern, size_t x, size_t y, size_t z, size_t t, size_t i)
{
    switch (pattern) {
    case SMOOTH: {
        double a = 0.31 * (double)x + 0.17 * (double)y + 0.23 * (double)z + 0.4 * (double)t;
        return (uint8_t)(127.5 + 120.0 * sin(a) * cos(0.11 * (double)(x + 2 * z)));
    }
    case NOISE:
        return (uint8_t)hash32((uint32_t)(i * 7919 + t * 104729 + 1));
    case CONSTANT:
        return CONSTANT_VALUE;
    case TWO_VALUED:
        return ((x + y + z + t) & 1) ? 200 : 40;
    default:
        return ((x * 7 + y * 3 + z * 5 + t) % 3 == 0) ? 255 : 0;
    }
}

/* nt frames of dims, frame t at series + t * voxels. */
static uint8_t *make_series(int pattern, const size_t dims[3], size_t nt)
{
    size_t voxels = dims[0] * dims[1] * dims[2];
    uint8_t *s = malloc(voxels * nt);
    if (!s)
        return NULL;
    for (size_t t = 0; t < nt; t++)
        for (size_t z = 0, i = 0; z < dims[2]; z++)
            for (size_t y = 0; y < dims[1]; y++)
                for (size_t x = 0; x < dims[0]; x++, i++)
                    s[t * voxels + i] = pattern_value(pattern, x, y, z, t, i);
    return s;
}

/* ---- one round trip ------------------------------------------------------------------------- */

typedef struct trip {
    const cdvr_codec *codec;
    const variant_case *vc;
    cdvr_codec_params params;
    const size_t *dims;
    size_t nt, voxels;
    int pattern;
    const uint8_t *series;
    char label[160];
} trip;

typedef struct trip_result {
    double sse;      /* squared error over the whole series */
    int max_err;
    int ok;          /* every encode and decode succeeded */
} trip_result;

/* Frames of the chunk starting at t0: exact-size allocations so that the sanitizer build
 * catches any write past a frame. */
static int alloc_frames(uint8_t *frames[MAX_T], size_t n, size_t voxels)
{
    for (size_t f = 0; f < n; f++)
        if (!(frames[f] = malloc(voxels)))
            return 0;
    return 1;
}

static void free_frames(uint8_t *frames[MAX_T], size_t n)
{
    for (size_t f = 0; f < n; f++) {
        free(frames[f]);
        frames[f] = NULL;
    }
}

/* Decoding a damaged payload: CDVR_OK or CDVR_ERR_CORRUPT, never anything out of bounds. */
static void damaged_decodes(const trip *tr, const uint8_t *payload, size_t bytes, size_t count,
                            uint32_t seed)
{
    uint8_t *frames[MAX_T] = {NULL};
    uint8_t *copy = malloc(bytes + 1);
    if (!copy || !alloc_frames(frames, count, tr->voxels)) {
        CHECK(0, "out of memory");
        free(copy);
        free_frames(frames, count);
        return;
    }
    size_t lengths[4] = {bytes ? bytes - 1 : 0, bytes / 2, 0, bytes + 1};
    for (int k = 0; k < 7; k++) {
        size_t n = bytes;
        if (bytes)
            memcpy(copy, payload, bytes);
        copy[bytes] = 0x5a;
        if (k < 4) {
            n = lengths[k];
        } else if (bytes) {
            for (int flips = 0; flips <= k - 4; flips++) {
                uint32_t h = hash32(seed + (uint32_t)(k * 31 + flips));
                copy[h % bytes] ^= (uint8_t)(1u << (h >> 29));
            }
        }
        /* A fresh exact-size copy, so reads past n are caught too. */
        uint8_t *in = malloc(n ? n : 1);
        if (!in)
            break;
        memcpy(in, copy, n);
        cdvr_error err;
        cdvr_status s = tr->codec->decode(&tr->params, tr->dims, in, n, frames, count, &err);
        CHECK(s == CDVR_OK || s == CDVR_ERR_CORRUPT, "%s: damaged payload (%zu of %zu bytes, "
              "case %d): status %d: %s", tr->label, n, bytes, k, (int)s, err.msg);
        free(in);
    }
    free(copy);
    free_frames(frames, count);
}

/* PVTC: the chunk decodes exactly as the reference decoder does, and twice the same. */
static void check_pvtc_reference(const trip *tr, const uint8_t *payload, size_t bytes,
                                 uint8_t *const *decoded, size_t count)
{
    cdvr_pvtc_params q;
    cdvr_pvtc_params_from_blob(&tr->params, &q, NULL);
    uint8_t *ref[MAX_T] = {NULL}, *again[MAX_T] = {NULL};
    if (!alloc_frames(ref, count, tr->voxels) || !alloc_frames(again, count, tr->voxels)) {
        CHECK(0, "out of memory");
    } else {
        cdvr_error err;
        CHECK_OK(pvtc_decode_chunk_path(&q, tr->dims, payload, bytes, ref, count,
                                        PVTC_DECODE_REFERENCE, &err), err);
        CHECK_OK(tr->codec->decode(&tr->params, tr->dims, payload, bytes, again, count, &err),
                 err);
        for (size_t f = 0; f < count; f++) {
            CHECK(memcmp(decoded[f], ref[f], tr->voxels) == 0, "%s: frame %zu differs from the "
                  "reference decoder", tr->label, f);
            CHECK(memcmp(decoded[f], again[f], tr->voxels) == 0, "%s: frame %zu: decode not "
                  "deterministic", tr->label, f);
        }
    }
    free_frames(ref, count);
    free_frames(again, count);
}

/* Encodes and decodes one chunk (frames t0 .. t0 + count - 1, padded by repeating the last
 * real one) and adds its error to res. */
static void round_trip_chunk(const trip *tr, const cdvr_codec_shape *shape, size_t t0,
                             trip_result *res)
{
    size_t T = shape->timesteps, count = tr->nt - t0 < T ? tr->nt - t0 : T;
    const uint8_t *in[MAX_T];
    for (size_t k = 0; k < T; k++)
        in[k] = tr->series + (t0 + k < tr->nt ? t0 + k : tr->nt - 1) * tr->voxels;
    enum { GUARD = 32 };
    uint8_t *payload = malloc(shape->bound_bytes + GUARD);
    uint8_t *out[MAX_T] = {NULL}, *first[MAX_T] = {NULL};
    if (!payload || !alloc_frames(out, count, tr->voxels) || !alloc_frames(first, 1, tr->voxels)) {
        CHECK(0, "out of memory");
        res->ok = 0;
        goto done;
    }
    memset(payload + shape->bound_bytes, 0xA5, GUARD);
    size_t bytes = 0;
    cdvr_error err;
    cdvr_status s = tr->codec->encode(&tr->params, tr->dims, in, count, payload,
                                      shape->bound_bytes, &bytes, &err);
    CHECK(s == CDVR_OK, "%s t0=%zu: encode: %s", tr->label, t0, err.msg);
    if (s != CDVR_OK) {
        res->ok = 0;
        goto done;
    }
    CHECK(bytes <= shape->bound_bytes, "%s: %zu bytes over the bound %zu", tr->label, bytes,
          shape->bound_bytes);
    CHECK(!shape->payload_bytes || bytes == shape->payload_bytes, "%s: %zu bytes, fixed size "
          "%zu", tr->label, bytes, shape->payload_bytes);
    for (size_t g = 0; g < GUARD; g++)
        if (payload[shape->bound_bytes + g] != 0xA5) {
            CHECK(0, "%s: encoder wrote past its bound", tr->label);
            break;
        }
    s = tr->codec->decode(&tr->params, tr->dims, payload, bytes, out, count, &err);
    CHECK(s == CDVR_OK, "%s t0=%zu: decode: %s", tr->label, t0, err.msg);
    if (s != CDVR_OK) {
        res->ok = 0;
        goto done;
    }
    for (size_t f = 0; f < count; f++)
        for (size_t i = 0; i < tr->voxels; i++) {
            int e = abs((int)out[f][i] - (int)in[f][i]);
            res->sse += (double)e * e;
            if (e > res->max_err)
                res->max_err = e;
        }
    if (count > 1) { /* fewer frames than the chunk holds: the leading ones, the same */
        s = tr->codec->decode(&tr->params, tr->dims, payload, bytes, first, 1, &err);
        CHECK(s == CDVR_OK && memcmp(first[0], out[0], tr->voxels) == 0, "%s: decode of 1 of %zu "
              "frames: %s", tr->label, count, s == CDVR_OK ? "differs" : err.msg);
    }
    if (tr->vc->kind == PVTC_REF)
        check_pvtc_reference(tr, payload, bytes, out, count);
    damaged_decodes(tr, payload, bytes, count, (uint32_t)(t0 * 131 + bytes));
done:
    free(payload);
    free_frames(out, count);
    free_frames(first, 1);
}

static trip_result round_trip(const trip *tr)
{
    trip_result res = {0, 0, 1};
    cdvr_codec_shape shape, again;
    cdvr_error err;
    cdvr_status s = cdvr_codec_shape_of(tr->codec, &tr->params, tr->dims, &shape, &err);
    CHECK(s == CDVR_OK, "%s: shape: %s", tr->label, err.msg);
    if (s != CDVR_OK) {
        res.ok = 0;
        return res;
    }
    CHECK(shape.timesteps >= 1 && shape.timesteps <= MAX_T, "%s: %zu timesteps per chunk",
          tr->label, shape.timesteps);
    CHECK_OK(tr->codec->shape(&tr->params, tr->dims, &again, &err), err);
    CHECK(memcmp(&shape, &again, sizeof shape) == 0, "%s: shape not stable", tr->label);
    if (shape.timesteps > MAX_T) {
        res.ok = 0;
        return res;
    }
    for (size_t t0 = 0; t0 < tr->nt; t0 += shape.timesteps)
        round_trip_chunk(tr, &shape, t0, &res);
    return res;
}

/* ---- behaviour per codec ------------------------------------------------------------------- */

static void check_behaviour(const trip *tr, const trip_result *res)
{
    const variant_case *vc = tr->vc;
    if (!res->ok)
        return;
    if (vc->kind == EXACT)
        CHECK(res->max_err == 0, "%s: lossless codec off by %d", tr->label, res->max_err);
    if (vc->kind == BOUNDED)
        CHECK(res->max_err <= vc->max_err, "%s: error %d > %d", tr->label, res->max_err,
              vc->max_err);
    if (vc->kind == ZFP_RATE && tr->pattern == CONSTANT)
        CHECK(res->max_err == 0, "%s: constant input off by %d", tr->label, res->max_err);
    if (vc->kind == PVTC_REF && tr->pattern == CONSTANT) {
        cdvr_pvtc_params q;
        cdvr_pvtc_params_from_blob(&tr->params, &q, NULL);
        CHECK(res->max_err <= (q.T == 2 ? 0 : 4), "%s: constant input off by %d", tr->label,
              res->max_err);
    }
}

/* zfp: squared error non-increasing with the rate, and lower at 4 than at 0.5 unless both
 * are exact. sse[i] for CASES' zfp rows in order 0.5, 1, 2, 4. */
static void check_zfp_rates(const char *input, const double sse[NZFP])
{
    for (int i = 1; i < NZFP; i++)
        CHECK(sse[i] <= sse[i - 1], "%s: zfp squared error %g at rate step %d > %g before",
              input, sse[i], i, sse[i - 1]);
    CHECK(sse[NZFP - 1] < sse[0] || sse[0] == 0, "%s: zfp error does not fall with the rate "
          "(%g .. %g)", input, sse[0], sse[NZFP - 1]);
}

/* lsq is never worse than bbox: CASES lists each PVTC variant as lsq then bbox. */
static void check_lsq_vs_bbox(const char *input, size_t i, const double sse[NCASES])
{
    if (CASES[i].kind == PVTC_REF && strcmp(CASES[i].values[3], "bbox") == 0)
        CHECK(sse[i - 1] <= sse[i], "%s %s: lsq error %g > bbox %g", input, CASES[i].name,
              sse[i - 1], sse[i]);
}

static int run_table(const cdvr_codec *codecs[NCASES])
{
    int inputs = 0;
    for (size_t d = 0; d < sizeof DIMS / sizeof DIMS[0]; d++)
        for (size_t n = 0; n < sizeof NTIMES / sizeof NTIMES[0]; n++)
            for (int pattern = 0; pattern < NPATTERNS; pattern++) {
                uint8_t *series = make_series(pattern, DIMS[d], NTIMES[n]);
                if (!series) {
                    CHECK(0, "out of memory");
                    continue;
                }
                char input[96];
                snprintf(input, sizeof input, "%zux%zux%zu, %zu timesteps, %s", DIMS[d][0],
                         DIMS[d][1], DIMS[d][2], NTIMES[n], PATTERN_NAME[pattern]);
                double sse[NCASES] = {0}, zfp_sse[NZFP];
                int nzfp = 0;
                for (size_t c = 0; c < NCASES; c++) {
                    if (!codecs[c])
                        continue;
                    trip tr = {codecs[c], &CASES[c], {{0}}, DIMS[d], NTIMES[n],
                               DIMS[d][0] * DIMS[d][1] * DIMS[d][2], pattern, series, ""};
                    cdvr_error err;
                    CHECK_OK(cdvr_codec_params_parse(codecs[c], CASES[c].keys, CASES[c].values,
                                                     CASES[c].nkeys, &tr.params, &err), err);
                    snprintf(tr.label, sizeof tr.label, "%s (%s) on %s", CASES[c].name,
                             c && CASES[c].kind == PVTC_REF ? CASES[c].values[3] : CASES[c].codec,
                             input);
                    trip_result res = round_trip(&tr);
                    check_behaviour(&tr, &res);
                    sse[c] = res.sse;
                    if (CASES[c].kind == ZFP_RATE)
                        zfp_sse[nzfp++] = res.sse;
                    check_lsq_vs_bbox(input, c, sse);
                }
                if (nzfp == NZFP)
                    check_zfp_rates(input, zfp_sse);
                free(series);
                inputs++;
            }
    return inputs;
}

/* ---- parameters, names, sizes ---------------------------------------------------------------- */

/* Parse -> variant name -> params_get of every documented key -> parse again: same blob. */
static void check_params_round_trip(const cdvr_codec *codec, const variant_case *vc)
{
    cdvr_codec_params p, back;
    cdvr_error err;
    CHECK_OK(cdvr_codec_params_parse(codec, vc->keys, vc->values, vc->nkeys, &p, &err), err);
    char name[CDVR_VARIANT_NAME_MAX];
    codec->variant_name(&p, name, sizeof name);
    CHECK(strcmp(name, vc->name) == 0, "%s: variant name %s, want %s", codec->name, name,
          vc->name);
    const char *keys[8], *values[8];
    char text[8][64];
    size_t n = 0;
    for (const cdvr_codec_param_doc *doc = codec->params; doc->key && n < 8; doc++, n++) {
        CHECK(doc->def && doc->description && *doc->description, "%s.%s: undocumented",
              codec->name, doc->key);
        CHECK(codec->params_get(&p, doc->key, text[n], sizeof text[n]) == 0, "%s: get %s",
              codec->name, doc->key);
        keys[n] = doc->key;
        values[n] = text[n];
    }
    CHECK_OK(cdvr_codec_params_parse(codec, keys, values, n, &back, &err), err);
    CHECK(memcmp(&p, &back, sizeof p) == 0, "%s %s: params_get/params_set do not round-trip",
          codec->name, vc->name);
    char junk[8];
    CHECK(codec->params_get(&p, "no_such_key", junk, sizeof junk) == -1, "%s: get unknown key",
          codec->name);
    /* The documented defaults are what params_default gives. */
    cdvr_codec_params def, from_docs;
    memset(&def, 0, sizeof def);
    codec->params_default(&def);
    CHECK_OK(codec->params_check(&def, &err), err);
    n = 0;
    for (const cdvr_codec_param_doc *doc = codec->params; doc->key && n < 8; doc++, n++) {
        keys[n] = doc->key;
        values[n] = doc->def;
    }
    CHECK_OK(cdvr_codec_params_parse(codec, keys, values, n, &from_docs, &err), err);
    CHECK(memcmp(&def, &from_docs, sizeof def) == 0, "%s: documented defaults differ from "
          "params_default", codec->name);
}

static void expect_bad_value(const cdvr_codec *codec, const char *key, const char *value,
                             const char *want)
{
    cdvr_codec_params p;
    cdvr_error err;
    const char *k[1] = {key}, *v[1] = {value};
    cdvr_status s = cdvr_codec_params_parse(codec, k, v, 1, &p, &err);
    CHECK(s == CDVR_ERR_ARG && strstr(err.msg, want), "%s: %s=%s: status %d: %s", codec->name,
          key, value, (int)s, err.msg);
}

static void check_refusals(const cdvr_codec *codec)
{
    expect_bad_value(codec, "no_such_key", "1", "unknown parameter 'no_such_key'");
    cdvr_codec_params p;
    memset(&p, 0, sizeof p);
    codec->params_default(&p);
    p.bytes[CDVR_CODEC_PARAMS_MAX - 1] = 1; /* an unused byte set */
    cdvr_error err;
    CHECK(codec->params_check(&p, &err) == CDVR_ERR_ARG, "%s: stray blob byte accepted",
          codec->name);
    /* Dims whose sizes overflow size_t: an error, not a wrapped size. */
    codec->params_default(&p);
    size_t huge[3] = {SIZE_MAX / 2, 3, 3};
    cdvr_codec_shape shape;
    cdvr_status s = cdvr_codec_shape_of(codec, &p, huge, &shape, &err);
    CHECK(s == CDVR_ERR_NOMEM || s == CDVR_ERR_ARG, "%s: huge dims: status %d", codec->name,
          (int)s);
}

static void check_zfp_specifics(const cdvr_codec *zfp)
{
    expect_bad_value(zfp, "rate", "0.3", "nearest: 0.296875 or 0.3125");
    expect_bad_value(zfp, "rate", "0", "from 1/64");
    expect_bad_value(zfp, "rate", "17", "to 16");
    expect_bad_value(zfp, "rate", "fast", "must be a number");
    expect_bad_value(zfp, "rate", "", "must be a number");
    const char *k[1] = {"rate"}, *v[1] = {"0.015625"};
    cdvr_codec_params p;
    cdvr_error err;
    CHECK_OK(cdvr_codec_params_parse(zfp, k, v, 1, &p, &err), err);
    char name[CDVR_VARIANT_NAME_MAX];
    zfp->variant_name(&p, name, sizeof name);
    CHECK(strcmp(name, "zfp0.015625") == 0, "%s", name);
    /* Payload = ceil(nblocks * 64 * rate / 8) bytes; bound from zfp adds its header room. */
    static const struct {
        const char *rate;
        size_t dims[3], bytes;
    } sizes[] = {{"0.5", {1, 1, 1}, 4},      {"0.5", {5, 3, 7}, 16},
                 {"1", {33, 17, 9}, 1080},   {"0.015625", {33, 17, 9}, 17},
                 {"16", {256, 256, 128}, 16 * 256 * 256 * 128 / 8}};
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        v[0] = sizes[i].rate;
        cdvr_codec_shape shape;
        CHECK_OK(cdvr_codec_params_parse(zfp, k, v, 1, &p, &err), err);
        CHECK_OK(cdvr_codec_shape_of(zfp, &p, sizes[i].dims, &shape, &err), err);
        CHECK(shape.timesteps == 1 && shape.payload_bytes == sizes[i].bytes &&
                  shape.bound_bytes >= shape.payload_bytes &&
                  shape.bound_bytes <= shape.payload_bytes + 32,
              "zfp rate %s: %zu bytes (want %zu), bound %zu", sizes[i].rate, shape.payload_bytes,
              sizes[i].bytes, shape.bound_bytes);
    }
    /* A blob from a zfp with another stream format is refused, not misread. */
    zfp->params_default(&p);
    cdvr_params_set_u32(&p, 4, cdvr_params_get_u32(&p, 4) + 1);
    CHECK(zfp->params_check(&p, &err) == CDVR_ERR_ARG && strstr(err.msg, "stream format"), "%s",
          err.msg);
}

static void check_rle_specifics(const cdvr_codec *rle)
{
    expect_bad_value(rle, "bits", "0", "from 1 to 8");
    expect_bad_value(rle, "bits", "9", "from 1 to 8");
    expect_bad_value(rle, "bits", "4.5", "from 1 to 8");
    /* Payloads that do not cover the frame exactly are refused. */
    cdvr_codec_params p;
    rle->params_default(&p);
    size_t dims[3] = {4, 1, 1};
    uint8_t frame[4], *frames[1] = {frame};
    cdvr_error err;
    static const struct {
        uint8_t bytes[6];
        size_t n;
        cdvr_status want;
    } payloads[] = {{{3, 9}, 2, CDVR_OK},
                    {{1, 9, 1, 7}, 4, CDVR_OK},
                    {{4, 9}, 2, CDVR_ERR_CORRUPT},       /* run of 5 into 4 voxels */
                    {{1, 9}, 2, CDVR_ERR_CORRUPT},       /* 2 of 4 voxels */
                    {{3, 9, 0}, 3, CDVR_ERR_CORRUPT},    /* odd size */
                    {{3, 9, 0, 1}, 4, CDVR_ERR_CORRUPT}, /* past the end */
                    {{0}, 0, CDVR_ERR_CORRUPT}};
    for (size_t i = 0; i < sizeof payloads / sizeof payloads[0]; i++) {
        cdvr_status s = rle->decode(&p, dims, payloads[i].bytes, payloads[i].n, frames, 1, &err);
        CHECK(s == payloads[i].want, "rle payload %zu: status %d", i, (int)s);
    }
}

/* ---- main ------------------------------------------------------------------------------------ */

static int plugin_built(const char *name)
{
    const char *list = getenv("CDVR_BUILT_PLUGINS");
    size_t n = strlen(name);
    for (const char *p = list ? strstr(list, name) : NULL; p; p = strstr(p + 1, name))
        if ((p == list || p[-1] == ' ') && (p[n] == '\0' || p[n] == ' '))
            return 1;
    return 0;
}

/* Loads build/plugins/cdvr_<file>.so when that plugin was built; 0 when it was not. */
static int load_plugin(const char *file)
{
    if (!plugin_built(file)) {
        printf("plugin %s not built: its cases are skipped\n", file);
        return 0;
    }
    const char *bin = getenv("CDVR_BINARY_DIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/plugins/cdvr_%s.so", bin && *bin ? bin : ".", file);
    cdvr_error err;
    cdvr_status s = cdvr_plugin_load(path, NULL, &err);
    CHECK_OK(s, err);
    return s == CDVR_OK;
}

int main(void)
{
    int have_zfp = load_plugin("zfp");
    int have_rle = load_plugin("example"); /* not with -DCDVR_WITH_PLUGINS=OFF */
    const cdvr_codec *codecs[NCASES];
    for (size_t c = 0; c < NCASES; c++) {
        int loaded = strcmp(CASES[c].codec, "zfp") == 0   ? have_zfp
                     : strcmp(CASES[c].codec, "rle") == 0 ? have_rle
                                                          : 1;
        codecs[c] = loaded ? cdvr_codec_find(CASES[c].codec) : NULL;
        CHECK(!loaded || codecs[c], "codec %s not registered", CASES[c].codec);
        if (codecs[c])
            check_params_round_trip(codecs[c], &CASES[c]);
    }
    for (size_t i = 0; i < cdvr_codec_count(); i++)
        check_refusals(cdvr_codec_at(i));
    if (have_zfp)
        check_zfp_specifics(cdvr_codec_find("zfp"));
    if (have_rle)
        check_rle_specifics(cdvr_codec_find("rle"));
    int inputs = run_table(codecs);
    printf("%d inputs x %zu variants\n", inputs, NCASES);
    return check_finish();
}
