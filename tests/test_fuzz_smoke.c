/* tests/test_fuzz_smoke.c - runs the libFuzzer targets of tests/fuzz/ (store reader, PVTC
 * chunk decoder, codec-table decoders with the zfp and rle plugins, the hvq decoder, the hvq
 * OpenCL decode/fetch path when a device exists (PoCL here), LZO stage 2, the on-disk cache
 * and the stage-2 rates it holds, NRRD/NIfTI/raw
 * loaders, the VTK .vti/.vtk header parsers) without libFuzzer: a deterministic
 * corpus of valid inputs built here, then thousands of seeded mutations of each (bit flips,
 * byte sets, truncations, insertions, copies). In the sanitizer build any out-of-bounds access
 * fails the test; in every build a target's differential check (FUZZ_ASSERT) aborts it. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "check.h"
#include "spec.h"
#include "cdvr/hvq.h"
#include "cdvr/pvtc.h"
#include "cdvr/store.h"
#include "cdvr/volume.h"

#define LLVMFuzzerTestOneInput fuzz_store_input
#include "fuzz/fuzz_store.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_pvtc_input
#include "fuzz/fuzz_pvtc.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_lzo_input
#include "fuzz/fuzz_lzo.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_cache_input
#include "fuzz/fuzz_cache.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_load_input
#include "fuzz/fuzz_load.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_vtk_input
#include "fuzz/fuzz_vtk.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_desc_input
#include "fuzz/fuzz_desc.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_codec_input
#include "fuzz/fuzz_codec.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_hvq_input
#include "fuzz/fuzz_hvq.c"
#undef LLVMFuzzerTestOneInput
#define LLVMFuzzerTestOneInput fuzz_hvq_cl_input
#include "fuzz/fuzz_hvq_cl.c"
#undef LLVMFuzzerTestOneInput

typedef int (*fuzz_target)(const uint8_t *data, size_t size);

typedef struct bytes {
    uint8_t *p;
    size_t n, cap;
} bytes;

static int bytes_append(bytes *b, const void *src, size_t n)
{
    if (b->n + n > b->cap) {
        size_t cap = 2 * (b->n + n) + 64;
        uint8_t *p = realloc(b->p, cap);
        if (!p)
            return 0;
        b->p = p;
        b->cap = cap;
    }
    if (n)
        memcpy(b->p + b->n, src, n);
    b->n += n;
    return 1;
}

static uint32_t rng_next(uint32_t *state)
{
    *state ^= *state << 13;
    *state ^= *state >> 17;
    *state ^= *state << 5;
    return *state;
}

/* One random edit of m (which has room for 64 more bytes than m->n). Truncations are rare so
 * that most mutants keep their size fields consistent and reach the parsers' later checks. */
static void mutate_once(bytes *m, uint32_t *rng)
{
    static const uint8_t interesting[] = {0, 1, 2, 3, 4, 0x7f, 0x80, 0xfe, 0xff};
    size_t n = m->n, at = n ? rng_next(rng) % n : 0;
    uint32_t op = rng_next(rng) % 20;
    if (op == 0) { /* truncation */
        m->n = at;
    } else if (op <= 2) { /* insertion of up to 16 random bytes */
        size_t k = 1 + rng_next(rng) % 16;
        if (n + k > m->cap)
            return;
        memmove(m->p + at + k, m->p + at, n - at);
        for (size_t i = 0; i < k; i++)
            m->p[at + i] = (uint8_t)rng_next(rng);
        m->n = n + k;
    } else if (op <= 5) { /* copy of up to 8 bytes inside the input (moves size fields) */
        size_t from = n ? rng_next(rng) % n : 0, k = 1 + rng_next(rng) % 8;
        for (size_t i = 0; i < k && from + i < n && at + i < n; i++)
            m->p[at + i] = m->p[from + i];
    } else if (n && op <= 11) { /* bit flip */
        m->p[at] ^= (uint8_t)(1u << (rng_next(rng) % 8));
    } else if (n && op <= 15) { /* interesting byte */
        m->p[at] = interesting[rng_next(rng) % sizeof interesting];
    } else if (n) { /* random byte */
        m->p[at] = (uint8_t)rng_next(rng);
    }
}

/* With CDVR_FUZZ_SEED_DIR set, the seed is also written there as NAME_N (libFuzzer corpus
 * directories NAME/, see tests/fuzz/README). */
static void save_seed(const char *name, const bytes *seed)
{
    static int counter = 0;
    const char *dir = getenv("CDVR_FUZZ_SEED_DIR");
    char path[512];
    if (!dir || !*dir || snprintf(path, sizeof path, "%s/%s/seed_%d", dir, name, counter++) >=
                             (int)sizeof path)
        return;
    FILE *f = fopen(path, "wb");
    CHECK(f && fwrite(seed->p, 1, seed->n, f) == seed->n, "cannot write %s", path);
    if (f)
        fclose(f);
}

/* Outcomes of all mutants per target (name): broken inputs must be rejected and some mutants
 * still accepted, or the target does not reach its decoder (checked in main). Per seed only the
 * seed's own acceptance is checked: for fixed-size formats (PVTC, zfp fixed rate, raw) every
 * mutant of the right length is a valid input. */
typedef struct target_totals {
    const char *name;
    size_t seeds, accepted, rejected;
} target_totals;
static target_totals smoke_totals[12];

static void add_totals(const char *name, size_t accepted, size_t rejected)
{
    for (size_t i = 0; i < sizeof smoke_totals / sizeof smoke_totals[0]; i++)
        if (!smoke_totals[i].name || strcmp(smoke_totals[i].name, name) == 0) {
            smoke_totals[i].name = name;
            smoke_totals[i].seeds++;
            smoke_totals[i].accepted += accepted;
            smoke_totals[i].rejected += rejected;
            return;
        }
}

static void check_totals(void)
{
    for (size_t i = 0; i < sizeof smoke_totals / sizeof smoke_totals[0] && smoke_totals[i].name; i++) {
        const target_totals *t = &smoke_totals[i];
        fprintf(stderr, "%s: %zu seeds, mutants %zu accepted, %zu rejected\n", t->name, t->seeds, t->accepted,
                t->rejected);
        CHECK(t->accepted > 0 && t->rejected > 0, "%s: mutants %zu accepted, %zu rejected: both outcomes expected",
              t->name, t->accepted, t->rejected);
    }
}

/* Runs target on seed, then on `count` mutations of it (1..4 edits each). keep_first: that
 * many leading bytes (mode/selector bytes) are restored after mutating, so that every mode is
 * driven deliberately rather than by chance. */
static void fuzz_seed(const char *name, fuzz_target target, const bytes *seed, size_t count,
                      size_t keep_first, uint32_t rng)
{
    save_seed(name, seed);
    bytes m = {malloc(seed->n + 64), 0, seed->n + 64};
    if (!m.p) {
        CHECK(0, "out of memory");
        return;
    }
    const unsigned seed_id = (unsigned)rng;
    fuzz_outcome_counts = (fuzz_outcomes){0, 0};
    target(seed->p, seed->n);
    CHECK(fuzz_outcome_counts.accepted == 1 && fuzz_outcome_counts.rejected == 0, "%s seed %u: accepted by the target",
          name, seed_id);
    for (size_t i = 0; i < count; i++) {
        memcpy(m.p, seed->p, seed->n);
        m.n = seed->n;
        int edits = 1 + (int)(rng_next(&rng) % 4);
        for (int e = 0; e < edits; e++)
            mutate_once(&m, &rng);
        if (m.n >= keep_first)
            memcpy(m.p, seed->p, keep_first);
        target(m.p, m.n);
    }
    free(m.p);
    size_t decided = fuzz_outcome_counts.accepted - 1 + fuzz_outcome_counts.rejected;
    CHECK(decided >= count / 2, "%s seed %u: only %zu of %zu mutants reached the code under test", name, seed_id,
          decided, count);
    add_totals(name, fuzz_outcome_counts.accepted - 1, fuzz_outcome_counts.rejected);
}

/* ---- corpus ---------------------------------------------------------------------------- */

/* A smooth 10x7x5 series of 5 timesteps with a constant region (LZO pays on it). */
static cdvr_volume *make_series(void)
{
    const size_t dims[3] = {10, 7, 5};
    cdvr_volume *vol = NULL;
    cdvr_error err;
    if (cdvr_volume_create(dims, 5, CDVR_TYPE_U8, &vol, &err) != CDVR_OK)
        return NULL;
    uint8_t *v = vol->data;
    for (size_t t = 0; t < 5; t++)
        for (size_t z = 0; z < 5; z++)
            for (size_t y = 0; y < 7; y++)
                for (size_t x = 0; x < 10; x++)
                    *v++ = (uint8_t)(x < 4 ? 40 : 20 * x + 9 * y + 5 * z + 7 * t);
    return vol;
}

/* Store seed: mode byte + a store with four variants (LZO, LZ4 in 128-byte segments, raw with
 * zstd in 256-byte segments, none), so mutations reach the segment tables too. With
 * multilevel, a fifth variant, hvqc with a shared codebook blob, and a second resolution level
 * (the level directory and an embedded store). */
static int make_store_seed(bytes *seed, uint8_t mode, int multilevel)
{
    cdvr_variant_spec specs[5];
    memset(specs, 0, sizeof specs);
    specs[0] = spec_pvtc(1, 3, CDVR_PACK_TIME, CDVR_ENCODER_BBOX, CDVR_STAGE2_LZO, 0.0);
    specs[1] = spec_pvtc(4, 2, CDVR_PACK_SPACE, CDVR_ENCODER_BBOX, CDVR_STAGE2_LZ4, 0.0);
    specs[1].stage2_segment = 128;
    specs[2] = spec_codec("raw", CDVR_STAGE2_ZSTD, 0.0);
    specs[2].stage2_segment = 256;
    specs[3] = spec_pvtc(4, 3, CDVR_PACK_TIME, CDVR_ENCODER_BBOX, CDVR_STAGE2_NONE, -1.0);
    size_t nvariants = 4;
    cdvr_error err;
    if (multilevel) {
        specs[4] = spec_codec("hvqc", CDVR_STAGE2_NONE, -1.0);
        const char *key = "shared", *value = "1";
        CHECK(specs[4].codec && cdvr_codec_params_parse(specs[4].codec, &key, &value, 1,
                                                        &specs[4].params, &err) == CDVR_OK,
              "hvqc shared=1 for the multi-level store seed");
        nvariants = 5;
    }
    cdvr_encode_opts opts = {.variants = specs, .nvariants = nvariants, .qlo = 0, .qhi = 1,
                             .source_type = CDVR_TYPE_U8, .levels = multilevel ? 2 : 0};
    cdvr_volume *vol = make_series();
    char path[256];
    int ok = vol && fuzz_write_temp(NULL, 0, ".cdv", path);
    cdvr_status st = ok ? cdvr_store_encode(vol, &opts, path, &err) : CDVR_ERR_NOMEM;
    CHECK_OK(st, err);
    cdvr_volume_free(vol);
    if (!ok)
        return 0;
    FILE *f = st == CDVR_OK ? fopen(path, "rb") : NULL;
    uint8_t buf[4096];
    size_t got;
    ok = f && bytes_append(seed, &mode, 1);
    while (ok && (got = fread(buf, 1, sizeof buf, f)) > 0)
        ok = bytes_append(seed, buf, got);
    if (f)
        fclose(f);
    /* the seed is what the store target wants: it opens, LZO chunks included */
    cdvr_store *opened = NULL;
    if (ok && cdvr_store_open(path, &opened, &err) == CDVR_OK) {
        size_t lzo_chunks = 0, segmented = 0;
        for (size_t v = 0; v < 4; v++)
            for (size_t c = 0; c < cdvr_store_variant(opened, v)->nchunks; c++) {
                lzo_chunks += cdvr_store_chunk(opened, v, c)->stage2 == CDVR_STAGE2_LZO;
                segmented += (size_t)cdvr_store_chunk(opened, v, c)->stage2_segmented;
            }
        CHECK(cdvr_store_get_info(opened)->nvariants == nvariants && lzo_chunks > 0 &&
              segmented > 0 && cdvr_store_get_info(opened)->nlevels == (multilevel ? 2u : 1u),
              "store seed: %zu variants, %zu levels, %zu LZO chunks, %zu segmented",
              cdvr_store_get_info(opened)->nvariants, cdvr_store_get_info(opened)->nlevels,
              lzo_chunks, segmented);
        cdvr_store_close(opened);
    } else {
        CHECK(0, "store seed does not open: %s", ok ? err.msg : "no bytes");
    }
    unlink(path);
    return ok;
}

/* PVTC seed: header bytes for (params, dims) + an encoded chunk of make_series' first frames. */
static int make_pvtc_seed(bytes *seed, uint8_t param_bits, uint8_t path)
{
    const cdvr_pvtc_params p = {param_bits & 1 ? 4 : 1, param_bits & 2 ? 3 : 2,
                                param_bits & 4 ? CDVR_PACK_SPACE : CDVR_PACK_TIME};
    cdvr_volume *vol = make_series();
    cdvr_pvtc_geometry g;
    cdvr_error err;
    int ok = vol && cdvr_pvtc_geometry_get(&p, vol->dims, &g, &err) == CDVR_OK;
    uint8_t *chunk = ok ? malloc(g.chunk_bytes) : NULL;
    const uint8_t *frames[3];
    for (size_t f = 0; ok && f < 3; f++)
        frames[f] = cdvr_volume_frame(vol, f);
    ok = chunk && cdvr_pvtc_encode_chunk(&p, CDVR_ENCODER_LSQ, vol->dims, frames, chunk, &err) ==
                      CDVR_OK;
    uint8_t nframes = p.pack == CDVR_PACK_SPACE ? 1 : (uint8_t)p.T;
    uint8_t head[5] = {(uint8_t)(param_bits | path << 3 | nframes << 6), (uint8_t)vol->dims[0] - 1,
                       (uint8_t)vol->dims[1] - 1, (uint8_t)vol->dims[2] - 1, 1};
    ok = ok && bytes_append(seed, head, 5) && bytes_append(seed, chunk, g.chunk_bytes);
    CHECK(ok, "pvtc seed %d", param_bits);
    free(chunk);
    cdvr_volume_free(vol);
    return ok;
}

/* Codec seed: header for PRESETS[preset] on make_series' dims + a payload encoded through the
 * codec table from its first frames. 0 when the preset's codec is not loaded. */
static int make_codec_seed(bytes *seed, uint8_t preset)
{
    const codec_preset *pre = &PRESETS[preset];
    const cdvr_codec *codec = cdvr_codec_find(pre->codec);
    if (!codec)
        return 0;
    cdvr_volume *vol = make_series();
    cdvr_codec_params params;
    cdvr_codec_shape shape;
    cdvr_error err;
    const char *keys[1] = {pre->key}, *values[1] = {pre->value};
    int ok = vol && cdvr_codec_params_parse(codec, keys, values, pre->key ? 1 : 0, &params,
                                            &err) == CDVR_OK &&
             cdvr_codec_shape_of(codec, &params, vol->dims, &shape, &err) == CDVR_OK &&
             shape.timesteps <= 4;
    uint8_t *payload = ok ? malloc(shape.bound_bytes) : NULL;
    const uint8_t *frames[4];
    for (size_t f = 0; payload && f < shape.timesteps; f++)
        frames[f] = cdvr_volume_frame(vol, f);
    size_t n = 0;
    ok = payload && codec->encode(&params, vol->dims, frames, shape.timesteps, payload,
                                  shape.bound_bytes, &n, &err) == CDVR_OK;
    uint8_t head[5] = {preset, (uint8_t)(vol ? vol->dims[0] - 1 : 0),
                       (uint8_t)(vol ? vol->dims[1] - 1 : 0), (uint8_t)(vol ? vol->dims[2] - 1 : 0),
                       (uint8_t)(2 * preset)};
    ok = ok && bytes_append(seed, head, 5) && bytes_append(seed, payload, n);
    CHECK(ok, "codec seed %s %s=%s", pre->codec, pre->key ? pre->key : "",
          pre->value ? pre->value : "");
    free(payload);
    cdvr_volume_free(vol);
    return ok;
}

/* hvq seed: 4 header bytes (fuzz_hvq.c) + a payload encoded for those dims. kind 0: smooth +
 * edges + zero background, 1: noise with residual 0 (a dense residual hash), 2: all zero. */
static int make_hvq_seed(bytes *seed, const uint8_t head[4], const size_t dims[3],
                         const cdvr_hvq_params *p, int kind)
{
    size_t n = dims[0] * dims[1] * dims[2], bound = 0, got = 0;
    uint8_t *v = malloc(n), *out = NULL;
    uint32_t rng = 77;
    for (size_t i = 0; v && i < n; i++) {
        size_t x = i % dims[0], y = i / dims[0] % dims[1], z = i / dims[0] / dims[1];
        int val = (int)((x * 9 + y * 5 + z * 3) % 160) + (x % 11 == 0 ? 90 : 0);
        v[i] = kind == 2 ? 0 : kind == 1 ? (uint8_t)rng_next(&rng)
                             : (uint8_t)((x / 4 + y / 4) % 3 == 0 ? 0 : val);
    }
    cdvr_error err;
    int compact = (head[0] & 4) != 0; /* fuzz_hvq.c: the compact form */
    cdvr_status st = !v ? CDVR_ERR_NOMEM : compact ? cdvr_hvq_compact_bound(p, dims, &bound, &err)
                                                   : cdvr_hvq_bound(p, dims, &bound, &err);
    out = st == CDVR_OK ? malloc(bound) : NULL;
    if (out)
        st = compact ? cdvr_hvq_encode_compact(p, NULL, dims, v, 1, out, bound, &got, NULL, &err)
                     : cdvr_hvq_encode(p, dims, v, 1, out, bound, &got, NULL, &err);
    CHECK_OK(st, err);
    /* the seed passes the decoder's check with the parameters the target will use */
    cdvr_hvq_params q;
    cdvr_hvq_params_default(&q);
    q.k1 = q.k2 = head[0] & 2 ? CDVR_HVQ_K_MAX : q.k1;
    if (out && st == CDVR_OK) {
        cdvr_status checked = compact ? cdvr_hvq_compact_check(&q, NULL, dims, out, got, NULL, &err)
                                      : cdvr_hvq_check(&q, dims, out, got, NULL, &err);
        CHECK_OK(checked, err);
    }
    int ok = out && st == CDVR_OK && bytes_append(seed, head, 4) && bytes_append(seed, out, got);
    free(v);
    free(out);
    return ok;
}

/* The crafted payload of issue 21 (n1 = 0xffffffff, huge hash offsets, residual hash side
 * 65535) made from an hvq seed: the device refuses it, and unchecked it renders without
 * reading outside the payload (the target's own checks). */
static void fuzz_hvq_cl_crafted(const bytes *seed)
{
    bytes m = {malloc(seed->n), seed->n, seed->n};
    if (!m.p)
        return;
    memcpy(m.p, seed->p, seed->n);
    uint8_t *payload = m.p + 4;
    size_t dims[3] = {1 + m.p[1] % 40u, 1 + m.p[2] % 40u, 1 + m.p[3] % 40u};
    uint64_t nb = ((dims[0] + 3) / 4) * ((dims[1] + 3) / 4) * ((dims[2] + 3) / 4);
    uint64_t c1 = (32 + nb + 7) & ~(uint64_t)7;
    uint64_t dir = (c1 + 16 * fuzz_le(payload + 16, 4) + 128 * fuzz_le(payload + 20, 4) + 7) &
                   ~(uint64_t)7;
    CHECK(!(m.p[0] & 1) && dir + 32 <= m.n - 4, "crafted hvq payload: directory at %llu",
          (unsigned long long)dir);
    if (!(m.p[0] & 1) && dir + 32 <= m.n - 4) {
        fuzz_put_le(payload + 16, 0xffffffffu, 4);
        fuzz_put_le(payload + dir + 8, 0x7ffffffffff00000ull, 8);
        fuzz_put_le(payload + dir + 16, 65535, 2);
        fuzz_put_le(payload + dir + 24, 0x7fffffff00000000ull, 8);
        fuzz_outcome_counts = (fuzz_outcomes){0, 0};
        fuzz_hvq_cl_input(m.p, m.n);
        CHECK(fuzz_outcome_counts.rejected == 1, "the crafted hvq payload is not refused");
    }
    free(m.p);
}

static int make_lzo_seed(bytes *seed)
{
    cdvr_volume *vol = make_series();
    size_t n = vol ? cdvr_volume_frame_bytes(vol) * 2 : 0, packed_n = 0;
    uint8_t *packed = vol ? malloc(cdvr_lzo_bound(n)) : NULL;
    cdvr_error err;
    uint8_t head[2] = {(uint8_t)n, (uint8_t)(n >> 8)};
    int ok = packed && cdvr_lzo_compress(vol->data, n, packed, cdvr_lzo_bound(n), &packed_n,
                                         &err) == CDVR_OK &&
             bytes_append(seed, head, 2) && bytes_append(seed, packed, packed_n);
    CHECK(ok && packed_n < n, "lzo seed: %zu -> %zu bytes", n, packed_n);
    free(packed);
    cdvr_volume_free(vol);
    return ok;
}

/* fuzz_cache.c's seeds: mode 1 and rates text (stored, loaded back, parsed), or mode 0 and
 * the entry file cdvr_cache_store writes for that text under the target's key. */
static int make_cache_seed(bytes *seed, int framed)
{
    static const char text[] = "lzo 581.0 lz4 3229.0 zstd 1146.0";
    uint8_t mode = (uint8_t)framed;
    if (framed)
        return bytes_append(seed, &mode, 1) && bytes_append(seed, text, strlen(text));
    const char *parts[] = {"fuzz cache entry"};
    char key[33], path[256];
    cdvr_cache_key(parts, 1, key);
    if (!fuzz_write_temp((const uint8_t *)text, 0, ".entry", path))
        return 0;
    cdvr_cache_store(path, key, (const unsigned char *)text, strlen(text));
    FILE *f = fopen(path, "rb");
    uint8_t file[256];
    size_t n = f ? fread(file, 1, sizeof file, f) : 0;
    if (f)
        fclose(f);
    unlink(path);
    int ok = n > 56 && bytes_append(seed, &mode, 1) && bytes_append(seed, file, n);
    CHECK(ok, "cache seed: an entry file of %zu bytes", n);
    return ok;
}

static int make_nrrd_seed(bytes *seed)
{
    const char header[] = "NRRD0004\ntype: int16\ndimension: 4\nsizes: 3 4 2 2\n"
                          "kinds: space space space time\nspace dimension: 3\n"
                          "space directions: (1.5,0,0) (0,1,0) (0,0,2) none\n"
                          "space origin: (1,2,3)\nendian: little\n"
                          "encoding: raw\n\n";
    uint8_t sel = 0, data[96];
    for (int i = 0; i < 96; i++)
        data[i] = (uint8_t)(i * 37);
    return bytes_append(seed, &sel, 1) && bytes_append(seed, header, sizeof header - 1) &&
           bytes_append(seed, data, sizeof data);
}

/* A NIfTI-1 single file: 348-byte header, 4 bytes of extension flags, int16 voxels 3x2x2x2. */
static int make_nifti_seed(bytes *seed, uint8_t sel)
{
    uint8_t hdr[352] = {0}, data[48];
    const int16_t dim[8] = {4, 3, 2, 2, 2, 1, 1, 1};
    const float pixdim[8] = {1, 1.5f, 2, 2.5f, 1, 1, 1, 1}, vox_offset = 352, slope = 1;
    fuzz_put_le(hdr, 348, 4);
    for (int i = 0; i < 8; i++)
        fuzz_put_le(hdr + 40 + 2 * i, (uint16_t)dim[i], 2);
    fuzz_put_le(hdr + 70, 4, 2);  /* datatype int16 */
    fuzz_put_le(hdr + 72, 16, 2); /* bitpix */
    memcpy(hdr + 76, pixdim, sizeof pixdim);
    memcpy(hdr + 108, &vox_offset, 4);
    memcpy(hdr + 112, &slope, 4);
    memcpy(hdr + 344, "n+1", 4);
    for (int i = 0; i < 48; i++)
        data[i] = (uint8_t)(i * 29 + 3);
    return bytes_append(seed, &sel, 1) && bytes_append(seed, hdr, sizeof hdr) &&
           bytes_append(seed, data, sizeof data);
}

static int make_raw_seed(bytes *seed)
{
    /* selector 5, dims 5x3x2, type u16 (1), little endian, 4 header bytes, 2 timesteps */
    const uint8_t head[9] = {5, 4, 2, 1, 1, 0, 4, 2, 16};
    uint8_t data[4 + 2 * 5 * 3 * 2 * 2];
    for (size_t i = 0; i < sizeof data; i++)
        data[i] = (uint8_t)(i * 13);
    return bytes_append(seed, head, sizeof head) && bytes_append(seed, data, sizeof data);
}

/* VTK seeds (fuzz_vtk.c): sel 0 a .vti of 5x3x2 Int16 (kind 0: ascii, 1: base64 inline, 2:
 * appended raw; the active scalars the second array), sel 1 a legacy .vtk (kind 3: BINARY, 4:
 * ASCII), sel 2 a MetaImage .mha (kind 5: raw big endian, 6: zlib). */
static int make_vtk_seed(bytes *seed, int kind)
{
    char text[2048];
    uint8_t sel = kind >= 5 ? 2 : kind >= 3;
    int n = 0;
    if (kind >= 5) {
        n = snprintf(text, sizeof text, "ObjectType = Image\nNDims = 3\nBinaryData = True\n"
                     "BinaryDataByteOrderMSB = True\nCompressedData = %s\nTransformMatrix = 0 1 "
                     "0 -1 0 0 0 0 1\nOffset = 1 2 3\nElementSpacing = 0.5 1 2\nDimSize = 5 3 2\n"
                     "ElementType = MET_SHORT\nElementDataFile = LOCAL\n",
                     kind == 6 ? "True" : "False");
        uint8_t raw[60], packed[128];
        for (int i = 0; i < 30; i++) {
            raw[2 * i] = (uint8_t)(((i * 1111 - 9000) >> 8) & 0xff);
            raw[2 * i + 1] = (uint8_t)((i * 1111 - 9000) & 0xff);
        }
        uLongf zn = sizeof packed;
        if (kind == 6 && compress2(packed, &zn, raw, sizeof raw, 9) != Z_OK)
            return 0;
        memcpy(text + n, kind == 6 ? packed : raw, kind == 6 ? zn : sizeof raw);
        n += kind == 6 ? (int)zn : (int)sizeof raw;
    } else if (kind < 3) {
        static const char *const fmt[] = {"ascii", "binary", "appended"};
        n = snprintf(text, sizeof text, "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" "
                     "version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt32\">\n"
                     "<ImageData WholeExtent=\"1 5 0 2 0 1\" Origin=\"1 2 3\" Spacing=\"0.5 1 2\" "
                     "Direction=\"0 -1 0 1 0 0 0 0 1\">\n<Piece Extent=\"1 5 0 2 0 1\">\n"
                     "<PointData Scalars=\"b\">\n<DataArray type=\"UInt8\" Name=\"a\" "
                     "format=\"ascii\">1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20 21 22 23 "
                     "24 25 26 27 28 29 30</DataArray>\n<DataArray type=\"Int16\" Name=\"b\" "
                     "format=\"%s\"%s>", fmt[kind], kind == 2 ? " offset=\"0\"" : "");
        uint8_t raw[4 + 60];
        fuzz_put_le(raw, 60, 4);
        for (int i = 0; i < 30; i++)
            fuzz_put_le(raw + 4 + 2 * i, (uint64_t)(i * 1111 - 9000), 2);
        if (kind == 0)
            for (int i = 0; i < 30; i++)
                n += snprintf(text + n, sizeof text - (size_t)n, " %d", i * 1111 - 9000);
        if (kind == 1) {
            static const char a[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
            for (int i = 0; i < 64; i += 3) {
                uint32_t v = (uint32_t)raw[i] << 16 | (i + 1 < 64 ? (uint32_t)raw[i + 1] << 8 : 0) |
                             (i + 2 < 64 ? raw[i + 2] : 0);
                text[n++] = a[v >> 18];
                text[n++] = a[(v >> 12) & 63];
                text[n++] = i + 1 < 64 ? a[(v >> 6) & 63] : '=';
                text[n++] = i + 2 < 64 ? a[v & 63] : '=';
            }
        }
        n += snprintf(text + n, sizeof text - (size_t)n, "</DataArray>\n</PointData>\n</Piece>\n"
                      "</ImageData>\n%s", kind == 2 ? "<AppendedData encoding=\"raw\">\n_" : "");
        if (kind == 2) {
            memcpy(text + n, raw, sizeof raw);
            n += (int)sizeof raw;
            n += snprintf(text + n, sizeof text - (size_t)n, "\n</AppendedData>\n");
        }
        n += snprintf(text + n, sizeof text - (size_t)n, "</VTKFile>\n");
    } else {
        n = snprintf(text, sizeof text, "# vtk DataFile Version 3.0\nseed\n%s\nDATASET "
                     "STRUCTURED_POINTS\nDIMENSIONS 5 3 2\nORIGIN 1 2 3\nSPACING 0.5 1 2\n"
                     "POINT_DATA 30\nSCALARS a short 1\nLOOKUP_TABLE default\n",
                     kind == 3 ? "BINARY" : "ASCII");
        for (int i = 0; i < 30; i++) {
            int v = i * 1111 - 9000;
            if (kind == 3) {
                text[n++] = (char)((v >> 8) & 0xff);
                text[n++] = (char)(v & 0xff);
            } else
                n += snprintf(text + n, sizeof text - (size_t)n, "%d ", v);
        }
        text[n++] = '\n';
    }
    return bytes_append(seed, &sel, 1) && bytes_append(seed, text, (size_t)n);
}

/* The seeds themselves load: the loader target is not rejecting everything up front. */
static void check_loader_seed(const bytes *seed, const char *suffix, size_t skip, size_t timesteps)
{
    char path[256];
    cdvr_volume *vol = NULL;
    cdvr_error err;
    cdvr_raw_opts opts;
    if (skip == 9)
        load_raw_opts(seed->p + 1, &opts);
    if (!fuzz_write_temp(seed->p + skip, seed->n - skip, suffix, path)) {
        CHECK(0, "cannot write %s seed", suffix);
        return;
    }
    cdvr_status st = cdvr_volume_load(path, skip == 9 ? &opts : NULL, &vol, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK)
        CHECK(vol->timesteps == timesteps, "%s seed: %zu timesteps", suffix, vol->timesteps);
    cdvr_volume_free(vol);
    unlink(path);
}

int main(void)
{
    bytes seed = {0};
    for (uint8_t mode = 0; mode < 4; mode++) {
        seed.n = 0;
        if (make_store_seed(&seed, mode, 0))
            fuzz_seed("store", fuzz_store_input, &seed, 600, 1, 1000u + mode);
    }
    for (uint8_t mode = 0; mode < 4; mode++) { /* levels and a shared codebook blob */
        seed.n = 0;
        if (make_store_seed(&seed, mode, 1))
            fuzz_seed("store", fuzz_store_input, &seed, 300, 1, 1100u + mode);
    }
    for (uint8_t bits = 0; bits < 8; bits++) {
        seed.n = 0;
        if (make_pvtc_seed(&seed, bits, (uint8_t)(bits % 5)))
            fuzz_seed("pvtc", fuzz_pvtc_input, &seed, 300, 1, 2000u + bits);
    }
    /* codec-table decoders; the plugins the build made must be there */
    pthread_once(&fuzz_codec_plugins_once, fuzz_codec_load_plugins);
    const char *built = getenv("CDVR_BUILT_PLUGINS");
    CHECK(!built || !strstr(built, "zfp") || cdvr_codec_find("zfp"), "zfp plugin not loaded");
    CHECK(!built || !strstr(built, "example") || cdvr_codec_find("rle"), "rle plugin not loaded");
    for (uint8_t preset = 0; preset < NPRESETS; preset++) {
        seed.n = 0;
        if (make_codec_seed(&seed, preset))
            fuzz_seed("codec", fuzz_codec_input, &seed, 300, 1, 7000u + preset);
    }
    {
        cdvr_hvq_params p;
        cdvr_hvq_params_default(&p);
        const struct {
            uint8_t head[4];
            size_t dims[3];
            double grad;
            unsigned residual, k;
            int kind;
            size_t mutations;
        } hvq_seeds[] = {{{0, 10, 8, 6}, {11, 9, 7}, 4, 10, 256, 0, 600},
                         {{1, 3, 2, 1}, {260, 3, 2}, 2, 10, 256, 0, 300},
                         {{2, 39, 35, 19}, {40, 36, 20}, 1, 10, 400, 0, 150},
                         {{0, 12, 4, 2}, {13, 5, 3}, 64, 10, 256, 2, 400},
                         {{0, 7, 7, 7}, {8, 8, 8}, 8, 0, 16, 1, 400},
                         {{4, 10, 8, 6}, {11, 9, 7}, 4, 10, 256, 0, 600},
                         {{6, 39, 35, 19}, {40, 36, 20}, 1, 10, 400, 0, 150},
                         {{4, 12, 4, 2}, {13, 5, 3}, 64, 10, 256, 2, 300},
                         {{4, 7, 7, 7}, {8, 8, 8}, 8, 0, 16, 1, 400}};
        for (size_t i = 0; i < sizeof hvq_seeds / sizeof *hvq_seeds; i++) {
            seed.n = 0;
            p.grad = hvq_seeds[i].grad;
            p.residual = hvq_seeds[i].residual;
            p.k1 = p.k2 = hvq_seeds[i].k;
            if (make_hvq_seed(&seed, hvq_seeds[i].head, hvq_seeds[i].dims, &p, hvq_seeds[i].kind))
                fuzz_seed("hvq", fuzz_hvq_input, &seed, hvq_seeds[i].mutations, 4,
                          8000u + (uint32_t)i);
            /* the OpenCL decode/fetch path (PoCL here), on as many mutants */
            if (fuzz_hvq_cl_device() && seed.n && !(hvq_seeds[i].head[0] & 4))
                fuzz_seed("hvq_cl", fuzz_hvq_cl_input, &seed, hvq_seeds[i].mutations, 4,
                          9000u + (uint32_t)i);
            if (fuzz_hvq_cl_device() && i == 0 && seed.n > 4)
                fuzz_hvq_cl_crafted(&seed);
        }
    }
    seed.n = 0;
    if (make_lzo_seed(&seed))
        fuzz_seed("lzo", fuzz_lzo_input, &seed, 2000, 0, 3000u);
    seed.n = 0;
    if (make_cache_seed(&seed, 1)) /* rates content, stored and loaded back: the parse */
        fuzz_seed("cache", fuzz_cache_input, &seed, 1500, 1, 3100u);
    seed.n = 0;
    if (make_cache_seed(&seed, 0)) /* a whole entry file: its header and checksum */
        fuzz_seed("cache", fuzz_cache_input, &seed, 1500, 1, 3200u);
    seed.n = 0;
    if (make_nrrd_seed(&seed)) {
        check_loader_seed(&seed, ".nrrd", 1, 2);
        fuzz_seed("load", fuzz_load_input, &seed, 1500, 1, 4000u);
    }
    for (uint8_t sel = 2; sel <= 4; sel++) {
        seed.n = 0;
        if (make_nifti_seed(&seed, sel)) {
            if (sel == 2)
                check_loader_seed(&seed, ".nii", 1, 2);
            fuzz_seed("load", fuzz_load_input, &seed, 700, 1, 5000u + sel);
        }
    }
    seed.n = 0;
    if (make_raw_seed(&seed)) {
        check_loader_seed(&seed, ".raw", 9, 2);
        fuzz_seed("load", fuzz_load_input, &seed, 1000, 1, 6000u);
    }
    for (int kind = 0; kind < 7; kind++) {
        seed.n = 0;
        if (make_vtk_seed(&seed, kind)) {
            check_loader_seed(&seed, kind < 3 ? ".vti" : kind < 5 ? ".vtk" : ".mha", 1, 1);
            fuzz_seed("vtk", fuzz_vtk_input, &seed, 800, 1, 10000u + (uint32_t)kind);
        }
    }
    static const char *const desc_seed[3] = { /* fuzz_desc.c: .pvd, OME-XML, ImageJ */
        "\0<?xml version=\"1.0\"?><VTKFile type=\"Collection\" version=\"0.1\"><Collection>"
        "<DataSet timestep=\"1.5\" part=\"0\" file=\"b.vti\"/>"
        "<DataSet timestep=\"0.5\" part=\"0\" file=\"a.vti\"/></Collection></VTKFile>",
        "\1<?xml version=\"1.0\"?><OME><Image ID=\"Image:0\"><Pixels DimensionOrder=\"XYZCT\" "
        "SizeX=\"4\" SizeY=\"3\" SizeZ=\"3\" SizeC=\"1\" SizeT=\"1\" PhysicalSizeX=\"500\" "
        "PhysicalSizeXUnit=\"nm\" PhysicalSizeY=\"0.25\" PhysicalSizeZ=\"2\"/></Image></OME>",
        "\2ImageJ=1.52\nimages=3\nslices=3\nunit=micron\nspacing=2.5\n"};
    for (int k = 0; k < 3; k++) {
        seed.n = 0;
        if (bytes_append(&seed, desc_seed[k], 1 + strlen(desc_seed[k] + 1)))
            fuzz_seed("desc", fuzz_desc_input, &seed, 800, 1, 11000u + (uint32_t)k);
    }
    free(seed.p);
    check_totals();
    return check_finish();
}
