"""The registry of diagnostic codes. Every code is documented in docs/diagnostics.md (a test
checks that both agree)."""

from __future__ import annotations

from enum import Enum

from rssm_core.records import dataclass


class Severity(str, Enum):
    ERROR = "error"
    WARNING = "warning"
    NOTE = "note"


@dataclass(frozen=True, slots=True)
class Code:
    code: str
    slug: str
    severity: Severity
    summary: str


_E = Severity.ERROR
_W = Severity.WARNING

CODES: tuple[Code, ...] = (
    # input and syntax
    Code("E001", "file-not-found", _E, "the file does not exist or cannot be read"),
    Code("E002", "not-a-file", _E, "the path is a directory or not a regular file"),
    Code("E003", "not-text", _E, "the file is not UTF-8 text"),
    Code("E004", "file-too-large", _E, "the file is larger than the compiler accepts"),
    Code("E005", "syntax-error", _E, "unexpected token"),
    Code("E006", "unexpected-character", _E, "a character that starts no token"),
    Code("E007", "unexpected-eof", _E, "the file ends in the middle of a declaration"),
    Code("E008", "nesting-too-deep", _E, "expressions or brackets nested too deeply"),
    Code("E009", "import-not-found", _E, "an imported module cannot be found"),
    Code("E010", "import-cycle", _E, "modules import each other in a cycle"),
    Code("E011", "name-unusable-as-file-name", _E, "a name too long or otherwise unusable as the file name it becomes"),
    Code("W012", "line-separator-in-comment", _W, "U+2028/U+2029/U+0085 in a comment do not end the line"),
    Code("E013", "literal-too-large", _E, "a number literal with more digits than the compiler reads"),
    Code("E014", "import-not-a-spec", _E, "an import names a file that is not a .rssm specification"),
    # names
    Code("E101", "duplicate-name", _E, "a name is declared twice in the same scope"),
    Code("E102", "undefined-name", _E, "a name that is not declared"),
    Code("E103", "wrong-kind", _E, "a name of the wrong kind of declaration"),
    Code("E104", "no-system", _E, "the file declares no system, or more than one"),
    # types
    Code("E201", "type-mismatch", _E, "an expression of the wrong type"),
    Code("E202", "unknown-type", _E, "a type name that is not declared"),
    Code("E203", "bad-operand", _E, "an operator applied to operands it does not accept"),
    Code("E204", "wrong-arity", _E, "a call with the wrong number of arguments"),
    Code("E205", "not-assignable", _E, "an assignment to something that cannot be assigned"),
    Code("E206", "bad-index", _E, "an index out of range or on a non-array"),
    Code("E207", "unknown-field", _E, "a record field that does not exist"),
    Code("E208", "bad-binding", _E, "an external binding is not of the form module:function"),
    Code("E209", "bad-frequency", _E, "a frequency that is not positive or is above 100 kHz"),
    Code("E210", "empty-enum", _E, "an enum without members"),
    Code("E211", "duplicate-enum-member", _E, "an enum member declared twice"),
    Code("E212", "unknown-enum-member", _E, "a member that the enum does not have"),
    Code("E213", "empty-range", _E, "a range type whose low bound is above its high bound"),
    Code("E214", "value-out-of-range", _E, "a constant outside the range of the type it is stored in"),
    Code("E215", "call-before-the-run", _E, "an external operation called in an initial value or a constant"),
    Code("E216", "binding-not-found", _E, "the module of a binding lacks the function or class it names"),
    Code("E217", "binding-arity", _E, "an extern's Python function cannot take the extern's arguments"),
    Code("W218", "binding-module-not-found", _W, "the Python module of a binding is not found here"),
    Code("W228", "binding-module-unreadable", _W,
         "the Python module of a binding is too large or too deeply nested to read"),
    # structure (paper III-A)
    Code("E301", "control-count", _E, "an agent needs exactly one control subsystem"),
    Code("E302", "link-not-allowed", _E, "a link between subsystems the methodology forbids"),
    Code("E303", "peer-not-found", _E, "a buffer names a peer subsystem that does not exist"),
    Code("E304", "unpaired-buffer", _E, "a buffer with no matching buffer on its peer"),
    Code("E305", "endpoint-type-mismatch", _E, "the two buffers of a channel have different types"),
    Code("E306", "ambiguous-peer-buffer", _E, "several buffers of the peer could match"),
    Code("E307", "missing-peer", _E, "a subsystem buffer must name its peer"),
    Code("E308", "device-kind-mismatch", _E, "a device instance of the wrong kind"),
    Code("E309", "wrong-direction-word", _E, "an input names its peer with `to` or an output with `from`"),
    Code("E310", "unknown-device-parameter", _E, "an instance gives a parameter its device type does not declare"),
    Code("E311", "unknown-agent-definition", _E, "an agent instance names no agent definition"),
    Code("E312", "bad-agent-argument", _E, "an agent instance's arguments do not fit its definition's parameters"),
    Code("E313", "bad-instance-range", _E, "an indexed agent line declares no agent or too many"),
    # canonical decomposition
    Code("E401", "write-outside-target", _E, "a partial function writes outside its own target"),
    Code("E402", "write-to-input", _E, "an input buffer is written"),
    Code("E403", "duplicate-partial-function", _E, "two partial functions for one target"),
    Code("E404", "unknown-update-target", _E, "an update of something that is neither an output buffer nor memory"),
    # data availability
    Code("E501", "cases-not-exhaustive", _E, "a data-availability combination no case covers"),
    Code("E502", "cases-overlap", _E, "a data-availability combination two cases cover"),
    Code("E503", "new-of-non-input", _E, "new() of something that is not an input buffer"),
    Code("E505", "new-outside-case", _E, "new() outside a data-availability case condition"),
    Code("E506", "case-condition-not-data", _E, "a case condition that is not over new() only"),
    # behaviours and the subsystem layer
    Code("E601", "no-initial-behaviour", _E, "a subsystem without exactly one initial behaviour"),
    Code("E602", "no-terminal-condition", _E, "a behaviour without a terminal condition"),
    Code("E603", "switch-not-exhaustive", _E, "after a behaviour ends, no switch condition may hold"),
    Code("W604", "switch-overlap", _W, "after a behaviour ends, two switch conditions may hold at once"),
    Code("W605", "unreachable-behaviour", _W, "a behaviour no switch leads to"),
    Code("E606", "arrangement-incomplete", _E, "a send or receive arrangement misses a buffer"),
    Code("E607", "arrangement-duplicate", _E,
         "a buffer appears twice in an arrangement or not a buffer of that direction"),
    Code("E608", "condition-out-of-scope", _E,
         "a terminal or error condition used outside the switches of its behaviour"),
    Code("E609", "no-behaviours", _E, "a subsystem without behaviours"),
    Code("E610", "duplicate-arrangement", _E, "two send or two receive declarations in a behaviour"),
    Code("W611", "output-resent-unchanged", _W,
         "a behaviour sends, by default, an output it never updates to a consumer that "
         "tests new(): the last value, as new, in every iteration"),
    # properties (the verifier's user-stated properties)
    Code("E620", "property-unknown-subsystem", _E, "a property names a subsystem the system does not have"),
    Code("E621", "property-unknown-behaviour", _E, "a property names a behaviour its subsystem does not have"),
    Code("E622", "property-unknown-variable", _E, "a property reads a variable its subsystem does not have"),
    Code("E623", "property-not-bool", _E, "a property's condition is not a bool"),
    Code("E624", "duplicate-property", _E, "two properties with the same name"),
    Code("E625", "misplaced-behaviour-test", _E, "`SUBSYSTEM in BEHAVIOUR` outside a property"),
    Code("W626", "property-value-abstracted", _W,
         "a property reads a value with no finite domain, which the verifier abstracts"),
    # usage warnings
    Code("W701", "unused-buffer", _W, "an input buffer never read or an output buffer never written"),
    Code("W702", "unused-memory", _W, "a memory variable never read"),
    Code("W703", "unused-param", _W, "a parameter never read"),
    # simulation (rssmc simulate)
    Code("E801", "binding-not-found", _E, "the Python module, function or class of a binding cannot be loaded"),
    Code("E802", "operation-failed", _E, "an operation raised an error while the system was simulated"),
    Code("E803", "wrong-return-type", _E, "an external operation or a device returned a value of the wrong type"),
    Code("E804", "binding-signature", _E, "a bound Python callable does not accept the declared parameters"),
    Code("E805", "simulation-deadlock", _E, "the simulation reached a marking where nothing can ever fire"),
    Code("E806", "replay-diverged", _E, "a step of a replayed counterexample cannot be fired"),
    Code("E807", "unsafe-firing", _E, "a firing would put a second token into a place"),
    Code("E808", "time-stands-still", _E,
         "the simulation fires endlessly without simulated time advancing"),
    Code("E809", "subsystem-stalled", _E,
         "a subsystem completes no iteration while the rest of the system runs on"),
    # render (rssmc render)
    Code("W849", "page-layout-failed", _W,
         "Graphviz could not lay out a page in time: drawn with a quick layout, or not drawn"),
    Code("W850", "graphviz-missing", _W, "Graphviz `dot` is not installed: no SVG figures drawn"),
    Code("E851", "graphviz-failed", _E, "Graphviz `dot` failed on every page"),
    Code("E852", "trace-unreadable", _E, "a trace or counterexample file that cannot be read"),
    Code("E853", "trace-unknown-transition", _E, "a trace fires a transition the net lacks"),
    Code("E854", "trace-not-enabled", _E, "a trace fires a transition that is not enabled"),
    Code("W855", "trace-truncated", _W, "a trace longer than the explorer plays (--max-steps)"),
    Code("E856", "series-unreadable", _E, "a series file that cannot be read (rssmc render --series)"),
    Code("E857", "series-not-selected", _E, "a --select pattern chooses no series of the series file"),
    Code("W858", "series-other-system", _W, "the series file was recorded from another system"),
    Code("W859", "series-too-many", _W, "more series than the explorer draws: only the first are shown"),
    # ROS 2 packages (rssmc ros2)
    Code("E860", "not-a-ros-name", _E, "a name of the specification cannot become a ROS 2 or Python name"),
    Code("W861", "module-not-shipped", _W, "a binding's module is not shipped in the ROS 2 workspace"),
    Code("E862", "ros-type-mismatch", _E,
         "the ROS message type named for a buffer cannot carry the buffer's values"),
    Code("E863", "ros-types-file", _E,
         "the ROS types file of a specification cannot be read or names no channel's buffer"),
    Code("W868", "file-not-shipped", _W,
         "a file of a binding's package is not shipped in the ROS 2 workspace (a link, a special file)"),
    # the LWR4+ experiment (rssmc run)
    Code("E870", "run-no-lwr4", _E, "no LWR4+ device, effector or set points for the experiment"),
    Code("E871", "run-option-unsupported", _E, "an option of `rssmc run` that the specification cannot honour"),
    Code("W872", "viewer-unavailable", _W, "the MuJoCo viewer cannot open (no display): the run goes on headless"),
    Code("W873", "video-unavailable", _W, "the video cannot be rendered or encoded here"),
    # output folders (rssmc compile, rssmc render)
    Code("E880", "bad-output-folder", _E,
         "the output folder given with --output/-o is empty or is not a folder"),
    Code("E881", "file-system-error", _E,
         "a file the command reads or writes cannot be: no permission, a full disk, a path "
         "the file system refuses"),
    # the command line
    Code("E890", "bad-option-value", _E,
         "an option's value is not one the command accepts (a number out of range, a word "
         "it does not know, a file name of the wrong kind)"),
    # internal
    Code("E900", "internal-error", _E, "the compiler failed: please report it"),
)

BY_CODE: dict[str, Code] = {c.code: c for c in CODES}
