"""A closed torus as an ASCII PLY: N x N grid points (660 by default: 435,600 points, 871,200
faces), two triangles a cell, every face wound outward.

    python torus.py OUT.ply [--n N] [--shuffle SEED]

Faces are written in grid order, or shuffled with `--shuffle`. meshvet sorts faces by vertex as
it builds its Corner Table, so the order changes nothing for it; CGAL's query and PyMeshLab's
selection keep the file's order and take longer on the shuffled file. Radii 1 and 0.3.
"""
import argparse
import math
import random


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("--n", type=int, default=660)
    ap.add_argument("--shuffle", type=int, default=None, metavar="SEED")
    a = ap.parse_args()
    n = a.n
    points = []
    for i in range(n):
        u = 2 * math.pi * i / n
        for j in range(n):
            v = 2 * math.pi * j / n
            ring = 1 + 0.3 * math.cos(v)
            points.append((ring * math.cos(u), ring * math.sin(u), 0.3 * math.sin(v)))
    faces = []
    for i in range(n):
        for j in range(n):
            p, q = i * n + j, ((i + 1) % n) * n + j
            p1, q1 = i * n + (j + 1) % n, ((i + 1) % n) * n + (j + 1) % n
            faces += [(p, q, q1), (p, q1, p1)]
    if a.shuffle is not None:
        random.Random(a.shuffle).shuffle(faces)
    with open(a.out, "w") as f:
        f.write(f"ply\nformat ascii 1.0\nelement vertex {len(points)}\n")
        f.write("property float x\nproperty float y\nproperty float z\n")
        f.write(f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
        f.writelines(f"{x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in points)
        f.writelines(f"3 {p} {q} {r}\n" for p, q, r in faces)


if __name__ == "__main__":
    main()
