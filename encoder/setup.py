"""Builds the encoder's cffi extension (mocodec._native); metadata lives in pyproject.toml."""
from setuptools import setup

setup(cffi_modules=["build_native.py:ffibuilder"])
