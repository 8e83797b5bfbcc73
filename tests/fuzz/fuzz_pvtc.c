/* tests/fuzz/fuzz_pvtc.c - libFuzzer target for the PVTC chunk decoder (core/codec/pvtc/pvtc.c and its
 * SSSE3/AVX2 paths). How to run: README.
 *
 * Input: 5 header bytes, then the chunk.
 *   byte 0: bit 0 S (1 or 4), bit 1 T (2 or 3), bit 2 pack (time/space), bits 3..5 decode
 *           path (mod 5: auto, reference, portable, ssse3, avx2), bits 6..7 frames wanted
 *   bytes 1..3: X, Y, Z = 1 + byte % 40
 *   byte 4: bit 0 set: the rest is passed with its own length (exercises the size check);
 *           clear: the rest is repeated (or cut) to exactly the chunk size
 * Every frame is its own exact-size allocation, so ASan sees any write past it. A path other
 * than the reference must give the reference's bytes (differential check). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "codec/pvtc/pvtc_internal.h"
#include "cdvr/pvtc.h"
#include "fuzz_common.h"

typedef struct pvtc_frames {
    uint8_t *frame[3];
} pvtc_frames;

static int pvtc_frames_alloc(pvtc_frames *f, size_t voxels)
{
    int ok = 1;
    for (int i = 0; i < 3; i++) {
        f->frame[i] = malloc(voxels);
        ok = ok && f->frame[i];
        if (f->frame[i])
            memset(f->frame[i], 0xA5, voxels);
    }
    return ok;
}

static void pvtc_frames_free(pvtc_frames *f)
{
    for (int i = 0; i < 3; i++)
        free(f->frame[i]);
}

/* The chunk to decode: exactly chunk_bytes (rest repeated or cut), or rest as it is. */
static uint8_t *pvtc_chunk_from(const uint8_t *rest, size_t rest_n, int as_is, size_t chunk_bytes,
                                size_t *out_n)
{
    size_t n = as_is ? rest_n : chunk_bytes;
    uint8_t *chunk = malloc(n ? n : 1);
    if (!chunk)
        return NULL;
    for (size_t i = 0; i < n; i++)
        chunk[i] = as_is ? rest[i] : rest_n ? rest[i % rest_n] : (uint8_t)i;
    *out_n = n;
    return chunk;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 5)
        return 0;
    const cdvr_pvtc_params params = {data[0] & 1 ? 4 : 1, data[0] & 2 ? 3 : 2,
                                     data[0] & 4 ? CDVR_PACK_SPACE : CDVR_PACK_TIME};
    const pvtc_decode_path path = (pvtc_decode_path)(((data[0] >> 3) & 7) % 5);
    const size_t nframes = (size_t)(data[0] >> 6), dims[3] = {1 + data[1] % 40u,
                                                                1 + data[2] % 40u,
                                                                1 + data[3] % 40u};
    cdvr_pvtc_geometry geom;
    cdvr_error err;
    if (cdvr_pvtc_geometry_get(&params, dims, &geom, &err) != CDVR_OK)
        abort(); /* valid parameters and small dims always have a geometry */
    size_t chunk_n = 0, voxels = dims[0] * dims[1] * dims[2];
    uint8_t *chunk = pvtc_chunk_from(data + 5, size - 5, data[4] & 1, geom.chunk_bytes, &chunk_n);
    pvtc_frames out = {{NULL}}, ref = {{NULL}};
    if (chunk && pvtc_frames_alloc(&out, voxels) && pvtc_frames_alloc(&ref, voxels)) {
        cdvr_status st = pvtc_decode_chunk_path(&params, dims, chunk, chunk_n, out.frame, nframes,
                                                path, &err);
        cdvr_status st_ref = pvtc_decode_chunk_path(&params, dims, chunk, chunk_n, ref.frame,
                                                    nframes, PVTC_DECODE_REFERENCE, &err);
        FUZZ_OUTCOME(st_ref == CDVR_OK);
        if (st != CDVR_ERR_UNSUPPORTED)
            FUZZ_ASSERT(st == st_ref);
        for (int i = 0; st == CDVR_OK && i < 3; i++)
            FUZZ_ASSERT(memcmp(out.frame[i], ref.frame[i], voxels) == 0);
    }
    pvtc_frames_free(&out);
    pvtc_frames_free(&ref);
    free(chunk);
    return 0;
}
