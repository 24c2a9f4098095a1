#!/usr/bin/env bash
# Re-vendor the JavaScript layout library of the HTML explorer from the npm registry.
# Installs exactly what package-lock.json pins into a temporary folder, copies the minified
# browser build (dagre with graphlib bundled, one global `dagre`) and the licences here, and
# drops the source-map comment so that no browser ever asks for a .map file.
# Usage: bash rssm_dsl/render/assets/vendor.sh   (needs node and npm; run by a developer, not CI)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cp "$here/package.json" "$here/package-lock.json" "$work/"
(cd "$work" && npm ci --no-audit --no-fund --ignore-scripts >/dev/null)
dist="$work/node_modules/@dagrejs/dagre/dist"
grep -v '^//# sourceMappingURL=' "$dist/dagre.min.js" \
  | sed 's/dagre.min.js.LEGAL.txt/LICENSE.dagre.txt/' > "$here/dagre.min.js"
{
  echo "@dagrejs/dagre $(node -p "require('$work/node_modules/@dagrejs/dagre/package.json').version")"
  cat "$work/node_modules/@dagrejs/dagre/LICENSE"
  echo
  echo "@dagrejs/graphlib $(node -p "require('$work/node_modules/@dagrejs/graphlib/package.json').version") (bundled in dagre.min.js)"
  cat "$work/node_modules/@dagrejs/graphlib/LICENSE"
} > "$here/LICENSE.dagre.txt"
sha256sum "$here/dagre.min.js"
