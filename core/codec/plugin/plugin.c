/* core/codec/plugin/plugin.c - loading codec plugins (cdvr/plugin.h) with dlopen. */
#include "cdvr/plugin.h"

#include <dirent.h>
#include <dlfcn.h>
#include <errno.h>
#include <pthread.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* The plugins loaded so far (the loader context): which file each registered codec came from,
 * for clash messages and cdvr_plugin_file. The mutex also makes each load atomic, so that
 * two threads loading the same file do not both register it. Never freed: plugins stay. */
typedef struct loaded_plugin {
    const cdvr_codec *codec;  /* as registered */
    const cdvr_codec *own;    /* as the plugin returned it (differs for ABI 2: full_table) */
    char *path;
} loaded_plugin;

static struct {
    pthread_mutex_t mu;
    loaded_plugin *items;
    size_t count, cap;
} loader = {PTHREAD_MUTEX_INITIALIZER, NULL, 0, 0};

/* Caller holds loader.mu. */
static const char *file_of_locked(const cdvr_codec *codec)
{
    for (size_t i = 0; codec && i < loader.count; i++)
        if (loader.items[i].codec == codec)
            return loader.items[i].path;
    return NULL;
}

/* The registered table of a plugin table already loaded, or NULL. Caller holds loader.mu. */
static const cdvr_codec *registered_locked(const cdvr_codec *own)
{
    for (size_t i = 0; own && i < loader.count; i++)
        if (loader.items[i].own == own)
            return loader.items[i].codec;
    return NULL;
}

/* Caller holds loader.mu. 0 when out of memory (the codec stays registered, unnamed). */
static int remember_locked(const cdvr_codec *codec, const cdvr_codec *own, const char *path)
{
    if (loader.count == loader.cap) {
        size_t cap = loader.cap ? 2 * loader.cap : 8;
        loaded_plugin *items = realloc(loader.items, cap * sizeof *items);
        if (!items)
            return 0;
        loader.items = items;
        loader.cap = cap;
    }
    char *copy = strdup(path);
    if (!copy)
        return 0;
    loader.items[loader.count++] = (loaded_plugin){codec, own, copy};
    return 1;
}

const char *cdvr_plugin_file(const cdvr_codec *codec)
{
    pthread_mutex_lock(&loader.mu);
    const char *path = file_of_locked(codec);
    pthread_mutex_unlock(&loader.mu);
    return path;
}

/* Checks what cdvr_plugin_v1 returned, before anything reads the codec table. */
static cdvr_status check_info(const char *path, const cdvr_plugin_info *info, cdvr_error *err)
{
    if (!info)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s returned NULL", path,
                              CDVR_PLUGIN_SYMBOL);
    if (info->abi < CDVR_PLUGIN_ABI_OLDEST || info->abi > CDVR_PLUGIN_ABI)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: plugin built for ABI version %u, this "
                              "cdvr has version %u and loads version %u too (rebuild the plugin "
                              "against this cdvr's cdvr/plugin.h)", path, info->abi,
                              CDVR_PLUGIN_ABI, CDVR_PLUGIN_ABI_OLDEST);
    if (!info->codec)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s returned no codec", path,
                              CDVR_PLUGIN_SYMBOL);
    return CDVR_OK;
}

/* Registers codec; on a refusal the message names the file and, for a clash with a plugin
 * codec, the file that one came from. Caller holds loader.mu. */
static cdvr_status register_locked(const char *path, const cdvr_codec *codec, cdvr_error *err)
{
    cdvr_error rerr;
    cdvr_status s = cdvr_codec_register(codec, &rerr);
    if (s == CDVR_OK)
        return CDVR_OK;
    const cdvr_codec *other = NULL;
    if (strstr(rerr.msg, "already")) { /* a name or id clash, not a bad table */
        other = codec->name ? cdvr_codec_find(codec->name) : NULL;
        if (!other)
            other = cdvr_codec_by_id(codec->id);
    }
    const char *other_file = file_of_locked(other);
    if (other_file)
        return cdvr_error_set(err, s, "%s: %s (codec '%s' was loaded from %s)", path, rerr.msg,
                              other->name, other_file);
    return cdvr_error_set(err, s, "%s: %s", path, rerr.msg);
}

/* The table to register: the plugin's own, or for an ABI-2 plugin (whose table ends before
 * `check`) a copy of it with check NULL, never freed. NULL when out of memory. */
static const cdvr_codec *full_table(const cdvr_plugin_info *info)
{
    if (info->abi == CDVR_PLUGIN_ABI)
        return info->codec;
    cdvr_codec *copy = calloc(1, sizeof *copy);
    if (copy)
        memcpy(copy, info->codec, offsetof(cdvr_codec, check));
    return copy;
}

/* dlopen + dlsym + checks + registration; caller holds loader.mu. */
static cdvr_status load_locked(const char *path, const cdvr_codec **out, cdvr_error *err)
{
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        const char *why = dlerror();
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: cannot load plugin: %s", path,
                              why ? why : "unknown reason");
    }
    void *sym = dlsym(h, CDVR_PLUGIN_SYMBOL);
    if (!sym) {
        dlclose(h);
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not a cdvr plugin (no %s symbol)", path,
                              CDVR_PLUGIN_SYMBOL);
    }
    cdvr_plugin_entry_fn entry;
    memcpy(&entry, &sym, sizeof entry); /* object -> function pointer (POSIX guarantees it) */
    const cdvr_plugin_info *info = entry();
    cdvr_status s = check_info(path, info, err);
    if (s == CDVR_OK && registered_locked(info->codec)) {
        *out = registered_locked(info->codec); /* the same file loaded again: dlopen gave the
                                                  same handle */
        dlclose(h);         /* drops the reference this call added; the first one stays */
        return CDVR_OK;
    }
    const cdvr_codec *table = s == CDVR_OK ? full_table(info) : NULL;
    if (s == CDVR_OK && !table)
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    if (s == CDVR_OK)
        s = register_locked(path, table, err);
    if (s != CDVR_OK) {
        if (table && table != info->codec)
            free((void *)table);
        dlclose(h);
        return s;
    }
    (void)remember_locked(table, info->codec, path);
    *out = table;
    return CDVR_OK; /* never dlclose'd: the registry keeps the table */
}

cdvr_status cdvr_plugin_load(const char *path, const cdvr_codec **out, cdvr_error *err)
{
    const cdvr_codec *codec = NULL;
    if (out)
        *out = NULL;
    if (!path || !*path)
        return cdvr_error_set(err, CDVR_ERR_ARG, "plugin: empty path");
    struct stat sb;
    if (stat(path, &sb) != 0)
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot load plugin: %s", path,
                              strerror(errno));
    if (!S_ISREG(sb.st_mode))
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: cannot load plugin: not a regular file",
                              path);
    /* A path without '/' would make dlopen search the library path instead of this file. */
    char local[4096];
    if (!strchr(path, '/')) {
        if (snprintf(local, sizeof local, "./%s", path) >= (int)sizeof local)
            return cdvr_error_set(err, CDVR_ERR_ARG, "plugin: path too long");
        path = local;
    }
    pthread_mutex_lock(&loader.mu);
    cdvr_status s = load_locked(path, &codec, err);
    pthread_mutex_unlock(&loader.mu);
    if (s == CDVR_OK && out)
        *out = codec;
    return s;
}

static int compare_names(const void *a, const void *b)
{
    return strcmp(*(char *const *)a, *(char *const *)b);
}

static size_t load_dir(const char *dir, void (*report)(void *, const char *), void *ud)
{
    DIR *d = opendir(dir);
    if (!d) {
        if (report) {
            char msg[CDVR_ERRMSG_MAX];
            snprintf(msg, sizeof msg, "%s: cannot read plugin directory", dir);
            report(ud, msg);
        }
        return 0;
    }
    char **names = NULL;
    size_t n = 0, cap = 0, loaded = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        size_t len = strlen(e->d_name);
        if (len < 4 || strcmp(e->d_name + len - 3, ".so") != 0)
            continue;
        if (n == cap) {
            size_t ncap = cap ? 2 * cap : 16;
            char **nn = realloc(names, ncap * sizeof *nn);
            if (!nn)
                break;
            names = nn;
            cap = ncap;
        }
        if ((names[n] = strdup(e->d_name)) != NULL)
            n++;
    }
    closedir(d);
    if (n)
        qsort(names, n, sizeof *names, compare_names);
    for (size_t i = 0; i < n; i++) {
        char path[4096];
        cdvr_error err;
        cdvr_error_set(&err, CDVR_ERR_ARG, "%s/%s: path too long", dir, names[i]);
        if (snprintf(path, sizeof path, "%s/%s", dir, names[i]) < (int)sizeof path &&
            cdvr_plugin_load(path, NULL, &err) == CDVR_OK)
            loaded++;
        else if (report)
            report(ud, err.msg);
        free(names[i]);
    }
    free(names);
    return loaded;
}

size_t cdvr_plugin_load_dirs(const char *dirs, void (*report)(void *, const char *), void *ud)
{
    if (!dirs)
        return 0;
    char *copy = strdup(dirs);
    if (!copy)
        return 0;
    size_t loaded = 0;
    char *save = NULL;
    for (char *dir = strtok_r(copy, ":", &save); dir; dir = strtok_r(NULL, ":", &save))
        if (*dir)
            loaded += load_dir(dir, report, ud);
    free(copy);
    return loaded;
}
