#define _POSIX_C_SOURCE 200809L

#include "exercise.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mocodec.h"

/* The largest skeleton the format allows (docs/FORMAT.md, SKEL node_count). */
#define MAX_NODES 1024u

static int broken(char* why, size_t why_size, const char* fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    if (why && why_size) vsnprintf(why, why_size, fmt, ap);
    va_end(ap);
    return MCD_EXERCISE_BROKEN;
}

static int finite_all(const float* v, int n) {
    int i;
    for (i = 0; i < n; ++i)
        if (!(v[i] - v[i] == 0.0f)) return 0;
    return 1;
}

static double norm4(const float* q) {
    return sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] + (double)q[3] * q[3]);
}

/* Outputs are promised finite, and rotations unit quaternions (mcd_transform). The 1e-3 slack
 * is far above float rounding and far below any real defect. */
static int check_pose(const mcd_transform* pose, uint32_t n, char* why, size_t why_size) {
    uint32_t i;
    for (i = 0; i < n; ++i) {
        const float* q = pose[i].rotation;
        if (!finite_all(q, 4) || !finite_all(pose[i].translation, 3) || !finite_all(pose[i].scale, 3))
            return broken(why, why_size, "node %u: non-finite output", i);
        if (fabs(norm4(q) - 1.0) > 1e-3) return broken(why, why_size, "node %u: |q| = %g", i, norm4(q));
    }
    return MCD_EXERCISE_SAMPLED;
}

/* A node record as docs/FORMAT.md "SKEL" (version 2) allows it: a rest rotation unit within
 * 1e-5 (the runtime's bound is on |q|^2, 2e-5), finite rest values, leaves below end sites and
 * virtual points only. */
static int check_node(const mcd_node_info* ni, uint32_t n, const uint8_t* kinds, char* why, size_t why_size) {
    if (!ni->name || !ni->name[0] || ni->parent < -1 || ni->parent >= (int32_t)n || ni->channel_count > 6)
        return broken(why, why_size, "node %u: bad name, parent or channels", n);
    if (ni->kind > MCD_NODE_VIRTUAL || (ni->kind != MCD_NODE_JOINT && ni->channel_count != 0))
        return broken(why, why_size, "node %u: kind %u with %u channels", n, ni->kind, ni->channel_count);
    if (ni->parent >= 0 && kinds[ni->parent] != MCD_NODE_JOINT)
        return broken(why, why_size, "node %u hangs below node %d of kind %u", n, ni->parent, kinds[ni->parent]);
    if (!finite_all(ni->rest_translation, 3) || !finite_all(ni->rest_scale, 3) || !finite_all(ni->rest_rotation, 4))
        return broken(why, why_size, "node %u: non-finite rest transform", n);
    if (fabs(norm4(ni->rest_rotation) * norm4(ni->rest_rotation) - 1.0) > 2e-5)
        return broken(why, why_size, "node %u: rest |q| = %.9g", n, norm4(ni->rest_rotation));
    return MCD_EXERCISE_SAMPLED;
}

static int exercise_queries(const mcd_asset* a, char* why, size_t why_size) {
    uint32_t s, n, skeletons = mcd_skeleton_count(a), found;
    uint8_t kinds[MAX_NODES];
    size_t scratch = mcd_scratch_size(a);
    if (skeletons < 1 || mcd_clip_count(a) < 1) return broken(why, why_size, "no skeleton or no clip");
    if (scratch < MCD_SCRATCH_MIN_SIZE || scratch % 16u != 0) return broken(why, why_size, "scratch size %lu", (unsigned long)scratch);
    if (mcd_find_clip(a, "", &found) != MCD_ERROR_NOT_FOUND) return broken(why, why_size, "found a clip with an empty name");
    for (s = 0; s < skeletons; ++s) {
        mcd_skeleton_info si;
        mcd_result r = mcd_get_skeleton_info(a, s, &si);
        if (r != MCD_OK) return broken(why, why_size, "skeleton %u: info gave %d", s, (int)r);
        if (si.node_count < 1 || si.node_count > MAX_NODES || !(si.cm_per_unit > 0.0f) || !finite_all(&si.cm_per_unit, 1))
            return broken(why, why_size, "skeleton %u: bad info", s);
        for (n = 0; n < si.node_count; ++n) {
            mcd_node_info ni;
            int ok;
            r = mcd_get_node_info(a, s, n, &ni);
            if (r != MCD_OK) return broken(why, why_size, "node %u/%u: info gave %d", s, n, (int)r);
            ok = check_node(&ni, n, kinds, why, why_size);
            if (ok != MCD_EXERCISE_SAMPLED) return ok;
            kinds[n] = (uint8_t)ni.kind;
        }
    }
    return MCD_EXERCISE_SAMPLED;
}

/* What a prevalidated open reports must be what the validating open reports. */
static int same_opens(const mcd_asset* a, const mcd_asset* b, char* why, size_t why_size) {
    uint32_t c, s, n;
    if (mcd_clip_count(a) != mcd_clip_count(b) || mcd_skeleton_count(a) != mcd_skeleton_count(b) ||
        mcd_scratch_size(a) != mcd_scratch_size(b))
        return broken(why, why_size, "prevalidated open: other counts or scratch size");
    for (c = 0; c < mcd_clip_count(a); ++c) {
        mcd_clip_info x, y;
        if (mcd_get_clip_info(a, c, &x) != MCD_OK || mcd_get_clip_info(b, c, &y) != MCD_OK || x.name != y.name ||
            x.skeleton != y.skeleton || x.codec != y.codec || x.frame_count != y.frame_count ||
            memcmp(&x.frame_rate, &y.frame_rate, sizeof x.frame_rate) != 0 ||
            memcmp(&x.duration, &y.duration, sizeof x.duration) != 0 || x.node_count != y.node_count ||
            x.scratch_size != y.scratch_size || x.data_offset != y.data_offset || x.data_size != y.data_size)
            return broken(why, why_size, "prevalidated open: clip %u info differs", c);
    }
    for (s = 0; s < mcd_skeleton_count(a); ++s) {
        mcd_skeleton_info x, y;
        if (mcd_get_skeleton_info(a, s, &x) != MCD_OK || mcd_get_skeleton_info(b, s, &y) != MCD_OK ||
            memcmp(&x, &y, sizeof x) != 0)
            return broken(why, why_size, "prevalidated open: skeleton %u info differs", s);
        for (n = 0; n < x.node_count; ++n) {
            mcd_node_info p, q;
            if (mcd_get_node_info(a, s, n, &p) != MCD_OK || mcd_get_node_info(b, s, n, &q) != MCD_OK ||
                p.name != q.name || p.parent != q.parent || p.kind != q.kind || p.channel_count != q.channel_count ||
                memcmp(p.channels, q.channels, sizeof p.channels) != 0 ||
                memcmp(p.rest_translation, q.rest_translation, sizeof p.rest_translation) != 0 ||
                memcmp(p.rest_rotation, q.rest_rotation, sizeof p.rest_rotation) != 0 ||
                memcmp(p.rest_scale, q.rest_scale, sizeof p.rest_scale) != 0)
                return broken(why, why_size, "prevalidated open: node %u/%u info differs", s, n);
        }
    }
    return MCD_EXERCISE_SAMPLED;
}

/* A scratch of exactly `size` bytes, initialised for `a`; NULL when out of memory or refused. */
static void* exact_scratch(const mcd_asset* a, size_t size, mcd_result* r) {
    void* p = NULL;
    *r = MCD_ERROR_INVALID_ARGUMENT;
    if (posix_memalign(&p, 16, size ? size : 1u) != 0) return NULL;
    *r = mcd_scratch_init(a, p, size);
    return p;
}

/* A scratch one byte short of the clip's stated need is refused, at init or at sampling. */
static int exercise_short_scratch(const mcd_asset* a, uint32_t c, const mcd_clip_info* ci, mcd_transform* pose, char* why,
                                  size_t why_size) {
    mcd_result r;
    void* s = exact_scratch(a, ci->scratch_size - 1u, &r);
    int result = MCD_EXERCISE_SAMPLED;
    if (!s) return broken(why, why_size, "out of memory");
    if (r == MCD_OK) r = mcd_sample(a, c, 0.0f, 0, pose, MAX_NODES, s);
    if (r != MCD_ERROR_BUFFER_TOO_SMALL)
        result = broken(why, why_size, "clip %u: a scratch of %u bytes (need %u) gave %d", c, ci->scratch_size - 1u,
                        ci->scratch_size, (int)r);
    free(s);
    return result;
}

/* The sample flags, and the 5 combinations that hold every pair of them on and off. */
#define ALL_FLAGS (MCD_SAMPLE_WORLD | MCD_SAMPLE_LOOP | MCD_SAMPLE_NEAREST | MCD_SAMPLE_CONTACTS)
static const uint32_t k_pairwise[5] = {
    0u,
    MCD_SAMPLE_LOOP | MCD_SAMPLE_NEAREST | MCD_SAMPLE_CONTACTS,
    MCD_SAMPLE_WORLD | MCD_SAMPLE_NEAREST | MCD_SAMPLE_CONTACTS,
    MCD_SAMPLE_WORLD | MCD_SAMPLE_LOOP | MCD_SAMPLE_CONTACTS,
    MCD_SAMPLE_WORLD | MCD_SAMPLE_LOOP | MCD_SAMPLE_NEAREST,
};

/* Clip `c` of the validated open `a` (sampled with `shared`, the asset's scratch, which other
 * clips use too) and of the prevalidated open `pre` (sampled with a scratch of the clip's own
 * size): both must give the same bytes. */
static int exercise_clip(const mcd_asset* a, const mcd_asset* pre, size_t asset_size, uint32_t c, void* shared,
                         mcd_transform* pose, mcd_transform* pose2, int pairwise, char* why, size_t why_size) {
    mcd_clip_info ci;
    uint32_t found = UINT32_MAX, flags, k, combos = pairwise ? 5u : ALL_FLAGS + 1u;
    size_t t;
    mcd_result r = mcd_get_clip_info(a, c, &ci);
    float times[8];
    void* own;
    int result = MCD_EXERCISE_SAMPLED;
    if (r != MCD_OK) return broken(why, why_size, "clip %u: info gave %d", c, (int)r);
    if (!ci.name || !ci.name[0] || ci.node_count < 1 || ci.node_count > MAX_NODES || ci.frame_count < 1 ||
        !(ci.frame_rate > 0.0f) || !finite_all(&ci.duration, 1))
        return broken(why, why_size, "clip %u: bad info", c);
    if (ci.scratch_size < MCD_SCRATCH_MIN_SIZE || ci.scratch_size % 16u != 0 || ci.scratch_size > mcd_scratch_size(a))
        return broken(why, why_size, "clip %u: scratch size %u (asset %lu)", c, ci.scratch_size, (unsigned long)mcd_scratch_size(a));
    if (ci.data_offset % 4u != 0 || (uint64_t)ci.data_offset + ci.data_size > asset_size)
        return broken(why, why_size, "clip %u: data range %u + %u", c, ci.data_offset, ci.data_size);
    /* Names may repeat; find_clip returns the first clip of that name. */
    if (mcd_find_clip(a, ci.name, &found) != MCD_OK || found > c)
        return broken(why, why_size, "clip %u: find_clip(\"%s\") gave %u", c, ci.name, found);
    result = exercise_short_scratch(pre, c, &ci, pose, why, why_size);
    if (result != MCD_EXERCISE_SAMPLED) return result;
    own = exact_scratch(pre, ci.scratch_size, &r);
    if (!own || r != MCD_OK) {
        free(own);
        return broken(why, why_size, "clip %u: scratch of its own size (%u): %d", c, ci.scratch_size, (int)r);
    }
    times[0] = 0.0f;
    times[1] = 0.5f * ci.duration;
    times[2] = ci.duration;
    times[3] = -0.3f * ci.duration - 0.1f;         /* before the start */
    times[4] = 1.7f * ci.duration + 0.3f;          /* past the end */
    times[5] = 1.5f / ci.frame_rate;               /* between two frames */
    times[6] = 1000.25f * ci.duration;             /* many loops later */
    times[7] = -1e6f;
    for (t = 0; t < sizeof times / sizeof times[0] && result == MCD_EXERCISE_SAMPLED; ++t) {
        /* A valid asset may have a huge duration; time arithmetic above can then overflow. */
        if (!finite_all(&times[t], 1)) continue;
        for (k = 0; k < combos; ++k) {
            flags = pairwise ? k_pairwise[k] : k;
            r = mcd_sample(a, c, times[t], flags, pose, ci.node_count, shared);
            if (r != MCD_OK) {
                result = broken(why, why_size, "clip %u t=%g flags=%u: sample gave %d", c, times[t], flags, (int)r);
                break;
            }
            r = mcd_sample(pre, c, times[t], flags, pose2, ci.node_count, own);
            if (r != MCD_OK) {
                result = broken(why, why_size, "clip %u t=%g flags=%u: prevalidated, own scratch: sample gave %d", c,
                                times[t], flags, (int)r);
                break;
            }
            result = check_pose(pose, ci.node_count, why, why_size);
            if (result != MCD_EXERCISE_SAMPLED) break;
            if (memcmp(pose, pose2, ci.node_count * sizeof *pose) != 0) {
                result = broken(why, why_size, "clip %u t=%g flags=%u: the clip's own scratch (prevalidated open) "
                                "gives other bytes than the asset's", c, times[t], flags);
                break;
            }
        }
    }
    free(own);
    return result;
}

static int exercise_opened(const mcd_asset* asset, const mcd_asset* pre, size_t size, uint32_t max_clips, int pairwise,
                           char* why, size_t why_size) {
    size_t scratch_size = mcd_scratch_size(asset);
    void* scratch = NULL;
    mcd_transform *pose, *pose2;
    uint32_t c, clips = mcd_clip_count(asset), largest = 0;
    int result = exercise_queries(asset, why, why_size);
    if (result == MCD_EXERCISE_SAMPLED) result = same_opens(asset, pre, why, why_size);
    if (result != MCD_EXERCISE_SAMPLED) return result;
    pose = (mcd_transform*)malloc(MAX_NODES * sizeof *pose);
    pose2 = (mcd_transform*)malloc(MAX_NODES * sizeof *pose2);
    if (!pose || !pose2 || posix_memalign(&scratch, 16, scratch_size) != 0) {
        free(pose);
        free(pose2);
        return broken(why, why_size, "out of memory");
    }
    if (mcd_scratch_init(asset, scratch, scratch_size) != MCD_OK) result = broken(why, why_size, "scratch_init failed");
    for (c = 0; c < clips && result == MCD_EXERCISE_SAMPLED; ++c) {
        mcd_clip_info ci;
        /* The asset's scratch is the largest clip's (mocodec.h, mcd_scratch_size). */
        if (mcd_get_clip_info(asset, c, &ci) == MCD_OK && ci.scratch_size > largest) largest = ci.scratch_size;
        if (c < max_clips) result = exercise_clip(asset, pre, size, c, scratch, pose, pose2, pairwise, why, why_size);
    }
    if (result == MCD_EXERCISE_SAMPLED && largest != scratch_size)
        result = broken(why, why_size, "mcd_scratch_size %lu, largest clip need %u", (unsigned long)scratch_size, largest);
    if (result == MCD_EXERCISE_SAMPLED && mcd_sample(asset, clips, 0.0f, 0, pose, MAX_NODES, scratch) != MCD_ERROR_OUT_OF_RANGE)
        result = broken(why, why_size, "sampling clip %u of %u did not give OUT_OF_RANGE", clips, clips);
    free(scratch);
    free(pose);
    free(pose2);
    return result;
}

static int exercise(const void* data, size_t size, uint32_t validate_flags, uint32_t max_clips, int pairwise,
                    char* why, size_t why_size) {
    mcd_asset asset, pre;
    mcd_result v = mcd_validate(data, size, validate_flags), o;
    if (why && why_size) why[0] = 0;
    /* mcd_open validates as mcd_validate does: the same answer. */
    o = mcd_open(data, size, validate_flags, &asset);
    if (o != v) return broken(why, why_size, "validate gave %d but open gave %d", (int)v, (int)o);
    if (o != MCD_OK) {
        const char* text = mcd_result_string(o);
        return text && text[0] ? MCD_EXERCISE_REJECTED : broken(why, why_size, "no text for result %d", (int)o);
    }
    /* The bytes passed mcd_validate: the one case MCD_OPEN_PREVALIDATED may be used. */
    o = mcd_open(data, size, validate_flags | MCD_OPEN_PREVALIDATED, &pre);
    if (o != MCD_OK) return broken(why, why_size, "validated bytes: prevalidated open gave %d", (int)o);
    return exercise_opened(&asset, &pre, size, max_clips, pairwise, why, why_size);
}

int mcd_exercise(const void* data, size_t size, uint32_t validate_flags, uint32_t max_clips,
                 char* why, size_t why_size) {
    return exercise(data, size, validate_flags, max_clips, 0, why, why_size);
}

int mcd_exercise_pairwise(const void* data, size_t size, uint32_t validate_flags, uint32_t max_clips,
                          char* why, size_t why_size) {
    return exercise(data, size, validate_flags, max_clips, 1, why, why_size);
}
