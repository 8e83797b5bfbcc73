/* tests/test_crc32c.c - CRC-32C known vectors, incremental use, hardware == portable path
 * (also across the hardware path's three interleaved blocks of 8192 bytes). */
#include "check.h"

#include "base/crc32c.h"
#include "cdvr/crc32c.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static void test_known_vectors(void)
{
    CHECK(cdvr_crc32c(0, "123456789", 9) == 0xE3069283u, "got 0x%08x",
          cdvr_crc32c(0, "123456789", 9));
    CHECK(cdvr_crc32c_portable(0, "123456789", 9) == 0xE3069283u, "portable path");
    CHECK(cdvr_crc32c(0, "", 0) == 0, "empty input keeps the initial value");
    /* RFC 3720 (iSCSI) B.4: 32 bytes of zeros, of 0xff, and ascending 0..31. */
    uint8_t buf[32];
    memset(buf, 0, sizeof buf);
    CHECK(cdvr_crc32c(0, buf, 32) == 0x8A9136AAu, "zeros: 0x%08x", cdvr_crc32c(0, buf, 32));
    memset(buf, 0xff, sizeof buf);
    CHECK(cdvr_crc32c(0, buf, 32) == 0x62A8AB43u, "ones: 0x%08x", cdvr_crc32c(0, buf, 32));
    for (int i = 0; i < 32; i++)
        buf[i] = (uint8_t)i;
    CHECK(cdvr_crc32c(0, buf, 32) == 0x46DD794Eu, "ascending: 0x%08x", cdvr_crc32c(0, buf, 32));
    for (int i = 0; i < 32; i++)
        buf[i] = (uint8_t)(31 - i);
    CHECK(cdvr_crc32c(0, buf, 32) == 0x113FDB5Cu, "descending: 0x%08x", cdvr_crc32c(0, buf, 32));
}

static void test_incremental_and_paths(void)
{
    uint8_t data[1031];
    uint32_t x = 12345;
    for (size_t i = 0; i < sizeof data; i++) {
        x = x * 1103515245u + 12345u;
        data[i] = (uint8_t)(x >> 16);
    }
    uint32_t whole = cdvr_crc32c(0, data, sizeof data);
    for (size_t split = 0; split <= sizeof data; split += 37) {
        uint32_t part = cdvr_crc32c(cdvr_crc32c(0, data, split), data + split, sizeof data - split);
        CHECK(part == whole, "split at %zu", split);
    }
    for (size_t off = 0; off < 9; off++) /* unaligned starts and odd tails */
        for (size_t n = 0; n < 40; n++)
            CHECK(cdvr_crc32c(0, data + off, n) == cdvr_crc32c_portable(0, data + off, n),
                  "offset %zu length %zu", off, n);
    data[500] ^= 1;
    CHECK(cdvr_crc32c(0, data, sizeof data) != whole, "a flipped bit changes the CRC");
}

/* Lengths around the hardware path's rounds of 3 x 8192 bytes (one round, several, a round
 * and a tail), from unaligned starts, split anywhere: the same value as the byte-wise table.
 * Then a flipped bit in each of the three blocks of a round changes the value. */
static void test_interleaved_rounds(void)
{
    enum { ROUND = 3 * 8192, BYTES = 5 * ROUND + 64 };
    uint8_t *data = malloc(BYTES);
    CHECK(data != NULL, "no memory");
    if (!data)
        return;
    uint32_t x = 987654321u;
    for (size_t i = 0; i < BYTES; i++) {
        x = x * 1664525u + 1013904223u;
        data[i] = (uint8_t)(x >> 24);
    }
    const size_t lengths[] = {ROUND - 1, ROUND, ROUND + 1, ROUND + 7, ROUND + 8,
                              2 * ROUND - 3, 2 * ROUND, 2 * ROUND + 4099, 5 * ROUND};
    for (size_t k = 0; k < sizeof lengths / sizeof lengths[0]; k++)
        for (size_t off = 0; off < 9; off += 3) {
            size_t n = lengths[k];
            uint32_t want = cdvr_crc32c_portable(0, data + off, n);
            CHECK(cdvr_crc32c(0, data + off, n) == want, "offset %zu length %zu", off, n);
            CHECK(cdvr_crc32c(0x1234567u, data + off, n) ==
                      cdvr_crc32c_portable(0x1234567u, data + off, n),
                  "offset %zu length %zu, initial value set", off, n);
            size_t split = n / 3 + 5; /* both parts long or short, at odd places */
            CHECK(cdvr_crc32c(cdvr_crc32c(0, data + off, split), data + off + split, n - split) ==
                      want, "offset %zu length %zu split at %zu", off, n, split);
        }
    memset(data, 0, ROUND); /* zeros: the register passes through the shift alone */
    CHECK(cdvr_crc32c(0, data, ROUND) == cdvr_crc32c_portable(0, data, ROUND), "zeros");
    uint32_t whole = cdvr_crc32c(0, data, 2 * ROUND);
    for (size_t at = 100; at < 2 * ROUND; at += 8192) {
        data[at] ^= 0x10;
        CHECK(cdvr_crc32c(0, data, 2 * ROUND) != whole, "a flipped bit at %zu changes the CRC", at);
        CHECK(cdvr_crc32c(0, data, 2 * ROUND) == cdvr_crc32c_portable(0, data, 2 * ROUND),
              "flipped at %zu: same as the table", at);
        data[at] ^= 0x10;
    }
    free(data);
}

int main(void)
{
    test_known_vectors();
    test_incremental_and_paths();
    test_interleaved_rounds();
    return check_finish();
}
