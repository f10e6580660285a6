/* Codec `neural`: a clip as a Fourier-feature MLP from time to pose (seed 001; docs/FORMAT.md,
 * NEUR).
 *
 * A sample evaluates eq. 2 once: K sin/cos pairs, then (2K+1)·H + H·H + H·M multiply-adds and
 * 2H expm1f. The quantized weights are expanded into the scratch when the clip changes
 * (`fresh`), so a sample reads only floats. Validation bounds every weight, scale and offset,
 * and the outputs are clamped, so any accepted payload samples to finite transforms. */
#include <math.h>
#include <string.h>

#include "internal.h"

#define HEADER 44u
#define NODE_ENTRY 8u
#define MAX_K 32u
#define MAX_H (2u * (2u * MAX_K + 1u))
#define MAX_WEIGHT 1e4f
#define PI_D 3.14159265358979323846

enum { ROT_IDENTITY = 0, ROT_CONSTANT = 1, ROT_QUATERNION = 2, ROT_AXIS_ANGLE = 3 };
enum { TRANS_REST = 0, TRANS_OUTPUT = 2 };

typedef struct layout {
    uint32_t frames, nodes, k, h, m, refs, bits, d, weights;
    const uint8_t *steps, *node_table, *freqs, *ref_table, *scale, *offset, *stream;
} layout;

static size_t align4z(size_t x) {
    return (x + 3u) & ~(size_t)3u;
}

static size_t align16z(size_t x) {
    return (x + 15u) & ~(size_t)15u;
}

/* Bytes before the weight stream; only meaningful for counts within the format's limits. */
static size_t head_bytes(uint32_t nodes, uint32_t k, uint32_t m, uint32_t refs) {
    return HEADER + (size_t)nodes * NODE_ENTRY + align4z(2u * (size_t)k) + 16u * (size_t)refs + 8u * (size_t)m;
}

static void read_layout(const uint8_t* p, layout* L) {
    L->frames = mcd_rd_u32(p);
    L->nodes = mcd_rd_u32(p + 4);
    L->k = mcd_rd_u16(p + 8);
    L->h = mcd_rd_u16(p + 10);
    L->m = mcd_rd_u16(p + 12);
    L->refs = mcd_rd_u16(p + 14);
    L->bits = p[16];
    L->d = 2u * L->k + 1u;
    L->weights = L->h * L->d + L->h + L->h * L->h + L->h + L->m * L->h + L->m;
    L->steps = p + 20;
    L->node_table = p + HEADER;
    L->freqs = L->node_table + (size_t)L->nodes * NODE_ENTRY;
    L->ref_table = L->freqs + align4z(2u * (size_t)L->k);
    L->scale = L->ref_table + 16u * (size_t)L->refs;
    L->offset = L->scale + 4u * (size_t)L->m;
    L->stream = L->offset + 4u * (size_t)L->m;
}

static int bounded(float v, float limit) {
    return mcd_finite(v) && v <= limit && v >= -limit;
}

/* ---------------------------------------------------------------- validation */
static mcd_result neural_validate(const mcd_clip_view* v) {
    const uint8_t* p = v->payload;
    layout L;
    uint64_t stream_bits, stream_bytes, pos;
    uint32_t i, c;
    if (v->payload_size < HEADER) return MCD_ERROR_MALFORMED;
    /* Counts first: nothing below forms a pointer from a count that was not checked. */
    if (mcd_rd_u32(p) != v->frame_count || mcd_rd_u32(p + 4) != v->node_count) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u16(p + 8) > MAX_K || mcd_rd_u16(p + 10) == 0 || mcd_rd_u16(p + 10) > MAX_H) return MCD_ERROR_MALFORMED;
    if (mcd_rd_u16(p + 12) > 7u * v->node_count || mcd_rd_u16(p + 14) > v->node_count) return MCD_ERROR_MALFORMED;
    if (p[16] < 2u || p[16] > 16u || p[17] || p[18] || p[19]) return MCD_ERROR_MALFORMED;
    read_layout(p, &L);
    stream_bits = (uint64_t)L.weights * L.bits;
    stream_bytes = align4z((size_t)((stream_bits + 7u) / 8u));
    if ((uint64_t)head_bytes(L.nodes, L.k, L.m, L.refs) + stream_bytes != v->payload_size) return MCD_ERROR_MALFORMED;

    for (i = 0; i < 6; ++i) {
        float s = mcd_rd_f32(L.steps + 4 * i);
        /* |code| <= 2^(bits-1): every dequantized weight stays within MAX_WEIGHT. */
        if (!mcd_finite(s) || !(s > 0.0f) || s * (float)(1u << (L.bits - 1u)) > MAX_WEIGHT) return MCD_ERROR_MALFORMED;
    }
    for (i = 0; i < L.k; ++i)
        if (mcd_rd_u16(L.freqs + 2 * i) == 0) return MCD_ERROR_MALFORMED;
    if ((L.k & 1u) && mcd_rd_u16(L.freqs + 2 * L.k) != 0) return MCD_ERROR_MALFORMED;
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
    /* Unused bits of the stream's last byte and the padding after it are zero. */
    pos = stream_bits;
    if ((pos & 7u) && (L.stream[pos >> 3] >> (pos & 7u)) != 0) return MCD_ERROR_MALFORMED;
    for (pos = (stream_bits + 7u) / 8u; pos < stream_bytes; ++pos)
        if (L.stream[pos] != 0) return MCD_ERROR_MALFORMED;
    return MCD_OK;
}

/* ---------------------------------------------------------------- scratch */
/* Layout: u32 header[4] | f32 weights[P] | f32 features[D] | f32 hidden0[H] | f32 hidden1[H] | f32 out[M] */
static size_t neural_scratch_size(const mcd_clip_view* v) {
    layout L;
    read_layout(v->payload, &L);
    return align16z(16u + 4u * ((size_t)L.weights + L.d + 2u * (size_t)L.h + L.m));
}

/* Expand the bit-packed codes into floats: code - 2^(bits-1), times its tensor's step. */
static void expand_weights(const layout* L, float* w) {
    uint32_t counts[6], t, i, n = 0, have = 0;
    uint32_t mask = (1u << L->bits) - 1u, bias = 1u << (L->bits - 1u);
    uint64_t acc = 0;
    const uint8_t* s = L->stream;
    counts[0] = L->h * L->d;
    counts[1] = L->h;
    counts[2] = L->h * L->h;
    counts[3] = L->h;
    counts[4] = L->m * L->h;
    counts[5] = L->m;
    for (t = 0; t < 6; ++t) {
        float step = mcd_rd_f32(L->steps + 4 * t);
        for (i = 0; i < counts[t]; ++i) {
            uint32_t u;
            /* Validation sized the stream for every code, so these byte loads stay inside it. */
            while (have < L->bits) {
                acc |= (uint64_t)*s++ << have;
                have += 8u;
            }
            u = (uint32_t)acc & mask;
            acc >>= L->bits;
            have -= L->bits;
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

static mcd_result neural_sample(const mcd_clip_view* v, float x, uint32_t flags, mcd_transform* out,
                                void* scratch, int fresh) {
    layout L;
    float *w, *feat, *h0, *h1, *y;
    const float *W0, *b0, *W1, *b1, *W2, *b2;
    double t;
    uint32_t i, k;
    (void)flags;
    read_layout(v->payload, &L);
    w = (float*)((uint8_t*)scratch + 16);
    feat = w + L.weights;
    h0 = feat + L.d;
    h1 = h0 + L.h;
    y = h1 + L.h;
    if (fresh) expand_weights(&L, w);
    W0 = w;
    b0 = W0 + (size_t)L.h * L.d;
    W1 = b0 + L.h;
    b1 = W1 + (size_t)L.h * L.h;
    W2 = b1 + L.h;
    b2 = W2 + (size_t)L.m * L.h;

    /* Eq. 1 in double: pi k t reaches hundreds of radians, where a float phase would cost
     * more accuracy than the whole network keeps. */
    t = L.frames > 1u ? (double)x / (double)(L.frames - 1u) : 0.0;
    feat[0] = (float)t;
    for (k = 0; k < L.k; ++k) {
        double phase = PI_D * (double)mcd_rd_u16(L.freqs + 2 * k) * t;
        feat[1 + 2 * k] = (float)sin(phase);
        feat[2 + 2 * k] = (float)cos(phase);
    }
    /* Eq. 2. */
    dense(W0, b0, feat, L.h, L.d, h0);
    for (i = 0; i < L.h; ++i) h0[i] = elu(h0[i]);
    dense(W1, b1, h0, L.h, L.h, h1);
    for (i = 0; i < L.h; ++i) h1[i] = elu(h1[i]);
    dense(W2, b2, h1, L.m, L.h, y);
    for (i = 0; i < L.m; ++i)
        y[i] = clamp_abs((float)((double)mcd_rd_f32(L.offset + 4 * i) + (double)mcd_rd_f32(L.scale + 4 * i) * (double)y[i]));

    for (i = 0; i < L.nodes; ++i) {
        const uint8_t* e = L.node_table + (size_t)i * NODE_ENTRY;
        const uint8_t* rec = v->skeleton + 16 + (size_t)i * MCD_SKEL_NODE_SIZE;
        const float* o = y + mcd_rd_u16(e + 2);
        mcd_quat q;
        q.x = q.y = q.z = 0.0f;
        q.w = 1.0f;
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
        } else {
            out[i].translation[0] = mcd_rd_f32(rec + 8);
            out[i].translation[1] = mcd_rd_f32(rec + 12);
            out[i].translation[2] = mcd_rd_f32(rec + 16);
        }
    }
    return MCD_OK;
}

const mcd_codec_ops mcd_codec_neural_ops = {
    MCD_CODEC_NEURAL, 0x5255454Eu /* "NEUR" */, neural_validate, NULL, NULL, neural_scratch_size,
    neural_sample};
