/* core/render/cpu/splat.c - the CPU splat renderer (cdvr/splat.h): Gaussian footprints of the
 * voxels, integrated exactly along each pixel's ray, composited back to front in a voxel order
 * from splat_order.c. Screen tiles are composited in parallel; each tile sees its splats in
 * the global order, so the image does not depend on the thread count. */
#include "cdvr/render.h"
#include "cdvr/splat.h"
#include "cdvr/timing.h"

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define TILE 32
#define BATCH ((size_t)1 << 20) /* splats binned at a time */
#define MAX_THREADS 256
#define MAX_RADIUS 16.0
#define MAX_SIGMA 8.0
#define OPAQUE_TAU 1e30
#define GAUSS_TABLE 4096 /* intervals over p^2 in [0, radius^2] */

typedef struct pixel_ray {
    float o[3];  /* index-space point of the ray closest to the box centre */
    float e[3];  /* unit index-space direction */
    float inv_g; /* 1 / |M^-1 d|: world length per index length along the ray */
} pixel_ray;

typedef struct splat_rec {
    float c[3];  /* index-space centre */
    float ka;    /* tau * footprint normalisation */
    float rgb[3];
    int x0, y0, x1, y1; /* pixel box, inclusive; x0 > x1 when culled */
} splat_rec;

typedef struct splat_job {
    /* volume and view */
    const uint8_t *voxels;
    size_t dims[3];
    double origin[3], m[9], minv[9]; /* index to world: origin + M c */
    const cdvr_camera *camera;
    double eye[3], f[3], u[3], r[3];
    int orthographic, width, height;
    double aspect, tan_half;        /* width / height; tan(fov / 2) */
    double pixel_scale;             /* ortho: pixels per world unit; persp: H / (2 tan(fov/2)) */
    double half_r, half_u, half_f;  /* world half-extents of a splat's support along r, u, f */
    float rgb[256][3], ka[256];
    float cut2, gauss_scale;          /* gauss_scale = GAUSS_TABLE / radius^2 */
    float gauss[GAUSS_TABLE + 2];     /* exp(-p2 / (2 sigma^2)) at p2 = i / gauss_scale */
    pixel_ray *rays;
    cdvr_image *img;
    int tiles_x, tiles_y, ntiles, nthreads;
    /* the batch being drawn */
    const uint32_t *order;
    size_t begin, end;
    splat_rec *rec;
    size_t *tile_count;  /* [thread][tile]: counts, then write offsets */
    size_t *tile_start;  /* [tile + 1] */
    uint32_t *tile_list; /* splat positions (from begin) per tile, in order */
    size_t list_cap;
    atomic_int next_tile;
    atomic_uint_fast64_t fragments;
} splat_job;

/* ---- small linear algebra -------------------------------------------------------------- */

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void mat_vec(const double m[9], const double v[3], double out[3])
{
    for (int r = 0; r < 3; r++)
        out[r] = m[3 * r] * v[0] + m[3 * r + 1] * v[1] + m[3 * r + 2] * v[2];
}

static void mat_t_vec(const double m[9], const double v[3], double out[3])
{
    for (int c = 0; c < 3; c++)
        out[c] = m[c] * v[0] + m[3 + c] * v[1] + m[6 + c] * v[2];
}

static double mat_det(const double m[9])
{
    return m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
           m[2] * (m[3] * m[7] - m[4] * m[6]);
}

static void mat_inverse(const double m[9], double det, double out[9])
{
    out[0] = (m[4] * m[8] - m[5] * m[7]) / det;
    out[1] = (m[2] * m[7] - m[1] * m[8]) / det;
    out[2] = (m[1] * m[5] - m[2] * m[4]) / det;
    out[3] = (m[5] * m[6] - m[3] * m[8]) / det;
    out[4] = (m[0] * m[8] - m[2] * m[6]) / det;
    out[5] = (m[2] * m[3] - m[0] * m[5]) / det;
    out[6] = (m[3] * m[7] - m[4] * m[6]) / det;
    out[7] = (m[1] * m[6] - m[0] * m[7]) / det;
    out[8] = (m[0] * m[4] - m[1] * m[3]) / det;
}

/* M = direction * diag(spacing) (volume.h). */
static void index_to_world(const cdvr_volume *vol, double m[9])
{
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            m[3 * r + c] = vol->direction[3 * r + c] * vol->spacing[c];
}

/* ---- threads --------------------------------------------------------------------------- */

typedef struct worker_arg {
    splat_job *job;
    int index;
    void (*fn)(splat_job *job, int index);
} worker_arg;

static void *worker_main(void *p)
{
    worker_arg *w = p;
    w->fn(w->job, w->index);
    return NULL;
}

/* Runs fn(job, i) for i = 0..nthreads-1, the caller running i = 0. A thread that fails to
 * start has its share run by the caller afterwards. */
static void run_parallel(splat_job *job, void (*fn)(splat_job *, int))
{
    pthread_t threads[MAX_THREADS];
    worker_arg args[MAX_THREADS];
    int started[MAX_THREADS];
    for (int i = 1; i < job->nthreads; i++) {
        args[i] = (worker_arg){job, i, fn};
        started[i] = pthread_create(&threads[i], NULL, worker_main, &args[i]) == 0;
    }
    fn(job, 0);
    for (int i = 1; i < job->nthreads; i++) {
        if (started[i])
            pthread_join(threads[i], NULL);
        else
            fn(job, i);
    }
}

static int thread_count(int requested)
{
    long n = requested > 0 ? requested : sysconf(_SC_NPROCESSORS_ONLN);
    if (n < 1)
        n = 1;
    return n > MAX_THREADS ? MAX_THREADS : (int)n;
}

/* ---- projection and binning ------------------------------------------------------------ */

static void chunk_of(const splat_job *job, int index, size_t *lo, size_t *hi)
{
    size_t n = job->end - job->begin;
    *lo = n * (size_t)index / (size_t)job->nthreads;
    *hi = n * (size_t)(index + 1) / (size_t)job->nthreads;
}

static int clamp_pixel(double v, int hi)
{
    return v < -1.0 ? -1 : v > (double)hi + 1.0 ? hi + 1 : (int)v;
}

/* Pixel box of a splat at world offset rel = w - eye; returns 0 when off screen or when its
 * support reaches the eye plane. */
static int splat_box(const splat_job *job, const double rel[3], splat_rec *s)
{
    double xs = dot3(rel, job->r), ys = dot3(rel, job->u), zf = dot3(rel, job->f);
    if (zf - job->half_f <= 0.0)
        return 0;
    double xlo, xhi, ylo, yhi, k = job->pixel_scale;
    if (job->orthographic) {
        xlo = (xs - job->half_r) * k;
        xhi = (xs + job->half_r) * k;
        ylo = (ys - job->half_u) * k;
        yhi = (ys + job->half_u) * k;
    } else {
        double znear = zf - job->half_f, zfar = zf + job->half_f;
        double a = xs - job->half_r, b = xs + job->half_r;
        double c = ys - job->half_u, d = ys + job->half_u;
        xlo = fmin(a / znear, a / zfar) * k;
        xhi = fmax(b / znear, b / zfar) * k;
        ylo = fmin(c / znear, c / zfar) * k;
        yhi = fmax(d / znear, d / zfar) * k;
    }
    /* pixel x = X + W/2 - 0.5, y = -Y + H/2 - 0.5 (camera.h) */
    double cx = 0.5 * job->width - 0.5, cy = 0.5 * job->height - 0.5;
    s->x0 = clamp_pixel(ceil(xlo + cx), job->width);
    s->x1 = clamp_pixel(floor(xhi + cx), job->width);
    s->y0 = clamp_pixel(ceil(-yhi + cy), job->height);
    s->y1 = clamp_pixel(floor(-ylo + cy), job->height);
    if (s->x0 < 0)
        s->x0 = 0;
    if (s->y0 < 0)
        s->y0 = 0;
    if (s->x1 >= job->width)
        s->x1 = job->width - 1;
    if (s->y1 >= job->height)
        s->y1 = job->height - 1;
    return s->x0 <= s->x1 && s->y0 <= s->y1;
}

static void project_splat(const splat_job *job, uint32_t lin, splat_rec *s)
{
    size_t i = lin % job->dims[0], j = lin / job->dims[0] % job->dims[1],
           k = lin / (job->dims[0] * job->dims[1]);
    double c[3] = {(double)i, (double)j, (double)k}, w[3], rel[3];
    mat_vec(job->m, c, w);
    for (int a = 0; a < 3; a++) {
        rel[a] = job->origin[a] + w[a] - job->eye[a];
        s->c[a] = (float)c[a];
    }
    uint8_t v = job->voxels[lin];
    s->ka = job->ka[v];
    memcpy(s->rgb, job->rgb[v], sizeof s->rgb);
    if (!splat_box(job, rel, s)) {
        s->x0 = 1;
        s->x1 = 0;
    }
}

static void project_batch(splat_job *job, int index)
{
    size_t lo, hi, *count = job->tile_count + (size_t)index * (size_t)job->ntiles;
    chunk_of(job, index, &lo, &hi);
    memset(count, 0, (size_t)job->ntiles * sizeof *count);
    for (size_t i = lo; i < hi; i++) {
        splat_rec *s = &job->rec[i];
        project_splat(job, job->order[job->begin + i], s);
        if (s->x0 > s->x1)
            continue;
        for (int ty = s->y0 / TILE; ty <= s->y1 / TILE; ty++)
            for (int tx = s->x0 / TILE; tx <= s->x1 / TILE; tx++)
                count[ty * job->tiles_x + tx]++;
    }
}

static void fill_batch(splat_job *job, int index)
{
    size_t lo, hi, *next = job->tile_count + (size_t)index * (size_t)job->ntiles;
    chunk_of(job, index, &lo, &hi);
    for (size_t i = lo; i < hi; i++) {
        const splat_rec *s = &job->rec[i];
        if (s->x0 > s->x1)
            continue;
        for (int ty = s->y0 / TILE; ty <= s->y1 / TILE; ty++)
            for (int tx = s->x0 / TILE; tx <= s->x1 / TILE; tx++)
                job->tile_list[next[ty * job->tiles_x + tx]++] = (uint32_t)i;
    }
}

/* Turns the per-thread counts into write offsets (thread order inside each tile keeps the
 * global order); returns the total or 0 with *ok = 0 when the list cannot grow. */
static size_t bin_offsets(splat_job *job, int *ok)
{
    size_t total = 0;
    for (int t = 0; t < job->ntiles; t++) {
        job->tile_start[t] = total;
        for (int th = 0; th < job->nthreads; th++) {
            size_t *c = &job->tile_count[(size_t)th * (size_t)job->ntiles + (size_t)t];
            size_t n = *c;
            *c = total;
            total += n;
        }
    }
    job->tile_start[job->ntiles] = total;
    *ok = 1;
    if (total > job->list_cap) {
        uint32_t *bigger = realloc(job->tile_list, total * sizeof *bigger);
        if (!bigger) {
            *ok = 0;
            return 0;
        }
        job->tile_list = bigger;
        job->list_cap = total;
    }
    return total;
}

/* ---- compositing ----------------------------------------------------------------------- */

/* alpha = 1 - exp(-depth): three terms of the series below 2^-10 (relative error below
 * 2^-40 there, where 1 - expf would lose digits), expf above (glibc's expm1f is several
 * times slower than expf). */
static inline float splat_alpha(float depth)
{
    if (depth < 0x1p-10f)
        return depth * (1.0f - depth * (0.5f - depth * (1.0f / 6.0f)));
    return 1.0f - expf(-depth);
}

static uint64_t draw_splat(const splat_job *job, const splat_rec *s, int x0, int y0, int x1,
                           int y1)
{
    uint64_t fragments = 0;
    for (int y = y0; y <= y1; y++) {
        const pixel_ray *ray = job->rays + (size_t)y * (size_t)job->width;
        float *px = job->img->rgba + ((size_t)y * (size_t)job->width) * 4;
        for (int x = x0; x <= x1; x++) {
            const pixel_ray *q = &ray[x];
            float a = q->o[0] - s->c[0], b = q->o[1] - s->c[1], c = q->o[2] - s->c[2];
            float cx = b * q->e[2] - c * q->e[1];
            float cy = c * q->e[0] - a * q->e[2];
            float cz = a * q->e[1] - b * q->e[0];
            float p2 = cx * cx + cy * cy + cz * cz;
            if (p2 > job->cut2)
                continue;
            float g = p2 * job->gauss_scale;
            int gi = (int)g;
            float gw = g - (float)gi;
            float kernel = job->gauss[gi] + gw * (job->gauss[gi + 1] - job->gauss[gi]);
            float depth = s->ka * q->inv_g * kernel;
            float alpha = splat_alpha(depth), keep = 1.0f - alpha;
            float *p = px + (size_t)x * 4;
            p[0] = s->rgb[0] * alpha + keep * p[0];
            p[1] = s->rgb[1] * alpha + keep * p[1];
            p[2] = s->rgb[2] * alpha + keep * p[2];
            p[3] = alpha + keep * p[3];
            fragments++;
        }
    }
    return fragments;
}

static void composite_tiles(splat_job *job, int index)
{
    (void)index;
    uint64_t fragments = 0;
    for (;;) {
        int t = atomic_fetch_add(&job->next_tile, 1);
        if (t >= job->ntiles)
            break;
        int tx0 = (t % job->tiles_x) * TILE, ty0 = (t / job->tiles_x) * TILE;
        int tx1 = tx0 + TILE - 1, ty1 = ty0 + TILE - 1;
        for (size_t i = job->tile_start[t]; i < job->tile_start[t + 1]; i++) {
            const splat_rec *s = &job->rec[job->tile_list[i]];
            int x0 = s->x0 > tx0 ? s->x0 : tx0, x1 = s->x1 < tx1 ? s->x1 : tx1;
            int y0 = s->y0 > ty0 ? s->y0 : ty0, y1 = s->y1 < ty1 ? s->y1 : ty1;
            fragments += draw_splat(job, s, x0, y0, x1, y1);
        }
    }
    atomic_fetch_add(&job->fragments, fragments);
}

/* ---- set-up ---------------------------------------------------------------------------- */

static cdvr_status check_inputs(const cdvr_volume *vol, size_t t, const cdvr_splat_opts *o,
                                double *radius, double *sigma, cdvr_error *err)
{
    if (vol->type != CDVR_TYPE_U8)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "splat render: volume type %s is not u8 (quantize it first)",
                              cdvr_type_name(vol->type));
    if (t >= vol->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat render: timestep %zu outside 0..%zu", t,
                              vol->timesteps - 1);
    if (!o->tf || !o->camera)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "splat render: transfer function and camera needed");
    cdvr_status st = cdvr_camera_validate(o->camera, err);
    if (st != CDVR_OK)
        return st;
    *radius = o->radius == 0.0 ? CDVR_SPLAT_DEFAULT_RADIUS : o->radius;
    *sigma = o->sigma == 0.0 ? CDVR_SPLAT_DEFAULT_SIGMA : o->sigma;
    if (!(*radius > 0.0 && *radius <= MAX_RADIUS) || !(*sigma > 0.0 && *sigma <= MAX_SIGMA))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "splat render: radius %g must be in (0, %g] and sigma %g in (0, %g]",
                              o->radius, MAX_RADIUS, o->sigma, MAX_SIGMA);
    if (!isfinite(o->unit) || o->unit < 0.0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat render: unit %g must be >= 0", o->unit);
    if (o->has_threshold && isnan(o->threshold))
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat render: threshold is NaN");
    if ((unsigned)o->order > CDVR_SPLAT_QUICKSORT)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat render: unknown order %d", (int)o->order);
    for (int a = 0; a < 3; a++)
        if (!isfinite(vol->spacing[a]) || vol->spacing[a] <= 0.0 || !isfinite(vol->origin[a]))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "splat render: volume spacing %g and origin %g (axis %d) must "
                                  "be finite, spacing positive",
                                  vol->spacing[a], vol->origin[a], a);
    for (int i = 0; i < 9; i++)
        if (!isfinite(vol->direction[i]))
            return cdvr_error_set(err, CDVR_ERR_ARG, "splat render: direction matrix not finite");
    return CDVR_OK;
}

/* Classification: the TF table at the voxel's value (pre-classified), extinction per world
 * unit times the footprint normalisation. */
static void classify_table(splat_job *job, const cdvr_tf *tf, double unit, double radius,
                           double sigma)
{
    const double pi = 3.14159265358979323846;
    double norm = 1.0 / (2.0 * pi * sigma * sigma *
                         (1.0 - exp(-radius * radius / (2.0 * sigma * sigma))));
    for (int v = 0; v < 256; v++) {
        double a = tf->table[v][3];
        double tau = a >= 1.0 ? OPAQUE_TAU : -log1p(-a) / unit;
        job->ka[v] = (float)(tau * norm);
        for (int c = 0; c < 3; c++)
            job->rgb[v][c] = tf->table[v][c];
    }
}

/* The ray of pixel (x, y): cdvr_camera_ray's formula (camera.h) with the basis, aspect and
 * tan(fov/2) computed once per frame instead of per pixel (the same double operations). */
static void pixel_ray_world(const splat_job *job, int x, int y, double origin[3], double dir[3])
{
    double sx = (2.0 * (x + 0.5) / job->width - 1.0) * job->aspect;
    double sy = -(2.0 * (y + 0.5) / job->height - 1.0);
    if (job->orthographic) {
        double half = 0.5 * job->camera->ortho_height;
        for (int i = 0; i < 3; i++) {
            origin[i] = job->eye[i] + (sx * job->r[i] + sy * job->u[i]) * half;
            dir[i] = job->f[i];
        }
        return;
    }
    double len2 = 0.0;
    for (int i = 0; i < 3; i++) {
        origin[i] = job->eye[i];
        dir[i] = job->f[i] + (sx * job->r[i] + sy * job->u[i]) * job->tan_half;
        len2 += dir[i] * dir[i];
    }
    double len = sqrt(len2);
    for (int i = 0; i < 3; i++)
        dir[i] /= len;
}

/* Per-pixel rays in index space, each origin moved along its ray to the point nearest the
 * box centre (keeps the float differences small; the footprint depends on the line only).
 * Rows are shared among the threads. */
static void fill_rays(splat_job *job, int index)
{
    double centre[3];
    for (int a = 0; a < 3; a++)
        centre[a] = 0.5 * (double)(job->dims[a] - 1);
    for (int y = index; y < job->height; y += job->nthreads)
        for (int x = 0; x < job->width; x++) {
            double o[3], d[3], rel[3], oi[3], di[3];
            pixel_ray_world(job, x, y, o, d);
            for (int a = 0; a < 3; a++)
                rel[a] = o[a] - job->origin[a];
            mat_vec(job->minv, rel, oi);
            mat_vec(job->minv, d, di);
            double g = sqrt(dot3(di, di));
            for (int a = 0; a < 3; a++)
                di[a] /= g;
            double to_centre[3] = {centre[0] - oi[0], centre[1] - oi[1], centre[2] - oi[2]};
            double s = dot3(to_centre, di);
            pixel_ray *ray = &job->rays[(size_t)y * (size_t)job->width + (size_t)x];
            for (int a = 0; a < 3; a++) {
                ray->o[a] = (float)(oi[a] + s * di[a]);
                ray->e[a] = (float)di[a];
            }
            ray->inv_g = (float)(1.0 / g);
        }
}

static void setup_view(splat_job *job, const cdvr_camera *cam, double radius)
{
    cdvr_camera_basis(cam, job->f, job->u, job->r);
    memcpy(job->eye, cam->eye, sizeof job->eye);
    job->orthographic = cam->orthographic;
    job->width = cam->width;
    job->height = cam->height;
    job->aspect = (double)cam->width / (double)cam->height;
    job->tan_half = tan(0.5 * cam->fov * 3.14159265358979323846 / 180.0);
    if (cam->orthographic)
        job->pixel_scale = (double)cam->height / cam->ortho_height;
    else
        job->pixel_scale = (double)cam->height /
                           (2.0 * tan(0.5 * cam->fov * 3.14159265358979323846 / 180.0));
    double mr[3], mu[3], mf[3];
    mat_t_vec(job->m, job->r, mr);
    mat_t_vec(job->m, job->u, mu);
    mat_t_vec(job->m, job->f, mf);
    job->half_r = radius * sqrt(dot3(mr, mr));
    job->half_u = radius * sqrt(dot3(mu, mu));
    job->half_f = radius * sqrt(dot3(mf, mf));
    job->tiles_x = (job->width + TILE - 1) / TILE;
    job->tiles_y = (job->height + TILE - 1) / TILE;
    job->ntiles = job->tiles_x * job->tiles_y;
}

/* The order for the camera: v = M^T f, or the eye in index space with G = M^T M. */
static cdvr_status build_order(const splat_job *job, const cdvr_volume *vol,
                               const cdvr_splat_opts *o,
                               const uint8_t keep[256], cdvr_splat_order **order,
                               cdvr_error *err)
{
    cdvr_splat_view view;
    memset(&view, 0, sizeof view);
    view.perspective = !job->orthographic;
    if (job->orthographic) {
        mat_t_vec(job->m, job->f, view.dir);
    } else {
        double rel[3];
        for (int a = 0; a < 3; a++)
            rel[a] = job->eye[a] - job->origin[a];
        mat_vec(job->minv, rel, view.eye);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) {
                double col_r[3] = {job->m[r], job->m[3 + r], job->m[6 + r]};
                double col_c[3] = {job->m[c], job->m[3 + c], job->m[6 + c]};
                view.metric[3 * r + c] = dot3(col_r, col_c);
            }
    }
    cdvr_splat_filter filter = {job->voxels, keep};
    return cdvr_splat_order_build(vol->dims, &view, o->order, &filter, order, err);
}

static int alloc_batches(splat_job *job, size_t count)
{
    size_t batch = count < BATCH ? count : BATCH;
    job->rec = malloc((batch ? batch : 1) * sizeof *job->rec);
    job->tile_count = malloc((size_t)job->nthreads * (size_t)job->ntiles * sizeof *job->tile_count);
    job->tile_start = malloc(((size_t)job->ntiles + 1) * sizeof *job->tile_start);
    job->list_cap = batch ? 2 * batch : 1;
    job->tile_list = malloc(job->list_cap * sizeof *job->tile_list);
    return job->rec && job->tile_count && job->tile_start && job->tile_list;
}

static void free_job(splat_job *job)
{
    free(job->rays);
    free(job->rec);
    free(job->tile_count);
    free(job->tile_start);
    free(job->tile_list);
    free(job);
}

static cdvr_status draw_order(splat_job *job, const cdvr_splat_order *order, cdvr_error *err)
{
    job->order = order->index;
    for (size_t begin = 0; begin < order->count; begin += BATCH) {
        job->begin = begin;
        job->end = order->count - begin < BATCH ? order->count : begin + BATCH;
        run_parallel(job, project_batch);
        int ok;
        bin_offsets(job, &ok);
        if (!ok)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat render: no memory for tile lists");
        run_parallel(job, fill_batch);
        atomic_store(&job->next_tile, 0);
        run_parallel(job, composite_tiles);
    }
    return CDVR_OK;
}

cdvr_status cdvr_render_splat(const cdvr_volume *vol, size_t t, cdvr_splat_opts *opts,
                              cdvr_image **out, cdvr_error *err)
{
    *out = NULL;
    if (!vol || !opts)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat render: NULL volume or options");
    double radius = 0.0, sigma = 0.0;
    cdvr_status st = check_inputs(vol, t, opts, &radius, &sigma, err);
    cdvr_render_opts ro = {.tf = opts->tf, .camera = opts->camera, .unit = opts->unit};
    if (st == CDVR_OK)
        st = cdvr_render_opts_check(vol, &ro, err); /* unit (splats take no step) */
    if (st != CDVR_OK)
        return st;
    splat_job *job = calloc(1, sizeof *job);
    if (!job)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat render: no memory for the job");
    job->voxels = cdvr_volume_frame(vol, t);
    memcpy(job->dims, vol->dims, sizeof job->dims);
    memcpy(job->origin, vol->origin, sizeof job->origin);
    index_to_world(vol, job->m);
    double det = mat_det(job->m);
    if (!(fabs(det) > 1e-300)) {
        free_job(job);
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat render: index-to-world matrix is singular");
    }
    mat_inverse(job->m, det, job->minv);
    job->camera = opts->camera;
    double step_unused, unit, term_unused;
    cdvr_render_resolve(vol, &ro, &step_unused, &unit, &term_unused);
    classify_table(job, opts->tf, unit, radius, sigma);
    job->cut2 = (float)(radius * radius);
    job->gauss_scale = (float)(GAUSS_TABLE / (radius * radius));
    for (int i = 0; i < GAUSS_TABLE + 2; i++) /* the last entry only meets weight 0 */
        job->gauss[i] = (float)exp(-(double)i / job->gauss_scale / (2.0 * sigma * sigma));
    setup_view(job, opts->camera, radius);
    job->nthreads = thread_count(opts->threads);
    uint8_t keep[256];
    for (int v = 0; v < 256; v++)
        keep[v] = (!opts->has_threshold || (double)v > opts->threshold) &&
                  opts->tf->table[v][3] > 0.0f;
    double start = cdvr_now_ms();
    cdvr_splat_order *order = NULL;
    st = build_order(job, vol, opts, keep, &order, err);
    opts->order_ms = cdvr_now_ms() - start;
    cdvr_image *img = NULL;
    if (st == CDVR_OK)
        st = cdvr_image_create(job->width, job->height, &img, err);
    if (st == CDVR_OK) {
        job->rays = malloc((size_t)job->width * (size_t)job->height * sizeof *job->rays);
        if (!job->rays || !alloc_batches(job, order->count))
            st = cdvr_error_set(err, CDVR_ERR_NOMEM, "splat render: no memory for %dx%d pixels",
                                job->width, job->height);
    }
    if (st == CDVR_OK) {
        run_parallel(job, fill_rays);
        job->img = img;
        for (int c = 0; c < 4; c++)
            img->background[c] = opts->background[c];
        atomic_init(&job->fragments, 0);
        st = draw_order(job, order, err);
        opts->splats = order->count;
        opts->fragments = (uint64_t)atomic_load(&job->fragments);
    }
    cdvr_splat_order_free(order);
    free_job(job);
    if (st != CDVR_OK) {
        cdvr_image_free(img);
        return st;
    }
    *out = img;
    return CDVR_OK;
}
