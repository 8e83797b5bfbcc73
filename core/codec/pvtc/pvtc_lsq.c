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
#define SEARCH_RADIUS 2
#define CLUSTER_FIT_MAX_POSITIONS 16
#define CLUSTER_FIT_MIN_ERROR_PER_VALUE 1u

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
    double count[4];
    double sum[3][4];   /* per channel, per index: sum of v */
    double sumsq[3][4]; /* per channel, per index: sum of v^2 */
} index_stats;

static void gather_stats(const pvtc_block *blk, const pvtc_code *code, index_stats *st)
{
    memset(st, 0, sizeof *st);
    for (int i = 0; i < blk->npos; i++) {
        int k = code->index[i];
        st->count[k] += 1.0;
        for (int c = 0; c < blk->T; c++) {
            double v = blk->v[i][c];
            st->sum[c][k] += v;
            st->sumsq[c][k] += v * v;
        }
    }
}

/* Least-squares endpoints for the current indices; returns 0 if the system is singular (all
 * positions share one palette weight). */
static int least_squares_endpoints(int T, const index_stats *st, pvtc_code *code)
{
    double aa = 0.0, ab = 0.0, bb = 0.0;
    for (int k = 0; k < 4; k++) {
        double w = INDEX_WEIGHT[k];
        aa += st->count[k] * w * w;
        ab += st->count[k] * w * (1.0 - w);
        bb += st->count[k] * (1.0 - w) * (1.0 - w);
    }
    double det = aa * bb - ab * ab;
    if (fabs(det) < 1e-9)
        return 0;
    for (int c = 0; c < T; c++) {
        double ra = 0.0, rb = 0.0;
        for (int k = 0; k < 4; k++) {
            ra += INDEX_WEIGHT[k] * st->sum[c][k];
            rb += (1.0 - INDEX_WEIGHT[k]) * st->sum[c][k];
        }
        int bits = pvtc_channel_bits(T, c);
        code->qa[c] = quantize_real(bits, (bb * ra - ab * rb) / det);
        code->qb[c] = quantize_real(bits, (aa * rb - ab * ra) / det);
    }
    return 1;
}

/* Exact squared error of channel c with 8-bit endpoints a, b for the fixed indices. */
static double channel_error(const index_stats *st, int c, int a, int b)
{
    int pal[4];
    pvtc_palette(a, b, pal);
    double e = 0.0;
    for (int k = 0; k < 4; k++)
        e += st->count[k] * pal[k] * pal[k] - 2.0 * pal[k] * st->sum[c][k] + st->sumsq[c][k];
    return e;
}

/* With indices fixed the error separates by channel: per channel, the best quantised (a, b)
 * within SEARCH_RADIUS steps of the current pair. */
static void search_neighbourhood(int T, const index_stats *st, pvtc_code *code)
{
    for (int c = 0; c < T; c++) {
        int bits = pvtc_channel_bits(T, c), max = (1 << bits) - 1;
        int qa0 = code->qa[c], qb0 = code->qb[c];
        double best = channel_error(st, c, pvtc_expand(bits, qa0), pvtc_expand(bits, qb0));
        for (int qa = clamp_int(qa0 - SEARCH_RADIUS, 0, max);
             qa <= clamp_int(qa0 + SEARCH_RADIUS, 0, max); qa++)
            for (int qb = clamp_int(qb0 - SEARCH_RADIUS, 0, max);
                 qb <= clamp_int(qb0 + SEARCH_RADIUS, 0, max); qb++) {
                double e = channel_error(st, c, pvtc_expand(bits, qa), pvtc_expand(bits, qb));
                if (e < best) {
                    best = e;
                    code->qa[c] = qa;
                    code->qb[c] = qb;
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

/* Every split is scored by its unconstrained error first; only splits whose bound beats the
 * best so far pay for the clamped fit, so the result is the same as fitting them all. */
static void cluster_fit(const pvtc_block *blk, const double axis[3], pvtc_code *code)
{
    int order[PVTC_MAX_POSITIONS], n = blk->npos;
    double prefix[PVTC_MAX_POSITIONS + 1][3] = {{0}};
    sort_by_projection(blk, axis, order);
    for (int i = 0; i < n; i++)
        for (int c = 0; c < 3; c++)
            prefix[i + 1][c] = prefix[i][c] + (c < blk->T ? blk->v[order[i]][c] : 0);
    split_fit best = {{0}, {0}, INFINITY}, fit;
    split_system sys;
    for (int i = 0; i <= n; i++)
        for (int j = i; j <= n; j++)
            for (int k = j; k <= n; k++) {
                const int bounds[5] = {0, i, j, k, n};
                if (!split_system_init(blk->T, (const double(*)[3])prefix, bounds, &sys) ||
                    !split_may_beat(blk->T, &sys, best.err))
                    continue;
                fit_split(blk->T, &sys, &fit);
                if (fit.err < best.err)
                    best = fit;
            }
    for (int c = 0; c < blk->T; c++) {
        int bits = pvtc_channel_bits(blk->T, c);
        code->qa[c] = quantize_real(bits, best.a[c]);
        code->qb[c] = quantize_real(bits, best.b[c]);
    }
}

/* ---- refinement loop --------------------------------------------------------------------- */

static uint32_t refine(const pvtc_block *blk, pvtc_code *code)
{
    uint32_t err = pvtc_assign_indices(blk, code);
    index_stats st;
    pvtc_code trial;
    for (int it = 0; it < LSQ_MAX_ITERATIONS && err > 0; it++) {
        gather_stats(blk, code, &st);
        trial = *code;
        if (least_squares_endpoints(blk->T, &st, &trial)) {
            uint32_t e = pvtc_assign_indices(blk, &trial);
            if (e < err) {
                *code = trial;
                err = e;
                gather_stats(blk, code, &st);
            }
        }
        trial = *code;
        search_neighbourhood(blk->T, &st, &trial);
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
        /* the cluster fit rarely improves a fit that is already within 1 per value (RMS),
         * and it is most of the encoder's time: measured on viscous fingers S1T3, skipping
         * it there costs 0.001 dB and saves about a sixth of the time */
        if (blk->npos <= CLUSTER_FIT_MAX_POSITIONS &&
            axis_err > CLUSTER_FIT_MIN_ERROR_PER_VALUE * (uint32_t)(blk->npos * blk->T)) {
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
