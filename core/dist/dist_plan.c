/* core/dist/dist_plan.c - which bricks each process renders and the order to blend their
 * images (cdvr/dist.h): a k-d split of the brick grid and its view-dependent traversal. Plain
 * C, no MPI: built in every configuration and unit-tested alone (tests/test_dist.c). */
#include "cdvr/dist.h"
#include "dist_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* One node of the k-d split: bricks [lo, hi) shared by parts [p0, p1). */
typedef struct kd_node {
    size_t lo[3], hi[3];
    size_t p0, p1;
} kd_node;

/* The cut of a node with several parts: axis, first brick of the upper side, parts of the
 * lower side (half of them, rounded down). Along each axis the lower side gets its share of
 * the bricks rounded to whole slabs (at least one slab each side); the axis whose cut gives
 * the least loaded parts wins (the largest bricks-per-part ratio of the two sides is
 * smallest), then the one with more bricks, then the lowest. Returns 0 when the node cannot
 * be cut (a single brick). */
static int kd_cut(const kd_node *n, int *axis, size_t *at, size_t *lower_parts)
{
    size_t parts = n->p1 - n->p0, lp = parts / 2;
    double best = INFINITY;
    int found = 0;
    for (int a = 0; a < 3; a++) {
        size_t m = n->hi[a] - n->lo[a];
        if (m < 2)
            continue;
        size_t lb = (m * lp + parts / 2) / parts; /* m * lp / parts, rounded */
        lb = lb < 1 ? 1 : lb > m - 1 ? m - 1 : lb;
        double load = fmax((double)lb / (double)lp, (double)(m - lb) / (double)(parts - lp)) *
                      (double)parts / (double)m;
        size_t best_m = found ? n->hi[*axis] - n->lo[*axis] : 0;
        if (!found || load < best - 1e-12 || (fabs(load - best) <= 1e-12 && m > best_m)) {
            best = load;
            *axis = a;
            *at = n->lo[a] + lb;
            found = 1;
        }
    }
    *lower_parts = lp;
    return found;
}

static void kd_children(const kd_node *n, int axis, size_t at, size_t lp, kd_node *lower,
                        kd_node *upper)
{
    *lower = *upper = *n;
    lower->hi[axis] = at;
    upper->lo[axis] = at;
    lower->p1 = n->p0 + lp;
    upper->p0 = n->p0 + lp;
}

int cdvr_dist_partition(const size_t grid[3], size_t nparts, size_t part, size_t lo[3],
                        size_t hi[3])
{
    kd_node n = {{0, 0, 0}, {grid[0], grid[1], grid[2]}, 0, nparts};
    while (n.p1 - n.p0 > 1) {
        int axis;
        size_t at, lp;
        if (!kd_cut(&n, &axis, &at, &lp)) {
            if (part != n.p0)
                n.hi[0] = n.lo[0]; /* the brick goes to the node's first part */
            break;
        }
        kd_node lower, upper;
        kd_children(&n, axis, at, lp, &lower, &upper);
        n = part < lower.p1 ? lower : upper;
    }
    memcpy(lo, n.lo, sizeof n.lo);
    memcpy(hi, n.hi, sizeof n.hi);
    if (n.hi[0] == n.lo[0])
        for (int a = 0; a < 3; a++)
            hi[a] = lo[a];
    return hi[0] > lo[0];
}

/* First voxel of brick i along axis a: c_i of the brick rule (store.h). */
static double cut_voxel(const size_t vol_dims[3], const size_t grid[3], int a, size_t i)
{
    size_t lo[3], dims[3], b = 0, stride = 1;
    for (int k = 0; k < a; k++)
        stride *= grid[k];
    b = i * stride;
    if (!cdvr_brick_box(vol_dims, grid, b, lo, dims))
        return 0.0;
    return (double)lo[a];
}

/* 1 when the rays meet the lower side of a cut at voxel plane c on axis a first. */
static int lower_first(const cdvr_dist_view *v, int a, double c)
{
    return v->orthographic ? v->dir[a] >= 0.0 : v->eye[a] < c;
}

static void kd_order(const size_t vol_dims[3], const size_t grid[3], const kd_node *n,
                     const cdvr_dist_view *v, int *order, size_t *next)
{
    int axis;
    size_t at, lp;
    if (n->p1 - n->p0 == 1 || !kd_cut(n, &axis, &at, &lp)) {
        for (size_t p = n->p0; p < n->p1; p++)
            order[(*next)++] = (int)p;
        return;
    }
    kd_node lower, upper;
    kd_children(n, axis, at, lp, &lower, &upper);
    int first_low = lower_first(v, axis, cut_voxel(vol_dims, grid, axis, at));
    kd_order(vol_dims, grid, first_low ? &lower : &upper, v, order, next);
    kd_order(vol_dims, grid, first_low ? &upper : &lower, v, order, next);
}

void cdvr_dist_order(const size_t vol_dims[3], const size_t grid[3], size_t nparts,
                     const cdvr_dist_view *view, int *order)
{
    kd_node root = {{0, 0, 0}, {grid[0], grid[1], grid[2]}, 0, nparts};
    size_t next = 0;
    kd_order(vol_dims, grid, &root, view, order, &next);
}

/* Inverse of the 3x3 row-major matrix m (identity when singular: the store reader rejects
 * singular directions, so this only guards). */
static void invert3(const double m[9], double out[9])
{
    double c[9] = {m[4] * m[8] - m[5] * m[7], m[2] * m[7] - m[1] * m[8], m[1] * m[5] - m[2] * m[4],
                   m[5] * m[6] - m[3] * m[8], m[0] * m[8] - m[2] * m[6], m[2] * m[3] - m[0] * m[5],
                   m[3] * m[7] - m[4] * m[6], m[1] * m[6] - m[0] * m[7], m[0] * m[4] - m[1] * m[3]};
    double det = m[0] * c[0] + m[1] * c[3] + m[2] * c[6];
    for (int i = 0; i < 9; i++)
        out[i] = det != 0.0 && isfinite(det) ? c[i] / det : (i % 4 == 0);
}

void cdvr_dist_view_of(const cdvr_store_info *info, const cdvr_camera *cam, cdvr_dist_view *view)
{
    double inv[9], f[3], u[3], r[3];
    invert3(info->direction, inv);
    cdvr_camera_basis(cam, f, u, r);
    view->orthographic = cam->orthographic != 0;
    for (int a = 0; a < 3; a++) {
        double e = 0.0, d = 0.0;
        for (int k = 0; k < 3; k++) {
            e += inv[3 * a + k] * (cam->eye[k] - info->origin[k]);
            d += inv[3 * a + k] * f[k];
        }
        view->eye[a] = e / info->spacing[a];
        view->dir[a] = d / info->spacing[a];
    }
}

/* ---- shared by both process-group implementations --------------------------------------- */

void cdvr_dist_share(cdvr_dist_mode mode, int rank, int size, cdvr_player_opts *opts)
{
    opts->rank = rank;
    if (mode == CDVR_DIST_TIME) {
        opts->frame_stride = (size_t)size;
        opts->frame_phase = (size_t)rank;
    } else if (mode == CDVR_DIST_BRICKS) {
        const cdvr_store_info *info = cdvr_store_get_info(opts->store);
        if (!cdvr_dist_partition(info->bricks, (size_t)size, (size_t)rank, opts->region_lo,
                                 opts->region_hi)) {
            memcpy(opts->region_lo, info->bricks, sizeof opts->region_lo); /* empty (player.h) */
            memcpy(opts->region_hi, info->bricks, sizeof opts->region_hi);
        }
    }
}

static int row_order(const void *a, const void *b)
{
    const cdvr_frame_row *x = a, *y = b;
    if (x->frame != y->frame)
        return x->frame < y->frame ? -1 : 1;
    return (x->rank > y->rank) - (x->rank < y->rank);
}

void cdvr_dist_sort_rows(cdvr_frame_row *rows, size_t n)
{
    qsort(rows, n, sizeof *rows, row_order);
}

double cdvr_dist_time_fps(size_t ok_frames, double slowest_wall_ms)
{
    return slowest_wall_ms > 0 ? 1e3 * (double)ok_frames / slowest_wall_ms : 0.0;
}

/* ---- what the ranks must agree on ------------------------------------------------------- */

static uint32_t fnv1a(uint32_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++)
        h = (h ^ p[i]) * 16777619u;
    return h;
}

#define FNV_START 2166136261u
#define HASH_FIELD(h, x) ((h) = fnv1a((h), &(x), sizeof(x)))

uint32_t cdvr_dist_store_hash(const cdvr_store *st)
{
    const cdvr_store_info *in = cdvr_store_get_info(st);
    uint32_t h = FNV_START;
    HASH_FIELD(h, in->dims);
    HASH_FIELD(h, in->timesteps);
    HASH_FIELD(h, in->spacing);
    HASH_FIELD(h, in->origin);
    HASH_FIELD(h, in->direction);
    HASH_FIELD(h, in->qlo);
    HASH_FIELD(h, in->qhi);
    HASH_FIELD(h, in->nvariants);
    HASH_FIELD(h, in->bricks);
    HASH_FIELD(h, in->file_bytes);
    for (size_t v = 0; v < in->nvariants; v++) {
        const cdvr_variant_info *vi = cdvr_store_variant(st, v);
        h = fnv1a(h, vi->name, strlen(vi->name));
        HASH_FIELD(h, vi->codec_id);
        HASH_FIELD(h, vi->nchunks);
    }
    return h & 0x3fffffff;
}

uint32_t cdvr_dist_camera_hash(const cdvr_camera *cam)
{
    uint32_t h = FNV_START;
    HASH_FIELD(h, cam->eye);
    HASH_FIELD(h, cam->center);
    HASH_FIELD(h, cam->up);
    HASH_FIELD(h, cam->fov);
    HASH_FIELD(h, cam->width);
    HASH_FIELD(h, cam->height);
    HASH_FIELD(h, cam->orthographic);
    if (cam->orthographic)
        HASH_FIELD(h, cam->ortho_height);
    return h & 0x3fffffff;
}
