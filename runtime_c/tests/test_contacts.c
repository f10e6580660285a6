/* Contacts (docs/FORMAT.md "Contacts — CNTC section", src/contacts.c): the IK solvers on
 * their own, the validation of every rule of the section on the golden asset that carries one,
 * and that the flag changes nothing unless asked for and a clip has contacts. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../src/contacts.h" /* internal header: the tests build with -Iinclude only */
#include "harness.h"

#define CONTACTS_GOLDEN "spline_contacts_02_01.mcd"
#define MAX_NODES 1024u

/* ---------------------------------------------------------------- solver helpers */
static double dist3(const float a[3], const double b[3]) {
    double x = a[0] - b[0], y = a[1] - b[1], z = a[2] - b[2];
    return sqrt(x * x + y * y + z * z);
}
static double len3d(const double a[3]) {
    return sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}
static void rotate(mcd_quat q, const double v[3], double out[3]) {
    float vf[3], of[3];
    vf[0] = (float)v[0]; vf[1] = (float)v[1]; vf[2] = (float)v[2];
    mcd_qrotate(q, vf, of);
    out[0] = of[0]; out[1] = of[1]; out[2] = of[2];
}
/* New knee and ankle after the two-bone rotations: c' = a + da((b - a) + db(c - b)). */
static void apply_two_bone(const float a[3], const float b[3], const float c[3], mcd_quat da, mcd_quat db,
                           double b2[3], double c2[3]) {
    double ab[3], bc[3], r1[3], r2[3], s[3];
    int k;
    for (k = 0; k < 3; ++k) { ab[k] = (double)b[k] - a[k]; bc[k] = (double)c[k] - b[k]; }
    rotate(db, bc, r1);
    for (k = 0; k < 3; ++k) s[k] = ab[k] + r1[k];
    rotate(da, s, r2);
    rotate(da, ab, r1);
    for (k = 0; k < 3; ++k) { b2[k] = a[k] + r1[k]; c2[k] = a[k] + r2[k]; }
}

void test_contacts_two_bone_reaches(void) {
    /* A bent leg (hip at the origin, y up) and reachable targets all around it. */
    const float a[3] = {0.0f, 0.0f, 0.0f}, b[3] = {0.1f, -0.45f, 0.08f}, c[3] = {0.05f, -0.9f, -0.02f};
    uint32_t rng = 7u, i;
    double l1 = sqrt(0.1 * 0.1 + 0.45 * 0.45 + 0.08 * 0.08), l2 = sqrt(0.05 * 0.05 + 0.45 * 0.45 + 0.1 * 0.1);
    for (i = 0; i < 200; ++i) {
        float t[3];
        double dir[3], r, b2[3], c2[3], u[3], v[3];
        mcd_quat da, db;
        int k;
        for (k = 0; k < 3; ++k) dir[k] = (double)(mcd_test_rand(&rng) % 2001u) / 1000.0 - 1.0;
        /* Distances strictly inside the reachable shell |l1 - l2| ... l1 + l2. */
        r = fabs(l1 - l2) + 0.02 + (l1 + l2 - fabs(l1 - l2) - 0.04) * (double)(mcd_test_rand(&rng) % 1001u) / 1000.0;
        for (k = 0; k < 3; ++k) t[k] = (float)(dir[k] / (len3d(dir) + 1e-12) * r);
        mcd_ik_two_bone(a, b, c, t, &da, &db);
        apply_two_bone(a, b, c, da, db, b2, c2);
        CHECK_MSG(dist3(t, c2) <= 1e-4, "target %u missed by %g", i, dist3(t, c2));
        for (k = 0; k < 3; ++k) { u[k] = b2[k] - a[k]; v[k] = c2[k] - b2[k]; }
        CHECK_MSG(fabs(len3d(u) - l1) <= 1e-5 && fabs(len3d(v) - l2) <= 1e-5,
                  "bone lengths changed: %g %g (want %g %g)", len3d(u), len3d(v), l1, l2);
    }
}

void test_contacts_two_bone_keeps_knee_plane(void) {
    /* Leg in the x-y plane: a target in that plane must keep the knee in it (z = 0). */
    const float a[3] = {0.0f, 0.0f, 0.0f}, b[3] = {0.2f, -0.4f, 0.0f}, c[3] = {0.0f, -0.8f, 0.0f};
    const float t[3] = {0.1f, -0.7f, 0.0f};
    double b2[3], c2[3];
    mcd_quat da, db;
    mcd_ik_two_bone(a, b, c, t, &da, &db);
    apply_two_bone(a, b, c, da, db, b2, c2);
    CHECK(dist3(t, c2) <= 1e-4);
    CHECK_MSG(fabs(b2[2]) <= 1e-6, "knee left its plane: z = %g", b2[2]);
    CHECK(b2[0] > 0.0); /* and bends the same way as before */
}

void test_contacts_two_bone_unreachable(void) {
    const float a[3] = {0.0f, 0.0f, 0.0f}, b[3] = {0.0f, -0.5f, 0.05f}, c[3] = {0.0f, -1.0f, 0.0f};
    const float far[3] = {3.0f, -4.0f, 0.0f}, near_hip[3] = {0.0f, 0.0f, 0.0f};
    double b2[3], c2[3], u[3], v[3], cosang;
    mcd_quat da, db;
    int k;
    /* Too far: the limb is straight and points at the target. */
    mcd_ik_two_bone(a, b, c, far, &da, &db);
    apply_two_bone(a, b, c, da, db, b2, c2);
    for (k = 0; k < 3; ++k) { u[k] = b2[k] - a[k]; v[k] = c2[k] - b2[k]; }
    cosang = (u[0] * v[0] + u[1] * v[1] + u[2] * v[2]) / (len3d(u) * len3d(v));
    CHECK_MSG(cosang > 1.0 - 1e-6, "limb not straight: cos %g", cosang);
    CHECK(fabs(c2[0] / len3d(c2) - 0.6) <= 1e-5 && fabs(c2[1] / len3d(c2) + 0.8) <= 1e-5);
    CHECK(fabs(len3d(c2) - (len3d(u) + len3d(v))) <= 1e-5);
    /* On the hip itself (and any degenerate input): finite unit rotations. */
    mcd_ik_two_bone(a, b, c, near_hip, &da, &db);
    CHECK(mcd_finite(da.x) && mcd_finite(da.w) && mcd_finite(db.x) && mcd_finite(db.w));
    CHECK(fabs(da.x * da.x + da.y * da.y + da.z * da.z + da.w * da.w - 1.0) <= 1e-5);
    mcd_ik_two_bone(a, a, a, far, &da, &db);
    CHECK(da.w == 1.0f && db.w == 1.0f);
}

void test_contacts_dls_converges(void) {
    /* Hip, knee, ankle chain moving the toe: reachable targets a few cm away converge. */
    const float joints[3][3] = {{0.0f, 0.0f, 0.0f}, {0.05f, -0.42f, 0.04f}, {0.0f, -0.84f, 0.0f}};
    const float toe[3] = {0.0f, -0.88f, 0.14f};
    uint32_t rng = 11u, i;
    for (i = 0; i < 100; ++i) {
        float t[3], reached[3];
        mcd_quat d[3];
        double err0, err1, p[3];
        int k;
        for (k = 0; k < 3; ++k) t[k] = toe[k] + ((float)(mcd_test_rand(&rng) % 2001u) / 1000.0f - 1.0f) * 0.04f;
        for (k = 0; k < 3; ++k) p[k] = toe[k];
        err0 = dist3(t, p);
        mcd_ik_dls(3, joints, toe, t, d, reached);
        for (k = 0; k < 3; ++k) p[k] = reached[k];
        err1 = dist3(t, p);
        CHECK_MSG(err1 <= 1e-4 + 1e-3 * err0, "DLS %u: error %g -> %g", i, err0, err1);
        CHECK(mcd_finite(d[2].w) && fabs(d[2].x * d[2].x + d[2].y * d[2].y + d[2].z * d[2].z + d[2].w * d[2].w - 1.0) <= 1e-5);
    }
}

void test_contacts_dls_one_joint(void) {
    /* One ball joint: the effector moves on its sphere to the point nearest the target. */
    const float joint[1][3] = {{0.0f, 0.0f, 0.0f}};
    const float e[3] = {0.0f, 0.0f, 0.2f}, t[3] = {0.0f, -0.1f, 0.3f};
    float reached[3];
    mcd_quat d[1];
    double want[3] = {0.0, -0.1 / sqrt(0.1), 0.3 / sqrt(0.1)}, r;
    int k;
    for (k = 0; k < 3; ++k) want[k] *= 0.2;
    mcd_ik_dls(1, joint, e, t, d, reached);
    r = dist3(reached, want);
    CHECK_MSG(r <= 1e-4, "one-joint DLS off the nearest point by %g", r);
}

/* ---------------------------------------------------------------- the golden asset with CNTC */
typedef struct cntc_asset {
    mcd_test_file file;
    uint32_t section; /* offset of the CNTC section */
    uint32_t size;
    uint32_t entry;   /* section table entry of it */
} cntc_asset;

static int load_contacts_golden(cntc_asset* c) {
    char path[1024];
    uint32_t index = 0;
    const uint8_t* e;
    snprintf(path, sizeof path, "%s/%s", mcd_test_golden_dir(), CONTACTS_GOLDEN);
    if (!mcd_test_read_file(path, &c->file)) return 0;
    e = mcd_test_section(c->file.data, "CNTC", 0, &index);
    if (!e) {
        FAIL("%s has no CNTC section", path);
        mcd_test_free_file(&c->file);
        return 0;
    }
    c->entry = 32 + 16 * index;
    c->section = mcd_test_rd_u32(e + 8);
    c->size = mcd_test_rd_u32(e + 12);
    return 1;
}

/* Apply `edit` to a copy, fix the checksum, expect `want` from mcd_validate. */
typedef void (*edit_fn)(uint8_t* asset, const cntc_asset* c);
static void expect_edit(const cntc_asset* c, edit_fn edit, mcd_result want, const char* what) {
    uint8_t* copy = (uint8_t*)malloc(c->file.size);
    mcd_result r;
    if (!copy) return;
    memcpy(copy, c->file.data, c->file.size);
    edit(copy, c);
    mcd_test_fix_crc(copy, c->file.size);
    r = mcd_validate(copy, c->file.size, 0);
    CHECK_MSG(r == want, "%s: mcd_validate gave %d, want %d", what, (int)r, (int)want);
    free(copy);
}

/* Offsets inside the first clip block (the golden holds one clip). */
static uint8_t* block(uint8_t* d, const cntc_asset* c) {
    return d + c->section + mcd_test_rd_u32(d + c->section + 12);
}
static uint32_t effectors(uint8_t* d, const cntc_asset* c) {
    return block(d, c)[12] | (uint32_t)block(d, c)[13] << 8;
}
static uint8_t* effector(uint8_t* d, const cntc_asset* c, uint32_t k) {
    return block(d, c) + 16 + 8 * k;
}
static uint8_t* segment(uint8_t* d, const cntc_asset* c, uint32_t s) {
    return block(d, c) + 16 + 8 * effectors(d, c) + 16 * s;
}

static void e_entry_count_zero(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(d + c->section, 0); }
static void e_entry_count_big(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(d + c->section, 2); }
static void e_reserved(uint8_t* d, const cntc_asset* c) { d[c->section + 4] = 1; }
static void e_clip_index(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(d + c->section + 8, 1); }
static void e_block_offset(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(d + c->section + 12, 20); }
static void e_block_offset_far(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(d + c->section + 12, 0xFFFFFFF0u); }
static void e_frames(uint8_t* d, const cntc_asset* c) { block(d, c)[0] ^= 1; }
static void e_step_zero(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(block(d, c) + 4, 0); }
static void e_step_nan(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(block(d, c) + 4, 0x7FC00000u); }
static void e_step_huge(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(block(d, c) + 4, 0x4E6E6B28u); /* 1e9 */ }
static void e_blend_negative(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(block(d, c) + 8, 0xBF800000u); }
static void e_blend_inf(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(block(d, c) + 8, 0x7F800000u); }
static void e_no_effectors(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(block(d, c) + 12, 0); }
static void e_many_effectors(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(block(d, c) + 12, 17); }
static void e_no_segments(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(block(d, c) + 14, 0); }
static void e_more_segments(uint8_t* d, const cntc_asset* c) {
    mcd_test_wr_u16(block(d, c) + 14, (uint16_t)(block(d, c)[14] + 1));
}
static void e_node_range(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(effector(d, c, 0), 38); }
static void e_node_order(uint8_t* d, const cntc_asset* c) {
    uint8_t* e1 = effector(d, c, 1);
    mcd_test_wr_u16(e1, (uint16_t)(effector(d, c, 0)[0] | effector(d, c, 0)[1] << 8));
}
static void e_node_root(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(effector(d, c, 0), 1); /* one ancestor */ }
static void e_solver(uint8_t* d, const cntc_asset* c) { effector(d, c, 0)[2] = 3; }
static void e_two_bone_chain(uint8_t* d, const cntc_asset* c) { effector(d, c, 0)[3] = 3; }
static void e_dls_chain(uint8_t* d, const cntc_asset* c) {
    effector(d, c, 0)[2] = 2;
    effector(d, c, 0)[3] = 5;
}
static void e_first_segment(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(effector(d, c, 0) + 4, 1); }
static void e_segment_count(uint8_t* d, const cntc_asset* c) {
    uint8_t* e = effector(d, c, 0);
    mcd_test_wr_u16(e + 6, (uint16_t)((e[6] | e[7] << 8) + 1));
}
static void e_seg_start(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(segment(d, c, 0), 100000); }
static void e_seg_length_zero(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(segment(d, c, 0) + 8, 0); }
static void e_seg_length_long(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u16(segment(d, c, 0) + 8, 1025); }
static void e_seg_past_end(uint8_t* d, const cntc_asset* c) {
    mcd_test_wr_u32(segment(d, c, 0), mcd_test_rd_u32(block(d, c)) - 1u);
}
static void e_seg_reserved(uint8_t* d, const cntc_asset* c) { segment(d, c, 0)[13] = 1; }
static void e_seg_reserved2(uint8_t* d, const cntc_asset* c) { segment(d, c, 0)[15] = 1; }
static void e_seg_delta_offset(uint8_t* d, const cntc_asset* c) { segment(d, c, 0)[4] ^= 1; }
static void e_seg_overlap(uint8_t* d, const cntc_asset* c) {
    /* The first effector with two segments: move its second to start inside the first. */
    uint32_t k, n = effectors(d, c);
    for (k = 0; k < n; ++k) {
        uint8_t* e = effector(d, c, k);
        uint32_t first = e[4] | (uint32_t)e[5] << 8, count = e[6] | (uint32_t)e[7] << 8;
        if (count >= 2) {
            mcd_test_wr_u32(segment(d, c, first + 1), mcd_test_rd_u32(segment(d, c, first)));
            return;
        }
    }
    e_seg_reserved(d, c); /* no such effector: still a broken rule */
}
static void e_section_size_short(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(d + c->entry + 12, c->size - 4); }
static void e_version(uint8_t* d, const cntc_asset* c) { mcd_test_wr_u32(d + c->entry + 4, 2); }
static void e_second_cntc(uint8_t* d, const cntc_asset* c) {
    /* Turn the META section (there is one) into a second CNTC: at most one is allowed. */
    uint32_t count = mcd_test_rd_u32(d + 24), i;
    for (i = 0; i < count; ++i)
        if (memcmp(d + 32 + 16 * i, "META", 4) == 0) memcpy(d + 32 + 16 * i, "CNTC", 4);
    (void)c;
}

void test_contacts_validation(void) {
    cntc_asset c;
    uint8_t* copy;
    mcd_result r;
    uint32_t i;
    if (!load_contacts_golden(&c)) return;
    CHECK_RESULT(mcd_validate(c.file.data, c.file.size, 0), MCD_OK);
    expect_edit(&c, e_entry_count_zero, MCD_ERROR_MALFORMED, "no entries");
    expect_edit(&c, e_entry_count_big, MCD_ERROR_MALFORMED, "more entries than clips");
    expect_edit(&c, e_reserved, MCD_ERROR_MALFORMED, "reserved word");
    expect_edit(&c, e_clip_index, MCD_ERROR_MALFORMED, "clip index past the directory");
    expect_edit(&c, e_block_offset, MCD_ERROR_MALFORMED, "block not where the table ends");
    expect_edit(&c, e_block_offset_far, MCD_ERROR_MALFORMED, "block offset past the section");
    expect_edit(&c, e_frames, MCD_ERROR_MALFORMED, "frame count differs from the clip's");
    expect_edit(&c, e_step_zero, MCD_ERROR_MALFORMED, "step 0");
    expect_edit(&c, e_step_nan, MCD_ERROR_MALFORMED, "step NaN");
    expect_edit(&c, e_step_huge, MCD_ERROR_MALFORMED, "step 1e9");
    expect_edit(&c, e_blend_negative, MCD_ERROR_MALFORMED, "blend -1");
    expect_edit(&c, e_blend_inf, MCD_ERROR_MALFORMED, "blend inf");
    expect_edit(&c, e_no_effectors, MCD_ERROR_MALFORMED, "no effectors");
    expect_edit(&c, e_many_effectors, MCD_ERROR_MALFORMED, "17 effectors");
    expect_edit(&c, e_no_segments, MCD_ERROR_MALFORMED, "no segments");
    expect_edit(&c, e_more_segments, MCD_ERROR_MALFORMED, "segment count larger than the effectors use");
    expect_edit(&c, e_node_range, MCD_ERROR_MALFORMED, "node past the skeleton");
    expect_edit(&c, e_node_order, MCD_ERROR_MALFORMED, "nodes not increasing");
    expect_edit(&c, e_node_root, MCD_ERROR_MALFORMED, "node without the ancestors its solver needs");
    expect_edit(&c, e_solver, MCD_ERROR_MALFORMED, "unknown solver");
    expect_edit(&c, e_two_bone_chain, MCD_ERROR_MALFORMED, "two-bone with chain 3");
    expect_edit(&c, e_dls_chain, MCD_ERROR_MALFORMED, "DLS chain 5");
    expect_edit(&c, e_first_segment, MCD_ERROR_MALFORMED, "effector segments not packed");
    expect_edit(&c, e_segment_count, MCD_ERROR_MALFORMED, "effector segment count");
    expect_edit(&c, e_seg_start, MCD_ERROR_MALFORMED, "segment start past the clip");
    expect_edit(&c, e_seg_length_zero, MCD_ERROR_MALFORMED, "segment length 0");
    expect_edit(&c, e_seg_length_long, MCD_ERROR_MALFORMED, "segment length 1025");
    expect_edit(&c, e_seg_past_end, MCD_ERROR_MALFORMED, "segment running past the clip");
    expect_edit(&c, e_seg_reserved, MCD_ERROR_MALFORMED, "segment reserved byte");
    expect_edit(&c, e_seg_reserved2, MCD_ERROR_MALFORMED, "segment reserved u16");
    expect_edit(&c, e_seg_delta_offset, MCD_ERROR_MALFORMED, "delta offset");
    expect_edit(&c, e_seg_overlap, MCD_ERROR_MALFORMED, "overlapping segments");
    expect_edit(&c, e_section_size_short, MCD_ERROR_MALFORMED, "section size 4 short");
    expect_edit(&c, e_version, MCD_ERROR_UNSUPPORTED, "section version 2");
    expect_edit(&c, e_second_cntc, MCD_ERROR_MALFORMED, "two CNTC sections");
    /* Every shorter section size (the section then ends inside its own data or padding). */
    copy = (uint8_t*)malloc(c.file.size);
    if (copy) {
        for (i = 0; i < c.size; ++i) {
            memcpy(copy, c.file.data, c.file.size);
            mcd_test_wr_u32(copy + c.entry + 12, i);
            mcd_test_fix_crc(copy, c.file.size);
            r = mcd_validate(copy, c.file.size, 0);
            CHECK_MSG(r != MCD_OK, "CNTC section cut to %u of %u bytes accepted", i, c.size);
        }
        free(copy);
    }
    mcd_test_free_file(&c.file);
}

/* Poses with and without the flag: equal when no contact is active, different (and finite,
 * unit) when one is; equal to an asset without the section when the flag is off. */
void test_contacts_flag_semantics(void) {
    cntc_asset c;
    mcd_asset a, plain;
    uint8_t* stripped;
    void *s1 = NULL, *s2 = NULL;
    mcd_transform* p = (mcd_transform*)malloc(MAX_NODES * sizeof *p);
    mcd_transform* q = (mcd_transform*)malloc(MAX_NODES * sizeof *q);
    mcd_clip_info info;
    uint32_t f, differ = 0, world_differ = 0;
    if (!p || !q || !load_contacts_golden(&c)) {
        free(p);
        free(q);
        return;
    }
    /* The same asset with the CNTC section renamed to an unknown kind: the runtime skips it. */
    stripped = (uint8_t*)malloc(c.file.size);
    memcpy(stripped, c.file.data, c.file.size);
    memcpy(stripped + c.entry, "UNKN", 4);
    mcd_test_fix_crc(stripped, c.file.size);
    CHECK_RESULT(mcd_open(c.file.data, c.file.size, 0, &a), MCD_OK);
    CHECK_RESULT(mcd_open(stripped, c.file.size, 0, &plain), MCD_OK);
    CHECK(mcd_scratch_size(&a) > mcd_scratch_size(&plain));
    s1 = mcd_test_scratch(&a);
    s2 = mcd_test_scratch(&plain);
    CHECK_RESULT(mcd_get_clip_info(&a, 0, &info), MCD_OK);
    for (f = 0; f < info.frame_count && s1 && s2; ++f) {
        float t = (float)f / info.frame_rate;
        uint32_t fl;
        for (fl = 0; fl < 8; ++fl) {
            /* No flag: byte-identical to the asset without contacts. */
            CHECK_RESULT(mcd_sample(&a, 0, t, fl, p, MAX_NODES, s1), MCD_OK);
            CHECK_RESULT(mcd_sample(&plain, 0, t, fl, q, MAX_NODES, s2), MCD_OK);
            CHECK_MSG(memcmp(p, q, info.node_count * sizeof *p) == 0, "frame %u flags %u: output changed without the flag", f, fl);
            /* The flag on an asset without contacts: a no-op. */
            CHECK_RESULT(mcd_sample(&plain, 0, t, fl | MCD_SAMPLE_CONTACTS, p, MAX_NODES, s2), MCD_OK);
            CHECK_MSG(memcmp(p, q, info.node_count * sizeof *p) == 0, "frame %u flags %u: contacts flag changed a clip without contacts", f, fl);
        }
        CHECK_RESULT(mcd_sample(&a, 0, t, MCD_SAMPLE_CONTACTS, p, MAX_NODES, s1), MCD_OK);
        CHECK(mcd_test_pose_finite(p, info.node_count));
        CHECK_RESULT(mcd_sample(&a, 0, t, 0, q, MAX_NODES, s1), MCD_OK);
        differ += memcmp(p, q, info.node_count * sizeof *p) != 0;
        /* Only rotations change in local output; translations are the codec's. */
        {
            uint32_t n;
            for (n = 0; n < info.node_count; ++n)
                CHECK(memcmp(p[n].translation, q[n].translation, sizeof p[n].translation) == 0);
        }
        CHECK_RESULT(mcd_sample(&a, 0, t, MCD_SAMPLE_CONTACTS | MCD_SAMPLE_WORLD, p, MAX_NODES, s1), MCD_OK);
        CHECK_RESULT(mcd_sample(&a, 0, t, MCD_SAMPLE_WORLD, q, MAX_NODES, s1), MCD_OK);
        world_differ += memcmp(p, q, info.node_count * sizeof *p) != 0;
    }
    /* The golden walk has contacts on both feet for a good part of the clip. */
    CHECK_MSG(differ > info.frame_count / 4, "contacts changed only %u of %u frames", differ, info.frame_count);
    CHECK(world_differ > info.frame_count / 4);
    mcd_test_free_scratch(s1);
    mcd_test_free_scratch(s2);
    free(stripped);
    free(p);
    free(q);
    mcd_test_free_file(&c.file);
}

/* A quick timing of the contact pass, printed for the record (not a pass/fail criterion). */
void test_contacts_timing(void) {
    cntc_asset c;
    mcd_asset a;
    void* s;
    mcd_transform* p = (mcd_transform*)malloc(MAX_NODES * sizeof *p);
    mcd_clip_info info;
    double secs[2];
    int pass;
    if (!p || !load_contacts_golden(&c)) {
        free(p);
        return;
    }
    CHECK_RESULT(mcd_open(c.file.data, c.file.size, 0, &a), MCD_OK);
    s = mcd_test_scratch(&a);
    CHECK_RESULT(mcd_get_clip_info(&a, 0, &info), MCD_OK);
    for (pass = 0; pass < 2 && s; ++pass) {
        struct timespec t0, t1;
        uint32_t rep, f;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        for (rep = 0; rep < 20; ++rep)
            for (f = 0; f < info.frame_count; ++f)
                mcd_sample(&a, 0, (float)f / info.frame_rate, pass ? MCD_SAMPLE_CONTACTS : 0, p, MAX_NODES, s);
        clock_gettime(CLOCK_MONOTONIC, &t1);
        secs[pass] = ((double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec)) / (20.0 * info.frame_count);
    }
    if (s && getenv("MCD_TEST_VERBOSE"))
        printf("    contacts timing: %.3f us per pose without, %.3f us with (+%.3f)\n", secs[0] * 1e6, secs[1] * 1e6,
               (secs[1] - secs[0]) * 1e6);
    mcd_test_free_scratch(s);
    free(p);
    mcd_test_free_file(&c.file);
}

/* The per-effector offset cache must not change a result: every frame and midpoint, sampled in
 * a shuffled order on one scratch, equals the same sample on a freshly initialised scratch. */
void test_contacts_order_independence(void) {
    cntc_asset c;
    mcd_asset a;
    void *warm = NULL, *cold = NULL;
    mcd_transform* p = (mcd_transform*)malloc(MAX_NODES * sizeof *p);
    mcd_transform* q = (mcd_transform*)malloc(MAX_NODES * sizeof *q);
    mcd_clip_info info;
    uint32_t* order = NULL;
    uint32_t i, n, same = 0;
    if (!p || !q || !load_contacts_golden(&c)) {
        free(p);
        free(q);
        return;
    }
    CHECK_RESULT(mcd_open(c.file.data, c.file.size, 0, &a), MCD_OK);
    CHECK_RESULT(mcd_get_clip_info(&a, 0, &info), MCD_OK);
    warm = mcd_test_scratch(&a);
    cold = mcd_test_scratch(&a);
    n = 2u * info.frame_count - 1u;
    order = (uint32_t*)malloc(n * sizeof *order);
    for (i = 0; order && i < n; ++i) order[i] = i;
    if (order) mcd_test_shuffle(order, n, 5u);
    for (i = 0; order && warm && cold && i < n; ++i) {
        float t = (float)(0.5 * order[i] / info.frame_rate);
        CHECK_RESULT(mcd_sample(&a, 0, t, MCD_SAMPLE_CONTACTS, p, MAX_NODES, warm), MCD_OK);
        CHECK_RESULT(mcd_scratch_init(&a, cold, mcd_scratch_size(&a)), MCD_OK);
        CHECK_RESULT(mcd_sample(&a, 0, t, MCD_SAMPLE_CONTACTS, q, MAX_NODES, cold), MCD_OK);
        same += memcmp(p, q, info.node_count * sizeof *p) == 0;
    }
    CHECK_MSG(same == n, "%u of %u samples depend on what the scratch sampled before", n - same, n);
    free(order);
    mcd_test_free_scratch(warm);
    mcd_test_free_scratch(cold);
    free(p);
    free(q);
    mcd_test_free_file(&c.file);
}
