/* vh_aes128_target.c - SecOC's AES backend on the emulated board: none. A real ECU links its
 * HSM/SHE driver here (vh_aes128.h); QEMU's mps2-an386 models no crypto engine and the project
 * writes no AES of its own, so the image refuses every key (SecOC and XCP's seed & key cannot be
 * switched on in it; the processor-in-the-loop host says so rather than run them unkeyed). */
#include <string.h>

#include "vh_aes128.h"

int vh_aes128_setkey(vh_aes128_key_t *k, const uint8_t key[VH_AES_BLOCK])
{
    (void)key;
    memset(k, 0, sizeof *k);
    return -1;
}

void vh_aes128_encrypt(const vh_aes128_key_t *k, const uint8_t in[VH_AES_BLOCK], uint8_t out[VH_AES_BLOCK])
{
    (void)k;
    (void)in;
    memset(out, 0, VH_AES_BLOCK); /* unreachable: no key was ever accepted */
}
