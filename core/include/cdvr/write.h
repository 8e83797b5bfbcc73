/* cdvr/write.h - saving a volume in an exchange format (ParaView, Slicer, ITK-SNAP, 3D Slicer,
 * FSL, VTK and ITK read these), the inverse of cdvr_volume_load: load(save(v)) gives the same
 * voxels, dims, timesteps, type, spacing, origin and direction (NIfTI: within float32, the
 * precision of its header fields).
 *
 * The format is chosen by the name's suffix (case-insensitive):
 *   .nrrd           NRRD through teem (nrrdWrite): "space dimension: 3", "space directions" =
 *                   the columns of D times the spacing, "space origin"; encoding raw, or gzip
 *                   with compress. 4D: a 4th axis of kind time.
 *   .nhdr           the same header (teem) with the voxels in a detached file beside it: NAME.raw,
 *                   or NAME.raw.gz with compress ("data file:" names it).
 *   .nii / .nii.gz  NIfTI-1 through niftilib (nifti_convert_nim2nhdr; zlib for gzip): sform (code 1,
 *                   scanner) = D times the spacing and the origin, in the world the NIfTI loader
 *                   reads (it takes the sform first); qform (code 1) from the same matrix
 *                   (nifti_mat44_to_quatern: exact for an orthonormal D, the nearest rotation
 *                   otherwise); pixdim = spacing. .nii.gz is gzip (compress may not say false),
 *                   .nii plain (compress=true is refused: name it .nii.gz). 4D: dim[4] = timesteps.
 *   .vti            VTK XML ImageData, written by cdvr (no XML library needed): Origin, Spacing,
 *                   Direction (row-major D), one point-data array "scalars" appended raw
 *                   (header_type UInt64), or vtkZLibDataCompressor blocks of 32 KiB with
 *                   compress. A series (timesteps > 1) named NAME.vti is written as NAME.pvd
 *                   (below): a .vti holds one volume.
 *   .pvd            a ParaView collection (cdvr/pvd.h): NAME_0000.vti, NAME_0001.vti, ... (at
 *                   least 4 digits) beside NAME.pvd, one .vti per timestep as above, and the
 *                   .pvd listing them with their times (opts->times, else 0, 1, ...); a failed
 *                   save removes the frames it wrote. Loads back with cdvr.load_series(NAME.pvd),
 *                   times kept.
 *   .mha / .mhd     MetaImage as ITK writes it: ObjectType, NDims, DimSize, ElementSpacing,
 *                   Offset, TransformMatrix (the direction of index axis 0, then of axis 1, ...:
 *                   ITK's order), ElementType MET_UCHAR/MET_USHORT/MET_SHORT/MET_FLOAT; .mha holds
 *                   the voxels (LOCAL), .mhd names NAME.raw (NAME.zraw with compress) beside it;
 *                   compress: CompressedData = True, one zlib stream, CompressedDataSize. 4D:
 *                   NDims 4 (the 4th axis time, spacing 1).
 * Voxels are written in the machine's byte order, which every header records. The value window
 * of a u8 volume (what its codes stand for, e.g. a decoded store frame's) is not stored: the
 * files hold the codes.
 *
 * Every file goes through cdvr/atomicfile.h: nothing stands under a name until it is complete,
 * and a failed save leaves nothing new (for a header with a detached data file the data file is
 * written first and removed again when the header fails). A target that exists and is not a
 * regular file (a directory, a FIFO, a device) is refused. Errors name the file and the reason.
 *
 * Why a separate writer table (core/io/write.c) and not a `save` member of cdvr_format: the
 * format table is the plugin ABI (cdvr/plugin.h); a member would need an ABI bump and the
 * widening copy of older plugins' tables for something only built-in formats do today. A plugin
 * that wants to write can gain that member later without changing this call. */
#ifndef CDVR_WRITE_H
#define CDVR_WRITE_H

#include "cdvr/error.h"
#include "cdvr/volume.h"

typedef struct cdvr_save_opts {
    /* 1: zlib/gzip (see above); 0: uncompressed; -1: the suffix's default (.nii.gz gzip, the
     * others uncompressed). A NULL opts means -1. */
    int compress;
    /* Appended: the time of each timestep (timesteps values) for a .pvd collection, or NULL
     * (0, 1, 2, ...). Other formats ignore it. */
    const double *times;
} cdvr_save_opts;

/* Saves vol (all timesteps) to path in the format its suffix names (above). An unknown suffix
 * is CDVR_ERR_ARG listing the suffixes; a geometry that cdvr_volume_check_geometry refuses CDVR_ERR_ARG;
 * I/O failures CDVR_ERR_IO naming the file. */
cdvr_status cdvr_volume_save(const cdvr_volume *vol, const char *path, const cdvr_save_opts *opts,
                             cdvr_error *err);

/* ".nrrd .nhdr .nii .nii.gz .vti .pvd .mha .mhd" for messages and help. */
const char *cdvr_save_suffixes(void);

#endif
