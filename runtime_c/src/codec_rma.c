/* Codec `rma`: per-track Catmull-Rom keys placed freely (no block grid), their times and values
 * entropy coded with the runtime's coder (docs/FORMAT.md, RMAL).
 *
 * The section is decoded once, at mcd_open, into resident memory: per clip the key frames,
 * the dequantised key values and a seek table (the key at or before every 32nd frame). A
 * sample then reads floats only: random access finds each track's interval through the seek
 * table and a short scan; sequential playback keeps each track's interval in the scratch and
 * moves it forward a key at a time. */
#include <string.h>

#include "entropy.h"
#include "internal.h"

#define SECTION_HEADER 16u
#define PAYLOAD_HEADER 32u
#define RESIDENT_SECTION_HEADER 16u
#define CLIP_BLOCK_HEADER 16u
#define TRACK_ENTRY 16u
#define SEEK_SHIFT 5u
#define MAX_Q 16777216 /* |q| <= 2^24: q x step is exact in binary32 */

enum { KIND_MRP = 1, KIND_TWIST = 2, KIND_TRANSLATION = 3 };
enum { PREDICT_PREVIOUS = 0, PREDICT_HALF_SLOPE = 1, PREDICT_SLOPE = 2 };

static size_t align4z(size_t x) {
    return (x + 3u) & ~(size_t)3u;
}

static size_t align16z(size_t x) {
    return (x + 15u) & ~(size_t)15u;
}

/* Descriptor: u8 kind, u8 key grid | predictor << 4, then i16 reference[3] (rotations) or u16 0 (translation), u32
 * key_count, u32 value_bytes, f32 step (one for all components; a twist's MRPs), and for a
 * twist i16 axis[3], u16 0, f32 angle step. */
static uint32_t desc_size(uint32_t kind) {
    return kind == KIND_MRP ? 20u : kind == KIND_TWIST ? 32u : kind == KIND_TRANSLATION ? 16u : 0u;
}

/* Offsets within a descriptor. */
static uint32_t desc_counts(uint32_t kind) {
    return kind == KIND_TRANSLATION ? 4u : 8u;
}

static void desc_steps(const uint8_t* d, uint32_t kind, float step[4]) {
    float s = mcd_rd_f32(d + desc_counts(kind) + 8u);
    step[0] = step[1] = step[2] = step[3] = s;
    if (kind == KIND_TWIST) step[0] = mcd_rd_f32(d + 28);
}

static uint32_t kind_dims(uint32_t kind) {
    return kind == KIND_TWIST ? 4u : 3u;
}

/* ---------------------------------------------------------------- payload layout */
typedef struct layout {
    uint32_t size, frames, nodes, tracks, constants, keys, resident_offset, gap_bytes;
    uint32_t values;   /* key values over all tracks (sum of key_count x dims) */
    uint32_t interior; /* keys between each track's first and last: two gap-stream values each */
    uint32_t seek_len; /* seek entries per track */
    const uint8_t *modes, *consts, *descs, *gaps, *streams;
} layout;

static uint32_t seek_len(uint32_t frames) {
    return ((frames - 1u) >> SEEK_SHIFT) + 1u;
}

/* Bytes of a clip's resident block (multiple of 16). */
static size_t clip_resident_bytes(const layout* L) {
    return CLIP_BLOCK_HEADER + (size_t)TRACK_ENTRY * L->tracks + align16z(4u * (size_t)L->keys) +
           align16z(4u * (size_t)L->values) + align16z(4u * (size_t)L->tracks * L->seek_len);
}

/* Parse and check everything the raw bytes of one payload allow; `avail` bytes are readable
 * at p. Does not decode the entropy streams (mcd_open does). */
static mcd_result parse_payload(const uint8_t* p, size_t avail, layout* L) {
    uint32_t i, off, track, consts_used = 0;
    uint64_t keys = 0, values = 0, streams = 0, interior = 0, end;
    if (avail < PAYLOAD_HEADER) return MCD_ERROR_MALFORMED;
    L->size = mcd_rd_u32(p);
    L->frames = mcd_rd_u32(p + 4);
    L->nodes = mcd_rd_u32(p + 8);
    L->tracks = mcd_rd_u32(p + 12);
    L->constants = mcd_rd_u32(p + 16);
    L->keys = mcd_rd_u32(p + 20);
    L->resident_offset = mcd_rd_u32(p + 24);
    L->gap_bytes = mcd_rd_u32(p + 28);
    if (L->size < PAYLOAD_HEADER || L->size > avail || (L->size & 3u)) return MCD_ERROR_MALFORMED;
    if (L->frames == 0 || L->nodes == 0 || L->nodes > MCD_MAX_NODES) return MCD_ERROR_MALFORMED;
    if (L->tracks > 2u * L->nodes || L->constants > 7u * L->nodes) return MCD_ERROR_MALFORMED;
    if (L->resident_offset & 15u) return MCD_ERROR_MALFORMED;
    if ((uint64_t)L->keys > (uint64_t)L->tracks * L->frames) return MCD_ERROR_MALFORMED;
    L->modes = p + PAYLOAD_HEADER;
    end = PAYLOAD_HEADER + align4z(L->nodes) + 4u * (uint64_t)L->constants;
    if (end > L->size) return MCD_ERROR_MALFORMED;
    L->consts = L->modes + align4z(L->nodes);
    L->descs = p + end;
    for (i = L->nodes; i < align4z(L->nodes); ++i)
        if (L->modes[i]) return MCD_ERROR_MALFORMED;
    for (i = 0; i < L->constants; ++i)
        if (!mcd_in_bounds(mcd_rd_f32(L->consts + 4u * i))) return MCD_ERROR_MALFORMED;
    /* Node modes: tracks and constants are taken in node order, rotation before translation. */
    for (i = 0, track = 0, off = 0; i < L->nodes; ++i) {
        uint32_t m = L->modes[i], rm = m & 3u, tm = (m >> 2) & 3u, pass;
        if ((m >> 4) || rm == 3u || tm == 3u) return MCD_ERROR_MALFORMED;
        for (pass = 0; pass < 2; ++pass) {
            uint32_t mode = pass ? tm : rm, kind, size, dims, count, vbytes, c;
            const uint8_t* d;
            if (mode == 1u) {
                if (!pass) {
                    if (consts_used + 4u > L->constants || !mcd_unit_quat_at(L->consts + 4u * consts_used))
                        return MCD_ERROR_MALFORMED;
                    consts_used += 4u;
                } else {
                    if (consts_used + 3u > L->constants) return MCD_ERROR_MALFORMED;
                    consts_used += 3u;
                }
                continue;
            }
            if (mode != 2u) continue;
            if (track >= L->tracks || end + off + 4u > L->size) return MCD_ERROR_MALFORMED;
            d = L->descs + off;
            kind = d[0];
            size = desc_size(kind);
            if (size == 0 || end + off + size > L->size) return MCD_ERROR_MALFORMED;
            if ((kind == KIND_TRANSLATION) != (pass == 1u)) return MCD_ERROR_MALFORMED;
            /* Byte 1: key grid (1 ... 8) in the low nibble, value predictor (0 ... 2) above. */
            if ((d[1] & 15u) < 1u || (d[1] & 15u) > 8u || (d[1] >> 4) > PREDICT_SLOPE) return MCD_ERROR_MALFORMED;
            if (kind == KIND_TRANSLATION && mcd_rd_u16(d + 2)) return MCD_ERROR_MALFORMED;
            dims = kind_dims(kind);
            count = mcd_rd_u32(d + desc_counts(kind));
            vbytes = mcd_rd_u32(d + desc_counts(kind) + 4u);
            if (count == 0 || count > L->frames || (L->frames > 1u && count < 2u)) return MCD_ERROR_MALFORMED;
            {
                float step[4];
                desc_steps(d, kind, step);
                for (c = 0; c < dims; ++c)
                    /* The decoded values are bounded at open (q x step within the format's bound). */
                    if (!mcd_in_bounds(step[c]) || step[c] < 0.0f) return MCD_ERROR_MALFORMED;
            }
            if (kind == KIND_TWIST) {
                float ax = (float)(int16_t)mcd_rd_u16(d + 20), ay = (float)(int16_t)mcd_rd_u16(d + 22);
                float az = (float)(int16_t)mcd_rd_u16(d + 24);
                if (mcd_rd_u16(d + 26)) return MCD_ERROR_MALFORMED;
                if (ax * ax + ay * ay + az * az < 0.25f * 32767.0f * 32767.0f) return MCD_ERROR_MALFORMED;
            }
            keys += count;
            interior += count - (count > 1u ? 2u : 1u);
            values += (uint64_t)count * dims;
            streams += vbytes;
            off += size;
            track++;
        }
    }
    if (track != L->tracks || consts_used != L->constants || keys != L->keys) return MCD_ERROR_MALFORMED;
    if (values > 0xFFFFFFFFu / 4u) return MCD_ERROR_MALFORMED;
    L->values = (uint32_t)values;
    L->interior = (uint32_t)interior; /* <= keys */
    L->seek_len = seek_len(L->frames);
    L->gaps = L->descs + off;
    L->streams = L->gaps + L->gap_bytes;
    end += (uint64_t)off + L->gap_bytes + streams;
    /* The payload ends after its streams, padded with zeros to a multiple of 4. */
    if (align4z((size_t)end) != L->size || end > L->size) return MCD_ERROR_MALFORMED;
    for (i = (uint32_t)end; i < L->size; ++i)
        if (p[i]) return MCD_ERROR_MALFORMED;
    if ((uint64_t)clip_resident_bytes(L) > 0x7FFFFFFFu) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* Walk the section's payloads (they follow the 16-byte section header back to back). Calls
 * nothing; returns the resident bytes they need, or 0 when the walk breaks a rule. */
static size_t walk_resident(const uint8_t* section, uint32_t size) {
    uint32_t count, i;
    size_t pos = SECTION_HEADER, total = RESIDENT_SECTION_HEADER;
    if (size < SECTION_HEADER) return 0;
    count = mcd_rd_u32(section);
    if (count == 0 || mcd_rd_u32(section + 4) || mcd_rd_u32(section + 8) || mcd_rd_u32(section + 12)) return 0;
    for (i = 0; i < count; ++i) {
        layout L;
        if (parse_payload(section + pos, size - pos, &L) != MCD_OK) return 0;
        if ((size_t)L.resident_offset != total - RESIDENT_SECTION_HEADER) return 0;
        total += clip_resident_bytes(&L);
        if (total > 0x7FFFFFFFu) return 0;
        pos += L.size;
    }
    return pos == size ? total : 0;
}

static mcd_result rma_validate(const mcd_clip_view* v) {
    layout L;
    mcd_result r;
    if ((size_t)(v->payload - v->section) < SECTION_HEADER) return MCD_ERROR_MALFORMED;
    r = parse_payload(v->payload, v->payload_size, &L);
    if (r != MCD_OK) return r;
    if (L.size != v->payload_size || L.frames != v->frame_count || L.nodes != v->node_count)
        return MCD_ERROR_MALFORMED;
    if (v->resident) {
        /* Opened: the clip must point at a payload the section walk decoded, not at bytes
         * inside another one. */
        uint32_t total = mcd_rd_u32(v->resident);
        const uint8_t* block = v->resident + RESIDENT_SECTION_HEADER + L.resident_offset;
        if ((uint64_t)RESIDENT_SECTION_HEADER + L.resident_offset + clip_resident_bytes(&L) > total)
            return MCD_ERROR_MALFORMED;
        if (mcd_rd_u32(block) != (uint32_t)(v->payload - v->section)) return MCD_ERROR_MALFORMED;
    }
    return MCD_OK;
}

static size_t rma_resident_size(const uint8_t* section, uint32_t size) {
    size_t need = walk_resident(section, size);
    /* A broken walk still gets a header, so mcd_open reaches open_section and reports it. */
    return need ? need : RESIDENT_SECTION_HEADER;
}

/* ---------------------------------------------------------------- decoding at open */
typedef struct clip_block {
    uint32_t* track_table; /* [tracks][4]: first key, key count, first value, 0 */
    uint32_t* frames;
    float* values;
    uint32_t* seek;
} clip_block;

static void block_views(uint8_t* block, const layout* L, clip_block* b) {
    uint8_t* q = block + CLIP_BLOCK_HEADER;
    b->track_table = (uint32_t*)q;
    q += (size_t)TRACK_ENTRY * L->tracks;
    b->frames = (uint32_t*)q;
    q += align16z(4u * (size_t)L->keys);
    b->values = (float*)q;
    q += align16z(4u * (size_t)L->values);
    b->seek = (uint32_t*)q;
}

/* The prediction of key i's component c from the keys before it, already decoded in q: the
 * previous key, plus (predictor 1) half or (2) all of the slope of the two keys before,
 * carried over the gap to key i, rounded half up in integers. Frames increase strictly
 * (checked when they were decoded) and |q| <= 2^24, gaps < 2^32: products stay below 2^60. */
static int64_t predict(const int32_t* q, const uint32_t* frames, uint32_t i, uint32_t dims, uint32_t c,
                       uint32_t predictor) {
    int64_t prev, num, den, n2;
    if (i == 0) return 0;
    prev = q[(i - 1u) * dims + c];
    if (i < 2u || predictor == PREDICT_PREVIOUS) return prev;
    num = (prev - q[(i - 2u) * dims + c]) * (int64_t)(frames[i] - frames[i - 1u]) * (int64_t)predictor;
    den = 2 * (int64_t)(frames[i - 1u] - frames[i - 2u]);
    n2 = 2 * num + den;
    /* Floor division (C truncates toward zero). */
    return prev + (n2 >= 0 ? n2 / (2 * den) : -((-n2 + 2 * den - 1) / (2 * den)));
}

static mcd_result open_clip(const layout* L, uint32_t payload_offset, uint8_t* block) {
    clip_block b;
    uint32_t u, first = 0, value = 0, gap_pos = 0;
    size_t stream_off = 0;
    const uint8_t* d;
    int32_t* gaps;
    mcd_result r;
    block_views(block, L, &b);
    ((uint32_t*)block)[0] = payload_offset;
    ((uint32_t*)block)[1] = L->tracks;
    ((uint32_t*)block)[2] = L->keys;
    ((uint32_t*)block)[3] = L->values;
    /* Key frames. Each interior key's (grid cells since the previous key's cell, offset in its
     * cell) pair is decoded into the value array first (it holds at least 3 entries per key),
     * then expanded into frames. */
    gaps = (int32_t*)b.values;
    r = mcd_entropy_decode(L->gaps, L->gap_bytes, 2u, gaps, 2u * L->interior);
    if (r != MCD_OK) return MCD_ERROR_MALFORMED;
    for (u = 0, d = L->descs; u < L->tracks; ++u) {
        uint32_t kind = d[0], grid = d[1] & 15u, count = mcd_rd_u32(d + desc_counts(kind)), i;
        uint64_t cell = 0, frame = 0;
        b.track_table[4u * u] = first;
        b.track_table[4u * u + 1u] = count;
        b.frames[first] = 0;
        for (i = 1; i + 1u < count; ++i) {
            int32_t step = gaps[2u * gap_pos], offset = gaps[2u * gap_pos + 1u];
            uint64_t f;
            gap_pos++;
            if (step < 0 || offset < 0 || (uint32_t)offset >= grid) return MCD_ERROR_MALFORMED;
            cell += (uint64_t)step;
            f = cell * grid + (uint32_t)offset;
            if (f <= frame || f >= (uint64_t)L->frames - 1u) return MCD_ERROR_MALFORMED;
            frame = f;
            b.frames[first + i] = (uint32_t)frame;
        }
        if (count > 1u) b.frames[first + count - 1u] = L->frames - 1u; /* the last key is implied */
        first += count;
        d += desc_size(kind);
    }
    for (u = 0, d = L->descs; u < L->tracks; ++u) {
        uint32_t kind = d[0], dims = kind_dims(kind), count = mcd_rd_u32(d + desc_counts(kind));
        uint32_t vbytes = mcd_rd_u32(d + desc_counts(kind) + 4u), i, c, j;
        const uint32_t* frames = b.frames + b.track_table[4u * u];
        int32_t* q = (int32_t*)(b.values + value);
        float step[4];
        b.track_table[4u * u + 2u] = value;
        /* Values: residuals from each key's prediction (docs/FORMAT.md), then q x step. */
        r = mcd_entropy_decode(L->streams + stream_off, vbytes, dims, q, count * dims);
        if (r != MCD_OK) return MCD_ERROR_MALFORMED;
        desc_steps(d, kind, step);
        for (c = 0; c < dims; ++c)
            for (i = 0; i < count; ++i) {
                int64_t v = predict(q, frames, i, dims, c, (uint32_t)d[1] >> 4) + q[i * dims + c];
                if (v > MAX_Q || v < -MAX_Q) return MCD_ERROR_MALFORMED;
                q[i * dims + c] = (int32_t)v;
            }
        for (i = 0; i < count * dims; ++i) {
            b.values[value + i] = (float)q[i] * step[i % dims];
            if (!mcd_in_bounds(b.values[value + i])) return MCD_ERROR_MALFORMED;
        }
        /* Seek: per 32-frame block, the last key at or before its first frame. */
        for (j = 0, i = 0; j < L->seek_len; ++j) {
            uint32_t f = j << SEEK_SHIFT;
            while (i + 1u < count && frames[i + 1u] <= f) ++i;
            b.seek[(size_t)u * L->seek_len + j] = i;
        }
        stream_off += vbytes;
        value += count * dims;
        d += desc_size(kind);
    }
    return MCD_OK;
}

static mcd_result rma_open_section(const uint8_t* section, uint32_t size, uint8_t* resident) {
    size_t total = walk_resident(section, size), pos = SECTION_HEADER;
    uint32_t count, i;
    if (total == 0) return MCD_ERROR_MALFORMED;
    count = mcd_rd_u32(section);
    ((uint32_t*)resident)[0] = (uint32_t)total;
    ((uint32_t*)resident)[1] = count;
    for (i = 0; i < count; ++i) {
        layout L;
        mcd_result r;
        parse_payload(section + pos, size - pos, &L); /* checked by the walk */
        r = open_clip(&L, (uint32_t)pos, resident + RESIDENT_SECTION_HEADER + L.resident_offset);
        if (r != MCD_OK) return r;
        pos += L.size;
    }
    return MCD_OK;
}

/* ---------------------------------------------------------------- sampling */
typedef struct track_state {
    uint32_t kind, dims, count, valid;
    const uint32_t* frames;
    const float* values;
    const uint32_t* seek;
    mcd_quat ref;
    float axis[4];
    uint32_t seg;      /* interval [frames[seg], frames[seg + 1]] */
    float t1, t2, inv_h;
    float coef[4][4];
} track_state;

typedef struct node_plan {
    mcd_transform base;
    int32_t rot_track, trans_track;
} node_plan;

typedef struct rma_views {
    node_plan* plans;
    track_state* tracks;
} rma_views;

static size_t rma_scratch_size(const mcd_clip_view* v) {
    uint32_t nodes = mcd_rd_u32(v->payload + 8), tracks = mcd_rd_u32(v->payload + 12);
    return align16z(sizeof(node_plan) * nodes) + align16z(sizeof(track_state) * tracks);
}

static void scratch_views(void* scratch, uint32_t nodes, rma_views* s) {
    s->plans = (node_plan*)scratch;
    s->tracks = (track_state*)((uint8_t*)scratch + align16z(sizeof(node_plan) * nodes));
}

static void prepare(const layout* L, const mcd_clip_view* v, const rma_views* s) {
    const uint8_t* block = v->resident + RESIDENT_SECTION_HEADER + L->resident_offset;
    clip_block b;
    const uint8_t* d = L->descs;
    uint32_t i, k, track = 0, consts = 0;
    block_views((uint8_t*)block, L, &b);
    for (i = 0; i < L->tracks; ++i) {
        track_state* ts = &s->tracks[i];
        memset(ts, 0, sizeof *ts);
        ts->kind = d[0];
        ts->dims = kind_dims(ts->kind);
        ts->count = b.track_table[4u * i + 1u];
        ts->frames = b.frames + b.track_table[4u * i];
        ts->values = b.values + b.track_table[4u * i + 2u];
        ts->seek = b.seek + (size_t)i * L->seek_len;
        if (ts->kind != KIND_TRANSLATION) ts->ref = mcd_reference_at(d + 2);
        if (ts->kind == KIND_TWIST) mcd_axis_at(d + 20, ts->axis);
        d += desc_size(ts->kind);
    }
    for (i = 0; i < L->nodes; ++i) {
        node_plan* np = &s->plans[i];
        uint32_t rm = L->modes[i] & 3u, tm = (L->modes[i] >> 2) & 3u;
        np->base.rotation[0] = np->base.rotation[1] = np->base.rotation[2] = 0.0f;
        np->base.rotation[3] = 1.0f;
        /* Rest offsets; none for curve sets of codec rma-pca, which have no skeleton. */
        for (k = 0; k < 3; ++k)
            np->base.translation[k] =
                v->skeleton ? mcd_rd_f32(v->skeleton + 16 + (size_t)i * MCD_SKEL_NODE_SIZE + 8 + 4 * k) : 0.0f;
        np->rot_track = -1;
        np->trans_track = -1;
        if (rm == 1u) {
            for (k = 0; k < 4; ++k) np->base.rotation[k] = mcd_rd_f32(L->consts + 4u * (consts + k));
            consts += 4u;
        } else if (rm == 2u) {
            np->rot_track = (int32_t)track++;
        }
        if (tm == 1u) {
            for (k = 0; k < 3; ++k) np->base.translation[k] = mcd_rd_f32(L->consts + 4u * (consts + k));
            consts += 3u;
        } else if (tm == 2u) {
            np->trans_track = (int32_t)track++;
        }
    }
}

/* Make interval `seg` current: its four keys (ends repeated) as a cubic in s. */
static void set_segment(track_state* ts, uint32_t seg) {
    float t[4], v[4][4];
    uint32_t idx[4], j, c, last = ts->count - 1u;
    idx[0] = seg ? seg - 1u : 0u;
    idx[1] = seg;
    idx[2] = seg + 1u;
    idx[3] = seg + 2u <= last ? seg + 2u : last;
    for (j = 0; j < 4; ++j) {
        t[j] = (float)ts->frames[idx[j]];
        for (c = 0; c < ts->dims; ++c) v[j][c] = ts->values[(size_t)idx[j] * ts->dims + c];
    }
    ts->seg = seg;
    ts->t1 = t[1];
    ts->t2 = t[2];
    ts->inv_h = mcd_segment_coefficients(t, (const float(*)[4])v, ts->dims, ts->coef);
    ts->valid = 1;
}

/* Interval holding x: [frames[seg], frames[seg + 1]) or the last one for x at the end. */
static uint32_t find_segment(const track_state* ts, float x) {
    uint32_t seg = ts->seek[(uint32_t)x >> SEEK_SHIFT], last = ts->count - 2u;
    if (seg > last) seg = last;
    while (seg < last && (float)ts->frames[seg + 1u] <= x) ++seg;
    return seg;
}

static int in_segment(const track_state* ts, uint32_t seg, float x) {
    float hi = (float)ts->frames[seg + 1u];
    return x >= (float)ts->frames[seg] && (x < hi || (x == hi && seg + 2u == ts->count));
}

static void track_value(track_state* ts, float x, float out[4]) {
    uint32_t c;
    float s;
    if (ts->count == 1u) { /* a one-frame clip */
        for (c = 0; c < ts->dims; ++c) out[c] = ts->values[c];
        return;
    }
    if (!ts->valid || x < ts->t1 || x > ts->t2 || (x == ts->t2 && ts->seg + 2u < ts->count)) {
        /* Sequential playback moves on by a key or two; anything else seeks. */
        uint32_t seg = ts->seg;
        if (ts->valid && x > ts->t1 && seg + 2u < ts->count && in_segment(ts, seg + 1u, x))
            seg += 1u;
        else if (ts->valid && x > ts->t1 && seg + 3u < ts->count && in_segment(ts, seg + 2u, x))
            seg += 2u;
        else
            seg = find_segment(ts, x);
        set_segment(ts, seg);
    }
    s = (x - ts->t1) * ts->inv_h;
    for (c = 0; c < ts->dims; ++c)
        out[c] = ((ts->coef[c][3] * s + ts->coef[c][2]) * s + ts->coef[c][1]) * s + ts->coef[c][0];
}

static mcd_result rma_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out,
                             void* scratch, int fresh) {
    rma_views s;
    uint32_t i, nodes = mcd_rd_u32(v->payload + 8);
    (void)flags;
    if (!v->resident) return MCD_ERROR_INVALID_ARGUMENT; /* validated but not opened */
    scratch_views(scratch, nodes, &s);
    if (fresh) {
        layout L;
        parse_payload(v->payload, v->payload_size, &L); /* validated at open: cannot fail */
        prepare(&L, v, &s);
    }
    for (i = 0; i < nodes; ++i) {
        const node_plan* np = &s.plans[i];
        out[i] = np->base;
        if (np->rot_track >= 0) {
            track_state* ts = &s.tracks[np->rot_track];
            float val[4];
            track_value(ts, x, val);
            mcd_set_rotation(out[i].rotation, mcd_track_rotation(ts->kind, ts->ref, ts->axis, val));
        }
        if (np->trans_track >= 0) {
            float val[4];
            track_value(&s.tracks[np->trans_track], x, val);
            out[i].translation[0] = val[0];
            out[i].translation[1] = val[1];
            out[i].translation[2] = val[2];
        }
    }
    return MCD_OK;
}

const mcd_codec_ops mcd_codec_rma_ops = {
    MCD_CODEC_RMA, 0x4C414D52u /* "RMAL" */, rma_validate, rma_resident_size, rma_open_section,
    rma_scratch_size, rma_sample};
