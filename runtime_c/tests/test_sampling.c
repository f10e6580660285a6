/* Sampling semantics (docs/FORMAT.md "CLIP", mocodec.h mcd_sample), the sequential cache
 * (results must not depend on the order of calls) and thread safety. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "../src/internal.h" /* mcd_compose and its scalar reference; the tests build with -Iinclude only */
#include "harness.h"

#define MAX_NODES 1024u
#define ALL_FLAGS 8u /* every combination of WORLD, LOOP, NEAREST */

/* Sample with a scratch initialised just before: the reference that no cache state can touch. */
static int sample_cold(const mcd_asset* a, uint32_t clip, float t, uint32_t flags, mcd_transform* out, void* scratch) {
    if (mcd_scratch_init(a, scratch, mcd_scratch_size(a)) != MCD_OK) return 0;
    return mcd_sample(a, clip, t, flags, out, MAX_NODES, scratch) == MCD_OK;
}

static int same_pose(const mcd_transform* x, const mcd_transform* y, uint32_t n) {
    return memcmp(x, y, (size_t)n * sizeof *x) == 0;
}

static float component(const mcd_transform* t, uint32_t k) {
    return k < 4 ? t->rotation[k] : k < 7 ? t->translation[k - 4] : t->scale[k - 7];
}

/* Largest |x - y| over every float, relative to max(1, |y|). */
static double pose_distance(const mcd_transform* x, const mcd_transform* y, uint32_t n) {
    double worst = 0.0;
    uint32_t i, k;
    for (i = 0; i < n; ++i) {
        for (k = 0; k < 10; ++k) {
            double vx = component(&x[i], k), vy = component(&y[i], k);
            double d = fabs(vx - vy) / (fabs(vy) > 1.0 ? fabs(vy) : 1.0);
            if (d > worst) worst = d;
        }
    }
    return worst;
}

typedef struct clip_ctx {
    const mcd_asset* a;
    uint32_t clip;
    mcd_clip_info info;
    void* scratch;
    mcd_transform p[MAX_NODES], q[MAX_NODES];
} clip_ctx;

/* Exactly equal results of (t1, f1) and (t2, f2). */
static void expect_same(clip_ctx* c, float t1, uint32_t f1, float t2, uint32_t f2, const char* what) {
    if (!sample_cold(c->a, c->clip, t1, f1, c->p, c->scratch) || !sample_cold(c->a, c->clip, t2, f2, c->q, c->scratch)) {
        FAIL("clip %u: sampling failed (%s)", c->clip, what);
        return;
    }
    CHECK_MSG(same_pose(c->p, c->q, c->info.node_count), "clip %u: %s: t=%.9g flags %u differs from t=%.9g flags %u (by %g)",
              c->clip, what, t1, f1, t2, f2, pose_distance(c->p, c->q, c->info.node_count));
}

static void expect_close(clip_ctx* c, float t1, float t2, uint32_t flags, double tol, const char* what) {
    double d;
    if (!sample_cold(c->a, c->clip, t1, flags, c->p, c->scratch) || !sample_cold(c->a, c->clip, t2, flags, c->q, c->scratch)) {
        FAIL("clip %u: sampling failed (%s)", c->clip, what);
        return;
    }
    d = pose_distance(c->p, c->q, c->info.node_count);
    CHECK_MSG(d <= tol, "clip %u: %s: t=%.9g and t=%.9g differ by %g", c->clip, what, t1, t2, d);
}

static float frame_time(const clip_ctx* c, double frame) {
    return (float)(frame / (double)c->info.frame_rate);
}

static void check_clamp_and_loop(clip_ctx* c) {
    const float last = frame_time(c, (double)c->info.frame_count - 1.0);
    const float dur = c->info.duration;
    uint32_t f, k;
    for (f = 0; f < ALL_FLAGS; ++f) {
        if (f & MCD_SAMPLE_LOOP) continue;
        expect_same(c, -0.25f, f, 0.0f, f, "clamp before 0");
        expect_same(c, -1e6f, f, 0.0f, f, "clamp far before 0");
        expect_same(c, dur + 0.5f, f, last, f, "clamp past the end");
        expect_same(c, 1e6f, f, last, f, "clamp far past the end");
        expect_same(c, dur, f, last, f, "duration is the last frame");
    }
    /* Loop: the clip repeats with period duration = (F - 1) / rate; the instant of the wrap
     * shows frame 0. Integer frames snap exactly; between frames the time arithmetic rounds,
     * so compare with a tolerance far below one frame's motion. */
    expect_same(c, dur, MCD_SAMPLE_LOOP, 0.0f, MCD_SAMPLE_LOOP, "loop at the duration shows frame 0");
    expect_same(c, last, MCD_SAMPLE_LOOP, 0.0f, MCD_SAMPLE_LOOP, "loop at the last frame shows frame 0");
    for (k = 0; k + 1u < c->info.frame_count; k += 7u) {
        uint32_t f2 = MCD_SAMPLE_LOOP | (k & 1u ? MCD_SAMPLE_WORLD : 0u);
        expect_same(c, dur + frame_time(c, k), f2, frame_time(c, k), f2, "loop one period later");
        expect_same(c, frame_time(c, k) - dur, f2, frame_time(c, k), f2, "loop one period earlier");
        expect_close(c, frame_time(c, k) + 3.0f * dur, frame_time(c, k), f2, 1e-3, "loop three periods later");
        expect_close(c, dur + frame_time(c, k + 0.25), frame_time(c, k + 0.25), f2, 1e-3, "loop between frames");
        expect_close(c, frame_time(c, k + 0.75) - dur, frame_time(c, k + 0.75), f2, 1e-3, "negative loop between frames");
    }
    if (c->info.frame_count > 1) {
        expect_same(c, -0.25f, MCD_SAMPLE_LOOP, dur - 0.25f, MCD_SAMPLE_LOOP, "negative times wrap");
    }
}

static void check_nearest_and_snap(clip_ctx* c) {
    uint32_t k, f;
    for (k = 0; k + 1u < c->info.frame_count; k += 3u) {
        for (f = 0; f < ALL_FLAGS; ++f) {
            double frac = (k % 2u) ? 0.3 : 0.7;
            float t = frame_time(c, k + frac);
            float x = t * c->info.frame_rate, rounded = floorf(x + 0.5f);
            if (!(f & MCD_SAMPLE_NEAREST)) continue;
            expect_same(c, t, f, frame_time(c, rounded), f & ~MCD_SAMPLE_NEAREST, "nearest is the rounded frame");
        }
        /* A position within 1e-4 of an integer frame is that frame (docs/FORMAT.md). */
        expect_same(c, frame_time(c, k + 5e-5), 0, frame_time(c, k), 0, "snap to the frame");
    }
}

/* World transforms composed here from local ones, in double: parent first (docs/FORMAT.md). */
static void check_world(clip_ctx* c) {
    int32_t parent[MAX_NODES];
    uint32_t n, k, i;
    for (n = 0; n < c->info.node_count; ++n) {
        mcd_node_info ni;
        CHECK_RESULT(mcd_get_node_info(c->a, c->info.skeleton, n, &ni), MCD_OK);
        parent[n] = ni.parent;
    }
    for (k = 0; k < 2u * c->info.frame_count - 1u; k += 5u) {
        double wq[MAX_NODES][4], wt[MAX_NODES][3];
        float t = frame_time(c, 0.5 * k);
        if (!sample_cold(c->a, c->clip, t, 0, c->p, c->scratch) ||
            !sample_cold(c->a, c->clip, t, MCD_SAMPLE_WORLD, c->q, c->scratch)) {
            FAIL("sampling failed");
            return;
        }
        for (n = 0; n < c->info.node_count; ++n) {
            const float* lq = c->p[n].rotation;
            const float* lt = c->p[n].translation;
            double worst = 0.0;
            if (parent[n] < 0) {
                for (i = 0; i < 4; ++i) wq[n][i] = lq[i];
                for (i = 0; i < 3; ++i) wt[n][i] = lt[i];
            } else {
                const double* pq = wq[parent[n]];
                const double* pt = wt[parent[n]];
                /* v' = v + 2w (u x v) + 2 u x (u x v), u = (x, y, z) of the unit parent rotation */
                double cx = pq[1] * lt[2] - pq[2] * lt[1], cy = pq[2] * lt[0] - pq[0] * lt[2], cz = pq[0] * lt[1] - pq[1] * lt[0];
                double ccx = pq[1] * cz - pq[2] * cy, ccy = pq[2] * cx - pq[0] * cz, ccz = pq[0] * cy - pq[1] * cx;
                wt[n][0] = pt[0] + lt[0] + 2.0 * (pq[3] * cx + ccx);
                wt[n][1] = pt[1] + lt[1] + 2.0 * (pq[3] * cy + ccy);
                wt[n][2] = pt[2] + lt[2] + 2.0 * (pq[3] * cz + ccz);
                /* parent (x) local: the local rotation applies first */
                wq[n][0] = pq[3] * lq[0] + pq[0] * lq[3] + pq[1] * lq[2] - pq[2] * lq[1];
                wq[n][1] = pq[3] * lq[1] - pq[0] * lq[2] + pq[1] * lq[3] + pq[2] * lq[0];
                wq[n][2] = pq[3] * lq[2] + pq[0] * lq[1] - pq[1] * lq[0] + pq[2] * lq[3];
                wq[n][3] = pq[3] * lq[3] - pq[0] * lq[0] - pq[1] * lq[1] - pq[2] * lq[2];
            }
            /* 1e-5 absolute, and for translations 1e-6 relative on top (the golden tolerance):
             * float rounding grows with the magnitude of the positions composed along the chain */
            for (i = 0; i < 4; ++i) {
                double d = fabs(wq[n][i] - c->q[n].rotation[i]);
                if (d > worst) worst = d;
            }
            for (i = 0; i < 3; ++i) {
                double d = fabs(wt[n][i] - c->q[n].translation[i]) / (1.0 + 1e-1 * fabs(wt[n][i]));
                if (d > worst) worst = d;
            }
            CHECK_MSG(worst <= 1e-5, "clip %u t=%.9g node %u: world differs from composed local by %g", c->clip, t, n, worst);
        }
    }
}

static void check_unit(clip_ctx* c) {
    uint32_t k, n, f;
    size_t count;
    float* times = mcd_test_frame_times(&c->info, &count);
    for (f = 0; f <= MCD_SAMPLE_WORLD; ++f) {
        for (k = 0; k < count; ++k) {
            double worst = 0.0;
            if (mcd_sample(c->a, c->clip, times[k], f, c->p, MAX_NODES, c->scratch) != MCD_OK) {
                FAIL("sampling failed");
                break;
            }
            for (n = 0; n < c->info.node_count; ++n) {
                const float* q = c->p[n].rotation;
                double d = fabs(sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] + (double)q[3] * q[3]) - 1.0);
                if (d > worst) worst = d;
            }
            CHECK(mcd_test_pose_finite(c->p, c->info.node_count));
            CHECK_MSG(worst <= 1e-4, "clip %u t=%.9g flags %u: |q| - 1 = %g", c->clip, times[k], f, worst);
        }
    }
    free(times);
}

void test_sampling_semantics(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    clip_ctx* c = (clip_ctx*)malloc(sizeof *c);
    for (i = 0; c && i < n; ++i) {
        c->a = &g[i].asset;
        c->scratch = mcd_test_scratch(c->a);
        for (c->clip = 0; c->scratch && c->clip < mcd_clip_count(c->a); ++c->clip) {
            CHECK_RESULT(mcd_get_clip_info(c->a, c->clip, &c->info), MCD_OK);
            check_clamp_and_loop(c);
            check_nearest_and_snap(c);
            check_world(c);
            check_unit(c);
        }
        mcd_test_free_scratch(c->scratch);
    }
    free(c);
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- local -> world */

/* A float of any sign and magnitude the composition may meet: tiny, unit-sized, large, zeros
 * of both signs; an eighth of them near 1 so that sums cancel and round. */
static float any_float(uint32_t* rng) {
    uint32_t r = mcd_test_rand(rng), kind = r & 7u;
    float unit = (float)(mcd_test_rand(rng) & 0xFFFFFFu) / 16777216.0f;
    float sign = (r & 8u) ? -1.0f : 1.0f;
    switch (kind) {
    case 0: return sign * 0.0f;
    case 1: return sign * unit * 1e-30f;
    case 2: return sign * unit * 1e6f;
    case 3: return sign * (1.0f - unit * 1e-6f);
    default: return sign * unit;
    }
}

/* The same inputs give these bits on every platform: x86-64 with SSE (gcc, clang), aarch64
 * (gcc) and any build that rounds every product. A build that fuses multiply-adds differs
 * (clang -ffp-contract=fast changes 5 floats of the first composition). */
static void check_fixed_bits(void) {
    static const mcd_transform parents[2] = {
        {{0.2718281f, -0.5772157f, 0.1414214f, 0.7548776f}, {12.34567f, -0.0009765625f, 3.3333333f}, {1.0f, 1.0f, 1.0f}},
        {{0.9999f, 0.001f, -0.0123f, 0.0001f}, {-1000.5f, 250.125f, 1e-3f}, {1.5f, 0.75f, 2.0f}}};
    static const mcd_transform locals[2] = {
        {{-0.3090170f, 0.0f, 0.9510565f, 0.0174533f}, {-7.071068f, 2.236068f, 0.5772157f}, {1.0f, 1.0f, 1.0f}},
        {{0.5f, 0.5f, -0.5f, 0.5f}, {33.3f, -66.6f, 99.9f}, {0.5f, 4.0f, 1.25f}}};
    static const uint32_t composed[2][10] = {
        {0xbf47099cu, 0xbe9fe5c2u, 0x3f0ac27cu, 0xbd18e23au, 0x410a1ac3u, 0x400c5e90u, 0xc02d9a5fu, 0x3f800000u,
         0x3f800000u, 0x3f800000u},
        {0x3f017247u, 0x3efd1b72u, 0x3efc8b43u, 0xbf01ad43u, 0xc46ee51bu, 0x43961001u, 0xc348f4f4u, 0x3f400000u,
         0x40400000u, 0x40200000u}};
    static const mcd_quat refs[2] = {{0.0618034f, -0.7071068f, 0.3826834f, 0.5877853f}, {-0.25f, 0.9f, 0.1f, -0.3f}};
    static const float vals[2][4] = {{0.1234567f, -0.4567891f, 0.7890123f, 0.0f}, {-1.75f, 0.003f, 2.5e-5f, 0.0f}};
    static const uint32_t rotated[2][4] = {{0xbea99724u, 0xbeb3da7du, 0x3f192002u, 0xbf22e440u},
                                           {0x3ec53f30u, 0xbf0b23fau, 0x3f3967d4u, 0xbd83e795u}};
    const float axis[3] = {0.0f, 0.0f, 1.0f};
    uint32_t i, k;
    for (i = 0; i < 2u; ++i) {
        mcd_transform w;
        float r[4];
        mcd_compose(&parents[i], &locals[i], &w);
        for (k = 0; k < 10u; ++k) {
            float got = k < 4u ? w.rotation[k] : k < 7u ? w.translation[k - 4u] : w.scale[k - 7u];
            CHECK_MSG(mcd_test_f32_bits(got) == composed[i][k], "composition %u float %u: 0x%08x, every platform gives 0x%08x", i,
                      k, (unsigned)mcd_test_f32_bits(got), (unsigned)composed[i][k]);
        }
        mcd_store_track_rotation(1u, &refs[i], axis, vals[i], r);
        for (k = 0; k < 4u; ++k)
            CHECK_MSG(mcd_test_f32_bits(r[k]) == rotated[i][k], "track rotation %u float %u: 0x%08x, every platform gives 0x%08x",
                      i, k, (unsigned)mcd_test_f32_bits(r[k]), (unsigned)rotated[i][k]);
    }
}

/* The SSE paths (where the target has them) give the scalar code's bits, every float, on
 * random inputs, non-unit rotations included: the composition of the world pose, also with
 * `world` the same object as `local` as mcd_local_to_world calls it, and a curve track's
 * rotation from its reference and MRP value (kind 1; kind 2 stays scalar); then fixed
 * results that every platform must give. */
void test_simd_paths_agree(void) {
    uint32_t rng = 0x5eed1234u, i, k, composed = 0, rotations = 0;
    for (i = 0; i < 200000u; ++i) {
        mcd_transform p, l, w1, w2, in_place;
        mcd_quat ref, q;
        float val[4], axis[3] = {0.0f, 0.0f, 1.0f}, got[4], want[4];
        for (k = 0; k < 4; ++k) p.rotation[k] = any_float(&rng), l.rotation[k] = any_float(&rng);
        for (k = 0; k < 3; ++k) {
            p.translation[k] = any_float(&rng), l.translation[k] = any_float(&rng);
            p.scale[k] = (i & 1u) ? 1.0f : any_float(&rng), l.scale[k] = (i & 2u) ? 1.0f : any_float(&rng);
        }
        in_place = l;
        mcd_compose(&p, &l, &w1);
        mcd_compose_scalar(&p, &l, &w2);
        mcd_compose(&p, &in_place, &in_place);
        if (memcmp(&w1, &w2, sizeof w1) != 0 || memcmp(&in_place, &w2, sizeof w2) != 0) ++composed;
        ref.x = any_float(&rng), ref.y = any_float(&rng), ref.z = any_float(&rng), ref.w = any_float(&rng);
        for (k = 0; k < 4; ++k) val[k] = any_float(&rng);
        mcd_store_track_rotation(1u, &ref, axis, val, got);
        q = mcd_track_rotation(1u, ref, axis, val);
        mcd_set_rotation(want, q);
        if (memcmp(got, want, sizeof got) != 0) ++rotations;
    }
    CHECK_MSG(composed == 0, "%u of 200000 compositions differ from the scalar code's bits (SSE path wrong, or the "
              "build fuses multiply-adds: see src/internal.h)", composed);
    CHECK_MSG(rotations == 0, "%u of 200000 track rotations differ from the scalar code's bits (SSE path wrong, or "
              "the build fuses multiply-adds)", rotations);
#ifndef MCD_SSE
    mcd_test_note("this target has no SSE path: both sides are the scalar code");
#endif
    check_fixed_bits();
}

/* ---------------------------------------------------------------- access order */

/* Every (clip, time) of an asset: all frames and midpoints of every clip. */
typedef struct job {
    uint32_t clip, nodes;
    float time;
    size_t offset; /* of its pose in a results array */
} job;

typedef struct job_list {
    job* jobs;
    size_t count, floats_total; /* transforms over all jobs */
} job_list;

static int make_jobs(const mcd_asset* a, job_list* L) {
    uint32_t c;
    size_t cap = 0;
    memset(L, 0, sizeof *L);
    for (c = 0; c < mcd_clip_count(a); ++c) {
        mcd_clip_info ci;
        size_t count, k;
        float* times;
        if (mcd_get_clip_info(a, c, &ci) != MCD_OK) return 0;
        times = mcd_test_frame_times(&ci, &count);
        if (!times) return 0;
        if (L->count + count > cap) {
            job* grown;
            cap = 2u * (L->count + count);
            grown = (job*)realloc(L->jobs, cap * sizeof *grown);
            if (!grown) {
                free(times);
                return 0;
            }
            L->jobs = grown;
        }
        for (k = 0; k < count; ++k) {
            job* j = &L->jobs[L->count++];
            j->clip = c;
            j->nodes = ci.node_count;
            j->time = times[k];
            j->offset = L->floats_total;
            L->floats_total += ci.node_count;
        }
        free(times);
    }
    return L->count > 0;
}

/* How a caller keeps its scratch memory while it runs the jobs. */
enum scratch_use {
    ONE_SCRATCH,       /* one scratch for every clip, never re-initialised */
    REINIT_ON_SWITCH,  /* one scratch, initialised again whenever the clip changes */
    SCRATCH_PER_CLIP   /* one scratch per clip, each of exactly the size that clip states */
};

/* Runs `order` (job indices); `scratch` holds one scratch, or one per clip (SCRATCH_PER_CLIP). */
static int run_jobs(const mcd_asset* a, const job_list* L, const uint32_t* order, uint32_t flags,
                    mcd_transform* out, void** scratch, enum scratch_use use) {
    size_t k;
    uint32_t clip = UINT32_MAX;
    for (k = 0; k < L->count; ++k) {
        const job* j = &L->jobs[order[k]];
        void* s = scratch[use == SCRATCH_PER_CLIP ? j->clip : 0];
        if (use == REINIT_ON_SWITCH && j->clip != clip && mcd_scratch_init(a, s, mcd_scratch_size(a)) != MCD_OK) return 0;
        clip = j->clip;
        if (mcd_sample(a, j->clip, j->time, flags, out + j->offset, j->nodes, s) != MCD_OK) return 0;
    }
    return 1;
}

/* Orders: 0 forwards, 1 backwards, 2 and above shuffled with seed `kind`. */
static void make_order(uint32_t* order, size_t count, uint32_t kind) {
    size_t k;
    for (k = 0; k < count; ++k) order[k] = (uint32_t)(kind == 1 ? count - 1u - k : k);
    if (kind >= 2) mcd_test_shuffle(order, count, 0x1234567u * kind);
}

/* Forwards and backwards keep each clip's samples together; a shuffle interleaves clips. The
 * reference samples each job with a scratch initialised just before it. */
void test_access_order_independence(void) {
    static const uint32_t flag_sets[4] = {0, MCD_SAMPLE_WORLD | MCD_SAMPLE_LOOP, MCD_SAMPLE_NEAREST,
                                          MCD_SAMPLE_CONTACTS | MCD_SAMPLE_WORLD};
    static const char* const uses[3] = {"one scratch", "scratch re-initialised per clip", "scratch per clip"};
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, k;
    for (i = 0; i < n; ++i) {
        const mcd_asset* a = &g[i].asset;
        uint32_t c, clips = mcd_clip_count(a), kind;
        job_list L;
        void* scratch = mcd_test_scratch(a);
        void* shared = mcd_test_scratch(a); /* one scratch reused across clips and orders */
        void** own = (void**)calloc(clips, sizeof *own);
        mcd_transform *ref = NULL, *got = NULL;
        uint32_t* order = NULL;
        size_t f;
        int setup;
        memset(&L, 0, sizeof L);
        setup = scratch && shared && own && make_jobs(a, &L);
        for (c = 0; setup && c < clips; ++c) {
            mcd_clip_info ci;
            setup = mcd_get_clip_info(a, c, &ci) == MCD_OK && (own[c] = mcd_test_scratch_sized(a, ci.scratch_size)) != NULL;
        }
        if (setup) {
            ref = (mcd_transform*)malloc(L.floats_total * sizeof *ref);
            got = (mcd_transform*)malloc(L.floats_total * sizeof *got);
            order = (uint32_t*)malloc(L.count * sizeof *order);
        }
        for (f = 0; ref && got && order && f < 4; ++f) {
            for (k = 0; k < L.count; ++k)
                if (!sample_cold(a, L.jobs[k].clip, L.jobs[k].time, flag_sets[f], ref + L.jobs[k].offset, scratch))
                    FAIL("sampling failed");
            for (kind = 0; kind < 4; ++kind) {
                int use;
                make_order(order, L.count, kind);
                for (use = ONE_SCRATCH; use <= SCRATCH_PER_CLIP; ++use) {
                    void** s = use == SCRATCH_PER_CLIP ? own : use == REINIT_ON_SWITCH ? &scratch : &shared;
                    memset(got, 0xA5, L.floats_total * sizeof *got);
                    if (!run_jobs(a, &L, order, flag_sets[f], got, s, (enum scratch_use)use)) FAIL("sampling failed");
                    for (k = 0; k < L.count; ++k) {
                        const job* j = &L.jobs[k];
                        if (!same_pose(ref + j->offset, got + j->offset, j->nodes)) {
                            FAIL("%s clip %u t=%.9g flags %u order %u, %s: differs from a cold sample", g[i].file.path,
                                 j->clip, j->time, flag_sets[f], kind, uses[use]);
                            break;
                        }
                    }
                    CHECK(k == L.count);
                }
            }
        }
        if (!setup) FAIL("%s: setup failed", g[i].file.path);
        free(order);
        free(got);
        free(ref);
        free(L.jobs);
        for (c = 0; own && c < clips; ++c) mcd_test_free_scratch(own[c]);
        free(own);
        mcd_test_free_scratch(shared);
        mcd_test_free_scratch(scratch);
    }
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- scratch per clip */

/* A scratch of one clip's stated size plays every clip whose need it covers, giving the bytes
 * the asset's scratch gives, and refuses the others with MCD_ERROR_BUFFER_TOO_SMALL, after
 * which it still plays the clips it covers. */
void test_scratch_per_clip(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    mcd_transform* p = (mcd_transform*)malloc(MAX_NODES * sizeof *p);
    mcd_transform* q = (mcd_transform*)malloc(MAX_NODES * sizeof *q);
    unsigned long refused = 0;
    for (i = 0; p && q && i < n; ++i) {
        const mcd_asset* a = &g[i].asset;
        uint32_t c, d, clips = mcd_clip_count(a);
        void* full = mcd_test_scratch(a);
        for (c = 0; full && c < clips; ++c) {
            mcd_clip_info ci;
            void* small;
            CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
            small = mcd_test_scratch_sized(a, ci.scratch_size);
            for (d = 0; small && d < clips; ++d) {
                mcd_clip_info di;
                uint32_t k;
                CHECK_RESULT(mcd_get_clip_info(a, d, &di), MCD_OK);
                for (k = 0; k < 2u * di.frame_count - 1u; k += 7u) {
                    float t = (float)(0.5 * k / di.frame_rate);
                    mcd_result r = mcd_sample(a, d, t, MCD_SAMPLE_WORLD, p, MAX_NODES, small);
                    if (di.scratch_size > ci.scratch_size) {
                        CHECK_MSG(r == MCD_ERROR_BUFFER_TOO_SMALL, "%s: clip %u (needs %u) on the scratch of clip %u (%u): %s",
                                  g[i].file.path, d, di.scratch_size, c, ci.scratch_size, mcd_result_string(r));
                        refused++;
                        /* Refused, the scratch keeps serving the clip it was sized for. */
                        r = mcd_sample(a, c, t, MCD_SAMPLE_WORLD, p, MAX_NODES, small);
                        CHECK_RESULT(r, MCD_OK);
                        CHECK(sample_cold(a, c, t, MCD_SAMPLE_WORLD, q, full) && same_pose(p, q, ci.node_count));
                        continue;
                    }
                    CHECK_MSG(r == MCD_OK, "%s: clip %u (needs %u) on the scratch of clip %u (%u): %s", g[i].file.path, d,
                              di.scratch_size, c, ci.scratch_size, mcd_result_string(r));
                    CHECK(sample_cold(a, d, t, MCD_SAMPLE_WORLD, q, full));
                    CHECK_MSG(same_pose(p, q, di.node_count), "%s clip %u t=%.9g: the scratch of clip %u gives other bytes",
                              g[i].file.path, d, t, c);
                }
            }
            mcd_test_free_scratch(small);
        }
        mcd_test_free_scratch(full);
    }
    /* The goldens include libraries whose clips need different amounts. */
    CHECK_MSG(refused > 0, "no golden clip needs more scratch than another: the refusal was not tested");
    free(p);
    free(q);
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- threads */
#define THREADS 4

typedef struct thread_arg {
    const mcd_asset* a;
    const job_list* L;
    uint32_t* order;
    mcd_transform* out;
    void* scratch;
    uint32_t flags;
    int ok;
} thread_arg;

static void* thread_main(void* p) {
    thread_arg* t = (thread_arg*)p;
    t->ok = run_jobs(t->a, t->L, t->order, t->flags, t->out, &t->scratch, ONE_SCRATCH);
    return NULL;
}

/* Four threads share one opened asset, each with its own scratch and its own order of the same
 * samples; each must match a serial run bit for bit. All memory is allocated up front. */
void test_threads_match_serial(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, k;
    uint32_t flags;
    for (i = 0; i < n; ++i) {
        const mcd_asset* a = &g[i].asset;
        job_list L;
        thread_arg args[THREADS];
        pthread_t threads[THREADS];
        mcd_transform* serial = NULL;
        uint32_t* serial_order = NULL;
        void* scratch = mcd_test_scratch(a);
        int t, ok = scratch && make_jobs(a, &L);
        if (!ok) {
            FAIL("setup failed");
            mcd_test_free_scratch(scratch);
            continue;
        }
        memset(args, 0, sizeof args);
        serial = (mcd_transform*)malloc(L.floats_total * sizeof *serial);
        serial_order = (uint32_t*)malloc(L.count * sizeof *serial_order);
        for (t = 0; t < THREADS; ++t) {
            args[t].a = a;
            args[t].L = &L;
            args[t].order = (uint32_t*)malloc(L.count * sizeof(uint32_t));
            args[t].out = (mcd_transform*)malloc(L.floats_total * sizeof(mcd_transform));
            args[t].scratch = mcd_test_scratch(a);
            ok = ok && args[t].order && args[t].out && args[t].scratch;
            if (args[t].order) make_order(args[t].order, L.count, (uint32_t)t == 3 ? 7u : (uint32_t)t);
        }
        ok = ok && serial && serial_order;
        for (flags = 0; ok && flags <= MCD_SAMPLE_WORLD; ++flags) {
            int started = 0;
            make_order(serial_order, L.count, 0);
            CHECK(run_jobs(a, &L, serial_order, flags, serial, &scratch, REINIT_ON_SWITCH));
            for (t = 0; t < THREADS; ++t) {
                args[t].flags = flags;
                if (pthread_create(&threads[t], NULL, thread_main, &args[t]) != 0) break;
                started++;
            }
            CHECK(started == THREADS);
            for (t = 0; t < started; ++t) pthread_join(threads[t], NULL);
            for (t = 0; t < started; ++t) {
                CHECK(args[t].ok);
                for (k = 0; k < L.count; ++k) {
                    const job* j = &L.jobs[k];
                    if (!same_pose(serial + j->offset, args[t].out + j->offset, j->nodes)) {
                        FAIL("%s thread %d clip %u t=%.9g flags %u: differs from the serial run", g[i].file.path, t,
                             j->clip, j->time, flags);
                        break;
                    }
                }
                CHECK(k == L.count);
            }
        }
        if (!ok) FAIL("setup failed");
        for (t = 0; t < THREADS; ++t) {
            free(args[t].order);
            free(args[t].out);
            mcd_test_free_scratch(args[t].scratch);
        }
        free(serial_order);
        free(serial);
        free(L.jobs);
        mcd_test_free_scratch(scratch);
    }
    mcd_test_free_golden(g, n);
}
