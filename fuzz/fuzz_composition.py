"""Coverage-guided fuzzing of compositions (``specholo compose``), with atheris.

An input with an even first byte is the TOML composition after that byte; with
an odd one the rest adds hostile lines (wrong types, NaN/inf, huge and negative
numbers, host kinds and files, frame patterns, a FIFO) to the tables of a small
composition. The file is read as ``specholo compose`` reads it, in a folder
holding a tetrahedron, a height field and a FIFO; a composition that designs in
a second or two (a dozen stipples, steps of a degree or more) is designed,
verified, written and read back as ``specholo verify`` reads it. A SpecholoError
with a one-line message is the expected answer to a bad composition; anything
else is a crash. See README.md in this folder.
"""

from __future__ import annotations

import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parent))

import targets  # noqa: E402

# Modules with compiled (numba) kernels are left as they are: numba compiles a
# kernel from its bytecode, and instrumented bytecode calls into atheris.
with atheris.instrument_imports(include=["specholo", "specholo_cli"],
                                exclude=targets.compiled_modules()):
    import specholo.jobs.composition.design  # noqa: F401
    import specholo.readback  # noqa: F401


def test_one_input(data: bytes) -> None:
    """One fuzz case."""
    targets.run_case(targets.check_composition_bytes, data)


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
