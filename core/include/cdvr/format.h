/* cdvr/format.h - one table per volume file format (DESIGN.md section 2, `load`) and the registry.
 *
 * A format turns a file into a cdvr_volume (cdvr/volume.h). cdvr_volume_load, the header probe
 * that out-of-core series use (cdvr/series.h), cdvr.load and cdvr.load_series only ever go
 * through a `cdvr_format` table; none of them names a format. Built-in formats: "nrrd" (teem),
 * "nifti" (niftilib), "raw" (the caller describes the file) and more; plugins (cdvr/plugin.h) add
 * more at run time, so a loader written against a C++ library stays out of core.
 *
 * Which format reads a file (cdvr_format_for):
 *  0. a directory: the first format, in registration order, whose accepts_dir(dir) is 1; a
 *     directory no format accepts is refused: CDVR_ERR_FORMAT, "PATH: is a directory that no
 *     format reads", naming the formats that read directories;
 *  1. its name: the format with the longest suffix that ends the name, compared without regard
 *     to case (".nii.gz" before a plugin's ".gz");
 *  1b. else, for a name holding ':', the longest prefix FILE before a ':' that ends in a suffix
 *     of a CDVR_FORMAT_SUBPATH format and names an existing file: that format;
 *  2. else, when the caller describes a raw file (cdvr_raw_opts with dims): raw, whatever the
 *     name (as cdvr.load always did);
 *  3. else its first bytes (at most CDVR_FORMAT_MAGIC_MAX, fewer for a short file): the first
 *     format, in registration order, whose magic test accepts them;
 *  4. else the file is refused: CDVR_ERR_FORMAT, "PATH: unknown file type", the reason (no
 *     suffix or magic matched, or the file cannot be read), and the list of the formats known,
 *     each with its suffixes.
 *
 * What a format supplies:
 *  - name (registry key, 1..15 characters of [a-z0-9_]), a one-line description and its
 *    suffixes (a NULL-terminated list, each starting with '.'; may be empty for a format found
 *    by its magic only);
 *  - magic, optional: a test of the first bytes (NULL for a format that has no signature, such
 *    as raw);
 *  - probe: what loading the file would give (dims, timesteps, type after the format's
 *    conversions, spacing, origin, direction) without reading the voxels; head comes preset
 *    (spacing 1, origin 0, direction identity, everything else 0) and head->data is left alone;
 *  - load or read (at least one): `load` makes the whole volume (built-in formats, which call
 *    cdvr_volume_create); `read` fills a buffer the registry allocated after a probe, so a plugin
 *    needs no libcdvr symbol: the registry probes, creates the volume with the probe's dims,
 *    timesteps, type and geometry, and read writes its timesteps * voxels values of that type,
 *    x fastest, timestep slowest. Where both are given, load is used;
 *  - expand, optional: a file that stands for several (a list of files): calls add(ud, path)
 *    once per file, in order (relative names resolved by the format); cdvr_volume_load_series
 *    and cdvr_series_open replace such a file by its list. A 4D file needs no expand: its probe
 *    gives timesteps > 1 and a series of it is the series of its timesteps.
 *  - flags: CDVR_FORMAT_DESCRIBED when the format reads only what the caller describes (raw:
 *    dims and type in cdvr_raw_opts); then a file without a description is refused naming what
 *    is missing. CDVR_FORMAT_SUBPATH when the format reads an object inside a file named as
 *    FILE:NAME (HDF5 `scan.h5:/group/dataset`, NetCDF `flow.nc:u`): see rule 1b below; its
 *    functions get the whole string and split it themselves (cdvr_format_split_subpath);
 *  - expand_opts, optional (ABI 5): expand given the caller's cdvr_raw_opts (a list whose
 *    files must obey allow_outside); used instead of expand where both are given;
 *  - accepts_dir, optional (ABI 5): 1 when the format reads the directory dir as one volume or
 *    series (DICOM files, a TIFF stack); see rule 0 below. probe/load/read then get the
 *    directory's path.
 * opts (cdvr_raw_opts: the raw description, a spacing override and the readers' limits) is
 * passed to every function and may be NULL; formats that read their geometry from the file ignore
 * the description: the registry applies a given spacing (> 0 per axis) over what the file says,
 * after probe and load. The limits bind every format: a file may read only files under its own
 * directory (after realpath) unless opts->allow_outside, and a claim of more than
 * cdvr_load_max_bytes(opts) voxel bytes is refused before anything is allocated or inflated (the
 * registry checks it for a format with `read`, from the probe). A header field a format cannot
 * honour is refused naming the field and its value, never replaced by a default.
 * Errors name the file and the reason (cdvr/error.h); a format never aborts on bad input and
 * must not read outside what the file's header justifies (they are fuzzed). Every function of a
 * table must be safe to call from several threads at once on different files.
 */
#ifndef CDVR_FORMAT_H
#define CDVR_FORMAT_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"
#include "cdvr/volume.h"

#define CDVR_FORMAT_NAME_MAX 16    /* format names: 1..15 bytes of [a-z0-9_] */
#define CDVR_FORMAT_MAGIC_MAX 512  /* first bytes a magic test sees, at most */
#define CDVR_FORMAT_DESCRIBED 1u   /* flag: reads only what cdvr_raw_opts describes (raw) */
#define CDVR_FORMAT_SUBPATH 2u     /* flag: reads FILE:NAME (an object inside FILE) */

typedef struct cdvr_format {
    const char *name;                /* registry key, e.g. "nrrd" */
    const char *description;         /* one line for cdvr.formats() */
    const char *const *suffixes;     /* {".nrrd", ".nhdr", NULL} */
    unsigned flags;                  /* CDVR_FORMAT_DESCRIBED or 0 */

    /* Optional: 1 when the first n bytes of a file (n <= CDVR_FORMAT_MAGIC_MAX; the whole
     * file when shorter) are this format's signature. */
    int (*magic)(const uint8_t *head, size_t n);
    /* Header only; see the top of this file. */
    cdvr_status (*probe)(const char *path, const cdvr_raw_opts *opts, cdvr_volume *head,
                         cdvr_error *err);
    /* The whole file as a new volume (*out); *out stays NULL on error. */
    cdvr_status (*load)(const char *path, const cdvr_raw_opts *opts, cdvr_volume **out,
                        cdvr_error *err);
    /* Or: the voxels of the volume head describes (what probe gave) into voxels, which holds
     * head->timesteps * dims product values of head->type. */
    cdvr_status (*read)(const char *path, const cdvr_raw_opts *opts, const cdvr_volume *head,
                        void *voxels, cdvr_error *err);
    /* Optional: the files this one stands for; add returns 0 when out of memory (then expand
     * returns CDVR_ERR_NOMEM). */
    cdvr_status (*expand)(const char *path, int (*add)(void *ud, const char *file), void *ud,
                          cdvr_error *err);
    /* ABI 5 and later (a plugin of an older ABI gets a copy with NULL here). Optional: 1 when
     * this format reads the directory dir (rule 0 above). Must not read voxels. */
    int (*accepts_dir)(const char *dir);
    /* ABI 5 and later, optional: expand with the caller's load options (the list's files obey
     * allow_outside and the limits as the file itself does). Where given, it is used instead
     * of expand. */
    cdvr_status (*expand_opts)(const char *path, const cdvr_raw_opts *opts,
                               int (*add)(void *ud, const char *file), void *ud,
                               cdvr_error *err);
} cdvr_format;

/* Splits "FILE:NAME" for a CDVR_FORMAT_SUBPATH format (inline: plugins may use it): the
 * longest prefix before a ':' that ends in one of f's suffixes (case-insensitive) goes to
 * file (n bytes), the rest to name (n bytes; "" when path has no such ':', then file is path).
 * Returns 0 when either part does not fit. */
static inline int cdvr_format_split_subpath(const cdvr_format *f, const char *path, char *file,
                                            char *name, size_t n)
{
    size_t len = 0, cut = 0;
    while (path[len])
        len++;
    for (size_t i = len; i-- > 0 && !cut;) {
        if (path[i] != ':')
            continue;
        for (const char *const *s = f->suffixes; *s && !cut; s++) {
            size_t k = 0;
            while ((*s)[k])
                k++;
            int match = k <= i;
            for (size_t j = 0; match && j < k; j++) {
                char a = path[i - k + j], b = (*s)[j];
                a = (char)(a >= 'A' && a <= 'Z' ? a + 32 : a);
                b = (char)(b >= 'A' && b <= 'Z' ? b + 32 : b);
                match = a == b;
            }
            if (match)
                cut = i;
        }
    }
    size_t file_len = cut ? cut : len, name_len = cut ? len - cut - 1 : 0;
    if (file_len >= n || name_len >= n)
        return 0;
    for (size_t i = 0; i < file_len; i++)
        file[i] = path[i];
    file[file_len] = '\0';
    for (size_t i = 0; i < name_len; i++)
        name[i] = path[cut + 1 + i];
    name[name_len] = '\0';
    return 1;
}

/* ---- registry -------------------------------------------------------------------------------
 * One process-wide table (built-ins first, registered on first use; thread-safe). */

/* Registers a format. Refused (CDVR_ERR_ARG): a NULL table, a bad name, a missing member
 * ("format 'x': the table has no probe"), a suffix that does not start with '.', a name or a
 * suffix another format already has (the message names that format); CDVR_ERR_NOMEM when the
 * registry is full. Registering the same table again is a no-op. */
cdvr_status cdvr_format_register(const cdvr_format *format, cdvr_error *err);
/* The format called name, or NULL. */
const cdvr_format *cdvr_format_find(const char *name);
/* The format whose suffix (longest first) ends path, or NULL. */
const cdvr_format *cdvr_format_by_suffix(const char *path);
/* The first format whose magic accepts these first bytes, or NULL. */
const cdvr_format *cdvr_format_by_magic(const uint8_t *head, size_t n);
/* Registered formats, in registration order. */
size_t cdvr_format_count(void);
const cdvr_format *cdvr_format_at(size_t i);
/* The known formats as text for messages: "nrrd (.nrrd .nhdr), nifti (...), raw (...)", at
 * most n-1 bytes (cut with "..."). */
void cdvr_format_list(char *out, size_t n);

/* The format that reads path (the rule at the top of this file); errors as described there. */
cdvr_status cdvr_format_for(const char *path, const cdvr_raw_opts *opts,
                            const cdvr_format **out, cdvr_error *err);
/* Probe and load through a given format, with the registry's rules: the raw description check
 * (CDVR_FORMAT_DESCRIBED), read through a probe where the format has no load, the spacing
 * override. cdvr_volume_load and cdvr_volume_probe are cdvr_format_for then these. */
cdvr_status cdvr_format_probe(const cdvr_format *f, const char *path, const cdvr_raw_opts *opts,
                              cdvr_volume *head, cdvr_error *err);
cdvr_status cdvr_format_load(const cdvr_format *f, const char *path, const cdvr_raw_opts *opts,
                             cdvr_volume **out, cdvr_error *err);

/* The files of a series given as paths: each path whose format has expand is replaced by its
 * files (not recursively); the others are kept. *out is a malloc'd array of *count malloc'd
 * strings (cdvr_format_free_paths). A path whose format cannot be told is kept as it is (its
 * load reports it). */
cdvr_status cdvr_format_expand(const char *const *paths, size_t count, const cdvr_raw_opts *opts,
                               char ***out, size_t *out_count, cdvr_error *err);
void cdvr_format_free_paths(char **paths, size_t count);

#endif
