/* cdvr/store.h - the .cdv store (DESIGN.md section 5) and the encode driver.
 *
 * A store holds one u8 series (dims, index-to-world matrix, timesteps, quantisation window)
 * in one or more variants. Every timestep may be split into bricks (a bx x by x bz grid with
 * the one-voxel overlap trilinear sampling needs; cdvr_store_brick_box). A variant is a
 * sequence of chunk groups in time order; a group covers timesteps [t0, t0+count) and holds
 * one chunk per brick. Each chunk records its own codec id and parameter blob (so a
 * schedule may change the parameters per group; cdvr/codec.h), its file offset, stored size,
 * payload size (after undoing stage 2), CRC-32C of the stored bytes, its stage-2 codec and
 * the range of its decoded values. Readers check bounds and CRC before decoding; every error names
 * the file, the variant, the chunk and the reason. A store written with a codec that is not
 * loaded (a plugin) opens and lists it; reading that variant fails with "codec 'zfp' is not
 * loaded (load its plugin: cdvr.plugin.load)".
 *
 * Playback uses the three steps separately (b1, b1', decode), which are safe to call from
 * different threads on one open store:
 *   cdvr_store_read_chunk   -> stored bytes (pread + CRC check)            (b1)
 *   cdvr_store_unpack_chunk -> codec payload (undoes the chunk's stage 2)   (b1')
 *   cdvr_store_decode_chunk -> u8 frames of the chunk's brick (C decoder)  (b3 on the CPU)
 */
#ifndef CDVR_STORE_H
#define CDVR_STORE_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/bricks.h" /* the brick and range-brick geometry */
#include "cdvr/crc32c.h" /* the chunk checksums */
#include "cdvr/codec.h"
#include "cdvr/error.h"
#include "cdvr/volume.h"

#define CDVR_NAME_MAX CDVR_VARIANT_NAME_MAX

/* Stage 2 (DESIGN.md 4.2) over each chunk's codec payload, on the CPU at playback.
 *   NONE  stored as is.
 *   LZO   LZO1X-1 (seed 001; stores of the seed keep reading bit-identically).
 *   LZ4   LZ4 (LZ4_compress_default), the fastest to unpack.
 *   ZSTD  zstd level 3, the smallest.
 *   AUTO  per chunk, the one of NONE, LZO, LZ4, ZSTD with the smallest modelled time per chunk
 *         in the pipelined player, which reads one chunk while it unpacks another on all
 *         cores: NONE costs payload bytes / R (the player keeps the stored bytes as the
 *         payload), a codec c max(stored bytes / R, 2 * payload bytes / (U_c * n)), where
 *         U_c is this machine's single-thread unpack rate of c, n its online cores, and the 2
 *         keeps stage 2 to at most half of the machine, the rest being the render's. R is
 *         stage2_read_mbps, by default the rate the player will read at
 *         (cdvr_store_modelled_read_mbps): the page cache's where the series (its u8 voxels)
 *         fits in half the memory this process may fill (cdvr_usable_memory_bytes: the
 *         machine's or its control group's limit), as it is read from there after the first pass,
 *         else the disk's, as a loop larger than the page cache finds no chunk still there;
 *         both measured once per filesystem (cdvr_store_read_rates), CDVR_STAGE2_READ_MBPS
 *         where they cannot be measured; the R used is recorded
 *         (cdvr_variant_info.stage2_read_mbps). The unpack rates are measured once per
 *         machine on a fixed calibration payload and remembered in the cache
 *         (cdvr_s2_unpack_rates, core/codec/stage2/stage2.h; cdvr/cache.h), so the choice
 *         follows the chunk's packed sizes and these rates, not the load at encode time: two
 *         encodes on one machine write the same store. A chunk of more than 4 segments is
 *         modelled from every 4th segment. The choice is recorded per chunk
 *         (cdvr_chunk_info.stage2). The Lua layer's default (cdvr.encode).
 * A chunk's stage 2 is kept only where it pays: for LZO, LZ4 and ZSTD when it saves at least
 * lzo_min_saving of the chunk (AUTO: where the model says so). LZ4 and ZSTD chunks, and LZO
 * ones larger than one segment, are cut into segments of stage2_segment payload bytes
 * (default CDVR_STAGE2_SEGMENT), packed independently, so cdvr_store_unpack_chunk unpacks one
 * chunk on all cores (byte layout: core/codec/stage2/stage2.h, store.c). */
typedef enum cdvr_stage2 {
    CDVR_STAGE2_NONE = 0,
    CDVR_STAGE2_LZO = 1,
    CDVR_STAGE2_LZ4 = 2,
    CDVR_STAGE2_ZSTD = 3,
    CDVR_STAGE2_AUTO = 4 /* a variant's setting only; a chunk records what AUTO chose */
} cdvr_stage2;

#define CDVR_STAGE2_READ_MBPS 500.0          /* AUTO's disk read rate where none is measured,
                                                MB/s (10^6 bytes) */
#define CDVR_STAGE2_SEGMENT (1u << 20)       /* payload bytes per segment */
#define CDVR_STAGE2_SEGMENT_MIN 64u
#define CDVR_STAGE2_SEGMENT_MAX (1u << 30)

/* The codec a variant uses when none is named. */
#define CDVR_CODEC_DEFAULT "pvtc"

/* What to encode, per variant. */
typedef struct cdvr_variant_spec {
    char name[CDVR_NAME_MAX];      /* "" -> the codec's default name ("S4T3", "zfp2", "raw") */
    const cdvr_codec *codec;
    cdvr_codec_params params;      /* default parameters (a schedule may change them per group) */
    cdvr_stage2 stage2;
    double lzo_min_saving;         /* stage 2 kept only if it saves at least this fraction of
                                      the chunk (default CDVR_LZO_MIN_SAVING); <0 -> default */
    double stage2_read_mbps;       /* AUTO's read rate in MB/s; 0 -> the store's filesystem's
                                      (cdvr_store_modelled_read_mbps; non-AUTO variants
                                      record CDVR_STAGE2_READ_MBPS) */
    size_t stage2_segment;         /* segment bytes; 0 -> CDVR_STAGE2_SEGMENT */
} cdvr_variant_spec;

#define CDVR_LZO_MIN_SAVING 0.10
#define CDVR_STORE_MAX_BRICKS 4096 /* bricks per timestep */
#define CDVR_STORE_MAX_LEVELS 16   /* resolution levels of a multi-resolution store */

/* Per-group schedule: called once per chunk group of variant `variant` (from 0) whose first
 * timestep is t0 (from 0), with *params preset to the variant's parameters; may change them
 * (same codec). Nonzero return = error (err filled). */
typedef cdvr_status (*cdvr_schedule_fn)(void *ud, size_t variant, size_t t0,
                                        cdvr_codec_params *params, cdvr_error *err);
/* Progress: done out of total chunks. */
typedef void (*cdvr_progress_fn)(void *ud, size_t done, size_t total);
/* Frame source: writes the dims-product u8 voxels of timestep t (from 0) into out. Called in
 * increasing t order, each t at most once per encode (the encoder keeps what it still needs). */
typedef cdvr_status (*cdvr_source_frame_fn)(void *ud, size_t t, uint8_t *out, cdvr_error *err);

#define CDVR_ENCODE_MAX_THREADS 256

typedef struct cdvr_encode_opts {
    const cdvr_variant_spec *variants;
    size_t nvariants;
    cdvr_schedule_fn schedule;     /* may be NULL */
    void *schedule_ud;
    cdvr_progress_fn progress;     /* may be NULL */
    void *progress_ud;
    double qlo, qhi;               /* quantisation window recorded in the header */
    cdvr_type source_type;         /* type before quantisation, recorded */
    size_t bricks[3];              /* brick grid; 0 -> 1 */
    int threads;                   /* encode threads: 0 one per online core, 1 only the calling
                                      thread; the output is the same byte for byte (but for
                                      stage 2 AUTO, whose choices follow measured times) */
    int no_range_tables;           /* 1: record no range tables (smaller store; playback then
                                      computes each frame's brick ranges itself) */
    unsigned range_shift;          /* range bricks of 2^range_shift voxels in the tables,
                                      CDVR_RANGE_SHIFT .. CDVR_RANGE_SHIFT_MAX; 0 ->
                                      CDVR_RANGE_SHIFT_DEFAULT (8^3) */
    size_t levels;                 /* resolution levels (0 or 1: level 0 only; 2 ..
                                      CDVR_STORE_MAX_LEVELS: a multi-resolution store, below) */
    const cdvr_variant_spec *const *level_variants; /* NULL, or levels - 1 entries: the
                                      variants of level l at [l - 1] (nvariants each, matched
                                      to `variants` by position; names are level 0's), NULL
                                      entries: `variants` again */
} cdvr_encode_opts;

/* A series to encode, read one timestep at a time (out of core). */
typedef struct cdvr_encode_source {
    size_t dims[3];
    size_t timesteps;
    double spacing[3], origin[3], direction[9];  /* as cdvr_volume */
    cdvr_source_frame_fn frame;
    void *frame_ud;
} cdvr_encode_source;

typedef struct cdvr_store cdvr_store;

#define CDVR_RANGES_LZO 1    /* cdvr_chunk_info.ranges_stage2: the table is LZO1X of it */
#define CDVR_RANGES_PACKED 2 /* the table is cdvr_range_pack of it (bricks.h) */

typedef struct cdvr_chunk_info {
    size_t t0, count;              /* timesteps covered (from 0) */
    size_t brick;                  /* brick index (from 0, x fastest) */
    uint32_t codec_id;
    const cdvr_codec *codec;       /* NULL when that codec is not loaded */
    cdvr_codec_params params;      /* this chunk's parameters */
    uint64_t offset;               /* file offset of the stored bytes */
    uint64_t stored_bytes;         /* bytes on disk */
    uint64_t payload_bytes;        /* bytes after undoing stage 2 */
    uint32_t crc32c;               /* of the stored bytes */
    int stage2;                    /* its stage 2: 0 none, 1 LZO, 2 LZ4, 3 zstd (cdvr_stage2) */
    int stage2_segmented;          /* 1: the stored bytes are segments behind a table */
    uint8_t value_min, value_max;  /* range of the decoded voxels of the chunk's timesteps */
    /* Range table (value ranges per range brick, see below), stored after the chunk's bytes;
     * ranges_shift 0: the chunk has none (version 1 stores and older version 2 ones). */
    unsigned ranges_shift;         /* range bricks of 2^shift voxels */
    int ranges_stage2;             /* 0 stored as is, CDVR_RANGES_LZO LZO1X of the table,
                                      CDVR_RANGES_PACKED cdvr_range_pack (bricks.h) */
    uint32_t ranges_crc32c;        /* of the stored table bytes */
    uint64_t ranges_offset, ranges_stored_bytes;
} cdvr_chunk_info;

typedef struct cdvr_variant_info {
    char name[CDVR_NAME_MAX];
    uint32_t codec_id;
    const cdvr_codec *codec;       /* NULL when not loaded */
    char codec_name[CDVR_CODEC_NAME_MAX]; /* as recorded ("raw", "pvtc", "zfp", ...) */
    cdvr_codec_params params;      /* parameters given at encode time (first group's) */
    cdvr_stage2 stage2;
    size_t nchunks;                /* groups x bricks */
    size_t ngroups;
    uint64_t bytes;                /* stored bytes of all chunks (and the shared blob) */
    uint64_t payload_bytes;        /* bytes before stage 2 */
    uint64_t ranges_bytes;         /* stored bytes of the chunks' range tables */
    double psnr, maxerr;           /* volume PSNR / max error measured at encode time */
    double lzo_min_saving;
    double stage2_read_mbps;       /* AUTO's read rate at encode time (0: not recorded) */
    size_t stage2_segment;         /* segment bytes at encode time (0: not recorded) */
    size_t stage2_chunks[4];       /* chunks stored with stage 2 none, LZO, LZ4, zstd */
    /* The blob the variant's chunks share (cdvr/codec.h; hvqc shared=1), 0 bytes if none;
     * counted in `bytes`. shared_id: its id in the shared-blob table while the store is open. */
    uint64_t shared_offset, shared_bytes, shared_id;
} cdvr_variant_info;

typedef struct cdvr_store_info {
    unsigned version;              /* format version of the file (1 or 2) */
    size_t dims[3];
    size_t timesteps;
    double spacing[3], origin[3], direction[9];
    double qlo, qhi;               /* value window: u8 0..255 stands for [qlo, qhi] */
    cdvr_type source_type;
    size_t nvariants;
    size_t bricks[3], nbricks;     /* brick grid (1 1 1 for unbricked stores) */
    size_t nlevels;                /* resolution levels (1: level 0 only) */
    uint64_t raw_bytes;            /* dims product * timesteps (u8) */
    uint64_t file_bytes;
} cdvr_store_info;

/* Multi-resolution stores (DESIGN.md section 15; core/store/levels.c). With opts->levels =
 * N >= 2 the store holds the series at level 0 and at N-1 coarser levels. Level l has dims
 * N_l = ceil((N_{l-1} - 1) / 2) + 1 per axis (1 stays 1): its voxel i sits where voxel 2i of
 * level l-1 sits, so it has the same origin and direction and twice the spacing. Filter: the
 * separable tent (1 2 1)/4 per axis over voxels 2i-1, 2i, 2i+1 of level l-1 (indices clamped
 * to the level's range), i.e. v = (sum of w_x w_y w_z u, w in {1,2,1}, + 32) >> 6, exact in
 * integers (round half up). Each level is a complete store (the same variants by position,
 * each with its own codec and parameters: level_variants; the same brick counts, each axis
 * capped at the level's cells, so the one-voxel overlap holds at every level), embedded in
 * the file after level 0 (format: store.c, levels.c); readers see level 0 as the store and
 * reach level l through cdvr_store_level. Encoding reads the source once per level plus once
 * to measure each level's error: the source's frame function is called in increasing t
 * order within each pass (levels + 1 passes), holding one frame per level at a time. */

/* Dims of level `level` (0: dims) under the rule above. */
void cdvr_level_dims(const size_t dims[3], size_t level, size_t out[3]);
/* Level l (0 .. info.nlevels - 1) of a store: st itself for 0, else a store of the level's
 * dims, spacing, bricks and variants (same names, timesteps and window), read as any store;
 * NULL out of range. It lives as long as st. */
const cdvr_store *cdvr_store_level(const cdvr_store *st, size_t level);
/* Error of variant v at level l against the series at level 0 as encoded (the source): the
 * level's decoded frames upsampled to level 0 by trilinear interpolation (level-0 voxel x
 * read at x / 2^l), PSNR (peak 255) and max error over all voxels and timesteps; for level 0
 * the variant's own figures. Bytes: the level's stored bytes of variant v. */
void cdvr_store_level_error(const cdvr_store *st, size_t level, size_t v, double *psnr,
                            double *maxerr);
/* Level l as a new, independent store object (closed by cdvr_store_close; level 0: the
 * store with its levels again). CDVR_ERR_ARG for a level the store does not have. */
cdvr_status cdvr_store_open_level(const cdvr_store *st, size_t level, cdvr_store **out,
                                  cdvr_error *err);

/* Encodes a u8 volume/series into a new store at path (temporary name, fsync, rename). The
 * volume's spacing, origin and direction are recorded. */
cdvr_status cdvr_store_encode(const cdvr_volume *u8, const cdvr_encode_opts *opts,
                              const char *path, cdvr_error *err);
/* The same from a frame source: only the frames of the chunk groups in flight are held. */
cdvr_status cdvr_store_encode_source(const cdvr_encode_source *src,
                                     const cdvr_encode_opts *opts, const char *path,
                                     cdvr_error *err);

cdvr_status cdvr_store_open(const char *path, cdvr_store **out, cdvr_error *err);
void cdvr_store_close(cdvr_store *st);
const char *cdvr_store_path(const cdvr_store *st);
const cdvr_store_info *cdvr_store_get_info(const cdvr_store *st);
/* v from 0; NULL if out of range. */
const cdvr_variant_info *cdvr_store_variant(const cdvr_store *st, size_t v);
/* Index of the variant called name, or -1. */
int cdvr_store_find_variant(const cdvr_store *st, const char *name);
/* The variant of best quality (from 0), the default of the player and the window and the
 * first in share/lua/cdvr/policy.lua's quality order: a raw variant (lossless) first, then
 * the highest PSNR recorded at encode time (+inf for a lossless one), ties broken by more
 * stored bytes, then by the lower index. 0 for a store with one variant. */
int cdvr_store_best_variant(const cdvr_store *st);
/* Chunk c (from 0) of variant v: chunk c belongs to group c / nbricks and brick c % nbricks. */
const cdvr_chunk_info *cdvr_store_chunk(const cdvr_store *st, size_t v, size_t c);
/* Chunk of variant v holding timestep t (from 0) in brick 0; (size_t)-1 if out of range. */
size_t cdvr_store_chunk_for_time(const cdvr_store *st, size_t v, size_t t);
/* Chunk of variant v holding timestep t in brick b; (size_t)-1 if out of range. */
size_t cdvr_store_chunk_for(const cdvr_store *st, size_t v, size_t t, size_t b);
/* Voxel box of brick b of the store's grid (cdvr_brick_box, cdvr/bricks.h); the whole volume
 * when the grid is invalid. */
void cdvr_store_brick_box(const cdvr_store_info *info, size_t b, size_t lo[3], size_t dims[3]);
/* The voxels brick b of the store's grid owns (cdvr_brick_owned). */
void cdvr_store_brick_owned(const cdvr_store_info *info, size_t b, size_t lo[3],
                            size_t dims[3]);
/* The codec of variant v, or CDVR_ERR_UNSUPPORTED "codec 'zfp' is not loaded (load its
 * plugin: cdvr.plugin.load)" naming the file and variant. */
cdvr_status cdvr_store_variant_codec(const cdvr_store *st, size_t v, const cdvr_codec **out,
                                     cdvr_error *err);

/* b1: reads chunk c of variant v into buf (stored_bytes) and checks its CRC-32C. */
cdvr_status cdvr_store_read_chunk(const cdvr_store *st, size_t v, size_t c, uint8_t *buf,
                                  cdvr_error *err);
/* Drops the chunk's pages from the page cache (posix_fadvise DONTNEED), for cold reads. */
void cdvr_store_drop_cache(const cdvr_store *st, size_t v, size_t c);
/* b1': undoes stage 2: out holds payload_bytes. Copies if the chunk has no stage 2. A
 * segmented chunk is unpacked on one thread per online core (at most one per segment). */
cdvr_status cdvr_store_unpack_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *stored, uint8_t *out, cdvr_error *err);
/* The same on at most `threads` threads (0: one per online core); the same bytes for any. */
cdvr_status cdvr_store_unpack_chunk_threads(const cdvr_store *st, size_t v, size_t c,
                                            const uint8_t *stored, uint8_t *out, int threads,
                                            cdvr_error *err);
/* cdvr_store_unpack_chunk, adding to *cpu_ms the CPU time it took on all its threads
 * (cdvr_thread_cpu_ms: the work itself, without the waits a low-priority thread has). */
cdvr_status cdvr_store_unpack_chunk_cpu(const cdvr_store *st, size_t v, size_t c,
                                        const uint8_t *stored, uint8_t *out, double *cpu_ms,
                                        cdvr_error *err);
/* "none", "lzo", "lz4", "zstd", "auto" for a cdvr_stage2; "?" otherwise. */
const char *cdvr_stage2_name(int stage2);
/* The single-thread unpack rates AUTO models this machine with (payload MB/s; measured once
 * on a fixed calibration payload and remembered, see AUTO above), by cdvr_stage2: mbps[LZO],
 * mbps[LZ4], mbps[ZSTD]; mbps[NONE] and mbps[AUTO] are 0. *from_cache: 1 when remembered. */
cdvr_status cdvr_stage2_unpack_rates(double mbps[5], int *from_cache, cdvr_error *err);
/* The rates at which the filesystem holding path (a store's path: its directory is measured)
 * reads, MB/s (10^6 bytes): disk_mbps for bytes not in the page cache, cache_mbps for bytes
 * in it. A 32 MiB test file is written and synced there (unlinked at once: nothing is left),
 * then read with 4 MiB preads three times after dropping it from the page cache and three
 * times while cached; each rate is the median pass rounded to two significant digits, in
 * [1, 1e7]. Measured once per filesystem (device, id and size) and remembered in the cache
 * (cdvr/cache.h; from_cache 1); about 0.2 s on an SSD. Where files live in memory (tmpfs)
 * both are the memory's rate. Fails (CDVR_ERR_IO naming the directory and the reason, the
 * rates 0) where the test file cannot be written. */
typedef struct cdvr_read_rates {
    double disk_mbps, cache_mbps;
    int from_cache;
} cdvr_read_rates;

cdvr_status cdvr_store_read_rates(const char *path, cdvr_read_rates *out, cdvr_error *err);

/* The read rate AUTO models for a series of raw_bytes u8 voxels (all timesteps) on a machine
 * of memory_bytes: rates->cache_mbps when raw_bytes <= memory_bytes / 2, else disk_mbps. */
double cdvr_store_modelled_read_mbps(const cdvr_read_rates *rates, uint64_t raw_bytes,
                                     uint64_t memory_bytes);
/* b1 + b1' in one call: a new malloc'ed buffer (*payload, freed by the caller) holding chunk c's
 * payload_bytes after the CRC check and stage 2. */
cdvr_status cdvr_store_load_payload(const cdvr_store *st, size_t v, size_t c, uint8_t **payload,
                                    cdvr_error *err);
/* cdvr_store_load_payload into buffers the caller keeps between calls (cdvr_grow_large of
 * cdvr/memory.h, contents not kept: *payload of *payload_cap bytes, and *stored for a chunk
 * with stage 2): a new buffer of a large chunk costs a page fault per page on first touch, on
 * every call. */
cdvr_status cdvr_store_load_payload_into(const cdvr_store *st, size_t v, size_t c,
                                         uint8_t **payload, size_t *payload_cap,
                                         uint8_t **stored, size_t *stored_cap, cdvr_error *err);
/* Decodes a chunk payload into its `count` u8 frames of the chunk's brick dims (frames[i] for
 * t0+i) with the chunk's codec. */
cdvr_status cdvr_store_decode_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *payload, uint8_t *const *frames,
                                    cdvr_error *err);
/* Whether chunk c can be decoded by cells (a codec with decode_cells, one timestep). */
int cdvr_store_chunk_decodes_cells(const cdvr_store *st, size_t v, size_t c);
/* For such a chunk, the voxels of the cells of 2^cell_log2 voxels (ceil(brick dims /
 * 2^cell_log2) per axis, x fastest) with need[cell] != 0 into frame in layout (codec.h,
 * decode_cells): the other voxels of frame may keep what they held. CDVR_ERR_UNSUPPORTED for
 * another chunk. */
cdvr_status cdvr_store_decode_chunk_cells(const cdvr_store *st, size_t v, size_t c,
                                          const uint8_t *payload, uint8_t *frame,
                                          unsigned layout, const uint8_t *need,
                                          unsigned cell_log2, cdvr_error *err);
/* Convenience: read + unpack + decode timestep t of variant v (all bricks, assembled) into a
 * new u8 volume carrying the store's spacing, origin, direction and value window. */
cdvr_status cdvr_store_decode(const cdvr_store *st, size_t v, size_t t, cdvr_volume **out,
                              cdvr_error *err);

/* Reads and decodes only brick b's chunk of timestep t of variant v into a new u8 volume of
 * the brick's dims (cdvr_store_brick_box), placed in the world where the brick lies: its
 * origin is the store's origin + D * (lo * spacing), spacing and direction the store's. Its
 * boundary voxels are the brick's own decoded values (an assembled volume takes a shared
 * voxel from the lower brick). */
cdvr_status cdvr_store_decode_brick(const cdvr_store *st, size_t v, size_t t, size_t b,
                                    cdvr_volume **out, cdvr_error *err);

/* Bytes of chunk c's range table (count frames of its window), 0 when it has none. */
size_t cdvr_store_ranges_bytes(const cdvr_store *st, size_t v, size_t c);
/* Reads chunk c's range table into out (cdvr_store_ranges_bytes): pread, CRC-32C check, LZO
 * if flagged. CDVR_ERR_ARG when the chunk has none. */
cdvr_status cdvr_store_read_ranges(const cdvr_store *st, size_t v, size_t c, uint8_t *out,
                                   cdvr_error *err);


#endif
