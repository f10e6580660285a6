/* Golden assets: every released asset validates and samples to the poses recorded beside it
 * (tests/golden/make_golden.py documents the poses format), opened with and without
 * MCD_OPEN_PREVALIDATED, and the queries report what the file holds. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

#define ROW 10u /* floats per node: qx qy qz qw tx ty tz sx sy sz */

/* One `sample <clip> <time> <flags>` record and its node_count rows. */
typedef struct pose_record {
    uint32_t clip, flags, nodes;
    float time;
    float* values; /* nodes * ROW */
} pose_record;

typedef struct pose_file {
    pose_record* records;
    size_t count;
} pose_file;

static void free_poses(pose_file* p) {
    size_t i;
    for (i = 0; i < p->count; ++i) free(p->records[i].values);
    free(p->records);
    memset(p, 0, sizeof *p);
}

/* A row of exactly ROW numbers. */
static int add_row(pose_record* r, const char* line, size_t* cap) {
    float v[ROW];
    char extra;
    if (sscanf(line, "%g %g %g %g %g %g %g %g %g %g %c", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6], &v[7], &v[8],
               &v[9], &extra) != (int)ROW)
        return 0;
    if (r->nodes == *cap) {
        float* grown;
        *cap = *cap ? 2u * *cap : 64u;
        grown = (float*)realloc(r->values, *cap * ROW * sizeof(float));
        if (!grown) return 0;
        r->values = grown;
    }
    memcpy(r->values + (size_t)r->nodes * ROW, v, sizeof v);
    r->nodes++;
    return 1;
}

/* The `.poses.txt` beside `mcd_path`. Times are float32 printed with %.9g, so reading them back
 * with strtod and rounding to float gives the exact time that was sampled. */
static int read_poses(const char* mcd_path, pose_file* out) {
    char path[4096], line[1024];
    size_t len = strlen(mcd_path), cap = 0, rec_cap = 0;
    FILE* f;
    memset(out, 0, sizeof *out);
    if (len < 4 || len + 16 > sizeof path) return 0;
    memcpy(path, mcd_path, len - 4);
    strcpy(path + len - 4, ".poses.txt");
    f = fopen(path, "r");
    if (!f) {
        FAIL("missing %s", path);
        return 0;
    }
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "sample ", 7) == 0) {
            char* end;
            pose_record* r;
            if (out->count == rec_cap) {
                pose_record* grown;
                rec_cap = rec_cap ? 2u * rec_cap : 32u;
                grown = (pose_record*)realloc(out->records, rec_cap * sizeof *grown);
                if (!grown) break;
                out->records = grown;
            }
            r = &out->records[out->count++];
            memset(r, 0, sizeof *r);
            cap = 0;
            r->clip = (uint32_t)strtoul(line + 7, &end, 10);
            r->time = (float)strtod(end, &end);
            r->flags = (uint32_t)strtoul(end, &end, 10);
        } else if (out->count == 0 || !add_row(&out->records[out->count - 1], line, &cap)) {
            FAIL("%s: unreadable line: %s", path, line);
            fclose(f);
            free_poses(out);
            return 0;
        }
    }
    fclose(f);
    if (out->count == 0) FAIL("%s has no samples", path);
    return out->count > 0;
}

static int close_enough(float got, float want) {
    return fabs((double)got - (double)want) <= 1e-5 + 1e-6 * fabs((double)want);
}

static void transform_row(const mcd_transform* t, float row[ROW]) {
    memcpy(row, t->rotation, 4 * sizeof(float));
    memcpy(row + 4, t->translation, 3 * sizeof(float));
    memcpy(row + 7, t->scale, 3 * sizeof(float));
}

/* Scratch of exactly each clip's stated size, for the prevalidated open (NULL entries on failure). */
static void** clip_scratches(const mcd_asset* a) {
    uint32_t c, n = mcd_clip_count(a);
    void** s = (void**)calloc(n ? n : 1u, sizeof *s);
    for (c = 0; s && c < n; ++c) {
        mcd_clip_info ci;
        if (mcd_get_clip_info(a, c, &ci) == MCD_OK) s[c] = mcd_test_scratch_sized(a, ci.scratch_size);
    }
    return s;
}

static void free_scratches(void** s, uint32_t n) {
    uint32_t c;
    for (c = 0; s && c < n; ++c) mcd_test_free_scratch(s[c]);
    free(s);
}

/* Each record sampled from the validated open (the asset's scratch) is within the golden
 * tolerance of the file; the prevalidated open, sampling with a scratch of the clip's own size,
 * gives the very same bytes. */
void test_golden_replay(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, k;
    for (i = 0; i < n; ++i) {
        pose_file poses;
        void* scratch;
        void** own;
        mcd_asset pre;
        mcd_transform pose[1024], pose2[1024];
        CHECK_RESULT(mcd_validate(g[i].file.data, g[i].file.size, 0), MCD_OK);
        CHECK_RESULT(mcd_validate(g[i].file.data, g[i].file.size, MCD_VALIDATE_SKIP_CHECKSUM), MCD_OK);
        CHECK_RESULT(mcd_open(g[i].file.data, g[i].file.size, MCD_OPEN_PREVALIDATED, &pre), MCD_OK);
        if (!read_poses(g[i].file.path, &poses)) continue;
        scratch = mcd_test_scratch(&g[i].asset);
        own = clip_scratches(&pre);
        for (k = 0; scratch && own && k < poses.count; ++k) {
            const pose_record* r = &poses.records[k];
            mcd_clip_info info;
            uint32_t node;
            CHECK_RESULT(mcd_get_clip_info(&g[i].asset, r->clip, &info), MCD_OK);
            if (r->nodes != info.node_count || r->nodes > 1024 || r->clip >= mcd_clip_count(&pre)) {
                FAIL("%s sample %lu: %u rows for %u nodes", g[i].file.path, (unsigned long)k, r->nodes, info.node_count);
                continue;
            }
            CHECK_RESULT(mcd_sample(&g[i].asset, r->clip, r->time, r->flags, pose, 1024, scratch), MCD_OK);
            CHECK_RESULT(mcd_sample(&pre, r->clip, r->time, r->flags, pose2, 1024, own[r->clip]), MCD_OK);
            CHECK_MSG(memcmp(pose, pose2, r->nodes * sizeof *pose) == 0,
                      "%s clip %u t=%.9g flags %u: the prevalidated open samples other bytes", g[i].file.path, r->clip,
                      r->time, r->flags);
            for (node = 0; node < r->nodes; ++node) {
                const float* want = r->values + (size_t)node * ROW;
                float got[ROW];
                uint32_t c = 0;
                transform_row(&pose[node], got);
                while (c < ROW && close_enough(got[c], want[c])) c++;
                CHECK_MSG(c == ROW, "%s clip %u t=%.9g flags %u node %u value %u: got %.9g, want %.9g", g[i].file.path,
                          r->clip, r->time, r->flags, node, c, got[c < ROW ? c : 0], want[c < ROW ? c : 0]);
            }
        }
        free_scratches(own, mcd_clip_count(&pre));
        mcd_test_free_scratch(scratch);
        free_poses(&poses);
    }
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- queries */

/* Facts of the source files, not of the encoder's output: the BVH files in
 * encoder/mocodec/samples (CMU subjects) and the clips tests/golden/make_golden.py cuts from them. */
typedef struct clip_fact {
    const char* name;
    uint32_t frames;   /* BVH `Frames:` (a _head clip: the frames make_golden.py keeps) */
    uint32_t skeleton; /* make_golden.py: one skeleton per source file, in order */
    int leg;           /* 1: make_golden.py's glTF-like leg (_leg), 0: a whole CMU skeleton */
} clip_fact;

typedef struct asset_fact {
    const char* file; /* name in the golden folder */
    uint32_t codec;   /* make_golden.py: the codec of every clip */
    /* 1: make_golden.py writes it with every runtime; 0: only once the runtime decodes its
     * codec (fk-wavelet: written when its port lands; set to 1 then). */
    int required;
    uint32_t clip_count, skeleton_count;
    clip_fact clips[2];
} asset_fact;

/* mixed (make_golden.py): 02_01, 09_11 and 02_01 again without their first frames. */
#define MIXED_FRAMES (343u + 165u + 343u)

static const asset_fact k_facts[] = {
    {"spline_09_11.mcd", MCD_CODEC_SPLINE, 1, 1, 1, {{"09_11", 166, 0, 0}}},
    {"spline_library.mcd", MCD_CODEC_SPLINE, 1, 2, 2, {{"07_01", 317, 0, 0}, {"02_01_head", 61, 1, 0}}},
    {"rma_library.mcd", MCD_CODEC_RMA, 1, 2, 2, {{"07_01", 317, 0, 0}, {"09_11", 166, 1, 0}}},
    {"spline_rest_pose.mcd", MCD_CODEC_SPLINE, 1, 2, 2, {{"07_01", 317, 0, 0}, {"09_11_leg", 166, 1, 1}}},
    {"rma_rest_pose.mcd", MCD_CODEC_RMA, 1, 2, 2, {{"07_01", 317, 0, 0}, {"09_11_leg", 166, 1, 1}}},
    /* RMAL version 4 at 0.05 cm in blocks of 8 keys: dense keys, wide differences, short blocks,
     * slope predictors and streams of zeros */
    {"rma_09_11_dense.mcd", MCD_CODEC_RMA, 1, 1, 1, {{"09_11_head", 120, 0, 0}}},
    /* RMAL version 3 (rma before version 4): still read */
    {"rma_rmal3_library.mcd", MCD_CODEC_RMA, 1, 2, 2, {{"07_01", 317, 0, 0}, {"09_11", 166, 1, 0}}},
    {"rma_rmal3_rest_pose.mcd", MCD_CODEC_RMA, 1, 2, 2, {{"07_01", 317, 0, 0}, {"09_11_leg", 166, 1, 1}}},
    {"rma_rmal3_09_11_dense.mcd", MCD_CODEC_RMA, 1, 1, 1, {{"09_11_head", 120, 0, 0}}},
    /* RMAL version 2 (rma before version 3): still read */
    {"rma_rmal2_library.mcd", MCD_CODEC_RMA, 1, 2, 2, {{"07_01", 317, 0, 0}, {"09_11", 166, 1, 0}}},
    {"rma_rmal2_rest_pose.mcd", MCD_CODEC_RMA, 1, 2, 2, {{"07_01", 317, 0, 0}, {"09_11_leg", 166, 1, 1}}},
    {"rma_pca_library.mcd", MCD_CODEC_RMA_PCA, 1, 2, 2, {{"07_01", 317, 0, 0}, {"mixed", MIXED_FRAMES, 1, 0}}},
    {"rma_pca_repeats.mcd", MCD_CODEC_RMA_PCA, 1, 1, 1, {{"mixed", MIXED_FRAMES, 0, 0}}},
    {"neural_09_11.mcd", MCD_CODEC_NEURAL, 1, 1, 1, {{"09_11_head", 90, 0, 0}}},
    {"fk_wavelet_09_11.mcd", MCD_CODEC_FK_WAVELET, 0, 1, 1, {{"09_11", 166, 0, 0}}},
    {"ik_predict_09_11.mcd", MCD_CODEC_IK_PREDICT, 1, 1, 1, {{"09_11_head", 100, 0, 0}}},
    {"spline_contacts_02_01.mcd", MCD_CODEC_SPLINE, 1, 1, 1, {{"02_01", 344, 0, 0}}},
};
#define FACT_COUNT (sizeof k_facts / sizeof k_facts[0])

/* Every CMU skeleton here: 31 joints (1 ROOT + 30 JOINT) + 7 End Sites = 38 nodes. */
#define CMU_NODES 38u
#define CMU_END_SITES 7u
#define CMU_FRAME_TIME 0.0083333 /* BVH `Frame Time:` */

static int file_is(const char* path, const char* file) {
    size_t len = strlen(path), fl = strlen(file);
    return len >= fl && strcmp(path + len - fl, file) == 0 && (len == fl || path[len - fl - 1] == '/');
}

static const asset_fact* find_fact(const char* path) {
    size_t i;
    for (i = 0; i < FACT_COUNT; ++i)
        if (file_is(path, k_facts[i].file)) return &k_facts[i];
    return NULL;
}

#define MAX_NODES 1024u /* docs/FORMAT.md, SKEL node_count */

/* Format rules every skeleton follows (docs/FORMAT.md "SKEL", version 2), read back through
 * the queries: unique names, parents first, end sites and virtual points are leaves without
 * channels, the rest rotation is a unit quaternion. */
static void check_skeleton_rules(const mcd_asset* a, uint32_t s, const char* path, mcd_node_info* nodes) {
    mcd_skeleton_info si;
    uint32_t n, k;
    CHECK_RESULT(mcd_get_skeleton_info(a, s, &si), MCD_OK);
    CHECK(si.cm_per_unit > 0.0f);
    for (n = 0; n < si.node_count && n < MAX_NODES; ++n) {
        mcd_node_info* ni = &nodes[n];
        const float* q = ni->rest_rotation;
        CHECK_RESULT(mcd_get_node_info(a, s, n, ni), MCD_OK);
        CHECK(ni->name != NULL && ni->name[0] != 0);
        for (k = 0; k < n; ++k)
            CHECK_MSG(strcmp(nodes[k].name, ni->name) != 0, "%s skeleton %u: name %s twice", path, s, ni->name);
        CHECK(ni->parent >= -1 && ni->parent < (int32_t)n);
        if (ni->parent >= 0) CHECK(nodes[ni->parent].kind == MCD_NODE_JOINT);
        CHECK(ni->kind <= MCD_NODE_VIRTUAL);
        CHECK(ni->channel_count <= 6);
        if (ni->kind != MCD_NODE_JOINT) CHECK(ni->channel_count == 0);
        CHECK(fabs((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] + (double)q[3] * q[3] - 1.0) <= 2e-5);
    }
}

/* Facts of the CMU BVH files behind these assets: every node of every skeleton. */
static void check_cmu_skeleton(const mcd_asset* a, uint32_t s, const char* path) {
    static const uint8_t root[6] = {MCD_CHANNEL_XPOSITION, MCD_CHANNEL_YPOSITION, MCD_CHANNEL_ZPOSITION,
                                    MCD_CHANNEL_ZROTATION, MCD_CHANNEL_YROTATION, MCD_CHANNEL_XROTATION};
    static const uint8_t joint[3] = {MCD_CHANNEL_ZROTATION, MCD_CHANNEL_YROTATION, MCD_CHANNEL_XROTATION};
    mcd_skeleton_info si;
    mcd_node_info nodes[CMU_NODES];
    uint32_t n, end_sites = 0;
    CHECK_RESULT(mcd_get_skeleton_info(a, s, &si), MCD_OK);
    if (si.node_count != CMU_NODES) {
        FAIL("%s skeleton %u: %u nodes, the BVH has %u", path, s, si.node_count, CMU_NODES);
        return;
    }
    for (n = 0; n < CMU_NODES; ++n) {
        mcd_node_info* ni = &nodes[n];
        CHECK_RESULT(mcd_get_node_info(a, s, n, ni), MCD_OK);
        /* BVH has no rest rotation or scale: identity and 1 1 1 (mocodec.h, mcd_node_info). */
        CHECK_MSG(ni->rest_rotation[0] == 0.0f && ni->rest_rotation[1] == 0.0f && ni->rest_rotation[2] == 0.0f &&
                      ni->rest_rotation[3] == 1.0f,
                  "%s skeleton %u node %u: rest rotation not the identity", path, s, n);
        CHECK_MSG(ni->rest_scale[0] == 1.0f && ni->rest_scale[1] == 1.0f && ni->rest_scale[2] == 1.0f,
                  "%s skeleton %u node %u: rest scale not 1", path, s, n);
        CHECK(ni->kind == MCD_NODE_JOINT || ni->kind == MCD_NODE_END_SITE); /* BVH has no virtual points */
        if (ni->kind == MCD_NODE_END_SITE) {
            end_sites++;
        } else if (n == 0) {
            /* ROOT Hips: CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation */
            CHECK(strcmp(ni->name, "Hips") == 0 && ni->parent == -1);
            CHECK(ni->channel_count == 6 && memcmp(ni->channels, root, 6) == 0);
        } else {
            /* every JOINT: CHANNELS 3 Zrotation Yrotation Xrotation */
            CHECK(ni->parent >= 0);
            CHECK(ni->channel_count == 3 && memcmp(ni->channels, joint, 3) == 0);
        }
    }
    CHECK(end_sites == CMU_END_SITES);
    /* Depth-first BVH order: Hips, LHipJoint, LeftUpLeg, LeftLeg, LeftFoot, LeftToeBase, End Site. */
    CHECK(strcmp(nodes[1].name, "LHipJoint") == 0 && nodes[1].parent == 0);
    CHECK(strcmp(nodes[2].name, "LeftUpLeg") == 0 && nodes[2].parent == 1);
    CHECK(strcmp(nodes[5].name, "LeftToeBase") == 0 && nodes[5].parent == 4);
    CHECK(nodes[6].kind == MCD_NODE_END_SITE && nodes[6].parent == 5);
}

/* make_golden.py's _leg(): the first seven nodes of 09_11.bvh, a virtual point instead of the
 * End Site, rest rotations of its own on LHipJoint and the virtual point. */
#define LEG_NODES 7u

static double axis_angle_gap(const float q[4], double x, double y, double z, double angle) {
    double n = sqrt(x * x + y * y + z * z), s = sin(angle / 2.0) / n, w[4], gap = 0.0;
    int k;
    w[0] = x * s;
    w[1] = y * s;
    w[2] = z * s;
    w[3] = cos(angle / 2.0);
    for (k = 0; k < 4; ++k)
        if (fabs(q[k] - w[k]) > gap) gap = fabs(q[k] - w[k]);
    return gap;
}

static void check_leg_skeleton(const mcd_asset* a, uint32_t s, const char* path) {
    static const char* const names[LEG_NODES] = {"Hips", "LHipJoint", "LeftUpLeg", "LeftLeg", "LeftFoot", "LeftToeBase",
                                                 "LeftToeBase_End"};
    mcd_skeleton_info si;
    mcd_node_info ni;
    uint32_t n;
    CHECK_RESULT(mcd_get_skeleton_info(a, s, &si), MCD_OK);
    if (si.node_count != LEG_NODES) {
        FAIL("%s skeleton %u: %u nodes, the leg has %u", path, s, si.node_count, LEG_NODES);
        return;
    }
    for (n = 0; n < LEG_NODES; ++n) {
        CHECK_RESULT(mcd_get_node_info(a, s, n, &ni), MCD_OK);
        CHECK_MSG(strcmp(ni.name, names[n]) == 0 && ni.parent == (int32_t)n - 1, "%s skeleton %u node %u: %s below %d",
                  path, s, n, ni.name, ni.parent);
        CHECK(ni.kind == (n + 1u == LEG_NODES ? MCD_NODE_VIRTUAL : MCD_NODE_JOINT));
        CHECK(ni.channel_count == (n == 0 ? 6u : n + 1u == LEG_NODES ? 0u : 3u));
        CHECK(ni.rest_scale[0] == 1.0f && ni.rest_scale[1] == 1.0f && ni.rest_scale[2] == 1.0f);
    }
    CHECK_RESULT(mcd_get_node_info(a, s, 1, &ni), MCD_OK);
    CHECK(axis_angle_gap(ni.rest_rotation, 1.0, 2.0, -0.5, 0.4) <= 1e-7);
    CHECK_RESULT(mcd_get_node_info(a, s, 6, &ni), MCD_OK);
    CHECK(axis_angle_gap(ni.rest_rotation, 0.3, -0.5, 0.81, 0.7) <= 1e-7);
}

/* 09_11.bvh: LeftUpLeg OFFSET 1.57314 -1.85774 0.63783; its first End Site OFFSET 0 -0 1.09718. */
static void check_09_11_offsets(const mcd_asset* a, uint32_t skeleton) {
    /* Stored as float objects: where FLT_EVAL_METHOD is 1 (s390x) a float constant keeps double
     * precision in an expression, and would never equal the float the asset holds. */
    static const float up_leg[3] = {1.57314f, -1.85774f, 0.63783f}, end_site[3] = {0.0f, 0.0f, 1.09718f};
    mcd_node_info ni;
    CHECK_RESULT(mcd_get_node_info(a, skeleton, 2, &ni), MCD_OK);
    CHECK(ni.rest_translation[0] == up_leg[0] && ni.rest_translation[1] == up_leg[1] && ni.rest_translation[2] == up_leg[2]);
    CHECK_RESULT(mcd_get_node_info(a, skeleton, 6, &ni), MCD_OK);
    CHECK(ni.rest_translation[0] == end_site[0] && ni.rest_translation[1] == end_site[1] && ni.rest_translation[2] == end_site[2]);
}

/* Position channels replace the rest translation and rotation channels the rest rotation
 * (docs/FORMAT.md "SKEL"): a node without them keeps its rest value, and no node of these
 * BVH skeletons has a scale other than its rest scale. The samples must agree with the node
 * info (translations within the quantisation an encoder may apply). */
static void check_rest_in_samples(const mcd_asset* a, uint32_t clip, void* scratch, mcd_transform* pose) {
    mcd_clip_info ci;
    uint32_t n, k;
    CHECK_RESULT(mcd_get_clip_info(a, clip, &ci), MCD_OK);
    CHECK_RESULT(mcd_sample(a, clip, 0.4f * ci.duration, 0, pose, MAX_NODES, scratch), MCD_OK);
    for (n = 0; n < ci.node_count; ++n) {
        mcd_node_info ni;
        int positioned = 0, rotated = 0;
        CHECK_RESULT(mcd_get_node_info(a, ci.skeleton, n, &ni), MCD_OK);
        for (k = 0; k < ni.channel_count && k < 6; ++k) {
            positioned |= ni.channels[k] <= MCD_CHANNEL_ZPOSITION;
            rotated |= ni.channels[k] >= MCD_CHANNEL_XROTATION;
        }
        CHECK_MSG(memcmp(pose[n].scale, ni.rest_scale, sizeof ni.rest_scale) == 0, "clip %u node %u: scale %g %g %g",
                  clip, n, pose[n].scale[0], pose[n].scale[1], pose[n].scale[2]);
        if (!rotated)
            CHECK_MSG(memcmp(pose[n].rotation, ni.rest_rotation, sizeof ni.rest_rotation) == 0,
                      "clip %u node %u: no rotation channel but rotation %g %g %g %g", clip, n, pose[n].rotation[0],
                      pose[n].rotation[1], pose[n].rotation[2], pose[n].rotation[3]);
        if (positioned) continue;
        for (k = 0; k < 3; ++k)
            CHECK_MSG(fabsf(pose[n].translation[k] - ni.rest_translation[k]) <= 1e-5f,
                      "clip %u node %u: translation %g, rest %g", clip, n, pose[n].translation[k], ni.rest_translation[k]);
    }
}

/* What the poses file implies: make_golden.py samples every clip at six times with four flag
 * sets each, the fourth time being the clip's duration; one row per node. */
static void check_against_poses(const mcd_golden* g) {
    pose_file poses;
    uint32_t max_clip = 0;
    size_t k;
    if (!read_poses(g->file.path, &poses)) return;
    CHECK(poses.count % 24u == 0);
    for (k = 0; k < poses.count; ++k) {
        mcd_clip_info ci;
        const pose_record* r = &poses.records[k];
        if (r->clip > max_clip) max_clip = r->clip;
        if (mcd_get_clip_info(&g->asset, r->clip, &ci) != MCD_OK) {
            FAIL("%s: poses name clip %u", g->file.path, r->clip);
            continue;
        }
        CHECK(r->nodes == ci.node_count);
        if ((k / 4) % 6 == 3) CHECK(r->time == ci.duration);
    }
    CHECK(mcd_clip_count(&g->asset) == max_clip + 1u);
    free_poses(&poses);
}

/* Per clip (mcd_clip_info): the scratch it needs, covered by the asset's (the largest clip's),
 * and the byte range its payload takes, inside the asset, clips of one codec section apart. */
static void check_clip_needs(const mcd_golden* g) {
    const mcd_asset* a = &g->asset;
    uint32_t c, d, largest = 0, clips = mcd_clip_count(a);
    for (c = 0; c < clips; ++c) {
        mcd_clip_info ci, di;
        CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
        CHECK(ci.scratch_size >= MCD_SCRATCH_MIN_SIZE && ci.scratch_size % 16u == 0);
        CHECK(ci.scratch_size <= mcd_scratch_size(a));
        if (ci.scratch_size > largest) largest = ci.scratch_size;
        CHECK(ci.data_size > 0 && ci.data_offset % 4u == 0);
        CHECK_MSG((uint64_t)ci.data_offset + ci.data_size <= g->file.size, "%s clip %u: data %u + %u past the asset",
                  g->file.path, c, ci.data_offset, ci.data_size);
        for (d = 0; d < c; ++d) {
            CHECK_RESULT(mcd_get_clip_info(a, d, &di), MCD_OK);
            CHECK_MSG(ci.data_offset >= di.data_offset + di.data_size || di.data_offset >= ci.data_offset + ci.data_size,
                      "%s: the data of clips %u and %u overlap", g->file.path, d, c);
        }
    }
    CHECK_MSG(largest == mcd_scratch_size(a), "%s: mcd_scratch_size %lu, largest clip %u", g->file.path,
              (unsigned long)mcd_scratch_size(a), largest);
}

/* The facts hard-coded above, for the golden files they describe. */
static void check_facts(const mcd_golden* g, const asset_fact* fact) {
    const mcd_asset* a = &g->asset;
    uint32_t c, s;
    CHECK(mcd_clip_count(a) == fact->clip_count);
    CHECK(mcd_skeleton_count(a) == fact->skeleton_count);
    for (s = 0; s < mcd_skeleton_count(a); ++s) {
        int leg = 0;
        for (c = 0; c < fact->clip_count; ++c) leg |= fact->clips[c].skeleton == s && fact->clips[c].leg;
        if (leg) check_leg_skeleton(a, s, g->file.path);
        else check_cmu_skeleton(a, s, g->file.path);
    }
    for (c = 0; c < mcd_clip_count(a) && c < fact->clip_count; ++c) {
        mcd_clip_info ci;
        CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
        CHECK(strcmp(ci.name, fact->clips[c].name) == 0);
        CHECK(ci.frame_count == fact->clips[c].frames);
        CHECK(ci.skeleton == fact->clips[c].skeleton);
        CHECK(ci.node_count == (fact->clips[c].leg ? LEG_NODES : CMU_NODES));
        CHECK(fabs((double)ci.frame_rate * CMU_FRAME_TIME - 1.0) < 1e-6);
        CHECK_MSG(ci.codec == fact->codec, "%s clip %u: codec %u, make_golden.py used %u", g->file.path, c, ci.codec,
                  fact->codec);
        if (strncmp(ci.name, "09_11", 5) == 0) check_09_11_offsets(a, ci.skeleton);
    }
}

void test_queries_match_golden(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, k;
    int seen[FACT_COUNT] = {0};
    mcd_transform* pose = (mcd_transform*)malloc(MAX_NODES * sizeof *pose);
    mcd_node_info* nodes = (mcd_node_info*)malloc(MAX_NODES * sizeof *nodes);
    for (i = 0; pose && nodes && i < n; ++i) {
        const mcd_asset* a = &g[i].asset;
        const asset_fact* fact = find_fact(g[i].file.path);
        uint32_t c, s;
        void* scratch = mcd_test_scratch(a);
        check_against_poses(&g[i]);
        check_clip_needs(&g[i]);
        for (s = 0; s < mcd_skeleton_count(a); ++s) check_skeleton_rules(a, s, g[i].file.path, nodes);
        for (c = 0; c < mcd_clip_count(a); ++c) {
            mcd_clip_info ci;
            uint32_t found = 99;
            CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
            CHECK(fabs((double)ci.duration - (double)(ci.frame_count - 1u) / ci.frame_rate) <= 1e-4 * ci.duration);
            CHECK_RESULT(mcd_find_clip(a, ci.name, &found), MCD_OK);
            CHECK(found == c);
            if (scratch) check_rest_in_samples(a, c, scratch, pose);
        }
        /* Every golden has its facts here: a new or renamed golden file fails until it does. */
        CHECK_MSG(fact != NULL, "%s: no facts in test_golden.c", g[i].file.path);
        if (fact) {
            seen[fact - k_facts] = 1;
            check_facts(&g[i], fact);
        }
        mcd_test_free_scratch(scratch);
    }
    /* And every golden make_golden.py always writes is there. */
    for (k = 0; k < FACT_COUNT; ++k) {
        CHECK_MSG(seen[k] || !k_facts[k].required, "%s missing from %s", k_facts[k].file, mcd_test_golden_dir());
        if (!seen[k] && !k_facts[k].required)
            mcd_test_note("not yet written (its codec's runtime port has not landed): %s", k_facts[k].file);
    }
    free(nodes);
    free(pose);
    mcd_test_free_golden(g, n);
}
