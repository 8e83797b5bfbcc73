/* cdvr/visible.h - a store chunk decoded only where a composite ray cast looks.
 *
 * For a chunk whose codec decodes by cells (codec.h decode_cells: hvq, zfp), one timestep of
 * a store of one brick with a range table of bricks at least the ray caster's (store.h): the
 * skip grid for the TF comes from the table, only the cells the render reads are decoded
 * (cdvr_skip_cells_needed), the others get a transparent fill, and a linear frame's grid is
 * refined to exact ranges (cdvr_skip_refine). The image is the one of the whole frame (the
 * player does the same per group, cdvr/player.h). cdvr.render of such a chunk on cl takes
 * this path when the chunk is decoded on the host anyway (a fetch-mode codec's bulk path,
 * or a codec without kernels); render stats report the share of cells decoded. */
#ifndef CDVR_VISIBLE_H
#define CDVR_VISIBLE_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/skip.h"
#include "cdvr/store.h"
#include "cdvr/tf.h"

/* The skip grid (the ray caster's bricks, CDVR_RANGE_SHIFT; allocated for info's dims) of
 * frame `frame` of a chunk group for tf from its range tables (store.h; tables[b]: brick b's
 * chunk's table, every brick's of bricks of 2^shift, at least grid's): the tables' ranges
 * merged over the store's bricks (cdvr_range_merge), made at the tables' bricks in coarse
 * (allocated or remade as needed; its minmax NULL at first) when coarser, and spread over
 * grid (cdvr_skip_grid_expand). The player and cdvr_visible_decode make their grids so. */
cdvr_status cdvr_visible_table_grid(cdvr_skip_grid *grid, cdvr_skip_grid *coarse,
                                    const cdvr_store_info *info, unsigned shift,
                                    const uint8_t *const *tables, size_t frame,
                                    const cdvr_tf *tf, cdvr_error *err);

/* The decode by cells of chunk c of variant v from its payload into frame (layout: linear,
 * or tiled with grid's bricks as tiles, shift 2), grid's flags made: the cells a composite
 * render reads (cdvr_skip_cells_needed, with gradients or not), fill in the others
 * (cdvr_skip_transparent_fill's value). Then a linear frame from range tables coarser than
 * grid has grid refined to exact ranges (cdvr_skip_refine on `threads` threads, 0: the online
 * cores; on failure the coarse grid stays, which renders the same image). need: 2 * nbricks
 * bytes of scratch. *share: the share of cells decoded (0 .. 1). The player and
 * cdvr_visible_decode decode so. Errors: the codec's. */
cdvr_status cdvr_visible_decode_cells(const cdvr_store *st, size_t v, size_t c,
                                      const uint8_t *payload, uint8_t *frame, unsigned layout,
                                      cdvr_skip_grid *grid, const cdvr_tf *tf, int gradients,
                                      uint8_t fill, unsigned threads, uint8_t *need,
                                      double *share, cdvr_error *err);

/* cdvr_visible_decode_cells in two halves, for a caller that serialises the codec's work
 * (the player: a codec that decodes on all cores decodes one chunk at a time) but not the
 * rest: cells_decode marks the cells the render reads in need (its first nbricks bytes),
 * sets *share and decodes them (errors: the codec's); cells_finish then fills the other
 * cells and refines the grid, as above. */
cdvr_status cdvr_visible_cells_decode(const cdvr_store *st, size_t v, size_t c,
                                      const uint8_t *payload, uint8_t *frame, unsigned layout,
                                      const cdvr_skip_grid *grid, int gradients, uint8_t *need,
                                      double *share, cdvr_error *err);
void cdvr_visible_cells_finish(const cdvr_store *st, size_t v, size_t c, uint8_t *frame,
                               unsigned layout, cdvr_skip_grid *grid, const cdvr_tf *tf,
                               uint8_t fill, unsigned threads, uint8_t *need);

/* The frame, its grid and their scratch, reused from one decode to the next. */
typedef struct cdvr_visible cdvr_visible;

cdvr_status cdvr_visible_create(cdvr_visible **out, cdvr_error *err);
void cdvr_visible_free(cdvr_visible *vis);

/* Whether chunk c of variant v of st can be decoded by visible cells (see above). */
int cdvr_visible_applies(const cdvr_store *st, size_t v, size_t c);

/* Decodes chunk c of variant v (cdvr_visible_applies) for a composite render with tf, with
 * gradients (shading or gradient opacity) or not, into the frame (linear). *applied 0 (and
 * nothing decoded) when the fill cannot be transparent for this TF
 * (cdvr_skip_transparent_fill): decode it whole then. Errors: the store's (reading, checking,
 * decoding) and CDVR_ERR_NOMEM. */
cdvr_status cdvr_visible_decode(cdvr_visible *vis, const cdvr_store *st, size_t v, size_t c,
                                const cdvr_tf *tf, int gradients, int *applied,
                                cdvr_error *err);

/* After a decode that applied: the frame (page-aligned, linear, the store's dims; valid
 * until the next decode or free), its grid at the ray caster's bricks (CDVR_RANGE_SHIFT,
 * flags made for the TF) and the share of cells decoded (0 .. 1). */
const uint8_t *cdvr_visible_frame(const cdvr_visible *vis);
const cdvr_skip_grid *cdvr_visible_grid(const cdvr_visible *vis);
double cdvr_visible_share(const cdvr_visible *vis);

#endif
