/* The entropy coder (src/entropy.h, docs/FORMAT.md "Entropy coder"): round trips, the pinned
 * bitstream, hostile streams (every truncation, a trailing byte, every single-bit flip),
 * argument checks, the size bound and compression against the data's order-0 entropy.
 * Streams handed to the decoder are malloc'd at their exact size so ASan sees any overread. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../src/entropy.h" /* internal header: the tests build with -Iinclude only */
#include "harness.h"

#define MAX_ABS MCD_ENTROPY_MAX_ABS

/* ---------------------------------------------------------------- data */
/* Laplacian with the given scale, rounded: what prediction residuals look like. */
static int32_t laplace(uint32_t* rng, double scale) {
    double u = ((double)(mcd_test_rand(rng) >> 8) + 0.5) / 16777216.0 - 0.5;
    double x = -scale * log(1.0 - 2.0 * fabs(u));
    double r = floor(x + 0.5);
    if (r > MAX_ABS) r = MAX_ABS;
    return (int32_t)(u < 0 ? -r : r);
}

/* Magnitudes spread evenly over every exponent 0 ... 29, random signs, some zeros. */
static int32_t any_value(uint32_t* rng) {
    uint32_t e = mcd_test_rand(rng) % 31u, m;
    if (e == 30) return 0;
    m = (1u << e) | (mcd_test_rand(rng) & ((1u << e) - 1u));
    return (mcd_test_rand(rng) & 1u) ? -(int32_t)m : (int32_t)m;
}

/* Empirical order-0 entropy of v[0 .. n) in bytes (n * H / 8), values within +-limit. */
static double order0_bytes(const int32_t* v, size_t n, int32_t limit) {
    size_t bins = 2u * (size_t)limit + 1u, i;
    uint32_t* hist = (uint32_t*)calloc(bins, sizeof *hist);
    double bits = 0.0;
    if (!hist) {
        FAIL("out of memory");
        return 0.0;
    }
    for (i = 0; i < n; ++i) {
        if (v[i] < -limit || v[i] > limit) {
            FAIL("value %ld outside the histogram", (long)v[i]);
            free(hist);
            return 0.0;
        }
        hist[v[i] + limit]++;
    }
    for (i = 0; i < bins; ++i)
        if (hist[i]) bits -= (double)hist[i] * log2((double)hist[i] / (double)n);
    free(hist);
    return bits / 8.0;
}

/* ---------------------------------------------------------------- helpers */
/* Encodes into an exact-size malloc'd stream (caller frees); NULL on failure. */
static uint8_t* encode(const int32_t* v, uint32_t n, uint32_t channels, size_t* size) {
    size_t cap = mcd_entropy_bound(n);
    uint8_t* buf = (uint8_t*)malloc(cap);
    uint8_t* exact;
    mcd_result r;
    *size = 0;
    if (!buf) {
        FAIL("out of memory");
        return NULL;
    }
    r = mcd_entropy_encode(v, n, channels, buf, cap, size);
    CHECK_MSG(r == MCD_OK, "encode of %lu values, %lu channels: %s", (unsigned long)n, (unsigned long)channels,
              mcd_result_string(r));
    CHECK(*size <= cap);
    if (r != MCD_OK) {
        free(buf);
        return NULL;
    }
    exact = (uint8_t*)malloc(*size ? *size : 1u);
    if (exact) memcpy(exact, buf, *size);
    free(buf);
    return exact;
}

/* Encode, decode, compare; returns the stream size. */
static size_t round_trip(const int32_t* v, uint32_t n, uint32_t channels) {
    size_t size, again_size, i;
    uint8_t *s = encode(v, n, channels, &size), *again;
    int32_t* out = (int32_t*)malloc(((size_t)n + 1u) * sizeof *out);
    if (!s || !out) {
        free(s);
        free(out);
        return 0;
    }
    out[n] = 0x5A5A5A5A; /* the decoder writes exactly count values */
    CHECK_RESULT(mcd_entropy_decode(s, size, channels, out, n), MCD_OK);
    for (i = 0; i < n; ++i)
        if (out[i] != v[i]) {
            FAIL("value %lu of %lu (%lu channels): %ld decoded as %ld", (unsigned long)i, (unsigned long)n,
                 (unsigned long)channels, (long)v[i], (long)out[i]);
            break;
        }
    CHECK(out[n] == 0x5A5A5A5A);
    again = encode(v, n, channels, &again_size); /* deterministic */
    CHECK(again && again_size == size && memcmp(again, s, size) == 0);
    free(again);
    free(s);
    free(out);
    return size;
}

/* ---------------------------------------------------------------- tests */
void test_entropy_round_trips(void) {
    static const double scales[] = {0.3, 2.0, 20.0, 300.0, 5000.0, 1e6};
    static const uint32_t channel_counts[] = {1, 2, 3, 7, 16};
    uint32_t n = 20000, rng = 12345u, i, s, c;
    int32_t* v = (int32_t*)malloc(n * sizeof *v);
    if (!v) return;
    memset(v, 0, n * sizeof *v);
    CHECK(round_trip(v, 0, 1) == 0); /* the empty stream has no bytes */
    CHECK(round_trip(v, n, 1) < 40); /* 20000 zeros: a few bits of learning, then ~0.01 bit each */
    for (i = 1; i <= 40; ++i) round_trip(v, i, 1 + i % 16);
    for (s = 0; s < sizeof scales / sizeof scales[0]; ++s) {
        for (i = 0; i < n; ++i) v[i] = laplace(&rng, scales[s]);
        for (c = 0; c < sizeof channel_counts / sizeof channel_counts[0]; ++c) round_trip(v, n, channel_counts[c]);
    }
    for (i = 0; i < n; ++i) v[i] = any_value(&rng);
    for (c = 1; c <= 16; ++c) round_trip(v, n, c);
    for (i = 0; i < n; ++i) v[i] = (i & 1u) ? -MAX_ABS : MAX_ABS; /* the extremes */
    round_trip(v, n, 1);
    round_trip(v, n, 2);
    for (i = 0; i < n; ++i) v[i] = (int32_t)(mcd_test_rand(&rng) % 3u) - 1;
    round_trip(v, n, 5);
    free(v);
}

/* The bitstream is frozen: these bytes are what docs/FORMAT.md produces for these values. The
 * Python tests replay the same vector against an independent implementation of the spec. */
void test_entropy_golden(void) {
    static const int32_t values[16] = {0, 1, -1, 2, -3, 7, -100, 1000, 123456, -1073741823, 1073741823, 0, 5, 0, 0, -2};
    static const uint8_t golden[33] = {0x4D, 0xA7, 0xBA, 0x37, 0xFB, 0xC8, 0xDC, 0x71, 0xE2, 0xCB, 0x7E,
                                       0x28, 0x30, 0x31, 0x7F, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x6F, 0x10,
                                       0x3F, 0xFF, 0xFF, 0xFF, 0xFD, 0xAC, 0xAF, 0x2F, 0x81, 0xC8, 0x00};
    uint8_t out[64];
    int32_t back[16];
    size_t size = 0;
    CHECK_RESULT(mcd_entropy_encode(values, 16, 3, out, sizeof out, &size), MCD_OK);
    CHECK(size == sizeof golden && memcmp(out, golden, sizeof golden) == 0);
    CHECK_RESULT(mcd_entropy_decode(golden, sizeof golden, 3, back, 16), MCD_OK);
    CHECK(memcmp(back, values, sizeof values) == 0);
}

/* Every prefix ends early and the stream plus any one byte does not end where the values do. */
void test_entropy_truncation(void) {
    static const double scales[] = {0.5, 40.0, 1e5};
    uint32_t rng = 777u, n = 300, i, s, extra;
    int32_t v[300], out[300];
    for (s = 0; s < sizeof scales / sizeof scales[0]; ++s) {
        size_t size, len;
        uint8_t *stream, *longer;
        for (i = 0; i < n; ++i) v[i] = laplace(&rng, scales[s]);
        stream = encode(v, n, 2, &size);
        if (!stream) continue;
        for (len = 0; len < size; ++len) {
            uint8_t* prefix = (uint8_t*)malloc(len ? len : 1u);
            if (!prefix) break;
            memcpy(prefix, stream, len);
            CHECK_MSG(mcd_entropy_decode(len ? prefix : NULL, len, 2, out, n) == MCD_ERROR_MALFORMED,
                      "scale %g: prefix of %lu of %lu bytes not rejected", scales[s], (unsigned long)len,
                      (unsigned long)size);
            free(prefix);
        }
        longer = (uint8_t*)malloc(size + 1u);
        if (longer) {
            memcpy(longer, stream, size);
            for (extra = 0; extra < 256; extra += 51) {
                longer[size] = (uint8_t)extra;
                CHECK_RESULT(mcd_entropy_decode(longer, size + 1u, 2, out, n), MCD_ERROR_MALFORMED);
            }
            free(longer);
        }
        /* The count is not in the stream: a last 0 may cost no byte, so a shorter count can
         * also be valid, but then it must give the same values. */
        if (mcd_entropy_decode(stream, size, 2, out, n - 1) == MCD_OK)
            CHECK(v[n - 1] == 0 && memcmp(out, v, (n - 1u) * sizeof *v) == 0);
        free(stream);
    }
    /* The empty stream belongs to count 0 only. */
    {
        uint8_t zero = 0;
        CHECK_RESULT(mcd_entropy_decode(NULL, 0, 1, NULL, 0), MCD_OK);
        CHECK_RESULT(mcd_entropy_decode(&zero, 1, 1, NULL, 0), MCD_ERROR_MALFORMED);
        CHECK_RESULT(mcd_entropy_decode(NULL, 0, 1, out, 1), MCD_ERROR_MALFORMED);
    }
}

/* A flipped bit must never decode silently to the same values: the stream is the encoder's one
 * and only output for what it decodes to, so the decoder either rejects it or returns others. */
void test_entropy_bit_flips(void) {
    static const double scales[] = {0.5, 30.0, 3e4};
    uint32_t rng = 4242u, n = 200, i, s;
    int32_t v[200], out[200];
    unsigned long rejected = 0, changed = 0;
    memset(out, 0, sizeof out); /* a rejected decode stops early and leaves the rest as it was */
    for (s = 0; s < sizeof scales / sizeof scales[0]; ++s) {
        size_t size, pos;
        uint8_t* stream;
        for (i = 0; i < n; ++i) v[i] = laplace(&rng, scales[s]);
        stream = encode(v, n, 3, &size);
        if (!stream) continue;
        for (pos = 0; pos < size * 8u && mcd_test_failures() < 20; ++pos) {
            mcd_result r;
            stream[pos / 8u] ^= (uint8_t)(1u << (pos % 8u));
            r = mcd_entropy_decode(stream, size, 3, out, n);
            if (r == MCD_OK) {
                CHECK_MSG(memcmp(out, v, sizeof v) != 0, "scale %g: bit %lu flipped, same values accepted", scales[s],
                          (unsigned long)pos);
                changed++;
            } else {
                CHECK_RESULT(r, MCD_ERROR_MALFORMED);
                rejected++;
            }
            for (i = 0; i < n; ++i) CHECK(out[i] >= -MAX_ABS && out[i] <= MAX_ABS);
            stream[pos / 8u] ^= (uint8_t)(1u << (pos % 8u));
        }
        free(stream);
    }
    /* Most flips are caught (the final code must be 0 and the length exact). */
    CHECK_MSG(rejected > 10u * changed, "%lu flips rejected, %lu decoded to other values", rejected, changed);
}

void test_entropy_arguments(void) {
    int32_t v[4] = {1, -2, 3, 0}, out[4];
    uint8_t buf[64];
    size_t size = 99, full, cap;
    CHECK(mcd_entropy_bound(0) >= 4);
    CHECK(mcd_entropy_bound(1000) >= mcd_entropy_bound(999));
    CHECK_RESULT(mcd_entropy_encode(v, 4, 0, buf, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_encode(v, 4, 17, buf, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_encode(NULL, 4, 1, buf, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_encode(v, 4, 1, NULL, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_encode(v, 4, 1, buf, sizeof buf, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_encode(NULL, 0, 1, NULL, 0, &size), MCD_OK);
    CHECK(size == 0);
    /* One value out of range, at either end and past the first value. */
    v[2] = MAX_ABS + 1;
    CHECK_RESULT(mcd_entropy_encode(v, 4, 1, buf, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    v[2] = -MAX_ABS - 1;
    CHECK_RESULT(mcd_entropy_encode(v, 4, 1, buf, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    v[2] = INT32_MIN;
    CHECK_RESULT(mcd_entropy_encode(v, 4, 1, buf, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    v[2] = INT32_MAX;
    CHECK_RESULT(mcd_entropy_encode(v, 4, 1, buf, sizeof buf, &size), MCD_ERROR_INVALID_ARGUMENT);
    v[2] = 3;
    CHECK_RESULT(mcd_entropy_encode(v, 4, 1, buf, sizeof buf, &full), MCD_OK);
    /* Every capacity short of the stream fails and writes nothing past it. */
    for (cap = 0; cap < full; ++cap) {
        uint8_t* small = (uint8_t*)malloc(cap ? cap : 1u);
        if (!small) break;
        CHECK_RESULT(mcd_entropy_encode(v, 4, 1, cap ? small : NULL, cap, &size), MCD_ERROR_BUFFER_TOO_SMALL);
        free(small);
    }
    CHECK_RESULT(mcd_entropy_decode(buf, full, 0, out, 4), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_decode(buf, full, 17, out, 4), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_decode(NULL, full, 1, out, 4), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_decode(buf, full, 1, NULL, 4), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_entropy_decode(buf, full, 1, out, 4), MCD_OK);
    CHECK(memcmp(out, v, sizeof v) == 0);
    /* Four 0xFF bytes: the initial code would not be below the initial range. */
    memset(buf, 0xFF, 8);
    CHECK_RESULT(mcd_entropy_decode(buf, 4, 1, out, 1), MCD_ERROR_MALFORMED);
}

/* mcd_entropy_bound holds for the costliest inputs: every exponent context first trained to
 * expect short values, then the largest magnitudes. */
void test_entropy_bound(void) {
    uint32_t n = 0, rng = 99u, e, k, i;
    int32_t* v = (int32_t*)malloc(40000u * sizeof *v);
    size_t size;
    uint8_t* s;
    if (!v) return;
    for (e = 29; e-- > 0;)
        for (k = 0; k < 200; ++k) v[n++] = (int32_t)(1u << e); /* train unary position e to stop */
    for (i = 0; i < 200; ++i) v[n++] = (i & 1u) ? MAX_ABS : -MAX_ABS;
    s = encode(v, n, 1, &size);
    CHECK(s && size <= mcd_entropy_bound(n));
    free(s);
    for (i = 0; i < 40000u; ++i) v[i] = any_value(&rng);
    s = encode(v, 40000u, 16, &size);
    CHECK(s && size <= mcd_entropy_bound(40000u));
    free(s);
    free(v);
}

/* Within 5% of the empirical order-0 entropy on stationary Laplacian data, and well below it
 * when two interleaved channels of different scales each get their own statistics. */
void test_entropy_efficiency(void) {
    static const double scales[] = {1.0, 8.0, 60.0};
    uint32_t n = 100000, rng = 2024u, i, s;
    int32_t* v = (int32_t*)malloc(n * sizeof *v);
    size_t size;
    double h;
    if (!v) return;
    for (s = 0; s < sizeof scales / sizeof scales[0]; ++s) {
        for (i = 0; i < n; ++i) v[i] = laplace(&rng, scales[s]);
        h = order0_bytes(v, n, 100000);
        size = round_trip(v, n, 1);
        CHECK_MSG((double)size <= 1.05 * h && (double)size >= 0.98 * h, "scale %g: %lu bytes, order-0 entropy %.0f",
                  scales[s], (unsigned long)size, h);
    }
    {
        /* Per-channel entropies: each channel's values gathered apart. */
        int32_t* part = (int32_t*)malloc(n / 2u * sizeof *part);
        double h_split = 0.0;
        uint32_t c;
        for (i = 0; i < n; ++i) v[i] = laplace(&rng, (i & 1u) ? 200.0 : 1.0);
        for (c = 0; part && c < 2; ++c) {
            for (i = 0; i < n / 2u; ++i) part[i] = v[2u * i + c];
            h_split += order0_bytes(part, n / 2u, 100000);
        }
        free(part);
        h = order0_bytes(v, n, 100000);
        size = round_trip(v, n, 2);
        CHECK_MSG((double)size <= 0.92 * h && (double)size <= 1.05 * h_split,
                  "two channels: %lu bytes, order-0 entropy of the mix %.0f, of each channel apart %.0f",
                  (unsigned long)size, h, h_split);
    }
    size = round_trip(v, n, 1);
    CHECK_MSG((double)size >= 0.95 * h, "two channels coded as one: %lu bytes below the entropy %.0f", (unsigned long)size, h);
    free(v);
}
