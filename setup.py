"""Builds the cffi extensions for the one-step install (the runtime binding and the encoder's
compiled fitting helpers); metadata lives in pyproject.toml."""
from setuptools import setup

setup(cffi_modules=["bindings/python/build_ffi.py:ffibuilder", "encoder/build_native.py:ffibuilder"])
