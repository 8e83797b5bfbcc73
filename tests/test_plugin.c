/* tests/test_plugin.c - the plugin loader (core/codec/plugin/plugin.c, cdvr/plugin.h): the
 * example and zfp plugins load and register; every broken plugin of tests/plugins/ is refused
 * with a message naming the file and the reason (wrong ABI, no entry symbol, NULL info or
 * codec, name or id clash, missing decode, unresolvable symbol), and so are a text file, a
 * directory, a missing file and a second copy of a loaded plugin; nothing refused stays
 * registered; a plugin built for ABI 2 still loads (its table, which ends before `check`, as
 * a copy with check NULL); one refused after its first table keeps
 * that table and is refused again on every load; cdvr_plugin_load_dirs loads what it can and
 * reports each failure once. (Format plugins: tests/test_format.c.) */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cdvr/codec.h"
#include "cdvr/plugin.h"
#include "check.h"

static char bin_dir[2048] = ".";

static void path_in_build(char *out, size_t n, const char *rel)
{
    snprintf(out, n, "%s/%s", bin_dir, rel);
}

static int built(const char *plugin)
{
    const char *list = getenv("CDVR_BUILT_PLUGINS");
    if (!list)
        return 0;
    size_t n = strlen(plugin);
    for (const char *p = strstr(list, plugin); p; p = strstr(p + 1, plugin))
        if ((p == list || p[-1] == ' ') && (p[n] == '\0' || p[n] == ' '))
            return 1;
    return 0;
}

static int copy_file(const char *from, const char *to)
{
    FILE *in = fopen(from, "rb"), *out = fopen(to, "wb");
    int ok = in && out;
    char buf[65536];
    size_t n;
    while (ok && (n = fread(buf, 1, sizeof buf, in)) > 0)
        ok = fwrite(buf, 1, n, out) == n;
    if (in)
        fclose(in);
    if (out && fclose(out) != 0)
        ok = 0;
    return ok;
}

static int write_text(const char *path, const char *text)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return 0;
    fputs(text, f);
    return fclose(f) == 0;
}

/* Loading path fails with status and a message that names path and holds each of the
 * NULL-terminated substrings. */
static void expect_refusal(const char *path, cdvr_status status, const char *const *want)
{
    static const cdvr_codec sentinel;
    size_t before = cdvr_codec_count();
    const cdvr_codec *codec = &sentinel; /* must be reset to NULL */
    cdvr_error err;
    cdvr_error_clear(&err);
    cdvr_status s = cdvr_plugin_load(path, &codec, &err);
    CHECK(s == status, "%s: status %d (want %d): %s", path, (int)s, (int)status, err.msg);
    CHECK(codec == NULL, "%s: codec set on failure", path);
    CHECK(strstr(err.msg, path) != NULL, "message does not name the file: %s", err.msg);
    for (; *want; want++)
        CHECK(strstr(err.msg, *want) != NULL, "message lacks '%s': %s", *want, err.msg);
    CHECK(cdvr_codec_count() == before, "%s: registry grew on a refusal", path);
}

static void test_bad_plugins(void)
{
    static const struct {
        const char *file;
        cdvr_status status;
        const char *want[3];
    } cases[] = {
        {"bad_abi.so", CDVR_ERR_FORMAT, {"ABI version 42", "version 2", NULL}},
        {"bad_nosym.so", CDVR_ERR_FORMAT, {"not a cdvr plugin", "no cdvr_plugin_v1 symbol", NULL}},
        {"bad_null_info.so", CDVR_ERR_FORMAT, {"cdvr_plugin_v1 returned NULL", NULL}},
        {"bad_null_codec.so", CDVR_ERR_FORMAT, {"returned no codec", NULL}},
        {"bad_clash_name.so", CDVR_ERR_ARG, {"codec 'pvtc' is already registered", NULL}},
        {"bad_clash_id.so", CDVR_ERR_ARG, {"id 1 is already taken by codec 'pvtc'", NULL}},
        {"bad_no_decode.so", CDVR_ERR_ARG, {"codec 'bad': the table has no decode", NULL}},
        {"bad_undefined.so", CDVR_ERR_FORMAT,
         {"cannot load plugin", "cdvr_test_symbol_nobody_defines", NULL}},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char path[4096], rel[256];
        snprintf(rel, sizeof rel, "tests/plugins/%s", cases[i].file);
        path_in_build(path, sizeof path, rel);
        expect_refusal(path, cases[i].status, cases[i].want);
        expect_refusal(path, cases[i].status, cases[i].want); /* and again: same answer */
    }
    CHECK(cdvr_codec_find("bad") == NULL, "a refused codec is registered");
}

static void test_not_plugins(const char *tmp)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/text.so", tmp);
    CHECK(write_text(path, "this is not a shared object\n"), "%s", path);
    expect_refusal(path, CDVR_ERR_FORMAT, (const char *const[]){"cannot load plugin", NULL});
    snprintf(path, sizeof path, "%s/empty.so", tmp);
    CHECK(write_text(path, ""), "%s", path);
    expect_refusal(path, CDVR_ERR_FORMAT, (const char *const[]){"cannot load plugin", NULL});
    expect_refusal(tmp, CDVR_ERR_IO, (const char *const[]){"not a regular file", NULL});
    snprintf(path, sizeof path, "%s/missing.so", tmp);
    expect_refusal(path, CDVR_ERR_IO, (const char *const[]){"No such file", NULL});
    cdvr_error err;
    CHECK(cdvr_plugin_load("", NULL, &err) == CDVR_ERR_ARG && strstr(err.msg, "empty path"),
          "%s", err.msg);
    CHECK(cdvr_plugin_load(NULL, NULL, &err) == CDVR_ERR_ARG, "%s", err.msg);
}

static const cdvr_codec *load_good(const char *rel, const char *name)
{
    char path[4096];
    path_in_build(path, sizeof path, rel);
    const cdvr_codec *codec = NULL, *again = NULL;
    cdvr_error err;
    CHECK_OK(cdvr_plugin_load(path, &codec, &err), err);
    CHECK(codec && strcmp(codec->name, name) == 0, "%s: codec %s", path,
          codec ? codec->name : "(none)");
    CHECK(codec && cdvr_codec_find(name) == codec, "%s not registered", name);
    CHECK(codec && cdvr_codec_by_id(codec->id) == codec, "%s: lookup by id", name);
    const char *file = cdvr_plugin_file(codec);
    CHECK(file && strcmp(file, path) == 0, "plugin file %s", file ? file : "(none)");
    size_t count = cdvr_codec_count();
    CHECK_OK(cdvr_plugin_load(path, &again, &err), err); /* the same file twice: no-op */
    CHECK(again == codec && cdvr_codec_count() == count, "second load of %s", path);
    return codec;
}

/* A second copy of a loaded plugin clashes by name; the message names both files. */
static void test_copy_clash(const char *tmp)
{
    char from[4096], copy[4096];
    path_in_build(from, sizeof from, "plugins/cdvr_example.so");
    snprintf(copy, sizeof copy, "%s/copy_of_example.so", tmp);
    CHECK(copy_file(from, copy), "copy %s", copy);
    expect_refusal(copy, CDVR_ERR_ARG,
                   (const char *const[]){"codec 'rle' is already registered", from, NULL});
}

typedef struct reports {
    int count;
    char text[4][CDVR_ERRMSG_MAX];
} reports;

static void collect(void *ud, const char *message)
{
    reports *r = ud;
    if (r->count < 4)
        snprintf(r->text[r->count], sizeof r->text[0], "%s", message);
    r->count++;
}

static void test_load_dirs(const char *tmp)
{
    char dir[2048], path[4096], from[4096];
    snprintf(dir, sizeof dir, "%s/dir", tmp);
    CHECK(mkdir(dir, 0700) == 0, "mkdir %s: %s", dir, strerror(errno));
    snprintf(path, sizeof path, "%s/a_junk.so", dir);
    CHECK(write_text(path, "junk"), "%s", path);
    path_in_build(from, sizeof from, "tests/plugins/bad_abi.so");
    snprintf(path, sizeof path, "%s/b_abi.so", dir);
    CHECK(copy_file(from, path), "%s", path);
    snprintf(path, sizeof path, "%s/c_notes.txt", dir);
    CHECK(write_text(path, "not a plugin name"), "%s", path);

    char list[8192];
    snprintf(list, sizeof list, "%s::%s/nowhere", dir, tmp);
    reports r = {0};
    size_t before = cdvr_codec_count();
    CHECK(cdvr_plugin_load_dirs(list, collect, &r) == 0, "loaded from %s", list);
    CHECK(r.count == 3, "%d reports", r.count);
    CHECK(strstr(r.text[0], "a_junk.so") && strstr(r.text[1], "b_abi.so") &&
              strstr(r.text[1], "ABI version") && strstr(r.text[2], "nowhere"),
          "reports: [%s] [%s] [%s]", r.text[0], r.text[1], r.text[2]);
    CHECK(cdvr_codec_count() == before, "registry changed");

    if (!built("example") && !built("zfp"))
        return;
    char plugins[4096];
    path_in_build(plugins, sizeof plugins, "plugins");
    reports none = {0};
    size_t want = 0; /* every plugin the build made (CDVR_BUILT_PLUGINS: names, space-separated) */
    for (const char *p = getenv("CDVR_BUILT_PLUGINS"); p && *(p += strspn(p, " "));
         p += strcspn(p, " "))
        want++;
    CHECK(cdvr_plugin_load_dirs(plugins, collect, &none) == want && none.count == 0,
          "build plugins: %d reports: %s", none.count, none.text[0]);
    CHECK(cdvr_plugin_load_dirs(NULL, collect, &none) == 0, "NULL list");
}

int main(void)
{
    const char *env = getenv("CDVR_BINARY_DIR");
    if (env && *env)
        snprintf(bin_dir, sizeof bin_dir, "%s", env);
    char tmp[] = "/tmp/cdvr_test_plugin_XXXXXX";
    if (!mkdtemp(tmp)) {
        perror("mkdtemp");
        return 1;
    }
    CHECK(cdvr_plugin_file(cdvr_codec_find("raw")) == NULL, "raw has a plugin file");
    printf("plugins built: %s\n", getenv("CDVR_BUILT_PLUGINS") ? getenv("CDVR_BUILT_PLUGINS")
                                                                : "(unset: none)");
    test_bad_plugins();
    test_not_plugins(tmp);
    size_t builtins = cdvr_codec_count();
    if (built("example")) { /* not with -DCDVR_WITH_PLUGINS=OFF */
        const cdvr_codec *rle = load_good("plugins/cdvr_example.so", "rle");
        CHECK(rle && rle->cl_mode == CDVR_CODEC_CL_NONE, "rle table");
    }
    if (built("zfp")) {
        const cdvr_codec *zfp = load_good("plugins/cdvr_zfp.so", "zfp");
        CHECK(zfp && zfp->id == 0x7A667000u, "zfp id");
    }
    /* a plugin built against ABI 2 (its info has two fields) still loads */
    const cdvr_codec *abi2 = load_good("tests/plugins_more/abi2.so", "abi2");
    CHECK(abi2 && abi2->id == 0x41424932u, "abi2 id");
    /* its table ends before `check` (ABI 4): a copy is registered, with check NULL */
    CHECK(abi2 && abi2->check == NULL && abi2->decode_cells == NULL && abi2->decode,
          "ABI-2 table: check %p, decode_cells %p", abi2 ? (void *)abi2->check : NULL,
          abi2 ? (void *)abi2->decode_cells : NULL);
    /* a plugin refused after its first table: that one stays, and every load is refused */
    char partial[4096];
    path_in_build(partial, sizeof partial, "tests/plugins_more/partial.so");
    for (int i = 0; i < 2; i++) {
        cdvr_error err;
        const cdvr_codec *got = NULL;
        CHECK(cdvr_plugin_load(partial, &got, &err) == CDVR_ERR_ARG && !got &&
                  strstr(err.msg, partial) &&
                  strstr(err.msg, "format 'partial': suffix .nrrd is already taken by format "
                                  "'nrrd'"),
              "partial plugin, load %d: %s", i + 1, err.msg);
    }
    CHECK(cdvr_codec_find("partial") != NULL, "the partial plugin's codec stays registered");
    CHECK(cdvr_codec_count() == builtins + 2 + (size_t)built("example") + (size_t)built("zfp"),
          "%zu codecs", cdvr_codec_count());
    if (built("example"))
        test_copy_clash(tmp);
    test_load_dirs(tmp);

    char cmd[4200];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", tmp);
    return check_finish();
}
