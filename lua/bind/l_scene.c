/* lua/bind/l_scene.c - the scene contract the player (l_player.c) and the window (l_window.c)
 * share, so that a policy or a camera path behaves the same in both:
 *   - the policy's `stats` table (share/lua/cdvr/policy.lua documents it), built from frame
 *     rows (cdvr_frame_row) by one function;
 *   - the policy and camera callbacks, called under the instruction budget
 *     (lcdvr_pcall_limits: `callback_limit`, `callback_memory`), and their results read the same way;
 *   - the default variant (cdvr_store_best_variant) and the default device
 *     (lcdvr_default_device);
 *   - a store frame decoded with its read, unzip and decode timed apart (the window; the
 *     player's pipeline times them itself).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/timing.h"
#include "lcdvr.h"

static void setnum(lua_State *L, const char *key, double v)
{
    lua_pushnumber(L, v);
    lua_setfield(L, -2, key);
}

void lcdvr_push_frame_row(lua_State *L, const cdvr_store *st, const cdvr_frame_row *r)
{
    lua_createtable(L, 0, 22);
    lua_pushinteger(L, (lua_Integer)r->frame + 1);
    lua_setfield(L, -2, "frame");
    lua_pushinteger(L, (lua_Integer)r->t + 1);
    lua_setfield(L, -2, "t");
    lua_pushstring(L, cdvr_store_variant(st, (size_t)r->variant)->name);
    lua_setfield(L, -2, "variant");
    setnum(L, "read_ms", r->read_ms);
    setnum(L, "unzip_ms", r->unzip_ms);
    setnum(L, "unzip_cpu_ms", r->unzip_cpu_ms);
    setnum(L, "grid_ms", r->grid_ms);
    setnum(L, "upload_ms", r->upload_ms);
    setnum(L, "decode_ms", r->decode_ms);
    setnum(L, "setup_ms", r->setup_ms);
    setnum(L, "render_ms", r->render_ms);
    setnum(L, "frame_ms", r->frame_ms);
    setnum(L, "interval_ms", r->interval_ms);
    setnum(L, "bytes", (double)r->bytes);
    setnum(L, "payload_bytes", (double)r->payload_bytes);
    setnum(L, "device_bytes", (double)r->device_bytes);
    setnum(L, "composite_ms", r->composite_ms);
    setnum(L, "wait_ms", r->wait_ms);
    lua_pushinteger(L, (lua_Integer)r->bricks_read);
    lua_setfield(L, -2, "bricks_read");
    lua_pushinteger(L, (lua_Integer)r->bricks_skipped);
    lua_setfield(L, -2, "bricks_skipped");
    setnum(L, "samples", (double)r->samples);
    setnum(L, "decoded_share", r->decoded_share);
    if (r->nlevels) { /* the brick cache (cache=true) */
        setnum(L, "resident_bytes", (double)r->resident_bytes);
        setnum(L, "lod_error", r->lod_error);
        lua_pushinteger(L, (lua_Integer)r->bricks_coarser);
        lua_setfield(L, -2, "bricks_coarser");
        lua_pushinteger(L, (lua_Integer)r->bricks_pending);
        lua_setfield(L, -2, "bricks_pending");
        for (size_t l = 0; l < r->nlevels && l < 16; l++) {
            char key[24];
            snprintf(key, sizeof key, "bricks_level%u", (unsigned)l);
            lua_pushinteger(L, (lua_Integer)r->bricks_at[l]);
            lua_setfield(L, -2, key);
        }
    }
    lua_pushinteger(L, r->rank);
    lua_setfield(L, -2, "rank");
    if (r->group_start) {
        lua_pushstring(L, r->reason);
        lua_setfield(L, -2, "reason");
    }
    if (r->status != CDVR_OK) {
        lua_pushstring(L, r->error);
        lua_setfield(L, -2, "error");
    }
}

void lcdvr_push_store_variants(lua_State *L, const cdvr_store *st)
{
    const cdvr_store_info *info = cdvr_store_get_info(st);
    lua_createtable(L, (int)info->nvariants, 0);
    for (size_t v = 0; v < info->nvariants; v++) {
        const cdvr_variant_info *var = cdvr_store_variant(st, v);
        const cdvr_chunk_info *ch0 = cdvr_store_chunk(st, v, 0);
        lua_createtable(L, 0, 10);
        lua_pushstring(L, var->name);
        lua_setfield(L, -2, "name");
        lua_pushstring(L, var->codec_name);
        lua_setfield(L, -2, "codec");
        if (var->codec)
            lcdvr_push_params(L, var->codec, &ch0->params);
        lua_pushstring(L, cdvr_stage2_name(var->stage2));
        lua_setfield(L, -2, "stage2");
        setnum(L, "bytes_per_timestep", (double)var->bytes / (double)info->timesteps);
        setnum(L, "payload_bytes_per_timestep", (double)var->payload_bytes / (double)info->timesteps);
        setnum(L, "psnr", var->psnr);
        lua_pushinteger(L, (lua_Integer)lcdvr_chunk_timesteps(st, v));
        lua_setfield(L, -2, "group");
        lua_rawseti(L, -2, (lua_Integer)v + 1);
    }
}

void lcdvr_push_policy_stats(lua_State *L, const cdvr_store *st, const lcdvr_policy_view *view,
                             const cdvr_frame_row *rows, size_t nrows)
{
    lua_createtable(L, 0, 12);                    /* stats */
    if (view->target_fps > 0.0)
        setnum(L, "target_fps", view->target_fps);
    if (!isnan(view->min_psnr))
        setnum(L, "min_psnr", view->min_psnr);
    lua_pushinteger(L, (lua_Integer)view->t + 1);
    lua_setfield(L, -2, "t");
    lua_pushinteger(L, (lua_Integer)view->group + 1);
    lua_setfield(L, -2, "group");
    lua_pushboolean(L, view->pipelined);
    lua_setfield(L, -2, "pipelined");
    lua_pushboolean(L, view->capture);
    lua_setfield(L, -2, "capture");
    if (nrows) {
        lua_pushstring(L, cdvr_store_variant(st, (size_t)rows[nrows - 1].variant)->name);
        lua_setfield(L, -2, "current");
    }
    lua_pushstring(L, cdvr_store_variant(st, (size_t)cdvr_store_best_variant(st))->name);
    lua_setfield(L, -2, "best");
    if (view->cache) {
        setnum(L, "lod_error", view->lod_error);
        setnum(L, "lod_base", view->lod_base);
        lua_pushinteger(L, (lua_Integer)view->levels);
        lua_setfield(L, -2, "levels");
    }
    size_t first = nrows > LCDVR_POLICY_ROWS ? nrows - LCDVR_POLICY_ROWS : 0;
    lua_createtable(L, (int)(nrows - first), 0);  /* stats, frames */
    for (size_t i = first; i < nrows; i++) {
        lcdvr_push_frame_row(L, st, &rows[i]);
        lua_rawseti(L, -2, (lua_Integer)(i - first + 1));
    }
    lua_setfield(L, -2, "frames");
    lcdvr_push_store_variants(L, st);
    lua_setfield(L, -2, "variants");
}

cdvr_status lcdvr_call_callback(lua_State *L, int nargs, int nres, const lcdvr_limits *lim,
                                const char *what, cdvr_error *err)
{
    if (lcdvr_pcall_limits(L, nargs, nres, lim) != LUA_OK) {
        const atomic_int *interrupt = lcdvr_interrupt_flag(L); /* Ctrl-C in the console */
        cdvr_status why = interrupt && atomic_load(interrupt) ? CDVR_ERR_CANCELLED : CDVR_ERR_ARG;
        cdvr_error_set(err, why, "%s: %s", what, lua_tostring(L, -1));
        lua_pop(L, 1);
        return why;
    }
    return CDVR_OK;
}

int lcdvr_find_variant(lua_State *L, int idx, const cdvr_store *st)
{
    size_t len = 0;
    const char *name = lua_type(L, idx) == LUA_TSTRING ? lua_tolstring(L, idx, &len) : NULL;
    return name && strlen(name) == len ? cdvr_store_find_variant(st, name) : -1;
}

const char *lcdvr_push_quoted(lua_State *L, int idx)
{
    if (lua_type(L, idx) != LUA_TSTRING)
        return lua_pushstring(L, luaL_typename(L, idx));
    size_t len;
    const char *s = lua_tolstring(L, idx, &len);
    luaL_Buffer b;
    luaL_buffinit(L, &b);                         /* ..., buffer */
    luaL_addchar(&b, '"');
    for (size_t i = 0; i < len && i < 64; i++) {
        unsigned char c = (unsigned char)s[i];
        char esc[8];
        if (c >= 32 && c < 127 && c != '"' && c != '\\') {
            luaL_addchar(&b, (char)c);
        } else {
            snprintf(esc, sizeof esc, "\\%u", c);
            luaL_addstring(&b, esc);
        }
    }
    luaL_addstring(&b, len > 64 ? "\"..." : "\"");
    luaL_pushresult(&b);                          /* ..., quoted */
    return lua_tostring(L, -1);
}

cdvr_status lcdvr_policy_result(lua_State *L, const cdvr_store *st, int *variant, char *reason,
                                size_t reason_size, cdvr_error *err)
{
    int v = lcdvr_find_variant(L, -2, st);
    cdvr_status s = CDVR_OK;
    if (v < 0) {
        s = cdvr_error_set(err, CDVR_ERR_ARG, "policy returned %s, not a variant of %s",
                           lcdvr_push_quoted(L, -2), cdvr_store_path(st));
        lua_pop(L, 1);
    } else {
        *variant = v;
        snprintf(reason, reason_size, "%s", lua_isstring(L, -1) ? lua_tostring(L, -1) : "policy");
    }
    lua_pop(L, 2);
    return s;
}

cdvr_status lcdvr_camera_result(lua_State *L, int idx, cdvr_camera *cam, cdvr_error *err)
{
    cdvr_camera *ucam = luaL_testudata(L, idx, LCDVR_CAMERA);
    if (ucam) {
        int w = cam->width, h = cam->height;
        *cam = *ucam;
        cam->width = w;
        cam->height = h;
    } else if (lua_istable(L, idx)) {
        lcdvr_numberarrayfield(L, idx, "eye", cam->eye, 3);
        lcdvr_numberarrayfield(L, idx, "center", cam->center, 3);
        lcdvr_numberarrayfield(L, idx, "up", cam->up, 3);
        cam->fov = lcdvr_optnumberfield(L, idx, "fov", cam->fov);
    } else {
        return cdvr_error_set(err, CDVR_ERR_ARG,
                              "camera function returned %s (cdvr.Camera or {eye=,center=,up=,fov=} expected)",
                              luaL_typename(L, idx));
    }
    return cdvr_camera_validate(cam, err);
}

const char *lcdvr_default_device(lua_State *L, const char *method_name)
{
    const cdvr_render_method *m = lcdvr_method_lookup(L, method_name, "default device");
    return cdvr_device_name(cdvr_render_method_default_device(m, lcdvr_render_ctx(L)));
}

cdvr_status lcdvr_store_decode_group(const cdvr_store *st, size_t v, size_t t, cdvr_volume **out,
                                     size_t *t0, cdvr_frame_row *share, cdvr_error *err)
{
    *out = NULL;
    const cdvr_store_info *info = cdvr_store_get_info(st);
    size_t c0 = cdvr_store_chunk_for(st, v, t, 0);
    if (c0 == (size_t)-1)
        return cdvr_error_set(err, CDVR_ERR_ARG, "%s: no timestep %zu in variant %zu (%zu "
                              "timesteps, %zu variants)", cdvr_store_path(st), t + 1, v + 1,
                              info->timesteps, info->nvariants);
    const cdvr_chunk_info *first = cdvr_store_chunk(st, v, c0);
    size_t count = first->count;
    cdvr_volume *vol = NULL;
    cdvr_status s = cdvr_volume_create(info->dims, count, CDVR_TYPE_U8, &vol, err);
    if (s != CDVR_OK)
        return s;
    double read_ms = 0, unzip_ms = 0, unzip_cpu_ms = 0, decode_ms = 0;
    uint64_t bytes = 0, payload_bytes = 0;
    int whole = info->nbricks == 1;
    uint8_t **frames = calloc(count, sizeof *frames);
    uint8_t *stored = NULL, *payload = NULL, *brick = NULL;
    if (!frames)
        s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory decoding timestep %zu",
                           cdvr_store_path(st), t + 1);
    /* last brick first: a voxel two bricks share keeps the value of the lower brick, which
     * owns it (as cdvr_store_decode) */
    for (size_t b = info->nbricks; s == CDVR_OK && b-- > 0;) {
        const cdvr_chunk_info *ch = cdvr_store_chunk(st, v, c0 + b);
        size_t lo[3], bd[3];
        cdvr_store_brick_box(info, b, lo, bd);
        size_t brick_voxels = bd[0] * bd[1] * bd[2];
        stored = malloc(ch->stored_bytes ? ch->stored_bytes : 1);
        payload = malloc(ch->payload_bytes ? ch->payload_bytes : 1);
        brick = whole ? NULL : malloc(count * brick_voxels);
        if (!stored || !payload || (!whole && !brick)) {
            s = cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: out of memory reading chunk %zu",
                               cdvr_store_path(st), c0 + b + 1);
            break;
        }
        for (size_t i = 0; i < count; i++)
            frames[i] = whole ? (uint8_t *)cdvr_volume_frame(vol, i) : brick + i * brick_voxels;
        double start = cdvr_now_ms();
        s = cdvr_store_read_chunk(st, v, c0 + b, stored, err);
        double mid = cdvr_now_ms();
        read_ms += mid - start;
        if (s == CDVR_OK)
            s = cdvr_store_unpack_chunk_cpu(st, v, c0 + b, stored, payload, &unzip_cpu_ms, err);
        double mid2 = cdvr_now_ms();
        unzip_ms += mid2 - mid;
        if (s == CDVR_OK)
            s = cdvr_store_decode_chunk(st, v, c0 + b, payload, frames, err);
        decode_ms += cdvr_now_ms() - mid2;
        bytes += ch->stored_bytes;
        payload_bytes += ch->payload_bytes;
        if (s == CDVR_OK && !whole)
            for (size_t i = 0; i < count; i++)
                cdvr_brick_place((uint8_t *)cdvr_volume_frame(vol, i), info->dims, frames[i], lo, bd);
        free(stored);
        free(payload);
        free(brick);
        stored = payload = brick = NULL;
    }
    free(stored);
    free(payload);
    free(brick);
    free(frames);
    if (s != CDVR_OK) {
        cdvr_volume_free(vol);
        return s;
    }
    memcpy(vol->spacing, info->spacing, sizeof vol->spacing);
    memcpy(vol->origin, info->origin, sizeof vol->origin);
    memcpy(vol->direction, info->direction, sizeof vol->direction);
    vol->window[0] = info->qlo; /* the codes 0..255 stand for the store's value window */
    vol->window[1] = info->qhi;
    memset(share, 0, sizeof *share);
    share->read_ms = read_ms / (double)count;
    share->unzip_ms = unzip_ms / (double)count;
    share->unzip_cpu_ms = unzip_cpu_ms / (double)count;
    share->decode_ms = decode_ms / (double)count;
    share->bytes = bytes / count;
    share->payload_bytes = payload_bytes / count;
    share->bricks_read = info->nbricks;
    *t0 = first->t0;
    *out = vol;
    return CDVR_OK;
}
