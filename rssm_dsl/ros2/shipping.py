"""Which Python modules the workspace ships: the modules of the bindings the nodes use
(``extern ... = "module:function"``, device ``binding "module:Class"``), found where the
interpreter finds them (rssm_dsl.bindings.find_module): rssmc's standard library
(``rssm_stdlib.*``, shipped as the package ``rssm_stdlib`` with the one sub-package or module
named) or the folder of the file that declares the binding, or of the root specification
(the top-level module or package named). A module found in neither, or in a namespace
package there (a folder without ``__init__.py``), is expected to be installed in the Python
environment ROS 2 runs in (warning W861).

Of a user's package only its Python sources are shipped (``*.py``, and its sub-packages:
folders with ``__init__.py``), each a regular file of the package. Nothing is followed out of
the package: a symbolic link is shipped only when it leads to a Python source inside the
package (or, for the module or package itself, inside the folder it is found in); other
links, special files (FIFOs, sockets, devices) and files that are not Python sources are left
out, each with warning W868 (the files that are not Python sources, one warning per package).
Nothing left out is opened. The semantics core (``rssm_core``) and the standard library are
rssmc's own: their data files (a MuJoCo model, a robot table) are shipped too, by the same
rules otherwise.

The semantics core, the package ``rssm_core`` (values and their operations, communication
modes, trace format), is always shipped, unchanged: the nodes run the very code the
interpreter runs.

The shipped files are copied into the runtime package beside its own Python package and
installed with it (setup.py lists them); they are read with :func:`read_shipped`, which
reads regular files only."""

from __future__ import annotations

import os
import stat
from dataclasses import field
from pathlib import Path

import rssm_core
from rssm_core.records import dataclass
from rssm_dsl.bindings import STDLIB_PACKAGE, BindingError, find_module
from rssm_dsl.resources import stdlib_dir
from rssm_dsl.source import file_kind

SKIP_DIRS = {"__pycache__"}
SKIP_SUFFIXES = {".pyc", ".pyo", ".rssm"}
# a shipped file larger than this is not read (no Python source or data file of a package is)
MAX_SHIPPED_BYTES = 64 << 20
# the names of files left out shown in one warning
SHOWN = 5


@dataclass
class Shipment:
    copies: dict[str, Path] = field(default_factory=dict)      # relative path -> source
    packages: set[str] = field(default_factory=set)            # dotted package names
    modules: set[str] = field(default_factory=set)             # top-level single modules
    data: dict[str, set[str]] = field(default_factory=dict)    # package -> data file names
    missing: dict[str, str] = field(default_factory=dict)      # module -> binding using it
    # what was left out (W868): (the file or folder, why, the binding that wanted it)
    skipped: list[tuple[str, str, str]] = field(default_factory=list)

    def add_tree(self, folder: Path, package: str, rel: str, with_data: bool = True,
                 binding: str = "") -> None:
        """Copy a package folder (its sub-packages too) as ``package`` at ``rel``: its Python
        sources, and its data files when ``with_data`` (rssmc's own packages). Links are not
        followed out of ``folder``; special files are left out (``skipped``)."""
        root = folder.resolve()
        todo = [(folder, package, rel)]
        while todo:        # not recursive: a package may be nested deeper than Python recurses
            here, name, at = todo.pop()
            self.packages.add(name)
            other: list[str] = []
            try:
                entries = sorted(os.scandir(here), key=lambda e: e.name)
            except OSError as e:
                self.skipped.append((str(here), f"cannot be listed ({e.strerror or e})",
                                     binding))
                continue
            subs = []
            for entry in entries:
                if entry.name in SKIP_DIRS or entry.name.startswith("."):
                    continue
                path = Path(entry.path)
                source, why = _entry(path, root)
                if why is not None:
                    self.skipped.append((str(path), why, binding))
                    continue
                if source is None:          # a folder of the package's own
                    if _exists(path / "__init__.py"):
                        subs.append((path, f"{name}.{entry.name}", f"{at}/{entry.name}"))
                    continue
                if path.suffix in SKIP_SUFFIXES:
                    continue
                if path.suffix != ".py":
                    if not with_data:
                        other.append(entry.name)
                        continue
                    self.data.setdefault(name, set()).add(entry.name)
                self.copies[f"{at}/{entry.name}"] = source
            if other:
                shown = ", ".join(other[:SHOWN]) + (f" and {len(other) - SHOWN} more"
                                                    if len(other) > SHOWN else "")
                self.skipped.append((str(here), f"holds {len(other)} file(s) that are not "
                                     f"Python sources, not shipped: {shown}", binding))
            todo.extend(reversed(subs))


def _inside(path: Path, root: Path) -> bool:
    return path == root or root in path.parents


def _entry(path: Path, root: Path, python: bool = True) -> tuple[Path | None, str | None]:
    """What an entry of a folder under ``root`` ships from: (the regular file to copy, None)
    or (None, None) for a folder (not a link); (None, why) when it is left out. Nothing is
    opened, and a link is followed only to a regular file in ``root`` (a Python source when
    ``python``)."""
    try:
        st = path.lstat()
    except OSError as e:
        return None, f"cannot be read ({e.strerror or e})"
    if stat.S_ISDIR(st.st_mode):
        return None, None
    if stat.S_ISREG(st.st_mode):
        return path, None
    if not stat.S_ISLNK(st.st_mode):
        return None, f"is {_kind(st.st_mode)}, not a regular file: not shipped"
    try:
        target = path.resolve(strict=True)
        tst = target.stat()
    except (OSError, RuntimeError):
        return None, "is a symbolic link that leads nowhere (broken, or a loop): not followed"
    if not _inside(target, root):
        return None, f"is a symbolic link out of {root}: not followed"
    if not stat.S_ISREG(tst.st_mode) or (python and (target.suffix != ".py"
                                                      or path.suffix != ".py")):
        what = "a Python source" if python else "a regular file"
        return None, f"is a symbolic link to something other than {what} of {root}: not followed"
    return target, None


def _kind(mode: int) -> str:
    """"a FIFO", "a character device", ... (rssm_dsl.source.file_kind's words)."""
    return file_kind(mode).strip(" ()") or "a special file"


def read_shipped(path: Path) -> bytes:
    """The bytes of a file to ship: a regular file only (not a link's target, a FIFO or a
    device, should the file have been replaced since it was chosen), at most
    MAX_SHIPPED_BYTES; OSError otherwise."""
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise OSError(f"{path} is not a regular file: not shipped")
        if st.st_size > MAX_SHIPPED_BYTES:
            raise OSError(f"{path} is larger than {MAX_SHIPPED_BYTES >> 20} MB: not shipped")
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read(MAX_SHIPPED_BYTES + 1)
        if len(data) > MAX_SHIPPED_BYTES:
            raise OSError(f"{path} is larger than {MAX_SHIPPED_BYTES >> 20} MB: not shipped")
        return data
    finally:
        os.close(fd)


def shippable_file(path: Path, folder: Path) -> tuple[Path | None, str | None]:
    """A file next to the specification that the workspace ships as it is (a device's CSV
    file): (the regular file to copy, None); (None, why) when it is there but left out (a
    special file, a link out of ``folder``); (None, None) when there is no such file."""
    if not _exists(path):
        return None, None
    return _entry(path, folder.resolve(), python=False)


def ship(modules: dict[str, tuple[str, list[Path]]]) -> Shipment:
    """``modules`` maps each module to ship to a binding that uses it (for messages) and the
    folders it is looked up in (rssm_dsl.bindings.binding_dirs)."""
    out = Shipment()
    out.add_tree(Path(rssm_core.__file__).resolve().parent, "rssm_core", "rssm_core")
    for module, (binding, dirs) in sorted(modules.items()):
        parts = module.split(".")
        if parts[0] == STDLIB_PACKAGE:
            _ship_stdlib(out, parts, binding)
            continue
        top = parts[0]
        try:
            found = find_module(module, dirs).folder
            folder = found.resolve() if found is not None else None
        except (BindingError, OSError, RuntimeError):
            folder = None
        if folder is None:
            out.missing[module] = binding
            continue
        package, module_file = folder / top, folder / f"{top}.py"
        if _is_package(package):
            where, why = _top_level(package, folder)
            if where is not None:
                out.add_tree(where, top, top, with_data=False, binding=binding)
            else:
                out.skipped.append((str(package), why or "not shipped", binding))
        elif _exists(module_file):
            where, why = _top_level(module_file, folder)
            if where is not None and why is None:
                out.modules.add(top)
                out.copies[f"{top}.py"] = where
            else:
                out.skipped.append((str(module_file), why or "not shipped", binding))
        else:
            out.missing[module] = binding
    return out


def _exists(path: Path) -> bool:
    try:
        path.lstat()
    except OSError:
        return False
    return True


def _is_package(path: Path) -> bool:
    try:
        return (path / "__init__.py").is_file()
    except OSError:
        return False


def _top_level(path: Path, folder: Path) -> tuple[Path | None, str | None]:
    """The module file or package folder a binding names, found in ``folder``: where it is
    shipped from (a link followed only to a place inside ``folder``), or why it is not."""
    try:
        st = path.lstat()
    except OSError as e:
        return None, f"cannot be read ({e.strerror or e})"
    if stat.S_ISLNK(st.st_mode):
        try:
            target = path.resolve(strict=True)
            st = target.stat()
        except (OSError, RuntimeError):
            return None, "is a symbolic link that leads nowhere (broken, or a loop): not followed"
        if not _inside(target, folder):
            return None, (f"is a symbolic link out of {folder}: not followed (copy the "
                          "module there, or install it in the Python environment of ROS 2)")
        path = target
    if stat.S_ISDIR(st.st_mode) or stat.S_ISREG(st.st_mode):
        return path, None
    return None, f"is {_kind(st.st_mode)}, not a regular file: not shipped"


def _ship_stdlib(out: Shipment, parts: list[str], binding: str) -> None:
    root = stdlib_dir()
    out.packages.add(STDLIB_PACKAGE)
    init = root / "__init__.py"
    if init.is_file():
        out.copies[f"{STDLIB_PACKAGE}/__init__.py"] = init
    if len(parts) < 2:
        return
    sub = root / parts[1]
    if (sub / "__init__.py").is_file():
        out.add_tree(sub, f"{STDLIB_PACKAGE}.{parts[1]}", f"{STDLIB_PACKAGE}/{parts[1]}",
                     binding=binding)
    elif (root / f"{parts[1]}.py").is_file():
        out.copies[f"{STDLIB_PACKAGE}/{parts[1]}.py"] = root / f"{parts[1]}.py"
    else:
        out.missing[".".join(parts)] = binding
