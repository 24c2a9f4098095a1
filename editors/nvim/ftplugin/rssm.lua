-- RSSM buffers: two-space indentation, // comments, and the rssmc language server.
if vim.b.did_ftplugin then
  return
end
vim.b.did_ftplugin = true

vim.bo.commentstring = "// %s"
vim.bo.comments = "s1:/*,mb:*,ex:*/,://"
vim.bo.shiftwidth = 2
vim.bo.tabstop = 2
vim.bo.expandtab = true

require("rssm").attach(vim.api.nvim_get_current_buf())
