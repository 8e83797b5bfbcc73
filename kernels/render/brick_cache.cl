/* kernels/render/brick_cache.cl - the brick cache's fetch (cdvr/brick_cache.h): the ray caster
 * reads every voxel through the page table of the cache's payload. Bit-exact with
 * cdvr_brick_cache_fetch (core/render/cache/brick_cache.c), which it mirrors; every read is
 * clamped inside the payload's n bytes (bytes 48..55 of the params buffer, cdvr/codec.h).
 * Integer arithmetic only. Defining CDVR_BRICK_CACHE makes raycast.cl (built after this
 * file) compile the brick march, which reads the page table through bc_entry below. */

#define CDVR_BRICK_CACHE 1
#define BC_HEADER_WORDS 8 /* cdvr/brick_cache.h: CDVR_BRICK_CACHE_HEADER_WORDS */
#define BC_ENTRY_WORDS 16 /* CDVR_BRICK_CACHE_ENTRY_WORDS */
#define BC_MIN_BYTES (4 * (BC_HEADER_WORDS + BC_ENTRY_WORDS))

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

static uint bc_coord(uint x, uint lvl, uint lo, uint d)
{
    long c = (long)(x >> lvl) - (long)lo;
    return (uint)clamp(c, 0L, (long)d - 1);
}

/* The payload is read as little-endian 32-bit words (every device cdvr runs on is little
 * endian; buffers are aligned); word indices are clamped below the payload's n / 4 words. */
uchar brick_cache_fetch(__global const uchar *p, __constant uchar *params, int4 dims, int x,
                        int y, int z)
{
    ulong n = bc_payload_bytes(params);
    if (n < BC_MIN_BYTES)
        return 0;
    __global const uint *w = (__global const uint *)p;
    ulong nw = n >> 2, X = (ulong)dims.x, Y = (ulong)dims.y, o = BC_HEADER_WORDS;
    ulong bi = w[min(o + (ulong)x, nw - 1)], bj = w[min(o + X + (ulong)y, nw - 1)];
    ulong bk = w[min(o + X + Y + (ulong)z, nw - 1)];
    ulong e = min((ulong)(w[5] >> 2) +
                      BC_ENTRY_WORDS * (bi + (ulong)w[1] * (bj + (ulong)w[2] * bk)),
                  nw - BC_ENTRY_WORDS);
    __global const uint *t = w + e;
    ulong base = (ulong)w[4] + t[0];
    uint lvl = min(t[1], 15u);
    uint d0 = max(t[5], 1u), d1 = max(t[6], 1u), d2 = max(t[7], 1u);
    uint cx = bc_coord((uint)x, lvl, t[2], d0), cy = bc_coord((uint)y, lvl, t[3], d1);
    uint cz = bc_coord((uint)z, lvl, t[4], d2);
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

/* The march's look-up: the page-table entry (its first word) of the level-0 brick that owns
 * voxel (x, y, z), clamped inside the payload like the fetch; the caller reads its 16 words. */
__global const uint *bc_entry(__global const uchar *p, __constant uchar *params, int4 dims,
                              int x, int y, int z)
{
    ulong n = max(bc_payload_bytes(params), (ulong)BC_MIN_BYTES);
    __global const uint *w = (__global const uint *)p;
    ulong nw = n >> 2, X = (ulong)dims.x, Y = (ulong)dims.y, o = BC_HEADER_WORDS;
    ulong bi = w[min(o + (ulong)x, nw - 1)], bj = w[min(o + X + (ulong)y, nw - 1)];
    ulong bk = w[min(o + X + Y + (ulong)z, nw - 1)];
    return w + min((ulong)(w[5] >> 2) +
                       BC_ENTRY_WORDS * (bi + (ulong)w[1] * (bj + (ulong)w[2] * bk)),
                   nw - BC_ENTRY_WORDS);
}
