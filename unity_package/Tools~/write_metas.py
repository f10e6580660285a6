"""Writes the .meta of every file and folder of unity_package/ that has none (after adding a
script, say), with a GUID made from its path; existing .meta files are never changed.

    python3 unity_package/Tools~/write_metas.py
"""
from __future__ import annotations

import sys

from layout import PACKAGE, write_missing_metas


def main() -> int:
    written = write_missing_metas(PACKAGE)
    for rel in written:
        print(f"wrote unity_package/{rel}")
    print(f"unity package: {len(written)} .meta written")
    return 0


if __name__ == "__main__":
    sys.exit(main())
