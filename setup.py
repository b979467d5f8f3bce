"""Build of the optional compiled core (issue 16); everything else is in pyproject.toml.

``horsemocap.detection._regions`` (``horsemocap/detection/_regions.c``) needs
only Python's headers and a C compiler. It is optional: if it cannot be built
the install still succeeds and the package runs its pure-Python path
(``horsemocap.detection.ACTIVE_PATH`` says which one runs).
"""
from setuptools import Extension, setup

setup(ext_modules=[
    Extension(
        "horsemocap.detection._regions",
        sources=["horsemocap/detection/_regions.c"],
        # each floating expression rounded as Python rounds it (no fused multiply-add)
        extra_compile_args=["-ffp-contract=off"],
        optional=True,
    ),
])
