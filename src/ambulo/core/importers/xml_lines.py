"""XML with the line number of every element, so errors point into the user's file.

``xml.etree.ElementTree`` forgets where elements were, and re-serializing a tree (to hand
MuJoCo an edited URDF) drops comments and reflows lines, so MuJoCo's "line N" no longer
matches the file the user opens. ``parse_with_lines`` records each element's line with
expat (stdlib); ``serialize_with_lines`` writes one start tag per line and returns which
element each output line holds, so a line MuJoCo reports maps back to the user's line.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from xml.parsers import expat

from .asset_errors import AssetError


def parse_with_lines(file: Path, kind: str = "XML") -> tuple[ET.Element, dict[ET.Element, int]]:
    """The root element of ``file`` and the 1-based line of each element's start tag."""
    builder = ET.TreeBuilder()
    parser = expat.ParserCreate()
    parser.buffer_text = True
    lines: dict[ET.Element, int] = {}

    def start(tag: str, attrs: dict[str, str]) -> None:
        lines[builder.start(tag, attrs)] = parser.CurrentLineNumber

    parser.StartElementHandler = start
    parser.EndElementHandler = builder.end
    parser.CharacterDataHandler = builder.data
    try:
        with open(file, "rb") as f:
            parser.ParseFile(f)
        root = builder.close()
    except expat.ExpatError as err:
        raise AssetError(
            f"{file}:{err.lineno}:{err.offset + 1}: malformed {kind} "
            f"({expat.errors.messages[err.code]}); fix the file or re-export it.") from None
    return root, lines


def serialize_with_lines(root: ET.Element) -> tuple[str, dict[int, ET.Element]]:
    """``root`` as text with one start tag per line, and the element starting on each line.

    Changes ``root``'s whitespace: text and tails become indentation; a newline inside an
    element's text becomes a space (URDF text is never read by MuJoCo)."""
    for elem in root.iter():
        if elem.text and "\n" in elem.text and elem.text.strip():
            elem.text = " ".join(elem.text.split())
    ET.indent(root)
    text = ET.tostring(root, encoding="unicode")
    elements = iter(root.iter())
    by_line: dict[int, ET.Element] = {}
    for number, line in enumerate(text.split("\n"), start=1):
        stripped = line.lstrip()
        if stripped.startswith("<") and not stripped.startswith("</"):
            by_line[number] = next(elements)
    return text, by_line


def describe(elem: ET.Element) -> str:
    """``<joint name="elbow">``: how an error names an element."""
    name = elem.get("name") or elem.get("link") or elem.get("filename")
    key = "name" if elem.get("name") else "link" if elem.get("link") else "filename"
    return f'<{elem.tag} {key}="{name}">' if name else f"<{elem.tag}>"
