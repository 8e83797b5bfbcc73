/* tests/test_lzo.c - stage 2: LZO1X round trips, corrupt input, the keep rule. */
#include "check.h"

#include "codec/stage2/stage2.h"

#include <stdint.h>
#include <string.h>

static void fill_random(uint8_t *p, size_t n, uint32_t seed)
{
    for (size_t i = 0; i < n; i++) {
        seed = seed * 1664525u + 1013904223u;
        p[i] = (uint8_t)(seed >> 24);
    }
}

static void fill_structured(uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; i++) /* runs and a repeating ramp, like constant PVTC blocks */
        p[i] = (i / 512) % 2 ? (uint8_t)(i % 7) : 0x40;
}

/* Round trip of n bytes; returns the compressed size. */
static size_t round_trip(const uint8_t *in, size_t n, const char *what)
{
    size_t cap = cdvr_lzo_bound(n), packed_n = 0;
    uint8_t *packed = malloc(cap), *out = malloc(n ? n : 1);
    cdvr_error err;
    cdvr_status s = cdvr_lzo_compress(in, n, packed, cap, &packed_n, &err);
    CHECK_OK(s, err);
    CHECK(packed_n <= cap, "%s: %zu > bound %zu", what, packed_n, cap);
    s = cdvr_lzo_decompress(packed, packed_n, out, n, &err);
    CHECK_OK(s, err);
    CHECK(n == 0 || memcmp(in, out, n) == 0, "%s: round trip differs", what);
    if (n > 8) { /* wrong expected size and a truncated stream are reported, never overrun */
        CHECK(cdvr_lzo_decompress(packed, packed_n, out, n - 1, &err) == CDVR_ERR_CORRUPT,
              "%s: short output accepted", what);
        CHECK(cdvr_lzo_decompress(packed, packed_n / 2, out, n, &err) == CDVR_ERR_CORRUPT,
              "%s: truncated stream accepted", what);
    }
    free(packed);
    free(out);
    return packed_n;
}

static void test_round_trips(void)
{
    size_t sizes[] = {0, 1, 7, 100, 4096, 100003, 1 << 20};
    for (size_t k = 0; k < sizeof sizes / sizeof *sizes; k++) {
        size_t n = sizes[k];
        uint8_t *buf = malloc(n ? n : 1);
        fill_random(buf, n, (uint32_t)n);
        size_t random_packed = round_trip(buf, n, "random");
        fill_structured(buf, n);
        size_t structured_packed = round_trip(buf, n, "structured");
        if (n >= 4096) {
            CHECK(random_packed >= n, "random data of %zu bytes shrank to %zu", n, random_packed);
            CHECK(structured_packed < n / 10, "structured %zu -> %zu", n, structured_packed);
        }
        free(buf);
    }
}

static void test_corrupt_input(void)
{
    uint8_t in[8192], packed[9000], out[8192];
    fill_structured(in, sizeof in);
    size_t n = 0;
    cdvr_error err;
    CHECK_OK(cdvr_lzo_compress(in, sizeof in, packed, sizeof packed, &n, &err), err);
    int caught = 0;
    for (size_t i = 0; i < n; i++) { /* every flipped byte: an error or the same size, no crash */
        packed[i] ^= 0x5a;
        cdvr_status s = cdvr_lzo_decompress(packed, n, out, sizeof out, &err);
        caught += s != CDVR_OK;
        packed[i] ^= 0x5a;
    }
    CHECK(caught > 0, "no flipped byte was detected");
    CHECK(cdvr_lzo_compress(in, sizeof in, packed, 10, &n, &err) == CDVR_ERR_ARG,
          "small output buffer accepted");
}

static void test_keep_rule(void)
{
    CHECK(cdvr_lzo_keep(1000, 900, 0.10), "exactly 10%% saved is kept");
    CHECK(!cdvr_lzo_keep(1000, 901, 0.10), "9.9%% saved is skipped");
    CHECK(!cdvr_lzo_keep(1000, 1000, 0.0), "no saving is never kept");
    CHECK(cdvr_lzo_keep(1000, 999, 0.0), "threshold 0 keeps any saving");
    CHECK(!cdvr_lzo_keep(1000, 10, 1.0), "threshold 1 never keeps");
    CHECK(cdvr_lzo_bound(100) == 100 + 6 + 67, "bound");
}

int main(void)
{
    test_round_trips();
    test_corrupt_input();
    test_keep_rule();
    return check_finish();
}
