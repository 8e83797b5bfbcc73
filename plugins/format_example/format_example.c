/* plugins/format_example/format_example.c - the smallest complete file-format plugin: the guide
 * to writing one (cdvr/format.h, cdvr/plugin.h). It adds two formats:
 *
 *   "cvol" (.cvol): a text header, an empty line, then the voxels, little endian, x fastest,
 *       timestep slowest:
 *           CVOL1
 *           dims 64 64 32
 *           type u8                 (u8, u16, i16 or f32)
 *           timesteps 2             (optional, default 1)
 *           spacing 1 1 2.5         (optional, default 1 1 1)
 *           <empty line>
 *   "cvls" (.cvls): a list of volume files, one per line after the line CVLS1, names relative
 *       to the list's directory; cdvr.load_series / cdvr_volume_load_series open it as the
 *       series of those files (expand). On its own it is not a volume.
 *
 * A plugin uses no libcdvr symbol (see cdvr/plugin.h): it gives `read`, not `load`, so the
 * registry allocates the volume from what `probe` says, and it reports errors with
 * cdvr_plugin_error. Both formats are found by their suffix or, under any other name, by their
 * first bytes (magic). Build: plugins/CMakeLists.txt (cdvr_add_plugin); load: cdvr.plugin.load(
 * "build/plugins/cdvr_format_example.so"), or put it in CDVR_PLUGIN_PATH.
 */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cdvr/plugin.h"

#define HEADER_MAX 4096 /* header bytes, at most */

typedef struct cvol_header {
    size_t dims[3], timesteps;
    cdvr_type type;
    double spacing[3];
    long data_offset;
} cvol_header;

static size_t type_size(cdvr_type t)
{
    return t == CDVR_TYPE_U8 ? 1 : t == CDVR_TYPE_F32 ? 4 : 2;
}

static int parse_type(const char *s, cdvr_type *t)
{
    static const struct { const char *name; cdvr_type type; } types[] = {
        {"u8", CDVR_TYPE_U8}, {"u16", CDVR_TYPE_U16}, {"i16", CDVR_TYPE_I16},
        {"f32", CDVR_TYPE_F32}};
    for (size_t i = 0; i < sizeof types / sizeof *types; i++)
        if (strcmp(s, types[i].name) == 0) {
            *t = types[i].type;
            return 1;
        }
    return 0;
}

/* One header line (without its '\n') into h; 0 for a line it does not know. */
static int parse_line(const char *line, cvol_header *h)
{
    char word[16];
    unsigned long long a, b, c;
    if (sscanf(line, "dims %llu %llu %llu", &a, &b, &c) == 3 && a && b && c && a < 1u << 20 &&
        b < 1u << 20 && c < 1u << 20) {
        h->dims[0] = (size_t)a;
        h->dims[1] = (size_t)b;
        h->dims[2] = (size_t)c;
        return 1;
    }
    if (sscanf(line, "timesteps %llu", &a) == 1 && a && a < 1u << 20) {
        h->timesteps = (size_t)a;
        return 1;
    }
    if (sscanf(line, "type %15s", word) == 1)
        return parse_type(word, &h->type);
    return sscanf(line, "spacing %lf %lf %lf", &h->spacing[0], &h->spacing[1],
                  &h->spacing[2]) == 3 && h->spacing[0] > 0 && h->spacing[1] > 0 &&
           h->spacing[2] > 0 && h->spacing[0] < 1e30 && h->spacing[1] < 1e30 &&
           h->spacing[2] < 1e30;
}

/* Reads and checks the header; the file must hold exactly the voxels it announces. */
static cdvr_status read_header(const char *path, cvol_header *h, cdvr_error *err)
{
    memset(h, 0, sizeof *h);
    h->timesteps = 1;
    h->type = CDVR_TYPE_U8;
    h->spacing[0] = h->spacing[1] = h->spacing[2] = 1;
    FILE *f = fopen(path, "rb");
    if (!f)
        return cdvr_plugin_error(err, CDVR_ERR_IO, "%s: cannot open", path);
    char line[256];
    int n = 0, ended = 0, bad = 0;
    while (!ended && !bad && ftell(f) < HEADER_MAX && fgets(line, sizeof line, f)) {
        size_t len = strcspn(line, "\n");
        bad = line[len] != '\n'; /* too long, or no newline */
        line[len] = '\0';
        if (n++ == 0)
            bad = bad || strcmp(line, "CVOL1") != 0;
        else if (len == 0)
            ended = 1;
        else if (!bad && !parse_line(line, h))
            bad = 1;
    }
    h->data_offset = ftell(f);
    int seek = fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fclose(f);
    if (bad || !ended || !h->dims[0])
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: not a cvol file (line %d: '%s')", path,
                                 n, bad ? line : "header without dims or its empty line");
    double want = (double)h->dims[0] * (double)h->dims[1] * (double)h->dims[2] *
                  (double)h->timesteps * (double)type_size(h->type);
    if (seek != 0 || size < 0 || (double)(size - h->data_offset) != want)
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: cvol header announces %.0f bytes of "
                                 "voxels, the file holds %ld", path, want, size - h->data_offset);
    return CDVR_OK;
}

static int cvol_magic(const uint8_t *head, size_t n)
{
    return n >= 6 && memcmp(head, "CVOL1\n", 6) == 0;
}

static cdvr_status cvol_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                              cdvr_error *err)
{
    (void)opts; /* the registry applies opts->spacing */
    cvol_header h;
    cdvr_status st = read_header(path, &h, err);
    if (st != CDVR_OK)
        return st;
    memcpy(head->dims, h.dims, sizeof h.dims);
    head->timesteps = h.timesteps;
    head->type = h.type;
    memcpy(head->spacing, h.spacing, sizeof h.spacing);
    return CDVR_OK; /* origin 0 and direction identity: head comes preset */
}

static cdvr_status cvol_read(const char *path, const cdvr_raw_opts *opts, const cdvr_volume *head,
                             void *voxels, cdvr_error *err)
{
    (void)opts;
    cvol_header h;
    cdvr_status st = read_header(path, &h, err);
    if (st != CDVR_OK)
        return st;
    if (memcmp(h.dims, head->dims, sizeof h.dims) != 0 || h.timesteps != head->timesteps ||
        h.type != head->type)
        return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: changed since it was probed", path);
    size_t elem = type_size(h.type);
    size_t count = h.dims[0] * h.dims[1] * h.dims[2] * h.timesteps;
    FILE *f = fopen(path, "rb");
    int ok = f && fseek(f, h.data_offset, SEEK_SET) == 0 && fread(voxels, elem, count, f) == count;
    if (f)
        fclose(f);
    if (!ok)
        return cdvr_plugin_error(err, CDVR_ERR_IO, "%s: cannot read the voxels", path);
    const uint16_t one = 1;
    if (elem > 1 && *(const uint8_t *)&one == 0) /* big-endian host: the file is little endian */
        for (uint8_t *p = voxels, *end = p + count * elem; p < end; p += elem)
            for (size_t i = 0; i < elem / 2; i++) {
                uint8_t t = p[i];
                p[i] = p[elem - 1 - i];
                p[elem - 1 - i] = t;
            }
    return CDVR_OK;
}

/* ---- cvls: a list of files ------------------------------------------------------------------ */

static int cvls_magic(const uint8_t *head, size_t n)
{
    return n >= 6 && memcmp(head, "CVLS1\n", 6) == 0;
}

static cdvr_status cvls_probe(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                              cdvr_error *err)
{
    (void)opts;
    (void)head;
    return cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: a cvls file lists volume files; open it "
                             "as a series (cdvr.load_series)", path);
}

static cdvr_status cvls_read(const char *path, const cdvr_raw_opts *opts, const cdvr_volume *head,
                             void *voxels, cdvr_error *err)
{
    (void)voxels;
    (void)head;
    return cvls_probe(path, opts, NULL, err);
}

static cdvr_status cvls_expand(const char *path, int (*add)(void *ud, const char *file), void *ud,
                               cdvr_error *err)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return cdvr_plugin_error(err, CDVR_ERR_IO, "%s: cannot open", path);
    const char *slash = strrchr(path, '/');
    int dir_len = slash ? (int)(slash - path + 1) : 0; /* keeps the '/' */
    char line[PATH_MAX], file[2 * PATH_MAX];
    cdvr_status st = CDVR_OK;
    for (int n = 0; st == CDVR_OK && fgets(line, sizeof line, f); n++) {
        size_t len = strcspn(line, "\r\n");
        line[len] = '\0';
        if (n == 0 && strcmp(line, "CVLS1") != 0)
            st = cdvr_plugin_error(err, CDVR_ERR_FORMAT, "%s: not a cvls file", path);
        else if (n > 0 && len > 0 && line[0] != '#') {
            if (line[0] == '/')
                snprintf(file, sizeof file, "%s", line);
            else
                snprintf(file, sizeof file, "%.*s%s", dir_len, path, line);
            if (!add(ud, file))
                st = cdvr_plugin_error(err, CDVR_ERR_NOMEM, "%s: out of memory", path);
        }
    }
    fclose(f);
    return st;
}

/* ---- the tables and the entry point --------------------------------------------------------- */

static const char *const cvol_suffixes[] = {".cvol", NULL};
static const char *const cvls_suffixes[] = {".cvls", NULL};

static const cdvr_format cvol_format = {
    .name = "cvol",
    .description = "example plugin: a text header (dims, type, timesteps, spacing), then voxels",
    .suffixes = cvol_suffixes,
    .magic = cvol_magic,
    .probe = cvol_probe,
    .read = cvol_read, /* no load: the registry allocates from the probe */
};

static const cdvr_format cvls_format = {
    .name = "cvls",
    .description = "example plugin: a list of volume files, opened as a series",
    .suffixes = cvls_suffixes,
    .magic = cvls_magic,
    .probe = cvls_probe,
    .read = cvls_read,
    .expand = cvls_expand,
};

static const cdvr_format *const formats[] = {&cvol_format, &cvls_format, NULL};

static const cdvr_plugin_info format_plugin = {
    .abi = CDVR_PLUGIN_ABI, /* 3 or later: the version with format lists */
    .codec = NULL,          /* no codec; a plugin may give both */
    .formats = formats,
};

CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void);
CDVR_PLUGIN_EXPORT const cdvr_plugin_info *cdvr_plugin_v1(void)
{
    return &format_plugin;
}
