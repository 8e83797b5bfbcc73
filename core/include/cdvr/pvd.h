/* cdvr/pvd.h - ParaView data collections (.pvd): a time series of VTK files.
 *
 * A .pvd file is VTK XML (read through expat):
 *     <VTKFile type="Collection" version="0.1">
 *       <Collection>
 *         <DataSet timestep="0.5" part="0" file="run/run_0000.vti"/>
 *         ...
 * Format "pvd" (cdvr/format.h) reads it as the series of its DataSet files (its `expand_opts`):
 * cdvr.load_series("run.pvd") and cdvr_series_open of it open those files, in the order of
 * their timestep values (ParaView's; equal values keep the file's order), and keep the values
 * (cdvr_series_times, Lua v:times()); cdvr.load of it loads every file into one volume. File
 * names are relative to the .pvd's directory (absolute names as they are) and must lie under
 * that directory once resolved by realpath unless the load option allow_outside is set; a
 * DataSet naming another .pvd is refused (no nesting). Refused, naming the file and the
 * DataSet: another root than VTKFile type="Collection", a DataSet without file= or timestep=,
 * a timestep that is not a finite number, a part other than 0 (multi-part collections), no
 * DataSet, more than 10^6 of them or a file over 64 MiB. */
#ifndef CDVR_PVD_H
#define CDVR_PVD_H

#include <stddef.h>

#include "cdvr/error.h"
#include "cdvr/volume.h"

typedef struct cdvr_pvd_entry {
    double time;   /* timestep= */
    char *file;    /* resolved path (cdvr_pvd_read) or file= as written (cdvr_pvd_parse) */
} cdvr_pvd_entry;

/* The DataSets of the collection at path, sorted by time, files resolved and confined as
 * above (opts may be NULL). *out is a malloc'd array of *n (cdvr_pvd_free). */
cdvr_status cdvr_pvd_read(const char *path, const cdvr_raw_opts *opts, cdvr_pvd_entry **out,
                          size_t *n, cdvr_error *err);
/* The same from text[0..len) (path only names it in messages); file names as written. */
cdvr_status cdvr_pvd_parse(const char *path, const char *text, size_t len, cdvr_pvd_entry **out,
                           size_t *n, cdvr_error *err);
void cdvr_pvd_free(cdvr_pvd_entry *entries, size_t n);
/* The format's expand_opts: the DataSet files, confined by the load options (allow_outside). */
cdvr_status cdvr_pvd_expand(const char *path, const cdvr_raw_opts *opts,
                            int (*add)(void *ud, const char *file), void *ud, cdvr_error *err);

#endif
