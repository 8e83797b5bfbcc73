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
    cdvr_tf_point high = {256, 0, 0, 0, 0};
    CHECK(cdvr_tf_init(&tf, &high, 1, 1.0, &err) == CDVR_ERR_ARG, "value 256 accepted");
    CHECK(strstr(err.msg, "256") != NULL, "message does not name the value: %s", err.msg);
    cdvr_tf_point neg = {-1, 0, 0, 0, 0};
    CHECK(cdvr_tf_init(&tf, &neg, 1, 1.0, &err) == CDVR_ERR_ARG, "value -1 accepted");
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

int main(void)
{
    test_piecewise_linear();
    test_sorting_and_steps();
    test_bad_points();
    return check_finish();
}
