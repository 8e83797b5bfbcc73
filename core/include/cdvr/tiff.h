/* cdvr/tiff.h - TIFF stacks: one file per z slice (light-sheet and microscopy exports).
 * cdvr_volume_load reads one TIFF file (format "tiff", its pages as z slices); these calls stack
 * the files of a directory (its *.tif and *.tiff, dot files skipped) or of a glob(3) pattern
 * ("scan/slice_*.tif"), in natural order (slice2 before slice10). Every file's pages are slices
 * (a multi-page file adds all of its pages); all must have the first file's width, height and
 * sample type (the error names the first file that differs). Spacing comes from the first file
 * (ImageJ: 1/XResolution, 1/YResolution, spacing=; else 1); origin 0, direction identity.
 * Types as for single files: int8, (u)int32, (u)int64 and float64 become float32 with the
 * window computed in double. */
#ifndef CDVR_TIFF_H
#define CDVR_TIFF_H

#include <stddef.h>

#include "cdvr/error.h"
#include "cdvr/volume.h"

/* The stack's header (dims with z = slices, type, spacing) without reading pixels; *files
 * (may be NULL) the number of files. A directory without TIFF files or a pattern that matches
 * nothing is refused saying so. */
cdvr_status cdvr_tiff_probe_stack(const char *where, cdvr_volume *head, size_t *files,
                                  cdvr_error *err);
/* The stack as one volume; *out stays NULL on error. */
cdvr_status cdvr_tiff_load_stack(const char *where, cdvr_volume **out, cdvr_error *err);

#endif
