/* kernels/codec/pvtc_decode.cl - PVTC chunk decode (DESIGN.md 4.1), bit-exact with
 * cdvr_pvtc_decode_chunk. One work-item per block; blocks are numbered x fastest, then y,
 * then z, so neighbouring work-items read neighbouring endpoint and index words
 * (struct-of-arrays chunk: all 4-byte endpoint words, then all index words, S per block). */

static uint load_le32(__global const uchar *p)
{
    return (uint)p[0] | ((uint)p[1] << 8) | ((uint)p[2] << 16) | ((uint)p[3] << 24);
}

static uint expand5(uint x) { return (x << 3) | (x >> 2); }
static uint expand6(uint x) { return (x << 2) | (x >> 4); }

/* Endpoints U (a) and D (b) of channel c from the block's endpoint word. */
static void endpoints(uint word, int T, int c, uint *a, uint *b)
{
    if (T == 2) {
        *a = (word >> (8 * c)) & 0xffu;
        *b = (word >> (8 * (2 + c))) & 0xffu;
        return;
    }
    uint u = word & 0xffffu, d = word >> 16;
    if (c == 0) {
        *a = expand5(u >> 11);
        *b = expand5(d >> 11);
    } else if (c == 1) {
        *a = expand6((u >> 5) & 63u);
        *b = expand6((d >> 5) & 63u);
    } else {
        *a = expand5(u & 31u);
        *b = expand5(d & 31u);
    }
}

static uint param_u32(__constant uchar *params, int offset)
{
    return (uint)params[offset] | ((uint)params[offset + 1] << 8) |
           ((uint)params[offset + 2] << 16) | ((uint)params[offset + 3] << 24);
}

/* The codec decode kernel of cdvr/codec.h. params: the PVTC blob (u32 S at 0, T at 4, pack at 8;
 * core/codec/pvtc/pvtc_codec.c). One work-item per block (cl_work_items = block count).
 * Time packing writes channel c to frame c (c < nframes); space packing writes channel c of
 * packed position z to slice T*z + c of frame 0. Positions past the dims are cropped. The
 * host checked payload_bytes against the chunk size. */
__kernel void pvtc_decode(__global const uchar *chunk, ulong payload_bytes,
                          __constant uchar *params, uint X, uint Y, uint Z, uint nframes,
                          __global uchar *frames)
{
    int S = (int)param_u32(params, 0), T = (int)param_u32(params, 4);
    int space = param_u32(params, 8) == 1u;
    uint zdepth = (uint)S * (space ? (uint)T : 1u);
    uint bx = (X + 3) / 4, by = (Y + 3) / 4, bz = (Z + zdepth - 1) / zdepth;
    uint blk = get_global_id(0);
    uint nblocks = bx * by * bz;
    if (blk >= nblocks)
        return;
    (void)payload_bytes;
    uint ix = blk % bx, iy = (blk / bx) % by, iz = blk / (bx * by);
    uint ends = load_le32(chunk + 4 * (size_t)blk);
    __global const uchar *index_words = chunk + 4 * (size_t)nblocks + 4 * (size_t)S * blk;
    ulong frame_voxels = (ulong)X * Y * Z;
    int channels = space ? T : (int)nframes;
    for (int c = 0; c < channels; c++) {
        uint a, b;
        endpoints(ends, T, c, &a, &b);
        uchar palette[4] = {(uchar)a, (uchar)((2 * a + b + 1) / 3), (uchar)((a + 2 * b + 1) / 3),
                            (uchar)b};
        for (int zl = 0; zl < S; zl++) {
            uint packed_z = iz * (uint)S + (uint)zl;
            uint z = space ? packed_z * (uint)T + (uint)c : packed_z;
            if (z >= Z)
                continue;
            uint word = load_le32(index_words + 4 * zl);
            __global uchar *out = frames + (space ? 0 : (ulong)c * frame_voxels) +
                                  (ulong)X * ((ulong)Y * z);
            for (uint yl = 0; yl < 4; yl++) {
                uint y = iy * 4 + yl;
                if (y >= Y)
                    break;
                for (uint xl = 0; xl < 4; xl++) {
                    uint x = ix * 4 + xl;
                    if (x >= X)
                        break;
                    uint idx = (word >> (2 * (xl + 4 * yl))) & 3u;
                    out[(ulong)y * X + x] = palette[idx];
                }
            }
        }
    }
}
