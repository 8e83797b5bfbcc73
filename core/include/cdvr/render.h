/* cdvr/render.h - the CPU reference ray caster (DESIGN.md section 6).
 *
 * This file is the definition of cdvr's ray casting; the OpenCL kernel follows it step by step
 * (in float arithmetic, like this code) and must match it to image PSNR >= 50 dB.
 *
 * For pixel (x, y) with ray o + t*d from cdvr_camera_ray (world coordinates, |d| = 1, so t is
 * world distance from the eye):
 *  0. Box frame. The volume's index-to-world map is world = origin + D * (i*sx, j*sy, k*sz)
 *     (volume.h; D = the direction matrix, identity for an axis-aligned volume). The ray is
 *     carried into the box frame q = D^-1 (world - origin), in which the volume is the
 *     axis-aligned box [0, (dims-1)*spacing] and voxel (i,j,k) sits at (i*sx, j*sy, k*sz):
 *     o' = D^-1 (o - origin) and d' = D^-1 d, computed in double and rounded to float once.
 *     The map is affine, so o' + t*d' is the box-frame image of the world point o + t*d for
 *     the same t: the slab test, the segment lengths, the step and the opacity unit below are
 *     all in world units whatever D is (rotations, flips, or a shear; |d'| = 1 when D is
 *     orthonormal). D must be invertible (render errors name it otherwise).
 *  1. Box B = [0, (dims-1)*spacing] in the box frame. Slab intersection per axis of o' + t*d';
 *     an axis with |d'| < 1e-12 (ray parallel to the faces) keeps (-inf, inf) if o' lies inside
 *     the slab and misses otherwise: no division by zero. t_near = max(t_enter, 0) (camera
 *     inside the volume starts at the eye), t_far = t_exit; no hit if t_far <= t_near.
 *  2. Segments: L = t_far - t_near, n = ceil(L / step) (at least 1); segment i covers
 *     [t_near + i*step, min(t_near + (i+1)*step, t_far)] with length ds_i; it is sampled at its
 *     midpoint. Summing exact segment lengths makes a constant medium give exactly
 *     T = (1 - a_tf)^(L/unit) = exp(-k L) with k = -ln(1 - a_tf)/unit.
 *  3. Sample at box-frame point p' = o' + t*d': g = p'/spacing (as p' * (1/spacing), the
 *     reciprocal rounded to float) clamped to [0, dims-1] per axis; trilinear
 *     interpolation of the 8 neighbouring u8 voxels (upper index clamped to dims-1) -> s.
 *  4. Post-classification: s is a code 0..255 of the u8 frame; its data value is
 *     lo + s*(hi-lo)/255 over the series' value window [lo, hi] (volume.h), and the TF table
 *     was built over the same window (tf.h: table[i] = TF(lo + i*(hi-lo)/255)), so the
 *     renderer only indexes the table: i0 = min((int)s, 254), f = s - i0; rgb = lerp of table[i0],
 *     table[i0+1]. Opacity: for a full segment (ds == step) lerp of the step-corrected table
 *     a_c[i] = 1 - (1 - a[i])^(step/unit); for the shorter last segment
 *     a = 1 - (1 - lerp(a))^(ds/unit).
 *  5. Front-to-back: C += (1 - A) * a * rgb; A += (1 - A) * a. Stop after a sample with
 *     A >= term_alpha (early termination).
 *  6. The pixel stores premultiplied (C, A); the background is composited later (image.h).
 */
#ifndef CDVR_RENDER_H
#define CDVR_RENDER_H

#include <stdatomic.h>
#include <stdint.h>

#include "cdvr/camera.h"
#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/tf.h"
#include "cdvr/volume.h"

typedef struct cdvr_render_opts {
    const cdvr_tf *tf;
    const cdvr_camera *camera;
    double step;        /* world units; 0 -> 0.5 * min(spacing) */
    double unit;        /* opacity unit length; 0 -> tf->unit, or min(spacing) if that is 0 */
    double term_alpha;  /* early termination threshold; 0 -> 0.99; >= 1 disables */
    float background[4];/* straight RGBA stored into the image */
    int threads;        /* 0 -> number of online CPUs */
    uint64_t samples;   /* out: samples taken (for samples/second) */
    const atomic_int *cancel; /* optional: once *cancel != 0 (e.g. set by a SIGINT handler)
                                 the render stops and fails with CDVR_ERR_CANCELLED */
} cdvr_render_opts;

/* Resolved step, unit and termination threshold (the defaults above) for a volume. */
void cdvr_render_resolve(const cdvr_volume *vol, const cdvr_render_opts *opts, double *step,
                         double *unit, double *term_alpha);

/* 1 when the ray of at least one pixel hits the volume's box (steps 0 and 1 above, so exactly
 * the rays the renderer marches), 0 when the camera's view misses the volume altogether (the
 * image would be only background). Scans pixels coarse to fine and stops at the first hit.
 * A volume with invalid geometry or an invalid camera gives 0. */
int cdvr_render_view_hits(const cdvr_volume *vol, const cdvr_camera *cam);

/* Renders frame t (from 0) of a u8 volume into a new image of the camera's size.
 * Non-u8 volumes are an error (quantize first). Checks opts->cancel before each row. */
cdvr_status cdvr_render_cpu(const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                            cdvr_image **out, cdvr_error *err);

#endif
