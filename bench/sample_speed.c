/* Microseconds per sampled pose through the C runtime, sequential and random access.
 *
 *   sample_speed ASSET.mcd [runs] [only]   -> one JSON object on stdout
 *   (only: "local-seq", "local-rand", "world-seq" or "world-rand" to time one mode, for profiling)
 *
 * Sequential: every frame of a clip in order (what playback does; the scratch cache makes
 * it O(1) per frame). Random: the same number of uniformly random times. Each figure is the
 * median over `runs` passes of the per-pose mean within a pass; warm cache, one thread. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mocodec.h"

static double now_us(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e6 + ts.tv_nsec / 1e3;
}

static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

static unsigned long long rng = 0x9E3779B97F4A7C15ull;
static double uniform(void) { /* xorshift64*: fixed seed, same times every run */
    rng ^= rng >> 12; rng ^= rng << 25; rng ^= rng >> 27;
    return (double)((rng * 2685821657736338717ull) >> 11) / 9007199254740992.0;
}

int main(int argc, char** argv) {
    FILE* f;
    long size;
    unsigned char* data;
    mcd_asset asset;
    void* scratch;
    int runs = argc > 2 ? atoi(argv[2]) : 15, mode;
    uint32_t c, flags_list[2] = {0, MCD_SAMPLE_WORLD};
    mcd_transform pose[1024];
    double total_frames = 0;
    double medians[2][2] = {{0, 0}, {0, 0}};
    const char* only = argc > 3 ? argv[3] : NULL;
    static const char* names[2][2] = {{"local-seq", "local-rand"}, {"world-seq", "world-rand"}};
    if (argc < 2) { fprintf(stderr, "usage: sample_speed ASSET.mcd [runs]\n"); return 2; }
    f = fopen(argv[1], "rb");
    if (!f) { perror(argv[1]); return 1; }
    fseek(f, 0, SEEK_END); size = ftell(f); fseek(f, 0, SEEK_SET);
    data = (unsigned char*)malloc((size_t)size);
    if (!data || fread(data, 1, (size_t)size, f) != (size_t)size) { fprintf(stderr, "read failed\n"); return 1; }
    fclose(f);
    if (mcd_open(data, (size_t)size, 0, &asset) != MCD_OK) { fprintf(stderr, "open failed\n"); return 1; }
    if (posix_memalign(&scratch, 16, mcd_scratch_size(&asset) + 16) != 0) return 1;
    mcd_scratch_init(&asset, scratch, mcd_scratch_size(&asset));
    for (c = 0; c < mcd_clip_count(&asset); ++c) {
        mcd_clip_info info;
        mcd_get_clip_info(&asset, c, &info);
        total_frames += info.frame_count;
    }
    for (mode = 0; mode < 2; ++mode) {        /* 0 local, 1 world */
        int access;
        for (access = 0; access < 2; ++access) { /* 0 sequential, 1 random */
            double* per;
            int r;
            if (only && strcmp(only, names[mode][access]) != 0) continue;
            per = (double*)malloc(sizeof(double) * (size_t)runs);
            for (r = 0; r < runs; ++r) {
                double t0 = now_us(), count = 0;
                for (c = 0; c < mcd_clip_count(&asset); ++c) {
                    mcd_clip_info info;
                    uint32_t i;
                    mcd_get_clip_info(&asset, c, &info);
                    for (i = 0; i < info.frame_count; ++i) {
                        float t = access == 0 ? (float)i / info.frame_rate : (float)(uniform() * info.duration);
                        if (mcd_sample(&asset, c, t, flags_list[mode], pose, 1024, scratch) != MCD_OK) {
                            fprintf(stderr, "sample failed\n");
                            return 1;
                        }
                        count += 1;
                    }
                }
                per[r] = (now_us() - t0) / count;
            }
            qsort(per, (size_t)runs, sizeof(double), cmp_double);
            medians[mode][access] = per[runs / 2];
            free(per);
        }
    }
    printf("{\"asset_bytes\": %ld, \"scratch_bytes\": %lu, \"clips\": %u, "
           "\"frames\": %.0f, \"runs\": %d, "
           "\"us_per_pose_local_sequential\": %.4f, \"us_per_pose_local_random\": %.4f, "
           "\"us_per_pose_world_sequential\": %.4f, \"us_per_pose_world_random\": %.4f}\n",
           size, (unsigned long)mcd_scratch_size(&asset), mcd_clip_count(&asset),
           total_frames, runs, medians[0][0], medians[0][1], medians[1][0], medians[1][1]);
    free(scratch);
    free(data);
    return 0;
}
