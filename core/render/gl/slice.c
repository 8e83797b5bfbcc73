/* core/render/gl/slice.c - object-aligned 2D-texture slicing with a level of detail per slice
 * (seed 002), drawn with OpenGL 3.3 in a headless EGL context. The rules (axis, order,
 * sampling, classification, opacity correction, levels) are in cdvr/gl.h. */
#include "cdvr/gl.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/crc32c.h"
#include "cdvr/timing.h"
#include "gl_internal.h"

#define MAX_LEVELS 48

/* One slice of the stack: its texture (at `level`, -1 before the first upload) and the host
 * copies of its levels above 0, built once each while the stack's frame and axis stay. */
typedef struct slice_entry {
    GLuint texture;
    int level;
    uint8_t *levels[MAX_LEVELS];
} slice_entry;

typedef struct slice_stack {
    int valid;
    uint32_t crc;   /* CRC-32C of the frame's voxels */
    size_t dims[3];
    int axis;
    size_t n;       /* slices (dims[axis]) */
    slice_entry *slices;
    uint64_t texture_bytes;
} slice_stack;

typedef struct uniforms {
    GLint clip, world, index, plane, level_scale, level_size, unit, axis, slab, box_hi, eye,
        eye_index, forward, forward_index, ortho, slice, table;
} uniforms;

struct cdvr_gl {
    cdvr_egl egl;
    GLuint program, vao, vbo, fbo, color, table;
    int fb_width, fb_height;
    GLint max_texture;
    uniforms loc;
    slice_stack stack;
};

/* ---- shaders: sampling and classification (the only place they are written) ---------------- */

static const char *vertex_src =
    "#version 330 core\n"
    "layout(location = 0) in vec2 a_st;\n"
    "uniform mat4 u_clip;   /* unit square of the slice -> clip space */\n"
    "uniform mat4 u_world;  /* unit square of the slice -> world */\n"
    "uniform mat4 u_index;  /* unit square of the slice -> index coordinates (x, y, z) */\n"
    "uniform ivec2 u_plane; /* the slice's in-plane index axes (u, v) */\n"
    "out vec2 v_uv;\n"
    "out vec3 v_world;\n"
    "out vec3 v_index;\n"
    "void main() {\n"
    "  vec4 p = vec4(a_st, 0.0, 1.0);\n"
    "  v_world = (u_world * p).xyz;\n"
    "  v_index = (u_index * p).xyz;\n"
    "  v_uv = vec2(v_index[u_plane.x], v_index[u_plane.y]);\n"
    "  gl_Position = u_clip * p;\n"
    "}\n";

static const char *fragment_src =
    "#version 330 core\n"
    "uniform usampler2D u_slice; /* u8 texels of this slice at its level */\n"
    "uniform sampler2D u_table;  /* 256 x 1 RGBA float: the TF table */\n"
    "uniform float u_level_scale; /* 2^level */\n"
    "uniform ivec2 u_level_size;\n"
    "uniform float u_unit;\n"
    "uniform int u_axis;         /* the stack's index axis */\n"
    "uniform vec2 u_slab;        /* this slice's slab [lo, hi] along the axis (index units) */\n"
    "uniform vec3 u_box_hi;      /* dims - 1: the box is [0, dims-1] in index coordinates */\n"
    "uniform vec3 u_eye, u_eye_index, u_forward, u_forward_index;\n"
    "uniform int u_ortho;\n"
    "in vec2 v_uv;\n"
    "in vec3 v_world;\n"
    "in vec3 v_index;\n"
    "out vec4 o_color;\n"
    "float texel(ivec2 p) { return float(texelFetch(u_slice, p, 0).r); }\n"
    "/* 1. bilinear, u first then v, clamped like the ray caster's trilinear */\n"
    "float sample_slice() {\n"
    "  vec2 g = clamp((v_uv + 0.5) / u_level_scale - 0.5, vec2(0.0), vec2(u_level_size - 1));\n"
    "  ivec2 i0 = ivec2(g);\n"
    "  ivec2 i1 = min(i0 + 1, u_level_size - 1);\n"
    "  vec2 f = g - vec2(i0);\n"
    "  float c0 = mix(texel(i0), texel(ivec2(i1.x, i0.y)), f.x);\n"
    "  float c1 = mix(texel(ivec2(i0.x, i1.y)), texel(i1), f.x);\n"
    "  return mix(c0, c1, f.y);\n"
    "}\n"
    "/* 2. post-classification: linear between table[i0] and table[i0 + 1] */\n"
    "vec4 classify(float s) {\n"
    "  int i0 = min(int(s), 254);\n"
    "  float f = s - float(i0);\n"
    "  return mix(texelFetch(u_table, ivec2(i0, 0), 0), texelFetch(u_table, ivec2(i0 + 1, 0), 0), f);\n"
    "}\n"
    "/* 3. world length of this pixel's ray inside the slab, the box and in front of the eye */\n"
    "float slab_length() {\n"
    "  vec3 o, d;\n"
    "  float t0, len;\n"
    "  if (u_ortho != 0) {\n"
    "    o = v_index; d = u_forward_index; len = 1.0;\n"
    "    t0 = -dot(v_world - u_eye, u_forward);\n"
    "  } else {\n"
    "    o = u_eye_index; d = v_index - u_eye_index; len = length(v_world - u_eye);\n"
    "    t0 = 0.0;\n"
    "  }\n"
    "  float t1 = 3.0e38;\n"
    "  for (int c = 0; c < 3; c++) {\n"
    "    float lo = c == u_axis ? u_slab.x : 0.0, hi = c == u_axis ? u_slab.y : u_box_hi[c];\n"
    "    if (abs(d[c]) < 1e-12) {\n"
    "      if (o[c] < lo || o[c] > hi) return 0.0;\n"
    "    } else {\n"
    "      float a = (lo - o[c]) / d[c], b = (hi - o[c]) / d[c];\n"
    "      t0 = max(t0, min(a, b));\n"
    "      t1 = min(t1, max(a, b));\n"
    "    }\n"
    "  }\n"
    "  return max(t1 - t0, 0.0) * len;\n"
    "}\n"
    "void main() {\n"
    "  vec4 c = classify(sample_slice());\n"
    "  float ds = slab_length();\n"
    "  float a = c.a >= 1.0 && ds > 0.0 ? 1.0 : 1.0 - pow(1.0 - c.a, ds / u_unit);\n"
    "  o_color = vec4(c.rgb * a, a);\n"
    "}\n";

/* ---- context ------------------------------------------------------------------------------ */

static void find_uniforms(cdvr_gl *gl)
{
    GLuint p = gl->program;
    uniforms *u = &gl->loc;
    u->clip = glGetUniformLocation(p, "u_clip");
    u->world = glGetUniformLocation(p, "u_world");
    u->index = glGetUniformLocation(p, "u_index");
    u->plane = glGetUniformLocation(p, "u_plane");
    u->level_scale = glGetUniformLocation(p, "u_level_scale");
    u->level_size = glGetUniformLocation(p, "u_level_size");
    u->unit = glGetUniformLocation(p, "u_unit");
    u->axis = glGetUniformLocation(p, "u_axis");
    u->slab = glGetUniformLocation(p, "u_slab");
    u->box_hi = glGetUniformLocation(p, "u_box_hi");
    u->eye = glGetUniformLocation(p, "u_eye");
    u->eye_index = glGetUniformLocation(p, "u_eye_index");
    u->forward = glGetUniformLocation(p, "u_forward");
    u->forward_index = glGetUniformLocation(p, "u_forward_index");
    u->ortho = glGetUniformLocation(p, "u_ortho");
    u->slice = glGetUniformLocation(p, "u_slice");
    u->table = glGetUniformLocation(p, "u_table");
}

static cdvr_status create_objects(cdvr_gl *gl, cdvr_error *err)
{
    cdvr_status st = cdvr_gl_program(vertex_src, fragment_src, &gl->program, err);
    if (st != CDVR_OK)
        return st;
    find_uniforms(gl);
    static const float square[8] = {0, 0, 1, 0, 0, 1, 1, 1};
    glGenVertexArrays(1, &gl->vao);
    glBindVertexArray(gl->vao);
    glGenBuffers(1, &gl->vbo);
    glBindBuffer(GL_ARRAY_BUFFER, gl->vbo);
    glBufferData(GL_ARRAY_BUFFER, sizeof square, square, GL_STATIC_DRAW);
    glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 0, NULL);
    glEnableVertexAttribArray(0);
    glGenFramebuffers(1, &gl->fbo);
    glGenTextures(1, &gl->color);
    glGenTextures(1, &gl->table);
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &gl->max_texture);
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    return cdvr_gl_check("creating the slicer's objects", err);
}

cdvr_status cdvr_gl_create(cdvr_gl **out, cdvr_error *err)
{
    *out = NULL;
    cdvr_gl *gl = calloc(1, sizeof *gl);
    if (!gl)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "GL: no memory for the slicer");
    cdvr_status st = cdvr_egl_open(&gl->egl, err);
    if (st != CDVR_OK) {
        free(gl);
        return st;
    }
    st = cdvr_egl_begin(&gl->egl, err);
    if (st == CDVR_OK) {
        st = create_objects(gl, err);
        cdvr_egl_end(&gl->egl);
    }
    if (st != CDVR_OK) {
        cdvr_gl_free(gl);
        return st;
    }
    *out = gl;
    return CDVR_OK;
}

static void drop_stack(slice_stack *stack)
{
    for (size_t k = 0; k < stack->n && stack->slices; k++) {
        slice_entry *e = &stack->slices[k];
        if (e->texture)
            glDeleteTextures(1, &e->texture);
        for (int l = 0; l < MAX_LEVELS; l++)
            free(e->levels[l]);
    }
    free(stack->slices);
    memset(stack, 0, sizeof *stack);
}

void cdvr_gl_free(cdvr_gl *gl)
{
    if (!gl)
        return;
    if (gl->egl.display != EGL_NO_DISPLAY && cdvr_egl_begin(&gl->egl, NULL) == CDVR_OK) {
        drop_stack(&gl->stack);
        if (gl->program)
            glDeleteProgram(gl->program);
        glDeleteBuffers(1, &gl->vbo);
        glDeleteVertexArrays(1, &gl->vao);
        glDeleteFramebuffers(1, &gl->fbo);
        glDeleteTextures(1, &gl->color);
        glDeleteTextures(1, &gl->table);
        cdvr_egl_end(&gl->egl);
    }
    cdvr_egl_close(&gl->egl);
    free(gl);
}

const char *cdvr_gl_renderer(const cdvr_gl *gl)
{
    return gl->egl.renderer;
}

/* ---- slice textures ---------------------------------------------------------------------- */

/* Level-0 slice k along axis of a u8 frame into buf (n_u x n_v, u fastest). */
static void extract_slice(const uint8_t *vox, const size_t dims[3], int axis, size_t k,
                          uint8_t *buf)
{
    size_t X = dims[0], Y = dims[1], Z = dims[2];
    if (axis == 2) {
        memcpy(buf, vox + k * X * Y, X * Y);
    } else if (axis == 1) {
        for (size_t z = 0; z < Z; z++)
            memcpy(buf + z * X, vox + X * (k + Y * z), X);
    } else {
        for (size_t z = 0; z < Z; z++)
            for (size_t y = 0; y < Y; y++)
                buf[y + Y * z] = vox[k + X * (y + Y * z)];
    }
}

/* Level L of an n_u x n_v slice: means of 2^L x 2^L blocks (the voxels that exist), rounded
 * half up. */
static void build_level(const uint8_t *base, size_t n_u, size_t n_v, int level, uint8_t *out)
{
    size_t scale = (size_t)1 << level;
    size_t m_u = cdvr_lod_extent(n_u, level), m_v = cdvr_lod_extent(n_v, level);
    for (size_t j = 0; j < m_v; j++) {
        size_t v0 = j * scale, v1 = v0 + scale < n_v ? v0 + scale : n_v;
        for (size_t i = 0; i < m_u; i++) {
            size_t u0 = i * scale, u1 = u0 + scale < n_u ? u0 + scale : n_u;
            uint64_t sum = 0;
            for (size_t v = v0; v < v1; v++)
                for (size_t u = u0; u < u1; u++)
                    sum += base[u + n_u * v];
            uint64_t count = (uint64_t)(u1 - u0) * (v1 - v0);
            out[i + m_u * j] = (uint8_t)((2 * sum + count) / (2 * count));
        }
    }
}

static int same_stack(const slice_stack *s, uint32_t crc, const size_t dims[3], int axis)
{
    return s->valid && s->crc == crc && s->axis == axis && s->dims[0] == dims[0] &&
           s->dims[1] == dims[1] && s->dims[2] == dims[2];
}

static cdvr_status reset_stack(cdvr_gl *gl, uint32_t crc, const size_t dims[3], int axis,
                               cdvr_error *err)
{
    drop_stack(&gl->stack);
    slice_stack *s = &gl->stack;
    s->slices = calloc(dims[axis], sizeof *s->slices);
    if (!s->slices)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "GL slicing: no memory for %zu slices",
                              dims[axis]);
    s->n = dims[axis];
    for (size_t k = 0; k < s->n; k++)
        s->slices[k].level = -1;
    memcpy(s->dims, dims, sizeof s->dims);
    s->crc = crc;
    s->axis = axis;
    s->valid = 1;
    return CDVR_OK;
}

/* Uploads slice k at `level` (building the level once), replacing its previous texture. */
static cdvr_status upload_slice(cdvr_gl *gl, const uint8_t *vox, size_t k, int level,
                                uint8_t *scratch, uint64_t *uploaded, cdvr_error *err)
{
    slice_stack *s = &gl->stack;
    slice_entry *e = &s->slices[k];
    int u, v;
    cdvr_slice_plane_axes(s->axis, &u, &v);
    size_t n_u = s->dims[u], n_v = s->dims[v];
    const uint8_t *texels = scratch;
    extract_slice(vox, s->dims, s->axis, k, scratch);
    if (level > 0) {
        if (!e->levels[level]) {
            e->levels[level] = malloc(cdvr_lod_extent(n_u, level) * cdvr_lod_extent(n_v, level));
            if (!e->levels[level])
                return cdvr_error_set(err, CDVR_ERR_NOMEM, "GL slicing: no memory for level %d",
                                      level);
            build_level(scratch, n_u, n_v, level, e->levels[level]);
        }
        texels = e->levels[level];
    }
    size_t m_u = cdvr_lod_extent(n_u, level), m_v = cdvr_lod_extent(n_v, level);
    if (!e->texture)
        glGenTextures(1, &e->texture);
    glBindTexture(GL_TEXTURE_2D, e->texture);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_R8UI, (GLsizei)m_u, (GLsizei)m_v, 0, GL_RED_INTEGER,
                 GL_UNSIGNED_BYTE, texels);
    if (e->level >= 0)
        s->texture_bytes -= (uint64_t)cdvr_lod_extent(n_u, e->level) * cdvr_lod_extent(n_v, e->level);
    s->texture_bytes += (uint64_t)m_u * m_v;
    *uploaded += (uint64_t)m_u * m_v;
    e->level = level;
    return cdvr_gl_check("uploading a slice texture", err);
}

/* Brings every slice's texture to its planned level. */
static cdvr_status update_textures(cdvr_gl *gl, const cdvr_volume *vol, size_t t,
                                   const cdvr_lod_plan *plan, uint64_t *uploaded, cdvr_error *err)
{
    const uint8_t *vox = cdvr_volume_frame(vol, t);
    uint32_t crc = cdvr_crc32c(0, vox, cdvr_volume_frame_bytes(vol));
    cdvr_status st = CDVR_OK;
    if (!same_stack(&gl->stack, crc, vol->dims, plan->axis))
        st = reset_stack(gl, crc, vol->dims, plan->axis, err);
    int u, v;
    cdvr_slice_plane_axes(plan->axis, &u, &v);
    uint8_t *scratch = st == CDVR_OK ? malloc(vol->dims[u] * vol->dims[v]) : NULL;
    if (st == CDVR_OK && !scratch)
        st = cdvr_error_set(err, CDVR_ERR_NOMEM, "GL slicing: no memory for a slice");
    for (size_t k = 0; st == CDVR_OK && k < plan->nslices; k++)
        if (gl->stack.slices[k].level != plan->levels[k])
            st = upload_slice(gl, vox, k, plan->levels[k], scratch, uploaded, err);
    free(scratch);
    if (st != CDVR_OK)
        drop_stack(&gl->stack);
    return st;
}

/* ---- camera and geometry ----------------------------------------------------------------- */

typedef struct view {
    double f[3], u[3], r[3];
    double proj_view[16]; /* column-major, world -> clip */
    int empty;            /* the whole box lies behind the camera */
} view;

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* out = a * b, 4x4 column-major. */
static void mat4_mul(const double a[16], const double b[16], double out[16])
{
    for (int c = 0; c < 4; c++)
        for (int r = 0; r < 4; r++) {
            double sum = 0.0;
            for (int k = 0; k < 4; k++)
                sum += a[k * 4 + r] * b[c * 4 + k];
            out[c * 4 + r] = sum;
        }
}

/* Depth range of the box's corners along f, from the eye. */
static void box_depths(const cdvr_grid *g, const cdvr_camera *cam, const double f[3],
                       double *zmin, double *zmax)
{
    *zmin = INFINITY;
    *zmax = -INFINITY;
    for (int corner = 0; corner < 8; corner++) {
        double p[3];
        for (int r = 0; r < 3; r++) {
            p[r] = g->origin[r] - cam->eye[r];
            for (int c = 0; c < 3; c++) {
                double extent = (corner >> c & 1) ? (double)(g->dims[c] - 1) * g->spacing[c] : 0.0;
                p[r] += g->direction[3 * r + c] * extent;
            }
        }
        double z = dot3(p, f);
        *zmin = fmin(*zmin, z);
        *zmax = fmax(*zmax, z);
    }
}

/* The projection of cdvr/camera.h: pixel centres of a GL viewport of width x height land on the
 * camera's rays (GL's rows run bottom-up; the read-back flips them). */
static void setup_view(const cdvr_grid *g, const cdvr_camera *cam, view *vw)
{
    cdvr_camera_basis(cam, vw->f, vw->u, vw->r);
    double zmin, zmax;
    box_depths(g, cam, vw->f, &zmin, &zmax);
    double margin = 1e-4 * (zmax - zmin) + 1e-12;
    double aspect = (double)cam->width / (double)cam->height;
    double n, fa;
    double p[16] = {0};
    /* the far plane leaves room for the slices' margins beyond the box (slab_margin): far at
     * infinity in perspective (GL's limit of the projection, shrunk by 1e-6 so points at any
     * depth stay inside), 32 box diagonals behind the box in orthographic views */
    if (cam->orthographic) {
        n = fmax(zmin - margin, 0.0);
        fa = zmax + margin + 32.0 * (zmax - zmin + 1.0);
        double half_h = 0.5 * cam->ortho_height, half_w = half_h * aspect;
        p[0] = 1.0 / half_w;
        p[5] = 1.0 / half_h;
        p[10] = -2.0 / (fa - n);
        p[14] = -(fa + n) / (fa - n);
        p[15] = 1.0;
    } else {
        n = fmax(zmin - margin, zmax * 1e-6);
        fa = INFINITY;
        double tan_half = tan(0.5 * cam->fov * 3.14159265358979323846 / 180.0);
        const double eps = 1e-6;
        p[0] = 1.0 / (aspect * tan_half);
        p[5] = 1.0 / tan_half;
        p[10] = eps - 1.0;
        p[11] = -1.0;
        p[14] = (eps - 2.0) * n;
    }
    vw->empty = !(zmax > 0.0) || !(fa > n);
    double v[16] = {0};
    for (int c = 0; c < 3; c++) {
        v[c * 4 + 0] = vw->r[c];
        v[c * 4 + 1] = vw->u[c];
        v[c * 4 + 2] = -vw->f[c];
    }
    v[12] = -dot3(vw->r, cam->eye);
    v[13] = -dot3(vw->u, cam->eye);
    v[14] = dot3(vw->f, cam->eye);
    v[15] = 1.0;
    mat4_mul(p, v, vw->proj_view);
}

/* Index coordinates -> world, column-major: columns spacing_c * (column c of the direction
 * matrix), translation origin. */
static void grid_matrix(const cdvr_grid *g, double out[16])
{
    memset(out, 0, 16 * sizeof *out);
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < 3; r++)
            out[4 * c + r] = g->direction[3 * r + c] * g->spacing[c];
    for (int r = 0; r < 3; r++)
        out[12 + r] = g->origin[r];
    out[15] = 1.0;
}

static void set_mat4(GLint loc, const double m[16])
{
    float f[16];
    for (int i = 0; i < 16; i++)
        f[i] = (float)m[i];
    glUniformMatrix4fv(loc, 1, GL_FALSE, f);
}

/* ---- drawing ------------------------------------------------------------------------------- */

static cdvr_status ensure_framebuffer(cdvr_gl *gl, int width, int height, cdvr_error *err)
{
    if (width > gl->max_texture || height > gl->max_texture)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "GL slicing: image %dx%d larger than the GL limit %d", width,
                              height, gl->max_texture);
    glBindFramebuffer(GL_FRAMEBUFFER, gl->fbo);
    if (gl->fb_width != width || gl->fb_height != height) {
        glBindTexture(GL_TEXTURE_2D, gl->color);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, width, height, 0, GL_RGBA, GL_FLOAT, NULL);
        glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, gl->color, 0);
        GLenum status = glCheckFramebufferStatus(GL_FRAMEBUFFER);
        if (status != GL_FRAMEBUFFER_COMPLETE)
            return cdvr_error_set(err, CDVR_ERR_DEVICE,
                                  "GL slicing: float framebuffer %dx%d incomplete (0x%x)", width,
                                  height, (unsigned)status);
        gl->fb_width = width;
        gl->fb_height = height;
    }
    glViewport(0, 0, width, height);
    glClearColor(0.0f, 0.0f, 0.0f, 0.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    return cdvr_gl_check("preparing the framebuffer", err);
}

static void upload_table(cdvr_gl *gl, const cdvr_tf *tf)
{
    glActiveTexture(GL_TEXTURE1);
    glBindTexture(GL_TEXTURE_2D, gl->table);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, 256, 1, 0, GL_RGBA, GL_FLOAT, tf->table);
    glActiveTexture(GL_TEXTURE0);
}

static void set_frame_uniforms(cdvr_gl *gl, const cdvr_grid *g, const cdvr_camera *cam,
                               const view *vw, int axis, double unit)
{
    int u, v;
    cdvr_slice_plane_axes(axis, &u, &v);
    glUseProgram(gl->program);
    glUniform1i(gl->loc.slice, 0);
    glUniform1i(gl->loc.table, 1);
    glUniform2i(gl->loc.plane, u, v);
    glUniform1f(gl->loc.unit, (float)unit);
    glUniform1i(gl->loc.axis, axis);
    glUniform3f(gl->loc.box_hi, (float)(g->dims[0] - 1), (float)(g->dims[1] - 1),
                (float)(g->dims[2] - 1));
    double eye_index[3], forward_index[3];
    cdvr_grid_index_of(g, cam->eye, eye_index);
    cdvr_grid_index_direction(g, vw->f, forward_index);
    glUniform3f(gl->loc.eye, (float)cam->eye[0], (float)cam->eye[1], (float)cam->eye[2]);
    glUniform3f(gl->loc.eye_index, (float)eye_index[0], (float)eye_index[1], (float)eye_index[2]);
    glUniform3f(gl->loc.forward, (float)vw->f[0], (float)vw->f[1], (float)vw->f[2]);
    glUniform3f(gl->loc.forward_index, (float)forward_index[0], (float)forward_index[1],
                (float)forward_index[2]);
    glUniform1i(gl->loc.ortho, cam->orthographic != 0);
    glEnable(GL_BLEND);
    glBlendFunc(GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
    glDisable(GL_DEPTH_TEST);
    glDisable(GL_CULL_FACE);
    glBindVertexArray(gl->vao);
}

/* Slab of slice k along the axis, in index units: [k - 1/2, k + 1/2], except that the slices
 * next to the eye (index coordinate eye_k) reach to the eye; clipped to the stack [0, n-1].
 * The slabs partition the stack on each side of the eye, so the pieces a ray crosses add up to
 * its path through the box (the shader clips each to the box and the eye). */
static void slab_range(size_t k, size_t n, double eye_k, double *lo, double *hi)
{
    double kk = (double)k;
    *lo = kk - 0.5;
    *hi = kk + 0.5;
    if (kk > eye_k && kk - 1.0 <= eye_k)
        *lo = eye_k;
    else if (kk < eye_k && kk + 1.0 >= eye_k)
        *hi = eye_k;
    *lo = fmax(*lo, 0.0);
    *hi = fmin(*hi, (double)(n - 1));
}

/* Unit square of slice k -> index coordinates, column-major: the slice's rectangle
 * [0, n_u-1] x [0, n_v-1] grown by `margin` on every side (see slab_margin). */
static void slice_index(const cdvr_grid *g, int axis, size_t k, double margin, double out[16])
{
    int u, v;
    cdvr_slice_plane_axes(axis, &u, &v);
    memset(out, 0, 16 * sizeof *out);
    out[0 + u] = (double)(g->dims[u] - 1) + 2.0 * margin;
    out[4 + v] = (double)(g->dims[v] - 1) + 2.0 * margin;
    out[12 + u] = -margin;
    out[12 + v] = -margin;
    out[12 + axis] = (double)k;
    out[15] = 1.0;
}

/* How far (index units) beyond the box a ray can cross a slice plane while its slab's piece is
 * inside the box: half a slab times the largest tan(angle to the axis) of the view's rays, plus
 * a voxel; at most 16 times the larger side of the slice (float interpolation across the quad
 * stays well below a voxel). Without it a ray leaving the box through a side face would lose the
 * piece of its path in its last slab; rays closer to parallel to the slices than that still do.
 * The unnormalised ray direction f + (sx aspect r - sy u) tan(fov/2) is linear in the image
 * position (sx, sy) in [-1, 1]^2: its axis component changes sign inside the image iff it does
 * between corners (then tan is unbounded), else |axis component| is smallest and the in-plane
 * length largest at corners, so corners bound tan. */
static double slab_margin(const cdvr_grid *g, const cdvr_camera *cam, const view *vw, int axis)
{
    int u, v;
    cdvr_slice_plane_axes(axis, &u, &v);
    double cap = 16.0 * (double)(g->dims[u] > g->dims[v] ? g->dims[u] : g->dims[v]);
    double aspect = (double)cam->width / (double)cam->height;
    double half = cam->orthographic ? 0.0 : tan(0.5 * cam->fov * 3.14159265358979323846 / 180.0);
    double side_max = 0.0, along_min = INFINITY;
    int positive = 0, negative = 0;
    for (int corner = 0; corner < 4; corner++) {
        double sx = corner & 1 ? 1.0 : -1.0, sy = corner & 2 ? 1.0 : -1.0, d[3], di[3];
        for (int c = 0; c < 3; c++)
            d[c] = vw->f[c] + (sx * aspect * vw->r[c] - sy * vw->u[c]) * half;
        cdvr_grid_index_direction(g, d, di);
        side_max = fmax(side_max, sqrt(di[u] * di[u] + di[v] * di[v]));
        along_min = fmin(along_min, fabs(di[axis]));
        positive |= di[axis] > 0.0;
        negative |= di[axis] < 0.0;
    }
    if ((positive && negative) || along_min < 1e-12)
        return cap;
    return fmin(0.5 * side_max / along_min + 1.0, cap);
}

static void draw_slice(cdvr_gl *gl, const cdvr_grid *g, const view *vw, int axis, size_t k,
                       double eye_k, double margin)
{
    const slice_stack *s = &gl->stack;
    const slice_entry *e = &s->slices[k];
    int u, v;
    cdvr_slice_plane_axes(axis, &u, &v);
    double to_world[16], world[16], clip[16], index[16], lo, hi;
    slice_index(g, axis, k, margin, index);
    grid_matrix(g, to_world);
    mat4_mul(to_world, index, world);
    mat4_mul(vw->proj_view, world, clip);
    set_mat4(gl->loc.world, world);
    set_mat4(gl->loc.index, index);
    set_mat4(gl->loc.clip, clip);
    slab_range(k, s->n, eye_k, &lo, &hi);
    glUniform2f(gl->loc.slab, (float)lo, (float)hi);
    glUniform1f(gl->loc.level_scale, (float)ldexp(1.0, e->level));
    glUniform2i(gl->loc.level_size, (GLint)cdvr_lod_extent(s->dims[u], e->level),
                (GLint)cdvr_lod_extent(s->dims[v], e->level));
    glBindTexture(GL_TEXTURE_2D, e->texture);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
}

static int cancelled(const cdvr_render_opts *opts)
{
    return opts->cancel && atomic_load(opts->cancel);
}

/* Back to front: slices on the far side of the eye's index coordinate along the axis first,
 * from each end of the stack towards the eye (orthographic: from the end the view points at). */
static cdvr_status draw_stack(cdvr_gl *gl, const cdvr_grid *g, const cdvr_camera *cam,
                              const view *vw, const cdvr_render_opts *opts, cdvr_error *err)
{
    int axis = gl->stack.axis;
    size_t n = gl->stack.n;
    double eye_index[3], forward_index[3];
    cdvr_grid_index_of(g, cam->eye, eye_index);
    cdvr_grid_index_direction(g, vw->f, forward_index);
    double eye_k = eye_index[axis];
    if (cam->orthographic)
        eye_k = forward_index[axis] > 0.0 ? -INFINITY : INFINITY;
    double margin = slab_margin(g, cam, vw, axis);
    for (size_t k = 0; k < n && (double)k < eye_k; k++) {
        if (cancelled(opts))
            return cdvr_error_set(err, CDVR_ERR_CANCELLED, "GL slicing: interrupted");
        draw_slice(gl, g, vw, axis, k, eye_k, margin);
    }
    for (size_t i = 0; i < n && (double)(n - 1 - i) > eye_k; i++) {
        if (cancelled(opts))
            return cdvr_error_set(err, CDVR_ERR_CANCELLED, "GL slicing: interrupted");
        draw_slice(gl, g, vw, axis, n - 1 - i, eye_k, margin);
    }
    return cdvr_gl_check("drawing the slices", err);
}

/* Reads the float framebuffer into img, top row first. */
static cdvr_status read_back(cdvr_image *img, cdvr_error *err)
{
    glReadPixels(0, 0, img->width, img->height, GL_RGBA, GL_FLOAT, img->rgba);
    cdvr_status st = cdvr_gl_check("reading the image back", err);
    if (st != CDVR_OK)
        return st;
    size_t row = (size_t)img->width * 4;
    float *tmp = malloc(row * sizeof *tmp);
    if (!tmp)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "GL slicing: no memory for a row");
    for (int y = 0; y < img->height / 2; y++) {
        float *a = img->rgba + (size_t)y * row, *b = img->rgba + (size_t)(img->height - 1 - y) * row;
        memcpy(tmp, a, row * sizeof *tmp);
        memcpy(a, b, row * sizeof *tmp);
        memcpy(b, tmp, row * sizeof *tmp);
    }
    free(tmp);
    return CDVR_OK;
}

/* ---- cdvr_gl_slice ------------------------------------------------------------------------ */

static cdvr_status check_input(const cdvr_gl *gl, const cdvr_volume *vol, size_t t,
                               const cdvr_render_opts *opts, cdvr_error *err)
{
    if (!gl || !vol || !opts || !opts->tf || !opts->camera)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "GL slicing: context, volume, transfer function and camera needed");
    if (vol->type != CDVR_TYPE_U8)
        return cdvr_error_set(err, CDVR_ERR_ARG, "GL slicing: volume type %s is not u8 (quantize it first)",
                              cdvr_type_name(vol->type));
    if (t >= vol->timesteps)
        return cdvr_error_set(err, CDVR_ERR_ARG, "GL slicing: timestep %zu outside 0..%zu", t,
                              vol->timesteps - 1);
    for (int a = 0; a < 3; a++)
        if (vol->dims[a] > (size_t)gl->max_texture)
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "GL slicing: dim %zu (axis %d) larger than the GL texture limit %d",
                                  vol->dims[a], a, gl->max_texture);
    cdvr_status st = cdvr_volume_check_geometry(vol, "GL slicing", err);
    if (st != CDVR_OK)
        return st;
    st = cdvr_render_opts_check(vol, opts, err); /* step, unit, term_alpha: bounded work */
    if (st != CDVR_OK)
        return st;
    return cdvr_camera_validate(opts->camera, err);
}

static void fill_stats(cdvr_slice_stats *stats, const cdvr_gl *gl, const cdvr_lod_plan *plan,
                       uint64_t uploaded, double upload_ms, double draw_ms)
{
    if (!stats)
        return;
    memset(stats, 0, sizeof *stats);
    stats->axis = plan->axis;
    stats->slices = plan->nslices;
    stats->min_level = INT_MAX;
    for (size_t k = 0; k < plan->nslices; k++) {
        stats->min_level = plan->levels[k] < stats->min_level ? plan->levels[k] : stats->min_level;
        stats->max_level = plan->levels[k] > stats->max_level ? plan->levels[k] : stats->max_level;
    }
    if (plan->nslices == 0)
        stats->min_level = 0;
    stats->nearest = plan->nearest;
    stats->texture_bytes = gl->stack.texture_bytes;
    stats->full_bytes = plan->full_bytes;
    stats->uploaded_bytes = uploaded;
    stats->upload_ms = upload_ms;
    stats->draw_ms = draw_ms;
}

static cdvr_status render_frame(cdvr_gl *gl, const cdvr_volume *vol, size_t t,
                                const cdvr_render_opts *opts, const cdvr_lod_plan *plan,
                                const cdvr_grid *g, cdvr_image *img, cdvr_slice_stats *stats,
                                cdvr_error *err)
{
    double start = cdvr_now_ms();
    uint64_t uploaded = 0;
    cdvr_status st = update_textures(gl, vol, t, plan, &uploaded, err);
    double upload_ms = cdvr_now_ms() - start;
    if (st == CDVR_OK)
        st = ensure_framebuffer(gl, img->width, img->height, err);
    view vw;
    setup_view(g, opts->camera, &vw);
    if (st == CDVR_OK && !vw.empty) {
        double step, unit, term;
        cdvr_render_resolve(vol, opts, &step, &unit, &term);
        upload_table(gl, opts->tf);
        set_frame_uniforms(gl, g, opts->camera, &vw, plan->axis, unit);
        st = draw_stack(gl, g, opts->camera, &vw, opts, err);
    }
    if (st == CDVR_OK)
        st = read_back(img, err);
    fill_stats(stats, gl, plan, uploaded, upload_ms, cdvr_now_ms() - start - upload_ms);
    return st;
}

cdvr_status cdvr_gl_slice(cdvr_gl *gl, const cdvr_volume *vol, size_t t,
                          const cdvr_render_opts *opts, int lod, cdvr_slice_stats *stats,
                          cdvr_image **out, cdvr_error *err)
{
    *out = NULL;
    cdvr_status st = check_input(gl, vol, t, opts, err);
    if (st != CDVR_OK)
        return st;
    cdvr_grid g;
    cdvr_grid_of_volume(vol, &g);
    const cdvr_camera *cam = opts->camera;
    int axis = cdvr_slice_axis(&g, cam);
    double min_nearest = lod == CDVR_LOD_SCREEN ? cdvr_lod_pixel_distance(&g, axis, cam) : 0.0;
    cdvr_lod_plan plan;
    st = cdvr_lod_plan_compute(&g, axis, cam->eye, 1, lod != CDVR_LOD_OFF && !cam->orthographic,
                               min_nearest, &plan, err);
    if (st != CDVR_OK)
        return st;
    cdvr_image *img = NULL;
    st = cdvr_image_create(cam->width, cam->height, &img, err);
    if (st == CDVR_OK) {
        memcpy(img->background, opts->background, sizeof img->background);
        st = cdvr_egl_begin(&gl->egl, err);
    }
    if (st == CDVR_OK) {
        st = render_frame(gl, vol, t, opts, &plan, &g, img, stats, err);
        cdvr_egl_end(&gl->egl);
    }
    cdvr_lod_plan_free(&plan);
    if (st != CDVR_OK) {
        cdvr_image_free(img);
        return st;
    }
    *out = img;
    return CDVR_OK;
}
