/* Codec `rma-pca`: seed 003's subspace representation (docs/FORMAT.md, RMAP).
 *
 * Per behaviour group a PCA basis of virtual markers (16-bit mean, 12-bit axes); per clip the
 * root curves and, for each piece of the clip (a run of frames in one group), the coefficient
 * curves. Every curve set is an `rma` clip payload whose node translations carry the curves, in
 * an RMAL section embedded in this one: this file reuses the rma codec to decode and sample
 * them and adds what the subspace needs: markers = mean + axes x coefficients, each joint's
 * world frame from its markers by Gram-Schmidt, local rotations, the root re-applied. */
#include <string.h>

#include "internal.h"

#define SECTION_HEADER 32u
#define JOINT_RECORD 24u
#define GROUP_HEADER 16u
#define CLIP_HEADER 24u
#define PIECE_RECORD 8u
#define NO_INDEX 0xFFFFu
#define MAX_MARKERS 4096u
#define MAX_GROUPS 65535u
#define RESIDENT_HEADER 16u
#define FULL_ROOT 1u
#define MAX_BLEND 64u

static size_t align4z(size_t x) {
    return (x + 3u) & ~(size_t)3u;
}

static size_t align16z(size_t x) {
    return (x + 15u) & ~(size_t)15u;
}

/* ---------------------------------------------------------------- section prefix */
typedef struct prefix {
    uint32_t clips, groups, markers, joints, basis_bytes, curves_bytes, blend, size;
    const uint8_t *joint_table, *group_table, *curves;
} prefix;

/* Bytes of a group record: header, k (min, step) pairs, 16-bit mean, 12-bit axes. */
static uint64_t group_record_size(uint32_t k, uint32_t dims) {
    uint64_t codes = (uint64_t)dims * k;
    return align4z((size_t)(GROUP_HEADER + 8u * (uint64_t)k + 2u * (uint64_t)dims + 3u * ((codes + 1u) / 2u)));
}

static int f32_ok(const uint8_t* p) {
    return mcd_in_bounds(mcd_rd_f32(p));
}

static mcd_result parse_prefix(const uint8_t* s, uint32_t size, prefix* P) {
    uint32_t i, g;
    uint64_t end, pos;
    if (size < SECTION_HEADER) return MCD_ERROR_MALFORMED;
    P->clips = mcd_rd_u32(s);
    P->groups = mcd_rd_u32(s + 4);
    P->markers = mcd_rd_u32(s + 8);
    P->joints = mcd_rd_u32(s + 12);
    P->basis_bytes = mcd_rd_u32(s + 16);
    P->curves_bytes = mcd_rd_u32(s + 20);
    P->blend = mcd_rd_u32(s + 24);
    if (P->blend > MAX_BLEND || mcd_rd_u32(s + 28)) return MCD_ERROR_MALFORMED;
    if (P->clips == 0 || P->groups == 0 || P->groups > MAX_GROUPS) return MCD_ERROR_MALFORMED;
    if (P->markers == 0 || P->markers > MAX_MARKERS || P->joints == 0 || P->joints > MCD_MAX_NODES)
        return MCD_ERROR_MALFORMED;
    if ((P->basis_bytes & 3u) || (P->curves_bytes & 3u)) return MCD_ERROR_MALFORMED;
    end = SECTION_HEADER + (uint64_t)JOINT_RECORD * P->joints + P->basis_bytes + P->curves_bytes;
    if (end > size) return MCD_ERROR_MALFORMED;
    P->size = (uint32_t)end;
    P->joint_table = s + SECTION_HEADER;
    P->group_table = P->joint_table + (size_t)JOINT_RECORD * P->joints;
    P->curves = P->group_table + P->basis_bytes;
    for (i = 0; i < P->joints; ++i) {
        const uint8_t* j = P->joint_table + (size_t)JOINT_RECORD * i;
        uint32_t child = mcd_rd_u16(j + 2), origin = mcd_rd_u16(j + 8);
        float bx, by, bz;
        if (mcd_rd_u16(j + 4) >= P->markers || mcd_rd_u16(j + 6) >= P->markers) return MCD_ERROR_MALFORMED;
        if ((origin != NO_INDEX && origin >= P->markers) || mcd_rd_u16(j + 10)) return MCD_ERROR_MALFORMED;
        if (!f32_ok(j + 12) || !f32_ok(j + 16) || !f32_ok(j + 20)) return MCD_ERROR_MALFORMED;
        bx = mcd_rd_f32(j + 12);
        by = mcd_rd_f32(j + 16);
        bz = mcd_rd_f32(j + 20);
        /* A marker-b joint carries its rest direction: a unit vector. */
        if (child == NO_INDEX && !(bx * bx + by * by + bz * bz > 0.25f && bx * bx + by * by + bz * bz < 4.0f))
            return MCD_ERROR_MALFORMED;
    }
    for (g = 0, pos = 0; g < P->groups; ++g) {
        const uint8_t* r = P->group_table + pos;
        uint32_t k, a;
        uint64_t rs;
        if (pos + GROUP_HEADER > P->basis_bytes) return MCD_ERROR_MALFORMED;
        k = mcd_rd_u32(r);
        if (k > 3u * P->markers || mcd_rd_u32(r + 4)) return MCD_ERROR_MALFORMED;
        rs = group_record_size(k, 3u * P->markers);
        if (pos + rs > P->basis_bytes) return MCD_ERROR_MALFORMED;
        for (a = 0; a <= k; ++a) {
            const uint8_t* q = a ? r + GROUP_HEADER + 8u * (a - 1u) : r + 8;
            if (!f32_ok(q) || !f32_ok(q + 4) || mcd_rd_f32(q + 4) < 0.0f) return MCD_ERROR_MALFORMED;
        }
        pos += rs;
    }
    return pos == P->basis_bytes ? MCD_OK : MCD_ERROR_MALFORMED;
}

/* Offset of group g's record (the prefix is valid). */
static const uint8_t* group_at(const prefix* P, uint32_t g) {
    const uint8_t* r = P->group_table;
    uint32_t i;
    for (i = 0; i < g; ++i) r += group_record_size(mcd_rd_u32(r), 3u * P->markers);
    return r;
}

/* ---------------------------------------------------------------- curve sets (rma payloads) */
/* A view of the curve set at byte `offset` of the embedded RMAL section, as the rma codec's
 * clip: `nodes` curves of `frames` frames. */
static void curve_view(const prefix* P, const uint8_t* rma_resident, uint32_t offset, uint32_t frames,
                       uint32_t nodes, mcd_clip_view* v) {
    memset(v, 0, sizeof *v);
    v->section = P->curves;
    v->section_size = P->curves_bytes;
    v->payload = P->curves + offset;
    v->payload_size = offset + 4u <= P->curves_bytes ? mcd_rd_u32(P->curves + offset) : 0u;
    v->frame_count = frames;
    v->node_count = nodes;
    v->frame_rate = 1.0f;
    v->skeleton = NULL; /* curve translations only: no rest offsets */
    v->resident = rma_resident;
}

/* ---------------------------------------------------------------- clip payload */
typedef struct clip_layout {
    uint32_t frames, pieces, flags, curves_offset, repeats;
    const uint8_t *piece_table, *repeat_table;
} clip_layout;

static uint32_t piece_start(const clip_layout* C, uint32_t i) {
    return mcd_rd_u32(C->piece_table + (size_t)PIECE_RECORD * i);
}

static uint32_t piece_group(const clip_layout* C, uint32_t i) {
    return mcd_rd_u32(C->piece_table + (size_t)PIECE_RECORD * i + 4u);
}

/* Piece i's curves span its frames plus `blend` frames into each neighbour, where the two
 * pieces are cross-faded (the seed's clip-boundary smoothing); parse_clip keeps every span
 * inside the clip. */
static uint32_t piece_lo(const prefix* P, const clip_layout* C, uint32_t i) {
    return i ? piece_start(C, i) - P->blend : 0u;
}

static uint32_t piece_frames(const prefix* P, const clip_layout* C, uint32_t i) {
    uint32_t hi = i + 1u < C->pieces ? piece_start(C, i + 1u) + P->blend : C->frames - 1u;
    return hi - piece_lo(P, C, i) + 1u;
}

static uint32_t group_k(const prefix* P, uint32_t g) {
    return mcd_rd_u32(group_at(P, g));
}

/* Offset of the primary's curve set when piece i is a repeated piece (seed 003 eq. 6), else 0:
 * a binary search of the repeat table, which lists repeated pieces in increasing order. */
static uint32_t piece_primary(const clip_layout* C, uint32_t i) {
    uint32_t lo = 0, hi = C->repeats;
    while (lo < hi) {
        uint32_t mid = (lo + hi) / 2u, p = mcd_rd_u32(C->repeat_table + (size_t)PIECE_RECORD * mid);
        if (p == i) return mcd_rd_u32(C->repeat_table + (size_t)PIECE_RECORD * mid + 4u);
        if (p < i) lo = mid + 1u;
        else hi = mid;
    }
    return 0u;
}

/* Curves of piece i: one per component (one zero curve for a group without components), after
 * the reference curve of a repeated piece. */
static uint32_t piece_nodes(const prefix* P, const clip_layout* C, uint32_t i) {
    uint32_t k = group_k(P, piece_group(C, i));
    return (k ? k : 1u) + (piece_primary(C, i) ? 1u : 0u);
}

/* Frames of the curve set at `offset` as its own header says (the runtime clamps the
 * reference into them); 0 when the header is not readable. */
static uint32_t set_frames(const prefix* P, uint32_t offset) {
    return (uint64_t)offset + 8u <= P->curves_bytes ? mcd_rd_u32(P->curves + offset + 4u) : 0u;
}

static mcd_result parse_clip(const mcd_clip_view* v, const prefix* P, clip_layout* C) {
    const uint8_t* p = v->payload;
    uint32_t i;
    if ((size_t)(v->payload - v->section) < P->size || v->payload_size < CLIP_HEADER) return MCD_ERROR_MALFORMED;
    C->frames = mcd_rd_u32(p + 4);
    C->pieces = mcd_rd_u32(p + 8);
    C->flags = mcd_rd_u32(p + 12);
    C->curves_offset = mcd_rd_u32(p + 16);
    C->repeats = mcd_rd_u32(p + 20);
    C->piece_table = p + CLIP_HEADER;
    C->repeat_table = C->piece_table;
    if (mcd_rd_u32(p) != v->payload_size) return MCD_ERROR_MALFORMED;
    if (C->frames != v->frame_count || C->frames == 0 || C->flags > FULL_ROOT) return MCD_ERROR_MALFORMED;
    if (C->pieces == 0 || C->pieces > C->frames || C->repeats > C->pieces) return MCD_ERROR_MALFORMED;
    if ((uint64_t)CLIP_HEADER + (uint64_t)PIECE_RECORD * ((uint64_t)C->pieces + C->repeats) != v->payload_size)
        return MCD_ERROR_MALFORMED;
    C->repeat_table = C->piece_table + (size_t)PIECE_RECORD * C->pieces; /* inside: sizes checked */
    if (C->curves_offset < 16u || (C->curves_offset & 3u) || C->curves_offset >= P->curves_bytes)
        return MCD_ERROR_MALFORMED;
    /* Pieces start at 0 and are more than two blend windows long, so cross-fades neither
     * overlap nor leave the clip. */
    if (piece_start(C, 0) != 0) return MCD_ERROR_MALFORMED;
    for (i = 0; i < C->pieces; ++i) {
        uint32_t next = i + 1u < C->pieces ? piece_start(C, i + 1u) : C->frames - 1u;
        if (piece_group(C, i) >= P->groups) return MCD_ERROR_MALFORMED;
        if (C->pieces > 1u && ((uint64_t)piece_start(C, i) + 2u * P->blend + 1u > next || next >= C->frames))
            return MCD_ERROR_MALFORMED;
    }
    /* Repeated pieces: increasing piece indices, primaries' curve sets inside the section, in
     * groups with components. */
    for (i = 0; i < C->repeats; ++i) {
        const uint8_t* r = C->repeat_table + (size_t)PIECE_RECORD * i;
        uint32_t piece = mcd_rd_u32(r), offset = mcd_rd_u32(r + 4);
        if (piece >= C->pieces || (i > 0 && piece <= mcd_rd_u32(r - PIECE_RECORD))) return MCD_ERROR_MALFORMED;
        if (offset < 16u || (offset & 3u) || offset >= P->curves_bytes) return MCD_ERROR_MALFORMED;
        if (group_k(P, piece_group(C, piece)) == 0) return MCD_ERROR_MALFORMED;
    }
    return MCD_OK;
}

/* The clip's curve sets lie back to back from curves_offset: the root's, then one per piece.
 * Walks to set `index` (0 = root); returns its offset in the RMAL section, or 0 past the end. */
static uint32_t set_offset(const prefix* P, const clip_layout* C, uint32_t index) {
    uint64_t off = C->curves_offset;
    uint32_t i;
    for (i = 0; i < index; ++i) {
        uint32_t size;
        if (off + 4u > P->curves_bytes) return 0;
        size = mcd_rd_u32(P->curves + off);
        if (size == 0) return 0;
        off += size;
    }
    return off + 4u <= P->curves_bytes ? (uint32_t)off : 0u;
}

/* The skeleton node's rest offset. */
static void rest_offset(const mcd_clip_view* v, uint32_t node, float out[3]) {
    const uint8_t* rec = v->skeleton + 16 + (size_t)node * MCD_SKEL_NODE_SIZE;
    out[0] = mcd_rd_f32(rec + 8);
    out[1] = mcd_rd_f32(rec + 12);
    out[2] = mcd_rd_f32(rec + 16);
}

static int32_t parent_of(const mcd_clip_view* v, uint32_t node) {
    return mcd_rd_i32(v->skeleton + 16 + (size_t)node * MCD_SKEL_NODE_SIZE);
}

static mcd_result rmap_validate(const mcd_clip_view* v) {
    prefix P;
    clip_layout C;
    mcd_result r;
    uint32_t i;
    if (parse_prefix(v->section, v->section_size, &P) != MCD_OK) return MCD_ERROR_MALFORMED;
    if (parse_clip(v, &P, &C) != MCD_OK) return MCD_ERROR_MALFORMED;
    /* One root (node 0): the root curves move it. */
    for (i = 1; i < v->node_count; ++i)
        if (parent_of(v, i) < 0) return MCD_ERROR_MALFORMED;
    /* The joint table must fit this clip's skeleton. */
    for (i = 0; i < P.joints; ++i) {
        const uint8_t* j = P.joint_table + (size_t)JOINT_RECORD * i;
        uint32_t node = mcd_rd_u16(j), child = mcd_rd_u16(j + 2);
        if (node >= v->node_count) return MCD_ERROR_MALFORMED;
        if (child != NO_INDEX) {
            float o[3];
            if (child >= v->node_count || parent_of(v, child) != (int32_t)node) return MCD_ERROR_MALFORMED;
            rest_offset(v, child, o);
            if (!(o[0] * o[0] + o[1] * o[1] + o[2] * o[2] > 1e-12f)) return MCD_ERROR_MALFORMED;
        }
    }
    /* Every curve set this clip reads is a valid rma clip of the expected shape. */
    for (i = 0; i <= C.pieces; ++i) {
        mcd_clip_view cv;
        uint32_t off = set_offset(&P, &C, i);
        uint32_t frames = i ? piece_frames(&P, &C, i - 1u) : C.frames;
        uint32_t nodes = i ? piece_nodes(&P, &C, i - 1u) : (C.flags & FULL_ROOT) ? 3u : 2u;
        const uint8_t* rma_resident = NULL;
        if (off == 0) return MCD_ERROR_MALFORMED;
        if (v->resident) rma_resident = v->resident + mcd_rd_u32(v->resident + 4);
        curve_view(&P, rma_resident, off, frames, nodes, &cv);
        r = mcd_codec_rma_ops.validate(&cv);
        if (r != MCD_OK) return MCD_ERROR_MALFORMED;
    }
    /* A primary's curve set: k coefficient curves, as many frames as its header says. */
    for (i = 0; i < C.repeats; ++i) {
        mcd_clip_view cv;
        uint32_t piece = mcd_rd_u32(C.repeat_table + (size_t)PIECE_RECORD * i);
        uint32_t off = mcd_rd_u32(C.repeat_table + (size_t)PIECE_RECORD * i + 4u), frames = set_frames(&P, off);
        if (frames == 0) return MCD_ERROR_MALFORMED;
        curve_view(&P, v->resident ? v->resident + mcd_rd_u32(v->resident + 4) : NULL, off, frames,
                   group_k(&P, piece_group(&C, piece)), &cv);
        if (mcd_codec_rma_ops.validate(&cv) != MCD_OK) return MCD_ERROR_MALFORMED;
    }
    return MCD_OK;
}

/* ---------------------------------------------------------------- resident memory */
/* Resident: u32 total, u32 offset of the embedded RMAL's resident block, u32 groups, u32 0;
 * u32 offset of each group's floats; per group the mean (3M floats) and the k axes (3M floats
 * each), 16-aligned; then the RMAL resident block. */
static size_t bases_bytes(const prefix* P) {
    size_t total = align16z(4u * (size_t)P->groups);
    uint32_t g;
    const uint8_t* r = P->group_table;
    for (g = 0; g < P->groups; ++g) {
        uint32_t k = mcd_rd_u32(r);
        total += align16z(4u * 3u * (size_t)P->markers * (k + 1u));
        r += group_record_size(k, 3u * P->markers);
    }
    return total;
}

static size_t rmap_resident_size(const uint8_t* section, uint32_t size) {
    prefix P;
    if (parse_prefix(section, size, &P) != MCD_OK) return RESIDENT_HEADER;
    return RESIDENT_HEADER + bases_bytes(&P) + mcd_codec_rma_ops.resident_size(P.curves, P.curves_bytes);
}

static uint32_t code12(const uint8_t* packed, size_t i) {
    const uint8_t* b = packed + 3u * (i / 2u);
    return (i & 1u) ? (uint32_t)(b[1] >> 4) | ((uint32_t)b[2] << 4) : (uint32_t)b[0] | ((uint32_t)(b[1] & 15u) << 8);
}

static mcd_result rmap_open_section(const uint8_t* section, uint32_t size, uint8_t* resident) {
    prefix P;
    uint32_t g, dims, *offsets;
    size_t pos;
    const uint8_t* r;
    if (parse_prefix(section, size, &P) != MCD_OK) return MCD_ERROR_MALFORMED;
    dims = 3u * P.markers;
    offsets = (uint32_t*)(resident + RESIDENT_HEADER);
    pos = RESIDENT_HEADER + align16z(4u * (size_t)P.groups);
    for (g = 0, r = P.group_table; g < P.groups; ++g) {
        uint32_t k = mcd_rd_u32(r), a, d;
        float* f = (float*)(resident + pos);
        const uint8_t* mean_codes = r + GROUP_HEADER + 8u * k;
        const uint8_t* axis_codes = mean_codes + 2u * dims;
        offsets[g] = (uint32_t)pos;
        for (a = 0; a <= k; ++a) {
            const uint8_t* q = a ? r + GROUP_HEADER + 8u * (a - 1u) : r + 8;
            float lo = mcd_rd_f32(q), step = mcd_rd_f32(q + 4);
            for (d = 0; d < dims; ++d) {
                uint32_t code = a ? code12(axis_codes, (size_t)(a - 1u) * dims + d) : mcd_rd_u16(mean_codes + 2u * d);
                float x = lo + (float)code * step;
                if (!mcd_in_bounds(x)) return MCD_ERROR_MALFORMED;
                f[(size_t)a * dims + d] = x;
            }
        }
        pos += align16z(4u * (size_t)dims * (k + 1u));
        r += group_record_size(k, dims);
    }
    ((uint32_t*)resident)[0] = (uint32_t)(pos + mcd_codec_rma_ops.resident_size(P.curves, P.curves_bytes));
    ((uint32_t*)resident)[1] = (uint32_t)pos;
    ((uint32_t*)resident)[2] = P.groups;
    return mcd_codec_rma_ops.open_section(P.curves, P.curves_bytes, resident + pos) == MCD_OK ? MCD_OK
                                                                                                : MCD_ERROR_MALFORMED;
}

/* ---------------------------------------------------------------- scratch */
/* A piece's curve set loaded in one of two rma scratch areas (two: a cross-fade reads both). */
typedef struct piece_slot {
    int32_t piece; /* -1 none */
    uint32_t offset, nodes, frames, lo;
    uint32_t primary, primary_frames; /* a repeated piece's primary curve set (0: none loaded) */
} piece_slot;

typedef struct rmap_state {
    piece_slot slot[2];
    uint32_t max_nodes;   /* transforms in `curves` */
    size_t root_scratch, piece_scratch, primary_scratch; /* bytes of the rma scratch areas (each) */
} rmap_state;

typedef struct rmap_views {
    rmap_state* st;
    float* rest;          /* [joints][9] rest frames, columns */
    int32_t* slot;        /* [nodes] joint index of a node, -1 none */
    float* world;         /* [nodes][4] aligned-frame world rotations */
    float* markers;       /* [3M] */
    mcd_transform* curves;/* [max_nodes] */
    float* diff;          /* [max_nodes] a repeated piece's coefficient differences */
    uint8_t *root_rma, *piece_rma[2], *primary_rma[2];
} rmap_views;

static size_t rmap_scratch_layout(const mcd_clip_view* v, const prefix* P, const clip_layout* C,
                                  size_t* root_rma, size_t* piece_rma, size_t* primary_rma, uint32_t* max_nodes) {
    uint32_t i;
    size_t fixed;
    *root_rma = *piece_rma = *primary_rma = 0;
    for (i = 0; i < C->repeats; ++i) {
        mcd_clip_view cv;
        uint32_t off = mcd_rd_u32(C->repeat_table + (size_t)PIECE_RECORD * i + 4u);
        uint32_t piece = mcd_rd_u32(C->repeat_table + (size_t)PIECE_RECORD * i);
        size_t sz;
        curve_view(P, NULL, off, set_frames(P, off), group_k(P, piece_group(C, piece)), &cv);
        sz = mcd_codec_rma_ops.scratch_size(&cv);
        if (sz > *primary_rma) *primary_rma = sz;
    }
    *max_nodes = 3u;
    for (i = 0; i <= C->pieces; ++i) {
        mcd_clip_view cv;
        uint32_t nodes = i ? piece_nodes(P, C, i - 1u) : (C->flags & FULL_ROOT) ? 3u : 2u;
        size_t s;
        curve_view(P, NULL, set_offset(P, C, i), i ? piece_frames(P, C, i - 1u) : C->frames, nodes, &cv);
        s = mcd_codec_rma_ops.scratch_size(&cv);
        if (i == 0) *root_rma = s;
        else if (s > *piece_rma) *piece_rma = s;
        if (nodes > *max_nodes) *max_nodes = nodes;
    }
    fixed = align16z(sizeof(rmap_state)) + align16z(4u * 9u * (size_t)P->joints) + align16z(4u * (size_t)v->node_count) +
            align16z(16u * (size_t)v->node_count) + align16z(4u * 3u * (size_t)P->markers) +
            align16z(sizeof(mcd_transform) * *max_nodes) + align16z(4u * (size_t)*max_nodes);
    return fixed + *root_rma + 2u * *piece_rma + 2u * *primary_rma;
}

static size_t rmap_scratch_size(const mcd_clip_view* v) {
    prefix P;
    clip_layout C;
    size_t a, b, c;
    uint32_t n;
    parse_prefix(v->section, v->section_size, &P); /* validated */
    parse_clip(v, &P, &C);
    return rmap_scratch_layout(v, &P, &C, &a, &b, &c, &n);
}

static void views(void* scratch, const prefix* P, const mcd_clip_view* v, rmap_views* s) {
    uint8_t* q = (uint8_t*)scratch;
    s->st = (rmap_state*)q;
    q += align16z(sizeof(rmap_state));
    s->rest = (float*)q;
    q += align16z(4u * 9u * (size_t)P->joints);
    s->slot = (int32_t*)q;
    q += align16z(4u * (size_t)v->node_count);
    s->world = (float*)q;
    q += align16z(16u * (size_t)v->node_count);
    s->markers = (float*)q;
    q += align16z(4u * 3u * (size_t)P->markers);
    s->curves = (mcd_transform*)q;
    q += align16z(sizeof(mcd_transform) * s->st->max_nodes);
    s->diff = (float*)q;
    q += align16z(4u * (size_t)s->st->max_nodes);
    s->root_rma = q;
    s->piece_rma[0] = q + s->st->root_scratch;
    s->piece_rma[1] = s->piece_rma[0] + s->st->piece_scratch;
    s->primary_rma[0] = s->piece_rma[1] + s->st->piece_scratch;
    s->primary_rma[1] = s->primary_rma[0] + s->st->primary_scratch;
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

/* Unit quaternion of a rotation matrix (Shepperd); finite for any bounded input. */
static mcd_quat quat_from_matrix(const float r[9]) {
    float tr = r[0] + r[4] + r[8], s, n;
    mcd_quat q;
    if (tr > 0.0f) {
        s = 2.0f * sqrtf(tr + 1.0f);
        q.w = 0.25f * s;
        q.x = (r[7] - r[5]) / s;
        q.y = (r[2] - r[6]) / s;
        q.z = (r[3] - r[1]) / s;
    } else if (r[0] > r[4] && r[0] > r[8]) {
        s = 2.0f * sqrtf(fmaxf(1.0f + r[0] - r[4] - r[8], 1e-12f));
        q.w = (r[7] - r[5]) / s;
        q.x = 0.25f * s;
        q.y = (r[1] + r[3]) / s;
        q.z = (r[2] + r[6]) / s;
    } else if (r[4] > r[8]) {
        s = 2.0f * sqrtf(fmaxf(1.0f + r[4] - r[0] - r[8], 1e-12f));
        q.w = (r[2] - r[6]) / s;
        q.x = (r[1] + r[3]) / s;
        q.y = 0.25f * s;
        q.z = (r[5] + r[7]) / s;
    } else {
        s = 2.0f * sqrtf(fmaxf(1.0f + r[8] - r[0] - r[4], 1e-12f));
        q.w = (r[3] - r[1]) / s;
        q.x = (r[2] + r[6]) / s;
        q.y = (r[5] + r[7]) / s;
        q.z = 0.25f * s;
    }
    n = sqrtf(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    if (!(n > 1e-20f)) {
        q.x = q.y = q.z = 0.0f;
        q.w = 1.0f;
        return q;
    }
    q.x /= n;
    q.y /= n;
    q.z /= n;
    q.w /= n;
    return q;
}

static mcd_quat qconj(mcd_quat q) {
    q.x = -q.x;
    q.y = -q.y;
    q.z = -q.z;
    return q;
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
static void prepare(const mcd_clip_view* v, const prefix* P, const rmap_views* s) {
    uint32_t i;
    for (i = 0; i < v->node_count; ++i) s->slot[i] = -1;
    for (i = 0; i < P->joints; ++i) {
        const uint8_t* j = P->joint_table + (size_t)JOINT_RECORD * i;
        uint32_t node = mcd_rd_u16(j), child = mcd_rd_u16(j + 2);
        float axis[3];
        if (child != NO_INDEX) {
            rest_offset(v, child, axis);
        } else {
            axis[0] = mcd_rd_f32(j + 12);
            axis[1] = mcd_rd_f32(j + 16);
            axis[2] = mcd_rd_f32(j + 20);
        }
        rest_frame(axis, s->rest + 9u * i);
        s->slot[node] = (int32_t)i;
    }
    s->st->slot[0].piece = s->st->slot[1].piece = -1;
    s->st->slot[0].primary = s->st->slot[1].primary = 0;
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

/* markers += weight x (mean + axes x coefficients) of piece p at x; `other` is the piece the
 * same sample also reads, whose slot must not be taken. */
static void add_piece_markers(const prefix* P, const clip_layout* C, const mcd_clip_view* v, const rmap_views* s,
                              const uint8_t* rma_resident, uint32_t p, uint32_t other, float x, float weight) {
    piece_slot* sl;
    mcd_clip_view cv;
    const float* basis;
    float local, last;
    uint32_t i, d, k, g = piece_group(C, p), dims = 3u * P->markers, which;
    int fresh = 0;
    if (s->st->slot[0].piece == (int32_t)p) which = 0;
    else if (s->st->slot[1].piece == (int32_t)p) which = 1;
    else {
        which = s->st->slot[0].piece == (int32_t)other && other != p ? 1u : 0u;
        sl = &s->st->slot[which];
        sl->piece = (int32_t)p;
        sl->offset = set_offset(P, C, p + 1u);
        sl->nodes = piece_nodes(P, C, p);
        sl->frames = piece_frames(P, C, p);
        sl->lo = piece_lo(P, C, p);
        fresh = 1;
    }
    sl = &s->st->slot[which];
    curve_view(P, rma_resident, sl->offset, sl->frames, sl->nodes, &cv);
    local = x - (float)sl->lo;
    last = (float)(sl->frames - 1u);
    mcd_codec_rma_ops.sample(&cv, local < 0.0f ? 0.0f : local > last ? last : local, 0, s->curves,
                             s->piece_rma[which], fresh);
    k = mcd_rd_u32(group_at(P, g));
    if (sl->nodes == k + 1u && k > 0u) {
        /* Repeated piece: curve 0 is the frame of the primary's curve set to read, the others
         * the differences to add to the primary's coefficients there (seed 003 eq. 6). */
        uint32_t primary = piece_primary(C, p);
        float r = s->curves[0].translation[0], rl;
        int pfresh = 0;
        for (i = 0; i < k; ++i) s->diff[i] = s->curves[i + 1u].translation[0];
        if (fresh || sl->primary != primary) {
            sl->primary = primary;
            sl->primary_frames = set_frames(P, primary);
            pfresh = 1;
        }
        curve_view(P, rma_resident, primary, sl->primary_frames, k, &cv);
        rl = (float)(sl->primary_frames - 1u);
        mcd_codec_rma_ops.sample(&cv, r > 0.0f ? (r < rl ? r : rl) : 0.0f, 0, s->curves, s->primary_rma[which],
                                 pfresh);
        for (i = 0; i < k; ++i) s->curves[i].translation[0] += s->diff[i];
    }
    basis = (const float*)(v->resident + ((const uint32_t*)(v->resident + RESIDENT_HEADER))[g]);
    for (d = 0; d < dims; ++d) s->markers[d] += weight * basis[d];
    for (i = 0; i < k; ++i) {
        float c = weight * s->curves[i].translation[0];
        const float* axis = basis + (size_t)(i + 1u) * dims;
        for (d = 0; d < dims; ++d) s->markers[d] += c * axis[d];
    }
}

static mcd_result rmap_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out,
                              void* scratch, int fresh) {
    prefix P;
    clip_layout C;
    rmap_views s;
    mcd_clip_view cv;
    const uint8_t* rma_resident;
    uint32_t i;
    mcd_quat removed;
    float root_t[3];
    (void)flags;
    if (!v->resident) return MCD_ERROR_INVALID_ARGUMENT; /* validated but not opened */
    parse_prefix(v->section, v->section_size, &P);      /* validated at open: cannot fail */
    parse_clip(v, &P, &C);
    rma_resident = v->resident + mcd_rd_u32(v->resident + 4);
    if (fresh) {
        rmap_state* st = (rmap_state*)scratch;
        size_t a, b, c;
        uint32_t n;
        rmap_scratch_layout(v, &P, &C, &a, &b, &c, &n);
        st->root_scratch = a;
        st->piece_scratch = b;
        st->primary_scratch = c;
        st->max_nodes = n;
    }
    views(scratch, &P, v, &s);
    if (fresh) prepare(v, &P, &s);
    /* Root: translation, and the heading (or the whole rotation of a six-DOF clip). */
    curve_view(&P, rma_resident, C.curves_offset, C.frames, (C.flags & FULL_ROOT) ? 3u : 2u, &cv);
    mcd_codec_rma_ops.sample(&cv, x, 0, s.curves, s.root_rma, fresh);
    memcpy(root_t, s.curves[0].translation, sizeof root_t);
    if (C.flags & FULL_ROOT) {
        float n;
        removed.x = s.curves[1].translation[0];
        removed.y = s.curves[1].translation[1];
        removed.z = s.curves[1].translation[2];
        removed.w = s.curves[2].translation[0];
        n = sqrtf(removed.x * removed.x + removed.y * removed.y + removed.z * removed.z + removed.w * removed.w);
        if (n > 1e-20f) {
            removed.x /= n;
            removed.y /= n;
            removed.z /= n;
            removed.w /= n;
        } else {
            removed.x = removed.y = removed.z = 0.0f;
            removed.w = 1.0f;
        }
    } else {
        float half = 0.5f * s.curves[1].translation[0];
        removed.x = removed.z = 0.0f;
        removed.y = sinf(half);
        removed.w = cosf(half);
    }
    /* Markers of the piece holding x, cross-faded with its neighbour within `blend` frames of
     * their border (smoothstep weights). */
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
        w = w < 0.0f ? 0.0f : w > 1.0f ? 1.0f : w;
        w = w * w * (3.0f - 2.0f * w);
        memset(s.markers, 0, 4u * 3u * (size_t)P.markers);
        add_piece_markers(&P, &C, v, &s, rma_resident, a, b, x, a == b ? 1.0f : 1.0f - w);
        if (a != b) add_piece_markers(&P, &C, v, &s, rma_resident, b, a, x, w);
    }
    /* Joint rotations from markers, parents first (the skeleton orders them so). */
    for (i = 0; i < v->node_count; ++i) {
        int32_t parent = parent_of(v, i), slot = s.slot[i];
        mcd_quat w, local;
        rest_offset(v, i, out[i].translation);
        if (slot >= 0) {
            const uint8_t* j = P.joint_table + (size_t)JOINT_RECORD * (uint32_t)slot;
            uint32_t origin = mcd_rd_u16(j + 8), c, r;
            const float* am = s.markers + 3u * mcd_rd_u16(j + 4);
            const float* sm = s.markers + 3u * mcd_rd_u16(j + 6);
            const float* rest = s.rest + 9u * (uint32_t)slot;
            float a[3] = {0.0f, 0.0f, 0.0f}, u[3], vv[3], wm[9], rm[9];
            if (origin != NO_INDEX) memcpy(a, s.markers + 3u * origin, sizeof a);
            for (c = 0; c < 3; ++c) {
                u[c] = am[c] - a[c];
                vv[c] = sm[c] - a[c];
            }
            frame_from(u, vv, wm);
            /* R = W Rest^T. */
            for (r = 0; r < 3; ++r)
                for (c = 0; c < 3; ++c)
                    rm[r * 3 + c] = wm[r * 3] * rest[c * 3] + wm[r * 3 + 1] * rest[c * 3 + 1] + wm[r * 3 + 2] * rest[c * 3 + 2];
            w = quat_from_matrix(rm);
            local = parent < 0 ? w : mcd_qmul(qconj(quat_at(s.world + 4u * (uint32_t)parent)), w);
        } else {
            /* A node without rotation channels turns with its parent. */
            w.x = w.y = w.z = 0.0f;
            w.w = 1.0f;
            if (parent >= 0) w = quat_at(s.world + 4u * (uint32_t)parent);
            local.x = local.y = local.z = 0.0f;
            local.w = 1.0f;
        }
        s.world[4u * i] = w.x;
        s.world[4u * i + 1u] = w.y;
        s.world[4u * i + 2u] = w.z;
        s.world[4u * i + 3u] = w.w;
        if (parent < 0) {
            local = mcd_qmul(removed, local);
            memcpy(out[i].translation, root_t, sizeof root_t);
        }
        mcd_set_rotation(out[i].rotation, local);
    }
    return MCD_OK;
}

const mcd_codec_ops mcd_codec_rmapca_ops = {
    MCD_CODEC_RMA_PCA, 0x50414D52u /* "RMAP" */, rmap_validate, rmap_resident_size, rmap_open_section,
    rmap_scratch_size, rmap_sample};
