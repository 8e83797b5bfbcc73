#!/usr/bin/env python3
"""tests/xinput.py - synthetic mouse and keyboard input for the window test, through the X
server's XTEST extension (libXtst via ctypes), as a user's hand would give it.

usage: xinput.py drag X0 Y0 X1 Y1     left-button drag in screen pixels
       xinput.py scroll STEPS         wheel steps at the pointer (positive: away from the user)
       xinput.py key NAME [NAME...]   press and release keys (X keysym names: Right, space, ...)
Needs $DISPLAY; exits 77 when the X libraries or XTEST are missing.
"""
import ctypes
import ctypes.util
import sys


def load(name):
    path = ctypes.util.find_library(name)
    if not path:
        sys.stderr.write("xinput.py: lib%s not found\n" % name)
        sys.exit(77)
    return ctypes.CDLL(path)


def main():
    x11, xtst = load("X11"), load("Xtst")
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XSync.argtypes = [ctypes.c_void_p, ctypes.c_int]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    x11.XStringToKeysym.restype = ctypes.c_ulong
    x11.XStringToKeysym.argtypes = [ctypes.c_char_p]
    x11.XKeysymToKeycode.restype = ctypes.c_ubyte
    x11.XKeysymToKeycode.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
    xtst.XTestFakeMotionEvent.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_ulong]
    xtst.XTestFakeButtonEvent.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_ulong]
    xtst.XTestFakeKeyEvent.argtypes = [ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_ulong]
    dpy = x11.XOpenDisplay(None)
    if not dpy:
        sys.stderr.write("xinput.py: cannot open the display\n")
        return 77
    what, args = sys.argv[1], sys.argv[2:]
    if what == "drag":
        x0, y0, x1, y1 = (int(a) for a in args)
        xtst.XTestFakeMotionEvent(dpy, -1, x0, y0, 0)
        x11.XSync(dpy, 0)
        xtst.XTestFakeButtonEvent(dpy, 1, 1, 0)
        x11.XSync(dpy, 0)
        steps = 8
        for i in range(1, steps + 1):
            xtst.XTestFakeMotionEvent(dpy, -1, x0 + (x1 - x0) * i // steps, y0 + (y1 - y0) * i // steps, 0)
            x11.XSync(dpy, 0)
        xtst.XTestFakeButtonEvent(dpy, 1, 0, 0)
    elif what == "scroll":
        n = int(args[0])
        button = 4 if n > 0 else 5
        for _ in range(abs(n)):
            xtst.XTestFakeButtonEvent(dpy, button, 1, 0)
            xtst.XTestFakeButtonEvent(dpy, button, 0, 0)
    elif what == "key":
        for name in args:
            code = x11.XKeysymToKeycode(dpy, x11.XStringToKeysym(name.encode()))
            xtst.XTestFakeKeyEvent(dpy, code, 1, 0)
            xtst.XTestFakeKeyEvent(dpy, code, 0, 0)
    else:
        sys.stderr.write(__doc__)
        return 2
    x11.XSync(dpy, 0)
    x11.XCloseDisplay(dpy)
    return 0


if __name__ == "__main__":
    sys.exit(main())
