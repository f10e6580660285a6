/* What the POSIX test suite needs on Windows and MinGW-w64 lacks; CMakeLists.txt force-includes
 * it (-include) into the test sources of a MinGW build. posix_memalign is the only call missing.
 * Win64's malloc returns 16-byte aligned blocks (MEMORY_ALLOCATION_ALIGNMENT), so a request for
 * up to 16 is a plain malloc, released by free() like every other block; anything stricter is
 * refused, so a test that needs more alignment fails instead of running misaligned. */
#ifndef MCD_TEST_COMPAT_WINDOWS_H
#define MCD_TEST_COMPAT_WINDOWS_H

#include <errno.h>
#include <stdint.h>
#include <stdlib.h>

static inline int posix_memalign(void** out, size_t alignment, size_t size) {
    void* p;
    if (alignment > 16u) return EINVAL;
    p = malloc(size ? size : 1u);
    if (!p) return ENOMEM;
    if ((uintptr_t)p % alignment != 0) {
        free(p);
        return EINVAL;
    }
    *out = p;
    return 0;
}

#endif
