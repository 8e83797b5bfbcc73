/* core/render/gl/gl_off.c - the slicer and window entry points of a build without GL
 * (CDVR_WITH_GL=OFF or EGL/OpenGL/GLFW not found): each fails with CDVR_ERR_UNSUPPORTED and
 * says so, so callers need no #if. */
#include "cdvr/gl.h"

#include <stddef.h>

#define NO_GL "this cdvr was built without GL (CMake option CDVR_WITH_GL, needs EGL, OpenGL and GLFW)"

cdvr_status cdvr_gl_create(cdvr_gl **out, cdvr_error *err)
{
    *out = NULL;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "GL slicing: %s", NO_GL);
}

void cdvr_gl_free(cdvr_gl *gl)
{
    (void)gl;
}

const char *cdvr_gl_renderer(const cdvr_gl *gl)
{
    (void)gl;
    return "none";
}

cdvr_status cdvr_gl_slice(cdvr_gl *gl, const cdvr_volume *vol, size_t t,
                          const cdvr_render_opts *opts, int lod, cdvr_slice_stats *stats,
                          cdvr_image **out, cdvr_error *err)
{
    (void)gl, (void)vol, (void)t, (void)opts, (void)lod, (void)stats;
    *out = NULL;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "GL slicing: %s", NO_GL);
}

int cdvr_window_available(cdvr_error *err)
{
    cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "window: %s", NO_GL);
    return 0;
}

cdvr_status cdvr_window_open(int width, int height, const char *title, cdvr_window **out,
                             cdvr_error *err)
{
    (void)width, (void)height, (void)title;
    *out = NULL;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "window: %s", NO_GL);
}

void cdvr_window_close(cdvr_window *win)
{
    (void)win;
}

size_t cdvr_window_poll(cdvr_window *win, cdvr_window_event *ev, size_t max)
{
    (void)win, (void)ev, (void)max;
    return 0;
}

int cdvr_window_should_close(const cdvr_window *win)
{
    (void)win;
    return 1;
}

void cdvr_window_size(const cdvr_window *win, int *width, int *height)
{
    (void)win;
    *width = *height = 0;
}

cdvr_status cdvr_window_show(cdvr_window *win, const uint8_t *rgba, int width, int height,
                             cdvr_error *err)
{
    (void)win, (void)rgba, (void)width, (void)height;
    return cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "window: %s", NO_GL);
}

const uint8_t *cdvr_window_pixels(const cdvr_window *win, int *width, int *height)
{
    (void)win;
    *width = *height = 0;
    return NULL;
}
