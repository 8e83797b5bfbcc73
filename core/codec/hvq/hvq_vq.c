/* core/codec/hvq/hvq_vq.c - codebook training for the hvq codec: PCA splitting (the seed's
 * section 2.3), LBG refinement, rounding to int16 entries, and the exact nearest-entry search.
 *
 * Determinism: every sum that decides something is either an exact integer sum (covariance,
 * means, cluster sums: int64, so the order of accumulation and the number of threads do not
 * matter) or computed per vector in a fixed order; threads only split work between vectors. */
#include "codec/hvq/hvq_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LBG_MAX_ITERATIONS 100
#define POWER_ITERATIONS 100
#define ASSIGN_CHUNK 1024

/* ---- PCA splitting ------------------------------------------------------------------------- */

typedef struct cluster_sums {
    const int16_t *vectors;
    const uint32_t *members;  /* the cluster's vector indices */
    size_t count;
    unsigned d;
    unsigned parts;
    int full;                 /* 0: only the diagonal of the covariance */
    int64_t *part_cov;        /* parts x d x d (upper triangle used) */
    int64_t *part_sum;        /* parts x d */
} cluster_sums;

static void cluster_sums_part(void *ctx, size_t part)
{
    cluster_sums *c = ctx;
    unsigned d = c->d;
    size_t lo = c->count * part / c->parts, hi = c->count * (part + 1) / c->parts;
    int64_t *cov = c->part_cov + part * d * d, *sum = c->part_sum + part * d;
    memset(cov, 0, sizeof *cov * d * d);
    memset(sum, 0, sizeof *sum * d);
    int32_t x[64];
    for (size_t i = lo; i < hi; i++) {
        const int16_t *v = c->vectors + (size_t)c->members[i] * d;
        for (unsigned a = 0; a < d; a++) {
            x[a] = v[a];
            sum[a] += x[a];
        }
        for (unsigned a = 0; a < d; a++) {
            int64_t *row = cov + a * d;
            unsigned end = c->full ? d : a + 1;
            for (unsigned b = a; b < end; b++)
                row[b] += (int64_t)(x[a] * x[b]);
        }
    }
}

/* Mean, squared-error distortion and (cov not NULL) covariance about the mean (d x d) of a
 * cluster, from exact integer sums. 0: out of memory. */
static int cluster_stats(const int16_t *vectors, const uint32_t *members, size_t count,
                         unsigned d, unsigned threads, double *mean, double *cov, double *sse)
{
    double diag[64];
    unsigned parts = threads < 1 ? 1 : threads;
    if ((size_t)parts > count / 4096 + 1)
        parts = (unsigned)(count / 4096 + 1);
    cluster_sums c = {vectors, members, count, d, parts, cov != NULL,
                      malloc(sizeof(int64_t) * parts * d * d), malloc(sizeof(int64_t) * parts * d)};
    if (!c.part_cov || !c.part_sum) {
        free(c.part_cov);
        free(c.part_sum);
        return 0;
    }
    hvq_parallel_for(threads, parts, cluster_sums_part, &c);
    for (unsigned p = 1; p < parts; p++) {
        for (unsigned a = 0; a < d * d; a++)
            c.part_cov[a] += c.part_cov[p * d * d + a];
        for (unsigned a = 0; a < d; a++)
            c.part_sum[a] += c.part_sum[p * d + a];
    }
    double n = (double)count, trace = 0;
    for (unsigned a = 0; a < d; a++)
        mean[a] = (double)c.part_sum[a] / n;
    for (unsigned a = 0; a < d; a++) {
        diag[a] = (double)c.part_cov[a * d + a] - (double)c.part_sum[a] * mean[a];
        trace += diag[a] > 0 ? diag[a] : 0;
        for (unsigned b = a; cov && b < d; b++)
            cov[a * d + b] = cov[b * d + a] =
                b == a ? diag[a] : (double)c.part_cov[a * d + b] - (double)c.part_sum[a] * mean[b];
    }
    *sse = trace;
    free(c.part_cov);
    free(c.part_sum);
    return 1;
}

/* Principal eigenvector of a covariance by power iteration from the axis of largest variance.
 * 0 when the covariance is zero. */
static int principal_axis(const double *cov, unsigned d, double *axis)
{
    unsigned start = 0;
    for (unsigned a = 1; a < d; a++)
        if (cov[a * d + a] > cov[start * d + start])
            start = a;
    if (!(cov[start * d + start] > 0))
        return 0;
    double next[64];
    for (unsigned a = 0; a < d; a++)
        axis[a] = a == start;
    for (int it = 0; it < POWER_ITERATIONS; it++) {
        double norm = 0, change = 0;
        for (unsigned a = 0; a < d; a++) {
            double s = 0;
            for (unsigned b = 0; b < d; b++)
                s += cov[a * d + b] * axis[b];
            next[a] = s;
            norm += s * s;
        }
        if (!(norm > 0))
            return 0;
        norm = sqrt(norm);
        for (unsigned a = 0; a < d; a++) {
            next[a] /= norm;
            change += (next[a] - axis[a]) * (next[a] - axis[a]);
            axis[a] = next[a];
        }
        if (change < 1e-20)
            break;
    }
    return 1;
}

typedef struct pca_cluster {
    size_t start, count;
    double sse;
    int splittable;
} pca_cluster;

cdvr_status hvq_pca_split(const int16_t *vectors, size_t n, unsigned d, unsigned k,
                          unsigned threads, float *centroids, unsigned *kout, cdvr_error *err)
{
    *kout = 0;
    if (n == 0 || k == 0)
        return CDVR_OK;
    uint32_t *members = malloc(n * sizeof *members), *tmp = malloc(n * sizeof *tmp);
    pca_cluster *cl = malloc(k * sizeof *cl);
    double *means = malloc(sizeof(double) * k * d), *cov = malloc(sizeof(double) * d * d);
    double axis[64];
    unsigned nc = 1;
    int ok = members && tmp && cl && means && cov;
    for (size_t i = 0; ok && i < n; i++)
        members[i] = (uint32_t)i;
    if (ok) {
        cl[0] = (pca_cluster){0, n, 0, 1};
        ok = cluster_stats(vectors, members, n, d, threads, means, NULL, &cl[0].sse);
    }
    while (ok && nc < k) {
        unsigned c = nc;
        for (unsigned j = 0; j < nc; j++)
            if (cl[j].splittable && cl[j].sse > 0 && (c == nc || cl[j].sse > cl[c].sse))
                c = j;
        if (c == nc)
            break; /* every cluster is a single point: fewer distinct vectors than k */
        const uint32_t *mem = members + cl[c].start;
        double sse;
        ok = cluster_stats(vectors, mem, cl[c].count, d, threads, means + (size_t)c * d, cov,
                           &sse);
        if (!ok || !principal_axis(cov, d, axis)) {
            cl[c].splittable = 0;
            continue;
        }
        size_t left = 0, right = cl[c].count;
        for (size_t i = 0; i < cl[c].count; i++) {
            const int16_t *v = vectors + (size_t)mem[i] * d;
            double proj = 0;
            for (unsigned a = 0; a < d; a++)
                proj += (v[a] - means[(size_t)c * d + a]) * axis[a];
            if (proj < 0)
                tmp[left++] = mem[i];
            else
                tmp[--right] = mem[i];
        }
        if (left == 0 || left == cl[c].count) {
            cl[c].splittable = 0; /* rounding put everything on one side */
            continue;
        }
        /* right half was filled backwards: restore vector order */
        for (size_t i = left, j = cl[c].count - 1; i < j; i++, j--) {
            uint32_t t = tmp[i];
            tmp[i] = tmp[j];
            tmp[j] = t;
        }
        memcpy(members + cl[c].start, tmp, cl[c].count * sizeof *tmp);
        cl[nc] = (pca_cluster){cl[c].start + left, cl[c].count - left, 0, 1};
        cl[c].count = left;
        ok = cluster_stats(vectors, members + cl[c].start, cl[c].count, d, threads,
                           means + (size_t)c * d, NULL, &cl[c].sse) &&
             cluster_stats(vectors, members + cl[nc].start, cl[nc].count, d, threads,
                           means + (size_t)nc * d, NULL, &cl[nc].sse);
        nc++;
    }
    for (unsigned j = 0; ok && j < nc; j++)
        for (unsigned a = 0; a < d; a++)
            centroids[(size_t)j * d + a] = (float)means[(size_t)j * d + a];
    if (ok)
        *kout = nc;
    free(members);
    free(tmp);
    free(cl);
    free(means);
    free(cov);
    return ok ? CDVR_OK : cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory splitting "
                                         "%zu vectors of %u values", n, d);
}

/* ---- LBG ----------------------------------------------------------------------------------- */

/* x . c with 8 partial sums in a fixed order (d is a multiple of 8). */
static float dot8(const float *restrict x, const float *restrict c, unsigned d)
{
    float a0 = 0, a1 = 0, a2 = 0, a3 = 0, a4 = 0, a5 = 0, a6 = 0, a7 = 0;
    for (unsigned a = 0; a < d; a += 8, x += 8, c += 8) {
        a0 += x[0] * c[0];
        a1 += x[1] * c[1];
        a2 += x[2] * c[2];
        a3 += x[3] * c[3];
        a4 += x[4] * c[4];
        a5 += x[5] * c[5];
        a6 += x[6] * c[6];
        a7 += x[7] * c[7];
    }
    return ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7));
}

typedef struct lbg_assign {
    const float *vectors;
    const float *norms;      /* |x|^2 per vector */
    const float *centroids;
    float *cnorms;           /* |c|^2 per centroid */
    size_t n;
    unsigned d, k;
    uint32_t *index;         /* out: nearest centroid */
    float *dist;             /* out: its squared distance (>= 0) */
} lbg_assign;

/* Nearest centroid by |c|^2 - 2 x.c (ties: the lowest index). */
static void lbg_assign_chunk(void *ctx, size_t chunk)
{
    lbg_assign *a = ctx;
    size_t lo = chunk * ASSIGN_CHUNK, hi = lo + ASSIGN_CHUNK < a->n ? lo + ASSIGN_CHUNK : a->n;
    for (size_t i = lo; i < hi; i++) {
        const float *x = a->vectors + i * a->d;
        uint32_t best = 0;
        float best_s = INFINITY;
        for (uint32_t j = 0; j < a->k; j++) {
            float sj = a->cnorms[j] - 2 * dot8(x, a->centroids + (size_t)j * a->d, a->d);
            if (sj < best_s) {
                best = j;
                best_s = sj;
            }
        }
        float dist = a->norms[i] + best_s;
        a->index[i] = best;
        a->dist[i] = dist > 0 ? dist : 0;
    }
}

static double lbg_assign_all(lbg_assign *a, unsigned threads)
{
    for (unsigned j = 0; j < a->k; j++) {
        const float *c = a->centroids + (size_t)j * a->d;
        a->cnorms[j] = dot8(c, c, a->d);
    }
    hvq_parallel_for(threads, (a->n + ASSIGN_CHUNK - 1) / ASSIGN_CHUNK, lbg_assign_chunk, a);
    double total = 0;
    for (size_t i = 0; i < a->n; i++)
        total += a->dist[i];
    return total;
}

static void lbg_sums(const int16_t *vectors, size_t n, unsigned d, unsigned k,
                     const uint32_t *index, int64_t *sums, uint64_t *counts)
{
    memset(sums, 0, sizeof *sums * k * d);
    memset(counts, 0, sizeof *counts * k);
    for (size_t i = 0; i < n; i++) {
        int64_t *s = sums + (size_t)index[i] * d;
        const int16_t *v = vectors + i * d;
        for (unsigned a = 0; a < d; a++)
            s[a] += v[a];
        counts[index[i]]++;
    }
}

/* Empty clusters: re-seed each (in index order) with the farthest vector not used yet, or
 * drop it when no vector is off its centroid. Returns the new k; renumbers index. */
static unsigned lbg_fix_empty(const float *fv, size_t n, unsigned d, unsigned k, float *centroids,
                              const uint64_t *counts, uint32_t *index, float *dist,
                              hvq_vq_report *rep)
{
    uint32_t map[CDVR_HVQ_K_MAX];
    unsigned kept = 0;
    for (unsigned j = 0; j < k; j++) {
        if (counts[j] == 0) {
            size_t far = n;
            for (size_t i = 0; i < n; i++)
                if (dist[i] > 0 && (far == n || dist[i] > dist[far]))
                    far = i;
            if (far == n) {
                map[j] = UINT32_MAX;
                rep->dropped++;
                continue;
            }
            dist[far] = -1; /* used */
            memcpy(centroids + (size_t)j * d, fv + far * d, sizeof *fv * d);
            rep->reseeded++;
        }
        map[j] = kept;
        if (kept != j)
            memmove(centroids + (size_t)kept * d, centroids + (size_t)j * d, sizeof *fv * d);
        kept++;
    }
    for (size_t i = 0; kept != k && i < n; i++)
        index[i] = map[index[i]];
    return kept;
}

cdvr_status hvq_lbg(const int16_t *vectors, size_t n, unsigned d, float *centroids, unsigned *k,
                    double eps, unsigned threads, int64_t *sums, uint64_t *counts,
                    hvq_vq_report *rep, cdvr_error *err)
{
    if (n == 0 || *k == 0)
        return CDVR_OK;
    float *fv = malloc(sizeof *fv * n * d), *dist = malloc(sizeof *dist * n);
    float *norms = malloc(sizeof *norms * n), *cnorms = malloc(sizeof *cnorms * *k);
    uint32_t *index = malloc(sizeof *index * n);
    if (!fv || !dist || !norms || !cnorms || !index) {
        free(fv);
        free(dist);
        free(norms);
        free(cnorms);
        free(index);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for LBG on %zu vectors",
                              n);
    }
    for (size_t i = 0; i < n * d; i++)
        fv[i] = vectors[i];
    for (size_t i = 0; i < n; i++)
        norms[i] = dot8(fv + i * d, fv + i * d, d);
    lbg_assign a = {fv, norms, centroids, cnorms, n, d, *k, index, dist};
    double before = lbg_assign_all(&a, threads), after = before;
    int it = 0;
    while (before > 0 && it < LBG_MAX_ITERATIONS) {
        it++;
        lbg_sums(vectors, n, d, a.k, index, sums, counts);
        for (unsigned j = 0; j < a.k; j++)
            for (unsigned c = 0; counts[j] && c < d; c++)
                centroids[(size_t)j * d + c] =
                    (float)((double)sums[(size_t)j * d + c] / (double)counts[j]);
        a.k = lbg_fix_empty(fv, n, d, a.k, centroids, counts, index, dist, rep);
        after = lbg_assign_all(&a, threads);
        if (fabs(before - after) / before < eps)
            break;
        before = after;
    }
    lbg_sums(vectors, n, d, a.k, index, sums, counts);
    /* clusters still empty at the end are dropped (sums and counts move with them) */
    unsigned kept = 0;
    for (unsigned j = 0; j < a.k; j++) {
        if (counts[j] == 0) {
            rep->dropped++;
            continue;
        }
        if (kept != j) {
            memmove(centroids + (size_t)kept * d, centroids + (size_t)j * d, sizeof *fv * d);
            memmove(sums + (size_t)kept * d, sums + (size_t)j * d, sizeof *sums * d);
            counts[kept] = counts[j];
        }
        kept++;
    }
    a.k = kept;
    *k = a.k;
    rep->lbg_iterations = it;
    rep->distortion = after;
    free(fv);
    free(dist);
    free(norms);
    free(cnorms);
    free(index);
    return CDVR_OK;
}

/* ---- training and assignment ---------------------------------------------------------------- */

/* round(s / q), halves away from zero, q > 0. */
static int64_t round_div(int64_t s, int64_t q)
{
    return s >= 0 ? (2 * s + q) / (2 * q) : -((-2 * s + q) / (2 * q));
}

static int16_t clamp_s16(double v)
{
    return v < -32768 ? -32768 : v > 32767 ? 32767 : (int16_t)v;
}

cdvr_status hvq_vq_train(const int16_t *vectors, size_t n, unsigned d, unsigned k, int scale,
                         double eps, uint32_t train, unsigned threads, int16_t *codebook,
                         unsigned *kout, hvq_vq_report *rep, cdvr_error *err)
{
    memset(rep, 0, sizeof *rep);
    *kout = 0;
    if (d > 64 || d % 8 || k > CDVR_HVQ_K_MAX || scale < 1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "hvq: codebook of %u entries of %u values, "
                              "scale %d (at most %u entries of 8, 16, .. 64)", k, d, scale, CDVR_HVQ_K_MAX);
    if (n == 0 || k == 0)
        return CDVR_OK;
    if ((uint64_t)k > ((uint64_t)n + HVQ_VECTORS_PER_ENTRY - 1) / HVQ_VECTORS_PER_ENTRY)
        k = (unsigned)((n + HVQ_VECTORS_PER_ENTRY - 1) / HVQ_VECTORS_PER_ENTRY);
    size_t m = (train && n > train) ? train : n;
    int16_t *sample = NULL;
    const int16_t *use = vectors;
    if (m < n) {
        sample = malloc(sizeof *sample * m * d);
        if (!sample)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory sampling vectors");
        for (size_t j = 0; j < m; j++)
            memcpy(sample + j * d, vectors + (size_t)((uint64_t)j * n / m) * d,
                   sizeof *sample * d);
        use = sample;
    }
    float *centroids = malloc(sizeof *centroids * k * d);
    int64_t *sums = malloc(sizeof *sums * k * d);
    uint64_t *counts = malloc(sizeof *counts * k);
    unsigned kk = 0;
    cdvr_status st = (centroids && sums && counts)
                         ? hvq_pca_split(use, m, d, k, threads, centroids, &kk, err)
                         : cdvr_error_set(err, CDVR_ERR_NOMEM, "hvq: out of memory for a "
                                          "codebook of %u entries", k);
    rep->pca_entries = kk;
    if (st == CDVR_OK)
        st = hvq_lbg(use, m, d, centroids, &kk, eps, threads, sums, counts, rep, err);
    for (unsigned j = 0; st == CDVR_OK && j < kk; j++)
        for (unsigned a = 0; a < d; a++) {
            size_t i = (size_t)j * d + a;
            codebook[i] = counts[j] ? clamp_s16((double)round_div(sums[i], (int64_t)counts[j] *
                                                                               scale))
                                    : clamp_s16(round((double)centroids[i] / scale));
        }
    if (st == CDVR_OK) {
        *kout = kk;
        rep->entries = kk;
    }
    free(sample);
    free(centroids);
    free(sums);
    free(counts);
    return st;
}

typedef struct exact_assign {
    const int16_t *vectors, *codebook;
    size_t n;
    unsigned d, k;
    int scale;
    uint16_t *index;
} exact_assign;

static int64_t exact_dist(const int16_t *v, const int16_t *c, unsigned d, int scale, int64_t bound)
{
    int64_t s = 0;
    for (unsigned a = 0; a < d; a++) {
        int64_t t = (int64_t)v[a] - (int64_t)scale * c[a];
        s += t * t;
        if ((a & 7) == 7 && s > bound)
            return s;
    }
    return s;
}

static void exact_assign_chunk(void *ctx, size_t chunk)
{
    exact_assign *a = ctx;
    size_t lo = chunk * ASSIGN_CHUNK, hi = lo + ASSIGN_CHUNK < a->n ? lo + ASSIGN_CHUNK : a->n;
    for (size_t i = lo; i < hi; i++) {
        const int16_t *v = a->vectors + i * a->d;
        uint32_t best = 0;
        int64_t best_d = exact_dist(v, a->codebook, a->d, a->scale, INT64_MAX);
        for (uint32_t j = 1; j < a->k && best_d > 0; j++) {
            int64_t dj = exact_dist(v, a->codebook + (size_t)j * a->d, a->d, a->scale, best_d);
            if (dj < best_d) {
                best = j;
                best_d = dj;
            }
        }
        a->index[i] = (uint16_t)best;
    }
}

void hvq_vq_assign(const int16_t *vectors, size_t n, unsigned d, const int16_t *codebook,
                   unsigned k, int scale, unsigned threads, uint16_t *index)
{
    exact_assign a = {vectors, codebook, n, d, k, scale, index};
    hvq_parallel_for(threads, (n + ASSIGN_CHUNK - 1) / ASSIGN_CHUNK, exact_assign_chunk, &a);
}
