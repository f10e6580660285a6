"""cffi build script: compiles native/*.c into ``mocodec._native``, the encoder's compiled
fitting helpers (key placement, Wahba rotations). The declarations are read from
native/fit.h itself, so the module cannot drift from the header.

Built without floating-point contraction so that the compiled arithmetic is the numpy
reference's, operation for operation.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

from cffi import FFI

HERE = Path(__file__).resolve().parent
NATIVE = HERE / "native"
HEADER = NATIVE / "fit.h"


def header_cdef(header: Path = HEADER) -> str:
    """The header's declarations in the form cffi's cdef accepts."""
    text = re.sub(r"/\*.*?\*/", "", header.read_text(), flags=re.S)
    lines = []
    for line in text.splitlines():
        m = re.match(r"#define (MCF_\w+) (\d+)\s*$", line.strip())
        if m:
            lines.append(f"#define {m.group(1)} {m.group(2)}")
        elif not line.lstrip().startswith("#"):
            lines.append(line)
    return "\n".join(lines)


ffibuilder = FFI()
ffibuilder.cdef(header_cdef())
ffibuilder.set_source(
    "mocodec._native",
    '#include "fit.h"\n',
    # setuptools wants paths relative to the project directory it builds in (encoder/, or the
    # repository root for the one-step install).
    sources=[os.path.relpath(p, os.getcwd()) for p in sorted(NATIVE.glob("*.c"))],
    include_dirs=[os.path.relpath(NATIVE, os.getcwd())],
    extra_compile_args=["-std=c99", "-O2", "-ffp-contract=off", "-Wall", "-Wextra"],
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(tmpdir=str(HERE / "build"), verbose=True)
