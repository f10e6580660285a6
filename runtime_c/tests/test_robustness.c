/* Hostile input: truncations, single-byte corruptions, bad headers and the fuzzer's past finds.
 * Every buffer handed to the library is malloc'd at its exact size so that ASan reports any read
 * past the end, which reading a prefix of a larger buffer would hide. */
#define _POSIX_C_SOURCE 200809L

#include <stdlib.h>
#include <string.h>

#include "exercise.h"
#include "harness.h"

#define SKIP MCD_VALIDATE_SKIP_CHECKSUM

void test_truncation_sweep(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, len;
    for (i = 0; i < n; ++i) {
        const mcd_test_file* f = &g[i].file;
        uint8_t* longer = (uint8_t*)malloc(f->size + 1u);
        for (len = 0; len < f->size; ++len) {
            uint8_t* prefix = (uint8_t*)malloc(len ? len : 1u);
            mcd_result r0, r1;
            mcd_asset a;
            if (!prefix) break;
            memcpy(prefix, f->data, len);
            r0 = mcd_validate(prefix, len, 0);
            r1 = mcd_validate(prefix, len, SKIP);
            CHECK_MSG(r0 != MCD_OK && r1 != MCD_OK, "%s: prefix of %lu bytes accepted", f->path, (unsigned long)len);
            /* A prefix that keeps the whole magic is a truncated asset, and the error says so. */
            if (len >= 8)
                CHECK_MSG(r0 == MCD_ERROR_TRUNCATED && r1 == MCD_ERROR_TRUNCATED, "%s: prefix of %lu bytes gave %d/%d, not TRUNCATED",
                          f->path, (unsigned long)len, (int)r0, (int)r1);
            CHECK(mcd_open(prefix, len, 0, &a) == r0);
            CHECK(mcd_open(prefix, len, SKIP, &a) == r1);
            /* Even a prevalidated open reads the header's size first: a short buffer (a file
             * still loading) is TRUNCATED, never read past. */
            CHECK(mcd_open(prefix, len, MCD_OPEN_PREVALIDATED, &a) == r1);
            free(prefix);
        }
        if (longer) {
            memcpy(longer, f->data, f->size);
            longer[f->size] = 0;
            CHECK_RESULT(mcd_validate(longer, f->size + 1u, 0), MCD_ERROR_TRAILING_DATA);
            CHECK_RESULT(mcd_validate(longer, f->size + 1u, SKIP), MCD_ERROR_TRAILING_DATA);
            {
                mcd_asset a;
                CHECK_RESULT(mcd_open(longer, f->size + 1u, MCD_OPEN_PREVALIDATED, &a), MCD_ERROR_TRAILING_DATA);
            }
            free(longer);
        }
    }
    mcd_test_free_golden(g, n);
}

void test_corruption_sweep(void) {
    static const uint8_t masks[4] = {0x01, 0x10, 0x80, 0xFF};
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, pos, m;
    char why[256];
    for (i = 0; i < n; ++i) {
        const mcd_test_file* f = &g[i].file;
        uint8_t* copy = (uint8_t*)malloc(f->size);
        unsigned long accepted = 0;
        if (!copy) break;
        memcpy(copy, f->data, f->size);
        for (pos = 0; pos < f->size && mcd_test_failures() < 100; pos = mcd_test_sweep_next(pos, 211)) {
            for (m = 0; m < 4; ++m) {
                mcd_result r;
                int e;
                copy[pos] ^= masks[m];
                /* CRC-32 catches every single-byte error in the bytes it covers, and the header
                 * bytes before it are checked field by field, except version_minor: any minor of
                 * the runtime's major is read (docs/FORMAT.md, compatibility policy). */
                r = mcd_validate(copy, f->size, 0);
                if (pos == 10 || pos == 11)
                    CHECK_RESULT(r, MCD_OK);
                else
                    CHECK_MSG(r != MCD_OK, "%s: byte %lu ^ 0x%02x accepted with the checksum on", f->path, (unsigned long)pos, masks[m]);
                /* Every pair of sample flags, not all 16 combinations: the sweep's cost under
                 * ASan, a third; the fuzz targets and the regression replay use all 16. */
                e = mcd_exercise_pairwise(copy, f->size, SKIP, UINT32_MAX, why, sizeof why);
                CHECK_MSG(e != MCD_EXERCISE_BROKEN, "%s: byte %lu ^ 0x%02x: %s", f->path, (unsigned long)pos, masks[m], why);
                accepted += e == MCD_EXERCISE_SAMPLED;
                copy[pos] ^= masks[m];
            }
        }
        /* Values in the payload (floats, bit-stream keys, META text) can change without breaking
         * a rule: the sweep must have reached sampling, or its second half tested nothing. */
        CHECK(accepted > 0);
        free(copy);
    }
    mcd_test_free_golden(g, n);
}

/* A golden asset copy whose header the test edits. */
typedef struct edit {
    uint8_t* bytes;
    size_t size;
} edit;

static int edit_begin(edit* e, const mcd_test_file* f) {
    e->size = f->size;
    e->bytes = (uint8_t*)malloc(f->size);
    if (!e->bytes) return 0;
    memcpy(e->bytes, f->data, f->size);
    return 1;
}

static void check_edit(const mcd_test_file* f, size_t offset, uint32_t value, int width, int fix_crc,
                       mcd_result want, const char* what) {
    edit e;
    mcd_result r;
    if (!edit_begin(&e, f)) return;
    if (width == 4) mcd_test_wr_u32(e.bytes + offset, value);
    else if (width == 2) mcd_test_wr_u16(e.bytes + offset, (uint16_t)value);
    else e.bytes[offset] = (uint8_t)value;
    if (fix_crc) mcd_test_fix_crc(e.bytes, e.size);
    r = mcd_validate(e.bytes, e.size, 0);
    CHECK_MSG(r == want, "%s: %s gave %d (%s), expected %d (%s)", f->path, what, (int)r, mcd_result_string(r), (int)want,
              mcd_result_string(want));
    free(e.bytes);
}

void test_header_errors(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    /* The CRC helper itself, on the standard check input of CRC-32/ISO-HDLC. */
    CHECK(mcd_test_crc32((const uint8_t*)"123456789", 9) == 0xCBF43926u);
    for (i = 0; i < n; ++i) {
        const mcd_test_file* f = &g[i].file;
        uint32_t total = mcd_test_rd_u32(f->data + 16), count = mcd_test_rd_u32(f->data + 24);
        uint16_t major = (uint16_t)(f->data[8] | (f->data[9] << 8));
        CHECK(total == f->size);
        CHECK(mcd_test_crc32(f->data + 24, f->size - 24) == mcd_test_rd_u32(f->data + 20));
        check_edit(f, 0, 0x88, 1, 0, MCD_ERROR_BAD_MAGIC, "magic byte 0");
        check_edit(f, 4, '\n', 1, 0, MCD_ERROR_BAD_MAGIC, "magic \\r\\n -> \\n\\n (text-mode transfer)");
        check_edit(f, 7, 0x0B, 1, 0, MCD_ERROR_BAD_MAGIC, "magic byte 7");
        check_edit(f, 8, major + 1u, 2, 0, MCD_ERROR_VERSION_TOO_NEW, "major + 1");
        check_edit(f, 8, 0xFFFF, 2, 0, MCD_ERROR_VERSION_TOO_NEW, "major 65535");
        check_edit(f, 8, 0, 2, 0, MCD_ERROR_VERSION_TOO_OLD, "major 0");
        check_edit(f, 8, major - 1u, 2, 0, MCD_ERROR_VERSION_TOO_OLD, "major - 1 (format 1: resident memory)");
        /* Any minor of the runtime's major is read (compatibility policy); outside the CRC. */
        check_edit(f, 10, 7, 2, 0, MCD_OK, "minor 7");
        check_edit(f, 20, mcd_test_rd_u32(f->data + 20) ^ 1u, 4, 0, MCD_ERROR_CHECKSUM, "crc ^ 1");
        check_edit(f, f->size - 1, f->data[f->size - 1] ^ 0x40, 1, 0, MCD_ERROR_CHECKSUM, "last byte changed");
        check_edit(f, 12, 31, 4, 0, MCD_ERROR_MALFORMED, "header_size 31");
        check_edit(f, 12, 48, 4, 0, MCD_ERROR_MALFORMED, "header_size 48");
        check_edit(f, 12, 0, 4, 0, MCD_ERROR_MALFORMED, "header_size 0");
        check_edit(f, 16, total + 16u, 4, 0, MCD_ERROR_TRUNCATED, "total_size past the buffer");
        check_edit(f, 16, total - 16u, 4, 0, MCD_ERROR_TRAILING_DATA, "total_size short of the buffer");
        check_edit(f, 16, total - 1u, 4, 0, MCD_ERROR_MALFORMED, "total_size not a multiple of 16");
        /* Fields under the checksum: recompute it so the structural check is what answers. */
        check_edit(f, 24, 0, 4, 1, MCD_ERROR_MALFORMED, "section_count 0");
        check_edit(f, 24, 1, 4, 1, MCD_ERROR_MALFORMED, "section_count 1");
        check_edit(f, 24, 4097, 4, 1, MCD_ERROR_MALFORMED, "section_count 4097");
        check_edit(f, 24, 0xFFFFFFFFu, 4, 1, MCD_ERROR_MALFORMED, "section_count 2^32-1");
        check_edit(f, 24, 4096, 4, 1, MCD_ERROR_MALFORMED, "section_count 4096 (table past the end)");
        check_edit(f, 24, count + 1u, 4, 1, MCD_ERROR_MALFORMED, "section_count + 1");
        check_edit(f, 28, 1, 4, 1, MCD_ERROR_MALFORMED, "reserved flags 1");
        /* The first section table entry: offset and kind version. */
        check_edit(f, 32 + 8, mcd_test_rd_u32(f->data + 40) + 16u, 4, 1, MCD_ERROR_MALFORMED, "section 0 offset + 16");
        check_edit(f, 32 + 12, 0xFFFFFFF0u, 4, 1, MCD_ERROR_MALFORMED, "section 0 size huge");
        /* Section 0 is a SKEL (version 2): version 1 (format 1's 32-byte nodes) and 3 are unknown. */
        CHECK(memcmp(f->data + 32, "SKEL", 4) == 0 && mcd_test_rd_u32(f->data + 36) == 2);
        check_edit(f, 32 + 4, 1, 4, 1, MCD_ERROR_UNSUPPORTED, "SKEL version 1");
        check_edit(f, 32 + 4, 3, 4, 1, MCD_ERROR_UNSUPPORTED, "SKEL version 3");
        /* Without the fix the checksum is what catches a changed section count. */
        check_edit(f, 24, count + 1u, 4, 0, MCD_ERROR_CHECKSUM, "section_count + 1, stale crc");
    }
    mcd_test_free_golden(g, n);
}

/* The clip directory's rules (docs/FORMAT.md "CLIP", version 2), each broken alone in clip 0's
 * record with the checksum recomputed, so each answer comes from the rule itself. */
/* Frame positions are binary32: a clip holds at most 2^24 frames. The record alone decides it
 * (a prevalidated open, which reads no payload, refuses 2^24 + 1 frames with a matching
 * duration and takes 2^24). */
static void check_frame_limit(const mcd_test_file* f, uint32_t rec, float rate) {
    static const uint32_t counts[2] = {(1u << 24) + 1u, 1u << 24};
    uint32_t k;
    for (k = 0; k < 2; ++k) {
        edit e;
        mcd_asset a;
        if (!edit_begin(&e, f)) return;
        mcd_test_wr_u32(e.bytes + rec + 24, counts[k]);
        mcd_test_wr_u32(e.bytes + rec + 32, mcd_test_f32_bits((float)((double)(counts[k] - 1u) / (double)rate)));
        mcd_test_fix_crc(e.bytes, e.size);
        CHECK_MSG(mcd_open(e.bytes, e.size, MCD_OPEN_PREVALIDATED, &a) == (k == 0 ? MCD_ERROR_MALFORMED : MCD_OK),
                  "%s: frame_count %u under a prevalidated open", f->path, counts[k]);
        CHECK_RESULT(mcd_validate(e.bytes, e.size, 0), MCD_ERROR_MALFORMED); /* the payload disagrees */
        free(e.bytes);
    }
}

void test_clip_directory_errors(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    for (i = 0; i < n; ++i) {
        const mcd_test_file* f = &g[i].file;
        uint32_t index = 0;
        const uint8_t* entry = mcd_test_section(f->data, "CLIP", 0, &index);
        uint32_t clip = entry ? mcd_test_rd_u32(entry + 8) : 0, rec = clip + 8u;
        float rate, duration;
        uint32_t frames, need;
        if (clip == 0 || rec + 48u > f->size) {
            FAIL("%s: no clip directory", f->path);
            continue;
        }
        frames = mcd_test_rd_u32(f->data + rec + 24);
        rate = mcd_test_rd_f32(f->data + rec + 28);
        duration = mcd_test_rd_f32(f->data + rec + 32);
        need = mcd_test_rd_u32(f->data + rec + 40);
        check_edit(f, 32 + 16 * index + 4, 1, 4, 1, MCD_ERROR_UNSUPPORTED, "CLIP version 1 (40-byte records)");
        check_edit(f, 32 + 16 * index + 4, 3, 4, 1, MCD_ERROR_UNSUPPORTED, "CLIP version 3");
        check_edit(f, clip, 0, 4, 1, MCD_ERROR_MALFORMED, "clip_count 0");
        check_edit(f, clip + 4, 0, 4, 1, MCD_ERROR_MALFORMED, "string_block_offset 0");
        check_edit(f, rec, 0xFFFFu, 4, 1, MCD_ERROR_MALFORMED, "name_offset past the string block");
        check_edit(f, rec + 4, mcd_skeleton_count(&g[i].asset), 4, 1, MCD_ERROR_MALFORMED, "skeleton index past the end");
        check_edit(f, rec + 8, 99, 4, 1, MCD_ERROR_UNSUPPORTED, "codec 99");
        check_edit(f, rec + 12, mcd_test_rd_u32(f->data + 24), 4, 1, MCD_ERROR_MALFORMED, "section index past the end");
        check_edit(f, rec + 12, 0, 4, 1, MCD_ERROR_MALFORMED, "payload section of another kind");
        check_edit(f, rec + 16, mcd_test_rd_u32(f->data + rec + 16) + 2u, 4, 1, MCD_ERROR_MALFORMED, "payload_offset not a multiple of 4");
        check_edit(f, rec + 20, 0xFFFFFFF0u, 4, 1, MCD_ERROR_MALFORMED, "payload past its section");
        check_edit(f, rec + 24, 0, 4, 1, MCD_ERROR_MALFORMED, "frame_count 0");
        check_edit(f, rec + 24, frames + 1u, 4, 1, MCD_ERROR_MALFORMED, "frame_count + 1 (duration and payload disagree)");
        check_edit(f, rec + 28, 0, 4, 1, MCD_ERROR_MALFORMED, "frame_rate 0");
        check_edit(f, rec + 28, mcd_test_f32_bits(-rate), 4, 1, MCD_ERROR_MALFORMED, "frame_rate negative");
        check_edit(f, rec + 28, 0x7FC00000u, 4, 1, MCD_ERROR_MALFORMED, "frame_rate NaN");
        check_edit(f, rec + 28, 0x7F800000u, 4, 1, MCD_ERROR_MALFORMED, "frame_rate +inf");
        check_edit(f, rec + 28, mcd_test_f32_bits(100001.0f), 4, 1, MCD_ERROR_MALFORMED, "frame_rate above 100000");
        /* (frame_count - 1) / rate overflows a float: no finite duration can equal it. */
        check_edit(f, rec + 28, mcd_test_f32_bits(1e-39f), 4, 1, MCD_ERROR_MALFORMED, "frame_rate 1e-39 (duration overflows)");
        check_edit(f, rec + 32, mcd_test_f32_bits(duration * 1.001f), 4, 1, MCD_ERROR_MALFORMED, "duration 0.1% off");
        check_edit(f, rec + 32, 0x7FC00000u, 4, 1, MCD_ERROR_MALFORMED, "duration NaN");
        check_edit(f, rec + 36, 1, 4, 1, MCD_ERROR_MALFORMED, "clip flags 1");
        check_edit(f, rec + 44, 1, 4, 1, MCD_ERROR_MALFORMED, "clip reserved word 1");
        /* The scratch the record states is the codec's own figure, a multiple of 16. */
        check_edit(f, rec + 40, need + 16u, 4, 1, MCD_ERROR_MALFORMED, "scratch need + 16");
        if (need >= 16u) check_edit(f, rec + 40, need - 16u, 4, 1, MCD_ERROR_MALFORMED, "scratch need - 16");
        check_edit(f, rec + 40, need + 1u, 4, 1, MCD_ERROR_MALFORMED, "scratch need not a multiple of 16");
        check_edit(f, rec + 40, 0xFFFFFFF0u, 4, 1, MCD_ERROR_MALFORMED, "scratch need 4 GB");
        /* Within the 1e-4 relative tolerance the duration is accepted. */
        check_edit(f, rec + 32, mcd_test_f32_bits(duration * (1.0f + 2e-5f)), 4, 1, MCD_OK, "duration 2e-5 off");
        check_frame_limit(f, rec, rate);
    }
    mcd_test_free_golden(g, n);
}

/* Inputs the fuzzer once crashed on (fuzz/regressions): each must be handled like any input. */
void test_fuzz_regressions(void) {
    mcd_test_file* files;
    size_t n = mcd_test_list_files(mcd_test_regression_dir(), ".mcd", &files), i;
    char why[256];
    for (i = 0; i < n; ++i) {
        uint32_t flags;
        for (flags = 0; flags <= SKIP; ++flags) {
            int e = mcd_exercise(files[i].data, files[i].size, flags, UINT32_MAX, why, sizeof why);
            CHECK_MSG(e != MCD_EXERCISE_BROKEN, "%s: %s", files[i].path, why);
        }
    }
    /* No inputs yet is fine (mcd_test_list_files already failed if the folder is missing). */
    mcd_test_free_files(files, n);
}
