/* Prototype sampler of the RMAL version 3 candidate "frame blocks" (docs/RMAL_V3_STUDY.md), for
 * instruction counts only: it reads the .v3p file bench/rmal_v3_probe.py --write makes (the
 * rows and records of every track exactly as a v3 payload would hold them, plus each track's
 * descriptor fields in a fixed record) and samples every track's Catmull-Rom curve, rotations
 * to quaternions, the same float operations as runtime_c/src/codec_rma.c (the window, curve,
 * rotation and file code is bench/rmal_v3_shared.h, shared with bench/rmal_v3_eb.c). Build with
 * -Iruntime_c/include -Iruntime_c/src and link the runtime (its curve.c).
 *
 *   rmal_v3_proto FILE.v3p MODE        MODE 0 every frame in order, 1 uniform random times,
 *                                       2 every other frame (same sequence as bench/rmal_v3_poses.c),
 *                                       3 load only
 *   rmal_v3_check FILE.v3p ASSET.mcd   (built with -DRMAL_V3_CHECK) compares every animated
 *                                       track, bit for bit, with mcd_sample
 *
 * Not the codec: no validation (the file is trusted), no MCD_SAMPLE_* flags. */
#define RMAL_V3_PART 1
#include "rmal_v3_shared.h"
#undef RMAL_V3_PART

/* ------------------------------------------------------------------ layout */
typedef struct track {
    const uint8_t *table, *data;
    uint32_t keys, rows, row_bits, offset_bits, head_bits, anchor_bits, nmask, wkeep[4];
    uint64_t omask;
    uint8_t b, tmode, knot, nbits; /* knot: the predictor, 0 for, 1 knot, 2 prev */
    uint8_t abits[4], kshift[4];
    RMAL_V3_TRACK_DESC
} track;

/* A block's row: key count, key-time field width, data offset, widths and anchors (and the
 * next row's anchors for a knot predictor). */
typedef struct row {
    uint32_t e, n, gw, tbits, rec, at; /* at: bit of the first record */
    uint32_t off;
    uint8_t w[4], sh[4];
    uint64_t mask[4]; /* (1 << w) - 1 */
    int64_t a0[4], da[4];
    uint32_t cr;      /* prev predictor: the rank whose value cq holds (the running sum) */
    int64_t cq[4];
} row;

static void anchors(const track* t, uint32_t e, int64_t a[4]) {
    uint64_t bit = (uint64_t)e * t->row_bits + t->head_bits, w;
    uint32_t c;
    a[3] = 0;
    if (t->anchor_bits <= 57u) { /* one load for every component */
        w = rd64(t->table + (bit >> 3)) >> (bit & 7u);
        for (c = 0; c < t->d; ++c) {
            a[c] = sext(w, t->abits[c]) * ((int64_t)1 << t->kshift[c]);
            w >>= t->abits[c];
        }
        return;
    }
    for (c = 0; c < t->d; ++c) {
        a[c] = sext(bits_at(t->table, bit, t->abits[c]), t->abits[c]) * ((int64_t)1 << t->kshift[c]);
        bit += t->abits[c];
    }
}

static void load_row(const track* t, uint32_t e, row* R) {
    uint64_t bit = (uint64_t)e * t->row_bits;
    uint64_t h = rd64(t->table + (bit >> 3)) >> (bit & 7u); /* head: <= 57 bits */
    uint32_t c, at = 0;
    R->e = e;
    R->n = (uint32_t)h & t->nmask;
    h >>= t->nbits;
    R->gw = (uint32_t)h & (t->tmode ? 15u : 0u);
    h >>= 4u * t->tmode;
    R->off = (uint32_t)(h & t->omask);
    h >>= t->offset_bits;
    for (c = 0; c < 4u; ++c) { /* widths past the track's are 0 (the field is masked to d) */
        uint32_t w = (uint32_t)(h >> (5u * c)) & 31u & t->wkeep[c];
        R->w[c] = (uint8_t)w;
        R->sh[c] = (uint8_t)at;
        R->mask[c] = ((uint64_t)1 << w) - 1u;
        at += w;
    }
    R->rec = at;
    R->tbits = t->tmode ? R->n * R->gw : (R->n ? 1u << t->b : 0u);
    R->at = R->off + R->tbits;
    anchors(t, e, R->a0);
    if (t->knot == 2u) {
        R->cr = 0;
        memcpy(R->cq, R->a0, sizeof R->cq);
    } else if (t->knot == 1u) {
        int64_t a1[4];
        anchors(t, e + 1u, a1);
        for (c = 0; c < 4u; ++c) R->da[c] = a1[c] - R->a0[c];
    }
}

/* Key r of the row's block, at offset o in the block: its lattice integers (components past
 * the track's: 0). D is a constant in each caller's copy, so the component loops unroll. */
static inline void key_q_d(const track* t, const row* R, uint32_t r, uint32_t o, int64_t q[4], uint32_t D) {
    uint32_t bit = R->at + r * R->rec, c;
    uint64_t w = rd64(t->data + (bit >> 3)) >> (bit & 7u);
    q[3] = 0;
    if (t->knot == 1u) {
        for (c = 0; c < D; ++c) {
            int64_t res = R->w[c] ? sext(w >> R->sh[c], R->w[c]) : 0;
            q[c] = R->a0[c] + ((R->da[c] * (int64_t)o) >> t->b) + res; /* floor of the chord */
        }
    } else {
        for (c = 0; c < D; ++c) q[c] = R->a0[c] + (int64_t)((w >> R->sh[c]) & R->mask[c]);
    }
}

/* prev predictor: key r is the anchor plus the differences of records 0 ... r - 1 (key 0 has
 * none); the row keeps the last sum, so keys read in order cost one record each. */
static inline void key_prev_d(const track* t, row* R, uint32_t r, int64_t q[4], uint32_t D) {
    uint32_t c;
    if (r < R->cr) {
        R->cr = 0;
        memcpy(R->cq, R->a0, sizeof R->cq);
    }
    while (R->cr < r) {
        uint32_t bit = R->at + R->cr * R->rec;
        uint64_t w = rd64(t->data + (bit >> 3)) >> (bit & 7u);
        for (c = 0; c < D; ++c) R->cq[c] += R->w[c] ? sext(w >> R->sh[c], R->w[c]) : 0;
        R->cr++;
    }
    memcpy(q, R->cq, sizeof R->cq);
}

static void key_q(const track* t, const row* R, uint32_t r, uint32_t o, int64_t q[4]) {
    if (t->knot == 2u) { /* the running sum lives in the row: a cache, not the row's fields */
        if (t->d == 3u)
            key_prev_d(t, (row*)R, r, q, 3u);
        else
            key_prev_d(t, (row*)R, r, q, 4u);
        return;
    }
    if (t->d == 3u)
        key_q_d(t, R, r, o, q, 3u);
    else
        key_q_d(t, R, r, o, q, 4u);
}

/* A position in the key sequence: block, rank, frame offset in the block, and the bit of the
 * next key-time field (gaps) or the mask (mask mode). */
typedef struct cursor {
    row R;
    uint32_t r, o, tbit;
    uint64_t mask;
} cursor;
typedef cursor lstate; /* the window's slot 3 key */

static uint64_t block_mask(const track* t, const row* R) {
    uint32_t B = 1u << t->b;
    uint64_t m = bits_at(t->data, R->off, B < 32u ? B : 32u);
    if (B > 32u) m |= bits_at(t->data, R->off + 32u, B - 32u) << 32;
    return m;
}

/* The first key at or after block e (one always is: the last key ends the last block). */
static void first_from(const track* t, uint32_t e, cursor* k) {
    load_row(t, e, &k->R);
    while (k->R.n == 0) load_row(t, ++e, &k->R);
    k->r = 0;
    if (t->tmode) {
        k->o = (uint32_t)bits_at(t->data, k->R.off, k->R.gw);
        k->tbit = k->R.off + k->R.gw;
    } else {
        k->mask = block_mask(t, &k->R);
        k->o = (uint32_t)__builtin_ctzll(k->mask);
    }
}

/* The next key; 0 past the last. */
static int next_key(const track* t, cursor* k) {
    if (k->r + 1u < k->R.n) {
        k->r++;
        if (t->tmode) {
            k->o += 1u + (uint32_t)bits_at(t->data, k->tbit, k->R.gw);
            k->tbit += k->R.gw;
        } else {
            uint64_t m = k->mask & ~((((uint64_t)2) << k->o) - 1u);
            if (k->o == 63u) m = 0;
            k->o = (uint32_t)__builtin_ctzll(m);
        }
        return 1;
    }
    if (k->R.e + 1u >= (t->frames - 1u) / (1u << t->b) + 1u) return 0;
    first_from(t, k->R.e + 1u, k);
    return 1;
}

static uint32_t key_frame(const track* t, const cursor* k) {
    return (k->R.e << t->b) + k->o;
}

#define RMAL_V3_PART 2
#include "rmal_v3_shared.h"
#undef RMAL_V3_PART

/* The keys of a block around offset o (o = -1: before the block's first key): how many are at
 * or before o, the offsets of the last two of those (lo[1] the last) and of the first two
 * after (hi[0] the first), and how many after it found (at most 2). */
static uint32_t scan_block(const track* t, const row* R, int32_t o, uint32_t lo[2], uint32_t hi[2], uint32_t* after) {
    uint32_t n = 0, a = 0;
    if (R->n == 0) {
        *after = 0;
        return 0;
    }
    if (t->tmode) { /* gaps: a running sum over the fields, refilled from one load */
        uint32_t gw = R->gw, bit = R->off, left = 0, m = (1u << gw) - 1u, r, f = 0;
        uint64_t w = 0;
        for (r = 0; r < R->n && a < 2u; ++r) {
            if (left < gw) {
                w = rd64(t->data + (bit >> 3)) >> (bit & 7u);
                left = 57u;
            }
            f = (r ? f + 1u : 0u) + ((uint32_t)w & m);
            w >>= gw, left -= gw, bit += gw;
            if ((int32_t)f <= o) {
                lo[0] = lo[1], lo[1] = f, ++n;
            } else {
                hi[a++] = f;
            }
        }
    } else { /* mask: bit scans */
        uint64_t mask = block_mask(t, R), le = o < 0 ? 0 : o >= 63 ? mask : mask & ((((uint64_t)2) << o) - 1u), gt = mask & ~le;
        n = (uint32_t)__builtin_popcountll(le);
        if (n) lo[1] = 63u - (uint32_t)__builtin_clzll(le);
        if (n > 1u) lo[0] = 63u - (uint32_t)__builtin_clzll(le & ~((uint64_t)1 << lo[1]));
        if (gt) hi[a++] = (uint32_t)__builtin_ctzll(gt), gt &= gt - 1u;
        if (gt) hi[a++] = (uint32_t)__builtin_ctzll(gt);
    }
    *after = a;
    return n;
}

/* A key found by a scan: its block's row, rank in the block and offset. */
typedef struct kref {
    const row* R;
    uint32_t r, o;
} kref;

/* Random access: the window around frame position x from x's block's row and key times, and
 * the neighbouring blocks' when the window crosses an edge (keys are sparse at the block's
 * ends only). */
static void locate(const track* t, state* s, float x) {
    uint32_t xi = (uint32_t)x, e, o, n, after, lo[2] = {0, 0}, hi[2] = {0, 0}, slot, used = 1;
    uint32_t blocks = (t->frames - 1u) / (1u << t->b) + 1u, have = 0;
    row rows[5]; /* x's block, and up to two before and two after it that the window reaches */
    kref k[4], before[2];
    if (xi >= t->frames - 1u) xi = t->frames - 2u; /* the last frame: the segment before it */
    e = xi >> t->b;
    o = xi & ((1u << t->b) - 1u);
    load_row(t, e, &rows[0]);
    n = scan_block(t, &rows[0], (int32_t)o, lo, hi, &after);
    /* Keys i - 1 and i (before[1] = key i): x's block, else the last keys of the blocks before. */
    if (n >= 1u) before[1].R = &rows[0], before[1].r = n - 1u, before[1].o = lo[1], have = 1;
    if (n >= 2u) before[0].R = &rows[0], before[0].r = n - 2u, before[0].o = lo[0], have = 2;
    {
        uint32_t pb = e;
        while (have < 2u && pb > 0) {
            uint32_t l2[2] = {0, 0}, h2[2], a2, got;
            row* R = &rows[used];
            load_row(t, --pb, R);
            got = scan_block(t, R, (int32_t)(1u << t->b) - 1, l2, h2, &a2);
            if (!got) continue;
            ++used;
            if (have == 1u) {
                before[0].R = R, before[0].r = got - 1u, before[0].o = l2[1], have = 2;
            } else {
                before[1].R = R, before[1].r = got - 1u, before[1].o = l2[1], have = 1;
                if (got >= 2u) before[0].R = R, before[0].r = got - 2u, before[0].o = l2[0], have = 2;
            }
        }
    }
    /* key i is always found (key 0 is frame 0); have < 2: key i is key 0 */
    k[1] = before[1];
    if (have == 2u) k[0] = before[0];
    /* Keys i + 1 and i + 2: x's block, else the first keys of the blocks after it. */
    if (after >= 1u) k[2].R = &rows[0], k[2].r = n, k[2].o = hi[0];
    if (after >= 2u) k[3].R = &rows[0], k[3].r = n + 1u, k[3].o = hi[1];
    {
        uint32_t nb = e, m = after;
        while (m < 2u && nb + 1u < blocks) {
            uint32_t l2[2], h2[2] = {0, 0}, a2;
            row* R = &rows[used];
            load_row(t, ++nb, R);
            scan_block(t, R, -1, l2, h2, &a2);
            if (!a2) continue;
            ++used;
            if (m == 0u) {
                k[2].R = R, k[2].r = 0, k[2].o = h2[0], m = 1;
                if (a2 >= 2u) k[3].R = R, k[3].r = 1, k[3].o = h2[1], m = 2;
            } else {
                k[3].R = R, k[3].r = 0, k[3].o = h2[0], m = 2;
            }
        }
        s->at_end = m < 2u; /* key i + 1 is the last key */
    }
    for (slot = have == 2u ? 0u : 1u; slot < (s->at_end ? 3u : 4u); ++slot) {
        int64_t q[4];
        key_q(t, k[slot].R, k[slot].r, k[slot].o, q);
        put_key(t, s, slot, (k[slot].R->e << t->b) + k[slot].o, q);
    }
    /* Slot 3's key as a cursor, for playback onwards (at the end: never read). */
    if (!s->at_end) {
        cursor* q = &s->L;
        q->R = *k[3].R;
        q->r = k[3].r;
        q->o = k[3].o;
        if (t->tmode)
            q->tbit = q->R.off + (q->r + 1u) * q->R.gw;
        else
            q->mask = block_mask(t, &q->R);
    }
    close_window(t, s, have);
}

/* Playback one key on: slot 3 becomes the key after it; 0 past the last key. */
static int next_slot3(const track* t, state* s) {
    int64_t q[4];
    if (!next_key(t, &s->L)) return 0;
    key_q(t, &s->L.R, s->L.r, s->L.o, q);
    put_key(t, s, 3, key_frame(t, &s->L), q);
    return 1;
}

#define RMAL_V3_MAGIC "V3P1"
/* A record's layout bytes: 3 block shift, 4 time mode, 5 predictor, 7 count bits, 12 keys,
 * 16 rows, 20 row bits, 24 offset bits, 28 table and 32 data offsets in the blob, 36 anchor
 * bits, 40 anchor shifts. */
static void load_track(track* t, const uint8_t* r, const uint8_t* blob) {
    uint32_t k;
    t->b = r[3], t->tmode = r[4], t->knot = r[5], t->nbits = r[7];
    t->keys = rd32(r + 12), t->rows = rd32(r + 16), t->row_bits = rd32(r + 20), t->offset_bits = rd32(r + 24);
    t->table = blob + rd32(r + 28);
    t->data = blob + rd32(r + 32);
    memcpy(t->abits, r + 36, 4);
    memcpy(t->kshift, r + 40, 4);
    t->head_bits = t->nbits + 4u * t->tmode + t->offset_bits + 5u * t->d;
    t->anchor_bits = t->abits[0] + t->abits[1] + t->abits[2] + t->abits[3];
    t->nmask = (1u << t->nbits) - 1u;
    t->omask = ((uint64_t)1 << t->offset_bits) - 1u;
    for (k = 0; k < 4u; ++k) t->wkeep[k] = k < t->d ? 31u : 0u;
}

#define RMAL_V3_PART 3
#include "rmal_v3_shared.h"
#undef RMAL_V3_PART
