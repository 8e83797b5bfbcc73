/* cdvr/codec.h - one interface for every codec (DESIGN.md section 4.0) and the registry.
 *
 * A codec turns the u8 frames of one chunk (a few consecutive timesteps of one brick of a
 * series) into a payload and back. The store, the encoder, schedules, the player, the
 * renderers and the Lua layer only ever go through a `cdvr_codec` table; none of them names a
 * codec or its parameters. Built-in codecs: "raw" (id 0), "pvtc" (id 1), "hvq" (id 2),
 * "hvqc" (id 3);
 * plugins (cdvr/plugin.h) add more at run time.
 *
 * Parameters. Each codec keeps its parameters in a `cdvr_codec_params` blob of at most
 * CDVR_CODEC_PARAMS_MAX bytes whose layout the codec alone defines. The blob is stored as it
 * is in the store (per variant and per chunk), so its layout must be byte-exact and
 * independent of the host: fixed-width little-endian fields at fixed offsets, unused bytes 0.
 * The codec parses it from key/value text (what Lua gives: `S=4`, `pack="space"`,
 * `rate=0.5`), renders it back for reports, validates a blob read from a file, and names a
 * variant after it ("S4T3s", "zfp2", "raw").
 *
 * Chunks. For the dims of a brick, `shape` gives the timesteps one chunk holds, the exact
 * payload size when it is fixed by the parameters (PVTC, raw) and a worst-case bound (any
 * codec; what the encoder allocates). `encode` gets exactly shape.timesteps frame pointers:
 * the encoder repeats the last real timestep past the end of the series, and `count` says
 * how many are real. `decode` writes `count` (1 .. shape.timesteps) frames. The C decoder is
 * the definition of the codec: every other path (SIMD, OpenCL) must be bit-exact with it.
 * Decoders must never read or write out of bounds, whatever the payload holds (they are
 * fuzzed): a payload that does not fit gives CDVR_ERR_CORRUPT.
 *
 * OpenCL, optional (cl_mode):
 *  - CDVR_CODEC_CL_NONE: the chunk is decoded on the CPU and its frames are uploaded.
 *  - CDVR_CODEC_CL_DECODE: a decode kernel writes the chunk's dense u8 frames on the device
 *    before the ray cast. Its signature is fixed:
 *        __kernel void NAME(__global const uchar *payload, ulong payload_bytes,
 *                           __constant uchar *params, uint X, uint Y, uint Z, uint nframes,
 *                           __global uchar *frames)
 *    frames holds nframes frames of X*Y*Z voxels, frame f at offset f*X*Y*Z; the host runs
 *    cl_work_items(params, dims) work-items (1-D, no local size).
 *  - CDVR_CODEC_CL_FETCH: no dense volume on the device. The ray-cast kernel (and the brick
 *    min/max kernel) read every voxel through the codec's fetch function:
 *        uchar NAME(__global const uchar *payload, __constant uchar *params, int4 dims,
 *                   int x, int y, int z)
 *    dims = (X, Y, Z, frame within the chunk); 0 <= x < X, 0 <= y < Y, 0 <= z < Z. The
 *    function must return exactly what the C decoder gives for that voxel, and must never
 *    read outside the payload, whatever its bytes: it clamps every offset it computes from
 *    payload bytes below the payload's size (kernels/codec/hvq_fetch.cl).
 *  The source is cl_source (text; what plugins use) or cl_file (a path under the kernel
 *  directory, e.g. "codec/pvtc_decode.cl"). The params buffer holds the chunk's blob
 *  (CDVR_CODEC_PARAMS_MAX bytes) followed by the payload's size in bytes, a little-endian
 *  u64 at byte CDVR_CODEC_PARAMS_MAX (56 bytes in all: CDVR_CL_PARAMS_BUFFER_BYTES of
 *  kernels/common/cl_shared.h).
 *  Before either mode sees a chunk, cdvr_cl_decode runs the codec's `check` hook (below) on
 *  it, when the codec has one.
 *
 * Threads: every function of a codec table must be safe to call from several threads at
 * once on different chunks (the encoder runs chunks in parallel).
 */
#ifndef CDVR_CODEC_H
#define CDVR_CODEC_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "cdvr/error.h"

#define CDVR_CODEC_PARAMS_MAX 48  /* bytes of a parameter blob */
#define CDVR_CODEC_NAME_MAX 16    /* codec names: 1..15 bytes of [a-z0-9_] */
#define CDVR_VARIANT_NAME_MAX 32  /* variant names, NUL included */

/* Built-in codec ids. Plugin codecs choose any other id below 2^31 (the store records it);
 * a clash with a loaded codec is refused at registration. */
#define CDVR_CODEC_ID_RAW 0u
#define CDVR_CODEC_ID_PVTC 1u
#define CDVR_CODEC_ID_HVQ 2u
#define CDVR_CODEC_ID_HVQC 3u  /* hvq's compact form (cdvr/hvq.h) */

typedef struct cdvr_codec_params {
    uint8_t bytes[CDVR_CODEC_PARAMS_MAX];
} cdvr_codec_params;

/* One parameter a codec accepts, for cdvr.codecs() and error messages. */
typedef struct cdvr_codec_param_doc {
    const char *key;          /* "S" */
    const char *def;          /* default value as text: "4" */
    const char *description;  /* "block depth: 1 or 4" */
} cdvr_codec_param_doc;

typedef struct cdvr_codec_shape {
    size_t timesteps;         /* timesteps per chunk (>= 1) */
    size_t payload_bytes;     /* exact payload bytes when fixed by the parameters, else 0 */
    size_t bound_bytes;       /* worst-case payload bytes (>= payload_bytes) */
} cdvr_codec_shape;

typedef enum cdvr_codec_cl_mode {
    CDVR_CODEC_CL_NONE = 0,
    CDVR_CODEC_CL_DECODE = 1,
    CDVR_CODEC_CL_FETCH = 2
} cdvr_codec_cl_mode;

/* Frame layouts (decode_cells). LINEAR: voxel (x, y, z) at x + X * (y + Y * z). TILED: the
 * OpenCL ray caster's tiled copy (kernels/common/cl_shared.h): tiles of 4^3 voxels (64
 * bytes; x fastest, then y, z inside), 4^3 tiles to a page of 16^3 voxels (4096 bytes; tiles
 * x fastest, then y, z), pages x fastest, then y, z, ceil(dims / 16) pages per axis
 * (cdvr_tiled_bytes in all); voxel (x, y, z) at cdvr_tiled_offset. The voxels of a tile past
 * the frame's edge repeat the frame's last voxel along that axis (a decoder writes them with
 * the tile; tiles wholly past the edge are never read). */
#define CDVR_LAYOUT_LINEAR 0u
#define CDVR_LAYOUT_TILED 1u

static inline size_t cdvr_tiled_offset(const size_t dims[3], size_t x, size_t y, size_t z)
{
    size_t pages_x = (dims[0] + 15) / 16, pages_y = (dims[1] + 15) / 16;
    size_t page = (x >> 4) + pages_x * ((y >> 4) + pages_y * (z >> 4));
    size_t tile = ((x >> 2) & 3) + 4 * (((y >> 2) & 3) + 4 * ((z >> 2) & 3));
    return 4096 * page + 64 * tile + (x & 3) + 4 * (y & 3) + 16 * (z & 3);
}

/* Writes a codec block of 4^3 values (vals: x fastest, then y, z) whose first n[a] voxels per
 * axis lie inside the frame (dims), its first voxel at `at`, into frame in layout: rows of
 * n[0] bytes into a linear frame; the whole tile into a tiled one, the voxels past the
 * frame's edge repeating the last one inside along each axis. */
static inline void cdvr_block_store(uint8_t *frame, const size_t dims[3], unsigned layout,
                                    const size_t at[3], const size_t n[3],
                                    const uint8_t vals[64])
{
    if (layout == CDVR_LAYOUT_TILED) {
        uint8_t *tile = frame + cdvr_tiled_offset(dims, at[0], at[1], at[2]);
        if (n[0] == 4 && n[1] == 4 && n[2] == 4) {
            memcpy(tile, vals, 64);
            return;
        }
        for (size_t z = 0; z < 4; z++)
            for (size_t y = 0; y < 4; y++)
                for (size_t x = 0; x < 4; x++) {
                    size_t sx = x < n[0] ? x : n[0] - 1, sy = y < n[1] ? y : n[1] - 1;
                    size_t sz = z < n[2] ? z : n[2] - 1;
                    tile[x + 4 * y + 16 * z] = vals[sx + 4 * sy + 16 * sz];
                }
        return;
    }
    uint8_t *first = frame + at[0] + dims[0] * (at[1] + dims[1] * at[2]);
    for (size_t z = 0; z < n[2]; z++)
        for (size_t y = 0; y < n[1]; y++)
            memcpy(first + dims[0] * (y + dims[1] * z), vals + 4 * y + 16 * z, n[0]);
}

/* Bytes of a tiled frame of dims (whole pages), or 0 when that overflows a size_t. */
static inline size_t cdvr_tiled_bytes(const size_t dims[3])
{
    size_t n = 4096;
    for (int a = 0; a < 3; a++) {
        size_t pages = dims[a] / 16 + (dims[a] % 16 != 0);
        if (pages && n > (size_t)-1 / pages)
            return 0;
        n *= pages;
    }
    return n;
}

/* decode_cells' cells: need[] over cells of 2^cell_log2 voxels, cdims per axis (x fastest). */
typedef struct cdvr_cells {
    const uint8_t *need;
    unsigned log2;
    size_t cdims[3];
} cdvr_cells;

/* The cells of a frame of dims (each >= 1). */
static inline cdvr_cells cdvr_cells_of(const uint8_t *need, unsigned cell_log2,
                                       const size_t dims[3])
{
    cdvr_cells c = {need, cell_log2, {0, 0, 0}};
    for (int a = 0; a < 3; a++)
        c.cdims[a] = ((dims[a] - 1) >> cell_log2) + 1;
    return c;
}

/* The need byte of the cell holding voxel (x, y, z). */
static inline uint8_t cdvr_cells_voxel(const cdvr_cells *c, size_t x, size_t y, size_t z)
{
    return c->need[(x >> c->log2) + c->cdims[0] * ((y >> c->log2) + c->cdims[1] * (z >> c->log2))];
}

/* Whether the box of voxels lo[a] .. lo[a] + n[a] - 1 (each n >= 1) meets a needed cell: a
 * codec's test for one of its blocks. */
static inline int cdvr_cells_meet(const cdvr_cells *c, const size_t lo[3], const size_t n[3])
{
    size_t a0[3], a1[3];
    for (int a = 0; a < 3; a++) {
        a0[a] = lo[a] >> c->log2;
        a1[a] = (lo[a] + n[a] - 1) >> c->log2;
    }
    for (size_t z = a0[2]; z <= a1[2]; z++)
        for (size_t y = a0[1]; y <= a1[1]; y++)
            for (size_t x = a0[0]; x <= a1[0]; x++)
                if (c->need[x + c->cdims[0] * (y + c->cdims[1] * z)])
                    return 1;
    return 0;
}

typedef struct cdvr_codec cdvr_codec;

struct cdvr_codec {
    const char *name;                     /* registry key, e.g. "pvtc" */
    uint32_t id;                          /* recorded in stores */
    const char *description;              /* one line for cdvr.codecs() */
    const cdvr_codec_param_doc *params;   /* accepted keys, terminated by {NULL} */

    /* Fills p with the defaults (unused bytes 0). */
    void (*params_default)(cdvr_codec_params *p);
    /* Sets one parameter from text. Unknown key or bad value: CDVR_ERR_ARG with a message
     * naming the key, the value and what is accepted. */
    cdvr_status (*params_set)(cdvr_codec_params *p, const char *key, const char *value,
                              cdvr_error *err);
    /* Writes parameter `key` as text into out (n bytes); 0 on success, -1 for an unknown
     * key. Numbers are written so that params_set reads them back unchanged. */
    int (*params_get)(const cdvr_codec_params *p, const char *key, char *out, size_t n);
    /* Validates a whole blob (from the user or from a file): CDVR_ERR_ARG naming the reason. */
    cdvr_status (*params_check)(const cdvr_codec_params *p, cdvr_error *err);
    /* Default variant name for these parameters ("S4T3s", "zfp2"), at most n-1 bytes. */
    void (*variant_name)(const cdvr_codec_params *p, char *name, size_t n);

    /* Chunk shape for frames of dims (each >= 1); CDVR_ERR_ARG / CDVR_ERR_NOMEM on bad
     * parameters or sizes that overflow. */
    cdvr_status (*shape)(const cdvr_codec_params *p, const size_t dims[3],
                         cdvr_codec_shape *out, cdvr_error *err);
    /* Encodes one chunk: frames[0 .. shape.timesteps) (count of them real) into out
     * (out_cap >= shape.bound_bytes); *out_bytes = payload size (== shape.payload_bytes
     * when that is fixed). */
    cdvr_status (*encode)(const cdvr_codec_params *p, const size_t dims[3],
                          const uint8_t *const *frames, size_t count, uint8_t *out,
                          size_t out_cap, size_t *out_bytes, cdvr_error *err);
    /* Decodes count frames (1 .. shape.timesteps) of a payload of in_bytes. */
    cdvr_status (*decode)(const cdvr_codec_params *p, const size_t dims[3], const uint8_t *in,
                          size_t in_bytes, uint8_t *const *frames, size_t count,
                          cdvr_error *err);

    /* Optional (may be NULL): figures about one stored payload for reports, e.g. the bytes of
     * each part of an hvq chunk ("means", "codebook1", ...), "zero_blocks". st:info() sums
     * them over a variant's chunks. Calls emit(ud, key, value) once per figure; keys are
     * identifiers. Returns CDVR_OK, or an error for a payload it cannot read. */
    cdvr_status (*describe)(const cdvr_codec_params *p, const size_t dims[3],
                            const uint8_t *payload, size_t bytes,
                            void (*emit)(void *ud, const char *key, double value), void *ud,
                            cdvr_error *err);

    /* OpenCL (see the top of this file); cl_mode CDVR_CODEC_CL_NONE leaves the rest NULL. */
    cdvr_codec_cl_mode cl_mode;
    const char *cl_source;                /* OpenCL C text, or NULL */
    const char *cl_file;                  /* or a file under the kernel directory */
    const char *cl_function;              /* decode kernel or fetch function name */
    /* Decode mode: work-items to launch for a chunk of dims. */
    size_t (*cl_work_items)(const cdvr_codec_params *p, const size_t dims[3]);

    /* Optional (may be NULL), for codecs whose payload size is fixed by the parameters
     * (shape.payload_bytes != 0): lets the encoder spread one chunk over several threads.
     * Writes the bytes of part `part` (0 .. nparts-1, any nparts >= 1) of the payload that
     * `encode` writes for the same frames into out (out_cap >= shape.payload_bytes). The parts
     * write disjoint bytes that together make the whole payload, so running every part, in
     * any order and on any threads, into one buffer gives exactly encode's output. */
    cdvr_status (*encode_part)(const cdvr_codec_params *p, const size_t dims[3],
                               const uint8_t *const *frames, size_t count, size_t part,
                               size_t nparts, uint8_t *out, size_t out_cap, cdvr_error *err);

    /* Optional (may be NULL; plugin ABI 3): checks a payload of `bytes` for these parameters
     * and chunk dims before it reaches a device, against every rule the codec's device code
     * relies on, above all the bounds of every index that code computes from payload bytes.
     * CDVR_OK, or CDVR_ERR_CORRUPT naming the rule broken. cdvr_cl_decode (cdvr/device.h)
     * runs it on every uploaded chunk and refuses the chunk when it fails; a fetch-mode codec
     * should have one, since its fetch function reads the payload at every sample and cannot
     * report an error from there. Device code must still never read outside its buffers
     * whatever the payload holds (the check is the place for a clear error, not the only
     * guard). */
    cdvr_status (*check)(const cdvr_codec_params *p, const size_t dims[3],
                         const uint8_t *payload, size_t bytes, cdvr_error *err);

    /* Optional (may be NULL; plugin ABI 6): decode for chunks of one timestep, of the cells
     * the caller needs only, into a frame of either layout (CDVR_LAYOUT_LINEAR or
     * CDVR_LAYOUT_TILED, above; both must be supported). The frame is cut into cells of
     * 2^cell_log2 voxels per axis (ceil(dims / 2^cell_log2) per axis, x fastest, the last
     * ones cut by the frame's edge); every voxel of a cell with need[cell] != 0 gets exactly
     * the value `decode` gives it, and the other voxels of frame are either given that value
     * too or left as they were. Errors as decode's. The player uses it on the cl device for
     * the ray caster's composite renders, whose skip grid says which cells its samples read,
     * and hands the tiled frame to the device as the ray caster's own copy (player.c). */
    cdvr_status (*decode_cells)(const cdvr_codec_params *p, const size_t dims[3],
                                const uint8_t *in, size_t in_bytes, uint8_t *frame,
                                unsigned layout, const uint8_t *need, unsigned cell_log2,
                                cdvr_error *err);
    /* Plugin ABI 6: 1 when decode and decode_cells spread one chunk over all cores
     * themselves (zfp, hvq): the player then runs one such decode at a time rather than one
     * per unzip worker, which would only make the threads take turns on the cores. */
    int decodes_in_parallel;
};

/* ---- registry ------------------------------------------------------------------------------
 * One process-wide table of codecs (the codec registry context), guarded by a mutex: the
 * built-ins are present from the start; plugins add theirs. Registered tables must stay
 * valid until the process ends (plugins are never unloaded). */

/* The codec called name, or NULL. */
const cdvr_codec *cdvr_codec_find(const char *name);
/* The codec with this id, or NULL. */
const cdvr_codec *cdvr_codec_by_id(uint32_t id);
/* Number of registered codecs, and the i-th (registration order, built-ins first). */
size_t cdvr_codec_count(void);
const cdvr_codec *cdvr_codec_at(size_t i);
/* Adds a codec. Refused (CDVR_ERR_ARG) when the table lacks a required function, its name
 * is not 1..15 bytes of [a-z0-9_], or its name or id is already registered (the message
 * names the codec it clashes with). */
cdvr_status cdvr_codec_register(const cdvr_codec *codec, cdvr_error *err);

/* ---- helpers over a codec table ------------------------------------------------------------ */

/* Defaults, then each key/value pair in order (keys[i] = values[i]); the result is checked. */
cdvr_status cdvr_codec_params_parse(const cdvr_codec *codec, const char *const *keys,
                                    const char *const *values, size_t n, cdvr_codec_params *out,
                                    cdvr_error *err);
/* 1 if name is a valid codec name: 1..15 bytes of [a-z0-9_]. */
int cdvr_codec_name_valid(const char *name);
/* 1 if the codec accepts key. */
int cdvr_codec_has_param(const cdvr_codec *codec, const char *key);
/* Shape, after params_check; errors are prefixed with the codec's name. */
cdvr_status cdvr_codec_shape_of(const cdvr_codec *codec, const cdvr_codec_params *p,
                                const size_t dims[3], cdvr_codec_shape *out, cdvr_error *err);

/* Little-endian fields inside a parameter blob, for codec implementations (inline, so a
 * plugin needs no symbol from libcdvr for them). Fields past the blob read 0 and are not
 * written. */
static inline uint32_t cdvr_params_get_u32(const cdvr_codec_params *p, size_t offset)
{
    uint32_t v = 0;
    for (size_t i = 0; i < 4 && offset + i < CDVR_CODEC_PARAMS_MAX; i++)
        v |= (uint32_t)p->bytes[offset + i] << (8 * i);
    return v;
}

static inline void cdvr_params_set_u32(cdvr_codec_params *p, size_t offset, uint32_t v)
{
    for (size_t i = 0; i < 4 && offset + i < CDVR_CODEC_PARAMS_MAX; i++)
        p->bytes[offset + i] = (uint8_t)(v >> (8 * i));
}

static inline double cdvr_params_get_f64(const cdvr_codec_params *p, size_t offset)
{
    uint64_t v = 0;
    for (size_t i = 0; i < 8 && offset + i < CDVR_CODEC_PARAMS_MAX; i++)
        v |= (uint64_t)p->bytes[offset + i] << (8 * i);
    double d;
    memcpy(&d, &v, sizeof d);
    return d;
}

static inline void cdvr_params_set_f64(cdvr_codec_params *p, size_t offset, double d)
{
    uint64_t v;
    memcpy(&v, &d, sizeof v);
    for (size_t i = 0; i < 8 && offset + i < CDVR_CODEC_PARAMS_MAX; i++)
        p->bytes[offset + i] = (uint8_t)(v >> (8 * i));
}


/* ---- data shared by a variant's chunks (built-in codecs; no plugin ABI change) --------------
 * A variant may hold one blob every chunk decoder of it needs (hvqc's shared codebooks),
 * stored once per variant in the store and trained before the chunks are encoded. A codec
 * that uses one names it in its chunk parameter blob by its id (cdvr_shared_id). The blobs in
 * use live in the process-wide shared-blob table (a context like the registry, guarded by a
 * mutex, reference counted): the store adds its variants' blobs on open and encode and drops
 * them on close, and a decoder borrows the blob its parameters name while it decodes. */

/* FNV-1a 64 of the blob (never 0): the id a chunk's parameters name it by. */
uint64_t cdvr_shared_id(const uint8_t *blob, size_t bytes);
/* Adds a reference to the blob of id cdvr_shared_id(blob, bytes) (copied on the first). */
cdvr_status cdvr_shared_put(const uint8_t *blob, size_t bytes, uint64_t *id, cdvr_error *err);
/* Drops one reference (put); the last one frees the copy. Unknown ids are ignored. */
void cdvr_shared_drop(uint64_t id);
/* Borrows the blob of id: *blob and *bytes stay valid until cdvr_shared_drop (the borrow
 * holds a reference); CDVR_ERR_UNSUPPORTED naming the id when no open store holds it. */
cdvr_status cdvr_shared_borrow(uint64_t id, const uint8_t **blob, size_t *bytes,
                               cdvr_error *err);
/* 1 when the codec wants a shared blob trained for these parameters. */
int cdvr_codec_wants_shared(const cdvr_codec *codec, const cdvr_codec_params *p);
/* Trains the shared blob on nframes sample frames of the whole volume (dims) and records its
 * id in *p (the codec's own field). *blob is malloc'd. */
cdvr_status cdvr_codec_train_shared(const cdvr_codec *codec, cdvr_codec_params *p,
                                    const size_t dims[3], const uint8_t *const *frames,
                                    size_t nframes, uint8_t **blob, size_t *bytes,
                                    cdvr_error *err);

#endif
