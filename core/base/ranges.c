/* core/base/ranges.c - value ranges per range brick (cdvr/bricks.h): the grid, the window of range
 * bricks a voxel box meets, their ranges over one frame of it, and the merge of windows into
 * the grid of the whole volume.
 *
 * Range brick g (per axis) holds voxels E*g .. min(E*g + E, N - 1): its cube plus the upper
 * apron that trilinear interpolation reads. It meets a box whose voxels are lo .. hi
 * when E*g <= hi and E*g + E >= lo, i.e. g from ceil(lo / E) - 1 (at least 0) to hi / E.
 * Ranges are computed separably, one z slab of bricks at a time: each voxel row is folded
 * voxelwise into the rows of the one or two bricks along y whose spans hold it (min and max
 * of whole rows, which vectorise); then per brick row the min and max of each brick's x span
 * (for every x at once, by passes that double a window). */
#include "cdvr/bricks.h"

#include <stdlib.h>
#include <string.h>
#include <zstd.h>

void cdvr_range_grid(const size_t vol_dims[3], unsigned shift, size_t n[3])
{
    size_t edge = (size_t)1 << shift;
    for (int a = 0; a < 3; a++)
        n[a] = vol_dims[a] / edge + (vol_dims[a] % edge != 0);
}

void cdvr_range_window(const size_t vol_dims[3], const size_t lo[3], const size_t bd[3],
                       unsigned shift, size_t g0[3], size_t n[3])
{
    size_t grid[3], edge = (size_t)1 << shift;
    cdvr_range_grid(vol_dims, shift, grid);
    for (int a = 0; a < 3; a++) {
        size_t hi = lo[a] + bd[a] - 1, last = hi / edge;
        g0[a] = lo[a] == 0 ? 0 : (lo[a] - 1) / edge;
        last = last < grid[a] - 1 ? last : grid[a] - 1;
        n[a] = last - g0[a] + 1;
    }
}

size_t cdvr_range_window_bytes(const size_t vol_dims[3], const size_t lo[3],
                               const size_t bd[3], unsigned shift)
{
    size_t g0[3], n[3];
    cdvr_range_window(vol_dims, lo, bd, shift, g0, n);
    return 2 * n[0] * n[1] * n[2];
}

/* Local voxel span [first[w], last[w]] of window brick w along one axis. */
static void spans(size_t N, size_t lo, size_t bd, unsigned shift, size_t g0, size_t n,
                  size_t *first, size_t *last)
{
    size_t edge = (size_t)1 << shift, hi = lo + bd - 1;
    for (size_t w = 0; w < n; w++) {
        size_t g = g0 + w, a = g * edge, b = g * edge + edge;
        b = b < N - 1 ? b : N - 1;
        a = a > lo ? a : lo;
        b = b < hi ? b : hi;
        first[w] = a - lo;
        last[w] = b - lo;
    }
}

/* Window bricks (at most two) whose span along an axis holds local voxel i. */
static int bricks_of(size_t i, size_t lo, unsigned shift, size_t g0, size_t n,
                     const size_t *first, const size_t *last, size_t out[2])
{
    size_t g = (lo + i) >> shift, k = 0;
    for (size_t c = 0; c < 2; c++, g--) {
        if (g >= g0 && g - g0 < n && first[g - g0] <= i && i <= last[g - g0])
            out[k++] = g - g0;
        if (g == 0)
            break;
    }
    return (int)k;
}

/* t[x] = min(a[x], b[x]) (max when take_max) for x < n: blocks of 16 with a constant count,
 * which gcc vectorises at -O2 too, then the tail. */
static void min_max_rows(const uint8_t *restrict a, const uint8_t *restrict b,
                         uint8_t *restrict t, size_t n, int take_max)
{
    size_t x = 0;
    if (take_max) {
        for (; x + 16 <= n; x += 16)
            for (int k = 0; k < 16; k++)
                t[x + k] = a[x + k] > b[x + k] ? a[x + k] : b[x + k];
        for (; x < n; x++)
            t[x] = a[x] > b[x] ? a[x] : b[x];
    } else {
        for (; x + 16 <= n; x += 16)
            for (int k = 0; k < 16; k++)
                t[x + k] = a[x + k] < b[x + k] ? a[x + k] : b[x + k];
        for (; x < n; x++)
            t[x] = a[x] < b[x] ? a[x] : b[x];
    }
}

/* acc[x] = min(acc[x], r[x]) (max when take_max) for x < n, as min_max_rows. */
static void fold_into(uint8_t *restrict acc, const uint8_t *restrict r, size_t n, int take_max)
{
    size_t x = 0;
    if (take_max) {
        for (; x + 16 <= n; x += 16)
            for (int k = 0; k < 16; k++)
                acc[x + k] = r[x + k] > acc[x + k] ? r[x + k] : acc[x + k];
        for (; x < n; x++)
            acc[x] = r[x] > acc[x] ? r[x] : acc[x];
    } else {
        for (; x + 16 <= n; x += 16)
            for (int k = 0; k < 16; k++)
                acc[x + k] = r[x + k] < acc[x + k] ? r[x + k] : acc[x + k];
        for (; x < n; x++)
            acc[x] = r[x] < acc[x] ? r[x] : acc[x];
    }
}

/* t[x] = min (max) of a[x] and a[min(x + span, len - 1)]: a window of a[] twice as long, or
 * with the apron voxel, per pass. */
static void fold_pass(const uint8_t *a, uint8_t *t, size_t len, size_t span, int take_max)
{
    size_t head = len > span ? len - span : 0;
    min_max_rows(a, a + span, t, head, take_max);
    for (size_t x = head; x < len; x++)
        t[x] = take_max ? (a[len - 1] > a[x] ? a[len - 1] : a[x])
                        : (a[len - 1] < a[x] ? a[len - 1] : a[x]);
}

/* The min (max) of row[x .. min(x + E, len - 1)] for every x, into one of buf's two halves
 * (len bytes each): shift doubling passes give windows of E voxels, one more pass with the row
 * itself the apron. Returns the half holding the result. */
static const uint8_t *row_windows(const uint8_t *row, size_t len, unsigned shift, int take_max,
                                  uint8_t *buf)
{
    const uint8_t *a = row;
    uint8_t *t = buf;
    for (unsigned k = 0; k < shift; k++) {
        fold_pass(a, t, len, (size_t)1 << k, take_max);
        a = t;
        t = t == buf ? buf + len : buf;
    }
    /* the apron: the window [x, x + E - 1] and the voxel x + E (clamped to the row's end) */
    size_t edge = (size_t)1 << shift, head = len > edge ? len - edge : 0;
    min_max_rows(a, row + edge, t, head, take_max);
    for (size_t x = head; x < len; x++)
        t[x] = take_max ? (row[len - 1] > a[x] ? row[len - 1] : a[x])
                        : (row[len - 1] < a[x] ? row[len - 1] : a[x]);
    return t;
}

cdvr_status cdvr_range_compute(const uint8_t *voxels, size_t row_stride, size_t plane_stride,
                               const size_t vol_dims[3], const size_t lo[3], const size_t bd[3],
                               unsigned shift, uint8_t *out, cdvr_error *err)
{
    size_t g0[3], n[3], edge = (size_t)1 << shift;
    cdvr_range_window(vol_dims, lo, bd, shift, g0, n);
    size_t total = n[0] + n[1] + n[2], X = bd[0];
    size_t *first = malloc(2 * total * sizeof *first);
    /* per window brick row along y of one z brick slab: the voxelwise min and max over the
     * rows its y and z spans hold (X bytes each), then the x windows of one such row */
    uint8_t *acc = malloc(2 * n[1] * X + 4 * X);
    if (!first || !acc) {
        free(first);
        free(acc);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "value ranges: no memory for %zu bricks",
                              total);
    }
    size_t *fx = first, *fy = fx + n[0], *fz = fy + n[1], *last = first + total;
    size_t *lx = last, *ly = lx + n[0], *lz = ly + n[1];
    spans(vol_dims[0], lo[0], bd[0], shift, g0[0], n[0], fx, lx);
    spans(vol_dims[1], lo[1], bd[1], shift, g0[1], n[1], fy, ly);
    spans(vol_dims[2], lo[2], bd[2], shift, g0[2], n[2], fz, lz);
    uint8_t *amin = acc, *amax = acc + n[1] * X, *scratch = acc + 2 * n[1] * X;
    for (size_t wz = 0; wz < n[2]; wz++) {
        memset(amin, 255, n[1] * X);
        memset(amax, 0, n[1] * X);
        for (size_t z = fz[wz]; z <= lz[wz]; z++)
            for (size_t y = 0; y < bd[1]; y++) {
                size_t wy[2];
                int ny = bricks_of(y, lo[1], shift, g0[1], n[1], fy, ly, wy);
                const uint8_t *row = voxels + row_stride * y + plane_stride * z;
                for (int iy = 0; iy < ny; iy++) {
                    fold_into(amin + X * wy[iy], row, X, 0);
                    fold_into(amax + X * wy[iy], row, X, 1);
                }
            }
        for (size_t wy = 0; wy < n[1]; wy++) {
            const uint8_t *rmin = amin + X * wy, *rmax = amax + X * wy;
            const uint8_t *tmin = row_windows(rmin, X, shift, 0, scratch);
            const uint8_t *tmax = row_windows(rmax, X, shift, 1, scratch + 2 * X);
            uint8_t *dst = out + 2 * n[0] * (wy + n[1] * wz);
            for (size_t w = 0; w < n[0]; w++) {
                size_t whole = fx[w] + edge < X - 1 ? fx[w] + edge : X - 1;
                uint8_t mn = tmin[fx[w]], mx = tmax[fx[w]]; /* the window tmin/tmax hold */
                if (lx[w] != whole) { /* cut short by the box: its own voxels */
                    mn = 255;
                    mx = 0;
                    for (size_t x = fx[w]; x <= lx[w]; x++) {
                        mn = rmin[x] < mn ? rmin[x] : mn;
                        mx = rmax[x] > mx ? rmax[x] : mx;
                    }
                }
                dst[2 * w] = mn;
                dst[2 * w + 1] = mx;
            }
        }
    }
    free(first);
    free(acc);
    return CDVR_OK;
}

void cdvr_range_merge(const uint8_t *window, const size_t g0[3], const size_t n[3],
                      const size_t grid[3], uint8_t *grid_minmax)
{
    for (size_t z = 0; z < n[2]; z++)
        for (size_t y = 0; y < n[1]; y++) {
            const uint8_t *src = window + 2 * n[0] * (y + n[1] * z);
            uint8_t *dst = grid_minmax + 2 * (g0[0] + grid[0] * ((g0[1] + y) +
                                                                 grid[1] * (g0[2] + z)));
            for (size_t x = 0; x < n[0]; x++) {
                dst[2 * x] = src[2 * x] < dst[2 * x] ? src[2 * x] : dst[2 * x];
                dst[2 * x + 1] = src[2 * x + 1] > dst[2 * x + 1] ? src[2 * x + 1]
                                                                  : dst[2 * x + 1];
            }
        }
}

/* ---- compact stored tables ------------------------------------------------------------------ */

size_t cdvr_range_pack_bound(size_t n)
{
    size_t bound = ZSTD_compressBound(n);
    return ZSTD_isError(bound) ? 0 : bound;
}

/* Planar form of a table of n bytes (n even): the n/2 mins, then the n/2 widths max - min
 * (mod 256: an empty brick, min 255 and max 0, keeps width 1). Smooth data makes both planes
 * runs of small, repeated bytes, which zstd packs far better than the interleaved pairs. */
static void to_planar(const uint8_t *table, size_t n, uint8_t *planar)
{
    size_t half = n / 2;
    for (size_t i = 0; i < half; i++) {
        planar[i] = table[2 * i];
        planar[half + i] = (uint8_t)(table[2 * i + 1] - table[2 * i]);
    }
}

static void from_planar(const uint8_t *planar, size_t n, uint8_t *table)
{
    size_t half = n / 2;
    for (size_t i = 0; i < half; i++) {
        table[2 * i] = planar[i];
        table[2 * i + 1] = (uint8_t)(planar[i] + planar[half + i]);
    }
}

cdvr_status cdvr_range_pack(const uint8_t *table, size_t n, uint8_t *out, size_t out_cap,
                            size_t *out_n, cdvr_error *err)
{
    if (n % 2 != 0 || out_cap < cdvr_range_pack_bound(n))
        return cdvr_error_set(err, CDVR_ERR_ARG, "range table: %zu bytes (odd) or room %zu "
                              "below the bound", n, out_cap);
    uint8_t *planar = malloc(n ? n : 1);
    if (!planar)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "range table: no memory for %zu bytes", n);
    to_planar(table, n, planar);
    size_t got = ZSTD_compress(out, out_cap, planar, n, CDVR_RANGE_ZSTD_LEVEL);
    free(planar);
    if (ZSTD_isError(got))
        return cdvr_error_set(err, CDVR_ERR_IO, "range table: zstd: %s", ZSTD_getErrorName(got));
    *out_n = got;
    return CDVR_OK;
}

cdvr_status cdvr_range_unpack(const uint8_t *in, size_t n, uint8_t *table, size_t expect,
                              cdvr_error *err)
{
    if (expect % 2 != 0)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "range table of %zu bytes (odd)", expect);
    unsigned long long frame = ZSTD_getFrameContentSize(in, n);
    if (frame != expect)
        return cdvr_error_set(err, CDVR_ERR_CORRUPT, "packed range table claims %llu bytes, "
                              "%zu expected", frame, expect);
    uint8_t *planar = malloc(expect ? expect : 1);
    if (!planar)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "range table: no memory for %zu bytes",
                              expect);
    size_t got = ZSTD_decompress(planar, expect, in, n);
    cdvr_status s = CDVR_OK;
    if (ZSTD_isError(got) || got != expect)
        s = cdvr_error_set(err, CDVR_ERR_CORRUPT, "packed range table: %s",
                           ZSTD_isError(got) ? ZSTD_getErrorName(got) : "short");
    else
        from_planar(planar, expect, table);
    free(planar);
    return s;
}

/* ---- coarse tables for a finer grid --------------------------------------------------------- */

void cdvr_range_expand(const uint8_t *coarse, const size_t coarse_dims[3], unsigned factor_log2,
                       uint8_t *fine, const size_t fine_dims[3])
{
    /* fine rows (planes) of one coarse row (plane) are alike: each is made once, then copied */
    size_t k = (size_t)1 << factor_log2, row_bytes = 2 * fine_dims[0];
    size_t plane_bytes = row_bytes * fine_dims[1];
    for (size_t z = 0; z < fine_dims[2]; z++) {
        uint8_t *out_plane = fine + plane_bytes * z;
        if (z % k != 0) {
            memcpy(out_plane, out_plane - plane_bytes, plane_bytes);
            continue;
        }
        for (size_t y = 0; y < fine_dims[1]; y++) {
            uint8_t *out = out_plane + row_bytes * y;
            if (y % k != 0) {
                memcpy(out, out - row_bytes, row_bytes);
                continue;
            }
            const uint8_t *row = coarse + 2 * coarse_dims[0] *
                                              ((y >> factor_log2) +
                                               coarse_dims[1] * (z >> factor_log2));
            for (size_t x = 0; x < fine_dims[0]; x++) {
                const uint8_t *c = row + 2 * (x >> factor_log2);
                out[2 * x] = c[0];
                out[2 * x + 1] = c[1];
            }
        }
    }
}
