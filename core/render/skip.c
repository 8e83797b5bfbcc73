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

/* The loops below work in blocks of BLOCK bytes with a constant count, which gcc vectorises
 * at -O2 too (it leaves loops of unknown count scalar there), then the tail: the flags of a
 * 256^3 frame's 4^3 bricks took 9.7 ms with the loops written plainly, 2.25 ms so. */
#define BLOCK 16

/* x + s, or 255 (none) when that passes 254 (s at most 255; the wrapped sum is below x
 * exactly when it passes 255: gcc makes it an unsigned saturating add). */
static uint8_t add_sat(uint8_t x, uint8_t s)
{
    uint8_t sum = (uint8_t)(x + s);
    return sum < x ? 255 : sum;
}

/* out[x] = min(row[x - 1], row[x], row[x + 1]) over the entries inside the row. */
static void row_min3(const uint8_t *restrict row, size_t n, uint8_t *restrict out)
{
    if (n == 1) {
        out[0] = row[0];
        return;
    }
    out[0] = min_u8(row[0], row[1]);
    size_t x = 1;
    for (; x + BLOCK < n; x += BLOCK)
        for (int k = 0; k < BLOCK; k++)
            out[x + k] = min_u8(min_u8(row[x + k - 1], row[x + k]), row[x + k + 1]);
    for (; x + 1 < n; x++)
        out[x] = min_u8(min_u8(row[x - 1], row[x]), row[x + 1]);
    out[n - 1] = min_u8(row[n - 2], row[n - 1]);
}

/* row[x] = min(row[x], src[x] + 1) for x < n (255 stays 255). */
static void take_neighbour(uint8_t *restrict row, const uint8_t *restrict src, size_t n)
{
    size_t x = 0;
    for (; x + BLOCK <= n; x += BLOCK)
        for (int k = 0; k < BLOCK; k++)
            row[x + k] = min_u8(row[x + k], add_sat(src[x + k], 1));
    for (; x < n; x++)
        row[x] = min_u8(row[x], add_sat(src[x], 1));
}

/* out[x] = min(in[x], in[x - s] + s) (dir +1; in[x + s] for dir -1) where that entry is in
 * the row, else in[x]. */
static void scan_step(const uint8_t *restrict in, uint8_t *restrict out, size_t n, size_t s,
                      int dir)
{
    size_t lo = dir > 0 ? s : 0, hi = dir > 0 ? n : n - s; /* the entries with a neighbour */
    const uint8_t *from = dir > 0 ? in - s : in + s;
    uint8_t by = s < 255 ? (uint8_t)s : 255; /* farther is 255 (none) anyway */
    memcpy(out, in, n);
    size_t x = lo;
    for (; x + BLOCK <= hi; x += BLOCK)
        for (int k = 0; k < BLOCK; k++)
            out[x + k] = min_u8(in[x + k], add_sat(from[x + k], by));
    for (; x < hi; x++)
        out[x] = min_u8(in[x], add_sat(from[x], by));
}

/* The row's own chamfer scan, row[x] = min(row[x], row[x - dir] + 1) in the direction dir, as
 * its closed form min over j behind x of row[j] + |x - j| (capped at 255): steps of 1, 2, 4,
 * .. (each taking the entries up to twice as far back), in tmp (2 * n bytes), vectorised
 * where the step by step scan is one long dependency chain. */
static void row_scan(uint8_t *row, size_t n, int dir, uint8_t *tmp)
{
    uint8_t *a = tmp, *b = tmp + n;
    const uint8_t *in = row;
    for (size_t s = 1; s < n; s <<= 1) {
        scan_step(in, a, n, s, dir);
        in = a;
        uint8_t *t = a;
        a = b;
        b = t;
    }
    if (in != row)
        memcpy(row, in, n);
}

/* One chamfer pass; dir = +1 forward (raster order), -1 backward. near3 holds, per row of the
 * planes visited so far, the row_min3 of its final values (two planes: the one before and
 * the current one), then 2 * nx bytes of scratch. */
static void chamfer_pass(uint8_t *dist, const size_t n[3], int dir, uint8_t *near3)
{
    const size_t nx = n[0], ny = n[1], nz = n[2], plane = nx * ny;
    uint8_t *prev = near3, *cur = near3 + plane, *tmp = near3 + 2 * plane;
    for (size_t zi = 0; zi < nz; zi++) {
        size_t z = dir > 0 ? zi : nz - 1 - zi;
        for (size_t yi = 0; yi < ny; yi++) {
            size_t y = dir > 0 ? yi : ny - 1 - yi;
            uint8_t *row = dist + nx * (y + ny * z);
            /* earlier rows: plane z - dir at y - 1, y, y + 1, and this plane at y - dir */
            if (zi > 0) {
                take_neighbour(row, prev + nx * y, nx);
                if (y > 0)
                    take_neighbour(row, prev + nx * (y - 1), nx);
                if (y + 1 < ny)
                    take_neighbour(row, prev + nx * (y + 1), nx);
            }
            if (yi > 0)
                take_neighbour(row, cur + nx * (dir > 0 ? y - 1 : y + 1), nx);
            row_scan(row, nx, dir, tmp);
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
    uint8_t *near3 = malloc(2 * dims[0] * dims[1] + 2 * dims[0]);
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

/* ---- entry distances ---------------------------------------------------------------------- */

void cdvr_skip_entry_free(cdvr_skip_entry *e)
{
    free(e->boxes);
    e->boxes = NULL;
    e->count = e->capacity = 0;
}

/* A visible brick met first by a ray from outside: one with an invisible brick among its 26
 * neighbours (code 128 + 1) or on the grid's border (bricks beyond it count as invisible). */
static int boundary_brick(const cdvr_skip_grid *g, size_t x, size_t y, size_t z, uint8_t code)
{
    const size_t *n = g->dims;
    return code >= 128 && (code == 129 || x == 0 || y == 0 || z == 0 || x + 1 == n[0] ||
                           y + 1 == n[1] || z + 1 == n[2]);
}

/* Appends the grid box (a voxel of margin, clamped to [-1, dims]) around the boundary
 * bricks of the cell from brick c0 (cell_edge bricks per axis), if it has any. */
static int add_cell_box(cdvr_skip_entry *e, const cdvr_skip_grid *g, const size_t c0[3],
                        size_t cell_edge)
{
    size_t lo[3] = {SIZE_MAX, SIZE_MAX, SIZE_MAX}, hi[3] = {0, 0, 0}, end[3];
    for (int a = 0; a < 3; a++)
        end[a] = c0[a] + cell_edge < g->dims[a] ? c0[a] + cell_edge : g->dims[a];
    for (size_t z = c0[2]; z < end[2]; z++)
        for (size_t y = c0[1]; y < end[1]; y++)
            for (size_t x = c0[0]; x < end[0]; x++) {
                if (!boundary_brick(g, x, y, z, g->flags[x + g->dims[0] * (y + g->dims[1] * z)]))
                    continue;
                size_t at[3] = {x, y, z};
                for (int a = 0; a < 3; a++) {
                    lo[a] = at[a] < lo[a] ? at[a] : lo[a];
                    hi[a] = at[a] > hi[a] ? at[a] : hi[a];
                }
            }
    if (lo[0] == SIZE_MAX)
        return 1;
    if (e->count == e->capacity) {
        size_t cap = e->capacity ? 2 * e->capacity : 256;
        float *grown = realloc(e->boxes, cap * 6 * sizeof *grown);
        if (!grown)
            return 0;
        e->boxes = grown;
        e->capacity = cap;
    }
    float *box = e->boxes + 6 * e->count++;
    for (int a = 0; a < 3; a++) {
        double top = (double)g->vol_dims[a];
        box[a] = (float)((double)(lo[a] << g->shift) - 1.0);
        box[3 + a] = (float)fmin((double)((hi[a] + 1) << g->shift) + 1.0, top);
    }
    return 1;
}

cdvr_status cdvr_skip_entry_make(cdvr_skip_entry *e, const cdvr_skip_grid *g, unsigned cell_log2,
                                 cdvr_error *err)
{
    e->count = 0;
    e->version++;
    if (!g->flags_valid)
        return cdvr_error_set(err, CDVR_ERR_ARG, "skip entry list: the grid's flags are not made");
    if (cell_log2 > 8)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "skip entry list: cells of 2^%u bricks (at most 2^8)", cell_log2);
    memcpy(e->vol_dims, g->vol_dims, sizeof e->vol_dims);
    size_t edge = (size_t)1 << cell_log2, c[3];
    for (c[2] = 0; c[2] < g->dims[2]; c[2] += edge)
        for (c[1] = 0; c[1] < g->dims[1]; c[1] += edge)
            for (c[0] = 0; c[0] < g->dims[0]; c[0] += edge)
                if (!add_cell_box(e, g, c, edge)) {
                    e->count = 0;
                    return cdvr_error_set(err, CDVR_ERR_NOMEM, "skip entry list: no memory for "
                                          "%zu boxes", 2 * e->capacity);
                }
    return CDVR_OK;
}

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The view as three affine maps of a grid point q (voxel units): its view depth (along f) and
 * its offsets along r and u from the eye, each base[m] + sum over axes a of q_a coef[m][a]
 * (the world point origin + D (q * spacing), less the eye, dotted with f, r, u): no matrix
 * product per box corner (moving cameras make the entry tiles every frame: Colin27 512^2,
 * 1.1 ms of host time per frame with one). */
typedef struct view_map {
    double base[3], coef[3][3]; /* [0] depth, [1] along r, [2] along u */
} view_map;

static view_map view_map_of(const cdvr_skip_view *v)
{
    const double *axis[3] = {v->f, v->r, v->u};
    double from_eye[3];
    for (int r = 0; r < 3; r++)
        from_eye[r] = v->origin[r] - v->eye[r];
    view_map m;
    for (int i = 0; i < 3; i++) {
        m.base[i] = dot3(from_eye, axis[i]);
        for (int a = 0; a < 3; a++) {
            double column = 0.0; /* D's column a, dotted with the axis */
            for (int r = 0; r < 3; r++)
                column += v->direction[3 * r + a] * axis[i][r];
            m.coef[i][a] = column * v->spacing[a];
        }
    }
    return m;
}

/* The eight corners (k: bit 0 x, 1 y, 2 z from hi) of grid box lo..hi through the view map m,
 * each its depth and its offsets along r and u: the lower corner plus sums of the box's three
 * edges. */
static void box_corners(const view_map *m, const double lo[3], const double hi[3],
                        double at[8][3])
{
    for (int i = 0; i < 3; i++) {
        double low = m->base[i], edge[3];
        for (int a = 0; a < 3; a++) {
            low += lo[a] * m->coef[i][a];
            edge[a] = (hi[a] - lo[a]) * m->coef[i][a];
        }
        for (int k = 0; k < 8; k++)
            at[k][i] = low + (k & 1 ? edge[0] : 0.0) + (k & 2 ? edge[1] : 0.0) +
                       (k & 4 ? edge[2] : 0.0);
    }
}

/* The least and greatest view depth of grid box lo..hi and its pixel rectangle [x0, x1] x
 * [y0, y1] (a pixel of margin, clamped to the image); 0 when it covers no pixel or lies behind
 * the eye. Screen positions in pixel units, pixel centres at whole numbers: x from the
 * offset along r over depth tan_half aspect (over ortho_half_height aspect when
 * orthographic), y from minus the offset along u over depth tan_half, mapped from [-1, 1]. */
static int box_footprint(const cdvr_skip_view *v, const view_map *m, const double lo[3],
                         const double hi[3], double *depth_min, double *depth_max, int rect[4])
{
    double x_lo = INFINITY, x_hi = -INFINITY, y_lo = INFINITY, y_hi = -INFINITY;
    double d_lo = INFINITY, d_hi = -INFINITY, inv_aspect = 1.0 / v->aspect;
    double corners[8][3];
    box_corners(m, lo, hi, corners);
    for (int k = 0; k < 8; k++) {
        const double *at = corners[k];
        double depth = at[0];
        if (!(depth > 0.0))
            return 0;
        double inv_scale = 1.0 / (v->orthographic ? v->ortho_half_height : depth * v->tan_half);
        double sx = at[1] * inv_scale * inv_aspect, sy = -at[2] * inv_scale;
        double px = (sx + 1.0) * 0.5 * v->width - 0.5, py = (sy + 1.0) * 0.5 * v->height - 0.5;
        d_lo = depth < d_lo ? depth : d_lo;
        d_hi = depth > d_hi ? depth : d_hi;
        x_lo = px < x_lo ? px : x_lo;
        x_hi = px > x_hi ? px : x_hi;
        y_lo = py < y_lo ? py : y_lo;
        y_hi = py > y_hi ? py : y_hi;
    }
    *depth_min = d_lo;
    *depth_max = d_hi;
    x_lo = fmax(floor(x_lo) - 1.0, 0.0);
    y_lo = fmax(floor(y_lo) - 1.0, 0.0);
    x_hi = fmin(ceil(x_hi) + 1.0, v->width - 1.0);
    y_hi = fmin(ceil(y_hi) + 1.0, v->height - 1.0);
    if (!(x_lo <= x_hi && y_lo <= y_hi))
        return 0;
    rect[0] = (int)x_lo;
    rect[1] = (int)x_hi;
    rect[2] = (int)y_lo;
    rect[3] = (int)y_hi;
    return 1;
}

/* The pixel-centre coordinate in [-1, 1] of the tile's pixel [i0, i1] (of n) nearest 0 (the
 * axis), or (far) farthest from it. */
static double tile_axis(int i0, int i1, int n, int far)
{
    double a = 2.0 * (i0 + 0.5) / n - 1.0, b = 2.0 * (i1 + 0.5) / n - 1.0;
    if (far)
        return fabs(a) > fabs(b) ? a : b;
    return a <= 0.0 && b >= 0.0 ? 0.0 : fabs(a) < fabs(b) ? a : b;
}

/* Turns the tiles' least (far: greatest) depths into bounds of t: t = depth / cos(ray, f) on
 * a perspective ray, so dividing by the tile's largest (far: smallest) cosine keeps a lower
 * (upper) bound; on an orthographic ray t is the depth. */
static void depth_to_t(const cdvr_skip_view *v, int tile_w, int tile_h, size_t tiles_x,
                       size_t tiles_y, int far, float *tiles)
{
    for (size_t ty = 0; ty < tiles_y; ty++)
        for (size_t tx = 0; tx < tiles_x; tx++) {
            float *t = tiles + ty * tiles_x + tx;
            if (!isfinite(*t) || v->orthographic)
                continue;
            int x0 = (int)tx * tile_w, y0 = (int)ty * tile_h;
            int x1 = x0 + tile_w - 1, y1 = y0 + tile_h - 1;
            x1 = x1 < v->width ? x1 : v->width - 1; /* the image's last tiles are cut */
            y1 = y1 < v->height ? y1 : v->height - 1;
            double sx = tile_axis(x0, x1, v->width, far) * v->aspect;
            double sy = tile_axis(y0, y1, v->height, far);
            double cosine = 1.0 / sqrt(1.0 + (sx * sx + sy * sy) * v->tan_half * v->tan_half);
            *t = (float)(*t / cosine * (far ? 1.0 + 1e-6 : 1.0 - 1e-6));
        }
}

/* cdvr_skip_entry_tiles into entry, and with exit (not NULL) the exit bounds into exit:
 * one projection of the boxes for both. */
static int bound_tiles(const cdvr_skip_entry *e, const cdvr_skip_view *v, int tile_w,
                       int tile_h, size_t tiles_x, size_t tiles_y, float *entry, float *exit)
{
    double vol_lo[3] = {-1.0, -1.0, -1.0}, vol_hi[3];
    for (int a = 0; a < 3; a++)
        vol_hi[a] = (double)e->vol_dims[a];
    view_map map = view_map_of(v);
    double corners[8][3];
    box_corners(&map, vol_lo, vol_hi, corners);
    for (int k = 0; k < 8; k++) /* every box corner in front of the eye */
        if (!(corners[k][0] > 0.0))
            return 0;
    size_t n = tiles_x * tiles_y;
    if (n == 0)
        return 1;
    for (size_t i = 0; i < n; i++) {
        entry[i] = INFINITY;
        if (exit)
            exit[i] = -INFINITY;
    }
    for (size_t b = 0; b < e->count; b++) {
        const float *box = e->boxes + 6 * b;
        double lo[3] = {box[0], box[1], box[2]}, hi[3] = {box[3], box[4], box[5]}, near, deep;
        int rect[4];
        if (!box_footprint(v, &map, lo, hi, &near, &deep, rect))
            continue;
        /* rounded outwards, in float */
        float d_near = (float)(near * (1.0 - 1e-6)), d_far = (float)(deep * (1.0 + 1e-6));
        size_t tx1 = (size_t)(rect[1] / tile_w), ty1 = (size_t)(rect[3] / tile_h);
        tx1 = tx1 < tiles_x ? tx1 : tiles_x - 1;
        ty1 = ty1 < tiles_y ? ty1 : tiles_y - 1;
        for (size_t ty = (size_t)(rect[2] / tile_h); ty <= ty1; ty++)
            for (size_t tx = (size_t)(rect[0] / tile_w); tx <= tx1; tx++) {
                size_t t = ty * tiles_x + tx;
                entry[t] = d_near < entry[t] ? d_near : entry[t];
                if (exit)
                    exit[t] = d_far > exit[t] ? d_far : exit[t];
            }
    }
    depth_to_t(v, tile_w, tile_h, tiles_x, tiles_y, 0, entry);
    if (exit)
        depth_to_t(v, tile_w, tile_h, tiles_x, tiles_y, 1, exit);
    return 1;
}

int cdvr_skip_entry_tiles(const cdvr_skip_entry *e, const cdvr_skip_view *v, int tile_w,
                          int tile_h, size_t tiles_x, size_t tiles_y, float *tiles)
{
    return bound_tiles(e, v, tile_w, tile_h, tiles_x, tiles_y, tiles, NULL);
}

int cdvr_skip_entry_exit_tiles(const cdvr_skip_entry *e, const cdvr_skip_view *v, int tile_w,
                               int tile_h, size_t tiles_x, size_t tiles_y, float *entry,
                               float *exit)
{
    return bound_tiles(e, v, tile_w, tile_h, tiles_x, tiles_y, entry, exit);
}
