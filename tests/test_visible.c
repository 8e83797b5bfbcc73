/* tests/test_visible.c - cdvr/visible.h: a store chunk decoded only where a composite ray cast
 * looks. An hvq store (decode by cells, one brick, range tables of 8^3 bricks) of a volume
 * whose dims are no multiple of 4, with empty space, a bright ball and sparse dim voxels:
 *  - cdvr_visible_decode gives the whole decode's voxels in every visible brick and the
 *    transparent fill or the whole decode's voxel elsewhere, decodes only part of the frame,
 *    and its grid's visible bricks have the frame's exact ranges (the refine);
 *  - cdvr_visible_cells_decode then cdvr_visible_cells_finish (the player's two halves) give
 *    the frame, grid and share of cdvr_visible_decode_cells in one call, byte for byte,
 *    whatever the frame held before (two different fillings), with and without gradients;
 *  - a chunk that cannot decode by cells is refused by name. */
#include "check.h"

#include "cdvr/bricks.h"
#include "cdvr/codec.h"
#include "cdvr/skip.h"
#include "cdvr/store.h"
#include "cdvr/tf.h"
#include "cdvr/visible.h"
#include "cdvr/volume.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define T 2

static const size_t DIMS[3] = {37, 30, 26};

static cdvr_volume *make_volume(void)
{
    cdvr_volume *v = NULL;
    cdvr_error err;
    if (cdvr_volume_create(DIMS, T, CDVR_TYPE_U8, &v, &err) != CDVR_OK)
        return NULL;
    uint8_t *p = v->data;
    for (size_t t = 0; t < T; t++)
        for (size_t z = 0; z < DIMS[2]; z++)
            for (size_t y = 0; y < DIMS[1]; y++)
                for (size_t x = 0; x < DIMS[0]; x++) {
                    double dx = (double)x - 11 - 3.0 * t, dy = (double)y - 10, dz = (double)z - 8;
                    double r = dx * dx + dy * dy + dz * dz;
                    *p++ = (uint8_t)(r < 80 ? 240 - 2 * r : (x * 7 + y * 3 + z) % 29 == 0 ? 35 : 0);
                }
    return v;
}

/* Values up to 60 transparent: the sparse voxels (35) only count through interpolation. */
static void make_tf(cdvr_tf *tf)
{
    cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {60, 0, 0, 0, 0}, {120, 0.9, 0.5, 0.2, 0.3},
                           {255, 1, 1, 1, 0.9}};
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(tf, pts, 4, 0, &err), err);
}

static size_t voxel_brick(const cdvr_skip_grid *g, size_t x, size_t y, size_t z)
{
    unsigned s = g->shift;
    return (x >> s) + g->dims[0] * ((y >> s) + g->dims[1] * (z >> s));
}

/* cdvr_visible_decode of timestep t against the whole decode `whole`. */
static void check_decode(const cdvr_store *st, size_t t, const uint8_t *whole, const cdvr_tf *tf)
{
    cdvr_visible *vis = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_visible_create(&vis, &err), err);
    if (!vis)
        return;
    int applied = 0;
    CHECK_OK(cdvr_visible_decode(vis, st, 0, t, tf, 0, &applied, &err), err);
    CHECK(applied, "timestep %zu: the decode by cells did not apply", t + 1);
    if (!applied) {
        cdvr_visible_free(vis);
        return;
    }
    const uint8_t *frame = cdvr_visible_frame(vis);
    const cdvr_skip_grid *g = cdvr_visible_grid(vis);
    double share = cdvr_visible_share(vis);
    CHECK(share > 0 && share < 1, "timestep %zu: decoded share %g", t + 1, share);
    uint8_t fill = 0;
    CHECK(cdvr_skip_transparent_fill(g, &fill), "timestep %zu: no transparent fill", t + 1);
    size_t wrong_visible = 0, wrong_other = 0, filled = 0, visible_bricks = 0;
    for (size_t z = 0; z < DIMS[2]; z++)
        for (size_t y = 0; y < DIMS[1]; y++)
            for (size_t x = 0; x < DIMS[0]; x++) {
                size_t i = x + DIMS[0] * (y + DIMS[1] * z);
                int visible = g->flags[voxel_brick(g, x, y, z)] >= 128;
                wrong_visible += visible && frame[i] != whole[i];
                wrong_other += !visible && frame[i] != whole[i] && frame[i] != fill;
                filled += frame[i] != whole[i];
            }
    for (size_t b = 0; b < g->nbricks; b++)
        visible_bricks += g->flags[b] >= 128;
    CHECK(visible_bricks > 0 && visible_bricks < g->nbricks, "timestep %zu: %zu of %zu bricks "
          "visible", t + 1, visible_bricks, g->nbricks);
    CHECK(wrong_visible == 0, "timestep %zu: %zu voxels of visible bricks differ from the whole "
          "decode", t + 1, wrong_visible);
    CHECK(wrong_other == 0, "timestep %zu: %zu other voxels neither decoded nor the fill %u",
          t + 1, wrong_other, fill);
    CHECK(filled > 0, "timestep %zu: no voxel was left to the fill", t + 1);
    /* the refine: a visible brick's range is that of its voxels and their apron in the frame */
    cdvr_skip_grid exact;
    CHECK_OK(cdvr_skip_grid_init(&exact, DIMS, g->shift, &err), err);
    CHECK_OK(cdvr_skip_minmax_from_frame(&exact, frame, &err), err);
    size_t inexact = 0;
    for (size_t b = 0; b < g->nbricks; b++)
        inexact += g->flags[b] >= 128 && (g->minmax[2 * b] != exact.minmax[2 * b] ||
                                          g->minmax[2 * b + 1] != exact.minmax[2 * b + 1]);
    CHECK(inexact == 0, "timestep %zu: %zu visible bricks without their exact range", t + 1,
          inexact);
    cdvr_skip_grid_free(&exact);
    cdvr_visible_free(vis);
}

/* The grid of chunk c for tf from its range table, as cdvr_visible_decode makes it. */
static int table_grid(const cdvr_store *st, size_t c, const cdvr_tf *tf, cdvr_skip_grid *g,
                      cdvr_skip_grid *coarse, uint8_t *ranges)
{
    cdvr_error err;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    const uint8_t *tables[1] = {ranges};
    cdvr_status s = cdvr_skip_grid_init(g, DIMS, CDVR_RANGE_SHIFT, &err);
    if (s == CDVR_OK)
        s = cdvr_store_read_ranges(st, 0, c, ranges, &err);
    if (s == CDVR_OK)
        s = cdvr_visible_table_grid(g, coarse, info, cdvr_store_chunk(st, 0, c)->ranges_shift,
                                    tables, 0, tf, &err);
    CHECK_OK(s, err);
    return s == CDVR_OK;
}

/* One call against the two halves on frames that held different bytes before. */
static void check_halves(const cdvr_store *st, size_t c, const cdvr_tf *tf, int gradients)
{
    cdvr_error err;
    size_t voxels = DIMS[0] * DIMS[1] * DIMS[2];
    uint8_t *payload = NULL, *stored = NULL;
    size_t payload_cap = 0, stored_cap = 0;
    CHECK_OK(cdvr_store_load_payload_into(st, 0, c, &payload, &payload_cap, &stored,
                                          &stored_cap, &err),
             err);
    uint8_t *ranges = malloc(cdvr_store_ranges_bytes(st, 0, c));
    uint8_t *frames[2] = {malloc(voxels), malloc(voxels)};
    cdvr_skip_grid grids[2] = {{0}, {0}}, coarse[2] = {{0}, {0}};
    int ok = payload && ranges && frames[0] && frames[1] &&
             table_grid(st, c, tf, &grids[0], &coarse[0], ranges) &&
             table_grid(st, c, tf, &grids[1], &coarse[1], ranges);
    uint8_t *need[2] = {NULL, NULL};
    if (ok) {
        need[0] = malloc(2 * grids[0].nbricks);
        need[1] = malloc(2 * grids[1].nbricks);
        ok = need[0] && need[1];
    }
    uint8_t fill = 0;
    ok = ok && cdvr_skip_transparent_fill(&grids[0], &fill);
    CHECK(ok, "chunk %zu: set-up failed", c + 1);
    if (ok) {
        memset(frames[0], 0xab, voxels);
        for (size_t i = 0; i < voxels; i++)
            frames[1][i] = (uint8_t)(i * 131 + 7);
        double share[2] = {-1, -1};
        CHECK_OK(cdvr_visible_decode_cells(st, 0, c, payload, frames[0], CDVR_LAYOUT_LINEAR,
                                           &grids[0], tf, gradients, fill, 1, need[0], &share[0],
                                           &err),
                 err);
        CHECK_OK(cdvr_visible_cells_decode(st, 0, c, payload, frames[1], CDVR_LAYOUT_LINEAR,
                                           &grids[1], gradients, need[1], &share[1], &err),
                 err);
        cdvr_visible_cells_finish(st, 0, c, frames[1], CDVR_LAYOUT_LINEAR, &grids[1], tf, fill, 2,
                                  need[1]);
        CHECK(share[0] == share[1] && share[0] > 0 && share[0] < 1,
              "chunk %zu, gradients %d: shares %g and %g", c + 1, gradients, share[0], share[1]);
        CHECK(memcmp(frames[0], frames[1], voxels) == 0,
              "chunk %zu, gradients %d: the two halves' frame differs from the one call's", c + 1,
              gradients);
        CHECK(memcmp(grids[0].flags, grids[1].flags, grids[0].nbricks) == 0 &&
                  memcmp(grids[0].minmax, grids[1].minmax, 2 * grids[0].nbricks) == 0,
              "chunk %zu, gradients %d: the two halves' grid differs from the one call's",
              c + 1, gradients);
    }
    for (int k = 0; k < 2; k++) {
        free(need[k]);
        free(frames[k]);
        cdvr_skip_grid_free(&grids[k]);
        cdvr_skip_grid_free(&coarse[k]);
    }
    free(ranges);
    free(payload);
    free(stored);
}

int main(void)
{
    cdvr_volume *vol = make_volume();
    char path[] = "/tmp/cdvr_test_visible_XXXXXX";
    int fd = mkstemp(path);
    if (fd >= 0)
        close(fd);
    cdvr_variant_spec vs = {.codec = cdvr_codec_find("hvq"), .lzo_min_saving = -1};
    vs.codec->params_default(&vs.params);
    cdvr_encode_opts eo = {.variants = &vs, .nvariants = 1, .qhi = 255};
    cdvr_error err;
    CHECK(vol != NULL, "no volume");
    if (vol)
        CHECK_OK(cdvr_store_encode(vol, &eo, path, &err), err);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    cdvr_tf tf;
    make_tf(&tf);
    for (size_t t = 0; st && t < T; t++) {
        CHECK(cdvr_visible_applies(st, 0, t), "timestep %zu: decode by cells does not apply",
              t + 1);
        cdvr_volume *whole = NULL;
        CHECK_OK(cdvr_store_decode(st, 0, t, &whole, &err), err);
        if (whole)
            check_decode(st, t, whole->data, &tf);
        cdvr_volume_free(whole);
        check_halves(st, t, &tf, 0);
        check_halves(st, t, &tf, 1);
    }
    /* a raw store cannot decode by cells: refused, naming the store */
    char raw_path[64];
    snprintf(raw_path, sizeof raw_path, "%s.raw", path);
    cdvr_variant_spec rs = {.codec = cdvr_codec_find("raw"), .lzo_min_saving = -1};
    rs.codec->params_default(&rs.params);
    cdvr_encode_opts ro = {.variants = &rs, .nvariants = 1, .qhi = 255};
    cdvr_store *raw = NULL;
    if (vol && cdvr_store_encode(vol, &ro, raw_path, &err) == CDVR_OK &&
        cdvr_store_open(raw_path, &raw, &err) == CDVR_OK) {
        cdvr_visible *vis = NULL;
        int applied = 1;
        CHECK(!cdvr_visible_applies(raw, 0, 0), "raw chunk decodes by cells");
        if (cdvr_visible_create(&vis, &err) == CDVR_OK) {
            cdvr_status s = cdvr_visible_decode(vis, raw, 0, 0, &tf, 0, &applied, &err);
            CHECK(s == CDVR_ERR_ARG && !applied && strstr(err.msg, raw_path) &&
                      strstr(err.msg, "visible"),
                  "raw chunk: status %d, applied %d, '%s'", (int)s, applied, err.msg);
        }
        cdvr_visible_free(vis);
    } else {
        CHECK(0, "raw store: %s", err.msg);
    }
    cdvr_store_close(raw);
    cdvr_store_close(st);
    unlink(raw_path);
    unlink(path);
    cdvr_volume_free(vol);
    return check_finish();
}
