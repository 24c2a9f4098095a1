-- The rssmc language server for Neovim, without nvim-lspconfig.
--
--   vim.opt.runtimepath:append("/path/to/rssmc/editors/nvim")
--   require("rssm").setup({ cmd = { "rssmc", "lsp" } })   -- optional: the defaults
--
-- Works with Neovim 0.7 (vim.lsp.start_client) and newer (vim.lsp.start).
local M = {}

M.config = {
  cmd = nil,          -- default: vim.g.rssm_lsp_cmd or { "rssmc", "lsp" }
  format_on_save = false,
}

local clients = {}    -- root directory -> client id (Neovim 0.7)

function M.setup(opts)
  M.config = vim.tbl_extend("force", M.config, opts or {})
end

local function command()
  return M.config.cmd or vim.g.rssm_lsp_cmd or { "rssmc", "lsp" }
end

local function root_of(bufnr)
  local name = vim.api.nvim_buf_get_name(bufnr)
  local dir = name ~= "" and vim.fn.fnamemodify(name, ":p:h") or vim.fn.getcwd()
  local marker = vim.fn.finddir(".git", dir .. ";")
  if marker ~= "" then
    return vim.fn.fnamemodify(marker, ":p:h:h")
  end
  return dir
end

local function keymaps(bufnr)
  local function map(lhs, rhs, desc)
    vim.keymap.set("n", lhs, rhs, { buffer = bufnr, silent = true, desc = desc })
  end
  map("gd", vim.lsp.buf.definition, "RSSM: go to definition")
  map("gr", vim.lsp.buf.references, "RSSM: references")
  map("K", vim.lsp.buf.hover, "RSSM: hover")
  map("<leader>rn", vim.lsp.buf.rename, "RSSM: rename")
  map("<leader>ca", vim.lsp.buf.code_action, "RSSM: code actions (quick fixes)")
  map("<leader>f", function()
    if vim.lsp.buf.format then
      vim.lsp.buf.format({ bufnr = bufnr })
    else
      vim.lsp.buf.formatting_sync(nil, 5000)
    end
  end, "RSSM: format")
  vim.bo[bufnr].omnifunc = "v:lua.vim.lsp.omnifunc"
end

function M.attach(bufnr)
  local root = root_of(bufnr)
  local config = {
    name = "rssmc",
    cmd = command(),
    root_dir = root,
    on_attach = function(_, b)
      keymaps(b)
    end,
  }
  if vim.lsp.start then                     -- Neovim 0.8 and newer
    return vim.lsp.start(config, { bufnr = bufnr })
  end
  local id = clients[root]                   -- Neovim 0.7
  if id == nil or vim.lsp.get_client_by_id(id) == nil then
    id = vim.lsp.start_client(config)
    clients[root] = id
  end
  if id then
    vim.lsp.buf_attach_client(bufnr, id)
  end
  return id
end

return M
