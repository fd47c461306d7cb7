"""CLI file safety: check output paths before the long work, never overwrite an input, never
overwrite an existing output without ``--force``, and write atomically.

Rules (issue 14), for every ``consistid`` subcommand that writes files:

1. **Check first.** :func:`check_output` (a file) or :func:`check_output_dir` (a folder of
   files) runs *before* any simulation, identification or design, so a bad path costs nothing.
2. **Never over an input.** An output that resolves (symlinks followed) to one of the run's
   inputs — the configuration, a URDF, a data file — is refused even with ``--force``.
3. **No silent overwrite.** An existing output is refused unless ``force=True`` (``--force``).
4. **Inputs exist.** :func:`check_inputs` runs before the work too: every input the result's
   provenance will record (files, and ROS 2 bag folders) must be there, so that a run never
   ends in an error after its work.
5. **Atomic.** :func:`atomic_path` hands the writer a temporary file in the same folder (same
   suffix, so writers that choose the format by suffix still work) and renames it over the target
   only when the writer returned (``os.replace``: atomic on POSIX and Windows within one
   filesystem); on failure the temporary file is removed and the target is untouched.
   :func:`atomic_dir` does the same for a folder of files: a new folder appears whole (one
   rename), files into an existing one are renamed under a journal that readers check, and
   SIGINT/SIGTERM wait for the renames (:mod:`consistid.filesafety`).
6. **One writer.** A checked output is locked until the command ends
   (:func:`consistid.filesafety.lock_output`): a second run asking for the same output is
   refused by name instead of replacing the first one's files. A folder of files
   (:func:`check_output_dir`) is held alone; a file (:func:`check_output`) is held alone and
   its folder shared, so a file of one command (``rollout --output DIR/r.html``) never lands
   among the set another writes into the same folder (``identify --output DIR``).

Usage in a subcommand::

    inputs = config_inputs(config)                     # consistid.cli.config
    out = check_output(args.output, inputs=inputs, force=args.force, what="--output")
    ...                                                # the long work
    with atomic_path(out) as tmp:
        design.save_csv(tmp, rate)
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from pathlib import Path
from typing import Iterable, Iterator

from ..errors import ConfigError, OutputPathError, ResultFileError
from ..identification.persistence import check_input
from ..filesafety import (check_regular, commit_folder, lock_output, lock_output_file,
                          replacing, signals_deferred)

__all__ = ["check_output", "check_output_dir", "check_inputs", "atomic_path", "atomic_dir",
           "same_file"]


def _resolved(path: str | os.PathLike) -> Path:
    return Path(path).expanduser().resolve()


def same_file(a: str | os.PathLike, b: str | os.PathLike) -> bool:
    """Whether ``a`` and ``b`` name the same file (after resolving symlinks and ``..``; hard
    links to an existing file count too)."""
    ra, rb = _resolved(a), _resolved(b)
    if ra == rb:
        return True
    try:
        return ra.exists() and rb.exists() and os.path.samefile(ra, rb)
    except OSError:
        return False


def check_inputs(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """The run's inputs resolved, each a file or a folder (a ROS 2 bag folder), else
    :class:`ConfigError` naming it — called before the work, with the same rule the result's
    provenance applies when it records them
    (:func:`consistid.identification.persistence.input_record`)."""
    out = []
    for path in inputs:
        try:
            out.append(check_input(path))
        except ResultFileError:
            raise ConfigError(f"input {str(path)!r} does not exist: name a file, or a ROS 2 bag "
                              "folder (the folder holding metadata.yaml)") from None
    return out


def _check_not_input(path: Path, inputs: Iterable[str | os.PathLike], what: str) -> None:
    for source in inputs:
        if same_file(path, source):
            raise OutputPathError(
                f"{what} {str(path)!r} is an input of this run ({str(source)!r}): consistid "
                "never writes over its inputs, even with --force; choose another output path")


def _check_not_inside_input(out: Path, inputs: Iterable[str | os.PathLike], what: str) -> None:
    """An output folder is no input folder (a ROS 2 bag folder) nor inside one: its files
    would change what the input holds."""
    for source in inputs:
        src = _resolved(source)
        if src.is_dir() and (out == src or src in out.parents):
            raise OutputPathError(
                f"{what} {str(out)!r} is inside the input folder {str(source)!r}: consistid "
                "never writes into its inputs; choose an output folder elsewhere")


def _check_folder(folder: Path, what: str, path: Path) -> None:
    if not folder.is_dir():
        raise OutputPathError(f"{what} {str(path)!r}: folder {str(folder)!r} does not exist; "
                              "create it first or choose another path")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputPathError(f"{what} {str(path)!r}: folder {str(folder)!r} is not writable")


def _check_target(target: Path, inputs: Iterable[str | os.PathLike], force: bool, what: str,
                  other: str) -> None:
    """An output file ``target`` is no input, no folder, and new unless ``force``; the
    message names it after ``what`` and says to choose another ``other`` (path, folder)."""
    _check_not_input(target, inputs, what.rstrip(":"))
    check_regular(target, what.rstrip(":"))         # a folder, a device, a FIFO
    if target.exists() and not force:
        raise OutputPathError(f"{what} {str(target)!r} exists; pass --force to replace it (or "
                              f"choose another {other})")


def check_output(path: str | os.PathLike, *, inputs: Iterable[str | os.PathLike] = (),
                 force: bool = False, what: str = "output") -> Path:
    """The output file ``path`` (absolute) if it is safe to write, else :class:`OutputPathError`.

    Parameters
    ----------
    path : the file the command will write.
    inputs : every file the run reads (configuration, URDFs, data): never written over.
    force : replace an existing output (``--force``); inputs stay protected.
    what : how the message names the output (``"--output"``, ``"[recover] urdf"`` …).

    Raises
    ------
    OutputPathError : ``path`` is an input, an existing folder, an existing file without
        ``force``, or its folder does not exist or is not writable.
    """
    if path is None or str(path) == "":
        raise OutputPathError(f"{what} is empty: give a file path")
    with _os_errors(what, path):
        out = _resolved(path)
        _check_target(out, inputs, force, what, "path")
        _check_folder(out.parent, what, out)
    lock_output_file(out, what)
    return out


@contextlib.contextmanager
def _os_errors(what: str, path: str | os.PathLike) -> Iterator[None]:
    """An ``OSError`` of a path check (a name longer than the filesystem allows, a loop of
    symlinks) as :class:`OutputPathError` naming the option and the path."""
    try:
        yield
    except OSError as exc:
        raise OutputPathError(f"{what} {str(path)!r}: {exc.strerror or exc}; choose another "
                              "path") from None


def check_output_dir(path: str | os.PathLike, names: Iterable[str], *,
                     inputs: Iterable[str | os.PathLike] = (), force: bool = False,
                     what: str = "output") -> Path:
    """The output folder ``path`` (absolute) if writing ``names`` into it is safe, else
    :class:`OutputPathError`. The folder itself may exist (or will be created, its parent must
    exist); each of ``names`` that exists needs ``force``; none may be an input."""
    if path is None or str(path) == "":
        raise OutputPathError(f"{what} is empty: give a folder path")
    inputs = list(inputs)
    with _os_errors(what, path):
        out = _resolved(path)
        if out.exists() and not out.is_dir():
            raise OutputPathError(f"{what} {str(out)!r} is an existing file, not a folder")
        _check_not_inside_input(out, inputs, what)
        for name in names:
            _check_target(out / name, inputs, force, f"{what}:", "folder")
        _check_folder(out if out.is_dir() else out.parent, what, out)
    lock_output(out, what)
    return out


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path beside ``path`` (same suffix) for a writer; renamed over ``path`` when
    the ``with`` block ends without an exception, removed otherwise (``path`` untouched;
    :func:`consistid.filesafety.replacing`)."""
    with replacing(path) as tmp:
        yield tmp


@contextlib.contextmanager
def atomic_dir(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary folder beside ``path`` for a writer of several files; on success the set is
    moved into ``path`` whole (:func:`consistid.filesafety.commit_folder`: a new folder is the
    temporary one renamed; other files of an existing one are left alone), on failure or
    interruption the temporary folder is removed and ``path`` untouched."""
    out = _resolved(path)
    parent = out if out.is_dir() else out.parent
    tmp = None
    try:
        with signals_deferred():                # a signal here must not leak the folder
            tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.part-", dir=parent))
        yield tmp
        commit_folder(tmp, out)
    finally:
        if tmp is not None:
            with signals_deferred():            # nor one during the clean-up
                shutil.rmtree(tmp, ignore_errors=True)
