"""The editor support under editors/: the TextMate grammar and the Vim syntax use exactly the
compiler's keywords; the VS Code extension checks and packages with npm; headless Neovim,
configured by editors/nvim, receives the diagnostics and applies a quick fix."""

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
from tests.lsp.specs import GOOD, MISSING_CASE

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


@pytest.mark.external
@pytest.mark.skipif(shutil.which("nvim") is None, reason="neovim is not installed")
def test_headless_neovim_receives_diagnostics_and_applies_a_quick_fix(tmp_path: Path) -> None:
    spec = tmp_path / "circle.rssm"
    spec.write_text(MISSING_CASE, encoding="utf-8")
    report = tmp_path / "report.json"
    init = tmp_path / "init.lua"
    init.write_text("\n".join([
        f"vim.opt.runtimepath:prepend({json.dumps(str(NVIM))})",
        "vim.cmd('filetype plugin on')",
        "vim.cmd('syntax on')",
        f"vim.g.rssm_lsp_cmd = {{ {json.dumps(sys.executable)}, '-m', 'rssm_dsl', 'lsp' }}",
        f"_G.rssm_spec = {json.dumps(str(spec))}",
        f"_G.rssm_report = {json.dumps(str(report))}",
    ]) + "\n", encoding="utf-8")
    script = Path(__file__).with_name("nvim_quickfix.lua")
    done = subprocess.run(["nvim", "--headless", "-n", "-i", "NONE", "-u", str(init),
                           "-c", f"luafile {script}"], cwd=ROOT, capture_output=True,
                          text=True, timeout=240)
    assert report.exists(), done.stdout + done.stderr
    result = json.loads(report.read_text(encoding="utf-8"))
    assert "error" not in result, result
    assert result["filetype"] == "rssm"
    assert result["codes"] == ["E501"]
    assert result["applied"].startswith("Add the missing data-availability cases")
    assert result["cleared"] is True
    fixed = spec.read_text(encoding="utf-8")
    assert fixed != MISSING_CASE and fixed != GOOD
    assert compile_file(spec).diagnostics == ()
