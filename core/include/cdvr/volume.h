/* cdvr/volume.h - scalar volumes and time series in memory, and their file I/O.
 *
 * A cdvr_volume holds `timesteps` frames of dims[0] x dims[1] x dims[2] voxels of
 * one scalar type, contiguous: voxel (x,y,z) of frame t (all from 0) is element
 * x + X*(y + Y*(z + Z*t)). World position of voxel (i,j,k) is
 *     origin + D * (i*spacing[0], j*spacing[1], k*spacing[2])
 * with D the 3x3 direction matrix (row-major: direction[3*r + c]; column c is the world
 * direction of index axis c), VTK image data's index-to-world convention (DESIGN.md
 * section 6). Volumes are created with D = identity. D must be invertible; it need not be
 * orthonormal (an oblique NRRD may shear), though loaders normalise its columns (the length
 * of each index step is in spacing). A D of all zeros (a zero-initialised struct) means the
 * identity to every function here and to the renderers. World coordinates are those of the
 * file: NIfTI's RAS+ (sform, else qform with its qfac), a NRRD's `space` (for example LPS for
 * "left-posterior-superior"); cdvr does not convert between them.
 *
 * Value window: window[0..1] are the data values [lo, hi] that the 256 codes of the
 * renderers' transfer-function table span (tf.h, render.h). For a u8 volume, code q stands
 * for the data value lo + q * (hi - lo) / 255: [0, 255] for u8 files (code = value), the
 * quantisation window for the output of cdvr_volume_quantize and for frames decoded from a
 * store. For u16, i16 and f32 volumes the window is the range of the whole series (all
 * timesteps), computed once by cdvr_volume_window and cached here; NAN means not computed
 * yet (cdvr_volume_create), and code that changes voxels of such a volume sets it back to NAN.
 * Every frame of a series is then classified over the same window, so a series does not
 * flicker and frame(t) of a series renders like timestep t of it.
 */
#ifndef CDVR_VOLUME_H
#define CDVR_VOLUME_H

#include <stddef.h>
#include <stdint.h>

#include "cdvr/error.h"

typedef enum cdvr_type {
    CDVR_TYPE_U8 = 0,
    CDVR_TYPE_U16,
    CDVR_TYPE_I16,
    CDVR_TYPE_F32
} cdvr_type;

typedef struct cdvr_volume {
    size_t dims[3];
    size_t timesteps;
    cdvr_type type;
    double spacing[3];
    double origin[3];
    double direction[9]; /* row-major; column c = world direction of index axis c */
    double window[2];    /* value window [lo, hi] in data units (see above) */
    void *data;
    /* Appended (ABI 5; plugins read the fields above only): the element type of the file the
     * volume was loaded from, "uint8" "int8" "uint16" "int16" "uint32" "int32" "uint64" "int64"
     * "float32" "float64", set by every built-in loader and probe; "" when not loaded from a
     * file (cdvr_volume_create) or the format does not say (a plugin). A type other than the
     * volume's (cdvr_volume_converted) means its values were converted to f32 on load. */
    char source_type[16];
    /* Appended: how many finite file values lay beyond f32's range and were loaded as +-Inf
     * because the load options accepted that (cdvr_raw_opts.f32_overflow_inf); 0 otherwise. */
    uint64_t beyond_f32;
    /* Appended: the world the coordinates are in when the file named it: "RAS" (NIfTI, a NRRD
     * of space right-anterior-superior), "LAS", "LPS" (DICOM, a NRRD left-posterior-superior);
     * "" when unknown. The NRRD writer names it (space:), the NIfTI writer turns LPS/LAS into
     * NIfTI's RAS; nothing else converts. */
    char space[8];
    /* Appended: the voxels' revision, 0 at creation (cdvr_volume_create); every cdvr function
     * that changes voxels of an existing volume in place adds 1 (cdvr_volume_touch), so two
     * equal revisions of one live volume mean the same voxels. Code that writes vol->data
     * directly calls cdvr_volume_touch. A new volume, even one allocated where a freed one
     * lay, starts at 0 again: the revision tells versions of one volume apart, never two
     * volumes (the render context's cdvr_render_ctx_hold_volume, method.h, says how it tells
     * volumes apart). Plugins never read it. */
    uint64_t revision;
} cdvr_volume;

/* Bytes per voxel of a type (1, 2, 2, 4). */
size_t cdvr_type_size(cdvr_type type);
/* "u8", "u16", "i16", "f32". */
const char *cdvr_type_name(cdvr_type type);
/* The file type name of a volume type ("uint8", "uint16", "int16", "float32"). */
const char *cdvr_type_file_name(cdvr_type type);
/* 1 when vol->source_type names a file type other than vol->type's (the loader converted the
 * file's values to f32, with the window computed in double: "converted from float64"). */
int cdvr_volume_converted(const cdvr_volume *vol);
/* Sets vol->space to "RAS", "LAS" or "LPS" (anything else clears it). */
void cdvr_volume_set_space(cdvr_volume *vol, const char *space);
/* Sets vol->source_type (cut to 15 bytes; NULL clears it). */
void cdvr_volume_set_source_type(cdvr_volume *vol, const char *name);
/* Parses a type name (also accepts "uint8", "uchar", "uint16", "int16", "short", "float", "float32");
 * returns 1 on success. */
int cdvr_type_parse(const char *name, cdvr_type *type);

/* Allocates a zero-filled volume; spacing 1, origin 0, direction identity, window [0, 255]
 * for u8 and NAN (not computed) for other types. Fails with CDVR_ERR_NOMEM when the
 * byte count overflows size_t, CDVR_ERR_ARG for a zero dim or zero timesteps. */
cdvr_status cdvr_volume_create(const size_t dims[3], size_t timesteps, cdvr_type type,
                               cdvr_volume **out, cdvr_error *err);
void cdvr_volume_free(cdvr_volume *vol);
/* Marks the voxels of vol as changed in place (vol->revision + 1): code that writes vol->data
 * directly calls it, after the writes and before the volume is rendered again. It changes
 * nothing else (the window of a non-u8 volume is set back to NAN by the writer, see above). */
void cdvr_volume_touch(cdvr_volume *vol);
/* Which voxels of which volume at which revision: for a volume that stays alive (a held one,
 * cdvr_render_ctx_hold_volume in cdvr/method.h), two equal stamps mean the same voxels. A
 * zeroed stamp (vol NULL) is none. */
typedef struct cdvr_frame_stamp {
    const cdvr_volume *vol;
    const void *voxels;  /* the frame's first voxel */
    uint64_t revision;
} cdvr_frame_stamp;
/* The stamp of frame t of vol now. */
cdvr_frame_stamp cdvr_volume_stamp(const cdvr_volume *vol, size_t t);
/* 1 when a and b name the same frame of the same volume at the same revision (none: 0). */
int cdvr_frame_stamp_same(cdvr_frame_stamp a, cdvr_frame_stamp b);

/* Voxels per frame (dims product) and bytes per frame. */
size_t cdvr_volume_voxels(const cdvr_volume *vol);
size_t cdvr_volume_frame_bytes(const cdvr_volume *vol);
/* Pointer to the first voxel of frame t (from 0); NULL if t is out of range. */
void *cdvr_volume_frame(const cdvr_volume *vol, size_t t);
/* Value of voxel (x,y,z) in frame t as double; coordinates must be in range. */
double cdvr_volume_get(const cdvr_volume *vol, size_t x, size_t y, size_t z, size_t t);
/* Minimum and maximum over all finite values (NaN and +-Inf ignored); both 0 if none. */
void cdvr_volume_range(const cdvr_volume *vol, double *lo, double *hi);
/* The value window (see above) into w[0..1]: for u8 the stored one; for other types the
 * cached one, computed as cdvr_volume_range over all timesteps (and cached) on first use. */
void cdvr_volume_window(cdvr_volume *vol, double w[2]);
/* The window without caching (a const volume whose window is not computed yet is scanned). */
void cdvr_volume_window_peek(const cdvr_volume *vol, double w[2]);

/* Geometry (see the top of this file). D is vol->direction, or the identity when that is all
 * zeros. */
void cdvr_volume_direction(const cdvr_volume *vol, double D[9]);
/* world = origin + D * (ijk[0]*sx, ijk[1]*sy, ijk[2]*sz); ijk may be fractional. */
void cdvr_volume_index_to_world(const cdvr_volume *vol, const double ijk[3], double world[3]);
/* Inverse of a 3x3 row-major matrix by cofactors; returns 0 (inv untouched) when
 * |det| <= 1e-12 * (product of the column lengths) or anything is not finite. */
int cdvr_mat3_inverse(const double m[9], double inv[9]);
/* Axis-aligned world bounds of the volume's box (its 8 corner voxel centres). */
void cdvr_volume_bounds(const cdvr_volume *vol, double lo[3], double hi[3]);
/* Checks that spacing is finite and positive, origin finite and D invertible; the error
 * names `what` (e.g. "render") and the offending part. */
cdvr_status cdvr_volume_check_geometry(const cdvr_volume *vol, const char *what, cdvr_error *err);

/* A new volume holding frames [t0, t0+count) of vol (copied), with vol's geometry and value
 * window (computed from all of vol's timesteps when not cached yet). */
cdvr_status cdvr_volume_slice_time(const cdvr_volume *vol, size_t t0, size_t count,
                                   cdvr_volume **out, cdvr_error *err);

/* Raw file description. header_bytes are skipped at the start of the file. timesteps 0
 * means 1. The file must hold exactly header_bytes + product(dims)*timesteps*typesize bytes. */
typedef struct cdvr_raw_opts {
    size_t dims[3];
    size_t timesteps;
    cdvr_type type;
    int big_endian;
    size_t header_bytes;
    double spacing[3]; /* 0 -> 1 */
    /* Limits for every loader (not only raw; appended fields, so older plugins still read the
     * ones above). A NRRD header's detached data files must lie under the header's directory
     * (after realpath: symlinks and '..' resolved) unless allow_outside is nonzero; the refusal
     * names the path. max_bytes caps the voxel bytes a file may claim (after conversion, all
     * timesteps): a larger claim is refused before anything is allocated or inflated; 0 means
     * cdvr_load_max_bytes_default(). */
    int allow_outside;
    uint64_t max_bytes;
    /* ABI 5 and later. The object to read inside the file or directory, for formats that hold
     * several (NULL or "": the format's default, which it documents): a VTK file's array name,
     * a DICOM directory's SeriesInstanceUID or SeriesDescription, an HDF5 dataset or NetCDF
     * variable (where the path gives none as FILE:NAME). A format that holds one object ignores
     * it; a name the file does not hold is refused, listing the names it does. */
    const char *select;
    /* Values beyond f32 (one rule for every loader that converts a file's f64, i64, u64, ... to
     * f32): a finite value whose magnitude exceeds FLT_MAX is refused (CDVR_ERR_FORMAT naming
     * the file, the voxel, the value and its file type) unless f32_overflow_inf is nonzero; then
     * it loads as +-Inf and the count is kept in cdvr_volume.beyond_f32. Appended field. */
    int f32_overflow_inf;
} cdvr_raw_opts;

/* The default max_bytes of cdvr_raw_opts: half the physical memory (sysconf), at least 64 MiB;
 * 1 TiB when the memory size cannot be told. */
uint64_t cdvr_load_max_bytes_default(void);
/* opts->max_bytes, or the default when opts is NULL or gives 0. */
uint64_t cdvr_load_max_bytes(const cdvr_raw_opts *opts);

cdvr_status cdvr_volume_load_raw(const char *path, const cdvr_raw_opts *opts,
                                 cdvr_volume **out, cdvr_error *err);
/* Writes all timesteps' voxels, no header, to `path` (little endian unless big_endian),
 * through a temporary file in the same directory that is renamed over `path` at the end.
 * Exchange formats with their geometry (NRRD, NIfTI, VTI, MetaImage): cdvr_volume_save in
 * cdvr/write.h. */
cdvr_status cdvr_volume_save_raw(const cdvr_volume *vol, const char *path, int big_endian,
                                 cdvr_error *err);

/* Loaders keep u8, u16, i16 and f32 as they are; other file types (i8, u32, i32, i64, u64,
 * f64) become f32, each value rounded to the nearest float, the value window the range of the
 * file's values computed in double, and source_type names the file's type (never silent:
 * tostring(v) and v:info() in Lua say "converted from float64"); a finite value beyond float's
 * range is refused by the NRRD and NIfTI loaders naming the value and its index, and becomes
 * +-Inf in the VTK, MetaImage and TIFF loaders (their window, computed in double, keeps it, as
 * VTK's readers do); NaN and +-Inf stay as they are. Header fields the loaders cannot honour are refused naming the field and its value
 * (README: what the readers refuse), never replaced by a default. */
/* .nrrd / .nhdr through teem. 3D (or 4D: the 4th axis becomes timesteps). */
cdvr_status cdvr_volume_load_nrrd(const char *path, cdvr_volume **out, cdvr_error *err);
/* .nii / .nii.gz through niftilib. 3D, or 4D (timesteps = dim[4]). */
cdvr_status cdvr_volume_load_nifti(const char *path, cdvr_volume **out, cdvr_error *err);
/* Loads path through the format registry (cdvr/format.h: by suffix, a raw description, then
 * the first bytes; an unknown file is refused listing the formats known); raw needs opts (NULL
 * -> error naming the missing dims/type). opts with dims 0 describe no raw file and only carry
 * spacing (> 0: overrides the file's). */
cdvr_status cdvr_volume_load(const char *path, const cdvr_raw_opts *raw, cdvr_volume **out,
                             cdvr_error *err);
/* What cdvr_volume_load of the same file gives (dims, timesteps, type after the loaders'
 * conversions, spacing with raw's override, origin, direction) without reading the voxels; the
 * same choice of format (cdvr/format.h). head->data is left alone, the rest is overwritten. */
cdvr_status cdvr_volume_probe(const char *path, const cdvr_raw_opts *raw, cdvr_volume *head,
                              cdvr_error *err);
/* Loads count files (each 3D, or 4D) and concatenates their timesteps; dims, type and spacing
 * must agree (the error names the first file that differs), unless raw gives all three spacings,
 * which then apply to the whole series. A file whose format lists files (cdvr_format.expand, e.g.
 * a list file) stands for those files. */
cdvr_status cdvr_volume_load_series(const char *const *paths, size_t count,
                                    const cdvr_raw_opts *raw, cdvr_volume **out,
                                    cdvr_error *err);

/* Quantisation to u8 over the window [lo, hi]:
 *   q = round((v - lo) * 255 / (hi - lo)) clamped to [0, 255], round half up (floor(x + 0.5)).
 *   v < lo or -Inf -> 0 (counted in clipped_low); v > hi or +Inf -> 255 (clipped_high);
 *   NaN -> 0 (counted in nan_count). hi == lo: v <= lo -> 0, v > lo -> 255. hi < lo is an error.
 * Inf values are counted in the clipped counts and also in inf_count. */
typedef struct cdvr_quantize_report {
    size_t clipped_low, clipped_high, nan_count, inf_count;
} cdvr_quantize_report;

/* The output keeps in's spacing, origin and direction; its value window is [lo, hi]. */
cdvr_status cdvr_volume_quantize(const cdvr_volume *in, double lo, double hi, cdvr_volume **out,
                                 cdvr_quantize_report *report, cdvr_error *err);

/* Synthetic test fields (cdvr.generate). */
typedef struct cdvr_generate_opts {
    size_t dims[3];   /* 0 -> 64 */
    size_t timesteps; /* 0 -> 1 */
    cdvr_type type;   /* output type: u8 (default) or f32 */
    double value;     /* "box": value inside the box (default 128); "sphere": inside value (255) */
    double radius;    /* "sphere": radius as a fraction of the half extent (default 0.8) */
    double fM, alpha; /* "ml": Marschner-Lobb parameters (default fM = 6, alpha = 0.25) */
} cdvr_generate_opts;

/* name: "box" (constant everywhere), "sphere" (value inside, 0 outside; centre moves with t),
 * "ml" (Marschner-Lobb on [-1,1]^3, scaled to [0,255] for u8), "ramp" (x ramp 0..255). */
cdvr_status cdvr_volume_generate(const char *name, const cdvr_generate_opts *opts,
                                 cdvr_volume **out, cdvr_error *err);

#endif
