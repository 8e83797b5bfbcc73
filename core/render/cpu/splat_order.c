/* core/render/cpu/splat_order.c - back-to-front voxel orders for splatting (cdvr/splat.h):
 * axis-aligned sheets, the seed's extended DDA (Fig. 6), and exact depth sorts (radix and the
 * quicksort baseline); and the wrong-order fraction of an order. */
#include "cdvr/splat.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Components below this fraction of the largest count as zero in the DDA. */
#define DDA_ZERO_RATIO 1e-9

static const char *const how_names[] = {"dda", "axis", "sort", "quicksort"};

const char *cdvr_splat_how_name(cdvr_splat_how how)
{
    return (unsigned)how < 4 ? how_names[how] : "?";
}

int cdvr_splat_how_parse(const char *name, cdvr_splat_how *how)
{
    for (int i = 0; i < 4; i++)
        if (strcmp(name, how_names[i]) == 0) {
            *how = (cdvr_splat_how)i;
            return 1;
        }
    return 0;
}

/* ---- the order being built ------------------------------------------------------------- */

typedef struct order_sink {
    uint32_t *out;
    size_t count, capacity;
    const uint8_t *voxels; /* NULL: every voxel listed */
    const uint8_t *keep;
} order_sink;

static inline void sink_emit(order_sink *s, size_t lin)
{
    if (s->voxels && !s->keep[s->voxels[lin]])
        return;
    if (s->count < s->capacity) /* a miscount is reported by the caller, never overruns */
        s->out[s->count] = (uint32_t)lin;
    s->count++;
}

/* One axis of a (sub)box in traversal order: off[r] = index of rank r (far to near) times the
 * axis stride. */
typedef struct axis_seq {
    size_t n;
    size_t *off;
} axis_seq;

static void seq_free(axis_seq seq[3])
{
    for (int a = 0; a < 3; a++) {
        free(seq[a].off);
        seq[a].off = NULL;
    }
}

/* Indices lo..hi (inclusive) ascending (descending = 0) or descending. */
static int seq_range(axis_seq *seq, size_t lo, size_t hi, int descending, size_t stride)
{
    seq->n = hi - lo + 1;
    seq->off = malloc(seq->n * sizeof *seq->off);
    if (!seq->off)
        return 0;
    for (size_t r = 0; r < seq->n; r++)
        seq->off[r] = (descending ? hi - r : lo + r) * stride;
    return 1;
}

/* Indices 0..n-1 by decreasing |i - e| (ties: lower index first). */
static int seq_from_eye(axis_seq *seq, size_t n, double e, size_t stride)
{
    seq->n = n;
    seq->off = malloc(n * sizeof *seq->off);
    if (!seq->off)
        return 0;
    size_t left = 0, right = n - 1;
    for (size_t r = 0; r < n; r++) {
        double dl = fabs((double)left - e), dr = fabs((double)right - e);
        if (dl >= dr)
            seq->off[r] = (left++) * stride;
        else
            seq->off[r] = (right--) * stride;
    }
    return 1;
}

static void strides_of(const size_t dims[3], size_t stride[3])
{
    stride[0] = 1;
    stride[1] = dims[0];
    stride[2] = dims[0] * dims[1];
}

/* Axes sorted by decreasing |v| (ties: lower axis first). */
static void axes_by_magnitude(const double mag[3], int order[3])
{
    order[0] = 0;
    order[1] = 1;
    order[2] = 2;
    for (int i = 1; i < 3; i++)
        for (int j = i; j > 0 && mag[order[j]] > mag[order[j - 1]]; j--) {
            int swap = order[j];
            order[j] = order[j - 1];
            order[j - 1] = swap;
        }
}

/* ---- axis-aligned sheets --------------------------------------------------------------- */

/* Sheets along `major`; of the other two axes the one with the larger stride is the middle
 * loop (seq[] are in traversal order already). */
static void emit_axis(order_sink *s, const axis_seq seq[3], int major)
{
    int mid = major == 2 ? 1 : 2, inner = major == 0 ? 1 : 0;
    for (size_t a = 0; a < seq[major].n; a++)
        for (size_t b = 0; b < seq[mid].n; b++) {
            size_t base = seq[major].off[a] + seq[mid].off[b];
            for (size_t c = 0; c < seq[inner].n; c++)
                sink_emit(s, base + seq[inner].off[c]);
        }
}

/* ---- the extended DDA ------------------------------------------------------------------ */

/* T(k) = min{s >= 0 integer : s * r >= k}: the step at which the Fig. 6 accumulator
 * (d += r after each step, add an entry when d >= 1) has added entry k. r == 0 means every
 * entry is there from the start (a zero view component: all tie in depth). */
static int dda_times(uint64_t **out, size_t n, double r)
{
    uint64_t *t = malloc(n * sizeof *t);
    if (!t)
        return 0;
    for (size_t k = 0; k < n; k++) {
        if (r == 0.0 || k == 0) {
            t[k] = 0;
            continue;
        }
        double kd = (double)k;
        uint64_t s = (uint64_t)ceil(kd / r);
        while (s > 0 && (double)(s - 1) * r >= kd)
            s--;
        while ((double)s * r < kd)
            s++;
        t[k] = s;
    }
    *out = t;
    return 1;
}

typedef struct heap_item {
    uint64_t time;
    size_t plane;
} heap_item;

static void heap_sift_down(heap_item *h, size_t n, size_t i)
{
    heap_item x = h[i];
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n)
            break;
        if (c + 1 < n && (h[c + 1].time < h[c].time ||
                          (h[c + 1].time == h[c].time && h[c + 1].plane < h[c].plane)))
            c++;
        if (h[c].time > x.time || (h[c].time == x.time && h[c].plane > x.plane))
            break;
        h[i] = h[c];
        i = c;
    }
    h[i] = x;
}

/* State of one DDA run over a box: planes x columns x in-column ranks. */
typedef struct dda_run {
    const axis_seq *P, *C, *I;
    uint64_t *tp, *tc;   /* step at which plane k / column k (within its plane) starts */
    size_t *head, *tail; /* per plane: active columns [head, tail) */
    uint64_t *busy;      /* bitset of planes with active columns */
    heap_item *heap;     /* next column start per plane with columns left */
    size_t heap_n, busy_n, busy_lo, busy_hi; /* busy planes lie in words [busy_lo, busy_hi] */
} dda_run;

static void dda_free(dda_run *r)
{
    free(r->tp);
    free(r->tc);
    free(r->head);
    free(r->tail);
    free(r->busy);
    free(r->heap);
}

static int dda_alloc(dda_run *r, double ratio_p, double ratio_c)
{
    size_t np = r->P->n, words = (np + 63) / 64;
    r->head = calloc(np, sizeof *r->head);
    r->tail = calloc(np, sizeof *r->tail);
    r->busy = calloc(words, sizeof *r->busy);
    r->heap = malloc(np * sizeof *r->heap);
    if (!r->head || !r->tail || !r->busy || !r->heap || !dda_times(&r->tp, np, ratio_p) ||
        !dda_times(&r->tc, r->C->n, ratio_c))
        return 0;
    for (size_t p = 0; p < np; p++) { /* sorted by time: already a heap */
        r->heap[p].time = r->tp[p];
        r->heap[p].plane = p;
    }
    r->heap_n = np;
    r->busy_n = 0;
    r->busy_lo = words;
    r->busy_hi = 0;
    return 1;
}

/* Starts every column whose start time is <= t. */
static void dda_start_columns(dda_run *r, uint64_t t)
{
    while (r->heap_n > 0 && r->heap[0].time <= t) {
        size_t p = r->heap[0].plane;
        if (r->head[p] == r->tail[p]) {
            size_t w = p / 64;
            r->busy[w] |= (uint64_t)1 << (p % 64);
            r->busy_n++;
            if (w < r->busy_lo)
                r->busy_lo = w;
            if (w > r->busy_hi)
                r->busy_hi = w;
        }
        r->tail[p]++;
        if (r->tail[p] < r->C->n) {
            r->heap[0].time = r->tp[p] + r->tc[r->tail[p]];
        } else {
            r->heap[0] = r->heap[--r->heap_n];
        }
        if (r->heap_n > 0)
            heap_sift_down(r->heap, r->heap_n, 0);
    }
}

/* Step t of plane p: each active column draws its farthest undrawn voxel; finished columns
 * leave from the head. */
static void dda_step_plane(dda_run *r, order_sink *s, size_t p, uint64_t t)
{
    uint64_t local = t - r->tp[p], last = (uint64_t)r->I->n - 1;
    size_t base = r->P->off[p];
    const size_t *coff = r->C->off, *ioff = r->I->off;
    const uint64_t *tc = r->tc;
    for (size_t c = r->head[p]; c < r->tail[p]; c++)
        sink_emit(s, base + coff[c] + ioff[local - tc[c]]);
    while (r->head[p] < r->tail[p] && local - tc[r->head[p]] >= last)
        r->head[p]++;
    if (r->head[p] == r->tail[p]) {
        r->busy[p / 64] &= ~((uint64_t)1 << (p % 64));
        r->busy_n--;
    }
}

static void dda_loop(dda_run *r, order_sink *s)
{
    uint64_t t = 0;
    while (r->busy_n > 0 || r->heap_n > 0) {
        if (r->busy_n == 0 && r->heap[0].time > t)
            t = r->heap[0].time; /* nothing to draw until the next column starts */
        dda_start_columns(r, t);
        size_t lo = r->busy_lo, hi = r->busy_hi, new_lo = hi + 1, new_hi = 0;
        for (size_t w = lo; w <= hi; w++) {
            uint64_t bits = r->busy[w];
            if (!bits)
                continue;
            while (bits) {
                int b = __builtin_ctzll(bits);
                bits &= bits - 1;
                dda_step_plane(r, s, w * 64 + (size_t)b, t);
            }
            if (r->busy[w]) {
                if (w < new_lo)
                    new_lo = w;
                new_hi = w;
            }
        }
        r->busy_lo = new_lo;
        r->busy_hi = new_hi;
        if (r->busy_n == 0) {
            r->busy_lo = (r->P->n + 63) / 64;
            r->busy_hi = 0;
        }
        t++;
    }
}

/* The DDA over one box whose axes seq[] are in traversal order, for magnitudes mag[]. */
static int emit_dda(order_sink *s, const axis_seq seq[3], const double mag_in[3])
{
    double mag[3], top = fmax(mag_in[0], fmax(mag_in[1], mag_in[2]));
    for (int a = 0; a < 3; a++)
        mag[a] = mag_in[a] < DDA_ZERO_RATIO * top ? 0.0 : mag_in[a];
    int ax[3];
    axes_by_magnitude(mag, ax);
    int M = ax[0], m = ax[1], n = ax[2];
    dda_run r;
    memset(&r, 0, sizeof r);
    double ratio_p, ratio_c;
    if (mag[n] > 0.0) { /* Fig. 6: planes across M, columns along n, one per m index */
        r.P = &seq[M];
        r.C = &seq[m];
        r.I = &seq[n];
        ratio_p = mag[n] / mag[M];
        ratio_c = mag[n] / mag[m];
    } else if (mag[m] > 0.0) { /* section 4.2 in 2D; columns along n drawn whole */
        r.P = &seq[M];
        r.C = &seq[n];
        r.I = &seq[m];
        ratio_p = mag[m] / mag[M];
        ratio_c = 0.0;
    } else { /* along an axis: one sheet per step */
        r.P = &seq[m];
        r.C = &seq[n];
        r.I = &seq[M];
        ratio_p = 0.0;
        ratio_c = 0.0;
    }
    int ok = dda_alloc(&r, ratio_p, ratio_c);
    if (ok)
        dda_loop(&r, s);
    dda_free(&r);
    return ok;
}

/* ---- exact sorts ----------------------------------------------------------------------- */

/* 32-bit key that sorts ascending as phi descends (float phi, -0 folded to +0). */
static inline uint32_t descending_key(double phi)
{
    float f = (float)phi + 0.0f;
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    uint32_t ascending = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return ~ascending;
}

/* LSD radix sort by the upper 32 bits, 4 passes of 8 bits (256 buckets keep the scatter
 * within the TLB), all histograms from one read; ping-pongs between a and tmp and returns
 * the buffer holding the result. */
static uint64_t *radix_sort(uint64_t *a, uint64_t *tmp, size_t n)
{
    size_t count[4][256];
    memset(count, 0, sizeof count);
    for (size_t i = 0; i < n; i++) {
        uint32_t key = (uint32_t)(a[i] >> 32);
        count[0][key & 255]++;
        count[1][(key >> 8) & 255]++;
        count[2][(key >> 16) & 255]++;
        count[3][key >> 24]++;
    }
    for (int pass = 0; pass < 4; pass++) {
        int shift = 32 + 8 * pass;
        if (n == 0 || count[pass][(a[0] >> shift) & 255] == n)
            continue; /* one bucket: the pass would not move anything */
        size_t sum = 0;
        for (int b = 0; b < 256; b++) {
            size_t c = count[pass][b];
            count[pass][b] = sum;
            sum += c;
        }
        for (size_t i = 0; i < n; i++)
            tmp[count[pass][(a[i] >> shift) & 255]++] = a[i];
        uint64_t *swap = a;
        a = tmp;
        tmp = swap;
    }
    return a;
}

static void insertion_sort(uint64_t *a, size_t n)
{
    for (size_t i = 1; i < n; i++) {
        uint64_t x = a[i];
        size_t j = i;
        for (; j > 0 && a[j - 1] > x; j--)
            a[j] = a[j - 1];
        a[j] = x;
    }
}

static void swap64(uint64_t *a, uint64_t *b)
{
    uint64_t t = *a;
    *a = *b;
    *b = t;
}

/* Quicksort with Hoare's partition around the middle element's value (median of three):
 * both parts are nonempty, recursion goes to the smaller one. */
static void quick_sort(uint64_t *a, size_t n)
{
    while (n > 16) {
        size_t mid = n / 2;
        if (a[mid] < a[0])
            swap64(&a[mid], &a[0]);
        if (a[n - 1] < a[0])
            swap64(&a[n - 1], &a[0]);
        if (a[n - 1] < a[mid])
            swap64(&a[n - 1], &a[mid]);
        uint64_t pivot = a[mid];
        ptrdiff_t i = -1, j = (ptrdiff_t)n;
        for (;;) {
            do
                i++;
            while (a[i] < pivot);
            do
                j--;
            while (a[j] > pivot);
            if (i >= j)
                break;
            swap64(&a[i], &a[j]);
        }
        size_t left = (size_t)j + 1; /* [0, left) <= pivot <= [left, n) */
        if (left < n - left) {
            quick_sort(a, left);
            a += left;
            n -= left;
        } else {
            quick_sort(a + left, n - left);
            n = left;
        }
    }
    insertion_sort(a, n);
}

typedef struct sort_view {
    int perspective;
    double v[3], e[3], g[9];
} sort_view;

static double farness(const sort_view *sv, double i, double j, double k)
{
    if (!sv->perspective)
        return sv->v[0] * i + sv->v[1] * j + sv->v[2] * k;
    double d[3] = {i - sv->e[0], j - sv->e[1], k - sv->e[2]}, sum = 0.0;
    for (int r = 0; r < 3; r++)
        sum += d[r] * (sv->g[3 * r] * d[0] + sv->g[3 * r + 1] * d[1] + sv->g[3 * r + 2] * d[2]);
    return sum;
}

static cdvr_status emit_sorted(order_sink *s, const size_t dims[3], const sort_view *sv,
                               cdvr_splat_how how, cdvr_error *err)
{
    size_t n = s->capacity;
    uint64_t *rec = malloc((n ? n : 1) * sizeof *rec);
    uint64_t *tmp = how == CDVR_SPLAT_SORT ? malloc((n ? n : 1) * sizeof *tmp) : NULL;
    if (!rec || (how == CDVR_SPLAT_SORT && !tmp)) {
        free(rec);
        free(tmp);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat order: no memory to sort %zu voxels",
                              n);
    }
    size_t m = 0, lin = 0;
    for (size_t k = 0; k < dims[2]; k++)
        for (size_t j = 0; j < dims[1]; j++)
            for (size_t i = 0; i < dims[0]; i++, lin++) {
                if (s->voxels && !s->keep[s->voxels[lin]])
                    continue;
                uint32_t key = descending_key(farness(sv, (double)i, (double)j, (double)k));
                rec[m++] = ((uint64_t)key << 32) | (uint64_t)lin;
            }
    const uint64_t *sorted = rec;
    if (how == CDVR_SPLAT_SORT)
        sorted = radix_sort(rec, tmp, m);
    else
        quick_sort(rec, m);
    for (size_t i = 0; i < m; i++)
        s->out[s->count++] = (uint32_t)sorted[i];
    free(rec);
    free(tmp);
    return CDVR_OK;
}

/* ---- building -------------------------------------------------------------------------- */

static int finite_n(const double *x, int n)
{
    for (int i = 0; i < n; i++)
        if (!isfinite(x[i]))
            return 0;
    return 1;
}

static void view_metric(const cdvr_splat_view *view, double g[9])
{
    int zero = 1;
    for (int i = 0; i < 9; i++)
        zero &= view->metric[i] == 0.0;
    for (int i = 0; i < 9; i++)
        g[i] = zero ? (i % 4 == 0 ? 1.0 : 0.0) : view->metric[i];
}

static void apply_metric(const double g[9], const double d[3], double out[3])
{
    for (int r = 0; r < 3; r++)
        out[r] = g[3 * r] * d[0] + g[3 * r + 1] * d[1] + g[3 * r + 2] * d[2];
}

static cdvr_status check_build(const size_t dims[3], const cdvr_splat_view *view,
                               cdvr_splat_how how, size_t *voxels, cdvr_error *err)
{
    if ((unsigned)how > CDVR_SPLAT_QUICKSORT)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat order: unknown ordering %d", (int)how);
    size_t n = 1;
    for (int a = 0; a < 3; a++) {
        if (dims[a] == 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "splat order: dims %zux%zux%zu must be >= 1",
                                  dims[0], dims[1], dims[2]);
        if (n > (size_t)UINT32_MAX / dims[a])
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "splat order: %zux%zux%zu voxels exceed 2^32-1", dims[0],
                                  dims[1], dims[2]);
        n *= dims[a];
    }
    if (!finite_n(view->metric, 9))
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat order: metric must be finite");
    if (view->perspective) {
        if (!finite_n(view->eye, 3))
            return cdvr_error_set(err, CDVR_ERR_ARG, "splat order: eye (%g, %g, %g) must be finite",
                                  view->eye[0], view->eye[1], view->eye[2]);
    } else if (!finite_n(view->dir, 3) ||
               (view->dir[0] == 0.0 && view->dir[1] == 0.0 && view->dir[2] == 0.0)) {
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "splat order: view direction (%g, %g, %g) must be finite and nonzero",
                              view->dir[0], view->dir[1], view->dir[2]);
    }
    *voxels = n;
    return CDVR_OK;
}

/* Orthographic axis and DDA orders: every axis far to near along v. */
static int emit_orthographic(order_sink *s, const size_t dims[3], const double v[3],
                             cdvr_splat_how how)
{
    size_t stride[3];
    strides_of(dims, stride);
    axis_seq seq[3] = {{0, NULL}, {0, NULL}, {0, NULL}};
    double mag[3];
    int ok = 1;
    for (int a = 0; a < 3 && ok; a++) {
        ok = seq_range(&seq[a], 0, dims[a] - 1, v[a] > 0.0, stride[a]);
        mag[a] = fabs(v[a]);
    }
    if (ok) {
        if (how == CDVR_SPLAT_AXIS) {
            int ax[3];
            axes_by_magnitude(mag, ax);
            emit_axis(s, seq, ax[0]);
        } else {
            ok = emit_dda(s, seq, mag);
        }
    }
    seq_free(seq);
    return ok;
}

static int emit_axis_perspective(order_sink *s, const size_t dims[3], const double e[3],
                                 const double g[9])
{
    size_t stride[3];
    strides_of(dims, stride);
    axis_seq seq[3] = {{0, NULL}, {0, NULL}, {0, NULL}};
    double to_center[3], v[3], mag[3];
    int ok = 1;
    for (int a = 0; a < 3 && ok; a++) {
        ok = seq_from_eye(&seq[a], dims[a], e[a], stride[a]);
        to_center[a] = 0.5 * (double)(dims[a] - 1) - e[a];
    }
    apply_metric(g, to_center, v);
    for (int a = 0; a < 3; a++)
        mag[a] = fabs(v[a]);
    if (ok) {
        int ax[3];
        axes_by_magnitude(mag, ax);
        emit_axis(s, seq, ax[0]);
    }
    seq_free(seq);
    return ok;
}

typedef struct octant {
    size_t lo[3], hi[3];
    int descending[3];
    double distance;
} octant;

static int compare_octants(const void *pa, const void *pb)
{
    const octant *a = pa, *b = pb;
    return a->distance < b->distance ? 1 : a->distance > b->distance ? -1 : 0;
}

/* Splits the box at the eye: per axis, indices < e_a (run ascending) and >= e_a
 * (descending); returns the number of nonempty octants, farthest first. */
static int split_octants(const size_t dims[3], const double e[3], const double g[9],
                         octant oct[8])
{
    size_t cut[3];
    for (int a = 0; a < 3; a++) {
        double c = ceil(e[a]);
        cut[a] = c <= 0.0 ? 0 : c >= (double)dims[a] ? dims[a] : (size_t)c;
    }
    int count = 0;
    for (int mask = 0; mask < 8; mask++) {
        octant o;
        int empty = 0;
        for (int a = 0; a < 3; a++) {
            int high = (mask >> a) & 1;
            o.lo[a] = high ? cut[a] : 0;
            o.hi[a] = high ? dims[a] : cut[a]; /* exclusive here */
            o.descending[a] = high;
            empty |= o.lo[a] >= o.hi[a];
        }
        if (empty)
            continue;
        double d[3], gd[3];
        for (int a = 0; a < 3; a++) {
            o.hi[a]--; /* inclusive */
            d[a] = 0.5 * (double)(o.lo[a] + o.hi[a]) - e[a];
        }
        apply_metric(g, d, gd);
        o.distance = d[0] * gd[0] + d[1] * gd[1] + d[2] * gd[2];
        oct[count++] = o;
    }
    qsort(oct, (size_t)count, sizeof *oct, compare_octants);
    return count;
}

static int emit_dda_perspective(order_sink *s, const size_t dims[3], const double e[3],
                                const double g[9])
{
    size_t stride[3];
    strides_of(dims, stride);
    octant oct[8];
    int count = split_octants(dims, e, g, oct);
    for (int i = 0; i < count; i++) {
        axis_seq seq[3] = {{0, NULL}, {0, NULL}, {0, NULL}};
        double d[3], v[3], mag[3];
        int ok = 1;
        for (int a = 0; a < 3 && ok; a++) {
            ok = seq_range(&seq[a], oct[i].lo[a], oct[i].hi[a], oct[i].descending[a], stride[a]);
            d[a] = 0.5 * (double)(oct[i].lo[a] + oct[i].hi[a]) - e[a];
        }
        apply_metric(g, d, v);
        for (int a = 0; a < 3; a++)
            mag[a] = fabs(v[a]);
        if (ok)
            ok = emit_dda(s, seq, mag);
        seq_free(seq);
        if (!ok)
            return 0;
    }
    return 1;
}

static size_t count_listed(size_t n, const cdvr_splat_filter *filter)
{
    if (!filter || !filter->voxels)
        return n;
    size_t count = 0;
    for (size_t i = 0; i < n; i++)
        count += filter->keep[filter->voxels[i]] != 0;
    return count;
}

cdvr_status cdvr_splat_order_build(const size_t dims[3], const cdvr_splat_view *view,
                                   cdvr_splat_how how, const cdvr_splat_filter *filter,
                                   cdvr_splat_order **out, cdvr_error *err)
{
    *out = NULL;
    if (!dims || !view)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat order: NULL dims or view");
    if (filter && filter->voxels && !filter->keep)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat order: filter without keep table");
    size_t n = 0;
    cdvr_status st = check_build(dims, view, how, &n, err);
    if (st != CDVR_OK)
        return st;
    cdvr_splat_order *o = calloc(1, sizeof *o);
    size_t listed = count_listed(n, filter);
    if (o)
        o->index = malloc((listed ? listed : 1) * sizeof *o->index);
    if (!o || !o->index) {
        free(o);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat order: no memory for %zu voxels",
                              listed);
    }
    memcpy(o->dims, dims, sizeof o->dims);
    order_sink sink = {o->index, 0, listed, filter ? filter->voxels : NULL,
                       filter ? filter->keep : NULL};
    double g[9];
    view_metric(view, g);
    int ok = 1;
    if (how == CDVR_SPLAT_SORT || how == CDVR_SPLAT_QUICKSORT) {
        sort_view sv = {view->perspective != 0, {0}, {0}, {0}};
        memcpy(sv.v, view->dir, sizeof sv.v);
        memcpy(sv.e, view->eye, sizeof sv.e);
        memcpy(sv.g, g, sizeof sv.g);
        st = emit_sorted(&sink, dims, &sv, how, err);
        ok = st == CDVR_OK;
    } else if (!view->perspective) {
        ok = emit_orthographic(&sink, dims, view->dir, how);
    } else if (how == CDVR_SPLAT_AXIS) {
        ok = emit_axis_perspective(&sink, dims, view->eye, g);
    } else {
        ok = emit_dda_perspective(&sink, dims, view->eye, g);
    }
    if (!ok || sink.count != listed) {
        cdvr_splat_order_free(o);
        if (st != CDVR_OK)
            return st;
        if (!ok)
            return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat order: no memory for the %s order",
                                  cdvr_splat_how_name(how));
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "splat order: %s order listed %zu of %zu voxels",
                              cdvr_splat_how_name(how), sink.count, listed);
    }
    o->count = listed;
    *out = o;
    return CDVR_OK;
}

void cdvr_splat_order_free(cdvr_splat_order *order)
{
    if (!order)
        return;
    free(order->index);
    free(order);
}

/* ---- order quality --------------------------------------------------------------------- */

#define QUALITY_DEFAULT_BUDGET ((uint64_t)1 << 27)

typedef struct pair_offset {
    int32_t d[3];
    ptrdiff_t lin;
    int farther;  /* 1: p + d is farther than p (drawn first when right); 0: a tie */
    double along; /* d . v */
} pair_offset;

static int lex_positive(const long d[3])
{
    for (int a = 0; a < 3; a++)
        if (d[a] != 0)
            return d[a] > 0;
    return 0;
}

/* Offsets d with |d x v| < rho, one of each +-d pair (see cdvr_splat_order_quality). */
static cdvr_status list_offsets(const size_t dims[3], const double v[3], double rho,
                                pair_offset **out, size_t *count, cdvr_error *err)
{
    double tie = 0.0;
    for (int a = 0; a < 3; a++)
        tie += fabs(v[a]) * (double)(dims[a] - 1);
    tie = fmax(1e-6 * tie, 1e-9);
    double mag[3] = {fabs(v[0]), fabs(v[1]), fabs(v[2])};
    int ax[3];
    axes_by_magnitude(mag, ax);
    int a = ax[0], b = ax[1], c = ax[2];
    long reach = (long)ceil(rho / mag[a]) + 1;
    size_t cap = 64, n = 0;
    pair_offset *list = malloc(cap * sizeof *list);
    if (!list)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat order quality: no memory");
    long na = (long)dims[a] - 1, nb = (long)dims[b] - 1, nc = (long)dims[c] - 1;
    for (long k = -na; k <= na; k++) {
        double cb = (double)k * v[b] / v[a], cc = (double)k * v[c] / v[a];
        long b0 = (long)floor(cb) - reach, b1 = (long)ceil(cb) + reach;
        long c0 = (long)floor(cc) - reach, c1 = (long)ceil(cc) + reach;
        for (long jb = b0 < -nb ? -nb : b0; jb <= (b1 > nb ? nb : b1); jb++)
            for (long jc = c0 < -nc ? -nc : c0; jc <= (c1 > nc ? nc : c1); jc++) {
                long d[3];
                d[a] = k;
                d[b] = jb;
                d[c] = jc;
                double along = (double)d[0] * v[0] + (double)d[1] * v[1] + (double)d[2] * v[2];
                double len2 = (double)(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                if (len2 == 0.0 || len2 - along * along >= rho * rho)
                    continue;
                int farther = along > tie;
                if (!farther && !(fabs(along) <= tie && lex_positive(d)))
                    continue;
                if (n == cap) {
                    pair_offset *bigger = realloc(list, 2 * cap * sizeof *list);
                    if (!bigger) {
                        free(list);
                        return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat order quality: no memory");
                    }
                    list = bigger;
                    cap *= 2;
                }
                pair_offset *po = &list[n++];
                for (int x = 0; x < 3; x++)
                    po->d[x] = (int32_t)d[x];
                po->lin = (ptrdiff_t)d[0] + (ptrdiff_t)dims[0] * ((ptrdiff_t)d[1] +
                                                                  (ptrdiff_t)dims[1] * (ptrdiff_t)d[2]);
                po->farther = farther;
                po->along = along;
            }
    }
    *out = list;
    *count = n;
    return CDVR_OK;
}

static void count_pairs_of(const cdvr_splat_order *o, const uint32_t *rank,
                           const pair_offset *offs, size_t noffs, size_t p,
                           cdvr_splat_quality *q)
{
    long x = (long)(p % o->dims[0]), y = (long)(p / o->dims[0] % o->dims[1]),
         z = (long)(p / (o->dims[0] * o->dims[1]));
    uint32_t rp = rank[p];
    for (size_t i = 0; i < noffs; i++) {
        const pair_offset *po = &offs[i];
        long qx = x + po->d[0], qy = y + po->d[1], qz = z + po->d[2];
        if (qx < 0 || qy < 0 || qz < 0 || qx >= (long)o->dims[0] || qy >= (long)o->dims[1] ||
            qz >= (long)o->dims[2])
            continue;
        uint32_t rq = rank[(size_t)((ptrdiff_t)p + po->lin)];
        if (rq == UINT32_MAX)
            continue;
        q->pairs++;
        if (po->farther && rq > rp) {
            q->wrong++;
            if (po->along > q->max_inversion)
                q->max_inversion = po->along;
        }
    }
}

static uint64_t xorshift64(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    return *s = x;
}

cdvr_status cdvr_splat_order_quality(const cdvr_splat_order *order, const double dir[3],
                                     double radius, uint64_t budget, cdvr_splat_quality *q,
                                     cdvr_error *err)
{
    memset(q, 0, sizeof *q);
    if (!order || !dir)
        return cdvr_error_set(err, CDVR_ERR_ARG, "splat order quality: NULL order or direction");
    double len = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    if (!finite_n(dir, 3) || !(len > 0.0) || !isfinite(len))
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "splat order quality: direction (%g, %g, %g) must be finite and nonzero",
                              dir[0], dir[1], dir[2]);
    if (!(radius > 0.0) || radius > 64.0)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "splat order quality: radius %g outside (0, 64]", radius);
    double v[3] = {dir[0] / len, dir[1] / len, dir[2] / len};
    size_t n = order->dims[0] * order->dims[1] * order->dims[2];
    uint32_t *rank = malloc(n * sizeof *rank);
    if (!rank)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "splat order quality: no memory for ranks");
    memset(rank, 0xff, n * sizeof *rank);
    for (size_t i = 0; i < order->count; i++)
        rank[order->index[i]] = (uint32_t)i;
    pair_offset *offs = NULL;
    size_t noffs = 0;
    cdvr_status st = list_offsets(order->dims, v, 2.0 * radius, &offs, &noffs, err);
    if (st != CDVR_OK) {
        free(rank);
        return st;
    }
    q->offsets = noffs;
    if (budget == 0)
        budget = QUALITY_DEFAULT_BUDGET;
    if (noffs > 0 && order->count > 0) {
        if ((double)order->count * (double)noffs <= (double)budget) {
            for (size_t i = 0; i < order->count; i++)
                count_pairs_of(order, rank, offs, noffs, order->index[i], q);
        } else {
            uint64_t samples = budget / noffs, state = 0x9E3779B97F4A7C15ull;
            if (samples == 0)
                samples = 1;
            q->sampled = 1;
            for (uint64_t i = 0; i < samples; i++)
                count_pairs_of(order, rank, offs, noffs,
                               order->index[xorshift64(&state) % order->count], q);
        }
    }
    q->fraction = q->pairs ? (double)q->wrong / (double)q->pairs : 0.0;
    free(offs);
    free(rank);
    return CDVR_OK;
}
