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

/* The quads of a dense frame for the ray caster (raycast.cl): per voxel (x, y, z), one word
 * holding voxels (x, y), (x1, y), (x, y1), (x1, y1) of its plane, low byte first, with
 * x1 = min(x + 1, X - 1) and y1 = min(y + 1, Y - 1), at its place in the tiled layout of
 * kernels/common/cl_shared.h (quad_slot; the padding of the last tiles is never read). One
 * work-item per voxel. */
static size_t quad_slot(uint x, uint y, uint z, uint X, uint Y)
{
    const uint sh = CDVR_CL_QUAD_TILE_SHIFT, m = (1u << sh) - 1u;
    size_t tx = (X + m) >> sh, ty = (Y + m) >> sh;
    size_t tile = ((size_t)(z >> sh) * ty + (y >> sh)) * tx + (x >> sh);
    return (tile << (3 * sh)) + ((z & m) << (2 * sh)) + ((y & m) << sh) + (x & m);
}

__kernel void make_quads(__global const uchar *frames, ulong offset, uint X, uint Y, uint Z,
                         __global uint *quads)
{
    size_t i = get_global_id(0);
    if (i >= (size_t)X * Y * Z)
        return;
    __global const uchar *f = frames + offset;
    uint x = i % X, y = (i / X) % Y, z = i / ((size_t)X * Y);
    size_t row = i - x, up = y + 1 < Y ? X : 0;
    uint x1 = x + 1 < X ? x + 1 : x;
    quads[quad_slot(x, y, z, X, Y)] = (uint)f[row + x] | (uint)f[row + x1] << 8 |
                                      (uint)f[row + up + x] << 16 |
                                      (uint)f[row + up + x1] << 24;
}
