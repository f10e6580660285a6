/* The skeleton: SKEL records, the rest pose, names, local -> world, and the small binary64
 * quaternion helpers the solvers share (docs/FORMAT.md, "SKEL section"). Every codec, the
 * contact pass and the sampling entry point read the hierarchy through these functions. */
#include <math.h>
#include <string.h>

#include "internal.h"

#define KIND_SKEL 0x4C454B53u /* "SKEL" */

void mcd_transform_identity(mcd_transform* out) {
    out->rotation[0] = out->rotation[1] = out->rotation[2] = 0.0f;
    out->rotation[3] = 1.0f;
    out->translation[0] = out->translation[1] = out->translation[2] = 0.0f;
    out->scale[0] = out->scale[1] = out->scale[2] = 1.0f;
}

void mcd_skel_rest_translation(const uint8_t* skel, uint32_t node, float out[3]) {
    const uint8_t* r = mcd_skel_record(skel, node);
    uint32_t k;
    for (k = 0; k < 3; ++k) out[k] = mcd_rd_f32(r + 8 + 4 * k);
}

void mcd_skel_rest(const uint8_t* skel, uint32_t node, mcd_transform* out) {
    const uint8_t* r = mcd_skel_record(skel, node);
    uint32_t k;
    mcd_transform_identity(out);
    for (k = 0; k < 3; ++k) out->translation[k] = mcd_rd_f32(r + 8 + 4 * k);
    if (mcd_rd_u32(skel + 4) & 1u) { /* rest rotations and scales follow the node records */
        const uint8_t* e = skel + 16 + (size_t)mcd_skel_nodes(skel) * MCD_SKEL_NODE_SIZE + (size_t)node * MCD_SKEL_REST_SIZE;
        for (k = 0; k < 4; ++k) out->rotation[k] = mcd_rd_f32(e + 4 * k);
        for (k = 0; k < 3; ++k) out->scale[k] = mcd_rd_f32(e + 16 + 4 * k);
    }
}

/* ---------------------------------------------------------------- names */

/* Well-formed UTF-8 (no overlong forms, no surrogates, at most U+10FFFF) without control
 * characters, `n` bytes. */
static int clean_utf8(const uint8_t* s, uint32_t n) {
    uint32_t i = 0;
    while (i < n) {
        uint32_t c = s[i], len, cp, k;
        if (c < 0x80u) {
            if (c < 0x20u || c == 0x7Fu) return 0;
            ++i;
            continue;
        }
        if (c >= 0xC2u && c <= 0xDFu) len = 2, cp = c & 0x1Fu;
        else if (c >= 0xE0u && c <= 0xEFu) len = 3, cp = c & 0x0Fu;
        else if (c >= 0xF0u && c <= 0xF4u) len = 4, cp = c & 0x07u;
        else return 0;
        if (i + len > n) return 0;
        for (k = 1; k < len; ++k) {
            if ((s[i + k] & 0xC0u) != 0x80u) return 0;
            cp = (cp << 6) | (s[i + k] & 0x3Fu);
        }
        if ((len == 3 && (cp < 0x800u || (cp >= 0xD800u && cp <= 0xDFFFu))) || (len == 4 && (cp < 0x10000u || cp > 0x10FFFFu)))
            return 0;
        if (cp >= 0x80u && cp < 0xA0u) return 0; /* C1 controls */
        i += len;
    }
    return 1;
}

int mcd_valid_name(const uint8_t* block, uint32_t size, uint32_t off, int is_clip) {
    uint32_t n, i;
    if (off >= size || block[off] == 0) return 0;
    for (n = 0; off + n < size && block[off + n] != 0; ++n)
        if (n >= MCD_MAX_NAME_BYTES) return 0;
    if (off + n >= size) return 0; /* no NUL inside the block */
    if (!clean_utf8(block + off, n)) return 0;
    if (!is_clip) return 1;
    /* A clip name becomes a file name when an asset is decoded: nothing that steers a path. */
    if ((n == 1 && block[off] == '.') || (n == 2 && block[off] == '.' && block[off + 1] == '.')) return 0;
    for (i = 0; i < n; ++i) {
        uint8_t c = block[off + i];
        if (c == '/' || c == '\\' || c == ':') return 0;
    }
    return 1;
}

/* ---------------------------------------------------------------- SKEL */

static int bounded(float v) {
    return mcd_in_bounds(v);
}

mcd_result mcd_skel_check(const uint8_t* s, uint32_t size) {
    uint32_t n, i, strings, flags;
    uint64_t expect;
    float cm;
    if (size < 16) return MCD_ERROR_MALFORMED;
    n = mcd_rd_u32(s);
    if (n < 1 || n > MCD_MAX_NODES) return MCD_ERROR_MALFORMED;
    flags = mcd_rd_u32(s + 4);
    if (flags > 1u) return MCD_ERROR_MALFORMED;
    cm = mcd_rd_f32(s + 8);
    if (!mcd_finite(cm) || !(cm > 0.0f) || cm > MCD_MAX_ABS_VALUE) return MCD_ERROR_MALFORMED;
    strings = mcd_rd_u32(s + 12);
    expect = 16u + (uint64_t)n * (MCD_SKEL_NODE_SIZE + (flags ? MCD_SKEL_REST_SIZE : 0u));
    if ((uint64_t)strings != expect || strings > size) return MCD_ERROR_MALFORMED;
    for (i = 0; i < n; ++i) {
        const uint8_t* r = mcd_skel_record(s, i);
        int32_t parent = mcd_rd_i32(r);
        uint32_t kind = r[20], channels = r[21], c, k, seen = 0;
        if (parent < -1 || parent >= (int32_t)i) return MCD_ERROR_MALFORMED;
        /* End sites and virtual points are leaves. */
        if (parent >= 0 && mcd_skel_kind(s, (uint32_t)parent) != MCD_NODE_JOINT) return MCD_ERROR_MALFORMED;
        if (!mcd_valid_name(s + strings, size - strings, mcd_rd_u32(r + 4), 0)) return MCD_ERROR_MALFORMED;
        for (k = 0; k < 3; ++k)
            if (!bounded(mcd_rd_f32(r + 8 + 4 * k))) return MCD_ERROR_MALFORMED;
        if (kind > MCD_NODE_VIRTUAL || channels > 6 || (kind != MCD_NODE_JOINT && channels != 0)) return MCD_ERROR_MALFORMED;
        for (k = 0; k < 6; ++k) {
            c = r[22 + k];
            if (k < channels) {
                if (c > 5 || (seen & (1u << c))) return MCD_ERROR_MALFORMED;
                seen |= 1u << c;
            } else if (c != 0xFF) {
                return MCD_ERROR_MALFORMED;
            }
        }
        if (mcd_rd_u32(r + 28) != 0) return MCD_ERROR_MALFORMED;
        if (flags) {
            const uint8_t* e = s + 16 + (size_t)n * MCD_SKEL_NODE_SIZE + (size_t)i * MCD_SKEL_REST_SIZE;
            if (!mcd_unit_quat_at(e)) return MCD_ERROR_MALFORMED;
            for (k = 4; k < 7; ++k)
                if (!bounded(mcd_rd_f32(e + 4 * k))) return MCD_ERROR_MALFORMED;
        }
    }
    return MCD_OK;
}

uint32_t mcd_skeleton_offset(const mcd_asset* asset, uint32_t index) {
    uint32_t i, seen = 0;
    if (index >= asset->skeleton_count) return 0;
    if (index < 16) return asset->skeleton_offsets[index];
    for (i = 0; i < asset->section_count; ++i) {
        const uint8_t* e = asset->data + asset->section_table + (size_t)i * MCD_SECTION_ENTRY_SIZE;
        if (mcd_rd_u32(e) == KIND_SKEL) {
            if (seen == index) return mcd_rd_u32(e + 8);
            seen++;
        }
    }
    return 0;
}

/* ---------------------------------------------------------------- local -> world */

/* The scalar composition: the reference for the SSE path's bits. */
void mcd_compose_scalar(const mcd_transform* p, const mcd_transform* local, mcd_transform* world) {
    mcd_quat pq = mcd_quat_of(p), wq;
    float t[3], s[3];
    s[0] = p->scale[0] * local->translation[0];
    s[1] = p->scale[1] * local->translation[1];
    s[2] = p->scale[2] * local->translation[2];
    mcd_qrotate(pq, s, t);
    wq = mcd_qmul(pq, mcd_quat_of(local));
    world->translation[0] = p->translation[0] + t[0];
    world->translation[1] = p->translation[1] + t[1];
    world->translation[2] = p->translation[2] + t[2];
    world->scale[0] = p->scale[0] * local->scale[0];
    world->scale[1] = p->scale[1] * local->scale[1];
    world->scale[2] = p->scale[2] * local->scale[2];
    mcd_set_rotation(world->rotation, wq);
}

#ifdef MCD_SSE
static void store3(float out[3], __m128 v) {
    float f[4];
    _mm_storeu_ps(f, v);
    out[0] = f[0];
    out[1] = f[1];
    out[2] = f[2];
}

void mcd_compose(const mcd_transform* p, const mcd_transform* local, mcd_transform* world) {
    __m128 pq = _mm_loadu_ps(p->rotation);
    __m128 ps = _mm_setr_ps(p->scale[0], p->scale[1], p->scale[2], 0.0f);
    __m128 lt = _mm_setr_ps(local->translation[0], local->translation[1], local->translation[2], 0.0f);
    __m128 ls = _mm_setr_ps(local->scale[0], local->scale[1], local->scale[2], 0.0f);
    __m128 pt = _mm_setr_ps(p->translation[0], p->translation[1], p->translation[2], 0.0f);
    __m128 wq = mcd_qmul_sse(pq, _mm_loadu_ps(local->rotation));
    store3(world->translation, _mm_add_ps(pt, mcd_qrotate_sse(pq, _mm_mul_ps(ps, lt))));
    store3(world->scale, _mm_mul_ps(ps, ls));
    _mm_storeu_ps(world->rotation, wq);
}
#else
void mcd_compose(const mcd_transform* p, const mcd_transform* local, mcd_transform* world) {
    mcd_compose_scalar(p, local, world);
}
#endif

void mcd_local_to_world(const uint8_t* skel, uint32_t nodes, mcd_transform* pose) {
    uint32_t i;
    for (i = 0; i < nodes; ++i) {
        int32_t parent = mcd_skel_parent(skel, i);
        if (parent >= 0) mcd_compose(&pose[parent], &pose[i], &pose[i]);
    }
}

/* ---------------------------------------------------------------- binary64 helpers */

mcd_quat mcd_dq_to_quat(mcd_dquat q) {
    mcd_quat r;
    double n = sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    if (!(n > 0.0) || !(n < 1e300)) {
        r.x = r.y = r.z = 0.0f;
        r.w = 1.0f;
        return r;
    }
    r.x = (float)(q.x / n);
    r.y = (float)(q.y / n);
    r.z = (float)(q.z / n);
    r.w = (float)(q.w / n);
    return r;
}

uint32_t mcd_least_axis(const double u[3]) {
    double a = fabs(u[0]), b = fabs(u[1]), c = fabs(u[2]);
    return a <= b ? (a <= c ? 0u : 2u) : (b <= c ? 1u : 2u);
}
