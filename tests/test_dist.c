/* tests/test_dist.c - cdvr/dist.h without MPI: the k-d partition of brick grids among
 * processes (disjoint boxes covering the grid, balanced, empty parts when there are more
 * processes than bricks) and the blend order (a visibility order: along rays from the eye,
 * perspective or orthographic, from outside and inside the volume, the parts are met in the
 * order given), the view in index coordinates, the single-process group, and the fingerprints
 * the ranks compare to agree on a camera (every field counts, 30 bits) and the collective-call
 * deadline (CDVR_MPI_TIMEOUT, else the default). */
#include "check.h"

#include "cdvr/dist.h"
#include "dist/dist_internal.h"

#include <stdlib.h>

#include <string.h>

/* Part owning brick (i,j,k), or -1; checks no brick is owned twice. */
static int owner_map(const size_t grid[3], size_t nparts, int *owner, size_t *empty)
{
    size_t n = grid[0] * grid[1] * grid[2];
    for (size_t b = 0; b < n; b++)
        owner[b] = -1;
    int twice = 0;
    *empty = 0;
    for (size_t p = 0; p < nparts; p++) {
        size_t lo[3], hi[3];
        int has = cdvr_dist_partition(grid, nparts, p, lo, hi);
        *empty += !has;
        for (size_t k = lo[2]; has && k < hi[2]; k++)
            for (size_t j = lo[1]; j < hi[1]; j++)
                for (size_t i = lo[0]; i < hi[0]; i++) {
                    size_t b = i + grid[0] * (j + grid[1] * k);
                    twice |= owner[b] >= 0;
                    owner[b] = (int)p;
                }
    }
    return !twice;
}

static void test_partition(void)
{
    static const size_t grids[][3] = {{1, 1, 1}, {2, 1, 1}, {4, 2, 2}, {3, 5, 2}, {8, 8, 8},
                                      {1, 1, 7}, {2, 2, 1}};
    static const size_t counts[] = {1, 2, 3, 4, 5, 7, 8, 16};
    int owner[512];
    for (size_t g = 0; g < sizeof grids / sizeof *grids; g++)
        for (size_t c = 0; c < sizeof counts / sizeof *counts; c++) {
            const size_t *grid = grids[g];
            size_t n = grid[0] * grid[1] * grid[2], np = counts[c], empty;
            CHECK(owner_map(grid, np, owner, &empty), "grid %zux%zux%zu / %zu: brick twice",
                  grid[0], grid[1], grid[2], np);
            size_t min = n, max = 0, per[16] = {0};
            for (size_t b = 0; b < n; b++) {
                CHECK(owner[b] >= 0, "grid %zux%zux%zu / %zu: brick %zu unowned", grid[0],
                      grid[1], grid[2], np, b);
                if (owner[b] >= 0)
                    per[owner[b]]++;
            }
            for (size_t p = 0; p < np; p++) {
                min = per[p] < min ? per[p] : min;
                max = per[p] > max ? per[p] : max;
            }
            if (n >= np) { /* every part has bricks, within a factor 3 of each other (the
                              k-d cuts fall between whole bricks) */
                CHECK(empty == 0, "grid %zu bricks / %zu: %zu empty parts", n, np, empty);
                CHECK(max <= 3 * min, "grid %zu bricks / %zu: %zu..%zu per part", n, np, min,
                      max);
            } else {
                CHECK(empty >= np - n, "more parts than bricks: %zu empty", empty);
            }
        }
    size_t lo[3], hi[3], grid[3] = {4, 2, 2};
    cdvr_dist_partition(grid, 4, 0, lo, hi); /* x cut 2|2, then each half cut in x again */
    CHECK(lo[0] == 0 && hi[0] == 1 && hi[1] == 2 && hi[2] == 2, "4 parts of 4x2x2: part 0 "
          "%zu..%zu %zu %zu", lo[0], hi[0], hi[1], hi[2]);
}

/* Brick voxel boxes along one axis (the store's rule) for the ray walk. */
static size_t brick_of(const size_t dims[3], const size_t grid[3], int a, double g)
{
    for (size_t i = grid[a]; i-- > 0;) {
        size_t lo[3], bd[3], stride = a == 0 ? 1 : a == 1 ? grid[0] : grid[0] * grid[1];
        cdvr_brick_box(dims, grid, i * stride, lo, bd);
        if (g >= (double)lo[a])
            return i;
    }
    return 0;
}

/* Walks rays through the volume (index coordinates) and checks each meets the parts in an
 * order consistent with cdvr_dist_order. */
static void check_order(const size_t dims[3], const size_t grid[3], size_t np,
                        const cdvr_dist_view *v, const char *what)
{
    int order[16], rank_of[16], owner[512];
    size_t empty;
    cdvr_dist_order(dims, grid, np, v, order);
    int seen[16] = {0};
    for (size_t i = 0; i < np; i++) {
        CHECK(order[i] >= 0 && (size_t)order[i] < np && !seen[order[i]], "%s: order is a "
              "permutation", what);
        if (order[i] >= 0 && (size_t)order[i] < np) {
            seen[order[i]] = 1;
            rank_of[order[i]] = (int)i;
        }
    }
    owner_map(grid, np, owner, &empty);
    int bad = 0;
    uint32_t seed = 11;
    for (int r = 0; r < 200 && !bad; r++) {
        double o[3], d[3], len = 0;
        for (int a = 0; a < 3; a++) {
            seed = seed * 1664525u + 1013904223u;
            double target = (double)(seed >> 8) / (1 << 24) * (double)(dims[a] - 1);
            o[a] = v->orthographic ? target - 1000 * v->dir[a] : v->eye[a];
            d[a] = v->orthographic ? v->dir[a] : target - v->eye[a];
            len += d[a] * d[a];
        }
        len = sqrt(len);
        double t0 = 0, t1 = 1e9; /* the ray's stretch inside the box */
        for (int a = 0; a < 3; a++) {
            double u = d[a] / len, hi = (double)(dims[a] - 1);
            if (fabs(u) < 1e-12)
                continue;
            double ta = (0 - o[a]) / u, tb = (hi - o[a]) / u;
            t0 = fmax(t0, fmin(ta, tb));
            t1 = fmin(t1, fmax(ta, tb));
        }
        int last = -1;
        for (double t = t0 + 1e-9; t < t1 && !bad; t += 0.25) {
            double p[3];
            for (int a = 0; a < 3; a++)
                p[a] = o[a] + t * d[a] / len;
            size_t b = brick_of(dims, grid, 0, p[0]) +
                       grid[0] * (brick_of(dims, grid, 1, p[1]) +
                                  grid[1] * brick_of(dims, grid, 2, p[2]));
            int part = owner[b];
            if (last >= 0 && part != last && rank_of[part] < rank_of[last])
                bad = 1;
            last = part;
        }
    }
    CHECK(!bad, "%s: a ray meets the parts out of the blend order", what);
}

static void test_order(void)
{
    size_t dims[3] = {41, 29, 23};
    static const size_t grids[][3] = {{4, 2, 2}, {3, 3, 3}, {2, 1, 1}, {5, 4, 2}};
    static const size_t counts[] = {2, 3, 4, 7};
    static const double eyes[][3] = {{-30, 14, 11}, {80, -20, 40}, {20, 14, 11}, {5, 25, 3},
                                     {38, 2, 20}};
    static const double dirs[][3] = {{1, 0.2, 0.1}, {-0.3, 1, -0.5}, {0, 0, -1}};
    char what[96];
    for (size_t g = 0; g < 4; g++)
        for (size_t c = 0; c < 4; c++) {
            for (size_t e = 0; e < 5; e++) {
                cdvr_dist_view v = {0, {eyes[e][0], eyes[e][1], eyes[e][2]}, {0, 0, 0}};
                snprintf(what, sizeof what, "grid %zu, %zu parts, eye %zu", g, counts[c], e);
                check_order(dims, grids[g], counts[c], &v, what);
            }
            for (size_t k = 0; k < 3; k++) {
                cdvr_dist_view v = {1, {0, 0, 0}, {dirs[k][0], dirs[k][1], dirs[k][2]}};
                snprintf(what, sizeof what, "grid %zu, %zu parts, ortho %zu", g, counts[c], k);
                check_order(dims, grids[g], counts[c], &v, what);
            }
        }
}

static void test_view(void)
{
    cdvr_store_info info;
    memset(&info, 0, sizeof info);
    double D[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1}; /* index x -> world y, index y -> world -x */
    memcpy(info.direction, D, sizeof D);
    for (int a = 0; a < 3; a++) {
        info.spacing[a] = 2.0;
        info.origin[a] = 10.0;
    }
    cdvr_camera cam = {{10, 30, 14}, {10, 10, 14}, {0, 0, 1}, 30, 8, 8, 0, 0};
    cdvr_dist_view v;
    cdvr_dist_view_of(&info, &cam, &v);
    /* eye - origin = (0, 20, 4) = D * (q), q = (20, 0, 4) -> index (10, 0, 2) */
    CHECK(fabs(v.eye[0] - 10) < 1e-12 && fabs(v.eye[1]) < 1e-12 && fabs(v.eye[2] - 2) < 1e-12,
          "eye in index coordinates %g %g %g", v.eye[0], v.eye[1], v.eye[2]);
    CHECK(v.dir[0] < 0 && fabs(v.dir[1]) < 1e-12, "view direction %g %g", v.dir[0], v.dir[1]);
}

static void test_group(void)
{
    cdvr_error err;
    int argc = 1;
    char *args[] = {"test_dist", NULL}, **argv = args;
    CHECK_OK(cdvr_dist_init(&argc, &argv, &err), err);
    CHECK(cdvr_dist_rank() == 0 && cdvr_dist_size() == 1, "one process outside mpirun");
    cdvr_dist_barrier();
    cdvr_dist_abort(1); /* returns in a group of one */
    cdvr_dist_finalize();
}

static void test_agreement(void)
{
    cdvr_camera a = {.eye = {1, 2, 3}, .center = {0, 0, 0}, .up = {0, 0, 1}, .fov = 30, .width = 64, .height = 48};
    cdvr_camera b = a;
    uint32_t h = cdvr_dist_camera_hash(&a);
    CHECK(h == cdvr_dist_camera_hash(&b) && h < (1u << 30), "same camera, same 30-bit fingerprint");
    b.eye[2] = 3.0000001;
    CHECK(cdvr_dist_camera_hash(&b) != h, "the eye counts");
    b = a;
    b.width = 65;
    CHECK(cdvr_dist_camera_hash(&b) != h, "the width counts");
    b = a;
    b.orthographic = 1;
    CHECK(cdvr_dist_camera_hash(&b) != h, "the projection counts");
    unsetenv("CDVR_MPI_TIMEOUT");
    double def = cdvr_dist_timeout_s();
    CHECK(def == CDVR_DIST_TIMEOUT_DEFAULT || !cdvr_dist_built(), "default deadline %g", def);
    if (cdvr_dist_built()) {
        setenv("CDVR_MPI_TIMEOUT", "2.5", 1);
        CHECK(cdvr_dist_timeout_s() == 2.5, "CDVR_MPI_TIMEOUT=2.5");
        setenv("CDVR_MPI_TIMEOUT", "-1", 1);
        CHECK(cdvr_dist_timeout_s() == CDVR_DIST_TIMEOUT_DEFAULT, "a negative deadline is ignored");
        unsetenv("CDVR_MPI_TIMEOUT");
    }
}

int main(void)
{
    test_agreement();
    test_partition();
    test_order();
    test_view();
    test_group();
    return check_finish();
}
