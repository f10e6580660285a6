/* The codec table: the only place that lists the codecs this runtime decodes, one entry per
 * section version it reads; a codec's first entry is the version its encoder writes now. */
#include "internal.h"

static const mcd_codec_ops* const k_codecs[] = {
    &mcd_codec_spline_ops,   &mcd_codec_neural_ops,  &mcd_codec_rma_ops, &mcd_codec_rma_v3_ops, &mcd_codec_rma_v2_ops,
    &mcd_codec_ikpredict_ops, &mcd_codec_rmapca_ops, &mcd_codec_fkwavelet_ops,
};

#define CODEC_ENTRIES (sizeof k_codecs / sizeof k_codecs[0])

const mcd_codec_ops* mcd_find_codec(uint32_t codec) {
    size_t i;
    for (i = 0; i < CODEC_ENTRIES; ++i)
        if (k_codecs[i]->codec == codec) return k_codecs[i];
    return NULL;
}

const mcd_codec_ops* mcd_find_codec_version(uint32_t codec, uint32_t section_version) {
    size_t i;
    for (i = 0; i < CODEC_ENTRIES; ++i)
        if (k_codecs[i]->codec == codec && k_codecs[i]->section_version == section_version) return k_codecs[i];
    return NULL;
}

const mcd_codec_ops* mcd_find_codec_by_kind(uint32_t section_kind) {
    size_t i;
    for (i = 0; i < CODEC_ENTRIES; ++i)
        if (k_codecs[i]->section_kind == section_kind) return k_codecs[i];
    return NULL;
}
