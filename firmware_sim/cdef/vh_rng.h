/* cffi declarations: vh_rng.h */
typedef struct {
    uint64_t s[4];
    double spare;
    int has_spare;
} vh_rng_t;
void vh_rng_seed(vh_rng_t *r, uint64_t seed);
uint64_t vh_rng_u64(vh_rng_t *r);
double vh_rng_uniform(vh_rng_t *r);
double vh_rng_gauss(vh_rng_t *r);

