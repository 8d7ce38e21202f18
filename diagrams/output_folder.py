"""The folder a command writes its files into, and the folder of one run.

``output_folder`` makes a folder (or refuses one that cannot be). ``FolderLock`` keeps a second
run out of a folder a run is writing (a Monte Carlo sweep's, which later runs append to).
``RunFolder`` is the folder a run writes (`maskless simulate`, `maskless excite`), claimed before
anything is simulated:

- checked: a file in the way, a folder that cannot be made or written, a folder another run is
  writing, or one holding a run's files (replaced only with ``overwrite``, `--overwrite`) are
  refused with one line naming the folder or the file;
- locked: ``.maskless.lock`` holds the pid of the run writing the folder and an exclusive
  ``flock`` on it. The kernel drops the lock when its last holder ends, even by SIGKILL, so a
  dead run's lock file is simply taken over, and a recycled pid cannot fake one;
- written under temporary names, the suffix kept (``run.partial.mcap``: viewers and matplotlib
  know the format by it) and renamed to the final names when the run succeeds, so a reader never
  sees a half-written file under a final name. A run that fails or is stopped leaves its
  ``*.partial.*`` files (a stopped run's recording finished with its footer where it could be)
  and nothing under the final names.
"""

import contextlib
import fcntl
import os
from collections.abc import Sequence
from pathlib import Path

from maskless.errors import ConfigError

LOCK_NAME = ".maskless.lock"


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


def partial_name(name: str) -> str:
    """The temporary name a run writes ``name`` under: ``run.mcap`` -> ``run.partial.mcap``."""
    path = Path(name)
    return path.stem + ".partial" + path.suffix


class FolderLock:
    """``.maskless.lock`` in a folder: held by one run at a time (module docstring).

    Use it as a context manager (``acquire`` on entering, ``release`` on leaving). A folder
    that is appended to across runs (a Monte Carlo sweep's table) needs only this; a run's own
    folder has it inside ``RunFolder``.
    """

    def __init__(self, path: str | Path) -> None:
        """The lock of the folder ``path``; nothing is taken yet."""
        self.path = Path(path)
        self._descriptor: int | None = None

    def check(self) -> None:
        """Refuses the folder, as ``acquire`` would, without taking the lock.

        Raises:
            ConfigError: another run holds the lock (naming its pid), or the folder cannot be
                written.
        """
        try:
            os.close(self._locked(os.open(self.path / LOCK_NAME, os.O_RDWR)))
        except FileNotFoundError:
            pass
        except PermissionError as error:
            raise ConfigError(f"{self.path}: cannot write into it ({error.strerror})") from None

    def acquire(self) -> None:
        """Takes the lock and writes this process's pid into the lock file.

        Raises:
            ConfigError: as ``check``.
        """
        path = self.path / LOCK_NAME
        while True:
            try:
                descriptor = self._locked(os.open(path, os.O_RDWR | os.O_CREAT, 0o644))
            except OSError as error:
                raise ConfigError(f"{self.path}: cannot write into it ({error.strerror})") from None
            # The run before may have removed the file after it was opened here: lock the one
            # on disk.
            with contextlib.suppress(FileNotFoundError):
                if os.path.samestat(os.fstat(descriptor), os.stat(path)):
                    break
            os.close(descriptor)
        os.ftruncate(descriptor, 0)
        os.write(descriptor, f"{os.getpid()}\n".encode())
        self._descriptor = descriptor

    @property
    def held(self) -> bool:
        """Whether this object holds the lock now."""
        return self._descriptor is not None

    def release(self) -> None:
        """Removes the lock file and unlocks (nothing when not held)."""
        if self._descriptor is None:
            return
        # Removed while still locked: a run waiting on the old file then finds it gone.
        (self.path / LOCK_NAME).unlink(missing_ok=True)
        os.close(self._descriptor)
        self._descriptor = None

    def __enter__(self) -> "FolderLock":
        """Takes the lock (``acquire``)."""
        self.acquire()
        return self

    def __exit__(self, error_type, error, traceback) -> None:
        """Releases the lock."""
        self.release()

    def _locked(self, descriptor: int) -> int:
        """``descriptor`` locked; refused (and closed) if another run holds the lock."""
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            owner = os.pread(descriptor, 32, 0).decode(errors="replace").strip() or "unknown"
            os.close(descriptor)
            raise ConfigError(
                f"{self.path}: in use by another run (pid {owner}); wait for it to end or give "
                "another --out"
            ) from None
        return descriptor


class RunFolder:
    """The folder of one run: checked, locked, written under temporary names (module docstring).

    Use it as a context manager: entering claims the folder (``claim``); leaving it renames the
    temporaries when the block succeeded (``commit``), and releases the lock either way. A block
    that raised gets a note naming the temporaries it left.
    """

    def __init__(self, path: str | Path, names: Sequence[str], *, overwrite: bool = False) -> None:
        """Describes the folder; nothing is checked or made yet.

        Args:
            path: the folder (made with its parents when missing).
            names: every file a run of this kind may write there: an earlier run's are replaced
                only with ``overwrite``, and with it those this run does not write are removed.
            overwrite: replace an earlier run's files.
        """
        self.path = Path(path)
        self._names = list(names)
        self._overwrite = overwrite
        self._lock = FolderLock(self.path)
        self._made = False

    def temporary(self, name: str) -> Path:
        """Where the run writes ``name`` (one of ``names``) until it succeeds."""
        return self.path / partial_name(name)

    def final(self, name: str) -> Path:
        """Where ``name`` is once the run succeeded."""
        return self.path / name

    def final_paths(self, files: dict[str, str]) -> dict[str, str]:
        """``files`` (what -> name) with each name as its final path, as text."""
        return {what: str(self.final(name)) for what, name in files.items()}

    def check(self) -> None:
        """Refuses the folder, as ``claim`` would, without making or locking anything.

        For a command that claims several folders in turn: all are checked before any runs.

        Raises:
            ConfigError: as ``claim``.
        """
        if self.path.exists() and not self.path.is_dir():
            raise ConfigError(f"{self.path}: expected a folder to write into, found a file")
        existing = next((p for p in [self.path, *self.path.parents] if p.exists()), Path("."))
        if not os.access(existing, os.W_OK | os.X_OK):
            raise ConfigError(f"{self.path}: cannot write into {existing} (permission denied)")
        self._lock.check()
        self._refuse_an_earlier_run()

    def claim(self) -> None:
        """Makes and locks the folder, and clears an earlier run's temporaries.

        Raises:
            ConfigError: the folder is a file or cannot be made or written, another run is
                writing it (naming its pid), or an earlier run's files are there and
                ``overwrite`` was not given (naming a file and `--overwrite`).
        """
        self._made = not self.path.exists()
        output_folder(self.path)
        self._lock.acquire()
        try:
            self._refuse_an_earlier_run()
            for name in self._names:
                self.temporary(name).unlink(missing_ok=True)
        except BaseException:
            self.release()
            raise

    def commit(self) -> None:
        """Renames the temporaries written to their final names.

        With ``overwrite``, an earlier run's file that this run did not write goes, so no file
        of another run stays beside this one's.
        """
        for name in self._names:
            if self.temporary(name).exists():
                os.replace(self.temporary(name), self.final(name))
            elif self._overwrite:
                self.final(name).unlink(missing_ok=True)

    def release(self) -> None:
        """Removes the lock file and unlocks; a folder this run made and left empty goes too."""
        if not self._lock.held:
            return
        self._lock.release()
        if self._made:
            with contextlib.suppress(OSError):  # not empty: it holds what the run left
                self.path.rmdir()

    def __enter__(self) -> "RunFolder":
        """Claims the folder (``claim``)."""
        self.claim()
        return self

    def __exit__(self, error_type, error, traceback) -> None:
        """Commits if the block succeeded; releases the folder either way."""
        try:
            if error_type is None:
                self.commit()
            else:
                left = [str(self.temporary(n)) for n in self._names if self.temporary(n).exists()]
                if left:
                    error.add_note(f"what the run wrote is in {', '.join(left)}")
        finally:
            self.release()

    def _refuse_an_earlier_run(self) -> None:
        if self._overwrite:
            return
        for name in self._names:
            for path in (self.final(name), self.temporary(name)):
                if path.exists():
                    raise ConfigError(
                        f"{path}: an earlier run's file is there; give --overwrite to replace "
                        "that run"
                    )
