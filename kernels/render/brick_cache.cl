/* kernels/render/brick_cache.cl - the brick cache's fetch (cdvr/brick_cache.h): the ray caster
 * reads every voxel through the page table of the cache's payload. Bit-exact with
 * cdvr_brick_cache_fetch (core/render/cache/brick_cache.c), which it mirrors; every read is
 * clamped inside the payload's n bytes (bytes 48..55 of the params buffer, cdvr/codec.h).
 * Integer arithmetic only. */

#ifndef CDVR_CL_PARAMS_BYTES
#define CDVR_CL_PARAMS_BYTES 48
#endif

static ulong bc_payload_bytes(__constant uchar *params)
{
    ulong v = 0;
    for (int i = 0; i < 8; i++)
        v |= (ulong)params[CDVR_CL_PARAMS_BYTES + i] << (8 * i);
    return v;
}

static uint bc_word(__global const uchar *p, ulong n, ulong at)
{
    at = min(at, n - 4);
    return (uint)p[at] | ((uint)p[at + 1] << 8) | ((uint)p[at + 2] << 16) |
           ((uint)p[at + 3] << 24);
}

static uint bc_coord(uint x, uint lvl, uint lo, uint d)
{
    long c = (long)(x >> lvl) - (long)lo;
    return (uint)clamp(c, 0L, (long)d - 1);
}

uchar brick_cache_fetch(__global const uchar *p, __constant uchar *params, int4 dims, int x,
                        int y, int z)
{
    ulong n = bc_payload_bytes(params);
    if (n < 64)
        return 0;
    ulong X = (ulong)dims.x, Y = (ulong)dims.y;
    uint bx = bc_word(p, n, 4), by = bc_word(p, n, 8);
    ulong pool = bc_word(p, n, 16), table = bc_word(p, n, 20);
    ulong bi = bc_word(p, n, 24 + 4 * (ulong)x);
    ulong bj = bc_word(p, n, 24 + 4 * (X + (ulong)y));
    ulong bk = bc_word(p, n, 24 + 4 * (X + Y + (ulong)z));
    ulong e = table + 32 * (bi + (ulong)bx * (bj + (ulong)by * bk));
    ulong base = pool + bc_word(p, n, e);
    uint lvl = min(bc_word(p, n, e + 4), 15u);
    uint lo0 = bc_word(p, n, e + 8), lo1 = bc_word(p, n, e + 12), lo2 = bc_word(p, n, e + 16);
    uint d0 = max(bc_word(p, n, e + 20), 1u), d1 = max(bc_word(p, n, e + 24), 1u);
    uint d2 = max(bc_word(p, n, e + 28), 1u);
    uint cx = bc_coord((uint)x, lvl, lo0, d0), cy = bc_coord((uint)y, lvl, lo1, d1);
    uint cz = bc_coord((uint)z, lvl, lo2, d2);
    if (lvl == 0)
        return p[min(base + cx + (ulong)d0 * (cy + (ulong)d1 * cz), n - 1)];
    uint mask = (1u << lvl) - 1u, s = 1u << lvl;
    uint fx = (uint)x & mask, fy = (uint)y & mask, fz = (uint)z & mask;
    uint cx1 = min(cx + 1, d0 - 1), cy1 = min(cy + 1, d1 - 1), cz1 = min(cz + 1, d2 - 1);
    ulong wx[2] = {s - fx, fx}, wy[2] = {s - fy, fy}, wz[2] = {s - fz, fz};
    uint xs[2] = {cx, cx1}, ys[2] = {cy, cy1}, zs[2] = {cz, cz1};
    ulong sum = 0;
    for (int k = 0; k < 2; k++)
        for (int j = 0; j < 2; j++)
            for (int i = 0; i < 2; i++) {
                ulong at = base + xs[i] + (ulong)d0 * (ys[j] + (ulong)d1 * zs[k]);
                sum += wx[i] * wy[j] * wz[k] * (ulong)p[min(at, n - 1)];
            }
    uint shift = 3 * lvl;
    return (uchar)((sum + (1ul << (shift - 1))) >> shift);
}
