/* Codec `spline`: per-track Catmull-Rom keys, bit-packed in blocks (docs/FORMAT.md, SPLN).
 *
 * Random access walks at most four blocks' headers (the block of x and its neighbours, for
 * the keys around x). Sequential playback is O(1) per frame: each track keeps the four keys
 * of its current interval, dequantised, and only re-locates when x leaves the interval. */
#include <math.h>
#include <string.h>

#include "internal.h"

#define PAYLOAD_HEADER 32u
#define NODE_ENTRY 8u
#define WALK_SLOTS 4u

enum { KIND_MRP = 1, KIND_TWIST = 2, KIND_TRANSLATION = 3 };

/* ---------------------------------------------------------------- payload layout */
typedef struct layout {
    uint32_t frames, nodes, tracks, shift, block_len, blocks, constants, stream_size, desc_bytes;
    const uint8_t *node_table, *consts, *descs, *block_table, *stream;
} layout;

/* Descriptor size by kind (docs/FORMAT.md); 0 for an unknown kind. */
static uint32_t desc_size(uint32_t kind) {
    return kind == KIND_MRP ? 36u : kind == KIND_TWIST ? 56u : kind == KIND_TRANSLATION ? 28u : 0u;
}

static uint32_t kind_dims(uint32_t kind) {
    return kind == KIND_TWIST ? 4u : 3u;
}

static void read_layout(const uint8_t* p, layout* L) {
    L->frames = mcd_rd_u32(p);
    L->nodes = mcd_rd_u32(p + 4);
    L->tracks = mcd_rd_u32(p + 8);
    L->shift = p[12];
    L->block_len = 1u << L->shift;
    L->blocks = mcd_rd_u32(p + 16);
    L->constants = mcd_rd_u32(p + 20);
    L->stream_size = mcd_rd_u32(p + 24);
    L->desc_bytes = mcd_rd_u32(p + 28);
    L->node_table = p + PAYLOAD_HEADER;
    L->consts = L->node_table + (size_t)L->nodes * NODE_ENTRY;
    L->descs = L->consts + (size_t)L->constants * 4u;
    L->block_table = L->descs + L->desc_bytes;
    L->stream = L->block_table + (size_t)L->blocks * 4u;
}

static uint32_t block_start(const layout* L, uint32_t j) {
    uint64_t s = (uint64_t)j << L->shift;
    return s < L->frames - 1u ? (uint32_t)s : L->frames - 1u;
}

/* n extra keys take n offsets of `shift` bits, or a (B - 1)-bit mask when that is shorter. */
static uint32_t time_bits(const layout* L, uint32_t n) {
    return n * L->shift < L->block_len - 1u ? n * L->shift : L->block_len - 1u;
}

static uint64_t read_mask(const uint8_t* stream, uint64_t pos, uint32_t n) {
    if (n <= 32u) return mcd_read_bits(stream, pos, n);
    return (uint64_t)mcd_read_bits(stream, pos, 32u) | ((uint64_t)mcd_read_bits(stream, pos + 32u, n - 32u) << 32);
}

/* ---------------------------------------------------------------- validation */
/* Check one descriptor of `avail` bytes; on success its kind and key bits are returned. */
static mcd_result check_track(const uint8_t* t, uint32_t avail, uint32_t* out_size, uint8_t* out_kind,
                              uint8_t* out_keybits) {
    uint32_t kind, dims, size, head, c, keybits = 0;
    if (avail < 4) return MCD_ERROR_MALFORMED;
    kind = t[0];
    size = desc_size(kind);
    if (size == 0 || size > avail) return MCD_ERROR_MALFORMED;
    dims = kind_dims(kind);
    head = dims == 4u ? 8u : 4u;
    if (dims == 4u && (t[5] || t[6] || t[7])) return MCD_ERROR_MALFORMED;
    for (c = 0; c < dims; ++c) {
        uint32_t bits = t[1 + c];
        float mn = mcd_rd_f32(t + head + 4 * c), st = mcd_rd_f32(t + head + 4 * (dims + c));
        if (bits > 24u || !mcd_in_bounds(mn) || !mcd_finite(st) || st < 0.0f) return MCD_ERROR_MALFORMED;
        if (!mcd_in_bounds(mn + (float)((1u << bits) - 1u) * st)) return MCD_ERROR_MALFORMED;
        keybits += bits;
    }
    if (kind != KIND_TRANSLATION) {
        const uint8_t* r = t + head + 8u * dims;
        if (mcd_rd_u16(r + 6) != 0) return MCD_ERROR_MALFORMED;
        if (kind == KIND_TWIST) {
            float ax = (float)(int16_t)mcd_rd_u16(r + 8), ay = (float)(int16_t)mcd_rd_u16(r + 10);
            float az = (float)(int16_t)mcd_rd_u16(r + 12);
            if (mcd_rd_u16(r + 14) != 0) return MCD_ERROR_MALFORMED;
            if (ax * ax + ay * ay + az * az < 0.25f * 32767.0f * 32767.0f) return MCD_ERROR_MALFORMED;
        }
    }
    *out_size = size;
    *out_kind = (uint8_t)kind;
    *out_keybits = (uint8_t)keybits;
    return MCD_OK;
}

/* Parse block j's structure (not its values) starting at bit `pos`; returns the end bit or
 * UINT64_MAX when a rule is broken or it would read at or past `limit`. */
static uint64_t check_block(const layout* L, const uint8_t* keybits, uint32_t j, uint64_t pos, uint64_t limit) {
    uint32_t u, span = j + 1u < L->blocks ? block_start(L, j + 1u) - block_start(L, j) : 0u;
    int last = j + 1u == L->blocks;
    for (u = 0; u < L->tracks; ++u) {
        uint32_t kb = keybits[u], n = 0;
        if (!last) {
            uint32_t tb, e, prev = 0;
            if (pos + L->shift > limit) return UINT64_MAX;
            n = mcd_read_bits(L->stream, pos, L->shift);
            pos += L->shift;
            if (n + 1u > span) return UINT64_MAX;
            tb = time_bits(L, n);
            if (pos + tb > limit) return UINT64_MAX;
            if (n * L->shift < L->block_len - 1u) {
                for (e = 0; e < n; ++e) {
                    uint32_t off = mcd_read_bits(L->stream, pos + (uint64_t)e * L->shift, L->shift);
                    if (off <= prev || off >= span) return UINT64_MAX;
                    prev = off;
                }
            } else {
                uint64_t mask = read_mask(L->stream, pos, tb);
                uint32_t count = 0;
                if (span - 1u < 64u && (mask >> (span - 1u)) != 0) return UINT64_MAX;
                while (mask) {
                    mask &= mask - 1u;
                    count++;
                }
                if (count != n) return UINT64_MAX;
            }
            pos += tb;
        }
        pos += (uint64_t)(n + 1u) * kb;
        if (pos > limit) return UINT64_MAX;
    }
    return pos;
}

static mcd_result spline_validate(const mcd_clip_view* v) {
    const uint8_t* p = v->payload;
    layout L;
    uint8_t used[2 * MCD_MAX_NODES], kinds[2 * MCD_MAX_NODES], keybits[2 * MCD_MAX_NODES];
    uint64_t total, pos, limit;
    uint32_t i, j, off;
    uint32_t frames, nodes, tracks, shift, blocks, constants, stream_size, desc_bytes;
    if (v->payload_size < PAYLOAD_HEADER) return MCD_ERROR_MALFORMED;
    /* Check the counts before forming any pointer from them. */
    frames = mcd_rd_u32(p);
    nodes = mcd_rd_u32(p + 4);
    tracks = mcd_rd_u32(p + 8);
    shift = p[12];
    blocks = mcd_rd_u32(p + 16);
    constants = mcd_rd_u32(p + 20);
    stream_size = mcd_rd_u32(p + 24);
    desc_bytes = mcd_rd_u32(p + 28);
    if (frames != v->frame_count || nodes != v->node_count) return MCD_ERROR_MALFORMED;
    if (tracks > 2u * nodes || shift < 3u || shift > 6u) return MCD_ERROR_MALFORMED;
    if (p[13] || p[14] || p[15]) return MCD_ERROR_MALFORMED;
    if ((uint64_t)blocks != ((uint64_t)frames - 1u + (1u << shift) - 1u) / (1u << shift) + 1u) return MCD_ERROR_MALFORMED;
    if (constants > 7u * nodes || stream_size < 8u) return MCD_ERROR_MALFORMED;
    total = (uint64_t)PAYLOAD_HEADER + (uint64_t)nodes * NODE_ENTRY + (uint64_t)constants * 4u +
            (uint64_t)desc_bytes + (uint64_t)blocks * 4u + stream_size;
    if (total != v->payload_size) return MCD_ERROR_MALFORMED;
    read_layout(p, &L);

    for (i = 0; i < L.constants; ++i)
        if (!mcd_in_bounds(mcd_rd_f32(L.consts + 4 * i))) return MCD_ERROR_MALFORMED;
    for (i = 0, off = 0; i < L.tracks; ++i) {
        uint32_t size;
        mcd_result r = check_track(L.descs + off, L.desc_bytes - off, &size, &kinds[i], &keybits[i]);
        if (r != MCD_OK) return r;
        off += size;
    }
    if (off != L.desc_bytes) return MCD_ERROR_MALFORMED;
    memset(used, 0, sizeof used);
    for (i = 0; i < L.nodes; ++i) {
        const uint8_t* e = L.node_table + (size_t)i * NODE_ENTRY;
        uint32_t rm = e[0], tm = e[1], ri = mcd_rd_u16(e + 2), ti = mcd_rd_u16(e + 4);
        if (mcd_rd_u16(e + 6) != 0) return MCD_ERROR_MALFORMED;
        if (rm == 0) {
            if (ri != 0) return MCD_ERROR_MALFORMED;
        } else if (rm == 1) {
            if (ri + 4u > L.constants || !mcd_unit_quat_at(L.consts + 4u * ri)) return MCD_ERROR_MALFORMED;
        } else if (rm == 2) {
            if (ri >= L.tracks || used[ri] || kinds[ri] == KIND_TRANSLATION) return MCD_ERROR_MALFORMED;
            used[ri] = 1;
        } else {
            return MCD_ERROR_MALFORMED;
        }
        if (tm == 0) {
            if (ti != 0) return MCD_ERROR_MALFORMED;
        } else if (tm == 1) {
            if (ti + 3u > L.constants) return MCD_ERROR_MALFORMED;
        } else if (tm == 2) {
            if (ti >= L.tracks || used[ti] || kinds[ti] != KIND_TRANSLATION) return MCD_ERROR_MALFORMED;
            used[ti] = 1;
        } else {
            return MCD_ERROR_MALFORMED;
        }
    }
    for (i = 0; i < L.tracks; ++i)
        if (!used[i]) return MCD_ERROR_MALFORMED;

    limit = ((uint64_t)L.stream_size - 8u) * 8u;
    if (mcd_rd_u32(L.block_table) != 0) return MCD_ERROR_MALFORMED;
    pos = 0;
    for (j = 0; j < L.blocks; ++j) {
        if (mcd_rd_u32(L.block_table + 4u * j) != pos) return MCD_ERROR_MALFORMED;
        pos = check_block(&L, keybits, j, pos, limit);
        if (pos == UINT64_MAX) return MCD_ERROR_MALFORMED;
    }
    /* Everything after the last block is zero, including the unused bits of its last byte. */
    if ((pos & 7u) && (L.stream[pos >> 3] >> (pos & 7u)) != 0) return MCD_ERROR_MALFORMED;
    for (i = (uint32_t)((pos + 7u) >> 3); i < L.stream_size; ++i)
        if (L.stream[i] != 0) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* ---------------------------------------------------------------- scratch */
typedef struct track_state {
    uint32_t kind, dims, keybits, valid;
    uint32_t bits[4];
    float minimum[4], step[4];
    mcd_quat ref;
    float axis[4];
    float t[4];    /* frames of keys i-1, i, i+1, i+2 */
    float v[4][4]; /* their values */
    uint32_t ref_block[4], ref_k[4]; /* where those keys are: block and index in it */
    /* The segment [t1, t2] as a cubic in s = (x - t1) / (t2 - t1), Horner-ready: computed
     * once per key change, so a sample costs three multiply-adds per component. */
    float inv_h;
    float coef[4][4]; /* [power][component] */
} track_state;

typedef struct node_plan {
    mcd_transform base; /* constants and rest offsets resolved once per clip */
    int32_t rot_track, trans_track;
} node_plan;

typedef struct walk_header {
    uint32_t block, valid;
} walk_header;

typedef struct spline_state {
    uint32_t tracks, nodes, pad0, pad1;
} spline_state;

/* Layout: spline_state | node_plan[N] | track_state[T] | WALK_SLOTS x (walk_header | u32 n[T] | u32 tpos[T] | u32 vpos[T]) */

static size_t walk_slot_size(uint32_t tracks) {
    return mcd_align16(sizeof(walk_header) + 3u * 4u * (size_t)tracks);
}

static size_t spline_scratch_size(const mcd_clip_view* v) {
    uint32_t tracks = mcd_rd_u32(v->payload + 8), nodes = mcd_rd_u32(v->payload + 4);
    return mcd_align16(sizeof(spline_state)) + mcd_align16(sizeof(node_plan) * nodes) +
           mcd_align16(sizeof(track_state) * tracks) + WALK_SLOTS * walk_slot_size(tracks);
}

/* Block walk: per track, extra-key count and bit positions of its times and values. */
typedef struct walk {
    walk_header* h;
    uint32_t *n, *tpos, *vpos;
} walk;

typedef struct views {
    spline_state* st;
    node_plan* plans;
    track_state* tracks;
    uint8_t* walks;
    /* Walks already resolved during this sample call, by block % WALK_SLOTS: saves the
     * slot lookup and validity check on every key read. */
    walk resolved[WALK_SLOTS];
    uint32_t resolved_block[WALK_SLOTS];
} views;

static void scratch_views(void* scratch, uint32_t nodes, uint32_t tracks, views* s) {
    uint8_t* b = (uint8_t*)scratch;
    s->st = (spline_state*)b;
    b += mcd_align16(sizeof(spline_state));
    s->plans = (node_plan*)b;
    b += mcd_align16(sizeof(node_plan) * nodes);
    s->tracks = (track_state*)b;
    b += mcd_align16(sizeof(track_state) * tracks);
    s->walks = b;
}

static walk get_walk_slow(const layout* L, const views* s, uint32_t j) {
    walk w;
    uint8_t* slot = s->walks + (size_t)(j % WALK_SLOTS) * walk_slot_size(L->tracks);
    w.h = (walk_header*)slot;
    w.n = (uint32_t*)(slot + sizeof(walk_header));
    w.tpos = w.n + L->tracks;
    w.vpos = w.tpos + L->tracks;
    if (!w.h->valid || w.h->block != j) {
        uint64_t pos = mcd_rd_u32(L->block_table + 4u * j);
        int last = j + 1u == L->blocks;
        uint32_t u;
        for (u = 0; u < L->tracks; ++u) {
            uint32_t n = 0;
            if (!last) {
                n = mcd_read_bits(L->stream, pos, L->shift);
                pos += L->shift;
            }
            w.n[u] = n;
            w.tpos[u] = (uint32_t)pos;
            pos += last ? 0u : time_bits(L, n);
            w.vpos[u] = (uint32_t)pos;
            pos += (uint64_t)(n + 1u) * s->tracks[u].keybits;
        }
        w.h->block = j;
        w.h->valid = 1;
    }
    return w;
}

static const walk* walk_of(const layout* L, views* s, uint32_t j) {
    uint32_t slot = j % WALK_SLOTS;
    if (s->resolved_block[slot] != j) {
        s->resolved[slot] = get_walk_slow(L, s, j);
        s->resolved_block[slot] = j;
    }
    return &s->resolved[slot];
}

/* Offsets of all keys of track u in block j: out[0] = 0, out[1 .. n] the extras. */
static uint32_t block_offsets(const layout* L, const walk* w, uint32_t u, uint8_t out[64]) {
    uint32_t n = w->n[u], e;
    out[0] = 0;
    if (n * L->shift < L->block_len - 1u) {
        for (e = 0; e < n; ++e)
            out[1 + e] = (uint8_t)mcd_read_bits(L->stream, w->tpos[u] + (uint64_t)e * L->shift, L->shift);
    } else {
        uint64_t mask = read_mask(L->stream, w->tpos[u], L->block_len - 1u);
        for (e = 0; e < n; ++e) {
            out[1 + e] = (uint8_t)(mcd_lowest_bit(mask) + 1u);
            mask &= mask - 1u;
        }
    }
    return n;
}

/* Offset of key k (0 ... n) of track u in block j, without decoding the others. */
static uint32_t key_offset(const layout* L, const walk* w, uint32_t u, uint32_t k) {
    uint32_t n = w->n[u];
    uint64_t mask;
    if (k == 0) return 0;
    if (n * L->shift < L->block_len - 1u)
        return mcd_read_bits(L->stream, w->tpos[u] + (uint64_t)(k - 1u) * L->shift, L->shift);
    mask = read_mask(L->stream, w->tpos[u], L->block_len - 1u);
    if (k == n) return mcd_highest_bit(mask) + 1u; /* the block's last key: no scan */
    while (--k) mask &= mask - 1u;
    return mcd_lowest_bit(mask) + 1u;
}

static void read_key(const layout* L, const walk* w, const track_state* ts, uint32_t u, uint32_t k,
                     float out[4]) {
    uint64_t pos = w->vpos[u] + (uint64_t)k * ts->keybits;
    uint32_t c;
    if (ts->keybits <= 56u) { /* the whole key in one 8-byte load */
        uint64_t word = mcd_rd_u64(L->stream + (size_t)(pos >> 3)) >> (pos & 7u);
        for (c = 0; c < ts->dims; ++c) {
            uint32_t q = (uint32_t)(word & ((1u << ts->bits[c]) - 1u));
            out[c] = ts->minimum[c] + (float)q * ts->step[c];
            word >>= ts->bits[c];
        }
        return;
    }
    for (c = 0; c < ts->dims; ++c) {
        uint32_t q = ts->bits[c] ? mcd_read_bits(L->stream, pos, ts->bits[c]) : 0u;
        out[c] = ts->minimum[c] + (float)q * ts->step[c];
        pos += ts->bits[c];
    }
}


static void set_slot(const layout* L, track_state* ts, uint32_t slot, const walk* w, uint32_t u,
                     uint32_t block, uint32_t k, uint32_t frame) {
    ts->ref_block[slot] = block;
    ts->ref_k[slot] = k;
    ts->t[slot] = (float)frame;
    read_key(L, w, ts, u, k, ts->v[slot]);
}

/* Fill the track's four keys around frame position x (random access): the block of x and
 * at most one key of each neighbouring block, each found without decoding the rest. */
static void locate(const layout* L, views* s, uint32_t u, float x) {
    track_state* ts = &s->tracks[u];
    uint8_t offs[64];
    uint32_t j, n, i, sj, sj1;
    const walk* wj;
    if (L->blocks == 1u) { /* a single frame: one key, a flat curve */
        uint32_t slot;
        wj = walk_of(L, s, 0);
        for (slot = 0; slot < 4; ++slot) set_slot(L, ts, slot, wj, u, 0, 0, 0);
        ts->t[2] = ts->t[3] = 1.0f;
        ts->valid = 1;
        return;
    }
    j = (uint32_t)x >> L->shift;
    if (j > L->blocks - 2u) j = L->blocks - 2u;
    wj = walk_of(L, s, j);
    n = block_offsets(L, wj, u, offs);
    sj = block_start(L, j);
    sj1 = block_start(L, j + 1u);
    /* Interval i: the last key of block j at or before x. */
    for (i = 0; i < n && (float)(sj + offs[i + 1]) <= x; ++i) {
    }
    set_slot(L, ts, 1, wj, u, j, i, sj + offs[i]);
    if (i > 0) {
        set_slot(L, ts, 0, wj, u, j, i - 1u, sj + offs[i - 1u]);
    } else if (j > 0) {
        const walk* wp = walk_of(L, s, j - 1u);
        set_slot(L, ts, 0, wp, u, j - 1u, wp->n[u], block_start(L, j - 1u) + key_offset(L, wp, u, wp->n[u]));
    } else {
        set_slot(L, ts, 0, wj, u, j, 0, sj);
    }
    if (i + 1u <= n) {
        set_slot(L, ts, 2, wj, u, j, i + 1u, sj + offs[i + 1u]);
        if (i + 2u <= n) {
            set_slot(L, ts, 3, wj, u, j, i + 2u, sj + offs[i + 2u]);
        } else {
            set_slot(L, ts, 3, walk_of(L, s, j + 1u), u, j + 1u, 0, sj1);
        }
    } else {
        const walk* wn = walk_of(L, s, j + 1u);
        set_slot(L, ts, 2, wn, u, j + 1u, 0, sj1);
        if (j + 2u == L->blocks) {
            set_slot(L, ts, 3, wn, u, j + 1u, 0, sj1); /* the clip's last key repeats */
        } else if (wn->n[u] > 0) {
            set_slot(L, ts, 3, wn, u, j + 1u, 1, sj1 + key_offset(L, wn, u, 1));
        } else {
            set_slot(L, ts, 3, walk_of(L, s, j + 2u), u, j + 2u, 0, block_start(L, j + 2u));
        }
    }
    ts->valid = 1;
}

/* Move the four-key window one key forward (sequential playback): one new key read, its
 * frame found from the previous key's offset without rescanning the block. */
static void advance(const layout* L, views* s, uint32_t u) {
    track_state* ts = &s->tracks[u];
    uint32_t b = ts->ref_block[3], k = ts->ref_k[3], i, c, frame;
    const walk* w = walk_of(L, s, b);
    for (i = 0; i < 3; ++i) {
        ts->t[i] = ts->t[i + 1];
        ts->ref_block[i] = ts->ref_block[i + 1];
        ts->ref_k[i] = ts->ref_k[i + 1];
        for (c = 0; c < 4; ++c) ts->v[i][c] = ts->v[i + 1][c];
    }
    if (k < w->n[u]) {
        uint32_t prev = (uint32_t)ts->t[2] - block_start(L, b); /* offset of key k */
        if (w->n[u] * L->shift < L->block_len - 1u) {
            frame = block_start(L, b) + mcd_read_bits(L->stream, w->tpos[u] + (uint64_t)k * L->shift, L->shift);
        } else {
            uint64_t mask = read_mask(L->stream, w->tpos[u], L->block_len - 1u) >> prev;
            frame = block_start(L, b) + prev + 1u + mcd_lowest_bit(mask);
        }
        ++k;
    } else if (b + 1u < L->blocks) {
        ++b;
        k = 0;
        w = walk_of(L, s, b);
        frame = block_start(L, b);
    } else {
        frame = (uint32_t)ts->t[2]; /* the clip's last key repeats */
    }
    set_slot(L, ts, 3, w, u, b, k, frame);
}

/* Cubic coefficients of the window's middle segment. */
static void segment_coefficients(track_state* ts) {
    ts->inv_h = mcd_segment_coefficients(ts->t, (const float(*)[4])ts->v, ts->dims, ts->coef);
}

static void eval_track(const track_state* ts, float x, float out[4]) {
    float s = (x - ts->t[1]) * ts->inv_h;
    uint32_t c;
    for (c = 0; c < ts->dims; ++c)
        out[c] = ((ts->coef[3][c] * s + ts->coef[2][c]) * s + ts->coef[1][c]) * s + ts->coef[0][c];
}

static void prepare(const layout* L, const mcd_clip_view* v, const views* s) {
    uint32_t i, c, k, off;
    s->st->tracks = L->tracks;
    s->st->nodes = L->nodes;
    for (i = 0, off = 0; i < L->tracks; ++i) {
        const uint8_t* d = L->descs + off;
        track_state* ts = &s->tracks[i];
        uint32_t head;
        memset(ts, 0, sizeof *ts);
        ts->kind = d[0];
        ts->dims = kind_dims(ts->kind);
        head = ts->dims == 4u ? 8u : 4u;
        for (c = 0; c < ts->dims; ++c) {
            ts->bits[c] = d[1 + c];
            ts->keybits += ts->bits[c];
            ts->minimum[c] = mcd_rd_f32(d + head + 4 * c);
            ts->step[c] = mcd_rd_f32(d + head + 4 * (ts->dims + c));
        }
        if (ts->kind != KIND_TRANSLATION) {
            const uint8_t* r = d + head + 8u * ts->dims;
            ts->ref = mcd_reference_at(r);
            if (ts->kind == KIND_TWIST) mcd_axis_at(r + 8, ts->axis);
        }
        off += desc_size(ts->kind);
    }
    for (i = 0; i < L->nodes; ++i) {
        const uint8_t* e = L->node_table + (size_t)i * NODE_ENTRY;
        node_plan* np = &s->plans[i];
        uint32_t ri = mcd_rd_u16(e + 2), ti = mcd_rd_u16(e + 4);
        mcd_skel_rest(v->skeleton, i, &np->base);
        np->rot_track = -1;
        np->trans_track = -1;
        if (e[0] == 1)
            for (k = 0; k < 4; ++k) np->base.rotation[k] = mcd_rd_f32(L->consts + 4u * (ri + k));
        else if (e[0] == 2)
            np->rot_track = (int32_t)ri;
        if (e[1] == 1)
            for (k = 0; k < 3; ++k) np->base.translation[k] = mcd_rd_f32(L->consts + 4u * (ti + k));
        else if (e[1] == 2)
            np->trans_track = (int32_t)ti;
    }
    for (k = 0; k < WALK_SLOTS; ++k) ((walk_header*)(s->walks + (size_t)k * walk_slot_size(L->tracks)))->valid = 0;
}

static void track_value(const layout* L, views* s, uint32_t u, float x, float out[4]) {
    track_state* ts = &s->tracks[u];
    float last = (float)(L->frames - 1u);
    /* Sequential playback: reuse the window while x stays in it, slide it a few keys
     * forward when x moves on; anything else is a random access. */
    if (ts->valid && x >= ts->t[1] && x <= ts->t[3]) {
        int steps = 0;
        while ((x > ts->t[2] || (x == ts->t[2] && x < last)) && steps < 2 && ts->t[3] > ts->t[2]) {
            advance(L, s, u);
            ++steps;
        }
        if (x > ts->t[2] || (x == ts->t[2] && x < last)) {
            locate(L, s, u, x);
            segment_coefficients(ts);
        } else if (steps) {
            segment_coefficients(ts);
        }
    } else {
        locate(L, s, u, x);
        segment_coefficients(ts);
    }
    eval_track(ts, x, out);
}

static void spline_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                          int fresh) {
    layout L;
    views s;
    uint32_t i;
    (void)flags;
    read_layout(v->payload, &L);
    scratch_views(scratch, L.nodes, L.tracks, &s);
    for (i = 0; i < WALK_SLOTS; ++i) s.resolved_block[i] = UINT32_MAX;
    if (fresh) prepare(&L, v, &s);
    for (i = 0; i < L.nodes; ++i) {
        const node_plan* np = &s.plans[i];
        out[i] = np->base;
        if (np->rot_track >= 0) {
            const track_state* ts = &s.tracks[np->rot_track];
            float val[4];
            track_value(&L, &s, (uint32_t)np->rot_track, x, val);
            mcd_store_track_rotation(ts->kind, &ts->ref, ts->axis, val, out[i].rotation);
        }
        if (np->trans_track >= 0) {
            float val[4];
            track_value(&L, &s, (uint32_t)np->trans_track, x, val);
            out[i].translation[0] = val[0];
            out[i].translation[1] = val[1];
            out[i].translation[2] = val[2];
        }
    }
}

const mcd_codec_ops mcd_codec_spline_ops = {
    MCD_CODEC_SPLINE, 0x4E4C5053u /* "SPLN" */, 1u, NULL, spline_validate, spline_scratch_size, spline_sample};
