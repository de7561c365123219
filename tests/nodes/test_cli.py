"""The command-line tools against careless and hostile arguments (issue 31 items 7 and 8).

Every number a tool takes is bounded where it comes in (`ft_core.offline.cli.bounded`):
a structural check finds any that is not, and a property-based one feeds every bounded
option boundary values (NaN, infinities, 1e308, negative, huge integers, words) and
checks that it is refused with a usage error or taken inside its bounds. Then the
command lines that printed tracebacks, hung or answered wrongly, each refused with one
clear line and a non-zero exit status, before any long computation.
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path

import pytest
from ft_core.offline import (
    batch,
    bounds,
    design,
    fault_tolerant_workspace,
    placement,
    planning,
    swing_workspace,
)
from ft_sim import campaign, demo
from fuzzing import examples
from hypothesis import given, settings
from hypothesis import strategies as st
from models import chain_urdf

#: Each tool's parser and the arguments it needs besides the one tried.
PARSERS: dict[str, tuple[Callable[[], argparse.ArgumentParser], list[str]]] = {
    "ft-bounds": (bounds.parser, []),
    "ft-plan": (planning.parser, ["--points", "1,0.5", "--start", "0,0,0", "--rates", "0.1"]),
    "ft-map": (placement._parser, []),
    "ft-design dh": (design._parser, ["dh", "-o", "x.json"]),
    "ft-design r7": (design._parser, ["r7", "-o", "x.json"]),
    "ft-design redundant": (design._parser, ["redundant", "-o", "x.json", "--m", "3",
                                             "--probabilities", "0.1,0.2,0.3,0.4"]),
    "ft-design multicase": (design._parser, ["multicase", "-o", "x.json"]),
    "ft-design global": (design._parser, ["global", "-o", "x.json"]),
    "ft-demo": (demo.parser, []),
    "ft-campaign": (campaign.parser, []),
    "ft-swing": (swing_workspace.parser, []),
    "ft-map fault-tolerant-workspace": (fault_tolerant_workspace.parser, []),
}


def _actions(tool: str) -> list[argparse.Action]:
    """The options of `tool` (a design subcommand's own and its parents')."""
    make, base = PARSERS[tool]
    parser = make()
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            parser = action.choices[base[0]]
    return [a for a in parser._actions if a.option_strings]


def test_every_batch_tool_takes_the_same_execution_options() -> None:
    """Issue 33: `--workers` and `--cluster` (`ft_core.offline.batch`), nothing else."""
    batch_tools = ["ft-plan", "ft-map", "ft-design dh", "ft-design multicase", "ft-design global",
                   "ft-campaign"]
    for tool in PARSERS:
        options = {o for a in _actions(tool) for o in a.option_strings}
        assert ({"--workers", "--cluster"} <= options) == (tool in batch_tools), tool
        assert not {"--jobs", "-j"} & options, tool
    make, base = PARSERS["ft-campaign"]
    args = make().parse_args([*base, "--cluster", "tcp://10.0.0.2:8786", "--workers", "3"])
    assert batch.Where.from_arguments(args) == batch.Where(3, "tcp://10.0.0.2:8786")


BOUNDED = [(tool, action.option_strings[-1]) for tool in PARSERS for action in _actions(tool)
           if hasattr(action.type, "bounds")]
BOUNDARY = ["nan", "inf", "-inf", "1e308", "-1e308", "-1", "0", "1e-12", "1e12",
            str(2**64), "12abc", "", "0x10"]


def test_every_number_a_tool_takes_is_bounded() -> None:
    unbounded = [(tool, a.option_strings[-1]) for tool in PARSERS for a in _actions(tool)
                 if a.type in (int, float)]
    assert unbounded == []
    assert len(BOUNDED) >= 20  # the check looks at the real parsers


@settings(max_examples=examples(400), deadline=None)
@given(st.sampled_from(BOUNDED),
       st.one_of(st.sampled_from(BOUNDARY), st.floats().map(repr),
                 st.integers(-2**70, 2**70).map(str)))
def test_boundary_values_are_refused_or_taken_inside_their_bounds(option: tuple[str, str],
                                                                   text: str) -> None:
    tool, flag = option
    make, base = PARSERS[tool]
    try:
        args = make().parse_args([*base, f"{flag}={text}"])
    except SystemExit as stop:
        assert stop.code == 2
        return
    action = next(a for a in _actions(tool) if flag in a.option_strings)
    low, high = action.type.bounds
    value = getattr(args, action.dest)
    assert low <= value <= high, (tool, flag, text, value)


def _one_joint(tmp: Path) -> str:
    urdf = tmp / "one.urdf"
    urdf.write_text(chain_urdf("z", name="one"))
    return str(urdf)


#: (tool's main, arguments, exit status, words of its message); "{tmp}" is a temporary
#: folder, "{file}" a file in it, "{fifo}" a FIFO, "{one}" a URDF with a single joint.
REFUSED = [
    (bounds.main, ["--robot", "planar3r", "--task", "planar", "--points", "1,0.5", "--step",
                   "inf"], 2, "outside"),
    (bounds.main, ["--robot", "planar3r", "--task", "planar", "--points", "1e308,0.5"], 1,
     "further than 1000 m"),
    (bounds.main, ["--robot", "{one}"], 1, "cannot follow"),
    (planning.main, ["--points", "1,0.5;0.5,1", "--start", "0,0,0", "--rates", "0.01",
                     "--out", "{file}"], 1, "is a file"),
    (planning.main, ["--points", "1,0.5;0.5,1", "--start", "0,0,0", "--rates", "1e308"], 1,
     "rates must be"),
    (planning.main, ["--points", "1,0.5;0.5,1", "--start", "1e308,0,0", "--rates", "0.01"],
     1, "outside its limits"),
    (planning.main, ["--points", "1,0.5;0.5,1", "--start", "0,0,0", "--rates", "0.01",
                     "--monte-carlo", "1000000000000"], 2, "outside"),
    (planning.main, ["--points", "1,0.5;0.5,1", "--start", "0,0,0", "--rates", "0.01",
                     "--speed", "1e308"], 2, "outside"),
    (placement.main, ["--robot", "planar3r", "--task", "planar", "--x", "1e308", "--y", "0"],
     1, "within"),
    (placement.main, ["--robot", "planar3r", "--task", "planar", "--x", "0:1:1000000000",
                      "--y", "0"], 1, "count"),
    (placement.main, ["--robot", "panda", "--task", "pose", "--x", "0.5", "--y", "0", "--z",
                      "0.5", "--orientation", "1e308,0,0,1e308"], 1, "norm finite"),
    (placement.main, ["--robot", "{one}", "--x", "0.5", "--y", "0", "--z", "0"], 1,
     "cannot follow"),
    (design.main, ["redundant", "-o", "{tmp}/x.json", "--m", "3", "--probabilities",
                   ",".join(["0.1"] * 10000)], 2, "at most 4096"),
    (design.main, ["redundant", "-o", "{tmp}/x.json", "--m", "3", "--probabilities",
                   ",".join(["0.1"] * 100)], 2, "1 to 64"),
    (design.main, ["r7", "-o", "{tmp}/x.json", "--restarts", "1000000000"], 2, "outside"),
    (placement.main, ["--robot", "planar3r", "--task", "planar", "--x", "1", "--y", "0",
                      "-o", "{file}/map"], 1, "is a file"),
    (design.main, ["multicase", "-o", "{tmp}/x.json", "--step", "1e-9"], 2, "outside"),
    (design.main, ["r7", "-o", "{file}/x.json"], 1, "is a file"),
    (design.main, ["dh", "-o", "{tmp}/x.json", "--jacobian", "{fifo}"], 1,
     "not a regular file"),
    (demo.main, ["--seed", "-1"], 2, "outside"),
    (demo.main, ["--duration", "1e308"], 2, "outside"),
    (demo.main, ["--out", "{file}"], 1, "is a file"),
    (demo.main, ["--robot", "{one}"], 2, "cannot follow"),
    (campaign.main, ["--robot", "{one}", "--runs", "1"], 2, "no redundancy for a campaign"),
    (campaign.main, ["--runs", "-1"], 2, "outside"),
]


@pytest.mark.parametrize(("main", "argv", "status", "words"), REFUSED,
                         ids=[f"{m.__module__.split('.')[-1]}-{k}"
                              for k, (m, *_rest) in enumerate(REFUSED)])
def test_careless_command_lines_get_one_clear_line_and_a_failure_status(
        main: Callable[[list[str]], int], argv: list[str], status: int, words: str,
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "file").write_text("in the way\n")
    os.mkfifo(tmp_path / "fifo")  # reading it would hang
    argv = [a.format(tmp=tmp_path, file=tmp_path / "file", fifo=tmp_path / "fifo",
                     one=_one_joint(tmp_path)) for a in argv]
    if "--out" not in argv and main in (planning.main, demo.main, campaign.main):
        argv += ["--out", str(tmp_path / "out")]
    if "-o" not in argv and main in (bounds.main, placement.main):
        argv += ["-o", str(tmp_path / "out")]
    try:
        code = main(argv)
    except SystemExit as stop:
        code = stop.code
    err = capsys.readouterr().err
    assert code == status, err
    assert words in err and "Traceback" not in err, err
