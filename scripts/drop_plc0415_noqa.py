"""Drop the ``noqa: PLC0415`` directives: ruff does not run PLC0415 (import-outside-toplevel) here,
so each one is noise that ``ruff --select RUF100`` reports as unused (issue 23 item 6).

    python scripts/drop_plc0415_noqa.py           # rewrite src tests examples benchmarks scripts
    python scripts/drop_plc0415_noqa.py --check   # list them; exit 1 while any is left

What each comment becomes:
    import x  # noqa: PLC0415                   ->  import x
    import x  # noqa: PLC0415 - optional extra  ->  import x  # optional extra   (why it is lazy)
    import x  # noqa: F401, PLC0415             ->  import x  # noqa: F401       (other codes stay)

Only comment tokens are read and written (``tokenize``), so a string that spells a directive is
left alone, and a file is written only if its code tokens come out identical and it still compiles.
"""

from __future__ import annotations

import argparse
import io
import re
import sys
import tokenize
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
ROOTS = ("src", "tests", "examples", "benchmarks", "scripts")
CODE = "PLC0415"
# ruff's directive: "noqa", a colon, codes (upper-case letters then digits) split by commas or
# spaces, then free text (here often " - why the import is lazy")
DIRECTIVE = re.compile(r"#\s*(?i:noqa)\s*:\s*(?P<codes>[A-Z]+[0-9]+(?:[\s,]+[A-Z]+[0-9]+)*)(?P<rest>.*)")
REASON_LEAD = re.compile(r"^\s*[-:\u2013\u2014]?\s*")


def rewrite_comment(comment: str) -> str | None:
    """``comment`` (a COMMENT token, from ``#``) without ``PLC0415``; None if it has no such code."""
    match = DIRECTIVE.search(comment)
    if match is None:
        return None
    codes = [c for c in re.split(r"[\s,]+", match["codes"]) if c]
    if CODE not in codes:
        return None
    kept = [c for c in codes if c != CODE]
    before, rest = comment[: match.start()], match["rest"]
    if kept:
        return f"{before}# noqa: {', '.join(kept)}{rest}"
    reason = REASON_LEAD.sub("", rest, count=1).rstrip()
    return f"{before}# {reason}" if reason else before.rstrip()


def code_tokens(source: str) -> list[tuple[int, str]]:
    return [(t.type, t.string) for t in tokenize.generate_tokens(io.StringIO(source).readline)
            if t.type not in (tokenize.COMMENT, tokenize.NL)]


def rewrite_source(source: str) -> tuple[str, list[int]]:
    """``source`` without the directives, and the (1-based) lines it changed."""
    lines = source.splitlines(keepends=True)
    changed = []
    for token in tokenize.generate_tokens(io.StringIO(source).readline):
        if token.type != tokenize.COMMENT:
            continue
        new_comment = rewrite_comment(token.string)
        if new_comment is None:
            continue
        row, col = token.start
        line = lines[row - 1]
        body = line.rstrip("\r\n")
        ending = line[len(body):]
        code = body[:col]
        lines[row - 1] = (code + new_comment if new_comment else code.rstrip()) + ending
        changed.append(row)
    return "".join(lines), changed


def python_files(roots: list[Path]) -> list[Path]:
    files = []
    for root in roots:
        files += [root] if root.is_file() else sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts)
    return files


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("paths", nargs="*", type=Path, help=f"files or folders (default: {' '.join(ROOTS)})")
    parser.add_argument("--check", action="store_true", help="only list the directives; exit 1 if any")
    args = parser.parse_args(argv)
    roots = args.paths or [REPO / r for r in ROOTS if (REPO / r).exists()]

    total, files_changed = 0, 0
    for path in python_files(roots):
        source = path.read_bytes().decode("utf-8")  # as is: CRLF files stay CRLF
        if CODE not in source:
            continue
        new_source, rows = rewrite_source(source)
        if not rows:
            continue
        total += len(rows)
        files_changed += 1
        if args.check:
            print("\n".join(f"{path}:{row}" for row in rows))
            continue
        if code_tokens(new_source) != code_tokens(source):
            print(f"{path}: not rewritten, its code would change", file=sys.stderr)
            return 2
        compile(new_source, str(path), "exec")
        path.write_bytes(new_source.encode("utf-8"))

    verb = "found" if args.check else "removed"
    print(f"{verb} {total} noqa: {CODE} directive(s) in {files_changed} file(s)")
    return 1 if args.check and total else 0


if __name__ == "__main__":
    sys.exit(main())
