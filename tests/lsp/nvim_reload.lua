-- Run by test_editors.py in headless Neovim: the buffer of a spec keeps its rssmc client
-- when it is reloaded. Open a spec with a missing data-availability case (E501), then
--   _G.rssm_command == "edit!": replace the text in the buffer by a correct one (E501 goes
--     away) and `:e!` (the text on disk comes back: E501 again, from the server);
--   _G.rssm_command == "edit": change the file on disk to one without a switch and `:edit`
--     (E603, no E501).
-- Then correct the buffer again (the server follows: no E501, no E603). Report the clients and
-- the diagnostic codes of each step as JSON.
local spec, good, changed = _G.rssm_spec, _G.rssm_good, _G.rssm_changed
local command, report = _G.rssm_command, _G.rssm_report
local out = { steps = {} }
local WAIT = 30000

local function finish()
  local f = io.open(report, "w")
  f:write(vim.fn.json_encode(out))
  f:close()
  vim.cmd("qall!")
end

local function step(s)
  table.insert(out.steps, s)
end

local function code_of(d)
  if d.code then return d.code end
  if d.user_data and d.user_data.lsp then return d.user_data.lsp.code end
  return nil
end

local function codes(bufnr)
  local found = {}
  for _, d in ipairs(vim.diagnostic.get(bufnr)) do
    table.insert(found, code_of(d))
  end
  table.sort(found)
  return found
end

local function has_code(bufnr, code)
  return vim.tbl_contains(codes(bufnr), code)
end

-- the ids of the rssmc clients attached to bufnr (or to any buffer), Neovim 0.7 and newer
local function rssmc_clients(bufnr)
  local all
  if vim.lsp.get_clients then
    all = vim.lsp.get_clients(bufnr and { bufnr = bufnr } or nil)
  elseif bufnr then
    all = vim.tbl_values(vim.lsp.buf_get_clients(bufnr))
  else
    all = vim.lsp.get_active_clients()
  end
  local ids = {}
  for _, c in ipairs(all) do
    if c.name == "rssmc" then table.insert(ids, c.id) end
  end
  table.sort(ids)
  return ids
end

-- after a reload: the buffer has its client again, then the server's diagnostics satisfy `want`
local function observe(bufnr, want)
  local seen = {}
  seen.attached = vim.wait(5000, function() return #rssmc_clients(bufnr) > 0 end, 20)
  seen.clients = rssmc_clients(bufnr)
  if seen.attached then     -- without a client no diagnostics come: do not wait for them
    seen.diagnosed = vim.wait(WAIT, function() return want(bufnr) end, 50)
  else
    seen.diagnosed = false
  end
  seen.codes = codes(bufnr)
  seen.modified = vim.bo[bufnr].modified
  seen.filetype = vim.bo[bufnr].filetype
  return seen
end

local ok, err = pcall(function()
  vim.cmd("edit " .. vim.fn.fnameescape(spec))
  local bufnr = vim.api.nvim_get_current_buf()
  out.opened = observe(bufnr, function(b) return has_code(b, "E501") end)
  step("opened")
  if not out.opened.diagnosed then error("no E501 diagnostic after opening the spec") end

  if command == "edit!" then
    -- edit the buffer (not the file): the server sees the correct text
    vim.api.nvim_buf_set_lines(bufnr, 0, -1, false, vim.fn.readfile(good))
    out.edited = observe(bufnr, function(b) return not has_code(b, "E501") end)
    step("edited")
    if not out.edited.diagnosed then error("E501 stays after correcting the buffer") end
    -- :e! drops the change: the text on disk, with its E501, comes back
    vim.cmd("edit!")
    out.reloaded = observe(bufnr, function(b) return has_code(b, "E501") end)
  else
    -- another program changes the file; :edit reads it again
    vim.fn.writefile(vim.fn.readfile(changed), spec)
    vim.cmd("edit")
    out.reloaded = observe(bufnr, function(b)
      return has_code(b, "E603") and not has_code(b, "E501")
    end)
  end
  step("reloaded")

  -- the server still follows the changes in the buffer
  if out.reloaded.attached then
    vim.api.nvim_buf_set_lines(bufnr, 0, -1, false, vim.fn.readfile(good))
    out.changed = observe(bufnr, function(b)
      return not has_code(b, "E501") and not has_code(b, "E603")
    end)
    step("changed")
  end

  out.bufnr = bufnr
  out.current = vim.api.nvim_get_current_buf()
  out.all_clients = rssmc_clients(nil)
end)
if not ok then out.error = tostring(err) end
finish()
