/* core/codec/pvtc/pvtc_avx2.c - AVX2 fast path of the PVTC decoder: eight interior blocks of a block row
 * at a time. The same scheme as pvtc_ssse3.c in each 128-bit lane (AVX2 shuffles stay inside
 * a lane): the low lane holds blocks 0..3 of the group, the high lane blocks 4..7, so one
 * voxel row of the eight blocks (32 bytes, contiguous in x) is one store. Bit-exact with the
 * reference decoder in pvtc.c (tests/test_pvtc_paths.c checks every variant). Chosen at run
 * time with __builtin_cpu_supports("avx2"); the SSSE3 and portable paths stay for other CPUs. */
#include "pvtc_internal.h"

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>

#define PVTC_AVX2 __attribute__((target("avx2")))

int pvtc_avx2_available(void)
{
    return __builtin_cpu_supports("avx2");
}

/* Palette bytes of eight blocks from their endpoint pairs (16-bit lanes a0 b0 a1 b1 ..):
 * block k of a lane in bytes 4k..4k+3 as {a, (2a+b+1)/3, b, (a+2b+1)/3}, palette entries
 * 0 1 3 2. x / 3 == (x * 0xAAAB) >> 17 for every x < 2^17; here x <= 766. */
static PVTC_AVX2 __m256i palettes_from_pairs(__m256i ab)
{
    enum { swap_pairs = _MM_SHUFFLE(2, 3, 0, 1) };
    __m256i ba = _mm256_shufflehi_epi16(_mm256_shufflelo_epi16(ab, swap_pairs), swap_pairs);
    __m256i num = _mm256_add_epi16(_mm256_add_epi16(ab, ab),
                                   _mm256_add_epi16(ba, _mm256_set1_epi16(1)));
    __m256i third =
        _mm256_srli_epi16(_mm256_mulhi_epu16(num, _mm256_set1_epi16((short)0xAAAB)), 1);
    return _mm256_packus_epi16(_mm256_unpacklo_epi16(ab, third),
                               _mm256_unpackhi_epi16(ab, third));
}

/* 5- or 6-bit fields (16-bit lanes) expanded to 8 bits by bit replication. */
static PVTC_AVX2 __m256i expand5(__m256i q)
{
    return _mm256_or_si256(_mm256_slli_epi16(q, 3), _mm256_srli_epi16(q, 2));
}

static PVTC_AVX2 __m256i expand6(__m256i q)
{
    return _mm256_or_si256(_mm256_slli_epi16(q, 2), _mm256_srli_epi16(q, 4));
}

/* Palettes of up to three channels for the eight blocks whose endpoints start at ep. */
static PVTC_AVX2 void group_palettes(int T, const uint8_t *ep, __m256i pal[3])
{
    __m256i e = _mm256_loadu_si256((const __m256i *)ep); /* lanes: U0 D0 U1 D1 .. */
    if (T == 2) {
        pal[0] = palettes_from_pairs(_mm256_and_si256(e, _mm256_set1_epi16(0xFF)));
        pal[1] = palettes_from_pairs(_mm256_srli_epi16(e, 8));
        return;
    }
    pal[0] = palettes_from_pairs(expand5(_mm256_srli_epi16(e, 11)));
    pal[1] = palettes_from_pairs(
        expand6(_mm256_and_si256(_mm256_srli_epi16(e, 5), _mm256_set1_epi16(63))));
    pal[2] = palettes_from_pairs(expand5(_mm256_and_si256(e, _mm256_set1_epi16(31))));
}

/* 4x4 transpose of 32-bit elements inside each 128-bit lane. */
static PVTC_AVX2 void transpose4(const __m256i in[4], __m256i out[4])
{
    __m256i t0 = _mm256_unpacklo_epi32(in[0], in[1]), t1 = _mm256_unpacklo_epi32(in[2], in[3]);
    __m256i t2 = _mm256_unpackhi_epi32(in[0], in[1]), t3 = _mm256_unpackhi_epi32(in[2], in[3]);
    out[0] = _mm256_unpacklo_epi64(t0, t1);
    out[1] = _mm256_unpackhi_epi64(t0, t1);
    out[2] = _mm256_unpacklo_epi64(t2, t3);
    out[3] = _mm256_unpackhi_epi64(t2, t3);
}

/* Selectors for one slice of eight blocks (words: block k of a lane in its 32-bit element k):
 * rows[y] element k holds, for x = 0..3, the palette byte 4k + {0,1,3,2}[index] of voxel
 * (x, y) of that block. Each nibble of a word is two indices; a table maps it to each. */
static PVTC_AVX2 void group_selectors(__m256i words, __m256i rows[4])
{
    const __m256i low_nibbles = _mm256_set1_epi8(0x0F);
    const __m256i first = _mm256_setr_epi8(0, 1, 3, 2, 0, 1, 3, 2, 0, 1, 3, 2, 0, 1, 3, 2,
                                           0, 1, 3, 2, 0, 1, 3, 2, 0, 1, 3, 2, 0, 1, 3, 2);
    const __m256i second = _mm256_setr_epi8(0, 0, 0, 0, 1, 1, 1, 1, 3, 3, 3, 3, 2, 2, 2, 2,
                                            0, 0, 0, 0, 1, 1, 1, 1, 3, 3, 3, 3, 2, 2, 2, 2);
    __m256i lo = _mm256_and_si256(words, low_nibbles);
    __m256i hi = _mm256_and_si256(_mm256_srli_epi16(words, 4), low_nibbles);
    __m256i nib[2] = {_mm256_unpacklo_epi8(lo, hi), _mm256_unpackhi_epi8(lo, hi)};
    __m256i per_block[4];
    for (int h = 0; h < 2; h++) {
        __m256i even = _mm256_shuffle_epi8(first, nib[h]);
        __m256i odd = _mm256_shuffle_epi8(second, nib[h]);
        per_block[2 * h] = _mm256_or_si256(_mm256_unpacklo_epi8(even, odd),
                                           _mm256_set1_epi8((char)(8 * h)));
        per_block[2 * h + 1] = _mm256_or_si256(_mm256_unpackhi_epi8(even, odd),
                                               _mm256_set1_epi8((char)(8 * h + 4)));
    }
    transpose4(per_block, rows);
}

/* Index words of slice zi for eight blocks: element k of the low lane = word zi of block k,
 * of the high lane = word zi of block 4 + k. */
static PVTC_AVX2 void group_words(int S, const uint8_t *words, __m256i out[4])
{
    if (S == 1) {
        out[0] = _mm256_loadu_si256((const __m256i *)words);
        return;
    }
    __m256i per_block[4];
    for (int k = 0; k < 4; k++)
        per_block[k] = _mm256_loadu2_m128i((const __m128i *)(words + 16 * (k + 4)),
                                           (const __m128i *)(words + 16 * k));
    transpose4(per_block, out);
}

static PVTC_AVX2 void decode_group(const pvtc_row_job *job, size_t bx)
{
    __m256i pal[3], words[4], rows[4];
    group_palettes(job->T, job->endpoints + 4 * bx, pal);
    group_words(job->S, job->words + 4 * (size_t)job->S * bx, words);
    for (int zi = 0; zi < job->S; zi++) {
        group_selectors(words[zi], rows);
        for (int c = 0; c < job->nch; c++) {
            uint8_t *row = job->dst[zi][c] + 4 * bx;
            for (int y = 0; y < 4; y++, row += job->stride)
                _mm256_storeu_si256((__m256i *)row, _mm256_shuffle_epi8(pal[c], rows[y]));
        }
    }
}

PVTC_AVX2 size_t pvtc_decode_row_avx2(const pvtc_row_job *job)
{
    size_t groups = job->nblocks / 8;
    for (size_t g = 0; g < groups; g++)
        decode_group(job, 8 * g);
    return 8 * groups;
}

#else

int pvtc_avx2_available(void)
{
    return 0;
}

size_t pvtc_decode_row_avx2(const pvtc_row_job *job)
{
    (void)job;
    return 0;
}

#endif
