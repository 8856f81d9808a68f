"""A test run leaves nothing behind in the temporary folder: the model cache it
makes for itself goes when it ends."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_a_test_run_removes_its_model_cache(tmp_path: Path):
    env = {k: v for k, v in os.environ.items() if k != "SPECHOLO_CACHE_DIR"}
    env["TMPDIR"] = str(tmp_path)
    run = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                          "tests/test_docs_truths.py", "-k", "show_commands"],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stdout + run.stderr
    assert not list(tmp_path.glob("specholo-test-cache-*"))
