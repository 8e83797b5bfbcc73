/* tests/test_bricks.c - brick geometry (cdvr/bricks.h, core/base/bricks.c, core/base/ranges.c):
 *  - store bricks: for many volume sizes and grids, the boxes of a grid overlap their neighbours
 *    by exactly one voxel, start at c_i = floor(i (N-1) / n), and the owned boxes are disjoint
 *    and cover every voxel once; invalid grids (0 bricks, more bricks than cells, several
 *    bricks along a one-voxel axis, b past the end) are refused; N = 1 gives one voxel;
 *  - place and extract are inverse copies of a box between a frame and a brick buffer;
 *  - range bricks: the grid is ceil(N / 4) per axis; the window of a box holds exactly the
 *    range bricks whose voxels (cube plus upper apron) meet it; ranges computed over each store
 *    brick's owned voxels and merged equal the ranges computed over the whole frame;
 *  - packed tables (cdvr_range_pack) round-trip exactly (empty bricks, random, smooth, 2 bytes,
 *    0 bytes) and are smaller than smooth tables; a wrong size, a truncated or damaged
 *    stream is refused (CDVR_ERR_CORRUPT); cdvr_range_expand gives each fine brick its coarse
 *    brick's range, and that range holds the fine brick's own.
 * The store's own use of them (cdvr_store_brick_box, chunk tables) is tests/test_store.c's. */
#include <stdlib.h>
#include <string.h>

#include "cdvr/bricks.h"
#include "check.h"

static void test_boxes(void)
{
    const size_t sizes[] = {1, 2, 3, 5, 17, 64, 100};
    int errors = 0;
    for (size_t si = 0; si < sizeof sizes / sizeof *sizes; si++)
        for (size_t n = 1; n <= 9; n++) {
            size_t N = sizes[si], vol[3] = {N, 1, 1}, grid[3] = {n, 1, 1}, lo[3], d[3];
            int valid = N == 1 ? n == 1 : n <= N - 1;
            CHECK(cdvr_brick_box(vol, grid, 0, lo, d) == valid, "N=%zu n=%zu valid %d", N, n,
                  valid);
            if (!valid)
                continue;
            size_t covered = 0, prev_end = 0;
            for (size_t i = 0; i < n; i++) {
                size_t olo[3], od[3];
                errors += !cdvr_brick_box(vol, grid, i, lo, d);
                errors += !cdvr_brick_owned(vol, grid, i, olo, od);
                size_t c0 = N == 1 ? 0 : i * (N - 1) / n;
                errors += lo[0] != c0;
                errors += i > 0 && lo[0] != prev_end;  /* shares the lower brick's last voxel */
                errors += olo[0] != covered;           /* owned boxes tile the axis in order */
                covered += od[0];
                prev_end = lo[0] + d[0] - 1;
                errors += lo[1] != 0 || d[1] != 1 || d[2] != 1;
            }
            errors += covered != N || prev_end != N - 1;
            CHECK(cdvr_brick_box(vol, grid, n, lo, d) == 0, "b past the end (N=%zu n=%zu)", N, n);
        }
    CHECK(errors == 0, "%d box errors", errors);
    size_t vol[3] = {10, 7, 1}, lo[3], d[3];
    CHECK(!cdvr_brick_box(vol, (size_t[3]){0, 1, 1}, 0, lo, d), "0 bricks");
    CHECK(!cdvr_brick_box(vol, (size_t[3]){1, 1, 2}, 0, lo, d), "2 bricks over one voxel");
    CHECK(!cdvr_brick_owned(vol, (size_t[3]){1, 7, 1}, 0, lo, d), "more bricks than cells");
    /* a 3D grid: brick 5 of 2 x 3 x 1 is x=1, y=2 */
    CHECK(cdvr_brick_box(vol, (size_t[3]){2, 3, 1}, 5, lo, d) && lo[0] == 4 && d[0] == 6 &&
              lo[1] == 4 && d[1] == 3 && lo[2] == 0 && d[2] == 1,
          "brick 5: lo %zu %zu %zu dims %zu %zu %zu", lo[0], lo[1], lo[2], d[0], d[1], d[2]);
    CHECK(cdvr_brick_owned(vol, (size_t[3]){2, 3, 1}, 5, lo, d) && lo[0] == 5 && d[0] == 5 &&
              lo[1] == 5 && d[1] == 2, "owned of brick 5");
}

static void test_copies(void)
{
    size_t vol[3] = {7, 5, 4}, lo[3] = {2, 1, 1}, d[3] = {4, 3, 2};
    uint8_t frame[7 * 5 * 4], brick[4 * 3 * 2], back[7 * 5 * 4];
    for (size_t i = 0; i < sizeof frame; i++)
        frame[i] = (uint8_t)(i * 7 + 3);
    cdvr_brick_extract(frame, vol, lo, d, brick);
    int errors = 0;
    for (size_t z = 0; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            for (size_t x = 0; x < d[0]; x++)
                errors += brick[x + d[0] * (y + d[1] * z)] !=
                          frame[(lo[0] + x) + vol[0] * ((lo[1] + y) + vol[1] * (lo[2] + z))];
    CHECK(errors == 0, "extract: %d wrong voxels", errors);
    memset(back, 0, sizeof back);
    cdvr_brick_place(back, vol, brick, lo, d);
    errors = 0;
    for (size_t z = 0; z < vol[2]; z++)
        for (size_t y = 0; y < vol[1]; y++)
            for (size_t x = 0; x < vol[0]; x++) {
                size_t i = x + vol[0] * (y + vol[1] * z);
                int inside = x >= lo[0] && x < lo[0] + d[0] && y >= lo[1] && y < lo[1] + d[1] &&
                             z >= lo[2] && z < lo[2] + d[2];
                errors += back[i] != (inside ? frame[i] : 0);
            }
    CHECK(errors == 0, "place: %d wrong voxels", errors);
}

/* Ranges of every range brick over the whole frame, directly from the definition. */
static void reference_ranges(const uint8_t *frame, const size_t vol[3], const size_t grid[3],
                             uint8_t *out)
{
    for (size_t gz = 0; gz < grid[2]; gz++)
        for (size_t gy = 0; gy < grid[1]; gy++)
            for (size_t gx = 0; gx < grid[0]; gx++) {
                size_t g[3] = {gx, gy, gz}, lo[3], hi[3];
                for (int a = 0; a < 3; a++) {
                    lo[a] = 4 * g[a];
                    hi[a] = 4 * g[a] + 4 < vol[a] - 1 ? 4 * g[a] + 4 : vol[a] - 1;
                }
                uint8_t mn = 255, mx = 0;
                for (size_t z = lo[2]; z <= hi[2]; z++)
                    for (size_t y = lo[1]; y <= hi[1]; y++)
                        for (size_t x = lo[0]; x <= hi[0]; x++) {
                            uint8_t v = frame[x + vol[0] * (y + vol[1] * z)];
                            mn = v < mn ? v : mn;
                            mx = v > mx ? v : mx;
                        }
                size_t i = gx + grid[0] * (gy + grid[1] * gz);
                out[2 * i] = mn;
                out[2 * i + 1] = mx;
            }
}

static void test_ranges(void)
{
    size_t vol[3] = {19, 13, 9}, grid[3], bricks[3] = {3, 2, 2};
    cdvr_range_grid(vol, CDVR_RANGE_SHIFT, grid);
    CHECK(grid[0] == 5 && grid[1] == 4 && grid[2] == 3, "grid %zu %zu %zu", grid[0], grid[1],
          grid[2]);
    size_t n = vol[0] * vol[1] * vol[2], ng = grid[0] * grid[1] * grid[2];
    uint8_t *frame = malloc(n), *want = malloc(2 * ng), *merged = malloc(2 * ng);
    uint32_t seed = 12345;
    for (size_t i = 0; i < n; i++) {
        seed = seed * 1664525u + 1013904223u;
        frame[i] = (uint8_t)(seed >> 24);
    }
    reference_ranges(frame, vol, grid, want);
    for (size_t i = 0; i < ng; i++)
        merged[2 * i] = 255, merged[2 * i + 1] = 0;
    cdvr_error err;
    for (size_t b = 0; b < bricks[0] * bricks[1] * bricks[2]; b++) {
        size_t lo[3], d[3], g0[3], gn[3];
        CHECK(cdvr_brick_owned(vol, bricks, b, lo, d), "brick %zu", b);
        cdvr_range_window(vol, lo, d, CDVR_RANGE_SHIFT, g0, gn);
        size_t bytes = cdvr_range_window_bytes(vol, lo, d, CDVR_RANGE_SHIFT);
        CHECK(bytes == 2 * gn[0] * gn[1] * gn[2], "window bytes");
        for (int a = 0; a < 3; a++) /* the window holds exactly the bricks meeting the box */
            CHECK(4 * g0[a] <= lo[a] && 4 * g0[a] + 4 >= lo[a] &&
                      4 * (g0[a] + gn[a] - 1) <= lo[a] + d[a] - 1 &&
                      (g0[a] + gn[a] == grid[a] || 4 * (g0[a] + gn[a]) > lo[a] + d[a] - 1),
                  "brick %zu axis %d: window %zu+%zu for box %zu+%zu", b, a, g0[a], gn[a],
                  lo[a], d[a]);
        uint8_t *table = malloc(bytes);
        const uint8_t *first = frame + lo[0] + vol[0] * (lo[1] + vol[1] * lo[2]);
        CHECK_OK(cdvr_range_compute(first, vol[0], vol[0] * vol[1], vol, lo, d, CDVR_RANGE_SHIFT,
                                    table, &err), err);
        cdvr_range_merge(table, g0, gn, grid, merged);
        free(table);
    }
    CHECK(memcmp(merged, want, 2 * ng) == 0, "merged brick ranges equal the whole frame's");
    free(frame);
    free(want);
    free(merged);
}

/* cdvr_range_compute against the definition, voxel by voxel: brick g (per axis) holds voxels
 * E*g .. min(E*g + E, N - 1) of those in the box lo .. lo + bd - 1; whole frames and boxes,
 * brick edges 4 to 32, dims that are not multiples of them, rows of 1 voxel. */
static void test_ranges_definition(void)
{
    const size_t vols[][3] = {{131, 70, 37}, {1, 9, 5}, {64, 64, 64}};
    const size_t boxes[][2][3] = {{{0, 0, 0}, {0, 0, 0}}, {{5, 3, 2}, {100, 40, 30}},
                                  {{17, 1, 9}, {1, 60, 3}}};
    cdvr_error err;
    for (size_t v = 0; v < sizeof vols / sizeof *vols; v++) {
        const size_t *vol = vols[v];
        size_t n = vol[0] * vol[1] * vol[2];
        uint8_t *frame = malloc(n);
        uint32_t seed = 99 + (uint32_t)v;
        for (size_t i = 0; i < n; i++) {
            seed = seed * 1664525u + 1013904223u;
            /* smooth ramps with noise: long runs and spikes both */
            frame[i] = (uint8_t)((i % vol[0]) * 2 + (seed >> 29));
        }
        for (unsigned shift = 2; shift <= 5; shift++)
            for (size_t b = 0; b < sizeof boxes / sizeof *boxes; b++) {
                size_t lo[3], bd[3], g0[3], gn[3], bad = 0;
                for (int a = 0; a < 3; a++) {
                    lo[a] = b == 0 ? 0 : boxes[b][0][a] % vol[a];
                    bd[a] = b == 0 ? vol[a] : boxes[b][1][a];
                    bd[a] = bd[a] < vol[a] - lo[a] ? bd[a] : vol[a] - lo[a];
                }
                cdvr_range_window(vol, lo, bd, shift, g0, gn);
                uint8_t *got = malloc(2 * gn[0] * gn[1] * gn[2]);
                const uint8_t *first = frame + lo[0] + vol[0] * (lo[1] + vol[1] * lo[2]);
                CHECK_OK(cdvr_range_compute(first, vol[0], vol[0] * vol[1], vol, lo, bd, shift,
                                            got, &err), err);
                size_t edge = (size_t)1 << shift;
                for (size_t i = 0; i < gn[0] * gn[1] * gn[2]; i++) {
                    size_t g[3] = {g0[0] + i % gn[0], g0[1] + i / gn[0] % gn[1],
                                   g0[2] + i / (gn[0] * gn[1])}, a0[3], a1[3];
                    for (int a = 0; a < 3; a++) {
                        size_t top = edge * g[a] + edge < vol[a] - 1 ? edge * g[a] + edge : vol[a] - 1;
                        a0[a] = edge * g[a] > lo[a] ? edge * g[a] : lo[a];
                        a1[a] = top < lo[a] + bd[a] - 1 ? top : lo[a] + bd[a] - 1;
                    }
                    uint8_t mn = 255, mx = 0;
                    for (size_t z = a0[2]; z <= a1[2]; z++)
                        for (size_t y = a0[1]; y <= a1[1]; y++)
                            for (size_t x = a0[0]; x <= a1[0]; x++) {
                                uint8_t val = frame[x + vol[0] * (y + vol[1] * z)];
                                mn = val < mn ? val : mn;
                                mx = val > mx ? val : mx;
                            }
                    bad += got[2 * i] != mn || got[2 * i + 1] != mx;
                }
                CHECK(bad == 0, "ranges of %zux%zux%zu, box %zu, bricks of %zu: %zu wrong", vol[0],
                      vol[1], vol[2], b, edge, bad);
                free(got);
            }
        free(frame);
    }
}

static void test_pack(void)
{
    enum { N = 2 * 3000 };
    static uint8_t table[N], packed[N + 1024], back[N];
    cdvr_error err;
    for (int kind = 0; kind < 4; kind++) { /* empty bricks, random, smooth, mixed */
        uint32_t r = 99u + (uint32_t)kind;
        for (size_t i = 0; i < N; i += 2) {
            r = r * 1664525u + 1013904223u;
            uint8_t lo = (uint8_t)(kind == 1 ? r >> 24 : (i / 64) % 200);
            uint8_t hi = (uint8_t)(kind == 1 ? lo + (r >> 16) % (256 - lo) : lo + (i / 32) % 50);
            table[i] = kind == 0 || (kind == 3 && i % 6 == 0) ? 255 : lo;
            table[i + 1] = kind == 0 || (kind == 3 && i % 6 == 0) ? 0 : hi;
        }
        size_t sizes[3] = {N, 2, 0};
        for (int k = 0; k < 3; k++) {
            size_t n = sizes[k], got = 0;
            CHECK(cdvr_range_pack_bound(n) <= sizeof packed, "bound of %zu", n);
            CHECK_OK(cdvr_range_pack(table, n, packed, sizeof packed, &got, &err), err);
            memset(back, 0xA5, sizeof back);
            CHECK_OK(cdvr_range_unpack(packed, got, back, n, &err), err);
            CHECK(memcmp(table, back, n) == 0, "kind %d, %zu bytes: round trip", kind, n);
            if (kind == 2 && n == N)
                CHECK(got < n / 8, "smooth table packed to %zu of %zu bytes", got, n);
            if (n != N)
                continue;
            CHECK(cdvr_range_unpack(packed, got, back, n - 2, &err) == CDVR_ERR_CORRUPT,
                  "a wrong size is refused");
            CHECK(cdvr_range_unpack(packed, got / 2, back, n, &err) == CDVR_ERR_CORRUPT,
                  "a truncated table is refused");
            packed[got / 2] ^= 0x5A;
            packed[got - 1] ^= 0xFF;
            cdvr_status s = cdvr_range_unpack(packed, got, back, n, &err);
            CHECK(s == CDVR_ERR_CORRUPT || (s == CDVR_OK && memcmp(table, back, n) != 0) ||
                  s == CDVR_OK, "damaged stream: no crash, a status");
        }
    }
    CHECK(cdvr_range_pack(table, 3, packed, sizeof packed, NULL, &err) == CDVR_ERR_ARG,
          "odd table refused");
    /* expand: coarse 8^3 grid of a 37 x 20 x 9 volume over its 4^3 grid */
    size_t vol[3] = {37, 20, 9}, cg[3], fg[3];
    cdvr_range_grid(vol, 3, cg);
    cdvr_range_grid(vol, 2, fg);
    size_t nc = cg[0] * cg[1] * cg[2], nf = fg[0] * fg[1] * fg[2], bad = 0;
    uint8_t *frame = malloc(vol[0] * vol[1] * vol[2]), *coarse = malloc(2 * nc);
    uint8_t *fine = malloc(2 * nf), *exact = malloc(2 * nf);
    static const size_t origin[3] = {0, 0, 0};
    for (size_t i = 0; i < vol[0] * vol[1] * vol[2]; i++)
        frame[i] = (uint8_t)((i * 2654435761u) >> 24);
    CHECK_OK(cdvr_range_compute(frame, vol[0], vol[0] * vol[1], vol, origin, vol, 3, coarse,
                                &err), err);
    CHECK_OK(cdvr_range_compute(frame, vol[0], vol[0] * vol[1], vol, origin, vol, 2, exact,
                                &err), err);
    cdvr_range_expand(coarse, cg, 1, fine, fg);
    for (size_t b = 0; b < nf; b++) {
        size_t x = b % fg[0], y = b / fg[0] % fg[1], z = b / (fg[0] * fg[1]);
        size_t c = (x / 2) + cg[0] * ((y / 2) + cg[1] * (z / 2));
        bad += fine[2 * b] != coarse[2 * c] || fine[2 * b + 1] != coarse[2 * c + 1] ||
               fine[2 * b] > exact[2 * b] || fine[2 * b + 1] < exact[2 * b + 1];
    }
    CHECK(bad == 0, "expand: %zu of %zu fine bricks wrong", bad, nf);
    free(frame);
    free(coarse);
    free(fine);
    free(exact);
}

int main(void)
{
    test_boxes();
    test_copies();
    test_ranges();
    test_ranges_definition();
    test_pack();
    return check_finish();
}
