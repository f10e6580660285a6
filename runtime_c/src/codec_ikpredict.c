/* Codec `ik-predict`: closed-loop inverse-kinematics prediction of the converted joint angles
 * (seed 000 §3.2, §5 "IKBP"; docs/FORMAT.md, IKPR).
 *
 * Per frame the state is, per coded joint, the world direction of its bone as two spherical
 * angles (phi, varphi) about a per-joint polar axis and the twist psi about the bone, plus the
 * coded local translations. A frame is predicted from the decoded frames before it: the
 * effector displacement sent in the stream is turned into angle changes by the damped
 * pseudo-inverse of the closed-form chain Jacobian (eq. 15 with the acceleration parameter k,
 * all chains solved together), psi repeats the last frame; the quantized residual is added.
 * Frames come in blocks whose first frame is intra (no prediction), each block's codes in
 * their own entropy streams, so a seek decodes at most one block.
 *
 * The codec samples in place (no resident memory). The caller's scratch holds the decoded
 * codes of the current block and the last three decoded frames, so sequential playback costs
 * one prediction step per frame and a block's entropy decode every block_frames frames.
 * The encoder runs the same prediction through mcd_ikp_closed_loop (ikpredict.h). */
#include <math.h>
#include <string.h>

#include "entropy.h"
#include "ikpredict.h"
#include "internal.h"

#define HEADER 48u
#define NODE_RECORD 32u
#define BLOCK_ENTRY 16u
#define MAX_BLOCK_FRAMES 4096u
#define MAX_CHAINS 16u
#define MAX_CHAIN_TOTAL 4096u
#define MAX_BLOCK_VALUES (1u << 24) /* values of one block: bounds the scratch */
#define MAX_STEP 1e3f
#define MIN_STEP 1e-12f
#define MAX_K 4.0f
#define CLAMP 1e7                   /* every decoded value: keeps sampling finite */
#define NO_CHILD 0xFFFFu
#define SLOTS 3u                    /* decoded frames kept: f, f - 1, f - 2 */

enum { ROT_IDENTITY = 0, ROT_CONSTANT = 1, ROT_CODED = 2 };
enum { TRANS_REST = 0, TRANS_CODED = 1 };

typedef struct layout {
    uint32_t frames, nodes, block_frames, blocks, joints, tracks, chains, chain_total, flags;
    uint32_t stream_bytes, coded; /* coded frames G; when G < F the gap table places them */
    float k, eff_step, trans_step;
    const uint8_t *node_table, *chain_len, *chain_nodes, *gaps, *block_table, *streams;
    size_t head_size, size;
    const uint8_t* skel; /* the clip's SKEL section */
} layout;

static const uint8_t* node_rec(const layout* L, uint32_t i) {
    return L->node_table + (size_t)NODE_RECORD * i;
}

static int32_t parent_of(const layout* L, uint32_t i) {
    return mcd_skel_parent(L->skel, i);
}

static double rest_offset(const layout* L, uint32_t i, uint32_t k) {
    return (double)mcd_rd_f32(mcd_skel_record(L->skel, i) + 8u + 4u * k);
}

/* A node's rest rotation (identity for BVH skeletons), binary64 x y z w. */
static void rest_rotation(const layout* L, uint32_t i, double q[4]) {
    mcd_transform rest;
    uint32_t k;
    mcd_skel_rest(L->skel, i, &rest);
    for (k = 0; k < 4u; ++k) q[k] = (double)rest.rotation[k];
}

static uint32_t chain_length(const layout* L, uint32_t c) {
    return mcd_rd_u16(L->chain_len + 2u * c);
}

static uint32_t values_per_frame(const layout* L) {
    return 3u * (L->chains + L->joints + L->tracks);
}

/* Sizes of the head (header, node table, chain tables) at p; 0 unless they fit in avail. */
static int read_head(const uint8_t* p, size_t avail, layout* L) {
    size_t off;
    if (avail < HEADER) return 0;
    L->frames = mcd_rd_u32(p);
    L->nodes = mcd_rd_u32(p + 4);
    L->block_frames = mcd_rd_u32(p + 8);
    L->joints = mcd_rd_u32(p + 12);
    L->tracks = mcd_rd_u32(p + 16);
    L->chains = mcd_rd_u16(p + 20);
    L->chain_total = mcd_rd_u16(p + 22);
    L->k = mcd_rd_f32(p + 24);
    L->eff_step = mcd_rd_f32(p + 28);
    L->trans_step = mcd_rd_f32(p + 32);
    L->flags = p[36];
    L->stream_bytes = mcd_rd_u32(p + 40);
    L->coded = mcd_rd_u32(p + 44);
    if (L->frames < 1u || L->frames > MCD_MAX_FRAMES || L->nodes < 1u || L->nodes > MCD_MAX_NODES) return 0;
    if (L->block_frames < 1u || L->block_frames > MAX_BLOCK_FRAMES) return 0;
    if (L->coded < 1u || L->coded > L->frames) return 0;
    if (L->chains > MAX_CHAINS || L->chain_total > MAX_CHAIN_TOTAL) return 0;
    L->blocks = (L->coded + L->block_frames - 1u) / L->block_frames;
    off = HEADER + (size_t)NODE_RECORD * L->nodes;
    L->node_table = p + HEADER;
    L->chain_len = p + off;
    off += 2u * (size_t)L->chains;
    L->chain_nodes = p + off;
    off += 2u * (size_t)L->chain_total;
    L->gaps = p + off;
    if (L->coded < L->frames) off += L->coded - 1u; /* u8 frames to the next coded frame */
    off = mcd_align4(off);
    if (off > avail) return 0;
    L->head_size = off;
    return 1;
}

/* Head and block table sizes plus streams: the whole payload; 0 unless it fits in avail. */
static int read_layout(const uint8_t* p, size_t avail, layout* L) {
    size_t off;
    if (!read_head(p, avail, L)) return 0;
    off = L->head_size;
    L->block_table = p + off;
    off += (size_t)BLOCK_ENTRY * L->blocks;
    L->streams = p + off;
    off = mcd_align4(off + (size_t)L->stream_bytes);
    if (off > avail) return 0;
    L->size = off;
    return 1;
}

/* Everything the head shows, against the skeleton records in L->skel. */
static int check_head(const layout* L, const uint8_t* p) {
    uint32_t i, c, m, joints = 0, tracks = 0, at = 0;
    size_t b;
    if (p[37] || p[38] || p[39] || (L->flags & ~1u) != 0) return 0;
    if (!mcd_finite(L->k) || L->k < 0.0f || L->k > MAX_K) return 0;
    if (!mcd_finite(L->eff_step) || L->eff_step < MIN_STEP || L->eff_step > MAX_STEP) return 0;
    if (!mcd_finite(L->trans_step) || L->trans_step < MIN_STEP || L->trans_step > MAX_STEP) return 0;
    for (i = 0; i < L->nodes; ++i) {
        const uint8_t* r = node_rec(L, i);
        uint32_t primary = mcd_rd_u16(r + 4), k;
        float dir = mcd_rd_f32(r + 24), twist = mcd_rd_f32(r + 28);
        if (r[3] || mcd_rd_u16(r + 6) || r[1] > TRANS_CODED) return 0;
        tracks += r[1] == TRANS_CODED;
        if (r[0] == ROT_CODED) {
            float n2 = 0.0f;
            joints++;
            if (r[2] > 2u || mcd_rd_f32(r + 20) != 0.0f) return 0;
            for (k = 0; k < 3u; ++k) {
                float u = mcd_rd_f32(r + 8 + 4 * k);
                if (!mcd_finite(u)) return 0;
                n2 += u * u;
            }
            if (!(fabsf(n2 - 1.0f) <= 1e-5f)) return 0;
            if (!mcd_finite(dir) || !mcd_finite(twist) || dir < MIN_STEP || dir > MAX_STEP ||
                twist < MIN_STEP || twist > MAX_STEP)
                return 0;
            if (primary != NO_CHILD) {
                float len2 = 0.0f;
                if (primary >= L->nodes || parent_of(L, primary) != (int32_t)i) return 0;
                for (k = 0; k < 3u; ++k) len2 += (float)(rest_offset(L, primary, k) * rest_offset(L, primary, k));
                if (!(len2 > 0.0f)) return 0;
            }
        } else {
            if (r[0] > ROT_CONSTANT || r[2] || primary != NO_CHILD || dir != 0.0f || twist != 0.0f) return 0;
            if (r[0] == ROT_CONSTANT) {
                if (!mcd_unit_quat_at(r + 8)) return 0;
            } else {
                for (k = 0; k < 16u; ++k)
                    if (r[8 + k]) return 0;
            }
        }
    }
    if (joints != L->joints || tracks != L->tracks) return 0;
    if ((uint64_t)values_per_frame(L) * L->block_frames > MAX_BLOCK_VALUES) return 0;
    for (c = 0; c < L->chains; ++c) {
        uint32_t len = chain_length(L, c);
        if (len < 2u || at + len > L->chain_total) return 0;
        for (m = 0; m < len; ++m) {
            uint32_t node = mcd_rd_u16(L->chain_nodes + 2u * (at + m));
            uint32_t prev = m ? mcd_rd_u16(L->chain_nodes + 2u * (at + m - 1u)) : 0;
            if (node >= L->nodes) return 0;
            if (m == 0 ? parent_of(L, node) != -1 : parent_of(L, node) != (int32_t)prev) return 0;
        }
        at += len;
    }
    if (at != L->chain_total) return 0;
    if (L->coded < L->frames) {
        uint64_t sum = 0;
        for (c = 0; c + 1u < L->coded; ++c) {
            if (L->gaps[c] == 0u) return 0;
            sum += L->gaps[c];
        }
        if (sum != L->frames - 1u) return 0;
    }
    for (b = (size_t)(L->gaps - p) + (L->coded < L->frames ? L->coded - 1u : 0u); b < L->head_size; ++b)
        if (p[b]) return 0;
    return 1;
}

/* Frames from coded frame g to coded frame g + 1 (g + 1 < G). */
static uint32_t gap_after(const layout* L, uint32_t g) {
    return L->coded < L->frames ? L->gaps[g] : 1u;
}

/* Frames in block b, and its three streams (effector, angle, translation) with their value
 * counts; 0 unless the block table entry is consistent. */
typedef struct block_streams {
    uint32_t first, count;
    const uint8_t* at[3];
    uint32_t bytes[3], values[3];
} block_streams;

static int block_info(const layout* L, uint32_t b, block_streams* s) {
    const uint8_t* e = L->block_table + (size_t)BLOCK_ENTRY * b;
    uint32_t off = mcd_rd_u32(e), end, k;
    uint64_t used;
    s->first = b * L->block_frames;
    s->count = L->coded - s->first < L->block_frames ? L->coded - s->first : L->block_frames;
    end = b + 1u < L->blocks ? mcd_rd_u32(e + BLOCK_ENTRY) : L->stream_bytes;
    s->bytes[0] = mcd_rd_u32(e + 4);
    s->bytes[1] = mcd_rd_u32(e + 8);
    used = (uint64_t)off + s->bytes[0] + s->bytes[1];
    if (end > L->stream_bytes || used > end) return 0;
    s->bytes[2] = (uint32_t)(end - used);
    s->values[0] = (s->count - 1u) * 3u * L->chains;
    s->values[1] = s->count * 3u * L->joints;
    s->values[2] = s->count * 3u * L->tracks;
    s->at[0] = L->streams + off;
    s->at[1] = s->at[0] + s->bytes[0];
    s->at[2] = s->at[1] + s->bytes[1];
    for (k = 0; k < 3u; ++k)
        if (s->values[k] == 0u && s->bytes[k] != 0u) return 0;
    return 1;
}

/* Frame of block b's intra frame, as its entry says. */
static uint32_t block_first_frame(const layout* L, uint32_t b) {
    return mcd_rd_u32(L->block_table + (size_t)BLOCK_ENTRY * b + 12u);
}

static int check_blocks(const layout* L, const uint8_t* p) {
    uint32_t b, g, frame = 0;
    size_t end;
    block_streams s;
    if (mcd_rd_u32(L->block_table) != 0) return 0;
    for (b = 0; b < L->blocks; ++b)
        if (!block_info(L, b, &s)) return 0;
    /* Each block's first frame is where the gaps put its intra frame. */
    for (g = 0; g < L->coded; ++g) {
        if (g % L->block_frames == 0u && block_first_frame(L, g / L->block_frames) != frame) return 0;
        if (g + 1u < L->coded) frame += gap_after(L, g);
    }
    for (end = (size_t)(L->streams - p) + L->stream_bytes; end < L->size; ++end)
        if (p[end]) return 0;
    return 1;
}

/* ---------------------------------------------------------------- working memory */
typedef struct state {
    int32_t block;     /* block whose codes are decoded, -1 none */
    int32_t cur;       /* last decoded frame, -1 none */
    int32_t run_start; /* frames run_start ... cur were decoded in order from an intra frame */
    int32_t pose_frame[2]; /* coded frame whose local pose each pose slot holds, -1 none */
    int32_t pad[3];
} state;

typedef struct ctx {
    layout L;
    state* st;
    int32_t *joint_slot, *track_slot; /* per node: index among coded joints / tracks, or -1 */
    int32_t* codes[3];                /* decoded block: effector, angle, translation codes */
    double *vals, *steps, *jac, *m, *r, *theta0, *world;
    mcd_transform* poses; /* two cached local poses (N each): sequential samples between the
                           * same two coded frames only blend */
} ctx;

/* Bytes of each part of the working memory, 16-aligned, in order; returns the total. */
static size_t work_layout(const layout* L, size_t part[12]) {
    size_t V = (size_t)L->joints * 3u + (size_t)L->tracks * 3u, C3 = 3u * (size_t)L->chains;
    size_t B = L->block_frames, total = 0, i;
    part[0] = sizeof(state);
    part[1] = 4u * (size_t)L->nodes;
    part[2] = 4u * (size_t)L->nodes;
    part[3] = 4u * (B - 1u) * C3;
    part[4] = 4u * B * 3u * L->joints;
    part[5] = 4u * B * 3u * L->tracks;
    part[6] = 8u * SLOTS * V;
    part[7] = 8u * V;
    part[8] = 8u * C3 * 2u * L->joints;
    part[9] = 8u * C3 * C3 + 8u * C3;
    part[10] = 8u * 2u * L->joints + 8u * 4u * L->nodes;
    part[11] = 2u * sizeof(mcd_transform) * (size_t)L->nodes;
    for (i = 0; i < 12u; ++i) total += mcd_align16(part[i]);
    return total;
}

static void ctx_bind(ctx* c, uint8_t* work) {
    size_t part[12], at = 0;
    void* p[12];
    uint32_t i;
    work_layout(&c->L, part);
    for (i = 0; i < 12u; ++i) {
        p[i] = work + at;
        at += mcd_align16(part[i]);
    }
    c->st = (state*)p[0];
    c->joint_slot = (int32_t*)p[1];
    c->track_slot = (int32_t*)p[2];
    c->codes[0] = (int32_t*)p[3];
    c->codes[1] = (int32_t*)p[4];
    c->codes[2] = (int32_t*)p[5];
    c->vals = (double*)p[6];
    c->steps = (double*)p[7];
    c->jac = (double*)p[8];
    c->m = (double*)p[9];
    c->r = c->m + 9u * (size_t)c->L.chains * c->L.chains;
    c->theta0 = (double*)p[10];
    c->world = c->theta0 + 2u * (size_t)c->L.joints;
    c->poses = (mcd_transform*)p[11];
}

/* Slot maps and per-value steps (what does not change while sampling one clip). */
static void ctx_reset(ctx* c) {
    uint32_t i, j = 0, t = 0;
    for (i = 0; i < c->L.nodes; ++i) {
        const uint8_t* r = node_rec(&c->L, i);
        c->joint_slot[i] = r[0] == ROT_CODED ? (int32_t)j : -1;
        c->track_slot[i] = r[1] == TRANS_CODED ? (int32_t)t : -1;
        if (r[0] == ROT_CODED) {
            c->steps[3u * j] = (double)mcd_rd_f32(r + 24);
            c->steps[3u * j + 1u] = (double)mcd_rd_f32(r + 24);
            c->steps[3u * j + 2u] = (double)mcd_rd_f32(r + 28);
            j++;
        }
        if (r[1] == TRANS_CODED) t++;
    }
    for (i = 0; i < 3u * c->L.tracks; ++i) c->steps[3u * c->L.joints + i] = (double)c->L.trans_step;
    c->st->block = -1;
    c->st->cur = -1;
    c->st->run_start = 0;
    c->st->pose_frame[0] = c->st->pose_frame[1] = -1;
}

static double* slot_vals(const ctx* c, uint32_t frame) {
    size_t V = 3u * ((size_t)c->L.joints + c->L.tracks);
    return c->vals + (size_t)(frame % SLOTS) * V;
}

/* ---------------------------------------------------------------- geometry (double) */
static double clampd(double x) {
    if (!(x == x)) return 0.0;
    return x > CLAMP ? CLAMP : x < -CLAMP ? -CLAMP : x;
}

static void qmul(const double a[4], const double b[4], double out[4]) {
    double r[4];
    r[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
    r[1] = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
    r[2] = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
    r[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
    memcpy(out, r, sizeof r);
}

static void qrotate(const double q[4], const double v[3], double out[3]) {
    double tx = 2.0 * (q[1] * v[2] - q[2] * v[1]);
    double ty = 2.0 * (q[2] * v[0] - q[0] * v[2]);
    double tz = 2.0 * (q[0] * v[1] - q[1] * v[0]);
    out[0] = v[0] + q[3] * tx + (q[1] * tz - q[2] * ty);
    out[1] = v[1] + q[3] * ty + (q[2] * tx - q[0] * tz);
    out[2] = v[2] + q[3] * tz + (q[0] * ty - q[1] * tx);
}

/* The polar frame of axis a is a cyclic permutation: world[a] = s.z, world[a+1] = s.x,
 * world[a+2] = s.y (a = 2 is the identity), so the bone can be kept away from the poles. */
static void to_world_axes(uint32_t a, const double s[3], double w[3]) {
    w[a % 3u] = s[2];
    w[(a + 1u) % 3u] = s[0];
    w[(a + 2u) % 3u] = s[1];
}

/* World rotation of a coded joint: W = A(psi, d) R_cross(u -> d) (seed eq. 6-7). */
static void joint_world(const uint8_t* rec, const double* v, double q[4]) {
    double s[3], d[3], u[3], r[4], a[4], cross, n, h, sh;
    uint32_t k;
    s[0] = sin(v[0]) * cos(v[1]);
    s[1] = sin(v[0]) * sin(v[1]);
    s[2] = cos(v[0]);
    to_world_axes(rec[2], s, d);
    for (k = 0; k < 3u; ++k) u[k] = (double)mcd_rd_f32(rec + 8 + 4 * k);
    cross = 1.0 + u[0] * d[0] + u[1] * d[1] + u[2] * d[2];
    if (cross > 1e-12) {
        r[0] = u[1] * d[2] - u[2] * d[1];
        r[1] = u[2] * d[0] - u[0] * d[2];
        r[2] = u[0] * d[1] - u[1] * d[0];
        r[3] = cross;
    } else {
        /* d = -u: half turn about an axis normal to u (the basis axis least along u). */
        double e[3] = {0.0, 0.0, 0.0};
        k = fabs(u[0]) <= fabs(u[1]) ? (fabs(u[0]) <= fabs(u[2]) ? 0u : 2u) : (fabs(u[1]) <= fabs(u[2]) ? 1u : 2u);
        e[k] = 1.0;
        r[0] = u[1] * e[2] - u[2] * e[1];
        r[1] = u[2] * e[0] - u[0] * e[2];
        r[2] = u[0] * e[1] - u[1] * e[0];
        r[3] = 0.0;
    }
    n = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    for (k = 0; k < 4u; ++k) r[k] /= n;
    h = 0.5 * v[2];
    sh = sin(h);
    a[0] = d[0] * sh;
    a[1] = d[1] * sh;
    a[2] = d[2] * sh;
    a[3] = cos(h);
    qmul(a, r, q);
}

/* World rotations of every node for decoded values `v`. */
static void frame_world(const ctx* c, const double* v) {
    static const double identity[4] = {0.0, 0.0, 0.0, 1.0};
    uint32_t i, k;
    for (i = 0; i < c->L.nodes; ++i) {
        const uint8_t* rec = node_rec(&c->L, i);
        int32_t p = parent_of(&c->L, i);
        const double* pw = p >= 0 ? c->world + 4u * (size_t)p : identity;
        double* w = c->world + 4u * (size_t)i;
        if (rec[0] == ROT_CODED) {
            joint_world(rec, v + 3u * (size_t)c->joint_slot[i], w);
        } else {
            double q[4];
            if (rec[0] == ROT_CONSTANT)
                for (k = 0; k < 4u; ++k) q[k] = (double)mcd_rd_f32(rec + 8 + 4 * k);
            else
                rest_rotation(&c->L, i, q);
            qmul(pw, q, w);
        }
    }
}

static void local_translation(const ctx* c, const double* v, uint32_t i, double t[3]) {
    uint32_t k;
    int32_t s = c->track_slot[i];
    for (k = 0; k < 3u; ++k)
        t[k] = s >= 0 ? v[3u * ((size_t)c->L.joints + (size_t)s) + k] : rest_offset(&c->L, i, k);
}

/* Local pose of every node (what the runtime returns at an integer frame), after frame_world. */
static void frame_local(const ctx* c, const double* v, mcd_transform* out) {
    uint32_t i, k;
    for (i = 0; i < c->L.nodes; ++i) {
        const uint8_t* rec = node_rec(&c->L, i);
        double t[3];
        mcd_skel_rest(c->L.skel, i, &out[i]); /* rotation mode 0, and the scale */
        if (rec[0] == ROT_CODED) {
            int32_t p = parent_of(&c->L, i);
            double q[4], n;
            if (p >= 0) {
                const double* pw = c->world + 4u * (size_t)p;
                double inv[4];
                inv[0] = -pw[0];
                inv[1] = -pw[1];
                inv[2] = -pw[2];
                inv[3] = pw[3];
                qmul(inv, c->world + 4u * (size_t)i, q);
            } else {
                memcpy(q, c->world + 4u * (size_t)i, sizeof q);
            }
            n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
            for (k = 0; k < 4u; ++k) out[i].rotation[k] = (float)(q[k] / n);
        } else if (rec[0] == ROT_CONSTANT) {
            for (k = 0; k < 4u; ++k) out[i].rotation[k] = mcd_rd_f32(rec + 8 + 4 * k);
        }
        local_translation(c, v, i, t);
        for (k = 0; k < 3u; ++k) out[i].translation[k] = (float)t[k];
    }
}

/* ---------------------------------------------------------------- the prediction step */
/* Solve (J J^T + lambda I) y = r by Cholesky in place on c->m (n x n); 0 if not positive. */
static int solve_spd(double* m, double* r, uint32_t n) {
    uint32_t i, j, k;
    for (j = 0; j < n; ++j) {
        double d = m[(size_t)j * n + j];
        for (k = 0; k < j; ++k) d -= m[(size_t)j * n + k] * m[(size_t)j * n + k];
        if (!(d > 1e-300)) return 0;
        d = sqrt(d);
        m[(size_t)j * n + j] = d;
        for (i = j + 1u; i < n; ++i) {
            double s = m[(size_t)i * n + j];
            for (k = 0; k < j; ++k) s -= m[(size_t)i * n + k] * m[(size_t)j * n + k];
            m[(size_t)i * n + j] = s / d;
        }
    }
    for (i = 0; i < n; ++i) {
        double s = r[i];
        for (k = 0; k < i; ++k) s -= m[(size_t)i * n + k] * r[k];
        r[i] = s / m[(size_t)i * n + i];
    }
    for (i = n; i-- > 0u;) {
        double s = r[i];
        for (k = i + 1u; k < n; ++k) s -= m[(size_t)k * n + i] * r[k];
        r[i] = s / m[(size_t)i * n + i];
    }
    return 1;
}

/* The chain Jacobian (eq. 19-20) at the decoded angles `v`, 3C x 2J, row-major. Only links
 * whose child is the joint's primary child are columns: their direction is the joint's d. */
static void build_jacobian(const ctx* c, const double* v) {
    uint32_t ch, m, at = 0, J2 = 2u * c->L.joints;
    memset(c->jac, 0, sizeof(double) * 3u * c->L.chains * J2);
    for (ch = 0; ch < c->L.chains; ++ch) {
        uint32_t len = chain_length(&c->L, ch);
        for (m = 0; m + 1u < len; ++m) {
            uint32_t a = mcd_rd_u16(c->L.chain_nodes + 2u * (at + m));
            uint32_t b = mcd_rd_u16(c->L.chain_nodes + 2u * (at + m + 1u));
            const uint8_t* rec = node_rec(&c->L, a);
            int32_t s = c->joint_slot[a];
            double len_ab = 0.0, sp, cp, sa, ca, gp[3], ga[3], wp[3], wa[3];
            uint32_t k;
            if (s < 0 || mcd_rd_u16(rec + 4) != b) continue;
            for (k = 0; k < 3u; ++k) len_ab += rest_offset(&c->L, b, k) * rest_offset(&c->L, b, k);
            len_ab = sqrt(len_ab);
            sp = sin(v[3u * (size_t)s]);
            cp = cos(v[3u * (size_t)s]);
            sa = sin(v[3u * (size_t)s + 1u]);
            ca = cos(v[3u * (size_t)s + 1u]);
            gp[0] = cp * ca;
            gp[1] = cp * sa;
            gp[2] = -sp;
            ga[0] = -sp * sa;
            ga[1] = sp * ca;
            ga[2] = 0.0;
            to_world_axes(rec[2], gp, wp);
            to_world_axes(rec[2], ga, wa);
            for (k = 0; k < 3u; ++k) {
                double* row = c->jac + (size_t)(3u * ch + k) * J2;
                row[2u * (uint32_t)s] += len_ab * wp[k];
                row[2u * (uint32_t)s + 1u] += len_ab * wa[k];
            }
        }
        at += len;
    }
}

/* Prediction of a frame from the decoded frames before it: `prev` (f - 1), `prev2` (f - 2,
 * or NULL right after an intra frame) and the effector codes `eff` (3C). Eq. 15: the angle
 * change closest to k times the last change that moves every effector by its decoded delta
 * (damped pseudo-inverse of the stacked chain Jacobian); psi repeats; translations repeat or,
 * with flag bit 0, continue at constant velocity. */
static void predict(const ctx* c, const double* prev, const double* prev2, const int32_t* eff, double* pred) {
    uint32_t J = c->L.joints, J2 = 2u * J, n = 3u * c->L.chains, i, j, s, T3 = 3u * c->L.tracks;
    double k = (double)c->L.k, trace = 0.0;
    for (s = 0; s < J; ++s) {
        c->theta0[2u * s] = prev2 ? k * (prev[3u * s] - prev2[3u * s]) : 0.0;
        c->theta0[2u * s + 1u] = prev2 ? k * (prev[3u * s + 1u] - prev2[3u * s + 1u]) : 0.0;
    }
    if (n > 0u && J > 0u) {
        build_jacobian(c, prev);
        for (i = 0; i < n; ++i) {
            const double* ri = c->jac + (size_t)i * J2;
            double miss = (double)eff[i] * (double)c->L.eff_step;
            for (j = 0; j < J2; ++j) miss -= ri[j] * c->theta0[j];
            c->r[i] = miss;
            for (j = 0; j <= i; ++j) {
                const double* rj = c->jac + (size_t)j * J2;
                double dot = 0.0;
                uint32_t q;
                for (q = 0; q < J2; ++q) dot += ri[q] * rj[q];
                c->m[(size_t)i * n + j] = dot;
                c->m[(size_t)j * n + i] = dot;
            }
            trace += c->m[(size_t)i * n + i];
        }
        if (trace > 0.0) {
            /* Damping keeps a straight (rank-deficient) chain and effector-less rows solvable. */
            double lambda = 1e-6 * trace / (double)n + 1e-12;
            for (i = 0; i < n; ++i) c->m[(size_t)i * n + i] += lambda;
            if (solve_spd(c->m, c->r, n)) {
                for (j = 0; j < J2; ++j) {
                    double add = 0.0;
                    for (i = 0; i < n; ++i) add += c->jac[(size_t)i * J2 + j] * c->r[i];
                    c->theta0[j] += add;
                }
            }
        }
    }
    for (s = 0; s < J; ++s) {
        pred[3u * s] = clampd(prev[3u * s] + c->theta0[2u * s]);
        pred[3u * s + 1u] = clampd(prev[3u * s + 1u] + c->theta0[2u * s + 1u]);
        pred[3u * s + 2u] = prev[3u * s + 2u];
    }
    for (i = 0; i < T3; ++i) {
        double x = prev[3u * J + i];
        if ((c->L.flags & 1u) && prev2) x += x - prev2[3u * J + i];
        pred[3u * J + i] = clampd(x);
    }
}

/* Decoded value from its prediction (0 for intra frames) and code: one expression for both
 * the encoder and the decoder. */
static void reconstruct(const ctx* c, const double* pred, const int32_t* ang, const int32_t* tr, double* out) {
    uint32_t i, J3 = 3u * c->L.joints, T3 = 3u * c->L.tracks;
    for (i = 0; i < J3; ++i) out[i] = clampd((pred ? pred[i] : 0.0) + (double)ang[i] * c->steps[i]);
    for (i = 0; i < T3; ++i)
        out[J3 + i] = clampd((pred ? pred[J3 + i] : 0.0) + (double)tr[i] * c->steps[J3 + i]);
}

/* ---------------------------------------------------------------- decoder */
static mcd_result load_block(ctx* c, uint32_t b) {
    block_streams s;
    uint32_t k;
    if (!block_info(&c->L, b, &s)) return MCD_ERROR_MALFORMED;
    for (k = 0; k < 3u; ++k) {
        if (s.values[k] == 0u) continue;
        if (mcd_entropy_decode(s.at[k], s.bytes[k], 3u, c->codes[k], s.values[k]) != MCD_OK) {
            c->st->block = -1;
            return MCD_ERROR_MALFORMED;
        }
    }
    c->st->block = (int32_t)b;
    return MCD_OK;
}

/* Decode frame f, the next frame of the run (or its intra start). */
static mcd_result decode_frame(ctx* c, uint32_t f) {
    uint32_t B = c->L.block_frames, row = f % B, J3 = 3u * c->L.joints, T3 = 3u * c->L.tracks;
    double* out = slot_vals(c, f);
    if (row == 0u) {
        mcd_result r = load_block(c, f / B);
        if (r != MCD_OK) return r;
        reconstruct(c, NULL, c->codes[1], c->codes[2], out);
    } else {
        double* pred = slot_vals(c, f + 1u); /* frame f - 2's slot: read before it is overwritten */
        const double* prev = slot_vals(c, f - 1u);
        const double* prev2 = row >= 2u ? slot_vals(c, f - 2u) : NULL;
        /* pred shares frame f - 2's slot with prev2: predict() reads every prev2 value it
         * needs before it writes the same index of pred. */
        predict(c, prev, prev2, c->codes[0] + (size_t)(row - 1u) * 3u * c->L.chains, pred);
        reconstruct(c, pred, c->codes[1] + (size_t)row * J3, c->codes[2] + (size_t)row * T3, out);
    }
    c->st->cur = (int32_t)f;
    return MCD_OK;
}

/* Make frames i0 and i1 (i1 = i0 or i0 + 1) the decoded ones: continue the current run when
 * it reaches them without leaving i0's block start behind, else restart at i0's intra frame. */
static mcd_result seek(ctx* c, uint32_t i0, uint32_t i1) {
    state* st = c->st;
    uint32_t start = i0 - i0 % c->L.block_frames;
    int ok = st->cur >= 0 && (uint32_t)st->cur <= i1 && (uint32_t)st->cur >= start &&
             ((uint32_t)st->cur <= i0 || i0 == i1 || st->cur - 1 >= st->run_start);
    if (!ok) {
        mcd_result r;
        st->run_start = (int32_t)start;
        r = decode_frame(c, start);
        if (r != MCD_OK) {
            st->cur = -1;
            return r;
        }
    }
    while ((uint32_t)st->cur < i1) {
        mcd_result r = decode_frame(c, (uint32_t)st->cur + 1u);
        if (r != MCD_OK) {
            st->cur = -1;
            return r;
        }
    }
    return MCD_OK;
}

/* ---------------------------------------------------------------- codec ops */
static int read_view(const mcd_clip_view* v, layout* L) {
    if (!read_layout(v->payload, v->payload_size, L)) return 0;
    L->skel = v->skeleton;
    return 1;
}

static mcd_result ikp_validate(const mcd_clip_view* v) {
    layout L;
    uint32_t b, k;
    if (!read_view(v, &L) || L.size != v->payload_size) return MCD_ERROR_MALFORMED;
    if (L.frames != v->frame_count || L.nodes != v->node_count) return MCD_ERROR_MALFORMED;
    if (!check_head(&L, v->payload) || !check_blocks(&L, v->payload)) return MCD_ERROR_MALFORMED;
    /* Streams are decoded lazily, a block at a time, when a sample needs it: check every one
     * here, so that sampling a validated asset cannot fail. */
    for (b = 0; b < L.blocks; ++b) {
        block_streams s;
        block_info(&L, b, &s);
        for (k = 0; k < 3u; ++k)
            if (s.values[k] && mcd_entropy_check(s.at[k], s.bytes[k], 3u, s.values[k]) != MCD_OK)
                return MCD_ERROR_MALFORMED;
    }
    return MCD_OK;
}

static size_t ikp_scratch_size(const mcd_clip_view* v) {
    layout L;
    size_t part[12];
    if (!read_view(v, &L)) return 0;
    return work_layout(&L, part);
}

static void blend(mcd_transform* a, const mcd_transform* b, uint32_t nodes, float t) {
    uint32_t i, k;
    for (i = 0; i < nodes; ++i) {
        float dot = 0.0f, n2 = 0.0f, sign;
        for (k = 0; k < 4u; ++k) dot += a[i].rotation[k] * b[i].rotation[k];
        sign = dot < 0.0f ? -1.0f : 1.0f;
        for (k = 0; k < 4u; ++k) {
            a[i].rotation[k] += (sign * b[i].rotation[k] - a[i].rotation[k]) * t;
            n2 += a[i].rotation[k] * a[i].rotation[k];
        }
        if (n2 > 1e-30f) {
            float inv = 1.0f / sqrtf(n2);
            for (k = 0; k < 4u; ++k) a[i].rotation[k] *= inv;
        } else {
            a[i].rotation[0] = a[i].rotation[1] = a[i].rotation[2] = 0.0f;
            a[i].rotation[3] = 1.0f;
        }
        for (k = 0; k < 3u; ++k) a[i].translation[k] += (b[i].translation[k] - a[i].translation[k]) * t;
    }
}

/* The coded frame g at or before frame position x and the fraction t of the way to the next:
 * the block by binary search on the blocks' first frames, then the gaps inside it. */
static void locate(const layout* L, float x, uint32_t* g_out, float* t_out) {
    uint32_t lo = 0, hi = L->blocks, g, f, next;
    if (L->coded == L->frames) {
        g = (uint32_t)x < L->frames - 1u ? (uint32_t)x : L->frames - 1u;
        *g_out = g;
        *t_out = g + 1u < L->frames ? x - (float)g : 0.0f;
        return;
    }
    while (hi - lo > 1u) { /* invariant: block lo starts at or before x, block hi after it */
        uint32_t mid = lo + (hi - lo) / 2u;
        if ((float)block_first_frame(L, mid) <= x) lo = mid; else hi = mid;
    }
    g = lo * L->block_frames;
    f = block_first_frame(L, lo);
    while (g + 1u < L->coded && (float)(f + gap_after(L, g)) <= x) {
        f += gap_after(L, g);
        g++;
    }
    next = g + 1u < L->coded ? f + gap_after(L, g) : f;
    *g_out = g;
    *t_out = next > f ? (x - (float)f) / (float)(next - f) : 0.0f;
    if (*t_out > 1.0f) *t_out = 1.0f;
}

/* The pose slot holding coded frame g, or -1. */
static int cached_pose(const ctx* c, uint32_t g) {
    if (c->st->pose_frame[0] == (int32_t)g) return 0;
    if (c->st->pose_frame[1] == (int32_t)g) return 1;
    return -1;
}

/* The local pose of coded frame g (decoded, or cached), computing it into the slot that does
 * not hold coded frame `keep`. The pose depends on the decoded values only, so a cached pose
 * is bit for bit the one a fresh decode gives. */
static const mcd_transform* pose_of(ctx* c, uint32_t g, uint32_t keep) {
    int s = cached_pose(c, g);
    if (s < 0) {
        s = c->st->pose_frame[0] == (int32_t)keep ? 1 : 0;
        frame_world(c, slot_vals(c, g));
        frame_local(c, slot_vals(c, g), c->poses + (size_t)s * c->L.nodes);
        c->st->pose_frame[s] = (int32_t)g;
    }
    return c->poses + (size_t)s * c->L.nodes;
}

static void ikp_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                       int fresh) {
    ctx c;
    uint32_t i0, i1, i;
    float t;
    (void)flags;
    read_view(v, &c.L); /* validated: cannot fail */
    ctx_bind(&c, (uint8_t*)scratch);
    if (fresh) ctx_reset(&c);
    locate(&c.L, x, &i0, &t);
    i1 = i0 + 1u < c.L.coded ? i0 + 1u : i0;
    if (!(t > 0.0f)) i1 = i0; /* on a coded frame: that frame alone, bit for bit */
    if ((cached_pose(&c, i0) < 0 || cached_pose(&c, i1) < 0) && seek(&c, i0, i1) != MCD_OK) {
        /* Only bytes that did not pass mcd_validate get here (MCD_OPEN_PREVALIDATED misused):
         * the rest pose, finite. */
        for (i = 0; i < c.L.nodes; ++i) mcd_skel_rest(v->skeleton, i, &out[i]);
        return;
    }
    memcpy(out, pose_of(&c, i0, i1), sizeof(mcd_transform) * c.L.nodes);
    if (i1 != i0) blend(out, pose_of(&c, i1, i0), c.L.nodes, t);
}

const mcd_codec_ops mcd_codec_ikpredict_ops = {
    MCD_CODEC_IK_PREDICT, 0x52504B49u /* "IKPR" */, 1u, NULL, ikp_validate, ikp_scratch_size, ikp_sample};

/* ---------------------------------------------------------------- encoder support */
static int encoder_layout(const uint8_t* head, size_t head_size, const uint8_t* skeleton,
                          size_t skeleton_size, layout* L) {
    uint32_t i;
    if (!head || !skeleton || !read_head(head, head_size, L) || L->head_size != head_size) return 0;
    if (skeleton_size < 16u + (size_t)MCD_SKEL_NODE_SIZE * L->nodes) return 0;
    L->skel = skeleton;
    for (i = 0; i < L->nodes; ++i) {
        int32_t p = parent_of(L, i);
        uint32_t k;
        if (p < -1 || p >= (int32_t)i) return 0;
        for (k = 0; k < 3u; ++k)
            if (!mcd_in_bounds((float)rest_offset(L, i, k))) return 0;
    }
    return check_head(L, head);
}

size_t mcd_ikp_work_size(const uint8_t* head, size_t head_size, const uint8_t* skeleton,
                         size_t skeleton_size) {
    layout L;
    size_t part[12];
    if (!encoder_layout(head, head_size, skeleton, skeleton_size, &L)) return 0;
    return work_layout(&L, part);
}

/* Root-relative world position of each chain's effector for the world rotations in c->world. */
static void effector_positions(const ctx* c, const double* v, double* p) {
    uint32_t ch, m, at = 0, k;
    for (ch = 0; ch < c->L.chains; ++ch) {
        uint32_t len = chain_length(&c->L, ch);
        double acc[3] = {0.0, 0.0, 0.0};
        for (m = 1; m < len; ++m) {
            uint32_t a = mcd_rd_u16(c->L.chain_nodes + 2u * (at + m - 1u));
            uint32_t b = mcd_rd_u16(c->L.chain_nodes + 2u * (at + m));
            double t[3], w[3];
            local_translation(c, v, b, t);
            qrotate(c->world + 4u * (size_t)a, t, w);
            for (k = 0; k < 3u; ++k) acc[k] += w[k];
        }
        for (k = 0; k < 3u; ++k) p[3u * ch + k] = acc[k];
        at += len;
    }
}

/* Nearest integer code of x (half away from zero), 0 when out of the coder's range. */
static int quantize(double x, int32_t* q) {
    double r = x < 0.0 ? -floor(-x + 0.5) : floor(x + 0.5);
    if (!(r >= -(double)MCD_ENTROPY_MAX_ABS && r <= (double)MCD_ENTROPY_MAX_ABS)) return 0;
    *q = (int32_t)r;
    return 1;
}

mcd_result mcd_ikp_closed_loop(const uint8_t* head, size_t head_size, const uint8_t* skeleton,
                               size_t skeleton_size, uint32_t frames, const double* targets,
                               const double* effectors, int32_t* codes, mcd_transform* poses,
                               void* work, size_t work_size) {
    ctx c;
    size_t part[12];
    uint32_t f, i, C3, V, W;
    if (!encoder_layout(head, head_size, skeleton, skeleton_size, &c.L)) return MCD_ERROR_INVALID_ARGUMENT;
    if (frames != c.L.coded || !targets || !codes || !work || ((uintptr_t)work & 15u) != 0)
        return MCD_ERROR_INVALID_ARGUMENT;
    if (c.L.chains && !effectors) return MCD_ERROR_INVALID_ARGUMENT;
    if (work_size < work_layout(&c.L, part)) return MCD_ERROR_BUFFER_TOO_SMALL;
    ctx_bind(&c, (uint8_t*)work);
    ctx_reset(&c);
    C3 = 3u * c.L.chains;
    W = 3u * (c.L.joints + c.L.tracks);
    V = C3 + W;
    for (f = 0; f < frames; ++f) {
        uint32_t row = f % c.L.block_frames;
        const double* target = targets + (size_t)f * W;
        int32_t* q = codes + (size_t)f * V;
        double* out = slot_vals(&c, f);
        double* pred = slot_vals(&c, f + 1u);
        if (row == 0u) {
            for (i = 0; i < C3; ++i) q[i] = 0;
            for (i = 0; i < W; ++i)
                if (!quantize(target[i] / c.steps[i], q + C3 + i)) return MCD_ERROR_OUT_OF_RANGE;
            reconstruct(&c, NULL, q + C3, q + C3 + 3u * c.L.joints, out);
        } else {
            const double* prev = slot_vals(&c, f - 1u);
            const double* prev2 = row >= 2u ? slot_vals(&c, f - 2u) : NULL;
            if (C3) {
                /* Effector codes against the decoded previous frame, so drift is corrected. */
                frame_world(&c, prev);
                effector_positions(&c, prev, c.r);
                for (i = 0; i < C3; ++i)
                    if (!quantize((effectors[(size_t)f * C3 + i] - c.r[i]) / (double)c.L.eff_step, q + i))
                        return MCD_ERROR_OUT_OF_RANGE;
            }
            predict(&c, prev, prev2, q, pred);
            for (i = 0; i < W; ++i)
                if (!quantize((target[i] - pred[i]) / c.steps[i], q + C3 + i)) return MCD_ERROR_OUT_OF_RANGE;
            reconstruct(&c, pred, q + C3, q + C3 + 3u * c.L.joints, out);
        }
        if (poses) {
            frame_world(&c, out);
            frame_local(&c, out, poses + (size_t)f * c.L.nodes);
        }
    }
    return MCD_OK;
}
