/* Codec `rma`: per-track Catmull-Rom keys placed freely in time, sampled in place from the
 * asset's bytes (docs/FORMAT.md, RMAL version 2).
 *
 * A track's keys come in groups of G. A fixed-size group entry gives the bit offset of the
 * group's records, its first key whole (frame and value) and the widths of the records'
 * fields; each further key is one record: its gap to the key before and, per component, its
 * residual from a prediction, at the group's widths, outliers stored whole after the records.
 * A seek table names the group of every 2^s-th frame. A random access finds the group by the
 * seek table and a step or two and decodes at most a group's records (and, when x lies just
 * after a group's first key, the group before); sequential playback keeps each track's four
 * keys and a decoding cursor in the scratch and decodes one record per key interval. */
#include <string.h>

#include "internal.h"

#define SECTION_HEADER 16u
#define PAYLOAD_HEADER 32u
#define MAX_GROUP_SHIFT 6u
#define MAX_SEEK_SHIFT 24u
#define WIDTH_BITS 4u /* a record field's width, 0 ... 15 */
#define MAX_Q 0x40000000LL /* |q| < 2^30: exact in binary64, products below 2^62 */

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
    uint8_t kind, dims, split, predictor, offset_bits, seek_shift, group_shift, frame_bits;
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
    /* Byte 1: the first segment detached (bit 0), the predictor (bits 1-2), groups of
     * 2^(bits 3-5) keys. */
    t->split = d[1] & 1u;
    t->predictor = (d[1] >> 1) & 3u;
    t->group_shift = (d[1] >> 3) & 7u;
    t->offset_bits = d[2];
    t->seek_shift = d[3];
    t->keys = mcd_rd_u32(d + 4);
    t->data_bytes = mcd_rd_u32(d + 8);
    if ((d[1] >> 6) || t->predictor > 2 || t->group_shift < 1 || t->group_shift > MAX_GROUP_SHIFT) return MCD_ERROR_MALFORMED;
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
    entry = t->offset_bits + (uint64_t)t->frame_bits + WIDTH_BITS * (1u + (uint64_t)t->dims);
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
/* Decodes a track's keys in index order from a group's first key on: the current group's
 * record layout, and the last two decoded keys. */
typedef struct cursor {
    uint32_t group, key;  /* the group, and index of the key the next call decodes */
    uint32_t left;        /* records left in the group */
    uint32_t bit, exc;    /* bit positions (in the data area) of the next record and outlier */
    uint32_t frame;       /* frame of the last decoded key */
    uint32_t keybits;     /* bits of one record */
    uint8_t shift[5];     /* each field's position in a record: gap, then four components */
    uint8_t width[5];     /* (a component past the track's is a field of width 0) */
    uint8_t pad[2];
    uint32_t mask[5];     /* its mask, the code that escapes (a width-0 field never does), */
    uint32_t escape[5];
    uint32_t sign[5];     /* and its sign bit (0 for width 0), for the two's complement */
    int32_t q[4], q2[4];  /* the last two decoded values, for the prediction */
} cursor;

/* floor(v / 2) for any sign (C's division truncates; a right shift of a negative number is
 * implementation-defined): the logical shift with the sign bit put back. */
static int64_t floor_half(int64_t v) {
    uint64_t u = (uint64_t)v >> 1;
    return (int64_t)(v < 0 ? u | ((uint64_t)1 << 63) : u);
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

/* Enter group g: its entry gives the record layout and the first key (value into q). */
static void group_open(const uint8_t* p, const track_layout* t, uint32_t g, cursor* cur, int32_t q[4]) {
    const uint8_t* table = p + t->table;
    uint64_t bit = (uint64_t)g * t->entry_bits;
    uint32_t c, n, first = g << t->group_shift, at = 0;
    cur->group = g;
    cur->bit = mcd_read_bits(table, bit, t->offset_bits);
    bit += t->offset_bits;
    cur->frame = mcd_read_bits(table, bit, t->frame_bits);
    bit += t->frame_bits;
    for (c = 0; c <= 4u; ++c) {
        uint32_t w = c <= t->dims ? mcd_read_bits(table, bit, WIDTH_BITS) : 0u;
        if (c <= t->dims) bit += WIDTH_BITS;
        cur->shift[c] = (uint8_t)at;
        cur->width[c] = (uint8_t)w;
        cur->mask[c] = ((uint32_t)1 << w) - 1u;
        /* The gap escapes with all ones, a residual with its most negative code. */
        cur->escape[c] = !w ? UINT32_MAX : c == 0 ? cur->mask[0] : (uint32_t)1 << (w - 1u);
        cur->sign[c] = w && c ? (uint32_t)1 << (w - 1u) : 0u;
        at += w;
    }
    cur->keybits = at;
    for (c = 0; c < 4u; ++c) {
        q[c] = cur->q[c] = cur->q2[c] = c < t->dims ? mcd_read_signed(table, bit, t->abits[c]) : 0;
        if (c < t->dims) bit += t->abits[c];
    }
    n = t->keys - first < (1u << t->group_shift) ? t->keys - first : 1u << t->group_shift;
    cur->left = n - 1u;
    cur->exc = cur->bit + cur->left * cur->keybits;
    cur->key = first + 1u;
}

/* Component c's residual in record word w, or, for its escape code, the outlier's value
 * (then *whole is set): two's complement in the group's width. */
static inline int64_t field_value(const uint8_t* data, const track_layout* t, cursor* cur, uint64_t w, uint32_t c,
                                  int* whole) {
    uint32_t u = (uint32_t)(w >> cur->shift[c + 1u]) & cur->mask[c + 1u];
    if (u == cur->escape[c + 1u]) { /* rare */
        int64_t v = mcd_read_signed(data, cur->exc, t->abits[c]);
        cur->exc += t->abits[c];
        *whole = 1;
        return v;
    }
    *whole = 0;
    return (int64_t)(u ^ cur->sign[c + 1u]) - (int64_t)cur->sign[c + 1u];
}

static inline int32_t clamp_q(int64_t v) {
    /* Validated payloads stay within +-2^30; the clamp keeps any other bytes finite. */
    return (int32_t)(v > MAX_Q ? MAX_Q : v < -MAX_Q ? -MAX_Q : v);
}

/* Decode the key the cursor points at: its value into q, its frame into cur->frame. */
static void cursor_next(const uint8_t* p, const track_layout* t, cursor* cur, int32_t q[4]) {
    const uint8_t* data = p + t->data;
    uint64_t w;
    uint32_t u, c, bit = cur->bit;
    int64_t r[4];
    int whole[4];
    if (cur->left == 0) {
        group_open(p, t, cur->key >> t->group_shift, cur, q);
        return;
    }
    w = mcd_rd_u64(data + (bit >> 3)) >> (bit & 7u);
    if (cur->keybits > 57u) w |= mcd_rd_u64(data + (bit >> 3) + 7u) << (56u - (bit & 7u)); /* wide records */
    u = (uint32_t)w & cur->mask[0];
    if (u == cur->escape[0]) { /* an outlier gap: the frame whole */
        cur->frame = mcd_read_bits(data, cur->exc, t->frame_bits);
        cur->exc += t->frame_bits;
    } else {
        cur->frame += u + 1u;
    }
    /* Four components always: a track's missing fourth is a field of width 0. */
    r[0] = field_value(data, t, cur, w, 0, &whole[0]);
    r[1] = field_value(data, t, cur, w, 1, &whole[1]);
    r[2] = field_value(data, t, cur, w, 2, &whole[2]);
    r[3] = field_value(data, t, cur, w, 3, &whole[3]);
    if (t->predictor) {
        for (c = 0; c < 4u; ++c) {
            int64_t pred = cur->q[c] + floor_half(((int64_t)cur->q[c] - cur->q2[c]) * t->predictor + 1);
            cur->q2[c] = cur->q[c];
            q[c] = cur->q[c] = clamp_q(whole[c] ? r[c] : pred + r[c]);
        }
    } else {
        for (c = 0; c < 4u; ++c) {
            cur->q2[c] = cur->q[c];
            q[c] = cur->q[c] = clamp_q(whole[c] ? r[c] : (int64_t)cur->q[c] + r[c]);
        }
    }
    cur->bit = bit + cur->keybits;
    cur->left--;
    cur->key++;
}

/* ---------------------------------------------------------------- sampling state */
/* A track in the scratch: its layout, what its descriptor stores, the four keys around the
 * last sample (i - 1 ... i + 2, ends repeated) with their curve, and a cursor after them. */
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
    cursor cur;    /* decodes the key after key min(i + 2, last) next */
} track_state;

typedef struct node_plan {
    mcd_transform base; /* rest pose and constants resolved once per clip */
    int16_t track[3];   /* rotation, translation, scale track, or -1 */
    uint16_t pad;
} node_plan;

/* The scratch sizes are part of the format (docs/FORMAT.md, RMAL "Sampling"): changing these
 * structures is a new section version. Plain 32-bit fields only, so every ABI agrees. */
typedef char node_plan_is_48_bytes[sizeof(node_plan) == 48u ? 1 : -1];
typedef char track_state_is_396_bytes[sizeof(track_state) == 396u ? 1 : -1];

static size_t rma_scratch_size(const mcd_clip_view* v) {
    uint32_t nodes = mcd_rd_u32(v->payload + 8), tracks = mcd_rd_u32(v->payload + 12);
    return mcd_align16(sizeof(node_plan) * nodes) + mcd_align16(sizeof(track_state) * tracks);
}

static void scratch_views(void* scratch, uint32_t nodes, node_plan** plans, track_state** tracks) {
    *plans = (node_plan*)scratch;
    *tracks = (track_state*)((uint8_t*)scratch + mcd_align16(sizeof(node_plan) * nodes));
}

/* Window slot `slot` from a decoded key. */
static void store_key(track_state* ts, uint32_t slot, uint32_t frame, const int32_t q[4]) {
    uint32_t c;
    ts->t[slot] = (float)frame;
    /* Binary64 first: q may exceed 2^24 on long clips, where binary32 would round it. */
    for (c = 0; c < ts->L.dims; ++c) ts->v[slot][c] = (float)((double)q[c] * (double)ts->L.step[c]);
}

static void repeat_slot(track_state* ts, uint32_t to, uint32_t from) {
    memcpy(ts->v[to], ts->v[from], sizeof ts->v[to]);
    ts->t[to] = ts->t[from];
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

/* Random access: the segment holding frame position x, its four keys decoded afresh. */
static void locate(const uint8_t* p, track_state* ts, float x) {
    const track_layout* t = &ts->L;
    uint32_t last = t->keys - 1u, xi = (uint32_t)x, g, k, i, s, j;
    int32_t q[4], ring_q[4][4]; /* the last four decoded keys, key k at k & 3 */
    uint32_t ring_f[4];
    cursor* cur = &ts->cur;
    g = find_group(p, t, xi);
    /* Key i - 1 lies in group g - 1 when key i is g's first: x before g's second key, or g's
     * second key the last (whose segment is the one before it). */
    if (g > 0) {
        uint32_t second = (g << t->group_shift) + 1u;
        if (second >= last) {
            --g;
        } else {
            cursor peek;
            group_open(p, t, g, &peek, q);
            cursor_next(p, t, &peek, q);
            if (peek.frame > xi) --g;
        }
    }
    /* Decode on from group g's first key to the first key after x, then to key i + 2. */
    group_open(p, t, g, cur, q);
    k = g << t->group_shift;
    ring_f[k & 3u] = cur->frame;
    memcpy(ring_q[k & 3u], q, sizeof q);
    while (k < last && cur->frame <= xi) {
        cursor_next(p, t, cur, q);
        ++k;
        ring_f[k & 3u] = cur->frame;
        memcpy(ring_q[k & 3u], q, sizeof q);
    }
    i = cur->frame > xi ? k - 1u : k;
    if (i >= last) i = last - 1u; /* x at the last frame: the last segment */
    while (k < i + 2u && k < last) {
        cursor_next(p, t, cur, q);
        ++k;
        ring_f[k & 3u] = cur->frame;
        memcpy(ring_q[k & 3u], q, sizeof q);
    }
    ts->i = i;
    for (s = 0; s < 4u; ++s) {
        j = i + s < 1u ? 0u : i + s - 1u; /* keys i - 1 ... i + 2, ends repeated */
        if (j > last) j = last;
        store_key(ts, s, ring_f[j & 3u], ring_q[j & 3u]);
    }
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
                int32_t q[4];
                cursor_next(p, &ts->L, &ts->cur, q);
                store_key(ts, 3, ts->cur.frame, q);
            } else {
                repeat_slot(ts, 3, 2);
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
            int32_t q[4];
            group_open(p, &ts->L, 0, &ts->cur, q);
            store_key(ts, 0, 0, q);
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
/* Every rule of one track's seek table, group table and records, decoding every key. */
static mcd_result check_track(const uint8_t* p, const track_layout* t, uint32_t frames) {
    uint64_t data_bits = 8u * (uint64_t)t->data_bytes, bit = 0, b;
    uint32_t g, c, k, key = 0, j, last_frame = 0;
    cursor cur;
    /* Padding after the seek entries and the group entries is zero. */
    for (b = (uint64_t)t->seeks * t->group_bits; b < 32u * (((uint64_t)t->seeks * t->group_bits + 31u) / 32u); ++b)
        if (mcd_read_bits(p + t->seek, b, 1)) return MCD_ERROR_MALFORMED;
    for (b = (uint64_t)t->groups * t->entry_bits; b < 32u * (((uint64_t)t->groups * t->entry_bits + 31u) / 32u); ++b)
        if (mcd_read_bits(p + t->table, b, 1)) return MCD_ERROR_MALFORMED;
    /* Every key in order: records and outliers within the data area, groups back to back. */
    for (g = 0; g < t->groups; ++g) {
        uint32_t n = t->keys - (g << t->group_shift);
        int32_t q[4];
        if (n > (1u << t->group_shift)) n = 1u << t->group_shift;
        group_open(p, t, g, &cur, q);
        if (cur.bit != bit || (uint64_t)cur.bit + (uint64_t)(n - 1u) * cur.keybits > data_bits) return MCD_ERROR_MALFORMED;
        for (k = 0; k < n; ++k) {
            if (k > 0) {
                /* The record's escape codes tell how many outlier bits it consumes. */
                uint64_t need = cur.exc;
                if (cur.width[0] && mcd_read_bits(p + t->data, cur.bit, cur.width[0]) == cur.escape[0]) need += t->frame_bits;
                for (c = 0; c < t->dims; ++c)
                    if (cur.width[c + 1] &&
                        mcd_read_bits(p + t->data, (uint64_t)cur.bit + cur.shift[c + 1], cur.width[c + 1]) == cur.escape[c + 1])
                        need += t->abits[c];
                if (need > data_bits) return MCD_ERROR_MALFORMED;
                cursor_next(p, t, &cur, q);
            }
            for (c = 0; c < t->dims; ++c) {
                if (q[c] >= MAX_Q || q[c] <= -MAX_Q) return MCD_ERROR_MALFORMED;
                if (!mcd_in_bounds((float)((double)q[c] * (double)t->step[c]))) return MCD_ERROR_MALFORMED;
            }
            /* Frames increase from 0 to the last frame, which is the last key's. */
            if (key == 0 ? cur.frame != 0 : (cur.frame <= last_frame || cur.frame > frames - 1u)) return MCD_ERROR_MALFORMED;
            if (key == t->keys - 1u && cur.frame != frames - 1u) return MCD_ERROR_MALFORMED;
            last_frame = cur.frame;
            key++;
        }
        bit = cur.exc;
    }
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
