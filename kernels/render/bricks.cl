/* kernels/render/bricks.cl - the brick min/max grid for empty-space skipping. One work-item per
 * brick of B^3 voxels: min and max over the brick plus the one-voxel upper apron that
 * trilinear interpolation reads (voxels B*b .. B*b + B, clamped to the volume). The host
 * turns the grid into per-brick visibility flags for each transfer function.
 * frames/params/offset as in raycast.cl: a dense frame at frames + offset, or with
 * -DCDVR_FETCH the chunk payload, its parameter blob and the frame within the chunk. */
__kernel void brick_minmax(__global const uchar *frames, __constant uchar *params, ulong offset,
                           uint X, uint Y, uint Z, uint B, uint nbx, uint nby, uint nbz,
                           __global uchar2 *minmax)
{
    uint b = get_global_id(0);
#ifndef CDVR_FETCH
    __global const uchar *frame = frames + offset;
#endif
    if (b >= nbx * nby * nbz)
        return;
    uint x0 = (b % nbx) * B, y0 = ((b / nbx) % nby) * B, z0 = (b / (nbx * nby)) * B;
    uint x1 = min(x0 + B, X - 1), y1 = min(y0 + B, Y - 1), z1 = min(z0 + B, Z - 1);
    uint lo = 255, hi = 0;
    for (uint z = z0; z <= z1; z++)
        for (uint y = y0; y <= y1; y++) {
#ifdef CDVR_FETCH
            int4 dims = (int4)((int)X, (int)Y, (int)Z, (int)offset);
#else
            __global const uchar *row = frame + (ulong)X * ((ulong)Y * z + y);
#endif
            for (uint x = x0; x <= x1; x++) {
#ifdef CDVR_FETCH
                uint v = CDVR_FETCH(frames, params, dims, (int)x, (int)y, (int)z);
#else
                uint v = row[x];
#endif
                lo = min(lo, v);
                hi = max(hi, v);
            }
        }
    minmax[b] = (uchar2)((uchar)lo, (uchar)hi);
}

/* The tiled copy of a dense frame for the ray caster (kernels/common/cl_shared.h): one
 * work-item per tile row (a 32-bit word, low byte first), rows = pages * 1024; voxels past the
 * frame's edge repeat its last one. */
__kernel void make_tiles(__global const uchar *frames, ulong offset, uint X, uint Y, uint Z,
                         __global uint *tiles)
{
    size_t i = get_global_id(0);
    const uint edge = CDVR_CL_PAGE_EDGE;
    uint px = (X + edge - 1) / edge, py = (Y + edge - 1) / edge, pz = (Z + edge - 1) / edge;
    if (i >= (size_t)px * py * pz * 1024)
        return;
    size_t page = i >> 10;
    uint within = (uint)i & 1023u, tile = within >> 4, row = within & 15u;
    uint cx = page % px, cy = (page / px) % py, cz = page / ((size_t)px * py);
    uint y = min(edge * cy + 4 * ((tile >> 2) & 3u) + (row & 3u), Y - 1);
    uint z = min(edge * cz + 4 * (tile >> 4) + (row >> 2), Z - 1);
    uint x0 = edge * cx + 4 * (tile & 3u);
    __global const uchar *line = frames + offset + ((size_t)z * Y + y) * X;
    uint word = 0;
    for (uint k = 0; k < 4; k++)
        word |= (uint)line[min(x0 + k, X - 1)] << (8 * k);
    tiles[i] = word;
}

/* The gradient copy (kernels/common/cl_shared.h) of the frame at frames + offset: work-item
 * i writes the four voxels of tile row word i of the tiled copy (words 4i .. 4i + 3). */
__kernel void make_grads(__global const uchar *frames, ulong offset, uint X, uint Y, uint Z,
                         __global uint *grads)
{
    size_t i = get_global_id(0);
    const uint edge = CDVR_CL_PAGE_EDGE;
    uint px = (X + edge - 1) / edge, py = (Y + edge - 1) / edge, pz = (Z + edge - 1) / edge;
    if (i >= (size_t)px * py * pz * 1024)
        return;
    size_t page = i >> 10;
    uint within = (uint)i & 1023u, tile = within >> 4, row = within & 15u;
    uint cx = page % px, cy = (page / px) % py, cz = page / ((size_t)px * py);
    uint y = min(edge * cy + 4 * ((tile >> 2) & 3u) + (row & 3u), Y - 1);
    uint z = min(edge * cz + 4 * (tile >> 4) + (row >> 2), Z - 1);
    uint x0 = edge * cx + 4 * (tile & 3u);
    __global const uchar *f = frames + offset;
    size_t sy = X, sz = (size_t)X * Y;
    size_t ym = (size_t)(y > 0 ? y - 1 : 0), yp = (size_t)min(y + 1, Y - 1);
    size_t zm = (size_t)(z > 0 ? z - 1 : 0), zp = (size_t)min(z + 1, Z - 1);
    for (uint k = 0; k < 4; k++) {
        uint x = min(x0 + k, X - 1);
        size_t at = (size_t)z * sz + (size_t)y * sy;
        int dx = (int)f[at + min(x + 1, X - 1)] - (int)f[at + (x > 0 ? x - 1 : 0)];
        int dy = (int)f[(size_t)z * sz + yp * sy + x] - (int)f[(size_t)z * sz + ym * sy + x];
        int dz = (int)f[zp * sz + (size_t)y * sy + x] - (int)f[zm * sz + (size_t)y * sy + x];
        grads[4 * i + k] = (uint)(dx + CDVR_CL_GRAD_BIAS) |
                           ((uint)(dy + CDVR_CL_GRAD_BIAS) << 10) |
                           ((uint)(dz + CDVR_CL_GRAD_BIAS) << 20);
    }
}
