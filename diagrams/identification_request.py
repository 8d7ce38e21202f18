"""What `maskless identify` is asked: the record, its parts, the orders, the method.

Its own module, light to import: the command parses and checks its flags with it, and starts its
plotting worker, before it imports the estimators (scipy.signal alone takes most of a second).
"""

from dataclasses import dataclass
from pathlib import Path

from maskless.analysis.identification import METHODS
from maskless.diagrams.fit_split import DEFAULT_ESTIMATION, DEFAULT_VALIDATION
from maskless.diagrams.request_labels import LabelledRequest
from maskless.errors import ConfigError
from maskless.recording import COMMAND_TOPIC, FUSION_TOPIC
from maskless.systems.limits import SAMPLE_PERIOD_S

# What a maskless recording's input and output are, unless the request says otherwise.
DEFAULT_MCAP_INPUT = f"{COMMAND_TOPIC}:inlet_valve_current_a"
DEFAULT_MCAP_OUTPUT = f"{FUSION_TOPIC}:head_height_m"
DETREND_MODES = ("mean", "linear", "none")
# A unit string is shown as given, on one line of a report or a plot's label.
_UNIT_MAX_CHARS = 32


@dataclass(frozen=True)
class IdentificationRequest(LabelledRequest):
    """What to identify, from which record; checked when made.

    Attributes:
        input: the input record: a CSV file (one value per line, or a column) or a maskless MCAP
            recording; None when the signals are given as arrays (``identify``).
        output: the output record; None when ``input`` is an MCAP recording holding both.
        ts: the sample period (s).
        orders: the model orders to fit.
        method: "pem", "armax", "arx" or "n4sid".
        input_column: CSV column (name or index) or MCAP ``TOPIC:FIELD``; None for the default.
            Several inputs (the inlet and the outlet valve) as "COLUMN,COLUMN" or
            "TOPIC:FIELD,FIELD" (``records.VALVE_CURRENTS_FIELDS``): an m-input model.
        output_column: likewise for the output.
        estimation: the part the models are fitted on: fractions ("0:0.6") or sample indices.
        validation: the part they are judged on.
        detrend: remove the whole record's "mean" (the authors' preprocessing), its "linear"
            trend, or "none".
        k_step: also report the K-step-ahead prediction fit; None for none.
        estimate_initial_state: estimate x(0) with the model (else fix it at zero).
        input_unit: the input's unit, any string (e.g. "mA", "degC", "V"), shown as given; None
            for mA (CSV, assumed) or the MCAP field's unit. Only m, mm, A and mA convert to
            the SI a design loads (``MODEL_FILE_UNITS``). With several inputs, one unit for all
            or "UNIT,UNIT" one each.
        output_unit: likewise for the output (None: mm for CSV, assumed).
        labels: see ``LabelledRequest``.
    """

    input: Path | None
    ts: float
    output: Path | None = None
    orders: tuple[int, ...] = (2,)
    method: str = "pem"
    input_column: str | None = None
    output_column: str | None = None
    estimation: str = DEFAULT_ESTIMATION
    validation: str = DEFAULT_VALIDATION
    detrend: str = "mean"
    k_step: int | None = None
    estimate_initial_state: bool = True
    input_unit: str | None = None
    output_unit: str | None = None

    def __post_init__(self):
        """Makes the files Paths and the orders a tuple; RecordError for a field out of range."""
        if self.input is not None:
            object.__setattr__(self, "input", Path(self.input))
        if self.output is not None:
            object.__setattr__(self, "output", Path(self.output))
        object.__setattr__(self, "orders", tuple(self.orders))
        label = self.label
        SAMPLE_PERIOD_S.check(self.ts, label("ts"))
        if not self.orders or any(
            not isinstance(order, int) or isinstance(order, bool) or order < 1
            for order in self.orders
        ):
            raise ConfigError(
                f"{label('orders')} {self.orders}: expected positive integers, e.g. 2,4"
            )
        if self.method not in METHODS:
            raise ConfigError(
                f"{label('method')} {self.method!r}: expected one of {', '.join(METHODS)}"
            )
        if self.detrend not in DETREND_MODES:
            raise ConfigError(
                f"{label('detrend')} {self.detrend!r}: expected {', '.join(DETREND_MODES)}"
            )
        for name in ("input_unit", "output_unit"):
            unit = getattr(self, name)
            if unit is not None and (
                not isinstance(unit, str)
                or not unit.strip()
                or not unit.isprintable()
                or len(unit) > _UNIT_MAX_CHARS
            ):
                raise ConfigError(
                    f"{label(name)} {unit!r}: expected a unit, printable text of 1 to "
                    f"{_UNIT_MAX_CHARS} characters (e.g. mA, mm, degC)"
                )
        if self.k_step is not None and self.k_step < 1:
            raise ConfigError(f"{label('k_step')} {self.k_step}: expected a positive integer")
