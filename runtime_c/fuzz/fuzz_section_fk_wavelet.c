/* libFuzzer target: the fk-wavelet codec's section spliced into a valid asset (fuzz/codec_section.h). */
#define FUZZ_CODEC MCD_CODEC_FK_WAVELET
#include "codec_section.h"
