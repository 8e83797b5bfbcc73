/* tests/test_overlay.c - the window's overlay text (core/render/gl/overlay.c; plain C, in every
 * build): cdvr_overlay_lines wraps a long line at spaces into lines that fit the image, draws
 * every glyph of it (the same lit pixels as one unwrapped line on a wide image), keeps fields
 * (two spaces apart) whole where they fit, cuts a word wider than the image with '~', and a
 * short text stays one line. */
#include "check.h"

#include "cdvr/gl.h"

#include <string.h>

static const uint8_t white[3] = {255, 255, 255};

/* Lit (text-coloured) pixels of an image cleared to mid grey, and the rightmost lit column. */
static size_t lit(const uint8_t *rgba, int width, int height, int *max_x)
{
    size_t n = 0;
    *max_x = -1;
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            const uint8_t *p = rgba + 4 * ((size_t)y * (size_t)width + (size_t)x);
            if (p[0] == 255 && p[1] == 255 && p[2] == 255) {
                n++;
                if (x > *max_x)
                    *max_x = x;
            }
        }
    return n;
}

static uint8_t *grey(int width, int height)
{
    uint8_t *rgba = malloc((size_t)width * (size_t)height * 4);
    for (size_t i = 0; rgba && i < (size_t)width * (size_t)height; i++) {
        rgba[4 * i] = rgba[4 * i + 1] = rgba[4 * i + 2] = 128;
        rgba[4 * i + 3] = 255;
    }
    return rgba;
}

int main(void)
{
    const char *text = "t 3/10 playing  S4T3  fixed: S4T3 (the first variant)  raycast (cl)  "
                       "12.5 ms (80.0 fps)";
    int wide_w = 3000, narrow_w = 200, h = 240, max_x;
    uint8_t *wide = grey(wide_w, h), *narrow = grey(narrow_w, h);
    if (!wide || !narrow)
        return 1;
    CHECK(cdvr_overlay_lines(wide, wide_w, h, 6, 6, 2, text, white) == 1, "one line when it fits");
    size_t all = lit(wide, wide_w, h, &max_x);
    CHECK(all > 0 && max_x > narrow_w, "the text is wider than the narrow image (%d px)", max_x);
    int lines = cdvr_overlay_lines(narrow, narrow_w, h, 6, 6, 2, text, white);
    CHECK(lines > 2, "wrapped into %d lines", lines);
    size_t wrapped = lit(narrow, narrow_w, h, &max_x);
    CHECK(wrapped == all, "every glyph drawn: %zu lit pixels of %zu", wrapped, all);
    CHECK(max_x < narrow_w - 2, "lines fit the width: rightmost text column %d of %d", max_x, narrow_w);

    /* a word wider than the image is cut, the rest still shown */
    uint8_t *tiny = grey(60, 100);
    int n = cdvr_overlay_lines(tiny, 60, 100, 6, 6, 2, "abcdefghijklmnop xy", white);
    size_t tiny_lit = lit(tiny, 60, 100, &max_x);
    CHECK(n == 2 && tiny_lit > 0 && max_x < 58, "long word cut: %d lines, rightmost %d", n, max_x);
    /* only lines that start inside the image are drawn */
    CHECK(cdvr_overlay_lines(tiny, 60, 30, 6, 6, 2, "aaaa bbbb cccc dddd eeee", white) == 1,
          "lines below the image are not drawn");
    CHECK(cdvr_overlay_lines(tiny, 60, 100, 6, 6, 2, "   ", white) == 0, "blank text: no line");
    /* fields (two spaces apart) stay whole where they fit: "aa" / "b cccccc", not "aa  b" /
     * "cccccc" (which single-space breaking gives: "aa  b" fits too) */
    uint8_t *a = grey(400, 100), *b = grey(400, 100);
    cdvr_overlay_lines(a, 400, 100, 6, 6, 2, "b cccccc", white);
    size_t field = lit(a, 400, 100, &max_x);
    int two_fields_w = max_x + 20; /* "b cccccc" fits, the whole text does not */
    int k = cdvr_overlay_lines(b, two_fields_w, 100, 6, 6, 2, "aa  b cccccc", white);
    size_t below = 0;
    for (int y = 30; y < 100; y++) /* the second line */
        for (int x = 0; x < two_fields_w; x++)
            below += b[4 * ((size_t)y * (size_t)two_fields_w + (size_t)x)] == 255;
    CHECK(k == 2 && below == field, "break between fields: %d lines, %zu of %zu lit below", k, below, field);
    free(a);
    free(b);
    free(tiny);
    free(wide);
    free(narrow);
    return check_finish();
}
