"""Packaging beside pyproject.toml: ship the top-level templates/ and generated/ in the wheel.

The repository keeps both folders at its top level; a wheel (or ``pip install .``) carries
them as the data-only packages ``hydrogen._templates`` and ``hydrogen._generated``, which
``hydrogen/resources.py`` looks for first. Every other setting lives in pyproject.toml.
"""
from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["hydrogen", "hydrogen.*"]) + ["hydrogen._templates", "hydrogen._generated"],
    package_dir={"hydrogen._templates": "templates", "hydrogen._generated": "generated"},
    package_data={
        "hydrogen": ["data/*.toml", "data/*.urdf"],
        "hydrogen._templates": ["*.j2"],
        "hydrogen._generated": ["*/manifest.json", "*/*.c", "*/*.h"],
    },
)
