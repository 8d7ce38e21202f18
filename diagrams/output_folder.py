"""The folder a command writes its files into: made when missing, refused when it cannot be."""

from pathlib import Path

from maskless.errors import ConfigError


def output_folder(path: str | Path) -> Path:
    """``path`` as a folder that exists (made with its parents when missing).

    Raises:
        ConfigError: naming ``path``, when it is a file or cannot be made.
    """
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        raise ConfigError(f"{path}: expected a folder to write into, found a file") from None
    except OSError as error:
        raise ConfigError(f"{path}: cannot make the folder ({error.strerror})") from None
    return path


def output_file(path: str | Path) -> Path:
    """``path`` with its folder made (``output_folder``), ready to be written."""
    path = Path(path)
    return output_folder(path.parent) / path.name
