/* core/render/cl/cl_render.c - per-frame setup (b4: TF, brick visibility) and ray casting (b5). */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "cl_internal.h"
#include "cdvr/timing.h"
#include "render/cpu/brick_range.h"

_Static_assert(CDVR_CL_WHOLE_POWER_MAX == (float)CDVR_SHADE_WHOLE_POWER_MAX,
               "raycast.cl and render.h take the same whole specular powers by squaring");

typedef cdvr_cl_camera cam_params; /* kernels/common/cl_shared.h */
typedef cdvr_cl_box_frame box_frame; /* render.h step 0 */
typedef cdvr_cl_clip clip_params;    /* clipped rendering, render.h */

static cdvr_status run_kernel(cdvr_cl *cl, cl_kernel k, cl_uint ndim, const size_t *global,
                              const size_t *local, const char *what, cdvr_error *err)
{
    cl_int code = clEnqueueNDRangeKernel(cl->queue, k, ndim, NULL, global, local, 0, NULL, NULL);
    if (!code)
        code = clFinish(cl->queue);
    return cdvr_cl_check(code, what, err);
}

static cdvr_status write_buffer(cdvr_cl *cl, cl_mem mem, const void *data, size_t bytes,
                                const char *what, cdvr_error *err)
{
    cl_int code = clEnqueueWriteBuffer(cl->queue, mem, CL_TRUE, 0, bytes, data, 0, NULL, NULL);
    return cdvr_cl_check(code, what, err);
}

/* The voxel source of device frame `frame` for the brick and ray-cast kernels (their first
 * three arguments): dense frames at an offset, or the payload, the parameter blob and the
 * frame index through the fetch-mode codec's kernels. */
typedef struct voxel_source {
    cl_kernel k_bricks, k_raycast;
    cl_mem vol, params;
    cl_ulong offset;
    cl_int tiled;               /* vol holds the frame's tiled copy (ray caster only) */
} voxel_source;

static cdvr_status source_of(cdvr_cl_stream *s, size_t frame, voxel_source *v, cdvr_error *err)
{
    if (s->fetch) {
        *v = (voxel_source){s->fetch->k_bricks, s->fetch->k_raycast, s->payload, s->params,
                            (cl_ulong)frame, 0};
        return CDVR_OK;
    }
    *v = (voxel_source){s->cl->k_bricks, s->cl->k_raycast, cdvr_cl_frames_mem(s), s->params,
                        (cl_ulong)(frame * s->voxels), 0};
    /* 32-bit indices overflow */
    if (s->voxels > INT_MAX || cdvr_cl_env_is("CDVR_CL_LONG_INDEX", "1"))
        return cdvr_cl_long_index_kernels(s->cl, &v->k_bricks, &v->k_raycast, err);
    return CDVR_OK;
}

static cdvr_status set_source_args(cl_kernel k, const char *name, const voxel_source *v,
                                   cdvr_error *err)
{
    cdvr_status st = cdvr_cl_arg(k, name, 0, sizeof(cl_mem), &v->vol, err);
    if (!st)
        st = cdvr_cl_arg(k, name, 1, sizeof(cl_mem), &v->params, err);
    if (!st)
        st = cdvr_cl_arg(k, name, 2, sizeof v->offset, &v->offset, err);
    return st;
}

/* The ranges of the blocks of 2^CDVR_CL_BLOCK_SHIFT bricks per axis from the bricks' ranges
 * (lo, hi pairs), written after them in brick_minmax. */
static cdvr_status upload_block_ranges(cdvr_cl_stream *s, const uint8_t *bricks, cdvr_error *err)
{
    uint8_t *blocks = malloc(2 * s->nblocks);
    if (!blocks)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL block ranges: out of memory");
    for (size_t i = 0; i < s->nblocks; i++) {
        blocks[2 * i] = 255;
        blocks[2 * i + 1] = 0;
    }
    const size_t *bd = s->brick_dims, *kd = s->block_dims;
    const unsigned shift = CDVR_CL_BLOCK_SHIFT;
    size_t b = 0;
    for (size_t z = 0; z < bd[2]; z++)
        for (size_t y = 0; y < bd[1]; y++)
            for (size_t x = 0; x < bd[0]; x++, b++) {
                size_t k = (x >> shift) + kd[0] * ((y >> shift) + kd[1] * (z >> shift));
                if (bricks[2 * b] < blocks[2 * k])
                    blocks[2 * k] = bricks[2 * b];
                if (bricks[2 * b + 1] > blocks[2 * k + 1])
                    blocks[2 * k + 1] = bricks[2 * b + 1];
            }
    cl_int code = clEnqueueWriteBuffer(s->cl->queue, s->brick_minmax, CL_TRUE, 2 * s->nbricks,
                                       2 * s->nblocks, blocks, 0, NULL, NULL);
    free(blocks);
    return cdvr_cl_check(code, "upload block ranges", err);
}

/* On a CPU device the ranges of a dense frame come from the host: the CPU ray caster's
 * cdvr_cpu_brick_ranges (render/cpu/brick_range.h) on the mapped frame (no copy in PoCL), on
 * every online core, then uploaded to brick_minmax: the same bytes as the brick_minmax
 * kernel, in a third of its CPU time (Colin27: 0.56 M bricks). Returns 1 when s->grid.minmax
 * and brick_minmax hold them; 0 (the kernel then runs) on any failure, or with
 * CDVR_CL_HOST_MINMAX=0. */
static int host_minmax(cdvr_cl_stream *s, size_t frame)
{
    if (s->cl->info.is_gpu || s->fetch || cdvr_cl_env_is("CDVR_CL_HOST_MINMAX", "0"))
        return 0;
    cl_int code;
    cl_mem mem = cdvr_cl_frames_mem(s);
    void *voxels = clEnqueueMapBuffer(s->cl->queue, mem, CL_TRUE, CL_MAP_READ, frame * s->voxels,
                                      s->voxels, 0, NULL, NULL, &code);
    if (code != CL_SUCCESS || !voxels)
        return 0;
    cdvr_error ignored;
    int ok = cdvr_cpu_brick_ranges(voxels, s->dims, CDVR_CL_BRICK_SHIFT, 0, s->grid.minmax,
                                   &ignored) == CDVR_OK;
    ok &= clEnqueueUnmapMemObject(s->cl->queue, mem, voxels, 0, NULL, NULL) == CL_SUCCESS;
    return ok && write_buffer(s->cl, s->brick_minmax, s->grid.minmax, 2 * s->nbricks,
                              "upload brick min/max grid", &ignored) == CDVR_OK;
}

/* The brick_minmax kernel on device frame `frame`, its grid read back into s->grid.minmax. */
static cdvr_status kernel_minmax(cdvr_cl_stream *s, size_t frame, cdvr_error *err)
{
    voxel_source src;
    cdvr_status st = source_of(s, frame, &src, err);
    if (st)
        return st;
    cl_kernel k = src.k_bricks;
    cl_uint args[7] = {(cl_uint)s->dims[0], (cl_uint)s->dims[1], (cl_uint)s->dims[2],
                       CDVR_CL_BRICK, (cl_uint)s->brick_dims[0], (cl_uint)s->brick_dims[1],
                       (cl_uint)s->brick_dims[2]};
    st = set_source_args(k, "brick_minmax", &src, err);
    for (cl_uint i = 0; !st && i < 7; i++)
        st = cdvr_cl_arg(k, "brick_minmax", 3 + i, sizeof(cl_uint), &args[i], err);
    if (!st)
        st = cdvr_cl_arg(k, "brick_minmax", 10, sizeof(cl_mem), &s->brick_minmax, err);
    if (!st)
        st = run_kernel(s->cl, k, 1, &s->nbricks, NULL, "brick_minmax kernel", err);
    if (st)
        return st;
    cl_int code = clEnqueueReadBuffer(s->cl->queue, s->brick_minmax, CL_TRUE, 0, 2 * s->nbricks,
                                      s->grid.minmax, 0, NULL, NULL);
    return cdvr_cl_check(code, "read brick min/max grid", err);
}

/* Min/max of every brick of device frame `frame` into s->grid.minmax and brick_minmax (the
 * blocks' ranges follow when a render needs them, set_raycast_args). */
static cdvr_status compute_minmax(cdvr_cl_stream *s, size_t frame, cdvr_error *err)
{
    if (s->only_tiles)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL setup: frame %zu is only a tiled copy "
                              "(cdvr_cl_use_host_tiles): its grid comes from the caller "
                              "(cdvr_cl_setup_grid)", frame);
    cdvr_status st = host_minmax(s, frame) ? CDVR_OK : kernel_minmax(s, frame, err);
    cdvr_skip_grid_touch(&s->grid);
    s->minmax_count++;
    s->blocks_valid = 0;
    return st;
}

/* Cells of the entry list (cdvr/skip.h): 2^2 bricks of 4 voxels per axis. */
#define ENTRY_CELL_LOG2 2

/* Makes *e the entry list of the stream's ranges with `flags` (cdvr_skip_flags_into's) in
 * place of the grid's own; returns 1 when it holds it. */
static int entry_list_of(const cdvr_cl_stream *s, uint8_t *flags, cdvr_skip_entry *e)
{
    cdvr_skip_grid g = s->grid;
    g.flags = flags;
    g.flags_valid = 1;
    cdvr_error ignored;
    return cdvr_skip_entry_make(e, &g, ENTRY_CELL_LOG2, &ignored) == CDVR_OK;
}

/* Puts the nbricks flags into device buffer *buf (made on first use). Returns 1 on success;
 * on failure the render goes without them. */
static int flags_uploaded(cdvr_cl_stream *s, cl_mem *buf, const uint8_t *flags, const char *what)
{
    cdvr_error ignored;
    size_t bytes = s->nbricks + CDVR_CL_FLAGS_PAD, cap = *buf ? bytes : 0;
    return cdvr_cl_ensure_buffer(s->cl, buf, &cap, bytes, CL_MEM_READ_ONLY, what,
                                 &ignored) == CDVR_OK &&
           write_buffer(s->cl, *buf, flags, s->nbricks, what, &ignored) == CDVR_OK;
}

/* Iso skipping (raycast.cl, march_iso): iso_flags gets the flags of the set-up frame's ranges
 * for the one code floor(code): a brick whose (whole-code) range [lo, hi] can hold the iso
 * code has lo <= floor(code) <= hi, so one without lies strictly on one side of it. Made
 * again only when the ranges or that code change. Returns 1 when iso_flags holds them; 0
 * (the iso render then takes every sample) when the ranges on the host are another grid's
 * (cdvr_cl_setup_grid) or on any failure. */
static int iso_flags_ready(cdvr_cl_stream *s, size_t frame, float code)
{
    if (!s->skipping || s->grid_uploaded || s->minmax_frame != frame || !s->minmax_count)
        return 0;
    double whole = floor(code); /* outside 0..255: no sample can reach the code */
    int mark = whole >= 0 && whole <= 255 ? (int)whole : -1;
    if (s->iso_minmax == s->minmax_count && s->iso_mark == mark)
        return 1;
    s->iso_minmax = 0;
    uint8_t *flags = malloc(s->nbricks);
    if (!flags)
        return 0;
    uint8_t marks[256] = {0};
    if (mark >= 0)
        marks[mark] = 1;
    cdvr_skip_flags_into(&s->grid, marks, flags);
    int uploaded = flags_uploaded(s, &s->iso_flags, flags, "iso brick flags");
    s->iso_entry_ok = uploaded && entry_list_of(s, flags, &s->iso_entry);
    free(flags);
    if (!uploaded)
        return 0;
    s->iso_minmax = s->minmax_count;
    s->iso_mark = mark;
    return 1;
}

/* Max and average (raycast.cl, march_extreme): the entry list of the set-up frame's bricks
 * whose range holds a code above 0, for entry and exit bounds: samples outside them lie in
 * bricks of zeros and are 0 (average: they add nothing to the sum and count in the mean; max:
 * its extreme is at least 0), and those bricks' flags in zero_flags (average's leaps over
 * cubes of zeros inside the bounds; zero_flags_ok says whether it holds them). Made again
 * only when the ranges change. Returns 1 when zero_entry holds the list; 0 (the render then
 * skips brick by brick) as iso_flags_ready. */
static int zero_entry_ready(cdvr_cl_stream *s, size_t frame)
{
    if (!s->skipping || s->grid_uploaded || s->minmax_frame != frame || !s->minmax_count)
        return 0;
    if (s->zero_minmax == s->minmax_count)
        return s->zero_entry_ok;
    s->zero_flags_ok = 0;
    uint8_t *flags = malloc(s->nbricks);
    if (!flags)
        return 0;
    uint8_t above_zero[256];
    memset(above_zero, 1, sizeof above_zero);
    above_zero[0] = 0;
    cdvr_skip_flags_into(&s->grid, above_zero, flags);
    s->zero_entry_ok = entry_list_of(s, flags, &s->zero_entry);
    /* without the flags average reads its whole window */
    s->zero_flags_ok = flags_uploaded(s, &s->zero_flags, flags, "zero brick flags");
    free(flags);
    s->zero_minmax = s->minmax_count;
    return s->zero_entry_ok;
}

/* Uploads the flags of grid g and takes its visible box, count and entry list. */
static cdvr_status use_grid(cdvr_cl_stream *s, const cdvr_skip_grid *g, cdvr_error *err)
{
    s->bricks_visible = g->bricks_visible;
    for (int a = 0; a < 3; a++) {
        s->visible_lo[a] = g->visible_lo[a];
        s->visible_hi[a] = g->visible_hi[a];
    }
    cdvr_error ignored; /* without the list rays start at the visible box, as without a camera */
    s->entry_ok = cdvr_skip_entry_make(&s->entry, g, ENTRY_CELL_LOG2, &ignored) == CDVR_OK;
    return write_buffer(s->cl, s->brick_visible, g->flags, s->nbricks, "upload brick flags",
                        err);
}

/* The min/max grid is computed once per decoded frame; the flags again only when the set of
 * TF entries with alpha > 0 changes. */
cdvr_status cdvr_cl_setup(cdvr_cl_stream *s, size_t frame, const cdvr_tf *tf, cdvr_error *err)
{
    s->setup_frame = (size_t)-1;
    if (!tf)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL setup: no transfer function");
    if (frame >= s->frames_valid)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL setup: frame %zu not decoded (%zu frames)",
                              frame, s->frames_valid);
    s->tf = *tf;
    cdvr_status st = CDVR_OK;
    if (s->minmax_frame != frame) {
        s->minmax_valid = 0;
        st = compute_minmax(s, frame, err);
        if (st)
            return st;
        s->minmax_frame = frame;
    }
    s->minmax_valid = 1;
    s->pending_minmax = NULL;
    if (cdvr_skip_flags(&s->grid, tf) || s->grid_uploaded != 0) {
        st = use_grid(s, &s->grid, err);
        if (st) {
            cdvr_skip_grid_touch(&s->grid);
            return st;
        }
        s->grid_uploaded = 0;
    }
    s->setup_frame = frame;
    return CDVR_OK;
}

cdvr_status cdvr_cl_setup_grid(cdvr_cl_stream *s, size_t frame, const cdvr_tf *tf,
                               const cdvr_skip_grid *g, cdvr_error *err)
{
    s->setup_frame = (size_t)-1;
    if (!tf || !g)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL setup: no transfer function or grid");
    if (frame >= s->frames_valid)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL setup: frame %zu not decoded (%zu frames)",
                              frame, s->frames_valid);
    unsigned char visible[256];
    for (int i = 0; i < 256; i++)
        visible[i] = tf->table[i][3] > 0.0f;
    if (g->shift != CDVR_CL_BRICK_SHIFT || g->nbricks != s->nbricks ||
        memcmp(g->dims, s->brick_dims, sizeof g->dims) != 0 || !g->flags_valid ||
        memcmp(visible, g->tf_visible, sizeof visible) != 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL setup: the grid (bricks of 2^%u, "
                              "%zux%zux%zu, flags %s) does not fit this stream and TF", g->shift,
                              g->dims[0], g->dims[1], g->dims[2],
                              g->flags_valid ? "made for another TF" : "not made");
    s->tf = *tf;
    cdvr_status st = use_grid(s, g, err);
    if (st)
        return st;
    s->grid_uploaded = 1; /* brick_visible no longer holds s->grid's flags */
    /* the grid's ranges, uploaded only when a max or min render of this frame asks for them
     * (pending_minmax: the caller keeps g until then); brick_minmax no longer holds s->grid's
     * (a later cdvr_cl_setup computes them again) */
    s->minmax_frame = (size_t)-1;
    s->minmax_valid = s->blocks_valid = 0;
    s->pending_minmax = g->minmax;
    s->setup_frame = frame;
    return CDVR_OK;
}

void cdvr_cl_set_skipping(cdvr_cl_stream *s, int enabled)
{
    s->skipping = enabled != 0;
}

uint64_t cdvr_cl_last_samples(const cdvr_cl_stream *s)
{
    return s->last_samples;
}

void cdvr_cl_brick_counts(const cdvr_cl_stream *s, size_t *visible, size_t *total)
{
    if (visible)
        *visible = s->bricks_visible;
    if (total)
        *total = s->nbricks;
}

/* camera.h's basis: f = normalize(center - eye), u = up orthogonalised to f, r = f x u. */
static cdvr_status camera_params(const cdvr_camera *cam, cam_params *out, cdvr_error *err)
{
    double f[3], u[3], r[3], fl = 0, dot = 0, ul = 0;
    for (int i = 0; i < 3; i++) {
        f[i] = cam->center[i] - cam->eye[i];
        fl += f[i] * f[i];
    }
    if (!(cam->width > 0 && cam->height > 0 && cam->fov > 0 && cam->fov < 180 && fl > 0))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: invalid camera (size %dx%d, fov %g)",
                              cam->width, cam->height, cam->fov);
    for (int i = 0; i < 3; i++)
        f[i] /= sqrt(fl);
    for (int i = 0; i < 3; i++)
        dot += cam->up[i] * f[i];
    for (int i = 0; i < 3; i++) {
        u[i] = cam->up[i] - dot * f[i];
        ul += u[i] * u[i];
    }
    if (!(ul > 1e-24))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: camera up is parallel to the view");
    for (int i = 0; i < 3; i++)
        u[i] /= sqrt(ul);
    r[0] = f[1] * u[2] - f[2] * u[1];
    r[1] = f[2] * u[0] - f[0] * u[2];
    r[2] = f[0] * u[1] - f[1] * u[0];
    for (int i = 0; i < 3; i++) {
        out->eye[i] = (cl_float)cam->eye[i];
        out->f[i] = (cl_float)f[i];
        out->u[i] = (cl_float)u[i];
        out->r[i] = (cl_float)r[i];
    }
    out->tan_half = (cl_float)tan(cam->fov * M_PI / 360.0);
    out->aspect = (cl_float)((double)cam->width / cam->height);
    out->ortho_half_height = (cl_float)(cam->ortho_height / 2);
    out->orthographic = cam->orthographic != 0;
    out->width = cam->width;
    out->height = cam->height;
    return CDVR_OK;
}

/* Pixels per work-item (kernels/render/raycast.cl marches a packet of PACKET_W x PACKET_H
 * neighbouring rays in lock-step) and the work-group in work-items: neighbouring rays share
 * voxels and bricks in cache. On a GPU 8 x 8 work-items fill a wave; a CPU device runs a
 * work-group on one thread, and there small groups (2 x 2 packets: 8 x 8 pixels) balance the
 * threads: with 8 x 8 packets PoCL on 2 threads rendered the engine CT at 512^2 in 1.45x its
 * one-thread time, with 2 x 2 in 1.95x (scripts/bench/vs_vtk.py's scene). */
#define PACKET_W CDVR_CL_PACKET_W
#define PACKET_H CDVR_CL_PACKET_H
#define RAY_GROUP_GPU 8
#define RAY_GROUP_CPU 2

static size_t round_up(size_t n, size_t m)
{
    return (n + m - 1) / m * m;
}

typedef struct render_params {
    double step, unit, term_alpha;
} render_params;

/* render.h defaults: step 0.5 min(spacing), unit from opts, TF or min(spacing), term 0.99. */
static render_params resolve(const cdvr_render_opts *opts, const cdvr_tf *tf, const double spacing[3])
{
    double min_spacing = fmin(spacing[0], fmin(spacing[1], spacing[2]));
    const cdvr_tf *unit_tf = opts->tf ? opts->tf : tf;
    render_params rp;
    rp.step = opts->step > 0 ? opts->step : 0.5 * min_spacing;
    rp.unit = opts->unit > 0 ? opts->unit : unit_tf->unit > 0 ? unit_tf->unit : min_spacing;
    rp.term_alpha = opts->term_alpha > 0 ? opts->term_alpha : 0.99;
    return rp;
}

/* x in [0, 1] (clamped) as the nearest of 0 .. top (raycast.cl TF rows). */
static uint64_t unorm(float x, unsigned top)
{
    double q = floor((x < 0 ? 0 : x > 1 ? 1 : (double)x) * top + 0.5);
    return (uint64_t)q;
}

/* The TF rows the kernel reads (raycast.cl classify): one 64-bit word per entry, the
 * step-corrected alpha (full segments) as a float in bits 0-31, and r, g, b as unsigned
 * normalised 11, 11 and 10 bits in bits 32-42, 43-53, 54-63 (q / 2047, q / 1023 in the
 * kernel), so a lane's two rows are two 64-bit gathers instead of four (engine CT 512^2 step
 * 0.5: 0.87 of the time with two gathers fewer). Colour is then within 2.5e-4 (r, g) and
 * 4.9e-4 (b) of the TF's, an eighth of an 8-bit step; alpha is exact. The exact rows as
 * floats beside them (r, g, b, alpha per unit): the shorter last segment's and shading's
 * alpha, and the colours of max, min, average and iso. */
static cdvr_status upload_tables(cdvr_cl_stream *s, render_params rp, cdvr_error *err)
{
    cl_ulong table[256];
    cl_float rows[256][4];
    for (int i = 0; i < 256; i++) {
        const float *row = s->tf.table[i];
        cl_float stepped = (cl_float)(1.0 - pow(1.0 - row[3], rp.step / rp.unit));
        uint32_t bits;
        memcpy(&bits, &stepped, sizeof bits);
        table[i] = (cl_ulong)bits | unorm(row[0], 2047) << 32 | unorm(row[1], 2047) << 43 |
                   unorm(row[2], 1023) << 54;
        for (int c = 0; c < 4; c++)
            rows[i][c] = row[c];
    }
    cdvr_status st = write_buffer(s->cl, s->table, table, sizeof table, "upload TF table", err);
    if (!st)
        st = write_buffer(s->cl, s->tf_rows, rows, sizeof rows, "upload TF rows", err);
    return st;
}

/* The direction matrix D a render uses: direction, or the identity when that is NULL or all
 * zeros (as cdvr_volume_direction). */
static void box_direction(const double direction[9], double D[9])
{
    int zero = 1;
    for (int i = 0; direction && i < 9; i++)
        zero &= direction[i] == 0.0;
    for (int i = 0; i < 9; i++)
        D[i] = direction && !zero ? direction[i] : (i % 4 == 0 ? 1.0 : 0.0);
}

/* render.h step 0: origin and D^-1 (computed in double, rounded to float); 0 if D is singular
 * or not finite. */
static int make_box_frame(const double origin[3], const double D[9], box_frame *out)
{
    double inv[9];
    if (!cdvr_mat3_inverse(D, inv))
        return 0;
    for (int i = 0; i < 3; i++)
        out->origin[i] = (cl_float)origin[i];
    for (int i = 0; i < 9; i++)
        out->inv_dir[i] = (cl_float)inv[i];
    return 1;
}

/* The kernel's clip argument for opts->clip (render.h; enabled 0 without one). */
static clip_params clip_params_of(const cdvr_render_clip *c)
{
    clip_params k;
    memset(&k, 0, sizeof k);
    k.enabled = c != NULL;
    for (int a = 0; c && a < 3; a++) {
        k.offset[a] = (cl_float)c->offset[a];
        k.whole_top[a] = (cl_float)(c->whole_dims[a] - 1);
        k.own_lo[a] = (cl_float)c->own_lo[a];
        k.own_hi[a] = (cl_float)c->own_hi[a];
        k.own_far[a] = c->own_hi[a] + 1 == c->whole_dims[a];
    }
    return k;
}

/* The look of render.h in the kernel's terms (cl_shared.h), for the stream's TF window, the
 * volume's box frame (its D^-1, made by make_box_frame) and spacing. */
static cdvr_cl_look look_of(const cdvr_look *look, const cdvr_tf *tf, const box_frame *box,
                            const double spacing[3])
{
    cdvr_cl_look k;
    memset(&k, 0, sizeof k);
    const cdvr_shading *sh = &look->shade;
    k.blend = look->blend;
    k.shade = sh->enabled;
    k.headlight = !sh->light_fixed;
    k.ambient = (cl_float)sh->ambient;
    k.diffuse = (cl_float)sh->diffuse;
    k.specular = (cl_float)sh->specular;
    k.power = (cl_float)sh->specular_power;
    double len = sqrt(sh->light_dir[0] * sh->light_dir[0] + sh->light_dir[1] * sh->light_dir[1] +
                      sh->light_dir[2] * sh->light_dir[2]);
    for (int a = 0; a < 3; a++) {
        k.light[a] = len > 0.0 ? (cl_float)(-sh->light_dir[a] / len) : 0.0f;
        k.spacing[a] = (cl_float)spacing[a];
    }
    for (int r = 0; r < 3; r++) /* (D^-1)^T from the box frame's D^-1 */
        for (int c = 0; c < 3; c++)
            k.grad_to_world[3 * r + c] = box->inv_dir[3 * c + r];
    double width = tf->window[1] - tf->window[0];
    k.value_per_code = (cl_float)(width / 255.0);
    k.go_points = (cl_int)look->gradient_opacity.npoints;
    for (int i = 0; i < k.go_points && i < CDVR_CL_GO_MAX; i++) {
        k.go_mag[i] = (cl_float)look->gradient_opacity.magnitude[i];
        k.go_factor[i] = (cl_float)look->gradient_opacity.factor[i];
    }
    k.iso_code = width > 0.0 ? (cl_float)((look->iso_value - tf->window[0]) * 255.0 / width) : 0.0f;
    k.iso_tf_color = !look->iso_color_set;
    for (int c = 0; c < 3; c++)
        k.iso_rgb[c] = look->iso_color[c];
    k.iso_alpha = look->iso_opacity > 0.0 ? (cl_float)look->iso_opacity : 1.0f;
    return k;
}

/* The entry tiles of this render in s->entry_tiles (one per packet: global work-items; for
 * max and average the exit tiles follow them), made again only when the camera, the
 * volume's placement or the flags change. Returns 1 when the kernel may start its rays there;
 * 0 leaves a buffer for the argument all the same. */
static int entry_tiles_ready(cdvr_cl_stream *s, const cam_params *cam, const double spacing[3],
                             const double origin[3], const double D[9], const size_t global[2],
                             int wanted, cdvr_cl_entry_kind kind)
{
    /* in the order of cdvr_cl_entry_kind */
    const cdvr_skip_entry *lists[] = {&s->entry, &s->iso_entry, &s->zero_entry};
    const int lists_ok[] = {s->entry_ok, s->iso_entry_ok, s->zero_entry_ok};
    const cdvr_skip_entry *entry = lists[kind];
    int entry_ok = lists_ok[kind];
    int with_exit = kind == CDVR_CL_ENTRY_ZEROS;
    size_t tiles = global[0] * global[1], bytes = (1 + with_exit) * tiles * sizeof(float);
    cdvr_error ignored;
    size_t capacity = s->entry_capacity;
    if (cdvr_cl_ensure_buffer(s->cl, &s->entry_tiles, &s->entry_capacity, wanted ? bytes : 4,
                              CL_MEM_READ_ONLY, "entry tiles", &ignored) != CDVR_OK) {
        s->entry_made.valid = 0;
        return 0;
    }
    if (s->entry_capacity != capacity) /* a new buffer: its contents are gone */
        s->entry_made.valid = 0;
    if (!wanted || !entry_ok)
        return 0;
    cdvr_cl_entry_made made;
    memset(&made, 0, sizeof made); /* padding too: compared with memcmp */
    cdvr_skip_view *v = &made.view;
    for (int a = 0; a < 3; a++) {
        v->eye[a] = cam->eye[a];
        v->f[a] = cam->f[a];
        v->u[a] = cam->u[a];
        v->r[a] = cam->r[a];
        v->origin[a] = origin[a];
        v->spacing[a] = spacing[a];
    }
    memcpy(v->direction, D, sizeof v->direction);
    v->tan_half = cam->tan_half;
    v->aspect = cam->aspect;
    v->ortho_half_height = cam->ortho_half_height;
    v->orthographic = cam->orthographic;
    v->width = cam->width;
    v->height = cam->height;
    made.version = entry->version;
    made.kind = kind;
    made.tiles[0] = global[0];
    made.tiles[1] = global[1];
    made.valid = 1;
    if (!memcmp(&made, &s->entry_made, sizeof made))
        return 1;
    s->entry_made.valid = 0;
    float *map = malloc(bytes);
    int usable = map && cdvr_skip_entry_exit_tiles(entry, v, PACKET_W, PACKET_H, global[0],
                                                   global[1], map, with_exit ? map + tiles : NULL);
    usable = usable && write_buffer(s->cl, s->entry_tiles, map, bytes, "upload entry tiles",
                                    &ignored) == CDVR_OK;
    free(map);
    if (usable)
        memcpy(&s->entry_made, &made, sizeof made); /* with its padding: memcmp above */
    return usable;
}

/* Whether a render of `look` reads gradients (the gradient copy wants the tiled one). */
static int wants_grads(const cdvr_look *look)
{
    return look->shade.enabled || look->gradient_opacity.npoints > 0;
}

/* Whether a render that reads gradients (grads) or not casts from the tiled copy of a frame
 * that has one: not where the device keeps frames dense (info.dense_frames), unless it reads
 * gradients (cdvr_cl_tiles_fit), the tiles are the only copy (cdvr_cl_use_host_tiles) or it
 * reads the quad copy of a frame rendered again (quads_still, still_quads). */
static int casts_tiled(const cdvr_cl_stream *s, int grads, int quads_still)
{
    return !s->cl->info.dense_frames || grads || s->only_tiles || quads_still;
}

/* Sets the ray-cast kernel's arguments (in the order of kernels/render/raycast.cl). A clipped
 * render casts the whole volume's rays and skips no empty space (the brick grid describes
 * the stream's own voxels only). flags_skip: iso skips by iso_flags, average leaps by
 * zero_flags (the kernel's brick flags are then those). tiled: the samples come from the
 * frame's tiled copy where it has one (casts_tiled). */
static cdvr_status set_raycast_args(cdvr_cl_stream *s, size_t frame, render_params rp,
                                    const cam_params *cam, const cdvr_render_clip *clip,
                                    const double spacing[3], const box_frame *box,
                                    const cdvr_cl_look *look, int flags_skip, cl_mem image,
                                    cl_int entry_on, cl_int entry_tiles_x, cl_int grads_on,
                                    cl_int quads_on, int tiled, cl_kernel *kernel,
                                    cdvr_error *err)
{
    voxel_source src;
    cdvr_status sst = source_of(s, frame, &src, err);
    if (sst)
        return sst;
    if (!s->fetch && s->tiles_frame == frame && tiled) {
        src.vol = s->tiles;
        src.offset = 0;
        src.tiled = 1;
    }
    cl_kernel k = *kernel = src.k_raycast;
    cl_int ints[3] = {(cl_int)s->dims[0], (cl_int)s->dims[1], (cl_int)s->dims[2]};
    cl_float geo[6]; /* 1/spacing, then the box's upper corner in the box frame */
    for (int i = 0; i < 3; i++) {
        size_t whole = clip ? clip->whole_dims[i] : s->dims[i];
        geo[i] = (cl_float)(1.0 / spacing[i]);
        geo[3 + i] = (cl_float)((double)(whole - 1) * spacing[i]);
    }
    clip_params kclip = clip_params_of(clip);
    cl_int bricks[5] = {CDVR_CL_BRICK_SHIFT, (cl_int)s->brick_dims[0], (cl_int)s->brick_dims[1],
                        (cl_int)s->brick_dims[2], s->skipping && !clip};
    cl_mem flags = s->brick_visible;
    /* iso: skipping by the iso code's flags, or none; average: leaps by the zero flags */
    if (look->blend == CDVR_BLEND_ISO || look->blend == CDVR_BLEND_AVERAGE) {
        bricks[4] = flags_skip;
        if (flags_skip)
            flags = look->blend == CDVR_BLEND_ISO ? s->iso_flags : s->zero_flags;
    }
    cl_float step = (cl_float)rp.step, term_alpha = (cl_float)rp.term_alpha;
    cl_float unit = (cl_float)rp.unit;
    int extreme = look->blend == CDVR_BLEND_MAX || look->blend == CDVR_BLEND_MIN ||
                  look->blend == CDVR_BLEND_AVERAGE;
    cdvr_error ignored; /* without the ranges these modes just take every sample */
    if (extreme && !s->minmax_valid && s->pending_minmax) {
        s->minmax_valid = write_buffer(s->cl, s->brick_minmax, s->pending_minmax, 2 * s->nbricks,
                                       "upload brick ranges", &ignored) == CDVR_OK &&
                          upload_block_ranges(s, s->pending_minmax, &ignored) == CDVR_OK;
        s->blocks_valid = s->minmax_valid;
        s->pending_minmax = NULL;
    }
    if (extreme && s->minmax_valid && !s->blocks_valid) /* the device's ranges, on the host */
        s->blocks_valid = upload_block_ranges(s, s->grid.minmax, &ignored) == CDVR_OK;
    /* skip=false: max, min and average take every sample too */
    cl_int minmax_valid = s->minmax_valid && s->blocks_valid && s->setup_frame == frame &&
                          s->skipping;
    /* (size, value) of arguments 3.. in kernel order */
    struct {
        size_t size;
        const void *value;
    } args[] = {{sizeof src.tiled, &src.tiled},
                {sizeof(cl_int), &ints[0]},   {sizeof(cl_int), &ints[1]},
                {sizeof(cl_int), &ints[2]},   {sizeof *box, box},
                {sizeof(cl_float), &geo[0]},  {sizeof(cl_float), &geo[1]},
                {sizeof(cl_float), &geo[2]},  {sizeof(cl_float), &geo[3]},
                {sizeof(cl_float), &geo[4]},  {sizeof(cl_float), &geo[5]},
                {sizeof step, &step},         {sizeof term_alpha, &term_alpha},
                {sizeof *cam, cam},           {sizeof kclip, &kclip},
                {sizeof(cl_mem), &s->table},
                {sizeof(cl_mem), &s->tf_rows}, {sizeof unit, &unit},
                {sizeof(cl_mem), &flags},     {sizeof(cl_int), &bricks[0]},
                {sizeof(cl_int), &bricks[1]}, {sizeof(cl_int), &bricks[2]},
                {sizeof(cl_int), &bricks[3]}, {sizeof(cl_int), &bricks[4]},
                {sizeof(cl_float), &s->visible_lo[0]}, {sizeof(cl_float), &s->visible_lo[1]},
                {sizeof(cl_float), &s->visible_lo[2]}, {sizeof(cl_float), &s->visible_hi[0]},
                {sizeof(cl_float), &s->visible_hi[1]}, {sizeof(cl_float), &s->visible_hi[2]},
                {sizeof(cl_mem), &image},     {sizeof(cl_mem), &s->samples},
                {sizeof *look, look},         {sizeof(cl_mem), &s->brick_minmax},
                {sizeof(cl_int), &minmax_valid}, {sizeof(cl_mem), &s->entry_tiles},
                {sizeof entry_tiles_x, &entry_tiles_x}, {sizeof entry_on, &entry_on},
                {sizeof(cl_mem), &s->grads},  {sizeof grads_on, &grads_on},
                {sizeof(cl_mem), &s->quads},  {sizeof quads_on, &quads_on}};
    cdvr_status st = set_source_args(k, "raycast", &src, err);
    for (cl_uint i = 0; !st && i < sizeof args / sizeof *args; i++)
        st = cdvr_cl_arg(k, "raycast", 3 + i, args[i].size, args[i].value, err);
    return st;
}

/* A frame rendered a second time (a scene shown again: another camera, TF or step) gets its
 * tiled copy (kernels/common/cl_shared.h), which the ray caster reads from fewer cache lines:
 * a byte per voxel in whole pages of 16^3, so only below 2^31 bytes and when the device takes
 * the buffer. Playback renders each frame once and never pays for it. On any failure the
 * frame is simply rendered from its voxels. */
/* Bytes of the tiled copy of a frame of dims (whole pages, codec.h); SIZE_MAX on overflow. */
static size_t tiled_bytes(const size_t dims[3])
{
    size_t n = cdvr_tiled_bytes(dims);
    return n ? n : SIZE_MAX;
}

/* Makes *mem (of `bytes`) the copy of `frame` that copy kernel k makes (make_tiles,
 * make_grads or make_quads in bricks.cl: frames, offset, X, Y, Z, out; a work-item per tile
 * of the tiled copy), unless *copy_frame says it holds it already; *copy_frame records the
 * frame made. Returns 1 when *mem holds the copy; on any failure *mem is released (the render
 * then reads the voxels). */
static int copy_ready(cdvr_cl_stream *s, size_t frame, cl_kernel k, const char *name,
                      cl_mem *mem, size_t *capacity, size_t *copy_frame, size_t bytes)
{
    if (*copy_frame == frame)
        return 1;
    cdvr_error err;
    size_t tiles = tiled_bytes(s->dims) / 64;
    cl_ulong offset = frame * s->voxels;
    cl_mem frames = cdvr_cl_frames_mem(s);
    cl_uint d[3] = {(cl_uint)s->dims[0], (cl_uint)s->dims[1], (cl_uint)s->dims[2]};
    cdvr_status st = cdvr_cl_ensure_gathered(s->cl, mem, capacity, bytes, name, &err);
    if (!st)
        st = cdvr_cl_arg(k, name, 0, sizeof(cl_mem), &frames, &err);
    if (!st)
        st = cdvr_cl_arg(k, name, 1, sizeof offset, &offset, &err);
    for (cl_uint i = 0; !st && i < 3; i++)
        st = cdvr_cl_arg(k, name, 2 + i, sizeof(cl_uint), &d[i], &err);
    if (!st)
        st = cdvr_cl_arg(k, name, 5, sizeof(cl_mem), mem, &err);
    if (!st)
        st = run_kernel(s->cl, k, 1, &tiles, NULL, name, &err);
    if (st) {
        cdvr_cl_release(mem);
        *capacity = 0;
    }
    *copy_frame = st ? (size_t)-1 : frame;
    return st == CDVR_OK;
}

static void make_tiles_if_rerendered(cdvr_cl_stream *s, size_t frame, int grads,
                                     int quads_still)
{
    int again = s->last_rendered == frame;
    s->last_rendered = frame;
    if (s->fetch || !again || !(cdvr_cl_takes_host_tiles(s, grads) || quads_still))
        return;
    copy_ready(s, frame, s->cl->k_tiles, "make_tiles", &s->tiles, &s->tiles_capacity,
               &s->tiles_frame, tiled_bytes(s->dims));
}

/* The largest copy of 4 bytes per voxel made (gradients, quads: a frame of 512 M voxels):
 * beyond it the gradients come from the tiled copy's 12 rows per sample (engine CT: 1.8x the
 * time per gradient), the samples from its 8 rows. */
#define WORD_COPY_MAX_BYTES ((size_t)2 << 30)

/* With the tiled copy of `frame`, a render that shades (or uses gradient opacity) gets the
 * frame's gradient copy (kernels/common/cl_shared.h): 4 bytes per voxel of the tiled copy,
 * read as 8 words per gradient instead of 32 voxels from 12 tile rows (raycast.cl). Off with
 * CDVR_CL_GRADS=0; on any failure the gradients come from the voxels. Returns 1 when the
 * render reads it. */
static int grads_ready(cdvr_cl_stream *s, size_t frame, const cdvr_look *look)
{
    int wanted = wants_grads(look);
    size_t bytes;
    if (s->tiles_frame != frame || !wanted || s->only_tiles ||
        cdvr_cl_env_is("CDVR_CL_GRADS", "0") || !cdvr_size_mul(tiled_bytes(s->dims), 4, &bytes) ||
        bytes > WORD_COPY_MAX_BYTES)
        return 0;
    return copy_ready(s, frame, s->cl->k_grads, "make_grads", &s->grads, &s->grads_capacity,
                      &s->grads_frame, bytes);
}

/* The largest quad copy made by default, CDVR_CL_QUADS_MAX_BYTES (device.h: a frame of 16 M
 * voxels, 256^3): on the CPU device (PoCL, 2 cores of an AMD EPYC, 2 MB L2 each;
 * cdvr.generate("ml") at 512^2, step 0.5) it took composite, average and max at 192^3 from
 * 23.8, 42.5 and 31.9 ms to 20.7, 30.6 and 27.1 ms, at 256^3 from 32.1, 58.2 and 41.2 to 26.5,
 * 47.0 and 39.1 ms, the engine CT's average from 36.8 to 28.7 ms; at 320^3 (131 MB) composite
 * and max were even, and on Colin27 (149 MB) average and max took 1.4x the time of the tiled
 * copy: beyond this its cache misses cost more than its six fewer gathers per sample save.
 * On 2 cores of an Intel Xeon (2 MB L2 each, 260 MB L3) the same Colin27 copy took composite
 * to 0.84 of the time, average to 0.74, shaded 0.95 and max even (512^2, step 0.5, per-process
 * minimums of 30-40 frames, 4-5 alternating pairs), so the limit beyond it is measured per
 * device (cdvr_cl_open, info.quads_max_bytes). Not measured on GPUs, which keep the tiled
 * copy. Iso, whose rays read few samples, took 1.04-1.08x the time with it (engine CT) and
 * keeps the tiled copy. */

/* The rule of quads_ready, whatever copies the stream holds: whether a render of blend mode
 * `blend` reads the quad copy of this stream's frames (*bytes: its size). */
static int quads_allowed(const cdvr_cl_stream *s, int blend, size_t *bytes)
{
    if (s->quads_probe < 0 || cdvr_cl_env_is("CDVR_CL_QUADS", "0") ||
        !cdvr_size_mul(tiled_bytes(s->dims), 4, bytes) || *bytes > WORD_COPY_MAX_BYTES)
        return 0;
    return s->quads_probe > 0 || cdvr_cl_env_is("CDVR_CL_QUADS", "1") ||
           (!s->cl->info.is_gpu && *bytes <= s->cl->info.quads_max_bytes &&
            blend != CDVR_BLEND_ISO);
}

/* With the tiled copy of `frame`, a render of blend mode `blend` (not iso) on a CPU device
 * gets the frame's quad copy (kernels/common/cl_shared.h) when it is at most
 * info.quads_max_bytes: 4 bytes per voxel of the tiled copy, read as 2 words per sample
 * instead of 8 tile rows (the same values). CDVR_CL_QUADS=0 turns it off, =1 on for any
 * device and mode up to WORD_COPY_MAX_BYTES. On any failure the samples come from the tiled
 * copy. Returns 1 when the render reads it. */
static int quads_ready(cdvr_cl_stream *s, size_t frame, int blend)
{
    size_t bytes;
    if (s->tiles_frame != frame || s->only_tiles || !quads_allowed(s, blend, &bytes))
        return 0;
    return copy_ready(s, frame, s->cl->k_quads, "make_quads", &s->quads, &s->quads_capacity,
                      &s->quads_frame, bytes);
}

/* Whether a frame rendered again in blend mode `blend` (unclipped) gets its tiled and quad
 * copies where the device keeps frames dense (info.still_quads: the quad probe beat dense
 * frames), or always on the quad probe's own stream. */
static int still_quads(const cdvr_cl_stream *s, int blend)
{
    size_t bytes;
    if (s->quads_probe)
        return s->quads_probe > 0;
    return s->cl->info.dense_frames && s->cl->info.still_quads && cdvr_cl_tiles_fit(s) &&
           quads_allowed(s, blend, &bytes);
}

/* Device image of `pixels` and one sample counter per work-item (`items`). */
static cdvr_status ensure_image(cdvr_cl_stream *s, size_t pixels, size_t items, cdvr_error *err)
{
    if (s->image && s->image_pixels >= pixels && s->sample_slots >= items)
        return CDVR_OK;
    size_t cap_img = 0, cap_samples = 0;
    cdvr_cl_release(&s->samples);
    s->image_pixels = 0;
    s->sample_slots = 0;
    size_t img_bytes, sample_bytes;
    if (!cdvr_size_mul(pixels, 4 * sizeof(cl_float), &img_bytes) ||
        !cdvr_size_mul(items, sizeof(cl_uint), &sample_bytes))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL render: image of %zu pixels overflows", pixels);
    cdvr_status st = cdvr_cl_ensure_buffer(s->cl, &s->image, &cap_img, img_bytes,
                                           CL_MEM_WRITE_ONLY, "image", err);
    if (!st)
        st = cdvr_cl_ensure_buffer(s->cl, &s->samples, &cap_samples, sample_bytes,
                                   CL_MEM_WRITE_ONLY, "sample counters", err);
    if (st)
        return st;
    s->image_pixels = pixels;
    s->sample_slots = items;
    return CDVR_OK;
}

/* On a device that shares host memory, a buffer over the image's own pixels: the kernel then
 * writes them in place and no copy of the frame is needed. NULL elsewhere, or on failure (the
 * stream's device image is used then). */
static cl_mem wrap_host_image(cdvr_cl *cl, cdvr_image *img, size_t pixels)
{
    cl_bool unified = CL_FALSE;
    if (clGetDeviceInfo(cl->device, CL_DEVICE_HOST_UNIFIED_MEMORY, sizeof unified, &unified,
                        NULL) != CL_SUCCESS || !unified)
        return NULL;
    cl_int code;
    cl_mem mem = clCreateBuffer(cl->context, CL_MEM_WRITE_ONLY | CL_MEM_USE_HOST_PTR,
                                pixels * 4 * sizeof(float), img->rgba, &code);
    return code == CL_SUCCESS ? mem : NULL;
}

/* Makes img hold the pixels of the host image buffer after the queued kernel: a map, which
 * on unified memory gives img's own pixels without a copy. Waits for everything queued. */
static cl_int sync_host_image(cl_command_queue q, cl_mem host_image, cdvr_image *img,
                              size_t bytes)
{
    cl_int code;
    void *mapped = clEnqueueMapBuffer(q, host_image, CL_TRUE, CL_MAP_READ, 0, bytes, 0, NULL,
                                      NULL, &code);
    if (code != CL_SUCCESS)
        return code;
    if (mapped != (void *)img->rgba)
        memcpy(img->rgba, mapped, bytes);
    code = clEnqueueUnmapMemObject(q, host_image, mapped, 0, NULL, NULL);
    cl_int finish_code = clFinish(q); /* the buffer must not touch img once we return */
    return code ? code : finish_code;
}

/* Runs the ray caster and reads the image (from host_image, or the stream's device image if
 * NULL) and the sample counters back, with one wait for the kernel and the reads (the
 * in-order queue keeps the reads behind the kernel). */
static cdvr_status cast_and_read(cdvr_cl_stream *s, cl_kernel kernel, const size_t global[2],
                                 const size_t local[2], cl_mem host_image, cdvr_image *img,
                                 size_t pixels, cdvr_error *err)
{
    size_t items = global[0] * global[1], image_bytes = pixels * 4 * sizeof(float);
    cl_uint *counts = malloc(items * sizeof *counts);
    if (!counts)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL render: out of memory");
    cl_command_queue q = s->cl->queue;
    cl_int code = clEnqueueNDRangeKernel(q, kernel, 2, NULL, global, local, 0, NULL, NULL);
    const char *what = "raycast kernel";
    if (!code) {
        what = "read image";
        code = host_image ? CL_SUCCESS
                          : clEnqueueReadBuffer(q, s->image, CL_FALSE, 0, image_bytes, img->rgba,
                                                0, NULL, NULL);
        cl_int sample_code = code ? code : clEnqueueReadBuffer(q, s->samples, CL_FALSE, 0,
                                                               items * sizeof *counts, counts,
                                                               0, NULL, NULL);
        /* wait even if a read failed to enqueue: the other may still write into our memory */
        cl_int finish_code = host_image ? sync_host_image(q, host_image, img, image_bytes)
                                        : clFinish(q);
        code = code ? code : sample_code ? sample_code : finish_code;
    }
    uint64_t total = 0;
    for (size_t i = 0; code == CL_SUCCESS && i < items; i++)
        total += counts[i];
    free(counts);
    s->last_samples = total;
    return cdvr_cl_check(code, what, err);
}

static cdvr_status check_render_args(const cdvr_cl_stream *s, size_t frame,
                                     const cdvr_render_opts *opts, const double spacing[3],
                                     const double origin[3], const cdvr_image *img,
                                     cdvr_error *err)
{
    if (!opts || !opts->camera || !img)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: camera and image are required");
    if (s->setup_frame != frame)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "OpenCL render: frame %zu has no setup (call cdvr_cl_setup first)", frame);
    for (int i = 0; i < 3; i++)
        if (!(spacing[i] > 0) || !isfinite(spacing[i]) || !isfinite(origin[i]))
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "OpenCL render: spacing %g and origin %g (axis %d) must be finite, "
                                  "spacing positive", spacing[i], origin[i], i);
    if (img->width != opts->camera->width || img->height != opts->camera->height)
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: image %dx%d, camera %dx%d",
                              img->width, img->height, opts->camera->width, opts->camera->height);
    if (!(opts->step >= 0) || !(opts->unit >= 0))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: step and unit must be >= 0");
    const cdvr_render_clip *c = opts->clip;
    for (int a = 0; c && a < 3; a++)
        if (c->whole_dims[a] == 0 || c->whole_dims[a] > (1u << 24) || c->own_lo[a] > c->own_hi[a] ||
            c->own_hi[a] >= c->whole_dims[a] || c->offset[a] > c->own_lo[a] ||
            c->own_hi[a] > c->offset[a] + s->dims[a] - 1)
            return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: clip axis %d: owned cells "
                                  "%zu..%zu of %zu voxels are not inside the %zu voxels from %zu",
                                  a, c->own_lo[a], c->own_hi[a], c->whole_dims[a], s->dims[a],
                                  c->offset[a]);
    return CDVR_OK;
}

cdvr_status cdvr_cl_render(cdvr_cl_stream *s, size_t frame, const cdvr_render_opts *opts,
                           const double spacing[3], const double origin[3],
                           const double direction[9], cdvr_image *img, cdvr_error *err)
{
    cam_params cam;
    box_frame box;
    cdvr_status st = check_render_args(s, frame, opts, spacing, origin, img, err);
    if (!st) /* step, unit, term_alpha: bounded work */
        st = cdvr_render_opts_check_box(opts->clip ? opts->clip->whole_dims : s->dims, spacing, opts, err);
    if (!st)
        st = camera_params(opts->camera, &cam, err);
    if (st)
        return st;
    double D[9];
    box_direction(direction, D);
    if (!make_box_frame(origin, D, &box))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "OpenCL render: volume direction matrix is singular or not finite");
    cdvr_render_opts checked = *opts; /* the look is checked against the stream's TF window */
    checked.tf = &s->tf;
    st = cdvr_render_check_look(&checked, err);
    if (st)
        return st;
    render_params rp = resolve(opts, &s->tf, spacing);
    if (!(rp.step > 0) || !(rp.unit > 0))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: step %g and unit %g must be > 0",
                              rp.step, rp.unit);
    double diagonal = 0;
    for (int a = 0; a < 3; a++)
        diagonal += pow((double)((opts->clip ? opts->clip->whole_dims[a] : s->dims[a]) - 1) *
                        spacing[a], 2);
    /* segment counts are ints, and a work-item sums its packet's counts in 32 bits */
    if (sqrt(diagonal) / rp.step > (double)UINT32_MAX / (PACKET_W * PACKET_H))
        return cdvr_error_set(err, CDVR_ERR_ARG, "OpenCL render: step %g too small for a box of "
                              "diagonal %g", rp.step, sqrt(diagonal));
    size_t pixels = (size_t)img->width * (size_t)img->height;
    size_t group = s->cl->info.is_gpu ? RAY_GROUP_GPU : RAY_GROUP_CPU;
    size_t local[2] = {group, group};
    size_t packets_x = ((size_t)img->width + PACKET_W - 1) / PACKET_W;
    size_t packets_y = ((size_t)img->height + PACKET_H - 1) / PACKET_H;
    size_t global[2] = {round_up(packets_x, local[0]), round_up(packets_y, local[1])};
    st = ensure_image(s, pixels, global[0] * global[1], err);
    if (!st)
        st = upload_tables(s, rp, err);
    if (st)
        return st;
    int grads_wanted = !opts->clip && wants_grads(&opts->look);
    int quads_still = !opts->clip && still_quads(s, opts->look.blend);
    make_tiles_if_rerendered(s, frame, grads_wanted, quads_still);
    cl_mem host_image = wrap_host_image(s->cl, img, pixels);
    cl_kernel kernel;
    cdvr_cl_look look = look_of(&opts->look, &s->tf, &box, spacing);
    int iso = look.blend == CDVR_BLEND_ISO;
    int iso_skip = iso && !opts->clip && iso_flags_ready(s, frame, look.iso_code);
    /* not min: its lanes end at their first brick of zeros anyway (Colin27 512^2: 2.4 -> 1.8
     * ms with a still camera, but 1.9 -> 3.6-4.0 ms with the tiles made again each frame) */
    int zero_bounds = (look.blend == CDVR_BLEND_MAX || look.blend == CDVR_BLEND_AVERAGE) &&
                      !opts->clip && zero_entry_ready(s, frame);
    int entry_wanted = s->skipping && !opts->clip &&
                       (look.blend == CDVR_BLEND_COMPOSITE || iso_skip || zero_bounds);
    cdvr_cl_entry_kind kind = iso           ? CDVR_CL_ENTRY_ISO
                              : zero_bounds ? CDVR_CL_ENTRY_ZEROS
                                            : CDVR_CL_ENTRY_VISIBLE;
    cl_int entry_on = entry_tiles_ready(s, &cam, spacing, origin, D, global, entry_wanted, kind);
    cl_int grads_on = !opts->clip && grads_ready(s, frame, &opts->look);
    int tiled = casts_tiled(s, grads_wanted, quads_still);
    cl_int quads_on = !opts->clip && tiled && quads_ready(s, frame, look.blend);
    /* CDVR_CL_LEAPS=0: average reads its whole window */
    int flags_skip = iso ? iso_skip
                         : look.blend == CDVR_BLEND_AVERAGE && zero_bounds && s->zero_flags_ok &&
                               !cdvr_cl_env_is("CDVR_CL_LEAPS", "0");
    st = set_raycast_args(s, frame, rp, &cam, opts->clip, spacing, &box, &look, flags_skip,
                          host_image ? host_image : s->image, entry_on, (cl_int)global[0],
                          grads_on, quads_on, tiled, &kernel, err);
    if (!st)
        st = cast_and_read(s, kernel, global, local, host_image, img, pixels, err);
    cdvr_cl_release(&host_image);
    if (st)
        return st;
    memcpy(img->background, opts->background, sizeof img->background);
    return CDVR_OK;
}

/* ---- which layout casts faster on this device (cdvr_cl_open) --------------------------- */

/* The probe's frame: PROBE_EDGE^3 voxels, whose tiled copy (288^3) gets no quad copy while
 * info.quads_max_bytes is CDVR_CL_QUADS_MAX_BYTES (its quad copy is 95 MB), so tiles meet the
 * dense frame itself; a smooth field of nested shells, rendered at PROBE_PIXELS^2 through a TF
 * that keeps rays long, as playback is. */
#define PROBE_EDGE 272
#define PROBE_PIXELS 256
#define PROBE_PAIRS 5

static uint8_t *probe_frames(size_t n_edge)
{
    size_t n = n_edge * n_edge * n_edge;
    uint8_t *v = malloc(2 * n);
    if (!v)
        return NULL;
    for (size_t z = 0, i = 0; z < n_edge; z++)
        for (size_t y = 0; y < n_edge; y++)
            for (size_t x = 0; x < n_edge; x++, i++) {
                double f = sin(0.11 * (double)x) * sin(0.13 * (double)y + 1.0) *
                           sin(0.17 * (double)z + 2.0);
                v[i] = (uint8_t)lrint(127.5 + 127.0 * f);
            }
    memcpy(v + n, v, n); /* frame 1 = frame 0: a stream that alternates never tiles */
    return v;
}

/* What every probe renders: its frames, TF, camera and image, and two streams of them. */
typedef struct probe_scene {
    uint8_t *frames;
    cdvr_tf *tf;
    cdvr_camera cam;
    cdvr_image *img;
    cdvr_cl_stream *a, *b;
    size_t next;        /* a's frame to cast next where a casts its two frames in turn */
    uint8_t *tiles[2];  /* b's two frames as a decoder writes them tiled, or NULL */
    cdvr_skip_grid grid; /* their ranges (cdvr_cl_setup_grid), with tiles */
    size_t next_tiles;  /* b's tiled frame to cast next */
} probe_scene;

static void probe_free(probe_scene *p)
{
    cdvr_image_free(p->img);
    cdvr_cl_stream_free(p->a);
    cdvr_cl_stream_free(p->b);
    free(p->tf);
    free(p->frames);
    for (int k = 0; k < 2; k++)
        free(p->tiles[k]);
    cdvr_skip_grid_free(&p->grid); /* zeroed by probe_init where unused */
}

/* Gives b the probe frame twice as the player's decoder writes it for a device that casts
 * from tiles (cdvr_cl_use_host_tiles, CDVR_LAYOUT_TILED; PROBE_EDGE is a whole number of
 * pages), with its ranges and flags for the probe's TF. */
static cdvr_status probe_host_tiles(probe_scene *p, cdvr_error *err)
{
    const size_t dims[3] = {PROBE_EDGE, PROBE_EDGE, PROBE_EDGE};
    cdvr_status st = cdvr_skip_grid_init(&p->grid, dims, CDVR_CL_BRICK_SHIFT, err);
    if (st)
        return st;
    size_t bytes = cdvr_tiled_bytes(dims);
    for (int k = 0; k < 2; k++)
        p->tiles[k] = malloc(bytes);
    if (!p->tiles[0] || !p->tiles[1])
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL layout probe: out of memory");
    for (size_t z = 0, i = 0; z < PROBE_EDGE; z++)
        for (size_t y = 0; y < PROBE_EDGE; y++)
            for (size_t x = 0; x < PROBE_EDGE; x++, i++)
                p->tiles[0][cdvr_tiled_offset(dims, x, y, z)] = p->frames[i];
    memcpy(p->tiles[1], p->tiles[0], bytes);
    st = cdvr_skip_minmax_from_frame(&p->grid, p->frames, err);
    if (!st)
        cdvr_skip_flags(&p->grid, p->tf);
    return st;
}

/* Streams a and b with frames_a and frames_b of the probe frames uploaded (none for b when
 * frames_b is 0: it casts host-tiled frames, probe_host_tiles). */
static cdvr_status probe_init(cdvr_cl *cl, probe_scene *p, size_t frames_a, size_t frames_b,
                              cdvr_error *err)
{
    const size_t dims[3] = {PROBE_EDGE, PROBE_EDGE, PROBE_EDGE};
    const cdvr_tf_point points[] = {{0, 0, 0, 0, 0}, {90, 0.2, 0.3, 0.8, 0},
                                    {160, 0.9, 0.6, 0.3, 0.03}, {255, 1, 1, 1, 0.3}};
    double c = 0.5 * (PROBE_EDGE - 1);
    *p = (probe_scene){.cam = {.eye = {c + 2.2 * PROBE_EDGE, c - 1.3 * PROBE_EDGE,
                                       c + 1.3 * PROBE_EDGE},
                               .center = {c, c, c}, .up = {0, 0, 1}, .fov = 30,
                               .width = PROBE_PIXELS, .height = PROBE_PIXELS}};
    p->frames = probe_frames(PROBE_EDGE);
    p->tf = malloc(sizeof *p->tf);
    cdvr_status st = p->frames && p->tf ? CDVR_OK
                                        : cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL layout "
                                                         "probe: out of memory");
    if (!st)
        st = cdvr_tf_init(p->tf, points, sizeof points / sizeof *points, 0, err);
    if (!st)
        st = cdvr_cl_stream_create(cl, dims, &p->a, err);
    if (!st)
        st = cdvr_cl_stream_create(cl, dims, &p->b, err);
    if (!st)
        st = cdvr_cl_upload_frames(p->a, p->frames, frames_a, err);
    if (!st && frames_b)
        st = cdvr_cl_upload_frames(p->b, p->frames, frames_b, err);
    if (!st)
        st = cdvr_image_create_unset(PROBE_PIXELS, PROBE_PIXELS, &p->img, err);
    return st;
}

/* A timed cast of `frame`, set up untimed: from the caller's grid (frames tiled on the host),
 * or by the stream (grid NULL). */
static cdvr_status probe_render(cdvr_cl_stream *s, size_t frame, const cdvr_render_opts *opts,
                                const cdvr_skip_grid *grid, cdvr_image *img, double *ms,
                                cdvr_error *err)
{
    static const double spacing[3] = {1, 1, 1}, origin[3] = {0, 0, 0},
                        direction[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    cdvr_status st = grid ? cdvr_cl_setup_grid(s, frame, opts->tf, grid, err)
                          : cdvr_cl_setup(s, frame, opts->tf, err);
    double t0 = cdvr_now_ms();
    if (st == CDVR_OK)
        st = cdvr_cl_render(s, frame, opts, spacing, origin, direction, img, err);
    *ms = cdvr_now_ms() - t0;
    return st;
}

/* One cast of the probe through stream b (its two tiled frames in turn where it has them),
 * or through stream a (its two frames in turn when a_dense: never the same frame twice, so
 * it gets no copies), into *ms. */
static cdvr_status probe_cast(probe_scene *p, int b, int a_dense, const cdvr_render_opts *opts,
                              double *ms, cdvr_error *err)
{
    if (b && p->tiles[0]) {
        cdvr_status st = cdvr_cl_use_host_tiles(p->b, p->tiles[p->next_tiles++ & 1], err);
        return st ? st : probe_render(p->b, 0, opts, &p->grid, p->img, ms, err);
    }
    if (b)
        return probe_render(p->b, 0, opts, NULL, p->img, ms, err);
    return probe_render(p->a, a_dense ? p->next++ & 1 : 0, opts, NULL, p->img, ms, err);
}

/* Median casts of streams a and b, alternating (A B, B A, ...) after a warm-up of two casts
 * each (where b makes copies of its frame, on its second). */
static cdvr_status probe_pairs(probe_scene *p, int a_dense, const cdvr_render_opts *opts,
                               double *a_ms, double *b_ms, cdvr_error *err)
{
    double ms[2][PROBE_PAIRS], warm;
    cdvr_status st = CDVR_OK;
    for (int i = 0; i < 4 && !st; i++)
        st = probe_cast(p, i & 1, a_dense, opts, &warm, err);
    for (int i = 0; i < PROBE_PAIRS && !st; i++)
        for (int k = 0; k < 2 && !st; k++) {
            int b = k ^ (i & 1);
            st = probe_cast(p, b, a_dense, opts, &ms[b][i], err);
        }
    if (!st) {
        *a_ms = cdvr_median(ms[0], PROBE_PAIRS);
        *b_ms = cdvr_median(ms[1], PROBE_PAIRS);
    }
    return st;
}

cdvr_status cdvr_cl_measure_layouts(cdvr_cl *cl, double *dense_ms, double *tiled_ms,
                                    cdvr_error *err)
{
    probe_scene p;
    cdvr_status st = probe_init(cl, &p, 2, 0, err); /* a: dense, b: tiled on the host */
    if (!st)
        st = probe_host_tiles(&p, err);
    cdvr_render_opts opts = {.tf = p.tf, .camera = &p.cam};
    if (!st)
        st = probe_pairs(&p, 1, &opts, dense_ms, tiled_ms, err);
    probe_free(&p);
    return st;
}

cdvr_status cdvr_cl_measure_quads(cdvr_cl *cl, int dense, double *base_ms, double *quads_ms,
                                  cdvr_error *err)
{
    probe_scene p;
    cdvr_status st = probe_init(cl, &p, dense ? 2 : 1, 1, err);
    if (!st) {
        p.a->quads_probe = -1; /* the tiled copy alone, or dense frames */
        p.b->quads_probe = 1;  /* the tiled copy with its quad copy */
    }
    const cdvr_blend blends[2] = {CDVR_BLEND_COMPOSITE, CDVR_BLEND_MAX};
    double sums[2] = {0, 0};
    for (int m = 0; m < 2 && !st; m++) {
        cdvr_render_opts opts = {.tf = p.tf, .camera = &p.cam, .look = {.blend = blends[m]}};
        double a_ms, b_ms;
        st = probe_pairs(&p, dense, &opts, &a_ms, &b_ms, err);
        if (!st) {
            sums[0] += a_ms;
            sums[1] += b_ms;
        }
    }
    if (!st && !(p.b->quads_frame == 0 && p.b->quads && !p.a->quads))
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "OpenCL quad probe: no quad copy was made");
    if (!st) {
        *base_ms = sums[0];
        *quads_ms = sums[1];
    }
    probe_free(&p);
    return st;
}
