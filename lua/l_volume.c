/* lua/l_volume.c - cdvr.Volume: volumes and series in Lua (cdvr.load, v:dims(), ...). */
#include "lcdvr.h"

typedef struct lvolume {
    cdvr_volume *vol; /* NULL once closed */
} lvolume;

static lvolume *tolvolume(lua_State *L, int idx)
{
    return (lvolume *)luaL_checkudata(L, idx, LCDVR_VOLUME);
}

cdvr_volume *lcdvr_checkvolume(lua_State *L, int idx)
{
    lvolume *ud = tolvolume(L, idx);
    if (!ud->vol)
        luaL_error(L, "attempt to use a closed volume");
    return ud->vol;
}

void lcdvr_pushvolume(lua_State *L, cdvr_volume *vol)
{
    lvolume *ud = (lvolume *)lua_newuserdatauv(L, sizeof *ud, 0);
    ud->vol = vol;
    luaL_setmetatable(L, LCDVR_VOLUME);
}

static int volume_gc(lua_State *L)
{
    lvolume *ud = tolvolume(L, 1);
    cdvr_volume_free(ud->vol);
    ud->vol = NULL;
    return 0;
}

static int volume_tostring(lua_State *L)
{
    lvolume *ud = tolvolume(L, 1);
    if (!ud->vol) {
        lua_pushliteral(L, "cdvr.Volume (closed)");
        return 1;
    }
    const cdvr_volume *v = ud->vol;
    lua_pushfstring(L, "cdvr.Volume %dx%dx%d x %d %s (%p)", (int)v->dims[0], (int)v->dims[1],
                    (int)v->dims[2], (int)v->timesteps, cdvr_type_name(v->type), (void *)ud);
    return 1;
}

static int volume_dims(lua_State *L)
{
    const cdvr_volume *v = lcdvr_checkvolume(L, 1);
    for (int i = 0; i < 3; i++)
        lua_pushinteger(L, (lua_Integer)v->dims[i]);
    return 3;
}

static int volume_type(lua_State *L)
{
    lua_pushstring(L, cdvr_type_name(lcdvr_checkvolume(L, 1)->type));
    return 1;
}

static int volume_timesteps(lua_State *L)
{
    lua_pushinteger(L, (lua_Integer)lcdvr_checkvolume(L, 1)->timesteps);
    return 1;
}

static int volume_range(lua_State *L)
{
    double lo, hi;
    cdvr_volume_range(lcdvr_checkvolume(L, 1), &lo, &hi);
    lua_pushnumber(L, lo);
    lua_pushnumber(L, hi);
    return 2;
}

static int volume_get(lua_State *L)
{
    const cdvr_volume *v = lcdvr_checkvolume(L, 1);
    lua_Integer c[4];
    for (int i = 0; i < 3; i++) {
        c[i] = luaL_checkinteger(L, i + 2);
        luaL_argcheck(L, c[i] >= 0 && (size_t)c[i] < v->dims[i], i + 2, "voxel coordinate out of range");
    }
    c[3] = luaL_optinteger(L, 5, 1);
    luaL_argcheck(L, c[3] >= 1 && (size_t)c[3] <= v->timesteps, 5, "timestep out of range");
    lua_pushnumber(L, cdvr_volume_get(v, (size_t)c[0], (size_t)c[1], (size_t)c[2], (size_t)c[3] - 1));
    return 1;
}

static const luaL_Reg volume_methods[] = {
    {"dims", volume_dims},   {"type", volume_type}, {"timesteps", volume_timesteps},
    {"range", volume_range}, {"get", volume_get},   {NULL, NULL}};

static const luaL_Reg volume_meta[] = {
    {"__gc", volume_gc}, {"__close", volume_gc}, {"__tostring", volume_tostring}, {NULL, NULL}};

int lcdvr_open_volume(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_VOLUME, volume_methods, volume_meta);
    lcdvr_help_add(L, "v:dims()", "x, y, z dimensions of a volume");
    lcdvr_help_add(L, "v:type()", "voxel type: u8, u16, i16 or f32");
    lcdvr_help_add(L, "v:timesteps()", "number of timesteps");
    lcdvr_help_add(L, "v:range()", "min, max over finite values");
    lcdvr_help_add(L, "v:get(x, y, z [, t])", "voxel value (x, y, z from 0; t from 1)");
    return 0;
}
