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
        (["identify", "--input", "u.csv", "--ts", "0.1"], "output is required when --input"),
        (["excite", "--signal", "prbs", "--clock-periods", "9000"], "--clock-periods 9000"),
        # Files a user may hand over by mistake, each refused in one line before anything runs.
        (["simulate", "--config", "dup.yaml"], "dup.yaml:2:1: duplicate key 'duration_s'"),
        (["simulate", "--config", "latin1.yaml"], "latin1.yaml: not UTF-8 text"),
        (["simulate", "--duration", "1e12"], "duration_s = 1000000000000.0: expected 0 to 86400"),
        (
            ["simulate", "--plant", "identified:u.csv"],
            "plant.model_file: u.csv: expected a mapping",
        ),
        (["excite", "--duration", "1e12"], "--duration 1000000000000.0: expected 0 to 86400"),
    ],
)
def test_the_cli_reports_a_user_error_as_one_line_naming_only_the_flags_given(
    tmp_path, capsys, monkeypatch, argv, message
):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "u.csv").write_text("1\n2\n")
    (tmp_path / "dup.yaml").write_text("duration_s: 10.0\nduration_s: 20.0\n")
    (tmp_path / "latin1.yaml").write_bytes("duration_s: 10.0 # café\n".encode("latin-1"))
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


def test_more_user_errors_are_one_line_and_name_what_was_given(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "a_file").write_text("")
    (tmp_path / "broken.yaml").write_text("cameras:\n  kinect_v1: [unclosed\n")
    (tmp_path / "model.yaml").write_text("- not a mapping\n")
    (tmp_path / "u.csv").write_text("\n".join(str(k % 7) for k in range(60)))
    (tmp_path / "y.csv").write_text("\n".join(str(k % 5) for k in range(60)))
    cases = [
        (["simulate", "--out", "a_file"], "a_file: expected a folder to write into"),
        (["simulate", "--config", "broken.yaml"], "broken.yaml:3:1: not valid YAML"),
        (["simulate", "--plant", "identified:model.yaml"], "model.yaml: expected a mapping"),
        (["identify", "--input", "u.csv", "--output", "y.csv", "--ts", "0.1", "--orders", "20"],
         "estimation selects"),
        (["excite", "--signal", "multisine", "--band", "0.01:0.02", "--duration", "2"],
         "contains no line of the grid"),
    ]  # fmt: skip
    for argv, message in cases:
        assert main(argv) == 2, argv
        error = capsys.readouterr().err
        assert error.count("\n") == 1 and message in error, (argv, error)
        named = {word for word in error.replace(",", " ").replace(")", " ").split()}
        assert {flag for flag in named if flag.startswith("--")} <= set(argv), error


def test_a_current_flag_is_checked_in_its_own_unit(capsys):
    with pytest.raises(SystemExit) as raised:
        main(["excite", "--amplitude", "-5"])
    assert raised.value.code == 2
    assert "argument --amplitude: '-5': expected a positive number" in capsys.readouterr().err


def test_the_workflow_names_no_seed_it_was_not_given(tmp_path, capsys):
    config = tmp_path / "bad.yaml"
    config.write_text("duration_s: -1.0\n")
    assert main(["workflow", "--config", str(config), "--out", str(tmp_path / "wf")]) == 2
    error = capsys.readouterr().err
    assert "bad.yaml: duration_s = -1.0" in error
    assert "seed" not in error and "overrides" not in error
