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
#ifndef CDVR_FETCH
    if (B == 4 && x0 + 8 <= X && y1 == y0 + 4 && z1 == z0 + 4) {
        /* a whole brick with its apron: 25 rows of 5 voxels, each read as 8 bytes of its row
           (the voxel loop below read one byte at a time: Colin27, 0.56 M bricks, most of a
           50 ms set-up) */
        uchar8 lo8 = (uchar8)(255), hi8 = (uchar8)(0);
        for (uint z = z0; z <= z1; z++)
            for (uint y = y0; y <= y1; y++) {
                uchar8 row = vload8(0, frame + (ulong)X * ((ulong)Y * z + y) + x0);
                lo8 = min(lo8, row);
                hi8 = max(hi8, row);
            }
        uchar4 lo4 = min(lo8.lo, (uchar4)(lo8.s4)), hi4 = max(hi8.lo, (uchar4)(hi8.s4));
        uchar2 lo2 = min(lo4.lo, lo4.hi), hi2 = max(hi4.lo, hi4.hi);
        minmax[b] = (uchar2)(min(lo2.x, lo2.y), max(hi2.x, hi2.y));
        return;
    }
#endif
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

/* Where tile t of the tiled copy (kernels/common/cl_shared.h) lies: its first voxel (x0, y0,
 * z0); 0 when t is past the last page. */
static int tile_origin(size_t t, uint X, uint Y, uint Z, uint *x0, uint *y0, uint *z0)
{
    const uint edge = CDVR_CL_PAGE_EDGE;
    uint px = (X + edge - 1) / edge, py = (Y + edge - 1) / edge, pz = (Z + edge - 1) / edge;
    if (t >= (size_t)px * py * pz * 64)
        return 0;
    size_t page = t >> 6;
    uint tile = (uint)t & 63u;
    uint cx = page % px, cy = (page / px) % py, cz = page / ((size_t)px * py);
    *x0 = edge * cx + 4 * (tile & 3u);
    *y0 = edge * cy + 4 * ((tile >> 2) & 3u);
    *z0 = edge * cz + 4 * (tile >> 4);
    return 1;
}

/* Voxels x0 .. x0 + 3 of a frame row (indices past X - 1 clamped to it). */
static uint4 row_voxels(__global const uchar *line, uint x0, uint X)
{
    if (x0 + 3 < X)
        return convert_uint4(vload4(0, line + x0));
    return (uint4)(line[min(x0, X - 1)], line[min(x0 + 1, X - 1)], line[min(x0 + 2, X - 1)],
                   line[min(x0 + 3, X - 1)]);
}

/* The tiled copy of a dense frame for the ray caster (kernels/common/cl_shared.h): one
 * work-item per tile (16 rows of 4 voxels, each a 32-bit word, low byte first: words 16t ..
 * 16t + 15), tiles = pages * 64; voxels past the frame's edge repeat its last one. */
__kernel void make_tiles(__global const uchar *frames, ulong offset, uint X, uint Y, uint Z,
                         __global uint *tiles)
{
    size_t t = get_global_id(0);
    uint x0, y0, z0;
    if (!tile_origin(t, X, Y, Z, &x0, &y0, &z0))
        return;
    uint words[16];
    for (uint row = 0; row < 16; row++) {
        uint y = min(y0 + (row & 3u), Y - 1), z = min(z0 + (row >> 2), Z - 1);
        uint4 b = row_voxels(frames + offset + ((size_t)z * Y + y) * X, x0, X);
        words[row] = b.x | (b.y << 8) | (b.z << 16) | (b.w << 24);
    }
    vstore16(vload16(0, words), t, tiles);
}

/* The quad copy (kernels/common/cl_shared.h) of the frame at frames + offset: one work-item
 * per tile of the tiled copy, its 64 voxels' words at 64t .. 64t + 63 (row by row, x
 * fastest). */
__kernel void make_quads(__global const uchar *frames, ulong offset, uint X, uint Y, uint Z,
                         __global uint *quads)
{
    size_t t = get_global_id(0);
    uint x0, y0, z0;
    if (!tile_origin(t, X, Y, Z, &x0, &y0, &z0))
        return;
    __global const uchar *f = frames + offset;
    for (uint row = 0; row < 16; row++) {
        uint y = min(y0 + (row & 3u), Y - 1), z = min(z0 + (row >> 2), Z - 1);
        __global const uchar *line = f + ((size_t)z * Y + y) * X;
        __global const uchar *next = f + ((size_t)z * Y + min(y + 1, Y - 1)) * X;
        uint4 a = row_voxels(line, x0, X), b = row_voxels(next, x0, X);
        uint4 a1 = (uint4)(a.y, a.z, a.w, line[min(x0 + 4, X - 1)]);
        uint4 b1 = (uint4)(b.y, b.z, b.w, next[min(x0 + 4, X - 1)]);
        vstore4(a | (a1 << 8) | (b << 16) | (b1 << 24), 0, quads + 64 * t + 4 * row);
    }
}

/* The gradient copy (kernels/common/cl_shared.h) of the frame at frames + offset: one
 * work-item per tile of the tiled copy, its 64 voxels' words at 64t .. 64t + 63 (row by row,
 * x fastest). */
__kernel void make_grads(__global const uchar *frames, ulong offset, uint X, uint Y, uint Z,
                         __global uint *grads)
{
    size_t t = get_global_id(0);
    uint x0, y0, z0;
    if (!tile_origin(t, X, Y, Z, &x0, &y0, &z0))
        return;
    __global const uchar *f = frames + offset;
    size_t sy = X, sz = (size_t)X * Y;
    for (uint row = 0; row < 16; row++) {
        uint y = min(y0 + (row & 3u), Y - 1), z = min(z0 + (row >> 2), Z - 1);
        uint ym = y > 0 ? y - 1 : 0, yp = min(y + 1, Y - 1);
        uint zm = z > 0 ? z - 1 : 0, zp = min(z + 1, Z - 1);
        __global const uchar *line = f + z * sz + y * sy;
        int4 dx;
        if (x0 + 4 < X) { /* neighbours along x: voxels x0 - 1 .. x0 + 4 */
            int4 mid = convert_int4(vload4(0, line + x0));
            dx = (int4)(mid.y, mid.z, mid.w, line[x0 + 4]) -
                 (int4)(line[x0 > 0 ? x0 - 1 : 0], mid.x, mid.y, mid.z);
        } else { /* at the frame's edge, as a voxel past it repeats the last one */
            int d[4];
            for (uint k = 0; k < 4; k++) {
                uint x = min(x0 + k, X - 1);
                d[k] = (int)line[min(x + 1, X - 1)] - (int)line[x > 0 ? x - 1 : 0];
            }
            dx = vload4(0, d);
        }
        int4 dy = convert_int4(row_voxels(f + z * sz + yp * sy, x0, X)) -
                  convert_int4(row_voxels(f + z * sz + ym * sy, x0, X));
        int4 dz = convert_int4(row_voxels(f + zp * sz + y * sy, x0, X)) -
                  convert_int4(row_voxels(f + zm * sz + y * sy, x0, X));
        int4 bias = (int4)(CDVR_CL_GRAD_BIAS);
        uint4 word = as_uint4(dx + bias) | (as_uint4(dy + bias) << 10) | (as_uint4(dz + bias) << 20);
        vstore4(word, 0, grads + 64 * t + 4 * row);
    }
}
