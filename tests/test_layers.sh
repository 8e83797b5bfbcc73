#!/usr/bin/env bash
# tests/test_layers.sh - dependencies point one way (DESIGN.md section 1, issue 20): no source of
# libcdvr (core/) includes a Lua header or anything under lua/ or plugins/, and only the sources
# of core/render/gl include a GL, EGL, GLES, KHR or GLFW header. Usage: test_layers.sh
# path/to/cdvr (ctest passes it); env CDVR_SOURCE_DIR, CDVR_BINARY_DIR (set by ctest).
#
# What is checked is what the compiler read, not what the text says: the dependency output of
# the cdvr_core target (the *.o.d depfiles that CMake's Makefile generator has gcc/clang write,
# or `ninja -t deps` for Ninja), so an include reached through another header counts too.
# Self-check first: the same check on made-up dependency lists (a core/io source reaching
# lua.h, a core/store source reaching GL/gl.h, a core/render/gl source reaching EGL/egl.h) must
# name the first two and not the third, so the test is seen to be able to fail.
set -uo pipefail

cdvr=${1:?usage: test_layers.sh path/to/cdvr}
bin=${CDVR_BINARY_DIR:-$(cd "$(dirname "$cdvr")" && pwd)}
src=${CDVR_SOURCE_DIR:-$(cd "$(dirname "$0")/.." && pwd)}
src=$(cd "$src" && pwd -P)

# Reads "source<TAB>prerequisite" lines on stdin; prints one line per forbidden include.
check_pairs() {
    awk -F'\t' -v src="$src/" '
    function rel(p) { return index(p, src) == 1 ? substr(p, length(src) + 1) : p }
    {
        s = rel($1); d = rel($2)
        if (s !~ /^core\//) next
        if (d ~ /(^|\/)(lua|lualib|lauxlib|luaconf)\.h$/ || d ~ /(^|\/)lua5\.[0-9]\// ||
            d ~ /^lua\// || d ~ /^plugins\//)
            print s ": includes " d " (core/ uses no Lua and nothing of lua/ or plugins/)"
        else if (s !~ /^core\/render\/gl\// &&
                 d ~ /(^|\/)(GL|EGL|GLES[0-9]*|KHR|GLFW)\//)
            print s ": includes " d " (only core/render/gl may include GL, EGL or GLFW)"
    }' | sort -u
}

# Depfiles (make syntax: "target: source dep dep \" continued) -> source<TAB>dep pairs.
depfile_pairs() {
    for f in "$@"; do
        tr -s ' \\\n' '\n' <"$f" | awk 'NF && $0 !~ /:$/' |
            awk -v OFS='\t' 'NR == 1 { s = $0; next } { print s, $0 }'
    done
}

fail=0
# ---- self-check -------------------------------------------------------------------------------
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf 'a.o: %s/core/io/x.c /usr/include/lua5.4/lua.h \\\n /usr/include/stdio.h\n' "$src" >"$tmp/a.o.d"
printf 'b.o: %s/core/store/y.c \\\n /usr/include/GL/gl.h\n' "$src" >"$tmp/b.o.d"
printf 'c.o: %s/core/render/gl/z.c /usr/include/EGL/egl.h\n' "$src" >"$tmp/c.o.d"
self=$(depfile_pairs "$tmp"/*.o.d | check_pairs)
if ! grep -q 'core/io/x.c: includes /usr/include/lua5.4/lua.h' <<<"$self" ||
   ! grep -q 'core/store/y.c: includes /usr/include/GL/gl.h' <<<"$self" ||
   grep -q 'core/render/gl/z.c' <<<"$self"; then
    echo "FAIL: self-check: the check did not name what it should:"
    echo "$self"
    fail=1
fi

# ---- the build's dependency output ------------------------------------------------------------
if [ -f "$bin/build.ninja" ]; then
    pairs=$(ninja -C "$bin" -t deps 2>/dev/null | awk -v OFS='\t' '
        /^[^ ].*: #deps/ { t = $1; sub(/:$/, "", t); keep = t ~ /cdvr_core\.dir\//; s = ""; next }
        keep && NF { if (s == "") s = $1; else print s, $1 }')
    # the first dep of a ninja entry is the source, as in a depfile
else
    mapfile -t files < <(find "$bin/CMakeFiles/cdvr_core.dir" -name '*.o.d' 2>/dev/null)
    if [ "${#files[@]}" -eq 0 ]; then
        echo "FAIL: no dependency files under $bin/CMakeFiles/cdvr_core.dir (build cdvr_core first)"
        exit 1
    fi
    pairs=$(depfile_pairs "${files[@]}")
fi
nsrc=$(cut -f1 <<<"$pairs" | sort -u | grep -c '/core/')
if [ "$nsrc" -lt 20 ]; then
    echo "FAIL: dependency output names only $nsrc core/ sources"
    fail=1
fi
found=$(check_pairs <<<"$pairs")
if [ -n "$found" ]; then
    echo "FAIL: core/ reaches headers it must not:"
    echo "$found"
    fail=1
fi
[ "$fail" -eq 0 ] && echo "ok: $nsrc core/ sources, no Lua header, GL only in core/render/gl"
exit "$fail"
