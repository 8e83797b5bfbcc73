/* core/base/cache.c - the on-disk cache of per-machine measurements and builds (cdvr/cache.h). */
#include "cdvr/cache.h"

#include <errno.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define CACHE_MAGIC "CDVRCLB1" /* the name from when only OpenCL binaries were cached */
#define FNV_SEED 14695981039346656037ULL

static uint64_t fnv1a(uint64_t h, const void *data, size_t n)
{
    const unsigned char *p = data;
    for (size_t i = 0; i < n; i++) {
        h ^= p[i];
        h *= 1099511628211ULL;
    }
    return h;
}

void cdvr_cache_key(const char *const *parts, size_t n, char key[33])
{
    uint64_t h1 = FNV_SEED, h2 = 0x9e3779b97f4a7c15ULL;
    for (size_t i = 0; i < n; i++) {
        const char *part = parts[i] ? parts[i] : "";
        h1 = fnv1a(h1, part, strlen(part) + 1);
        h2 = fnv1a(h2 ^ (uint64_t)(i + 1), part, strlen(part) + 1);
    }
    snprintf(key, 33, "%016llx%016llx", (unsigned long long)h1, (unsigned long long)h2);
}

static int mkdir_p(const char *dir)
{
    char path[512];
    if (snprintf(path, sizeof path, "%s", dir) >= (int)sizeof path)
        return -1;
    for (char *p = path + 1; *p; p++) {
        if (*p != '/')
            continue;
        *p = '\0';
        if (mkdir(path, 0755) && errno != EEXIST)
            return -1;
        *p = '/';
    }
    return (mkdir(path, 0755) && errno != EEXIST) ? -1 : 0;
}

int cdvr_cache_path(const char *key, const char *kind, char *path, size_t n)
{
    const char *env = getenv("CDVR_CACHE_DIR");
    const char *xdg = getenv("XDG_CACHE_HOME");
    const char *home = getenv("HOME");
    char dir[400];
    int len;
    if (env && *env)
        len = snprintf(dir, sizeof dir, "%s", env);
    else if (xdg && *xdg)
        len = snprintf(dir, sizeof dir, "%s/cdvr", xdg);
    else if (home && *home)
        len = snprintf(dir, sizeof dir, "%s/.cache/cdvr", home);
    else
        return 0;
    if (len < 0 || len >= (int)sizeof dir || mkdir_p(dir) != 0)
        return 0;
    len = snprintf(path, n, "%s/%s.%s", dir, key, kind);
    return len > 0 && (size_t)len < n;
}

unsigned char *cdvr_cache_load(const char *path, const char *key, size_t *size)
{
    FILE *f = fopen(path, "rb");
    *size = 0;
    if (!f)
        return NULL;
    char magic[8], stored_key[32];
    uint64_t len = 0, sum = 0;
    unsigned char *content = NULL;
    if (fread(magic, 1, 8, f) == 8 && !memcmp(magic, CACHE_MAGIC, 8) &&
        fread(stored_key, 1, 32, f) == 32 && !memcmp(stored_key, key, 32) &&
        fread(&len, sizeof len, 1, f) == 1 && fread(&sum, sizeof sum, 1, f) == 1 && len > 0 &&
        len < ((uint64_t)1 << 31) && (content = malloc((size_t)len)) != NULL) {
        if (fread(content, 1, (size_t)len, f) != len || fgetc(f) != EOF ||
            fnv1a(FNV_SEED, content, (size_t)len) != sum) {
            free(content);
            content = NULL;
        }
    }
    fclose(f);
    if (content)
        *size = (size_t)len;
    return content;
}

void cdvr_cache_store(const char *path, const char *key, const unsigned char *content,
                      size_t size)
{
    char tmp[640]; /* its own name per process and thread: writers never share a file */
    if (snprintf(tmp, sizeof tmp, "%s.%ld.%lx.tmp", path, (long)getpid(),
                 (unsigned long)pthread_self()) >= (int)sizeof tmp)
        return;
    FILE *f = fopen(tmp, "wb");
    if (!f)
        return;
    uint64_t len = size, sum = fnv1a(FNV_SEED, content, size);
    int ok = fwrite(CACHE_MAGIC, 1, 8, f) == 8 && fwrite(key, 1, 32, f) == 32 &&
             fwrite(&len, sizeof len, 1, f) == 1 && fwrite(&sum, sizeof sum, 1, f) == 1 &&
             fwrite(content, 1, size, f) == size;
    ok = (fclose(f) == 0) && ok;
    if (!ok || rename(tmp, path))
        remove(tmp);
}
