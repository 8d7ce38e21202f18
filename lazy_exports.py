"""A package's re-exported names, each imported from its own module on first use (PEP 562).

So that importing a package costs nothing until a name is used, and a name costs only its own
module: ``from maskless.recording import COMMAND_TOPIC`` loads the format's table, not mcap.
"""

import importlib
from collections.abc import Callable


def lazy_exports(namespace: dict, exports: dict[str, str]) -> tuple[Callable, Callable]:
    """The package's ``__getattr__`` and ``__dir__``, importing each name's module when first used.

    Args:
        namespace: the package's ``globals()``; a name, once imported, is kept there, so Python
            finds it without calling ``__getattr__`` again.
        exports: public name -> the module that defines it.

    Returns:
        ``(__getattr__, __dir__)``, to be bound to those names in the package.
    """
    package = namespace["__name__"]

    def attribute(name: str):
        if name not in exports:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(exports[name]), name)
        namespace[name] = value
        return value

    def names() -> list[str]:
        return sorted({*namespace, *exports})

    return attribute, names
