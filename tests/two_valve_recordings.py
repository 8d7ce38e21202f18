"""Reading a two-valve excitation's recording back in tests: its currents and a model's fit."""

from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.records import (
    VALVE_CURRENTS_FIELDS,
    parse_range,
    read_mcap_signals,
)
from maskless.diagrams.hammerstein_run import read_two_valve_record


def recorded_currents(folder, samples):
    """The valve currents the recording holds at the excitation's samples (A), as (N, 2)."""
    ((_, currents),) = read_mcap_signals(folder / "run.mcap", VALVE_CURRENTS_FIELDS)
    # The log also holds the instant the run ends, when the last sample is still held.
    return currents[:samples]


def validation_fit(recording, model, validation: str) -> float:
    """The validation simulation fit of ``model`` simulated over the whole recording."""
    u, y, _ = read_two_valve_record(recording)
    part = parse_range(validation, y.size, "--validation")
    return fit_percent(y[part], model.simulate(u)[part])
