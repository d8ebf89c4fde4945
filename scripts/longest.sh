#!/usr/bin/env bash
# Prints the longest functions and files under src/ (or the folders given),
# test modules (`#[cfg(test)] mod ... { ... }`) left out: the check behind "no function
# over ~100 lines, no file over ~600". Relies on rustfmt's layout: a
# function's closing brace sits at its `fn` line's indentation.
# Usage: scripts/longest.sh [-n N] [dir...]   (N rows of each list, default 15)
set -euo pipefail
cd "$(dirname "$0")/.."
n=15
if [ "${1:-}" = "-n" ]; then n=$2; shift 2; fi
dirs=("$@")
[ ${#dirs[@]} -eq 0 ] && dirs=(src)
files=$(find "${dirs[@]}" -name '*.rs' | sort)

echo "== longest functions (lines, file:line, name; test modules left out)"
# shellcheck disable=SC2086
awk '
  FNR == 1 { in_tests = 0; depth = 0; cfg_test = 0 }
  cfg_test && /^(pub(\([a-z]+\))? )?mod [a-z_]+ \{$/ { in_tests = 1 }
  { cfg_test = ($0 == "#[cfg(test)]") }
  in_tests { if ($0 ~ /^\}$/) in_tests = 0; next }
  {
    if (match($0, /^ *((pub(\([a-z]+\))? )?((const|async|unsafe|extern "C") )*fn [A-Za-z0-9_]+)/)) {
      indent = match($0, /[^ ]/) - 1
      name = $0; sub(/^ *(pub(\([a-z]+\))? )?((const|async|unsafe|extern "C") )*fn /, "", name); sub(/[^A-Za-z0-9_].*/, "", name)
      # A declaration without a body (trait item) ends with `;`.
      if ($0 ~ /;$/) next
      depth++; start[depth] = FNR; ind[depth] = indent; nm[depth] = name
      if ($0 ~ /\}$/ && $0 ~ /\{/) { printf "%6d  %s:%d  %s\n", 1, FILENAME, FNR, name; depth-- }
      next
    }
    if (depth > 0) {
      closing = sprintf("^%" ind[depth] "s\\}$", "")
      if (ind[depth] == 0) closing = "^\\}$"
      if ($0 ~ closing) {
        printf "%6d  %s:%d  %s\n", FNR - start[depth] + 1, FILENAME, start[depth], nm[depth]
        depth--
      }
    }
  }
' $files | sort -rn | head -n "$n"

echo
echo "== longest files (lines without test modules, all lines, file)"
for f in $files; do
  body=$(awk '
    cfg && /^(pub(\([a-z]+\))? )?mod [a-z_]+ \{$/ { t = 1 }
    { cfg = ($0 == "#[cfg(test)]") }
    !t { c++ }
    t && /^\}$/ { t = 0 }
    END { print c + 0 }' "$f")
  printf "%6d %6d  %s\n" "$body" "$(wc -l < "$f")" "$f"
done | sort -rn | head -n "$n"
