/* core/render/text.c - bitmap text on cdvr images (cdvr/text.h): stb_easy_font's quads
 * rasterised as rectangles. */
#include "cdvr/text.h"

#include <stdlib.h>

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wmissing-braces"
#include <stb_easy_font.h>
#pragma GCC diagnostic pop

typedef struct easy_vertex {
    float x, y, z;
    unsigned char color[4];
} easy_vertex;

/* text as one printable line of at most CDVR_TEXT_MAX_CHARS. */
static void clean_line(const char *text, char line[CDVR_TEXT_MAX_CHARS + 1])
{
    size_t len = 0;
    for (const char *s = text ? text : ""; *s && len < CDVR_TEXT_MAX_CHARS; s++)
        line[len++] = (*s >= 32 && *s < 127) ? *s : ' ';
    line[len] = '\0';
}

int cdvr_text_width(const char *text, int scale)
{
    char line[CDVR_TEXT_MAX_CHARS + 1];
    clean_line(text, line);
    return stb_easy_font_width(line) * (scale < 1 ? 1 : scale);
}

int cdvr_text_height(const char *text, int scale)
{
    char line[CDVR_TEXT_MAX_CHARS + 1];
    clean_line(text, line);
    return stb_easy_font_height(line) * (scale < 1 ? 1 : scale);
}

void cdvr_image_fill_rect(cdvr_image *img, int x0, int y0, int x1, int y1, const float c[4])
{
    x0 = x0 < 0 ? 0 : x0;
    y0 = y0 < 0 ? 0 : y0;
    x1 = x1 > img->width ? img->width : x1;
    y1 = y1 > img->height ? img->height : y1;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            float *p = cdvr_image_pixel(img, x, y);
            for (int k = 0; k < 4; k++)
                p[k] = c[k] + (1.0f - c[3]) * p[k];
        }
}

static void draw_once(cdvr_image *img, int x, int y, const char *line, int scale,
                      const float c[4], const easy_vertex *quads, int nquads)
{
    (void)line;
    for (int q = 0; q < nquads; q++) {
        const easy_vertex *v = &quads[4 * q];
        int x0 = x + (int)(v[0].x * (float)scale), y0 = y + (int)(v[0].y * (float)scale);
        int x1 = x + (int)(v[2].x * (float)scale), y1 = y + (int)(v[2].y * (float)scale);
        cdvr_image_fill_rect(img, x0, y0, x1, y1, c);
    }
}

void cdvr_text_draw(cdvr_image *img, int x, int y, const char *text, int scale,
                    const float rgb[3], int shadow)
{
    char line[CDVR_TEXT_MAX_CHARS + 1];
    clean_line(text, line);
    if (scale < 1)
        scale = 1;
    size_t len = 0;
    while (line[len])
        len++;
    /* at most 4 vertices per segment; a glyph has fewer than 16 segments */
    size_t cap = (len + 1) * 64 * sizeof(easy_vertex);
    easy_vertex *quads = malloc(cap);
    if (!quads)
        return; /* text is decoration: nothing drawn rather than a failed render */
    unsigned char white[4] = {255, 255, 255, 255};
    int nquads = stb_easy_font_print(0.0f, 0.0f, line, white, quads, (int)cap);
    if (shadow) {
        const float dark[4] = {0.0f, 0.0f, 0.0f, 1.0f};
        draw_once(img, x + scale, y + scale, line, scale, dark, quads, nquads);
    }
    const float c[4] = {rgb[0], rgb[1], rgb[2], 1.0f};
    draw_once(img, x, y, line, scale, c, quads, nquads);
    free(quads);
}
