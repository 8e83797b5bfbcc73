/* core/render/cpu/render_cpu.c - the multithreaded CPU reference ray caster (cdvr/render.h). Every step
 * below follows the numbered algorithm in render.h; the OpenCL kernel copies it. */
#include "cdvr/render.h"

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>

#define MAX_THREADS 256

typedef struct render_job {
    const uint8_t *voxels;
    int dims[3];             /* of the whole volume (clipped: render.h) */
    size_t stride_y, stride_z;
    double origin[3], inv_dir[9];   /* step 0: box frame q = inv_dir * (world - origin) */
    float inv_spacing[3], box_hi[3]; /* box [0, box_hi] in the box frame */
    int clipped;             /* opts->clip given: keep only samples in the owned cells */
    size_t offset[3];        /* whole-volume index of the passed voxels' first one */
    float own_lo[3], own_hi[3];
    int own_far[3];          /* own_hi is the volume's far face (closed there) */
    float step, unit, term_alpha;
    const cdvr_tf *tf;
    float alpha_step[256]; /* a_c[i] = 1 - (1 - a[i])^(step/unit) */
    const cdvr_camera *camera;
    const atomic_int *cancel; /* NULL, or stop before the next row once nonzero */
    cdvr_image *img;
    atomic_int next_row;
    atomic_uint_fast64_t samples;
} render_job;

static double min_spacing(const cdvr_volume *vol)
{
    return fmin(vol->spacing[0], fmin(vol->spacing[1], vol->spacing[2]));
}

void cdvr_render_resolve(const cdvr_volume *vol, const cdvr_render_opts *opts, double *step,
                         double *unit, double *term_alpha)
{
    double spacing = min_spacing(vol);
    *step = opts->step > 0.0 ? opts->step : 0.5 * spacing;
    if (opts->unit > 0.0)
        *unit = opts->unit;
    else if (opts->tf && opts->tf->unit > 0.0)
        *unit = opts->tf->unit;
    else
        *unit = spacing;
    *term_alpha = opts->term_alpha > 0.0 ? opts->term_alpha : 0.99;
}

/* Step 1: slab intersection in float, in the box frame; returns 1 and [t_near, t_far) on a
 * hit. */
static int intersect_box(const render_job *job, const float o[3], const float d[3],
                         float *t_near, float *t_far)
{
    float t_enter = -INFINITY, t_exit = INFINITY;
    for (int a = 0; a < 3; a++) {
        float lo = 0.0f, hi = job->box_hi[a];
        if (fabsf(d[a]) < 1e-12f) {
            if (o[a] < lo || o[a] > hi)
                return 0;
            continue;
        }
        float t0 = (lo - o[a]) / d[a], t1 = (hi - o[a]) / d[a];
        if (t0 > t1) {
            float swap = t0;
            t0 = t1;
            t1 = swap;
        }
        t_enter = fmaxf(t_enter, t0);
        t_exit = fminf(t_exit, t1);
    }
    *t_near = fmaxf(t_enter, 0.0f);
    *t_far = t_exit;
    return *t_far > *t_near;
}

static float lerpf(float a, float b, float f)
{
    return a + f * (b - a);
}

/* Step 3, first half: grid coordinates of box-frame position p, clamped. */
static void grid_position(const render_job *job, const float p[3], float g[3])
{
    for (int a = 0; a < 3; a++) {
        float top = (float)(job->dims[a] - 1);
        g[a] = fminf(fmaxf(p[a] * job->inv_spacing[a], 0.0f), top);
    }
}

/* Clipped rendering: is the sample at grid position g in the owned cells? */
static int owned(const render_job *job, const float g[3])
{
    for (int a = 0; a < 3; a++)
        if (g[a] < job->own_lo[a] || (g[a] >= job->own_hi[a] && !job->own_far[a]))
            return 0;
    return 1;
}

/* Step 3, second half: trilinear interpolation at grid position g (of the whole volume). */
static float sample_volume(const render_job *job, const float g[3])
{
    size_t lo[3], hi[3];
    float f[3];
    for (int a = 0; a < 3; a++) {
        int i0 = (int)g[a];
        lo[a] = (size_t)i0 - job->offset[a];
        hi[a] = (size_t)(i0 + 1 < job->dims[a] ? i0 + 1 : i0) - job->offset[a];
        f[a] = g[a] - (float)i0;
    }
    const uint8_t *v = job->voxels;
    size_t y0 = lo[1] * job->stride_y, y1 = hi[1] * job->stride_y;
    size_t z0 = lo[2] * job->stride_z, z1 = hi[2] * job->stride_z;
    float c00 = lerpf(v[lo[0] + y0 + z0], v[hi[0] + y0 + z0], f[0]);
    float c10 = lerpf(v[lo[0] + y1 + z0], v[hi[0] + y1 + z0], f[0]);
    float c01 = lerpf(v[lo[0] + y0 + z1], v[hi[0] + y0 + z1], f[0]);
    float c11 = lerpf(v[lo[0] + y1 + z1], v[hi[0] + y1 + z1], f[0]);
    return lerpf(lerpf(c00, c10, f[1]), lerpf(c01, c11, f[1]), f[2]);
}

/* Step 4: post-classification of value s for a segment of length ds (full: ds == step). */
static void classify(const render_job *job, float s, float ds, int full, float rgba[4])
{
    int i0 = (int)s;
    if (i0 > 254)
        i0 = 254;
    float f = s - (float)i0;
    const float *lo = job->tf->table[i0], *hi = job->tf->table[i0 + 1];
    if (full) {
        rgba[3] = lerpf(job->alpha_step[i0], job->alpha_step[i0 + 1], f);
    } else {
        float a = lerpf(lo[3], hi[3], f);
        rgba[3] = 1.0f - powf(1.0f - a, ds / job->unit);
    }
    if (rgba[3] > 0.0f)
        for (int c = 0; c < 3; c++)
            rgba[c] = lerpf(lo[c], hi[c], f);
}

/* Clipped rendering: segments [*first, *stop) of a ray (n segments from t_near) that may
 * have their midpoint in the owned cells: the ray's stretch (box frame) through the owned box
 * widened by a cell, in double, then by two segments each side for rounding. The exact test
 * is owned(), on each sample's own grid position. */
static void owned_segments(const render_job *job, const float o[3], const float d[3],
                           float t_near, long n, long *first, long *stop)
{
    double t0 = -INFINITY, t1 = INFINITY;
    for (int a = 0; a < 3; a++) {
        double sp = 1.0 / job->inv_spacing[a];
        double lo = (job->own_lo[a] - 1.0) * sp, hi = (job->own_hi[a] + 1.0) * sp;
        if (fabs(d[a]) < 1e-12) {
            if (o[a] < lo || o[a] > hi) {
                *first = *stop = 0;
                return;
            }
            continue;
        }
        double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
        t0 = fmax(t0, fmin(ta, tb));
        t1 = fmin(t1, fmax(ta, tb));
    }
    double step = job->step;
    double f = floor((t0 - t_near) / step) - 2.0, s = ceil((t1 - t_near) / step) + 2.0;
    *first = f < 0.0 ? 0 : f > (double)n ? n : (long)f;
    *stop = s < 0.0 ? 0 : s > (double)n ? n : (long)s;
}

/* Steps 2 and 5 for one ray; returns the number of samples taken. */
static uint64_t march_ray(const render_job *job, const float o[3], const float d[3],
                          float out[4])
{
    float t_near, t_far;
    out[0] = out[1] = out[2] = out[3] = 0.0f;
    if (!intersect_box(job, o, d, &t_near, &t_far))
        return 0;
    float length = t_far - t_near, step = job->step;
    long n = (long)ceilf(length / step);
    if (n < 1)
        n = 1;
    float C[3] = {0.0f, 0.0f, 0.0f}, A = 0.0f;
    long i, first = 0, stop = n;
    if (job->clipped)
        owned_segments(job, o, d, t_near, n, &first, &stop);
    uint64_t taken = 0;
    for (i = first; i < stop; i++) {
        float ts = t_near + (float)i * step;
        float ds = i < n - 1 ? step : t_far - ts;
        if (ds <= 0.0f)
            break;
        float tm = ts + 0.5f * ds, p[3], g[3], rgba[4];
        for (int a = 0; a < 3; a++)
            p[a] = o[a] + tm * d[a];
        grid_position(job, p, g);
        if (job->clipped && !owned(job, g))
            continue;
        taken++;
        classify(job, sample_volume(job, g), ds, ds >= step, rgba);
        if (rgba[3] > 0.0f) {
            float w = (1.0f - A) * rgba[3];
            for (int c = 0; c < 3; c++)
                C[c] += w * rgba[c];
            A += w;
            if (A >= job->term_alpha || A >= 1.0f)
                break;
        }
    }
    out[0] = C[0];
    out[1] = C[1];
    out[2] = C[2];
    out[3] = A;
    return taken;
}

/* Step 0: the world ray (double) in the box frame, rounded to float. */
static void to_box_frame(const render_job *job, const double od[3], const double dd[3],
                         float o[3], float d[3])
{
    const double *m = job->inv_dir;
    double rel[3] = {od[0] - job->origin[0], od[1] - job->origin[1], od[2] - job->origin[2]};
    for (int r = 0; r < 3; r++) {
        o[r] = (float)(m[3 * r] * rel[0] + m[3 * r + 1] * rel[1] + m[3 * r + 2] * rel[2]);
        d[r] = (float)(m[3 * r] * dd[0] + m[3 * r + 1] * dd[1] + m[3 * r + 2] * dd[2]);
    }
}

static uint64_t render_row(const render_job *job, int y)
{
    uint64_t samples = 0;
    for (int x = 0; x < job->img->width; x++) {
        double od[3], dd[3];
        float o[3], d[3];
        cdvr_camera_ray(job->camera, x, y, od, dd);
        to_box_frame(job, od, dd, o, d);
        samples += march_ray(job, o, d, cdvr_image_pixel(job->img, x, y));
    }
    return samples;
}

static void *render_worker(void *arg)
{
    render_job *job = arg;
    uint64_t samples = 0;
    for (;;) {
        int y = atomic_fetch_add(&job->next_row, 1);
        if (y >= job->img->height || (job->cancel && atomic_load(job->cancel)))
            break;
        samples += render_row(job, y);
    }
    atomic_fetch_add(&job->samples, samples);
    return NULL;
}

static int thread_count(const cdvr_render_opts *opts, int rows)
{
    long n = opts->threads > 0 ? opts->threads : sysconf(_SC_NPROCESSORS_ONLN);
    if (n < 1)
        n = 1;
    if (n > MAX_THREADS)
        n = MAX_THREADS;
    return n > rows ? rows : (int)n;
}

/* Runs the workers; the calling thread is one of them. Threads that fail to start are
 * simply not used: the rows are shared by whoever runs. */
static void run_workers(render_job *job, int nthreads)
{
    pthread_t threads[MAX_THREADS];
    int started = 0;
    for (int i = 1; i < nthreads; i++) {
        if (pthread_create(&threads[started], NULL, render_worker, job) != 0)
            break;
        started++;
    }
    render_worker(job);
    for (int i = 0; i < started; i++)
        pthread_join(threads[i], NULL);
}

/* The clip box must lie inside the whole volume and its owned cells inside the passed
 * voxels (render.h). */
static cdvr_status check_clip(const cdvr_volume *vol, const cdvr_render_clip *c, cdvr_error *err)
{
    for (int a = 0; c && a < 3; a++)
        if (c->whole_dims[a] == 0 || c->whole_dims[a] > INT_MAX || c->own_lo[a] > c->own_hi[a] ||
            c->own_hi[a] >= c->whole_dims[a] || c->offset[a] > c->own_lo[a] ||
            c->own_hi[a] > c->offset[a] + vol->dims[a] - 1)
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: clip axis %d: owned cells %zu..%zu "
                                  "of %zu voxels are not inside the %zu voxels given from %zu", a,
                                  c->own_lo[a], c->own_hi[a], c->whole_dims[a], vol->dims[a],
                                  c->offset[a]);
    return CDVR_OK;
}

static cdvr_status check_volume(const cdvr_volume *vol, size_t t, cdvr_error *err)
{
    if (vol->type != CDVR_TYPE_U8)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "render: volume type %s is not u8 (quantize it first)",
                              cdvr_type_name(vol->type));
    if (t >= vol->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: timestep %zu outside 0..%zu", t,
                              vol->timesteps - 1);
    for (int a = 0; a < 3; a++)
        if (vol->dims[a] > INT_MAX)
            return cdvr_error_set(err, CDVR_ERR_ARG, "render: dim %zu too large",
                                  vol->dims[a]);
    return cdvr_volume_check_geometry(vol, "render", err);
}

static double box_diagonal(const cdvr_volume *vol)
{
    double sum = 0.0;
    for (int a = 0; a < 3; a++) {
        double extent = (double)(vol->dims[a] - 1) * vol->spacing[a];
        sum += extent * extent;
    }
    return sqrt(sum);
}

static cdvr_status check_opts(const cdvr_volume *vol, const cdvr_render_opts *opts,
                              double step, double unit, double term, cdvr_error *err)
{
    if (!opts->tf || !opts->camera)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: transfer function and camera needed");
    cdvr_status st = cdvr_camera_validate(opts->camera, err);
    if (st != CDVR_OK)
        return st;
    st = cdvr_render_opts_check(vol, opts, err); /* step, unit, term_alpha: bounded work */
    if (st != CDVR_OK)
        return st;
    if (box_diagonal(vol) / step > (double)INT_MAX)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "render: step %g too small for a box of diagonal %g", step,
                              box_diagonal(vol));
    (void)unit;
    (void)term;
    return CDVR_OK;
}

static void setup_job(render_job *job, const cdvr_volume *vol, size_t t,
                      const cdvr_render_opts *opts, double step, double unit, double term,
                      cdvr_image *img)
{
    job->voxels = cdvr_volume_frame(vol, t);
    job->stride_y = vol->dims[0];
    job->stride_z = vol->dims[0] * vol->dims[1];
    const cdvr_render_clip *clip = opts->clip;
    double D[9];
    cdvr_volume_direction(vol, D);
    cdvr_mat3_inverse(D, job->inv_dir); /* invertible: checked by check_volume */
    job->clipped = clip != NULL;
    for (int a = 0; a < 3; a++) {
        size_t whole = clip ? clip->whole_dims[a] : vol->dims[a];
        job->dims[a] = (int)whole;
        job->origin[a] = vol->origin[a];
        job->inv_spacing[a] = (float)(1.0 / vol->spacing[a]);
        job->box_hi[a] = (float)((double)(whole - 1) * vol->spacing[a]);
        job->offset[a] = clip ? clip->offset[a] : 0;
        job->own_lo[a] = clip ? (float)clip->own_lo[a] : 0.0f;
        job->own_hi[a] = clip ? (float)clip->own_hi[a] : (float)(whole - 1);
        job->own_far[a] = !clip || clip->own_hi[a] + 1 == whole;
    }
    job->step = (float)step;
    job->unit = (float)unit;
    job->term_alpha = (float)term;
    job->tf = opts->tf;
    for (int i = 0; i < 256; i++)
        job->alpha_step[i] = (float)(1.0 - pow(1.0 - opts->tf->table[i][3], step / unit));
    job->camera = opts->camera;
    job->cancel = opts->cancel;
    job->img = img;
    atomic_init(&job->next_row, 0);
    atomic_init(&job->samples, 0);
}

/* Steps 0 and 1 for pixel (x, y). */
static int pixel_hits(const render_job *job, const cdvr_camera *cam, int x, int y)
{
    double od[3], dd[3];
    float o[3], d[3], t_near, t_far;
    cdvr_camera_ray(cam, x, y, od, dd);
    to_box_frame(job, od, dd, o, d);
    return intersect_box(job, o, d, &t_near, &t_far);
}

int cdvr_render_view_hits(const cdvr_volume *vol, const cdvr_camera *cam)
{
    cdvr_error err;
    if (!vol || !cam || cdvr_volume_check_geometry(vol, "render", &err) != CDVR_OK ||
        cdvr_camera_validate(cam, &err) != CDVR_OK)
        return 0;
    render_job *job = calloc(1, sizeof *job);
    if (!job)
        return 1; /* cannot tell: do not claim a miss */
    double D[9];
    cdvr_volume_direction(vol, D);
    cdvr_mat3_inverse(D, job->inv_dir);
    for (int a = 0; a < 3; a++) {
        job->origin[a] = vol->origin[a];
        job->box_hi[a] = (float)((double)(vol->dims[a] - 1) * vol->spacing[a]);
    }
    int hit = pixel_hits(job, cam, cam->width / 2, cam->height / 2);
    static const int strides[] = {16, 4, 1};
    for (int s = 0; s < 3 && !hit; s++)
        for (int y = 0; y < cam->height && !hit; y += strides[s])
            for (int x = 0; x < cam->width && !hit; x += strides[s])
                hit = pixel_hits(job, cam, x, y);
    free(job);
    return hit;
}

cdvr_status cdvr_render_cpu(const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                            cdvr_image **out, cdvr_error *err)
{
    *out = NULL;
    if (!vol || !opts)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render: NULL volume or options");
    cdvr_status st = check_volume(vol, t, err);
    if (st == CDVR_OK)
        st = check_clip(vol, opts->clip, err);
    if (st != CDVR_OK)
        return st;
    double step, unit, term;
    cdvr_render_resolve(vol, opts, &step, &unit, &term);
    st = check_opts(vol, opts, step, unit, term, err);
    if (st != CDVR_OK)
        return st;
    cdvr_image *img;
    st = cdvr_image_create(opts->camera->width, opts->camera->height, &img, err);
    if (st != CDVR_OK)
        return st;
    for (int c = 0; c < 4; c++)
        img->background[c] = opts->background[c];
    render_job *job = malloc(sizeof *job);
    if (!job) {
        cdvr_image_free(img);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "render: no memory for the job");
    }
    setup_job(job, vol, t, opts, step, unit, term, img);
    run_workers(job, thread_count(opts, img->height));
    opts->samples = (uint64_t)atomic_load(&job->samples);
    free(job);
    if (opts->cancel && atomic_load(opts->cancel)) {
        cdvr_image_free(img);
        return cdvr_error_set(err, CDVR_ERR_CANCELLED, "render: interrupted");
    }
    *out = img;
    return CDVR_OK;
}
