"""Sets of output files that are written whole or not at all, one writer at a time.

A result set (``result.json``, ``parameters.csv``, the models and the report of ``consistid
identify --output DIR``) is useful only whole: a new ``parameters.csv`` beside an old
``result.json`` is a silent lie. Three rules keep a set whole:

1. **One writer.** :func:`lock_output` takes an exclusive lock on the output path (an
   ``flock`` on ``.NAME.consistid-lock`` beside it; the kernel releases it when the process
   dies, so a killed run leaves no stale lock). A second run that asks for the same output is
   refused by name (:class:`~consistid.errors.OutputPathError`) instead of replacing the
   first one's files. A folder is one output: a run that writes a set of files into a folder
   holds the folder alone, and a run that writes one file (:func:`lock_output_file`) holds
   that file alone and *shares* the folder that receives it (``LOCK_SH`` on the folder's
   lock), so that no file of another run lands among a set while it is written, and two runs
   that write different files into one folder do not stop each other. The temporaries a
   killed writer (SIGKILL) left beside its output are removed by the next run that holds the
   output's lock (:func:`remove_stale`).
2. **All or nothing.** The files are written into a staging folder; a new output folder is
   that staging folder renamed once (``rename(2)`` is atomic). Into an existing folder the files
   are renamed one by one under a journal (:data:`JOURNAL`, listing them) written before the
   first rename and removed after the last: a reader that finds the journal
   (:func:`interrupted_files`) knows the set is mixed and refuses it.
3. **Signals wait.** SIGINT and SIGTERM that arrive during the renames are held
   (:func:`signals_deferred`) and delivered after the last one; before the renames, they stop
   the run and the staging folder is removed (:func:`sigterm_interrupts` turns SIGTERM into
   :class:`Terminated`, a ``KeyboardInterrupt``, so ``finally`` clauses run).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import re
import shutil
import signal
import threading
import uuid
from pathlib import Path
from typing import Iterator

from .errors import OutputPathError

__all__ = ["JOURNAL", "Terminated", "lock_output", "lock_output_file", "release_output_locks",
           "interrupted_files", "check_destination", "check_regular", "remove_stale",
           "commit_folder", "replacing", "signals_deferred", "sigterm_interrupts"]

#: The file an output folder holds while a set of files is renamed into it (one name a line).
JOURNAL = ".consistid-incomplete"
#: Locks this process holds: lock file → its descriptor.
_HELD: dict[Path, int] = {}


class Terminated(KeyboardInterrupt):
    """The process received SIGTERM (raised by the handler of :func:`sigterm_interrupts`)."""


def _lock_file(out: Path) -> Path:
    return out.parent / f".{out.name}.consistid-lock"


def lock_output(path: str | os.PathLike, what: str = "output", *,
                shared: bool = False) -> Path:
    """Hold a lock on the output ``path`` (a file or a folder) until
    :func:`release_output_locks` or the process ends; returns the lock file. The lock is
    exclusive, or with ``shared=True`` shared with other shared holders (the folder that
    receives one file of :func:`lock_output_file`; where ``flock`` is missing, exclusive).

    Raises
    ------
    OutputPathError : another process holds the lock (names its pid and what to do), or the
        lock file cannot be made beside ``path``.
    """
    out = Path(path).expanduser().resolve()
    lock = _lock_file(out)
    if lock in _HELD:
        return lock
    try:
        import fcntl
    except ImportError:                         # Windows: an exclusive create instead
        fcntl = None
    mode = (fcntl.LOCK_SH if shared else fcntl.LOCK_EX) if fcntl else 0
    while True:
        flags = os.O_RDWR | os.O_CREAT | (0 if fcntl else os.O_EXCL)
        try:
            fd = os.open(lock, flags, 0o644)
        except FileExistsError:
            _refuse(out, lock, what)
        except OSError as exc:
            raise OutputPathError(f"{what} {str(out)!r}: cannot make its lock {str(lock)!r} "
                                  f"({exc.strerror}); choose an output in a writable folder"
                                  ) from None
        if fcntl is None:
            break
        try:
            fcntl.flock(fd, mode | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            _refuse(out, lock, what)
        try:                                    # the holder before us may have removed it
            same = os.fstat(fd).st_ino == os.stat(lock).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    if not shared:                              # shared holders leave the first one's pid
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        remove_stale(out)
    elif os.fstat(fd).st_size == 0:
        os.write(fd, f"{os.getpid()}\n".encode())
    _HELD[lock] = fd
    return lock


def remove_stale(out: Path) -> list[str]:
    """Remove the temporaries that a killed writer of ``out`` left beside it (SIGKILL, a power
    cut: no ``finally`` ran): the staging folders of :func:`commit_folder` callers
    (``.NAME.part-XXXXXXXX``) and the files of :func:`replacing`
    (``.STEM.<12 hex>.partSUFFIX``). Called by :func:`lock_output` once it holds ``out``
    alone, so no live writer owns them. Returns their names."""
    stem, suffix = out.stem, out.suffix
    pattern = re.compile(rf"\.{re.escape(out.name)}\.part-[a-z0-9_]{{8}}|"
                         rf"\.{re.escape(stem)}\.[0-9a-f]{{12}}\.part{re.escape(suffix)}")
    removed = []
    try:
        entries = list(os.scandir(out.parent))
    except OSError:
        return removed
    for entry in entries:
        if pattern.fullmatch(entry.name):
            if entry.is_dir(follow_symlinks=False):
                shutil.rmtree(entry.path, ignore_errors=True)
            else:
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
            removed.append(entry.name)
    return removed


def lock_output_file(path: str | os.PathLike, what: str = "output") -> Path:
    """Lock the output file ``path`` for one run: its folder shared (a run writing a set of
    files into that folder is refused, and refuses this one), the file itself exclusive
    (module docstring, rule 1); returns the file's lock."""
    out = Path(path).expanduser().resolve()
    if os.access(_lock_file(out.parent).parent, os.W_OK | os.X_OK):
        lock_output(out.parent, what, shared=True)
    # else no run can lock that folder for a set of files either (its lock cannot be made)
    return lock_output(out, what)


def _refuse(out: Path, lock: Path, what: str) -> None:
    try:
        pid = lock.read_text(encoding="ascii", errors="replace").strip() or "?"
    except OSError:
        pid = "?"
    raise OutputPathError(
        f"{what} {str(out)!r} is being written by another consistid run (pid {pid}, lock "
        f"{lock.name!r}); wait for it to end or choose another output, so that neither "
        "replaces the other's files")


def release_output_locks() -> None:
    """Release every lock :func:`lock_output` took in this process (and remove the files)."""
    for lock, fd in reversed(list(_HELD.items())):
        if _alone(fd):                          # a shared lock stays while others hold it
            with contextlib.suppress(OSError):
                lock.unlink()
        with contextlib.suppress(OSError):
            os.close(fd)
        del _HELD[lock]


def _alone(fd: int) -> bool:
    """Whether this process is the lock's only holder (an exclusive ``flock`` is granted)."""
    try:
        import fcntl
    except ImportError:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        return False
    return True


atexit.register(release_output_locks)


def interrupted_files(folder: str | os.PathLike) -> list[str] | None:
    """The files whose replacement in ``folder`` was interrupted (the :data:`JOURNAL`'s
    names), or ``None`` when the folder's set is whole."""
    journal = Path(folder) / JOURNAL
    if not journal.is_file():
        return None
    try:
        text = journal.read_text(encoding="utf-8", errors="replace")[:100_000]
    except OSError:
        return []
    return [line for line in text.splitlines() if line]


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Hold SIGINT and SIGTERM during the block and deliver them after it (main thread only;
    elsewhere Python delivers no signal to the block anyway)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    arrived: list[int] = []
    previous = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, lambda s, _frame: arrived.append(s))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        for sig in dict.fromkeys(arrived):
            signal.raise_signal(sig)


@contextlib.contextmanager
def sigterm_interrupts() -> Iterator[None]:
    """In the block, SIGTERM raises :class:`Terminated` (as SIGINT raises
    ``KeyboardInterrupt``), so that temporaries are removed on the way out. Left alone when
    the program set its own SIGTERM handler, or outside the main thread."""
    if threading.current_thread() is not threading.main_thread() \
            or signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        yield
        return

    def stop(_sig: int, _frame: object) -> None:
        raise Terminated("terminated (SIGTERM)")

    signal.signal(signal.SIGTERM, stop)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def commit_folder(staging: Path, out: Path) -> list[str]:
    """Move the files of ``staging`` into ``out`` whole (module docstring, rule 2), with
    signals held; returns their names. ``staging`` must be on the filesystem of ``out``."""
    names = sorted(p.name for p in staging.iterdir())
    with signals_deferred():
        if not out.exists():
            os.chmod(staging, 0o777 & ~_umask())
            try:
                os.rename(staging, out)         # one rename: the set appears whole
                return names
            except OSError:                     # someone made the folder meanwhile
                out.mkdir(exist_ok=True)
        journal = out / JOURNAL
        with open(journal, "w", encoding="utf-8") as fh:
            fh.write("".join(f"{name}\n" for name in names))
            fh.flush()
            os.fsync(fh.fileno())
        for name in names:
            os.replace(staging / name, out / name)
        journal.unlink()
    return names


def check_destination(path: str | os.PathLike) -> Path:
    """``path`` (absolute) if a file can be written there, else
    :class:`~consistid.errors.OutputPathError` naming it: a NUL character, an existing folder
    or anything else not a regular file (:func:`check_regular`), a folder that does not exist or
    is not writable."""
    text = os.fspath(path)
    if not text or "\0" in str(text):
        raise OutputPathError(f"output path {str(text)[:120]!r} is empty or holds a NUL "
                              "character; give a file path")
    out = Path(text).expanduser().resolve()
    check_regular(out)                          # a folder, a device, a name too long
    if not out.parent.is_dir():
        raise OutputPathError(f"output {str(out)!r}: folder {str(out.parent)!r} does not "
                              "exist; create it first or choose another path")
    if not os.access(out.parent, os.W_OK | os.X_OK):
        raise OutputPathError(f"output {str(out)!r}: folder {str(out.parent)!r} is not "
                              "writable")
    return out


def check_regular(out: Path, what: str = "output") -> None:
    """:class:`OutputPathError` unless ``out`` is new or a regular file (symlinks followed):
    replacing a folder, a device (``/dev/null``, a disk), a FIFO or a socket by a file would
    destroy it (run as root, ``rename(2)`` over ``/dev/null`` succeeds)."""
    try:
        if not out.exists() or out.is_file():
            return
        kind = ("an existing folder" if out.is_dir()
                else "a device, FIFO or socket, not a regular file")
    except OSError as exc:                      # a name too long, a loop of symlinks …
        raise OutputPathError(f"{what} {str(out)!r}: {exc.strerror}") from None
    raise OutputPathError(f"{what} {str(out)!r} is {kind}; consistid writes only regular "
                          "files: choose a file path")


@contextlib.contextmanager
def replacing(path: str | os.PathLike) -> Iterator[Path]:
    """A fresh temporary path beside ``path`` (same suffix, so writers that choose the format
    by suffix still work) for a writer of one file; renamed over ``path`` when the block ends
    without an exception (``os.replace``: atomic within one filesystem), removed otherwise, so
    ``path`` is never half-written. The destination is checked first
    (:func:`check_destination`)."""
    out = check_destination(path)
    tmp = out.parent / f".{out.stem}.{uuid.uuid4().hex[:12]}.part{out.suffix}"
    try:
        yield tmp
        if not tmp.is_file():
            raise OutputPathError(f"the writer of {str(out)!r} wrote no file")
        os.replace(tmp, out)
    finally:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
