/* core/render/image.c - RGBA float images, compositing and PNG output (cdvr/image.h). */
#include "cdvr/atomicfile.h"
#include "cdvr/image.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wsign-compare"
#include <stb_image_write.h>
#pragma GCC diagnostic pop

/* A new image; its pixels zeroed when `zero`. */
static cdvr_status image_new(int width, int height, int zero, cdvr_image **out, cdvr_error *err)
{
    *out = NULL;
    if (width <= 0 || height <= 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "image: size %dx%d must be positive", width,
                              height);
    size_t pixels, floats;
    if (!cdvr_size_mul((size_t)width, (size_t)height, &pixels) ||
        !cdvr_size_mul(pixels, 4 * sizeof(float), &floats) || floats > SIZE_MAX - 63)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "image: %dx%d overflows size_t", width,
                              height);
    cdvr_image *img = malloc(sizeof *img);
    /* 64-byte aligned (a cache line): the OpenCL ray caster writes whole lines of a packet's
     * pixels without reading them first (raycast.cl, store_pixels) */
    size_t padded = (floats + 63) & ~(size_t)63;
    float *rgba = !img ? NULL : aligned_alloc(64, padded);
    if (rgba && zero)
        memset(rgba, 0, floats);
    if (!rgba) {
        free(img);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "image: no memory for %dx%d pixels", width,
                              height);
    }
    img->width = width;
    img->height = height;
    img->rgba = rgba;
    img->background[0] = img->background[1] = img->background[2] = 0.0f;
    img->background[3] = 1.0f;
    *out = img;
    return CDVR_OK;
}

cdvr_status cdvr_image_create(int width, int height, cdvr_image **out, cdvr_error *err)
{
    return image_new(width, height, 1, out, err);
}

cdvr_status cdvr_image_create_unset(int width, int height, cdvr_image **out, cdvr_error *err)
{
    return image_new(width, height, 0, out, err);
}

void cdvr_image_free(cdvr_image *img)
{
    if (img) {
        free(img->rgba);
        free(img);
    }
}

float *cdvr_image_pixel(const cdvr_image *img, int x, int y)
{
    return img->rgba + 4 * ((size_t)y * (size_t)img->width + (size_t)x);
}

/* Premultiplied "over": pixel over the background. The result's colour is returned straight
 * (divided by its alpha) because that is what PNG stores; with the default opaque background
 * this is exactly c + (1 - a) * background. */
void cdvr_image_composited(const cdvr_image *img, int x, int y, float out[4])
{
    const float *c = cdvr_image_pixel(img, x, y);
    const float *bg = img->background;
    float rest = 1.0f - c[3];
    float alpha = c[3] + rest * bg[3];
    for (int i = 0; i < 3; i++) {
        float premul = c[i] + rest * bg[3] * bg[i];
        out[i] = alpha > 0.0f ? premul / alpha : 0.0f;
    }
    out[3] = alpha;
}

static uint8_t to_byte(float v)
{
    if (!(v > 0.0f))
        return 0; /* also NaN */
    if (v >= 1.0f)
        return 255;
    return (uint8_t)floorf(v * 255.0f + 0.5f);
}

void cdvr_image_to_rgba8(const cdvr_image *img, uint8_t *buf)
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float px[4];
            cdvr_image_composited(img, x, y, px);
            uint8_t *dst = buf + 4 * ((size_t)y * (size_t)img->width + (size_t)x);
            for (int c = 0; c < 4; c++)
                dst[c] = to_byte(px[c]);
        }
}

void cdvr_image_to_rgb8(const cdvr_image *img, uint8_t *buf)
{
    const float *bg = img->background;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *c = cdvr_image_pixel(img, x, y);
            float rest = (1.0f - c[3]) * bg[3];
            uint8_t *dst = buf + 3 * ((size_t)y * (size_t)img->width + (size_t)x);
            for (int i = 0; i < 3; i++)
                dst[i] = to_byte(c[i] + rest * bg[i]);
        }
}

typedef struct png_sink {
    FILE *file;
    int failed;
} png_sink;

static void png_write(void *context, void *data, int size)
{
    png_sink *sink = context;
    if (!sink->failed && fwrite(data, 1, (size_t)size, sink->file) != (size_t)size)
        sink->failed = 1;
}

/* Writes the encoded PNG (quality 0) or JPEG (quality 1..100) into the open temporary file;
 * returns 0 on success. */
static int write_image_file(FILE *file, const cdvr_image *img, const uint8_t *pixels,
                            int channels, int quality)
{
    png_sink sink = {file, 0};
    int ok = quality > 0 ? stbi_write_jpg_to_func(png_write, &sink, img->width, img->height,
                                                  channels, pixels, quality)
                         : stbi_write_png_to_func(png_write, &sink, img->width, img->height,
                                                  channels, pixels, img->width * channels);
    if (!ok)
        return -1;
    return sink.failed ? -1 : 0;
}

static cdvr_status save_image(const cdvr_image *img, const char *path, int channels,
                              int quality, cdvr_error *err)
{
    if (!img || !path || !*path)
        return cdvr_error_set(err, CDVR_ERR_ARG, "image: saving needs an image and a path");
    if (img->width > (1 << 28) / img->height)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: image %dx%d too large to save", path,
                              img->width, img->height);
    size_t bytes = (size_t)img->width * (size_t)img->height * (size_t)channels;
    uint8_t *pixels = malloc(bytes);
    if (!pixels)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: no memory for the image file", path);
    if (channels == 4)
        cdvr_image_to_rgba8(img, pixels);
    else
        cdvr_image_to_rgb8(img, pixels);
    cdvr_atomic_file af;
    cdvr_status st = cdvr_atomic_open(&af, path, err);
    if (st == CDVR_OK)
        st = cdvr_atomic_commit(&af, write_image_file(af.f, img, pixels, channels, quality) != 0,
                                err);
    free(pixels);
    return st;
}

static cdvr_status save_png(const cdvr_image *img, const char *path, int channels, cdvr_error *err)
{
    return save_image(img, path, channels, 0, err);
}

cdvr_status cdvr_image_save_jpeg(const cdvr_image *img, const char *path, int quality,
                                 cdvr_error *err)
{
    if (quality < 1 || quality > 100)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: JPEG quality %d outside 1..100",
                              path ? path : "image", quality);
    return save_image(img, path, 3, quality, err);
}

cdvr_status cdvr_image_save_png(const cdvr_image *img, const char *path, cdvr_error *err)
{
    return save_png(img, path, 3, err);
}

cdvr_status cdvr_image_save_png_rgba(const cdvr_image *img, const char *path, cdvr_error *err)
{
    return save_png(img, path, 4, err);
}
