/* core/io/io_hdf5.h - what the HDF5 and NetCDF loaders (io_hdf5.c, io_netcdf.c) share. Internal
 * to libcdvr; not a public header.
 *
 * The HDF5 library lock (named context `hdf5_library` in io_hdf5.c): Debian's libhdf5 (serial)
 * is built without its thread-safety option, and libnetcdf calls it for netCDF-4 files (and is
 * not thread-safe itself), so every call into either library, from open to close, is made
 * holding this one mutex. Loads of HDF5 and NetCDF files in several threads therefore run one
 * after the other (other formats are not held up). While it is held, HDF5's automatic error
 * printing is off (H5Eset_auto2 NULL; the previous handler is put back at unlock): the loaders
 * turn HDF5's error stack into their messages instead (cdvr_hdf5_reason). */
#ifndef CDVR_IO_HDF5_H
#define CDVR_IO_HDF5_H

#include <stddef.h>

#include "cdvr/error.h"
#include "cdvr/format.h"
#include "cdvr/volume.h"

void cdvr_hdf5_lock(void);
void cdvr_hdf5_unlock(void);

/* The innermost message of HDF5's error stack of this thread (empty when none) into out, and
 * clears the stack. Call holding the lock. */
void cdvr_hdf5_reason(char *out, size_t n);

/* The file and object a FILE:NAME path (or opts->select) names, and the file checked as a
 * regular file. On CDVR_OK, s->file is the file's path (for messages), s->name the object
 * ("" when neither names one), s->open the path to give the library: /proc/self/fd/N of a
 * descriptor this opened after the check (so a file swapped for a FIFO in between is not
 * waited on), or the file itself where /proc is missing. cdvr_subpath_done closes it. */
typedef struct cdvr_subpath {
    char *file, *name;
    char open[64 + 4096];
    int fd;
} cdvr_subpath;
cdvr_status cdvr_subpath_begin(const cdvr_format *f, const char *path, const cdvr_raw_opts *opts,
                               const char *what, cdvr_subpath *s, cdvr_error *err);
void cdvr_subpath_done(cdvr_subpath *s);

#endif
