/* clones.h - PG_CLONES: compile a hot plain-C function three times (AVX-512, AVX2+FMA, baseline
 * x86-64) and let the loader pick the best the CPU has, so a portable build (-DPG_NATIVE=OFF) keeps
 * the vector speed of a native one in loops written for the auto-vectoriser. GCC on x86-64 only
 * (elsewhere, and for clang's fuzzing builds, the attribute is empty). */
#ifndef PG_CORE_CLONES_H
#define PG_CORE_CLONES_H

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#define PG_CLONES __attribute__((target_clones("arch=x86-64-v4", "arch=x86-64-v3", "default")))
#else
#define PG_CLONES
#endif

#endif
