/* tests/fuzz/fuzz_codec.c - libFuzzer target for codec decoders reached through the codec
 * table (cdvr/codec.h), above all the plugin codecs (zfp, rle) whose decoders read stored
 * payloads. How to run: README (plugins come from CDVR_PLUGIN_PATH, else
 * $CDVR_BINARY_DIR/plugins).
 *
 * Input: 5 header bytes, then the payload.
 *   byte 0: preset (codec and one parameter), index into PRESETS modulo its length; a preset
 *           whose codec is not loaded is skipped
 *   bytes 1..3: X, Y, Z = 1 + byte % 24
 *   byte 4: bit 0 set: the rest is the payload with its own length (exercises the size
 *           checks); clear: the rest is repeated (or cut) to the codec's fixed payload size
 *           when it has one
 * The payload ends exactly at a page followed by an inaccessible page, so a decoder (or a
 * library under it, such as libzfp, which no sanitizer instruments) reading past it faults;
 * every frame is its own exact-size allocation. Each decode runs twice and must give the same
 * status and bytes (determinism). Status must be CDVR_OK or CDVR_ERR_CORRUPT. */
#include <pthread.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <unistd.h>

#include "cdvr/codec.h"
#include "cdvr/plugin.h"
#include "fuzz_common.h"

typedef struct codec_preset {
    const char *codec, *key, *value;
} codec_preset;

static const codec_preset PRESETS[] = {
    {"zfp", "rate", "0.5"},      {"zfp", "rate", "1"},   {"zfp", "rate", "2"},
    {"zfp", "rate", "4"},        {"zfp", "rate", "16"},  {"zfp", "rate", "0.015625"},
    {"zfp", "rate", "1.515625"}, {"rle", "bits", "8"},   {"rle", "bits", "3"},
    {"raw", NULL, NULL},         {"pvtc", "S", "1"},     {"pvtc", "pack", "space"}};
#define NPRESETS (sizeof PRESETS / sizeof PRESETS[0])

/* Plugins, loaded once: $CDVR_PLUGIN_PATH, else $CDVR_BINARY_DIR/plugins. */
static pthread_once_t fuzz_codec_plugins_once = PTHREAD_ONCE_INIT;

static void fuzz_codec_load_plugins(void)
{
    const char *path = getenv("CDVR_PLUGIN_PATH"), *bin = getenv("CDVR_BINARY_DIR");
    char dir[4096];
    if (!path && bin && snprintf(dir, sizeof dir, "%s/plugins", bin) < (int)sizeof dir)
        path = dir;
    if (path)
        cdvr_plugin_load_dirs(path, NULL, NULL);
}

/* n bytes of src placed so that they end where an inaccessible page begins. *base and *span
 * are what to munmap. NULL on failure. */
static uint8_t *fuzz_guarded_copy(const uint8_t *src, size_t n, void **base, size_t *span)
{
    size_t page = (size_t)sysconf(_SC_PAGESIZE), body = (n + page - 1) / page * page;
    *span = body + page;
    *base = mmap(NULL, *span, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (*base == MAP_FAILED)
        return NULL;
    uint8_t *guard = (uint8_t *)*base + body;
    if (mprotect(guard, page, PROT_NONE) != 0) {
        munmap(*base, *span);
        return NULL;
    }
    uint8_t *p = guard - n;
    if (n)
        memcpy(p, src, n);
    return p;
}

/* The payload to decode: the rest as it is, or repeated/cut to the fixed size. */
static uint8_t *fuzz_codec_payload(const uint8_t *rest, size_t rest_n, size_t want, size_t *out_n)
{
    size_t n = want ? want : rest_n;
    uint8_t *p = malloc(n ? n : 1);
    if (!p)
        return NULL;
    for (size_t i = 0; i < n; i++)
        p[i] = i < rest_n ? rest[i] : rest_n ? rest[i % rest_n] : (uint8_t)i;
    *out_n = n;
    return p;
}

typedef struct fuzz_codec_frames {
    uint8_t *frame[4];
    size_t n;
} fuzz_codec_frames;

static int fuzz_codec_frames_alloc(fuzz_codec_frames *f, size_t n, size_t voxels)
{
    f->n = n;
    int ok = 1;
    for (size_t i = 0; i < n; i++) {
        f->frame[i] = malloc(voxels);
        ok = ok && f->frame[i];
        if (f->frame[i])
            memset(f->frame[i], 0xA5, voxels);
    }
    return ok;
}

static void fuzz_codec_frames_free(fuzz_codec_frames *f)
{
    for (size_t i = 0; i < f->n; i++)
        free(f->frame[i]);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    pthread_once(&fuzz_codec_plugins_once, fuzz_codec_load_plugins);
    if (size < 5)
        return 0;
    const codec_preset *pre = &PRESETS[data[0] % NPRESETS];
    const cdvr_codec *codec = cdvr_codec_find(pre->codec);
    if (!codec)
        return 0;
    const size_t dims[3] = {1 + data[1] % 24u, 1 + data[2] % 24u, 1 + data[3] % 24u};
    const size_t voxels = dims[0] * dims[1] * dims[2];
    cdvr_codec_params params;
    cdvr_codec_shape shape;
    cdvr_error err;
    const char *keys[1] = {pre->key}, *values[1] = {pre->value};
    if (cdvr_codec_params_parse(codec, keys, values, pre->key ? 1 : 0, &params, &err) != CDVR_OK ||
        cdvr_codec_shape_of(codec, &params, dims, &shape, &err) != CDVR_OK || shape.timesteps > 4)
        abort(); /* the presets are valid and the dims small */
    size_t n = 0;
    uint8_t *payload = fuzz_codec_payload(data + 5, size - 5,
                                          data[4] & 1 ? 0 : shape.payload_bytes, &n);
    void *base = NULL;
    size_t span = 0;
    uint8_t *guarded = payload ? fuzz_guarded_copy(payload, n, &base, &span) : NULL;
    size_t count = 1 + data[4] / 2 % shape.timesteps;
    fuzz_codec_frames a = {{NULL}, 0}, b = {{NULL}, 0};
    if (guarded && fuzz_codec_frames_alloc(&a, count, voxels) &&
        fuzz_codec_frames_alloc(&b, count, voxels)) {
        cdvr_status s1 = codec->decode(&params, dims, guarded, n, a.frame, count, &err);
        cdvr_status s2 = codec->decode(&params, dims, guarded, n, b.frame, count, &err);
        FUZZ_ASSERT(s1 == CDVR_OK || s1 == CDVR_ERR_CORRUPT);
        FUZZ_OUTCOME(s1 == CDVR_OK);
        FUZZ_ASSERT(s1 == s2);
        for (size_t f = 0; s1 == CDVR_OK && f < count; f++)
            FUZZ_ASSERT(memcmp(a.frame[f], b.frame[f], voxels) == 0);
    }
    fuzz_codec_frames_free(&a);
    fuzz_codec_frames_free(&b);
    if (guarded)
        munmap(base, span);
    free(payload);
    return 0;
}
