/* cdvr/atomicfile.h - writing a file so that no partial file ever stands under its name.
 *
 *   cdvr_atomic_file af;
 *   if (cdvr_atomic_open(&af, path, err) != CDVR_OK) return err->status;
 *   int failed = write_everything(af.f) != 0;
 *   return cdvr_atomic_commit(&af, failed, err);
 *
 * The data goes to a temporary file beside `path` ("path.tmpXXXXXX"); commit flushes, fsyncs,
 * closes and renames it onto path (then fsyncs the directory so the rename is durable), or
 * removes it when anything failed. Details:
 *  - A symbolic link at path is written through: the temporary file goes beside the link's
 *    target and replaces the target; the link stays.
 *  - An existing path that is not a regular file (/dev/null, /dev/full, a FIFO, a directory)
 *    is refused: the rename would replace it with a plain file.
 *  - The new file keeps the mode of the file it replaces, else gets 0644.
 *  - The temporary file is registered in the cleanup context (cdvr/cleanup.h) until commit, so
 *    SIGINT, SIGTERM or SIGHUP meanwhile removes it.
 *  - Errors name path, never the temporary file (e.g. "out.raw: cannot write: No space left
 *    on device").
 */
#ifndef CDVR_ATOMICFILE_H
#define CDVR_ATOMICFILE_H

#include <stdio.h>

#include "cdvr/error.h"

typedef struct cdvr_atomic_file {
    FILE *f;           /* write the contents here */
    char *tmp_path;    /* the temporary file's name */
    const char *path;  /* the final name (not copied: keep it alive until commit) */
    char *target_path; /* path with its symbolic links followed: what the rename replaces */
    int cleanup_slot;  /* in the cleanup context, or -1 */
} cdvr_atomic_file;

/* Creates the temporary file; on failure af->f is NULL and err names path and the reason. */
cdvr_status cdvr_atomic_open(cdvr_atomic_file *af, const char *path, cdvr_error *err);
/* Finishes the file: failed != 0 (the caller's writes failed) or any flush, fsync, close or
 * rename failure removes the temporary file and returns CDVR_ERR_IO naming path and errno's
 * reason; otherwise the file stands complete under path. Always releases af. */
cdvr_status cdvr_atomic_commit(cdvr_atomic_file *af, int failed, cdvr_error *err);

#endif
