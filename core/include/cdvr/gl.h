/* cdvr/gl.h - 2D-texture slicing with a level of detail per slice (seed 002), through a
 * headless EGL context, and the GLFW window (DESIGN.md sections 6 and 11).
 *
 * The level-of-detail plan (cdvr_grid, cdvr_slice_axis, cdvr_lod_*) is plain arithmetic and
 * exists in every build. The slicer (cdvr_gl_*) and the window (cdvr_window_*) exist only when
 * cdvr is built with GL (CMake option CDVR_WITH_GL; CDVR_HAVE_GL is then 1); without it
 * cdvr_gl_create, cdvr_gl_slice, cdvr_window_open and cdvr_window_show fail with
 * CDVR_ERR_UNSUPPORTED (core/render/gl/gl_off.c).
 *
 * ---- Slicing (cdvr_gl_slice) ----
 * Object-aligned stack: the slices are the planes of constant index k along the index axis a
 * whose slices face the camera best: a maximises |f . n_a| / |n_a| with f = normalize(center -
 * eye) the view direction and n_a = row a of D^-1 the slices' normal (column a of D when D
 * is orthonormal; D = the volume's direction matrix, cdvr_volume_direction; ties: the lower
 * axis). Slice k (k = 0..n_a-1) is the rectangle of voxel centres [0, n_u-1] x
 * [0, n_v-1] at index k, with in-plane axes (u, v) = (x, y) for a = z, (x, z) for a = y and
 * (y, z) for a = x, so it covers exactly the ray caster's box (cdvr/render.h step 1).
 * The slices are drawn back to front (farthest first: on each side of the eye's index
 * coordinate along a, from the far end towards the eye) into a float RGBA framebuffer with
 * premultiplied "over" blending, dst = src + (1 - src.a) dst, starting from (0,0,0,0), so the
 * image holds premultiplied (C, A) before the background exactly as cdvr_render_cpu's does
 * (cdvr/image.h). Per fragment:
 *  1. s = bilinear interpolation of the slice's texels (in-plane index coordinates (x, y) of
 *     the level-L texture: g = (p + 0.5) / 2^L - 0.5, clamped to [0, size-1]; for L = 0 this is
 *     the ray caster's clamped trilinear interpolation restricted to the slice plane, same
 *     order: u first, then v).
 *  2. Post-classification as cdvr_render_cpu step 4: i0 = min((int)s, 254), rgb and a_tf
 *     interpolated linearly between table[i0] and table[i0+1] of the TF's 256-entry table.
 *  3. Opacity per unit length for this slice's share of the pixel's ray: slice k stands for the
 *     slab [k - 1/2, k + 1/2] of the stack (index units along a; the slices next to the eye
 *     reach to the eye's index coordinate e, for an orthographic camera e is at infinity
 *     behind the view; clipped to [0, n_a - 1]). ds is the world length of the pixel's ray
 *     (from the eye, or from the eye plane for orthographic cameras) inside that slab and the
 *     box, and a = 1 - (1 - a_tf)^(ds / unit), unit as cdvr_render_resolve. The slabs
 *     partition the box, so the ds a ray collects add up to its path through the box exactly
 *     as the ray caster's segments do: the slice spacing is the step along the normal,
 *     spacing_a / |cos theta| along an inner ray, shorter where the ray enters or leaves
 *     through a side face.
 * Every slice is composited (no early termination); opts->step and opts->term_alpha are not
 * used. Any invertible D works (the path lengths are computed in index space and measured in
 * world units).
 *
 * ---- Level of detail per slice (seed 002, eq. 3) ----
 *   R_k = R_org / 2^L_k,  L_k = floor(log2(d_k / D)),  D = min_k d_k,
 * with d_k the distance from the eye to slice k. The seed's geometry has the eye on the axis of
 * the stack, where d_k is the distance to the slice's plane; for any other view d_k is the
 * distance from the eye to the nearest point of slice k's rectangle (which is the plane
 * distance on the axis; the point is found by clamping the eye's index coordinates to the
 * rectangle, exact for orthonormal D, an approximation for sheared ones), and D, the distance to the nearest slice, is clamped below to
 * spacing_a / 2 (an eye inside the stack would otherwise make D vanish). floor(log2(x)) is
 * computed exactly: L is the largest integer with D * 2^L <= d_k (no log2 rounding). L is capped
 * at the level where both texture sides are 1. Level L of an n_u x n_v slice is a texture of
 * ceil(n_u / 2^L) x ceil(n_v / 2^L) texels; texel (i, j) is the mean of the level-0 voxels
 * [i 2^L, (i+1) 2^L) x [j 2^L, (j+1) 2^L) that exist, rounded half up to u8. Orthographic
 * cameras project every slice at the same scale: every slice keeps level 0.
 * The seed assumes (as its Table 2 does) that the nearest slice maps one texel to one pixel;
 * the formula ignores the image resolution, so where the nearest slice is magnified on screen
 * (a close or wide view of a volume smaller than the image) the coarser slices are visibly
 * coarser. CDVR_LOD_SCREEN keeps the rule but never lets D fall below D_pix, the distance at
 * which a texel of the slices (the smaller in-plane spacing s) spans one pixel at the image
 * centre: D_pix = s * H / (2 tan(fov/2)), H the image height. Then a slice is halved only where
 * its texels are at most half a pixel.
 */
#ifndef CDVR_GL_H
#define CDVR_GL_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/camera.h"
#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/render.h"
#include "cdvr/volume.h"

/* ---- level-of-detail plan (every build) ---------------------------------------------------- */

/* Index-to-world geometry of a volume (cdvr/volume.h), without its voxels. */
typedef struct cdvr_grid {
    size_t dims[3];
    double origin[3], spacing[3];
    double direction[9]; /* row-major; column c = world direction of index axis c */
} cdvr_grid;

/* The geometry of vol. */
void cdvr_grid_of_volume(const cdvr_volume *vol, cdvr_grid *grid);
/* Continuous index coordinates of world point p, and of world direction d (through D^-1). */
void cdvr_grid_index_of(const cdvr_grid *grid, const double p[3], double out[3]);
void cdvr_grid_index_direction(const cdvr_grid *grid, const double d[3], double out[3]);
/* Index axis (0, 1, 2) whose world direction is most parallel to the camera's view. */
int cdvr_slice_axis(const cdvr_grid *grid, const cdvr_camera *cam);
/* In-plane index axes (u, v) of slices perpendicular to axis. */
void cdvr_slice_plane_axes(int axis, int *u, int *v);
/* Distance from eye to the nearest point of slice k (0-based) along axis. */
double cdvr_slice_distance(const cdvr_grid *grid, int axis, size_t k, const double eye[3]);
/* ceil(n / 2^level), at least 1. */
size_t cdvr_lod_extent(size_t n, int level);
/* Level at which both sides of an n_u x n_v slice are 1 texel. */
int cdvr_lod_max_level(size_t n_u, size_t n_v);

typedef struct cdvr_lod_plan {
    int axis;
    size_t nslices;
    int *levels;           /* nslices entries */
    double nearest;        /* D, after clamping */
    uint64_t total_bytes;  /* sum over slices of ceil(n_u/2^L) ceil(n_v/2^L) bytes_per_voxel */
    uint64_t full_bytes;   /* the same with every level 0 */
} cdvr_lod_plan;

/* Level-of-detail rules for cdvr_lod_plan_compute and cdvr_gl_slice. */
typedef enum cdvr_lod_mode {
    CDVR_LOD_OFF = 0,   /* every slice at level 0 */
    CDVR_LOD_SEED = 1,  /* seed 002's rule exactly */
    CDVR_LOD_SCREEN = 2 /* the seed's rule with D at least D_pix (needs a camera) */
} cdvr_lod_mode;

/* D_pix of CDVR_LOD_SCREEN for the slices along axis seen by cam (0 for orthographic cameras). */
double cdvr_lod_pixel_distance(const cdvr_grid *grid, int axis, const cdvr_camera *cam);

/* Levels of the slices along axis seen from eye. lod: 0 every level 0; otherwise the seed's
 * rule with D = max(min_k d_k, spacing_a / 2, min_nearest) (min_nearest = 0 for the seed's
 * rule, D_pix for CDVR_LOD_SCREEN). Fails on an empty grid, a non-finite eye, non-positive
 * spacing, bytes_per_voxel 0 or overflowing sums. */
cdvr_status cdvr_lod_plan_compute(const cdvr_grid *grid, int axis, const double eye[3],
                                  size_t bytes_per_voxel, int lod, double min_nearest,
                                  cdvr_lod_plan *plan, cdvr_error *err);
void cdvr_lod_plan_free(cdvr_lod_plan *plan);

/* ---- the EGL slicer (CDVR_HAVE_GL builds) ------------------------------------------------- */

/* A headless EGL context (Mesa surfaceless platform, else an EGL device, else the default
 * display with a 1x1 pbuffer; desktop OpenGL 3.3 core) and the slicer's GL objects. It keeps
 * the last volume's slice textures: a frame with the same voxels (CRC-32C of the frame), axis
 * and levels reuses them; levels above 0 are built once per slice and level and kept in host
 * memory while the frame and axis stay the same. The context is current only inside calls;
 * not thread-safe (one cdvr_gl per thread). */
typedef struct cdvr_gl cdvr_gl;

cdvr_status cdvr_gl_create(cdvr_gl **out, cdvr_error *err);
void cdvr_gl_free(cdvr_gl *gl);
/* "llvmpipe (LLVM 15.0.6, 256 bits); EGL surfaceless", for reports. */
const char *cdvr_gl_renderer(const cdvr_gl *gl);

typedef struct cdvr_slice_stats {
    int axis;                 /* 0, 1, 2 */
    size_t slices;            /* slices drawn */
    int min_level, max_level; /* over the slices */
    double nearest;           /* D of the level-of-detail rule (0 without lod) */
    uint64_t texture_bytes;   /* bytes of the slice textures allocated for this frame (u8
                                 texels, one byte each: classification is in the shader) */
    uint64_t full_bytes;      /* the same at level 0 for every slice */
    uint64_t uploaded_bytes;  /* texture bytes uploaded by this call (0 when all reused) */
    double upload_ms, draw_ms;/* texture building + upload; drawing + read-back */
} cdvr_slice_stats;

/* Renders frame t (from 0) of a u8 volume by slicing (the rules above). Uses opts->tf, camera,
 * unit, background, cancel; lod is a cdvr_lod_mode (orthographic cameras: always off). stats
 * may be NULL.
 * An interrupted render (opts->cancel) fails with CDVR_ERR_CANCELLED. */
cdvr_status cdvr_gl_slice(cdvr_gl *gl, const cdvr_volume *vol, size_t t,
                          const cdvr_render_opts *opts, int lod, cdvr_slice_stats *stats,
                          cdvr_image **out, cdvr_error *err);

/* ---- the window (GLFW; CDVR_HAVE_GL builds) ---------------------------------------------- */

/* A GLFW window that shows 8-bit RGBA images (it never renders a scene itself) and queues its
 * input. Needs a display (X11 or Wayland); cdvr_window_open fails with CDVR_ERR_UNSUPPORTED
 * and a message naming the reason when there is none. */
typedef struct cdvr_window cdvr_window;

typedef enum cdvr_window_event_type {
    CDVR_WINDOW_DRAG = 1,  /* dx, dy: cursor motion in pixels with the left button held */
    CDVR_WINDOW_SCROLL,    /* dy: wheel steps (positive: away from the user) */
    CDVR_WINDOW_KEY,       /* key: CDVR_KEY_*, or another letter as its lower-case
                              character ('a'..'z') */
    CDVR_WINDOW_RESIZE     /* the framebuffer size changed */
} cdvr_window_event_type;

enum { CDVR_KEY_LEFT = 1, CDVR_KEY_RIGHT, CDVR_KEY_UP, CDVR_KEY_DOWN, CDVR_KEY_SPACE,
       CDVR_KEY_HOME, CDVR_KEY_END, CDVR_KEY_ESCAPE, CDVR_KEY_Q, CDVR_KEY_R };

typedef struct cdvr_window_event {
    cdvr_window_event_type type;
    double dx, dy;
    int key;
} cdvr_window_event;

/* 1 when a window can be opened (a display answers; GLFW stays initialised until exit), else 0
 * and the reason in err. */
int cdvr_window_available(cdvr_error *err);
cdvr_status cdvr_window_open(int width, int height, const char *title, cdvr_window **out,
                             cdvr_error *err);
void cdvr_window_close(cdvr_window *win);
/* Processes pending window-system events; copies up to max queued events into ev and returns
 * their count (later ones wait for the next call). */
size_t cdvr_window_poll(cdvr_window *win, cdvr_window_event *ev, size_t max);
/* 1 once the user asked to close the window (close button). */
int cdvr_window_should_close(const cdvr_window *win);
/* Framebuffer size in pixels. */
void cdvr_window_size(const cdvr_window *win, int *width, int *height);
/* Shows a width x height 8-bit RGBA image (row 0 on top) at the top-left corner, the rest of
 * the window black, and swaps buffers. */
cdvr_status cdvr_window_show(cdvr_window *win, const uint8_t *rgba, int width, int height,
                             cdvr_error *err);
/* What the last cdvr_window_show displayed, read back from the window's framebuffer before
 * the swap: 8-bit RGBA of the framebuffer's size, row 0 on top; NULL before the first show.
 * Valid until the next show or close. */
const uint8_t *cdvr_window_pixels(const cdvr_window *win, int *width, int *height);

/* Draws one line of text (stb_easy_font's glyphs, scaled by `scale` pixels per unit) in
 * opaque colour rgb at (x, y) (top-left) on a darkened band, into an 8-bit RGBA image. */
void cdvr_overlay_text(uint8_t *rgba, int width, int height, int x, int y, int scale,
                       const char *text, const uint8_t rgb[3]);
/* The same text wrapped to the image: broken into lines that fit between x and the right
 * edge, before two spaces (fields) where one field fits, else before a space (a word wider
 * than the line is cut and ends in '~'), drawn from (x, y) down,
 * one under the other, while they start inside the image. Returns the number of lines drawn. */
int cdvr_overlay_lines(uint8_t *rgba, int width, int height, int x, int y, int scale,
                       const char *text, const uint8_t rgb[3]);

#endif
