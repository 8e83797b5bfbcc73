/* cdvr/names.h - the registry name rule shared by codecs, file formats and render methods. */
#ifndef CDVR_NAMES_H
#define CDVR_NAMES_H

#include <stddef.h>

/* 1 if name is 1 .. size-1 bytes of [a-z0-9_] (size: the buffer a name must fit, NUL
 * included), else 0 (NULL too). */
int cdvr_name_valid(const char *name, size_t size);

#endif
