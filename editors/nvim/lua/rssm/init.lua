-- The rssmc language server for Neovim, without nvim-lspconfig.
--
--   vim.opt.runtimepath:append("/path/to/rssmc/editors/nvim")
--   require("rssm").setup({ cmd = { "rssmc", "lsp" }, format_on_save = false })  -- the defaults
--
-- ftplugin/rssm.lua calls attach() whenever a buffer gets the filetype rssm, which includes
-- reading it again (`:e!`, `:edit`): Neovim detaches the clients of a reloaded buffer, and
-- attach() gives it back the client of its root (one client per root, started once).
-- Works with Neovim 0.7 (vim.lsp.start_client) and newer (vim.lsp.start).
local M = {}

M.config = {
  cmd = nil,              -- default: vim.g.rssm_lsp_cmd or { "rssmc", "lsp" }
  format_on_save = false, -- format with the server before each write (read at each write)
  format_timeout_ms = 5000,
}

local NAME = "rssmc"

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

-- the rssmc client attached to bufnr, if any
local function client_of(bufnr)
  local attached
  if vim.lsp.get_clients then                -- Neovim 0.10 and newer
    attached = vim.lsp.get_clients({ bufnr = bufnr, name = NAME })
  else
    attached = vim.tbl_values(vim.lsp.buf_get_clients(bufnr))
  end
  for _, client in ipairs(attached) do
    if client.name == NAME then
      return client
    end
  end
  return nil
end

-- Format bufnr (0: the current buffer) with the rssmc server only, synchronously (the
-- canonical layout of `rssmc fmt`). Nothing happens without an initialized rssmc client or
-- when the text does not parse. Returns whether a client was asked.
function M.format(bufnr)
  if bufnr == nil or bufnr == 0 then
    bufnr = vim.api.nvim_get_current_buf()
  end
  local client = client_of(bufnr)
  local capabilities = client and client.server_capabilities
  if not (capabilities and capabilities.documentFormattingProvider) then
    return false                             -- no client, or not initialized yet
  end
  local timeout = M.config.format_timeout_ms
  if vim.lsp.buf.format then                 -- Neovim 0.8 and newer
    vim.lsp.buf.format({ bufnr = bufnr, id = client.id, async = false, timeout_ms = timeout })
    return true
  end
  local params = {                           -- Neovim 0.7: vim.lsp.buf.formatting_sync
    textDocument = { uri = vim.uri_from_bufnr(bufnr) },  -- would format the current buffer
    options = {                              -- with whichever client it picks
      tabSize = vim.lsp.util.get_effective_tabstop(bufnr),
      insertSpaces = vim.api.nvim_buf_get_option(bufnr, "expandtab"),
    },
  }
  local response, err = client.request_sync("textDocument/formatting", params, timeout, bufnr)
  if response and response.result then
    vim.lsp.util.apply_text_edits(response.result, bufnr, client.offset_encoding)
  elseif err or (response and response.err) then
    vim.notify("rssm: formatting failed: " .. vim.inspect(err or response.err),
      vim.log.levels.WARN)
  end
  return true
end

local group = vim.api.nvim_create_augroup("rssm", { clear = true })

local function format_on_save(bufnr)
  vim.api.nvim_clear_autocmds({ group = group, buffer = bufnr })
  vim.api.nvim_create_autocmd("BufWritePre", {
    group = group,
    buffer = bufnr,
    desc = "RSSM: format on save (require('rssm').setup({ format_on_save = true }))",
    callback = function(args)
      if M.config.format_on_save then
        M.format(args.buf)
      end
    end,
  })
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
  map("<leader>f", function() M.format(bufnr) end, "RSSM: format")
  vim.bo[bufnr].omnifunc = "v:lua.vim.lsp.omnifunc"
end

-- Attach the rssmc client of the buffer's root to bufnr (0: the current buffer), starting it
-- if need be; nothing to do when it is attached already. Returns the client id.
function M.attach(bufnr)
  if bufnr == nil or bufnr == 0 then
    bufnr = vim.api.nvim_get_current_buf()
  end
  format_on_save(bufnr)
  local attached = client_of(bufnr)
  if attached then
    return attached.id
  end
  local root = root_of(bufnr)
  local config = {
    name = NAME,
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
