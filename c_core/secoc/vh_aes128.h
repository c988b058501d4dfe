/* The AES-128 block cipher behind the CMAC: one encryption of one block, nothing else.
 *
 * No AES is written here. On the host the backend is OpenSSL's libcrypto (vh_aes128_host.c, the
 * library CPython's own ssl module links); on a target ECU it is the crypto driver of its HSM/SHE
 * (the key never leaves it there). The key schedule is kept in caller-owned storage: no heap. */
#ifndef VH_AES128_H
#define VH_AES128_H

#include <stdint.h>

#define VH_AES_BLOCK 16

/* Opaque storage for the backend's key schedule (OpenSSL's AES_KEY needs 244 bytes). */
typedef struct {
    uint32_t words[64];
} vh_aes128_key_t;

/* 0 on success, -1 if the backend refused the key. */
int vh_aes128_setkey(vh_aes128_key_t *k, const uint8_t key[VH_AES_BLOCK]);
void vh_aes128_encrypt(const vh_aes128_key_t *k, const uint8_t in[VH_AES_BLOCK], uint8_t out[VH_AES_BLOCK]);

#endif
