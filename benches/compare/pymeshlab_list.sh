#!/bin/bash
# pymeshlab_list.sh CORPUS > LIST: the OBJ/PLY/STL/OFF files under CORPUS that PyMeshLab loads,
# measures and selects on without an error or a crash (`pymeshlab_scan.py --strict`), each tried
# in a process of its own (some crash it). `assimp/invalid/malformed.obj` is left out: PyMeshLab
# crashes on it only now and then.
set -u
PY=${PY:-python3}
here=$(cd "$(dirname "$0")" && pwd)
corpus=$(cd "$1" && pwd)
one=$(mktemp)
find "$corpus" -type f \( -iname '*.obj' -o -iname '*.ply' -o -iname '*.stl' -o -iname '*.off' \) | sort |
while read -r f; do
    case $f in */malformed.obj) continue ;; esac
    printf '%s\n' "$f" > "$one"
    if timeout 60 "$PY" "$here/pymeshlab_scan.py" "$one" --selfx --strict > /dev/null 2>&1; then
        echo "$f"
    fi
done
rm -f "$one"
