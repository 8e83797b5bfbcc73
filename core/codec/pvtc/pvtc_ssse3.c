/* core/codec/pvtc/pvtc_ssse3.c - SSSE3 fast path of the PVTC decoder: four interior blocks of a block
 * row at a time. The four palettes of a channel sit in one register (block k in bytes
 * 4k..4k+3), the 2-bit indices become pshufb selectors into it, and each voxel row of the four
 * blocks (16 bytes, contiguous in x) is written with one store. Bit-exact with the reference
 * decoder in pvtc.c (tests/test_pvtc_paths.c checks every variant); the portable decoder is
 * used where this file has nothing to offer (other compilers or CPUs). */
#include "pvtc_internal.h"

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <tmmintrin.h>

#define PVTC_SSSE3 __attribute__((target("ssse3")))

int pvtc_ssse3_available(void)
{
    return __builtin_cpu_supports("ssse3");
}

/* Palette bytes of four blocks from their endpoint pairs (16-bit lanes a0 b0 a1 b1 ..):
 * block k in bytes 4k..4k+3 as {a, (2a+b+1)/3, b, (a+2b+1)/3}, i.e. palette entries 0 1 3 2.
 * x / 3 == (x * 0xAAAB) >> 17 for every x < 2^17; here x <= 766. */
static PVTC_SSSE3 __m128i palettes_from_pairs(__m128i ab)
{
    enum { swap_pairs = _MM_SHUFFLE(2, 3, 0, 1) }; /* a constant expression for clang too */
    __m128i ba = _mm_shufflehi_epi16(_mm_shufflelo_epi16(ab, swap_pairs), swap_pairs);
    __m128i num = _mm_add_epi16(_mm_add_epi16(ab, ab), _mm_add_epi16(ba, _mm_set1_epi16(1)));
    __m128i third = _mm_srli_epi16(_mm_mulhi_epu16(num, _mm_set1_epi16((short)0xAAAB)), 1);
    return _mm_packus_epi16(_mm_unpacklo_epi16(ab, third), _mm_unpackhi_epi16(ab, third));
}

/* 5- or 6-bit fields (16-bit lanes) expanded to 8 bits by bit replication. */
static PVTC_SSSE3 __m128i expand5(__m128i q)
{
    return _mm_or_si128(_mm_slli_epi16(q, 3), _mm_srli_epi16(q, 2));
}

static PVTC_SSSE3 __m128i expand6(__m128i q)
{
    return _mm_or_si128(_mm_slli_epi16(q, 2), _mm_srli_epi16(q, 4));
}

/* Palettes of up to three channels for the four blocks whose endpoints start at ep. */
static PVTC_SSSE3 void group_palettes(int T, const uint8_t *ep, __m128i pal[3])
{
    __m128i e = _mm_loadu_si128((const __m128i *)ep); /* lanes: U0 D0 U1 D1 .. */
    if (T == 2) {
        pal[0] = palettes_from_pairs(_mm_and_si128(e, _mm_set1_epi16(0xFF)));
        pal[1] = palettes_from_pairs(_mm_srli_epi16(e, 8));
        return;
    }
    pal[0] = palettes_from_pairs(expand5(_mm_srli_epi16(e, 11)));
    pal[1] = palettes_from_pairs(expand6(_mm_and_si128(_mm_srli_epi16(e, 5), _mm_set1_epi16(63))));
    pal[2] = palettes_from_pairs(expand5(_mm_and_si128(e, _mm_set1_epi16(31))));
}

/* 4x4 transpose of 32-bit lanes: out[j] lane k = in[k] lane j. */
static PVTC_SSSE3 void transpose4(const __m128i in[4], __m128i out[4])
{
    __m128i t0 = _mm_unpacklo_epi32(in[0], in[1]), t1 = _mm_unpacklo_epi32(in[2], in[3]);
    __m128i t2 = _mm_unpackhi_epi32(in[0], in[1]), t3 = _mm_unpackhi_epi32(in[2], in[3]);
    out[0] = _mm_unpacklo_epi64(t0, t1);
    out[1] = _mm_unpackhi_epi64(t0, t1);
    out[2] = _mm_unpacklo_epi64(t2, t3);
    out[3] = _mm_unpackhi_epi64(t2, t3);
}

/* Selectors for one slice of four blocks, words = their index words (block k in lane k):
 * rows[y] lane k holds, for x = 0..3, the palette byte 4k + {0,1,3,2}[index] of voxel
 * (x, y) of block k. Each nibble of a word is two indices; a table maps it to each. */
static PVTC_SSSE3 void group_selectors(__m128i words, __m128i rows[4])
{
    const __m128i low_nibbles = _mm_set1_epi8(0x0F);
    const __m128i first = _mm_setr_epi8(0, 1, 3, 2, 0, 1, 3, 2, 0, 1, 3, 2, 0, 1, 3, 2);
    const __m128i second = _mm_setr_epi8(0, 0, 0, 0, 1, 1, 1, 1, 3, 3, 3, 3, 2, 2, 2, 2);
    __m128i lo = _mm_and_si128(words, low_nibbles);
    __m128i hi = _mm_and_si128(_mm_srli_epi16(words, 4), low_nibbles);
    __m128i nib[2] = {_mm_unpacklo_epi8(lo, hi), _mm_unpackhi_epi8(lo, hi)};
    __m128i per_block[4];
    for (int h = 0; h < 2; h++) {
        __m128i even = _mm_shuffle_epi8(first, nib[h]), odd = _mm_shuffle_epi8(second, nib[h]);
        per_block[2 * h] = _mm_or_si128(_mm_unpacklo_epi8(even, odd), _mm_set1_epi8((char)(8 * h)));
        per_block[2 * h + 1] =
            _mm_or_si128(_mm_unpackhi_epi8(even, odd), _mm_set1_epi8((char)(8 * h + 4)));
    }
    transpose4(per_block, rows);
}

/* Index words of slice zi for four blocks: lane k = word zi of block k. */
static PVTC_SSSE3 void group_words(int S, const uint8_t *words, __m128i out[4])
{
    if (S == 1) {
        out[0] = _mm_loadu_si128((const __m128i *)words);
        return;
    }
    __m128i per_block[4];
    for (int k = 0; k < 4; k++)
        per_block[k] = _mm_loadu_si128((const __m128i *)(words + 16 * k));
    transpose4(per_block, out);
}

static PVTC_SSSE3 void decode_group(const pvtc_row_job *job, size_t bx)
{
    __m128i pal[3], words[4], rows[4];
    group_palettes(job->T, job->endpoints + 4 * bx, pal);
    group_words(job->S, job->words + 4 * (size_t)job->S * bx, words);
    for (int zi = 0; zi < job->S; zi++) {
        group_selectors(words[zi], rows);
        for (int c = 0; c < job->nch; c++) {
            uint8_t *row = job->dst[zi][c] + 4 * bx;
            for (int y = 0; y < 4; y++, row += job->stride)
                _mm_storeu_si128((__m128i *)row, _mm_shuffle_epi8(pal[c], rows[y]));
        }
    }
}

PVTC_SSSE3 size_t pvtc_decode_row_ssse3(const pvtc_row_job *job)
{
    size_t groups = job->nblocks / 4;
    for (size_t g = 0; g < groups; g++)
        decode_group(job, 4 * g);
    return 4 * groups;
}

#else

int pvtc_ssse3_available(void)
{
    return 0;
}

size_t pvtc_decode_row_ssse3(const pvtc_row_job *job)
{
    (void)job;
    return 0;
}

#endif
