/*
 * Godot 3 binding of the mocodec runtime: a GDNative library with one NativeScript tool class,
 * MocodecAnimation (a Resource: its `data` property, the .mcd bytes, is saved with it, so the
 * import plugin of addons/mocodec turns a .mcd into a .res that exports carry). It holds one
 * opened asset, samples it into a pose buffer it owns, and poses a Skeleton through the
 * runtime's retargeting (mcd_retarget_*: the Skeleton's own bone names, rests and proportions).
 * Every buffer is allocated when the asset is loaded or a skeleton bound, never while sampling.
 * Results are the runtime's codes (0 = OK); a failure is also printed through Godot's error
 * channel, GDScript having no exceptions.
 *
 * Built against the godot_headers of the crates.io crate gdnative-sys 0.11.3; only the core
 * 1.0 and NativeScript 1.0 tables are used, which every Godot 3.x provides.
 */
#include <stdint.h>
#include <string.h>

#include <gdnative_api_struct.gen.h>

#include "mcd_engine_asset.h"
#include "mocodec.h"

/* The library is built with hidden visibility (only the entry points are public); GDN_EXPORT
 * marks them for Windows only. */
#if defined(__GNUC__) && !defined(_WIN32)
#define ENTRY GDN_EXPORT __attribute__((visibility("default")))
#else
#define ENTRY GDN_EXPORT
#endif

static const godot_gdnative_core_api_struct *core;
static const godot_gdnative_ext_nativescript_api_struct *ns;

/* Skeleton methods, resolved once at init; ptrcall passes ints as int64 in Godot 3. */
static godot_method_bind *skel_get_bone_count, *skel_get_bone_name, *skel_get_bone_parent, *skel_get_bone_rest,
    *skel_set_bone_pose;

typedef struct {
    mcd_engine_asset a;
    int64_t result; /* of the last load */
    godot_pool_byte_array data; /* the `data` property as set, returned by its getter */
    /* the bound skeleton: the retargeting onto its bones, and their inverse rests (Godot 3
     * composes a bone as parent * rest * pose, so the pose is rest^-1 * the rig's local) */
    godot_object *skeleton;
    mcd_engine_rig rig;
    godot_transform *inverse_rest;
} instance;

static void report(const char *what, mcd_result r) {
    core->godot_print_error(mcd_result_string(r), what, __FILE__, __LINE__);
}

/* godot_free complains about NULL, unlike free(). */
static void release(void *p) {
    if (p) core->godot_free(p);
}

static void *engine_alloc(size_t n) {
    return core->godot_alloc((int)n);
}

static void engine_free(void *p) {
    core->godot_free(p);
}

static const mcd_engine_allocator godot_memory = {engine_alloc, engine_free};

static void unbind(instance *self) {
    release(self->inverse_rest);
    self->inverse_rest = NULL;
    self->skeleton = NULL;
    mcd_engine_rig_close(&self->rig, &godot_memory);
}

static void close_asset(instance *self) {
    unbind(self);
    mcd_engine_asset_close(&self->a, &godot_memory);
}

/* ---- variant helpers ---------------------------------------------------------------------- */

static godot_variant v_int(int64_t i) {
    godot_variant v;
    core->godot_variant_new_int(&v, i);
    return v;
}

static godot_variant v_real(double d) {
    godot_variant v;
    core->godot_variant_new_real(&v, d);
    return v;
}

static godot_variant v_utf8(const char *s) {
    godot_variant v;
    godot_string str;
    core->godot_string_new(&str);
    core->godot_string_parse_utf8(&str, s ? s : "");
    core->godot_variant_new_string(&v, &str);
    core->godot_string_destroy(&str);
    return v;
}

static godot_variant v_vector3(const float *xyz) {
    godot_variant v;
    godot_vector3 vec;
    core->godot_vector3_new(&vec, xyz[0], xyz[1], xyz[2]);
    core->godot_variant_new_vector3(&v, &vec);
    return v;
}

static int64_t arg_int(int argc, godot_variant **argv, int i) {
    return i < argc ? core->godot_variant_as_int(argv[i]) : -1;
}

static godot_transform to_transform(const mcd_transform *t) {
    godot_quat q;
    godot_basis b;
    godot_vector3 o;
    godot_transform out;
    core->godot_quat_new(&q, t->rotation[0], t->rotation[1], t->rotation[2], t->rotation[3]);
    core->godot_basis_new_with_euler_quat(&b, &q); /* Basis(Quat) despite the name */
    core->godot_vector3_new(&o, t->translation[0], t->translation[1], t->translation[2]);
    core->godot_transform_new(&out, &b, &o);
    return out;
}

/* ---- asset ---------------------------------------------------------------------------------- */


/* Opens a copy of the bytes and keeps them as the `data` property. */
static mcd_result load(instance *self, const godot_variant *value) {
    godot_pool_byte_array_read_access *read;
    mcd_result r;
    unbind(self);
    core->godot_pool_byte_array_destroy(&self->data);
    self->data = core->godot_variant_as_pool_byte_array(value);
    read = core->godot_pool_byte_array_read(&self->data);
    r = mcd_engine_asset_load(&self->a, core->godot_pool_byte_array_read_access_ptr(read),
                              (size_t)core->godot_pool_byte_array_size(&self->data), &godot_memory);
    core->godot_pool_byte_array_read_access_destroy(read);
    self->result = r;
    return r;
}

/* load_bytes(bytes: PoolByteArray) -> int */
static godot_variant m_load_bytes(godot_object *obj, void *md, void *ud, int argc, godot_variant **argv) {
    mcd_result r;
    (void)obj;
    (void)md;
    if (argc != 1) return v_int(MCD_ERROR_INVALID_ARGUMENT);
    r = load(ud, argv[0]);
    if (r != MCD_OK) report("MocodecAnimation.load_bytes", r);
    return v_int(r);
}

/* The `data` property: what a saved resource stores and a loaded one is opened from. */
static void p_set_data(godot_object *obj, void *md, void *ud, godot_variant *value) {
    mcd_result r;
    (void)obj, (void)md;
    r = load(ud, value);
    if (r != MCD_OK) report("MocodecAnimation.data", r);
}

static godot_variant p_get_data(godot_object *obj, void *md, void *ud) {
    godot_variant v;
    (void)obj, (void)md;
    core->godot_variant_new_pool_byte_array(&v, &((instance *)ud)->data);
    return v;
}

/* get_result() -> int: the runtime's code for the bytes last set (0: a valid asset) */
static godot_variant m_get_result(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md, (void)argc, (void)argv;
    return v_int(((instance *)ud)->result);
}

static godot_variant m_get_version(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md, (void)ud, (void)argc, (void)argv;
    return v_int(mcd_version());
}

static godot_variant m_result_string(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md, (void)ud;
    return v_utf8(mcd_result_string((mcd_result)arg_int(argc, argv, 0)));
}

static godot_variant m_get_clip_count(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    (void)o, (void)md, (void)argc, (void)argv;
    return v_int(self->a.opened ? mcd_clip_count(&self->a.asset) : 0);
}

static godot_variant m_get_skeleton_count(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    (void)o, (void)md, (void)argc, (void)argv;
    return v_int(self->a.opened ? mcd_skeleton_count(&self->a.asset) : 0);
}

/* Clip queries share one lookup; a bad index gives a nil-like default and an error print. */
enum clip_field { CLIP_NAME, CLIP_DURATION, CLIP_FRAMES, CLIP_RATE, CLIP_NODES, CLIP_SKELETON };

static godot_variant clip_query(instance *self, int argc, godot_variant **argv, enum clip_field f) {
    mcd_clip_info info;
    mcd_result r = self->a.opened ? mcd_get_clip_info(&self->a.asset, (uint32_t)arg_int(argc, argv, 0), &info)
                                : MCD_ERROR_INVALID_ARGUMENT;
    if (r != MCD_OK) {
        report("MocodecAnimation clip query", r);
        return f == CLIP_NAME ? v_utf8("") : v_int(-1);
    }
    switch (f) {
    case CLIP_NAME: return v_utf8(info.name);
    case CLIP_DURATION: return v_real(info.duration);
    case CLIP_FRAMES: return v_int(info.frame_count);
    case CLIP_RATE: return v_real(info.frame_rate);
    case CLIP_NODES: return v_int(info.node_count);
    default: return v_int(info.skeleton);
    }
}

#define CLIP_METHOD(fn, field)                                                                      \
    static godot_variant fn(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) { \
        (void)o, (void)md;                                                                          \
        return clip_query(ud, argc, argv, field);                                                   \
    }
CLIP_METHOD(m_get_clip_name, CLIP_NAME)
CLIP_METHOD(m_get_clip_duration, CLIP_DURATION)
CLIP_METHOD(m_get_clip_frame_count, CLIP_FRAMES)
CLIP_METHOD(m_get_clip_frame_rate, CLIP_RATE)
CLIP_METHOD(m_get_clip_node_count, CLIP_NODES)
CLIP_METHOD(m_get_clip_skeleton, CLIP_SKELETON)

/* find_clip(name: String) -> int, -1 when there is none of that name */
static godot_variant m_find_clip(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    godot_string name;
    godot_char_string utf8;
    uint32_t clip = 0;
    mcd_result r;
    (void)o, (void)md;
    if (argc != 1 || !self->a.opened) return v_int(-1);
    name = core->godot_variant_as_string(argv[0]);
    utf8 = core->godot_string_utf8(&name);
    r = mcd_find_clip(&self->a.asset, core->godot_char_string_get_data(&utf8), &clip);
    core->godot_char_string_destroy(&utf8);
    core->godot_string_destroy(&name);
    return v_int(r == MCD_OK ? (int64_t)clip : -1);
}

static godot_variant m_get_node_count(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    mcd_skeleton_info info;
    (void)o, (void)md;
    if (!self->a.opened || mcd_get_skeleton_info(&self->a.asset, (uint32_t)arg_int(argc, argv, 0), &info) != MCD_OK)
        return v_int(-1);
    return v_int(info.node_count);
}

static godot_variant m_get_cm_per_unit(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    mcd_skeleton_info info;
    (void)o, (void)md;
    if (!self->a.opened || mcd_get_skeleton_info(&self->a.asset, (uint32_t)arg_int(argc, argv, 0), &info) != MCD_OK)
        return v_real(0.0);
    return v_real(info.cm_per_unit);
}

enum node_field { NODE_NAME, NODE_PARENT, NODE_KIND, NODE_REST };

static godot_variant node_query(instance *self, int argc, godot_variant **argv, enum node_field f) {
    mcd_node_info info;
    godot_variant v;
    mcd_result r = self->a.opened ? mcd_get_node_info(&self->a.asset, (uint32_t)arg_int(argc, argv, 0),
                                                    (uint32_t)arg_int(argc, argv, 1), &info)
                                : MCD_ERROR_INVALID_ARGUMENT;
    if (r != MCD_OK) {
        report("MocodecAnimation node query", r);
        return f == NODE_NAME ? v_utf8("") : v_int(-2);
    }
    if (f == NODE_NAME) return v_utf8(info.name);
    if (f == NODE_PARENT) return v_int(info.parent);
    if (f == NODE_KIND) return v_int(info.kind);
    {
        mcd_transform t;
        godot_transform x;
        memcpy(t.rotation, info.rest_rotation, sizeof t.rotation);
        memcpy(t.translation, info.rest_translation, sizeof t.translation);
        memcpy(t.scale, info.rest_scale, sizeof t.scale);
        x = to_transform(&t);
        core->godot_variant_new_transform(&v, &x);
    }
    return v;
}

#define NODE_METHOD(fn, field)                                                                      \
    static godot_variant fn(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) { \
        (void)o, (void)md;                                                                          \
        return node_query(ud, argc, argv, field);                                                   \
    }
NODE_METHOD(m_get_node_name, NODE_NAME)
NODE_METHOD(m_get_node_parent, NODE_PARENT)
NODE_METHOD(m_get_node_kind, NODE_KIND)
NODE_METHOD(m_get_node_rest, NODE_REST)

/* ---- sampling ------------------------------------------------------------------------------- */

static mcd_result sample_into_pose(instance *self, int argc, godot_variant **argv, int first) {
    if (!self->a.opened) return MCD_ERROR_INVALID_ARGUMENT;
    if (argc < first + 3) return MCD_ERROR_INVALID_ARGUMENT;
    return mcd_sample(&self->a.asset, (uint32_t)core->godot_variant_as_int(argv[first]),
                      core->godot_variant_as_real(argv[first + 1]),
                      (uint32_t)core->godot_variant_as_int(argv[first + 2]), self->a.pose,
                      self->a.asset.max_nodes, self->a.scratch);
}

/* sample(clip: int, time: float, flags: int) -> int; the pose is read with get_pose_* */
static godot_variant m_sample(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    mcd_result r = sample_into_pose(ud, argc, argv, 0);
    (void)o, (void)md;
    if (r != MCD_OK) report("MocodecAnimation.sample", r);
    return v_int(r);
}

static const mcd_transform *pose_at(instance *self, int argc, godot_variant **argv) {
    static const mcd_transform identity = {{0, 0, 0, 1}, {0, 0, 0}, {1, 1, 1}};
    int64_t i = arg_int(argc, argv, 0);
    return self->a.opened && i >= 0 && i < (int64_t)self->a.asset.max_nodes ? &self->a.pose[i] : &identity;
}

static godot_variant m_get_pose_rotation(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    const float *r = pose_at(ud, argc, argv)->rotation;
    godot_quat q;
    godot_variant v;
    (void)o, (void)md;
    core->godot_quat_new(&q, r[0], r[1], r[2], r[3]);
    core->godot_variant_new_quat(&v, &q);
    return v;
}

static godot_variant m_get_pose_translation(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md;
    return v_vector3(pose_at(ud, argc, argv)->translation);
}

static godot_variant m_get_pose_scale(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md;
    return v_vector3(pose_at(ud, argc, argv)->scale);
}

/* ---- a Skeleton as the rig ------------------------------------------------------------------ */

static mcd_transform from_transform(const godot_transform *x) {
    mcd_transform t;
    godot_basis b = core->godot_transform_get_basis(x), unit;
    godot_vector3 o = core->godot_transform_get_origin(x), s = core->godot_basis_get_scale(&b);
    double m[3][3];
    int row, col;
    unit = core->godot_basis_orthonormalized(&b); /* the rotation of a scaled basis */
    for (row = 0; row < 3; row++) {
        godot_vector3 r = core->godot_basis_get_row(&unit, row);
        for (col = 0; col < 3; col++) m[row][col] = core->godot_vector3_get_axis(&r, (godot_vector3_axis)col);
    }
    mcd_engine_rotation_from_rows(m, t.rotation); /* the core 1.0 API has no Basis -> Quat */
    t.translation[0] = core->godot_vector3_get_axis(&o, GODOT_VECTOR3_AXIS_X);
    t.translation[1] = core->godot_vector3_get_axis(&o, GODOT_VECTOR3_AXIS_Y);
    t.translation[2] = core->godot_vector3_get_axis(&o, GODOT_VECTOR3_AXIS_Z);
    t.scale[0] = core->godot_vector3_get_axis(&s, GODOT_VECTOR3_AXIS_X);
    t.scale[1] = core->godot_vector3_get_axis(&s, GODOT_VECTOR3_AXIS_Y);
    t.scale[2] = core->godot_vector3_get_axis(&s, GODOT_VECTOR3_AXIS_Z);
    return t;
}

/* A transform applied as scale, then rotation, then translation: basis = R * diag(scale). */
static godot_transform to_transform_scaled(const mcd_transform *t) {
    godot_transform x = to_transform(t);
    godot_basis r, sb, rs;
    godot_vector3 o, row[3];
    if (t->scale[0] == 1.0f && t->scale[1] == 1.0f && t->scale[2] == 1.0f) return x;
    r = core->godot_transform_get_basis(&x);
    o = core->godot_transform_get_origin(&x);
    core->godot_vector3_new(&row[0], t->scale[0], 0, 0);
    core->godot_vector3_new(&row[1], 0, t->scale[1], 0);
    core->godot_vector3_new(&row[2], 0, 0, t->scale[2]);
    core->godot_basis_new_with_rows(&sb, &row[0], &row[1], &row[2]);
    rs = core->godot_basis_operator_multiply_vector(&r, &sb); /* Basis * Basis, despite the name */
    core->godot_transform_new(&x, &rs, &o);
    return x;
}

/* The pairs of a Dictionary {bone name: node name or null} as C strings (freed by the caller
 * through `strings`, `count` of them). */
static uint32_t read_pairs(const godot_dictionary *d, mcd_retarget_pair *pairs, uint32_t max, godot_char_string *strings,
                           uint32_t *count) {
    godot_array keys = core->godot_dictionary_keys(d);
    godot_int n = core->godot_array_size(&keys), i;
    uint32_t made = 0;
    *count = 0;
    for (i = 0; i < n && made < max; i++) {
        godot_variant key = core->godot_array_get(&keys, i), value = core->godot_dictionary_get(d, &key);
        godot_string ks = core->godot_variant_as_string(&key);
        strings[*count] = core->godot_string_utf8(&ks);
        pairs[made].bone = core->godot_char_string_get_data(&strings[(*count)++]);
        core->godot_string_destroy(&ks);
        if (core->godot_variant_get_type(&value) == GODOT_VARIANT_TYPE_NIL) {
            pairs[made].node = NULL;
        } else {
            godot_string vs = core->godot_variant_as_string(&value);
            strings[*count] = core->godot_string_utf8(&vs);
            pairs[made].node = core->godot_char_string_get_data(&strings[(*count)++]);
            core->godot_string_destroy(&vs);
        }
        core->godot_variant_destroy(&value);
        core->godot_variant_destroy(&key);
        made++;
    }
    core->godot_array_destroy(&keys);
    return made;
}

#define MAX_PAIRS 256

/* bind_skeleton(skeleton: Skeleton, skeleton_index: int, unit_scale := 1.0, flags := 3,
 *               pairs := {}) -> int: bones driven by a node, or -1. The Skeleton's bones (names,
 * parents, rests) are the rig; unit_scale is rig units per asset unit (metres: cm_per_unit /
 * 100), flags the runtime's MCD_RETARGET_* (1 root motion, 2 match bone directions), pairs
 * {bone: node or null} overrides the name match. */
static godot_variant m_bind_skeleton(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    godot_object *skeleton;
    mcd_retarget_config config;
    mcd_retarget_issue issue;
    mcd_retarget_pair pairs[MAX_PAIRS];
    static godot_char_string strings[2 * MAX_PAIRS];
    godot_char_string *names = NULL;
    mcd_rig_bone *bones = NULL;
    uint32_t pair_count = 0, string_count = 0, i;
    int64_t bone_count = 0;
    mcd_result r;
    (void)o, (void)md;
    unbind(self);
    if (argc < 2 || argc > 5 || !self->a.opened || !(skeleton = core->godot_variant_as_object(argv[0]))) {
        report("MocodecAnimation.bind_skeleton(skeleton, skeleton_index, unit_scale, flags, pairs)", MCD_ERROR_INVALID_ARGUMENT);
        return v_int(-1);
    }
    mcd_retarget_config_default(&config);
    if (argc >= 3) config.unit_scale = (float)core->godot_variant_as_real(argv[2]);
    if (argc >= 4) config.flags = (uint32_t)core->godot_variant_as_int(argv[3]);
    if (argc >= 5) {
        godot_dictionary d = core->godot_variant_as_dictionary(argv[4]);
        pair_count = read_pairs(&d, pairs, MAX_PAIRS, strings, &string_count);
        core->godot_dictionary_destroy(&d);
    }
    core->godot_method_bind_ptrcall(skel_get_bone_count, skeleton, NULL, &bone_count);
    if (bone_count > 0) {
        bones = core->godot_alloc((int)(bone_count * (int64_t)sizeof *bones));
        names = core->godot_alloc((int)(bone_count * (int64_t)sizeof *names));
        self->inverse_rest = core->godot_alloc((int)(bone_count * (int64_t)sizeof(godot_transform)));
    }
    for (i = 0; i < (uint32_t)bone_count; i++) {
        int64_t bone = i, parent = -1;
        const void *args[1];
        godot_string name;
        godot_transform rest;
        args[0] = &bone;
        core->godot_string_new(&name); /* a String result is assigned to, so it must exist */
        core->godot_method_bind_ptrcall(skel_get_bone_name, skeleton, args, &name);
        names[i] = core->godot_string_utf8(&name);
        core->godot_string_destroy(&name);
        core->godot_method_bind_ptrcall(skel_get_bone_parent, skeleton, args, &parent);
        core->godot_method_bind_ptrcall(skel_get_bone_rest, skeleton, args, &rest);
        bones[i].name = core->godot_char_string_get_data(&names[i]);
        bones[i].parent = (int32_t)parent;
        bones[i].flags = 0;
        bones[i].rest = from_transform(&rest);
        self->inverse_rest[i] = core->godot_transform_affine_inverse(&rest);
    }
    r = mcd_engine_rig_build(&self->rig, &self->a, (uint32_t)core->godot_variant_as_int(argv[1]), bones, (uint32_t)bone_count,
                             pairs, pair_count, &config, &godot_memory, &issue);
    if (r != MCD_OK) {
        /* one line: which bone, pair or setting */
        char where[320];
        const char *what = issue.where == MCD_RETARGET_ISSUE_BONE ? "bone" : issue.where == MCD_RETARGET_ISSUE_PAIR ? "pair" : "setting";
        const char *name = issue.where == MCD_RETARGET_ISSUE_BONE && issue.index < bone_count ? bones[issue.index].name
                         : issue.where == MCD_RETARGET_ISSUE_PAIR && issue.index < pair_count && pairs[issue.index].bone ? pairs[issue.index].bone
                         : "";
        size_t k = 0;
        const char *prefix = "MocodecAnimation.bind_skeleton: ";
        while (*prefix && k < sizeof where - 1) where[k++] = *prefix++;
        while (*what && k < sizeof where - 1) where[k++] = *what++;
        if (*name && k < sizeof where - 3) where[k++] = ' ', where[k++] = '\'';
        while (*name && k < sizeof where - 2) where[k++] = *name++;
        if (k > 0 && where[k - 1] != 'g' && k < sizeof where - 1) where[k++] = '\'';
        where[k] = 0;
        report(where, r);
    } else {
        self->skeleton = skeleton;
    }
    for (i = 0; i < (uint32_t)bone_count; i++) core->godot_char_string_destroy(&names[i]);
    for (i = 0; i < string_count; i++) core->godot_char_string_destroy(&strings[i]);
    release(names);
    release(bones);
    if (r != MCD_OK) {
        unbind(self);
        return v_int(-1);
    }
    return v_int(self->rig.info.matched);
}

/* get_bone_node(bone: int) -> int: the asset node driving a bone of the bound skeleton, -1 */
static godot_variant m_get_bone_node(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    int32_t node = -1;
    (void)o, (void)md;
    if (!self->rig.bound || mcd_retarget_get_node(self->rig.map, (uint32_t)arg_int(argc, argv, 0), &node) != MCD_OK)
        return v_int(-1);
    return v_int(node);
}

/* apply(skeleton: Skeleton, clip: int, time: float, flags: int) -> int: samples, retargets onto
 * the bound skeleton and sets its bone poses (MCD_SAMPLE_WORLD is refused). */
static godot_variant m_apply(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    mcd_result r;
    uint32_t i;
    (void)o, (void)md;
    if (argc != 4 || !self->skeleton || core->godot_variant_as_object(argv[0]) != self->skeleton ||
        (core->godot_variant_as_int(argv[3]) & MCD_SAMPLE_WORLD)) {
        report("MocodecAnimation.apply (bind_skeleton first, local flags only)", MCD_ERROR_INVALID_ARGUMENT);
        return v_int(MCD_ERROR_INVALID_ARGUMENT);
    }
    r = mcd_engine_rig_pose(&self->rig, &self->a, (uint32_t)core->godot_variant_as_int(argv[1]),
                            core->godot_variant_as_real(argv[2]), (uint32_t)core->godot_variant_as_int(argv[3]));
    if (r != MCD_OK) {
        report("MocodecAnimation.apply", r);
        return v_int(r);
    }
    for (i = 0; i < self->rig.info.bone_count; i++) {
        godot_transform local, pose;
        int64_t bone = i;
        const void *args[2];
        local = to_transform_scaled(&self->rig.rig_pose[i]);
        pose = core->godot_transform_operator_multiply(&self->inverse_rest[i], &local);
        args[0] = &bone;
        args[1] = &pose;
        core->godot_method_bind_ptrcall(skel_set_bone_pose, self->skeleton, args, NULL);
    }
    return v_int(MCD_OK);
}

/* ---- registration --------------------------------------------------------------------------- */

static void *create(godot_object *obj, void *md) {
    instance *self = core->godot_alloc(sizeof(instance));
    (void)obj, (void)md;
    if (self) {
        memset(self, 0, sizeof *self);
        core->godot_pool_byte_array_new(&self->data);
        self->result = MCD_ERROR_INVALID_ARGUMENT; /* nothing loaded yet */
    }
    return self;
}

static void destroy(godot_object *obj, void *md, void *ud) {
    (void)obj, (void)md;
    close_asset(ud);
    core->godot_pool_byte_array_destroy(&((instance *)ud)->data);
    release(ud);
}

ENTRY void godot_gdnative_init(godot_gdnative_init_options *options) {
    unsigned i;
    core = options->api_struct;
    for (i = 0; i < core->num_extensions; i++)
        if (core->extensions[i]->type == GDNATIVE_EXT_NATIVESCRIPT)
            ns = (const godot_gdnative_ext_nativescript_api_struct *)core->extensions[i];
    skel_get_bone_count = core->godot_method_bind_get_method("Skeleton", "get_bone_count");
    skel_get_bone_name = core->godot_method_bind_get_method("Skeleton", "get_bone_name");
    skel_get_bone_parent = core->godot_method_bind_get_method("Skeleton", "get_bone_parent");
    skel_get_bone_rest = core->godot_method_bind_get_method("Skeleton", "get_bone_rest");
    skel_set_bone_pose = core->godot_method_bind_get_method("Skeleton", "set_bone_pose");
}

ENTRY void godot_gdnative_terminate(godot_gdnative_terminate_options *options) {
    (void)options;
    core = NULL;
    ns = NULL;
}

typedef godot_variant (*method_fn)(godot_object *, void *, void *, int, godot_variant **);

ENTRY void godot_nativescript_init(void *handle) {
    static const struct {
        const char *name;
        method_fn fn;
    } methods[] = {
        {"load_bytes", m_load_bytes},
        {"get_result", m_get_result},
        {"get_version", m_get_version},
        {"result_string", m_result_string},
        {"get_clip_count", m_get_clip_count},
        {"get_skeleton_count", m_get_skeleton_count},
        {"get_clip_name", m_get_clip_name},
        {"get_clip_duration", m_get_clip_duration},
        {"get_clip_frame_count", m_get_clip_frame_count},
        {"get_clip_frame_rate", m_get_clip_frame_rate},
        {"get_clip_node_count", m_get_clip_node_count},
        {"get_clip_skeleton", m_get_clip_skeleton},
        {"find_clip", m_find_clip},
        {"get_node_count", m_get_node_count},
        {"get_cm_per_unit", m_get_cm_per_unit},
        {"get_node_name", m_get_node_name},
        {"get_node_parent", m_get_node_parent},
        {"get_node_kind", m_get_node_kind},
        {"get_node_rest", m_get_node_rest},
        {"sample", m_sample},
        {"get_pose_rotation", m_get_pose_rotation},
        {"get_pose_translation", m_get_pose_translation},
        {"get_pose_scale", m_get_pose_scale},
        {"bind_skeleton", m_bind_skeleton},
        {"get_bone_node", m_get_bone_node},
        {"apply", m_apply},
    };
    godot_instance_create_func c = {NULL, NULL, NULL};
    godot_instance_destroy_func d = {NULL, NULL, NULL};
    size_t i;
    c.create_func = create;
    d.destroy_func = destroy;
    godot_property_attributes data_attr;
    godot_property_set_func set = {NULL, NULL, NULL};
    godot_property_get_func get = {NULL, NULL, NULL};
    /* a tool class: the editor's import plugin (addons/mocodec) runs it */
    ns->godot_nativescript_register_tool_class(handle, "MocodecAnimation", "Resource", c, d);
    memset(&data_attr, 0, sizeof data_attr);
    data_attr.type = GODOT_VARIANT_TYPE_POOL_BYTE_ARRAY;
    data_attr.hint = GODOT_PROPERTY_HINT_NONE;
    core->godot_string_new(&data_attr.hint_string);
    data_attr.usage = GODOT_PROPERTY_USAGE_STORAGE; /* saved, not shown as a byte list */
    core->godot_variant_new_nil(&data_attr.default_value);
    set.set_func = p_set_data;
    get.get_func = p_get_data;
    ns->godot_nativescript_register_property(handle, "MocodecAnimation", "data", &data_attr, set, get);
    core->godot_string_destroy(&data_attr.hint_string);
    core->godot_variant_destroy(&data_attr.default_value);
    for (i = 0; i < sizeof methods / sizeof methods[0]; i++) {
        godot_instance_method m = {NULL, NULL, NULL};
        godot_method_attributes attr = {GODOT_METHOD_RPC_MODE_DISABLED};
        m.method = methods[i].fn;
        ns->godot_nativescript_register_method(handle, "MocodecAnimation", methods[i].name, attr, m);
    }
}
