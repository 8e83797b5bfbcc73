/* tests/test_lod.c - the per-slice level of detail of seed 002 (cdvr/gl.h): Table 2's memory
 * figures exactly, the slice axis, distances for off-axis views, level extents and bad input.
 * Plain arithmetic: runs in every build. */
#include <math.h>
#include <string.h>

#include "cdvr/gl.h"
#include "check.h"

#define MIB (1024.0 * 1024.0)

/* The seed's setup: 1024^3 voxels in [-1, 1]^3 (voxel centres span the box). */
static cdvr_grid seed_grid(void)
{
    cdvr_grid g;
    memset(&g, 0, sizeof g);
    for (int a = 0; a < 3; a++) {
        g.dims[a] = 1024;
        g.origin[a] = -1.0;
        g.spacing[a] = 2.0 / 1023.0;
        g.direction[4 * a] = 1.0;
    }
    return g;
}

static void test_table2(void)
{
    /* Table 2: U1 (with LOD) for D = 0.5 .. 1.5, against U2 = 4096 MB, 4 bytes per voxel */
    const double distance[5] = {0.5, 0.75, 1.0, 1.25, 1.5};
    const double expect_mib[5] = {1600, 2176, 2560, 2944, 3328};
    cdvr_grid g = seed_grid();
    for (int i = 0; i < 5; i++) {
        double eye[3] = {0.0, 0.0, -1.0 - distance[i]};
        cdvr_lod_plan plan;
        cdvr_error err;
        cdvr_status st = cdvr_lod_plan_compute(&g, 2, eye, 4, 1, 0.0, &plan, &err);
        CHECK_OK(st, err);
        if (st != CDVR_OK)
            continue;
        CHECK(plan.total_bytes / MIB == expect_mib[i], "D = %g: %g MiB, expected %g",
              distance[i], plan.total_bytes / MIB, expect_mib[i]);
        CHECK(plan.full_bytes / MIB == 4096.0, "D = %g: full %g MiB", distance[i],
              plan.full_bytes / MIB);
        CHECK(fabs(plan.nearest - distance[i]) < 1e-12, "D = %g: nearest %g", distance[i],
              plan.nearest);
        CHECK(plan.levels[0] == 0, "nearest slice at level 0");
        for (size_t k = 1; k < plan.nslices; k++)
            CHECK(plan.levels[k] >= plan.levels[k - 1], "levels grow with distance (k %zu)", k);
        cdvr_lod_plan_free(&plan);
    }
    /* D = 0.5: slices 0..255 at level 0 (d < 1), 256..767 at 1 (d < 2), 768..1023 at 2 */
    double eye[3] = {0.0, 0.0, -1.5};
    cdvr_lod_plan plan;
    CHECK(cdvr_lod_plan_compute(&g, 2, eye, 4, 1, 0.0, &plan, NULL) == CDVR_OK, "plan D = 0.5");
    CHECK(plan.levels[255] == 0 && plan.levels[256] == 1 && plan.levels[767] == 1 &&
              plan.levels[768] == 2 && plan.levels[1023] == 2,
          "D = 0.5 level boundaries %d %d %d %d %d", plan.levels[255], plan.levels[256],
          plan.levels[767], plan.levels[768], plan.levels[1023]);
    cdvr_lod_plan_free(&plan);
    /* lod off: every level 0 */
    CHECK(cdvr_lod_plan_compute(&g, 2, eye, 4, 0, 0.0, &plan, NULL) == CDVR_OK &&
              plan.total_bytes == plan.full_bytes && plan.levels[1023] == 0,
          "lod off keeps level 0");
    cdvr_lod_plan_free(&plan);
}

static void test_extents(void)
{
    CHECK(cdvr_lod_extent(1024, 0) == 1024 && cdvr_lod_extent(1024, 3) == 128, "1024");
    CHECK(cdvr_lod_extent(301, 1) == 151 && cdvr_lod_extent(301, 2) == 76 &&
              cdvr_lod_extent(301, 9) == 1 && cdvr_lod_extent(301, 60) == 1,
          "odd extents round up");
    CHECK(cdvr_lod_extent(1, 0) == 1 && cdvr_lod_extent(1, 5) == 1, "one texel");
    CHECK(cdvr_lod_max_level(256, 128) == 8 && cdvr_lod_max_level(1, 1) == 0 &&
              cdvr_lod_max_level(301, 370) == 9,
          "max levels %d %d %d", cdvr_lod_max_level(256, 128), cdvr_lod_max_level(1, 1),
          cdvr_lod_max_level(301, 370));
    int u, v;
    cdvr_slice_plane_axes(0, &u, &v);
    CHECK(u == 1 && v == 2, "x slices span y, z");
    cdvr_slice_plane_axes(1, &u, &v);
    CHECK(u == 0 && v == 2, "y slices span x, z");
    cdvr_slice_plane_axes(2, &u, &v);
    CHECK(u == 0 && v == 1, "z slices span x, y");
}

static void test_axis_and_distance(void)
{
    cdvr_grid g = seed_grid();
    cdvr_camera cam = {{0, 0, -5}, {0, 0, 0}, {0, 1, 0}, 30, 64, 64, 0, 0};
    CHECK(cdvr_slice_axis(&g, &cam) == 2, "view along z");
    cdvr_camera side = {{4, 1, 0.5}, {0, 0, 0}, {0, 0, 1}, 30, 64, 64, 0, 0};
    CHECK(cdvr_slice_axis(&g, &side) == 0, "view mostly along x");
    /* a rotated grid: index x runs along world y, so a view along world y slices index x */
    cdvr_grid r = g;
    memset(r.direction, 0, sizeof r.direction);
    r.direction[1] = 1.0;  /* column 0 (index x) = world y */
    r.direction[3] = -1.0; /* column 1 (index y) = world -x */
    r.direction[8] = 1.0;
    cdvr_camera along_y = {{0, -6, 0}, {0, 0, 0}, {0, 0, 1}, 30, 64, 64, 0, 0};
    CHECK(cdvr_slice_axis(&r, &along_y) == 0, "rotated grid: axis %d", cdvr_slice_axis(&r, &along_y));

    /* on the axis: plane distance; off the axis: nearest point of the slice rectangle */
    double on_axis[3] = {0.0, 0.0, -2.0};
    CHECK(fabs(cdvr_slice_distance(&g, 2, 0, on_axis) - 1.0) < 1e-12, "on axis, first slice");
    CHECK(fabs(cdvr_slice_distance(&g, 2, 1023, on_axis) - 3.0) < 1e-12, "on axis, last slice");
    double off[3] = {4.0, 0.0, -2.0}; /* 3 units beside the box's x = 1 face */
    CHECK(fabs(cdvr_slice_distance(&g, 2, 0, off) - sqrt(9.0 + 1.0)) < 1e-12,
          "off axis: nearest corner edge %g", cdvr_slice_distance(&g, 2, 0, off));
    double inside[3] = {0.0, 0.0, 0.0};
    CHECK(cdvr_slice_distance(&g, 2, 0, inside) == 1.0, "inside: plane distance");
    /* inside the stack: D is clamped to half a slice spacing, the nearest slices stay at 0 */
    double on_slice[3] = {0.0, 0.0, -1.0 + 2.0 * 100 / 1023.0};
    cdvr_lod_plan plan;
    CHECK(cdvr_lod_plan_compute(&g, 2, on_slice, 1, 1, 0.0, &plan, NULL) == CDVR_OK &&
              plan.nearest == 0.5 * g.spacing[2] && plan.levels[100] == 0 &&
              plan.levels[1023] == 10,
          "eye on a slice: nearest %g, levels %d %d", plan.nearest, plan.levels[100],
          plan.levels[1023]);
    cdvr_lod_plan_free(&plan);
}

/* CDVR_LOD_SCREEN: D is at least the distance where a texel spans a pixel. */
static void test_screen(void)
{
    cdvr_grid g = seed_grid();
    cdvr_camera cam = {{0, 0, -1.5}, {0, 0, 0}, {0, 1, 0}, 90, 512, 512, 0, 0};
    double dpix = cdvr_lod_pixel_distance(&g, 2, &cam);
    /* texel 2/1023, pixel angle 2 tan(45 deg) / 512 */
    CHECK(fabs(dpix - (2.0 / 1023.0) * 512.0 / 2.0) < 1e-12, "D_pix %g", dpix);
    cdvr_lod_plan seed, screen;
    CHECK(cdvr_lod_plan_compute(&g, 2, cam.eye, 4, 1, 0.0, &seed, NULL) == CDVR_OK &&
              cdvr_lod_plan_compute(&g, 2, cam.eye, 4, 1, dpix, &screen, NULL) == CDVR_OK,
          "plans");
    /* D_pix = 0.5005 > D = 0.5: slices nearer than 2 D_pix = 1.001 stay at level 0 */
    CHECK(screen.nearest == dpix && screen.total_bytes > seed.total_bytes &&
              screen.levels[256] == 0 && seed.levels[256] == 1,
          "screen plan: nearest %g, %g vs %g MiB", screen.nearest, screen.total_bytes / MIB,
          seed.total_bytes / MIB);
    cdvr_lod_plan_free(&seed);
    cdvr_lod_plan_free(&screen);
    cam.orthographic = 1;
    cam.ortho_height = 2;
    CHECK(cdvr_lod_pixel_distance(&g, 2, &cam) == 0.0, "orthographic: no D_pix");
}

static void test_bad_input(void)
{
    cdvr_grid g = seed_grid();
    double eye[3] = {0.0, 0.0, -2.0};
    cdvr_lod_plan plan;
    cdvr_error err;
    CHECK(cdvr_lod_plan_compute(&g, 3, eye, 4, 1, 0.0, &plan, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "axis"),
          "bad axis: %s", err.msg);
    CHECK(cdvr_lod_plan_compute(&g, 2, eye, 0, 1, 0.0, &plan, &err) == CDVR_ERR_ARG,
          "zero bytes per voxel");
    double nan_eye[3] = {NAN, 0.0, 0.0};
    CHECK(cdvr_lod_plan_compute(&g, 2, nan_eye, 4, 1, 0.0, &plan, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "eye"),
          "NaN eye: %s", err.msg);
    g.spacing[1] = 0.0;
    CHECK(cdvr_lod_plan_compute(&g, 2, eye, 4, 1, 0.0, &plan, &err) == CDVR_ERR_ARG, "zero spacing");
    g = seed_grid();
    g.dims[0] = 0;
    CHECK(cdvr_lod_plan_compute(&g, 2, eye, 4, 1, 0.0, &plan, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "zero"),
          "zero dim: %s", err.msg);
    g = seed_grid();
    g.dims[0] = g.dims[1] = (size_t)1 << 31; /* 2 slices of 2^62 voxels x 4 bytes: overflows */
    g.dims[2] = 2;
    CHECK(cdvr_lod_plan_compute(&g, 2, eye, 4, 0, 0.0, &plan, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "overflow"),
          "huge slices are refused, not wrapped: %s", err.msg);
}

int main(void)
{
    test_table2();
    test_extents();
    test_axis_and_distance();
    test_screen();
    test_bad_input();
    return check_finish();
}
