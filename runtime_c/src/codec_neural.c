/* Codec `neural`: a clip as Fourier-feature MLPs from time to pose (seed 001; docs/FORMAT.md,
 * NEUR version 2).
 *
 * The clip is cut into windows that tile it (consecutive windows share their border frame),
 * each with its own network. A sample picks the window of x and evaluates its eq. 2 once: K
 * sin/cos pairs, then (2K+1)·H + H·H + H·M multiply-adds and 2H expm1f. The quantized weights
 * of the window are expanded into the scratch when the sample lands in another window than the
 * one held, so sequential playback reads only floats. Validation bounds every offset, weight,
 * scale and offset value, and the outputs are clamped, so any accepted payload samples to
 * finite transforms. */
#include <math.h>
#include <string.h>

#include "internal.h"

#define HEADER 16u
#define NODE_ENTRY 8u
#define WINDOW_ENTRY 16u
#define WINDOW_HEADER 32u
#define MAX_K 32u
#define MAX_H (2u * (2u * MAX_K + 1u))
#define MAX_WINDOWS 65535u
#define MAX_WEIGHT 1e4f
#define PI_D 3.14159265358979323846
#define NO_WINDOW 0xFFFFFFFFu

enum { ROT_IDENTITY = 0, ROT_CONSTANT = 1, ROT_QUATERNION = 2, ROT_AXIS_ANGLE = 3 };
enum { TRANS_REST = 0, TRANS_OUTPUT = 2 };

/* The clip-wide part of a payload (NEUR version 2). */
typedef struct layout {
    uint32_t frames, nodes, m, refs, windows;
    const uint8_t *node_table, *ref_table, *scale, *offset, *window_table;
} layout;

/* One window's network: frames [start, start + count - 1], eq. 1-2 with its own K, H, bits. */
typedef struct window {
    uint32_t start, count, k, h, bits, d, weights;
    const uint8_t *steps, *freqs, *stream;
} window;


/* Bytes before the first window block; only meaningful for counts within the format's limits. */
static size_t head_bytes(uint32_t nodes, uint32_t m, uint32_t refs, uint32_t windows) {
    return HEADER + (size_t)nodes * NODE_ENTRY + 16u * (size_t)refs + 8u * (size_t)m + (size_t)windows * WINDOW_ENTRY;
}

static uint32_t weight_count(uint32_t d, uint32_t h, uint32_t m) {
    return h * d + h + h * h + h + m * h + m;
}

/* Bytes of a window block with these counts (counts within the format's limits). */
static size_t block_bytes(uint32_t k, uint32_t h, uint32_t m, uint32_t bits) {
    uint64_t stream_bits = (uint64_t)weight_count(2u * k + 1u, h, m) * bits;
    return WINDOW_HEADER + mcd_align4(2u * (size_t)k) + mcd_align4((size_t)((stream_bits + 7u) / 8u));
}

static void read_layout(const uint8_t* p, layout* L) {
    L->frames = mcd_rd_u32(p);
    L->nodes = mcd_rd_u32(p + 4);
    L->m = mcd_rd_u16(p + 8);
    L->refs = mcd_rd_u16(p + 10);
    L->windows = mcd_rd_u16(p + 12);
    L->node_table = p + HEADER;
    L->ref_table = L->node_table + (size_t)L->nodes * NODE_ENTRY;
    L->scale = L->ref_table + 16u * (size_t)L->refs;
    L->offset = L->scale + 4u * (size_t)L->m;
    L->window_table = L->offset + 4u * (size_t)L->m;
}

/* Window `i` of a validated payload (or of one whose entry and block header were checked). */
static void read_window(const uint8_t* payload, const layout* L, uint32_t i, window* w) {
    const uint8_t* e = L->window_table + (size_t)i * WINDOW_ENTRY;
    const uint8_t* b = payload + mcd_rd_u32(e + 8);
    w->start = mcd_rd_u32(e);
    w->count = mcd_rd_u32(e + 4);
    w->k = mcd_rd_u16(b);
    w->h = mcd_rd_u16(b + 2);
    w->bits = b[4];
    w->d = 2u * w->k + 1u;
    w->weights = weight_count(w->d, w->h, L->m);
    w->steps = b + 8;
    w->freqs = b + WINDOW_HEADER;
    w->stream = w->freqs + mcd_align4(2u * (size_t)w->k);
}

static int bounded(float v, float limit) {
    return mcd_finite(v) && v <= limit && v >= -limit;
}

/* ---------------------------------------------------------------- validation */
static mcd_result check_window(const mcd_clip_view* v, const layout* L, uint32_t i, uint32_t start,
                               uint32_t block_offset, uint32_t* next_offset) {
    const uint8_t* e = L->window_table + (size_t)i * WINDOW_ENTRY;
    const uint8_t* b;
    window w;
    uint64_t stream_bits, pos, end;
    uint32_t c, count = mcd_rd_u32(e + 4), off = mcd_rd_u32(e + 8), size = mcd_rd_u32(e + 12);
    /* Windows tile the clip in order, consecutive ones sharing one frame; blocks are packed. */
    if (mcd_rd_u32(e) != start || count == 0 || (uint64_t)start + count > L->frames) return MCD_ERROR_MALFORMED;
    if (count == 1 && L->frames != 1) return MCD_ERROR_MALFORMED;
    if (off != block_offset || size < WINDOW_HEADER || (uint64_t)off + size > v->payload_size) return MCD_ERROR_MALFORMED;
    b = v->payload + off;
    if (mcd_rd_u16(b) > MAX_K || mcd_rd_u16(b + 2) == 0 || mcd_rd_u16(b + 2) > MAX_H) return MCD_ERROR_MALFORMED;
    if (b[4] < 2u || b[4] > 16u || b[5] || b[6] || b[7]) return MCD_ERROR_MALFORMED;
    if (block_bytes(mcd_rd_u16(b), mcd_rd_u16(b + 2), L->m, b[4]) != size) return MCD_ERROR_MALFORMED;
    read_window(v->payload, L, i, &w);
    for (c = 0; c < 6; ++c) {
        float s = mcd_rd_f32(w.steps + 4 * c);
        /* |code| <= 2^(bits-1): every dequantized weight stays within MAX_WEIGHT. */
        if (!mcd_finite(s) || !(s > 0.0f) || s * (float)(1u << (w.bits - 1u)) > MAX_WEIGHT) return MCD_ERROR_MALFORMED;
    }
    for (c = 0; c < w.k; ++c)
        if (mcd_rd_u16(w.freqs + 2 * c) == 0) return MCD_ERROR_MALFORMED;
    if ((w.k & 1u) && mcd_rd_u16(w.freqs + 2 * w.k) != 0) return MCD_ERROR_MALFORMED;
    /* Unused bits of the stream's last byte and the padding after it are zero. */
    stream_bits = (uint64_t)w.weights * w.bits;
    end = (uint64_t)(b + size - w.stream);
    if ((stream_bits & 7u) && (w.stream[stream_bits >> 3] >> (stream_bits & 7u)) != 0) return MCD_ERROR_MALFORMED;
    for (pos = (stream_bits + 7u) / 8u; pos < end; ++pos)
        if (w.stream[pos] != 0) return MCD_ERROR_MALFORMED;
    *next_offset = off + size;
    return MCD_OK;
}

static mcd_result neural_validate(const mcd_clip_view* v) {
    const uint8_t* p = v->payload;
    layout L;
    uint32_t i, c, start = 0, offset;
    if (v->payload_size < HEADER) return MCD_ERROR_MALFORMED;
    /* Counts first: nothing below forms a pointer from a count that was not checked. */
    if (mcd_rd_u32(p) != v->frame_count || mcd_rd_u32(p + 4) != v->node_count) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u16(p + 8) > 7u * v->node_count || mcd_rd_u16(p + 10) > v->node_count) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u16(p + 12) == 0 || mcd_rd_u16(p + 12) > v->frame_count || mcd_rd_u16(p + 14) != 0) return MCD_ERROR_MALFORMED;
    read_layout(p, &L);
    if ((uint64_t)head_bytes(L.nodes, L.m, L.refs, L.windows) > v->payload_size) return MCD_ERROR_MALFORMED;

    for (i = 0; i < L.refs; ++i) {
        const uint8_t* q = L.ref_table + 16u * i;
        float n = 0.0f;
        for (c = 0; c < 4; ++c) {
            float x = mcd_rd_f32(q + 4 * c);
            if (!bounded(x, 2.0f)) return MCD_ERROR_MALFORMED;
            n += x * x;
        }
        if (!(n > 1.0f - 2e-5f && n < 1.0f + 2e-5f)) return MCD_ERROR_MALFORMED;
    }
    for (i = 0; i < L.m; ++i)
        if (!bounded(mcd_rd_f32(L.scale + 4 * i), MCD_MAX_ABS_VALUE) ||
            !bounded(mcd_rd_f32(L.offset + 4 * i), MCD_MAX_ABS_VALUE))
            return MCD_ERROR_MALFORMED;
    for (i = 0; i < L.nodes; ++i) {
        const uint8_t* e = L.node_table + (size_t)i * NODE_ENTRY;
        uint32_t rm = e[0], tm = e[1], ro = mcd_rd_u16(e + 2), to = mcd_rd_u16(e + 4), ri = mcd_rd_u16(e + 6);
        if (rm == ROT_IDENTITY) {
            if (ro || ri) return MCD_ERROR_MALFORMED;
        } else if (rm == ROT_CONSTANT) {
            if (ro || ri >= L.refs) return MCD_ERROR_MALFORMED;
        } else if (rm == ROT_QUATERNION) {
            if (ro + 4u > L.m || ri) return MCD_ERROR_MALFORMED;
        } else if (rm == ROT_AXIS_ANGLE) {
            if (ro + 3u > L.m || ri >= L.refs) return MCD_ERROR_MALFORMED;
        } else {
            return MCD_ERROR_MALFORMED;
        }
        if (tm == TRANS_REST) {
            if (to) return MCD_ERROR_MALFORMED;
        } else if (tm == TRANS_OUTPUT) {
            if (to + 3u > L.m) return MCD_ERROR_MALFORMED;
        } else {
            return MCD_ERROR_MALFORMED;
        }
    }
    offset = (uint32_t)head_bytes(L.nodes, L.m, L.refs, L.windows);
    for (i = 0; i < L.windows; ++i) {
        mcd_result r = check_window(v, &L, i, start, offset, &offset);
        if (r != MCD_OK) return r;
        start += mcd_rd_u32(L.window_table + (size_t)i * WINDOW_ENTRY + 4) - 1u;
    }
    /* The last window ends on the last frame, the last block at the payload's end. */
    if (start != L.frames - 1u || offset != v->payload_size) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* ---------------------------------------------------------------- scratch */
/* Layout: u32 header[4] (window held, or NO_WINDOW) | f32 weights[max P] | f32 features[max D]
 * | f32 hidden0[max H] | f32 hidden1[max H] | f32 out[M]. Sized for the largest window, so one
 * scratch serves every window; a sample in another window re-expands its weights. */
static size_t neural_scratch_size(const mcd_clip_view* v) {
    layout L;
    window w;
    uint32_t i, weights = 0, d = 0, h = 0;
    read_layout(v->payload, &L);
    for (i = 0; i < L.windows; ++i) {
        read_window(v->payload, &L, i, &w);
        if (w.weights > weights) weights = w.weights;
        if (w.d > d) d = w.d;
        if (w.h > h) h = w.h;
    }
    return mcd_align16(16u + 4u * ((size_t)weights + d + 2u * (size_t)h + L.m));
}

/* The window that samples frame position x: the last one starting at or before x (a shared
 * border frame belongs to the later window). `hint` (the window held) is tried first, so
 * sequential playback does not search. */
static uint32_t find_window(const layout* L, float x, uint32_t hint) {
    uint32_t lo = 0, hi = L->windows - 1u;
    if (hint < L->windows) {
        const uint8_t* e = L->window_table + (size_t)hint * WINDOW_ENTRY;
        float s = (float)mcd_rd_u32(e);
        if (x >= s && (hint + 1u == L->windows || x < (float)mcd_rd_u32(e + WINDOW_ENTRY))) return hint;
    }
    while (lo < hi) {
        uint32_t mid = lo + (hi - lo + 1u) / 2u;
        if ((float)mcd_rd_u32(L->window_table + (size_t)mid * WINDOW_ENTRY) <= x)
            lo = mid;
        else
            hi = mid - 1u;
    }
    return lo;
}

/* Expand the bit-packed codes into floats: code - 2^(bits-1), times its tensor's step. */
static void expand_weights(const window* W, uint32_t m, float* w) {
    uint32_t counts[6], t, i, n = 0, have = 0;
    uint32_t mask = (1u << W->bits) - 1u, bias = 1u << (W->bits - 1u);
    uint64_t acc = 0;
    const uint8_t* s = W->stream;
    counts[0] = W->h * W->d;
    counts[1] = W->h;
    counts[2] = W->h * W->h;
    counts[3] = W->h;
    counts[4] = m * W->h;
    counts[5] = m;
    for (t = 0; t < 6; ++t) {
        float step = mcd_rd_f32(W->steps + 4 * t);
        for (i = 0; i < counts[t]; ++i) {
            uint32_t u;
            /* Validation sized the stream for every code, so these byte loads stay inside it. */
            while (have < W->bits) {
                acc |= (uint64_t)*s++ << have;
                have += 8u;
            }
            u = (uint32_t)acc & mask;
            acc >>= W->bits;
            have -= W->bits;
            w[n++] = (float)((int32_t)u - (int32_t)bias) * step;
        }
    }
}

static float elu(float z) {
    return z > 0.0f ? z : expm1f(z);
}

/* y = W x + b for a rows x cols row-major W. Float32 weights and activations, double
 * accumulator: a float sum over ~100 terms drifted by ~1e-6 rad on the joints, enough to
 * move an end site by 2e-4 cm; the double sum costs little at this size. */
static void dense(const float* W, const float* b, const float* x, uint32_t rows, uint32_t cols, float* y) {
    uint32_t r, c;
    for (r = 0; r < rows; ++r) {
        const float* row = W + (size_t)r * cols;
        double acc = b[r];
        for (c = 0; c < cols; ++c) acc += (double)row[c] * (double)x[c];
        y[r] = (float)acc;
    }
}

static float clamp_abs(float x) {
    return x > MCD_MAX_ABS_VALUE ? MCD_MAX_ABS_VALUE : x < -MCD_MAX_ABS_VALUE ? -MCD_MAX_ABS_VALUE : x;
}

static mcd_quat ref_quat(const layout* L, uint32_t index) {
    const uint8_t* q = L->ref_table + 16u * index;
    mcd_quat r;
    r.x = mcd_rd_f32(q);
    r.y = mcd_rd_f32(q + 4);
    r.z = mcd_rd_f32(q + 8);
    r.w = mcd_rd_f32(q + 12);
    return r;
}

static void neural_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out, void* scratch,
                          int fresh) {
    layout L;
    window W;
    uint32_t* held = (uint32_t*)scratch;
    float *w, *feat, *h0, *h1, *y;
    const float *W0, *b0, *W1, *b1, *W2, *b2;
    double t;
    uint32_t i, k, index, max_weights, max_d, max_h;
    (void)flags;
    read_layout(v->payload, &L);
    if (fresh) held[0] = NO_WINDOW;
    index = find_window(&L, x, held[0]);
    read_window(v->payload, &L, index, &W);
    /* The buffers after the weights are placed for the largest window (the scratch's size). */
    max_weights = (uint32_t)held[1];
    max_d = (uint32_t)held[2];
    max_h = (uint32_t)held[3];
    if (held[0] == NO_WINDOW) {
        window o;
        max_weights = max_d = max_h = 0;
        for (i = 0; i < L.windows; ++i) {
            read_window(v->payload, &L, i, &o);
            if (o.weights > max_weights) max_weights = o.weights;
            if (o.d > max_d) max_d = o.d;
            if (o.h > max_h) max_h = o.h;
        }
        held[1] = max_weights;
        held[2] = max_d;
        held[3] = max_h;
    }
    w = (float*)((uint8_t*)scratch + 16);
    feat = w + max_weights;
    h0 = feat + max_d;
    h1 = h0 + max_h;
    y = h1 + max_h;
    if (held[0] != index) {
        expand_weights(&W, L.m, w);
        held[0] = index;
    }
    W0 = w;
    b0 = W0 + (size_t)W.h * W.d;
    W1 = b0 + W.h;
    b1 = W1 + (size_t)W.h * W.h;
    W2 = b1 + W.h;
    b2 = W2 + (size_t)L.m * W.h;

    /* Eq. 1 in double on the window's own time: pi k t reaches hundreds of radians, where a
     * float phase would cost more accuracy than the whole network keeps. */
    t = W.count > 1u ? ((double)x - (double)W.start) / (double)(W.count - 1u) : 0.0;
    feat[0] = (float)t;
    for (k = 0; k < W.k; ++k) {
        double phase = PI_D * (double)mcd_rd_u16(W.freqs + 2 * k) * t;
        feat[1 + 2 * k] = (float)sin(phase);
        feat[2 + 2 * k] = (float)cos(phase);
    }
    /* Eq. 2. */
    dense(W0, b0, feat, W.h, W.d, h0);
    for (i = 0; i < W.h; ++i) h0[i] = elu(h0[i]);
    dense(W1, b1, h0, W.h, W.h, h1);
    for (i = 0; i < W.h; ++i) h1[i] = elu(h1[i]);
    dense(W2, b2, h1, L.m, W.h, y);
    for (i = 0; i < L.m; ++i)
        y[i] = clamp_abs((float)((double)mcd_rd_f32(L.offset + 4 * i) + (double)mcd_rd_f32(L.scale + 4 * i) * (double)y[i]));

    for (i = 0; i < L.nodes; ++i) {
        const uint8_t* e = L.node_table + (size_t)i * NODE_ENTRY;
        const float* o = y + mcd_rd_u16(e + 2);
        mcd_quat q;
        mcd_skel_rest(v->skeleton, i, &out[i]);
        q = mcd_quat_of(&out[i]);
        if (e[0] == ROT_CONSTANT) {
            q = ref_quat(&L, mcd_rd_u16(e + 6));
        } else if (e[0] == ROT_QUATERNION) {
            float n2 = o[0] * o[0] + o[1] * o[1] + o[2] * o[2] + o[3] * o[3];
            if (n2 > 1e-30f) {
                float inv = 1.0f / sqrtf(n2);
                q.x = o[0] * inv;
                q.y = o[1] * inv;
                q.z = o[2] * inv;
                q.w = o[3] * inv;
            }
        } else if (e[0] == ROT_AXIS_ANGLE) {
            float a = sqrtf(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
            float s = a > 1e-12f ? sinf(0.5f * a) / a : 0.5f;
            mcd_quat r;
            r.x = o[0] * s;
            r.y = o[1] * s;
            r.z = o[2] * s;
            r.w = cosf(0.5f * a);
            q = mcd_qmul(ref_quat(&L, mcd_rd_u16(e + 6)), r);
        }
        out[i].rotation[0] = q.x;
        out[i].rotation[1] = q.y;
        out[i].rotation[2] = q.z;
        out[i].rotation[3] = q.w;
        if (e[1] == TRANS_OUTPUT) {
            const float* tr = y + mcd_rd_u16(e + 4);
            out[i].translation[0] = tr[0];
            out[i].translation[1] = tr[1];
            out[i].translation[2] = tr[2];
        }
    }
}

const mcd_codec_ops mcd_codec_neural_ops = {
    MCD_CODEC_NEURAL, 0x5255454Eu /* "NEUR" */, 2u, NULL, neural_validate, neural_scratch_size, neural_sample};
