"""Write the nodes' parameter tables into docs/*.md from the parameter declarations.

A page asks for a node's table with two marker comments; everything between them
is generated::

    <!-- parameters: ft_controller.controller_node -->
    ...
    <!-- parameters: end -->

The rows come from what the node module declares: its module-level `PARAMETERS`
table (name -> `ft_msgs_py.parameter_table.Setting`, from its package's `settings.py`),
the one it passes to `parameter_table.declare`. Importing a node module does not start
ROS, and neither does this script.

Usage (from the repository root)::

    .venv/bin/python tools/param_tables.py --write   # regenerate the tables
    .venv/bin/python tools/param_tables.py --check   # exit 1 with a diff if stale

`tests/nodes/test_docs.py` runs the check.
"""

from __future__ import annotations

import argparse
import difflib
import importlib
import re
import sys
from pathlib import Path

from ft_msgs_py.parameter_table import Setting
from rclpy.parameter import Parameter

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
#: The node modules whose parameters must be documented somewhere in docs/.
NODES = (
    "ft_controller.controller_node",
    "ft_monitor.monitor_node",
    "ft_sim.sim_node",
    "ft_sim.fault_injector_node",
)
COMMAND = ".venv/bin/python tools/param_tables.py --write"
BEGIN = re.compile(r"^<!-- parameters: (?!end -->)([\w.]+) -->\n", re.MULTILINE)
END = "<!-- parameters: end -->\n"

_TYPE_NAMES = {
    Parameter.Type.BOOL: "bool",
    Parameter.Type.INTEGER: "integer",
    Parameter.Type.DOUBLE: "double",
    Parameter.Type.STRING: "string",
    Parameter.Type.BYTE_ARRAY: "byte[]",
    Parameter.Type.BOOL_ARRAY: "bool[]",
    Parameter.Type.INTEGER_ARRAY: "integer[]",
    Parameter.Type.DOUBLE_ARRAY: "double[]",
    Parameter.Type.STRING_ARRAY: "string[]",
}


def declared_parameters(module_name: str) -> dict[str, Setting]:
    """The parameters a node module declares.

    Args:
        module_name: a node module, such as `ft_sim.sim_node`.

    Returns:
        name -> `Setting`, in declaration order: the module's `PARAMETERS`.

    Raises:
        LookupError: the module has no `PARAMETERS`.
    """
    module = importlib.import_module(module_name)
    if not hasattr(module, "PARAMETERS"):
        raise LookupError(f"{module_name} declares no module-level PARAMETERS")
    return dict(module.PARAMETERS)


def _default(default: object) -> str:
    if isinstance(default, Parameter.Type):
        return "`[]`"
    if isinstance(default, bool):
        return f"`{str(default).lower()}`"
    if isinstance(default, str):
        return f'`"{default}"`'
    if isinstance(default, list):
        return "`[" + ", ".join(_number(v) for v in default) + "]`"
    return f"`{_number(default)}`"


def _number(value: object) -> str:
    return f"{value:g}" if isinstance(value, float) else str(value)


def _range(setting: Setting) -> str:
    return setting.constraints() if setting.bounds is not None or setting.choices else ""


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def table(declared: dict[str, Setting]) -> str:
    """A Markdown table of declared parameters.

    Args:
        declared: name -> `Setting`.

    Returns:
        The table, one row per parameter in declaration order, ending in a newline.
    """
    lines = ["| parameter | type | default | allowed | at run time | description |",
             "|---|---|---|---|---|---|"]
    for name, setting in declared.items():
        changeable = "read-only" if setting.read_only else "settable"
        lines.append(f"| `{name}` | {_TYPE_NAMES[setting.type]} | {_default(setting.default)} | "
                     f"{_cell(_range(setting))} | {changeable} | {_cell(setting.description)} |")
    return "\n".join(lines) + "\n"


def render(text: str) -> str:
    """A page's text with every marked table regenerated.

    Args:
        text: a Markdown page.

    Returns:
        The page with the text between each pair of markers replaced.

    Raises:
        ValueError: a begin marker without its end marker.
    """
    out, position = [], 0
    for match in BEGIN.finditer(text):
        if match.start() < position:
            raise ValueError(f"nested parameter markers at {match.group(0).strip()}")
        end = text.find(END, match.end())
        if end < 0:
            raise ValueError(f"{match.group(0).strip()} has no {END.strip()}")
        out += [text[position:match.end()], table(declared_parameters(match.group(1)))]
        position = end
    out.append(text[position:])
    return "".join(out)


def documented_nodes(pages: list[Path]) -> set[str]:
    """The node modules whose tables the pages ask for."""
    return {m.group(1) for page in pages for m in BEGIN.finditer(page.read_text())}


def stale(pages: list[Path]) -> dict[Path, str]:
    """Pages whose tables are not current, with a unified diff for each."""
    diffs = {}
    for page in pages:
        text = page.read_text()
        fresh = render(text)
        if fresh != text:
            diffs[page] = "".join(difflib.unified_diff(
                text.splitlines(keepends=True), fresh.splitlines(keepends=True),
                f"{page.relative_to(REPO)} (committed)", f"{page.relative_to(REPO)} (generated)"))
    return diffs


def main(argv: list[str] | None = None) -> int:
    """Regenerate (`--write`) or check (`--check`) the tables of docs/*.md."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--write", action="store_true", help="rewrite stale tables")
    mode.add_argument("--check", action="store_true", help="exit 1 if a table is stale")
    args = parser.parse_args(argv)
    pages = sorted(DOCS.glob("*.md"))
    missing = set(NODES) - documented_nodes(pages)
    if missing:
        print(f"no page in docs/ has a parameter table for {sorted(missing)}", file=sys.stderr)
        return 1
    diffs = stale(pages)
    for page, diff in diffs.items():
        if args.write:
            page.write_text(render(page.read_text()))
            print(f"rewrote {page.relative_to(REPO)}")
        else:
            sys.stdout.write(diff)
    if args.check and diffs:
        print(f"parameter tables are stale; regenerate with: {COMMAND}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
