/* core/codec/plugin/plugin.c - loading codec plugins (cdvr/plugin.h) with dlopen. */
#include "cdvr/plugin.h"

#include <dirent.h>
#include <dlfcn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

cdvr_status cdvr_plugin_load(const char *path, const cdvr_codec **out, cdvr_error *err)
{
    if (out)
        *out = NULL;
    if (!path || !*path)
        return cdvr_error_set(err, CDVR_ERR_ARG, "plugin: empty path");
    struct stat sb;
    if (stat(path, &sb) != 0 || !S_ISREG(sb.st_mode))
        return cdvr_error_set(err, CDVR_ERR_IO, "%s: plugin is not a readable regular file",
                              path);
    /* A path without '/' would make dlopen search the library path instead of this file. */
    char local[4096];
    if (!strchr(path, '/') && snprintf(local, sizeof local, "./%s", path) < (int)sizeof local)
        path = local;
    void *h = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!h) {
        const char *why = dlerror();
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: cannot load plugin: %s", path,
                              why ? why : "unknown reason");
    }
    cdvr_plugin_entry_fn entry;
    void *sym = dlsym(h, CDVR_PLUGIN_SYMBOL);
    memcpy(&entry, &sym, sizeof entry); /* object -> function pointer (POSIX guarantees it) */
    if (!sym) {
        dlclose(h);
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: not a cdvr plugin (no %s symbol)", path,
                              CDVR_PLUGIN_SYMBOL);
    }
    const cdvr_plugin_info *info = entry();
    cdvr_status s = CDVR_OK;
    if (!info || !info->codec)
        s = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s returned no codec", path,
                           CDVR_PLUGIN_SYMBOL);
    else if (info->abi != CDVR_PLUGIN_ABI)
        s = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: plugin built for ABI version %u, this cdvr "
                           "has version %u (rebuild the plugin against this cdvr's "
                           "cdvr/plugin.h)", path, info->abi, CDVR_PLUGIN_ABI);
    if (s == CDVR_OK) {
        const cdvr_codec *known = cdvr_codec_find(info->codec->name);
        if (known == info->codec) { /* the same file loaded again */
            if (out)
                *out = known;
            return CDVR_OK; /* keep the handle: dlopen counts references */
        }
        cdvr_error rerr;
        s = cdvr_codec_register(info->codec, &rerr);
        if (s != CDVR_OK)
            cdvr_error_set(err, s, "%s: %s", path, rerr.msg);
    }
    if (s != CDVR_OK) {
        dlclose(h);
        return s;
    }
    if (out)
        *out = info->codec;
    return CDVR_OK; /* never dlclose'd: the registry keeps the table */
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
