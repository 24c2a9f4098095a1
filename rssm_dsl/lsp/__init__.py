"""The RSSM language server (`rssmc lsp`): pygls 2 on top of the compiler's front end."""
