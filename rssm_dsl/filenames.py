"""The one way a name of a specification becomes a file or directory name.

Output files and folders are named after names of the specification: ``<system>.hpn.json``,
``<system>.html``, the ROS 2 packages ``<system>_<agent>``, ``<agent>.launch.py``,
``node_e_<subsystem>.py``, ``device_E_<device>.py``, ``<Record>.msg``, the figures
``fig-<page id>.svg``. One path component is at most 255 bytes (NAME_MAX on Linux and macOS,
255 UTF-16 units on Windows); a specification name that becomes part of one is at most
:data:`MAX_NAME_LENGTH` characters, which leaves room for what is put around it (two names
and a suffix still fit: ``<system>_<agent>`` is at most 201 bytes).

- :func:`file_name` turns a name into a file name, checked (:class:`UnusableFileName`);
- :func:`name_problem` says why a name cannot become one (the loader reports it as E011 at
  the name, so nothing is ever written under an unusable name);
- :func:`fitted_file_name` makes a file name of a derived stem (a page id) that is not
  checked but made to fit: unusable characters become ``-`` and a long stem is cut and
  ended by a hash of the whole stem, so that distinct stems stay distinct;
- :func:`is_file` looks a path up where a name becomes one (an import, a binding's module):
  a name the file system cannot take is not there, it does not raise;
- :func:`check_output_path` is the last guard of the writer (rssm_dsl/emit/write.py): every
  component of every path it is given can be a file name, before anything is written.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path

NAME_MAX_BYTES = 255          # one path component (a file or directory name), in UTF-8 bytes
MAX_NAME_LENGTH = 100         # a specification name that names a file or folder (ASCII: bytes)
MAX_FITTED_BYTES = 200        # a derived file name: room left for `-2` de-duplication and more

# Not in a file name on some system we write for: the path separators, NUL and the other
# control characters, and the characters Windows reserves.
_UNUSABLE = re.compile(r'[\x00-\x1f\x7f/\\:*?"<>|]')


class UnusableFileName(ValueError):
    """A name cannot be (part of) a file or directory name."""

    def __init__(self, name: str, reason: str) -> None:
        shown = name if len(name) <= 40 else name[:30] + "…" + name[-8:]
        super().__init__(f"'{shown}' cannot name a file: {reason}")
        self.name = name
        self.reason = reason


def name_problem(name: str, limit: int = MAX_NAME_LENGTH) -> str | None:
    """Why ``name`` cannot be part of a file or directory name, or None when it can."""
    if not name:
        return "it is empty"
    if name in (".", ".."):
        return f"'{name}' names a folder"
    bad = _UNUSABLE.search(name)
    if bad is not None:
        return f"it contains {bad.group()!r}, which cannot be in a file name"
    size = len(name.encode("utf-8"))
    if size > limit:
        if size == len(name):
            return f"it is {size} characters long; the limit is {limit}"
        return f"it is {len(name)} characters long ({size} bytes in UTF-8); the limit is {limit} bytes"
    return None


def _component(whole: str) -> str:
    """``whole`` if it can be one path component, else :class:`UnusableFileName`."""
    if len(whole.encode("utf-8")) > NAME_MAX_BYTES or name_problem(whole, NAME_MAX_BYTES):
        raise UnusableFileName(whole, f"a file name is at most {NAME_MAX_BYTES} bytes, "
                               "without control characters or any of /\\:*?\"<>|")
    return whole


def file_name(name: str, suffix: str = "", prefix: str = "") -> str:
    """``prefix + name + suffix`` as one file or directory name. ``name`` comes from the
    specification and is checked (:func:`name_problem`); ``prefix`` and ``suffix`` are the
    compiler's own. Raises :class:`UnusableFileName` (the loader reports the names that
    would, E011, so this raises only on a compiler bug)."""
    problem = name_problem(name)
    if problem is not None:
        raise UnusableFileName(name, problem)
    return _component(prefix + name + suffix)


def fitted_file_name(stem: str, suffix: str = "") -> str:
    """A file name for ``stem + suffix`` where ``stem`` is derived from several names (e.g.
    a page id): characters that cannot be in a file name become ``-``; a stem too long for
    :data:`MAX_FITTED_BYTES` is cut and ended by ``~`` and 12 hex digits of a hash of the
    whole stem."""
    clean = _UNUSABLE.sub("-", stem) or "-"
    if clean in (".", ".."):
        clean = clean.replace(".", "-")
    room = MAX_FITTED_BYTES - len(suffix.encode("utf-8"))
    if len(clean.encode("utf-8")) > room:
        digest = hashlib.sha256(stem.encode("utf-8")).hexdigest()[:12]
        head = clean.encode("utf-8")[: room - 13].decode("utf-8", errors="ignore")
        clean = f"{head}~{digest}"
    return _component(clean + suffix)


def check_output_path(rel: str) -> None:
    """Raise :class:`UnusableFileName` unless every component of the relative path ``rel``
    (``/``-separated) can be a file or directory name (and none is ``.`` or ``..``)."""
    for part in rel.split("/"):
        if part in ("", ".", ".."):
            raise UnusableFileName(rel, f"'{part}' is not a file or directory name")
        _component(part)


def is_file(path: Path) -> bool:
    """Whether ``path`` is a file. False, not an exception, when it cannot even be looked up:
    a component longer than the file system takes (ENAMETOOLONG), a NUL, no permission
    (``Path.is_file`` raises on all but a few errors)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False
