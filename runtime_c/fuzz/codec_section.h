/* The body of the per-codec section targets (fuzz/fuzz_section_<codec>.c, each defining
 * FUZZ_CODEC to an mcd_codec value and including this file once).
 *
 * A mutation of a whole asset mostly breaks the container (an offset, a size, the CRC) before it
 * reaches a codec. Here the input is one codec section only, and the container around it is
 * rebuilt so that it holds: the input is spliced into a template asset (a golden asset of
 * tests/golden/v2 holding this codec's section) with every section moved to its packed place,
 * total_size, the clip records' payload ranges and scratch sizes recomputed. The asset then
 * goes through tests/exercise.c with the checksum skipped: under the fuzzer's instrumentation
 * the CRC of each validation and open took about a third of the time, and the checksum is
 * the other targets' business (an asset written out, below, carries its right CRC).
 *
 * Input: byte 0 picks the template (modulo their count, in file-name order), the rest is the
 * section, read as the version of the template's section (rma's templates hold RMAL version 2,
 * 3 or 4: the codec's reader of that version checks and sizes it). The payload ranges follow
 * the section's own layout as far as it states one (an RMAL payload starts with its size; an
 * RMAP section says where its clip payloads start); otherwise
 * each payload keeps the template's size. The last payload always runs to the section's end,
 * so inserting or removing bytes keeps the framing. A clip record's scratch_bytes is what the
 * codec computes for the new payload (as mcd_offline_clip_scratch does for the encoder),
 * so a payload that needs more scratch still validates, and is sampled on a scratch of exactly
 * that size.
 *
 * Environment:
 *   MCD_FUZZ_GOLDEN=DIR         templates from DIR (default: the golden folder it was built with)
 *   MCD_FUZZ_WRITE_SEEDS=DIR    write one seed per template (its byte 0 and its own section) into
 *                               DIR and exit: `make fuzz` seeds the corpus this way
 *   MCD_FUZZ_ASSET_OUT=FILE     write each spliced asset (CRC made right) to FILE before it is
 *                               exercised: how a crashing input becomes a regression asset for
 *                               fuzz/regressions
 */
#define _POSIX_C_SOURCE 200809L

#include <dirent.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "exercise.h"
#include "internal.h"
#include "mocodec.h"

#ifndef FUZZ_CODEC
#error "define FUZZ_CODEC to the codec whose section is fuzzed"
#endif
#ifndef MCD_FUZZ_GOLDEN_DIR
#define MCD_FUZZ_GOLDEN_DIR "../tests/golden/v2"
#endif

#define MAX_TEMPLATES 64u
#define MAX_CLIPS 8u /* clips sampled per asset, as fuzz_validate_sample */
/* Clips of one template's codec section whose payload ranges follow the input (later ones keep
 * the template's). */
#define MAX_SECTION_CLIPS 64u

typedef struct fuzz_template {
    char name[256];
    uint8_t* data;
    size_t size;
    uint32_t section; /* index of the codec's section in the table */
    const mcd_codec_ops* ops; /* the codec's reader of that section's version */
} fuzz_template;

static fuzz_template g_templates[MAX_TEMPLATES];
static uint32_t g_template_count;
static const char* g_asset_out;

int LLVMFuzzerInitialize(int* argc, char*** argv);
int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

static void fail(const char* what, const char* detail) {
    fprintf(stderr, "fuzz_section (codec %u): %s%s%s\n", (unsigned)FUZZ_CODEC, what, detail ? ": " : "",
            detail ? detail : "");
    abort();
}

static void wr_u32(uint8_t* p, uint32_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static size_t align16(size_t x) {
    return (x + 15u) & ~(size_t)15u;
}

static const uint8_t* entry(const uint8_t* asset, uint32_t i) {
    return asset + MCD_HEADER_SIZE + (size_t)i * MCD_SECTION_ENTRY_SIZE;
}

/* The range of the payload that starts at `start` in a section of `n` bytes: as long as its
 * own size field says (rma, rma-pca) or the template's payload was (the others, whose payloads
 * do not state their size), cut at the section's end; the last one runs to the end. */
static void payload_range(const uint8_t* sec, size_t n, size_t start, size_t template_size, int last,
                          size_t* off, size_t* size) {
    size_t sz = template_size;
    if (start > n) start = n;
    if ((FUZZ_CODEC == MCD_CODEC_RMA || FUZZ_CODEC == MCD_CODEC_RMA_PCA) && start + 4u <= n)
        sz = mcd_rd_u32(sec + start);
    if (last || sz > n - start) sz = n - start;
    *off = start;
    *size = sz;
}

/* Where the section's clip payloads begin: after the RMAL header, at the RMAP shared_end. */
static size_t payloads_start(const uint8_t* sec, size_t n) {
    if (FUZZ_CODEC == MCD_CODEC_RMA) return n < 16u ? n : 16u;
    if (FUZZ_CODEC == MCD_CODEC_RMA_PCA) return n < 28u ? n : mcd_rd_u32(sec + 24);
    return 0;
}

/* The scratch bytes the codec computes for clip record `r` on a payload in `section` (of `n`
 * bytes, checked as a whole already), as the encoder stores them, into `need`; returns 0 when
 * the codec refuses the payload (the record keeps the template's value: validation refuses it). What
 * mcd_offline_clip_scratch does, without checking the template's skeleton again and the section
 * once per clip: a third of the time per input went there. */
static int clip_scratch(const mcd_codec_ops* ops, const uint8_t* section, size_t n, const uint8_t* r,
                        const uint8_t* skeleton, uint32_t* need) {
    mcd_clip_view v;
    size_t size;
    memset(&v, 0, sizeof v);
    v.section = section;
    v.section_size = (uint32_t)n;
    v.payload = section + mcd_rd_u32(r + 16);
    v.payload_size = mcd_rd_u32(r + 20);
    v.frame_count = mcd_rd_u32(r + 24);
    v.frame_rate = mcd_rd_f32(r + 28);
    v.skeleton = skeleton;
    v.node_count = mcd_rd_u32(skeleton);
    /* The range rules the container checks before the codec sees a payload. */
    if ((mcd_rd_u32(r + 16) & 3u) != 0 || (uint64_t)mcd_rd_u32(r + 16) + v.payload_size > n) return 0;
    if (ops->validate(&v) != MCD_OK) return 0;
    size = ops->scratch_size(&v);
    if (size > 0xFFFFFFFFu) return 0;
    *need = (uint32_t)size;
    return 1;
}

/* The template `t` with its codec section replaced by `sec[0 .. n)`, into `out` (room for
 * t->size + n + 16 bytes). Returns the asset's size. */
static size_t splice(const fuzz_template* t, const uint8_t* sec, size_t n, uint8_t* out) {
    const uint8_t* in = t->data;
    const uint8_t *in_clips, *section;
    uint32_t count = mcd_rd_u32(in + 24), i, clip_section = 0, order[MAX_SECTION_CLIPS];
    uint32_t clip_count, codec_clips = 0, skel_index[16], skel_count = 0;
    size_t pos = align16(MCD_HEADER_SIZE + (size_t)count * MCD_SECTION_ENTRY_SIZE), next_start;
    const mcd_codec_ops* ops = t->ops;
    int section_ok;
    uint8_t* clips;
    memcpy(out, in, pos);
    for (i = 0; i < count; ++i) {
        uint32_t kind = mcd_rd_u32(entry(in, i));
        const uint8_t* src = i == t->section ? sec : in + mcd_rd_u32(entry(in, i) + 8);
        size_t sz = i == t->section ? n : mcd_rd_u32(entry(in, i) + 12);
        memcpy(out + pos, src, sz);
        memset(out + pos + sz, 0, align16(pos + sz) - (pos + sz));
        wr_u32(out + MCD_HEADER_SIZE + (size_t)i * MCD_SECTION_ENTRY_SIZE + 8u, (uint32_t)pos);
        wr_u32(out + MCD_HEADER_SIZE + (size_t)i * MCD_SECTION_ENTRY_SIZE + 12u, (uint32_t)sz);
        if (kind == mcd_fourcc('C', 'L', 'I', 'P')) clip_section = i;
        if (kind == mcd_fourcc('S', 'K', 'E', 'L') && skel_count < 16u) skel_index[skel_count++] = i;
        pos = align16(pos + sz);
    }
    wr_u32(out + 16, (uint32_t)pos);
    section = out + mcd_rd_u32(entry(out, t->section) + 8);

    /* This section's clip records in the template's payload order (insertion sort: a template
     * has a handful of clips). Records are read from the template, written into `out`. */
    in_clips = in + mcd_rd_u32(entry(in, clip_section) + 8) + 8u;
    clips = out + mcd_rd_u32(entry(out, clip_section) + 8) + 8u;
    clip_count = mcd_rd_u32(in_clips - 8u);
    for (i = 0; i < clip_count && codec_clips < MAX_SECTION_CLIPS; ++i) {
        uint32_t j = codec_clips;
        if (mcd_rd_u32(in_clips + (size_t)i * MCD_CLIP_RECORD_SIZE + 12u) != t->section) continue;
        while (j > 0 && mcd_rd_u32(in_clips + (size_t)order[j - 1] * MCD_CLIP_RECORD_SIZE + 16u) >
                            mcd_rd_u32(in_clips + (size_t)i * MCD_CLIP_RECORD_SIZE + 16u)) {
            order[j] = order[j - 1];
            --j;
        }
        order[j] = i;
        ++codec_clips;
    }
    next_start = payloads_start(sec, n);
    section_ok = !ops->validate_section || ops->validate_section(section, (uint32_t)n) == MCD_OK;
    for (i = 0; i < codec_clips; ++i) {
        const uint8_t* tr = in_clips + (size_t)order[i] * MCD_CLIP_RECORD_SIZE;
        uint8_t* r = clips + (size_t)order[i] * MCD_CLIP_RECORD_SIZE;
        uint32_t skel = mcd_rd_u32(r + 4);
        size_t off, size;
        if (i > 0 && mcd_rd_u32(tr + 16) == mcd_rd_u32(in_clips + (size_t)order[i - 1] * MCD_CLIP_RECORD_SIZE + 16u)) {
            /* Clips that share a payload in the template share it here too. */
            memcpy(r + 16, clips + (size_t)order[i - 1] * MCD_CLIP_RECORD_SIZE + 16u, 8);
        } else {
            int last = mcd_rd_u32(tr + 16) ==
                       mcd_rd_u32(in_clips + (size_t)order[codec_clips - 1] * MCD_CLIP_RECORD_SIZE + 16u);
            payload_range(sec, n, next_start, mcd_rd_u32(tr + 20), last, &off, &size);
            wr_u32(r + 16, (uint32_t)off);
            wr_u32(r + 20, (uint32_t)size);
            next_start = (off + size + 3u) & ~(size_t)3u;
        }
        if (skel < skel_count && section_ok) {
            uint32_t need;
            if (clip_scratch(ops, section, n, r, out + mcd_rd_u32(entry(out, skel_index[skel]) + 8), &need))
                wr_u32(r + 40, need);
        }
    }
    return pos;
}

static int by_name(const void* a, const void* b) {
    return strcmp(((const fuzz_template*)a)->name, ((const fuzz_template*)b)->name);
}

static uint8_t* read_file(const char* path, size_t* size) {
    FILE* f = fopen(path, "rb");
    uint8_t* data = NULL;
    long n;
    if (!f) return NULL;
    if (fseek(f, 0, SEEK_END) == 0 && (n = ftell(f)) > 0 && fseek(f, 0, SEEK_SET) == 0 &&
        (data = (uint8_t*)malloc((size_t)n)) != NULL && fread(data, 1, (size_t)n, f) != (size_t)n) {
        free(data);
        data = NULL;
    }
    fclose(f);
    if (data) *size = (size_t)n;
    return data;
}

/* Every asset of `dir` that validates and holds this codec's section with a clip in it. */
static void load_templates(const char* dir) {
    const mcd_codec_ops* ops = mcd_find_codec(FUZZ_CODEC);
    DIR* d = opendir(dir);
    struct dirent* e;
    if (!ops) fail("unknown codec", NULL);
    if (!d) fail("cannot list the template folder", dir);
    while ((e = readdir(d)) != NULL && g_template_count < MAX_TEMPLATES) {
        fuzz_template* t = &g_templates[g_template_count];
        size_t len = strlen(e->d_name);
        char path[4096];
        uint32_t i, count;
        if (len < 5 || strcmp(e->d_name + len - 4, ".mcd") != 0 || len >= sizeof t->name) continue;
        if ((size_t)snprintf(path, sizeof path, "%s/%s", dir, e->d_name) >= sizeof path) continue;
        t->data = read_file(path, &t->size);
        if (!t->data) fail("cannot read", path);
        if (mcd_validate(t->data, t->size, 0) != MCD_OK) fail("a template does not validate", path);
        count = mcd_rd_u32(t->data + 24);
        for (i = 0; i < count && mcd_rd_u32(entry(t->data, i)) != ops->section_kind; ++i) {
        }
        if (i == count) {
            free(t->data);
            continue;
        }
        t->section = i;
        t->ops = mcd_find_codec_version(FUZZ_CODEC, mcd_rd_u32(entry(t->data, i) + 4));
        if (!t->ops) fail("a template's section version has no reader", path); /* it validated */
        memcpy(t->name, e->d_name, len + 1);
        ++g_template_count;
    }
    closedir(d);
    if (g_template_count == 0) fail("no template asset holds this codec's section in", dir);
    qsort(g_templates, g_template_count, sizeof g_templates[0], by_name);
}

/* Input `i`'s seed: its index and its own section. */
static uint8_t* template_seed(const fuzz_template* t, uint32_t i, size_t* size) {
    size_t n = mcd_rd_u32(entry(t->data, t->section) + 12);
    uint8_t* seed = (uint8_t*)malloc(n + 1u);
    if (!seed) fail("out of memory", NULL);
    seed[0] = (uint8_t)i;
    memcpy(seed + 1, t->data + mcd_rd_u32(entry(t->data, t->section) + 8), n);
    *size = n + 1u;
    return seed;
}

static void write_seeds(const char* dir) {
    uint32_t i;
    for (i = 0; i < g_template_count; ++i) {
        char path[4096];
        size_t size;
        uint8_t* seed = template_seed(&g_templates[i], i, &size);
        FILE* f;
        if ((size_t)snprintf(path, sizeof path, "%s/%s.section", dir, g_templates[i].name) >= sizeof path)
            fail("seed path too long", dir);
        f = fopen(path, "wb");
        if (!f || fwrite(seed, 1, size, f) != size || fclose(f) != 0) fail("cannot write a seed", path);
        free(seed);
    }
}

int LLVMFuzzerInitialize(int* argc, char*** argv) {
    const char* dir = getenv("MCD_FUZZ_GOLDEN");
    const char* seeds = getenv("MCD_FUZZ_WRITE_SEEDS");
    uint32_t i;
    (void)argc;
    (void)argv;
    load_templates(dir && dir[0] ? dir : MCD_FUZZ_GOLDEN_DIR);
    /* The splice must be exact: each template's own section gives the template back, byte for
     * byte (offsets, payload ranges, scratch sizes; the CRC is left as it was). */
    for (i = 0; i < g_template_count; ++i) {
        size_t seed_size, size;
        uint8_t* seed = template_seed(&g_templates[i], i, &seed_size);
        uint8_t* out = (uint8_t*)malloc(g_templates[i].size + seed_size + 16u);
        if (!out) fail("out of memory", NULL);
        size = splice(&g_templates[i], seed + 1, seed_size - 1u, out);
        if (size != g_templates[i].size || memcmp(out, g_templates[i].data, size) != 0)
            fail("splicing a template's own section does not give the template back", g_templates[i].name);
        free(out);
        free(seed);
    }
    if (seeds && seeds[0]) {
        write_seeds(seeds);
        exit(0);
    }
    g_asset_out = getenv("MCD_FUZZ_ASSET_OUT");
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    const fuzz_template* t;
    uint8_t *room, *asset;
    size_t asset_size;
    char why[256];
    if (size < 1 || g_template_count == 0) return 0;
    t = &g_templates[data[0] % g_template_count];
    room = (uint8_t*)malloc(t->size + size + 16u);
    if (!room) fail("out of memory", NULL);
    asset_size = splice(t, data + 1, size - 1u, room);
    /* A copy of exactly the asset's size: ASan sees any read past its end. */
    asset = (uint8_t*)malloc(asset_size);
    if (!asset) fail("out of memory", NULL);
    memcpy(asset, room, asset_size);
    free(room);
    if (g_asset_out && g_asset_out[0]) {
        FILE* f = fopen(g_asset_out, "wb");
        wr_u32(asset + 20, mcd_crc32(asset + 24, asset_size - 24u));
        if (!f || fwrite(asset, 1, asset_size, f) != asset_size || fclose(f) != 0) fail("cannot write", g_asset_out);
    }
    if (mcd_exercise(asset, asset_size, MCD_VALIDATE_SKIP_CHECKSUM, MAX_CLIPS, why, sizeof why) == MCD_EXERCISE_BROKEN) {
        fprintf(stderr, "mocodec promise broken (template %s): %s\n", t->name, why);
        abort();
    }
    free(asset);
    return 0;
}
