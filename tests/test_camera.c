/* tests/test_camera.c - pixel-centre ray formula, orthonormal basis, orbit, validation. */
#include "check.h"

#include <string.h>

#include "cdvr/camera.h"

static double dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static cdvr_camera make_camera(void)
{
    cdvr_camera cam = {{0, -10, 0}, {0, 0, 0}, {0, 0, 1}, 90.0, 4, 2, 0, 0.0};
    return cam;
}

static void test_basis(void)
{
    cdvr_camera cam = {{1, 2, 3}, {-4, 0.5, 2}, {0.3, 0.2, 1}, 40, 10, 10, 0, 0};
    double f[3], u[3], r[3];
    cdvr_camera_basis(&cam, f, u, r);
    CHECK(fabs(dot(f, f) - 1) < 1e-12 && fabs(dot(u, u) - 1) < 1e-12 &&
              fabs(dot(r, r) - 1) < 1e-12,
          "basis not unit length");
    CHECK(fabs(dot(f, u)) < 1e-12 && fabs(dot(f, r)) < 1e-12 && fabs(dot(u, r)) < 1e-12,
          "basis not orthogonal");
    CHECK(dot(u, cam.up) > 0, "u points away from up");
    /* looking along +y with z up: right is +x (r = f x u) */
    cdvr_camera c2 = make_camera();
    cdvr_camera_basis(&c2, f, u, r);
    CHECK(fabs(r[0] - 1) < 1e-12 && fabs(f[1] - 1) < 1e-12 && fabs(u[2] - 1) < 1e-12,
          "r = (%g %g %g)", r[0], r[1], r[2]);
}

static void test_ray_formula(void)
{
    cdvr_camera cam = make_camera(); /* fov 90: tan(45) = 1, aspect 2 */
    double o[3], d[3];
    /* pixel (0, 0): sx = (2*0.5/4 - 1)*2 = -1.5, sy = -(2*0.5/2 - 1) = 0.5 */
    cdvr_camera_ray(&cam, 0, 0, o, d);
    double expect[3] = {-1.5, 1.0, 0.5}, len = sqrt(dot(expect, expect));
    for (int i = 0; i < 3; i++)
        CHECK(fabs(d[i] - expect[i] / len) < 1e-12, "d[%d] = %g, want %g", i, d[i],
              expect[i] / len);
    CHECK(o[0] == 0 && o[1] == -10 && o[2] == 0, "origin is not the eye");
    /* y down: row 1 (bottom) looks below the axis */
    cdvr_camera_ray(&cam, 3, 1, o, d);
    CHECK(d[2] < 0 && d[0] > 0, "pixel (3,1) direction (%g %g %g)", d[0], d[1], d[2]);
    /* orthographic: origin offset in the image plane, direction f */
    cam.orthographic = 1;
    cam.ortho_height = 4.0;
    cdvr_camera_ray(&cam, 0, 0, o, d);
    CHECK(fabs(o[0] + 3.0) < 1e-12 && fabs(o[2] - 1.0) < 1e-12 && fabs(o[1] + 10) < 1e-12,
          "ortho origin (%g %g %g)", o[0], o[1], o[2]);
    CHECK(fabs(d[1] - 1.0) < 1e-12, "ortho direction (%g %g %g)", d[0], d[1], d[2]);
}

static void test_orbit(void)
{
    cdvr_camera cam = make_camera();
    double center[3] = {1, 2, 3}, up[3] = {0, 0, 1};
    cdvr_camera_orbit(&cam, center, up, 5.0, 90.0, 0.0);
    double off[3] = {cam.eye[0] - 1, cam.eye[1] - 2, cam.eye[2] - 3};
    CHECK(fabs(sqrt(dot(off, off)) - 5.0) < 1e-12, "orbit distance %g", sqrt(dot(off, off)));
    CHECK(fabs(off[2]) < 1e-12, "elevation 0 leaves the plane: %g", off[2]);
    cdvr_camera_orbit(&cam, center, up, 5.0, 0.0, 90.0);
    CHECK(fabs(cam.eye[2] - 8.0) < 1e-12, "elevation 90: eye z %g", cam.eye[2]);
    cdvr_camera_orbit(&cam, center, up, 5.0, 30.0, 30.0);
    cdvr_error err;
    CHECK_OK(cdvr_camera_validate(&cam, &err), err);
}

static void test_validation(void)
{
    cdvr_error err;
    cdvr_camera cam = make_camera();
    CHECK_OK(cdvr_camera_validate(&cam, &err), err);
    cam.fov = 0;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "fov 0 accepted");
    cam.fov = 180;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "fov 180 accepted");
    cam = make_camera();
    cam.width = 0;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "width 0 accepted");
    cam = make_camera();
    cam.center[1] = -10;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "eye == center accepted");
    cam = make_camera();
    cam.up[0] = 0, cam.up[1] = 3, cam.up[2] = 0;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "up parallel accepted");
    CHECK(strstr(err.msg, "parallel") != NULL, "message: %s", err.msg);
    cam = make_camera();
    cam.up[2] = 0;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "zero up accepted");
    cam = make_camera();
    cam.eye[0] = NAN;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "NaN eye accepted");
    cam = make_camera();
    cam.orthographic = 1;
    CHECK(cdvr_camera_validate(&cam, &err) == CDVR_ERR_ARG, "ortho_height 0 accepted");
}

int main(void)
{
    test_basis();
    test_ray_formula();
    test_orbit();
    test_validation();
    return check_finish();
}
