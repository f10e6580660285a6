"""cffi build script: compiles runtime_c/src/*.c into the extension `mocodec_runtime._native`.

The C declarations are read from runtime_c/include/mocodec.h and runtime_c/src/entropy.h
themselves (preprocessor lines dropped), so the binding cannot drift from the headers.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
RUNTIME = (HERE / ".." / ".." / "runtime_c").resolve()
HEADER = RUNTIME / "include" / "mocodec.h"
# The entropy coder is internal to the runtime but the encoder runs it too (one implementation).
ENTROPY_HEADER = RUNTIME / "src" / "entropy.h"
# So is the ik-predict prediction step: the encoder's closed loop runs the decoder's code.
IKPREDICT_HEADER = RUNTIME / "src" / "ikpredict.h"
# And the numbers the encoder stores about a payload (the scratch a clip needs).
OFFLINE_HEADER = RUNTIME / "src" / "offline.h"

# Glue that only loops over the public API, so Python pays one call per clip, not per frame.
GLUE = """
int mcdpy_sample_many(const mcd_asset* asset, uint32_t clip, const double* times, uint32_t count,
                      uint32_t flags, mcd_transform* out, uint32_t nodes, void* scratch);
"""
GLUE_SOURCE = """
int mcdpy_sample_many(const mcd_asset* asset, uint32_t clip, const double* times, uint32_t count,
                      uint32_t flags, mcd_transform* out, uint32_t nodes, void* scratch) {
    uint32_t i;
    for (i = 0; i < count; ++i) {
        mcd_result r = mcd_sample(asset, clip, times[i], flags, out + (size_t)i * nodes, nodes, scratch);
        if (r != MCD_OK) return (int)r;
    }
    return 0;
}
"""


def header_cdef(header: Path = HEADER) -> str:
    """The header's declarations in the form cffi's cdef accepts."""
    text = header.read_text()
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"#ifdef __cplusplus.*?#endif", "", text, flags=re.S)
    lines = []
    for line in text.splitlines():
        m = re.match(r"#define (MCD_\w+) (0x[0-9A-Fa-f]+|\d+)u?\s*$", line.strip())
        if m:
            lines.append(f"#define {m.group(1)} {int(m.group(2), 0)}")
        elif not line.lstrip().startswith("#"):
            lines.append(line.replace("MCD_API ", ""))
    return "\n".join(lines)


ffibuilder = FFI()
ffibuilder.cdef(header_cdef() + GLUE)
ffibuilder.cdef(header_cdef(ENTROPY_HEADER))
ffibuilder.cdef(header_cdef(IKPREDICT_HEADER))
ffibuilder.cdef(header_cdef(OFFLINE_HEADER))
ffibuilder.set_source(
    "mocodec_runtime._native",
    '#include "mocodec.h"\n#include "entropy.h"\n#include "ikpredict.h"\n#include "offline.h"\n' + GLUE_SOURCE,
    # setuptools wants paths relative to the project directory it builds in (bindings/python,
    # or the repository root for the one-step install).
    sources=[os.path.relpath(p, os.getcwd()) for p in sorted((RUNTIME / "src").glob("*.c"))],
    include_dirs=[os.path.relpath(RUNTIME / d, os.getcwd()) for d in ("include", "src")],
    extra_compile_args=["-std=c99", "-O2"],
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(HERE / "build"), verbose=True)
