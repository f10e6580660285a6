"""Does the C runtime accept a codec payload? Shared by the tests that damage payloads."""
from __future__ import annotations

from mocodec.encode import _single_clip_asset
from mocodec.motion import Motion
from mocodec.runtime import Result, RuntimeResultError, validate


def runtime_accepts(motion: Motion, cm_per_unit: float, codec: str, payload: bytes, prefix: bytes = b"",
                    skip_checksum: bool = False) -> bool:
    """True when a one-clip asset around ``payload`` validates. Writing the asset already asks
    the runtime for the clip's scratch, which checks the payload as ``mcd_validate`` does
    (``mcd_offline_clip_scratch``): a payload refused there is not accepted either."""
    try:
        data = _single_clip_asset(motion, cm_per_unit, codec, payload, prefix)
    except RuntimeResultError as exc:
        assert exc.code in (Result.MALFORMED, Result.UNSUPPORTED), exc
        return False
    return validate(data, skip_checksum=skip_checksum) == Result.OK
