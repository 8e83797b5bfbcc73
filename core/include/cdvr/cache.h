/* cdvr/cache.h - the on-disk cache of things measured or built once per machine: OpenCL
 * program binaries, the remembered decode, fetch and layout choices (core/render/cl), the
 * stage-2 unpack rates (core/codec/stage2).
 *
 * Directory: CDVR_CACHE_DIR, else $XDG_CACHE_HOME/cdvr, else ~/.cache/cdvr (created on
 * first use). An entry is one file named KEY.KIND holding: magic "CDVRCLB1" (8 bytes), the
 * key (32 hex digits), the content's bytes (u64), FNV-1a of the content (u64), the content.
 * A missing, short, corrupt or foreign entry reads as absent; writes go to a temporary file
 * renamed over the entry, so readers never see half an entry. Nothing here is an error:
 * without a cache the caller measures or builds again. */
#ifndef CDVR_CACHE_H
#define CDVR_CACHE_H

#include <stddef.h>

/* A 128-bit key over the n NUL-terminated parts (two FNV-1a streams, different seeds) as 32
 * hex digits and a NUL. Parts are hashed with their terminators, so ("ab","c") != ("a","bc"). */
void cdvr_cache_key(const char *const *parts, size_t n, char key[33]);

/* The entry's path, DIR/KEY.KIND, into path[n]; 0 when no cache directory is known or it
 * cannot be created (then nothing is cached), 1 otherwise. */
int cdvr_cache_path(const char *key, const char *kind, char *path, size_t n);

/* The content of the entry at path when it holds key (malloc'd, *size its bytes), else NULL. */
unsigned char *cdvr_cache_load(const char *path, const char *key, size_t *size);

/* Writes the entry (best effort: a failure leaves the old entry or none). */
void cdvr_cache_store(const char *path, const char *key, const unsigned char *content,
                      size_t size);

#endif
