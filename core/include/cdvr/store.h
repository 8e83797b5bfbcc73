/* cdvr/store.h - the .cdv store (DESIGN.md section 5) and the encode driver.
 *
 * A store holds one u8 series (dims, spacing, timesteps, quantisation window) in one or more
 * variants. A variant is a sequence of chunks; each chunk covers timesteps [t0, t0+count)
 * and records its own codec parameters (so a schedule may change them per group), its file
 * offset, stored size, payload size (after undoing stage 2), CRC-32C of the stored bytes and
 * the stage-2 flag. Readers check bounds and CRC before decoding; every error names the
 * file, the variant, the chunk and the reason.
 *
 * Playback uses the three steps separately (b1, b1', decode), which are safe to call from
 * different threads on one open store:
 *   cdvr_store_read_chunk   -> stored bytes (pread + CRC check)          (b1)
 *   cdvr_store_unpack_chunk -> codec payload (LZO1X decompress if flagged) (b1')
 *   cdvr_store_decode_chunk -> u8 frames (C decoder)                     (b3 on the CPU)
 */
#ifndef CDVR_STORE_H
#define CDVR_STORE_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/pvtc.h"
#include "cdvr/volume.h"

#define CDVR_NAME_MAX 32

typedef enum cdvr_codec_id { CDVR_CODEC_RAW = 0, CDVR_CODEC_PVTC = 1, CDVR_CODEC_PLUGIN = 2 } cdvr_codec_id;
typedef enum cdvr_stage2 { CDVR_STAGE2_NONE = 0, CDVR_STAGE2_LZO = 1 } cdvr_stage2;

/* What to encode, per variant. */
typedef struct cdvr_variant_spec {
    char name[CDVR_NAME_MAX];      /* "" -> default name: "S4T3", "S1T2s", "raw" */
    cdvr_codec_id codec;
    cdvr_pvtc_params pvtc;         /* default parameters (a schedule may override per group) */
    cdvr_pvtc_encoder encoder;
    cdvr_stage2 stage2;
    double lzo_min_saving;         /* stage 2 kept only if it saves at least this fraction of
                                      the chunk (default CDVR_LZO_MIN_SAVING); <0 -> default */
} cdvr_variant_spec;

#define CDVR_LZO_MIN_SAVING 0.10

/* Per-group schedule: called at the start of each chunk of variant `variant` (from 0) whose
 * first timestep is t0 (from 0); may change *params (S, T, pack). Nonzero return = error
 * (err filled). */
typedef cdvr_status (*cdvr_schedule_fn)(void *ud, size_t variant, size_t t0,
                                        cdvr_pvtc_params *params, cdvr_error *err);
/* Progress: done out of total chunks. */
typedef void (*cdvr_progress_fn)(void *ud, size_t done, size_t total);

typedef struct cdvr_encode_opts {
    const cdvr_variant_spec *variants;
    size_t nvariants;
    cdvr_schedule_fn schedule;     /* may be NULL */
    void *schedule_ud;
    cdvr_progress_fn progress;     /* may be NULL */
    void *progress_ud;
    double qlo, qhi;               /* quantisation window recorded in the header */
    cdvr_type source_type;         /* type before quantisation, recorded */
} cdvr_encode_opts;

typedef struct cdvr_store cdvr_store;

typedef struct cdvr_chunk_info {
    size_t t0, count;              /* timesteps covered (from 0) */
    cdvr_pvtc_params pvtc;         /* parameters of this chunk (pvtc codec) */
    uint64_t offset;               /* file offset of the stored bytes */
    uint64_t stored_bytes;         /* bytes on disk */
    uint64_t payload_bytes;        /* bytes after undoing stage 2 */
    uint32_t crc32c;               /* of the stored bytes */
    int stage2;                    /* 1 if LZO applies to this chunk */
} cdvr_chunk_info;

typedef struct cdvr_variant_info {
    char name[CDVR_NAME_MAX];
    cdvr_codec_id codec;
    char codec_name[CDVR_NAME_MAX];/* "raw", "pvtc", or the plugin's name */
    cdvr_pvtc_params pvtc;         /* parameters of the first chunk */
    cdvr_pvtc_encoder encoder;
    cdvr_stage2 stage2;
    size_t nchunks;
    uint64_t bytes;                /* stored bytes of all chunks */
    uint64_t payload_bytes;        /* bytes before stage 2 */
    double psnr, maxerr;           /* volume PSNR / max error measured at encode time */
} cdvr_variant_info;

typedef struct cdvr_store_info {
    size_t dims[3];
    size_t timesteps;
    double spacing[3], origin[3];
    double qlo, qhi;
    cdvr_type source_type;
    size_t nvariants;
    uint64_t raw_bytes;            /* dims product * timesteps (u8) */
    uint64_t file_bytes;
} cdvr_store_info;

/* Encodes a u8 volume/series into a new store at path (temporary name, fsync, rename). */
cdvr_status cdvr_store_encode(const cdvr_volume *u8, const cdvr_encode_opts *opts,
                              const char *path, cdvr_error *err);

cdvr_status cdvr_store_open(const char *path, cdvr_store **out, cdvr_error *err);
void cdvr_store_close(cdvr_store *st);
const char *cdvr_store_path(const cdvr_store *st);
const cdvr_store_info *cdvr_store_get_info(const cdvr_store *st);
/* v from 0; NULL if out of range. */
const cdvr_variant_info *cdvr_store_variant(const cdvr_store *st, size_t v);
/* Index of the variant called name, or -1. */
int cdvr_store_find_variant(const cdvr_store *st, const char *name);
const cdvr_chunk_info *cdvr_store_chunk(const cdvr_store *st, size_t v, size_t c);
/* Chunk of variant v holding timestep t (from 0); (size_t)-1 if out of range. */
size_t cdvr_store_chunk_for_time(const cdvr_store *st, size_t v, size_t t);

/* b1: reads chunk c of variant v into buf (stored_bytes) and checks its CRC-32C. */
cdvr_status cdvr_store_read_chunk(const cdvr_store *st, size_t v, size_t c, uint8_t *buf,
                                  cdvr_error *err);
/* Drops the chunk's pages from the page cache (posix_fadvise DONTNEED), for cold reads. */
void cdvr_store_drop_cache(const cdvr_store *st, size_t v, size_t c);
/* b1': undoes stage 2: out holds payload_bytes. Copies if the chunk has no stage 2. */
cdvr_status cdvr_store_unpack_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *stored, uint8_t *out, cdvr_error *err);
/* b1 + b1' in one call: a new malloc'ed buffer (*payload, freed by the caller) holding chunk c's
 * payload_bytes after the CRC check and stage 2. */
cdvr_status cdvr_store_load_payload(const cdvr_store *st, size_t v, size_t c, uint8_t **payload,
                                    cdvr_error *err);
/* Decodes a chunk payload into its `count` u8 frames of dims (frames[i] for t0+i). */
cdvr_status cdvr_store_decode_chunk(const cdvr_store *st, size_t v, size_t c,
                                    const uint8_t *payload, uint8_t *const *frames,
                                    cdvr_error *err);
/* Convenience: read + unpack + decode timestep t of variant v into a new u8 volume. */
cdvr_status cdvr_store_decode(const cdvr_store *st, size_t v, size_t t, cdvr_volume **out,
                              cdvr_error *err);

/* CRC-32C (Castagnoli), initial value 0 for a fresh CRC: crc = cdvr_crc32c(0, buf, n). */
uint32_t cdvr_crc32c(uint32_t crc, const void *buf, size_t n);

#endif
