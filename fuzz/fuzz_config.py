"""Coverage-guided fuzzing of TOML design configs with atheris.

An input with an even first byte is a raw TOML file; with an odd one the rest
drives a generator of ``key = value`` lines over the real option names with
hostile values (wrong types, NaN/inf, huge and negative numbers, tables, lists,
dates). The file is read as ``specholo design --config`` reads it and turned
into a DesignConfig; a SpecholoError with a one-line message is the expected
answer to a bad config, anything else is a crash. See README.md in this folder.
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
    import specholo.jobs.flat.folder  # noqa: F401
    import specholo.scene.stippling  # noqa: F401
    import specholo_cli.cli  # noqa: F401


def test_one_input(data: bytes) -> None:
    """One fuzz case."""
    targets.run_case(targets.check_config_bytes, data)


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
