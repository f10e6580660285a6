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


def test_a_clip_that_is_not_there_is_refused_by_name_or_index(sample_paths):
    """`Asset.sample(99, t)` raised a bare "list index out of range" and `sample(-1, t)` sampled
    the last clip; a clip index is 0 ... clips - 1, as in the runtime's API."""
    import pytest

    asset = mocodec.Asset(mocodec.encode(mocodec.load(sample_paths[2]), tolerance=2.0))
    assert asset.sample(0, 0.1).shape == (len(asset.nodes), 10)
    with pytest.raises(KeyError, match=f"no clip named 'nope'; the asset has {sample_paths[2].stem}"):
        asset.sample("nope", 0.1)
    for bad in (1, 99, -1):
        with pytest.raises(IndexError, match=rf"no clip {bad}: the asset has 1 clip\(s\), 0 \.\.\. 0"):
            asset.sample(bad, 0.1)
    for t in (float("nan"), float("inf"), [0.1, float("-inf")]):
        with pytest.raises(ValueError, match="times must be finite seconds"):
            asset.sample(0, t)
