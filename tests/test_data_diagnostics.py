"""Data diagnostics: each fires where planted and stays silent on a clean record.

The pure functions are checked against independent references (closed forms, numpy); then, through
`maskless identify`, one test per failure issue 14 names (no word on a three-pulse input's
excitation, no hint on offset and drift, an integrator not named, a constant output, a
temperature plotted in "mm"), each of which fails on the code before the diagnostics.
"""

import json

import numpy as np
import pytest
import scipy.signal
import scipy.stats
from identification_records import PAPER_DATA, paper_record

import maskless
from maskless.analysis.identification import data_diagnostics as dd
from maskless.analysis.identification.fit_plots import plot_compare, plot_record
from maskless.analysis.identification.part_curves import part_curves
from maskless.diagrams.cli import main
from maskless.diagrams.identification_run import (
    IdentificationRequest,
    format_identification_report,
    identify_record,
)
from maskless.errors import ConfigError, RecordError

SAMPLES = 2000
TS = 0.1
# The clean record's system: poles 0.9 and 0.7, as tests/identification_records.py's order 2.
B, A = [0.0, 0.5, 0.3], np.poly([0.9, 0.7])


def respond(u, seed=1, noise_std=0.1):
    """The clean system's output to ``u`` plus white measurement noise."""
    rng = np.random.default_rng(seed)
    return scipy.signal.lfilter(B, A, u) + noise_std * rng.standard_normal(u.size)


def clean_record(seed=0):
    """White input, stable order-2 response, white noise: nothing for a diagnostic to find."""
    u = np.random.default_rng(seed).standard_normal(SAMPLES)
    return u, respond(u, seed + 1)


def three_pulses(samples=SAMPLES, width=5):
    """Zero but for three short unit pulses."""
    u = np.zeros(samples)
    for start in (300, 900, 1500):
        u[start : start + width] = 1.0
    return u


# --- the pure functions against independent references ---


def test_a_sum_of_k_sinusoids_excites_exactly_2k_directions():
    # A sinusoid obeys a second-order recursion exactly, so k of them span 2k directions.
    k = np.arange(SAMPLES)
    one = np.sin(2 * np.pi * 0.05 * k)
    two = one + np.sin(2 * np.pi * 0.13 * k + 0.4)
    assert dd.excitation(one, [2]).order == 2
    assert dd.excitation(two, [4]).order == 4
    assert dd.excitation(one, [2]).too_poor_for_orders == (2,)
    assert dd.excitation(two, [2]).too_poor_for_orders == ()  # 4 = 2 x order 2
    assert dd.excitation(two, [2, 4]).too_poor_for_orders == (4,)


@pytest.mark.parametrize("name", ["white noise", "PRBS", "the authors' input"])
def test_rich_inputs_excite_every_direction_in_every_stretch(name):
    rng = np.random.default_rng(2)
    if name == "white noise":
        u = rng.standard_normal(SAMPLES)
    elif name == "PRBS":  # bits held 10 samples
        u = np.repeat(np.sign(rng.standard_normal(SAMPLES // 10)), 10)
    else:
        u = paper_record()[0][:11782]
    excited = dd.excitation(u, [2, 4])
    assert (excited.order, excited.tested_order) == (8, 8)
    assert excited.persistent_stretches == excited.stretches == dd.EXCITATION_STRETCHES
    assert excited.too_poor_for_orders == ()


@pytest.mark.parametrize("name", ["three pulses", "one step"])
def test_transient_excitation_is_named_too_poor(name):
    u = three_pulses() if name == "three pulses" else (np.arange(SAMPLES) >= 1100) * 1.0
    excited = dd.excitation(u, [2])
    # Only the stretches holding a pulse (or the step) excite anything.
    assert excited.persistent_stretches == (3 if name == "three pulses" else 1)
    assert excited.too_poor_for_orders == (2,)


@pytest.mark.parametrize("samples", [3, 4, 50, SAMPLES])
def test_trend_matches_scipy_linregress(samples):
    # trend fits its line with numpy (scipy.stats is slow to import); linregress is the reference.
    rng = np.random.default_rng(3)
    k = np.arange(samples)
    signal = 40.0 + 0.002 * k + rng.standard_normal(samples)
    line = scipy.stats.linregress(k, signal)
    residual = signal - (line.intercept + line.slope * k)
    lag_1 = np.dot(residual[1:], residual[:-1]) / np.dot(residual, residual)
    widened = line.stderr * np.sqrt((1 + lag_1) / (1 - lag_1))
    found = dd.trend(signal)
    assert found.slope_per_sample == pytest.approx(line.slope, rel=1e-9)
    assert found.drift_share == pytest.approx(line.rvalue**2, rel=1e-9)
    assert found.slope_t_statistic == pytest.approx(line.slope / widened, rel=1e-9)
    assert found.offset_share == pytest.approx(signal.mean() ** 2 / np.mean(signal**2))


def test_trend_of_two_samples_is_the_line_through_them():
    found = dd.trend(np.array([1.0, 3.0]))
    assert found.slope_per_sample == pytest.approx(2.0)
    assert found.drift_share == pytest.approx(1.0)
    assert found.slope_t_statistic == np.inf


def test_a_slow_stable_process_wanders_but_does_not_drift():
    # Pole 0.995 (a 200-sample time constant) driven by white noise: over 3000 samples a line
    # fits more than a quarter of its wandering, but its slope is within the wandering's own
    # spread once the residuals' correlation is counted.
    u = np.random.default_rng(1).standard_normal(3000)
    slow = dd.trend(scipy.signal.lfilter([0.0, 1.0], [1.0, -0.995], u))
    assert slow.drift_share > dd.DRIFT_SHARE and not slow.drifts
    planted = dd.trend(scipy.signal.lfilter(B, A, u) + 0.003 * np.arange(3000))
    assert planted.drift_share > dd.DRIFT_SHARE and planted.drifts


def test_longest_hold_finds_the_planted_stretch():
    signal = np.random.default_rng(4).standard_normal(SAMPLES)
    signal[700:950] = 2.5
    assert dd.longest_hold(signal) == dd.Hold(2.5, 700, 250, 250 / SAMPLES)


def test_clipping_needs_a_pile_up_at_a_limit():
    rng = np.random.default_rng(5)
    noise = rng.standard_normal(SAMPLES)
    clipped = np.clip(noise, -5.0, 1.0)  # about 16 % above one sigma
    found = dd.clipping(clipped)
    assert found.share_at_maximum == pytest.approx(np.mean(noise >= 1.0))
    assert found.clipped_at == ("maximum",)
    assert dd.clipping(noise).clipped_at == ()
    # Two- and four-level signals sit at their extremes by design.
    prbs = np.repeat(np.sign(rng.standard_normal(SAMPLES // 10)), 10)
    assert dd.clipping(prbs).clipped_at == ()
    assert dd.clipping(rng.integers(0, 4, SAMPLES).astype(float)).clipped_at == ()


def test_integrators_are_the_poles_near_one():
    poles = {2: np.array([0.9996, 0.5]), 3: np.array([0.995 + 0.005j, 0.995 - 0.005j, -0.9999])}
    (found,) = dd.integrators(poles, 100_000)
    assert (found.order, found.pole) == (2, (0.9996, 0.0))
    assert found.distance_to_1 == pytest.approx(4e-4)
    assert found.threshold == dd.INTEGRATOR_POLE_DISTANCE
    # On 400 samples a time constant of 100 samples (|1 - p| = 0.01) spans a quarter of the part.
    assert dd.integrator_distance(400) == pytest.approx(0.01)
    assert [i.order for i in dd.integrators(poles, 399)] == [2, 3, 3]


def test_a_constant_signal_is_refused_naming_it_and_its_source():
    # Constant up to rounding: 0.1 + 0.2 and 0.3 differ in the last bit.
    rounding = np.where(np.arange(SAMPLES) % 2 == 0, 0.1 + 0.2, 0.3)
    assert np.ptp(rounding) > 0
    with pytest.raises(RecordError, match=r"^temp\.csv: the output is constant \(0\.3 over"):
        dd.refuse_constant(rounding, "output", "temp.csv")
    dd.refuse_constant(0.3 + 1e-6 * np.arange(SAMPLES), "output", "temp.csv")  # varies: fine


def test_a_signal_varying_by_rounding_of_its_companions_spread_is_constant():
    # A closed loop's outlet: never opened, but for one sample of 1.4e-17 A (rounding of a
    # difference of currents), while the inlet spans 53 mA. Against its own size it varies by
    # all of it; against the inlet's spread, by nothing.
    outlet = np.zeros(SAMPLES)
    outlet[0] = 1.4e-17
    assert not dd.is_constant(outlet)
    assert dd.is_constant(outlet, scale=0.053)
    assert not dd.is_constant(1e-6 * np.arange(SAMPLES), scale=0.053)  # a micro-amp ramp moves
    with pytest.raises(
        RecordError,
        match=r"^run\.mcap: the outlet is constant \(it varies by 1\.4e-17 over 2000 samples: "
        r"rounding, beside the 0\.053 A the widest input spans\)",
    ):
        dd.refuse_constant(outlet, "outlet", "run.mcap", "A", scale=0.053)


def test_a_clean_record_raises_no_warning():
    u, y = clean_record()
    run = maskless.identify(u, y, TS, order=2)
    diagnostics = run.report["diagnostics"]
    assert diagnostics["warnings"] == [] and run.report["warnings"] == []
    assert diagnostics["record"]["suggested_detrend"] is None
    assert diagnostics["excitation"]["too_poor_for_orders"] == []
    assert diagnostics["integrators"] == []


# --- one test per failure issue 14 names, through `maskless identify` ---


def test_three_short_pulses_are_named_too_poor_for_the_order():
    u = three_pulses()
    run = maskless.identify(u, respond(u), TS, order=2)
    (warning,) = run.report["diagnostics"]["warnings"]
    assert warning.startswith("the input is too poor an excitation for order 2")
    assert warning in run.report["warnings"]
    assert "Warning: the input is too poor" in run.report["verdict"]
    assert "TOO POOR for order 2" in format_identification_report(run.report, "out")


def test_offset_and_drift_suggest_the_linear_detrend_that_recovers_the_fit():
    u, y = clean_record()
    drifting = y + 500.0 + 0.01 * np.arange(SAMPLES)
    by_mean = maskless.identify(u, drifting, TS, order=2, detrend="mean")
    record = by_mean.report["diagnostics"]["record"]
    assert record["suggested_detrend"] == "linear"
    (warning,) = by_mean.report["diagnostics"]["warnings"]
    assert warning.startswith("the output drifts") and "use --detrend linear" in warning
    assert "suggested --detrend linear" in format_identification_report(by_mean.report, "out")
    # The suggestion is right: the linear detrend recovers the simulation fit.
    by_line = maskless.identify(u, drifting, TS, order=2, detrend="linear")
    assert by_line.report["diagnostics"]["warnings"] == []
    fits = [run.report["models"][0]["validation"]["fit_percent_sim"] for run in (by_mean, by_line)]
    assert fits[1] > 90.0 > fits[0] + 50.0
    # With --detrend none the offset alone is named, with the mean as its remedy.
    offset_only = maskless.identify(u, y + 500.0, TS, order=2, detrend="none")
    assert offset_only.report["diagnostics"]["record"]["suggested_detrend"] == "mean"


def test_an_integrating_process_is_named_with_the_advice():
    u = np.random.default_rng(6).standard_normal(SAMPLES)
    y = scipy.signal.lfilter([0.0, 0.05], [1.0, -0.9996], u) + 0.1 * np.random.default_rng(
        7
    ).standard_normal(SAMPLES)
    run = maskless.identify(u, y, TS, order=1)
    (integrator,) = run.report["diagnostics"]["integrators"]
    assert integrator["distance_to_1"] < integrator["threshold"]
    warning = next(w for w in run.report["warnings"] if "looks integrating" in w)
    assert "Δy(k) = y(k) - y(k-1)" in warning
    assert "integrators: order 1 pole 0.99" in format_identification_report(run.report, "o")


def test_a_constant_output_is_a_one_line_refusal_naming_the_output_and_file(tmp_path, capsys):
    u = np.random.default_rng(8).standard_normal(SAMPLES)
    # A constant temperature whose last digit wobbles with the arithmetic that produced it.
    y = np.where(np.arange(SAMPLES) % 3 == 0, 0.1 + 0.2, 0.3) * 70
    np.savetxt(tmp_path / "u.csv", u)
    np.savetxt(tmp_path / "temp.csv", y, fmt="%.17g")
    args = ["identify", "--input", str(tmp_path / "u.csv"), "--output", str(tmp_path / "temp.csv")]
    assert main([*args, "--ts", "1", "--out", str(tmp_path / "out")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"{tmp_path / 'temp.csv'}: the output is constant" in line
    # The input likewise.
    with pytest.raises(RecordError, match=r"^u: the input is constant"):
        maskless.identify(np.full(SAMPLES, 3.0), y + np.arange(SAMPLES), TS)


def test_a_stuck_output_is_reported():
    u, y = clean_record()
    y[900:1100] = y[900]  # a frozen sensor for 10 % of the record
    run = maskless.identify(u, y, TS, order=2)
    hold = run.report["diagnostics"]["record"]["output_hold"]
    assert (hold["start"], hold["samples"]) == (900, 200)
    assert any(w.startswith("the output is stuck at") for w in run.report["warnings"])


def test_a_temperature_record_is_plotted_and_reported_in_its_own_unit(
    tmp_path, capsys, monkeypatch
):
    u, y = clean_record()
    np.savetxt(tmp_path / "heater.csv", 40 + 10 * u)
    np.savetxt(tmp_path / "temp.csv", 21.0 + y)
    args = ["--input", str(tmp_path / "heater.csv"), "--output", str(tmp_path / "temp.csv")]
    units = ["--input-unit", "%", "--output-unit", "degC"]
    out = tmp_path / "out"
    assert main(["identify", *args, *units, "--ts", "1", "--out", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["record"]["units"] == {"input": "%", "output": "degC"}
    assert report["record"]["units_from"] == {"input": "given", "output": "given"}
    assert (out / "record.png").stat().st_size > 0
    # Units the designs cannot convert to SI are kept in the model file and named.
    assert "degC" in (out / "model_pem_order2.yaml").read_text()
    assert any("are not all among m, mm, A, mA" in w for w in report["warnings"])
    text = format_identification_report(report, out)
    assert "input in % (given), output in degC (given)" in text
    # A CSV without units says its mA and mm are assumed.
    request = IdentificationRequest(
        input=tmp_path / "heater.csv", output=tmp_path / "temp.csv", ts=1.0
    )
    assumed = identify_record(request).report["record"]
    assert assumed["units"] == {"input": "mA", "output": "mm"}
    assert assumed["units_from"]["output"].startswith("assumed")


def test_a_unit_that_is_not_one_line_of_text_is_refused():
    u, y = clean_record()
    with pytest.raises(ConfigError, match=r"^output_unit 'deg\\nC': expected a unit"):
        maskless.identify(u, y, TS, output_unit="deg\nC")


def test_the_authors_record_is_clipped_16_percent_at_165_ma():
    paper_record()  # skips with the reason when shared/ is absent
    u = np.loadtxt(PAPER_DATA / "inputUGWN3.csv")
    y = np.loadtxt(PAPER_DATA / "outputUGWN3.csv")
    record = dd.diagnose_record(u, y, "mean")
    assert record.clipping.maximum == 165.0 and record.clipping.clipped_at == ("maximum",)
    assert record.clipping.share_at_maximum == pytest.approx(np.mean(u == 165.0))
    assert round(record.clipping.share_at_maximum, 2) == 0.16  # the README's "16 %"
    # Its output is held 3-4 samples at a time (sensor cadence), never stuck.
    assert record.output_hold.share < dd.STUCK_OUTPUT_SHARE
    assert record.suggested_detrend is None


def test_the_plots_label_each_signal_in_its_own_unit(tmp_path, monkeypatch):
    # `maskless identify` draws in a forked process; here the same calls run in this one.
    from matplotlib.axes import Axes

    labels = []
    original = Axes.set_ylabel
    monkeypatch.setattr(
        Axes, "set_ylabel", lambda axis, text, *a, **k: labels.append(text) or original(axis, text)
    )
    u, y = clean_record()
    run = maskless.identify(40 + 10 * u, 21 + y, TS, input_unit="%", output_unit="degC")
    (fitted,) = run.fitted_models
    curves = [part_curves(fitted, part, run.parts[0]) for part in run.parts]
    plot_compare(tmp_path / "compare.png", curves, "pem order 2", TS, run.units[1])
    plot_record(
        tmp_path / "record.png", *run.signals, TS, run.units, run.report["diagnostics"]["record"]
    )
    assert labels == [
        "output - offset (degC)",
        "output - offset (degC)",
        "input (%)",
        "output (degC)",
    ]
    unknown = maskless.identify(u, y, TS)  # units not given: said so, not guessed
    labels.clear()
    (fitted,) = unknown.fitted_models
    curves = [part_curves(fitted, part, unknown.parts[0]) for part in unknown.parts]
    plot_compare(tmp_path / "c2.png", curves, "pem order 2", TS, unknown.units[1])
    assert labels == ["output - offset (unit not given)"] * 2


def test_a_recordings_fields_carry_their_units():
    from maskless.diagrams.identification_run import _field_unit

    fields = [
        "/controller/command:inlet_valve_current_a",
        "/fusion/estimate:head_height_m",
        "/plant/state:gauge_pressure_pa",
        "/plant/state:head_velocity_m_s",
        "/safety/status:valid",
    ]
    assert [_field_unit(field) for field in fields] == ["A", "m", "Pa", "m/s", ""]


@pytest.mark.parametrize("order", [1, 2, 3, 4, 5, 6])
def test_no_diagnostic_fires_on_clean_generated_systems(order):
    # Orders 1-6, poles up to 0.995, coloured noise, white input: nothing planted.
    poles = {
        1: [0.995],
        2: [0.9, 0.7],
        3: [0.95, 0.6 + 0.3j, 0.6 - 0.3j],
        4: [0.95, 0.9, 0.85, 0.8],
        5: [0.99, 0.8, 0.5 + 0.4j, 0.5 - 0.4j, -0.3],
        6: [0.97, 0.9, 0.7 + 0.2j, 0.7 - 0.2j, 0.3, -0.5],
    }[order]
    rng = np.random.default_rng(order)
    a, c = np.real(np.poly(poles)), np.real(np.poly([0.5] * order))
    u = rng.standard_normal(3000)
    noise = scipy.signal.lfilter(c, a, 0.05 * rng.standard_normal(3000))
    y = scipy.signal.lfilter([0.0, *np.full(order, 1 / order)], a, u) + noise
    run = maskless.identify(u, y, TS, order=order)
    assert run.report["diagnostics"]["warnings"] == []


def test_an_input_held_over_half_the_record_is_reported_and_a_prbs_bit_is_not():
    u, y = clean_record()
    held = u.copy()
    held[:1100] = 0.25  # 55 % of the record
    (warning,) = dd._record_warnings(dd.diagnose_record(held, y, "mean", ("V", "K")))
    assert (
        warning == "the input is stuck at 0.25 V for 1100 samples (55% of the record) from sample 0"
    )
    prbs = np.repeat(np.sign(np.random.default_rng(9).standard_normal(SAMPLES // 50)), 50)
    assert dd._record_warnings(dd.diagnose_record(prbs, y, "mean")) == []
