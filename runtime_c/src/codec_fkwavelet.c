/* Codec `fk-wavelet`: per-channel CDF 9/7 wavelet coefficients, quantized with per-joint step
 * sizes and entropy coded band by band, coarse to fine (seed 000 §4; docs/FORMAT.md, FKWV).
 *
 * mcd_open decodes every payload of the section and runs the inverse transform once, so the
 * resident memory holds every channel reconstructed on every frame (4 bytes per channel per
 * frame). A sample then reads two rows and interpolates: no transform, no allocation.
 *
 * The inverse transform works in place inside the clip's resident block. Before level l is
 * undone, rows [0, n_l) hold the level-l approximation; the level's detail band is decoded
 * straight after it, the lifting steps are undone on the two halves, and the result is
 * interleaved using the rows past n_(l-1) (not yet decoded) as room. The finest level is not
 * interleaved: even frames stay in the first half and odd frames in the second, and a sample
 * computes the row of a frame instead. */
#include <math.h>
#include <string.h>

#include "entropy.h"
#include "internal.h"

#define HEADER 16u
#define NODE_ENTRY 4u
#define MAX_LEVELS 15u
#define MAX_CODE_SUM 296u         /* step = 2^(e/4 - 64) <= 2^10 */
#define MAX_ROI 30u               /* ROI gain and per-band shifts */
#define MAX_VALUES (1u << 26)     /* frames x channels of one payload */
#define MAX_RESIDENT (1u << 31)   /* the whole section's resident block */
#define CLAMP 1e7f
#define DIR_ENTRY 8u

enum { ROT_IDENTITY = 0, ROT_QUATERNION = 2 };
enum { TRANS_REST = 0, TRANS_CHANNELS = 2 };

/* Lifting constants of the CDF 9/7 wavelet (JPEG 2000's irreversible transform). */
static const float k_alpha = -1.5861343f;
static const float k_beta = -0.052980117f;
static const float k_gamma = 0.8829111f;
static const float k_delta = 0.44350687f;
static const float k_scale = 1.2301741f;
static const float k_inv_scale = 0.81289306f;
static const float k_mantissa[4] = {1.0f, 1.1892071f, 1.4142135f, 1.6817929f};

static size_t align4z(size_t x) {
    return (x + 3u) & ~(size_t)3u;
}

static size_t align16z(size_t x) {
    return (x + 15u) & ~(size_t)15u;
}

/* Length of the level-l approximation of an F-frame channel: ceil(F / 2^l). */
static uint32_t level_length(uint32_t frames, uint32_t level) {
    return (uint32_t)(((uint64_t)frames + ((uint64_t)1 << level) - 1u) >> level);
}

/* Rows of band b: b = 0 the coarsest approximation, b >= 1 the details of level L + 1 - b. */
static uint32_t band_rows(uint32_t frames, uint32_t levels, uint32_t band) {
    uint32_t l;
    if (band == 0) return level_length(frames, levels);
    l = levels + 1u - band;
    return level_length(frames, l - 1u) - level_length(frames, l);
}

typedef struct layout {
    uint32_t frames, nodes, channels, levels, roi_gain, size;
    const uint8_t *node_table, *band_codes, *roi_shifts, *band_bytes, *streams;
} layout;

/* Parse the sizes of the payload at p (avail bytes readable). Returns 0 unless the header
 * is readable and the parts it announces fit in avail; checks nothing else. */
static int read_layout(const uint8_t* p, size_t avail, layout* L) {
    size_t off, total;
    uint32_t b;
    if (avail < HEADER) return 0;
    L->frames = mcd_rd_u32(p);
    L->nodes = mcd_rd_u32(p + 4);
    L->channels = mcd_rd_u32(p + 8);
    L->levels = p[12];
    L->roi_gain = p[13];
    if (L->frames < 1u || L->nodes < 1u || L->nodes > MCD_MAX_NODES || L->levels > MAX_LEVELS) return 0;
    if (L->channels > 7u * L->nodes) return 0;
    off = HEADER + (size_t)NODE_ENTRY * L->nodes;
    L->node_table = p + HEADER;
    L->band_codes = p + off;
    L->roi_shifts = p + off + L->levels + 1u;
    off += align4z(2u * (L->levels + 1u));
    L->band_bytes = p + off;
    off += 4u * (size_t)(L->levels + 1u);
    if (off > avail) return 0;
    L->streams = p + off;
    total = off;
    for (b = 0; b <= L->levels; ++b) {
        total += mcd_rd_u32(L->band_bytes + 4u * b);
        if (total > avail) return 0;
    }
    total = align4z(total);
    if (total > avail || total > 0xFFFFFFFFu) return 0;
    L->size = (uint32_t)total;
    return 1;
}

/* Everything about one payload the raw bytes show, apart from the entropy streams. */
static int check_payload(const layout* L, const uint8_t* p) {
    uint32_t i, b, channels = 0, max_track = 0, max_band = 0;
    size_t end;
    if (L->roi_gain > MAX_ROI || p[14] || p[15]) return 0;
    if ((uint64_t)L->frames * L->channels > MAX_VALUES) return 0;
    /* Every level splits a signal of at least two samples. */
    if (L->levels > 0u && level_length(L->frames, L->levels - 1u) < 2u) return 0;
    for (i = 0; i < L->nodes; ++i) {
        const uint8_t* e = L->node_table + (size_t)NODE_ENTRY * i;
        if (e[0] == ROT_QUATERNION) {
            channels += 4u;
            if (e[2] > max_track) max_track = e[2];
        } else if (e[0] != ROT_IDENTITY || e[2] != 0) {
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
    for (b = 0; b <= L->levels; ++b)
        if (L->band_codes[b] > max_band) max_band = L->band_codes[b];
    for (b = 0; b <= L->levels; ++b)
        if (L->roi_shifts[b] > MAX_ROI) return 0;
    for (b = 2u * (L->levels + 1u); b < align4z(2u * (L->levels + 1u)); ++b)
        if (L->band_codes[b] != 0) return 0;
    if (max_track + max_band > MAX_CODE_SUM) return 0;
    /* A stream of no values is empty; any other holds at least 4 bytes (checked on decode). */
    for (b = 0; b <= L->levels; ++b)
        if (L->channels == 0u && mcd_rd_u32(L->band_bytes + 4u * b) != 0) return 0;
    end = (size_t)(L->streams - p);
    for (b = 0; b <= L->levels; ++b) end += mcd_rd_u32(L->band_bytes + 4u * b);
    for (; end < L->size; ++end)
        if (p[end] != 0) return 0;
    return 1;
}

/* Walk the section: payloads back to back from offset 0, each a multiple of 4 bytes, filling
 * it exactly. Returns the payload count (0 when the walk fails) and the resident bytes. When
 * `find` is not UINT32_MAX, *found is set to 1 if a payload starts at that offset with size
 * `find_size`. */
static uint32_t walk(const uint8_t* section, uint32_t size, size_t* resident, uint32_t find,
                     uint32_t find_size, int* found) {
    uint32_t off = 0, count = 0;
    size_t total = 0;
    while (off < size) {
        layout L;
        if (!read_layout(section + off, size - off, &L) || !check_payload(&L, section + off)) return 0;
        if (off == find && L.size == find_size && found) *found = 1;
        total += align16z(4u * (size_t)L.frames * L.channels);
        if (total > MAX_RESIDENT) return 0;
        off += L.size;
        count++;
    }
    if (count == 0u) return 0;
    total += align16z(16u + (size_t)DIR_ENTRY * count);
    if (total > MAX_RESIDENT) return 0;
    *resident = total;
    return count;
}

/* ---------------------------------------------------------------- validation */
static mcd_result fkw_validate(const mcd_clip_view* v) {
    layout L;
    size_t resident;
    int found = 0;
    uint32_t poff = (uint32_t)(v->payload - v->section);
    if (!read_layout(v->payload, v->payload_size, &L) || L.size != v->payload_size) return MCD_ERROR_MALFORMED;
    if (L.frames != v->frame_count || L.nodes != v->node_count) return MCD_ERROR_MALFORMED;
    if (!check_payload(&L, v->payload)) return MCD_ERROR_MALFORMED;
    /* Every payload of the section must be walkable, so the resident block exists. */
    if (!walk(v->section, v->section_size, &resident, poff, v->payload_size, &found) || !found)
        return MCD_ERROR_MALFORMED;
    if (v->resident) {
        /* Opened: the directory holds this payload (the walk above guarantees it). */
        uint32_t count = mcd_rd_u32(v->resident), lo = 0, hi = count;
        while (lo < hi) {
            uint32_t mid = lo + (hi - lo) / 2u;
            uint32_t at = mcd_rd_u32(v->resident + 16u + (size_t)DIR_ENTRY * mid);
            if (at == poff) return MCD_OK;
            if (at < poff) lo = mid + 1u; else hi = mid;
        }
        return MCD_ERROR_MALFORMED;
    }
    return MCD_OK;
}

static size_t fkw_resident_size(const uint8_t* section, uint32_t size) {
    size_t total = 0;
    if (!walk(section, size, &total, UINT32_MAX, 0, NULL)) return 0;
    return total;
}

/* ---------------------------------------------------------------- open: decode + synthesis */
static float clampf(float x) {
    return x > CLAMP ? CLAMP : x < -CLAMP ? -CLAMP : x;
}

static float step_for(uint32_t code_sum) {
    return ldexpf(k_mantissa[code_sum & 3u], (int)(code_sum >> 2) - 64);
}

/* The quantization step of every channel for band code `band_code` into steps[C]. */
static void channel_steps(const layout* L, uint32_t band_code, float* steps) {
    uint32_t i, c = 0, k;
    for (i = 0; i < L->nodes; ++i) {
        const uint8_t* e = L->node_table + (size_t)NODE_ENTRY * i;
        if (e[0] == ROT_QUATERNION)
            for (k = 0; k < 4u; ++k) steps[c++] = step_for(e[2] + band_code);
        if (e[1] == TRANS_CHANNELS)
            for (k = 0; k < 3u; ++k) steps[c++] = step_for(e[3] + band_code);
    }
}

/* Decode band b into rows (count rows x C) as floats: value x step, or, for a value at or
 * above the band's ROI threshold 2^shift (max-shift ROI coding), value x step x 2^-(shift +
 * roi_gain). The decoder writes int32 in place; each is read back and replaced by its float
 * through memcpy. */
static mcd_result decode_band(const layout* L, uint32_t b, const uint8_t* stream, uint32_t bytes,
                              uint32_t rows, float* out, float* steps, int clamp) {
    uint32_t r, c, shift = L->roi_shifts[b];
    uint32_t threshold = shift ? (uint32_t)1u << shift : 0xFFFFFFFFu;
    int scale = -(int)(shift + L->roi_gain);
    size_t n = (size_t)rows * L->channels;
    int32_t* ints = (int32_t*)(void*)out;
    mcd_result res;
    if (n == 0) return bytes == 0 ? MCD_OK : MCD_ERROR_MALFORMED;
    res = mcd_entropy_decode(stream, bytes, 1u, ints, (uint32_t)n);
    if (res != MCD_OK) return MCD_ERROR_MALFORMED;
    channel_steps(L, L->band_codes[b], steps);
    for (r = 0; r < rows; ++r) {
        for (c = 0; c < L->channels; ++c) {
            size_t at = (size_t)r * L->channels + c;
            int32_t q;
            uint32_t mag;
            float f;
            memcpy(&q, out + at, sizeof q);
            mag = q < 0 ? (uint32_t)(-(q + 1)) + 1u : (uint32_t)q; /* |q| <= 2^30 - 1 */
            f = (float)q * (mag >= threshold ? ldexpf(steps[c], scale) : steps[c]);
            if (clamp) f = clampf(f);
            memcpy(out + at, &f, sizeof f);
        }
    }
    return MCD_OK;
}

/* One lifting step on the even rows: s[k] -= w (d[k-1] + d[k]), d[-1] = d[0], d[nd] = d[nd-1]. */
static void lift_even(float* s, const float* d, uint32_t ns, uint32_t nd, uint32_t C, float w) {
    uint32_t k, c;
    for (k = 0; k < ns; ++k) {
        const float* dl = d + (size_t)(k > 0u ? k - 1u : 0u) * C;
        const float* dr = d + (size_t)(k < nd ? k : nd - 1u) * C;
        for (c = 0; c < C; ++c) s[(size_t)k * C + c] -= w * (dl[c] + dr[c]);
    }
}

/* One lifting step on the odd rows: d[k] -= w (s[k] + s[k+1]), s[ns] = s[ns-1]. */
static void lift_odd(const float* s, float* d, uint32_t ns, uint32_t nd, uint32_t C, float w) {
    uint32_t k, c;
    for (k = 0; k < nd; ++k) {
        const float* sl = s + (size_t)k * C;
        const float* sr = s + (size_t)(k + 1u < ns ? k + 1u : ns - 1u) * C;
        for (c = 0; c < C; ++c) d[(size_t)k * C + c] -= w * (sl[c] + sr[c]);
    }
}

/* Undo one level: s = rows [0, ns), d = rows [ns, ns + nd), C floats per row. The boundary
 * rules above are the whole-sample symmetric extension. */
static void inverse_lifting(float* s, float* d, uint32_t ns, uint32_t nd, uint32_t C) {
    uint32_t k, c;
    for (k = 0; k < ns; ++k)
        for (c = 0; c < C; ++c) s[(size_t)k * C + c] *= k_scale;
    for (k = 0; k < nd; ++k)
        for (c = 0; c < C; ++c) d[(size_t)k * C + c] *= k_inv_scale;
    lift_even(s, d, ns, nd, C, k_delta);
    lift_odd(s, d, ns, nd, C, k_gamma);
    lift_even(s, d, ns, nd, C, k_beta);
    lift_odd(s, d, ns, nd, C, k_alpha);
    for (k = 0; k < (ns + nd) * C; ++k) s[k] = clampf(s[k]);
}

/* Rows [0, ns) = even samples, [ns, ns + nd) = odd: put them in sample order, with the nd
 * rows from `room` as temporary space. */
static void interleave(float* x, uint32_t ns, uint32_t nd, uint32_t C, float* room) {
    size_t row = (size_t)C * sizeof(float);
    uint32_t k;
    memcpy(room, x + (size_t)ns * C, (size_t)nd * row);
    for (k = ns; k-- > 1u;) memcpy(x + (size_t)(2u * k) * C, x + (size_t)k * C, row);
    for (k = 0; k < nd; ++k) memcpy(x + (size_t)(2u * k + 1u) * C, room + (size_t)k * C, row);
}

static mcd_result open_payload(const layout* L, float* x, float* steps) {
    const uint8_t* stream = L->streams;
    uint32_t b, l, C = L->channels;
    mcd_result r;
    uint32_t bytes = mcd_rd_u32(L->band_bytes);
    r = decode_band(L, 0, stream, bytes, band_rows(L->frames, L->levels, 0), x, steps, 1);
    if (r != MCD_OK) return r;
    stream += bytes;
    for (b = 1; b <= L->levels; ++b) {
        uint32_t ns, nd;
        l = L->levels + 1u - b;
        ns = level_length(L->frames, l);
        nd = level_length(L->frames, l - 1u) - ns;
        bytes = mcd_rd_u32(L->band_bytes + 4u * b);
        r = decode_band(L, b, stream, bytes, nd, x + (size_t)ns * C, steps, 0);
        if (r != MCD_OK) return r;
        stream += bytes;
        if (C == 0u) continue;
        inverse_lifting(x, x + (size_t)ns * C, ns, nd, C);
        if (l > 1u) interleave(x, ns, nd, C, x + (size_t)(ns + nd) * C);
    }
    return MCD_OK;
}

static mcd_result fkw_open_section(const uint8_t* section, uint32_t size, uint8_t* resident) {
    size_t total = 0, at;
    uint32_t count = walk(section, size, &total, UINT32_MAX, 0, NULL), off = 0, i;
    float steps[7u * MCD_MAX_NODES]; /* one step per channel, C <= 7 x node_count */
    if (!count) return MCD_ERROR_MALFORMED;
    at = align16z(16u + (size_t)DIR_ENTRY * count);
    memcpy(resident, &count, 4);
    for (i = 0; i < count; ++i) {
        layout L;
        uint32_t rel = (uint32_t)at;
        mcd_result r;
        read_layout(section + off, size - off, &L);
        memcpy(resident + 16u + (size_t)DIR_ENTRY * i, &off, 4);
        memcpy(resident + 16u + (size_t)DIR_ENTRY * i + 4u, &rel, 4);
        r = open_payload(&L, (float*)(void*)(resident + at), steps);
        if (r != MCD_OK) return r;
        at += align16z(4u * (size_t)L.frames * L.channels);
        off += L.size;
    }
    return MCD_OK;
}

/* ---------------------------------------------------------------- sampling */
static size_t fkw_scratch_size(const mcd_clip_view* v) {
    (void)v;
    return 0;
}

static const float* clip_rows(const mcd_clip_view* v) {
    uint32_t poff = (uint32_t)(v->payload - v->section);
    uint32_t count = mcd_rd_u32(v->resident), lo = 0, hi = count;
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo) / 2u;
        const uint8_t* e = v->resident + 16u + (size_t)DIR_ENTRY * mid;
        uint32_t at = mcd_rd_u32(e);
        if (at == poff) return (const float*)(const void*)(v->resident + mcd_rd_u32(e + 4));
        if (at < poff) lo = mid + 1u; else hi = mid;
    }
    return NULL;
}

/* Row of frame f: the finest level leaves even frames first, then odd ones. */
static uint32_t frame_row(uint32_t f, uint32_t frames, uint32_t levels) {
    if (levels == 0u) return f;
    return (f & 1u) ? level_length(frames, 1u) + (f >> 1) : (f >> 1);
}

static mcd_result fkw_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out,
                             void* scratch, int fresh) {
    layout L;
    const float *rows, *a, *b;
    uint32_t i0, i1, i, c = 0;
    float t;
    (void)flags;
    (void)scratch;
    (void)fresh;
    if (!v->resident) return MCD_ERROR_MALFORMED;
    read_layout(v->payload, v->payload_size, &L);
    rows = clip_rows(v);
    if (!rows) return MCD_ERROR_MALFORMED;
    i0 = (uint32_t)x;
    if (i0 > L.frames - 1u) i0 = L.frames - 1u;
    i1 = i0 + 1u < L.frames ? i0 + 1u : i0;
    t = x - (float)i0;
    a = rows + (size_t)frame_row(i0, L.frames, L.levels) * L.channels;
    b = rows + (size_t)frame_row(i1, L.frames, L.levels) * L.channels;
    for (i = 0; i < L.nodes; ++i) {
        const uint8_t* e = L.node_table + (size_t)NODE_ENTRY * i;
        const uint8_t* rec = v->skeleton + 16 + (size_t)i * MCD_SKEL_NODE_SIZE;
        float q[4] = {0.0f, 0.0f, 0.0f, 1.0f};
        uint32_t k;
        if (e[0] == ROT_QUATERNION) {
            float n2 = 0.0f;
            for (k = 0; k < 4u; ++k) {
                q[k] = a[c + k] + (b[c + k] - a[c + k]) * t;
                n2 += q[k] * q[k];
            }
            c += 4u;
            if (n2 > 1e-30f) {
                float inv = 1.0f / sqrtf(n2);
                for (k = 0; k < 4u; ++k) q[k] *= inv;
            } else {
                q[0] = q[1] = q[2] = 0.0f;
                q[3] = 1.0f;
            }
        }
        for (k = 0; k < 4u; ++k) out[i].rotation[k] = q[k];
        if (e[1] == TRANS_CHANNELS) {
            for (k = 0; k < 3u; ++k) out[i].translation[k] = a[c + k] + (b[c + k] - a[c + k]) * t;
            c += 3u;
        } else {
            for (k = 0; k < 3u; ++k) out[i].translation[k] = mcd_rd_f32(rec + 8 + 4 * k);
        }
    }
    return MCD_OK;
}

const mcd_codec_ops mcd_codec_fkwavelet_ops = {
    MCD_CODEC_FK_WAVELET, 0x56574B46u /* "FKWV" */, fkw_validate, fkw_resident_size,
    fkw_open_section, fkw_scratch_size, fkw_sample};
