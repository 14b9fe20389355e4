#!/usr/bin/env python3
"""Writes the tiny seed files in fuzz/seeds/<target>/ (run from anywhere; overwrites them).

Each seed is a small valid mesh (a tetrahedron, a quad, an open fan...) in one encoding the reader
supports, so libFuzzer starts from inputs that reach the geometry code instead of the first check.
"""
import base64
import json
import os
import struct
import zipfile
import io

HERE = os.path.dirname(os.path.abspath(__file__))

TET_P = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TET_T = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
QUAD_P = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]


def put(target, name, data):
    d = os.path.join(HERE, target)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, name), "wb") as f:
        f.write(data)


def obj():
    v = "".join(f"v {x} {y} {z}\n" for x, y, z in TET_P)
    f = "".join(f"f {a+1} {b+1} {c+1}\n" for a, b, c in TET_T)
    put("obj", "tet.obj", "# tetrahedron\no tet\n" + v + f)
    put("obj", "quad_vt_vn.obj",
        "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n"
        "g quad\nusemtl red\nf 1/1/1 2/2/1 3/3/1 4/4/1\n")
    put("obj", "negative_idx.obj",
        "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf 1//1 2//1 -1//1\nl 1 2\np 3\n")
    put("obj", "concave_ngon.obj",
        "v 0 0 0\nv 2 0 0\nv 2 2 0\nv 1 0.5 0\nv 0 2 0\nf 1 2 3 4 5\n")


def stl():
    s = "solid tet\n"
    for t in TET_T:
        s += " facet normal 0 0 0\n  outer loop\n"
        for i in t:
            s += "   vertex %g %g %g\n" % TET_P[i]
        s += "  endloop\n endfacet\n"
    s += "endsolid tet\n"
    put("stl", "tet_ascii.stl", s)
    b = b"binary tet".ljust(80, b" ") + struct.pack("<I", len(TET_T))
    for t in TET_T:
        b += struct.pack("<3f", 0, 0, 0)
        for i in t:
            b += struct.pack("<3f", *TET_P[i])
        b += b"\0\0"
    put("stl", "tet_binary.stl", b)
    # Binary data behind a 'solid' header, as many exporters write it.
    put("stl", "tet_binary_solid.stl", b"solid" + b[5:])


def ply():
    hdr = ("ply\nformat {fmt} 1.0\ncomment seed\nelement vertex 4\nproperty float x\n"
           "property float y\nproperty float z\nelement face 4\n"
           "property list uchar int vertex_indices\nend_header\n")
    body = "".join("%g %g %g\n" % p for p in TET_P)
    body += "".join("3 %d %d %d\n" % t for t in TET_T)
    put("ply", "tet_ascii.ply", hdr.format(fmt="ascii") + body)
    for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        b = hdr.format(fmt=fmt).encode()
        for p in TET_P:
            b += struct.pack(e + "3f", *p)
        for t in TET_T:
            b += struct.pack(e + "B3i", 3, *t)
        put("ply", f"tet_{fmt}.ply", b)
    # double coordinates, a colour, vertex_index with uint list and a quad, an extra element
    b = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\n"
         "property double y\nproperty double z\nproperty uchar red\nelement face 1\n"
         "property list uchar uint vertex_index\nelement edge 1\nproperty int vertex1\n"
         "property int vertex2\nend_header\n").encode()
    for p in QUAD_P:
        b += struct.pack("<3dB", *p, 200)
    b += struct.pack("<B4I", 4, 0, 1, 2, 3)
    b += struct.pack("<2i", 0, 1)
    put("ply", "quad_double_le.ply", b)


def off():
    s = "OFF\n# tetrahedron\n4 4 6\n" + "".join("%g %g %g\n" % p for p in TET_P)
    s += "".join("3 %d %d %d\n" % t for t in TET_T)
    put("off", "tet.off", s)
    put("off", "quad_colour.off",
        "OFF 4 1 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 255 0 0\n")
    put("off", "coff.off", "COFF\n3 1 0\n0 0 0 1 1 1 1\n1 0 0 1 1 1 1\n0 1 0 1 1 1 1\n3 0 1 2\n")


def gltf_model(bin_len, uri=None):
    buf = {"byteLength": bin_len}
    if uri is not None:
        buf["uri"] = uri
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"mesh": 0},
                  {"mesh": 0, "scale": [-1, 1, 1], "translation": [3, 0, 0]}],
        "meshes": [{"name": "tet", "primitives": [
            {"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "buffers": [buf],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48, "target": 34962},
            {"buffer": 0, "byteOffset": 48, "byteLength": 24, "target": 34963}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0, 0, 0], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5123, "count": 12, "type": "SCALAR"}],
    }


def tet_bin():
    b = b"".join(struct.pack("<3f", *p) for p in TET_P)
    b += b"".join(struct.pack("<3H", *t) for t in TET_T)
    return b


def gltf():
    b = tet_bin()
    uri = "data:application/octet-stream;base64," + base64.b64encode(b).decode()
    put("gltf", "tet_data_uri.gltf", json.dumps(gltf_model(len(b), uri), indent=1))
    # u8 indices, a non-indexed triangle strip primitive, sparse-free
    m = gltf_model(len(b), uri)
    m["meshes"][0]["primitives"].append({"attributes": {"POSITION": 0}, "mode": 5})
    put("gltf", "tet_two_primitives.gltf", json.dumps(m))


def glb():
    b = tet_bin()
    js = json.dumps(gltf_model(len(b)), separators=(",", ":")).encode()
    js += b" " * (-len(js) % 4)
    b += b"\0" * (-len(b) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(b), 0x004E4942) + b
    put("glb", "tet.glb", struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)


def package(parts, method):
    """A ZIP of (name, text) parts with fixed dates, so the seeds do not change between runs."""
    out = io.BytesIO()
    with zipfile.ZipFile(out, "w") as z:
        for name, text in parts:
            info = zipfile.ZipInfo(name, date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = method
            z.writestr(info, text)
    return out.getvalue()


CORE = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
PROD = "http://schemas.microsoft.com/3dmanufacturing/production/2015/06"
RELS = ('<?xml version="1.0" encoding="UTF-8"?><Relationships xmlns="http://schemas.openxmlformats.org/'
        'package/2006/relationships"><Relationship Target="/3D/3dmodel.model" Id="rel0" '
        'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/></Relationships>')


def mesh_3mf(oid, name, points, triangles, props=False):
    v = "".join(f'<vertex x="{x}" y="{y}" z="{z}"/>' for x, y, z in points)
    t = "".join(f'<triangle v1="{a}" v2="{b}" v3="{c}"' + (f' pid="9" p1="{a}" p2="{b}" p3="{c}"' if props else "")
                + "/>" for a, b, c in triangles)
    return f'<object id="{oid}" name="{name}"><mesh><vertices>{v}</vertices><triangles>{t}</triangles></mesh></object>'


def threemf():
    model = (f'<?xml version="1.0" encoding="UTF-8"?><model unit="millimeter" xmlns="{CORE}"><resources>'
             + mesh_3mf(1, "tet", TET_P, TET_T) + '</resources><build><item objectid="1"/></build></model>')
    put("3mf", "tet_stored.3mf", package([("_rels/.rels", RELS), ("3D/3dmodel.model", model)], zipfile.ZIP_STORED))
    put("3mf", "tet_deflated.3mf", package([("_rels/.rels", RELS), ("3D/3dmodel.model", model)], zipfile.ZIP_DEFLATED))
    # An assembly: an open tetrahedron (a hole to fill) with colours per corner, placed by two
    # components (one mirrored) from a second model part, and a flipped triangle to orient.
    open_tet = [TET_T[0], (TET_T[1][0], TET_T[1][2], TET_T[1][1]), TET_T[2]]
    part = (f'<?xml version="1.0" encoding="UTF-8"?><model unit="millimeter" xmlns="{CORE}"><resources>'
            f'<m:colorgroup xmlns:m="http://schemas.microsoft.com/3dmanufacturing/material/2015/02" id="9">'
            '<m:color color="#FF0000"/><m:color color="#00FF00"/><m:color color="#0000FF"/><m:color color="#FFFFFF"/>'
            '</m:colorgroup>' + mesh_3mf(1, "open", TET_P, open_tet, props=True) + '</resources><build/></model>')
    root = (f'<?xml version="1.0" encoding="UTF-8"?><model unit="inch" xmlns="{CORE}" xmlns:p="{PROD}" '
            'requiredextensions="p"><resources><object id="2" name="pair"><components>'
            '<component objectid="1" p:path="/3D/part.model"/>'
            '<component objectid="1" p:path="/3D/part.model" transform="-1 0 0 0 1 0 0 0 1 2 0 0"/>'
            '</components></object></resources><build><item objectid="2"/></build></model>')
    put("3mf", "assembly.3mf", package([("_rels/.rels", RELS), ("3D/3dmodel.model", root),
                                        ("3D/part.model", part), ("Metadata/notes.txt", "kept as it is")],
                                       zipfile.ZIP_STORED))


if __name__ == "__main__":
    obj(); stl(); ply(); off(); gltf(); glb(); threemf()
