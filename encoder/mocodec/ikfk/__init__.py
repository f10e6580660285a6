"""Groundwork for seed 000's codecs (IK prediction, wavelet + FK) and its baselines.

``angles``: the converted angle format (bone direction φ, ϕ and twist ψ per joint).
``chains``: motion chains root → end effector for any skeleton.
``jacobian``: the closed-form chain Jacobian (eq. 17–20) and the IK prediction step (eq. 15).
``baselines``: SPBLF, DWT and IBKF, quantized and entropy coded with the runtime's coder.
"""
