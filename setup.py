"""Builds the runtime binding's cffi extension for the one-step install; metadata lives in
pyproject.toml."""
from setuptools import setup

setup(cffi_modules=["bindings/python/build_ffi.py:ffibuilder"])
