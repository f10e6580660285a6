/* Fields packed back to back, least significant bit first (mocodec.bitpack.pack_fields). */
#include "fit.h"

int64_t mcf_pack_fields(const uint64_t* values, const int64_t* widths, int64_t n, uint64_t* words) {
    int64_t i, bit = 0;
    for (i = 0; i < n; ++i)
        if (widths[i] < 0 || widths[i] > 32) return -1;
    for (i = 0; i < n; ++i) {
        const int64_t w = widths[i];
        const uint64_t v = values[i];
        const int64_t word = bit >> 6;
        const int shift = (int)(bit & 63);
        if (w == 0) continue;
        words[word] |= v << shift;
        if (shift + w > 64) words[word + 1] |= v >> (64 - shift);
        bit += w;
    }
    return bit;
}
