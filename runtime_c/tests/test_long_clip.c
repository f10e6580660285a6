/* mcd_sample's time on a two-hour clip (long_clip_fixture.h: 864,000 frames at 120 fps, rma):
 * a double time frame / frame_rate shows exactly that frame's pose, and a quarter frame after it
 * the curve's pose there. With a float time (0.2's API) the late times resolved 0.06 frames and
 * the snap onto frames reached 0.35 frames, so the quarter-frame times showed the frame. */
#include <math.h>
#include <string.h>

#include "harness.h"
#include "long_clip_fixture.h"

void test_long_clip_time(void);

#define NODES LONG_FIXTURE_NODES

/* Largest difference from the reference pose (10 floats a node): rotations whichever sign the
 * quaternion has, translations and scales relative to 1 + |reference|. */
static double gap_to(const mcd_transform* pose, const float* want) {
    double worst = 0.0;
    uint32_t i, k;
    for (i = 0; i < NODES; ++i) {
        const float* w = want + 10u * i;
        double plus = 0.0, minus = 0.0, d;
        for (k = 0; k < 4; ++k) {
            double a = fabs((double)pose[i].rotation[k] - w[k]), b = fabs((double)pose[i].rotation[k] + w[k]);
            if (a > plus) plus = a;
            if (b > minus) minus = b;
        }
        d = plus < minus ? plus : minus;
        if (d > worst) worst = d;
        for (k = 0; k < 3; ++k) {
            d = fabs((double)pose[i].translation[k] - w[4 + k]) / (1.0 + fabs(w[4 + k]));
            if (d > worst) worst = d;
            d = fabs((double)pose[i].scale[k] - w[7 + k]) / (1.0 + fabs(w[7 + k]));
            if (d > worst) worst = d;
        }
    }
    return worst;
}

void test_long_clip_time(void) {
    mcd_asset asset;
    mcd_clip_info info;
    mcd_transform pose[NODES], nearest[NODES];
    void* scratch;
    uint32_t i;
    CHECK_RESULT(mcd_open(k_long_fixture, sizeof k_long_fixture, 0, &asset), MCD_OK);
    CHECK_RESULT(mcd_get_clip_info(&asset, 0, &info), MCD_OK);
    CHECK(info.frame_count == LONG_FIXTURE_FRAMES && info.node_count == NODES && info.codec == MCD_CODEC_RMA);
    scratch = mcd_test_scratch(&asset);
    for (i = 0; i < LONG_FIXTURE_LATE; ++i) {
        double frame = (double)k_long_fixture_frames[i];
        const float* want = k_long_fixture_poses + (size_t)i * NODES * 10u;
        CHECK_RESULT(mcd_sample(&asset, 0, frame / (double)info.frame_rate, 0, pose, NODES, scratch), MCD_OK);
        CHECK_RESULT(mcd_sample(&asset, 0, frame / (double)info.frame_rate, MCD_SAMPLE_NEAREST, nearest, NODES,
                                scratch), MCD_OK);
        CHECK_MSG(memcmp(pose, nearest, sizeof pose) == 0, "frame %.0f: the time frame / rate is not that frame", frame);
        CHECK_MSG(gap_to(pose, want) <= 1e-5, "frame %.0f differs from the reference by %g", frame, gap_to(pose, want));
        if (i + 1 < LONG_FIXTURE_LATE) {
            const float* between = k_long_fixture_poses + (size_t)(LONG_FIXTURE_LATE + i) * NODES * 10u;
            double t = (frame + LONG_FIXTURE_QUARTER) / (double)info.frame_rate;
            CHECK_RESULT(mcd_sample(&asset, 0, t, 0, pose, NODES, scratch), MCD_OK);
            CHECK_MSG(gap_to(pose, between) <= 1e-5, "frame %.0f + 1/4 differs from the reference by %g", frame,
                      gap_to(pose, between));
            /* And the pose there is not the frame's (the joint swings ~1 degree in a quarter frame). */
            CHECK_MSG(gap_to(nearest, between) > 1e-3, "frame %.0f + 1/4: the reference does not move (%g)", frame,
                      gap_to(nearest, between));
        }
    }
    mcd_test_free_scratch(scratch);
}
