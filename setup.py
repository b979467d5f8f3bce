"""Build of the optional compiled core (issue 16); everything else is in pyproject.toml.

``horsemocap.detection._regions`` (``horsemocap/detection/_regions.c``) needs
only Python's headers and a C compiler. It is optional: if it cannot be built
the install still succeeds and the package runs its pure-Python path
(``horsemocap.detection.ACTIVE_PATH`` says which one runs).
"""
import hashlib
from pathlib import Path

from setuptools import Extension, setup

SOURCE = "horsemocap/detection/_regions.c"
# The module carries the hash of the source it was built from: an editable install leaves the built
# module beside the source, and horsemocap.detection.regions_core refuses one built from another version.
SOURCE_HASH = hashlib.sha256(Path(__file__).with_name("horsemocap").joinpath("detection", "_regions.c")
                             .read_bytes()).hexdigest()[:16]

setup(ext_modules=[
    Extension(
        "horsemocap.detection._regions",
        sources=[SOURCE],
        define_macros=[("CORE_SOURCE_HASH", f'"{SOURCE_HASH}"')],
        # each floating expression rounded as Python rounds it (no fused multiply-add)
        extra_compile_args=["-ffp-contract=off"],
        optional=True,
    ),
])
