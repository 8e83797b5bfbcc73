/* core/store/store_format.h - internal: the in-memory form of a store's metadata, shared by the
 * format code (store.c) and the encode driver (encode.c). The byte layout is documented at the
 * top of store.c. */
#ifndef CDVR_STORE_FORMAT_H
#define CDVR_STORE_FORMAT_H

#include "cdvr/store.h"

#define CDVR_STORE_MAGIC "CDVR\0STR"
#define CDVR_STORE_VERSION 2u
#define CDVR_STORE_HEADER_BYTES 256u
#define CDVR_STORE_VARIANT_BYTES 160u
#define CDVR_STORE_CHUNK_BYTES 128u
#define CDVR_STORE_MAX_VARIANTS 256u
/* format version 1 (read only) */
#define CDVR_STORE_V1_HEADER_BYTES 152u
#define CDVR_STORE_V1_VARIANT_BYTES 96u
#define CDVR_STORE_V1_CHUNK_BYTES 64u

struct cdvr_store {
    char *path;                 /* as given to open/encode */
    int fd;                     /* -1 while encoding */
    cdvr_store_info info;
    cdvr_variant_info *variants; /* info.nvariants */
    size_t *chunk_first;        /* per variant: index of its first chunk in chunks */
    cdvr_chunk_info *chunks;    /* all chunks, variant-major, then group, then brick */
    size_t nchunks_total;
    uint64_t base;              /* file offset of this store's byte 0 (a level inside a
                                   multi-resolution store; 0 otherwise) */
    uint64_t levels_offset;     /* level directory (levels.c), 0 without levels */
    struct cdvr_store **levels; /* info.nlevels entries: [0] NULL (this store), [l] level l */
    double *level_psnr, *level_maxerr; /* against level 0 (levels.c) */
    uint64_t *level_bytes;      /* bytes of each level's embedded store ([0]: this one's) */
};

/* Opens the store whose bytes are [base, base + size) of the open file fd (taking fd, closed
 * on failure and by cdvr_store_close). cdvr_store_open is this for a whole file. */
cdvr_status cdvr_store_open_at(const char *path, int fd, uint64_t base, uint64_t size,
                               cdvr_store **out, cdvr_error *err);
/* pread of n bytes at offset (from the store's byte 0); short reads are CDVR_ERR_CORRUPT. */
cdvr_status cdvr_store_read_bytes(const cdvr_store *st, uint8_t *buf, size_t n, uint64_t offset,
                                  cdvr_error *err);
/* levels.c: reads the level directory and opens levels 1 .. nlevels-1; frees them. */
cdvr_status cdvr_store_open_levels(cdvr_store *st, uint32_t nlevels, uint64_t offset,
                                   cdvr_error *err);
void cdvr_store_close_levels(cdvr_store *st);
/* levels.c: cdvr_store_encode_source for opts->levels >= 2. */
cdvr_status cdvr_store_encode_levels(const cdvr_encode_source *src, const cdvr_encode_opts *opts,
                                     const char *path, cdvr_error *err);

/* Allocates an empty store description with room for nvariants and nchunks (zeroed). */
cdvr_status cdvr_store_alloc(size_t nvariants, size_t nchunks, const char *path,
                             cdvr_store **out, cdvr_error *err);

/* Bytes of header + variant table + chunk index of format version 2 (the metadata CRC
 * follows them); 0 on overflow. */
uint64_t cdvr_store_meta_bytes(size_t nvariants, size_t nchunks);

/* Serialises the metadata (version 2) and its CRC-32C into buf (cdvr_store_meta_bytes + 4). */
void cdvr_store_serialize_meta(const cdvr_store *st, uint8_t *buf);

#endif
