/* A minimal test harness for the C runtime: no external framework, so the suite builds with
 * nothing but a C compiler (plus pthreads for the thread test). */
#ifndef MCD_TEST_HARNESS_H
#define MCD_TEST_HARNESS_H

#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

/* ---------------------------------------------------------------- checks */
/* Each failed check prints file:line and counts against the running test. The sweeps run
 * millions of checks, so printing stops after a few failures per test but counting does not. */
void mcd_test_check(int ok, const char* file, int line, const char* expr);
void mcd_test_check_result(mcd_result got, mcd_result want, const char* file, int line, const char* expr);
void mcd_test_fail(const char* file, int line, const char* fmt, ...);
void mcd_test_check_msg(int ok, const char* file, int line, const char* fmt, ...);
/* Marks the running test as skipped (with the reason printed) unless it already failed. */
void mcd_test_skip(const char* reason);
/* A line printed under the running test's result (what it could not cover, and why). */
void mcd_test_note(const char* fmt, ...);
/* Failed checks of the running test so far: lets a sweep stop early once it is clearly broken. */
unsigned long mcd_test_failures(void);

/* MCD_TEST_QUICK=1 in the environment (the cross-platform runs under qemu and wine set it)
 * shortens the byte-by-byte damage sweeps: they still visit every position below 64 (headers),
 * then every `quick_stride`-th one. The runner's first line says when it is on. */
int mcd_test_quick(void);
size_t mcd_test_sweep_next(size_t pos, size_t quick_stride);

#define CHECK(cond) mcd_test_check((cond) != 0, __FILE__, __LINE__, #cond)
#define CHECK_RESULT(expr, want) mcd_test_check_result((expr), (want), __FILE__, __LINE__, #expr)
#define FAIL(...) mcd_test_fail(__FILE__, __LINE__, __VA_ARGS__)
/* A check whose failure message is formatted (printf-style) from the values involved. */
#define CHECK_MSG(cond, ...) mcd_test_check_msg((cond) != 0, __FILE__, __LINE__, __VA_ARGS__)

/* ---------------------------------------------------------------- test data */
/* Folders given on the command line or at compile time (MCD_TEST_GOLDEN_DIR, ...): the golden
 * assets of the format this runtime reads, those of format 1 (which it must refuse), and the
 * fuzz regressions. */
const char* mcd_test_golden_dir(void);
const char* mcd_test_golden_v1_dir(void);
const char* mcd_test_regression_dir(void);

typedef struct mcd_test_file {
    char* path;
    uint8_t* data; /* exactly `size` bytes, malloc'd: ASan sees any read past the end */
    size_t size;
} mcd_test_file;

/* Reads a whole file; returns 0 and fails the running test when it cannot. */
int mcd_test_read_file(const char* path, mcd_test_file* out);
void mcd_test_free_file(mcd_test_file* f);

/* Every regular file in `dir` whose name ends with `suffix` (sorted by name). Returns the count;
 * a missing folder fails the running test. Free with mcd_test_free_files. */
size_t mcd_test_list_files(const char* dir, const char* suffix, mcd_test_file** out);
void mcd_test_free_files(mcd_test_file* files, size_t count);

/* The golden assets, each opened (mcd_open validates them); fails the running test (and returns
 * 0) when there are none, so a wrong path cannot make the golden tests pass vacuously. */
typedef struct mcd_golden {
    mcd_test_file file;
    mcd_asset asset;
} mcd_golden;
size_t mcd_test_load_golden(mcd_golden** out);
void mcd_test_free_golden(mcd_golden* g, size_t count);

/* ---------------------------------------------------------------- helpers */
/* 16-byte aligned scratch initialised for `asset` (the API requires the alignment): of
 * mcd_scratch_size bytes, or of exactly `size` bytes (malloc'd at that size, so ASan reports a
 * codec that writes past the need its clip record states). */
void* mcd_test_scratch(const mcd_asset* asset);
void* mcd_test_scratch_sized(const mcd_asset* asset, size_t size);
void mcd_test_free_scratch(void* scratch);

/* ---------------------------------------------------------------- container edits */
/* The section table entry (docs/FORMAT.md) of the `nth` section of `kind` (0 = the first), or
 * NULL; its offset and size are the u32 at +8 and +12. Also the index in the table. */
const uint8_t* mcd_test_section(const uint8_t* asset, const char kind[4], uint32_t nth, uint32_t* out_index);

/* A copy of `asset` with section `index` replaced by `data[0 .. size)`: the following sections
 * move (16-aligned, zero padding), the table and total size follow, the checksum is rewritten.
 * Malloc'd at its exact size (*out_size); NULL when out of memory. */
uint8_t* mcd_test_replace_section(const uint8_t* asset, uint32_t index, const uint8_t* data, uint32_t size,
                                  size_t* out_size);

/* A malloc'd copy of `size` bytes (NULL and a failed check when out of memory). */
uint8_t* mcd_test_copy(const uint8_t* data, size_t size);

/* Our own CRC-32 (zlib's), written from docs/FORMAT.md, so the checksum is checked independently
 * of the library's; and a helper that rewrites the header checksum after a test edits a field. */
uint32_t mcd_test_crc32(const uint8_t* data, size_t size);
void mcd_test_fix_crc(uint8_t* asset, size_t size);

uint32_t mcd_test_rd_u32(const uint8_t* p);
float mcd_test_rd_f32(const uint8_t* p); /* little-endian, as the format stores floats */
uint32_t mcd_test_f32_bits(float f);     /* the float's bit pattern, to write or compare exactly */
void mcd_test_wr_u32(uint8_t* p, uint32_t v);
void mcd_test_wr_u16(uint8_t* p, uint16_t v);

/* Deterministic pseudo-random numbers (fixed seeds keep failures reproducible). */
uint32_t mcd_test_rand(uint32_t* state);
void mcd_test_shuffle(uint32_t* items, size_t count, uint32_t seed);

/* Times at which a clip shows its integer frames and the midpoints between them, in order:
 * 2 * frame_count - 1 of them. Caller frees. */
float* mcd_test_frame_times(const mcd_clip_info* info, size_t* out_count);

/* Every rotation, translation and scale float of the pose is finite. */
int mcd_test_pose_finite(const mcd_transform* pose, uint32_t count);

/* Largest difference between `pose` and `want`: absolute for rotation components, relative to
 * 1 + |want| for translations and scales. `want` holds count x 10 floats (qx qy qz qw tx ty tz
 * sx sy sz) for mcd_test_pose_gap_trs, count x 7 (no scale) for mcd_test_pose_gap. */
double mcd_test_pose_gap_trs(const mcd_transform* pose, const float* want, uint32_t count);
double mcd_test_pose_gap(const mcd_transform* pose, const float* want, uint32_t count);

#endif /* MCD_TEST_HARNESS_H */
