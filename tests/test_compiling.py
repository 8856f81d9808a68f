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
