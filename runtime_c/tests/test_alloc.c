/* The runtime promises no allocation. This test counts calls into the C allocator across every
 * entry point, with the linker routing malloc & co. through the wrappers below
 * (-Wl,--wrap=malloc ...; the build defines MCD_TEST_WRAP_MALLOC when it links that way).
 * Under ASan the allocator is intercepted by the sanitizer runtime, so the test skips there. */
#define _POSIX_C_SOURCE 200809L

#include <stdlib.h>
#include <string.h>

#include "harness.h"

#if defined(__SANITIZE_ADDRESS__)
#define MCD_TEST_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define MCD_TEST_UNDER_ASAN 1
#endif
#endif

#if defined(MCD_TEST_WRAP_MALLOC) && !defined(MCD_TEST_UNDER_ASAN)

/* volatile: compilers assume malloc leaves user globals alone and would fold the counts. */
static volatile unsigned long g_allocator_calls;

void* __real_malloc(size_t n);
void* __real_calloc(size_t n, size_t size);
void* __real_realloc(void* p, size_t n);
void __real_free(void* p);
void* __wrap_malloc(size_t n);
void* __wrap_calloc(size_t n, size_t size);
void* __wrap_realloc(void* p, size_t n);
void __wrap_free(void* p);

void* __wrap_malloc(size_t n) {
    g_allocator_calls++;
    return __real_malloc(n);
}
void* __wrap_calloc(size_t n, size_t size) {
    g_allocator_calls++;
    return __real_calloc(n, size);
}
void* __wrap_realloc(void* p, size_t n) {
    g_allocator_calls++;
    return __real_realloc(p, n);
}
void __wrap_free(void* p) {
    g_allocator_calls++;
    __real_free(p);
}

void test_no_allocation(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    unsigned long before;
    /* The wrappers must be live, or the counts below would prove nothing. */
    {
        /* volatile again, or the unused malloc/free pair is deleted */
        void* volatile probe;
        before = g_allocator_calls;
        probe = malloc(16);
        free(probe);
        CHECK(g_allocator_calls == before + 2u);
    }
    for (i = 0; i < n; ++i) {
        const mcd_test_file* f = &g[i].file;
        mcd_asset a;
        mcd_clip_info ci;
        mcd_node_info ni;
        mcd_transform* pose = (mcd_transform*)malloc(1024 * sizeof *pose);
        void* scratch = NULL;
        size_t size;
        uint32_t c, flags, k, found;
        /* Everything the caller provides is allocated before the counting starts. */
        if (!pose || posix_memalign(&scratch, 16, 1u << 20) != 0) {
            FAIL("out of memory");
            free(scratch);
            free(pose);
            break;
        }
        before = g_allocator_calls;
        CHECK_RESULT(mcd_validate(f->data, f->size, 0), MCD_OK);
        CHECK_RESULT(mcd_open(f->data, f->size, MCD_OPEN_PREVALIDATED, &a), MCD_OK);
        CHECK_RESULT(mcd_open(f->data, f->size, 0, &a), MCD_OK);
        size = mcd_scratch_size(&a);
        CHECK(size <= (1u << 20));
        CHECK_RESULT(mcd_scratch_init(&a, scratch, size), MCD_OK);
        for (c = 0; c < mcd_clip_count(&a) && mcd_test_failures() == 0; ++c) {
            CHECK_RESULT(mcd_get_clip_info(&a, c, &ci), MCD_OK);
            CHECK_RESULT(mcd_find_clip(&a, ci.name, &found), MCD_OK);
            CHECK_RESULT(mcd_get_node_info(&a, ci.skeleton, 0, &ni), MCD_OK);
            /* Half the clips on the asset's scratch, half on one of the clip's own size. */
            CHECK_RESULT(mcd_scratch_init(&a, scratch, c % 2u ? ci.scratch_size : size), MCD_OK);
            for (flags = 0; flags < 16u; ++flags) /* every flag combination, contacts too */
                for (k = 0; k < 2u * ci.frame_count; k += 3u)
                    CHECK_RESULT(mcd_sample(&a, c, (float)k * 0.5f / ci.frame_rate - 0.1f, flags, pose, 1024, scratch), MCD_OK);
        }
        CHECK_MSG(g_allocator_calls == before, "%s: %lu allocator calls inside the runtime", f->path,
                  g_allocator_calls - before);
        /* retargeting skeleton 0 onto itself: init and pose */
        {
            mcd_skeleton_info si;
            mcd_rig_bone* bones;
            mcd_retarget_config cfg;
            mcd_retarget_info info;
            mcd_transform* rig_pose;
            void *map, *work;
            size_t map_size = 0;
            uint32_t j;
            mcd_get_skeleton_info(&a, 0, &si);
            mcd_retarget_size(&a, 0, si.node_count, &map_size);
            /* the caller's buffers, outside the count */
            bones = (mcd_rig_bone*)malloc(si.node_count * sizeof *bones);
            rig_pose = (mcd_transform*)malloc(si.node_count * sizeof *rig_pose);
            map = malloc(map_size);
            work = malloc(si.node_count * 2u * 256u);
            before = g_allocator_calls;
            for (j = 0; j < si.node_count && bones; ++j) {
                mcd_get_node_info(&a, 0, j, &ni);
                bones[j].name = ni.name;
                bones[j].parent = ni.parent;
                bones[j].flags = 0;
                memcpy(bones[j].rest.rotation, ni.rest_rotation, sizeof ni.rest_rotation);
                memcpy(bones[j].rest.translation, ni.rest_translation, sizeof ni.rest_translation);
                memcpy(bones[j].rest.scale, ni.rest_scale, sizeof ni.rest_scale);
            }
            mcd_retarget_config_default(&cfg);
            CHECK_RESULT(mcd_scratch_init(&a, scratch, size), MCD_OK);
            CHECK_RESULT(mcd_retarget_init(&a, 0, bones, si.node_count, NULL, 0, &cfg, map, map_size, NULL), MCD_OK);
            CHECK_RESULT(mcd_retarget_get_info(map, &info), MCD_OK);
            CHECK(info.work_size <= si.node_count * 2u * 256u);
            for (k = 0; k < 8u; ++k) {
                CHECK_RESULT(mcd_sample(&a, 0, 0.1f * (float)k, 0, pose, 1024, scratch), MCD_OK);
                CHECK_RESULT(mcd_retarget_pose(map, pose, si.node_count, rig_pose, si.node_count, work, info.work_size), MCD_OK);
            }
            CHECK_MSG(g_allocator_calls == before, "%s: %lu allocator calls inside retargeting", f->path, g_allocator_calls - before);
            free(bones);
            free(rig_pose);
            free(map);
            free(work);
            before = g_allocator_calls;
        }
        CHECK_RESULT(mcd_validate(f->data, f->size - 1u, 0), MCD_ERROR_TRUNCATED); /* error paths too */
        CHECK_MSG(g_allocator_calls == before, "%s: %lu allocator calls inside the runtime", f->path,
                  g_allocator_calls - before);
        free(scratch);
        free(pose);
    }
    mcd_test_free_golden(g, n);
}

#else

void test_no_allocation(void) {
#if defined(MCD_TEST_UNDER_ASAN)
    mcd_test_skip("ASan intercepts malloc, so the allocator cannot be wrapped");
#else
    mcd_test_skip("built without -Wl,--wrap=malloc (MCD_TEST_WRAP_MALLOC)");
#endif
}

#endif
