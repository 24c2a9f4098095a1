"""`rssmc ros2`: a colcon workspace (the ``src`` folder) from a compiled specification.

    spec -> names checked (E860) -> values evaluated -> view-model -> one template per file

For system S with agents a_j it writes:

* ``S_interfaces`` (ament_cmake): a .msg per record, per channel sample type, Ack and
  SubsystemStatus;
* ``S_runtime`` (ament_python): the run-time support (rssm_dsl/ros2/runtime, copied) and the
  modules of the external operations and devices found next to the specification or in the
  standard library;
* ``S_<a_j>`` (ament_python) per agent: a node per subsystem, a node per device with a
  binding, ``launch/<a_j>.launch.py``, ``config/params.yaml``;
* ``S_bringup`` (ament_python): ``launch/system.launch.py`` starting every agent's nodes in
  their namespaces (launch argument ``domain_id``), ``config/system.yaml`` (a ``/**``
  section common to every node, then one section per node instance);
* ``README.md``: packages, nodes and topics.

Data topics carry standard messages where the buffer's type has a counterpart
(:mod:`rssm_dsl.ros2.stdtypes`), or the type named for the buffer in ``<spec>.ros2.toml``
(E862 when it does not fit, E863 for a file naming no buffer).

Output is deterministic (sorted, no time stamps), every file says it was generated and from
what. Templates see only :mod:`rssm_dsl.ros2.viewmodel` records.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any
from xml.sax.saxutils import escape

from jinja2 import Environment, PackageLoader, StrictUndefined

from rssm_core.records import dataclass
from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.diagnostics.diagnostic import bound_text
from rssm_dsl.emit.write import write_outputs
from rssm_dsl.filenames import file_name
from rssm_dsl.interp.initial import InitialValues
from rssm_dsl.pipeline import Compilation
from rssm_dsl.pycode import comment, tuple_source
from rssm_dsl.ros2.msgtypes import MessageTypes
from rssm_dsl.ros2.names import NameChecker
from rssm_dsl.ros2.shipping import read_shipped
from rssm_dsl.ros2.stdtypes import (
    RosType,
    explicit_diagnostic,
    load_mapping,
    mapping_path,
    resolve,
)
from rssm_dsl.ros2.viewmodel import (
    DATA_DIR,
    RUNTIME_MODULES,
    Options,
    WorkspaceView,
    build_view,
)
from rssm_dsl.syntax import ast

RUNTIME_DIR = Path(__file__).resolve().parent / "runtime"


@dataclass(frozen=True)
class Workspace:
    """The generated files (text, by path under the output folder) and the files copied
    unchanged (user and standard-library modules), plus warnings."""

    files: dict[str, str]
    copies: dict[str, Path]
    warnings: tuple[Diagnostic, ...]
    view: WorkspaceView

    @property
    def packages(self) -> list[str]:
        v = self.view
        return [v.interfaces.package, v.runtime.name, *(a.package.name for a in v.agents),
                v.bringup.package.name]


def _env() -> Environment:
    env = Environment(loader=PackageLoader("rssm_dsl.ros2", "templates"), autoescape=False,
                      undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                      keep_trailing_newline=True)
    env.filters["py"] = repr
    env.filters["pytuple"] = lambda items: tuple_source([repr(x) for x in items])
    env.filters["pylist"] = lambda items: "[" + ", ".join(repr(x) for x in items) + "]"
    env.filters["pairs"] = lambda pairs: tuple_source([f"({a!r}, {b})" for a, b in pairs])
    env.filters["xml"] = lambda s: escape(str(s), {'"': "&quot;"})
    return env


def _record_spans(comp: Compilation) -> dict[str, Any]:
    spans = {}
    for module in comp.program.modules:
        for d in module.decls:
            if isinstance(d, ast.RecordDecl | ast.EnumDecl):
                spans[d.name] = d.name_span
    return spans


def generate(comp: Compilation, options: Options | None = None) -> Workspace | list[Diagnostic]:
    """The workspace of a specification that compiled without errors, or the diagnostics
    that prevent it (E860 names, values that cannot be computed)."""
    if comp.system is None or not comp.ok:
        raise ValueError("generate needs a specification that compiled without errors")
    system = comp.system
    problems = NameChecker().check(system, _record_spans(comp))
    if problems:
        return problems
    values = InitialValues(system)
    if values.diagnostics:
        return values.diagnostics
    explicit, problems = explicit_types(comp, MessageTypes())
    if problems:
        return problems
    bindings = {d.id: d.binding for d in system.devices() if d.binding is not None}
    source = comp.path.name
    assert comp.hpn is not None
    view, shipment = build_view(system, comp.hpn, source, values, comp.path.resolve().parent,
                                bindings, options or Options(), explicit)
    files = _render(view)
    warnings = tuple(
        Diagnostic("W861", f"module '{module}' (binding \"{binding}\") is neither next to the "
                   "specification nor in the standard library: the workspace does not ship it",
                   system.span, "install it in the Python environment ROS 2 runs in")
        for module, binding in view.shipped_missing) + tuple(
        Diagnostic("W868", f"{bound_text(path)} (binding \"{binding}\") {why}", system.span,
                   "ship only the package's Python sources; give a device its data file next "
                   "to the specification, or install what the node needs in the Python "
                   "environment ROS 2 runs in")
        for path, why, binding in shipment.skipped)
    copies = {f"{view.runtime.name}/{rel}": src for rel, src in shipment.copies.items()}
    for agent in view.agents:
        for name, src in agent.data_files:
            copies[f"{agent.package.name}/{DATA_DIR}/{name}"] = src
    return Workspace(files, copies, warnings, view)


def explicit_types(comp: Compilation, msgs: MessageTypes
                   ) -> tuple[dict[str, RosType], list[Diagnostic]]:
    """The ROS types named in the specification's ``<stem>.ros2.toml``, by channel id, or
    the diagnostics of that file (E863) and of the types that do not fit (E862)."""
    assert comp.system is not None
    named, problems = load_mapping(comp.path, comp.system)
    out: dict[str, RosType] = {}
    for channel, (name, buf) in sorted(named.items()):
        found = resolve(name, buf.type, msgs.descriptor)
        if isinstance(found, str):
            problems.append(explicit_diagnostic(name, buf, found, mapping_path(comp.path)))
        else:
            out[channel] = found
    return out, problems


def _render(ws: WorkspaceView) -> dict[str, str]:
    env = _env()
    out: dict[str, str] = {}

    def header(what: str) -> str:
        return comment(f"generated by rssmc from {ws.source} (system {ws.system}): {what}; "
                       "do not edit").replace("--", "- -")

    def put(path: str, template: str, what: str, **context: Any) -> None:
        out[path] = env.get_template(template).render(ws=ws, header=header(what), **context)

    put("README.md", "README.md.j2", "workspace overview")
    ip = ws.interfaces.package
    put(f"{ip}/package.xml", "interfaces_package.xml.j2", "package manifest")
    put(f"{ip}/CMakeLists.txt", "CMakeLists.txt.j2", "interfaces build")
    for m in ws.interfaces.msgs:
        put(f"{ip}/msg/{m.name}.msg", "msg.j2", f"message {m.name}", m=m)
    rp = ws.runtime
    _python_package(put, out, rp, f"run-time support of the nodes of system {ws.system}")
    for name in RUNTIME_MODULES:
        text = (RUNTIME_DIR / f"{name}.py").read_text(encoding="utf-8")
        put(f"{rp.name}/{rp.name}/{name}.py", "runtime_module.py.j2",
            f"copy of rssm_dsl/ros2/runtime/{name}.py", text=text.rstrip("\n"))
    for agent in ws.agents:
        pkg = agent.package
        _python_package(put, out, pkg, f"agent {agent.name} of system {ws.system}")
        for node in agent.nodes:
            put(f"{pkg.name}/{pkg.name}/{node.module}.py", "node.py.j2",
                f"node of subsystem {node.id}", node=node)
        for dev in agent.devices:
            put(f"{pkg.name}/{pkg.name}/{dev.module}.py", "device.py.j2",
                f"node of device {dev.id}", dev=dev)
        put(f"{pkg.name}/launch/{file_name(agent.name, '.launch.py')}", "launch.py.j2",
            f"launch file of agent {agent.name}", agent=agent)
        put(f"{pkg.name}/config/params.yaml", "params.yaml.j2",
            f"parameters of agent {agent.name}", agent=agent)
    bp = ws.bringup.package
    _python_package(put, out, bp, f"system {ws.system}: its launch file and parameters")
    put(f"{bp.name}/launch/system.launch.py", "system.launch.py.j2",
        f"launch file of system {ws.system}")
    put(f"{bp.name}/config/system.yaml", "system.yaml.j2", f"parameters of system {ws.system}")
    return dict(sorted(out.items()))


def _python_package(put: Any, out: dict[str, str], pkg: Any, doc: str) -> None:
    put(f"{pkg.name}/package.xml", "python_package.xml.j2", "package manifest", pkg=pkg)
    put(f"{pkg.name}/setup.py", "setup.py.j2", "package setup", pkg=pkg)
    put(f"{pkg.name}/setup.cfg", "setup.cfg.j2", "package setup", pkg=pkg)
    put(f"{pkg.name}/{pkg.name}/__init__.py", "package_init.py.j2", "Python package",
        doc=comment(doc[:1].upper() + doc[1:] + "."))
    out[f"{pkg.name}/resource/{pkg.name}"] = ""


def write_workspace(ws: Workspace, target: Path) -> list[Path]:
    """Write the workspace into ``target`` (the colcon ``src`` folder), all or nothing:
    files are staged beside it and moved into place. Files of packages this workspace
    generates that are no longer generated are removed; anything else is left alone."""
    files: dict[str, str | bytes] = dict(ws.files)
    files.update({rel: read_shipped(src) for rel, src in ws.copies.items()})
    return write_outputs(target, files, replace_dirs=ws.packages)
