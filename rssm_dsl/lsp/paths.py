"""Files as the compiler names them (display paths) and as the editor does (URIs).

Whatever URI the editor sends, the path of its document resolves (Path.resolve, which the
compiler calls on it, does not raise): a URI that is no file (`untitled:`), or whose file
has no usable path (a NUL in it, a symbolic link loop, a host the URI parser refuses), gets
a stable made-up path, beside the file when its directory resolves (its imports are then
found as they would be), else in the working directory. The compiler never reads a
document's path: it gets the editor's text (the analysis's overrides).
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path
from urllib.parse import unquote, urlparse

from pygls import uris

from rssm_dsl.resources import stdlib_dir
from rssm_dsl.semantics.loader import STDLIB_PREFIX

_untitled = itertools.count(1)
_untitled_paths: dict[str, Path] = {}
_UNSAFE = re.compile(r"[^\w.+-]")
MAX_NAME = 64       # characters of the URI's last segment kept in a made-up file name


def resolved(path: Path) -> Path | None:
    """`path.resolve()`, or None when it cannot be resolved (a symbolic link loop, a NUL or
    a character the file system cannot encode)."""
    try:
        return path.resolve()
    except (OSError, RuntimeError, ValueError):
        return None


def path_of_uri(uri: str) -> Path:
    """The file of a document; documents that are not files (or whose file's path cannot be
    resolved) get a stable made-up path that can."""
    made_up = _untitled_paths.get(uri)
    if made_up is not None:
        return made_up
    fs = file_path_of_uri(uri)
    if fs is not None and resolved(fs) is not None:
        return fs
    name = _UNSAFE.sub("_", fs.name if fs is not None else _last_segment(uri))[:MAX_NAME]
    name = name or "untitled"
    if not name.endswith(".rssm"):
        name += ".rssm"
    folder = resolved(fs.parent) if fs is not None else None
    path = (folder or Path.cwd()) / f".untitled-{next(_untitled)}-{name}"
    _untitled_paths[uri] = path
    return path


def file_path_of_uri(uri: str) -> Path | None:
    """The path of a `file:` URI (None for another scheme or a URI that does not parse)."""
    try:
        if urlparse(uri).scheme != "file":
            return None
        fs = uris.to_fs_path(uri)
    except ValueError:     # e.g. file://[x/a.rssm: an invalid IPv6 host
        return None
    return Path(fs) if fs else None


def _last_segment(uri: str) -> str:
    try:
        path = urlparse(uri).path
    except ValueError:
        path = uri
    return unquote(path).rsplit("/", 1)[-1]


def path_of_display(display: str) -> Path:
    """The resolved path of a file the compiler named `display` (absolute, if it no longer
    resolves)."""
    if display.startswith(STDLIB_PREFIX):
        path = stdlib_dir() / display.removeprefix(STDLIB_PREFIX)
    else:
        path = Path(display)
    return resolved(path) or path.absolute()


def uri_of_path(path: Path) -> str:
    for uri, p in _untitled_paths.items():
        if p == path:
            return uri
    real = resolved(path) or path.absolute()
    return uris.from_fs_path(str(real)) or real.as_uri()


def is_stdlib(display: str) -> bool:
    return display.startswith(STDLIB_PREFIX)
