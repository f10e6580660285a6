/* libFuzzer target: the ik-predict codec's section spliced into a valid asset (fuzz/codec_section.h). */
#define FUZZ_CODEC MCD_CODEC_IK_PREDICT
#include "codec_section.h"
