"""CLI commands, one module each; the order here is the order in `rssmc --help`.
Add a command by adding its module name (one line). What the commands share (exit codes,
options, the error guard, the diagnostics report) is in `common` (not a command)."""

COMMANDS: tuple[str, ...] = (
    "compile",
    "verify",
    "simulate",
    "run",
    "render",
    "fmt",
    "lsp",
    "ros2",
)
