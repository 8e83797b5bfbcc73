/* core/base/crc32c.h - internal: the portable CRC-32C path, exposed so tests can check that it
 * agrees with the hardware path that cdvr_crc32c (cdvr/crc32c.h) picks on x86-64. */
#ifndef CDVR_CRC32C_INTERNAL_H
#define CDVR_CRC32C_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

/* Same contract as cdvr_crc32c, always the byte-wise table. */
uint32_t cdvr_crc32c_portable(uint32_t crc, const void *buf, size_t n);

#endif
