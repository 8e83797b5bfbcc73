/* cdvr/text.h - bitmap text on cdvr images (stb_easy_font's segment glyphs, the font the
 * window overlay uses), for annotations.
 *
 * Text is one line of printable ASCII (other bytes draw as spaces); a glyph cell is about 6 x 12
 * font pixels (stb_easy_font_width / _height), each font pixel drawn as scale x scale image
 * pixels. (x, y) is the top-left corner of the text in image pixels (y down); what falls
 * outside the image is clipped. Drawing composites an opaque colour over the image's
 * premultiplied pixels (cdvr/image.h): the pixel becomes (rgb, 1).
 */
#ifndef CDVR_TEXT_H
#define CDVR_TEXT_H

#include "cdvr/image.h"

#define CDVR_TEXT_MAX_CHARS 256 /* longer text is cut */

/* Width and height in image pixels of text at scale (>= 1). */
int cdvr_text_width(const char *text, int scale);
int cdvr_text_height(const char *text, int scale);
/* Draws text at (x, y) in colour rgb (straight, in [0, 1]); with shadow, a one-pixel dark
 * copy first (down-right), so the text reads on bright pictures too. */
void cdvr_text_draw(cdvr_image *img, int x, int y, const char *text, int scale,
                    const float rgb[3], int shadow);
/* Fills the rectangle [x0, x1) x [y0, y1) (clipped) with the premultiplied colour c (c[3] is
 * its alpha: over-composited). */
void cdvr_image_fill_rect(cdvr_image *img, int x0, int y0, int x1, int y1, const float c[4]);

#endif
