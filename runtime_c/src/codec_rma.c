/* Codec `rma`: per-track Catmull-Rom keys placed freely in time, sampled in place from the
 * asset's bytes (docs/FORMAT.md, RMAL version 2).
 *
 * A track's keys come in groups of G. A fixed-size group entry gives the bit offset of the
 * group's data, its first key's frame, the widths of its fields and, per component, the
 * group's smallest value; the data holds the gaps between the group's keys, then each key's
 * value relative to the group's smallest at the group's widths (so any key's value is one read),
 * then the gaps too wide for their field, whole. A seek table names the group of every 2^s-th
 * frame. A random access finds the group by the seek table and a step or two, sums at most G
 * small gap fields and reads the four keys it needs; sequential playback keeps each track's
 * four keys and a cursor in the scratch and reads one gap and one value per key interval. */
#include <string.h>

#include "internal.h"

#define SECTION_HEADER 16u
#define PAYLOAD_HEADER 32u
#define MAX_GROUP_SHIFT 6u
#define MAX_SEEK_SHIFT 24u
#define GAP_WIDTH_BITS 4u   /* a gap field's width, 0 ... 15 */
#define VALUE_WIDTH_BITS 5u /* a value field's width, 0 ... 30 */
#define MAX_VALUE_WIDTH 30u

enum { KIND_MRP = 1, KIND_TWIST = 2, KIND_TRANSLATION = 3, KIND_SCALE = 4 };
enum { MODE_REST = 0, MODE_CONSTANT = 1, MODE_ANIMATED = 2 };

static uint32_t desc_size(uint32_t kind) {
    return kind == KIND_MRP ? 28u : kind == KIND_TWIST ? 40u : (kind == KIND_TRANSLATION || kind == KIND_SCALE) ? 20u : 0u;
}

static uint32_t kind_dims(uint32_t kind) {
    return kind == KIND_TWIST ? 4u : 3u;
}

/* Bits that hold every value 0 ... n (at least 1). */
static uint32_t bits_for(uint32_t n) {
    uint32_t b = 1;
    while (b < 32u && (n >> b)) ++b;
    return b;
}

/* ---------------------------------------------------------------- payload layout */
typedef struct header {
    uint32_t size, frames, nodes, tracks, constants;
    const uint8_t *modes, *consts, *descs;
} header;

/* Everything about one track that its descriptor and the clip's frame count give. Offsets
 * are bytes from the start of the payload. */
typedef struct track_layout {
    uint8_t kind, dims, split, offset_bits, seek_shift, group_shift, frame_bits;
    uint8_t group_bits, abits[4];
    uint32_t keys, groups, seeks, entry_bits, data_bytes;
    float step[4];
    uint32_t seek, table, data, end;
} track_layout;

static mcd_result parse_header(const uint8_t* p, size_t avail, header* H) {
    uint32_t i;
    if (avail < PAYLOAD_HEADER) return MCD_ERROR_MALFORMED;
    H->size = mcd_rd_u32(p);
    H->frames = mcd_rd_u32(p + 4);
    H->nodes = mcd_rd_u32(p + 8);
    H->tracks = mcd_rd_u32(p + 12);
    H->constants = mcd_rd_u32(p + 16);
    if (H->size < PAYLOAD_HEADER || H->size > avail || (H->size & 3u)) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u32(p + 20) || mcd_rd_u32(p + 24) || mcd_rd_u32(p + 28)) return MCD_ERROR_MALFORMED;
    if (H->frames == 0 || H->nodes == 0 || H->nodes > MCD_MAX_NODES) return MCD_ERROR_MALFORMED;
    if (H->tracks > 3u * H->nodes || H->constants > 10u * H->nodes) return MCD_ERROR_MALFORMED;
    if ((uint64_t)PAYLOAD_HEADER + mcd_align4(H->nodes) + 4u * (uint64_t)H->constants > H->size) return MCD_ERROR_MALFORMED;
    H->modes = p + PAYLOAD_HEADER;
    H->consts = H->modes + mcd_align4(H->nodes);
    H->descs = H->consts + 4u * (size_t)H->constants;
    for (i = H->nodes; i < mcd_align4(H->nodes); ++i)
        if (H->modes[i]) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* The layout of a track whose descriptor is at `d` and whose data starts at byte `at`;
 * checks what the descriptor alone shows and that the parts fit before `limit`. */
static mcd_result track_geometry(const uint8_t* d, uint32_t frames, uint32_t at, uint32_t limit, track_layout* t) {
    uint32_t c;
    uint64_t end, entry;
    t->kind = d[0];
    if (!desc_size(t->kind)) return MCD_ERROR_MALFORMED;
    t->dims = (uint8_t)kind_dims(t->kind);
    /* Byte 1: the first segment detached (bit 0); groups of 2^(bits 1-3) keys. */
    t->split = d[1] & 1u;
    t->group_shift = (d[1] >> 1) & 7u;
    t->offset_bits = d[2];
    t->seek_shift = d[3];
    t->keys = mcd_rd_u32(d + 4);
    t->data_bytes = mcd_rd_u32(d + 8);
    if ((d[1] >> 4) || t->group_shift < 1 || t->group_shift > MAX_GROUP_SHIFT) return MCD_ERROR_MALFORMED;
    if (t->offset_bits < 1 || t->offset_bits > 32) return MCD_ERROR_MALFORMED;
    if (t->seek_shift > MAX_SEEK_SHIFT) return MCD_ERROR_MALFORMED;
    if (t->keys < 1 || t->keys > frames || (frames > 1u && t->keys < 2u)) return MCD_ERROR_MALFORMED;
    if (t->data_bytes & 3u) return MCD_ERROR_MALFORMED;
    t->step[0] = t->step[1] = t->step[2] = t->step[3] = mcd_rd_f32(d + 12);
    if (t->kind == KIND_TWIST) t->step[0] = mcd_rd_f32(d + 36);
    t->frame_bits = (uint8_t)bits_for(frames - 1u);
    t->groups = ((t->keys - 1u) >> t->group_shift) + 1u;
    t->group_bits = (uint8_t)bits_for(t->groups - 1u);
    t->seeks = ((frames - 1u) >> t->seek_shift) + 1u;
    entry = t->offset_bits + (uint64_t)t->frame_bits + GAP_WIDTH_BITS + VALUE_WIDTH_BITS * (uint64_t)t->dims;
    for (c = 0; c < 4; ++c) {
        t->abits[c] = d[16 + c];
        if (c < t->dims) {
            if (t->abits[c] < 1 || t->abits[c] > 31) return MCD_ERROR_MALFORMED;
            if (!mcd_in_bounds(t->step[c]) || t->step[c] < 0.0f) return MCD_ERROR_MALFORMED;
            entry += t->abits[c];
        } else if (t->abits[c]) {
            return MCD_ERROR_MALFORMED;
        }
    }
    t->entry_bits = (uint32_t)entry;
    t->seek = at;
    end = at + 4u * (((uint64_t)t->seeks * t->group_bits + 31u) / 32u);
    if (end > limit) return MCD_ERROR_MALFORMED;
    t->table = (uint32_t)end;
    end += 4u * (((uint64_t)t->groups * t->entry_bits + 31u) / 32u);
    if (end > limit) return MCD_ERROR_MALFORMED;
    t->data = (uint32_t)end;
    end += t->data_bytes;
    if (end > limit) return MCD_ERROR_MALFORMED;
    t->end = (uint32_t)end;
    return MCD_OK;
}

/* ---------------------------------------------------------------- key decoding */
/* One group's entry, unpacked as far as needed: the head (where its gaps lie, its first key's
 * frame, the gap width) always, the value widths and bases once a value is read. */
typedef struct group {
    uint32_t index, first, count; /* group number, index of its first key, keys in it */
    uint32_t frame;               /* its first key's frame */
    uint32_t gaps;                /* bit position (in the data area) of its gap fields */
    uint32_t values, outliers;    /* ... of its value records and outlier frames (loaded) */
    uint32_t value_bits;          /* bits of one key's values (loaded) */
    uint8_t gap_width, loaded, width[4];
    uint8_t pad[2];
    int32_t base[4];              /* per component, the group's smallest value (loaded) */
} group;

static void group_head(const uint8_t* p, const track_layout* t, uint32_t g, group* G) {
    const uint8_t* table = p + t->table;
    uint64_t bit = (uint64_t)g * t->entry_bits;
    uint32_t size = 1u << t->group_shift;
    G->index = g;
    G->first = g << t->group_shift;
    G->count = t->keys - G->first < size ? t->keys - G->first : size;
    G->gaps = mcd_read_bits(table, bit, t->offset_bits);
    G->frame = mcd_read_bits(table, bit + t->offset_bits, t->frame_bits);
    G->gap_width = (uint8_t)mcd_read_bits(table, bit + t->offset_bits + t->frame_bits, GAP_WIDTH_BITS);
    G->loaded = 0;
}

/* The rest of the entry: value widths and bases, and where the values and outliers lie. */
static void group_load(const uint8_t* p, const track_layout* t, group* G) {
    const uint8_t* table = p + t->table;
    uint64_t bit = (uint64_t)G->index * t->entry_bits + t->offset_bits + t->frame_bits + GAP_WIDTH_BITS;
    uint32_t c;
    if (G->loaded) return;
    G->value_bits = 0;
    for (c = 0; c < t->dims; ++c) {
        G->width[c] = (uint8_t)mcd_read_bits(table, bit + VALUE_WIDTH_BITS * c, VALUE_WIDTH_BITS);
        G->value_bits += G->width[c];
    }
    bit += VALUE_WIDTH_BITS * t->dims;
    for (c = 0; c < t->dims; ++c) {
        G->base[c] = mcd_read_signed(table, bit, t->abits[c]);
        bit += t->abits[c];
    }
    G->values = G->gaps + (G->count - 1u) * G->gap_width;
    G->outliers = G->values + G->count * G->value_bits;
    G->loaded = 1;
}

/* Key `pos` of a group: its lattice integers (q = base + the field). */
static void group_value(const uint8_t* p, const track_layout* t, group* G, uint32_t pos, int32_t q[4]) {
    const uint8_t* data = p + t->data;
    uint32_t c, bit;
    group_load(p, t, G);
    bit = G->values + pos * G->value_bits;
    if (G->value_bits <= 57u) {
        uint64_t w = mcd_rd_u64(data + (bit >> 3)) >> (bit & 7u);
        for (c = 0; c < t->dims; ++c) {
            q[c] = (int32_t)((int64_t)G->base[c] + (int64_t)(w & (((uint64_t)1 << G->width[c]) - 1u)));
            w >>= G->width[c];
        }
    } else {
        for (c = 0; c < t->dims; ++c) {
            q[c] = (int32_t)((int64_t)G->base[c] + (int64_t)mcd_read_bits(data, bit, G->width[c]));
            bit += G->width[c];
        }
    }
}

/* The first key's frame of group g. */
static uint32_t group_frame(const uint8_t* p, const track_layout* t, uint32_t g) {
    return mcd_read_bits(p + t->table, (uint64_t)g * t->entry_bits + t->offset_bits, t->frame_bits);
}

/* The group holding the last key at or before frame xi: the seek table's group, then the
 * next ones while they start no later than xi. */
static uint32_t find_group(const uint8_t* p, const track_layout* t, uint32_t xi) {
    uint32_t g = mcd_read_bits(p + t->seek, (uint64_t)(xi >> t->seek_shift) * t->group_bits, t->group_bits);
    while (g + 1u < t->groups && group_frame(p, t, g + 1u) <= xi) ++g;
    return g;
}

/* ---------------------------------------------------------------- sampling state */
/* Reads a track's keys in order: the group of the last key read, its position, its frame, and
 * where the next gap and (once one escaped) the next outlier frame lie. */
#define NO_OUTLIER UINT32_MAX
typedef struct cursor {
    group G;
    uint32_t pos, frame, gap_bit, exc_bit;
} cursor;

/* The frame after `frame` for gap field `gap` (escaped: the group's next outlier frame). */
static inline uint32_t next_frame(const uint8_t* p, const track_layout* t, cursor* cur, uint32_t gap, int advance) {
    uint32_t w = cur->G.gap_width, f;
    if (!w || gap != ((uint32_t)1 << w) - 1u) return cur->frame + gap + 1u;
    if (cur->exc_bit == NO_OUTLIER) {
        group_load(p, t, &cur->G);
        cur->exc_bit = cur->G.outliers;
    }
    f = mcd_read_bits(p + t->data, cur->exc_bit, t->frame_bits);
    if (advance) cur->exc_bit += t->frame_bits;
    return f;
}

/* The cursor at key `pos` of group g (its gaps summed from the group's first key). */
static void cursor_seek(const uint8_t* p, const track_layout* t, uint32_t g, uint32_t pos, cursor* cur) {
    const uint8_t* data = p + t->data;
    uint32_t j, w;
    group_head(p, t, g, &cur->G);
    w = cur->G.gap_width;
    cur->frame = cur->G.frame;
    cur->gap_bit = cur->G.gaps;
    cur->exc_bit = NO_OUTLIER;
    for (j = 0; j < pos; ++j) {
        cur->frame = next_frame(p, t, cur, mcd_read_bits(data, cur->gap_bit, w), 1);
        cur->gap_bit += w;
    }
    cur->pos = pos;
}

/* Move the cursor to the next key (which exists). */
static void cursor_next(const uint8_t* p, const track_layout* t, cursor* cur) {
    uint32_t w = cur->G.gap_width;
    if (cur->pos + 1u == cur->G.count) {
        cursor_seek(p, t, cur->G.index + 1u, 0, cur);
        return;
    }
    cur->frame = next_frame(p, t, cur, mcd_read_bits(p + t->data, cur->gap_bit, w), 1);
    cur->gap_bit += w;
    cur->pos++;
}

/* A track in the scratch: its layout, what its descriptor stores, the four keys around the
 * last sample (i - 1 ... i + 2, ends repeated) with their curve, and a cursor at key i + 2. */
typedef struct track_state {
    track_layout L;
    mcd_quat ref;
    float axis[4];
    uint32_t valid;
    uint32_t i;    /* the segment [key i, key i + 1] the curve below belongs to */
    float t[4];    /* frames of keys i - 1 ... i + 2 */
    float v[4][4]; /* their values */
    float t1, t2, inv_h;
    float coef[4][4];
    cursor cur;    /* at key min(i + 2, last) */
} track_state;

typedef struct node_plan {
    mcd_transform base; /* rest pose and constants resolved once per clip */
    int16_t track[3];   /* rotation, translation, scale track, or -1 */
    uint16_t pad;
} node_plan;

/* The scratch sizes are part of the format (docs/FORMAT.md, RMAL "Sampling"): changing these
 * structures is a new section version. Plain 32-bit fields only, so every ABI agrees. */
typedef char node_plan_is_48_bytes[sizeof(node_plan) == 48u ? 1 : -1];
typedef char track_state_is_332_bytes[sizeof(track_state) == 332u ? 1 : -1];

static size_t rma_scratch_size(const mcd_clip_view* v) {
    uint32_t nodes = mcd_rd_u32(v->payload + 8), tracks = mcd_rd_u32(v->payload + 12);
    return mcd_align16(sizeof(node_plan) * nodes) + mcd_align16(sizeof(track_state) * tracks);
}

static void scratch_views(void* scratch, uint32_t nodes, node_plan** plans, track_state** tracks) {
    *plans = (node_plan*)scratch;
    *tracks = (track_state*)((uint8_t*)scratch + mcd_align16(sizeof(node_plan) * nodes));
}

/* Window slot `slot` from key `pos` of group G at `frame`. */
static void store_key(const uint8_t* p, track_state* ts, uint32_t slot, group* G, uint32_t pos, uint32_t frame) {
    int32_t q[4];
    uint32_t c;
    group_value(p, &ts->L, G, pos, q);
    ts->t[slot] = (float)frame;
    /* Binary64 first: q may exceed 2^24 on long clips, where binary32 would round it. */
    for (c = 0; c < ts->L.dims; ++c) ts->v[slot][c] = (float)((double)q[c] * (double)ts->L.step[c]);
}

static void set_curve(track_state* ts) {
    float t[4], v[4][4];
    memcpy(t, ts->t, sizeof t);
    memcpy(v, ts->v, sizeof v);
    /* A detached first segment (capture that jumps after frame 0): key 0 and key 1 are each
     * an end of their curves, so the first segment is the straight line between them and key
     * 0 takes no part in key 1's tangent. */
    if (ts->L.split && ts->i <= 1u) {
        memcpy(v[0], v[1], sizeof v[0]);
        t[0] = t[1];
        if (ts->i == 0) {
            memcpy(v[3], v[2], sizeof v[3]);
            t[3] = t[2];
        }
    }
    ts->t1 = t[1];
    ts->t2 = t[2];
    ts->inv_h = mcd_segment_coefficients(t, (const float(*)[4])v, ts->L.dims, ts->coef);
    ts->valid = 1;
}

/* Move the cursor forward within its group to the last key at or before frame xi (the group
 * holds it: the next group starts after xi). `before`: the frame of the key before. */
static void walk_to(const uint8_t* p, const track_layout* t, cursor* cur, uint32_t xi, uint32_t* before) {
    const uint8_t* data = p + t->data;
    uint32_t w = cur->G.gap_width, n = cur->G.count, escape = ((uint32_t)1 << w) - 1u;
    uint32_t pos = cur->pos, frame = cur->frame, bit = cur->gap_bit, prev = frame;
    if (w == 0) { /* every gap 0: keys on consecutive frames */
        uint32_t step = xi - frame < n - 1u - pos ? xi - frame : n - 1u - pos;
        if (step) prev = frame + step - 1u;
        cur->pos = pos + step;
        cur->frame = frame + step;
        *before = prev;
        return;
    }
    while (pos + 1u < n) {
        uint32_t gap = mcd_read_bits(data, bit, w), next;
        if (gap == escape) {
            cur->frame = frame;
            next = next_frame(p, t, cur, gap, 0);
            if (next > xi) break;
            cur->exc_bit += t->frame_bits;
        } else {
            next = frame + gap + 1u;
            if (next > xi) break;
        }
        bit += w;
        prev = frame;
        frame = next;
        ++pos;
    }
    cur->pos = pos;
    cur->frame = frame;
    cur->gap_bit = bit;
    *before = prev;
}

/* Random access: the segment holding frame position x, its four keys read afresh. */
static void locate(const uint8_t* p, track_state* ts, float x) {
    const track_layout* t = &ts->L;
    uint32_t last = t->keys - 1u, xi = (uint32_t)x, i, before;
    cursor* cur = &ts->cur;
    /* Walk the gaps from the first key of x's group to i, the last key at or before x (the
     * key before the last at the clip's end); values are read only for the four keys. */
    cursor_seek(p, t, find_group(p, t, xi), 0, cur);
    walk_to(p, t, cur, xi, &before);
    i = cur->G.first + cur->pos;
    if (i >= last) { /* x at the last frame: the segment before it, keys read afresh (rare) */
        uint32_t slot;
        i = last - 1u;
        for (slot = 0; slot < 3u; ++slot) {
            uint32_t key = i + slot < 1u ? 0u : i + slot - 1u;
            cursor_seek(p, t, key >> t->group_shift, key & ((1u << t->group_shift) - 1u), cur);
            store_key(p, ts, slot, &cur->G, cur->pos, cur->frame);
        }
        memcpy(ts->v[3], ts->v[2], sizeof ts->v[3]);
        ts->t[3] = ts->t[2];
        ts->i = i;
        set_curve(ts);
        return;
    }
    store_key(p, ts, 1, &cur->G, cur->pos, cur->frame);
    /* Slot 0: key i - 1: the walk passed it within the group, or it ends the group before. */
    if (i == 0) {
        memcpy(ts->v[0], ts->v[1], sizeof ts->v[0]);
        ts->t[0] = ts->t[1];
    } else if (cur->pos > 0) {
        store_key(p, ts, 0, &cur->G, cur->pos - 1u, before);
    } else {
        cursor prev;
        cursor_seek(p, t, cur->G.index - 1u, (1u << t->group_shift) - 1u, &prev);
        store_key(p, ts, 0, &prev.G, prev.pos, prev.frame);
    }
    /* Slots 2 and 3: keys i + 1 and i + 2, the last key repeated past the end. */
    cursor_next(p, t, cur);
    store_key(p, ts, 2, &cur->G, cur->pos, cur->frame);
    if (i + 2u <= last) {
        cursor_next(p, t, cur);
        store_key(p, ts, 3, &cur->G, cur->pos, cur->frame);
    } else {
        memcpy(ts->v[3], ts->v[2], sizeof ts->v[3]);
        ts->t[3] = ts->t[2];
    }
    ts->i = i;
    set_curve(ts);
}

/* The curve of one track at x: the cached segment, the next one in sequential playback, or a
 * fresh locate. */
static void track_value(const uint8_t* p, track_state* ts, float x, float out[4]) {
    uint32_t c, last = ts->L.keys - 1u;
    float s;
    if (last == 0) { /* a one-frame clip */
        for (c = 0; c < ts->L.dims; ++c) out[c] = ts->v[0][c];
        return;
    }
    if (!ts->valid || x < ts->t1) {
        locate(p, ts, x);
    } else if (x >= ts->t2 && !(x == ts->t2 && ts->i + 1u == last)) {
        /* Sequential playback moves on by a key; anything further is a random access. */
        if (ts->i + 2u <= last && x < ts->t[3]) {
            memmove(ts->v[0], ts->v[1], sizeof ts->v[0] * 3u);
            memmove(ts->t, ts->t + 1, sizeof ts->t[0] * 3u);
            ts->i++;
            if (ts->i + 2u <= last) {
                cursor_next(p, &ts->L, &ts->cur);
                store_key(p, ts, 3, &ts->cur.G, ts->cur.pos, ts->cur.frame);
            } else {
                memcpy(ts->v[3], ts->v[2], sizeof ts->v[3]);
                ts->t[3] = ts->t[2];
            }
            set_curve(ts);
        } else {
            locate(p, ts, x);
        }
    }
    s = (x - ts->t1) * ts->inv_h;
    for (c = 0; c < ts->L.dims; ++c)
        out[c] = ((ts->coef[c][3] * s + ts->coef[c][2]) * s + ts->coef[c][1]) * s + ts->coef[c][0];
}

/* Per clip: each track's layout and constants, each node's base transform and tracks. */
static void prepare(const mcd_clip_view* v, node_plan* plans, track_state* tracks) {
    const uint8_t* p = v->payload;
    header H;
    const uint8_t* d;
    uint32_t i, k, m, track = 0, consts = 0, at, off;
    parse_header(p, v->payload_size, &H); /* validated: cannot fail */
    d = H.descs;
    for (i = 0, off = 0; i < H.tracks; ++i) off += desc_size(H.descs[off]);
    at = (uint32_t)mcd_align4((size_t)(H.descs - p) + off);
    for (i = 0; i < H.tracks; ++i) {
        track_state* ts = &tracks[i];
        memset(ts, 0, sizeof *ts);
        track_geometry(d, H.frames, at, H.size, &ts->L);
        if (ts->L.kind == KIND_MRP || ts->L.kind == KIND_TWIST) ts->ref = mcd_reference_at(d + 20);
        if (ts->L.kind == KIND_TWIST) mcd_axis_at(d + 28, ts->axis);
        if (ts->L.keys == 1u) { /* one frame: the single key is group 0's first */
            cursor_seek(p, &ts->L, 0, 0, &ts->cur);
            store_key(p, ts, 0, &ts->cur.G, 0, 0);
        }
        at = ts->L.end;
        d += desc_size(ts->L.kind);
    }
    for (i = 0; i < H.nodes; ++i) {
        node_plan* np = &plans[i];
        uint32_t mode = H.modes[i];
        if (v->skeleton)
            mcd_skel_rest(v->skeleton, i, &np->base);
        else
            mcd_transform_identity(&np->base); /* curve sets of codec rma-pca have no skeleton */
        for (m = 0; m < 3; ++m) {
            uint32_t mm = (mode >> (2u * m)) & 3u, n = m == 0 ? 4u : 3u;
            float* field = m == 0 ? np->base.rotation : m == 1 ? np->base.translation : np->base.scale;
            np->track[m] = -1;
            if (mm == MODE_CONSTANT) {
                for (k = 0; k < n; ++k) field[k] = mcd_rd_f32(H.consts + 4u * (consts + k));
                consts += n;
            } else if (mm == MODE_ANIMATED) {
                np->track[m] = (int16_t)track++;
            }
        }
    }
}

static void rma_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                       int fresh) {
    node_plan* plans;
    track_state* tracks;
    uint32_t i, nodes = mcd_rd_u32(v->payload + 8);
    (void)flags;
    scratch_views(scratch, nodes, &plans, &tracks);
    if (fresh) prepare(v, plans, tracks);
    for (i = 0; i < nodes; ++i) {
        const node_plan* np = &plans[i];
        float val[4];
        out[i] = np->base;
        if (np->track[0] >= 0) {
            track_state* ts = &tracks[np->track[0]];
            track_value(v->payload, ts, x, val);
            mcd_set_rotation(out[i].rotation, mcd_track_rotation(ts->L.kind, ts->ref, ts->axis, val));
        }
        if (np->track[1] >= 0) {
            track_value(v->payload, &tracks[np->track[1]], x, val);
            memcpy(out[i].translation, val, sizeof out[i].translation);
        }
        if (np->track[2] >= 0) {
            track_value(v->payload, &tracks[np->track[2]], x, val);
            memcpy(out[i].scale, val, sizeof out[i].scale);
        }
    }
}

/* ---------------------------------------------------------------- validation */
/* Every rule of one track's seek table, group table and data, reading every key. */
static mcd_result check_track(const uint8_t* p, const track_layout* t, uint32_t frames) {
    uint64_t data_bits = 8u * (uint64_t)t->data_bytes, bit = 0, b;
    uint32_t g, c, j, last_frame = 0;
    /* Padding after the seek entries and the group entries is zero. */
    for (b = (uint64_t)t->seeks * t->group_bits; b < 32u * (((uint64_t)t->seeks * t->group_bits + 31u) / 32u); ++b)
        if (mcd_read_bits(p + t->seek, b, 1)) return MCD_ERROR_MALFORMED;
    for (b = (uint64_t)t->groups * t->entry_bits; b < 32u * (((uint64_t)t->groups * t->entry_bits + 31u) / 32u); ++b)
        if (mcd_read_bits(p + t->table, b, 1)) return MCD_ERROR_MALFORMED;
    for (g = 0; g < t->groups; ++g) {
        group G;
        uint32_t escapes = 0, frame, w;
        group_head(p, t, g, &G);
        group_load(p, t, &G);
        /* Groups lie back to back from the start of the data area, each within it. */
        if (G.gaps != bit) return MCD_ERROR_MALFORMED;
        for (c = 0; c < t->dims; ++c)
            if (G.width[c] > MAX_VALUE_WIDTH) return MCD_ERROR_MALFORMED;
        if ((uint64_t)G.outliers > data_bits) return MCD_ERROR_MALFORMED;
        w = G.gap_width;
        for (j = 1; j < G.count; ++j)
            if (w && mcd_read_bits(p + t->data, G.gaps + (j - 1u) * w, w) == ((uint32_t)1 << w) - 1u) ++escapes;
        if ((uint64_t)G.outliers + (uint64_t)escapes * t->frame_bits > data_bits) return MCD_ERROR_MALFORMED;
        /* Frames increase from 0 to the last frame, the last key's; values within bounds. */
        for (j = 0; j < G.count; ++j) {
            cursor cur;
            int32_t q[4];
            cursor_seek(p, t, g, j, &cur);
            frame = cur.frame;
            if (g == 0 && j == 0 ? frame != 0 : (frame <= last_frame || frame > frames - 1u)) return MCD_ERROR_MALFORMED;
            last_frame = frame;
            group_value(p, t, &G, j, q);
            for (c = 0; c < t->dims; ++c) {
                if ((int64_t)G.base[c] + ((int64_t)1 << G.width[c]) - 1 >= ((int64_t)1 << 30) || G.base[c] <= -(1 << 30))
                    return MCD_ERROR_MALFORMED;
                if (!mcd_in_bounds((float)((double)q[c] * (double)t->step[c]))) return MCD_ERROR_MALFORMED;
            }
        }
        bit = (uint64_t)G.outliers + (uint64_t)escapes * t->frame_bits;
    }
    if (last_frame != frames - 1u) return MCD_ERROR_MALFORMED;
    /* The data area ends after the last group, zero-padded to a multiple of 4 bytes. */
    if (t->data_bytes != mcd_align4((size_t)((bit + 7u) / 8u))) return MCD_ERROR_MALFORMED;
    for (; bit < data_bits; ++bit)
        if (mcd_read_bits(p + t->data, bit, 1)) return MCD_ERROR_MALFORMED;
    /* The seek table names, for every 2^s-th frame, the last group starting at or before it. */
    for (j = 0, g = 0; j < t->seeks; ++j) {
        uint32_t f = j << t->seek_shift;
        while (g + 1u < t->groups && group_frame(p, t, g + 1u) <= f) ++g;
        if (mcd_read_bits(p + t->seek, (uint64_t)j * t->group_bits, t->group_bits) != g) return MCD_ERROR_MALFORMED;
    }
    return MCD_OK;
}

static mcd_result rma_validate(const mcd_clip_view* v) {
    const uint8_t* p = v->payload;
    header H;
    mcd_result r;
    uint32_t i, m, k, off = 0, consts = 0, track = 0, at;
    static const uint8_t kinds[3][2] = {{KIND_MRP, KIND_TWIST}, {KIND_TRANSLATION, 0}, {KIND_SCALE, 0}};
    if ((size_t)(v->payload - v->section) < SECTION_HEADER) return MCD_ERROR_MALFORMED;
    r = parse_header(p, v->payload_size, &H);
    if (r != MCD_OK) return r;
    if (H.size != v->payload_size || H.frames != v->frame_count || H.nodes != v->node_count) return MCD_ERROR_MALFORMED;
    for (i = 0; i < H.constants; ++i)
        if (!mcd_in_bounds(mcd_rd_f32(H.consts + 4u * i))) return MCD_ERROR_MALFORMED;
    /* Node modes: constants and tracks taken in node order, rotation, translation, scale. */
    for (i = 0; i < H.nodes; ++i) {
        uint32_t mode = H.modes[i];
        if (mode >> 6) return MCD_ERROR_MALFORMED;
        for (m = 0; m < 3; ++m) {
            uint32_t mm = (mode >> (2u * m)) & 3u, n = m == 0 ? 4u : 3u, kind;
            if (mm == 3u) return MCD_ERROR_MALFORMED;
            if (mm == MODE_CONSTANT) {
                if (consts + n > H.constants) return MCD_ERROR_MALFORMED;
                if (m == 0 && !mcd_unit_quat_at(H.consts + 4u * consts)) return MCD_ERROR_MALFORMED;
                consts += n;
            } else if (mm == MODE_ANIMATED) {
                if (track >= H.tracks || (size_t)(H.descs - p) + off + 4u > H.size) return MCD_ERROR_MALFORMED;
                kind = H.descs[off];
                if (kind == 0 || (kind != kinds[m][0] && kind != kinds[m][1])) return MCD_ERROR_MALFORMED;
                if ((size_t)(H.descs - p) + off + desc_size(kind) > H.size) return MCD_ERROR_MALFORMED;
                if ((kind == KIND_MRP || kind == KIND_TWIST) && mcd_rd_u16(H.descs + off + 26)) return MCD_ERROR_MALFORMED;
                if (kind == KIND_TWIST) {
                    const uint8_t* a = H.descs + off + 28;
                    float ax = (float)(int16_t)mcd_rd_u16(a), ay = (float)(int16_t)mcd_rd_u16(a + 2);
                    float az = (float)(int16_t)mcd_rd_u16(a + 4);
                    if (mcd_rd_u16(a + 6)) return MCD_ERROR_MALFORMED;
                    if (ax * ax + ay * ay + az * az < 0.25f * 32767.0f * 32767.0f) return MCD_ERROR_MALFORMED;
                }
                off += desc_size(kind);
                track++;
            }
        }
    }
    if (track != H.tracks || consts != H.constants) return MCD_ERROR_MALFORMED;
    /* Track data back to back after the descriptors, then at least 8 zero bytes (the bit
     * reader's 64-bit loads), zero padding to the payload size. */
    at = (uint32_t)mcd_align4((size_t)(H.descs - p) + off);
    if (at > H.size) return MCD_ERROR_MALFORMED;
    for (k = (uint32_t)((size_t)(H.descs - p) + off); k < at; ++k)
        if (p[k]) return MCD_ERROR_MALFORMED;
    for (i = 0, off = 0; i < H.tracks; ++i) {
        track_layout t;
        r = track_geometry(H.descs + off, H.frames, at, H.size, &t);
        if (r != MCD_OK) return r;
        if (t.end + 8u > H.size) return MCD_ERROR_MALFORMED;
        r = check_track(p, &t, H.frames);
        if (r != MCD_OK) return r;
        at = t.end;
        off += desc_size(t.kind);
    }
    if ((size_t)H.size != mcd_align4((size_t)at + 8u)) return MCD_ERROR_MALFORMED;
    for (k = at; k < H.size; ++k)
        if (p[k]) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* The section: a 16-byte header, then the payloads back to back, each one a clip's. */
static mcd_result rma_validate_section(const uint8_t* s, uint32_t size) {
    uint32_t count, i;
    size_t pos = SECTION_HEADER;
    if (size < SECTION_HEADER) return MCD_ERROR_MALFORMED;
    count = mcd_rd_u32(s);
    if (count == 0 || mcd_rd_u32(s + 4) || mcd_rd_u32(s + 8) || mcd_rd_u32(s + 12)) return MCD_ERROR_MALFORMED;
    for (i = 0; i < count; ++i) {
        uint32_t n;
        if (size - pos < PAYLOAD_HEADER) return MCD_ERROR_MALFORMED;
        n = mcd_rd_u32(s + pos);
        if (n < PAYLOAD_HEADER || (n & 3u) || n > size - pos) return MCD_ERROR_MALFORMED;
        pos += n;
    }
    return pos == size ? MCD_OK : MCD_ERROR_MALFORMED;
}

const mcd_codec_ops mcd_codec_rma_ops = {
    MCD_CODEC_RMA, 0x4C414D52u /* "RMAL" */, 2u, rma_validate_section, rma_validate, rma_scratch_size, rma_sample};
