/* core/render/gl/lod.c - the slice stack's axis and the per-slice level of detail of seed 002
 * (cdvr/gl.h). Plain arithmetic: built with or without GL. */
#include "cdvr/gl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void cdvr_grid_of_volume(const cdvr_volume *vol, cdvr_grid *grid)
{
    memcpy(grid->dims, vol->dims, sizeof grid->dims);
    memcpy(grid->origin, vol->origin, sizeof grid->origin);
    memcpy(grid->spacing, vol->spacing, sizeof grid->spacing);
    cdvr_volume_direction(vol, grid->direction); /* all zeros means the identity */
}

/* The inverse of the direction matrix (the identity if it is singular: callers check the
 * geometry first, cdvr_volume_check_geometry). */
static void inverse_direction(const cdvr_grid *grid, double inv[9])
{
    if (!cdvr_mat3_inverse(grid->direction, inv)) {
        memset(inv, 0, 9 * sizeof *inv);
        inv[0] = inv[4] = inv[8] = 1.0;
    }
}

int cdvr_slice_axis(const cdvr_grid *grid, const cdvr_camera *cam)
{
    double f[3], u[3], r[3], inv[9];
    cdvr_camera_basis(cam, f, u, r);
    inverse_direction(grid, inv);
    int best = 0;
    double best_cos = -1.0;
    for (int a = 0; a < 3; a++) {
        /* the slices' normal: the gradient of index coordinate a, row a of D^-1 */
        const double *d = inv + 3 * a;
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        double c = len > 0.0 ? fabs(f[0] * d[0] + f[1] * d[1] + f[2] * d[2]) / len : 0.0;
        if (c > best_cos) {
            best_cos = c;
            best = a;
        }
    }
    return best;
}

void cdvr_slice_plane_axes(int axis, int *u, int *v)
{
    *u = axis == 0 ? 1 : 0;
    *v = axis == 2 ? 1 : 2;
}

/* World position of continuous index coordinates idx. */
static void index_to_world(const cdvr_grid *grid, const double idx[3], double out[3])
{
    for (int r = 0; r < 3; r++) {
        out[r] = grid->origin[r];
        for (int c = 0; c < 3; c++)
            out[r] += grid->direction[3 * r + c] * idx[c] * grid->spacing[c];
    }
}

void cdvr_grid_index_direction(const cdvr_grid *grid, const double d[3], double out[3])
{
    double inv[9];
    inverse_direction(grid, inv);
    for (int c = 0; c < 3; c++)
        out[c] = (inv[3 * c] * d[0] + inv[3 * c + 1] * d[1] + inv[3 * c + 2] * d[2]) /
                 grid->spacing[c];
}

void cdvr_grid_index_of(const cdvr_grid *grid, const double p[3], double out[3])
{
    double q[3] = {p[0] - grid->origin[0], p[1] - grid->origin[1], p[2] - grid->origin[2]};
    cdvr_grid_index_direction(grid, q, out);
}

double cdvr_slice_distance(const cdvr_grid *grid, int axis, size_t k, const double eye[3])
{
    double e[3], nearest[3], w[3];
    cdvr_grid_index_of(grid, eye, e);
    for (int c = 0; c < 3; c++) {
        double top = (double)(grid->dims[c] - 1);
        nearest[c] = c == axis ? (double)k : fmin(fmax(e[c], 0.0), top);
    }
    index_to_world(grid, nearest, w);
    double dx = w[0] - eye[0], dy = w[1] - eye[1], dz = w[2] - eye[2];
    return sqrt(dx * dx + dy * dy + dz * dz);
}

size_t cdvr_lod_extent(size_t n, int level)
{
    if (level <= 0)
        return n ? n : 1;
    if (level >= (int)(8 * sizeof(size_t) - 1))
        return 1;
    size_t scale = (size_t)1 << level;
    size_t e = n / scale + (n % scale != 0);
    return e ? e : 1;
}

int cdvr_lod_max_level(size_t n_u, size_t n_v)
{
    size_t n = n_u > n_v ? n_u : n_v;
    int level = 0;
    while (cdvr_lod_extent(n, level) > 1)
        level++;
    return level;
}

/* floor(log2(d / nearest)) without log2's rounding: the largest L with nearest * 2^L <= d
 * (scaling by 2 is exact in binary floating point). */
static int lod_level(double d, double nearest, int max_level)
{
    int level = 0;
    double reach = nearest * 2.0;
    while (level < max_level && reach <= d) {
        level++;
        reach *= 2.0;
    }
    return level;
}

static cdvr_status check_plan_args(const cdvr_grid *grid, int axis, const double eye[3],
                                   size_t bytes_per_voxel, cdvr_error *err)
{
    if (axis < 0 || axis > 2)
        return cdvr_error_set(err, CDVR_ERR_ARG, "lod plan: axis %d outside 0..2", axis);
    if (bytes_per_voxel == 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "lod plan: bytes_per_voxel must be positive");
    for (int c = 0; c < 3; c++) {
        if (grid->dims[c] == 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "lod plan: dims %zux%zux%zu has a zero",
                                  grid->dims[0], grid->dims[1], grid->dims[2]);
        if (!(grid->spacing[c] > 0.0) || !isfinite(grid->spacing[c]) ||
            !isfinite(grid->origin[c]) || !isfinite(eye[c]))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "lod plan: spacing must be positive and finite, origin and "
                                  "eye finite (axis %d: spacing %g, origin %g, eye %g)",
                                  c, grid->spacing[c], grid->origin[c], eye[c]);
    }
    return CDVR_OK;
}

/* Adds the bytes of a slice at `level` to *sum; 0 on overflow. */
static int add_slice_bytes(uint64_t *sum, size_t n_u, size_t n_v, int level, size_t bpv)
{
    uint64_t a = cdvr_lod_extent(n_u, level), b = cdvr_lod_extent(n_v, level);
    if (a > UINT64_MAX / b || a * b > UINT64_MAX / bpv)
        return 0;
    uint64_t bytes = a * b * bpv;
    if (*sum > UINT64_MAX - bytes)
        return 0;
    *sum += bytes;
    return 1;
}

double cdvr_lod_pixel_distance(const cdvr_grid *grid, int axis, const cdvr_camera *cam)
{
    if (cam->orthographic || cam->height <= 0 || !(cam->fov > 0.0 && cam->fov < 180.0))
        return 0.0;
    int u, v;
    cdvr_slice_plane_axes(axis, &u, &v);
    double texel = fmin(grid->spacing[u], grid->spacing[v]);
    double pixel_angle = 2.0 * tan(0.5 * cam->fov * 3.14159265358979323846 / 180.0) / cam->height;
    return texel / pixel_angle;
}

cdvr_status cdvr_lod_plan_compute(const cdvr_grid *grid, int axis, const double eye[3],
                                  size_t bytes_per_voxel, int lod, double min_nearest,
                                  cdvr_lod_plan *plan, cdvr_error *err)
{
    memset(plan, 0, sizeof *plan);
    cdvr_status st = check_plan_args(grid, axis, eye, bytes_per_voxel, err);
    if (st != CDVR_OK)
        return st;
    size_t n = grid->dims[axis];
    int u, v;
    cdvr_slice_plane_axes(axis, &u, &v);
    size_t n_u = grid->dims[u], n_v = grid->dims[v];
    plan->levels = calloc(n, sizeof *plan->levels);
    if (!plan->levels)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "lod plan: no memory for %zu slice levels", n);
    plan->axis = axis;
    plan->nslices = n;
    if (lod) {
        double nearest = INFINITY;
        for (size_t k = 0; k < n; k++)
            nearest = fmin(nearest, cdvr_slice_distance(grid, axis, k, eye));
        plan->nearest = fmax(fmax(nearest, 0.5 * grid->spacing[axis]),
                             isfinite(min_nearest) ? min_nearest : 0.0);
        int max_level = cdvr_lod_max_level(n_u, n_v);
        for (size_t k = 0; k < n; k++)
            plan->levels[k] =
                lod_level(cdvr_slice_distance(grid, axis, k, eye), plan->nearest, max_level);
    }
    for (size_t k = 0; k < n; k++) {
        if (!add_slice_bytes(&plan->total_bytes, n_u, n_v, plan->levels[k], bytes_per_voxel) ||
            !add_slice_bytes(&plan->full_bytes, n_u, n_v, 0, bytes_per_voxel)) {
            cdvr_lod_plan_free(plan);
            return cdvr_error_set(err, CDVR_ERR_ARG, "lod plan: byte count overflows");
        }
    }
    return CDVR_OK;
}

void cdvr_lod_plan_free(cdvr_lod_plan *plan)
{
    if (!plan)
        return;
    free(plan->levels);
    plan->levels = NULL;
    plan->nslices = 0;
}
