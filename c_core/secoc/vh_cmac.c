/* AES-CMAC, RFC 4493 (the mode only: the block cipher is vh_aes128). */
#include "vh_cmac.h"

#include <string.h>

/* RFC 4493 sec. 2.3: K1 = L << 1 (xor Rb if MSB(L)), K2 = K1 << 1 (likewise), Rb = 0x87. */
static void dbl(const uint8_t in[VH_AES_BLOCK], uint8_t out[VH_AES_BLOCK])
{
    uint8_t carry = 0;
    for (int i = VH_AES_BLOCK - 1; i >= 0; --i) {
        out[i] = (uint8_t)((in[i] << 1) | carry);
        carry = (uint8_t)(in[i] >> 7);
    }
    if (in[0] & 0x80u)
        out[VH_AES_BLOCK - 1] ^= 0x87u;
}

int vh_cmac_init(vh_cmac_key_t *c, const uint8_t key[VH_AES_BLOCK])
{
    static const uint8_t zero[VH_AES_BLOCK] = {0};
    uint8_t l[VH_AES_BLOCK];
    memset(c, 0, sizeof *c);
    if (vh_aes128_setkey(&c->aes, key) != 0)
        return -1;
    vh_aes128_encrypt(&c->aes, zero, l); /* L = AES-128(K, 0^128) */
    dbl(l, c->k1);
    dbl(c->k1, c->k2);
    memset(l, 0, sizeof l);
    return 0;
}

/* RFC 4493 sec. 2.4, steps 1-7. */
void vh_cmac(const vh_cmac_key_t *c, const uint8_t *msg, size_t len, uint8_t tag[VH_AES_BLOCK])
{
    size_t n = (len + VH_AES_BLOCK - 1) / VH_AES_BLOCK; /* step 2 */
    int complete = n > 0 && len % VH_AES_BLOCK == 0;    /* step 3 */
    uint8_t x[VH_AES_BLOCK] = {0}, y[VH_AES_BLOCK];
    if (n == 0)
        n = 1;
    for (size_t i = 0; i + 1 < n; ++i) { /* step 6: X = AES(K, X xor M_i) */
        for (int j = 0; j < VH_AES_BLOCK; ++j)
            y[j] = (uint8_t)(x[j] ^ msg[i * VH_AES_BLOCK + (size_t)j]);
        vh_aes128_encrypt(&c->aes, y, x);
    }
    /* step 4: the last block, xor K1 if complete, else padded 10^i and xor K2 */
    size_t off = (n - 1) * VH_AES_BLOCK, rest = len - off;
    for (size_t j = 0; j < VH_AES_BLOCK; ++j) {
        uint8_t m = j < rest ? msg[off + j] : (j == rest ? 0x80u : 0x00u);
        y[j] = (uint8_t)(x[j] ^ m ^ (complete ? c->k1[j] : c->k2[j]));
    }
    vh_aes128_encrypt(&c->aes, y, tag); /* step 6-7: T = AES(K, Y) */
}

void vh_cmac_wipe(vh_cmac_key_t *c)
{
    volatile uint8_t *p = (volatile uint8_t *)c;
    for (size_t i = 0; i < sizeof *c; ++i)
        p[i] = 0;
}
