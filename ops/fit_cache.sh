#!/usr/bin/env bash
# fit_cache.sh - `reflcheck fit` through a cache, so that a nightly run over an unchanged tree
# hands back each scene's fit instead of fitting again (hundreds of renders a scene).
#
# Usage: bash ops/fit_cache.sh CACHE BIN SCENE.yaml RUN BOUNDS [--small]
#   runs BIN fit SCENE --out RUN --cache CACHE --bounds BOUNDS [--small], or copies its record
#   (RUN/<scene>/fit.json, fit-wide.json with BOUNDS wide; its references pointed at RUN's
#   records) and its output line from CACHE/fits/<key>/. Exit status: fit's (a cache hit: 0).
# The key (SHA-256) covers what the fit reads: the scene file's bytes, the bounds and size, the
# reflcheck program (path, size, modification time: a rebuilt one fits again) and the cache
# keys of the scene's render records in RUN/<scene>/ (the references the fit compares with;
# each key covers the scene's meshes and images, the renderer and the code behind it). A scene
# whose records are not there yet, or a failed fit, is not cached.
set -uo pipefail
[ $# -ge 5 ] || { echo "fit_cache.sh: usage: CACHE BIN SCENE RUN BOUNDS [--small]" >&2; exit 2; }
cache=$1 bin=$2 scene=$3 run=$4 bounds=$5
shift 5
fit=("$bin" fit "$scene" --out "$run" --cache "$cache" --bounds "$bounds" "$@")
record=fit.json
[ "$bounds" = wide ] && record="fit-wide.json"
# The scene's folder in RUN: the one whose records name this scene file.
dir=$(grep -lF "\"scene_path\":	\"$scene\"" "$run"/*/*.json 2> /dev/null | head -n1)
dir=${dir%/*}
# The render records' keys only: the fits' own records (fit.json, fit-wide.json) name the same
# keys but are written by this stage, two fits at a time, so whether the other bound's is
# already there (and how its JSON is spaced) must not change the key.
keys=$([ -n "$dir" ] && for f in "$dir"/*.json; do
    case ${f##*/} in fit.json | fit-wide.json) ;; *) grep -hoE '"key":[[:space:]]*"[0-9a-f]+"' "$f" ;; esac
done 2> /dev/null | sort -u)
binstat=$(stat -Lc '%s %Y' "$bin" 2> /dev/null)
if [ -z "$dir" ] || [ -z "$keys" ] || [ -z "$binstat" ] || [ ! -r "$scene" ]; then
    exec "${fit[@]}"
fi
key=$({
    echo "reflcheck-fit-cache 1 $bounds $* $(readlink -f "$bin") $binstat"
    sha256sum < "$scene"
    echo "$keys"
} | sha256sum | cut -c1-32)
entry=$cache/fits/$key
# A kept record names the run that fitted first: its references (reference_job, reference_exr)
# become this run's records of the same cache keys, so the record names the renders (and their
# Slurm jobs) this run holds.
relink='
import json, os, sys
src, dst, folder = sys.argv[1:]
with open(src, encoding="utf-8") as f:
    doc = json.load(f)
for fit in doc.get("fits", []):
    old = fit.get("reference_job")
    if not isinstance(old, dict) or not old.get("record"):
        continue
    path = os.path.join(folder, os.path.basename(old["record"]))
    with open(path, encoding="utf-8") as f:
        job = json.load(f)
    if job.get("key") != old.get("key"):
        sys.exit(path + ": not the job the kept fit read")
    fit["reference_job"] = dict(record=path, reused=True, **{k: job.get(k) for k in ("key", "cached", "cpu_s", "finished_unix", "slurm")})
    if "reference_exr" in fit:
        fit["reference_exr"] = job.get("exr")
with open(dst, "w", encoding="utf-8") as f:
    json.dump(doc, f, indent="\t")
    f.write("\n")
'
if [ -f "$entry/ok" ] && /usr/bin/python3 -c "$relink" "$entry/$record" "$dir/$record.tmp.$$" "$dir" 2> /dev/null; then
    mv "$dir/$record.tmp.$$" "$dir/$record" && cat "$entry/out.txt" && exit 0
fi
rm -f "$dir/$record.tmp.$$"
mkdir -p "$cache/fits" || exec "${fit[@]}"
tmp=$(mktemp -d "$cache/fits/tmp-$key-XXXXXX") || exec "${fit[@]}"
trap 'rm -rf "$tmp"' EXIT
"${fit[@]}" > "$tmp/out.txt"
st=$?
cat "$tmp/out.txt"
if [ $st -eq 0 ] && cp "$dir/$record" "$tmp/$record" 2> /dev/null && : > "$tmp/ok"; then
    # Published whole by rename; a concurrent run that published first keeps its entry.
    mv -T "$tmp" "$entry" 2> /dev/null
fi
exit $st
