"""Coverage-guided fuzzing of ``specholo.scene.loading.load_model`` with atheris.

The first byte of an input picks the file extension (see ``targets.MODEL_EXTS``),
the rest is the file. A loaded model is also placed and stippled. A
SpecholoError with a one-line message is the expected answer to a bad file;
anything else is a crash. See README.md in this folder.
"""

from __future__ import annotations

import sys
from pathlib import Path

import atheris

sys.path.insert(0, str(Path(__file__).resolve().parent))

import targets  # noqa: E402

# Modules with compiled (numba) kernels are left as they are: numba compiles a
# kernel from its bytecode, and instrumented bytecode calls into atheris.
with atheris.instrument_imports(include=["specholo", "trimesh"],
                                exclude=targets.compiled_modules()):
    import specholo.scene.loading  # noqa: F401
    import specholo.scene.placement  # noqa: F401
    import specholo.scene.stippling  # noqa: F401


def test_one_input(data: bytes) -> None:
    """One fuzz case."""
    targets.run_case(targets.check_model_bytes, data)


if __name__ == "__main__":
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
