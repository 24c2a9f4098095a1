"""Files as the compiler names them (display paths) and as the editor does (URIs)."""

from __future__ import annotations

import itertools
from pathlib import Path
from urllib.parse import unquote, urlparse

from pygls import uris

from rssm_dsl.resources import stdlib_dir
from rssm_dsl.semantics.loader import STDLIB_PREFIX

_untitled = itertools.count(1)
_untitled_paths: dict[str, Path] = {}


def path_of_uri(uri: str) -> Path:
    """The file of a document; documents that are not files get a stable made-up path."""
    if urlparse(uri).scheme == "file":
        fs = uris.to_fs_path(uri)
        if fs:
            return Path(fs)
    if uri not in _untitled_paths:
        name = Path(unquote(urlparse(uri).path or "untitled")).name or "untitled"
        if not name.endswith(".rssm"):
            name += ".rssm"
        _untitled_paths[uri] = Path.cwd() / f".untitled-{next(_untitled)}-{name}"
    return _untitled_paths[uri]


def path_of_display(display: str) -> Path:
    if display.startswith(STDLIB_PREFIX):
        return stdlib_dir() / display.removeprefix(STDLIB_PREFIX)
    return Path(display).resolve()


def uri_of_path(path: Path) -> str:
    for uri, p in _untitled_paths.items():
        if p == path:
            return uri
    return uris.from_fs_path(str(path.resolve())) or path.resolve().as_uri()


def is_stdlib(display: str) -> bool:
    return display.startswith(STDLIB_PREFIX)
