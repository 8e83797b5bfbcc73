/* core/io/tiff_desc.c - the ImageDescription of a TIFF: ImageJ key=value lines and OME-XML
 * (through expat), as the TIFF loader (io_tiff.c) reads them (cdvr/tiff.h). */
#include "cdvr/tiff.h"

#include <expat.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- ImageJ ----------------------------------------------------------------------------------- */

/* The value of key on a line of text[0..len) ("key=value\n"), copied into out (n bytes, cut);
 * 0 when absent. */
static int imagej_value(const char *text, size_t len, const char *key, char *out, size_t n)
{
    size_t k = strlen(key);
    for (size_t at = 0; at < len;) {
        size_t end = at;
        while (end < len && text[end] != '\n' && text[end] != '\0')
            end++;
        if (end - at > k && memcmp(text + at, key, k) == 0 && text[at + k] == '=') {
            size_t v = at + k + 1, m = end - v < n - 1 ? end - v : n - 1;
            memcpy(out, text + v, m);
            out[m] = '\0';
            return 1;
        }
        if (end < len && text[end] == '\0')
            break;
        at = end + 1;
    }
    return 0;
}

static int imagej_number(const char *text, size_t len, const char *key, double *v)
{
    char buf[64], *end;
    if (!imagej_value(text, len, key, buf, sizeof buf))
        return 0;
    *v = strtod(buf, &end);
    return end != buf && isfinite(*v);
}

/* A count from 1 to 10^6 (ImageJ and OME sizes). */
static int size_of(double v, size_t *out)
{
    if (!(v >= 1 && v <= 1e6 && v == floor(v)))
        return 0;
    *out = (size_t)v;
    return 1;
}

int cdvr_tiff_imagej_parse(const char *text, size_t len, cdvr_tiff_desc *out)
{
    memset(out, 0, sizeof *out);
    if (len < 7 || memcmp(text, "ImageJ=", 7) != 0)
        return 0;
    double v;
    if (imagej_number(text, len, "spacing", &v) && v > 0 && v < 1e30)
        out->spacing[2] = v;
    if (imagej_number(text, len, "slices", &v))
        (void)size_of(v, &out->slices);
    if (imagej_number(text, len, "frames", &v))
        (void)size_of(v, &out->frames);
    if (imagej_number(text, len, "channels", &v))
        (void)size_of(v, &out->channels);
    (void)imagej_value(text, len, "unit", out->unit, sizeof out->unit);
    return 1;
}

/* ---- OME-XML ---------------------------------------------------------------------------------- */

typedef struct ome_parse {
    const char *path;
    size_t pages;
    XML_Parser xp;
    cdvr_error *err;
    cdvr_status st;
    cdvr_tiff_desc *out;
    int images, pixels, in_tiffdata;
    size_t strides[3];           /* plane index strides of Z, T, C (DimensionOrder) */
    size_t tiffdata;
} ome_parse;

static void stop(ome_parse *p, cdvr_status st, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* stop, as an expression that is 0 (for `return FAIL(...)`). */
#define FAIL(...) (stop(__VA_ARGS__), 0)

static void stop(ome_parse *p, cdvr_status st, const char *fmt, ...)
{
    if (p->st != CDVR_OK)
        return;
    char why[CDVR_ERRMSG_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(why, sizeof why, fmt, ap);
    va_end(ap);
    p->st = cdvr_error_set(p->err, st, "%s: OME-XML %s", p->path, why);
    XML_StopParser(p->xp, XML_FALSE);
}

/* Element or attribute name without its namespace prefix ("ome:Pixels" -> "Pixels"). */
static const char *local(const char *name)
{
    const char *c = strrchr(name, ':');
    return c ? c + 1 : name;
}

static const char *attr(const XML_Char **a, const char *name)
{
    for (size_t i = 0; a[i]; i += 2)
        if (strcmp(local(a[i]), name) == 0)
            return a[i + 1];
    return NULL;
}

/* Micrometres per unit (OME's UnitsLength that are lengths); 0 for another. */
static double unit_um(const char *u)
{
    static const struct { const char *name; double um; } units[] = {
        {"Ym", 1e30}, {"Zm", 1e27}, {"Em", 1e24}, {"Pm", 1e21}, {"Tm", 1e18}, {"Gm", 1e15},
        {"Mm", 1e12}, {"km", 1e9}, {"hm", 1e8}, {"dam", 1e7}, {"m", 1e6}, {"dm", 1e5},
        {"cm", 1e4}, {"mm", 1e3}, {"\xc2\xb5m", 1}, {"\xce\xbcm", 1}, {"um", 1}, {"nm", 1e-3},
        {"pm", 1e-6}, {"fm", 1e-9}, {"am", 1e-12}, {"zm", 1e-15}, {"ym", 1e-18},
        {"\xc3\x85", 1e-4}, {"\xe2\x84\xab", 1e-4}, {"in", 25400}, {"ft", 304800},
        {"yd", 914400}, {"mi", 1609344e3}, {"pt", 25400.0 / 72}};
    for (size_t i = 0; i < sizeof units / sizeof *units; i++)
        if (strcmp(u, units[i].name) == 0)
            return units[i].um;
    return 0;
}

static int positive(const char *s, double *v)
{
    char *end;
    *v = strtod(s, &end);
    return end != s && *end == '\0' && isfinite(*v) && *v > 0;
}

static int pixels(ome_parse *p, const XML_Char **a)
{
    cdvr_tiff_desc *o = p->out;
    static const char *const size_names[3] = {"SizeZ", "SizeT", "SizeC"};
    size_t *sizes[3] = {&o->slices, &o->frames, &o->channels};
    for (int i = 0; i < 3; i++) {
        const char *v = attr(a, size_names[i]);
        double d = 1;
        char *end = NULL;
        if (v)
            d = strtod(v, &end);
        if ((v && (end == v || *end)) || !size_of(d, sizes[i]))
            return FAIL(p, CDVR_ERR_FORMAT, "Pixels %s=\"%s\" is not a count 1..10^6",
                        size_names[i], v ? v : "");
    }
    if (o->channels > 1)
        return FAIL(p, CDVR_ERR_UNSUPPORTED, "Pixels SizeC=\"%zu\": cdvr reads one channel",
                    o->channels);
    static const char *const phys[3] = {"PhysicalSizeX", "PhysicalSizeY", "PhysicalSizeZ"};
    for (int i = 0; i < 3; i++) {
        char key[32];
        const char *v = attr(a, phys[i]), *u;
        snprintf(key, sizeof key, "%sUnit", phys[i]);
        u = attr(a, key);
        double d, um = unit_um(u ? u : "um");
        if (!v)
            continue;
        if (!positive(v, &d))
            return FAIL(p, CDVR_ERR_FORMAT, "Pixels %s=\"%s\" is not a positive number",
                        phys[i], v);
        if (um == 0)
            return FAIL(p, CDVR_ERR_UNSUPPORTED, "Pixels %s=\"%s\" is not a unit of length "
                        "cdvr converts", key, u);
        if (!isfinite(d * um) || !(d * um > 0))
            return FAIL(p, CDVR_ERR_FORMAT, "Pixels %s=\"%s\" %s is out of range", phys[i], v,
                        u ? u : "um");
        o->spacing[i] = d * um;
    }
    snprintf(o->unit, sizeof o->unit, "um");
    const char *order = attr(a, "DimensionOrder");
    if (!order)
        order = "XYZCT";
    static const char *const orders[] = {"XYZCT", "XYZTC", "XYCTZ", "XYCZT", "XYTCZ", "XYTZC"};
    int known = 0;
    for (size_t i = 0; i < sizeof orders / sizeof *orders; i++)
        known |= strcmp(order, orders[i]) == 0;
    if (!known)
        return FAIL(p, CDVR_ERR_FORMAT, "Pixels DimensionOrder=\"%s\" is not one of XYZCT, "
                    "XYZTC, XYCTZ, XYCZT, XYTCZ, XYTZC", order);
    size_t stride = 1;
    for (int i = 2; i < 5; i++) {
        int axis = order[i] == 'Z' ? 0 : order[i] == 'T' ? 1 : 2;
        p->strides[axis] = stride;
        stride *= *sizes[axis];
    }
    o->t_before_z = p->strides[1] < p->strides[0];
    if (stride != p->pages)
        return FAIL(p, CDVR_ERR_FORMAT, "Pixels SizeZ %zu x SizeT %zu x SizeC %zu = %zu planes, "
                    "the file has %zu pages", o->slices, o->frames, o->channels, stride,
                    p->pages);
    return 1;
}

/* A TiffData must map planes onto this file's IFDs in the DimensionOrder's own order. */
static int tiffdata(ome_parse *p, const XML_Char **a)
{
    static const char *const keys[4] = {"IFD", "FirstZ", "FirstT", "FirstC"};
    double v[4] = {0, 0, 0, 0};
    for (int i = 0; i < 4; i++) {
        const char *s = attr(a, keys[i]);
        char *end;
        if (!s)
            continue;
        v[i] = strtod(s, &end);
        if (end == s || *end || !(v[i] >= 0 && v[i] <= 1e6) || v[i] != floor(v[i]))
            return FAIL(p, CDVR_ERR_FORMAT, "TiffData %s=\"%s\" is not an index", keys[i], s);
    }
    double plane = v[1] * (double)p->strides[0] + v[2] * (double)p->strides[1] +
                   v[3] * (double)p->strides[2];
    if (plane != v[0])
        return FAIL(p, CDVR_ERR_UNSUPPORTED, "TiffData IFD=\"%.0f\" holds plane Z=%.0f T=%.0f "
                    "C=%.0f, not IFD %.0f as the DimensionOrder's order would: planes stored out "
                    "of order are not read", v[0], v[1], v[2], v[3], plane);
    p->tiffdata++;
    return 1;
}

/* A UUID FileName must be this file (a multi-file OME-TIFF is not read). */
static void uuid(ome_parse *p, const XML_Char **a)
{
    const char *file = attr(a, "FileName"), *self = strrchr(p->path, '/');
    self = self ? self + 1 : p->path;
    if (file && strcmp(file, self) != 0)
        stop(p, CDVR_ERR_UNSUPPORTED, "TiffData names another file (%s): multi-file OME-TIFF is "
             "not read", file);
}

static void XMLCALL on_start(void *ud, const XML_Char *el, const XML_Char **a)
{
    ome_parse *p = ud;
    const char *name = local(el);
    if (strcmp(name, "Image") == 0 && ++p->images > 1)
        stop(p, CDVR_ERR_UNSUPPORTED, "has %d or more Images: cdvr reads a file of one",
             p->images);
    else if (strcmp(name, "Pixels") == 0 && p->images == 1 && p->pixels++ == 0)
        (void)pixels(p, a);
    else if (strcmp(name, "TiffData") == 0 && p->pixels == 1) {
        p->in_tiffdata = 1;
        (void)tiffdata(p, a);
    } else if (strcmp(name, "UUID") == 0 && p->in_tiffdata)
        uuid(p, a);
}

static void XMLCALL on_end(void *ud, const XML_Char *el)
{
    ome_parse *p = ud;
    if (strcmp(local(el), "TiffData") == 0)
        p->in_tiffdata = 0;
}

static void XMLCALL on_doctype(void *ud, const XML_Char *name, const XML_Char *sys,
                               const XML_Char *pub, int internal)
{
    (void)name, (void)sys, (void)pub, (void)internal;
    stop(ud, CDVR_ERR_FORMAT, "has a DOCTYPE (not allowed)");
}

cdvr_status cdvr_tiff_ome_parse(const char *path, const char *xml, size_t len, size_t pages,
                                cdvr_tiff_desc *out, cdvr_error *err)
{
    memset(out, 0, sizeof *out);
    if (len > ((size_t)64 << 20))
        return cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: OME-XML of %zu bytes (more than 64 "
                              "MiB)", path, len);
    ome_parse p = {.path = path, .pages = pages, .err = err, .st = CDVR_OK, .out = out};
    if (!(p.xp = XML_ParserCreate(NULL)))
        return cdvr_error_set(err, CDVR_ERR_NOMEM, "%s: cannot create an XML parser", path);
    XML_SetUserData(p.xp, &p);
    XML_SetElementHandler(p.xp, on_start, on_end);
    XML_SetStartDoctypeDeclHandler(p.xp, on_doctype);
    if (XML_Parse(p.xp, xml ? xml : "", (int)len, 1) == XML_STATUS_ERROR && p.st == CDVR_OK)
        p.st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: OME-XML error at line %lu: %s", path,
                              (unsigned long)XML_GetCurrentLineNumber(p.xp),
                              XML_ErrorString(XML_GetErrorCode(p.xp)));
    XML_ParserFree(p.xp);
    if (p.st == CDVR_OK && !p.pixels)
        p.st = cdvr_error_set(err, CDVR_ERR_FORMAT, "%s: OME-XML has no Image with Pixels",
                              path);
    if (p.st != CDVR_OK)
        memset(out, 0, sizeof *out);
    return p.st;
}
