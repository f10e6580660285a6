/* libFuzzer target: the spline codec's section spliced into a valid asset (fuzz/codec_section.h). */
#define FUZZ_CODEC MCD_CODEC_SPLINE
#include "codec_section.h"
