/* core/render/gl/window.c - the GLFW window (cdvr/gl.h): shows 8-bit images given to it and
 * queues mouse and key input. It renders nothing itself; the scene is rendered by the ray caster
 * or the slicer and handed over as pixels. Its GL context is current only inside
 * cdvr_window_show / cdvr_window_read, so the slicer's EGL context can be made current between. */
#include "cdvr/gl.h"

#define GL_GLEXT_PROTOTYPES 1
#define GLFW_INCLUDE_GLEXT
#include <GLFW/glfw3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define QUEUE_MAX 64

struct cdvr_window {
    GLFWwindow *glfw;
    cdvr_window_event queue[QUEUE_MAX];
    size_t queued;
    int dragging, have_cursor;
    double last_x, last_y;   /* the last cursor position seen */
    uint8_t *shown;       /* what the last show displayed, read back from the framebuffer */
    int shown_w, shown_h;
};

/* GLFW is process-wide: initialised on first use and never terminated (an X server with no other
 * client resets when its last connection closes, and a window opened during the reset fails;
 * glfwTerminate would also unload the GL driver, whose allocations at exit then cannot be told
 * from cdvr's). The process's exit closes the connection. Its error callback keeps the last
 * message. */
static struct {
    int initialised;
    char last_error[256];
} glfw_context;

static void on_glfw_error(int code, const char *description)
{
    snprintf(glfw_context.last_error, sizeof glfw_context.last_error, "%s (GLFW error 0x%x)",
             description ? description : "?", (unsigned)code);
}

static int glfw_start(cdvr_error *err)
{
    if (glfw_context.initialised)
        return 1;
    glfwSetErrorCallback(on_glfw_error);
    glfw_context.last_error[0] = '\0';
    if (glfwInit()) {
        glfw_context.initialised = 1;
        return 1;
    }
    cdvr_error_set(err, CDVR_ERR_UNSUPPORTED, "window: no display (%s)",
                   glfw_context.last_error[0] ? glfw_context.last_error : "glfwInit failed");
    return 0;
}

int cdvr_window_available(cdvr_error *err)
{
    return glfw_start(err);
}

static void push_event(cdvr_window *w, const cdvr_window_event *ev)
{
    if (ev->type == CDVR_WINDOW_DRAG && w->queued > 0 &&
        w->queue[w->queued - 1].type == CDVR_WINDOW_DRAG) { /* coalesce motion */
        w->queue[w->queued - 1].dx += ev->dx;
        w->queue[w->queued - 1].dy += ev->dy;
        return;
    }
    if (w->queued < QUEUE_MAX)
        w->queue[w->queued++] = *ev;
}

static void on_cursor(GLFWwindow *glfw, double x, double y)
{
    cdvr_window *w = glfwGetWindowUserPointer(glfw);
    if (w->dragging && w->have_cursor) {
        cdvr_window_event ev = {CDVR_WINDOW_DRAG, x - w->last_x, y - w->last_y, 0};
        push_event(w, &ev);
    }
    w->last_x = x;
    w->last_y = y;
    w->have_cursor = 1;
}

static void on_button(GLFWwindow *glfw, int button, int action, int mods)
{
    (void)mods;
    cdvr_window *w = glfwGetWindowUserPointer(glfw);
    /* the position at the press is the last cursor event's: glfwGetCursorPos would ask the
     * server for where the pointer is now, after motion still queued for us */
    if (button == GLFW_MOUSE_BUTTON_LEFT)
        w->dragging = action == GLFW_PRESS;
}

static void on_scroll(GLFWwindow *glfw, double dx, double dy)
{
    (void)dx;
    cdvr_window *w = glfwGetWindowUserPointer(glfw);
    cdvr_window_event ev = {CDVR_WINDOW_SCROLL, 0.0, dy, 0};
    push_event(w, &ev);
}

static void on_key(GLFWwindow *glfw, int key, int scancode, int action, int mods)
{
    (void)scancode;
    (void)mods;
    if (action != GLFW_PRESS && action != GLFW_REPEAT)
        return;
    static const int keys[][2] = {{GLFW_KEY_LEFT, CDVR_KEY_LEFT},   {GLFW_KEY_RIGHT, CDVR_KEY_RIGHT},
                                  {GLFW_KEY_UP, CDVR_KEY_UP},       {GLFW_KEY_DOWN, CDVR_KEY_DOWN},
                                  {GLFW_KEY_SPACE, CDVR_KEY_SPACE}, {GLFW_KEY_HOME, CDVR_KEY_HOME},
                                  {GLFW_KEY_END, CDVR_KEY_END},     {GLFW_KEY_ESCAPE, CDVR_KEY_ESCAPE},
                                  {GLFW_KEY_Q, CDVR_KEY_Q},         {GLFW_KEY_R, CDVR_KEY_R}};
    int code = 0;
    for (size_t i = 0; i < sizeof keys / sizeof keys[0] && !code; i++)
        if (keys[i][0] == key)
            code = keys[i][1];
    if (!code && key >= GLFW_KEY_A && key <= GLFW_KEY_Z) /* other letters: lower case */
        code = 'a' + (key - GLFW_KEY_A);
    if (code) {
        cdvr_window *w = glfwGetWindowUserPointer(glfw);
        cdvr_window_event ev = {CDVR_WINDOW_KEY, 0.0, 0.0, code};
        push_event(w, &ev);
    }
}

static void on_resize(GLFWwindow *glfw, int width, int height)
{
    (void)width;
    (void)height;
    cdvr_window *w = glfwGetWindowUserPointer(glfw);
    cdvr_window_event ev = {CDVR_WINDOW_RESIZE, 0.0, 0.0, 0};
    push_event(w, &ev);
}

cdvr_status cdvr_window_open(int width, int height, const char *title, cdvr_window **out,
                             cdvr_error *err)
{
    *out = NULL;
    if (width <= 0 || height <= 0 || width > 16384 || height > 16384)
        return cdvr_error_set(err, CDVR_ERR_ARG, "window: size %dx%d outside 1..16384", width,
                              height);
    cdvr_window *w = calloc(1, sizeof *w);
    if (!w)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "window: no memory");
    if (!glfw_start(err)) {
        free(w);
        return err ? err->status : CDVR_ERR_UNSUPPORTED;
    }
    glfwDefaultWindowHints();
    glfwWindowHint(GLFW_DOUBLEBUFFER, GLFW_TRUE);
    w->glfw = glfwCreateWindow(width, height, title ? title : "cdvr", NULL, NULL);
    if (!w->glfw) {
        cdvr_error_set(err, CDVR_ERR_DEVICE, "window: cannot open a %dx%d window: %s", width,
                       height, glfw_context.last_error[0] ? glfw_context.last_error : "?");
        free(w);
        return CDVR_ERR_DEVICE;
    }
    glfwSetWindowUserPointer(w->glfw, w);
    glfwSetCursorPosCallback(w->glfw, on_cursor);
    glfwSetMouseButtonCallback(w->glfw, on_button);
    glfwSetScrollCallback(w->glfw, on_scroll);
    glfwSetKeyCallback(w->glfw, on_key);
    glfwSetFramebufferSizeCallback(w->glfw, on_resize);
    *out = w;
    return CDVR_OK;
}

void cdvr_window_close(cdvr_window *w)
{
    if (!w)
        return;
    if (w->glfw)
        glfwDestroyWindow(w->glfw);
    free(w->shown);
    free(w);
}

size_t cdvr_window_poll(cdvr_window *w, cdvr_window_event *ev, size_t max)
{
    glfwPollEvents();
    size_t n = w->queued < max ? w->queued : max;
    memcpy(ev, w->queue, n * sizeof *ev);
    memmove(w->queue, w->queue + n, (w->queued - n) * sizeof *ev);
    w->queued -= n;
    return n;
}

int cdvr_window_should_close(const cdvr_window *w)
{
    return glfwWindowShouldClose(w->glfw);
}

void cdvr_window_size(const cdvr_window *w, int *width, int *height)
{
    glfwGetFramebufferSize(w->glfw, width, height);
}

/* Copies the framebuffer (bottom-up) into w->shown, top row first. */
static cdvr_status read_framebuffer(cdvr_window *w, int width, int height, cdvr_error *err)
{
    size_t row = (size_t)width * 4;
    uint8_t *buf = malloc(row * (size_t)height);
    if (!buf)
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "window: no memory to read %dx%d pixels",
                              width, height);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    glReadBuffer(GL_BACK);
    glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, buf);
    free(w->shown);
    w->shown = malloc(row * (size_t)height);
    if (!w->shown) {
        free(buf);
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "window: no memory to read %dx%d pixels",
                              width, height);
    }
    for (int y = 0; y < height; y++)
        memcpy(w->shown + (size_t)y * row, buf + (size_t)(height - 1 - y) * row, row);
    free(buf);
    w->shown_w = width;
    w->shown_h = height;
    return CDVR_OK;
}

cdvr_status cdvr_window_show(cdvr_window *w, const uint8_t *rgba, int width, int height,
                             cdvr_error *err)
{
    int fb_w, fb_h;
    glfwGetFramebufferSize(w->glfw, &fb_w, &fb_h);
    if (fb_w <= 0 || fb_h <= 0)
        return CDVR_OK; /* minimised */
    glfwMakeContextCurrent(w->glfw);
    glViewport(0, 0, fb_w, fb_h);
    glClearColor(0.0f, 0.0f, 0.0f, 1.0f);
    glClear(GL_COLOR_BUFFER_BIT);
    /* row 0 of the image at the top: start at the top-left corner and draw downwards */
    glPixelStorei(GL_UNPACK_ALIGNMENT, 1);
    glWindowPos2i(0, fb_h);
    glPixelZoom(1.0f, -1.0f);
    glDrawPixels(width, height, GL_RGBA, GL_UNSIGNED_BYTE, rgba);
    glPixelZoom(1.0f, 1.0f);
    cdvr_status st = read_framebuffer(w, fb_w, fb_h, err);
    GLenum gl_err = glGetError();
    if (st == CDVR_OK && gl_err != GL_NO_ERROR)
        st = cdvr_error_set(err, CDVR_ERR_DEVICE, "window: GL error 0x%x while drawing",
                            (unsigned)gl_err);
    glfwSwapBuffers(w->glfw);
    glfwMakeContextCurrent(NULL);
    return st;
}

const uint8_t *cdvr_window_pixels(const cdvr_window *w, int *width, int *height)
{
    *width = w->shown_w;
    *height = w->shown_h;
    return w->shown;
}
