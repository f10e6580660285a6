/* libFuzzer target for the entropy coder (src/entropy.h): decode arbitrary bytes, and when they
 * decode, re-encode the values and require the very same bytes back (the stream is the
 * encoder's only output for those values, docs/FORMAT.md "Entropy coder").
 *
 * Input: byte 0 picks channels (1 ... 16), bytes 1-2 the count (0 ... 65535, little-endian),
 * the rest is the stream.
 *
 * Build with clang from the repository root, with every .c file of runtime_c/src:
 *     clang -fsanitize=fuzzer,address,undefined -std=c99 -Iruntime_c/include -Iruntime_c/src \
 *         runtime_c/src/[a-z]*.c runtime_c/fuzz/fuzz_entropy.c -o fuzz_entropy -lm
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "entropy.h"

#define MAX_COUNT 65535u

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

static void broken(const char* why) {
    fprintf(stderr, "entropy coder promise broken: %s\n", why);
    abort();
}

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    uint32_t channels, count, i;
    int32_t* values;
    uint8_t *stream, *again;
    size_t stream_size, again_size = 0;
    mcd_result r;
    if (size < 3) return 0;
    channels = 1u + data[0] % 16u;
    count = (uint32_t)data[1] | ((uint32_t)data[2] << 8);
    stream_size = size - 3;
    /* A copy of exactly stream_size bytes, so ASan catches any read past the end. */
    stream = (uint8_t*)malloc(stream_size ? stream_size : 1u);
    values = (int32_t*)malloc((count ? count : 1u) * sizeof *values);
    if (!stream || !values) broken("out of memory");
    memcpy(stream, data + 3, stream_size);
    r = mcd_entropy_decode(stream_size ? stream : NULL, stream_size, channels, values, count);
    if (r != MCD_OK && r != MCD_ERROR_MALFORMED) broken("decode returned neither OK nor MALFORMED");
    if (r == MCD_OK) {
        for (i = 0; i < count; ++i)
            if (values[i] > MCD_ENTROPY_MAX_ABS || values[i] < -MCD_ENTROPY_MAX_ABS) broken("decoded value out of range");
        /* The stream's own size is enough room: a longer re-encoding is a broken promise too. */
        again = (uint8_t*)malloc(stream_size ? stream_size : 1u);
        if (!again) broken("out of memory");
        if (mcd_entropy_encode(values, count, channels, stream_size ? again : NULL, stream_size, &again_size) != MCD_OK)
            broken("decoded values do not encode into the stream's size");
        if (again_size != stream_size || memcmp(again, stream, stream_size) != 0)
            broken("re-encoding gives other bytes");
        free(again);
    }
    free(values);
    free(stream);
    return 0;
}
