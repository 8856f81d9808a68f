"""Coverage-guided fuzzing of design folders read back, with atheris.

A tiny design folder is made once (8 stipples on a tetrahedron); each input
mutates one of its files (the first byte picks hologram.json, grooves.npz,
stipples.npz or model.ply, the second how: the rest of the input as the whole
file, hostile changes to its arrays or settings, or byte edits of the real
file), and ``specholo verify``, ``render``, ``report``, ``stereo`` and
``verify --from-gcode`` then read the folder. Each must work or refuse in one
line (exit 1, "error: ..."); anything else is a crash. See README.md in this
folder.
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
    import specholo.readback  # noqa: F401
    import specholo_cli.cli  # noqa: F401


def test_one_input(data: bytes) -> None:
    """One fuzz case."""
    targets.run_case(targets.check_folder_bytes, data)


if __name__ == "__main__":
    targets.base_folder()  # before fuzzing: the design is not part of any case
    atheris.Setup(sys.argv, test_one_input)
    atheris.Fuzz()
