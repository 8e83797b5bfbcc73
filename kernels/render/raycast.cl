/* kernels/render/raycast.cl - ray casting as defined in core/include/cdvr/render.h, in float:
 * slab test, segments of length `step` from t_near with a partial last one, midpoint
 * samples, trilinear interpolation, post-classification with the step-corrected table,
 * front-to-back compositing and early termination.
 *
 * Each work-item marches a packet of RAY_PACKET neighbouring rays (PACKET_W x PACKET_H
 * pixels) in lock-step on 16-wide vectors, so the CPU device's compiler emits vector code
 * (PoCL does not vectorise across work-items: the march loop is data dependent). Every lane
 * keeps its own sample index on its own segment grid; lane masks (-1 true, as vector
 * comparisons give) say which lanes sample, which look up bricks and which are still running.
 * Inside visible runs each step takes up to UNROLL samples per lane (with skipping, runs hold
 * at least RUN_VOXELS voxels' worth) whose voxel loads do not depend on each other (the CPU
 * overlaps them), composited in order; a lane takes only the samples
 * left in its run and none after it terminates, so the samples and their order are those of
 * one sample per step.
 *
 * Dense frames are read as rows of voxel pairs, or, when the host made it for a frame it
 * renders again (cdvr_cl_render), from a tiled copy: the voxels in 4x4x4 tiles of 64 bytes,
 * one cache line each (kernels/common/cl_shared.h), read as 32-bit tile rows, so a sample's
 * eight voxels mostly lie on one line and a frame's rays touch a quarter of the lines that a
 * 4-byte-per-voxel layout (each voxel with its 2x2 neighbourhood, read in two gathers) did:
 * misses, not gathers, limit the march. Both give the same values. Voxel indices are 32-bit
 * unless the program is built with -DCDVR_LONG_INDEX (frames of 2^31 voxels or more; no tiled
 * copy then).
 *
 * Rays are carried in grid (voxel) coordinates: sample i of the full segments sits at
 * g0 + i*dg. Empty-space skipping walks the brick grid: for the brick holding a lane's current
 * sample it computes, in sample units, where the ray leaves the cube of like bricks around
 * it; an invisible cube is jumped in one step (conservatively, so a skipped sample is always
 * inside it), a visible cube's samples need no further look-ups, and a visible run lasts to
 * the cube's exit and at least RUN_VOXELS voxels (samples past the exit may lie in invisible
 * bricks: they add nothing, and are counted). Skipped samples are exactly those whose value
 * range has zero opacity under the TF. With skipping on, the host may also give each packet a
 * bound of the ray parameter before which none of its rays can meet a visible brick
 * (cdvr/skip.h, entry distances; composite only): lanes start at the sample before it, and a
 * packet whose bound is +inf stores the image of no sample without casting.
 *
 * Built after kernels/render/brick_cache.cl (which defines CDVR_BRICK_CACHE), the composite
 * blend can march through the brick cache's payload brick by brick instead of fetching every
 * voxel (byte 0 of the codec parameters; the definition is in cdvr/brick_cache.h, "the brick
 * march"): each lane keeps the page-table entry of the brick its run lies in (cache_lanes),
 * looks it up once when it enters the brick (cache_lookup), and samples the brick's voxels
 * directly; level-0 bricks with the dense render's positions, corners, weights and mix order
 * (the same bits), a level-l brick as one sample per 2^l level-0 segments at its own
 * resolution, alpha corrected to 1 - (1 - alpha)^k. Runs end where the skip grid's visible
 * cube or the brick ends, whichever comes first; gradients, the last segment and the other
 * blend modes use the per-voxel fetch. The packets stay: lanes at different levels step by
 * different group sizes within one packet. */

#define RAY_PACKET 16 /* a packet is PACKET_W x PACKET_H pixels (lanes row by row) */
#define PACKET_W CDVR_CL_PACKET_W
#define PACKET_H CDVR_CL_PACKET_H
typedef float16 vfloat;
typedef int16 vint;
typedef long16 vlong;
typedef uint16 vuint;
#define convert_vfloat convert_float16
#define convert_vint convert_int16
#define convert_vlong convert_long16
/* Whether any lane is set (its sign bit, as any()). PoCL 3.1 compiles any(int16) into a
 * chain of 16 sign tests, about 40 instructions; with AVX-512 DQ it is one vpmovd2m and a
 * test (Colin27 composite 512^2 step 1.0, where a packet takes about 4 samples per lane and
 * the march's tests are a large part: 5% less time; engine CT shaded 4%). */
#if defined(__AVX512DQ__) && defined(__has_builtin)
#if __has_builtin(__builtin_ia32_cvtd2mask512)
#define HAVE_MOVEMASK 1
#endif
#endif
/* Whether 16 32-bit words at byte offsets can be read in one gather (AVX-512): bytes and
 * pairs of bytes are then read as the low bits of the words at their offsets. */
#ifdef HAVE_MOVEMASK
#if __has_builtin(__builtin_ia32_gathersiv16si)
#define HAVE_BYTE_GATHER 1
#define WORDS_AT(p, offsets)                                                                   \
    __builtin_ia32_gathersiv16si((vint)(0), (const void *)(ulong)(p), (offsets), (ushort)0xffff, 1)
#endif
#endif
static int lanes_any(vint x)
{
#ifdef HAVE_MOVEMASK
    return __builtin_ia32_cvtd2mask512(x) != 0;
#else
    return any(x);
#endif
}

/* L16(E) lists E(0), E(1), .. E(f): one expression per lane (s0 .. sf) */
#define L16(E) E(0), E(1), E(2), E(3), E(4), E(5), E(6), E(7), E(8), E(9), E(a), E(b), E(c), \
               E(d), E(e), E(f)

/* Per lane of a packet: one coordinate per axis. */
typedef struct vec3x {
    vfloat x, y, z;
} vec3x;

typedef cdvr_cl_camera cam_params; /* kernels/common/cl_shared.h */
typedef cdvr_cl_box_frame box_frame; /* render.h step 0, kernels/common/cl_shared.h */
typedef cdvr_cl_clip clip_params;    /* clipped rendering, render.h */
typedef cdvr_cl_look look_params;    /* blend modes and shading, render.h */

/* Voxels are read from a dense u8 frame, or, when the program is built with
 * -DCDVR_FETCH=name, through a codec's per-sample fetch function (cdvr/codec.h): vol is then
 * the chunk's payload, params its parameter blob and frame the timestep within the chunk. */
typedef struct volume_geo {
    __global const uchar *vol;
    __constant uchar *params;
    int frame;
    int tiled;      /* vol holds the frame's tiled copy (see the top of this file) */
    int page_row;   /* tiled copy: words per row of pages along x, and per slab of them */
    int page_slab;  /* (kernels/common/cl_shared.h) */
    int3 dims;
    int3 base_max;  /* largest lower trilinear corner per axis: max(dims - 2, 0) */
    long3 stride;   /* index step to the upper corner per axis; 0 where dims is 1 */
    float3 top;     /* dims - 1 */
    float3 offset;  /* clipped rendering: whole-volume index of voxel (0,0,0), else 0 */
    __global const uint *grads; /* the frame's gradient copy (cl_shared.h) when grads_on */
    int grads_on;
    __global const uint *quads; /* the frame's quad copy (cl_shared.h) when quads_on */
    int quads_on;
    int last_word;  /* dense frame: the last byte offset a 32-bit word fits at (voxels - 4;
                       below 0 when the frame holds fewer than 4 voxels) */
    int march;      /* CDVR_BRICK_CACHE: vol is a cache payload read brick by brick */
    uint limit;     /* then the largest byte index a voxel pair may start at */
} volume_geo;

/* Per-lane rays of the packet and their clipped segments. */
typedef struct packet {
    vec3x o, d;
    vfloat t_near, t_far;
    vint hit;
} packet;

static void camera_rays(const cam_params *cam, vint px, vint py, packet *p)
{
    vfloat sxn = 2.0f * (convert_vfloat(px) + 0.5f) / (float)cam->width - 1.0f;
    vfloat syn = 2.0f * (convert_vfloat(py) + 0.5f) / (float)cam->height - 1.0f;
    vfloat sx = sxn * cam->aspect;
    vfloat side[3];
    for (int a = 0; a < 3; a++)
        side[a] = sx * cam->r[a] - syn * cam->u[a];
    if (cam->orthographic) {
        float h = cam->ortho_half_height;
        p->o = (vec3x){cam->eye[0] + side[0] * h, cam->eye[1] + side[1] * h,
                        cam->eye[2] + side[2] * h};
        p->d = (vec3x){(vfloat)cam->f[0], (vfloat)cam->f[1], (vfloat)cam->f[2]};
        return;
    }
    p->o = (vec3x){(vfloat)cam->eye[0], (vfloat)cam->eye[1], (vfloat)cam->eye[2]};
    vfloat dx = cam->f[0] + side[0] * cam->tan_half, dy = cam->f[1] + side[1] * cam->tan_half;
    vfloat dz = cam->f[2] + side[2] * cam->tan_half;
    vfloat inv_len = 1.0f / sqrt(dx * dx + dy * dy + dz * dz);
    p->d = (vec3x){dx * inv_len, dy * inv_len, dz * inv_len};
}

/* render.h step 0: the packet's world rays in the box frame q = inv_dir * (world - origin)
 * (same t: the map is affine). */
static void to_box_frame(const box_frame *bf, packet *p)
{
    const float *m = bf->inv_dir;
    vfloat rx = p->o.x - bf->origin[0], ry = p->o.y - bf->origin[1], rz = p->o.z - bf->origin[2];
    vec3x o = {m[0] * rx + m[1] * ry + m[2] * rz, m[3] * rx + m[4] * ry + m[5] * rz,
                m[6] * rx + m[7] * ry + m[8] * rz};
    vec3x d = {m[0] * p->d.x + m[1] * p->d.y + m[2] * p->d.z,
                m[3] * p->d.x + m[4] * p->d.y + m[5] * p->d.z,
                m[6] * p->d.x + m[7] * p->d.y + m[8] * p->d.z};
    p->o = o;
    p->d = d;
}

/* One slab of render.h step 1; a ray parallel to the faces misses if it lies outside. */
static void slab(vfloat o, vfloat d, float lo, float hi, vfloat *t_enter, vfloat *t_exit,
                 vint *miss)
{
    vint parallel = fabs(d) < 1e-12f;
    *miss |= parallel & (o < lo | o > hi);
    vfloat t0 = (lo - o) / d, t1 = (hi - o) / d;
    *t_enter = select(fmax(*t_enter, fmin(t0, t1)), *t_enter, parallel);
    *t_exit = select(fmin(*t_exit, fmax(t0, t1)), *t_exit, parallel);
}

static void intersect_box(packet *p, float3 lo, float3 hi)
{
    vfloat t_enter = (vfloat)(-INFINITY), t_exit = (vfloat)(INFINITY);
    vint miss = (vint)(0);
    slab(p->o.x, p->d.x, lo.x, hi.x, &t_enter, &t_exit, &miss);
    slab(p->o.y, p->d.y, lo.y, hi.y, &t_enter, &t_exit, &miss);
    slab(p->o.z, p->d.z, lo.z, hi.z, &t_enter, &t_exit, &miss);
    p->t_near = fmax(t_enter, 0.0f);
    p->t_far = t_exit;
    p->hit &= ~miss & (p->t_far > p->t_near);
}


#ifdef CDVR_LONG_INDEX
typedef vlong vindex;
typedef long sindex;
#define convert_vindex convert_vlong
#define LANE_INDEX(i) (i)
#else
typedef vint vindex;
typedef int sindex;
#define convert_vindex convert_vint
/* A lane's index (never negative) as unsigned: the address then takes it as it stands, where a
 * signed one is sign-extended to 64 bits lane by lane. The packed TF rows (TABLE_PAIR) and the
 * brick and leap codes (CODE_AT, LEAP_CODE) index the same way. Alternating kernels: engine
 * CT 512^2 step 0.5 0.958 of the time, Colin27 0.97-0.99, the 256^3 zfp1 frame 0.95, its
 * playback at 512^2 1.048x the fps. The gathers of 32-bit words (tile rows, quad and gradient
 * words, the exact TF rows) keep signed indices: unsigned ones let the compiler use AVX-512
 * hardware gathers there, and shaded frames (tiles and gradient words) took 1.05-1.07x the
 * time. */
#define LANE_INDEX(i) ((uint)(i))
#endif

/* Byte of each lane at p[idx]; lanes are independent scalar loads. */
#define BYTE_AT(k) p[LANE_INDEX(idx.s##k)]
static vfloat gather16(__global const uchar *p, vindex idx)
{
    return convert_vfloat((uchar16)(L16(BYTE_AT)));
}

/* Clamped grid position -> lower trilinear corner, at most dims - 2 so the upper corner is
 * always inside (at g == dims - 1 the upper voxel gets weight 1: the clamped index of
 * render.h); *frac gets the weight of the upper corner. */
static vint corner(vfloat g, float top, int base_max, vfloat *frac)
{
    /* clamp() as two selects (NaN -> 0, as clamp): clamp's NaN rules cost four
       instructions */
    g = select((vfloat)(0.0f), g, g > 0.0f);
    g = select((vfloat)(top), g, g < top);
    vint i0 = min(convert_vint(g), base_max);
    *frac = g - convert_vfloat(i0);
    return i0;
}

#ifdef __ENDIAN_LITTLE__
/* Voxels x0 and x0 + 1 of a row in one 16-bit load: low byte x0. */
static ushort pair_at(__global const uchar *q)
{
    return as_ushort(vload2(0, q));
}

/* The pairs at p + base + off of each lane. */
#define PAIR_AT(k) pair_at(p + off + LANE_INDEX(base.s##k))
static ushort16 pairs16(__global const uchar *p, vindex base, sindex off)
{
    return (ushort16)(L16(PAIR_AT));
}

#if defined(HAVE_BYTE_GATHER) && !defined(CDVR_LONG_INDEX)
/* pairs16 by one gather: the low 16 bits of the word at each pair's offset; a word that would
 * run past the frame's end (its last three bytes) is read from last_word and shifted down. */
static ushort16 pairs16_gathered(__global const uchar *p, vindex base, sindex off,
                                 int last_word)
{
    vint at = base + off, from = min(at, last_word);
    return convert_ushort16(as_uint16(WORDS_AT(p, from)) >> as_uint16((at - from) << 3));
}
#endif

static vfloat lerp_pairs(ushort16 w, vfloat fx)
{
    return mix(convert_vfloat(w & (ushort)0xff), convert_vfloat(w >> (ushort)8), fx);
}
#endif


#ifdef CDVR_FETCH
/* Voxel (x, y, z) of each lane through the codec's fetch function. */
static vfloat fetch16(const volume_geo *v, vint x, vint y, vint z)
{
    int xs[RAY_PACKET], ys[RAY_PACKET], zs[RAY_PACKET];
    float out[RAY_PACKET];
    vstore16(x, 0, xs);
    vstore16(y, 0, ys);
    vstore16(z, 0, zs);
    int4 dims = (int4)(v->dims.x, v->dims.y, v->dims.z, v->frame);
    for (int k = 0; k < RAY_PACKET; k++)
        out[k] = (float)CDVR_FETCH(v->vol, v->params, dims, xs[k], ys[k], zs[k]);
    return vload16(0, out);
}
#endif

#ifndef CDVR_LONG_INDEX
/* The tiled copy's word offsets of voxel rows (kernels/common/cl_shared.h; make_tiles in
 * bricks.cl writes it, the host keeps its words below 2^31): word(x, y, z) = along_x(x) +
 * along_y(y) + along_z(z) is the tile row holding voxel (x, y, z), at byte x & 3 of it: page
 * (16^3 voxels, 1024 words), tile within the page (4^3, 16 words), row within the tile. */
static vint along_x(vint x)
{
    return ((x >> 4) << 10) + (((x >> 2) & 3) << 4);
}

static vint along_y(const volume_geo *v, vint y)
{
    return (y >> 4) * v->page_row + (((y >> 2) & 3) << 6) + (y & 3);
}

static vint along_z(const volume_geo *v, vint z)
{
    return (z >> 4) * v->page_slab + (((z >> 2) & 3) << 8) +
           ((z & 3) << 2);
}

/* The word of voxel (x, y, z) in the gradient and quad copies (cl_shared.h: 4 w + (x & 3),
 * w the voxel's row word in the tiled copy) is copy_x(x) + copy_y(y) + copy_z(z). */
#if defined(__AVX512F__) && defined(__has_builtin)
#if __has_builtin(__builtin_ia32_permvarsi512)
#define HAVE_VPERMD 1
#endif
#endif
#ifdef HAVE_VPERMD
/* PoCL on a CPU with AVX-512: the bits within a page come from a 16-entry table indexed by
 * the coordinate's low 4 bits (vpermd, one instruction where the shifts and masks took
 * five: engine CT average 512^2 5% less time, composite 2%). */
#define PAGE_BITS(c, shift)                                                                    \
    as_int16(__builtin_ia32_permvarsi512(                                                      \
        (int16)(0, 1, 2, 3, 64, 65, 66, 67, 128, 129, 130, 131, 192, 193, 194, 195) << (shift),  \
        (c)))
static vint copy_x(vint x)
{
    return PAGE_BITS(x, 0) + ((x >> 4) << 12);
}

static vint copy_y(const volume_geo *v, vint y)
{
    return PAGE_BITS(y, 2) + (y >> 4) * (v->page_row << 2);
}

static vint copy_z(const volume_geo *v, vint z)
{
    return PAGE_BITS(z, 4) + (z >> 4) * (v->page_slab << 2);
}
#undef PAGE_BITS
#else
static vint copy_x(vint x)
{
    return (along_x(x) << 2) + (x & 3);
}

static vint copy_y(const volume_geo *v, vint y)
{
    return along_y(v, y) << 2;
}

static vint copy_z(const volume_geo *v, vint z)
{
    return along_z(v, z) << 2;
}
#endif

/* The x-lerp of voxels x0 and x1 (words at row + wx0 and row + wx1, bytes at bit offsets sh0
 * and sh1) of each lane's row: two gathers, the same word unless x1 starts the next tile. */
#define ROW_WORD0(k) q[w0.s##k]
#define ROW_WORD1(k) q[w1.s##k]
__attribute__((always_inline)) static inline vfloat lerp_row(__global const uint *q, vint row,
                                                            vint wx0, vint wx1, vuint sh0,
                                                            vuint sh1, vfloat fx)
{
    vint w0 = row + wx0, w1 = row + wx1;
    vuint a = (vuint)(L16(ROW_WORD0)), b = (vuint)(L16(ROW_WORD1));
    return mix(convert_vfloat((a >> sh0) & 0xffu), convert_vfloat((b >> sh1) & 0xffu), fx);
}

/* The x-lerp of the low two bytes of each lane's quad word (voxels x0 and x0 + 1). */
static vfloat pair_lerp(vuint q, vfloat fx)
{
    return mix(convert_vfloat(q & 0xffu), convert_vfloat((q >> 8) & 0xffu), fx);
}
#define QUAD0(k) v->quads[i0.s##k]
#define QUAD1(k) v->quads[i1.s##k]
#endif

#ifdef CDVR_BRICK_CACHE
/* ---- sampling through the brick cache (cdvr/brick_cache.h, "the brick march") ------------- */

/* Per lane, the cache brick of its run (written by look-ups lane by lane). */
typedef struct cache_lanes {
    uint base[RAY_PACKET];                   /* payload byte offset of the brick's voxels */
    int lo[3][RAY_PACKET], d[3][RAY_PACKET]; /* its box at its level */
    int group[RAY_PACKET];                   /* 2^level: level-0 samples per group */
    float scale[RAY_PACKET];                 /* 2^-level */
    int end[RAY_PACKET];                     /* first sample index past the run */
    float cell_lo[3][RAY_PACKET], cell_hi[3][RAY_PACKET]; /* the level-0 brick's cells */
} cache_lanes;

/* Lanes not looked up yet: an empty run of a one-voxel brick at 0. */
static void cache_lanes_init(cache_lanes *cl)
{
    for (int k = 0; k < RAY_PACKET; k++) {
        cl->base[k] = 0;
        for (int a = 0; a < 3; a++) {
            cl->lo[a][k] = 0;
            cl->d[a][k] = 1;
            cl->cell_lo[a][k] = cl->cell_hi[a][k] = 0.0f;
        }
        cl->group[k] = 1;
        cl->scale[k] = 1.0f;
        cl->end[k] = 0;
    }
}

/* Lanes `need` look up the brick of the sample at grid position g: the owner of its lower
 * corner + 1 per axis (cdvr/brick_cache.h), whose box holds the cell's eight voxels. */
static void cache_fill(cache_lanes *cl, vint need, const volume_geo *v, vec3x g)
{
    vfloat f;
    vint x = corner(g.x - v->offset.x, v->top.x, v->base_max.x, &f) + (v->stride.x != 0);
    vint y = corner(g.y - v->offset.y, v->top.y, v->base_max.y, &f) + (v->stride.y != 0);
    vint z = corner(g.z - v->offset.z, v->top.z, v->base_max.z, &f) + (v->stride.z != 0);
    int xs[RAY_PACKET], ys[RAY_PACKET], zs[RAY_PACKET], on[RAY_PACKET];
    vstore16(x, 0, xs);
    vstore16(y, 0, ys);
    vstore16(z, 0, zs);
    vstore16(need, 0, on);
    int4 dims = (int4)(v->dims.x, v->dims.y, v->dims.z, 0);
    uint pool = ((__global const uint *)v->vol)[4];
    for (int k = 0; k < RAY_PACKET; k++) {
        if (!on[k])
            continue;
        __global const uint *e = bc_entry(v->vol, v->params, dims, xs[k], ys[k], zs[k]);
        uint lvl = min(e[1], 15u);
        cl->base[k] = pool + e[0];
        for (int a = 0; a < 3; a++) {
            cl->lo[a][k] = (int)e[2 + a];
            cl->d[a][k] = (int)max(e[5 + a], 1u);
            cl->cell_lo[a][k] = (float)e[8 + a];
            cl->cell_hi[a][k] = (float)e[11 + a];
        }
        cl->group[k] = 1 << lvl;
        cl->scale[k] = ldexp(1.0f, -(int)lvl);
    }
}

/* The same as vectors, for the samples. */
typedef struct cache_run {
    vuint base;
    vint lo_x, lo_y, lo_z, d_x, d_y, d_z, group, end;
    vfloat scale;
    uint limit; /* largest byte index a voxel pair may start at */
} cache_run;

static cache_run load_run(const cache_lanes *cl, uint limit)
{
    cache_run r;
    r.base = vload16(0, cl->base);
    r.lo_x = vload16(0, cl->lo[0]);
    r.lo_y = vload16(0, cl->lo[1]);
    r.lo_z = vload16(0, cl->lo[2]);
    r.d_x = vload16(0, cl->d[0]);
    r.d_y = vload16(0, cl->d[1]);
    r.d_z = vload16(0, cl->d[2]);
    r.group = vload16(0, cl->group);
    r.end = vload16(0, cl->end);
    r.scale = vload16(0, cl->scale);
    r.limit = limit;
    return r;
}

/* Voxels x0 and x0 + ox (ox 0 or 1) of each lane at p[idx], lerped by fx: the dense
 * render's pair lerp. */
#define CPAIR_AT(k) pair_at(p + idx.s##k)
#define CBYTE_AT(k) p[idx.s##k]
#define CBYTE1_AT(k) p[idx.s##k + 1]
__attribute__((always_inline)) static inline vfloat cache_lerp(__global const uchar *p, vuint idx,
                                                               vint ox, vfloat fx)
{
#ifdef __ENDIAN_LITTLE__
    ushort16 w = (ushort16)(L16(CPAIR_AT));
    vfloat a = convert_vfloat(w & (ushort)0xff), b = convert_vfloat(w >> (ushort)8);
#else
    vfloat a = convert_vfloat((uchar16)(L16(CBYTE_AT)));
    vfloat b = convert_vfloat((uchar16)(L16(CBYTE1_AT)));
#endif
    return mix(a, select(b, a, ox == 0), fx);
}

/* Lower corner of one axis: level 0 (`level0` lanes) as corner() does; coarser levels at
 * floor(g) (the box clamps it). */
__attribute__((always_inline)) static inline vint cache_corner(vfloat g, vint level0, float top,
                                                             int base_max, vfloat *frac)
{
    vfloat gc = select(fmax(g, 0.0f), clamp(g, 0.0f, top), level0);
    vint i0 = convert_vint(gc);
    i0 = select(i0, min(i0, base_max), level0);
    *frac = gc - convert_vfloat(i0);
    return i0;
}

/* The sample at whole-volume grid position g from each lane's brick (cdvr/brick_cache.h);
 * *inside: lanes whose cell lies in the brick's box (always, unless rounding put a level-0
 * sample past the run's brick). */
__attribute__((always_inline)) static inline vfloat cache_trilinear(const volume_geo *v,
                                                                    const cache_run *r, vec3x g,
                                                                    vint *inside)
{
    vint level0 = r->group == 1;
    vfloat fx, fy, fz;
    vint cx = cache_corner((g.x - v->offset.x) * r->scale, level0, v->top.x, v->base_max.x, &fx) -
              r->lo_x;
    vint cy = cache_corner((g.y - v->offset.y) * r->scale, level0, v->top.y, v->base_max.y, &fy) -
              r->lo_y;
    vint cz = cache_corner((g.z - v->offset.z) * r->scale, level0, v->top.z, v->base_max.z, &fz) -
              r->lo_z;
    int ux = v->stride.x != 0, uy = v->stride.y != 0, uz = v->stride.z != 0;
    *inside = cx >= 0 & cx + ux < r->d_x & cy >= 0 & cy + uy < r->d_y & cz >= 0 &
              cz + uz < r->d_z;
    vint x0 = clamp(cx, 0, r->d_x - 1), x1 = clamp(cx + ux, 0, r->d_x - 1);
    vint y0 = clamp(cy, 0, r->d_y - 1), y1 = clamp(cy + uy, 0, r->d_y - 1);
    vint z0 = clamp(cz, 0, r->d_z - 1), z1 = clamp(cz + uz, 0, r->d_z - 1);
    vint ox = x1 - x0, oy = (y1 - y0) * r->d_x, oz = (z1 - z0) * r->d_x * r->d_y;
    vuint idx = r->base + as_uint16(x0 + r->d_x * (y0 + r->d_y * z0));
    vuint lim = (vuint)(r->limit);
    __global const uchar *p = v->vol;
    vfloat c00 = cache_lerp(p, min(idx, lim), ox, fx);
    vfloat c10 = cache_lerp(p, min(idx + as_uint16(oy), lim), ox, fx);
    vfloat c01 = cache_lerp(p, min(idx + as_uint16(oz), lim), ox, fx);
    vfloat c11 = cache_lerp(p, min(idx + as_uint16(oz + oy), lim), ox, fx);
    return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
}

/* The sample at grid position g through the brick of its cell, one look-up per lane (the
 * march's reading of a single sample: the last segment, gradients, the other blend modes). */
__attribute__((noinline)) static vfloat cache_value_at(const volume_geo *v, vec3x g)
{
    cache_lanes cl;
    cache_lanes_init(&cl);
    cache_fill(&cl, (vint)(-1), v, g);
    cache_run r = load_run(&cl, v->limit);
    vint inside;
    return cache_trilinear(v, &r, g, &inside);
}
#endif

/* render.h step 3 at grid position g (clamped here). */
/* always inlined: as a call (two callers) its vector arguments and result go through memory */
/* g is a whole-volume grid position; the frame's voxels start at v->offset (an integer:
 * g - offset is exact in float). */
/* Lanes off `on` read voxel (0, 0, 0) instead (their values are discarded): lanes that wait or
 * skip then cost cache hits, not misses on voxels they may never sample. */
#if !defined(CDVR_FETCH) && !defined(CDVR_LONG_INDEX)
/* A lower corner without the clamp of g into the volume: g lies in it up to the rounding of
 * its position (below 0: the index truncates to 0, the weight is g; above dims - 1: the
 * corner is dims - 2, the weight above 1), within float rounding of corner()'s sample. */
static vint corner_inside(vfloat g, int base_max, vfloat *frac)
{
    vint i0 = min(convert_vint(g), base_max);
    *frac = g - convert_vfloat(i0);
    return i0;
}

/* The trilinear sample from the quad copy: two words, rows y0, y1 of the cell's z0 and z1
 * faces (never clipped: no offset). `inside`: corner_inside's corners. */
__attribute__((always_inline)) static inline vfloat quad_trilinear(const volume_geo *v, vec3x g,
                                                                   vint on, int inside)
{
    vfloat fx, fy, fz;
    vint x0 = inside ? corner_inside(g.x, v->base_max.x, &fx)
                     : corner(g.x, v->top.x, v->base_max.x, &fx);
    vint y0 = inside ? corner_inside(g.y, v->base_max.y, &fy)
                     : corner(g.y, v->top.y, v->base_max.y, &fy);
    vint z0 = inside ? corner_inside(g.z, v->base_max.z, &fz)
                     : corner(g.z, v->top.z, v->base_max.z, &fz);
    vint xy = copy_x(x0) + copy_y(v, y0), zero = (vint)(0);
    vint i0 = select(zero, xy + copy_z(v, z0), on);
    vint i1 = select(zero, xy + copy_z(v, z0 + (v->stride.z != 0)), on);
    vuint q0 = (vuint)(L16(QUAD0)), q1 = (vuint)(L16(QUAD1));
    return mix(mix(pair_lerp(q0, fx), pair_lerp(q0 >> 16, fx), fy),
               mix(pair_lerp(q1, fx), pair_lerp(q1 >> 16, fx), fy), fz);
}
#endif

__attribute__((always_inline)) static inline vfloat trilinear_on(const volume_geo *v, vec3x g,
                                                                 vint on)
{
    vfloat fx, fy, fz;
#if !defined(CDVR_FETCH) && !defined(CDVR_LONG_INDEX)
    if (v->quads_on)
        return quad_trilinear(v, g, on, 0);
#endif
    vint x0 = corner(g.x - v->offset.x, v->top.x, v->base_max.x, &fx);
    vint y0 = corner(g.y - v->offset.y, v->top.y, v->base_max.y, &fy);
    vint z0 = corner(g.z - v->offset.z, v->top.z, v->base_max.z, &fz);
#ifdef CDVR_FETCH
#ifdef CDVR_BRICK_CACHE
    if (v->march)
        return cache_value_at(v, g);
#endif
    vint x1 = x0 + (v->stride.x != 0), y1 = y0 + (v->stride.y != 0), z1 = z0 + (v->stride.z != 0);
    return mix(mix(mix(fetch16(v, x0, y0, z0), fetch16(v, x1, y0, z0), fx),
                   mix(fetch16(v, x0, y1, z0), fetch16(v, x1, y1, z0), fx), fy),
               mix(mix(fetch16(v, x0, y0, z1), fetch16(v, x1, y0, z1), fx),
                   mix(fetch16(v, x0, y1, z1), fetch16(v, x1, y1, z1), fx), fy),
               fz);
#else
    sindex sx = (sindex)v->stride.x, sy = (sindex)v->stride.y, sz = (sindex)v->stride.z;
    vindex base = convert_vindex(x0) + sy * convert_vindex(y0) + sz * convert_vindex(z0);
    base = select((vindex)(0), base, convert_vindex(on));
    __global const uchar *p = v->vol;
    vfloat c00, c10, c01, c11;
#ifndef CDVR_LONG_INDEX
    if (v->tiled) {
        __global const uint *q = (__global const uint *)p;
        vint x1 = x0 + (sx != 0), y1 = y0 + (sy != 0), z1 = z0 + (sz != 0);
        vint wx0 = along_x(x0), wx1 = along_x(x1);
        vuint sh0 = as_uint16((x0 & 3) << 3), sh1 = as_uint16((x1 & 3) << 3);
        vint wy0 = along_y(v, y0), wy1 = along_y(v, y1);
        vint wz0 = along_z(v, z0), wz1 = along_z(v, z1);
        vint zero = (vint)(0);
        c00 = lerp_row(q, select(zero, wy0 + wz0, on), wx0, wx1, sh0, sh1, fx);
        c10 = lerp_row(q, select(zero, wy1 + wz0, on), wx0, wx1, sh0, sh1, fx);
        c01 = lerp_row(q, select(zero, wy0 + wz1, on), wx0, wx1, sh0, sh1, fx);
        c11 = lerp_row(q, select(zero, wy1 + wz1, on), wx0, wx1, sh0, sh1, fx);
        return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
    }
#endif
#ifdef __ENDIAN_LITTLE__
    if (sx == 1) {
#if defined(HAVE_BYTE_GATHER) && !defined(CDVR_LONG_INDEX)
        /* one gather per row pair where the lanes' 16 loads took 0.78-0.85 of the time on an
         * Intel Xeon (dense frames, 512^2: Colin27 step 0.5 0.81, step 1.0 0.86, engine CT
         * 0.78; per-process minimums of 30 frames, 5 alternating pairs) */
        if (v->last_word >= 0) {
            int last = v->last_word;
            c00 = lerp_pairs(pairs16_gathered(p, base, 0, last), fx);
            c10 = lerp_pairs(pairs16_gathered(p, base, sy, last), fx);
            c01 = lerp_pairs(pairs16_gathered(p, base, sz, last), fx);
            c11 = lerp_pairs(pairs16_gathered(p, base, sz + sy, last), fx);
            return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
        }
#endif
        c00 = lerp_pairs(pairs16(p, base, 0), fx);
        c10 = lerp_pairs(pairs16(p, base, sy), fx);
        c01 = lerp_pairs(pairs16(p, base, sz), fx);
        c11 = lerp_pairs(pairs16(p, base, sz + sy), fx);
        return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
    }
#endif
    c00 = mix(gather16(p, base), gather16(p, base + sx), fx);
    c10 = mix(gather16(p, base + sy), gather16(p, base + sy + sx), fx);
    c01 = mix(gather16(p, base + sz), gather16(p, base + sz + sx), fx);
    c11 = mix(gather16(p, base + sz + sy), gather16(p, base + sz + sy + sx), fx);
    return mix(mix(c00, c10, fy), mix(c01, c11, fy), fz);
#endif
}

__attribute__((always_inline)) static inline vfloat trilinear(const volume_geo *v, vec3x g)
{
    return trilinear_on(v, g, (vint)(-1));
}

/* Classified sample per lane: rgb lerped from the table, alpha per the caller. */
typedef struct rgbax {
    vfloat r, g, b, a;
} rgbax;

/* Rows w and w + 1 of the TF table per lane, 64-bit words (cl_render.c upload_tables: the
 * step-corrected alpha as a float in the low half, r, g, b as unorm 11, 11, 10 bits in the
 * high one; against two 64-bit channel pairs per row: engine CT 512^2 step 0.5 0.87 of the
 * time). The two rows lie side by side, so a lane reads both in one 16-byte load: against one
 * load per row, alternating kernels, engine CT 512^2 step 0.5 0.926 of the time, Colin27
 * 0.958, zfp1 playback at 512^2 1.06x the fps. *r0 and *r1 get the loads' even and odd
 * words. */
#define TABLE_PAIR(k) vload2(0, t + (uint)w.s##k)
__attribute__((always_inline)) static inline void table_pairs(__global const ulong *t, vint w,
                                                              ulong16 *r0, ulong16 *r1)
{
    ulong16 lo = (ulong16)(TABLE_PAIR(0), TABLE_PAIR(1), TABLE_PAIR(2), TABLE_PAIR(3),
                           TABLE_PAIR(4), TABLE_PAIR(5), TABLE_PAIR(6), TABLE_PAIR(7));
    ulong16 hi = (ulong16)(TABLE_PAIR(8), TABLE_PAIR(9), TABLE_PAIR(a), TABLE_PAIR(b),
                           TABLE_PAIR(c), TABLE_PAIR(d), TABLE_PAIR(e), TABLE_PAIR(f));
    *r0 = (ulong16)(lo.even, hi.even);
    *r1 = (ulong16)(lo.odd, hi.odd);
}

/* A table row's rgba. */
static rgbax table_rgba(ulong16 row)
{
    uint16 hi = convert_uint16(row >> 32);
    return (rgbax){convert_vfloat(hi & 0x7ffu) * (1.0f / 2047.0f),
                   convert_vfloat((hi >> 11) & 0x7ffu) * (1.0f / 2047.0f),
                   convert_vfloat(hi >> 22) * (1.0f / 1023.0f),
                   as_float16(convert_uint16(row))};
}

/* render.h step 4 for full segments: lerp of rgb and of the step-corrected alpha. *i0_out and
 * *fr_out give the table position for the shorter last segment's alpha. */
__attribute__((always_inline)) static inline rgbax classify(vfloat s, __global const ulong *table,
                                                            vint *i0_out, vfloat *fr_out)
{
    vint i0 = min(convert_vint(s), 254);
    vfloat fr = s - convert_vfloat(i0);
    ulong16 row0, row1;
    table_pairs(table, i0, &row0, &row1);
    rgbax c0 = table_rgba(row0), c1 = table_rgba(row1);
    *i0_out = i0;
    *fr_out = fr;
    return (rgbax){mix(c0.r, c1.r, fr), mix(c0.g, c1.g, fr), mix(c0.b, c1.b, fr),
                   mix(c0.a, c1.a, fr)};
}

/* render.h step 5 on the lanes whose alpha is given (others pass 0 and change nothing). */
static void composite(rgbax *acc, rgbax c)
{
    vfloat w = (1.0f - acc->a) * c.a;
    acc->r += w * c.r;
    acc->g += w * c.g;
    acc->b += w * c.b;
    acc->a += w;
}

/* ---- shading, gradient opacity and the other blend modes (render.h) ----------------------- */

static vec3x clamp_grid(const volume_geo *v, vec3x g)
{
    return (vec3x){clamp(g.x, 0.0f, v->top.x), clamp(g.y, 0.0f, v->top.y),
                   clamp(g.z, 0.0f, v->top.z)};
}

/* One axis of the central difference: (s(g+) - s(g-)) / ((g+ - g-) spacing), 0 where g+ == g-. */
#define CENTRAL(AX, SP)                                                                        \
    do {                                                                                       \
        vec3x gp = g, gm = g;                                                                  \
        gp.AX = fmin(g.AX + 1.0f, v->top.AX);                                                  \
        gm.AX = fmax(g.AX - 1.0f, 0.0f);                                                       \
        vfloat h = gp.AX - gm.AX;                                                              \
        vfloat diff = trilinear(v, gp) - trilinear(v, gm);                                     \
        dq.AX = select((vfloat)(0.0f), diff / (h * (SP)), h > 0.0f);                           \
    } while (0)

#ifndef CDVR_LONG_INDEX
/* ---- the gradient from the tiled copy ------------------------------------------------------
 * The six trilinear values of the central differences at g +- one voxel per axis use 32
 * voxels: rows x0 - 1 .. x0 + 2 at (y0, y1) x (z0, z1), and x0, x1 at rows y0 - 1 .. y0 + 2
 * (z0, z1) and z0 - 1 .. z0 + 2 (y0, y1), where (x0, y0, z0) is g's trilinear corner. They lie
 * in 12 tile rows of two words each: 24 gathers instead of the 48 of six trilinear calls (the
 * gradient was 55% of a shaded frame). Each value is computed as trilinear() computes it, from
 * the corners and weights of its own position (g + 1 may round, and both ends clamp), so the
 * results are the same bits; a voxel outside the rows read only ever gets weight 0 (the upper
 * corner of a position that rounded up to a whole number), and a packet with any lane whose
 * corners fall outside (clipped rendering's offsets) takes six trilinear calls instead. */

/* Per lane, the corners of g, g + 1 and g - 1 (clamped as CENTRAL clamps) on one axis: c0 and
 * weight f0 of g; dp, dm the corners of g + 1 and g - 1 relative to c0, fp, fm their weights;
 * h the distance between the two. Returns the lanes whose corners the tile rows hold. */
typedef struct axis_corners {
    vint c0, dp, dm;
    vfloat f0, fp, fm, h;
} axis_corners;

static vint axis_corners_at(vfloat g, float top, int base_max, float offset, axis_corners *a)
{
    vfloat gp = fmin(g + 1.0f, top), gm = fmax(g - 1.0f, 0.0f);
    a->h = gp - gm;
    a->c0 = corner(g - offset, top, base_max, &a->f0);
    a->dp = corner(gp - offset, top, base_max, &a->fp) - a->c0;
    a->dm = corner(gm - offset, top, base_max, &a->fm) - a->c0;
    return ((a->dp >= 0 & a->dp <= 1) | (a->dp == 2 & a->fp == 0.0f)) &
           (a->dm == -1 | a->dm == 0);
}

/* Voxels x0 - 1 .. x0 + 2 of tile row `row` per lane, as bytes 0..3 (low first): the words at
 * row + wlo and row + whi funnel-shifted by sh bits. Voxels outside the volume are arbitrary. */
#define QUAD_LO(k) q[lo.s##k]
#define QUAD_HI(k) q[hi.s##k]
__attribute__((always_inline)) static inline vuint row_quad(__global const uint *q, vint row,
                                                            vint wlo, vint whi, ulong16 sh)
{
    vint lo = row + wlo, hi = row + whi;
    ulong16 both = convert_ulong16((vuint)(L16(QUAD_LO))) |
                   (convert_ulong16((vuint)(L16(QUAD_HI))) << 32);
    return convert_uint16(both >> sh);
}

/* Byte k (0..3) of each lane's quad, as a float. */
static vfloat quad_at(vuint quad, vint k)
{
    return convert_vfloat((quad >> as_uint16(k << 3)) & 0xffu);
}

/* The x-lerp of quad slots k and k + 1 (slot 3 stands in for slot 4, which only gets weight 0). */
static vfloat quad_lerp(vuint quad, vint k, vfloat f)
{
    return mix(quad_at(quad, k), quad_at(quad, min(k + 1, 3)), f);
}

/* Row j in -1..2 of four per lane: r[j + 1]. */
static vfloat row_pick(const vfloat *r, vint j)
{
    return select(select(select(r[0], r[1], j == 0), r[2], j == 1), r[3], j == 2);
}

/* Lerp of rows r[dp + 1], r[dp + 2] by fp (g + 1) and of r[dm + 1], r[dm + 2] by fm (g - 1):
 * four values per lane indexed -1..2 along an axis with corners `a`. */
static void along_axis(const vfloat *r, const axis_corners *a, vfloat *plus, vfloat *minus)
{
    *plus = mix(row_pick(r, a->dp), row_pick(r, min(a->dp + 1, 2)), a->fp);
    *minus = mix(row_pick(r, a->dm), row_pick(r, a->dm + 1), a->fm);
}

/* The differences trilinear(g + 1) - trilinear(g - 1) per axis (dq) and the distances h of
 * CENTRAL, from the tile rows; returns 0 (dq unset) when some lane of `on` needs voxels
 * outside them. */
static int central_tiled(const volume_geo *v, vec3x g, vint on, vec3x *dq, vec3x *h)
{
    axis_corners ax, ay, az;
    vint ok = axis_corners_at(g.x, v->top.x, v->base_max.x, v->offset.x, &ax) &
              axis_corners_at(g.y, v->top.y, v->base_max.y, v->offset.y, &ay) &
              axis_corners_at(g.z, v->top.z, v->base_max.z, v->offset.z, &az);
    if (lanes_any(on & ~ok))
        return 0;
    __global const uint *q = (__global const uint *)v->vol;
    int xmax = v->dims.x - 1;
    vint wlo = along_x(clamp(ax.c0 - 1, 0, xmax)), whi = along_x(clamp(ax.c0 + 2, 0, xmax));
    ulong16 sh = convert_ulong16(((ax.c0 - 1) & 3) << 3);
    vint one = (vint)(1);
    /* word offsets of rows y0 - 1 .. y0 + 2 and z0 - 1 .. z0 + 2 (clamped to the volume; lanes
     * off `on` read word 0, as trilinear_on reads voxel 0) */
    vint wy[4], wz[4];
    for (int j = 0; j < 4; j++) {
        wy[j] = along_y(v, clamp(ay.c0 + (j - 1), 0, v->dims.y - 1));
        wz[j] = along_z(v, clamp(az.c0 + (j - 1), 0, v->dims.z - 1));
    }
    vint zero = (vint)(0);
    /* y rows -1..2 at z0 and z1; z rows -1..2 at y0 and y1 (the four central rows in both) */
    vuint yq0[4], yq1[4], zq0[4], zq1[4];
    for (int j = 0; j < 4; j++) {
        yq0[j] = row_quad(q, select(zero, wy[j] + wz[1], on), wlo, whi, sh);
        yq1[j] = row_quad(q, select(zero, wy[j] + wz[2], on), wlo, whi, sh);
    }
    zq0[1] = yq0[1];
    zq0[2] = yq1[1];
    zq1[1] = yq0[2];
    zq1[2] = yq1[2];
    for (int l = 0; l < 4; l += 3) {
        zq0[l] = row_quad(q, select(zero, wy[1] + wz[l], on), wlo, whi, sh);
        zq1[l] = row_quad(q, select(zero, wy[2] + wz[l], on), wlo, whi, sh);
    }
    /* x: the four central rows, lerped at g + 1 and g - 1 along x, then y, then z */
    vint kp = ax.dp + 1, km = ax.dm + 1;
    vfloat p00 = quad_lerp(yq0[1], kp, ax.fp), p10 = quad_lerp(yq0[2], kp, ax.fp);
    vfloat p01 = quad_lerp(yq1[1], kp, ax.fp), p11 = quad_lerp(yq1[2], kp, ax.fp);
    vfloat m00 = quad_lerp(yq0[1], km, ax.fm), m10 = quad_lerp(yq0[2], km, ax.fm);
    vfloat m01 = quad_lerp(yq1[1], km, ax.fm), m11 = quad_lerp(yq1[2], km, ax.fm);
    vfloat xp = mix(mix(p00, p10, ay.f0), mix(p01, p11, ay.f0), az.f0);
    vfloat xm = mix(mix(m00, m10, ay.f0), mix(m01, m11, ay.f0), az.f0);
    /* y: rows x-lerped at g's x, along y at z0 and z1, then z */
    vfloat r0[4], r1[4];
    for (int j = 0; j < 4; j++) {
        r0[j] = quad_lerp(yq0[j], one, ax.f0);
        r1[j] = quad_lerp(yq1[j], one, ax.f0);
    }
    vfloat yp0, ym0, yp1, ym1;
    along_axis(r0, &ay, &yp0, &ym0);
    along_axis(r1, &ay, &yp1, &ym1);
    vfloat yp = mix(yp0, yp1, az.f0), ym = mix(ym0, ym1, az.f0);
    /* z: rows x-lerped, y-lerped per z, then along z */
    vfloat rz[4];
    for (int l = 0; l < 4; l++)
        rz[l] = mix(quad_lerp(zq0[l], one, ax.f0), quad_lerp(zq1[l], one, ax.f0), ay.f0);
    vfloat zp, zm;
    along_axis(rz, &az, &zp, &zm);
    *dq = (vec3x){xp - xm, yp - ym, zp - zm};
    *h = (vec3x){ax.h, ay.h, az.h};
    return 1;
}
#endif
#ifndef CDVR_LONG_INDEX
/* The gradient copy's words at w per lane, unpacked: D_x, D_y, D_z. */
#define GRAD_AT(k) v->grads[w.s##k]
static vec3x grad_words(const volume_geo *v, vint w)
{
    vuint d = (vuint)(L16(GRAD_AT));
    vint bias = (vint)(CDVR_CL_GRAD_BIAS);
    return (vec3x){convert_vfloat(as_int16(d & 0x3ffu) - bias),
                   convert_vfloat(as_int16((d >> 10) & 0x3ffu) - bias),
                   convert_vfloat(as_int16((d >> 20) & 0x3ffu) - bias)};
}

static vec3x mix3(vec3x a, vec3x b, vfloat f)
{
    return (vec3x){mix(a.x, b.x, f), mix(a.y, b.y, f), mix(a.z, b.z, f)};
}

/* The differences of CENTRAL per axis (dq) from the gradient copy: the
 * trilinear interpolation of the voxels' central differences at g (8 words instead of 32
 * voxels; equal to CENTRAL's in exact arithmetic, within float rounding otherwise). Returns
 * 0 when some lane of `on` has a corner voxel on the frame's border (its differences there
 * are one-sided: CENTRAL then). Clipped renders have no gradient copy: g is the frame's own
 * grid position. */
static int central_copied(const volume_geo *v, vec3x g, vint on, vec3x *dq)
{
    vfloat fx, fy, fz;
    vint x0 = corner(g.x, v->top.x, v->base_max.x, &fx);
    vint y0 = corner(g.y, v->top.y, v->base_max.y, &fy);
    vint z0 = corner(g.z, v->top.z, v->base_max.z, &fz);
    vint inside = x0 >= 1 & x0 <= v->dims.x - 3 & y0 >= 1 & y0 <= v->dims.y - 3 & z0 >= 1 &
                  z0 <= v->dims.z - 3;
    if (lanes_any(on & ~inside))
        return 0;
    vint x1 = x0 + 1, y1 = y0 + 1, z1 = z0 + 1, zero = (vint)(0);
    vint wx0 = copy_x(x0), wx1 = copy_x(x1);
    vint wy0 = copy_y(v, y0), wy1 = copy_y(v, y1), wz0 = copy_z(v, z0), wz1 = copy_z(v, z1);
    vint r00 = select(zero, wy0 + wz0, on), r10 = select(zero, wy1 + wz0, on);
    vint r01 = select(zero, wy0 + wz1, on), r11 = select(zero, wy1 + wz1, on);
    vec3x c00 = mix3(grad_words(v, r00 + wx0), grad_words(v, r00 + wx1), fx);
    vec3x c10 = mix3(grad_words(v, r10 + wx0), grad_words(v, r10 + wx1), fx);
    vec3x c01 = mix3(grad_words(v, r01 + wx0), grad_words(v, r01 + wx1), fx);
    vec3x c11 = mix3(grad_words(v, r11 + wx0), grad_words(v, r11 + wx1), fx);
    *dq = mix3(mix3(c00, c10, fy), mix3(c01, c11, fy), fz);
    return 1;
}
#endif

/* CENTRAL's differences per axis, divided by distance and spacing, as render.h defines them
 * (from the tile rows when the frame is tiled); noinline: only packets off the gradient copy
 * come here. */
__attribute__((noinline)) static vec3x central_exact(const volume_geo *v,
                                                     const look_params *lk, vec3x g, vint on)
{
    vec3x dq;
#if !defined(CDVR_LONG_INDEX) && !defined(CDVR_FETCH)
    vec3x diff, h;
    if (v->tiled && central_tiled(v, g, on, &diff, &h)) {
        dq.x = select((vfloat)(0.0f), diff.x / (h.x * lk->spacing[0]), h.x > 0.0f);
        dq.y = select((vfloat)(0.0f), diff.y / (h.y * lk->spacing[1]), h.y > 0.0f);
        dq.z = select((vfloat)(0.0f), diff.z / (h.z * lk->spacing[2]), h.z > 0.0f);
        return dq;
    }
#endif
    CENTRAL(x, lk->spacing[0]);
    CENTRAL(y, lk->spacing[1]);
    CENTRAL(z, lk->spacing[2]);
    return dq;
}

/* World gradient (codes per world unit) at grid position g (clamped like render_cpu.c) on
 * lanes `on` (others get any finite value). From the gradient copy, the differences (over a
 * distance of 2 voxels: inside the frame CENTRAL's h is 2 within rounding) go through
 * grad_to_world with the division folded in. */
__attribute__((always_inline)) static inline vec3x gradient(const volume_geo *v,
                                                            const look_params *lk, vec3x g,
                                                            vint on)
{
    g = clamp_grid(v, g);
    const float *m = lk->grad_to_world;
#ifndef CDVR_LONG_INDEX
#ifndef CDVR_FETCH
    vec3x diff;
    if (v->grads_on && central_copied(v, g, on, &diff)) {
        float sx = 0.5f / lk->spacing[0], sy = 0.5f / lk->spacing[1], sz = 0.5f / lk->spacing[2];
        return (vec3x){m[0] * sx * diff.x + m[1] * sy * diff.y + m[2] * sz * diff.z,
                       m[3] * sx * diff.x + m[4] * sy * diff.y + m[5] * sz * diff.z,
                       m[6] * sx * diff.x + m[7] * sy * diff.y + m[8] * sz * diff.z};
    }
#endif
#endif
    vec3x dq = central_exact(v, lk, g, on);
    return (vec3x){m[0] * dq.x + m[1] * dq.y + m[2] * dq.z, m[3] * dq.x + m[4] * dq.y + m[5] * dq.z,
                   m[6] * dq.x + m[7] * dq.y + m[8] * dq.z};
}

static vfloat length3x(vec3x a)
{
    return sqrt(a.x * a.x + a.y * a.y + a.z * a.z);
}

/* x^n per lane (n >= 0) by binary exponentiation, lowest bit first (render.h: the specular
 * term; the brick march's transparency of n segments of transparency x): pow is a call per
 * lane on a CPU device. */
static vfloat power_of(vfloat x, vint n)
{
    vfloat p = (vfloat)(1.0f);
    for (int bit = 0; lanes_any((n >> bit) != 0); bit++) {
        p = select(p, p * x, ((n >> bit) & 1) != 0);
        x = x * x;
    }
    return p;
}

/* render.h's |n.H|^power: repeated squaring for a whole power up to CDVR_CL_WHOLE_POWER_MAX
 * (VTK's default 10), else pow. The power is the same for every lane: power_of's products,
 * in a loop the compiler unrolls without per-bit lane tests. */
static vfloat specular_power(vfloat x, float power)
{
    if (power == floor(power) && power <= CDVR_CL_WHOLE_POWER_MAX) {
        vfloat p = (vfloat)(1.0f);
        for (int n = (int)power; n != 0; n >>= 1) {
            if (n & 1)
                p = p * x;
            x = x * x;
        }
        return p;
    }
    return pow(x, power);
}

/* Per ray, what shading needs of the viewer: the light L (the headlight: towards the eye)
 * and the half vector H = L + V over its length (0 where that is 0), made once per packet:
 * |n.H| / |H| per sample is then a product (within rounding of the quotient). */
typedef struct viewer {
    vec3x L, H;
} viewer;

static viewer make_viewer(const look_params *lk, vec3x V)
{
    viewer w;
    w.L = lk->headlight ? V : (vec3x){(vfloat)lk->light[0], (vfloat)lk->light[1],
                                      (vfloat)lk->light[2]};
    vec3x H = {w.L.x + V.x, w.L.y + V.y, w.L.z + V.z};
    vfloat hl = length3x(H);
    vfloat inv = select((vfloat)(0.0f), 1.0f / hl, hl > 0.0f);
    w.H = (vec3x){H.x * inv, H.y * inv, H.z * inv};
    return w;
}

/* rgb' = min(1, rgb (ambient + diffuse |n.L|) + specular |n.H|^power), two-sided. */
static void shade_rgb(const look_params *lk, vec3x G, const viewer *view, rgbax *c)
{
    vfloat len = length3x(G);
    vint ok = len >= 1e-12f;
    vfloat inv = select((vfloat)(0.0f), 1.0f / len, ok);
    vec3x n = {G.x * inv, G.y * inv, G.z * inv};
    vec3x L = view->L, H = view->H;
    vfloat ndl = fabs(n.x * L.x + n.y * L.y + n.z * L.z);
    vfloat ndh = fabs(n.x * H.x + n.y * H.y + n.z * H.z);
    vfloat spec = select((vfloat)(0.0f), lk->specular * specular_power(ndh, lk->power), ndh > 0.0f);
    vfloat k = lk->ambient + lk->diffuse * ndl;
    c->r = fmin(c->r * k + spec, 1.0f);
    c->g = fmin(c->g * k + spec, 1.0f);
    c->b = fmin(c->b * k + spec, 1.0f);
}

static vfloat go_factor(const look_params *lk, vfloat m)
{
    int n = lk->go_points;
    vfloat f = (vfloat)(lk->go_factor[n - 1]);
    for (int i = n - 1; i >= 1; i--) {
        float lo = lk->go_mag[i - 1], w = lk->go_mag[i] - lo;
        vfloat t = w > 0.0f ? (m - lo) / w : (vfloat)(1.0f);
        f = select(f, mix((vfloat)(lk->go_factor[i - 1]), (vfloat)(lk->go_factor[i]), t),
                   m <= lk->go_mag[i]);
    }
    return select(f, (vfloat)(lk->go_factor[0]), m <= lk->go_mag[0]);
}

/* Channel ch of the exact TF rows (r, g, b, alpha per unit as floats: cl_render.c
 * upload_tables) lerped between rows i0 and i0 + 1 by fr. */
#define TF_ROW0(k) rows[4 * i0.s##k + ch]
#define TF_ROW1(k) rows[4 * i0.s##k + 4 + ch]
__attribute__((always_inline)) static inline vfloat row_lerp(__global const float *rows,
                                                            vint i0, vfloat fr, int ch)
{
    return mix((vfloat)(L16(TF_ROW0)), (vfloat)(L16(TF_ROW1)), fr);
}

/* Shading and gradient opacity of composite samples c at g on lanes `on` (opacity > 0): the
 * alpha becomes 1 - (1 - a * factor)^(ds/unit) from the table's alpha per unit. */
/* always inlined: as a call its vector arguments go through memory (a quarter of a shaded
 * frame's time outside the gradient) */
__attribute__((always_inline)) static inline void look_sample(
    const volume_geo *v, const look_params *lk, vec3x g, vint i0, vfloat fr, vfloat ds,
    float unit, __global const float *rows, const viewer *V, vint on, rgbax *c)
{
    vec3x G = gradient(v, lk, g, on);
    if (lk->go_points) {
        vfloat raw = row_lerp(rows, i0, fr, 3);
        vfloat a = raw * go_factor(lk, length3x(G) * lk->value_per_code);
        vfloat corrected = select((vfloat)(0.0f), 1.0f - pow(1.0f - a, ds / unit), a > 0.0f);
        c->a = select(c->a, corrected, on);
    }
    if (lk->shade) {
        rgbax shaded = *c;
        shade_rgb(lk, G, V, &shaded);
        on &= c->a > 0.0f;
        c->r = select(c->r, shaded.r, on);
        c->g = select(c->g, shaded.g, on);
        c->b = select(c->b, shaded.b, on);
    }
}

typedef struct bricks {
    __global const uchar *dist; /* per brick: d if invisible, 128 + d if visible (see host) */
    int shift, nbx, nby, nbz;   /* brick edge 1 << shift */
    vec3x inv_dg;              /* 1 / dg per axis, +inf where dg is 0 */
    vint fwd_x, fwd_y, fwd_z;   /* -1 where dg >= 0: the ray leaves by the upper face */
} bricks;

/* The flag buffer d's codes at brick indices idx. A CPU device with AVX-512 reads them as
 * the low bytes of 32-bit words at the indices, one gather (the buffers hold
 * CDVR_CL_FLAGS_PAD bytes more), where a load per lane took 5-6% of the composite march's
 * time (perf, Colin27 512^2 step 1.0; with it 0.975 of the time, slicer TF 0.979: per-process
 * minimums of 40 frames, 6 alternating pairs, Intel Xeon). */
#define CODE_AT(k) d[(uint)idx.s##k]
static vint flag_codes(__global const uchar *d, vint idx)
{
#ifdef HAVE_BYTE_GATHER
    return WORDS_AT(d, idx) & 0xff;
#else
    return convert_vint((uchar16)(L16(CODE_AT)));
#endif
}

/* Per lane, the parameter of the face where the ray leaves the cube of like bricks around
 * the brick holding grid point g. Code d (invisible) or 128 + d (visible) from the host says
 * that all bricks within chessboard distance d - 1 share its state. */
static vfloat brick_exit(const bricks *b, const volume_geo *v, vec3x g0, vec3x g,
                         vint *visible)
{
    vint bx = min(convert_vint(clamp(g.x, 0.0f, v->top.x)) >> b->shift, b->nbx - 1);
    vint by = min(convert_vint(clamp(g.y, 0.0f, v->top.y)) >> b->shift, b->nby - 1);
    vint bz = min(convert_vint(clamp(g.z, 0.0f, v->top.z)) >> b->shift, b->nbz - 1);
    vint idx = bx + b->nbx * (by + b->nby * bz);
    vint code = flag_codes(b->dist, idx);
    *visible = code >= 128;
    vint reach = max(code & 127, 1) - 1; /* bricks on each side that are alike */
    vint fx = select(bx - reach, bx + reach + 1, b->fwd_x);
    vint fy = select(by - reach, by + reach + 1, b->fwd_y);
    vint fz = select(bz - reach, bz + reach + 1, b->fwd_z);
    vfloat tx = (convert_vfloat(fx << b->shift) - g0.x) * b->inv_dg.x;
    vfloat ty = (convert_vfloat(fy << b->shift) - g0.y) * b->inv_dg.y;
    vfloat tz = (convert_vfloat(fz << b->shift) - g0.z) * b->inv_dg.z;
    return fmin(tx, fmin(ty, tz));
}

/* The least length (in voxels along the ray's longest axis) of a visible run: a lane that
 * meets a visible brick samples on past its face rather than look up every 4-voxel brick
 * (samples in invisible bricks add nothing: their alpha is 0, so the image is the same). A
 * look-up costs about as much as a step of samples: Colin27 512^2 at 2 voxels per sample,
 * 10.4 -> 8.0 ms per frame, engine CT 11.3 -> 8.6 ms; 8, 12, 24 voxels measured no better. */
#define RUN_VOXELS 16.0f
/* Tolerance (in samples) that keeps a skip short of the computed brick exit, so rounding
 * never skips a sample that lies past the brick's face. */
#define SKIP_MARGIN 0.01f

/* March state of a packet over its full segments. */
typedef struct march {
    vint i, end, n_full, active, done, taken;
    int unroll; /* samples per lane per step inside visible runs: UNROLL or UNROLL_SHORT */
    int run_min; /* fewest samples a visible run holds (RUN_VOXELS) */
} march;

static vec3x at(vec3x g0, vec3x dg, vint i)
{
    vfloat fi = convert_vfloat(i);
    return (vec3x){g0.x + fi * dg.x, g0.y + fi * dg.y, g0.z + fi * dg.z};
}

/* Lanes whose visible run is used up look up their brick: an invisible cube moves the lane's
 * index past it, a visible one sets the end of the lane's next run (at the cube's exit, and
 * at least run_min samples on). */
static void brick_step(march *m, vint need, const bricks *b, const volume_geo *v, vec3x g0,
                       vec3x dg)
{
    vint visible;
    vfloat t_exit = fmin(brick_exit(b, v, g0, at(g0, dg, m->i), &visible),
                         convert_vfloat(m->n_full));
    vint skip_to = max(m->i + 1, convert_vint(ceil(t_exit - SKIP_MARGIN)));
    vint run_end =
        clamp(max(convert_vint(ceil(t_exit)), m->i + m->run_min), m->i + 1, m->n_full);
    m->i = select(m->i, select(skip_to, m->i, visible), need);
    m->end = select(m->end, select(m->end, run_end, visible), need);
}

/* Clipped rendering: lanes whose sample at whole-volume grid position g is in the owned
 * cells (all lanes when not clipped). */
static vint owned(const clip_params *c, vec3x g)
{
    if (!c->enabled)
        return (vint)(-1);
    vfloat gx = clamp(g.x, 0.0f, c->whole_top[0]), gy = clamp(g.y, 0.0f, c->whole_top[1]);
    vfloat gz = clamp(g.z, 0.0f, c->whole_top[2]);
    return (gx >= c->own_lo[0]) & ((gx < c->own_hi[0]) | (vint)(-c->own_far[0])) &
           (gy >= c->own_lo[1]) & ((gy < c->own_hi[1]) | (vint)(-c->own_far[1])) &
           (gz >= c->own_lo[2]) & ((gz < c->own_hi[2]) | (vint)(-c->own_far[2]));
}

/* CPU devices (PoCL) prefetch, PREFETCH_AHEAD samples ahead of each step, the tile row (or quad
 * word) of every running lane's lower corner, and its gradient copy's word when the render
 * reads one, so the cache misses of a ray entering new tiles overlap the samples before it:
 * the composite march waits on its gathers' misses, not on their count (perf on an AMD EPYC,
 * Colin27 512^2: a fifth of march_full's cycles on the first gather of a sample). Measured
 * with both kernels alternating (CDVR_KERNELS, 6-12 pairs, medians of per-pair ratios) on
 * that machine: Colin27 512^2 step 0.5 0.943 of the time without, engine CT (quad copy)
 * 512^2 step 0.5 0.921, step 1 0.927; shaded (gradient copy) Colin27 0.941, engine CT
 * 0.954; max (march_extreme, every 4 samples) engine CT 0.915, Colin27 0.999; Colin27 1024^2
 * step 0.5, average and the 256^3 zfp playback of scale.lua even (1.009, 0.98-1.0, 0.98 of
 * the fps); 8 and 32 samples ahead no better than 16. Dense frames (the device's choice on
 * that machine, cl_device.c) get the four voxel rows of the lower corners PREFETCH_AHEAD_DENSE
 * samples ahead in the composite march: Colin27 512^2 step 0.5 0.87-0.92 of the time (8 ahead;
 * 6: 0.91, 12: 0.89, 16: 0.94; two rows instead of four: 0.97), 1024^2 0.97, step 1 even;
 * engine CT composite even; the zfp playback 1.03x the fps. The extreme march leaves dense
 * frames out: engine CT max took 1.08x the time with it, Colin27 max 0.98. OpenCL's
 * prefetch() is a no-op in PoCL; __builtin_prefetch never faults, so lanes off the volume
 * need no clamp beyond the corners'. GPU compilers leave it out. */
#if defined(__has_builtin) && (defined(__x86_64__) || defined(__aarch64__)) &&                  \
    !defined(CDVR_FETCH) && !defined(CDVR_LONG_INDEX)
#if __has_builtin(__builtin_prefetch)
#define HAVE_PREFETCH 1
#endif
#endif
#ifdef HAVE_PREFETCH
#define PREFETCH_AHEAD 16      /* samples ahead: tiled and quad copies */
#define PREFETCH_AHEAD_DENSE 8 /* dense frames, whose four voxel rows per sample lie apart */
/* The prefetch for lanes `on` at sample i + the layout's distance along g0 + i * dg; of dense
 * frames only with `dense_too`. */
__attribute__((always_inline)) static inline void prefetch_corners(const volume_geo *v, vec3x g0,
                                                                vec3x dg, vint i, vint on,
                                                                int dense_too)
{
    int dense = !(v->tiled | v->quads_on);
    if (dense && !dense_too)
        return;
    vec3x g = at(g0, dg, i + (dense ? PREFETCH_AHEAD_DENSE : PREFETCH_AHEAD));
    vint x = clamp(convert_vint(g.x - v->offset.x), 0, v->base_max.x);
    vint y = clamp(convert_vint(g.y - v->offset.y), 0, v->base_max.y);
    vint z = clamp(convert_vint(g.z - v->offset.z), 0, v->base_max.z);
    uint words[RAY_PACKET];
    if (dense) { /* the rows of the cell's four voxel pairs (trilinear_on's pairs16) */
        int sy = (int)v->stride.y, sz = (int)v->stride.z;
        vstore16(as_uint16(select((vint)(0), x + sy * y + sz * z, on)), 0, words);
        for (int k = 0; k < RAY_PACKET; k++) {
            __global const uchar *row = v->vol + words[k];
            __builtin_prefetch(row);
            __builtin_prefetch(row + sy);
            __builtin_prefetch(row + sz);
            __builtin_prefetch(row + sz + sy);
        }
        return;
    }
    vint w;
    __global const uint *q;
    if (v->quads_on) {
        w = copy_x(x) + copy_y(v, y) + copy_z(v, z);
        q = v->quads;
    } else {
        w = along_x(x) + along_y(v, y) + along_z(v, z);
        q = (__global const uint *)v->vol;
    }
    vstore16(as_uint16(select((vint)(0), w, on)), 0, words);
    for (int k = 0; k < RAY_PACKET; k++)
        __builtin_prefetch(q + words[k]);
    if (v->grads_on) {
        vint gw = v->quads_on ? w : copy_x(x) + copy_y(v, y) + copy_z(v, z);
        vstore16(as_uint16(select((vint)(0), gw, on)), 0, words);
        for (int k = 0; k < RAY_PACKET; k++)
            __builtin_prefetch(v->grads + words[k]);
    }
}
#endif

/* Samples the lanes inside a visible run (all lanes run when skipping is off). */
#define UNROLL 4 /* most samples per lane per step inside visible runs */
#define UNROLL_SHORT 2 /* the same where a run holds fewer than UNROLL samples */

/* Samples the lanes inside a visible run (all lanes run when skipping is off): up to UNROLL
 * each, the k-th only for lanes whose run still holds it and that have not terminated; a
 * sample outside the owned cells (clipped rendering) advances the lane but adds nothing. */
__attribute__((always_inline)) static inline void sample_steps(
    march *m, vint run, const volume_geo *v, const clip_params *clip, vec3x g0, vec3x dg,
    __global const ulong *table, float term_alpha, const look_params *lk,
    __global const float *rows, float step, float unit, const viewer *V, rgbax *acc, const int unroll)
{
    vfloat s[UNROLL];
    vint own[UNROLL];
    vint i_first = m->i;
    for (int k = 0; k < unroll; k++) { /* independent loads, before any compositing */
        vec3x g = at(g0, dg, i_first + k);
        own[k] = owned(clip, g);
        s[k] = trilinear_on(v, g, run & (i_first + k < m->end));
    }
#ifdef HAVE_PREFETCH
    prefetch_corners(v, g0, dg, i_first, run, 1);
#endif
    vint stop = (vint)(0), live = run;
    for (int k = 0; k < unroll; k++) {
        live &= m->i < m->end;
        vint keep = live & ~stop & own[k];
        vint i0;
        vfloat fr;
        rgbax c = classify(s[k], table, &i0, &fr);
        c.a = select((vfloat)(0.0f), c.a, keep);
        if (lk->shade | lk->go_points) {
            vint on = keep & (c.a > 0.0f);
            if (lanes_any(on))
                look_sample(v, lk, at(g0, dg, i_first + k), i0, fr, (vfloat)(step), unit, rows,
                            V, on, &c);
            c.a = select((vfloat)(0.0f), c.a, on);
        }
        composite(acc, c);
        m->i -= live; /* a lane that stopped moves on too: its index is no longer used */
        m->taken -= keep;
        stop |= keep & (acc->a >= term_alpha | acc->a >= 1.0f);
    }
    /* Termination changes the lanes only behind a branch: as a data dependency (of the sample
     * indices, hence of the next step's addresses) it would chain each step's loads to the
     * previous step's compositing, while the branch (rarely taken) lets the CPU start the next
     * step's loads early. */
    if (lanes_any(stop)) {
        m->done |= stop;
        m->active &= ~stop;
    }
    m->active &= m->i < m->n_full;
}

/* Brick look-ups per march step: a lane that jumps an invisible cube looks up the next brick
 * at once (up to BRICK_HOPS cubes) instead of idling through the others' next samples, so more
 * lanes sample in each step (Colin27 512^2 step 1: 5-7% less kernel time than one look-up). */
#ifndef BRICK_HOPS
#define BRICK_HOPS 4
#endif
/* Look-ups are made when at least HOP_MIN lanes (of 16) need one, or no lane can sample
 * without: a look-up costs the whole packet about a step of samples, however few lanes it
 * serves (Colin27 and engine CT 512^2: 3-5% less time than looking up for any lane; 12
 * measured the same). */
#define HOP_MIN 8

/* Samples in RUN_VOXELS voxels along a ray at `step` (world units) on a grid of 1/spacing
 * inv_spacing: the fewest a visible run holds. */
static int run_samples(float step, float3 inv_spacing)
{
    float voxels_per_step = step * fmax(inv_spacing.x, fmax(inv_spacing.y, inv_spacing.z));
    return max((int)(RUN_VOXELS / voxels_per_step + 0.5f), 1);
}

/* Whether lanes `need` (at their run's end) look up their bricks now (HOP_MIN): yes when
 * enough of them need it, or when no lane of `can_sample` could sample meanwhile; else they
 * sample a step on unlooked with the others. */
static int look_up_now(vint need, vint can_sample)
{
    vint one = need & 1;
    int8 m8 = one.lo + one.hi;
    int4 m4 = m8.lo + m8.hi;
    return m4.s0 + m4.s1 + m4.s2 + m4.s3 >= HOP_MIN || !lanes_any(can_sample);
}
static void march_full(march *m, int skipping, const bricks *b, const volume_geo *v,
                       const clip_params *clip, vec3x g0, vec3x dg,
                       __global const ulong *table, float term_alpha, const look_params *lk,
                       __global const float *rows, float step, float unit, const viewer *V,
                       rgbax *acc)
{
    while (lanes_any(m->active)) {
        if (skipping) {
            vint need = m->active & (m->i >= m->end);
            if (!look_up_now(need, m->active & (m->i < m->end)))
                /* samples in invisible bricks add nothing */
                m->end = select(m->end, min(m->i + m->unroll, m->n_full), need);
            else
                for (int hop = 0; hop < BRICK_HOPS && lanes_any(need); hop++) {
                    brick_step(m, need, b, v, g0, dg);
                    m->active &= m->i < m->n_full;
                    need = m->active & (m->i >= m->end);
                }
        }
        vint run = m->active & (m->i < m->end);
        if (!lanes_any(run))
            continue;
        if (m->unroll == UNROLL) /* two copies, each with a constant count */
            sample_steps(m, run, v, clip, g0, dg, table, term_alpha, lk, rows, step, unit, V,
                         acc, UNROLL);
        else
            sample_steps(m, run, v, clip, g0, dg, table, term_alpha, lk, rows, step, unit, V,
                         acc, UNROLL_SHORT);
    }
}

#ifdef CDVR_BRICK_CACHE
/* Lanes `need` look up the brick of their sample i and set their run: up to the first sample
 * past the brick's cells. */
static void cache_lookup(cache_lanes *cl, vint need, vint i, vint n_full, const volume_geo *v,
                         vec3x g0, vec3x dg, const bricks *b)
{
    cache_fill(cl, need, v, at(g0, dg, i));
    vfloat fx = select(vload16(0, cl->cell_lo[0]), vload16(0, cl->cell_hi[0]), b->fwd_x);
    vfloat fy = select(vload16(0, cl->cell_lo[1]), vload16(0, cl->cell_hi[1]), b->fwd_y);
    vfloat fz = select(vload16(0, cl->cell_lo[2]), vload16(0, cl->cell_hi[2]), b->fwd_z);
    vfloat tx = (fx - g0.x) * b->inv_dg.x;
    vfloat ty = (fy - g0.y) * b->inv_dg.y;
    vfloat tz = (fz - g0.z) * b->inv_dg.z;
    vfloat t_exit = clamp(fmin(tx, fmin(ty, tz)), 0.0f, convert_vfloat(n_full));
    vint end = min(max(convert_vint(ceil(t_exit)), i + 1), n_full);
    vstore16(select(vload16(0, cl->end), end, need), 0, cl->end);
}

/* sample_steps through the cache: up to UNROLL groups per lane (one sample each, 2^level
 * level-0 segments each, fewer at the run's end), then composited in order; alpha corrected
 * for the group's segments. `fresh`: lanes whose run was just looked up (never cut). */
/* Lanes whose grid position g lies in a visible range brick (the skip grid's flags). */
static vint range_visible(const bricks *b, const volume_geo *v, vec3x g)
{
    vint bx = min(convert_vint(clamp(g.x, 0.0f, v->top.x)) >> b->shift, b->nbx - 1);
    vint by = min(convert_vint(clamp(g.y, 0.0f, v->top.y)) >> b->shift, b->nby - 1);
    vint bz = min(convert_vint(clamp(g.z, 0.0f, v->top.z)) >> b->shift, b->nbz - 1);
    vint idx = bx + b->nbx * (by + b->nby * bz);
    return flag_codes(b->dist, idx) >= 128;
}

static void cache_sample_steps(march *m, vint run, vint fresh, cache_lanes *cl, uint limit,
                               const bricks *b, const volume_geo *v, const clip_params *clip,
                               vec3x g0, vec3x dg,
                               __global const ulong *table, float term_alpha,
                               const look_params *lk, __global const float *rows, float step,
                               float unit, const viewer *V, rgbax *acc)
{
    cache_run r = load_run(cl, limit);
    vint stop_at = min(m->end, r.end);
    vfloat s[UNROLL], fi[UNROLL];
    vint own[UNROLL], len[UNROLL], in[UNROLL];
    vint ik = m->i;
    for (int k = 0; k < UNROLL; k++) { /* independent loads, before any compositing */
        len[k] = clamp(stop_at - ik, 0, r.group);
        fi[k] = convert_vfloat(ik) + 0.5f * convert_vfloat(max(len[k] - 1, 0));
        vec3x g = {g0.x + fi[k] * dg.x, g0.y + fi[k] * dg.y, g0.z + fi[k] * dg.z};
        own[k] = owned(clip, g);
        s[k] = cache_trilinear(v, &r, g, &in[k]);
        ik += len[k];
        /* a coarse sample counts only where level 0 has opacity (its range brick visible) */
        if (!all(r.group == 1))
            own[k] &= (r.group == 1) | range_visible(b, v, g);
    }
    vint stop = (vint)(0), live = run, cut = (vint)(0), level0 = r.group == 1;
    for (int k = 0; k < UNROLL; k++) {
        live &= len[k] > 0;
        vint out = live & ~in[k] & level0;
        if (k == 0)
            out &= ~fresh;
        cut |= out;
        live &= ~out;
        vint keep = live & own[k];
        vint i0;
        vfloat fr;
        rgbax c = classify(s[k], table, &i0, &fr);
        c.a = select((vfloat)(0.0f), c.a, keep);
        vint multi = keep & (len[k] > 1) & (c.a > 0.0f);
        if (lanes_any(multi))
            c.a = select(c.a, 1.0f - power_of(1.0f - c.a, select((vint)(0), len[k], multi)),
                         multi);
        if (lk->shade | lk->go_points) {
            vint on = keep & (c.a > 0.0f);
            vec3x g = {g0.x + fi[k] * dg.x, g0.y + fi[k] * dg.y, g0.z + fi[k] * dg.z};
            if (lanes_any(on))
                look_sample(v, lk, g, i0, fr, convert_vfloat(max(len[k], 1)) * step, unit,
                            rows, V, on, &c);
            c.a = select((vfloat)(0.0f), c.a, on);
        }
        composite(acc, c);
        m->i += select((vint)(0), len[k], live);
        m->taken -= keep;
        stop |= keep & (acc->a >= term_alpha | acc->a >= 1.0f);
        live &= ~stop;
    }
    if (lanes_any(cut)) /* look the lane up again at the sample it stopped at */
        vstore16(select(r.end, m->i, cut), 0, cl->end);
    if (lanes_any(stop)) {
        m->done |= stop;
        m->active &= ~stop;
    }
    m->active &= m->i < m->n_full;
}

/* march_full through the cache: the skip grid's runs, cut at the cache bricks' exits. */
static void march_cached(march *m, int skipping, const bricks *b, const volume_geo *v,
                         const clip_params *clip, vec3x g0, vec3x dg,
                         __global const ulong *table, float term_alpha, const look_params *lk,
                         __global const float *rows, float step, float unit, const viewer *V,
                         rgbax *acc)
{
    cache_lanes cl;
    cache_lanes_init(&cl);
    uint limit = v->limit;
    while (lanes_any(m->active)) {
        if (skipping) {
            vint need = m->active & (m->i >= m->end);
            if (lanes_any(need)) {
                brick_step(m, need, b, v, g0, dg);
                m->active &= m->i < m->n_full;
            }
        }
        vint run = m->active & (m->i < m->end);
        vint fresh = run & (m->i >= vload16(0, cl.end));
        if (lanes_any(fresh))
            cache_lookup(&cl, fresh, m->i, m->n_full, v, g0, dg, b);
        if (lanes_any(run))
            cache_sample_steps(m, run, fresh, &cl, limit, b, v, clip, g0, dg, table, term_alpha,
                               lk, rows, step, unit, V, acc);
    }
}
#endif

/* The last segment, shorter than step unless L is a multiple of it, on lanes `last`. */
static void last_segment(const packet *p, vint n, vint last, float step, float unit,
                         const volume_geo *v, const clip_params *clip, float3 inv_spacing,
                         __global const ulong *table, __global const float *rows,
                         const look_params *lk, const viewer *V, rgbax *acc, vint *taken)
{
    vfloat ts = p->t_near + convert_vfloat(n - 1) * step;
    vfloat ds = p->t_far - ts;
    last &= ds > 0.0f;
    if (!lanes_any(last))
        return;
    vfloat tm = ts + 0.5f * ds;
    vec3x g = {(p->o.x + tm * p->d.x) * inv_spacing.x, (p->o.y + tm * p->d.y) * inv_spacing.y,
               (p->o.z + tm * p->d.z) * inv_spacing.z};
    last &= owned(clip, g);
    if (!lanes_any(last))
        return;
    vint i0;
    vfloat fr;
    rgbax c = classify(trilinear(v, g), table, &i0, &fr);
    vfloat a = row_lerp(rows, i0, fr, 3);
    /* 1 - pow(1, x) is exactly 0: most last segments lie in empty space */
    vint partial = ds < step & a > 0.0f;
    if (lanes_any(partial))
        a = select(a, 1.0f - pow(1.0f - a, ds / unit), partial);
    c.a = select(a, c.a, ds >= step);
    c.a = select((vfloat)(0.0f), c.a, last & (c.a > 0.0f));
    if (lk->shade | lk->go_points) {
        vint on = last & (c.a > 0.0f);
        if (lanes_any(on))
            look_sample(v, lk, g, i0, fr, ds, unit, rows, V, on, &c);
        c.a = select((vfloat)(0.0f), c.a, on);
    }
    composite(acc, c);
    *taken -= last;
}

/* row_lerp at codes s: the colours of max, min, average and iso, exact where the composite
 * march reads the packed rows. */
static vfloat row_channel(vfloat s, __global const float *rows, int ch)
{
    s = clamp(s, 0.0f, 255.0f);
    vint i0 = min(convert_vint(s), 254);
    return row_lerp(rows, i0, s - convert_vfloat(i0), ch);
}

/* The TF's colour at codes s (alpha 0: max, min, average and iso take their own). */
static rgbax table_at(vfloat s, __global const float *rows)
{
    return (rgbax){row_channel(s, rows, 0), row_channel(s, rows, 1), row_channel(s, rows, 2),
                   (vfloat)(0.0f)};
}

static vfloat raw_alpha(vfloat s, __global const float *rows)
{
    return row_channel(s, rows, 3);
}

/* Sample i (from 0) of each lane: the midpoint of segment i (the shorter last one included),
 * as render_cpu.c's sample_at computes it; *ok: lanes where segment i exists. */
static vec3x sample_point(const packet *p, vint i, vint n, float step, float3 inv_spacing,
                          vint *ok, vfloat *tm)
{
    vfloat ts = p->t_near + convert_vfloat(i) * step;
    vfloat ds = select((vfloat)(step), p->t_far - ts, i >= n - 1);
    *ok = p->hit & (i < n) & (ds > 0.0f);
    *tm = ts + 0.5f * ds;
    return (vec3x){(p->o.x + *tm * p->d.x) * inv_spacing.x, (p->o.y + *tm * p->d.y) * inv_spacing.y,
                   (p->o.z + *tm * p->d.z) * inv_spacing.z};
}

static vec3x point_at(const packet *p, vfloat t, float3 inv_spacing)
{
    return (vec3x){(p->o.x + t * p->d.x) * inv_spacing.x, (p->o.y + t * p->d.y) * inv_spacing.y,
                   (p->o.z + t * p->d.z) * inv_spacing.z};
}

/* Max and min skip bricks that cannot change the lane's extreme: every sample in a brick's
 * cells lies in its [min, max] (the range includes the upper apron trilinear reads), so a brick
 * whose max is at most the lane's max so far (min: whose min is at least its min) is stepped
 * over to its exit face, as the composite march steps over invisible bricks. The result is
 * exactly the unskipped one. */
typedef struct extreme_bricks {
    __global const uchar2 *minmax;
    int shift, nbx, nby, nbz;
    vec3x g0, dg, inv_dg;     /* sample i (full segments) at g0 + i dg */
} extreme_bricks;

/* Lanes `need` look up the brick holding their sample i: one that cannot beat best moves i
 * past its exit face, one that can sets *end to the first sample past it, and at least
 * run_min samples on (the lane then samples up to there without looking again; samples of a
 * brick that cannot beat best change nothing). */
static vint extreme_step(const extreme_bricks *eb, const volume_geo *v, vint *i, vint *end,
                         vfloat *best_io, int is_max, int flats, vint need, int run_min)
{
    vec3x g = at(eb->g0, eb->dg, *i);
    vint bx = min(convert_vint(clamp(g.x, 0.0f, v->top.x)) >> eb->shift, eb->nbx - 1);
    vint by = min(convert_vint(clamp(g.y, 0.0f, v->top.y)) >> eb->shift, eb->nby - 1);
    vint bz = min(convert_vint(clamp(g.z, 0.0f, v->top.z)) >> eb->shift, eb->nbz - 1);
    vint idx = bx + eb->nbx * (by + eb->nby * bz);
    int ids[RAY_PACKET];
    float lim[RAY_PACKET], other[RAY_PACKET];
    vstore16(select((vint)(0), idx, need), 0, ids);
    for (int k = 0; k < RAY_PACKET; k++) {
        uchar2 mm = eb->minmax[ids[k]];
        lim[k] = is_max ? (float)mm.y : (float)mm.x;
        other[k] = is_max ? (float)mm.x : (float)mm.y;
    }
    vfloat limit = vload16(0, lim);
    /* `flats`: a brick of one code c (its range a single code) gives every sample in it the
     * value c, so the lane takes c and skips the brick as dull */
    vint flat = need & (limit == vload16(0, other)) & (vint)(-flats);
    vfloat best = select(*best_io, is_max ? fmax(*best_io, limit) : fmin(*best_io, limit),
                         flat);
    *best_io = best;
    vint dull = is_max ? limit <= best : limit >= best;
    /* a dull brick's block (CDVR_CL_BLOCK_SHIFT), when dull too, is left at once */
    vint block = need & dull, shift = (vint)(eb->shift);
    if (lanes_any(block)) {
        int kx = (eb->nbx + (1 << CDVR_CL_BLOCK_SHIFT) - 1) >> CDVR_CL_BLOCK_SHIFT;
        int ky = (eb->nby + (1 << CDVR_CL_BLOCK_SHIFT) - 1) >> CDVR_CL_BLOCK_SHIFT;
        vint kidx = (bx >> CDVR_CL_BLOCK_SHIFT) +
                    kx * ((by >> CDVR_CL_BLOCK_SHIFT) + ky * (bz >> CDVR_CL_BLOCK_SHIFT));
        __global const uchar2 *blocks = eb->minmax + eb->nbx * eb->nby * eb->nbz;
        vstore16(select((vint)(0), kidx, block), 0, ids);
        for (int k = 0; k < RAY_PACKET; k++) {
            uchar2 mm = blocks[ids[k]];
            lim[k] = is_max ? (float)mm.y : (float)mm.x;
        }
        limit = vload16(0, lim);
        block &= is_max ? limit <= best : limit >= best;
        /* the block as a brick of 2^CDVR_CL_BLOCK_SHIFT times the edge */
        bx = select(bx, bx >> CDVR_CL_BLOCK_SHIFT, block);
        by = select(by, by >> CDVR_CL_BLOCK_SHIFT, block);
        bz = select(bz, bz >> CDVR_CL_BLOCK_SHIFT, block);
        shift = select(shift, shift + CDVR_CL_BLOCK_SHIFT, block);
    }
    vint fx = select(bx << shift, (bx + 1) << shift, eb->dg.x >= 0.0f);
    vint fy = select(by << shift, (by + 1) << shift, eb->dg.y >= 0.0f);
    vint fz = select(bz << shift, (bz + 1) << shift, eb->dg.z >= 0.0f);
    vfloat tx = (convert_vfloat(fx) - eb->g0.x) * eb->inv_dg.x;
    vfloat ty = (convert_vfloat(fy) - eb->g0.y) * eb->inv_dg.y;
    vfloat tz = (convert_vfloat(fz) - eb->g0.z) * eb->inv_dg.z;
    vfloat t_exit = fmin(tx, fmin(ty, tz));
    vint past = max(*i + 1, convert_vint(ceil(t_exit - SKIP_MARGIN)));
    vint run_end = max(*i + 1, max(convert_vint(ceil(t_exit)), *i + run_min));
    *i = select(*i, past, need & dull);
    *end = select(*end, run_end, need & ~dull);
    return flat;
}

/* The least and the greatest of a packet's lanes, halving the vector (floats: no NaN among
 * them, so selects, which compile to one instruction where fmin and fmax take three). */
#define LESS_OF(a, b) select(b, a, (a) < (b))
#define GREATER_OF(a, b) select(b, a, (a) > (b))
#define LANES_REDUCE(NAME, T, T8, T4, T2, PICK)                                                    \
    static T NAME(T##16 x)                                                                         \
    {                                                                                              \
        T8 m8 = PICK(x.lo, x.hi);                                                                  \
        T4 m4 = PICK(m8.lo, m8.hi);                                                                \
        T2 m2 = PICK(m4.lo, m4.hi);                                                                \
        return PICK(m2.x, m2.y);                                                                   \
    }
LANES_REDUCE(lanes_min, int, int8, int4, int2, min)
LANES_REDUCE(lanes_max, int, int8, int4, int2, max)
LANES_REDUCE(lanes_min_float, float, float8, float4, float2, LESS_OF)
LANES_REDUCE(lanes_max_float, float, float8, float4, float2, GREATER_OF)
#undef LANES_REDUCE
#undef LESS_OF
#undef GREATER_OF

/* The samples that count per lane (render.h: n - 1 full segments, and the last unless its
 * segment is empty; none on lanes that miss); *last: -1 where the last one counts. */
static vint counted_samples(const packet *p, vint n, float step, vint *last)
{
    vfloat ts = p->t_near + convert_vfloat(n - 1) * step;
    *last = p->t_far - ts > 0.0f;
    return select((vint)(0), n - 1 - *last, p->hit);
}

/* Sample i of each lane as average, and max and min lane by lane, read it: at g0 + i dg (eb's,
 * as composite's `at`) on the full segments and sample_point's midpoint on the last, shorter
 * one; within float rounding of render.h's sample position (engine CT and Colin27 average
 * 512^2: 9% less time than sample_point everywhere; Colin27 max 7%, engine max 2%, the image
 * 19 pixels apart by one level of 255). The lock-step loop takes the `at` side by a
 * packet-wide test (i < full): with this lane-wise test in it, the compiler computed both
 * sides and it gained nothing. *ok: lanes where segment i exists. */
static vec3x march_point(const packet *p, const extreme_bricks *eb, vint i, vint n, float step,
                         float3 inv_spacing, vint *ok)
{
    vec3x g = at(eb->g0, eb->dg, i);
    *ok = p->hit & (i < n);
    vint last = *ok & (i >= n - 1);
    if (lanes_any(last)) {
        vint ok_last;
        vfloat tm;
        vec3x gl = sample_point(p, i, n, step, inv_spacing, &ok_last, &tm);
        g = (vec3x){select(g.x, gl.x, last), select(g.y, gl.y, last), select(g.z, gl.z, last)};
        *ok = select(*ok, ok_last, last);
    }
    return g;
}

/* The window [*first, *lim) of each lane's samples between the entry bound te and the exit
 * bound tx of the bricks above 0 (cdvr/skip.h; cl_render.c, zero_entry_ready): the samples
 * outside it lie in bricks of zeros (the sample before the one before te and after the one
 * after tx: a sample of margin for rounding). Returns how many of the samples outside count
 * (render.h: n - 1 full segments, the last unless empty): all of them have the value 0. */
static vint zero_window(const packet *p, vint n, float step, float te, float tx, vint *first,
                        vint *lim)
{
    vfloat k0 = floor((te - p->t_near) / step - 0.5f) - 1.0f;
    vfloat k1 = ceil((tx - p->t_near) / step - 0.5f) + 2.0f;
    *first = convert_vint(clamp(k0, 0.0f, convert_vfloat(n)));
    *lim = max(convert_vint(clamp(k1, 0.0f, convert_vfloat(n))), *first);
    vint last_counts;
    counted_samples(p, n, step, &last_counts);
    /* counting samples in [0, first) and [lim, n): every full one, the last where it counts */
    vint before = min(*first, n - 1) - ((*first == n) & last_counts);
    vint after = n - 1 - min(*lim, n - 1) - ((*lim < n) & last_counts);
    return select((vint)(0), before + after, p->hit);
}

/* Max: a sparse pass over every `every`-th sample of each lane's window [first, lim) raises
 * *best before the march, which then finds more bricks dull. These are samples of the ray, so
 * *best stays at most its maximum and the result is the same. Lanes already at 255 take no
 * part. Returns the samples read per lane. */
static vint sparse_max(const packet *p, const extreme_bricks *eb, vint n, float step,
                       float3 inv_spacing, const volume_geo *v, vint first, vint lim, int every,
                       vfloat *best)
{
    vint on = p->hit & (first < lim) & (*best < 255.0f), read = (vint)(0);
    int from = lanes_min(select((vint)(INT_MAX), first, on));
    int to = lanes_max(select((vint)(0), lim, on));
    if (from >= to)
        return read;
    for (int j = from + every / 2; j < to; j += every) {
        vint ok;
        vec3x g = march_point(p, eb, (vint)(j), n, step, inv_spacing, &ok);
        ok &= on & (j >= first) & (j < lim);
        vfloat s = trilinear_on(v, g, ok);
        *best = select(*best, fmax(*best, s), ok);
        read -= ok;
    }
    return read;
}

/* Average's leaps: a packet in lock-step skips the samples where every lane lies in bricks
 * of zeros (their samples are 0: they add nothing to the sum and count in the mean, as
 * samples outside the window do). One lane leads: where it lies in a cube of zero bricks
 * (the flags of the bricks above 0, cdvr/skip.h: code d, the cube within d - 1 is all
 * zeros) at least `spread` inside its faces and inside the volume (so no lane's sample is
 * clamped), every lane's sample of the same index lies in the cube too: `spread` bounds each
 * axis of the distance between a lane's sample and the lead's over the indices the leaps
 * cover (a linear function of the index: its bound at the two ends). */
typedef struct zero_leap {
    __global const uchar *dist;
    int shift, nbx, nby, nbz;
    float3 g0, dg, inv_dg; /* the lead's sample i at g0 + i dg; 1 / dg */
    float3 spread, top;
} zero_leap;

#define LEAP_MARGIN 0.01f /* voxels added to the spread for the rounding of positions */
#define LEAPS_MAX 16 /* leaps kept per packet, more are not taken (engine CT and Colin27
                        512^2: 0.3 and 0.6 per packet, none over 16) */

/* One axis of the lead: through the middle of the lanes' samples `from` and `last` (hit
 * lanes), and the greater half-width of the two as the spread (the distance of a lane's
 * sample to the lead's is a linear function of the index: at most that between them). */
#define LEAD_AXIS(AX)                                                                          \
    do {                                                                                       \
        vfloat pa = eb->g0.AX + fa * eb->dg.AX, pb = eb->g0.AX + fb * eb->dg.AX;               \
        float lo_a = lanes_min_float(select((vfloat)(INFINITY), pa, p->hit));                  \
        float hi_a = lanes_max_float(select((vfloat)(-INFINITY), pa, p->hit));                 \
        float lo_b = lanes_min_float(select((vfloat)(INFINITY), pb, p->hit));                  \
        float hi_b = lanes_max_float(select((vfloat)(-INFINITY), pb, p->hit));                 \
        float mid_a = 0.5f * (lo_a + hi_a), mid_b = 0.5f * (lo_b + hi_b);                      \
        z->dg.AX = (mid_b - mid_a) / (float)(last - from);                                     \
        z->g0.AX = mid_a - (float)from * z->dg.AX;                                             \
        z->spread.AX = 0.5f * fmax(hi_a - lo_a, hi_b - lo_b) + LEAP_MARGIN;                    \
    } while (0)

/* The lead of samples from..last (from < last) of the packet's lanes (eb: their
 * positions), with `zb`'s flags; 0 when no lane hits. */
static int zero_leap_make(const packet *p, const extreme_bricks *eb, const bricks *zb,
                          const volume_geo *v, int from, int last, zero_leap *z)
{
    if (!lanes_any(p->hit))
        return 0;
    vfloat fa = (vfloat)((float)from), fb = (vfloat)((float)last);
    LEAD_AXIS(x);
    LEAD_AXIS(y);
    LEAD_AXIS(z);
    z->inv_dg = 1.0f / z->dg; /* inf where dg is 0 or denormal: LEAP_AXIS's still case */
    z->dist = zb->dist;
    z->shift = zb->shift;
    z->nbx = zb->nbx;
    z->nby = zb->nby;
    z->nbz = zb->nbz;
    z->top = (float3)(v->top.x, v->top.y, v->top.z);
    return 1;
}
#undef LEAD_AXIS

/* One axis of the lead's cube look-ups (a lane per look-up): the inner box [lo, hi) of the
 * cube of bricks b - reach .. b + reach, max(cube, 0) + spread .. min(cube, top) - spread,
 * and the sample parameters `enter` and `leave` between which the lead lies inside it on this
 * axis (t0, t1: where it crosses the faces; on an axis it does not move along, all or none:
 * `in`); wide: the box is not empty on this axis. */
#define LEAP_AXIS(AX, NB)                                                                      \
    vint b##AX = min(convert_vint(clamp(g.AX, 0.0f, z->top.AX)) >> z->shift, z->NB - 1);       \
    vfloat lo##AX = fmax(convert_vfloat((b##AX - reach) << z->shift), 0.0f) + z->spread.AX;    \
    vfloat hi##AX = fmin(convert_vfloat((b##AX + reach + 1) << z->shift), z->top.AX) -         \
                    z->spread.AX;                                                              \
    vfloat t0##AX = (lo##AX - z->g0.AX) * z->inv_dg.AX;                                        \
    vfloat t1##AX = (hi##AX - z->g0.AX) * z->inv_dg.AX;                                        \
    vint still##AX = (vint)(-isinf(z->inv_dg.AX)); /* dg 0, or too small to invert */         \
    vint in##AX = z->g0.AX >= lo##AX & z->g0.AX < hi##AX;                                      \
    vint wide##AX = lo##AX < hi##AX; /* the box is not empty on this axis */                  \
    vfloat enter##AX = select(fmin(t0##AX, t1##AX),                                            \
                              select((vfloat)(INFINITY), (vfloat)(-INFINITY), in##AX),         \
                              still##AX);                                                      \
    vfloat leave##AX = select(fmax(t0##AX, t1##AX),                                            \
                              select((vfloat)(-INFINITY), (vfloat)(INFINITY), in##AX),         \
                              still##AX)

/* Adds to skip_from/skip_to (*skips of them, in order) the leaps found by looking up the
 * lead at samples first + k stride (k = 0..15, those below limit): each look-up gives the
 * samples where the lead lies in the inner box of its cube of zero bricks. Sixteen at once,
 * since one look-up after another cost more than the leaps saved (each waited on the one
 * before). Returns the sample after the last looked up. */
static int zero_leaps(const zero_leap *z, int first, int stride, int from, int limit,
                      int *skip_from, int *skip_to, int *skips)
{
    vint k = first + stride * (vint)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    vint on = k < limit;
    vfloat fk = convert_vfloat(k);
    vec3x g = {z->g0.x + fk * z->dg.x, z->g0.y + fk * z->dg.y, z->g0.z + fk * z->dg.z};
    vint cx = min(convert_vint(clamp(g.x, 0.0f, z->top.x)) >> z->shift, z->nbx - 1);
    vint cy = min(convert_vint(clamp(g.y, 0.0f, z->top.y)) >> z->shift, z->nby - 1);
    vint cz = min(convert_vint(clamp(g.z, 0.0f, z->top.z)) >> z->shift, z->nbz - 1);
    vint idx = select((vint)(0), cx + z->nbx * (cy + z->nby * cz), on);
    __global const uchar *d = z->dist;
#define LEAP_CODE(k) d[(uint)idx.s##k]
    vint code = convert_vint((uchar16)(L16(LEAP_CODE)));
#undef LEAP_CODE
    vint reach = max(code & 127, 1) - 1; /* bricks on each side that are alike */
    LEAP_AXIS(x, nbx);
    LEAP_AXIS(y, nby);
    LEAP_AXIS(z, nbz);
    vfloat enter = fmax(enterx, fmax(entery, enterz));
    vfloat leave = fmin(leavex, fmin(leavey, leavez));
    /* samples k_in .. k_out - 1 lie in the box, rounding aside */
    vfloat k_in = fmax(ceil(enter + SKIP_MARGIN), (float)from);
    vfloat k_out = fmin(ceil(leave - SKIP_MARGIN), (float)limit);
    vint leap = on & (code < 128) & (k_out > k_in) & widex & widey & widez;
    if (!lanes_any(leap))
        return first + RAY_PACKET * stride;
    float ins[RAY_PACKET], outs[RAY_PACKET];
    int leaps[RAY_PACKET];
    vstore16(k_in, 0, ins);
    vstore16(k_out, 0, outs);
    vstore16(leap, 0, leaps);
    for (int j = 0; j < RAY_PACKET; j++) { /* in order along the ray: merge those that meet */
        if (!leaps[j])
            continue;
        int a = (int)ins[j], b = (int)outs[j];
        if (*skips > 0 && a <= skip_to[*skips - 1])
            skip_to[*skips - 1] = max(skip_to[*skips - 1], b);
        else if (*skips < LEAPS_MAX) {
            skip_from[*skips] = a;
            skip_to[(*skips)++] = b;
        }
    }
    return first + RAY_PACKET * stride;
}
#undef LEAP_AXIS

/* Max, min or average of every sample's code (no termination). With the ranges, lanes skip
 * dull bricks (whose range cannot beat the lane's best; for average, bricks of zeros) and a
 * dull brick's whole block when the block is dull too (CDVR_CL_BLOCK_SHIFT); max and min
 * take a flat brick's code (a range of one code: every sample in it has that value) without
 * reading its samples, which count as taken. With `bounds` (the entry bound te and exit bound
 * tx of the bricks above 0) lanes read only the samples of their window (zero_window): the
 * others are 0, in the mean and the extreme, not read. Average then reads the packet's widest
 * window in lock-step instead of skipping bricks of zeros lane by lane (engine CT and Colin27
 * 512^2: the per-lane march reads 74% and 52% of the samples, this 88% and 61%, in the same
 * time and 0.79x), and with zb (the flags of the bricks above 0) leaps over the samples where
 * the whole packet lies in zeros (zero_leap: 88% -> 77% and 61% -> 49%); max marches its
 * window lane by lane. (The host gives min no bounds: its lanes end at their first brick of
 * zeros anyway.) *taken: the samples read (and those of flat bricks). */
static rgbax march_extreme(const packet *p, vint n, float step, float3 inv_spacing,
                           const volume_geo *v, const look_params *lk,
                           __global const ulong *table, __global const float *rows,
                           const extreme_bricks *eb, int bounds, float te, float tx,
                           const bricks *zb, vint *taken)
{
    /* average keeps best at 0: the bound it skips bricks by (those whose maximum is 0) */
    vfloat best = (vfloat)(lk->blend == 2 ? INFINITY : lk->blend == 3 ? 0.0f : -INFINITY);
    vfloat sum = (vfloat)(0.0f);
    vint count = (vint)(0); /* samples read (max, min: and those of flat bricks) */
    /* samples of bricks of zeros not read: 0 each, in the mean (max: in the extreme) */
    vint zeros = (vint)(0);
    vint first = (vint)(0), end = n; /* each lane's window (zero_window) */
    if (bounds) {
        zeros = zero_window(p, n, step, te, tx, &first, &end);
        /* max takes the zeros' 0 into its extreme at once */
        best = select(best, fmax(best, 0.0f), (zeros > 0) & (vint)(-(lk->blend == 1)));
    }
    if (!eb->minmax || (bounds && lk->blend == 3)) { /* samples from..to - 1 in lock-step */
        vint on = p->hit & (first < end);
        int from = lanes_min(select((vint)(INT_MAX), first, on));
        int to = lanes_max(select((vint)(0), end, on));
        /* samples below `full` are full segments on every lane (march_point) */
        int full = lanes_min(select((vint)(INT_MAX), n - 1, p->hit));
        /* average with the zero flags: the leaps below `full` (zero_leap), found before the
         * samples are read (the samples' addresses then never wait on a look-up) */
        int skip_from[LEAPS_MAX], skip_to[LEAPS_MAX], skips = 0;
        int limit = min(full, to);
        zero_leap zl;
        if (lk->blend == 3 && bounds && zb && from < limit &&
            zero_leap_make(p, eb, zb, v, from, limit, &zl)) {
            /* a look-up per brick edge of the lead's path along its longest axis */
            float most = fmax(fabs(zl.dg.x), fmax(fabs(zl.dg.y), fabs(zl.dg.z)));
            int stride = (int)clamp((float)(1 << zl.shift) / most, 1.0f, 64.0f);
            for (int first = from; first < limit;)
                first = zero_leaps(&zl, first, stride, from, limit, skip_from, skip_to,
                                   &skips);
        }
        int i = from;
        for (int k = 0; k <= skips; k++) {
            int stop = k < skips ? skip_from[k] : to;
            /* average's full segments in a loop of their own, with no blend or `full` tests:
               every hit lane has sample i (i < full), and a lane that misses reads voxel 0
               (g0 = dg = 0) into a sum it never shows (in_mean is 0) */
            int end = lk->blend == 3 ? min(stop, full) : i;
            count += p->hit & (vint)(max(end - i, 0));
            /* i as a float counted up (exact below 2^24): at()'s conversion, one
               instruction where at() takes three */
            for (float fi = (float)i; i < end; i++, fi += 1.0f) {
                vec3x g = {eb->g0.x + fi * eb->dg.x, eb->g0.y + fi * eb->dg.y,
                           eb->g0.z + fi * eb->dg.z};
#if !defined(CDVR_FETCH) && !defined(CDVR_LONG_INDEX)
                /* inside the volume: every hit lane's full segments (a lane that misses
                   samples voxel 0) */
                if (v->quads_on) {
                    sum += quad_trilinear(v, g, (vint)(-1), 1);
                    continue;
                }
#endif
                sum += trilinear(v, g);
            }
            for (; i < stop; i++) {
                vint ok;
                vec3x g;
                if (i < full) { /* march_point's at() for every lane */
                    g = at(eb->g0, eb->dg, (vint)(i));
                    ok = p->hit & (i < n);
                } else {
                    g = march_point(p, eb, (vint)(i), n, step, inv_spacing, &ok);
                }
                vfloat s = trilinear(v, g);
                count -= ok;
                if (lk->blend == 3)
                    sum += select((vfloat)(0.0f), s, ok);
                else
                    best = select(best, lk->blend == 1 ? fmax(best, s) : fmin(best, s), ok);
            }
            if (k < skips)
                i = skip_to[k];
        }
        /* the packet's widest window was read: a lane's samples read outside its own window
         * are not among its zeros */
        vint last;
        if (bounds)
            zeros = counted_samples(p, n, step, &last) - count;
    } else { /* per-lane sample index: lanes skip dull bricks on their own; the last, shorter
                segment is always sampled. Average skips the bricks whose voxels are all 0 (as
                max does while its best is 0): their samples are 0, add nothing to the sum and
                count in the mean. */
        int is_avg = lk->blend == 3, is_max = lk->blend == 1 || is_avg;
        /* no code lies beyond 255 (below 0): a lane whose extreme got there is done */
        float saturated = is_avg ? NAN : is_max ? 255.0f : 0.0f;
        vint i = first, lim = end; /* lanes march from first to lim - 1 */
        end = (vint)(0);
        /* max: a sample per RUN_VOXELS first (engine CT 512^2: 27.8 -> 23.9 ms, Colin27
         * 22.8 -> 23.5 ms; every 4, 8 or 32 voxels: 1.1x, 1.02x, 1.01x that time on the
         * engine; min, whose lanes end at 0, lost 1.2x and 3.7x) */
        if (lk->blend == 1)
            count += sparse_max(p, eb, n, step, inv_spacing, v, i, lim,
                                run_samples(step, inv_spacing), &best);
        vint live = p->hit & (i < lim) & (best != saturated);
        /* runs of 2 RUN_VOXELS for max and min (engine CT and Colin27 512^2 max: 1.5% and 4%
         * less time than 1; 4 was 4% slower on the engine), 4 for average, whose look-ups
         * only find bricks of zeros (3% and 7% less than 1; 8 and 16 the same as 4) */
        int run_min = run_samples(step, inv_spacing) * (is_avg ? 4 : 2);
        while (lanes_any(live)) {
            vint need = live & (i >= end) & (i < lim - 1);
            /* look-ups only when no lane can sample without one (lanes at their run's end
             * meanwhile sample a step on, unlooked): engine CT and Colin27 512^2 max 4% and
             * 12% less time than the HOP_MIN rule, average 2-3%, min the same */
            if (lanes_any(live & (i < end)))
                end = select(end, i + 4, need);
            else /* a lane that skipped a dull brick looks up the next at once (BRICK_HOPS) */
                for (int hop = 0; hop < BRICK_HOPS && lanes_any(need); hop++) {
                    vint before = i;
                    vint flat = extreme_step(eb, v, &i, &end, &best, is_max, !is_avg, need,
                                             run_min);
                    i = min(i, lim - 1);
                    /* the skipped samples count in the mean, and as taken where a flat brick
                     * gave their value */
                    if (is_avg)
                        zeros += select((vint)(0), i - before, need);
                    else
                        count += select((vint)(0), i - before, flat);
                    need &= (i >= end) & (i < lim - 1) & (best != saturated);
                }
            live &= best != saturated; /* a flat brick of the saturated code ends the lane */
            end = select(end, lim, i >= lim - 1); /* the last sample needs no look-up */
#ifdef HAVE_PREFETCH
            prefetch_corners(v, eb->g0, eb->dg, i, live, 0);
#endif
            for (int k = 0; k < 4; k++) {
                vint run = live & (i < end);
                if (!lanes_any(run))
                    break;
                vint ok;
                vec3x g = march_point(p, eb, i, n, step, inv_spacing, &ok);
                ok &= run;
                vfloat s = trilinear(v, g);
                count -= ok;
                if (is_avg)
                    sum += select((vfloat)(0.0f), s, ok);
                else
                    best = select(best, is_max ? fmax(best, s) : fmin(best, s), ok);
                i -= run;
                live &= i < lim;
            }
            /* after the step's samples: as a condition of each sample it would chain their
             * loads to the previous sample's value */
            live &= best != saturated; /* never for average (NaN) */
        }
    }
    *taken = count;
    vint in_mean = count + zeros;
    vfloat s = lk->blend == 3 ? sum / convert_vfloat(max(in_mean, 1)) : best;
    s = select((vfloat)(0.0f), s, in_mean > 0);
    rgbax c = table_at(s, rows);
    vfloat a = select((vfloat)(0.0f), raw_alpha(s, rows), in_mean > 0);
    return (rgbax){c.r * a, c.g * a, c.b * a, a};
}

/* render.h's iso: the first crossing along the samples, refined. With b (skipping: its flags
 * are made for the code floor(c), cl_render.c), a lane in a cube of bricks whose ranges do
 * not hold it (all its samples lie strictly on one side of c: adjacent bricks' ranges share
 * voxels, so the cube's ranges cannot straddle c) moves on to the cube's last sample, which
 * the crossing test and the refinement of the first sample past it read as the predecessor;
 * the samples between are counted as taken (the same image and count as without skipping).
 * Lanes start at sample `first` (the iso entry bound, else 0), which has no predecessor: the
 * samples before it are counted as taken too. */
static rgbax march_iso(const packet *p, vint n, float step, float3 inv_spacing,
                       const volume_geo *v, const look_params *lk,
                       __global const float *rows, const viewer *V, const bricks *b, vec3x g0,
                       vec3x dg, vint first, vint *taken)
{
    float c = lk->iso_code;
    vfloat prev = (vfloat)(0.0f), t_prev = (vfloat)(0.0f), t_hit = (vfloat)(0.0f);
    vint found = (vint)(0), count = first;
    vfloat ta = (vfloat)(0.0f), tb = (vfloat)(0.0f), sa = (vfloat)(0.0f), sb = (vfloat)(0.0f);
    vint i = first, end = (vint)(0), live = p->hit & (i < n);
    while (lanes_any(live)) {
        vint ok;
        vfloat tm;
        vec3x g = sample_point(p, i, n, step, inv_spacing, &ok, &tm);
        ok &= live;
        vfloat s = trilinear(v, g);
        count -= ok;
        vint hit = ok & ((s == c) | ((i > first) & ((prev - c) * (s - c) < 0.0f)));
        ta = select(ta, t_prev, hit);
        tb = select(tb, tm, hit);
        sa = select(sa, prev, hit);
        sb = select(sb, s, hit);
        t_hit = select(t_hit, tm, hit);
        found |= hit;
        prev = select(prev, s, ok);
        t_prev = select(t_prev, tm, ok);
        live &= ok & ~hit; /* an empty last segment ends the lane, as in the definition */
        vint next = i + 1;
        vint need = live & (i >= end) & (i < n - 2);
        if (b && lanes_any(need)) {
            vint visible;
            vfloat t_exit = brick_exit(b, v, g0, at(g0, dg, i), &visible);
            vint last_inside = min(max(i + 1, convert_vint(ceil(t_exit - SKIP_MARGIN))) - 1,
                                   n - 1);
            vint jump = need & ~visible & (last_inside > i + 1);
            count += select((vint)(0), last_inside - (i + 1), jump);
            end = select(end, max(i + 1, convert_vint(ceil(t_exit))), need & visible);
            next = select(next, last_inside, jump);
        }
        i = select(i, next, live);
        live &= i < n;
    }
    *taken = count;
    if (!lanes_any(found))
        return (rgbax){(vfloat)(0.0f), (vfloat)(0.0f), (vfloat)(0.0f), (vfloat)(0.0f)};
    vint refine = found & (sb != c);
    for (int k = 0; k < 2; k++) {
        refine &= sb != sa;
        if (!lanes_any(refine))
            break;
        vfloat t = ta + (c - sa) * (tb - ta) / (sb - sa);
        t_hit = select(t_hit, t, refine);
        vfloat st = trilinear(v, point_at(p, t, inv_spacing));
        vint lower = (sa - c) * (st - c) <= 0.0f;
        tb = select(tb, t, refine & lower);
        sb = select(sb, st, refine & lower);
        ta = select(ta, t, refine & ~lower);
        sa = select(sa, st, refine & ~lower);
    }
    rgbax col = table_at((vfloat)(c), rows);
    if (!lk->iso_tf_color)
        col = (rgbax){(vfloat)(lk->iso_rgb[0]), (vfloat)(lk->iso_rgb[1]), (vfloat)(lk->iso_rgb[2]),
                      (vfloat)(1.0f)};
    if (lk->shade)
        shade_rgb(lk, gradient(v, lk, point_at(p, t_hit, inv_spacing), found), V, &col);
    vfloat a = select((vfloat)(0.0f), (vfloat)(lk->iso_alpha), found);
    return (rgbax){col.r * a, col.g * a, col.b * a, a};
}

static volume_geo make_geo(__global const uchar *vol, __constant uchar *params, int frame,
                           int tiled, int X, int Y, int Z, const clip_params *clip)
{
    volume_geo v;
    v.vol = vol;
    v.params = params;
    v.frame = frame;
    v.tiled = tiled;
    int pages_x = (X + CDVR_CL_PAGE_EDGE - 1) / CDVR_CL_PAGE_EDGE;
    int pages_y = (Y + CDVR_CL_PAGE_EDGE - 1) / CDVR_CL_PAGE_EDGE;
    v.page_row = pages_x << 10;
    v.page_slab = pages_x * pages_y << 10;
    v.dims = (int3)(X, Y, Z);
    v.base_max = max(v.dims - 2, 0);
    v.stride = (long3)(X > 1 ? 1 : 0, Y > 1 ? (long)X : 0, Z > 1 ? (long)X * (long)Y : 0);
    v.top = convert_float3(v.dims - 1);
    v.offset = clip->enabled ? (float3)(clip->offset[0], clip->offset[1], clip->offset[2])
                             : (float3)(0.0f);
    v.grads = 0;
    v.grads_on = 0;
    v.quads = 0;
    v.quads_on = 0;
    v.march = 0;
    v.limit = 0;
#ifndef CDVR_LONG_INDEX
    v.last_word = X * Y * Z - 4; /* frames of fewer than 2^31 voxels here */
#else
    v.last_word = -1;
#endif
    return v;
}

static bricks make_bricks(__global const uchar *dist, int shift, int nbx, int nby, int nbz,
                          vec3x dg)
{
    bricks b;
    b.dist = dist;
    b.shift = shift;
    b.nbx = nbx;
    b.nby = nby;
    b.nbz = nbz;
    b.inv_dg = (vec3x){select((vfloat)(INFINITY), 1.0f / dg.x, dg.x != 0.0f),
                        select((vfloat)(INFINITY), 1.0f / dg.y, dg.y != 0.0f),
                        select((vfloat)(INFINITY), 1.0f / dg.z, dg.z != 0.0f)};
    b.fwd_x = dg.x >= 0.0f;
    b.fwd_y = dg.y >= 0.0f;
    b.fwd_z = dg.z >= 0.0f;
    return b;
}

/* clang's two-vector shuffle with constant indices (one instruction each on AVX-512), where
 * the compiler has it */
#if defined(__has_builtin)
#if __has_builtin(__builtin_shufflevector)
#define HAVE_SHUFFLEVECTOR 1
#endif
#if __has_builtin(__builtin_nontemporal_store)
#define HAVE_NONTEMPORAL 1
#endif
#endif

/* A packet wholly inside the image stores each row of 4 pixels as one 16-float vector;
 * packets over the image's edge store pixel by pixel. */
static void store_pixels(__global float4 *image, vint px, vint py, int width, int height,
                         rgbax acc)
{
    float r[RAY_PACKET], g[RAY_PACKET], b[RAY_PACKET], a[RAY_PACKET];
    int px_[RAY_PACKET], py_[RAY_PACKET];
    vstore16(acc.r, 0, r);
    vstore16(acc.g, 0, g);
    vstore16(acc.b, 0, b);
    vstore16(acc.a, 0, a);
    int px0 = px.s0, py0 = py.s0;
    if (px0 + PACKET_W <= width && py0 + PACKET_H <= height) { /* whole packet: rows of 4 */
        __global float *row = (__global float *)(image + (size_t)py0 * width + px0);
#ifdef HAVE_SHUFFLEVECTOR
        /* rgba of lanes 4y .. 4y + 3 by six two-vector shuffles (through the arrays, the
           stores took 40% of an empty frame on PoCL) */
        float16 rg_lo = __builtin_shufflevector(acc.r, acc.g, 0, 16, 1, 17, 2, 18, 3, 19, 4,
                                                20, 5, 21, 6, 22, 7, 23);
        float16 ba_lo = __builtin_shufflevector(acc.b, acc.a, 0, 16, 1, 17, 2, 18, 3, 19, 4,
                                                20, 5, 21, 6, 22, 7, 23);
        float16 rg_hi = __builtin_shufflevector(acc.r, acc.g, 8, 24, 9, 25, 10, 26, 11, 27,
                                                12, 28, 13, 29, 14, 30, 15, 31);
        float16 ba_hi = __builtin_shufflevector(acc.b, acc.a, 8, 24, 9, 25, 10, 26, 11, 27,
                                                12, 28, 13, 29, 14, 30, 15, 31);
        float16 rows[PACKET_H] = {
            __builtin_shufflevector(rg_lo, ba_lo, 0, 1, 16, 17, 2, 3, 18, 19, 4, 5, 20, 21, 6,
                                    7, 22, 23),
            __builtin_shufflevector(rg_lo, ba_lo, 8, 9, 24, 25, 10, 11, 26, 27, 12, 13, 28, 29,
                                    14, 15, 30, 31),
            __builtin_shufflevector(rg_hi, ba_hi, 0, 1, 16, 17, 2, 3, 18, 19, 4, 5, 20, 21, 6,
                                    7, 22, 23),
            __builtin_shufflevector(rg_hi, ba_hi, 8, 9, 24, 25, 10, 11, 26, 27, 12, 13, 28, 29,
                                    14, 15, 30, 31)};
#ifdef HAVE_NONTEMPORAL
        /* rows of 64 aligned bytes (cdvr_image's pixels are, image.c) as non-temporal stores:
         * a frame's image is written once and read after the kernel, so its lines need not be
         * read into the cache first (Colin27 512^2 on PoCL, 2 cores of an Intel Xeon: 0.94 of
         * the time at step 1, 0.93 at 0.5; engine CT step 1 0.96: per-process minimums of 40
         * frames, 6-8 alternating pairs). They need no fence here: the worker's locked
         * operations that report the work-group done drain them (Intel SDM 11.3.1) before
         * the host sees the kernel complete. */
        if (((size_t)row & 63) == 0 && (width & 3) == 0) {
            for (int y = 0; y < PACKET_H; y++, row += 4 * width)
                __builtin_nontemporal_store(rows[y], (__global float16 *)row);
            return;
        }
#endif
        for (int y = 0; y < PACKET_H; y++, row += 4 * width)
            vstore16(rows[y], 0, row);
#else
        for (int y = 0; y < PACKET_H; y++, row += 4 * width) {
            int k = PACKET_W * y;
            vstore16((float16)(r[k], g[k], b[k], a[k], r[k + 1], g[k + 1], b[k + 1], a[k + 1],
                               r[k + 2], g[k + 2], b[k + 2], a[k + 2], r[k + 3], g[k + 3],
                               b[k + 3], a[k + 3]),
                     0, row);
        }
#endif
        return;
    }
    vstore16(px, 0, px_);
    vstore16(py, 0, py_);
    for (int k = 0; k < RAY_PACKET; k++)
        if (px_[k] < width && py_[k] < height)
            image[py_[k] * width + px_[k]] = (float4)(r[k], g[k], b[k], a[k]);
}

/* Per lane, the parameter range [*enter, *exit) (in samples) where g0 + i*dg lies in the
 * grid slab [lo, hi) of one axis; a ray parallel to it is inside or outside throughout. */
static void visible_slab(vfloat g0, vfloat dg, float lo, float hi, vfloat *enter,
                         vfloat *exit)
{
    vfloat t0 = (lo - g0) / dg, t1 = (hi - g0) / dg;
    vint parallel = dg == 0.0f;
    vint inside = g0 >= lo & g0 < hi;
    vfloat flat_enter = select((vfloat)(INFINITY), (vfloat)(-INFINITY), inside);
    *enter = fmax(*enter, select(fmin(t0, t1), flat_enter, parallel));
    *exit = fmin(*exit, select(fmax(t0, t1), -flat_enter, parallel));
}

/* Sample indices [*first, *stop) of the full segments that can lie in visible bricks: the
 * others are in invisible bricks outside the visible box, which the host sized in grid
 * coordinates. One sample of margin on each side absorbs rounding. */
__attribute__((always_inline)) static inline void visible_range(vec3x g0, vec3x dg, float3 lo,
                                                                float3 hi, vint n_full,
                                                                vint *first, vint *stop)
{
    if (any(lo > hi)) { /* no visible brick */
        *first = *stop = (vint)(0);
        return;
    }
    vfloat enter = (vfloat)(-INFINITY), exit = (vfloat)(INFINITY);
    visible_slab(g0.x, dg.x, lo.x, hi.x, &enter, &exit);
    visible_slab(g0.y, dg.y, lo.y, hi.y, &enter, &exit);
    visible_slab(g0.z, dg.z, lo.z, hi.z, &enter, &exit);
    vfloat limit = convert_vfloat(n_full) + 1.0f;
    enter = clamp(floor(enter) - 1.0f, 0.0f, limit);
    exit = clamp(ceil(exit) + 1.0f, 0.0f, limit);
    *first = convert_vint(enter);
    *stop = min(convert_vint(exit), n_full);
}

/* frames/params/offset: a dense frame at frames + offset (params unused; with tiled != 0, the
 * frame's tiled copy), or, with CDVR_FETCH, the chunk payload, its parameter blob and the frame
 * index within the chunk.
 * Geometry as render_cpu.c holds it: the box frame (origin, D^-1), 1/spacing and the box's
 * upper corner (dims-1)*spacing in the box frame (computed in double on the host; the whole
 * volume's when clipped: clip, render.h). table: the packed TF rows (rgb + step-corrected
 * alpha, classify); rows: the exact TF rows as floats (rgb + alpha per unit: the shorter last
 * segment, shading, the colours of max, min, average and iso). Bricks: edge 1 << brick_shift, counts nbx, nby, nbz, skipping on/off.
 * Work-item (gx, gy) renders the PACKET_W x PACKET_H pixels from (PACKET_W gx, PACKET_H gy). */
__kernel void raycast(__global const uchar *frames, __constant uchar *params, ulong offset,
                      int tiled, int X, int Y, int Z,
                      box_frame box, float isx, float isy, float isz,
                      float hx, float hy, float hz,
                      float step, float term_alpha, cam_params cam, clip_params clip,
                      __global const ulong *table, __global const float *rows,
                      float unit, __global const uchar *brick_visible, int brick_shift,
                      int nbx, int nby, int nbz, int skipping, float vlx, float vly,
                      float vlz, float vhx, float vhy, float vhz, __global float4 *image,
                      __global uint *samples, /* per work-item */
                      look_params look, __global const uchar2 *brick_minmax, int minmax_valid,
                      __global const float *entry, int entry_tiles_x, int entry_on,
                      __global const uint *grads, int grads_on, __global const uint *quads,
                      int quads_on)
{
    int px0 = get_global_id(0) * PACKET_W, py0 = get_global_id(1) * PACKET_H;
    size_t slot = get_global_id(1) * get_global_size(0) + get_global_id(0);
    if (px0 >= cam.width || py0 >= cam.height) {
        samples[slot] = 0;
        return;
    }
    vint px = px0 + (vint)(0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3);
    vint py = py0 + (vint)(0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2, 3, 3, 3, 3);
    /* no visible sample before t = te (cdvr/skip.h, entry distances) */
    size_t tile = get_global_id(1) * entry_tiles_x + get_global_id(0);
    float te = entry_on ? entry[tile] : 0.0f;
    /* max, average: the exit bounds follow the entry bounds (cl_render.c, entry_tiles_ready) */
    size_t tiles = get_global_size(0) * get_global_size(1);
    float tx = entry_on && (look.blend == 1 || look.blend == 3) ? entry[tiles + tile] : INFINITY;
    rgbax none = {(vfloat)(0.0f), (vfloat)(0.0f), (vfloat)(0.0f), (vfloat)(0.0f)};
    if (isinf(te) && look.blend == 0) {
        /* no ray of the packet meets a visible brick: the image of no sample (iso marches
         * its last sample only, so its count stays that of every sample) */
        store_pixels(image, px, py, cam.width, cam.height, none);
        samples[slot] = 0;
        return;
    }
    packet p;
    camera_rays(&cam, px, py, &p);
    p.hit = px < cam.width & py < cam.height;
    /* towards the eye, world (shading) */
    viewer view = make_viewer(&look, (vec3x){-p.d.x, -p.d.y, -p.d.z});
    to_box_frame(&box, &p);
    float3 inv_spacing = (float3)(isx, isy, isz);
    intersect_box(&p, (float3)(0.0f), (float3)(hx, hy, hz));
    /* lanes that miss get an empty, well-defined segment (their t values may be inf/NaN) */
    p.t_near = select((vfloat)(0.0f), p.t_near, p.hit);
    p.t_far = select((vfloat)(0.0f), p.t_far, p.hit);
    if (!lanes_any(p.hit)) { /* every blend mode's image of no sample */
        store_pixels(image, px, py, cam.width, cam.height, none);
        samples[slot] = 0;
        return;
    }
    vint n = max(convert_vint(ceil((p.t_far - p.t_near) / step)), 1);
    vfloat t0 = p.t_near + 0.5f * step;
    vec3x g0 = {(p.o.x + t0 * p.d.x) * inv_spacing.x, (p.o.y + t0 * p.d.y) * inv_spacing.y,
                (p.o.z + t0 * p.d.z) * inv_spacing.z};
    g0.x = select((vfloat)(0.0f), g0.x, p.hit);
    g0.y = select((vfloat)(0.0f), g0.y, p.hit);
    g0.z = select((vfloat)(0.0f), g0.z, p.hit);
    vec3x dg = {select((vfloat)(0.0f), p.d.x * step * inv_spacing.x, p.hit),
                select((vfloat)(0.0f), p.d.y * step * inv_spacing.y, p.hit),
                select((vfloat)(0.0f), p.d.z * step * inv_spacing.z, p.hit)};
#ifdef CDVR_FETCH
    volume_geo v = make_geo(frames, params, (int)offset, 0, X, Y, Z, &clip);
#ifdef CDVR_BRICK_CACHE
    /* the brick march (byte 0 of the cache codec's parameters), else the per-voxel fetch */
    v.march = params[0] && !clip.enabled && bc_payload_bytes(params) >= BC_MIN_BYTES;
    v.limit = (uint)min(bc_payload_bytes(params) - 2, (ulong)UINT_MAX);
#endif
#else
    volume_geo v = make_geo(frames + offset, params, 0, tiled, X, Y, Z, &clip);
    v.grads = grads;
    v.grads_on = grads_on && tiled && !clip.enabled;
    v.quads = quads;
    v.quads_on = quads_on && tiled && !clip.enabled;
#endif
    if (look.blend != 0) { /* max, min, average, iso: no TF skipping, no termination */
        vint taken;
        extreme_bricks eb;
        eb.minmax = minmax_valid && !clip.enabled ? brick_minmax : 0;
        eb.shift = brick_shift;
        eb.nbx = nbx;
        eb.nby = nby;
        eb.nbz = nbz;
        eb.g0 = g0;
        eb.dg = dg;
        /* the flags of iso (the bricks that can hold its code) or of average (those above 0) */
        bricks flag_bricks = make_bricks(brick_visible, brick_shift, nbx, nby, nbz, dg);
        eb.inv_dg = (vec3x){select((vfloat)(INFINITY), 1.0f / dg.x, dg.x != 0.0f),
                            select((vfloat)(INFINITY), 1.0f / dg.y, dg.y != 0.0f),
                            select((vfloat)(INFINITY), 1.0f / dg.z, dg.z != 0.0f)};
        /* iso with the iso flags' entry bound: from the sample before it (samples 0 .. first
         * lie in bricks that do not hold the code, all on one side of it: no crossing) */
        vint first = (vint)(0);
        if (entry_on) {
            vfloat k = floor((te - p.t_near) / step - 0.5f) - 1.0f;
            first = select((vint)(0), convert_vint(clamp(k, 0.0f, convert_vfloat(n - 1))), p.hit);
        }
        rgbax out = none;
        if (look.blend == 4 && entry_on && isinf(te)) {
            /* no ray meets a brick that can hold the code: march_iso's count from sample
             * n - 1 alone (n - 1 before it, and it unless its segment is empty) */
            vint last;
            taken = counted_samples(&p, n, step, &last);
        } else if (look.blend == 4)
            out = march_iso(&p, n, step, inv_spacing, &v, &look, rows, &view,
                            skipping ? &flag_bricks : 0, g0, dg, first, &taken);
        else
            out = march_extreme(&p, n, step, inv_spacing, &v, &look, table, rows, &eb,
                                entry_on && (look.blend == 1 || look.blend == 3), te, tx,
                                look.blend == 3 && skipping ? &flag_bricks : 0, &taken);
        store_pixels(image, px, py, cam.width, cam.height, out);
        int8 s8 = taken.lo + taken.hi;
        int4 s4 = s8.lo + s8.hi;
        samples[slot] = (uint)(s4.s0 + s4.s1 + s4.s2 + s4.s3);
        return;
    }
    bricks b = make_bricks(brick_visible, brick_shift, nbx, nby, nbz, dg);
    march m;
    m.i = (vint)(0);
    m.n_full = select((vint)(0), n - 1, p.hit);
    vint last = p.hit;
    if (skipping) {
        float3 vis_lo = (float3)(vlx, vly, vlz), vis_hi = (float3)(vhx, vhy, vhz);
        vint stop;
        visible_range(g0, dg, vis_lo, vis_hi, m.n_full, &m.i, &stop);
        last &= stop >= m.n_full; /* the last segment lies beyond the full ones */
        m.n_full = stop;
        if (entry_on) { /* the sample before the first one at te */
            vfloat first = floor((te - p.t_near) / step - 0.5f) - 1.0f;
            first = clamp(first, 0.0f, convert_vfloat(m.n_full));
            m.i = max(m.i, convert_vint(first));
        }
    }
    if (clip.enabled) { /* only the samples near the owned cells (owned() decides); the host
                           turns skipping off for clipped renders */
        float3 own_lo = (float3)(clip.own_lo[0], clip.own_lo[1], clip.own_lo[2]) - 1.0f;
        float3 own_hi = (float3)(clip.own_hi[0], clip.own_hi[1], clip.own_hi[2]) + 1.0f;
        vint first, stop;
        visible_range(g0, dg, own_lo, own_hi, m.n_full, &first, &stop);
        last &= stop >= m.n_full;
        m.i = max(m.i, first);
        m.n_full = min(m.n_full, stop);
    }
    m.end = skipping ? (vint)(0) : m.n_full;
    m.active = p.hit & (m.i < m.n_full);
    m.done = (vint)(0);
    m.taken = (vint)(0);
    /* visible runs hold at least run_min samples: UNROLL per step unless that is fewer */
    m.run_min = run_samples(step, inv_spacing);
    m.unroll = skipping && m.run_min < UNROLL ? UNROLL_SHORT : UNROLL;
    rgbax acc = {(vfloat)(0.0f), (vfloat)(0.0f), (vfloat)(0.0f), (vfloat)(0.0f)};
#ifdef CDVR_BRICK_CACHE
    if (v.march)
        march_cached(&m, skipping, &b, &v, &clip, g0, dg, table, term_alpha, &look, rows, step,
                     unit, &view, &acc);
    else
#endif
        march_full(&m, skipping, &b, &v, &clip, g0, dg, table, term_alpha, &look, rows, step,
                   unit, &view, &acc);
    last_segment(&p, n, last & ~m.done, step, unit, &v, &clip, inv_spacing, table, rows, &look,
                 &view, &acc, &m.taken);
    store_pixels(image, px, py, cam.width, cam.height, acc);
    int8 t8 = m.taken.lo + m.taken.hi;
    int4 t4 = t8.lo + t8.hi;
    samples[slot] = (uint)(t4.s0 + t4.s1 + t4.s2 + t4.s3);
}
