/* core/render/method.c - the render-method registry (cdvr/method.h) and helpers over method
 * tables.
 *
 * The registry is one process-wide table of methods (a named context: `registry` below),
 * guarded by a mutex, in the idiom of the codec registry (core/codec/registry.c): the
 * built-ins are registered on first use (pthread_once); incomplete or clashing tables are
 * refused naming what is wrong. */
#include "cdvr/method.h"
#include "cdvr/names.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

extern const cdvr_render_method cdvr_method_raycast;
extern const cdvr_render_method cdvr_method_slice;
extern const cdvr_render_method cdvr_method_splat;

#define REGISTRY_MAX 32

static struct {
    pthread_mutex_t mu;
    pthread_once_t once;
    const cdvr_render_method *methods[REGISTRY_MAX];
    size_t count;
} registry = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_ONCE_INIT, {NULL}, 0};

static const char *const device_names[CDVR_DEVICE_COUNT] = {"cpu", "cl", "gl"};

const char *cdvr_device_name(cdvr_device_kind kind)
{
    return (unsigned)kind < CDVR_DEVICE_COUNT ? device_names[kind] : NULL;
}

int cdvr_device_parse(const char *name)
{
    for (int k = 0; name && k < CDVR_DEVICE_COUNT; k++)
        if (strcmp(name, device_names[k]) == 0)
            return k;
    return -1;
}

/* ---- registry ------------------------------------------------------------------------------ */

static cdvr_status check_options(const cdvr_render_method *m, cdvr_error *err)
{
    for (const cdvr_method_option *o = m->options; o->key; o++) {
        if (!o->doc)
            return cdvr_error_set(err, CDVR_ERR_ARG, "method '%s': option '%s' has no doc",
                                  m->name, o->key);
        if (o->type == CDVR_MOPT_CHOICE && !o->choices)
            return cdvr_error_set(err, CDVR_ERR_ARG, "method '%s': option '%s' has no choices",
                                  m->name, o->key);
    }
    return CDVR_OK;
}

static cdvr_status check_table(const cdvr_render_method *m, cdvr_error *err)
{
    if (!m)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render method table is NULL");
    if (!cdvr_name_valid(m->name, CDVR_METHOD_NAME_MAX))
        return cdvr_error_set(err, CDVR_ERR_ARG, "render method name '%s' is not 1..31 "
                              "characters of [a-z0-9_]", m->name ? m->name : "(null)");
    const char *missing = !m->description ? "description" : !m->options ? "options"
                        : !m->params_default ? "params_default" : !m->params_set ? "params_set"
                        : !m->render ? "render"
                        : !(m->devices & (CDVR_DEVICE_BIT(CDVR_DEVICE_COUNT) - 1)) ? "device"
                        : !(m->blends & CDVR_BLEND_BIT(CDVR_BLEND_COMPOSITE)) ? "composite blend mode"
                        : NULL;
    if (missing)
        return cdvr_error_set(err, CDVR_ERR_ARG, "render method '%s': the table has no %s",
                              m->name, missing);
    return check_options(m, err);
}

/* Caller holds registry.mu. */
static cdvr_status add_locked(const cdvr_render_method *m, cdvr_error *err)
{
    cdvr_status s = check_table(m, err);
    if (s != CDVR_OK)
        return s;
    for (size_t i = 0; i < registry.count; i++) {
        if (registry.methods[i] == m)
            return CDVR_OK;
        if (strcmp(registry.methods[i]->name, m->name) == 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "render method '%s' is already registered",
                                  m->name);
    }
    if (registry.count == REGISTRY_MAX)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "render method '%s': registry full (%d)",
                              m->name, REGISTRY_MAX);
    registry.methods[registry.count++] = m;
    return CDVR_OK;
}

static void register_builtins(void)
{
    const cdvr_render_method *builtins[] = {&cdvr_method_raycast, &cdvr_method_slice,
                                            &cdvr_method_splat};
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; i < sizeof builtins / sizeof builtins[0]; i++) {
        cdvr_error err;
        if (add_locked(builtins[i], &err) != CDVR_OK) { /* a programming error: say so */
            fprintf(stderr, "cdvr: built-in render method refused: %s\n", err.msg);
            abort();
        }
    }
    pthread_mutex_unlock(&registry.mu);
}

static void ensure_builtins(void)
{
    pthread_once(&registry.once, register_builtins);
}

const cdvr_render_method *cdvr_render_method_find(const char *name)
{
    if (!name)
        return NULL;
    ensure_builtins();
    const cdvr_render_method *found = NULL;
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; i < registry.count && !found; i++)
        if (strcmp(registry.methods[i]->name, name) == 0)
            found = registry.methods[i];
    pthread_mutex_unlock(&registry.mu);
    return found;
}

size_t cdvr_render_method_count(void)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    size_t n = registry.count;
    pthread_mutex_unlock(&registry.mu);
    return n;
}

const cdvr_render_method *cdvr_render_method_at(size_t i)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    const cdvr_render_method *m = i < registry.count ? registry.methods[i] : NULL;
    pthread_mutex_unlock(&registry.mu);
    return m;
}

cdvr_status cdvr_render_method_register(const cdvr_render_method *m, cdvr_error *err)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    cdvr_status s = add_locked(m, err);
    pthread_mutex_unlock(&registry.mu);
    return s;
}

void cdvr_render_method_names(char *out, size_t n)
{
    if (!n)
        return;
    out[0] = '\0';
    size_t used = 0, count = cdvr_render_method_count();
    for (size_t i = 0; i < count && used < n; i++) {
        int w = snprintf(out + used, n - used, "%s%s", i ? ", " : "", cdvr_render_method_at(i)->name);
        if (w < 0)
            break;
        used += (size_t)w;
    }
}

/* ---- helpers ------------------------------------------------------------------------------- */

int cdvr_render_method_has_option(const cdvr_render_method *m, const char *key)
{
    for (const cdvr_method_option *o = m->options; key && o->key; o++)
        if (strcmp(o->key, key) == 0)
            return 1;
    return 0;
}

cdvr_status cdvr_render_method_params_parse(const cdvr_render_method *m, const char *const *keys,
                                            const char *const *values, size_t n,
                                            cdvr_method_params *out, cdvr_error *err)
{
    memset(out, 0, sizeof *out);
    m->params_default(out);
    for (size_t i = 0; i < n; i++) {
        if (!cdvr_render_method_has_option(m, keys[i]))
            return cdvr_error_set(err, CDVR_ERR_ARG, "method '%s': unknown option '%s'", m->name,
                                  keys[i]);
        cdvr_status s = m->params_set(out, keys[i], values[i], err);
        if (s != CDVR_OK)
            return s;
    }
    return CDVR_OK;
}

int cdvr_render_method_supports(const cdvr_render_method *m, cdvr_device_kind device)
{
    return (unsigned)device < CDVR_DEVICE_COUNT && (m->devices & CDVR_DEVICE_BIT(device)) != 0;
}

void cdvr_render_method_devices(const cdvr_render_method *m, char *out, size_t n)
{
    if (!n)
        return;
    out[0] = '\0';
    size_t used = 0;
    for (int k = 0; k < CDVR_DEVICE_COUNT && used < n; k++) {
        if (!cdvr_render_method_supports(m, (cdvr_device_kind)k))
            continue;
        int w = snprintf(out + used, n - used, "%s%s", used ? ", " : "", device_names[k]);
        if (w < 0)
            break;
        used += (size_t)w;
    }
}

cdvr_device_kind cdvr_render_method_default_device(const cdvr_render_method *m,
                                                   cdvr_render_ctx *ctx)
{
    if (cdvr_render_method_supports(m, CDVR_DEVICE_CL) && ctx && cdvr_render_ctx_has_cl(ctx))
        return CDVR_DEVICE_CL;
    if (cdvr_render_method_supports(m, CDVR_DEVICE_CPU))
        return CDVR_DEVICE_CPU;
    if (cdvr_render_method_supports(m, CDVR_DEVICE_GL))
        return CDVR_DEVICE_GL;
    return CDVR_DEVICE_CL; /* a cl-only method: its render names the missing device */
}

cdvr_status cdvr_render_method_check_device(const cdvr_render_method *m, cdvr_device_kind device,
                                            cdvr_error *err)
{
    if (cdvr_render_method_supports(m, device))
        return CDVR_OK;
    char list[64];
    cdvr_render_method_devices(m, list, sizeof list);
    const char *name = cdvr_device_name(device);
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "method '%s' renders on %s, not %s",
                          m->name, list, name ? name : "an unknown device");
}

/* ---- stats --------------------------------------------------------------------------------- */

static cdvr_render_stat *stat_slot(cdvr_render_stats *s, const char *key)
{
    if (!s || !key)
        return NULL;
    for (size_t i = 0; i < s->count; i++)
        if (strcmp(s->items[i].key, key) == 0)
            return &s->items[i];
    if (s->count == CDVR_RENDER_STATS_MAX)
        return NULL;
    cdvr_render_stat *it = &s->items[s->count++];
    memset(it, 0, sizeof *it);
    snprintf(it->key, sizeof it->key, "%s", key);
    return it;
}

void cdvr_render_stats_number(cdvr_render_stats *s, const char *key, double value)
{
    cdvr_render_stat *it = stat_slot(s, key);
    if (it) {
        it->kind = CDVR_STAT_NUMBER;
        it->number = value;
    }
}

void cdvr_render_stats_integer(cdvr_render_stats *s, const char *key, long long value)
{
    cdvr_render_stat *it = stat_slot(s, key);
    if (it) {
        it->kind = CDVR_STAT_INTEGER;
        it->integer = value;
    }
}

void cdvr_render_stats_string(cdvr_render_stats *s, const char *key, const char *value)
{
    cdvr_render_stat *it = stat_slot(s, key);
    if (it) {
        it->kind = CDVR_STAT_STRING;
        snprintf(it->string, sizeof it->string, "%s", value ? value : "");
    }
}
