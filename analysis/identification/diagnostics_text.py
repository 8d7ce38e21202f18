"""The record's units and the data diagnostics of a report, as lines a person reads.

The warnings the diagnostics raise are the report's own ("WARNING: ..." lines, printed after the
models); these lines give every diagnostic's figures, fired or not, in the record's units.
"""

from maskless.analysis.identification.data_diagnostics import format_pole


def format_diagnostics(report: dict) -> list[str]:
    """The record's units and the data diagnostics' figures, a line each (warnings come later)."""
    lines = []
    record = report.get("record")
    if record is not None:
        units, origins = record["units"], record["units_from"]
        lines.append(
            "record: "
            + ", ".join(
                f"{name} in {units[name]} ({origins[name]})"
                if units[name]
                else f"{name} unit not given"
                for name in ("input", "output")
            )
            + f"; {record['samples']} samples, --detrend {record['detrend']}"
        )
    diagnostics = report["diagnostics"]
    excitation = diagnostics["excitation"]
    persistence = (
        f"all {excitation['tested_order']} excited in {excitation['persistent_stretches']} of "
        f"{excitation['stretches']} stretches"
        if excitation["stretches"]
        else "the part is too short to judge persistence"
    )
    poor = excitation["too_poor_for_orders"]
    lines.append(
        f"excitation: the input excites {excitation['order']} of {excitation['tested_order']} "
        f"directions ({persistence}); "
        + (f"TOO POOR for order {', '.join(map(str, poor))}" if poor else "enough for every order")
    )
    found = diagnostics["integrators"]
    lines.append(
        "integrators: "
        + (
            "; ".join(
                f"order {i['order']} pole {format_pole(i['pole'])} ({i['distance_to_1']:.2g} "
                "from 1)"
                for i in found
            )
            if found
            else f"no pole within {diagnostics['thresholds']['integrator_pole_distance']:.2g} of 1"
        )
    )
    whole = diagnostics["record"]
    if whole is None:
        return lines
    lines.append(
        "offset and drift: "
        + ", ".join(
            f"{name} {whole[f'{name}_trend']['offset_share']:.0%} constant, "
            f"{whole[f'{name}_trend']['drift_share']:.0%} of its variance a line "
            f"(slope t {whole[f'{name}_trend']['slope_t_statistic']:.1f})"
            for name in ("input", "output")
        )
        + (
            f"; suggested --detrend {whole['suggested_detrend']}"
            if whole["suggested_detrend"]
            else f"; --detrend {whole['detrend']} suits it"
        )
    )
    units = dict(zip(("input", "output"), whole["units"], strict=True))
    lines.append(
        "longest holds: "
        + ", ".join(
            f"{name} {whole[f'{name}_hold']['samples']} samples at "
            f"{whole[f'{name}_hold']['value']:.9g}{_spaced(units[name])} "
            f"({whole[f'{name}_hold']['share']:.2%})"
            for name in ("input", "output")
        )
    )
    clip, unit = whole["clipping"], _spaced(units["input"])
    lines.append(
        f"input limits: {clip['share_at_minimum']:.2%} of samples at the minimum "
        f"{clip['minimum']:.9g}{unit}, {clip['share_at_maximum']:.2%} at the maximum "
        f"{clip['maximum']:.9g}{unit}"
        + (f" (clipped at the {' and '.join(clip['clipped_at'])})" if clip["clipped_at"] else "")
    )
    return lines


def _spaced(unit: str) -> str:
    """A unit to follow a number: " mA", or nothing when not given."""
    return f" {unit}" if unit else ""


def format_input_diagnostics(report: dict) -> list[str]:
    """``format_diagnostics`` for several inputs: each input's lines, then their separation."""
    diagnostics, record = report["diagnostics"], report.get("record")
    lines = []
    if record is not None:
        units = record["units"]
        lines.append(
            "record: "
            + ", ".join(
                f"input {name} in {unit}" if unit else f"input {name} unit not given"
                for name, unit in zip(record["inputs"], units["input"], strict=True)
            )
            + f" ({record['units_from']['input']}), output in {units['output'] or 'no unit'}"
            + f"; {record['samples']} samples, --detrend {record['detrend']}"
        )
    for name, own in diagnostics["inputs"].items():
        lines += [f"{name}: {line}" for line in format_diagnostics({"diagnostics": own})]
    separation = diagnostics["separation"]
    lines.append(
        f"inputs together: they excite {separation['joint_order']} of "
        f"{separation['needed_order']} directions; the others explain "
        + ", ".join(
            f"{share:.1%} of {name}'s variance"
            for name, share in separation["shared_variance"].items()
        )
        + f" (limit {separation['shared_variance_limit']:.0%})"
    )
    return lines
