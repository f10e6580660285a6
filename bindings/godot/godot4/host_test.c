/*
 * A stand-in for the Godot 4 engine, enough to load the GDExtension the way Godot does and
 * drive it: dlopen, the entry point, initialisation at the SCENE level, then the registered
 * classes are checked and their methods called through both entry points Godot uses
 * (Variant call and ptrcall). Engine values are modelled simply (strings as char*, byte
 * arrays as pointer + size, a Skeleton3D as arrays of bone names and poses); what this checks
 * is the extension's side of the contract: registration, argument and result marshalling,
 * sampling against the reference poses, driving bones by name, and that every byte it
 * allocated through mem_alloc is freed. It cannot check Godot's own behaviour.
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
    float rotation[64][4];
    float position[64][3];
    int rotation_set[64], position_set[64];
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

enum bind_id { BIND_FIND_BONE = 1, BIND_SET_ROTATION, BIND_SET_POSITION, BIND_GET_NODE };
static const int bind_ids[] = {0, BIND_FIND_BONE, BIND_SET_ROTATION, BIND_SET_POSITION, BIND_GET_NODE};
static int binds_requested;
static GDExtensionMethodBindPtr f_get_method_bind(GDExtensionConstStringNamePtr c, GDExtensionConstStringNamePtr m, GDExtensionInt hash) {
    const char *cls = ((const fstr *)c)->s, *met = ((const fstr *)m)->s;
    int id = 0;
    if (!strcmp(cls, "Skeleton3D") && !strcmp(met, "find_bone")) id = BIND_FIND_BONE;
    if (!strcmp(cls, "Skeleton3D") && !strcmp(met, "set_bone_pose_rotation")) id = BIND_SET_ROTATION;
    if (!strcmp(cls, "Skeleton3D") && !strcmp(met, "set_bone_pose_position")) id = BIND_SET_POSITION;
    if (!strcmp(cls, "Node") && !strcmp(met, "get_node_or_null")) id = BIND_GET_NODE;
    if (!id || hash == 0) return NULL;
    binds_requested++;
    return (GDExtensionMethodBindPtr)&bind_ids[id];
}
static void f_bind_ptrcall(GDExtensionMethodBindPtr b, GDExtensionObjectPtr o, const GDExtensionConstTypePtr *args, GDExtensionTypePtr ret) {
    fobject *ob = (fobject *)o;
    int64_t bone;
    int i;
    switch (*(const int *)b) {
    case BIND_FIND_BONE:
        *(int64_t *)ret = -1;
        for (i = 0; i < ob->bone_count; i++)
            if (!strcmp(ob->bone_names[i], ((const fstr *)args[0])->s)) *(int64_t *)ret = i;
        break;
    case BIND_SET_ROTATION:
        bone = *(const int64_t *)args[0];
        memcpy(ob->rotation[bone], args[1], 16);
        ob->rotation_set[bone]++;
        break;
    case BIND_SET_POSITION:
        bone = *(const int64_t *)args[0];
        memcpy(ob->position[bone], args[1], 12);
        ob->position_set[bone]++;
        break;
    case BIND_GET_NODE:
        *(GDExtensionObjectPtr *)ret = !strcmp(((const fstr *)args[0])->s, "Skeleton") ? (GDExtensionObjectPtr)skeleton_object : NULL;
        break;
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
} property_rec;

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

typedef struct { int clip; float time; int flags; int rows; float pose[64][7]; } reference;

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
            sscanf(line, "%f %f %f %f %f %f %f", &p[0], &p[1], &p[2], &p[3], &p[4], &p[5], &p[6]);
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
    static const char *player_props[] = {"animation", "skeleton", "clip", "time", "speed", "playing", "loop", "contacts"};
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
    player_class = find_class("MocodecSkeletonPlayer");
    CHECK(anim_class && !strcmp(anim_class->parent, "Resource"), "MocodecAnimation extends Resource");
    CHECK(player_class && !strcmp(player_class->parent, "Node"), "MocodecSkeletonPlayer extends Node");
    if (!anim_class || !player_class) return 1;
    CHECK(anim_class->info.is_exposed && player_class->info.is_exposed, "exposed");
    CHECK(anim_class->info.create_instance_func && anim_class->info.free_instance_func, "animation constructor/destructor");
    CHECK(player_class->info.get_virtual_func != NULL, "player virtuals");
    {
        fstr process = {dup("_process")}, ready = {dup("_ready")};
        CHECK(player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&process) != NULL, "_process overridden");
        CHECK(player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&ready) == NULL, "_ready not claimed");
        free(process.s);
        free(ready.s);
    }
    for (k = 0; k < sizeof animation_methods / sizeof animation_methods[0]; k++) {
        const method_rec *m = find_method("MocodecAnimation", animation_methods[k]);
        CHECK(m && m->info.call_func && m->info.ptrcall_func, "method MocodecAnimation.%s with call and ptrcall", animation_methods[k]);
    }
    for (k = 0; k < sizeof player_props / sizeof player_props[0]; k++) {
        const property_rec *p = NULL;
        for (i = 0; i < property_count; i++)
            if (!strcmp(properties[i].cls, "MocodecSkeletonPlayer") && !strcmp(properties[i].name, player_props[k])) p = &properties[i];
        CHECK(p && find_method(p->cls, p->setter) && find_method(p->cls, p->getter), "property %s with registered accessors", player_props[k]);
        if (p && !strcmp(p->name, "animation"))
            CHECK(p->type == GDEXTENSION_VARIANT_TYPE_OBJECT && !strcmp(p->hint_string, "MocodecAnimation"), "animation property typed");
    }
    CHECK(binds_requested == 4, "engine methods resolved by class, name and hash (%d of 4)", binds_requested);
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
                ptrcall(anim, "MocodecAnimation", "get_pose_rotation", args, q);
                v[0] = vint(n);
                vcall(anim, "MocodecAnimation", "get_pose_translation", v, 1, &ret);
                for (c = 0; c < 4; c++) CHECK(fabs(q[c] - r.pose[n][c]) <= 1e-5, "clip %d t=%g node %d rotation[%d]", r.clip, r.time, n, c);
                for (c = 0; c < 3; c++) CHECK(fabs(ret.u.v[c] - r.pose[n][4 + c]) <= 1e-5, "clip %d t=%g node %d translation[%d]", r.clip, r.time, n, c);
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
        CHECK((ret.u.i >> 8) == 0x0001, "mcd_version 0.1.x (%llx)", (long long)ret.u.i);
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

    begin("MocodecSkeletonPlayer drives Skeleton3D bones by name");
    {
        int64_t skel = 0, count, clip = 0, n;
        double cm;
        uint8_t no = 0, yes = 1;
        GDExtensionClassCallVirtual process;
        fstr process_name = {dup("_process")};
        static reference expect;
        float local[64][7];
        args[0] = &clip;
        ptrcall(anim, "MocodecAnimation", "get_clip_skeleton", args, &skel);
        args[0] = &skel;
        ptrcall(anim, "MocodecAnimation", "get_node_count", args, &count);
        ptrcall(anim, "MocodecAnimation", "get_cm_per_unit", args, &cm);
        skeleton_object = new_object("Skeleton3D");
        /* bones in reverse order, so a name lookup is needed to get them right */
        skeleton_object->bone_count = (int)count;
        for (n = 0; n < count; n++) {
            fstr name;
            int64_t a2[2];
            a2[0] = skel;
            a2[1] = n;
            args[0] = &a2[0];
            args[1] = &a2[1];
            ptrcall(anim, "MocodecAnimation", "get_node_name", args, &name);
            snprintf(skeleton_object->bone_names[count - 1 - n], 64, "%s", name.s);
            free(name.s);
        }
        player_obj = player_class->info.create_instance_func(player_class->info.class_userdata);
        args[0] = &anim; /* a Ref<MocodecAnimation> through ptrcall */
        ptrcall(player_obj, "MocodecSkeletonPlayer", "set_animation", args, NULL);
        v[0] = vstr(GDEXTENSION_VARIANT_TYPE_NODE_PATH, "Skeleton");
        err = vcall(player_obj, "MocodecSkeletonPlayer", "set_skeleton", v, 1, &ret);
        CHECK(err.error == GDEXTENSION_CALL_OK, "set_skeleton");
        variant_clear(&v[0]);
        f64 = 0.4;
        args[0] = &f64;
        ptrcall(player_obj, "MocodecSkeletonPlayer", "set_time", args, NULL);
        args[0] = &no;
        ptrcall(player_obj, "MocodecSkeletonPlayer", "set_playing", args, NULL);
        {
            GDExtensionObjectPtr got = NULL;
            ptrcall(player_obj, "MocodecSkeletonPlayer", "get_animation", args, &got);
            CHECK(got == anim, "get_animation returns the resource");
        }
        process = player_class->info.get_virtual_func(NULL, (GDExtensionConstStringNamePtr)&process_name);
        free(process_name.s);
        f64 = 0.0;
        args[0] = &f64;
        process(instance_of(player_obj), (const GDExtensionConstTypePtr *)args, NULL);
        /* expected: the local pose at 0.4 s, translations in metres */
        v[0] = vint(0);
        v[1] = vfloat(0.4);
        v[2] = vint(2 | 8); /* the player loops and applies contact IK by default */
        vcall(anim, "MocodecAnimation", "sample", v, 3, &ret);
        for (n = 0; n < count; n++) {
            int64_t node = n;
            args[0] = &node;
            ptrcall(anim, "MocodecAnimation", "get_pose_rotation", args, local[n]);
            ptrcall(anim, "MocodecAnimation", "get_pose_translation", args, &local[n][4]);
        }
        for (n = 0; n < count && !case_failed; n++) {
            int b = (int)(count - 1 - n), c;
            CHECK(skeleton_object->rotation_set[b] == 1 && skeleton_object->position_set[b] == 1, "bone %d written once", b);
            for (c = 0; c < 4; c++) CHECK(fabs(skeleton_object->rotation[b][c] - local[n][c]) <= 1e-6, "node %d rotation", (int)n);
            for (c = 0; c < 3; c++)
                CHECK(fabs(skeleton_object->position[b][c] - local[n][4 + c] * cm * 0.01) <= 1e-5, "node %d position (metres)", (int)n);
        }
        /* playing: time advances by delta * speed */
        args[0] = &yes;
        ptrcall(player_obj, "MocodecSkeletonPlayer", "set_playing", args, NULL);
        f64 = 0.25;
        args[0] = &f64;
        process(instance_of(player_obj), (const GDExtensionConstTypePtr *)args, NULL);
        ptrcall(player_obj, "MocodecSkeletonPlayer", "get_time", args, &f64);
        CHECK(fabs(f64 - 0.65) < 1e-9, "time advanced to %g", f64);
        CHECK(skeleton_object->rotation_set[0] == 2, "second frame written");
        (void)expect;
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
