"""Model files: units in the file (mm, mA) load into SI, and unknown units are refused."""

import numpy as np
import pytest
import yaml
from identification_records import simulate_record

from maskless.analysis.identification.model_file import load_identified_model, model_file_contents
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
