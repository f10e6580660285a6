/* One check per invalid argument of every entry point (mocodec.h documents each failure). */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

static void check_result_strings(void) {
    int r, k;
    for (r = MCD_OK; r <= MCD_ERROR_NOT_FOUND; ++r) {
        const char* s = mcd_result_string((mcd_result)r);
        CHECK(s != NULL && s[0] != 0);
        for (k = MCD_OK; k < r; ++k) CHECK(strcmp(s, mcd_result_string((mcd_result)k)) != 0);
    }
    CHECK(mcd_result_string((mcd_result)999) != NULL);
    CHECK(mcd_version() == (uint32_t)MCD_VERSION);
}

static void check_validate_open(const mcd_test_file* f) {
    mcd_asset a;
    CHECK_RESULT(mcd_validate(NULL, f->size, 0), MCD_ERROR_INVALID_ARGUMENT);
    /* MCD_OPEN_PREVALIDATED is an mcd_open flag: mcd_validate does not take it. */
    CHECK_RESULT(mcd_validate(f->data, f->size, MCD_OPEN_PREVALIDATED), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_validate(f->data, f->size, 0x4u), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_validate(f->data, f->size, 0x80000000u), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(NULL, f->size, 0, &a), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(NULL, f->size, MCD_OPEN_PREVALIDATED, &a), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(f->data, f->size, 0, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(f->data, f->size, MCD_OPEN_PREVALIDATED, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(f->data, f->size, 0x4u, &a), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(f->data, f->size, 0x80000000u | MCD_OPEN_PREVALIDATED, &a), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(f->data, f->size, 0, &a), MCD_OK);
    CHECK_RESULT(mcd_open(f->data, f->size, MCD_VALIDATE_SKIP_CHECKSUM, &a), MCD_OK);
    CHECK_RESULT(mcd_open(f->data, f->size, MCD_OPEN_PREVALIDATED, &a), MCD_OK);
    CHECK_RESULT(mcd_open(f->data, f->size, MCD_OPEN_PREVALIDATED | MCD_VALIDATE_SKIP_CHECKSUM, &a), MCD_OK);
}

static void check_queries(const mcd_asset* a) {
    mcd_clip_info ci;
    mcd_skeleton_info si;
    mcd_node_info ni;
    uint32_t clips = mcd_clip_count(a), skeletons = mcd_skeleton_count(a), found = 12345, last;
    mcd_asset empty;
    memset(&empty, 0, sizeof empty);
    CHECK(mcd_clip_count(NULL) == 0);
    CHECK(mcd_skeleton_count(NULL) == 0);
    CHECK(mcd_scratch_size(NULL) == 0);
    CHECK_RESULT(mcd_get_clip_info(NULL, 0, &ci), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_get_clip_info(&empty, 0, &ci), MCD_ERROR_INVALID_ARGUMENT); /* never opened */
    CHECK_RESULT(mcd_get_clip_info(a, 0, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_get_clip_info(a, clips, &ci), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_get_clip_info(a, UINT32_MAX, &ci), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_get_skeleton_info(NULL, 0, &si), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_get_skeleton_info(a, 0, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_get_skeleton_info(a, skeletons, &si), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_get_node_info(NULL, 0, 0, &ni), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_get_node_info(a, 0, 0, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_get_node_info(a, skeletons, 0, &ni), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_get_skeleton_info(a, skeletons - 1u, &si), MCD_OK);
    CHECK_RESULT(mcd_get_node_info(a, skeletons - 1u, si.node_count, &ni), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_get_node_info(a, skeletons - 1u, UINT32_MAX, &ni), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_get_node_info(a, skeletons - 1u, si.node_count - 1u, &ni), MCD_OK);
    CHECK_RESULT(mcd_find_clip(NULL, "x", &found), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_find_clip(a, NULL, &found), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_get_clip_info(a, clips - 1u, &ci), MCD_OK);
    CHECK_RESULT(mcd_find_clip(a, ci.name, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_find_clip(a, "no such clip", &found), MCD_ERROR_NOT_FOUND);
    CHECK_RESULT(mcd_find_clip(a, "", &found), MCD_ERROR_NOT_FOUND); /* names are never empty */
    CHECK(found == 12345); /* untouched on failure */
    last = clips - 1u;
    CHECK_RESULT(mcd_find_clip(a, ci.name, &found), MCD_OK);
    CHECK(found == last);
}

/* The scratch any clip can use (mcd_scratch_size), and smaller ones: init takes any size from
 * MCD_SCRATCH_MIN_SIZE (plus what the contact pass keeps), sampling checks each clip's need. */
static void check_scratch_init(const mcd_asset* a) {
    size_t n = mcd_scratch_size(a);
    uint8_t* block = NULL;
    uint32_t c;
    mcd_transform pose[1024];
    CHECK(n >= MCD_SCRATCH_MIN_SIZE && n % 16u == 0);
    if (posix_memalign((void**)&block, 16, n + 16u) != 0) return;
    CHECK_RESULT(mcd_scratch_init(NULL, block, n), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_scratch_init(a, NULL, n), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_scratch_init(a, block, MCD_SCRATCH_MIN_SIZE - 1u), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(mcd_scratch_init(a, block, 0), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(mcd_scratch_init(a, block + 8, n), MCD_ERROR_INVALID_ARGUMENT); /* 8-aligned only */
    CHECK_RESULT(mcd_scratch_init(a, block + 1, n), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_scratch_init(a, block + 16, n), MCD_OK);
    CHECK_RESULT(mcd_scratch_init(a, block, n + 16u), MCD_OK); /* larger is fine */
    for (c = 0; c < mcd_clip_count(a); ++c) {
        static const uint32_t short_by[2] = {1, 16};
        mcd_clip_info ci;
        size_t k;
        CHECK_RESULT(mcd_get_clip_info(a, c, &ci), MCD_OK);
        /* The clip's own size works; less is refused, by init or by the sample. */
        CHECK_RESULT(mcd_scratch_init(a, block, ci.scratch_size), MCD_OK);
        CHECK_RESULT(mcd_sample(a, c, 0.0f, 0, pose, 1024, block), MCD_OK);
        for (k = 0; k < 2; ++k) {
            size_t size = ci.scratch_size - short_by[k]; /* scratch_size >= MCD_SCRATCH_MIN_SIZE */
            mcd_result r = mcd_scratch_init(a, block, size);
            if (r == MCD_OK) r = mcd_sample(a, c, 0.0f, 0, pose, 1024, block);
            CHECK_MSG(r == MCD_ERROR_BUFFER_TOO_SMALL, "clip %u: scratch of %lu bytes (need %u) gave %s", c,
                      (unsigned long)size, ci.scratch_size, mcd_result_string(r));
        }
    }
    free(block);
}

static void check_sample(const mcd_golden* g, size_t count, size_t which) {
    const mcd_asset* a = &g[which].asset;
    mcd_clip_info ci;
    mcd_transform pose[1024];
    uint32_t clips = mcd_clip_count(a);
    void* scratch = mcd_test_scratch(a);
    uint8_t* zeros;
    if (!scratch) return;
    CHECK_RESULT(mcd_get_clip_info(a, 0, &ci), MCD_OK);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, pose, ci.node_count, scratch), MCD_OK);
    CHECK_RESULT(mcd_sample(NULL, 0, 0.0f, 0, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, NULL, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, pose, ci.node_count, NULL), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0x10u, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0x80000000u, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, (float)NAN, 0, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, (float)NAN, MCD_SAMPLE_LOOP, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, (float)INFINITY, 0, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, -(float)INFINITY, 0, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, 0, (float)INFINITY, MCD_SAMPLE_LOOP, pose, ci.node_count, scratch), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_sample(a, clips, 0.0f, 0, pose, 1024, scratch), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_sample(a, UINT32_MAX, 0.0f, 0, pose, 1024, scratch), MCD_ERROR_OUT_OF_RANGE);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, pose, ci.node_count - 1u, scratch), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, pose, 0, scratch), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, pose, ci.node_count, scratch), MCD_OK); /* still usable */
    /* A scratch that was never initialised, then one initialised for another asset. */
    zeros = (uint8_t*)calloc(1, mcd_scratch_size(a));
    if (zeros) CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, pose, 1024, zeros), MCD_ERROR_SCRATCH_MISMATCH);
    free(zeros);
    if (count > 1) {
        const mcd_asset* other = &g[(which + 1) % count].asset;
        size_t n = mcd_scratch_size(a) > mcd_scratch_size(other) ? mcd_scratch_size(a) : mcd_scratch_size(other);
        void* s2 = NULL;
        if (posix_memalign(&s2, 16, n) == 0) {
            CHECK_RESULT(mcd_scratch_init(other, s2, n), MCD_OK);
            CHECK_RESULT(mcd_sample(a, 0, 0.0f, 0, pose, 1024, s2), MCD_ERROR_SCRATCH_MISMATCH);
            CHECK_RESULT(mcd_sample(other, 0, 0.0f, 0, pose, 1024, s2), MCD_OK);
            free(s2);
        }
    } else {
        FAIL("the SCRATCH_MISMATCH check needs two golden assets");
    }
    {
        /* The same bytes at another address are another asset: the scratch caches pointers. */
        uint8_t* copy = (uint8_t*)malloc(g[which].file.size);
        mcd_asset moved;
        if (copy) {
            memcpy(copy, g[which].file.data, g[which].file.size);
            CHECK_RESULT(mcd_open(copy, g[which].file.size, 0, &moved), MCD_OK);
            CHECK_RESULT(mcd_sample(&moved, 0, 0.0f, 0, pose, 1024, scratch), MCD_ERROR_SCRATCH_MISMATCH);
            free(copy);
        }
    }
    mcd_test_free_scratch(scratch);
}

void test_argument_checks(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    check_result_strings();
    for (i = 0; i < n; ++i) {
        check_validate_open(&g[i].file);
        check_queries(&g[i].asset);
        check_scratch_init(&g[i].asset);
        check_sample(g, n, i);
    }
    mcd_test_free_golden(g, n);
}
