#!/usr/bin/env bash
# What `make report` does before its first render: it builds only what the nightly runs (the
# program, its DDS plugin, the cache-key lists, the example shading model user_ggx loads), not
# the unit-test programs, their fixtures or the manual page, and compiles the longest file first;
# ops/deps.sh asks dpkg once for the whole package list and installs exactly the missing ones
# (dpkg-query and apt-get are stand-ins on PATH that log their calls, so nothing is installed).
# Usage: bash tests/nightly_build.sh BUILD
set -uo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
work=$PWD/$build/nightly-build-test
rm -rf "$work"
mkdir -p "$work/bin"
pass=0
fail=0
ok() { pass=$((pass + 1)); echo "nightly-build: $*"; }
bad() { fail=$((fail + 1)); echo "nightly-build: FAILED: $*"; }

# make -n into an empty build folder prints every command a clean clone's `make report` runs
# (the recursive make too) and runs none but the version stamp's mkdir.
fresh=$work/fresh
make -n --no-print-directory BUILD="$fresh" report > "$work/report.n" 2>&1
grep -q -- "-o $fresh/reflcheck\$" "$work/report.n" && ok "make report builds the program" ||
    bad "make report does not link $fresh/reflcheck ($work/report.n)"
for want in reflcheck-oiio.so key_sources.py examples/ggx/ggx.so ops/nightly.sh; do
    grep -qF "$want" "$work/report.n" && ok "make report makes or runs $want" ||
        bad "make report does not make or run $want ($work/report.n)"
done
# The longest compiles (the shading kernels render/shade_batch_{ct,d3d9,d3d}.c, most of the
# build's CPU) start first, longest first.
first=$(grep -o -- "-c [^ ]*\.c" "$work/report.n" | head -3 | sed 's/^-c //' | tr '\n' ' ')
want="render/shade_batch_ct.c render/shade_batch_d3d9.c render/shade_batch_d3d.c "
[ "$first" = "$want" ] && ok "make report compiles the shading kernels first, longest first" ||
    bad "make report's first compiles are '$first', not '$want'"
n=$(grep -c -e "tests/test_" -e "tests/user_models/" -e "gen_man" "$work/report.n")
[ "$n" = 0 ] && ok "make report builds no unit test, fixture or manual page" ||
    bad "make report runs $n commands for unit tests, fixtures or the manual page ($work/report.n)"

# deps.sh with dpkg saying every package but groff-base is installed (and one package twice, as
# a multi-arch package is listed, one instance not installed).
cat > "$work/bin/dpkg-query" << 'SH'
#!/usr/bin/env bash
echo "$*" >> "$DEPS_TEST_LOG.dpkg"
for a in "$@"; do
    case $a in
        -*) ;;
        groff-base) printf '%s\t%s\n' "$a" "unknown ok not-installed" ;;
        libgl1-mesa-dri) printf '%s\t%s\n%s\t%s\n' "$a" "unknown ok not-installed" "$a" "install ok installed" ;;
        *) printf '%s\t%s\n' "$a" "install ok installed" ;;
    esac
done
SH
cat > "$work/bin/apt-get" << 'SH'
#!/usr/bin/env bash
echo "$*" >> "$DEPS_TEST_LOG.apt"
SH
chmod +x "$work/bin/dpkg-query" "$work/bin/apt-get"
export DEPS_TEST_LOG=$work/deps
if [ "$(id -u)" -ne 0 ]; then
    printf '#!/bin/sh\nexec "$@"\n' > "$work/bin/sudo" && chmod +x "$work/bin/sudo"
fi
PATH="$work/bin:$PATH" bash ops/deps.sh 2> "$work/deps.err"
st=$?
[ $st = 0 ] && ok "deps.sh exit 0" || bad "deps.sh exit $st ($work/deps.err)"
calls=$(wc -l < "$work/deps.dpkg" 2> /dev/null || echo 0)
[ "$calls" = 1 ] && ok "deps.sh asks dpkg-query once" || bad "deps.sh asks dpkg-query $calls times, not once"
if grep -qx -- "install -y -qq --no-install-recommends groff-base" "$work/deps.apt" 2> /dev/null; then
    ok "deps.sh installs exactly the missing package"
else
    bad "deps.sh's apt-get calls are not one install of groff-base: $(cat "$work/deps.apt" 2> /dev/null)"
fi

echo "nightly-build: $pass passed, $fail failed"
[ $fail = 0 ]
