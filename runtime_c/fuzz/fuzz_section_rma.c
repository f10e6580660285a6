/* libFuzzer target: the rma codec's section spliced into a valid asset (fuzz/codec_section.h). */
#define FUZZ_CODEC MCD_CODEC_RMA
#include "codec_section.h"
