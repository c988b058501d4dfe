/* AES-CMAC (RFC 4493; NIST SP 800-38B), the MAC of AUTOSAR SecOC's CMAC/AES-128 profiles. */
#ifndef VH_CMAC_H
#define VH_CMAC_H

#include <stddef.h>
#include <stdint.h>

#include "vh_aes128.h"

typedef struct {
    vh_aes128_key_t aes;
    uint8_t k1[VH_AES_BLOCK]; /* RFC 4493 sec. 2.3 subkeys */
    uint8_t k2[VH_AES_BLOCK];
} vh_cmac_key_t;

/* Key schedule and subkeys; 0 on success, -1 if the cipher refused the key. */
int vh_cmac_init(vh_cmac_key_t *c, const uint8_t key[VH_AES_BLOCK]);
/* The full 128-bit tag of msg[0..len) (RFC 4493 sec. 2.4). */
void vh_cmac(const vh_cmac_key_t *c, const uint8_t *msg, size_t len, uint8_t tag[VH_AES_BLOCK]);
/* Wipes the key material (the caller's storage). */
void vh_cmac_wipe(vh_cmac_key_t *c);

#endif
