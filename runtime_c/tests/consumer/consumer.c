/* A program outside the mocodec tree, built against an installed copy by run.cmake (with
 * find_package and with pkg-config): the installed header, the library it links and the package
 * metadata must agree on the version, garbage must be refused, and a golden asset must open and
 * sample to finite transforms.
 *
 *     consumer VERSION [ASSET]      prints one line per check, exits 0 when all pass */
#include <mocodec.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int g_failed;

static void check(int ok, const char* what) {
    printf("consumer: %s: %s\n", what, ok ? "ok" : "FAILED");
    if (!ok) g_failed = 1;
}

/* `size` bytes at a 16-byte boundary inside a malloc'd block (*block, for free). */
static void* aligned16(size_t size, void** block) {
    unsigned char* p = (unsigned char*)malloc(size + 15u);
    *block = p;
    return p ? p + ((16u - (size_t)((uintptr_t)p % 16u)) % 16u) : NULL;
}

static int pose_finite(const mcd_transform* pose, uint32_t count) {
    /* Every member of mcd_transform is a float, whatever the format version adds. */
    const float* f = (const float*)(const void*)pose;
    size_t i, n = (size_t)count * (sizeof *pose / sizeof(float));
    for (i = 0; i < n; ++i)
        if (!(f[i] - f[i] == 0.0f)) return 0;
    return n > 0;
}

/* Opens the asset with whichever API the installed header declares. */
static mcd_result open_asset(const void* data, size_t size, mcd_asset* asset, void** resident_block) {
    *resident_block = NULL;
#if MCD_FORMAT_MAJOR >= 2
    return mcd_open(data, size, 0, asset);
#else
    {
        size_t need = 0;
        void* resident = NULL;
        mcd_result r = mcd_resident_size(data, size, 0, &need);
        if (r != MCD_OK) return r;
        if (need > 0 && !(resident = aligned16(need, resident_block))) return MCD_ERROR_BUFFER_TOO_SMALL;
        return mcd_open(data, size, 0, resident, need, asset);
    }
#endif
}

static void sample_asset(const char* path) {
    FILE* f = fopen(path, "rb");
    long n = -1;
    void *data_block = NULL, *scratch_block = NULL, *resident_block = NULL;
    unsigned char* data = NULL;
    void* scratch = NULL;
    mcd_transform* pose = NULL;
    mcd_asset asset;
    mcd_clip_info info;
    mcd_result r;
    char line[512];
    if (f && fseek(f, 0, SEEK_END) == 0) n = ftell(f);
    if (n > 0 && fseek(f, 0, SEEK_SET) == 0 && (data = (unsigned char*)aligned16((size_t)n, &data_block)) != NULL &&
        fread(data, 1, (size_t)n, f) == (size_t)n) {
        r = open_asset(data, (size_t)n, &asset, &resident_block);
        snprintf(line, sizeof line, "%s opens (%s)", path, mcd_result_string(r));
        check(r == MCD_OK, line);
        if (r == MCD_OK && mcd_get_clip_info(&asset, 0, &info) == MCD_OK) {
            scratch = aligned16(mcd_scratch_size(&asset), &scratch_block);
            pose = (mcd_transform*)malloc(info.node_count * sizeof *pose);
            r = scratch ? mcd_scratch_init(&asset, scratch, mcd_scratch_size(&asset)) : MCD_ERROR_BUFFER_TOO_SMALL;
            if (r == MCD_OK && pose)
                r = mcd_sample(&asset, 0, 0.5f * info.duration, MCD_SAMPLE_WORLD, pose, info.node_count, scratch);
            snprintf(line, sizeof line, "clip 0 (%u nodes) sampled half-way to finite transforms (%s)", (unsigned)info.node_count,
                     mcd_result_string(r));
            check(r == MCD_OK && pose && pose_finite(pose, info.node_count), line);
        } else if (r == MCD_OK) {
            check(0, "clip 0 has info");
        }
    } else {
        snprintf(line, sizeof line, "%s read", path);
        check(0, line);
    }
    if (f) fclose(f);
    free(pose);
    free(scratch_block);
    free(resident_block);
    free(data_block);
}

int main(int argc, char** argv) {
    static const char garbage[64] = "not a mocodec asset, just some text of the right length";
    char header_version[64], line[256];
    uint32_t v = mcd_version();
    if (argc < 2 || argc > 3) {
        fprintf(stderr, "usage: consumer VERSION [ASSET]\n");
        return 2;
    }
    snprintf(header_version, sizeof header_version, "%u.%u.%u", (unsigned)MCD_VERSION_MAJOR,
             (unsigned)MCD_VERSION_MINOR, (unsigned)MCD_VERSION_PATCH);
    snprintf(line, sizeof line, "library %u.%u.%u = header %s", (unsigned)(v >> 16), (unsigned)((v >> 8) & 0xFFu),
             (unsigned)(v & 0xFFu), header_version);
    check(v == (uint32_t)MCD_VERSION, line);
    snprintf(line, sizeof line, "header %s = package %s", header_version, argv[1]);
    check(strcmp(header_version, argv[1]) == 0, line);
    check(mcd_validate(garbage, sizeof garbage, 0) == MCD_ERROR_BAD_MAGIC, "garbage refused as not an asset");
    check(mcd_validate(NULL, 0, 0) != MCD_OK, "no bytes refused");
    check(mcd_result_string(MCD_ERROR_BAD_MAGIC) != NULL && mcd_result_string(MCD_ERROR_BAD_MAGIC)[0] != '\0',
          "result strings");
    if (argc == 3) sample_asset(argv[2]);
    printf("consumer: %s\n", g_failed ? "FAILED" : "all checks passed");
    return g_failed;
}
