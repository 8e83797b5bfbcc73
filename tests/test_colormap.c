/* tests/test_colormap.c - colour maps with separate opacity and the automatic window
 * (cdvr/tf.h) prove: cdvr_tf_init_colormap equals the colour map at its points and the
 * opacity function at its own (the ramp by default), on the union of both point sets;
 * cdvr_tf_percentile_window picks the codes at the 1% and 99% quantiles of a frame's
 * histogram and maps them to data units, and falls back to min..max for a nearly constant
 * frame; an auto_range TF's table follows that window, cdvr_tf_set_window refuses it (a
 * caller without the data must not ignore it), and cdvr_tf_rescale_auto pins it to data
 * values of a u16 frame (quantised over its window first); cdvr_tf_misses_window tells an
 * absolute TF that shows nothing of a data range from one that shows something. */
#include <string.h>

#include "cdvr/tf.h"
#include "check.h"

static void test_colormap(void)
{
    const double cmap[3][4] = {{0, 1, 0, 0}, {0.5, 0, 1, 0}, {1, 0, 0, 1}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init_colormap(&tf, cmap, 3, NULL, 0, 0, &err), err);
    CHECK(tf.normalized && tf.npoints == 3, "ramp: %zu points", tf.npoints);
    float c[4];
    cdvr_tf_eval(&tf, 0.25, c);
    CHECK(fabsf(c[0] - 0.5f) < 1e-6f && fabsf(c[1] - 0.5f) < 1e-6f && fabsf(c[3] - 0.25f) < 1e-6f,
          "ramp at 0.25: %g %g %g %g", c[0], c[1], c[2], c[3]);
    const double alpha[3][2] = {{0.8, 1.0}, {0.2, 0.0}, {0.3, 0.5}}; /* any order */
    CHECK_OK(cdvr_tf_init_colormap(&tf, cmap, 3, alpha, 3, 1.0, &err), err);
    CHECK(tf.npoints == 6 && tf.unit == 1.0, "merged %zu points", tf.npoints);
    cdvr_tf_eval(&tf, 0.3, c);
    CHECK(fabsf(c[3] - 0.5f) < 1e-6f && fabsf(c[0] - 0.4f) < 1e-6f && fabsf(c[1] - 0.6f) < 1e-6f,
          "at 0.3: %g %g %g %g", c[0], c[1], c[2], c[3]);
    cdvr_tf_eval(&tf, 0.1, c);
    CHECK(c[3] == 0.0f, "below the first opacity point: %g", c[3]);
    cdvr_tf_eval(&tf, 0.9, c);
    CHECK(c[3] == 1.0f && fabsf(c[2] - 0.8f) < 1e-6f, "at 0.9: %g %g", c[2], c[3]);
    const double bad[2][4] = {{0.5, 0, 0, 0}, {0.2, 1, 1, 1}};
    CHECK(cdvr_tf_init_colormap(&tf, bad, 2, NULL, 0, 0, &err) == CDVR_ERR_ARG,
          "decreasing x accepted");
    const double bada[1][2] = {{0.5, 2.0}};
    CHECK(cdvr_tf_init_colormap(&tf, cmap, 3, bada, 1, 0, &err) == CDVR_ERR_ARG,
          "opacity 2 accepted");
    double big[CDVR_TF_MAX_POINTS][4], bigalpha[CDVR_TF_MAX_POINTS][2];
    for (int i = 0; i < CDVR_TF_MAX_POINTS; i++) {
        big[i][0] = i / (CDVR_TF_MAX_POINTS - 1.0), big[i][1] = big[i][2] = big[i][3] = 0.5;
        bigalpha[i][0] = (i + 0.5) / CDVR_TF_MAX_POINTS, bigalpha[i][1] = 0.5;
    }
    CHECK(cdvr_tf_init_colormap(&tf, big, CDVR_TF_MAX_POINTS, bigalpha, CDVR_TF_MAX_POINTS, 0,
                                &err) == CDVR_ERR_ARG,
          "too many merged points accepted");
}

static void test_percentiles(void)
{
    const size_t dims[3] = {10, 10, 10};
    cdvr_volume *v = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &v, &err), err);
    uint8_t *d = v->data; /* codes 0..249 four times each: quantiles known */
    for (int i = 0; i < 1000; i++)
        d[i] = (uint8_t)(i / 4);
    const double window[2] = {-1000, 1550}; /* code q stands for -1000 + 10 q */
    double w[2];
    CHECK_OK(cdvr_tf_percentile_window(v, 0, window, 0.01, 0.99, w, &err), err);
    /* 1% of 1000 = 10 voxels: code 2 (cumulative 12); 99% = 990: code 247 (cumulative 992) */
    CHECK(fabs(w[0] - (-980)) < 1e-9 && fabs(w[1] - 1470) < 1e-9, "window %g %g", w[0], w[1]);
    memset(d, 7, 1000);
    d[0] = 3, d[999] = 200; /* nearly constant: quantiles coincide, min..max instead */
    CHECK_OK(cdvr_tf_percentile_window(v, 0, window, 0.01, 0.99, w, &err), err);
    CHECK(fabs(w[0] - (-970)) < 1e-9 && fabs(w[1] - 1000) < 1e-9, "fallback %g %g", w[0], w[1]);
    CHECK(cdvr_tf_percentile_window(v, 1, window, 0.01, 0.99, w, &err) == CDVR_ERR_ARG,
          "frame out of range");
    CHECK(cdvr_tf_percentile_window(v, 0, window, 0.5, 0.5, w, &err) == CDVR_ERR_ARG,
          "empty percentile range");
    /* an auto TF: its fractions are of the percentile window */
    for (int i = 0; i < 1000; i++)
        d[i] = (uint8_t)(i / 4);
    const cdvr_tf_point ramp[2] = {{0, 0, 0, 0, 0}, {1, 1, 1, 1, 1}};
    cdvr_tf tf;
    CHECK_OK(cdvr_tf_init_normalized(&tf, ramp, 2, 0, &err), err);
    tf.auto_range = 1;
    double used[2];
    CHECK_OK(cdvr_tf_apply_window(&tf, window, v, 0, used, &err), err);
    CHECK(used[0] == w[0] || fabs(used[0] - (-980)) < 1e-9, "used %g", used[0]);
    CHECK(tf.table[2][3] == 0.0f && tf.table[0][3] == 0.0f, "below p1: %g", tf.table[2][3]);
    CHECK(tf.table[247][3] == 1.0f && tf.table[255][3] == 1.0f, "above p99: %g",
          tf.table[247][3]);
    CHECK(fabsf(tf.table[124][3] - (float)((124 - 2) / 245.0)) < 1e-6f, "middle %g",
          tf.table[124][3]);
    CHECK(cdvr_tf_apply_window(&tf, window, NULL, 0, used, &err) == CDVR_ERR_ARG,
          "auto without data");
    CHECK(cdvr_tf_set_window(&tf, -1000, 1550, &err) == CDVR_ERR_UNSUPPORTED &&
              strstr(err.msg, "range=\"auto\""),
          "set_window ignored auto: %s", err.msg);
    tf.auto_range = 0; /* not auto: the plain window */
    CHECK_OK(cdvr_tf_apply_window(&tf, window, NULL, 0, used, &err), err);
    CHECK(used[0] == -1000 && fabsf(tf.table[51][3] - 0.2f) < 1e-6f, "plain %g", tf.table[51][3]);
    cdvr_volume_free(v);
}

static void test_rescale_auto(void)
{
    const size_t dims[3] = {20, 10, 5};
    cdvr_volume *v = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_create(dims, 2, CDVR_TYPE_U16, &v, &err), err);
    uint16_t *d = v->data;
    for (int i = 0; i < 2000; i++)
        d[i] = (uint16_t)(i < 1000 ? (i / 4) * 10 : 2550); /* frame 0: 0..2490, frame 1: 2550 */
    const cdvr_tf_point ramp[2] = {{0, 0, 0, 0, 0}, {1, 1, 1, 1, 1}};
    cdvr_tf tf;
    CHECK_OK(cdvr_tf_init_normalized(&tf, ramp, 2, 0, &err), err);
    tf.auto_range = 1;
    CHECK_OK(cdvr_tf_rescale_auto(&tf, v, 0, &err), err);
    /* window 0..2550 (both frames): code q = value / 10; p1 = code 2, p99 = code 247 */
    CHECK(!tf.normalized && !tf.auto_range, "still normalised / auto");
    CHECK(fabs(tf.points[0].value - 20) < 1e-9 && fabs(tf.points[1].value - 2470) < 1e-9,
          "pinned to %g .. %g", tf.points[0].value, tf.points[1].value);
    CHECK(cdvr_tf_rescale_auto(&tf, v, 0, &err) == CDVR_ERR_ARG, "rescaled twice");
    CHECK_OK(cdvr_tf_init_normalized(&tf, ramp, 2, 0, &err), err);
    tf.auto_range = 1;
    CHECK(cdvr_tf_rescale_auto(&tf, v, 2, &err) == CDVR_ERR_ARG, "frame 3 of 2");
    cdvr_volume_free(v);
}

static void test_misses(void)
{
    const cdvr_tf_point lung[] = {{-1000, 0, 0, 0, 0}, {-600, 0, 0, 0, 0}, {-599, 1, 1, 1, 0.15},
                                  {-400, 1, 1, 1, 0.15}, {-399, 0, 0, 0, 0}, {2952, 0, 0, 0, 0}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, lung, 6, 1, &err), err);
    CHECK(cdvr_tf_misses_window(&tf, 0, 255), "lung on 0..255 shows something?");
    CHECK(!cdvr_tf_misses_window(&tf, -1024, 3071), "lung on a CT range misses");
    CHECK(!cdvr_tf_misses_window(&tf, -500, -450), "inside the visible band misses");
    CHECK(cdvr_tf_misses_window(&tf, -3000, -1500), "below every point shows something?");
    const cdvr_tf_point bone[] = {{-16, 0, 0, 0, 0}, {641, 1, 1, 1, 0.7}};
    CHECK_OK(cdvr_tf_init(&tf, bone, 2, 1, &err), err);
    CHECK(!cdvr_tf_misses_window(&tf, 0, 255), "bone ramp on 0..255 misses");
    CHECK(!cdvr_tf_misses_window(&tf, 2000, 3000), "constant opaque end misses");
    const cdvr_tf_point zero[] = {{0, 0, 0, 0, 0}, {1, 0, 0, 0, 0}};
    CHECK_OK(cdvr_tf_init_normalized(&tf, zero, 2, 0, &err), err);
    CHECK(!cdvr_tf_misses_window(&tf, 0, 255), "a normalised TF is never an absolute miss");
}

int main(void)
{
    test_colormap();
    test_percentiles();
    test_rescale_auto();
    test_misses();
    return check_finish();
}
