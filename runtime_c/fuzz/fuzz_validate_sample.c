/* libFuzzer target: validate any bytes, and when they pass, open them (validating, and with
 * MCD_OPEN_PREVALIDATED, which only bytes that passed mcd_validate may use), query them and
 * sample every clip at a few times with every flag (local, world, loop, nearest, contacts),
 * on the asset's scratch and on one of exactly the clip's stated size.
 *
 * The checksum is skipped so that mutations reach the structural checks instead of stopping at
 * the CRC. Everything after validation is tests/exercise.c, the same body the C tests run on
 * corrupted assets: a sample that fails, a non-finite or non-unit output, entry points or
 * scratches that disagree abort, and ASan/UBSan catch the memory and arithmetic errors (a
 * codec writing past the scratch its clip states included). Seeds: the format-2 goldens of
 * every codec (tests/golden/v2) and the past finds in fuzz/regressions.
 *
 *     make fuzz FUZZ_SECONDS=120          (runtime_c/Makefile)
 */
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "exercise.h"
#include "mocodec.h"

/* An asset may hold 65535 clips; sampling 8 of them (every clip of the seeds) finds the same bugs
 * at a fraction of the cost. */
#define MAX_CLIPS 8u

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
    char why[256];
    if (mcd_exercise(data, size, MCD_VALIDATE_SKIP_CHECKSUM, MAX_CLIPS, why, sizeof why) == MCD_EXERCISE_BROKEN) {
        fprintf(stderr, "mocodec promise broken: %s\n", why);
        abort();
    }
    return 0;
}
