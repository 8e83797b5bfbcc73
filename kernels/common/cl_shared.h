/* kernels/common/cl_shared.h - the one definition of what the OpenCL kernels and the host code
 * (core/render/cl/) share: constants and argument structs. The host includes this file; the
 * program builder puts its text in front of every kernel program, so both sides always agree.
 * Plain C that both C11 and OpenCL C accept; structs hold 4-byte members only (no padding). */
#ifndef CDVR_CL_SHARED_H
#define CDVR_CL_SHARED_H

#ifdef __OPENCL_VERSION__
typedef float cdvr_cl_f32;
typedef int cdvr_cl_i32;
#else
#include <stdint.h>
typedef float cdvr_cl_f32;
typedef int32_t cdvr_cl_i32;
#endif

/* Rays per ray-cast work-item: a packet of PACKET_W x PACKET_H neighbouring pixels marched
 * in lock-step on 16-wide vectors (lanes row by row). */
#define CDVR_CL_PACKET_W 4
#define CDVR_CL_PACKET_H 4
/* The ray caster's tiled copy of a frame (kernels/render/raycast.cl) holds its voxels in tiles
 * of 4 x 4 x 4 (64 bytes: one cache line; within a tile x fastest, then y, z, so each tile
 * row of 4 voxels is one 32-bit word), 4 x 4 x 4 tiles to a page of 16^3 voxels (4096 bytes:
 * one memory page; tiles x fastest, then y, z), pages x fastest, then y, z. The buffer holds
 * whole pages: ceil(dims / 16) of them per axis; voxels past the frame's edge repeat its last
 * voxel (never read). Rays near each other read few lines and few pages (TLB entries).
 * raycast.cl's along_x/y/z and bricks.cl's make_tiles spell out these sizes: the edge must
 * stay 16. */
#define CDVR_CL_PAGE_EDGE 16
/* The gradient copy of a frame (made with the tiled copy for renders that shade or use
 * gradient opacity): per voxel (x, y, z) one 32-bit word at index 4 * w + (x & 3), where w is
 * the voxel's tile row word in the tiled copy, holding the central differences
 * D_a = v(p + e_a) - v(p - e_a) (neighbours clamped to the frame) as D_x + 512 in bits 0-9,
 * D_y + 512 in bits 10-19 and D_z + 512 in bits 20-29. Inside the frame the trilinear
 * interpolation of D at g equals the difference of the trilinear values at g + e_a and
 * g - e_a (render.h's gradient) in exact arithmetic; raycast.cl reads it only where every
 * corner's neighbours lie in the frame. */
#define CDVR_CL_GRAD_BIAS 512
/* The quad copy of a frame (made with the tiled copy where cl_render.c's quads_ready says):
 * per voxel (x, y, z) one 32-bit word at index 4 * w + (x & 3), as the gradient copy's,
 * holding v(x, y, z), v(x + 1, y, z), v(x, y + 1, z) and v(x + 1, y + 1, z) from the low byte
 * up (x + 1 and y + 1 clamped to the frame), so a trilinear sample reads two words (its
 * cell's z faces) instead of eight tile rows, the same values in the same order. */
/* The largest whole specular power taken by repeated squaring: CDVR_SHADE_WHOLE_POWER_MAX of
 * render.h, shading (cl_render.c checks that they agree). */
#define CDVR_CL_WHOLE_POWER_MAX 128.0f
/* Edge of the min/max bricks for empty-space skipping: 1 << CDVR_CL_BRICK_SHIFT voxels. */
#define CDVR_CL_BRICK_SHIFT 2
/* Bytes after the last brick's flag in every brick flag buffer (brick_visible, the iso and
 * zero flags): a CPU device with AVX-512 reads a flag as the low byte of a 32-bit word at its
 * index (raycast.cl, brick_exit: one gather instead of a load per lane). */
#define CDVR_CL_FLAGS_PAD 3
/* Edge of the blocks of bricks whose ranges follow the bricks' (max, min and average skip a
 * dull block at once): 1 << CDVR_CL_BLOCK_SHIFT bricks. */
#define CDVR_CL_BLOCK_SHIFT 2
/* Bytes of the codec parameter blob handed to decode kernels and fetch functions
 * (CDVR_CODEC_PARAMS_MAX in cdvr/codec.h). */
#define CDVR_CL_PARAMS_BYTES 48
/* The params buffer of decode kernels and fetch functions: the blob, then at byte
 * CDVR_CL_PARAMS_BYTES the payload's size in bytes (little-endian u64), which fetch functions
 * clamp their reads below (cdvr/codec.h). */
#define CDVR_CL_PARAMS_BUFFER_BYTES 56

/* The camera of render.h, in float (cdvr_cl_render converts it). */
typedef struct cdvr_cl_camera {
    cdvr_cl_f32 eye[3], f[3], u[3], r[3];
    cdvr_cl_f32 tan_half, aspect, ortho_half_height;
    cdvr_cl_i32 orthographic, width, height;
} cdvr_cl_camera;

/* The volume's box frame of render.h step 0: q = inv_dir * (world - origin), inv_dir = D^-1
 * (row-major), in float (cdvr_cl_render computes D^-1 in double and rounds it). */
typedef struct cdvr_cl_box_frame {
    cdvr_cl_f32 origin[3], inv_dir[9];
} cdvr_cl_box_frame;

/* Clipped rendering (render.h, cdvr_render_clip) in the ray caster's terms: the stream's
 * frame holds the whole volume's voxels from `offset`; a sample at whole-volume grid
 * position g (clamped to [0, whole_top]) is kept when own_lo <= g < own_hi per axis, or
 * g <= own_hi on axes where own_far is set (own_hi is the volume's far face). */
typedef struct cdvr_cl_clip {
    cdvr_cl_f32 offset[3], whole_top[3], own_lo[3], own_hi[3];
    cdvr_cl_i32 own_far[3], enabled;
} cdvr_cl_clip;

/* Blend mode, shading and gradient opacity of render.h (cdvr_look) in the ray caster's terms
 * (cdvr_cl_render converts them): light is the world direction towards the light (unit) when
 * headlight is 0; grad_to_world = D^-T (row-major) takes box-frame gradients to world; codes
 * times value_per_code are data units; iso_code is the iso value as a code. */
#define CDVR_CL_GO_MAX 16
typedef struct cdvr_cl_look {
    cdvr_cl_i32 blend, shade, headlight, go_points;
    cdvr_cl_f32 ambient, diffuse, specular, power;
    cdvr_cl_f32 light[3];
    cdvr_cl_f32 grad_to_world[9];
    cdvr_cl_f32 spacing[3];
    cdvr_cl_f32 value_per_code;
    cdvr_cl_f32 go_mag[CDVR_CL_GO_MAX], go_factor[CDVR_CL_GO_MAX];
    cdvr_cl_f32 iso_code, iso_rgb[3], iso_alpha;
    cdvr_cl_i32 iso_tf_color;
} cdvr_cl_look;

#endif
