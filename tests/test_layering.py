"""The architecture's one-way imports, checked on the source.

Assets, errors, sensor names and the lazy re-exports <- camera frames and the recording format <-
systems <- analysis <- diagrams (the library) <- commands and the CLI. No command imports another,
and only the command layer knows argparse.
"""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE_FOLDERS = ("recording", "systems", "analysis", "diagrams", "assets")

# Module-name prefix -> layer; the longest matching prefix decides.
LAYERS = {
    "maskless.errors": 0,
    "maskless.assets": 0,
    "maskless.sensor_names": 0,
    "maskless.lazy_exports": 0,
    "maskless.camera_images": 1,
    "maskless.recording": 1,
    "maskless.systems": 2,
    "maskless.analysis": 3,
    "maskless.diagrams": 4,
    "maskless.diagrams.cli": 5,
    "maskless.diagrams.commands": 5,
}


def layer_of(module: str) -> int:
    prefix = max((p for p in LAYERS if module == p or module.startswith(p + ".")), key=len)
    return LAYERS[prefix]


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(("maskless", *parts))


def library_modules() -> list[Path]:
    # The top-level modules, then the subpackages' (the root's __init__ imports only lazy_exports).
    paths = sorted(path for path in ROOT.glob("*.py") if path.name != "__init__.py")
    for folder in PACKAGE_FOLDERS:
        # A script in a folder that is no package (assets/face/make_face.py, which makes an asset
        # with the library's face finder) is not part of the library.
        paths += sorted(
            path for path in (ROOT / folder).rglob("*.py") if (path.parent / "__init__.py").exists()
        )
    return paths


def imported_modules(path: Path) -> set[str]:
    """Every maskless module ``path`` imports, at the top, in a function or for type checking."""
    tree = ast.parse(path.read_text(), filename=str(path))
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
            # "from maskless.diagrams.commands import excite" imports a module too.
            found |= {f"{node.module}.{alias.name}" for alias in node.names}
    return {name for name in found if name.startswith("maskless.")}


def test_every_module_is_checked():
    names = {module_name(path) for path in library_modules()}
    assert {"maskless.errors", "maskless.diagrams.commands.simulate"} <= names
    assert len(names) > 50


@pytest.mark.parametrize("path", library_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_imports_go_one_way(path):
    own = module_name(path)
    against = []
    for name in imported_modules(path):
        if name.startswith("maskless.diagrams.commands.") and not name.startswith(own):
            # Commands share the library, never each other.
            against.append(f"{name} (a command)")
        elif layer_of(name) > layer_of(own) and _is_module(name):
            against.append(f"{name} (layer {layer_of(name)} > {layer_of(own)})")
    assert not against, f"{own} imports against the layering: {', '.join(sorted(against))}"


def _is_module(name: str) -> bool:
    """``name`` is a module (not a function imported from one)."""
    relative = name.removeprefix("maskless.").replace(".", "/")
    return (ROOT / f"{relative}.py").is_file() or (ROOT / relative / "__init__.py").is_file()


@pytest.mark.parametrize("path", library_modules(), ids=lambda p: str(p.relative_to(ROOT)))
def test_only_the_command_layer_parses_flags(path):
    if layer_of(module_name(path)) >= 5:
        return
    text = path.read_text()
    assert "argparse" not in text and "Namespace" not in text, (
        f"{path.relative_to(ROOT)}: library code takes typed arguments, not parsed flags"
    )


def test_the_checker_catches_an_import_against_the_layering(tmp_path):
    # An independent reference for the checker itself: a systems module importing a diagram.
    bad = tmp_path / "bad.py"
    bad.write_text("def f():\n    from maskless.diagrams.closed_loop import build_closed_loop\n")
    (name,) = {n for n in imported_modules(bad) if _is_module(n)}
    assert layer_of(name) > layer_of("maskless.systems.plant.pneumatic_plant")
