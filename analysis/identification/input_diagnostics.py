"""The data diagnostics of several inputs: each input's own, and whether they can be told apart.

Excitation, clipping, holds, offsets and drift are properties of each input, so each input gets
``data_diagnostics``' own judgement, its warnings naming the input. What only several inputs have
is whether the record can tell their effects apart: an m-input model of order n needs the inputs
*together* to excite m·2n directions, and no input may be (nearly) a linear function of the
others' recent values. A split-range drive, where one command moves both valves, or two valves
driven by one signal, are the cases to catch: the fit then divides the output among the inputs
arbitrarily, and each input's DC gain means little however good the total fit.
"""

from dataclasses import dataclass

import numpy as np

from maskless.analysis.identification import data_diagnostics

# An input whose variance is this much explained by the other inputs' values (at lags within the
# tested window) cannot be told apart from them: less than a tenth of it is its own (convention,
# as data_diagnostics' thresholds).
SHARED_VARIANCE_LIMIT = 0.9


@dataclass(frozen=True)
class InputSeparation:
    """Whether the inputs of one record can be told apart, on the estimation part.

    Attributes:
        correlation: the inputs' correlation coefficients at lag 0 (m x m, as nested lists).
        window: L, the lags tested (2n for the largest order n, as ``data_diagnostics``).
        shared_variance: per input, the share of its variance about its mean that a least-squares
            combination of the other inputs' values at lags -L+1..L-1 explains (R²).
        joint_order: how many of the m·L directions of the inputs' stacked windows are excited
            (``data_diagnostics.EXCITATION_TOLERANCE`` of the largest).
        needed_order: m·L, what an m-input model of the largest order needs.
    """

    correlation: list
    window: int
    shared_variance: tuple[float, ...]
    joint_order: int
    needed_order: int


@dataclass(frozen=True)
class InputDiagnostics:
    """The diagnostics of an m-input identification, and the warnings they raise.

    Attributes:
        names: the inputs' names.
        per_input: each input's ``DataDiagnostics`` (its excitation, and with the record its
            offsets, drift, holds and clipping), in the order of ``names``.
        separation: whether the inputs can be told apart.
        warnings: one sentence per diagnostic that fired; each input's name its own.
    """

    names: tuple[str, ...]
    per_input: tuple[data_diagnostics.DataDiagnostics, ...]
    separation: InputSeparation
    warnings: tuple[str, ...]

    def as_dict(self) -> dict:
        """The report's "diagnostics" entry for several inputs (JSON-ready)."""
        separation = self.separation
        return {
            "inputs": {
                name: diagnostics.as_dict()
                for name, diagnostics in zip(self.names, self.per_input, strict=True)
            },
            "separation": {
                "correlation": separation.correlation,
                "window": separation.window,
                "shared_variance": dict(zip(self.names, separation.shared_variance, strict=True)),
                "joint_order": separation.joint_order,
                "needed_order": separation.needed_order,
                "shared_variance_limit": SHARED_VARIANCE_LIMIT,
            },
            "warnings": list(self.warnings),
        }


def separation(u: np.ndarray, window: int) -> InputSeparation:
    """How well the columns of ``u`` (N, m) can be told apart over ``window`` lags.

    Args:
        u: the estimation part's inputs, one column each (any units).
        window: L, the lags an order-n model spans (2n).
    """
    deviations = u - u.mean(axis=0)
    samples, m = deviations.shape
    lags = range(-(window - 1), window)
    shared = []
    for index in range(m):
        target = deviations[window - 1 : samples - window + 1, index]
        regressors = np.column_stack(
            [
                deviations[window - 1 + lag : samples - window + 1 + lag, other]
                for other in range(m)
                if other != index
                for lag in lags
            ]
        )
        coefficients, *_ = np.linalg.lstsq(regressors, target, rcond=None)
        residual = target - regressors @ coefficients
        shared.append(float(1.0 - residual @ residual / (target @ target)))
    windows = np.concatenate(
        [np.lib.stride_tricks.sliding_window_view(column, window) for column in deviations.T],
        axis=1,
    )
    eigenvalues = np.linalg.eigvalsh(windows.T @ windows / windows.shape[0])
    joint = int(np.sum(eigenvalues > data_diagnostics.EXCITATION_TOLERANCE * eigenvalues[-1]))
    return InputSeparation(
        correlation=np.corrcoef(deviations.T).tolist(),
        window=window,
        shared_variance=tuple(shared),
        joint_order=joint,
        needed_order=m * window,
    )


def diagnose_inputs(
    estimation_u: np.ndarray,
    poles_by_order: dict[int, np.ndarray],
    names: tuple[str, ...],
    records: tuple[data_diagnostics.RecordDiagnostics, ...] | None = None,
) -> InputDiagnostics:
    """Every diagnostic of an m-input identification, with its warnings.

    Args:
        estimation_u: the detrended inputs of the estimation part, (N, m).
        poles_by_order: each fitted model's poles, by its order.
        names: the inputs' names (m).
        records: per input, ``data_diagnostics.diagnose_record`` of that input and the output;
            None to judge the parts alone.
    """
    m = estimation_u.shape[1]
    if len(names) != m or (records is not None and len(records) != m):
        raise ValueError(f"names and records: expected {m} each, one per input column")
    per_input, warnings = [], []
    for index, name in enumerate(names):
        diagnostics = data_diagnostics.diagnose(
            estimation_u[:, index], poles_by_order, None if records is None else records[index]
        )
        per_input.append(diagnostics)
        # The output's and the poles' warnings are the same for every input: said once.
        for warning in diagnostics.warnings:
            named = warning.replace("the input", f"the input {name}")
            if named not in warnings:
                warnings.append(named)
    window = data_diagnostics.EXCITATION_ORDER_PER_MODEL_ORDER * max(poles_by_order)
    separated = separation(estimation_u, window)
    warnings += _separation_warnings(separated, names)
    return InputDiagnostics(tuple(names), tuple(per_input), separated, tuple(warnings))


def _separation_warnings(separated: InputSeparation, names: tuple[str, ...]) -> list[str]:
    """A warning when the record cannot tell the inputs apart."""
    warnings = []
    shared = [
        f"{share:.0%} of {name}'s variance"
        for name, share in zip(names, separated.shared_variance, strict=True)
        if share > SHARED_VARIANCE_LIMIT
    ]
    if shared:
        warnings.append(
            f"the inputs cannot be told apart: the other inputs' values within {separated.window}"
            f" samples explain {', '.join(shared)} (a split-range or common drive moves them "
            "together), so the fit divides the output among them arbitrarily and each input's "
            "DC gain and contribution mean little; excite the inputs independently"
        )
    if separated.joint_order < separated.needed_order:
        warnings.append(
            f"the inputs together excite {separated.joint_order} of the {separated.needed_order}"
            f" directions an order-{separated.window // 2} model of {len(names)} inputs needs: "
            "the record cannot separate every input's dynamics; excite the inputs independently"
        )
    return warnings
