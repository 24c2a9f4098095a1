"""Which Python modules the workspace ships: the modules of the bindings the nodes use
(``extern ... = "module:function"``, device ``binding "module:Class"``), found where the
interpreter finds them (rssm_dsl.bindings.find_module): rssmc's standard library
(``rssm_stdlib.*``, shipped as the package ``rssm_stdlib`` with the one sub-package or module
named) or the folder of the file that declares the binding, or of the root specification
(the top-level module or package named). A module found in neither, or in a namespace
package there (a folder without ``__init__.py``), is expected to be installed in the Python
environment ROS 2 runs in (warning W861).

The semantics core, the package ``rssm_core`` (values and their operations, communication
modes, trace format), is always shipped, unchanged: the nodes run the very code the
interpreter runs.

The shipped files are copied into the runtime package beside its own Python package and
installed with it (setup.py lists them)."""

from __future__ import annotations

from dataclasses import field
from pathlib import Path

import rssm_core
from rssm_core.records import dataclass
from rssm_dsl.bindings import STDLIB_PACKAGE, BindingError, find_module
from rssm_dsl.resources import stdlib_dir

SKIP_DIRS = {"__pycache__"}
SKIP_SUFFIXES = {".pyc", ".pyo", ".rssm"}


@dataclass
class Shipment:
    copies: dict[str, Path] = field(default_factory=dict)      # relative path -> source
    packages: set[str] = field(default_factory=set)            # dotted package names
    modules: set[str] = field(default_factory=set)             # top-level single modules
    data: dict[str, set[str]] = field(default_factory=dict)    # package -> data file names
    missing: dict[str, str] = field(default_factory=dict)      # module -> binding using it

    def add_tree(self, folder: Path, package: str, rel: str) -> None:
        """Copy a package folder (recursively) as ``package`` at ``rel``."""
        self.packages.add(package)
        for path in sorted(folder.iterdir()):
            if path.name in SKIP_DIRS or path.name.startswith("."):
                continue
            if path.is_dir():
                if (path / "__init__.py").is_file():
                    self.add_tree(path, f"{package}.{path.name}", f"{rel}/{path.name}")
                continue
            if path.suffix in SKIP_SUFFIXES:
                continue
            self.copies[f"{rel}/{path.name}"] = path
            if path.suffix != ".py":
                self.data.setdefault(package, set()).add(path.name)


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
        except BindingError:
            folder = None
        if folder is not None and (folder / top / "__init__.py").is_file():
            out.add_tree(folder / top, top, top)
        elif folder is not None and (folder / f"{top}.py").is_file():
            out.modules.add(top)
            out.copies[f"{top}.py"] = folder / f"{top}.py"
        else:
            out.missing[module] = binding
    return out


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
        out.add_tree(sub, f"{STDLIB_PACKAGE}.{parts[1]}", f"{STDLIB_PACKAGE}/{parts[1]}")
    elif (root / f"{parts[1]}.py").is_file():
        out.copies[f"{STDLIB_PACKAGE}/{parts[1]}.py"] = root / f"{parts[1]}.py"
    else:
        out.missing[".".join(parts)] = binding
