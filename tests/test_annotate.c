/* tests/test_annotate.c - annotations on an image (cdvr/annotate.h, cdvr/text.h) prove:
 * the colour bar is drawn where cdvr_annotate_bar_box says, each row's left part in the TF's
 * colour at that row's data value (red at the top of a blue-to-red TF, blue at the bottom), its
 * opacity strip grey by opacity; orientation letters are the patient directions of the
 * screen's right / left / up / down for a camera in world (LPS, RAS) coordinates and are
 * drawn in their edge regions; title and time land in their corners; nothing asked leaves
 * the image unchanged; bad options are errors, not crashes. */
#include <string.h>

#include "cdvr/annotate.h"
#include "cdvr/text.h"
#include "check.h"

static cdvr_image *blank(int w, int h)
{
    cdvr_image *img = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_image_create(w, h, &img, &err), err);
    return img;
}

/* Number of pixels in [x0, x1) x [y0, y1) with any non-zero channel. */
static int lit(const cdvr_image *img, int x0, int y0, int x1, int y1)
{
    int n = 0;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            const float *p = cdvr_image_pixel(img, x, y);
            n += p[0] > 0 || p[1] > 0 || p[2] > 0 || p[3] > 0;
        }
    return n;
}

static void test_letters(void)
{
    char s[4];
    const double x[3] = {1, 0, 0}, my[3] = {0, -1, 0}, z[3] = {0, 0, 2}, o[3] = {1, 0.5, 0.1};
    CHECK(cdvr_annotate_letters(x, "LPS", s) == 0 && strcmp(s, "L") == 0, "+x LPS: %s", s);
    CHECK(cdvr_annotate_letters(x, "RAS", s) == 0 && strcmp(s, "R") == 0, "+x RAS: %s", s);
    CHECK(cdvr_annotate_letters(my, NULL, s) == 0 && strcmp(s, "A") == 0, "-y LPS: %s", s);
    CHECK(cdvr_annotate_letters(z, "LPS", s) == 0 && strcmp(s, "S") == 0, "+z: %s", s);
    CHECK(cdvr_annotate_letters(o, "LPS", s) == 0 && strcmp(s, "LP") == 0, "oblique: %s", s);
    const double zero[3] = {0, 0, 0};
    CHECK(cdvr_annotate_letters(zero, "LPS", s) == 0 && s[0] == 0, "zero: %s", s);
    CHECK(cdvr_annotate_letters(x, "LLS", s) == -1, "bad space accepted");
    CHECK(cdvr_annotate_letters(x, "LPSX", s) == -1, "long space accepted");
}

static cdvr_tf blue_to_red(void)
{
    const cdvr_tf_point pts[] = {{-1000, 0, 0, 1, 0}, {1000, 1, 0, 0, 0.5}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 0, &err), err);
    CHECK_OK(cdvr_tf_set_window(&tf, -1000, 1000, &err), err);
    return tf;
}

static void test_colorbar(void)
{
    cdvr_tf tf = blue_to_red();
    cdvr_image *img = blank(256, 256);
    cdvr_annotate_opts o = {.colorbar = 1, .tf = &tf, .unit = "HU"};
    cdvr_error err;
    CHECK_OK(cdvr_annotate(img, &o, &err), err);
    int box[4];
    cdvr_annotate_bar_box(256, 256, &o, box);
    CHECK(box[0] > 128 && box[2] < 256 && box[1] > 100 && box[3] < 240, "bar box %d %d %d %d",
          box[0], box[1], box[2], box[3]);
    int xc = box[0] + 1; /* colour part */
    const float *top = cdvr_image_pixel(img, xc, box[1]);
    const float *bot = cdvr_image_pixel(img, xc, box[3] - 1);
    CHECK(top[0] > 0.99f && top[2] < 0.01f && top[3] == 1.0f, "top %g %g %g", top[0], top[1], top[2]);
    CHECK(bot[2] > 0.99f && bot[0] < 0.01f, "bottom %g %g %g", bot[0], bot[1], bot[2]);
    int ymid = (box[1] + box[3]) / 2; /* value ~0: half red, half blue */
    float want[4];
    double f = (ymid - box[1] + 0.5) / (box[3] - box[1]);
    cdvr_tf_eval(&tf, 1000 - f * 2000, want);
    const float *mid = cdvr_image_pixel(img, xc, ymid);
    CHECK(fabsf(mid[0] - want[0]) < 0.01f && fabsf(mid[2] - want[2]) < 0.01f,
          "middle %g %g, TF %g %g", mid[0], mid[2], want[0], want[2]);
    /* opacity strip: white where opacity is largest (top), black at the bottom (a = 0) */
    const float *otop = cdvr_image_pixel(img, box[2] - 2, box[1]);
    const float *obot = cdvr_image_pixel(img, box[2] - 2, box[3] - 1);
    CHECK(otop[0] > 0.99f && obot[0] < 0.01f, "opacity strip %g .. %g", otop[0], obot[0]);
    CHECK(lit(img, box[2] + 1, box[1] - 8, 256, box[3] + 8) > 30, "no tick labels");
    CHECK(lit(img, 0, 0, box[0] - 2, 256) == 0, "drew left of the bar");
    cdvr_image_free(img);
}

static void test_axes(void)
{
    /* looking along +y (posterior) with up +z: screen right is +x = L in LPS */
    cdvr_camera cam = {.eye = {0, -10, 0}, .center = {0, 0, 0}, .up = {0, 0, 1}, .fov = 30,
                       .width = 256, .height = 256};
    double f[3], u[3], r[3];
    cdvr_camera_basis(&cam, f, u, r);
    char s[4];
    cdvr_annotate_letters(r, "LPS", s);
    CHECK(strcmp(s, "L") == 0, "screen right %s (r = %g %g %g)", s, r[0], r[1], r[2]);
    cdvr_image *img = blank(256, 256);
    cdvr_annotate_opts o = {.axes = 1, .camera = &cam};
    cdvr_error err;
    CHECK_OK(cdvr_annotate(img, &o, &err), err);
    CHECK(lit(img, 200, 50, 256, 90) > 10, "no right letter");
    CHECK(lit(img, 0, 110, 40, 146) > 10, "no left letter");
    CHECK(lit(img, 110, 0, 146, 40) > 10, "no top letter");
    CHECK(lit(img, 110, 216, 146, 256) > 10, "no bottom letter");
    CHECK(lit(img, 60, 60, 196, 196) == 0, "drew in the middle");
    /* the right letter is an L: the same pixels as L drawn there */
    cdvr_image *ref = blank(256, 256);
    const float white[3] = {1, 1, 1};
    int ls = 2, m = 6;
    cdvr_text_draw(ref, 256 - m - cdvr_text_width("L", ls), (int)(0.25 * 256), "L", ls, white, 1);
    int diff = 0;
    for (int y = 40; y < 100; y++)
        for (int x = 200; x < 256; x++)
            diff += cdvr_image_pixel(img, x, y)[0] != cdvr_image_pixel(ref, x, y)[0];
    CHECK(diff == 0, "right letter differs from 'L' in %d pixels", diff);
    cdvr_image_free(ref);
    cdvr_image_free(img);
}

static void test_text_and_nothing(void)
{
    cdvr_image *img = blank(256, 256);
    cdvr_annotate_opts none = {0};
    cdvr_error err;
    CHECK_OK(cdvr_annotate(img, &none, &err), err);
    CHECK(lit(img, 0, 0, 256, 256) == 0, "nothing asked, something drawn");
    cdvr_annotate_opts o = {.title = "neghip", .time = "t = 3 / 25"};
    CHECK_OK(cdvr_annotate(img, &o, &err), err);
    CHECK(lit(img, 0, 0, 128, 40) > 20, "no title top-left");
    CHECK(lit(img, 0, 220, 128, 256) > 20, "no time bottom-left");
    CHECK(lit(img, 128, 0, 256, 256) == 0, "title/time spilled right");
    CHECK(cdvr_text_width("abc", 2) == 2 * cdvr_text_width("abc", 1), "text scale");
    cdvr_annotate_opts bad = {.colorbar = 1};
    CHECK(cdvr_annotate(img, &bad, &err) == CDVR_ERR_ARG, "colour bar without a TF");
    cdvr_annotate_opts bad2 = {.axes = 1};
    CHECK(cdvr_annotate(img, &bad2, &err) == CDVR_ERR_ARG, "axes without a camera");
    cdvr_camera cam = {.eye = {0, -10, 0}, .center = {0, 0, 0}, .up = {0, 0, 1}, .fov = 30,
                       .width = 256, .height = 256};
    cdvr_annotate_opts bad3 = {.axes = 1, .camera = &cam, .space = "XYZ"};
    CHECK(cdvr_annotate(img, &bad3, &err) == CDVR_ERR_ARG && strstr(err.msg, "XYZ"),
          "bad space: %s", err.msg);
    cdvr_image *tiny = blank(3, 2); /* everything clipped, nothing out of bounds */
    cdvr_tf tf = blue_to_red();
    cdvr_annotate_opts all = {.colorbar = 1, .tf = &tf, .axes = 1, .camera = &cam,
                              .title = "a long title that does not fit", .time = "t"};
    CHECK_OK(cdvr_annotate(tiny, &all, &err), err);
    cdvr_image_free(tiny);
    cdvr_image_free(img);
}

int main(void)
{
    test_letters();
    test_colorbar();
    test_axes();
    test_text_and_nothing();
    return check_finish();
}
