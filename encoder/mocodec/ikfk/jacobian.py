"""Closed-form chain Jacobian (seed 000 eq. 17–20) and the IK prediction step (eq. 15).

A chain's end effector, relative to the chain's first node, is ``f(θ) = Σ_j L_j d(φ_j, ϕ_j)``
(eq. 18), with ``d`` the world direction of link j in the spherical angles of eq. 5. Because
each link has its own world angles, ``∂f/∂(φ_j, ϕ_j)`` involves link j only: the 3 × 2n
Jacobian is closed form (eq. 19–20) and costs O(n).

Prediction (eq. 15): ``Δθ = θ₀ + J⁺(Δp − J θ₀)``, ``θ₀ = k Δθ_prev``: among all angle changes
that move the effector by Δp (to first order), the one closest to ``k`` times the previous
change, i.e. the smallest change of angular velocity for k = 1. J⁺ is the Moore–Penrose
pseudo-inverse; eq. 14's ``Jᵀ(JJᵀ)⁻¹`` is the same matrix when J has rank 3, and we take the
SVD form so a straight chain (rank 2: the effector cannot move along the bone) stays defined.

Everything is vectorised over leading axes (frames, chains of equal length).
"""
from __future__ import annotations

import numpy as np

from .angles import direction_to_spherical, spherical_to_direction
from .chains import Chain

RCOND = 1e-10  # singular values below this × the largest are treated as zero in J⁺


def link_angles(chain: Chain, world_positions: np.ndarray) -> np.ndarray:
    """θ (F, n, 2): (φ, ϕ) of each link's world direction, ϕ unwrapped over frames."""
    parents = [a for a, _ in chain.links]
    children = [b for _, b in chain.links]
    v = world_positions[:, children] - world_positions[:, parents]
    polar, azimuth = direction_to_spherical(v / np.linalg.norm(v, axis=-1, keepdims=True))
    return np.stack((polar, np.unwrap(azimuth, axis=0)), axis=-1)


def effector_offset(theta: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """f(θ) (..., 3) of eq. 17–18: effector position relative to the chain's first node."""
    d = spherical_to_direction(theta[..., 0], theta[..., 1])
    return np.sum(lengths[:, None] * d, axis=-2)


def jacobian(theta: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """J (..., 3, 2n) of eq. 19–20; columns ordered φ₁, ϕ₁, φ₂, ϕ₂, ..."""
    polar, azimuth = theta[..., 0], theta[..., 1]
    sp, cp = np.sin(polar), np.cos(polar)
    sa, ca = np.sin(azimuth), np.cos(azimuth)
    L = lengths
    d_polar = np.stack((L * cp * ca, L * cp * sa, -L * sp), axis=-2)       # (..., 3, n)
    d_azimuth = np.stack((-L * sp * sa, L * sp * ca, np.zeros_like(sp)), axis=-2)
    # Interleave so column 2j is ∂/∂φ_j and 2j+1 is ∂/∂ϕ_j, as in eq. 19.
    return np.stack((d_polar, d_azimuth), axis=-1).reshape(d_polar.shape[:-1] + (-1,))


def predict_step(
    theta_prev: np.ndarray,
    dtheta_prev: np.ndarray,
    dp: np.ndarray,
    lengths: np.ndarray,
    k: float,
) -> tuple[np.ndarray, np.ndarray]:
    """One IK prediction (eq. 15, 22): from the previous decoded link angles ``theta_prev``
    (..., n, 2), their last change ``dtheta_prev`` (..., n, 2) and the decoded effector delta
    ``dp`` (..., 3), return the predicted angles and the predicted change Δθ."""
    J = jacobian(theta_prev, lengths)
    shape = theta_prev.shape
    theta0 = k * dtheta_prev.reshape(shape[:-2] + (-1,))
    miss = dp - np.einsum("...ij,...j->...i", J, theta0)
    dtheta = theta0 + np.einsum("...ji,...i->...j", np.linalg.pinv(J, rcond=RCOND), miss)
    dtheta = dtheta.reshape(shape)
    return theta_prev + dtheta, dtheta


def residual_energy_ratio(theta: np.ndarray, lengths: np.ndarray, k: float) -> dict[str, float]:
    """Open-loop study on a clean chain trajectory θ (F, n, 2), frames 2 ... F-1.

    Compares three predictions of θᵢ from the frames before it: IK (eq. 15 with this ``k``,
    given the true effector delta), "repeat the last frame" θᵢ₋₁, and constant velocity
    θᵢ₋₁ + Δθᵢ₋₁ (no IK, a reference). Returns residual-energy ratios against "repeat":

    * ``ik_angle`` / ``velocity_angle``: Σ (angle residual)² in radians², the quantity the
      codec would quantize;
    * ``ik_link`` / ``velocity_link``: Σ L_j² |d(θᵢ) − d(θ^pred)|², the link endpoints'
      displacement, which is what world error follows and which, unlike ϕ, does not blow
      up at the poles (φ ≈ 0 or π, where ϕ jumps);
    * ``repeat_angle`` / ``repeat_link``: the "repeat" energies themselves, to pool chains.

    Previous frames are the originals: the lossless limit of the closed loop.
    """
    f = effector_offset(theta, lengths)
    prev, dprev = theta[1:-1], theta[1:-1] - theta[:-2]
    pred, _ = predict_step(prev, dprev, f[2:] - f[1:-1], lengths, k)
    target = theta[2:]

    def angle_energy(p: np.ndarray) -> float:
        return float(np.sum((target - p) ** 2))

    def link_energy(p: np.ndarray) -> float:
        diff = spherical_to_direction(target[..., 0], target[..., 1]) \
            - spherical_to_direction(p[..., 0], p[..., 1])
        return float(np.sum(lengths[:, None] ** 2 * diff ** 2))

    velocity = prev + dprev
    return {
        "ik_angle": angle_energy(pred) / angle_energy(prev),
        "velocity_angle": angle_energy(velocity) / angle_energy(prev),
        "ik_link": link_energy(pred) / link_energy(prev),
        "velocity_link": link_energy(velocity) / link_energy(prev),
        "repeat_angle": angle_energy(prev),
        "repeat_link": link_energy(prev),
    }


def closed_loop_encode(
    theta: np.ndarray, lengths: np.ndarray, k: float | None, angle_step: float,
    effector_step: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closed-loop IK prediction of one chain's link angles θ (F, n, 2), study version.

    The effector offset ``f(θ)`` is sent by last-frame DPCM with ``effector_step``; each frame's
    angles are predicted from the *decoded* previous frames and the *decoded* effector delta
    (eq. 22), and the residual δ (eq. 23) is quantized with ``angle_step``. ``k=None`` predicts
    by repeating the last decoded frame (no IK, no effector stream needed). Returns the
    effector codes (F, 3), the angle codes (F, n, 2) and the encoder's reconstruction, which
    :func:`closed_loop_decode` must reproduce from the codes alone.
    """
    f = effector_offset(theta, lengths)
    eff_codes = np.zeros(f.shape, dtype=np.int64)
    eff_state = np.zeros(3, dtype=np.int64)
    codes = np.zeros(theta.shape, dtype=np.int64)
    recon = np.zeros_like(theta)
    for i in range(theta.shape[0]):
        eff_codes[i] = np.rint((f[i] - eff_state * effector_step) / effector_step)
        eff_state += eff_codes[i]
        pred = _closed_loop_prediction(recon, eff_codes, i, lengths, k, effector_step)
        codes[i] = np.rint((theta[i] - pred) / angle_step)
        recon[i] = pred + codes[i] * angle_step
    return eff_codes, codes, recon


def closed_loop_decode(
    eff_codes: np.ndarray, codes: np.ndarray, lengths: np.ndarray, k: float | None,
    angle_step: float, effector_step: float,
) -> np.ndarray:
    """The decoder of :func:`closed_loop_encode`: link angles (F, n, 2) from the codes."""
    recon = np.zeros(codes.shape)
    for i in range(codes.shape[0]):
        pred = _closed_loop_prediction(recon, eff_codes, i, lengths, k, effector_step)
        recon[i] = pred + codes[i] * angle_step
    return recon


def _closed_loop_prediction(recon: np.ndarray, eff_codes: np.ndarray, i: int,
                            lengths: np.ndarray, k: float | None,
                            effector_step: float) -> np.ndarray:
    """Prediction of frame i from decoded frames < i: zero for frame 0 (sent whole), the last
    frame for "repeat" and frame 1 (no previous change yet), else eq. 15 with the decoded
    effector delta (the DPCM code times its step)."""
    if i == 0:
        return np.zeros(recon.shape[1:])
    if k is None or i == 1:
        return recon[i - 1]
    dp = eff_codes[i] * effector_step
    pred, _ = predict_step(recon[i - 1], recon[i - 1] - recon[i - 2], dp, lengths, k)
    return pred
