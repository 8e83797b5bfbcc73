/* cdvr/regular_file.h - opening input files without blocking on FIFOs or reading devices.
 *
 * Readers accept regular files only: open() on a FIFO waits for a writer (forever), and a device
 * such as /dev/zero or /dev/urandom never ends. The check never blocks: the type is taken with
 * stat first, and the open itself uses O_NONBLOCK (cleared afterwards), so a file swapped for a
 * FIFO in between is still refused rather than waited on. Symbolic links are followed.
 */
#ifndef CDVR_REGULAR_FILE_H
#define CDVR_REGULAR_FILE_H

#include <stdint.h>
#include <stdio.h>
#include <sys/stat.h>

#include "cdvr/error.h"

/* CDVR_OK when path names a regular file (without opening it); else CDVR_ERR_IO with
 * "path: cannot open: reason" or "path: not a regular file (a FIFO); cdvr reads regular files
 * only". *sb (may be NULL) receives its stat. */
cdvr_status cdvr_check_regular_file(const char *path, struct stat *sb, cdvr_error *err);

/* Opens a regular file for reading (errors as above); *fd is a blocking descriptor with
 * O_CLOEXEC, *sb (may be NULL) its fstat. */
cdvr_status cdvr_open_regular_file(const char *path, int *fd, struct stat *sb, cdvr_error *err);

/* The same as a stdio stream opened "rb". */
cdvr_status cdvr_fopen_regular_file(const char *path, FILE **f, struct stat *sb, cdvr_error *err);

/* "a FIFO", "a directory", "a character device", ... for the type bits of st_mode. */
const char *cdvr_file_kind(unsigned mode);

#endif
