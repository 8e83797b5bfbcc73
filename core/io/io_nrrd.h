/* core/io/io_nrrd.h - the NRRD header and its data files as io_nrrd_check.c finds and checks them,
 * for io_nrrd.c. Internal to libcdvr. */
#ifndef CDVR_IO_NRRD_H
#define CDVR_IO_NRRD_H

#include <stdint.h>
#include <teem/nrrd.h>

#include "cdvr/volume.h"

#define CDVR_NRRD_HEADER_MAX (4u << 20) /* header bytes (with a LIST of data files) */
#define CDVR_NRRD_FILES_MAX 16384       /* detached data files (LIST or FORMAT min max step) */

typedef struct cdvr_nrrd_source cdvr_nrrd_source;

/* Reads path's header (teem parses it from our copy, with the data file field taken out, so
 * teem opens nothing), resolves its data files and checks them (see io_nrrd_check.c): at most
 * CDVR_NRRD_FILES_MAX, each under the header's directory after realpath unless
 * opts->allow_outside, the claimed size within cdvr_load_max_bytes(opts). With header_only the
 * data files are only resolved and confined (no size checks). */
cdvr_status cdvr_nrrd_open(const char *path, const cdvr_raw_opts *opts, int header_only,
                           cdvr_nrrd_source **out, cdvr_error *err);
void cdvr_nrrd_close(cdvr_nrrd_source *s);
/* The parsed header (no data) and teem's state of that parse (encoding, endian, seen fields). */
const Nrrd *cdvr_nrrd_header(const cdvr_nrrd_source *s);
const NrrdIoState *cdvr_nrrd_io(const cdvr_nrrd_source *s);
/* 1 when cdvr_nrrd_stream reads the data itself (raw, gzip, bzip2 encodings); else the data must
 * be read by teem (nrrdLoad), after the checks cdvr_nrrd_open made. */
int cdvr_nrrd_streamable(const cdvr_nrrd_source *s);
/* 1 when the file's multi-byte values must be byte-swapped on this host. */
int cdvr_nrrd_swap(const cdvr_nrrd_source *s);
/* Passes the data bytes (byte skip, line skip and decompression done), in file order, to sink in
 * pieces; exactly the claimed bytes: a stream that ends early or goes on past the claim, or a
 * corrupt one, is refused naming the file. sink returns 0 to stop (then CDVR_ERR_FORMAT with
 * the message it left in err). */
cdvr_status cdvr_nrrd_stream(const cdvr_nrrd_source *s,
                             int (*sink)(void *ud, const unsigned char *p, size_t n), void *ud,
                             cdvr_error *err);

#endif
