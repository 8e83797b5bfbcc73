/* core/render/camera.c - pinhole and orthographic cameras (cdvr/camera.h, DESIGN.md section 6). */
#include "cdvr/camera.h"

#include <math.h>

static const double kPi = 3.14159265358979323846;

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const double a[3], const double b[3], double out[3])
{
    double x = a[1] * b[2] - a[2] * b[1];
    double y = a[2] * b[0] - a[0] * b[2];
    double z = a[0] * b[1] - a[1] * b[0];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}

/* Normalises v in place; returns its length before (0 leaves v unchanged). */
static double normalize3(double v[3])
{
    double len = sqrt(dot3(v, v));
    if (len > 0.0)
        for (int i = 0; i < 3; i++)
            v[i] /= len;
    return len;
}

static int finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

cdvr_status cdvr_camera_validate(const cdvr_camera *cam, cdvr_error *err)
{
    if (!cam)
        return cdvr_error_set(err, CDVR_ERR_ARG, "camera: NULL");
    if (!finite3(cam->eye) || !finite3(cam->center) || !finite3(cam->up))
        return cdvr_error_set(err, CDVR_ERR_ARG, "camera: eye, center and up must be finite");
    if (cam->width <= 0 || cam->height <= 0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "camera: size %dx%d must be positive",
                              cam->width, cam->height);
    if (cam->orthographic) {
        if (!isfinite(cam->ortho_height) || cam->ortho_height <= 0.0)
            return cdvr_error_set(err, CDVR_ERR_ARG,
                                  "camera: ortho_height %g must be positive", cam->ortho_height);
    } else if (!isfinite(cam->fov) || cam->fov <= 0.0 || cam->fov >= 180.0) {
        return cdvr_error_set(err, CDVR_ERR_ARG, "camera: fov %g outside (0, 180) degrees",
                              cam->fov);
    }
    double f[3], up[3], side[3];
    for (int i = 0; i < 3; i++) {
        f[i] = cam->center[i] - cam->eye[i];
        up[i] = cam->up[i];
    }
    double dist = normalize3(f);
    if (dist == 0.0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "camera: eye equals center (%g, %g, %g)",
                              cam->eye[0], cam->eye[1], cam->eye[2]);
    if (!isfinite(dist)) /* the view direction would be lost (not "up parallel") */
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "camera: eye (%g, %g, %g) and center (%g, %g, %g) are too far apart: "
                              "their distance overflows (a box or distance too large)",
                              cam->eye[0], cam->eye[1], cam->eye[2], cam->center[0],
                              cam->center[1], cam->center[2]);
    double up_len = normalize3(up);
    if (!isfinite(up_len))
        return cdvr_error_set(err, CDVR_ERR_ARG, "camera: up (%g, %g, %g) is too long: its length "
                              "overflows", cam->up[0], cam->up[1], cam->up[2]);
    if (up_len == 0.0)
        return cdvr_error_set(err, CDVR_ERR_ARG, "camera: up vector is zero");
    cross3(f, up, side);
    if (sqrt(dot3(side, side)) < 1e-9)
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "camera: up (%g, %g, %g) is parallel to the view direction",
                              cam->up[0], cam->up[1], cam->up[2]);
    return CDVR_OK;
}

void cdvr_camera_basis(const cdvr_camera *cam, double f[3], double u[3], double r[3])
{
    for (int i = 0; i < 3; i++)
        f[i] = cam->center[i] - cam->eye[i];
    normalize3(f);
    double along = dot3(cam->up, f);
    for (int i = 0; i < 3; i++)
        u[i] = cam->up[i] - along * f[i];
    normalize3(u);
    cross3(f, u, r);
}

void cdvr_camera_frame_init(const cdvr_camera *cam, cdvr_camera_frame *frame)
{
    cdvr_camera_basis(cam, frame->f, frame->u, frame->r);
    frame->tan_half_fov = tan(0.5 * cam->fov * kPi / 180.0);
}

void cdvr_camera_frame_ray(const cdvr_camera *cam, const cdvr_camera_frame *frame, int x, int y,
                           double origin[3], double dir[3])
{
    const double *f = frame->f, *u = frame->u, *r = frame->r;
    double aspect = (double)cam->width / (double)cam->height;
    double sx = (2.0 * (x + 0.5) / cam->width - 1.0) * aspect;
    double sy = -(2.0 * (y + 0.5) / cam->height - 1.0);
    if (cam->orthographic) {
        double half = 0.5 * cam->ortho_height;
        for (int i = 0; i < 3; i++) {
            origin[i] = cam->eye[i] + (sx * r[i] + sy * u[i]) * half;
            dir[i] = f[i];
        }
        return;
    }
    for (int i = 0; i < 3; i++) {
        origin[i] = cam->eye[i];
        dir[i] = f[i] + (sx * r[i] + sy * u[i]) * frame->tan_half_fov;
    }
    normalize3(dir);
}

void cdvr_camera_ray(const cdvr_camera *cam, int x, int y, double origin[3], double dir[3])
{
    cdvr_camera_frame frame;
    cdvr_camera_frame_init(cam, &frame);
    cdvr_camera_frame_ray(cam, &frame, x, y, origin, dir);
}

/* Unit vector orthogonal to the unit vector n: the world axis least parallel to n, with its
 * n component removed (for n = z this is x). */
static void perpendicular(const double n[3], double out[3])
{
    int axis = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(n[i]) < fabs(n[axis]))
            axis = i;
    double e[3] = {0.0, 0.0, 0.0};
    e[axis] = 1.0;
    double along = dot3(e, n);
    for (int i = 0; i < 3; i++)
        out[i] = e[i] - along * n[i];
    normalize3(out);
}

void cdvr_camera_orbit(cdvr_camera *cam, const double center[3], const double up[3],
                       double distance, double azimuth_deg, double elevation_deg)
{
    double n[3] = {up[0], up[1], up[2]}, a[3], b[3];
    normalize3(n);
    perpendicular(n, a);
    cross3(n, a, b);
    double az = azimuth_deg * kPi / 180.0, el = elevation_deg * kPi / 180.0;
    for (int i = 0; i < 3; i++) {
        double dir = cos(el) * (cos(az) * a[i] + sin(az) * b[i]) + sin(el) * n[i];
        cam->center[i] = center[i];
        cam->up[i] = up[i];
        cam->eye[i] = center[i] + distance * dir;
    }
}

/* A point v (relative to the eye, in the camera basis: x along r, y along u, z along f) lies
 * on the outer side of plane k of the view volume when plane_dist(k) > 0. The side planes pass
 * through the image's outer edges, half a pixel beyond the outermost pixel-centre rays; the
 * front plane is the eye's (rays sample at t >= 0). */
static double plane_dist(const cdvr_camera *cam, int k, double x, double y, double z)
{
    double aspect = (double)cam->width / cam->height;
    if (cam->orthographic) {
        double hy = 0.5 * cam->ortho_height, hx = hy * aspect;
        double d[5] = {x - hx, -x - hx, y - hy, -y - hy, -z};
        return d[k];
    }
    double ty = tan(cam->fov * kPi / 360.0), tx = ty * aspect;
    double d[5] = {x - tx * z, -x - tx * z, y - ty * z, -y - ty * z, -z};
    return d[k];
}

int cdvr_camera_sees_box(const cdvr_camera *cam, const double corners[8][3])
{
    double f[3], u[3], r[3], v[8][3], scale = 0.0;
    cdvr_camera_basis(cam, f, u, r);
    for (int c = 0; c < 8; c++) {
        double rel[3];
        for (int i = 0; i < 3; i++)
            rel[i] = corners[c][i] - cam->eye[i];
        v[c][0] = dot3(rel, r);
        v[c][1] = dot3(rel, u);
        v[c][2] = dot3(rel, f);
        scale = fmax(scale, sqrt(dot3(rel, rel)));
    }
    /* a margin far above the renderer's float rounding keeps the test conservative */
    double margin = 1e-4 * (scale + 1.0);
    for (int k = 0; k < 5; k++) {
        int outside = 0;
        for (int c = 0; c < 8; c++)
            outside += plane_dist(cam, k, v[c][0], v[c][1], v[c][2]) > margin;
        if (outside == 8)
            return 0;
    }
    return 1;
}
