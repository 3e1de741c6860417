"""The Isaac API coverage table: every `*` member present, and the committed doc up to date."""

import sys
from pathlib import Path

import pytest

from script_loader import load_script

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def coverage_script():
    module = load_script(ROOT / "scripts" / "isaac_coverage.py", "isaac_coverage", register=True)
    try:
        yield module
    finally:
        sys.modules.pop(module.__name__, None)


@pytest.fixture(scope="module")
def result(coverage_script):
    return coverage_script.coverage()


def test_every_starred_isaac_member_is_present(coverage_script, result):
    assert coverage_script.missing_starred(result) == []


def test_the_committed_coverage_doc_is_regenerated_text(coverage_script, result):
    assert coverage_script.DOC.read_text() == coverage_script.render(result), \
        "docs/isaac-api-coverage.md is stale: run .venv/bin/python scripts/isaac_coverage.py"


def test_a_member_that_only_raises_counts_as_missing(coverage_script):
    class Probe:
        ISAAC_UNSUPPORTED = {"pause": "use stop"}

        def pause(self):
            raise NotImplementedError("use stop")

        def resume(self):
            return None

        @property
        def size(self):
            return 1

    assert coverage_script.resolve_class(Probe, "pause", prop=False) == (False, "not supported: use stop")
    assert coverage_script.resolve_class(Probe, "size", prop=False)[0] is False  # a property, Isaac's a method
    assert coverage_script.resolve_class(Probe, "size", prop=True)[0] is True
    assert coverage_script.resolve_class(Probe, "resume", prop=True)[0] is False  # a method, Isaac's a property
    assert coverage_script.resolve_class(Probe, "resume", prop=False)[0] is True
    assert coverage_script.resolve_class(Probe, "stop", prop=False) == (False, "missing")


def test_the_member_lists_match_the_research_table(coverage_script):
    research = Path("/work/shared/research/isaac-api-coverage.md")
    if not research.exists():
        pytest.skip("the research table is outside this checkout")
    assert coverage_script.import_research(research)["sections"] == coverage_script.load_members()
