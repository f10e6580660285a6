/* Drive every entry point of the runtime over one asset of unknown origin: the body shared by
 * the corruption sweep, the fuzz-regression replay and the fuzz target, so all three hold the
 * runtime to the same promises. */
#ifndef MCD_TEST_EXERCISE_H
#define MCD_TEST_EXERCISE_H

#include <stddef.h>
#include <stdint.h>

#include "mocodec.h"

enum {
    MCD_EXERCISE_REJECTED = 0, /* validation refused the bytes (and mcd_open agreed) */
    MCD_EXERCISE_SAMPLED = 1,  /* accepted; every query and sample behaved */
    MCD_EXERCISE_BROKEN = -1   /* a promise was broken; `why` says which */
};

/* Validates `data` with `validate_flags` and opens it with the same flags (the two must agree).
 * If accepted, opens it again with MCD_OPEN_PREVALIDATED (it passed mcd_validate: the only case
 * the flag allows), calls every query on both opens, and samples up to `max_clips` clips at a
 * handful of times (inside, at both ends, before, after, between frames) with every flag
 * combination, each clip with the asset's scratch and with a scratch of exactly the size its
 * clip info states (malloc'd at that size: ASan sees a codec writing past its stated need).
 * Breaks when a sample fails, an output float is not finite or a quaternion is not unit, two
 * entry points or the two scratches disagree, or a scratch smaller than the clip's need is
 * not refused. */
int mcd_exercise(const void* data, size_t size, uint32_t validate_flags, uint32_t max_clips,
                 char* why, size_t why_size);

/* As mcd_exercise, sampling with 5 of the 16 flag combinations instead of all: every pair of
 * flags in each of its 4 on/off states (a strength-2 covering array). The corruption sweep
 * samples tens of thousands of assets under ASan; this halves its cost or better. */
int mcd_exercise_pairwise(const void* data, size_t size, uint32_t validate_flags, uint32_t max_clips,
                          char* why, size_t why_size);

#endif /* MCD_TEST_EXERCISE_H */
