/* core/render/cpu/brick_range.c - brick value ranges of a dense u8 frame on several threads
 * (brick_range.h). For each row of bricks (by, bz), the voxel rows it covers (apron
 * included) are folded element-wise into one row of column minima and maxima, 16 bytes at a
 * time (the E + 1 rows of a slice in registers), and each brick then takes the range of its
 * E + 1 columns, from windowed minima and maxima of that row (also whole-row vector
 * operations): every voxel is read about ((E + 1) / E)^2 times. */
#include "render/cpu/brick_range.h"

#include <pthread.h>
#include <unistd.h>
#include <stdlib.h>
#include <string.h>

#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define MAX_THREADS 256

typedef struct range_job {
    const uint8_t *frame;
    size_t dims[3], nb[3];
    unsigned shift;
    uint8_t *minmax;
    size_t next_plane; /* brick planes handed out in order, under lock */
    pthread_mutex_t lock;
} range_job;

/* lo[x] = min(lo[x], rows[r][x]), hi[x] = max(hi[x], rows[r][x]) for x < n over the rows
 * rows[0], rows[stride], ... (nrows of them): each 16 columns are folded in registers and
 * stored once. */
static void fold_rows(const uint8_t *restrict rows, size_t stride, size_t nrows,
                      uint8_t *restrict lo, uint8_t *restrict hi, size_t n)
{
    size_t x = 0;
#ifdef __SSE2__
    for (; x + 16 <= n; x += 16) {
        __m128i l = _mm_loadu_si128((const __m128i *)(lo + x));
        __m128i h = _mm_loadu_si128((const __m128i *)(hi + x));
        for (size_t r = 0; r < nrows; r++) {
            __m128i v = _mm_loadu_si128((const __m128i *)(rows + r * stride + x));
            l = _mm_min_epu8(l, v);
            h = _mm_max_epu8(h, v);
        }
        _mm_storeu_si128((__m128i *)(lo + x), l);
        _mm_storeu_si128((__m128i *)(hi + x), h);
    }
#endif
    for (; x < n; x++)
        for (size_t r = 0; r < nrows; r++) {
            uint8_t v = rows[r * stride + x];
            lo[x] = v < lo[x] ? v : lo[x];
            hi[x] = v > hi[x] ? v : hi[x];
        }
}

/* Last voxel index of brick g along an axis of n voxels. */
static size_t brick_last(size_t g, unsigned shift, size_t n)
{
    size_t last = (g << shift) + ((size_t)1 << shift);
    return last < n - 1 ? last : n - 1;
}

/* w[x] = min(w[x], w[x + len]) (is_max: max) for x < n, in place, 16 at a time; w holds
 * neutral padding (255 for min, 0 for max) from n on, which stays as it is. */
static void window_pass(uint8_t *w, size_t len, size_t n, int is_max)
{
    size_t x = 0;
#ifdef __SSE2__
    for (; x < n; x += 16) {
        __m128i a = _mm_loadu_si128((const __m128i *)(w + x));
        __m128i b = _mm_loadu_si128((const __m128i *)(w + x + len));
        _mm_storeu_si128((__m128i *)(w + x), is_max ? _mm_max_epu8(a, b) : _mm_min_epu8(a, b));
    }
#endif
    for (; x < n; x++)
        w[x] = is_max ? (w[x + len] > w[x] ? w[x + len] : w[x])
                      : (w[x + len] < w[x] ? w[x + len] : w[x]);
}

/* w[x] = the extreme of w[x .. x + E] (E = 2^shift: a brick's columns, apron included), by
 * doubling windows up to E and one pass more. */
static void brick_windows(uint8_t *w, unsigned shift, size_t n, int is_max)
{
    for (size_t len = 1; len < ((size_t)1 << shift); len *= 2)
        window_pass(w, len, n, is_max);
    window_pass(w, 1, n, is_max);
}

/* Padding after a scratch row of n columns: the windows read up to 16 + E past n. */
static size_t row_padding(unsigned shift)
{
    return 32 + ((size_t)1 << shift);
}

/* The ranges of the bricks of brick plane bz; lo, hi: one padded row of scratch each. */
static void plane_ranges(range_job *job, size_t bz, uint8_t *lo, uint8_t *hi)
{
    const size_t *d = job->dims, *nb = job->nb;
    unsigned sh = job->shift;
    size_t z0 = bz << sh, z1 = brick_last(bz, sh, d[2]);
    for (size_t by = 0; by < nb[1]; by++) {
        size_t y0 = by << sh, y1 = brick_last(by, sh, d[1]);
        memset(lo, 255, d[0]);
        memset(hi, 0, d[0]);
        for (size_t z = z0; z <= z1; z++)
            fold_rows(job->frame + d[0] * (y0 + d[1] * z), d[0], y1 - y0 + 1, lo, hi, d[0]);
        brick_windows(lo, sh, d[0], 0);
        brick_windows(hi, sh, d[0], 1);
        uint8_t *out = job->minmax + 2 * nb[0] * (by + nb[1] * bz);
        for (size_t bx = 0; bx < nb[0]; bx++) {
            out[2 * bx] = lo[bx << sh];
            out[2 * bx + 1] = hi[bx << sh];
        }
    }
}

static void *range_worker(void *arg)
{
    range_job *job = arg;
    size_t row = job->dims[0] + row_padding(job->shift);
    uint8_t *lo = malloc(2 * row);
    if (!lo) /* takes no plane: the others do them */
        return NULL;
    uint8_t *hi = lo + row;
    memset(lo, 255, row); /* the padding stays neutral */
    memset(hi, 0, row);
    for (;;) {
        pthread_mutex_lock(&job->lock);
        size_t bz = job->next_plane++;
        pthread_mutex_unlock(&job->lock);
        if (bz >= job->nb[2])
            break;
        plane_ranges(job, bz, lo, hi);
    }
    free(lo);
    return NULL;
}

cdvr_status cdvr_cpu_brick_ranges(const uint8_t *frame, const size_t dims[3], unsigned shift,
                                  int threads, uint8_t *minmax, cdvr_error *err)
{
    range_job job = {.frame = frame, .shift = shift, .minmax = minmax};
    for (int a = 0; a < 3; a++) {
        job.dims[a] = dims[a];
        job.nb[a] = (dims[a] + ((size_t)1 << shift) - 1) >> shift;
    }
    if (pthread_mutex_init(&job.lock, NULL) != 0)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick ranges: no mutex");
    if (threads < 1) {
        long online = sysconf(_SC_NPROCESSORS_ONLN);
        threads = online > 0 && online < MAX_THREADS ? (int)online : 1;
    }
    int n = threads > MAX_THREADS ? MAX_THREADS : threads;
    if ((size_t)n > job.nb[2])
        n = (int)job.nb[2];
    pthread_t tid[MAX_THREADS];
    int started = 0;
    for (int i = 1; i < n; i++) {
        if (pthread_create(&tid[started], NULL, range_worker, &job) != 0)
            break;
        started++;
    }
    range_worker(&job);
    for (int i = 0; i < started; i++)
        pthread_join(tid[i], NULL);
    pthread_mutex_destroy(&job.lock);
    /* a worker without scratch takes no plane: planes remain only if all of them failed */
    if (job.next_plane < job.nb[2])
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "brick ranges: no memory for %zu-voxel rows",
                              dims[0]);
    return CDVR_OK;
}
