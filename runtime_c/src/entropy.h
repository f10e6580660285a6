/* The runtime's lossless back-end: an adaptive binary range coder over signed integers
 * (docs/FORMAT.md, "Entropy coder"). Codecs decode their streams with it at sample time (in
 * blocks small enough for the scratch); the Python encoder calls the same functions through the cffi binding, so both sides run one
 * implementation.
 *
 * Value i of a stream is coded with the statistics of channel i % channels, so interleaved
 * components (x y z x y z ...) each adapt to their own distribution. No allocation, no global
 * state: the contexts (about 3.7 KB) live on the stack. Thread-safe. Not installed. */
#ifndef MCD_ENTROPY_H
#define MCD_ENTROPY_H

#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

#define MCD_ENTROPY_MAX_CHANNELS 16u
/* Every value satisfies |v| <= MCD_ENTROPY_MAX_ABS (2^30 - 1). */
#define MCD_ENTROPY_MAX_ABS 0x3FFFFFFF

/* Upper bound of the encoded size of `count` values, whatever they are: 55 bytes per value plus
 * 8. It covers a worst case no real data comes near (typical residuals take 1 to 3 bytes per
 * value), so a caller may first try a smaller buffer and retry with this one on
 * MCD_ERROR_BUFFER_TOO_SMALL. SIZE_MAX when the bound does not fit in size_t. */
size_t mcd_entropy_bound(uint32_t count);

/* Encode values[0 .. count) (each |v| < 2^30) with `channels` context sets (1 ... 16) into
 * out[0 .. capacity) and store the stream's length in *out_size. count == 0 gives an empty
 * stream. Fails with MCD_ERROR_INVALID_ARGUMENT on a value out of range, channels outside
 * 1 ... 16 or a NULL pointer (values may be NULL when count == 0, out when capacity == 0), and
 * MCD_ERROR_BUFFER_TOO_SMALL when the stream does not fit (never writes past capacity); out is
 * then undefined. Deterministic: the same input gives the same bytes on every platform. */
mcd_result mcd_entropy_encode(const int32_t* values, uint32_t count, uint32_t channels,
                              uint8_t* out, size_t capacity, size_t* out_size);

/* Decode exactly `count` values from in[0 .. size) with `channels` context sets into
 * values[0 .. count). Safe on any bytes: never reads outside in[0 .. size). Returns
 * MCD_ERROR_MALFORMED when the stream ends early, does not consume exactly `size` bytes, or is
 * not what mcd_entropy_encode produces for the values it decodes to (its final code is not 0);
 * decoded values are within range by construction. MCD_ERROR_INVALID_ARGUMENT for channels
 * outside 1 ... 16 or a NULL pointer (in may be NULL when size == 0, values when count == 0).
 * On failure values[] holds unspecified (but in-range) numbers. */
mcd_result mcd_entropy_decode(const uint8_t* in, size_t size, uint32_t channels, int32_t* values,
                              uint32_t count);

/* Whether in[0 .. size) decodes to exactly `count` values with `channels` context sets, as
 * mcd_entropy_decode would accept it, without storing them: lets mcd_validate check a
 * stream that is decoded lazily at sample time. Same results as mcd_entropy_decode. */
mcd_result mcd_entropy_check(const uint8_t* in, size_t size, uint32_t channels, uint32_t count);

#endif /* MCD_ENTROPY_H */
