/* libFuzzer target: the neural codec's section spliced into a valid asset (fuzz/codec_section.h). */
#define FUZZ_CODEC MCD_CODEC_NEURAL
#include "codec_section.h"
