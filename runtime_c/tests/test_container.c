/* Rules of the format-2 container (docs/FORMAT.md, mocodec.h): format-1 assets are refused, clip
 * and node names that could steer a path or confuse a reader are malformed, SKEL version 2
 * records (rest rotation unit, end sites and virtual points as leaves), a prevalidated open
 * that reads no payload byte, and clip data ranges that hold everything sampling a clip reads.
 * Each edit of a golden asset rewrites the checksum, so the answer comes from the rule. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifndef _WIN32 /* the read check of a prevalidated open needs fork and mprotect */
#include <sys/mman.h>
#include <sys/wait.h>
#include <unistd.h>
#define MCD_HAVE_FORK 1
#endif

#include "harness.h"

#define MAX_NODES 1024u
#define SKEL_NODE 32u /* bytes of a SKEL version 2 node record */
#define SKEL_REST 28u /* bytes of a rest-table entry: rotation x y z w, scale x y z */

/* ---------------------------------------------------------------- format 1 */

/* tests/golden/v1 holds the assets mocodec 0.1 wrote: every entry point says VERSION_TOO_OLD. */
void test_format1_refused(void) {
    mcd_test_file* files;
    size_t n = mcd_test_list_files(mcd_test_golden_v1_dir(), ".mcd", &files), i;
    CHECK_MSG(n > 0, "no format-1 assets in %s", mcd_test_golden_v1_dir());
    for (i = 0; i < n; ++i) {
        const mcd_test_file* f = &files[i];
        mcd_asset a;
        CHECK_MSG(f->size >= 32 && f->data[8] == 1 && f->data[9] == 0, "%s: not a format-1 asset", f->path);
        CHECK_RESULT(mcd_validate(f->data, f->size, 0), MCD_ERROR_VERSION_TOO_OLD);
        CHECK_RESULT(mcd_validate(f->data, f->size, MCD_VALIDATE_SKIP_CHECKSUM), MCD_ERROR_VERSION_TOO_OLD);
        CHECK_RESULT(mcd_open(f->data, f->size, 0, &a), MCD_ERROR_VERSION_TOO_OLD);
        CHECK_RESULT(mcd_open(f->data, f->size, MCD_VALIDATE_SKIP_CHECKSUM, &a), MCD_ERROR_VERSION_TOO_OLD);
        CHECK_RESULT(mcd_open(f->data, f->size, MCD_OPEN_PREVALIDATED, &a), MCD_ERROR_VERSION_TOO_OLD);
    }
    mcd_test_free_files(files, n);
}

/* ---------------------------------------------------------------- names */

typedef struct name_case {
    const char* bytes;
    size_t length; /* 0: strlen(bytes) */
    mcd_result clip; /* as a clip name */
    mcd_result node; /* as a node name */
} name_case;

/* Clip names become file names when an asset is decoded, so nothing that steers a path; node
 * names only have to be clean text. */
static const name_case k_names[] = {
    {"walk_01", 0, MCD_OK, MCD_OK},
    {"a.b", 0, MCD_OK, MCD_OK},
    {"...", 0, MCD_OK, MCD_OK},
    {"Gehen \xc3\xa4\xc3\xb6\xc3\xbc", 0, MCD_OK, MCD_OK},  /* two-byte UTF-8 */
    {"\xe6\xad\xa9\xe3\x81\x8f", 0, MCD_OK, MCD_OK},        /* three-byte */
    {"run \xf0\x9f\x8f\x83", 0, MCD_OK, MCD_OK},            /* four-byte */
    {"a/b", 0, MCD_ERROR_MALFORMED, MCD_OK},
    {"/", 0, MCD_ERROR_MALFORMED, MCD_OK},
    {"a\\b", 0, MCD_ERROR_MALFORMED, MCD_OK},
    {"c:walk", 0, MCD_ERROR_MALFORMED, MCD_OK},
    {"..", 0, MCD_ERROR_MALFORMED, MCD_OK},
    {".", 0, MCD_ERROR_MALFORMED, MCD_OK},
    {"", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},
    {"a\x01" "b", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},
    {"tab\tname", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},
    {"new\nline", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},
    {"\x1f", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},
    {"del\x7f", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},
    {"c1 \xc2\x80", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},          /* U+0080, a C1 control */
    {"\xff", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},                 /* never in UTF-8 */
    {"a\x80", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},                /* lone continuation */
    {"\xc0\xaf", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},             /* overlong '/' */
    {"\xe0\x80\xaf", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},         /* overlong, three bytes */
    {"\xed\xa0\x80", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},         /* a surrogate */
    {"\xf4\x90\x80\x80", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},     /* past U+10FFFF */
    {"cut \xc3", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},             /* sequence cut by the NUL */
    {"cut \xe2\x82", 0, MCD_ERROR_MALFORMED, MCD_ERROR_MALFORMED},
};

/* `section` (index in the table) rebuilt with `name` appended to its string block (which runs
 * from `strings` to the end) and the name field at `name_field` pointing at it; `nul` 0 leaves
 * the name unterminated at the end of the block. Returns the validate result. */
static mcd_result validate_with_name(const mcd_test_file* f, uint32_t section, uint32_t strings, uint32_t name_field,
                                     const char* name, size_t length, int nul) {
    const uint8_t* e = f->data + 32 + 16 * (size_t)section;
    uint32_t off = mcd_test_rd_u32(e + 8), size = mcd_test_rd_u32(e + 12);
    size_t grown = size + length + 1u, out_size = 0;
    uint8_t* s = (uint8_t*)malloc(grown);
    uint8_t* asset;
    mcd_result r = MCD_ERROR_INVALID_ARGUMENT;
    if (!s) return r;
    memcpy(s, f->data + off, size);
    memcpy(s + size, name, length);
    s[size + length] = 0;
    mcd_test_wr_u32(s + name_field, size - strings);
    asset = mcd_test_replace_section(f->data, section, s, (uint32_t)(nul ? grown : grown - 1u), &out_size);
    if (asset) {
        r = mcd_validate(asset, out_size, 0);
        free(asset);
    }
    free(s);
    return r;
}

static void check_names(const mcd_test_file* f, uint32_t section, uint32_t strings, uint32_t name_field, int is_clip) {
    char long_name[300];
    size_t i;
    const char* what = is_clip ? "clip" : "node";
    for (i = 0; i < sizeof k_names / sizeof k_names[0]; ++i) {
        const name_case* c = &k_names[i];
        size_t len = c->length ? c->length : strlen(c->bytes);
        mcd_result want = is_clip ? c->clip : c->node;
        mcd_result r = validate_with_name(f, section, strings, name_field, c->bytes, len, 1);
        CHECK_MSG(r == want, "%s: %s name \"%s\" (%lu bytes) gave %s, expected %s", f->path, what, c->bytes,
                  (unsigned long)len, mcd_result_string(r), mcd_result_string(want));
    }
    /* At most 255 bytes (without the NUL). */
    memset(long_name, 'a', sizeof long_name);
    CHECK_RESULT(validate_with_name(f, section, strings, name_field, long_name, 255, 1), MCD_OK);
    CHECK_RESULT(validate_with_name(f, section, strings, name_field, long_name, 256, 1), MCD_ERROR_MALFORMED);
    CHECK_RESULT(validate_with_name(f, section, strings, name_field, long_name, 299, 1), MCD_ERROR_MALFORMED);
    /* The NUL inside the block. */
    CHECK_RESULT(validate_with_name(f, section, strings, name_field, "walk", 4, 0), MCD_ERROR_MALFORMED);
}

/* Every name case as clip 0's name and as node 0's name, in every golden asset. */
void test_name_rules(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    for (i = 0; i < n; ++i) {
        const mcd_test_file* f = &g[i].file;
        uint32_t clip_index = 0, skel_index = 0;
        const uint8_t* clip = mcd_test_section(f->data, "CLIP", 0, &clip_index);
        const uint8_t* skel = mcd_test_section(f->data, "SKEL", 0, &skel_index);
        if (!clip || !skel) {
            FAIL("%s: no CLIP or SKEL section", f->path);
            continue;
        }
        /* CLIP: count, string block offset, records (name offset first); SKEL: node count,
         * reserved, cm per unit, string block offset, records (parent, then name offset). */
        check_names(f, clip_index, mcd_test_rd_u32(f->data + mcd_test_rd_u32(clip + 8) + 4), 8, 1);
        check_names(f, skel_index, mcd_test_rd_u32(f->data + mcd_test_rd_u32(skel + 8) + 12), 16 + 4, 0);
    }
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- SKEL version 2 */

typedef struct skel_edit {
    uint32_t node;  /* UINT32_MAX: the section header */
    uint32_t at;    /* byte in the node record, the node's rest-table entry, or the header */
    int width;      /* 1 or 4 */
    uint32_t value; /* bits */
    mcd_result want;
    const char* what;
} skel_edit;

#define HDR UINT32_MAX
#define REST_T 8u
#define KIND 20u
#define CHANNELS 21u
#define RESERVED 28u
#define REST_R 0u  /* in the rest-table entry */
#define REST_S 16u /* in the rest-table entry */

/* Apply each edit to a copy of `f` (skeleton at `skel`, `nodes` nodes); `rest_table`: the
 * edits address the node's rest-table entry instead of its record. */
static void apply_skel_edits(const mcd_test_file* f, uint32_t skel, uint32_t nodes, int rest_table,
                             const skel_edit* edits, size_t count) {
    uint8_t* copy = mcd_test_copy(f->data, f->size);
    size_t i;
    for (i = 0; copy && i < count; ++i) {
        const skel_edit* d = &edits[i];
        uint32_t base = d->node == HDR ? 0u
                        : rest_table  ? 16u + SKEL_NODE * nodes + SKEL_REST * d->node
                                      : 16u + SKEL_NODE * d->node;
        uint8_t* p = copy + skel + base + d->at;
        mcd_result r;
        memcpy(copy, f->data, f->size);
        if (d->width == 4) mcd_test_wr_u32(p, d->value);
        else *p = (uint8_t)d->value;
        mcd_test_fix_crc(copy, f->size);
        r = mcd_validate(copy, f->size, 0);
        CHECK_MSG(r == d->want, "%s: SKEL %s: %s, expected %s", f->path, d->what, mcd_result_string(r), mcd_result_string(d->want));
    }
    free(copy);
}

/* Node numbers of the CMU skeleton (test_golden.c checks them): 0 Hips (6 channels), 1
 * LHipJoint (3 channels, children), 6 the first End Site, 7 RHipJoint (a child of Hips). */
static void check_skeleton_edits(const mcd_test_file* f) {
    const skel_edit edits[] = {
        {6, REST_T, 4, 0x7FC00000u, MCD_ERROR_MALFORMED, "rest translation NaN"},
        {6, REST_T + 4, 4, 0x7F800000u, MCD_ERROR_MALFORMED, "rest translation inf"},
        {6, REST_T + 8, 4, mcd_test_f32_bits(2e7f), MCD_ERROR_MALFORMED, "rest translation 2e7"},
        {6, REST_T + 8, 4, mcd_test_f32_bits(-1e6f), MCD_OK, "rest translation -1e6"},
        {6, KIND, 1, 3, MCD_ERROR_MALFORMED, "kind 3"},
        {6, KIND, 1, 255, MCD_ERROR_MALFORMED, "kind 255"},
        {6, KIND, 1, 2, MCD_OK, "end site made virtual"},
        {6, KIND, 1, 0, MCD_OK, "end site made a joint without channels"},
        {1, KIND, 1, 1, MCD_ERROR_MALFORMED, "joint with channels and children made an end site"},
        {1, KIND, 1, 2, MCD_ERROR_MALFORMED, "joint with channels and children made virtual"},
        {7, 0, 4, 6, MCD_ERROR_MALFORMED, "a joint hung below an end site"},
        {7, 0, 4, 7, MCD_ERROR_MALFORMED, "its own parent"},
        {7, 0, 4, 8, MCD_ERROR_MALFORMED, "parent after it"},
        {7, 0, 4, 0xFFFFFFFEu, MCD_ERROR_MALFORMED, "parent -2"},
        {7, 0, 4, 2, MCD_OK, "a joint hung below another joint"},
        {1, CHANNELS, 1, 7, MCD_ERROR_MALFORMED, "7 channels"},
        {1, CHANNELS + 1, 1, 6, MCD_ERROR_MALFORMED, "channel code 6"},
        {1, CHANNELS + 2, 1, 5, MCD_ERROR_MALFORMED, "a channel twice (Z rotation)"},
        {1, CHANNELS + 4, 1, 0, MCD_ERROR_MALFORMED, "unused channel slot not 0xFF"},
        {6, CHANNELS, 1, 1, MCD_ERROR_MALFORMED, "an end site with a channel"},
        {1, RESERVED, 4, 1, MCD_ERROR_MALFORMED, "node reserved word 1"},
        {HDR, 0, 4, 0, MCD_ERROR_MALFORMED, "node count 0"},
        {HDR, 0, 4, 1025, MCD_ERROR_MALFORMED, "node count 1025"},
        {HDR, 4, 4, 1, MCD_ERROR_MALFORMED, "rest-table flag without the table"},
        {HDR, 4, 4, 2, MCD_ERROR_MALFORMED, "flags bit 1"},
        {HDR, 8, 4, mcd_test_f32_bits(0.0f), MCD_ERROR_MALFORMED, "cm per unit 0"},
        {HDR, 8, 4, mcd_test_f32_bits(-1.0f), MCD_ERROR_MALFORMED, "cm per unit -1"},
        {HDR, 8, 4, 0x7FC00000u, MCD_ERROR_MALFORMED, "cm per unit NaN"},
        {HDR, 12, 4, 16u + 38u * SKEL_NODE - 4u, MCD_ERROR_MALFORMED, "string block inside the records"},
    };
    uint32_t skel;
    const uint8_t* e = mcd_test_section(f->data, "SKEL", 0, NULL);
    uint8_t* copy;
    if (!e || mcd_test_rd_u32(f->data + mcd_test_rd_u32(e + 8)) != 38u || mcd_test_rd_u32(f->data + mcd_test_rd_u32(e + 8) + 4) != 0) {
        FAIL("%s: no 38-node SKEL section without a rest table", f->path);
        return;
    }
    skel = mcd_test_rd_u32(e + 8);
    apply_skel_edits(f, skel, 38u, 0, edits, sizeof edits / sizeof edits[0]);
    /* The leaf rule holds for virtual points too: make node 6 virtual, then hang node 7 below it. */
    copy = mcd_test_copy(f->data, f->size);
    if (copy) {
        copy[skel + 16u + SKEL_NODE * 6u + KIND] = 2;
        mcd_test_wr_u32(copy + skel + 16u + SKEL_NODE * 7u, 6);
        mcd_test_fix_crc(copy, f->size);
        CHECK_RESULT(mcd_validate(copy, f->size, 0), MCD_ERROR_MALFORMED);
    }
    free(copy);
}

/* The rest table (SKEL flags bit 0), on the skeletons that have one. */
static void check_rest_table_edits(const mcd_test_file* f, uint32_t* checked) {
    const skel_edit edits[] = {
        {1, REST_R + 12, 4, 0x7FC00000u, MCD_ERROR_MALFORMED, "rest rotation w NaN"},
        {1, REST_R + 4, 4, 0x7F800000u, MCD_ERROR_MALFORMED, "rest rotation y inf"},
        {1, REST_S, 4, 0x7FC00000u, MCD_ERROR_MALFORMED, "rest scale NaN"},
        {1, REST_S + 4, 4, mcd_test_f32_bits(-2e7f), MCD_ERROR_MALFORMED, "rest scale -2e7"},
        {1, REST_S + 8, 4, mcd_test_f32_bits(2.5f), MCD_OK, "rest scale 2.5"},
    };
    uint32_t k;
    const uint8_t* e;
    for (k = 0; (e = mcd_test_section(f->data, "SKEL", k, NULL)) != NULL; ++k) {
        uint32_t skel = mcd_test_rd_u32(e + 8), nodes = mcd_test_rd_u32(f->data + skel);
        uint8_t* copy;
        uint32_t at;
        if (mcd_test_rd_u32(f->data + skel + 4) != 1u || nodes < 2) continue;
        apply_skel_edits(f, skel, nodes, 1, edits, sizeof edits / sizeof edits[0]);
        /* Node 1's rest rotation made exactly (0 0 0 1), then off the unit sphere by a margin,
         * so the unit rule is checked against a known quaternion. */
        copy = mcd_test_copy(f->data, f->size);
        at = skel + 16u + SKEL_NODE * nodes + SKEL_REST * 1u;
        if (copy) {
            static const float unit[4] = {0.0f, 0.0f, 0.0f, 1.0f};
            static const struct { float value; mcd_result want; const char* what; } w[] = {
                {1.0f + 0.9e-5f, MCD_OK, "1 + 0.9e-5"},     {1.0f - 0.9e-5f, MCD_OK, "1 - 0.9e-5"},
                {1.0f + 1.1e-5f, MCD_ERROR_MALFORMED, "1 + 1.1e-5"}, {1.0f - 1.1e-5f, MCD_ERROR_MALFORMED, "1 - 1.1e-5"},
                {0.0f, MCD_ERROR_MALFORMED, "0"},           {-1.0f, MCD_OK, "-1"},
            };
            uint32_t c;
            for (c = 0; c < 4; ++c) mcd_test_wr_u32(copy + at + 4u * c, mcd_test_f32_bits(unit[c]));
            mcd_test_fix_crc(copy, f->size);
            CHECK_RESULT(mcd_validate(copy, f->size, 0), MCD_OK);
            for (c = 0; c < sizeof w / sizeof w[0]; ++c) {
                mcd_test_wr_u32(copy + at + 12u, mcd_test_f32_bits(w[c].value));
                mcd_test_fix_crc(copy, f->size);
                CHECK_MSG(mcd_validate(copy, f->size, 0) == w[c].want, "%s: SKEL rest rotation (0 0 0 %s)", f->path, w[c].what);
            }
        }
        free(copy);
        ++*checked;
    }
}

/* On the spline goldens, whose payloads do not depend on the rest pose or the hierarchy, so
 * that an accepted edit is accepted by the SKEL rules and the codec alike. */
void test_skeleton_rules(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    uint32_t checked = 0, rest_tables = 0;
    for (i = 0; i < n; ++i) {
        mcd_clip_info ci;
        if (mcd_get_clip_info(&g[i].asset, 0, &ci) != MCD_OK || ci.codec != MCD_CODEC_SPLINE) continue;
        check_skeleton_edits(&g[i].file);
        check_rest_table_edits(&g[i].file, &rest_tables);
        checked++;
    }
    CHECK_MSG(checked > 0, "no spline golden asset");
    CHECK_MSG(rest_tables > 0, "no spline golden asset with a SKEL rest table");
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- prevalidated open */

/* True when section `e` is part of the container a prevalidated open reads: SKEL and CLIP. */
static int container_section(const uint8_t* e) {
    return memcmp(e, "SKEL", 4) == 0 || memcmp(e, "CLIP", 4) == 0;
}

#ifdef MCD_HAVE_FORK

/* Open `data` with `flags` and call every query, with every byte from `protect_from` on made
 * unreadable, in a child process; returns its wait status. `quiet` silences the child's
 * stderr (the crash a validating open must cause there). */
static int open_in_child(const uint8_t* data, size_t size, size_t protect_from, uint32_t flags, int quiet) {
    long page = sysconf(_SC_PAGESIZE);
    size_t p = page > 0 ? (size_t)page : 4096u, shift = (p - protect_from % p) % p, total;
    uint8_t* base = NULL;
    void* scratch = NULL;
    int status = -1;
    pid_t pid;
    total = (shift + size + p - 1u) / p * p;
    if (posix_memalign((void**)&base, p, total) != 0 || posix_memalign(&scratch, 16, 1u << 16) != 0) {
        FAIL("out of memory");
        free(base);
        return -1;
    }
    memcpy(base + shift, data, size);
    fflush(NULL);
    pid = fork();
    if (pid == 0) {
        mcd_asset a;
        uint32_t c, s, k, found;
        if (quiet && !freopen("/dev/null", "w", stderr)) _exit(20);
        if (mprotect(base + shift + protect_from, total - shift - protect_from, PROT_NONE) != 0) _exit(21);
        if (mcd_open(base + shift, size, flags, &a) != MCD_OK) _exit(10);
        for (c = 0; c < mcd_clip_count(&a); ++c) {
            mcd_clip_info ci;
            if (mcd_get_clip_info(&a, c, &ci) != MCD_OK || mcd_find_clip(&a, ci.name, &found) != MCD_OK) _exit(11);
        }
        for (s = 0; s < mcd_skeleton_count(&a); ++s) {
            mcd_skeleton_info si;
            mcd_node_info ni;
            if (mcd_get_skeleton_info(&a, s, &si) != MCD_OK) _exit(12);
            for (k = 0; k < si.node_count; ++k)
                if (mcd_get_node_info(&a, s, k, &ni) != MCD_OK) _exit(13);
        }
        if (mcd_scratch_size(&a) > (1u << 16) || mcd_scratch_init(&a, scratch, mcd_scratch_size(&a)) != MCD_OK) _exit(14);
        _exit(0);
    }
    if (pid < 0) FAIL("fork failed");
    else if (waitpid(pid, &status, 0) != pid) FAIL("waitpid failed");
    free(scratch);
    free(base);
    return status;
}

static int exited_ok(int status) {
    return status != -1 && WIFEXITED(status) && WEXITSTATUS(status) == 0;
}

/* The bytes behind the container (codec sections, META, CNTC) made unreadable: a prevalidated
 * open and every query still work, so their cost does not grow with the payloads (O(clips +
 * sections)); a validating open does read them (the control that the protection works). */
static void check_reads_no_payload(const mcd_golden* g) {
    const uint8_t* d = g->file.data;
    uint32_t i, count = mcd_test_rd_u32(d + 24), first = (uint32_t)g->file.size, container_end = 0;
    int status;
    for (i = 0; i < count; ++i) {
        const uint8_t* e = d + 32 + 16 * (size_t)i;
        uint32_t off = mcd_test_rd_u32(e + 8), end = off + mcd_test_rd_u32(e + 12);
        if (container_section(e)) container_end = end > container_end ? end : container_end;
        else if (off < first) first = off;
    }
    if (container_end > first || first >= g->file.size) {
        FAIL("%s: SKEL and CLIP are not the first sections", g->file.path);
        return;
    }
    status = open_in_child(d, g->file.size, first, MCD_OPEN_PREVALIDATED, 0);
    CHECK_MSG(exited_ok(status), "%s: prevalidated open touched bytes past the container (offset %u on): status 0x%x",
              g->file.path, first, (unsigned)status);
    status = open_in_child(d, g->file.size, first, 0, 1);
    CHECK_MSG(status != -1 && !exited_ok(status), "%s: a validating open did not read the payloads", g->file.path);
}
#endif

/* Validated bytes whose payloads are then overwritten: a prevalidated open does not look at
 * them (and reports the same clips), a validating open refuses them. */
static void check_ignores_payload(const mcd_golden* g) {
    uint8_t* copy = mcd_test_copy(g->file.data, g->file.size);
    uint32_t c;
    mcd_asset a;
    if (!copy) return;
    for (c = 0; c < mcd_clip_count(&g->asset); ++c) {
        mcd_clip_info ci;
        CHECK_RESULT(mcd_get_clip_info(&g->asset, c, &ci), MCD_OK);
        memset(copy + ci.data_offset, 0xFF, ci.data_size);
    }
    CHECK_RESULT(mcd_validate(copy, g->file.size, 0), MCD_ERROR_CHECKSUM);
    CHECK(mcd_validate(copy, g->file.size, MCD_VALIDATE_SKIP_CHECKSUM) != MCD_OK);
    CHECK(mcd_open(copy, g->file.size, MCD_VALIDATE_SKIP_CHECKSUM, &a) != MCD_OK);
    CHECK_RESULT(mcd_open(copy, g->file.size, MCD_OPEN_PREVALIDATED, &a), MCD_OK);
    CHECK_RESULT(mcd_open(copy, g->file.size, MCD_OPEN_PREVALIDATED | MCD_VALIDATE_SKIP_CHECKSUM, &a), MCD_OK);
    CHECK(mcd_clip_count(&a) == mcd_clip_count(&g->asset) && mcd_scratch_size(&a) == mcd_scratch_size(&g->asset));
    for (c = 0; c < mcd_clip_count(&a) && c < mcd_clip_count(&g->asset); ++c) {
        mcd_clip_info x, y;
        CHECK_RESULT(mcd_get_clip_info(&a, c, &x), MCD_OK);
        CHECK_RESULT(mcd_get_clip_info(&g->asset, c, &y), MCD_OK);
        CHECK(strcmp(x.name, y.name) == 0 && x.frame_count == y.frame_count && x.scratch_size == y.scratch_size &&
              x.data_offset == y.data_offset && x.data_size == y.data_size && x.codec == y.codec);
    }
    free(copy);
}

void test_prevalidated_open(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    for (i = 0; i < n; ++i) {
        check_ignores_payload(&g[i]);
#ifdef MCD_HAVE_FORK
        check_reads_no_payload(&g[i]);
#endif
    }
#ifndef MCD_HAVE_FORK
    printf("  prevalidated_open: NOT RUN here: the check that no payload byte is read (fork + mprotect) is POSIX only\n");
#endif
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- clip data ranges */

/* Sampling clip `clip` reads the container, its data range, (with contacts) the CNTC section and,
 * for rma-pca, its RMAP section's shared part [0, shared_end) (mocodec.h, mcd_clip_info;
 * docs/FORMAT.md), nothing else: with every other byte overwritten by `fill`, every frame and
 * midpoint samples to the same bytes as the intact asset. */
static void check_range_suffices(const mcd_golden* g, uint32_t clip, uint8_t fill, mcd_transform* p, mcd_transform* q) {
    static const uint32_t flag_sets[3] = {0, MCD_SAMPLE_WORLD | MCD_SAMPLE_CONTACTS, MCD_SAMPLE_NEAREST | MCD_SAMPLE_LOOP};
    const uint8_t* d = g->file.data;
    uint32_t i, count = mcd_test_rd_u32(d + 24), k, f, differ = 0;
    uint8_t* copy = mcd_test_copy(d, g->file.size);
    mcd_clip_info ci;
    mcd_asset a;
    void *s1, *s2;
    if (!copy) return;
    CHECK_RESULT(mcd_get_clip_info(&g->asset, clip, &ci), MCD_OK);
    for (i = 0; i < count; ++i) {
        const uint8_t* e = d + 32 + 16 * (size_t)i;
        uint32_t off = mcd_test_rd_u32(e + 8), end = off + mcd_test_rd_u32(e + 12), b;
        if (container_section(e) || memcmp(e, "CNTC", 4) == 0) continue;
        /* RMAP header: shared_end at byte 24 (the golden is valid, so it lies in the section). */
        if (memcmp(e, "RMAP", 4) == 0) off += mcd_test_rd_u32(d + off + 24);
        for (b = off; b < end; ++b)
            if (b < ci.data_offset || b >= ci.data_offset + ci.data_size) copy[b] = fill;
    }
    CHECK_RESULT(mcd_open(copy, g->file.size, MCD_OPEN_PREVALIDATED, &a), MCD_OK);
    s1 = mcd_test_scratch(&g->asset);
    s2 = mcd_test_scratch_sized(&a, ci.scratch_size);
    for (f = 0; s1 && s2 && f < 3; ++f) {
        for (k = 0; k < 2u * ci.frame_count - 1u; ++k) {
            float t = (float)(0.5 * k / ci.frame_rate);
            CHECK_RESULT(mcd_sample(&g->asset, clip, t, flag_sets[f], p, MAX_NODES, s1), MCD_OK);
            CHECK_RESULT(mcd_sample(&a, clip, t, flag_sets[f], q, MAX_NODES, s2), MCD_OK);
            differ += memcmp(p, q, ci.node_count * sizeof *p) != 0;
        }
    }
    CHECK_MSG(differ == 0, "%s clip %u: %u samples read bytes outside [%u, %u) (filled with 0x%02x)", g->file.path, clip,
              differ, ci.data_offset, ci.data_offset + ci.data_size, fill);
    mcd_test_free_scratch(s1);
    mcd_test_free_scratch(s2);
    free(copy);
}

/* Where the range is: inside the one codec section the clip's record names, and holding at
 * least the payload the record states (offset and size in the CLIP section, version 2). */
static void check_range_place(const mcd_golden* g, uint32_t clip) {
    const uint8_t* d = g->file.data;
    const uint8_t* e = mcd_test_section(d, "CLIP", 0, NULL);
    const uint8_t* rec;
    const uint8_t* section;
    mcd_clip_info ci;
    uint32_t off, size;
    CHECK_RESULT(mcd_get_clip_info(&g->asset, clip, &ci), MCD_OK);
    if (!e) return;
    rec = d + mcd_test_rd_u32(e + 8) + 8u + 48u * clip;
    section = d + 32 + 16 * (size_t)mcd_test_rd_u32(rec + 12);
    off = mcd_test_rd_u32(section + 8);
    size = mcd_test_rd_u32(section + 12);
    CHECK_MSG(ci.data_offset >= off && (uint64_t)ci.data_offset + ci.data_size <= (uint64_t)off + size,
              "%s clip %u: data [%u, +%u) outside its section [%u, +%u)", g->file.path, clip, ci.data_offset, ci.data_size,
              off, size);
    CHECK_MSG(ci.data_offset <= off + mcd_test_rd_u32(rec + 16) &&
                  (uint64_t)ci.data_offset + ci.data_size >= (uint64_t)off + mcd_test_rd_u32(rec + 16) + mcd_test_rd_u32(rec + 20),
              "%s clip %u: data [%u, +%u) does not hold its payload", g->file.path, clip, ci.data_offset, ci.data_size);
}

void test_clip_data_ranges(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    mcd_transform* p = (mcd_transform*)malloc(MAX_NODES * sizeof *p);
    mcd_transform* q = (mcd_transform*)malloc(MAX_NODES * sizeof *q);
    for (i = 0; p && q && i < n; ++i) {
        uint32_t c;
        for (c = 0; c < mcd_clip_count(&g[i].asset); ++c) {
            check_range_place(&g[i], c);
            check_range_suffices(&g[i], c, 0x00, p, q);
            check_range_suffices(&g[i], c, 0xFF, p, q);
        }
    }
    free(p);
    free(q);
    mcd_test_free_golden(g, n);
}
