/* cdvr/device.h - the OpenCL device pipeline (DESIGN.md sections 2 and 6).
 *
 * A cdvr_cl is one OpenCL context, queue and compiled program on one device; a
 * cdvr_cl_stream holds the device buffers of one playback (one volume size). Every call is
 * blocking (it returns when the device work is done), so the caller can time each stage, and
 * all calls on one cdvr_cl and its streams must come from one thread at a time.
 *
 * Device choice: the first GPU over all platforms, else the first CPU device. The environment
 * variable CDVR_CL_DEVICE overrides it: "gpu", "cpu", "none" (no device: cdvr_cl_open fails
 * with CDVR_ERR_DEVICE, everything on the CPU keeps working), "P:D" (platform P, device D,
 * indices from 0 as clinfo -l lists them) or any other text, matched as a case-insensitive
 * substring of the device name.
 *
 * Kernels are compiled at run time from the OpenCL C sources in CDVR_KERNELS (environment)
 * or else the build's kernels/ directory. Program binaries are cached on disk in
 * CDVR_CACHE_DIR, else $XDG_CACHE_HOME/cdvr, else ~/.cache/cdvr, keyed by a hash of the
 * source, build options, device name, driver version and platform; an unreadable, corrupt
 * or stale entry is ignored and rebuilt.
 *
 * This header needs no OpenCL headers; without OpenCL in the build (CDVR_HAVE_OPENCL 0) the
 * functions are not compiled and the Lua layer reports that OpenCL is not built in.
 */
#ifndef CDVR_DEVICE_H
#define CDVR_DEVICE_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/codec.h"
#include "cdvr/render.h"
#include "cdvr/skip.h"
#include "cdvr/tf.h"

typedef struct cdvr_cl cdvr_cl;
typedef struct cdvr_cl_stream cdvr_cl_stream;

/* What was opened (strings are NUL-terminated, truncated if longer). */
typedef struct cdvr_cl_info {
    char platform[128];
    char device[128];
    char device_version[128];
    char driver_version[64];
    int is_gpu;                  /* 1 for CL_DEVICE_TYPE_GPU, 0 for CPU / other */
    unsigned compute_units;
    uint64_t global_mem_bytes;
    uint64_t max_alloc_bytes;
    int platform_index, device_index;
    double build_seconds;        /* time to get the program (compile, or load from cache) */
    int from_cache;              /* 1 if the program binary came from the on-disk cache */
    char cache_path[512];        /* the cache file used or written ("" if caching failed) */
    int dense_frames;            /* 1: frames stay dense, with no tiled or quad copy, for
                                    renders that read no gradients (cdvr_cl_takes_host_tiles):
                                    CDVR_CL_TILES=0, or a CPU device where cdvr_cl_open measured
                                    dense casts faster; CDVR_CL_TILES=1 forces the copies */
    double layout_dense_ms;      /* that measurement (remembered beside the program cache):  */
    double layout_tiled_ms;      /* median cast of the dense and the tiled probe frame; 0: none */
    size_t quads_max_bytes;      /* the largest quad copy a CPU device makes by default:
                                    CDVR_CL_QUADS_MAX_BYTES, or CDVR_CL_QUADS_LARGE_MAX_BYTES
                                    where cdvr_cl_open measured the probe frame's quad copy
                                    faster than its tiled copy, or than its dense frame where
                                    frames stay dense (0 on GPUs: no quad copy) */
    int still_quads;             /* dense frames only: a frame rendered again still gets its
                                    tiled and quad copies (quad copy within quads_max_bytes,
                                    not iso, not clipped), as that measurement found faster */
    double quads_base_ms;        /* that measurement (remembered): the probe's composite and */
    double quads_ms;             /* max casts without quads (the tiled copy, or the dense
                                    frame where frames stay dense) and with them; 0: none */
} cdvr_cl_info;

/* Chooses a device (see above), creates context, queue and program, and on a CPU device the
 * frame layout the ray caster reads (info.dense_frames): the one that cast faster, measured
 * once per device, driver and cdvr version on a synthetic 272^3 frame (5 alternating pairs,
 * medians; dense where it takes below CDVR_CL_DENSE_SHARE of the tiled time; both sides cast
 * two frames in turn, the tiled side from frames tiled by the host as the player's decoder
 * writes them, so neither casts a frame it cast just before) and remembered
 * beside the program cache; GPUs keep the tiled copies. The layout decides the frames cast
 * once (playback, a frame's first render): frames rendered again get the quad copy where it
 * measured faster either way (still_quads), and renders that read gradients the tiled copy. On failure *out is NULL
 * and err names the reason (no platform, CDVR_CL_DEVICE=none, no match for the override,
 * missing kernel file, build failure with the build log). */
cdvr_status cdvr_cl_open(cdvr_cl **out, cdvr_error *err);
/* 0.93 while dense devices gave up the copies of frames rendered again (an Intel Xeon then
 * measured 0.924-0.935 from run to run after pairs16_gathered, and its still frames lost the
 * quads when the record said dense); since still_quads, the faster one */
#define CDVR_CL_DENSE_SHARE 1.0
/* Which probes made a remembered choice: 2 since the layout probe's tiled side casts two
 * host-tiled frames in turn (before, one tiled copy again and again, which the caches kept:
 * an Intel Xeon measured tiled 0.99 of dense there, but 1.09-1.11 cast once, and zfp1
 * playback's render took 55-58 ms tiled against 47-52 dense). A record of other probes is
 * measured again. */
#define CDVR_CL_PROBES_REVISION 2
/* The quad copy (cl_render.c, quads_ready: 4 bytes per voxel of the tiled copy, 2 reads per
 * sample instead of 8) is made for frames whose copy takes at most CDVR_CL_QUADS_MAX_BYTES.
 * Beyond that its cache misses may cost more than its fewer reads save, and which wins depends
 * on the CPU's caches, so cdvr_cl_open measures it once per CPU device (the probe frame's
 * quad copy is 95 MB; composite and max, 5 alternating pairs each, the sums of their medians)
 * against the tiled copy, or against the dense frame where frames stay dense, and raises the
 * limit to CDVR_CL_QUADS_LARGE_MAX_BYTES where quads take below CDVR_CL_QUADS_SHARE of that
 * time; where frames stay dense, a frame rendered again then still gets the copies
 * (info.still_quads), while the player's frames stay dense. CDVR_CL_QUADS=0|1 at render time
 * overrides the limit; with it or CDVR_CL_TILES set, nothing is measured and the limit stays
 * the default (no copies where frames stay dense). */
#define CDVR_CL_QUADS_MAX_BYTES ((size_t)64 << 20)
#define CDVR_CL_QUADS_LARGE_MAX_BYTES ((size_t)256 << 20)
#define CDVR_CL_QUADS_SHARE 0.95
/* Releases everything; NULL is allowed. Streams must be freed first. */
void cdvr_cl_close(cdvr_cl *cl);

/* Pins PoCL's CPU worker threads, one per CPU, where that is safe; returns 1 when it did.
 * PoCL runs kernels on one unpinned worker per core. Woken together by the host thread, two
 * workers often start on one core and share it for the whole kernel while another core idles
 * (Linux wakes a thread near its waker): in scripts/bench/vs_vtk.py's alternation, Colin27
 * 512^2 frames of 12-19 ms among frames of 8-9 ms on 2 cores. Pinned (PoCL's POCL_AFFINITY=1:
 * worker i on CPU i) the slow frames went (12 ms at most, 90% under 9.6 ms).
 * It sets POCL_AFFINITY=1 in the environment unless CDVR_CL_AFFINITY is "0", the user set
 * POCL_AFFINITY, POCL_MAX_PTHREAD_COUNT or POCL_PTHREAD_MIN_THREADS, or this process may not
 * run on every online CPU (numbered 0 .. n-1): PoCL aborts when a pin is refused, as it is
 * inside a restricted CPU set (taskset, container cpusets). Other OpenCL platforms ignore the
 * variable. It also sets CDVR_CL_AFFINITY_SET=1, so that a cdvr started from this process
 * (which inherits both) decides afresh in its own CPU set. Call it before any other thread
 * starts (setenv is not thread-safe) and before the first OpenCL call (PoCL reads it when it
 * starts its workers); cdvr's main() does. */
int cdvr_cl_default_affinity(void);
/* Device name as the driver reports it. */
const char *cdvr_cl_device_name(const cdvr_cl *cl);
/* Platform, device and build details. */
const cdvr_cl_info *cdvr_cl_get_info(const cdvr_cl *cl);

/* Edge (voxels) of the bricks of the min/max grid used for empty-space skipping (one
 * definition, kernels/common/cl_shared.h). */
size_t cdvr_cl_brick_edge(void);

/* Device buffers for frames of dims (u8), the chunk payload, the TF and the brick grid.
 * Buffers grow on demand (larger payloads, more frames per chunk). */
cdvr_status cdvr_cl_stream_create(cdvr_cl *cl, const size_t dims[3], cdvr_cl_stream **out,
                                  cdvr_error *err);
/* Releases the stream's buffers; NULL is allowed. */
void cdvr_cl_stream_free(cdvr_cl_stream *s);

/* b2: copies a chunk payload to the device. */
cdvr_status cdvr_cl_upload(cdvr_cl_stream *s, const void *payload, size_t bytes,
                           cdvr_error *err);

/* b3: makes device frames 0 .. count-1 of the stream's dims from the uploaded payload of a
 * chunk of `codec` with `params` (cdvr/codec.h), count <= the codec's timesteps per chunk:
 *  - decode mode: dense frames, by the codec's decode kernel or, on a CPU device where that
 *    is faster, by its C decoder (cdvr_cl_decode_path), bit-exact with each other;
 *  - fetch mode: on the SAMPLE path (cdvr_cl_fetch_path) keeps the payload as it is;
 *    cdvr_cl_setup and cdvr_cl_render read every voxel through the codec's fetch function
 *    (rendering in the compressed domain); on the BULK path dense frames by the codec's C
 *    decoder, as decode mode's host path;
 *  - codecs without OpenCL source: CDVR_ERR_UNSUPPORTED (decode on the CPU and use
 *    cdvr_cl_upload_frames).
 * The codec's program is built (or loaded from the binary cache) on first use. */
cdvr_status cdvr_cl_decode(cdvr_cl_stream *s, const cdvr_codec *codec,
                           const cdvr_codec_params *params, size_t count, cdvr_error *err);

/* Decode paths of decode-mode codecs. Both give the same bytes (the kernels are bit-exact
 * with the codecs' C decoders). */
typedef enum cdvr_cl_decode_path {
    CDVR_CL_DECODE_AUTO = 0,   /* the kernel on GPUs and other devices that are not CPUs; on a
                                  CPU device the faster of the two, measured on the first
                                  chunk of each codec and remembered for the device (in
                                  memory, and on disk beside the program cache) */
    CDVR_CL_DECODE_KERNEL = 1, /* the codec's decode kernel */
    CDVR_CL_DECODE_HOST = 2    /* the codec's C decoder writing straight into the frames
                                  buffer, mapped (host memory on CPU devices: no copy) */
} cdvr_cl_decode_path;

/* The path cdvr_cl_decode takes from now on. New streams take AUTO, or what the environment
 * variable CDVR_CL_DECODE says ("auto", "kernel" or "host"). */
void cdvr_cl_set_decode_path(cdvr_cl_stream *s, cdvr_cl_decode_path path);
/* The path the last successful cdvr_cl_decode of a decode-mode codec took (AUTO before any). */
cdvr_cl_decode_path cdvr_cl_last_decode_path(const cdvr_cl_stream *s);

/* Paths of fetch-mode codecs (hvq). Both give the same images: the fetch function returns
 * exactly what the codec's C decoder gives (cdvr/codec.h). */
typedef enum cdvr_cl_fetch_path {
    CDVR_CL_FETCH_AUTO = 0,    /* SAMPLE on GPUs and other devices that are not CPUs; on a
                                  CPU device (PoCL) the faster of the two for the codec and
                                  the chunk's size class, measured on the first render that
                                  needs it (cdvr_cl_remember_fetch_path) and remembered for
                                  the device (in memory, and on disk beside the program
                                  cache); BULK until measured (on PoCL it is 20-40x faster
                                  than a hashed fetch per sample at 512^2) */
    CDVR_CL_FETCH_SAMPLE = 1,  /* the ray caster reads every sample through the codec's fetch
                                  function: the device holds only the payload */
    CDVR_CL_FETCH_BULK = 2     /* cdvr_cl_decode runs the codec's C decoder into dense frames
                                  (device memory: dims product per frame), then the dense
                                  kernels render them */
} cdvr_cl_fetch_path;

/* The fetch-mode path cdvr_cl_decode takes from now on. New streams take AUTO, which means
 * what the environment variable CDVR_CL_FETCH says ("sample" or "bulk") when it is set,
 * else the rule above. */
void cdvr_cl_set_fetch_path(cdvr_cl_stream *s, cdvr_cl_fetch_path path);
/* The path a fetch-mode codec takes on this stream by the set path, the environment and the
 * device type alone: SAMPLE or BULK. */
cdvr_cl_fetch_path cdvr_cl_fetch_path_of(const cdvr_cl_stream *s);
/* The path cdvr_cl_decode takes for count frames of codec: the set path, the environment,
 * SAMPLE on a GPU, else the path remembered for the codec and size class (floor(log4) of
 * the decoded bytes) on this device; AUTO when that is not measured yet (cdvr_cl_decode
 * then takes BULK). Not thread-safe with other calls on the stream's device. */
cdvr_cl_fetch_path cdvr_cl_fetch_path_for(cdvr_cl_stream *s, const cdvr_codec *codec,
                                          size_t count);
/* Records a measurement of both paths for count frames of codec on this device (whole
 * frames: load, decode and render, in ms): the faster one becomes the remembered path. */
void cdvr_cl_remember_fetch_path(cdvr_cl_stream *s, const cdvr_codec *codec, size_t count,
                                 double sample_ms, double bulk_ms);

/* b2 for frames decoded on the host: uploads count dense u8 frames (count * dims product
 * bytes) as device frames 0 .. count-1. */
cdvr_status cdvr_cl_upload_frames(cdvr_cl_stream *s, const uint8_t *frames, size_t count,
                                  cdvr_error *err);

/* b2 without a copy for frames decoded on the host: count dense u8 frames in the caller's
 * memory become device frames 0 .. count-1 (a buffer over that memory: devices that share host
 * memory read it in place, others copy it). The memory must stay allocated and unchanged
 * until the stream's next decode or upload, or until the stream is freed. Page-aligned memory
 * avoids a copy on most CPU drivers. */
cdvr_status cdvr_cl_use_host_frames(cdvr_cl_stream *s, const uint8_t *frames, size_t count,
                                    cdvr_error *err);

/* b2 for a frame the host decoded straight into the ray caster's tiled copy (codec.h,
 * CDVR_LAYOUT_TILED; cdvr_tiled_bytes of the stream's dims, in the caller's memory as for
 * cdvr_cl_use_host_frames): it becomes frame 0, whose ray casts read it instead of a copy the
 * device makes (the tiles are read from fewer cache lines than a dense frame: 1.17x faster
 * casts on the CPU device). No frame holds the dense voxels then: such a frame is rendered
 * only with a grid from the caller (cdvr_cl_setup_grid; cdvr_cl_setup and cdvr_cl_download
 * refuse it), its samples and gradients come from the tiles (no quad or gradient copy).
 * CDVR_ERR_UNSUPPORTED where the frames do not fit a tiled copy (cdvr_cl_takes_host_tiles). */
cdvr_status cdvr_cl_use_host_tiles(cdvr_cl_stream *s, const uint8_t *tiles, cdvr_error *err);
/* Whether a render that reads gradients (1: shading or gradient opacity) or not (0) casts
 * from the ray caster's tiled copy, the device's own (made for a frame rendered again) or the
 * caller's: the stream's frames fit it (whole pages within its 32-bit indices and the
 * device's largest buffer; not with CDVR_CL_LONG_INDEX=1), and the device casts from tiles
 * (cdvr_cl_info.dense_frames 0, or a render that reads gradients: those come from the tiles
 * and their gradient copy faster than from a dense frame). */
int cdvr_cl_takes_host_tiles(const cdvr_cl_stream *s, int gradients);

/* Device memory the stream holds now (all its buffers), and the part that holds the volume
 * data of the current frames (dense frames, or payload + parameters in fetch mode). */
uint64_t cdvr_cl_stream_bytes(const cdvr_cl_stream *s);
uint64_t cdvr_cl_volume_bytes(const cdvr_cl_stream *s);

/* b4: per-frame setup for device frame `frame` (from 0, < count of the last decode): uploads
 * the TF table, computes the brick min/max grid (bricks of cdvr_cl_brick_edge()^3 voxels, each range
 * including the upper one-voxel apron that trilinear interpolation reads) and the per-brick
 * flag "some value in [min, max] has alpha > 0 under this TF". */
cdvr_status cdvr_cl_setup(cdvr_cl_stream *s, size_t frame, const cdvr_tf *tf, cdvr_error *err);

/* b4 from a grid the caller made (cdvr/skip.h: bricks of cdvr_cl_brick_edge() voxels over
 * the stream's dims, flags made for tf, e.g. from a store's range tables on another thread):
 * its flags are uploaded as they are. CDVR_ERR_ARG when the grid does not fit. The grid must
 * stay allocated and unchanged until the frame's cdvr_cl_render: a max or min render uploads
 * its min/max ranges then (composite never needs them). */
cdvr_status cdvr_cl_setup_grid(cdvr_cl_stream *s, size_t frame, const cdvr_tf *tf,
                               const cdvr_skip_grid *g, cdvr_error *err);

/* b5: ray casts device frame `frame` with the TF of the last cdvr_cl_setup (which must have
 * been called for this frame) following render.h exactly, in float. A frame rendered a second
 * time in a row gets a tiled copy (a byte per voxel in 4x4x4 tiles of one cache line) that
 * the ray caster reads faster; the images are the same; with empty-space skipping, rays start
 * at a per-packet bound of where they can first meet a visible brick (cdvr/skip.h, entry
 * distances). Frames of 2^31 voxels or more use kernels with 64-bit voxel indices
 * (built on first use; the environment variable CDVR_CL_LONG_INDEX=1 forces them, for tests). The volume's geometry:
 * spacing, origin and direction (volume.h: row-major 3x3, column c = world direction of index
 * axis c; NULL or all zeros = identity; must be invertible). opts->tf is used only
 * for its unit when opts->unit is 0 (NULL: the TF of the setup); opts->threads and
 * opts->samples are ignored (see cdvr_cl_last_samples). With opts->clip the stream's frames
 * are the box of the whole volume that render.h's clipped rendering describes (no empty-space
 * skipping then: the brick grid covers the box's voxels only). img must have the camera's size;
 * its pixels are overwritten and its background set from opts->background. */
cdvr_status cdvr_cl_render(cdvr_cl_stream *s, size_t frame, const cdvr_render_opts *opts,
                           const double spacing[3], const double origin[3],
                           const double direction[9], cdvr_image *img, cdvr_error *err);

/* Empty-space skipping on (default) or off. Results agree within rounding (0.5/255). */
void cdvr_cl_set_skipping(cdvr_cl_stream *s, int enabled);
/* Samples taken (trilinear + classification) by the last cdvr_cl_render. */
uint64_t cdvr_cl_last_samples(const cdvr_cl_stream *s);
/* Bricks flagged visible / total by the last cdvr_cl_setup. */
void cdvr_cl_brick_counts(const cdvr_cl_stream *s, size_t *visible, size_t *total);

/* Copies device frame `frame` (from 0) to out (dims product bytes). Dense frames only: in
 * fetch mode the frames stay compressed (CDVR_ERR_UNSUPPORTED). */
cdvr_status cdvr_cl_download(cdvr_cl_stream *s, size_t frame, uint8_t *out, cdvr_error *err);

#endif
