/* Test runner and shared helpers. Usage:
 *     mcd_tests [--golden DIR] [--golden-v1 DIR] [--regressions DIR] [test-name ...]
 * Without names every test runs. Exit status: 0 passed, 1 a test failed, 77 every test that ran
 * skipped itself. The folders default to the compile-time MCD_TEST_GOLDEN_DIR,
 * MCD_TEST_GOLDEN_V1_DIR and MCD_TEST_REGRESSION_DIR so `ctest` and `make test` need no
 * arguments. */
#define _POSIX_C_SOURCE 200809L

#include "harness.h"

#include <dirent.h>
#include <stdarg.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#ifndef MCD_TEST_GOLDEN_DIR
#define MCD_TEST_GOLDEN_DIR "../tests/golden/v2"
#endif
#ifndef MCD_TEST_GOLDEN_V1_DIR
#define MCD_TEST_GOLDEN_V1_DIR "../tests/golden/v1"
#endif
#ifndef MCD_TEST_REGRESSION_DIR
#define MCD_TEST_REGRESSION_DIR "fuzz/regressions"
#endif

#define MCD_TEST(name) void test_##name(void);
#include "test_list.h"
#undef MCD_TEST

typedef struct test_entry {
    const char* name;
    void (*fn)(void);
} test_entry;

static const test_entry k_tests[] = {
#define MCD_TEST(name) {#name, test_##name},
#include "test_list.h"
#undef MCD_TEST
};

#define MAX_PRINTED_FAILURES 10

static const char* g_golden_dir = MCD_TEST_GOLDEN_DIR;
static const char* g_golden_v1_dir = MCD_TEST_GOLDEN_V1_DIR;
static const char* g_regression_dir = MCD_TEST_REGRESSION_DIR;
static unsigned long g_checks, g_failures;
static const char* g_skip_reason;
static char g_notes[2048];

/* ---------------------------------------------------------------- checks */
static void report_failure(const char* file, int line) {
    g_failures++;
    if (g_failures <= MAX_PRINTED_FAILURES) fprintf(stderr, "  %s:%d: ", file, line);
}

void mcd_test_check(int ok, const char* file, int line, const char* expr) {
    g_checks++;
    if (ok) return;
    report_failure(file, line);
    if (g_failures <= MAX_PRINTED_FAILURES) fprintf(stderr, "CHECK(%s) failed\n", expr);
}

void mcd_test_check_result(mcd_result got, mcd_result want, const char* file, int line, const char* expr) {
    g_checks++;
    if (got == want) return;
    report_failure(file, line);
    if (g_failures <= MAX_PRINTED_FAILURES)
        fprintf(stderr, "%s gave %d (%s), expected %d (%s)\n", expr, (int)got, mcd_result_string(got),
                (int)want, mcd_result_string(want));
}

static void vcheck_msg(int ok, const char* file, int line, const char* fmt, va_list ap) {
    g_checks++;
    if (ok) return;
    report_failure(file, line);
    if (g_failures > MAX_PRINTED_FAILURES) return;
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
}

void mcd_test_fail(const char* file, int line, const char* fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vcheck_msg(0, file, line, fmt, ap);
    va_end(ap);
}

void mcd_test_check_msg(int ok, const char* file, int line, const char* fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vcheck_msg(ok, file, line, fmt, ap);
    va_end(ap);
}

void mcd_test_skip(const char* reason) {
    g_skip_reason = reason;
}

void mcd_test_note(const char* fmt, ...) {
    size_t used = strlen(g_notes);
    va_list ap;
    if (used + 8 >= sizeof g_notes) return;
    memcpy(g_notes + used, "    ", 5);
    va_start(ap, fmt);
    vsnprintf(g_notes + used + 4, sizeof g_notes - used - 5, fmt, ap);
    va_end(ap);
    used = strlen(g_notes);
    g_notes[used] = '\n';
    g_notes[used + 1] = 0;
}

unsigned long mcd_test_failures(void) {
    return g_failures;
}

int mcd_test_quick(void) {
    const char* v = getenv("MCD_TEST_QUICK");
    return v && v[0] && strcmp(v, "0") != 0;
}

size_t mcd_test_sweep_next(size_t pos, size_t quick_stride) {
    static int quick = -1;
    if (quick < 0) quick = mcd_test_quick();
    return quick && pos >= 64u && quick_stride > 1u ? pos + quick_stride : pos + 1u;
}

const char* mcd_test_golden_dir(void) {
    return g_golden_dir;
}

const char* mcd_test_golden_v1_dir(void) {
    return g_golden_v1_dir;
}

const char* mcd_test_regression_dir(void) {
    return g_regression_dir;
}

/* ---------------------------------------------------------------- files */
int mcd_test_read_file(const char* path, mcd_test_file* out) {
    FILE* f = fopen(path, "rb");
    long n;
    memset(out, 0, sizeof *out);
    if (!f) {
        FAIL("cannot open %s", path);
        return 0;
    }
    if (fseek(f, 0, SEEK_END) != 0 || (n = ftell(f)) < 0 || fseek(f, 0, SEEK_SET) != 0) {
        fclose(f);
        FAIL("cannot size %s", path);
        return 0;
    }
    out->size = (size_t)n;
    out->data = (uint8_t*)malloc(out->size ? out->size : 1u);
    out->path = (char*)malloc(strlen(path) + 1u);
    if (!out->data || !out->path || fread(out->data, 1, out->size, f) != out->size) {
        fclose(f);
        FAIL("cannot read %s", path);
        mcd_test_free_file(out);
        return 0;
    }
    strcpy(out->path, path);
    fclose(f);
    return 1;
}

void mcd_test_free_file(mcd_test_file* f) {
    free(f->data);
    free(f->path);
    memset(f, 0, sizeof *f);
}

static int by_path(const void* a, const void* b) {
    return strcmp(((const mcd_test_file*)a)->path, ((const mcd_test_file*)b)->path);
}

size_t mcd_test_list_files(const char* dir, const char* suffix, mcd_test_file** out) {
    DIR* d = opendir(dir);
    struct dirent* e;
    size_t count = 0, cap = 0, suffix_len = strlen(suffix);
    mcd_test_file* files = NULL;
    *out = NULL;
    CHECK(d != NULL);
    if (!d) {
        FAIL("cannot open folder %s", dir);
        return 0;
    }
    while ((e = readdir(d)) != NULL) {
        size_t len = strlen(e->d_name);
        char* path;
        struct stat st;
        if (e->d_name[0] == '.' || len < suffix_len || strcmp(e->d_name + len - suffix_len, suffix) != 0) continue;
        path = (char*)malloc(strlen(dir) + len + 2u);
        if (!path) break;
        sprintf(path, "%s/%s", dir, e->d_name);
        if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
            free(path);
            continue;
        }
        if (count == cap) {
            mcd_test_file* grown;
            cap = cap ? 2u * cap : 8u;
            grown = (mcd_test_file*)realloc(files, cap * sizeof *files);
            if (!grown) {
                free(path);
                break;
            }
            files = grown;
        }
        if (mcd_test_read_file(path, &files[count])) count++;
        free(path);
    }
    closedir(d);
    if (count) qsort(files, count, sizeof *files, by_path);
    *out = files;
    return count;
}

void mcd_test_free_files(mcd_test_file* files, size_t count) {
    size_t i;
    for (i = 0; i < count; ++i) mcd_test_free_file(&files[i]);
    free(files);
}

size_t mcd_test_load_golden(mcd_golden** out) {
    mcd_test_file* files;
    size_t count = mcd_test_list_files(g_golden_dir, ".mcd", &files), i, kept;
    mcd_golden* g;
    *out = NULL;
    if (count == 0) {
        FAIL("no golden assets (*.mcd) in %s", g_golden_dir);
        free(files);
        return 0;
    }
    g = (mcd_golden*)calloc(count, sizeof *g);
    if (!g) {
        mcd_test_free_files(files, count);
        FAIL("out of memory");
        return 0;
    }
    for (i = 0, kept = 0; i < count; ++i) {
        mcd_result r = mcd_open(files[i].data, files[i].size, 0, &g[kept].asset);
        if (r != MCD_OK) {
            /* Reported once here; the tests then run on the assets that did open. */
            FAIL("golden asset %s does not open: %s", files[i].path, mcd_result_string(r));
            mcd_test_free_file(&files[i]);
            continue;
        }
        g[kept++].file = files[i];
    }
    free(files); /* the entries moved into g */
    *out = g;
    return kept;
}

void mcd_test_free_golden(mcd_golden* g, size_t count) {
    size_t i;
    for (i = 0; i < count; ++i) mcd_test_free_file(&g[i].file);
    free(g);
}

/* ---------------------------------------------------------------- helpers */
void* mcd_test_scratch_sized(const mcd_asset* asset, size_t n) {
    void* p = NULL;
    mcd_result r;
    if (n == 0 || posix_memalign(&p, 16, n) != 0) {
        FAIL("cannot allocate %lu scratch bytes", (unsigned long)n);
        return NULL;
    }
    r = mcd_scratch_init(asset, p, n);
    if (r != MCD_OK) FAIL("mcd_scratch_init of %lu bytes: %s", (unsigned long)n, mcd_result_string(r));
    return p;
}

void* mcd_test_scratch(const mcd_asset* asset) {
    return mcd_test_scratch_sized(asset, mcd_scratch_size(asset));
}

void mcd_test_free_scratch(void* scratch) {
    free(scratch);
}

uint32_t mcd_test_crc32(const uint8_t* data, size_t size) {
    uint32_t crc = 0xFFFFFFFFu;
    size_t i;
    int k;
    for (i = 0; i < size; ++i) {
        crc ^= data[i];
        for (k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
    }
    return crc ^ 0xFFFFFFFFu;
}

uint32_t mcd_test_rd_u32(const uint8_t* p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

float mcd_test_rd_f32(const uint8_t* p) {
    uint32_t u = mcd_test_rd_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

uint32_t mcd_test_f32_bits(float f) {
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    return u;
}

void mcd_test_wr_u32(uint8_t* p, uint32_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

void mcd_test_wr_u16(uint8_t* p, uint16_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

/* The checksum covers [24, total_size) (docs/FORMAT.md, header). */
void mcd_test_fix_crc(uint8_t* asset, size_t size) {
    if (size >= 24) mcd_test_wr_u32(asset + 20, mcd_test_crc32(asset + 24, size - 24));
}

/* ---------------------------------------------------------------- container edits */
const uint8_t* mcd_test_section(const uint8_t* asset, const char kind[4], uint32_t nth, uint32_t* out_index) {
    uint32_t i, count = mcd_test_rd_u32(asset + 24);
    for (i = 0; i < count; ++i) {
        const uint8_t* e = asset + 32 + 16 * (size_t)i;
        if (memcmp(e, kind, 4) == 0 && nth-- == 0) {
            if (out_index) *out_index = i;
            return e;
        }
    }
    return NULL;
}

static size_t align16(size_t x) {
    return (x + 15u) & ~(size_t)15u;
}

uint8_t* mcd_test_replace_section(const uint8_t* asset, uint32_t index, const uint8_t* data, uint32_t size,
                                  size_t* out_size) {
    uint32_t i, count = mcd_test_rd_u32(asset + 24);
    size_t total = align16(32 + 16 * (size_t)count), pos;
    uint8_t* out;
    for (i = 0; i < count; ++i) total = align16(total + (i == index ? size : mcd_test_rd_u32(asset + 32 + 16 * (size_t)i + 12)));
    out = (uint8_t*)calloc(1, total);
    if (!out) {
        FAIL("out of memory");
        return NULL;
    }
    memcpy(out, asset, 32 + 16 * (size_t)count);
    pos = align16(32 + 16 * (size_t)count);
    for (i = 0; i < count; ++i) {
        uint8_t* e = out + 32 + 16 * (size_t)i;
        uint32_t n = i == index ? size : mcd_test_rd_u32(e + 12);
        memcpy(out + pos, i == index ? data : asset + mcd_test_rd_u32(e + 8), n);
        mcd_test_wr_u32(e + 8, (uint32_t)pos);
        mcd_test_wr_u32(e + 12, n);
        pos = align16(pos + n);
    }
    mcd_test_wr_u32(out + 16, (uint32_t)total);
    mcd_test_fix_crc(out, total);
    *out_size = total;
    return out;
}

uint8_t* mcd_test_copy(const uint8_t* data, size_t size) {
    uint8_t* p = (uint8_t*)malloc(size ? size : 1u);
    if (!p) {
        FAIL("out of memory");
        return NULL;
    }
    memcpy(p, data, size);
    return p;
}

uint32_t mcd_test_rand(uint32_t* state) {
    /* xorshift32: tiny and good enough for shuffles. */
    uint32_t x = *state ? *state : 0x9E3779B9u;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    return x;
}

void mcd_test_shuffle(uint32_t* items, size_t count, uint32_t seed) {
    size_t i;
    for (i = count; i > 1; --i) {
        size_t j = mcd_test_rand(&seed) % i;
        uint32_t t = items[i - 1];
        items[i - 1] = items[j];
        items[j] = t;
    }
}

float* mcd_test_frame_times(const mcd_clip_info* info, size_t* out_count) {
    size_t n = 2u * (size_t)info->frame_count - 1u, i;
    float* t = (float*)malloc(n * sizeof *t);
    *out_count = 0;
    if (!t) {
        FAIL("out of memory");
        return NULL;
    }
    for (i = 0; i < n; ++i) t[i] = (float)((double)i * 0.5 / (double)info->frame_rate);
    *out_count = n;
    return t;
}

int mcd_test_pose_finite(const mcd_transform* pose, uint32_t count) {
    uint32_t i, k;
    for (i = 0; i < count; ++i) {
        for (k = 0; k < 4; ++k)
            if (!(pose[i].rotation[k] - pose[i].rotation[k] == 0.0f)) return 0;
        for (k = 0; k < 3; ++k)
            if (!(pose[i].translation[k] - pose[i].translation[k] == 0.0f) ||
                !(pose[i].scale[k] - pose[i].scale[k] == 0.0f))
                return 0;
    }
    return 1;
}

/* Rows of `row` floats: rotation, translation, then (row 10) scale. */
static double pose_gap(const mcd_transform* pose, const float* want, uint32_t count, uint32_t row) {
    double worst = 0.0;
    uint32_t i, k;
    for (i = 0; i < count; ++i) {
        const float* w = want + (size_t)i * row;
        for (k = 0; k < 4u; ++k) {
            double d = fabs((double)pose[i].rotation[k] - w[k]);
            if (d > worst) worst = d;
        }
        for (k = 0; k + 4u < row; ++k) {
            double got = k < 3u ? pose[i].translation[k] : pose[i].scale[k - 3u];
            double d = fabs(got - w[4 + k]) / (1.0 + fabs(w[4 + k]));
            if (d > worst) worst = d;
        }
    }
    return worst;
}

double mcd_test_pose_gap_trs(const mcd_transform* pose, const float* want, uint32_t count) {
    return pose_gap(pose, want, count, 10u);
}

double mcd_test_pose_gap(const mcd_transform* pose, const float* want, uint32_t count) {
    return pose_gap(pose, want, count, 7u);
}

/* ---------------------------------------------------------------- runner */
static int selected(const char* name, int argc, char** argv, int first) {
    int i, any = 0;
    for (i = first; i < argc; ++i) {
        any = 1;
        if (strcmp(argv[i], name) == 0) return 1;
    }
    return !any;
}

int main(int argc, char** argv) {
    size_t i, n = sizeof k_tests / sizeof k_tests[0];
    int first = 1, passed = 0, failed = 0, skipped = 0, ran = 0;
    clock_t start;
    while (first + 1 < argc && argv[first][0] == '-') {
        if (strcmp(argv[first], "--golden") == 0) g_golden_dir = argv[first + 1];
        else if (strcmp(argv[first], "--golden-v1") == 0) g_golden_v1_dir = argv[first + 1];
        else if (strcmp(argv[first], "--regressions") == 0) g_regression_dir = argv[first + 1];
        else break;
        first += 2;
    }
    for (i = first; i < (size_t)argc; ++i) {
        size_t k;
        for (k = 0; k < n && strcmp(argv[i], k_tests[k].name) != 0; ++k) {}
        if (k == n) {
            fprintf(stderr, "unknown test or option: %s\n", argv[i]);
            return 2;
        }
    }
    printf("mocodec %u.%u.%u tests (golden: %s)%s\n", MCD_VERSION_MAJOR, MCD_VERSION_MINOR, MCD_VERSION_PATCH,
           g_golden_dir, mcd_test_quick() ? ", MCD_TEST_QUICK: damage sweeps shortened" : "");
    for (i = 0; i < n; ++i) {
        if (!selected(k_tests[i].name, argc, argv, first)) continue;
        g_checks = g_failures = 0;
        g_skip_reason = NULL;
        g_notes[0] = 0;
        printf("%-28s ", k_tests[i].name);
        fflush(stdout);
        start = clock();
        k_tests[i].fn();
        ran++;
        if (g_failures) {
            printf("FAILED (%lu of %lu checks)\n", g_failures, g_checks);
            failed++;
        } else if (g_skip_reason) {
            printf("skipped: %s\n", g_skip_reason);
            skipped++;
        } else if (g_checks == 0) {
            /* A test that checked nothing proves nothing: count it as a failure. */
            printf("FAILED (no checks ran)\n");
            failed++;
        } else {
            /* CPU time, not wall: where a slow run spends it, whatever else the machine runs. */
            printf("ok (%lu checks, %.1f s CPU)\n", g_checks, (double)(clock() - start) / CLOCKS_PER_SEC);
            passed++;
        }
        fputs(g_notes, stdout);
        fflush(stdout);
    }
    printf("%d passed, %d failed", passed, failed);
    if (skipped) printf(", %d skipped", skipped);
    printf("\n");
    if (failed || ran == 0) return 1;
    return skipped == ran ? 77 : 0; /* 77: "skipped" to CTest (SKIP_RETURN_CODE) */
}
