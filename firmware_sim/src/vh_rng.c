/* vh_rng.c - see vh_rng.h. */
#include "vh_rng.h"

#include <math.h>

static uint64_t rotl(uint64_t x, int k)
{
    return (x << k) | (x >> (64 - k));
}

static uint64_t splitmix64(uint64_t *state)
{
    uint64_t z = (*state += 0x9E3779B97F4A7C15u);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9u;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBu;
    return z ^ (z >> 31);
}

void vh_rng_seed(vh_rng_t *r, uint64_t seed)
{
    uint64_t sm = seed;
    int i;
    /* splitmix64 never yields four zero words in a row, so the state is never all zero */
    for (i = 0; i < 4; ++i) {
        r->s[i] = splitmix64(&sm);
    }
    r->spare = 0.0;
    r->has_spare = 0;
}

uint64_t vh_rng_u64(vh_rng_t *r)
{
    uint64_t *s = r->s;
    const uint64_t result = rotl(s[1] * 5u, 7) * 9u;
    const uint64_t t = s[1] << 17;
    s[2] ^= s[0];
    s[3] ^= s[1];
    s[1] ^= s[2];
    s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double vh_rng_uniform(vh_rng_t *r)
{
    /* top 53 bits: every double in [0, 1) on a 2^-53 grid, equally likely */
    return (double)(vh_rng_u64(r) >> 11) * (1.0 / 9007199254740992.0);
}

double vh_rng_gauss(vh_rng_t *r)
{
    double u, v, s, f;
    if (r->has_spare) {
        r->has_spare = 0;
        return r->spare;
    }
    /* polar Box-Muller: a point uniform in the unit disc (s in (0, 1)) gives two deviates */
    do {
        u = 2.0 * vh_rng_uniform(r) - 1.0;
        v = 2.0 * vh_rng_uniform(r) - 1.0;
        s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    f = sqrt(-2.0 * log(s) / s);
    r->spare = v * f;
    r->has_spare = 1;
    return u * f;
}
