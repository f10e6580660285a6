/*
 * A stand-in for the Godot 4 engine, enough to load the GDExtension the way Godot does and
 * drive it: dlopen, the entry point, initialisation at the SCENE level, then the registered
 * classes are checked and their methods called through both entry points Godot uses
 * (Variant call and ptrcall). Engine values are modelled simply (strings as char*, byte
 * arrays as pointer + size, a Skeleton3D as arrays of bone names, parents, rests and poses, a
 * SkeletonModifier3D that hands out that skeleton); what this checks is the extension's side of
 * the contract: registration, argument and result marshalling, sampling against the reference
 * poses, the modifier's pass retargeting onto a skeleton with its own rests (every joint where
 * the world-space sample puts it, in metres; a bone the asset does not drive left alone), and
 * that every byte it allocated through mem_alloc is freed. It cannot check Godot's own
 * behaviour (the modification pass, influence blending, the editor's import).
 *
 *   host_test LIBRARY ASSET.mcd ASSET.poses.txt
 */
#include <dlfcn.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gdextension_interface.h"

static int passed, failed, case_failed;
static const char *case_name;

static void begin(const char *name) {
    case_name = name;
    case_failed = 0;
}

#define CHECK(cond, ...)                                                           \
    do {                                                                           \
        if (!(cond)) {                                                             \
            if (!case_failed) {                                                    \
                printf("FAIL %s: ", case_name);                                    \
                printf(__VA_ARGS__);                                               \
                printf("  (%s:%d)\n", __FILE__, __LINE__);                         \
            }                                                                      \
            case_failed = 1;                                                       \
        }                                                                          \
    } while (0)

static void finish(void) {
    if (case_failed) failed++;
    else passed++;
}

/* ---- fake engine values ------------------------------------------------------------------- */

typedef struct { char *s; } fstr; /* String, StringName, NodePath */
typedef struct { uint8_t *data; int64_t size; } fbytes;
typedef struct {
    int32_t type;
    int32_t pad;
    union { int64_t i; double f; uint8_t b; float v[4]; void *p; fbytes bytes; char *s; } u;
} fvariant;

typedef struct fobject {
    const char *base_class;
    const char *ext_class;
    void *instance;
    void *binding;
    uint64_t id;
    /* a Skeleton3D */
    int bone_count;
    char bone_names[64][64];
    int64_t bone_parent[64];
    float bone_rest[64][12]; /* Transform3D: basis rows, origin */
    float rotation[64][4];
    float position[64][3];
    float scale[64][3];
    int rotation_set[64], position_set[64], scale_set[64];
} fobject;

static fobject *objects[64];
static int object_count;
static fobject *skeleton_object;
static long live_allocations, error_prints;

static char *dup(const char *s) {
    char *d = malloc(strlen(s) + 1);
    strcpy(d, s);
    return d;
}

static void *f_mem_alloc(size_t n) {
    live_allocations++;
    return malloc(n ? n : 1);
}
static void f_mem_free(void *p) {
    if (p) live_allocations--;
    free(p);
}
static void f_print_error(const char *d, const char *f, const char *file, int32_t line, GDExtensionBool n) {
    (void)file, (void)line, (void)n;
    error_prints++;
    printf("  (engine error print) %s: %s\n", f, d);
}
static void f_string_name_new(GDExtensionUninitializedStringNamePtr dest, const char *s, GDExtensionBool st) {
    (void)st;
    ((fstr *)dest)->s = dup(s);
}
static void f_string_new_utf8(GDExtensionUninitializedStringPtr dest, const char *s) {
    ((fstr *)dest)->s = dup(s);
}
static GDExtensionInt f_string_to_utf8(GDExtensionConstStringPtr self, char *out, GDExtensionInt max) {
    const char *s = ((const fstr *)self)->s;
    GDExtensionInt n = (GDExtensionInt)strlen(s);
    memcpy(out, s, (size_t)(n < max ? n : max));
    return n;
}
static void variant_clear(fvariant *v) {
    if (v->type == GDEXTENSION_VARIANT_TYPE_STRING || v->type == GDEXTENSION_VARIANT_TYPE_NODE_PATH ||
        v->type == GDEXTENSION_VARIANT_TYPE_STRING_NAME)
        free(v->u.s);
    if (v->type == GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY) free(v->u.bytes.data);
    v->type = GDEXTENSION_VARIANT_TYPE_NIL;
}
static void f_variant_new_nil(GDExtensionUninitializedVariantPtr dest) {
    memset(dest, 0, sizeof(fvariant));
}
static void f_variant_destroy(GDExtensionVariantPtr v) {
    variant_clear((fvariant *)v);
}
static GDExtensionVariantType f_variant_get_type(GDExtensionConstVariantPtr v) {
    return (GDExtensionVariantType)((const fvariant *)v)->type;
}

/* from_type / to_type, one pair per type the extension uses */
#define FROM_TO(tag, field, copy_in, copy_out)                                                        \
    static void from_##tag(GDExtensionUninitializedVariantPtr dv, GDExtensionTypePtr value) {      \
        fvariant *v = (fvariant *)dv;                                                               \
        memset(v, 0, sizeof *v);                                                                    \
        v->type = GDEXTENSION_VARIANT_TYPE_##tag;                                                   \
        copy_in;                                                                                    \
    }                                                                                               \
    static void to_##tag(GDExtensionUninitializedTypePtr value, GDExtensionVariantPtr dv) {        \
        fvariant *v = (fvariant *)dv;                                                               \
        copy_out;                                                                                   \
    }
FROM_TO(INT, i, v->u.i = *(int64_t *)value, *(int64_t *)value = v->u.i)
FROM_TO(FLOAT, f, v->u.f = *(double *)value, *(double *)value = v->u.f)
FROM_TO(BOOL, b, v->u.b = *(uint8_t *)value, *(uint8_t *)value = v->u.b)
FROM_TO(STRING, s, v->u.s = dup(((fstr *)value)->s), ((fstr *)value)->s = dup(v->u.s))
FROM_TO(NODE_PATH, s, v->u.s = dup(((fstr *)value)->s), ((fstr *)value)->s = dup(v->u.s))
FROM_TO(VECTOR3, v, memcpy(v->u.v, value, 12), memcpy(value, v->u.v, 12))
FROM_TO(QUATERNION, v, memcpy(v->u.v, value, 16), memcpy(value, v->u.v, 16))
FROM_TO(OBJECT, p, v->u.p = *(void **)value, *(void **)value = v->u.p)
FROM_TO(PACKED_BYTE_ARRAY, bytes,
        { v->u.bytes.size = ((fbytes *)value)->size; v->u.bytes.data = malloc((size_t)v->u.bytes.size + 1);
          memcpy(v->u.bytes.data, ((fbytes *)value)->data, (size_t)v->u.bytes.size); },
        { ((fbytes *)value)->size = v->u.bytes.size; ((fbytes *)value)->data = malloc((size_t)v->u.bytes.size + 1);
          memcpy(((fbytes *)value)->data, v->u.bytes.data, (size_t)v->u.bytes.size); })

static GDExtensionVariantFromTypeConstructorFunc f_from_type(GDExtensionVariantType t) {
    switch (t) {
    case GDEXTENSION_VARIANT_TYPE_INT: return from_INT;
    case GDEXTENSION_VARIANT_TYPE_FLOAT: return from_FLOAT;
    case GDEXTENSION_VARIANT_TYPE_BOOL: return from_BOOL;
    case GDEXTENSION_VARIANT_TYPE_STRING: return from_STRING;
    case GDEXTENSION_VARIANT_TYPE_NODE_PATH: return from_NODE_PATH;
    case GDEXTENSION_VARIANT_TYPE_VECTOR3: return from_VECTOR3;
    case GDEXTENSION_VARIANT_TYPE_QUATERNION: return from_QUATERNION;
    case GDEXTENSION_VARIANT_TYPE_OBJECT: return from_OBJECT;
    case GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY: return from_PACKED_BYTE_ARRAY;
    default: return NULL;
    }
}
static GDExtensionTypeFromVariantConstructorFunc f_to_type(GDExtensionVariantType t) {
    switch (t) {
    case GDEXTENSION_VARIANT_TYPE_INT: return to_INT;
    case GDEXTENSION_VARIANT_TYPE_FLOAT: return to_FLOAT;
    case GDEXTENSION_VARIANT_TYPE_BOOL: return to_BOOL;
    case GDEXTENSION_VARIANT_TYPE_STRING: return to_STRING;
    case GDEXTENSION_VARIANT_TYPE_NODE_PATH: return to_NODE_PATH;
    case GDEXTENSION_VARIANT_TYPE_VECTOR3: return to_VECTOR3;
    case GDEXTENSION_VARIANT_TYPE_QUATERNION: return to_QUATERNION;
    case GDEXTENSION_VARIANT_TYPE_OBJECT: return to_OBJECT;
    case GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY: return to_PACKED_BYTE_ARRAY;
    default: return NULL;
    }
}

static void bytes_ctor_default(GDExtensionUninitializedTypePtr d, const GDExtensionConstTypePtr *a) {
    (void)a;
    memset(d, 0, sizeof(fbytes));
}
static void bytes_ctor_copy(GDExtensionUninitializedTypePtr d, const GDExtensionConstTypePtr *a) {
    const fbytes *src = (const fbytes *)a[0];
    fbytes *dst = (fbytes *)d;
    dst->size = src->size;
    dst->data = malloc((size_t)src->size + 1);
    if (src->size) memcpy(dst->data, src->data, (size_t)src->size);
}
static void str_ctor_default(GDExtensionUninitializedTypePtr d, const GDExtensionConstTypePtr *a) {
    (void)a;
    ((fstr *)d)->s = dup("");
}
static void str_ctor_copy(GDExtensionUninitializedTypePtr d, const GDExtensionConstTypePtr *a) {
    ((fstr *)d)->s = dup(((const fstr *)a[0])->s);
}
static GDExtensionPtrConstructor f_ptr_constructor(GDExtensionVariantType t, int32_t index) {
    if (t == GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY) return index == 0 ? bytes_ctor_default : index == 1 ? bytes_ctor_copy : NULL;
    if (t == GDEXTENSION_VARIANT_TYPE_NODE_PATH) return index == 0 ? str_ctor_default : index == 1 ? str_ctor_copy : NULL;
    return NULL;
}
static void str_dtor(GDExtensionTypePtr p) {
    free(((fstr *)p)->s);
    ((fstr *)p)->s = NULL;
}
static void bytes_dtor(GDExtensionTypePtr p) {
    free(((fbytes *)p)->data);
    ((fbytes *)p)->data = NULL;
}
static GDExtensionPtrDestructor f_ptr_destructor(GDExtensionVariantType t) {
    if (t == GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY) return bytes_dtor;
    if (t == GDEXTENSION_VARIANT_TYPE_STRING || t == GDEXTENSION_VARIANT_TYPE_STRING_NAME ||
        t == GDEXTENSION_VARIANT_TYPE_NODE_PATH)
        return str_dtor;
    return NULL;
}
static void bytes_size(GDExtensionTypePtr base, const GDExtensionConstTypePtr *a, GDExtensionTypePtr ret, int n) {
    (void)a, (void)n;
    *(int64_t *)ret = ((fbytes *)base)->size;
}
static int64_t requested_size_hash;
static GDExtensionPtrBuiltInMethod f_ptr_builtin(GDExtensionVariantType t, GDExtensionConstStringNamePtr name, GDExtensionInt hash) {
    if (t == GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY && !strcmp(((const fstr *)name)->s, "size")) {
        requested_size_hash = hash;
        return bytes_size;
    }
    return NULL;
}
static void sn_equal(GDExtensionConstTypePtr a, GDExtensionConstTypePtr b, GDExtensionTypePtr r) {
    *(GDExtensionBool *)r = !strcmp(((const fstr *)a)->s, ((const fstr *)b)->s);
}
static GDExtensionPtrOperatorEvaluator f_ptr_operator(GDExtensionVariantOperator op, GDExtensionVariantType a, GDExtensionVariantType b) {
    return op == GDEXTENSION_VARIANT_OP_EQUAL && a == GDEXTENSION_VARIANT_TYPE_STRING_NAME && b == a ? sn_equal : NULL;
}
static const uint8_t *f_bytes_at(GDExtensionConstTypePtr self, GDExtensionInt i) {
    return ((const fbytes *)self)->data + i;
}

/* ---- objects, classes, method binds -------------------------------------------------------- */

static const char *class_tags[16];
static void *f_get_class_tag(GDExtensionConstStringNamePtr name) {
    const char *s = ((const fstr *)name)->s;
    int i;
    for (i = 0; i < 16 && class_tags[i]; i++)
        if (!strcmp(class_tags[i], s)) return (void *)&class_tags[i];
    class_tags[i] = dup(s);
    return (void *)&class_tags[i];
}
static fobject *new_object(const char *base) {
    fobject *o = calloc(1, sizeof *o);
    o->base_class = base;
    o->id = (uint64_t)(object_count + 1000);
    objects[object_count++] = o;
    return o;
}
static GDExtensionObjectPtr f_construct(GDExtensionConstStringNamePtr name) {
    return (GDExtensionObjectPtr)new_object(dup(((const fstr *)name)->s));
}
static void f_set_instance(GDExtensionObjectPtr o, GDExtensionConstStringNamePtr name, GDExtensionClassInstancePtr inst) {
    ((fobject *)o)->ext_class = dup(((const fstr *)name)->s);
    ((fobject *)o)->instance = inst;
}
static void f_set_binding(GDExtensionObjectPtr o, void *token, void *binding, const GDExtensionInstanceBindingCallbacks *cb) {
    (void)token, (void)cb;
    ((fobject *)o)->binding = binding;
}
static void *f_get_binding(GDExtensionObjectPtr o, void *token, const GDExtensionInstanceBindingCallbacks *cb) {
    (void)token, (void)cb;
    return ((fobject *)o)->binding;
}
static GDExtensionObjectPtr f_cast_to(GDExtensionConstObjectPtr o, void *tag) {
    const fobject *ob = (const fobject *)o;
    const char *cls = ob->ext_class ? ob->ext_class : ob->base_class;
    return !strcmp(*(const char **)tag, cls) ? (GDExtensionObjectPtr)o : NULL;
}
static GDObjectInstanceID f_get_id(GDExtensionConstObjectPtr o) {
    return ((const fobject *)o)->id;
}
static GDExtensionObjectPtr f_from_id(GDObjectInstanceID id) {
    int i;
    for (i = 0; i < object_count; i++)
        if (objects[i] && objects[i]->id == id) return (GDExtensionObjectPtr)objects[i];
    return NULL;
}
static GDExtensionObjectPtr f_ref_get(GDExtensionConstRefPtr r) {
    return *(GDExtensionObjectPtr const *)r;
}
static void f_ref_set(GDExtensionRefPtr r, GDExtensionObjectPtr o) {
    *(GDExtensionObjectPtr *)r = o;
}

static const struct { const char *cls, *method; } bind_names[] = {
    {NULL, NULL},
    {"Skeleton3D", "get_bone_count"}, {"Skeleton3D", "get_bone_name"}, {"Skeleton3D", "get_bone_parent"},
    {"Skeleton3D", "get_bone_rest"}, {"Skeleton3D", "set_bone_pose_rotation"}, {"Skeleton3D", "set_bone_pose_position"},
    {"Skeleton3D", "set_bone_pose_scale"}, {"SkeletonModifier3D", "get_skeleton"}, {"Node", "get_process_delta_time"},
};
enum bind_id { BIND_BONE_COUNT = 1, BIND_BONE_NAME, BIND_BONE_PARENT, BIND_BONE_REST, BIND_SET_ROTATION, BIND_SET_POSITION,
               BIND_SET_SCALE, BIND_GET_SKELETON, BIND_DELTA, BIND_COUNT };
static const int bind_ids[] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9};
static int binds_requested;
static double process_delta = 0.25;
static GDExtensionMethodBindPtr f_get_method_bind(GDExtensionConstStringNamePtr c, GDExtensionConstStringNamePtr m, GDExtensionInt hash) {
    const char *cls = ((const fstr *)c)->s, *met = ((const fstr *)m)->s;
    int id;
    for (id = 1; id < BIND_COUNT; id++)
        if (!strcmp(cls, bind_names[id].cls) && !strcmp(met, bind_names[id].method) && hash != 0) {
            binds_requested++;
            return (GDExtensionMethodBindPtr)&bind_ids[id];
        }
    return NULL;
}
static void f_bind_ptrcall(GDExtensionMethodBindPtr b, GDExtensionObjectPtr o, const GDExtensionConstTypePtr *args, GDExtensionTypePtr ret) {
    fobject *ob = (fobject *)o;
    int64_t bone = args ? *(const int64_t *)args[0] : 0;
    switch (*(const int *)b) {
    case BIND_BONE_COUNT: *(int64_t *)ret = ob->bone_count; break;
    case BIND_BONE_NAME: ((fstr *)ret)->s = dup(ob->bone_names[bone]); break; /* the caller frees the String */
    case BIND_BONE_PARENT: *(int64_t *)ret = ob->bone_parent[bone]; break;
    case BIND_BONE_REST: memcpy(ret, ob->bone_rest[bone], 48); break;
    case BIND_SET_ROTATION:
        memcpy(ob->rotation[bone], args[1], 16);
        ob->rotation_set[bone]++;
        break;
    case BIND_SET_POSITION:
        memcpy(ob->position[bone], args[1], 12);
        ob->position_set[bone]++;
        break;
    case BIND_SET_SCALE:
        memcpy(ob->scale[bone], args[1], 12);
        ob->scale_set[bone]++;
        break;
    case BIND_GET_SKELETON:
        *(GDExtensionObjectPtr *)ret = !strcmp(ob->base_class, "SkeletonModifier3D") ? (GDExtensionObjectPtr)skeleton_object : NULL;
        break;
    case BIND_DELTA: *(double *)ret = process_delta; break;
    }
}

/* ---- a little double-precision rotation math for the expected poses ------------------------ */

typedef struct { double x, y, z, w; } dq;
static dq q_mul(dq a, dq b) {
    dq r;
    r.x = a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y;
    r.y = a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x;
    r.z = a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w;
    r.w = a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z;
    return r;
}
static dq q_conj(dq q) { q.x = -q.x, q.y = -q.y, q.z = -q.z; return q; }
static dq q_of(const float *f) { dq q; q.x = f[0], q.y = f[1], q.z = f[2], q.w = f[3]; return q; }
static void q_rot(dq q, const double v[3], double out[3]) {
    dq p, r;
    p.x = v[0], p.y = v[1], p.z = v[2], p.w = 0;
    r = q_mul(q_mul(q, p), q_conj(q));
    out[0] = r.x, out[1] = r.y, out[2] = r.z;
}
/* Rows of the rotation matrix of q (the basis of a Transform3D). */
static void q_rows(dq q, float rows[3][3]) {
    double e[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, v[3];
    int r, c;
    for (c = 0; c < 3; c++) {
        q_rot(q, e[c], v); /* column c */
        for (r = 0; r < 3; r++) rows[r][c] = (float)v[r];
    }
}

/* ---- registration records ------------------------------------------------------------------ */

typedef struct {
    char cls[64], parent[64];
    GDExtensionClassCreationInfo2 info;
    int unregistered;
} class_rec;
typedef struct {
    char cls[64], name[64];
    GDExtensionClassMethodInfo info;
    GDExtensionVariantType arg_types[4], ret_type;
} method_rec;
typedef struct {
    char cls[64], name[64], setter[64], getter[64], hint_string[64];
    GDExtensionVariantType type;
    uint32_t usage;
} property_rec;

#define PROPERTY_USAGE_STORAGE_VALUE 2u /* Godot 4's PROPERTY_USAGE_STORAGE */

static class_rec classes[8];
static method_rec methods[64];
static property_rec properties[32];
static int class_count, method_count, property_count;

static void f_register_class(GDExtensionClassLibraryPtr lib, GDExtensionConstStringNamePtr name, GDExtensionConstStringNamePtr parent,
                             const GDExtensionClassCreationInfo2 *info) {
    class_rec *c = &classes[class_count++];
    (void)lib;
    snprintf(c->cls, sizeof c->cls, "%s", ((const fstr *)name)->s);
    snprintf(c->parent, sizeof c->parent, "%s", ((const fstr *)parent)->s);
    c->info = *info;
}
static void f_register_method(GDExtensionClassLibraryPtr lib, GDExtensionConstStringNamePtr cls, const GDExtensionClassMethodInfo *info) {
    method_rec *m = &methods[method_count++];
    uint32_t i;
    (void)lib;
    snprintf(m->cls, sizeof m->cls, "%s", ((const fstr *)cls)->s);
    snprintf(m->name, sizeof m->name, "%s", ((const fstr *)info->name)->s);
    m->info = *info;
    for (i = 0; i < info->argument_count && i < 4; i++) m->arg_types[i] = info->arguments_info[i].type;
    m->ret_type = info->has_return_value ? info->return_value_info->type : GDEXTENSION_VARIANT_TYPE_NIL;
}
static void f_register_property(GDExtensionClassLibraryPtr lib, GDExtensionConstStringNamePtr cls, const GDExtensionPropertyInfo *info,
                                GDExtensionConstStringNamePtr setter, GDExtensionConstStringNamePtr getter) {
    property_rec *p = &properties[property_count++];
    (void)lib;
    snprintf(p->cls, sizeof p->cls, "%s", ((const fstr *)cls)->s);
    snprintf(p->name, sizeof p->name, "%s", ((const fstr *)info->name)->s);
    snprintf(p->setter, sizeof p->setter, "%s", ((const fstr *)setter)->s);
    snprintf(p->getter, sizeof p->getter, "%s", ((const fstr *)getter)->s);
    snprintf(p->hint_string, sizeof p->hint_string, "%s", ((const fstr *)info->hint_string)->s);
    p->type = info->type;
    p->usage = info->usage;
}
static void f_unregister_class(GDExtensionClassLibraryPtr lib, GDExtensionConstStringNamePtr name) {
    int i;
    (void)lib;
    for (i = 0; i < class_count; i++)
        if (!strcmp(classes[i].cls, ((const fstr *)name)->s)) classes[i].unregistered = 1;
}

static const char *requested_missing;
static GDExtensionInterfaceFunctionPtr get_proc(const char *name) {
#define PROC(n, f) if (!strcmp(name, n)) return (GDExtensionInterfaceFunctionPtr)(void (*)(void))f
    PROC("mem_alloc", f_mem_alloc);
    PROC("mem_free", f_mem_free);
    PROC("print_error", f_print_error);
    PROC("string_name_new_with_latin1_chars", f_string_name_new);
    PROC("string_new_with_utf8_chars", f_string_new_utf8);
    PROC("string_to_utf8_chars", f_string_to_utf8);
    PROC("variant_new_nil", f_variant_new_nil);
    PROC("variant_destroy", f_variant_destroy);
    PROC("variant_get_type", f_variant_get_type);
    PROC("get_variant_from_type_constructor", f_from_type);
    PROC("get_variant_to_type_constructor", f_to_type);
    PROC("variant_get_ptr_constructor", f_ptr_constructor);
    PROC("variant_get_ptr_destructor", f_ptr_destructor);
    PROC("variant_get_ptr_builtin_method", f_ptr_builtin);
    PROC("variant_get_ptr_operator_evaluator", f_ptr_operator);
    PROC("packed_byte_array_operator_index_const", f_bytes_at);
    PROC("classdb_construct_object", f_construct);
    PROC("classdb_get_method_bind", f_get_method_bind);
    PROC("classdb_get_class_tag", f_get_class_tag);
    PROC("classdb_register_extension_class2", f_register_class);
    PROC("classdb_register_extension_class_method", f_register_method);
    PROC("classdb_register_extension_class_property", f_register_property);
    PROC("classdb_unregister_extension_class", f_unregister_class);
    PROC("object_set_instance", f_set_instance);
    PROC("object_set_instance_binding", f_set_binding);
    PROC("object_get_instance_binding", f_get_binding);
    PROC("object_cast_to", f_cast_to);
    PROC("object_get_instance_id", f_get_id);
    PROC("object_get_instance_from_id", f_from_id);
    PROC("object_method_bind_ptrcall", f_bind_ptrcall);
    PROC("ref_get_object", f_ref_get);
    PROC("ref_set_object", f_ref_set);
#undef PROC
    requested_missing = name;
    return NULL;
}

/* ---- calling the extension the way Godot does ---------------------------------------------- */

static const method_rec *find_method(const char *cls, const char *name) {
    int i;
    for (i = 0; i < method_count; i++)
        if (!strcmp(methods[i].cls, cls) && !strcmp(methods[i].name, name)) return &methods[i];
    return NULL;
}
static const class_rec *find_class(const char *cls) {
    int i;
    for (i = 0; i < class_count; i++)
        if (!strcmp(classes[i].cls, cls)) return &classes[i];
    return NULL;
}

static void *instance_of(GDExtensionObjectPtr o) {
    return ((fobject *)o)->instance;
}

static void ptrcall(GDExtensionObjectPtr o, const char *cls, const char *name, const void **args, void *ret) {
    const method_rec *m = find_method(cls, name);
    if (!m) {
        printf("no method %s.%s\n", cls, name);
        exit(2);
    }
    m->info.ptrcall_func(m->info.method_userdata, instance_of(o), (const GDExtensionConstTypePtr *)args, ret);
}

static GDExtensionCallError vcall(GDExtensionObjectPtr o, const char *cls, const char *name, fvariant *args, int argc, fvariant *ret) {
    const method_rec *m = find_method(cls, name);
    GDExtensionConstVariantPtr ptrs[4];
    GDExtensionCallError err;
    int i;
    if (!m) {
        printf("no method %s.%s\n", cls, name);
        exit(2);
    }
    for (i = 0; i < argc; i++) ptrs[i] = (GDExtensionConstVariantPtr)&args[i];
    memset(ret, 0, sizeof *ret);
    memset(&err, 0, sizeof err);
    m->info.call_func(m->info.method_userdata, instance_of(o), ptrs, argc, (GDExtensionVariantPtr)ret, &err);
    return err;
}

static fvariant vint(int64_t i) { fvariant v; memset(&v, 0, sizeof v); v.type = GDEXTENSION_VARIANT_TYPE_INT; v.u.i = i; return v; }
static fvariant vfloat(double f) { fvariant v; memset(&v, 0, sizeof v); v.type = GDEXTENSION_VARIANT_TYPE_FLOAT; v.u.f = f; return v; }
static fvariant vstr(int type, const char *s) { fvariant v; memset(&v, 0, sizeof v); v.type = type; v.u.s = dup(s); return v; }

static uint8_t *read_file(const char *path, long *size) {
    FILE *f = fopen(path, "rb");
    uint8_t *data;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    *size = ftell(f);
    fseek(f, 0, SEEK_SET);
    data = malloc((size_t)*size + 1);
    if (fread(data, 1, (size_t)*size, f) != (size_t)*size) *size = -1;
    fclose(f);
    return data;
}

typedef struct { int clip; float time; int flags; int rows; float pose[64][10]; } reference;

static int read_reference(FILE *f, reference *r) {
    char line[512];
    long pos;
    if (!fgets(line, sizeof line, f)) return 0;
    if (sscanf(line, "sample %d %f %d", &r->clip, &r->time, &r->flags) != 3) return 0;
    r->rows = 0;
    for (;;) {
        pos = ftell(f);
        if (!fgets(line, sizeof line, f)) break;
        if (!strncmp(line, "sample", 6)) {
            fseek(f, pos, SEEK_SET);
            break;
        }
        if (r->rows < 64) {
            float *p = r->pose[r->rows++];
            if (sscanf(line, "%f %f %f %f %f %f %f %f %f %f", &p[0], &p[1], &p[2], &p[3], &p[4], &p[5], &p[6], &p[7], &p[8], &p[9]) != 10)
                r->rows = -1000; /* not a row of 10: fails the record */
        }
    }
    return 1;
}

int main(int argc, char **argv) {
    void *lib;
    GDExtensionInitializationFunction entry;
    GDExtensionInitialization init;
    static const char *animation_methods[] = {"set_data", "get_data", "get_result", "get_version", "get_clip_count",
                                              "get_clip_name", "get_clip_duration", "find_clip", "get_node_count",
                                              "get_node_name", "sample", "get_pose_rotation", "get_pose_translation"};
    static const char *player_props[] = {"animation", "clip", "time", "speed", "playing", "loop", "contacts",
                                         "root_motion", "match_directions", "unit_scale"};
    GDExtensionObjectPtr anim, player_obj;
    const class_rec *anim_class, *player_class;
    uint8_t *asset;
    long asset_size;
    fbytes bytes;
    const void *args[3];
    int64_t i64;
    double f64;
    fvariant v[3], ret;
    GDExtensionCallError err;
    size_t k;
    int i;

    if (argc != 4) {
        fprintf(stderr, "usage: %s LIBRARY ASSET.mcd ASSET.poses.txt\n", argv[0]);
        return 2;
    }
    asset = read_file(argv[2], &asset_size);
    if (!asset || asset_size <= 0) {
        printf("cannot read %s\n", argv[2]);
        return 2;
    }

    begin("load and enter the library");
    lib = dlopen(argv[1], RTLD_NOW | RTLD_LOCAL);
    CHECK(lib != NULL, "dlopen: %s", dlerror());
    if (!lib) return 1;
    *(void **)&entry = dlsym(lib, "mocodec_gdextension_init");
    CHECK(entry != NULL, "entry symbol mocodec_gdextension_init not exported");
    if (!entry) return 1;
    memset(&init, 0, sizeof init);
    CHECK(entry(get_proc, (GDExtensionClassLibraryPtr)&init, &init) == 1, "entry returned false (missing %s)",
          requested_missing ? requested_missing : "?");
    CHECK(init.minimum_initialization_level == GDEXTENSION_INITIALIZATION_SCENE, "initialisation level");
    CHECK(init.initialize != NULL && init.deinitialize != NULL, "init callbacks");
    init.initialize(init.userdata, GDEXTENSION_INITIALIZATION_CORE);
    CHECK(class_count == 0, "nothing registered before the SCENE level");
    init.initialize(init.userdata, GDEXTENSION_INITIALIZATION_SERVERS);
    init.initialize(init.userdata, GDEXTENSION_INITIALIZATION_SCENE);
    finish();

    begin("classes registered");
    anim_class = find_class("MocodecAnimation");
    player_class = find_class("MocodecSkeletonModifier");
    CHECK(anim_class && !strcmp(anim_class->parent, "Resource"), "MocodecAnimation extends Resource");
    CHECK(player_class && !strcmp(player_class->parent, "SkeletonModifier3D"), "MocodecSkeletonModifier extends SkeletonModifier3D");
    if (!anim_class || !player_class) return 1;
    CHECK(anim_class->info.is_exposed && player_class->info.is_exposed, "exposed");
    CHECK(anim_class->info.create_instance_func && anim_class->info.free_instance_func, "animation constructor/destructor");
    CHECK(player_class->info.get_virtual_func != NULL, "player virtuals");
    {
        fstr process = {dup("_process_modification")}, with_delta = {dup("_process_modification_with_delta")},
             frame = {dup("_process")};
        CHECK(player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&process) != NULL, "_process_modification overridden");
        CHECK(player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&with_delta) != NULL,
              "_process_modification_with_delta (4.5+) overridden");
        CHECK(player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&frame) == NULL, "_process not claimed: no bones written per frame");
        free(process.s);
        free(with_delta.s);
        free(frame.s);
    }
    for (k = 0; k < sizeof animation_methods / sizeof animation_methods[0]; k++) {
        const method_rec *m = find_method("MocodecAnimation", animation_methods[k]);
        CHECK(m && m->info.call_func && m->info.ptrcall_func, "method MocodecAnimation.%s with call and ptrcall", animation_methods[k]);
    }
    for (k = 0; k < sizeof player_props / sizeof player_props[0]; k++) {
        const property_rec *p = NULL;
        for (i = 0; i < property_count; i++)
            if (!strcmp(properties[i].cls, "MocodecSkeletonModifier") && !strcmp(properties[i].name, player_props[k])) p = &properties[i];
        CHECK(p && find_method(p->cls, p->setter) && find_method(p->cls, p->getter), "property %s with registered accessors", player_props[k]);
        if (p && !strcmp(p->name, "animation"))
            CHECK(p->type == GDEXTENSION_VARIANT_TYPE_OBJECT && !strcmp(p->hint_string, "MocodecAnimation"), "animation property typed");
    }
    CHECK(binds_requested == BIND_COUNT - 1, "engine methods resolved by class, name and hash (%d of %d)", binds_requested, BIND_COUNT - 1);
    {
        const property_rec *data = NULL;
        for (i = 0; i < property_count; i++)
            if (!strcmp(properties[i].cls, "MocodecAnimation") && !strcmp(properties[i].name, "data")) data = &properties[i];
        /* what ResourceSaver writes: the import plugin's .res keeps the bytes */
        CHECK(data && data->type == GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY && data->usage == PROPERTY_USAGE_STORAGE_VALUE,
              "MocodecAnimation.data is a stored PackedByteArray");
    }
    CHECK(requested_size_hash != 0, "PackedByteArray.size hash");
    {
        const method_rec *m = find_method("MocodecAnimation", "sample");
        CHECK(m && m->info.argument_count == 3 && m->arg_types[0] == GDEXTENSION_VARIANT_TYPE_INT &&
                  m->arg_types[1] == GDEXTENSION_VARIANT_TYPE_FLOAT && m->ret_type == GDEXTENSION_VARIANT_TYPE_INT,
              "sample(int, float, int) -> int");
    }
    finish();

    begin("MocodecAnimation replays the reference poses");
    anim = anim_class->info.create_instance_func(anim_class->info.class_userdata);
    bytes.data = asset;
    bytes.size = asset_size;
    args[0] = &bytes;
    ptrcall(anim, "MocodecAnimation", "set_data", args, NULL);
    err = vcall(anim, "MocodecAnimation", "get_result", v, 0, &ret);
    CHECK(err.error == GDEXTENSION_CALL_OK && ret.type == GDEXTENSION_VARIANT_TYPE_INT && ret.u.i == 0, "get_result after set_data: %lld", (long long)ret.u.i);
    ptrcall(anim, "MocodecAnimation", "get_clip_count", args, &i64);
    CHECK(i64 >= 1, "clip count %lld", (long long)i64);
    {
        FILE *f = fopen(argv[3], "r");
        static reference r;
        int records = 0;
        CHECK(f != NULL, "reference poses %s", argv[3]);
        while (f && read_reference(f, &r) && !case_failed) {
            int n;
            v[0] = vint(r.clip);
            v[1] = vfloat(r.time);
            v[2] = vint(r.flags);
            err = vcall(anim, "MocodecAnimation", "sample", v, 3, &ret);
            CHECK(err.error == GDEXTENSION_CALL_OK && ret.u.i == 0, "sample(%d, %g, %d) -> %lld", r.clip, r.time, r.flags, (long long)ret.u.i);
            for (n = 0; n < r.rows; n++) {
                float q[4];
                int64_t node = n;
                int c;
                args[0] = &node;
                float sc[3];
                ptrcall(anim, "MocodecAnimation", "get_pose_rotation", args, q);
                ptrcall(anim, "MocodecAnimation", "get_pose_scale", args, sc);
                v[0] = vint(n);
                vcall(anim, "MocodecAnimation", "get_pose_translation", v, 1, &ret);
                for (c = 0; c < 4; c++) CHECK(fabs(q[c] - r.pose[n][c]) <= 1e-5, "clip %d t=%g node %d rotation[%d]", r.clip, r.time, n, c);
                for (c = 0; c < 3; c++) CHECK(fabs(ret.u.v[c] - r.pose[n][4 + c]) <= 1e-5, "clip %d t=%g node %d translation[%d]", r.clip, r.time, n, c);
                for (c = 0; c < 3; c++) CHECK(fabs(sc[c] - r.pose[n][7 + c]) <= 1e-5, "clip %d t=%g node %d scale[%d]", r.clip, r.time, n, c);
            }
            records++;
        }
        if (f) fclose(f);
        CHECK(records > 0, "reference records read");
    }
    finish();

    begin("queries and dynamic-call type checks");
    {
        fstr name;
        int64_t clip = 0;
        args[0] = &clip;
        ptrcall(anim, "MocodecAnimation", "get_clip_name", args, &name);
        v[0] = vstr(GDEXTENSION_VARIANT_TYPE_STRING, name.s);
        vcall(anim, "MocodecAnimation", "find_clip", v, 1, &ret);
        CHECK(ret.u.i == 0, "find_clip(get_clip_name(0)) == 0");
        variant_clear(&v[0]);
        free(name.s);
        v[0] = vstr(GDEXTENSION_VARIANT_TYPE_STRING, "no such clip");
        vcall(anim, "MocodecAnimation", "find_clip", v, 1, &ret);
        CHECK(ret.u.i == -1, "unknown clip -> -1");
        variant_clear(&v[0]);
        v[0] = vstr(GDEXTENSION_VARIANT_TYPE_STRING, "0");
        v[1] = vint(0);
        v[2] = vint(0);
        err = vcall(anim, "MocodecAnimation", "sample", v, 3, &ret);
        CHECK(err.error == GDEXTENSION_CALL_ERROR_INVALID_ARGUMENT && err.argument == 0, "a String for an int is refused");
        variant_clear(&v[0]);
        v[0] = vint(0);
        err = vcall(anim, "MocodecAnimation", "sample", v, 2, &ret);
        CHECK(err.error == GDEXTENSION_CALL_ERROR_TOO_FEW_ARGUMENTS, "too few arguments");
        v[1] = vint(0); /* an int where a float is due is accepted, as GDScript passes 0 */
        err = vcall(anim, "MocodecAnimation", "sample", v, 3, &ret);
        CHECK(err.error == GDEXTENSION_CALL_OK && ret.u.i == 0, "int accepted for float");
        v[0] = vint(1 << 20);
        v[1] = vfloat(0);
        vcall(anim, "MocodecAnimation", "sample", v, 3, &ret);
        CHECK(ret.u.i == 10, "clip out of range -> MCD_ERROR_OUT_OF_RANGE (%lld)", (long long)ret.u.i);
        vcall(anim, "MocodecAnimation", "get_version", v, 0, &ret);
        CHECK((ret.u.i >> 8) == 0x0003, "mcd_version 0.3.x (%llx)", (long long)ret.u.i);
        vcall(anim, "MocodecAnimation", "get_data", v, 0, &ret);
        CHECK(ret.type == GDEXTENSION_VARIANT_TYPE_PACKED_BYTE_ARRAY && ret.u.bytes.size == asset_size &&
                  !memcmp(ret.u.bytes.data, asset, (size_t)asset_size), "data property round-trips");
        variant_clear(&ret);
    }
    finish();

    begin("bad bytes give the runtime's codes");
    bytes.size = asset_size - 16;
    args[0] = &bytes;
    ptrcall(anim, "MocodecAnimation", "set_data", args, NULL);
    ptrcall(anim, "MocodecAnimation", "get_result", args, &i64);
    CHECK(i64 == 2, "truncated -> MCD_ERROR_TRUNCATED (%lld)", (long long)i64);
    ptrcall(anim, "MocodecAnimation", "get_clip_count", args, &i64);
    CHECK(i64 == 0, "no clips after a failed load");
    bytes.size = 0;
    ptrcall(anim, "MocodecAnimation", "set_data", args, NULL);
    ptrcall(anim, "MocodecAnimation", "get_result", args, &i64);
    CHECK(i64 == 2, "empty -> MCD_ERROR_TRUNCATED (%lld)", (long long)i64);
    asset[1] ^= 0x20;
    bytes.size = asset_size;
    ptrcall(anim, "MocodecAnimation", "set_data", args, NULL);
    ptrcall(anim, "MocodecAnimation", "get_result", args, &i64);
    CHECK(i64 == 3, "bad magic -> MCD_ERROR_BAD_MAGIC (%lld)", (long long)i64);
    asset[1] ^= 0x20;
    ptrcall(anim, "MocodecAnimation", "set_data", args, NULL);
    ptrcall(anim, "MocodecAnimation", "get_result", args, &i64);
    CHECK(i64 == 0, "the original loads again");
    finish();

    begin("MocodecSkeletonModifier retargets onto a Skeleton3D with its own rests");
    {
        int64_t skel = 0, count, clip = 0, n, virtual_count = 0;
        double cm, metres;
        uint8_t no = 0, yes = 1;
        GDExtensionClassCallVirtual process, process_delta_fn;
        fstr process_name = {dup("_process_modification")}, delta_name = {dup("_process_modification_with_delta")};
        static float world[64][10];
        static dq rest_rot[64], rig_rot[64];
        static double rest_pos[64][3], rig_pos[64][3];
        static int64_t kinds[64];
        uint32_t seed = 99;
        args[0] = &clip;
        ptrcall(anim, "MocodecAnimation", "get_clip_skeleton", args, &skel);
        args[0] = &skel;
        ptrcall(anim, "MocodecAnimation", "get_node_count", args, &count);
        ptrcall(anim, "MocodecAnimation", "get_cm_per_unit", args, &cm);
        metres = cm * 0.01;
        skeleton_object = new_object("Skeleton3D");
        /* bones as the asset's nodes, names in capitals, each with a rest rotation of its own
         * (the node's world rest turned at random) and the rest shape in metres; one more bone,
         * "Prop", that nothing drives */
        skeleton_object->bone_count = (int)count + 1;
        for (n = 0; n < count && n < 63; n++) {
            fstr name;
            int64_t a2[2], parent, kind;
            float rq[4], rt[3];
            double t[3], v[3], u;
            char *ch;
            dq turn, local;
            int k;
            a2[0] = skel;
            a2[1] = n;
            args[0] = &a2[0];
            args[1] = &a2[1];
            ptrcall(anim, "MocodecAnimation", "get_node_name", args, &name);
            for (ch = name.s; *ch; ch++)
                if (*ch >= 'a' && *ch <= 'z') *ch = (char)(*ch - 'a' + 'A');
            snprintf(skeleton_object->bone_names[n], 64, "%s", name.s);
            free(name.s);
            ptrcall(anim, "MocodecAnimation", "get_node_parent", args, &parent);
            ptrcall(anim, "MocodecAnimation", "get_node_kind", args, &kind);
            ptrcall(anim, "MocodecAnimation", "get_node_rest_rotation", args, rq);
            ptrcall(anim, "MocodecAnimation", "get_node_rest_translation", args, rt);
            virtual_count += kind == 2;
            kinds[n] = kind;
            skeleton_object->bone_parent[n] = parent;
            for (k = 0; k < 3; k++) t[k] = rt[k];
            if (parent < 0) {
                rest_rot[n] = q_of(rq);
                for (k = 0; k < 3; k++) rest_pos[n][k] = t[k];
            } else {
                q_rot(rest_rot[parent], t, v);
                rest_rot[n] = q_mul(rest_rot[parent], q_of(rq));
                for (k = 0; k < 3; k++) rest_pos[n][k] = rest_pos[parent][k] + v[k];
            }
            seed = seed * 1664525u + 1013904223u;
            u = (seed >> 8) / 16777216.0;
            turn.x = sin(0.2 + 1.3 * u) * 0.6, turn.y = sin(0.2 + 1.3 * u) * 0.8, turn.z = 0, turn.w = cos(0.2 + 1.3 * u);
            rig_rot[n] = q_mul(rest_rot[n], turn);
            for (k = 0; k < 3; k++) rig_pos[n][k] = rest_pos[n][k] * metres;
            if (parent < 0) {
                local = rig_rot[n];
                for (k = 0; k < 3; k++) v[k] = rig_pos[n][k];
            } else {
                double d[3];
                local = q_mul(q_conj(rig_rot[parent]), rig_rot[n]);
                for (k = 0; k < 3; k++) d[k] = rig_pos[n][k] - rig_pos[parent][k];
                q_rot(q_conj(rig_rot[parent]), d, v);
            }
            q_rows(local, (float(*)[3])skeleton_object->bone_rest[n]);
            for (k = 0; k < 3; k++) skeleton_object->bone_rest[n][9 + k] = (float)v[k];
        }
        snprintf(skeleton_object->bone_names[count], 64, "%s", "Prop");
        skeleton_object->bone_parent[count] = 0;
        skeleton_object->bone_rest[count][0] = skeleton_object->bone_rest[count][4] = skeleton_object->bone_rest[count][8] = 1;
        player_obj = player_class->info.create_instance_func(player_class->info.class_userdata);
        CHECK(!strcmp(((fobject *)player_obj)->base_class, "SkeletonModifier3D"), "the instance's engine object is a SkeletonModifier3D");
        args[0] = &anim; /* a Ref<MocodecAnimation> through ptrcall */
        ptrcall(player_obj, "MocodecSkeletonModifier", "set_animation", args, NULL);
        f64 = 0.4;
        args[0] = &f64;
        ptrcall(player_obj, "MocodecSkeletonModifier", "set_time", args, NULL);
        args[0] = &no;
        ptrcall(player_obj, "MocodecSkeletonModifier", "set_playing", args, NULL);
        {
            GDExtensionObjectPtr got = NULL;
            ptrcall(player_obj, "MocodecSkeletonModifier", "get_animation", args, &got);
            CHECK(got == anim, "get_animation returns the resource");
        }
        process = player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&process_name);
        process_delta_fn = player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&delta_name);
        free(process_name.s);
        free(delta_name.s);
        f64 = 0.0;
        args[0] = &f64;
        process_delta_fn(instance_of(player_obj), (const GDExtensionConstTypePtr *)args, NULL);
        /* expected: every joint where the world sample at 0.4 s puts it, in metres */
        v[0] = vint(0);
        v[1] = vfloat(0.4);
        v[2] = vint(1 | 2 | 8); /* world; the modifier loops and applies contact IK by default */
        vcall(anim, "MocodecAnimation", "sample", v, 3, &ret);
        for (n = 0; n < count; n++) {
            int64_t node = n;
            args[0] = &node;
            ptrcall(anim, "MocodecAnimation", "get_pose_translation", args, &world[n][4]);
        }
        {
            static dq wr[64];
            static double wp[64][3];
            double worst = 0;
            for (n = 0; n < count && !case_failed; n++) {
                int64_t parent = skeleton_object->bone_parent[n];
                double t[3], vv[3], d = 0;
                int c, written = skeleton_object->rotation_set[n];
                CHECK(written == (kinds[n] == 2 ? 0 : 1), "bone %d written %d times (virtual points match no bone name)", (int)n, written);
                for (c = 0; c < 3; c++) t[c] = skeleton_object->position[n][c];
                if (!written) { /* a virtual point: at its rest */
                    for (c = 0; c < 3; c++) t[c] = skeleton_object->bone_rest[n][9 + c];
                }
                if (parent < 0) {
                    wr[n] = q_of(skeleton_object->rotation[n]);
                    for (c = 0; c < 3; c++) wp[n][c] = t[c];
                } else {
                    dq local = written ? q_of(skeleton_object->rotation[n]) : q_mul(q_conj(rig_rot[parent]), rig_rot[n]);
                    q_rot(wr[parent], t, vv);
                    wr[n] = q_mul(wr[parent], local);
                    for (c = 0; c < 3; c++) wp[n][c] = wp[parent][c] + vv[c];
                }
                for (c = 0; c < 3; c++) d += (wp[n][c] - world[n][4 + c] * metres) * (wp[n][c] - world[n][4 + c] * metres);
                d = sqrt(d);
                if (d > worst) worst = d;
                CHECK(d <= 1e-5, "bone %s is %g m from the world sample", skeleton_object->bone_names[n], d);
                if (written) CHECK(fabs(skeleton_object->scale[n][1] - 1.0f) < 1e-5 && skeleton_object->scale_set[n] == 1, "bone %d scale", (int)n);
            }
            printf("  retargeted joints within %.2g m of the world sample\n", worst);
        }
        CHECK(skeleton_object->rotation_set[count] == 0 && skeleton_object->position_set[count] == 0,
              "the bone no node drives (Prop) keeps what the mixer gave it");
        {
            int64_t bone = 1, node = -5;
            args[0] = &bone;
            ptrcall(player_obj, "MocodecSkeletonModifier", "get_bone_node", args, &node);
            CHECK(node == 1, "get_bone_node(1) = %lld", (long long)node);
            bone = count;
            ptrcall(player_obj, "MocodecSkeletonModifier", "get_bone_node", args, &node);
            CHECK(node == -1, "Prop is driven by no node");
        }
        /* playing: the 4.3 entry point takes the frame's delta from the node */
        args[0] = &yes;
        ptrcall(player_obj, "MocodecSkeletonModifier", "set_playing", args, NULL);
        process(instance_of(player_obj), NULL, NULL);
        ptrcall(player_obj, "MocodecSkeletonModifier", "get_time", args, &f64);
        CHECK(fabs(f64 - 0.65) < 1e-9, "time advanced by get_process_delta_time to %g", f64);
        CHECK(skeleton_object->rotation_set[0] == 2, "second pass written");
    }
    finish();

    begin("teardown frees everything");
    player_class->info.free_instance_func(player_class->info.class_userdata, instance_of(player_obj));
    anim_class->info.free_instance_func(anim_class->info.class_userdata, instance_of(anim));
    init.deinitialize(init.userdata, GDEXTENSION_INITIALIZATION_SCENE);
    CHECK(classes[0].unregistered && classes[1].unregistered, "classes unregistered");
    CHECK(live_allocations == 0, "%ld mem_alloc blocks not freed", live_allocations);
    finish();

    printf("gdextension tests ran in a stand-in host (not Godot): %ld engine error prints expected from the bad-input cases\n",
           error_prints);
    printf("gdextension: %d passed, %d failed\n", passed, failed);
    dlclose(lib);
    return failed ? 1 : 0;
}
