"""Write settings into a car's ``myconfig.py`` without disturbing the rest of the file.

An existing top-level assignment of a name is replaced in place (its trailing comment kept); a
commented-out line ``# NAME = ...`` (as in DonkeyCar's generated myconfig) is replaced by the live
assignment at that spot; any other name is appended in one block at the end. The result is parsed
before it replaces the file, and the file is replaced atomically.
"""

from __future__ import annotations

import ast
import datetime
import os
import re
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

#: settings written in hexadecimal
HEX_SETTINGS = frozenset({"PCA9685_I2C_ADDR"})


def format_value(name: str, value: Any) -> str:
    """The Python literal for ``value`` (addresses in hex)."""
    if name in HEX_SETTINGS and isinstance(value, int):
        return f"0x{value:02X}"
    text = repr(value)
    try:
        ast.literal_eval(text)
    except (ValueError, SyntaxError):
        raise ValueError(f"{name} = {value!r} cannot be written as a Python literal") from None
    return text


def update_myconfig(path: str | os.PathLike[str], values: Mapping[str, Any], *,
                    header: str = "vehicle calibrate") -> list[str]:
    """Set ``values`` in the config file at ``path``; returns a line per change, for the user.

    Raises:
        FileNotFoundError: ``path`` does not exist.
        ValueError: a name is not an UPPERCASE identifier, or the file is not valid Python.
    """
    path = Path(path)
    source = path.read_text()
    try:
        tree = ast.parse(source, filename=str(path))
    except SyntaxError as exc:
        raise ValueError(f"{path}, line {exc.lineno}: not valid Python ({exc.msg}); fix it first") from exc
    lines = source.splitlines(keepends=True)
    replacements: dict[int, tuple[int, str]] = {}  # first line index -> (last line index, new text)
    appended: list[str] = []
    report: list[str] = []
    for name, value in values.items():
        if not re.fullmatch(r"[A-Z][A-Z0-9_]*", name):
            raise ValueError(f"{name!r} is not a setting name (UPPERCASE)")
        text = f"{name} = {format_value(name, value)}"
        nodes = [n for n in tree.body if _assigns(n, name)]
        if nodes:
            for node in nodes:
                last = lines[node.end_lineno - 1]
                comment = _trailing_comment(last, node.end_col_offset)
                replacements[node.lineno - 1] = (node.end_lineno - 1, f"{text}{comment}\n")
            report.append(f"{text}  (replaced line {nodes[-1].lineno})")
            continue
        pattern = re.compile(rf"^#\s*{name}\s*(:[^=]*)?=")
        hit = next((i for i, ln in enumerate(lines) if pattern.match(ln) and i not in replacements), None)
        if hit is not None:
            replacements[hit] = (hit, f"{text}\n")
            report.append(f"{text}  (uncommented line {hit + 1})")
        else:
            appended.append(f"{text}\n")
            report.append(f"{text}  (added)")
    out: list[str] = []
    i = 0
    while i < len(lines):
        if i in replacements:
            end, new = replacements[i]
            out.append(new)
            i = end + 1
        else:
            out.append(lines[i])
            i += 1
    if appended:
        if out and not out[-1].endswith("\n"):
            out[-1] += "\n"
        stamp = datetime.datetime.now().strftime("%Y-%m-%d %H:%M")
        out.append(f"\n# Written by {header} on {stamp}\n")
        out.extend(appended)
    result = "".join(out)
    ast.parse(result, filename=str(path))  # never leave a broken config behind
    _atomic_write(path, result)
    return report


def _assigns(node: ast.stmt, name: str) -> bool:
    if isinstance(node, ast.Assign):
        return any(isinstance(t, ast.Name) and t.id == name for t in node.targets)
    return isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name) and node.target.id == name


def _trailing_comment(line: str, end_col: int | None) -> str:
    # ast column offsets count UTF-8 bytes
    rest = line.encode()[end_col:].decode(errors="replace").strip() if end_col is not None else ""
    return f"  {rest}" if rest.startswith("#") else ""


def _atomic_write(path: Path, text: str) -> None:
    mode = path.stat().st_mode & 0o777
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, mode)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
