-- RSSM buffers: the rssmc language server, two-space indentation, // comments.

-- Every time, not only the first: reading the buffer again (`:e!`, `:edit`) sets its
-- filetype again, which sources this file, and Neovim has detached its clients meanwhile.
-- attach() does nothing when the buffer has its client.
require("rssm").attach(vim.api.nvim_get_current_buf())

if vim.b.did_ftplugin then
  return
end
vim.b.did_ftplugin = true
vim.b.undo_ftplugin = "setlocal commentstring< comments< shiftwidth< tabstop< expandtab<"

vim.bo.commentstring = "// %s"
vim.bo.comments = "s1:/*,mb:*,ex:*/,://"
vim.bo.shiftwidth = 2
vim.bo.tabstop = 2
vim.bo.expandtab = true
