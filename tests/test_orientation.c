/* tests/test_orientation.c - index-to-world geometry (volume.h) from NIfTI and NRRD headers and
 * its use by the CPU reference ray caster (render.h step 0).
 *
 * Loaders: small files written here byte by byte (no niftilib or teem on the writing side)
 * with a radiological qform (qfac -1) and a 90-degree rotation, an sform that flips x (the
 * ASL series' layout), sform preferred over qform, a NRRD with a negative direction, an
 * oblique NRRD and a degenerate one. Every expected world position is computed by hand from
 * the header numbers in the comments.
 *
 * Renderer: a volume and its copy stored in another index order (x reversed, or x and y
 * swapped) with the geometry adjusted so that both describe the same field in world space
 * render the same image; an oblique, sheared volume too. On the real ASL series
 * (share/data): its render equals the render of its x-reversed copy with identity
 * direction, and is the left-right mirror image of the render that ignores the direction
 * (what cdvr did before). */
#include "check.h"

#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "cdvr/compare.h"
#include "cdvr/render.h"
#include "cdvr/tf.h"
#include "cdvr/volume.h"

#define TMP "test_orientation_tmp_"

static void put_i16(uint8_t *h, size_t off, int16_t v) { memcpy(h + off, &v, 2); }
static void put_i32(uint8_t *h, size_t off, int32_t v) { memcpy(h + off, &v, 4); }
static void put_f32(uint8_t *h, size_t off, float v) { memcpy(h + off, &v, 4); }

typedef struct nifti_spec {
    float pixdim[4];     /* qfac, dx, dy, dz */
    int qform_code, sform_code;
    float quatern[3];    /* b, c, d */
    float qoffset[3];
    float srow[3][4];
} nifti_spec;

/* A 4x3x2 u8 NIfTI-1 single file (348-byte header, 4 bytes of extension flags, data) with
 * the header fields at their offsets of the NIfTI-1 standard (little endian host). */
static void write_nifti(const char *path, const nifti_spec *s)
{
    uint8_t buf[352 + 24];
    memset(buf, 0, sizeof buf);
    put_i32(buf, 0, 348);
    const int16_t dim[8] = {3, 4, 3, 2, 1, 1, 1, 1};
    for (int i = 0; i < 8; i++)
        put_i16(buf, 40 + 2 * (size_t)i, dim[i]);
    put_i16(buf, 70, 2); /* DT_UINT8 */
    put_i16(buf, 72, 8);
    for (int i = 0; i < 4; i++)
        put_f32(buf, 76 + 4 * (size_t)i, s->pixdim[i]);
    put_f32(buf, 108, 352.0f);
    put_i16(buf, 252, (int16_t)s->qform_code);
    put_i16(buf, 254, (int16_t)s->sform_code);
    for (int i = 0; i < 3; i++) {
        put_f32(buf, 256 + 4 * (size_t)i, s->quatern[i]);
        put_f32(buf, 268 + 4 * (size_t)i, s->qoffset[i]);
        for (int c = 0; c < 4; c++)
            put_f32(buf, 280 + 16 * (size_t)i + 4 * (size_t)c, s->srow[i][c]);
    }
    memcpy(buf + 344, "n+1", 4);
    for (int i = 0; i < 24; i++)
        buf[352 + i] = (uint8_t)(10 * i);
    FILE *f = fopen(path, "wb");
    CHECK(f && fwrite(buf, 1, sizeof buf, f) == sizeof buf, "cannot write %s", path);
    if (f)
        fclose(f);
}

static void write_nrrd(const char *path, const char *geometry)
{
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL, "cannot write %s", path);
    if (!f)
        return;
    fprintf(f, "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 3 2\n%sendian: little\n"
               "encoding: raw\n\n", geometry);
    for (int i = 0; i < 24; i++)
        fputc(10 * i, f);
    fclose(f);
}

/* world(ijk) of vol against the expected point, within tol. */
static void expect_world(const cdvr_volume *vol, const char *what, double i, double j, double k,
                         double x, double y, double z, double tol)
{
    double ijk[3] = {i, j, k}, w[3];
    cdvr_volume_index_to_world(vol, ijk, w);
    CHECK(fabs(w[0] - x) <= tol && fabs(w[1] - y) <= tol && fabs(w[2] - z) <= tol,
          "%s: voxel (%g,%g,%g) at (%.6f, %.6f, %.6f), expected (%g, %g, %g)", what, i, j, k,
          w[0], w[1], w[2], x, y, z);
}

static cdvr_volume *load(const char *path, int nifti)
{
    cdvr_volume *vol = NULL;
    cdvr_error err;
    cdvr_status st = nifti ? cdvr_volume_load_nifti(path, &vol, &err)
                           : cdvr_volume_load_nrrd(path, &vol, &err);
    CHECK_OK(st, err);
    return vol;
}

static void test_nifti(void)
{
    const char *path = TMP "q.nii";
    /* qform: rotation of 90 degrees about z (quaternion a = cos 45, d = sin 45, b = c = 0):
     * R = [0 -1 0; 1 0 0; 0 0 1]; qfac = pixdim[0] = -1 negates R's third column;
     * pixdim (2, 3, 4), qoffset (10, 20, 30). world = qoffset + R * diag(2,3,4) * (i,j,k):
     *   x = 10 - 3j, y = 20 + 2i, z = 30 - 4k. */
    nifti_spec q = {.pixdim = {-1, 2, 3, 4}, .qform_code = 1, .quatern = {0, 0, 0.70710678f},
                    .qoffset = {10, 20, 30}};
    write_nifti(path, &q);
    cdvr_volume *vol = load(path, 1);
    if (vol) {
        expect_world(vol, "qform qfac -1", 0, 0, 0, 10, 20, 30, 1e-5);
        expect_world(vol, "qform qfac -1", 1, 0, 0, 10, 22, 30, 1e-5);
        expect_world(vol, "qform qfac -1", 0, 1, 0, 7, 20, 30, 1e-5);
        expect_world(vol, "qform qfac -1", 3, 2, 1, 4, 26, 26, 1e-5);
        CHECK(fabs(vol->spacing[0] - 2) < 1e-6 && fabs(vol->spacing[1] - 3) < 1e-6 &&
                  fabs(vol->spacing[2] - 4) < 1e-6,
              "qform spacing %g %g %g", vol->spacing[0], vol->spacing[1], vol->spacing[2]);
        CHECK(fabs(vol->direction[8] + 1) < 1e-6 && fabs(vol->direction[3] - 1) < 1e-6,
              "qform direction D[2][2] %g D[1][0] %g", vol->direction[8], vol->direction[3]);
        cdvr_volume_free(vol);
    }
    /* sform only, radiological like the ASL series: srow_x = (-3.5, 0, 0, 100),
     * srow_y = (0, 2, 0, -50), srow_z = (0, 0, 5, -20): x = 100 - 3.5 i. */
    nifti_spec s = {.pixdim = {1, 3.5f, 2, 5}, .sform_code = 2,
                    .srow = {{-3.5f, 0, 0, 100}, {0, 2, 0, -50}, {0, 0, 5, -20}}};
    write_nifti(path, &s);
    if ((vol = load(path, 1)) != NULL) {
        expect_world(vol, "sform x flip", 0, 0, 0, 100, -50, -20, 1e-5);
        expect_world(vol, "sform x flip", 3, 2, 1, 89.5, -46, -15, 1e-5);
        CHECK(vol->spacing[0] == 3.5 && vol->direction[0] == -1.0, "sform spacing %g D00 %g",
              vol->spacing[0], vol->direction[0]);
        double lo[3], hi[3];
        cdvr_volume_bounds(vol, lo, hi);
        CHECK(lo[0] == 89.5 && hi[0] == 100 && lo[1] == -50 && hi[1] == -46 && lo[2] == -20 &&
                  hi[2] == -15,
              "bounds x [%g, %g] y [%g, %g] z [%g, %g]", lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
        cdvr_volume_free(vol);
    }
    /* both set: the sform wins (nibabel's choice); an oblique sform with a shear column:
     * srow_x = (1, 0.5, 0, 1), srow_y = (0, 1, 0, 2), srow_z = (0, 0, -2, 3):
     * voxel (2, 2, 1) -> (1 + 2 + 1, 2 + 2, 3 - 2) = (4, 4, 1). */
    nifti_spec both = q;
    both.sform_code = 1;
    float shear[3][4] = {{1, 0.5f, 0, 1}, {0, 1, 0, 2}, {0, 0, -2, 3}};
    memcpy(both.srow, shear, sizeof shear);
    write_nifti(path, &both);
    if ((vol = load(path, 1)) != NULL) {
        expect_world(vol, "sform over qform, shear", 2, 2, 1, 4, 4, 1, 1e-5);
        expect_world(vol, "sform over qform, shear", 0, 0, 0, 1, 2, 3, 1e-5);
        cdvr_volume_free(vol);
    }
    /* neither: "method 1", |pixdim| spacing, origin 0, no rotation */
    nifti_spec none = {.pixdim = {1, -2, 3, 4}};
    write_nifti(path, &none);
    if ((vol = load(path, 1)) != NULL) {
        expect_world(vol, "no qform/sform", 1, 1, 1, 2, 3, 4, 0);
        cdvr_volume_free(vol);
    }
    unlink(path);
}

static void test_nrrd(void)
{
    const char *path = TMP "d.nrrd";
    /* negative direction along x (LPS): world = (5 - 2i, 6 + 3j, 7 + 4k) */
    write_nrrd(path, "space: left-posterior-superior\n"
                     "space directions: (-2,0,0) (0,3,0) (0,0,4)\nspace origin: (5,6,7)\n");
    cdvr_volume *vol = load(path, 0);
    if (vol) {
        expect_world(vol, "nrrd negative x", 3, 2, 1, -1, 12, 11, 1e-12);
        CHECK(vol->spacing[0] == 2 && vol->direction[0] == -1, "nrrd spacing %g D00 %g",
              vol->spacing[0], vol->direction[0]);
        cdvr_volume_free(vol);
    }
    /* oblique: axis 0 = 2 * (0.6, 0.8, 0), axis 1 = 3 * (-0.8, 0.6, 0), axis 2 = (0, 0, -1.5);
     * voxel (1, 2, 2) -> (1.2 - 4.8, 1.6 + 3.6, -3) + origin (1, 1, 1) = (-2.6, 6.2, -2) */
    write_nrrd(path, "space dimension: 3\n"
                     "space directions: (1.2,1.6,0) (-2.4,1.8,0) (0,0,-1.5)\n"
                     "space origin: (1,1,1)\n");
    if ((vol = load(path, 0)) != NULL) {
        expect_world(vol, "nrrd oblique", 1, 2, 1, -2.6, 6.2, -0.5, 1e-12);
        expect_world(vol, "nrrd oblique", 3, 0, 0, 4.6, 5.8, 1, 1e-12);
        CHECK(fabs(vol->spacing[1] - 3) < 1e-12 && fabs(vol->spacing[2] - 1.5) < 1e-12,
              "oblique spacing %g %g", vol->spacing[1], vol->spacing[2]);
        cdvr_volume_free(vol);
    }
    /* scalar spacings without a space: a negative spacing runs the axis backwards */
    write_nrrd(path, "spacings: -2 1 1\n");
    if ((vol = load(path, 0)) != NULL) {
        expect_world(vol, "nrrd negative spacing", 3, 1, 1, -6, 1, 1, 0);
        cdvr_volume_free(vol);
    }
    /* degenerate: axes 0 and 1 parallel */
    write_nrrd(path, "space dimension: 3\nspace directions: (1,0,0) (2,0,0) (0,0,1)\n");
    cdvr_volume *bad = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_volume_load_nrrd(path, &bad, &err);
    CHECK(st != CDVR_OK && bad == NULL && strstr(err.msg, "degenerate") && strstr(err.msg, path),
          "degenerate directions: status %d, %s", (int)st, err.msg);
    unlink(path);
}

/* ---- renders ------------------------------------------------------------------------------ */

static cdvr_image *render(const cdvr_volume *vol, const cdvr_tf *tf, const cdvr_camera *cam)
{
    cdvr_render_opts opts = {.tf = tf, .camera = cam, .step = 0.3, .threads = 2};
    cdvr_image *img = NULL;
    cdvr_error err;
    cdvr_status st = cdvr_render_cpu(vol, 0, &opts, &img, &err);
    CHECK_OK(st, err);
    return img;
}

static double psnr(const cdvr_image *a, const cdvr_image *b)
{
    cdvr_compare_result res = {0, 0, 0};
    cdvr_error err;
    if (!a || !b || cdvr_compare_images(a, b, &res, &err) != CDVR_OK)
        return -1;
    return res.psnr;
}

static double mean_alpha(const cdvr_image *img)
{
    double sum = 0;
    for (int i = 0; img && i < img->width * img->height; i++)
        sum += img->rgba[4 * i + 3];
    return img ? sum / (img->width * img->height) : 0;
}

static void look_at_centre(cdvr_camera *cam, const cdvr_volume *vol, const double dir[3],
                           const double up[3], double distance)
{
    double lo[3], hi[3];
    cdvr_volume_bounds(vol, lo, hi);
    memset(cam, 0, sizeof *cam);
    for (int a = 0; a < 3; a++) {
        cam->center[a] = 0.5 * (lo[a] + hi[a]);
        cam->eye[a] = cam->center[a] - distance * dir[a];
        cam->up[a] = up[a];
    }
    cam->fov = 30;
    cam->width = cam->height = 96;
}

/* b holds a's voxels in another index order: b(i,j,k) = a(map(i,j,k)). */
typedef void (*index_map)(const cdvr_volume *a, size_t i, size_t j, size_t k, size_t out[3]);

static void reverse_x(const cdvr_volume *a, size_t i, size_t j, size_t k, size_t out[3])
{
    out[0] = a->dims[0] - 1 - i, out[1] = j, out[2] = k;
}

static void swap_xy(const cdvr_volume *a, size_t i, size_t j, size_t k, size_t out[3])
{
    (void)a;
    out[0] = j, out[1] = i, out[2] = k;
}

static cdvr_volume *reorder(const cdvr_volume *a, const size_t dims[3], index_map map)
{
    cdvr_volume *b;
    cdvr_error err;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_U8, &b, &err) != CDVR_OK)
        return NULL;
    const uint8_t *src = a->data;
    uint8_t *dst = b->data;
    for (size_t k = 0; k < dims[2]; k++)
        for (size_t j = 0; j < dims[1]; j++)
            for (size_t i = 0; i < dims[0]; i++) {
                size_t s[3];
                map(a, i, j, k, s);
                dst[i + dims[0] * (j + dims[1] * k)] =
                    src[s[0] + a->dims[0] * (s[1] + a->dims[1] * s[2])];
            }
    return b;
}

/* a rendered from several views equals b rendered from the same views. */
static void expect_same_renders(const cdvr_volume *a, const cdvr_volume *b, const cdvr_tf *tf,
                                const char *what)
{
    const double views[3][3] = {{0, 1, 0}, {0.6, 0.48, -0.64}, {-1, 0, 0}};
    const double up[3] = {0, 0, 1};
    for (int v = 0; v < 3; v++) {
        cdvr_camera cam;
        look_at_centre(&cam, a, views[v], up, 120);
        cdvr_image *ia = render(a, tf, &cam), *ib = render(b, tf, &cam);
        double p = psnr(ia, ib);
        CHECK(p >= 60 && mean_alpha(ia) > 0.02, "%s, view %d: PSNR %.1f dB, coverage %.3f", what,
              v, p, mean_alpha(ia));
        cdvr_image_free(ia);
        cdvr_image_free(ib);
    }
}

static void test_render_index_order(void)
{
    cdvr_generate_opts gen = {{23, 17, 13}, 1, CDVR_TYPE_U8, 0, 0, 0, 0};
    cdvr_volume *a;
    cdvr_error err;
    cdvr_status st = cdvr_volume_generate("ml", &gen, &a, &err);
    CHECK_OK(st, err);
    if (st)
        return;
    /* oblique and flipped: rotation of 30 degrees about z, then y mirrored */
    const double c = cos(M_PI / 6), s = sin(M_PI / 6);
    const double D[9] = {c, -s, 0, -s, -c, 0, 0, 0, 1};
    memcpy(a->direction, D, sizeof D);
    a->spacing[0] = 1.5, a->spacing[1] = 1.0, a->spacing[2] = 2.0;
    a->origin[0] = 3, a->origin[1] = -7, a->origin[2] = 11;
    cdvr_tf tf;
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {100, 0, 0, 0, 0}, {180, .9, .5, .2, .3},
                                 {255, 1, 1, 1, .8}};
    st = cdvr_tf_init(&tf, pts, 4, 0, &err);
    CHECK_OK(st, err);

    /* x reversed: D column 0 negated, origin at a's voxel (X-1, 0, 0) */
    cdvr_volume *b = reorder(a, a->dims, reverse_x);
    if (b) {
        memcpy(b->spacing, a->spacing, sizeof b->spacing);
        memcpy(b->direction, D, sizeof D);
        for (int r = 0; r < 3; r++)
            b->direction[3 * r] = -D[3 * r];
        double last[3] = {(double)(a->dims[0] - 1), 0, 0};
        cdvr_volume_index_to_world(a, last, b->origin);
        expect_same_renders(a, b, &tf, "x reversed");
        cdvr_volume_free(b);
    }
    /* x and y swapped: D columns 0 and 1 swapped, spacing too, same origin */
    const size_t swapped[3] = {a->dims[1], a->dims[0], a->dims[2]};
    if ((b = reorder(a, swapped, swap_xy)) != NULL) {
        b->spacing[0] = a->spacing[1], b->spacing[1] = a->spacing[0], b->spacing[2] = a->spacing[2];
        memcpy(b->origin, a->origin, sizeof b->origin);
        for (int r = 0; r < 3; r++) {
            b->direction[3 * r] = D[3 * r + 1];
            b->direction[3 * r + 1] = D[3 * r];
            b->direction[3 * r + 2] = D[3 * r + 2];
        }
        expect_same_renders(a, b, &tf, "x and y swapped");
        cdvr_volume_free(b);
    }
    /* a shear: index axis 1 leans towards x; D = [1 0.5 0; 0 1 0; 0 0 1]. The voxel at
     * index (i, j, k) must sit at x = ox + 1.5 i + 0.5 j (spacing 1.5, 1, 2). */
    const double shear[9] = {1, 0.5, 0, 0, 1, 0, 0, 0, 1};
    memcpy(a->direction, shear, sizeof shear);
    expect_world(a, "shear", 2, 4, 1, 3 + 3 + 2, -7 + 4, 11 + 2, 1e-12);
    cdvr_camera cam;
    const double view[3] = {0, 1, 0}, up[3] = {0, 0, 1};
    look_at_centre(&cam, a, view, up, 120);
    cdvr_image *img = render(a, &tf, &cam);
    CHECK(mean_alpha(img) > 0.02, "sheared volume renders (coverage %.3f)", mean_alpha(img));
    cdvr_image_free(img);
    /* a singular direction is an error naming it */
    memset(a->direction, 0, sizeof a->direction);
    a->direction[0] = a->direction[3] = a->direction[8] = 1;
    cdvr_render_opts opts = {.tf = &tf, .camera = &cam};
    st = cdvr_render_cpu(a, 0, &opts, &img, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "direction matrix") != NULL,
          "singular direction: %d %s", (int)st, err.msg);
    cdvr_volume_free(a);
}

/* The ASL series of share/data: sform x = 106.97 - 3.4375 i (radiological). */
static void test_asl_mirror(void)
{
    const char *src = getenv("CDVR_SOURCE_DIR");
    char path[1024];
    snprintf(path, sizeof path, "%s/share/data/mpld_asl_64x64x24x25_f32.nii.gz", src ? src : "..");
    cdvr_volume *series = load(path, 1), *frame = NULL, *q = NULL;
    if (!series)
        return;
    cdvr_error err;
    double w[2];
    cdvr_volume_window(series, w);
    CHECK_OK(cdvr_volume_slice_time(series, 0, 1, &frame, &err), err);
    CHECK_OK(cdvr_volume_quantize(frame, 0, w[1], &q, NULL, &err), err);
    cdvr_volume_free(series);
    cdvr_volume_free(frame);
    if (!q)
        return;
    CHECK(q->direction[0] == -1 && q->direction[4] == 1 && q->direction[8] == 1 &&
              fabs(q->origin[0] - 106.973388671875) < 1e-9 && q->spacing[0] == 3.4375,
          "ASL geometry: D diag %g %g %g, origin x %g, spacing x %g", q->direction[0],
          q->direction[4], q->direction[8], q->origin[0], q->spacing[0]);
    cdvr_tf tf;
    const cdvr_tf_point pts[] = {{0, 0, 0, 0, 0}, {40, .1, .2, .6, 0}, {80, .2, .6, 1, .12},
                                 {160, 1, .35, .1, .8}, {255, 1, 1, 1, 1}};
    CHECK_OK(cdvr_tf_init(&tf, pts, 5, 0, &err), err);
    /* from the front (anterior, +y) and from above (+z), looking at the box centre */
    const double views[2][3] = {{0, -1, 0}, {0, 0, -1}}, ups[2][3] = {{0, 0, 1}, {0, 1, 0}};
    /* the x-reversed copy with identity direction: the same field */
    cdvr_volume *flipped = reorder(q, q->dims, reverse_x);
    /* what cdvr rendered before: the direction ignored, the box centred at the same place */
    cdvr_volume *ignored = NULL;
    CHECK_OK(cdvr_volume_slice_time(q, 0, 1, &ignored, &err), err);
    if (flipped && ignored) {
        memset(ignored->direction, 0, sizeof ignored->direction);
        ignored->direction[0] = ignored->direction[4] = ignored->direction[8] = 1;
        memcpy(flipped->spacing, q->spacing, sizeof q->spacing);
        memcpy(ignored->spacing, q->spacing, sizeof q->spacing);
        double lo[3], hi[3];
        cdvr_volume_bounds(q, lo, hi);
        memcpy(flipped->origin, lo, sizeof lo);
        memcpy(ignored->origin, lo, sizeof lo);
        for (int v = 0; v < 2; v++) {
            cdvr_camera cam;
            look_at_centre(&cam, q, views[v], ups[v], 700);
            cdvr_image *now = render(q, &tf, &cam), *same = render(flipped, &tf, &cam);
            cdvr_image *before = render(ignored, &tf, &cam), *mirror = NULL;
            CHECK(psnr(now, same) >= 60 && mean_alpha(now) > 0.05,
                  "ASL view %d: oriented vs x-reversed copy %.1f dB, coverage %.3f", v,
                  psnr(now, same), mean_alpha(now));
            if (before && cdvr_image_create(before->width, before->height, &mirror, &err) == CDVR_OK) {
                memcpy(mirror->background, before->background, sizeof mirror->background);
                for (int y = 0; y < before->height; y++)
                    for (int x = 0; x < before->width; x++)
                        memcpy(cdvr_image_pixel(mirror, x, y),
                               cdvr_image_pixel(before, before->width - 1 - x, y), 4 * sizeof(float));
                CHECK(psnr(now, mirror) >= 45 && psnr(now, before) < 30,
                      "ASL view %d: the render is the left-right mirror of the old one (%.1f dB; "
                      "unmirrored %.1f dB)", v, psnr(now, mirror), psnr(now, before));
            }
            cdvr_image_free(now);
            cdvr_image_free(same);
            cdvr_image_free(before);
            cdvr_image_free(mirror);
        }
    }
    cdvr_volume_free(flipped);
    cdvr_volume_free(ignored);
    cdvr_volume_free(q);
}

int main(void)
{
    test_nifti();
    test_nrrd();
    test_render_index_order();
    test_asl_mirror();
    return check_finish();
}
