/* Prototype sampler of the RMAL version 3 candidate "frame blocks" (docs/RMAL_V3_STUDY.md), for
 * instruction counts only: it reads the .v3p file bench/rmal_v3_probe.py --write makes (the
 * rows and records of every track exactly as a v3 payload would hold them, plus each track's
 * descriptor fields in a fixed record) and samples every track's Catmull-Rom curve, rotations
 * to quaternions, the same float operations as runtime_c/src/codec_rma.c.
 *
 *   rmal_v3_proto FILE.v3p MODE        MODE 0 every frame in order, 1 uniform random times,
 *                                       2 every other frame (same sequence as /tmp/ps/once.c)
 *   rmal_v3_check FILE.v3p ASSET.mcd   (built with -DRMAL_V3_CHECK and the runtime) compares
 *                                       every animated track, bit for bit, with mcd_sample
 *
 * Not the codec: no validation (the file is trusted), no MCD_SAMPLE_* flags. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_TRACKS 256
#define MAX_CLIPS 256
#define MAX_NODES 256
#define MAX_ADVANCE 3u
#define FAR_FRAMES 8.0f /* frames past the window's last key from which a step forward locates */

typedef struct quat { float x, y, z, w; } quat;

static uint32_t rd32(const uint8_t* p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static uint64_t rd64(const uint8_t* p) {
    uint64_t v;
    memcpy(&v, p, 8); /* little-endian host (x86-64): one unaligned load */
    return v;
}
/* n bits (0 ... 57) at bit `bit`. */
static uint64_t bits_at(const uint8_t* p, uint64_t bit, uint32_t n) {
    return (rd64(p + (bit >> 3)) >> (bit & 7u)) & (((uint64_t)1 << n) - 1u);
}
/* The low n bits of u (1 ... 57; bits above ignored) as a two's complement number. */
static int64_t sext(uint64_t u, uint32_t n) {
    return (int64_t)(u << (64u - n)) >> (64u - n); /* arithmetic shift: every x86-64 compiler */
}

/* ------------------------------------------------------------------ layout */
typedef struct track {
    const uint8_t *table, *data;
    uint32_t keys, rows, row_bits, offset_bits, frames, head_bits, anchor_bits, nmask, wkeep[4];
    uint64_t omask;
    uint8_t kind, d, split, b, tmode, knot, slot, nbits; /* knot: the predictor, 0 for, 1 knot, 2 prev */
    uint8_t abits[4], kshift[4];
    uint16_t node;
    float step[4];
    quat ref;
    float axis[3];
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

/* ------------------------------------------------------------------ sampling state */
typedef struct state {
    int valid, at_end; /* at_end: slot 2 is the last key */
    uint32_t i;        /* segment [key i, key i + 1]: 0, 1, or 2 for any later one */
    float t[4], v[4][4];
    float t1, t2, inv_h;
    float coef[4][4];
    cursor k3;         /* the key of slot 3 (when not at_end) */
} state;

static void store(const track* t, state* s, uint32_t slot, const cursor* k) {
    int64_t q[4];
    uint32_t c;
    key_q(t, &k->R, k->r, k->o, q);
    s->t[slot] = (float)key_frame(t, k);
    for (c = 0; c < 4u; ++c) s->v[slot][c] = (float)((double)q[c] * (double)t->step[c]);
}

static void repeat(state* s, uint32_t to, uint32_t from) {
    memcpy(s->v[to], s->v[from], sizeof s->v[to]);
    s->t[to] = s->t[from];
}

/* Catmull-Rom segment [t1, t2] as Horner coefficients, the runtime's arithmetic. */
static float coefficients(const float t[4], const float v[4][4], float coef[4][4]) {
    float h = t[2] - t[1], a = h / (t[2] - t[0]), b = h / (t[3] - t[1]);
    uint32_t c;
    for (c = 0; c < 4u; ++c) {
        float p1 = v[1][c], p2 = v[2][c];
        float m1 = a * (p2 - v[0][c]), m2 = b * (v[3][c] - p1);
        coef[c][0] = p1;
        coef[c][1] = m1;
        coef[c][2] = 3.0f * (p2 - p1) - 2.0f * m1 - m2;
        coef[c][3] = 2.0f * (p1 - p2) + m1 + m2;
    }
    return 1.0f / h;
}

static void set_curve(const track* t, state* s) {
    s->t1 = s->t[1];
    s->t2 = s->t[2];
    if (t->split && s->i <= 1u) { /* detached first segment, as RMAL v2 */
        float tt[4], v[4][4];
        memcpy(tt, s->t, sizeof tt);
        memcpy(v, s->v, sizeof v);
        memcpy(v[0], v[1], sizeof v[0]);
        tt[0] = tt[1];
        if (s->i == 0) {
            memcpy(v[3], v[2], sizeof v[3]);
            tt[3] = tt[2];
        }
        s->inv_h = coefficients(tt, (const float(*)[4])v, s->coef);
    } else {
        s->inv_h = coefficients(s->t, (const float(*)[4])s->v, s->coef);
    }
    s->valid = 1;
}

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
    uint32_t xi = (uint32_t)x, e, o, n, after, lo[2] = {0, 0}, hi[2] = {0, 0}, slot, c, used = 1;
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
        s->t[slot] = (float)((k[slot].R->e << t->b) + k[slot].o);
        for (c = 0; c < 3u; ++c) s->v[slot][c] = (float)((double)q[c] * (double)t->step[c]);
        s->v[slot][3] = t->d == 4u ? (float)((double)q[3] * (double)t->step[3]) : 0.0f;
    }
    s->i = have < 2u ? 0u : s->t[0] == 0.0f ? 1u : 2u;
    if (have < 2u) repeat(s, 0, 1);
    if (s->at_end) repeat(s, 3, 2);
    /* Slot 3's key as a cursor, for playback onwards (at the end: never read). */
    if (!s->at_end) {
        cursor* q = &s->k3;
        q->R = *k[3].R;
        q->r = k[3].r;
        q->o = k[3].o;
        if (t->tmode)
            q->tbit = q->R.off + (q->r + 1u) * q->R.gw;
        else
            q->mask = block_mask(t, &q->R);
    }
    set_curve(t, s);
}

/* One key on (the window's slot 2 is not the last key): slot 3's key's successor, if any,
 * becomes slot 3. */
static void advance(const track* t, state* s) {
    uint32_t c;
    for (c = 0; c < 3u; ++c) repeat(s, c, c + 1u);
    if (s->i < 2u) s->i++;
    if (next_key(t, &s->k3)) {
        store(t, s, 3, &s->k3);
    } else {
        s->at_end = 1;
        repeat(s, 3, 2);
    }
}

static void track_value(const track* t, state* s, float x, float out[4]) {
    float u;
    uint32_t c, n;
    if (!s->valid || x < s->t1) {
        locate(t, s, x);
    } else if (x >= s->t2 && !s->at_end) {
        /* A jump well past the window (random access): locate at once rather than read keys
         * one by one first. */
        if (x >= s->t[3] + FAR_FRAMES) {
            locate(t, s, x);
            goto eval;
        }
        for (n = 0; n < MAX_ADVANCE && x >= s->t[2] && !s->at_end; ++n) advance(t, s);
        if (x >= s->t[2] && !s->at_end)
            locate(t, s, x);
        else
            set_curve(t, s);
    }
eval:
    u = (x - s->t1) * s->inv_h;
    for (c = 0; c < 4u; ++c) out[c] = ((s->coef[c][3] * u + s->coef[c][2]) * u + s->coef[c][1]) * u + s->coef[c][0];
}

/* ------------------------------------------------------------------ rotations */
static quat qmul(quat a, quat b) {
    quat r;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    return r;
}
static quat mrp_quat(const float p[3]) {
    float s = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    float inv = 1.0f / (1.0f + s);
    quat q;
    q.x = 2.0f * p[0] * inv;
    q.y = 2.0f * p[1] * inv;
    q.z = 2.0f * p[2] * inv;
    q.w = (1.0f - s) * inv;
    return q;
}
static quat track_quat(const track* t, const float* v) {
    quat tw;
    float half, sn;
    if (t->kind != 2u) return qmul(t->ref, mrp_quat(v));
    half = 0.5f * v[0];
    sn = sinf(half);
    tw.x = t->axis[0] * sn;
    tw.y = t->axis[1] * sn;
    tw.z = t->axis[2] * sn;
    tw.w = cosf(half);
    return qmul(tw, qmul(t->ref, mrp_quat(v + 1)));
}

/* ------------------------------------------------------------------ file */
typedef struct xform { float r[4], t[3], s[3]; } xform;

typedef struct clip {
    uint32_t frames, ntracks, nodes;
    track tracks[MAX_TRACKS];
} clip;

static clip clips[MAX_CLIPS];
static state states[MAX_TRACKS];
static uint32_t nclips;

static int load(const char* path) {
    FILE* f = fopen(path, "rb");
    long n;
    uint8_t* d;
    size_t pos = 8;
    uint32_t c, i;
    if (!f) return 0;
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    fseek(f, 0, SEEK_SET);
    d = malloc((size_t)n);
    if (!d || fread(d, 1, (size_t)n, f) != (size_t)n || memcmp(d, "V3P1", 4)) return 0;
    fclose(f);
    nclips = rd32(d + 4);
    if (nclips > MAX_CLIPS) return 0; /* the prototype's fixed tables */
    for (c = 0; c < nclips; ++c) {
        clip* C = &clips[c];
        const uint8_t *recs, *blob;
        C->frames = rd32(d + pos);
        C->ntracks = rd32(d + pos + 4);
        if (C->ntracks > MAX_TRACKS) return 0;
        recs = d + pos + 12;
        blob = recs + 68u * C->ntracks;
        C->nodes = 0;
        for (i = 0; i < C->ntracks; ++i) {
            const uint8_t* r = recs + 68u * i;
            track* t = &C->tracks[i];
            float ref[3];
            uint32_t k;
            t->kind = r[0], t->d = r[1], t->split = r[2], t->b = r[3], t->tmode = r[4], t->knot = r[5];
            t->slot = r[6], t->nbits = r[7];
            t->node = (uint16_t)(r[8] | (r[9] << 8));
            t->keys = rd32(r + 12), t->rows = rd32(r + 16), t->row_bits = rd32(r + 20), t->offset_bits = rd32(r + 24);
            t->table = blob + rd32(r + 28);
            t->data = blob + rd32(r + 32);
            memcpy(t->abits, r + 36, 4);
            memcpy(t->kshift, r + 40, 4);
            t->frames = C->frames;
            t->head_bits = t->nbits + 4u * t->tmode + t->offset_bits + 5u * t->d;
            t->anchor_bits = t->abits[0] + t->abits[1] + t->abits[2] + t->abits[3];
            t->nmask = (1u << t->nbits) - 1u;
            t->omask = ((uint64_t)1 << t->offset_bits) - 1u;
            for (k = 0; k < 4u; ++k) t->wkeep[k] = k < t->d ? 31u : 0u;
            memcpy(&t->step[0], r + 44, 4);
            t->step[1] = t->step[2] = t->step[3] = t->step[0];
            if (t->kind == 2u) memcpy(&t->step[0], r + 64, 4);
            for (k = 0; k < 3u; ++k) ref[k] = (float)(int16_t)(r[48 + 2 * k] | (r[49 + 2 * k] << 8)) / 32767.0f;
            t->ref = mrp_quat(ref);
            if (t->kind == 2u) {
                float n2 = 0.0f, inv;
                for (k = 0; k < 3u; ++k) {
                    t->axis[k] = (float)(int16_t)(r[56 + 2 * k] | (r[57 + 2 * k] << 8)) / 32767.0f;
                    n2 += t->axis[k] * t->axis[k];
                }
                inv = 1.0f / sqrtf(n2);
                for (k = 0; k < 3u; ++k) t->axis[k] *= inv;
            }
            if (t->node >= MAX_NODES) return 0;
            if (t->node + 1u > C->nodes) C->nodes = t->node + 1u;
        }
        pos += 12u + 68u * C->ntracks + rd32(d + pos + 8);
    }
    return 1;
}

/* One pose: the base transform of every node, then each animated track's value. The base is
 * the identity here (the real reader copies the rest pose and constants the same way). */
static void sample(uint32_t ci, float x, xform* out, int fresh) {
    const clip* C = &clips[ci];
    static const xform base = {{0, 0, 0, 1}, {0, 0, 0}, {1, 1, 1}};
    uint32_t i;
    if (fresh) memset(states, 0, sizeof(state) * C->ntracks);
    for (i = 0; i < C->nodes; ++i) out[i] = base;
    for (i = 0; i < C->ntracks; ++i) {
        const track* t = &C->tracks[i];
        float v[4];
        track_value(t, &states[i], x, v);
        if (t->slot == 0) {
            quat q = track_quat(t, v);
            out[t->node].r[0] = q.x, out[t->node].r[1] = q.y, out[t->node].r[2] = q.z, out[t->node].r[3] = q.w;
        } else {
            memcpy(t->slot == 1 ? out[t->node].t : out[t->node].s, v, 12);
        }
    }
}

static double uni(unsigned long long* s) {
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ull) >> 11) / 9007199254740992.0;
}

#ifdef RMAL_V3_CHECK
#include "mocodec.h"

/* The runtime's frame position of t seconds (clamp mode, snapped near frames). */
static float position(double t, double rate, uint32_t frames) {
    double x = t * rate, last = frames - 1.0, r;
    if (x < 0.0) x = 0.0;
    if (x > last) x = last;
    r = floor(x + 0.5);
    if (fabs(x - r) < fmin(1e-4 + 4e-7 * x, 1.0 / 128.0)) x = r;
    if (x > last) x = last;
    return (float)x;
}

int main(int argc, char** argv) {
    static mcd_transform pose[1024];
    static xform mine[MAX_NODES];
    FILE* f;
    long n;
    unsigned char* d;
    mcd_asset a;
    void* s;
    uint32_t c, i, mode, k;
    unsigned long long seed = 0x9E3779B97F4A7C15ull, poses = 0, diff = 0;
    double worst = 0.0;
    if (argc < 3 || !load(argv[1])) return 2;
    f = fopen(argv[2], "rb");
    if (!f) return 2;
    fseek(f, 0, SEEK_END);
    n = ftell(f);
    fseek(f, 0, SEEK_SET);
    d = malloc((size_t)n);
    if (!d || fread(d, 1, (size_t)n, f) != (size_t)n) return 2;
    fclose(f);
    if (mcd_open(d, (size_t)n, 0, &a) != MCD_OK || mcd_clip_count(&a) != nclips) return 3;
    s = malloc(mcd_scratch_size(&a));
    mcd_scratch_init(&a, s, mcd_scratch_size(&a));
    for (mode = 0; mode < 3; ++mode) {
        for (c = 0; c < nclips; ++c) {
            mcd_clip_info info;
            mcd_get_clip_info(&a, c, &info);
            if (info.frame_count != clips[c].frames) return 4;
            for (i = 0; i < info.frame_count; ++i) {
                double t = mode == 1 ? uni(&seed) * info.duration : (mode == 2 ? 2.0 * i : (double)i) / info.frame_rate;
                if (t > info.duration) break;
                if (mcd_sample(&a, c, t, 0, pose, 1024, s) != MCD_OK) return 5;
                sample(c, position(t, info.frame_rate, info.frame_count), mine, i == 0);
                ++poses;
                for (k = 0; k < clips[c].ntracks; ++k) {
                    const track* tr = &clips[c].tracks[k];
                    const float* ref = tr->slot == 0 ? pose[tr->node].rotation
                                       : tr->slot == 1 ? pose[tr->node].translation : pose[tr->node].scale;
                    const float* got = tr->slot == 0 ? mine[tr->node].r : tr->slot == 1 ? mine[tr->node].t : mine[tr->node].s;
                    uint32_t m, dims = tr->slot == 0 ? 4u : 3u;
                    if (memcmp(ref, got, 4u * dims)) {
                        ++diff;
                        for (m = 0; m < dims; ++m)
                            if (fabs((double)ref[m] - got[m]) > worst) worst = fabs((double)ref[m] - got[m]);
                        if (diff <= 5)
                            fprintf(stderr, "mode %u clip %u frame %u track %u kind %u: %.9g %.9g %.9g vs %.9g %.9g %.9g\n",
                                    mode, c, i, k, tr->kind, ref[0], ref[1], ref[2], got[0], got[1], got[2]);
                    }
                }
            }
        }
    }
    printf("poses %llu, track values differing %llu, largest difference %.3g\n", poses, diff, worst);
    return diff != 0;
}
#else
int main(int argc, char** argv) {
    static xform pose[MAX_NODES];
    unsigned long long seed = 0x9E3779B97F4A7C15ull, poses = 0;
    uint32_t c, i, mode;
    if (argc < 3 || !load(argv[1])) return 2;
    mode = (uint32_t)atoi(argv[2]);
    for (c = 0; c < nclips; ++c) {
        /* the clip's duration and rate as once.c uses them: frames at 1 frame per unit time */
        for (i = 0; mode != 3u && i < clips[c].frames; ++i, ++poses) {
            double x = mode == 1u ? uni(&seed) * (clips[c].frames - 1u) : (double)(mode == 2u ? 2u * i : i);
            if (x > clips[c].frames - 1u) break;
            sample(c, (float)x, pose, i == 0);
        }
    }
    fprintf(stderr, "poses %llu\n", poses);
    return 0;
}
#endif
