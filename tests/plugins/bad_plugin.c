/* tests/plugins/bad_plugin.c - deliberately broken codec plugins for the loader's refusal
 * tests (tests/test_plugin.c, tests/lua/test_codecs.lua). The top-level CMakeLists.txt builds
 * one MODULE per case, build/tests/plugins/bad_<case>.so, with BAD_<CASE> defined:
 *   BAD_ABI         valid codec, wrong ABI version
 *   BAD_NOSYM       no cdvr_plugin_v1 symbol (exports cdvr_plugin_v0)
 *   BAD_NULL_INFO   cdvr_plugin_v1 returns NULL
 *   BAD_NULL_CODEC  info with a NULL codec
 *   BAD_CLASH_NAME  a codec called "pvtc" (built-in name)
 *   BAD_CLASH_ID    a codec with the built-in PVTC id
 *   BAD_NO_DECODE   a table without decode
 *   BAD_UNDEFINED   needs a symbol nothing defines (dlopen fails)
 *   BAD_ABI2        not bad: a valid codec "abi2" behind an ABI 2 info (two fields), which
 *                   this cdvr still loads; its table here ends with a poisoned `check`
 *                   (ABI 4), which a loader reading past an ABI 2 table would pick up
 *   BAD_PARTIAL     ABI 3: a valid codec "partial", then a format whose suffix .nrrd clashes
 *                   with the built-in NRRD format (the codec stays registered)
 * The codec itself is raw-like and valid unless the case says otherwise. */
#include <string.h>

#include "cdvr/plugin.h"

static const cdvr_codec_param_doc bad_params[] = {{NULL, NULL, NULL}};

static void bad_default(cdvr_codec_params *p)
{
    memset(p, 0, sizeof *p);
}

static cdvr_status bad_set(cdvr_codec_params *p, const char *key, const char *value,
                           cdvr_error *err)
{
    (void)p;
    (void)value;
    return cdvr_plugin_error(err, CDVR_ERR_ARG, "codec bad: unknown parameter '%s'", key);
}

static int bad_get(const cdvr_codec_params *p, const char *key, char *out, size_t n)
{
    (void)p;
    (void)key;
    (void)out;
    (void)n;
    return -1;
}

static cdvr_status bad_check(const cdvr_codec_params *p, cdvr_error *err)
{
    (void)p;
    (void)err;
    return CDVR_OK;
}

static void bad_name(const cdvr_codec_params *p, char *name, size_t n)
{
    (void)p;
    strncpy(name, "bad", n);
    name[n - 1] = '\0';
}

static cdvr_status bad_shape(const cdvr_codec_params *p, const size_t dims[3],
                             cdvr_codec_shape *out, cdvr_error *err)
{
    (void)p;
    (void)err;
    out->timesteps = 1;
    out->payload_bytes = out->bound_bytes = dims[0] * dims[1] * dims[2];
    return CDVR_OK;
}

static cdvr_status bad_encode(const cdvr_codec_params *p, const size_t dims[3],
                              const uint8_t *const *frames, size_t count, uint8_t *out,
                              size_t out_cap, size_t *out_bytes, cdvr_error *err)
{
    (void)p;
    (void)count;
    (void)out_cap;
    (void)err;
    *out_bytes = dims[0] * dims[1] * dims[2];
    memcpy(out, frames[0], *out_bytes);
    return CDVR_OK;
}

#if defined(BAD_UNDEFINED)
extern int cdvr_test_symbol_nobody_defines(void);
#endif

static cdvr_status bad_decode(const cdvr_codec_params *p, const size_t dims[3],
                              const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                              size_t count, cdvr_error *err)
{
    (void)p;
    (void)count;
#if defined(BAD_UNDEFINED)
    if (cdvr_test_symbol_nobody_defines())
        return CDVR_ERR_ARG;
#endif
    if (in_bytes != dims[0] * dims[1] * dims[2])
        return cdvr_plugin_error(err, CDVR_ERR_CORRUPT, "codec bad: size");
    memcpy(frames[0], in, in_bytes);
    return CDVR_OK;
}

#if defined(BAD_CLASH_NAME)
#define BAD_CODEC_NAME "pvtc"
#elif defined(BAD_ABI2)
#define BAD_CODEC_NAME "abi2"
#elif defined(BAD_PARTIAL)
#define BAD_CODEC_NAME "partial"
#else
#define BAD_CODEC_NAME "bad"
#endif
#if defined(BAD_CLASH_ID)
#define BAD_CODEC_ID CDVR_CODEC_ID_PVTC
#elif defined(BAD_ABI2)
#define BAD_CODEC_ID 0x41424932u /* "ABI2" */
#elif defined(BAD_PARTIAL)
#define BAD_CODEC_ID 0x50415254u /* "PART" */
#else
#define BAD_CODEC_ID 0x42414400u /* "BAD\0" */
#endif

#if defined(BAD_ABI2)
/* Past the end of an ABI-2 table: never to be read by the loader. */
static cdvr_status poisoned_check(const cdvr_codec_params *p, const size_t dims[3],
                                  const uint8_t *payload, size_t bytes, cdvr_error *err)
{
    (void)p, (void)dims, (void)payload, (void)bytes;
    return cdvr_plugin_error(err, CDVR_ERR_CORRUPT, "the loader read past an ABI-2 table");
}
static cdvr_status poisoned_cells(const cdvr_codec_params *p, const size_t dims[3],
                                  const uint8_t *in, size_t in_bytes, uint8_t *frame,
                                  unsigned layout, const uint8_t *need, unsigned cell_log2,
                                  cdvr_error *err)
{
    (void)p, (void)dims, (void)in, (void)in_bytes, (void)frame, (void)layout, (void)need,
        (void)cell_log2;
    return cdvr_plugin_error(err, CDVR_ERR_CORRUPT, "the loader read past an ABI-2 table");
}
#endif

static const cdvr_codec bad_codec = {
    .name = BAD_CODEC_NAME,
    .id = BAD_CODEC_ID,
    .description = "a test plugin that must be refused",
    .params = bad_params,
    .params_default = bad_default,
    .params_set = bad_set,
    .params_get = bad_get,
    .params_check = bad_check,
    .variant_name = bad_name,
    .shape = bad_shape,
    .encode = bad_encode,
#if !defined(BAD_NO_DECODE)
    .decode = bad_decode,
#endif
    .cl_mode = CDVR_CODEC_CL_NONE,
#if defined(BAD_ABI2)
    .check = poisoned_check,
    .decode_cells = poisoned_cells,
#endif
};

#if defined(BAD_ABI)
static const cdvr_plugin_info bad_info = {.abi = 42u, .codec = &bad_codec}; /* never real */
#elif defined(BAD_NULL_CODEC)
static const cdvr_plugin_info bad_info = {.abi = CDVR_PLUGIN_ABI, .codec = NULL};
static const cdvr_codec *const unused_codec = &bad_codec;
#elif defined(BAD_ABI2)
/* What a plugin built against ABI 2's header returns: only these two fields exist. */
static const struct {
    uint32_t abi;
    const cdvr_codec *codec;
} bad_info_v2 = {2u, &bad_codec};
#define BAD_INFO_PTR ((const cdvr_plugin_info *)(const void *)&bad_info_v2)
#elif defined(BAD_PARTIAL)
static cdvr_status bad_probe(const char *path, const cdvr_raw_opts *o, cdvr_volume *h,
                             cdvr_error *err)
{
    (void)o, (void)h;
    return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: never", path);
}
static cdvr_status bad_read(const char *path, const cdvr_raw_opts *o, const cdvr_volume *h,
                            void *voxels, cdvr_error *err)
{
    (void)o, (void)h, (void)voxels;
    return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: never", path);
}
static const char *const bad_suffixes[] = {".nrrd", NULL};
static const cdvr_format bad_format = {.name = "partial", .description = "clashes",
                                       .suffixes = bad_suffixes, .probe = bad_probe,
                                       .read = bad_read};
static const cdvr_format *const bad_formats[] = {&bad_format, NULL};
static const cdvr_plugin_info bad_info = {.abi = CDVR_PLUGIN_ABI, .codec = &bad_codec,
                                          .formats = bad_formats};
#else
static const cdvr_plugin_info bad_info = {.abi = CDVR_PLUGIN_ABI, .codec = &bad_codec};
#endif
#ifndef BAD_INFO_PTR
#define BAD_INFO_PTR (&bad_info)
#endif

#if defined(BAD_NOSYM)
#define BAD_ENTRY cdvr_plugin_v0
#else
#define BAD_ENTRY cdvr_plugin_v1
#endif

CDVR_PLUGIN_EXPORT const cdvr_plugin_info *BAD_ENTRY(void);
CDVR_PLUGIN_EXPORT const cdvr_plugin_info *BAD_ENTRY(void)
{
    (void)bad_decode;
#if defined(BAD_NULL_CODEC)
    (void)unused_codec;
#endif
#if defined(BAD_NULL_INFO)
    (void)bad_info;
    return NULL;
#else
    return BAD_INFO_PTR;
#endif
}
