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

/* mcd_resident_size, then mcd_open with resident memory of that size (16-byte aligned,
 * malloc'd into *resident, NULL when the asset needs none; the caller frees it). */
mcd_result mcd_exercise_open(const void* data, size_t size, uint32_t flags, mcd_asset* out, void** resident);

/* Validates `data` with `validate_flags`; if accepted, opens it, calls every query and samples
 * up to `max_clips` clips at a handful of times (inside, at both ends, before, after, between
 * frames) with every flag combination. Breaks when a sample fails, an output float is not
 * finite or a quaternion is not unit, or two entry points disagree. */
int mcd_exercise(const void* data, size_t size, uint32_t validate_flags, uint32_t max_clips,
                 char* why, size_t why_size);

#endif /* MCD_TEST_EXERCISE_H */
