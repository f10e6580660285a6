/* Entropy coder throughput (runtime_c/src/entropy.c) on rounded Laplacian data, the shape of
 * prediction residuals: encode and decode speed in millions of values per second, and size.
 *
 *     cc -std=c99 -O2 -Iruntime_c/include -Iruntime_c/src runtime_c/src/entropy.c \
 *         bench/bench_entropy.c -o /tmp/bench_entropy -lm && /tmp/bench_entropy [channels]
 */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "entropy.h"

#define COUNT 1000000u
#define REPEATS 5

static double seconds(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static uint32_t next(uint32_t* s) {
    *s ^= *s << 13;
    *s ^= *s >> 17;
    *s ^= *s << 5;
    return *s;
}

int main(int argc, char** argv) {
    static const double scales[] = {0.3, 2.0, 20.0, 300.0, 5000.0};
    uint32_t channels = argc > 1 ? (uint32_t)atoi(argv[1]) : 1u, rng = 1u, i, s;
    int32_t* values = (int32_t*)malloc(COUNT * sizeof *values);
    int32_t* back = (int32_t*)malloc(COUNT * sizeof *back);
    size_t cap = mcd_entropy_bound(COUNT), size = 0;
    uint8_t* stream = (uint8_t*)malloc(cap);
    if (!values || !back || !stream) return 1;
    printf("%u values, %u channel(s)\n", COUNT, channels);
    for (s = 0; s < sizeof scales / sizeof scales[0]; ++s) {
        double best_enc = 1e30, best_dec = 1e30, t;
        int k;
        for (i = 0; i < COUNT; ++i) {
            double u = ((double)(next(&rng) >> 8) + 0.5) / 16777216.0 - 0.5;
            double x = floor(-scales[s] * log(1.0 - 2.0 * fabs(u)) + 0.5);
            values[i] = (int32_t)(u < 0 ? -x : x);
        }
        /* Best of several runs: the machine is shared, the minimum is the least disturbed. */
        for (k = 0; k < REPEATS; ++k) {
            t = seconds();
            if (mcd_entropy_encode(values, COUNT, channels, stream, cap, &size) != MCD_OK) return 1;
            t = seconds() - t;
            if (t < best_enc) best_enc = t;
            t = seconds();
            if (mcd_entropy_decode(stream, size, channels, back, COUNT) != MCD_OK) return 1;
            t = seconds() - t;
            if (t < best_dec) best_dec = t;
        }
        if (memcmp(values, back, COUNT * sizeof *values) != 0) return 1;
        printf("scale %7.1f: %6.3f bits/value, encode %6.1f M/s, decode %6.1f M/s\n", scales[s],
               8.0 * (double)size / COUNT, COUNT / best_enc * 1e-6, COUNT / best_dec * 1e-6);
    }
    free(values);
    free(back);
    free(stream);
    return 0;
}
