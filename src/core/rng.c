/* rng.c - xoshiro256** seeded through splitmix64. */
#include "core/rng.h"
#include "core/mathx.h"

static uint64_t splitmix64(uint64_t *x)
{
    uint64_t z = (*x += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

void pg_rng_seed(pg_rng *rng, uint64_t seed)
{
    for (int i = 0; i < 4; i++) rng->s[i] = splitmix64(&seed);
}

static inline uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }

uint64_t pg_rng_u64(pg_rng *rng)
{
    uint64_t *s = rng->s;
    uint64_t result = rotl(s[1] * 5, 7) * 9;
    uint64_t t = s[1] << 17;
    s[2] ^= s[0]; s[3] ^= s[1]; s[1] ^= s[2]; s[0] ^= s[3];
    s[2] ^= t;
    s[3] = rotl(s[3], 45);
    return result;
}

double pg_rng_uniform(pg_rng *rng) { return (pg_rng_u64(rng) >> 11) * 0x1.0p-53; }

double pg_rng_range(pg_rng *rng, double lo, double hi) { return lo + (hi - lo) * pg_rng_uniform(rng); }

double pg_rng_normal(pg_rng *rng)
{
    double u1 = pg_rng_uniform(rng), u2 = pg_rng_uniform(rng);
    if (u1 < 1e-300) u1 = 1e-300;
    return sqrt(-2.0 * log(u1)) * cos(2.0 * PG_PI * u2);
}

uint32_t pg_rng_below(pg_rng *rng, uint32_t n)
{
    return (uint32_t)(((pg_rng_u64(rng) >> 32) * (uint64_t)n) >> 32);
}
