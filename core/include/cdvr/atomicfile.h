/* cdvr/atomicfile.h - writing a file so that no partial file ever stands under its name.
 *
 *   cdvr_atomic_file af;
 *   if (cdvr_atomic_open(&af, path, err) != CDVR_OK) return err->status;
 *   int failed = write_everything(af.f) != 0;
 *   return cdvr_atomic_commit(&af, failed, err);
 *
 * The data goes to a temporary file beside `path` ("path.tmpXXXXXX", mode 0644); commit
 * flushes, fsyncs, closes and renames it onto path (then fsyncs the directory so the rename is
 * durable), or removes it when anything failed.
 */
#ifndef CDVR_ATOMICFILE_H
#define CDVR_ATOMICFILE_H

#include <stdio.h>

#include "cdvr/error.h"

typedef struct cdvr_atomic_file {
    FILE *f;          /* write the contents here */
    char *tmp_path;   /* the temporary file's name */
    const char *path; /* the final name (not copied: keep it alive until commit) */
} cdvr_atomic_file;

/* Creates the temporary file; on failure af->f is NULL and err names path and the reason. */
cdvr_status cdvr_atomic_open(cdvr_atomic_file *af, const char *path, cdvr_error *err);
/* Finishes the file: failed != 0 (the caller's writes failed) or any flush, fsync, close or
 * rename failure removes the temporary file and returns CDVR_ERR_IO naming path and errno's
 * reason; otherwise the file stands complete under path. Always releases af. */
cdvr_status cdvr_atomic_commit(cdvr_atomic_file *af, int failed, cdvr_error *err);

#endif
