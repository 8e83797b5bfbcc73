#!/usr/bin/env bash
# tests/test_deps.sh - a fresh Debian machine gets every package the build uses from
# scripts/setup.sh (issue 9, item 1). Usage: test_deps.sh path/to/cdvr (ctest passes it);
# env CDVR_SOURCE_DIR, CDVR_BINARY_DIR (set by ctest; default: the checkout and cdvr's dir).
#
# Lists what this build directory actually used, whatever parts were configured (GL, MPI,
# plugins, tests: whatever is built is covered):
#   - system headers: the compiler's dependency output (the *.o.d depfiles that CMake's
#     Makefile generator has gcc/clang write, or `ninja -t deps` for Ninja);
#   - libraries: the link lines (link.txt, or build.ninja's LINK_LIBRARIES), -lNAME resolved
#     with the compiler, and `ldd` of every ELF executable and shared object built;
# maps each file to its Debian package with one `dpkg -S` call, and fails naming every
# package that is neither in setup.sh's packages=(...) list nor in the Depends/PreDepends
# closure of that list (one `apt-cache depends --recurse` call, parsed once: an OR-group
# counts as its first alternative, which is what apt installs on a fresh machine; a virtual
# package as its provider that is installed here, else its first provider; Essential
# packages count as present, since Debian policy lets packages omit depending on them).
# Files under the source or build directory are the project's own and are ignored. Any other
# file no package owns (/usr/local, hand-copied libraries) fails the test: a fresh machine
# would not have it. A library ldd cannot find fails it too.
# Self-check: the same computation on the list as it was before issue 9 (no libznz-dev, no
# libnifti2-dev) must name both, so the test is seen to be able to fail.
# CDVR_SETUP_SH=FILE checks FILE's list instead of scripts/setup.sh's (demonstrations).
# Exit 77 (skip) where dpkg or apt-cache is missing (not a Debian system).
set -uo pipefail

cdvr=${1:?usage: test_deps.sh path/to/cdvr}
bin=${CDVR_BINARY_DIR:-$(cd "$(dirname "$cdvr")" && pwd)}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
setup=${CDVR_SETUP_SH:-$src/scripts/setup.sh}
for tool in dpkg dpkg-query apt-cache ldd awk; do
  command -v "$tool" >/dev/null || { echo "test_deps: $tool not found (not Debian?): skipped"; exit 77; }
done
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
bin=$(cd "$bin" && pwd -P); src=$(cd "$src" && pwd -P)

# ---- setup.sh's package list -----------------------------------------------------------------
awk '/^[[:space:]]*packages=\(/ { on = 1; sub(/.*packages=\(/, "") }
     on { line = $0; sub(/#.*/, "", line); done = sub(/\).*/, "", line)
          n = split(line, w, /[[:space:]]+/); for (i = 1; i <= n; i++) if (w[i] != "") print w[i]
          if (done) exit }' "$setup" | sort -u > "$tmp/roots"
[ -s "$tmp/roots" ] || { echo "test_deps: no packages=(...) list in $setup" >&2; exit 1; }

# ---- files the build used --------------------------------------------------------------------
# One line per file: "path<TAB>what used it".
used=$tmp/used
: > "$used"
if [ -f "$bin/build.ninja" ] && command -v ninja >/dev/null; then
  ninja -C "$bin" -t deps 2>/dev/null | awk '/^[^ ]/ { obj = $1; sub(/:$/, "", obj); next }
                                            NF == 1 { print $1 "\t" obj }' >> "$used"
fi
find "$bin" -name '*.o.d' -type f -print0 |
  xargs -0 -r awk '{ for (i = 1; i <= NF; i++) { w = $i
                       if (w == "\\" || w ~ /:$/) continue
                       obj = FILENAME; sub(/\.d$/, "", obj); print w "\t" obj } }' >> "$used"
nheaders=$(cut -f1 "$used" | sort -u | wc -l)

cc_for_l=$(awk -F= '/^CMAKE_C_COMPILER:/ { print $2 }' "$bin/CMakeCache.txt" 2>/dev/null)
resolve_l() { # -lNAME -> the file the linker takes (shared first, as ld does)
  local f
  for f in "lib$1.so" "lib$1.a"; do
    f=$("${cc_for_l:-cc}" -print-file-name="$f" 2>/dev/null)
    case $f in /*) [ -e "$f" ] && { echo "$f"; return; } ;; esac
  done
}
link_lines() {
  find "$bin" -name link.txt -type f -exec awk '{ print FILENAME "\t" $0 }' {} +
  [ -f "$bin/build.ninja" ] && awk '/^ *LINK_(LIBRARIES|FLAGS) = / { print "build.ninja\t" $0 }' \
    "$bin/build.ninja"
}
while IFS=$'\t' read -r where line; do
  for w in $line; do
    case $w in
      -l*) f=$(resolve_l "${w#-l}"); [ -n "$f" ] && printf '%s\t%s\n' "$f" "$where" ;;
      /*.so|/*.so.*|/*.a) printf '%s\t%s\n' "$w" "$where" ;;
    esac
  done
done < <(link_lines) | sort -u >> "$used"

nelf=0
while IFS= read -r -d '' f; do
  [ "$(head -c 4 "$f" 2>/dev/null | od -An -c | tr -d ' \n')" = "177ELF" ] || continue
  nelf=$((nelf + 1))
  ldd "$f" 2>/dev/null | awk -v obj="${f#$bin/}" -v miss="$tmp/notfound" '
    /=> not found/ { print $1 "\t" obj >> miss; next }
    /=> \// { print $3 "\t" obj; next }
    /^[[:space:]]*\// { print $1 "\t" obj }' >> "$used"
done < <(find "$bin" -path '*/CMakeFiles' -prune -o -type f \( -perm -u+x -o -name '*.so' \) -print0)

# ---- files -> packages (one dpkg -S) -----------------------------------------------------------
# Absolute paths, normalised ("norm": path<TAB>normalised), outside the project; for each, the
# candidate names dpkg may know it by: as written, with symlinks resolved (alternatives), and
# across the /usr merge.
cut -f1 "$used" | grep '^/' | sort -u > "$tmp/paths"
xargs -r -d '\n' realpath -m -s -- < "$tmp/paths" > "$tmp/normalised"
xargs -r -d '\n' realpath -m -- < "$tmp/paths" > "$tmp/resolved"
paste "$tmp/paths" "$tmp/normalised" > "$tmp/norm"
paste "$tmp/normalised" "$tmp/resolved" |
  awk -F'\t' -v src="$src/" -v bin="$bin/" '
    function own(p) { return index(p "/", src) == 1 || index(p "/", bin) == 1 }
    function emit(n, c) {
      print n "\t" c
      if (c ~ /^\/usr\/(lib|lib64|bin|sbin)\//) print n "\t" substr(c, 5)
      else if (c ~ /^\/(lib|lib64|bin|sbin)\//) print n "\t/usr" c
    }
    !own($1) && !own($2) { emit($1, $1); emit($1, $2) }' | sort -u > "$tmp/candidates"
cut -f2 "$tmp/candidates" | sort -u > "$tmp/names"
xargs -r -d '\n' dpkg -S < "$tmp/names" 2>/dev/null |
  awk '/^diversion by/ { next }
       { i = index($0, ": "); pk = substr($0, 1, i - 1); path = substr($0, i + 2)
         n = split(pk, a, /, */)
         for (j = 1; j <= n; j++) { sub(/:.*/, "", a[j]); print path "\t" a[j] } }' |
  sort -u > "$tmp/owners"
# normalised file -> its owning packages (space-separated; empty: no package owns it)
awk -F'\t' 'NR == FNR { own[$1] = own[$1] " " $2; next }
            { o[$1] = ($1 in o ? o[$1] : "") ($2 in own ? own[$2] : "") }
            END { for (f in o) print f "\t" o[f] }' "$tmp/owners" "$tmp/candidates" |
  sort > "$tmp/file_pkgs"
# normalised file -> the first object or binary that used it (for messages)
awk -F'\t' -v bin="$bin/" 'NR == FNR { norm[$1] = $2; next }
       ($1 in norm) && !(norm[$1] in user) { u = $2; if (index(u, bin) == 1) u = substr(u, length(bin) + 1)
                                            user[norm[$1]] = u }
       END { for (f in user) print f "\t" user[f] }' "$tmp/norm" "$used" > "$tmp/users"

# ---- the closure and the verdict -----------------------------------------------------------------
apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks \
  --no-replaces --no-enhances $(cat "$tmp/roots") > "$tmp/graph" 2>/dev/null
dpkg-query -W -f='${Package}\t${Essential}\t${db:Status-Status}\n' > "$tmp/installed" 2>/dev/null

# closure ROOTS_FILE -> the packages a fresh machine gets from installing ROOTS.
closure() {
  awk -F'\t' '
    FILENAME == ARGV[1] { if ($3 == "installed") inst[$1] = 1; if ($2 == "yes") print $1; next }
    FILENAME == ARGV[2] { sub(/:any$/, ""); root[++nroot] = $0; next }
    # the apt-cache depends --recurse graph: pkg, then "  Depends: x", " |Depends: x" (OR
    # with the next line), "    provider" under a <virtual> entry
    /^[^ ]/ { pkg = $0; skip = pkg in real; real[pkg] = 1; ngrp[pkg] += 0; open = 0; next }
    skip { next }                                          # listed twice: the first counts
    /^ [ |](Pre)?Depends: / {
      alt = $0; sub(/^ [ |](Pre)?Depends: /, "", alt); sub(/:any>$/, ">", alt); sub(/:any$/, "", alt)
      if (!open) { g = ++ngrp[pkg]; nalt[pkg, g] = 0 }
      nalt[pkg, g]++; alts[pkg, g, nalt[pkg, g]] = alt; last = alt
      open = substr($0, 2, 1) == "|"; next }
    /^    [^ ]/ { p = $1; if (!((last, p) in isprov)) { isprov[last, p] = 1; prov[last] = prov[last] " " p } }
    function pick(alt,    n, ps, i, name) {
      if (alt !~ /^</) return alt
      name = substr(alt, 2, length(alt) - 2)
      if (name in real) return name                       # e.g. <perl:any> -> perl
      n = split(prov[alt], ps, " ")
      for (i = 1; i <= n; i++) if (ps[i] in inst) return ps[i]
      return n ? ps[1] : ""
    }
    END {
      for (i = 1; i <= nroot; i++) { q[++tail] = root[i]; seen[root[i]] = 1 }
      for (head = 1; head <= tail; head++) {
        p = q[head]; print p
        for (g = 1; g <= ngrp[p]; g++) {
          d = pick(alts[p, g, 1])
          if (d != "" && !(d in seen)) { seen[d] = 1; q[++tail] = d }
        }
      }
    }' "$tmp/installed" "$1" "$tmp/graph" | sort -u
}

# verdict CLOSURE_FILE -> "package<TAB>file<TAB>user" for each needed package not covered.
verdict() {
  awk -F'\t' 'FILENAME == ARGV[1] { have[$1] = 1; next }
              FILENAME == ARGV[2] { user[$1] = $2; next }
              { n = split($2, ps, " "); ok = 0
                for (i = 1; i <= n; i++) if (ps[i] in have) ok = 1
                if (!ok && n) print ps[1] "\t" $1 "\t" user[$1] }' \
    "$1" "$tmp/users" "$tmp/file_pkgs" | sort -t $'\t' -k1,1 -u
}

closure "$tmp/roots" > "$tmp/closure"
verdict "$tmp/closure" > "$tmp/missing"
awk -F'\t' '$2 == "" { print $1 }' "$tmp/file_pkgs" > "$tmp/unowned"
needed=$(awk -F'\t' '{ n = split($2, ps, " "); for (i = 1; i <= n; i++) print ps[i] }' \
         "$tmp/file_pkgs" | sort -u)
echo "test_deps: $nheaders header and source paths, $nelf ELF files, $(wc -l < "$tmp/file_pkgs") system files" \
     "from $(echo "$needed" | grep -c .) packages; setup.sh lists $(wc -l < "$tmp/roots")," \
     "closure $(wc -l < "$tmp/closure")"

fail=0
# The collection found something real: the C library's and Lua's headers at least.
for want in libc6-dev liblua5.4-dev; do
  grep -qx "$want" <<<"$needed" || { echo "FAIL: sanity: no file of $want among the build's inputs" >&2; fail=1; }
done
if [ -s "$tmp/missing" ]; then
  echo "FAIL: packages the build uses that scripts/setup.sh does not install:" >&2
  awk -F'\t' '{ printf "  %-24s %s (used by %s)\n", $1, $2, $3 }' "$tmp/missing" >&2
  # the fewest to add: -dev packages first, each only if the ones before do not pull it in
  apt-cache depends --recurse --no-recommends --no-suggests --no-conflicts --no-breaks \
    --no-replaces --no-enhances $(cut -f1 "$tmp/missing") >> "$tmp/graph" 2>/dev/null
  cp "$tmp/roots" "$tmp/roots_fix"; add=""
  for m in $(cut -f1 "$tmp/missing" | awk '{ print ($0 ~ /-dev$/ ? 0 : 1) "\t" $0 }' | sort | cut -f2); do
    closure "$tmp/roots_fix" | grep -qx "$m" && continue
    echo "$m" >> "$tmp/roots_fix"; add="$add $m"
  done
  echo "  add to packages=(...) in scripts/setup.sh:$add" >&2
  fail=1
fi
if [ -s "$tmp/unowned" ]; then
  echo "FAIL: files the build uses that no Debian package owns (a fresh machine lacks them):" >&2
  sed 's/^/  /' "$tmp/unowned" >&2
  fail=1
fi
if [ -s "$tmp/notfound" ]; then
  echo "FAIL: libraries ldd cannot find:" >&2
  sort -u "$tmp/notfound" | sed 's/^/  /' >&2
  fail=1
fi

# Self-check: the list as it was before issue 9 (without libznz-dev and libnifti2-dev; the
# latter depends on the former) must be refused naming both.
if grep -qx libznz-dev <<<"$needed" && grep -qx libnifti2-dev <<<"$needed" &&
   grep -qx libznz-dev "$tmp/roots" && grep -qx libnifti2-dev "$tmp/roots"; then
  grep -vx -e libznz-dev -e libnifti2-dev "$tmp/roots" > "$tmp/roots_without"
  closure "$tmp/roots_without" > "$tmp/closure_without"
  named=$(verdict "$tmp/closure_without" | cut -f1 | grep -x -e libznz-dev -e libnifti2-dev | sort | tr '\n' ' ')
  if [ "$named" = "libnifti2-dev libznz-dev " ]; then
    echo "test_deps: self-check: the list without libznz-dev and libnifti2-dev is refused naming both"
  else
    echo "FAIL: self-check: the list without libznz-dev and libnifti2-dev names only: ${named:-nothing}" >&2
    fail=1
  fi
fi
[ $fail -eq 0 ] && echo "test_deps: every package the build uses is installed by scripts/setup.sh"
exit $fail
