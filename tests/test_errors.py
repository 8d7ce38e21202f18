"""The error family: what a user can cause is a MasklessError naming it.

The CLI prints it as one line and exits 2, and anything else keeps its traceback.
"""

import pytest

import maskless
from maskless.diagrams.cli import main
from maskless.errors import ConfigError, MasklessError, MissingFileError, ModelError, RecordError


@pytest.mark.parametrize(
    "error, builtin",
    [
        (ConfigError, ValueError),
        (RecordError, ValueError),
        (ModelError, ValueError),
        (MissingFileError, FileNotFoundError),
    ],
)
def test_each_error_is_of_the_family_and_of_the_builtin_a_caller_expects(error, builtin):
    assert issubclass(error, MasklessError) and issubclass(error, builtin)
    assert getattr(maskless, error.__name__) is error


@pytest.mark.parametrize(
    "argv, message",
    [
        (["simulate", "--duration", "-3"], "command line (--duration)"),
        (["simulate", "--config", "no_such.yaml"], "config file not found: no_such.yaml"),
        (["identify", "--input", "no_such.csv", "--output", "y.csv", "--ts", "0.1"], "no_such.csv"),
        (["identify", "--input", "u.csv", "--ts", "0.1"], "--output is required"),
        (["excite", "--signal", "prbs", "--clock-periods", "9000"], "--clock-periods 9000"),
    ],
)
def test_the_cli_reports_a_user_error_as_one_line_naming_only_the_flags_given(
    tmp_path, capsys, monkeypatch, argv, message
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "u.csv").write_text("1\n2\n")
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and error.startswith(f"maskless {argv[0]}: error: ")
    assert message in error
    # Only the flags given are named: no other flag of the command appears.
    for flag in ("--seed", "--plant", "--controller", "--orders", "--amplitude"):
        assert flag in argv or flag not in error


def test_a_library_bug_keeps_its_traceback(monkeypatch):
    def broken(*args, **kwargs):
        raise KeyError("a bug, not a user's mistake")

    monkeypatch.setattr("maskless.diagrams.simulation.simulate_to_files", broken)
    monkeypatch.setattr("maskless.diagrams.commands.simulate.simulate_to_files", broken)
    with pytest.raises(KeyError, match="a bug"):
        main(["simulate", "--duration", "1"])
