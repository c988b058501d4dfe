/* vh_rng.h - small deterministic random number generator for the simulated car.
 *
 * xoshiro256** (Blackman & Vigna) with its 256-bit state expanded from a 64-bit seed by
 * splitmix64, as its authors recommend; Gaussian deviates by the polar (Marsaglia) form of
 * Box-Muller, which needs no trigonometry and caches the second deviate of each pair.
 * Integer output is bit-reproducible everywhere; the Gaussian path uses sqrt and log, so it
 * is bit-reproducible on a given libm (always within a run and between runs on one machine).
 * Not for cryptography.
 */
#ifndef VH_RNG_H
#define VH_RNG_H

#include <stdint.h>

typedef struct {
    uint64_t s[4];     /* xoshiro256** state, never all zero */
    double spare;      /* second deviate of the last polar pair */
    int has_spare;     /* 1 when spare is unused */
} vh_rng_t;

/* (Re)start the generator: the same seed always gives the same sequence. */
void vh_rng_seed(vh_rng_t *r, uint64_t seed);
/* Next 64 random bits. */
uint64_t vh_rng_u64(vh_rng_t *r);
/* Uniform on [0, 1), 53 random bits. */
double vh_rng_uniform(vh_rng_t *r);
/* Standard normal N(0, 1). */
double vh_rng_gauss(vh_rng_t *r);

#endif /* VH_RNG_H */
