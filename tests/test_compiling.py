"""The first-run progress: a kernel compiled for this machine is announced, a
cached one is not."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

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
    from specholo.jobs.flat import FlatJob

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
