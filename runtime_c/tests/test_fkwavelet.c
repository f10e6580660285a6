/* Codec fk-wavelet (docs/FORMAT.md, FKWV) on a small generated asset (fkwavelet_fixture.h):
 * the resident block, the poses against the Python reference decoder, and sweeps of truncated
 * and corrupted copies, which the sanitizer builds check for any out-of-bounds access. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fkwavelet_fixture.h"
#include "harness.h"

void test_fkwavelet_fixture(void);
void test_fkwavelet_damage_sweep(void);

static void* aligned_resident(size_t size, void** base) {
    uint8_t* p = (uint8_t*)malloc(size + 16u);
    *base = p;
    if (!p) return NULL;
    return p + ((16u - ((uintptr_t)p & 15u)) & 15u);
}

/* Open a copy of `data`; on success sample every frame and midpoint and check the poses are
 * finite. Returns the open result. */
static mcd_result open_and_sample(const uint8_t* data, size_t size) {
    size_t need = 0;
    void *base = NULL, *resident = NULL, *scratch;
    mcd_asset asset;
    mcd_result r = mcd_resident_size(data, size, 0, &need);
    mcd_transform pose[FKW_FIXTURE_NODES];
    uint32_t clip;
    if (r != MCD_OK) return r;
    if (need) {
        resident = aligned_resident(need, &base);
        if (!resident) return MCD_ERROR_INVALID_ARGUMENT;
    }
    r = mcd_open(data, size, 0, resident, need, &asset);
    if (r == MCD_OK) {
        scratch = mcd_test_scratch(&asset);
        for (clip = 0; clip < mcd_clip_count(&asset); ++clip) {
            mcd_clip_info info;
            uint32_t f;
            if (mcd_get_clip_info(&asset, clip, &info) != MCD_OK || info.node_count > FKW_FIXTURE_NODES) continue;
            for (f = 0; f < 2u * info.frame_count; ++f) {
                float t = 0.5f * (float)f / info.frame_rate;
                CHECK(mcd_sample(&asset, clip, t, MCD_SAMPLE_WORLD, pose, FKW_FIXTURE_NODES, scratch) == MCD_OK);
                CHECK(mcd_test_pose_finite(pose, info.node_count));
            }
        }
        mcd_test_free_scratch(scratch);
    }
    free(base);
    return r;
}

void test_fkwavelet_fixture(void) {
    const uint8_t* data = k_fkw_fixture;
    size_t size = sizeof k_fkw_fixture, need = 0;
    void *base = NULL, *resident, *scratch;
    mcd_asset asset;
    mcd_clip_info info;
    mcd_transform pose[FKW_FIXTURE_NODES];
    uint32_t f;
    double worst = 0.0;
    CHECK_RESULT(mcd_validate(data, size, 0), MCD_OK);
    CHECK_RESULT(mcd_resident_size(data, size, 0, &need), MCD_OK);
    /* Directory (16 + 8 bytes, to 16) plus every channel on every frame as float32. */
    CHECK(need == 32u + ((4u * FKW_FIXTURE_FRAMES * FKW_FIXTURE_CHANNELS + 15u) & ~(size_t)15u));
    resident = aligned_resident(need, &base);
    if (!resident) return;
    CHECK_RESULT(mcd_open(data, size, 0, NULL, 0, &asset), MCD_ERROR_INVALID_ARGUMENT);
    CHECK_RESULT(mcd_open(data, size, 0, resident, need - 16u, &asset), MCD_ERROR_BUFFER_TOO_SMALL);
    CHECK_RESULT(mcd_open(data, size, 0, resident, need, &asset), MCD_OK);
    CHECK_RESULT(mcd_get_clip_info(&asset, 0, &info), MCD_OK);
    CHECK(info.codec == MCD_CODEC_FK_WAVELET);
    CHECK(info.frame_count == FKW_FIXTURE_FRAMES && info.node_count == FKW_FIXTURE_NODES);
    scratch = mcd_test_scratch(&asset);
    for (f = 0; f < FKW_FIXTURE_FRAMES; ++f) {
        double gap;
        CHECK_RESULT(mcd_sample(&asset, 0, (float)f / info.frame_rate, 0, pose, FKW_FIXTURE_NODES, scratch), MCD_OK);
        gap = mcd_test_pose_gap(pose, k_fkw_fixture_poses + (size_t)f * FKW_FIXTURE_NODES * 7u, FKW_FIXTURE_NODES);
        if (gap > worst) worst = gap;
    }
    CHECK_MSG(worst <= 1e-5, "fk-wavelet poses differ from the Python reference by %g", worst);
    mcd_test_free_scratch(scratch);
    free(base);
}

/* Every shorter buffer is rejected; every single-byte change (with the checksum rewritten so
 * the codec's own checks are reached) is rejected or samples finite poses. */
void test_fkwavelet_damage_sweep(void) {
    size_t size = sizeof k_fkw_fixture, pos, len;
    uint8_t* copy = (uint8_t*)malloc(size);
    uint32_t rejected = 0, total = 0, seed = 12345u;
    static const uint8_t flips[4] = {0x01, 0x80, 0xFF, 0x10};
    if (!copy) return;
    for (len = 0; len < size; len += 16u) {
        uint8_t* t = (uint8_t*)malloc(len ? len : 1u);
        if (!t) break;
        memcpy(t, k_fkw_fixture, len);
        CHECK(open_and_sample(t, len) != MCD_OK);
        free(t);
    }
    for (pos = 24; pos < size; pos = mcd_test_sweep_next(pos, 7)) {
        size_t j;
        for (j = 0; j < 2u; ++j) {
            mcd_result r;
            memcpy(copy, k_fkw_fixture, size);
            copy[pos] ^= (j == 0u) ? flips[pos & 3u] : (uint8_t)(1u + mcd_test_rand(&seed) % 255u);
            mcd_test_fix_crc(copy, size);
            r = open_and_sample(copy, size);
            total++;
            if (r != MCD_OK) rejected++;
        }
        if (mcd_test_failures() > 20) break;
    }
    CHECK(rejected > total / 2u);
    free(copy);
}
