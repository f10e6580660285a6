/* libFuzzer target: the rma-pca codec's section spliced into a valid asset (fuzz/codec_section.h). */
#define FUZZ_CODEC MCD_CODEC_RMA_PCA
#include "codec_section.h"
