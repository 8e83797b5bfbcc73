/* cdvr/atomicfile.h - writing a file so that no partial file ever stands under its name.
 *
 *   cdvr_atomic_file af;
 *   if (cdvr_atomic_open(&af, path, err) != CDVR_OK) return err->status;
 *   int failed = write_everything(af.f) != 0;
 *   return cdvr_atomic_commit(&af, failed, err);
 *
 * The data goes to an unnamed file in path's directory (O_TMPFILE): nothing exists under any
 * name until commit flushes and fsyncs it and links it in, directly as path where no file
 * stands there, else as "path.tmp.PID.XXXXXX" renamed over path at once; a failure or any
 * death of the process (kill -9 included) just drops it. Where the filesystem has no
 * O_TMPFILE (or /proc/self/fd is missing, or CDVR_ATOMIC_NAMED=1 is in the environment, which
 * tests use to take this path) the data goes to the named temporary "path.tmp.PID.XXXXXX"
 * (mkstemp) that commit renames onto path or removes. Either way commit then fsyncs the
 * directory so the rename is durable. Details:
 *  - A symbolic link at path is written through: the temporary file goes beside the link's
 *    target and replaces the target; the link stays.
 *  - An existing path that is not a regular file (/dev/null, /dev/full, a FIFO, a directory)
 *    is refused: the rename would replace it with a plain file.
 *  - The new file keeps the mode of the file it replaces, else gets 0644.
 *  - A named temporary file is registered in the cleanup context (cdvr/cleanup.h) while it
 *    exists, so a cleanup signal (SIGINT, SIGTERM, SIGQUIT, SIGHUP, SIGUSR1, SIGUSR2, SIGPIPE,
 *    SIGALRM, SIGXCPU, SIGXFSZ, SIGVTALRM, SIGPROF) meanwhile removes it.
 *  - Stale temporaries: on the named path, open first removes every "path.tmp.PID.XXXXXX"
 *    whose PID names no running process (a writer of path killed by SIGKILL; this costs one
 *    scan of the directory per file written). PIDs are those
 *    of this machine's PID namespace: writers sharing a directory across namespaces or hosts
 *    may mistake a live writer's file for a stale one.
 *  - Errors name path, never the temporary file (e.g. "out.raw: cannot write: No space left
 *    on device").
 */
#ifndef CDVR_ATOMICFILE_H
#define CDVR_ATOMICFILE_H

#include <stdio.h>

#include "cdvr/error.h"

typedef struct cdvr_atomic_file {
    FILE *f;           /* write the contents here */
    char *tmp_path;    /* the temporary file's name; NULL while it is unnamed */
    const char *path;  /* the final name (not copied: keep it alive until commit) */
    char *target_path; /* path with its symbolic links followed: what the rename replaces */
    int cleanup_slot;  /* in the cleanup context, or -1 */
    int unnamed;       /* 1: an O_TMPFILE file, linked in at commit */
} cdvr_atomic_file;

/* Creates the temporary file; on failure af->f is NULL and err names path and the reason. */
cdvr_status cdvr_atomic_open(cdvr_atomic_file *af, const char *path, cdvr_error *err);
/* Finishes the file: failed != 0 (the caller's writes failed) or any flush, fsync, close or
 * rename failure removes the temporary file and returns CDVR_ERR_IO naming path and errno's
 * reason; otherwise the file stands complete under path. Always releases af. */
cdvr_status cdvr_atomic_commit(cdvr_atomic_file *af, int failed, cdvr_error *err);

/* Removes the stale temporaries of target (the file a write lands on: symbolic links already
 * followed): "target.tmp.PID.XXXXXX" where PID names no running process. open calls it on
 * the named path. */
void cdvr_atomic_clean_stale(const char *target);

#endif
