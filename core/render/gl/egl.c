/* core/render/gl/egl.c - a headless OpenGL 3.3 core context through EGL (no display needed):
 * Mesa's surfaceless platform, else an EGL device (e.g. a GPU driver's headless path), else the
 * default display with a 1x1 pbuffer. */
#include "gl_internal.h"

#include <EGL/eglext.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_DEVICES 16

const char *cdvr_egl_error_name(EGLint code)
{
    switch (code) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_CURRENT_SURFACE: return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_NATIVE_PIXMAP: return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW: return "EGL_BAD_NATIVE_WINDOW";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    case EGL_BAD_SURFACE: return "EGL_BAD_SURFACE";
    case EGL_CONTEXT_LOST: return "EGL_CONTEXT_LOST";
    }
    return "EGL error";
}

static int has_extension(const char *list, const char *name)
{
    size_t n = strlen(name);
    for (const char *p = list; p && (p = strstr(p, name)) != NULL; p += n)
        if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0'))
            return 1;
    return 0;
}

/* Appends "what: reason; " to the log of failed attempts. */
static void note(char *log, size_t size, const char *what, const char *reason)
{
    size_t len = strlen(log);
    if (len < size)
        snprintf(log + len, size - len, "%s%s: %s", len ? "; " : "", what, reason);
}

/* Initialises dpy and creates the context on it; 1 on success, else notes why and returns 0.
 * A display that fails stays initialised (see cdvr_egl_close). */
static int try_display(cdvr_egl *egl, EGLDisplay dpy, const char *platform, char *log,
                       size_t logsize)
{
    if (dpy == EGL_NO_DISPLAY) {
        note(log, logsize, platform, "no display");
        return 0;
    }
    EGLint major, minor;
    if (!eglInitialize(dpy, &major, &minor)) {
        note(log, logsize, platform, cdvr_egl_error_name(eglGetError()));
        return 0;
    }
    const char *ext = eglQueryString(dpy, EGL_EXTENSIONS);
    int surfaceless = has_extension(ext, "EGL_KHR_surfaceless_context");
    if (!eglBindAPI(EGL_OPENGL_API)) {
        note(log, logsize, platform, "no desktop OpenGL (eglBindAPI)");
        return 0;
    }
    const EGLint config_attrs[] = {EGL_SURFACE_TYPE, surfaceless ? 0 : EGL_PBUFFER_BIT,
                                   EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT,
                                   EGL_RED_SIZE, 8, EGL_GREEN_SIZE, 8, EGL_BLUE_SIZE, 8,
                                   EGL_NONE};
    EGLConfig config;
    EGLint nconfig = 0;
    if (!eglChooseConfig(dpy, config_attrs, &config, 1, &nconfig) || nconfig < 1) {
        note(log, logsize, platform, "no OpenGL config");
        return 0;
    }
    const EGLint context_attrs[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
                                    EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                    EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
    EGLContext ctx = eglCreateContext(dpy, config, EGL_NO_CONTEXT, context_attrs);
    if (ctx == EGL_NO_CONTEXT) {
        note(log, logsize, platform, "no OpenGL 3.3 core context");
        return 0;
    }
    EGLSurface surface = EGL_NO_SURFACE;
    if (!surfaceless) {
        const EGLint pbuffer_attrs[] = {EGL_WIDTH, 1, EGL_HEIGHT, 1, EGL_NONE};
        surface = eglCreatePbufferSurface(dpy, config, pbuffer_attrs);
        if (surface == EGL_NO_SURFACE) {
            note(log, logsize, platform, "no pbuffer");
            eglDestroyContext(dpy, ctx);
                return 0;
        }
    }
    egl->display = dpy;
    egl->context = ctx;
    egl->surface = surface;
    snprintf(egl->renderer, sizeof egl->renderer, "EGL %s", platform);
    return 1;
}

static int try_surfaceless(cdvr_egl *egl, char *log, size_t logsize)
{
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!get_display || !has_extension(client, "EGL_MESA_platform_surfaceless")) {
        note(log, logsize, "surfaceless", "EGL_MESA_platform_surfaceless not offered");
        return 0;
    }
    return try_display(egl, get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, NULL),
                       "surfaceless", log, logsize);
}

static int try_devices(cdvr_egl *egl, char *log, size_t logsize)
{
    const char *client = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
    PFNEGLQUERYDEVICESEXTPROC query_devices =
        (PFNEGLQUERYDEVICESEXTPROC)eglGetProcAddress("eglQueryDevicesEXT");
    PFNEGLGETPLATFORMDISPLAYEXTPROC get_display =
        (PFNEGLGETPLATFORMDISPLAYEXTPROC)eglGetProcAddress("eglGetPlatformDisplayEXT");
    if (!query_devices || !get_display || !has_extension(client, "EGL_EXT_platform_device")) {
        note(log, logsize, "device", "EGL_EXT_platform_device not offered");
        return 0;
    }
    EGLDeviceEXT devices[MAX_DEVICES];
    EGLint n = 0;
    if (!query_devices(MAX_DEVICES, devices, &n) || n < 1) {
        note(log, logsize, "device", "no EGL device");
        return 0;
    }
    for (EGLint i = 0; i < n; i++)
        if (try_display(egl, get_display(EGL_PLATFORM_DEVICE_EXT, devices[i], NULL), "device",
                        log, logsize))
            return 1;
    return 0;
}

static void describe_renderer(cdvr_egl *egl)
{
    char platform[64];
    snprintf(platform, sizeof platform, "%.60s", egl->renderer);
    const char *name = (const char *)glGetString(GL_RENDERER);
    snprintf(egl->renderer, sizeof egl->renderer, "%.120s; %s", name ? name : "?", platform);
}

cdvr_status cdvr_egl_open(cdvr_egl *egl, cdvr_error *err)
{
    memset(egl, 0, sizeof *egl);
    egl->display = EGL_NO_DISPLAY;
    char log[400] = "";
    if (!try_surfaceless(egl, log, sizeof log) && !try_devices(egl, log, sizeof log) &&
        !try_display(egl, eglGetDisplay(EGL_DEFAULT_DISPLAY), "default", log, sizeof log))
        return cdvr_error_set(err, CDVR_ERR_DEVICE, "EGL: no OpenGL 3.3 context (%s)", log);
    cdvr_status st = cdvr_egl_begin(egl, err);
    if (st != CDVR_OK) {
        cdvr_egl_close(egl);
        return st;
    }
    describe_renderer(egl);
    cdvr_egl_end(egl);
    return CDVR_OK;
}

void cdvr_egl_close(cdvr_egl *egl)
{
    if (!egl || egl->display == EGL_NO_DISPLAY)
        return;
    eglMakeCurrent(egl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (egl->surface != EGL_NO_SURFACE)
        eglDestroySurface(egl->display, egl->surface);
    if (egl->context != EGL_NO_CONTEXT)
        eglDestroyContext(egl->display, egl->context);
    /* No eglTerminate: EGL displays are per-process singletons, and terminating one would pull
     * it from under every other cdvr_gl of the process. */
    egl->display = EGL_NO_DISPLAY;
}

cdvr_status cdvr_egl_begin(cdvr_egl *egl, cdvr_error *err)
{
    if (!eglBindAPI(EGL_OPENGL_API) ||
        !eglMakeCurrent(egl->display, egl->surface, egl->surface, egl->context))
        return cdvr_error_set(err, CDVR_ERR_DEVICE, "EGL: cannot make the context current (%s)",
                              cdvr_egl_error_name(eglGetError()));
    return CDVR_OK;
}

void cdvr_egl_end(cdvr_egl *egl)
{
    eglMakeCurrent(egl->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
}

static char *info_log(GLuint object, int is_program)
{
    GLint len = 0;
    if (is_program)
        glGetProgramiv(object, GL_INFO_LOG_LENGTH, &len);
    else
        glGetShaderiv(object, GL_INFO_LOG_LENGTH, &len);
    char *log = calloc((size_t)len + 1, 1);
    if (log && len > 0) {
        if (is_program)
            glGetProgramInfoLog(object, len, NULL, log);
        else
            glGetShaderInfoLog(object, len, NULL, log);
    }
    return log;
}

static cdvr_status compile(GLenum type, const char *src, GLuint *out, cdvr_error *err)
{
    GLuint shader = glCreateShader(type);
    glShaderSource(shader, 1, &src, NULL);
    glCompileShader(shader);
    GLint ok = 0;
    glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char *log = info_log(shader, 0);
        cdvr_error_set(err, CDVR_ERR_DEVICE, "GL: %s shader does not compile: %s",
                       type == GL_VERTEX_SHADER ? "vertex" : "fragment", log ? log : "");
        free(log);
        glDeleteShader(shader);
        return CDVR_ERR_DEVICE;
    }
    *out = shader;
    return CDVR_OK;
}

cdvr_status cdvr_gl_program(const char *vs, const char *fs, GLuint *out, cdvr_error *err)
{
    GLuint v, f;
    cdvr_status st = compile(GL_VERTEX_SHADER, vs, &v, err);
    if (st != CDVR_OK)
        return st;
    st = compile(GL_FRAGMENT_SHADER, fs, &f, err);
    if (st != CDVR_OK) {
        glDeleteShader(v);
        return st;
    }
    GLuint prog = glCreateProgram();
    glAttachShader(prog, v);
    glAttachShader(prog, f);
    glLinkProgram(prog);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        char *log = info_log(prog, 1);
        cdvr_error_set(err, CDVR_ERR_DEVICE, "GL: slicing program does not link: %s",
                       log ? log : "");
        free(log);
        glDeleteProgram(prog);
        return CDVR_ERR_DEVICE;
    }
    *out = prog;
    return CDVR_OK;
}

static const char *gl_error_name(GLenum e)
{
    switch (e) {
    case GL_INVALID_ENUM: return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE: return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION: return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION: return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY: return "GL_OUT_OF_MEMORY";
    }
    return "GL error";
}

cdvr_status cdvr_gl_check(const char *what, cdvr_error *err)
{
    GLenum e = glGetError();
    if (e == GL_NO_ERROR)
        return CDVR_OK;
    while (glGetError() != GL_NO_ERROR) {
    }
    return cdvr_error_set(err, CDVR_ERR_DEVICE, "GL: %s failed (%s 0x%x)", what, gl_error_name(e),
                          (unsigned)e);
}
