/* core/codec/plugin/plugin.c - loading codec and format plugins (cdvr/plugin.h) with dlopen. */
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

/* The plugins loaded so far (the loader context): the file each came from and what it provides
 * (as an ABI 3 info: the raw info, entry point and the copy below), for clash messages,
 * cdvr_plugin_file and loading a file twice. The mutex also makes each load atomic, so that two
 * threads loading the same file do not both register it. Never freed: plugins stay. */
typedef struct loaded_plugin {
    const cdvr_plugin_info *raw;  /* what cdvr_plugin_v1 returned */
    cdvr_plugin_info info;        /* normalised to ABI 3 */
    char *path;
    cdvr_error refusal;           /* status CDVR_OK, or why a table of it was refused (the
                                     ones before it stay registered): every load says so */
} loaded_plugin;

static struct {
    pthread_mutex_t mu;
    loaded_plugin **items;       /* each allocated alone: the infos handed out stay put */
    size_t count, cap;
} loader = {PTHREAD_MUTEX_INITIALIZER, NULL, 0, 0};

/* The codecs of an info: codec, then codecs[]; i from 0, NULL past the end. */
static const cdvr_codec *codec_at(const cdvr_plugin_info *info, size_t i)
{
    if (info->codec && i-- == 0)
        return info->codec;
    for (size_t k = 0; info->codecs && info->codecs[k]; k++)
        if (k == i)
            return info->codecs[k];
    return NULL;
}

static const cdvr_format *format_at(const cdvr_plugin_info *info, size_t i)
{
    for (size_t k = 0; info->formats && info->formats[k]; k++)
        if (k == i)
            return info->formats[k];
    return NULL;
}

/* Caller holds loader.mu. */
static const char *file_of_locked(const cdvr_codec *codec, const cdvr_format *format)
{
    for (size_t i = 0; (codec || format) && i < loader.count; i++) {
        const cdvr_plugin_info *info = &loader.items[i]->info;
        for (size_t k = 0; codec && codec_at(info, k); k++)
            if (codec_at(info, k) == codec)
                return loader.items[i]->path;
        for (size_t k = 0; format && format_at(info, k); k++)
            if (format_at(info, k) == format)
                return loader.items[i]->path;
    }
    return NULL;
}

/* Caller holds loader.mu. */
static const loaded_plugin *loaded_locked(const cdvr_plugin_info *raw)
{
    for (size_t i = 0; i < loader.count; i++)
        if (loader.items[i]->raw == raw)
            return loader.items[i];
    return NULL;
}

/* Caller holds loader.mu. NULL when out of memory (the tables stay registered, unnamed). */
static loaded_plugin *remember_locked(const cdvr_plugin_info *raw,
                                            const cdvr_plugin_info *info, const char *path)
{
    if (loader.count == loader.cap) {
        size_t cap = loader.cap ? 2 * loader.cap : 8;
        loaded_plugin **items = realloc(loader.items, cap * sizeof *items);
        if (!items)
            return NULL;
        loader.items = items;
        loader.cap = cap;
    }
    loaded_plugin *lp = malloc(sizeof *lp);
    char *copy = strdup(path);
    if (!lp || !copy) {
        free(lp);
        free(copy);
        return NULL;
    }
    *lp = (loaded_plugin){raw, *info, copy, {CDVR_OK, ""}};
    loader.items[loader.count++] = lp;
    return lp;
}

const char *cdvr_plugin_file(const cdvr_codec *codec)
{
    pthread_mutex_lock(&loader.mu);
    const char *path = file_of_locked(codec, NULL);
    pthread_mutex_unlock(&loader.mu);
    return path;
}

const char *cdvr_plugin_format_file(const cdvr_format *format)
{
    pthread_mutex_lock(&loader.mu);
    const char *path = file_of_locked(NULL, format);
    pthread_mutex_unlock(&loader.mu);
    return path;
}

/* Checks what cdvr_plugin_v1 returned, before anything reads a table, and copies it into *out
 * as an ABI 3 info (an ABI 2 info has only abi and codec: nothing past them is read). */
static cdvr_status check_info(const char *path, const cdvr_plugin_info *info,
                              cdvr_plugin_info *out, cdvr_error *err)
{
    if (!info)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: %s returned NULL", path,
                              CDVR_PLUGIN_SYMBOL);
    if (info->abi < CDVR_PLUGIN_ABI_MIN || info->abi > CDVR_PLUGIN_ABI)
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: plugin built for ABI version %u, this "
                              "cdvr loads version %u to %u (rebuild the plugin against this "
                              "cdvr's cdvr/plugin.h)", path, info->abi, CDVR_PLUGIN_ABI_MIN,
                              CDVR_PLUGIN_ABI);
    memset(out, 0, sizeof *out);
    out->abi = info->abi;
    out->codec = info->codec;
    if (info->abi >= 3) {
        out->codecs = info->codecs;
        out->formats = info->formats;
    }
    if (!codec_at(out, 0) && !format_at(out, 0))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, info->abi >= 3 ? "%s: %s returned no codec "
                              "and no format" : "%s: %s returned no codec", path,
                              CDVR_PLUGIN_SYMBOL);
    return CDVR_OK;
}

/* A plugin built before ABI 6 has codec tables that end before `decode_cells` (before ABI 4,
 * before `check`): out's codecs become full-size copies with those NULL, so that nothing reads
 * past the plugin's tables. The copies are never freed (registered tables stay).
 * CDVR_ERR_NOMEM naming the file. */
static cdvr_status widen_codecs(const char *path, cdvr_plugin_info *out, cdvr_error *err)
{
    if (out->abi >= 6)
        return CDVR_OK;
    size_t table_bytes = out->abi >= 4 ? offsetof(cdvr_codec, decode_cells)
                                       : offsetof(cdvr_codec, check);
    size_t n = 0;
    while (codec_at(out, n))
        n++;
    cdvr_codec *copies = n ? calloc(n, sizeof *copies) : NULL;
    const cdvr_codec **list = n ? calloc(n + 1, sizeof *list) : NULL;
    if (n && (!copies || !list)) {
        free(copies);
        free(list);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    for (size_t k = 0; k < n; k++) {
        memcpy(&copies[k], codec_at(out, k), table_bytes);
        list[k] = &copies[k];
    }
    out->codec = NULL;
    out->codecs = list;
    return CDVR_OK;
}

/* The same for formats: a plugin built before ABI 5 has format tables that end before
 * `accepts_dir`, so out's formats become full-size copies with accepts_dir and expand_opts
 * NULL. */
static cdvr_status widen_formats(const char *path, cdvr_plugin_info *out, cdvr_error *err)
{
    if (out->abi >= 5)
        return CDVR_OK;
    size_t n = 0;
    while (format_at(out, n))
        n++;
    if (!n)
        return CDVR_OK;
    cdvr_format *copies = calloc(n, sizeof *copies);
    const cdvr_format **list = calloc(n + 1, sizeof *list);
    if (!copies || !list) {
        free(copies);
        free(list);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    }
    for (size_t k = 0; k < n; k++) {
        memcpy(&copies[k], format_at(out, k), offsetof(cdvr_format, accepts_dir));
        list[k] = &copies[k];
    }
    out->formats = list;
    return CDVR_OK;
}

/* Registers codec; on a refusal the message names the file and, for a clash with a plugin
 * codec, the file that one came from. Caller holds loader.mu. */
static cdvr_status register_codec_locked(const char *path, const cdvr_codec *codec,
                                         cdvr_error *err)
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
    const char *other_file = file_of_locked(other, NULL);
    if (other_file)
        return cdvr_error_set(err, s, "%s: %s (codec '%s' was loaded from %s)", path, rerr.msg,
                              other->name, other_file);
    return cdvr_error_set(err, s, "%s: %s", path, rerr.msg);
}

/* The same for a format (a name or suffix clash names the other format's file). */
static cdvr_status register_format_locked(const char *path, const cdvr_format *format,
                                          cdvr_error *err)
{
    cdvr_error rerr;
    cdvr_status s = cdvr_format_register(format, &rerr);
    if (s == CDVR_OK)
        return CDVR_OK;
    const cdvr_format *other = NULL;
    const char *by = strstr(rerr.msg, "by format '");
    char name[CDVR_FORMAT_NAME_MAX] = "";
    if (by && sscanf(by, "by format '%15[a-z0-9_]'", name) == 1)
        other = cdvr_format_find(name);
    else if (strstr(rerr.msg, "already registered") && format->name)
        other = cdvr_format_find(format->name);
    const char *other_file = file_of_locked(NULL, other);
    if (other_file)
        return cdvr_error_set(err, s, "%s: %s (format '%s' was loaded from %s)", path, rerr.msg,
                              other->name, other_file);
    return cdvr_error_set(err, s, "%s: %s", path, rerr.msg);
}

/* Registers every codec and format of info, stopping at the first refusal; *done counts
 * the tables registered. Caller holds loader.mu. */
static cdvr_status register_all_locked(const char *path, const cdvr_plugin_info *info,
                                       size_t *done, cdvr_error *err)
{
    cdvr_status s = CDVR_OK;
    *done = 0;
    for (size_t k = 0; s == CDVR_OK && codec_at(info, k); k++)
        if ((s = register_codec_locked(path, codec_at(info, k), err)) == CDVR_OK)
            (*done)++;
    for (size_t k = 0; s == CDVR_OK && format_at(info, k); k++)
        if ((s = register_format_locked(path, format_at(info, k), err)) == CDVR_OK)
            (*done)++;
    return s;
}

/* dlopen + dlsym + checks + registration; caller holds loader.mu. */
static cdvr_status load_locked(const char *path, const loaded_plugin **out, cdvr_error *err)
{
    cdvr_error local;
    if (!err)
        err = &local; /* a refusal is kept (loaded_plugin.refusal) even when nobody asks */
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
    const cdvr_plugin_info *raw = entry();
    if (raw && (*out = loaded_locked(raw)) != NULL) {
        dlclose(h); /* the same file loaded again: drops the reference this call added */
        if ((*out)->refusal.status == CDVR_OK)
            return CDVR_OK;
        *err = (*out)->refusal;
        return (*out)->refusal.status;
    }
    cdvr_plugin_info info;
    size_t done = 0;
    cdvr_status s = check_info(path, raw, &info, err);
    if (s == CDVR_OK)
        s = widen_codecs(path, &info, err);
    if (s == CDVR_OK)
        s = widen_formats(path, &info, err);
    if (s == CDVR_OK)
        s = register_all_locked(path, &info, &done, err);
    if (s != CDVR_OK) {
        loaded_plugin *lp;
        if (done == 0)
            dlclose(h); /* nothing of it was registered */
        else if ((lp = remember_locked(raw, &info, path)) != NULL)
            lp->refusal = *err; /* its registered tables stay: name them, refuse it again */
        return s;
    }
    *out = remember_locked(raw, &info, path);
    if (!*out)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
    return CDVR_OK; /* never dlclose'd: the registries keep its tables */
}

cdvr_status cdvr_plugin_load_info(const char *path, const cdvr_plugin_info **out,
                                  cdvr_error *err)
{
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
    const loaded_plugin *lp = NULL;
    pthread_mutex_lock(&loader.mu);
    cdvr_status s = load_locked(path, &lp, err);
    const cdvr_plugin_info *info = lp ? &lp->info : NULL; /* items may move: copy under mu */
    pthread_mutex_unlock(&loader.mu);
    if (s == CDVR_OK && out)
        *out = info;
    return s;
}

cdvr_status cdvr_plugin_load(const char *path, const cdvr_codec **out, cdvr_error *err)
{
    if (out)
        *out = NULL;
    const cdvr_plugin_info *info;
    cdvr_status s = cdvr_plugin_load_info(path, &info, err);
    if (s == CDVR_OK && out)
        *out = codec_at(info, 0);
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
