/* Adaptive key placement for one Catmull-Rom curve: mocodec.curves.fit_keys compiled.
 *
 * The same algorithm, step for step and in the same float64 arithmetic (built without
 * floating-point contraction), as the numpy reference in curves.py: insert into every failing
 * key interval its worst candidate frame until every sample is within budget, then try
 * dropping every fourth key at a time. What is compiled away is the cost: after an insertion
 * only the frames whose curve segment changed are evaluated again, and a removal is judged on
 * its own region, stopping at the first sample over budget. */
#include "fit.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    const mcf_curve* c;
    const int64_t* kf; /* key frames, sorted */
    int64_t k;
} keyset;

/* Index of the segment a position x falls in: searchsorted(kf, x, "right") - 1, clipped to
 * 0 ... k - 2 (curves.catmull_rom). */
static int64_t segment_of(const keyset* s, double x) {
    int64_t lo = 0, hi = s->k; /* first index with kf > x */
    while (lo < hi) {
        int64_t mid = lo + (hi - lo) / 2;
        if ((double)s->kf[mid] > x) hi = mid; else lo = mid + 1;
    }
    lo -= 1;
    if (lo > s->k - 2) lo = s->k - 2;
    if (lo < 0) lo = 0;
    return lo;
}

/* The curve at x in segment i1, written to out (dims values). */
static void curve_at(const keyset* s, int64_t i1, double x, double* out) {
    const mcf_curve* c = s->c;
    const int d = c->dims;
    int64_t i0, i2, i3;
    double t0, t1, t2, t3, h, u, u2, u3, h00, h10, h01, h11, a, b;
    const double *p0, *p1, *p2, *p3;
    int j;
    if (s->k == 1) {
        memcpy(out, c->deq + s->kf[0] * d, sizeof(double) * (size_t)d);
        return;
    }
    i0 = i1 > 0 ? i1 - 1 : 0;
    i2 = i1 + 1;
    i3 = i1 + 2 < s->k - 1 ? i1 + 2 : s->k - 1;
    if (c->split) {
        if (i1 <= 1) i0 = i1;
        if (i1 == 0) i3 = i2;
    }
    t0 = (double)s->kf[i0]; t1 = (double)s->kf[i1]; t2 = (double)s->kf[i2]; t3 = (double)s->kf[i3];
    p0 = c->deq + s->kf[i0] * d; p1 = c->deq + s->kf[i1] * d;
    p2 = c->deq + s->kf[i2] * d; p3 = c->deq + s->kf[i3] * d;
    h = t2 - t1;
    u = (x - t1) / h;
    u2 = u * u;
    u3 = u2 * u;
    h00 = 2.0 * u3 - 3.0 * u2 + 1.0;
    h10 = u3 - 2.0 * u2 + u;
    h01 = -2.0 * u3 + 3.0 * u2;
    h11 = u3 - u2;
    a = h10 * h / (t2 - t0);
    b = h11 * h / (t3 - t1);
    for (j = 0; j < d; ++j)
        out[j] = h00 * p1[j] + h01 * p2[j] + a * (p2[j] - p0[j]) + b * (p3[j] - p1[j]);
}

/* Hamilton product a * b, in rotations.quat_multiply's order of operations. */
static void qmul(const double* a, const double* b, double* o) {
    const double ax = a[0], ay = a[1], az = a[2], aw = a[3];
    const double bx = b[0], by = b[1], bz = b[2], bw = b[3];
    o[0] = aw * bx + ax * bw + ay * bz - az * by;
    o[1] = aw * by - ax * bz + ay * bw + az * bx;
    o[2] = aw * bz + ax * by - ay * bx + az * bw;
    o[3] = aw * bw - ax * bx - ay * by - az * bz;
}

static void quat_from_mrp(const double* p, double* q) {
    const double s = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    const double d = 1.0 + s;
    q[0] = 2.0 * p[0] / d;
    q[1] = 2.0 * p[1] / d;
    q[2] = 2.0 * p[2] / d;
    q[3] = (1.0 - s) / d;
}

/* Error of one sample: rotations.quat_angle(target, decoded) or the translation distance. */
static double sample_error(const mcf_curve* c, const double* v, const double* t) {
    double m[4], r[4], rot[4], rel[4], conj[4];
    if (c->kind == MCF_KIND_TRANSLATION || c->kind == MCF_KIND_SCALE) {
        const double dx = v[0] - t[0], dy = v[1] - t[1], dz = v[2] - t[2];
        return sqrt(dx * dx + dy * dy + dz * dz);
    }
    if (c->kind == MCF_KIND_MRP) {
        quat_from_mrp(v, m);
        qmul(c->ref, m, rot);
    } else {
        const double half = 0.5 * v[0];
        const double sh = sin(half);
        double tw[4];
        tw[0] = c->axis[0] * sh; tw[1] = c->axis[1] * sh; tw[2] = c->axis[2] * sh; tw[3] = cos(half);
        quat_from_mrp(v + 1, m);
        qmul(c->ref, m, r);
        qmul(tw, r, rot);
    }
    conj[0] = -t[0]; conj[1] = -t[1]; conj[2] = -t[2]; conj[3] = t[3];
    qmul(conj, rot, rel);
    return 2.0 * atan2(sqrt(rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]), fabs(rel[3]));
}

static int target_dims(const mcf_curve* c) {
    return c->kind == MCF_KIND_TRANSLATION || c->kind == MCF_KIND_SCALE ? 3 : 4;
}

/* Error of frame f, and of the half-way sample f + 1/2 into *half when half is not NULL. */
static double errors_at(const keyset* s, int64_t f, double* half) {
    const mcf_curve* c = s->c;
    const int td = target_dims(c);
    double v[4];
    curve_at(s, segment_of(s, (double)f), (double)f, v);
    if (half) {
        const double x = (double)f + 0.5;
        double w[4];
        curve_at(s, segment_of(s, x), x, w);
        *half = sample_error(c, w, c->half_target + f * td);
    }
    return sample_error(c, v, c->target + f * td);
}

/* Whether half-way sample f is held: a finite budget (most are infinite where the hold is
 * lazy, and are not evaluated at all). */
static int half_held(const mcf_curve* c, int64_t f) {
    return c->half_target && !isinf(c->half_budget[f]);
}

/* Errors of frames lo ... hi, and of the half-way samples lo ... hi - 1 when herr is not NULL
 * (0 where not held). */
static void evaluate_range(const keyset* s, int64_t lo, int64_t hi, double* err, double* herr) {
    int64_t f;
    for (f = lo; f <= hi; ++f) {
        const int with_half = herr && f < hi && half_held(s->c, f);
        if (herr && f < hi && !with_half) herr[f] = 0.0;
        err[f] = errors_at(s, f, with_half ? herr + f : NULL);
    }
}

/* True when some frame lo ... hi or half-way sample lo ... hi - 1 is over budget. */
static int region_fails(const keyset* s, int64_t lo, int64_t hi) {
    const mcf_curve* c = s->c;
    int64_t f;
    for (f = lo; f <= hi; ++f) {
        double half = 0.0;
        const int with_half = f < hi && half_held(c, f);
        if (errors_at(s, f, with_half ? &half : NULL) > c->budget[f]) return 1;
        if (with_half && half > c->half_budget[f]) return 1;
    }
    return 0;
}

/* Key cell of frame f of F (curves.fit_keys_reference): frame 0 and, from three frames on,
 * the last frame have cells of their own; frames 1 ... F - 2 are in cells of grid frames. */
static int64_t cell_of(int64_t f, int32_t grid, int64_t F) {
    if (f == 0) return 0;
    if (F > 2 && f == F - 1) return (F - 3) / grid + 2;
    return (f - 1) / grid + 1;
}

/* Drop keys the curve can do without (curves._remove_keys): every fourth key at a time, a
 * removal kept when no sample of its region (keys i - 2 ... i + 2) goes over budget. */
static int remove_keys(const mcf_curve* c, int64_t* kf, int64_t* k, const uint8_t* mandatory,
                       int64_t* kept, uint8_t* drop) {
    int changed = 1;
    while (changed) {
        int r;
        changed = 0;
        for (r = 0; r < 4; ++r) {
            int64_t i, n = 0, any = 0;
            keyset s;
            for (i = 0; i < *k; ++i) {
                drop[i] = (uint8_t)(i % 4 == r && !mandatory[kf[i]]);
                any |= drop[i];
                if (!drop[i]) kept[n++] = kf[i];
            }
            if (!any) continue;
            s.c = c; s.kf = kept; s.k = n;
            any = 0;
            for (i = 0; i < *k; ++i) {
                int64_t lo, hi;
                if (!drop[i]) continue;
                lo = kf[i >= 2 ? i - 2 : 0];
                hi = kf[i + 2 < *k ? i + 2 : *k - 1];
                if (region_fails(&s, lo, hi)) drop[i] = 0; else any = 1;
            }
            if (!any) continue;
            n = 0;
            for (i = 0; i < *k; ++i)
                if (!drop[i]) kf[n++] = kf[i];
            *k = n;
            changed = 1;
        }
    }
    return 0;
}

int32_t mcf_fit_keys(const mcf_curve* c, int64_t* keys, int64_t* n_keys, const uint8_t* mandatory) {
    const int64_t F = c ? c->frames : 0;
    const int64_t H = (c && c->half_target) ? F - 1 : 0;
    const int32_t grid = c ? c->grid : 0;
    int64_t k, ncells, f, i;
    double *err = NULL, *ratio = NULL, *herr = NULL, *hratio = NULL, *rank = NULL;
    uint8_t *is_key = NULL, *taken = NULL, *bad = NULL, *frame_bad = NULL;
    int64_t *chosen = NULL, *merged = NULL;
    int32_t status = -1;
    keyset s;

    if (!c || !keys || !n_keys || !mandatory || F < 1 || *n_keys < 1 || *n_keys > F || grid < 1 ||
        (c->dims != 3 && c->dims != 4))
        return -1;
    k = *n_keys;
    ncells = cell_of(F - 1, grid, F) + 1;
    err = malloc(sizeof(double) * (size_t)F);
    ratio = malloc(sizeof(double) * (size_t)F);
    rank = malloc(sizeof(double) * (size_t)F);
    herr = malloc(sizeof(double) * (size_t)(H + 1));
    hratio = malloc(sizeof(double) * (size_t)(H + 1));
    is_key = calloc((size_t)F, 1);
    frame_bad = calloc((size_t)F, 1);
    bad = calloc((size_t)F, 1);
    taken = calloc((size_t)ncells, 1);
    chosen = malloc(sizeof(int64_t) * (size_t)F);
    merged = malloc(sizeof(int64_t) * (size_t)F);
    if (!err || !ratio || !rank || !herr || !hratio || !is_key || !frame_bad || !bad || !taken || !chosen || !merged)
        goto done;

    s.c = c; s.kf = keys; s.k = k;
    evaluate_range(&s, 0, F - 1, err, H ? herr : NULL);
    for (f = 0; f < F; ++f) ratio[f] = err[f] / c->budget[f];
    for (f = 0; f < H; ++f) hratio[f] = herr[f] / c->half_budget[f];

    for (;;) {
        int64_t n_chosen = 0, any_bad = 0, any_frame_bad = 0, n, a, b, added;
        memset(is_key, 0, (size_t)F);
        memset(taken, 0, (size_t)ncells);
        for (i = 0; i < k; ++i) {
            is_key[keys[i]] = 1;
            taken[cell_of(keys[i], grid, F)] = 1;
        }
        /* A frame is bad when it, or a half-way sample next to it, is over budget; a half-way
         * sample between two keys flags the frames beyond them too (their keys shape it). */
        for (f = 0; f < F; ++f) {
            frame_bad[f] = (uint8_t)(ratio[f] > 1.0);
            bad[f] = frame_bad[f];
            rank[f] = ratio[f];
            any_frame_bad |= frame_bad[f];
        }
        for (f = 0; f < H; ++f) {
            if (!(hratio[f] > 1.0)) continue;
            bad[f] = bad[f + 1] = 1;
            if (hratio[f] > rank[f]) rank[f] = hratio[f];
            if (hratio[f] > rank[f + 1]) rank[f + 1] = hratio[f];
            if (is_key[f] && is_key[f + 1]) {
                if (f >= 1 && !is_key[f - 1]) {
                    bad[f - 1] = 1;
                    if (hratio[f] > rank[f - 1]) rank[f - 1] = hratio[f];
                }
                if (f + 2 < F && !is_key[f + 2]) {
                    bad[f + 2] = 1;
                    if (hratio[f] > rank[f + 2]) rank[f + 2] = hratio[f];
                }
            }
        }
        for (f = 0; f < F; ++f) any_bad |= bad[f];
        if (!any_bad) {
            status = 1;
            break;
        }
        /* The worst candidate of each failing interval (curves.fit_keys' rules). */
        for (i = 0; i < k; ++i) {
            const int64_t lo = keys[i], hi = i + 1 < k ? keys[i + 1] - 1 : F - 1;
            int64_t best = -1, pass;
            int has_bad = 0;
            for (f = lo; f <= hi; ++f) has_bad |= bad[f];
            if (!has_bad) continue;
            /* grid > 1: free cell starts, else bad frames in free cells, else bad non-keys;
             * grid == 1: bad non-keys (every frame is a cell). */
            for (pass = grid > 1 ? 0 : 2; pass < 3 && best < 0; ++pass) {
                for (f = lo; f <= hi; ++f) {
                    int ok;
                    if (pass == 0) ok = f >= 1 && (f - 1) % grid == 0 && !taken[cell_of(f, grid, F)];
                    else if (pass == 1) ok = bad[f] && !taken[cell_of(f, grid, F)];
                    else ok = bad[f] && !is_key[f];
                    if (ok && (best < 0 || rank[f] > rank[best])) best = f;
                }
            }
            if (best >= 0) {
                /* Two intervals may pick frames of one cell (a cell straddling a key): keep one. */
                if (n_chosen > 0 && cell_of(chosen[n_chosen - 1], grid, F) == cell_of(best, grid, F)) continue;
                chosen[n_chosen++] = best;
            }
        }
        if (n_chosen == 0) {
            status = any_frame_bad ? 0 : 2;
            break;
        }
        /* Merge the new keys in, then evaluate again the frames whose segment changed: those
         * between keys j - 2 and j + 2 around each new key j. */
        a = b = n = 0;
        while (a < k || b < n_chosen) {
            if (b >= n_chosen || (a < k && keys[a] < chosen[b])) merged[n++] = keys[a++];
            else merged[n++] = chosen[b++];
        }
        memcpy(keys, merged, sizeof(int64_t) * (size_t)n);
        k = n;
        s.k = k;
        added = 0;
        {
            int64_t lo_dirty = -1, hi_dirty = -1;
            for (i = 0; i < k; ++i) {
                int64_t lo, hi;
                if (added < n_chosen && keys[i] == chosen[added]) {
                    ++added;
                    lo = keys[i >= 2 ? i - 2 : 0];
                    hi = keys[i + 2 < k ? i + 2 : k - 1];
                    if (lo_dirty >= 0 && lo <= hi_dirty) {
                        if (hi > hi_dirty) hi_dirty = hi;
                        continue;
                    }
                    if (lo_dirty >= 0) {
                        evaluate_range(&s, lo_dirty, hi_dirty, err, H ? herr : NULL);
                        for (f = lo_dirty; f <= hi_dirty; ++f) ratio[f] = err[f] / c->budget[f];
                        for (f = lo_dirty; f < hi_dirty && f < H; ++f) hratio[f] = herr[f] / c->half_budget[f];
                    }
                    lo_dirty = lo;
                    hi_dirty = hi;
                }
            }
            if (lo_dirty >= 0) {
                evaluate_range(&s, lo_dirty, hi_dirty, err, H ? herr : NULL);
                for (f = lo_dirty; f <= hi_dirty; ++f) ratio[f] = err[f] / c->budget[f];
                for (f = lo_dirty; f < hi_dirty && f < H; ++f) hratio[f] = herr[f] / c->half_budget[f];
            }
        }
    }
    if (status >= 1) remove_keys(c, keys, &k, mandatory, merged, bad);
    *n_keys = k;
done:
    free(err); free(ratio); free(rank); free(herr); free(hratio); free(is_key); free(frame_bad);
    free(bad); free(taken); free(chosen); free(merged);
    return status;
}

int32_t mcf_evaluate(const mcf_curve* c, const int64_t* keys, int64_t n_keys, double* values,
                     double* error, double* half_error) {
    keyset s;
    const int td = c ? target_dims(c) : 0;
    double v[4];
    int64_t f;
    if (!c || !keys || n_keys < 1 || c->frames < 1 || (c->dims != 3 && c->dims != 4)) return -1;
    s.c = c; s.kf = keys; s.k = n_keys;
    for (f = 0; f < c->frames; ++f) {
        curve_at(&s, segment_of(&s, (double)f), (double)f, v);
        if (values) memcpy(values + f * c->dims, v, sizeof(double) * (size_t)c->dims);
        if (error) error[f] = sample_error(c, v, c->target + f * td);
        if (half_error && c->half_target && f + 1 < c->frames) {
            const double x = (double)f + 0.5;
            curve_at(&s, segment_of(&s, x), x, v);
            half_error[f] = sample_error(c, v, c->half_target + f * td);
        }
    }
    return 0;
}
