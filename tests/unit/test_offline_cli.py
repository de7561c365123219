"""The offline tools' shared option parsing (`ft_core.offline.cli`) against empty values.

An option that takes a list refuses an empty value with a usage error (exit status 2,
one line naming the option), never a traceback nor the option's default; an output
file that cannot be written is refused before any tracing (exit status 1).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import pytest
from ft_core.offline import bounds, cli, placement, planning, swing_workspace

#: (tool's main, arguments, the option named in the usage error).
EMPTY = [
    (bounds.main, ["--robot", "panda", "--points", ""], "--points"),
    (bounds.main, ["--robot", "panda", "--points", ";"], "--points"),
    (bounds.main, ["--robot", "panda", "--seed", " , "], "--seed"),
    (planning.main, ["--points", "", "--start", "0.1,0.2,0.3", "--rates", "0.01"], "--points"),
    (planning.main, ["--points", "1,0.5", "--start", "", "--rates", "0.01"], "--start"),
    (planning.main, ["--points", "1,0.5", "--start", "0.1,0.2,0.3", "--rates", ""], "--rates"),
    (swing_workspace.main, ["--joints", ""], "--joints"),
    (swing_workspace.main, ["--point", ""], "--point"),
    (swing_workspace.main, ["--gravity", ""], "--gravity"),
    (placement.main, ["--robot", "planar3r", "--x", "1", "--y", "0", "--suggest", ";"],
     "--suggest"),
    (placement.main, ["--robot", "planar3r", "--x", "1", "--y", "0", "--joints", ""],
     "--joints"),
]


@pytest.mark.parametrize(("main", "argv", "option"), EMPTY,
                         ids=[f"{m.__module__.split('.')[-1]}{a[-1]!r}{o}" for m, a, o in EMPTY])
def test_an_empty_list_value_is_a_usage_error(main, argv, option, tmp_path, capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        main([*argv, "--out" if main is planning.main or main is swing_workspace.main
              else "-o", str(tmp_path / "out")])
    assert stop.value.code == 2
    error = capsys.readouterr().err
    assert f"argument {option}: no number in" in error
    assert "Traceback" not in error
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("text", ["", " ", ";", ",", " ; , "])
def test_nonempty_refuses_text_without_a_value(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        cli.nonempty(text)


@pytest.mark.parametrize("text", ["0", "1,2;", " 0.5 "])
def test_nonempty_passes_text_with_a_value_unchanged(text: str) -> None:
    assert cli.nonempty(text) == text


def test_bounds_refuses_an_unwritable_output_before_the_tracing(tmp_path, capsys,
                                                                 monkeypatch) -> None:
    def trace(*args, **kwargs):
        raise AssertionError("traced before the output was checked")

    monkeypatch.setattr(bounds.selfmotion, "critical_boxes", trace)
    for output, words in [(tmp_path, "is a folder"), (tmp_path / "no" / "x.yaml", "no such"),
                          (Path("/proc/x"), "/proc/x")]:
        assert bounds.main(["--robot", "panda", "--points", "0.5,0.1,0.4",
                            "-o", str(output)]) == 1
        error = capsys.readouterr().err
        assert error.startswith("ft-bounds: ") and words in error, error
        assert error.count("\n") == 1


def test_check_file_leaves_an_existing_file_and_no_new_one(tmp_path) -> None:
    existing = tmp_path / "kept.yaml"
    existing.write_text("content")
    cli.check_file(existing)
    assert existing.read_text() == "content"
    cli.check_file(tmp_path / "new.yaml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept.yaml"]
