"""Where a command's results go: files written whole or not at all, and ``-`` for
standard output.

Every output flag (``-o``, ``--error-map``, ``--report``, ``--map``, ``--figures`` ...)
is checked before the work starts, so a typo costs a second, not a calibration.
Missing parent folders are created, as ``mkdir -p`` would (the same for every command
and every flag); anything else that stops a write (a folder named where a file is
asked for, a file where a folder is, no permission, a read-only or virtual file system
such as /proc) is one line naming the flag, exit status 2.

Files are staged as hidden temporary files beside their targets and renamed into
place together when the command has produced everything (``Outputs.writing``); if
anything fails before that, the staged files and the folders made for them are
removed: a failure leaves no file, not even half of one. Devices and pipes
(``/dev/null``, a FIFO) are written directly: they cannot be renamed onto.
"""
from __future__ import annotations

import contextlib
import errno
import os
import shutil
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from calib_core.errors import CalibError

from . import output

STDOUT = "-"


class OutputError(CalibError):
    """An output path that cannot be written: names the flag and the path."""


def _reason(exc: OSError) -> str:
    if exc.errno in (errno.EACCES, errno.EPERM):
        return "permission denied"
    return (exc.strerror or str(exc)).lower()


def _existing_ancestor(path: Path) -> Path:
    """The nearest folder (or file) on the way up from ``path`` that exists."""
    for parent in path.parents:
        if parent.exists():
            return parent
    return Path(path.anchor or ".")


def _check_creatable(path: Path, flag: str, shown: Path | None = None) -> None:
    """Files can be created at ``path`` (which does not exist): its nearest existing
    ancestor must be a folder we may create files in, tried for real (permissions
    alone do not tell, e.g. for root, on /proc or on a read-only mount).
    ``shown``: the path the user gave, for the message."""
    top = _existing_ancestor(path)
    shown = shown or path
    if not top.is_dir():
        raise OutputError(f"{flag} {shown}: {top} is a file, not a folder")
    try:
        fd, probe = tempfile.mkstemp(dir=top, prefix=".freecal-probe-")
    except OSError as exc:
        raise OutputError(f"{flag} {shown}: cannot create files in {top}/ ({_reason(exc)})") from None
    os.close(fd)
    os.unlink(probe)


def _new_file_mode(target: Path) -> int:
    """The mode a file written in place would get: the replaced file's, else 0666 less the umask
    (``mkstemp`` makes its files 0600, private, which a calibration is not)."""
    try:
        return stat.S_IMODE(os.stat(target).st_mode)
    except OSError:
        mask = os.umask(0)
        os.umask(mask)
        return 0o666 & ~mask


class Outputs:
    """The outputs of one command run. Declare each at the start (``file``,
    ``folder``: checked at once), produce everything, then write inside
    ``with outputs.writing():``: all of them land, or none."""

    def __init__(self) -> None:
        self._staged: list[tuple[Path, Path]] = []   # (temporary, target), renamed at the end
        self._folders: list[tuple[Path, Path]] = []  # (staging folder, target folder): its files land there
        self._made: list[Path] = []                  # folders created for the outputs, removed on failure
        self._stdout: list[bytes] = []               # what ``-`` receives, printed at the end
        self._declared: dict[Path, str] = {}          # target → the flag that named it
        self._writing = False

    def file(self, path: str | None, flag: str, example: str = "out.json") -> OutputFile | None:
        """A file output (None if the flag was not given); ``-``: standard output."""
        if path is None:
            return None
        if path == STDOUT:
            output.claim_stdout(f"{flag} -")
            return OutputFile(self, None, flag)
        target = Path(path)
        if path.endswith(("/", os.sep)) or target.is_dir():
            raise OutputError(f"{flag} {path}: is a folder; name a file, e.g. {target / example}")
        if target.exists():
            if _is_regular(target) and not os.access(target, os.W_OK):
                raise OutputError(f"{flag} {path}: the file is read-only")
            if target.is_symlink():
                target = Path(os.path.realpath(target))  # replace what the link points to, not the link
            if _is_regular(target):
                _check_creatable(target.parent / ".freecal", flag, Path(path))
        else:
            _check_creatable(target, flag)
        key = target.resolve()
        if key in self._declared and (not target.exists() or _is_regular(target)):  # /dev/null twice is fine
            raise OutputError(f"{flag} {path}: also given to {self._declared[key]}; give each output its own file")
        self._declared[key] = flag
        return OutputFile(self, target, flag)

    def folder(self, path: str | None, flag: str) -> OutputFolder | None:
        """A folder output (None if the flag was not given), created if missing."""
        if path is None:
            return None
        if path == STDOUT:
            raise OutputError(f"{flag} -: a folder is asked for here; standard output takes one file")
        target = Path(path)
        if target.exists() and not target.is_dir():
            raise OutputError(f"{flag} {path}: is a file, not a folder")
        _check_creatable(target / ".freecal", flag, target)
        return OutputFolder(self, target, flag)

    @contextlib.contextmanager
    def writing(self) -> Iterator[Outputs]:
        """Stage the outputs inside; on success rename them into place (and print
        what goes to standard output), on any failure remove what was staged."""
        self._writing = True
        try:
            yield self
        except BaseException:
            self._rollback()
            raise
        moves = self._staged + [(f, target / f.name) for folder, target in self._folders
                                for f in sorted(folder.iterdir()) if f.is_file()]
        try:
            for tmp, target in moves:
                tmp.replace(target)
        except OSError as exc:
            self._rollback()
            raise OutputError(f"could not write {target} ({_reason(exc)})") from None
        finally:
            for folder, _ in self._folders:
                shutil.rmtree(folder, ignore_errors=True)
        for data in self._stdout:
            output.write_data(data)

    # the parts OutputFile and OutputFolder use

    def _make_parents(self, folder: Path, flag: str) -> None:
        missing = [p for p in (folder, *folder.parents) if not p.exists()]
        try:
            for p in reversed(missing):
                p.mkdir()
                self._made.append(p)
        except OSError as exc:
            raise OutputError(f"{flag} {folder}: cannot create this folder ({_reason(exc)})") from None

    def _temporary(self, target: Path, flag: str) -> Path:
        """A new hidden file beside ``target`` (same suffix: some writers choose the format by it)."""
        if not self._writing:
            raise RuntimeError("outputs are staged inside `with outputs.writing():`")
        self._make_parents(target.parent, flag)
        try:
            fd, name = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=f".tmp{target.suffix}")
        except OSError as exc:
            raise OutputError(f"{flag} {target}: cannot create files in {target.parent}/ ({_reason(exc)})") from None
        os.close(fd)
        tmp = Path(name)
        self._staged.append((tmp, target))
        os.chmod(tmp, _new_file_mode(target))
        return tmp

    def _rollback(self) -> None:
        for tmp, _ in self._staged:
            tmp.unlink(missing_ok=True)
        for folder, _ in self._folders:
            shutil.rmtree(folder, ignore_errors=True)
        for folder in reversed(self._made):
            with contextlib.suppress(OSError):
                folder.rmdir()  # only if empty: never what was there before
        self._staged, self._folders, self._made = [], [], []


def _is_regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.stat(path).st_mode)
    except OSError:
        return False


class OutputFile:
    """One output file (``target`` None: standard output)."""

    def __init__(self, outputs: Outputs, target: Path | None, flag: str):
        self.outputs, self.target, self.flag = outputs, target, flag

    @property
    def to_stdout(self) -> bool:
        return self.target is None

    def __str__(self) -> str:
        return "standard output" if self.target is None else str(self.target)

    def write(self, data: str | bytes) -> None:
        raw = data.encode("utf-8") if isinstance(data, str) else data
        if self.target is None:
            self.outputs._stdout.append(raw)
            return
        if self.target.exists() and not _is_regular(self.target):  # /dev/null, a FIFO: written as they are
            self._direct(raw)
            return
        tmp = self.outputs._temporary(self.target, self.flag)
        try:
            tmp.write_bytes(raw)
        except OSError as exc:
            raise OutputError(f"{self.flag} {self.target}: could not write ({_reason(exc)})") from None

    def _direct(self, raw: bytes) -> None:
        assert self.target is not None
        try:
            with open(self.target, "wb") as f:
                f.write(raw)
        except OSError as exc:
            raise OutputError(f"{self.flag} {self.target}: could not write ({_reason(exc)})") from None


class OutputFolder:
    """One output folder: its files are staged and land together with the rest."""

    def __init__(self, outputs: Outputs, target: Path, flag: str):
        self.outputs, self.target, self.flag = outputs, target, flag

    def __str__(self) -> str:
        return str(self.target)

    def file(self, name: str) -> OutputFile:
        return OutputFile(self.outputs, self.target / name, self.flag)

    def staging(self) -> Path:
        """A hidden folder inside the target for a library that writes several files
        into a folder by itself (``save_maps``): at the end, every file in it is moved
        into the target, under its name."""
        outputs = self.outputs
        if not outputs._writing:
            raise RuntimeError("outputs are staged inside `with outputs.writing():`")
        outputs._make_parents(self.target, self.flag)
        try:
            folder = Path(tempfile.mkdtemp(dir=self.target, prefix=".freecal-"))
        except OSError as exc:
            raise OutputError(f"{self.flag} {self.target}: cannot create files in it ({_reason(exc)})") from None
        outputs._folders.append((folder, self.target))
        return folder
