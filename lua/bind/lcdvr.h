/* lua/bind/lcdvr.h - what the Lua binding files share.
 *
 * One binding file per core module (l_volume.c, l_tf.c, ...). Each exports
 * lcdvr_open_<module>(L), called by the host with the `cdvr` table on top of the stack; it
 * registers its functions in that table, creates its metatables (one named metatable per
 * type, liolib.c style: __gc, __close, __tostring, __name, methods behind __index) and adds
 * one-line help entries with lcdvr_help_add. It leaves the stack as it found it.
 *
 * Errors, one rule: misuse (bad argument types or values) raises, naming the function and the
 * option or argument (lcdvr_error, lcdvr_checkoption: never Lua's "bad argument #-1" or
 * "to '?'"); so do loaders and openers whose file cannot be read (cdvr.load,
 * cdvr.load_series, cdvr.open, cdvr.tf(path), cdvr.camera(path); cdvr.encode too, which
 * opens the store it wrote: the message names the file and the reason); savers (img:save,
 * v:save_raw, tf:save, cam:save) return nil, message on I/O failure (lcdvr_fail,
 * lcdvr_save_file); other core failures raise with the core's message, prefixed with the
 * function's name (lcdvr_raise). Every help line of a loader, opener or saver says which
 * ("raises ..." or "true or nil, msg"). Two documented exceptions return nil, message:
 * cdvr.cl_info (a query: no device is not misuse) and cdvr.load_lua (share/lua).
 */
#ifndef CDVR_LCDVR_H
#define CDVR_LCDVR_H

#include <stdatomic.h>
#include <stdio.h>

#include <lauxlib.h>
#include <lua.h>
#include <lualib.h>

#include "cdvr/annotate.h"
#include "cdvr/camera.h"
#include "cdvr/error.h"
#include "cdvr/image.h"
#include "cdvr/method.h"
#include "cdvr/player.h"
#include "cdvr/store.h"
#include "cdvr/tf.h"
#include "cdvr/volume.h"

#define LCDVR_VOLUME "cdvr.Volume"
#define LCDVR_IMAGE "cdvr.Image"
#define LCDVR_TF "cdvr.TF"
#define LCDVR_CAMERA "cdvr.Camera"
#define LCDVR_STORE "cdvr.Store"
#define LCDVR_PLAYER "cdvr.Player"

/* Raises a Lua error with the core's message ("interrupted!" for CDVR_ERR_CANCELLED, as the
 * console's Ctrl-C), prefixed with the running function's name ("cdvr.orbit_camera: camera:
 * width must be ...", lcdvr_push_funcname) unless it starts with it. Never returns. */
int lcdvr_raise(lua_State *L, const cdvr_error *err);
/* Pushes nil and the message; returns 2 (for `return lcdvr_fail(L, &err);`). */
int lcdvr_fail(lua_State *L, const cdvr_error *err);

/* Writes one line "cdvr: warning: <message>" to stderr (lua_pushfstring formats): for results
 * that are valid but probably not what the user meant (a camera that misses the volume,
 * playback stopped at the last timestep). */
void lcdvr_warn(lua_State *L, const char *fmt, ...);

/* Writes path through a temporary file (cdvr_atomic_file) with write(f, obj), which returns
 * nonzero on failure; pushes true, or nil and a message naming path. Returns the count. */
int lcdvr_save_file(lua_State *L, const char *path, int (*write)(FILE *f, const void *obj),
                    const void *obj);

/* Creates metatable `name` with __name, __index = methods table; `meta` adds metamethods
 * (__gc, __close, __tostring, ...). Leaves the stack unchanged. */
void lcdvr_newclass(lua_State *L, const char *name, const luaL_Reg *methods, const luaL_Reg *meta);
/* Names the function table at idx for messages: package.loaded[name] = table, so that Lua's
 * "bad argument" messages of a function called without a name (through pcall, from C) say
 * 'cdvr.plugin.load' or 'cdvr.Volume.get', never '?'. lcdvr_newclass names its methods table
 * with the class name; a subtable of cdvr (cdvr.plugin, cdvr.mpi) is named by its opener. */
void lcdvr_name_table(lua_State *L, int idx, const char *name);
/* Registers funcs into the table on top of the stack (the cdvr table). */
void lcdvr_setfuncs(lua_State *L, const luaL_Reg *funcs);
/* Adds a help line for `name` (e.g. "cdvr.load(path [, opts])") to cdvr.help(). */
void lcdvr_help_add(lua_State *L, const char *name, const char *description);

/* Pushes and returns the name of the running C function for messages: "cdvr.render",
 * "cdvr.Volume.get" (its name in package.loaded, see lcdvr_name_table), else the name it was
 * called by, else "cdvr". */
const char *lcdvr_push_funcname(lua_State *L);
/* Raises "<function>: <message>" (lcdvr_push_funcname; lua_pushfstring formats), for
 * messages that do not name their function themselves ("option 'x': ..."). Never returns. */
int lcdvr_error(lua_State *L, const char *fmt, ...);
/* Optional table fields (table at index idx): return the default when absent or nil,
 * raise when present with the wrong type: "<function>: option 'key': number expected, got
 * string" (lcdvr_push_funcname). */
lua_Number lcdvr_optnumberfield(lua_State *L, int idx, const char *key, lua_Number def);
lua_Integer lcdvr_optintegerfield(lua_State *L, int idx, const char *key, lua_Integer def);
const char *lcdvr_optstringfield(lua_State *L, int idx, const char *key, const char *def);
int lcdvr_optbooleanfield(lua_State *L, int idx, const char *key, int def);
/* Reads an array field of n numbers (e.g. dims={64,64,64}); returns 0 if absent, raises if
 * present with the wrong length or types. */
int lcdvr_numberarrayfield(lua_State *L, int idx, const char *key, double *out, int n);

/* Raises "what: unknown option 'devcie' (did you mean 'device'?)" for any key of the options
 * table at idx that is not in keys (NULL-terminated); non-string keys are errors too. Does
 * nothing when idx is not a table. Every function taking an options table calls it first. */
void lcdvr_checkoptions(lua_State *L, int idx, const char *what, const char *const keys[]);
/* The same for a table that also holds a list (cdvr.tf's points, a dims triple): its array
 * part 1..#t is allowed. */
void lcdvr_checkoptions_array(lua_State *L, int idx, const char *what, const char *const keys[]);

/* The userdata of metatable tname in option `key` of the value at idx (an options table field
 * already pushed, usually -1); raises "what: option 'key': tname expected, got <type>" (never
 * "bad argument #-1"); what NULL: the running function's name (lcdvr_push_funcname). */
void *lcdvr_checkoption(lua_State *L, int idx, const char *what, const char *key, const char *tname);

/* Object lifetimes. A binding whose C object uses another object's C data beyond one call (a
 * player its store) or during a call that runs Lua code (cdvr.encode its volume while the
 * schedule runs) marks it in use with lcdvr_use and lets go with lcdvr_unuse (counted, kept in
 * a weak table in the registry, so it never keeps the object alive). Every close, __close and
 * __gc of a type that can be in use first calls lcdvr_defer_close: while the object is in use
 * it records the close and returns 1, and the caller returns without freeing; the last
 * lcdvr_unuse then calls the object's __close, which frees it. An object whose close is pending
 * counts as closed for Lua (lcdvr_closing: its methods raise "attempt to use a closed ...")
 * while its users keep working. */
void lcdvr_use(lua_State *L, int idx);
void lcdvr_unuse(lua_State *L, int idx);
int lcdvr_defer_close(lua_State *L, int idx);
int lcdvr_closing(lua_State *L, int idx);

/* Callback budgets (lbudget.c). A callback (policy, camera, schedule, window policy) and a data
 * file run under a budget: `instructions` Lua VM instructions (a count hook, checked every
 * min(limit, 10000); C loops that run none charge it themselves: pattern matching, string.rep,
 * table.move) and `memory` bytes the Lua state may grow by while it runs (the state's
 * allocator, lcdvr_newstate). The budget covers every coroutine the callback resumes and every
 * __gc that runs meanwhile; once spent every further instruction raises again, so a pcall
 * inside the callback cannot swallow it; debug.* but traceback and getinfo raises inside it.
 * Nested budgets (a callback that runs another player) restore the outer one and count against
 * it. */
#define LCDVR_CALLBACK_LIMIT 50000000  /* default callback_limit, VM instructions */
#define LCDVR_CALLBACK_MEMORY_MB 256   /* default callback_memory, MB */
typedef struct lcdvr_limits {
    lua_Integer instructions;          /* callback_limit */
    size_t memory;                     /* callback_memory, in bytes */
} lcdvr_limits;
/* Calls the function below its nargs arguments in protected mode, with a traceback message
 * handler, under lim. Returns the lua_pcall status; on error the message with its traceback is
 * on top: "... exceeded its instruction budget (callback_limit = N instructions) ..." or
 * "callback exceeded its memory budget (callback_memory = N MB)" when a budget ran out. */
int lcdvr_pcall_limits(lua_State *L, int nargs, int nres, const lcdvr_limits *lim);
/* The same with `limit` instructions and the default memory budget. */
int lcdvr_pcall_budget(lua_State *L, int nargs, int nres, lua_Integer limit);
/* Reads options callback_limit (instructions, 1 .. INT_MAX) and callback_memory (MB, 1 ..
 * 2^20) of the options table at idx (absent: the defaults; idx not a table: the defaults);
 * raises "what: option '...' must be ..." on bad values. The caller lists both keys in its
 * lcdvr_checkoptions. */
void lcdvr_limits_options(lua_State *L, int idx, const char *what, lcdvr_limits *out);
/* Charges steps to the running budget (a C loop that runs no VM instruction); raises the
 * budget error once it is spent. Does nothing outside a budget. */
void lcdvr_budget_charge(lua_State *L, lua_Integer steps);
/* Installs what budgets need, once, before any script runs (the host calls it after
 * luaL_openlibs; later calls do nothing): coroutine.resume, wrap and close and xpcall that pass
 * the budget on (xpcall no longer calls its message handler once the budget is spent),
 * setmetatable and debug.setmetatable that guard __gc, the guarded debug functions, string.rep,
 * table.move and the step-counting pattern functions (lstrmatch.c: lcdvr_open_strmatch).
 * Outside a budget all behave as Lua's own, but that getmetatable(x).__gc is a cdvr function
 * (the real finalizer is kept aside) and debug.getupvalue/setupvalue refuse C functions. */
void lcdvr_open_budget(lua_State *L);
void lcdvr_open_strmatch(lua_State *L);
/* A Lua state whose allocator counts its bytes (needed by budgets), with Lua's panic and
 * warning functions; NULL when out of memory. lcdvr_close closes it: every remaining __gc runs
 * under a budget of the default limits; returns how many were stopped by their budget (each
 * printed on stderr). */
lua_State *lcdvr_newstate(void);
int lcdvr_close(lua_State *L);
/* Data files (cdvr.tf(path), cdvr.camera(path), cdvr.path.load, cdvr.load_lua): loads the
 * regular file at path as a text chunk (no precompiled chunks) in an empty environment and
 * runs it under a data budget: no function calls, 100000 + 16 per byte VM instructions, the
 * default memory budget. Pushes the value it returns and returns LUA_OK, or pushes a message
 * naming path and the reason and returns the error status. */
int lcdvr_load_data(lua_State *L, const char *path);
/* Registers cdvr.load_lua(file) -> value | nil, message (lcdvr_load_data) in the table on top. */
void lcdvr_open_data(lua_State *L);

/* ---- the scene contract (l_scene.c): what the player and the window share ---------------- */

/* The callback budget both give their policy and camera callbacks (option callback_limit). */
#define LCDVR_CALLBACK_LIMIT 50000000
/* Frame rows a policy sees (stats.frames): the last ones, oldest first. */
#define LCDVR_POLICY_ROWS 16

/* What a policy is told besides the store and the rows. */
typedef struct lcdvr_policy_view {
    size_t t, group;         /* the next timestep to show and its group, from 0 */
    double target_fps;       /* > 0: stats.target_fps; else absent */
    double min_psnr;         /* NaN: absent */
    int pipelined, capture;
    /* the brick cache (player cache=true): stats.lod_error (the knob now), stats.lod_base (the
     * user's lod_error) and stats.levels; absent when cache is 0 */
    int cache;
    double lod_error, lod_base;
    size_t levels;
} lcdvr_policy_view;

/* Pushes one frame row as a table (policy stats.frames[i], the player's report rows). */
void lcdvr_push_frame_row(lua_State *L, const cdvr_store *st, const cdvr_frame_row *r);
/* Pushes stats.variants: {name=, codec=, <codec parameters>, stage2=, bytes_per_timestep=,
 * payload_bytes_per_timestep=, psnr=, group=} per variant. */
void lcdvr_push_store_variants(lua_State *L, const cdvr_store *st);
/* Pushes the policy's stats table (share/lua/cdvr/policy.lua documents it): view's fields,
 * current (the variant of the last row), best (cdvr_store_best_variant), frames (the last
 * LCDVR_POLICY_ROWS rows) and variants. */
void lcdvr_push_policy_stats(lua_State *L, const cdvr_store *st, const lcdvr_policy_view *view,
                             const cdvr_frame_row *rows, size_t nrows);
/* Calls the function below its nargs arguments under a budget of `limit` instructions
 * (lcdvr_pcall_budget); leaves nres results and returns CDVR_OK, or pops the error and fills
 * err with "what: message and traceback" (CDVR_ERR_CANCELLED after Ctrl-C in the console). */
cdvr_status lcdvr_call_callback(lua_State *L, int nargs, int nres, const lcdvr_limits *lim,
                                const char *what, cdvr_error *err);
/* Reads a policy's two results (name [, reason], on top; popped) into *variant (from 0) and
 * reason, or fills err ("policy returned X, not a variant of <store>"). */
/* The variant a Lua value names (the string at idx, matched over its whole length: a name with
 * an embedded zero byte names none), or -1. */
int lcdvr_find_variant(lua_State *L, int idx, const cdvr_store *st);
/* Pushes the value at idx for a message: a string quoted with its zero bytes and control
 * characters escaped ("S4T3\0junk"), else its type name. Returns the pushed text. */
const char *lcdvr_push_quoted(lua_State *L, int idx);
cdvr_status lcdvr_policy_result(lua_State *L, const cdvr_store *st, int *variant, char *reason,
                                size_t reason_size, cdvr_error *err);
/* Applies a camera callback's result (a cdvr.Camera, or {eye=, center=, up=, fov=}) at idx
 * to *cam, keeping its width and height, and validates it. */
cdvr_status lcdvr_camera_result(lua_State *L, int idx, cdvr_camera *cam, cdvr_error *err);
/* The name of the default device of a render method (cdvr_render_method_default_device: "cl"
 * when the method has it and the state's OpenCL device opens, else "cpu", else "gl"), one rule
 * for cdvr.render, cdvr.player and cdvr.window. */
const char *lcdvr_default_device(lua_State *L, const char *method_name);
/* Decodes the chunk group of variant v holding timestep t (from 0), every brick, assembled,
 * into a new u8 volume of the group's timesteps (the first is *t0, from 0) with the store's
 * geometry and value window, timing b1 (read), b1' (unzip) and the decode apart: *share gets
 * read_ms, unzip_ms, decode_ms, bytes and payload_bytes divided by the group's timesteps (each
 * frame's share, as the player's rows) and bricks_read; its other fields are zero. */
cdvr_status lcdvr_store_decode_group(const cdvr_store *st, size_t v, size_t t, cdvr_volume **out,
                                     size_t *t0, cdvr_frame_row *share, cdvr_error *err);

/* Per-type accessors, implemented in the type's binding file. push* takes ownership. */
/* lcdvr_checkvolume reads every timestep of a lazy volume (cdvr.load_series, l_volume.c)
 * into memory first (once: it is an ordinary volume from then on); bindings that can work a
 * timestep at a time use the lazy accessors below instead. */
cdvr_volume *lcdvr_checkvolume(lua_State *L, int idx);
/* The volume at idx without reading voxels: dims, timesteps, type, geometry and window of a
 * lazy volume (data NULL; window NAN while not computed), else the volume itself. */
const cdvr_volume *lcdvr_volume_header(lua_State *L, int idx);
/* 1 when the volume at idx is lazy (its voxels not in memory). */
int lcdvr_volume_lazy(lua_State *L, int idx);
/* Pushes and returns a new volume of timesteps [t, t + count) (from 0) of the volume at idx,
 * carrying its value window (for a lazy float series one pass over its files computes that
 * range the first time); raises on errors. */
cdvr_volume *lcdvr_volume_read(lua_State *L, int idx, size_t t, size_t count);
/* The lazy volume at idx as an encode source (cdvr_store_encode_source): its u8 codes, or its
 * values quantised over its window; sets o->qlo, o->qhi and o->source_type. The source reads
 * the volume's files, so the volume must stay open (lcdvr_use) while it is used. */
void lcdvr_volume_source(lua_State *L, int idx, cdvr_encode_source *src, cdvr_encode_opts *o);
void lcdvr_pushvolume(lua_State *L, cdvr_volume *vol);
cdvr_image *lcdvr_checkimage(lua_State *L, int idx);
void lcdvr_pushimage(lua_State *L, cdvr_image *img);
cdvr_tf *lcdvr_checktf(lua_State *L, int idx);
cdvr_tf *lcdvr_pushtf(lua_State *L, const cdvr_tf *tf);      /* copies */
cdvr_camera *lcdvr_checkcamera(lua_State *L, int idx);
cdvr_camera *lcdvr_pushcamera(lua_State *L, const cdvr_camera *cam); /* copies */
cdvr_store *lcdvr_checkstore(lua_State *L, int idx);
/* Sets each parameter of a codec blob as a field of the table on top (numbers as numbers),
 * and the same in its subtable `params` (l_store.c). */
void lcdvr_push_params(lua_State *L, const cdvr_codec *codec, const cdvr_codec_params *p);
/* Codec parameters from the table at idx (nil: the defaults); unknown keys and bad values
 * raise, naming `what`. */
void lcdvr_parse_params(lua_State *L, int idx, const cdvr_codec *codec, cdvr_codec_params *out,
                        const char *what);
/* Timesteps per chunk of variant v (its codec's chunk shape). */
size_t lcdvr_chunk_timesteps(const cdvr_store *st, size_t v);

/* Attaches the table on top of the stack (popped) to the image at idx: img:stats() returns
 * it. Every renderer's binding fills it (ms, method, device and its own figures). */
void lcdvr_setimagestats(lua_State *L, int idx);

/* The console's interrupt flag: set by Ctrl-C while a line runs, cleared before the next;
 * long-running bindings pass it to the core (cdvr_render_opts.cancel). NULL outside the
 * console (scripts stop on Ctrl-C as usual). */
const atomic_int *lcdvr_interrupt_flag(lua_State *L);
void lcdvr_set_interrupt_flag(lua_State *L, atomic_int *flag);

/* Render methods (l_method.c, cdvr/method.h). The state's render context (OpenCL device and
 * stream, EGL slicer), made on first use and kept in the registry. */
cdvr_render_ctx *lcdvr_render_ctx(lua_State *L);
/* The context holds vol, the volume userdata at idx (cdvr_render_ctx_hold_volume: its frames
 * are known on the device by identity and revision), and keeps a reference to that userdata
 * (a user value of the context per hold) so it is not collected while held; idx 0 and vol
 * NULL release every held volume. Up to CDVR_RENDER_CTX_HOLDS volumes are held: holding
 * another releases the one held least recently. */
void lcdvr_render_ctx_hold(lua_State *L, int idx, const cdvr_volume *vol);
/* Called before vol is freed (its __gc or __close): the state's context, if it holds vol,
 * releases it. Makes no context. */
void lcdvr_render_ctx_release(lua_State *L, const cdvr_volume *vol);
/* The method called name, or raises "what: option 'method': unknown method 'x' (methods: ...)". */
const cdvr_render_method *lcdvr_method_lookup(lua_State *L, const char *name, const char *what);
/* The method of option `method` of the table at idx (default "raycast"). */
const cdvr_render_method *lcdvr_method_option(lua_State *L, int idx, const char *what);
/* lcdvr_checkoptions for the table at idx with the keys `base` (NULL-terminated) plus the
 * scene keys and own options of method m. */
void lcdvr_method_checkoptions(lua_State *L, int idx, const cdvr_render_method *m,
                               const char *what, const char *const base[]);
/* 1 when m takes key (a scene key it honours or one of its options). */
int lcdvr_method_takes(const cdvr_render_method *m, const char *key);
/* m's options from the table at idx (the defaults for absent keys; not a table: all defaults);
 * wrong types and bad values raise naming `what` and the option. */
void lcdvr_method_params(lua_State *L, int idx, const cdvr_render_method *m, const char *what,
                         cdvr_method_params *out);
/* Option `device` of the table at idx for m: absent or "auto" -> the default device rule
 * (cdvr_render_method_default_device); a device m does not list raises. */
cdvr_device_kind lcdvr_method_device(lua_State *L, int idx, const cdvr_render_method *m,
                                     const char *what);
/* The look options of the table at idx (blend=, iso={value=, color=, opacity=}, shade=,
 * ambient=, diffuse=, specular=, specular_power=, light={dir=} | {headlight=true},
 * gradient_opacity={{magnitude, opacity}, ...}) for method m: a blend mode or shading m lacks
 * raises naming both. iso= implies blend "iso", which shades unless shade=false. */
void lcdvr_read_look(lua_State *L, int idx, const cdvr_render_method *m, const char *what,
                     cdvr_look *look);
/* Option annotate= of the table at idx (true: colour bar and letters; or {colorbar=, axes=,
 * title=, time=, unit=, space=}) into o (tf, camera and time text are the caller's); *time: the
 * timestep is asked for. Returns 1 when something is to be drawn. The strings stay in the
 * table: the caller keeps it referenced while it draws. */
int lcdvr_read_annotate(lua_State *L, int idx, const char *what, cdvr_annotate_opts *o,
                        int *time);
/* The look keys (NULL-terminated) every look-taking options table allows. */
extern const char *const lcdvr_look_keys[];
/* Pushes a table of a render's figures, with method = m->name and device = the device's name
 * unless the method named it more closely (the OpenCL device, the GL renderer). */
void lcdvr_push_render_stats(lua_State *L, const cdvr_render_method *m, cdvr_device_kind device,
                             const cdvr_render_stats *stats);

/* Windows (l_window.c), driven by the console between input lines: processes every open
 * window's events and playback and redraws what changed (all of them when `changed`: a console
 * line ran). Returns the milliseconds until it wants to run again, or -1 when no window is
 * open. Errors are printed (then *printed is set), never raised. */
int lcdvr_window_tick(lua_State *L, int changed, int *printed);
/* Opens the console's window (cdvr -i with a display) as the global `window`; returns 0 and
 * prints one notice line when there is no display or no GL. */
int lcdvr_window_console(lua_State *L);

/* OpenCL decode for st:decode(t, variant, {device="cl"}) (l_device.c): decodes timestep t
 * (from 0) of variant v with the decode kernel and pushes a new u8 volume, or raises. */
int lcdvr_decode_cl(lua_State *L, const cdvr_store *st, size_t v, size_t t);

/* Module openers (the host calls each, in this order). */
int lcdvr_open_volume(lua_State *L);
int lcdvr_open_image(lua_State *L);
int lcdvr_open_tf(lua_State *L);
int lcdvr_open_camera(lua_State *L);
int lcdvr_open_render(lua_State *L);
int lcdvr_open_method(lua_State *L);
int lcdvr_open_compare(lua_State *L);
int lcdvr_open_store(lua_State *L);
int lcdvr_open_device(lua_State *L);
int lcdvr_open_player(lua_State *L);
int lcdvr_open_splat(lua_State *L);
int lcdvr_open_codec(lua_State *L);
int lcdvr_open_gl(lua_State *L);
int lcdvr_open_window(lua_State *L);
int lcdvr_open_mpi(lua_State *L);
int lcdvr_open_movie(lua_State *L);

#endif
