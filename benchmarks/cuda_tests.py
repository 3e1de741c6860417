"""pytest plugin: select every test that needs or uses CUDA, and record which ran, passed, skipped.

    PYTHONPATH=benchmarks AMBULO_TEST_DEVICE=cuda python -m pytest -p cuda_tests \\
        --cuda-report gpu_tests.json tests

The project marks GPU tests two ways, and both are selected:

- ``pytest.mark.skipif(not torch.cuda.is_available(), reason="... CUDA ...")``, on a test or as a
  module's ``pytestmark`` (perception's CUDA tests, tests/rl/test_sync_free_gpu.py, ...): a
  skipif whose reason names CUDA;
- modules that read ``AMBULO_TEST_DEVICE`` into a module-level name (tests/engine/test_gpu_engine.py,
  tests/sensors/test_tiled_camera.py): all their tests, which run on Warp's CPU device by
  default and on the GPU with ``AMBULO_TEST_DEVICE=cuda``.

Everything else is deselected. The report is rewritten after every test, so a run stopped by a
time limit still says what ran: ``{"device", "selected", "deselected", "summary": {outcome:
count, "not_run": n}, "tests": {nodeid: {"outcome", "seconds", "reason"?}}, "not_run": [...]}``.
"""

from __future__ import annotations

import json
import os
import re
import time
from pathlib import Path

import pytest

DEVICE_VARIABLE = "AMBULO_TEST_DEVICE"
READS_VARIABLE = re.compile(r"^\w+\s*=\s*os\.environ\.get\(\s*[\"']AMBULO_TEST_DEVICE[\"']", re.MULTILINE)
"""A module-level ``DEVICE = os.environ.get("AMBULO_TEST_DEVICE", ...)``: the name in a string or a
comment (a test that writes such a module, say) does not count."""


def pytest_addoption(parser):
    parser.addoption("--cuda-report", default=None, help="write which CUDA tests ran, passed and skipped here (JSON)")


def _reads_device_variable(path: Path, cache: dict[Path, bool]) -> bool:
    if path not in cache:
        try:
            cache[path] = READS_VARIABLE.search(path.read_text(errors="replace")) is not None
        except OSError:
            cache[path] = False
    return cache[path]


def needs_cuda(item, cache: dict[Path, bool]) -> bool:
    """Whether ``item`` is one of the project's GPU tests (see the module doc)."""
    for mark in item.iter_markers("skipif"):
        if "cuda" in str(mark.kwargs.get("reason", "")).lower():
            return True
    return _reads_device_variable(Path(str(item.fspath)), cache)


class CudaReport:
    def __init__(self, path: str | None):
        self.path = Path(path) if path else None
        self.selected: list[str] = []
        self.deselected = 0
        self.tests: dict[str, dict] = {}
        self.started_s = time.time()

    def write(self) -> None:
        if self.path is None:
            return
        try:
            import torch
            device = torch.cuda.get_device_name() if torch.cuda.is_available() else "no CUDA device"
        except Exception as err:  # the report must be written whatever torch says
            device = f"unknown ({err})"
        summary: dict[str, int] = {}
        for row in self.tests.values():
            summary[row["outcome"]] = summary.get(row["outcome"], 0) + 1
        not_run = [n for n in self.selected if n not in self.tests]
        summary["not_run"] = len(not_run)
        report = {"device": device, "test_device": os.environ.get(DEVICE_VARIABLE, "cpu"),
                  "seconds": round(time.time() - self.started_s, 1), "selected": len(self.selected),
                  "deselected": self.deselected, "summary": summary, "tests": self.tests, "not_run": not_run}
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(json.dumps(report, indent=1))
        tmp.replace(self.path)

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, config, items):
        cache: dict[Path, bool] = {}
        keep = [item for item in items if needs_cuda(item, cache)]
        dropped = [item for item in items if item not in keep]
        if dropped:
            config.hook.pytest_deselected(items=dropped)
        items[:] = keep
        self.selected = [item.nodeid for item in keep]
        self.deselected = len(dropped)
        self.write()

    def pytest_runtest_logreport(self, report):
        row = self.tests.get(report.nodeid)
        if report.when == "setup" or row is None:
            row = self.tests.setdefault(report.nodeid, {"outcome": "passed", "seconds": 0.0})
        row["seconds"] = round(row["seconds"] + report.duration, 2)
        if report.skipped:
            row["outcome"] = "skipped"
            reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
            row["reason"] = reason.removeprefix("Skipped: ")
        elif report.failed:
            row["outcome"] = "failed" if report.when == "call" else "error"
            crash = getattr(report.longrepr, "reprcrash", None)  # the assertion's message, where there is one
            row["reason"] = (crash.message if crash is not None else str(report.longrepr))[:300]
        if report.when == "teardown":
            self.write()

    def pytest_sessionfinish(self):
        self.write()


def pytest_configure(config):
    config.pluginmanager.register(CudaReport(config.getoption("--cuda-report")), "cuda_report")
