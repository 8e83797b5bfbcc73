/* core/render/skip.c - empty-space skipping grids on the host (cdvr/skip.h).
 *
 * The distance transform is the two-pass 26-neighbour chamfer (each pass visits bricks in
 * raster order, forward then backward, taking the minimum over the 13 neighbours already
 * visited plus one), computed a row at a time: the 12 neighbours in earlier rows are final
 * when a row starts, so their minimum is taken for the whole row at once (min of three
 * neighbouring entries of four earlier rows), and only the neighbour at x - 1 (x + 1
 * backward) needs a sequential sweep. Same result as visiting brick by brick. */
#include "cdvr/skip.h"
#include "cdvr/bricks.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

cdvr_status cdvr_skip_grid_init(cdvr_skip_grid *g, const size_t vol_dims[3], unsigned shift,
                                cdvr_error *err)
{
    memset(g, 0, sizeof *g);
    g->shift = shift;
    g->nbricks = 1;
    cdvr_range_grid(vol_dims, shift, g->dims);
    for (int a = 0; a < 3; a++) {
        g->vol_dims[a] = vol_dims[a];
        if (!cdvr_size_mul(g->nbricks, g->dims[a], &g->nbricks))
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "skip grid: %zux%zux%zu bricks overflow",
                                  g->dims[0], g->dims[1], g->dims[2]);
    }
    g->minmax = malloc(2 * g->nbricks);
    g->flags = malloc(g->nbricks);
    g->scratch = malloc(2 * g->nbricks);
    if (!g->minmax || !g->flags || !g->scratch) {
        cdvr_skip_grid_free(g);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "skip grid: no memory for %zu bricks",
                              g->nbricks);
    }
    return CDVR_OK;
}

void cdvr_skip_grid_free(cdvr_skip_grid *g)
{
    free(g->minmax);
    free(g->flags);
    free(g->scratch);
    g->minmax = g->flags = g->scratch = NULL;
    g->flags_valid = 0;
}

void cdvr_skip_grid_touch(cdvr_skip_grid *g)
{
    g->flags_valid = 0;
}

cdvr_status cdvr_skip_minmax_from_frame(cdvr_skip_grid *g, const uint8_t *frame,
                                        cdvr_error *err)
{
    static const size_t origin[3] = {0, 0, 0};
    const size_t *d = g->vol_dims;
    g->flags_valid = 0;
    return cdvr_range_compute(frame, d[0], d[0] * d[1], d, origin, d, g->shift, g->minmax, err);
}

/* ---- distance transform ---------------------------------------------------------------- */

static uint8_t min_u8(uint8_t a, uint8_t b)
{
    return a < b ? a : b;
}

/* out[x] = min(row[x - 1], row[x], row[x + 1]) over the entries inside the row. */
static void row_min3(const uint8_t *restrict row, size_t n, uint8_t *restrict out)
{
    if (n == 1) {
        out[0] = row[0];
        return;
    }
    out[0] = min_u8(row[0], row[1]);
    for (size_t x = 1; x + 1 < n; x++)
        out[x] = min_u8(min_u8(row[x - 1], row[x]), row[x + 1]);
    out[n - 1] = min_u8(row[n - 2], row[n - 1]);
}

/* One chamfer pass; dir = +1 forward (raster order), -1 backward. near3 holds, per row of the
 * planes visited so far, the row_min3 of its final values (two planes: the one before and
 * the current one). */
static void chamfer_pass(uint8_t *dist, const size_t n[3], int dir, uint8_t *near3)
{
    const size_t nx = n[0], ny = n[1], nz = n[2], plane = nx * ny;
    uint8_t *prev = near3, *cur = near3 + plane;
    for (size_t zi = 0; zi < nz; zi++) {
        size_t z = dir > 0 ? zi : nz - 1 - zi;
        for (size_t yi = 0; yi < ny; yi++) {
            size_t y = dir > 0 ? yi : ny - 1 - yi;
            uint8_t *row = dist + nx * (y + ny * z);
            /* earlier rows: plane z - dir at y - 1, y, y + 1, and this plane at y - dir */
            const uint8_t *src[4];
            int k = 0;
            if (zi > 0) {
                src[k++] = prev + nx * y;
                if (y > 0)
                    src[k++] = prev + nx * (y - 1);
                if (y + 1 < ny)
                    src[k++] = prev + nx * (y + 1);
            }
            if (yi > 0)
                src[k++] = cur + nx * (dir > 0 ? y - 1 : y + 1);
            for (int i = 0; i < k; i++)
                for (size_t x = 0; x < nx; x++) {
                    uint8_t c = src[i][x] == 255 ? 255 : (uint8_t)(src[i][x] + 1);
                    row[x] = min_u8(row[x], c);
                }
            if (dir > 0) {
                for (size_t x = 1; x < nx; x++)
                    if (row[x - 1] < 255)
                        row[x] = min_u8(row[x], (uint8_t)(row[x - 1] + 1));
            } else {
                for (size_t x = nx - 1; x-- > 0;)
                    if (row[x + 1] < 255)
                        row[x] = min_u8(row[x], (uint8_t)(row[x + 1] + 1));
            }
            row_min3(row, nx, cur + nx * y);
        }
        uint8_t *t = prev;
        prev = cur;
        cur = t;
    }
}

void cdvr_skip_distance(const uint8_t *seed, uint8_t *dist, const size_t dims[3])
{
    size_t count = dims[0] * dims[1] * dims[2];
    for (size_t b = 0; b < count; b++)
        dist[b] = seed[b] ? 0 : 255;
    uint8_t *near3 = malloc(2 * dims[0] * dims[1]);
    if (!near3) { /* out of memory: every distance 1 (no skipping across bricks, still exact) */
        for (size_t b = 0; b < count; b++)
            dist[b] = seed[b] ? 0 : 1;
        return;
    }
    chamfer_pass(dist, dims, 1, near3);
    chamfer_pass(dist, dims, -1, near3);
    free(near3);
}

/* ---- flags ------------------------------------------------------------------------------ */

static void visible_box(cdvr_skip_grid *g, const uint8_t *visible)
{
    size_t lo[3] = {SIZE_MAX, SIZE_MAX, SIZE_MAX}, hi[3] = {0, 0, 0};
    const size_t *n = g->dims, edge = (size_t)1 << g->shift;
    for (size_t z = 0, b = 0; z < n[2]; z++)
        for (size_t y = 0; y < n[1]; y++)
            for (size_t x = 0; x < n[0]; x++, b++) {
                if (!visible[b])
                    continue;
                size_t at[3] = {x, y, z};
                for (int a = 0; a < 3; a++) {
                    lo[a] = at[a] < lo[a] ? at[a] : lo[a];
                    hi[a] = at[a] > hi[a] ? at[a] : hi[a];
                }
            }
    for (int a = 0; a < 3; a++) {
        if (lo[a] == SIZE_MAX) { /* nothing visible: an empty box */
            g->visible_lo[a] = INFINITY;
            g->visible_hi[a] = -INFINITY;
            continue;
        }
        g->visible_lo[a] = lo[a] == 0 ? -INFINITY : (float)(lo[a] * edge);
        g->visible_hi[a] = hi[a] + 1 == n[a] ? INFINITY : (float)((hi[a] + 1) * edge);
    }
}

/* The flags of g's ranges for the codes whose entry is not 0 into flags (nbricks), with
 * scratch (2 * nbricks); afterwards scratch[b] is 1 where brick b is visible. Returns how
 * many bricks are visible. */
static size_t make_flags(const cdvr_skip_grid *g, const uint8_t visible_entry[256],
                         uint8_t *flags, uint8_t *scratch)
{
    int prefix[257];
    prefix[0] = 0;
    for (int i = 0; i < 256; i++)
        prefix[i + 1] = prefix[i] + (visible_entry[i] != 0);
    uint8_t *visible = scratch, *hidden = scratch + g->nbricks;
    size_t count = 0;
    for (size_t b = 0; b < g->nbricks; b++) {
        int lo = g->minmax[2 * b], hi = g->minmax[2 * b + 1];
        visible[b] = lo <= hi && prefix[hi + 1] - prefix[lo] > 0;
        hidden[b] = !visible[b];
        count += visible[b];
    }
    cdvr_skip_distance(visible, flags, g->dims); /* distance to visible, in flags */
    cdvr_skip_distance(hidden, hidden, g->dims); /* distance to invisible (in place) */
    for (size_t b = 0; b < g->nbricks; b++) {
        int vis = flags[b] == 0;
        int d = vis ? hidden[b] : flags[b];
        d = d > CDVR_SKIP_REACH_MAX ? CDVR_SKIP_REACH_MAX : d;
        flags[b] = (uint8_t)(vis ? 128 + d : d);
    }
    return count;
}

int cdvr_skip_flags(cdvr_skip_grid *g, const cdvr_tf *tf)
{
    uint8_t visible_entry[256];
    for (int i = 0; i < 256; i++)
        visible_entry[i] = tf->table[i][3] > 0.0f;
    if (g->flags_valid && memcmp(visible_entry, g->tf_visible, sizeof visible_entry) == 0)
        return 0;
    g->bricks_visible = make_flags(g, visible_entry, g->flags, g->scratch);
    visible_box(g, g->scratch);
    memcpy(g->tf_visible, visible_entry, sizeof visible_entry);
    g->flags_valid = 1;
    return 1;
}

void cdvr_skip_flags_into(cdvr_skip_grid *g, const uint8_t visible_entry[256], uint8_t *flags)
{
    make_flags(g, visible_entry, flags, g->scratch);
}

/* ---- a coarse grid's flags on a finer grid ---------------------------------------------- */

/* Code d (invisible) or 128 + d (visible) of a coarse brick says every brick within d - 1 of
 * it is alike; k = coarse edge / fine edge. A fine brick c of coarse brick P lies at least
 * k (d - 1) fine bricks inside the coarse cube around P (c - k (P - d + 1) >= k (d - 1) and
 * k (P + d - 1) + k - 1 - c >= k (d - 1)), so it gets k (d - 1) + 1. (Where the fine grid
 * ends before the coarse one, ceil(N / 4) < 2 ceil(N / 8), a cube may reach past it: no
 * sample lies there, as with cdvr_skip_flags' cubes past the grid's border.) */
static uint8_t fine_code(uint8_t coarse_code, unsigned factor_log2)
{
    unsigned vis = coarse_code & 128u, d = coarse_code & 127u;
    unsigned reach = d > 0 ? (d - 1) << factor_log2 : 0;
    unsigned fine = reach + 1 > CDVR_SKIP_REACH_MAX ? CDVR_SKIP_REACH_MAX : reach + 1;
    return (uint8_t)(vis | fine);
}

cdvr_status cdvr_skip_grid_expand(const cdvr_skip_grid *coarse, cdvr_skip_grid *fine,
                                  cdvr_error *err)
{
    if (!coarse->flags_valid || coarse->shift < fine->shift ||
        memcmp(coarse->vol_dims, fine->vol_dims, sizeof fine->vol_dims) != 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "skip grid: bricks of 2^%u (flags %s) do not "
                              "spread over bricks of 2^%u of the same volume", coarse->shift,
                              coarse->flags_valid ? "made" : "not made", fine->shift);
    unsigned f = coarse->shift - fine->shift;
    uint8_t codes[256];
    for (int c = 0; c < 256; c++)
        codes[c] = fine_code((uint8_t)c, f);
    cdvr_range_expand(coarse->minmax, coarse->dims, f, fine->minmax, fine->dims);
    const size_t *cd = coarse->dims, *n = fine->dims;
    /* fine rows (planes) of one coarse row (plane) are alike: each is made once, then copied */
    size_t k = (size_t)1 << f, plane = n[0] * n[1], plane_visible = 0;
    fine->bricks_visible = 0;
    for (size_t z = 0; z < n[2]; z++) {
        uint8_t *out_plane = fine->flags + plane * z;
        if (z % k != 0) {
            memcpy(out_plane, out_plane - plane, plane);
            fine->bricks_visible += plane_visible;
            continue;
        }
        size_t row_visible = 0;
        plane_visible = 0;
        for (size_t y = 0; y < n[1]; y++) {
            uint8_t *out = out_plane + n[0] * y;
            if (y % k != 0) {
                memcpy(out, out - n[0], n[0]);
            } else {
                const uint8_t *row = coarse->flags + cd[0] * ((y >> f) + cd[1] * (z >> f));
                row_visible = 0;
                for (size_t x = 0; x < n[0]; x++) {
                    out[x] = codes[row[x >> f]];
                    row_visible += out[x] >= 128;
                }
            }
            plane_visible += row_visible;
        }
        fine->bricks_visible += plane_visible;
    }
    for (int a = 0; a < 3; a++) {
        fine->visible_lo[a] = coarse->visible_lo[a];
        fine->visible_hi[a] = coarse->visible_hi[a];
    }
    memcpy(fine->tf_visible, coarse->tf_visible, sizeof fine->tf_visible);
    fine->flags_valid = 1;
    return CDVR_OK;
}
