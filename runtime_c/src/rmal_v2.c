/* RMAL version 2 payloads: per-track Catmull-Rom keys, sampled in place from the asset's bytes
 * (docs/FORMAT.md, RMAL version 2): what codec `rma` wrote before version 3, and what codec
 * `rma-pca`'s curve sets are. The payload around the tracks and the window's curve are
 * rmal_payload.c's.
 *
 * Every part of a track is read directly. Key times: cells of frames in unary (a one per key,
 * a zero closing each cell) with a rank entry every 64 cells, so the key at or before a frame
 * is a rank entry and a popcount or two away and its neighbours the next ones. Key values: groups of G keys; a group's row holds its first key whole (the
 * anchor), its records' bit offset and widths, and each other key is one fixed-width record,
 * its residual from the chord between the group's anchor and the next, so any key's value is
 * one read (an escaped residual, rare, a short walk to its outlier). A random access reads the
 * four keys around x; sequential playback keeps them in the scratch and reads one key per key
 * interval, and a step forward of up to three keys (a game tick) reads just those keys. */
#include <string.h>

#include "rmal_payload.h"

#define MAX_GROUP_SHIFT 6u
#define RANK_SHIFT 6u /* a rank entry every 64 cells */
#define WIDTH_BITS 4u /* a record field's width, 0 ... 15 */

/* ---------------------------------------------------------------- payload layout */
/* Everything about one track that its descriptor and the clip's frame count give. Offsets
 * are bytes from the start of the payload. */
typedef struct track_layout {
    uint8_t kind, dims, split, cell_shift, group_shift, offset_bits, rank_bits, in_cell_bits;
    uint8_t abits[4], anchor_bits, reserved[3]; /* anchor_bits: the sum of abits */
    uint32_t keys, frames;
    uint32_t cells, words;          /* key cells (the last is the last frame's), unary words */
    uint32_t rows, row_bits;        /* group table: one row per group, and one for the last anchor */
    uint32_t data_bytes;
    float step[4];
    uint32_t bitmap, rank, places, table, data, end;
} track_layout;

/* The layout of a track whose descriptor is at `d` and whose data starts at byte `at`;
 * checks what the descriptor alone shows and that the parts fit before `limit`. */
static mcd_result track_geometry(const uint8_t* d, uint32_t frames, uint32_t at, uint32_t limit, track_layout* t) {
    uint32_t c;
    uint64_t end, row;
    mcd_rmal_desc D;
    mcd_result r = mcd_rmal_parse_desc(d, frames, &D);
    if (r != MCD_OK) return r;
    t->kind = (uint8_t)D.kind;
    t->dims = (uint8_t)D.dims;
    t->split = (uint8_t)D.split;
    /* Byte 1: key cells of 2^(bits 1-2) frames, groups of 2^(bits 3-5) keys. */
    t->cell_shift = (d[1] >> 1) & 3u;
    t->group_shift = (d[1] >> 3) & 7u;
    t->offset_bits = (uint8_t)D.offset_bits;
    t->in_cell_bits = d[3];
    t->keys = D.keys;
    t->data_bytes = D.data_bytes;
    t->frames = frames;
    if ((d[1] >> 6) || t->group_shift < 1 || t->group_shift > MAX_GROUP_SHIFT) return MCD_ERROR_MALFORMED;
    /* Byte 3: bits of each key's place in its cell (0, or the cell shift when some key is
     * off its cell's first frame). */
    if (t->in_cell_bits && t->in_cell_bits != t->cell_shift) return MCD_ERROR_MALFORMED;
    /* Cells: frame 0, frames 1 ... F - 2 in cells of 2^s, the last frame. */
    t->cells = frames > 1u ? ((frames - 2u + (1u << t->cell_shift) - 1u) >> t->cell_shift) + 2u : 1u;
    t->words = (uint32_t)(((uint64_t)t->keys + t->cells + 63u) / 64u);
    t->rank_bits = (uint8_t)mcd_rmal_bits_for(t->keys);
    t->rows = ((t->keys - 1u + (1u << t->group_shift) - 1u) >> t->group_shift) + 1u;
    t->anchor_bits = (uint8_t)D.anchor_bits;
    t->reserved[0] = t->reserved[1] = t->reserved[2] = 0;
    for (c = 0; c < 4; ++c) {
        t->abits[c] = D.abits[c];
        t->step[c] = D.step[c];
    }
    row = t->offset_bits + (uint64_t)WIDTH_BITS * t->dims + t->anchor_bits;
    t->row_bits = (uint32_t)row;
    t->bitmap = at;
    end = at + 8u * (uint64_t)t->words;
    t->rank = (uint32_t)(end > limit ? limit : end);
    end += mcd_rmal_packed_bytes((t->cells + 63u) / 64u, t->rank_bits);
    t->places = (uint32_t)(end > limit ? limit : end);
    end += mcd_rmal_packed_bytes(t->in_cell_bits ? t->keys : 0u, t->in_cell_bits);
    t->table = (uint32_t)(end > limit ? limit : end);
    end += mcd_rmal_packed_bytes(t->rows, t->row_bits);
    t->data = (uint32_t)(end > limit ? limit : end);
    end += t->data_bytes;
    if (end > limit) return MCD_ERROR_MALFORMED;
    t->end = (uint32_t)end;
    return MCD_OK;
}

/* ---------------------------------------------------------------- key times */
static uint64_t bitmap_word(const uint8_t* p, const track_layout* t, uint32_t w) {
    return mcd_rd_u64(p + t->bitmap + 8u * (size_t)w);
}

/* The cell of frame f (0 ... F - 1), and the frame a key in cell c sits on. */
static uint32_t cell_of(const track_layout* t, uint32_t f) {
    if (f == 0) return 0;
    if (f >= t->frames - 1u) return t->cells - 1u;
    return ((f - 1u) >> t->cell_shift) + 1u;
}

static uint32_t cell_frame(const track_layout* t, uint32_t c) {
    /* Without branches (random access meets every case): the last cell's formula start is at or
     * past the last frame, every other cell's before it. */
    uint32_t f = 1u + ((c - 1u) << t->cell_shift);
    f = f < t->frames - 1u ? f : t->frames - 1u;
    return c ? f : 0u;
}

/* The frame of key k, whose cell is c. */
static uint32_t key_frame(const uint8_t* p, const track_layout* t, uint32_t k, uint32_t c) {
    uint32_t f = cell_frame(t, c);
    return t->in_cell_bits ? f + mcd_read_bits(p + t->places, (uint64_t)k * t->in_cell_bits, t->in_cell_bits) : f;
}

/* The positions of the set bits of a nibble, two bits each from the lowest. */
static const uint8_t nibble_select[16] = {0x00, 0x00, 0x01, 0x04, 0x02, 0x08, 0x09, 0x24,
                                          0x03, 0x0C, 0x0D, 0x34, 0x0E, 0x38, 0x39, 0xE4};

/* The r-th set bit (from 0) of x, which has more than r. Without data-dependent branches (a
 * random access's select is unpredictable): the byte from running counts of every byte at
 * once, then the nibble and a table. */
static uint32_t select_in_word(uint64_t x, uint32_t r) {
    const uint64_t ones = 0x0101010101010101u, highs = 0x8080808080808080u;
    uint64_t s = x - ((x >> 1) & 0x5555555555555555u), at_most;
    uint32_t byte, b, low, nib;
    s = (s & 0x3333333333333333u) + ((s >> 2) & 0x3333333333333333u);
    s = ((s + (s >> 4)) & 0x0F0F0F0F0F0F0F0Fu) * ones; /* byte k: the set bits of bytes 0 ... k */
    at_most = ((((uint64_t)r * ones) | highs) - s) & highs; /* bytes whose count is at most r */
    byte = mcd_popcount(at_most);                           /* counts rise: the first byte past r */
    r -= (uint32_t)((s << 8) >> (8u * byte)) & 0xFFu;      /* the bytes below it */
    b = (uint32_t)(x >> (8u * byte)) & 0xFFu;
    low = mcd_popcount(b & 15u);
    nib = r >= low ? 4u : 0u;
    r -= r >= low ? low : 0u;
    return 8u * byte + nib + ((nibble_select[(b >> nib) & 15u] >> (2u * r)) & 3u);
}

/* The bit of the zero that closes cell c: from the start of c's 64-cell block (its cells and
 * keys before it), the (c mod 64)-th zero on. The word bound only matters for bytes never
 * validated. */
static uint32_t cell_end(const uint8_t* p, const track_layout* t, uint32_t c) {
    uint32_t r = c & 63u, n, w;
    uint32_t pos = (c & ~63u) + mcd_read_bits(p + t->rank, (uint64_t)(c >> RANK_SHIFT) * t->rank_bits, t->rank_bits);
    uint64_t x;
    w = pos >> 6;
    if (w >= t->words) return (t->words << 6) - 1u;
    x = ~bitmap_word(p, t, w) & (~(uint64_t)0 << (pos & 63u));
    n = mcd_popcount(x);
    while (n <= r && w + 1u < t->words) {
        r -= n;
        x = ~bitmap_word(p, t, ++w);
        n = mcd_popcount(x);
    }
    return n > r ? (w << 6) + select_in_word(x, r) : (t->words << 6) - 1u;
}

/* The last one below bit u (key 0's is bit 0), the first one above bit u (the last key's is
 * above every other). */
static uint32_t one_before(const uint8_t* p, const track_layout* t, uint32_t u) {
    uint32_t w = u >> 6;
    uint64_t m = bitmap_word(p, t, w) & (((uint64_t)1 << (u & 63u)) - 1u);
    while (!m && w > 0) m = bitmap_word(p, t, --w);
    return m ? (w << 6) + mcd_highest_bit(m) : 0u;
}

static uint32_t one_after(const uint8_t* p, const track_layout* t, uint32_t u) {
    uint32_t w = u >> 6;
    uint64_t m = (u & 63u) == 63u ? 0u : bitmap_word(p, t, w) & (~(uint64_t)0 << ((u & 63u) + 1u));
    while (!m && w + 1u < t->words) m = bitmap_word(p, t, ++w);
    return m ? (w << 6) + mcd_lowest_bit(m) : u;
}

/* 64 unary bits from bit `lo` in one load (the ones around a random access are usually near
 * each other), with the bitmap's end: bits past it are masked off. */
typedef struct bit_window {
    uint64_t w;
    uint32_t lo, end;
} bit_window;

static bit_window window_at(const uint8_t* p, const track_layout* t, uint32_t around) {
    bit_window b;
    uint32_t byte = around > 28u ? (around - 28u) >> 3 : 0u;
    b.lo = byte << 3;
    b.end = t->words << 6;
    b.w = mcd_rd_u64(p + t->bitmap + byte); /* within the payload: its last 8 bytes are padding */
    if (b.end - b.lo < 64u) b.w &= ((uint64_t)1 << (b.end - b.lo)) - 1u;
    return b;
}

/* one_before and one_after, from the window when it holds the answer. */
static uint32_t prev_one(const uint8_t* p, const track_layout* t, const bit_window* b, uint32_t u) {
    uint32_t n = u - b->lo;
    if (u > b->lo && n < 64u) {
        uint64_t m = b->w & (((uint64_t)1 << n) - 1u);
        if (m) return b->lo + mcd_highest_bit(m);
        if (b->lo == 0) return 0;
    }
    return one_before(p, t, u);
}

static uint32_t next_one(const uint8_t* p, const track_layout* t, const bit_window* b, uint32_t u) {
    uint32_t n = u - b->lo + 1u;
    if (u >= b->lo && n < 64u) {
        uint64_t m = b->w & (~(uint64_t)0 << n);
        if (m) return b->lo + mcd_lowest_bit(m);
        if (b->lo + 64u >= b->end) return u;
    }
    return one_after(p, t, u);
}

/* The frame of key k, whose one is at bit u (its cell is u - k). */
static uint32_t key_frame_at(const uint8_t* p, const track_layout* t, uint32_t k, uint32_t u) {
    return key_frame(p, t, k, u - k);
}

/* ---------------------------------------------------------------- key values */
/* One group as its row and the next row's anchor give it. */
typedef struct group_view {
    uint32_t row;         /* the row (group) number; UINT32_MAX: none loaded */
    uint32_t bit;         /* bit offset of its records in the data area */
    uint32_t span;        /* keys from its anchor to the next anchor (0 for the last row) */
    uint32_t rec_bits;    /* bits of one record */
    uint8_t width[4], shift[4];
    int32_t a0[4], d[4];  /* its anchor, and the next one's difference from it */
} group_view;

/* The anchor of row e (the key e * G, or the last key for the last row). */
static void row_anchor(const uint8_t* p, const track_layout* t, uint32_t e, int32_t a[4]) {
    uint64_t bit = (uint64_t)e * t->row_bits + t->offset_bits + WIDTH_BITS * t->dims;
    uint32_t c;
    a[3] = 0;
    if (t->anchor_bits <= 57u) { /* one load for all components */
        uint64_t w = mcd_rd_u64(p + t->table + (size_t)(bit >> 3)) >> (bit & 7u);
        for (c = 0; c < t->dims; ++c) {
            uint32_t n = t->abits[c];
            uint64_t sign = (uint64_t)1 << (n - 1u), u = w & ((sign << 1) - 1u);
            a[c] = (int32_t)((int64_t)(u ^ sign) - (int64_t)sign);
            w >>= n;
        }
        return;
    }
    for (c = 0; c < t->dims; ++c) {
        a[c] = mcd_read_signed(p + t->table, bit, t->abits[c]);
        bit += t->abits[c];
    }
}

static void group_load(const uint8_t* p, const track_layout* t, uint32_t e, group_view* g) {
    const uint8_t* table = p + t->table;
    uint64_t bit = (uint64_t)e * t->row_bits;
    uint64_t head = mcd_rd_u64(table + (size_t)(bit >> 3)) >> (bit & 7u); /* offset and widths: <= 48 bits */
    uint32_t c, at = 0, widths, first = e << t->group_shift;
    g->row = e;
    g->bit = (uint32_t)(head & ((((uint64_t)1) << t->offset_bits) - 1u));
    widths = (uint32_t)(head >> t->offset_bits) & ((1u << (WIDTH_BITS * t->dims)) - 1u); /* 0 past the track's */
    for (c = 0; c < 4u; ++c) {
        uint32_t w = (widths >> (WIDTH_BITS * c)) & 15u;
        g->width[c] = (uint8_t)w;
        g->shift[c] = (uint8_t)at;
        at += w;
    }
    g->rec_bits = at;
    row_anchor(p, t, e, g->a0);
    if (e + 1u < t->rows) {
        int32_t a1[4];
        g->span = t->keys - 1u - first < (1u << t->group_shift) ? t->keys - 1u - first : 1u << t->group_shift;
        row_anchor(p, t, e + 1u, a1);
        for (c = 0; c < 4u; ++c) g->d[c] = a1[c] - g->a0[c]; /* |a| < 2^30 */
    } else {
        g->span = 0;
        memset(g->d, 0, sizeof g->d);
    }
}

/* floor(v / 2^s) for any sign (a right shift of a negative number is implementation-defined
 * in C): the biased value shifted. |v| < 2^37. */
static int64_t floor_shift(int64_t v, uint32_t s) {
    const int64_t bias = (int64_t)1 << 40;
    /* The compiler folds the test: every common one shifts arithmetically, which is floor. */
    return ((int64_t)-1 >> 1) == -1 ? v >> s : (int64_t)((uint64_t)(v + (bias << s)) >> s) - bias;
}

/* floor(v / n), n > 0 (C's division truncates). */
static int64_t floor_div(int64_t v, int64_t n) {
    return v >= 0 ? v / n : -((-v + n - 1) / n);
}

/* A record's fields: bits [bit, bit + rec_bits) of the data area (rec_bits <= 60). */
static uint64_t record_word(const uint8_t* data, const group_view* g, uint32_t bit) {
    uint64_t w = mcd_rd_u64(data + (bit >> 3)) >> (bit & 7u);
    if (g->rec_bits > 57u) w |= mcd_rd_u64(data + (bit >> 3) + 7u) << (56u - (bit & 7u)); /* wide records */
    return w;
}

/* Record i's component c when its field holds the escape code: the outlier, stored whole
 * after the group's records in record and component order, so the escapes before it count. */
MCD_RARE_PATH static int32_t outlier(const uint8_t* data, const track_layout* t, const group_view* g, uint32_t i, uint32_t c) {
    uint32_t at = g->bit + (g->span - 1u) * g->rec_bits, j, k, bit = g->bit, mask[4], code[4];
    uint64_t top = 0, low = 0, below;
    for (k = 0; k < 4u; ++k) {
        mask[k] = ((uint32_t)1 << g->width[k]) - 1u;
        code[k] = g->width[k] ? (mask[k] + 1u) >> 1 : UINT32_MAX; /* width 0: no escape */
        if (g->width[k]) {
            top |= (uint64_t)1 << (g->shift[k] + g->width[k] - 1u);
            low |= (uint64_t)1 << g->shift[k];
        }
    }
    below = top - low; /* each field's bits under its top bit */
    for (j = 1; j <= i; ++j, bit += g->rec_bits) {
        uint64_t w = record_word(data, g, bit), x = w ^ top;
        uint32_t n;
        /* Most records escape nothing: a field is the escape code (its top bit alone) where x
         * is zero, i.e. where the top bit of ((x & below) + below) | x is clear (no carry
         * leaves a field). */
        if (j < i && !(~(((x & below) + below) | x) & top)) continue;
        n = j < i ? t->dims : c;
        for (k = 0; k < n; ++k) {
            at += ((uint32_t)w & mask[k]) == code[k] ? t->abits[k] : 0u;
            w >>= g->width[k];
        }
    }
    return mcd_read_signed(data, at, t->abits[c]);
}

/* Key j's lattice integers (components past the track's: 0), as wide as any bytes make them:
 * in a validated payload every one is within +-2^30 (check_track reads them all). `g` caches
 * the last group read; row e's anchor is also the end of group e - 1. */
static MCD_HOT_INLINE void key_value(const uint8_t* p, const track_layout* t, group_view* g, uint32_t j, int64_t q[4]) {
    uint32_t e = j >> t->group_shift, i = j & ((1u << t->group_shift) - 1u), c, full;
    uint64_t w;
    if (i == 0) { /* an anchor */
        if (g->row == e) {
            for (c = 0; c < 4u; ++c) q[c] = g->a0[c];
        } else if (g->row != UINT32_MAX && g->row + 1u == e) {
            for (c = 0; c < 4u; ++c) q[c] = (int64_t)g->a0[c] + g->d[c];
        } else {
            int32_t a[4];
            row_anchor(p, t, e, a);
            for (c = 0; c < 4u; ++c) q[c] = a[c];
        }
        return;
    }
    if (g->row != e) group_load(p, t, e, g);
    if (i >= g->span) { /* the track's last key: the next anchor */
        for (c = 0; c < 4u; ++c) q[c] = (int64_t)g->a0[c] + g->d[c];
        return;
    }
    w = record_word(p + t->data, g, g->bit + (i - 1u) * g->rec_bits);
    full = g->span == (1u << t->group_shift);
    q[3] = 0;
    for (c = 0; c < t->dims; ++c) {
        uint32_t wc = g->width[c], mask = ((uint32_t)1 << wc) - 1u, sign = (mask + 1u) >> 1, u = (uint32_t)w & mask;
        int64_t v;
        w >>= wc;
        if (u == sign && wc) { /* the escape code (never at width 0): the value is an outlier */
            q[c] = outlier(p + t->data, t, g, i, c);
            continue;
        }
        v = (int64_t)g->d[c] * (int64_t)i;
        q[c] = g->a0[c] + (int64_t)(u ^ sign) - (int64_t)sign +
               (full ? floor_shift(v, t->group_shift) : floor_div(v, (int64_t)g->span));
    }
}

/* key_value out of line, for the callers that read one key at a time (a step forward, the
 * validation): inlined there it only grows their loops. */
static MCD_OUT_OF_LINE void one_key_value(const uint8_t* p, const track_layout* t, group_view* g, uint32_t j, int64_t q[4]) {
    key_value(p, t, g, j, q);
}

/* ---------------------------------------------------------------- sampling state */
/* A track in the scratch: its window and curve (rmal_payload.h), its layout, and the last
 * group read. */
typedef struct track_state {
    mcd_rmal_curve W;
    track_layout L;
    uint32_t u3; /* the unary bit of key min(i + 2, last) */
    uint32_t pad;
    group_view group;
} track_state;

/* The scratch size is part of the format (docs/FORMAT.md, RMAL version 2 "Sampling"): changing
 * this structure is a new section version. Plain 32-bit fields only, so every ABI agrees. */
typedef char track_state_is_348_bytes[sizeof(track_state) == 348u ? 1 : -1];

static size_t rma_scratch_size(const mcd_clip_view* v) {
    return mcd_rmal_scratch_size(v, sizeof(track_state));
}

static void store_key(track_state* ts, uint32_t slot, uint32_t frame, const int64_t q[4]) {
    mcd_rmal_store_key(&ts->W, slot, frame, q, ts->L.step);
}

/* Random access: the segment holding frame position x, its four keys read afresh. */
static void locate(const uint8_t* p, track_state* ts, float x) {
    const track_layout* t = &ts->L;
    uint32_t last = t->keys - 1u, xi = (uint32_t)x, i, c, u[4], s;
    int64_t q[4];
    if (xi > t->frames - 1u) xi = t->frames - 1u;
    bit_window b;
    c = cell_of(t, xi);
    u[1] = cell_end(p, t, c);
    i = u[1] - c - 1u; /* the ones before the zero closing c are the keys in cells up to c */
    b = window_at(p, t, u[1]);
    u[1] = prev_one(p, t, &b, u[1]);
    /* x at the last frame: its segment is the one before. Keys of x's own cell after x (at
     * most a cell's frames; key 0 is frame 0): the key before them. */
    if (i >= last) {
        i = last - 1u;
        u[1] = prev_one(p, t, &b, u[1]);
    }
    while (t->in_cell_bits && i > 0 && key_frame_at(p, t, i, u[1]) > xi) {
        i--;
        u[1] = prev_one(p, t, &b, u[1]);
    }
    u[0] = i > 0 ? prev_one(p, t, &b, u[1]) : u[1];
    u[2] = next_one(p, t, &b, u[1]);
    u[3] = i + 2u <= last ? next_one(p, t, &b, u[2]) : u[2];
    ts->W.i = i;
    ts->u3 = u[3];
    /* Keys i - 1 ... i + 2, ends repeated. */
    for (s = i > 0 ? 0u : 1u; s < 4u && i + s <= last + 1u; ++s) {
        key_value(p, t, &ts->group, i + s - 1u, q);
        store_key(ts, s, key_frame_at(p, t, i + s - 1u, u[s]), q);
    }
    if (i == 0) mcd_rmal_repeat_slot(&ts->W, 0, 1);
    if (i + 2u > last) mcd_rmal_repeat_slot(&ts->W, 3, 2);
    mcd_rmal_set_curve(&ts->W);
}

/* Keys a step forward may read one by one before a fresh locate is cheaper. */
#define MAX_ADVANCE 3u

/* Sequential playback and short steps forward (a game tick moves a few frames): the window
 * moves on by n keys (1 ... MAX_ADVANCE) in one shift, then reads the new last keys, whose
 * unary bits and frames the scan ahead found. One shift, not one a key: a shift reads slots
 * whole, and a key just stored would make it wait for the stores. */
static void advance(const uint8_t* p, track_state* ts, uint32_t n, const uint32_t u[MAX_ADVANCE],
                    const uint32_t f[MAX_ADVANCE]) {
    uint32_t last = ts->L.keys - 1u, k;
    memmove(ts->W.t, ts->W.t + n, (4u - n) * sizeof ts->W.t[0]);
    memmove(ts->W.v[0], ts->W.v[n], (4u - n) * sizeof ts->W.v[0]);
    for (k = 0; k < n; ++k) {
        uint32_t slot = 4u - n + k;
        if (ts->W.i + k + 3u <= last) { /* key i + 2 of the window after k + 1 steps */
            int64_t q[4];
            ts->u3 = u[k];
            one_key_value(p, &ts->L, &ts->group, ts->W.i + k + 3u, q);
            store_key(ts, slot, f[k], q);
        } else {
            mcd_rmal_repeat_slot(&ts->W, slot, slot - 1u);
        }
    }
    ts->W.i += n;
}

/* Frames past the window's last key from which a step forward first asks far_ahead: a game
 * tick moves a frame or two and would only pay for the question. */
#define FAR_FRAMES 8.0f

/* True when x is at or past key i + 1 + MAX_ADVANCE (which is before the last), so that
 * keys_ahead would give up: that key's cell, from the unary bits after the window's last key,
 * ends at or before x. A random jump forward then locates at once instead of reading keys
 * one by one first. */
static int far_ahead(const uint8_t* p, const track_state* ts, float x) {
    uint32_t from = ts->u3 + 1u, byte = from >> 3, k, cell;
    uint64_t w = mcd_rd_u64(p + ts->L.bitmap + byte) >> (from & 7u); /* >= 57 bits from `from` */
    if (ts->L.words * 64u - from < 57u) w &= ((uint64_t)1 << (ts->L.words * 64u - from)) - 1u;
    w &= ((uint64_t)1 << 57) - 1u;
    for (k = 2; k < MAX_ADVANCE; ++k) w &= w - 1u; /* the ones of keys i + 3 ... before it */
    if (!w) return 0;
    cell = from + mcd_lowest_bit(w) - (ts->W.i + 1u + MAX_ADVANCE);
    return cell + 1u < ts->L.cells && (float)cell_frame(&ts->L, cell + 1u) <= x;
}

/* Keys the window moves on for x at or past t_{i+1}: the first n with x < t_{i+1+n} (or
 * t_{i+1+n} the last key), found from the key times alone, with the unary bit and frame of
 * each key the window takes on (past the last key: none); 0 when more than MAX_ADVANCE. */
static uint32_t keys_ahead(const uint8_t* p, const track_state* ts, float x, uint32_t u[MAX_ADVANCE],
                           uint32_t f[MAX_ADVANCE]) {
    uint32_t n, k = ts->W.i + 2u, at = ts->u3, last = ts->L.keys - 1u;
    if (x >= ts->W.t[3] + FAR_FRAMES && ts->W.i + 1u + MAX_ADVANCE < last && far_ahead(p, ts, x)) return 0;
    for (n = 1; n <= MAX_ADVANCE; ++n) {
        if (k < last) { /* key k + 1, the window's new last key */
            at = one_after(p, &ts->L, at);
            u[n - 1u] = at;
            f[n - 1u] = key_frame_at(p, &ts->L, ++k, at);
        } else { /* unread: the window repeats the last key */
            u[n - 1u] = at;
            f[n - 1u] = 0;
        }
        /* The segment's end is now key i + 1 + n. */
        if (ts->W.i + 1u + n >= last || x < (n == 1u ? ts->W.t[3] : (float)f[n - 2u])) return n;
    }
    return 0;
}

/* The curve of one track at x: the cached segment, a few keys on from it, or a fresh locate.
 * Either way the window is the four keys around x's segment, so the curve is the same bits. */
static void track_value(const uint8_t* p, mcd_rmal_curve* w, float x, float out[4]) {
    track_state* ts = (track_state*)w;
    uint32_t c, n, last = ts->L.keys - 1u, u[MAX_ADVANCE], f[MAX_ADVANCE];
    if (last == 0) { /* a one-frame clip */
        for (c = 0; c < ts->L.dims; ++c) out[c] = ts->W.v[0][c];
        return;
    }
    if (!ts->W.valid || x < ts->W.t1) {
        locate(p, ts, x);
    } else if (x >= ts->W.t2 && ts->W.i + 1u < last) { /* x = the last key is the last segment's */
        n = keys_ahead(p, ts, x, u, f);
        if (n == 0) {
            locate(p, ts, x);
        } else {
            advance(p, ts, n, u, f);
            mcd_rmal_set_curve(&ts->W);
        }
    }
    mcd_rmal_eval(&ts->W, x, out);
}

/* A track's state from its validated descriptor (rmal_payload.h). */
static uint32_t init_track(const uint8_t* p, const uint8_t* d, uint32_t frames, uint32_t at, uint32_t limit,
                           mcd_rmal_curve* w) {
    track_state* ts = (track_state*)w;
    track_geometry(d, frames, at, limit, &ts->L); /* validated: cannot fail */
    ts->group.row = UINT32_MAX;
    if (ts->L.keys == 1u) { /* one frame: the single key is row 0's anchor */
        int64_t q[4];
        key_value(p, &ts->L, &ts->group, 0, q);
        store_key(ts, 0, 0, q);
    }
    return ts->L.end;
}

static void rma_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                       int fresh) {
    (void)flags;
    mcd_rmal_sample(v, x, out, scratch, fresh, sizeof(track_state), init_track, track_value);
}

/* ---------------------------------------------------------------- validation */
/* Every rule of one track's bitmap, rank table, group table and records, reading every key. */
static mcd_result check_track(const uint8_t* p, const track_layout* t) {
    uint64_t total = 0, data_bits = 8u * (uint64_t)t->data_bytes, bits;
    uint32_t b, e, c, j;
    group_view g;
    /* Key times: K ones and NC zeros, zero bits after them; key 0 alone in cell 0, the last
     * key alone in the last cell; frames increasing, interior keys before the last frame; each
     * rank entry the keys in the cells below its block. */
    {
        uint64_t n = (uint64_t)t->keys + t->cells, bit;
        uint32_t k = 0, cell = 0, last_frame = 0, in_cell = 0;
        if (!mcd_rmal_zero_bits(p + t->bitmap, n, 64u * (uint64_t)t->words)) return MCD_ERROR_MALFORMED;
        for (bit = 0; bit < n; ++bit) {
            if ((cell & 63u) == 0 && in_cell == 0 &&
                mcd_read_bits(p + t->rank, (uint64_t)(cell >> RANK_SHIFT) * t->rank_bits, t->rank_bits) != k)
                return MCD_ERROR_MALFORMED;
            if ((bitmap_word(p, t, (uint32_t)(bit >> 6)) >> (bit & 63u)) & 1u) {
                uint32_t f;
                if (k >= t->keys || cell >= t->cells) return MCD_ERROR_MALFORMED;
                f = key_frame(p, t, k, cell);
                if (cell == 0 || cell == t->cells - 1u) {
                    if (in_cell || f != cell_frame(t, cell)) return MCD_ERROR_MALFORMED;
                } else if (f > t->frames - 2u) {
                    return MCD_ERROR_MALFORMED;
                }
                if (k > 0 && f <= last_frame) return MCD_ERROR_MALFORMED;
                last_frame = f;
                k++;
                in_cell++;
            } else {
                if (cell >= t->cells || (cell == 0 && k != 1u)) return MCD_ERROR_MALFORMED;
                cell++;
                in_cell = 0;
            }
        }
        if (k != t->keys || cell != t->cells) return MCD_ERROR_MALFORMED;
        /* The last cell holds exactly the last key: "0 1 0" ends the bits (or "1 0" alone). */
        if (t->cells > 1u && (!((bitmap_word(p, t, (uint32_t)((n - 2u) >> 6)) >> ((n - 2u) & 63u)) & 1u) ||
                              ((bitmap_word(p, t, (uint32_t)((n - 3u) >> 6)) >> ((n - 3u) & 63u)) & 1u)))
            return MCD_ERROR_MALFORMED;
    }
    if (!mcd_rmal_zero_bits(p + t->rank, (uint64_t)((t->cells + 63u) / 64u) * t->rank_bits,
                   8u * mcd_rmal_packed_bytes((t->cells + 63u) / 64u, t->rank_bits)))
        return MCD_ERROR_MALFORMED;
    if (!mcd_rmal_zero_bits(p + t->table, (uint64_t)t->rows * t->row_bits, 8u * mcd_rmal_packed_bytes(t->rows, t->row_bits)))
        return MCD_ERROR_MALFORMED;
    if (t->in_cell_bits &&
        !mcd_rmal_zero_bits(p + t->places, (uint64_t)t->keys * t->in_cell_bits, 8u * mcd_rmal_packed_bytes(t->keys, t->in_cell_bits)))
        return MCD_ERROR_MALFORMED;
    /* Groups back to back from bit 0, each its records then its outliers; the last row
     * (the last anchor) marks the end and has widths 0. */
    for (e = 0; e < t->rows; ++e) {
        group_load(p, t, e, &g);
        if (g.bit != total) return MCD_ERROR_MALFORMED;
        if (e + 1u == t->rows) {
            if (g.rec_bits) return MCD_ERROR_MALFORMED;
            break;
        }
        bits = (uint64_t)(g.span - 1u) * g.rec_bits;
        if (total + bits > data_bits) return MCD_ERROR_MALFORMED;
        for (j = 1; j < g.span; ++j)
            for (c = 0; c < t->dims; ++c)
                if (g.width[c] && mcd_read_bits(p + t->data, total + (uint64_t)(j - 1u) * g.rec_bits + g.shift[c], g.width[c]) ==
                                      (uint32_t)1 << (g.width[c] - 1u))
                    bits += t->abits[c];
        total += bits;
        if (total > data_bits) return MCD_ERROR_MALFORMED;
    }
    /* The data area ends after the last group, zero-padded to a multiple of 4 bytes. */
    if (t->data_bytes != mcd_align4((size_t)((total + 7u) / 8u))) return MCD_ERROR_MALFORMED;
    if (!mcd_rmal_zero_bits(p + t->data, total, data_bits)) return MCD_ERROR_MALFORMED;
    /* Every key's value within range. */
    g.row = UINT32_MAX;
    for (b = 0; b < t->keys; ++b) {
        int64_t q[4];
        one_key_value(p, t, &g, b, q);
        for (c = 0; c < t->dims; ++c) {
            if (q[c] >= MCD_RMAL_MAX_Q || q[c] <= -MCD_RMAL_MAX_Q) return MCD_ERROR_MALFORMED;
            if (!mcd_in_bounds((float)((double)q[c] * (double)t->step[c]))) return MCD_ERROR_MALFORMED;
        }
    }
    return MCD_OK;
}

/* One track: its layout within [at, limit), then every rule of its data (rmal_payload.h). */
static mcd_result check_one(const uint8_t* p, const uint8_t* desc, uint32_t frames, uint32_t at, uint32_t limit,
                            uint32_t* end) {
    track_layout t;
    mcd_result r = track_geometry(desc, frames, at, limit, &t);
    if (r != MCD_OK) return r;
    *end = t.end;
    return check_track(p, &t);
}

static mcd_result rma_validate(const mcd_clip_view* v) {
    return mcd_rmal_validate_payload(v, check_one);
}

const mcd_codec_ops mcd_codec_rma_v2_ops = {MCD_CODEC_RMA, 0x4C414D52u /* "RMAL" */, 2u, mcd_rmal_validate_section,
                                            rma_validate, rma_scratch_size, rma_sample};
