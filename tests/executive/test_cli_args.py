"""Bad command-line values are argparse's error line and exit status 2, never a traceback."""
from __future__ import annotations

import pytest

from hearth.cli.main import build_parser, main


def refused(argv, capsys) -> str:
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "Traceback" not in err
    return err.strip().splitlines()[-1]


@pytest.mark.parametrize("value", ["0", "-5", "nan", "inf", "1e9", "fast"])
@pytest.mark.parametrize("command", ["run", "step", "record", "serve"])
def test_a_bad_tick_rate_is_one_error_line(command, value, capsys, tmp_path):
    argv = {"run": ["run", "m.yaml"], "step": ["step", "m.yaml"],
            "record": ["record", "m.yaml", "--out", str(tmp_path / "rec")], "serve": ["serve"]}
    line = refused(argv[command] + ["--tick-hz", value], capsys)
    assert line == (f"hearth {command}: error: argument --tick-hz: the tick rate must be a "
                    f"number >= 0.1 and <= 1000, got {value!r}")


def test_a_negative_seed_is_one_error_line(capsys, tmp_path):
    line = refused(["scenario", "make", "--seed", "-1", "--out", str(tmp_path / "s")], capsys)
    assert line == ("hearth scenario make: error: argument --seed: a seed must be an integer "
                    "from 0 to 4294967295, got '-1'")


def test_an_output_directory_that_is_a_file_is_one_error_line(capsys, tmp_path):
    f = tmp_path / "taken"
    f.write_text("x")
    line = refused(["scenario", "make", "--out", str(f)], capsys)
    assert line == f"hearth scenario make: error: argument --out: '{f}' exists and is not a directory"
    line = refused(["record", "m.yaml", "--out", str(f)], capsys)
    assert line.endswith(f"'{f}' exists and is not a directory")


@pytest.mark.parametrize("argv, option", [
    (["step", "m.yaml", "--ticks", "-1"], "--ticks"),
    (["serve", "--port", "70000"], "--port"),
    (["serve", "--approval-timeout", "nan"], "--approval-timeout"),
    (["demo", "--seed", "2e3"], "--seed"),
])
def test_other_numbers_out_of_range_are_one_error_line(argv, option, capsys):
    assert f"error: argument {option}:" in refused(argv, capsys)


def test_good_values_parse(tmp_path):
    args = build_parser().parse_args(["run", "m.yaml", "--tick-hz", "25"])
    assert args.tick_hz == 25.0
    args = build_parser().parse_args(["scenario", "make", "--seed", "7", "--out", str(tmp_path)])
    assert (args.seed, args.out) == (7, str(tmp_path))
