/* core/render/cl/cl_internal.h - what cl_device.c, cl_pvtc.c and cl_render.c share (not installed). */
#ifndef CDVR_CL_INTERNAL_H
#define CDVR_CL_INTERNAL_H

#ifdef __APPLE__
#include <OpenCL/cl.h>
#else
#include <CL/cl.h>
#endif

#include <stdlib.h>
#include <string.h>

#include "cdvr/codec.h"
#include "cdvr/device.h"
#include "cdvr/skip.h"
#include "common/cl_shared.h"

/* Whether environment variable `name` is set to `value` (the CDVR_CL_* switches). */
static inline int cdvr_cl_env_is(const char *name, const char *value)
{
    const char *env = getenv(name);
    return env && !strcmp(env, value);
}

/* The dense render kernels with 64-bit voxel indices (built on first use). */
cdvr_status cdvr_cl_long_index_kernels(cdvr_cl *cl, cl_kernel *bricks, cl_kernel *raycast,
                                       cdvr_error *err);

/* The program of one codec: its decode kernel (decode mode), or the brick min/max and
 * ray-cast kernels built over its fetch function (fetch mode). */
#define CDVR_CL_SIZE_CLASSES 32

typedef struct cdvr_cl_codec_program {
    const cdvr_codec *codec;
    cl_program program;
    cl_kernel k_decode;
    cl_kernel k_bricks, k_raycast;
    /* decode mode on a CPU device: the faster path per size class of the decoded frames
     * (floor(log4(bytes))), once measured (cl_stream.c); AUTO until known */
    cdvr_cl_decode_path fastest[CDVR_CL_SIZE_CLASSES];
    double kernel_ms[CDVR_CL_SIZE_CLASSES], host_ms[CDVR_CL_SIZE_CLASSES];
} cdvr_cl_codec_program;

#define CDVR_CL_MAX_CODEC_PROGRAMS 32

/* The faster path of a fetch-mode codec for one size class on this device: measured
 * (cdvr_cl_remember_fetch_path) or loaded from the disk record; AUTO when neither exists. */
typedef struct cdvr_cl_fetch_choice {
    const cdvr_codec *codec;
    unsigned size_class;
    cdvr_cl_fetch_path path;
    double sample_ms, bulk_ms;
} cdvr_cl_fetch_choice;

#define CDVR_CL_MAX_FETCH_CHOICES 64
#define CDVR_CL_BRICK (1u << CDVR_CL_BRICK_SHIFT) /* edge of the skipping bricks, voxels */

struct cdvr_cl {
    cl_platform_id platform;
    cl_device_id device;
    cl_context context;
    cl_command_queue queue;
    cl_program program;              /* dense brick min/max, ray cast, tiled copy, gradients */
    cl_kernel k_bricks, k_raycast, k_tiles, k_grads, k_quads;
    cl_program program_long;         /* the same with 64-bit voxel indices (frames of 2^31
                                        voxels or more), built on first use */
    cl_kernel k_bricks_long, k_raycast_long;
    cdvr_cl_codec_program codecs[CDVR_CL_MAX_CODEC_PROGRAMS]; /* built on first use */
    size_t ncodecs;
    cdvr_cl_fetch_choice fetch_choices[CDVR_CL_MAX_FETCH_CHOICES]; /* looked up or measured */
    size_t nfetch_choices;
    cdvr_cl_info info;
};

/* The program of codec (built, or loaded from the binary cache, on first use). */
cdvr_status cdvr_cl_get_codec_program(cdvr_cl *cl, const cdvr_codec *codec,
                                      cdvr_cl_codec_program **out, cdvr_error *err);
/* The decode path remembered on disk for codec and a size class on this device (beside the
 * program cache, keyed by the device, its driver, the codec's kernel source and the class), or
 * CDVR_CL_DECODE_AUTO when none is; and the writer of that record. */
cdvr_cl_decode_path cdvr_cl_load_decode_choice(cdvr_cl *cl, const cdvr_codec *codec,
                                               unsigned size_class, double *kernel_ms,
                                               double *host_ms);
void cdvr_cl_store_decode_choice(cdvr_cl *cl, const cdvr_codec *codec, unsigned size_class,
                                 cdvr_cl_decode_path path, double kernel_ms, double host_ms);
/* The same for the paths of fetch-mode codecs (cdvr_cl_fetch_path). */
cdvr_cl_fetch_path cdvr_cl_load_fetch_choice(cdvr_cl *cl, const cdvr_codec *codec,
                                             unsigned size_class, double *sample_ms,
                                             double *bulk_ms);
void cdvr_cl_store_fetch_choice(cdvr_cl *cl, const cdvr_codec *codec, unsigned size_class,
                                cdvr_cl_fetch_path path, double sample_ms, double bulk_ms);
/* Whether the stream's frames fit the tiled copy (cdvr_cl_takes_host_tiles, whatever the
 * device's layout): a shaded render on a device that keeps frames dense still gets the tiled
 * and gradient copies (cl_render.c: from the dense frame, central differences took 1.6-1.8x
 * the time on the AMD EPYC that prefers dense frames otherwise). */
int cdvr_cl_tiles_fit(const cdvr_cl_stream *s);
/* Median times of casting a synthetic frame (cl_render.c: 272^3, 256^2 pixels) from the dense
 * frame and from its tiled copy, alternating (cdvr_cl_open's choice of info.dense_frames). */
cdvr_status cdvr_cl_measure_layouts(cdvr_cl *cl, double *dense_ms, double *tiled_ms,
                                    cdvr_error *err);
/* The sums of the median composite and max casts of that frame from its tiled copy alone
 * (or its dense frame when `dense`) and with its quad copy (95 MB), alternating (cdvr_cl_open's
 * info.quads_max_bytes and still_quads). */
cdvr_status cdvr_cl_measure_quads(cdvr_cl *cl, int dense, double *base_ms, double *quads_ms,
                                  cdvr_error *err);
/* Sets argument `index` of kernel `name`; on failure fills err naming both. */
cdvr_status cdvr_cl_arg(cl_kernel k, const char *name, cl_uint index, size_t size,
                        const void *value, cdvr_error *err);

/* Which entry list a render's entry tiles come from: the TF's visible bricks (composite), the
 * iso flags' or the bricks above 0 (max, average: entry and exit tiles). */
typedef enum { CDVR_CL_ENTRY_VISIBLE, CDVR_CL_ENTRY_ISO, CDVR_CL_ENTRY_ZEROS } cdvr_cl_entry_kind;

/* What a stream's entry tiles were made for (cl_render.c): the camera and the volume's
 * placement, which entry list and its version, and the tiles' count. */
typedef struct cdvr_cl_entry_made {
    cdvr_skip_view view;
    uint64_t version;
    size_t tiles[2];
    int kind; /* cdvr_cl_entry_kind */
    int valid;
} cdvr_cl_entry_made;

struct cdvr_cl_stream {
    cdvr_cl *cl;
    size_t dims[3];
    size_t voxels;               /* dims product */
    size_t brick_dims[3];
    size_t nbricks;
    cl_mem payload;              /* uploaded chunk */
    size_t payload_capacity, payload_bytes;
    cl_mem params;               /* the chunk's parameter blob + payload size (cl_shared.h) */
    cl_mem frames;               /* decoded u8 frames, contiguous */
    size_t frame_capacity, frames_valid;
    cl_mem host_frames;          /* frames in the caller's memory (cdvr_cl_use_host_frames), */
                                 /* read instead of `frames` while set */
    const cdvr_cl_codec_program *fetch; /* frames stay compressed: read through this codec's
                                           fetch kernels (NULL: dense frames) */
    cl_mem table;                /* 256 ulong: packed rgb + step-corrected alpha (per render) */
    cl_mem tf_rows;              /* 256 x 4 floats: the TF's r, g, b, alpha per unit length */
    cl_mem brick_minmax;         /* nbricks uchar2: value range per brick incl. apron, then
                                    nblocks uchar2: the range of each block of bricks
                                    (CDVR_CL_BLOCK_SHIFT) */
    size_t block_dims[3], nblocks; /* blocks per axis, in all */
    const uint8_t *pending_minmax; /* cdvr_cl_setup_grid's grid ranges, not uploaded yet (only
                                    a max or min render uploads them) */
    int minmax_valid;            /* brick_minmax holds the set-up frame's ranges (the max and
                                    min blend modes skip by them) */
    int blocks_valid;            /* and after them its blocks' ranges (made when a max, min or
                                    average render first needs them) */
    cl_mem tiles;                /* tiled copy of frame tiles_frame for the ray caster */
    size_t tiles_capacity, tiles_frame;
    int only_tiles;              /* frame 0 is the caller's tiled copy (cdvr_cl_use_host_tiles):
                                    tiles wraps that memory, and no frame holds its voxels */
    cl_mem grads;                /* gradient copy of frame grads_frame (cl_shared.h), made with
                                    the tiled copy for renders that shade */
    size_t grads_capacity, grads_frame;
    cl_mem quads;                /* quad copy of frame quads_frame (cl_shared.h), made with the
                                    tiled copy (cl_render.c, quads_ready) */
    size_t quads_capacity, quads_frame;
    int quads_probe;             /* cdvr_cl_measure_quads' streams: 1 always makes the quad
                                    copy, -1 never; 0 (every other stream): quads_ready's rule */
    size_t last_rendered;        /* frame of the last render: a second render of it makes tiles */
    cl_mem brick_visible;        /* nbricks uchar flags */
    cl_mem image;                /* width*height float4 */
    cl_mem samples;              /* uint sample counter per ray-cast work-item */
    size_t image_pixels, sample_slots;
    cdvr_skip_grid grid;         /* host copy of the min/max grid (minmax_frame) and the
                                    flags last uploaded to brick_visible (cdvr/skip.h) */
    size_t minmax_frame;         /* frame grid.minmax belongs to, (size_t)-1 for none */
    int grid_uploaded;           /* brick_visible holds another grid's flags (setup_grid) */
    uint64_t minmax_count;       /* grid.minmax computations so far (compute_minmax) */
    cl_mem iso_flags;            /* nbricks uchar flags of grid.minmax for the code iso_mark
                                    (iso skipping, raycast.cl; cl_render.c, iso_flags_ready) */
    uint64_t iso_minmax;         /* minmax_count of the ranges iso_flags holds, 0: none */
    int iso_mark;                /* the code they mark, -1: none */
    cdvr_tf tf;                  /* TF of the last setup */
    size_t setup_frame;          /* frame of the last setup, (size_t)-1 for none */
    size_t bricks_visible;
    cl_float visible_lo[3];      /* grid box holding every visible brick (lower corner of its */
    cl_float visible_hi[3];      /* bricks, +-inf at the grid's faces); lo > hi: none visible */
    int skipping;
    cdvr_skip_entry entry;       /* boxes of the uploaded flags' boundary bricks (cdvr/skip.h) */
    int entry_ok;                /* entry describes the flags in brick_visible */
    cdvr_skip_entry iso_entry;   /* the same for the flags in iso_flags */
    int iso_entry_ok;
    cdvr_skip_entry zero_entry;  /* the same for the bricks holding a code above 0 (max and
                                    average: entry and exit bounds) */
    int zero_entry_ok;
    uint64_t zero_minmax;        /* minmax_count of the ranges zero_entry was made of, 0: none */
    cl_mem zero_flags;           /* nbricks uchar flags of those bricks (average's leaps,
                                    raycast.cl; cl_render.c, zero_entry_ready) */
    int zero_flags_ok;           /* zero_flags holds them */
    cl_mem entry_tiles;          /* per packet: t before which no ray meets a visible brick */
    size_t entry_capacity;       /* bytes of entry_tiles */
    cdvr_cl_entry_made entry_made; /* what entry_tiles were made for (valid 0: none) */
    uint64_t last_samples;
    cdvr_cl_decode_path decode_path;      /* what cdvr_cl_decode may use (AUTO: choose) */
    cdvr_cl_decode_path last_decode_path; /* what the last decode used */
    cdvr_cl_fetch_path fetch_path;        /* what a fetch-mode codec takes (AUTO: by device) */
};

/* The buffer holding the stream's dense frames now. */
static inline cl_mem cdvr_cl_frames_mem(const cdvr_cl_stream *s)
{
    return s->host_frames ? s->host_frames : s->frames;
}

/* "CL_OUT_OF_RESOURCES" etc. for an OpenCL error code. */
const char *cdvr_cl_error_name(cl_int code);
/* If code is not CL_SUCCESS fills err with "OpenCL: what: NAME (code)" and returns
 * CDVR_ERR_DEVICE; otherwise returns CDVR_OK. */
cdvr_status cdvr_cl_check(cl_int code, const char *what, cdvr_error *err);
/* (Re)allocates *mem to hold at least bytes (contents are lost on growth). */
cdvr_status cdvr_cl_ensure_buffer(cdvr_cl *cl, cl_mem *mem, size_t *capacity, size_t bytes,
                                  cl_mem_flags flags, const char *what, cdvr_error *err);
/* cdvr_cl_ensure_buffer (CL_MEM_READ_WRITE) for a frame's copy that kernels gather voxels from
 * at random (tiles, quads, gradients): on a CPU device, from a huge page up, in host memory
 * marked for huge pages. Copies of up to hundreds of MB are read by lanes that each land on
 * another page; once other programs have taken the caches (a frame drawn after a pause, or
 * after VTK's frame in vs_vtk.py) each such read's page walk goes to memory too. */
cdvr_status cdvr_cl_ensure_gathered(cdvr_cl *cl, cl_mem *mem, size_t *capacity, size_t bytes,
                                    const char *what, cdvr_error *err);
/* Releases a buffer if set and clears the handle. */
void cdvr_cl_release(cl_mem *mem);

#endif
