"""Write a set of output files all or nothing: into a temporary folder beside the target,
then moved into place; on any failure the target folder is left as it was."""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import TracebackType

from rssm_dsl.filenames import check_output_path

# what is written to one file: its text, its bytes (a binary file), or its text in pieces
# (a large output written as it is made, never held whole)
Content = str | bytes | Iterable[str]


def write_outputs(target: Path, files: Mapping[str, str | bytes],
                  replace_dirs: Iterable[str] = ()) -> list[Path]:
    """Write ``files`` (name relative to ``target`` -> text, or bytes for binary files).
    The subfolders ``replace_dirs`` of ``target`` are emptied first (once everything is
    staged), so files no longer generated there disappear; anything else is left alone.
    Every name is checked first (rssm_dsl.filenames.check_output_path): a name that cannot
    be a file name raises before anything is written."""
    for rel in files:
        check_output_path(rel)
    with Staging(target) as staging:
        staging.folder()
        for rel, content in files.items():
            staging.write(rel, content)
        return staging.commit(replace_dirs)


class Staging:
    """Output files staged one by one in a temporary folder beside ``target`` (made at the
    first write), then moved into place together by :meth:`commit`. Leaving the ``with``
    block removes the folder and whatever is still in it: after a failure, nothing of the
    outputs is in the target. Several processes may write into the folder (:meth:`folder`
    made before they start); the one that commits is told the names the others wrote
    (:meth:`add`)."""

    def __init__(self, target: Path) -> None:
        self.target = target.resolve()
        self.names: list[str] = []            # staged, in the order written (no repeats)
        self._folder: Path | None = None
        self._made: list[Path] = []           # the target's missing parents, made for it
        self._committed = False

    def __enter__(self) -> Staging:
        return self

    def __exit__(self, kind: type[BaseException] | None, error: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
        if not self._committed:           # a failure: the folders made for it go too
            for parent in reversed(self._made):
                with contextlib.suppress(OSError):
                    parent.rmdir()

    def folder(self) -> Path:
        """The staging folder, made on first use."""
        if self._folder is None:
            try:
                missing = [p for p in self.target.parents if not p.exists()]
                self.target.parent.mkdir(parents=True, exist_ok=True)
                self._made = missing[::-1]
                self._folder = Path(tempfile.mkdtemp(prefix=".rssmc-", dir=self.target.parent))
            except OSError as e:          # name the user's folder, not the staging one
                raise OSError(e.errno, e.strerror, str(self.target)) from e
        return self._folder

    def write(self, rel: str, content: Content) -> None:
        """Stage one file (its name checked first: rssm_dsl.filenames.check_output_path)."""
        check_output_path(rel)
        path = self.folder() / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif isinstance(content, str):
            path.write_text(content, encoding="utf-8")
        else:
            with path.open("w", encoding="utf-8") as f:     # as write_text opens it
                f.writelines(content)
        self.add([rel])

    def add(self, names: Iterable[str]) -> None:
        """Names of files staged by another process."""
        for rel in names:
            if rel not in self.names:
                self.names.append(rel)

    def commit(self, replace_dirs: Iterable[str] = ()) -> list[Path]:
        """Move every staged file into place, after checking that each one's place is free.
        The subfolders ``replace_dirs`` of the target are emptied first (see
        :func:`write_outputs`). Returns the paths written, sorted."""
        staging, target, names = self.folder(), self.target, self.names
        self._committed = True            # (the target's folders stay, even if a move fails)
        target.mkdir(parents=True, exist_ok=True)
        replaced = tuple(replace_dirs)
        _check_places(target, names, replaced)
        for sub in replaced:
            shutil.rmtree(target / sub, ignore_errors=True)
        written: list[Path] = []
        for rel in sorted(names):
            dest = target / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(staging / rel, dest)
            written.append(dest)
        return written


def _check_places(target: Path, files: Iterable[str], replaced: tuple[str, ...]) -> None:
    """Raise before anything is moved when an output's place is taken: the file's name by a
    folder (or a FIFO, a device), or one of its folders by a file; so that a failure leaves
    the target as it was, not half written."""
    for rel in files:
        if any(rel == sub or rel.startswith(sub + "/") for sub in replaced):
            continue
        dest = target / rel
        if not dest.is_symlink() and dest.exists() and not dest.is_file():
            raise OSError(errno.EISDIR, "the place of an output file is taken by something "
                          "that is not a regular file", str(dest))
        for parent in dest.parents:
            if parent == target:
                break
            if parent.exists() and not parent.is_dir():
                raise OSError(errno.ENOTDIR, "the folder of an output file is taken by a "
                              "file", str(parent))
