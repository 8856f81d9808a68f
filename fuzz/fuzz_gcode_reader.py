"""Coverage-guided fuzzing of ``specholo.fabrication.programs.gcode.read_gcode`` with atheris.

An input with an even first byte is the G-code file after that byte; with an
odd one the rest drives a generator of G-code lines (motion words, huge and
tiny numbers, stipple comments). A SpecholoError with a one-line message is the
expected answer to a bad program; anything else, or grooves that are not well
formed, is a crash. See README.md in this folder.
"""

from __future__ import annotations

import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parent))

import targets  # noqa: E402

# Modules with compiled (numba) kernels are left as they are: numba compiles a
# kernel from its bytecode, and instrumented bytecode calls into atheris.
with atheris.instrument_imports(include=["specholo"],
                                exclude=targets.compiled_modules()):
    import specholo.fabrication.programs.gcode  # noqa: F401


def test_one_input(data: bytes) -> None:
    """One fuzz case."""
    targets.run_case(targets.check_gcode_bytes, data)


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
