/* cdvr/plugin.h - codec and file-format plugins (DESIGN.md section 4.4).
 *
 * A plugin is a shared object that exports one function,
 *
 *     const cdvr_plugin_info *cdvr_plugin_v1(void);
 *
 * returning the plugin ABI version it was built for (CDVR_PLUGIN_ABI) and what it provides:
 * codecs (cdvr/codec.h) and/or file formats (cdvr/format.h). cdvr loads it with dlopen, checks
 * the version and registers every table; from then on `codec="name"` works everywhere a built-in
 * codec does (stores written with it open wherever it is loaded), and cdvr.load / cdvr_volume_load
 * open files of its formats. Plugins are never unloaded (their tables stay registered until the
 * process ends). plugins/example/ is the smallest complete codec plugin and the guide to writing
 * one; tests/plugins/format_plugin.c the same for a format.
 *
 * ABI versions (what cdvr_plugin_info holds; this cdvr loads CDVR_PLUGIN_ABI_MIN ..
 * CDVR_PLUGIN_ABI):
 *   2  {abi, codec}: one codec (cdvr_codec with encode_part). Still loaded as it is.
 *   3  {abi, codec, codecs, formats}: `codec` may be NULL; `codecs` and `formats` are
 *      NULL-terminated lists (or NULL). At least one codec or format in all.
 *   4  as 3; cdvr_codec ends with `check` (the payload check before the device). The codec
 *      tables of a version 2 or 3 plugin end before it: cdvr registers full-size copies of
 *      them with check NULL (so an ABI 2/3 plugin's info, from cdvr_plugin_load_info, lists
 *      those copies, in `codecs`).
 *   5  as 4; cdvr_format ends with `accepts_dir` (directories read as one volume) and
 *      `expand_opts` (a list file expanded with the load options), and
 *      cdvr_raw_opts ends with `select` (the object inside a file: array, series, dataset). The
 *      format tables of a version 2 to 4 plugin end before it: cdvr registers full-size
 *      copies with accepts_dir and expand_opts NULL (listed in the info's `formats`).
 *   6  as 5; cdvr_codec ends with `decode_cells` (decode of the cells a render reads) and
 *      `decodes_in_parallel`. The codec tables of a version 2 to 5 plugin end before them:
 *      cdvr registers full-size copies with those NULL and 0 (and, before 4, check NULL).
 * A version outside that range is refused naming both versions. The ABI version covers the
 * layouts of cdvr_plugin_info, cdvr_codec, cdvr_codec_params, cdvr_codec_shape, cdvr_format,
 * cdvr_volume, cdvr_raw_opts and cdvr_error.
 *
 * A plugin uses no symbol of libcdvr: only the declarations and inline helpers of
 * cdvr/codec.h, cdvr/format.h and this header (cdvr_plugin_error below in place of
 * cdvr_error_set; a format without the libcdvr allocator gives `read`, not `load`, and the
 * registry allocates the volume). Programs link libcdvr statically and do not export it, so a
 * plugin that called into it would not load; plugins/CMakeLists.txt links plugins with -z defs
 * so such a call fails at build time.
 */
#ifndef CDVR_PLUGIN_H
#define CDVR_PLUGIN_H

#include <stdarg.h>
#include <stdio.h>

#include "cdvr/codec.h"
#include "cdvr/error.h"
#include "cdvr/format.h"

#define CDVR_PLUGIN_ABI 6u     /* 6: cdvr_codec.decode_cells; 5: cdvr_format.accepts_dir; 4: cdvr_codec.check; 3: lists of codecs and formats;
                                  2: cdvr_codec.encode_part */
#define CDVR_PLUGIN_ABI_MIN 2u /* the oldest version this cdvr still loads */
#define CDVR_PLUGIN_SYMBOL "cdvr_plugin_v1"

/* Put before the definition of cdvr_plugin_v1: plugins are built with hidden visibility
 * (plugins/CMakeLists.txt) and export this one symbol. */
#if defined(__GNUC__)
#define CDVR_PLUGIN_EXPORT __attribute__((visibility("default")))
#else
#define CDVR_PLUGIN_EXPORT
#endif

typedef struct cdvr_plugin_info {
    uint32_t abi;                       /* CDVR_PLUGIN_ABI as the plugin was compiled */
    const cdvr_codec *codec;            /* a codec it provides (ABI 2: required; 3: or NULL) */
    /* ABI 3 and later (not read from an ABI 2 plugin): */
    const cdvr_codec *const *codecs;    /* more codecs, NULL-terminated, or NULL */
    const cdvr_format *const *formats;  /* formats, NULL-terminated, or NULL */
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

/* Loads the plugin at path and registers its codecs and formats; *out (may be NULL) is its
 * first codec, NULL for a plugin of formats only. Errors, each naming the file: not a readable
 * regular file, cannot be loaded (dlopen's reason: not a shared object, missing library or
 * symbol), no cdvr_plugin_v1 symbol, NULL info, an ABI version outside CDVR_PLUGIN_ABI_MIN ..
 * CDVR_PLUGIN_ABI, neither codec nor format, a table a registry refuses (missing functions,
 * bad name or id; a name, id or suffix clash names the clashing codec or format and, for a
 * plugin's, the file it came from). A refused table leaves the plugin's tables registered before
 * it in place (registries never drop a table). Loading the same file twice returns its codec
 * again. Thread-safe. */
cdvr_status cdvr_plugin_load(const char *path, const cdvr_codec **out, cdvr_error *err);
/* The same, giving what the plugin provides, as ABI 3 lists (an ABI 2 plugin's one codec
 * appears as `codec`, its lists NULL). The info lives until the process ends. */
cdvr_status cdvr_plugin_load_info(const char *path, const cdvr_plugin_info **out,
                                  cdvr_error *err);

/* The file a registered codec or format was loaded from (as given to cdvr_plugin_load), or
 * NULL for a built-in one. The string lives until the process ends. */
const char *cdvr_plugin_file(const cdvr_codec *codec);
const char *cdvr_plugin_format_file(const cdvr_format *format);

/* Loads every regular file ending in ".so" in each directory of a colon-separated list
 * (CDVR_PLUGIN_PATH), in name order. Failures do not stop the others; each is reported
 * through report(ud, message) when report is not NULL. Returns the number loaded. */
size_t cdvr_plugin_load_dirs(const char *dirs, void (*report)(void *ud, const char *message),
                             void *ud);

#endif
