"""Without libLLVM the path tier fails in one line naming the package to install (issue 26, item 5).

Dr.Jit loads libLLVM from ``DRJIT_LIBLLVM_PATH`` when it is set; pointing it at a missing file in a
subprocess is the machine without ``libllvm19`` (Debian 12 ships LLVM 15, which Mitsuba refuses).
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytest.importorskip("mitsuba", reason="the path tier's extra is not installed: pip install 'ambulo[render]'")

SCRIPT = """
import mujoco
from ambulo.render.path import PathTracer, PathTracerCfg
model = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom size="0.1"/></worldbody></mujoco>')
PathTracer(model, PathTracerCfg(variant="auto"))
"""


def test_a_machine_without_libllvm_gets_one_line_naming_libllvm19():
    env = {**os.environ, "DRJIT_LIBLLVM_PATH": "/nonexistent/libLLVM.so", "CUDA_VISIBLE_DEVICES": ""}
    run = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode != 0
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("ambulo.render.path.NoPathTracerError:"), run.stderr[-2000:]
    assert "apt-get install libllvm19" in last
