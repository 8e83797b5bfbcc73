/* tests/fuzz/fuzz_hvq.c - libFuzzer target for the hvq decoders (core/codec/hvq/hvq_decode.c,
 * hvq_compact.c) through their codec tables: check, whole-frame decode and describe. How to
 * run: README.
 *
 * Input: 4 header bytes, then the payload (passed as it is).
 *   byte 0: bit 0: dims across two regions (X = 257 + byte1 % 8, Y = 1 + byte2 % 4,
 *           Z = 1 + byte3 % 4); clear: X, Y, Z = 1 + byte % 40;
 *           bit 1: parameters k1 = k2 = 4096 (else the defaults, which bound the codebooks)
 *           bit 2: the compact form (codec "hvqc"; no fetch to compare with)
 *   bytes 1..3: dims as above
 * The frame is its own exact-size allocation, so ASan sees any write past it. A payload the
 * decoder accepts must decode, voxel for voxel, to what the per-voxel fetch (the C twin of the
 * OpenCL fetch) returns (differential check), and describe's parts must add up to its size. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/codec.h"
#include "cdvr/hvq.h"
#include "fuzz_common.h"

typedef struct hvq_fuzz_sum {
    double parts;
} hvq_fuzz_sum;

static void hvq_fuzz_emit(void *ud, const char *key, double value)
{
    hvq_fuzz_sum *s = ud;
    if (strcmp(key, "blocks") && strcmp(key, "zero_blocks") && strcmp(key, "residual_voxels") &&
        strcmp(key, "residual_sum")) /* counts and the threshold: not bytes */
        s->parts += value;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 4)
        return 0;
    int compact = (data[0] & 4) != 0;
    const cdvr_codec *codec = cdvr_codec_find(compact ? "hvqc" : "hvq");
    FUZZ_ASSERT(codec != NULL);
    size_t dims[3];
    if (data[0] & 1) {
        dims[0] = 257 + data[1] % 8u;
        dims[1] = 1 + data[2] % 4u;
        dims[2] = 1 + data[3] % 4u;
    } else {
        for (int a = 0; a < 3; a++)
            dims[a] = 1 + data[1 + a] % 40u;
    }
    cdvr_codec_params blob;
    cdvr_error err;
    codec->params_default(&blob);
    if (data[0] & 2) {
        FUZZ_ASSERT(codec->params_set(&blob, "k1", "4096", &err) == CDVR_OK);
        FUZZ_ASSERT(codec->params_set(&blob, "k2", "4096", &err) == CDVR_OK);
    }
    size_t voxels = dims[0] * dims[1] * dims[2], bytes = size - 4;
    uint8_t *payload = malloc(bytes ? bytes : 1), *frame = malloc(voxels);
    if (payload && frame) {
        memcpy(payload, data + 4, bytes);
        memset(frame, 0xA5, voxels);
        uint8_t *frames[1] = {frame};
        cdvr_status st = codec->decode(&blob, dims, payload, bytes, frames, 1, &err);
        FUZZ_ASSERT(st == CDVR_OK || st == CDVR_ERR_CORRUPT);
        FUZZ_OUTCOME(st == CDVR_OK);
        hvq_fuzz_sum sum = {0};
        cdvr_status described = codec->describe(&blob, dims, payload, bytes, hvq_fuzz_emit, &sum,
                                                &err);
        FUZZ_ASSERT(described == st);
        if (st == CDVR_OK)
            FUZZ_ASSERT(sum.parts == (double)bytes);
        if (st == CDVR_OK && !compact) {
            for (size_t z = 0, i = 0; z < dims[2]; z++)
                for (size_t y = 0; y < dims[1]; y++)
                    for (size_t x = 0; x < dims[0]; x++, i++)
                        FUZZ_ASSERT(cdvr_hvq_fetch(payload, dims, x, y, z) == frame[i]);
        }
    }
    free(payload);
    free(frame);
    return 0;
}
