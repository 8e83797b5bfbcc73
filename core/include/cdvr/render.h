/* cdvr/render.h - the CPU reference ray caster (DESIGN.md section 6).
 *
 * This file is the definition of cdvr's ray casting; the OpenCL kernel follows it step by step
 * (in float arithmetic, like this code) and must match it to image PSNR >= 50 dB. (Its
 * composite march reads the TF's colours as unorm 11, 11 and 10 bits, within an eighth of an
 * 8-bit step of these, and its opacities exactly: cl_render.c upload_tables.)
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
 *
 * Blend modes (opts->look.blend, VTK's BlendMode; steps 4-5 above are "composite", the default):
 *  - CDVR_BLEND_MAX / MIN: over the samples of steps 2-3 (the owned ones when clipped) the
 *    largest / smallest code s; the pixel is the TF at s, its opacity taken as it is (no unit
 *    or step correction, as VTK's MIP): C = rgb(s) * a(s), A = a(s) (lerped table entries,
 *    step 4's i0 and f). A ray that takes no sample stays (0, 0).
 *  - CDVR_BLEND_AVERAGE: the same with the mean of the samples' codes (float sum / count).
 *  - CDVR_BLEND_ISO: the first crossing of the iso code c = (iso_value - lo) * 255 / (hi - lo)
 *    (the TF's window [lo, hi], hi > lo) along the samples: the first i >= 1 with
 *    (s_{i-1} - c) and (s_i - c) of opposite signs or s_i == c (or s_0 == c). The hit
 *    parameter is refined between the two sample midpoints by two regula-falsi steps on the
 *    trilinear field: t = t_a + (c - s_a) (t_b - t_a) / (s_b - s_a), s(t) sampled, and the
 *    bracket [t_a, t_b] narrowed to the side that still crosses. The pixel is iso_color (the
 *    TF's rgb at c when iso_color_set is 0) with opacity iso_opacity (0 -> 1), shaded at the
 *    hit when look.shade.enabled: C = rgb' * a, A = a. No early termination, no clipping
 *    (a clipped iso render is an error: a crossing may straddle two boxes).
 *  Max, min and average ignore shading and gradient opacity; none of them may be clipped.
 *
 * Shading (opts->look.shade, VTK's vtkVolumeProperty; composite and iso): at a sample with
 * opacity > 0 the gradient of the data is taken by central differences of the trilinear field
 * one voxel apart along each index axis: with g the sample's grid position, for axis a
 * g+ = min(g_a + 1, dims_a - 1), g- = max(g_a - 1, 0), dq_a = (s(g+) - s(g-)) / ((g+ - g-)
 * spacing_a) (0 when g+ == g-): codes per world unit along the box-frame axes; the world
 * gradient is G = D^-T dq (the direction matrix honoured; G = D dq for a rotation). With
 * V = -(world ray direction), L = V for the headlight (light_fixed 0) else -light_dir
 * normalised (light_dir: the direction the light travels), H = normalize(L + V), and
 * n = G / |G| (n = 0 when |G| < 1e-12: no NaN), two-sided lighting as VTK's renderers:
 *     rgb' = min(1, rgb * (ambient + diffuse |n.L|) + specular |n.H|^specular_power)
 * (0^power is 0: a zero gradient keeps only the ambient term). Alpha is unchanged by shading.
 * x^power (x = |n.H| in float): for a whole power up to CDVR_SHADE_WHOLE_POWER_MAX (VTK's
 * default 10) the float product of repeated squaring, lowest bit first: p = 1, then for each
 * bit b of power from 0, p = p * x if b is set, x = x * x (x^0 = 1); any other power powf.
 * Gradient opacity (opts->look.gradient_opacity, VTK's GradientOpacity; composite only): the
 * sample's opacity a (step 4's lerp of the table, before the unit correction) is multiplied by
 * the piecewise-linear function of |G| (hi - lo) / 255 (data units per world unit) through the
 * points (constant beyond the end points), then corrected for the segment as
 * 1 - (1 - a * factor)^(ds/unit) for every segment, full or not.
 *
 * Clipped rendering (opts->clip; sort-last compositing of boxes of one volume, cdvr/dist.h):
 * the volume passed holds only voxels offset .. offset + dims - 1 of a whole volume of
 * whole_dims voxels; its origin, spacing and direction are the whole volume's. Steps 0-2
 * use the whole volume's box, so the rays, t_near, t_far, n and every segment and midpoint
 * are those of the render of the whole volume. Step 3 computes g for the whole volume
 * (clamped to [0, whole_dims - 1]) and keeps the sample only if g lies in the owned cells:
 * for each axis own_lo <= g < own_hi, or g <= own_hi where own_hi = whole_dims - 1 (the last
 * box owns the far face); other samples are skipped (not classified, not composited, not
 * counted). A kept sample interpolates voxels floor(g) and floor(g) + 1 of the whole volume,
 * read from the passed volume at minus offset, so offset <= own_lo and own_hi <= offset +
 * dims - 1 are required. Boxes whose owned cells tile the whole volume's cells (the brick
 * rule of store.h: own_hi of one box = own_lo of the next) own disjoint sets of the whole
 * render's samples that together are all of them, each with the same value; blended front
 * to back in a visibility order (C = C_front + (1 - A_front) C_back, A likewise) they give
 * the whole render up to float rounding, except that early termination (step 5) acts on
 * each box's own accumulation: with term_alpha < 1 a pixel may keep up to (1 - term_alpha)
 * of colour the whole render would have dropped.
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

/* The box of a whole volume that a clipped render covers (see above). */
typedef struct cdvr_render_clip {
    size_t whole_dims[3];   /* dims of the whole volume */
    size_t offset[3];       /* whole-volume index of the passed volume's voxel (0,0,0) */
    size_t own_lo[3];       /* owned cells: voxel planes own_lo .. own_hi per axis */
    size_t own_hi[3];
} cdvr_render_clip;

/* Blend modes (VTK's BlendMode), the values of cdvr_render_opts.blend. */
typedef enum cdvr_blend {
    CDVR_BLEND_COMPOSITE = 0,
    CDVR_BLEND_MAX = 1,
    CDVR_BLEND_MIN = 2,
    CDVR_BLEND_AVERAGE = 3,
    CDVR_BLEND_ISO = 4
} cdvr_blend;
#define CDVR_BLEND_COUNT 5
/* "composite", "max", "min", "average", "iso"; NULL for other values. */
const char *cdvr_blend_name(int blend);
/* The mode called name; -1 for an unknown name. */
int cdvr_blend_parse(const char *name);

/* Shading as VTK's volume property (see above); zeros: off. */
typedef struct cdvr_shading {
    int enabled;
    double ambient, diffuse, specular, specular_power; /* VTK: 0.1, 0.7, 0.2, 10 */
    int light_fixed;        /* 0: a headlight; 1: a directional light along light_dir */
    double light_dir[3];    /* world direction the light travels (light_fixed) */
} cdvr_shading;
#define CDVR_SHADE_AMBIENT 0.1
#define CDVR_SHADE_DIFFUSE 0.7
#define CDVR_SHADE_SPECULAR 0.2
#define CDVR_SHADE_SPECULAR_POWER 10.0
#define CDVR_SHADE_WHOLE_POWER_MAX 128 /* whole specular powers taken by repeated squaring */

#define CDVR_GRADIENT_OPACITY_MAX 16
/* Opacity factor against gradient magnitude (data units per world unit); npoints 0: off. */
typedef struct cdvr_gradient_opacity {
    size_t npoints;
    double magnitude[CDVR_GRADIENT_OPACITY_MAX]; /* increasing */
    double factor[CDVR_GRADIENT_OPACITY_MAX];    /* in [0, 1] */
} cdvr_gradient_opacity;

/* How samples become a pixel beyond the TF: blend mode, shading, gradient opacity (above). */
typedef struct cdvr_look {
    int blend;                /* cdvr_blend (0: composite) */
    cdvr_shading shade;       /* composite and iso */
    cdvr_gradient_opacity gradient_opacity; /* composite */
    double iso_value;         /* CDVR_BLEND_ISO: data units */
    int iso_color_set;        /* 1: iso_color, else the TF's colour at iso_value */
    float iso_color[3];
    double iso_opacity;       /* 0 -> 1 */
} cdvr_look;

typedef struct cdvr_render_opts {
    const cdvr_tf *tf;
    const cdvr_camera *camera;
    double step;        /* world units; 0 -> 0.5 * min(spacing) */
    double unit;        /* opacity unit length; 0 -> tf->unit, or min(spacing) if that is 0 */
    double term_alpha;  /* early termination threshold; 0 -> 0.99; >= 1 disables */
    float background[4];/* straight RGBA stored into the image */
    int threads;        /* 0 -> number of online CPUs */
    const cdvr_render_clip *clip; /* NULL: the volume is whole; else render only its box */
    uint64_t samples;   /* out: samples taken (for samples/second) */
    const atomic_int *cancel; /* optional: once *cancel != 0 (e.g. set by a SIGINT handler)
                                 the render stops and fails with CDVR_ERR_CANCELLED */
    cdvr_look look;           /* blend mode, shading, gradient opacity, iso (zeros: plain
                                 composite) */
    int no_skip;              /* CPU: 1 takes every sample, one ray at a time (the plain
                                 loop); 0 (default) jumps samples whose brick has zero
                                 opacity and marches plain composite rays four at a time
                                 (render_cpu.c; the same image bit for bit, the same
                                 samples count) */
} cdvr_render_opts;

/* Checks the blend, shading, gradient-opacity and iso options for a TF built over window
 * [lo, hi] (tf->window): an unknown blend mode, coefficients that are negative or not finite,
 * a zero light_dir, unsorted or out-of-range gradient-opacity points, an iso value that is not
 * finite or a window of zero width for iso, and clipping with a blend other than composite or
 * with shading (central differences reach past a box's one-voxel overlap) are CDVR_ERR_ARG
 * naming the option and the value. Every renderer calls it. */
cdvr_status cdvr_render_check_look(const cdvr_render_opts *opts, cdvr_error *err);
/* A look with shading on at VTK's defaults (headlight). */
void cdvr_shading_default(cdvr_shading *sh);
/* The bounds on render work (cdvr_render_opts_check): a step below 1/64 of the smallest voxel
 * spacing is refused (64 samples per voxel is far past where the image stops changing; the
 * default step is 1/2), and so is a step that puts more than 2^24 samples on the box's
 * diagonal (e.g. a very anisotropic spacing). */
#define CDVR_RENDER_MIN_STEP_DIVISOR 64
#define CDVR_RENDER_MAX_RAY_SAMPLES (1u << 24)

/* Checks the options every renderer takes (the CPU ray caster, splatting, OpenCL, GL slicing
 * and the player call it; bindings may call it early): spacing positive and finite; step
 * finite and 0 (default) or >= min(spacing) / CDVR_RENDER_MIN_STEP_DIVISOR, and at most
 * CDVR_RENDER_MAX_RAY_SAMPLES steps along the box's diagonal (the whole volume's box when
 * opts->clip is set); unit finite and >= 0; term_alpha >= 0 (not NaN). Does not check tf or
 * camera. Errors (CDVR_ERR_ARG) name the option, its value and the limit, e.g. "render: step
 * 1e-06 is below 1/64 of the smallest voxel spacing 1 (the limit: step >= 0.015625)". */
cdvr_status cdvr_render_opts_check(const cdvr_volume *vol, const cdvr_render_opts *opts,
                                   cdvr_error *err);
/* The same for a box of dims voxels with this spacing, for callers that hold no volume yet
 * (a device stream, a player that has only the store's header). */
cdvr_status cdvr_render_opts_check_box(const size_t dims[3], const double spacing[3],
                                       const cdvr_render_opts *opts, cdvr_error *err);

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

/* What a CPU render's empty-space skipping keeps for the next one (a render context holds
 * one, cdvr/method.h): the brick ranges of the last frame and the skip flags made from them.
 * A render recomputes the ranges (cheap, on all threads) and makes the flags again (a distance
 * transform over the bricks, on one thread) only when the ranges or the TF's set of entries
 * with alpha > 0 (iso: the iso value) changed; the image is the same either way, bit for bit.
 * Belongs to one thread at a time. */
typedef struct cdvr_cpu_skip_cache cdvr_cpu_skip_cache;
cdvr_status cdvr_cpu_skip_cache_create(cdvr_cpu_skip_cache **out, cdvr_error *err);
/* NULL is allowed. */
void cdvr_cpu_skip_cache_free(cdvr_cpu_skip_cache *c);
/* The caller's promise (as cdvr_render_ctx_hold_volume's, cdvr/method.h) that vol (NULL:
 * none) stays alive and changes its voxels only with cdvr_volume_touch until it calls this
 * again with another volume or NULL: a render of vol's frame at the revision whose ranges the
 * cache holds then takes them as they are instead of computing them again (a tenth of a
 * Colin27 frame). NULL c is allowed. */
void cdvr_cpu_skip_cache_hold(cdvr_cpu_skip_cache *c, const cdvr_volume *vol);
/* cdvr_render_cpu with a cache (NULL: none, as cdvr_render_cpu). */
cdvr_status cdvr_render_cpu_cached(const cdvr_volume *vol, size_t t, cdvr_render_opts *opts,
                                   cdvr_cpu_skip_cache *cache, cdvr_image **out,
                                   cdvr_error *err);

#endif
