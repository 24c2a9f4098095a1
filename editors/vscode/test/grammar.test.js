// Checks that the TextMate grammar is valid JSON with the scope the manifest names, and that
// its keywords are exactly the reserved words of the compiler's Lark grammar.
"use strict";

const assert = require("node:assert");
const fs = require("node:fs");
const path = require("node:path");

const here = path.join(__dirname, "..");
const manifest = JSON.parse(fs.readFileSync(path.join(here, "package.json"), "utf8"));
const grammar = JSON.parse(
  fs.readFileSync(path.join(here, "syntaxes", "rssm.tmLanguage.json"), "utf8"));
assert.strictEqual(grammar.scopeName, manifest.contributes.grammars[0].scopeName);

const lark = fs.readFileSync(path.join(here, "..", "..", "grammar", "rssm.lark"), "utf8")
  .split("\n").map((line) => line.replace(/\/\/.*$/, "")).join("\n");
const reserved = new Set([...lark.matchAll(/"([A-Za-z]+)"/g)].map((m) => m[1]));

const inGrammar = new Set();
for (const p of grammar.repository.keywords.patterns) {
  const m = /^\\b\(\?:([^)]*)\)\\b$/.exec(p.match);
  assert.ok(m, `unexpected keyword pattern ${p.match}`);
  m[1].split("|").forEach((w) => inGrammar.add(w));
}
assert.deepStrictEqual([...inGrammar].sort(), [...reserved].sort());
console.log(`ok: ${inGrammar.size} keywords match grammar/rssm.lark`);
