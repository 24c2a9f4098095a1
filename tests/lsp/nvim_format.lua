-- Run by test_editors.py in headless Neovim, after require("rssm").setup({ format_on_save =
-- ... }) in the init file: open a valid but badly laid out spec, wait until its rssmc client
-- can format, `:w`, and report as JSON; the test compares the file on disk with `rssmc fmt`.
local spec, report = _G.rssm_spec, _G.rssm_report
local out = { steps = {} }

local function finish()
  local f = io.open(report, "w")
  f:write(vim.fn.json_encode(out))
  f:close()
  vim.cmd("qall!")
end

local function rssmc_client(bufnr)
  local all
  if vim.lsp.get_clients then
    all = vim.lsp.get_clients({ bufnr = bufnr })
  else
    all = vim.tbl_values(vim.lsp.buf_get_clients(bufnr))
  end
  for _, c in ipairs(all) do
    if c.name == "rssmc" then return c end
  end
  return nil
end

local ok, err = pcall(function()
  vim.cmd("edit " .. vim.fn.fnameescape(spec))
  local bufnr = vim.api.nvim_get_current_buf()
  out.filetype = vim.bo[bufnr].filetype
  out.format_on_save = require("rssm").config.format_on_save
  -- the client has initialized (it knows the server formats) and has sent didOpen
  out.ready = vim.wait(30000, function()
    local c = rssmc_client(bufnr)
    return c ~= nil and c.server_capabilities ~= nil
      and c.server_capabilities.documentFormattingProvider ~= nil
  end, 20)
  table.insert(out.steps, "ready:" .. tostring(out.ready))
  if not out.ready then error("no rssmc client that can format is attached to the buffer") end
  vim.cmd("write")
  out.modified = vim.bo[bufnr].modified
  out.attached = rssmc_client(bufnr) ~= nil
end)
if not ok then out.error = tostring(err) end
finish()
