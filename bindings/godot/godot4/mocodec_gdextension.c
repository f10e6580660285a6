/*
 * Godot 4 binding of the mocodec runtime, a GDExtension in C99 with no dependency but the
 * official gdextension_interface.h (fetched at build time from the crates.io crate
 * gdextension-api 0.4.0, interface 4.2, so Godot 4.2 and newer load it). Two classes:
 *
 *   MocodecAnimation (Resource): holds the .mcd bytes (property `data`, saved with the
 *     resource), opens them with the runtime, answers clip/skeleton queries and samples poses.
 *   MocodecSkeletonPlayer (Node): plays one clip of a MocodecAnimation on a Skeleton3D, bones
 *     matched by name, every frame from _process. Buffers are allocated when it binds to an
 *     animation and skeleton, never per frame.
 *
 * Every method is registered with both entry points Godot uses: a Variant call (GDScript's
 * dynamic calls) and a ptrcall (typed calls), both funnelled into one implementation per
 * method through the small type table below. Results are the runtime's codes (0 = OK);
 * failures are also printed through Godot's error channel.
 */
#include <stdint.h>
#include <string.h>

#include "gdextension_interface.h"
#include "mcd_godot_api_constants.h"
#include "mcd_engine_asset.h"
#include "mocodec.h"

#if defined(_WIN32)
#define ENTRY __declspec(dllexport)
#elif defined(__GNUC__)
#define ENTRY __attribute__((visibility("default")))
#else
#define ENTRY
#endif

/* Opaque engine values, sized as in extension_api.json's float_32 configuration. */
typedef struct { uint64_t opaque[1]; } gd_string_name;
typedef struct { uint64_t opaque[1]; } gd_string;
typedef struct { uint64_t opaque[1]; } gd_node_path;
typedef struct { uint64_t opaque[2]; } gd_bytes;
typedef struct { uint64_t opaque[3]; } gd_variant;

/* ---- the engine's interface, resolved once in the entry point ------------------------------
 * Declared with void pointers where the header has one opaque pointer type per engine type:
 * the values below live in our own storage types, and every pointer passes the same way. */

typedef void (*ctor_fn)(void *dest, const void *const *args);
typedef void (*dtor_fn)(void *self);
typedef void (*builtin_fn)(void *base, const void *const *args, void *ret, int argc);
typedef void (*operator_fn)(const void *a, const void *b, void *ret);
typedef void (*from_type_fn)(void *variant, void *value);
typedef void (*to_type_fn)(void *value, void *variant);

static struct {
    void *(*mem_alloc)(size_t bytes);
    void (*mem_free)(void *p);
    void (*print_error)(const char *description, const char *function, const char *file, int32_t line, uint8_t notify);
    void (*string_name_new)(void *dest, const char *latin1, uint8_t is_static);
    void (*string_new_utf8)(void *dest, const char *utf8);
    int64_t (*string_to_utf8)(const void *self, char *out, int64_t max_length);
    void (*variant_new_nil)(void *dest);
    void (*variant_destroy)(void *self);
    GDExtensionVariantType (*variant_get_type)(const void *self);
    from_type_fn (*from_type_ctor)(GDExtensionVariantType type);
    to_type_fn (*to_type_ctor)(GDExtensionVariantType type);
    ctor_fn (*ptr_constructor)(GDExtensionVariantType type, int32_t index);
    dtor_fn (*ptr_destructor)(GDExtensionVariantType type);
    builtin_fn (*ptr_builtin_method)(GDExtensionVariantType type, const void *name, int64_t hash);
    operator_fn (*ptr_operator)(GDExtensionVariantOperator op, GDExtensionVariantType a, GDExtensionVariantType b);
    const uint8_t *(*bytes_at)(const void *bytes, int64_t index);
    void *(*construct_object)(const void *class_name);
    const void *(*get_method_bind)(const void *class_name, const void *method, int64_t hash);
    void *(*get_class_tag)(const void *class_name);
    void (*register_class)(void *library, const void *name, const void *parent, const GDExtensionClassCreationInfo2 *info);
    void (*register_method)(void *library, const void *class_name, const GDExtensionClassMethodInfo *info);
    void (*register_property)(void *library, const void *class_name, const GDExtensionPropertyInfo *info,
                              const void *setter, const void *getter);
    void (*unregister_class)(void *library, const void *class_name);
    void (*object_set_instance)(void *object, const void *class_name, void *instance);
    void (*object_set_binding)(void *object, void *token, void *binding, const GDExtensionInstanceBindingCallbacks *callbacks);
    void *(*object_get_binding)(void *object, void *token, const GDExtensionInstanceBindingCallbacks *callbacks);
    void *(*object_cast_to)(const void *object, void *class_tag);
    uint64_t (*object_get_id)(const void *object);
    void *(*object_from_id)(uint64_t id);
    void (*method_ptrcall)(const void *bind, void *object, const void *const *args, void *ret);
    void *(*ref_get_object)(const void *ref);
    void (*ref_set_object)(void *ref, void *object);
} gd;

static GDExtensionClassLibraryPtr library;

/* Built-in helpers resolved at initialisation. */
static ctor_fn bytes_new, bytes_copy, node_path_new, node_path_copy;
static dtor_fn string_name_free, string_free, bytes_free, node_path_free;
static builtin_fn bytes_size;
static operator_fn string_name_equal;
static const void *skel_find_bone, *skel_set_rotation, *skel_set_position, *node_get_node;
static void *skeleton_tag, *animation_tag;

static gd_string_name name_animation, name_player, name_resource, name_node, name_process, name_empty;

static void make_name(gd_string_name *out, const char *latin1) {
    gd.string_name_new(out, latin1, 1); /* the literals live as long as the library */
}

static void report(const char *where, mcd_result r) {
    gd.print_error(mcd_result_string(r), where, __FILE__, __LINE__, 0);
}

static void release(void *p) {
    if (p) gd.mem_free(p);
}

/* ---- MocodecAnimation ------------------------------------------------------------------------ */

typedef struct {
    GDExtensionObjectPtr object;
    gd_bytes data;           /* the `data` property, kept so the resource saves its bytes */
    int64_t result;          /* result of the last load */
    mcd_engine_asset a;
} animation;

static void *engine_alloc(size_t n) {
    return gd.mem_alloc(n);
}

static void engine_free(void *p) {
    gd.mem_free(p);
}

static const mcd_engine_allocator godot_memory = {engine_alloc, engine_free};

static void animation_set_data(void *p, const void *const *args, void *ret) {
    animation *self = p;
    const void *copy_args[1];
    int64_t size = 0;
    mcd_result r;
    (void)ret;
    bytes_free(&self->data);
    copy_args[0] = args[0];
    bytes_copy(&self->data, copy_args);
    bytes_size(&self->data, NULL, &size, 0);
    r = mcd_engine_asset_load(&self->a, size > 0 ? gd.bytes_at(&self->data, 0) : NULL, (size_t)size, &godot_memory);
    if (r != MCD_OK) report("MocodecAnimation.set_data", r);
    self->result = r;
}

static void animation_get_data(void *p, const void *const *args, void *ret) {
    const void *copy_args[1];
    (void)args;
    copy_args[0] = &((animation *)p)->data;
    bytes_copy(ret, copy_args);
}

static void animation_get_result(void *p, const void *const *args, void *ret) {
    (void)args;
    *(int64_t *)ret = ((animation *)p)->result;
}

static void animation_get_version(void *p, const void *const *args, void *ret) {
    (void)p, (void)args;
    *(int64_t *)ret = mcd_version();
}

static void animation_get_clip_count(void *p, const void *const *args, void *ret) {
    animation *self = p;
    (void)args;
    *(int64_t *)ret = self->a.opened ? mcd_clip_count(&self->a.asset) : 0;
}

/* One clip lookup for the clip getters; -1 (or "") and an error print on a bad index. */
static int clip_info(animation *self, const void *const *args, mcd_clip_info *info) {
    mcd_result r = self->a.opened ? mcd_get_clip_info(&self->a.asset, (uint32_t) * (const int64_t *)args[0], info)
                                : MCD_ERROR_INVALID_ARGUMENT;
    if (r != MCD_OK) report("MocodecAnimation clip query", r);
    return r == MCD_OK;
}

static void animation_get_clip_name(void *p, const void *const *args, void *ret) {
    mcd_clip_info info;
    gd.string_new_utf8(ret, clip_info(p, args, &info) ? info.name : "");
}

static void animation_get_clip_duration(void *p, const void *const *args, void *ret) {
    mcd_clip_info info;
    *(double *)ret = clip_info(p, args, &info) ? info.duration : -1.0;
}

static void animation_get_clip_frame_count(void *p, const void *const *args, void *ret) {
    mcd_clip_info info;
    *(int64_t *)ret = clip_info(p, args, &info) ? (int64_t)info.frame_count : -1;
}

static void animation_get_clip_skeleton(void *p, const void *const *args, void *ret) {
    mcd_clip_info info;
    *(int64_t *)ret = clip_info(p, args, &info) ? (int64_t)info.skeleton : -1;
}

static void animation_get_clip_node_count(void *p, const void *const *args, void *ret) {
    mcd_clip_info info;
    *(int64_t *)ret = clip_info(p, args, &info) ? (int64_t)info.node_count : -1;
}

/* find_clip(name) -> index or -1 */
static void animation_find_clip(void *p, const void *const *args, void *ret) {
    animation *self = p;
    char name[512];
    uint32_t clip = 0;
    GDExtensionInt n = gd.string_to_utf8(args[0], name, (GDExtensionInt)sizeof name - 1);
    /* the returned length is the whole string's; only sizeof name - 1 bytes were written */
    name[n < 0 ? 0 : (n > (GDExtensionInt)sizeof name - 1 ? (GDExtensionInt)sizeof name - 1 : n)] = 0;
    *(int64_t *)ret = self->a.opened && mcd_find_clip(&self->a.asset, name, &clip) == MCD_OK ? (int64_t)clip : -1;
}

static void animation_get_node_count(void *p, const void *const *args, void *ret) {
    animation *self = p;
    mcd_skeleton_info info;
    *(int64_t *)ret = self->a.opened && mcd_get_skeleton_info(&self->a.asset, (uint32_t) * (const int64_t *)args[0], &info) == MCD_OK
                          ? (int64_t)info.node_count
                          : -1;
}

static void animation_get_cm_per_unit(void *p, const void *const *args, void *ret) {
    animation *self = p;
    mcd_skeleton_info info;
    *(double *)ret = self->a.opened && mcd_get_skeleton_info(&self->a.asset, (uint32_t) * (const int64_t *)args[0], &info) == MCD_OK
                         ? info.cm_per_unit
                         : 0.0;
}

static int node_info(animation *self, const void *const *args, mcd_node_info *info) {
    mcd_result r = self->a.opened ? mcd_get_node_info(&self->a.asset, (uint32_t) * (const int64_t *)args[0],
                                                    (uint32_t) * (const int64_t *)args[1], info)
                                : MCD_ERROR_INVALID_ARGUMENT;
    if (r != MCD_OK) report("MocodecAnimation node query", r);
    return r == MCD_OK;
}

static void animation_get_node_name(void *p, const void *const *args, void *ret) {
    mcd_node_info info;
    gd.string_new_utf8(ret, node_info(p, args, &info) ? info.name : "");
}

static void animation_get_node_parent(void *p, const void *const *args, void *ret) {
    mcd_node_info info;
    *(int64_t *)ret = node_info(p, args, &info) ? (int64_t)info.parent : -2;
}

/* sample(clip, time, flags) -> result; read the pose with get_pose_rotation/translation */
static void animation_sample(void *p, const void *const *args, void *ret) {
    animation *self = p;
    mcd_result r = MCD_ERROR_INVALID_ARGUMENT;
    if (self->a.opened)
        r = mcd_sample(&self->a.asset, (uint32_t) * (const int64_t *)args[0], (float)*(const double *)args[1],
                       (uint32_t) * (const int64_t *)args[2], self->a.pose, self->a.asset.max_nodes, self->a.scratch);
    if (r != MCD_OK) report("MocodecAnimation.sample", r);
    *(int64_t *)ret = r;
}

static const mcd_transform *pose_at(animation *self, const void *const *args) {
    static const mcd_transform identity = {{0, 0, 0, 1}, {0, 0, 0}};
    int64_t i = *(const int64_t *)args[0];
    return self->a.opened && i >= 0 && i < (int64_t)self->a.asset.max_nodes ? &self->a.pose[i] : &identity;
}

static void animation_get_pose_rotation(void *p, const void *const *args, void *ret) {
    memcpy(ret, pose_at(p, args)->rotation, 4 * sizeof(float));
}

static void animation_get_pose_translation(void *p, const void *const *args, void *ret) {
    memcpy(ret, pose_at(p, args)->translation, 3 * sizeof(float));
}

/* ---- MocodecSkeletonPlayer ------------------------------------------------------------------- */

typedef struct {
    GDExtensionObjectPtr object;
    gd_variant animation_ref; /* a Variant holding the Ref keeps the resource alive */
    animation *anim;
    gd_node_path skeleton_path;
    int64_t clip;
    double time, speed;
    uint8_t playing, loop, contacts;
    /* bound state, rebuilt when a property changes or sampling fails */
    uint32_t bound;
    GDObjectInstanceID skeleton_id;
    uint32_t node_count;
    int64_t *bone_of_node;
    uint8_t *scratch_block;
    void *scratch;
    mcd_transform *pose;
    float metres_per_unit;
    double duration;
} player;

static void player_unbind(player *self) {
    release(self->bone_of_node);
    release(self->scratch_block);
    release(self->pose);
    self->bone_of_node = NULL;
    self->scratch_block = NULL;
    self->scratch = NULL;
    self->pose = NULL;
    self->bound = 0;
}

static animation *as_animation(GDExtensionObjectPtr obj) {
    static const GDExtensionInstanceBindingCallbacks none = {NULL, NULL, NULL};
    if (!obj || !gd.object_cast_to(obj, animation_tag)) return NULL;
    return gd.object_get_binding(obj, library, &none);
}

/* Resolves the skeleton and maps the clip's nodes to its bones by name. */
static int player_bind(player *self) {
    GDExtensionObjectPtr skeleton = NULL;
    const void *args[1];
    mcd_clip_info clip;
    mcd_skeleton_info skel;
    size_t scratch_size;
    uint32_t i;
    player_unbind(self);
    if (!self->anim || !self->anim->a.opened) return 0;
    if (mcd_get_clip_info(&self->anim->a.asset, (uint32_t)self->clip, &clip) != MCD_OK) return 0;
    mcd_get_skeleton_info(&self->anim->a.asset, clip.skeleton, &skel);
    args[0] = &self->skeleton_path;
    gd.method_ptrcall(node_get_node, self->object, args, &skeleton);
    if (!skeleton || !gd.object_cast_to(skeleton, skeleton_tag)) return 0;
    self->skeleton_id = gd.object_get_id(skeleton);
    self->node_count = clip.node_count;
    self->duration = clip.duration;
    self->metres_per_unit = skel.cm_per_unit * 0.01f; /* Godot scenes are in metres */
    self->bone_of_node = gd.mem_alloc(clip.node_count * sizeof(int64_t) + 1);
    for (i = 0; i < clip.node_count; i++) {
        mcd_node_info node;
        gd_string name;
        int64_t bone = -1;
        mcd_get_node_info(&self->anim->a.asset, clip.skeleton, i, &node);
        gd.string_new_utf8(&name, node.name);
        args[0] = &name;
        gd.method_ptrcall(skel_find_bone, skeleton, args, &bone);
        string_free(&name);
        self->bone_of_node[i] = bone;
    }
    scratch_size = mcd_scratch_size(&self->anim->a.asset);
    self->scratch_block = gd.mem_alloc(scratch_size + 16);
    self->scratch = mcd_engine_align16(self->scratch_block);
    self->pose = gd.mem_alloc(clip.node_count * sizeof(mcd_transform) + 1);
    if (mcd_scratch_init(&self->anim->a.asset, self->scratch, scratch_size) != MCD_OK) return 0;
    self->bound = 1;
    return 1;
}

/* Advances time and writes the pose: the body of _process, also callable as advance(delta). */
static void player_step(player *self, double delta) {
    GDExtensionObjectPtr skeleton;
    mcd_result r;
    uint32_t i;
    if (!self->bound && !player_bind(self)) return;
    skeleton = gd.object_from_id(self->skeleton_id);
    if (!skeleton) {
        player_unbind(self);
        return;
    }
    if (self->playing) {
        self->time += delta * self->speed;
        if (!self->loop && (self->time > self->duration || self->time < 0)) {
            self->time = self->time < 0 ? 0 : self->duration;
            self->playing = 0;
        }
    }
    r = mcd_sample(&self->anim->a.asset, (uint32_t)self->clip, (float)self->time,
                   (self->loop ? MCD_SAMPLE_LOOP : 0) | (self->contacts ? MCD_SAMPLE_CONTACTS : 0), self->pose, self->node_count, self->scratch);
    if (r != MCD_OK) { /* e.g. the animation's data changed under us: rebind next frame */
        report("MocodecSkeletonPlayer", r);
        player_unbind(self);
        return;
    }
    for (i = 0; i < self->node_count; i++) {
        const void *args[2];
        float position[3];
        if (self->bone_of_node[i] < 0) continue;
        args[0] = &self->bone_of_node[i];
        args[1] = self->pose[i].rotation;
        gd.method_ptrcall(skel_set_rotation, skeleton, args, NULL);
        position[0] = self->pose[i].translation[0] * self->metres_per_unit;
        position[1] = self->pose[i].translation[1] * self->metres_per_unit;
        position[2] = self->pose[i].translation[2] * self->metres_per_unit;
        args[1] = position;
        gd.method_ptrcall(skel_set_position, skeleton, args, NULL);
    }
}

static void player_set_animation(void *p, const void *const *args, void *ret) {
    player *self = p;
    GDExtensionObjectPtr obj = *(GDExtensionObjectPtr const *)args[0];
    (void)ret;
    player_unbind(self);
    gd.variant_destroy(&self->animation_ref);
    self->anim = as_animation(obj);
    if (self->anim)
        gd.from_type_ctor(GDEXTENSION_VARIANT_TYPE_OBJECT)(&self->animation_ref, &obj);
    else
        gd.variant_new_nil(&self->animation_ref);
}

static void player_get_animation(void *p, const void *const *args, void *ret) {
    player *self = p;
    (void)args;
    *(GDExtensionObjectPtr *)ret = self->anim ? self->anim->object : NULL;
}

static void player_set_skeleton(void *p, const void *const *args, void *ret) {
    player *self = p;
    const void *copy_args[1];
    (void)ret;
    player_unbind(self);
    node_path_free(&self->skeleton_path);
    copy_args[0] = args[0];
    node_path_copy(&self->skeleton_path, copy_args);
}

static void player_get_skeleton(void *p, const void *const *args, void *ret) {
    const void *copy_args[1];
    (void)args;
    copy_args[0] = &((player *)p)->skeleton_path;
    node_path_copy(ret, copy_args);
}

static void player_set_clip(void *p, const void *const *args, void *ret) {
    (void)ret;
    player_unbind(p);
    ((player *)p)->clip = *(const int64_t *)args[0];
}

static void player_get_clip(void *p, const void *const *args, void *ret) {
    (void)args;
    *(int64_t *)ret = ((player *)p)->clip;
}

#define PLAYER_FIELD(name, field, ctype)                                            \
    static void player_set_##name(void *p, const void *const *args, void *ret) {    \
        (void)ret;                                                                  \
        ((player *)p)->field = *(const ctype *)args[0];                             \
    }                                                                               \
    static void player_get_##name(void *p, const void *const *args, void *ret) {    \
        (void)args;                                                                 \
        *(ctype *)ret = ((player *)p)->field;                                       \
    }
PLAYER_FIELD(time, time, double)
PLAYER_FIELD(speed, speed, double)
PLAYER_FIELD(playing, playing, uint8_t)
PLAYER_FIELD(loop, loop, uint8_t)
PLAYER_FIELD(contacts, contacts, uint8_t)

static void player_advance(void *p, const void *const *args, void *ret) {
    (void)ret;
    player_step(p, *(const double *)args[0]);
}

static void player_process(GDExtensionClassInstancePtr p, const GDExtensionConstTypePtr *args, GDExtensionTypePtr ret) {
    (void)ret;
    player_step((player *)p, *(const double *)args[0]);
}

/* ---- method table and the two calling conventions ------------------------------------------- */

enum kind { K_VOID, K_INT, K_FLOAT, K_BOOL, K_STRING, K_BYTES, K_VECTOR3, K_QUATERNION, K_NODE_PATH, K_ANIMATION };

static const GDExtensionVariantType variant_type[] = {
    GDEXTENSION_VARIANT_TYPE_NIL, GDEXTENSION_VARIANT_TYPE_INT, GDEXTENSION_VARIANT_TYPE_FLOAT,
    GDEXTENSION_VARIANT_TYPE_BOOL, GDEXTENSION_VARIANT_TYPE_STRING, GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY,
    GDEXTENSION_VARIANT_TYPE_VECTOR3, GDEXTENSION_VARIANT_TYPE_QUATERNION, GDEXTENSION_VARIANT_TYPE_NODE_PATH,
    GDEXTENSION_VARIANT_TYPE_OBJECT};

typedef union {
    int64_t i;
    double f;
    uint8_t b;
    float v[4];
    uint64_t opaque[3];
    GDExtensionObjectPtr object;
} value;

typedef void (*impl_fn)(void *self, const void *const *args, void *ret);

typedef struct {
    const char *name;
    impl_fn fn;
    enum kind ret;
    uint32_t argc;
    enum kind args[3];
    const char *arg_names[3];
} method_def;

static const method_def animation_methods[] = {
    {"set_data", animation_set_data, K_VOID, 1, {K_BYTES}, {"data"}},
    {"get_data", animation_get_data, K_BYTES, 0, {K_VOID}, {NULL}},
    {"get_result", animation_get_result, K_INT, 0, {K_VOID}, {NULL}},
    {"get_version", animation_get_version, K_INT, 0, {K_VOID}, {NULL}},
    {"get_clip_count", animation_get_clip_count, K_INT, 0, {K_VOID}, {NULL}},
    {"get_clip_name", animation_get_clip_name, K_STRING, 1, {K_INT}, {"clip"}},
    {"get_clip_duration", animation_get_clip_duration, K_FLOAT, 1, {K_INT}, {"clip"}},
    {"get_clip_frame_count", animation_get_clip_frame_count, K_INT, 1, {K_INT}, {"clip"}},
    {"get_clip_skeleton", animation_get_clip_skeleton, K_INT, 1, {K_INT}, {"clip"}},
    {"get_clip_node_count", animation_get_clip_node_count, K_INT, 1, {K_INT}, {"clip"}},
    {"find_clip", animation_find_clip, K_INT, 1, {K_STRING}, {"name"}},
    {"get_node_count", animation_get_node_count, K_INT, 1, {K_INT}, {"skeleton"}},
    {"get_cm_per_unit", animation_get_cm_per_unit, K_FLOAT, 1, {K_INT}, {"skeleton"}},
    {"get_node_name", animation_get_node_name, K_STRING, 2, {K_INT, K_INT}, {"skeleton", "node"}},
    {"get_node_parent", animation_get_node_parent, K_INT, 2, {K_INT, K_INT}, {"skeleton", "node"}},
    {"sample", animation_sample, K_INT, 3, {K_INT, K_FLOAT, K_INT}, {"clip", "time", "flags"}},
    {"get_pose_rotation", animation_get_pose_rotation, K_QUATERNION, 1, {K_INT}, {"node"}},
    {"get_pose_translation", animation_get_pose_translation, K_VECTOR3, 1, {K_INT}, {"node"}},
};

static const method_def player_methods[] = {
    {"set_animation", player_set_animation, K_VOID, 1, {K_ANIMATION}, {"animation"}},
    {"get_animation", player_get_animation, K_ANIMATION, 0, {K_VOID}, {NULL}},
    {"set_skeleton", player_set_skeleton, K_VOID, 1, {K_NODE_PATH}, {"path"}},
    {"get_skeleton", player_get_skeleton, K_NODE_PATH, 0, {K_VOID}, {NULL}},
    {"set_clip", player_set_clip, K_VOID, 1, {K_INT}, {"clip"}},
    {"get_clip", player_get_clip, K_INT, 0, {K_VOID}, {NULL}},
    {"set_time", player_set_time, K_VOID, 1, {K_FLOAT}, {"time"}},
    {"get_time", player_get_time, K_FLOAT, 0, {K_VOID}, {NULL}},
    {"set_speed", player_set_speed, K_VOID, 1, {K_FLOAT}, {"speed"}},
    {"get_speed", player_get_speed, K_FLOAT, 0, {K_VOID}, {NULL}},
    {"set_playing", player_set_playing, K_VOID, 1, {K_BOOL}, {"playing"}},
    {"is_playing", player_get_playing, K_BOOL, 0, {K_VOID}, {NULL}},
    {"set_loop", player_set_loop, K_VOID, 1, {K_BOOL}, {"loop"}},
    {"is_loop", player_get_loop, K_BOOL, 0, {K_VOID}, {NULL}},
    {"set_contacts", player_set_contacts, K_VOID, 1, {K_BOOL}, {"contacts"}},
    {"is_contacts", player_get_contacts, K_BOOL, 0, {K_VOID}, {NULL}},
    {"advance", player_advance, K_VOID, 1, {K_FLOAT}, {"delta"}},
};

static int has_destructor(enum kind k) {
    return k == K_STRING || k == K_BYTES || k == K_NODE_PATH;
}

static void destroy_value(enum kind k, value *v) {
    if (k == K_STRING) string_free(v);
    else if (k == K_BYTES) bytes_free(v);
    else if (k == K_NODE_PATH) node_path_free(v);
}

/* Typed call: arguments arrive as pointers to engine values; a Ref argument or result
 * is a Ref<T>, read and written through ref_get_object / ref_set_object. */
static void method_ptrcall(void *userdata, GDExtensionClassInstancePtr instance,
                           const GDExtensionConstTypePtr *args, GDExtensionTypePtr r_ret) {
    const method_def *m = userdata;
    const void *native[3];
    GDExtensionObjectPtr objects[3];
    value ret;
    uint32_t i;
    for (i = 0; i < m->argc; i++) {
        native[i] = args[i];
        if (m->args[i] == K_ANIMATION) {
            objects[i] = gd.ref_get_object(args[i]);
            native[i] = &objects[i];
        }
    }
    if (m->ret == K_ANIMATION) {
        m->fn(instance, native, &ret);
        gd.ref_set_object(r_ret, ret.object);
    } else {
        m->fn(instance, native, r_ret);
    }
}

/* Dynamic call: Variants in and out, types checked (an int is accepted where a float is due). */
static void method_call(void *userdata, GDExtensionClassInstancePtr instance, const GDExtensionConstVariantPtr *args,
                        GDExtensionInt argc, GDExtensionVariantPtr r_return, GDExtensionCallError *r_error) {
    const method_def *m = userdata;
    value values[3], ret;
    const void *native[3];
    uint32_t i;
    r_error->error = GDEXTENSION_CALL_OK;
    if (argc != (GDExtensionInt)m->argc) {
        r_error->error = argc < (GDExtensionInt)m->argc ? GDEXTENSION_CALL_ERROR_TOO_FEW_ARGUMENTS
                                                        : GDEXTENSION_CALL_ERROR_TOO_MANY_ARGUMENTS;
        r_error->expected = (int32_t)m->argc;
        return;
    }
    for (i = 0; i < m->argc; i++) {
        GDExtensionVariantType have = gd.variant_get_type(args[i]);
        GDExtensionVariantType want = variant_type[m->args[i]];
        if (want == GDEXTENSION_VARIANT_TYPE_FLOAT && have == GDEXTENSION_VARIANT_TYPE_INT) {
            int64_t n;
            gd.to_type_ctor(GDEXTENSION_VARIANT_TYPE_INT)(&n, (GDExtensionVariantPtr)args[i]);
            values[i].f = (double)n;
        } else if (m->args[i] == K_ANIMATION && have == GDEXTENSION_VARIANT_TYPE_NIL) {
            values[i].object = NULL;
        } else if (have != want) {
            uint32_t j;
            for (j = 0; j < i; j++) destroy_value(m->args[j], &values[j]);
            r_error->error = GDEXTENSION_CALL_ERROR_INVALID_ARGUMENT;
            r_error->argument = (int32_t)i;
            r_error->expected = (int32_t)want;
            return;
        } else {
            gd.to_type_ctor(want)(&values[i], (GDExtensionVariantPtr)args[i]);
        }
        native[i] = &values[i];
    }
    m->fn(instance, native, &ret);
    if (m->ret == K_VOID)
        gd.variant_new_nil(r_return);
    else
        gd.from_type_ctor(variant_type[m->ret])(r_return, &ret);
    if (has_destructor(m->ret)) destroy_value(m->ret, &ret);
    for (i = 0; i < m->argc; i++) destroy_value(m->args[i], &values[i]);
}

static GDExtensionPropertyInfo property_info(enum kind k, gd_string_name *name, gd_string_name *class_name,
                                             gd_string *hint_string) {
    GDExtensionPropertyInfo info;
    info.type = variant_type[k];
    info.name = (GDExtensionStringNamePtr)name;
    info.class_name = (GDExtensionStringNamePtr)(k == K_ANIMATION ? class_name : &name_empty);
    info.hint = k == K_ANIMATION ? PROPERTY_HINT_RESOURCE_TYPE : PROPERTY_HINT_NONE;
    info.hint_string = (GDExtensionStringPtr)hint_string;
    info.usage = PROPERTY_USAGE_DEFAULT;
    return info;
}

static GDExtensionClassMethodArgumentMetadata metadata(enum kind k) {
    if (k == K_INT) return GDEXTENSION_METHOD_ARGUMENT_METADATA_INT_IS_INT64;
    if (k == K_FLOAT) return GDEXTENSION_METHOD_ARGUMENT_METADATA_REAL_IS_DOUBLE;
    return GDEXTENSION_METHOD_ARGUMENT_METADATA_NONE;
}

static void register_methods(gd_string_name *class_name, const method_def *defs, size_t count) {
    size_t i;
    gd_string hint_animation, hint_empty;
    gd.string_new_utf8(&hint_animation, "MocodecAnimation");
    gd.string_new_utf8(&hint_empty, "");
    for (i = 0; i < count; i++) {
        const method_def *m = &defs[i];
        gd_string_name method_name, arg_names[3], ret_name;
        GDExtensionPropertyInfo ret_info, arg_info[3];
        GDExtensionClassMethodArgumentMetadata arg_meta[3];
        GDExtensionClassMethodInfo info;
        uint32_t a;
        make_name(&method_name, m->name);
        make_name(&ret_name, "");
        ret_info = property_info(m->ret, &ret_name, &name_animation, m->ret == K_ANIMATION ? &hint_animation : &hint_empty);
        for (a = 0; a < m->argc; a++) {
            make_name(&arg_names[a], m->arg_names[a]);
            arg_info[a] = property_info(m->args[a], &arg_names[a], &name_animation,
                                        m->args[a] == K_ANIMATION ? &hint_animation : &hint_empty);
            arg_meta[a] = metadata(m->args[a]);
        }
        memset(&info, 0, sizeof info);
        info.name = (GDExtensionStringNamePtr)&method_name;
        info.method_userdata = (void *)m;
        info.call_func = method_call;
        info.ptrcall_func = method_ptrcall;
        info.method_flags = GDEXTENSION_METHOD_FLAGS_DEFAULT;
        info.has_return_value = m->ret != K_VOID;
        info.return_value_info = &ret_info;
        info.return_value_metadata = metadata(m->ret);
        info.argument_count = m->argc;
        info.arguments_info = arg_info;
        info.arguments_metadata = arg_meta;
        gd.register_method(library, class_name, &info);
        string_name_free(&method_name);
        string_name_free(&ret_name);
        for (a = 0; a < m->argc; a++) string_name_free(&arg_names[a]);
    }
    string_free(&hint_animation);
    string_free(&hint_empty);
}

static void register_property(gd_string_name *class_name, const char *name, enum kind k, const char *setter,
                              const char *getter) {
    gd_string_name prop, set, get;
    gd_string hint;
    GDExtensionPropertyInfo info;
    make_name(&prop, name);
    make_name(&set, setter);
    make_name(&get, getter);
    gd.string_new_utf8(&hint, k == K_ANIMATION ? "MocodecAnimation" : "");
    info = property_info(k, &prop, &name_animation, &hint);
    if (k == K_BYTES) info.usage = PROPERTY_USAGE_STORAGE; /* saved, not shown as a byte list */
    gd.register_property(library, class_name, &info, &set, &get);
    string_name_free(&prop);
    string_name_free(&set);
    string_name_free(&get);
    string_free(&hint);
}

/* ---- instances ---------------------------------------------------------------------------- */

static void *binding_create(void *token, void *instance) {
    (void)token, (void)instance;
    return NULL;
}

static void binding_free(void *token, void *instance, void *binding) {
    (void)token, (void)instance, (void)binding;
}

static GDExtensionBool binding_reference(void *token, void *binding, GDExtensionBool reference) {
    (void)token, (void)binding, (void)reference;
    return 1;
}

static const GDExtensionInstanceBindingCallbacks binding_callbacks = {binding_create, binding_free, binding_reference};

static GDExtensionObjectPtr attach(gd_string_name *parent, gd_string_name *class_name, void *self,
                                   GDExtensionObjectPtr *slot) {
    GDExtensionObjectPtr obj = gd.construct_object(parent);
    *slot = obj;
    gd.object_set_instance(obj, class_name, self);
    gd.object_set_binding(obj, library, self, &binding_callbacks);
    return obj;
}

static GDExtensionObjectPtr animation_create(void *userdata) {
    animation *self = gd.mem_alloc(sizeof *self);
    (void)userdata;
    memset(self, 0, sizeof *self);
    bytes_new(&self->data, NULL);
    self->result = MCD_ERROR_INVALID_ARGUMENT; /* nothing loaded yet */
    return attach(&name_resource, &name_animation, self, &self->object);
}

static void animation_free(void *userdata, GDExtensionClassInstancePtr p) {
    animation *self = (animation *)p;
    (void)userdata;
    mcd_engine_asset_close(&self->a, &godot_memory);
    bytes_free(&self->data);
    gd.mem_free(self);
}

static GDExtensionObjectPtr player_create(void *userdata) {
    player *self = gd.mem_alloc(sizeof *self);
    (void)userdata;
    memset(self, 0, sizeof *self);
    gd.variant_new_nil(&self->animation_ref);
    node_path_new(&self->skeleton_path, NULL);
    self->speed = 1.0;
    self->playing = 1;
    self->loop = 1;
    self->contacts = 1; /* contact IK on by default: a no-op for assets without contacts */
    return attach(&name_node, &name_player, self, &self->object);
}

static void player_free(void *userdata, GDExtensionClassInstancePtr p) {
    player *self = (player *)p;
    (void)userdata;
    player_unbind(self);
    gd.variant_destroy(&self->animation_ref);
    node_path_free(&self->skeleton_path);
    gd.mem_free(self);
}

static GDExtensionClassCallVirtual player_get_virtual(void *userdata, GDExtensionConstStringNamePtr name) {
    GDExtensionBool equal = 0;
    (void)userdata;
    string_name_equal(name, &name_process, &equal);
    return equal ? player_process : NULL;
}

/* ---- initialisation ------------------------------------------------------------------------ */

static const void *method_bind(const char *cls, const char *method, GDExtensionInt hash) {
    gd_string_name c, m;
    const void *bind;
    make_name(&c, cls);
    make_name(&m, method);
    bind = gd.get_method_bind(&c, &m, hash);
    string_name_free(&c);
    string_name_free(&m);
    return bind;
}

static void initialize(void *userdata, GDExtensionInitializationLevel level) {
    GDExtensionClassCreationInfo2 info;
    gd_string_name skeleton_name, size_name;
    (void)userdata;
    if (level != GDEXTENSION_INITIALIZATION_SCENE) return;

    bytes_new = gd.ptr_constructor(GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY, 0);
    bytes_copy = gd.ptr_constructor(GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY, 1);
    node_path_new = gd.ptr_constructor(GDEXTENSION_VARIANT_TYPE_NODE_PATH, 0);
    node_path_copy = gd.ptr_constructor(GDEXTENSION_VARIANT_TYPE_NODE_PATH, 1);
    string_name_free = gd.ptr_destructor(GDEXTENSION_VARIANT_TYPE_STRING_NAME);
    string_free = gd.ptr_destructor(GDEXTENSION_VARIANT_TYPE_STRING);
    bytes_free = gd.ptr_destructor(GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY);
    node_path_free = gd.ptr_destructor(GDEXTENSION_VARIANT_TYPE_NODE_PATH);
    string_name_equal = gd.ptr_operator(GDEXTENSION_VARIANT_OP_EQUAL, GDEXTENSION_VARIANT_TYPE_STRING_NAME,
                                        GDEXTENSION_VARIANT_TYPE_STRING_NAME);
    make_name(&size_name, "size");
    bytes_size = gd.ptr_builtin_method(GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY, &size_name, HASH_PACKED_BYTE_ARRAY_SIZE);
    string_name_free(&size_name);

    skel_find_bone = method_bind("Skeleton3D", "find_bone", HASH_SKELETON3D_FIND_BONE);
    skel_set_rotation = method_bind("Skeleton3D", "set_bone_pose_rotation", HASH_SKELETON3D_SET_BONE_POSE_ROTATION);
    skel_set_position = method_bind("Skeleton3D", "set_bone_pose_position", HASH_SKELETON3D_SET_BONE_POSE_POSITION);
    node_get_node = method_bind("Node", "get_node_or_null", HASH_NODE_GET_NODE_OR_NULL);
    make_name(&skeleton_name, "Skeleton3D");
    skeleton_tag = gd.get_class_tag(&skeleton_name);
    string_name_free(&skeleton_name);

    make_name(&name_animation, "MocodecAnimation");
    make_name(&name_player, "MocodecSkeletonPlayer");
    make_name(&name_resource, "Resource");
    make_name(&name_node, "Node");
    make_name(&name_process, "_process");
    make_name(&name_empty, "");

    memset(&info, 0, sizeof info);
    info.is_exposed = 1;
    info.create_instance_func = animation_create;
    info.free_instance_func = animation_free;
    gd.register_class(library, &name_animation, &name_resource, &info);
    animation_tag = gd.get_class_tag(&name_animation);
    register_methods(&name_animation, animation_methods, sizeof animation_methods / sizeof animation_methods[0]);
    register_property(&name_animation, "data", K_BYTES, "set_data", "get_data");

    memset(&info, 0, sizeof info);
    info.is_exposed = 1;
    info.create_instance_func = player_create;
    info.free_instance_func = player_free;
    info.get_virtual_func = player_get_virtual;
    gd.register_class(library, &name_player, &name_node, &info);
    register_methods(&name_player, player_methods, sizeof player_methods / sizeof player_methods[0]);
    register_property(&name_player, "animation", K_ANIMATION, "set_animation", "get_animation");
    register_property(&name_player, "skeleton", K_NODE_PATH, "set_skeleton", "get_skeleton");
    register_property(&name_player, "clip", K_INT, "set_clip", "get_clip");
    register_property(&name_player, "time", K_FLOAT, "set_time", "get_time");
    register_property(&name_player, "speed", K_FLOAT, "set_speed", "get_speed");
    register_property(&name_player, "playing", K_BOOL, "set_playing", "is_playing");
    register_property(&name_player, "loop", K_BOOL, "set_loop", "is_loop");
    register_property(&name_player, "contacts", K_BOOL, "set_contacts", "is_contacts");
}

static void deinitialize(void *userdata, GDExtensionInitializationLevel level) {
    (void)userdata;
    if (level != GDEXTENSION_INITIALIZATION_SCENE) return;
    gd.unregister_class(library, &name_player);
    gd.unregister_class(library, &name_animation);
}

/* Copies the engine's function pointer into our field of the same function, declared with
 * void pointers (C99 has no typeof to spell the cast). */
#define LOAD(field, name)                                                   \
    do {                                                                    \
        GDExtensionInterfaceFunctionPtr f_ = get_proc(name);                \
        if (!f_) return 0;                                                  \
        memcpy(&gd.field, &f_, sizeof f_);                                  \
    } while (0)

/* The entry point named in mocodec.gdextension. Fails (returns 0) when the engine lacks an
 * interface function this library needs, i.e. an engine older than 4.2. */
ENTRY GDExtensionBool mocodec_gdextension_init(GDExtensionInterfaceGetProcAddress get_proc,
                                               GDExtensionClassLibraryPtr lib,
                                               GDExtensionInitialization *init) {
    LOAD(mem_alloc, "mem_alloc");
    LOAD(mem_free, "mem_free");
    LOAD(print_error, "print_error");
    LOAD(string_name_new, "string_name_new_with_latin1_chars");
    LOAD(string_new_utf8, "string_new_with_utf8_chars");
    LOAD(string_to_utf8, "string_to_utf8_chars");
    LOAD(variant_new_nil, "variant_new_nil");
    LOAD(variant_destroy, "variant_destroy");
    LOAD(variant_get_type, "variant_get_type");
    LOAD(from_type_ctor, "get_variant_from_type_constructor");
    LOAD(to_type_ctor, "get_variant_to_type_constructor");
    LOAD(ptr_constructor, "variant_get_ptr_constructor");
    LOAD(ptr_destructor, "variant_get_ptr_destructor");
    LOAD(ptr_builtin_method, "variant_get_ptr_builtin_method");
    LOAD(ptr_operator, "variant_get_ptr_operator_evaluator");
    LOAD(bytes_at, "packed_byte_array_operator_index_const");
    LOAD(construct_object, "classdb_construct_object");
    LOAD(get_method_bind, "classdb_get_method_bind");
    LOAD(get_class_tag, "classdb_get_class_tag");
    LOAD(register_class, "classdb_register_extension_class2");
    LOAD(register_method, "classdb_register_extension_class_method");
    LOAD(register_property, "classdb_register_extension_class_property");
    LOAD(unregister_class, "classdb_unregister_extension_class");
    LOAD(object_set_instance, "object_set_instance");
    LOAD(object_set_binding, "object_set_instance_binding");
    LOAD(object_get_binding, "object_get_instance_binding");
    LOAD(object_cast_to, "object_cast_to");
    LOAD(object_get_id, "object_get_instance_id");
    LOAD(object_from_id, "object_get_instance_from_id");
    LOAD(method_ptrcall, "object_method_bind_ptrcall");
    LOAD(ref_get_object, "ref_get_object");
    LOAD(ref_set_object, "ref_set_object");
    library = lib;
    init->minimum_initialization_level = GDEXTENSION_INITIALIZATION_SCENE;
    init->userdata = NULL;
    init->initialize = initialize;
    init->deinitialize = deinitialize;
    return 1;
}
