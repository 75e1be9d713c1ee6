# scratch_tree.sh - sourced by tests that build a changed copy of the tree (test-mutant,
# test-renderer).
#   scratch_tree DEST [BUILD]   copies the layers, scenes, tests and Makefile into DEST with their
#                               times, and BUILD's objects and libraries (default build) into
#                               DEST/build, so make there recompiles only what the test changes
#                               afterwards (and what depends on it, by the -MMD files).
# The copy keeps modification times (cp -p): the objects stay newer than their sources, and a
# file the test then edits becomes newer than its object. Without a BUILD the copy builds whole.
scratch_tree() {
    local dest=$1 build=${2:-build}
    mkdir -p "$dest" || return 1
    cp -rp core model scene render harness cli tools ops examples scenes tests Makefile "$dest"/ || return 1
    if [ -d "$build/model" ] && [ -d "$build/harness" ]; then
        mkdir -p "$dest/build"
        local l
        for l in core model scene render harness cli tools pic; do
            [ ! -d "$build/$l" ] || cp -rp "$build/$l" "$dest/build"/ || return 1
        done
        cp -p "$build"/libreflcheck*.a "$dest/build"/ 2>/dev/null
    fi
    return 0
}
