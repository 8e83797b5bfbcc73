/* tests/test_cache.c - the on-disk cache (cdvr/cache.h): keys tell parts apart (terminators
 * hashed), the directory follows CDVR_CACHE_DIR, XDG_CACHE_HOME, HOME and is created; an
 * entry reads back byte for byte; a missing, foreign-key, truncated, checksum-broken or
 * trailing-byte entry reads as absent; without any directory nothing is cached. */
#include "check.h"

#include "cdvr/cache.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static char dir[] = "/tmp/cdvr_test_cache_XXXXXX";

static void test_keys(void)
{
    const char *a[] = {"ab", "c"}, *b[] = {"a", "bc"}, *c[] = {"ab", "c", ""};
    char ka[33], ka2[33], kb[33], kc[33];
    cdvr_cache_key(a, 2, ka);
    cdvr_cache_key(a, 2, ka2);
    cdvr_cache_key(b, 2, kb);
    cdvr_cache_key(c, 3, kc);
    CHECK(strlen(ka) == 32 && strspn(ka, "0123456789abcdef") == 32, "32 hex digits: %s", ka);
    CHECK(!strcmp(ka, ka2), "same parts, same key");
    CHECK(strcmp(ka, kb) && strcmp(ka, kc) && strcmp(kb, kc), "%s %s %s differ", ka, kb, kc);
}

static void test_directory(void)
{
    char path[512], want[512];
    setenv("CDVR_CACHE_DIR", "", 1);
    snprintf(want, sizeof want, "%s/xdg", dir);
    setenv("XDG_CACHE_HOME", want, 1);
    CHECK(cdvr_cache_path("k", "kind", path, sizeof path), "XDG directory");
    snprintf(want, sizeof want, "%s/xdg/cdvr/k.kind", dir);
    CHECK(!strcmp(path, want), "%s", path);
    struct stat sb;
    snprintf(want, sizeof want, "%s/xdg/cdvr", dir);
    CHECK(stat(want, &sb) == 0 && S_ISDIR(sb.st_mode), "created %s", want);
    unsetenv("XDG_CACHE_HOME");
    snprintf(want, sizeof want, "%s/home", dir);
    setenv("HOME", want, 1);
    CHECK(cdvr_cache_path("k", "kind", path, sizeof path), "HOME directory");
    snprintf(want, sizeof want, "%s/home/.cache/cdvr/k.kind", dir);
    CHECK(!strcmp(path, want), "%s", path);
    unsetenv("HOME");
    CHECK(!cdvr_cache_path("k", "kind", path, sizeof path), "no directory known");
    snprintf(want, sizeof want, "%s/file", dir);
    FILE *f = fopen(want, "w");
    if (f)
        fclose(f);
    snprintf(want, sizeof want, "%s/file/sub", dir);
    setenv("CDVR_CACHE_DIR", want, 1);
    CHECK(!cdvr_cache_path("k", "kind", path, sizeof path), "a directory under a file");
    CHECK(!cdvr_cache_path("k", "kind", path, 10), "a path longer than the buffer");
}

/* Rewrites the entry at path with byte `at` xor-ed (or cut to `at` bytes when cut). */
static void damage(const char *path, long at, int cut)
{
    FILE *f = fopen(path, "r+b");
    if (!f)
        return;
    if (cut) {
        CHECK(ftruncate(fileno(f), at) == 0, "truncate");
    } else {
        fseek(f, at, SEEK_SET);
        int c = fgetc(f);
        fseek(f, at, SEEK_SET);
        fputc(c ^ 0x40, f);
    }
    fclose(f);
}

static void test_entries(void)
{
    char path[512], key[33], other[33];
    const char *parts[] = {"entry"}, *other_parts[] = {"other"};
    cdvr_cache_key(parts, 1, key);
    cdvr_cache_key(other_parts, 1, other);
    setenv("CDVR_CACHE_DIR", dir, 1);
    CHECK(cdvr_cache_path(key, "t", path, sizeof path), "path");
    size_t size = 99;
    CHECK(!cdvr_cache_load(path, key, &size) && size == 0, "missing entry");
    const unsigned char content[] = "lzo 600.0 lz4 3800.0 zstd 1700.0";
    cdvr_cache_store(path, key, content, sizeof content);
    unsigned char *got = cdvr_cache_load(path, key, &size);
    CHECK(got && size == sizeof content && !memcmp(got, content, size), "round trip");
    free(got);
    CHECK(!cdvr_cache_load(path, other, &size), "another key");
    long header = 8 + 32 + 8 + 8;
    damage(path, header + 3, 0);
    CHECK(!cdvr_cache_load(path, key, &size), "a changed byte fails the checksum");
    cdvr_cache_store(path, key, content, sizeof content);
    damage(path, header + 5, 1);
    CHECK(!cdvr_cache_load(path, key, &size), "truncated");
    cdvr_cache_store(path, key, content, sizeof content);
    FILE *f = fopen(path, "ab");
    if (f) {
        fputc('x', f);
        fclose(f);
    }
    CHECK(!cdvr_cache_load(path, key, &size), "a trailing byte");
    cdvr_cache_store(path, key, content, sizeof content);
    damage(path, 0, 0);
    CHECK(!cdvr_cache_load(path, key, &size), "wrong magic");
    cdvr_cache_store(path, key, content, sizeof content);
    got = cdvr_cache_load(path, key, &size);
    CHECK(got && size == sizeof content, "a store replaces a damaged entry");
    free(got);
    cdvr_cache_store("/nonexistent-dir/x.t", key, content, sizeof content); /* no crash */
}

int main(void)
{
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    test_keys();
    test_directory();
    test_entries();
    char cmd[128];
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
    if (system(cmd) != 0)
        fprintf(stderr, "could not remove %s\n", dir);
    return check_finish();
}
