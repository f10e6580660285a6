/* Codec `rma`: per-track Catmull-Rom keys, sampled in place from the asset's bytes
 * (docs/FORMAT.md, RMAL versions 4 and 3; version 2 is rmal_v2.c, the payload around the
 * tracks and the window's curve rmal_payload.c).
 *
 * A track's keys come in blocks of 2^b. A block's row, at a fixed bit stride, holds its first
 * key whole (frame and lattice integers), where its codes start and their Rice parameters;
 * every later key is its frame gap and its differences from the key before, Rice coded (a
 * count of trailing zeros a code, the codes of a key from one 64-bit load). Version 4 adds,
 * per block and stream, a stream of zeros with no codes and, per component, a slope predictor
 * (the difference before plus the code). A random access searches the rows by frame and decodes on from its block's
 * first key to the keys around x; playback keeps a reader per track and decodes one key per
 * key interval, a step forward of a few keys (a game tick) just those keys.
 *
 * Both versions share every function; V (3 or 4) is a constant in each caller, so each
 * version's code is what it would be alone. */
#include <stddef.h>
#include <string.h>

#include "rmal_payload.h"

#define MAX_BLOCK_SHIFT 6u
#define K_BITS 5u       /* a Rice parameter in a row */
/* Version 4: a row's 5-bit field holds k in bits 0-3 (15: the block's values of the stream are
 * all zero and have no codes) and, for a component, the slope predictor in bit 4. The reader
 * keeps k with these two flags. */
#define K_ZERO_FIELD 15u
#define K_SLOPE_FIELD 16u
#define K_ZERO 0x20u
#define K_SLOPE 0x40u
#define RICE_CAP 16u    /* 16 zeros: an escape, the value follows in 32 raw bits */
#define RICE_RAW 32u
/* Bit positions in a track's data area are 32-bit (a row's offset is at most 32 bits), and a
 * code may start at any of them. */
#define MAX_DATA_BYTES 0x1FFFFFF0u
#define MAX_ADVANCE 3u  /* keys a step forward reads one by one before a fresh locate */
#define WALK_REFILL 32u /* bits under which a walk reloads before a key's codes (measured: 32 of 1, 32, 48, 65) */
#define FAR_FRAMES 8.0f /* frames past the window's last key from which a step forward locates */

/* Everything about one track that its descriptor and the clip's frame count give. Offsets are
 * bytes from the start of the payload. */
typedef struct track_layout {
    uint32_t table, data;    /* the row table, the data area */
    uint32_t keys, rows, row_bits, frames;
    uint8_t dims, shift, fbits, obits; /* components, block shift, bits of a row's frame and offset */
    uint8_t abits[4];
    float step[4];
} track_layout;

/* A decoded key: its frame and lattice integers (components past the track's: 0); version 4:
 * d, its differences from the key before (0 at a block's first key), which the slope predicts
 * the next key's from. */
typedef struct key {
    int64_t q[4];
    int64_t d[4];
    uint32_t frame;
} key;

/* Where a track is read: the codes of the key after the current one start at `bit` of the
 * data area; the current key's block e and rank r, the block's key count n; per stream (the
 * gaps, then each component) the block's Rice parameter. */
typedef struct reader {
    uint32_t bit, e, r, n;
    uint8_t k[5];   /* version 4: with K_ZERO and K_SLOPE */
    uint8_t at_end; /* playback: the window's slot 2 is the last key */
    uint8_t pad[2];
} reader;

/* A track in the scratch: its window and curve (rmal_payload.h), its layout, the reader and
 * the key it stands at (the window's slot 3, unless at_end); version 4 also that key's
 * differences (|d| < 2^31: both keys are validated). A version 3 track ends before d3. */
typedef struct track_state {
    mcd_rmal_curve W;
    track_layout L;
    reader R;
    uint32_t frame3;
    int32_t q3[4];
    int32_t d3[4];
} track_state;

/* The scratch size is part of the format (docs/FORMAT.md, RMAL versions 3 and 4 "Sampling"):
 * changing this structure is a new section version. Plain 32-bit fields only, so every ABI
 * agrees. */
#define TRACK_BYTES(V) ((V) == 4u ? sizeof(track_state) : offsetof(track_state, d3))
typedef char track_state_v3_is_292_bytes[offsetof(track_state, d3) == 292u ? 1 : -1];
typedef char track_state_v4_is_308_bytes[sizeof(track_state) == 308u ? 1 : -1];

/* ---------------------------------------------------------------- layout */
/* The layout of a track whose descriptor is at `d` and whose data starts at byte `at`; checks
 * what the descriptor alone shows and that the track fits before `limit`. */
static mcd_result track_geometry(const uint8_t* d, uint32_t frames, uint32_t at, uint32_t limit, track_layout* t,
                                 uint32_t* data_bytes, uint32_t* end_out) {
    mcd_rmal_desc D;
    uint64_t end;
    uint32_t c;
    mcd_result r = mcd_rmal_parse_desc(d, frames, &D);
    if (r != MCD_OK) return r;
    /* Byte 1: the first segment detached (bit 0), blocks of 2^(bits 1-3) keys; byte 3 zero. */
    t->shift = (d[1] >> 1) & 7u;
    if ((d[1] >> 4) || t->shift < 1 || t->shift > MAX_BLOCK_SHIFT || d[3]) return MCD_ERROR_MALFORMED;
    if (D.data_bytes > MAX_DATA_BYTES) return MCD_ERROR_MALFORMED;
    t->dims = (uint8_t)D.dims;
    t->keys = D.keys;
    t->frames = frames;
    t->fbits = (uint8_t)mcd_rmal_bits_for(frames - 1u);
    t->obits = (uint8_t)D.offset_bits;
    for (c = 0; c < 4; ++c) {
        t->abits[c] = D.abits[c];
        t->step[c] = D.step[c];
    }
    t->rows = (t->keys + (1u << t->shift) - 1u) >> t->shift;
    t->row_bits = t->fbits + t->obits + K_BITS * (t->dims + 1u) + D.anchor_bits;
    t->table = at;
    end = at + mcd_rmal_packed_bytes(t->rows, t->row_bits);
    t->data = (uint32_t)(end > limit ? limit : end);
    end += D.data_bytes;
    if (end > limit) return MCD_ERROR_MALFORMED;
    *data_bytes = D.data_bytes;
    *end_out = (uint32_t)end;
    return MCD_OK;
}

/* ---------------------------------------------------------------- codes and rows */
/* The value of a short code that starts at bit 0 of w: q zeros, a one, k low bits. */
static MCD_HOT_INLINE uint64_t rice_value(uint64_t w, uint32_t q, uint32_t k) {
    return ((uint64_t)q << k) | ((w >> (q + 1u)) & (((uint64_t)1 << k) - 1u));
}

/* One Rice code at *bit with parameter k: the quotient is the count of trailing zeros of one
 * 64-bit load (a code is at most 16 + 32 bits). */
static MCD_HOT_INLINE uint64_t rice(const uint8_t* data, uint32_t* bit, uint32_t k) {
    uint64_t w = mcd_rd_u64(data + (*bit >> 3)) >> (*bit & 7u);
    uint32_t q = mcd_lowest_bit(w | ((uint64_t)1 << RICE_CAP));
    if (q < RICE_CAP) {
        *bit += q + 1u + k;
        return rice_value(w, q, k);
    }
    *bit += RICE_CAP + RICE_RAW;
    return (w >> RICE_CAP) & 0xFFFFFFFFu;
}

static MCD_HOT_INLINE int64_t unzig(uint64_t z) {
    return (int64_t)(z >> 1) ^ -(int64_t)(z & 1u);
}

/* The frame of row e's key. */
static uint32_t row_frame(const uint8_t* p, const track_layout* t, uint32_t e) {
    return mcd_read_bits(p + t->table, (uint64_t)e * t->row_bits, t->fbits);
}

/* Row e: the reader at the block's first key, which is `k` (the anchor). */
static MCD_HOT_INLINE void load_row(const uint8_t* p, const track_layout* t, uint32_t e, reader* R, key* k,
                                    uint32_t V) {
    const uint8_t* table = p + t->table;
    uint64_t bit = (uint64_t)e * t->row_bits;
    uint64_t h = mcd_rd_u64(table + (size_t)(bit >> 3)) >> (bit & 7u); /* frame and offset: <= 56 bits */
    uint32_t c;
    k->frame = (uint32_t)h & ((1u << t->fbits) - 1u);
    R->bit = (uint32_t)((h >> t->fbits) & ((((uint64_t)1) << t->obits) - 1u));
    bit += t->fbits + t->obits;
    h = mcd_rd_u64(table + (size_t)(bit >> 3)) >> (bit & 7u); /* parameters: <= 25 bits */
    for (c = 0; c < 5u; ++c) {
        uint32_t f = (uint32_t)(h >> (K_BITS * c)) & 31u;
        if (V == 4u) /* the zero flag with k = 0, so a code never reads for it */
            f = ((f & 15u) == K_ZERO_FIELD ? K_ZERO : (f & 15u)) | (f & K_SLOPE_FIELD ? K_SLOPE : 0u);
        R->k[c] = (uint8_t)f;
    }
    if (V == 4u)
        for (c = 0; c < 4u; ++c) k->d[c] = 0;
    bit += K_BITS * (t->dims + 1u);
    k->q[3] = 0;
    for (c = 0; c < t->dims; ++c) {
        k->q[c] = mcd_read_signed(table, bit, t->abits[c]);
        bit += t->abits[c];
    }
    R->e = e;
    R->r = 0;
    R->n = e + 1u < t->rows ? 1u << t->shift : t->keys - (e << t->shift);
}

/* A key's codes read from one 64-bit load: `w` holds the bits from `bit` on, `avail` of them
 * loaded. Decoding a code then shifts a register instead of loading at the bit position the
 * code before computed (a load and a shift off the chain of every code: a random access's
 * walk through a block is that chain, and took 18-23 % less time). Values are rice()'s; a code
 * the register does not hold whole, or an escape, is read by rice() itself. A load is at the
 * start of a code or at the end of a track's codes (a reload after its last code, a block of
 * one key, a version 4 key with no codes), one byte further than rice() reads: validation
 * (check_track, each block's codes starting where the one before ended, and
 * mcd_rmal_validate_payload's 8 bytes after the track data) keeps every such load inside the
 * payload. */
typedef struct bits {
    uint64_t w;
    uint32_t bit, avail;
} bits;

static MCD_HOT_INLINE void bits_at(const uint8_t* data, bits* B, uint32_t bit) {
    B->bit = bit;
    B->w = mcd_rd_u64(data + (bit >> 3)) >> (bit & 7u);
    B->avail = 64u - (bit & 7u);
}

static MCD_HOT_INLINE uint64_t bits_code(const uint8_t* data, bits* B, uint32_t f, uint32_t V) {
    uint32_t k = V == 4u ? f & 15u : f, q, n;
    uint64_t z;
    if (V == 4u && (f & K_ZERO)) return 0;
    /* Bits past `avail` are zeros, so a run of zeros that leaves the register finds bit 16 or
     * a q with q + 1 + k > avail: both take the slow path. */
    q = mcd_lowest_bit(B->w | ((uint64_t)1 << RICE_CAP));
    n = q + 1u + k;
    if (q < RICE_CAP && n <= B->avail) {
        z = rice_value(B->w, q, k);
        B->w >>= n; /* n <= 15 + 1 + 31 < 64 */
        B->avail -= n;
        B->bit += n;
        return z;
    }
    /* Inline: out of line (a cold call) the register went through memory, random 17-20 %
     * slower (bench/results/rma_key_register.txt). */
    z = rice(data, &B->bit, k);
    bits_at(data, B, B->bit);
    return z;
}

/* Key `to` from key `from` and the codes at B: its frame, then each component (version 4:
 * the slope predictor adds the difference before). */
static MCD_HOT_INLINE void key_from_codes(const uint8_t* data, bits* B, const uint8_t k[5], const key* from,
                                          key* to, uint32_t D, uint32_t V) {
    uint32_t c;
    to->frame = from->frame + 1u + (uint32_t)bits_code(data, B, k[0], V);
    for (c = 0; c < D; ++c) {
        int64_t d = unzig(bits_code(data, B, k[c + 1u], V));
        if (V == 4u) {
            d += k[c + 1u] & K_SLOPE ? from->d[c] : 0;
            to->d[c] = d;
        }
        to->q[c] = from->q[c] + d;
    }
    if (D == 3u) {
        to->q[3] = 0;
        if (V == 4u) to->d[3] = 0; /* the scratch keeps d[3] too: no unset value goes there */
    }
}

/* The key after `from` inside the reader's block into `to` (may be `from`). D and V are
 * constants in each caller's copy, so the component loop unrolls. */
static MCD_HOT_INLINE void step_d(const uint8_t* data, reader* R, const key* from, key* to, uint32_t D, uint32_t V) {
    bits B;
    bits_at(data, &B, R->bit);
    key_from_codes(data, &B, R->k, from, to, D, V);
    R->bit = B.bit;
    R->r++;
}

/* Inline, as next_key: playback calls them once per key of a track. */
static MCD_HOT_INLINE void step(const uint8_t* p, const track_layout* t, reader* R, const key* from, key* to,
                                uint32_t V) {
    if (t->dims == 3u)
        step_d(p + t->data, R, from, to, 3u, V);
    else
        step_d(p + t->data, R, from, to, 4u, V);
}

/* The key after `from`, into the next block when the reader's ends; 0 past the last key. */
static MCD_HOT_INLINE int next_key(const uint8_t* p, const track_layout* t, reader* R, const key* from, key* to,
                                   uint32_t V) {
    if (R->r + 1u < R->n) {
        step(p, t, R, from, to, V);
        return 1;
    }
    if (R->e + 1u >= t->rows) return 0;
    load_row(p, t, R->e + 1u, R, to, V);
    return 1;
}

/* ---------------------------------------------------------------- random access */
/* The block of frame xi: the last whose first key is at or before it (block 0 starts at 0). */
static uint32_t find_block(const uint8_t* p, const track_layout* t, uint32_t xi) {
    uint32_t lo = 0, n = t->rows;
    while (n > 1u) {
        uint32_t half = n >> 1;
        lo = row_frame(p, t, lo + half) <= xi ? lo + half : lo;
        n -= half;
    }
    return lo;
}

/* From the block's first key (ring[0]) on to key i + 1, the first after xi, inside the block:
 * returns key i's rank j, keys j - 3 ... j + 1 in ring[rank & 3]; the reader at key j + 1 (or at
 * key j = n - 1 when the block ends first). */
static MCD_HOT_INLINE uint32_t walk_d(const uint8_t* data, reader* R, key ring[4], uint32_t xi, uint32_t D,
                                      uint32_t V) {
    uint32_t j, n = R->n;
    bits B;
    bits_at(data, &B, R->bit);
    for (j = 0; j + 1u < n; ++j) {
        key* b = &ring[(j + 1u) & 3u];
        if (B.avail < WALK_REFILL) bits_at(data, &B, B.bit);
        key_from_codes(data, &B, R->k, &ring[j & 3u], b, D, V);
        if (b->frame > xi) break;
    }
    R->bit = B.bit;
    R->r = j + 1u < n ? j + 1u : j;
    return j;
}

/* The last key of block e (the whole block's decode). */
static void block_last_key(const uint8_t* p, const track_layout* t, uint32_t e, key* k, uint32_t V) {
    reader P;
    load_row(p, t, e, &P, k, V);
    while (P.r + 1u < P.n) step(p, t, &P, k, k, V);
}

static void set_key3(track_state* ts, const key* k, uint32_t V) {
    uint32_t c;
    ts->frame3 = k->frame;
    for (c = 0; c < 4u; ++c) ts->q3[c] = (int32_t)k->q[c]; /* validated: |q| < 2^30 */
    if (V == 4u)
        for (c = 0; c < 4u; ++c) ts->d3[c] = (int32_t)k->d[c]; /* so |d| < 2^31 */
}

static MCD_HOT_INLINE void get_key3(const track_state* ts, key* k, uint32_t V) {
    uint32_t c;
    k->frame = ts->frame3;
    for (c = 0; c < 4u; ++c) k->q[c] = ts->q3[c];
    if (V == 4u)
        for (c = 0; c < 4u; ++c) k->d[c] = ts->d3[c];
}

/* Random access: the segment holding frame position x, its four keys decoded afresh; key i - 1
 * from the previous block when key i is a block's first. */
static MCD_HOT_INLINE void locate_v(const uint8_t* p, track_state* ts, float x, uint32_t V) {
    const track_layout* t = &ts->L;
    uint32_t xi = (uint32_t)x, j, e;
    key ring[4], k3;
    reader R;
    if (xi > t->frames - 2u) xi = t->frames - 2u; /* the last frame: the segment before it */
    e = find_block(p, t, xi);
    load_row(p, t, e, &R, &ring[0], V);
    j = t->dims == 3u ? walk_d(p + t->data, &R, ring, xi, 3u, V) : walk_d(p + t->data, &R, ring, xi, 4u, V);
    if (j + 1u >= R.n) load_row(p, t, e + 1u, &R, &ring[(j + 1u) & 3u], V); /* key i ends its block */
    if (j == 0u && e > 0u) block_last_key(p, t, e - 1u, &ring[3], V);
    if (j > 0u || e > 0u) mcd_rmal_store_key(&ts->W, 0, ring[(j + 3u) & 3u].frame, ring[(j + 3u) & 3u].q, t->step);
    mcd_rmal_store_key(&ts->W, 1, ring[j & 3u].frame, ring[j & 3u].q, t->step);
    mcd_rmal_store_key(&ts->W, 2, ring[(j + 1u) & 3u].frame, ring[(j + 1u) & 3u].q, t->step);
    if (j == 0u && e == 0u) mcd_rmal_repeat_slot(&ts->W, 0, 1);
    k3 = ring[(j + 1u) & 3u];
    R.at_end = (uint8_t)!next_key(p, t, &R, &k3, &k3, V);
    if (R.at_end)
        mcd_rmal_repeat_slot(&ts->W, 3, 2);
    else
        mcd_rmal_store_key(&ts->W, 3, k3.frame, k3.q, t->step);
    set_key3(ts, &k3, V);
    ts->R = R;
    ts->W.i = (e << t->shift) + j;
    mcd_rmal_set_curve(&ts->W);
}

static void locate3(const uint8_t* p, track_state* ts, float x) {
    locate_v(p, ts, x, 3u);
}

static void locate4(const uint8_t* p, track_state* ts, float x) {
    locate_v(p, ts, x, 4u);
}

static MCD_HOT_INLINE void locate(const uint8_t* p, track_state* ts, float x, uint32_t V) {
    if (V == 4u)
        locate4(p, ts, x);
    else
        locate3(p, ts, x);
}

/* ---------------------------------------------------------------- playback */
/* One key on (the window's slot 2 is not the last key): the key after slot 3's, if any,
 * becomes slot 3. */
static MCD_HOT_INLINE void advance_v(const uint8_t* p, track_state* ts, uint32_t V) {
    key k;
    /* memmove: copies through locals took fewer instructions but timed 10 % slower at 0.02 cm
     * (their vector loads of the slot just stored wait for the stores), and a ring of slots
     * (no copies; the curve gathers them) 23 % slower (bench/results/rma_key_register.txt). */
    memmove(ts->W.t, ts->W.t + 1, 3u * sizeof ts->W.t[0]);
    memmove(ts->W.v[0], ts->W.v[1], 3u * sizeof ts->W.v[0]);
    ts->W.i++;
    get_key3(ts, &k, V);
    if (next_key(p, &ts->L, &ts->R, &k, &k, V)) {
        mcd_rmal_store_key(&ts->W, 3, k.frame, k.q, ts->L.step);
        set_key3(ts, &k, V);
    } else {
        ts->R.at_end = 1;
        mcd_rmal_repeat_slot(&ts->W, 3, 2);
    }
}

static void advance3(const uint8_t* p, track_state* ts) {
    advance_v(p, ts, 3u);
}

static void advance4(const uint8_t* p, track_state* ts) {
    advance_v(p, ts, 4u);
}

/* The curve of one track at x: the cached segment, a few keys on from it, or a fresh locate.
 * Either way the window is the four keys around x's segment, so the curve is the same bits. */
static MCD_HOT_INLINE void track_value(const uint8_t* p, mcd_rmal_curve* w, float x, float out[4], uint32_t V) {
    track_state* ts = (track_state*)w;
    uint32_t n;
    if (ts->L.keys == 1u) { /* a one-frame clip */
        memcpy(out, ts->W.v[0], sizeof ts->W.v[0]);
        return;
    }
    if (!ts->W.valid || x < ts->W.t1) {
        locate(p, ts, x, V);
    } else if (x >= ts->W.t2 && !ts->R.at_end) { /* x = the last key is the last segment's */
        if (x >= ts->W.t[3] + FAR_FRAMES) { /* a jump: locate at once rather than step there */
            locate(p, ts, x, V);
        } else {
            for (n = 0; n < MAX_ADVANCE && x >= ts->W.t[2] && !ts->R.at_end; ++n) {
                if (V == 4u)
                    advance4(p, ts);
                else
                    advance3(p, ts);
            }
            if (x >= ts->W.t[2] && !ts->R.at_end)
                locate(p, ts, x, V);
            else
                mcd_rmal_set_curve(&ts->W);
        }
    }
    mcd_rmal_eval(&ts->W, x, out);
}

static void track_value3(const uint8_t* p, mcd_rmal_curve* w, float x, float out[4]) {
    track_value(p, w, x, out, 3u);
}

static void track_value4(const uint8_t* p, mcd_rmal_curve* w, float x, float out[4]) {
    track_value(p, w, x, out, 4u);
}

/* A track's state from its validated descriptor (rmal_payload.h). */
static uint32_t init_track(const uint8_t* p, const uint8_t* d, uint32_t frames, uint32_t at, uint32_t limit,
                           mcd_rmal_curve* w) {
    track_state* ts = (track_state*)w;
    uint32_t data_bytes, end = at;
    track_geometry(d, frames, at, limit, &ts->L, &data_bytes, &end); /* validated: cannot fail */
    if (ts->L.keys == 1u) { /* one frame: the single key is row 0's anchor */
        key k;
        load_row(p, &ts->L, 0, &ts->R, &k, 3u); /* the anchor reads alike in both versions */
        mcd_rmal_store_key(&ts->W, 0, 0, k.q, ts->L.step);
    }
    return end;
}

static size_t rma3_scratch_size(const mcd_clip_view* v) {
    return mcd_rmal_scratch_size(v, TRACK_BYTES(3u));
}

static size_t rma4_scratch_size(const mcd_clip_view* v) {
    return mcd_rmal_scratch_size(v, TRACK_BYTES(4u));
}

static void rma3_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                        int fresh) {
    (void)flags;
    mcd_rmal_sample(v, x, out, scratch, fresh, TRACK_BYTES(3u), init_track, track_value3);
}

static void rma4_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                        int fresh) {
    (void)flags;
    mcd_rmal_sample(v, x, out, scratch, fresh, TRACK_BYTES(4u), init_track, track_value4);
}

/* ---------------------------------------------------------------- validation */
/* One code at *bit of a data area whose codes end by bit `end`, into z: 0 when it reads past
 * `end` or is an escape of a value that had a short code (no other code is valid). */
static int checked_code(const uint8_t* data, uint64_t* bit, uint32_t f, uint64_t end, uint64_t* z, uint32_t V) {
    uint32_t b = (uint32_t)*bit, k = V == 4u ? f & 15u : f; /* b < end < 2^32 (MAX_DATA_BYTES) */
    if (V == 4u && (f & K_ZERO)) { /* a zero stream: no code */
        *z = 0;
        return 1;
    }
    if (*bit >= end) return 0;
    *z = rice(data, &b, k);
    /* Only an escape is 48 bits long: a short code is at most 15 + 1 + 31. */
    if (b - (uint32_t)*bit == RICE_CAP + RICE_RAW && (*z >> k) < RICE_CAP) return 0;
    *bit = b;
    return *bit <= end;
}

/* A key's lattice integers: |q| < 2^30, and each value (binary64 product, then binary32)
 * within the format's bound. */
static int key_in_range(const track_layout* t, const key* k) {
    uint32_t c;
    for (c = 0; c < t->dims; ++c) {
        if (k->q[c] >= MCD_RMAL_MAX_Q || k->q[c] <= -MCD_RMAL_MAX_Q) return 0;
        if (!mcd_in_bounds((float)((double)k->q[c] * (double)t->step[c]))) return 0;
    }
    return 1;
}

/* Every rule of one track's row table and data area, decoding every key. */
static mcd_result check_track(const uint8_t* p, const track_layout* t, uint32_t data_bytes, uint32_t V) {
    const uint8_t* data = p + t->data;
    uint64_t end = 8u * (uint64_t)data_bytes, bit = 0;
    uint32_t e, r, c, last = 0;
    if (!mcd_rmal_zero_bits(p + t->table, (uint64_t)t->rows * t->row_bits,
                            8u * mcd_rmal_packed_bytes(t->rows, t->row_bits)))
        return MCD_ERROR_MALFORMED;
    for (e = 0; e < t->rows; ++e) {
        reader R;
        key k;
        load_row(p, t, e, &R, &k, V);
        /* Each block's codes where the one before ended; frames increasing from 0; version 4:
         * no slope on the gaps. */
        if (R.bit != bit || (e == 0 ? k.frame != 0 : k.frame <= last) || k.frame > t->frames - 1u)
            return MCD_ERROR_MALFORMED;
        if (V == 4u && (R.k[0] & K_SLOPE)) return MCD_ERROR_MALFORMED;
        if (!key_in_range(t, &k)) return MCD_ERROR_MALFORMED;
        for (r = 1; r < R.n; ++r) {
            uint64_t z;
            if (!checked_code(data, &bit, R.k[0], end, &z, V) || z >= (uint64_t)(t->frames - 1u - k.frame))
                return MCD_ERROR_MALFORMED; /* the gap: the frame after stays at most F - 1 */
            k.frame += 1u + (uint32_t)z;
            for (c = 0; c < t->dims; ++c) {
                int64_t d;
                if (!checked_code(data, &bit, R.k[c + 1u], end, &z, V)) return MCD_ERROR_MALFORMED;
                /* z < 2^32 and, the keys before being in range, |d before| < 2^31: no overflow */
                d = unzig(z) + (V == 4u && (R.k[c + 1u] & K_SLOPE) ? k.d[c] : 0);
                k.d[c] = d;
                k.q[c] += d;
            }
            if (!key_in_range(t, &k)) return MCD_ERROR_MALFORMED;
        }
        last = k.frame;
    }
    /* The last key on the last frame; the data area ends after the last block's codes, zero
     * padded to a multiple of 4 bytes. */
    if (last != t->frames - 1u) return MCD_ERROR_MALFORMED;
    if (data_bytes != mcd_align4((size_t)((bit + 7u) / 8u))) return MCD_ERROR_MALFORMED;
    if (!mcd_rmal_zero_bits(data, bit, end)) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* One track: its layout within [at, limit), then every rule of its data (rmal_payload.h). */
static mcd_result check_one(const uint8_t* p, const uint8_t* desc, uint32_t frames, uint32_t at, uint32_t limit,
                            uint32_t* end, uint32_t V) {
    track_layout t;
    uint32_t data_bytes;
    mcd_result r = track_geometry(desc, frames, at, limit, &t, &data_bytes, end);
    if (r != MCD_OK) return r;
    return check_track(p, &t, data_bytes, V);
}

static mcd_result check_one3(const uint8_t* p, const uint8_t* desc, uint32_t frames, uint32_t at, uint32_t limit,
                             uint32_t* end) {
    return check_one(p, desc, frames, at, limit, end, 3u);
}

static mcd_result check_one4(const uint8_t* p, const uint8_t* desc, uint32_t frames, uint32_t at, uint32_t limit,
                             uint32_t* end) {
    return check_one(p, desc, frames, at, limit, end, 4u);
}

static mcd_result rma3_validate(const mcd_clip_view* v) {
    return mcd_rmal_validate_payload(v, check_one3);
}

static mcd_result rma4_validate(const mcd_clip_view* v) {
    return mcd_rmal_validate_payload(v, check_one4);
}

const mcd_codec_ops mcd_codec_rma_ops = {MCD_CODEC_RMA, 0x4C414D52u /* "RMAL" */, 4u, mcd_rmal_validate_section,
                                         rma4_validate, rma4_scratch_size, rma4_sample};
const mcd_codec_ops mcd_codec_rma_v3_ops = {MCD_CODEC_RMA, 0x4C414D52u /* "RMAL" */, 3u, mcd_rmal_validate_section,
                                            rma3_validate, rma3_scratch_size, rma3_sample};
