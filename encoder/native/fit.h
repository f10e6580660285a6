/* The encoder's compiled fitting helpers (cffi module mocodec._native, built with the encoder).
 * Offline code: it allocates, and it is never part of the runtime an engine links. */
#ifndef MOCODEC_FIT_H
#define MOCODEC_FIT_H

#include <stdint.h>

/* Error kinds of a curve (keyframes.KIND_*): the angle between target rotations and the
 * rotations an MRP or twist + MRP curve decodes to, or the distance of a translation or
 * scale curve from its target. */
#define MCF_KIND_MRP 1
#define MCF_KIND_TWIST 2
#define MCF_KIND_TRANSLATION 3
#define MCF_KIND_SCALE 4

/* One curve to key (curves.fit_keys): every array C-contiguous float64. */
typedef struct {
    int32_t kind;
    int32_t dims;               /* values per frame: 3, or 4 for a twist (angle + MRP) */
    int64_t frames;
    const double* deq;          /* (frames, dims) each frame's value as the decoder sees it */
    const double* target;       /* (frames, 4) rotations or (frames, 3) translations / scales */
    const double* ref;          /* (4,) reference rotation x y z w */
    const double* axis;         /* (3,) twist axis */
    const double* budget;       /* (frames,) allowed error per frame */
    const double* half_target;  /* (frames - 1, 4 | 3) target half-way between frames, or NULL */
    const double* half_budget;  /* (frames - 1,) allowed error there (inf: not held) */
    int32_t grid;               /* key cells of this many frames (1: every frame a cell) */
    int32_t split;              /* the first segment is detached */
} mcf_curve;

/* Place keys until the curve is within budget on every frame (and half-way sample), then
 * drop the keys it can do without. ``keys`` (capacity frames) holds ``n_keys`` sorted start
 * keys on entry (mandatory ones included) and the result on return; ``mandatory`` (frames)
 * marks keys that stay. Returns 1 when every sample is within budget, 0 when samples over it
 * are all at keys (or between two adjacent keys), -1 on a bad argument or no memory. */
int32_t mcf_fit_keys(const mcf_curve* curve, int64_t* keys, int64_t* n_keys, const uint8_t* mandatory);

/* The curve through ``keys`` (each key's value is its frame's row of ``deq``) on every
 * frame: ``values`` (frames, dims), and its error per frame ``error`` (frames,) and per
 * half-way sample ``half_error`` (frames - 1,) when not NULL. */
int32_t mcf_evaluate(const mcf_curve* curve, const int64_t* keys, int64_t n_keys, double* values,
                     double* error, double* half_error);

/* Per frame, the rotation that best re-aims a node (keyframes.Compensation): the rotation
 * Q minimising sum_k w_k |Q v_k - u_k|^2 over ``count`` point pairs (v, u), (frames, count, 3)
 * each, as a unit quaternion on the hemisphere of ``hint`` (frames, 4). Davenport's
 * q-method: the principal eigenvector of a 4x4 symmetric matrix, by Jacobi rotations. */
int32_t mcf_wahba(int64_t frames, int32_t count, const double* v, const double* u, const double* w,
                  const double* hint, double* out);

/* Pack ``n`` fields (``widths`` 0 ... 32 bits, ``values`` within them) back to back, least
 * significant bit first, into ``words`` (zeroed, at least total / 64 + 2 of them). Returns the
 * bit length, or -1 when a width is out of range. */
int64_t mcf_pack_fields(const uint64_t* values, const int64_t* widths, int64_t n, uint64_t* words);

#endif
