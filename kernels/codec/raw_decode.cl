/* kernels/codec/raw_decode.cl - the raw codec's decode kernel (cdvr/codec.h): the payload is
 * the frame; each work-item copies 16 voxels (cl_work_items = ceil(voxels / 16)). */
__kernel void raw_decode(__global const uchar *payload, ulong payload_bytes,
                         __constant uchar *params, uint X, uint Y, uint Z, uint nframes,
                         __global uchar *frames)
{
    ulong total = (ulong)X * Y * Z * nframes;
    ulong first = (ulong)get_global_id(0) * 16;
    (void)params;
    if (total > payload_bytes)
        total = payload_bytes;
    for (ulong i = first; i < first + 16 && i < total; i++)
        frames[i] = payload[i];
}
