/* tests/test_compare.c - identical inputs give infinite PSNR; known mse, psnr and maxerr for
 * volumes and images; mismatched inputs are rejected. */
#include "check.h"
#include "cdvr/compare.h"

#include <stdint.h>
#include <string.h>

static cdvr_volume *make_u8(size_t x, size_t y, size_t z)
{
    size_t dims[3] = {x, y, z};
    cdvr_volume *v = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err), err);
    return v;
}

static void test_volumes(void)
{
    cdvr_volume *a = make_u8(4, 2, 2), *b = make_u8(4, 2, 2);
    if (!a || !b)
        return;
    cdvr_compare_result res;
    cdvr_error err;
    CHECK_OK(cdvr_compare_volumes(a, b, &res, &err), err);
    CHECK(isinf(res.psnr) && res.psnr > 0 && res.mse == 0 && res.maxerr == 0, "identical");
    /* 16 voxels: one differs by 4, one by 2 -> mse = (16 + 4)/16 = 1.25 */
    ((uint8_t *)b->data)[3] = 4;
    ((uint8_t *)a->data)[7] = 2;
    CHECK_OK(cdvr_compare_volumes(a, b, &res, &err), err);
    CHECK(fabs(res.mse - 1.25) < 1e-12, "mse %g", res.mse);
    CHECK(res.maxerr == 4.0, "maxerr %g", res.maxerr);
    double want = 10 * log10(255.0 * 255.0 / 1.25);
    CHECK(fabs(res.psnr - want) < 1e-9, "psnr %g want %g", res.psnr, want);
    cdvr_volume *c = make_u8(4, 2, 3);
    CHECK(cdvr_compare_volumes(a, c, &res, &err) == CDVR_ERR_ARG, "size mismatch accepted");
    cdvr_volume_free(a);
    cdvr_volume_free(b);
    cdvr_volume_free(c);
}

static void test_float_volumes(void)
{
    size_t dims[3] = {2, 1, 1};
    cdvr_volume *a = NULL, *b = NULL, *u = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_F32, &a, &err), err);
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_F32, &b, &err), err);
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &u, &err), err);
    if (!a || !b || !u)
        return;
    float *fa = a->data, *fb = b->data;
    fa[0] = 0.0f, fa[1] = 10.0f; /* peak = range of a = 10 */
    fb[0] = 1.0f, fb[1] = 10.0f; /* mse = 0.5 */
    cdvr_compare_result res;
    CHECK_OK(cdvr_compare_volumes(a, b, &res, &err), err);
    CHECK(fabs(res.mse - 0.5) < 1e-12 && fabs(res.psnr - 10 * log10(100 / 0.5)) < 1e-9,
          "f32 mse %g psnr %g", res.mse, res.psnr);
    CHECK(cdvr_compare_volumes(a, u, &res, &err) == CDVR_ERR_ARG, "type mismatch accepted");
    CHECK(strstr(err.msg, "f32") && strstr(err.msg, "u8"), "message: %s", err.msg);
    fb[1] = NAN;
    CHECK_OK(cdvr_compare_volumes(a, b, &res, &err), err);
    CHECK(isinf(res.maxerr), "NaN against a number must count as an infinite error");
    cdvr_volume_free(a);
    cdvr_volume_free(b);
    cdvr_volume_free(u);
}

static void test_images(void)
{
    cdvr_image *a, *b, *c;
    cdvr_error err;
    CHECK_OK(cdvr_image_create(2, 2, &a, &err), err);
    CHECK_OK(cdvr_image_create(2, 2, &b, &err), err);
    CHECK_OK(cdvr_image_create(3, 2, &c, &err), err);
    cdvr_compare_result res;
    CHECK_OK(cdvr_compare_images(a, b, &res, &err), err);
    CHECK(isinf(res.psnr), "identical images psnr %g", res.psnr);
    /* one channel of one pixel off by 51/255 (alpha ignored): mse = 51^2 / 12 */
    float *p = cdvr_image_pixel(b, 1, 1);
    p[2] = 51.0f / 255.0f;
    p[3] = 0.0f; /* premultiplied emission without opacity still shows over black */
    CHECK_OK(cdvr_compare_images(a, b, &res, &err), err);
    CHECK(fabs(res.mse - 51.0 * 51.0 / 12.0) < 1e-3, "image mse %g", res.mse);
    CHECK(fabs(res.maxerr - 51.0) < 1e-4, "image maxerr %g", res.maxerr);
    CHECK(fabs(res.psnr - cdvr_psnr(res.mse, 255)) < 1e-12, "image psnr");
    CHECK(cdvr_compare_images(a, c, &res, &err) == CDVR_ERR_ARG, "size mismatch accepted");
    cdvr_image_free(a);
    cdvr_image_free(b);
    cdvr_image_free(c);
}

int main(void)
{
    CHECK(isinf(cdvr_psnr(0.0, 255.0)), "psnr of mse 0");
    CHECK(fabs(cdvr_psnr(1.0, 255.0) - 48.1308036) < 1e-6, "psnr(1, 255) = %g",
          cdvr_psnr(1.0, 255.0));
    test_volumes();
    test_float_volumes();
    test_images();
    return check_finish();
}
