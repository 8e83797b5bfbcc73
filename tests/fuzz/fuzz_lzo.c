/* tests/fuzz/fuzz_lzo.c - libFuzzer target for stage 2 (core/codec/stage2/stage2.h). How to run: README.
 *
 * Input: 2 bytes expected payload size (little endian, 0..65535), then LZO1X data. The data
 * is decompressed into a buffer of exactly that size (ASan sees any overrun). Then the same
 * bytes are compressed and decompressed again: the round trip must give them back. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "codec/stage2/stage2.h"
#include "fuzz_common.h"

static void lzo_round_trip(const uint8_t *data, size_t size)
{
    size_t bound = cdvr_lzo_bound(size), packed_n = 0;
    uint8_t *packed = malloc(bound ? bound : 1), *back = malloc(size ? size : 1);
    cdvr_error err;
    if (packed && back &&
        cdvr_lzo_compress(data, size, packed, bound, &packed_n, &err) == CDVR_OK) {
        FUZZ_ASSERT(packed_n <= bound);
        FUZZ_ASSERT(cdvr_lzo_decompress(packed, packed_n, back, size, &err) == CDVR_OK);
        FUZZ_ASSERT(memcmp(back, data, size) == 0);
        (void)cdvr_lzo_keep(size, packed_n, 0.1);
    }
    free(packed);
    free(back);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 2)
        return 0;
    size_t expect = (size_t)fuzz_le(data, 2);
    uint8_t *out = malloc(expect ? expect : 1);
    cdvr_error err;
    if (out)
        FUZZ_OUTCOME(cdvr_lzo_decompress(data + 2, size - 2, out, expect, &err) == CDVR_OK);
    free(out);
    lzo_round_trip(data + 2, size - 2);
    return 0;
}
