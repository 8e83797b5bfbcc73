/* cdvr/crc32c.h - CRC-32C (Castagnoli, reflected polynomial 0x82F63B78).
 *
 * The checksum of every stored chunk and range table (cdvr/store.h) and of anything else that
 * wants a fast content check (the GL slicer's texture cache). The value does not depend on the
 * host: cdvr_crc32c(0, "123456789", 9) == 0xE3069283. On x86-64 CPUs with SSE4.2 it uses the
 * crc32 instruction, elsewhere a byte-wise table (core/base/crc32c.c).
 */
#ifndef CDVR_CRC32C_H
#define CDVR_CRC32C_H

#include <stddef.h>
#include <stdint.h>

/* CRC-32C of n bytes at buf, continuing crc (0 for a fresh CRC: crc = cdvr_crc32c(0, buf, n);
 * cdvr_crc32c(cdvr_crc32c(0, a, na), b, nb) is the CRC of a followed by b). */
uint32_t cdvr_crc32c(uint32_t crc, const void *buf, size_t n);

#endif
