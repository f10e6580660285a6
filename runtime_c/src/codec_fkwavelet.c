/* Codec `fk-wavelet`: per-channel CDF 9/7 wavelet coefficients, quantized with per-joint step
 * sizes and entropy coded band by band, coarse to fine (seed 000 §4; docs/FORMAT.md, FKWV
 * version 2), sampled in place from the asset's bytes.
 *
 * A clip is cut into blocks of B frames, each an independent wavelet signal with its own
 * entropy stream. The scratch holds one decoded block (every channel on its B frames) and one
 * more row: a copy of the frame on the far side of a block boundary, so the segment between
 * the last frame of a block and the first of the next is interpolated without holding two
 * blocks. Playing forward or backward decodes each block once; a random access decodes one
 * block, or two on a boundary segment.
 *
 * The inverse transform runs in place in the block's rows. The stream decodes into the Mallat
 * layout (approximation first, then the details of each level, coarse to fine), and no level
 * is interleaved: a table of row indices says where each sample of the current approximation
 * lies, so a lifting step reads its even samples through the table and its odd samples from
 * the contiguous detail rows. After level 1 the table gives the row of every frame. */
#include <math.h>
#include <string.h>

#include "entropy.h"
#include "internal.h"

#define HEADER 16u
#define NODE_ENTRY 4u
#define MAX_LEVELS 12u
#define MAX_BLOCK 4096u
#define MAX_BLOCK_VALUES (1u << 20) /* B x C: bounds the scratch at about 4 MB */
#define MAX_FRAMES (1u << 24)
#define MAX_CODE_SUM 296u           /* step = 2^(e/4 - 64) <= 2^10 x 1.68 */
#define MAX_ROI 30u                 /* ROI gain and per-band shifts */
#define CLAMP 1e7f
#define NONE 0xFFFFFFFFu

enum { ROT_REST = 0, ROT_QUATERNION = 2 };
enum { TRANS_REST = 0, TRANS_CHANNELS = 2 };

/* Lifting constants of the CDF 9/7 wavelet (JPEG 2000's irreversible transform). */
static const float k_alpha = -1.5861343f;
static const float k_beta = -0.052980117f;
static const float k_gamma = 0.8829111f;
static const float k_delta = 0.44350687f;
static const float k_scale = 1.2301741f;
static const float k_inv_scale = 0.81289306f;
static const float k_mantissa[4] = {1.0f, 1.1892071f, 1.4142135f, 1.6817929f};

/* Samples of the level-l approximation of an n-sample signal: ceil(n / 2^l). */
static uint32_t level_length(uint32_t n, uint32_t level) {
    return (uint32_t)(((uint64_t)n + ((uint64_t)1 << level) - 1u) >> level);
}

/* Levels of a block of n frames: the most, up to L, such that every level splits a signal of
 * at least two samples. */
static uint32_t block_levels(uint32_t n, uint32_t levels) {
    while (levels > 0u && level_length(n, levels - 1u) < 2u) levels--;
    return levels;
}

/* ---------------------------------------------------------------- payload layout */
typedef struct layout {
    uint32_t frames, nodes, channels, block, levels, roi_gain, blocks, stream_bytes, size;
    const uint8_t *node_table, *approx_codes, *detail_codes, *approx_shifts, *detail_shifts;
    const uint8_t *ends, *streams;
} layout;

/* Parse the sizes of the payload at p (avail bytes readable). Returns 0 unless the header
 * is readable and the parts it announces fit in avail; checks nothing else. */
static int read_layout(const uint8_t* p, size_t avail, layout* L) {
    size_t off, total;
    /* Defined on every return: the sampler reads validated bytes and ignores the result, which
     * gcc -O3 cannot see (maybe-uninitialized). */
    memset(L, 0, sizeof *L);
    if (avail < HEADER) return 0;
    L->frames = mcd_rd_u32(p);
    L->nodes = mcd_rd_u32(p + 4);
    L->channels = mcd_rd_u32(p + 8);
    L->block = mcd_rd_u16(p + 12);
    L->levels = p[14];
    L->roi_gain = p[15];
    if (L->frames < 1u || L->frames > MAX_FRAMES || L->nodes < 1u || L->nodes > MCD_MAX_NODES) return 0;
    if (L->block < 1u || L->block > MAX_BLOCK || L->levels > MAX_LEVELS) return 0;
    if (L->channels > 7u * L->nodes || (uint64_t)L->block * L->channels > MAX_BLOCK_VALUES) return 0;
    L->blocks = (L->frames + L->block - 1u) / L->block;
    off = HEADER + (size_t)NODE_ENTRY * L->nodes;
    L->node_table = p + HEADER;
    L->approx_codes = p + off;
    L->detail_codes = L->approx_codes + L->levels + 1u;
    L->approx_shifts = L->detail_codes + L->levels;
    L->detail_shifts = L->approx_shifts + L->levels + 1u;
    off += mcd_align4(4u * (size_t)L->levels + 2u);
    L->ends = p + off;
    off += 4u * ((size_t)L->blocks + 1u);
    if (off > avail) return 0;
    L->streams = p + off;
    L->stream_bytes = mcd_rd_u32(L->ends + 4u * (size_t)L->blocks);
    total = mcd_align4(off + (size_t)L->stream_bytes);
    if (total > avail || total > 0xFFFFFFFFu) return 0;
    L->size = (uint32_t)total;
    return 1;
}

/* Stream i (0: the approximation offsets, 1 + k: block k) is [start, end) of the stream area. */
static uint32_t stream_start(const layout* L, uint32_t i) {
    return i ? mcd_rd_u32(L->ends + 4u * (size_t)(i - 1u)) : 0u;
}

static uint32_t stream_end(const layout* L, uint32_t i) {
    return mcd_rd_u32(L->ends + 4u * (size_t)i);
}

static uint32_t block_frames(const layout* L, uint32_t k) {
    uint32_t first = k * L->block;
    return L->frames - first < L->block ? L->frames - first : L->block;
}

/* ---------------------------------------------------------------- validation */
/* Everything the header and tables show, apart from the entropy streams. */
static int check_tables(const layout* L, const uint8_t* p) {
    uint32_t i, b, channels = 0, max_track = 0, max_band = 0, prev = 0;
    size_t end;
    const uint8_t* codes = L->approx_codes;
    uint32_t table = 4u * L->levels + 2u;
    if (L->roi_gain > MAX_ROI) return 0;
    /* Every level of a full block splits a signal of at least two samples. */
    if (block_levels(L->block, L->levels) != L->levels) return 0;
    for (i = 0; i < L->nodes; ++i) {
        const uint8_t* e = L->node_table + (size_t)NODE_ENTRY * i;
        if (e[0] == ROT_QUATERNION) {
            channels += 4u;
            if (e[2] > max_track) max_track = e[2];
        } else if (e[0] != ROT_REST || e[2] != 0) {
            return 0;
        }
        if (e[1] == TRANS_CHANNELS) {
            channels += 3u;
            if (e[3] > max_track) max_track = e[3];
        } else if (e[1] != TRANS_REST || e[3] != 0) {
            return 0;
        }
    }
    if (channels != L->channels) return 0;
    for (b = 0; b < 2u * L->levels + 1u; ++b)
        if (codes[b] > max_band) max_band = codes[b];
    if (max_track + max_band > MAX_CODE_SUM) return 0;
    for (b = 2u * L->levels + 1u; b < table; ++b)
        if (codes[b] > MAX_ROI) return 0;
    for (b = table; b < mcd_align4(table); ++b)
        if (codes[b] != 0) return 0;
    for (b = 0; b <= L->blocks; ++b) {
        uint32_t e = stream_end(L, b);
        if (e < prev) return 0;
        prev = e;
    }
    end = (size_t)(L->streams - p) + L->stream_bytes;
    for (; end < L->size; ++end)
        if (p[end] != 0) return 0;
    return 1;
}

static mcd_result fkw_validate(const mcd_clip_view* v) {
    layout L;
    uint32_t k;
    if (!read_layout(v->payload, v->payload_size, &L) || L.size != v->payload_size) return MCD_ERROR_MALFORMED;
    if (L.frames != v->frame_count || L.nodes != v->node_count) return MCD_ERROR_MALFORMED;
    if (!check_tables(&L, v->payload)) return MCD_ERROR_MALFORMED;
    /* The offsets stream holds C values and every block's stream exactly its frames x
     * channels (an empty stream when there are none), so decoding them at sample time cannot
     * fail. */
    for (k = 0; k <= L.blocks; ++k) {
        uint32_t start = stream_start(&L, k), count = k ? block_frames(&L, k - 1u) * L.channels : L.channels;
        if (mcd_entropy_check(L.streams + start, stream_end(&L, k) - start, 1u, count) != MCD_OK)
            return MCD_ERROR_MALFORMED;
    }
    return MCD_OK;
}

/* ---------------------------------------------------------------- scratch */
/* The codec's area: this header, the row table (u16 per frame of a block), the block's rows
 * (B x C binary32), the edge row (C binary32) and the approximation offsets (C int32), each
 * 16-aligned. */
typedef struct state {
    uint32_t slot; /* block whose rows are decoded, or NONE */
    uint32_t edge; /* frame the edge row holds, or NONE */
    uint32_t reserved[2];
} state;

typedef struct view {
    state* st;
    uint16_t* rows;
    float* slot;
    float* edge;
    int32_t* offsets;
} view;

static size_t fkw_scratch_size(const mcd_clip_view* v) {
    layout L;
    if (!read_layout(v->payload, v->payload_size, &L)) return 0;
    return mcd_align16(sizeof(state)) + mcd_align16(2u * (size_t)L.block) +
           mcd_align16(4u * (size_t)L.block * L.channels) + 2u * mcd_align16(4u * (size_t)L.channels);
}

static view scratch_view(const layout* L, void* scratch) {
    view s;
    uint8_t* p = (uint8_t*)scratch;
    s.st = (state*)(void*)p;
    p += mcd_align16(sizeof(state));
    s.rows = (uint16_t*)(void*)p;
    p += mcd_align16(2u * (size_t)L->block);
    s.slot = (float*)(void*)p;
    p += mcd_align16(4u * (size_t)L->block * L->channels);
    s.edge = (float*)(void*)p;
    p += mcd_align16(4u * (size_t)L->channels);
    s.offsets = (int32_t*)(void*)p;
    return s;
}

/* ---------------------------------------------------------------- block decoding */
static float clampf(float x) {
    return x > CLAMP ? CLAMP : x < -CLAMP ? -CLAMP : x;
}

static float step_for(uint32_t code_sum) {
    return ldexpf(k_mantissa[code_sum & 3u], (int)(code_sum >> 2) - 64);
}

/* Rows [r0, r0 + rows) of the slot hold one band's values as int32 (the entropy decoder's
 * output): replace each by its binary32 value, q x step, or for |q| >= 2^shift (an ROI value,
 * max-shift coding) q x step x 2^-(shift + roi_gain); clamped. Node by node, so each step is
 * computed once per band. */
static void dequantize_band(const layout* L, float* slot, uint32_t r0, uint32_t rows, uint32_t code,
                            uint32_t shift) {
    uint32_t i, c = 0, r, k, C = L->channels;
    uint32_t threshold = shift ? (uint32_t)1u << shift : NONE;
    int roi_exp = -(int)(shift + L->roi_gain);
    for (i = 0; i < L->nodes; ++i) {
        const uint8_t* e = L->node_table + (size_t)NODE_ENTRY * i;
        uint32_t part;
        for (part = 0; part < 2u; ++part) {
            uint32_t width = part == 0 ? (e[0] == ROT_QUATERNION ? 4u : 0u) : (e[1] == TRANS_CHANNELS ? 3u : 0u);
            float step, fine;
            if (!width) continue;
            step = step_for(e[2u + part] + code);
            fine = ldexpf(step, roi_exp);
            for (r = r0; r < r0 + rows; ++r) {
                float* row = slot + (size_t)r * C + c;
                for (k = 0; k < width; ++k) {
                    int32_t q;
                    uint32_t mag;
                    float f;
                    memcpy(&q, row + k, sizeof q);
                    mag = q < 0 ? (uint32_t)(-(q + 1)) + 1u : (uint32_t)q; /* |q| <= 2^30 - 1 */
                    f = clampf((float)q * (mag >= threshold ? fine : step));
                    memcpy(row + k, &f, sizeof f);
                }
            }
            c += width;
        }
    }
}

/* s[k] -= w (d[k-1] + d[k]) for the ns even samples (rows through the table), d[-1] = d[0],
 * d[nd] = d[nd-1]: the whole-sample symmetric extension. */
static void lift_even(float* x, const uint16_t* rows, uint32_t ns, uint32_t nd, uint32_t C, float w) {
    uint32_t k, c;
    const float* d = x + (size_t)ns * C;
    for (k = 0; k < ns; ++k) {
        float* s = x + (size_t)rows[k] * C;
        const float* dl = d + (size_t)(k > 0u ? k - 1u : 0u) * C;
        const float* dr = d + (size_t)(k < nd ? k : nd - 1u) * C;
        for (c = 0; c < C; ++c) s[c] -= w * (dl[c] + dr[c]);
    }
}

/* d[k] -= w (s[k] + s[k+1]) for the nd odd samples, s[ns] = s[ns-1]. */
static void lift_odd(float* x, const uint16_t* rows, uint32_t ns, uint32_t nd, uint32_t C, float w) {
    uint32_t k, c;
    float* d = x + (size_t)ns * C;
    for (k = 0; k < nd; ++k) {
        float* dk = d + (size_t)k * C;
        const float* sl = x + (size_t)rows[k] * C;
        const float* sr = x + (size_t)rows[k + 1u < ns ? k + 1u : ns - 1u] * C;
        for (c = 0; c < C; ++c) dk[c] -= w * (sl[c] + sr[c]);
    }
}

/* Undo one level: the approximation's ns samples lie at rows[0 .. ns), the level's nd details
 * in rows [ns, ns + nd); afterwards rows[] places the ns + nd samples of the finer one. */
static void inverse_level(float* x, uint16_t* rows, uint32_t ns, uint32_t nd, uint32_t C) {
    uint32_t k, c, j;
    for (k = 0; k < ns; ++k)
        for (c = 0; c < C; ++c) x[(size_t)rows[k] * C + c] *= k_scale;
    for (k = 0; k < (size_t)nd * C; ++k) x[(size_t)ns * C + k] *= k_inv_scale;
    lift_even(x, rows, ns, nd, C, k_delta);
    lift_odd(x, rows, ns, nd, C, k_gamma);
    lift_even(x, rows, ns, nd, C, k_beta);
    lift_odd(x, rows, ns, nd, C, k_alpha);
    for (k = 0; k < (ns + nd) * C; ++k) x[k] = clampf(x[k]);
    /* Sample 2k is the even sample k, sample 2k + 1 the detail row ns + k. Top down, so each
     * entry read (j / 2 < j) is still the coarser level's. */
    for (j = ns + nd; j-- > 0u;) rows[j] = (uint16_t)((j & 1u) ? ns + (j >> 1) : rows[j >> 1]);
}

/* Decode block k into the slot: its stream, the dequantization band by band, the synthesis.
 * Cannot fail on a validated payload. */
static void decode_block(const layout* L, const view* s, uint32_t k) {
    uint32_t n = block_frames(L, k), levels = block_levels(n, L->levels), C = L->channels;
    uint32_t start = stream_start(L, k + 1u), l, r0, j, c;
    s->st->slot = k;
    for (j = 0; j < n; ++j) s->rows[j] = (uint16_t)j; /* the approximation's rows; the rest is rewritten */
    if (C == 0u) return;
    (void)mcd_entropy_decode(L->streams + start, stream_end(L, k + 1u) - start, 1u, (int32_t*)(void*)s->slot, n * C);
    r0 = level_length(n, levels);
    if (levels == L->levels) { /* the approximation is coded as its deviation from the offsets */
        (void)mcd_entropy_decode(L->streams, stream_end(L, 0), 1u, s->offsets, C);
        for (j = 0; j < r0; ++j) {
            int32_t* row = (int32_t*)(void*)(s->slot + (size_t)j * C);
            for (c = 0; c < C; ++c) row[c] = (int32_t)((int64_t)row[c] + s->offsets[c]);
        }
    }
    dequantize_band(L, s->slot, 0u, r0, L->approx_codes[levels], L->approx_shifts[levels]);
    for (l = levels; l >= 1u; --l) {
        uint32_t rows = level_length(n, l - 1u) - level_length(n, l);
        dequantize_band(L, s->slot, r0, rows, L->detail_codes[l - 1u], L->detail_shifts[l - 1u]);
        r0 += rows;
    }
    for (l = levels; l >= 1u; --l) {
        uint32_t ns = level_length(n, l);
        inverse_level(s->slot, s->rows, ns, level_length(n, l - 1u) - ns, C);
    }
}

/* The decoded channels of frame f: a row of the slot, or the edge row. */
static const float* frame_values(const layout* L, const view* s, uint32_t f) {
    if (f / L->block == s->st->slot) return s->slot + (size_t)s->rows[f % L->block] * L->channels;
    return s->edge;
}

static void copy_edge(const layout* L, const view* s, uint32_t f) {
    memcpy(s->edge, frame_values(L, s, f), 4u * (size_t)L->channels);
    s->st->edge = f;
}

/* Make frames f0 and f1 = f0 + 1 (or f0 alone when f1 == f0) readable. On a block boundary
 * the slot holds one side and the edge row a copy of the other: forward playback keeps the
 * last frame of the block it leaves, backward playback the first frame of the block it leaves,
 * so each block is decoded once whichever way the clip plays. */
static void prepare_frames(const layout* L, const view* s, uint32_t f0, uint32_t f1) {
    uint32_t k0 = f0 / L->block, k1 = f1 / L->block;
    if (k0 == k1) {
        if (s->st->slot != k0) decode_block(L, s, k0);
        return;
    }
    if ((s->st->slot == k0 && s->st->edge == f1) || (s->st->slot == k1 && s->st->edge == f0)) return;
    if (s->st->slot == k1) { /* backward: keep the first frame of k1 */
        copy_edge(L, s, f1);
        decode_block(L, s, k0);
        return;
    }
    if (s->st->slot != k0) decode_block(L, s, k0);
    copy_edge(L, s, f0);
    decode_block(L, s, k1);
}

/* ---------------------------------------------------------------- sampling */
static void fkw_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                       int fresh) {
    layout L;
    view s;
    const float *a, *b;
    uint32_t f0, f1, i, c = 0, k;
    float t;
    (void)flags;
    read_layout(v->payload, v->payload_size, &L); /* validated: cannot fail */
    s = scratch_view(&L, scratch);
    if (fresh) {
        s.st->slot = NONE;
        s.st->edge = NONE;
    }
    f0 = (uint32_t)x;
    if (f0 > L.frames - 1u) f0 = L.frames - 1u;
    t = x - (float)f0;
    f1 = t > 0.0f && f0 + 1u < L.frames ? f0 + 1u : f0;
    prepare_frames(&L, &s, f0, f1);
    a = frame_values(&L, &s, f0);
    b = frame_values(&L, &s, f1);
    for (i = 0; i < L.nodes; ++i) {
        const uint8_t* e = L.node_table + (size_t)NODE_ENTRY * i;
        mcd_skel_rest(v->skeleton, i, &out[i]);
        if (e[0] == ROT_QUATERNION) {
            float q[4], n2 = 0.0f;
            for (k = 0; k < 4u; ++k) {
                q[k] = f1 == f0 ? a[c + k] : a[c + k] + (b[c + k] - a[c + k]) * t;
                n2 += q[k] * q[k];
            }
            c += 4u;
            if (n2 > 1e-30f) {
                float inv = 1.0f / sqrtf(n2);
                for (k = 0; k < 4u; ++k) out[i].rotation[k] = q[k] * inv;
            } else {
                out[i].rotation[0] = out[i].rotation[1] = out[i].rotation[2] = 0.0f;
                out[i].rotation[3] = 1.0f;
            }
        }
        if (e[1] == TRANS_CHANNELS) {
            for (k = 0; k < 3u; ++k)
                out[i].translation[k] = f1 == f0 ? a[c + k] : a[c + k] + (b[c + k] - a[c + k]) * t;
            c += 3u;
        }
    }
}

const mcd_codec_ops mcd_codec_fkwavelet_ops = {
    MCD_CODEC_FK_WAVELET, 0x56574B46u /* "FKWV" */, 2u, NULL, fkw_validate, fkw_scratch_size, fkw_sample};
