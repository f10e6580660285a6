/* Adaptive binary range coder over signed integers (docs/FORMAT.md, "Entropy coder").
 *
 * A value is binarized as: zero flag, sign, exponent e = floor(log2 |v|) in unary, the two
 * mantissa bits below the leading one with adaptive contexts, the rest raw. Every adaptive bit
 * has its own 16-bit state: a 12-bit probability of a 0 and a 4-bit update count. The count
 * makes a fresh context learn fast (shift 1, 2, 2, 3, ...) and settle at shift 5, which saves
 * a few percent on short streams at no cost on long ones. */
#include "entropy.h"

/* ---------------------------------------------------------------- constants */
#define PROB_BITS 12u
#define PROB_ONE (1u << PROB_BITS)
#define PROB_MASK (PROB_ONE - 1u)
#define COUNT_MAX 15u
#define CTX_INIT (PROB_ONE / 2u) /* p = 1/2, count 0 */
#define TOP (1u << 24)           /* range is renormalised to at least this */

#define MAX_EXP 29u /* |v| < 2^30, so e = floor(log2 |v|) <= 29 */
#define MANT_CTX_BITS 2u

/* Per-channel context layout (docs/FORMAT.md). */
#define CTX_ZERO 0u
#define CTX_SIGN 1u
#define CTX_EXP 2u                      /* + j for unary position j = 0 ... 28 */
#define CTX_MANT (CTX_EXP + MAX_EXP)    /* + 3 (e - 1) + node, node 0 ... 2 */
#define CTX_PER_CHANNEL (CTX_MANT + 3u * MAX_EXP)

/* Update shift by update count n: bit length of n + 1, so 1, 2, 2, 3, 3, 3, 3, 4 ... 4, 5. */
static const uint8_t k_shift[COUNT_MAX + 1u] = {1, 2, 2, 3, 3, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5};

static inline uint16_t ctx_update(uint32_t s, uint32_t bit) {
    uint32_t p = s & PROB_MASK, n = s >> PROB_BITS;
    uint32_t shift = k_shift[n];
    /* p stays in [1, 4095]: (4096 - p) >> shift < 4096 - p and p >> shift < p. */
    p = bit ? p - (p >> shift) : p + ((PROB_ONE - p) >> shift);
    n += n < COUNT_MAX;
    return (uint16_t)(p | (n << PROB_BITS));
}

/* floor(log2 m) for 1 <= m < 2^30, by halving the search interval. */
static uint32_t floor_log2(uint32_t m) {
    uint32_t e = 0;
    if (m >> 16) { m >>= 16; e += 16; }
    if (m >> 8) { m >>= 8; e += 8; }
    if (m >> 4) { m >>= 4; e += 4; }
    if (m >> 2) { m >>= 2; e += 2; }
    if (m >> 1) e += 1;
    return e;
}

static void ctx_init(uint16_t* ctx, uint32_t channels) {
    uint32_t i;
    for (i = 0; i < channels * CTX_PER_CHANNEL; ++i) ctx[i] = (uint16_t)CTX_INIT;
}

size_t mcd_entropy_bound(uint32_t count) {
    /* Per value at most 34 adaptive bits (each narrows the range by at most 2^12.0004) and 26
     * raw bits: < 434.02 bits = 54.26 bytes. The flush adds 4 bytes, the range's headroom 1. */
#if SIZE_MAX / 55u < 0xFFFFFFFFu
    if ((size_t)count > (SIZE_MAX - 8u) / 55u) return SIZE_MAX;
#endif
    return (size_t)count * 55u + 8u;
}

/* ---------------------------------------------------------------- encoder */
typedef struct encoder {
    uint64_t low;     /* 33 bits: bit 32 is a carry into the bytes already produced */
    uint32_t range;
    uint8_t cache;    /* the oldest byte not yet written: a carry may still increment it */
    size_t pending;   /* cache plus the 0xFF bytes after it; 0 before the first byte */
    uint8_t* out;
    size_t capacity, pos;
} encoder;

static inline void put_byte(encoder* e, uint8_t b) {
    if (e->pos < e->capacity) e->out[e->pos] = b;
    e->pos++; /* counted past capacity so the caller learns the stream does not fit */
}

/* Move the top byte of low out. A byte below 0xFF (or any byte once a carry arrived) settles
 * everything pending; a 0xFF byte waits, since a later carry would turn it into 0x00. */
static void shift_low(encoder* e) {
    if (e->pending == 0 || (uint32_t)e->low < 0xFF000000u || (e->low >> 32) != 0) {
        uint8_t carry = (uint8_t)(e->low >> 32);
        if (e->pending) {
            put_byte(e, (uint8_t)(e->cache + carry));
            while (--e->pending) put_byte(e, (uint8_t)(0xFFu + carry));
        }
        e->cache = (uint8_t)(e->low >> 24);
        e->pending = 1;
    } else {
        e->pending++;
    }
    e->low = (e->low & 0x00FFFFFFu) << 8;
}

static inline void enc_bit(encoder* e, uint16_t* ctx, uint32_t bit) {
    uint32_t bound = (e->range >> PROB_BITS) * (uint32_t)(*ctx & PROB_MASK);
    if (bit) {
        e->low += bound;
        e->range -= bound;
    } else {
        e->range = bound;
    }
    *ctx = ctx_update(*ctx, bit);
    while (e->range < TOP) {
        e->range <<= 8;
        shift_low(e);
    }
}

/* The low `n` bits of v, most significant first, each with probability 1/2. */
static inline void enc_raw(encoder* e, uint32_t v, uint32_t n) {
    while (n--) {
        e->range >>= 1;
        if ((v >> n) & 1u) e->low += e->range;
        if (e->range < TOP) {
            e->range <<= 8;
            shift_low(e);
        }
    }
}

static inline void enc_value(encoder* e, uint16_t* c, int32_t v) {
    uint32_t m, x, j;
    if (v == 0) {
        enc_bit(e, c + CTX_ZERO, 0);
        return;
    }
    enc_bit(e, c + CTX_ZERO, 1);
    enc_bit(e, c + CTX_SIGN, v < 0);
    m = v < 0 ? 0u - (uint32_t)v : (uint32_t)v;
    x = floor_log2(m);
    for (j = 0; j < x; ++j) enc_bit(e, c + CTX_EXP + j, 1);
    if (x < MAX_EXP) enc_bit(e, c + CTX_EXP + x, 0);
    if (x >= 1) {
        uint16_t* t = c + CTX_MANT + 3u * (x - 1u);
        uint32_t b1 = (m >> (x - 1u)) & 1u;
        enc_bit(e, t, b1);
        if (x >= 2) {
            enc_bit(e, t + 1u + b1, (m >> (x - 2u)) & 1u);
            enc_raw(e, m, x - MANT_CTX_BITS);
        }
    }
}

mcd_result mcd_entropy_encode(const int32_t* values, uint32_t count, uint32_t channels,
                              uint8_t* out, size_t capacity, size_t* out_size) {
    uint16_t ctx[MCD_ENTROPY_MAX_CHANNELS * CTX_PER_CHANNEL];
    encoder e;
    uint32_t i, ch = 0;
    int k;
    if (!out_size) return MCD_ERROR_INVALID_ARGUMENT;
    *out_size = 0;
    if (channels < 1 || channels > MCD_ENTROPY_MAX_CHANNELS || (!values && count) ||
        (!out && capacity))
        return MCD_ERROR_INVALID_ARGUMENT;
    if (count == 0) return MCD_OK; /* the empty stream */
    ctx_init(ctx, channels);
    e.low = 0;
    e.range = 0xFFFFFFFFu;
    e.cache = 0;
    e.pending = 0;
    e.out = out;
    e.capacity = capacity;
    e.pos = 0;
    for (i = 0; i < count; ++i) {
        int32_t v = values[i];
        if (v > MCD_ENTROPY_MAX_ABS || v < -MCD_ENTROPY_MAX_ABS) return MCD_ERROR_INVALID_ARGUMENT;
        enc_value(&e, ctx + ch * CTX_PER_CHANNEL, v);
        if (++ch == channels) ch = 0;
        /* Past capacity already: stop instead of coding the rest for nothing. */
        if (e.pos > capacity) return MCD_ERROR_BUFFER_TOO_SMALL;
    }
    /* Four shifts move all of low into cache/pending, the fifth writes them out: the stream
     * ends with low itself, so a decoder finishes with code == 0. */
    for (k = 0; k < 5; ++k) shift_low(&e);
    if (e.pos > capacity) return MCD_ERROR_BUFFER_TOO_SMALL;
    *out_size = e.pos;
    return MCD_OK;
}

/* ---------------------------------------------------------------- decoder */
typedef struct decoder {
    uint32_t range, code;
    uint32_t bad;     /* nonzero once code >= range was seen: not an encoder's stream */
    const uint8_t* in;
    size_t size, pos; /* pos may pass size: reads there give 0 and fail the decode */
} decoder;

static inline void dec_normalize(decoder* d) {
    while (d->range < TOP) {
        /* A stream from the encoder keeps code < range; checking here, before the shift can
         * drop code's top bits, catches every violation (it persists until the next shift). */
        d->bad |= d->code >= d->range;
        d->range <<= 8;
        d->code = (d->code << 8) | (d->pos < d->size ? d->in[d->pos] : 0u);
        d->pos++;
    }
}

/* Branch-free selects: the bit is as unpredictable as its probability, and a mispredicted
 * branch costs more than computing both sides. */
static inline uint32_t dec_bit(decoder* d, uint16_t* ctx) {
    uint32_t bound = (d->range >> PROB_BITS) * (uint32_t)(*ctx & PROB_MASK);
    uint32_t bit = d->code >= bound, mask = 0u - bit;
    d->code -= bound & mask;
    d->range = bit ? d->range - bound : bound;
    *ctx = ctx_update(*ctx, bit);
    dec_normalize(d);
    return bit;
}

static inline uint32_t dec_raw(decoder* d, uint32_t n) {
    uint32_t v = 0;
    while (n--) {
        uint32_t bit;
        d->range >>= 1;
        bit = d->code >= d->range;
        d->code -= d->range & (0u - bit);
        v = (v << 1) | bit;
        dec_normalize(d);
    }
    return v;
}

static inline int32_t dec_value(decoder* d, uint16_t* c) {
    uint32_t x = 0, m, neg;
    if (!dec_bit(d, c + CTX_ZERO)) return 0;
    neg = dec_bit(d, c + CTX_SIGN);
    while (x < MAX_EXP && dec_bit(d, c + CTX_EXP + x)) x++;
    m = 1;
    if (x >= 1) {
        uint16_t* t = c + CTX_MANT + 3u * (x - 1u);
        uint32_t b1 = dec_bit(d, t);
        m = 2u | b1;
        if (x >= 2) {
            m = (m << 1) | dec_bit(d, t + 1u + b1);
            m = (m << (x - MANT_CTX_BITS)) | dec_raw(d, x - MANT_CTX_BITS);
        }
    }
    /* m < 2^30 by construction, so the value is always within range. */
    return neg ? -(int32_t)m : (int32_t)m;
}

/* Decode into values[], or only check the stream when values is NULL. */
static mcd_result decode_stream(const uint8_t* in, size_t size, uint32_t channels, int32_t* values,
                                uint32_t count) {
    uint16_t ctx[MCD_ENTROPY_MAX_CHANNELS * CTX_PER_CHANNEL];
    decoder d;
    uint32_t i, ch = 0;
    if (count == 0) return size == 0 ? MCD_OK : MCD_ERROR_MALFORMED;
    if (size < 4) return MCD_ERROR_MALFORMED;
    ctx_init(ctx, channels);
    d.range = 0xFFFFFFFFu;
    d.code = ((uint32_t)in[0] << 24) | ((uint32_t)in[1] << 16) | ((uint32_t)in[2] << 8) | in[3];
    d.bad = d.code >= d.range;
    d.in = in;
    d.size = size;
    d.pos = 4;
    for (i = 0; i < count; ++i) {
        int32_t v = dec_value(&d, ctx + ch * CTX_PER_CHANNEL);
        if (values) values[i] = v;
        if (++ch == channels) ch = 0;
        if (d.pos > size || d.bad) return MCD_ERROR_MALFORMED; /* ran out, or not a stream */
    }
    return d.pos == size && d.code == 0 ? MCD_OK : MCD_ERROR_MALFORMED;
}

mcd_result mcd_entropy_decode(const uint8_t* in, size_t size, uint32_t channels, int32_t* values,
                              uint32_t count) {
    if (channels < 1 || channels > MCD_ENTROPY_MAX_CHANNELS || (!in && size) || (!values && count))
        return MCD_ERROR_INVALID_ARGUMENT;
    return decode_stream(in, size, channels, values, count);
}

mcd_result mcd_entropy_check(const uint8_t* in, size_t size, uint32_t channels, uint32_t count) {
    if (channels < 1 || channels > MCD_ENTROPY_MAX_CHANNELS || (!in && size)) return MCD_ERROR_INVALID_ARGUMENT;
    return decode_stream(in, size, channels, NULL, count);
}
