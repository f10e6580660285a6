/* Microseconds per sampled pose through the native C runtime, for bench/wasm_speed.py, which
 * runs bench/pose_speed.mjs (the same loop on the wasm build, under node) beside it.
 *
 *   pose_speed ASSET.mcd RUNS   -> one JSON object on stdout
 *
 * Four modes: local or world transforms, sequential (every frame of every clip in order, what
 * playback does) or random (as many times, uniform over each clip, from xorshift64* with a fixed
 * seed; pose_speed.mjs draws the same times). The times are drawn before the clock starts. Each
 * mode: warm-up passes for WARMUP_US (node's wasm tiers up to its optimising compiler meanwhile;
 * the same rule here), then RUNS passes; per pass the mean per pose; reported: median, min and
 * max over the passes. One thread, one scratch. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mocodec.h"

#define MAX_NODES 1024
#define WARMUP_US 500000.0

static double now_us(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec * 1e6 + ts.tv_nsec / 1e3;
}

static int cmp_double(const void* a, const void* b) {
    double x = *(const double*)a, y = *(const double*)b;
    return (x > y) - (x < y);
}

/* xorshift64*, top 53 bits as a double in [0, 1) */
static double uniform(unsigned long long* s) {
    *s ^= *s >> 12; *s ^= *s << 25; *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ull) >> 11) / 9007199254740992.0;
}

static unsigned char* read_file(const char* path, size_t* size) {
    FILE* f = fopen(path, "rb");
    unsigned char* data;
    long n;
    if (!f) return NULL;
    fseek(f, 0, SEEK_END); n = ftell(f); fseek(f, 0, SEEK_SET);
    data = (unsigned char*)malloc(n > 0 ? (size_t)n : 1);
    if (data && fread(data, 1, (size_t)n, f) != (size_t)n) { free(data); data = NULL; }
    fclose(f);
    *size = (size_t)n;
    return data;
}

int main(int argc, char** argv) {
    static mcd_transform pose[MAX_NODES];
    static const char* names[4] = {"local_sequential", "local_random", "world_sequential", "world_random"};
    size_t size, total = 0, k;
    unsigned char* data;
    mcd_asset asset;
    void* scratch;
    uint32_t c, i, count;
    uint32_t* clips;
    float *seq, *rnd;
    double *per;
    int runs = argc > 2 ? atoi(argv[2]) : 15, mode, r;
    unsigned long long seed = 0x9E3779B97F4A7C15ull;
    if (argc < 2 || runs < 1) { fprintf(stderr, "usage: pose_speed ASSET.mcd RUNS\n"); return 2; }
    data = read_file(argv[1], &size);
    if (!data) { perror(argv[1]); return 1; }
    if (mcd_open(data, size, 0, &asset) != MCD_OK) { fprintf(stderr, "%s: not a valid asset\n", argv[1]); return 1; }
    count = mcd_clip_count(&asset);
    for (c = 0; c < count; ++c) {
        mcd_clip_info info;
        mcd_get_clip_info(&asset, c, &info);
        total += info.frame_count;
    }
    clips = (uint32_t*)malloc(total * sizeof *clips);
    seq = (float*)malloc(total * sizeof *seq);
    rnd = (float*)malloc(total * sizeof *rnd);
    per = (double*)malloc((size_t)runs * sizeof *per);
    if (posix_memalign(&scratch, 16, mcd_scratch_size(&asset)) != 0 || !clips || !seq || !rnd || !per) return 1;
    mcd_scratch_init(&asset, scratch, mcd_scratch_size(&asset));
    for (c = 0, k = 0; c < count; ++c) {
        mcd_clip_info info;
        mcd_get_clip_info(&asset, c, &info);
        for (i = 0; i < info.frame_count; ++i, ++k) {
            clips[k] = c;
            seq[k] = (float)i / info.frame_rate;
            rnd[k] = (float)(uniform(&seed) * info.duration);
        }
    }
    printf("{\"asset_bytes\": %lu, \"scratch_bytes\": %lu, \"clips\": %u, \"poses_per_pass\": %lu, \"runs\": %d",
           (unsigned long)size, (unsigned long)mcd_scratch_size(&asset), count, (unsigned long)total, runs);
    for (mode = 0; mode < 4; ++mode) {
        uint32_t flags = mode >= 2 ? MCD_SAMPLE_WORLD : 0;
        const float* times = mode % 2 ? rnd : seq;
        double warm_until = now_us() + WARMUP_US;
        for (r = -1; r < runs; ++r) {
            double t0 = now_us();
            for (k = 0; k < total; ++k) {
                if (mcd_sample(&asset, clips[k], times[k], flags, pose, MAX_NODES, scratch) != MCD_OK) {
                    fprintf(stderr, "sample failed\n");
                    return 1;
                }
            }
            if (r >= 0) per[r] = (now_us() - t0) / (double)total;
            else if (now_us() < warm_until) --r; /* still warming up */
        }
        qsort(per, (size_t)runs, sizeof *per, cmp_double);
        printf(", \"%s\": {\"median\": %.4f, \"min\": %.4f, \"max\": %.4f}", names[mode], per[runs / 2], per[0],
               per[runs - 1]);
    }
    printf("}\n");
    free(per); free(rnd); free(seq); free(clips); free(scratch); free(data);
    return 0;
}
