/* cdvr/camera.h - pinhole (or orthographic) camera, DESIGN.md section 6.
 *
 * f = normalize(center - eye), u = up made orthogonal to f and normalised, r = f x u,
 * aspect = width / height. Pixel (x, y) (x right, y down, from 0) is the ray from eye along
 *   normalize(f + ((2(x+0.5)/W - 1) * aspect * r - (2(y+0.5)/H - 1) * u) * tan(fov/2)).
 * Orthographic: direction f, origin eye + ((2(x+0.5)/W-1)*aspect*r - (2(y+0.5)/H-1)*u) * h/2
 * with h = ortho_height (world units, full height of the view).
 */
#ifndef CDVR_CAMERA_H
#define CDVR_CAMERA_H

#include "cdvr/error.h"

typedef struct cdvr_camera {
    double eye[3], center[3], up[3];
    double fov;       /* vertical full view angle in degrees, (0, 180) */
    int width, height;
    int orthographic;
    double ortho_height;
} cdvr_camera;

/* Checks fov range, positive size, eye != center, up not parallel to the view direction. */
cdvr_status cdvr_camera_validate(const cdvr_camera *cam, cdvr_error *err);
/* Orthonormal basis f (forward), u (up), r (right). */
void cdvr_camera_basis(const cdvr_camera *cam, double f[3], double u[3], double r[3]);
/* Ray through pixel (x, y): origin and unit direction. */
void cdvr_camera_ray(const cdvr_camera *cam, int x, int y, double origin[3], double dir[3]);
/* What cdvr_camera_ray derives from the camera alone (its basis and tan(fov / 2)), computed
 * once for all the rays of an image: cdvr_camera_frame_ray gives exactly cdvr_camera_ray's
 * ray, bit for bit. */
typedef struct cdvr_camera_frame {
    double f[3], u[3], r[3];
    double tan_half_fov;
} cdvr_camera_frame;
void cdvr_camera_frame_init(const cdvr_camera *cam, cdvr_camera_frame *frame);
void cdvr_camera_frame_ray(const cdvr_camera *cam, const cdvr_camera_frame *frame, int x, int y,
                           double origin[3], double dir[3]);
/* Camera on a circle around center: eye at distance `distance`, angle `azimuth_deg` around
 * the up axis, `elevation_deg` above the plane orthogonal to up. */
void cdvr_camera_orbit(cdvr_camera *cam, const double center[3], const double up[3],
                       double distance, double azimuth_deg, double elevation_deg);

/* 0 when no ray of the camera can meet the convex hull of the 8 world points `corners` (a
 * box): all of them lie beyond one plane of the view volume (the four planes through the
 * image's outer edges, and the eye's plane: rays start at t = 0). 1 otherwise. Conservative:
 * a hull that no ray meets may still give 1, a hull some pixel-centre ray meets never gives
 * 0 (a margin of 1e-4 of the corners' distance covers rounding). */
int cdvr_camera_sees_box(const cdvr_camera *cam, const double corners[8][3]);

#endif
