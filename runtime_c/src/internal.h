/* Internal declarations shared by the runtime's source files. Not installed. */
#ifndef MCD_INTERNAL_H
#define MCD_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

/* ---------------------------------------------------------------- limits (docs/FORMAT.md) */
#define MCD_HEADER_SIZE 32u
#define MCD_SECTION_ENTRY_SIZE 16u
#define MCD_MAX_SECTIONS 4096u
#define MCD_MAX_NODES 1024u
#define MCD_MAX_CLIPS 65535u
#define MCD_SKEL_NODE_SIZE 32u
#define MCD_CLIP_RECORD_SIZE 48u
#define MCD_MAX_FRAME_RATE 100000.0f
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

/* True when x is finite (no isfinite in strict C99 without libm macros on every compiler). */
static inline int mcd_finite(float x) {
    return x == x && x - x == 0.0f;
}

static inline uint32_t mcd_fourcc(char a, char b, char c, char d) {
    return (uint32_t)(uint8_t)a | ((uint32_t)(uint8_t)b << 8) | ((uint32_t)(uint8_t)c << 16) |
           ((uint32_t)(uint8_t)d << 24);
}

uint32_t mcd_crc32(const uint8_t* data, size_t size);

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

/* Write a track's rotation into a transform. */
static inline void mcd_set_rotation(float out[4], mcd_quat q) {
    out[0] = q.x;
    out[1] = q.y;
    out[2] = q.z;
    out[3] = q.w;
}

/* Catmull-Rom segment [t1, t2] of keys (t0, v0) ... (t3, v3) as Horner coefficients in
 * s = (x - t1) / (t2 - t1): coef[c][power], for `dims` components; returns 1 / (t2 - t1). */
float mcd_segment_coefficients(const float t[4], const float v[4][4], uint32_t dims, float coef[4][4]);

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
    /* The section's resident memory (filled by open_section), or NULL: always NULL during
     * mcd_validate, and for codecs that sample in place. */
    const uint8_t* resident;
} mcd_clip_view;

typedef struct mcd_codec_ops {
    uint32_t codec;         /* mcd_codec */
    uint32_t section_kind;  /* FourCC of the section that holds its payloads */
    /* Check one clip's payload. Called by mcd_validate with clip->resident == NULL (check
     * everything the raw bytes allow) and again by mcd_open with the section's resident
     * memory decoded (check what only the decoded data shows). After both return MCD_OK,
     * sampling is memory-safe and finite. */
    mcd_result (*validate)(const mcd_clip_view* clip);
    /* Resident bytes the codec decodes its section into at open (multiple of 16), or NULL
     * when it samples in place. Safe on any section bytes; 0 means none. */
    size_t (*resident_size)(const uint8_t* section, uint32_t size);
    /* Decode the section into `resident` (resident_size bytes, 16-aligned, zeroed by the
     * caller) and check the decoded data. NULL when resident_size is NULL. */
    mcd_result (*open_section)(const uint8_t* section, uint32_t size, uint8_t* resident);
    /* Scratch bytes this codec needs for the clip (multiple of 16). Called after validate. */
    size_t (*scratch_size)(const mcd_clip_view* clip);
    /* Local transforms of every node at frame position x in [0, frame_count - 1].
     * `fresh` is nonzero when the scratch holds nothing from an earlier call for this clip. */
    mcd_result (*sample)(const mcd_clip_view* clip, float x, uint32_t flags, mcd_transform* out,
                         void* scratch, int fresh);
} mcd_codec_ops;

/* The codec table (codecs.c); NULL for an unknown codec id or section kind. */
const mcd_codec_ops* mcd_find_codec(uint32_t codec);
const mcd_codec_ops* mcd_find_codec_by_kind(uint32_t section_kind);
/* The layout version of a codec's section this runtime reads (docs/FORMAT.md). */
uint32_t mcd_codec_section_version(uint32_t codec);

#define MCD_MAX_CODEC_ID 7u /* resident_offsets[] in mcd_asset is indexed by codec id */

/* Codec implementations. */
extern const mcd_codec_ops mcd_codec_spline_ops;
extern const mcd_codec_ops mcd_codec_neural_ops;
extern const mcd_codec_ops mcd_codec_rma_ops;
extern const mcd_codec_ops mcd_codec_fkwavelet_ops;
extern const mcd_codec_ops mcd_codec_ikpredict_ops;
extern const mcd_codec_ops mcd_codec_rmapca_ops;

/* ---------------------------------------------------------------- container access */
/* Resolve clip `clip` of an opened (validated) asset. */
mcd_result mcd_clip_view_get(const mcd_asset* asset, uint32_t clip, mcd_clip_view* out,
                             const mcd_codec_ops** out_ops);

/* Offset (and size) of the asset's CNTC section, or 0 when it has none. */
uint32_t mcd_contacts_section(const mcd_asset* asset, uint32_t* out_size);

/* Offset of skeleton `index`'s SKEL section, or 0 when there is none. */
uint32_t mcd_skeleton_offset(const mcd_asset* asset, uint32_t index);

#define MCD_SCRATCH_HEADER_SIZE 64u

#endif /* MCD_INTERNAL_H */
