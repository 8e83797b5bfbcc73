/* core/codec/pvtc/pvtc_internal.h - block-level helpers shared by core/codec/pvtc/pvtc.c (geometry, decoder, bbox
 * encoder, chunk gather/scatter) and core/codec/pvtc/pvtc_lsq.c (least-squares encoder). Not public. */
#ifndef CDVR_PVTC_INTERNAL_H
#define CDVR_PVTC_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/pvtc.h"

#define PVTC_MAX_POSITIONS 64 /* 4 x 4 x S with S <= 4 */
#define PVTC_MAX_CHANNELS 3

/* The voxels of one block, gathered with edge replication: v[i][c] is channel c at position
 * i = x + 4y + 16z. */
typedef struct pvtc_block {
    int T;         /* channels, 2 or 3 */
    int npos;      /* positions, 16 * S */
    uint8_t v[PVTC_MAX_POSITIONS][PVTC_MAX_CHANNELS];
} pvtc_block;

/* One encoded block before serialisation: quantised endpoints (5/6/5 bits for T = 3, 8 bits
 * for T = 2) and the 2-bit index of every position. */
typedef struct pvtc_code {
    int qa[PVTC_MAX_CHANNELS]; /* U, palette entry 0 */
    int qb[PVTC_MAX_CHANNELS]; /* D, palette entry 3 */
    uint8_t index[PVTC_MAX_POSITIONS];
} pvtc_code;

/* Bits of the quantised endpoint of channel c (5, 6, 5 for T = 3; 8 for T = 2). */
int pvtc_channel_bits(int T, int c);
/* Quantised value -> 8-bit value (bit replication; identity for 8 bits). */
int pvtc_expand(int bits, int q);
/* 8-bit value -> nearest quantised value: floor(x * max / 255 + 0.5). */
int pvtc_quantize(int bits, int x);
/* palette = {a, (2a+b+1)/3, (a+2b+1)/3, b} for 8-bit a, b. */
void pvtc_palette(int a, int b, int pal[4]);

/* Fills code->index with the nearest palette entry of every position (squared error summed
 * over channels, ties to the lower index) and returns the total squared error. */
uint32_t pvtc_assign_indices(const pvtc_block *blk, pvtc_code *code);
/* Total squared error of the decoded block against blk, for the indices in code. */
uint32_t pvtc_code_error(const pvtc_block *blk, const pvtc_code *code);

/* Encoders: fill code completely and return its squared error. */
uint32_t pvtc_encode_block_bbox(const pvtc_block *blk, pvtc_code *code);
uint32_t pvtc_encode_block_lsq(const pvtc_block *blk, pvtc_code *code);

/* Encodes blocks [first, first + count) (linear block index x fastest, then y, z) of a chunk
 * into their places in out (the whole chunk's buffer); cdvr_pvtc_encode_chunk is all of
 * them. */
cdvr_status pvtc_encode_blocks(const cdvr_pvtc_params *params, cdvr_pvtc_encoder encoder,
                               const size_t dims[3], const uint8_t *const *frames,
                               size_t first, size_t count, uint8_t *out, cdvr_error *err);

/* ---- decoder paths ------------------------------------------------------------------------
 * The reference decoder (one voxel at a time, pvtc.c) is the definition; the portable
 * (64-bit SWAR), SSSE3 and AVX2 paths must be bit-exact with it. AUTO picks the fastest
 * available. */
typedef enum pvtc_decode_path {
    PVTC_DECODE_AUTO = 0,
    PVTC_DECODE_REFERENCE,
    PVTC_DECODE_PORTABLE,
    PVTC_DECODE_SSSE3,
    PVTC_DECODE_AVX2
} pvtc_decode_path;

/* cdvr_pvtc_decode_chunk with a chosen path; CDVR_ERR_UNSUPPORTED if this CPU or build lacks
 * it. */
cdvr_status pvtc_decode_chunk_path(const cdvr_pvtc_params *params, const size_t dims[3],
                                   const uint8_t *in, size_t in_bytes, uint8_t *const *frames,
                                   size_t nframes, pvtc_decode_path path, cdvr_error *err);

/* One row of blocks (fixed y and z block coordinates) whose first nblocks blocks lie wholly
 * inside the volume. */
typedef struct pvtc_row_job {
    const uint8_t *endpoints; /* 4 bytes per block, block 0 of the row first */
    const uint8_t *words;     /* 4 * S bytes of index words per block */
    uint8_t *dst[4][PVTC_MAX_CHANNELS]; /* [zi][c]: voxel x = 0 of the block row's first row */
    size_t stride;            /* X: bytes from one voxel row to the next */
    size_t nblocks;
    int S, T, nch;            /* nch: channels to write (time packing may want fewer than T) */
} pvtc_row_job;

int pvtc_ssse3_available(void);
/* Decodes the leading blocks of the row in groups of four; returns how many it decoded. */
size_t pvtc_decode_row_ssse3(const pvtc_row_job *job);
int pvtc_avx2_available(void);
/* Decodes the leading blocks of the row in groups of eight; returns how many it decoded. */
size_t pvtc_decode_row_avx2(const pvtc_row_job *job);

#endif
