/* rng.h - small seeded random generator (splitmix64 seeding, xoshiro256** stream).
 * Same seed gives the same sequence on every machine. */
#ifndef PG_RNG_H
#define PG_RNG_H

#include <stdint.h>

typedef struct { uint64_t s[4]; } pg_rng;

void pg_rng_seed(pg_rng *rng, uint64_t seed);
uint64_t pg_rng_u64(pg_rng *rng);
/* Uniform in [0, 1). */
double pg_rng_uniform(pg_rng *rng);
/* Uniform in [lo, hi). */
double pg_rng_range(pg_rng *rng, double lo, double hi);
/* Standard normal (Box-Muller). */
double pg_rng_normal(pg_rng *rng);
/* Uniform integer in [0, n). */
uint32_t pg_rng_below(pg_rng *rng, uint32_t n);

#endif
