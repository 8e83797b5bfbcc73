/* core/render/visible.c - decoding only the cells a composite ray cast reads: the cell
 * functions of cdvr/skip.h and a store chunk decoded by them (cdvr/visible.h). */
#include "cdvr/visible.h"

#include <stdlib.h>
#include <string.h>

#include "cdvr/bricks.h"
#include "cdvr/codec.h"
#include "cdvr/memory.h"
#include "render/cpu/brick_range.h"

/* ---- cells (cdvr/skip.h) ------------------------------------------------------------------ */

/* out[c] = in[c - d] or'ed over d = lo .. 1 (lo 0 or -1) along axis a of a grid of n bricks. */
static void dilate_axis(const uint8_t *in, uint8_t *out, const size_t n[3], int a, int lo)
{
    size_t stride = a == 0 ? 1 : a == 1 ? n[0] : n[0] * n[1], len = n[a];
    size_t outer = n[0] * n[1] * n[2] / (stride * len); /* runs of len * stride bricks */
    if (a == 0) { /* along rows: a byte at a time */
        for (size_t o = 0; o < outer; o++, in += len, out += len)
            for (size_t x = 0; x < len; x++)
                out[x] = in[x] | (x > 0 ? in[x - 1] : 0) |
                         (lo < 0 && x + 1 < len ? in[x + 1] : 0);
        return;
    }
    for (size_t o = 0; o < outer; o++)
        for (size_t at = 0; at < len; at++) {
            const uint8_t *src = in + (o * len + at) * stride;
            uint8_t *dst = out + (o * len + at) * stride;
            memcpy(dst, src, stride);
            for (size_t i = 0; at > 0 && i < stride; i++)
                dst[i] |= src[i - stride];
            for (size_t i = 0; lo < 0 && at + 1 < len && i < stride; i++)
                dst[i] |= src[i + stride];
        }
}

size_t cdvr_skip_cells_needed(const cdvr_skip_grid *g, int gradients, uint8_t *need)
{
    uint8_t *a = need, *b = need + g->nbricks;
    for (size_t i = 0; i < g->nbricks; i++)
        a[i] = g->flags[i] >= 128;
    dilate_axis(a, b, g->dims, 0, gradients ? -1 : 0);
    dilate_axis(b, a, g->dims, 1, gradients ? -1 : 0);
    dilate_axis(a, b, g->dims, 2, gradients ? -1 : 0);
    size_t count = 0;
    for (size_t i = 0; i < g->nbricks; i++)
        count += (a[i] = b[i]) != 0;
    return count;
}

int cdvr_skip_transparent_fill(const cdvr_skip_grid *g, uint8_t *fill)
{
    unsigned lo = 255, hi = 0;
    for (size_t i = 0; i < g->nbricks; i++)
        if (g->flags[i] < 128) {
            lo = g->minmax[2 * i] < lo ? g->minmax[2 * i] : lo;
            hi = g->minmax[2 * i + 1] > hi ? g->minmax[2 * i + 1] : hi;
        }
    for (unsigned v = lo; v <= hi; v++)
        if (g->tf_visible[v])
            return 0;
    *fill = (uint8_t)lo;
    return 1;
}

void cdvr_skip_fill_cells(uint8_t *frame, const cdvr_skip_grid *g, const uint8_t *need,
                          uint8_t fill)
{
    const size_t *dims = g->vol_dims;
    unsigned sh = g->shift;
    for (size_t z = 0; z < dims[2]; z++)
        for (size_t y = 0; y < dims[1]; y++) {
            const uint8_t *cells = need + g->dims[0] * ((y >> sh) + g->dims[1] * (z >> sh));
            uint8_t *row = frame + dims[0] * (y + dims[1] * z);
            for (size_t cx = 0; cx < g->dims[0];) {
                if (cells[cx]) {
                    cx++;
                    continue;
                }
                size_t end = cx;
                while (end < g->dims[0] && !cells[end])
                    end++;
                size_t x0 = cx << sh, x1 = end << sh < dims[0] ? end << sh : dims[0];
                memset(row + x0, fill, x1 - x0);
                cx = end;
            }
        }
}

void cdvr_skip_fill_tiles(uint8_t *tiles, const cdvr_skip_grid *g, const uint8_t *need,
                          uint8_t fill)
{
    const size_t *n = g->dims;
    for (size_t z = 0; z < n[2]; z++)
        for (size_t y = 0; y < n[1]; y++)
            for (size_t x = 0; x < n[0]; x++)
                if (!need[x + n[0] * (y + n[1] * z)])
                    memset(tiles + cdvr_tiled_offset(g->vol_dims, 4 * x, 4 * y, 4 * z), fill, 64);
}

/* Refined only with one visible brick in REFINE_SHARE or more: with fewer, the pass over the
 * frame and the flags made again over the whole grid cost more than the samples they save
 * (Colin27 with 0.3% of its bricks visible: 4 ms more per frame for 0.5 M samples fewer; the
 * engine CT at 18%: the same time, 25% fewer samples). */
#define REFINE_SHARE 16

cdvr_status cdvr_skip_refine(cdvr_skip_grid *g, const uint8_t *frame, const cdvr_tf *tf,
                             unsigned threads, uint8_t *scratch, cdvr_error *err)
{
    size_t visible = 0;
    for (size_t b = 0; b < g->nbricks; b++)
        visible += g->flags[b] >= 128;
    if (visible * REFINE_SHARE < g->nbricks)
        return CDVR_OK;
    cdvr_status s = cdvr_cpu_brick_ranges(frame, g->vol_dims, g->shift, (int)threads, scratch,
                                          err);
    if (s != CDVR_OK)
        return s;
    for (size_t b = 0; b < g->nbricks; b++)
        if (g->flags[b] >= 128) {
            g->minmax[2 * b] = scratch[2 * b];
            g->minmax[2 * b + 1] = scratch[2 * b + 1];
        }
    cdvr_skip_grid_touch(g);
    cdvr_skip_flags(g, tf);
    return CDVR_OK;
}

int cdvr_skip_refine_enabled(void)
{
    const char *e = getenv("CDVR_REFINE");
    return !(e && strcmp(e, "0") == 0);
}

/* ---- a store chunk (cdvr/visible.h) -------------------------------------------------------- */

struct cdvr_visible {
    cdvr_skip_grid grid;   /* the ray caster's bricks; grid.minmax NULL until first made */
    cdvr_skip_grid coarse; /* the table's bricks when coarser */
    uint8_t *ranges, *need, *frame, *payload, *stored; /* payload, stored: the chunk's */
    size_t ranges_cap, need_cap, frame_cap, payload_cap, stored_cap;
    double share;
};

cdvr_status cdvr_visible_create(cdvr_visible **out, cdvr_error *err)
{
    *out = calloc(1, sizeof **out);
    return *out ? CDVR_OK
                : cdvr_error_set(err, CDVR_ERR_NOMEM, "visible cells: out of memory");
}

void cdvr_visible_free(cdvr_visible *vis)
{
    if (!vis)
        return;
    if (vis->grid.minmax)
        cdvr_skip_grid_free(&vis->grid);
    if (vis->coarse.minmax)
        cdvr_skip_grid_free(&vis->coarse);
    free(vis->ranges);
    free(vis->need);
    free(vis->frame);
    free(vis->payload);
    free(vis->stored);
    free(vis);
}

int cdvr_visible_applies(const cdvr_store *st, size_t v, size_t c)
{
    const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
    return ci && cdvr_store_get_info(st)->nbricks == 1 &&
           cdvr_store_chunk_decodes_cells(st, v, c) && ci->ranges_shift >= CDVR_RANGE_SHIFT;
}

/* g as a grid of dims at shift (made anew when either changed). */
static cdvr_status fit_grid(cdvr_skip_grid *g, const size_t dims[3], unsigned shift,
                            cdvr_error *err)
{
    if (g->minmax && g->shift == shift && !memcmp(g->vol_dims, dims, sizeof g->vol_dims))
        return CDVR_OK;
    if (g->minmax)
        cdvr_skip_grid_free(g);
    memset(g, 0, sizeof *g);
    return cdvr_skip_grid_init(g, dims, shift, err);
}

cdvr_status cdvr_visible_table_grid(cdvr_skip_grid *grid, cdvr_skip_grid *coarse,
                                    const cdvr_store_info *info, unsigned shift,
                                    const uint8_t *const *tables, size_t frame,
                                    const cdvr_tf *tf, cdvr_error *err)
{
    cdvr_skip_grid *g = grid;
    if (shift != grid->shift) {
        cdvr_status s = fit_grid(coarse, info->dims, shift, err);
        if (s != CDVR_OK)
            return s;
        g = coarse;
    }
    for (size_t i = 0; i < g->nbricks; i++) {
        g->minmax[2 * i] = 255;
        g->minmax[2 * i + 1] = 0;
    }
    for (size_t b = 0; b < info->nbricks; b++) {
        size_t lo[3], bd[3], g0[3], n[3];
        cdvr_store_brick_owned(info, b, lo, bd);
        cdvr_range_window(info->dims, lo, bd, shift, g0, n);
        cdvr_range_merge(tables[b] + frame * 2 * n[0] * n[1] * n[2], g0, n, g->dims, g->minmax);
    }
    cdvr_skip_grid_touch(g);
    cdvr_skip_flags(g, tf);
    return g == grid ? CDVR_OK : cdvr_skip_grid_expand(g, grid, err);
}

/* vis->grid with flags for tf from chunk c's range table (the store's one brick). */
static cdvr_status make_grid(cdvr_visible *vis, const cdvr_store *st, size_t v, size_t c,
                             const cdvr_tf *tf, cdvr_error *err)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    size_t bytes = cdvr_store_ranges_bytes(st, v, c);
    cdvr_status s = fit_grid(&vis->grid, info->dims, CDVR_RANGE_SHIFT, err);
    if (s != CDVR_OK)
        return s;
    if (!bytes || !cdvr_grow_bytes(&vis->ranges, &vis->ranges_cap, bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: chunk %zu: no memory for its %zu-byte "
                              "range table", cdvr_store_path(st), c + 1, bytes);
    s = cdvr_store_read_ranges(st, v, c, vis->ranges, err);
    const uint8_t *tables[1] = {vis->ranges};
    return s != CDVR_OK ? s
                        : cdvr_visible_table_grid(&vis->grid, &vis->coarse, info,
                                                  cdvr_store_chunk(st, v, c)->ranges_shift,
                                                  tables, 0, tf, err);
}

/* vis->frame with room for a frame of `bytes` (on huge pages: cdvr/memory.h). It grows only
 * for larger dims, whose render made a new stream: the one that read the old frame is gone. */
static cdvr_status fit_frame(cdvr_visible *vis, size_t bytes, cdvr_error *err)
{
    if (!cdvr_grow_large(&vis->frame, &vis->frame_cap, bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "visible cells: no memory for a %zu-byte "
                              "frame", bytes);
    return CDVR_OK;
}

cdvr_status cdvr_visible_cells_decode(const cdvr_store *st, size_t v, size_t c,
                                      const uint8_t *payload, uint8_t *frame, unsigned layout,
                                      const cdvr_skip_grid *grid, int gradients, uint8_t *need,
                                      double *share, cdvr_error *err)
{
    size_t cells = cdvr_skip_cells_needed(grid, gradients, need);
    *share = grid->nbricks ? (double)cells / (double)grid->nbricks : 0;
    return cdvr_store_decode_chunk_cells(st, v, c, payload, frame, layout, need, grid->shift,
                                         err);
}

void cdvr_visible_cells_finish(const cdvr_store *st, size_t v, size_t c, uint8_t *frame,
                               unsigned layout, cdvr_skip_grid *grid, const cdvr_tf *tf,
                               uint8_t fill, unsigned threads, uint8_t *need)
{
    if (layout == CDVR_LAYOUT_TILED)
        cdvr_skip_fill_tiles(frame, grid, need, fill);
    else
        cdvr_skip_fill_cells(frame, grid, need, fill);
    /* tiled frames are not refined: the same from tiles made the player's decode 1.9x as
     * long and its playback 0.9x as fast */
    unsigned table_shift = cdvr_store_chunk(st, v, c)->ranges_shift;
    if (layout != CDVR_LAYOUT_TILED && table_shift > grid->shift && cdvr_skip_refine_enabled()) {
        cdvr_error ignored;
        cdvr_skip_refine(grid, frame, tf, threads, need, &ignored);
    }
}

cdvr_status cdvr_visible_decode_cells(const cdvr_store *st, size_t v, size_t c,
                                      const uint8_t *payload, uint8_t *frame, unsigned layout,
                                      cdvr_skip_grid *grid, const cdvr_tf *tf, int gradients,
                                      uint8_t fill, unsigned threads, uint8_t *need,
                                      double *share, cdvr_error *err)
{
    cdvr_status s = cdvr_visible_cells_decode(st, v, c, payload, frame, layout, grid, gradients,
                                              need, share, err);
    if (s == CDVR_OK)
        cdvr_visible_cells_finish(st, v, c, frame, layout, grid, tf, fill, threads, need);
    return s;
}

cdvr_status cdvr_visible_decode(cdvr_visible *vis, const cdvr_store *st, size_t v, size_t c,
                                const cdvr_tf *tf, int gradients, int *applied, cdvr_error *err)
{
    *applied = 0;
    if (!cdvr_visible_applies(st, v, c))
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: chunk %zu does not decode by visible "
                              "cells", cdvr_store_path(st), c + 1);
    const size_t *dims = cdvr_store_get_info(st)->dims;
    uint8_t fill;
    cdvr_status s = make_grid(vis, st, v, c, tf, err);
    if (s != CDVR_OK || !cdvr_skip_transparent_fill(&vis->grid, &fill))
        return s;
    if (!cdvr_grow_bytes(&vis->need, &vis->need_cap, 2 * vis->grid.nbricks))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "visible cells: no memory for a %zu-cell "
                              "mask", vis->grid.nbricks);
    size_t voxels = dims[0] * dims[1] * dims[2];
    if ((s = fit_frame(vis, voxels, err)) != CDVR_OK)
        return s;
    s = cdvr_store_load_payload_into(st, v, c, &vis->payload, &vis->payload_cap, &vis->stored,
                                     &vis->stored_cap, err);
    if (s == CDVR_OK)
        s = cdvr_visible_decode_cells(st, v, c, vis->payload, vis->frame, CDVR_LAYOUT_LINEAR,
                                      &vis->grid, tf, gradients, fill, 0, vis->need,
                                      &vis->share, err);
    *applied = s == CDVR_OK;
    return s;
}

const uint8_t *cdvr_visible_frame(const cdvr_visible *vis) { return vis->frame; }
const cdvr_skip_grid *cdvr_visible_grid(const cdvr_visible *vis) { return &vis->grid; }
double cdvr_visible_share(const cdvr_visible *vis) { return vis->share; }
