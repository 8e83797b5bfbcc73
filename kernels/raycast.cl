/* kernels/raycast.cl - ray casting as defined in core/include/cdvr/render.h, in float:
 * slab test, segments of length `step` from t_near with a partial last one, midpoint
 * samples, trilinear interpolation, post-classification with the step-corrected table,
 * front-to-back compositing and early termination.
 *
 * For speed the ray is carried in grid (voxel) coordinates: sample i of the full segments
 * sits at g0 + i*dg, so a sample costs one multiply-add per axis, an integer base index with
 * clamped increments, eight byte loads and one float4 table pair. Empty-space skipping walks
 * the brick grid: for the brick holding the current sample it computes, in sample units, where
 * the ray leaves the brick; an invisible brick is jumped over in one step (conservatively, so
 * a skipped sample is always inside it), a visible brick's samples run in a tight inner loop.
 * Skipped samples are exactly those whose value range has zero opacity under the TF. */

typedef struct ray_box {
    float t_near, t_far;
} ray_box;

static int intersect_box(float3 o, float3 d, float3 lo, float3 hi, ray_box *out)
{
    float t_enter = -INFINITY, t_exit = INFINITY;
    float oa[3] = {o.x, o.y, o.z}, da[3] = {d.x, d.y, d.z};
    float la[3] = {lo.x, lo.y, lo.z}, ha[3] = {hi.x, hi.y, hi.z};
    for (int a = 0; a < 3; a++) {
        if (fabs(da[a]) < 1e-12f) {
            if (oa[a] < la[a] || oa[a] > ha[a])
                return 0;
            continue;
        }
        float t0 = (la[a] - oa[a]) / da[a], t1 = (ha[a] - oa[a]) / da[a];
        t_enter = fmax(t_enter, fmin(t0, t1));
        t_exit = fmin(t_exit, fmax(t0, t1));
    }
    out->t_near = fmax(t_enter, 0.0f);
    out->t_far = t_exit;
    return out->t_far > out->t_near;
}

typedef struct volume_geo {
    __global const uchar *vol;
    int X, Y, Z;
    long XY;
    float3 top; /* dims - 1 */
} volume_geo;

/* render.h step 3 at grid position g (clamped here): trilinear, upper index clamped. */
static float trilinear(const volume_geo *v, float3 g)
{
    g = clamp(g, (float3)(0.0f), v->top);
    int x0 = (int)g.x, y0 = (int)g.y, z0 = (int)g.z;
    float fx = g.x - (float)x0, fy = g.y - (float)y0, fz = g.z - (float)z0;
    long base = (long)x0 + (long)v->X * (long)y0 + v->XY * (long)z0;
    long dx = x0 < v->X - 1 ? 1 : 0;
    long dy = y0 < v->Y - 1 ? (long)v->X : 0;
    long dz = z0 < v->Z - 1 ? v->XY : 0;
    __global const uchar *p = v->vol + base;
    float c00 = mix((float)p[0], (float)p[dx], fx);
    float c10 = mix((float)p[dy], (float)p[dy + dx], fx);
    float c01 = mix((float)p[dz], (float)p[dz + dx], fx);
    float c11 = mix((float)p[dz + dy], (float)p[dz + dy + dx], fx);
    return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
}

/* Front-to-back compositing of one classified sample; returns 1 once the ray is done. */
static int composite(float4 *acc, float3 rgb, float a, float term_alpha)
{
    float w = (1.0f - acc->w) * a;
    acc->xyz += w * rgb;
    acc->w += w;
    return acc->w >= term_alpha || acc->w >= 1.0f;
}

/* Full segment: table holds rgb and the step-corrected alpha per entry. Compositing a zero
 * alpha changes nothing, so it is done unconditionally (no unpredictable branch). */
static int sample_full(const volume_geo *v, float3 g, __global const float4 *table,
                       float term_alpha, float4 *acc)
{
    float s = trilinear(v, g);
    int i0 = min((int)s, 254);
    float fr = s - (float)i0;
    float4 lo = table[i0], hi = table[i0 + 1];
    float4 c = mix(lo, hi, fr);
    float w = (1.0f - acc->w) * c.w;
    *acc += w * (float4)(c.xyz, 1.0f);
    return acc->w >= term_alpha || acc->w >= 1.0f;
}

typedef struct cam_params {
    float eye[3], f[3], u[3], r[3];
    float tan_half, aspect, ortho_half_height;
    int orthographic, width, height;
} cam_params;

typedef struct bricks {
    __global const uchar *dist; /* per brick: d if invisible, 128 + d if visible (see host) */
    int shift, nbx, nby, nbz;   /* brick edge 1 << shift */
    float3 inv_dg;              /* 1 / dg per axis, +inf where dg is 0 */
    int3 forward;               /* -1 (true) where dg >= 0: the ray leaves by the upper face */
} bricks;

/* Sample-index parameter where the ray g0 + i*dg leaves the cube of like bricks around the
 * brick holding grid point g (clamped): code d (invisible) or 128 + d (visible, *visible = 1)
 * from the host says that all bricks within chessboard distance d - 1 share its state. */
static float brick_exit(const bricks *b, const volume_geo *v, float3 g0, float3 g, int *visible)
{
    g = clamp(g, (float3)(0.0f), v->top);
    int bx = min((int)g.x >> b->shift, b->nbx - 1), by = min((int)g.y >> b->shift, b->nby - 1);
    int bz = min((int)g.z >> b->shift, b->nbz - 1);
    int code = b->dist[bx + b->nbx * (by + b->nby * bz)];
    *visible = code >= 128;
    int3 reach = (int3)(max(code & 127, 1) - 1); /* bricks on each side that are alike */
    int3 up = (int3)(bx, by, bz) + reach + (int3)(1), down = (int3)(bx, by, bz) - reach;
    int3 face = select(down, up, b->forward);
    float3 t = (convert_float3(face << b->shift) - g0) * b->inv_dg;
    return fmin(t.x, fmin(t.y, t.z));
}

/* Tolerance (in samples) that keeps a skip short of the computed brick exit, so rounding
 * never skips a sample that lies past the brick's face. */
#define SKIP_MARGIN 0.01f

/* Marches the n_full full segments from index 0; returns 1 if the ray terminated early. */
static int march_full(const volume_geo *v, const bricks *b, int skipping, float3 g0,
                      float3 dg, int n_full, __global const float4 *table, float term_alpha,
                      float4 *acc, uint *taken)
{
    int i = 0;
    while (i < n_full) {
        int end = n_full;
        if (skipping) {
            int visible;
            float t_exit = brick_exit(b, v, g0, g0 + (float)i * dg, &visible);
            t_exit = fmin(t_exit, (float)n_full);
            if (!visible) {
                i = max(i + 1, (int)ceil(t_exit - SKIP_MARGIN));
                continue;
            }
            end = clamp((int)ceil(t_exit), i + 1, n_full);
        }
        for (; i < end; i++) {
            (*taken)++;
            if (sample_full(v, g0 + (float)i * dg, table, term_alpha, acc))
                return 1;
        }
    }
    return 0;
}

/* Geometry as render_cpu.c holds it: origin, 1/spacing and the box's upper corner (computed
 * in double on the host). table: rgb + step-corrected alpha; alpha: alpha per unit (for the
 * shorter last segment). Bricks: edge 1 << brick_shift, counts nbx, nby, nbz, skipping on/off. */
__kernel void raycast(__global const uchar *frames, ulong offset, int X, int Y, int Z,
                      float ox, float oy, float oz, float isx, float isy, float isz,
                      float hx, float hy, float hz,
                      float step, float term_alpha, cam_params cam,
                      __global const float4 *table, __global const float *alpha,
                      float unit, __global const uchar *brick_visible, int brick_shift,
                      int nbx, int nby, int nbz, int skipping, __global float4 *image,
                      __global uint *samples)
{
    int px = get_global_id(0), py = get_global_id(1);
    if (px >= cam.width || py >= cam.height)
        return;
    float3 eye = (float3)(cam.eye[0], cam.eye[1], cam.eye[2]);
    float3 f = (float3)(cam.f[0], cam.f[1], cam.f[2]);
    float3 u = (float3)(cam.u[0], cam.u[1], cam.u[2]);
    float3 r = (float3)(cam.r[0], cam.r[1], cam.r[2]);
    float sxn = 2.0f * ((float)px + 0.5f) / (float)cam.width - 1.0f;
    float syn = 2.0f * ((float)py + 0.5f) / (float)cam.height - 1.0f;
    float3 o, d;
    if (cam.orthographic) {
        o = eye + (sxn * cam.aspect * r - syn * u) * cam.ortho_half_height;
        d = f;
    } else {
        o = eye;
        d = normalize(f + (sxn * cam.aspect * r - syn * u) * cam.tan_half);
    }
    float3 origin = (float3)(ox, oy, oz), inv_spacing = (float3)(isx, isy, isz);
    volume_geo v = {frames + offset, X, Y, Z, (long)X * (long)Y,
                    (float3)((float)(X - 1), (float)(Y - 1), (float)(Z - 1))};
    float4 acc = (float4)(0.0f);
    uint taken = 0;
    ray_box box;
    if (intersect_box(o, d, origin, (float3)(hx, hy, hz), &box)) {
        float L = box.t_far - box.t_near;
        int n = max((int)ceil(L / step), 1);
        float3 g0 = (o + (box.t_near + 0.5f * step) * d - origin) * inv_spacing;
        float3 dg = d * step * inv_spacing;
        bricks b = {brick_visible, brick_shift, nbx, nby, nbz,
                    (float3)(dg.x != 0.0f ? 1.0f / dg.x : INFINITY,
                             dg.y != 0.0f ? 1.0f / dg.y : INFINITY,
                             dg.z != 0.0f ? 1.0f / dg.z : INFINITY),
                    dg >= (float3)(0.0f)};
        int done = march_full(&v, &b, skipping, g0, dg, n - 1, table, term_alpha, &acc, &taken);
        /* the last segment, shorter than step unless L is a multiple of it */
        float ts = box.t_near + (float)(n - 1) * step;
        float ds = box.t_far - ts;
        if (!done && ds > 0.0f) {
            taken++;
            float s = trilinear(&v, (o + (ts + 0.5f * ds) * d - origin) * inv_spacing);
            int i0 = min((int)s, 254);
            float fr = s - (float)i0;
            float4 lo = table[i0], hi = table[i0 + 1];
            float a = mix(alpha[i0], alpha[i0 + 1], fr);
            /* pow is costly on CPU devices and most last segments lie in empty space, where
             * 1 - pow(1, x) is exactly 0 anyway */
            if (ds >= step)
                a = mix(lo.w, hi.w, fr);
            else if (a > 0.0f)
                a = 1.0f - pow(1.0f - a, ds / unit);
            if (a > 0.0f)
                composite(&acc, mix(lo.xyz, hi.xyz, fr), a, term_alpha);
        }
    }
    image[py * cam.width + px] = acc;
    samples[py * cam.width + px] = taken;
}
