/* cdvr/vti.h - VTK image files with a choice of array: XML ImageData (.vti, through expat) and
 * legacy STRUCTURED_POINTS (.vtk). cdvr_volume_load reads the same files through the format
 * table (cdvr/format.h: formats "vti" and "vtk") with the default array; these calls name one.
 *
 * Geometry is VTK's: world of voxel (i,j,k) = Origin + Direction * ((extent start + (i,j,k)) *
 * Spacing), so the volume's origin is the world position of the first voxel of the extent and
 * its direction the file's Direction (identity when absent), columns normalised (their length
 * goes into spacing), which gives the same world box as VTK's reader of the file.
 * Element types: uint8, uint16, int16 and float32 are kept; int8, int32, uint32, int64, uint64
 * and float64 become float32 with the value window the range of the file's values computed in
 * double; info reports which (never silently). Scalar arrays only (one component). */
#ifndef CDVR_VTI_H
#define CDVR_VTI_H

#include "cdvr/error.h"
#include "cdvr/volume.h"

typedef struct cdvr_vti_info {
    char array[128];    /* name of the array read */
    char file_type[16]; /* its type in the file: "uint8" ... "float64" */
    int converted;      /* 1 when its values became float32 (window computed in double) */
} cdvr_vti_info;

/* Header of path (.vti: XML; anything else: legacy .vtk) as cdvr_volume_probe gives it, for the
 * point-data array called array (NULL: the active scalars, else the first point-data array);
 * info may be NULL. No voxel is decoded. */
cdvr_status cdvr_vti_probe(const char *path, const char *array, cdvr_volume *head,
                           cdvr_vti_info *info, cdvr_error *err);
/* The volume of that array; *out stays NULL on error. */
cdvr_status cdvr_vti_load(const char *path, const char *array, cdvr_volume **out,
                          cdvr_vti_info *info, cdvr_error *err);

#endif
