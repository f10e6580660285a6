/* Retargeting onto a rig (mocodec.h, "retargeting"), checked numerically on the golden assets:
 * the asset's own skeleton as the rig gives the sampled pose back; a rig with other rest
 * orientations (and the same rest shape) puts every joint where the world-space sample has it;
 * an A-posed rig follows the asset's bone directions with MCD_RETARGET_MATCH_DIRECTIONS and
 * not without; root motion, units, a rotated rig space, names, pairs and every bad input. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

/* ---------------------------------------------------------------- small binary64 helpers */

typedef struct { double x, y, z, w; } dq;
typedef struct { dq r; double t[3]; } dpose;

static dq q_of(const float* r) {
    dq q;
    q.x = r[0], q.y = r[1], q.z = r[2], q.w = r[3];
    return q;
}
static dq q_mul(dq a, dq b) {
    dq r;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    return r;
}
static dq q_conj(dq q) {
    q.x = -q.x, q.y = -q.y, q.z = -q.z;
    return q;
}
static void q_rot(dq q, const double v[3], double out[3]) {
    dq p, r;
    p.x = v[0], p.y = v[1], p.z = v[2], p.w = 0;
    r = q_mul(q_mul(q, p), q_conj(q));
    out[0] = r.x, out[1] = r.y, out[2] = r.z;
}
static dq q_axis(double x, double y, double z, double angle) {
    double n = sqrt(x * x + y * y + z * z), s = sin(angle / 2);
    dq q;
    q.x = x / n * s, q.y = y / n * s, q.z = z / n * s, q.w = cos(angle / 2);
    return q;
}
static void set_rot(float* out, dq q) {
    out[0] = (float)q.x, out[1] = (float)q.y, out[2] = (float)q.z, out[3] = (float)q.w;
}
/* |angle| between two rotations, radians (float poses are unit only to ~1e-7: normalised) */
static double q_angle(dq a, dq b) {
    double na = sqrt(a.x * a.x + a.y * a.y + a.z * a.z + a.w * a.w), nb = sqrt(b.x * b.x + b.y * b.y + b.z * b.z + b.w * b.w);
    double d = fabs(a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w) / (na * nb);
    return 2.0 * acos(d > 1.0 ? 1.0 : d);
}

/* World transforms (rotation, position; unit scales) from local ones, parents first. */
static void to_world(const mcd_transform* local, const int32_t* parent, uint32_t n, dpose* world) {
    uint32_t i, k;
    for (i = 0; i < n; ++i) {
        dq r = q_of(local[i].rotation);
        double t[3] = {local[i].translation[0], local[i].translation[1], local[i].translation[2]};
        if (parent[i] < 0) {
            world[i].r = r;
            for (k = 0; k < 3; ++k) world[i].t[k] = t[k];
        } else {
            const dpose* p = &world[parent[i]];
            double v[3];
            q_rot(p->r, t, v);
            world[i].r = q_mul(p->r, r);
            for (k = 0; k < 3; ++k) world[i].t[k] = p->t[k] + v[k];
        }
    }
}

static double dist(const double a[3], const double b[3]) {
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
}

/* ---------------------------------------------------------------- a rig from a skeleton */

typedef struct {
    uint32_t n;
    mcd_rig_bone* bones;
    int32_t* parent;
    char (*names)[64];
    mcd_transform* node_rest; /* the skeleton's own rest, per node */
    dpose* node_rest_world;
    uint32_t* kind;
} rig;

static int make_rig(const mcd_asset* a, uint32_t skeleton, rig* out) {
    mcd_skeleton_info si;
    uint32_t i;
    memset(out, 0, sizeof *out);
    if (mcd_get_skeleton_info(a, skeleton, &si) != MCD_OK) return 0;
    out->n = si.node_count;
    out->bones = calloc(si.node_count, sizeof *out->bones);
    out->parent = calloc(si.node_count, sizeof *out->parent);
    out->names = calloc(si.node_count, sizeof *out->names);
    out->node_rest = calloc(si.node_count, sizeof *out->node_rest);
    out->node_rest_world = calloc(si.node_count, sizeof *out->node_rest_world);
    out->kind = calloc(si.node_count, sizeof *out->kind);
    for (i = 0; i < si.node_count; ++i) {
        mcd_node_info ni;
        CHECK_RESULT(mcd_get_node_info(a, skeleton, i, &ni), MCD_OK);
        snprintf(out->names[i], 64, "%s", ni.name);
        out->parent[i] = ni.parent;
        out->kind[i] = ni.kind;
        memcpy(out->node_rest[i].rotation, ni.rest_rotation, sizeof ni.rest_rotation);
        memcpy(out->node_rest[i].translation, ni.rest_translation, sizeof ni.rest_translation);
        memcpy(out->node_rest[i].scale, ni.rest_scale, sizeof ni.rest_scale);
        out->bones[i].name = out->names[i];
        out->bones[i].parent = ni.parent;
        out->bones[i].rest = out->node_rest[i];
    }
    to_world(out->node_rest, out->parent, out->n, out->node_rest_world);
    return 1;
}

static void free_rig(rig* r) {
    free(r->bones);
    free(r->parent);
    free(r->names);
    free(r->node_rest);
    free(r->node_rest_world);
    free(r->kind);
}

/* An initialised map and work buffer; NULL on failure (a failed check). */
typedef struct { void* map; void* work; size_t work_size; } mapped;

static int build(const mcd_asset* a, uint32_t skeleton, const mcd_rig_bone* bones, uint32_t n,
                 const mcd_retarget_pair* pairs, uint32_t pair_count, const mcd_retarget_config* cfg, mapped* out) {
    size_t size = 0;
    mcd_retarget_info info;
    mcd_retarget_issue issue;
    mcd_result r;
    out->map = out->work = NULL;
    CHECK_RESULT(mcd_retarget_size(a, skeleton, n, &size), MCD_OK);
    out->map = malloc(size);
    r = mcd_retarget_init(a, skeleton, bones, n, pairs, pair_count, cfg, out->map, size, &issue);
    CHECK_MSG(r == MCD_OK, "mcd_retarget_init: %s (issue %u index %u)", mcd_result_string(r), issue.where, issue.index);
    if (r != MCD_OK) return 0;
    CHECK_RESULT(mcd_retarget_get_info(out->map, &info), MCD_OK);
    out->work_size = info.work_size;
    out->work = malloc(info.work_size);
    return 1;
}

static void unbuild(mapped* m) {
    free(m->map);
    free(m->work);
}

/* The golden assets this test uses: every one (skeletons of BVH and glTF kind). */
static size_t goldens(mcd_golden** g) {
    return mcd_test_load_golden(g);
}

static const float kTimes[] = {0.0f, 0.13f, 0.41f, 0.77f, 1.3f, 2.9f};
#define TIMES (sizeof kTimes / sizeof kTimes[0])

/* ---------------------------------------------------------------- tests */

/* The asset's own skeleton as the rig: the sampled pose comes back (to float rounding). */
void test_retarget_own_skeleton_exact(void) {
    mcd_golden* g;
    size_t n = goldens(&g), i;
    double worst = 0;
    for (i = 0; i < n; ++i) {
        mcd_asset* a = &g[i].asset;
        void* scratch = mcd_test_scratch(a);
        uint32_t c;
        for (c = 0; c < mcd_clip_count(a); ++c) {
            mcd_clip_info ci;
            rig r;
            mapped m;
            mcd_retarget_config cfg;
            mcd_transform* pose;
            mcd_transform* out;
            uint32_t t, j;
            CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
            if (!make_rig(a, ci.skeleton, &r)) continue;
            mcd_retarget_config_default(&cfg);
            pose = calloc(r.n, sizeof *pose);
            out = calloc(r.n, sizeof *out);
            if (build(a, ci.skeleton, r.bones, r.n, NULL, 0, &cfg, &m)) {
                mcd_retarget_info info;
                mcd_retarget_get_info(m.map, &info);
                for (j = 0; j < r.n; ++j) {
                    int32_t node = -5;
                    CHECK_RESULT(mcd_retarget_get_node(m.map, j, &node), MCD_OK);
                    /* virtual points match only by pair: they stay at rest, as sampled */
                    CHECK_MSG(node == (r.kind[j] == MCD_NODE_VIRTUAL ? -1 : (int32_t)j), "%s bone %u -> node %d",
                              g[i].file.path, j, node);
                }
                for (t = 0; t < TIMES; ++t) {
                    CHECK_RESULT(mcd_sample(a, c, kTimes[t] * ci.duration, 0, pose, r.n, scratch), MCD_OK);
                    CHECK_RESULT(mcd_retarget_pose(m.map, pose, r.n, out, r.n, m.work, m.work_size), MCD_OK);
                    for (j = 0; j < r.n; ++j) {
                        double d = q_angle(q_of(pose[j].rotation), q_of(out[j].rotation)), e = 0;
                        uint32_t k;
                        for (k = 0; k < 3; ++k) {
                            e = fmax(e, fabs(pose[j].translation[k] - out[j].translation[k]) / (1.0 + fabs(pose[j].translation[k])));
                            e = fmax(e, fabs(pose[j].scale[k] - out[j].scale[k]));
                        }
                        worst = fmax(worst, fmax(d, e));
                        CHECK_MSG(d <= 2e-6 && e <= 2e-6, "%s clip %u t %g bone %s: rotation %g rad, translation/scale %g apart",
                                  g[i].file.path, c, kTimes[t] * ci.duration, r.names[j], d, e);
                    }
                }
            }
            unbuild(&m);
            free(pose);
            free(out);
            free_rig(&r);
        }
        mcd_test_free_scratch(scratch);
    }
    mcd_test_note("largest difference from the sampled pose: %.2g (rad or relative)", worst);
    mcd_test_free_golden(g, n);
}

/* A rig with the asset's names and rest shape but its own rest orientation per bone (as an FBX
 * or glTF rig has): every joint lands where the asset's world-space sample puts it, and each
 * bone has turned from its rest as the node turned from its rest. Also through a rotated,
 * rescaled rig space (Z up, centimetres -> metres). */
void test_retarget_other_rest_orientations(void) {
    mcd_golden* g;
    size_t n = goldens(&g), i;
    double worst = 0, worst_turn = 0;
    for (i = 0; i < n; ++i) {
        mcd_asset* a = &g[i].asset;
        void* scratch = mcd_test_scratch(a);
        uint32_t c, variant;
        for (c = 0; c < mcd_clip_count(a); ++c)
            for (variant = 0; variant < 2; ++variant) {
                mcd_clip_info ci;
                mcd_skeleton_info si;
                rig r;
                mapped m;
                mcd_retarget_config cfg;
                mcd_transform *pose, *world, *out;
                dpose *rig_rest_world, *got;
                dq space = variant ? q_axis(1, 0, 0, 1.5707963267948966) : q_axis(1, 0, 0, 0);
                double scale = variant ? 0.01 : 1.0, size = 1.0;
                uint32_t t, j, k, state = 1234u + c;
                CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
                CHECK_RESULT(mcd_get_skeleton_info(a, ci.skeleton, &si), MCD_OK);
                if (!make_rig(a, ci.skeleton, &r)) continue;
                rig_rest_world = calloc(r.n, sizeof *rig_rest_world);
                got = calloc(r.n, sizeof *got);
                pose = calloc(r.n, sizeof *pose);
                world = calloc(r.n, sizeof *world);
                out = calloc(r.n, sizeof *out);
                /* rig rests: world rotation = S * node's * a random turn; world position = the
                 * node's, scaled and turned into rig space */
                for (j = 0; j < r.n; ++j) {
                    double u = (mcd_test_rand(&state) % 1000) / 1000.0, v = (mcd_test_rand(&state) % 1000) / 1000.0;
                    dq turn = q_axis(u - 0.5, 1.0 - v, u * v - 0.2, 0.3 + 2.5 * v);
                    double p[3];
                    rig_rest_world[j].r = q_mul(space, q_mul(r.node_rest_world[j].r, turn));
                    q_rot(space, r.node_rest_world[j].t, p);
                    for (k = 0; k < 3; ++k) rig_rest_world[j].t[k] = scale * p[k];
                    size = fmax(size, sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]));
                }
                for (j = 0; j < r.n; ++j) {
                    mcd_transform* rest = &r.bones[j].rest;
                    if (r.parent[j] < 0) {
                        set_rot(rest->rotation, rig_rest_world[j].r);
                        for (k = 0; k < 3; ++k) rest->translation[k] = (float)rig_rest_world[j].t[k];
                    } else {
                        const dpose* p = &rig_rest_world[r.parent[j]];
                        double d[3], l[3];
                        set_rot(rest->rotation, q_mul(q_conj(p->r), rig_rest_world[j].r));
                        for (k = 0; k < 3; ++k) d[k] = rig_rest_world[j].t[k] - p->t[k];
                        q_rot(q_conj(p->r), d, l);
                        for (k = 0; k < 3; ++k) rest->translation[k] = (float)l[k];
                    }
                }
                mcd_retarget_config_default(&cfg);
                cfg.unit_scale = (float)scale;
                set_rot(cfg.space_rotation, space);
                if (build(a, ci.skeleton, r.bones, r.n, NULL, 0, &cfg, &m)) {
                    for (t = 0; t < TIMES; ++t) {
                        float time = kTimes[t] * ci.duration;
                        CHECK_RESULT(mcd_sample(a, c, time, 0, pose, r.n, scratch), MCD_OK);
                        CHECK_RESULT(mcd_sample(a, c, time, MCD_SAMPLE_WORLD, world, r.n, scratch), MCD_OK);
                        CHECK_RESULT(mcd_retarget_pose(m.map, pose, r.n, out, r.n, m.work, m.work_size), MCD_OK);
                        to_world(out, r.parent, r.n, got);
                        for (j = 0; j < r.n; ++j) {
                            double want[3], w[3], d, turn_rig, turn_asset;
                            dq delta_rig, delta_asset;
                            for (k = 0; k < 3; ++k) w[k] = world[j].translation[k];
                            q_rot(space, w, want);
                            for (k = 0; k < 3; ++k) want[k] *= scale;
                            d = dist(got[j].t, want) / (scale * size);
                            worst = fmax(worst, d);
                            CHECK_MSG(d <= 2e-6, "%s clip %u variant %u t %g bone %s: %g of the skeleton's size from the world sample",
                                      g[i].file.path, c, variant, time, r.names[j], d);
                            /* rig: world * rest_world^-1; asset: S * world * rest_world^-1 * S^-1 */
                            if (r.kind[j] == MCD_NODE_VIRTUAL) continue; /* unmatched: follows its parent */
                            delta_rig = q_mul(got[j].r, q_conj(rig_rest_world[j].r));
                            delta_asset = q_mul(space, q_mul(q_mul(q_of(world[j].rotation), q_conj(r.node_rest_world[j].r)), q_conj(space)));
                            turn_rig = q_angle(delta_rig, delta_asset);
                            (void)turn_asset;
                            worst_turn = fmax(worst_turn, turn_rig);
                            CHECK_MSG(turn_rig <= 2e-5, "%s clip %u bone %s: turned %g rad otherwise than its node",
                                      g[i].file.path, c, r.names[j], turn_rig);
                        }
                    }
                }
                unbuild(&m);
                free(rig_rest_world);
                free(got);
                free(pose);
                free(world);
                free(out);
                free_rig(&r);
            }
        mcd_test_free_scratch(scratch);
    }
    mcd_test_note("joints off the world sample by at most %.2g of the skeleton's size; rotations by %.2g rad", worst, worst_turn);
    mcd_test_free_golden(g, n);
}

/* The largest angle between a bone's world direction (towards its only child) in the rig and
 * the node's in the asset, over the bones that have one child. */
static double direction_gap(const rig* r, const dpose* got, const mcd_transform* world, const char** worst_bone) {
    double worst = 0;
    uint32_t j, i;
    for (j = 0; j < r->n; ++j) {
        uint32_t children = 0, child = 0, k;
        double u[3], v[3], nu, nv, dot;
        for (i = j + 1; i < r->n; ++i)
            if (r->parent[i] == (int32_t)j && r->kind[i] != MCD_NODE_VIRTUAL) children++, child = i;
        if (children != 1) continue;
        for (k = 0; k < 3; ++k) {
            u[k] = got[child].t[k] - got[j].t[k];
            v[k] = (double)world[child].translation[k] - world[j].translation[k];
        }
        nu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        nv = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        if (nu < 1e-9 || nv < 1e-6) continue;
        dot = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (nu * nv);
        dot = acos(dot > 1 ? 1 : dot < -1 ? -1 : dot);
        if (dot > worst) {
            worst = dot;
            *worst_bone = r->names[j];
        }
    }
    return worst;
}

/* An A-posed rig of other proportions: every limb turned down 40 degrees at its root joint and
 * every bone 0.8 times as long. With MCD_RETARGET_MATCH_DIRECTIONS each single-child bone points
 * where its node points in the asset; without it, the limbs stay 40 degrees off. */
void test_retarget_matches_directions(void) {
    mcd_golden* g;
    size_t n = goldens(&g), i;
    double worst_on = 0, least_off = 1e9; /* least over skeletons of the worst gap without the flag */
    uint32_t tested = 0;
    for (i = 0; i < n; ++i) {
        mcd_asset* a = &g[i].asset;
        void* scratch = mcd_test_scratch(a);
        rig r;
        uint32_t s;
        for (s = 0; s < mcd_skeleton_count(a); ++s) {
            dpose* rest_world;
            mcd_transform *pose, *world, *out;
            dpose* got;
            uint32_t j, k, on, clip = UINT32_MAX, c, turned;
            double worst_off = 0;
            mcd_clip_info ci;
            for (c = 0; c < mcd_clip_count(a); ++c)
                if (mcd_get_clip_info(a, c, &ci) == MCD_OK && ci.skeleton == s) {
                    clip = c;
                    break;
                }
            if (clip == UINT32_MAX || !make_rig(a, s, &r)) continue;
            rest_world = calloc(r.n, sizeof *rest_world);
            got = calloc(r.n, sizeof *got);
            pose = calloc(r.n, sizeof *pose);
            world = calloc(r.n, sizeof *world);
            out = calloc(r.n, sizeof *out);
            /* rest shape: bones 0.8 as long, each limb swung 40 degrees at its first joint */
            for (j = 0; j < r.n; ++j) {
                for (k = 0; k < 3; ++k) r.bones[j].rest.translation[k] *= 0.8f;
            }
            {
                mcd_transform* local = calloc(r.n, sizeof *local);
                turned = 0;
                for (j = 0; j < r.n; ++j) local[j] = r.bones[j].rest;
                for (j = 1; j < r.n; ++j) {
                    /* the first joint of a limb: its parent branches, it has one child, at a
                     * distance (CMU's branch joints sit at their parent, so the limb starts one
                     * joint down) */
                    uint32_t siblings = 0, children = 0, child = 0, q;
                    double d[3], up[3] = {0, 1, 0}, axis[3], len;
                    if (r.parent[j] < 0) continue;
                    for (q = 0; q < r.n; ++q) {
                        if (r.parent[q] == r.parent[j]) siblings++;
                        if (r.parent[q] == (int32_t)j) children++, child = q;
                    }
                    if (siblings < 2 || children != 1) continue;
                    /* the child's direction in the parent's frame (rest rotations as stored) */
                    for (k = 0; k < 3; ++k) axis[k] = local[child].translation[k];
                    q_rot(q_of(local[j].rotation), axis, d);
                    axis[0] = d[1] * up[2] - d[2] * up[1];
                    axis[1] = d[2] * up[0] - d[0] * up[2];
                    axis[2] = d[0] * up[1] - d[1] * up[0];
                    len = sqrt(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
                    if (len < 1e-6 * (1.0 + sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]))) continue;
                    /* turn the joint's rest rotation: its whole limb swings 40 degrees */
                    set_rot(local[j].rotation, q_mul(q_axis(axis[0], axis[1], axis[2], 0.7), q_of(local[j].rotation)));
                    turned++;
                }
                for (j = 0; j < r.n; ++j) r.bones[j].rest = local[j];
                free(local);
            }
            for (on = 0; on < 2; ++on) {
                mcd_retarget_config cfg;
                mapped m;
                uint32_t t;
                mcd_retarget_config_default(&cfg);
                cfg.flags = on ? MCD_RETARGET_MATCH_DIRECTIONS | MCD_RETARGET_ROOT_MOTION : MCD_RETARGET_ROOT_MOTION;
                if (!build(a, s, r.bones, r.n, NULL, 0, &cfg, &m)) {
                    unbuild(&m);
                    continue;
                }
                CHECK_RESULT(mcd_get_clip_info(a, clip, &ci), MCD_OK);
                for (t = 0; t < TIMES; ++t) {
                    const char* bone = "";
                    double gap;
                    CHECK_RESULT(mcd_sample(a, clip, kTimes[t] * ci.duration, 0, pose, r.n, scratch), MCD_OK);
                    CHECK_RESULT(mcd_sample(a, clip, kTimes[t] * ci.duration, MCD_SAMPLE_WORLD, world, r.n, scratch), MCD_OK);
                    CHECK_RESULT(mcd_retarget_pose(m.map, pose, r.n, out, r.n, m.work, m.work_size), MCD_OK);
                    to_world(out, r.parent, r.n, got);
                    gap = direction_gap(&r, got, world, &bone);
                    if (on) {
                        worst_on = fmax(worst_on, gap);
                        CHECK_MSG(gap <= 1e-4, "%s skeleton %u t %g: bone %s points %g rad off its node", g[i].file.path, s,
                                  kTimes[t] * ci.duration, bone, gap);
                    } else {
                        worst_off = fmax(worst_off, gap);
                    }
                }
                tested++;
                unbuild(&m);
            }
            /* without the flag the turned limbs are visibly off: the check above is not vacuous */
            if (turned) {
                least_off = fmin(least_off, worst_off);
                CHECK_MSG(worst_off > 0.3, "%s skeleton %u: without MATCH_DIRECTIONS the A-posed limbs are only %g rad off",
                          g[i].file.path, s, worst_off);
            }
            free(rest_world);
            free(got);
            free(pose);
            free(world);
            free(out);
            free_rig(&r);
        }
        mcd_test_free_scratch(scratch);
    }
    CHECK(tested > 0 && least_off < 1e9);
    mcd_test_note("bone directions: at most %.2g rad off with MATCH_DIRECTIONS, at least %.2g rad without", worst_on, least_off);
    mcd_test_free_golden(g, n);
}

/* Root motion off keeps the motion root over its rest spot (height still moves); a bone flagged
 * KEEP_TRANSLATION does not move at all; unit_scale scales the root's travel. */
void test_retarget_root_motion(void) {
    mcd_golden* g;
    size_t n = goldens(&g), i;
    for (i = 0; i < n; ++i) {
        mcd_asset* a = &g[i].asset;
        void* scratch = mcd_test_scratch(a);
        mcd_clip_info ci;
        rig r;
        mcd_retarget_config cfg;
        mapped on, off, keep;
        mcd_transform *pose, *o1, *o2, *o3;
        uint32_t t, k, up;
        CHECK_RESULT(mcd_get_clip_info(a, 0, &ci), MCD_OK);
        if (!make_rig(a, ci.skeleton, &r)) continue;
        pose = calloc(r.n, sizeof *pose);
        o1 = calloc(r.n, sizeof *o1);
        o2 = calloc(r.n, sizeof *o2);
        o3 = calloc(r.n, sizeof *o3);
        r.bones[0].rest.translation[0] = 7.0f; /* a rest spot off the origin */
        r.bones[0].rest.translation[2] = -3.0f;
        for (up = 0; up < 3; ++up) {
            mcd_retarget_config_default(&cfg);
            cfg.unit_scale = 0.5f;
            cfg.up_axis = up;
            build(a, ci.skeleton, r.bones, r.n, NULL, 0, &cfg, &on);
            cfg.flags &= ~MCD_RETARGET_ROOT_MOTION;
            build(a, ci.skeleton, r.bones, r.n, NULL, 0, &cfg, &off);
            r.bones[0].flags = MCD_RIG_BONE_KEEP_TRANSLATION;
            build(a, ci.skeleton, r.bones, r.n, NULL, 0, &cfg, &keep);
            r.bones[0].flags = 0;
            for (t = 0; t < TIMES && on.map && off.map && keep.map; ++t) {
                CHECK_RESULT(mcd_sample(a, 0, kTimes[t] * ci.duration, 0, pose, r.n, scratch), MCD_OK);
                CHECK_RESULT(mcd_retarget_pose(on.map, pose, r.n, o1, r.n, on.work, on.work_size), MCD_OK);
                CHECK_RESULT(mcd_retarget_pose(off.map, pose, r.n, o2, r.n, off.work, off.work_size), MCD_OK);
                CHECK_RESULT(mcd_retarget_pose(keep.map, pose, r.n, o3, r.n, keep.work, keep.work_size), MCD_OK);
                for (k = 0; k < 3; ++k) {
                    double travel = 0.5 * pose[0].translation[k];
                    CHECK(fabs(o1[0].translation[k] - travel) <= 1e-5 * (1 + fabs(travel)));
                    CHECK(fabs(o2[0].translation[k] - (k == up ? travel : r.bones[0].rest.translation[k])) <= 1e-5 * (1 + fabs(travel)));
                    CHECK(o3[0].translation[k] == r.bones[0].rest.translation[k]);
                }
                CHECK(q_angle(q_of(o1[0].rotation), q_of(o2[0].rotation)) < 1e-6); /* rotation unaffected */
            }
            unbuild(&on);
            unbuild(&off);
            unbuild(&keep);
        }
        free(pose);
        free(o1);
        free(o2);
        free(o3);
        free_rig(&r);
        mcd_test_free_scratch(scratch);
    }
    mcd_test_free_golden(g, n);
}

/* Names: a namespace, case and separators do not stop a match; an ambiguous loose name does;
 * pairs override names and can leave a bone out; an unknown bone or node in a pair is refused. */
void test_retarget_names_and_pairs(void) {
    mcd_golden* g;
    size_t n = goldens(&g), i;
    for (i = 0; i < n && i < 1; ++i) {
        mcd_asset* a = &g[i].asset;
        rig r;
        mcd_retarget_config cfg;
        mapped m;
        uint32_t j;
        int32_t node;
        mcd_retarget_pair pairs[3];
        mcd_retarget_issue issue;
        size_t size;
        void* map;
        if (!make_rig(a, 0, &r)) continue;
        mcd_retarget_config_default(&cfg);
        /* "rig:LEFT_up.leg"-style names */
        for (j = 0; j < r.n; ++j) {
            char loose[48];
            size_t k, o = 0;
            for (k = 0; r.names[j][k] && o < 44; ++k) {
                char ch = r.names[j][k];
                if (k == 2) loose[o++] = '_';
                loose[o++] = (char)((ch >= 'a' && ch <= 'z') ? ch - 'a' + 'A' : ch);
            }
            loose[o] = 0;
            snprintf(r.names[j], 64, "mixamorig:%s", loose);
        }
        if (build(a, 0, r.bones, r.n, NULL, 0, &cfg, &m)) {
            mcd_retarget_info info;
            mcd_retarget_get_info(m.map, &info);
            for (j = 0; j < r.n; ++j) {
                mcd_retarget_get_node(m.map, j, &node);
                CHECK_MSG(node == (r.kind[j] == MCD_NODE_VIRTUAL ? -1 : (int32_t)j) || node == -1,
                          "loose name %s -> node %d", r.names[j], node);
            }
            CHECK_MSG(info.matched + 8u >= r.n, "only %u of %u loose names matched", info.matched, r.n);
            CHECK_RESULT(mcd_retarget_get_node(m.map, r.n, &node), MCD_ERROR_OUT_OF_RANGE);
            CHECK_RESULT(mcd_retarget_get_node(m.map, 0, NULL), MCD_ERROR_INVALID_ARGUMENT);
        }
        unbuild(&m);
        /* pairs: bone 1 driven by node 2, bone 2 by nothing */
        {
            mcd_node_info n2;
            mcd_get_node_info(a, 0, 2, &n2);
            pairs[0].bone = r.names[1];
            pairs[0].node = n2.name;
            pairs[1].bone = r.names[2];
            pairs[1].node = NULL;
            if (build(a, 0, r.bones, r.n, pairs, 2, &cfg, &m)) {
                mcd_retarget_get_node(m.map, 1, &node);
                CHECK(node == 2);
                mcd_retarget_get_node(m.map, 2, &node);
                CHECK(node == -1);
            }
            unbuild(&m);
        }
        /* two nodes that look alike once loosened: neither is picked */
        snprintf(r.names[0], 64, "%s", "no_such_bone");
        mcd_retarget_size(a, 0, r.n, &size);
        map = malloc(size);
        pairs[0].bone = "not a bone";
        pairs[0].node = NULL;
        CHECK_RESULT(mcd_retarget_init(a, 0, r.bones, r.n, pairs, 1, &cfg, map, size, &issue), MCD_ERROR_NOT_FOUND);
        CHECK(issue.where == MCD_RETARGET_ISSUE_PAIR && issue.index == 0);
        pairs[0].bone = r.names[3];
        pairs[0].node = "not a node";
        CHECK_RESULT(mcd_retarget_init(a, 0, r.bones, r.n, pairs, 1, &cfg, map, size, &issue), MCD_ERROR_NOT_FOUND);
        CHECK(issue.where == MCD_RETARGET_ISSUE_PAIR && issue.index == 0);
        pairs[0].node = NULL;
        pairs[1].bone = r.names[4];
        pairs[1].node = NULL;
        pairs[2].bone = r.names[3];
        pairs[2].node = NULL;
        CHECK_RESULT(mcd_retarget_init(a, 0, r.bones, r.n, pairs, 3, &cfg, map, size, &issue), MCD_ERROR_INVALID_ARGUMENT);
        CHECK(issue.where == MCD_RETARGET_ISSUE_PAIR && issue.index == 2);
        CHECK_RESULT(mcd_retarget_init(a, 0, r.bones, r.n, pairs, 2, &cfg, map, size, &issue), MCD_OK);
        mcd_retarget_get_node(map, 0, &node);
        CHECK(node == -1); /* no_such_bone */
        free(map);
        free_rig(&r);
    }
    mcd_test_free_golden(g, n);
}

/* Every bad input to init and pose, each with the result (and issue) the header names. */
void test_retarget_argument_checks(void) {
    mcd_golden* g;
    size_t n = goldens(&g), size = 0;
    mcd_asset* a;
    rig r;
    mcd_retarget_config cfg;
    mcd_retarget_issue issue;
    mcd_retarget_info info;
    uint8_t* block;
    void* map;
    void* work;
    mcd_transform *pose, *out;
    mcd_rig_bone saved;
    char long_name[300];
    uint32_t j;
    if (n == 0) return;
    a = &g[0].asset;
    if (!make_rig(a, 0, &r)) return;
    mcd_retarget_config_default(&cfg);
    CHECK(cfg.flags == (MCD_RETARGET_ROOT_MOTION | MCD_RETARGET_MATCH_DIRECTIONS) && cfg.up_axis == 1 &&
          cfg.unit_scale == 1.0f && cfg.space_rotation[3] == 1.0f);
    mcd_retarget_config_default(NULL); /* no crash */
    CHECK_RESULT(mcd_retarget_size(NULL, 0, r.n, &size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_size(a, 0, r.n, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_size(a, 0, 0, &size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_size(a, 0, 1025, &size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_size(a, mcd_skeleton_count(a), r.n, &size), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_retarget_size(a, 0, r.n, &size), MCD_OK);
    block = malloc(size + 8);
    map = block;
#define INIT(...) mcd_retarget_init(__VA_ARGS__, &issue)
#define ISSUE(w, i) CHECK_MSG(issue.where == (w) && issue.index == (i), "issue %u index %u, want %u %u", issue.where, issue.index, (unsigned)(w), (unsigned)(i))
    CHECK_RESULT(INIT(NULL, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    ISSUE(MCD_RETARGET_ISSUE_CONFIG, 0);
    CHECK_RESULT(INIT(a, 0, NULL, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 1, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, NULL, map, size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, NULL, size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, block + 4, size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(INIT(a, 0, r.bones, 0, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size - 1), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(INIT(a, 99, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_OUT_OF_RANGE);
    cfg.flags = 0x4u;
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    ISSUE(MCD_RETARGET_ISSUE_CONFIG, 0);
    mcd_retarget_config_default(&cfg);
    cfg.up_axis = 3;
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    mcd_retarget_config_default(&cfg);
    cfg.unit_scale = 0.0f;
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    cfg.unit_scale = -1.0f;
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    cfg.unit_scale = (float)NAN;
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    mcd_retarget_config_default(&cfg);
    cfg.space_rotation[3] = 0.5f;
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    mcd_retarget_config_default(&cfg);
    /* bones: one broken at index 3 at a time */
    memset(long_name, 'a', sizeof long_name - 1);
    long_name[sizeof long_name - 1] = 0;
    for (j = 0; j < 12; ++j) {
        saved = r.bones[3];
        switch (j) {
        case 0: r.bones[3].name = NULL; break;
        case 1: r.bones[3].name = ""; break;
        case 2: r.bones[3].name = long_name; break;
        case 3: r.bones[3].name = "bad\xC3("; break;       /* broken UTF-8 */
        case 4: r.bones[3].name = r.bones[1].name; break; /* a second bone of that name */
        case 5: r.bones[3].parent = 3; break;             /* not before itself */
        case 6: r.bones[3].parent = -2; break;
        case 7: r.bones[3].flags = 0x2u; break;
        case 8: r.bones[3].rest.rotation[0] += 0.5f; break; /* not unit */
        case 9: r.bones[3].rest.translation[1] = (float)INFINITY; break;
        case 10: r.bones[3].rest.scale[2] = 0.0f; break;
        default: r.bones[3].rest.rotation[2] = (float)NAN; break;
        }
        CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
        ISSUE(MCD_RETARGET_ISSUE_BONE, 3);
        r.bones[3] = saved;
    }
    {
        mcd_retarget_pair p = {NULL, NULL};
        CHECK_RESULT(INIT(a, 0, r.bones, r.n, &p, 1, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
        ISSUE(MCD_RETARGET_ISSUE_PAIR, 0);
        p.bone = r.names[0];
        p.node = "";
        CHECK_RESULT(INIT(a, 0, r.bones, r.n, &p, 1, &cfg, map, size), MCD_ERROR_INVALID_ARGUMENT);
    }
    /* a failed init leaves no map behind */
    CHECK_RESULT(mcd_retarget_get_info(map, &info), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(INIT(a, 0, r.bones, r.n, NULL, 0, &cfg, map, size), MCD_OK);
    ISSUE(MCD_RETARGET_ISSUE_NONE, 0);
    CHECK_RESULT(mcd_retarget_get_info(NULL, &info), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_get_info(map, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_get_info(map, &info), MCD_OK);
    CHECK(info.bone_count == r.n && info.node_count == r.n && info.work_size > 0);
    /* pose */
    pose = calloc(r.n, sizeof *pose);
    out = calloc(r.n, sizeof *out);
    work = malloc(info.work_size + 8);
    {
        void* scratch = mcd_test_scratch(a);
        CHECK_RESULT(mcd_sample(a, 0, 0.2f, 0, pose, r.n, scratch), MCD_OK);
        mcd_test_free_scratch(scratch);
    }
    CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, work, info.work_size), MCD_OK);
    CHECK(mcd_test_pose_finite(out, r.n));
    CHECK_RESULT(mcd_retarget_pose(NULL, pose, r.n, out, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_pose(pose, pose, r.n, out, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT); /* not a map */
    CHECK_RESULT(mcd_retarget_pose(map, NULL, r.n, out, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_pose(map, pose, r.n - 1, out, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, NULL, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n - 1, work, info.work_size), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, NULL, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, work, info.work_size - 1), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, (uint8_t*)work + 4, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
    {
        mcd_transform keep = pose[2];
        mcd_transform* doubled = calloc(r.n, sizeof *doubled);
        uint32_t k;
        pose[2].translation[1] = (float)NAN;
        CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
        pose[2] = keep;
        pose[2].scale[0] = (float)INFINITY;
        CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
        pose[2] = keep;
        memset(pose[2].rotation, 0, sizeof pose[2].rotation);
        CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, work, info.work_size), MCD_ERROR_INVALID_ARGUMENT);
        pose[2] = keep;
        /* a rotation not of unit length (a blend) is normalised, not refused */
        CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, out, r.n, work, info.work_size), MCD_OK);
        for (k = 0; k < 4; ++k) pose[2].rotation[k] *= 2.0f;
        CHECK_RESULT(mcd_retarget_pose(map, pose, r.n, doubled, r.n, work, info.work_size), MCD_OK);
        for (j = 0; j < r.n; ++j) CHECK(q_angle(q_of(out[j].rotation), q_of(doubled[j].rotation)) < 1e-6);
        free(doubled);
    }
#undef INIT
#undef ISSUE
    free(pose);
    free(out);
    free(work);
    free(block);
    free_rig(&r);
    mcd_test_free_golden(g, n);
}
