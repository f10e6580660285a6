"""Scale tracks: the motion model, forward kinematics composed the runtime's way, rma storing
scale within the tolerance (checked through the C runtime), rest values that cost nothing, and
the codecs without scale tracks refusing animated scale with one clear error."""
from __future__ import annotations

import numpy as np
import pytest

from gltf_build import arm, quat_z
from mocodec import codecs
from mocodec.codecs import UnsupportedMotion
from mocodec.codecs.rma_reference import decode_keys, decode_payload
from mocodec.encode import encode_motions
from mocodec.io import read_gltf
from mocodec.kinematics import forward_kinematics, world_positions
from mocodec.runtime import Asset
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_library_units


def _scaled_arm(tmp_path, scale_values=None, name="grow"):
    doc = arm()
    t = np.linspace(0.0, 2.0, 9)
    rot = quat_z(np.linspace(0, 90, 9))
    scale = scale_values if scale_values is not None else np.stack([1 + 0.5 * np.sin(t), np.ones(9), 1 + 0.3 * t], axis=1)
    doc.animation(name, [(2, "rotation", t, rot, "LINEAR"), (1, "scale", t, scale, "LINEAR")])
    return read_gltf(doc.write(tmp_path / f"{name}.gltf"))


def _units(motions):
    return resolve_library_units(motions)


def test_fk_composes_scale_as_the_runtime_does():
    from mocodec.motion import Skeleton
    sk = Skeleton(["a", "b", "c"], [-1, 0, 1], [[0, 0, 0], [1, 0, 0], [1, 0, 0]], [()] * 3, [False] * 3)
    rot = np.zeros((1, 3, 4))
    rot[..., 3] = 1.0
    rot[0, 1] = quat_z(90)[0]
    scale = np.array([[[2, 3, 1], [1, 1, 1], [1, 1, 1]]], dtype=float)
    _, pos, ws = forward_kinematics(sk, rot, np.broadcast_to(sk.offsets, (1, 3, 3)), scale, world_scales=True)
    # b: a.t + a.r (a.s * b.t) = (2, 0, 0); c: b.t + b.r (b.s * c.t), b.s = (2, 3, 1).
    np.testing.assert_allclose(pos[0], [[0, 0, 0], [2, 0, 0], [2, 2, 0]], atol=1e-12)
    np.testing.assert_allclose(ws[0, 2], [2, 3, 1])


def test_rma_stores_animated_scale_within_the_tolerance(tmp_path):
    motions = _scaled_arm(tmp_path)
    m = motions[0]
    assert m.animated()[1, 2]
    result = encode_motions(motions, _units(motions), "rma", Tolerance(0.5))
    assert result.max_error_cm <= 0.5
    asset = Asset(result.asset)
    _, pos = asset.sample_frames(0, world=True)
    assert np.linalg.norm(pos - world_positions(m), axis=-1).max() * 100 <= 0.5
    _, _, scale = asset.sample_frames(0, scales=True)
    # The shoulder's scale carries 2 m of arm: 0.5 cm there is 0.0025 of scale.
    assert np.abs(scale[:, 1] - m.scales[:, 1]).max() < 0.01
    # The payload has a kind 4 track and scale mode bits (node modes bits 4-5 = 2).
    payload = result.asset[asset.clips[0].data_offset: asset.clips[0].data_offset + asset.clips[0].data_size]
    header, descs = decode_keys(payload)
    assert 4 in [d["kind"] for d in descs]
    assert (header["modes"][1] >> 4) & 3 == 2
    # The Python reference decoder of RMAL v2 reads the scale track as the C runtime does.
    x = np.arange(m.frame_count, dtype=np.float64)
    rot_py, trans_py, scale_py = decode_payload(payload, m.skeleton, x)
    np.testing.assert_allclose(scale_py, scale, atol=1e-5)
    np.testing.assert_allclose(trans_py, asset.sample_frames(0)[1], atol=1e-5)


def test_rest_scale_costs_nothing_and_a_constant_scale_a_constant(tmp_path):
    ones = np.ones((9, 3))
    same, = _scaled_arm(tmp_path, ones, "ones")          # a scale channel that stays at 1
    assert not same.animated()[:, 2].any()
    const, = _scaled_arm(tmp_path, np.full((9, 3), 1.5), "const")
    for m, mode in ((same, 0), (const, 1)):
        result = encode_motions([m], _units([m]), "rma", Tolerance(1.0))
        info = Asset(result.asset).clips[0]
        header, descs = decode_keys(result.asset[info.data_offset: info.data_offset + info.data_size])
        assert (header["modes"][1] >> 4) & 3 == mode
        assert 4 not in [d["kind"] for d in descs]


@pytest.mark.parametrize("codec", ["spline", "ik-predict", "neural", "fk-wavelet", "rma-pca"])
def test_codecs_without_scale_tracks_refuse_animated_scale(tmp_path, codec):
    motions = _scaled_arm(tmp_path)
    entry = codecs.get(codec)
    assert not entry.scale
    with pytest.raises(UnsupportedMotion) as info:
        entry.encode(motions, [100.0], Tolerance(1.0), check=None)
    text = str(info.value)
    assert f"codec {codec!r}" in text and "clip 'grow'" in text and "node 'shoulder'" in text


def test_scale_noise_is_taken_as_the_rest_scale(tmp_path):
    noisy = np.ones((9, 3)) + 1e-6 * np.arange(9)[:, None]
    motions = _scaled_arm(tmp_path, noisy, "noise")
    result = encode_motions(motions, _units(motions), "spline", Tolerance(1.0))
    assert result.max_error_cm <= 1.0  # measured against the noisy source


def test_only_rma_says_it_stores_scale():
    assert [c.name for c in codecs.CODECS if c.scale] == ["rma"]
