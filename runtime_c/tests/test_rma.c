/* Codec rma's RMAL sections (docs/FORMAT.md, RMAL versions 4, 3 and 2): the scratch each
 * version states, playback in steps of every size (a key interval, a game tick, a jump) against
 * a cold random access bit for bit, and the rules of versions 3 and 4 one by one on payloads
 * written here from keys (a small writer of the spec's layout), each broken alone and refused.
 *
 * The writer replaces the RMAL section of a golden asset of codec rma: every clip gets a
 * payload whose node 0 translation is one track (kind 3) and whose other nodes rest. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "harness.h"

void test_rma_section_versions(void);
void test_rma_scratch_sizes(void);
void test_rma_playback_steps(void);
void test_rma_block_rules(void);

#define MAX_NODES 1024u
#define ALIGN16(x) (((x) + 15u) & ~(size_t)15u)

/* The RMAL section of an asset (NULL when none) and its version. */
static const uint8_t* rmal_entry(const uint8_t* asset, uint32_t* version, uint32_t* index) {
    const uint8_t* e = mcd_test_section(asset, "RMAL", 0, index);
    if (e && version) *version = mcd_test_rd_u32(e + 4);
    return e;
}

/* ---------------------------------------------------------------- versions */
/* Versions 2, 3 and 4 are read, each by its own reader: a golden's section labelled with
 * another of them is malformed, one labelled 1 or 5 unsupported. */
void test_rma_section_versions(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    uint32_t tested = 0;
    for (i = 0; i < n; ++i) {
        uint32_t version = 0, index, label;
        if (!rmal_entry(g[i].file.data, &version, &index)) continue;
        tested++;
        for (label = 1; label <= 5u; ++label) {
            uint8_t* copy;
            if (label == version) continue;
            copy = mcd_test_copy(g[i].file.data, g[i].file.size);
            if (!copy) break;
            mcd_test_wr_u32(copy + 32 + 16u * index + 4u, label);
            mcd_test_fix_crc(copy, g[i].file.size);
            CHECK_MSG(mcd_validate(copy, g[i].file.size, 0) ==
                          (label == 1u || label == 5u ? MCD_ERROR_UNSUPPORTED : MCD_ERROR_MALFORMED),
                      "%s: RMAL version %u labelled %u: %s", g[i].file.path, version, label,
                      mcd_result_string(mcd_validate(copy, g[i].file.size, 0)));
            free(copy);
        }
    }
    CHECK(tested > 0);
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- scratch */
/* align16(48 N) + align16(S T): S = 308 bytes a track in version 4, 292 in version 3, 348 in
 * version 2. */
void test_rma_scratch_sizes(void) {
    static const size_t track_bytes[5] = {0, 0, 348u, 292u, 308u};
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    uint32_t seen[5] = {0, 0, 0, 0, 0};
    for (i = 0; i < n; ++i) {
        const uint8_t* d = g[i].file.data;
        uint32_t version = 0, c;
        const uint8_t* e = rmal_entry(d, &version, NULL);
        const uint8_t* clips = mcd_test_section(d, "CLIP", 0, NULL);
        if (!e || !clips) continue;
        CHECK_MSG(version >= 2u && version <= 4u, "%s: RMAL version %u", g[i].file.path, version);
        if (version < 2u || version > 4u) continue;
        seen[version]++;
        for (c = 0; c < mcd_clip_count(&g[i].asset); ++c) {
            const uint8_t* r = d + mcd_test_rd_u32(clips + 8) + 8u + 48u * c;
            const uint8_t* p = d + mcd_test_rd_u32(e + 8) + mcd_test_rd_u32(r + 16);
            size_t want = ALIGN16(48u * (size_t)mcd_test_rd_u32(p + 8)) +
                          ALIGN16(track_bytes[version] * (size_t)mcd_test_rd_u32(p + 12));
            mcd_clip_info info;
            if (mcd_test_rd_u32(r + 8) != MCD_CODEC_RMA) continue;
            CHECK_RESULT(mcd_get_clip_info(&g[i].asset, c, &info), MCD_OK);
            CHECK_MSG(info.scratch_size == 64u + want, "%s clip %u: scratch %u, want 64 + %lu", g[i].file.path, c,
                      (unsigned)info.scratch_size, (unsigned long)want);
        }
    }
    CHECK_MSG(seen[2] > 0 && seen[3] > 0 && seen[4] > 0, "goldens with RMAL version 2: %u, version 3: %u, version 4: %u",
              seen[2], seen[3], seen[4]);
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- playback */
/* From each start, forward in steps of `step` frames with one scratch (what playback and game
 * ticks do), each pose the same bits as a cold sample at that time; then the same backward. */
static void check_steps(const mcd_golden* g, uint32_t clip, const mcd_clip_info* info, void* warm, void* cold,
                        mcd_transform* a, mcd_transform* b) {
    static const float steps[] = {0.25f, 0.5f, 1.0f, 2.0f, 3.0f, 5.0f, 9.0f, 17.0f, 40.0f, 150.0f};
    size_t s;
    for (s = 0; s < sizeof steps / sizeof steps[0]; ++s) {
        int dir;
        for (dir = 0; dir < 2; ++dir) {
            double x = dir ? (double)info->frame_count - 1.0 : 0.37 * (double)(s & 1u);
            uint32_t count = 0;
            CHECK_RESULT(mcd_scratch_init(&g->asset, warm, mcd_scratch_size(&g->asset)), MCD_OK);
            for (; x >= 0.0 && x <= (double)info->frame_count - 1.0 && count < 4000u; ++count) {
                float t = (float)(x / (double)info->frame_rate);
                CHECK_RESULT(mcd_sample(&g->asset, clip, t, 0, a, MAX_NODES, warm), MCD_OK);
                CHECK_RESULT(mcd_scratch_init(&g->asset, cold, mcd_scratch_size(&g->asset)), MCD_OK);
                CHECK_RESULT(mcd_sample(&g->asset, clip, t, 0, b, MAX_NODES, cold), MCD_OK);
                if (memcmp(a, b, sizeof *a * info->node_count) != 0) {
                    FAIL("%s clip %u: step %g %s, t = %.9g: differs from a cold sample", g->file.path, clip,
                         (double)steps[s], dir ? "backward" : "forward", (double)t);
                    return;
                }
                x += dir ? -(double)steps[s] : (double)steps[s];
            }
        }
    }
}

void test_rma_playback_steps(void) {
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i;
    mcd_transform* a = (mcd_transform*)malloc(sizeof *a * MAX_NODES);
    mcd_transform* b = (mcd_transform*)malloc(sizeof *b * MAX_NODES);
    uint32_t tested = 0;
    for (i = 0; a && b && i < n; ++i) {
        uint32_t c;
        void *warm, *cold;
        if (!rmal_entry(g[i].file.data, NULL, NULL)) continue;
        warm = mcd_test_scratch(&g[i].asset);
        cold = mcd_test_scratch(&g[i].asset);
        for (c = 0; warm && cold && c < mcd_clip_count(&g[i].asset); ++c) {
            mcd_clip_info info;
            CHECK_RESULT(mcd_get_clip_info(&g[i].asset, c, &info), MCD_OK);
            if (info.codec != MCD_CODEC_RMA) continue;
            check_steps(&g[i], c, &info, warm, cold, a, b);
            tested++;
        }
        mcd_test_free_scratch(warm);
        mcd_test_free_scratch(cold);
    }
    CHECK(tested > 0);
    free(a);
    free(b);
    mcd_test_free_golden(g, n);
}

/* ---------------------------------------------------------------- rules of versions 3 and 4 */
/* What the writer breaks: each alone, and each one a rule the reader must refuse. */
enum fault {
    OK_PAYLOAD = 0,
    SHORT_ESCAPE,      /* a value with a short code written as an escape */
    ROW_PADDING,       /* a one in the row table's padding bits */
    DATA_PADDING,      /* a one after the last block's codes */
    DATA_BYTES_LONG,   /* data_bytes a word more than the codes need */
    ROW_OFFSET,        /* row 1's offset one bit on */
    FIRST_FRAME,       /* key 0 on frame 1 */
    LAST_FRAME,        /* the last key before the last frame */
    ROW_FRAME_BACK,    /* row 1's frame at the previous block's last key's */
    Q_TOO_WIDE,        /* a key's lattice integer at 2^30 */
    VALUE_TOO_LARGE,   /* q * step past 1e7 */
    BYTE3,             /* descriptor byte 3 not 0 */
    SHIFT_0,           /* block shift 0 */
    SHIFT_7,           /* block shift 7 */
    BYTE1_HIGH,        /* descriptor byte 1 bit 4 */
    END_PADDING,       /* a one in the payload's 8 zero end bytes */
    GAP_SLOPE,         /* version 4: the slope predictor on the gaps */
    FAULTS
};

typedef struct bits {
    uint8_t* p;
    uint64_t at;
} bits;

static void put(bits* w, uint64_t v, uint32_t n) {
    uint32_t i;
    for (i = 0; i < n; ++i, ++w->at)
        if ((v >> i) & 1u) w->p[w->at >> 3] |= (uint8_t)(1u << (w->at & 7u));
}

static uint32_t bits_of(uint32_t n) {
    uint32_t b = 1;
    while (b < 32u && (n >> b)) ++b;
    return b;
}

/* One Rice code; `escape` writes the value as an escape whatever its size. */
static void put_rice(bits* w, uint64_t z, uint32_t k, int escape) {
    if (escape || (z >> k) >= 16u) {
        put(w, 0, 16);
        put(w, z, 32);
    } else {
        put(w, 0, (uint32_t)(z >> k));
        put(w, 1, 1);
        put(w, z & (((uint64_t)1 << k) - 1u), k);
    }
}

static uint64_t zig(int64_t v) {
    return v >= 0 ? 2u * (uint64_t)v : 2u * (uint64_t)(-v) - 1u;
}

/* A track's keys: frames and three lattice integers each. */
typedef struct keys {
    uint32_t count, frame[128];
    int64_t q[128][3];
} keys;

/* Keys for a clip of F frames: every 3rd frame (at most 100 of them) and the last, values that
 * wander, one jump that takes an escape. For version 4, component 1 stands still (streams of
 * zeros) and component 2 bends evenly (the slope predictor). */
static void make_keys(uint32_t frames, keys* K, uint32_t version) {
    uint32_t f = 0, c;
    K->count = 0;
    while (K->count < 100u && f < frames - 1u) {
        K->frame[K->count] = f;
        for (c = 0; c < 3u; ++c) K->q[K->count][c] = (int64_t)((K->count * (c + 3u) * 37u) % 101u) - 50;
        if (version == 4u) {
            K->q[K->count][1] = 5;
            K->q[K->count][2] = (int64_t)K->count * (int64_t)K->count - 50;
        }
        K->count++;
        f += 3u;
    }
    K->frame[K->count] = frames - 1u; /* F = 1: the one key */
    for (c = 0; c < 3u; ++c) K->q[K->count][c] = frames > 1u ? 40000 - (int64_t)c : -7; /* escapes at k = 3 */
    K->count++;
}

#define STEP 0.001f
#define ABITS 20u
#define GAP_K 2u
#define VAL_K 3u

/* Version 4: component c's residual into key j (block e's keys from e B) and its row field. */
static int64_t residual(const keys* K, uint32_t j, uint32_t c, uint32_t first) {
    int64_t d = K->q[j][c] - K->q[j - 1u][c];
    return c == 2u && j >= first + 2u ? d - (K->q[j - 1u][c] - K->q[j - 2u][c]) : d;
}

static uint32_t field(const keys* K, uint32_t e, uint32_t B, uint32_t c, uint32_t version) {
    uint32_t j, zero = 1;
    if (version == 3u) return VAL_K;
    for (j = e * B + 1u; j < e * B + B && j < K->count; ++j) zero &= residual(K, j, c, e * B) == 0;
    return (zero && e * B + 1u < K->count ? 15u : VAL_K) | (c == 2u ? 16u : 0u);
}

/* The payload of one clip: N nodes, node 0's translation the track, in blocks of 2^shift. */
static size_t write_payload(uint8_t* out, uint32_t frames, uint32_t nodes, uint32_t shift, enum fault f,
                            uint32_t version) {
    keys K;
    uint32_t B, rows, fb, ob = 16, row_bits, e, j, c, at, table_bytes, data_bytes, end, size;
    uint8_t* d;
    bits w;
    uint64_t total;
    make_keys(frames, &K, version);
    if (f == FIRST_FRAME) K.frame[0] = 1;
    if (f == LAST_FRAME) K.frame[K.count - 1u] = frames - 2u;
    if (f == Q_TOO_WIDE) K.q[1][1] = (int64_t)1 << 30; /* key 1: never a row's */
    if (f == VALUE_TOO_LARGE) K.q[3][0] = 20000000; /* key 3: never a row's; the step is 1 */
    B = 1u << shift;
    rows = (K.count + B - 1u) >> shift;
    fb = bits_of(frames - 1u);
    row_bits = fb + ob + 5u * 4u + 3u * ABITS;
    table_bytes = 4u * ((rows * row_bits + 31u) / 32u);
    memset(out, 0, 32);
    mcd_test_wr_u32(out + 4, frames);
    mcd_test_wr_u32(out + 8, nodes);
    mcd_test_wr_u32(out + 12, 1);
    memset(out + 32, 0, (nodes + 3u) & ~3u);
    out[32] = 2u << 2; /* node 0: translation animated */
    d = out + 32 + ((nodes + 3u) & ~3u);
    at = (uint32_t)(d - out) + 20u;
    /* Data area first (its length goes into the descriptor and row offsets). */
    {
        static uint8_t data[4096];
        uint64_t offsets[128];
        memset(data, 0, sizeof data);
        w.p = data;
        w.at = 0;
        for (e = 0; e < rows; ++e) {
            offsets[e] = w.at;
            for (j = e * B + 1u; j < e * B + B && j < K.count; ++j) {
                put_rice(&w, K.frame[j] - K.frame[j - 1u] - 1u, GAP_K, 0);
                for (c = 0; c < 3u; ++c) {
                    if (version == 4u && (field(&K, e, B, c, version) & 15u) == 15u) continue; /* no codes */
                    put_rice(&w, zig(version == 4u ? residual(&K, j, c, e * B) : K.q[j][c] - K.q[j - 1u][c]), VAL_K,
                             f == SHORT_ESCAPE && j == 1u && c == 0u);
                }
            }
        }
        total = w.at;
        data_bytes = 4u * (uint32_t)((total + 31u) / 32u) + (f == DATA_BYTES_LONG ? 4u : 0u);
        if (f == DATA_PADDING) data[total >> 3] |= (uint8_t)(1u << (total & 7u)); /* total < 8 data_bytes */
        if (f == DATA_PADDING && (total & 7u) == 0u && (total >> 3) >= data_bytes) data_bytes += 4u;
        /* Descriptor (kind 3). */
        d[0] = 3;
        d[1] = (uint8_t)(shift << 1);
        if (f == SHIFT_0) d[1] = 0;
        if (f == SHIFT_7) d[1] = 7u << 1;
        if (f == BYTE1_HIGH) d[1] |= 0x10u;
        d[2] = (uint8_t)ob;
        d[3] = f == BYTE3 ? 1u : 0u;
        mcd_test_wr_u32(d + 4, K.count);
        mcd_test_wr_u32(d + 8, data_bytes);
        mcd_test_wr_u32(d + 12, mcd_test_f32_bits(f == VALUE_TOO_LARGE ? 1.0f : STEP));
        d[16] = d[17] = d[18] = (uint8_t)ABITS;
        d[19] = 0;
        /* Row table. */
        memset(out + at, 0, table_bytes);
        w.p = out + at;
        w.at = 0;
        for (e = 0; e < rows; ++e) {
            uint32_t k0 = e * B;
            put(&w, f == ROW_FRAME_BACK && e == 1u ? K.frame[k0 - 1u] : K.frame[k0], fb);
            put(&w, offsets[e] + (f == ROW_OFFSET && e == 1u ? 1u : 0u), ob);
            put(&w, GAP_K | (f == GAP_SLOPE && e == 0u ? 16u : 0u), 5);
            for (c = 0; c < 3u; ++c) put(&w, field(&K, e, B, c, version), 5);
            for (c = 0; c < 3u; ++c) put(&w, (uint64_t)K.q[k0][c] & ((1u << ABITS) - 1u), ABITS);
        }
        if (f == ROW_PADDING) {
            if (w.at == 8u * table_bytes) table_bytes += 4u, out[at + table_bytes - 4u] = 0;
            put(&w, 1, 1);
        }
        memcpy(out + at + table_bytes, data, data_bytes);
    }
    end = at + table_bytes + data_bytes;
    size = (end + 8u + 3u) & ~3u;
    memset(out + end, 0, size - end);
    if (f == END_PADDING) out[end + 3u] = 1;
    mcd_test_wr_u32(out, size);
    return size;
}

/* A golden of codec rma with every clip's payload written anew (`f` in clip 0's), its RMAL
 * section made `version`; with `one_frame`, clip 0 made one frame long. NULL when out of
 * memory. */
static uint8_t* rewrite_asset(const mcd_test_file* src, uint32_t shift, enum fault f, int one_frame, uint32_t version,
                              size_t* size) {
    static uint8_t section[1u << 20];
    const uint8_t* d = src->data;
    uint32_t index, c, count, pos = 16;
    const uint8_t* clips = mcd_test_section(d, "CLIP", 0, NULL);
    uint8_t *asset, *records;
    uint32_t offsets[64], sizes[64];
    if (!rmal_entry(d, NULL, &index) || !clips) return NULL;
    count = mcd_test_rd_u32(d + mcd_test_rd_u32(clips + 8));
    memset(section, 0, 16);
    mcd_test_wr_u32(section, count);
    for (c = 0; c < count && c < 64u; ++c) {
        const uint8_t* r = d + mcd_test_rd_u32(clips + 8) + 8u + 48u * c;
        uint32_t frames = c == 0 && one_frame ? 1u : mcd_test_rd_u32(r + 24);
        const uint8_t* skel = mcd_test_section(d, "SKEL", mcd_test_rd_u32(r + 4), NULL);
        uint32_t nodes = mcd_test_rd_u32(d + mcd_test_rd_u32(skel + 8));
        offsets[c] = pos;
        sizes[c] = (uint32_t)write_payload(section + pos, frames, nodes, shift, c == 0 ? f : OK_PAYLOAD, version);
        pos += sizes[c];
    }
    asset = mcd_test_replace_section(d, index, section, pos, size);
    if (!asset) return NULL;
    mcd_test_wr_u32(asset + 32 + 16u * index + 4u, version);
    clips = mcd_test_section(asset, "CLIP", 0, NULL);
    records = asset + mcd_test_rd_u32(clips + 8) + 8u;
    for (c = 0; c < count && c < 64u; ++c) {
        uint32_t nodes = mcd_test_rd_u32(section + offsets[c] + 8);
        mcd_test_wr_u32(records + 48u * c + 16u, offsets[c]);
        mcd_test_wr_u32(records + 48u * c + 20u, sizes[c]);
        mcd_test_wr_u32(records + 48u * c + 40u, (uint32_t)(ALIGN16(48u * nodes) + ALIGN16(version == 4u ? 308u : 292u)));
    }
    if (one_frame) {
        mcd_test_wr_u32(records + 24u, 1); /* and its duration 0 */
        mcd_test_wr_u32(records + 32u, 0);
    }
    mcd_test_fix_crc(asset, *size);
    return asset;
}

/* The written keys come back: at each key frame the track's value is q * step. Within 1e-6:
 * the time of a frame, in seconds and binary32, maps back to the frame only nearly, and
 * platforms round the cubic near s = 0 differently (s390x contracts into FMA); a wrong key
 * is a step (0.01) off. */
static void check_key_values(const uint8_t* asset, size_t size, const char* path, uint32_t version) {
    mcd_asset a;
    mcd_transform* pose = (mcd_transform*)malloc(sizeof *pose * MAX_NODES);
    void* scratch;
    mcd_clip_info info;
    keys K;
    uint32_t k, c;
    if (!pose) return;
    CHECK_RESULT(mcd_open(asset, size, 0, &a), MCD_OK);
    scratch = mcd_test_scratch(&a);
    CHECK_RESULT(mcd_get_clip_info(&a, 0, &info), MCD_OK);
    make_keys(info.frame_count, &K, version);
    /* The last key is its segment's far end, where the cubic in s = 1 rounds: not exact. */
    for (k = 0; scratch && k + 1u < K.count; ++k) {
        CHECK_RESULT(mcd_sample(&a, 0, (float)((double)K.frame[k] / info.frame_rate), 0, pose, MAX_NODES, scratch),
                     MCD_OK);
        for (c = 0; c < 3u; ++c)
            CHECK_MSG(fabs((double)pose[0].translation[c] - (double)K.q[k][c] * (double)STEP) <= 1e-6,
                      "%s: key %u component %u: %.9g, want %.9g", path, k, c, (double)pose[0].translation[c],
                      (double)K.q[k][c] * (double)STEP);
    }
    mcd_test_free_scratch(scratch);
    free(pose);
}

void test_rma_block_rules(void) {
    static const char* const names[FAULTS] = {
        "none", "short escape", "row padding", "data padding", "data_bytes long", "row offset", "first frame",
        "last frame", "row frame back", "q 2^30", "value past 1e7", "byte 3", "shift 0", "shift 7", "byte 1 bit 4",
        "end padding", "slope on the gaps"};
    mcd_golden* g;
    size_t n = mcd_test_load_golden(&g), i, size;
    int done = 0;
    for (i = 0; i < n && !done; ++i) {
        uint32_t shift, version;
        int f;
        mcd_clip_info info;
        if (!rmal_entry(g[i].file.data, NULL, NULL) || mcd_get_clip_info(&g[i].asset, 0, &info) != MCD_OK ||
            info.codec != MCD_CODEC_RMA || info.frame_count < 200u)
            continue;
        done = 1;
        for (version = 3; version <= 4u; ++version) {
            for (shift = 1; shift <= 6u; ++shift) {
                for (f = 0; f < FAULTS; ++f) {
                    uint8_t* asset;
                    mcd_result r;
                    if (f == GAP_SLOPE && version == 3u) continue; /* version 3's field is k alone */
                    asset = rewrite_asset(&g[i].file, shift, (enum fault)f, 0, version, &size);
                    if (!asset) {
                        FAIL("%s: cannot rewrite", g[i].file.path);
                        continue;
                    }
                    r = mcd_validate(asset, size, 0);
                    if (f == OK_PAYLOAD) {
                        CHECK_MSG(r == MCD_OK, "%s, version %u, blocks of %u: the written payload is refused: %s",
                                  g[i].file.path, version, 1u << shift, mcd_result_string(r));
                        if (r == MCD_OK) check_key_values(asset, size, g[i].file.path, version);
                    } else {
                        CHECK_MSG(r == MCD_ERROR_MALFORMED, "%s, version %u, blocks of %u, %s: %s, want malformed",
                                  g[i].file.path, version, 1u << shift, names[f], mcd_result_string(r));
                    }
                    free(asset);
                }
            }
        }
    }
    /* A one-frame clip: one key, row 0 alone, no codes; every time samples it. */
    for (i = 0; i < n && done == 1; ++i) {
        uint32_t version;
        uint8_t* asset;
        mcd_asset a;
        mcd_transform* pose = (mcd_transform*)malloc(sizeof *pose * MAX_NODES);
        void* scratch;
        if (!rmal_entry(g[i].file.data, NULL, NULL) || !pose) {
            free(pose);
            continue;
        }
        done = 2;
        for (version = 3; version <= 4u; ++version) {
            asset = rewrite_asset(&g[i].file, 5, OK_PAYLOAD, 1, version, &size);
            if (asset && mcd_open(asset, size, 0, &a) == MCD_OK && (scratch = mcd_test_scratch(&a)) != NULL) {
                static const float times[4] = {0.0f, -1.0f, 0.5f, 7.0f};
                uint32_t k;
                for (k = 0; k < 4u; ++k) {
                    CHECK_RESULT(mcd_sample(&a, 0, times[k], 0, pose, MAX_NODES, scratch), MCD_OK);
                    CHECK(pose[0].translation[0] == (float)(-7.0 * (double)STEP));
                }
                mcd_test_free_scratch(scratch);
            } else {
                FAIL("%s: the one-frame payload of version %u is refused", g[i].file.path, version);
            }
            free(asset);
        }
        free(pose);
    }
    CHECK_MSG(done == 2, "no golden of codec rma with a clip of 200 frames or more");
    mcd_test_free_golden(g, n);
}
