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

static int finite3(const float* v, int n) {
    int i;
    for (i = 0; i < n; ++i)
        if (!(v[i] - v[i] == 0.0f)) return 0;
    return 1;
}

/* Outputs are promised finite, and rotations unit quaternions (mcd_transform). The 1e-3 slack
 * is far above float rounding and far below any real defect. */
static int check_pose(const mcd_transform* pose, uint32_t n, char* why, size_t why_size) {
    uint32_t i;
    for (i = 0; i < n; ++i) {
        const float* q = pose[i].rotation;
        double len;
        if (!finite3(q, 4) || !finite3(pose[i].translation, 3))
            return broken(why, why_size, "node %u: non-finite output", i);
        len = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] + (double)q[3] * q[3]);
        if (fabs(len - 1.0) > 1e-3) return broken(why, why_size, "node %u: |q| = %g", i, len);
    }
    return MCD_EXERCISE_SAMPLED;
}

static int exercise_queries(const mcd_asset* a, char* why, size_t why_size) {
    uint32_t s, n, skeletons = mcd_skeleton_count(a), found;
    if (skeletons < 1 || mcd_clip_count(a) < 1) return broken(why, why_size, "no skeleton or no clip");
    if (mcd_find_clip(a, "", &found) != MCD_ERROR_NOT_FOUND) return broken(why, why_size, "found a clip with an empty name");
    for (s = 0; s < skeletons; ++s) {
        mcd_skeleton_info si;
        mcd_result r = mcd_get_skeleton_info(a, s, &si);
        if (r != MCD_OK) return broken(why, why_size, "skeleton %u: info gave %d", s, (int)r);
        if (si.node_count < 1 || si.node_count > MAX_NODES || !(si.cm_per_unit > 0.0f) || !finite3(&si.cm_per_unit, 1))
            return broken(why, why_size, "skeleton %u: bad info", s);
        for (n = 0; n < si.node_count; ++n) {
            mcd_node_info ni;
            r = mcd_get_node_info(a, s, n, &ni);
            if (r != MCD_OK) return broken(why, why_size, "node %u/%u: info gave %d", s, n, (int)r);
            if (!ni.name || !ni.name[0] || ni.parent < -1 || ni.parent >= (int32_t)n || ni.channel_count > 6 ||
                ni.is_end_site > 1 || !finite3(ni.rest_offset, 3))
                return broken(why, why_size, "node %u/%u: bad info", s, n);
        }
    }
    return MCD_EXERCISE_SAMPLED;
}

static int exercise_clip(const mcd_asset* a, uint32_t c, void* scratch, mcd_transform* pose, char* why,
                         size_t why_size) {
    mcd_clip_info ci;
    uint32_t found = UINT32_MAX, flags;
    size_t t;
    mcd_result r = mcd_get_clip_info(a, c, &ci);
    float times[8];
    if (r != MCD_OK) return broken(why, why_size, "clip %u: info gave %d", c, (int)r);
    if (!ci.name || !ci.name[0] || ci.node_count < 1 || ci.node_count > MAX_NODES || ci.frame_count < 1 ||
        !(ci.frame_rate > 0.0f) || !finite3(&ci.duration, 1))
        return broken(why, why_size, "clip %u: bad info", c);
    /* Names may repeat; find_clip returns the first clip of that name. */
    if (mcd_find_clip(a, ci.name, &found) != MCD_OK || found > c)
        return broken(why, why_size, "clip %u: find_clip(\"%s\") gave %u", c, ci.name, found);
    times[0] = 0.0f;
    times[1] = 0.5f * ci.duration;
    times[2] = ci.duration;
    times[3] = -0.3f * ci.duration - 0.1f;         /* before the start */
    times[4] = 1.7f * ci.duration + 0.3f;          /* past the end */
    times[5] = 1.5f / ci.frame_rate;               /* between two frames */
    times[6] = 1000.25f * ci.duration;             /* many loops later */
    times[7] = -1e6f;
    for (t = 0; t < sizeof times / sizeof times[0]; ++t) {
        /* A valid asset may have a huge duration; time arithmetic above can then overflow. */
        if (!finite3(&times[t], 1)) continue;
        for (flags = 0; flags <= (MCD_SAMPLE_WORLD | MCD_SAMPLE_LOOP | MCD_SAMPLE_NEAREST | MCD_SAMPLE_CONTACTS); ++flags) {
            int ok;
            r = mcd_sample(a, c, times[t], flags, pose, ci.node_count, scratch);
            if (r != MCD_OK) return broken(why, why_size, "clip %u t=%g flags=%u: sample gave %d", c, times[t], flags, (int)r);
            ok = check_pose(pose, ci.node_count, why, why_size);
            if (ok != MCD_EXERCISE_SAMPLED) return ok;
        }
    }
    return MCD_EXERCISE_SAMPLED;
}

mcd_result mcd_exercise_open(const void* data, size_t size, uint32_t flags, mcd_asset* out, void** resident) {
    size_t need = 0;
    mcd_result r = mcd_resident_size(data, size, flags, &need);
    *resident = NULL;
    if (r != MCD_OK) return r;
    if (need > 0 && posix_memalign(resident, 16, need) != 0) {
        *resident = NULL;
        return MCD_ERROR_BUFFER_TOO_SMALL;
    }
    r = mcd_open(data, size, flags, *resident, need, out);
    if (r != MCD_OK) {
        free(*resident);
        *resident = NULL;
    }
    return r;
}

/* Opening with less resident memory than asked for must fail cleanly, not write past it. */
static int exercise_short_resident(const void* data, size_t size, uint32_t flags, char* why, size_t why_size) {
    size_t need = 0;
    void* small = NULL;
    mcd_asset a;
    mcd_result r;
    if (mcd_resident_size(data, size, flags, &need) != MCD_OK || need == 0) return MCD_EXERCISE_SAMPLED;
    if (mcd_open(data, size, flags, NULL, 0, &a) == MCD_OK) return broken(why, why_size, "open without resident memory");
    if (posix_memalign(&small, 16, need) != 0) return broken(why, why_size, "out of memory");
    r = mcd_open(data, size, flags, small, need - 1u, &a);
    free(small);
    if (r != MCD_ERROR_BUFFER_TOO_SMALL) return broken(why, why_size, "open with short resident memory gave %d", (int)r);
    return MCD_EXERCISE_SAMPLED;
}

static int exercise_opened(const mcd_asset* asset, uint32_t max_clips, char* why, size_t why_size) {
    size_t scratch_size = mcd_scratch_size(asset);
    void* scratch = NULL;
    mcd_transform* pose;
    uint32_t c, clips = mcd_clip_count(asset);
    int result = exercise_queries(asset, why, why_size);
    if (result != MCD_EXERCISE_SAMPLED) return result;
    if (scratch_size == 0 || scratch_size % 16u != 0) return broken(why, why_size, "scratch size %lu", (unsigned long)scratch_size);
    pose = (mcd_transform*)malloc(MAX_NODES * sizeof *pose);
    if (!pose || posix_memalign(&scratch, 16, scratch_size) != 0) {
        free(pose);
        return broken(why, why_size, "out of memory");
    }
    if (mcd_scratch_init(asset, scratch, scratch_size) != MCD_OK) result = broken(why, why_size, "scratch_init failed");
    for (c = 0; c < clips && c < max_clips && result == MCD_EXERCISE_SAMPLED; ++c)
        result = exercise_clip(asset, c, scratch, pose, why, why_size);
    if (result == MCD_EXERCISE_SAMPLED && mcd_sample(asset, clips, 0.0f, 0, pose, MAX_NODES, scratch) != MCD_ERROR_OUT_OF_RANGE)
        result = broken(why, why_size, "sampling clip %u of %u did not give OUT_OF_RANGE", clips, clips);
    free(scratch);
    free(pose);
    return result;
}

int mcd_exercise(const void* data, size_t size, uint32_t validate_flags, uint32_t max_clips,
                 char* why, size_t why_size) {
    mcd_asset asset;
    void* resident = NULL;
    mcd_result v = mcd_validate(data, size, validate_flags), o;
    int result;
    if (why && why_size) why[0] = 0;
    /* mcd_open may still refuse what validate accepted, but only for decoded data (MALFORMED). */
    o = mcd_exercise_open(data, size, validate_flags, &asset, &resident);
    if (o != v && !(v == MCD_OK && o == MCD_ERROR_MALFORMED))
        return broken(why, why_size, "validate gave %d but open gave %d", (int)v, (int)o);
    if (o != MCD_OK) {
        const char* text = mcd_result_string(o);
        return text && text[0] ? MCD_EXERCISE_REJECTED : broken(why, why_size, "no text for result %d", (int)o);
    }
    result = exercise_short_resident(data, size, validate_flags, why, why_size);
    if (result == MCD_EXERCISE_SAMPLED) result = exercise_opened(&asset, max_clips, why, why_size);
    free(resident);
    return result;
}
