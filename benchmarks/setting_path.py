"""Follow ``--tool-radius`` from the command line to the program it writes.

Runs ``specholo design`` on the bundled bunny (200 stipples) with a tool radius
no default takes, and records the calls that carry it: the stack of specholo's
functions where the radius is turned into a cutter (every time it is), and the
stack where the program is written with the tool it became. Prints both paths,
module by module, with the hops (moves into another module) and the returns
to a module already left, and checks that the program's header states the
radius.

    python benchmarks/setting_path.py
"""

from __future__ import annotations

import sys
import tempfile
import traceback
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RADIUS = 0.0317  # mm


def stack() -> list[str]:
    """specholo's frames on the stack, outermost first, as module:function."""
    frames = []
    for f, _ in traceback.walk_stack(sys._getframe(2)):
        module = f.f_globals.get("__name__", "")
        if module.startswith("specholo"):
            frames.append(f"{module}:{f.f_code.co_qualname}")
    return frames[::-1]


def describe(name: str, frames: list[str]) -> None:
    modules = [m for i, m in enumerate(f.partition(":")[0] for f in frames)
               if i == 0 or frames[i - 1].partition(":")[0] != m]
    print(f"{name}: {len(frames)} calls, {len(modules) - 1} hops between modules, "
          f"{len(modules) - len(set(modules))} returns to a module already left")
    for f in frames:
        print("   ", f)


def main() -> None:
    import specholo.fabrication.programs.gcode as gcode
    import specholo.jobs.flat.settings as settings
    from specholo_cli.cli import main as cli

    made: list[list[str]] = []
    written: list[list[str]] = []
    make, write = settings.make_cutter, gcode.write_gcode

    def make_cutter(*args, **kwargs):  # type: ignore[no-untyped-def]
        made.append([*stack(), "specholo.optics.cutters:make_cutter"])
        return make(*args, **kwargs)

    def write_gcode(*args, **kwargs):  # type: ignore[no-untyped-def]
        written.append([*stack(), "specholo.fabrication.programs.gcode:write_gcode"])
        return write(*args, **kwargs)

    settings.make_cutter = make_cutter
    gcode.write_gcode = write_gcode
    # the folder's writer imports write_gcode when it runs: it meets this one
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "holo"
        rc = cli(["design", str(ROOT / "examples" / "bunny.obj"), "--out", str(out),
                  "--stipples", "200", "--tool-radius", str(RADIUS)])
        if rc != 0:
            raise SystemExit(f"the design failed (exit {rc})")
        header = (out / "hologram.gcode").read_text().splitlines()[:40]
    print(f"\ncutters made from the radius: {len(made)}; programs written: {len(written)}; "
          f"the program's header states it: "
          f"{any(f'radius {RADIUS:g} mm' in line for line in header)}")
    for i, frames in enumerate(made):
        describe(f"cutter {i + 1} made", frames)
    for frames in written:
        describe("program written", frames)


if __name__ == "__main__":
    main()
