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
};

/* Allocates an empty store description with room for nvariants and nchunks (zeroed). */
cdvr_status cdvr_store_alloc(size_t nvariants, size_t nchunks, const char *path,
                             cdvr_store **out, cdvr_error *err);

/* Bytes of header + variant table + chunk index of format version 2 (the metadata CRC
 * follows them); 0 on overflow. */
uint64_t cdvr_store_meta_bytes(size_t nvariants, size_t nchunks);

/* Serialises the metadata (version 2) and its CRC-32C into buf (cdvr_store_meta_bytes + 4). */
void cdvr_store_serialize_meta(const cdvr_store *st, uint8_t *buf);

#endif
