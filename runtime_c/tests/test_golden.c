/* Golden assets: every released asset validates and samples to the poses recorded beside it
 * (tests/golden/make_golden.py documents the poses format), and the queries report what the
 * file holds. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

/* One `sample <clip> <time> <flags>` record and its node_count rows of qx qy qz qw tx ty tz. */
typedef struct pose_record {
    uint32_t clip, flags, nodes;
    float time;
    float* values; /* nodes * 7 */
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

static int add_row(pose_record* r, const char* line, size_t* cap) {
    float v[7];
    if (sscanf(line, "%g %g %g %g %g %g %g", &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6]) != 7) return 0;
    if (r->nodes == *cap) {
        float* grown;
        *cap = *cap ? 2u * *cap : 64u;
        grown = (float*)realloc(r->values, *cap * 7u * sizeof(float));
        if (!grown) return 0;
        r->values = grown;
    }
    memcpy(r->values + (size_t)r->nodes * 7u, v, sizeof v);
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

void test_golden_replay(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, k;
    for (i = 0; i < n; ++i) {
        pose_file poses;
        void* scratch;
        mcd_transform pose[1024];
        CHECK_RESULT(mcd_validate(g[i].file.data, g[i].file.size, 0), MCD_OK);
        CHECK_RESULT(mcd_validate(g[i].file.data, g[i].file.size, MCD_VALIDATE_SKIP_CHECKSUM), MCD_OK);
        if (!read_poses(g[i].file.path, &poses)) continue;
        scratch = mcd_test_scratch(&g[i].asset);
        for (k = 0; scratch && k < poses.count; ++k) {
            const pose_record* r = &poses.records[k];
            mcd_clip_info info;
            uint32_t node;
            CHECK_RESULT(mcd_get_clip_info(&g[i].asset, r->clip, &info), MCD_OK);
            if (r->nodes != info.node_count || r->nodes > 1024) {
                FAIL("%s sample %lu: %u rows for %u nodes", g[i].file.path, (unsigned long)k, r->nodes, info.node_count);
                continue;
            }
            CHECK_RESULT(mcd_sample(&g[i].asset, r->clip, r->time, r->flags, pose, 1024, scratch), MCD_OK);
            for (node = 0; node < r->nodes; ++node) {
                const float* want = r->values + (size_t)node * 7u;
                float got[7];
                int c = 0;
                memcpy(got, pose[node].rotation, 4 * sizeof(float));
                memcpy(got + 4, pose[node].translation, 3 * sizeof(float));
                while (c < 7 && close_enough(got[c], want[c])) c++;
                CHECK_MSG(c == 7, "%s clip %u t=%.9g flags %u node %u value %d: got %.9g, want %.9g", g[i].file.path,
                          r->clip, r->time, r->flags, node, c, got[c < 7 ? c : 0], want[c < 7 ? c : 0]);
            }
        }
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
    uint32_t frames;   /* BVH `Frames:` (02_01_head: the first 61 frames) */
    uint32_t skeleton; /* make_golden.py: one skeleton per source file, in order */
} clip_fact;

typedef struct asset_fact {
    const char* file; /* name in tests/golden/v1 */
    uint32_t clip_count, skeleton_count;
    clip_fact clips[2];
} asset_fact;

static const asset_fact k_facts[] = {
    {"spline_09_11.mcd", 1, 1, {{"09_11", 166, 0}}},
    {"spline_library.mcd", 2, 2, {{"07_01", 317, 0}, {"02_01_head", 61, 1}}},
    {"rma_library.mcd", 2, 2, {{"07_01", 317, 0}, {"09_11", 166, 1}}},
    {"spline_contacts_02_01.mcd", 1, 1, {{"02_01", 344, 0}}}, /* make_golden_contacts.py */
};

/* Every CMU skeleton here: 31 joints (1 ROOT + 30 JOINT) + 7 End Sites = 38 nodes. */
#define CMU_NODES 38u
#define CMU_END_SITES 7u
#define CMU_FRAME_TIME 0.0083333 /* BVH `Frame Time:` */

static const asset_fact* find_fact(const char* path) {
    size_t i, len = strlen(path);
    for (i = 0; i < sizeof k_facts / sizeof k_facts[0]; ++i) {
        size_t fl = strlen(k_facts[i].file);
        if (len >= fl && strcmp(path + len - fl, k_facts[i].file) == 0 && (len == fl || path[len - fl - 1] == '/'))
            return &k_facts[i];
    }
    return NULL;
}

#define MAX_NODES 1024u /* docs/FORMAT.md, SKEL node_count */

/* Format rules every skeleton follows (docs/FORMAT.md "SKEL"), read back through the queries. */
static void check_skeleton_rules(const mcd_asset* a, uint32_t s, const char* path, mcd_node_info* nodes) {
    mcd_skeleton_info si;
    uint32_t n, k;
    CHECK_RESULT(mcd_get_skeleton_info(a, s, &si), MCD_OK);
    CHECK(si.cm_per_unit > 0.0f);
    for (n = 0; n < si.node_count && n < MAX_NODES; ++n) {
        mcd_node_info* ni = &nodes[n];
        CHECK_RESULT(mcd_get_node_info(a, s, n, ni), MCD_OK);
        CHECK(ni->name != NULL && ni->name[0] != 0);
        for (k = 0; k < n; ++k)
            CHECK_MSG(strcmp(nodes[k].name, ni->name) != 0, "%s skeleton %u: name %s twice", path, s, ni->name);
        CHECK(ni->parent >= -1 && ni->parent < (int32_t)n);
        if (ni->parent >= 0) CHECK(!nodes[ni->parent].is_end_site);
        CHECK(ni->channel_count <= 6);
        if (ni->is_end_site) CHECK(ni->channel_count == 0);
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
        if (ni->is_end_site) {
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
    CHECK(nodes[6].is_end_site && nodes[6].parent == 5);
}

/* 09_11.bvh: LeftUpLeg OFFSET 1.57314 -1.85774 0.63783; its first End Site OFFSET 0 -0 1.09718. */
static void check_09_11_offsets(const mcd_asset* a) {
    /* Stored as float objects: where FLT_EVAL_METHOD is 1 (s390x) a float constant keeps double
     * precision in an expression, and would never equal the float the asset holds. */
    static const float up_leg[3] = {1.57314f, -1.85774f, 0.63783f}, end_site[3] = {0.0f, 0.0f, 1.09718f};
    mcd_node_info ni;
    CHECK_RESULT(mcd_get_node_info(a, 0, 2, &ni), MCD_OK);
    CHECK(ni.rest_offset[0] == up_leg[0] && ni.rest_offset[1] == up_leg[1] && ni.rest_offset[2] == up_leg[2]);
    CHECK_RESULT(mcd_get_node_info(a, 0, 6, &ni), MCD_OK);
    CHECK(ni.rest_offset[0] == end_site[0] && ni.rest_offset[1] == end_site[1] && ni.rest_offset[2] == end_site[2]);
}

/* Position channels replace the OFFSET (docs/FORMAT.md "SKEL"): a node without them keeps its
 * OFFSET as local translation, and an end site also keeps the identity rotation. The samples
 * must agree with the node info (within the translation quantisation an encoder may apply). */
static void check_rest_in_samples(const mcd_asset* a, uint32_t clip, void* scratch, mcd_transform* pose) {
    mcd_clip_info ci;
    uint32_t n, k;
    CHECK_RESULT(mcd_get_clip_info(a, clip, &ci), MCD_OK);
    CHECK_RESULT(mcd_sample(a, clip, 0.4f * ci.duration, 0, pose, MAX_NODES, scratch), MCD_OK);
    for (n = 0; n < ci.node_count; ++n) {
        mcd_node_info ni;
        int positioned = 0;
        CHECK_RESULT(mcd_get_node_info(a, ci.skeleton, n, &ni), MCD_OK);
        for (k = 0; k < ni.channel_count && k < 6; ++k) positioned |= ni.channels[k] <= MCD_CHANNEL_ZPOSITION;
        if (positioned) continue;
        for (k = 0; k < 3; ++k)
            CHECK_MSG(fabsf(pose[n].translation[k] - ni.rest_offset[k]) <= 1e-5f, "clip %u node %u: translation %g, OFFSET %g",
                      clip, n, pose[n].translation[k], ni.rest_offset[k]);
        if (ni.is_end_site)
            CHECK(pose[n].rotation[0] == 0.0f && pose[n].rotation[1] == 0.0f && pose[n].rotation[2] == 0.0f &&
                  pose[n].rotation[3] == 1.0f);
    }
}

/* What the poses file implies: make_golden.py samples every clip at six times with four flag
 * sets each, the fourth time being the clip's duration; one row per node. */
static void check_against_poses(const mcd_golden* g) {
    pose_file poses;
    uint32_t max_clip = 0;
    size_t k;
    if (!read_poses(g->file.path, &poses)) return;
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

/* The facts hard-coded above, for the golden files they describe. */
static void check_facts(const mcd_golden* g, const asset_fact* fact) {
    const mcd_asset* a = &g->asset;
    uint32_t c, s;
    CHECK(mcd_clip_count(a) == fact->clip_count);
    CHECK(mcd_skeleton_count(a) == fact->skeleton_count);
    for (s = 0; s < mcd_skeleton_count(a); ++s) check_cmu_skeleton(a, s, g->file.path);
    for (c = 0; c < mcd_clip_count(a) && c < fact->clip_count; ++c) {
        mcd_clip_info ci;
        CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
        CHECK(strcmp(ci.name, fact->clips[c].name) == 0);
        CHECK(ci.frame_count == fact->clips[c].frames);
        CHECK(ci.skeleton == fact->clips[c].skeleton);
        CHECK(ci.node_count == CMU_NODES);
        CHECK(fabs((double)ci.frame_rate * CMU_FRAME_TIME - 1.0) < 1e-6);
        /* make_golden.py: the spline_* assets are encoded with the spline codec */
        if (strncmp(fact->file, "spline_", 7) == 0) CHECK(ci.codec == MCD_CODEC_SPLINE);
        if (strncmp(fact->file, "rma_", 4) == 0) CHECK(ci.codec == MCD_CODEC_RMA);
    }
    if (strcmp(fact->clips[0].name, "09_11") == 0) check_09_11_offsets(a);
}

void test_queries_match_golden(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, known = 0;
    mcd_transform* pose = (mcd_transform*)malloc(MAX_NODES * sizeof *pose);
    mcd_node_info* nodes = (mcd_node_info*)malloc(MAX_NODES * sizeof *nodes);
    for (i = 0; pose && nodes && i < n; ++i) {
        const mcd_asset* a = &g[i].asset;
        const asset_fact* fact = find_fact(g[i].file.path);
        uint32_t c, s, in_place = 1;
        size_t resident = 99;
        void* scratch = mcd_test_scratch(a);
        check_against_poses(&g[i]);
        for (s = 0; s < mcd_skeleton_count(a); ++s) check_skeleton_rules(a, s, g[i].file.path, nodes);
        for (c = 0; c < mcd_clip_count(a); ++c) {
            mcd_clip_info ci;
            uint32_t found = 99;
            CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
            in_place &= ci.codec == MCD_CODEC_SPLINE;
            CHECK(fabs((double)ci.duration - (double)(ci.frame_count - 1u) / ci.frame_rate) <= 1e-4 * ci.duration);
            CHECK_RESULT(mcd_find_clip(a, ci.name, &found), MCD_OK);
            CHECK(found == c);
            if (scratch) check_rest_in_samples(a, c, scratch, pose);
        }
        CHECK_RESULT(mcd_resident_size(g[i].file.data, g[i].file.size, 0, &resident), MCD_OK);
        if (in_place) CHECK(resident == 0); /* spline clips are sampled in place (mocodec.h) */
        if (fact && strncmp(fact->file, "rma_", 4) == 0) CHECK(resident > 0); /* rma decodes at open */
        if (fact) {
            known++;
            check_facts(&g[i], fact);
        }
        mcd_test_free_scratch(scratch);
    }
    /* The hard-coded facts must meet their files: a renamed golden asset fails here. */
    CHECK(known == sizeof k_facts / sizeof k_facts[0]);
    free(nodes);
    free(pose);
    mcd_test_free_golden(g, n);
}
