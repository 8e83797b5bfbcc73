/* cdvr/method.h - one interface for every render method (DESIGN.md section 13) and the registry.
 *
 * A render method turns one u8 frame (a volume, its value window already applied to the TF),
 * a camera and options into an image. Lua (cdvr.render, cdvr.window, cdvr.methods), the
 * player, capture and the MPI paths only ever go through a `cdvr_render_method` table found
 * by name; none of them names a method or branches on an index. Built-in methods: "raycast"
 * (cpu, cl), "slice" (gl: 2D textures through EGL) and "splat" (cpu).
 *
 * Options. Every method reads the scene's common options from cdvr_render_opts (render.h):
 * tf, camera and background always, and those of step, unit, term and threads that its
 * `scene_keys` names. Its own options (lod, order, ...) are listed in `options` with their
 * type, default and one-line documentation (cdvr.methods() and cdvr.help show them; Lua
 * refuses every other key), and are kept in a `cdvr_method_params` blob whose layout the
 * method alone defines (in memory only, never stored: a plain struct copied in and out).
 * The method parses each option from text, as codecs do (Lua gives `lod=true` as "true",
 * numbers as "%.17g").
 *
 * Devices. `devices` is a bit set of cdvr_device_kind (CDVR_DEVICE_BIT(kind)). The default
 * device, one rule everywhere (cdvr.render, cdvr.window, the player, capture, MPI):
 * OpenCL when the method supports it and an OpenCL device can be opened, else the first
 * other device the method lists (cpu, then gl). A render on a device the method does not
 * list is an error naming the devices it has.
 *
 * Devices live in a cdvr_render_ctx that the caller owns (the Lua state keeps one): the
 * OpenCL device and its stream, and the EGL slicer's context, each opened on first use.
 *
 * Hooks. `render` is required: one frame of a dense u8 volume into a new image. The others
 * are optional:
 *  - render_stream: the player's device path on OpenCL (frames already on the device, decoded
 *    there or kept compressed for a fetch-mode codec); a method without it plays from frames
 *    decoded on the host, on whichever device it renders;
 *  - render_store: one timestep of a stored variant straight from its chunk on the device
 *    (cdvr.render(store, {device="cl"})); without it the chunk is decoded on the host;
 *  - window_key: a key the window hands to the method (slice cycles lod with 'l', splat
 *    cycles its order with 'o'): names the option to change and its new value as text, which
 *    the window sets like any option;
 *  - describe: a short text for the window's overlay ("lod seed", "order dda").
 *
 * Adding a method: a file core/render/<folder>/<name>_method.c defining its table, one line in
 * the built-in list of core/render/method.c, and that folder's CMakeLists.txt. Nothing else
 * names a method.
 *
 * Threads: the table is immutable; a cdvr_render_ctx and what it opened belong to one thread
 * at a time.
 */
#ifndef CDVR_METHOD_H
#define CDVR_METHOD_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/camera.h"
#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/render.h"
#include "cdvr/skip.h"
#include "cdvr/tf.h"
#include "cdvr/volume.h"

typedef struct cdvr_store cdvr_store;
typedef struct cdvr_cl cdvr_cl;
typedef struct cdvr_cl_stream cdvr_cl_stream;
typedef struct cdvr_gl cdvr_gl;

/* Where a frame is rendered. Names: "cpu", "cl", "gl". */
typedef enum cdvr_device_kind {
    CDVR_DEVICE_CPU = 0,
    CDVR_DEVICE_CL = 1,
    CDVR_DEVICE_GL = 2,
    CDVR_DEVICE_COUNT = 3
} cdvr_device_kind;
#define CDVR_DEVICE_BIT(kind) (1u << (kind))

/* "cpu", "cl", "gl"; NULL for anything else. */
const char *cdvr_device_name(cdvr_device_kind kind);
/* The kind called name; -1 for an unknown name. */
int cdvr_device_parse(const char *name);

/* Blend modes: cdvr_blend of render.h; the bit set says what a method supports. */
#define CDVR_BLEND_BIT(mode) (1u << (mode))

/* Common scene options a method honours (scene_keys bits); the rest of cdvr_render_opts
 * (tf, camera, background, cancel) every method honours. */
#define CDVR_SCENE_STEP 0x01u    /* opts->step */
#define CDVR_SCENE_UNIT 0x02u    /* opts->unit */
#define CDVR_SCENE_TERM 0x04u    /* opts->term_alpha */
#define CDVR_SCENE_THREADS 0x08u /* opts->threads */

/* Distribution modes (cdvr/dist.h) a method can run in. */
#define CDVR_METHOD_DIST_TIME 0x1u      /* whole frames per rank */
#define CDVR_METHOD_DIST_BRICKS 0x2u    /* sort-last: a box of every frame per rank (needs clip) */

typedef enum cdvr_method_option_type {
    CDVR_MOPT_NUMBER = 0,   /* finite number */
    CDVR_MOPT_INTEGER = 1,
    CDVR_MOPT_BOOLEAN = 2,  /* "true" / "false" */
    CDVR_MOPT_CHOICE = 3    /* one of `choices` ("|"-separated); booleans are "true"/"false" */
} cdvr_method_option_type;

typedef struct cdvr_method_option {
    const char *key;        /* "order" */
    cdvr_method_option_type type;
    const char *def;        /* default as text ("dda"); NULL: unset (the method decides) */
    const char *choices;    /* CHOICE: "dda|axis|sort|quicksort"; else NULL */
    const char *doc;        /* one line */
} cdvr_method_option;

#define CDVR_METHOD_NAME_MAX 32   /* method names: 1..31 bytes of [a-z0-9_] */
#define CDVR_METHOD_PARAMS_MAX 128
typedef struct cdvr_method_params {
    _Alignas(8) unsigned char bytes[CDVR_METHOD_PARAMS_MAX];
} cdvr_method_params;

/* A render's figures for img:stats() (ms, samples, order_ms, device, ...): a fixed list filled
 * in C (no Lua call runs inside a render), pushed by the binding afterwards. */
#define CDVR_RENDER_STATS_MAX 32
typedef enum cdvr_stat_kind { CDVR_STAT_NUMBER = 0, CDVR_STAT_INTEGER, CDVR_STAT_STRING } cdvr_stat_kind;
typedef struct cdvr_render_stat {
    char key[24];
    cdvr_stat_kind kind;
    double number;          /* NUMBER */
    long long integer;      /* INTEGER */
    char string[128];       /* STRING */
} cdvr_render_stat;
typedef struct cdvr_render_stats {
    size_t count;
    cdvr_render_stat items[CDVR_RENDER_STATS_MAX];
} cdvr_render_stats;

/* Set key (replacing an earlier value of key); NULL stats is allowed; past
 * CDVR_RENDER_STATS_MAX entries new keys are dropped. */
void cdvr_render_stats_number(cdvr_render_stats *s, const char *key, double value);
void cdvr_render_stats_integer(cdvr_render_stats *s, const char *key, long long value);
void cdvr_render_stats_string(cdvr_render_stats *s, const char *key, const char *value);

typedef struct cdvr_render_ctx cdvr_render_ctx;

typedef struct cdvr_render_method cdvr_render_method;

struct cdvr_render_method {
    const char *name;                    /* registry key: "raycast" */
    const char *description;             /* one line for cdvr.methods() */
    unsigned devices;                    /* CDVR_DEVICE_BIT set, at least one */
    unsigned blends;                     /* CDVR_BLEND_BIT set (composite at least) */
    int shading;                         /* 1 when it shades (none yet) */
    int bricks;                          /* 1 when it honours opts->clip (sort-last boxes) */
    unsigned distribute;                 /* CDVR_METHOD_DIST_* set */
    unsigned scene_keys;                 /* CDVR_SCENE_* set */
    const cdvr_method_option *options;   /* own keys, terminated by {NULL} */

    /* Fills p with the defaults. */
    void (*params_default)(cdvr_method_params *p);
    /* Sets option `key` from text; an unknown key or a bad value is CDVR_ERR_ARG naming the
     * key, the value and what is accepted. */
    cdvr_status (*params_set)(cdvr_method_params *p, const char *key, const char *value,
                              cdvr_error *err);

    /* Renders frame t (from 0) of the u8 volume vol on `device` (one of `devices`) into a new
     * image of the camera's size; opts->tf's table is built over the frame's window. Reports
     * figures through stats (may be NULL): at least "ms". */
    cdvr_status (*render)(cdvr_render_ctx *ctx, cdvr_device_kind device, const cdvr_volume *vol,
                          size_t t, cdvr_render_opts *opts, const cdvr_method_params *p,
                          cdvr_render_stats *stats, cdvr_image **out, cdvr_error *err);

    /* Optional: device frame `frame` of an OpenCL stream (cdvr/device.h) with the volume's
     * geometry; grid (may be NULL) holds brick flags made on the host for opts->tf. Fills
     * img (the camera's size, made by the caller); *setup_ms gets the per-frame setup (b4),
     * the rest is the render (b5). */
    cdvr_status (*render_stream)(cdvr_cl_stream *s, size_t frame, const cdvr_skip_grid *grid,
                                 const cdvr_render_opts *opts, const cdvr_method_params *p,
                                 const double spacing[3], const double origin[3],
                                 const double direction[9], cdvr_image *img, double *setup_ms,
                                 cdvr_error *err);
    /* Optional: timestep t (from 0) of variant v of a store, from its chunk on `device`
     * (opts->tf built over the store's window). */
    cdvr_status (*render_store)(cdvr_render_ctx *ctx, cdvr_device_kind device,
                                const cdvr_store *st, size_t v, size_t t, cdvr_render_opts *opts,
                                const cdvr_method_params *p, cdvr_render_stats *stats,
                                cdvr_image **out, cdvr_error *err);
    /* Optional: the window's key (a printable character, lower case) for the options p: sets
     * *option to one of the method's option keys and value (n bytes) to its new value as
     * text, and returns 1; 0 when the key means nothing to the method. */
    int (*window_key)(const cdvr_method_params *p, int key, const char **option, char *value,
                      size_t n);
    /* Optional: the method's state in a few words for the window's overlay. */
    void (*describe)(const cdvr_method_params *p, char *out, size_t n);
};

/* ---- registry ------------------------------------------------------------------------------
 * One process-wide table of render methods (the method registry context), guarded by a
 * mutex; the built-ins are present from the start. Registered tables must stay valid until
 * the process ends. */

/* The method called name, or NULL. */
const cdvr_render_method *cdvr_render_method_find(const char *name);
/* Number of registered methods and the i-th (registration order, built-ins first). */
size_t cdvr_render_method_count(void);
const cdvr_render_method *cdvr_render_method_at(size_t i);
/* Adds a method. Refused (CDVR_ERR_ARG, naming the member) when the table lacks a name,
 * render, params_default or params_set, lists no device or no blend mode, has an option
 * without key or doc, or its name is taken. */
cdvr_status cdvr_render_method_register(const cdvr_render_method *m, cdvr_error *err);
/* The registered names joined by ", " into out (for "unknown method" messages). */
void cdvr_render_method_names(char *out, size_t n);

/* ---- helpers over a method table ---------------------------------------------------------- */

/* 1 if the method takes option key (its own; not the scene's). */
int cdvr_render_method_has_option(const cdvr_render_method *m, const char *key);
/* Defaults, then each key/value pair in order. */
cdvr_status cdvr_render_method_params_parse(const cdvr_render_method *m, const char *const *keys,
                                            const char *const *values, size_t n,
                                            cdvr_method_params *out, cdvr_error *err);
/* 1 if the method renders on device. */
int cdvr_render_method_supports(const cdvr_render_method *m, cdvr_device_kind device);
/* The devices of m as "cpu, cl" into out. */
void cdvr_render_method_devices(const cdvr_render_method *m, char *out, size_t n);
/* The default device (the rule above); ctx (may be NULL: no OpenCL is tried) is asked whether
 * an OpenCL device opens. */
cdvr_device_kind cdvr_render_method_default_device(const cdvr_render_method *m,
                                                   cdvr_render_ctx *ctx);
/* Checks that m renders on device: CDVR_ERR_UNSUPPORTED "method 'splat' renders on cpu, not
 * cl" otherwise. */
cdvr_status cdvr_render_method_check_device(const cdvr_render_method *m, cdvr_device_kind device,
                                            cdvr_error *err);

/* ---- render context ----------------------------------------------------------------------- */

cdvr_status cdvr_render_ctx_create(cdvr_render_ctx **out, cdvr_error *err);
/* Closes what it opened; NULL is allowed. */
void cdvr_render_ctx_free(cdvr_render_ctx *ctx);
/* The OpenCL device, opened on first use (the failure is remembered: later calls fail at
 * once with the same message). CDVR_ERR_UNSUPPORTED without OpenCL in the build. */
cdvr_status cdvr_render_ctx_cl(cdvr_render_ctx *ctx, cdvr_cl **out, cdvr_error *err);
/* 1 when an OpenCL device is open or opens now. */
int cdvr_render_ctx_has_cl(cdvr_render_ctx *ctx);
/* The OpenCL streams a context keeps (cdvr_cl_stream: frames and their copies on the
 * device), and the volumes it holds at once: two volumes rendered in turn keep a stream each
 * and upload nothing on the second round (the comparison of an original with its decoded
 * copy, two datasets side by side). */
#define CDVR_RENDER_CTX_STREAMS 2
#define CDVR_RENDER_CTX_HOLDS 2
/* A stream for frames of dims on the context's device: the one of these dims used most
 * recently, else a new one in place of the one used least recently. It becomes the
 * context's current stream (cdvr_render_ctx_forget_frame). */
cdvr_status cdvr_render_ctx_stream(cdvr_render_ctx *ctx, const size_t dims[3],
                                   cdvr_cl_stream **out, cdvr_error *err);
/* A stream whose frame 0 is frame t of a u8 volume: one holding exactly these voxels already
 * (a second render of the same frame uploads nothing), else it uploads them into the stream
 * of another frame of this volume, or, for a held volume, the stream used least recently
 * (made for the volume's dims when needed), or, for one not held, the most recently used
 * stream of its dims. It becomes the current stream. */
cdvr_status cdvr_render_ctx_volume_stream(cdvr_render_ctx *ctx, const cdvr_volume *vol,
                                          size_t t, cdvr_cl_stream **out, cdvr_error *err);
/* Forgets the current stream's frame (its frame 0 was overwritten by someone else). */
void cdvr_render_ctx_forget_frame(cdvr_render_ctx *ctx);
/* The caller's promise that vol stays alive, never freed nor its data pointer replaced,
 * until the context releases it: up to CDVR_RENDER_CTX_HOLDS volumes are held at once, and
 * holding one more releases the one held least recently; the caller releases one with
 * cdvr_render_ctx_release_volume, all with vol NULL, and must do so before freeing a held
 * volume. Returns the index of vol's hold (0 .. CDVR_RENDER_CTX_HOLDS - 1; the volume held
 * there before, if another, is released), -1 for NULL. While vol is held,
 * cdvr_render_ctx_volume_stream knows its frame t is on a stream when the frame pointer,
 * dims, type, t and vol->revision (volume.h) equal those of the upload that put it there:
 * O(1), and no host copy of the frame is kept. So whoever changes voxels of a held volume in
 * place must call cdvr_volume_touch. Volumes not held are compared voxel by voxel with a host
 * copy of the uploaded frame (a volume freed and another allocated at its address is never
 * taken for it). A context without a held volume works as before (the memcmp path), as the
 * player's does. The CPU ray caster's skip cache keeps the ranges of the volume held last. */
int cdvr_render_ctx_hold_volume(cdvr_render_ctx *ctx, const cdvr_volume *vol);
/* Releases vol if ctx holds it (nothing otherwise). */
void cdvr_render_ctx_release_volume(cdvr_render_ctx *ctx, const cdvr_volume *vol);
/* The index of vol's hold, or -1 when ctx does not hold it (or vol is NULL). */
int cdvr_render_ctx_held_index(const cdvr_render_ctx *ctx, const cdvr_volume *vol);
/* How many frames cdvr_render_ctx_volume_stream sent to the device since ctx was created (a render
 * of a frame the device holds already sends none). */
uint64_t cdvr_render_ctx_uploads(const cdvr_render_ctx *ctx);
/* The context's brick cache (cdvr/brick_cache.h) for variant v of st with this budget, made
 * (or remade, dropping the old one) when it serves another store, variant or budget. */
struct cdvr_brick_cache;
cdvr_status cdvr_render_ctx_brick_cache(cdvr_render_ctx *ctx, const struct cdvr_store *st,
                                        size_t v, uint64_t budget_bytes,
                                        struct cdvr_brick_cache **out, cdvr_error *err);
/* Makes the frames of the chunk holding timestep t (from 0) of variant v of a store on the
 * context's stream for the store's dims: the codec's decode kernel, its fetch mode (frames
 * stay compressed), or a host decode + upload for codecs without device code and for bricked
 * stores. *frame gets the device frame of t. Errors name the store, variant and chunk. */
cdvr_status cdvr_render_ctx_load_chunk(cdvr_render_ctx *ctx, const cdvr_store *st, size_t v,
                                       size_t t, cdvr_cl_stream **stream, size_t *frame,
                                       cdvr_error *err);
/* Frames decoded by visible cells for the context's stream (cdvr/visible.h), created on first
 * use; they live as long as the context. */
struct cdvr_visible;
cdvr_status cdvr_render_ctx_visible(cdvr_render_ctx *ctx, struct cdvr_visible **out,
                                    cdvr_error *err);
/* The EGL slicer, created on first use. */
cdvr_status cdvr_render_ctx_gl(cdvr_render_ctx *ctx, cdvr_gl **out, cdvr_error *err);
/* The CPU ray caster's skip cache (cdvr/render.h), created on first use; NULL when ctx is
 * NULL or out of memory (the render then makes its grid each time). */
cdvr_cpu_skip_cache *cdvr_render_ctx_cpu_skip(cdvr_render_ctx *ctx);

#endif
