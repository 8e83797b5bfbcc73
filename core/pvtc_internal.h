/* core/pvtc_internal.h - block-level helpers shared by core/pvtc.c (geometry, decoder, bbox
 * encoder, chunk gather/scatter) and core/pvtc_lsq.c (least-squares encoder). Not public. */
#ifndef CDVR_PVTC_INTERNAL_H
#define CDVR_PVTC_INTERNAL_H

#include <stdint.h>

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

#endif
