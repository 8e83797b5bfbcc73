/* core/base/bricks.c - store-brick geometry and brick copies (cdvr/bricks.h). */
#include "cdvr/bricks.h"

#include <string.h>

int cdvr_brick_box(const size_t vol_dims[3], const size_t bricks[3], size_t b, size_t lo[3],
                   size_t dims[3])
{
    size_t idx = b;
    for (int a = 0; a < 3; a++) {
        size_t n = bricks[a], N = vol_dims[a];
        if (n == 0 || N == 0 || (N > 1 && n > N - 1) || (N == 1 && n != 1))
            return 0;
        size_t i = idx % n;
        idx /= n;
        if (N == 1) {
            lo[a] = 0;
            dims[a] = 1;
            continue;
        }
        /* c_i = floor(i (N-1) / n) = i q + floor(i r / n) with N-1 = q n + r: exact, and
         * i r < n^2 cannot overflow (n <= cells; callers bound the brick count) */
        size_t cells = N - 1, q = cells / n, r = cells % n;
        size_t c0 = i * q + i * r / n, c1 = (i + 1) * q + (i + 1) * r / n;
        lo[a] = c0;
        dims[a] = c1 - c0 + 1;
    }
    return idx == 0;
}

int cdvr_brick_owned(const size_t vol_dims[3], const size_t bricks[3], size_t b, size_t lo[3],
                     size_t dims[3])
{
    if (!cdvr_brick_box(vol_dims, bricks, b, lo, dims))
        return 0;
    for (int a = 0; a < 3; a++)
        if (lo[a] > 0 && dims[a] > 1) {
            lo[a]++;
            dims[a]--;
        }
    return 1;
}

void cdvr_brick_place(uint8_t *frame, const size_t vol_dims[3], const uint8_t *brick,
                      const size_t lo[3], const size_t dims[3])
{
    const size_t *vd = vol_dims;
    for (size_t z = 0; z < dims[2]; z++)
        for (size_t y = 0; y < dims[1]; y++)
            memcpy(frame + lo[0] + vd[0] * ((lo[1] + y) + vd[1] * (lo[2] + z)),
                   brick + dims[0] * (y + dims[1] * z), dims[0]);
}

void cdvr_brick_extract(const uint8_t *frame, const size_t vol_dims[3], const size_t lo[3],
                        const size_t dims[3], uint8_t *brick)
{
    const size_t *vd = vol_dims;
    for (size_t z = 0; z < dims[2]; z++)
        for (size_t y = 0; y < dims[1]; y++)
            memcpy(brick + dims[0] * (y + dims[1] * z),
                   frame + lo[0] + vd[0] * ((lo[1] + y) + vd[1] * (lo[2] + z)), dims[0]);
}
