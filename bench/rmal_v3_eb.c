/* Prototype sampler of the RMAL version 3 candidate "entropy-coded blocks" (EB,
 * docs/RMAL_V3_STUDY.md), for instruction counts only. It reads the .v3e file that
 * bench/rmal_v3_probe.py --eb --write makes (every track's rows and Rice-coded blocks exactly
 * as a v3 payload would hold them) and samples each track's Catmull-Rom curve with the FB
 * prototype's window, curve and rotation code (bench/rmal_v3_shared.h). Build with
 * -Iruntime_c/include -Iruntime_c/src and link the runtime (its curve.c).
 *
 *   rmal_v3_eb FILE.v3e MODE        MODE 0 every frame in order, 1 uniform random times,
 *                                    2 every other frame, 3 load only
 *   rmal_v3_eb_check FILE.v3e ASSET.mcd   (-DRMAL_V3_CHECK, linked with the runtime) compares
 *                                    every animated track, bit for bit, with mcd_sample
 *
 * A track: blocks of K = 2^shift keys. Row e (fixed stride): the block's first key frame, the
 * bit offset of its data, in the "gaps first" variant the bit length of its gap codes, a 5-bit
 * Rice parameter for the gaps and one per component, each component's anchor (the block's
 * first key's lattice integer, v2's anchor width). Data: for each key after the block's first,
 * gap - 1 and each component's zigzag difference from the key before, Rice-coded;
 * interleaved (per key its gap, then its components) or gaps first (the block's gaps, then
 * per key its components). Not the codec: the file is trusted, no MCD_SAMPLE_* flags. */
#define RMAL_V3_PART 1
#include "rmal_v3_shared.h"
#undef RMAL_V3_PART

/* -DRMAL_V3_PHASES keeps the random access's phases out of line, for callgrind's per-function
 * counts (where the instructions go); the measured builds inline them. */
#ifdef RMAL_V3_PHASES
#define PHASE __attribute__((noinline))
static unsigned long long walks, walked; /* locates, keys their walks (two-way: searches and window) decoded */
__attribute__((destructor)) static void walk_report(void) {
    fprintf(stderr, "walks %llu, keys decoded by walks %llu\n", walks, walked);
}
#else
#define PHASE
#endif

#define RICE_CAP 16u /* a run of 16 zeros: an escape, the symbol follows in 32 raw bits */
#define RICE_RAW 32u

struct kv;
typedef struct track {
    const uint8_t *table, *data;
    struct kv* back; /* two-way: the current block's backward keys by rank (the window's reader's) */
    uint32_t keys, blocks, row_bits, fbits, obits, lbits, shift, gaps_first, two_way;
    uint32_t fmask;
    uint64_t omask, lmask;
    uint8_t abits[4];
    RMAL_V3_TRACK_DESC
} track;

/* A key: frame and lattice integers (components past d: 0). */
typedef struct kv {
    int64_t q[4];
    uint32_t frame;
} kv;

/* Where the codes of the key after the current one start (gbit: its gap; vbit: its components,
 * the same place when interleaved), the current key's block e and rank r, the block's key
 * count, and per stream (gaps, then each component) the Rice parameter k and (1 << k) - 1. */
typedef struct reader {
    uint64_t gbit, vbit;
    uint64_t mk[5];
    uint32_t e, r, n, k[5];
} reader;

typedef struct lstate {
    reader R;
    kv key; /* the window's slot 3 key, where R stands */
} lstate;

#define RMAL_V3_PART 2
#include "rmal_v3_shared.h"
#undef RMAL_V3_PART

/* One Rice code at *bit with parameter k (mk = (1 << k) - 1): the quotient is the count of
 * trailing zeros of a 64-bit window (a code is at most 16 + 1 + 31 bits, so one load holds it). */
static inline uint64_t rice(const uint8_t* p, uint64_t* bit, uint32_t k, uint64_t mk) {
    uint64_t w = rd64(p + (*bit >> 3)) >> (*bit & 7u);
    uint32_t q = (uint32_t)__builtin_ctzll(w | ((uint64_t)1 << RICE_CAP));
    if (__builtin_expect(q < RICE_CAP, 1)) {
        *bit += q + 1u + k;
        return ((uint64_t)q << k) | ((w >> (q + 1u)) & mk);
    }
    *bit += RICE_CAP + RICE_RAW;
    return (w >> RICE_CAP) & 0xFFFFFFFFu;
}

static inline int64_t unzig(uint64_t z) {
    return (int64_t)(z >> 1) ^ -(int64_t)(z & 1u);
}

static uint32_t first_frame(const track* t, uint32_t e) {
    return (uint32_t)bits_at(t->table, (uint64_t)e * t->row_bits, t->fbits);
}

/* Row e: the reader at the block's first key, which is `key` (the anchor). */
PHASE static void load_row(const track* t, uint32_t e, reader* R, kv* key) {
    uint64_t bit = (uint64_t)e * t->row_bits, h = rd64(t->table + (bit >> 3)) >> (bit & 7u), off;
    uint32_t c;
    key->frame = (uint32_t)h & t->fmask;
    h >>= t->fbits;
    off = h & t->omask;
    R->gbit = off;
    R->vbit = off + ((h >> t->obits) & t->lmask); /* interleaved: lmask 0 */
    bit += t->fbits + t->obits + t->lbits;
    h = rd64(t->table + (bit >> 3)) >> (bit & 7u);
    for (c = 0; c < 5u; ++c) {
        R->k[c] = (uint32_t)(h >> (5u * c)) & 31u;
        R->mk[c] = ((uint64_t)1 << R->k[c]) - 1u;
    }
    bit += 5u * (t->d + 1u);
    key->q[3] = 0;
    for (c = 0; c < t->d; ++c) {
        key->q[c] = sext(bits_at(t->table, bit, t->abits[c]), t->abits[c]);
        bit += t->abits[c];
    }
    R->e = e;
    R->r = 0;
    R->n = e + 1u < t->blocks ? 1u << t->shift : t->keys - (e << t->shift);
}

/* The key after `from` inside the reader's block into `to` (may be `from`). D is a constant in
 * each caller's copy, so the component loop unrolls. */
static inline void step_d(const track* t, reader* R, const kv* from, kv* to, uint32_t D) {
    uint64_t bit = R->gbit;
    uint32_t c;
    to->frame = from->frame + 1u + (uint32_t)rice(t->data, &bit, R->k[0], R->mk[0]);
    if (t->gaps_first) {
        R->gbit = bit;
        bit = R->vbit;
    }
    for (c = 0; c < D; ++c) to->q[c] = from->q[c] + unzig(rice(t->data, &bit, R->k[c + 1u], R->mk[c + 1u]));
    if (D == 3u) to->q[3] = 0;
    if (t->gaps_first)
        R->vbit = bit;
    else
        R->gbit = bit;
    R->r++;
}

static void step(const track* t, reader* R, const kv* from, kv* to) {
    if (t->d == 3u)
        step_d(t, R, from, to, 3u);
    else
        step_d(t, R, from, to, 4u);
}

/* The key after `from`, crossing into the next block; 0 past the last key. */
static int next(const track* t, reader* R, const kv* from, kv* to) {
    if (R->r + 1u < R->n) {
        step(t, R, from, to);
        return 1;
    }
    if (R->e + 1u >= t->blocks) return 0;
    load_row(t, R->e + 1u, R, to);
    return 1;
}

/* The block of frame xi: the last whose first key is at or before it (block 0 starts at 0). */
PHASE static uint32_t find_block(const track* t, uint32_t xi) {
    uint32_t lo = 0, n = t->blocks;
    while (n > 1u) {
        uint32_t half = n >> 1;
        if (first_frame(t, lo + half) <= xi) lo += half;
        n -= half;
    }
    return lo;
}

/* From the block's first key (ring[0]) to key i + 1, the first after xi, inside the block:
 * returns key i's rank j, keys j - 3 ... j + 1 in ring[rank & 3]; the reader at key j + 1 (or
 * at key j = n - 1 when the block ends first). Interleaved: one pass, each key's gap then its
 * components. Gaps first: the gaps alone find j, then the components of keys 1 ... j + 1 in
 * one pass without a frame test. */
static inline uint32_t walk_d(const track* t, reader* R, kv ring[4], uint32_t xi, uint32_t D) {
    const uint8_t* p = t->data;
    uint64_t gbit = R->gbit, vbit = R->vbit;
    uint32_t j = 0, m, c, f = ring[0].frame, n = R->n;
    if (!t->gaps_first) {
        for (; j + 1u < n; ++j) {
            const kv* a = &ring[j & 3u];
            kv* b = &ring[(j + 1u) & 3u];
            b->frame = a->frame + 1u + (uint32_t)rice(p, &gbit, R->k[0], R->mk[0]);
            for (c = 0; c < D; ++c) b->q[c] = a->q[c] + unzig(rice(p, &gbit, R->k[c + 1u], R->mk[c + 1u]));
            if (b->frame > xi) break;
        }
        m = j + 1u < n ? j + 1u : j; /* keys decoded past the first */
        vbit = gbit;
    } else {
        uint32_t fr[4];
        fr[0] = f;
        for (; j + 1u < n; ++j) {
            f += 1u + (uint32_t)rice(p, &gbit, R->k[0], R->mk[0]);
            fr[(j + 1u) & 3u] = f;
            if (f > xi) break;
        }
        m = j + 1u < n ? j + 1u : j;
        for (c = 1; c <= m; ++c) { /* components of keys 1 ... m, sums in the ring */
            const kv* a = &ring[(c - 1u) & 3u];
            kv* b = &ring[c & 3u];
            uint32_t i;
            for (i = 0; i < D; ++i) b->q[i] = a->q[i] + unzig(rice(p, &vbit, R->k[i + 1u], R->mk[i + 1u]));
            b->frame = fr[c & 3u];
        }
    }
    if (D == 3u)
        for (c = 0; c < 4u; ++c) ring[c].q[3] = 0;
    R->gbit = gbit;
    R->vbit = vbit;
    R->r = m;
    return j;
}

PHASE static uint32_t walk(const track* t, reader* R, kv ring[4], uint32_t xi) {
    uint32_t j = t->d == 3u ? walk_d(t, R, ring, xi, 3u) : walk_d(t, R, ring, xi, 4u);
#ifdef RMAL_V3_PHASES
    walks++, walked += R->r;
#endif
    return j;
}

/* The last key of block e (a whole block's decode). */
PHASE static void last_key(const track* t, uint32_t e, kv* key) {
    reader P;
    load_row(t, e, &P, key);
    while (P.r + 1u < P.n) step(t, &P, key, key);
}

/* Random access: from the row of x's block, decode on to key i + 1 (the first after x), keys
 * i - 1 ... i + 2 in a ring; key i - 1 from the previous block when key i is a block's first. */
static void locate2(const track* t, state* s, float x);

static void locate(const track* t, state* s, float x) {
    uint32_t xi = (uint32_t)x, j = 0, have = 2, e;
    if (t->two_way) {
        locate2(t, s, x);
        return;
    }
    kv ring[4];
    reader R;
    if (xi >= t->frames - 1u) xi = t->frames - 2u; /* the last frame: the segment before it */
    e = find_block(t, xi);
    load_row(t, e, &R, &ring[0]);
    j = walk(t, &R, ring, xi);
    if (j + 1u >= R.n) load_row(t, e + 1u, &R, &ring[(j + 1u) & 3u]); /* key i ends the block */
    if (j == 0u) { /* key i is the block's first: key i - 1 ends the block before, if any */
        if (e == 0u) {
            have = 1;
        } else {
            last_key(t, e - 1u, &ring[3]);
        }
    }
    if (have == 2u) put_key(t, s, 0, ring[(j + 3u) & 3u].frame, ring[(j + 3u) & 3u].q);
    put_key(t, s, 1, ring[j & 3u].frame, ring[j & 3u].q);
    put_key(t, s, 2, ring[(j + 1u) & 3u].frame, ring[(j + 1u) & 3u].q);
    s->L.key = ring[(j + 1u) & 3u];
    s->at_end = !next(t, &R, &s->L.key, &s->L.key);
    s->L.R = R;
    if (!s->at_end) put_key(t, s, 3, s->L.key.frame, s->L.key.q);
    close_window(t, s, have);
}

/* ------------------------------------------------------------------ two-way blocks
 * Keys 1 ... h of a block are read forward from its anchor (h = K/2; the last block: all), keys
 * K - 1 ... h + 1 backward from the next row's anchor (key K), each the key after it minus its
 * step. Backward keys land in t->back[rank], so playback reads them there in order. */

static uint32_t half(const track* t, const reader* R) {
    return R->e + 1u < t->blocks ? 1u << (t->shift - 1u) : R->n - 1u;
}

/* Keys one by one from b[r]: forward (b[r + 1] = b[r] + its step) or backward (b[r - 1] =
 * b[r] - the step into b[r]), codes at *bit with R's parameters, until rank `to`, or until the
 * first key past xi in the walk's direction (forward: frame > xi; backward: frame <= xi).
 * Returns the last rank decoded. `forward` and D are constants in each caller's copy. */
static inline uint32_t run_d(const track* t, const reader* R, uint64_t* bit, kv* b, uint32_t r, uint32_t to,
                             uint32_t xi, int forward, uint32_t D) {
    const uint8_t* p = t->data;
    uint64_t bb = *bit;
    uint32_t c;
    while (r != to) {
        const kv* a = &b[r];
        kv* k = &b[forward ? r + 1u : r - 1u];
        uint32_t g = 1u + (uint32_t)rice(p, &bb, R->k[0], R->mk[0]);
        k->frame = forward ? a->frame + g : a->frame - g;
        for (c = 0; c < D; ++c) {
            int64_t dq = unzig(rice(p, &bb, R->k[c + 1u], R->mk[c + 1u]));
            k->q[c] = forward ? a->q[c] + dq : a->q[c] - dq;
        }
        if (D == 3u) k->q[3] = 0;
        r = forward ? r + 1u : r - 1u;
        if (forward ? k->frame > xi : k->frame <= xi) break;
    }
    *bit = bb;
    return r;
}
static uint32_t run_fwd(const track* t, const reader* R, uint64_t* bit, kv* b, uint32_t r, uint32_t to, uint32_t xi) {
    return t->d == 3u ? run_d(t, R, bit, b, r, to, xi, 1, 3u) : run_d(t, R, bit, b, r, to, xi, 1, 4u);
}
/* xi = 0: to rank `to` (no backward key is at frame 0) */
static uint32_t run_back(const track* t, const reader* R, uint64_t* bit, kv* b, uint32_t r, uint32_t to, uint32_t xi) {
    return t->d == 3u ? run_d(t, R, bit, b, r, to, xi, 0, 3u) : run_d(t, R, bit, b, r, to, xi, 0, 4u);
}

/* Playback: the key after L's; 0 past the last key. Entering a block's backward half decodes it
 * whole into t->back. */
static int next2(const track* t, lstate* L) {
    reader* R = &L->R;
    uint32_t h = half(t, R);
    if (R->r < h) {
        step(t, R, &L->key, &L->key);
        return 1;
    }
    if (R->r + 1u < R->n) {
        if (R->r == h) {
            reader N;
            uint64_t bit = R->vbit;
            load_row(t, R->e + 1u, &N, &t->back[R->n]);
            run_back(t, R, &bit, t->back, R->n, h + 1u, 0);
        }
        L->key = t->back[++R->r];
        return 1;
    }
    if (R->e + 1u >= t->blocks) return 0;
    load_row(t, R->e + 1u, R, &L->key);
    return 1;
}

/* Random access in a two-way block: search from the anchor nearer to x (by frame), forward keys
 * in fw[rank], backward ones in t->back[rank]; the window's keys by rank, decoding more only
 * when a window key lies beyond what the search decoded. */
typedef struct view {
    reader R, N;   /* x's block, forward at rank fn - 1; the next block at its anchor */
    kv fw[128];
    uint32_t fn, blo, h, have_next; /* backward keys blo ... n decoded (blo = n + 1: none) */
    uint64_t bbit;
} view;

/* Forward keys up to `rank`, or (xi < ~0) up to the first after xi; the last rank decoded. */
static uint32_t fw_to(const track* t, view* V, uint32_t rank, uint32_t xi) {
    uint32_t r = V->fn - 1u;
    if (rank > r) {
        r = run_fwd(t, &V->R, &V->R.gbit, V->fw, r, rank, xi);
#ifdef RMAL_V3_PHASES
        walked += r + 1u - V->fn;
#endif
        V->fn = r + 1u;
        V->R.r = r;
    }
    return r;
}
static void next_anchor(const track* t, view* V) {
    if (!V->have_next) load_row(t, V->R.e + 1u, &V->N, &t->back[V->R.n]), V->have_next = 1;
}
/* Backward keys down to `rank`, or (xi > 0) down to the first at or before xi; the lowest rank
 * decoded. */
static uint32_t bw_to(const track* t, view* V, uint32_t rank, uint32_t xi) {
    next_anchor(t, V);
    if (V->blo > V->R.n) V->blo = V->R.n;
    if (V->blo > rank) {
        uint32_t r = run_back(t, &V->R, &V->bbit, t->back, V->blo, rank, xi);
#ifdef RMAL_V3_PHASES
        walked += V->blo - r;
#endif
        V->blo = r;
    }
    return V->blo;
}
static const kv* at_rank(const track* t, view* V, uint32_t rank) {
    if (rank <= V->h) {
        fw_to(t, V, rank, ~0u);
        return &V->fw[rank];
    }
    bw_to(t, V, rank, 0);
    return &t->back[rank];
}

static void locate2(const track* t, state* s, float x) {
    uint32_t xi = (uint32_t)x, i, n, last, slot;
    view V;
    kv after;
    if (xi >= t->frames - 1u) xi = t->frames - 2u;
#ifdef RMAL_V3_PHASES
    walks++;
#endif
    load_row(t, find_block(t, xi), &V.R, &V.fw[0]);
    n = V.R.n;
    last = V.R.e + 1u >= t->blocks;
    V.h = half(t, &V.R), V.fn = 1, V.blo = n + 1u, V.have_next = 0, V.bbit = V.R.vbit;
    i = V.h; /* key i: the last at or before xi */
    /* search from the anchor nearer x (by frame); the other half when x is not in the first */
    if (!last && 2u * (xi - V.fw[0].frame) >= first_frame(t, V.R.e + 1u) - V.fw[0].frame) {
        i = bw_to(t, &V, V.h + 1u, xi); /* backward from the next anchor */
        if (t->back[i].frame > xi) {     /* key i is in the forward half */
            i = fw_to(t, &V, V.h, xi);
            if (V.fw[i].frame > xi) --i;
        }
    } else {
        i = fw_to(t, &V, V.h, xi);
        if (V.fw[i].frame > xi) {
            --i;
        } else if (!last) { /* past the forward half */
            i = bw_to(t, &V, V.h + 1u, xi);
            if (t->back[i].frame > xi) i = V.h;
        }
    }
    /* the window: keys i - 1 ... i + 2 */
    if (i > 0) {
        put_key(t, s, 0, at_rank(t, &V, i - 1u)->frame, at_rank(t, &V, i - 1u)->q);
    } else if (V.R.e > 0) { /* the previous block's last key: one backward step from this anchor */
        reader P;
        kv b[2];
        uint64_t bit;
        load_row(t, V.R.e - 1u, &P, &b[0]);
        bit = P.vbit;
        b[1] = V.fw[0];
        run_back(t, &P, &bit, b, 1, 0, 0);
        put_key(t, s, 0, b[0].frame, b[0].q);
    }
    put_key(t, s, 1, at_rank(t, &V, i)->frame, at_rank(t, &V, i)->q);
    for (slot = 2; slot < 4u; ++slot) { /* keys i + 1 and i + 2; the reader left at the last */
        uint32_t r = i + slot - 1u;
        const kv* k;
        s->at_end = 0;
        if (r < n || (r == n && !last)) {
            k = at_rank(t, &V, r);
            if (r <= V.h) {
                s->L.R = V.R; /* forward: the search stopped at key i + 1, fw_to(i + 2) at most */
            } else if (r < n) {
                s->L.R = V.R;
                s->L.R.r = r;
            } else {
                s->L.R = V.N;
            }
        } else if (r == n + 1u && !last && V.N.n > 1u) {
            s->L.R = V.N;
            step(t, &s->L.R, &t->back[n], &after);
            k = &after;
        } else {
            s->at_end = 1;
            break;
        }
        put_key(t, s, slot, k->frame, k->q);
        s->L.key = *k;
    }
    close_window(t, s, i > 0 || V.R.e > 0 ? 2u : 1u);
}

/* Playback one key on: slot 3 becomes the key after it; 0 past the last key. */
static int next_slot3(const track* t, state* s) {
    if (!(t->two_way ? next2(t, &s->L) : next(t, &s->L.R, &s->L.key, &s->L.key))) return 0;
    put_key(t, s, 3, s->L.key.frame, s->L.key.q);
    return 1;
}

#define RMAL_V3_MAGIC "V3E1"
/* A record's layout bytes: 3 block shift, 4 variant (1: gaps first), 7 first-frame bits,
 * 12 keys, 16 rows, 20 row bits, 24 offset bits, 28 table and 32 data offsets in the blob,
 * 36 anchor bits, 40 gap-length bits. */
static void load_track(track* t, const uint8_t* r, const uint8_t* blob) {
    static kv pool[MAX_TRACKS][129]; /* two-way backward keys, one row per track of a clip */
    static uint32_t used;
    t->shift = r[3], t->gaps_first = r[4] == 1u, t->two_way = r[4] == 2u, t->fbits = r[7];
    t->back = pool[used++ % MAX_TRACKS];
    t->keys = rd32(r + 12), t->blocks = rd32(r + 16), t->row_bits = rd32(r + 20), t->obits = rd32(r + 24);
    t->table = blob + rd32(r + 28);
    t->data = blob + rd32(r + 32);
    memcpy(t->abits, r + 36, 4);
    t->lbits = r[40];
    t->fmask = (1u << t->fbits) - 1u;
    t->omask = ((uint64_t)1 << t->obits) - 1u;
    t->lmask = ((uint64_t)1 << t->lbits) - 1u;
}

#define RMAL_V3_PART 3
#include "rmal_v3_shared.h"
#undef RMAL_V3_PART
