"""The first-run progress: a kernel compiled for this machine is announced, a
cached one is not."""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from specholo._compiling import kernel_name
from specholo.scene._sample_kernel import _points

#: One small kernel, called inside compiling_shown; prints what was announced.
SCRIPT = """
import json
import numpy as np
from specholo._compiling import compiling_shown
from specholo.scene._sample_kernel import _points
seen = []
with compiling_shown(lambda count, name: seen.append([count, name])):
    _points(np.eye(3), np.array([[0, 1, 2]]), np.zeros(2, np.int64), np.full((2, 2), 0.25))
print(json.dumps(seen))
"""


def announced(cache: Path) -> list[list]:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    run = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                         text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def test_a_compile_is_announced_and_a_cached_kernel_is_not(tmp_path):
    assert announced(tmp_path) == [[1, "scene sample points"], [1, None]]
    assert announced(tmp_path) == []


def test_kernel_names_read_as_words():
    assert kernel_name(_points) == "scene sample points"


def _readme_config():  # type: ignore[no-untyped-def]
    from specholo.jobs.flat.job import FlatJob

    values = {"size": 60.0, "center_z": -40.0, "light_elevation": 45.0,
              "view_distance": 600.0, "view_range": 45.0, "stipples": 2000}
    return FlatJob().configure(values, [Path(__file__).parents[1] / "examples" / "bunny.obj"])


def test_precompile_runs_the_later_stages() -> None:
    """The made-up design the first run's second process compiles for goes
    through every later stage (it hides its errors, so a break here would only
    show as a slower first run)."""
    from specholo import _precompile

    _precompile._run(_readme_config())


def test_precompile_only_on_a_cold_cache(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from specholo import _precompile

    monkeypatch.setattr(_precompile, "cache_is_cold", lambda: False)
    assert _precompile.start(_readme_config()) is None
    monkeypatch.setattr(_precompile, "cache_is_cold", lambda: True)
    monkeypatch.setenv("SPECHOLO_NO_PRECOMPILE", "1")
    assert _precompile.start(_readme_config()) is None
    _precompile.stop(None)


# -- one decorator for every kernel -------------------------------------------------

SRC = Path(__file__).resolve().parents[1] / "src"
ROOT = SRC.parent


def _decorator(fn: ast.FunctionDef) -> ast.Call | None:
    """The ``kernel(...)`` or ``njit(...)`` call decorating ``fn``, if any."""
    for d in fn.decorator_list:
        call = d if isinstance(d, ast.Call) else None
        name = ast.unparse(call.func if call else d)
        if name == "kernel" or name.endswith("njit"):
            return call if call else ast.Call(func=d, args=[], keywords=[])
    return None


def _kernels() -> list[tuple[Path, ast.FunctionDef, ast.Call]]:
    found = []
    for f in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.FunctionDef) and (call := _decorator(node)) is not None:
                found.append((f, node, call))
    return found


def test_every_kernel_is_compiled_through_one_decorator() -> None:
    """A kernel decorated with numba's own ``njit`` would get both wrappers back
    (and might not be cached); every one goes through ``kernel``."""
    kernels = _kernels()
    assert len(kernels) > 100
    raw = [f"{f.relative_to(SRC)}:{fn.name}" for f, fn, call in kernels
           if ast.unparse(call.func) != "kernel"]
    assert raw == []


def test_a_helper_is_never_called_from_python() -> None:
    """A ``helper=True`` kernel has no Python entry point: calling it from
    Python fails at run time, so its name appears only inside other kernels'
    bodies, in the sources, the tests and the benchmarks."""
    kernels = _kernels()
    helpers = {fn.name for _, fn, call in kernels
               if any(k.arg == "helper" and ast.unparse(k.value) == "True"
                      for k in call.keywords)}
    assert len(helpers) > 40
    bodies = {id(fn) for _, fn, _ in kernels}
    outside: list[str] = []

    def visit(node: ast.AST, where: Path) -> None:
        if id(node) in bodies:
            return
        if isinstance(node, ast.FunctionDef) and _decorator(node) is not None:
            return  # a kernel's body (a test's own kernel may call a helper)
        # (importing a helper is fine: other modules' kernels call it)
        name = node.id if isinstance(node, ast.Name) else \
            node.attr if isinstance(node, ast.Attribute) else None
        if name in helpers:
            outside.append(f"{where.relative_to(ROOT)}:{node.lineno}:{name}")  # type: ignore[attr-defined]
        for child in ast.iter_child_nodes(node):
            visit(child, where)

    for folder in ("src", "tests", "benchmarks"):
        for f in (ROOT / folder).rglob("*.py"):
            visit(ast.parse(f.read_text(encoding="utf-8")), f)
    assert outside == []


def test_a_helper_runs_inside_a_kernel_and_is_private() -> None:
    """A helper called from Python would crash the process (numba has no
    entry point to check its arguments), so only private names are helpers."""
    from specholo.visibility import _ray_kernel

    names = [fn.name for _, fn, call in _kernels()
             if any(k.arg == "helper" for k in call.keywords)]
    assert names and all(n.startswith("_") for n in names)
    out = np.empty(2, dtype=np.bool_)
    points = np.zeros((2, 3))
    normals = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
    eyes = np.array([[0.0, 0.0, 5.0]])
    _ray_kernel._facing(0, 2, points, normals, eyes, 1, out)  # through the helper _pair
    assert out.tolist() == [True, False]
