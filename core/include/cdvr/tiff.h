/* cdvr/tiff.h - TIFF stacks: one file per z slice (light-sheet and microscopy exports).
 * cdvr_volume_load reads one TIFF file (format "tiff", its pages as z slices); these calls stack
 * the files of a directory (its *.tif and *.tiff, dot files skipped) or of a glob(3) pattern
 * ("scan/slice_*.tif"), in natural order (slice2 before slice10). Every file's pages are slices
 * (a multi-page file adds all of its pages); all must have the first file's width, height and
 * sample type (the error names the first file that differs). Spacing comes from the first file
 * (ImageJ: 1/XResolution, 1/YResolution, spacing=; else 1); origin 0, direction identity.
 * Types as for single files: int8, (u)int32, (u)int64 and float64 become float32 with the
 * window computed in double (source_type says which). cdvr_volume_load of a directory holding
 * .tif/.tiff files is this stack (format "tiff" reads directories, cdvr/format.h rule 0); a
 * series of stacks (a light-sheet time lapse: one directory or one multi-page file per
 * timestep) is cdvr_series_open_path / cdvr.load_series of the parent directory or a glob
 * (cdvr/series.h).
 *
 * Single files: ImageJ descriptions as above; OME-TIFF (an ImageDescription holding OME-XML):
 * x, y, z spacing from PhysicalSizeX/Y/Z in micrometres, SizeZ slices and SizeT timesteps in
 * the page order DimensionOrder gives (cdvr_tiff_ome_parse). */
#ifndef CDVR_TIFF_H
#define CDVR_TIFF_H

#include <stddef.h>

#include "cdvr/error.h"
#include "cdvr/volume.h"

/* ---- what a TIFF's ImageDescription says (ImageJ and OME-XML) --------------------------------
 * The loaders' parsers of the first page's ImageDescription, reachable for tests and fuzzing
 * (tests/fuzz/fuzz_desc.c). They never read past len and refuse, naming the field and its
 * value, what the loader could not honour. */
typedef struct cdvr_tiff_desc {
    double spacing[3];     /* per axis, > 0 when the description gives it, else 0 */
    size_t slices;         /* z: ImageJ slices=, OME SizeZ; 0 when not given */
    size_t frames;         /* t: ImageJ frames=, OME SizeT; 0 when not given */
    size_t channels;       /* ImageJ channels=, OME SizeC; 0 when not given */
    int t_before_z;        /* OME DimensionOrder puts T before Z (XYTZC, XYCTZ, XYTCZ): page
                              t + frames * z holds slice z of frame t */
    char unit[16];         /* OME: the unit spacing is given in ("um": every length is
                              converted to micrometres); ImageJ: unit= as written, or "" */
} cdvr_tiff_desc;

/* ImageJ (text starting "ImageJ="): lines key=value; spacing[2] from spacing=, slices=,
 * frames=, channels=, unit=. Returns 0 for text that is not an ImageJ description. */
int cdvr_tiff_imagej_parse(const char *text, size_t len, cdvr_tiff_desc *out);
/* OME-XML (through expat): the one Image's Pixels: PhysicalSizeX/Y/Z with their units
 * (PhysicalSizeXUnit ...: Ym .. pm, Å, "um"/"µm" the default; converted to micrometres),
 * SizeZ, SizeT, SizeC and DimensionOrder; pages must be SizeZ * SizeT * SizeC. Refused
 * (CDVR_ERR_UNSUPPORTED or CDVR_ERR_FORMAT, naming path, the field and its value): several
 * Images, SizeC > 1, a unit that is not a length, a size or physical size that is not a
 * positive number, TiffData that maps planes to other IFDs or files, a sizes product other than
 * pages, an XML error or a DOCTYPE. */
cdvr_status cdvr_tiff_ome_parse(const char *path, const char *xml, size_t len, size_t pages,
                                cdvr_tiff_desc *out, cdvr_error *err);

/* The stack's header (dims with z = slices, type, spacing) without reading pixels; *files
 * (may be NULL) the number of files. A directory without TIFF files or a pattern that matches
 * nothing is refused saying so. */
cdvr_status cdvr_tiff_probe_stack(const char *where, cdvr_volume *head, size_t *files,
                                  cdvr_error *err);
/* The stack as one volume; *out stays NULL on error. */
cdvr_status cdvr_tiff_load_stack(const char *where, cdvr_volume **out, cdvr_error *err);

#endif
