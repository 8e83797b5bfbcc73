/* tests/fuzz/fuzz_cache.c - libFuzzer target for the on-disk cache (cdvr/cache.h) and the
 * stage-2 unpack rates it holds (cdvr_s2_rates_parse). How to run: README.
 *
 * Input: a mode byte, then bytes. Mode bit 0 clear: the bytes are an entry file, read by
 * cdvr_cache_load against a fixed key (a short, foreign, damaged or overlong entry reads as
 * absent, and nothing is read past the file); set: the bytes are stored as an entry's content
 * (cdvr_cache_store) and must load back unchanged. Loaded content is then parsed as stage-2
 * rates, which lie in range whenever the parse accepts them. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/cache.h"
#include "codec/stage2/stage2.h"
#include "fuzz_common.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1)
        return 0;
    const char *parts[] = {"fuzz cache entry"};
    char key[33], path[256];
    cdvr_cache_key(parts, 1, key);
    const uint8_t *body = data + 1;
    size_t n = size - 1, got = 0;
    int framed = data[0] & 1;
    if (!fuzz_write_temp(body, framed ? 0 : n, ".entry", path))
        return 0;
    if (framed)
        cdvr_cache_store(path, key, body, n);
    unsigned char *content = cdvr_cache_load(path, key, &got);
    unlink(path);
    if (framed && n > 0)
        FUZZ_ASSERT(content && got == n && memcmp(content, body, n) == 0);
    cdvr_s2_rates rates;
    int parsed = content && cdvr_s2_rates_parse(content, got, &rates);
    for (unsigned c = CDVR_S2_LZO; parsed && c < CDVR_S2_CODECS; c++)
        FUZZ_ASSERT(rates.mbps[c] > 0 && rates.mbps[c] < 1e9);
    FUZZ_OUTCOME(parsed);
    free(content);
    return 0;
}
