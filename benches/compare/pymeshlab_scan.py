"""PyMeshLab over a list of mesh files, one after another, as a scan would.

    python pymeshlab_scan.py LIST [--selfx] [--strict]    # prints the seconds inside the process

For each file: load, merge duplicate vertices, topological and geometric measures, and with
`--selfx` its per-face self-intersection selection. A file it cannot read is passed over, or with
`--strict` ends the run with an error (`pymeshlab_list.sh` uses that to try one file). Time whole
processes (`/usr/bin/time`) to compare with meshvet's; `pymeshlab_list.sh` makes the list.
Needs the `pymeshlab` package from PyPI.
"""
import sys
import time

import pymeshlab


def main():
    selfx = "--selfx" in sys.argv[2:]
    strict = "--strict" in sys.argv[2:]
    files = [line.strip() for line in open(sys.argv[1]) if line.strip()]
    start = time.perf_counter()
    for path in files:
        ms = pymeshlab.MeshSet()
        try:
            ms.load_new_mesh(path)
            ms.meshing_remove_duplicate_vertices()
            ms.get_topological_measures()
            ms.get_geometric_measures()
            if selfx:
                ms.compute_selection_by_self_intersections_per_face()
        except pymeshlab.PyMeshLabException:
            if strict:
                raise
    print(f"{time.perf_counter() - start:.3f}")


if __name__ == "__main__":
    main()
