"""Writes cgal_selfx_cases.txt: random small meshes with CGAL's count of face pairs that meet.

Run with the `cgal` package from PyPI (CGAL 6.0 bindings, exact predicates), outside the repository:
    python cgal_selfx_cases.py > cgal_selfx_cases.txt

Three kinds of case, 200 of each, from a fixed seed:
- soup: 10 triangles with 30 distinct points on the grid {0..3}^3, some coordinates moved by
  +-2^-30 (each triangle its own component, so every pair is tested with no shared vertex);
- closed: an icosahedron whose 12 vertices are moved to distinct random points of {0..4}^3
  (one component whose faces share edges and vertices, and fold or cross in every way);
- tight: the same on the grid {0..2}^3, where most contacts are exactly coplanar or touching.
Faces with three collinear points are avoided (CGAL reports those as (f, f)).
Each case: a line `case KIND V F PAIRS`, V lines of `x y z`, F lines of `a b c`.
"""
import random
import tempfile
from CGAL.CGAL_Polyhedron_3 import Polyhedron_3
from CGAL import CGAL_Polygon_mesh_processing as P

ICOSAHEDRON = [
    (0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
    (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
    (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1),
]


def collinear(p, q, r):
    u = [q[k] - p[k] for k in range(3)]
    w = [r[k] - p[k] for k in range(3)]
    return u[1] * w[2] - u[2] * w[1] == 0 and u[2] * w[0] - u[0] * w[2] == 0 and u[0] * w[1] - u[1] * w[0] == 0


def pairs(points, faces):
    with tempfile.NamedTemporaryFile("w", suffix=".off", delete=False) as f:
        f.write(f"OFF\n{len(points)} {len(faces)} 0\n")
        for p in points:
            f.write(" ".join(repr(float(x)) for x in p) + "\n")
        for t in faces:
            f.write("3 " + " ".join(map(str, t)) + "\n")
        name = f.name
    poly = Polyhedron_3(name)
    assert poly.size_of_facets() == len(faces), name
    out = []
    P.self_intersections(poly, out)
    return len(out)


def soup(rng):
    grid = [(x, y, z) for x in range(4) for y in range(4) for z in range(4)]
    while True:
        chosen = rng.sample(grid, 30)
        points = []
        for p in chosen:
            p = list(p)
            if rng.random() < 0.2:
                p[rng.randrange(3)] += rng.choice([-1, 1]) * 2.0 ** -30
            points.append(tuple(p))
        faces = [(3 * i, 3 * i + 1, 3 * i + 2) for i in range(10)]
        if not any(collinear(*(points[v] for v in t)) for t in faces):
            return points, faces


def closed(rng, side=5):
    grid = [(x, y, z) for x in range(side) for y in range(side) for z in range(side)]
    while True:
        points = rng.sample(grid, 12)
        if not any(collinear(*(points[v] for v in t)) for t in ICOSAHEDRON):
            return points, ICOSAHEDRON


rng = random.Random(13)
def tight(rng):
    return closed(rng, side=3)


for kind, make in [("soup", soup), ("closed", closed), ("tight", tight)]:
    for _ in range(200):
        points, faces = make(rng)
        print(f"case {kind} {len(points)} {len(faces)} {pairs(points, faces)}")
        for p in points:
            print(" ".join(repr(float(x)) for x in p))
        for t in faces:
            print(" ".join(map(str, t)))
