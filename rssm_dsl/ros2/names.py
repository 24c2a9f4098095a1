"""The names a ROS 2 workspace is made of, derived from the specification's names and
checked before they reach any template (diagnostic E860).

| specification name | becomes                           | rule checked                         |
|--------------------|-----------------------------------|--------------------------------------|
| system, agent      | package ``<system>_<agent>``      | REP 144 (lower-cased first)          |
| agent              | namespace ``/<agent>``            | ROS name token                       |
| subsystem, device  | node ``c``, ``e_<n>``, ``E_<n>`` …| ROS name token                       |
| buffer             | topic ``/<agent>/<node>/<buffer>``| ROS name token                       |
| record             | message ``<Pascal>`` (lwr_state → LwrState) | ``[A-Z][A-Za-z0-9]*``, unique |
| record field       | message field                     | rosidl's rule, no C++/Python keyword |
| enum member        | message constant ``PHASE_IDLE``   | rosidl's rule, unique, <= 256 members |

REP 144 and rosidl: ``[a-z][a-z0-9_]*``, no ``__``, no trailing ``_``.
| binding            | ``module:attribute``              | dotted Python identifiers            |

Every other name (behaviours, memory, parameters, conditions, locals) only ever appears in
generated Python as a mangled identifier (``v_<name>``) or inside a string literal written
with ``repr``; it is still checked to be an ASCII identifier.
"""

from __future__ import annotations

import keyword
import re

from rssm_dsl.diagnostics import Diagnostic
from rssm_dsl.semantics.model import Agent, Device, Subsystem, System
from rssm_dsl.semantics.types import ArrayT, EnumT, RecordT, Type
from rssm_dsl.source import Span

IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
ROS_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
PACKAGE = re.compile(r"[a-z][a-z0-9_]*\Z")
MSG_NAME = re.compile(r"[A-Z][A-Za-z0-9]*\Z")
MSG_FIELD = re.compile(r"[a-z][a-z0-9_]*\Z")
MSG_CONSTANT = re.compile(r"[A-Z]([A-Z0-9_]?[A-Z0-9]+)*\Z")   # rosidl's constant names

# Names rosidl's C++ and Python generators cannot take as field names.
CPP_KEYWORDS = frozenset((
    "alignas", "alignof", "and", "and_eq", "asm", "auto", "bitand", "bitor", "bool",
    "break", "case", "catch", "char", "char8_t", "char16_t", "char32_t", "class", "compl",
    "concept", "const", "consteval", "constexpr", "constinit", "const_cast", "continue",
    "co_await", "co_return", "co_yield", "decltype", "default", "delete", "do", "double",
    "dynamic_cast", "else", "enum", "explicit", "export", "extern", "false", "float",
    "for", "friend", "goto", "if", "inline", "int", "long", "mutable", "namespace", "new",
    "noexcept", "not", "not_eq", "nullptr", "operator", "or", "or_eq", "private",
    "protected", "public", "register", "reinterpret_cast", "requires", "return", "short",
    "signed", "sizeof", "static", "static_assert", "static_cast", "struct", "switch",
    "template", "this", "thread_local", "throw", "true", "try", "typedef", "typeid",
    "typename", "union", "unsigned", "using", "virtual", "void", "volatile", "wchar_t",
    "while", "xor", "xor_eq",
))
BRINGUP = "bringup"
RESERVED_PACKAGES = ("interfaces", "runtime", BRINGUP)
GENERATED_MSGS = ("Ack", "SampleInfo", "SubsystemStatus")


def pascal(name: str) -> str:
    """A record's message name: ``lwr_state`` -> ``LwrState``, ``LwrState`` unchanged."""
    return "".join(part[:1].upper() + part[1:] for part in name.split("_") if part)


def package_ok(name: str) -> bool:
    return bool(PACKAGE.match(name)) and "__" not in name and not name.endswith("_")


def ros_token_ok(name: str) -> bool:
    return bool(ROS_TOKEN.match(name)) and "__" not in name


def msg_field_ok(name: str) -> bool:
    return (bool(MSG_FIELD.match(name)) and "__" not in name and not name.endswith("_")
            and name not in CPP_KEYWORDS and not keyword.iskeyword(name)
            and not keyword.issoftkeyword(name))


def binding_ok(binding: str) -> bool:
    module, sep, attr = binding.partition(":")
    return bool(sep) and all(IDENT.match(p) for p in module.split(".")) and all(
        IDENT.match(p) for p in attr.split("."))


class NameChecker:
    """Collects E860 diagnostics for names that cannot become ROS 2 / Python names."""

    def __init__(self) -> None:
        self.diagnostics: list[Diagnostic] = []

    def error(self, message: str, span: Span, hint: str) -> None:
        self.diagnostics.append(Diagnostic("E860", message, span, hint))

    def ident(self, name: str, what: str, span: Span) -> None:
        if not IDENT.match(name):
            self.error(f"{what} '{name}' is not an ASCII identifier", span,
                       "use letters, digits and underscores")

    def token(self, name: str, what: str, span: Span) -> None:
        if not ros_token_ok(name):
            self.error(f"{what} '{name}' cannot be part of a ROS 2 name", span,
                       "ROS 2 names take letters, digits and single underscores")

    def check(self, system: System, record_spans: dict[str, Span]) -> list[Diagnostic]:
        prefix = system.name.lower()
        if not package_ok(prefix):
            self.error(f"system '{system.name}' cannot prefix a ROS 2 package name "
                       f"('{prefix}_...')", system.span,
                       "package names are lower-case letters, digits and single underscores, "
                       "starting with a letter")
        packages: dict[str, str] = {}
        for agent in system.agents:
            self._agent(agent, prefix, packages)
            for sub in agent.subsystems:
                self._subsystem(sub)
            for dev in agent.devices:
                self._device(dev)
        for ext in system.externs:
            self.ident(ext.name, "extern", ext.span)
            if not binding_ok(ext.binding):
                self.error(f"binding \"{ext.binding}\" of extern {ext.name} is not "
                           "module:function of Python identifiers", ext.span,
                           "write it as package.module:function")
        for k in system.consts:
            self.ident(k.name, "constant", k.span)
        self._records(system, record_spans)
        self._enums(system, record_spans)
        return self.diagnostics

    def _enums(self, system: System, spans: dict[str, Span]) -> None:
        from rssm_dsl.ros2.msgtypes import MAX_ENUM_MEMBERS, enum_constant
        for enum in enums_of(system):
            span = spans.get(enum.name, system.span)
            if len(enum.members) > MAX_ENUM_MEMBERS:
                self.error(f"enum {enum.name} has {len(enum.members)} members; a ROS 2 "
                           f"message carries at most {MAX_ENUM_MEMBERS} (uint8)", span,
                           "split the enum")
            seen: dict[str, str] = {}
            for member in enum.members:
                name = enum_constant(enum, member)
                if not MSG_CONSTANT.match(name):
                    self.error(f"member '{member}' of enum {enum.name} cannot become ROS 2 "
                               f"message constant '{name}'", span,
                               "message constants are upper-case letters, digits and single "
                               "underscores, not ending in '_'")
                elif name in seen:
                    self.error(f"members '{seen[name]}' and '{member}' of enum {enum.name} "
                               f"both become message constant '{name}'", span,
                               "rename one of them")
                seen[name] = member

    def _agent(self, agent: Agent, prefix: str, packages: dict[str, str]) -> None:
        self.token(agent.name, "agent", agent.span)
        pkg = f"{prefix}_{agent.name.lower()}"
        if agent.name.lower() in RESERVED_PACKAGES:
            self.error(f"agent '{agent.name}' would be package '{pkg}', which the "
                       "generator uses for itself", agent.span, "rename the agent")
        elif not package_ok(pkg):
            self.error(f"agent '{agent.name}' cannot become ROS 2 package '{pkg}'",
                       agent.span, "package names are lower-case letters, digits and "
                       "single underscores")
        elif pkg in packages:
            self.error(f"agents '{packages[pkg]}' and '{agent.name}' both become package "
                       f"'{pkg}'", agent.span, "ROS package names are lower case; rename "
                       "one of the agents")
        packages[pkg] = agent.name

    def _subsystem(self, sub: Subsystem) -> None:
        self.token(sub.name, "subsystem", sub.span)
        for v in (*sub.params, *sub.memory):
            self.ident(v.name, "name", v.span)
        for b in (*sub.inputs, *sub.outputs):
            self.token(b.name, "buffer", b.span)
        for beh in sub.behaviours:
            self.ident(beh.name, "behaviour", beh.span)
            for c in beh.conditions:
                self.ident(c.name, "condition", c.span)

    def _device(self, dev: Device) -> None:
        self.token(dev.name, "device", dev.span)
        for b in (*dev.inputs, *dev.outputs):
            self.token(b.name, "buffer", b.span)
        if dev.binding is not None and not binding_ok(dev.binding):
            self.error(f"binding \"{dev.binding}\" of device type {dev.device_type} is "
                       "not module:Class of Python identifiers", dev.span,
                       "write it as package.module:Class")

    def _records(self, system: System, spans: dict[str, Span]) -> None:
        seen: dict[str, str] = {}
        for record in records_of(system):
            span = spans.get(record.name, system.span)
            msg = pascal(record.name)
            if not MSG_NAME.match(msg) or msg in GENERATED_MSGS or msg.endswith("Sample") \
                    or re.search(r"Array[0-9]+\Z", msg):
                self.error(f"record {record.name} cannot become ROS 2 message '{msg}'", span,
                           "message names are CamelCase letters and digits; Ack, "
                           "SampleInfo, SubsystemStatus, *Sample and *Array<N> are the "
                           "generator's")
            elif msg in seen and seen[msg] != record.name:
                self.error(f"records {seen[msg]} and {record.name} both become message "
                           f"'{msg}'", span, "rename one of them")
            seen[msg] = record.name
            for field, _ in record.fields:
                if not msg_field_ok(field):
                    self.error(f"field '{field}' of record {record.name} cannot be a ROS 2 "
                               "message field", span,
                               "message fields are lower-case letters, digits and single "
                               "underscores, not ending in '_', and no C++ or Python keyword")


def records_of(system: System) -> list[RecordT]:
    """Every record type the system's buffers and parameters use, nested ones included, in
    a deterministic order (by name)."""
    found: dict[str, RecordT] = {}

    def visit(t: Type) -> None:
        if isinstance(t, ArrayT):
            visit(t.element)
        elif isinstance(t, RecordT) and t.name not in found:
            found[t.name] = t
            for _, ft in t.fields:
                visit(ft)

    for sub in system.subsystems():
        for b in (*sub.inputs, *sub.outputs):
            visit(b.type)
    for dev in system.devices():
        for b in (*dev.inputs, *dev.outputs):
            visit(b.type)
    return [found[k] for k in sorted(found)]


def enums_of(system: System) -> list[EnumT]:
    """Every enum type the system's buffers carry (in records and arrays too), by name."""
    found: dict[str, EnumT] = {}
    records: set[str] = set()

    def visit(t: Type) -> None:
        if isinstance(t, ArrayT):
            visit(t.element)
        elif isinstance(t, EnumT):
            found.setdefault(t.name, t)
        elif isinstance(t, RecordT) and t.name not in records:
            records.add(t.name)
            for _, ft in t.fields:
                visit(ft)

    for sub in system.subsystems():
        for b in (*sub.inputs, *sub.outputs):
            visit(b.type)
    for dev in system.devices():
        for b in (*dev.inputs, *dev.outputs):
            visit(b.type)
    return [found[k] for k in sorted(found)]
