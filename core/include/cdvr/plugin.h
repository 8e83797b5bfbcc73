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
 */
#ifndef CDVR_PLUGIN_H
#define CDVR_PLUGIN_H

#include "cdvr/codec.h"
#include "cdvr/error.h"

#define CDVR_PLUGIN_ABI 1u
#define CDVR_PLUGIN_SYMBOL "cdvr_plugin_v1"

typedef struct cdvr_plugin_info {
    uint32_t abi;              /* CDVR_PLUGIN_ABI as the plugin was compiled */
    const cdvr_codec *codec;   /* the codec it provides */
} cdvr_plugin_info;

typedef const cdvr_plugin_info *(*cdvr_plugin_entry_fn)(void);

/* Loads the plugin at path and registers its codec (*out, may be NULL). Errors, each naming
 * the file: cannot be loaded (dlopen's reason), no cdvr_plugin_v1 symbol, NULL info or codec,
 * ABI version other than CDVR_PLUGIN_ABI, a codec table the registry refuses (name or id
 * clash, missing functions). Loading the same file twice returns its codec again. */
cdvr_status cdvr_plugin_load(const char *path, const cdvr_codec **out, cdvr_error *err);

/* Loads every regular file ending in ".so" in each directory of a colon-separated list
 * (CDVR_PLUGIN_PATH), in name order. Failures do not stop the others; each is reported
 * through report(ud, message) when report is not NULL. Returns the number loaded. */
size_t cdvr_plugin_load_dirs(const char *dirs, void (*report)(void *ud, const char *message),
                             void *ud);

#endif
