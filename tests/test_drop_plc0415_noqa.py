"""scripts/drop_plc0415_noqa.py removes only the PLC0415 code: a reason stays as a plain comment,
other codes stay as a directive, a string that spells a directive and the code itself are untouched.
"""

from __future__ import annotations

from script_loader import ROOT, load_script

drop = load_script(ROOT / "scripts" / "drop_plc0415_noqa.py")

BEFORE = '''\
def f():
    import a  # noqa: PLC0415
    import b  # noqa: PLC0415 - optional extra
    import c  # noqa: F401, PLC0415
    import d  # noqa:PLC0415, N812 - rename kept
    import e  # note  # noqa: PLC0415
    text = "import x  # noqa: PLC0415"  # noqa: F401
    return text  # noqa: PLC04150
'''

AFTER = '''\
def f():
    import a
    import b  # optional extra
    import c  # noqa: F401
    import d  # noqa: N812 - rename kept
    import e  # note
    text = "import x  # noqa: PLC0415"  # noqa: F401
    return text  # noqa: PLC04150
'''


def test_each_form_of_the_directive(tmp_path):
    source = tmp_path / "pkg" / "module.py"
    source.parent.mkdir()
    source.write_text(BEFORE)
    (tmp_path / "clean.py").write_text("import os  # noqa: F401\n")

    assert drop.main(["--check", str(tmp_path)]) == 1
    assert source.read_text() == BEFORE  # --check writes nothing
    assert drop.main([str(tmp_path)]) == 0
    assert source.read_text() == AFTER
    assert (tmp_path / "clean.py").read_text() == "import os  # noqa: F401\n"
    assert drop.main(["--check", str(tmp_path)]) == 0


def test_crlf_line_endings_survive(tmp_path):
    source = tmp_path / "m.py"
    source.write_bytes(b"def f():\r\n    import a  # noqa: PLC0415\r\n    return a\r\n")
    assert drop.main([str(source)]) == 0
    assert source.read_bytes() == b"def f():\r\n    import a\r\n    return a\r\n"
