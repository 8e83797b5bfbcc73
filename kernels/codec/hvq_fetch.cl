/* kernels/codec/hvq_fetch.cl - per-sample fetch of the hvq codec (cdvr/hvq.h, DESIGN.md 4.3):
 * the ray caster reads every voxel through hvq_fetch, straight from the payload (block means,
 * codebooks, perfect spatial hashes) - no dense volume on the device. Bit-exact with
 * cdvr_hvq_fetch / cdvr_hvq_decode (core/codec/hvq/hvq_decode.c), which it mirrors, for every
 * payload that passes cdvr_hvq_check (the host runs it before a chunk reaches the device:
 * the codec's check hook). Whatever the payload holds, no read leaves it: every offset
 * computed from payload bytes (directory entry, hash offset entry and slot, block mean,
 * codebook entries) goes through hvq_at, which keeps the read inside the payload's n bytes
 * (n: bytes 48..55 of the params buffer, cdvr/codec.h); the fixed header is read only when
 * n >= 32; a hash with a side of 0 is a miss (no division by 0). For a valid payload every
 * read already lies inside, so the clamps change nothing. Integer arithmetic only. */

#ifndef CDVR_CL_PARAMS_BYTES /* kernels/common/cl_shared.h, when built without it */
#define CDVR_CL_PARAMS_BYTES 48
#endif

/* Where a read of k bytes at offset `at` of the payload of n bytes (n >= k) may start: at
 * itself when the read lies inside, else the last k bytes. */
static ulong hvq_at(ulong n, ulong at, uint k)
{
    return min(at, n - k);
}

static uint hvq_rd16(__global const uchar *p)
{
    return (uint)p[0] | ((uint)p[1] << 8);
}

static uint hvq_rd32(__global const uchar *p)
{
    return (uint)p[0] | ((uint)p[1] << 8) | ((uint)p[2] << 16) | ((uint)p[3] << 24);
}

static ulong hvq_rd64(__global const uchar *p)
{
    return (ulong)hvq_rd32(p) | ((ulong)hvq_rd32(p + 4) << 32);
}

static int hvq_rds16(__global const uchar *p)
{
    return (int)(short)(ushort)hvq_rd16(p);
}

/* The payload's size, from the params buffer (little-endian u64 at byte 48). */
static ulong hvq_payload_bytes(__constant uchar *params)
{
#ifdef __ENDIAN_LITTLE__
    return ((__constant ulong *)params)[CDVR_CL_PARAMS_BYTES / 8]; /* 8-byte aligned */
#else
    ulong v = 0;
    for (int i = 0; i < 8; i++)
        v |= (ulong)params[CDVR_CL_PARAMS_BYTES + i] << (8 * i);
    return v;
#endif
}

/* The value bytes of key (kx, ky, kz) in the hash whose data starts at offset data (sides
 * m, r), or 0 when it is absent. H(p) = (h0(p) + Phi[h1(p)]) mod m, h0 = p mod m,
 * h1 = p mod r. The offset entry and the slot are read where hvq_at puts them. */
static __global const uchar *hvq_find(__global const uchar *p, ulong n, ulong data, uint m,
                                      uint r, uint slot_bytes, uint kx, uint ky, uint kz)
{
    if (m == 0 || r == 0)
        return 0;
    uint w = m > 256u ? 2u : 1u;
    ulong e = kx % r + (ulong)r * (ky % r + (ulong)r * (kz % r));
    __global const uchar *o = p + hvq_at(n, data + e * 3u * w, 3u * w);
    uint ox = w == 1u ? o[0] : hvq_rd16(o);
    uint oy = w == 1u ? o[w] : hvq_rd16(o + w);
    uint oz = w == 1u ? o[2u * w] : hvq_rd16(o + 2u * w);
    ulong sx = (kx % m + ox) % m, sy = (ky % m + oy) % m, sz = (kz % m + oz) % m;
    ulong s = sx + m * (sy + (ulong)m * sz);
    __global const uchar *slot =
        p + hvq_at(n, data + (ulong)r * r * r * 3u * w + s * slot_bytes, slot_bytes);
    return (slot[0] == kx && slot[1] == ky && slot[2] == kz) ? slot + 3 : 0;
}

static uint hvq_index(__global const uchar *p, uint w)
{
    return w == 1u ? (uint)p[0] : hvq_rd16(p);
}

/* dims = (X, Y, Z, frame); hvq chunks hold one frame. params: the chunk's parameter blob
 * (not needed: the payload describes itself) and the payload's size n. A payload shorter
 * than its header (which no check passes) reads as 0. */
uchar hvq_fetch(__global const uchar *payload, __constant uchar *params, int4 dims, int x,
                int y, int z)
{
    ulong n = hvq_payload_bytes(params);
    if (n < 32)
        return 0;
    __global const uchar *p = payload;
    ulong X = (ulong)dims.x, Y = (ulong)dims.y, Z = (ulong)dims.z;
    uint n1 = hvq_rd32(p + 16), n2 = hvq_rd32(p + 20);
    uint w1 = n1 > 256u ? 2u : 1u, w2 = n2 > 256u ? 2u : 1u;
    ulong nbx = (X + 3) >> 2, nby = (Y + 3) >> 2, nbz = (Z + 3) >> 2;
    ulong nrx = (X + 255) >> 8, nry = (Y + 255) >> 8;
    ulong off_c1 = (32 + nbx * nby * nbz + 7) & ~(ulong)7;
    ulong off_c2 = off_c1 + 16 * (ulong)n1;
    ulong off_dir = (off_c2 + 128 * (ulong)n2 + 7) & ~(ulong)7;
    uint ux = (uint)x, uy = (uint)y, uz = (uint)z;
    ulong region = (ux >> 8) + nrx * ((uy >> 8) + nry * (ulong)(uz >> 8));
    __global const uchar *dir = p + hvq_at(n, off_dir + 32 * region, 32);

    __global const uchar *hit = hvq_find(p, n, hvq_rd64(dir + 24), hvq_rd16(dir + 16),
                                         hvq_rd16(dir + 18), 4u, ux & 255u, uy & 255u,
                                         uz & 255u);
    if (hit)
        return hit[0];
    ulong bx = ux >> 2, by = uy >> 2, bz = uz >> 2;
    int val = p[hvq_at(n, 32 + bx + nbx * (by + nby * bz), 1)];
    hit = hvq_find(p, n, hvq_rd64(dir + 8), hvq_rd16(dir), hvq_rd16(dir + 2), 3u + w1 + w2,
                   (uint)(bx & 63), (uint)(by & 63), (uint)(bz & 63));
    if (!hit)
        return (uchar)val;
    uint o8 = ((ux & 3u) >> 1) + 2u * ((uy & 3u) >> 1) + 4u * ((uz & 3u) >> 1);
    uint o64 = (ux & 3u) + 4u * (uy & 3u) + 16u * (uz & 3u);
    val += hvq_rds16(p + hvq_at(n, off_c1 + 16 * (ulong)hvq_index(hit, w1) + 2 * o8, 2));
    val += hvq_rds16(p + hvq_at(n, off_c2 + 128 * (ulong)hvq_index(hit + w1, w2) + 2 * o64, 2));
    return (uchar)clamp(val, 0, 255);
}
