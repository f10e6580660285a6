/* Internal declarations shared by the runtime's source files. Not installed. */
#ifndef MCD_INTERNAL_H
#define MCD_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

/* No fused multiply-add: every product is rounded, so the SSE path below and every platform's
 * scalar code give the same bits. GCC's ISO C modes contract nothing already; Clang and MSVC
 * are told here (GCC rejects the STDC pragma under -Wall; its GNU modes need -ffp-contract=off,
 * which CMakeLists.txt passes). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(_MSC_VER)
#pragma fp_contract(off)
#endif

/* ---------------------------------------------------------------- limits (docs/FORMAT.md) */
#define MCD_HEADER_SIZE 32u
#define MCD_SECTION_ENTRY_SIZE 16u
#define MCD_MAX_SECTIONS 4096u
#define MCD_MAX_NODES 1024u
#define MCD_MAX_CLIPS 65535u
#define MCD_SKEL_NODE_SIZE 32u
#define MCD_SKEL_REST_SIZE 28u /* rest rotation x y z w and scale x y z, when SKEL flag bit 0 is set */
#define MCD_CLIP_RECORD_SIZE 48u
#define MCD_MAX_NAME_BYTES 255u /* clip and node names, without the NUL */
#define MCD_MAX_FRAME_RATE 100000.0f
#define MCD_MAX_FRAMES (1u << 24) /* frames of a clip: frame positions are binary32, exact up to 2^24 */
#define MCD_MAX_ABS_VALUE 1e7f /* bound on every stored length or parameter: keeps outputs finite */

/* ---------------------------------------------------------------- little-endian byte loads */
/* Byte composition is endian-independent and compiles to single loads on x86 and ARM. */
static inline uint16_t mcd_rd_u16(const uint8_t* p) {
    return (uint16_t)(p[0] | (p[1] << 8));
}
static inline uint32_t mcd_rd_u32(const uint8_t* p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static inline uint64_t mcd_rd_u64(const uint8_t* p) {
    return (uint64_t)mcd_rd_u32(p) | ((uint64_t)mcd_rd_u32(p + 4) << 32);
}
static inline int32_t mcd_rd_i32(const uint8_t* p) {
    uint32_t u = mcd_rd_u32(p);
    return u <= 0x7FFFFFFFu ? (int32_t)u : (int32_t)(u - 0x80000000u) - (int32_t)0x7FFFFFFF - 1;
}
float mcd_rd_f32(const uint8_t* p);

/* Bit scans and counts on 64-bit words (the compiler's instructions where it has them). */
static inline uint32_t mcd_lowest_bit(uint64_t m) { /* m != 0 */
#if defined(__GNUC__) || defined(__clang__)
    return (uint32_t)__builtin_ctzll(m);
#else
    uint32_t i = 0;
    while (!(m & 1u)) {
        m >>= 1;
        ++i;
    }
    return i;
#endif
}
static inline uint32_t mcd_highest_bit(uint64_t m) { /* m != 0 */
#if defined(__GNUC__) || defined(__clang__)
    return 63u - (uint32_t)__builtin_clzll(m);
#else
    uint32_t i = 0;
    while (m >>= 1) ++i;
    return i;
#endif
}
static inline uint32_t mcd_popcount(uint64_t m) {
    /* The builtin only where it is an instruction: elsewhere it is a library call, slower
     * than the arithmetic below. */
#if (defined(__GNUC__) || defined(__clang__)) && (defined(__POPCNT__) || defined(__aarch64__) || defined(__wasm__))
    return (uint32_t)__builtin_popcountll(m);
#else
    m = m - ((m >> 1) & 0x5555555555555555u);
    m = (m & 0x3333333333333333u) + ((m >> 2) & 0x3333333333333333u);
    m = (m + (m >> 4)) & 0x0F0F0F0F0F0F0F0Fu;
    return (uint32_t)((m * 0x0101010101010101u) >> 56);
#endif
}

/* `n` <= 32 bits of an LSB-first bit stream at bit `pos` of `p`; the caller guarantees that
 * 8 bytes from byte pos / 8 are readable (payloads end with 8 zero bytes for it). */
static inline uint32_t mcd_read_bits(const uint8_t* p, uint64_t pos, uint32_t n) {
    uint64_t w = mcd_rd_u64(p + (size_t)(pos >> 3)) >> (pos & 7u);
    return n ? (uint32_t)(w & (((uint64_t)1 << n) - 1u)) : 0u;
}
/* The same field read as a two's complement number of n bits (1 ... 32). */
static inline int32_t mcd_read_signed(const uint8_t* p, uint64_t pos, uint32_t n) {
    uint32_t u = mcd_read_bits(p, pos, n), sign = (uint32_t)1 << (n - 1u);
    return (int32_t)((int64_t)(u ^ sign) - (int64_t)sign);
}

/* True when x is finite (no isfinite in strict C99 without libm macros on every compiler). */
static inline int mcd_finite(float x) {
    return x == x && x - x == 0.0f;
}

static inline uint32_t mcd_fourcc(char a, char b, char c, char d) {
    return (uint32_t)(uint8_t)a | ((uint32_t)(uint8_t)b << 8) | ((uint32_t)(uint8_t)c << 16) |
           ((uint32_t)(uint8_t)d << 24);
}

uint32_t mcd_crc32(const uint8_t* data, size_t size);

/* Sizes rounded up to 4 and 16 bytes (payload fields and scratch areas). */
static inline size_t mcd_align4(size_t x) {
    return (x + 3u) & ~(size_t)3u;
}
static inline size_t mcd_align16(size_t x) {
    return (x + 15u) & ~(size_t)15u;
}

/* ---------------------------------------------------------------- quaternion helpers */
typedef struct mcd_quat { float x, y, z, w; } mcd_quat;

static inline mcd_quat mcd_qmul(mcd_quat a, mcd_quat b) {
    mcd_quat r;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    return r;
}

/* v' = q v q* for unit q. */
static inline void mcd_qrotate(mcd_quat q, const float v[3], float out[3]) {
    float tx = 2.0f * (q.y * v[2] - q.z * v[1]);
    float ty = 2.0f * (q.z * v[0] - q.x * v[2]);
    float tz = 2.0f * (q.x * v[1] - q.y * v[0]);
    out[0] = v[0] + q.w * tx + (q.y * tz - q.z * ty);
    out[1] = v[1] + q.w * ty + (q.z * tx - q.x * tz);
    out[2] = v[2] + q.w * tz + (q.x * ty - q.y * tx);
}

/* Modified Rodrigues parameters -> unit quaternion (docs/FORMAT.md, spline track kind 1):
 * rational, no trigonometry. */
static inline mcd_quat mcd_mrp_to_quat(const float p[3]) {
    float s = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    float inv = 1.0f / (1.0f + s);
    mcd_quat q;
    q.x = 2.0f * p[0] * inv;
    q.y = 2.0f * p[1] * inv;
    q.z = 2.0f * p[2] * inv;
    q.w = (1.0f - s) * inv;
    return q;
}

/* `count` payloads back to back from `pos` to the section's end, each starting with its own u32
 * size (a multiple of 4, at least `header` bytes): the clip lists of RMAL and RMAP. */
static inline mcd_result mcd_check_payload_run(const uint8_t* s, size_t size, size_t pos, uint32_t count,
                                               uint32_t header) {
    uint32_t i, n;
    for (i = 0; i < count; ++i) {
        if (size - pos < header) return MCD_ERROR_MALFORMED;
        n = mcd_rd_u32(s + pos);
        if (n < header || (n & 3u) || n > size - pos) return MCD_ERROR_MALFORMED;
        pos += n;
    }
    return pos == size ? MCD_OK : MCD_ERROR_MALFORMED;
}

/* A stored length or parameter: finite and within the format's bound. */
static inline int mcd_in_bounds(float v) {
    return mcd_finite(v) && v <= MCD_MAX_ABS_VALUE && v >= -MCD_MAX_ABS_VALUE;
}

/* Four f32 at p form a unit quaternion (within the format's 1e-5). */
int mcd_unit_quat_at(const uint8_t* p);

/* A track's reference rotation stored as i16 MRPs x 32767, and its twist axis stored as i16
 * x 32767 and normalised (docs/FORMAT.md, SPLN descriptors). */
mcd_quat mcd_reference_at(const uint8_t* p);
void mcd_axis_at(const uint8_t* p, float axis[3]);

/* Rotation of a curve track (kinds shared by `spline` and `rma`): kind 1 is MRPs relative to
 * `ref`; kind 2 is a twist angle val[0] about `axis`, then MRPs val[1..3] relative to `ref`.
 * Inline: it runs once per rotation track per sample. */
static inline mcd_quat mcd_track_rotation(uint32_t kind, mcd_quat ref, const float axis[3], const float* val) {
    float half, sn;
    mcd_quat tw;
    if (kind != 2u) return mcd_qmul(ref, mcd_mrp_to_quat(val));
    half = 0.5f * val[0];
    sn = sinf(half);
    tw.x = axis[0] * sn;
    tw.y = axis[1] * sn;
    tw.z = axis[2] * sn;
    tw.w = cosf(half);
    return mcd_qmul(tw, mcd_qmul(ref, mcd_mrp_to_quat(val + 1)));
}

/* SSE, on x86-64 (not 32-bit x86, whose x87 float math rounds differently, nor ARM64EC), for
 * the quaternion products of sampling and of local -> world. Each lane does the scalar code's
 * operations in its order, so both paths give the same bits for every result that is not NaN
 * (tests/test_sampling.c compares them, and checks fixed results on every platform). */
#if defined(__x86_64__) || (defined(_M_X64) && !defined(_M_ARM64EC))
#include <xmmintrin.h>
#define MCD_SSE 1
#define MCD_SHUF(v, a, b, c, d) _mm_shuffle_ps(v, v, _MM_SHUFFLE(d, c, b, a))

/* mcd_qmul lane by lane: r = a.w b + a.x (b.w, -b.z, b.y, -b.x) + a.y (b.z, b.w, -b.x, -b.y)
 * + a.z (-b.y, b.x, b.w, -b.z), summed in mcd_qmul's order (a negated product is exact). */
static inline __m128 mcd_qmul_sse(__m128 a, __m128 b) {
    const __m128 s2 = _mm_setr_ps(0.0f, -0.0f, 0.0f, -0.0f);
    const __m128 s3 = _mm_setr_ps(0.0f, 0.0f, -0.0f, -0.0f);
    const __m128 s4 = _mm_setr_ps(-0.0f, 0.0f, 0.0f, -0.0f);
    __m128 r = _mm_mul_ps(MCD_SHUF(a, 3, 3, 3, 3), b);
    r = _mm_add_ps(r, _mm_mul_ps(MCD_SHUF(a, 0, 0, 0, 0), _mm_xor_ps(MCD_SHUF(b, 3, 2, 1, 0), s2)));
    r = _mm_add_ps(r, _mm_mul_ps(MCD_SHUF(a, 1, 1, 1, 1), _mm_xor_ps(MCD_SHUF(b, 2, 3, 0, 1), s3)));
    return _mm_add_ps(r, _mm_mul_ps(MCD_SHUF(a, 2, 2, 2, 2), _mm_xor_ps(MCD_SHUF(b, 1, 0, 3, 2), s4)));
}

/* mcd_qrotate lane by lane (lanes x, y, z; w is ignored). */
static inline __m128 mcd_qrotate_sse(__m128 q, __m128 v) {
    const __m128 two = _mm_set1_ps(2.0f);
    __m128 q1 = MCD_SHUF(q, 1, 2, 0, 3), q2 = MCD_SHUF(q, 2, 0, 1, 3);
    __m128 t = _mm_mul_ps(two, _mm_sub_ps(_mm_mul_ps(q1, MCD_SHUF(v, 2, 0, 1, 3)), _mm_mul_ps(q2, MCD_SHUF(v, 1, 2, 0, 3))));
    __m128 c = _mm_sub_ps(_mm_mul_ps(q1, MCD_SHUF(t, 2, 0, 1, 3)), _mm_mul_ps(q2, MCD_SHUF(t, 1, 2, 0, 3)));
    return _mm_add_ps(_mm_add_ps(v, _mm_mul_ps(MCD_SHUF(q, 3, 3, 3, 3), t)), c);
}
#endif

static inline mcd_quat mcd_qconj(mcd_quat q) {
    q.x = -q.x;
    q.y = -q.y;
    q.z = -q.z;
    return q;
}

/* A transform's rotation as a quaternion. */
static inline mcd_quat mcd_quat_of(const mcd_transform* t) {
    mcd_quat q;
    q.x = t->rotation[0];
    q.y = t->rotation[1];
    q.z = t->rotation[2];
    q.w = t->rotation[3];
    return q;
}

/* Write a track's rotation into a transform. */
static inline void mcd_set_rotation(float out[4], mcd_quat q) {
    out[0] = q.x;
    out[1] = q.y;
    out[2] = q.z;
    out[3] = q.w;
}

/* A curve track's rotation at val into out (mcd_track_rotation's bits). */
static inline void mcd_store_track_rotation(uint32_t kind, const mcd_quat* ref, const float axis[3], const float* val,
                                            float out[4]) {
#ifdef MCD_SSE
    if (kind != 2u) { /* mcd_mrp_to_quat lane by lane, then ref x it */
        float s = val[0] * val[0] + val[1] * val[1] + val[2] * val[2];
        __m128 inv = _mm_set1_ps(1.0f / (1.0f + s));
        __m128 m = _mm_mul_ps(_mm_setr_ps(2.0f * val[0], 2.0f * val[1], 2.0f * val[2], 1.0f - s), inv);
        _mm_storeu_ps(out, mcd_qmul_sse(_mm_setr_ps(ref->x, ref->y, ref->z, ref->w), m));
        return;
    }
#endif
    mcd_set_rotation(out, mcd_track_rotation(kind, *ref, axis, val));
}

/* Catmull-Rom segment [t1, t2] of keys (t0, v0) ... (t3, v3) as Horner coefficients in
 * s = (x - t1) / (t2 - t1): coef[power][c], for `dims` components; returns 1 / (t2 - t1).
 * The Hermite segment with finite-difference tangents, expanded in powers of s. Inline: it
 * runs once per track per key interval, and a constant `dims` lets the loop unroll. Powers
 * outermost, so building and evaluating all components is one vector operation each. */
static inline float mcd_segment_coefficients(const float t[4], const float v[4][4], uint32_t dims, float coef[4][4]) {
    float h = t[2] - t[1], a = h / (t[2] - t[0]), b = h / (t[3] - t[1]);
    uint32_t c;
    for (c = 0; c < dims; ++c) {
        float p1 = v[1][c], p2 = v[2][c];
        float m1 = a * (p2 - v[0][c]), m2 = b * (v[3][c] - p1);
        coef[0][c] = p1;
        coef[1][c] = m1;
        coef[2][c] = 3.0f * (p2 - p1) - 2.0f * m1 - m2;
        coef[3][c] = 2.0f * (p1 - p2) + m1 + m2;
    }
    return 1.0f / h;
}

/* ---------------------------------------------------------------- skeleton (skeleton.c) */
/* A SKEL section's node records (docs/FORMAT.md). `skel` points at the start of a SKEL section
 * that passed validation. One home for the rest pose and the hierarchy, used by every codec,
 * the contact pass and the local -> world step. */

static inline uint32_t mcd_skel_nodes(const uint8_t* skel) {
    return mcd_rd_u32(skel);
}
static inline const uint8_t* mcd_skel_record(const uint8_t* skel, uint32_t node) {
    return skel + 16 + (size_t)node * MCD_SKEL_NODE_SIZE;
}
static inline int32_t mcd_skel_parent(const uint8_t* skel, uint32_t node) {
    return mcd_rd_i32(mcd_skel_record(skel, node));
}
static inline uint32_t mcd_skel_kind(const uint8_t* skel, uint32_t node) {
    return mcd_skel_record(skel, node)[20];
}
/* The rest translation (BVH OFFSET, glTF rest T) of a node. */
void mcd_skel_rest_translation(const uint8_t* skel, uint32_t node, float out[3]);
/* The whole rest transform: rest rotation, translation and scale. */
void mcd_skel_rest(const uint8_t* skel, uint32_t node, mcd_transform* out);
/* A name at `off` in string block [0, size): non-empty, NUL-terminated inside the block, at
 * most MCD_MAX_NAME_BYTES, well-formed UTF-8 without control characters; a clip name
 * (`is_clip`) also has no '/', '\\' or ':' and is not "." or "..", so it cannot steer a path. */
int mcd_valid_name(const uint8_t* block, uint32_t size, uint32_t off, int is_clip);
/* Check a SKEL section (every rule of docs/FORMAT.md). */
mcd_result mcd_skel_check(const uint8_t* section, uint32_t size);
/* A node's world transform from its parent's world and its own local transform: rotation
 * p.r x c.r, translation p.t + p.r (p.s * c.t), scale p.s * c.s (`world` may be `local`). */
void mcd_compose(const mcd_transform* parent, const mcd_transform* local, mcd_transform* world);
/* The same in scalar code; mcd_compose gives its bits on every target (a test compares them). */
void mcd_compose_scalar(const mcd_transform* parent, const mcd_transform* local, mcd_transform* world);
/* Local transforms of every node -> model space, parents first (the skeleton orders them so). */
void mcd_local_to_world(const uint8_t* skel, uint32_t nodes, mcd_transform* pose);
/* The identity transform (unit scale). */
void mcd_transform_identity(mcd_transform* out);

/* ---------------------------------------------------------------- double quaternions */
/* For the solvers and closed-loop predictors that work in binary64 (contacts, ik-predict). */
typedef struct mcd_dquat { double x, y, z, w; } mcd_dquat;

static inline mcd_dquat mcd_dq_mul(mcd_dquat a, mcd_dquat b) {
    mcd_dquat r;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    return r;
}
static inline mcd_dquat mcd_dq_identity(void) {
    mcd_dquat q = {0.0, 0.0, 0.0, 1.0};
    return q;
}
static inline mcd_dquat mcd_dq_conj(mcd_dquat q) {
    q.x = -q.x;
    q.y = -q.y;
    q.z = -q.z;
    return q;
}
/* v' = q v q* for unit q. */
static inline void mcd_dq_rotate(mcd_dquat q, const double v[3], double out[3]) {
    double tx = 2.0 * (q.y * v[2] - q.z * v[1]);
    double ty = 2.0 * (q.z * v[0] - q.x * v[2]);
    double tz = 2.0 * (q.x * v[1] - q.y * v[0]);
    out[0] = v[0] + q.w * tx + (q.y * tz - q.z * ty);
    out[1] = v[1] + q.w * ty + (q.z * tx - q.x * tz);
    out[2] = v[2] + q.w * tz + (q.x * ty - q.y * tx);
}
/* Normalised to binary32 (identity when q is zero or not finite). */
mcd_quat mcd_dq_to_quat(mcd_dquat q);
/* The basis axis least along u (0, 1 or 2; the first of equals): a direction never parallel to u. */
uint32_t mcd_least_axis(const double u[3]);

/* ---------------------------------------------------------------- clip view and codecs */
/* Everything a codec needs to know about one clip, resolved from the container. */
typedef struct mcd_clip_view {
    const uint8_t* payload;
    uint32_t payload_size;
    uint32_t frame_count;
    float frame_rate;
    const uint8_t* skeleton; /* start of the clip's SKEL section */
    uint32_t node_count;
    const uint8_t* section;  /* the whole codec section the payload lies in */
    uint32_t section_size;
    uint32_t scratch_need;   /* the codec scratch the clip record states */
} mcd_clip_view;

typedef struct mcd_codec_ops {
    uint32_t codec;           /* mcd_codec */
    uint32_t section_kind;    /* FourCC of the section that holds its payloads */
    uint32_t section_version; /* a layout version of that section this runtime reads */
    /* Check the section as a whole (what is shared by its payloads), or NULL. Called once by
     * mcd_validate, before any payload is checked. */
    mcd_result (*validate_section)(const uint8_t* section, uint32_t size);
    /* Check one clip's payload: every rule the format states for it, including entropy
     * streams. After it returns MCD_OK, sampling is memory-safe and finite. Linear in the
     * payload size. */
    mcd_result (*validate)(const mcd_clip_view* clip);
    /* Scratch bytes this codec needs for the clip (multiple of 16). Called after validate;
     * the encoder stores the result in the clip record. */
    size_t (*scratch_size)(const mcd_clip_view* clip);
    /* Local transforms of every node at frame position x in [0, frame_count - 1].
     * `fresh` is nonzero when the scratch holds nothing from an earlier call for this clip.
     * Cannot fail on a validated payload. */
    void (*sample)(const mcd_clip_view* clip, float x, uint32_t flags, mcd_transform* out, void* scratch,
                   int fresh);
} mcd_codec_ops;

/* The codec table (codecs.c): one entry per codec and section version it reads. NULL for an
 * unknown codec id, section kind or version. mcd_find_codec gives the version the encoder
 * writes now; mcd_find_codec_by_kind any entry of the kind (which codec owns it). */
const mcd_codec_ops* mcd_find_codec(uint32_t codec);
const mcd_codec_ops* mcd_find_codec_version(uint32_t codec, uint32_t section_version);
const mcd_codec_ops* mcd_find_codec_by_kind(uint32_t section_kind);

#define MCD_MAX_CODEC_ID 7u

/* Codec implementations. */
extern const mcd_codec_ops mcd_codec_spline_ops;
extern const mcd_codec_ops mcd_codec_neural_ops;
extern const mcd_codec_ops mcd_codec_rma_ops;    /* RMAL version 4 */
extern const mcd_codec_ops mcd_codec_rma_v3_ops; /* RMAL version 3: rma before version 4 */
extern const mcd_codec_ops mcd_codec_rma_v2_ops; /* RMAL version 2: rma before, rma-pca's curve sets */
extern const mcd_codec_ops mcd_codec_fkwavelet_ops;
extern const mcd_codec_ops mcd_codec_ikpredict_ops;
extern const mcd_codec_ops mcd_codec_rmapca_ops;

/* ---------------------------------------------------------------- container access */
/* Resolve clip `clip` of an opened asset. */
mcd_result mcd_clip_view_get(const mcd_asset* asset, uint32_t clip, mcd_clip_view* out,
                             const mcd_codec_ops** out_ops);

/* Offset of skeleton `index`'s SKEL section, or 0 when there is none. */
uint32_t mcd_skeleton_offset(const mcd_asset* asset, uint32_t index);

#define MCD_SCRATCH_HEADER_SIZE 64u

#endif /* MCD_INTERNAL_H */
