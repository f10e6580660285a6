"""Baking a library on every core, on a Dask cluster, and incrementally.

The per-clip work of a codec (:func:`mocodec.codecs.encode_each_clip`) goes to a
:class:`Runner` (:func:`make_runner`: ``--jobs``, ``--scheduler``, ``--cache``); the asset is
assembled by the caller from the outcomes in clip order, byte for byte what a serial bake makes.
"""
from .cache import ClipCache, job_key
from .fingerprint import encoder_fingerprint, motion_digest, settings_digest
from .runners import (BakeError, ClipJob, ClipOutcome, DaskRunner, EncoderMismatch, ProcessRunner, Runner,
                      SerialRunner, default_jobs, make_runner, run_job)

__all__ = ["BakeError", "ClipCache", "ClipJob", "ClipOutcome", "DaskRunner", "EncoderMismatch", "ProcessRunner",
           "Runner", "SerialRunner", "default_jobs", "encoder_fingerprint", "job_key", "make_runner",
           "motion_digest", "run_job", "settings_digest"]
