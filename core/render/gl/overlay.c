/* core/render/gl/overlay.c - text on an 8-bit RGBA image (the window's overlay): one line, or
 * a line wrapped to the image's width, with stb_easy_font's segment glyphs rasterised as
 * rectangles on the CPU. No GL needed. */
#include "cdvr/gl.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__GNUC__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-braces"
#endif
#include <stb_easy_font.h>
#if defined(__GNUC__)
#pragma GCC diagnostic pop
#endif

#define OVERLAY_MAX_CHARS 200

typedef struct easy_vertex {
    float x, y, z;
    unsigned char color[4];
} easy_vertex;

static void darken_band(uint8_t *rgba, int width, int height, int x0, int y0, int x1, int y1)
{
    for (int y = y0 < 0 ? 0 : y0; y < y1 && y < height; y++)
        for (int x = x0 < 0 ? 0 : x0; x < x1 && x < width; x++)
            for (int c = 0; c < 3; c++) {
                uint8_t *p = rgba + 4 * ((size_t)y * (size_t)width + (size_t)x) + c;
                *p = (uint8_t)(*p * 3 / 10);
            }
}

static void fill_rect(uint8_t *rgba, int width, int height, int x0, int y0, int x1, int y1,
                      const uint8_t rgb[3])
{
    for (int y = y0 < 0 ? 0 : y0; y < y1 && y < height; y++)
        for (int x = x0 < 0 ? 0 : x0; x < x1 && x < width; x++) {
            uint8_t *p = rgba + 4 * ((size_t)y * (size_t)width + (size_t)x);
            p[0] = rgb[0];
            p[1] = rgb[1];
            p[2] = rgb[2];
            p[3] = 255;
        }
}

void cdvr_overlay_text(uint8_t *rgba, int width, int height, int x, int y, int scale,
                       const char *text, const uint8_t rgb[3])
{
    char line[OVERLAY_MAX_CHARS + 1];
    size_t len = 0;
    for (const char *s = text; *s && len < OVERLAY_MAX_CHARS; s++)
        line[len++] = (*s >= 32 && *s < 127) ? *s : ' '; /* one line, printable ASCII */
    line[len] = '\0';
    if (scale < 1)
        scale = 1;
    int text_w = stb_easy_font_width(line) * scale, text_h = stb_easy_font_height(line) * scale;
    darken_band(rgba, width, height, x - 2 * scale, y - scale, x + text_w + 2 * scale,
                y + text_h + scale);
    /* at most 4 vertices per segment; a glyph has fewer than 16 segments */
    size_t cap = (len + 1) * 64 * sizeof(easy_vertex);
    easy_vertex *quads = malloc(cap);
    if (!quads)
        return;
    unsigned char white[4] = {255, 255, 255, 255};
    int nquads = stb_easy_font_print(0.0f, 0.0f, line, white, quads, (int)cap);
    for (int q = 0; q < nquads; q++) {
        const easy_vertex *v = &quads[4 * q];
        int x0 = x + (int)(v[0].x * (float)scale), y0 = y + (int)(v[0].y * (float)scale);
        int x1 = x + (int)(v[2].x * (float)scale), y1 = y + (int)(v[2].y * (float)scale);
        fill_rect(rgba, width, height, x0, y0, x1, y1, rgb);
    }
    free(quads);
}

/* Width in pixels of the first n characters of s, drawn at `scale` (with `tail` appended). */
static int prefix_width(const char *s, size_t n, const char *tail, int scale)
{
    char buf[OVERLAY_MAX_CHARS + 8];
    if (n > OVERLAY_MAX_CHARS)
        n = OVERLAY_MAX_CHARS;
    memcpy(buf, s, n);
    snprintf(buf + n, sizeof buf - n, "%s", tail);
    return stb_easy_font_width(buf) * scale;
}

int cdvr_overlay_lines(uint8_t *rgba, int width, int height, int x, int y, int scale,
                       const char *text, const uint8_t rgb[3])
{
    if (scale < 1)
        scale = 1;
    int avail = width - x - 2 * scale, lines = 0;
    const char *s = text;
    while (*s && y < height) {
        while (*s == ' ')
            s++;
        if (!*s)
            break;
        size_t n = strlen(s), fit = 0;
        /* break before two spaces (between fields) where a field fits, else before one */
        for (int gap = 2; gap >= 1 && fit == 0; gap--)
            for (size_t k = 1; k <= n && k <= OVERLAY_MAX_CHARS; k++) {
                if (k < n && strncmp(s + k, "  ", (size_t)gap) != 0)
                    continue;
                if (prefix_width(s, k, "", scale) > avail)
                    break;
                fit = k;
            }
        char line[OVERLAY_MAX_CHARS + 8];
        size_t used = fit;
        if (fit == 0) { /* one word wider than the window: cut it, marked with '~' */
            size_t word = strcspn(s, " "), k = word < OVERLAY_MAX_CHARS ? word : OVERLAY_MAX_CHARS;
            while (k > 1 && prefix_width(s, k, "~", scale) > avail)
                k--;
            snprintf(line, sizeof line, "%.*s~", (int)k, s);
            used = word;
        } else {
            snprintf(line, sizeof line, "%.*s", (int)fit, s);
        }
        cdvr_overlay_text(rgba, width, height, x, y, scale, line, rgb);
        y += stb_easy_font_height(line) * scale + 2 * scale;
        s += used;
        lines++;
    }
    return lines;
}
