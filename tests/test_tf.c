/* tests/test_tf.c - transfer functions: piecewise linear, constant outside, sorting,
 * bad points rejected, table lookup. */
#include "check.h"

#include <string.h>

#include "cdvr/tf.h"

static int near(double a, double b, double tol)
{
    return fabs(a - b) <= tol;
}

static void test_piecewise_linear(void)
{
    cdvr_tf_point pts[] = {{50, 0, 0, 0, 0}, {150, 1, 0.5, 0, 0.8}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 2, 1.0, &err), err);
    CHECK(near(tf.table[100][0], 0.5, 1e-6), "r(100) = %g", tf.table[100][0]);
    CHECK(near(tf.table[100][1], 0.25, 1e-6), "g(100) = %g", tf.table[100][1]);
    CHECK(near(tf.table[125][3], 0.6, 1e-6), "a(125) = %g", tf.table[125][3]);
    /* constant outside the points */
    CHECK(tf.table[0][3] == 0.0f && tf.table[49][0] == 0.0f, "below first point not constant");
    CHECK(near(tf.table[255][3], 0.8, 1e-7) && near(tf.table[200][0], 1.0, 1e-7),
          "above last point not constant: %g", tf.table[255][3]);
    float out[4];
    cdvr_tf_lookup(&tf, 100.5f, out);
    CHECK(near(out[0], 0.505, 1e-6), "lookup(100.5) r = %g", out[0]);
    cdvr_tf_lookup(&tf, -3.0f, out);
    CHECK(out[3] == 0.0f, "lookup clamps below: %g", out[3]);
    cdvr_tf_lookup(&tf, 300.0f, out);
    CHECK(near(out[3], 0.8, 1e-7), "lookup clamps above: %g", out[3]);
    cdvr_tf_lookup(&tf, 255.0f, out);
    CHECK(near(out[3], 0.8, 1e-7), "lookup at 255: %g", out[3]);
}

static void test_sorting_and_steps(void)
{
    cdvr_tf_point pts[] = {{200, 1, 1, 1, 1}, {0, 0, 0, 0, 0}, {100, 0, 0, 0, 0},
                           {100, 1, 0, 0, 0.5}};
    cdvr_tf tf;
    cdvr_error err;
    CHECK_OK(cdvr_tf_init(&tf, pts, 4, 0.0, &err), err);
    CHECK(tf.points[0].value == 0 && tf.points[3].value == 200, "not sorted");
    /* the two points at 100 keep their order: a step up at 100 */
    CHECK(tf.points[1].a == 0.0 && tf.points[2].a == 0.5, "equal values reordered");
    CHECK(tf.table[99][3] == 0.0f, "a(99) = %g", tf.table[99][3]);
    CHECK(near(tf.table[100][3], 0.5, 1e-7), "a(100) = %g (step, later point)", tf.table[100][3]);
    CHECK(near(tf.table[150][3], 0.75, 1e-6), "a(150) = %g", tf.table[150][3]);

    cdvr_tf_point one = {42, 0.2, 0.4, 0.6, 0.3};
    CHECK_OK(cdvr_tf_init(&tf, &one, 1, 2.0, &err), err);
    CHECK(near(tf.table[0][1], 0.4, 1e-7) && near(tf.table[255][3], 0.3, 1e-7),
          "single point is not constant");
    CHECK(tf.unit == 2.0, "unit %g", tf.unit);
}

static void test_bad_points(void)
{
    cdvr_tf tf;
    cdvr_error err;
    /* data units: any finite value (CT values, densities); normalised: [0, 1] */
    cdvr_tf_point hu[] = {{-1000, 0, 0, 0, 0}, {3000, 1, 1, 1, 1}};
    CHECK(cdvr_tf_init(&tf, hu, 2, 1.0, &err) == CDVR_OK, "CT values refused: %s", err.msg);
    cdvr_tf_point high = {1.5, 0, 0, 0, 0};
    CHECK(cdvr_tf_init_normalized(&tf, &high, 1, 1.0, &err) == CDVR_ERR_ARG,
          "normalised value 1.5 accepted");
    CHECK(strstr(err.msg, "1.5") != NULL, "message does not name the value: %s", err.msg);
    cdvr_tf_point neg = {-0.1, 0, 0, 0, 0};
    CHECK(cdvr_tf_init_normalized(&tf, &neg, 1, 1.0, &err) == CDVR_ERR_ARG,
          "normalised value -0.1 accepted");
    cdvr_tf_point inf = {INFINITY, 0, 0, 0, 0};
    CHECK(cdvr_tf_init(&tf, &inf, 1, 1.0, &err) == CDVR_ERR_ARG, "infinite value accepted");
    cdvr_tf_point color = {10, 1.5, 0, 0, 0};
    CHECK(cdvr_tf_init(&tf, &color, 1, 1.0, &err) == CDVR_ERR_ARG, "r 1.5 accepted");
    cdvr_tf_point alpha = {10, 0, 0, 0, -0.1};
    CHECK(cdvr_tf_init(&tf, &alpha, 1, 1.0, &err) == CDVR_ERR_ARG, "alpha -0.1 accepted");
    cdvr_tf_point nan_value = {NAN, 0, 0, 0, 0};
    CHECK(cdvr_tf_init(&tf, &nan_value, 1, 1.0, &err) == CDVR_ERR_ARG, "NaN value accepted");
    cdvr_tf_point ok = {10, 0, 0, 0, 0};
    CHECK(cdvr_tf_init(&tf, &ok, 0, 1.0, &err) == CDVR_ERR_ARG, "zero points accepted");
    CHECK(cdvr_tf_init(&tf, &ok, CDVR_TF_MAX_POINTS + 1, 1.0, &err) == CDVR_ERR_ARG,
          "too many points accepted");
    CHECK(cdvr_tf_init(&tf, &ok, 1, -1.0, &err) == CDVR_ERR_ARG, "negative unit accepted");
}

/* tf.h: table[i] = TF(lo + (hi - lo) * i / 255), x_255 = hi; normalised: TF(i / 255). */
static void test_windows(void)
{
    cdvr_tf tf;
    cdvr_error err;
    /* density 0.2 .. 0.7 (the combustor's range): opaque ramp from 0.45 to 0.7 */
    cdvr_tf_point pts[] = {{0.2, 0, 0, 0, 0}, {0.45, 0, 0, 0, 0}, {0.7, 1, 1, 1, 1}};
    CHECK_OK(cdvr_tf_init(&tf, pts, 3, 0, &err), err);
    CHECK(tf.table[0][3] == 0.0f && tf.table[1][3] == 1.0f && tf.table[255][3] == 1.0f,
          "window [0, 255]: code 0 below 0.2, the rest above 0.7");
    CHECK_OK(cdvr_tf_set_window(&tf, 0.2, 0.7, &err), err);
    CHECK(tf.window[0] == 0.2 && tf.window[1] == 0.7, "window recorded");
    for (int i = 0; i < 256; i++) {
        double x = i == 255 ? 0.7 : 0.2 + 0.5 * i / 255.0;
        double a = x <= 0.45 ? 0 : (x - 0.45) / 0.25;
        CHECK(near(tf.table[i][3], a, 1e-6), "entry %d (value %g): alpha %g, expected %g", i, x,
              tf.table[i][3], a);
    }
    CHECK(tf.table[255][3] == 1.0f, "x_255 is hi exactly");
    float out[4];
    cdvr_tf_eval(&tf, 0.575, out);
    CHECK(near(out[3], 0.5, 1e-6), "eval(0.575) = %g", out[3]);
    /* a constant window: every entry is TF(lo) */
    CHECK_OK(cdvr_tf_set_window(&tf, 0.6, 0.6, &err), err);
    CHECK(near(tf.table[0][3], 0.6, 1e-6) && near(tf.table[255][3], 0.6, 1e-6), "window [0.6, 0.6]");
    CHECK(cdvr_tf_set_window(&tf, 1, 0, &err) == CDVR_ERR_ARG, "hi < lo accepted");
    CHECK(cdvr_tf_set_window(&tf, 0, NAN, &err) == CDVR_ERR_ARG, "NaN window accepted");
    CHECK(cdvr_tf_rescale(&tf, 0, 1, &err) == CDVR_ERR_ARG, "rescale of a TF in data units");

    /* normalised (presets): the table is the same over every window */
    cdvr_tf_point frac[] = {{0, 0, 0, 0, 0}, {120 / 255.0, 0.5, 0, 0, 0}, {1, 1, 1, 1, 1}};
    cdvr_tf norm, pinned;
    CHECK_OK(cdvr_tf_init_normalized(&norm, frac, 3, 0, &err), err);
    cdvr_tf_point codes[] = {{0, 0, 0, 0, 0}, {120, 0.5, 0, 0, 0}, {255, 1, 1, 1, 1}};
    cdvr_tf byte;
    CHECK_OK(cdvr_tf_init(&byte, codes, 3, 0, &err), err);
    CHECK(memcmp(norm.table, byte.table, sizeof byte.table) == 0,
          "normalised c/255 points give the 8-bit table exactly");
    CHECK_OK(cdvr_tf_set_window(&norm, 0, 3926, &err), err);
    CHECK(memcmp(norm.table, byte.table, sizeof byte.table) == 0,
          "a normalised TF's table does not depend on the window");
    /* pinned to data values (ParaView's rescale): point p -> lo + p (hi - lo) */
    pinned = norm;
    CHECK_OK(cdvr_tf_rescale(&pinned, 1000, 2020, &err), err);
    CHECK(!pinned.normalized && near(pinned.points[1].value, 1480, 1e-9) &&
              pinned.points[2].value == 2020,
          "rescaled points %g %g", pinned.points[1].value, pinned.points[2].value);
    CHECK_OK(cdvr_tf_set_window(&pinned, 0, 4080, &err), err);
    /* entry i stands for 16 i: 1480 is entry 92.5 -> below it the red ramp up to 0.5 */
    CHECK(pinned.table[62][0] == 0.0f && near(pinned.table[92][0], 0.5 * (1472 - 1000) / 480.0, 1e-6),
          "pinned over [0, 4080]: r(62) %g r(92) %g", pinned.table[62][0], pinned.table[92][0]);
}

int main(void)
{
    test_windows();
    test_piecewise_linear();
    test_sorting_and_steps();
    test_bad_points();
    return check_finish();
}
