/* tests/test_quantize.c - core/io/quantize.c: the window rule of volume.h, NaN/Inf policy,
 * denormals, huge ranges, lo == hi, 16-bit input, and the reported counts. */
#include "check.h"
#include "cdvr/volume.h"

#include <float.h>
#include <stdint.h>
#include <string.h>

static cdvr_volume *f32_volume(const float *values, size_t n)
{
    cdvr_volume *v = NULL;
    cdvr_error err;
    size_t dims[3] = {n, 1, 1};
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_F32, &v, &err), err);
    memcpy(v->data, values, n * sizeof *values);
    return v;
}

/* Quantizes v over [lo, hi] and compares every output byte with want. */
static void expect(const cdvr_volume *v, double lo, double hi, const uint8_t *want,
                   cdvr_quantize_report *report, const char *what)
{
    cdvr_volume *q = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_quantize(v, lo, hi, &q, report, &err), err);
    if (!q)
        return;
    CHECK(q->type == CDVR_TYPE_U8 && q->dims[0] == v->dims[0] && q->timesteps == v->timesteps, "%s: shape", what);
    size_t n = cdvr_volume_voxels(v) * v->timesteps;
    const uint8_t *got = q->data;
    for (size_t i = 0; i < n; i++)
        CHECK(got[i] == want[i], "%s: voxel %zu: got %u, want %u", what, i, got[i], want[i]);
    cdvr_volume_free(q);
}

static void test_rounding(void)
{
    /* window [0, 510]: q = v / 2, half up */
    const float in[] = {0, 1, 2, 3, 254, 255, 509, 510, -0.0f};
    const uint8_t want[] = {0, 1, 1, 2, 127, 128, 255, 255, 0};
    cdvr_volume *v = f32_volume(in, 9);
    cdvr_quantize_report r;
    expect(v, 0, 510, want, &r, "half up");
    CHECK(r.clipped_low == 0 && r.clipped_high == 0 && r.nan_count == 0 && r.inf_count == 0, "no clipping");
    cdvr_volume_free(v);
}

static void test_nan_inf_counts(void)
{
    const float in[] = {NAN, INFINITY, -INFINITY, -1, 11, 5, 10, 0, -NAN};
    const uint8_t want[] = {0, 255, 0, 0, 255, 128, 255, 0, 0};
    cdvr_volume *v = f32_volume(in, 9);
    cdvr_quantize_report r;
    expect(v, 0, 10, want, &r, "nan/inf");
    CHECK(r.nan_count == 2, "nan count %zu", r.nan_count);
    CHECK(r.inf_count == 2, "inf count %zu", r.inf_count);
    CHECK(r.clipped_low == 2 && r.clipped_high == 2, "clipped %zu low, %zu high (Inf included)", r.clipped_low,
          r.clipped_high);
    cdvr_volume_free(v);
}

static void test_denormals(void)
{
    const float tiny = FLT_TRUE_MIN;
    const float in[] = {0, tiny, 2 * tiny, 3 * tiny, FLT_MIN};
    /* window [0, 2 tiny]: tiny -> 127.5 -> 128; above the window clipped */
    const uint8_t want[] = {0, 128, 255, 255, 255};
    cdvr_volume *v = f32_volume(in, 5);
    cdvr_quantize_report r;
    expect(v, 0, 2 * (double)tiny, want, &r, "denormal window");
    CHECK(r.clipped_high == 2, "denormal clipped %zu", r.clipped_high);
    /* denormals in a normal window round to 0 */
    const uint8_t zeros[] = {0, 0, 0, 0, 0};
    expect(v, 0, 1, zeros, &r, "denormals in [0,1]");
    CHECK(r.clipped_high == 0 && r.clipped_low == 0, "denormals are not clipped");
    cdvr_volume_free(v);
}

static void test_huge_ranges(void)
{
    const float in[] = {0, 1e30f, -1e30f, 3e38f, -3e38f, 5e29f};
    const uint8_t want[] = {128, 255, 0, 255, 0, 191};
    cdvr_volume *v = f32_volume(in, 6);
    cdvr_quantize_report r;
    expect(v, -1e30, 1e30, want, &r, "window +-1e30");
    /* the float nearest 1e30 is slightly above it: clipped like 3e38 */
    CHECK(r.clipped_high == 2 && r.clipped_low == 2, "1e30 window clipping %zu %zu", r.clipped_low, r.clipped_high);
    /* hi - lo overflows a double */
    const uint8_t full[] = {128, 128, 128, 128, 128, 128};
    expect(v, -DBL_MAX, DBL_MAX, full, &r, "window +-DBL_MAX");
    CHECK(r.clipped_high == 0 && r.clipped_low == 0, "no clipping in +-DBL_MAX");
    cdvr_volume_free(v);
}

static void test_degenerate_window(void)
{
    const float in[] = {1, 2, 3, NAN, INFINITY};
    const uint8_t want[] = {0, 0, 255, 0, 255};
    cdvr_volume *v = f32_volume(in, 5);
    cdvr_quantize_report r;
    expect(v, 2, 2, want, &r, "lo == hi");
    CHECK(r.clipped_low == 1 && r.clipped_high == 2 && r.nan_count == 1 && r.inf_count == 1, "lo == hi counts");
    cdvr_volume *q = NULL;
    cdvr_error err;
    CHECK(cdvr_volume_quantize(v, 3, 2, &q, &r, &err) == CDVR_ERR_ARG && !q, "hi < lo is an error");
    CHECK(cdvr_volume_quantize(v, NAN, 2, &q, &r, &err) == CDVR_ERR_ARG, "NaN lo is an error");
    CHECK(cdvr_volume_quantize(v, 0, INFINITY, &q, &r, &err) == CDVR_ERR_ARG, "Inf hi is an error");
    cdvr_volume_free(v);
}

static void test_16bit(void)
{
    cdvr_volume *v = NULL, *q = NULL;
    cdvr_error err;
    size_t dims[3] = {2, 2, 1};
    CHECK_OK(cdvr_volume_create(dims, 2, CDVR_TYPE_U16, &v, &err), err);
    const uint16_t in[] = {0, 257, 32768, 65535, 128, 129, 40000, 1};
    memcpy(v->data, in, sizeof in);
    v->spacing[2] = 1.5;
    v->origin[0] = -3;
    cdvr_quantize_report r;
    const uint8_t want[] = {0, 1, 128, 255, 0, 1, 156, 0};
    expect(v, 0, 65535, want, &r, "u16 full window");
    CHECK_OK(cdvr_volume_quantize(v, 0, 65535, &q, NULL, &err), err);
    CHECK(q && q->spacing[2] == 1.5 && q->origin[0] == -3 && q->timesteps == 2, "geometry kept; NULL report ok");
    cdvr_volume_free(q);
    cdvr_volume_free(v);

    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_I16, &v, &err), err);
    const int16_t s[] = {-32768, -1, 0, 32767};
    memcpy(v->data, s, sizeof s);
    const uint8_t want_s[] = {0, 127, 128, 255};
    expect(v, -32768, 32767, want_s, &r, "i16 full window");
    const uint8_t want_w[] = {0, 0, 0, 255};
    expect(v, 0, 1000, want_w, &r, "i16 window [0,1000]");
    CHECK(r.clipped_low == 2 && r.clipped_high == 1, "i16 clipping %zu %zu", r.clipped_low, r.clipped_high);
    cdvr_volume_free(v);
}

static void test_u8_identity(void)
{
    cdvr_volume *v = NULL;
    cdvr_error err;
    size_t dims[3] = {256, 1, 1};
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err), err);
    uint8_t want[256];
    for (int i = 0; i < 256; i++)
        want[i] = ((uint8_t *)v->data)[i] = (uint8_t)i;
    cdvr_quantize_report r;
    expect(v, 0, 255, want, &r, "u8 identity");
    cdvr_volume_free(v);
}

int main(void)
{
    test_rounding();
    test_nan_inf_counts();
    test_denormals();
    test_huge_ranges();
    test_degenerate_window();
    test_16bit();
    test_u8_identity();
    return check_finish();
}
