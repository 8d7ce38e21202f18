"""Diagnostics and the report of several inputs: per input, and whether the inputs separate.

References: planted truths. Inputs built as linear functions of each other must be named as
inseparable, independent ones not; an input clipped at its maximum is named, the other not; an
input with no effect in the planted system contributes nothing in the report.
"""

import numpy as np
import pytest
import two_input_records
from two_input_records import simulate_two_inputs

from maskless.analysis.identification.data_diagnostics import diagnose_record
from maskless.analysis.identification.input_diagnostics import (
    SHARED_VARIANCE_LIMIT,
    diagnose_inputs,
    separation,
)
from maskless.analysis.identification.report import Part, identify

NAMES = ("inlet", "outlet")


def _report(u, y, method="pem"):
    split = y.size * 6 // 10
    return identify(
        method,
        Part("estimation", u[:split], y[:split]),
        Part("validation", u[split:], y[split:]),
        [2],
        1.0,
        input_names=NAMES,
    )


def test_independent_inputs_separate_and_a_delayed_copy_does_not():
    rng = np.random.default_rng(0)
    independent = rng.standard_normal((3000, 2))
    found = separation(independent, 4)
    assert max(found.shared_variance) < 0.05
    assert found.joint_order == found.needed_order == 8
    # The outlet is the inlet one sample later: within the window it is the inlet exactly.
    command = rng.standard_normal(3000)
    delayed = np.column_stack([command, np.r_[0.0, command[:-1]]])
    found = separation(delayed, 4)
    assert min(found.shared_variance) > 0.999
    assert found.joint_order < found.needed_order


def test_a_common_drive_is_named_as_inputs_that_cannot_be_told_apart():
    rng = np.random.default_rng(1)
    command = rng.standard_normal(3000)
    common = np.column_stack([command, -command + 0.1 * rng.standard_normal(3000)])
    u, y = simulate_two_inputs(3000, seed=1, inputs=common)
    report, _ = _report(u, y)
    separated = report["diagnostics"]["separation"]
    assert min(separated["shared_variance"].values()) > SHARED_VARIANCE_LIMIT
    assert any("the inputs cannot be told apart" in w for w in report["warnings"])
    assert "cannot be told apart" in report["verdict"]
    # Independent inputs on the same system raise no such warning.
    u, y = simulate_two_inputs(3000, seed=1)
    report, _ = _report(u, y)
    assert not any("told apart" in w for w in report["warnings"])


def test_clipping_and_excitation_are_judged_per_input():
    rng = np.random.default_rng(2)
    u = rng.standard_normal((3000, 2))
    u[:, 1] = np.clip(u[:, 1], None, 0.5)  # the outlet saturates; ~31 % of its samples at 0.5
    u, y = simulate_two_inputs(3000, seed=2, inputs=u)
    records = tuple(diagnose_record(column, y, "mean", ("A", "m")) for column in u.T)
    poles = {2: np.array(two_input_records.POLES, complex)}
    found = diagnose_inputs(u[:1800] - u.mean(axis=0), poles, NAMES, records)
    assert [d.record.clipping.clipped_at for d in found.per_input] == [(), ("maximum",)]
    clipped = [w for w in found.warnings if "clipped" in w]
    assert len(clipped) == 1 and clipped[0].startswith("the input outlet is clipped")
    # An outlet that holds still but for one pulse is too poor an excitation; the inlet is not.
    poor = rng.standard_normal((3000, 2))
    poor[:, 1] = 0.0
    poor[100:110, 1] = 1.0
    found = diagnose_inputs(poor[:1800], poles, NAMES)
    too_poor = [w for w in found.warnings if "too poor an excitation" in w]
    assert len(too_poor) == 1 and too_poor[0].startswith("the input outlet is too poor")
    with pytest.raises(ValueError, match="expected 2 each"):
        diagnose_inputs(poor[:1800], poles, ("inlet",))


@pytest.mark.parametrize("method", ["pem", "n4sid", "arx", "armax"])
def test_an_input_without_effect_contributes_nothing(method, monkeypatch):
    # Planted: the outlet's numerator is zero, so the output owes it nothing.
    monkeypatch.setattr(two_input_records, "NUMERATORS", ([0.5, 0.3], [0.0, 0.0]))
    u, y = two_input_records.simulate_two_inputs(3000, seed=3)
    report, fitted = _report(u, y, method)
    entry = report["models"][0]
    contributions = entry["input_contributions"]["validation"]
    assert abs(contributions["outlet"]["fit_points_lost_without"]) < 1.0
    assert contributions["outlet"]["output_variance_share"] < 0.01
    assert contributions["inlet"]["fit_points_lost_without"] > 50.0
    # The inlet alone is the whole model's simulation; without it only the outlet is left.
    assert contributions["inlet"]["fit_percent_sim_alone"] == pytest.approx(
        entry["validation"]["fit_percent_sim"], abs=1.0
    )
    assert contributions["inlet"]["dc_gain"] == pytest.approx(
        two_input_records.true_dc_gains()[0], rel=0.1
    )
    assert entry["dc_gain"] == [c["dc_gain"] for c in contributions.values()]
    assert np.array(entry["B"]).shape == (2, 2) and np.array(entry["D"]).shape == (1, 2)
    assert entry["input_names"] == list(NAMES)
    assert fitted[0].model is None and len(fitted[0].input_models) == 2
