/* core/codec/pvtc/pvtc_lsq.c - the default PVTC block encoder (DESIGN.md 4.1): principal axis of the
 * block's T-dimensional points, then alternate (a) nearest-palette index assignment, (b) the
 * 2x2 least-squares solve for the endpoints given the index weights {1, 2/3, 1/3, 0}, and
 * (c) a search of the quantised endpoint neighbourhood that minimises the true decoded error
 * (exact integer palette arithmetic). Every step only accepts a lower error, and the result
 * is compared with bbox, so it is never worse than bbox on any block. */
#include <math.h>
#include <string.h>

#include "pvtc_internal.h"

#define LSQ_MAX_ITERATIONS 6
#define POWER_ITERATIONS 12
/* Quantised steps searched around each channel's endpoints: 2 (25 pairs) for T = 2, whose
 * 8-bit endpoints are finer, 1 (9 pairs) for T = 3. Radius 1 against 2 for T = 3, measured on
 * viscous fingers 64^3 and its 256^3 upsampling (scripts/bench/make_series.py): at most
 * 0.002 dB lower, for a tenth to a sixth less time (T = 2 lost up to 0.03 dB). */
#define SEARCH_RADIUS_MAX 2
static int search_radius(int T)
{
    return T == 2 ? 2 : 1;
}
#define CLUSTER_FIT_MAX_POSITIONS 16
/* The cluster fit runs only when the refined principal-axis fit errs by more than this squared
 * error per value. The cluster fit rarely improves a fit already this close and is most of the
 * encoder's time. For T = 3 (5/6-bit endpoints) 3 against the earlier 1, measured on viscous
 * fingers 64^3 and its 256^3 upsampling: S1T3 0.003 to 0.022 dB lower for 1.4x to 2.5x less
 * time (the budget: 0.05 dB); T = 2 keeps 1 (a threshold of 2 lost up to 0.03 dB). */
#define CLUSTER_FIT_MIN_ERROR_PER_VALUE_T3 3u
#define CLUSTER_FIT_MIN_ERROR_PER_VALUE_T2 1u

static const double INDEX_WEIGHT[4] = {1.0, 2.0 / 3.0, 1.0 / 3.0, 0.0};

static int clamp_int(int v, int lo, int hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

/* 8-bit real value -> nearest quantised value, clamped to the channel's range. */
static int quantize_real(int bits, double x)
{
    int max = (1 << bits) - 1;
    return clamp_int((int)floor(x * max / 255.0 + 0.5), 0, max);
}

/* ---- principal axis ---------------------------------------------------------------------- */

static void block_mean_cov(const pvtc_block *blk, double mean[3], double cov[3][3])
{
    memset(cov, 0, 9 * sizeof(double));
    for (int c = 0; c < 3; c++)
        mean[c] = 0.0;
    for (int i = 0; i < blk->npos; i++)
        for (int c = 0; c < blk->T; c++)
            mean[c] += blk->v[i][c];
    for (int c = 0; c < blk->T; c++)
        mean[c] /= blk->npos;
    for (int i = 0; i < blk->npos; i++)
        for (int r = 0; r < blk->T; r++)
            for (int c = 0; c < blk->T; c++)
                cov[r][c] += (blk->v[i][r] - mean[r]) * (blk->v[i][c] - mean[c]);
}

/* Principal eigenvector by power iteration, started from the covariance column of largest
 * norm (never orthogonal to the principal axis). Returns 0 when all points are equal. */
static int principal_axis(int T, double cov[3][3], double axis[3])
{
    int best_col = 0;
    double best_norm = 0.0;
    for (int c = 0; c < T; c++) {
        double n = 0.0;
        for (int r = 0; r < T; r++)
            n += cov[r][c] * cov[r][c];
        if (n > best_norm) {
            best_norm = n;
            best_col = c;
        }
    }
    if (best_norm < 1e-12)
        return 0;
    double v[3] = {0.0, 0.0, 0.0};
    for (int r = 0; r < T; r++)
        v[r] = cov[r][best_col];
    for (int it = 0; it < POWER_ITERATIONS; it++) {
        double w[3] = {0.0, 0.0, 0.0}, norm = 0.0;
        for (int r = 0; r < T; r++) {
            for (int c = 0; c < T; c++)
                w[r] += cov[r][c] * v[c];
            norm += w[r] * w[r];
        }
        if (norm < 1e-24)
            return 0;
        norm = sqrt(norm);
        for (int r = 0; r < T; r++)
            v[r] = w[r] / norm;
    }
    memcpy(axis, v, sizeof v);
    return 1;
}

/* Endpoints at the extreme projections onto the principal axis. Returns 0 (code untouched)
 * when the PCA is degenerate: all points equal, a constant block. */
static int principal_endpoints(const pvtc_block *blk, pvtc_code *code, double axis[3])
{
    double mean[3], cov[3][3];
    block_mean_cov(blk, mean, cov);
    double tmin = 0.0, tmax = 0.0;
    if (!principal_axis(blk->T, cov, axis))
        return 0;
    {
        for (int i = 0; i < blk->npos; i++) {
            double t = 0.0;
            for (int c = 0; c < blk->T; c++)
                t += (blk->v[i][c] - mean[c]) * axis[c];
            if (t < tmin)
                tmin = t;
            if (t > tmax)
                tmax = t;
        }
    }
    for (int c = 0; c < blk->T; c++) {
        int bits = pvtc_channel_bits(blk->T, c);
        code->qa[c] = quantize_real(bits, mean[c] + tmax * axis[c]);
        code->qb[c] = quantize_real(bits, mean[c] + tmin * axis[c]);
    }
    return 1;
}

/* Best quantised (a, b) of one channel whose palette entry k (0 or 1; 2 and 3 mirror them)
 * is closest to value; returns the squared error. */
static int fit_value(int bits, int k, int value, int *qa_out, int *qb_out)
{
    int max = (1 << bits) - 1, best = -1, pal[4];
    for (int qa = 0; qa <= max && best != 0; qa++)
        for (int qb = (k == 0 ? qa : 0); qb <= (k == 0 ? qa : max); qb++) {
            pvtc_palette(pvtc_expand(bits, qa), pvtc_expand(bits, qb), pal);
            int e = (pal[k] - value) * (pal[k] - value);
            if (best < 0 || e < best) {
                best = e;
                *qa_out = qa;
                *qb_out = qb;
                if (e == 0)
                    break;
            }
        }
    return best;
}

/* Constant block: every position takes the same palette entry k, and each channel gets the
 * quantised pair whose entry k is nearest to its value (5/6-bit endpoints cannot hold every
 * 8-bit value, but an interpolated entry often can). */
static uint32_t fit_constant(const pvtc_block *blk, pvtc_code *code)
{
    uint32_t best_total = UINT32_MAX;
    for (int k = 0; k < 2; k++) {
        pvtc_code trial;
        uint32_t total = 0;
        for (int c = 0; c < blk->T; c++)
            total += (uint32_t)fit_value(pvtc_channel_bits(blk->T, c), k, blk->v[0][c],
                                         &trial.qa[c], &trial.qb[c]);
        if (total < best_total) {
            best_total = total;
            memset(trial.index, k, sizeof trial.index);
            *code = trial;
        }
    }
    return best_total;
}

/* ---- per-index statistics for fixed indices ---------------------------------------------- */

typedef struct index_stats {
    int count[4];
    int sum[3][4];      /* per channel, per index: sum of v */
} index_stats;

static void gather_stats(const pvtc_block *blk, const pvtc_code *code, index_stats *st)
{
    memset(st, 0, sizeof *st);
    for (int i = 0; i < blk->npos; i++) {
        int k = code->index[i];
        st->count[k]++;
        for (int c = 0; c < blk->T; c++)
            st->sum[c][k] += blk->v[i][c];
    }
}

/* Least-squares endpoints for the current indices; returns 0 if the system is singular (all
 * positions share one palette weight). */
static int least_squares_endpoints(int T, const index_stats *st, pvtc_code *code)
{
    double aa = 0.0, ab = 0.0, bb = 0.0;
    for (int k = 0; k < 4; k++) {
        double w = INDEX_WEIGHT[k], n = st->count[k];
        aa += n * w * w;
        ab += n * w * (1.0 - w);
        bb += n * (1.0 - w) * (1.0 - w);
    }
    double det = aa * bb - ab * ab;
    if (fabs(det) < 1e-9)
        return 0;
    for (int c = 0; c < T; c++) {
        double ra = 0.0, rb = 0.0;
        for (int k = 0; k < 4; k++) {
            double sum = st->sum[c][k];
            ra += INDEX_WEIGHT[k] * sum;
            rb += (1.0 - INDEX_WEIGHT[k]) * sum;
        }
        int bits = pvtc_channel_bits(T, c);
        code->qa[c] = quantize_real(bits, (bb * ra - ab * rb) / det);
        code->qb[c] = quantize_real(bits, (aa * rb - ab * ra) / det);
    }
    return 1;
}

/* Squared error of channel c with 8-bit endpoints a, b for the fixed indices, less the
 * constant sum of v^2 (exact integers: only differences between candidates matter). */
static int channel_error(const index_stats *st, int c, int a, int b)
{
    const int pal[4] = {a, (2 * a + b + 1) / 3, (a + 2 * b + 1) / 3, b}; /* pvtc_palette */
    int e = 0;
    for (int k = 0; k < 4; k++)
        e += pal[k] * (st->count[k] * pal[k] - 2 * st->sum[c][k]);
    return e;
}

/* With indices fixed the error separates by channel: per channel, the best quantised (a, b)
 * within search_radius steps of the current pair (the first of equal ones, a then b
 * ascending). */
static void search_neighbourhood(int T, const index_stats *st, pvtc_code *code)
{
    for (int c = 0; c < T; c++) {
        int bits = pvtc_channel_bits(T, c), max = (1 << bits) - 1;
        int qa0 = code->qa[c], qb0 = code->qb[c];
        int best = channel_error(st, c, pvtc_expand(bits, qa0), pvtc_expand(bits, qb0));
        int r = search_radius(T);
        int qb_lo = clamp_int(qb0 - r, 0, max);
        int qb_hi = clamp_int(qb0 + r, 0, max);
        int b_expanded[2 * SEARCH_RADIUS_MAX + 1];
        for (int qb = qb_lo; qb <= qb_hi; qb++)
            b_expanded[qb - qb_lo] = pvtc_expand(bits, qb);
        for (int qa = clamp_int(qa0 - r, 0, max); qa <= clamp_int(qa0 + r, 0, max); qa++) {
            int a = pvtc_expand(bits, qa);
            for (int qb = qb_lo; qb <= qb_hi; qb++) {
                int e = channel_error(st, c, a, b_expanded[qb - qb_lo]);
                if (e < best) {
                    best = e;
                    code->qa[c] = qa;
                    code->qb[c] = qb;
                }
            }
        }
    }
}

/* ---- cluster fit (S = 1) ------------------------------------------------------------------
 * As in BC1 cluster-fit encoders: order the points along the principal axis and try every
 * split of that order into four runs (palette entries b, 2/3 b, 2/3 a, a); for each split the
 * least-squares endpoints and their error follow from prefix sums. The best split seeds the
 * refinement. C(n+3, 3) splits: 969 for 16 points, so only used for S = 1. */

static void sort_by_projection(const pvtc_block *blk, const double axis[3], int order[])
{
    double key[PVTC_MAX_POSITIONS];
    for (int i = 0; i < blk->npos; i++) {
        key[i] = 0.0;
        for (int c = 0; c < blk->T; c++)
            key[i] += blk->v[i][c] * axis[c];
        order[i] = i;
    }
    for (int i = 1; i < blk->npos; i++) { /* insertion sort: at most 16 points */
        int o = order[i], j = i;
        while (j > 0 && key[order[j - 1]] > key[o]) {
            order[j] = order[j - 1];
            j--;
        }
        order[j] = o;
    }
}

static double clamp_real(double v)
{
    return v < 0.0 ? 0.0 : v > 255.0 ? 255.0 : v;
}

typedef struct split_fit {
    double a[3], b[3], err;
} split_fit;

/* Normal equations of a split into runs [0,i) [i,j) [j,k) [k,n) with a-weights 0, 1/3, 2/3, 1
 * (palette entries b, (a + 2b)/3, (2a + b)/3, a), scaled to integers so that scoring a split
 * needs no division: AA, AB, BB are 9 x the sums of w^2, w(1-w), (1-w)^2 over the points,
 * A3[c] and B3[c] are 3 x the sums of w v and (1-w) v, det = AA BB - AB^2 (81 x the true one).
 * With p_g the prefix sums at the run bounds and t the total, 3 sum(w v) = 3t - p1 - p2 - p3. */
typedef struct split_system {
    double AA, AB, BB, det;
    double A3[3], B3[3];
} split_system;

/* Returns 0 when the system is singular (all points in runs of one weight). */
static int split_system_init(int T, const double prefix[][3], const int bounds[5],
                             split_system *sys)
{
    double n0 = bounds[1], n1 = bounds[2] - bounds[1], n2 = bounds[3] - bounds[2],
           n3 = bounds[4] - bounds[3];
    sys->AA = n1 + 4 * n2 + 9 * n3;
    sys->AB = 2 * (n1 + n2);
    sys->BB = 9 * n0 + 4 * n1 + n2;
    sys->det = sys->AA * sys->BB - sys->AB * sys->AB;
    if (sys->det <= 0)
        return 0;
    const double *p1 = prefix[bounds[1]], *p2 = prefix[bounds[2]], *p3 = prefix[bounds[3]];
    for (int c = 0; c < T; c++) {
        sys->B3[c] = p1[c] + p2[c] + p3[c];
        sys->A3[c] = 3 * prefix[bounds[4]][c] - sys->B3[c];
    }
    return 1;
}

/* Whether the unconstrained least-squares error of the split (without the constant sum of
 * v^2), -Q / det, is below err: a lower bound of its error with clamped endpoints. */
static int split_may_beat(int T, const split_system *sys, double err)
{
    double q = 0;
    for (int c = 0; c < T; c++) {
        double xa = sys->A3[c], xb = sys->B3[c];
        q += sys->BB * xa * xa - 2 * sys->AB * xa * xb + sys->AA * xb * xb;
    }
    return -q < err * sys->det;
}

/* Least-squares endpoints of the split, clamped to [0, 255], and their error without the
 * constant sum of v^2. */
static void fit_split(int T, const split_system *sys, split_fit *fit)
{
    double scale = 3.0 / sys->det;
    fit->err = 0;
    for (int c = 0; c < T; c++) {
        double xa = sys->A3[c], xb = sys->B3[c];
        double a = clamp_real((sys->BB * xa - sys->AB * xb) * scale);
        double b = clamp_real((sys->AA * xb - sys->AB * xa) * scale);
        fit->a[c] = a;
        fit->b[c] = b;
        fit->err += (a * a * sys->AA + 2 * a * b * sys->AB + b * b * sys->BB) / 9 -
                    2 * (a * xa + b * xb) / 3;
    }
}

/* Screening a split needs only its bound q (split_may_beat) and det. With xa = 3t - xb and
 * AA + 2 AB + BB = 9n (the run lengths add up to n),
 *     q = sum_c BB xa^2 - 2 AB xa xb + AA xb^2 = 9 BB |t|^2 - 6 (BB + AB) t.xb + 9n |xb|^2,
 * and with xb = p_i + p_j + p_k (prefix sums at the run bounds) both dot products follow from
 * the Gram matrix G[a][b] = p_a . p_b of the prefix sums (t = p_n). Every term is an integer
 * far below 2^53, so q and det are exact, equal to what split_system_init and split_may_beat
 * compute, and a screened split passes exactly when their test with the same err passes. */
#define GRAM_N (CLUSTER_FIT_MAX_POSITIONS + 4) /* columns 0 .. n + 3 (lanes past n are 0) */

typedef struct split_gram {
    int n;
    double g[CLUSTER_FIT_MAX_POSITIONS + 1][GRAM_N];
    double diag[GRAM_N]; /* g[k][k] */
} split_gram;

static void gram_init(const double prefix[][3], int n, split_gram *gm)
{
    memset(gm, 0, sizeof *gm);
    gm->n = n;
    for (int a = 0; a <= n; a++)
        for (int b = 0; b <= n; b++)
            gm->g[a][b] = prefix[a][0] * prefix[b][0] + prefix[a][1] * prefix[b][1] +
                          prefix[a][2] * prefix[b][2];
    for (int k = 0; k <= n; k++)
        gm->diag[k] = gm->g[k][k];
}

static int lowest_bit(uint32_t m)
{
#if defined(__GNUC__)
    return __builtin_ctz(m);
#else
    int b = 0;
    while (!(m & 1u)) {
        m >>= 1;
        b++;
    }
    return b;
#endif
}

/* Bit k - j of the result: split (i, j, k), j <= k <= n, has det > 0 and a bound below err.
 * Two paths with the same exact arithmetic: AVX2 (four splits at a time, when the CPU has it)
 * and portable code. */
static uint32_t row_mask_portable(const split_gram *gm, int i, int j, double err)
{
    const int n = gm->n;
    const double *gn = gm->g[n], *gi = gm->g[i], *gj = gm->g[j];
    const double n0 = i, n1 = j - i, t2 = gn[n];
    uint32_t mask = 0;
    for (int k = j; k <= n; k++) {
        double n2 = k - j, n3 = n - k;
        double AA = n1 + 4 * n2 + 9 * n3, AB = 2 * (n1 + n2), BB = 9 * n0 + 4 * n1 + n2;
        double det = AA * BB - AB * AB;
        double x1 = gn[i] + gn[j] + gn[k];
        double x2 = gi[i] + gj[j] + gm->diag[k] + 2 * (gi[j] + gi[k] + gj[k]);
        double q = 9 * t2 * BB - 6 * (BB + AB) * x1 + 9.0 * n * x2;
        if (det > 0 && -q < err * det)
            mask |= 1u << (k - j);
    }
    return mask;
}

#if defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__))
#include <immintrin.h>
#define LSQ_AVX2 __attribute__((target("avx2")))

static LSQ_AVX2 uint32_t row_mask_avx2(const split_gram *gm, int i, int j, double err)
{
    const int n = gm->n;
    const double *gn = gm->g[n], *gi = gm->g[i], *gj = gm->g[j];
    const __m256d lane = _mm256_set_pd(3, 2, 1, 0), zero = _mm256_setzero_pd();
    const __m256d n0 = _mm256_set1_pd(i), n1 = _mm256_set1_pd(j - i), fn = _mm256_set1_pd(n);
    const __m256d fj = _mm256_set1_pd(j), vErr = _mm256_set1_pd(err);
    const __m256d c2 = _mm256_set1_pd(2), c4 = _mm256_set1_pd(4), c6 = _mm256_set1_pd(6);
    const __m256d c9 = _mm256_set1_pd(9), t2x9 = _mm256_set1_pd(9 * gn[n]);
    const __m256d nx9 = _mm256_set1_pd(9.0 * n), x1_ij = _mm256_set1_pd(gn[i] + gn[j]);
    const __m256d x2_ij = _mm256_set1_pd(gi[i] + gj[j] + 2 * gi[j]);
    const __m256d BB0 = _mm256_add_pd(_mm256_mul_pd(c9, n0), _mm256_mul_pd(c4, n1));
    uint32_t mask = 0;
    for (int l0 = 0; l0 <= n - j; l0 += 4) {
        int k0 = j + l0;
        __m256d k = _mm256_add_pd(_mm256_set1_pd(k0), lane);
        __m256d n2 = _mm256_sub_pd(k, fj), n3 = _mm256_sub_pd(fn, k);
        __m256d AA = _mm256_add_pd(_mm256_add_pd(n1, _mm256_mul_pd(c4, n2)), _mm256_mul_pd(c9, n3));
        __m256d AB = _mm256_mul_pd(c2, _mm256_add_pd(n1, n2));
        __m256d BB = _mm256_add_pd(BB0, n2);
        __m256d det = _mm256_sub_pd(_mm256_mul_pd(AA, BB), _mm256_mul_pd(AB, AB));
        __m256d x1 = _mm256_add_pd(x1_ij, _mm256_loadu_pd(gn + k0));
        __m256d cross = _mm256_add_pd(_mm256_loadu_pd(gi + k0), _mm256_loadu_pd(gj + k0));
        __m256d x2 = _mm256_add_pd(_mm256_add_pd(x2_ij, _mm256_loadu_pd(gm->diag + k0)),
                                   _mm256_mul_pd(c2, cross));
        __m256d q = _mm256_add_pd(_mm256_sub_pd(_mm256_mul_pd(t2x9, BB),
                                                _mm256_mul_pd(_mm256_mul_pd(c6, _mm256_add_pd(BB, AB)), x1)),
                                  _mm256_mul_pd(nx9, x2));
        __m256d ok = _mm256_and_pd(_mm256_cmp_pd(det, zero, _CMP_GT_OQ),
                                   _mm256_cmp_pd(_mm256_sub_pd(zero, q), _mm256_mul_pd(vErr, det),
                                                 _CMP_LT_OQ));
        ok = _mm256_and_pd(ok, _mm256_cmp_pd(k, fn, _CMP_LE_OQ));
        mask |= (uint32_t)_mm256_movemask_pd(ok) << l0;
    }
    return mask;
}

static int lsq_avx2_available(void)
{
    return __builtin_cpu_supports("avx2");
}
#else
static uint32_t row_mask_avx2(const split_gram *gm, int i, int j, double err)
{
    return row_mask_portable(gm, i, j, err);
}

static int lsq_avx2_available(void)
{
    return 0;
}
#endif

/* Every split is scored by its unconstrained error first; only splits whose bound beats the
 * best so far pay for the clamped fit, so the result is the same as fitting them all. The
 * bound is screened a row (fixed i, j) at a time against the best error at the row's start;
 * the best only falls inside a row, so every split the exact test below keeps is among
 * those screened in, and the result is that of testing the splits one by one. */
/* Sum of squared deviations from their mean of the sorted points [a, b): the least error of
 * any fit that gives them one value. sq[m] = sum of |v|^2 over the first m points. */
static double run_spread(const split_gram *gm, const double *sq, int a, int b)
{
    if (b <= a)
        return 0;
    double d2 = gm->g[b][b] - 2 * gm->g[a][b] + gm->g[a][a]; /* |p_b - p_a|^2 */
    return (sq[b] - sq[a]) - d2 / (b - a);
}

static void cluster_fit(const pvtc_block *blk, const double axis[3], pvtc_code *code)
{
    int order[PVTC_MAX_POSITIONS], n = blk->npos;
    double prefix[PVTC_MAX_POSITIONS + 1][3] = {{0}}, sq[PVTC_MAX_POSITIONS + 1] = {0};
    split_gram gm;
    uint32_t (*row_mask)(const split_gram *, int, int, double) =
        lsq_avx2_available() ? row_mask_avx2 : row_mask_portable;
    sort_by_projection(blk, axis, order);
    for (int i = 0; i < n; i++) {
        sq[i + 1] = sq[i];
        for (int c = 0; c < 3; c++) {
            double v = c < blk->T ? blk->v[order[i]][c] : 0;
            prefix[i + 1][c] = prefix[i][c] + v;
            sq[i + 1] += v * v;
        }
    }
    gram_init((const double(*)[3])prefix, n, &gm);
    split_fit best = {{0}, {0}, INFINITY}, fit;
    split_system sys;
    /* Runs [0, i) and [i, j) each take one palette value, so no split of a row fits better
     * than their spreads allow (fit errors leave out the constant sum of |v|^2); a spread only
     * grows as its run does, so once the bound fails, the rest of the j (or i) loop fails
     * too. The margin covers rounding: only splits that cannot win are skipped. */
    const double margin = 1e-9 * (1.0 + sq[n]);
    for (int i = 0; i <= n; i++) {
        double spread0 = run_spread(&gm, sq, 0, i) - sq[n];
        if (spread0 > best.err + margin)
            break;
        for (int j = i; j <= n; j++) {
            if (spread0 + run_spread(&gm, sq, i, j) > best.err + margin)
                break;
            for (uint32_t m = row_mask(&gm, i, j, best.err); m; m &= m - 1) {
                const int bounds[5] = {0, i, j, j + lowest_bit(m), n};
                if (!split_system_init(blk->T, (const double(*)[3])prefix, bounds, &sys) ||
                    !split_may_beat(blk->T, &sys, best.err))
                    continue;
                fit_split(blk->T, &sys, &fit);
                if (fit.err < best.err)
                    best = fit;
            }
        }
    }
    for (int c = 0; c < blk->T; c++) {
        int bits = pvtc_channel_bits(blk->T, c);
        code->qa[c] = quantize_real(bits, best.a[c]);
        code->qb[c] = quantize_real(bits, best.b[c]);
    }
}

/* ---- refinement loop --------------------------------------------------------------------- */

static int same_endpoints(int T, const pvtc_code *x, const pvtc_code *y)
{
    for (int c = 0; c < T; c++)
        if (x->qa[c] != y->qa[c] || x->qb[c] != y->qb[c])
            return 0;
    return 1;
}

/* Indices follow from the endpoints alone (pvtc_assign_indices), so a step that leaves the
 * endpoints as they are changes nothing: it is skipped, and an unchanged search ends the
 * loop (the assignment would give the same error, and the loop stops on no improvement). */
static uint32_t refine(const pvtc_block *blk, pvtc_code *code)
{
    uint32_t err = pvtc_assign_indices(blk, code);
    index_stats st;
    pvtc_code trial;
    for (int it = 0; it < LSQ_MAX_ITERATIONS && err > 0; it++) {
        gather_stats(blk, code, &st);
        trial = *code;
        if (least_squares_endpoints(blk->T, &st, &trial) &&
            !same_endpoints(blk->T, &trial, code)) {
            uint32_t e = pvtc_assign_indices(blk, &trial);
            if (e < err) {
                *code = trial;
                err = e;
                gather_stats(blk, code, &st);
            }
        }
        trial = *code;
        search_neighbourhood(blk->T, &st, &trial);
        if (same_endpoints(blk->T, &trial, code))
            break;
        uint32_t e = pvtc_assign_indices(blk, &trial);
        if (e >= err)
            break;
        *code = trial;
        err = e;
    }
    return err;
}

uint32_t pvtc_encode_block_lsq(const pvtc_block *blk, pvtc_code *code)
{
    pvtc_code bbox, from_bbox, from_axis;
    uint32_t bbox_err = pvtc_encode_block_bbox(blk, &bbox);
    *code = bbox;
    if (bbox_err == 0)
        return 0;
    uint32_t axis_err;
    double axis[3] = {0.0, 0.0, 0.0};
    if (principal_endpoints(blk, &from_axis, axis)) {
        axis_err = refine(blk, &from_axis);
        uint32_t per_value = blk->T == 3 ? CLUSTER_FIT_MIN_ERROR_PER_VALUE_T3
                                         : CLUSTER_FIT_MIN_ERROR_PER_VALUE_T2;
        if (blk->npos <= CLUSTER_FIT_MAX_POSITIONS &&
            axis_err > per_value * (uint32_t)(blk->npos * blk->T)) {
            pvtc_code from_clusters;
            cluster_fit(blk, axis, &from_clusters);
            uint32_t e = refine(blk, &from_clusters);
            if (e < axis_err) {
                axis_err = e;
                from_axis = from_clusters;
            }
        }
    } else {
        axis_err = fit_constant(blk, &from_axis);
    }
    from_bbox = bbox;
    uint32_t refined_bbox_err = refine(blk, &from_bbox);
    uint32_t best = bbox_err;
    if (axis_err < best) {
        *code = from_axis;
        best = axis_err;
    }
    if (refined_bbox_err < best) {
        *code = from_bbox;
        best = refined_bbox_err;
    }
    return best;
}
