/* core/render/gl/gl_internal.h - internal: the headless EGL context shared by the slicer's files. */
#ifndef CDVR_GL_INTERNAL_H
#define CDVR_GL_INTERNAL_H

#include <EGL/egl.h>
#define GL_GLEXT_PROTOTYPES 1
#include <GL/glcorearb.h>

#include "cdvr/error.h"

typedef struct cdvr_egl {
    EGLDisplay display;
    EGLContext context;
    EGLSurface surface; /* EGL_NO_SURFACE with EGL_KHR_surfaceless_context, else a 1x1 pbuffer */
    char renderer[192]; /* GL_RENDERER and the EGL platform used */
} cdvr_egl;

/* Opens a display (surfaceless, device, default, in that order) and an OpenGL 3.3 core
 * context; the error lists what each platform answered. */
cdvr_status cdvr_egl_open(cdvr_egl *egl, cdvr_error *err);
void cdvr_egl_close(cdvr_egl *egl);
/* Makes the context current on the calling thread / releases it. */
cdvr_status cdvr_egl_begin(cdvr_egl *egl, cdvr_error *err);
void cdvr_egl_end(cdvr_egl *egl);
/* Name of an EGL error code ("EGL_BAD_ALLOC"). */
const char *cdvr_egl_error_name(EGLint code);

/* Compiles and links a program from vertex and fragment sources; the error holds the whole
 * info log. */
cdvr_status cdvr_gl_program(const char *vs, const char *fs, GLuint *out, cdvr_error *err);
/* CDVR_OK if glGetError() reports nothing, else the error naming `what`. */
cdvr_status cdvr_gl_check(const char *what, cdvr_error *err);

#endif
