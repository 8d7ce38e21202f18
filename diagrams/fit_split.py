"""The parts of a record a model is fitted and judged on, and where each came from.

`maskless identify` takes them as --estimation and --validation. A designed experiment's recording
(``maskless excite --signal designed-levels``) says its own (``recording.FIT_SPLIT_METADATA``): its
rounds placed the levels that read the valves' starting currents in the part it fits, so a fit on
another part reads them from levels the design did not place, or misses some it did. On the
still population's patient 34, the default split read the inlet's start 7 mA off, unwarned, where
the recording's own read it within 0.2 mA (issue 14). A part not given is the recording's; one
given that differs from it is warned.
"""

from dataclasses import dataclass

from maskless.analysis.identification.records import (
    OVERLAPPING_PARTS_WARNING,
    parse_range,
    parts_overlap,
)

DEFAULT_ESTIMATION = "0:0.6"
DEFAULT_VALIDATION = "0.6:1"

# Where a part came from, as a report says it.
GIVEN, DESIGNED, DEFAULT = "given", "the recording's design", "the default"


def parts_of_share(share: float) -> dict[str, str]:
    """The split that fits the first ``share`` of a record and judges the rest, as flags take it."""
    return {"estimation": f"0:{share!r}", "validation": f"{share!r}:1"}


@dataclass(frozen=True)
class FitSplit:
    """The parts, as START:STOP text and as slices, where each came from, and what it risks.

    Attributes:
        estimation, validation: the parts, as `maskless identify` takes them.
        estimation_from, validation_from: ``GIVEN``, ``DESIGNED`` or ``DEFAULT``.
        estimation_part, validation_part: the parts as slices of the record.
        warnings: a sentence for an estimation part given that is not the recording's design's,
            and one for parts that overlap.
    """

    estimation: str
    validation: str
    estimation_from: str
    validation_from: str
    estimation_part: slice
    validation_part: slice
    warnings: tuple[str, ...] = ()

    def summary(self) -> dict:
        """The split as a report holds it."""
        return {
            "estimation": self.estimation,
            "estimation_from": self.estimation_from,
            "validation": self.validation,
            "validation_from": self.validation_from,
        }


def fit_split(
    designed: dict[str, str] | None,
    estimation: str | None,
    validation: str | None,
    samples: int,
) -> FitSplit:
    """Each part as given, else as the recording's design has it, else the default.

    Args:
        designed: the recording's ``FIT_SPLIT_METADATA`` record, or None for a recording without
            one (not designed, or written before recordings said it).
        estimation: the part given to fit on (--estimation), or None.
        validation: the part given to judge on (--validation), or None.
        samples: the record's length, to compare parts as the samples they take.

    Raises:
        RecordError: a part that is not START:STOP within the record, naming the flag, or the
            recording's part when the recording's is.
    """
    designed = designed or {}
    planned = {
        name: parse_range(designed[name], samples, f"the recording's {name} part")
        for name in ("estimation", "validation")
        if name in designed
    }
    texts, sources, parts = [], [], []
    for name, given, default in (
        ("estimation", estimation, DEFAULT_ESTIMATION),
        ("validation", validation, DEFAULT_VALIDATION),
    ):
        if given is not None:
            text, source, part = given, GIVEN, parse_range(given, samples, f"--{name}")
        elif name in planned:
            text, source, part = designed[name], DESIGNED, planned[name]
        else:
            text, source, part = default, DEFAULT, parse_range(default, samples, f"--{name}")
        texts.append(text)
        sources.append(source)
        parts.append(part)
    warnings = ()
    if estimation is not None and "estimation" in planned and parts[0] != planned["estimation"]:
        warnings = (
            f"--estimation {estimation} is not the part this recording was designed to be "
            f"fitted on ({designed['estimation']}: its rounds placed the levels that read the "
            "valves' starting currents for a fit of that part), so the starts are read from "
            "other levels than the design chose; leave --estimation out to fit the designed "
            "part",
        )
    if parts_overlap(*parts):
        warnings += (OVERLAPPING_PARTS_WARNING,)
    return FitSplit(*texts, *sources, *parts, warnings)
