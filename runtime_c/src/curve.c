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
