"""The README's Python example runs exactly as printed, and gives the figures the command gives."""

import json
import re
from pathlib import Path

from maskless.diagrams.cli import main

README = Path(__file__).resolve().parents[1] / "README.md"


def readme_python_examples() -> list[str]:
    """Every Python block of the README, in order; they run one after another."""
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_the_python_example_gives_the_metrics_of_maskless_simulate(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    namespace = {}
    for example in readme_python_examples():
        exec(compile(example, str(README), "exec"), namespace)  # noqa: S102
    run = namespace["run"]
    # The sweep block wrote each head into the one loop it built.
    assert namespace["swept"].scenario is run.scenario
    assert (tmp_path / "out" / "run.mcap").is_file() and (tmp_path / "out" / "run.png").is_file()
    # The rendered-cameras block found the face in its first frame and drew the frames.
    assert namespace["first"].valid and (tmp_path / "out" / "frames.png").is_file()
    capsys.readouterr()

    scenario = run.scenario
    flags = ["--duration", repr(scenario.duration_s), "--seed", str(scenario.random_seed)]
    assert main(["simulate", *flags, "--out", str(tmp_path / "cli"), "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    del printed["timing"], printed["files"]  # the machine's figures and the paths, not the run's
    assert printed == json.loads(json.dumps(run.metrics))
    # The same seed gives the same recording, message for message.
    cli_recording = (tmp_path / "cli" / "run.mcap").read_bytes()
    assert (tmp_path / "out" / "run.mcap").read_bytes() == cli_recording


def test_every_public_name_resolves_and_import_stays_cheap():
    import subprocess
    import sys

    import maskless

    assert all(getattr(maskless, name) is not None for name in maskless.__all__)
    # `import maskless` loads no Drake diagram code until a name is used.
    code = "import sys, maskless; print(any(m.startswith('pydrake') for m in sys.modules))"
    fresh = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert fresh.stdout.strip() == "False"
