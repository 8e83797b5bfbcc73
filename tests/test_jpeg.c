/* tests/test_jpeg.c - stills as JPEG (cdvr_image_save_jpeg, cdvr/image.h) prove: the file
 * written through stb_image_write reads back (stb_image) with the image's size and 3
 * channels, close to the 8-bit RGB of the image (PSNR above a floor measured on this
 * gradient-and-disc picture: 40.0 dB at quality 90, 34.5 dB at 50; floors 37 and 31 dB),
 * higher quality is closer; quality outside 1..100 and unwritable paths are errors, and no
 * partial file is left. */
#include <string.h>
#include <unistd.h>

#include "cdvr/image.h"
#include "check.h"

/* stb_image's unused static functions are reported at the end of the file: no pop */
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#define STBI_ONLY_JPEG
#include <stb/stb_image.h>

static cdvr_image *picture(void)
{
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_image_create(128, 96, &img, &err), err);
    for (int y = 0; y < 96; y++)
        for (int x = 0; x < 128; x++) {
            float *p = cdvr_image_pixel(img, x, y);
            float d = hypotf(x - 64.0f, y - 48.0f), a = d < 30 ? 1.0f : 0.3f;
            p[0] = a * x / 127.0f, p[1] = a * y / 95.0f, p[2] = a * 0.5f, p[3] = a;
        }
    return img;
}

static double psnr_file(const cdvr_image *img, const char *path)
{
    int w = 0, h = 0, n = 0;
    unsigned char *px = stbi_load(path, &w, &h, &n, 3);
    CHECK(px && w == img->width && h == img->height && n == 3, "%s: read back %dx%dx%d", path,
          w, h, n);
    if (!px)
        return 0;
    uint8_t *ref = malloc((size_t)w * h * 3);
    cdvr_image_to_rgb8(img, ref);
    double se = 0;
    for (size_t i = 0; i < (size_t)w * h * 3; i++)
        se += (px[i] - ref[i]) * (double)(px[i] - ref[i]);
    free(ref);
    stbi_image_free(px);
    double mse = se / ((double)w * h * 3);
    return mse > 0 ? 10 * log10(255.0 * 255.0 / mse) : 99;
}

int main(void)
{
    cdvr_image *img = picture();
    cdvr_error err;
    const char *path = "test_jpeg_out.jpg";
    CHECK_OK(cdvr_image_save_jpeg(img, path, 90, &err), err);
    double q90 = psnr_file(img, path);
    CHECK_OK(cdvr_image_save_jpeg(img, path, 50, &err), err);
    double q50 = psnr_file(img, path);
    printf("JPEG PSNR: quality 90 %.2f dB, quality 50 %.2f dB\n", q90, q50);
    CHECK(q90 >= 37.0, "quality 90: %.2f dB", q90);
    CHECK(q50 >= 31.0, "quality 50: %.2f dB", q50);
    CHECK(q90 > q50, "quality 90 (%.2f) not closer than 50 (%.2f)", q90, q50);
    unlink(path);
    CHECK(cdvr_image_save_jpeg(img, path, 0, &err) == CDVR_ERR_ARG, "quality 0 accepted");
    CHECK(cdvr_image_save_jpeg(img, path, 101, &err) == CDVR_ERR_ARG, "quality 101 accepted");
    CHECK(access(path, F_OK) != 0, "a file was left by a refused save");
    CHECK(cdvr_image_save_jpeg(img, "/nonexistent-dir/x.jpg", 90, &err) != CDVR_OK &&
              strstr(err.msg, "/nonexistent-dir/x.jpg"),
          "unwritable path: %s", err.msg);
    cdvr_image_free(img);
    return check_finish();
}
