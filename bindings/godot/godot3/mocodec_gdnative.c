/*
 * Godot 3 binding of the mocodec runtime: a GDNative library with one NativeScript class,
 * MocodecAnimation (a Reference). It holds one opened asset, samples it into a pose buffer it
 * owns, and writes poses onto a Skeleton's bones. Every buffer is allocated when the asset is
 * loaded or a skeleton bound, never while sampling. Results are the runtime's codes (0 = OK);
 * a failure is also printed through Godot's error channel, GDScript having no exceptions.
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
static godot_method_bind *skel_find_bone, *skel_get_bone_rest, *skel_set_bone_pose;

typedef struct {
    mcd_engine_asset a;
    /* the bound skeleton: node -> bone index (-1: no bone of that name), inverse bone rests */
    godot_object *skeleton;
    uint32_t skeleton_index;
    uint32_t bound_nodes;
    int64_t *bone_of_node;
    godot_transform *inverse_rest;
} instance;

static void report(const char *what, mcd_result r) {
    core->godot_print_error(mcd_result_string(r), what, __FILE__, __LINE__);
}

/* godot_free complains about NULL, unlike free(). */
static void release(void *p) {
    if (p) core->godot_free(p);
}

static void unbind(instance *self) {
    release(self->bone_of_node);
    release(self->inverse_rest);
    self->bone_of_node = NULL;
    self->inverse_rest = NULL;
    self->skeleton = NULL;
    self->bound_nodes = 0;
}

static void *engine_alloc(size_t n) {
    return core->godot_alloc((int)n);
}

static void engine_free(void *p) {
    core->godot_free(p);
}

static const mcd_engine_allocator godot_memory = {engine_alloc, engine_free};

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


/* load_bytes(bytes: PoolByteArray) -> int */
static godot_variant m_load_bytes(godot_object *obj, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    godot_pool_byte_array bytes;
    godot_pool_byte_array_read_access *read;
    mcd_result r;
    (void)obj;
    (void)md;
    if (argc != 1) return v_int(MCD_ERROR_INVALID_ARGUMENT);
    bytes = core->godot_variant_as_pool_byte_array(argv[0]);
    read = core->godot_pool_byte_array_read(&bytes);
    unbind(self);
    r = mcd_engine_asset_load(&self->a, core->godot_pool_byte_array_read_access_ptr(read),
                              (size_t)core->godot_pool_byte_array_size(&bytes), &godot_memory);
    core->godot_pool_byte_array_read_access_destroy(read);
    core->godot_pool_byte_array_destroy(&bytes);
    if (r != MCD_OK) report("MocodecAnimation.load_bytes", r);
    return v_int(r);
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

enum node_field { NODE_NAME, NODE_PARENT, NODE_REST };

static godot_variant node_query(instance *self, int argc, godot_variant **argv, enum node_field f) {
    mcd_node_info info;
    mcd_result r = self->a.opened ? mcd_get_node_info(&self->a.asset, (uint32_t)arg_int(argc, argv, 0),
                                                    (uint32_t)arg_int(argc, argv, 1), &info)
                                : MCD_ERROR_INVALID_ARGUMENT;
    if (r != MCD_OK) {
        report("MocodecAnimation node query", r);
        return f == NODE_NAME ? v_utf8("") : v_int(-2);
    }
    if (f == NODE_NAME) return v_utf8(info.name);
    if (f == NODE_PARENT) return v_int(info.parent);
    return v_vector3(info.rest_offset);
}

static godot_variant m_get_node_name(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md;
    return node_query(ud, argc, argv, NODE_NAME);
}

static godot_variant m_get_node_parent(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md;
    return node_query(ud, argc, argv, NODE_PARENT);
}

static godot_variant m_get_node_rest_offset(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    (void)o, (void)md;
    return node_query(ud, argc, argv, NODE_REST);
}

/* ---- sampling ------------------------------------------------------------------------------- */

static mcd_result sample_into_pose(instance *self, int argc, godot_variant **argv, int first) {
    if (!self->a.opened) return MCD_ERROR_INVALID_ARGUMENT;
    if (argc < first + 3) return MCD_ERROR_INVALID_ARGUMENT;
    return mcd_sample(&self->a.asset, (uint32_t)core->godot_variant_as_int(argv[first]),
                      (float)core->godot_variant_as_real(argv[first + 1]),
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

static godot_variant m_get_pose_rotation(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    int64_t i = arg_int(argc, argv, 0);
    godot_quat q;
    godot_variant v;
    (void)o, (void)md;
    if (!self->a.opened || i < 0 || i >= (int64_t)self->a.asset.max_nodes) {
        core->godot_quat_new(&q, 0, 0, 0, 1);
    } else {
        const float *r = self->a.pose[i].rotation;
        core->godot_quat_new(&q, r[0], r[1], r[2], r[3]);
    }
    core->godot_variant_new_quat(&v, &q);
    return v;
}

static godot_variant m_get_pose_translation(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    int64_t i = arg_int(argc, argv, 0);
    static const float zero[3] = {0, 0, 0};
    (void)o, (void)md;
    if (!self->a.opened || i < 0 || i >= (int64_t)self->a.asset.max_nodes) return v_vector3(zero);
    return v_vector3(self->a.pose[i].translation);
}

/* bind_skeleton(skeleton: Skeleton, skeleton_index: int) -> int: bones matched by name, or -1 */
static godot_variant m_bind_skeleton(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    godot_object *skeleton;
    mcd_skeleton_info info;
    uint32_t i, matched = 0;
    (void)o, (void)md;
    unbind(self);
    if (argc != 2 || !self->a.opened) return v_int(-1);
    skeleton = core->godot_variant_as_object(argv[0]);
    self->skeleton_index = (uint32_t)core->godot_variant_as_int(argv[1]);
    if (!skeleton || mcd_get_skeleton_info(&self->a.asset, self->skeleton_index, &info) != MCD_OK) {
        report("MocodecAnimation.bind_skeleton", MCD_ERROR_INVALID_ARGUMENT);
        return v_int(-1);
    }
    self->bone_of_node = core->godot_alloc((int)(info.node_count * sizeof(int64_t)));
    self->inverse_rest = core->godot_alloc((int)(info.node_count * sizeof(godot_transform)));
    for (i = 0; i < info.node_count; i++) {
        mcd_node_info node;
        godot_string name;
        const void *args[1];
        int64_t bone = -1;
        mcd_get_node_info(&self->a.asset, self->skeleton_index, i, &node);
        core->godot_string_new(&name);
        core->godot_string_parse_utf8(&name, node.name);
        args[0] = &name;
        core->godot_method_bind_ptrcall(skel_find_bone, skeleton, args, &bone);
        core->godot_string_destroy(&name);
        self->bone_of_node[i] = bone;
        if (bone >= 0) {
            /* Godot composes a bone as parent * rest * pose; keeping rest^-1 turns the asset's
             * local transform into the pose, so any rest the rig has is honoured. */
            godot_transform rest;
            const void *rest_args[1];
            rest_args[0] = &bone;
            core->godot_method_bind_ptrcall(skel_get_bone_rest, skeleton, rest_args, &rest);
            self->inverse_rest[i] = core->godot_transform_affine_inverse(&rest);
            matched++;
        }
    }
    self->skeleton = skeleton;
    self->bound_nodes = info.node_count;
    return v_int(matched);
}

/* apply(skeleton: Skeleton, clip: int, time: float, flags: int) -> int: samples and sets the
 * bound skeleton's bone poses (local transforms; MCD_SAMPLE_WORLD is refused). */
static godot_variant m_apply(godot_object *o, void *md, void *ud, int argc, godot_variant **argv) {
    instance *self = ud;
    mcd_clip_info info;
    mcd_result r;
    uint32_t i;
    (void)o, (void)md;
    if (argc != 4 || !self->skeleton || core->godot_variant_as_object(argv[0]) != self->skeleton ||
        (core->godot_variant_as_int(argv[3]) & MCD_SAMPLE_WORLD)) {
        report("MocodecAnimation.apply (bind_skeleton first, local flags only)", MCD_ERROR_INVALID_ARGUMENT);
        return v_int(MCD_ERROR_INVALID_ARGUMENT);
    }
    r = mcd_get_clip_info(&self->a.asset, (uint32_t)core->godot_variant_as_int(argv[1]), &info);
    if (r == MCD_OK && info.skeleton != self->skeleton_index) r = MCD_ERROR_INVALID_ARGUMENT;
    if (r == MCD_OK) r = sample_into_pose(self, argc, argv, 1);
    if (r != MCD_OK) {
        report("MocodecAnimation.apply", r);
        return v_int(r);
    }
    for (i = 0; i < self->bound_nodes; i++) {
        godot_transform local, pose;
        const void *args[2];
        if (self->bone_of_node[i] < 0) continue;
        local = to_transform(&self->a.pose[i]);
        pose = core->godot_transform_operator_multiply(&self->inverse_rest[i], &local);
        args[0] = &self->bone_of_node[i];
        args[1] = &pose;
        core->godot_method_bind_ptrcall(skel_set_bone_pose, self->skeleton, args, NULL);
    }
    return v_int(MCD_OK);
}

/* ---- registration --------------------------------------------------------------------------- */

static void *create(godot_object *obj, void *md) {
    instance *self = core->godot_alloc(sizeof(instance));
    (void)obj, (void)md;
    if (self) memset(self, 0, sizeof *self);
    return self;
}

static void destroy(godot_object *obj, void *md, void *ud) {
    (void)obj, (void)md;
    close_asset(ud);
    release(ud);
}

ENTRY void godot_gdnative_init(godot_gdnative_init_options *options) {
    unsigned i;
    core = options->api_struct;
    for (i = 0; i < core->num_extensions; i++)
        if (core->extensions[i]->type == GDNATIVE_EXT_NATIVESCRIPT)
            ns = (const godot_gdnative_ext_nativescript_api_struct *)core->extensions[i];
    skel_find_bone = core->godot_method_bind_get_method("Skeleton", "find_bone");
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
        {"get_node_rest_offset", m_get_node_rest_offset},
        {"sample", m_sample},
        {"get_pose_rotation", m_get_pose_rotation},
        {"get_pose_translation", m_get_pose_translation},
        {"bind_skeleton", m_bind_skeleton},
        {"apply", m_apply},
    };
    godot_instance_create_func c = {NULL, NULL, NULL};
    godot_instance_destroy_func d = {NULL, NULL, NULL};
    size_t i;
    c.create_func = create;
    d.destroy_func = destroy;
    ns->godot_nativescript_register_class(handle, "MocodecAnimation", "Reference", c, d);
    for (i = 0; i < sizeof methods / sizeof methods[0]; i++) {
        godot_instance_method m = {NULL, NULL, NULL};
        godot_method_attributes attr = {GODOT_METHOD_RPC_MODE_DISABLED};
        m.method = methods[i].fn;
        ns->godot_nativescript_register_method(handle, "MocodecAnimation", methods[i].name, attr, m);
    }
}
