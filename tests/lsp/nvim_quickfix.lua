-- Run by test_editors.py in headless Neovim: open a spec with a missing data-availability
-- case, wait for the server's diagnostics, ask for the code actions of E501, apply the
-- preferred quick fix, write the buffer, and report what happened as JSON.
local spec, report = _G.rssm_spec, _G.rssm_report
local out = { steps = {} }

local function finish()
  local f = io.open(report, "w")
  f:write(vim.fn.json_encode(out))
  f:close()
  vim.cmd("qall!")
end

local function code_of(d)
  if d.code then return d.code end
  if d.user_data and d.user_data.lsp then return d.user_data.lsp.code end
  return nil
end

local ok, err = pcall(function()
  vim.cmd("edit " .. vim.fn.fnameescape(spec))
  out.filetype = vim.bo.filetype
  local bufnr = vim.api.nvim_get_current_buf()
  local got = vim.wait(60000, function()
    for _, d in ipairs(vim.diagnostic.get(bufnr)) do
      if code_of(d) == "E501" then return true end
    end
    return false
  end, 50)
  table.insert(out.steps, "diagnostics:" .. tostring(got))
  local target
  out.codes = {}
  for _, d in ipairs(vim.diagnostic.get(bufnr)) do
    table.insert(out.codes, code_of(d))
    if code_of(d) == "E501" then target = d end
  end
  if not target then error("no E501 diagnostic") end
  -- back to an LSP diagnostic (Neovim keeps only the extra fields in user_data.lsp)
  local lsp_diag = vim.tbl_extend("force", target.user_data and target.user_data.lsp or {}, {
    range = { start = { line = target.lnum, character = target.col },
              ["end"] = { line = target.end_lnum, character = target.end_col } },
    message = target.message, code = code_of(target), severity = target.severity,
  })
  local params = {
    textDocument = { uri = vim.uri_from_bufnr(bufnr) },
    range = lsp_diag.range,
    context = { diagnostics = { lsp_diag } },
  }
  local responses = vim.lsp.buf_request_sync(bufnr, "textDocument/codeAction", params, 30000)
  local chosen, encoding
  for client_id, response in pairs(responses or {}) do
    encoding = vim.lsp.get_client_by_id(client_id).offset_encoding
    if response.err then table.insert(out.steps, "error:" .. vim.inspect(response.err)) end
    for _, action in ipairs(response.result or {}) do
      table.insert(out.steps, "action:" .. action.title)
      if action.isPreferred and not chosen then chosen = action end
    end
  end
  if not chosen then error("no preferred code action") end
  out.applied = chosen.title
  vim.lsp.util.apply_workspace_edit(chosen.edit, encoding or "utf-16")
  vim.cmd("write")
  -- the server sees the edit: the diagnostic goes away
  out.cleared = vim.wait(60000, function()
    for _, d in ipairs(vim.diagnostic.get(bufnr)) do
      if code_of(d) == "E501" then return false end
    end
    return true
  end, 50)
end)
if not ok then out.error = tostring(err) end
finish()
