/* cdvr/pvtc.h - the PVTC block codec family (DESIGN.md section 4.1).
 *
 * A chunk is one group of T timesteps (pack = time) or one timestep (pack = space) of u8
 * frames of dims X x Y x Z. It is cut into blocks of 4 x 4 x S positions; each block stores
 * 4 bytes of endpoints and 4*S bytes of 2-bit indices, struct-of-arrays: all endpoint words
 * of the chunk first (block order x fastest, then y, then z), then all index words.
 * Sizes: nblocks * (4 + 4S) bytes exactly.
 *
 *  pack = time:  blocks = ceil(X/4) x ceil(Y/4) x ceil(Z/S); channel c = timestep c of the
 *                group; frames beyond the series repeat the last timestep (encoder side).
 *  pack = space: packed position z holds slices T*z .. T*z+T-1 (channel c = slice T*z+c);
 *                blocks = ceil(X/4) x ceil(Y/4) x ceil(Z/(S*T)).
 *  Padding replicates the edge voxel; the decoder crops.
 *
 * Endpoints: T = 3 -> two little-endian RGB565 words U (bytes 0-1) and D (bytes 2-3),
 * channel 0 in bits 15..11, channel 1 in bits 10..5, channel 2 in bits 4..0, expanded by bit
 * replication (x<<3)|(x>>2) and (x<<2)|(x>>4). T = 2 -> bytes U0 U1 D0 D1.
 * Indices: position i = x + 4y + 16z inside the block, 2 bits at bit 2*(i%16) of little-endian
 * 32-bit word i/16. Channel c with a = U_c, b = D_c decodes palette[index] with
 * palette = {a, (2a+b+1)/3, (a+2b+1)/3, b} (integer division).
 */
#ifndef CDVR_PVTC_H
#define CDVR_PVTC_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/codec.h"
#include "cdvr/error.h"

typedef enum cdvr_pack { CDVR_PACK_TIME = 0, CDVR_PACK_SPACE = 1 } cdvr_pack;

typedef struct cdvr_pvtc_params {
    int S;          /* 1 or 4 */
    int T;          /* 2 or 3 */
    cdvr_pack pack;
} cdvr_pvtc_params;

typedef enum cdvr_pvtc_encoder {
    CDVR_ENCODER_LSQ = 0, /* default: principal axis + least-squares refinement, >= bbox */
    CDVR_ENCODER_BBOX = 1 /* per-channel max (U) and min (D), as in the papers */
} cdvr_pvtc_encoder;

typedef struct cdvr_pvtc_geometry {
    size_t blocks[3];    /* blocks along x, y, z */
    size_t nblocks;
    size_t chunk_bytes;  /* nblocks * (4 + 4S) */
    size_t frames;       /* u8 frames per chunk: T (time) or 1 (space) */
} cdvr_pvtc_geometry;

/* Validates params (S in {1,4}, T in {2,3}) and computes the chunk geometry for dims. */
cdvr_status cdvr_pvtc_geometry_get(const cdvr_pvtc_params *params, const size_t dims[3],
                                   cdvr_pvtc_geometry *geom, cdvr_error *err);

/* Encodes one chunk. frames: geom.frames pointers to u8 frames of dims (time packing: the
 * caller passes T pointers, repeating the last timestep past the end of the series).
 * out holds geom.chunk_bytes. */
cdvr_status cdvr_pvtc_encode_chunk(const cdvr_pvtc_params *params, cdvr_pvtc_encoder encoder,
                                   const size_t dims[3], const uint8_t *const *frames,
                                   uint8_t *out, cdvr_error *err);

/* Decodes one chunk of in_bytes (must equal geom.chunk_bytes) into nframes u8 frames of dims
 * (time packing: nframes <= T, the first nframes channels; space packing: nframes == 1). */
cdvr_status cdvr_pvtc_decode_chunk(const cdvr_pvtc_params *params, const size_t dims[3],
                                   const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                                   size_t nframes, cdvr_error *err);

/* The codec table's parameter blob (core/codec/pvtc/pvtc_codec.c documents its layout). */
void cdvr_pvtc_params_to_blob(const cdvr_pvtc_params *p, cdvr_pvtc_encoder encoder,
                              cdvr_codec_params *blob);
void cdvr_pvtc_params_from_blob(const cdvr_codec_params *blob, cdvr_pvtc_params *p,
                                cdvr_pvtc_encoder *encoder);

#endif
