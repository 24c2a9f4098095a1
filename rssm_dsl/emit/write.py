"""Write a set of output files all or nothing: into a temporary folder beside the target,
then moved into place; on any failure the target folder is left as it was."""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Iterable, Mapping
from pathlib import Path

from rssm_dsl.filenames import check_output_path


def write_outputs(target: Path, files: Mapping[str, str | bytes],
                  replace_dirs: Iterable[str] = ()) -> list[Path]:
    """Write ``files`` (name relative to ``target`` -> text, or bytes for binary files).
    The subfolders ``replace_dirs`` of ``target`` are emptied first (once everything is
    staged), so files no longer generated there disappear; anything else is left alone.
    Every name is checked first (rssm_dsl.filenames.check_output_path): a name that cannot
    be a file name raises before anything is written."""
    for rel in files:
        check_output_path(rel)
    target = target.resolve()
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        staging = Path(tempfile.mkdtemp(prefix=".rssmc-", dir=target.parent))
    except OSError as e:                  # name the user's folder, not the staging one
        raise OSError(e.errno, e.strerror, str(target)) from e
    try:
        for rel, text in files.items():
            path = staging / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            if isinstance(text, bytes):
                path.write_bytes(text)
            else:
                path.write_text(text, encoding="utf-8")
        target.mkdir(parents=True, exist_ok=True)
        _check_places(target, files, tuple(replace_dirs))
        for sub in replace_dirs:
            shutil.rmtree(target / sub, ignore_errors=True)
        written: list[Path] = []
        for rel in sorted(files):
            dest = target / rel
            dest.parent.mkdir(parents=True, exist_ok=True)
            os.replace(staging / rel, dest)
            written.append(dest)
        return written
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _check_places(target: Path, files: Mapping[str, str | bytes],
                  replaced: tuple[str, ...]) -> None:
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
