/* What the RMAL v3 prototype samplers share (bench/rmal_v3_proto.c: frame blocks, FB;
 * bench/rmal_v3_eb.c: entropy-coded blocks, EB): bit reads, the key window and its Catmull-Rom
 * curve with the runtime's arithmetic, rotations to quaternions, the input file's track
 * records, and the two mains (instruction counts; -DRMAL_V3_CHECK: bit for bit against
 * mcd_sample). Included three times, so that each layout's types and key reads sit in between:
 *
 *   #define RMAL_V3_PART 1 / include: helpers; then the layout's `track` (with RMAL_V3_TRACK_DESC)
 *                                      and `lstate` (its decoder state kept per track)
 *   #define RMAL_V3_PART 2 / include: the window (`state`); then the layout's locate(),
 *                                      next_slot3(), load_track() and RMAL_V3_MAGIC
 *   #define RMAL_V3_PART 3 / include: playback, rotations, file, mains. */
#if RMAL_V3_PART == 1
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h" /* the runtime's rotation and segment arithmetic (runtime_c/src) */

#define MAX_TRACKS 256
#define MAX_CLIPS 256
#define MAX_NODES 256
#define MAX_ADVANCE 3u
#define FAR_FRAMES 8.0f /* frames past the window's last key from which a step forward locates */

/* The descriptor fields every layout keeps as v2 has them. */
#define RMAL_V3_TRACK_DESC \
    uint32_t frames;       \
    uint8_t kind, d, split, slot; \
    uint16_t node;         \
    float step[4];         \
    mcd_quat ref;          \
    float axis[3];

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

#elif RMAL_V3_PART == 2
/* ------------------------------------------------------------------ sampling state */
typedef struct state {
    int valid, at_end; /* at_end: slot 2 is the last key */
    uint32_t i;        /* segment [key i, key i + 1]: 0, 1, or 2 for any later one */
    float t[4], v[4][4];
    float t1, t2, inv_h;
    float coef[4][4];
    lstate L;          /* the layout's reader, at slot 3's key (when not at_end) */
} state;

/* A key into the window: frame and lattice integers to floats, as the runtime converts them. */
static void put_key(const track* t, state* s, uint32_t slot, uint32_t frame, const int64_t q[4]) {
    uint32_t c;
    s->t[slot] = (float)frame;
    for (c = 0; c < 3u; ++c) s->v[slot][c] = (float)((double)q[c] * (double)t->step[c]);
    s->v[slot][3] = t->d == 4u ? (float)((double)q[3] * (double)t->step[3]) : 0.0f;
}

static void repeat(state* s, uint32_t to, uint32_t from) {
    memcpy(s->v[to], s->v[from], sizeof s->v[to]);
    s->t[to] = s->t[from];
}

/* The segment's Horner coefficients (coef[power][component]) with the runtime's arithmetic. A
 * detached first segment (split, as RMAL v2) is the straight line from key 0 to key 1: the
 * window's slots as the curve sees them, slot 1 twice, and slot 2 twice when i = 0. */
static void set_curve(const track* t, state* s) {
    static const uint8_t split_slots[2][4] = {{1, 1, 2, 2}, {1, 1, 2, 3}};
    s->t1 = s->t[1];
    s->t2 = s->t[2];
    if (t->split && s->i <= 1u) {
        float tt[4], v[4][4];
        uint32_t k;
        for (k = 0; k < 4u; ++k) {
            tt[k] = s->t[split_slots[s->i][k]];
            memcpy(v[k], s->v[split_slots[s->i][k]], sizeof v[k]);
        }
        s->inv_h = mcd_segment_coefficients(tt, (const float(*)[4])v, 4u, s->coef);
    } else {
        s->inv_h = mcd_segment_coefficients(s->t, (const float(*)[4])s->v, 4u, s->coef);
    }
    s->valid = 1;
}

/* A located window's slots are filled (slot 0 only when key i - 1 exists, have == 2; slot 3
 * only when not at_end): the segment index, the repeated ends, the curve. */
static void close_window(const track* t, state* s, uint32_t have) {
    s->i = have < 2u ? 0u : s->t[0] == 0.0f ? 1u : 2u;
    if (have < 2u) repeat(s, 0, 1);
    if (s->at_end) repeat(s, 3, 2);
    set_curve(t, s);
}

#elif RMAL_V3_PART == 3
/* One key on (the window's slot 2 is not the last key): slot 3's key's successor, if any,
 * becomes slot 3. */
static void advance(const track* t, state* s) {
    uint32_t c;
    for (c = 0; c < 3u; ++c) repeat(s, c, c + 1u);
    if (s->i < 2u) s->i++;
    if (!next_slot3(t, s)) {
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
    for (c = 0; c < 4u; ++c) out[c] = ((s->coef[3][c] * u + s->coef[2][c]) * u + s->coef[1][c]) * u + s->coef[0][c];
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

/* The file: RMAL_V3_MAGIC, clip count; per clip frame count, track count, blob bytes, one
 * 68-byte record per track, the blob. A record's bytes 0 kind, 1 d, 2 split, 6 slot, 8-9 node,
 * 44 step, 48 reference, 56 twist axis, 64 angle step are v2's; the others are the layout's
 * (load_track, with the track's table and data in the blob). */
/* A whole file in memory (NULL when it cannot be read). */
static uint8_t* whole_file(const char* path, size_t* size) {
    FILE* f = fopen(path, "rb");
    uint8_t* d = NULL;
    long n = -1;
    if (f && !fseek(f, 0, SEEK_END)) n = ftell(f);
    if (n >= 0 && !fseek(f, 0, SEEK_SET)) d = malloc((size_t)n + 1u);
    if (d && fread(d, 1, (size_t)n, f) != (size_t)n) free(d), d = NULL;
    if (f) fclose(f);
    *size = (size_t)n;
    return d;
}

static int load(const char* path) {
    size_t n, pos = 8;
    uint8_t* d = whole_file(path, &n);
    uint32_t c, i;
    if (!d || n < 8u || memcmp(d, RMAL_V3_MAGIC, 4)) return 0;
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
            t->kind = r[0], t->d = r[1], t->split = r[2], t->slot = r[6];
            t->node = (uint16_t)(r[8] | (r[9] << 8));
            t->frames = C->frames;
            load_track(t, r, blob);
            memcpy(&t->step[0], r + 44, 4);
            t->step[1] = t->step[2] = t->step[3] = t->step[0];
            if (t->kind == 2u) memcpy(&t->step[0], r + 64, 4);
            t->ref = mcd_reference_at(r + 48);
            if (t->kind == 2u) mcd_axis_at(r + 56, t->axis);
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
            mcd_set_rotation(out[t->node].r, mcd_track_rotation(t->kind, t->ref, t->axis, v));
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
    size_t n;
    uint8_t* d;
    mcd_asset a;
    void* s;
    uint32_t c, i, mode, k;
    unsigned long long seed = 0x9E3779B97F4A7C15ull, poses = 0, diff = 0;
    double worst = 0.0;
    if (argc < 3 || !load(argv[1])) return 2;
    d = whole_file(argv[2], &n);
    if (!d) return 2;
    if (mcd_open(d, n, 0, &a) != MCD_OK || mcd_clip_count(&a) != nclips) return 3;
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
#endif /* RMAL_V3_PART */
