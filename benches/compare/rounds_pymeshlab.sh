#!/bin/bash
# rounds_pymeshlab.sh N MESHVET LIST: N rounds of PyMeshLab with its self-intersection selection
# (pymeshlab_scan.py --selfx) and MESHVET's one-thread scan of the same files, each timed as the
# CPU time (user + system) of its whole process; prints each round's seconds and ratio.
set -eu
N=$1; BIN=$2; LIST=$3
PY=${PY:-python3}
here=$(cd "$(dirname "$0")" && pwd)
cpu() { { /usr/bin/time -f "%U %S" "$@" > /dev/null; } 2>&1 | tail -1 | awk '{print $1 + $2}'; }
mapfile -t files < "$LIST"
for _ in $(seq "$N"); do
    p=$(cpu "$PY" "$here/pymeshlab_scan.py" "$LIST" --selfx)
    m=$(cpu "$BIN" scan "${files[@]}" --jobs 1 --csv /dev/null -q)
    echo "$p $m" | awk '{printf "PyMeshLab %.2f s, meshvet %.3f s: %.1fx\n", $1, $2, $1 / $2}'
done
