"""Which members of Isaac Sim's core API ambulo provides: writes ``docs/isaac-api-coverage.md``.

Why: the issue's promise is that every member tutorial users call most (marked ``*``) exists
under the Isaac name a script imports. This script resolves each Isaac class or module through
the same table ``ambulo run`` uses (``ambulo.isaac.isaac_names()``), looks every Isaac member up
on what that import gives, and writes the table; it exits 1 when a ``*`` member is missing, so
a test (``tests/isaac/test_coverage.py``) keeps the promise.

"present" means the name resolves (``hasattr`` on the class, attributes its ``__init__`` sets,
dataclass fields, or the module's table entry) with the right kind: an Isaac property must not
be a method here, nor an Isaac method a plain value. Signatures and behaviour are not checked
here; ``tests/isaac/test_coverage_members.py`` and the sim tests do that. A member that exists
only to raise a clear error naming the alternative is listed in its class's (or module's)
``ISAAC_UNSUPPORTED`` dict and counts as missing ("not supported").

The member lists (``scripts/isaac_api_members.json``) come from Isaac's public type stubs via
``/work/shared/research/isaac-api-coverage.md``; ``--import PATH`` regenerates them from that
file, so the check runs from a fresh clone without it.

Usage: ``python scripts/isaac_coverage.py`` (write the doc), ``--check`` (compare only; exit 1
if the committed doc is stale or a ``*`` member is missing), ``--import research.md``.
"""

from __future__ import annotations

import argparse
import ast
import dataclasses
import importlib
import inspect
import json
import re
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MEMBERS_JSON = ROOT / "scripts" / "isaac_api_members.json"
DOC = ROOT / "docs" / "isaac-api-coverage.md"

SECTIONS: dict[str, tuple[str, str | None]] = {
    "World (+SimulationContext)": ("isaacsim.core.api", "World"),
    "Scene": ("isaacsim.core.api.scenes", "Scene"),
    "SingleArticulation / Robot": ("isaacsim.core.prims", "SingleArticulation"),
    "WheeledRobot": ("isaacsim.robot.wheeled_robots.robots", "WheeledRobot"),
    "ArticulationController": ("isaacsim.core.api.controllers", "ArticulationController"),
    "ArticulationAction": ("isaacsim.core.utils.types", "ArticulationAction"),
    "DifferentialController": ("isaacsim.robot.wheeled_robots.controllers", "DifferentialController"),
    "SingleXFormPrim": ("isaacsim.core.prims", "SingleXFormPrim"),
    "SingleRigidPrim": ("isaacsim.core.prims", "SingleRigidPrim"),
    "PhysicsMaterial": ("isaacsim.core.api.materials", "PhysicsMaterial"),
    "Camera": ("isaacsim.sensors.camera", "Camera"),
    "IMUSensor": ("isaacsim.sensors.physics", "IMUSensor"),
    "utils.stage": ("isaacsim.core.utils.stage", None),
    "utils.prims": ("isaacsim.core.utils.prims", None),
    "utils.viewports": ("isaacsim.core.utils.viewports", None),
    "utils.semantics": ("isaacsim.core.utils.semantics", None),
    "nucleus": ("isaacsim.storage.native", None),
}
"""Research-file section -> (Isaac module, class name; None: the module's own functions)."""

_ROW = re.compile(r"^\|\s*(\*?)([A-Za-z_][A-Za-z0-9_]*)(\s*\(prop\))?\s*\|")
_HEADING = re.compile(r"^#{2,4}\s+(.+?):\s+\d+ yes")


# -- the member lists ------------------------------------------------------------------
def import_research(path: Path) -> dict:
    """Member lists ``{"sections": [{"section", "members": [{"name", "star", "prop"}]}]}`` from
    the research table (its first occurrence of each section)."""
    sections: dict[str, list[dict]] = {}
    current = None
    for line in path.read_text().splitlines():
        heading = _HEADING.match(line)
        if heading:
            name = heading.group(1).strip()
            current = None if name in sections else sections.setdefault(name, [])
            continue
        row = _ROW.match(line)
        if row and current is not None and row.group(2) != "Isaac":
            current.append({"name": row.group(2), "star": bool(row.group(1)), "prop": bool(row.group(3))})
    unknown = sorted(set(sections) - set(SECTIONS))
    if unknown:
        raise SystemExit(f"sections {unknown} have no Isaac name; add them to SECTIONS in {__file__}")
    return {"source": "Isaac Sim 5.x public type stubs (research table isaac-api-coverage.md)",
            "sections": [{"section": s, "members": m} for s, m in sections.items()]}


def load_members() -> list[dict]:
    return json.loads(MEMBERS_JSON.read_text())["sections"]


# -- resolving members --------------------------------------------------------------------
@dataclasses.dataclass
class Row:
    name: str
    star: bool
    prop: bool
    present: bool
    where: str
    """The ambulo attribute it resolves to, or why it is missing."""


def _init_attributes(cls: type) -> dict[str, type]:
    """Instance attributes ``self.x = ...`` assigned in the ``__init__`` of ``cls`` and its bases
    -> the class whose ``__init__`` assigns it."""
    found: dict[str, type] = {}
    for klass in reversed(cls.__mro__):
        init = klass.__dict__.get("__init__")
        if init is None or not inspect.isfunction(init):
            continue
        try:
            tree = ast.parse(textwrap.dedent(inspect.getsource(init)))
        except (OSError, TypeError):
            continue
        for node in ast.walk(tree):
            targets = node.targets if isinstance(node, ast.Assign) else (
                [node.target] if isinstance(node, ast.AnnAssign) else [])
            for target in targets:
                for t in (target.elts if isinstance(target, ast.Tuple) else [target]):
                    if isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name) and t.value.id == "self":
                        found[t.attr] = klass
    return found


def _is_callable_member(value) -> bool:
    return callable(value) or isinstance(value, (classmethod, staticmethod))


def _unsupported(owner) -> dict[str, str]:
    return dict(getattr(owner, "ISAAC_UNSUPPORTED", {}) or {})


def resolve_class(cls: type, name: str, prop: bool) -> tuple[bool, str]:
    """(present, where) of member ``name`` on ambulo class ``cls``."""
    unsupported = _unsupported(cls)
    if name in unsupported:
        return False, f"not supported: {unsupported[name]}"
    if name == "__init__":
        owner = next((k for k in cls.__mro__ if "__init__" in k.__dict__ and k is not object), None)
        if owner is None:
            return False, "no constructor of its own"
        return True, f"`{owner.__module__}.{owner.__qualname__}.__init__` (signature not compared)"
    owner = next((k for k in cls.__mro__ if name in k.__dict__), None)
    if owner is not None and owner is not object:
        raw = owner.__dict__[name]
        where = f"`{owner.__module__}.{owner.__qualname__}.{name}`"
        if prop and not isinstance(raw, property) and _is_callable_member(raw):
            return False, f"{where} is a method; Isaac's is a property"
        if not prop and isinstance(raw, property):
            return False, f"{where} is a property; Isaac's is a method"
        if not prop and not _is_callable_member(raw):
            return False, f"{where} is a value; Isaac's is a method"
        return True, where
    fields = getattr(cls, "__dataclass_fields__", {})
    assigned = _init_attributes(cls)
    if name in fields or name in assigned:
        owner = assigned.get(name, cls)
        where = f"`{owner.__module__}.{owner.__qualname__}.{name}` (instance attribute)"
        return (True, where) if prop else (False, f"{where}; Isaac's is a method")
    return False, "missing"


def resolve_module(module: str, name: str, prop: bool) -> tuple[bool, str]:
    """(present, where) of function ``name`` of Isaac module ``module`` through the hook's table."""
    from ambulo.isaac import names

    target = names.MODULES.get(module, {}).get(name)
    if target is None:
        return False, "missing"
    ambulo_module, _, attr = target.partition(":")
    unsupported = _unsupported(importlib.import_module(ambulo_module))
    if name in unsupported:
        return False, f"not supported: {unsupported[name]}"
    return True, f"`{ambulo_module}.{attr}`"


def coverage(sections: list[dict] | None = None) -> list[dict]:
    """Per section: the Isaac name, the ambulo object it imports as, and a ``Row`` per member."""
    from ambulo.isaac import IsaacNameError, isaac_names

    result = []
    with isaac_names():
        for section in sections or load_members():
            module, attr = SECTIONS[section["section"]]
            isaac = module if attr is None else f"{module}.{attr}"
            try:
                obj = importlib.import_module(module)
                if attr is not None:
                    obj = getattr(obj, attr)
            except IsaacNameError as error:
                obj, ambulo = None, f"not importable: {error}"
            else:
                ambulo = (names_target(module) if attr is None else f"{obj.__module__}.{obj.__qualname__}")
            rows = []
            for m in section["members"]:
                if obj is None:
                    present, where = False, "missing"
                elif attr is None:
                    present, where = resolve_module(module, m["name"], m["prop"])
                else:
                    present, where = resolve_class(obj, m["name"], m["prop"])
                rows.append(Row(m["name"], m["star"], m["prop"], present, where))
            result.append({"section": section["section"], "isaac": isaac, "ambulo": ambulo, "rows": rows})
    return result


def names_target(module: str) -> str:
    """The ambulo modules an Isaac module's names come from."""
    from ambulo.isaac import names

    sources = sorted({t.partition(":")[0] for t in names.MODULES.get(module, {}).values()})
    return ", ".join(sources) or "nothing"


# -- the document ---------------------------------------------------------------------------
def _counts(rows: list[Row]) -> tuple[int, int, int]:
    present = sum(r.present for r in rows)
    unsupported = sum(r.where.startswith("not supported") for r in rows)
    return present, len(rows) - present, unsupported


def render(result: list[dict]) -> str:
    lines = [
        "# Isaac Sim API coverage",
        "",
        "Generated by `scripts/isaac_coverage.py` from `scripts/isaac_api_members.json` (Isaac Sim 5.x core",
        "API members from Isaac's public type stubs; `*` marks those tutorial users call most). Do not edit:",
        "run `.venv/bin/python scripts/isaac_coverage.py` after changing the API.",
        "",
        "A member is *present* when the Isaac name a script imports (through `ambulo run`'s module table)",
        "resolves it with the right kind (property or method). Signatures and behaviour are checked by",
        "tests, not here. *Not supported* members exist only to raise an error naming the alternative;",
        "they count as missing.",
        "",
        "## Summary",
        "",
        "| section | Isaac name | present | missing | of which not supported | `*` present | `*` missing |",
        "|---|---|---|---|---|---|---|",
    ]
    totals = [0, 0, 0, 0, 0]
    for s in result:
        present, missing, unsupported = _counts(s["rows"])
        s_present, s_missing, _ = _counts([r for r in s["rows"] if r.star])
        for i, v in enumerate((present, missing, unsupported, s_present, s_missing)):
            totals[i] += v
        lines.append(f"| {s['section']} | `{s['isaac']}` | {present} | {missing} | {unsupported} | "
                     f"{s_present} | {s_missing} |")
    lines.append("| **all** |  | {} | {} | {} | {} | {} |".format(*totals))
    for s in result:
        present, missing, _ = _counts(s["rows"])
        s_present, s_missing, _ = _counts([r for r in s["rows"] if r.star])
        lines += ["", f"## {s['section']}", "",
                  f"`{s['isaac']}` -> `{s['ambulo']}`: {present} of {len(s['rows'])} present "
                  f"(`*`: {s_present} of {s_present + s_missing}).", "",
                  "| Isaac member | present | ambulo |", "|---|---|---|"]
        for r in s["rows"]:
            label = ("\\*" if r.star else "") + r.name + (" (prop)" if r.prop else "")
            lines.append(f"| {label} | {'yes' if r.present else 'no'} | {r.where.replace('|', '/')} |")
    return "\n".join(lines) + "\n"


def missing_starred(result: list[dict]) -> list[str]:
    return [f"{s['section']}.{r.name}" for s in result for r in s["rows"] if r.star and not r.present]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--import", dest="research", type=Path,
                        help="regenerate scripts/isaac_api_members.json from the research table")
    parser.add_argument("--check", action="store_true", help="do not write; fail if the doc is stale")
    args = parser.parse_args(argv)
    if args.research is not None:
        MEMBERS_JSON.write_text(json.dumps(import_research(args.research), indent=1) + "\n")
        print(f"wrote {MEMBERS_JSON.relative_to(ROOT)}")
    result = coverage()
    text = render(result)
    status = 0
    if args.check:
        if not DOC.exists() or DOC.read_text() != text:
            print(f"{DOC.relative_to(ROOT)} is stale: run python scripts/isaac_coverage.py", file=sys.stderr)
            status = 1
    else:
        DOC.write_text(text)
        print(f"wrote {DOC.relative_to(ROOT)}")
    missing = missing_starred(result)
    if missing:
        print(f"{len(missing)} * members missing: {', '.join(missing)}", file=sys.stderr)
        status = 1
    return status


if __name__ == "__main__":
    sys.exit(main())
