/* tests/test_format.c - the file-format table and registry (cdvr/format.h, core/io/format.c):
 *  - the built-ins (nrrd, nifti, raw) are registered and found by name, by suffix (longest
 *    first, any case) and by magic; the registry refuses a NULL table, a bad name, each missing
 *    member (naming it), a bad suffix, a name or suffix clash (naming the other format), and
 *    takes the same table twice as a no-op;
 *  - dispatch: a NRRD under a name without suffix loads by its magic and equals the .nrrd load;
 *    a raw description reads any other name as raw; a file neither suffix nor magic matches is
 *    refused with a message naming it and listing every known format with its suffixes; so is
 *    a missing file of unknown suffix (with the reason);
 *  - a format registered here with `read` only (no load) loads through the registry's probe +
 *    allocate + read, with the spacing override applied; its `expand` turns one list file into
 *    a series for cdvr_volume_load_series and cdvr_series_open;
 *  - the example format plugin (plugins/format_example, when built) loads with
 *    cdvr_plugin_load_info, registers its two formats (file named), and cdvr_volume_load opens
 *    a .cvol file (and one without suffix, by magic); a .cvls list opens as a series; a .cvls
 *    alone is refused with its reason.
 * Behaviour of the NRRD, NIfTI and raw loads themselves is tests/test_io.c's. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cdvr/format.h"
#include "cdvr/plugin.h"
#include "cdvr/series.h"
#include "cdvr/volume.h"
#include "check.h"

static char dir[] = "/tmp/cdvr_test_format_XXXXXX";

static const char *tmp(const char *name)
{
    static char paths[8][512];
    static int next;
    char *p = paths[next++ % 8];
    snprintf(p, sizeof paths[0], "%s/%s", dir, name);
    return p;
}

static void write_file(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    CHECK(f && fwrite(data, 1, n, f) == n, "write %s", path);
    if (f)
        fclose(f);
}

static void write_text(const char *path, const char *text)
{
    write_file(path, text, strlen(text));
}

/* ---- the registry --------------------------------------------------------------------------- */

static cdvr_status ok_probe(const char *path, const cdvr_raw_opts *o, cdvr_volume *h,
                            cdvr_error *err)
{
    (void)path, (void)o, (void)h, (void)err;
    return CDVR_OK;
}

static cdvr_status ok_read(const char *path, const cdvr_raw_opts *o, const cdvr_volume *h,
                           void *voxels, cdvr_error *err)
{
    (void)path, (void)o, (void)h, (void)voxels, (void)err;
    return CDVR_OK;
}

static int never(const uint8_t *head, size_t n)
{
    (void)head, (void)n;
    return 0;
}

static void expect_refused(const cdvr_format *f, const char *want)
{
    cdvr_error err;
    cdvr_error_clear(&err);
    size_t before = cdvr_format_count();
    CHECK(cdvr_format_register(f, &err) == CDVR_ERR_ARG && strstr(err.msg, want),
          "want '%s': %s", want, err.msg);
    CHECK(cdvr_format_count() == before, "registry grew on a refusal (%s)", want);
}

static void test_registry(void)
{
    CHECK(cdvr_format_count() >= 3, "%zu formats", cdvr_format_count());
    const char *names[] = {"nrrd", "nifti", "raw"};
    for (size_t i = 0; i < 3; i++) {
        const cdvr_format *f = cdvr_format_find(names[i]);
        CHECK(f && f == cdvr_format_at(i) && f->description && f->probe && f->load, "%s",
              names[i]);
    }
    CHECK(cdvr_format_find("nope") == NULL && cdvr_format_find(NULL) == NULL, "find unknown");
    CHECK(cdvr_format_at(cdvr_format_count()) == NULL, "at past the end");
    CHECK(cdvr_format_by_suffix("a/b.NRRD") == cdvr_format_find("nrrd"), "suffix case");
    CHECK(cdvr_format_by_suffix("x.nhdr") == cdvr_format_find("nrrd"), ".nhdr");
    CHECK(cdvr_format_by_suffix("x.nii.gz") == cdvr_format_find("nifti"), ".nii.gz");
    CHECK(cdvr_format_by_suffix("x.dat") == cdvr_format_find("raw"), ".dat");
    CHECK(cdvr_format_by_suffix("x.gz") == NULL && cdvr_format_by_suffix("nrrd") == NULL,
          "no suffix");
    uint8_t head[400] = "NRRD0004\ntype: uchar\n";
    CHECK(cdvr_format_by_magic(head, 20) == cdvr_format_find("nrrd"), "nrrd magic");
    CHECK(cdvr_format_by_magic(head, 7) == NULL, "7 bytes are not enough");
    memset(head, 0, sizeof head);
    head[0] = 92, head[1] = 1; /* sizeof_hdr 348, little endian */
    memcpy(head + 344, "n+1", 4);
    CHECK(cdvr_format_by_magic(head, 348) == cdvr_format_find("nifti"), "nifti magic");
    CHECK(cdvr_format_by_magic(head, 347) == NULL, "a cut nifti header");
    head[0] = head[1] = 0, head[2] = 1, head[3] = 92; /* big endian */
    CHECK(cdvr_format_by_magic(head, 348) == cdvr_format_find("nifti"), "nifti big endian");
    memcpy(head, "\x7f" "ELF", 4);
    CHECK(cdvr_format_by_magic(head, sizeof head) == NULL, "no magic");

    static const char *const sfx[] = {".tst", NULL}, *const bad_sfx[] = {"tst", NULL},
                             *const nii[] = {".xyz", ".NII", NULL}, *const none[] = {NULL};
    cdvr_format t = {"tst", "test format", sfx, 0, NULL, ok_probe, NULL, ok_read, NULL, NULL, NULL};
    cdvr_format f = t;
    expect_refused(NULL, "format table is NULL");
    f.name = "Bad Name";
    expect_refused(&f, "format name 'Bad Name' is not");
    f = t, f.description = NULL;
    expect_refused(&f, "format 'tst': the table has no description");
    f = t, f.suffixes = NULL;
    expect_refused(&f, "the table has no suffixes");
    f = t, f.probe = NULL;
    expect_refused(&f, "format 'tst': the table has no probe");
    f = t, f.read = NULL;
    expect_refused(&f, "the table has no load or read");
    f = t, f.suffixes = none;
    expect_refused(&f, "neither a suffix nor a magic test");
    f = t, f.suffixes = bad_sfx;
    expect_refused(&f, "suffix 'tst' is not");
    f = t, f.name = "nrrd";
    expect_refused(&f, "format 'nrrd' is already registered");
    f = t, f.suffixes = nii;
    expect_refused(&f, "suffix .NII is already taken by format 'nifti'");
    static cdvr_format magic_only; /* found by magic alone: fine */
    magic_only = t;
    magic_only.name = "magic_only";
    magic_only.suffixes = none;
    magic_only.magic = never;
    cdvr_error err;
    size_t before = cdvr_format_count();
    CHECK_OK(cdvr_format_register(&magic_only, &err), err);
    CHECK_OK(cdvr_format_register(&magic_only, &err), err); /* again: no-op */
    CHECK(cdvr_format_count() == before + 1 && cdvr_format_find("magic_only") == &magic_only,
          "registered once");
    char list[1024];
    cdvr_format_list(list, sizeof list);
    CHECK(strstr(list, "nrrd (.nrrd .nhdr), nifti (.nii .nii.gz .hdr), raw (.raw .bin .dat, "
                       "with dims and type)") && strstr(list, "magic_only (by content)"),
          "%s", list);
    cdvr_format_list(list, 12);
    CHECK(strlen(list) == 11 && strcmp(list + 8, "...") == 0, "cut list: '%s'", list);
}

/* ---- dispatch ------------------------------------------------------------------------------- */

static void test_dispatch(void)
{
    static const char hdr[] = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n"
                              "spacings: 1 2 3\nencoding: raw\n\n";
    uint8_t file[sizeof hdr - 1 + 8];
    memcpy(file, hdr, sizeof hdr - 1);
    for (int i = 0; i < 8; i++)
        file[sizeof hdr - 1 + i] = (uint8_t)(10 * i);
    write_file(tmp("a.nrrd"), file, sizeof file);
    write_file(tmp("a_nrrd_without_suffix"), file, sizeof file);
    cdvr_volume *a = NULL, *b = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_volume_load(tmp("a.nrrd"), NULL, &a, &err), err);
    CHECK_OK(cdvr_volume_load(tmp("a_nrrd_without_suffix"), NULL, &b, &err), err);
    CHECK(a && b && a->type == b->type && b->spacing[2] == 3 &&
              memcmp(a->data, b->data, 8) == 0 && ((uint8_t *)b->data)[7] == 70,
          "NRRD by magic equals the .nrrd load");
    cdvr_volume head;
    head.data = NULL;
    CHECK_OK(cdvr_volume_probe(tmp("a_nrrd_without_suffix"), NULL, &head, &err), err);
    CHECK(head.dims[0] == 2 && head.spacing[1] == 2 && head.data == NULL, "probe by magic");
    cdvr_volume_free(a);
    cdvr_volume_free(b);

    /* a raw description reads any name as raw (the NRRD's bytes, header included) */
    cdvr_raw_opts raw = {{sizeof file, 1, 1}, 1, CDVR_TYPE_U8, 0, 0, {0, 0, 0}, 0, 0, NULL, 0};
    CHECK_OK(cdvr_volume_load(tmp("a_nrrd_without_suffix"), &raw, &a, &err), err);
    CHECK(a && a->dims[0] == sizeof file && ((uint8_t *)a->data)[0] == 'N', "raw by request");
    cdvr_volume_free(a);
    CHECK(cdvr_volume_load(tmp("a.raw"), NULL, &a, &err) == CDVR_ERR_ARG &&
              strstr(err.msg, "a raw file needs its dims and type"), "%s", err.msg);

    write_text(tmp("junk.vol"), "this is not a volume of any kind\n");
    CHECK(cdvr_volume_load(tmp("junk.vol"), NULL, &a, &err) == CDVR_ERR_FORMAT && !a, "junk");
    CHECK(strstr(err.msg, tmp("junk.vol")) && strstr(err.msg, "unknown file type") &&
              strstr(err.msg, "neither its name nor its first bytes") &&
              strstr(err.msg, "nrrd (.nrrd .nhdr)") && strstr(err.msg, "nifti (.nii") &&
              strstr(err.msg, "raw (.raw .bin .dat, with dims and type)"),
          "unknown magic: %s", err.msg);
    CHECK(cdvr_volume_probe(tmp("junk.vol"), NULL, &head, &err) == CDVR_ERR_FORMAT &&
              strstr(err.msg, "unknown file type"), "probe: %s", err.msg);
    CHECK(cdvr_volume_load(tmp("missing.vol"), NULL, &a, &err) == CDVR_ERR_FORMAT &&
              strstr(err.msg, "missing.vol") && strstr(err.msg, "cannot be read") &&
              strstr(err.msg, "No such file") && strstr(err.msg, "nrrd (.nrrd"),
          "missing: %s", err.msg);
    write_file(tmp("empty.vol"), "", 0);
    CHECK(cdvr_volume_load(tmp("empty.vol"), NULL, &a, &err) == CDVR_ERR_FORMAT &&
              strstr(err.msg, "unknown file type"), "empty: %s", err.msg);
}

/* ---- a format with read (no load) and expand, registered here -------------------------------
 * "tfmt": the file is "TFMT" and one byte n; the volume is n x 1 x 1 u16 with voxel i = 100 + i
 * and spacing 0.5 along x. "tlst": "TLST" then names of files in dir, one per line. */

static cdvr_status tfmt_probe(const char *path, const cdvr_raw_opts *o, cdvr_volume *h,
                              cdvr_error *err)
{
    (void)o;
    uint8_t b[5];
    FILE *f = fopen(path, "rb");
    size_t got = f ? fread(b, 1, 5, f) : 0;
    if (f)
        fclose(f);
    if (got != 5 || memcmp(b, "TFMT", 4) != 0 || b[4] == 0)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not tfmt", path);
    CHECK(h->spacing[0] == 1 && h->direction[0] == 1 && h->direction[1] == 0 && h->dims[0] == 0,
          "head comes preset");
    h->dims[0] = b[4], h->dims[1] = h->dims[2] = 1;
    h->timesteps = 1;
    h->type = CDVR_TYPE_U16;
    h->spacing[0] = 0.5;
    return CDVR_OK;
}

static cdvr_status tfmt_read(const char *path, const cdvr_raw_opts *o, const cdvr_volume *h,
                             void *voxels, cdvr_error *err)
{
    (void)path, (void)o, (void)err;
    for (size_t i = 0; i < h->dims[0]; i++)
        ((uint16_t *)voxels)[i] = (uint16_t)(100 + i);
    return CDVR_OK;
}

static int tfmt_magic(const uint8_t *head, size_t n)
{
    return n >= 4 && memcmp(head, "TFMT", 4) == 0;
}

static cdvr_status tlst_expand(const char *path, int (*add)(void *, const char *), void *ud,
                               cdvr_error *err)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot open", path);
    char line[256];
    int n = 0;
    while (fgets(line, sizeof line, f))
        if (n++ > 0) {
            line[strcspn(line, "\n")] = '\0';
            add(ud, tmp(line)); /* add's 0 ignored on purpose: the registry notices anyway */
        }
    fclose(f);
    return CDVR_OK;
}

static void test_read_and_expand(void)
{
    static const char *const tfmt_sfx[] = {".tfmt", NULL}, *const tlst_sfx[] = {".tlst", NULL};
    static const cdvr_format tfmt = {"tfmt", "test: read only", tfmt_sfx, 0, tfmt_magic,
                                     tfmt_probe, NULL, tfmt_read, NULL, NULL, NULL};
    static const cdvr_format tlst = {"tlst", "test: a list", tlst_sfx, 0, NULL,
                                     tfmt_probe, NULL, tfmt_read, tlst_expand, NULL, NULL};
    cdvr_error err;
    CHECK_OK(cdvr_format_register(&tfmt, &err), err);
    CHECK_OK(cdvr_format_register(&tlst, &err), err);
    write_file(tmp("three.tfmt"), "TFMT\3", 5);
    write_file(tmp("two"), "TFMT\2", 5); /* no suffix: by magic */
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load(tmp("three.tfmt"), NULL, &v, &err), err);
    CHECK(v && v->dims[0] == 3 && v->type == CDVR_TYPE_U16 && v->spacing[0] == 0.5 &&
              ((uint16_t *)v->data)[2] == 102 && isnan(v->window[0]),
          "read through the registry");
    cdvr_volume_free(v);
    cdvr_raw_opts spacing = {{0, 0, 0}, 0, CDVR_TYPE_U8, 0, 0, {2, 0, 0}, 0, 0, NULL, 0};
    CHECK_OK(cdvr_volume_load(tmp("two"), &spacing, &v, &err), err);
    CHECK(v && v->dims[0] == 2 && v->spacing[0] == 2 && v->spacing[1] == 1, "spacing override");
    cdvr_volume_free(v);

    write_text(tmp("s.tlst"), "TLST\nthree.tfmt\nthree.tfmt\n");
    const char *list = tmp("s.tlst");
    CHECK_OK(cdvr_volume_load_series(&list, 1, NULL, &v, &err), err);
    CHECK(v && v->timesteps == 2 && v->dims[0] == 3 && ((uint16_t *)v->data)[5] == 102,
          "a list file expands into a series");
    cdvr_volume_free(v);
    cdvr_series *s = NULL;
    CHECK_OK(cdvr_series_open(&list, 1, NULL, &s, &err), err);
    CHECK(s && cdvr_series_get_info(s)->files == 2 && cdvr_series_get_info(s)->timesteps == 2 &&
              strcmp(cdvr_series_path(s, 1), tmp("three.tfmt")) == 0,
          "cdvr_series_open expands it too");
    cdvr_series_close(s);
    write_text(tmp("bad.tlst"), "TLST\nthree.tfmt\ntwo\n"); /* dims differ: named */
    list = tmp("bad.tlst");
    CHECK(cdvr_volume_load_series(&list, 1, NULL, &v, &err) == CDVR_ERR_FORMAT &&
              strstr(err.msg, "two") && strstr(err.msg, "three.tfmt"), "%s", err.msg);
    write_text(tmp("empty.tlst"), "TLST\n");
    list = tmp("empty.tlst");
    CHECK(cdvr_volume_load_series(&list, 1, NULL, &v, &err) == CDVR_ERR_FORMAT &&
              strstr(err.msg, "empty.tlst: the tlst file names no files"), "%s", err.msg);
}

/* ---- the example format plugin -------------------------------------------------------------- */

static int built(const char *plugin)
{
    const char *list = getenv("CDVR_BUILT_PLUGINS");
    size_t n = strlen(plugin);
    for (const char *p = list ? strstr(list, plugin) : NULL; p; p = strstr(p + 1, plugin))
        if ((p == list || p[-1] == ' ') && (p[n] == '\0' || p[n] == ' '))
            return 1;
    return 0;
}

static void test_plugin(void)
{
    if (!built("format_example")) {
        printf("plugin format_example not built: its cases are skipped\n");
        return;
    }
    const char *bin = getenv("CDVR_BINARY_DIR");
    char path[2048];
    snprintf(path, sizeof path, "%s/plugins/cdvr_format_example.so", bin && *bin ? bin : ".");
    const cdvr_plugin_info *info = NULL;
    cdvr_error err;
    size_t before = cdvr_format_count();
    CHECK_OK(cdvr_plugin_load_info(path, &info, &err), err);
    CHECK(info && info->abi == CDVR_PLUGIN_ABI && !info->codec && info->formats &&
              info->formats[0] && info->formats[1] && !info->formats[2],
          "what the plugin gives");
    const cdvr_format *cvol = cdvr_format_find("cvol"), *cvls = cdvr_format_find("cvls");
    CHECK(cvol && cvls && cdvr_format_count() == before + 2, "registered: %zu formats",
          cdvr_format_count());
    const char *file = cdvr_plugin_format_file(cvol);
    CHECK(file && strcmp(file, path) == 0, "plugin file %s", file ? file : "(none)");
    CHECK(cdvr_plugin_format_file(cdvr_format_find("nrrd")) == NULL, "built-in has no file");
    const cdvr_codec *codec = (const cdvr_codec *)1;
    CHECK_OK(cdvr_plugin_load(path, &codec, &err), err); /* again: no-op, and no codec */
    CHECK(codec == NULL && cdvr_format_count() == before + 2, "second load");

    static const char hdr[] = "CVOL1\ndims 2 1 1\ntype f32\ntimesteps 2\nspacing 1 1 4\n\n";
    const float vals[4] = {1.5f, -2, 3, 4};
    uint8_t bytes[sizeof hdr - 1 + sizeof vals];
    memcpy(bytes, hdr, sizeof hdr - 1);
    memcpy(bytes + sizeof hdr - 1, vals, sizeof vals); /* little-endian host */
    write_file(tmp("v.cvol"), bytes, sizeof bytes);
    write_file(tmp("v_by_magic"), bytes, sizeof bytes);
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load(tmp("v.cvol"), NULL, &v, &err), err);
    CHECK(v && v->type == CDVR_TYPE_F32 && v->timesteps == 2 && v->spacing[2] == 4 &&
              ((float *)v->data)[1] == -2 && ((float *)v->data)[3] == 4,
          "a .cvol through cdvr_volume_load");
    cdvr_volume_free(v);
    CHECK_OK(cdvr_volume_load(tmp("v_by_magic"), NULL, &v, &err), err);
    CHECK(v && v->dims[0] == 2 && ((float *)v->data)[0] == 1.5f, "a cvol file by its magic");
    cdvr_volume_free(v);
    write_file(tmp("short.cvol"), bytes, sizeof bytes - 1);
    CHECK(cdvr_volume_load(tmp("short.cvol"), NULL, &v, &err) == CDVR_ERR_FORMAT &&
              strstr(err.msg, "short.cvol") && strstr(err.msg, "announces 16 bytes"),
          "%s", err.msg);

    write_text(tmp("l.cvls"), "CVLS1\nv.cvol\nv_by_magic\n");
    const char *list = tmp("l.cvls");
    CHECK_OK(cdvr_volume_load_series(&list, 1, NULL, &v, &err), err);
    CHECK(v && v->timesteps == 4 && ((float *)v->data)[7] == 4, "a .cvls list as a series");
    cdvr_volume_free(v);
    CHECK(cdvr_volume_load(list, NULL, &v, &err) == CDVR_ERR_FORMAT &&
              strstr(err.msg, "open it as a series"), "%s", err.msg);
}

/* ---- directories (rule 0) and FILE:NAME paths (rule 1b) ------------------------------------
 * "tdir" reads a directory that holds a file "tdir.marker"; "tsub" reads "x.tsub:NAME". */

static int tdir_accepts(const char *path)
{
    char marker[600];
    snprintf(marker, sizeof marker, "%s/tdir.marker", path);
    return access(marker, F_OK) == 0;
}

static cdvr_status t1_probe(const char *path, const cdvr_raw_opts *o, cdvr_volume *h,
                            cdvr_error *err)
{
    (void)path, (void)o, (void)err;
    h->dims[0] = h->dims[1] = h->dims[2] = 1;
    h->timesteps = 1;
    h->type = CDVR_TYPE_U8;
    return CDVR_OK;
}

static void test_dirs_and_subpaths(void)
{
    static const char *const no_suffix[] = {NULL}, *const tsub_suffix[] = {".tsub", NULL};
    static const cdvr_format tdir = {.name = "tdir", .description = "test directories",
                                     .suffixes = no_suffix, .magic = never, .probe = t1_probe,
                                     .read = ok_read, .accepts_dir = tdir_accepts};
    static const cdvr_format tsub = {.name = "tsub", .description = "test FILE:NAME",
                                     .suffixes = tsub_suffix, .flags = CDVR_FORMAT_SUBPATH,
                                     .probe = t1_probe, .read = ok_read};
    cdvr_error err;
    CHECK_OK(cdvr_format_register(&tdir, &err), err);
    CHECK_OK(cdvr_format_register(&tsub, &err), err);
    const cdvr_format *f = NULL;
    CHECK(mkdir(tmp("plain_dir"), 0700) == 0 && mkdir(tmp("marked_dir"), 0700) == 0, "mkdir");
    write_text(tmp("marked_dir/tdir.marker"), "");
    CHECK(cdvr_format_for(tmp("plain_dir"), NULL, &f, &err) == CDVR_ERR_FORMAT && !f &&
              strstr(err.msg, "plain_dir: is a directory that no format reads") &&
              strstr(err.msg, "tdir"), "plain directory: %s", err.msg);
    CHECK(cdvr_format_for(tmp("marked_dir"), NULL, &f, &err) == CDVR_OK && f == &tdir,
          "directory read by tdir: %s", err.msg);
    cdvr_volume *v = NULL;
    CHECK_OK(cdvr_volume_load(tmp("marked_dir"), NULL, &v, &err), err);
    CHECK(v && v->dims[0] == 1, "directory loaded");
    cdvr_volume_free(v);

    write_text(tmp("x.tsub"), "");
    char path[700], file[700], name[700];
    snprintf(path, sizeof path, "%s:/group/data:set", tmp("x.tsub"));
    CHECK(cdvr_format_for(path, NULL, &f, &err) == CDVR_OK && f == &tsub, "subpath: %s", err.msg);
    CHECK(cdvr_format_split_subpath(&tsub, path, file, name, sizeof file) &&
              strcmp(file, tmp("x.tsub")) == 0 && strcmp(name, "/group/data:set") == 0,
          "split: %s | %s", file, name);
    CHECK(cdvr_format_split_subpath(&tsub, tmp("x.tsub"), file, name, sizeof file) &&
              strcmp(file, tmp("x.tsub")) == 0 && name[0] == '\0', "no name");
    CHECK(!cdvr_format_split_subpath(&tsub, path, file, name, 8), "too long for the buffers");
    snprintf(path, sizeof path, "%s:u", tmp("missing.tsub"));
    CHECK(cdvr_format_for(path, NULL, &f, &err) == CDVR_ERR_FORMAT && !f, "missing FILE: %s",
          err.msg);
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_registry();
    test_dispatch();
    test_read_and_expand();
    test_dirs_and_subpaths();
    test_plugin();
    char cmd[600];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return check_finish();
}
