/* tests/test_crc32c.c - CRC-32C known vectors, incremental use, hardware == portable path. */
#include "check.h"

#include "base/crc32c.h"
#include "cdvr/crc32c.h"

#include <stdint.h>
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

int main(void)
{
    test_known_vectors();
    test_incremental_and_paths();
    return check_finish();
}
