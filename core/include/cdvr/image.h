/* cdvr/image.h - RGBA float images produced by the renderers.
 *
 * Pixels are premultiplied RGBA floats in [0,1], accumulated front to back, *before* the
 * background is composited; row 0 is the top row, x grows to the right. The background is
 * kept beside the pixels and composited when the image is saved or compared:
 *   out = c + (1 - a) * background.
 */
#ifndef CDVR_IMAGE_H
#define CDVR_IMAGE_H

#include <stdint.h>

#include "cdvr/error.h"

typedef struct cdvr_image {
    int width, height;
    float *rgba;          /* width*height*4, premultiplied; 64-byte aligned when made by
                             cdvr_image_create* */
    float background[4];  /* straight RGBA, default opaque black */
} cdvr_image;

cdvr_status cdvr_image_create(int width, int height, cdvr_image **out, cdvr_error *err);
/* The same with the pixels left unset, for a renderer that writes every one of them (the
 * OpenCL ray caster: zeroing a 512^2 image cost 5-10% of a frame). */
cdvr_status cdvr_image_create_unset(int width, int height, cdvr_image **out, cdvr_error *err);
void cdvr_image_free(cdvr_image *img);
/* Pointer to the 4 floats of pixel (x, y). */
float *cdvr_image_pixel(const cdvr_image *img, int x, int y);
/* Composited pixel over the background as floats in [0,1] (rgb) and alpha of the result. */
void cdvr_image_composited(const cdvr_image *img, int x, int y, float out[4]);
/* 8-bit RGBA of the composited image, row 0 first; each channel round(clamp(x,0,1)*255)
 * (round half up). buf holds width*height*4 bytes. */
void cdvr_image_to_rgba8(const cdvr_image *img, uint8_t *buf);
/* 8-bit RGB of the image over its background, row 0 first: each channel
 * round(clamp(c + (1 - a) * bg_a * bg, 0, 1) * 255) of the premultiplied pixel (c, a) and the
 * straight background (bg, bg_a); with an opaque background (the default) these are the RGB
 * bytes of cdvr_image_to_rgba8. buf holds width*height*3 bytes. */
void cdvr_image_to_rgb8(const cdvr_image *img, uint8_t *buf);
/* Writes an 8-bit RGB PNG (cdvr_image_to_rgb8) through stb_image_write, to a temporary name
 * then renamed, so no partial file is left under path. */
cdvr_status cdvr_image_save_png(const cdvr_image *img, const char *path, cdvr_error *err);
/* The same with an alpha channel: 8-bit RGBA of cdvr_image_to_rgba8 (straight colour). */
cdvr_status cdvr_image_save_png_rgba(const cdvr_image *img, const char *path, cdvr_error *err);
/* Writes an 8-bit RGB baseline JPEG of cdvr_image_to_rgb8 through stb_image_write (quality
 * 1..100, stb's scale; 90 is visually lossless on renders), atomically like the PNG. */
cdvr_status cdvr_image_save_jpeg(const cdvr_image *img, const char *path, int quality,
                                 cdvr_error *err);

#endif
