/* tests/test_image.c - PNG written and readable, compositing over the background, rgba8
 * rounding, bad paths and sizes; an image made with its pixels unset. */
#include "check.h"
#include "cdvr/image.h"

#include <stdint.h>
#include <string.h>
#include <unistd.h>

#define STB_IMAGE_IMPLEMENTATION
#define STBI_ONLY_PNG
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <stb/stb_image.h>
#pragma GCC diagnostic pop

static void set_pixel(cdvr_image *img, int x, int y, float r, float g, float b, float a)
{
    float *p = cdvr_image_pixel(img, x, y);
    p[0] = r, p[1] = g, p[2] = b, p[3] = a;
}

static void test_compositing(void)
{
    cdvr_image *img;
    cdvr_error err;
    CHECK_OK(cdvr_image_create(3, 2, &img, &err), err);
    CHECK(img->background[3] == 1.0f && img->background[0] == 0.0f, "default background");
    CHECK(cdvr_image_pixel(img, 2, 1) == img->rgba + 4 * 5, "pixel addressing");
    img->background[0] = 1.0f; /* opaque red */
    set_pixel(img, 0, 0, 0.0f, 0.25f, 0.0f, 0.5f); /* premultiplied half-transparent green */
    float out[4];
    cdvr_image_composited(img, 0, 0, out);
    CHECK(fabsf(out[0] - 0.5f) < 1e-7f && fabsf(out[1] - 0.25f) < 1e-7f && out[3] == 1.0f,
          "composited %g %g %g %g", out[0], out[1], out[2], out[3]);
    cdvr_image_composited(img, 1, 0, out); /* empty pixel shows the background */
    CHECK(out[0] == 1.0f && out[1] == 0.0f && out[3] == 1.0f, "empty pixel %g %g", out[0],
          out[3]);
    /* transparent background: colour comes back straight, alpha is the pixel's */
    img->background[3] = 0.0f;
    cdvr_image_composited(img, 0, 0, out);
    CHECK(fabsf(out[1] - 0.5f) < 1e-7f && fabsf(out[3] - 0.5f) < 1e-7f, "straight %g %g",
          out[1], out[3]);
    cdvr_image_free(img);
}

static void test_rgba8_rounding(void)
{
    cdvr_image *img;
    cdvr_error err;
    CHECK_OK(cdvr_image_create(2, 1, &img, &err), err);
    /* 0.5/255 -> rounds half up to 1; 1.49/255 -> 1; values outside [0,1] clamp */
    set_pixel(img, 0, 0, 0.5f / 255.0f, 1.49f / 255.0f, 2.0f, 1.0f);
    set_pixel(img, 1, 0, -1.0f, 128.5f / 255.0f, 254.4f / 255.0f, 1.0f);
    uint8_t buf[8];
    cdvr_image_to_rgba8(img, buf);
    uint8_t want[8] = {1, 1, 255, 255, 0, 129, 254, 255};
    for (int i = 0; i < 8; i++)
        CHECK(buf[i] == want[i], "byte %d = %d, want %d", i, buf[i], want[i]);
    cdvr_image_free(img);
}

static void test_png(void)
{
    cdvr_image *img;
    cdvr_error err;
    CHECK_OK(cdvr_image_create(7, 5, &img, &err), err);
    for (int y = 0; y < 5; y++)
        for (int x = 0; x < 7; x++)
            set_pixel(img, x, y, x / 6.0f, y / 4.0f, 0.0f, 1.0f);
    const char *path = "test_image_out.png";
    unlink(path);
    CHECK_OK(cdvr_image_save_png(img, path, &err), err);
    FILE *f = fopen(path, "rb");
    CHECK(f != NULL, "PNG not created");
    if (f) {
        unsigned char head[8];
        const unsigned char magic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
        CHECK(fread(head, 1, 8, f) == 8 && memcmp(head, magic, 8) == 0, "PNG signature");
        fclose(f);
    }
    int w = 0, h = 0, n = 0;
    unsigned char *pix = stbi_load(path, &w, &h, &n, 4);
    CHECK(pix != NULL && w == 7 && h == 5 && n == 3, "read back %dx%d, %d channels (RGB)", w, h, n);
    if (pix) {
        uint8_t want[7 * 5 * 4];
        cdvr_image_to_rgba8(img, want);
        CHECK(memcmp(pix, want, sizeof want) == 0, "pixels differ after read back");
        CHECK(pix[4 * 6] == 255 && pix[4 * 7 * 4 + 1] == 255 && pix[1] == 0,
              "top-left / bottom row orientation");
        stbi_image_free(pix);
    }
    /* with alpha: RGBA, straight colour; a half-transparent pixel over a transparent
     * background keeps its alpha, and RGB composites it over black */
    img->background[3] = 0.0f;
    set_pixel(img, 0, 0, 0.5f, 0.25f, 0.0f, 0.5f);
    CHECK_OK(cdvr_image_save_png_rgba(img, path, &err), err);
    pix = stbi_load(path, &w, &h, &n, 0);
    CHECK(pix != NULL && n == 4 && pix[0] == 255 && pix[1] == 128 && pix[3] == 128,
          "RGBA: %d channels, first pixel %d %d %d", n, pix ? pix[0] : -1, pix ? pix[1] : -1,
          pix ? pix[3] : -1);
    stbi_image_free(pix);
    CHECK_OK(cdvr_image_save_png(img, path, &err), err);
    pix = stbi_load(path, &w, &h, &n, 0);
    CHECK(pix != NULL && n == 3 && pix[0] == 128 && pix[1] == 64,
          "RGB over a transparent background: %d %d", pix ? pix[0] : -1, pix ? pix[1] : -1);
    stbi_image_free(pix);
    unlink(path);
    /* an unwritable path: error naming it, no file left */
    CHECK(cdvr_image_save_png(img, "/nonexistent-dir/x.png", &err) == CDVR_ERR_IO,
          "bad path accepted");
    CHECK(strstr(err.msg, "/nonexistent-dir/x.png") != NULL, "message: %s", err.msg);
    cdvr_image_free(img);
}

static void test_bad_sizes(void)
{
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK(cdvr_image_create(0, 5, &img, &err) == CDVR_ERR_ARG && !img, "width 0 accepted");
    CHECK(cdvr_image_create(5, -1, &img, &err) == CDVR_ERR_ARG, "height -1 accepted");
    CHECK(cdvr_image_create_unset(0, 5, &img, &err) == CDVR_ERR_ARG && !img,
          "unset: width 0 accepted");
}

/* An unset image has the size and background of a zeroed one; its pixels can be written. */
static void test_unset(void)
{
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_image_create_unset(3, 2, &img, &err), err);
    CHECK(img->width == 3 && img->height == 2 && img->background[3] == 1.0f &&
              img->background[0] == 0.0f, "unset image: size or background");
    for (int i = 0; i < 3 * 2 * 4; i++)
        img->rgba[i] = 0.5f;
    CHECK(cdvr_image_pixel(img, 2, 1)[3] == 0.5f, "unset image: pixel written");
    cdvr_image_free(img);
}

int main(void)
{
    test_compositing();
    test_rgba8_rounding();
    test_png();
    test_bad_sizes();
    test_unset();
    return check_finish();
}
