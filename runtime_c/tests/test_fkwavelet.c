/* Codec fk-wavelet (docs/FORMAT.md, FKWV version 2) on a small generated asset
 * (fkwavelet_fixture.h, several blocks and a shorter last one): the scratch it asks for, the
 * poses against the Python reference decoder, the same poses whatever order the frames are
 * sampled in, and sweeps of truncated and corrupted copies, which the sanitizer builds check
 * for any out-of-bounds access. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fkwavelet_fixture.h"
#include "harness.h"

void test_fkwavelet_fixture(void);
void test_fkwavelet_access_orders(void);
void test_fkwavelet_damage_sweep(void);

#define ALIGN16(x) (((x) + 15u) & ~(size_t)15u)

/* Open a copy of `data`; on success sample every frame and midpoint, forward then backward,
 * and check the poses are finite. Returns the open result. */
static mcd_result open_and_sample(const uint8_t* data, size_t size) {
    mcd_asset asset;
    mcd_transform pose[FKW_FIXTURE_NODES];
    mcd_result r = mcd_open(data, size, 0, &asset);
    uint32_t clip;
    void* scratch;
    if (r != MCD_OK) return r;
    scratch = mcd_test_scratch(&asset);
    if (!scratch) return r;
    for (clip = 0; clip < mcd_clip_count(&asset); ++clip) {
        mcd_clip_info info;
        uint32_t f, n;
        if (mcd_get_clip_info(&asset, clip, &info) != MCD_OK || info.node_count > FKW_FIXTURE_NODES) continue;
        n = 2u * info.frame_count;
        for (f = 0; f < 2u * n; ++f) {
            float t = 0.5f * (float)(f < n ? f : 2u * n - 1u - f) / info.frame_rate;
            CHECK(mcd_sample(&asset, clip, t, MCD_SAMPLE_WORLD, pose, FKW_FIXTURE_NODES, scratch) == MCD_OK);
            CHECK(mcd_test_pose_finite(pose, info.node_count));
        }
    }
    mcd_test_free_scratch(scratch);
    return r;
}

void test_fkwavelet_fixture(void) {
    const uint8_t* data = k_fkw_fixture;
    size_t size = sizeof k_fkw_fixture;
    mcd_asset asset;
    mcd_clip_info info;
    mcd_transform pose[FKW_FIXTURE_NODES];
    uint32_t f;
    double worst = 0.0;
    void* scratch;
    /* State, row table, one block's rows, the edge row and the offsets (docs/FORMAT.md). */
    size_t codec_scratch = 16u + ALIGN16(2u * FKW_FIXTURE_BLOCK) +
                           ALIGN16(4u * FKW_FIXTURE_BLOCK * FKW_FIXTURE_CHANNELS) + 2u * ALIGN16(4u * FKW_FIXTURE_CHANNELS);
    CHECK(FKW_FIXTURE_FRAMES > 2u * FKW_FIXTURE_BLOCK && FKW_FIXTURE_FRAMES % FKW_FIXTURE_BLOCK != 0u);
    CHECK_RESULT(mcd_validate(data, size, 0), MCD_OK);
    CHECK_RESULT(mcd_open(data, size, 0, &asset), MCD_OK);
    CHECK_RESULT(mcd_get_clip_info(&asset, 0, &info), MCD_OK);
    CHECK(info.codec == MCD_CODEC_FK_WAVELET);
    CHECK(info.frame_count == FKW_FIXTURE_FRAMES && info.node_count == FKW_FIXTURE_NODES);
    CHECK(info.scratch_size == 64u + codec_scratch);
    CHECK(mcd_scratch_size(&asset) == 64u + codec_scratch);
    scratch = mcd_test_scratch(&asset);
    if (!scratch) return;
    for (f = 0; f < FKW_FIXTURE_FRAMES; ++f) {
        double gap;
        CHECK_RESULT(mcd_sample(&asset, 0, (float)f / info.frame_rate, 0, pose, FKW_FIXTURE_NODES, scratch), MCD_OK);
        gap = mcd_test_pose_gap(pose, k_fkw_fixture_poses + (size_t)f * FKW_FIXTURE_NODES * 7u, FKW_FIXTURE_NODES);
        if (gap > worst) worst = gap;
    }
    CHECK_MSG(worst <= 1e-5, "fk-wavelet poses differ from the Python reference by %g", worst);
    /* A scratch smaller than the clip needs is refused, not overrun. */
    CHECK_RESULT(mcd_scratch_init(&asset, scratch, 64u + codec_scratch - 16u), MCD_OK);
    CHECK_RESULT(mcd_sample(&asset, 0, 0.0f, 0, pose, FKW_FIXTURE_NODES, scratch), MCD_ERROR_BUFFER_TOO_SMALL);
    mcd_test_free_scratch(scratch);
}

/* Every frame and midpoint sampled forward, backward, in a shuffled order and each with a
 * fresh scratch gives the same bytes: what the scratch caches never changes a pose. */
void test_fkwavelet_access_orders(void) {
    mcd_asset asset;
    mcd_clip_info info;
    size_t count, i, pose_bytes = sizeof(mcd_transform) * FKW_FIXTURE_NODES;
    float* times;
    uint32_t* order;
    mcd_transform *forward, *other;
    void* scratch;
    int pass;
    CHECK_RESULT(mcd_open(k_fkw_fixture, sizeof k_fkw_fixture, 0, &asset), MCD_OK);
    CHECK_RESULT(mcd_get_clip_info(&asset, 0, &info), MCD_OK);
    times = mcd_test_frame_times(&info, &count);
    order = (uint32_t*)malloc(sizeof *order * count);
    forward = (mcd_transform*)malloc(pose_bytes * count);
    other = (mcd_transform*)malloc(pose_bytes * count);
    scratch = mcd_test_scratch(&asset);
    if (!times || !order || !forward || !other || !scratch) {
        FAIL("out of memory");
        free(times);
        free(order);
        free(forward);
        free(other);
        mcd_test_free_scratch(scratch);
        return;
    }
    for (i = 0; i < count; ++i)
        CHECK_RESULT(mcd_sample(&asset, 0, times[i], 0, forward + i * FKW_FIXTURE_NODES, FKW_FIXTURE_NODES, scratch),
                     MCD_OK);
    for (pass = 0; pass < 3; ++pass) {
        for (i = 0; i < count; ++i) order[i] = (uint32_t)(pass == 0 ? count - 1u - i : i);
        if (pass == 1) mcd_test_shuffle(order, count, 99u);
        for (i = 0; i < count; ++i) {
            uint32_t k = order[i];
            if (pass == 2) mcd_scratch_init(&asset, scratch, mcd_scratch_size(&asset));
            CHECK_RESULT(mcd_sample(&asset, 0, times[k], 0, other + (size_t)k * FKW_FIXTURE_NODES, FKW_FIXTURE_NODES,
                                    scratch),
                         MCD_OK);
        }
        CHECK_MSG(memcmp(forward, other, pose_bytes * count) == 0, "access order %d changes the poses", pass);
    }
    free(times);
    free(order);
    free(forward);
    free(other);
    mcd_test_free_scratch(scratch);
}

/* Every shorter buffer is rejected; every single-byte change (with the checksum rewritten so
 * the codec's own checks are reached) is rejected or samples finite poses. */
void test_fkwavelet_damage_sweep(void) {
    size_t size = sizeof k_fkw_fixture, pos, len;
    uint8_t* copy = (uint8_t*)malloc(size);
    uint32_t rejected = 0, total = 0, seed = 12345u;
    static const uint8_t flips[4] = {0x01, 0x80, 0xFF, 0x10};
    if (!copy) return;
    for (len = 0; len < size; len += 4u) {
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
