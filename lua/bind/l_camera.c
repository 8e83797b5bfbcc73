/* lua/bind/l_camera.c - cdvr.Camera: cdvr.camera{...}, cdvr.orbit_camera(volume, {...}),
 * (or a store, or a box table), cam:get(), cam:set{...}; fields readable as cam.eye, cam.fov, ... */
#include "lcdvr.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>
#include <string.h>

static const double kPi = 3.14159265358979323846;

cdvr_camera *lcdvr_checkcamera(lua_State *L, int idx)
{
    return (cdvr_camera *)luaL_checkudata(L, idx, LCDVR_CAMERA);
}

cdvr_camera *lcdvr_pushcamera(lua_State *L, const cdvr_camera *cam)
{
    cdvr_camera *ud = (cdvr_camera *)lua_newuserdatauv(L, sizeof *ud, 0);
    *ud = *cam;
    luaL_setmetatable(L, LCDVR_CAMERA);
    return ud;
}

static int size_field(lua_State *L, int idx, const char *key, int def)
{
    lua_Integer n = lcdvr_optintegerfield(L, idx, key, def);
    if (n < 1 || n > 65536)
        lcdvr_error(L, "option '%s' must be 1..65536, got %I", key, (LUAI_UACINT)n);
    return (int)n;
}

/* Copies the fields present in the table at idx into cam (absent fields keep their value). */
#define CAMERA_KEYS "eye", "center", "up", "fov", "width", "height", "orthographic", "ortho_height"

static void apply_fields(lua_State *L, int idx, cdvr_camera *cam)
{
    lcdvr_numberarrayfield(L, idx, "eye", cam->eye, 3);
    lcdvr_numberarrayfield(L, idx, "center", cam->center, 3);
    lcdvr_numberarrayfield(L, idx, "up", cam->up, 3);
    cam->fov = lcdvr_optnumberfield(L, idx, "fov", cam->fov);
    cam->width = size_field(L, idx, "width", cam->width);
    cam->height = size_field(L, idx, "height", cam->height);
    cam->orthographic = lcdvr_optbooleanfield(L, idx, "orthographic", cam->orthographic);
    cam->ortho_height = lcdvr_optnumberfield(L, idx, "ortho_height", cam->ortho_height);
}

static void check_valid(lua_State *L, const cdvr_camera *cam)
{
    cdvr_error err;
    if (cdvr_camera_validate(cam, &err) != CDVR_OK)
        lcdvr_raise(L, &err);
}

static cdvr_camera default_camera(void)
{
    cdvr_camera cam = {{0, 0, 0}, {0, 0, 0}, {0, 0, 1}, 30.0, 512, 512, 0, 0.0};
    return cam;
}

/* cdvr.camera(path.lua): loads the data file (lcdvr_load_data: it returns the field table) and
 * builds from that; an unreadable or malformed file raises, naming the file and the reason. */
static void camera_from_file(lua_State *L, const char *path)
{
    if (lcdvr_load_data(L, path) != LUA_OK)
        luaL_error(L, "cdvr.camera: %s", lua_tostring(L, -1));
    if (!lua_istable(L, -1))
        luaL_error(L, "%s: camera file must return a table, got %s", path, luaL_typename(L, -1));
    lua_replace(L, 1); /* fields table in place of the path */
    lua_settop(L, 1);
}

static int l_camera(lua_State *L)
{
    if (lua_type(L, 1) == LUA_TSTRING)
        camera_from_file(L, lua_tostring(L, 1));
    luaL_checktype(L, 1, LUA_TTABLE);
    static const char *const keys[] = {CAMERA_KEYS, NULL};
    lcdvr_checkoptions(L, 1, "cdvr.camera", keys);
    cdvr_camera cam = default_camera();
    lua_getfield(L, 1, "eye");
    if (lua_isnil(L, -1))
        return luaL_error(L, "cdvr.camera: eye={x, y, z} is required");
    lua_pop(L, 1);
    apply_fields(L, 1, &cam);
    if (cam.orthographic && cam.ortho_height == 0.0)
        return luaL_error(L, "cdvr.camera: orthographic needs ortho_height (world units)");
    check_valid(L, &cam);
    lcdvr_pushcamera(L, &cam);
    return 1;
}

static void push_vec3(lua_State *L, const double v[3])
{
    lua_createtable(L, 3, 0);
    for (int i = 0; i < 3; i++) {
        lua_pushnumber(L, v[i]);
        lua_rawseti(L, -2, i + 1);
    }
}

/* Pushes field `key` of cam; returns 0 if there is no such field. */
static int push_field(lua_State *L, const cdvr_camera *cam, const char *key)
{
    if (strcmp(key, "eye") == 0)
        push_vec3(L, cam->eye);
    else if (strcmp(key, "center") == 0)
        push_vec3(L, cam->center);
    else if (strcmp(key, "up") == 0)
        push_vec3(L, cam->up);
    else if (strcmp(key, "fov") == 0)
        lua_pushnumber(L, cam->fov);
    else if (strcmp(key, "width") == 0)
        lua_pushinteger(L, cam->width);
    else if (strcmp(key, "height") == 0)
        lua_pushinteger(L, cam->height);
    else if (strcmp(key, "orthographic") == 0)
        lua_pushboolean(L, cam->orthographic);
    else if (strcmp(key, "ortho_height") == 0)
        lua_pushnumber(L, cam->ortho_height);
    else
        return 0;
    return 1;
}

static const char *const camera_fields[] = {"eye",    "center",       "up",           "fov",
                                            "width",  "height",       "orthographic", "ortho_height",
                                            NULL};

static int camera_get(lua_State *L)
{
    const cdvr_camera *cam = lcdvr_checkcamera(L, 1);
    lua_createtable(L, 0, 8);
    for (int i = 0; camera_fields[i]; i++) {
        push_field(L, cam, camera_fields[i]);
        lua_setfield(L, -2, camera_fields[i]);
    }
    return 1;
}

static int camera_set(lua_State *L)
{
    cdvr_camera *cam = lcdvr_checkcamera(L, 1);
    luaL_checktype(L, 2, LUA_TTABLE);
    static const char *const keys[] = {CAMERA_KEYS, NULL};
    lcdvr_checkoptions(L, 2, "cam:set", keys);
    cdvr_camera changed = *cam;
    apply_fields(L, 2, &changed);
    check_valid(L, &changed);
    *cam = changed;
    lua_settop(L, 1);
    return 1;
}

static void write_vec3(FILE *f, const char *key, const double v[3])
{
    fprintf(f, "  %s = {%.17g, %.17g, %.17g},\n", key, v[0], v[1], v[2]);
}

/* Writes the camera as a Lua file returning its fields; returns 0 or -1 (errno set). */
static int write_camera(FILE *f, const void *obj)
{
    const cdvr_camera *cam = obj;
    fprintf(f, "-- cdvr camera: cdvr.camera(dofile(path)) or cdvr.camera(path)\nreturn {\n");
    write_vec3(f, "eye", cam->eye);
    write_vec3(f, "center", cam->center);
    write_vec3(f, "up", cam->up);
    fprintf(f, "  fov = %.17g, width = %d, height = %d,\n", cam->fov, cam->width, cam->height);
    fprintf(f, "  orthographic = %s, ortho_height = %.17g,\n}\n",
            cam->orthographic ? "true" : "false", cam->ortho_height);
    return ferror(f) ? -1 : 0;
}

/* cam:save(path): temporary file then rename; true or nil, message. */
static int camera_save(lua_State *L)
{
    const cdvr_camera *cam = lcdvr_checkcamera(L, 1);
    return lcdvr_save_file(L, luaL_checkstring(L, 2), write_camera, cam);
}

/* __index: methods first, then the camera's fields. */
static int camera_index(lua_State *L)
{
    const cdvr_camera *cam = lcdvr_checkcamera(L, 1);
    lua_pushvalue(L, 2);
    if (lua_rawget(L, lua_upvalueindex(1)) != LUA_TNIL)
        return 1;
    const char *key = lua_tostring(L, 2);
    if (key && push_field(L, cam, key))
        return 1;
    lua_pushnil(L);
    return 1;
}

static int camera_tostring(lua_State *L)
{
    const cdvr_camera *cam = lcdvr_checkcamera(L, 1);
    lua_pushfstring(L, "cdvr.Camera %dx%d eye (%f, %f, %f) center (%f, %f, %f) (%p)",
                    cam->width, cam->height, cam->eye[0], cam->eye[1], cam->eye[2],
                    cam->center[0], cam->center[1], cam->center[2], (const void *)cam);
    return 1;
}

static int camera_gc(lua_State *L)
{
    (void)lcdvr_checkcamera(L, 1); /* plain data inside the userdata: nothing to free */
    return 0;
}

/* World bounds of the first argument: a volume or a store (its oriented box), {x, y, z} dims, or
 * {dims=, spacing=, origin=[, direction=]}. */
#define BOX_LIMIT 1e100 /* largest |box coordinate| a camera is made for */
#define ZOOM_LIMIT 1e6  /* largest zoom= (beyond, the eye meets the centre) */

static void read_box(lua_State *L, double lo[3], double hi[3])
{
    cdvr_volume box = {.spacing = {1, 1, 1}, .direction = {1, 0, 0, 0, 1, 0, 0, 0, 1}};
    double dims[3];
    if (luaL_testudata(L, 1, LCDVR_VOLUME)) {
        const cdvr_volume *v = lcdvr_volume_header(L, 1); /* geometry only */
        box = *v;
        for (int a = 0; a < 3; a++)
            dims[a] = (double)v->dims[a];
    } else if (luaL_testudata(L, 1, LCDVR_STORE)) { /* its box, as st:info() gives it */
        const cdvr_store_info *info = cdvr_store_get_info(lcdvr_checkstore(L, 1));
        for (int a = 0; a < 3; a++) {
            dims[a] = (double)info->dims[a];
            box.spacing[a] = info->spacing[a];
            box.origin[a] = info->origin[a];
        }
        memcpy(box.direction, info->direction, sizeof box.direction);
    } else {
        luaL_argexpected(L, lua_istable(L, 1), 1, "cdvr.Volume, cdvr.Store or dims table");
        if (!lcdvr_numberarrayfield(L, 1, "dims", dims, 3)) {
            if (luaL_len(L, 1) != 3)
                luaL_argerror(L, 1, "dims {x, y, z} expected");
            for (int a = 0; a < 3; a++) {
                lua_geti(L, 1, a + 1);
                int isnum;
                dims[a] = lua_tonumberx(L, -1, &isnum);
                if (!isnum)
                    luaL_argerror(L, 1, lua_pushfstring(L, "dims[%d]: number expected, got %s", a + 1,
                                                        luaL_typename(L, -1)));
                lua_pop(L, 1);
            }
        }
        lcdvr_numberarrayfield(L, 1, "spacing", box.spacing, 3);
        lcdvr_numberarrayfield(L, 1, "origin", box.origin, 3);
        lcdvr_numberarrayfield(L, 1, "direction", box.direction, 9);
    }
    for (int a = 0; a < 3; a++) {
        if (!(dims[a] >= 1 && dims[a] <= 1e15) || !isfinite(box.spacing[a]) || !isfinite(box.origin[a]))
            luaL_argerror(L, 1, "dims must be >= 1, spacing and origin finite");
        box.dims[a] = (size_t)dims[a];
    }
    for (int i = 0; i < 9; i++)
        if (!isfinite(box.direction[i]))
            luaL_argerror(L, 1, "direction must be finite");
    cdvr_volume_bounds(&box, lo, hi);
    for (int a = 0; a < 3; a++) /* a camera around it must have finite distances */
        if (!(fabs(lo[a]) <= BOX_LIMIT && fabs(hi[a]) <= BOX_LIMIT))
            lcdvr_error(L, "the box [%f, %f] x [%f, %f] x [%f, %f] (spacing %f, %f, %f, origin "
                           "%f, %f, %f) is not finite or too large for a camera (|coordinates| "
                           "<= 1e100)", lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], box.spacing[0],
                        box.spacing[1], box.spacing[2], box.origin[0], box.origin[1],
                        box.origin[2]);
}

/* Distance at which a sphere of radius r fills the narrower of the two view angles. */
static double fit_distance(double r, double fov_deg, double aspect)
{
    double half_v = 0.5 * fov_deg * kPi / 180.0;
    double half_h = atan(aspect * tan(half_v));
    return r / sin(fmin(half_v, half_h));
}

#define FRAME_FILL 0.9 /* the box's projection spans this fraction of the narrower side */

/* Largest |projected coordinate| / tan(half angle) over the 8 corners of [lo, hi], horizontal
 * and vertical: 1 means a corner on the image's edge (infinite when a corner is behind the
 * eye). */
static double corner_fill(const cdvr_camera *cam, const double lo[3], const double hi[3])
{
    double f[3], u[3], r[3];
    cdvr_camera_basis(cam, f, u, r);
    double tan_v = tan(0.5 * cam->fov * kPi / 180.0);
    double tan_h = tan_v * (double)cam->width / cam->height, fill = 0.0;
    for (int c = 0; c < 8; c++) {
        double p[3] = {c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]};
        double d[3] = {p[0] - cam->eye[0], p[1] - cam->eye[1], p[2] - cam->eye[2]};
        double z = d[0] * f[0] + d[1] * f[1] + d[2] * f[2];
        if (cam->orthographic)
            z = 1.0;
        else if (z <= 1e-12)
            return INFINITY;
        double x = (d[0] * r[0] + d[1] * r[1] + d[2] * r[2]) / z;
        double y = (d[0] * u[0] + d[1] * u[1] + d[2] * u[2]) / z;
        fill = fmax(fill, fmax(fabs(x) / tan_h, fabs(y) / tan_v));
    }
    return fill;
}

/* The distance at which the box's corners fill FRAME_FILL of the view (bisection: the fill
 * falls as the eye moves away along the orbit's direction). */
static double frame_distance(cdvr_camera cam, const double lo[3], const double hi[3],
                             const double center[3], double radius, double azimuth,
                             double elevation)
{
    double near = 0.0, far = fit_distance(radius, cam.fov, (double)cam.width / cam.height) * 4.0;
    for (int i = 0; i < 64; i++) {
        double mid = 0.5 * (near + far);
        cdvr_camera_orbit(&cam, center, cam.up, mid, azimuth, elevation);
        if (corner_fill(&cam, lo, hi) > FRAME_FILL)
            near = mid;
        else
            far = mid;
    }
    return far;
}

static int l_orbit_camera(lua_State *L)
{
    double lo[3], hi[3], center[3], radius2 = 0.0;
    read_box(L, lo, hi);
    lua_settop(L, 2);
    if (lua_isnil(L, 2)) {
        lua_newtable(L);
        lua_replace(L, 2);
    }
    luaL_checktype(L, 2, LUA_TTABLE);
    static const char *const keys[] = {CAMERA_KEYS, "azimuth", "elevation", "distance", "zoom",
                                       NULL};
    lcdvr_checkoptions(L, 2, "cdvr.orbit_camera", keys);
    for (int a = 0; a < 3; a++) {
        center[a] = 0.5 * (lo[a] + hi[a]);
        radius2 += 0.25 * (hi[a] - lo[a]) * (hi[a] - lo[a]);
    }
    double radius = fmax(sqrt(radius2), 0.5);
    cdvr_camera cam = default_camera();
    apply_fields(L, 2, &cam);
    double aspect = (double)cam.width / cam.height;
    if (!(cam.fov > 0.0 && cam.fov < 180.0))
        return luaL_error(L, "cdvr.orbit_camera: fov %f outside (0, 180)", cam.fov);
    double azimuth = lcdvr_optnumberfield(L, 2, "azimuth", 0.0);
    double elevation = lcdvr_optnumberfield(L, 2, "elevation", 0.0);
    double zoom = lcdvr_optnumberfield(L, 2, "zoom", 1.0);
    if (!(zoom > 0.0 && zoom <= ZOOM_LIMIT))
        return luaL_error(L, "cdvr.orbit_camera: option 'zoom' = %f must be in (0, 1e6]", zoom);
    if (!isfinite(azimuth) || !isfinite(elevation))
        return luaL_error(L, "cdvr.orbit_camera: options 'azimuth' = %f and 'elevation' = %f "
                             "must be finite", azimuth, elevation);
    lua_getfield(L, 2, "distance");
    int given = !lua_isnil(L, -1);
    lua_pop(L, 1);
    double distance = given ? lcdvr_optnumberfield(L, 2, "distance", 1.0)
                    : cam.orthographic ? fit_distance(radius, cam.fov, aspect)
                    : frame_distance(cam, lo, hi, center, radius, azimuth, elevation) / zoom;
    if (!(distance > 0.0) || !isfinite(distance))
        return luaL_error(L, "cdvr.orbit_camera: option 'distance' = %f must be positive and finite",
                          distance);
    cdvr_camera_orbit(&cam, center, cam.up, distance, azimuth, elevation);
    if (cam.orthographic && cam.ortho_height == 0.0) { /* the corners at FRAME_FILL too */
        cam.ortho_height = 2.0;
        double fill = corner_fill(&cam, lo, hi); /* relative to half-height 1, tan_v 1 */
        double tan_v = tan(0.5 * cam.fov * kPi / 180.0);
        cam.ortho_height = 2.0 * fill * tan_v / FRAME_FILL / zoom;
        if (!(cam.ortho_height > 0.0))
            cam.ortho_height = 2.0 * radius / fmin(1.0, aspect);
    }
    check_valid(L, &cam);
    lcdvr_pushcamera(L, &cam);
    return 1;
}

static const luaL_Reg camera_methods[] = {
    {"get", camera_get}, {"set", camera_set}, {"save", camera_save}, {NULL, NULL}};

static const luaL_Reg camera_meta[] = {
    {"__gc", camera_gc}, {"__close", camera_gc}, {"__tostring", camera_tostring}, {NULL, NULL}};

static const luaL_Reg camera_funcs[] = {
    {"camera", l_camera}, {"orbit_camera", l_orbit_camera}, {NULL, NULL}};

int lcdvr_open_camera(lua_State *L)
{
    lcdvr_newclass(L, LCDVR_CAMERA, camera_methods, camera_meta);
    luaL_getmetatable(L, LCDVR_CAMERA);  /* mt */
    lua_getfield(L, -1, "__index");      /* mt, methods */
    lua_pushcclosure(L, camera_index, 1); /* mt, index */
    lua_setfield(L, -2, "__index");
    lua_pop(L, 1);
    lcdvr_setfuncs(L, camera_funcs);
    lcdvr_help_add(L, "cdvr.camera{eye=, center=, up=, fov=, width=, height=, orthographic=, ortho_height=}",
                   "pinhole camera (defaults center {0,0,0}, up {0,0,1}, fov 30, 512x512)");
    lcdvr_help_add(L, "cdvr.orbit_camera(volume | store | dims, {azimuth=, elevation=, distance=, zoom=, fov=, width=, height=, up=})",
                   "camera around the box centre looking at it; azimuth 0 = +x side for up z; "
                   "without distance= the box's corners span 90% of the narrower image side "
                   "(zoom=2: twice as large)");
    lcdvr_help_add(L, "cam:get()", "table of the camera's fields (also readable as cam.eye, cam.fov, ...)");
    lcdvr_help_add(L, "cdvr.camera(path.lua)", "camera saved by cam:save (raises if unreadable)");
    lcdvr_help_add(L, "cam:save(path)", "write a Lua file cdvr.camera(path) reads back; true or nil, msg");
    lcdvr_help_add(L, "cam:set{...}", "change fields (validated; the camera is unchanged on error)");
    return 0;
}
