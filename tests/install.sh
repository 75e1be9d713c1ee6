#!/usr/bin/env bash
# install.sh BUILD - `make install` (issue 23 item 5): into DESTDIR, the program, the DDS plugin,
# the manual page, the bash completion and the run-time data land where they belong; the manual
# page renders without warnings and names every command; the completion offers the commands,
# a command's options, the renderer names and scene files. Then, installed into a scratch PREFIX,
# the program renders a POV-Ray and a Cycles job from another folder, with the scripts and
# key sources of its PREFIX and no help from the environment or the source tree.
set -euo pipefail
BUILD=${1:?usage: tests/install.sh BUILD}
root=$(pwd)
tmp=$(mktemp -d "${TMPDIR:-/tmp}/reflcheck-install.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
fail() { echo "install.sh: FAIL: $*" >&2; exit 1; }

# 1. DESTDIR: the files, under the default PREFIX.
make -s BUILD="$BUILD" install DESTDIR="$tmp/stage" >/dev/null
p="$tmp/stage/usr/local"
for f in bin/reflcheck lib/reflcheck/reflcheck-oiio.so share/man/man1/reflcheck.1 \
    share/bash-completion/completions/reflcheck share/reflcheck/key-sources/cycles.list \
    share/reflcheck/harness/renderers/cycles/cycles_render.py \
    share/reflcheck/harness/renderers/eevee/eevee_render.py; do
    [ -s "$p/$f" ] || fail "make install DESTDIR did not install $f"
done
[ -x "$p/bin/reflcheck" ] || fail "bin/reflcheck is not executable"
# every file a key-source list names is installed, so installed cache keys cover the same code
while read -r f; do
    cmp -s "$f" "$p/share/reflcheck/$f" || fail "share/reflcheck/$f missing or not the tree's"
done < <(cat "$p"/share/reflcheck/key-sources/*.list | sort -u)

# 2. The manual page: groff renders it without a warning; it names every command and option.
man1="$p/share/man/man1/reflcheck.1"
# plain ASCII (no overstrike, no escape sequences), so options read as typed
groff -man -Tascii -P-cbou -ww "$man1" > "$tmp/man.ascii" 2> "$tmp/man.err" ||
    fail "groff failed: $(cat "$tmp/man.err")"
[ ! -s "$tmp/man.err" ] || fail "groff warns: $(head -3 "$tmp/man.err")"
if command -v man > /dev/null; then
    MANWIDTH=80 man -l "$man1" > /dev/null 2>&1 || fail "man -l $man1 failed"
fi
for cmd in $("$p/bin/reflcheck" --help | sed -n '/^commands:/,/^$/s/^  \([a-z]\+\) .*/\1/p'); do
    grep -q "^ *$cmd " "$tmp/man.ascii" || fail "the manual page has no section for $cmd"
    for opt in $("$p/bin/reflcheck" "$cmd" --help | grep -o -- '--[a-z0-9-]\+' | sort -u); do
        grep -q -- "$opt" "$tmp/man.ascii" || fail "the manual page does not name $cmd $opt"
    done
done
grep -q "EXIT STATUS" "$tmp/man.ascii" || fail "the manual page has no EXIT STATUS"

# 3. The completion: commands, options per command, renderer names, scene files.
comp="$p/share/bash-completion/completions/reflcheck"
complete_words() { # WORD... : what the completion offers for the last word
    bash -c 'source "$1"; shift; COMP_WORDS=("$@"); COMP_CWORD=$(($# - 1)); _reflcheck; echo "${COMPREPLY[*]}"' \
        _ "$comp" "$@"
}
got=$(complete_words reflcheck re)
[ "$got" = "render renderers" ] || fail "reflcheck re<TAB> offered '$got', want 'render renderers'"
got=$(complete_words reflcheck run x.yaml --ro)
[ "$got" = "--role" ] || fail "run --ro<TAB> offered '$got'"
got=$(complete_words "$p/bin/reflcheck" run x.yaml --renderer p)
[ "$got" = "povray" ] || fail "--renderer p<TAB> offered '$got', want povray (from reflcheck renderers)"
got=$(complete_words reflcheck render x.yaml --aovs "")
[ "$got" = "all none" ] || fail "--aovs <TAB> offered '$got'"
got=$(cd "$root/scenes" && complete_words reflcheck check d3d9_gl)
[ "$got" = "d3d9_glass.yaml d3d9_glass_sun.yaml" ] || fail "check d3d9_gl<TAB> offered '$got'"

# 4. Installed into a scratch PREFIX, run from another folder: POV-Ray and Cycles render.
prefix="$tmp/prefix with space"
make -s BUILD="$BUILD" install PREFIX="$prefix" >/dev/null
mkdir "$tmp/elsewhere"
cd "$tmp/elsewhere"
for r in povray cycles; do
    env -u REFLCHECK_DATA_DIR -u REFLCHECK_KEY_SOURCES -u REFLCHECK_OIIO_PLUGIN \
        "$prefix/bin/reflcheck" run "$root/scenes/d3d9_glass.yaml" --renderer "$r" --role validate --small \
        --out run --cache cache > "$tmp/$r.out" 2>&1 || fail "installed reflcheck run --renderer $r: $(cat "$tmp/$r.out")"
    grep -q " ok " "$tmp/$r.out" || fail "installed $r job not ok: $(cat "$tmp/$r.out")"
    [ -s "run/d3d9_glass/$r-validate.exr" ] || fail "no run/d3d9_glass/$r-validate.exr"
done
grep -q "$prefix/share/reflcheck/harness/renderers/cycles/cycles_render.py" run/d3d9_glass/cycles-validate.json ||
    fail "the Cycles job did not run the installed script: $(grep -o '"command":[^,]*' run/d3d9_glass/cycles-validate.json)"
echo "install.sh: ok (DESTDIR layout, manual page, completion, installed POV-Ray and Cycles jobs)"
