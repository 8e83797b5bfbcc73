/* core/codec/registry.c - the codec registry (cdvr/codec.h) and helpers over codec tables.
 *
 * The registry is the one process-wide table of codecs (a named context: `registry` below),
 * guarded by a mutex because plugins may be loaded while other threads look codecs up. The
 * built-ins are registered on first use (pthread_once). */
#include "cdvr/codec.h"
#include "cdvr/names.h"

#include <pthread.h>
#include <stdio.h>
#include <string.h>

extern const cdvr_codec cdvr_codec_raw;
extern const cdvr_codec cdvr_codec_pvtc;
extern const cdvr_codec cdvr_codec_hvq;
extern const cdvr_codec cdvr_codec_hvqc;

#define REGISTRY_MAX 64

static struct {
    pthread_mutex_t mu;
    pthread_once_t once;
    const cdvr_codec *codecs[REGISTRY_MAX];
    size_t count;
} registry = {PTHREAD_MUTEX_INITIALIZER, PTHREAD_ONCE_INIT, {NULL}, 0};

int cdvr_codec_name_valid(const char *name)
{
    return cdvr_name_valid(name, CDVR_CODEC_NAME_MAX);
}

static cdvr_status check_table(const cdvr_codec *c, cdvr_error *err)
{
    if (!c)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec table is NULL");
    if (!cdvr_codec_name_valid(c->name))
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec name '%s' is not 1..%d characters of "
                              "[a-z0-9_]", c->name ? c->name : "(null)", CDVR_CODEC_NAME_MAX - 1);
    if (c->id >= 0x80000000u)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec '%s': id %u is not below 2^31", c->name,
                              c->id);
    const char *missing = !c->description ? "description" : !c->params ? "params"
                        : !c->params_default ? "params_default" : !c->params_set ? "params_set"
                        : !c->params_get ? "params_get"
                        : !c->params_check ? "params_check" : !c->variant_name ? "variant_name"
                        : !c->shape ? "shape" : !c->encode ? "encode" : !c->decode ? "decode"
                        : NULL;
    if (!missing && c->cl_mode != CDVR_CODEC_CL_NONE) {
        if (c->cl_mode != CDVR_CODEC_CL_DECODE && c->cl_mode != CDVR_CODEC_CL_FETCH)
            return cdvr_error_set(err, CDVR_ERR_ARG, "codec '%s': unknown cl_mode %d", c->name,
                                  (int)c->cl_mode);
        missing = (!c->cl_source && !c->cl_file) ? "cl_source or cl_file"
                : !c->cl_function ? "cl_function"
                : (c->cl_mode == CDVR_CODEC_CL_DECODE && !c->cl_work_items) ? "cl_work_items"
                : NULL;
    }
    if (missing)
        return cdvr_error_set(err, CDVR_ERR_ARG, "codec '%s': the table has no %s", c->name,
                              missing);
    return CDVR_OK;
}

/* Caller holds registry.mu. */
static cdvr_status add_locked(const cdvr_codec *c, cdvr_error *err)
{
    cdvr_status s = check_table(c, err);
    if (s != CDVR_OK)
        return s;
    for (size_t i = 0; i < registry.count; i++) {
        const cdvr_codec *o = registry.codecs[i];
        if (o == c)
            return CDVR_OK;
        if (strcmp(o->name, c->name) == 0)
            return cdvr_error_set(err, CDVR_ERR_ARG, "codec '%s' is already registered (id %u)",
                                  c->name, o->id);
        if (o->id == c->id)
            return cdvr_error_set(err, CDVR_ERR_ARG, "codec '%s': id %u is already taken by "
                                  "codec '%s'", c->name, c->id, o->name);
    }
    if (registry.count == REGISTRY_MAX)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "codec '%s': the registry is full (%d "
                              "codecs)", c->name, REGISTRY_MAX);
    registry.codecs[registry.count++] = c;
    return CDVR_OK;
}

static void register_builtins(void)
{
    static const cdvr_codec *const builtins[] = {&cdvr_codec_raw, &cdvr_codec_pvtc,
                                                    &cdvr_codec_hvq, &cdvr_codec_hvqc};
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; i < sizeof builtins / sizeof *builtins; i++)
        (void)add_locked(builtins[i], NULL); /* built-ins are valid: test_codec checks */
    pthread_mutex_unlock(&registry.mu);
}

static void ensure_builtins(void)
{
    pthread_once(&registry.once, register_builtins);
}

cdvr_status cdvr_codec_register(const cdvr_codec *codec, cdvr_error *err)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    cdvr_status s = add_locked(codec, err);
    pthread_mutex_unlock(&registry.mu);
    return s;
}

const cdvr_codec *cdvr_codec_find(const char *name)
{
    ensure_builtins();
    const cdvr_codec *found = NULL;
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; name && !found && i < registry.count; i++)
        if (strcmp(registry.codecs[i]->name, name) == 0)
            found = registry.codecs[i];
    pthread_mutex_unlock(&registry.mu);
    return found;
}

const cdvr_codec *cdvr_codec_by_id(uint32_t id)
{
    ensure_builtins();
    const cdvr_codec *found = NULL;
    pthread_mutex_lock(&registry.mu);
    for (size_t i = 0; !found && i < registry.count; i++)
        if (registry.codecs[i]->id == id)
            found = registry.codecs[i];
    pthread_mutex_unlock(&registry.mu);
    return found;
}

size_t cdvr_codec_count(void)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    size_t n = registry.count;
    pthread_mutex_unlock(&registry.mu);
    return n;
}

const cdvr_codec *cdvr_codec_at(size_t i)
{
    ensure_builtins();
    pthread_mutex_lock(&registry.mu);
    const cdvr_codec *c = i < registry.count ? registry.codecs[i] : NULL;
    pthread_mutex_unlock(&registry.mu);
    return c;
}

/* ---- helpers -------------------------------------------------------------------------------- */

int cdvr_codec_has_param(const cdvr_codec *codec, const char *key)
{
    for (const cdvr_codec_param_doc *d = codec->params; d && d->key; d++)
        if (strcmp(d->key, key) == 0)
            return 1;
    return 0;
}

cdvr_status cdvr_codec_params_parse(const cdvr_codec *codec, const char *const *keys,
                                    const char *const *values, size_t n, cdvr_codec_params *out,
                                    cdvr_error *err)
{
    memset(out, 0, sizeof *out);
    codec->params_default(out);
    for (size_t i = 0; i < n; i++) {
        cdvr_status s = codec->params_set(out, keys[i], values[i], err);
        if (s != CDVR_OK)
            return s;
    }
    return codec->params_check(out, err);
}

cdvr_status cdvr_codec_shape_of(const cdvr_codec *codec, const cdvr_codec_params *p,
                                const size_t dims[3], cdvr_codec_shape *out, cdvr_error *err)
{
    cdvr_error e;
    cdvr_status s = codec->params_check(p, &e);
    if (s == CDVR_OK)
        s = codec->shape(p, dims, out, &e);
    if (s == CDVR_OK && (out->timesteps < 1 || out->bound_bytes < out->payload_bytes ||
                         out->bound_bytes == 0))
        s = cdvr_error_set(&e, CDVR_ERR_ARG, "bad chunk shape (%zu timesteps, %zu bytes, bound "
                           "%zu)", out->timesteps, out->payload_bytes, out->bound_bytes);
    if (s != CDVR_OK)
        return cdvr_error_set(err, s, "codec %s: %s", codec->name, e.msg);
    return CDVR_OK;
}
