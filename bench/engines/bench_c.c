/* Per-pose cost of sampling a clip by calling the C runtime directly: the baseline the engine
 * bindings are compared with (bench/engines/run_bench.sh). Plays the clip forward at 60 Hz,
 * looping, as a game does, and reports the best of several rounds in microseconds per pose.
 *
 *   bench_c ASSET.mcd SAMPLES_PER_ROUND
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "mocodec.h"

static double now_us(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e6 + ts.tv_nsec / 1e3;
}

int main(int argc, char **argv) {
    FILE *f;
    long size;
    unsigned char *bytes;
    mcd_asset asset;
    mcd_clip_info info;
    mcd_transform pose[256];
    void *scratch;
    long n, i;
    int round;
    double best = 1e30, sink = 0;
    if (argc != 3) return 2;
    n = atol(argv[2]);
    f = fopen(argv[1], "rb");
    if (!f) return 2;
    fseek(f, 0, SEEK_END);
    size = ftell(f);
    fseek(f, 0, SEEK_SET);
    bytes = malloc((size_t)size);
    if (fread(bytes, 1, (size_t)size, f) != (size_t)size) return 2;
    fclose(f);
    if (mcd_open(bytes, (size_t)size, 0, &asset) != MCD_OK) return 2;
    scratch = malloc(mcd_scratch_size(&asset));
    mcd_scratch_init(&asset, scratch, mcd_scratch_size(&asset));
    mcd_get_clip_info(&asset, 0, &info);
    for (round = 0; round < 5; round++) {
        double t0 = now_us(), us;
        for (i = 0; i < n; i++) {
            if (mcd_sample(&asset, 0, (float)i / 60.0f, MCD_SAMPLE_LOOP, pose, 256, scratch) != MCD_OK) return 1;
            sink += pose[3].rotation[0];
        }
        us = (now_us() - t0) / (double)n;
        if (us < best) best = us;
    }
    printf("c %u %.4f %g\n", info.node_count, best, sink);
    return 0;
}
