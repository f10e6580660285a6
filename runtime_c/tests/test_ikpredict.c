/* Codec ik-predict (docs/FORMAT.md, IKPR) on a small generated asset (ikpredict_fixture.h):
 * poses on the coded frames against the encoder's closed-loop reconstruction (frames between
 * coded ones are interpolated), sequential = random = backward
 * sampling bit for bit, and sweeps of truncated and corrupted copies, which the sanitizer
 * builds check for any out-of-bounds access. */
#include <stdlib.h>
#include <string.h>

#include "harness.h"
#include "ikpredict_fixture.h"

void test_ikpredict_fixture(void);
void test_ikpredict_access_orders(void);
void test_ikpredict_damage_sweep(void);

#define NODES IKP_FIXTURE_NODES
#define FRAMES IKP_FIXTURE_FRAMES
#define STEPS (4u * FRAMES) /* frame positions sampled: every quarter frame */

static float position_time(uint32_t s, float rate) {
    return 0.25f * (float)s / rate;
}

void test_ikpredict_fixture(void) {
    mcd_asset asset;
    mcd_clip_info info;
    mcd_transform pose[NODES];
    void* scratch;
    uint32_t f;
    double worst = 0.0;
    CHECK_RESULT(mcd_validate(k_ikp_fixture, sizeof k_ikp_fixture, 0), MCD_OK);
    CHECK_RESULT(mcd_open(k_ikp_fixture, sizeof k_ikp_fixture, 0, &asset), MCD_OK);
    CHECK_RESULT(mcd_get_clip_info(&asset, 0, &info), MCD_OK);
    CHECK(info.codec == MCD_CODEC_IK_PREDICT);
    CHECK(info.frame_count == FRAMES && info.node_count == NODES);
    scratch = mcd_test_scratch(&asset);
    for (f = 0; f < IKP_FIXTURE_CODED; ++f) {
        float time = (float)k_ikp_fixture_frames[f] / info.frame_rate;
        double gap;
        CHECK_RESULT(mcd_sample(&asset, 0, time, 0, pose, NODES, scratch), MCD_OK);
        gap = mcd_test_pose_gap_trs(pose, k_ikp_fixture_poses + (size_t)f * NODES * 10u, NODES);
        if (gap > worst) worst = gap;
    }
    /* Bit for bit when this binary rounds as the Python binding's build does (the pytest
     * suite checks that exactly); a few ulps allowed across compilers and sanitizer builds. */
    CHECK_MSG(worst <= 1e-6, "ik-predict poses differ from the encoder's reconstruction by %g", worst);
    mcd_test_free_scratch(scratch);
}

/* Forward, backward and scattered sampling give the same bytes at every position. */
void test_ikpredict_access_orders(void) {
    static mcd_transform forward[STEPS][NODES];
    mcd_transform pose[NODES];
    mcd_asset asset;
    mcd_clip_info info;
    void* scratch;
    uint32_t s, n, seed = 777u, mismatches = 0;
    CHECK_RESULT(mcd_open(k_ikp_fixture, sizeof k_ikp_fixture, 0, &asset), MCD_OK);
    CHECK_RESULT(mcd_get_clip_info(&asset, 0, &info), MCD_OK);
    scratch = mcd_test_scratch(&asset);
    for (s = 0; s < STEPS; ++s)
        CHECK_RESULT(mcd_sample(&asset, 0, position_time(s, info.frame_rate), 0, forward[s], NODES, scratch), MCD_OK);
    for (s = STEPS; s-- > 0u;) {
        CHECK_RESULT(mcd_sample(&asset, 0, position_time(s, info.frame_rate), 0, pose, NODES, scratch), MCD_OK);
        mismatches += memcmp(pose, forward[s], sizeof pose) != 0;
    }
    for (n = 0; n < 3u * STEPS; ++n) {
        s = mcd_test_rand(&seed) % STEPS;
        CHECK_RESULT(mcd_sample(&asset, 0, position_time(s, info.frame_rate), 0, pose, NODES, scratch), MCD_OK);
        mismatches += memcmp(pose, forward[s], sizeof pose) != 0;
    }
    CHECK_MSG(mismatches == 0, "%u poses depend on the access order", mismatches);
    mcd_test_free_scratch(scratch);
}

/* Open a copy; on success sample every half frame: it cannot fail (mcd_validate checked every
 * entropy stream) and the poses are finite. */
static mcd_result open_and_sample(const uint8_t* data, size_t size) {
    mcd_asset asset;
    mcd_transform pose[NODES];
    mcd_result r = mcd_open(data, size, 0, &asset);
    if (r == MCD_OK) {
        void* scratch = mcd_test_scratch(&asset);
        mcd_clip_info info;
        uint32_t f;
        if (mcd_get_clip_info(&asset, 0, &info) == MCD_OK && info.node_count <= NODES) {
            for (f = 0; f < 2u * info.frame_count; ++f) {
                mcd_result s = mcd_sample(&asset, 0, 0.5f * (float)f / info.frame_rate, MCD_SAMPLE_WORLD, pose, NODES, scratch);
                CHECK_RESULT(s, MCD_OK);
                if (s == MCD_OK) CHECK(mcd_test_pose_finite(pose, info.node_count));
            }
        }
        mcd_test_free_scratch(scratch);
    }
    return r;
}

void test_ikpredict_damage_sweep(void) {
    size_t size = sizeof k_ikp_fixture, pos, len;
    uint8_t* copy = (uint8_t*)malloc(size);
    uint32_t rejected = 0, total = 0, seed = 4242u;
    static const uint8_t flips[4] = {0x01, 0x80, 0xFF, 0x10};
    if (!copy) return;
    for (len = 0; len < size; len += 16u) {
        uint8_t* t = (uint8_t*)malloc(len ? len : 1u);
        if (!t) break;
        memcpy(t, k_ikp_fixture, len);
        CHECK(open_and_sample(t, len) != MCD_OK);
        free(t);
    }
    for (pos = 24; pos < size; pos = mcd_test_sweep_next(pos, 17)) {
        size_t j;
        for (j = 0; j < 2u; ++j) {
            memcpy(copy, k_ikp_fixture, size);
            copy[pos] ^= (j == 0u) ? flips[pos & 3u] : (uint8_t)(1u + mcd_test_rand(&seed) % 255u);
            mcd_test_fix_crc(copy, size);
            total++;
            if (open_and_sample(copy, size) != MCD_OK) rejected++;
        }
        if (mcd_test_failures() > 20) break;
    }
    /* mcd_validate decodes every entropy stream, so most changes break a rule (68 % measured
     * on this fixture); the rest sample finite poses. */
    CHECK_MSG(rejected > total / 2u, "only %u of %u damaged copies rejected", rejected, total);
    free(copy);
}
