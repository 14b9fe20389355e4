"""CGAL's exact self-intersection query alone on one mesh, timed inside the process.

    python cgal_query.py MESH.ply      # prints "SECONDS PAIRS"

Reads an ASCII PLY (vertex x y z first, faces as index lists), welds vertices by exact position
and drops faces with a repeated vertex (as `../shared/corpus/reference_selfx.csv` was made; the
Stanford dragon has duplicate points, and unwelded CGAL reports 14,670 touching pairs on it, not
205), builds a `Polyhedron_3`, then times `Polygon_mesh_processing.self_intersections` only.
Needs the `cgal` package from PyPI.
"""
import sys
import time

from CGAL import CGAL_Polygon_mesh_processing as pmp
from CGAL.CGAL_Kernel import Point_3
from CGAL.CGAL_Polyhedron_3 import Polyhedron_3


def read_ascii_ply(path):
    with open(path, encoding="ascii", errors="replace") as f:
        if f.readline().strip() != "ply":
            sys.exit(f"{path}: not a PLY")
        counts = {}
        while True:
            line = f.readline()
            if not line:
                sys.exit(f"{path}: no end_header")
            words = line.split()
            if not words:
                continue
            if words[0] == "format" and words[1] != "ascii":
                sys.exit(f"{path}: only ASCII PLY is read here")
            if words[0] == "element":
                counts[words[1]] = int(words[2])
            if words[0] == "end_header":
                break
        points = [tuple(map(float, f.readline().split()[:3])) for _ in range(counts.get("vertex", 0))]
        faces = []
        for _ in range(counts.get("face", 0)):
            words = f.readline().split()
            faces.append(tuple(map(int, words[1 : 1 + int(words[0])])))
    return points, faces


def main():
    points, faces = read_ascii_ply(sys.argv[1])
    ids = {}
    new_id = [ids.setdefault(p, len(ids)) for p in points]
    faces = [tuple(new_id[i] for i in f) for f in faces]
    faces = [list(f) for f in faces if len(set(f)) == len(f)]
    mesh = Polyhedron_3()
    pmp.polygon_soup_to_polygon_mesh([Point_3(*p) for p in ids], faces, mesh)
    pairs = []
    start = time.perf_counter()
    pmp.self_intersections(mesh, pairs)
    print(f"{time.perf_counter() - start:.3f} {len(pairs)}")


if __name__ == "__main__":
    main()
