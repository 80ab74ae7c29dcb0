#!/usr/bin/env bash
# The shape gate: fails when a function in a .cpp file of bake/, render/, probes/ or tools/ is
# over 80 lines, when a .cpp/.h file in bake/src or render/src is over 800 lines, or when one in
# probes/ is over 700, unless tools/shape_allowlist.txt names it. The allow-list only shrinks:
# an entry that is no longer over its limit, or no longer exists, fails too until its line is
# deleted. `tools/setup.sh test` (what CI runs) runs it before the tests.
#
#   bash tools/check_shape.sh [ROOT]     ROOT: the tree to check (default: this repository)
#
# Function lengths come from universal-ctags (`ctags --c++-kinds=f --fields=+ne`: from `line:`
# to `end:`); a lambda counts in the function that holds it. Allow-list lines are
# `FILE FUNCTION` (a member as Class::name, as the messages below write it) or `FILE` alone for
# a long file; `#` starts a comment.
set -euo pipefail

readonly kMaxFunction=80 kMaxLibraryFile=800 kMaxProbesFile=700

die() { printf 'check_shape.sh: %s\n' "$*" >&2; exit 2; }

[ $# -le 1 ] || die "usage: bash tools/check_shape.sh [ROOT]"
root=${1:-$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)}
[ -d "$root" ] || die "$root: no such folder"
cd "$root"
allow=tools/shape_allowlist.txt
ctags --version 2>/dev/null | grep -q '^Universal Ctags' ||
  die "universal-ctags not found (Debian: apt-get install universal-ctags; tools/setup.sh installs it)"

# Every function of FILE as "FILE<TAB>NAME<TAB>LINE<TAB>LENGTH". NAME keeps the classes of its
# scope and drops its namespaces (the file's own namespace tags name them) and anonymous scopes.
functions_of() {
  ctags --c++-kinds=fn --fields=+neKZ -o - "$1" | awk -F'\t' -v file="$1" '
    { kind[NR] = $4; name[NR] = $1; scope[NR] = ""; first[NR] = ""; last[NR] = ""
      for (i = 5; i <= NF; ++i) {
        if ($i ~ /^scope:/) scope[NR] = substr($i, 7)
        else if ($i ~ /^line:/) first[NR] = substr($i, 6)
        else if ($i ~ /^end:/) last[NR] = substr($i, 5)
      }
      if ($4 == "namespace") namespaces[$1] = 1 }
    END {
      for (r = 1; r <= NR; ++r) {
        if (kind[r] != "function" || name[r] ~ /^__anon/ || first[r] == "" || last[r] == "") continue
        qualified = name[r]
        if (scope[r] ~ /^(class|struct|union):/) {
          n = split(substr(scope[r], index(scope[r], ":") + 1), part, "::")
          for (i = n; i >= 1; --i)
            if (!(part[i] in namespaces) && part[i] !~ /^__anon/) qualified = part[i] "::" qualified
        }
        print file "\t" qualified "\t" first[r] "\t" (last[r] - first[r] + 1)
      }
    }'
}

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Functions over the limit (the longest of overloads that share a name): FILE NAME LINE LENGTH.
for dir in bake render probes tools; do
  [ -d "$dir" ] && find "$dir" -type f -name '*.cpp'
done | LC_ALL=C sort | while read -r f; do functions_of "$f"; done |
  awk -F'\t' -v max="$kMaxFunction" '$4 > max { key = $1 "\t" $2
      if (!(key in len) || $4 > len[key]) { len[key] = $4; at[key] = $3 } }
    END { for (k in len) print k "\t" at[k] "\t" len[k] }' | LC_ALL=C sort >"$work/long_functions"

# Files over their limit: FILE LENGTH LIMIT.
{
  for dir in bake/src render/src; do
    [ -d "$dir" ] && find "$dir" -type f \( -name '*.cpp' -o -name '*.h' \) -printf "%p\t$kMaxLibraryFile\n"
  done
  [ -d probes ] && find probes -type f \( -name '*.cpp' -o -name '*.h' \) -printf "%p\t$kMaxProbesFile\n"
} | LC_ALL=C sort | while IFS=$'\t' read -r f limit; do
  n=$(wc -l <"$f")
  [ "$n" -le "$limit" ] || printf '%s\t%s\t%s\n' "$f" "$n" "$limit"
done >"$work/long_files"

# The allow-list without comments and blank lines: "FILE<TAB>FUNCTION" or "FILE".
if [ -f "$allow" ]; then
  sed -e 's/#.*//' -e 's/[[:space:]]*$//' -e 's/^[[:space:]]*//' "$allow" | grep -v '^$' |
    sed -E 's/[[:space:]]+/\t/' >"$work/allowed" || true
else
  : >"$work/allowed"
fi

errors=0
fail() { printf 'check_shape.sh: %s\n' "$*" >&2; errors=$((errors + 1)); }

while IFS=$'\t' read -r f name line len; do
  grep -qxF "$f"$'\t'"$name" "$work/allowed" ||
    fail "$f:$line: $name is $len lines (at most $kMaxFunction): cut it into named steps"
done <"$work/long_functions"

while IFS=$'\t' read -r f len limit; do
  grep -qxF "$f" "$work/allowed" ||
    fail "$f: $len lines (at most $limit in its folder): split it along its concerns"
done <"$work/long_files"

while IFS=$'\t' read -r f name; do
  if [ -z "$name" ]; then
    cut -f1 "$work/long_files" | grep -qxF "$f" ||
      fail "$allow: $f is within its limit now (or gone): delete its line (the list only shrinks)"
  else
    cut -f1,2 "$work/long_functions" | grep -qxF "$f"$'\t'"$name" ||
      fail "$allow: $f $name is $kMaxFunction lines or fewer now (or gone): delete its line (the list only shrinks)"
  fi
done <"$work/allowed"

functions=$(wc -l <"$work/long_functions")
files=$(wc -l <"$work/long_files")
if [ "$errors" -gt 0 ]; then
  printf 'check_shape.sh: %d problem(s); limits: functions %d lines, files %d (bake/src, render/src) and %d (probes/)\n' \
    "$errors" "$kMaxFunction" "$kMaxLibraryFile" "$kMaxProbesFile" >&2
  exit 1
fi
printf 'check_shape.sh: shape kept (%d functions over %d lines and %d files over their limit, all on the allow-list)\n' \
  "$functions" "$kMaxFunction" "$files"
