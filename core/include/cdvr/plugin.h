/* cdvr/plugin.h - codec plugins (DESIGN.md section 4.4).
 *
 * A codec plugin is a shared object that exports one function,
 *
 *     const cdvr_plugin_info *cdvr_plugin_v1(void);
 *
 * returning the plugin ABI version it was built for (CDVR_PLUGIN_ABI, which covers the layout
 * of cdvr_codec and cdvr_codec_params in cdvr/codec.h) and its codec table. cdvr loads it with
 * dlopen, checks the version and registers the codec; from then on `codec="name"` works
 * everywhere a built-in codec does, and stores written with it open wherever it is loaded.
 * Plugins are never unloaded (their tables stay registered until the process ends).
 * plugins/example/ is the smallest complete plugin and the guide to writing one.
 *
 * A plugin uses no symbol of libcdvr: only the declarations and inline helpers of
 * cdvr/codec.h and this header (cdvr_plugin_error below in place of cdvr_error_set). Programs
 * link libcdvr statically and do not export it, so a plugin that called into it would not
 * load; plugins/CMakeLists.txt links plugins with -z defs so such a call fails at build time.
 * The ABI version covers the layouts of cdvr_plugin_info, cdvr_codec, cdvr_codec_params,
 * cdvr_codec_shape and cdvr_error.
 */
#ifndef CDVR_PLUGIN_H
#define CDVR_PLUGIN_H

#include <stdarg.h>
#include <stdio.h>

#include "cdvr/codec.h"
#include "cdvr/error.h"

#define CDVR_PLUGIN_ABI 3u /* 2: cdvr_codec.encode_part; 3: cdvr_codec.check */
/* The oldest ABI version still loaded: a version-2 table ends before `check`, so the loader
 * registers a copy of it with check NULL (nothing reads past the plugin's table). */
#define CDVR_PLUGIN_ABI_OLDEST 2u
#define CDVR_PLUGIN_SYMBOL "cdvr_plugin_v1"

/* Put before the definition of cdvr_plugin_v1: plugins are built with hidden visibility
 * (plugins/CMakeLists.txt) and export this one symbol. */
#if defined(__GNUC__)
#define CDVR_PLUGIN_EXPORT __attribute__((visibility("default")))
#else
#define CDVR_PLUGIN_EXPORT
#endif

typedef struct cdvr_plugin_info {
    uint32_t abi;              /* CDVR_PLUGIN_ABI as the plugin was compiled */
    const cdvr_codec *codec;   /* the codec it provides */
} cdvr_plugin_info;

typedef const cdvr_plugin_info *(*cdvr_plugin_entry_fn)(void);

/* cdvr_error_set for plugins (inline: no libcdvr symbol): fills err (if not NULL) with status
 * and a printf-formatted message; returns status. */
static inline cdvr_status cdvr_plugin_error(cdvr_error *err, cdvr_status status, const char *fmt,
                                            ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static inline cdvr_status cdvr_plugin_error(cdvr_error *err, cdvr_status status, const char *fmt,
                                            ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        err->status = status;
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
    }
    return status;
}

/* Loads the plugin at path and registers its codec (*out, may be NULL). Errors, each naming
 * the file: not a readable regular file, cannot be loaded (dlopen's reason: not a shared
 * object, missing library or symbol), no cdvr_plugin_v1 symbol, NULL info, ABI version outside
 * CDVR_PLUGIN_ABI_OLDEST .. CDVR_PLUGIN_ABI, NULL codec, a codec table the registry refuses (missing functions,
 * bad name or id; a name or id clash names the clashing codec and, for a plugin codec, the
 * file it came from). Loading the same file twice returns its codec again. Thread-safe. */
cdvr_status cdvr_plugin_load(const char *path, const cdvr_codec **out, cdvr_error *err);

/* The file a registered codec was loaded from (as given to cdvr_plugin_load), or NULL for a
 * built-in codec. The string lives until the process ends. */
const char *cdvr_plugin_file(const cdvr_codec *codec);

/* Loads every regular file ending in ".so" in each directory of a colon-separated list
 * (CDVR_PLUGIN_PATH), in name order. Failures do not stop the others; each is reported
 * through report(ud, message) when report is not NULL. Returns the number loaded. */
size_t cdvr_plugin_load_dirs(const char *dirs, void (*report)(void *ud, const char *message),
                             void *ud);

#endif
