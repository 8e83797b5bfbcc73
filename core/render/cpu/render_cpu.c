/* core/render/cpu/render_cpu.c - the multithreaded CPU reference ray caster (cdvr/render.h). Every step
 * below follows the numbered algorithm in render.h; the OpenCL kernel copies it. */
#include "cdvr/render.h"
#include "cdvr/bricks.h"
#include "cdvr/skip.h"
#include "render/cpu/brick_range.h"

#include <limits.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>
#include <string.h>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define MAX_THREADS 256
#define WIDE_REACH 2 /* max, min, average: the reach of the widened ranges (wide_ranges) */

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
    float rgb_alpha_step[256][4]; /* the TF's r, g, b and a_c[i] side by side */
    float code_value[256];     /* (float)i: a load instead of an int-to-float conversion */
    const cdvr_camera *camera;
    cdvr_camera_frame cam_frame; /* the camera's basis, once per render */
    float eye_box[3];          /* a pinhole camera's eye in the box frame (step 0's o) */
    /* blend modes and shading (render.h) */
    int blend;
    int shade;                 /* shading on */
    float ambient, diffuse, specular, power;
    int whole_power;           /* power when whole and at most CDVR_SHADE_WHOLE_POWER_MAX, else -1 */
    int headlight;
    float light[3];            /* world, towards the light (unit), when not a headlight */
    float dir[9];              /* D: box-frame directions to world */
    float grad_to_world[9];    /* D^-T: box-frame gradients to world */
    float spacing[3];
    float value_per_code;      /* (hi - lo) / 255 of the TF's window */
    int go_points;             /* gradient opacity points, 0: off */
    float go_mag[CDVR_GRADIENT_OPACITY_MAX], go_factor[CDVR_GRADIENT_OPACITY_MAX];
    float iso_code, iso_rgb[3], iso_alpha;
    int iso_tf_color;          /* the TF's colour at the iso code */
    /* empty-space skipping (not clipped): composite reads the brick flags of cdvr/skip.h */
    const uint8_t *skip_flags; /* NULL: every sample is taken */
    const uint8_t *skip_minmax; /* max, min, average (four lanes): brick ranges (NULL: every
                                 * sample is taken) */
    const uint8_t *skip_wide;  /* the range of the cube of reach WIDE_REACH around each brick
                                * (wide_ranges), or NULL */
    int skip_shift, skip_nb[3];
    double jump_inv_step, jump_edge, jump_far[3]; /* grid_ray_of's constants (skip_setup) */
    int lanes;                 /* rays four at a time (SSE2), every blend mode */
    const atomic_int *cancel; /* NULL, or stop before the next tile once nonzero */
    cdvr_image *img;
    atomic_int next_tile;
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

/* max(x, lo) and min(x, hi) as compares the compiler keeps inline (fmaxf/fminf are calls at
 * -O2 for their NaN rules); a NaN x gives lo (hi), as fmaxf(NaN, lo) (fminf(NaN, hi)) does. */
static inline float max_f(float x, float lo)
{
    return x > lo ? x : lo;
}

static inline float min_f(float x, float hi)
{
    return x < hi ? x : hi;
}

/* Step 3, first half: grid coordinates of box-frame position p, clamped. */
static void grid_position(const render_job *job, const float p[3], float g[3])
{
    for (int a = 0; a < 3; a++) {
        float top = (float)(job->dims[a] - 1);
        g[a] = min_f(max_f(p[a] * job->inv_spacing[a], 0.0f), top);
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
static inline float sample_volume(const render_job *job, const float g[3])
{
    size_t lo[3], hi[3];
    float f[3];
    for (int a = 0; a < 3; a++) {
        int i0 = (int)g[a];
        int i1 = i0 + 1 < job->dims[a] ? i0 + 1 : i0;
        lo[a] = (size_t)i0 - job->offset[a];
        hi[a] = (size_t)i1 - job->offset[a];
        f[a] = g[a] - (float)i0;
    }
    const uint8_t *v = job->voxels;
    size_t y0 = lo[1] * job->stride_y, y1 = hi[1] * job->stride_y;
    size_t z0 = lo[2] * job->stride_z, z1 = hi[2] * job->stride_z;
    const uint8_t *r00 = v + y0 + z0, *r10 = v + y1 + z0, *r01 = v + y0 + z1, *r11 = v + y1 + z1;
    /* the eight loads first, independent of each other, then the lerps */
    const float *cv = job->code_value;
    float a0 = cv[r00[lo[0]]], a1 = cv[r00[hi[0]]], b0 = cv[r10[lo[0]]], b1 = cv[r10[hi[0]]];
    float c0 = cv[r01[lo[0]]], c1 = cv[r01[hi[0]]], d0 = cv[r11[lo[0]]], d1 = cv[r11[hi[0]]];
    float c00 = lerpf(a0, a1, f[0]), c10 = lerpf(b0, b1, f[0]);
    float c01 = lerpf(c0, c1, f[0]), c11 = lerpf(d0, d1, f[0]);
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

/* ---- shading (render.h) ------------------------------------------------------------------ */

/* One axis of a trilinear sample at grid coordinate x along axis a: the byte offsets of its
 * two voxel planes in the passed voxels and the fraction, as sample_volume makes them. */
typedef struct axis_at {
    size_t lo, hi;
    float f;
} axis_at;

static inline axis_at axis_setup(const render_job *job, int a, float x)
{
    size_t stride = a == 0 ? 1 : a == 1 ? job->stride_y : job->stride_z;
    int i0 = (int)x;
    int i1 = i0 + 1 < job->dims[a] ? i0 + 1 : i0;
    axis_at r = {((size_t)i0 - job->offset[a]) * stride, ((size_t)i1 - job->offset[a]) * stride,
                 x - (float)i0};
    return r;
}

/* sample_volume at the point whose axes are X, Y, Z: the same loads and lerps. */
static inline float sample_axes(const render_job *job, const axis_at *X, const axis_at *Y,
                                const axis_at *Z)
{
    const uint8_t *v = job->voxels;
    const uint8_t *r00 = v + Y->lo + Z->lo, *r10 = v + Y->hi + Z->lo, *r01 = v + Y->lo + Z->hi,
                  *r11 = v + Y->hi + Z->hi;
    const float *cv = job->code_value;
    float a0 = cv[r00[X->lo]], a1 = cv[r00[X->hi]], b0 = cv[r10[X->lo]], b1 = cv[r10[X->hi]];
    float c0 = cv[r01[X->lo]], c1 = cv[r01[X->hi]], d0 = cv[r11[X->lo]], d1 = cv[r11[X->hi]];
    float c00 = lerpf(a0, a1, X->f), c10 = lerpf(b0, b1, X->f);
    float c01 = lerpf(c0, c1, X->f), c11 = lerpf(d0, d1, X->f);
    return lerpf(lerpf(c00, c10, Y->f), lerpf(c01, c11, Y->f), Z->f);
}

/* World gradient G (codes per world unit) at grid position g by central differences of the
 * trilinear field one voxel apart (render.h). The six samples are sample_volume's values;
 * each axis's setup at g and one voxel up and down is made once for all of them. */
static void gradient(const render_job *job, const float g[3], float G[3])
{
    axis_at at[3], up[3], down[3];
    float h[3], dq[3];
    for (int a = 0; a < 3; a++) {
        float top = (float)(job->dims[a] - 1);
        float gp = min_f(g[a] + 1.0f, top), gm = max_f(g[a] - 1.0f, 0.0f);
        h[a] = gp - gm;
        at[a] = axis_setup(job, a, g[a]);
        up[a] = axis_setup(job, a, gp);
        down[a] = axis_setup(job, a, gm);
    }
    float s[6];
    s[0] = sample_axes(job, &up[0], &at[1], &at[2]);
    s[1] = sample_axes(job, &down[0], &at[1], &at[2]);
    s[2] = sample_axes(job, &at[0], &up[1], &at[2]);
    s[3] = sample_axes(job, &at[0], &down[1], &at[2]);
    s[4] = sample_axes(job, &at[0], &at[1], &up[2]);
    s[5] = sample_axes(job, &at[0], &at[1], &down[2]);
    for (int a = 0; a < 3; a++)
        dq[a] = h[a] > 0.0f ? (s[2 * a] - s[2 * a + 1]) / (h[a] * job->spacing[a]) : 0.0f;
    const float *m = job->grad_to_world;
    for (int r = 0; r < 3; r++)
        G[r] = m[3 * r] * dq[0] + m[3 * r + 1] * dq[1] + m[3 * r + 2] * dq[2];
}

static float length3(const float v[3])
{
    return sqrtf(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

/* render.h's x^power of the specular term: repeated squaring for a whole power up to
 * CDVR_SHADE_WHOLE_POWER_MAX (job->whole_power), lowest bit first (raycast.cl's power_of
 * multiplies in the same order), else powf. */
static float specular_power(const render_job *job, float x)
{
    if (job->whole_power < 0)
        return powf(x, job->power);
    float p = 1.0f;
    for (unsigned n = (unsigned)job->whole_power; n; n >>= 1) {
        if (n & 1u)
            p *= x;
        x *= x;
    }
    return p;
}

/* rgb' = min(1, rgb (ambient + diffuse |n.L|) + specular |n.H|^power), two-sided; V towards
 * the eye (unit). */
static void shade_rgb(const render_job *job, const float G[3], const float V[3], float rgb[3])
{
    float len = length3(G), ndl = 0.0f, ndh = 0.0f;
    if (len >= 1e-12f) {
        const float *L = job->headlight ? V : job->light;
        float H[3] = {L[0] + V[0], L[1] + V[1], L[2] + V[2]};
        float hl = length3(H);
        float n[3] = {G[0] / len, G[1] / len, G[2] / len};
        ndl = fabsf(n[0] * L[0] + n[1] * L[1] + n[2] * L[2]);
        ndh = hl > 0.0f ? fabsf(n[0] * H[0] + n[1] * H[1] + n[2] * H[2]) / hl : 0.0f;
    }
    float spec = ndh > 0.0f ? job->specular * specular_power(job, ndh) : 0.0f;
    float k = job->ambient + job->diffuse * ndl;
    for (int c = 0; c < 3; c++)
        rgb[c] = min_f(rgb[c] * k + spec, 1.0f);
}

/* Gradient opacity factor at magnitude m (data units per world unit). */
static float go_factor(const render_job *job, float m)
{
    int n = job->go_points;
    if (m <= job->go_mag[0])
        return job->go_factor[0];
    for (int i = 1; i < n; i++)
        if (m <= job->go_mag[i]) {
            float w = job->go_mag[i] - job->go_mag[i - 1];
            float f = w > 0.0f ? (m - job->go_mag[i - 1]) / w : 1.0f;
            return lerpf(job->go_factor[i - 1], job->go_factor[i], f);
        }
    return job->go_factor[n - 1];
}

/* Shading and gradient opacity of a composite sample with world gradient G (rgba from
 * classify, a > 0): rgb shaded, alpha multiplied by the factor and corrected for ds
 * (render.h); look_sample: at grid position g. */
static void look_gradient(const render_job *job, const float G[3], float s, float ds,
                          const float V[3], float rgba[4])
{
    if (job->go_points) {
        int i0 = (int)s;
        if (i0 > 254)
            i0 = 254;
        float a = lerpf(job->tf->table[i0][3], job->tf->table[i0 + 1][3], s - (float)i0);
        a *= go_factor(job, length3(G) * job->value_per_code);
        rgba[3] = a > 0.0f ? 1.0f - powf(1.0f - a, ds / job->unit) : 0.0f;
    }
    if (job->shade && rgba[3] > 0.0f)
        shade_rgb(job, G, V, rgba);
}

static void look_sample(const render_job *job, const float g[3], float s, float ds,
                        const float V[3], float rgba[4])
{
    float G[3];
    gradient(job, g, G);
    look_gradient(job, G, s, ds, V, rgba);
}

/* The TF at code s without unit correction (max, min, average, iso colour). */
static void table_at(const render_job *job, float s, float rgba[4])
{
    int i0 = (int)s;
    if (i0 > 254)
        i0 = 254;
    if (i0 < 0)
        i0 = 0;
    float f = s - (float)i0;
    const float *lo = job->tf->table[i0], *hi = job->tf->table[i0 + 1];
    for (int c = 0; c < 4; c++)
        rgba[c] = lerpf(lo[c], hi[c], f);
}

/* ---- blend modes other than composite --------------------------------------------------- */

/* Sample i (of n from t_near) of a ray: its code, and its parameter in *tm. */
static float sample_at(const render_job *job, const float o[3], const float d[3], float t_near,
                       float t_far, long i, long n, float *tm, float g[3])
{
    float ts = t_near + (float)i * job->step;
    float ds = i < n - 1 ? job->step : t_far - ts;
    *tm = ts + 0.5f * ds;
    float p[3];
    for (int a = 0; a < 3; a++)
        p[a] = o[a] + *tm * d[a];
    grid_position(job, p, g);
    return sample_volume(job, g);
}

/* ---- empty-space skipping -------------------------------------------------------------
 * A sample whose brick's value range has zero opacity in the TF adds nothing (steps 4-5: both
 * table entries around any value of the range have alpha 0, so the lerped alpha is exactly 0
 * and the sample is not composited), so it need not be interpolated. The flags of cdvr/skip.h
 * say, for an invisible brick, that the cube of bricks within code - 1 of it is invisible too:
 * the ray jumps to its first sample whose nominal midpoint (t_near + (j + 1/2) step, in
 * double) is not short of the cube's exit face pulled in by a margin (0.01 voxel plus 1e-5 of
 * the coordinates' size, about 80 float ulps), so the samples jumped lie inside the cube
 * whatever the rounding of step 3's float positions (a few ulps). The sample landed on is
 * taken as usual (its own brick is looked up again). Images are those without skipping, bit
 * for bit; the samples jumped are still counted in opts->samples (the definition's count). */

/* Per ray: where its jumps land, as sample indices. For axis a the exit face of a cube of
 * bricks is face index f (in bricks: b + reach + 1 going up, b - reach going down) pulled in
 * by the margin m_a, at parameter t = (f E -+ m_a - o_a) / d_a (grid coordinates, double), and
 * the first sample whose nominal midpoint is not short of it is ceil((t - t_near) / step -
 * 1/2): that is base[a] + f * per_face[a] before the ceil, with per_face = E / (d_a step) and
 * everything else folded into base. m_a = 0.01 + 1e-5 (|o_a| + the largest |face| a cube of
 * reach CDVR_SKIP_REACH_MAX can have), at least the margin above. The double rounding of this
 * rearrangement is some 1e-13 of a sample, far inside the margin. An axis the ray does not
 * move along never bounds the jump (per_face 0, base +huge). */
typedef struct grid_ray {
    double base[3], per_face[3];
    int up[3];                   /* 1: d_a > 0 (exits through the upper face), 0: below */
} grid_ray;

static void grid_ray_of(const render_job *job, const float o[3], const float d[3],
                        float t_near, grid_ray *r)
{
    double inv_step = job->jump_inv_step, edge = job->jump_edge;
    for (int a = 0; a < 3; a++) {
        double og = (double)o[a] * (double)job->inv_spacing[a];
        double dg = (double)d[a] * (double)job->inv_spacing[a];
        r->up[a] = dg > 0.0;
        if (dg == 0.0) {
            r->base[a] = 1e300;
            r->per_face[a] = 0.0;
            continue;
        }
        double m = 0.01 + 1e-5 * (fabs(og) + job->jump_far[a]);
        double inv_d = 1.0 / dg;
        r->base[a] =
            ((dg > 0.0 ? -m : m) - og) * inv_d * inv_step - (double)t_near * inv_step - 0.5;
        r->per_face[a] = edge * inv_d * inv_step;
    }
}

/* The index of the brick holding voxel cell `cell` ((int) of a clamped grid position). */
static inline size_t brick_of_cell(const render_job *job, const int cell[3])
{
    int sh = job->skip_shift;
    size_t bx = (size_t)(cell[0] >> sh), by = (size_t)(cell[1] >> sh);
    size_t bz = (size_t)(cell[2] >> sh);
    return bx + (size_t)job->skip_nb[0] * (by + (size_t)job->skip_nb[1] * bz);
}

/* The cell of grid position g. */
static inline void cell_of(const float g[3], int cell[3])
{
    for (int a = 0; a < 3; a++)
        cell[a] = (int)g[a];
}

/* The flag byte of the brick holding grid position g (clamped to the volume: step 3). */
static inline int brick_code(const render_job *job, const float g[3])
{
    int cell[3];
    cell_of(g, cell);
    return job->skip_flags[brick_of_cell(job, cell)];
}

/* Sample i in voxel cell `cell` ((int) of its grid position) lies in an invisible brick of
 * the given code: the index of the first sample after it that may lie outside the invisible
 * cube around that brick. */
static inline long skip_target(const render_job *job, const grid_ray *r, const int cell[3],
                               int code, long i)
{
    int sh = job->skip_shift, reach = (code > 1 ? code : 1) - 1;
    double j = 1e300;
    for (int a = 0; a < 3; a++) {
        int b = cell[a] >> sh;
        int f = r->up[a] ? b + reach + 1 : b - reach;
        double ja = r->base[a] + (double)f * r->per_face[a];
        j = ja < j ? ja : j;
    }
    if (!(j > (double)(i + 1))) /* ceil(j) > i + 1 exactly when j > i + 1 */
        return i + 1;
    if (j >= (double)(LONG_MAX / 2))
        return LONG_MAX / 2;
    long c = (long)j; /* j > 1: truncation, then up to the ceiling */
    return (double)c < j ? c + 1 : c;
}

/* Max and min jump the bricks that cannot change the extreme so far: every sample in a brick
 * lies in its value range, so a brick whose max is at most the best max (min: whose min is at
 * least the best min) is jumped to its exit face as the composite march jumps an invisible
 * cube of reach 0 (skip_target): the result is exactly the unskipped one. This gives the
 * value range [min, max] of the brick holding grid position g. */
static inline void brick_range(const render_job *job, const float g[3], int *lo, int *hi)
{
    int sh = job->skip_shift;
    size_t bx = (size_t)((int)g[0] >> sh), by = (size_t)((int)g[1] >> sh);
    size_t bz = (size_t)((int)g[2] >> sh);
    const uint8_t *mm =
        job->skip_minmax + 2 * (bx + (size_t)job->skip_nb[0] * (by + (size_t)job->skip_nb[1] * bz));
    *lo = mm[0];
    *hi = mm[1];
}

/* The pixel of a max, min or average ray from its extreme, sum and samples (none: (0, 0)). */
static void extreme_pixel(const render_job *job, float best, double sum, uint64_t taken,
                          float out[4])
{
    if (!taken) {
        out[0] = out[1] = out[2] = out[3] = 0.0f;
        return;
    }
    float s = job->blend == CDVR_BLEND_AVERAGE ? (float)(sum / (double)taken) : best, rgba[4];
    table_at(job, s, rgba);
    for (int c = 0; c < 3; c++)
        out[c] = rgba[c] * rgba[3];
    out[3] = rgba[3];
}

/* Max, min or average of the samples' codes; returns the samples taken (jumped included). */
static uint64_t march_extreme(const render_job *job, const float o[3], const float d[3],
                              float t_near, float t_far, long n, float out[4])
{
    float best = job->blend == CDVR_BLEND_MIN ? INFINITY : -INFINITY;
    double sum = 0.0;
    uint64_t taken = 0;
    int is_max = job->blend == CDVR_BLEND_MAX;
    int skipping = job->skip_minmax && job->blend != CDVR_BLEND_AVERAGE;
    grid_ray gr;
    if (skipping)
        grid_ray_of(job, o, d, t_near, &gr);
    for (long i = 0; i < n; i++) {
        float tm, g[3];
        float ts = t_near + (float)i * job->step;
        if (i == n - 1 && t_far - ts <= 0.0f)
            break;
        if (skipping) {
            float p[3];
            float ds = i < n - 1 ? job->step : t_far - ts;
            float tmid = ts + 0.5f * ds;
            for (int a = 0; a < 3; a++)
                p[a] = o[a] + tmid * d[a];
            grid_position(job, p, g);
            int lo, hi;
            brick_range(job, g, &lo, &hi);
            if (is_max ? (float)hi <= best : (float)lo >= best) {
                int cell[3];
                cell_of(g, cell);
                long next = skip_target(job, &gr, cell, 1, i);
                next = next < n ? next : n;
                taken += (uint64_t)(next - i);
                if (next == n && t_far - (t_near + (float)(n - 1) * job->step) <= 0.0f)
                    taken--; /* the definition stops before an empty last segment */
                i = next - 1;
                continue;
            }
        }
        float s = sample_at(job, o, d, t_near, t_far, i, n, &tm, g);
        taken++;
        sum += s;
        best = is_max ? max_f(best, s) : job->blend == CDVR_BLEND_MIN ? min_f(best, s) : best;
    }
    extreme_pixel(job, best, sum, taken, out);
    return taken;
}

/* The point at parameter t on the ray, as a grid position, and its code. */
static float field_at(const render_job *job, const float o[3], const float d[3], float t,
                      float g[3])
{
    float p[3];
    for (int a = 0; a < 3; a++)
        p[a] = o[a] + t * d[a];
    grid_position(job, p, g);
    return sample_volume(job, g);
}

/* Iso skipping: the flags (iso_flags) mark the bricks whose value range holds the iso code;
 * in a cube of bricks that do not, every value lies on one side of it (neighbouring bricks
 * share their boundary voxels, so a connected block of bricks each wholly above or below the
 * code is wholly on one side). Sample i (at grid position g, not a hit) in such a cube: the
 * samples after it inside the cube are on its side: none is a hit. The march resumes at the
 * last of them, next - 1, which it takes as usual: the hit test there needs only the side of
 * its predecessor, which sample i's value gives. Returns the index before the one to take
 * (the loop's i++ follows); the samples jumped are counted. */
static long iso_jump(const render_job *job, const grid_ray *gr, const float g[3], long i, long n,
                     uint64_t *taken)
{
    int code = brick_code(job, g);
    if (code >= 128)
        return i;
    int cell[3];
    cell_of(g, cell);
    long next = skip_target(job, gr, cell, code, i);
    next = next < n ? next : n;
    if (next - 2 <= i)
        return i;
    *taken += (uint64_t)(next - 2 - i); /* samples i + 1 .. next - 2: full segments */
    return next - 2;
}

/* The pixel of a ray whose sample s (at parameter tm) is the first hit of the iso code, its
 * predecessor's code and parameter prev, t_prev: two regula-falsi steps, colour, shading. */
static void iso_hit(const render_job *job, const float o[3], const float d[3],
                    const float V[3], float prev, float t_prev, float s, float tm, float out[4])
{
    float c = job->iso_code, g[3];
    float ta = t_prev, tb = tm, sa = prev, sb = s, t = tm;
    for (int k = 0; k < 2 && s != c && sb != sa; k++) {
        t = ta + (c - sa) * (tb - ta) / (sb - sa);
        float st = field_at(job, o, d, t, g);
        if ((sa - c) * (st - c) <= 0.0f) {
            tb = t;
            sb = st;
        } else {
            ta = t;
            sa = st;
        }
    }
    field_at(job, o, d, t, g);
    float rgba[4];
    table_at(job, c, rgba);
    if (!job->iso_tf_color)
        for (int k = 0; k < 3; k++)
            rgba[k] = job->iso_rgb[k];
    if (job->shade) {
        float G[3];
        gradient(job, g, G);
        shade_rgb(job, G, V, rgba);
    }
    for (int k = 0; k < 3; k++)
        out[k] = rgba[k] * job->iso_alpha;
    out[3] = job->iso_alpha;
}

/* The first crossing of the iso code, refined by two regula-falsi steps (render.h). */
static uint64_t march_iso(const render_job *job, const float o[3], const float d[3],
                          float t_near, float t_far, long n, const float V[3], float out[4])
{
    float c = job->iso_code, prev = 0.0f, t_prev = 0.0f;
    uint64_t taken = 0;
    grid_ray gr;
    if (job->skip_flags)
        grid_ray_of(job, o, d, t_near, &gr);
    for (long i = 0; i < n; i++) {
        float tm, g[3];
        float ts = t_near + (float)i * job->step;
        if (i == n - 1 && t_far - ts <= 0.0f)
            break;
        float s = sample_at(job, o, d, t_near, t_far, i, n, &tm, g);
        taken++;
        int hit = s == c || (i > 0 && (prev - c) * (s - c) < 0.0f);
        if (!hit) {
            prev = s;
            t_prev = tm;
            if (job->skip_flags)
                i = iso_jump(job, &gr, g, i, n, &taken);
            continue;
        }
        iso_hit(job, o, d, V, prev, t_prev, s, tm, out);
        return taken;
    }
    return taken;
}

/* Steps 2-5 of a composite ray from segment `first` to before `stop`; returns the samples
 * of the definition taken (those jumped by skipping included). */
static uint64_t march_composite(const render_job *job, const float o[3], const float d[3],
                                const float V[3], float t_near, float t_far, long n, long first,
                                long stop, float out[4])
{
    int looks = job->shade || job->go_points;
    int skipping = job->skip_flags != NULL;
    float C[3] = {0.0f, 0.0f, 0.0f}, A = 0.0f, step = job->step;
    grid_ray gr;
    if (skipping)
        grid_ray_of(job, o, d, t_near, &gr);
    uint64_t taken = 0;
    for (long i = first; i < stop; i++) {
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
        if (skipping) {
            int code = brick_code(job, g);
            if (code < 128) { /* invisible: sample i and those up to the cube's face add nothing */
                int cell[3];
                cell_of(g, cell);
                long next = skip_target(job, &gr, cell, code, i);
                next = next < stop ? next : stop;
                taken += (uint64_t)(next - i);
                if (next == n && t_far - (t_near + (float)(n - 1) * step) <= 0.0f)
                    taken--; /* the definition stops before an empty last segment */
                i = next - 1;
                continue;
            }
        }
        taken++;
        float sv = sample_volume(job, g);
        classify(job, sv, ds, ds >= step, rgba);
        if (looks && rgba[3] > 0.0f)
            look_sample(job, g, sv, ds, V, rgba);
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

/* Steps 2 and 5 for one ray; returns the number of samples taken. V: towards the eye, world
 * (for shading). */
static uint64_t march_ray(const render_job *job, const float o[3], const float d[3],
                          const float V[3], float out[4])
{
    float t_near, t_far;
    out[0] = out[1] = out[2] = out[3] = 0.0f;
    if (!intersect_box(job, o, d, &t_near, &t_far))
        return 0;
    float length = t_far - t_near, step = job->step;
    long n = (long)ceilf(length / step);
    if (n < 1)
        n = 1;
    if (job->blend == CDVR_BLEND_ISO)
        return march_iso(job, o, d, t_near, t_far, n, V, out);
    if (job->blend != CDVR_BLEND_COMPOSITE)
        return march_extreme(job, o, d, t_near, t_far, n, out);
    long first = 0, stop = n;
    if (job->clipped)
        owned_segments(job, o, d, t_near, n, &first, &stop);
    return march_composite(job, o, d, V, t_near, t_far, n, first, stop, out);
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

/* cdvr_camera_ray's ray through pixel (x, y), with the camera's basis computed once per
 * render (job) instead of per pixel. */
static void pixel_ray(const render_job *job, int x, int y, double origin[3], double dir[3])
{
    cdvr_camera_frame_ray(job->camera, &job->cam_frame, x, y, origin, dir);
}

/* ---- four rays at a time (SSE2) -------------------------------------------------------------
 * The composite (shading and gradient opacity per lane, by look_sample), max, min, average
 * and iso (the hit refined by iso_hit) marches (not clipped) of four neighbouring pixels in
 * lock-step: each lane keeps its own segment index, so the lanes take exactly the samples, in
 * the same order, with the same float operations as march_composite, march_extreme and
 * march_iso (IEEE single precision, the same operand order, no fused multiply-add:
 * maxps/minps are max_f/min_f, cvttps2dq is the (int) truncation, cvtdq2ps is exact for the
 * at most 2^24 segments of a ray); voxel, brick and table reads are per lane. Lanes that
 * jump empty space or have finished read voxels too (at positions clamped into the volume)
 * but add zero weight, which leaves C and A bit for bit unchanged. The shorter last
 * segment's alpha (powf) is taken per lane as classify does. */
#ifdef __SSE2__
#define LANES 4

typedef struct lanes {
    int blend;               /* cdvr_blend */
    float best[LANES];       /* max, min: the extreme so far (from the guess, see render_lanes) */
    float guess[LANES];      /* max, min: the guess the march started from, or -inf / +inf */
    int reached[LANES];      /* max, min: a sample reached the guess (at or beyond it) */
    double sum[LANES];       /* average: the sum of the codes */
    int live[LANES];         /* the lanes that meet the volume: the marches start these */
    int n[LANES];            /* segments (the marches keep their indices in registers) */
    uint64_t taken[LANES];
    grid_ray gr[LANES];
    float t_near[LANES], t_far[LANES];
    float o[3][LANES], d[3][LANES];
    float V[3][LANES];       /* shading: towards the eye, world */
    float g[3][LANES];       /* shading: the grid positions of the last sample (lanes_march) */
    /* iso: the last sample's code and parameter before a hit, and the hit (code, parameter) */
    float prev[LANES], t_prev[LANES], hit_s[LANES], hit_tm[LANES];
    int hit[LANES];
} lanes;

/* Four integer codes as floats (exact). */
static inline __m128 code4(const int v[LANES])
{
    return _mm_cvtepi32_ps(_mm_loadu_si128((const __m128i *)v));
}

static inline __m128 lerp4(__m128 a, __m128 b, __m128 f)
{
    return _mm_add_ps(a, _mm_mul_ps(f, _mm_sub_ps(b, a)));
}

/* Lane k's eight voxel codes around cell (x, y, z) (clamped; the upper neighbour along an
 * axis is the voxel itself on the volume's last voxel, as in sample_volume) into v[0..7][k],
 * as integers: (float) of them, by cvtdq2ps, is code_value's value. */
static inline void gather_lane(const render_job *job, int x, int y, int z, int v[8][LANES],
                               int k)
{
    size_t dx = x + 1 < job->dims[0], dy = y + 1 < job->dims[1] ? job->stride_y : 0;
    size_t dz = z + 1 < job->dims[2] ? job->stride_z : 0;
    const uint8_t *p = job->voxels + (size_t)x + (size_t)y * job->stride_y +
                       (size_t)z * job->stride_z;
    v[0][k] = p[0];
    v[1][k] = p[dx];
    v[2][k] = p[dy];
    v[3][k] = p[dy + dx];
    v[4][k] = p[dz];
    v[5][k] = p[dz + dx];
    v[6][k] = p[dz + dy];
    v[7][k] = p[dz + dy + dx];
}

/* render.h step 3 for four lanes: the gathered corner codes v (gather_lane) blended at the
 * positions gv (lower corners gi), in the one-ray order. */
static inline __m128 lanes_trilinear(const __m128 gv[3], int gi[3][LANES], int v[8][LANES])
{
    __m128 f[3];
    for (int a = 0; a < 3; a++)
        f[a] = _mm_sub_ps(gv[a], _mm_cvtepi32_ps(_mm_loadu_si128((const __m128i *)gi[a])));
    __m128 c00 = lerp4(code4(v[0]), code4(v[1]), f[0]);
    __m128 c10 = lerp4(code4(v[2]), code4(v[3]), f[0]);
    __m128 c01 = lerp4(code4(v[4]), code4(v[5]), f[0]);
    __m128 c11 = lerp4(code4(v[6]), code4(v[7]), f[0]);
    return lerp4(lerp4(c00, c10, f[1]), lerp4(c01, c11, f[1]), f[2]);
}

/* gradient() for the lanes in mask at their grid positions L->g into G[.][k]: the six samples
 * of each lane gathered as sample_axes loads them, blended four lanes at a time in its order
 * (lanes_trilinear's lerps), the differences and the matrix as gradient() does them. */
static void lanes_gradient(const render_job *job, const lanes *L, unsigned mask,
                           __m128 G[3])
{
    int v[6][8][LANES];
    float f[6][3][LANES], h[3][LANES];
    for (int k = 0; k < LANES; k++) {
        if (!((mask >> k) & 1)) { /* zeros: a finite gradient, not used */
            for (int j = 0; j < 6; j++) {
                for (int c = 0; c < 8; c++)
                    v[j][c][k] = 0;
                f[j][0][k] = f[j][1][k] = f[j][2][k] = 0.0f;
            }
            h[0][k] = h[1][k] = h[2][k] = 0.0f;
            continue;
        }
        axis_at ax[3][3]; /* [axis][at, up, down] */
        for (int a = 0; a < 3; a++) {
            float g = L->g[a][k], top = (float)(job->dims[a] - 1);
            float gp = min_f(g + 1.0f, top), gm = max_f(g - 1.0f, 0.0f);
            h[a][k] = gp - gm;
            ax[a][0] = axis_setup(job, a, g);
            ax[a][1] = axis_setup(job, a, gp);
            ax[a][2] = axis_setup(job, a, gm);
        }
#pragma GCC unroll 6
        for (int j = 0; j < 6; j++) { /* sample j moves axis a = j / 2, up then down */
            int a = j / 2, up = j % 2 == 0;
            const axis_at *X = &ax[0][a == 0 ? 2 - up : 0];
            const axis_at *Y = &ax[1][a == 1 ? 2 - up : 0];
            const axis_at *Z = &ax[2][a == 2 ? 2 - up : 0];
#pragma GCC unroll 8
            for (int c = 0; c < 8; c++)
                v[j][c][k] = job->voxels[(c & 1 ? X->hi : X->lo) + (c & 2 ? Y->hi : Y->lo) +
                                         (c & 4 ? Z->hi : Z->lo)];
            f[j][0][k] = X->f, f[j][1][k] = Y->f, f[j][2][k] = Z->f;
        }
    }
    __m128 sv[6];
    for (int j = 0; j < 6; j++) {
        __m128 fx = _mm_loadu_ps(f[j][0]), fy = _mm_loadu_ps(f[j][1]), fz = _mm_loadu_ps(f[j][2]);
        __m128 c00 = lerp4(code4(v[j][0]), code4(v[j][1]), fx);
        __m128 c10 = lerp4(code4(v[j][2]), code4(v[j][3]), fx);
        __m128 c01 = lerp4(code4(v[j][4]), code4(v[j][5]), fx);
        __m128 c11 = lerp4(code4(v[j][6]), code4(v[j][7]), fx);
        sv[j] = lerp4(lerp4(c00, c10, fy), lerp4(c01, c11, fy), fz);
    }
    __m128 dq[3];
    for (int a = 0; a < 3; a++) { /* h > 0 ? (s+ - s-) / (h spacing) : 0 */
        __m128 hv = _mm_loadu_ps(h[a]), hs = _mm_mul_ps(hv, _mm_set1_ps(job->spacing[a]));
        __m128 q = _mm_div_ps(_mm_sub_ps(sv[2 * a], sv[2 * a + 1]), hs);
        dq[a] = _mm_and_ps(_mm_cmpgt_ps(hv, _mm_setzero_ps()), q);
    }
    const float *m = job->grad_to_world;
    for (int r = 0; r < 3; r++)
        G[r] = _mm_add_ps(_mm_add_ps(_mm_mul_ps(_mm_set1_ps(m[3 * r]), dq[0]),
                                     _mm_mul_ps(_mm_set1_ps(m[3 * r + 1]), dq[1])),
                          _mm_mul_ps(_mm_set1_ps(m[3 * r + 2]), dq[2]));
}

static inline __m128 length4(const __m128 v[3])
{
    return _mm_sqrt_ps(_mm_add_ps(_mm_add_ps(_mm_mul_ps(v[0], v[0]), _mm_mul_ps(v[1], v[1])),
                                  _mm_mul_ps(v[2], v[2])));
}

static inline __m128 dot4(const __m128 a[3], const __m128 b[3])
{
    return _mm_add_ps(_mm_add_ps(_mm_mul_ps(a[0], b[0]), _mm_mul_ps(a[1], b[1])),
                      _mm_mul_ps(a[2], b[2]));
}

/* shade_rgb for the lanes in mask (gradients G, rgb[c][k] in place), four at a time: the
 * same operations in its order (sqrtps, divps and minps round and choose as sqrtf, / and
 * min_f do; a lane whose gradient is below 1e-12 gets ndl = ndh = 0 as there); a power that
 * is not whole is taken per lane by powf. */
static void lanes_shade(const render_job *job, const lanes *L, unsigned mask, const __m128 G[3],
                        float rgb[3][LANES])
{
    const __m128 zero = _mm_setzero_ps(), sign = _mm_set1_ps(-0.0f);
    __m128 V[3], Lv[3], H[3], n[3];
    for (int a = 0; a < 3; a++) {
        V[a] = _mm_loadu_ps(L->V[a]);
        Lv[a] = job->headlight ? V[a] : _mm_set1_ps(job->light[a]);
        H[a] = _mm_add_ps(Lv[a], V[a]);
    }
    __m128 len = length4(G), hl = length4(H);
    __m128 ok = _mm_cmpge_ps(len, _mm_set1_ps(1e-12f));
    for (int a = 0; a < 3; a++)
        n[a] = _mm_div_ps(G[a], len);
    __m128 ndl = _mm_and_ps(ok, _mm_andnot_ps(sign, dot4(n, Lv)));
    __m128 ndh = _mm_div_ps(_mm_andnot_ps(sign, dot4(n, H)), hl);
    ndh = _mm_and_ps(_mm_and_ps(ok, _mm_cmpgt_ps(hl, zero)), ndh);
    __m128 pw;
    if (job->whole_power >= 0) {
        __m128 x = ndh;
        pw = _mm_set1_ps(1.0f);
        for (unsigned e = (unsigned)job->whole_power; e; e >>= 1) {
            if (e & 1u)
                pw = _mm_mul_ps(pw, x);
            x = _mm_mul_ps(x, x);
        }
    } else {
        float nv[LANES], pv[LANES];
        _mm_storeu_ps(nv, ndh);
        for (int k = 0; k < LANES; k++)
            pv[k] = nv[k] > 0.0f ? powf(nv[k], job->power) : 0.0f;
        pw = _mm_loadu_ps(pv);
    }
    __m128 spec = _mm_and_ps(_mm_cmpgt_ps(ndh, zero), _mm_mul_ps(_mm_set1_ps(job->specular), pw));
    __m128 kd = _mm_add_ps(_mm_set1_ps(job->ambient), _mm_mul_ps(_mm_set1_ps(job->diffuse), ndl));
    float out[3][LANES];
    for (int c = 0; c < 3; c++)
        _mm_storeu_ps(out[c], _mm_min_ps(_mm_add_ps(_mm_mul_ps(_mm_loadu_ps(rgb[c]), kd), spec),
                                         _mm_set1_ps(1.0f)));
    for (int k = 0; k < LANES; k++)
        if ((mask >> k) & 1)
            for (int c = 0; c < 3; c++)
                rgb[c][k] = out[c][k];
}

/* Step 2 at the four lanes' segment midpoints tm: grid positions clamped into the volume (gv)
 * and their lower corners (gi). */
static inline void lanes_position(const render_job *job, const lanes *L, __m128 tm,
                                  __m128 gv[3], int gi[3][LANES])
{
    const __m128 zero = _mm_setzero_ps();
    for (int a = 0; a < 3; a++) {
        __m128 p = _mm_add_ps(_mm_loadu_ps(L->o[a]), _mm_mul_ps(tm, _mm_loadu_ps(L->d[a])));
        __m128 top = _mm_set1_ps((float)(job->dims[a] - 1));
        gv[a] = _mm_min_ps(_mm_max_ps(_mm_mul_ps(p, _mm_set1_ps(job->inv_spacing[a])), zero), top);
        _mm_storeu_si128((__m128i *)gi[a], _mm_cvttps_epi32(gv[a]));
    }
}

/* Step 2 as sample_at, for lanes at segment indices i (last: n - 1): returns the segment
 * lengths ds (the step, or the rest of the ray for the last one) and gives the midpoints tm. */
static inline __m128 lanes_segment(__m128 t_near, __m128 t_far, __m128i i, __m128i last,
                                   __m128 step, __m128 *tm)
{
    __m128 ts = _mm_add_ps(t_near, _mm_mul_ps(_mm_cvtepi32_ps(i), step));
    __m128 full = _mm_castsi128_ps(_mm_cmplt_epi32(i, last));
    __m128 ds = _mm_or_ps(_mm_and_ps(full, step), _mm_andnot_ps(full, _mm_sub_ps(t_far, ts)));
    *tm = _mm_add_ps(ts, _mm_mul_ps(_mm_set1_ps(0.5f), ds));
    return ds;
}

/* ---- the march of four lanes (composite, max, min, average) -------------------------------
 * The lanes' indices, masks and results stay in registers from step to step, and the
 * choice to jump or sample is made for four lanes at once: a step branches per lane only
 * where a lane jumps (branches on the data of single lanes mispredict often). Every step
 * and sample is the one-ray march's (march_ray), in its order. */

typedef struct march_lanes {
    __m128i i, live, taken; /* segment index, still marching (-1: yes), samples counted */
    __m128i reached;        /* max, min: a sample reached the guess (-1: yes) */
    __m128 best;            /* max, min: the extreme so far */
    __m128d sum[2];         /* average: the sums of lanes 0-1 and of lanes 2-3 */
    __m128 C[3], A;         /* composite: colour and opacity */
} march_lanes;

/* The live lanes in empty space at cells gi, in bricks brick (composite: an invisible
 * brick; max: a brick whose max is at most the best, min: whose min is at least it; average:
 * a brick of zeros), as a mask. */
static __m128i lanes_empty(const render_job *job, const lanes *L, const march_lanes *M,
                           int gi[3][LANES], size_t brick[LANES])
{
    if (!job->skip_flags && !job->skip_minmax) /* skipping is only a saving */
        return _mm_setzero_si128();
    for (int k = 0; k < LANES; k++) { /* every gi lies in the volume: lanes off too */
        int cell[3] = {gi[0][k], gi[1][k], gi[2][k]};
        brick[k] = brick_of_cell(job, cell);
    }
    /* the vectors are built in registers: four scalar stores read back as one vector load
     * would stall */
    if (job->skip_flags) {
        const uint8_t *f = job->skip_flags;
        __m128i code = _mm_setr_epi32(f[brick[0]], f[brick[1]], f[brick[2]], f[brick[3]]);
        return _mm_and_si128(M->live, _mm_cmplt_epi32(code, _mm_set1_epi32(128)));
    }
    const int is_min = L->blend == CDVR_BLEND_MIN;
    const __m128 best = L->blend == CDVR_BLEND_AVERAGE ? _mm_setzero_ps() : M->best;
    const uint8_t *e = job->skip_minmax + !is_min; /* max, average: the bricks' max */
    __m128 edge = _mm_cvtepi32_ps(
        _mm_setr_epi32(e[2 * brick[0]], e[2 * brick[1]], e[2 * brick[2]], e[2 * brick[3]]));
    __m128 dull = is_min ? _mm_cmpge_ps(edge, best) : _mm_cmple_ps(edge, best);
    return _mm_and_si128(M->live, _mm_castps_si128(dull));
}

/* skip_target's code for a lane in empty space in brick b: composite the brick's flag (the
 * reach of its invisible cube), the others the cube of reach WIDE_REACH when it is dull too
 * (best: the lane's extreme, 0 for average). */
static inline int empty_code(const render_job *job, int blend, size_t b, float best)
{
    if (job->skip_flags)
        return job->skip_flags[b];
    if (!job->skip_wide)
        return 1;
    int is_min = blend == CDVR_BLEND_MIN;
    float wide = job->skip_wide[2 * b + !is_min];
    return (is_min ? wide >= best : wide <= best) ? WIDE_REACH + 1 : 1;
}

/* The lanes in the mask `jump` (bits `jumps`) jump from cells gi to the exit of the empty
 * cube around their bricks (skip_target), at most n; the samples jumped count as the
 * definition takes them: not an empty last segment (empty_end). */
static void lanes_jump(const render_job *job, const lanes *L, int jumps, __m128i jump,
                       int gi[3][LANES], const size_t brick[LANES], __m128i n,
                       __m128i empty_end, march_lanes *M)
{
    int iv[LANES], nv[LANES], next[LANES];
    float bv[LANES];
    _mm_storeu_si128((__m128i *)iv, M->i);
    _mm_storeu_si128((__m128i *)nv, n);
    _mm_storeu_ps(bv, L->blend == CDVR_BLEND_AVERAGE ? _mm_setzero_ps() : M->best);
    for (int k = 0; k < LANES; k++) {
        next[k] = iv[k];
        if (!((jumps >> k) & 1))
            continue;
        int cell[3] = {gi[0][k], gi[1][k], gi[2][k]};
        int code = empty_code(job, L->blend, brick[k], bv[k]);
        long to = skip_target(job, &L->gr[k], cell, code, iv[k]);
        next[k] = (int)(to < nv[k] ? to : nv[k]);
    }
    __m128i to = _mm_setr_epi32(next[0], next[1], next[2], next[3]);
    __m128i at_end = _mm_and_si128(jump, _mm_cmpeq_epi32(to, n));
    M->taken = _mm_add_epi32(M->taken, _mm_sub_epi32(to, M->i));
    M->taken = _mm_add_epi32(M->taken, _mm_and_si128(at_end, empty_end)); /* -1 there */
    M->i = to;
    M->live = _mm_andnot_si128(at_end, M->live);
}

/* look_sample for the lanes in the mask lit: gradients and shading four at a time, the
 * gradient opacity lane by lane (samples sv over segments dsv). */
static void lanes_look(const render_job *job, const lanes *L, unsigned lit, const float sv[LANES],
                       const float dsv[LANES], float rgb[3][LANES], float alpha[LANES])
{
    __m128 G[3];
    lanes_gradient(job, L, lit, G);
    if (!job->go_points) {
        lanes_shade(job, L, lit, G, rgb);
        return;
    }
    float Gv[3][LANES];
    for (int a = 0; a < 3; a++)
        _mm_storeu_ps(Gv[a], G[a]);
    for (int k = 0; k < LANES; k++) {
        if (!((lit >> k) & 1))
            continue;
        float rgba[4] = {rgb[0][k], rgb[1][k], rgb[2][k], alpha[k]};
        float Gk[3] = {Gv[0][k], Gv[1][k], Gv[2][k]};
        float Vk[3] = {L->V[0][k], L->V[1][k], L->V[2][k]};
        look_gradient(job, Gk, sv[k], dsv[k], Vk, rgba);
        for (int c = 0; c < 3; c++)
            rgb[c][k] = rgba[c];
        alpha[k] = rgba[3];
    }
}

/* Composite, render.h steps 4-5: the sampling lanes' samples s over segments ds classified,
 * lit and composited; the lanes whose opacity reaches the termination stop. */
static void composite_take(const render_job *job, const lanes *L, __m128i sampling, __m128 s,
                           __m128 ds, march_lanes *M)
{
    /* step 4: i0 = min((int)s, 254) as the truncation of min(s, 254) */
    __m128i si = _mm_cvttps_epi32(_mm_min_ps(s, _mm_set1_ps(254.0f)));
    __m128 fr = _mm_sub_ps(s, _mm_cvtepi32_ps(si));
    int ti[LANES];
    _mm_storeu_si128((__m128i *)ti, si);
    /* each lane's two entries (r, g, b, a_c) of the table, transposed to channels */
    __m128 lo[4], hi[4];
    for (int k = 0; k < LANES; k++) {
        lo[k] = _mm_loadu_ps(job->rgb_alpha_step[ti[k]]);
        hi[k] = _mm_loadu_ps(job->rgb_alpha_step[ti[k] + 1]);
    }
    _MM_TRANSPOSE4_PS(lo[0], lo[1], lo[2], lo[3]);
    _MM_TRANSPOSE4_PS(hi[0], hi[1], hi[2], hi[3]);
    const __m128 on = _mm_castsi128_ps(sampling), step = _mm_set1_ps(job->step);
    float alpha[LANES], rgb[3][LANES], sv[LANES], dsv[LANES];
    __m128 a = _mm_and_ps(on, lerp4(lo[3], hi[3], fr));
    for (int c = 0; c < 3; c++)
        _mm_storeu_ps(rgb[c], lerp4(lo[c], hi[c], fr));
    _mm_storeu_ps(sv, s);
    _mm_storeu_ps(dsv, ds);
    int shorter = _mm_movemask_ps(_mm_and_ps(on, _mm_cmpnge_ps(ds, step)));
    if (shorter) { /* the shorter last segment (classify) */
        _mm_storeu_ps(alpha, a);
        for (int k = 0; k < LANES; k++) {
            if (!((shorter >> k) & 1))
                continue;
            float rgba[4];
            classify(job, sv[k], dsv[k], 0, rgba);
            alpha[k] = rgba[3];
        }
        a = _mm_loadu_ps(alpha);
    }
    unsigned lit = job->shade || job->go_points
                       ? (unsigned)_mm_movemask_ps(_mm_cmpgt_ps(a, _mm_setzero_ps()))
                       : 0;
    if (lit) {
        _mm_storeu_ps(alpha, a);
        lanes_look(job, L, lit, sv, dsv, rgb, alpha);
        a = _mm_loadu_ps(alpha);
    }
    const __m128 one = _mm_set1_ps(1.0f);
    __m128 w = _mm_mul_ps(_mm_sub_ps(one, M->A), a);
    for (int c = 0; c < 3; c++)
        M->C[c] = _mm_add_ps(M->C[c], _mm_mul_ps(w, _mm_loadu_ps(rgb[c])));
    M->A = _mm_add_ps(M->A, w);
    __m128 opaque = _mm_or_ps(_mm_cmpge_ps(M->A, _mm_set1_ps(job->term_alpha)),
                              _mm_cmpge_ps(M->A, one));
    __m128 stop = _mm_and_ps(_mm_cmpgt_ps(a, _mm_setzero_ps()), opaque);
    M->live = _mm_andnot_si128(_mm_and_si128(sampling, _mm_castps_si128(stop)), M->live);
}

/* Max and min: the sampling lanes' samples s into their extremes; a lane at code 255 (min:
 * 0) stops, the rest counted as the definition takes them (not an empty last segment). */
static void extreme_take(const lanes *L, __m128i sampling, __m128 s, __m128i n,
                         __m128i empty_end, march_lanes *M)
{
    const int is_max = L->blend == CDVR_BLEND_MAX;
    const __m128 on = _mm_castsi128_ps(sampling), guess = _mm_loadu_ps(L->guess);
    __m128 best = is_max ? _mm_max_ps(M->best, s) : _mm_min_ps(M->best, s);
    M->best = _mm_or_ps(_mm_and_ps(on, best), _mm_andnot_ps(on, M->best));
    __m128 reach = is_max ? _mm_cmpge_ps(s, guess) : _mm_cmple_ps(s, guess);
    M->reached = _mm_or_si128(M->reached, _mm_and_si128(sampling, _mm_castps_si128(reach)));
    /* no code lies beyond 255 (below 0): the rest cannot change the extreme */
    __m128 stop = _mm_set1_ps(is_max ? 255.0f : 0.0f);
    __m128i done = _mm_and_si128(_mm_and_si128(M->live, sampling),
                                 _mm_castps_si128(_mm_cmpeq_ps(M->best, stop)));
    if (_mm_movemask_epi8(done)) {
        M->taken = _mm_add_epi32(M->taken, _mm_and_si128(done, _mm_sub_epi32(n, M->i)));
        M->taken = _mm_add_epi32(M->taken, _mm_and_si128(done, empty_end)); /* -1 there */
        M->i = _mm_or_si128(_mm_and_si128(done, n), _mm_andnot_si128(done, M->i));
        M->live = _mm_andnot_si128(done, M->live);
    }
}

/* Average: the sampling lanes' samples into their sums, in double (the others add +0). */
static void average_take(__m128i sampling, __m128 s, march_lanes *M)
{
    __m128 on = _mm_and_ps(_mm_castsi128_ps(sampling), s);
    M->sum[0] = _mm_add_pd(M->sum[0], _mm_cvtps_pd(on));
    M->sum[1] = _mm_add_pd(M->sum[1], _mm_cvtps_pd(_mm_movehl_ps(on, on)));
}

/* The march of the live lanes of L to their ends (composite: into C and A). */
static void lanes_march(const render_job *job, lanes *L, __m128 C[3], __m128 *A)
{
    const __m128 step = _mm_set1_ps(job->step), zero = _mm_setzero_ps();
    const __m128 t_near = _mm_loadu_ps(L->t_near), t_far = _mm_loadu_ps(L->t_far);
    const __m128i n = _mm_loadu_si128((const __m128i *)L->n);
    const __m128i last = _mm_sub_epi32(n, _mm_set1_epi32(1));
    /* the ray's last segment is empty: the definition neither takes nor counts it */
    const __m128 end = _mm_add_ps(t_near, _mm_mul_ps(_mm_cvtepi32_ps(last), step));
    const __m128i empty_end = _mm_castps_si128(_mm_cmple_ps(_mm_sub_ps(t_far, end), zero));
    const int looks = job->shade || job->go_points;
    march_lanes M = {
        .live = _mm_sub_epi32(_mm_setzero_si128(), _mm_loadu_si128((const __m128i *)L->live)),
        .best = _mm_loadu_ps(L->best),
        .sum = {_mm_setzero_pd(), _mm_setzero_pd()},
        .C = {zero, zero, zero},
    };
    for (;;) {
        __m128 tm, ds = lanes_segment(t_near, t_far, M.i, last, step, &tm);
        /* a lane at an empty last segment stops (the definition does not take it) */
        M.live = _mm_and_si128(M.live, _mm_castps_si128(_mm_cmpgt_ps(ds, zero)));
        if (!_mm_movemask_epi8(M.live))
            break;
        __m128 gv[3];
        int gi[3][LANES];
        size_t brick[LANES];
        lanes_position(job, L, tm, gv, gi);
        __m128i jump = lanes_empty(job, L, &M, gi, brick);
        __m128i sampling = _mm_andnot_si128(jump, M.live);
        int jumps = _mm_movemask_ps(_mm_castsi128_ps(jump));
        if (jumps)
            lanes_jump(job, L, jumps, jump, gi, brick, n, empty_end, &M);
        if (!_mm_movemask_epi8(sampling))
            continue;
        /* step 3 for every lane: a branch per lane costs more than the loads it saves */
        int v[8][LANES];
        for (int k = 0; k < LANES; k++)
            gather_lane(job, gi[0][k], gi[1][k], gi[2][k], v, k);
        if (looks) /* the gradient's positions (lanes_gradient) */
            for (int a = 0; a < 3; a++)
                _mm_storeu_ps(L->g[a], gv[a]);
        __m128 s = lanes_trilinear(gv, gi, v);
        M.taken = _mm_sub_epi32(M.taken, sampling); /* -1 in the sampling lanes */
        M.i = _mm_sub_epi32(M.i, sampling);
        M.live = _mm_andnot_si128(_mm_andnot_si128(_mm_cmplt_epi32(M.i, n), sampling), M.live);
        if (L->blend == CDVR_BLEND_COMPOSITE)
            composite_take(job, L, sampling, s, ds, &M);
        else if (L->blend == CDVR_BLEND_AVERAGE)
            average_take(sampling, s, &M);
        else
            extreme_take(L, sampling, s, n, empty_end, &M);
    }
    int tv[LANES], rv[LANES];
    _mm_storeu_si128((__m128i *)tv, M.taken);
    _mm_storeu_si128((__m128i *)rv, M.reached);
    _mm_storeu_ps(L->best, M.best);
    _mm_storeu_pd(L->sum, M.sum[0]);
    _mm_storeu_pd(L->sum + 2, M.sum[1]);
    for (int k = 0; k < LANES; k++) {
        L->taken[k] += (uint64_t)(unsigned)tv[k]; /* at most n: an int */
        L->reached[k] = rv[k] != 0;
    }
    for (int c = 0; c < 3; c++)
        C[c] = M.C[c];
    *A = M.A;
}

/* Iso misses that lie in an invisible brick (flag code < 128, the lanes in `misses`) jump as
 * iso_jump does: the samples after i inside the cube are on its side, none is a hit, and the
 * march resumes at the last of them (next - 2 before the step's i + 1), counted as taken. */
static void iso_jumps(const render_job *job, const lanes *L, int misses, int gi[3][LANES],
                      __m128i n, __m128i *i, __m128i *taken)
{
    int iv[LANES], nv[LANES], next[LANES], add[LANES];
    _mm_storeu_si128((__m128i *)iv, *i);
    _mm_storeu_si128((__m128i *)nv, n);
    for (int k = 0; k < LANES; k++) {
        next[k] = iv[k], add[k] = 0;
        if (!((misses >> k) & 1))
            continue;
        int cell[3] = {gi[0][k], gi[1][k], gi[2][k]};
        int code = job->skip_flags[brick_of_cell(job, cell)];
        if (code >= 128)
            continue;
        long to = skip_target(job, &L->gr[k], cell, code, iv[k]);
        to = to < nv[k] ? to : nv[k];
        if (to - 2 > iv[k]) { /* samples i + 1 .. next - 2: full segments */
            add[k] = (int)(to - 2 - iv[k]);
            next[k] = (int)(to - 2);
        }
    }
    /* built in registers: four scalar stores read back as one vector load would stall */
    *i = _mm_setr_epi32(next[0], next[1], next[2], next[3]);
    *taken = _mm_add_epi32(*taken, _mm_setr_epi32(add[0], add[1], add[2], add[3]));
}

/* Iso (march_iso lane by lane, its state in registers as lanes_march keeps it): every live
 * lane takes its sample (every lane reads its voxels: positions are clamped into the
 * volume); a hit stops the lane and is kept for iso_hit, a miss becomes the predecessor and
 * may jump as iso_jump does. */
static void lanes_iso_march(const render_job *job, lanes *L)
{
    const __m128 step = _mm_set1_ps(job->step), zero = _mm_setzero_ps();
    const __m128 c = _mm_set1_ps(job->iso_code);
    const __m128 t_near = _mm_loadu_ps(L->t_near), t_far = _mm_loadu_ps(L->t_far);
    const __m128i n = _mm_loadu_si128((const __m128i *)L->n);
    const __m128i last = _mm_sub_epi32(n, _mm_set1_epi32(1));
    __m128i i = _mm_setzero_si128(), taken = _mm_setzero_si128();
    __m128i live = _mm_sub_epi32(_mm_setzero_si128(), _mm_loadu_si128((const __m128i *)L->live));
    __m128i hit = _mm_setzero_si128();
    __m128 prev = zero, t_prev = zero, hit_s = zero, hit_tm = zero;
    for (;;) {
        __m128 tm, ds = lanes_segment(t_near, t_far, i, last, step, &tm);
        /* a lane at an empty last segment stops (the definition does not take it) */
        live = _mm_and_si128(live, _mm_castps_si128(_mm_cmpgt_ps(ds, zero)));
        if (!_mm_movemask_epi8(live))
            break;
        __m128 gv[3];
        int gi[3][LANES], v[8][LANES];
        lanes_position(job, L, tm, gv, gi);
        for (int k = 0; k < LANES; k++)
            gather_lane(job, gi[0][k], gi[1][k], gi[2][k], v, k);
        __m128 s = lanes_trilinear(gv, gi, v), on = _mm_castsi128_ps(live);
        taken = _mm_sub_epi32(taken, live); /* -1 in the live lanes */
        /* a hit: s == c, or a change of side from the predecessor (none before sample 0) */
        __m128 cross = _mm_cmplt_ps(_mm_mul_ps(_mm_sub_ps(prev, c), _mm_sub_ps(s, c)), zero);
        __m128 after = _mm_castsi128_ps(_mm_cmpgt_epi32(i, _mm_setzero_si128()));
        __m128 hits = _mm_and_ps(on, _mm_or_ps(_mm_cmpeq_ps(s, c), _mm_and_ps(after, cross)));
        __m128 miss = _mm_andnot_ps(hits, on);
        hit = _mm_or_si128(hit, _mm_castps_si128(hits));
        hit_s = _mm_or_ps(_mm_and_ps(hits, s), _mm_andnot_ps(hits, hit_s));
        hit_tm = _mm_or_ps(_mm_and_ps(hits, tm), _mm_andnot_ps(hits, hit_tm));
        prev = _mm_or_ps(_mm_and_ps(miss, s), _mm_andnot_ps(miss, prev));
        t_prev = _mm_or_ps(_mm_and_ps(miss, tm), _mm_andnot_ps(miss, t_prev));
        int misses = _mm_movemask_ps(miss);
        if (misses && job->skip_flags)
            iso_jumps(job, L, misses, gi, n, &i, &taken);
        __m128i missed = _mm_castps_si128(miss);
        i = _mm_sub_epi32(i, missed); /* i + 1 in the lanes that missed */
        live = _mm_andnot_si128(_mm_castps_si128(hits), live);
        live = _mm_andnot_si128(_mm_andnot_si128(_mm_cmplt_epi32(i, n), missed), live);
    }
    int tv[LANES], hv[LANES];
    _mm_storeu_si128((__m128i *)tv, taken);
    _mm_storeu_si128((__m128i *)hv, hit);
    _mm_storeu_ps(L->prev, prev);
    _mm_storeu_ps(L->t_prev, t_prev);
    _mm_storeu_ps(L->hit_s, hit_s);
    _mm_storeu_ps(L->hit_tm, hit_tm);
    for (int k = 0; k < LANES; k++) {
        L->taken[k] += (uint64_t)(unsigned)tv[k]; /* at most n: an int */
        L->hit[k] = hv[k] != 0;
    }
}

/* Steps 0 of pixels x .. x + 3 of row y for a pinhole camera, two rays at a time in double
 * (SSE2): the operations of cdvr_camera_frame_ray (its order, no fused multiply-add; sqrtpd
 * and divpd round as sqrt and / do) and of to_box_frame, so o, d and V are those of the
 * one-ray path bit for bit. The origin is the eye for every pixel: job->eye_box. Returns 0
 * (nothing written) for an orthographic camera or a zero-length direction: the caller then
 * takes the one-ray path. */
static int lanes_rays(const render_job *job, int x, int y, float o[3][LANES],
                      float d[3][LANES], float V[3][LANES])
{
    const cdvr_camera *cam = job->camera;
    const cdvr_camera_frame *fr = &job->cam_frame;
    if (cam->orthographic)
        return 0;
    double aspect = (double)cam->width / (double)cam->height;
    double sy = -(2.0 * (y + 0.5) / cam->height - 1.0);
    const __m128d two = _mm_set1_pd(2.0), one = _mm_set1_pd(1.0), half = _mm_set1_pd(0.5);
    const __m128d w = _mm_set1_pd((double)cam->width), tan = _mm_set1_pd(fr->tan_half_fov);
    __m128d dir[2][3];
    for (int p = 0; p < 2; p++) {
        __m128d xs = _mm_add_pd(_mm_set_pd((double)(x + 2 * p + 1), (double)(x + 2 * p)), half);
        __m128d sx = _mm_mul_pd(_mm_sub_pd(_mm_div_pd(_mm_mul_pd(two, xs), w), one),
                                _mm_set1_pd(aspect));
        for (int i = 0; i < 3; i++) {
            __m128d side = _mm_add_pd(_mm_mul_pd(sx, _mm_set1_pd(fr->r[i])),
                                      _mm_set1_pd(sy * fr->u[i]));
            dir[p][i] = _mm_add_pd(_mm_set1_pd(fr->f[i]), _mm_mul_pd(side, tan));
        }
        __m128d len2 = _mm_add_pd(_mm_add_pd(_mm_mul_pd(dir[p][0], dir[p][0]),
                                             _mm_mul_pd(dir[p][1], dir[p][1])),
                                  _mm_mul_pd(dir[p][2], dir[p][2]));
        __m128d len = _mm_sqrt_pd(len2);
        if (_mm_movemask_pd(_mm_cmpgt_pd(len, _mm_setzero_pd())) != 3)
            return 0;
        for (int i = 0; i < 3; i++)
            dir[p][i] = _mm_div_pd(dir[p][i], len);
    }
    const double *m = job->inv_dir;
    for (int p = 0; p < 2; p++) {
        double dd[3][2];
        for (int i = 0; i < 3; i++)
            _mm_storeu_pd(dd[i], dir[p][i]);
        for (int r = 0; r < 3; r++) {
            __m128d v = _mm_add_pd(_mm_add_pd(_mm_mul_pd(_mm_set1_pd(m[3 * r]), dir[p][0]),
                                              _mm_mul_pd(_mm_set1_pd(m[3 * r + 1]), dir[p][1])),
                                   _mm_mul_pd(_mm_set1_pd(m[3 * r + 2]), dir[p][2]));
            double db[2];
            _mm_storeu_pd(db, v);
            for (int k = 0; k < 2; k++) {
                d[r][2 * p + k] = (float)db[k];
                o[r][2 * p + k] = job->eye_box[r];
                V[r][2 * p + k] = (float)-dd[r][k];
            }
        }
    }
    return 1;
}

/* Step 1 for the four rays in L->o, L->d: intersect_box lane by lane (maxps and minps are
 * the fmaxf and fminf it calls, x86-64 glibc's maxss and minss, for operands that are not
 * NaN; the swap and the division as it does them), into t_near, t_far; returns the mask of
 * the lanes that hit, or -1 (nothing written) when a NaN turns up: the caller then takes
 * intersect_box. */
static int lanes_intersect(const render_job *job, const lanes *L, float t_near[LANES],
                           float t_far[LANES])
{
    const __m128 sign = _mm_set1_ps(-0.0f), zero = _mm_setzero_ps();
    __m128 t_enter = _mm_set1_ps(-INFINITY), t_exit = _mm_set1_ps(INFINITY);
    __m128 miss = zero, nan = zero;
    for (int a = 0; a < 3; a++) {
        __m128 o = _mm_loadu_ps(L->o[a]), d = _mm_loadu_ps(L->d[a]);
        __m128 hi = _mm_set1_ps(job->box_hi[a]);
        __m128 tiny = _mm_cmplt_ps(_mm_andnot_ps(sign, d), _mm_set1_ps(1e-12f));
        __m128 outside = _mm_or_ps(_mm_cmplt_ps(o, zero), _mm_cmpgt_ps(o, hi));
        miss = _mm_or_ps(miss, _mm_and_ps(tiny, outside));
        __m128 t0 = _mm_div_ps(_mm_sub_ps(zero, o), d), t1 = _mm_div_ps(_mm_sub_ps(hi, o), d);
        __m128 lo_t = _mm_min_ps(t1, t0), hi_t = _mm_max_ps(t0, t1); /* the swap */
        nan = _mm_or_ps(nan, _mm_andnot_ps(tiny, _mm_cmpunord_ps(lo_t, hi_t)));
        __m128 enter = _mm_max_ps(t_enter, lo_t), exit = _mm_min_ps(t_exit, hi_t);
        t_enter = _mm_or_ps(_mm_and_ps(tiny, t_enter), _mm_andnot_ps(tiny, enter));
        t_exit = _mm_or_ps(_mm_and_ps(tiny, t_exit), _mm_andnot_ps(tiny, exit));
    }
    if (_mm_movemask_ps(nan))
        return -1;
    __m128 tn = _mm_max_ps(t_enter, zero);
    _mm_storeu_ps(t_near, tn);
    _mm_storeu_ps(t_far, t_exit);
    return _mm_movemask_ps(_mm_andnot_ps(miss, _mm_cmpgt_ps(t_exit, tn)));
}

/* Pixels x .. x + 3 of row y (x + 3 < width) by the four-lane march; returns their samples.
 * Max and min may start from a guess of each ray's extreme (guess, NULL: none): the march then
 * jumps the bricks whose range cannot pass the guess either, and its extreme is exact once a
 * sample reaches the guess (every jumped sample lies at or below the best then, or the guess,
 * which the best has reached); the rays whose samples all stay short of their guess are
 * marched again together, without one. Only the lanes in the mask `want` are marched and
 * written. best_out (NULL: not wanted) gets each ray's exact extreme, NaN for a ray that
 * takes no sample. */
static uint64_t render_lanes(const render_job *job, int x, int y, const float guess[LANES],
                             float best_out[LANES], unsigned want)
{
    lanes L;
    memset(&L, 0, sizeof L);
    L.blend = job->blend;
    int fast = lanes_rays(job, x, y, L.o, L.d, L.V);
    float tn4[LANES], tf4[LANES];
    int hit4 = fast ? lanes_intersect(job, &L, tn4, tf4) : -1;
    for (int k = 0; k < LANES; k++) {
        L.guess[k] = guess ? guess[k] : job->blend == CDVR_BLEND_MIN ? INFINITY : -INFINITY;
        L.best[k] = L.guess[k];
        float o[3], d[3], t_near = 0.0f, t_far = 0.0f;
        if (!fast) {
            double od[3], dd[3];
            pixel_ray(job, x + k, y, od, dd);
            to_box_frame(job, od, dd, o, d);
            for (int a = 0; a < 3; a++) {
                L.o[a][k] = o[a];
                L.d[a][k] = d[a];
                L.V[a][k] = (float)-dd[a]; /* |dd| = 1 */
            }
        }
        for (int a = 0; a < 3; a++) {
            o[a] = L.o[a][k];
            d[a] = L.d[a][k];
        }
        if (!((want >> k) & 1))
            continue;
        if (hit4 >= 0) {
            if (!((hit4 >> k) & 1))
                continue;
            t_near = tn4[k];
            t_far = tf4[k];
        } else if (!intersect_box(job, o, d, &t_near, &t_far)) {
            continue;
        }
        long n = (long)ceilf((t_far - t_near) / job->step);
        L.n[k] = n < 1 ? 1 : (int)n;
        L.t_near[k] = t_near;
        L.t_far[k] = t_far;
        L.live[k] = 1;
        if (job->skip_flags || job->skip_minmax)
            grid_ray_of(job, o, d, t_near, &L.gr[k]);
    }
    __m128 C[3] = {_mm_setzero_ps(), _mm_setzero_ps(), _mm_setzero_ps()}, A = _mm_setzero_ps();
    if (job->blend == CDVR_BLEND_ISO) {
        lanes_iso_march(job, &L);
        uint64_t samples = 0;
        for (int k = 0; k < LANES; k++) {
            float *px = cdvr_image_pixel(job->img, x + k, y);
            px[0] = px[1] = px[2] = px[3] = 0.0f;
            if (L.hit[k]) {
                float o[3] = {L.o[0][k], L.o[1][k], L.o[2][k]};
                float d[3] = {L.d[0][k], L.d[1][k], L.d[2][k]};
                float V[3] = {L.V[0][k], L.V[1][k], L.V[2][k]};
                iso_hit(job, o, d, V, L.prev[k], L.t_prev[k], L.hit_s[k], L.hit_tm[k], px);
            }
            samples += L.taken[k];
        }
        return samples;
    }
    lanes_march(job, &L, C, &A);
    float out[4][LANES];
    for (int c = 0; c < 3; c++)
        _mm_storeu_ps(out[c], C[c]);
    _mm_storeu_ps(out[3], A);
    uint64_t samples = 0;
    unsigned again = 0; /* the lanes whose guess no sample reached */
    for (int k = 0; k < LANES; k++) {
        float *px = cdvr_image_pixel(job->img, x + k, y);
        if (!((want >> k) & 1))
            continue;
        if (guess && L.taken[k] && !L.reached[k]) {
            again |= 1u << k;
            continue;
        }
        if (job->blend == CDVR_BLEND_COMPOSITE)
            for (int c = 0; c < 4; c++)
                px[c] = out[c][k];
        else
            extreme_pixel(job, L.best[k], L.sum[k], L.taken[k], px);
        if (best_out)
            best_out[k] = L.taken[k] ? L.best[k] : NAN;
        samples += L.taken[k];
    }
    return again ? samples + render_lanes(job, x, y, NULL, best_out, again) : samples;
}
#endif

/* Max and min rays of a tile's rows after its first start from the extreme of the ray above
 * less (min: plus) this many codes (render_lanes). Engine CT and Colin27, max at 512^2, step
 * 0.5, 2 threads, 5 alternating rounds against no guess: margin 4: 0.76 / 0.93 of the time,
 * 8: 0.735 / 0.945, 16: 0.74 / 0.97 (a smaller margin jumps more bricks, a larger one
 * marches fewer rays twice). */
#define GUESS_MARGIN 8.0f

/* Pixels x0 .. x1 - 1 of row y: four at a time where four fit from x0 (a multiple of four)
 * and the march allows it, the others one at a time. above (NULL: none) holds the extremes
 * of row y - 1 from x0 (NaN: none), the guesses of max and min rays; row (NULL: not wanted)
 * gets those of row y. */
static uint64_t render_span(const render_job *job, int x0, int x1, int y, const float *above,
                            float *row)
{
    uint64_t samples = 0;
    int x = x0;
#ifdef __SSE2__
    for (; job->lanes && x + LANES <= x1; x += LANES) {
        float guess[LANES];
        for (int k = 0; above && k < LANES; k++) {
            float a = above[x - x0 + k]; /* a != a: NaN, no guess */
            guess[k] = job->blend == CDVR_BLEND_MIN ? (a == a ? a + GUESS_MARGIN : INFINITY)
                                                    : (a == a ? a - GUESS_MARGIN : -INFINITY);
        }
        samples += render_lanes(job, x, y, above ? guess : NULL, row ? row + (x - x0) : NULL,
                                (1u << LANES) - 1);
    }
#endif
    for (; x < x1; x++) {
        double od[3], dd[3];
        float o[3], d[3];
        pixel_ray(job, x, y, od, dd);
        to_box_frame(job, od, dd, o, d);
        float V[3] = {(float)-dd[0], (float)-dd[1], (float)-dd[2]}; /* |dd| = 1 */
        samples += march_ray(job, o, d, V, cdvr_image_pixel(job->img, x, y));
        if (row)
            row[x - x0] = NAN;
    }
    return samples;
}

/* The image is handed out in tiles of TILE_W x TILE_H pixels (TILE_W a multiple of four),
 * rows of tiles in turn: the rays of a tile run side by side through the same voxels, which
 * then stay in the cache from one ray to the next (a row of rays across the whole image
 * touches more voxels than the cache holds, and the next row fetches them again). */
#define TILE_W 16
#define TILE_H 8

static void *render_worker(void *arg)
{
    render_job *job = arg;
    uint64_t samples = 0;
    int w = job->img->width, h = job->img->height;
    int tiles_x = (w + TILE_W - 1) / TILE_W, tiles = tiles_x * ((h + TILE_H - 1) / TILE_H);
    int guessing = job->lanes && job->skip_minmax &&
                   (job->blend == CDVR_BLEND_MAX || job->blend == CDVR_BLEND_MIN);
    for (;;) {
        int t = atomic_fetch_add(&job->next_tile, 1);
        if (t >= tiles || (job->cancel && atomic_load(job->cancel)))
            break;
        int x0 = (t % tiles_x) * TILE_W, y0 = (t / tiles_x) * TILE_H;
        int x1 = x0 + TILE_W < w ? x0 + TILE_W : w, y1 = y0 + TILE_H < h ? y0 + TILE_H : h;
        float rows[2][TILE_W]; /* max, min: the extremes of the last row and of this one */
        for (int y = y0; y < y1; y++)
            samples += render_span(job, x0, x1, y, guessing && y > y0 ? rows[(y - 1) & 1] : NULL,
                                   guessing ? rows[y & 1] : NULL);
    }
    atomic_fetch_add(&job->samples, samples);
    return NULL;
}

static int thread_count(const cdvr_render_opts *opts, int tiles)
{
    long n = opts->threads > 0 ? opts->threads : sysconf(_SC_NPROCESSORS_ONLN);
    if (n < 1)
        n = 1;
    if (n > MAX_THREADS)
        n = MAX_THREADS;
    return n > tiles ? tiles : (int)n;
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

/* Blend mode, shading and gradient opacity of opts (checked) into the job. */
static void setup_look(render_job *job, const cdvr_render_opts *opts, const double D[9])
{
    const cdvr_look *look = &opts->look;
    const cdvr_shading *sh = &look->shade;
    const cdvr_tf *tf = opts->tf;
    job->blend = look->blend;
    job->shade = sh->enabled;
    job->ambient = (float)sh->ambient;
    job->diffuse = (float)sh->diffuse;
    job->specular = (float)sh->specular;
    job->power = (float)sh->specular_power;
    job->whole_power = job->power == floorf(job->power) &&
                               job->power <= (float)CDVR_SHADE_WHOLE_POWER_MAX
                           ? (int)job->power
                           : -1;
    job->headlight = !sh->light_fixed;
    double len = sqrt(sh->light_dir[0] * sh->light_dir[0] + sh->light_dir[1] * sh->light_dir[1] +
                      sh->light_dir[2] * sh->light_dir[2]);
    for (int a = 0; a < 3; a++)
        job->light[a] = len > 0.0 ? (float)(-sh->light_dir[a] / len) : 0.0f;
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            job->dir[3 * r + c] = (float)D[3 * r + c];
            job->grad_to_world[3 * r + c] = (float)job->inv_dir[3 * c + r]; /* (D^-1)^T */
        }
    job->value_per_code = (float)((tf->window[1] - tf->window[0]) / 255.0);
    job->go_points = (int)look->gradient_opacity.npoints;
    for (int i = 0; i < job->go_points; i++) {
        job->go_mag[i] = (float)look->gradient_opacity.magnitude[i];
        job->go_factor[i] = (float)look->gradient_opacity.factor[i];
    }
    double width = tf->window[1] - tf->window[0];
    job->iso_code = width > 0.0 ? (float)((look->iso_value - tf->window[0]) * 255.0 / width) : 0.0f;
    job->iso_tf_color = !look->iso_color_set;
    for (int c = 0; c < 3; c++)
        job->iso_rgb[c] = look->iso_color[c];
    job->iso_alpha = look->iso_opacity > 0.0 ? (float)look->iso_opacity : 1.0f;
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
        job->spacing[a] = (float)vol->spacing[a];
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
        job->code_value[i] = (float)i;
    for (int i = 0; i < 256; i++)
        job->alpha_step[i] = (float)(1.0 - pow(1.0 - opts->tf->table[i][3], step / unit));
    for (int i = 0; i < 256; i++) {
        for (int c = 0; c < 3; c++)
            job->rgb_alpha_step[i][c] = opts->tf->table[i][c];
        job->rgb_alpha_step[i][3] = job->alpha_step[i];
    }
    job->camera = opts->camera;
    cdvr_camera_frame_init(opts->camera, &job->cam_frame);
    double zero[3] = {0.0, 0.0, 0.0};
    float unused[3];
    to_box_frame(job, opts->camera->eye, zero, job->eye_box, unused);
    setup_look(job, opts, D);
    job->cancel = opts->cancel;
    job->img = img;
    atomic_init(&job->next_tile, 0);
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

/* Flags from the marked bricks: 128 where marked, else the distance to the nearest mark. */
static void reach_flags(cdvr_skip_grid *g, const uint8_t *visible)
{
    cdvr_skip_distance(visible, g->flags, g->dims);
    for (size_t b = 0; b < g->nbricks; b++) {
        int d = g->flags[b];
        g->flags[b] = (uint8_t)(visible[b] ? 128 : d > CDVR_SKIP_REACH_MAX ? CDVR_SKIP_REACH_MAX : d);
    }
}

/* The flags of cdvr/skip.h that the march reads: an invisible brick's code (its chessboard
 * distance to the nearest visible brick, at most CDVR_SKIP_REACH_MAX), and 128 for every
 * visible brick (the march never needs a visible brick's reach), which saves
 * cdvr_skip_flags's second distance transform. */
static void invisible_reach(cdvr_skip_grid *g, const cdvr_tf *tf)
{
    int prefix[257];
    prefix[0] = 0;
    for (int i = 0; i < 256; i++)
        prefix[i + 1] = prefix[i] + (tf->table[i][3] > 0.0f);
    uint8_t *visible = g->scratch;
    for (size_t b = 0; b < g->nbricks; b++) {
        int lo = g->minmax[2 * b], hi = g->minmax[2 * b + 1];
        visible[b] = lo <= hi && prefix[hi + 1] - prefix[lo] > 0;
    }
    reach_flags(g, visible);
}

/* The same flags with "visible" meaning that the brick's range holds iso code c (iso_jump). */
static void iso_flags(cdvr_skip_grid *g, float c)
{
    uint8_t *holds = g->scratch;
    for (size_t b = 0; b < g->nbricks; b++)
        holds[b] = (float)g->minmax[2 * b] <= c && c <= (float)g->minmax[2 * b + 1];
    reach_flags(g, holds);
}

/* Max, min and average: every brick's range widened to the cube of bricks within WIDE_REACH
 * of it (chessboard distance, bricks outside the grid left out): a ray whose extreme already
 * beats that range (average: a cube of zeros) jumps the whole cube (skip_target with code
 * WIDE_REACH + 1), as the composite march jumps an invisible cube, instead of one brick at a
 * time (WIDE_REACH: at the top of this file). */

/* out[2 b] = min, out[2 b + 1] = max of in over the bricks within WIDE_REACH of b along axis
 * a only (in and out distinct, both 2 per brick). */
static void widen_axis(const uint8_t *in, uint8_t *out, const size_t nb[3], int a)
{
    size_t stride = a == 0 ? 1 : a == 1 ? nb[0] : nb[0] * nb[1];
    size_t n = nb[a], lines = nb[0] * nb[1] * nb[2] / n;
    for (size_t l = 0; l < lines; l++) {
        /* the first brick of line l: l counts the other two axes, x before y before z */
        size_t first = a == 0 ? l * nb[0]
                     : a == 1 ? (l % nb[0]) + (l / nb[0]) * nb[0] * nb[1]
                              : l;
        for (size_t i = 0; i < n; i++) {
            size_t j0 = i >= WIDE_REACH ? i - WIDE_REACH : 0;
            size_t j1 = i + WIDE_REACH < n ? i + WIDE_REACH : n - 1;
            uint8_t lo = 255, hi = 0;
            for (size_t j = j0; j <= j1; j++) {
                const uint8_t *r = in + 2 * (first + j * stride);
                lo = r[0] < lo ? r[0] : lo;
                hi = r[1] > hi ? r[1] : hi;
            }
            uint8_t *o = out + 2 * (first + i * stride);
            o[0] = lo;
            o[1] = hi;
        }
    }
}

/* The widened ranges of grid g into out (2 per brick), with tmp (2 per brick) as scratch. */
static void wide_ranges(const cdvr_skip_grid *g, uint8_t *out, uint8_t *tmp)
{
    widen_axis(g->minmax, out, g->dims, 0);
    widen_axis(out, tmp, g->dims, 1);
    widen_axis(tmp, out, g->dims, 2);
}

/* What a skip grid's flags were made for: a composite TF's entries with alpha > 0, or an iso
 * code (the ranges are compared separately). */
typedef struct skip_key {
    int kind;                /* 0: none (flags not made), 1: composite, 2: iso */
    uint8_t tf_visible[256];
    float iso_code;
} skip_key;

struct cdvr_cpu_skip_cache {
    cdvr_skip_grid grid;     /* grid.minmax == NULL: nothing kept */
    skip_key key;
    int ranges_valid;        /* grid.minmax holds the ranges of the last render's frame */
    uint8_t *wide;           /* wide_ranges of grid.minmax (2 per brick), or NULL */
    int wide_valid;          /* wide was made from the ranges in grid.minmax */
    const cdvr_volume *held; /* cdvr_cpu_skip_cache_hold's volume, or NULL */
    cdvr_frame_stamp ranges_of; /* the held frame grid.minmax holds the ranges of, or none */
};

cdvr_status cdvr_cpu_skip_cache_create(cdvr_cpu_skip_cache **out, cdvr_error *err)
{
    *out = calloc(1, sizeof **out);
    if (!*out)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "render: no memory for the skip cache");
    return CDVR_OK;
}

void cdvr_cpu_skip_cache_hold(cdvr_cpu_skip_cache *c, const cdvr_volume *vol)
{
    if (!c || vol == c->held)
        return;
    c->held = vol; /* the one held before may be freed now, another allocated at its address */
    memset(&c->ranges_of, 0, sizeof c->ranges_of);
}

void cdvr_cpu_skip_cache_free(cdvr_cpu_skip_cache *c)
{
    if (!c)
        return;
    if (c->grid.minmax)
        cdvr_skip_grid_free(&c->grid);
    free(c->wide);
    free(c);
}

static skip_key key_of(const render_job *job, const cdvr_tf *tf)
{
    skip_key k;
    memset(&k, 0, sizeof k);
    if (job->blend == CDVR_BLEND_ISO) {
        k.kind = 2;
        k.iso_code = job->iso_code;
    } else {
        k.kind = 1;
        for (int i = 0; i < 256; i++)
            k.tf_visible[i] = tf->table[i][3] > 0.0f;
    }
    return k;
}

/* The cache's grid for a volume of dims with fresh brick ranges in grid->minmax; *same is 1
 * when they equal the ranges it held (its flags, when made, and its widened ranges, when
 * valid, were made from those: the flags are then valid for the same key); otherwise the
 * flags and widened ranges are marked stale. Returns NULL (no skipping) when out of memory. */
static cdvr_skip_grid *cached_ranges(cdvr_cpu_skip_cache *c, const render_job *job,
                                     const cdvr_volume *vol, int threads, int *same)
{
    cdvr_skip_grid *g = &c->grid;
    cdvr_error ignored;
    *same = 0;
    if (g->minmax && memcmp(g->vol_dims, vol->dims, sizeof g->vol_dims) != 0) {
        cdvr_skip_grid_free(g);
        memset(g, 0, sizeof *g);
        free(c->wide);
        c->wide = NULL;
        c->wide_valid = 0;
    }
    if (!g->minmax) {
        c->key.kind = 0;
        c->ranges_valid = 0;
        c->wide_valid = 0;
        if (cdvr_skip_grid_init(g, vol->dims, CDVR_RANGE_SHIFT, &ignored) != CDVR_OK) {
            memset(g, 0, sizeof *g);
            return NULL;
        }
    }
    /* a held volume's frame at the revision the ranges were made from: the same ranges */
    int held = vol == c->held;
    cdvr_frame_stamp now = {vol, job->voxels, vol->revision}; /* this render's frame */
    if (held && c->ranges_valid && cdvr_frame_stamp_same(c->ranges_of, now)) {
        *same = 1;
        return g;
    }
    memset(&c->ranges_of, 0, sizeof c->ranges_of);
    /* the new ranges into scratch (2 bytes per brick, as minmax), then compared */
    if (cdvr_cpu_brick_ranges(job->voxels, vol->dims, g->shift, threads, g->scratch,
                              &ignored) != CDVR_OK) {
        c->key.kind = 0;
        return NULL;
    }
    size_t bytes = 2 * g->nbricks;
    *same = c->ranges_valid && memcmp(g->scratch, g->minmax, bytes) == 0;
    c->ranges_valid = 1;
    if (held)
        c->ranges_of = now;
    if (!*same) {
        uint8_t *fresh = g->scratch;
        g->scratch = g->minmax;
        g->minmax = fresh;
        c->key.kind = 0;
        c->wide_valid = 0;
    }
    return g;
}

/* The widened ranges (wide_ranges) of grid: the cache's (made when its ranges changed), or
 * without a cache a new array in *own (free it); NULL (bricks jumped one at a time) when out
 * of memory. The grid's scratch is free here (it only ever holds what is made next). */
static const uint8_t *extreme_wide(cdvr_skip_grid *grid, cdvr_cpu_skip_cache *cache,
                                   uint8_t **own)
{
    if (!cache) {
        *own = malloc(2 * grid->nbricks);
        if (*own)
            wide_ranges(grid, *own, grid->scratch);
        return *own;
    }
    if (!cache->wide_valid) {
        if (!cache->wide)
            cache->wide = malloc(2 * grid->nbricks);
        if (!cache->wide)
            return NULL;
        wide_ranges(grid, cache->wide, grid->scratch);
        cache->wide_valid = 1;
    }
    return cache->wide;
}

/* Empty-space skipping for a composite render of a whole volume: the brick flags of its frame
 * under the TF (cdvr/skip.h, bricks of 2^CDVR_RANGE_SHIFT voxels) into the job, from cache
 * (its flags kept when the brick ranges and the key are those they were made for; the flags
 * depend on nothing else, so the image is the same bit for bit) or, when cache is NULL, a
 * grid made for this render in *own. Returns 1 when *own was made (free it), 0 otherwise;
 * the render takes every sample (job->skip_* NULL) when clipped, with opts->no_skip, or out
 * of memory (skipping is only a saving); max, min and average get the brick ranges (and
 * their widened ranges) only, iso the flags of iso_flags. Also chooses the four-lane march
 * unless opts->no_skip or clipped. */
static int skip_setup(render_job *job, const cdvr_volume *vol, const cdvr_render_opts *opts,
                      int threads, cdvr_cpu_skip_cache *cache, cdvr_skip_grid *own,
                      uint8_t **wide_own)
{
    job->skip_flags = NULL;
    job->skip_minmax = NULL;
    job->skip_wide = NULL;
    *wide_own = NULL;
    job->lanes = !opts->no_skip && !job->clipped;
    int extreme = job->blend == CDVR_BLEND_MAX || job->blend == CDVR_BLEND_MIN ||
                  job->blend == CDVR_BLEND_AVERAGE; /* the brick ranges (average: the lanes) */
    if (opts->no_skip || job->clipped ||
        (job->blend != CDVR_BLEND_COMPOSITE && job->blend != CDVR_BLEND_ISO && !extreme))
        return 0;
    cdvr_error ignored;
    cdvr_skip_grid *grid = own;
    int same = 0;
    if (cache) {
        grid = cached_ranges(cache, job, vol, threads, &same);
        if (!grid)
            return 0;
    } else {
        if (cdvr_skip_grid_init(grid, vol->dims, CDVR_RANGE_SHIFT, &ignored) != CDVR_OK)
            return 0;
        if (cdvr_cpu_brick_ranges(job->voxels, vol->dims, grid->shift, threads, grid->minmax,
                                  &ignored) != CDVR_OK) {
            cdvr_skip_grid_free(grid);
            return 0;
        }
    }
    job->skip_shift = (int)grid->shift;
    job->jump_inv_step = 1.0 / (double)job->step;
    job->jump_edge = (double)(1 << job->skip_shift);
    for (int a = 0; a < 3; a++) {
        job->skip_nb[a] = (int)grid->dims[a];
        /* the largest |face| of a cube of reach CDVR_SKIP_REACH_MAX, or more */
        job->jump_far[a] = ((double)job->skip_nb[a] + CDVR_SKIP_REACH_MAX + 2) * job->jump_edge;
    }
    if (extreme) {
        job->skip_minmax = grid->minmax;
        job->skip_wide = extreme_wide(grid, cache, wide_own);
        return cache == NULL;
    }
    skip_key key = key_of(job, opts->tf);
    if (!cache || !same || memcmp(&key, &cache->key, sizeof key) != 0) {
        if (job->blend == CDVR_BLEND_ISO)
            iso_flags(grid, job->iso_code);
        else
            invisible_reach(grid, opts->tf);
        if (cache)
            cache->key = key;
    }
    job->skip_flags = grid->flags;
    return cache == NULL;
}

cdvr_status cdvr_render_cpu(const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                            cdvr_image **out, cdvr_error *err)
{
    return cdvr_render_cpu_cached(vol, t, opts, NULL, out, err);
}

cdvr_status cdvr_render_cpu_cached(const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                                   cdvr_cpu_skip_cache *cache, cdvr_image **out, cdvr_error *err)
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
    if (st == CDVR_OK)
        st = cdvr_render_check_look(opts, err);
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
    cdvr_skip_grid grid;
    uint8_t *wide = NULL;
    int tiles = ((img->width + TILE_W - 1) / TILE_W) * ((img->height + TILE_H - 1) / TILE_H);
    int nthreads = thread_count(opts, tiles);
    int skipping = skip_setup(job, vol, opts, nthreads, cache, &grid, &wide);
    run_workers(job, nthreads);
    if (skipping)
        cdvr_skip_grid_free(&grid);
    free(wide);
    opts->samples = (uint64_t)atomic_load(&job->samples);
    free(job);
    if (opts->cancel && atomic_load(opts->cancel)) {
        cdvr_image_free(img);
        return cdvr_error_set(err, CDVR_ERR_CANCELLED, "render: interrupted");
    }
    *out = img;
    return CDVR_OK;
}
