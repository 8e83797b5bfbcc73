/* tests/test_io_write.c - cdvr_volume_save (cdvr/write.h) against cdvr's own loaders: for every
 * suffix (.nrrd .nhdr .nii .nii.gz .vti .mha .mhd), every volume type (u8, u16, i16, f32),
 * compressed and not, 3D and 4D (where the format holds a series), odd dims 5x7x3 with an
 * oblique direction (right- and left-handed) and a non-zero origin, load(save(v)) gives the same
 * voxels (byte for byte), dims, timesteps, type, spacing, origin and direction (NIfTI: within
 * float32, its header's precision; its qform equals its sform, qfac -1 when left-handed), and
 * the probe agrees. Refusals: a directory or FIFO target
 * (and a .nhdr/.mhd whose data file name is a directory) is refused and left as it was; a
 * series saved as .vti or .pvd is numbered .vti files and a .pvd with its times, loading back
 * voxel for voxel (a frame name that is a directory: refused, nothing left); an unknown suffix
 * and contradictory compress options are refused; a save that fails
 * part way (RLIMIT_FSIZE) leaves nothing in the directory. */
#include "check.h"
#include "cdvr/write.h"
#include "cdvr/volume.h"

#include <dirent.h>
#include <nifti1_io.h>
#include <math.h>
#include <signal.h>
#include <stdint.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

static char tmpdir[] = "/tmp/cdvr_test_io_write_XXXXXX";

static void path_of(char *out, size_t n, const char *name)
{
    snprintf(out, n, "%s/%s", tmpdir, name);
}

/* Entries of tmpdir, not counting . and .. */
static int entries(void)
{
    DIR *d = opendir(tmpdir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        n += strcmp(e->d_name, ".") && strcmp(e->d_name, "..");
    if (d)
        closedir(d);
    return n;
}

static void rm_all(void)
{
    DIR *d = opendir(tmpdir);
    for (struct dirent *e; d && (e = readdir(d));) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        char p[512];
        path_of(p, sizeof p, e->d_name);
        if (unlink(p) != 0)
            rmdir(p);
    }
    if (d)
        closedir(d);
}

/* A 5x7x3 volume of `type` with t timesteps, distinct values, oblique geometry. */
static cdvr_volume *make(cdvr_type type, size_t t, int left_handed)
{
    size_t dims[3] = {5, 7, 3};
    cdvr_volume *v;
    cdvr_error err;
    if (cdvr_volume_create(dims, t, type, &v, &err) != CDVR_OK)
        return NULL;
    size_t n = cdvr_volume_voxels(v) * t;
    for (size_t i = 0; i < n; i++) {
        switch (type) {
        case CDVR_TYPE_U8: ((uint8_t *)v->data)[i] = (uint8_t)(i * 7 % 256); break;
        case CDVR_TYPE_U16: ((uint16_t *)v->data)[i] = (uint16_t)(i * 977 % 65536); break;
        case CDVR_TYPE_I16: ((int16_t *)v->data)[i] = (int16_t)((long)(i * 131) % 60000 - 30000); break;
        default: ((float *)v->data)[i] = (float)(0.25 * (double)i - 7.5 + 1e-3 * (double)(i % 7)); break;
        }
    }
    v->spacing[0] = 0.5;
    v->spacing[1] = 1.25;
    v->spacing[2] = 2.0;
    v->origin[0] = -3.5;
    v->origin[1] = 10.25;
    v->origin[2] = 7.125;
    /* R = Rz(30 deg) * Rx(20 deg) */
    double a = 30.0 * M_PI / 180.0, b = 20.0 * M_PI / 180.0;
    double Rz[9] = {cos(a), -sin(a), 0, sin(a), cos(a), 0, 0, 0, 1};
    double Rx[9] = {1, 0, 0, 0, cos(b), -sin(b), 0, sin(b), cos(b)};
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) {
            double s = 0;
            for (int k = 0; k < 3; k++)
                s += Rz[3 * r + k] * Rx[3 * k + c];
            v->direction[3 * r + c] = s * (left_handed && c == 1 ? -1.0 : 1.0);
        }
    return v;
}

static int close_to(const double *a, const double *b, int n, double tol)
{
    for (int i = 0; i < n; i++)
        if (!(fabs(a[i] - b[i]) <= tol * (1.0 + fabs(b[i]))))
            return 0;
    return 1;
}

static void same_geometry(const char *what, const cdvr_volume *got, const cdvr_volume *want,
                          double tol)
{
    CHECK(got->dims[0] == want->dims[0] && got->dims[1] == want->dims[1] &&
              got->dims[2] == want->dims[2] && got->timesteps == want->timesteps,
          "%s: dims %zux%zux%zu x%zu", what, got->dims[0], got->dims[1], got->dims[2],
          got->timesteps);
    CHECK(got->type == want->type, "%s: type %s", what, cdvr_type_name(got->type));
    CHECK(close_to(got->spacing, want->spacing, 3, tol), "%s: spacing %.17g %.17g %.17g", what,
          got->spacing[0], got->spacing[1], got->spacing[2]);
    CHECK(close_to(got->origin, want->origin, 3, tol), "%s: origin %.17g %.17g %.17g", what,
          got->origin[0], got->origin[1], got->origin[2]);
    CHECK(close_to(got->direction, want->direction, 9, tol), "%s: direction %.17g %.17g %.17g "
          "%.17g %.17g %.17g %.17g %.17g %.17g", what, got->direction[0], got->direction[1],
          got->direction[2], got->direction[3], got->direction[4], got->direction[5],
          got->direction[6], got->direction[7], got->direction[8]);
}

/* First bytes of path contain needle (text headers) or start with 1f 8b (needle NULL). */
static int file_has(const char *path, const char *needle)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return 0;
    char buf[2048];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    if (!needle)
        return n >= 2 && (uint8_t)buf[0] == 0x1f && (uint8_t)buf[1] == 0x8b;
    for (size_t i = 0; i + strlen(needle) <= n; i++)
        if (memcmp(buf + i, needle, strlen(needle)) == 0)
            return 1;
    return 0;
}

typedef struct fmt {
    const char *suffix;
    int series;    /* holds timesteps > 1 */
    int can_plain, can_compress;
    double tol;    /* geometry tolerance (relative) */
    const char *compressed_mark; /* header text that says so, NULL: gzip magic */
    const char *data_tail[2];    /* detached data file: plain, compressed */
} fmt;

static const fmt FORMATS[] = {
    {".nrrd", 1, 1, 1, 1e-12, "encoding: gzip", {NULL, NULL}},
    {".nhdr", 1, 1, 1, 1e-12, "encoding: gzip", {".raw", ".raw.gz"}},
    {".nii", 1, 1, 0, 2e-6, NULL, {NULL, NULL}},
    {".nii.gz", 1, 0, 1, 2e-6, NULL, {NULL, NULL}},
    {".vti", 0, 1, 1, 1e-12, "vtkZLibDataCompressor", {NULL, NULL}},
    {".mha", 1, 1, 1, 1e-12, "CompressedData = True", {NULL, NULL}},
    {".mhd", 1, 1, 1, 1e-12, "CompressedData = True", {".raw", ".zraw"}},
};

static void round_trip(const fmt *f, cdvr_type type, size_t t, int compress, int left)
{
    char name[64], path[512], what[160];
    snprintf(name, sizeof name, "v_%s_%zu_%d%s", cdvr_type_name(type), t, compress, f->suffix);
    path_of(path, sizeof path, name);
    snprintf(what, sizeof what, "%s%s", name, left ? " (left-handed)" : "");
    cdvr_volume *v = make(type, t, left);
    cdvr_error err;
    cdvr_save_opts o = {compress, NULL};
    cdvr_status st = cdvr_volume_save(v, path, &o, &err);
    CHECK_OK(st, err);
    if (st == CDVR_OK) {
        if (compress)
            CHECK(file_has(path, f->compressed_mark), "%s: not compressed", what);
        if (f->data_tail[compress]) {
            char data[512];
            snprintf(data, sizeof data, "%.*s%s", (int)(strlen(path) - strlen(f->suffix)), path,
                     f->data_tail[compress]);
            struct stat sb;
            CHECK(stat(data, &sb) == 0 && S_ISREG(sb.st_mode), "%s: no data file %s", what, data);
        }
        if (strstr(f->suffix, ".nii")) { /* the qform is the sform (an orthonormal D) */
            nifti_image *nim = nifti_image_read(path, 0);
            CHECK(nim && nim->qform_code == 1 && nim->sform_code == 1, "%s: codes", what);
            double worst = 0;
            for (int r = 0; nim && r < 3; r++)
                for (int c = 0; c < 4; c++)
                    worst = fmax(worst, fabs(nim->qto_xyz.m[r][c] - nim->sto_xyz.m[r][c]));
            CHECK(nim && worst < 1e-5, "%s: qform differs from the sform by %g", what, worst);
            CHECK(nim && (nim->qfac < 0) == (left != 0), "%s: qfac %g", what,
                  nim ? nim->qfac : 0.0);
            if (nim)
                nifti_image_free(nim);
        }
        cdvr_volume *back = NULL;
        st = cdvr_volume_load(path, NULL, &back, &err);
        CHECK_OK(st, err);
        if (st == CDVR_OK) {
            same_geometry(what, back, v, f->tol);
            size_t bytes = cdvr_volume_frame_bytes(v) * t;
            CHECK(back->type == v->type && back->timesteps == t &&
                      memcmp(back->data, v->data, bytes) == 0, "%s: voxels differ", what);
            cdvr_volume head = {0};
            head.spacing[0] = head.spacing[1] = head.spacing[2] = 1;
            st = cdvr_volume_probe(path, NULL, &head, &err);
            CHECK_OK(st, err);
            if (st == CDVR_OK)
                same_geometry(what, &head, v, f->tol);
            cdvr_volume_free(back);
        }
    }
    cdvr_volume_free(v);
}

static void refusals(void)
{
    cdvr_error err;
    char path[512];
    cdvr_volume *v = make(CDVR_TYPE_U16, 1, 0), *s = make(CDVR_TYPE_U16, 2, 0);
    rm_all();
    /* a directory and a FIFO under the name */
    static const char *const names[] = {"d.nrrd", "d.nhdr", "d.nii", "d.nii.gz", "d.vti", "d.mha", "d.mhd"};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
        for (int fifo = 0; fifo < 2; fifo++) {
            path_of(path, sizeof path, names[i]);
            CHECK(fifo ? mkfifo(path, 0644) == 0 : mkdir(path, 0755) == 0, "%s", path);
            cdvr_status st = cdvr_volume_save(v, path, NULL, &err);
            CHECK(st == CDVR_ERR_IO && strstr(err.msg, names[i]) &&
                      strstr(err.msg, fifo ? "FIFO" : "directory"),
                  "%s (%s): %d %s", names[i], fifo ? "fifo" : "dir", (int)st, err.msg);
            struct stat sb;
            CHECK(stat(path, &sb) == 0 && (fifo ? S_ISFIFO(sb.st_mode) : S_ISDIR(sb.st_mode)),
                  "%s: target changed", names[i]);
            CHECK(entries() == 1, "%s: %d entries left", names[i], entries());
            if (fifo)
                unlink(path);
            else
                rmdir(path);
        }
    }
    /* a detached data file name that is a directory: nothing written */
    static const char *const detached[][2] = {{"x.nhdr", "x.raw"}, {"y.mhd", "y.raw"}};
    for (int i = 0; i < 2; i++) {
        char data[512];
        path_of(data, sizeof data, detached[i][1]);
        path_of(path, sizeof path, detached[i][0]);
        mkdir(data, 0755);
        cdvr_status st = cdvr_volume_save(v, path, NULL, &err);
        CHECK(st == CDVR_ERR_IO && strstr(err.msg, detached[i][1]), "%s: %d %s", detached[i][0],
              (int)st, err.msg);
        CHECK(entries() == 1, "%s: %d entries left", detached[i][0], entries());
        rmdir(data);
    }
    /* a .vti series whose second frame's name is a directory: refused, the first frame gone */
    path_of(path, sizeof path, "s_0001.vti");
    mkdir(path, 0755);
    path_of(path, sizeof path, "s.vti");
    cdvr_status st = cdvr_volume_save(s, path, NULL, &err);
    CHECK(st == CDVR_ERR_IO && strstr(err.msg, "s_0001.vti") && entries() == 1,
          "vti series over a directory: %d %s, %d entries", (int)st, err.msg, entries());
    path_of(path, sizeof path, "s_0001.vti");
    rmdir(path);
    /* an unknown suffix, contradictory compress */
    path_of(path, sizeof path, "v.png");
    st = cdvr_volume_save(v, path, NULL, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "v.png") && strstr(err.msg, ".mhd"), "png: %s",
          err.msg);
    cdvr_save_opts on = {1, NULL}, off = {0, NULL};
    path_of(path, sizeof path, "v.nii");
    st = cdvr_volume_save(v, path, &on, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, ".nii.gz"), "nii compress: %s", err.msg);
    path_of(path, sizeof path, "v.nii.gz");
    st = cdvr_volume_save(v, path, &off, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "compress=false"), "nii.gz plain: %s", err.msg);
    /* a singular direction */
    cdvr_volume *bad = make(CDVR_TYPE_U8, 1, 0);
    memset(bad->direction, 0, sizeof bad->direction);
    bad->direction[0] = 1;
    bad->direction[4] = 1; /* third column zero */
    path_of(path, sizeof path, "bad.nrrd");
    st = cdvr_volume_save(bad, path, NULL, &err);
    CHECK(st == CDVR_ERR_ARG && strstr(err.msg, "bad.nrrd") && strstr(err.msg, "singular"),
          "singular: %s", err.msg);
    cdvr_volume_free(bad);
    CHECK(entries() == 0, "refusals left %d entries", entries());
    /* a write that fails part way: nothing left (a 32000-byte volume, files limited to 2000) */
    size_t dims[3] = {20, 20, 20};
    cdvr_volume *big;
    if (cdvr_volume_create(dims, 1, CDVR_TYPE_F32, &big, &err) == CDVR_OK) {
        for (size_t i = 0; i < 8000; i++)
            ((float *)big->data)[i] = (float)i;
        signal(SIGXFSZ, SIG_IGN);
        struct rlimit old, lim;
        getrlimit(RLIMIT_FSIZE, &old);
        lim = old;
        lim.rlim_cur = 2000;
        CHECK(setrlimit(RLIMIT_FSIZE, &lim) == 0, "setrlimit");
        for (size_t i = 0; i < sizeof names / sizeof *names; i++) {
            char name[32];
            snprintf(name, sizeof name, "f%s", names[i] + 1);
            path_of(path, sizeof path, name);
            st = cdvr_volume_save(big, path, NULL, &err);
            CHECK(st == CDVR_ERR_IO && strstr(err.msg, "f."), "%s: %d %s", name, (int)st, err.msg);
            CHECK(entries() == 0, "%s: a failed save left %d entries", name, entries());
            rm_all();
        }
        setrlimit(RLIMIT_FSIZE, &old);
        signal(SIGXFSZ, SIG_DFL);
        cdvr_volume_free(big);
    }
    cdvr_volume_free(v);
    cdvr_volume_free(s);
}

/* The value window of a u8 volume survives save and load (and probe) in every format: NRRD's
 * old min/max, MetaImage's CdvrValueWindow key, VTI's CdvrValueWindow attribute, NIfTI's
 * descrip; a u8 volume of window [0, 255] loads as [0, 255]. */
static void test_u8_window(void)
{
    static const char *const names[] = {"w.nrrd", "w.nhdr", "w.nii", "w.nii.gz", "w.vti",
                                        "w.mha", "w.mhd"};
    cdvr_error err;
    char path[512];
    for (size_t i = 0; i < sizeof names / sizeof *names; i++)
        for (int plain = 0; plain < 2; plain++) {
            rm_all();
            cdvr_volume *v = make(CDVR_TYPE_U8, 1, 0);
            double want[2] = {plain ? 0 : -2.5, plain ? 255 : 1000.0078125};
            v->window[0] = want[0];
            v->window[1] = want[1];
            path_of(path, sizeof path, names[i]);
            cdvr_status st = cdvr_volume_save(v, path, NULL, &err);
            CHECK_OK(st, err);
            cdvr_volume *back = NULL, head;
            st = cdvr_volume_load(path, NULL, &back, &err);
            CHECK(st == CDVR_OK && back->type == CDVR_TYPE_U8 && back->window[0] == want[0] &&
                      back->window[1] == want[1] &&
                      memcmp(back->data, v->data, cdvr_volume_frame_bytes(v)) == 0,
                  "%s: u8 window [%g, %g] back as [%g, %g]", names[i], want[0], want[1],
                  back ? back->window[0] : NAN, back ? back->window[1] : NAN);
            st = cdvr_volume_probe(path, NULL, &head, &err);
            CHECK(st == CDVR_OK && head.window[0] == want[0] && head.window[1] == want[1],
                  "%s: the probe gives the window [%g, %g]", names[i], head.window[0],
                  head.window[1]);
            cdvr_volume_free(back);
            cdvr_volume_free(v);
        }
    rm_all();
}

/* The world a volume knows (cdvr_volume.space): NRRD names it (space:) and reads it back; NIfTI
 * loads as RAS and turns an LPS volume into RAS (x and y negated); unknown stays unnamed. */
static void test_space(void)
{
    cdvr_error err;
    char path[512];
    rm_all();
    cdvr_volume *v = make(CDVR_TYPE_I16, 1, 0), *back = NULL;
    memcpy(v->space, "LPS", 4);
    path_of(path, sizeof path, "lps.nrrd");
    CHECK_OK(cdvr_volume_save(v, path, NULL, &err), err);
    CHECK(file_has(path, "space: left-posterior-superior"), "lps.nrrd names its space");
    CHECK_OK(cdvr_volume_load(path, NULL, &back, &err), err);
    if (back) {
        CHECK(strcmp(back->space, "LPS") == 0, "lps.nrrd loads as LPS: '%s'", back->space);
        same_geometry("lps.nrrd", back, v, 1e-15);
    }
    cdvr_volume_free(back);
    path_of(path, sizeof path, "lps.nii");
    CHECK_OK(cdvr_volume_save(v, path, NULL, &err), err);
    back = NULL;
    CHECK_OK(cdvr_volume_load(path, NULL, &back, &err), err);
    if (back) {
        cdvr_volume ras = *v;
        for (int r = 0; r < 2; r++) { /* LPS -> RAS: x and y turn around */
            ras.origin[r] = -v->origin[r];
            for (int c = 0; c < 3; c++)
                ras.direction[3 * r + c] = -v->direction[3 * r + c];
        }
        CHECK(strcmp(back->space, "RAS") == 0, "lps.nii loads as RAS: '%s'", back->space);
        same_geometry("lps.nii (in RAS)", back, &ras, 1e-6);
        /* and a RAS volume (from NIfTI) saved as NRRD names RAS */
        path_of(path, sizeof path, "ras.nrrd");
        CHECK_OK(cdvr_volume_save(back, path, NULL, &err), err);
        CHECK(file_has(path, "space: right-anterior-superior"), "ras.nrrd names its space");
    }
    cdvr_volume_free(back);
    v->space[0] = '\0';
    path_of(path, sizeof path, "plain.nrrd");
    CHECK_OK(cdvr_volume_save(v, path, NULL, &err), err);
    CHECK(file_has(path, "space dimension: 3") && !file_has(path, "space: "),
          "a volume of unknown world: space dimension only");
    cdvr_volume_free(v);
    rm_all();
}

/* A series saved as .vti or .pvd: NAME_0000.vti ... and NAME.pvd with the times given (else
 * 0, 1, ...); cdvr_volume_load of the .pvd gives the series back voxel for voxel. */
static void test_pvd_series(void)
{
    cdvr_error err;
    char path[512], pvd[512];
    for (int compress = 0; compress < 2; compress++)
        for (int k = 0; k < 2; k++) {
            rm_all();
            cdvr_volume *s = make(k ? CDVR_TYPE_F32 : CDVR_TYPE_U16, 3, k);
            double times[3] = {0.5, 2.25, 7};
            cdvr_save_opts o = {compress, k ? times : NULL};
            path_of(path, sizeof path, k ? "run.pvd" : "run.vti");
            path_of(pvd, sizeof pvd, "run.pvd");
            cdvr_status st = cdvr_volume_save(s, path, &o, &err);
            CHECK_OK(st, err);
            CHECK(entries() == 4, "%s: run.pvd and three .vti files (%d entries)", path, entries());
            char frame[512];
            path_of(frame, sizeof frame, "run_0002.vti");
            CHECK(file_has(frame, "<ImageData"), "%s: run_0002.vti written", path);
            CHECK(file_has(pvd, k ? "timestep=\"2.25\"" : "timestep=\"1\"") &&
                      file_has(pvd, "file=\"run_0001.vti\""),
                  "%s: the .pvd lists the frames with their times", path);
            cdvr_volume *back = NULL;
            st = cdvr_volume_load(pvd, NULL, &back, &err);
            CHECK_OK(st, err);
            if (st == CDVR_OK) {
                same_geometry(path, back, s, 0);
                CHECK(memcmp(back->data, s->data, cdvr_volume_frame_bytes(s) * 3) == 0,
                      "%s: voxels differ", path);
            }
            cdvr_volume_free(back);
            cdvr_volume_free(s);
        }
    rm_all();
}

int main(void)
{
    if (!mkdtemp(tmpdir))
        return perror("mkdtemp"), 1;
    const cdvr_type types[] = {CDVR_TYPE_U8, CDVR_TYPE_U16, CDVR_TYPE_I16, CDVR_TYPE_F32};
    for (size_t i = 0; i < sizeof FORMATS / sizeof *FORMATS; i++) {
        const fmt *f = &FORMATS[i];
        for (int ty = 0; ty < 4; ty++)
            for (int c = 0; c < 2; c++) {
                if (c ? !f->can_compress : !f->can_plain)
                    continue;
                round_trip(f, types[ty], 1, c, 0);
                if (f->series)
                    round_trip(f, types[ty], 3, c, ty == 1);
            }
        round_trip(f, CDVR_TYPE_F32, 1, f->can_plain ? 0 : 1, 1);
        rm_all();
    }
    refusals();
    test_pvd_series();
    test_u8_window();
    test_space();
    rm_all();
    rmdir(tmpdir);
    return check_finish();
}
