"""CLI commands, one module each; the order here is the order in `rssmc --help`.
Add a command by adding its module name (one line)."""

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
