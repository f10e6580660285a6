/* Codec `rma`: per-track Catmull-Rom keys placed freely in time, sampled in place from the
 * asset's bytes (docs/FORMAT.md, RMAL version 2).
 *
 * A track's key times are a bit mask over the cells of its key grid with a rank directory (a
 * cell holding more than one key is listed, once per extra key, in a short sorted list); its
 * key values come in groups of G keys: a fixed-size group entry
 * (bit offset, residual widths, the first key whole) and fixed-width residuals from a
 * prediction, outliers stored whole. Random access finds the key at or before x by rank and
 * decodes the prefix of one or two groups; sequential playback keeps each track's four keys
 * and a decoding cursor in the scratch and reads one key record per key interval. */
#include <string.h>

#include "internal.h"

#define SECTION_HEADER 16u
#define PAYLOAD_HEADER 32u
#define MAX_GROUP_SHIFT 6u
#define MAX_Q 0x40000000LL /* |q| < 2^30: exact in binary64, products below 2^62 */
#define DIR_SHIFT 8u        /* a rank directory entry every 256 cells (4 mask words) */
#define WIDTH_BITS 5u

enum { KIND_MRP = 1, KIND_TWIST = 2, KIND_TRANSLATION = 3, KIND_SCALE = 4 };
enum { MODE_REST = 0, MODE_CONSTANT = 1, MODE_ANIMATED = 2 };

static uint32_t desc_size(uint32_t kind) {
    return kind == KIND_MRP ? 32u : kind == KIND_TWIST ? 44u : (kind == KIND_TRANSLATION || kind == KIND_SCALE) ? 24u : 0u;
}

static uint32_t kind_dims(uint32_t kind) {
    return kind == KIND_TWIST ? 4u : 3u;
}

/* ---------------------------------------------------------------- payload layout */
typedef struct header {
    uint32_t size, frames, nodes, tracks, constants, group_shift;
    const uint8_t *modes, *consts, *descs;
} header;

/* Everything about one track that its descriptor and the clip's frame count give. Offsets
 * are bytes from the start of the payload. */
typedef struct track_layout {
    uint8_t kind, dims, grid_shift, split, predictor, offset_bits, group_shift;
    uint8_t abits[4];
    uint32_t keys, cells, words, extras, extra_bits, groups, entry_bits, data_bytes;
    float step[4];
    uint32_t mask, dir, extra, table, data, end;
} track_layout;

static mcd_result parse_header(const uint8_t* p, size_t avail, header* H) {
    uint32_t i;
    if (avail < PAYLOAD_HEADER) return MCD_ERROR_MALFORMED;
    H->size = mcd_rd_u32(p);
    H->frames = mcd_rd_u32(p + 4);
    H->nodes = mcd_rd_u32(p + 8);
    H->tracks = mcd_rd_u32(p + 12);
    H->constants = mcd_rd_u32(p + 16);
    H->group_shift = p[20];
    if (H->size < PAYLOAD_HEADER || H->size > avail || (H->size & 3u)) return MCD_ERROR_MALFORMED;
    if (p[21] || p[22] || p[23] || mcd_rd_u32(p + 24) || mcd_rd_u32(p + 28)) return MCD_ERROR_MALFORMED;
    if (H->frames == 0 || H->nodes == 0 || H->nodes > MCD_MAX_NODES) return MCD_ERROR_MALFORMED;
    if (H->group_shift < 1 || H->group_shift > MAX_GROUP_SHIFT) return MCD_ERROR_MALFORMED;
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
static mcd_result track_geometry(const uint8_t* d, uint32_t frames, uint32_t group_shift, uint32_t at,
                                 uint32_t limit, track_layout* t) {
    uint32_t c;
    uint64_t end, entry;
    t->kind = d[0];
    if (!desc_size(t->kind)) return MCD_ERROR_MALFORMED;
    t->dims = (uint8_t)kind_dims(t->kind);
    /* Byte 1: the key grid's shift (bits 0-1), the first segment detached (bit 2). */
    t->grid_shift = d[1] & 3u;
    t->split = (d[1] >> 2) & 1u;
    t->predictor = d[2];
    t->offset_bits = d[3];
    t->group_shift = (uint8_t)group_shift;
    t->keys = mcd_rd_u32(d + 4);
    t->data_bytes = mcd_rd_u32(d + 8);
    t->extras = mcd_rd_u32(d + 12);
    if ((d[1] >> 3) || t->predictor > 2 || t->offset_bits < 1 || t->offset_bits > 32) return MCD_ERROR_MALFORMED;
    if (t->keys < 1 || t->keys > frames || (frames > 1u && t->keys < 2u)) return MCD_ERROR_MALFORMED;
    if ((t->data_bytes & 3u) || t->extras >= t->keys) return MCD_ERROR_MALFORMED;
    t->step[0] = t->step[1] = t->step[2] = t->step[3] = mcd_rd_f32(d + 16);
    if (t->kind == KIND_TWIST) t->step[0] = mcd_rd_f32(d + 40);
    entry = t->offset_bits + (uint64_t)WIDTH_BITS * t->dims + t->grid_shift;
    for (c = 0; c < 4; ++c) {
        t->abits[c] = d[20 + c];
        if (c < t->dims) {
            if (t->abits[c] < 1 || t->abits[c] > 31) return MCD_ERROR_MALFORMED;
            if (!mcd_in_bounds(t->step[c]) || t->step[c] < 0.0f) return MCD_ERROR_MALFORMED;
            entry += t->abits[c];
        } else if (t->abits[c]) {
            return MCD_ERROR_MALFORMED;
        }
    }
    t->entry_bits = (uint32_t)entry;
    t->cells = frames > 1u ? ((frames - 2u) >> t->grid_shift) + 1u : 0u;
    t->words = (t->cells + 63u) / 64u;
    t->groups = ((t->keys - 1u) >> group_shift) + 1u;
    /* Extra keys name their cell: as many bits as the largest cell index needs. */
    for (t->extra_bits = 1; t->extra_bits < 32u && t->cells > (1u << t->extra_bits); ++t->extra_bits) {}
    t->mask = at;
    t->dir = t->mask + 8u * t->words;
    t->extra = t->dir + 4u * ((t->words + 3u) / 4u);
    end = t->extra + 4u * (((uint64_t)t->extras * t->extra_bits + 31u) / 32u);
    if (end > limit) return MCD_ERROR_MALFORMED;
    t->table = (uint32_t)end;
    end += 4u * (((uint64_t)t->groups * t->entry_bits + 31u) / 32u);
    t->data = (uint32_t)(end < 0xFFFFFFFFu ? end : 0xFFFFFFFFu);
    end += t->data_bytes;
    if (end > limit) return MCD_ERROR_MALFORMED;
    t->end = (uint32_t)end;
    return MCD_OK;
}

/* ---------------------------------------------------------------- key times */
static uint64_t mask_word(const uint8_t* p, const track_layout* t, uint32_t w) {
    return mcd_rd_u64(p + t->mask + 8u * (size_t)w);
}

static int cell_set(const uint8_t* p, const track_layout* t, uint32_t c) {
    return (int)((mask_word(p, t, c >> 6) >> (c & 63u)) & 1u);
}

/* Extra keys in cells before c: a binary search of the sorted list. */
static uint32_t extras_before(const uint8_t* p, const track_layout* t, uint32_t c) {
    uint32_t lo = 0, hi = t->extras;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2u;
        if (mcd_read_bits(p + t->extra, (uint64_t)mid * t->extra_bits, t->extra_bits) < c) lo = mid + 1u; else hi = mid;
    }
    return lo;
}

/* Keys (not counting key 0) in cells [0, c): the directory entry of c's 256-cell block, its
 * words before c, and the extra keys there. */
static uint32_t rank(const uint8_t* p, const track_layout* t, uint32_t c) {
    uint32_t w = c >> 6, block = c >> DIR_SHIFT, n = mcd_rd_u32(p + t->dir + 4u * block), k;
    for (k = block << 2; k < w; ++k) n += mcd_popcount(mask_word(p, t, k));
    if (c & 63u) n += mcd_popcount(mask_word(p, t, w) & (((uint64_t)1 << (c & 63u)) - 1u));
    return n + (t->extras ? extras_before(p, t, c) : 0u);
}

/* Keys in cell c. */
static uint32_t keys_in_cell(const uint8_t* p, const track_layout* t, uint32_t c) {
    if (!cell_set(p, t, c)) return 0;
    return t->extras ? 1u + extras_before(p, t, c + 1u) - extras_before(p, t, c) : 1u;
}

/* The first set cell at or after c, or t->cells when there is none. */
static uint32_t next_set(const uint8_t* p, const track_layout* t, uint32_t c) {
    uint32_t w;
    uint64_t m;
    if (c >= t->cells) return t->cells;
    w = c >> 6;
    m = mask_word(p, t, w) & (~(uint64_t)0 << (c & 63u));
    while (!m) {
        if (++w >= t->words) return t->cells;
        m = mask_word(p, t, w);
    }
    return (w << 6) + mcd_lowest_bit(m);
}

/* The last set cell at or before c (c < cells), or UINT32_MAX when there is none. */
static uint32_t prev_set(const uint8_t* p, const track_layout* t, uint32_t c) {
    uint32_t w = c >> 6;
    uint64_t m = mask_word(p, t, w);
    if ((c & 63u) != 63u) m &= ((uint64_t)1 << ((c & 63u) + 1u)) - 1u;
    while (!m) {
        if (w == 0) return UINT32_MAX;
        m = mask_word(p, t, --w);
    }
    return (w << 6) + mcd_highest_bit(m);
}

/* ---------------------------------------------------------------- key values */
/* Decodes a track's keys in index order from a group's first key on. */
typedef struct cursor {
    uint32_t key;      /* index of the key the next call decodes */
    uint32_t left;     /* keys left in the current group after the last decoded one */
    uint32_t bit;      /* bit position (in the data area) of the next key record */
    uint32_t exc;      /* bit position of the current group's next outlier */
    uint8_t w[4];      /* residual widths of the current group */
    uint32_t keybits;  /* bits of one key record in the current group */
    int32_t q[4], q2[4]; /* the last two decoded values, for the prediction */
} cursor;

static int64_t floor_half(int64_t v) {
    return v >= 0 ? v / 2 : -((-v + 1) / 2);
}

/* Enter group g: its entry gives the record layout and the first key, written to q and o. */
static void group_open(const uint8_t* p, const track_layout* t, uint32_t g, cursor* cur, int32_t q[4], uint32_t* o) {
    const uint8_t* table = p + t->table;
    uint64_t bit = (uint64_t)g * t->entry_bits;
    uint32_t c, n, first = g << t->group_shift;
    cur->bit = mcd_read_bits(table, bit, t->offset_bits);
    bit += t->offset_bits;
    cur->keybits = t->grid_shift;
    for (c = 0; c < t->dims; ++c) {
        cur->w[c] = (uint8_t)mcd_read_bits(table, bit, WIDTH_BITS);
        cur->keybits += cur->w[c];
        bit += WIDTH_BITS;
    }
    *o = mcd_read_bits(table, bit, t->grid_shift);
    bit += t->grid_shift;
    for (c = 0; c < t->dims; ++c) {
        q[c] = cur->q[c] = cur->q2[c] = mcd_read_signed(table, bit, t->abits[c]);
        bit += t->abits[c];
    }
    n = t->keys - first < (1u << t->group_shift) ? t->keys - first : 1u << t->group_shift;
    cur->left = n - 1u;
    cur->exc = cur->bit + cur->left * cur->keybits;
    cur->key = first + 1u;
}

/* Decode the key the cursor points at (its value into q, its in-cell offset into o). */
static void cursor_next(const uint8_t* p, const track_layout* t, cursor* cur, int32_t q[4], uint32_t* o) {
    const uint8_t* data = p + t->data;
    uint32_t c, bit;
    if (cur->left == 0) {
        group_open(p, t, cur->key >> t->group_shift, cur, q, o);
        return;
    }
    bit = cur->bit;
    *o = mcd_read_bits(data, bit, t->grid_shift);
    bit += t->grid_shift;
    for (c = 0; c < t->dims; ++c) {
        uint32_t w = cur->w[c];
        int64_t v = cur->q[c];
        if (w) {
            int32_t r = mcd_read_signed(data, bit, w);
            bit += w;
            if (r == -(int32_t)((uint32_t)1 << (w - 1u)) && w > 0) {
                v = mcd_read_signed(data, cur->exc, t->abits[c]); /* an outlier, stored whole */
                cur->exc += t->abits[c];
            } else {
                v += floor_half((v - cur->q2[c]) * t->predictor + 1) + r;
            }
        } else {
            v += floor_half((v - cur->q2[c]) * t->predictor + 1);
        }
        /* Validated payloads stay within +-2^30; the clamp keeps any other bytes finite. */
        if (v > MAX_Q) v = MAX_Q;
        if (v < -MAX_Q) v = -MAX_Q;
        cur->q2[c] = cur->q[c];
        q[c] = cur->q[c] = (int32_t)v;
    }
    cur->bit = bit;
    cur->left--;
    cur->key++;
}

/* ---------------------------------------------------------------- sampling state */
/* Where a key's time lies: its cell (NO_CELL for key 0, at frame 0) and how many later keys
 * share that cell. */
#define NO_CELL UINT32_MAX
typedef struct key_place {
    uint32_t cell, after;
} key_place;

/* A track in the scratch: its layout, what its descriptor stores, the four keys around the
 * last sample (i - 1 ... i + 2, ends repeated) with their curve, and a cursor at key i + 3. */
typedef struct track_state {
    track_layout L;
    mcd_quat ref;
    float axis[4];
    uint32_t valid;
    uint32_t i;          /* the segment [key i, key i + 1] the curve below belongs to */
    key_place place[4];  /* where keys i - 1 ... i + 2 lie */
    float t[4];          /* their frames */
    float v[4][4];       /* their values */
    float t1, t2, inv_h;
    float coef[4][4];
    cursor cur;          /* decodes key i + 3 next (when it exists) */
} track_state;

typedef struct node_plan {
    mcd_transform base; /* rest pose and constants resolved once per clip */
    int16_t track[3];   /* rotation, translation, scale track, or -1 */
    uint16_t pad;
} node_plan;

static size_t rma_scratch_size(const mcd_clip_view* v) {
    uint32_t nodes = mcd_rd_u32(v->payload + 8), tracks = mcd_rd_u32(v->payload + 12);
    return mcd_align16(sizeof(node_plan) * nodes) + mcd_align16(sizeof(track_state) * tracks);
}

static void scratch_views(void* scratch, uint32_t nodes, node_plan** plans, track_state** tracks) {
    *plans = (node_plan*)scratch;
    *tracks = (track_state*)((uint8_t*)scratch + mcd_align16(sizeof(node_plan) * nodes));
}

static float dequantize(const track_layout* t, uint32_t c, int32_t q) {
    /* Binary64 first: q may exceed 2^24 on long clips, where binary32 would round it. */
    return (float)((double)q * (double)t->step[c]);
}

static float frame_of(const track_layout* t, uint32_t cell, uint32_t offset) {
    return cell == NO_CELL ? 0.0f : (float)(1u + (cell << t->grid_shift) + offset);
}

/* The place of the key after one at `k`. */
static key_place place_next(const uint8_t* p, const track_layout* t, key_place k) {
    key_place n;
    if (k.cell != NO_CELL && k.after > 0) {
        n.cell = k.cell;
        n.after = k.after - 1u;
        return n;
    }
    n.cell = next_set(p, t, k.cell == NO_CELL ? 0u : k.cell + 1u);
    n.after = n.cell < t->cells ? keys_in_cell(p, t, n.cell) - 1u : 0u;
    return n;
}

/* The place of the key before one at `k` (k is not key 0). */
static key_place place_prev(const uint8_t* p, const track_layout* t, key_place k) {
    key_place n;
    if (keys_in_cell(p, t, k.cell) > k.after + 1u) { /* not the first key of its cell */
        n.cell = k.cell;
        n.after = k.after + 1u;
        return n;
    }
    n.cell = k.cell ? prev_set(p, t, k.cell - 1u) : NO_CELL;
    n.after = 0;
    return n;
}

/* The in-cell offset of key k >= 1 (0 on a grid of one frame), read directly. */
static uint32_t key_offset(const uint8_t* p, const track_layout* t, uint32_t k) {
    uint32_t g = k >> t->group_shift, pos = k & ((1u << t->group_shift) - 1u), c, keybits = t->grid_shift;
    uint64_t bit = (uint64_t)g * t->entry_bits;
    uint32_t base;
    if (!t->grid_shift) return 0;
    base = mcd_read_bits(p + t->table, bit, t->offset_bits);
    bit += t->offset_bits;
    for (c = 0; c < t->dims; ++c) keybits += mcd_read_bits(p + t->table, bit + WIDTH_BITS * c, WIDTH_BITS);
    if (pos == 0) return mcd_read_bits(p + t->table, bit + WIDTH_BITS * t->dims, t->grid_shift);
    return mcd_read_bits(p + t->data, (uint64_t)base + (uint64_t)(pos - 1u) * keybits, t->grid_shift);
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

/* Decode the key after slot `slot - 1`'s into slot `slot`. */
static void load_next(const uint8_t* p, track_state* ts, uint32_t slot) {
    int32_t q[4];
    uint32_t o, c;
    cursor_next(p, &ts->L, &ts->cur, q, &o);
    ts->place[slot] = place_next(p, &ts->L, ts->place[slot - 1u]);
    ts->t[slot] = frame_of(&ts->L, ts->place[slot].cell, o);
    for (c = 0; c < ts->L.dims; ++c) ts->v[slot][c] = dequantize(&ts->L, c, q[c]);
}

static void repeat_slot(track_state* ts, uint32_t to, uint32_t from) {
    memcpy(ts->v[to], ts->v[from], sizeof ts->v[to]);
    ts->t[to] = ts->t[from];
    ts->place[to] = ts->place[from];
}

/* The last key at or before integer frame xi and its place. */
static uint32_t key_at_or_before(const uint8_t* p, const track_layout* t, uint32_t xi, key_place* at) {
    uint32_t cx, r, n, j;
    at->cell = NO_CELL;
    at->after = 0;
    if (xi == 0) return 0;
    cx = (xi - 1u) >> t->grid_shift;
    r = rank(p, t, cx);
    n = keys_in_cell(p, t, cx);
    for (j = n; j > 0; --j)
        if (1u + (cx << t->grid_shift) + key_offset(p, t, r + j) <= xi) {
            at->cell = cx;
            at->after = n - j;
            return r + j;
        }
    if (r == 0) return 0;
    at->cell = prev_set(p, t, cx - 1u); /* r > 0: an earlier cell holds keys */
    return r;
}

/* Random access: the segment holding frame position x, its four keys decoded afresh. */
static void locate(const uint8_t* p, track_state* ts, float x) {
    const track_layout* t = &ts->L;
    uint32_t last = t->keys - 1u, i, first, k, c, o, xi = (uint32_t)x;
    int32_t q[4];
    key_place at;
    /* i: the last key at or before x; the segment [i, i + 1], the last one at the clip's end. */
    i = key_at_or_before(p, t, xi, &at);
    if (i >= last) { /* x is the last frame: the last segment */
        i = last - 1u;
        at = place_prev(p, t, at);
    }
    ts->i = i;
    ts->place[1] = at;
    ts->place[0] = i == 0 ? at : place_prev(p, t, at);
    /* Decode keys from i - 1 (or 0) on: open its group and walk the records before it. */
    first = i ? i - 1u : 0u;
    group_open(p, t, first >> t->group_shift, &ts->cur, q, &o);
    for (k = first & ~((1u << t->group_shift) - 1u); k < first; ++k) cursor_next(p, t, &ts->cur, q, &o);
    for (c = 0; c < t->dims; ++c) ts->v[0][c] = dequantize(t, c, q[c]);
    ts->t[0] = frame_of(t, ts->place[0].cell, o);
    if (i == 0) {
        repeat_slot(ts, 1, 0);
    } else {
        cursor_next(p, t, &ts->cur, q, &o);
        for (c = 0; c < t->dims; ++c) ts->v[1][c] = dequantize(t, c, q[c]);
        ts->t[1] = frame_of(t, ts->place[1].cell, o);
    }
    load_next(p, ts, 2);
    if (i + 2u <= last)
        load_next(p, ts, 3);
    else
        repeat_slot(ts, 3, 2);
    set_curve(ts);
}

/* The curve of one track at x: the cached segment, a step or two forward in sequential
 * playback, or a fresh locate. */
static void track_value(const uint8_t* p, track_state* ts, float x, float out[4]) {
    uint32_t c, last = ts->L.keys - 1u, steps;
    float s;
    if (last == 0) { /* a one-frame clip */
        for (c = 0; c < ts->L.dims; ++c) out[c] = ts->v[0][c];
        return;
    }
    if (!ts->valid || x < ts->t1) {
        locate(p, ts, x);
    } else if (x >= ts->t2 && !(x == ts->t2 && ts->i + 1u == last)) {
        for (steps = 0; steps < 2 && x >= ts->t[2] && ts->i + 1u < last; ++steps) {
            memmove(ts->v[0], ts->v[1], sizeof ts->v[0] * 3u);
            memmove(ts->t, ts->t + 1, sizeof ts->t[0] * 3u);
            memmove(ts->place, ts->place + 1, sizeof ts->place[0] * 3u);
            ts->i++;
            if (ts->i + 2u <= last)
                load_next(p, ts, 3);
            else
                repeat_slot(ts, 3, 2);
        }
        if (x >= ts->t[2] && !(x == ts->t[2] && ts->i + 1u == last))
            locate(p, ts, x);
        else
            set_curve(ts);
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
        track_geometry(d, H.frames, H.group_shift, at, H.size, &ts->L);
        if (ts->L.kind == KIND_MRP || ts->L.kind == KIND_TWIST) ts->ref = mcd_reference_at(d + 24);
        if (ts->L.kind == KIND_TWIST) mcd_axis_at(d + 32, ts->axis);
        if (ts->L.keys == 1u) { /* one frame: the single key is group 0's first */
            int32_t q[4];
            uint32_t o, c;
            group_open(p, &ts->L, 0, &ts->cur, q, &o);
            for (c = 0; c < ts->L.dims; ++c) ts->v[0][c] = dequantize(&ts->L, c, q[c]);
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
/* Every rule of one track's mask, directory, group table and data, decoding every key. */
static mcd_result check_track(const uint8_t* p, const track_layout* t, uint32_t frames) {
    uint64_t data_bits = 8u * (uint64_t)t->data_bytes, bit = 0, tbits;
    uint32_t w, set = 0, g, c, k, key = 0, last_frame = 0, prev_extra = 0;
    key_place place = {NO_CELL, 0};
    cursor cur;
    /* Mask: no bit past the cells; the directory counts the keys before each 256 cells. */
    for (w = 0; w < t->words; ++w) {
        uint64_t m = mask_word(p, t, w);
        if ((w & 3u) == 0 && mcd_rd_u32(p + t->dir + 4u * (w >> 2)) != set) return MCD_ERROR_MALFORMED;
        if (w + 1u == t->words && (t->cells & 63u) && (m >> (t->cells & 63u))) return MCD_ERROR_MALFORMED;
        set += mcd_popcount(m);
    }
    if (set + t->extras != t->keys - 1u) return MCD_ERROR_MALFORMED;
    /* Extra keys: sorted cells that hold a key already; the list's padding is zero. */
    for (k = 0; k < t->extras; ++k) {
        uint32_t e = mcd_read_bits(p + t->extra, (uint64_t)k * t->extra_bits, t->extra_bits);
        if (e >= t->cells || e < prev_extra || !cell_set(p, t, e)) return MCD_ERROR_MALFORMED;
        prev_extra = e;
    }
    for (tbits = (uint64_t)t->extras * t->extra_bits; tbits < 32u * (((uint64_t)t->extras * t->extra_bits + 31u) / 32u); ++tbits)
        if (mcd_read_bits(p + t->extra, tbits, 1)) return MCD_ERROR_MALFORMED;
    /* The last frame is a key: the last cell is set. */
    if (t->keys > 1u && !((mask_word(p, t, (t->cells - 1u) >> 6) >> ((t->cells - 1u) & 63u)) & 1u)) return MCD_ERROR_MALFORMED;
    /* Group table padding. */
    tbits = (uint64_t)t->groups * t->entry_bits;
    for (; tbits < 32u * (((uint64_t)t->groups * t->entry_bits + 31u) / 32u); ++tbits)
        if (mcd_read_bits(p + t->table, tbits, 1)) return MCD_ERROR_MALFORMED;
    /* Every key, in order: records and outliers within the data area, groups back to back. */
    for (g = 0; g < t->groups; ++g) {
        uint64_t ebit = (uint64_t)g * t->entry_bits + t->offset_bits;
        uint32_t n = t->keys - (g << t->group_shift), keybits = t->grid_shift;
        int32_t q[4];
        uint32_t o;
        if (n > (1u << t->group_shift)) n = 1u << t->group_shift;
        if (mcd_read_bits(p + t->table, (uint64_t)g * t->entry_bits, t->offset_bits) != bit) return MCD_ERROR_MALFORMED;
        for (c = 0; c < t->dims; ++c) {
            uint32_t width = mcd_read_bits(p + t->table, ebit + WIDTH_BITS * c, WIDTH_BITS);
            if (width > 30u) return MCD_ERROR_MALFORMED;
            keybits += width;
        }
        if (bit + (uint64_t)(n - 1u) * keybits > data_bits) return MCD_ERROR_MALFORMED;
        cur.left = 0;
        cur.key = g << t->group_shift;
        group_open(p, t, g, &cur, q, &o);
        for (k = 0; k < n; ++k) {
            uint32_t cell, frame;
            (void)cell;
            if (k > 0) {
                /* Outliers: the escape codes of this record tell how many bits it consumes. */
                uint64_t need = cur.exc;
                uint32_t b = cur.bit + t->grid_shift;
                for (c = 0; c < t->dims; ++c) {
                    if (cur.w[c] && mcd_read_signed(p + t->data, b, cur.w[c]) == -(int32_t)((uint32_t)1 << (cur.w[c] - 1u)))
                        need += t->abits[c];
                    b += cur.w[c];
                }
                if (need > data_bits) return MCD_ERROR_MALFORMED;
                cursor_next(p, t, &cur, q, &o);
            }
            for (c = 0; c < t->dims; ++c) {
                if (q[c] >= MAX_Q || q[c] <= -MAX_Q) return MCD_ERROR_MALFORMED;
                if (!mcd_in_bounds(dequantize(t, c, q[c]))) return MCD_ERROR_MALFORMED;
            }
            if (key == 0) {
                if (o != 0) return MCD_ERROR_MALFORMED; /* key 0 is frame 0 */
            } else {
                place = place_next(p, t, place);
                cell = place.cell;
                frame = 1u + (cell << t->grid_shift) + o;
                if (frame <= last_frame || frame > frames - 1u) return MCD_ERROR_MALFORMED;
                if (key == t->keys - 1u && frame != frames - 1u) return MCD_ERROR_MALFORMED;
                last_frame = frame;
            }
            key++;
        }
        bit = cur.exc;
    }
    /* The data area ends after the last group, zero-padded to a multiple of 4 bytes. */
    if (t->data_bytes != mcd_align4((size_t)((bit + 7u) / 8u))) return MCD_ERROR_MALFORMED;
    for (; bit < data_bits; ++bit)
        if (mcd_read_bits(p + t->data, bit, 1)) return MCD_ERROR_MALFORMED;
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
                if (kind == KIND_MRP || kind == KIND_TWIST) {
                    if (mcd_rd_u16(H.descs + off + 30)) return MCD_ERROR_MALFORMED;
                }
                if (kind == KIND_TWIST) {
                    const uint8_t* a = H.descs + off + 32;
                    float ax = (float)(int16_t)mcd_rd_u16(a), ay = (float)(int16_t)mcd_rd_u16(a + 2);
                    float az = (float)(int16_t)mcd_rd_u16(a + 4);
                    if (mcd_rd_u16(a + 6)) return MCD_ERROR_MALFORMED;
                    if (ax * ax + ay * ay + az * az < 0.25f * 32767.0f * 32767.0f) return MCD_ERROR_MALFORMED;
                }
                /* The geometry is checked below, once every descriptor's size is known. */
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
        const uint8_t* d = H.descs + off;
        r = track_geometry(d, H.frames, H.group_shift, at, H.size, &t);
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
