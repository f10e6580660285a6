/*
 * Godot 4 binding of the mocodec runtime, a GDExtension in C99 with no dependency but the
 * official gdextension_interface.h (fetched at build time from the crates.io crate
 * gdextension-api 0.4.0, interface 4.3, so Godot 4.3 and newer load it). Two classes:
 *
 *   MocodecAnimation (Resource): holds the .mcd bytes (property `data`, saved with the
 *     resource: addons/mocodec's import plugin turns each .mcd into one), opens them with the
 *     runtime, answers clip/skeleton queries and samples poses.
 *   MocodecSkeletonModifier (SkeletonModifier3D, Godot 4.3+): plays one clip of a
 *     MocodecAnimation on its parent Skeleton3D through the runtime's retargeting (the
 *     skeleton's own bone names, rests and proportions). The skeleton calls it in its
 *     modification pass, after the AnimationMixer / AnimationTree, and blends it by the
 *     modifier's `influence`; it never writes bones from _process. Buffers are allocated when
 *     it binds to an animation and skeleton, never per frame.
 *
 * Every method is registered with both entry points Godot uses: a Variant call (GDScript's
 * dynamic calls) and a ptrcall (typed calls), both funnelled into one implementation per
 * method through the small type table below. Results are the runtime's codes (0 = OK);
 * failures are also printed through Godot's error channel.
 */
#include <math.h>
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
static const void *skel_get_bone_count, *skel_get_bone_name, *skel_get_bone_parent, *skel_get_bone_rest, *skel_set_rotation,
    *skel_set_position, *skel_set_scale, *modifier_get_skeleton, *node_get_delta;
static void *animation_tag;

static gd_string_name name_animation, name_modifier, name_resource, name_modifier_base, name_process, name_process_delta,
    name_empty;

static void make_name(gd_string_name *out, const char *latin1) {
    gd.string_name_new(out, latin1, 1); /* the literals live as long as the library */
}

static void report(const char *where, mcd_result r) {
    gd.print_error(mcd_result_string(r), where, __FILE__, __LINE__, 0);
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

static void animation_get_node_kind(void *p, const void *const *args, void *ret) {
    mcd_node_info info;
    *(int64_t *)ret = node_info(p, args, &info) ? (int64_t)info.kind : -1;
}

static void animation_get_node_rest_rotation(void *p, const void *const *args, void *ret) {
    static const float identity[4] = {0, 0, 0, 1};
    mcd_node_info info;
    memcpy(ret, node_info(p, args, &info) ? info.rest_rotation : identity, 4 * sizeof(float));
}

static void animation_get_node_rest_translation(void *p, const void *const *args, void *ret) {
    static const float zero[3] = {0, 0, 0};
    mcd_node_info info;
    memcpy(ret, node_info(p, args, &info) ? info.rest_translation : zero, 3 * sizeof(float));
}

/* sample(clip, time, flags) -> result; read the pose with get_pose_rotation/translation */
static void animation_sample(void *p, const void *const *args, void *ret) {
    animation *self = p;
    mcd_result r = MCD_ERROR_INVALID_ARGUMENT;
    if (self->a.opened)
        r = mcd_sample(&self->a.asset, (uint32_t) * (const int64_t *)args[0], *(const double *)args[1],
                       (uint32_t) * (const int64_t *)args[2], self->a.pose, self->a.asset.max_nodes, self->a.scratch);
    if (r != MCD_OK) report("MocodecAnimation.sample", r);
    *(int64_t *)ret = r;
}

static const mcd_transform *pose_at(animation *self, const void *const *args) {
    static const mcd_transform identity = {{0, 0, 0, 1}, {0, 0, 0}, {1, 1, 1}};
    int64_t i = *(const int64_t *)args[0];
    return self->a.opened && i >= 0 && i < (int64_t)self->a.asset.max_nodes ? &self->a.pose[i] : &identity;
}

static void animation_get_pose_rotation(void *p, const void *const *args, void *ret) {
    memcpy(ret, pose_at(p, args)->rotation, 4 * sizeof(float));
}

static void animation_get_pose_translation(void *p, const void *const *args, void *ret) {
    memcpy(ret, pose_at(p, args)->translation, 3 * sizeof(float));
}

static void animation_get_pose_scale(void *p, const void *const *args, void *ret) {
    memcpy(ret, pose_at(p, args)->scale, 3 * sizeof(float));
}

/* ---- MocodecSkeletonModifier ----------------------------------------------------------------- */

typedef struct {
    GDExtensionObjectPtr object;
    gd_variant animation_ref; /* a Variant holding the Ref keeps the resource alive */
    animation *anim;
    int64_t clip;
    double time, speed, unit_scale; /* unit_scale 0: metres from the asset's cm_per_unit */
    uint8_t playing, loop, contacts, root_motion, match_directions;
    /* bound state, rebuilt when a property changes or sampling fails */
    GDObjectInstanceID skeleton_id;
    mcd_engine_rig rig;
    double duration;
} modifier;

static void modifier_unbind(modifier *self) {
    mcd_engine_rig_close(&self->rig, &godot_memory);
    self->skeleton_id = 0;
}

static animation *as_animation(GDExtensionObjectPtr obj) {
    static const GDExtensionInstanceBindingCallbacks none = {NULL, NULL, NULL};
    if (!obj || !gd.object_cast_to(obj, animation_tag)) return NULL;
    return gd.object_get_binding(obj, library, &none);
}

/* Godot's Transform3D (float_32): the basis rows, then the origin. */
typedef struct { float rows[3][3]; float origin[3]; } gd_transform3d;

static mcd_transform from_transform3d(const gd_transform3d *x) {
    mcd_transform t;
    double m[3][3], len[3];
    int r, c;
    /* column lengths are the scale (basis = R * diag(scale)) */
    for (c = 0; c < 3; c++) {
        len[c] = sqrt((double)x->rows[0][c] * x->rows[0][c] + (double)x->rows[1][c] * x->rows[1][c] +
                      (double)x->rows[2][c] * x->rows[2][c]);
        if (!(len[c] > 0)) len[c] = 1;
        t.scale[c] = (float)len[c];
        t.translation[c] = x->origin[c];
    }
    for (r = 0; r < 3; r++)
        for (c = 0; c < 3; c++) m[r][c] = x->rows[r][c] / len[c];
    mcd_engine_rotation_from_rows(m, t.rotation);
    return t;
}

/* The skeleton's bones (names, parents, rests) as the rig, retargeted from the clip's skeleton. */
static int modifier_bind(modifier *self, GDExtensionObjectPtr skeleton) {
    mcd_clip_info clip;
    mcd_skeleton_info skel;
    mcd_retarget_config config;
    mcd_retarget_issue issue;
    mcd_rig_bone *bones;
    char (*names)[256];
    int64_t count = 0, i;
    mcd_result r;
    modifier_unbind(self);
    if (!self->anim || !self->anim->a.opened) return 0;
    if (mcd_get_clip_info(&self->anim->a.asset, (uint32_t)self->clip, &clip) != MCD_OK) return 0;
    mcd_get_skeleton_info(&self->anim->a.asset, clip.skeleton, &skel);
    gd.method_ptrcall(skel_get_bone_count, skeleton, NULL, &count);
    if (count <= 0) return 0;
    bones = gd.mem_alloc((size_t)count * sizeof *bones);
    names = gd.mem_alloc((size_t)count * sizeof *names);
    for (i = 0; i < count; i++) {
        const void *args[1];
        gd_string name;
        gd_transform3d rest;
        int64_t parent = -1;
        GDExtensionInt n;
        args[0] = &i;
        gd.method_ptrcall(skel_get_bone_name, skeleton, args, &name);
        n = gd.string_to_utf8(&name, names[i], 255);
        names[i][n < 0 ? 0 : (n > 255 ? 255 : n)] = 0;
        string_free(&name);
        gd.method_ptrcall(skel_get_bone_parent, skeleton, args, &parent);
        gd.method_ptrcall(skel_get_bone_rest, skeleton, args, &rest);
        bones[i].name = names[i];
        bones[i].parent = (int32_t)parent;
        bones[i].flags = 0;
        bones[i].rest = from_transform3d(&rest);
    }
    mcd_retarget_config_default(&config);
    config.flags = (self->root_motion ? MCD_RETARGET_ROOT_MOTION : 0u) | (self->match_directions ? MCD_RETARGET_MATCH_DIRECTIONS : 0u);
    config.unit_scale = self->unit_scale > 0 ? (float)self->unit_scale : skel.cm_per_unit * 0.01f; /* Godot scenes are in metres */
    r = mcd_engine_rig_build(&self->rig, &self->anim->a, clip.skeleton, bones, (uint32_t)count, NULL, 0, &config,
                             &godot_memory, &issue);
    if (r != MCD_OK) report(issue.where == MCD_RETARGET_ISSUE_BONE ? "MocodecSkeletonModifier: a bone of the skeleton"
                                                                    : "MocodecSkeletonModifier: retargeting settings", r);
    gd.mem_free(names);
    gd.mem_free(bones);
    if (r != MCD_OK) return 0;
    self->skeleton_id = gd.object_get_id(skeleton);
    self->duration = clip.duration;
    return 1;
}

/* Advances time and poses the skeleton: the body of the modification pass. */
static void modifier_step(modifier *self, double delta) {
    GDExtensionObjectPtr skeleton = NULL;
    mcd_result r;
    uint32_t i;
    gd.method_ptrcall(modifier_get_skeleton, self->object, NULL, &skeleton);
    if (!skeleton) return;
    if ((!self->rig.bound || gd.object_get_id(skeleton) != self->skeleton_id) && !modifier_bind(self, skeleton)) return;
    if (self->playing) {
        self->time += delta * self->speed;
        if (!self->loop && (self->time > self->duration || self->time < 0)) {
            self->time = self->time < 0 ? 0 : self->duration;
            self->playing = 0;
        }
    }
    r = mcd_engine_rig_pose(&self->rig, &self->anim->a, (uint32_t)self->clip, self->time,
                            (self->loop ? MCD_SAMPLE_LOOP : 0) | (self->contacts ? MCD_SAMPLE_CONTACTS : 0));
    if (r != MCD_OK) { /* e.g. the animation's data changed under us: rebind next time */
        report("MocodecSkeletonModifier", r);
        modifier_unbind(self);
        return;
    }
    for (i = 0; i < self->rig.info.bone_count; i++) {
        const void *args[2];
        int64_t bone = i;
        int32_t node = -1;
        /* a bone the asset does not drive keeps what the AnimationMixer gave it */
        if (mcd_retarget_get_node(self->rig.map, i, &node) != MCD_OK || node < 0) continue;
        args[0] = &bone;
        args[1] = self->rig.rig_pose[i].rotation;
        gd.method_ptrcall(skel_set_rotation, skeleton, args, NULL);
        args[1] = self->rig.rig_pose[i].translation;
        gd.method_ptrcall(skel_set_position, skeleton, args, NULL);
        args[1] = self->rig.rig_pose[i].scale;
        gd.method_ptrcall(skel_set_scale, skeleton, args, NULL);
    }
}

static void modifier_set_animation(void *p, const void *const *args, void *ret) {
    modifier *self = p;
    GDExtensionObjectPtr obj = *(GDExtensionObjectPtr const *)args[0];
    (void)ret;
    modifier_unbind(self);
    gd.variant_destroy(&self->animation_ref);
    self->anim = as_animation(obj);
    if (self->anim)
        gd.from_type_ctor(GDEXTENSION_VARIANT_TYPE_OBJECT)(&self->animation_ref, &obj);
    else
        gd.variant_new_nil(&self->animation_ref);
}

static void modifier_get_animation(void *p, const void *const *args, void *ret) {
    modifier *self = p;
    (void)args;
    *(GDExtensionObjectPtr *)ret = self->anim ? self->anim->object : NULL;
}

/* A property whose change needs a new retargeting map. */
#define REBIND_FIELD(name, field, ctype)                                            \
    static void modifier_set_##name(void *p, const void *const *args, void *ret) {  \
        (void)ret;                                                                  \
        modifier_unbind(p);                                                         \
        ((modifier *)p)->field = *(const ctype *)args[0];                           \
    }                                                                               \
    static void modifier_get_##name(void *p, const void *const *args, void *ret) {  \
        (void)args;                                                                 \
        *(ctype *)ret = ((modifier *)p)->field;                                     \
    }
REBIND_FIELD(clip, clip, int64_t)
REBIND_FIELD(root_motion, root_motion, uint8_t)
REBIND_FIELD(match_directions, match_directions, uint8_t)
REBIND_FIELD(unit_scale, unit_scale, double)

#define MODIFIER_FIELD(name, field, ctype)                                          \
    static void modifier_set_##name(void *p, const void *const *args, void *ret) {  \
        (void)ret;                                                                  \
        ((modifier *)p)->field = *(const ctype *)args[0];                           \
    }                                                                               \
    static void modifier_get_##name(void *p, const void *const *args, void *ret) {  \
        (void)args;                                                                 \
        *(ctype *)ret = ((modifier *)p)->field;                                     \
    }
MODIFIER_FIELD(time, time, double)
MODIFIER_FIELD(speed, speed, double)
MODIFIER_FIELD(playing, playing, uint8_t)
MODIFIER_FIELD(loop, loop, uint8_t)
MODIFIER_FIELD(contacts, contacts, uint8_t)

/* advance(delta): one modification pass by hand (what the skeleton runs each frame). */
static void modifier_advance(void *p, const void *const *args, void *ret) {
    (void)ret;
    modifier_step(p, *(const double *)args[0]);
}

/* get_bone_node(bone) -> the asset node driving a skeleton bone, -1 (also before binding) */
static void modifier_get_bone_node(void *p, const void *const *args, void *ret) {
    modifier *self = p;
    int32_t node = -1;
    if (self->rig.bound) mcd_retarget_get_node(self->rig.map, (uint32_t) * (const int64_t *)args[0], &node);
    *(int64_t *)ret = node;
}

/* _process_modification_with_delta(delta) (4.5+) */
static void modifier_process_delta(GDExtensionClassInstancePtr p, const GDExtensionConstTypePtr *args, GDExtensionTypePtr ret) {
    (void)ret;
    modifier_step((modifier *)p, *(const double *)args[0]);
}

/* _process_modification() (4.3, 4.4): the frame's delta comes from the node */
static void modifier_process(GDExtensionClassInstancePtr p, const GDExtensionConstTypePtr *args, GDExtensionTypePtr ret) {
    modifier *self = (modifier *)p;
    double delta = 0;
    (void)args, (void)ret;
    gd.method_ptrcall(node_get_delta, self->object, NULL, &delta);
    modifier_step(self, delta);
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
    {"get_node_kind", animation_get_node_kind, K_INT, 2, {K_INT, K_INT}, {"skeleton", "node"}},
    {"get_node_rest_rotation", animation_get_node_rest_rotation, K_QUATERNION, 2, {K_INT, K_INT}, {"skeleton", "node"}},
    {"get_node_rest_translation", animation_get_node_rest_translation, K_VECTOR3, 2, {K_INT, K_INT}, {"skeleton", "node"}},
    {"sample", animation_sample, K_INT, 3, {K_INT, K_FLOAT, K_INT}, {"clip", "time", "flags"}},
    {"get_pose_rotation", animation_get_pose_rotation, K_QUATERNION, 1, {K_INT}, {"node"}},
    {"get_pose_translation", animation_get_pose_translation, K_VECTOR3, 1, {K_INT}, {"node"}},
    {"get_pose_scale", animation_get_pose_scale, K_VECTOR3, 1, {K_INT}, {"node"}},
};

static const method_def modifier_methods[] = {
    {"set_animation", modifier_set_animation, K_VOID, 1, {K_ANIMATION}, {"animation"}},
    {"get_animation", modifier_get_animation, K_ANIMATION, 0, {K_VOID}, {NULL}},
    {"set_clip", modifier_set_clip, K_VOID, 1, {K_INT}, {"clip"}},
    {"get_clip", modifier_get_clip, K_INT, 0, {K_VOID}, {NULL}},
    {"set_time", modifier_set_time, K_VOID, 1, {K_FLOAT}, {"time"}},
    {"get_time", modifier_get_time, K_FLOAT, 0, {K_VOID}, {NULL}},
    {"set_speed", modifier_set_speed, K_VOID, 1, {K_FLOAT}, {"speed"}},
    {"get_speed", modifier_get_speed, K_FLOAT, 0, {K_VOID}, {NULL}},
    {"set_playing", modifier_set_playing, K_VOID, 1, {K_BOOL}, {"playing"}},
    {"is_playing", modifier_get_playing, K_BOOL, 0, {K_VOID}, {NULL}},
    {"set_loop", modifier_set_loop, K_VOID, 1, {K_BOOL}, {"loop"}},
    {"is_loop", modifier_get_loop, K_BOOL, 0, {K_VOID}, {NULL}},
    {"set_contacts", modifier_set_contacts, K_VOID, 1, {K_BOOL}, {"contacts"}},
    {"is_contacts", modifier_get_contacts, K_BOOL, 0, {K_VOID}, {NULL}},
    {"set_root_motion", modifier_set_root_motion, K_VOID, 1, {K_BOOL}, {"root_motion"}},
    {"is_root_motion", modifier_get_root_motion, K_BOOL, 0, {K_VOID}, {NULL}},
    {"set_match_directions", modifier_set_match_directions, K_VOID, 1, {K_BOOL}, {"match_directions"}},
    {"is_match_directions", modifier_get_match_directions, K_BOOL, 0, {K_VOID}, {NULL}},
    {"set_unit_scale", modifier_set_unit_scale, K_VOID, 1, {K_FLOAT}, {"unit_scale"}},
    {"get_unit_scale", modifier_get_unit_scale, K_FLOAT, 0, {K_VOID}, {NULL}},
    {"advance", modifier_advance, K_VOID, 1, {K_FLOAT}, {"delta"}},
    {"get_bone_node", modifier_get_bone_node, K_INT, 1, {K_INT}, {"bone"}},
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

static GDExtensionObjectPtr modifier_create(void *userdata) {
    modifier *self = gd.mem_alloc(sizeof *self);
    (void)userdata;
    memset(self, 0, sizeof *self);
    gd.variant_new_nil(&self->animation_ref);
    self->speed = 1.0;
    self->playing = 1;
    self->loop = 1;
    self->contacts = 1; /* contact IK on by default: a no-op for assets without contacts */
    self->root_motion = 1;
    self->match_directions = 1;
    return attach(&name_modifier_base, &name_modifier, self, &self->object);
}

static void modifier_free(void *userdata, GDExtensionClassInstancePtr p) {
    modifier *self = (modifier *)p;
    (void)userdata;
    modifier_unbind(self);
    gd.variant_destroy(&self->animation_ref);
    gd.mem_free(self);
}

static GDExtensionClassCallVirtual modifier_get_virtual(void *userdata, GDExtensionConstStringNamePtr name) {
    GDExtensionBool equal = 0;
    (void)userdata;
    string_name_equal(name, &name_process_delta, &equal);
    if (equal) return modifier_process_delta;
    string_name_equal(name, &name_process, &equal);
    return equal ? modifier_process : NULL;
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
    gd_string_name size_name;
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

    skel_get_bone_count = method_bind("Skeleton3D", "get_bone_count", HASH_SKELETON3D_GET_BONE_COUNT);
    skel_get_bone_name = method_bind("Skeleton3D", "get_bone_name", HASH_SKELETON3D_GET_BONE_NAME);
    skel_get_bone_parent = method_bind("Skeleton3D", "get_bone_parent", HASH_SKELETON3D_GET_BONE_PARENT);
    skel_get_bone_rest = method_bind("Skeleton3D", "get_bone_rest", HASH_SKELETON3D_GET_BONE_REST);
    skel_set_rotation = method_bind("Skeleton3D", "set_bone_pose_rotation", HASH_SKELETON3D_SET_BONE_POSE_ROTATION);
    skel_set_position = method_bind("Skeleton3D", "set_bone_pose_position", HASH_SKELETON3D_SET_BONE_POSE_POSITION);
    skel_set_scale = method_bind("Skeleton3D", "set_bone_pose_scale", HASH_SKELETON3D_SET_BONE_POSE_SCALE);
    modifier_get_skeleton = method_bind("SkeletonModifier3D", "get_skeleton", HASH_SKELETONMODIFIER3D_GET_SKELETON);
    node_get_delta = method_bind("Node", "get_process_delta_time", HASH_NODE_GET_PROCESS_DELTA_TIME);

    make_name(&name_animation, "MocodecAnimation");
    make_name(&name_modifier, "MocodecSkeletonModifier");
    make_name(&name_resource, "Resource");
    make_name(&name_modifier_base, "SkeletonModifier3D");
    make_name(&name_process, "_process_modification");
    make_name(&name_process_delta, "_process_modification_with_delta");
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
    info.create_instance_func = modifier_create;
    info.free_instance_func = modifier_free;
    info.get_virtual_func = modifier_get_virtual;
    gd.register_class(library, &name_modifier, &name_modifier_base, &info);
    register_methods(&name_modifier, modifier_methods, sizeof modifier_methods / sizeof modifier_methods[0]);
    register_property(&name_modifier, "animation", K_ANIMATION, "set_animation", "get_animation");
    register_property(&name_modifier, "clip", K_INT, "set_clip", "get_clip");
    register_property(&name_modifier, "time", K_FLOAT, "set_time", "get_time");
    register_property(&name_modifier, "speed", K_FLOAT, "set_speed", "get_speed");
    register_property(&name_modifier, "playing", K_BOOL, "set_playing", "is_playing");
    register_property(&name_modifier, "loop", K_BOOL, "set_loop", "is_loop");
    register_property(&name_modifier, "contacts", K_BOOL, "set_contacts", "is_contacts");
    register_property(&name_modifier, "root_motion", K_BOOL, "set_root_motion", "is_root_motion");
    register_property(&name_modifier, "match_directions", K_BOOL, "set_match_directions", "is_match_directions");
    register_property(&name_modifier, "unit_scale", K_FLOAT, "set_unit_scale", "get_unit_scale");
}

static void deinitialize(void *userdata, GDExtensionInitializationLevel level) {
    (void)userdata;
    if (level != GDEXTENSION_INITIALIZATION_SCENE) return;
    gd.unregister_class(library, &name_modifier);
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
 * interface function this library needs; Godot 4.2 has no SkeletonModifier3D (the .gdextension
 * asks for 4.3). */
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
