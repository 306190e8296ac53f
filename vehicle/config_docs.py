"""Generate docs/config.md from the settings modules: ``python -m vehicle.config_docs [--check]``."""

from __future__ import annotations

import argparse
import ast
import sys
from pathlib import Path

from vehicle.config import constraints, describe_type, settings

DOC_PATH = Path(__file__).resolve().parent.parent / "docs" / "config.md"


def render() -> str:
    """The config reference as Markdown, one table per section, module by module in file order."""
    out = ["# Configuration reference", "",
           "Every setting a car can override in its `myconfig.py`, with its type and default. Generated "
           "by `python -m vehicle.config_docs` from the `settings.py` beside each part family (each "
           "section names its file); do not edit by hand.",
           "",
           "A value shown as an expression (for example `DRIVE_LOOP_HZ`) is derived: it follows the "
           "settings it names, after your overrides, unless you set it yourself. Loading rejects an "
           "unknown name (suggesting the closest one), a value of the wrong type, a value outside "
           "the range in the Valid column, and settings that contradict each other (a PWM pulse "
           "outside 500-2500 µs at PWM_FREQ, two parts on one channel, a watchdog shorter than two "
           "loops); the error names the file, the line, the setting and what is valid.", ""]
    section = None
    for s in settings().values():
        if s.section != section:
            section = s.section
            where = f"{s.module.replace('.', '/')}.py"
            out += ["", f"## {section}", "", f"Declared in `{where}`.", "",
                    "| Setting | Type | Default | Valid | Meaning |", "|---|---|---|---|---|"]
        default = ast.unparse(s.expression).replace("|", "\\|")
        kind = describe_type(s.annotation).replace("|", "&#124;")
        valid = "; ".join(c.describe() for c in constraints(s.name)).replace("|", "\\|")
        out.append(f"| `{s.name}` | `{kind}` | `{default}` | {valid} | {s.doc} |")
    return "\n".join(out).replace("\n\n\n", "\n\n") + "\n"


def main(argv: list[str] | None = None) -> int:
    """Write docs/config.md, or with --check exit 1 if it is out of date."""
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--check", action="store_true", help="only check that the file is current")
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        current = DOC_PATH.read_text() if DOC_PATH.exists() else ""
        if current != text:
            print(f"{DOC_PATH} is out of date: run python -m vehicle.config_docs", file=sys.stderr)  # noqa: T201
            return 1
        return 0
    DOC_PATH.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
