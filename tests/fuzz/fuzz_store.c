/* tests/fuzz/fuzz_store.c - libFuzzer target for the .cdv store reader (core/store/store.c): open,
 * then read, unpack and decode every chunk of every variant (of every resolution level), and
 * decode every timestep through cdvr_store_decode; every error is tolerated, no input may
 * crash. How to run: README.
 *
 * Input: 1 mode byte, then the file.
 *   mode bit 0: recompute the chunk CRCs and the metadata CRC before writing the file, so that
 *               mutations get past the CRC checks into the parsers and decoders behind them
 *               (stage-2 segment tables of LZ4 and zstd chunks included: cdvr_s2_unpack)
 *   mode bit 1: set the header's file size to the real one (truncations, insertions)
 * Chunks whose payload or frames exceed FUZZ_MAX_BYTES are skipped (memory, not safety). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/store.h"
#include "fuzz_common.h"
#include "store/store_format.h"

/* Where the fixup writes, per format version (the layout comment at the top of store.c). */
typedef struct store_layout {
    size_t header, variant, chunk;           /* record sizes */
    size_t nvariants_at, nchunks_at, file_bytes_at;
    size_t crc_in_chunk, offset_in_chunk, stored_in_chunk;
} store_layout;

static const store_layout STORE_V1 = {CDVR_STORE_V1_HEADER_BYTES, CDVR_STORE_V1_VARIANT_BYTES, CDVR_STORE_V1_CHUNK_BYTES,
                                      124, 128, 144, 56, 32, 40};
static const store_layout STORE_V2 = {CDVR_STORE_HEADER_BYTES, CDVR_STORE_VARIANT_BYTES, CDVR_STORE_CHUNK_BYTES,
                                      196, 200, 216, 76, 80, 88};

/* Recomputes what mode asks for, where the (possibly corrupt) layout allows. */
static void store_fixup(uint8_t *buf, size_t size, int mode)
{
    if (size < CDVR_STORE_V1_HEADER_BYTES || memcmp(buf, CDVR_STORE_MAGIC, 8) != 0)
        return;
    const store_layout *l = fuzz_le(buf + 8, 4) == 1 ? &STORE_V1 : &STORE_V2;
    if (size < l->header)
        return;
    if (mode & 2)
        fuzz_put_le(buf + l->file_bytes_at, size, 8);
    if (!(mode & 1))
        return;
    uint64_t nvariants = fuzz_le(buf + l->nvariants_at, 4), nchunks = fuzz_le(buf + l->nchunks_at, 8);
    if (nvariants > 256 || nchunks > size / l->chunk)
        return;
    size_t index = l->header + l->variant * (size_t)nvariants;
    size_t meta = index + l->chunk * (size_t)nchunks;
    if (meta > size || size - meta < 4)
        return;
    for (size_t c = 0; c < nchunks; c++) {
        uint8_t *rec = buf + index + l->chunk * c;
        uint64_t offset = fuzz_le(rec + l->offset_in_chunk, 8), stored = fuzz_le(rec + l->stored_in_chunk, 8);
        if (offset <= size && stored <= size - offset)
            fuzz_put_le(rec + l->crc_in_chunk, cdvr_crc32c(0, buf + offset, (size_t)stored), 4);
    }
    fuzz_put_le(buf + meta, cdvr_crc32c(0, buf, meta), 4);
}

/* Read, unpack and decode one chunk; errors are fine, out-of-bounds access is not. */
static void store_chunk(const cdvr_store *st, size_t v, size_t c)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    size_t voxels = (size_t)(info->raw_bytes / info->timesteps);
    if (!ci || ci->stored_bytes > FUZZ_MAX_BYTES || ci->payload_bytes > FUZZ_MAX_BYTES ||
        ci->count > 8 || voxels > FUZZ_MAX_BYTES / ci->count)
        return;
    uint8_t *stored = malloc(ci->stored_bytes ? (size_t)ci->stored_bytes : 1);
    uint8_t *payload = malloc(ci->payload_bytes ? (size_t)ci->payload_bytes : 1);
    uint8_t *frames[8] = {NULL};
    int ok = stored && payload;
    for (size_t i = 0; i < ci->count; i++)
        ok = ok && (frames[i] = malloc(voxels)) != NULL;
    cdvr_error err;
    if (ok && cdvr_store_read_chunk(st, v, c, stored, &err) == CDVR_OK &&
        cdvr_store_unpack_chunk(st, v, c, stored, payload, &err) == CDVR_OK)
        (void)cdvr_store_decode_chunk(st, v, c, payload, frames, &err);
    for (size_t i = 0; i < ci->count; i++)
        free(frames[i]);
    free(stored);
    free(payload);
}

static void store_variant(const cdvr_store *st, size_t v)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    const cdvr_variant_info *vi = cdvr_store_variant(st, v);
    FUZZ_ASSERT(vi && cdvr_store_find_variant(st, vi->name) == (int)v);
    for (size_t c = 0; c < vi->nchunks; c++)
        store_chunk(st, v, c);
    size_t voxels = (size_t)(info->raw_bytes / info->timesteps);
    for (size_t t = 0; t < info->timesteps && t < 64; t++) {
        size_t c = cdvr_store_chunk_for_time(st, v, t);
        const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
        FUZZ_ASSERT(ci && ci->t0 <= t && t - ci->t0 < ci->count);
        if (ci->payload_bytes > FUZZ_MAX_BYTES || voxels > FUZZ_MAX_BYTES / 4)
            continue;
        cdvr_volume *vol = NULL;
        cdvr_error err;
        if (cdvr_store_decode(st, v, t, &vol, &err) == CDVR_OK)
            cdvr_volume_free(vol);
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    size_t n = size - 1;
    uint8_t *file = malloc(n ? n : 1);
    char path[256];
    if (!file)
        return 0;
    memcpy(file, data + 1, n);
    store_fixup(file, n, data[0]);
    int written = fuzz_write_temp(file, n, ".cdv", path);
    free(file);
    if (!written)
        return 0;
    cdvr_store *st = NULL;
    cdvr_error err;
    int opened = cdvr_store_open(path, &st, &err) == CDVR_OK;
    FUZZ_OUTCOME(opened);
    if (opened) {
        const cdvr_store_info *info = cdvr_store_get_info(st);
        for (size_t v = 0; v < info->nvariants; v++)
            store_variant(st, v);
        FUZZ_ASSERT(cdvr_store_variant(st, info->nvariants) == NULL);
        for (size_t l = 1; l < info->nlevels; l++) { /* the embedded level stores */
            const cdvr_store *level = cdvr_store_level(st, l);
            FUZZ_ASSERT(level != NULL);
            for (size_t v = 0; v < cdvr_store_get_info(level)->nvariants; v++)
                store_variant(level, v);
        }
        cdvr_store_close(st);
    }
    unlink(path);
    return 0;
}
