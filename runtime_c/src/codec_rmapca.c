/* Codec `rma-pca`: seed 003's subspace representation, sampled in place (docs/FORMAT.md, RMAP
 * version 2).
 *
 * Per behaviour group a PCA basis of virtual markers (16-bit mean, 12-bit axes) that the section
 * shares; per clip the root curves and, for each piece of the clip (a run of frames in one
 * group), the coefficient curves. Every curve set is an `rma` (RMAL v2) payload whose node
 * translations carry the curves, three coefficients a node: this file samples them with the rma
 * codec into scratch areas of their own and adds what the subspace needs: markers = mean + axes
 * x coefficients, dequantized from the codes of the groups the sample reads, each joint's world
 * frame from its markers by Gram-Schmidt, local rotations, the root re-applied. */
#include <string.h>

#include "internal.h"

#define SECTION_HEADER 32u
#define JOINT_RECORD 24u
#define GROUP_HEADER 16u
#define CLIP_HEADER 16u
#define PIECE_RECORD 16u
#define NO_INDEX 0xFFFFu
#define NO_PRIMARY 0xFFFFFFFFu
#define SHARED_BIT 0x80000000u /* a piece's `curves` names a shared set, not an own one */
#define MAX_MARKERS 4096u
#define MAX_GROUPS 65535u
#define MAX_SHARED 0x10000000u
#define FULL_ROOT 1u
#define MAX_BLEND 64u
#define PER_NODE 3u          /* coefficients per curve-set node: its translation's x, y, z */
#define MAX_AXIS_VALUE 2.0f  /* axes are unit vectors: their decoded values stay within +-2 */
#define RMAL_MODES 32u       /* where an RMAL v2 payload's node modes start */
#define MEAN_CODES 65535.0f
#define AXIS_CODES 4095.0f

/* ---------------------------------------------------------------- section prefix */
typedef struct prefix {
    const uint8_t* s;
    uint32_t size, clips, groups, markers, joints, blend, shared, shared_end;
    const uint8_t *joint_table, *group_offsets, *shared_offsets;
    uint32_t tables_end; /* where the first group record lies */
} prefix;

/* Bytes of a group record: header, k (min, step) pairs, 16-bit mean, 12-bit axes, to 4. */
static uint64_t group_record_size(uint64_t k, uint64_t dims) {
    return (GROUP_HEADER + 8u * k + 2u * dims + 3u * ((dims * k + 1u) / 2u) + 3u) & ~(uint64_t)3u;
}

/* The header and where the tables lie: O(1), what every entry point needs. */
static mcd_result parse_prefix(const uint8_t* s, uint32_t size, prefix* P) {
    uint64_t end;
    if (size < SECTION_HEADER) return MCD_ERROR_MALFORMED;
    P->s = s;
    P->size = size;
    P->clips = mcd_rd_u32(s);
    P->groups = mcd_rd_u32(s + 4);
    P->markers = mcd_rd_u32(s + 8);
    P->joints = mcd_rd_u32(s + 12);
    P->blend = mcd_rd_u32(s + 16);
    P->shared = mcd_rd_u32(s + 20);
    P->shared_end = mcd_rd_u32(s + 24);
    if (mcd_rd_u32(s + 28) || P->blend > MAX_BLEND || P->clips == 0) return MCD_ERROR_MALFORMED;
    if (P->groups == 0 || P->groups > MAX_GROUPS || P->shared > MAX_SHARED) return MCD_ERROR_MALFORMED;
    if (P->markers == 0 || P->markers > MAX_MARKERS || P->joints == 0 || P->joints > MCD_MAX_NODES)
        return MCD_ERROR_MALFORMED;
    end = SECTION_HEADER + (uint64_t)JOINT_RECORD * P->joints + 4u * ((uint64_t)P->groups + P->shared);
    if (end > P->shared_end || P->shared_end > size || (P->shared_end & 3u)) return MCD_ERROR_MALFORMED;
    P->joint_table = s + SECTION_HEADER;
    P->group_offsets = P->joint_table + (size_t)JOINT_RECORD * P->joints;
    P->shared_offsets = P->group_offsets + 4u * (size_t)P->groups;
    P->tables_end = (uint32_t)end;
    return MCD_OK;
}

static const uint8_t* group_at(const prefix* P, uint32_t g) {
    return P->s + mcd_rd_u32(P->group_offsets + 4u * (size_t)g);
}

static uint32_t group_k(const prefix* P, uint32_t g) {
    return mcd_rd_u32(group_at(P, g));
}

static uint32_t shared_offset(const prefix* P, uint32_t i) {
    return mcd_rd_u32(P->shared_offsets + 4u * (size_t)i);
}

/* Curve-set nodes that carry k coefficients (one node, resting, when k = 0). */
static uint32_t coef_nodes(uint32_t k) {
    return k ? (k + PER_NODE - 1u) / PER_NODE : 1u;
}

/* ---------------------------------------------------------------- curve sets (rma payloads) */
static uint32_t set_size(const uint8_t* set) {
    return mcd_rd_u32(set);
}
static uint32_t set_frames(const uint8_t* set) {
    return mcd_rd_u32(set + 4);
}
static uint32_t set_nodes(const uint8_t* set) {
    return mcd_rd_u32(set + 8);
}

/* The curve set at `set` as the rma codec's clip (it has no skeleton: rest is identity). */
static void set_view(const prefix* P, const uint8_t* set, mcd_clip_view* v) {
    memset(v, 0, sizeof *v);
    v->section = P->s;
    v->section_size = P->size;
    v->payload = set;
    v->payload_size = set_size(set);
    v->frame_count = set_frames(set);
    v->node_count = set_nodes(set);
    v->frame_rate = 1.0f;
    v->skeleton = NULL;
}

/* A complete curve set within [set, limit): an RMAL v2 payload whose nodes move only their
 * translations (rotation and scale at rest), of `frames` frames and `nodes` nodes (0: any). */
static mcd_result check_set(const prefix* P, const uint8_t* set, const uint8_t* limit, uint32_t frames,
                            uint32_t nodes) {
    mcd_clip_view v;
    uint32_t i, n;
    if (limit - set < (ptrdiff_t)RMAL_MODES) return MCD_ERROR_MALFORMED;
    if (set_size(set) < RMAL_MODES || set_size(set) > (size_t)(limit - set)) return MCD_ERROR_MALFORMED;
    if ((frames && set_frames(set) != frames) || (nodes && set_nodes(set) != nodes)) return MCD_ERROR_MALFORMED;
    set_view(P, set, &v);
    if (mcd_codec_rma_v2_ops.validate(&v) != MCD_OK) return MCD_ERROR_MALFORMED;
    for (i = 0, n = set_nodes(set); i < n; ++i)
        if (set[RMAL_MODES + i] & ~0x0Cu) return MCD_ERROR_MALFORMED; /* rma checked the bytes exist */
    return MCD_OK;
}

/* ---------------------------------------------------------------- section validation */
static int f32_ok(const uint8_t* p) {
    return mcd_in_bounds(mcd_rd_f32(p));
}

/* Group record g at `r`, `avail` bytes: every decoded mean value within +-1e7, every axis
 * value within +-2, padding zero. */
static mcd_result check_group(const uint8_t* r, uint64_t avail, uint32_t dims, uint64_t* size) {
    uint32_t k, a;
    uint64_t codes, end, i;
    const uint8_t* packed;
    if (avail < GROUP_HEADER) return MCD_ERROR_MALFORMED;
    k = mcd_rd_u32(r);
    if (k > dims || mcd_rd_u32(r + 4)) return MCD_ERROR_MALFORMED;
    *size = group_record_size(k, dims);
    if (*size > avail) return MCD_ERROR_MALFORMED;
    for (a = 0; a <= k; ++a) {
        const uint8_t* q = a ? r + GROUP_HEADER + 8u * (a - 1u) : r + 8;
        float lo = mcd_rd_f32(q), step = mcd_rd_f32(q + 4);
        float bound = a ? MAX_AXIS_VALUE : MCD_MAX_ABS_VALUE, top;
        if (!f32_ok(q) || !f32_ok(q + 4) || step < 0.0f) return MCD_ERROR_MALFORMED;
        top = lo + (a ? AXIS_CODES : MEAN_CODES) * step;
        if (lo < -bound || !mcd_finite(top) || top > bound) return MCD_ERROR_MALFORMED;
    }
    codes = (uint64_t)dims * k;
    packed = r + GROUP_HEADER + 8u * (size_t)k + 2u * (size_t)dims;
    /* An odd code count leaves the last byte pair's high code, which is zero; then zero bytes. */
    if ((codes & 1u) && (packed[3u * (codes / 2u) + 1u] >> 4 || packed[3u * (codes / 2u) + 2u]))
        return MCD_ERROR_MALFORMED;
    end = GROUP_HEADER + 8u * (uint64_t)k + 2u * dims + 3u * ((codes + 1u) / 2u);
    for (i = end; i < *size; ++i)
        if (r[i]) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

static mcd_result rmap_validate_section(const uint8_t* s, uint32_t size) {
    prefix P;
    uint32_t i, g, dims;
    uint64_t pos;
    if (parse_prefix(s, size, &P) != MCD_OK) return MCD_ERROR_MALFORMED;
    dims = 3u * P.markers;
    for (i = 0; i < P.joints; ++i) {
        const uint8_t* j = P.joint_table + (size_t)JOINT_RECORD * i;
        uint32_t child = mcd_rd_u16(j + 2), origin = mcd_rd_u16(j + 8);
        float bx, by, bz, b2;
        if (mcd_rd_u16(j + 4) >= P.markers || mcd_rd_u16(j + 6) >= P.markers) return MCD_ERROR_MALFORMED;
        if ((origin != NO_INDEX && origin >= P.markers) || mcd_rd_u16(j + 10)) return MCD_ERROR_MALFORMED;
        if (!f32_ok(j + 12) || !f32_ok(j + 16) || !f32_ok(j + 20)) return MCD_ERROR_MALFORMED;
        bx = mcd_rd_f32(j + 12);
        by = mcd_rd_f32(j + 16);
        bz = mcd_rd_f32(j + 20);
        b2 = bx * bx + by * by + bz * bz;
        /* A marker-b joint carries its rest direction, a unit vector; the others zeros. */
        if (child == NO_INDEX ? !(b2 > 0.25f && b2 < 4.0f) : b2 != 0.0f) return MCD_ERROR_MALFORMED;
    }
    /* Group records back to back after the tables, each where the offset table says. */
    for (g = 0, pos = P.tables_end; g < P.groups; ++g) {
        uint64_t rs;
        if (mcd_rd_u32(P.group_offsets + 4u * (size_t)g) != pos) return MCD_ERROR_MALFORMED;
        if (check_group(s + pos, P.shared_end - pos, dims, &rs) != MCD_OK) return MCD_ERROR_MALFORMED;
        pos += rs;
    }
    /* Shared curve sets back to back after the groups, ending at shared_end. */
    for (i = 0; i < P.shared; ++i) {
        if (shared_offset(&P, i) != pos) return MCD_ERROR_MALFORMED;
        if (check_set(&P, s + pos, s + P.shared_end, 0, 0) != MCD_OK) return MCD_ERROR_MALFORMED;
        pos += set_size(s + pos);
    }
    if (pos != P.shared_end) return MCD_ERROR_MALFORMED;
    /* Then the clip payloads, back to back to the section's end. */
    return mcd_check_payload_run(s, size, pos, P.clips, CLIP_HEADER);
}

/* ---------------------------------------------------------------- clip payload */
typedef struct clip_layout {
    const uint8_t* p;
    uint32_t frames, pieces, flags;
} clip_layout;

static const uint8_t* piece_record(const clip_layout* C, uint32_t i) {
    return C->p + CLIP_HEADER + (size_t)PIECE_RECORD * i;
}
static uint32_t piece_start(const clip_layout* C, uint32_t i) {
    return mcd_rd_u32(piece_record(C, i));
}
static uint32_t piece_group(const clip_layout* C, uint32_t i) {
    return mcd_rd_u32(piece_record(C, i) + 4u);
}
static uint32_t piece_curves(const clip_layout* C, uint32_t i) {
    return mcd_rd_u32(piece_record(C, i) + 8u);
}
static uint32_t piece_primary(const clip_layout* C, uint32_t i) {
    return mcd_rd_u32(piece_record(C, i) + 12u);
}

/* Piece i's curves span its frames plus `blend` frames into each neighbour, where the two
 * pieces are cross-faded (the seed's clip-boundary smoothing); validation keeps every span
 * inside the clip. */
static uint32_t piece_lo(const prefix* P, const clip_layout* C, uint32_t i) {
    return i ? piece_start(C, i) - P->blend : 0u;
}
static uint32_t piece_frames(const prefix* P, const clip_layout* C, uint32_t i) {
    uint32_t hi = i + 1u < C->pieces ? piece_start(C, i + 1u) + P->blend : C->frames - 1u;
    return hi - piece_lo(P, C, i) + 1u;
}

/* Curve-set nodes of piece i: the coefficients', after a repeated piece's reference curve. */
static uint32_t piece_nodes(const prefix* P, const clip_layout* C, uint32_t i) {
    return coef_nodes(group_k(P, piece_group(C, i))) + (piece_primary(C, i) != NO_PRIMARY ? 1u : 0u);
}

static const uint8_t* piece_set(const prefix* P, const clip_layout* C, uint32_t i) {
    uint32_t c = piece_curves(C, i);
    return c & SHARED_BIT ? P->s + shared_offset(P, c & ~SHARED_BIT) : C->p + c;
}

static const uint8_t* root_set(const clip_layout* C) {
    return C->p + CLIP_HEADER + (size_t)PIECE_RECORD * C->pieces;
}

static uint32_t root_nodes(const clip_layout* C) {
    return (C->flags & FULL_ROOT) ? 3u : 2u;
}

/* The header fields (the payload passed rmap_validate). */
static void read_clip(const mcd_clip_view* v, clip_layout* C) {
    C->p = v->payload;
    C->frames = mcd_rd_u32(v->payload + 4);
    C->pieces = mcd_rd_u32(v->payload + 8);
    C->flags = mcd_rd_u32(v->payload + 12);
}

static mcd_result check_pieces(const mcd_clip_view* v, const prefix* P, const clip_layout* C) {
    uint32_t i;
    uint64_t pos;
    if (set_size(C->p) != v->payload_size || C->frames != v->frame_count || C->flags > FULL_ROOT)
        return MCD_ERROR_MALFORMED;
    if (C->pieces == 0 || C->pieces > C->frames) return MCD_ERROR_MALFORMED;
    pos = CLIP_HEADER + (uint64_t)PIECE_RECORD * C->pieces;
    if (pos > v->payload_size) return MCD_ERROR_MALFORMED;
    /* Pieces start at 0 and are more than two blend windows long, so cross-fades neither
     * overlap nor leave the clip. */
    if (piece_start(C, 0) != 0) return MCD_ERROR_MALFORMED;
    for (i = 0; i < C->pieces; ++i) {
        uint32_t next = i + 1u < C->pieces ? piece_start(C, i + 1u) : C->frames - 1u;
        if (piece_group(C, i) >= P->groups) return MCD_ERROR_MALFORMED;
        if (C->pieces > 1u && ((uint64_t)piece_start(C, i) + 2u * P->blend + 1u > next || next >= C->frames))
            return MCD_ERROR_MALFORMED;
    }
    /* The root's curve set, then the pieces' own ones in piece order, to the payload's end. */
    if (check_set(P, C->p + pos, C->p + v->payload_size, C->frames, root_nodes(C)) != MCD_OK)
        return MCD_ERROR_MALFORMED;
    pos += set_size(C->p + pos);
    for (i = 0; i < C->pieces; ++i) {
        uint32_t c = piece_curves(C, i), primary = piece_primary(C, i), k = group_k(P, piece_group(C, i));
        uint32_t frames = piece_frames(P, C, i), nodes = piece_nodes(P, C, i);
        if (c & SHARED_BIT) {
            /* Checked whole by rmap_validate_section: only its shape is the piece's concern. */
            const uint8_t* set;
            if ((c & ~SHARED_BIT) >= P->shared) return MCD_ERROR_MALFORMED;
            set = P->s + shared_offset(P, c & ~SHARED_BIT);
            if (set_frames(set) != frames || set_nodes(set) != nodes) return MCD_ERROR_MALFORMED;
        } else {
            if (c != pos || check_set(P, C->p + pos, C->p + v->payload_size, frames, nodes) != MCD_OK)
                return MCD_ERROR_MALFORMED;
            pos += set_size(C->p + pos);
        }
        /* A repeated piece (seed 003 eq. 6) reads a shared set of k coefficients, any length. */
        if (primary != NO_PRIMARY) {
            if (k == 0 || primary >= P->shared) return MCD_ERROR_MALFORMED;
            if (set_nodes(P->s + shared_offset(P, primary)) != coef_nodes(k)) return MCD_ERROR_MALFORMED;
        }
    }
    return pos == v->payload_size ? MCD_OK : MCD_ERROR_MALFORMED;
}

static mcd_result rmap_validate(const mcd_clip_view* v) {
    prefix P;
    clip_layout C;
    uint32_t i;
    if (parse_prefix(v->section, v->section_size, &P) != MCD_OK) return MCD_ERROR_MALFORMED;
    if ((size_t)(v->payload - v->section) < P.shared_end || v->payload_size < CLIP_HEADER) return MCD_ERROR_MALFORMED;
    read_clip(v, &C);
    if (check_pieces(v, &P, &C) != MCD_OK) return MCD_ERROR_MALFORMED;
    /* One root (node 0): the root curves move it. */
    if (mcd_skel_parent(v->skeleton, 0) >= 0) return MCD_ERROR_MALFORMED;
    for (i = 1; i < v->node_count; ++i)
        if (mcd_skel_parent(v->skeleton, i) < 0) return MCD_ERROR_MALFORMED;
    /* The joint table must fit this clip's skeleton. */
    for (i = 0; i < P.joints; ++i) {
        const uint8_t* j = P.joint_table + (size_t)JOINT_RECORD * i;
        uint32_t node = mcd_rd_u16(j), child = mcd_rd_u16(j + 2);
        if (node >= v->node_count) return MCD_ERROR_MALFORMED;
        if (child != NO_INDEX) {
            float o[3];
            if (child >= v->node_count || mcd_skel_parent(v->skeleton, child) != (int32_t)node) return MCD_ERROR_MALFORMED;
            mcd_skel_rest_translation(v->skeleton, child, o);
            if (!(o[0] * o[0] + o[1] * o[1] + o[2] * o[2] > 1e-12f)) return MCD_ERROR_MALFORMED;
        }
    }
    return MCD_OK;
}

/* ---------------------------------------------------------------- scratch */
/* A piece's curve set loaded in one of two slots (two: a cross-fade reads both pieces). No
 * pointers in the scratch state: its size is stored in the asset (CLIP scratch_bytes), so it
 * must come out the same on 32- and 64-bit targets (wasm32 refused the assets otherwise). */
typedef struct piece_slot {
    int32_t piece;                 /* -1: none */
    uint32_t primary;              /* the primary whose curve set this slot's area samples, or NO_PRIMARY */
} piece_slot;

typedef struct rmap_state {
    piece_slot slot[2];
    uint32_t max_nodes, max_k;     /* transforms in `curves`, floats in `coef` */
    uint32_t root_scratch, piece_scratch, primary_scratch; /* bytes of each rma area */
} rmap_state;
typedef char rmap_state_is_36_bytes[sizeof(rmap_state) == 36u ? 1 : -1]; /* on every target */

typedef struct rmap_views {
    rmap_state* st;
    float* rest;           /* [joints][4] rest frames as quaternions */
    int32_t* joint;        /* [nodes] joint record of a node, -1 none */
    float* world;          /* [nodes][4] world rotations in the aligned frame */
    float* markers;        /* [3M] */
    mcd_transform* curves; /* [max_nodes] what a curve set gives */
    float* coef;           /* [max_k] a piece's coefficients */
    uint8_t *root_rma, *piece_rma[2], *primary_rma[2];
} rmap_views;

static size_t rma_need(const prefix* P, const uint8_t* set) {
    mcd_clip_view v;
    set_view(P, set, &v);
    return mcd_codec_rma_v2_ops.scratch_size(&v);
}

/* What a clip needs, from its curve sets' headers. */
static void clip_needs(const prefix* P, const clip_layout* C, rmap_state* st) {
    uint32_t i;
    size_t piece = 0, primary = 0;
    st->max_nodes = 3u;
    st->max_k = 1u;
    st->root_scratch = (uint32_t)rma_need(P, root_set(C));
    for (i = 0; i < C->pieces; ++i) {
        const uint8_t* set = piece_set(P, C, i);
        uint32_t k = group_k(P, piece_group(C, i)), nodes = set_nodes(set);
        size_t s = rma_need(P, set);
        if (s > piece) piece = s;
        if (nodes > st->max_nodes) st->max_nodes = nodes;
        if (k > st->max_k) st->max_k = k;
        if (piece_primary(C, i) != NO_PRIMARY) {
            s = rma_need(P, P->s + shared_offset(P, piece_primary(C, i)));
            if (s > primary) primary = s;
        }
    }
    st->piece_scratch = (uint32_t)piece;
    st->primary_scratch = (uint32_t)primary;
}

/* The scratch's parts after the state, in order; returns the total. */
static size_t layout(const prefix* P, const mcd_clip_view* v, const rmap_state* st, uint8_t* base, rmap_views* s) {
    size_t at = mcd_align16(sizeof(rmap_state)), sizes[6];
    uint32_t i;
    sizes[0] = mcd_align16(4u * 4u * (size_t)P->joints);
    sizes[1] = mcd_align16(4u * (size_t)v->node_count);
    sizes[2] = mcd_align16(16u * (size_t)v->node_count);
    sizes[3] = mcd_align16(4u * 3u * (size_t)P->markers);
    sizes[4] = mcd_align16(sizeof(mcd_transform) * st->max_nodes);
    sizes[5] = mcd_align16(4u * (size_t)st->max_k);
    if (s) {
        s->st = (rmap_state*)base;
        s->rest = (float*)(base + at);
        s->joint = (int32_t*)(base + at + sizes[0]);
        s->world = (float*)(base + at + sizes[0] + sizes[1]);
        s->markers = (float*)(base + at + sizes[0] + sizes[1] + sizes[2]);
        s->curves = (mcd_transform*)(base + at + sizes[0] + sizes[1] + sizes[2] + sizes[3]);
        s->coef = (float*)(base + at + sizes[0] + sizes[1] + sizes[2] + sizes[3] + sizes[4]);
    }
    for (i = 0; i < 6; ++i) at += sizes[i];
    if (s) {
        s->root_rma = base + at;
        s->piece_rma[0] = s->root_rma + st->root_scratch;
        s->piece_rma[1] = s->piece_rma[0] + st->piece_scratch;
        s->primary_rma[0] = s->piece_rma[1] + st->piece_scratch;
        s->primary_rma[1] = s->primary_rma[0] + st->primary_scratch;
    }
    return at + st->root_scratch + 2u * (size_t)st->piece_scratch + 2u * (size_t)st->primary_scratch;
}

static size_t rmap_scratch_size(const mcd_clip_view* v) {
    prefix P;
    clip_layout C;
    rmap_state st;
    parse_prefix(v->section, v->section_size, &P); /* validated */
    read_clip(v, &C);
    clip_needs(&P, &C, &st);
    return layout(&P, v, &st, NULL, NULL);
}

/* ---------------------------------------------------------------- geometry */
static float dot3(const float a[3], const float b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static void cross3(const float a[3], const float b[3], float out[3]) {
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

static void scale_to_unit(float a[3]) {
    float n = sqrtf(dot3(a, a)), inv = 1.0f / (n > 1e-12f ? n : 1e-12f);
    a[0] *= inv;
    a[1] *= inv;
    a[2] *= inv;
}

/* Columns (u, v', u x v') of Gram-Schmidt on (u, v), as m[row * 3 + column]. */
static void frame_from(const float u_in[3], const float v_in[3], float m[9]) {
    float e1[3], e2[3], e3[3], d;
    int k;
    memcpy(e1, u_in, sizeof e1);
    scale_to_unit(e1);
    d = dot3(v_in, e1);
    for (k = 0; k < 3; ++k) e2[k] = v_in[k] - d * e1[k];
    scale_to_unit(e2);
    cross3(e1, e2, e3);
    for (k = 0; k < 3; ++k) {
        m[k * 3 + 0] = e1[k];
        m[k * 3 + 1] = e2[k];
        m[k * 3 + 2] = e3[k];
    }
}

/* Rest frame of a joint: its bone direction and the side direction the encoder used (the
 * cross product with the coordinate axis least aligned with the bone). */
static void rest_frame(const float axis_in[3], float m[9]) {
    float axis[3], helper[3] = {0.0f, 0.0f, 0.0f}, side[3];
    int h = 0, k;
    memcpy(axis, axis_in, sizeof axis);
    scale_to_unit(axis);
    for (k = 1; k < 3; ++k)
        if (fabsf(axis[k]) < fabsf(axis[h])) h = k;
    helper[h] = 1.0f;
    cross3(axis, helper, side);
    frame_from(axis, side, m);
}

/* q scaled to unit length (the identity for a zero q). Local rotations go out through it too: a
 * product of two unit quaternions is up to 2e-6 off the unit sphere in float, and callers that
 * compose world poses from them (retargeting) would drift from the runtime's world sample. */
static mcd_quat unit_quat(mcd_quat q) {
    float n = sqrtf(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w), inv;
    if (!(n > 1e-20f)) {
        q.x = q.y = q.z = 0.0f;
        q.w = 1.0f;
        return q;
    }
    inv = 1.0f / n;
    q.x *= inv;
    q.y *= inv;
    q.z *= inv;
    q.w *= inv;
    return q;
}

/* Unit quaternion of a rotation matrix (Shepperd); finite for any bounded input. */
static mcd_quat quat_from_matrix(const float r[9]) {
    float tr = r[0] + r[4] + r[8], s, inv;
    mcd_quat q;
    if (tr > 0.0f) {
        s = 2.0f * sqrtf(tr + 1.0f);
        inv = 1.0f / s;
        q.w = 0.25f * s;
        q.x = (r[7] - r[5]) * inv;
        q.y = (r[2] - r[6]) * inv;
        q.z = (r[3] - r[1]) * inv;
    } else if (r[0] > r[4] && r[0] > r[8]) {
        s = 2.0f * sqrtf(fmaxf(1.0f + r[0] - r[4] - r[8], 1e-12f));
        inv = 1.0f / s;
        q.w = (r[7] - r[5]) * inv;
        q.x = 0.25f * s;
        q.y = (r[1] + r[3]) * inv;
        q.z = (r[2] + r[6]) * inv;
    } else if (r[4] > r[8]) {
        s = 2.0f * sqrtf(fmaxf(1.0f + r[4] - r[0] - r[8], 1e-12f));
        inv = 1.0f / s;
        q.w = (r[2] - r[6]) * inv;
        q.x = (r[1] + r[3]) * inv;
        q.y = 0.25f * s;
        q.z = (r[5] + r[7]) * inv;
    } else {
        s = 2.0f * sqrtf(fmaxf(1.0f + r[8] - r[0] - r[4], 1e-12f));
        inv = 1.0f / s;
        q.w = (r[3] - r[1]) * inv;
        q.x = (r[2] + r[6]) * inv;
        q.y = (r[5] + r[7]) * inv;
        q.z = 0.25f * s;
    }
    return unit_quat(q);
}

static mcd_quat quat_at(const float* f) {
    mcd_quat q;
    q.x = f[0];
    q.y = f[1];
    q.z = f[2];
    q.w = f[3];
    return q;
}

/* ---------------------------------------------------------------- sampling */
/* Per clip: each joint's rest frame and each node's joint record. */
static void prepare(const mcd_clip_view* v, const prefix* P, const rmap_views* s) {
    uint32_t i;
    for (i = 0; i < v->node_count; ++i) s->joint[i] = -1;
    for (i = 0; i < P->joints; ++i) {
        const uint8_t* j = P->joint_table + (size_t)JOINT_RECORD * i;
        uint32_t node = mcd_rd_u16(j), child = mcd_rd_u16(j + 2);
        float axis[3], m[9];
        if (child != NO_INDEX) {
            mcd_skel_rest_translation(v->skeleton, child, axis);
        } else {
            axis[0] = mcd_rd_f32(j + 12);
            axis[1] = mcd_rd_f32(j + 16);
            axis[2] = mcd_rd_f32(j + 20);
        }
        rest_frame(axis, m);
        mcd_set_rotation(s->rest + 4u * i, quat_from_matrix(m));
        s->joint[node] = (int32_t)i;
    }
    s->st->slot[0].piece = s->st->slot[1].piece = -1;
    s->st->slot[0].primary = s->st->slot[1].primary = NO_PRIMARY;
}

/* Piece holding frame position x (the last piece whose start is <= x). */
static uint32_t find_piece(const clip_layout* C, float x) {
    uint32_t lo = 0, hi = C->pieces - 1u;
    while (lo < hi) {
        uint32_t mid = (lo + hi + 1u) / 2u;
        if ((float)piece_start(C, mid) <= x) lo = mid;
        else hi = mid - 1u;
    }
    return lo;
}

static float clampf(float x, float lo, float hi) {
    return x > lo ? (x < hi ? x : hi) : lo;
}

/* Coefficient i of a curve set's output, `first` nodes in. */
static float coef_of(const mcd_transform* curves, uint32_t first, uint32_t i) {
    return curves[first + i / PER_NODE].translation[i % PER_NODE];
}

/* The axis codes are an LSB-first stream of 12-bit fields: three bytes hold two codes, six
 * bytes four. */
static float code12_lo(const uint8_t* b) {
    return (float)(int32_t)((uint32_t)b[0] | ((uint32_t)(b[1] & 15u) << 8));
}
static float code12_hi(const uint8_t* b) {
    return (float)(int32_t)((uint32_t)(b[1] >> 4) | ((uint32_t)b[2] << 4));
}
static uint64_t codes48(const uint8_t* b) {
    return (uint64_t)mcd_rd_u32(b) | ((uint64_t)mcd_rd_u16(b + 4) << 32);
}
static float code_at(uint64_t w, unsigned shift) {
    return (float)(int32_t)((w >> shift) & 0xFFFu);
}

/* out[d] += scale x code d, for the `count` 12-bit codes from code index `first`. */
static void add_axis(float* restrict out, const uint8_t* restrict packed, size_t first, uint32_t count, float scale) {
    const uint8_t* b = packed + 3u * (first / 2u);
    uint32_t d = 0;
    if ((first & 1u) && count) {
        out[0] += scale * code12_hi(b);
        b += 3;
        d = 1;
    }
    for (; d + 4u <= count; d += 4u, b += 6) {
        uint64_t w = codes48(b);
        out[d] += scale * code_at(w, 0);
        out[d + 1u] += scale * code_at(w, 12);
        out[d + 2u] += scale * code_at(w, 24);
        out[d + 3u] += scale * code_at(w, 36);
    }
    for (; d + 1u < count; d += 2u, b += 3) {
        out[d] += scale * code12_lo(b);
        out[d + 1u] += scale * code12_hi(b);
    }
    if (d < count) out[d] += scale * code12_lo(b);
}

/* Two axes at once (one pass over `out`), each starting on a byte triple: `count` is even. */
static void add_axis_pair(float* restrict out, const uint8_t* restrict a, const uint8_t* restrict b, uint32_t count,
                          float sa, float sb) {
    uint32_t d = 0;
    for (; d + 4u <= count; d += 4u, a += 6, b += 6) {
        uint64_t wa = codes48(a), wb = codes48(b);
        out[d] += sa * code_at(wa, 0) + sb * code_at(wb, 0);
        out[d + 1u] += sa * code_at(wa, 12) + sb * code_at(wb, 12);
        out[d + 2u] += sa * code_at(wa, 24) + sb * code_at(wb, 24);
        out[d + 3u] += sa * code_at(wa, 36) + sb * code_at(wb, 36);
    }
    if (d < count) {
        out[d] += sa * code12_lo(a) + sb * code12_lo(b);
        out[d + 1u] += sa * code12_hi(a) + sb * code12_hi(b);
    }
}

/* markers += weight x (mean + axes x coefficients) of group g, dequantizing its codes as it
 * goes: value = min + code x step, so sum_a c_a axis_a = sum_a c_a min_a + sum_a (c_a step_a) code_a. */
static void add_group_markers(const prefix* P, uint32_t g, const float* coef, float weight, float* restrict markers) {
    const uint8_t* r = group_at(P, g);
    uint32_t k = mcd_rd_u32(r), dims = 3u * P->markers, a = 0, d;
    const uint8_t* pairs = r + GROUP_HEADER;
    const uint8_t* restrict mean_codes = pairs + 8u * (size_t)k;
    const uint8_t* axis_codes = mean_codes + 2u * (size_t)dims;
    float offset = mcd_rd_f32(r + 8), mean_step = weight * mcd_rd_f32(r + 12);
    for (a = 0; a < k; ++a) offset += coef[a] * mcd_rd_f32(pairs + 8u * a);
    offset *= weight;
    for (d = 0; d < dims; ++d)
        markers[d] += offset + mean_step * (float)((uint32_t)mean_codes[2u * d] | ((uint32_t)mean_codes[2u * d + 1u] << 8));
    a = 0;
    if (!(dims & 1u)) /* every axis starts on a byte triple: two at a time */
        for (; a + 1u < k; a += 2u)
            add_axis_pair(markers, axis_codes + (size_t)3u * (a * (size_t)dims / 2u),
                          axis_codes + (size_t)3u * ((a + 1u) * (size_t)dims / 2u), dims,
                          weight * coef[a] * mcd_rd_f32(pairs + 8u * a + 4u),
                          weight * coef[a + 1u] * mcd_rd_f32(pairs + 8u * a + 12u));
    for (; a < k; ++a)
        add_axis(markers, axis_codes, (size_t)a * dims, dims, weight * coef[a] * mcd_rd_f32(pairs + 8u * a + 4u));
}

/* markers += weight x the markers of piece p at x; `other` is the piece the same sample also
 * reads, whose slot must not be taken. */
static void add_piece_markers(const prefix* P, const clip_layout* C, const rmap_views* s, uint32_t p, uint32_t other,
                              float x, float weight) {
    const uint8_t* set = piece_set(P, C, p);
    mcd_clip_view cv;
    uint32_t i, k = group_k(P, piece_group(C, p)), which, primary = piece_primary(C, p);
    int fresh = 0;
    if (s->st->slot[0].piece == (int32_t)p) which = 0;
    else if (s->st->slot[1].piece == (int32_t)p) which = 1;
    else {
        which = s->st->slot[0].piece == (int32_t)other && other != p ? 1u : 0u;
        s->st->slot[which].piece = (int32_t)p;
        fresh = 1;
    }
    set_view(P, set, &cv);
    mcd_codec_rma_v2_ops.sample(&cv, clampf(x - (float)piece_lo(P, C, p), 0.0f, (float)(cv.frame_count - 1u)), 0,
                                s->curves, s->piece_rma[which], fresh);
    if (primary == NO_PRIMARY) {
        for (i = 0; i < k; ++i) s->coef[i] = coef_of(s->curves, 0, i);
    } else {
        /* Repeated piece: node 0 gives the frame of the primary's curve set to read, the others
         * the differences to add to the primary's coefficients there (seed 003 eq. 6). */
        const uint8_t* pset = P->s + shared_offset(P, primary);
        float r = s->curves[0].translation[0];
        int pfresh = fresh || s->st->slot[which].primary != primary;
        for (i = 0; i < k; ++i) s->coef[i] = coef_of(s->curves, 1, i);
        s->st->slot[which].primary = primary;
        set_view(P, pset, &cv);
        mcd_codec_rma_v2_ops.sample(&cv, clampf(r, 0.0f, (float)(cv.frame_count - 1u)), 0, s->curves,
                                    s->primary_rma[which], pfresh);
        for (i = 0; i < k; ++i) s->coef[i] += coef_of(s->curves, 0, i);
    }
    add_group_markers(P, piece_group(C, p), s->coef, weight, s->markers);
}

/* The rotation the encoder took out of the root: a heading, or the whole rotation. */
static mcd_quat removed_rotation(const clip_layout* C, const mcd_transform* root) {
    mcd_quat q;
    if (C->flags & FULL_ROOT) {
        float n;
        q.x = root[1].translation[0];
        q.y = root[1].translation[1];
        q.z = root[1].translation[2];
        q.w = root[2].translation[0];
        n = sqrtf(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
        if (n > 1e-20f) {
            q.x /= n;
            q.y /= n;
            q.z /= n;
            q.w /= n;
        } else {
            q.x = q.y = q.z = 0.0f;
            q.w = 1.0f;
        }
    } else {
        float half = 0.5f * root[1].translation[0];
        q.x = q.z = 0.0f;
        q.y = sinf(half);
        q.w = cosf(half);
    }
    return q;
}

/* World rotation (aligned frame) of joint record `slot` from the markers: the rotation from the
 * rest frame to the frame W the markers span, W Rest^T. */
static mcd_quat joint_rotation(const prefix* P, const rmap_views* s, uint32_t slot) {
    const uint8_t* j = P->joint_table + (size_t)JOINT_RECORD * slot;
    uint32_t origin = mcd_rd_u16(j + 8), c;
    const float* am = s->markers + 3u * mcd_rd_u16(j + 4);
    const float* sm = s->markers + 3u * mcd_rd_u16(j + 6);
    float a[3] = {0.0f, 0.0f, 0.0f}, u[3], vv[3], wm[9];
    if (origin != NO_INDEX) memcpy(a, s->markers + 3u * origin, sizeof a);
    for (c = 0; c < 3; ++c) {
        u[c] = am[c] - a[c];
        vv[c] = sm[c] - a[c];
    }
    frame_from(u, vv, wm);
    return mcd_qmul(quat_from_matrix(wm), mcd_qconj(quat_at(s->rest + 4u * slot)));
}

static void rmap_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                        int fresh) {
    prefix P;
    clip_layout C;
    rmap_views s;
    mcd_clip_view cv;
    uint32_t i;
    mcd_quat removed;
    float root_t[3];
    (void)flags;
    parse_prefix(v->section, v->section_size, &P); /* validated: cannot fail */
    read_clip(v, &C);
    if (fresh) clip_needs(&P, &C, (rmap_state*)scratch);
    layout(&P, v, (rmap_state*)scratch, (uint8_t*)scratch, &s);
    if (fresh) prepare(v, &P, &s);
    /* Root: translation, and the heading (or the whole rotation of a six-DOF clip). */
    set_view(&P, root_set(&C), &cv);
    mcd_codec_rma_v2_ops.sample(&cv, x, 0, s.curves, s.root_rma, fresh);
    memcpy(root_t, s.curves[0].translation, sizeof root_t);
    removed = removed_rotation(&C, s.curves);
    /* Markers of the piece holding x, cross-faded with its neighbour within `blend` frames of
     * their border (smoothstep weights); the earlier piece is always added first. */
    {
        uint32_t p = find_piece(&C, x), a = p, b = p;
        float w = 0.0f, h = (float)P.blend;
        if (P.blend && p > 0u && x < (float)piece_start(&C, p) + h) {
            a = p - 1u;
            w = (x - ((float)piece_start(&C, p) - h)) / (2.0f * h);
        } else if (P.blend && p + 1u < C.pieces && x > (float)piece_start(&C, p + 1u) - h) {
            b = p + 1u;
            w = (x - ((float)piece_start(&C, b) - h)) / (2.0f * h);
        }
        w = clampf(w, 0.0f, 1.0f);
        w = w * w * (3.0f - 2.0f * w);
        memset(s.markers, 0, 4u * 3u * (size_t)P.markers);
        add_piece_markers(&P, &C, &s, a, b, x, a == b ? 1.0f : 1.0f - w);
        if (a != b) add_piece_markers(&P, &C, &s, b, a, x, w);
    }
    /* Joint rotations from markers, parents first (the skeleton orders them so). Nodes without
     * a joint record keep their rest rotation; every node its rest translation and scale. */
    for (i = 0; i < v->node_count; ++i) {
        int32_t parent = mcd_skel_parent(v->skeleton, i), slot = s.joint[i];
        mcd_quat w, local;
        mcd_skel_rest(v->skeleton, i, &out[i]);
        if (slot >= 0) {
            w = joint_rotation(&P, &s, (uint32_t)slot);
            local = parent < 0 ? w : mcd_qmul(mcd_qconj(quat_at(s.world + 4u * (uint32_t)parent)), w);
        } else {
            local = mcd_quat_of(&out[i]);
            w = parent < 0 ? local : mcd_qmul(quat_at(s.world + 4u * (uint32_t)parent), local);
        }
        mcd_set_rotation(s.world + 4u * i, w);
        if (parent < 0) {
            local = mcd_qmul(removed, local);
            memcpy(out[i].translation, root_t, sizeof root_t);
        }
        mcd_set_rotation(out[i].rotation, unit_quat(local));
    }
}

const mcd_codec_ops mcd_codec_rmapca_ops = {
    MCD_CODEC_RMA_PCA, 0x50414D52u /* "RMAP" */, 2u, rmap_validate_section, rmap_validate, rmap_scratch_size,
    rmap_sample};
