"""The editor support under editors/: the TextMate grammar and the Vim syntax use exactly the
compiler's keywords; the VS Code extension checks and packages with npm and formats RSSM by
default; headless Neovim, configured by editors/nvim, receives the diagnostics, applies a
quick fix, keeps its client through `:e!` and `:edit`, and formats on save when asked."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rssm_dsl.pipeline import compile_file
from rssm_dsl.resources import grammar_dir
from rssm_dsl.syntax.format import keywords
from tests.lsp.specs import GOOD, MISSING_CASE, MISSING_SWITCH

ROOT = Path(__file__).resolve().parents[2]
VSCODE = ROOT / "editors" / "vscode"
NVIM = ROOT / "editors" / "nvim"


def lark_keywords() -> set[str]:
    """The reserved words of grammar/rssm.lark: its quoted literals made of letters."""
    text = (grammar_dir() / "rssm.lark").read_text(encoding="utf-8")
    text = re.sub(r"//[^\n]*", "", text)
    return set(re.findall(r'"([A-Za-z]+)"', text))


def textmate_keywords() -> set[str]:
    grammar = json.loads((VSCODE / "syntaxes" / "rssm.tmLanguage.json").read_text("utf-8"))
    words: set[str] = set()
    for pattern in grammar["repository"]["keywords"]["patterns"]:
        m = re.fullmatch(r"\\b\(\?:([^)]*)\)\\b", pattern["match"])
        assert m is not None, pattern
        words |= set(m.group(1).split("|"))
    return words


def test_textmate_keywords_are_the_lark_keywords() -> None:
    assert lark_keywords() == keywords()
    assert textmate_keywords() == lark_keywords()


def test_vim_syntax_keywords_are_the_lark_keywords() -> None:
    text = (NVIM / "syntax" / "rssm.vim").read_text(encoding="utf-8")
    words: set[str] = set()
    for line in text.splitlines():
        parts = line.split()
        if parts[:2] == ["syntax", "keyword"] and parts[2] not in (
                "rssmBuiltin", "rssmConstant", "rssmType", "rssmTodo"):
            words |= set(parts[3:])
    assert words == lark_keywords()


def test_the_vscode_manifest_names_existing_files() -> None:
    manifest = json.loads((VSCODE / "package.json").read_text(encoding="utf-8"))
    [language] = manifest["contributes"]["languages"]
    assert language["id"] == "rssm" and language["extensions"] == [".rssm"]
    assert (VSCODE / language["configuration"]).is_file()
    [grammar] = manifest["contributes"]["grammars"]
    assert (VSCODE / grammar["path"]).is_file() and grammar["scopeName"] == "source.rssm"
    assert (VSCODE / manifest["main"]).is_file()
    assert "vscode-languageclient" in manifest["dependencies"]
    config = json.loads((VSCODE / "language-configuration.json").read_text(encoding="utf-8"))
    assert config["comments"]["lineComment"] == "//"
    client = (VSCODE / manifest["main"]).read_text(encoding="utf-8")
    assert '"rssmc", "lsp"' in client


def test_the_vscode_extension_is_the_default_formatter_of_rssm() -> None:
    """So that VS Code's editor.formatOnSave (and Format Document) use the rssmc server."""
    manifest = json.loads((VSCODE / "package.json").read_text(encoding="utf-8"))
    defaults = manifest["contributes"]["configurationDefaults"]["[rssm]"]
    assert defaults["editor.defaultFormatter"] == f"{manifest['publisher']}.{manifest['name']}"
    assert "editor.formatOnSave" in (VSCODE / "README.md").read_text(encoding="utf-8")


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not installed")
def test_the_vscode_checks_pass_under_node() -> None:
    done = subprocess.run(["node", "test/grammar.test.js"], cwd=VSCODE, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    done = subprocess.run(["node", "--check", "extension.js"], cwd=VSCODE, capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stderr


@pytest.mark.skipif(not (VSCODE / "node_modules" / ".bin" / "vsce").exists(),
                    reason="run `npm ci` in editors/vscode first")
def test_the_vscode_extension_packages(tmp_path: Path) -> None:
    out = tmp_path / "rssm.vsix"
    done = subprocess.run([str(VSCODE / "node_modules" / ".bin" / "vsce"), "package",
                           "--out", str(out)], cwd=VSCODE, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stdout + done.stderr
    import zipfile
    names = zipfile.ZipFile(out).namelist()
    assert "extension/syntaxes/rssm.tmLanguage.json" in names
    assert "extension/node_modules/vscode-languageclient/package.json" in names


def run_headless_neovim(tmp_path: Path, script: str, setup: str | None = None,
                        **names: str) -> dict:
    """Run tests/lsp/<script> in `nvim --headless`, configured by editors/nvim like a user's
    init.lua would (`setup`: a line of Lua after it), with `_G.rssm_<name>` set to each of
    `names`; return the JSON the script reports in `_G.rssm_report`."""
    report = tmp_path / "report.json"
    init = tmp_path / "init.lua"
    init.write_text("\n".join([
        f"vim.opt.runtimepath:prepend({json.dumps(str(NVIM))})",
        "vim.cmd('filetype plugin on')",
        "vim.cmd('syntax on')",
        f"vim.g.rssm_lsp_cmd = {{ {json.dumps(sys.executable)}, '-m', 'rssm_dsl', 'lsp' }}",
        *([setup] if setup else []),
        f"_G.rssm_report = {json.dumps(str(report))}",
        *(f"_G.rssm_{name} = {json.dumps(value)}" for name, value in names.items()),
    ]) + "\n", encoding="utf-8")
    command = ["nvim", "--headless", "-n", "-i", "NONE", "-u", str(init),
               "-c", f"luafile {Path(__file__).with_name(script)}"]
    try:
        done = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=240)
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"headless Neovim running {script} did not end within {e.timeout} s: "
                    f"{e.stdout!r} {e.stderr!r}")
    assert report.exists(), f"{script} wrote no report: {done.stdout}{done.stderr}"
    result = json.loads(report.read_text(encoding="utf-8"))
    assert "error" not in result, result
    return result


@pytest.mark.external
@pytest.mark.skipif(shutil.which("nvim") is None, reason="neovim is not installed")
def test_headless_neovim_receives_diagnostics_and_applies_a_quick_fix(tmp_path: Path) -> None:
    spec = tmp_path / "circle.rssm"
    spec.write_text(MISSING_CASE, encoding="utf-8")
    result = run_headless_neovim(tmp_path, "nvim_quickfix.lua", spec=str(spec))
    assert result["filetype"] == "rssm"
    assert result["codes"] == ["E501"]
    assert result["applied"].startswith("Add the missing data-availability cases")
    assert result["cleared"] is True
    fixed = spec.read_text(encoding="utf-8")
    assert fixed != MISSING_CASE and fixed != GOOD
    assert compile_file(spec).diagnostics == ()


@pytest.mark.external
@pytest.mark.skipif(shutil.which("nvim") is None, reason="neovim is not installed")
@pytest.mark.parametrize(("command", "code"), [("edit!", "E501"), ("edit", "E603")])
def test_headless_neovim_keeps_the_client_when_the_buffer_is_reloaded(
        tmp_path: Path, command: str, code: str) -> None:
    """`:e!` (dropping a change) and `:edit` (after the file changed on disk) reload the
    buffer; its rssmc client stays attached (the same one, reused for the root), the server
    diagnoses the text read again (`code`) and follows the changes made after."""
    spec = tmp_path / "circle.rssm"
    spec.write_text(MISSING_CASE, encoding="utf-8")
    good = tmp_path / "good.txt"
    good.write_text(GOOD, encoding="utf-8")
    changed = tmp_path / "changed.txt"
    changed.write_text(MISSING_SWITCH, encoding="utf-8")
    result = run_headless_neovim(tmp_path, "nvim_reload.lua", command=command, spec=str(spec),
                                 good=str(good), changed=str(changed))
    opened = result["opened"]
    assert opened["filetype"] == "rssm" and len(opened["clients"]) == 1, opened
    seen = result["reloaded"]
    assert seen["attached"] is True, f"no rssmc client after :{command}: {seen}"
    assert seen["clients"] == opened["clients"], f"another client after :{command}: {seen}"
    assert seen["diagnosed"] is True, f"no fresh {code} after :{command}: {seen}"
    assert seen["modified"] is False and seen["filetype"] == "rssm", seen
    expected = ["E603"] if command == "edit" else ["E501"]
    assert seen["codes"] == expected, seen
    assert result["changed"]["diagnosed"] is True, result["changed"]
    assert result["current"] == result["bufnr"], result
    assert result["all_clients"] == opened["clients"], result


def badly_laid_out(text: str) -> str:
    """Valid RSSM that `rssmc fmt` changes: doubled indentation, spaces after `:=`."""
    return re.sub(r"(?m)^( +)", lambda m: m.group(1) * 2, text).replace(" := ", " :=   ")


@pytest.mark.external
@pytest.mark.skipif(shutil.which("nvim") is None, reason="neovim is not installed")
@pytest.mark.parametrize("format_on_save", [True, False])
def test_headless_neovim_formats_on_save_when_asked(tmp_path: Path, format_on_save: bool
                                                    ) -> None:
    """With setup({ format_on_save = true }) `:w` writes what `rssmc fmt` writes; without
    it, `:w` writes the buffer as it is."""
    bad = badly_laid_out(GOOD)
    canonical = tmp_path / "canonical.rssm"
    canonical.write_text(bad, encoding="utf-8")
    done = subprocess.run([sys.executable, "-m", "rssm_dsl", "fmt", str(canonical)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    expected = canonical.read_text(encoding="utf-8")
    assert expected != bad and compile_file(canonical).diagnostics == ()
    spec = tmp_path / "circle.rssm"
    spec.write_text(bad, encoding="utf-8")
    flag = "true" if format_on_save else "false"
    result = run_headless_neovim(tmp_path, "nvim_format.lua", spec=str(spec),
                                 setup=f"require('rssm').setup({{ format_on_save = {flag} }})")
    assert result["filetype"] == "rssm" and result["ready"] is True, result
    assert result["format_on_save"] is format_on_save, result
    assert result["modified"] is False and result["attached"] is True, result
    written = spec.read_text(encoding="utf-8")
    if format_on_save:
        assert written == expected, "`:w` did not write the canonical layout of `rssmc fmt`"
    else:
        assert written == bad, "`:w` changed the file though format_on_save is off"
