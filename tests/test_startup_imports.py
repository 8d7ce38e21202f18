"""What `maskless identify` loads before and while it fits a CSV record, and the lazy public names.

The identify command reads CSV, fits and plots: Drake, the MCAP stack (mcap, protobuf and the
Foxglove schemas) and OpenCV are for other commands and other records, so its start-up must not
pay for them. Each check runs in a fresh interpreter, whose ``sys.modules`` starts empty.
"""

import importlib
import json
import os
import subprocess
import sys

import numpy as np
import pytest

import maskless
import maskless.recording

# Libraries a CSV identification never uses (the plots import matplotlib in their own function).
UNUSED_BY_CSV_IDENTIFY = ("pydrake", "mcap", "google.protobuf", "foxglove", "cv2")
# Printed by the fresh interpreter after the code under test: which of the libraries it loaded.
_LOADED = (
    "import json, sys; "
    "print(json.dumps([name for name in {libraries!r} "
    "if any(m == name or m.startswith(name + '.') for m in sys.modules)]))"
)


def loaded_by(code: str, libraries=(*UNUSED_BY_CSV_IDENTIFY, "matplotlib")) -> list[str]:
    """Which of ``libraries`` ``code`` loads in a fresh interpreter."""
    listing = _LOADED.format(libraries=list(libraries))
    done = subprocess.run(
        [sys.executable, "-c", f"{code}\n{listing}"], capture_output=True, text=True, check=True
    )
    return json.loads(done.stdout.splitlines()[-1])


@pytest.fixture(scope="module")
def loaded_by_identify_import():
    return loaded_by("import maskless.diagrams.commands.identify")


@pytest.mark.parametrize("library", [*UNUSED_BY_CSV_IDENTIFY, "matplotlib"])
def test_importing_the_identify_command_loads_no_unused_library(loaded_by_identify_import, library):
    assert library not in loaded_by_identify_import


def test_the_identify_command_module_loads_no_estimator():
    # Its plotting worker is forked before the estimators are imported, so that matplotlib's
    # import overlaps scipy's: the module the command starts from must not import scipy.
    assert loaded_by("import maskless.diagrams.commands.identify", ("scipy",)) == []


def test_the_plotting_worker_needs_no_estimator():
    # What it is sent (the plot functions and their curves) unpickles without scipy.
    code = "import maskless.analysis.identification.fit_plots"
    assert loaded_by(code, ("scipy", "pydrake")) == []


def identify_code(folder, out, *flags) -> str:
    """Code that runs `maskless identify` on a small CSV record written to ``folder``."""
    rng = np.random.default_rng(0)
    u = rng.standard_normal(400)
    y = np.convolve(u, [0.0, 0.5, 0.3])[: u.size] + 0.1 * rng.standard_normal(u.size)
    np.savetxt(folder / "u.csv", u)
    np.savetxt(folder / "y.csv", y)
    argv = ["identify", "--input", str(folder / "u.csv"), "--output", str(folder / "y.csv")]
    argv += ["--ts", "0.1", "--out", str(out), *flags]
    return f"from maskless.diagrams.cli import main\nassert main({argv!r}) == 0"


def test_a_whole_csv_identification_loads_none_of_them(tmp_path):
    loaded = loaded_by(identify_code(tmp_path, tmp_path / "out"))
    assert (tmp_path / "out" / "report.json").is_file()
    # Where fork is unsafe the plots are drawn in this process: matplotlib is then expected.
    assert not set(loaded) & set(UNUSED_BY_CSV_IDENTIFY)


def test_an_unplotted_csv_identification_loads_no_plotting_and_no_slow_scipy(tmp_path):
    # scipy.signal (it imports scipy.stats) and scipy.stats took 0.7-0.9 s of the command's
    # second; matplotlib is the plots' alone. Unplotted, the earlier run's plots are removed.
    out = tmp_path / "out"
    out.mkdir()
    (out / "record.png").write_bytes(b"an earlier run's plot")
    libraries = (*UNUSED_BY_CSV_IDENTIFY, "matplotlib", "scipy.signal", "scipy.stats")
    assert loaded_by(identify_code(tmp_path, out, "--no-plots"), libraries) == []
    report = json.loads((out / "report.json").read_text())
    assert report["plots"] == [] and not list(out.glob("*.png"))
    assert report["removed_stale_files"] == ["record.png"]
    assert (out / "model_pem_order2.yaml").is_file()


_BLAS_THREADS_AT_NUMPY_LOAD = (
    "import os, sys\n"
    "import maskless.diagrams.cli\n"
    "assert 'numpy' not in sys.modules, 'numpy loaded before the CLI could set its threads'\n"
    "print(os.environ.get('OPENBLAS_NUM_THREADS'))"
)


@pytest.mark.parametrize(("given", "expected"), [(None, "1"), ("2", "2")])
def test_the_cli_runs_blas_on_one_thread_unless_the_user_chose(given, expected):
    # OpenBLAS reads the variable when numpy loads: the CLI's module must set it before any
    # import of numpy, and leave a value the user set.
    environment = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if given is not None:
        environment["OPENBLAS_NUM_THREADS"] = given
    done = subprocess.run(
        [sys.executable, "-c", _BLAS_THREADS_AT_NUMPY_LOAD],
        capture_output=True,
        text=True,
        check=True,
        env=environment,
    )
    assert done.stdout.split() == [expected]


@pytest.mark.parametrize("name", maskless.__all__)
def test_every_public_name_of_the_package_imports(name):
    namespace = {}
    exec(f"from maskless import {name}", namespace)
    defining_module = importlib.import_module(maskless._EXPORTS[name])
    assert namespace[name] is getattr(defining_module, name)


# The recording package's public names: its __all__ and those re-exported "as" themselves.
RECORDING_NAMES = [
    *maskless.recording.__all__,
    "RecordingWriter",
    "write_recording_batches",
    "is_sensor_name",
]


@pytest.mark.parametrize("name", RECORDING_NAMES)
def test_every_public_name_of_the_recording_package_imports(name):
    namespace = {}
    exec(f"from maskless.recording import {name}", namespace)
    submodules = ("format", "encoding", "reading", "writing")
    defining = [importlib.import_module(f"maskless.recording.{s}") for s in submodules]
    defining.append(importlib.import_module("maskless.sensor_names"))
    assert any(namespace[name] is getattr(module, name, None) for module in defining)
    assert name in dir(maskless.recording)


def test_an_unknown_name_is_an_attribute_error_naming_it():
    with pytest.raises(AttributeError, match="no attribute 'read_recordings'"):
        maskless.recording.read_recordings  # noqa: B018
    with pytest.raises(ImportError, match="simulat"):
        exec("from maskless import simulat", {})
