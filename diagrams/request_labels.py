"""What a request calls its fields in messages: its own names, or the flags a user typed."""

from dataclasses import dataclass, field


@dataclass(frozen=True)
class LabelledRequest:
    """Base of the requests a command builds from flags.

    Attributes:
        labels: field -> what the user called it (a flag they gave); a field not in it is named
            by its own name. Keyword-only, so a request's own fields keep their order.
    """

    labels: dict[str, str] = field(default_factory=dict, compare=False, repr=False, kw_only=True)

    def label(self, field_name: str) -> str:
        """How the user named a field (the flag they gave), for messages."""
        return self.labels.get(field_name, field_name)
