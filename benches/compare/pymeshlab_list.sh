#!/bin/bash
# pymeshlab_list.sh CORPUS > LIST: the OBJ/PLY/STL/OFF files under CORPUS that PyMeshLab loads,
# measures and selects on without an error or a crash, each tried in a process of its own (some
# crash it). `assimp/invalid/malformed.obj` is left out: PyMeshLab crashes on it only now and then.
set -u
PY=${PY:-python3}
corpus=$(cd "$1" && pwd)
find "$corpus" -type f \( -iname '*.obj' -o -iname '*.ply' -o -iname '*.stl' -o -iname '*.off' \) | sort |
while read -r f; do
    case $f in */malformed.obj) continue ;; esac
    if timeout 60 "$PY" -c '
import sys, pymeshlab
ms = pymeshlab.MeshSet()
ms.load_new_mesh(sys.argv[1])
ms.meshing_remove_duplicate_vertices()
ms.get_topological_measures()
ms.get_geometric_measures()
ms.compute_selection_by_self_intersections_per_face()' "$f" > /dev/null 2>&1; then
        echo "$f"
    fi
done
