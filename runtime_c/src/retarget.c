/* Retargeting a sampled pose onto a game's rig (mocodec.h, "retargeting"): the name match and the
 * constant rotations are worked out once in mcd_retarget_init; mcd_retarget_pose is two passes
 * over the nodes and bones in binary64, so a rig identical to the asset's skeleton gets the
 * sampled pose back to the last float bit or so. */
#include <math.h>
#include <string.h>

#include "internal.h"

#define MAP_MAGIC 0x5452434Du /* "MCRT" */
#define MAX_BONES MCD_MAX_NODES
#define MAX_ABS 1e7
#define UNIT_TOLERANCE 1e-3
#define MIN_SCALE 1e-6

/* bone modes */
#define BONE_MATCHED 0x1u
#define BONE_MOTION_ROOT 0x2u
#define BONE_KEEP_TRANSLATION 0x4u

typedef struct map_header {
    uint32_t magic;
    uint32_t bones;
    uint32_t nodes;
    uint32_t flags;
    uint32_t up_axis;
    uint32_t matched;
    uint32_t work_size;
    uint32_t reserved;
    double unit_scale;
    mcd_dquat space;
} map_header;

typedef struct map_bone {
    int32_t node;   /* -1: not driven */
    int32_t parent; /* -1: a root of the rig */
    uint32_t mode;
    uint32_t reserved;
    mcd_dquat k;       /* world(bone) = S world(node) k */
    mcd_dquat rest_r;
    double rest_t[3];
    double rest_s[3];
    double home[3];    /* rest position in rig space: where root motion off keeps the root */
} map_bone;

typedef struct map_node {
    int32_t parent;
    uint32_t reserved;
    double rest_t[3];
    double inv_rest_s[3];
} map_node;

/* A world (or local) transform in binary64. */
typedef struct dxf {
    mcd_dquat r;
    double t[3];
    double s[3];
} dxf;

static size_t map_bytes(uint32_t bones, uint32_t nodes) {
    return sizeof(map_header) + (size_t)bones * sizeof(map_bone) + (size_t)nodes * sizeof(map_node);
}

static map_bone* bones_of(void* map) {
    return (map_bone*)((uint8_t*)map + sizeof(map_header));
}

static map_node* nodes_of(void* map, uint32_t bones) {
    return (map_node*)((uint8_t*)map + sizeof(map_header) + (size_t)bones * sizeof(map_bone));
}

/* ---------------------------------------------------------------- binary64 transforms */

static void dxf_identity(dxf* x) {
    x->r = mcd_dq_identity();
    x->t[0] = x->t[1] = x->t[2] = 0.0;
    x->s[0] = x->s[1] = x->s[2] = 1.0;
}

/* world = parent ∘ local, as mcd_compose composes. */
static void dxf_compose(const dxf* p, const dxf* local, dxf* world) {
    double v[3], t[3];
    uint32_t k;
    for (k = 0; k < 3; ++k) v[k] = p->s[k] * local->t[k];
    mcd_dq_rotate(p->r, v, t);
    for (k = 0; k < 3; ++k) {
        world->t[k] = p->t[k] + t[k];
        world->s[k] = p->s[k] * local->s[k];
    }
    world->r = mcd_dq_mul(p->r, local->r);
}

/* v in the frame of `p`: p.s^-1 (p.r^-1 (v - p.t)) for a point, without p.t for a direction. */
static void dxf_into(const dxf* p, const double v[3], int point, double out[3]) {
    double d[3];
    uint32_t k;
    for (k = 0; k < 3; ++k) d[k] = point ? v[k] - p->t[k] : v[k];
    mcd_dq_rotate(mcd_dq_conj(p->r), d, out);
    for (k = 0; k < 3; ++k) out[k] /= p->s[k];
}

static double dq_norm(mcd_dquat q) {
    return sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
}

static mcd_dquat dq_scale(mcd_dquat q, double f) {
    q.x *= f;
    q.y *= f;
    q.z *= f;
    q.w *= f;
    return q;
}

/* Exactly the identity when within rounding of it, so equal rest poses cost no bit. */
static mcd_dquat dq_snap(mcd_dquat q) {
    if (q.w < 0.0) q = dq_scale(q, -1.0);
    if (fabs(q.x) < 1e-12 && fabs(q.y) < 1e-12 && fabs(q.z) < 1e-12 && fabs(q.w - 1.0) < 1e-12) return mcd_dq_identity();
    return q;
}

/* The shortest rotation turning direction u onto direction v (both non-zero). */
static mcd_dquat dq_arc(const double u[3], const double v[3]) {
    double nu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    double nv = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    double a[3], b[3], d;
    mcd_dquat q;
    uint32_t k;
    for (k = 0; k < 3; ++k) {
        a[k] = u[k] / nu;
        b[k] = v[k] / nv;
    }
    d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    if (d < -1.0 + 1e-12) { /* opposite: half a turn about any axis across u */
        double e[3] = {0.0, 0.0, 0.0}, c[3], n;
        e[mcd_least_axis(a)] = 1.0;
        c[0] = a[1] * e[2] - a[2] * e[1];
        c[1] = a[2] * e[0] - a[0] * e[2];
        c[2] = a[0] * e[1] - a[1] * e[0];
        n = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        q.x = c[0] / n;
        q.y = c[1] / n;
        q.z = c[2] / n;
        q.w = 0.0;
        return q;
    }
    q.x = a[1] * b[2] - a[2] * b[1];
    q.y = a[2] * b[0] - a[0] * b[2];
    q.z = a[0] * b[1] - a[1] * b[0];
    q.w = 1.0 + d;
    return dq_scale(q, 1.0 / dq_norm(q));
}

/* ---------------------------------------------------------------- input checks */

static int bounded(double v) {
    return v == v && v <= MAX_ABS && v >= -MAX_ABS;
}

/* A transform the caller describes: finite, bounded, unit rotation, usable scale. Writes it
 * in binary64 with the rotation normalised. */
static int read_rest(const mcd_transform* t, dxf* out) {
    uint32_t k;
    double n;
    for (k = 0; k < 4; ++k)
        if (!bounded(t->rotation[k])) return 0;
    for (k = 0; k < 3; ++k)
        if (!bounded(t->translation[k]) || !bounded(t->scale[k]) || fabs(t->scale[k]) < MIN_SCALE) return 0;
    out->r.x = t->rotation[0];
    out->r.y = t->rotation[1];
    out->r.z = t->rotation[2];
    out->r.w = t->rotation[3];
    n = dq_norm(out->r);
    if (fabs(n - 1.0) > UNIT_TOLERANCE) return 0;
    out->r = dq_scale(out->r, 1.0 / n);
    for (k = 0; k < 3; ++k) {
        out->t[k] = t->translation[k];
        out->s[k] = t->scale[k];
    }
    return 1;
}

/* Length of a caller's name (0 when NULL, empty, longer than the format allows or not valid
 * UTF-8 without control characters: the same rule as node names). */
static uint32_t name_length(const char* s) {
    uint32_t n = 0;
    if (!s) return 0;
    while (n <= MCD_MAX_NAME_BYTES && s[n] != 0) ++n;
    if (n == 0 || n > MCD_MAX_NAME_BYTES) return 0;
    return mcd_valid_name((const uint8_t*)s, n + 1u, 0, 0) ? n : 0;
}

/* The name with its namespace (up to the last ':' or '|'), ASCII case and '_' '-' '.' ' '
 * dropped, into out (at most 255 bytes); returns its length. */
static uint32_t loose_name(const char* s, char out[256]) {
    const char* start = s;
    const char* p;
    uint32_t n = 0;
    for (p = s; *p; ++p)
        if (*p == ':' || *p == '|') start = p + 1;
    for (p = start; *p && n < 255u; ++p) {
        char c = *p;
        if (c == '_' || c == '-' || c == '.' || c == ' ') continue;
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        out[n++] = c;
    }
    out[n] = 0;
    return n;
}

/* ---------------------------------------------------------------- public API */

void mcd_retarget_config_default(mcd_retarget_config* out) {
    if (!out) return;
    memset(out, 0, sizeof *out);
    out->flags = MCD_RETARGET_ROOT_MOTION | MCD_RETARGET_MATCH_DIRECTIONS;
    out->up_axis = 1;
    out->unit_scale = 1.0f;
    out->space_rotation[3] = 1.0f;
}

static const uint8_t* skeleton_section(const mcd_asset* asset, uint32_t skeleton) {
    uint32_t off;
    if (skeleton >= asset->skeleton_count) return NULL;
    off = mcd_skeleton_offset(asset, skeleton);
    return off ? asset->data + off : NULL;
}

mcd_result mcd_retarget_size(const mcd_asset* asset, uint32_t skeleton, uint32_t bone_count, size_t* out_size) {
    const uint8_t* skel;
    if (!asset || !asset->data || !out_size) return MCD_ERROR_INVALID_ARGUMENT;
    *out_size = 0;
    if (bone_count == 0 || bone_count > MAX_BONES) return MCD_ERROR_INVALID_ARGUMENT;
    skel = skeleton_section(asset, skeleton);
    if (!skel) return MCD_ERROR_OUT_OF_RANGE;
    *out_size = map_bytes(bone_count, mcd_skel_nodes(skel));
    return MCD_OK;
}

static mcd_result fail(mcd_retarget_issue* issue, uint32_t where, uint32_t index, mcd_result r) {
    if (issue) {
        issue->where = where;
        issue->index = index;
    }
    return r;
}

/* Index of the node of this exact name, or -1. */
static int32_t node_named(const uint8_t* skel, const char* name) {
    uint32_t n = mcd_skel_nodes(skel), i;
    const char* strings = (const char*)skel + mcd_rd_u32(skel + 12);
    for (i = 0; i < n; ++i)
        if (strcmp(strings + mcd_rd_u32(mcd_skel_record(skel, i) + 4), name) == 0) return (int32_t)i;
    return -1;
}

/* The node a bone is matched to by name (exact, then loose and unique), or -1. */
static int32_t match_by_name(const uint8_t* skel, const char* bone) {
    uint32_t n = mcd_skel_nodes(skel), i;
    const char* strings = (const char*)skel + mcd_rd_u32(skel + 12);
    char want[256], have[256];
    int32_t found = -1;
    for (i = 0; i < n; ++i) {
        if (mcd_skel_kind(skel, i) == MCD_NODE_VIRTUAL) continue;
        if (strcmp(strings + mcd_rd_u32(mcd_skel_record(skel, i) + 4), bone) == 0) return (int32_t)i;
    }
    if (loose_name(bone, want) == 0) return -1;
    for (i = 0; i < n; ++i) {
        if (mcd_skel_kind(skel, i) == MCD_NODE_VIRTUAL) continue;
        loose_name(strings + mcd_rd_u32(mcd_skel_record(skel, i) + 4), have);
        if (strcmp(want, have) == 0) {
            if (found >= 0) return -1; /* ambiguous: leave it to a pair */
            found = (int32_t)i;
        }
    }
    return found;
}

/* Is node `d` strictly below node `a`? */
static int node_below(const uint8_t* skel, int32_t d, int32_t a) {
    int32_t p = mcd_skel_parent(skel, (uint32_t)d);
    while (p >= 0) {
        if (p == a) return 1;
        p = mcd_skel_parent(skel, (uint32_t)p);
    }
    return 0;
}

static void node_rest(const uint8_t* skel, uint32_t node, dxf* out) {
    mcd_transform t;
    uint32_t k;
    mcd_skel_rest(skel, node, &t);
    out->r.x = t.rotation[0];
    out->r.y = t.rotation[1];
    out->r.z = t.rotation[2];
    out->r.w = t.rotation[3];
    out->r = dq_scale(out->r, 1.0 / dq_norm(out->r));
    for (k = 0; k < 3; ++k) {
        out->t[k] = t.translation[k];
        out->s[k] = t.scale[k];
    }
}

mcd_result mcd_retarget_init(const mcd_asset* asset, uint32_t skeleton, const mcd_rig_bone* bones, uint32_t bone_count,
                             const mcd_retarget_pair* pairs, uint32_t pair_count, const mcd_retarget_config* config,
                             void* map, size_t map_size, mcd_retarget_issue* out_issue) {
    const uint32_t known_flags = MCD_RETARGET_ROOT_MOTION | MCD_RETARGET_MATCH_DIRECTIONS;
    const uint8_t* skel;
    map_header* h = (map_header*)map;
    map_bone* mb;
    map_node* mn;
    dxf space_check;
    mcd_transform space;
    uint32_t nodes, i, j, k;
    size_t need;
    /* The rests in world space, bones then nodes, are built in the map's own bone and node
     * records before those are filled: no memory beyond the map is needed. */
    fail(out_issue, MCD_RETARGET_ISSUE_NONE, 0, MCD_OK);
    if (!asset || !asset->data || !bones || !config || !map || (pair_count && !pairs))
        return fail(out_issue, MCD_RETARGET_ISSUE_CONFIG, 0, MCD_ERROR_INVALID_ARGUMENT);
    if (((uintptr_t)map & 7u) != 0) return fail(out_issue, MCD_RETARGET_ISSUE_CONFIG, 0, MCD_ERROR_INVALID_ARGUMENT);
    if (bone_count == 0 || bone_count > MAX_BONES) return fail(out_issue, MCD_RETARGET_ISSUE_CONFIG, 0, MCD_ERROR_INVALID_ARGUMENT);
    skel = skeleton_section(asset, skeleton);
    if (!skel) return fail(out_issue, MCD_RETARGET_ISSUE_CONFIG, 0, MCD_ERROR_OUT_OF_RANGE);
    nodes = mcd_skel_nodes(skel);
    need = map_bytes(bone_count, nodes);
    if (map_size < need) return fail(out_issue, MCD_RETARGET_ISSUE_CONFIG, 0, MCD_ERROR_BUFFER_TOO_SMALL);
    /* config */
    if ((config->flags & ~known_flags) != 0 || config->up_axis > 2u || !bounded(config->unit_scale) ||
        !(config->unit_scale > 0.0f))
        return fail(out_issue, MCD_RETARGET_ISSUE_CONFIG, 0, MCD_ERROR_INVALID_ARGUMENT);
    mcd_transform_identity(&space);
    memcpy(space.rotation, config->space_rotation, sizeof space.rotation);
    if (!read_rest(&space, &space_check)) return fail(out_issue, MCD_RETARGET_ISSUE_CONFIG, 0, MCD_ERROR_INVALID_ARGUMENT);

    memset(map, 0, need);
    h->magic = 0; /* set last: a map that failed half-way is not a map */
    h->bones = bone_count;
    h->nodes = nodes;
    h->flags = config->flags;
    h->up_axis = config->up_axis;
    h->unit_scale = config->unit_scale;
    h->space = dq_snap(space_check.r);
    h->work_size = (uint32_t)((nodes + bone_count) * sizeof(dxf));
    mb = bones_of(map);
    mn = nodes_of(map, bone_count);

    /* bones: names, parents, rests */
    for (j = 0; j < bone_count; ++j) {
        dxf rest;
        if (!name_length(bones[j].name)) return fail(out_issue, MCD_RETARGET_ISSUE_BONE, j, MCD_ERROR_INVALID_ARGUMENT);
        for (i = 0; i < j; ++i)
            if (strcmp(bones[i].name, bones[j].name) == 0)
                return fail(out_issue, MCD_RETARGET_ISSUE_BONE, j, MCD_ERROR_INVALID_ARGUMENT);
        if (bones[j].parent < -1 || bones[j].parent >= (int32_t)j || (bones[j].flags & ~MCD_RIG_BONE_KEEP_TRANSLATION))
            return fail(out_issue, MCD_RETARGET_ISSUE_BONE, j, MCD_ERROR_INVALID_ARGUMENT);
        if (!read_rest(&bones[j].rest, &rest)) return fail(out_issue, MCD_RETARGET_ISSUE_BONE, j, MCD_ERROR_INVALID_ARGUMENT);
        mb[j].node = -2; /* not decided yet */
        mb[j].parent = bones[j].parent;
        mb[j].mode = (bones[j].flags & MCD_RIG_BONE_KEEP_TRANSLATION) ? BONE_KEEP_TRANSLATION : 0u;
        mb[j].rest_r = rest.r;
        for (k = 0; k < 3; ++k) {
            mb[j].rest_t[k] = rest.t[k];
            mb[j].rest_s[k] = rest.s[k];
        }
    }
    /* pairs */
    for (i = 0; i < pair_count; ++i) {
        int32_t bone = -1, node = -1;
        if (!name_length(pairs[i].bone) || (pairs[i].node && !name_length(pairs[i].node)))
            return fail(out_issue, MCD_RETARGET_ISSUE_PAIR, i, MCD_ERROR_INVALID_ARGUMENT);
        for (j = 0; j < bone_count && bone < 0; ++j)
            if (strcmp(bones[j].name, pairs[i].bone) == 0) bone = (int32_t)j;
        if (bone < 0) return fail(out_issue, MCD_RETARGET_ISSUE_PAIR, i, MCD_ERROR_NOT_FOUND);
        if (mb[bone].node != -2) return fail(out_issue, MCD_RETARGET_ISSUE_PAIR, i, MCD_ERROR_INVALID_ARGUMENT);
        if (pairs[i].node) {
            node = node_named(skel, pairs[i].node);
            if (node < 0) return fail(out_issue, MCD_RETARGET_ISSUE_PAIR, i, MCD_ERROR_NOT_FOUND);
        }
        mb[bone].node = node;
    }
    for (j = 0; j < bone_count; ++j)
        if (mb[j].node == -2) mb[j].node = match_by_name(skel, bones[j].name);

    /* nodes: parents, rests */
    for (i = 0; i < nodes; ++i) {
        dxf rest;
        node_rest(skel, i, &rest);
        mn[i].parent = mcd_skel_parent(skel, i);
        for (k = 0; k < 3; ++k) {
            mn[i].rest_t[k] = rest.t[k];
            mn[i].inv_rest_s[k] = fabs(rest.s[k]) >= MIN_SCALE ? 1.0 / rest.s[k] : 1.0;
        }
    }

    /* World rests, then the constant rotations. The rig's and the skeleton's world rests are
     * needed together; they are recomputed per bone from the records (parents first), which is
     * quadratic only in the depth of the hierarchies. */
    for (j = 0; j < bone_count; ++j) {
        int32_t a;
        dxf wb, wn;
        mcd_dquat align = mcd_dq_identity();
        uint32_t children = 0, child = 0;
        mb[j].mode |= mb[j].node >= 0 ? BONE_MATCHED : 0u;
        if (mb[j].node >= 0) h->matched++;
        /* motion root: matched, no matched ancestor */
        if (mb[j].node >= 0) {
            int root = 1;
            for (a = mb[j].parent; a >= 0; a = mb[a].parent)
                if (mb[a].node >= 0) root = 0;
            if (root) mb[j].mode |= BONE_MOTION_ROOT;
        }
        /* the bone's world rest (position for root motion off) */
        {
            int32_t chain[MAX_BONES];
            uint32_t depth = 0;
            dxf local;
            for (a = (int32_t)j; a >= 0; a = mb[a].parent) chain[depth++] = a;
            dxf_identity(&wb);
            while (depth) {
                const map_bone* b = &mb[chain[--depth]];
                local.r = b->rest_r;
                for (k = 0; k < 3; ++k) {
                    local.t[k] = b->rest_t[k];
                    local.s[k] = b->rest_s[k];
                }
                dxf_compose(&wb, &local, &wb);
            }
            for (k = 0; k < 3; ++k) mb[j].home[k] = wb.t[k];
        }
        if (mb[j].node < 0) continue;
        /* the node's world rest */
        {
            int32_t chain[MCD_MAX_NODES];
            uint32_t depth = 0;
            dxf local;
            for (a = mb[j].node; a >= 0; a = mcd_skel_parent(skel, (uint32_t)a)) chain[depth++] = a;
            dxf_identity(&wn);
            while (depth) {
                node_rest(skel, (uint32_t)chain[--depth], &local);
                dxf_compose(&wn, &local, &wn);
            }
        }
        /* the direction child: the only matched child bone, if its node is below this bone's */
        for (i = j + 1; i < bone_count; ++i)
            if (mb[i].parent == (int32_t)j && mb[i].node >= 0) {
                children++;
                child = i;
            }
        if ((config->flags & MCD_RETARGET_MATCH_DIRECTIONS) && children == 1) {
            int32_t cn = mb[child].node;
            if (node_below(skel, cn, mb[j].node)) {
                /* rest directions: the child's rest position seen from the bone, in world */
                double bone_dir[3], node_dir[3], node_world[3], len_b, len_n;
                dxf cb, cw;
                dxf local;
                int32_t chain[MCD_MAX_NODES];
                uint32_t depth = 0;
                local.r = mb[child].rest_r;
                for (k = 0; k < 3; ++k) {
                    local.t[k] = mb[child].rest_t[k];
                    local.s[k] = mb[child].rest_s[k];
                }
                dxf_compose(&wb, &local, &cb);
                for (a = cn; a >= 0; a = mcd_skel_parent(skel, (uint32_t)a)) chain[depth++] = a;
                dxf_identity(&cw);
                while (depth) {
                    node_rest(skel, (uint32_t)chain[--depth], &local);
                    dxf_compose(&cw, &local, &cw);
                }
                for (k = 0; k < 3; ++k) {
                    bone_dir[k] = cb.t[k] - wb.t[k];
                    node_world[k] = cw.t[k] - wn.t[k];
                }
                mcd_dq_rotate(h->space, node_world, node_dir);
                len_b = sqrt(bone_dir[0] * bone_dir[0] + bone_dir[1] * bone_dir[1] + bone_dir[2] * bone_dir[2]);
                len_n = sqrt(node_dir[0] * node_dir[0] + node_dir[1] * node_dir[1] + node_dir[2] * node_dir[2]);
                if (len_b > 1e-9 * (1.0 + fabs(wb.t[0]) + fabs(wb.t[1]) + fabs(wb.t[2])) &&
                    len_n > 1e-9 * (1.0 + fabs(wn.t[0]) + fabs(wn.t[1]) + fabs(wn.t[2])))
                    align = dq_arc(bone_dir, node_dir);
            }
        }
        /* k = world_rest(node)^-1 S^-1 A world_rest(bone) */
        mb[j].k = dq_snap(mcd_dq_mul(mcd_dq_conj(wn.r), mcd_dq_mul(mcd_dq_conj(h->space), mcd_dq_mul(align, wb.r))));
    }
    for (j = 0; j < bone_count; ++j)
        if (mb[j].node < 0) mb[j].node = -1;
    h->magic = MAP_MAGIC;
    return MCD_OK;
}

static const map_header* as_map(const void* map) {
    const map_header* h = (const map_header*)map;
    if (!map || ((uintptr_t)map & 7u) != 0 || h->magic != MAP_MAGIC) return NULL;
    return h;
}

mcd_result mcd_retarget_get_info(const void* map, mcd_retarget_info* out) {
    const map_header* h = as_map(map);
    if (!h || !out) return MCD_ERROR_INVALID_ARGUMENT;
    out->bone_count = h->bones;
    out->node_count = h->nodes;
    out->matched = h->matched;
    out->work_size = h->work_size;
    return MCD_OK;
}

mcd_result mcd_retarget_get_node(const void* map, uint32_t bone, int32_t* out_node) {
    const map_header* h = as_map(map);
    if (!h || !out_node) return MCD_ERROR_INVALID_ARGUMENT;
    if (bone >= h->bones) return MCD_ERROR_OUT_OF_RANGE;
    *out_node = bones_of((void*)(uintptr_t)map)[bone].node;
    return MCD_OK;
}

static void to_float(const dxf* x, mcd_transform* out) {
    double n = dq_norm(x->r);
    uint32_t k;
    out->rotation[0] = (float)(x->r.x / n);
    out->rotation[1] = (float)(x->r.y / n);
    out->rotation[2] = (float)(x->r.z / n);
    out->rotation[3] = (float)(x->r.w / n);
    for (k = 0; k < 3; ++k) {
        out->translation[k] = (float)x->t[k];
        out->scale[k] = (float)x->s[k];
    }
}

mcd_result mcd_retarget_pose(const void* map, const mcd_transform* pose, uint32_t node_count, mcd_transform* out,
                             uint32_t out_capacity, void* work, size_t work_size) {
    const map_header* h = as_map(map);
    const map_bone* mb;
    const map_node* mn;
    dxf* src;
    dxf* dst;
    uint32_t i, j, k;
    if (!h || !pose || !out || !work || node_count != h->nodes || ((uintptr_t)work & 7u) != 0)
        return MCD_ERROR_INVALID_ARGUMENT;
    if (out_capacity < h->bones || work_size < h->work_size) return MCD_ERROR_BUFFER_TOO_SMALL;
    mb = bones_of((void*)(uintptr_t)map);
    mn = nodes_of((void*)(uintptr_t)map, h->bones);
    src = (dxf*)work;
    dst = src + h->nodes;

    /* the asset's pose in model space */
    for (i = 0; i < h->nodes; ++i) {
        const mcd_transform* p = &pose[i];
        dxf local;
        double n;
        for (k = 0; k < 4; ++k)
            if (!mcd_finite(p->rotation[k])) return MCD_ERROR_INVALID_ARGUMENT;
        for (k = 0; k < 3; ++k)
            if (!mcd_finite(p->translation[k]) || !mcd_finite(p->scale[k])) return MCD_ERROR_INVALID_ARGUMENT;
        local.r.x = p->rotation[0];
        local.r.y = p->rotation[1];
        local.r.z = p->rotation[2];
        local.r.w = p->rotation[3];
        n = dq_norm(local.r);
        if (!(n > 1e-12)) return MCD_ERROR_INVALID_ARGUMENT;
        if (n != 1.0) local.r = dq_scale(local.r, 1.0 / n);
        for (k = 0; k < 3; ++k) {
            local.t[k] = p->translation[k];
            local.s[k] = p->scale[k];
        }
        if (mn[i].parent >= 0) dxf_compose(&src[mn[i].parent], &local, &src[i]);
        else src[i] = local;
    }

    /* the rig, parents first */
    for (j = 0; j < h->bones; ++j) {
        const map_bone* b = &mb[j];
        dxf parent, local;
        if (b->parent >= 0) parent = dst[b->parent];
        else dxf_identity(&parent);
        local.r = b->rest_r;
        for (k = 0; k < 3; ++k) {
            local.t[k] = b->rest_t[k];
            local.s[k] = b->rest_s[k];
        }
        if (b->mode & BONE_MATCHED) {
            const dxf* w = &src[b->node];
            const mcd_transform* p = &pose[b->node];
            const map_node* nd = &mn[b->node];
            mcd_dquat world = mcd_dq_mul(h->space, mcd_dq_mul(w->r, b->k));
            local.r = mcd_dq_mul(mcd_dq_conj(parent.r), world);
            for (k = 0; k < 3; ++k) local.s[k] = b->rest_s[k] * (double)p->scale[k] * nd->inv_rest_s[k];
            if (b->mode & BONE_KEEP_TRANSLATION) {
                /* rest translation, set above */
            } else if (b->mode & BONE_MOTION_ROOT) {
                double at[3], pos[3];
                mcd_dq_rotate(h->space, w->t, at);
                for (k = 0; k < 3; ++k) pos[k] = h->unit_scale * at[k];
                if (!(h->flags & MCD_RETARGET_ROOT_MOTION))
                    for (k = 0; k < 3; ++k)
                        if (k != h->up_axis) pos[k] = b->home[k];
                dxf_into(&parent, pos, 1, local.t);
            } else {
                /* the node's displacement from its rest, turned from its parent's frame into
                 * the bone's parent's */
                double d[3], wd[3], rig[3], moved[3];
                for (k = 0; k < 3; ++k) d[k] = (double)p->translation[k] - nd->rest_t[k];
                if (d[0] != 0.0 || d[1] != 0.0 || d[2] != 0.0) {
                    if (nd->parent >= 0) {
                        const dxf* wp = &src[nd->parent];
                        double v[3];
                        for (k = 0; k < 3; ++k) v[k] = wp->s[k] * d[k];
                        mcd_dq_rotate(wp->r, v, wd);
                    } else {
                        for (k = 0; k < 3; ++k) wd[k] = d[k];
                    }
                    mcd_dq_rotate(h->space, wd, rig);
                    for (k = 0; k < 3; ++k) rig[k] *= h->unit_scale;
                    dxf_into(&parent, rig, 0, moved);
                    for (k = 0; k < 3; ++k) local.t[k] += moved[k];
                }
            }
        }
        dxf_compose(&parent, &local, &dst[j]);
        to_float(&local, &out[j]);
    }
    return MCD_OK;
}
