/* Curve and rotation helpers shared by the key-frame codecs (`spline`, `rma`): both store
 * tracks as Catmull-Rom keys of the same kinds (docs/FORMAT.md, SPLN "Curve"). */
#include <math.h>

#include "internal.h"

int mcd_unit_quat_at(const uint8_t* p) {
    float x = mcd_rd_f32(p), y = mcd_rd_f32(p + 4), z = mcd_rd_f32(p + 8), w = mcd_rd_f32(p + 12);
    float n;
    if (!mcd_finite(x) || !mcd_finite(y) || !mcd_finite(z) || !mcd_finite(w)) return 0;
    n = x * x + y * y + z * z + w * w;
    return n > 1.0f - 2e-5f && n < 1.0f + 2e-5f;
}

mcd_quat mcd_reference_at(const uint8_t* p) {
    float r[3];
    uint32_t k;
    for (k = 0; k < 3; ++k) r[k] = (float)(int16_t)mcd_rd_u16(p + 2 * k) / 32767.0f;
    return mcd_mrp_to_quat(r);
}

void mcd_axis_at(const uint8_t* p, float axis[3]) {
    float n2 = 0.0f, inv;
    uint32_t k;
    for (k = 0; k < 3; ++k) {
        axis[k] = (float)(int16_t)mcd_rd_u16(p + 2 * k) / 32767.0f;
        n2 += axis[k] * axis[k];
    }
    inv = 1.0f / sqrtf(n2);
    for (k = 0; k < 3; ++k) axis[k] *= inv;
}

/* The Hermite segment with finite-difference tangents, expanded in powers of s. */
float mcd_segment_coefficients(const float t[4], const float v[4][4], uint32_t dims, float coef[4][4]) {
    float h = t[2] - t[1], a = h / (t[2] - t[0]), b = h / (t[3] - t[1]);
    uint32_t c;
    for (c = 0; c < dims; ++c) {
        float p1 = v[1][c], p2 = v[2][c];
        float m1 = a * (p2 - v[0][c]), m2 = b * (v[3][c] - p1);
        coef[c][0] = p1;
        coef[c][1] = m1;
        coef[c][2] = 3.0f * (p2 - p1) - 2.0f * m1 - m2;
        coef[c][3] = 2.0f * (p1 - p2) + m1 + m2;
    }
    return 1.0f / h;
}
