"""docs/PYTHON_API.md: every example runs, in order, as one script; and the API keeps the
command line's defaults."""
from __future__ import annotations

import re
from pathlib import Path

import mocodec
from mocodec import codecs
from mocodec.cli import build_parser
from mocodec.tolerance import DEFAULT_TOLERANCE_CM

DOC = Path(__file__).resolve().parents[1] / "docs" / "PYTHON_API.md"


def test_every_example_of_the_api_page_runs(capsys):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), flags=re.S)
    assert len(blocks) >= 5
    scope: dict = {}
    for block in blocks:
        exec(compile(block, str(DOC), "exec"), scope)  # noqa: S102 - the page's own examples
    out = capsys.readouterr().out
    assert "02_01 344 120.0" in out and "SimpleSkin 133" in out
    assert "(133, 4, 4) (133, 4, 3) (133, 4, 3)" in out and "(38, 10) (5, 4, 10)" in out
    assert "codec 'spline' cannot store animated scale: clip 'ArmatureAction'" in out


def test_api_and_cli_share_defaults():
    args = build_parser().parse_args(["encode", "x.bvh", "-o", "x.mcd"])
    assert args.codec == codecs.DEFAULT_CODEC == "rma"
    assert args.tolerance == DEFAULT_TOLERANCE_CM
    import inspect
    sig = inspect.signature(mocodec.encode)
    assert sig.parameters["codec"].default == codecs.DEFAULT_CODEC
    assert sig.parameters["tolerance"].default == DEFAULT_TOLERANCE_CM
    assert inspect.signature(mocodec.encode_motions).parameters["codec"].default == codecs.DEFAULT_CODEC


def test_public_names_have_docstrings():
    for name in ("load", "encode", "Asset", "Motion", "Skeleton"):
        assert getattr(mocodec, name).__doc__, name
    import importlib
    importlib.import_module("mocodec.encode")  # importing the submodule again keeps the function
    assert callable(mocodec.encode)
    assert mocodec.Asset.sample.__doc__ and "world" in mocodec.Asset.sample.__doc__
