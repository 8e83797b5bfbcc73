/* kernels/raycast.cl - ray casting as defined in core/include/cdvr/render.h, in float:
 * slab test, segments of length `step` from t_near with a partial last one, midpoint
 * samples, trilinear interpolation, post-classification with the step-corrected table,
 * front-to-back compositing and early termination. Empty-space skipping jumps over bricks
 * flagged invisible while staying on the t_near + i*step segment grid, so skipped segments
 * are exactly those whose samples would have had zero opacity. */

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

static float voxel(__global const uchar *vol, int x, int y, int z, int X, int Y)
{
    return (float)vol[(ulong)x + (ulong)X * ((ulong)y + (ulong)Y * (ulong)z)];
}

static float trilinear(__global const uchar *vol, float3 g, int X, int Y, int Z)
{
    int x0 = (int)g.x, y0 = (int)g.y, z0 = (int)g.z;
    int x1 = min(x0 + 1, X - 1), y1 = min(y0 + 1, Y - 1), z1 = min(z0 + 1, Z - 1);
    float fx = g.x - (float)x0, fy = g.y - (float)y0, fz = g.z - (float)z0;
    float c00 = mix(voxel(vol, x0, y0, z0, X, Y), voxel(vol, x1, y0, z0, X, Y), fx);
    float c10 = mix(voxel(vol, x0, y1, z0, X, Y), voxel(vol, x1, y1, z0, X, Y), fx);
    float c01 = mix(voxel(vol, x0, y0, z1, X, Y), voxel(vol, x1, y0, z1, X, Y), fx);
    float c11 = mix(voxel(vol, x0, y1, z1, X, Y), voxel(vol, x1, y1, z1, X, Y), fx);
    return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
}

/* Ray parameter where the grid-space ray g0 + t*gd leaves the box [lo, lo + B) of a brick. */
static float brick_exit(float3 g0, float3 gd, float3 lo, float B)
{
    float t = INFINITY;
    if (gd.x > 0.0f) t = fmin(t, (lo.x + B - g0.x) / gd.x);
    if (gd.x < 0.0f) t = fmin(t, (lo.x - g0.x) / gd.x);
    if (gd.y > 0.0f) t = fmin(t, (lo.y + B - g0.y) / gd.y);
    if (gd.y < 0.0f) t = fmin(t, (lo.y - g0.y) / gd.y);
    if (gd.z > 0.0f) t = fmin(t, (lo.z + B - g0.z) / gd.z);
    if (gd.z < 0.0f) t = fmin(t, (lo.z - g0.z) / gd.z);
    return t;
}

typedef struct cam_params {
    float eye[3], f[3], u[3], r[3];
    float tan_half, aspect, ortho_half_height;
    int orthographic, width, height;
} cam_params;

/* Geometry as render_cpu.c holds it: origin, 1/spacing and the box's upper corner (computed
 * in double on the host). Bricks: edge B, counts nbx, nby, nbz, skipping on/off. */
__kernel void raycast(__global const uchar *frames, ulong offset, int X, int Y, int Z,
                      float ox, float oy, float oz, float isx, float isy, float isz,
                      float hx, float hy, float hz,
                      float step, float term_alpha, cam_params cam,
                      __global const float4 *table, __global const float *alpha_corrected,
                      float unit, __global const uchar *brick_visible, int B,
                      int nbx, int nby, int nbz, int skipping, __global float4 *image,
                      __global uint *samples)
{
    int px = get_global_id(0), py = get_global_id(1);
    if (px >= cam.width || py >= cam.height)
        return;
    __global const uchar *vol = frames + offset;
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
    float3 dims_m1 = (float3)((float)(X - 1), (float)(Y - 1), (float)(Z - 1));
    float4 acc = (float4)(0.0f);
    uint taken = 0;
    ray_box box;
    if (intersect_box(o, d, origin, (float3)(hx, hy, hz), &box)) {
        float L = box.t_far - box.t_near;
        int n = max((int)ceil(L / step), 1);
        float3 g0 = (o - origin) * inv_spacing, gd = d * inv_spacing;
        for (int i = 0; i < n; i++) {
            float ts = box.t_near + (float)i * step;
            float ds = i < n - 1 ? step : box.t_far - ts;
            if (ds <= 0.0f)
                break;
            float3 p = o + (ts + 0.5f * ds) * d;
            float3 g = clamp((p - origin) * inv_spacing, (float3)(0.0f), dims_m1);
            if (skipping) {
                int bx = min((int)g.x / B, nbx - 1), by = min((int)g.y / B, nby - 1);
                int bz = min((int)g.z / B, nbz - 1);
                if (!brick_visible[bx + nbx * (by + nby * bz)]) {
                    float3 lo = (float3)((float)(bx * B), (float)(by * B), (float)(bz * B));
                    float te = brick_exit(g0, gd, lo, (float)B);
                    /* first segment whose midpoint may lie past the brick, one early for
                     * rounding safety; never backwards */
                    float next = ceil((te - box.t_near) / step - 0.5f) - 1.0f;
                    if (next > (float)(i + 1))
                        i = (int)fmin(next, (float)n) - 1;
                    continue;
                }
            }
            float s = trilinear(vol, g, X, Y, Z);
            int i0 = min((int)s, 254);
            float fr = s - (float)i0;
            float4 c = mix(table[i0], table[i0 + 1], fr);
            float a;
            if (ds >= step)
                a = mix(alpha_corrected[i0], alpha_corrected[i0 + 1], fr);
            else
                a = 1.0f - pow(1.0f - c.w, ds / unit);
            taken++;
            if (a > 0.0f) {
                float w = (1.0f - acc.w) * a;
                acc.xyz += w * c.xyz;
                acc.w += w;
                if (acc.w >= term_alpha || acc.w >= 1.0f)
                    break;
            }
        }
    }
    image[py * cam.width + px] = acc;
    samples[py * cam.width + px] = taken;
}
