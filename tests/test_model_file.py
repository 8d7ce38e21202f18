"""Model files: units in the file (mm, mA) load into SI; every defect is one line naming it."""

import time

import numpy as np
import pytest
import yaml
from identification_records import simulate_record
from two_input_records import simulate_two_inputs

from maskless.analysis.identification.model_file import (
    load_identified_model,
    load_input_models,
    model_file_contents,
)
from maskless.analysis.identification.report import Part, fit
from maskless.errors import ModelError


def test_a_mm_per_ma_model_loads_into_si(tmp_path):
    u, y, _, _ = simulate_record(2, "white", 3000)
    fitted = fit("pem", Part("estimation", u, y), 2, 0.048)
    contents = model_file_contents(
        fitted,
        input_unit="mA",
        output_unit="mm",
        input_offset=81.3,
        output_offset=692.4,
        detrend="mean",
        trend_slopes_per_sample=None,
        verdict="The input explains the output: ...",
    )
    path = tmp_path / "model.yaml"
    path.write_text(yaml.safe_dump(contents))
    model = load_identified_model(path)
    # 1 mm/mA is 1e-3 m / 1e-3 A: B keeps its digits; the offsets and the variance become SI.
    np.testing.assert_allclose(model.B, fitted.model.B)
    np.testing.assert_allclose(model.K, fitted.model.K)
    assert model.operating_output == pytest.approx(0.6924)
    assert model.operating_input == pytest.approx(0.0813)
    assert (model.input_unit, model.output_unit) == ("A", "m")
    assert model.dc_gain() == pytest.approx(fitted.model.dc_gain())
    assert contents["innovations_variance"] == fitted.model.innovations_variance
    assert model.innovations_variance == pytest.approx(1e-6 * fitted.model.innovations_variance)


def test_mixed_units_scale_b_and_unknown_units_are_refused(tmp_path):
    contents = {
        "A": [[0.5, 1.0], [0.0, 0.0]],
        "B": [[2.0], [1.0]],
        "C": [[1.0, 0.0]],
        "D": [[0.0]],
        "K": [[0.1], [0.0]],
        "sample_period_s": 0.1,
        "input": {"unit": "A", "offset": 0.08},
        "output": {"unit": "mm", "offset": 700.0},
    }
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(contents))
    np.testing.assert_allclose(load_identified_model(path).B, [[2e-3], [1e-3]])  # mm/A -> m/A
    contents["input"]["unit"] = "psi"
    path.write_text(yaml.safe_dump(contents))
    with pytest.raises(ModelError, match="m.yaml"):
        load_identified_model(path)
    contents["input"]["unit"] = "A"
    contents["B"] = [[2.0]]
    path.write_text(yaml.safe_dump(contents))
    with pytest.raises(ModelError, match=r"m.yaml: B must have shape \(2, 1\)"):
        load_identified_model(path)


GOOD_MODEL = """\
A: [[0.9, 0.0], [0.0, 0.5]]
B: [[1.0], [1.0]]
C: [[1.0, 0.0]]
D: [[0.0]]
K: [[0.1], [0.0]]
sample_period_s: 0.048
input: {unit: mA, offset: 80.0}
output: {unit: mm, offset: 700.0}
innovations_variance: 0.01
stable: true
"""
# Nine levels of nine aliases: 387 million entries of A once expanded.
ALIAS_BOMB = "".join(
    f"l{i}: &l{i} [{','.join(['*l' + str(i - 1) if i else '1.0'] * 9)}]\n" for i in range(9)
)


def replaced(line_start, new_line):
    """GOOD_MODEL with its line beginning ``line_start`` replaced."""
    lines = [new_line if line.startswith(line_start) else line for line in GOOD_MODEL.split("\n")]
    return "\n".join(lines)


@pytest.mark.parametrize(
    "text, message",
    [
        ("A: [[0.9, 0.0]\n", r"not valid YAML"),
        ("", r"expected a mapping of A, B, .*got NoneType"),
        ("- 1\n- 2\n", r"expected a mapping .*got list"),
        (replaced("B:", ""), r"missing field 'B'"),
        (replaced("output:", "output: {unit: psi, offset: 700.0}"), r"'output\.unit' = 'psi'"),
        (replaced("output:", "output: 700.0"), r"field 'output' = 700\.0: expected a mapping"),
        (replaced("input:", "input: {unit: mA, offset: x}"), r"'input\.offset' = 'x'"),
        (replaced("C:", "C: [[1.0]]"), r"C must have shape \(1, 2\)"),
        (replaced("A:", "A: [[0.9, 0.0], [0.0]]"), r"field 'A': rows of different lengths"),
        (replaced("D:", "D: [[.nan]]"), r"field 'D': expected finite numbers"),
        (replaced("K:", "K: [[.inf], [0.0]]"), r"field 'K': expected finite numbers"),
        (replaced("innovations_variance:", "innovations_variance: [1]"), "innovations_variance"),
        (replaced("sample_period_s:", "sample_period_s: 1.0e+300"), r"sample_period_s = 1e\+300"),
        (replaced("sample_period_s:", "sample_period_s: 0"), r"sample_period_s = 0: expected"),
        (replaced("A:", "A: [[1.5, 0.0], [0.0, 0.5]]"), r"'stable' = true, but .* 1\.5"),
        (replaced("stable:", "stable: maybe"), r"'stable' = 'maybe'"),
        (replaced("input:", "input: {unit: mA, offset: 80.0}\ninput: {unit: A}"), "duplicate"),
        (ALIAS_BOMB + replaced("A:", "A: *l8"), "anchors and aliases"),
    ],
)
def test_a_defective_model_file_is_one_line_naming_file_and_field(tmp_path, text, message):
    path = tmp_path / "model_bad.yaml"
    path.write_text(text)
    start = time.perf_counter()
    with pytest.raises(ModelError, match=message) as raised:
        load_identified_model(path)
    assert time.perf_counter() - start < 0.5
    assert str(raised.value).startswith(str(path)) and "\n" not in str(raised.value)


@pytest.mark.parametrize("contents", [bytes(range(256)), "A: café\n".encode("latin-1")])
def test_a_binary_or_non_utf8_model_file_is_refused(tmp_path, contents):
    path = tmp_path / "model.yaml"
    path.write_bytes(contents)
    with pytest.raises(ModelError, match=r"model\.yaml: not UTF-8 text"):
        load_identified_model(path)


# --- Hammerstein model files -----------------------------------------------------------------


def _hammerstein_in_mm_ma():
    from maskless.systems.hammerstein_model import HammersteinModel
    from maskless.systems.plant.valve_map import ValveMap

    a = np.poly([0.9, 0.5])[1:]
    return HammersteinModel(
        maps=(ValveMap([60.0, 100.0, 165.0], [0.0, 0.3, 1.0]), ValveMap([55.0, 150.0], [0, 1])),
        a=[a, a],
        b=[[2.0, 1.0], [-0.3, -0.1]],
        input_delay_samples=2,
        operating_output=210.0,
        sample_period_s=0.0667,
        input_unit="mA",
        output_unit="mm",
    )


def test_a_hammerstein_file_loads_as_one_model_in_si(tmp_path):
    from maskless.analysis.identification.model_file import hammerstein_file_contents
    from maskless.systems.hammerstein_model import HammersteinModel

    written = _hammerstein_in_mm_ma()
    path = tmp_path / "hammerstein.yaml"
    path.write_text(yaml.safe_dump(hammerstein_file_contents(written, verdict="explains")))
    loaded = load_identified_model(path)
    assert isinstance(loaded, HammersteinModel)
    assert (loaded.input_unit, loaded.output_unit) == ("A", "m")
    np.testing.assert_allclose(loaded.maps[0].currents, [0.060, 0.100, 0.165])
    assert loaded.operating_output == pytest.approx(0.210)
    # The same experiment in SI gives the same output in m.
    u_ma = np.column_stack([np.linspace(0, 190, 300), np.linspace(190, 0, 300)])
    np.testing.assert_allclose(loaded.simulate(u_ma * 1e-3), written.simulate(u_ma) * 1e-3)
    assert loaded.input_delay_samples == 2


@pytest.mark.parametrize(
    "edit, message",
    [
        (
            lambda c: c["valves"]["inlet"].update(openings=[0.0, 0.5, 0.4]),
            r"valves\.inlet.*monotone",
        ),
        (lambda c: c["valves"]["inlet"].update(currents=[60.0, 50.0, 165.0]), "increasing knots"),
        (lambda c: c["valves"]["outlet"].update(currents=[55.0, "x"]), r"valves\.outlet\.currents"),
        (lambda c: c.update(valves={"outlet": c["valves"]["outlet"]}), "inlet and outlet"),
        (lambda c: c.update(b=[[2.0, 1.0]]), r"b must have shape \(2, 2\)"),
        (lambda c: c.update(a=[[0.1, float("nan")], [0.1, 0.2]]), "'a': expected finite"),
        (lambda c: c["input"].update(unit="mm"), "expected a current"),
        (lambda c: c["output"].pop("offset"), r"missing field 'output\.offset'"),
        (lambda c: c.update(stable=False), "'stable' = false"),
        (lambda c: c.update(input_delay_samples=0), "input_delay_samples = 0"),
    ],
)
def test_a_defective_hammerstein_file_is_one_line_naming_the_field(tmp_path, edit, message):
    from maskless.analysis.identification.model_file import hammerstein_file_contents

    contents = hammerstein_file_contents(_hammerstein_in_mm_ma(), verdict="explains")
    edit(contents)
    path = tmp_path / "h.yaml"
    path.write_text(yaml.safe_dump(contents))
    with pytest.raises(ModelError, match=message) as raised:
        load_identified_model(path)
    assert "h.yaml" in str(raised.value) and "\n" not in str(raised.value)


def two_input_contents():
    """A two-input model file's mapping, written as `maskless identify` writes one."""
    u, y = simulate_two_inputs(2000, seed=0)
    fitted = fit("pem", Part("estimation", u, y), 2, 0.048, input_names=("inlet", "outlet"))
    contents = model_file_contents(
        fitted,
        input_unit=("mA", "A"),
        output_unit="mm",
        input_offset=(80.0, 0.09),
        output_offset=692.4,
        detrend="mean",
        trend_slopes_per_sample=None,
        verdict="The input explains the output: ...",
    )
    return fitted, contents


def test_a_two_input_file_holds_b_per_input_and_loads_as_a_model_per_input(tmp_path):
    fitted, contents = two_input_contents()
    assert np.array(contents["B"]).shape == (2, 2) and np.array(contents["D"]).shape == (1, 2)
    assert [entry["name"] for entry in contents["inputs"]] == ["inlet", "outlet"]
    assert "input" not in contents
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(contents, sort_keys=False))
    inlet, outlet = load_input_models(path)
    # Each column scales by (output unit in SI) / (its input unit in SI): mm/mA keeps its digits,
    # mm/A is 1e-3 of them.
    np.testing.assert_allclose(inlet.B[:, 0], fitted.polynomials.b[:, 0])
    np.testing.assert_allclose(outlet.B[:, 0], 1e-3 * fitted.polynomials.b[:, 1])
    assert (inlet.operating_input, outlet.operating_input) == pytest.approx((0.08, 0.09))
    assert inlet.operating_output == pytest.approx(0.6924)
    np.testing.assert_array_equal(inlet.A, outlet.A)
    # The designs and plants drive one input: the file is refused in one line naming it.
    with pytest.raises(ModelError) as refused:
        load_identified_model(path)
    message = str(refused.value)
    assert "\n" not in message and str(path) in message
    assert "a model of 2 inputs (inlet, outlet)" in message
    # A single-input file still loads unchanged, and as one model per input.
    u, y, _, _ = simulate_record(2, "white", 3000)
    single = model_file_contents(
        fit("pem", Part("estimation", u, y), 2, 0.048),
        input_unit="mA",
        output_unit="mm",
        input_offset=81.3,
        output_offset=692.4,
        detrend="mean",
        trend_slopes_per_sample=None,
        verdict="...",
    )
    path.write_text(yaml.safe_dump(single))
    (only,) = load_input_models(path)
    np.testing.assert_array_equal(only.B, load_identified_model(path).B)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda c: c["inputs"].pop(), "expected a list of two or more mappings"),
        (lambda c: [row.pop() for row in c["B"]], r"field 'B' has shape \(2, 1\)"),
        (lambda c: c["D"][0].append(0.0), r"field 'D' has shape \(1, 3\)"),
        (lambda c: c.update(input={"unit": "A", "offset": 0.0}), "'input' and 'inputs' both"),
        (lambda c: c["inputs"][1].update(unit="psi"), r"inputs\[1\]\): field 'input.unit'"),
        (lambda c: c["inputs"][0].pop("offset"), r"inputs\[0\]\): missing field 'input.offset'"),
    ],
)
def test_a_defective_two_input_file_is_one_line_naming_the_field(tmp_path, change, message):
    _, contents = two_input_contents()
    change(contents)
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(contents))
    with pytest.raises(ModelError, match=message) as refused:
        load_input_models(path)
    assert "\n" not in str(refused.value) and str(path) in str(refused.value)
