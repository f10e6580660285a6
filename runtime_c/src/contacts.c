/* Contact trajectories (docs/FORMAT.md "Contacts — CNTC section", seed 003 §5.3): after the
 * codec's local pose, each effector with an active contact is pulled to its stored target by IK
 * (analytic two-bone for ankles and wrists, damped least squares for toes and longer chains).
 *
 * A target is stored relative to the decoded (pre-IK) position of its joint at the same frame,
 * so the runtime needs no second decode: target = decoded + weight × step × offset. The IK math
 * runs in double: it is a handful of joints per sample, and double keeps the solvers exact to
 * far below the format's 0.1 cm step on any skeleton scale. */
#include <math.h>
#include <string.h>

#include "contacts.h"

/* ---------------------------------------------------------------- layout (FORMAT.md) */
#define SECTION_HEADER 8u
#define ENTRY_SIZE 8u
#define BLOCK_HEADER 16u
#define EFFECTOR_SIZE 8u
#define SEGMENT_SIZE 16u
#define MAX_STEP 1000.0f  /* |offset| ≤ step × (127 + 8 × 1023) stays below 1e7 */
#define MAX_BLEND 1000.0f /* frames */

/* Bytes of nibble deltas of a segment of `length` frames: 3 per frame after the first. */
static uint32_t delta_bytes(uint32_t length) {
    return (3u * (length - 1u) + 1u) / 2u;
}

/* Bytes of the offset caches at the start of the contact scratch (offset_cache is 24 bytes). */
#define CACHE_BYTES (MCD_CONTACTS_MAX_EFFECTORS * 24u)

size_t mcd_contacts_scratch_size(uint32_t max_nodes) {
    size_t n = CACHE_BYTES + (size_t)max_nodes * sizeof(mcd_transform);
    return (n + 15u) & ~(size_t)15u;
}

/* ---------------------------------------------------------------- validation */

static mcd_result check_block(const mcd_asset* a, uint32_t clip, const uint8_t* blk, uint32_t avail,
                              uint32_t* out_size) {
    const uint8_t* rec = a->data + a->clip_records + (size_t)clip * MCD_CLIP_RECORD_SIZE;
    const uint8_t* skel;
    uint32_t frames = mcd_rd_u32(rec + 24), nodes, k, seg_base, deltas_base, expect_seg = 0, expect_delta = 0;
    uint32_t effectors, segments, prev_node = 0, end;
    float step, blend;
    uint64_t fixed;
    skel = a->data + mcd_skeleton_offset(a, mcd_rd_u32(rec + 4));
    nodes = mcd_rd_u32(skel);
    if (avail < BLOCK_HEADER) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u32(blk) != frames) return MCD_ERROR_MALFORMED;
    step = mcd_rd_f32(blk + 4);
    blend = mcd_rd_f32(blk + 8);
    if (!mcd_finite(step) || !(step > 0.0f) || step > MAX_STEP) return MCD_ERROR_MALFORMED;
    if (!mcd_finite(blend) || !(blend >= 0.0f) || blend > MAX_BLEND) return MCD_ERROR_MALFORMED;
    effectors = mcd_rd_u16(blk + 12);
    segments = mcd_rd_u16(blk + 14);
    if (effectors < 1 || effectors > MCD_CONTACTS_MAX_EFFECTORS || segments < 1) return MCD_ERROR_MALFORMED;
    fixed = (uint64_t)BLOCK_HEADER + (uint64_t)effectors * EFFECTOR_SIZE + (uint64_t)segments * SEGMENT_SIZE;
    if (fixed > avail) return MCD_ERROR_MALFORMED;
    seg_base = BLOCK_HEADER + effectors * EFFECTOR_SIZE;
    deltas_base = (uint32_t)fixed;
    for (k = 0; k < effectors; ++k) {
        const uint8_t* e = blk + BLOCK_HEADER + (size_t)k * EFFECTOR_SIZE;
        uint32_t node = mcd_rd_u16(e), solver = e[2], chain = e[3], first = mcd_rd_u16(e + 4);
        uint32_t count = mcd_rd_u16(e + 6), j, s, prev_end = 0;
        int32_t p;
        if (node >= nodes || (k > 0 && node <= prev_node)) return MCD_ERROR_MALFORMED;
        prev_node = node;
        if (solver == MCD_CONTACTS_SOLVER_TWO_BONE) {
            if (chain != 2) return MCD_ERROR_MALFORMED;
        } else if (solver == MCD_CONTACTS_SOLVER_DLS) {
            if (chain < 1 || chain > MCD_CONTACTS_MAX_CHAIN) return MCD_ERROR_MALFORMED;
        } else {
            return MCD_ERROR_MALFORMED;
        }
        /* The node needs `chain` ancestors for its solver. */
        p = (int32_t)node;
        for (j = 0; j < chain; ++j) {
            p = mcd_skel_parent(skel, (uint32_t)p);
            if (p < 0) return MCD_ERROR_MALFORMED;
        }
        if (first != expect_seg || count < 1 || (uint64_t)first + count > segments) return MCD_ERROR_MALFORMED;
        expect_seg = first + count;
        for (s = first; s < first + count; ++s) {
            const uint8_t* g = blk + seg_base + (size_t)s * SEGMENT_SIZE;
            uint32_t start = mcd_rd_u32(g), doff = mcd_rd_u32(g + 4), len = mcd_rd_u16(g + 8), nb;
            if (len < 1 || len > MCD_CONTACTS_MAX_SEGMENT || start >= frames || (uint64_t)start + len > frames)
                return MCD_ERROR_MALFORMED;
            if (s > first && start < prev_end) return MCD_ERROR_MALFORMED; /* increasing, no overlap */
            prev_end = start + len;
            if (g[13] != 0 || mcd_rd_u16(g + 14) != 0) return MCD_ERROR_MALFORMED;
            if (doff != expect_delta) return MCD_ERROR_MALFORMED;
            nb = delta_bytes(len);
            if ((uint64_t)deltas_base + doff + nb > avail) return MCD_ERROR_MALFORMED;
            /* An odd nibble count leaves the last byte's high nibble unused: it must be zero. */
            if (((3u * (len - 1u)) & 1u) && (blk[deltas_base + doff + nb - 1u] >> 4) != 0) return MCD_ERROR_MALFORMED;
            expect_delta += nb;
        }
    }
    if (expect_seg != segments) return MCD_ERROR_MALFORMED;
    end = deltas_base + expect_delta;
    if ((uint32_t)mcd_align4(end) > avail) return MCD_ERROR_MALFORMED;
    for (k = end; k < (uint32_t)mcd_align4(end); ++k)
        if (blk[k] != 0) return MCD_ERROR_MALFORMED;
    *out_size = (uint32_t)mcd_align4(end);
    return MCD_OK;
}

mcd_result mcd_contacts_validate(const mcd_asset* a, const uint8_t* s, uint32_t size) {
    uint32_t count, i, expect, prev_clip = 0;
    if (size < SECTION_HEADER) return MCD_ERROR_MALFORMED;
    count = mcd_rd_u32(s);
    if (count < 1 || count > a->clip_count || mcd_rd_u32(s + 4) != 0) return MCD_ERROR_MALFORMED;
    if ((uint64_t)SECTION_HEADER + (uint64_t)count * ENTRY_SIZE > size) return MCD_ERROR_MALFORMED;
    expect = SECTION_HEADER + count * ENTRY_SIZE;
    for (i = 0; i < count; ++i) {
        const uint8_t* e = s + SECTION_HEADER + (size_t)i * ENTRY_SIZE;
        uint32_t clip = mcd_rd_u32(e), off = mcd_rd_u32(e + 4), used = 0;
        mcd_result r;
        if (clip >= a->clip_count || (i > 0 && clip <= prev_clip)) return MCD_ERROR_MALFORMED;
        prev_clip = clip;
        /* Blocks are packed in entry order: every byte of the section belongs to one place. */
        if (off != expect) return MCD_ERROR_MALFORMED;
        r = check_block(a, clip, s + off, size - off, &used);
        if (r != MCD_OK) return r;
        expect = off + used;
    }
    return expect == size ? MCD_OK : MCD_ERROR_MALFORMED;
}

/* ---------------------------------------------------------------- small double math */
static void v_sub(const double a[3], const double b[3], double o[3]) {
    o[0] = a[0] - b[0]; o[1] = a[1] - b[1]; o[2] = a[2] - b[2];
}
static double v_dot(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void v_cross(const double a[3], const double b[3], double o[3]) {
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    o[0] = x; o[1] = y; o[2] = z;
}
static double v_len(const double a[3]) {
    return sqrt(v_dot(a, a));
}

/* Rotation by |v| radians about v (identity for a zero vector). */
static mcd_dquat dq_from_rotvec(const double v[3]) {
    double angle = v_len(v), s;
    mcd_dquat q;
    if (!(angle > 1e-300)) return mcd_dq_identity();
    s = sin(0.5 * angle) / angle;
    q.x = v[0] * s; q.y = v[1] * s; q.z = v[2] * s; q.w = cos(0.5 * angle);
    return q;
}
/* Any unit vector perpendicular to unit u. */
static void perpendicular(const double u[3], double o[3]) {
    double axis[3] = {0.0, 0.0, 0.0}, n;
    axis[mcd_least_axis(u)] = 1.0;
    v_cross(u, axis, o);
    n = v_len(o);
    o[0] /= n; o[1] /= n; o[2] /= n;
}
/* Shortest rotation taking direction u onto direction v (identity if either is ~zero). */
static mcd_dquat dq_arc(const double u_in[3], const double v_in[3]) {
    double lu = v_len(u_in), lv = v_len(v_in), u[3], v[3], c[3], d, n;
    mcd_dquat q;
    if (!(lu > 1e-300) || !(lv > 1e-300)) return mcd_dq_identity();
    u[0] = u_in[0] / lu; u[1] = u_in[1] / lu; u[2] = u_in[2] / lu;
    v[0] = v_in[0] / lv; v[1] = v_in[1] / lv; v[2] = v_in[2] / lv;
    d = v_dot(u, v);
    if (d < -1.0 + 1e-12) { /* opposite: half a turn about any perpendicular */
        perpendicular(u, c);
        q.x = c[0]; q.y = c[1]; q.z = c[2]; q.w = 0.0;
        return q;
    }
    v_cross(u, v, c);
    q.x = c[0]; q.y = c[1]; q.z = c[2]; q.w = 1.0 + d;
    n = sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    q.x /= n; q.y /= n; q.z /= n; q.w /= n;
    return q;
}
static void load3(const float f[3], double d[3]) {
    d[0] = f[0]; d[1] = f[1]; d[2] = f[2];
}

/* ---------------------------------------------------------------- solvers */

void mcd_ik_two_bone(const float a_f[3], const float b_f[3], const float c_f[3], const float t_f[3], mcd_quat* da,
                     mcd_quat* db) {
    double a[3], b[3], c[3], t[3], u[3], v[3], n[3], at[3], c2[3], ac2[3], vr[3];
    double l1, l2, d, lo, hi, cos_now, cos_want, nl;
    mcd_dquat qb = mcd_dq_identity(), qa;
    load3(a_f, a); load3(b_f, b); load3(c_f, c); load3(t_f, t);
    v_sub(a, b, u); /* knee -> hip */
    v_sub(c, b, v); /* knee -> ankle */
    v_sub(t, a, at);
    l1 = v_len(u);
    l2 = v_len(v);
    *da = mcd_dq_to_quat(mcd_dq_identity());
    *db = *da;
    if (!(l1 > 1e-12) || !(l2 > 1e-12)) return; /* a zero-length bone has no angle to solve */
    /* Reachable distances from the hip; outside them the limb is straight (or folded). */
    d = v_len(at);
    lo = fabs(l1 - l2);
    hi = l1 + l2;
    if (d < lo) d = lo;
    if (d > hi) d = hi;
    /* Knee interior angle now and wanted (law of cosines), turned about the limb plane's normal. */
    cos_now = v_dot(u, v) / (l1 * l2);
    cos_want = (l1 * l1 + l2 * l2 - d * d) / (2.0 * l1 * l2);
    cos_now = cos_now < -1.0 ? -1.0 : cos_now > 1.0 ? 1.0 : cos_now;
    cos_want = cos_want < -1.0 ? -1.0 : cos_want > 1.0 ? 1.0 : cos_want;
    v_cross(u, v, n);
    nl = v_len(n);
    if (!(nl > 1e-9 * l1 * l2)) {
        /* Straight or folded limb: no plane to keep. Bend towards the target's side. */
        v_cross(u, at, n);
        nl = v_len(n);
        if (!(nl > 1e-9 * l1 * v_len(at))) {
            double uu[3];
            uu[0] = u[0] / l1; uu[1] = u[1] / l1; uu[2] = u[2] / l1;
            perpendicular(uu, n);
            nl = 1.0;
        }
    }
    n[0] /= nl; n[1] /= nl; n[2] /= nl;
    /* Rotating v about u × v by +δ opens the angle between u and v by δ. */
    {
        double delta = acos(cos_want) - acos(cos_now), rv[3];
        rv[0] = n[0] * delta; rv[1] = n[1] * delta; rv[2] = n[2] * delta;
        qb = dq_from_rotvec(rv);
    }
    mcd_dq_rotate(qb, v, vr);
    c2[0] = b[0] + vr[0]; c2[1] = b[1] + vr[1]; c2[2] = b[2] + vr[2];
    /* Then swing the whole limb about the hip so the ankle points at the target. */
    v_sub(c2, a, ac2);
    qa = dq_arc(ac2, at);
    *da = mcd_dq_to_quat(qa);
    *db = mcd_dq_to_quat(qb);
}

/* Solve (A + λ²I) y = r for symmetric 3×3 A by Cramer's rule; the damping keeps it regular. */
static void solve3(double m[3][3], const double r[3], double y[3]) {
    double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                 m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    int k;
    if (!(fabs(det) > 1e-300)) {
        y[0] = y[1] = y[2] = 0.0;
        return;
    }
    for (k = 0; k < 3; ++k) {
        double c[3][3];
        int i, j;
        for (i = 0; i < 3; ++i)
            for (j = 0; j < 3; ++j) c[i][j] = j == k ? r[i] : m[i][j];
        y[k] = (c[0][0] * (c[1][1] * c[2][2] - c[1][2] * c[2][1]) - c[0][1] * (c[1][0] * c[2][2] - c[1][2] * c[2][0]) +
                c[0][2] * (c[1][0] * c[2][1] - c[1][1] * c[2][0])) / det;
    }
}

void mcd_ik_dls(uint32_t count, const float joints[][3], const float e_f[3], const float t_f[3], mcd_quat* d,
                float e_out[3]) {
    double p[MCD_CONTACTS_MAX_CHAIN][3], e[3], t[3], err[3];
    mcd_dquat acc[MCD_CONTACTS_MAX_CHAIN];
    uint32_t j, k, it;
    if (count > MCD_CONTACTS_MAX_CHAIN) count = MCD_CONTACTS_MAX_CHAIN;
    for (j = 0; j < count; ++j) {
        load3(joints[j], p[j]);
        acc[j] = mcd_dq_identity();
    }
    load3(e_f, e);
    load3(t_f, t);
    for (it = 0; it < MCD_CONTACTS_DLS_ITERATIONS && count > 0; ++it) {
        double m[3][3] = {{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}}, r[MCD_CONTACTS_MAX_CHAIN][3], y[3];
        double theta[MCD_CONTACTS_MAX_CHAIN][3], trace, lambda2, biggest = 0.0, scale = 1.0;
        v_sub(t, e, err);
        /* J_j = [e_k × r_j] for the three world axes, so J_j J_jᵀ = |r|² I − r rᵀ. */
        for (j = 0; j < count; ++j) {
            double rr;
            uint32_t i;
            v_sub(e, p[j], r[j]);
            rr = v_dot(r[j], r[j]);
            for (i = 0; i < 3; ++i)
                for (k = 0; k < 3; ++k) m[i][k] += (i == k ? rr : 0.0) - r[j][i] * r[j][k];
        }
        trace = m[0][0] + m[1][1] + m[2][2];
        if (!(trace > 1e-300)) break; /* effector on every joint: nothing can move it */
        /* Close enough: a millionth of the chain's reach (trace ~ its squared lever arms). */
        if (v_dot(err, err) <= 1e-12 * trace) break;
        /* Damping relative to the chain's own scale: units do not matter. */
        lambda2 = 1e-3 * trace / 3.0;
        m[0][0] += lambda2; m[1][1] += lambda2; m[2][2] += lambda2;
        solve3(m, err, y);
        /* θ_j = J_jᵀ y = r_j × y. Large steps are scaled down so no joint turns more than 0.5 rad. */
        for (j = 0; j < count; ++j) {
            double l;
            v_cross(r[j], y, theta[j]);
            l = v_len(theta[j]);
            if (l > biggest) biggest = l;
        }
        /* Converged (or at the closest point of an unreachable target): stop early. */
        if (!(biggest > 1e-7)) break;
        if (biggest > 0.5) scale = 0.5 / biggest;
        for (j = 0; j < count; ++j) {
            double rv[3], rel[3], out[3];
            mcd_dquat q;
            uint32_t i;
            rv[0] = theta[j][0] * scale; rv[1] = theta[j][1] * scale; rv[2] = theta[j][2] * scale;
            q = dq_from_rotvec(rv);
            /* The rotation about joint j carries every joint after it and the effector. */
            for (i = j + 1; i < count; ++i) {
                v_sub(p[i], p[j], rel);
                mcd_dq_rotate(q, rel, out);
                p[i][0] = p[j][0] + out[0]; p[i][1] = p[j][1] + out[1]; p[i][2] = p[j][2] + out[2];
            }
            v_sub(e, p[j], rel);
            mcd_dq_rotate(q, rel, out);
            e[0] = p[j][0] + out[0]; e[1] = p[j][1] + out[1]; e[2] = p[j][2] + out[2];
            for (i = j; i < count; ++i) acc[i] = mcd_dq_mul(q, acc[i]);
        }
    }
    for (j = 0; j < count; ++j) d[j] = mcd_dq_to_quat(acc[j]);
    e_out[0] = (float)e[0]; e_out[1] = (float)e[1]; e_out[2] = (float)e[2];
}

/* ---------------------------------------------------------------- sampling */

static void set_rot(mcd_transform* t, mcd_quat q) {
    float n = sqrtf(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
    if (!(n > 0.0f) || !mcd_finite(n)) {
        q.x = q.y = q.z = 0.0f; q.w = 1.0f; n = 1.0f;
    }
    t->rotation[0] = q.x / n; t->rotation[1] = q.y / n; t->rotation[2] = q.z / n; t->rotation[3] = q.w / n;
}
/* World transforms from local ones (the same arithmetic as mcd_sample's MCD_SAMPLE_WORLD) of
 * the nodes in `need` (a set closed under parents: the paths from the roots to the effectors,
 * all the contact pass reads). With first > 0, only the part of it under node `first`, after
 * an IK changed that subtree. Parents come first, so one pass in index order suffices. */
static void forward(const uint8_t* skeleton, uint32_t nodes, const mcd_transform* local, mcd_transform* world,
                    const uint8_t* need, uint32_t first) {
    uint8_t moved[MCD_MAX_NODES / 8u];
    uint32_t i;
    memset(moved, 0, sizeof moved);
    for (i = first; i < nodes; ++i) {
        int32_t parent;
        if (!(need[i >> 3] & (1u << (i & 7u)))) continue;
        parent = mcd_skel_parent(skeleton, i);
        if (first > 0 && i != first && (parent < 0 || !(moved[(uint32_t)parent >> 3] & (1u << ((uint32_t)parent & 7u)))))
            continue;
        moved[i >> 3] |= (uint8_t)(1u << (i & 7u));
        if (parent >= 0)
            mcd_compose(&world[parent], &local[i], &world[i]);
        else
            world[i] = local[i];
    }
}

/* Integer offset (in steps) of segment frame k: the start plus the first k nibble deltas. */
static void segment_offset(const uint8_t* g, const uint8_t* deltas, uint32_t k, int32_t o[3]) {
    const uint8_t* dd = deltas + mcd_rd_u32(g + 4);
    uint32_t n;
    o[0] = (int8_t)g[10]; o[1] = (int8_t)g[11]; o[2] = (int8_t)g[12];
    for (n = 0; n < 3u * k; ++n) {
        uint32_t nib = (n & 1u) ? (uint32_t)(dd[n >> 1] >> 4) : (uint32_t)(dd[n >> 1] & 15u);
        o[n % 3u] += nib >= 8u ? (int32_t)nib - 16 : (int32_t)nib;
    }
}

/* Sequential playback cache, one per effector, in the contact scratch: the integer offset at
 * segment frame k of a segment, so the next sample continues the delta walk instead of
 * restarting it. The sums are exact integers, so the result never depends on the cache. */
typedef struct offset_cache {
    uint32_t clip_plus1; /* 0: empty (mcd_scratch_init zeroes the scratch) */
    uint32_t segment;
    uint32_t k;
    int32_t o[3];
} offset_cache;

typedef char offset_cache_fits[sizeof(offset_cache) == 24u ? 1 : -1];

static void cached_offset(offset_cache* c, uint32_t clip, uint32_t segment, const uint8_t* g, const uint8_t* deltas,
                          uint32_t k, int32_t o[3]) {
    const uint8_t* dd = deltas + mcd_rd_u32(g + 4);
    uint32_t n, from = 0;
    if (c->clip_plus1 == clip + 1u && c->segment == segment && c->k <= k) {
        from = c->k;
        o[0] = c->o[0]; o[1] = c->o[1]; o[2] = c->o[2];
    } else {
        o[0] = (int8_t)g[10]; o[1] = (int8_t)g[11]; o[2] = (int8_t)g[12];
    }
    for (n = 3u * from; n < 3u * k; ++n) {
        uint32_t nib = (n & 1u) ? (uint32_t)(dd[n >> 1] >> 4) : (uint32_t)(dd[n >> 1] & 15u);
        o[n % 3u] += nib >= 8u ? (int32_t)nib - 16 : (int32_t)nib;
    }
    c->clip_plus1 = clip + 1u;
    c->segment = segment;
    c->k = k;
    c->o[0] = o[0]; c->o[1] = o[1]; c->o[2] = o[2];
}

/* The offset one frame on: b = a plus the deltas of segment frame k + 1. */
static void segment_next(const uint8_t* g, const uint8_t* deltas, uint32_t k, const int32_t a[3], int32_t b[3]) {
    const uint8_t* dd = deltas + mcd_rd_u32(g + 4);
    uint32_t n, c;
    for (c = 0; c < 3; ++c) {
        uint32_t nib;
        n = 3u * k + c;
        nib = (n & 1u) ? (uint32_t)(dd[n >> 1] >> 4) : (uint32_t)(dd[n >> 1] & 15u);
        b[c] = a[c] + (nib >= 8u ? (int32_t)nib - 16 : (int32_t)nib);
    }
}

/* IK weight at distance `dist` frames outside a segment: 1 at its edge, 0 from `blend` on,
 * smoothstep between (no velocity jump where IK starts or stops). */
static float ramp(float dist, float blend) {
    float s;
    if (!(dist < blend)) return 0.0f;
    s = 1.0f - dist / blend;
    return s * s * (3.0f - 2.0f * s);
}

/* Weight and offset (in steps) of one effector at frame position x. */
static float effector_state(const uint8_t* seg, const uint8_t* deltas, uint32_t first, uint32_t count, float x,
                            float blend, float off[3], offset_cache* cache, uint32_t clip) {
    uint32_t f0 = (uint32_t)x, lo = 0, hi = count, i, end;
    float fr = x - (float)f0;
    const uint8_t* g;
    int32_t a[3], b[3];
    /* Last segment starting at or before frame f0 (binary search: segments are increasing). */
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2u;
        if (mcd_rd_u32(seg + (size_t)(first + mid) * SEGMENT_SIZE) <= f0) lo = mid + 1u; else hi = mid;
    }
    if (lo > 0) {
        i = first + lo - 1u;
        g = seg + (size_t)i * SEGMENT_SIZE;
        end = mcd_rd_u32(g) + mcd_rd_u16(g + 8) - 1u;
        if (f0 < end || (f0 == end && fr == 0.0f)) { /* inside the segment */
            uint32_t k = f0 - mcd_rd_u32(g);
            cached_offset(cache, clip, i, g, deltas, k, a);
            if (fr > 0.0f) {
                segment_next(g, deltas, k, a, b);
            } else {
                b[0] = a[0]; b[1] = a[1]; b[2] = a[2];
            }
            off[0] = (float)a[0] + fr * (float)(b[0] - a[0]);
            off[1] = (float)a[1] + fr * (float)(b[1] - a[1]);
            off[2] = (float)a[2] + fr * (float)(b[2] - a[2]);
            return 1.0f;
        }
        if (f0 == end) {
            cached_offset(cache, clip, i, g, deltas, end - mcd_rd_u32(g), a);
            if (lo < count && mcd_rd_u32(seg + (size_t)(i + 1u) * SEGMENT_SIZE) == end + 1u) {
                /* The next segment starts on the next frame: cross over linearly. */
                segment_offset(seg + (size_t)(i + 1u) * SEGMENT_SIZE, deltas, 0, b);
                off[0] = (float)a[0] + fr * (float)(b[0] - a[0]);
                off[1] = (float)a[1] + fr * (float)(b[1] - a[1]);
                off[2] = (float)a[2] + fr * (float)(b[2] - a[2]);
                return 1.0f;
            }
        }
        /* After segment i: held at its last offset, fading out. */
        {
            float d_after = x - (float)end, w_after = ramp(d_after, blend), w_next = 0.0f;
            if (lo < count) {
                const uint8_t* n = seg + (size_t)(i + 1u) * SEGMENT_SIZE;
                w_next = ramp((float)mcd_rd_u32(n) - x, blend);
                if (w_next > w_after) {
                    segment_offset(n, deltas, 0, a);
                    off[0] = (float)a[0]; off[1] = (float)a[1]; off[2] = (float)a[2];
                    return w_next;
                }
            }
            if (w_after <= 0.0f) return 0.0f;
            cached_offset(cache, clip, i, g, deltas, end - mcd_rd_u32(g), a);
            off[0] = (float)a[0]; off[1] = (float)a[1]; off[2] = (float)a[2];
            return w_after;
        }
    }
    /* Before the first segment: held at its first offset, fading in. */
    g = seg + (size_t)first * SEGMENT_SIZE;
    {
        float w = ramp((float)mcd_rd_u32(g) - x, blend);
        if (w <= 0.0f) return 0.0f;
        segment_offset(g, deltas, 0, a);
        off[0] = (float)a[0]; off[1] = (float)a[1]; off[2] = (float)a[2];
        return w;
    }
}

/* Write the IK result back: chain[j]'s new world rotation is d[j] ⊗ old; the effector keeps
 * its world rotation (a planted foot does not tilt because the knee moved). */
static void write_chain(const uint8_t* skeleton, const mcd_transform* world, mcd_transform* local,
                        const uint32_t* chain, uint32_t count, const mcd_quat* d, uint32_t effector) {
    mcd_quat nw[MCD_CONTACTS_MAX_CHAIN];
    uint32_t j;
    int32_t p0 = mcd_skel_parent(skeleton, chain[0]);
    for (j = 0; j < count; ++j) nw[j] = mcd_qmul(d[j], mcd_quat_of(&world[chain[j]]));
    set_rot(&local[chain[0]], p0 >= 0 ? mcd_qmul(mcd_qconj(mcd_quat_of(&world[p0])), nw[0]) : nw[0]);
    for (j = 1; j < count; ++j) set_rot(&local[chain[j]], mcd_qmul(mcd_qconj(nw[j - 1]), nw[j]));
    set_rot(&local[effector], mcd_qmul(mcd_qconj(nw[count - 1]), mcd_quat_of(&world[effector])));
}

void mcd_contacts_apply(const uint8_t* s, uint32_t size, uint32_t clip, const mcd_clip_view* view, float x,
                        mcd_transform* local, void* scratch) {
    /* Contact scratch: the offset caches, then the world pose. */
    offset_cache* cache = (offset_cache*)scratch;
    mcd_transform* world = (mcd_transform*)((uint8_t*)scratch + CACHE_BYTES);
    uint32_t count = mcd_rd_u32(s), lo = 0, hi = count, k, effectors, active = 0;
    const uint8_t *blk, *seg, *deltas;
    float step, blend, weight[MCD_CONTACTS_MAX_EFFECTORS], target[MCD_CONTACTS_MAX_EFFECTORS][3];
    uint8_t need[MCD_MAX_NODES / 8u];
    (void)size;
    /* The entry table is sorted by clip: binary search, no allocation. */
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2u;
        if (mcd_rd_u32(s + SECTION_HEADER + (size_t)mid * ENTRY_SIZE) < clip) lo = mid + 1u; else hi = mid;
    }
    if (lo >= count || mcd_rd_u32(s + SECTION_HEADER + (size_t)lo * ENTRY_SIZE) != clip) return;
    blk = s + mcd_rd_u32(s + SECTION_HEADER + (size_t)lo * ENTRY_SIZE + 4);
    step = mcd_rd_f32(blk + 4);
    blend = mcd_rd_f32(blk + 8);
    effectors = mcd_rd_u16(blk + 12);
    seg = blk + BLOCK_HEADER + (size_t)effectors * EFFECTOR_SIZE;
    deltas = seg + (size_t)mcd_rd_u16(blk + 14) * SEGMENT_SIZE;
    /* Weights and offsets first: no world pose is needed unless a contact is active. */
    for (k = 0; k < effectors; ++k) {
        const uint8_t* e = blk + BLOCK_HEADER + (size_t)k * EFFECTOR_SIZE;
        weight[k] = effector_state(seg, deltas, mcd_rd_u16(e + 4), mcd_rd_u16(e + 6), x, blend, target[k],
                                   &cache[k], clip);
        if (weight[k] > 0.0f) active++;
    }
    if (active == 0) return;
    /* The nodes the pass reads: every active effector and its ancestors. */
    memset(need, 0, sizeof need);
    for (k = 0; k < effectors; ++k) {
        int32_t n = (int32_t)mcd_rd_u16(blk + BLOCK_HEADER + (size_t)k * EFFECTOR_SIZE);
        if (weight[k] <= 0.0f) continue;
        while (n >= 0 && !(need[(uint32_t)n >> 3] & (1u << ((uint32_t)n & 7u)))) {
            need[(uint32_t)n >> 3] |= (uint8_t)(1u << ((uint32_t)n & 7u));
            n = mcd_skel_parent(view->skeleton, (uint32_t)n);
        }
    }
    forward(view->skeleton, view->node_count, local, world, need, 0);
    /* Every target comes from the pre-IK pose: the encoder stored them against it. */
    for (k = 0; k < effectors; ++k) {
        const float* p = world[mcd_rd_u16(blk + BLOCK_HEADER + (size_t)k * EFFECTOR_SIZE)].translation;
        float w = weight[k] * step;
        if (weight[k] <= 0.0f) continue;
        target[k][0] = p[0] + w * target[k][0];
        target[k][1] = p[1] + w * target[k][1];
        target[k][2] = p[2] + w * target[k][2];
    }
    for (k = 0; k < effectors; ++k) {
        const uint8_t* e = blk + BLOCK_HEADER + (size_t)k * EFFECTOR_SIZE;
        uint32_t node = mcd_rd_u16(e), solver = e[2], chain_len = e[3], chain[MCD_CONTACTS_MAX_CHAIN], j, m;
        mcd_quat d[MCD_CONTACTS_MAX_CHAIN];
        int32_t p = (int32_t)node;
        if (weight[k] <= 0.0f) continue;
        /* A toe whose ankle is held by its own contact turns only the foot, so the ankle stays. */
        if (solver == MCD_CONTACTS_SOLVER_DLS) {
            int32_t parent = mcd_skel_parent(view->skeleton, node);
            for (m = 0; m < k; ++m)
                if ((int32_t)mcd_rd_u16(blk + BLOCK_HEADER + (size_t)m * EFFECTOR_SIZE) == parent && weight[m] > 0.0f)
                    chain_len = 1;
        }
        for (j = chain_len; j-- > 0;) {
            p = mcd_skel_parent(view->skeleton, (uint32_t)p);
            chain[j] = (uint32_t)p;
        }
        if (solver == MCD_CONTACTS_SOLVER_TWO_BONE) {
            mcd_quat da, db;
            mcd_ik_two_bone(world[chain[0]].translation, world[chain[1]].translation, world[node].translation,
                            target[k], &da, &db);
            d[0] = da;
            d[1] = mcd_qmul(da, db);
        } else {
            float joints[MCD_CONTACTS_MAX_CHAIN][3], reached[3];
            for (j = 0; j < chain_len; ++j) memcpy(joints[j], world[chain[j]].translation, sizeof joints[j]);
            mcd_ik_dls(chain_len, (const float(*)[3])joints, world[node].translation, target[k], d, reached);
        }
        write_chain(view->skeleton, world, local, chain, chain_len, d, node);
        if (--active > 0) forward(view->skeleton, view->node_count, local, world, need, chain[0]);
    }
}
