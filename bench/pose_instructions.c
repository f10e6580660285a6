/* Samples every pose of an .mcd asset through the C runtime (mcd_sample) in one of a few fixed
 * sequences, for counting instructions per pose under valgrind callgrind
 * (bench/pose_instructions.sh does the counting and the arithmetic).
 *
 *   pose_instructions ASSET.mcd MODE [world]   MODE: none (open only), seq (every frame of every
 *                                              clip), step2 (every other frame), rand (as many
 *                                              uniform random times as frames, xorshift64*),
 *                                              back (every frame, last first), tick (8 instances
 *                                              of different clips advanced by 1/60 s in turn)
 *   HASH=1 pose_instructions ...               also prints a hash of every pose's bytes, so two
 *                                              builds can be shown to give the same bits
 *
 * Prints "MODE poses N hash H". Trusts its input (a bench tool, not a reader). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mocodec.h"

#define MAX_NODES 1024
#define SCRATCHES 8

static unsigned char* read_file(const char* path, size_t* size) {
    FILE* f = fopen(path, "rb");
    unsigned char* buf;
    long n;
    if (!f || fseek(f, 0, SEEK_END) != 0 || (n = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) exit(2);
    buf = (unsigned char*)malloc((size_t)n + 16u);
    if (!buf || fread(buf, 1, (size_t)n, f) != (size_t)n) exit(2);
    fclose(f);
    *size = (size_t)n;
    return buf;
}

static uint64_t g_hash = 1469598103934665603ull; /* FNV-1a */
static int g_hashing;

static void mix(const mcd_transform* pose, uint32_t nodes) {
    const unsigned char* c = (const unsigned char*)pose;
    size_t i, n = nodes * sizeof *pose;
    if (!g_hashing) return;
    for (i = 0; i < n; ++i) {
        g_hash ^= c[i];
        g_hash *= 1099511628211ull;
    }
}

/* xorshift64*, top 53 bits as a double in [0, 1); the fixed seed keeps runs comparable */
static double uniform(uint64_t* s) {
    *s ^= *s >> 12;
    *s ^= *s << 25;
    *s ^= *s >> 27;
    return (double)((*s * 2685821657736338717ull) >> 11) / 9007199254740992.0;
}

int main(int argc, char** argv) {
    static mcd_transform pose[MAX_NODES];
    mcd_asset asset;
    void* scratch[SCRATCHES];
    size_t size, scratch_size;
    unsigned char* data;
    const char* mode;
    uint32_t clips, c, f, flags, i;
    uint64_t seed = 0x9E3779B97F4A7C15ull;
    long poses = 0;
    if (argc < 3) {
        fprintf(stderr, "usage: pose_instructions ASSET.mcd none|seq|step2|rand|back|tick [world]\n");
        return 2;
    }
    data = read_file(argv[1], &size);
    mode = argv[2];
    flags = argc > 3 && !strcmp(argv[3], "world") ? MCD_SAMPLE_WORLD : 0u;
    g_hashing = getenv("HASH") != NULL;
    if (mcd_open(data, size, MCD_OPEN_PREVALIDATED, &asset) != MCD_OK) return 1;
    scratch_size = (mcd_scratch_size(&asset) + 15u) / 16u * 16u;
    for (i = 0; i < SCRATCHES; ++i) {
        scratch[i] = malloc(scratch_size + 16u);
        if (!scratch[i]) return 1;
        scratch[i] = (void*)(((uintptr_t)scratch[i] + 15u) & ~(uintptr_t)15u);
        mcd_scratch_init(&asset, scratch[i], scratch_size);
    }
    clips = mcd_clip_count(&asset);
    if (!strcmp(mode, "tick")) {
        /* 8 instances of clips spread over the library, 6,247 ticks at 60 Hz (engine_bench's count) */
        static const uint32_t pick[SCRATCHES] = {0, 4, 9, 14, 19, 24, 29, 33};
        double t[SCRATCHES] = {0};
        int k;
        for (k = 0; k < 6247; ++k)
            for (i = 0; i < SCRATCHES; ++i) {
                mcd_clip_info ci;
                mcd_get_clip_info(&asset, pick[i] % clips, &ci);
                mcd_sample(&asset, pick[i] % clips, t[i], flags | MCD_SAMPLE_LOOP, pose, ci.node_count, scratch[i]);
                mix(pose, ci.node_count);
                t[i] += 1.0 / 60.0;
                poses++;
            }
    } else if (strcmp(mode, "none") != 0) {
        for (c = 0; c < clips; ++c) {
            mcd_clip_info ci;
            uint32_t frames;
            double rate;
            mcd_get_clip_info(&asset, c, &ci);
            frames = ci.frame_count;
            rate = ci.frame_rate;
            for (f = 0; f < frames; ++f) {
                double t;
                if (!strcmp(mode, "seq")) t = f / rate;
                else if (!strcmp(mode, "back")) t = (frames - 1u - f) / rate;
                else if (!strcmp(mode, "step2")) {
                    if (f & 1u) continue;
                    t = f / rate;
                } else if (!strcmp(mode, "rand")) t = uniform(&seed) * (frames - 1u) / rate;
                else return 2;
                mcd_sample(&asset, c, t, flags, pose, ci.node_count, scratch[0]);
                mix(pose, ci.node_count);
                poses++;
            }
        }
    }
    printf("%s poses %ld hash %016llx\n", mode, poses, (unsigned long long)g_hash);
    return 0;
}
