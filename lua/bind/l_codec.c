/* lua/bind/l_codec.c - the codec registry and plugins in Lua (cdvr/codec.h, cdvr/plugin.h):
 *
 *   cdvr.codecs()            every registered codec: {name=, id=, description=, cl_mode=
 *                            "decode"|"fetch"|"none", variant= (default variant name),
 *                            plugin= (file, plugin codecs only), params={{key=, default=,
 *                            description=}, ...}}, built-ins first, then in load order
 *   cdvr.plugin.load(path)   loads a plugin and registers its codecs and formats; returns the
 *                            name of its (first) codec, or of its first format, and
 *                            {codecs={names}, formats={names}}
 *   cdvr.codec_chunk(codec, params [, dims])
 *                            what one chunk of those parameters holds: {timesteps=,
 *                            payload_bytes= (0 when data dependent), bound_bytes=, variant=}
 *                            (dims default {4, 4, 4}); unknown or bad parameters raise
 */
#include <string.h>

#include "cdvr/codec.h"
#include "cdvr/plugin.h"
#include "lcdvr.h"

static const char *cl_mode_name(cdvr_codec_cl_mode mode)
{
    switch (mode) {
    case CDVR_CODEC_CL_DECODE:
        return "decode";
    case CDVR_CODEC_CL_FETCH:
        return "fetch";
    default:
        return "none";
    }
}

static void set_string(lua_State *L, const char *key, const char *value)
{
    lua_pushstring(L, value ? value : "");
    lua_setfield(L, -2, key);
}

/* Pushes {{key=, default=, description=}, ...} for the codec's documented parameters. */
static void push_params(lua_State *L, const cdvr_codec *codec)
{
    lua_newtable(L);                                 /* params */
    int n = 0;
    for (const cdvr_codec_param_doc *d = codec->params; d && d->key; d++) {
        lua_createtable(L, 0, 3);                    /* params, param */
        set_string(L, "key", d->key);
        set_string(L, "default", d->def);
        set_string(L, "description", d->description);
        lua_rawseti(L, -2, ++n);                     /* params */
    }
}

static void push_codec(lua_State *L, const cdvr_codec *codec)
{
    lua_createtable(L, 0, 8);                        /* codec */
    set_string(L, "name", codec->name);
    lua_pushinteger(L, (lua_Integer)codec->id);
    lua_setfield(L, -2, "id");
    set_string(L, "description", codec->description);
    set_string(L, "cl_mode", cl_mode_name(codec->cl_mode));
    cdvr_codec_params defaults;
    memset(&defaults, 0, sizeof defaults);
    codec->params_default(&defaults);
    char variant[CDVR_VARIANT_NAME_MAX] = "";
    codec->variant_name(&defaults, variant, sizeof variant);
    set_string(L, "variant", variant);
    const char *file = cdvr_plugin_file(codec);
    if (file)
        set_string(L, "plugin", file);
    push_params(L, codec);
    lua_setfield(L, -2, "params");                   /* codec */
}

static int l_codecs(lua_State *L)
{
    size_t n = cdvr_codec_count();
    lua_createtable(L, (int)n, 0);                   /* list */
    for (size_t i = 0; i < n; i++) {
        const cdvr_codec *codec = cdvr_codec_at(i);
        if (!codec)
            break;
        push_codec(L, codec);
        lua_rawseti(L, -2, (lua_Integer)i + 1);
    }
    return 1;
}

static int l_codec_chunk(lua_State *L)
{
    const char *name = luaL_checkstring(L, 1);
    const cdvr_codec *codec = cdvr_codec_find(name);
    if (!codec)
        return luaL_error(L, "cdvr.codec_chunk: unknown codec '%s' (see cdvr.codecs())", name);
    cdvr_codec_params params;
    lcdvr_parse_params(L, 2, codec, &params, "cdvr.codec_chunk");
    double d[3] = {4, 4, 4};
    if (!lua_isnoneornil(L, 3)) {
        luaL_checktype(L, 3, LUA_TTABLE);
        for (int i = 0; i < 3; i++) {
            lua_geti(L, 3, i + 1);
            int isnum = 0;
            d[i] = lua_tonumberx(L, -1, &isnum);
            if (!isnum)
                luaL_error(L, "cdvr.codec_chunk: dims[%d]: number expected, got %s", i + 1,
                           luaL_typename(L, -1));
            lua_pop(L, 1);
            if (!(d[i] >= 1 && d[i] <= 1e9 && d[i] == (double)(size_t)d[i]))
                luaL_error(L, "cdvr.codec_chunk: dims[%d] = %f: integers 1..1e9 expected", i + 1,
                           d[i]);
        }
    }
    size_t dims[3] = {(size_t)d[0], (size_t)d[1], (size_t)d[2]};
    cdvr_codec_shape shape;
    cdvr_error err;
    if (cdvr_codec_shape_of(codec, &params, dims, &shape, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    char variant[CDVR_VARIANT_NAME_MAX] = "";
    codec->variant_name(&params, variant, sizeof variant);
    lua_createtable(L, 0, 4);
    lua_pushinteger(L, (lua_Integer)shape.timesteps);
    lua_setfield(L, -2, "timesteps");
    lua_pushinteger(L, (lua_Integer)shape.payload_bytes);
    lua_setfield(L, -2, "payload_bytes");
    lua_pushinteger(L, (lua_Integer)shape.bound_bytes);
    lua_setfield(L, -2, "bound_bytes");
    set_string(L, "variant", variant);
    return 1;
}

/* t[i] = name for the table on top. */
static void set_index(lua_State *L, const char *name, int i)
{
    lua_pushstring(L, name);
    lua_seti(L, -2, i);
}

/* Returns the name of the plugin's first codec, or of its first format for a plugin of formats
 * only, then a list of all it registered: {codecs={names}, formats={names}}. */
static int l_plugin_load(lua_State *L)
{
    const char *path = luaL_checkstring(L, 1);
    const cdvr_plugin_info *info;
    cdvr_error err;
    if (cdvr_plugin_load_info(path, &info, &err) != CDVR_OK)
        return lcdvr_raise(L, &err);
    lua_newtable(L);                                   /* what */
    lua_newtable(L);                                   /* what, codecs */
    int n = 0;
    if (info->codec)
        set_index(L, info->codec->name, ++n);
    for (size_t i = 0; info->codecs && info->codecs[i]; i++)
        set_index(L, info->codecs[i]->name, ++n);
    lua_setfield(L, -2, "codecs");                     /* what */
    lua_newtable(L);                                   /* what, formats */
    int m = 0;
    for (size_t i = 0; info->formats && info->formats[i]; i++)
        set_index(L, info->formats[i]->name, ++m);
    lua_setfield(L, -2, "formats");                    /* what */
    lua_pushstring(L, info->codec ? info->codec->name
                      : info->codecs && info->codecs[0] ? info->codecs[0]->name
                      : info->formats[0]->name);       /* what, name */
    lua_insert(L, -2);                                 /* name, what */
    return 2;
}

int lcdvr_open_codec(lua_State *L)
{
    lua_pushcfunction(L, l_codecs);
    lua_setfield(L, -2, "codecs");
    lua_pushcfunction(L, l_codec_chunk);
    lua_setfield(L, -2, "codec_chunk");
    lua_newtable(L);                                 /* cdvr, plugin */
    lua_pushcfunction(L, l_plugin_load);
    lua_setfield(L, -2, "load");
    lcdvr_name_table(L, -1, "cdvr.plugin");
    lua_setfield(L, -2, "plugin");                   /* cdvr */
    lcdvr_help_add(L, "cdvr.codecs()",
                   "list of registered codecs: {name, id, description, cl_mode, variant, plugin, "
                   "params={{key, default, description}}}");
    lcdvr_help_add(L, "cdvr.codec_chunk(codec, params [, dims])",
                   "one chunk of a codec with these parameters: {timesteps=, payload_bytes=, "
                   "bound_bytes=, variant=} (dims default {4, 4, 4})");
    lcdvr_help_add(L, "cdvr.plugin.load(path)",
                   "load a plugin (.so) and register its codecs and file formats; returns the "
                   "name of its codec (or of its format, for a format plugin) and "
                   "{codecs={...}, formats={...}} (CDVR_PLUGIN_PATH: loaded at start-up)");
    return 0;
}
