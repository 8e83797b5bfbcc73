/* core/store/store_format.h - internal: the in-memory form of a store's metadata, shared by the
 * format code (store.c) and the encode driver (encode.c). The byte layout is documented at the
 * top of store.c. */
#ifndef CDVR_STORE_FORMAT_H
#define CDVR_STORE_FORMAT_H

#include "cdvr/store.h"

#define CDVR_STORE_MAGIC "CDVR\0STR"
#define CDVR_STORE_VERSION 1u
#define CDVR_STORE_HEADER_BYTES 152u
#define CDVR_STORE_VARIANT_BYTES 96u
#define CDVR_STORE_CHUNK_BYTES 64u
#define CDVR_STORE_MAX_VARIANTS 256u

struct cdvr_store {
    char *path;                 /* as given to open/encode */
    int fd;                     /* -1 while encoding */
    cdvr_store_info info;
    cdvr_variant_info *variants; /* info.nvariants */
    double *lzo_min_saving;     /* per variant, as recorded */
    size_t *chunk_first;        /* per variant: index of its first chunk in chunks */
    cdvr_chunk_info *chunks;    /* all chunks, variant-major, in file order */
    size_t nchunks_total;
};

/* Allocates an empty store description with room for nvariants and nchunks (zeroed). */
cdvr_status cdvr_store_alloc(size_t nvariants, size_t nchunks, const char *path,
                             cdvr_store **out, cdvr_error *err);

/* Bytes of header + variant table + chunk index (the metadata CRC follows them);
 * 0 on overflow. */
uint64_t cdvr_store_meta_bytes(size_t nvariants, size_t nchunks);

/* Serialises the metadata and its CRC-32C into buf (cdvr_store_meta_bytes + 4 bytes). */
void cdvr_store_serialize_meta(const cdvr_store *st, uint8_t *buf);

/* Default variant name: "S4T3", "S1T2s" (space packing), "raw". */
void cdvr_store_default_name(cdvr_codec_id codec, const cdvr_pvtc_params *p,
                             char name[CDVR_NAME_MAX]);

/* Decodes one payload of `codec` with params into count frames (no store needed). */
cdvr_status cdvr_store_decode_payload(cdvr_codec_id codec, const cdvr_pvtc_params *params,
                                      const size_t dims[3], const uint8_t *payload,
                                      size_t payload_bytes, uint8_t *const *frames,
                                      size_t count, cdvr_error *err);

/* Payload bytes of one chunk of codec/params for dims (validates params); 0 + err on error. */
cdvr_status cdvr_store_payload_bytes(cdvr_codec_id codec, const cdvr_pvtc_params *params,
                                     const size_t dims[3], size_t *bytes, cdvr_error *err);

#endif
