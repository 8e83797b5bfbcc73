/* cdvr/hvq.h - the "hvq" codec (id CDVR_CODEC_ID_HVQ): flag-based classified hierarchical
 * vector quantisation with perfect spatial hashing, decoded per sample inside the ray caster
 * (seed 004, DESIGN.md section 4.3). The codec table (cdvr_codec_find("hvq")) is the way the
 * rest of cdvr uses it; this header documents the format and gives the functions behind the
 * table, for tests and benchmarks.
 *
 * ---- Encoding ------------------------------------------------------------------------------
 * One u8 frame per chunk (shape.timesteps = 1; payload size is data dependent).
 *  1. The frame (X, Y, Z) is padded to multiples of 4 by edge replication: voxel (x, y, z) of
 *     the padded frame is v(min(x, X-1), min(y, Y-1), min(z, Z-1)). Blocks of 4x4x4, numbered
 *     x fastest: block (bx, by, bz) is bx + NBX*(by + NBY*bz), NBX = ceil(X/4) etc.
 *  2. Block mean: m = (sum of the 64 voxels + 32) >> 6 (u8).
 *  3. Gradient (seed eq. 11): G(x,y,z) = |f(x+1,y,z) - f| + |f(x,y+1,z) - f| + |f(x,y,z+1) - f|
 *     on the padded frame with coordinates clamped to it (so 0 past its edge); block sum SG of
 *     G over its 64 voxels; the block average (eq. 12) is SG/64. The block is a zero block iff
 *     SG < 64 * grad (exact: SG is an integer, 64*grad an exact double). A zero block decodes
 *     to its mean.
 *  4. Other blocks: residual r_i = v_i - m, voxel i = x + 4y + 16z inside the block.
 *     Level 1: the eight 2x2x2 sums S_j = sum of r over sub-block j = (x>>1) + 2(y>>1) + 4(z>>1)
 *     (8-d vector, eight times the sub-block averages). Codebook 1 (at most k1 entries of 8
 *     int16 values c1) is trained on these vectors and each block takes the entry minimising
 *     sum_j (S_j - 8 c1_j)^2 (ties: the lowest index). Level 2: e_i = r_i - c1[i1]_{j(i)} (64-d,
 *     the residual left after the decoded level 1); codebook 2 (at most k2 entries of 64 int16
 *     values c2) is trained on them and each block takes the entry minimising sum_i (e_i -
 *     c2_i)^2 (ties: the lowest index).
 *     Codebook sizes: at most min(k, ceil(NZ/8)) entries, NZ = the number of non-zero blocks
 *     (an int16 entry of level 2 costs 128 bytes, as much as ~27 residual voxels; measured on
 *     a 64^3 Colin27 brick, codebooks with fewer than ~8 blocks per entry do not pay).
 *     Training (both levels): on at most `train` vectors (all of them when train = 0 or there
 *     are fewer; else vector floor(j*n/train) for j < train). Initial codebook by PCA
 *     splitting: start with one cluster holding every vector; repeatedly take the cluster of
 *     largest squared-error distortion (ties: the lowest cluster index), find the principal
 *     eigenvector a of its covariance (power iteration), split it into {x : (x - mean).a < 0}
 *     and the rest; stop at k clusters or when no cluster has positive distortion (fewer
 *     distinct vectors than k: the codebook then has fewer entries). Then LBG (k-means):
 *     assign each vector to its nearest centroid, move each centroid to the mean of its
 *     vectors, until |D_old - D_new| / D_old < eps or D = 0 or 100 iterations. An empty
 *     cluster is re-seeded with the vector farthest from its own centroid (not yet used for
 *     another re-seed; ties: the lowest vector index), or dropped when every vector sits on a
 *     centroid; clusters empty when LBG stops are dropped. Entries are the cluster means
 *     rounded to the nearest integer, halves away from zero (level 1: the mean of S/8).
 *  5. The frame is cut into regions of 256x256x256 voxels (64^3 blocks), numbered x fastest
 *     (seed eq. 4). In each region the non-zero blocks go into a perfect spatial hash keyed by
 *     their block coordinates inside the region (0..63), holding (i1, i2); then every voxel's
 *     value before the residual stage, b = clamp(m + c1[i1]_{j} + c2[i2]_{i}, 0, 255) (zero
 *     blocks: b = m), is compared with the original: voxels with |v - b| > residual go into a
 *     second perfect spatial hash keyed by their voxel coordinates inside the region (0..255),
 *     holding v itself. Regions are built in parallel; the bytes do not depend on the number
 *     of threads.
 *
 * ---- Decoding (the definition; C and OpenCL are bit-exact) ---------------------------------
 * For voxel (x, y, z), block (bx, by, bz) = (x>>2, y>>2, z>>2), region (x>>8, y>>8, z>>8):
 *     value = v                    if the region's residual hash holds key (x&255, y&255, z&255)
 *                                  with value v;
 *           = clamp(m + c1[i1][j] + c2[i2][i], 0, 255)
 *                                  else, if its index hash holds key (bx&63, by&63, bz&63)
 *                                  with (i1, i2), j = ((x&3)>>1) + 2((y&3)>>1) + 4((z&3)>>1)
 *                                  (seed eq. 10), i = (x&3) + 4(y&3) + 16(z&3) (eq. 9);
 *           = m                    else (a zero block).
 * All integer arithmetic: there is no rounding in the decoder. After the residual stage every
 * voxel's error is at most `residual` (residual voxels are exact). On the OpenCL device
 * (CDVR_CODEC_CL_FETCH, kernels/codec/hvq_fetch.cl) a frame is its payload and nothing else:
 * the fetch reads the means, codebooks and hashes from it, so the device memory of a frame is
 * the payload's size (plus the 48-byte parameter blob).
 *
 * ---- Perfect spatial hash (Lefebvre & Hoppe 2006) ------------------------------------------
 * A hash of n > 0 keys p = (px, py, pz) (bytes) has a table side m (m^3 >= n slots) and an
 * offset table side r (r^3 entries), gcd(m, r) = 1:
 *     h1(p) = (px mod r, py mod r, pz mod r)                 -> offset entry
 *             e = h1x + r*(h1y + r*h1z), holding (ox, oy, oz), each < m
 *     H(p)  = ((px mod m + ox) mod m, (py mod m + oy) mod m, (pz mod m + oz) mod m)
 *             -> slot s = Hx + m*(Hy + m*Hz)
 * Slot s stores a key; the lookup of p hits iff the key in slot H(p) equals p. A slot that
 * holds no key stores the first key of the set (which lives in another slot), so no absent
 * key matches it. n = 0: m = r = 0 and no data; every lookup misses.
 * Construction (deterministic; the decoder does not depend on it): keys are given in z, y, x
 * order. Offset entries are assigned in order of decreasing number of keys (ties: the lower
 * entry first). For one entry whose first key is p, a candidate free slot f gives the offset
 * f - h0(p) (per axis, mod m), accepted when every key of the entry lands on a free slot. The
 * candidates: the first free slot at or after p's own slot (offset 0 when it is free: keeps
 * neighbours together); then 256 pseudo-random ones, the first free slot at or after
 * floor(u * m^3 / 2^32) for u the successive xorshift32 values (u ^= u << 13, u ^= u >> 17,
 * u ^= u << 5) starting from 0x9E3779B9 ^ (2654435761 * index of p, mod 2^32); then every free
 * slot from p's own onwards, wrapping around. If an entry cannot be placed (or two of its keys
 * share h0) the attempt fails and the next one is tried. Attempt a in 0..9: m = m0 +
 * floor(a/2) (m0: the smallest m with m^3 >= n); r the smallest with r^3 >= ceil(n*(15 +
 * 5*(a mod 2))/60) (r^3 ~ n/4, then n/3), except in the last two attempts, where r =
 * ceil(E/m), E = 1 + the largest key coordinate (then m*r >= E and (h0, h1) is one-to-one on
 * the keys); then r is increased until gcd(m, r) = 1. After ten failed attempts the encoder
 * fails with CDVR_ERR_UNSUPPORTED naming the region and the table sizes tried.
 *
 * ---- Payload, byte by byte (all integers little endian) ------------------------------------
 *   0  4   magic "HVQ1"
 *   4  4   u32 X, 8: u32 Y, 12: u32 Z (must equal the chunk's dims)
 *  16  4   u32 n1: codebook 1 entries (0..4096; 0 iff there is no non-zero block)
 *  20  4   u32 n2: codebook 2 entries (0..4096; 0 iff n1 = 0)
 *  24  8   zero
 *  32      means: NB = NBX*NBY*NBZ bytes, block order above
 *  C1 = align8(32 + NB): codebook 1, n1 entries of 8 int16 (16 bytes each), entry-major
 *  C2 = C1 + 16*n1: codebook 2, n2 entries of 64 int16 (128 bytes each)
 *  D  = align8(C2 + 128*n2): region directory, NR = NRX*NRY*NRZ entries of 32 bytes
 *       (NRX = ceil(X/256) etc., regions x fastest):
 *         0 u16 m, 2 u16 r, 4 u32 n, 8 u64 offset: the index hash
 *        16 u16 m, 18 u16 r, 20 u32 n, 24 u64 offset: the residual hash
 *       (offset: from the start of the payload; n = 0 iff m = 0 iff r = 0, offset then
 *       the current end of the data)
 *  D + 32*NR: hash data, for each region in order its index hash then its residual hash,
 *       contiguous, ending exactly at the end of the payload. One hash's data:
 *         r^3 offset entries of 3*w bytes (ox, oy, oz, each w bytes; w = 2 if m > 256 else 1)
 *         m^3 slots: index hash: key bx, by, bz (3 bytes), i1 (W1 bytes), i2 (W2 bytes),
 *                    W = 2 if the codebook has more than 256 entries else 1;
 *                    residual hash: key x, y, z (3 bytes), v (1 byte)
 *  Padding bytes are zero. The decoder rejects (CDVR_ERR_CORRUPT) any payload that breaks a
 *  rule above, including an offset component >= m, an index >= its codebook size in any slot,
 *  a directory n other than the number of slots whose key maps to themselves (and lies in the
 *  region), m > 1023, r > 256, and codebook sizes above the parameters' k1, k2.
 *
 * ---- Compact form: codec "hvqc" (id 3), payload magic "HVQ2" --------------------------------
 * Steps 1-4 as above (the same means, zero blocks, codebooks and indices for the same
 * parameters and frame; with shared codebooks, step 4 assigns to the given codebooks and
 * trains none). No hashes: residuals are a list. Residual stage: b as in step 5; for every
 * voxel with |d| > R, d = v - b, R = `residual`, the payload keeps its position and
 * q = sign(d) * floor((|d| + R) / (2R + 1)) (|d - q(2R+1)| <= R). Decoding:
 *     value = clamp(b + q * (2R + 1), 0, 255)     at a residual voxel (|value - v| <= R, as
 *                                                 clamping only moves toward v in 0..255);
 *           = b                                   elsewhere (b: the formula of step 5).
 * Payload: the magic "HVQ2", then these fields, each an unsigned LEB128 (7 bits a byte, low
 * first, bit 7 set on every byte but the last; at most 64 bits):
 *          X, Y, Z     the chunk's dims
 *          n1, n2      codebook sizes (the shared codebooks' when flags bit 0 is set)
 *          R           0..255
 *          flags       bit 0: the codebooks are the variant's shared ones (none inside);
 *                      others 0
 *          NR          residual voxels (at most X*Y*Z)
 *          P           bytes of the raw residual position list (at most 10 * NR)
 *          C1 .. C7    compressed bytes of the 7 sections below (0 iff the section is empty)
 *        then, with flag bit 0, the shared-codebook id (cdvr_shared_id of the blob, not 0):
 *        8 bytes little endian; then the sections, each one zstd frame with its content size
 *        and checksum, back to back, ending exactly at the end of the payload. Raw contents:
 *          means      NB bytes: m[b] - m[b-1] mod 256, block order (m[-1] = 0); the block
 *                     grid covers the core: an axis of n = 4k+1 >= 5 voxels (a store brick:
 *                     its owned voxels and the one-voxel overlap below them) leaves its first
 *                     plane out (the core starts at 1 there and has n-1 voxels), that plane
 *                     decoding as a copy of the next (b of the nearest core voxel) before
 *                     residuals: every brick's blocks then lie on the whole volume's grid
 *          bitmap     ceil(NB/8) bytes: bit b%8 of byte b/8 set iff block b is non-zero (bits
 *                     past NB zero); NZ = the number of set bits
 *          indices    NZ x W1 then NZ x W2 bytes (W as in the hashed form), each index list as
 *                     byte planes (all low bytes, then all high bytes when W = 2), non-zero
 *                     blocks in block order
 *          codebook 1 16 x n1 bytes: the 8 n1 int16 values entry-major, as byte planes
 *          codebook 2 128 x n2 bytes: likewise (both empty with shared codebooks)
 *          positions  NR unsigned LEB128 deltas: voxel index x + X(y + Y z) of residual k
 *                     minus (index of residual k-1) minus 1 (k = 0: the index itself)
 *          values     NR x WQ bytes, WQ = 2 if R = 0 else 1: zigzag(q) (2q for q >= 0, -2q-1
 *                     else), one u16 little endian per value when WQ = 2
 * The decoder rejects (CDVR_ERR_CORRUPT) any other layout, an index past its codebook, a
 * position past the last voxel, a section that does not inflate to its size exactly, a shared
 * payload without (or with other) shared codebooks, and codebook sizes above k1, k2.
 * Shared codebook blob ("HVQS", stored once per variant, cdvr/codec.h): 0 "HVQS", 4 u32 n1,
 * 8 u32 n2, 12 u32 0, 16 u64 compressed bytes C, 24: one zstd frame (C bytes) of codebook 1
 * then codebook 2 as byte planes (as in the payload). Trained on the pooled non-zero blocks
 * (on the block grid an unbricked compact chunk of the whole volume has)
 * of up to 4 sample frames of the whole volume (at most ceil(train / frames) vectors of each).
 *
 * ---- Quality target (encoder only; both forms) ----------------------------------------------
 * `residual` is the maximum error: every decoded voxel is within it of the original. With a
 * PSNR target T > 0 the encoder picks the residual threshold per chunk: after steps 1-4 (the
 * VQ result, not retrained) it counts the pairs (b, v) of every voxel's value before the
 * residual stage and its original, computes the decoded chunk's squared error SSE(R) exactly
 * for R = residual, residual-1, ..., 0 (hashed form: error d = v - b when |d| <= R, else 0;
 * compact form: d when |d| <= R, else clamp(b + q(2R+1), 0, 255) - v) and applies the first R
 * with SSE(R) = 0 or 10 log10(255^2 N / SSE(R)) >= T, N = the chunk's voxels (R = 0 always
 * qualifies: the decode is then exact). The compact payload records R in its header (hvqc's
 * describe figure "residual_sum", which st:info() sums over chunks); the hashed form decodes
 * without R (its encoder stats report it). A store's volume PSNR over owned voxels can differ
 * slightly from its bricks' (overlap voxels count in each brick).
 *
 * ---- Codebook size from the data (k2 = 0, "auto"; compact form only) ------------------------
 * Level 2 is trained and assigned at each size 256, 512, 1024, 2048 in turn (the size cap
 * above applies; the candidates stop at the first that gives no more entries than the one
 * before), the residual threshold chosen for each (under a PSNR target too), and the whole
 * compact payload's size measured (sections built and compressed); the size with the smallest
 * payload is kept (ties: the smaller), so the payload is byte for byte the plain encode at
 * that k2. Encode time: up to four level-2 trainings and residual stages (light-sheet 256^3:
 * about 3x the plain encode). The hashed form and shared codebooks refuse k2 = 0.
 *
 * ---- Parameter blob (CDVR_CODEC_PARAMS_MAX bytes, little endian, unused bytes 0) -----------
 *   0  f64 grad      zero-block threshold on the average gradient, 0..765 (default 8)
 *   8  f64 eps       LBG stop: relative distortion change, 0 < eps < 1 (default 0.01)
 *  16  u32 residual  residual threshold, 0..255 (default 10)
 *  20  u32 k1        codebook 1 size at most, 1..4096 (default 4096)
 *  24  u32 k2        codebook 2 size at most, 1..4096 (default 1024); hvqc: 0 = auto
 *  28  u32 train     training vectors at most, 0 = all (default 262144)
 *  36  u32 psnr      PSNR target in 1/100 dB, 0..20000, 0 = none (default 0; both forms)
 *  hvqc only: 32 u32 shared (0/1), 40 u64 shared-codebook id (set by the store encoder
 *  after training; 0 unless shared = 1)
 */
#ifndef CDVR_HVQ_H
#define CDVR_HVQ_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/codec.h"
#include "cdvr/error.h"

#define CDVR_HVQ_K_MAX 4096u       /* largest codebook */
#define CDVR_HVQ_REGION 256u       /* region side in voxels */

typedef struct cdvr_hvq_params {
    double grad;        /* zero-block threshold on the block's average gradient */
    double eps;         /* LBG relative distortion change at which it stops */
    uint32_t residual;  /* |original - decoded| above this -> residual voxel */
    uint32_t k1, k2;    /* codebook sizes (at most) */
    uint32_t train;     /* training vectors per codebook at most; 0 = all */
    double psnr;        /* quality target in dB, 0 = none: the residual threshold applied is
                         * the largest R <= residual whose decoded chunk has PSNR >= psnr
                         * (see "Quality target" above); a multiple of 0.01, 0..200 */
} cdvr_hvq_params;

/* Figures about one payload (cdvr_hvq_check fills them; the codec's describe hook emits
 * them). The byte counts add up to the payload size: header = the 32-byte header, alignment
 * padding and the region directory; index_hash and residual_hash = offset tables + slots. */
typedef struct cdvr_hvq_stats {
    size_t header, means, codebook1, codebook2, index_hash, residual_hash;
    size_t indices, residuals;  /* compact form: bitmap + index list, residual list */
    size_t blocks, zero_blocks, residual_voxels;
    size_t codebook1_entries, codebook2_entries, regions;
    /* the residual threshold R applied (the encoder's choice under a psnr target; the compact
     * form's check reads it from the payload, the hashed form's check leaves it 0) */
    uint32_t residual;
    /* encoder only (cdvr_hvq_check leaves them 0): LBG iterations of codebook 1 and 2, and
     * the PSH attempts of the region that needed the most */
    int lbg_iterations[2];
    int hash_attempts;
} cdvr_hvq_stats;

/* Sets p->psnr to db rounded to the nearest 0.01 and clamped to 0..200 (what the parameter
 * blob holds) and returns that value, the target the encoder applies (0: none). */
double cdvr_hvq_params_set_psnr(cdvr_hvq_params *p, double db);

/* The defaults (grad 8, eps 0.01, residual 10, k1 4096, k2 1024, train 262144), chosen by
 * measurement on Colin27 and the engine CT (scripts/bench/hvq_bench.sh sweep). */
void cdvr_hvq_params_default(cdvr_hvq_params *p);
/* Blob <-> struct (layout above). from_blob does not validate: see cdvr_hvq_params_check. */
void cdvr_hvq_params_to_blob(const cdvr_hvq_params *p, cdvr_codec_params *blob);
void cdvr_hvq_params_from_blob(const cdvr_codec_params *blob, cdvr_hvq_params *p);
/* CDVR_ERR_ARG naming the parameter out of range. */
cdvr_status cdvr_hvq_params_check(const cdvr_hvq_params *p, cdvr_error *err);

/* Worst-case payload bytes for dims (what encode may write); CDVR_ERR_NOMEM on overflow,
 * CDVR_ERR_ARG for dims of 0 or above 2^32-1. */
cdvr_status cdvr_hvq_bound(const cdvr_hvq_params *p, const size_t dims[3], size_t *bytes,
                           cdvr_error *err);

/* Encodes one u8 frame of dims (x fastest) into out. threads: worker threads for codebook
 * training and the regions (0: one per online CPU, at most 16); the bytes do not depend on
 * it. stats may be NULL. CDVR_ERR_ARG when out_cap is too small for this payload. */
cdvr_status cdvr_hvq_encode(const cdvr_hvq_params *p, const size_t dims[3],
                            const uint8_t *frame, unsigned threads, uint8_t *out,
                            size_t out_cap, size_t *out_bytes, cdvr_hvq_stats *stats,
                            cdvr_error *err);

/* Checks a whole payload against every rule of the format (p may be NULL: then the
 * codebook sizes are checked against CDVR_HVQ_K_MAX only) and fills stats (may be NULL).
 * CDVR_ERR_CORRUPT naming the first broken rule. */
cdvr_status cdvr_hvq_check(const cdvr_hvq_params *p, const size_t dims[3],
                           const uint8_t *payload, size_t bytes, cdvr_hvq_stats *stats,
                           cdvr_error *err);

/* Decodes a payload into out (X*Y*Z bytes). Checks it first (cdvr_hvq_check). Runs on up to
 * one thread per online CPU (at most 16): slabs of blocks, then runs of 64 K residual-hash
 * slots; the same bytes on any number of threads. */
cdvr_status cdvr_hvq_decode(const cdvr_hvq_params *p, const size_t dims[3],
                            const uint8_t *payload, size_t bytes, uint8_t *out,
                            cdvr_error *err);

/* One voxel, exactly as the decoder and the OpenCL fetch (kernels/codec/hvq_fetch.cl) give
 * it. The payload must have passed cdvr_hvq_check for these dims, and x < X, y < Y, z < Z:
 * like the OpenCL function it trusts the payload, so a host that fetches from a payload it
 * did not write must check it first. */
uint8_t cdvr_hvq_fetch(const uint8_t *payload, const size_t dims[3], size_t x, size_t y,
                       size_t z);

/* ---- compact form ("hvqc", magic HVQ2; layout at the top) ---- */

/* The variant's shared codebooks, opened from their blob (cdvr_hvq_shared_open). */
typedef struct cdvr_hvq_codebooks {
    uint32_t n1, n2;
    int16_t *c1, *c2;  /* n1 x 8, n2 x 64 */
    uint64_t id;       /* cdvr_shared_id of the blob (cdvr/codec.h) */
} cdvr_hvq_codebooks;

/* Worst-case compact payload bytes for dims. */
cdvr_status cdvr_hvq_compact_bound(const cdvr_hvq_params *p, const size_t dims[3],
                                   size_t *bytes, cdvr_error *err);
/* Encodes one u8 frame into the compact form: the same classification and codebooks as
 * cdvr_hvq_encode (shared != NULL: these codebooks, not trained; the payload then names their
 * id and holds none), residuals as a list of quantised corrections (every voxel within
 * p->residual of the original). stats: header, means, codebook1/2, indices, residuals. */
cdvr_status cdvr_hvq_encode_compact(const cdvr_hvq_params *p, const cdvr_hvq_codebooks *shared,
                                    const size_t dims[3], const uint8_t *frame, unsigned threads,
                                    uint8_t *out, size_t out_cap, size_t *out_bytes,
                                    cdvr_hvq_stats *stats, cdvr_error *err);
/* Checks a compact payload completely (every section inflated and checked). shared: the
 * codebooks a payload coded with shared codebooks needs (CDVR_ERR_CORRUPT without them). */
cdvr_status cdvr_hvq_compact_check(const cdvr_hvq_params *p, const cdvr_hvq_codebooks *shared,
                                   const size_t dims[3], const uint8_t *payload, size_t bytes,
                                   cdvr_hvq_stats *stats, cdvr_error *err);
/* Checks and decodes a compact payload into out (X*Y*Z bytes). */
cdvr_status cdvr_hvq_compact_decode(const cdvr_hvq_params *p, const cdvr_hvq_codebooks *shared,
                                    const size_t dims[3], const uint8_t *payload, size_t bytes,
                                    uint8_t *out, cdvr_error *err);

/* Shared codebooks: trains one codebook set on the pooled non-zero blocks of nframes sample
 * frames of dims (at most ceil(train / nframes) vectors of each, evenly spaced; the sizes
 * follow the same rules as one frame's) and writes its blob (*blob malloc'd). */
cdvr_status cdvr_hvq_train_shared(const cdvr_hvq_params *p, const size_t dims[3],
                                  const uint8_t *const *frames, size_t nframes, unsigned threads,
                                  uint8_t **blob, size_t *bytes, cdvr_error *err);
/* Opens a blob (checked: CDVR_ERR_CORRUPT) into cb; p may be NULL (sizes up to K_MAX). */
cdvr_status cdvr_hvq_shared_open(const cdvr_hvq_params *p, const uint8_t *blob, size_t bytes,
                                 cdvr_hvq_codebooks *cb, cdvr_error *err);
void cdvr_hvq_codebooks_free(cdvr_hvq_codebooks *cb);
/* The hvqc codec's side of cdvr_codec_wants_shared / cdvr_codec_train_shared (cdvr/codec.h):
 * shared=1 in the blob; training sets the blob's shared-codebook id. */
int cdvr_hvqc_wants_shared(const cdvr_codec_params *p);
cdvr_status cdvr_hvqc_train_shared(cdvr_codec_params *p, const size_t dims[3],
                                   const uint8_t *const *frames, size_t nframes, uint8_t **blob,
                                   size_t *bytes, cdvr_error *err);

#endif
