/* What the two RMAL readers share (docs/FORMAT.md, RMAL versions 2 and 3; rmal_payload.c):
 * the payload around the tracks (header, node modes, constants, descriptors, end padding),
 * a node's base transform and tracks, and a track's window of four keys with its Catmull-Rom
 * curve. Each version reads its own track data (rmal_v2.c, codec_rma.c) and plugs in here. */
#ifndef MCD_RMAL_PAYLOAD_H
#define MCD_RMAL_PAYLOAD_H

#include <string.h>

#include "internal.h"

#define MCD_RMAL_SECTION_HEADER 16u
#define MCD_RMAL_PAYLOAD_HEADER 32u
#define MCD_RMAL_MAX_Q 0x40000000LL /* |q| < 2^30: exact in binary64 */

/* Rare paths kept out of line, so the hot loops around them keep their registers; hot helpers
 * inlined where a random access calls them several times a track. */
#if defined(__GNUC__) || defined(__clang__)
#define MCD_RARE_PATH __attribute__((noinline, cold))
#define MCD_HOT_INLINE __attribute__((always_inline)) inline
#define MCD_OUT_OF_LINE __attribute__((noinline))
#else
#define MCD_RARE_PATH
#define MCD_HOT_INLINE inline
#define MCD_OUT_OF_LINE
#endif

enum { MCD_RMAL_MRP = 1, MCD_RMAL_TWIST = 2, MCD_RMAL_TRANSLATION = 3, MCD_RMAL_SCALE = 4 };

/* A descriptor's bytes by kind (0: no such kind), and the components of its values. */
static inline uint32_t mcd_rmal_desc_size(uint32_t kind) {
    return kind == MCD_RMAL_MRP ? 28u : kind == MCD_RMAL_TWIST ? 40u : (kind == 3u || kind == 4u) ? 20u : 0u;
}

/* Bits that hold every value 0 ... n (at least 1). */
static inline uint32_t mcd_rmal_bits_for(uint32_t n) {
    uint32_t b = 1;
    while (b < 32u && (n >> b)) ++b;
    return b;
}

/* Bytes of n fields of `bits` each, padded to 4 bytes. */
static inline uint64_t mcd_rmal_packed_bytes(uint64_t n, uint64_t bits) {
    return 4u * ((n * bits + 31u) / 32u);
}

/* Bits [from, to) of p are zero. */
int mcd_rmal_zero_bits(const uint8_t* p, uint64_t from, uint64_t to);

typedef struct mcd_rmal_header {
    uint32_t size, frames, nodes, tracks, constants;
    const uint8_t *modes, *consts, *descs;
    uint32_t data; /* where the tracks' data starts: the descriptors' end, aligned to 4 */
} mcd_rmal_header;

/* The payload header; on a validated payload it cannot fail. */
mcd_result mcd_rmal_parse_header(const uint8_t* p, size_t avail, mcd_rmal_header* H);

/* The descriptor fields both versions hold alike (bytes 0, bit 0 of 1, 2, 4 ... 39). */
typedef struct mcd_rmal_desc {
    uint32_t kind, dims, split, offset_bits, keys, data_bytes, anchor_bits; /* anchor_bits: sum of abits */
    uint8_t abits[4];
    float step[4]; /* per component: the twist angle's step first for kind 2 */
} mcd_rmal_desc;

/* Those fields of the descriptor at d, checked (the version checks its own bits of bytes 1, 3). */
mcd_result mcd_rmal_parse_desc(const uint8_t* d, uint32_t frames, mcd_rmal_desc* out);

/* A version's reader of one track whose descriptor is at `desc` and whose data starts at byte
 * `at` of the payload: checks every rule of the track's data, which must end at or before
 * `limit` (8 bytes before the payload's end, for the 64-bit loads), and gives its end. */
typedef mcd_result (*mcd_rmal_check_track)(const uint8_t* p, const uint8_t* desc, uint32_t frames, uint32_t at,
                                           uint32_t limit, uint32_t* end);

/* Every rule of the payload around its tracks, and each track through `check`. */
mcd_result mcd_rmal_validate_payload(const mcd_clip_view* v, mcd_rmal_check_track check);

/* The section: a 16-byte header, then the payloads back to back, each one a clip's. */
mcd_result mcd_rmal_validate_section(const uint8_t* s, uint32_t size);

/* ---------------------------------------------------------------- sampling state */
/* A track's window: what its descriptor says about rotations and the first segment, the four
 * keys around the last sample (i - 1 ... i + 2, ends repeated) and their curve. The first
 * member of each version's track state, so the node loop reads it from any of them. */
typedef struct mcd_rmal_curve {
    uint8_t kind, split, valid, pad;
    uint32_t i;    /* the segment [key i, key i + 1] the curve belongs to */
    mcd_quat ref;
    float axis[4];
    float t[4];    /* frames of keys i - 1 ... i + 2 */
    float v[4][4]; /* their values */
    float t1, t2, inv_h;
    uint32_t aux;  /* the version's own */
    float coef[4][4];
} mcd_rmal_curve;

typedef struct mcd_rmal_node {
    mcd_transform base; /* rest pose and constants resolved once per clip */
    int16_t track[3];   /* rotation, translation, scale track, or -1 */
    uint16_t pad;
} mcd_rmal_node;

/* The scratch sizes are part of the format (docs/FORMAT.md, RMAL "Sampling"). */
typedef char mcd_rmal_node_is_48_bytes[sizeof(mcd_rmal_node) == 48u ? 1 : -1];
typedef char mcd_rmal_curve_is_200_bytes[sizeof(mcd_rmal_curve) == 200u ? 1 : -1];

/* align16(48 N) + align16(track_size T). */
size_t mcd_rmal_scratch_size(const mcd_clip_view* v, size_t track_size);

/* A version's set-up of one track's state (it starts with an mcd_rmal_curve, whose kind,
 * split, reference and axis are set already) from its validated descriptor and data at `at`;
 * returns where the track's data ends. */
typedef uint32_t (*mcd_rmal_init_track)(const uint8_t* p, const uint8_t* desc, uint32_t frames, uint32_t at,
                                        uint32_t limit, mcd_rmal_curve* track);

/* Per clip (a fresh scratch): each node's base transform and tracks, each track's state. */
void mcd_rmal_prepare(const mcd_clip_view* v, void* scratch, size_t track_size, mcd_rmal_init_track init);

/* Window slot `slot` from a decoded key (four components: the unused ones are 0). */
static inline void mcd_rmal_store_key(mcd_rmal_curve* w, uint32_t slot, uint32_t frame, const int64_t q[4],
                                      const float step[4]) {
    uint32_t c;
    w->t[slot] = (float)frame;
    /* Binary64 first: q may exceed 2^24 on long clips, where binary32 would round it. */
    for (c = 0; c < 4u; ++c) w->v[slot][c] = (float)((double)q[c] * (double)step[c]);
}

static inline void mcd_rmal_repeat_slot(mcd_rmal_curve* w, uint32_t to, uint32_t from) {
    memcpy(w->v[to], w->v[from], sizeof w->v[to]);
    w->t[to] = w->t[from];
}

/* The curve of the window (its slots and i set), all four components. */
void mcd_rmal_set_curve(mcd_rmal_curve* w);

static inline void mcd_rmal_eval(const mcd_rmal_curve* w, float x, float out[4]) {
    float s = (x - w->t1) * w->inv_h;
    uint32_t c;
    for (c = 0; c < 4u; ++c) out[c] = ((w->coef[3][c] * s + w->coef[2][c]) * s + w->coef[1][c]) * s + w->coef[0][c];
}

/* A version's value of one track at frame position x (its window moved as needed). */
typedef void (*mcd_rmal_track_value)(const uint8_t* p, mcd_rmal_curve* track, float x, float out[4]);

/* Local transforms of every node at x: each node's base, its tracks' values over it. Inline,
 * so that each version's copy calls its own track_value directly. */
static MCD_HOT_INLINE void mcd_rmal_sample(const mcd_clip_view* v, float x, mcd_transform* out, void* scratch,
                                           int fresh, size_t track_size, mcd_rmal_init_track init,
                                           mcd_rmal_track_value value) {
    uint32_t i, nodes = mcd_rd_u32(v->payload + 8);
    const mcd_rmal_node* plans = (const mcd_rmal_node*)scratch;
    uint8_t* tracks = (uint8_t*)scratch + mcd_align16(sizeof(mcd_rmal_node) * nodes);
    if (fresh) mcd_rmal_prepare(v, scratch, track_size, init);
    for (i = 0; i < nodes; ++i) {
        const mcd_rmal_node* np = &plans[i];
        float val[4];
        out[i] = np->base;
        if (np->track[0] >= 0) {
            mcd_rmal_curve* w = (mcd_rmal_curve*)(tracks + track_size * (size_t)np->track[0]);
            value(v->payload, w, x, val);
            mcd_store_track_rotation(w->kind, &w->ref, w->axis, val, out[i].rotation);
        }
        if (np->track[1] >= 0) {
            value(v->payload, (mcd_rmal_curve*)(tracks + track_size * (size_t)np->track[1]), x, val);
            memcpy(out[i].translation, val, sizeof out[i].translation);
        }
        if (np->track[2] >= 0) {
            value(v->payload, (mcd_rmal_curve*)(tracks + track_size * (size_t)np->track[2]), x, val);
            memcpy(out[i].scale, val, sizeof out[i].scale);
        }
    }
}

#endif /* MCD_RMAL_PAYLOAD_H */
