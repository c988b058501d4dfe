/* AES-128 from OpenSSL's libcrypto: the host backend (a *_host.c file: never flashed; a target links
 * its HSM/SHE driver instead). Its low-level AES API is declared here rather
 * than taken from <openssl/aes.h>, so the build needs only the shared library that every CPython
 * with ssl already loads, not the development headers; the layout is OpenSSL's public, stable
 * `struct aes_key_st` (14 rounds max: 4 * 15 round-key words, then the round count). The RFC 4493
 * test vectors in tests/secoc/ fail if this ever disagrees with the library. */
#include "vh_aes128.h"

typedef struct {
    unsigned int rd_key[4 * (14 + 1)];
    int rounds;
} vh_openssl_aes_key;

int AES_set_encrypt_key(const unsigned char *user_key, const int bits, vh_openssl_aes_key *key);
void AES_encrypt(const unsigned char *in, unsigned char *out, const vh_openssl_aes_key *key);

typedef char vh_aes_storage_fits[(sizeof(vh_openssl_aes_key) <= sizeof(vh_aes128_key_t)) ? 1 : -1];

int vh_aes128_setkey(vh_aes128_key_t *k, const uint8_t key[VH_AES_BLOCK])
{
    return AES_set_encrypt_key(key, 128, (vh_openssl_aes_key *)(void *)k->words) == 0 ? 0 : -1;
}

void vh_aes128_encrypt(const vh_aes128_key_t *k, const uint8_t in[VH_AES_BLOCK], uint8_t out[VH_AES_BLOCK])
{
    AES_encrypt(in, out, (const vh_openssl_aes_key *)(const void *)k->words);
}
