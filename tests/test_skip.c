/* tests/test_skip.c - empty-space skipping grids on the host (cdvr/skip.h): the row-wise
 * chamfer distance equals the chessboard distance by brute force (random seeds, thin and odd
 * grids, one seed in rows of 300 bricks (distances past 255 are 255), no seed, all seeds);
 * flags and the visible box follow their definition; the grid made from a store's range
 * tables (range bricks of 4^3, 8^3, 16^3) equals the one computed from the decoded frame; a coarse grid spread over
 * the 4^3 bricks (cdvr_skip_grid_expand) is conservative and its flags keep their meaning; and
 * the cells a composite render reads, their fills and the refined grid follow their
 * definitions (cdvr_skip_cells_needed, cdvr_skip_refine); and
 * on the OpenCL device, setup from the recorded ranges (cdvr_cl_setup_grid) renders every
 * pixel exactly as setup from the frame itself (cdvr_cl_setup), taking the same samples with
 * 4^3 tables and at least as many with coarser ones; a store written with 4^3 LZO tables
 * before (tests/data/v2_lzo_store.cdv) reads them as the ranges of its decoded frames; a
 * packed table claiming another size, or index flags claiming two packings, are refused; the
 * entry distances (cdvr_skip_entry_tiles) never lie past the first visible brick of any
 * pixel's ray and the exit distances (cdvr_skip_entry_exit_tiles) never before its last
 * (perspective and orthographic views, axis-aligned and rotated volumes, anisotropic spacing,
 * cells of 1, 2 and 4 bricks) and are off with the eye inside the volume.
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/codec.h"
#include "cdvr/crc32c.h"
#include "cdvr/device.h"
#include "cdvr/skip.h"
#include "cdvr/store.h"
#include "check.h"
#include "store/store_format.h"

static uint32_t rng_state = 12345;

static uint32_t rng(void)
{
    rng_state = rng_state * 1664525u + 1013904223u;
    return rng_state >> 8;
}

static void test_distance(void)
{
    static const size_t grids[][3] = {{1, 1, 1}, {7, 1, 1}, {1, 9, 1}, {1, 1, 6},
                                      {5, 4, 3}, {13, 11, 9}, {33, 2, 17}, {300, 3, 2}};
    for (size_t gi = 0; gi < sizeof grids / sizeof *grids; gi++) {
        const size_t *n = grids[gi];
        size_t count = n[0] * n[1] * n[2];
        uint8_t *seed = malloc(count), *dist = malloc(count);
        for (int density = 0; density < 5; density++) { /* none, sparse, dense, all, one */
            for (size_t b = 0; b < count; b++)
                seed[b] = density == 0 ? 0 : density == 3 ? 1 : density == 4 ? b == 0 :
                          rng() % (density == 1 ? 40 : 3) == 0;
            cdvr_skip_distance(seed, dist, n);
            size_t wrong = 0;
            for (size_t b = 0; b < count; b++) {
                long x = (long)(b % n[0]), y = (long)(b / n[0] % n[1]), z = (long)(b / (n[0] * n[1]));
                long best = 255;
                for (size_t q = 0; q < count; q++) {
                    if (!seed[q])
                        continue;
                    long dx = labs(x - (long)(q % n[0])), dy = labs(y - (long)(q / n[0] % n[1]));
                    long dz = labs(z - (long)(q / (n[0] * n[1])));
                    long d = dx > dy ? dx : dy;
                    d = d > dz ? d : dz;
                    best = d < best ? d : best;
                }
                wrong += dist[b] != best;
            }
            CHECK(wrong == 0, "grid %zux%zux%zu density %d: %zu distances wrong", n[0], n[1],
                  n[2], density, wrong);
        }
        free(seed);
        free(dist);
    }
}

static void tf_window(cdvr_tf *tf, double lo, double hi)
{
    cdvr_tf_point pts[4] = {{0, 0, 0, 0, 0}, {lo, 1, 0.5, 0.2, 0}, {hi, 1, 1, 1, 0.6},
                            {255, 1, 1, 1, 0}};
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(tf, pts, 4, 0, &err), err);
}

/* A field with empty regions and two blobs. */
static void fill_frame(uint8_t *f, const size_t d[3], int t)
{
    for (size_t z = 0; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            for (size_t x = 0; x < d[0]; x++) {
                double a = hypot(hypot((double)x - 10 - t, (double)y - 12), (double)z - 9);
                double b = hypot(hypot((double)x - 30, (double)y - 8 - t), (double)z - 20);
                int v = a < 7 ? (int)(220 - 20 * a) : b < 5 ? (int)(140 - 10 * b) : 0;
                f[x + d[0] * (y + d[1] * z)] = (uint8_t)(v + (int)(rng() % 3));
            }
}

/* g: the 4^3 grid of fill_frame's field of d voxels, its ranges computed; *frame: the field. */
static void blob_grid(cdvr_skip_grid *g, const size_t d[3], uint8_t **frame)
{
    cdvr_error err;
    *frame = malloc(d[0] * d[1] * d[2]);
    fill_frame(*frame, d, 0);
    CHECK_OK(cdvr_skip_grid_init(g, d, 2, &err), err);
    CHECK_OK(cdvr_skip_minmax_from_frame(g, *frame, &err), err);
}

/* blob_grid with its flags for the TF window 100 .. 180 (tf). */
static void flagged_blob_grid(cdvr_skip_grid *g, const size_t d[3], uint8_t **frame, cdvr_tf *tf)
{
    blob_grid(g, d, frame);
    tf_window(tf, 100, 180);
    cdvr_skip_flags(g, tf);
}

static void test_flags(void)
{
    size_t d[3] = {41, 27, 30};
    uint8_t *f;
    cdvr_skip_grid g;
    blob_grid(&g, d, &f);
    CHECK(g.dims[0] == 11 && g.dims[1] == 7 && g.dims[2] == 8, "grid dims");
    cdvr_tf tf;
    tf_window(&tf, 100, 180);
    CHECK(cdvr_skip_flags(&g, &tf) == 1 && cdvr_skip_flags(&g, &tf) == 0, "flags cached per TF");
    size_t visible = 0, bad = 0;
    for (size_t b = 0; b < g.nbricks; b++) {
        int any = 0;
        for (int v = g.minmax[2 * b]; v <= g.minmax[2 * b + 1]; v++)
            any |= tf.table[v][3] > 0;
        visible += any;
        bad += any != (g.flags[b] >= 128) || (g.flags[b] & 127) == 0;
    }
    CHECK(bad == 0 && visible == g.bricks_visible && visible > 0 && visible < g.nbricks,
          "flags: %zu wrong, %zu visible of %zu", bad, visible, g.nbricks);
    tf_window(&tf, 250, 254); /* nothing in range: empty box */
    cdvr_skip_flags(&g, &tf);
    CHECK(g.bricks_visible == 0 && g.visible_lo[0] > g.visible_hi[0], "nothing visible");
    cdvr_skip_grid_free(&g);
    free(f);
}

/* Whether cell c (x, y, z) of g is read by a composite render: some visible brick b with
 * c - b in {0, 1}^3, or {-1, 0, 1}^3 with gradients (cdvr_skip_cells_needed's definition). */
static int cell_read(const cdvr_skip_grid *g, long x, long y, long z, int gradients)
{
    const size_t *n = g->dims;
    for (long dz = -1; dz <= 1; dz++)
        for (long dy = -1; dy <= 1; dy++)
            for (long dx = -1; dx <= 1; dx++) {
                long b[3] = {x - dx, y - dy, z - dz};
                int inside = gradients || (dx >= 0 && dy >= 0 && dz >= 0);
                for (int a = 0; a < 3; a++)
                    inside &= b[a] >= 0 && b[a] < (long)n[a];
                if (inside && g->flags[b[0] + (long)n[0] * (b[1] + (long)n[1] * b[2])] >= 128)
                    return 1;
            }
    return 0;
}

/* The cells a render reads, against their definition; the transparent fill (none when an
 * invisible brick holds values above the TF's visible band); cell and tile fills write the
 * fill into exactly the cells not needed; refine gives the visible bricks of a grid spread
 * from 16^3 ranges their exact ranges when enough are visible, and leaves the grid alone
 * when few are. */
static void test_cells(void)
{
    size_t d[3] = {37, 22, 19};
    uint8_t *f;
    cdvr_skip_grid g;
    cdvr_error err;
    cdvr_tf tf;
    flagged_blob_grid(&g, d, &f, &tf);
    uint8_t *need = malloc(2 * g.nbricks);
    for (int gradients = 0; gradients < 2; gradients++) {
        size_t count = cdvr_skip_cells_needed(&g, gradients, need), wrong = 0, expect = 0;
        for (size_t c = 0; c < g.nbricks; c++) {
            int read = cell_read(&g, (long)(c % g.dims[0]), (long)(c / g.dims[0] % g.dims[1]),
                                 (long)(c / (g.dims[0] * g.dims[1])), gradients);
            expect += (size_t)read;
            wrong += (need[c] != 0) != read;
        }
        CHECK(wrong == 0 && count == expect && count > g.bricks_visible && count < g.nbricks,
              "cells needed (gradients %d): %zu wrong, %zu counted, %zu expected", gradients,
              wrong, count, expect);
    }
    uint8_t fill = 1;
    unsigned lowest = 255;
    for (size_t b = 0; b < g.nbricks; b++)
        lowest = g.flags[b] < 128 && g.minmax[2 * b] < lowest ? g.minmax[2 * b] : lowest;
    CHECK(cdvr_skip_transparent_fill(&g, &fill) && fill == lowest && tf.table[fill][3] == 0,
          "transparent fill %u (lowest invisible value %u)", fill, lowest);

    /* every voxel of a frame of 7s: 99 where its cell is not needed */
    size_t voxels = d[0] * d[1] * d[2], tiled_bytes = cdvr_tiled_bytes(d), wrong = 0;
    uint8_t *linear = malloc(voxels), *tiles = malloc(tiled_bytes);
    memset(linear, 7, voxels);
    memset(tiles, 7, tiled_bytes);
    cdvr_skip_fill_cells(linear, &g, need, 99);
    cdvr_skip_fill_tiles(tiles, &g, need, 99);
    for (size_t z = 0; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            for (size_t x = 0; x < d[0]; x++) {
                uint8_t want = need[x / 4 + g.dims[0] * (y / 4 + g.dims[1] * (z / 4))] ? 7 : 99;
                wrong += linear[x + d[0] * (y + d[1] * z)] != want;
                wrong += tiles[cdvr_tiled_offset(d, x, y, z)] != want;
            }
    CHECK(wrong == 0, "cell and tile fills: %zu voxels wrong", wrong);

    /* refine a grid spread from 16^3 bricks: exact ranges for its visible bricks (a larger
     * volume, where one 16^3 brick is less than 1/16 of the 4^3 ones) */
    size_t big[3] = {70, 60, 50};
    cdvr_skip_grid exact;
    uint8_t *bf, *big_scratch = malloc(2 * 18 * 15 * 13);
    blob_grid(&exact, big, &bf);
    for (int few = 0; few < 2; few++) {
        cdvr_skip_grid coarse, fine;
        CHECK_OK(cdvr_skip_grid_init(&coarse, big, 4, &err), err);
        CHECK_OK(cdvr_skip_grid_init(&fine, big, 2, &err), err);
        CHECK_OK(cdvr_skip_minmax_from_frame(&coarse, bf, &err), err);
        tf_window(&tf, few ? 215 : 100, few ? 230 : 180);
        cdvr_skip_flags(&coarse, &tf);
        CHECK_OK(cdvr_skip_grid_expand(&coarse, &fine, &err), err);
        uint8_t *before = malloc(2 * fine.nbricks), *flags = malloc(fine.nbricks);
        memcpy(before, fine.minmax, 2 * fine.nbricks);
        memcpy(flags, fine.flags, fine.nbricks);
        size_t visible = fine.bricks_visible;
        CHECK_OK(cdvr_skip_refine(&fine, bf, &tf, 2, big_scratch, &err), err);
        size_t off = 0;
        int refines = visible * 16 >= fine.nbricks;
        for (size_t b = 0; b < fine.nbricks; b++) {
            const uint8_t *want = refines && flags[b] >= 128 ? exact.minmax + 2 * b
                                                             : before + 2 * b;
            off += fine.minmax[2 * b] != want[0] || fine.minmax[2 * b + 1] != want[1];
        }
        CHECK(refines == !few && off == 0 && fine.flags_valid &&
              (few ? fine.bricks_visible == visible : fine.bricks_visible < visible),
              "refine (%s visible: %zu of %zu, then %zu): %zu ranges wrong", few ? "few" : "many",
              visible, fine.nbricks, fine.bricks_visible, off);
        free(before);
        free(flags);
        cdvr_skip_grid_free(&coarse);
        cdvr_skip_grid_free(&fine);
    }
    cdvr_skip_grid_free(&exact);
    free(bf);
    free(big_scratch);

    /* bricks of 255 (invisible: the TF's alpha is 0 there) above the visible band: no fill */
    for (size_t z = 12; z < d[2]; z++)
        for (size_t y = 0; y < d[1]; y++)
            memset(f + d[0] * (y + d[1] * z), 255, 8);
    CHECK_OK(cdvr_skip_minmax_from_frame(&g, f, &err), err);
    cdvr_skip_grid_touch(&g);
    tf_window(&tf, 100, 180);
    cdvr_skip_flags(&g, &tf);
    CHECK(!cdvr_skip_transparent_fill(&g, &fill), "no transparent fill around a visible band");
    free(linear);
    free(tiles);
    free(need);
    free(f);
    cdvr_skip_grid_free(&g);
}

/* fine, spread from a coarser grid, against exact (the same bricks, from the frame): every
 * range holds the exact one, visibility follows the ranges under tf, and every brick of the
 * grid within d - 1 of a brick with code d shares its state. */
static void check_expanded(const cdvr_skip_grid *fine, const cdvr_skip_grid *exact,
                           const cdvr_tf *tf)
{
    const size_t *n = fine->dims;
    size_t wide = 0, wrong = 0, visible = 0;
    for (size_t b = 0; b < fine->nbricks; b++) {
        const uint8_t *r = fine->minmax + 2 * b, *e = exact->minmax + 2 * b;
        wide += r[0] > e[0] || r[1] < e[1];
        int any = 0;
        for (int v = r[0]; v <= r[1]; v++)
            any |= tf->table[v][3] > 0;
        int vis = fine->flags[b] >= 128, reach = (fine->flags[b] & 127) - 1;
        visible += (size_t)vis;
        wrong += any != vis || reach < 0;
        long x = (long)(b % n[0]), y = (long)(b / n[0] % n[1]), z = (long)(b / (n[0] * n[1]));
        for (long dz = -reach; dz <= reach; dz++)
            for (long dy = -reach; dy <= reach; dy++)
                for (long dx = -reach; dx <= reach; dx++) {
                    long q[3] = {x + dx, y + dy, z + dz};
                    int inside = 1;
                    for (int a = 0; a < 3; a++)
                        inside &= q[a] >= 0 && q[a] < (long)n[a];
                    if (inside) /* no sample lies past the grid */
                        wrong += (fine->flags[q[0] + (long)n[0] * (q[1] + (long)n[1] * q[2])] >=
                                  128) != vis;
                }
    }
    CHECK(wide == 0 && wrong == 0 && visible == fine->bricks_visible && fine->flags_valid,
          "expanded grid: %zu ranges narrower than exact, %zu flags wrong, %zu visible (%zu)",
          wide, wrong, visible, fine->bricks_visible);
}

/* Encodes three timesteps with range bricks of 2^shift, rebuilds each frame's grid from the
 * range tables and compares with the grid of the decoded frame; a coarser grid is spread over
 * the 4^3 bricks; with OpenCL, renders with both setups. */
static void test_store_grid(unsigned shift)
{
    size_t d[3] = {41, 27, 30};
    cdvr_volume *vol = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(d, 3, CDVR_TYPE_U8, &vol, &err), err);
    for (int t = 0; vol && t < 3; t++)
        fill_frame(cdvr_volume_frame(vol, (size_t)t), d, 3 * t);
    cdvr_variant_spec vs = {.codec = cdvr_codec_find("pvtc"), .lzo_min_saving = -1};
    vs.codec->params_default(&vs.params);
    char path[] = "/tmp/cdvr_test_skip_XXXXXX";
    int fd = mkstemp(path);
    if (fd >= 0)
        close(fd);
    static const size_t grids[2][3] = {{1, 1, 1}, {2, 3, 2}};
    for (int gi = 0; gi < 2 && vol; gi++) {
        cdvr_encode_opts o = {.variants = &vs, .nvariants = 1, .qhi = 255,
                              .range_shift = shift};
        memcpy(o.bricks, grids[gi], sizeof o.bricks);
        cdvr_store *st = NULL;
        CHECK_OK(cdvr_store_encode(vol, &o, path, &err), err);
        CHECK_OK(cdvr_store_open(path, &st, &err), err);
        if (!st)
            break;
        const cdvr_store_info *in = cdvr_store_get_info(st);
        cdvr_skip_grid from_tables, from_frame, fine, fine_exact;
        CHECK_OK(cdvr_skip_grid_init(&from_tables, d, shift, &err), err);
        CHECK_OK(cdvr_skip_grid_init(&from_frame, d, shift, &err), err);
        CHECK_OK(cdvr_skip_grid_init(&fine, d, CDVR_RANGE_SHIFT, &err), err);
        CHECK_OK(cdvr_skip_grid_init(&fine_exact, d, CDVR_RANGE_SHIFT, &err), err);
        for (size_t t = 0; t < in->timesteps; t++) {
            memset(from_tables.minmax, 0, 2 * from_tables.nbricks);
            for (size_t b = 0; b < from_tables.nbricks; b++)
                from_tables.minmax[2 * b] = 255;
            for (size_t b = 0; b < in->nbricks; b++) {
                size_t c = cdvr_store_chunk_for(st, 0, t, b);
                const cdvr_chunk_info *ci = cdvr_store_chunk(st, 0, c);
                size_t n = cdvr_store_ranges_bytes(st, 0, c), lo[3], bd[3], g0[3], wn[3];
                uint8_t *table = malloc(n ? n : 1);
                CHECK_OK(cdvr_store_read_ranges(st, 0, c, table, &err), err);
                cdvr_store_brick_owned(in, b, lo, bd);
                CHECK(ci->ranges_shift == shift, "chunk %zu: range shift %u, %u asked", c,
                      ci->ranges_shift, shift);
                cdvr_range_window(in->dims, lo, bd, shift, g0, wn);
                cdvr_range_merge(table + (t - ci->t0) * 2 * wn[0] * wn[1] * wn[2], g0, wn,
                                 from_tables.dims, from_tables.minmax);
                free(table);
            }
            cdvr_skip_grid_touch(&from_tables);
            cdvr_volume *dec = NULL;
            CHECK_OK(cdvr_store_decode(st, 0, t, &dec, &err), err);
            if (dec) {
                CHECK_OK(cdvr_skip_minmax_from_frame(&from_frame, dec->data, &err), err);
                CHECK_OK(cdvr_skip_minmax_from_frame(&fine_exact, dec->data, &err), err);
            }
            CHECK(memcmp(from_tables.minmax, from_frame.minmax, 2 * from_frame.nbricks) == 0,
                  "shift %u bricks %zu: timestep %zu: recorded ranges differ from the decoded "
                  "frame's", shift, in->nbricks, t);
            cdvr_tf tf;
            tf_window(&tf, 90, 200);
            cdvr_skip_flags(&from_tables, &tf);
            const cdvr_skip_grid *for_device = &from_tables;
            if (shift > CDVR_RANGE_SHIFT) {
                CHECK_OK(cdvr_skip_grid_expand(&from_tables, &fine, &err), err);
                check_expanded(&fine, &fine_exact, &tf);
                for_device = &fine;
            } else {
                CHECK(cdvr_skip_grid_expand(&fine_exact, &fine, &err) == CDVR_ERR_ARG,
                      "a grid without flags is not spread");
            }
#if CDVR_HAVE_OPENCL
            cdvr_cl *cl = NULL;
            cdvr_cl_stream *s = NULL;
            cdvr_cl_open(&cl, &err);
            if (cl && dec && cdvr_cl_stream_create(cl, d, &s, &err) == CDVR_OK) {
                cdvr_camera cam = {.eye = {80, -40, 60}, .center = {20, 13, 15},
                                   .up = {0, 0, 1}, .fov = 35, .width = 96, .height = 80};
                cdvr_render_opts ro = {.tf = &tf, .camera = &cam, .step = 0.5};
                cdvr_image *a = NULL, *b = NULL;
                uint64_t sa = 0, sb = 0;
                CHECK_OK(cdvr_cl_upload_frames(s, dec->data, 1, &err), err);
                CHECK_OK(cdvr_image_create(96, 80, &a, &err), err);
                CHECK_OK(cdvr_image_create(96, 80, &b, &err), err);
                CHECK_OK(cdvr_cl_setup(s, 0, &tf, &err), err);
                CHECK_OK(cdvr_cl_render(s, 0, &ro, dec->spacing, dec->origin, dec->direction,
                                        a, &err), err);
                sa = cdvr_cl_last_samples(s);
                CHECK_OK(cdvr_cl_setup_grid(s, 0, &tf, for_device, &err), err);
                CHECK_OK(cdvr_cl_render(s, 0, &ro, dec->spacing, dec->origin, dec->direction,
                                        b, &err), err);
                sb = cdvr_cl_last_samples(s);
                CHECK(a && b && memcmp(a->rgba, b->rgba, sizeof(float) * 4 * 96 * 80) == 0 &&
                      (shift == CDVR_RANGE_SHIFT ? sa == sb : sb >= sa) && sa > 0,
                      "shift %u timestep %zu: recorded ranges change pixels or samples (%llu "
                      "vs %llu)", shift, t, (unsigned long long)sa, (unsigned long long)sb);
                /* a grid made for another TF is refused */
                cdvr_tf other;
                tf_window(&other, 10, 20);
                CHECK(cdvr_cl_setup_grid(s, 0, &other, for_device, &err) == CDVR_ERR_ARG,
                      "grid for another TF refused");
                /* and the device's own setup works again after a grid was used */
                CHECK_OK(cdvr_cl_setup(s, 0, &tf, &err), err);
                CHECK_OK(cdvr_cl_render(s, 0, &ro, dec->spacing, dec->origin, dec->direction,
                                        b, &err), err);
                CHECK(memcmp(a->rgba, b->rgba, sizeof(float) * 4 * 96 * 80) == 0,
                      "kernel setup after a grid");
                cdvr_image_free(a);
                cdvr_image_free(b);
            }
            cdvr_cl_stream_free(s);
            cdvr_cl_close(cl);
#else
            (void)for_device; /* the device's grid: checked on OpenCL only */
#endif
            cdvr_volume_free(dec);
        }
        cdvr_skip_grid_free(&from_tables);
        cdvr_skip_grid_free(&from_frame);
        cdvr_skip_grid_free(&fine);
        cdvr_skip_grid_free(&fine_exact);
        cdvr_store_close(st);
    }
    unlink(path);
    cdvr_volume_free(vol);
}

/* A store written before 8^3 tables (tests/data/v2_lzo_store.cdv: 4^3 tables, LZO) still
 * gives, from its tables, exactly the ranges of its decoded frames. */
static void test_old_tables(void)
{
    const char *src = getenv("CDVR_SOURCE_DIR");
    char path[4096];
    snprintf(path, sizeof path, "%s/tests/data/v2_lzo_store.cdv", src ? src : "..");
    cdvr_store *st = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!st)
        return;
    const cdvr_store_info *in = cdvr_store_get_info(st);
    cdvr_skip_grid from_tables, from_frame;
    CHECK_OK(cdvr_skip_grid_init(&from_tables, in->dims, CDVR_RANGE_SHIFT, &err), err);
    CHECK_OK(cdvr_skip_grid_init(&from_frame, in->dims, CDVR_RANGE_SHIFT, &err), err);
    for (size_t v = 0; v < in->nvariants; v++)
        for (size_t t = 0; t < in->timesteps; t++) {
            size_t c = cdvr_store_chunk_for(st, v, t, 0);
            const cdvr_chunk_info *ci = cdvr_store_chunk(st, v, c);
            CHECK(ci->ranges_shift == CDVR_RANGE_SHIFT && ci->ranges_stage2 == CDVR_RANGES_LZO,
                  "fixture: 4^3 LZO tables expected (shift %u, stage 2 %d)", ci->ranges_shift,
                  ci->ranges_stage2);
            size_t n = cdvr_store_ranges_bytes(st, v, c), per = 2 * from_tables.nbricks;
            uint8_t *table = malloc(n ? n : 1);
            CHECK_OK(cdvr_store_read_ranges(st, v, c, table, &err), err);
            CHECK(n == per * ci->count, "fixture table of %zu bytes", n);
            cdvr_volume *dec = NULL;
            CHECK_OK(cdvr_store_decode(st, v, t, &dec, &err), err);
            if (dec && n == per * ci->count) {
                CHECK_OK(cdvr_skip_minmax_from_frame(&from_frame, dec->data, &err), err);
                CHECK(memcmp(table + per * (t - ci->t0), from_frame.minmax, per) == 0,
                      "fixture variant %zu timestep %zu: tables differ from the frame", v, t);
            }
            cdvr_volume_free(dec);
            free(table);
        }
    cdvr_skip_grid_free(&from_tables);
    cdvr_skip_grid_free(&from_frame);
    cdvr_store_close(st);
}

static uint8_t *read_file(const char *path, size_t *n)
{
    FILE *in = fopen(path, "rb");
    if (!in)
        return NULL;
    fseek(in, 0, SEEK_END);
    *n = (size_t)ftell(in);
    rewind(in);
    uint8_t *file = malloc(*n);
    if (file && fread(file, 1, *n, in) != *n) {
        free(file);
        file = NULL;
    }
    fclose(in);
    return file;
}

static void write_file(const char *path, const uint8_t *bytes, size_t n)
{
    FILE *out = fopen(path, "wb");
    CHECK(out && fwrite(bytes, 1, n, out) == n, "write %s", path);
    if (out)
        fclose(out);
}

/* A packed range table whose zstd frame claims another size (its CRC fixed) is refused when
 * read, naming the file, chunk and table; index flags claiming LZO and packed at once are
 * refused at open. */
static void test_hostile_tables(void)
{
    size_t d[3] = {41, 27, 30};
    cdvr_volume *vol = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(d, 1, CDVR_TYPE_U8, &vol, &err), err);
    if (!vol)
        return;
    fill_frame(cdvr_volume_frame(vol, 0), d, 0);
    cdvr_variant_spec vs = {.codec = cdvr_codec_find("raw"), .lzo_min_saving = -1};
    vs.codec->params_default(&vs.params);
    char path[] = "/tmp/cdvr_test_skiph_XXXXXX", bad[64];
    int fd = mkstemp(path);
    if (fd >= 0)
        close(fd);
    snprintf(bad, sizeof bad, "%s_bad", path);
    cdvr_encode_opts o = {.variants = &vs, .nvariants = 1, .qhi = 255, .bricks = {1, 1, 1}};
    CHECK_OK(cdvr_store_encode(vol, &o, path, &err), err);
    cdvr_volume_free(vol);
    size_t n = 0;
    uint8_t *file = read_file(path, &n);
    cdvr_store *st = NULL;
    CHECK_OK(cdvr_store_open(path, &st, &err), err);
    if (!file || !st) {
        free(file);
        cdvr_store_close(st);
        unlink(path);
        return;
    }
    cdvr_chunk_info *ci = (cdvr_chunk_info *)cdvr_store_chunk(st, 0, 0);
    CHECK(ci->ranges_shift == CDVR_RANGE_SHIFT_DEFAULT && ci->ranges_stage2 == CDVR_RANGES_PACKED,
          "a packed 8^3 table (shift %u, stage 2 %d)", ci->ranges_shift, ci->ranges_stage2);
    /* zstd frame header: magic (4), descriptor (1), then the content size: claim one more */
    uint8_t *table = file + ci->ranges_offset;
    uint64_t meta = 256 + 160 + 128;
    uint8_t saved[128];
    memcpy(saved, file + 256 + 160, sizeof saved);
    table[5] = (uint8_t)(table[5] + 2);
    ci->ranges_crc32c = cdvr_crc32c(0, table, (size_t)ci->ranges_stored_bytes);
    cdvr_store_serialize_meta(st, file);
    write_file(bad, file, n);
    cdvr_store *hs = NULL;
    CHECK_OK(cdvr_store_open(bad, &hs, &err), err);
    if (hs) {
        uint8_t *out = malloc(cdvr_store_ranges_bytes(hs, 0, 0));
        cdvr_status s = cdvr_store_read_ranges(hs, 0, 0, out, &err);
        CHECK(s == CDVR_ERR_CORRUPT && strstr(err.msg, bad) && strstr(err.msg, "chunk 1") &&
                  strstr(err.msg, "range table"), "hostile packed table: %d '%s'", s, err.msg);
        free(out);
        cdvr_store_close(hs);
    }
    /* flags byte 106 of the chunk record: present + LZO + packed */
    memcpy(file + 256 + 160, saved, sizeof saved);
    file[256 + 160 + 106] = 1 | 2 | 4;
    uint32_t crc = cdvr_crc32c(0, file, (size_t)meta);
    for (int i = 0; i < 4; i++)
        file[meta + (uint64_t)i] = (uint8_t)(crc >> (8 * i));
    write_file(bad, file, n);
    cdvr_status s = cdvr_store_open(bad, &hs, &err);
    CHECK(s == CDVR_ERR_CORRUPT && strstr(err.msg, "reserved"), "LZO and packed at once: %d '%s'",
          s, err.msg);
    if (s == CDVR_OK)
        cdvr_store_close(hs);
    cdvr_store_close(st);
    free(file);
    unlink(path);
    unlink(bad);
}

/* ---- entry distances ------------------------------------------------------------------- */

/* t where the ray o + t d (grid units per t: d) enters box lo..hi, or +inf if it misses. */
static double enter_box(const double o[3], const double d[3], const double lo[3],
                        const double hi[3])
{
    double t0 = -INFINITY, t1 = INFINITY;
    for (int a = 0; a < 3; a++) {
        if (d[a] == 0.0) {
            if (o[a] < lo[a] || o[a] > hi[a])
                return INFINITY;
            continue;
        }
        double u = (lo[a] - o[a]) / d[a], w = (hi[a] - o[a]) / d[a];
        t0 = fmax(t0, fmin(u, w));
        t1 = fmin(t1, fmax(u, w));
    }
    return t0 <= t1 && t1 >= 0.0 ? fmax(t0, 0.0) : INFINITY;
}

/* t where the ray o + t d leaves box lo..hi, or -inf if it misses. */
static double leave_box(const double o[3], const double d[3], const double lo[3],
                        const double hi[3])
{
    if (isinf(enter_box(o, d, lo, hi)))
        return -INFINITY;
    double t1 = INFINITY;
    for (int a = 0; a < 3; a++)
        if (d[a] != 0.0)
            t1 = fmin(t1, fmax((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]));
    return t1;
}

/* The ray of pixel (px, py) as the ray caster casts it (cdvr_skip_view), in the grid: origin
 * and direction per unit of t. */
static void pixel_ray(const cdvr_skip_view *v, int px, int py, double o[3], double d[3])
{
    double sx = (2.0 * (px + 0.5) / v->width - 1.0) * v->aspect;
    double sy = 2.0 * (py + 0.5) / v->height - 1.0, w[3], from[3], len = 0;
    for (int a = 0; a < 3; a++) {
        double side = sx * v->r[a] - sy * v->u[a];
        w[a] = v->orthographic ? v->f[a] : v->f[a] + side * v->tan_half;
        from[a] = v->eye[a] + (v->orthographic ? side * v->ortho_half_height : 0.0);
        len += w[a] * w[a];
    }
    for (int a = 0; a < 3; a++)
        w[a] /= sqrt(len);
    /* D is a rotation here: D^-1 = D^T */
    for (int c = 0; c < 3; c++) {
        o[c] = d[c] = 0;
        for (int r = 0; r < 3; r++) {
            o[c] += v->direction[3 * r + c] * (from[r] - v->origin[r]);
            d[c] += v->direction[3 * r + c] * w[r];
        }
        o[c] /= v->spacing[c];
        d[c] /= v->spacing[c];
    }
}

/* A camera at distance `dist` from the volume's centre (world), looking at it from azimuth
 * az and elevation el (degrees). */
static void orbit(cdvr_skip_view *v, const double centre[3], double dist, double az, double el,
                  int ortho)
{
    double a = az * M_PI / 180, e = el * M_PI / 180;
    double eye[3] = {centre[0] + dist * cos(e) * cos(a), centre[1] + dist * cos(e) * sin(a),
                     centre[2] + dist * sin(e)};
    double up[3] = {0, 0, 1}, fl = 0, dot = 0, ul = 0;
    for (int i = 0; i < 3; i++) {
        v->eye[i] = eye[i];
        v->f[i] = centre[i] - eye[i];
        fl += v->f[i] * v->f[i];
    }
    for (int i = 0; i < 3; i++)
        v->f[i] /= sqrt(fl);
    for (int i = 0; i < 3; i++)
        dot += up[i] * v->f[i];
    for (int i = 0; i < 3; i++) {
        v->u[i] = up[i] - dot * v->f[i];
        ul += v->u[i] * v->u[i];
    }
    for (int i = 0; i < 3; i++)
        v->u[i] /= sqrt(ul);
    v->r[0] = v->f[1] * v->u[2] - v->f[2] * v->u[1];
    v->r[1] = v->f[2] * v->u[0] - v->f[0] * v->u[2];
    v->r[2] = v->f[0] * v->u[1] - v->f[1] * v->u[0];
    v->tan_half = tan(20 * M_PI / 180);
    v->aspect = (double)v->width / v->height;
    v->orthographic = ortho;
    v->ortho_half_height = dist * 0.4;
}

/* Every pixel's ray reaches no visible sample before its tile's entry bound (a visible brick's
 * cells, within the volume's box, entered at t >= bound; none where the bound is +inf) nor
 * after its exit bound (left at t <= bound; -inf exactly where the entry is +inf), and some
 * tiles get +inf. Returns how many pixels' entry bounds lie past the volume's near face and
 * their exit bounds before its far face. */
static size_t check_entry_view(const cdvr_skip_grid *g, const cdvr_skip_entry *e,
                               const cdvr_skip_view *v, const char *what)
{
    const int tw = 4, th = 4;
    size_t tx = (size_t)(v->width + tw - 1) / tw, ty = (size_t)(v->height + th - 1) / th;
    float *tiles = malloc(tx * ty * sizeof *tiles);
    float *exits = malloc(tx * ty * sizeof *exits);
    float *alone = malloc(tx * ty * sizeof *alone);
    CHECK(cdvr_skip_entry_tiles(e, v, tw, th, tx, ty, alone) == 1, "%s: entry tiles made", what);
    CHECK(cdvr_skip_entry_exit_tiles(e, v, tw, th, tx, ty, tiles, exits) == 1,
          "%s: entry and exit tiles made", what);
    CHECK(!memcmp(alone, tiles, tx * ty * sizeof *alone), "%s: entry tiles alone differ", what);
    free(alone);
    size_t early = 0, late = 0, none = 0, bounded = 0, mismatched = 0;
    double vol_lo[3] = {0, 0, 0}, vol_hi[3];
    for (int a = 0; a < 3; a++)
        vol_hi[a] = (double)g->vol_dims[a] - 1.0;
    for (int py = 0; py < v->height; py++)
        for (int px = 0; px < v->width; px++) {
            double o[3], d[3], first = INFINITY, last = -INFINITY;
            pixel_ray(v, px, py, o, d);
            double near = enter_box(o, d, vol_lo, vol_hi), far = leave_box(o, d, vol_lo, vol_hi);
            for (size_t b = 0; b < g->nbricks && isfinite(near); b++) {
                if (g->flags[b] < 128)
                    continue;
                size_t at[3] = {b % g->dims[0], b / g->dims[0] % g->dims[1],
                                b / (g->dims[0] * g->dims[1])};
                double lo[3], hi[3];
                for (int a = 0; a < 3; a++) {
                    lo[a] = fmax((double)(at[a] << g->shift), 0.0);
                    hi[a] = fmin((double)((at[a] + 1) << g->shift), vol_hi[a]);
                }
                first = fmin(first, enter_box(o, d, lo, hi));
                last = fmax(last, leave_box(o, d, lo, hi));
            }
            size_t tile = (size_t)(py / th) * tx + (size_t)(px / tw);
            float bound = tiles[tile], exit = exits[tile];
            early += first < bound;
            late += last > exit;
            none += isinf(bound);
            mismatched += !isinf(bound) != !isinf(exit) || (isfinite(exit) && exit < bound);
            bounded += isfinite(bound) && bound > near + 1.0 && exit < far - 1.0;
        }
    CHECK(early == 0, "%s: %zu rays meet a visible brick before their tile's bound", what,
          early);
    CHECK(late == 0, "%s: %zu rays leave a visible brick after their tile's exit bound", what,
          late);
    CHECK(mismatched == 0, "%s: %zu pixels with an exit bound before their entry or only one "
          "infinite", what, mismatched);
    CHECK(none > 0, "%s: no pixel without a visible brick", what);
    free(tiles);
    free(exits);
    return bounded;
}

static void test_entry(void)
{
    size_t d[3] = {41, 27, 30};
    uint8_t *f;
    cdvr_skip_grid g;
    cdvr_error err;
    cdvr_tf tf;
    flagged_blob_grid(&g, d, &f, &tf);
    cdvr_skip_entry e = {0};
    double c30 = cos(M_PI / 6), s30 = sin(M_PI / 6);
    const double rotation[9] = {c30, -s30, 0, s30, c30, 0, 0, 0, 1};
    for (unsigned cell = 0; cell <= 2; cell++) {
        size_t bounded = 0;
        CHECK_OK(cdvr_skip_entry_make(&e, &g, cell, &err), err);
        CHECK(e.count > 0, "cells of 2^%u bricks: boxes", cell);
        for (int k = 0; k < 6; k++) {
            cdvr_skip_view v;
            memset(&v, 0, sizeof v);
            v.width = 37 + 10 * (k & 1);
            v.height = 29;
            const double spacing[3] = {1.0, 1.3, 0.8}, origin[3] = {-5, 3, 2};
            memcpy(v.spacing, spacing, sizeof spacing);
            memcpy(v.origin, origin, sizeof origin);
            memcpy(v.direction, k >= 3 ? rotation : (const double[9]){1, 0, 0, 0, 1, 0, 0, 0, 1},
                   sizeof v.direction);
            double centre[3];
            for (int r = 0; r < 3; r++) {
                centre[r] = origin[r];
                for (int c = 0; c < 3; c++)
                    centre[r] += v.direction[3 * r + c] * 0.5 * (double)(d[c] - 1) * spacing[c];
            }
            orbit(&v, centre, 90, 30 + 70 * k, k == 2 ? -60 : 25, k == 4);
            char what[80];
            snprintf(what, sizeof what, "cells 2^%u, view %d", cell, k);
            bounded += check_entry_view(&g, &e, &v, what);
            if (k == 0) { /* an eye inside the volume: no bound */
                memcpy(v.eye, centre, sizeof centre);
                float tile;
                CHECK(cdvr_skip_entry_tiles(&e, &v, 4, 4, 1, 1, &tile) == 0,
                      "eye inside: no entry tiles");
            }
        }
        CHECK(bounded > 0, "cells of 2^%u bricks: no bound past the volume's face", cell);
    }
    tf_window(&tf, 250, 254); /* nothing visible: every tile +inf */
    cdvr_skip_flags(&g, &tf);
    CHECK_OK(cdvr_skip_entry_make(&e, &g, 2, &err), err);
    CHECK(e.count == 0, "nothing visible: no boxes");
    cdvr_skip_entry_free(&e);
    cdvr_skip_grid_free(&g);
    free(f);
}

int main(void)
{
    test_distance();
    test_flags();
    test_cells();
    test_entry();
    test_store_grid(CDVR_RANGE_SHIFT);
    test_store_grid(3);
    test_store_grid(4);
    test_old_tables();
    test_hostile_tables();
    return check_finish();
}
