/* plugins/example/example.c - the smallest complete codec plugin, and the guide to writing one.
 *
 * The codec: "rle", run-length coding of u8 voxels, optionally quantised first.
 *   Parameter bits (1..8, default 8): high bits kept per voxel. 8 is lossless; with fewer, a
 *   voxel v becomes the middle of its bin, q(v) = (v >> s << s) | (s ? 1 << (s - 1) : 0) with
 *   s = 8 - bits, so |q(v) - v| <= 2^(s-1) and runs get longer.
 *   Chunk: one timestep. Payload: pairs of bytes (n - 1, value), a run of n = 1..256 voxels of
 *   value, in file order (x fastest, then y, then z), covering the frame exactly.
 *
 * Writing a plugin
 * ----------------
 * 1. Include only cdvr/plugin.h (it includes cdvr/codec.h, the contract: read its top comment).
 *    Call no libcdvr function: your .so is loaded into programs that link libcdvr statically
 *    without exporting it. Use cdvr_plugin_error() for errors and the inline
 *    cdvr_params_get_u32/set_u32/get_f64/set_f64 for the parameter blob.
 * 2. Fill one `static const cdvr_codec` table (bottom of this file) and return it from
 *    cdvr_plugin_v1() with CDVR_PLUGIN_ABI. Build it as a MODULE library with hidden
 *    visibility (plugins/CMakeLists.txt: cdvr_add_plugin) so that only cdvr_plugin_v1 is
 *    exported.
 * 3. Name: 1..15 characters of [a-z0-9_], unique among loaded codecs. Id: a number below 2^31
 *    that no other codec uses; stores record it, so never change it once data exists. A
 *    four-letter ASCII tag with a clear top bit keeps clashes unlikely ("RLE\0" here).
 * 4. The parameter blob (cdvr_codec_params, CDVR_CODEC_PARAMS_MAX bytes) is written into
 *    stores as it is, so its layout is a file format: fixed-width little-endian fields at fixed
 *    offsets (use the cdvr_params_* helpers), every unused byte 0, and params_check refusing
 *    anything else. Here: offset 0, u32 bits.
 * 5. The decoder is the definition of the codec. It gets bytes from a file: it must never read
 *    or write outside in[0 .. in_bytes) and the count frames of dims[0]*dims[1]*dims[2] bytes,
 *    whatever the payload holds, and must return CDVR_ERR_CORRUPT for any payload that does
 *    not describe exactly those frames (here: odd size, a run past the end, too few voxels).
 *    The fuzz smoke test (tests/test_fuzz_smoke.c) feeds it mutated payloads.
 * 6. Threads: every function may run on several threads at once for different chunks (the
 *    encoder runs chunks in parallel). Keep no mutable static state; allocate per call.
 * 7. Test it through the codec table: add it to the round-trip table of tests/test_codec.c.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/plugin.h"

#define RLE_CODEC_ID 0x524C4500u /* "RLE\0" */
#define RLE_MAX_RUN 256

enum { OFF_BITS = 0, USED_BYTES = 4 }; /* blob layout: u32 bits at offset 0 */

/* What cdvr.codecs() shows: every key params_set accepts, its default and what it does. */
static const cdvr_codec_param_doc rle_params[] = {
    {"bits", "8", "high bits kept per voxel, 1..8 (8: lossless; else error <= 2^(7-bits))"},
    {NULL, NULL, NULL}};

/* params_default: the blob for "no parameters given"; must pass params_check. */
static void rle_default(cdvr_codec_params *p)
{
    memset(p, 0, sizeof *p);
    cdvr_params_set_u32(p, OFF_BITS, 8);
}

/* params_set: one key=value from text (Lua's codec options); refuse unknown keys and bad
 * values naming the key, the value and what is accepted. */
static cdvr_status rle_set(cdvr_codec_params *p, const char *key, const char *value,
                           cdvr_error *err)
{
    if (strcmp(key, "bits") != 0)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec rle: unknown parameter '%s' "
                                 "(parameters: bits)", key);
    char *end;
    long bits = strtol(value, &end, 10);
    if (!*value || *end || bits < 1 || bits > 8)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec rle: bits = '%s', must be an integer "
                                 "from 1 to 8", value);
    cdvr_params_set_u32(p, OFF_BITS, (uint32_t)bits);
    return CDVR_OK;
}

/* params_get: the value as text that params_set reads back to the same blob; -1 if unknown. */
static int rle_get(const cdvr_codec_params *p, const char *key, char *out, size_t n)
{
    if (strcmp(key, "bits") != 0)
        return -1;
    snprintf(out, n, "%u", cdvr_params_get_u32(p, OFF_BITS));
    return 0;
}

/* params_check: the whole blob, which may come from a damaged file. */
static cdvr_status rle_check(const cdvr_codec_params *p, cdvr_error *err)
{
    uint32_t bits = cdvr_params_get_u32(p, OFF_BITS);
    if (bits < 1 || bits > 8)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec rle: bits = %u, must be 1..8", bits);
    for (size_t i = USED_BYTES; i < CDVR_CODEC_PARAMS_MAX; i++)
        if (p->bytes[i])
            return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec rle: unused parameter byte %zu "
                                     "is %u", i, p->bytes[i]);
    return CDVR_OK;
}

/* variant_name: short, distinct for distinct parameters ("rle8", "rle4"). */
static void rle_name(const cdvr_codec_params *p, char *name, size_t n)
{
    snprintf(name, n, "rle%u", cdvr_params_get_u32(p, OFF_BITS));
}

/* Voxels of one frame, or 0 when the count overflows what a payload bound can hold. */
static size_t frame_voxels(const size_t dims[3])
{
    size_t n = 1;
    for (int a = 0; a < 3; a++) {
        if (dims[a] == 0 || n > SIZE_MAX / 2 / dims[a])
            return 0;
        n *= dims[a];
    }
    return n;
}

/* shape: timesteps per chunk, the exact payload size if the parameters fix it (0 here: it
 * depends on the data) and the worst case, which the encoder allocates. */
static cdvr_status rle_shape(const cdvr_codec_params *p, const size_t dims[3],
                             cdvr_codec_shape *out, cdvr_error *err)
{
    (void)p;
    size_t voxels = frame_voxels(dims);
    if (!voxels)
        return cdvr_plugin_error(err, CDVR_ERR_NOMEM, "codec rle: dims %zux%zux%zu overflow "
                                 "size_t", dims[0], dims[1], dims[2]);
    out->timesteps = 1;
    out->payload_bytes = 0;
    out->bound_bytes = 2 * voxels; /* every run of length 1 */
    return CDVR_OK;
}

/* A voxel quantised to its bin's middle: s low bits dropped, mid = 2^(s-1) (0 when s = 0). */
static uint8_t quantise(uint8_t v, unsigned s, uint8_t mid)
{
    return (uint8_t)((v >> s << s) | mid);
}

/* encode: frames[0 .. shape.timesteps) with count of them real (always 1 here); out has
 * out_cap >= shape.bound_bytes bytes. */
static cdvr_status rle_encode(const cdvr_codec_params *p, const size_t dims[3],
                              const uint8_t *const *frames, size_t count, uint8_t *out,
                              size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    size_t voxels = frame_voxels(dims);
    if (count != 1 || !voxels || out_cap / 2 < voxels)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec rle: %zu frames of %zux%zux%zu into "
                                 "%zu bytes", count, dims[0], dims[1], dims[2], out_cap);
    unsigned s = 8 - cdvr_params_get_u32(p, OFF_BITS);
    uint8_t mid = s ? (uint8_t)(1u << (s - 1)) : 0;
    const uint8_t *v = frames[0];
    size_t n = 0;
    for (size_t i = 0; i < voxels;) {
        uint8_t q = quantise(v[i], s, mid);
        size_t run = 1;
        while (i + run < voxels && run < RLE_MAX_RUN && quantise(v[i + run], s, mid) == q)
            run++;
        out[n++] = (uint8_t)(run - 1);
        out[n++] = q;
        i += run;
    }
    *out_bytes = n;
    return CDVR_OK;
}

/* decode: count frames (1 .. shape.timesteps); refuse whatever does not fit exactly. */
static cdvr_status rle_decode(const cdvr_codec_params *p, const size_t dims[3],
                              const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                              size_t count, cdvr_error *err)
{
    (void)p;
    size_t voxels = frame_voxels(dims);
    if (count != 1 || !voxels)
        return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec rle: %zu frames of %zux%zux%zu",
                                 count, dims[0], dims[1], dims[2]);
    if (in_bytes % 2)
        return cdvr_plugin_error(err, CDVR_ERR_CORRUPT, "codec rle: odd payload size %zu",
                                 in_bytes);
    uint8_t *dst = frames[0];
    size_t filled = 0;
    for (size_t k = 0; k < in_bytes; k += 2) {
        size_t run = (size_t)in[k] + 1;
        if (run > voxels - filled)
            return cdvr_plugin_error(err, CDVR_ERR_CORRUPT, "codec rle: run of %zu at voxel %zu "
                                     "goes past the frame's %zu voxels", run, filled, voxels);
        memset(dst + filled, in[k + 1], run);
        filled += run;
    }
    if (filled != voxels)
        return cdvr_plugin_error(err, CDVR_ERR_CORRUPT, "codec rle: payload covers %zu of %zu "
                                 "voxels", filled, voxels);
    return CDVR_OK;
}

static const cdvr_codec rle_codec = {
    .name = "rle",              /* registry key: codec="rle" in Lua */
    .id = RLE_CODEC_ID,         /* recorded in stores; never change it */
    .description = "run-length coding of u8 voxels, optionally quantised (example plugin)",
    .params = rle_params,       /* documented keys, {NULL} terminated */
    .params_default = rle_default,
    .params_set = rle_set,
    .params_get = rle_get,
    .params_check = rle_check,
    .variant_name = rle_name,
    .shape = rle_shape,
    .encode = rle_encode,
    .decode = rle_decode,
    .describe = NULL,           /* optional per-chunk figures for st:info() */
    .cl_mode = CDVR_CODEC_CL_NONE, /* no OpenCL: the player decodes on the CPU and uploads;
                                      see cdvr/codec.h for CL_DECODE and CL_FETCH */
};

static const cdvr_plugin_info rle_plugin = {.abi = CDVR_PLUGIN_ABI, .codec = &rle_codec};

/* The one exported symbol. cdvr calls it once after dlopen. */
CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void);
CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void)
{
    return &rle_plugin;
}
