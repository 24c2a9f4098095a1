"""CLI commands, one module each; the order here is the order in `rssmc --help`.
Add a command by adding its module name (one line). What the commands share (exit codes,
options, the error guard, the diagnostics report) is in `common` (not a command)."""

COMMANDS: tuple[str, ...] = (
    "compile",
    "verify",
    "simulate",
    "plot",
    "run",
    "render",
    "fmt",
    "lsp",
    "ros2",
)

# a command that lives in another command's module (the default: the module of its own name)
MODULE_OF: dict[str, str] = {"check": "compile"}
