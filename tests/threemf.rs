//! The 3MF reader and writer on packages built here with a ZIP writer: hand-counted meshes,
//! components and mirrored placements, every refusal the format's rules demand (hostile packages
//! among them: ZIP bombs, DTD entity attacks, deep and cyclic component chains, targets outside the
//! package), repaired copies that keep the rest of the package, and agreement with lib3mf 2.5 (the
//! 3MF Consortium's reader) on the shared corpus.

use std::io::{Cursor, Read as _, Write as _};
use std::path::{Path, PathBuf};

use meshvet::config::Settings;
use meshvet::formats::write::write_repaired;
use meshvet::formats::{read, Format, Limits, ReadContext};
use meshvet::mesh::Mesh;
use meshvet::repair::{self, Plan};
use meshvet::topology::{analyse, Options};
use zip::write::SimpleFileOptions;
use zip::{CompressionMethod, ZipArchive, ZipWriter};

#[allow(dead_code)]
mod shapes;

// ---------------------------------------------------------------------------------------------
// Harness

const CORE: &str = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02";
const PRODUCTION: &str = "http://schemas.microsoft.com/3dmanufacturing/production/2015/06";
const MATERIAL: &str = "http://schemas.microsoft.com/3dmanufacturing/material/2015/02";

const ROOT_RELS: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">
 <Relationship Target="/3D/3dmodel.model" Id="rel0" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>
</Relationships>"#;

const CONTENT_TYPES: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types"><Default Extension="rels" ContentType="application/vnd.openxmlformats-package.relationships+xml"/><Default Extension="model" ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/></Types>"#;

/// A ZIP of `entries` (name, bytes), deflated.
fn zip(entries: &[(&str, &[u8])]) -> Vec<u8> {
    let mut w = ZipWriter::new(Cursor::new(Vec::new()));
    for (name, bytes) in entries {
        w.start_file(
            *name,
            SimpleFileOptions::default().compression_method(CompressionMethod::Deflated),
        )
        .unwrap();
        w.write_all(bytes).unwrap();
    }
    w.finish().unwrap().into_inner()
}

/// A package whose root model part is `model`.
fn package(model: &str) -> Vec<u8> {
    package_with(model, &[])
}

/// A package whose root model part is `model`, with `more` entries.
fn package_with(model: &str, more: &[(&str, &[u8])]) -> Vec<u8> {
    let mut entries: Vec<(&str, &[u8])> = vec![
        ("[Content_Types].xml", CONTENT_TYPES.as_bytes()),
        ("_rels/.rels", ROOT_RELS.as_bytes()),
        ("3D/3dmodel.model", model.as_bytes()),
    ];
    entries.extend_from_slice(more);
    zip(&entries)
}

/// A model part: `<model>` with the core, production and material namespaces, `resources` and
/// `build` as given.
fn model(resources: &str, build: &str) -> String {
    model_with("", resources, build)
}

fn model_with(attributes: &str, resources: &str, build: &str) -> String {
    format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<model unit="millimeter" xml:lang="en-US" xmlns="{CORE}" xmlns:p="{PRODUCTION}" xmlns:m="{MATERIAL}"{attributes}>
 <resources>
{resources}
 </resources>
 <build>
{build}
 </build>
</model>
"#
    )
}

/// An object with a mesh.
fn mesh_object(id: u32, name: &str, positions: &[[f64; 3]], triangles: &[[u32; 3]]) -> String {
    let mut s = format!(
        "  <object id=\"{id}\" name=\"{name}\" type=\"model\">\n   <mesh>\n    <vertices>\n"
    );
    for p in positions {
        s.push_str(&format!(
            "     <vertex x=\"{}\" y=\"{}\" z=\"{}\"/>\n",
            p[0], p[1], p[2]
        ));
    }
    s.push_str("    </vertices>\n    <triangles>\n");
    for t in triangles {
        s.push_str(&format!(
            "     <triangle v1=\"{}\" v2=\"{}\" v3=\"{}\"/>\n",
            t[0], t[1], t[2]
        ));
    }
    s.push_str("    </triangles>\n   </mesh>\n  </object>\n");
    s
}

/// The unit tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1), wound outward: V 4, E 6, F 4, chi 2,
/// volume 1/6.
fn tetrahedron() -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let t = shapes::tetrahedron();
    (t.positions, t.triangles)
}

/// The unit cube, 8 vertices and 12 triangles wound outward (volume 1); `open` leaves out the
/// last two triangles (the +z face), which makes one hole of 4 border edges.
fn cube(open: bool) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let positions = (0..8)
        .map(|i| [(i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64])
        .collect();
    let mut triangles = vec![
        [0, 2, 1],
        [1, 2, 3], // -z
        [0, 1, 5],
        [0, 5, 4], // -y
        [2, 6, 7],
        [2, 7, 3], // +y
        [0, 4, 6],
        [0, 6, 2], // -x
        [1, 3, 7],
        [1, 7, 5], // +x
        [4, 5, 7],
        [4, 7, 6], // +z
    ];
    if open {
        triangles.truncate(10);
    }
    (positions, triangles)
}

fn limits() -> Limits {
    Limits::default()
}

/// Writes `bytes` as `name` in a fresh folder and reads it with `limits`.
fn read_with(bytes: &[u8], limits: Limits) -> Result<Vec<Mesh>, String> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.3mf");
    std::fs::write(&path, bytes).unwrap();
    let cx = ReadContext {
        root: dir.path().to_path_buf(),
        limits,
    };
    let result = read(&path, Format::ThreeMf, &cx).map_err(|e| e.0);
    if let Err(e) = &result {
        assert!(
            !e.contains("crashed"),
            "the error came from a caught panic: {e}"
        );
    }
    result
}

fn read_ok(bytes: &[u8]) -> Vec<Mesh> {
    read_with(bytes, limits()).unwrap_or_else(|e| panic!("expected a read, got: {e}"))
}

/// The error of a package that must be refused, checked to contain `words`.
fn refused(bytes: &[u8], words: &str) -> String {
    match read_with(bytes, limits()) {
        Ok(meshes) => panic!("expected a refusal ({words}), read {} meshes", meshes.len()),
        Err(e) => {
            assert!(e.contains(words), "expected `{words}` in: {e}");
            e
        }
    }
}

fn tet_package() -> Vec<u8> {
    let (p, t) = tetrahedron();
    package(&model(
        &mesh_object(1, "tet", &p, &t),
        r#"  <item objectid="1"/>"#,
    ))
}

// ---------------------------------------------------------------------------------------------
// Hand-counted constructions

/// One tetrahedron placed once: V 4, F 4, closed (E 6, no border), chi = 4 - 6 + 4 = 2, volume 1/6.
#[test]
fn a_tetrahedron_reads_with_its_counts() {
    let meshes = read_ok(&tet_package());
    assert_eq!(meshes.len(), 1);
    let m = &meshes[0];
    assert_eq!(m.name.as_deref(), Some("tet"));
    assert_eq!((m.positions.len(), m.triangles.len()), (4, 4));
    assert_eq!(m.notes, ["unit millimeter", "1 placement"]);
    assert_eq!(m.mirrored_instances, 0);
    let a = analyse(m, &Options::default());
    assert_eq!(
        (a.vertices, a.faces, a.edges, a.border_edges, a.euler),
        (4, 4, 6, 0, 2)
    );
    let volume = a.volume().unwrap();
    assert!((volume - 1.0 / 6.0).abs() < 1e-12, "{volume}");
}

/// A plate: a cube placed twice, a tetrahedron once, an unnamed open cube once, and an object of
/// type `other` nobody places (no row). Rows: `cube` 12 faces, 2 placements; `tet` 4 faces;
/// `#3` (no name) 10 faces with one hole.
#[test]
fn a_plate_gives_one_mesh_per_placed_object() {
    let (cp, ct) = cube(false);
    let (tp, tt) = tetrahedron();
    let (op, ot) = cube(true);
    let unnamed = mesh_object(3, "", &op, &ot).replace(" name=\"\"", "");
    let other = mesh_object(4, "helper", &tp, &tt).replace("type=\"model\"", "type=\"other\"");
    let resources = [
        mesh_object(1, "cube", &cp, &ct),
        mesh_object(2, "tet", &tp, &tt),
        unnamed,
        other,
    ]
    .concat();
    let build = r#"  <item objectid="1" transform="1 0 0 0 1 0 0 0 1 0 0 0"/>
  <item objectid="2" transform="1 0 0 0 1 0 0 0 1 5 0 0"/>
  <item objectid="1" transform="1 0 0 0 1 0 0 0 1 10 0 0"/>
  <item objectid="3"/>"#;
    let meshes = read_ok(&package(&model(&resources, build)));
    let got: Vec<(String, usize, Vec<String>)> = meshes
        .iter()
        .map(|m| (m.name.clone().unwrap(), m.triangles.len(), m.notes.clone()))
        .collect();
    let notes = |n: &str| vec!["unit millimeter".to_owned(), n.to_owned()];
    assert_eq!(
        got,
        [
            ("cube".to_owned(), 12, notes("2 placements")),
            ("tet".to_owned(), 4, notes("1 placement")),
            ("#3".to_owned(), 10, notes("1 placement")),
        ]
    );
    let open = analyse(&meshes[2], &Options::default());
    assert_eq!((open.border_edges, open.components[0].holes), (4, 1));
}

/// An assembly: object 10 has two components of the tetrahedron (object 1), the second mirrored
/// in x (det diag(-1,1,1) = -1); the build places 10 once and the tetrahedron once directly.
/// Paths to 1: item 10 -> +, item 10 -> mirrored, item 1 -> +: 3 placements, 1 mirrored.
/// A build item that mirrors the assembly (det -1) swaps which of its two is mirrored (still 1 of
/// 3); mirroring the direct item as well makes it 2 of 3.
#[test]
fn components_count_placements_and_mirrored_ones() {
    let (p, t) = tetrahedron();
    let assembly = r#"  <object id="10" name="pair"><components>
   <component objectid="1"/>
   <component objectid="1" transform="-1 0 0 0 1 0 0 0 1 3 0 0"/>
  </components></object>"#;
    let resources = format!("{}{assembly}", mesh_object(1, "tet", &p, &t));
    let meshes = read_ok(&package(&model(
        &resources,
        "  <item objectid=\"10\"/><item objectid=\"1\"/>",
    )));
    assert_eq!(meshes.len(), 1);
    assert_eq!(meshes[0].notes, ["unit millimeter", "3 placements"]);
    assert_eq!(meshes[0].mirrored_instances, 1);

    let meshes = read_ok(&package(&model(
        &resources,
        "  <item objectid=\"10\" transform=\"1 0 0 0 -1 0 0 0 1 0 0 0\"/><item objectid=\"1\"/>",
    )));
    assert_eq!(meshes[0].mirrored_instances, 1);
    let meshes = read_ok(&package(&model(
        &resources,
        "  <item objectid=\"10\" transform=\"1 0 0 0 -1 0 0 0 1 0 0 0\"/><item objectid=\"1\" transform=\"1 0 0 0 1 0 0 0 -1 0 0 0\"/>",
    )));
    assert_eq!(meshes[0].mirrored_instances, 2);
}

/// The same mirrored assembly through a scan: the row carries the `mirrored-instance` finding.
#[test]
fn a_mirrored_placement_is_a_finding_in_the_scan() {
    let (p, t) = tetrahedron();
    let resources = format!(
        "{}  <object id=\"2\"><components><component objectid=\"1\" transform=\"-1 0 0 0 1 0 0 0 1 0 0 0\"/></components></object>",
        mesh_object(1, "tet", &p, &t)
    );
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("m.3mf"),
        package(&model(&resources, "<item objectid=\"2\"/>")),
    )
    .unwrap();
    let rows = scan_rows(dir.path(), &Settings::default());
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].format, "3mf");
    assert_eq!(rows[0].mesh, "tet");
    assert!(
        rows[0].findings.contains("mirrored-instance:1"),
        "{:?}",
        rows[0]
    );
    assert!(
        rows[0].message.contains("unit millimeter; 1 placement"),
        "{}",
        rows[0].message
    );
}

/// Every mesh object in a part other than the root is named with its part; names two objects share
/// get their ids; objects of type support are said to be.
#[test]
fn production_parts_names_and_types() {
    let (p, t) = tetrahedron();
    let other = model(
        &format!(
            "{}{}",
            mesh_object(1, "", &p, &t).replace(" name=\"\"", ""),
            mesh_object(2, "twin", &p, &t).replace("type=\"model\"", "type=\"support\"")
        ),
        "",
    );
    let root = model(
        &mesh_object(5, "twin", &p, &t),
        r#"<item objectid="1" p:path="/3D/parts/other.model"/><item objectid="2" p:path="/3D/parts/other.model"/><item objectid="5"/>"#,
    );
    let meshes = read_ok(&package_with(
        &root,
        &[("3D/parts/other.model", other.as_bytes())],
    ));
    let names: Vec<&str> = meshes.iter().map(|m| m.name.as_deref().unwrap()).collect();
    assert_eq!(
        names,
        [
            "twin (#5)",
            "/3D/parts/other.model#1",
            "twin (/3D/parts/other.model#2)"
        ]
    );
    assert!(
        meshes[2].notes.contains(&"type support".to_owned()),
        "{:?}",
        meshes[2].notes
    );
}

/// Non-finite coordinates are not refused: they reach the analysis as invalid vertices.
#[test]
fn non_finite_vertices_are_invalid_vertices() {
    let (mut p, t) = tetrahedron();
    p[3] = [f64::NAN, 0.0, 0.0];
    let text = mesh_object(1, "tet", &p, &t).replace("x=\"NaN\"", "x=\"INF\"");
    let meshes = read_ok(&package(&model(&text, "<item objectid=\"1\"/>")));
    assert!(meshes[0].positions[3][0].is_infinite());
    let a = analyse(&meshes[0], &Options::default());
    assert_eq!(a.invalid_vertices, 1);
}

/// Materials, colours, textures, beam lattices, slices, metadata and unknown extension elements
/// are read past; an empty build gives no mesh (an `empty` row), which is not an error.
#[test]
fn extensions_are_read_past() {
    let (p, t) = tetrahedron();
    let object = mesh_object(1, "tet", &p, &t).replace(
        "   </mesh>",
        r#"    <b:beamlattice radius="1" minlength="0.1" cap="sphere"><b:beams><b:beam v1="0" v2="1"/></b:beams></b:beamlattice>
   </mesh>"#,
    );
    let resources = format!(
        r##"  <basematerials id="7"><base name="red" displaycolor="#FF0000"/></basematerials>
  <m:colorgroup id="8"><m:color color="#00FF00"/></m:colorgroup>
  <s:slicestack id="9" zbottom="0"><s:slice ztop="1"><s:vertices><s:vertex x="0" y="0"/></s:vertices></s:slice></s:slicestack>
  <x:whatever xmlns:x="urn:vendor" a="1"><x:deeper/></x:whatever>
{object}"##
    );
    let text = |build: &str| {
        model_with(
            r#" xmlns:b="http://schemas.microsoft.com/3dmanufacturing/beamlattice/2017/02" xmlns:s="http://schemas.microsoft.com/3dmanufacturing/slice/2015/07" requiredextensions="p m b s""#,
            &resources,
            build,
        )
        .replace("<resources>", "<metadata name=\"Title\">A &amp; B &#65;</metadata>\n <resources>")
    };
    let meshes = read_ok(&package(&text("<item objectid=\"1\"/>")));
    assert_eq!(meshes[0].triangles.len(), 4);
    assert!(
        meshes[0]
            .notes
            .contains(&"a beam lattice in the mesh is not checked".to_owned()),
        "{:?}",
        meshes[0].notes
    );
    assert!(read_ok(&package(&text(""))).is_empty());
}

// ---------------------------------------------------------------------------------------------
// Refusals: the package

#[test]
fn a_file_that_is_not_a_zip_is_refused() {
    refused(b"solid cube\nendsolid\n", "not a 3MF package");
    refused(b"", "not a 3MF package");
    let mut cut = tet_package();
    cut.truncate(cut.len() / 2);
    refused(&cut, "not a 3MF package");
}

#[test]
fn a_package_without_a_root_model_is_refused() {
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>");
    // No _rels/.rels at all.
    refused(
        &zip(&[("3D/3dmodel.model", text.as_bytes())]),
        "no _rels/.rels",
    );
    // Relationships, but none of the model type.
    let rels = ROOT_RELS.replace("2013/01/3dmodel", "2013/01/thumbnail");
    refused(
        &zip(&[
            ("_rels/.rels", rels.as_bytes()),
            ("3D/3dmodel.model", text.as_bytes()),
        ]),
        "names no root model part",
    );
    // The named part is missing.
    refused(
        &zip(&[("_rels/.rels", ROOT_RELS.as_bytes())]),
        "which the package does not have",
    );
    // Two root model relationships.
    let two = ROOT_RELS.replace(
        "</Relationships>",
        r#"<Relationship Target="/3D/other.model" Id="rel9" Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/></Relationships>"#,
    );
    refused(
        &zip(&[
            ("_rels/.rels", two.as_bytes()),
            ("3D/3dmodel.model", text.as_bytes()),
            ("3D/other.model", text.as_bytes()),
        ]),
        "names 2 root model parts",
    );
}

/// Two entries with one part name give a package without one meaning (readers differ on which
/// they take): refused, whether the names are equal or differ in ASCII case only. The ZIP writer
/// refuses equal names, so the second is renamed in the bytes (name lengths are equal).
#[test]
fn two_parts_with_one_name_are_refused() {
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>");
    let (cp, ct) = cube(false);
    let other = model(&mesh_object(1, "cube", &cp, &ct), "<item objectid=\"1\"/>");
    let bytes = package_with(&text, &[("3D/3dmodel.modeX", other.as_bytes())]);
    assert_eq!(read_ok(&bytes).len(), 1);
    let renamed = |to: &[u8]| {
        let mut b = bytes.clone();
        let mut at = 0;
        while let Some(i) = find(&b[at..], b"3D/3dmodel.modeX") {
            b[at + i..at + i + to.len()].copy_from_slice(to);
            at += i + 1;
        }
        b
    };
    refused(
        &renamed(b"3D/3dmodel.model"),
        "two parts with the same name",
    );
    refused(&renamed(b"3D/3DModel.model"), "two parts named");
}

/// Names that differ only in bytes that are not UTF-8 (an old ZIP tool's code page), or in
/// percent-escapes of such bytes, are different parts: the package reads.
#[test]
fn names_differing_in_bytes_that_are_not_utf8_are_different_parts() {
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>");
    let mut bytes = package_with(
        &text,
        &[
            ("Metadata/aX.png", b"one"),
            ("Metadata/aY.png", b"two"),
            ("Metadata/b%FF.png", b"three"),
            ("Metadata/b%FE.png", b"four"),
        ],
    );
    for (from, to) in [
        (&b"aX.png"[..], &b"a\xff.png"[..]),
        (b"aY.png", b"a\xfe.png"),
    ] {
        let mut at = 0;
        while let Some(i) = find(&bytes[at..], from) {
            bytes[at + i..at + i + to.len()].copy_from_slice(to);
            at += i + 1;
        }
    }
    assert!(find(&bytes, b"a\xff.png").is_some() && find(&bytes, b"aX.png").is_none());
    assert_eq!(read_ok(&bytes).len(), 1);
}

/// Relationship targets and `p:path` references must name parts of the package: `..` above the
/// root, absolute `file:` URIs, other schemes, network paths and External targets are refused.
#[test]
fn targets_outside_the_package_are_refused() {
    let text = {
        let (p, t) = tetrahedron();
        model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>")
    };
    for target in [
        "../3dmodel.model",
        "/3D/../../3dmodel.model",
        "file:///etc/passwd",
        "file:3D/3dmodel.model",
        "http://example.com/3dmodel.model",
        "//server/share/3dmodel.model",
    ] {
        let rels = ROOT_RELS.replace("/3D/3dmodel.model", target);
        refused(
            &zip(&[
                ("_rels/.rels", rels.as_bytes()),
                ("3D/3dmodel.model", text.as_bytes()),
            ]),
            "a 3MF package may refer only to its own parts",
        );
    }
    // An external thumbnail next to a fine model is refused too (checked, never fetched).
    let rels = ROOT_RELS.replace(
        "</Relationships>",
        r#"<Relationship Target="http://example.com/t.png" TargetMode="External" Id="r2" Type="http://schemas.openxmlformats.org/package/2006/relationships/metadata/thumbnail"/></Relationships>"#,
    );
    refused(
        &zip(&[
            ("_rels/.rels", rels.as_bytes()),
            ("3D/3dmodel.model", text.as_bytes()),
        ]),
        "TargetMode External",
    );
    // The model part's own relationships are held to the same rule.
    let part_rels = ROOT_RELS.replace("/3D/3dmodel.model", "../../../etc/passwd");
    refused(
        &package_with(
            &text,
            &[("3D/_rels/3dmodel.model.rels", part_rels.as_bytes())],
        ),
        "climbs above the package root",
    );
    // And p:path.
    let (p, t) = tetrahedron();
    let root = model(
        &format!(
            "{}<object id=\"2\"><components><component objectid=\"1\" p:path=\"../../outside.model\"/></components></object>",
            mesh_object(1, "tet", &p, &t)
        ),
        "<item objectid=\"2\"/>",
    );
    refused(&package(&root), "p:path");
}

#[test]
fn a_missing_production_part_is_refused() {
    let root = model(
        "<object id=\"2\"><components><component objectid=\"1\" p:path=\"/3D/gone.model\"/></components></object>",
        "<item objectid=\"2\"/>",
    );
    refused(
        &package(&root),
        "/3d/gone.model, which the package does not have",
    );
}

/// An encrypted part: listed in a secure-content keystore, or a ZIP entry with the password flag.
#[test]
fn encrypted_meshes_are_refused_as_encrypted() {
    let root = model(
        "<object id=\"2\"><components><component objectid=\"1\" p:path=\"/3D/secret.model\"/></components></object>",
        "<item objectid=\"2\"/>",
    );
    let rels = ROOT_RELS.replace(
        "</Relationships>",
        r#"<Relationship Target="/Secure/keystore.xml" Id="rel1" Type="http://schemas.microsoft.com/3dmanufacturing/2019/04/keystore"/></Relationships>"#,
    );
    let keystore = r#"<?xml version="1.0" encoding="UTF-8"?>
<keystore xmlns="http://schemas.microsoft.com/3dmanufacturing/securecontent/2019/04" UUID="a">
 <resourcedatagroup keyuuid="b"><resourcedata path="/3D/secret.model"><cekparams encryptionalgorithm="http://www.w3.org/2009/xmlenc11#aes256-gcm"/></resourcedata></resourcedatagroup>
</keystore>"#;
    let bytes = zip(&[
        ("_rels/.rels", rels.as_bytes()),
        ("3D/3dmodel.model", root.as_bytes()),
        ("3D/secret.model", b"\x8f\x02 not XML at all"),
        ("Secure/keystore.xml", keystore.as_bytes()),
    ]);
    let e = refused(&bytes, "is encrypted");
    assert!(e.contains("/3D/secret.model"), "{e}");

    // The ZIP's own encryption flag (bit 0 of the general purpose flags, in the local header and
    // in the central directory) on the model part.
    let mut bytes = tet_package();
    let mut flagged = 0;
    for (signature, flags_at) in [(&b"PK\x03\x04"[..], 6), (&b"PK\x01\x02"[..], 8)] {
        let mut at = 0;
        while let Some(i) = find(&bytes[at..], signature) {
            let header = at + i;
            let name_at = if signature[2] == 3 {
                header + 30
            } else {
                header + 46
            };
            if bytes[name_at..].starts_with(b"3D/3dmodel.model") {
                bytes[header + flags_at] |= 1;
                flagged += 1;
            }
            at = header + 4;
        }
    }
    assert_eq!(flagged, 2);
    refused(&bytes, "is encrypted");
}

fn find(hay: &[u8], needle: &[u8]) -> Option<usize> {
    hay.windows(needle.len()).position(|w| w == needle)
}

/// A part that inflates far beyond what its stored bytes could hold as a mesh: 8 MiB of spaces
/// deflate to about 8 KiB (a ratio near 1,000 to 1, over the cap of 250).
#[test]
fn a_zip_bomb_by_ratio_is_refused_unread() {
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>")
        .replace("<build>", &format!("{}<build>", " ".repeat(8 << 20)));
    let bytes = package(&text);
    assert!(bytes.len() < 64 << 10, "{} bytes", bytes.len());
    refused(&bytes, "compression ratio over 250 to 1");
}

/// A part whose ZIP entry declares fewer bytes than it inflates to: reading stops at the declared
/// size with an error, whatever the stream holds. The declared size is patched in both headers.
#[test]
fn a_zip_bomb_by_lying_size_is_cut_off() {
    let bytes = tet_package();
    let mut archive = ZipArchive::new(Cursor::new(bytes.clone())).unwrap();
    let real = archive.by_name("3D/3dmodel.model").unwrap().size() as u32;
    drop(archive);
    let mut lying = bytes;
    let mut patched = 0;
    for (signature, size_at, name_at) in
        [(&b"PK\x03\x04"[..], 22, 30), (&b"PK\x01\x02"[..], 24, 46)]
    {
        let mut at = 0;
        while let Some(i) = find(&lying[at..], signature) {
            let h = at + i;
            if lying[h + name_at..].starts_with(b"3D/3dmodel.model") {
                assert_eq!(lying[h + size_at..h + size_at + 4], real.to_le_bytes());
                lying[h + size_at..h + size_at + 4].copy_from_slice(&100u32.to_le_bytes());
                patched += 1;
            }
            at = h + 4;
        }
    }
    assert_eq!(patched, 2);
    // The zip crate notices it first; meshvet's own cut-off stands behind it.
    refused(&lying, "declared uncompressed size");
}

/// The declared inflated sizes of the parts read are held to `max_file_bytes`, before inflating.
#[test]
fn parts_over_the_size_limit_are_refused_before_inflating() {
    // 20,000 spaces in the model part: about 21 kB inflated, a few dozen bytes stored.
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>")
        .replace("<build>", &format!("{}<build>", " ".repeat(20_000)));
    let bytes = package(&text);
    let small = Limits {
        max_file_bytes: 4000,
        ..Limits::default()
    };
    let size = bytes.len() as u64;
    assert!(size < 4000, "{size}");
    let e = read_with(&bytes, small).unwrap_err();
    assert!(e.contains("over the limit of 4000 bytes"), "{e}");
    assert!(e.contains("declares"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Refusals: the XML

/// Billion laughs: nested entities that would expand to gigabytes. Refused at the DOCTYPE, before
/// anything is expanded.
#[test]
fn a_billion_laughs_dtd_is_refused() {
    let mut dtd = String::from("<!DOCTYPE model [\n <!ENTITY lol \"lol\">\n");
    for i in 1..10 {
        let prev = if i == 1 {
            "lol".to_owned()
        } else {
            format!("lol{}", i - 1)
        };
        dtd.push_str(&format!(
            " <!ENTITY lol{i} \"{}\">\n",
            format!("&{prev};").repeat(10)
        ));
    }
    dtd.push_str("]>\n");
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "&lol9;", &p, &t), "<item objectid=\"1\"/>").replacen(
        "<model",
        &format!("{dtd}<model"),
        1,
    );
    refused(&package(&text), "document type declaration");
}

/// XXE: an external entity naming a file on the machine. Refused at the DOCTYPE; nothing is read.
#[test]
fn an_external_entity_is_refused() {
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "&xxe;", &p, &t), "<item objectid=\"1\"/>").replacen(
        "<model",
        "<!DOCTYPE model [ <!ENTITY xxe SYSTEM \"file:///etc/passwd\"> ]>\n<model",
        1,
    );
    refused(&package(&text), "document type declaration");
    // An entity that was never declared is refused too (no DTD to declare it).
    let undeclared = model(&mesh_object(1, "&xxe;", &p, &t), "<item objectid=\"1\"/>");
    refused(&package(&undeclared), "undefined reference");
    // ... and a DTD in the relationships part.
    let rels = ROOT_RELS.replacen(
        "<Relationships",
        "<!DOCTYPE r SYSTEM \"http://example.com/r.dtd\"><Relationships",
        1,
    );
    refused(
        &zip(&[
            ("_rels/.rels", rels.as_bytes()),
            ("3D/3dmodel.model", text.as_bytes()),
        ]),
        "document type declaration",
    );
}

#[test]
fn xml_that_is_not_well_formed_is_refused() {
    let good = {
        let (p, t) = tetrahedron();
        model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>")
    };
    // Mismatched end tag.
    refused(
        &package(&good.replacen("</vertices>", "</vertice>", 1)),
        "not well-formed XML",
    );
    // Cut short.
    refused(
        &package(&good[..good.find("</build>").unwrap()]),
        "ends before its elements are closed",
    );
    // An attribute twice.
    refused(
        &package(&good.replacen(
            "<item objectid=\"1\"",
            "<item objectid=\"1\" objectid=\"1\"",
            1,
        )),
        "twice",
    );
    // An undeclared prefix, on an element and on an attribute.
    refused(
        &package(&good.replacen("<resources>", "<resources><q:thing/>", 1)),
        "prefix `q:` without declaring it",
    );
    refused(
        &package(&good.replacen("<item objectid", "<item q:uuid=\"1\" objectid", 1)),
        "prefix `q:` without declaring it",
    );
    // A second root element, and so a second <model>.
    refused(
        &package(&format!("{good}<model xmlns=\"{CORE}\"/>")),
        "second root element",
    );
    // Not UTF-8.
    refused(
        &package(&good.replacen("encoding=\"UTF-8\"", "encoding=\"ISO-8859-1\"", 1)),
        "encoding",
    );
    // The root element is not a 3MF model.
    refused(
        &package(&good.replace(CORE, "urn:other")),
        "not the <model> of the 3MF core",
    );
}

#[test]
fn a_model_without_build_or_resources_is_refused() {
    let (p, t) = tetrahedron();
    let good = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>");
    let start = good.find(" <build>").unwrap();
    let end = good.find("</build>").unwrap() + "</build>".len();
    let no_build = format!("{}{}", &good[..start], &good[end..]);
    refused(&package(&no_build), "has no <build>");
    let start = good.find(" <resources>").unwrap();
    let end = good.find("</resources>").unwrap() + "</resources>".len();
    let no_resources = format!("{}{}", &good[..start], &good[end..]);
    refused(&package(&no_resources), "has no <resources>");
    let two_builds = good.replacen("<build>", "<build/><build>", 1);
    refused(&package(&two_builds), "2 <build> elements");
}

#[test]
fn unsupported_required_extensions_are_refused() {
    let (p, t) = tetrahedron();
    let resources = mesh_object(1, "tet", &p, &t);
    let text = model_with(
        r#" xmlns:v="http://schemas.3mf.io/3dmanufacturing/volumetric/2022/01" requiredextensions="v""#,
        &resources,
        "<item objectid=\"1\"/>",
    );
    refused(
        &package(&text),
        "volumetric/2022/01 (prefix `v`), which meshvet does not read",
    );
    // A required prefix that is not declared at all.
    let text = model_with(
        r#" requiredextensions="zz""#,
        &resources,
        "<item objectid=\"1\"/>",
    );
    refused(&package(&text), "prefix `zz`, which it does not declare");
    // Declared but not required: read.
    let text = model_with(
        r#" xmlns:v="http://schemas.3mf.io/3dmanufacturing/volumetric/2022/01""#,
        &resources,
        "<item objectid=\"1\"/>",
    );
    assert_eq!(read_ok(&package(&text)).len(), 1);
}

// ---------------------------------------------------------------------------------------------
// Refusals: objects, build and components

#[test]
fn references_to_missing_objects_are_refused() {
    let (p, t) = tetrahedron();
    let tet = mesh_object(1, "tet", &p, &t);
    refused(
        &package(&model(&tet, "<item objectid=\"9\"/>")),
        "build item 0 names object 9",
    );
    let assembly = format!(
        "{tet}<object id=\"2\"><components><component objectid=\"8\"/></components></object>"
    );
    refused(
        &package(&model(&assembly, "<item objectid=\"2\"/>")),
        "names object 8",
    );
}

/// Type `other` is not printable: placing it is an error, directly or as a component.
#[test]
fn placing_an_object_of_type_other_is_refused() {
    let (p, t) = tetrahedron();
    let other = mesh_object(1, "helper", &p, &t).replace("type=\"model\"", "type=\"other\"");
    refused(
        &package(&model(&other, "<item objectid=\"1\"/>")),
        "type is `other`",
    );
    let assembly = format!(
        "{other}<object id=\"2\"><components><component objectid=\"1\"/></components></object>"
    );
    refused(
        &package(&model(&assembly, "<item objectid=\"2\"/>")),
        "type is `other`",
    );
    // A type 3MF does not have.
    let odd = mesh_object(1, "tet", &p, &t).replace("type=\"model\"", "type=\"gizmo\"");
    refused(
        &package(&model(&odd, "<item objectid=\"1\"/>")),
        "type `gizmo`",
    );
}

/// Components that fan out three ways on 42 levels place the mesh 3^42 (about 1.1e20) times, more
/// than a 64-bit count holds, half of them mirrored (more than the 32-bit `mirrored_instances`
/// holds): the message says "more than", never a capped number as if it were exact.
#[test]
fn placement_counts_past_their_limit_say_more_than() {
    let (p, t) = tetrahedron();
    let mut text = mesh_object(1, "tet", &p, &t);
    for k in 2..=43 {
        text.push_str(&format!(
            "<object id=\"{k}\"><components><component objectid=\"{0}\" transform=\"-1 0 0 0 1 0 0 0 1 0 0 0\"/><component objectid=\"{0}\"/><component objectid=\"{0}\"/></components></object>",
            k - 1
        ));
    }
    let meshes = read_ok(&package(&model(&text, "<item objectid=\"43\"/>")));
    assert_eq!(meshes.len(), 1);
    let notes = &meshes[0].notes;
    assert!(
        notes.contains(&"more than 18446744073709551614 placements".to_owned()),
        "{notes:?}"
    );
    assert!(
        notes
            .iter()
            .any(|n| n.starts_with("more than 4294967294 mirrored placements")),
        "{notes:?}"
    );
    assert_eq!(meshes[0].mirrored_instances, u32::MAX);
}

#[test]
fn component_cycles_and_deep_chains_are_refused() {
    let (p, t) = tetrahedron();
    let tet = mesh_object(1, "tet", &p, &t);
    let cycle = format!(
        "{tet}<object id=\"2\"><components><component objectid=\"3\"/></components></object>\
         <object id=\"3\"><components><component objectid=\"2\"/><component objectid=\"1\"/></components></object>"
    );
    let e = refused(&package(&model(&cycle, "<item objectid=\"2\"/>")), "cycle");
    assert!(e.contains("object 2 -> object 3 -> object 2"), "{e}");
    // A chain of 100 levels (object k has object k - 1 as its component, 101 down to the mesh).
    let mut chain = tet.clone();
    for k in 2..=101 {
        chain.push_str(&format!(
            "<object id=\"{k}\"><components><component objectid=\"{}\"/></components></object>",
            k - 1
        ));
    }
    refused(
        &package(&model(&chain, "<item objectid=\"101\"/>")),
        "levels deep",
    );
    // Twenty levels are fine.
    let mut short = tet;
    for k in 2..=20 {
        short.push_str(&format!(
            "<object id=\"{k}\"><components><component objectid=\"{}\"/></components></object>",
            k - 1
        ));
    }
    assert_eq!(
        read_ok(&package(&model(&short, "<item objectid=\"20\"/>"))).len(),
        1
    );
}

#[test]
fn bad_numbers_and_indices_are_refused() {
    let (p, t) = tetrahedron();
    let tet = mesh_object(1, "tet", &p, &t);
    let item = "<item objectid=\"1\"/>";
    // A triangle naming vertex 4 of four (0..3).
    let out_of_range = tet.replacen("v3=\"1\"", "v3=\"4\"", 1);
    refused(
        &package(&model(&out_of_range, item)),
        "names vertex 4, but the mesh has 4 vertices",
    );
    refused(
        &package(&model(&tet.replacen("v3=\"1\"", "v3=\"-1\"", 1), item)),
        "triangle 0",
    );
    // Property ids and indices are whole numbers too (the core spec's ST_ResourceID and
    // ST_ResourceIndex): refused by the scan as the repair's reading refuses them, where the
    // scan used to read past them. lib3mf 2.5 refuses `p1="1.5"` and reads past `pid="-1"`.
    for bad in ["pid=\"-1\" p1=\"0\"", "pid=\"1\" p1=\"1.5\""] {
        let with = tet.replacen("v3=\"1\"", &format!("v3=\"1\" {bad}"), 1);
        refused(&package(&model(&with, item)), "a whole number");
    }
    refused(
        &package(&model(&tet.replacen("x=\"1\"", "x=\"1,5\"", 1), item)),
        "not a number",
    );
    refused(
        &package(&model(&tet.replacen(" z=\"0\"", "", 1), item)),
        "has no z coordinate",
    );
    for transform in [
        "1 0 0 0 1 0 0 0 1 NaN 0 0",
        "1 0 0 0 1 0 0 0 1 inf 0 0",
        "1 0 0 0 1 0 0 0 1 1e999 0 0",
    ] {
        let text = model(
            &tet,
            &format!("<item objectid=\"1\" transform=\"{transform}\"/>"),
        );
        refused(&package(&text), "not finite");
    }
    refused(
        &package(&model(
            &tet,
            "<item objectid=\"1\" transform=\"1 0 0 0 1 0 0 0 1 0 0\"/>",
        )),
        "has 11 numbers",
    );
    refused(
        &package(&model(&tet.replace("id=\"1\"", "id=\"x\""), item)),
        "is not a whole number",
    );
    refused(
        &package(&model(&format!("{tet}{tet}"), item)),
        "defines object 1 twice",
    );
    refused(
        &package(&model(
            &tet.replacen("<triangles>", "<triangles></triangles><triangles>", 1),
            item,
        )),
        "more than one <triangles>",
    );
    refused(
        &package(&model_with("", &tet, item).replace("unit=\"millimeter\"", "unit=\"furlong\"")),
        "unit `furlong`",
    );
}

#[test]
fn too_many_triangles_are_refused() {
    let (p, t) = tetrahedron();
    let text = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>");
    let small = Limits {
        max_triangles: 3,
        ..Limits::default()
    };
    let e = read_with(&package(&text), small).unwrap_err();
    assert!(e.contains("raise limits.max_triangles"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// Repaired copies

/// Reads the inflated entries of a ZIP, in order.
fn entries(bytes: &[u8]) -> Vec<(String, Vec<u8>)> {
    let mut archive = ZipArchive::new(Cursor::new(bytes)).unwrap();
    (0..archive.len())
        .map(|i| {
            let mut file = archive.by_index(i).unwrap();
            let mut data = Vec::new();
            file.read_to_end(&mut data).unwrap();
            (file.name().unwrap().into_owned(), data)
        })
        .collect()
}

/// The plans a scan would make for the meshes of `path` (None for meshes without changes).
fn plans(meshes: &[Mesh]) -> Vec<Option<Plan>> {
    meshes
        .iter()
        .map(|m| Some(repair::plan(m, &repair::Options::default())).filter(Plan::changes))
        .collect()
}

/// Writes the repaired copy of `source` (in the tree `root`) to `out`: what was written, with
/// the writer's notes.
fn copy_with_notes(
    source: &Path,
    plans: &[Option<Plan>],
    out: &Path,
    root: &Path,
) -> meshvet::formats::write::Written {
    meshvet::formats::write::write_copy(source, Format::ThreeMf, plans, out, &cx(root), None)
        .unwrap()
}

fn cx(root: &Path) -> ReadContext {
    ReadContext {
        root: root.to_path_buf(),
        limits: limits(),
    }
}

/// A plate with three objects: an open cube with a colour per corner (`pid` 8, `p1 p2 p3`) on its
/// triangles, a tetrahedron whose triangle 1 is wound against the others and has `p1 p2 p3` 0 1 2,
/// and a clean tetrahedron; plus a thumbnail, a slicer config and a metadata part. Returns the
/// package and the model text.
fn plate() -> (Vec<u8>, String) {
    let (cp, ct) = cube(true);
    let (tp, mut tt) = tetrahedron();
    tt[1] = [tt[1][0], tt[1][2], tt[1][1]];
    let mut open = mesh_object(1, "open box", &cp, &ct);
    for t in &ct {
        let plain = format!("v1=\"{}\" v2=\"{}\" v3=\"{}\"/>", t[0], t[1], t[2]);
        let colour = format!(
            "v1=\"{}\" v2=\"{}\" v3=\"{}\" pid=\"8\" p1=\"{}\" p2=\"{}\" p3=\"{}\"/>",
            t[0], t[1], t[2], t[0], t[1], t[2]
        );
        open = open.replacen(&plain, &colour, 1);
    }
    let mut bent = mesh_object(2, "bent", &tp, &tt);
    let t = tt[1];
    bent = bent.replacen(
        &format!("v1=\"{}\" v2=\"{}\" v3=\"{}\"/>", t[0], t[1], t[2]),
        &format!(
            "v1=\"{}\" v2=\"{}\" v3=\"{}\" pid=\"8\" p1=\"0\" p2=\"1\" p3=\"2\"/>",
            t[0], t[1], t[2]
        ),
        1,
    );
    let (tp2, tt2) = tetrahedron();
    let clean = mesh_object(3, "clean", &tp2, &tt2);
    let colours = "  <m:colorgroup id=\"8\"><m:color color=\"#FF0000\"/><m:color color=\"#00FF00\"/><m:color color=\"#0000FF\"/><m:color color=\"#FFFFFF\"/><m:color color=\"#000000\"/><m:color color=\"#808080\"/><m:color color=\"#800000\"/><m:color color=\"#008000\"/></m:colorgroup>\n";
    let text = model(
        &format!("{colours}{open}{bent}{clean}"),
        "  <item objectid=\"1\"/>\n  <item objectid=\"2\" transform=\"1 0 0 0 1 0 0 0 1 3 0 0\"/>\n  <item objectid=\"3\" transform=\"1 0 0 0 1 0 0 0 1 6 0 0\"/>",
    );
    let thumbnail: Vec<u8> = (0..=255u8).cycle().take(3000).collect();
    let bytes = package_with(
        &text,
        &[
            ("Metadata/thumbnail.png", &thumbnail),
            (
                "Metadata/Slic3r_PE.config",
                b"; layer_height = 0.2\n; fill_density = 15%\n",
            ),
            (
                "Metadata/model_settings.config",
                b"<?xml version=\"1.0\"?><config><object id=\"1\"/></config>",
            ),
        ],
    );
    (bytes, text)
}

/// The copy keeps every other entry and every byte of the model part outside the repaired meshes'
/// `<vertices>` and `<triangles>`; the open box is closed (2 fill triangles, taking the `pid`/`p1`
/// of the triangle beside them), the bent tetrahedron is turned (its odd triangle flipped, with
/// `p2`/`p3` following `v2`/`v3`), and a second repair of the copy changes nothing.
#[test]
fn a_repaired_copy_keeps_the_package_and_the_properties() {
    let dir = tempfile::tempdir().unwrap();
    let (bytes, text) = plate();
    let source = dir.path().join("plate.3mf");
    std::fs::write(&source, &bytes).unwrap();
    let meshes = read(&source, Format::ThreeMf, &cx(dir.path())).unwrap();
    let names: Vec<&str> = meshes.iter().map(|m| m.name.as_deref().unwrap()).collect();
    assert_eq!(names, ["open box", "bent", "clean"]);
    let plans = plans(&meshes);
    assert!(plans[0].is_some() && plans[1].is_some() && plans[2].is_none());
    assert_eq!(
        plans[0].as_ref().unwrap().summary(),
        "fill-holes:1(2 faces)"
    );
    assert_eq!(plans[1].as_ref().unwrap().summary(), "orient-faces:1");

    let out = dir.path().join("out/plate.3mf");
    write_repaired(&source, Format::ThreeMf, &plans, &out, &cx(dir.path())).unwrap();
    let copy = std::fs::read(&out).unwrap();
    let (before, after) = (entries(&bytes), entries(&copy));
    assert_eq!(
        before.iter().map(|e| &e.0).collect::<Vec<_>>(),
        after.iter().map(|e| &e.0).collect::<Vec<_>>()
    );
    for ((name, a), (_, b)) in before.iter().zip(&after) {
        if name != "3D/3dmodel.model" {
            assert_eq!(a, b, "{name} changed");
        }
    }
    // Outside the two repaired meshes' <vertices> .. </triangles> the model text is the same:
    // old = A X1 B X2 C, new = A Y1 B Y2 C.
    let new = String::from_utf8(after[2].1.clone()).unwrap();
    let mesh_range = |s: &str, name: &str| -> (usize, usize) {
        let at = s.find(&format!("name=\"{name}\"")).unwrap();
        let start = s[at..].find("<vertices>").unwrap() + at;
        let end = s[start..].find("</triangles>").unwrap() + start + "</triangles>".len();
        (start, end)
    };
    let ((o1, o2), (o3, o4)) = (mesh_range(&text, "open box"), mesh_range(&text, "bent"));
    let ((n1, n2), (n3, n4)) = (mesh_range(&new, "open box"), mesh_range(&new, "bent"));
    assert_eq!(
        &text[..o1],
        &new[..n1],
        "the text before the first repaired mesh changed"
    );
    assert_eq!(
        &text[o2..o3],
        &new[n2..n3],
        "the text between the repaired meshes changed"
    );
    assert_eq!(
        &text[o4..],
        &new[n4..],
        "the text after the repaired meshes changed"
    );
    assert_ne!(&text[o1..o2], &new[n1..n2]);

    // The copy, read back: closed, oriented, properties with their corners.
    let again = read(&out, Format::ThreeMf, &cx(out.parent().unwrap())).unwrap();
    assert_eq!(again.len(), 3);
    let a = analyse(&again[0], &Options::default());
    assert_eq!((a.faces, a.border_edges), (12, 0));
    assert!((a.volume().unwrap() - 1.0).abs() < 1e-12);
    let b = analyse(&again[1], &Options::default());
    assert_eq!((b.faces, b.inconsistent_edges), (4, 0));
    assert_eq!(again[2], meshes[2]);
    // Per triangle of the copy, the property of each corner: the open box's corners carry their
    // vertex number as colour (p_k = v_k); kept triangles still do, fills take the neighbour's p1
    // alone.
    let triangles = triangle_attributes(&new, "open box");
    assert_eq!(triangles.len(), 12);
    let mut fills = 0;
    for t in &triangles {
        assert_eq!(t.get("pid").map(String::as_str), Some("8"), "{t:?}");
        if t.contains_key("p2") {
            for k in 1..=3 {
                assert_eq!(t[&format!("p{k}")], t[&format!("v{k}")], "{t:?}");
            }
        } else {
            fills += 1;
            assert!(t.contains_key("p1"), "{t:?}");
        }
    }
    assert_eq!(fills, 2);
    // The bent tetrahedron's flipped triangle: source (0, 3, 1) with p 0 1 2, so vertex 0 had
    // colour 0, vertex 3 colour 1, vertex 1 colour 2; in the copy each vertex keeps its colour.
    let bent = triangle_attributes(&new, "bent");
    let flipped: Vec<_> = bent.iter().filter(|t| t.contains_key("pid")).collect();
    assert_eq!(flipped.len(), 1);
    let t = flipped[0];
    let colour_of = |v: &str| -> String {
        (1..=3)
            .find(|k| t[&format!("v{k}")] == v)
            .map(|k| t[&format!("p{k}")].clone())
            .unwrap()
    };
    assert_eq!(
        (colour_of("0"), colour_of("3"), colour_of("1")),
        ("0".into(), "1".into(), "2".into())
    );
    assert_ne!(
        (t["v1"].as_str(), t["v2"].as_str(), t["v3"].as_str()),
        ("0", "3", "1")
    );

    // A second repair changes nothing.
    assert!(
        plans_of(&again).iter().all(Option::is_none),
        "{:?}",
        plans_of(&again)
    );
}

fn plans_of(meshes: &[Mesh]) -> Vec<Option<String>> {
    plans(meshes)
        .into_iter()
        .map(|p| p.map(|p| p.summary()))
        .collect()
}

/// The attributes of every `<triangle>` of the object named `name` in a model text.
fn triangle_attributes(text: &str, name: &str) -> Vec<std::collections::BTreeMap<String, String>> {
    let doc = roxmltree::Document::parse(text).unwrap();
    let object = doc
        .descendants()
        .find(|n| n.has_tag_name("object") && n.attribute("name") == Some(name))
        .unwrap();
    object
        .descendants()
        .filter(|n| n.has_tag_name("triangle"))
        .map(|n| {
            n.attributes()
                .map(|a| (a.name().to_owned(), a.value().to_owned()))
                .collect()
        })
        .collect()
}

const SLIC3RPE: &str = "http://schemas.slic3r.org/3mf/2017/06";

/// A painted tetrahedron whose last triangle (0, 2, 3) is wound against the others, the way
/// PrusaSlicer and BambuStudio write paint: `slic3rpe:` attributes (not plain: read by the XML
/// reader) and unprefixed ones (plain: read by the fast path), a value in single quotes, an
/// attribute of a namespace declared on `<triangles>`, a value with a reference; and an open box
/// with `paint_color` on every triangle. Returns the model text.
fn painted_model() -> String {
    let tetra = r#"  <object id="1" name="painted" type="model">
   <mesh>
    <vertices>
     <vertex x="0" y="0" z="0"/>
     <vertex x="1" y="0" z="0"/>
     <vertex x="0" y="1" z="0"/>
     <vertex x="0" y="0" z="1"/>
    </vertices>
    <triangles xmlns:x="urn:example:x">
     <triangle v1="0" v2="2" v3="1" slic3rpe:mmu_segmentation="4"/>
     <triangle v1="0" v2="1" v3="3" paint_color='8'/>
     <triangle v1="1" v2="2" v3="3" slic3rpe:custom_supports="C" face_property="7"/>
     <triangle v1="0" v2="2" v3="3" slic3rpe:mmu_segmentation="481" paint_seam="4806" x:note="keep &amp; me" slic3rpe:custom_seam="C"/>
    </triangles>
   </mesh>
  </object>
"#;
    let (p, t) = cube(true);
    let mut open = mesh_object(2, "open box", &p, &t);
    open = open.replace(
        "\"/>\n     <triangle",
        "\" paint_color=\"4\"/>\n     <triangle",
    );
    open = open.replace(
        "\"/>\n    </triangles>",
        "\" paint_color=\"4\"/>\n    </triangles>",
    );
    model_with(
        &format!(" xmlns:slic3rpe=\"{SLIC3RPE}\""),
        &format!("{tetra}{open}"),
        "  <item objectid=\"1\"/>\n  <item objectid=\"2\" transform=\"1 0 0 0 1 0 0 0 1 3 0 0\"/>",
    )
}

/// The `<triangle .../>` tags of the object named `name` in a model text, as written.
fn triangle_tags(text: &str, name: &str) -> Vec<String> {
    let at = text.find(&format!("name=\"{name}\"")).unwrap();
    let end = at + text[at..].find("</triangles>").unwrap();
    text[at..end]
        .split("<triangle ")
        .skip(1)
        .map(|t| format!("<triangle {}", &t[..t.find("/>").unwrap() + 2]))
        .collect()
}

/// A repaired copy keeps every attribute of every kept triangle as the source writes it, prefix
/// and all (the `<triangles>` start tag keeps the namespace it declares). The flipped triangle's
/// paint is re-encoded for its new corners (hand-derived in `paint.rs`'s tests:
/// `481` -> `841`, `4806` -> `84905`); its `slic3rpe:custom_seam="C"` is no paint PrusaSlicer
/// could read (a state code `C` with no code after it), so it cannot be re-encoded: it is left
/// out, and a note says so. The unflipped triangle's `C` is carried as it is. The box's fill
/// triangles carry no paint.
#[test]
fn a_repaired_copy_keeps_slicer_paint_and_other_triangle_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let text = painted_model();
    let source = dir.path().join("painted.3mf");
    std::fs::write(&source, package(&text)).unwrap();
    let meshes = read(&source, Format::ThreeMf, &cx(dir.path())).unwrap();
    let plans = plans(&meshes);
    assert_eq!(
        plans_of(&meshes),
        [
            Some("orient-faces:1".to_owned()),
            Some("fill-holes:1(2 faces)".to_owned())
        ]
    );
    let out = dir.path().join("out/painted.3mf");
    let written = copy_with_notes(&source, &plans, &out, dir.path());
    assert_eq!(
        written.notes.len(),
        1,
        "one note, for the paint left out: {:?}",
        written.notes
    );
    assert!(
        written.notes[0].starts_with(
            "object 1 of /3D/3dmodel.model: 1 flipped triangle(s) lost their slicer paint (`slic3rpe:custom_seam`)"
        ),
        "{}",
        written.notes[0]
    );
    let copy = entries(&std::fs::read(&out).unwrap());
    let new = String::from_utf8(copy[2].1.clone()).unwrap();
    assert!(
        new.contains("<triangles xmlns:x=\"urn:example:x\">"),
        "{new}"
    );
    assert_eq!(
        triangle_tags(&new, "painted"),
        [
            r#"<triangle v1="0" v2="2" v3="1" slic3rpe:mmu_segmentation="4"/>"#,
            r#"<triangle v1="0" v2="1" v3="3" paint_color="8"/>"#,
            r#"<triangle v1="1" v2="2" v3="3" slic3rpe:custom_supports="C" face_property="7"/>"#,
            r#"<triangle v1="0" v2="3" v3="2" slic3rpe:mmu_segmentation="841" paint_seam="84905" x:note="keep &amp; me"/>"#,
        ]
    );
    let open = triangle_tags(&new, "open box");
    assert_eq!(open.len(), 12);
    assert!(
        open[..10]
            .iter()
            .all(|t| t.ends_with(" paint_color=\"4\"/>")),
        "{open:?}"
    );
    assert!(open[10..].iter().all(|t| !t.contains("paint")), "{open:?}");
    // The copy is namespace-well-formed: every prefix resolves, to the namespace it had.
    let doc = roxmltree::Document::parse(&new).unwrap();
    let last = doc
        .descendants()
        .filter(|n| n.has_tag_name("triangle"))
        .nth(3)
        .unwrap();
    assert_eq!(last.attribute(("urn:example:x", "note")), Some("keep & me"));
    assert_eq!(last.attribute((SLIC3RPE, "mmu_segmentation")), Some("841"));
    // Read back, the copy is repaired.
    let again = read(&out, Format::ThreeMf, &cx(out.parent().unwrap())).unwrap();
    assert!(plans_of(&again).iter().all(Option::is_none));
}

/// PrusaSlicer's `Metadata/Slic3r_PE_model.config` numbers each object's triangles for its
/// volumes (`firstid`/`lastid`); the copy keeps the file as it is, so an object whose repair drops
/// or adds triangles gets a note (the open box: 10 triangles, 2 added; a tetrahedron with a
/// repeated triangle: 5, 1 dropped), and one whose triangles all stay in place (the painted
/// tetrahedron, one flipped) none.
#[test]
fn stale_slicer_volume_ranges_are_noted() {
    let dir = tempfile::tempdir().unwrap();
    let (tp, mut tt) = tetrahedron();
    tt.push(tt[0]);
    let twice = mesh_object(3, "twice", &tp, &tt);
    let text = painted_model()
        .replace("\n </resources>", &format!("\n{twice} </resources>"))
        .replace(
            "  <item objectid=\"2\"",
            "  <item objectid=\"3\" transform=\"1 0 0 0 1 0 0 0 1 6 0 0\"/>\n  <item objectid=\"2\"",
        );
    let config = b"<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<config>\n <object id=\"1\" instances_count=\"1\">\n  <volume firstid=\"0\" lastid=\"3\"/>\n </object>\n <object id=\"2\" instances_count=\"1\">\n  <volume firstid=\"0\" lastid=\"4\"/>\n  <volume firstid=\"5\" lastid=\"9\"/>\n </object>\n <object id=\"3\" instances_count=\"1\">\n  <volume firstid=\"0\" lastid=\"4\"/>\n </object>\n</config>\n";
    let bytes = package_with(&text, &[("Metadata/Slic3r_PE_model.config", config)]);
    let source = dir.path().join("project.3mf");
    std::fs::write(&source, &bytes).unwrap();
    let meshes = read(&source, Format::ThreeMf, &cx(dir.path())).unwrap();
    assert_eq!(
        plans_of(&meshes),
        [
            Some("orient-faces:1".to_owned()),
            Some("fill-holes:1(2 faces)".to_owned()),
            Some("drop-duplicate-faces:1".to_owned())
        ]
    );
    let out = dir.path().join("out/project.3mf");
    let written = copy_with_notes(&source, &plans(&meshes), &out, dir.path());
    let ranges: Vec<&String> = written
        .notes
        .iter()
        .filter(|n| n.contains("Slic3r_PE_model.config"))
        .collect();
    assert_eq!(ranges.len(), 2, "{:?}", written.notes);
    assert!(
        ranges[0].starts_with("object 2 of /3D/3dmodel.model: Metadata/Slic3r_PE_model.config is kept as it was, but its volumes' triangle ranges (firstid/lastid) number the source's 10 triangles, and the repair dropped 0 and added 2"),
        "{}",
        ranges[0]
    );
    assert!(
        ranges[1].starts_with("object 3 of /3D/3dmodel.model: Metadata/Slic3r_PE_model.config is kept as it was, but its volumes' triangle ranges (firstid/lastid) number the source's 5 triangles, and the repair dropped 1 and added 0"),
        "{}",
        ranges[1]
    );
    let copy = entries(&std::fs::read(&out).unwrap());
    let kept = copy
        .iter()
        .find(|(name, _)| name == "Metadata/Slic3r_PE_model.config")
        .unwrap();
    assert_eq!(kept.1, config);
}

/// An attribute value holding a NUL character (not XML, but read) is left out of the copy with a
/// note, not written back where it would be read as part of the writer's own text.
#[test]
fn a_triangle_attribute_with_a_nul_is_left_out_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let text = painted_model().replace("face_property=\"7\"", "face_property=\"a\0Pb\"");
    let source = dir.path().join("nul.3mf");
    std::fs::write(&source, package(&text)).unwrap();
    let meshes = read(&source, Format::ThreeMf, &cx(dir.path())).unwrap();
    let out = dir.path().join("out/nul.3mf");
    let written = copy_with_notes(&source, &plans(&meshes), &out, dir.path());
    assert!(
        written.notes.iter().any(|n| n.starts_with(
            "object 1 of /3D/3dmodel.model: 1 attribute(s) of its triangles hold a NUL character"
        )),
        "{:?}",
        written.notes
    );
    let new = String::from_utf8(entries(&std::fs::read(&out).unwrap())[2].1.clone()).unwrap();
    assert_eq!(
        triangle_tags(&new, "painted")[2],
        r#"<triangle v1="1" v2="2" v3="3" slic3rpe:custom_supports="C"/>"#
    );
}

/// A mesh with a beam lattice is not rewritten (the lattice numbers its vertices): the writer says
/// so, and the source is untouched.
#[test]
fn a_mesh_with_a_beam_lattice_is_not_rewritten() {
    let dir = tempfile::tempdir().unwrap();
    let (p, t) = cube(true);
    let object = mesh_object(1, "lattice box", &p, &t).replace(
        "   </mesh>",
        "<b:beamlattice radius=\"1\" minlength=\"0.1\" cap=\"sphere\"><b:beams><b:beam v1=\"0\" v2=\"7\"/></b:beams></b:beamlattice></mesh>",
    );
    let text = model_with(
        " xmlns:b=\"http://schemas.microsoft.com/3dmanufacturing/beamlattice/2017/02\"",
        &object,
        "<item objectid=\"1\"/>",
    );
    let source = dir.path().join("lattice.3mf");
    std::fs::write(&source, package(&text)).unwrap();
    let meshes = read(&source, Format::ThreeMf, &cx(dir.path())).unwrap();
    let plans = plans(&meshes);
    assert!(plans[0].is_some());
    let e = write_repaired(
        &source,
        Format::ThreeMf,
        &plans,
        &dir.path().join("out.3mf"),
        &cx(dir.path()),
    )
    .unwrap_err();
    assert!(e.0.contains("a beam lattice"), "{e}");
    assert!(!dir.path().join("out.3mf").exists());
}

/// The scan with a repair folder: the plate's copy is written, read back and judged like any
/// other copy; its rows say so.
#[test]
fn a_repairing_scan_writes_and_judges_the_copy() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    std::fs::create_dir_all(&tree).unwrap();
    std::fs::write(tree.join("plate.3mf"), plate().0).unwrap();
    let settings = Settings {
        repair_dir: Some(dir.path().join("out")),
        ..Settings::default()
    };
    let rows = scan_rows(&tree, &settings);
    let got: Vec<(&str, &str, &str, &str)> = rows
        .iter()
        .map(|r| {
            (
                r.mesh.as_str(),
                r.status.as_str(),
                r.repairs.as_str(),
                r.status_after.as_str(),
            )
        })
        .collect();
    assert_eq!(
        got,
        [
            ("bent", "fail", "orient-faces:1", "pass"),
            ("clean", "pass", "", ""),
            ("open box", "warn", "fill-holes:1(2 faces)", "pass"),
        ]
    );
    assert!(dir.path().join("out/plate.3mf").is_file());
}

/// The cells of a row the tests look at.
#[derive(Debug)]
struct Row {
    format: String,
    mesh: String,
    status: String,
    findings: String,
    message: String,
    repairs: String,
    status_after: String,
}

fn scan_rows(tree: &Path, settings: &Settings) -> Vec<Row> {
    let sources = meshvet::walk::walk(&[tree.to_path_buf()], &meshvet::walk::Filter::everything());
    let mut rows = Vec::new();
    meshvet::scan::scan::<std::io::Error>(&sources, settings, &|_| {}, |o| {
        let r = o.row;
        rows.push(Row {
            format: r.format.clone(),
            mesh: r.mesh.clone(),
            status: r.status.map(|s| s.to_string()).unwrap_or_default(),
            findings: meshvet::report::findings_cell(&o.findings),
            message: r.message.clone(),
            repairs: r.repairs.clone(),
            status_after: r.status_after.clone(),
        });
        Ok(())
    })
    .unwrap();
    rows
}

// ---------------------------------------------------------------------------------------------
// The shared corpus against lib3mf 2.5

fn corpus() -> Option<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    dir.join("reference_3mf.csv").is_file().then_some(dir)
}

/// Files lib3mf reads that meshvet refuses on purpose, each with the rule it follows.
const REFUSED_ON_PURPOSE: &[(&str, &str)] = &[
    (
        "lib3mf_tests/Reader/CS-1111_3dmodel-e1r1_other-e1r1.3mf",
        "two root model relationships: which model is printed is unclear, so the package is refused",
    ),
    (
        "lib3mf_tests/Volumetric/RadialRadiator.3mf",
        "requires the implicit extension, which changes what the build means and meshvet does not read",
    ),
    (
        "lib3mf_tests/Volumetric/SphereInACage.3mf",
        "requires the implicit extension",
    ),
    (
        "lib3mf_tests/Volumetric/template.3mf",
        "requires the implicit extension",
    ),
];

/// Every corpus file gets a row; for every file lib3mf reads (but the ones above), meshvet gives
/// no error row and its rows' faces sum to the triangles the build reaches in lib3mf.
#[test]
fn the_corpus_agrees_with_lib3mf() {
    let Some(dir) = corpus() else {
        eprintln!("no ../shared/corpus: skipped");
        return;
    };
    let mut reader = csv::Reader::from_path(dir.join("reference_3mf.csv")).unwrap();
    let header = reader.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let mut files = Vec::new();
    for record in reader.records() {
        let r = record.unwrap();
        if &r[col("kind")] == "file" {
            let reached = r[col("reached_triangles")].parse::<usize>().ok();
            files.push((
                r[col("file")].to_owned(),
                &r[col("lib3mf_ok")] == "True",
                reached,
            ));
        }
    }
    assert_eq!(files.len(), 81);
    let settings = Settings {
        jobs: 2,
        ..Settings::default()
    };
    let mut problems = Vec::new();
    let mut refused_on_purpose = Vec::new();
    for (file, ok, reached) in &files {
        let path = dir.join(file);
        let source = meshvet::walk::walk(
            std::slice::from_ref(&path),
            &meshvet::walk::Filter::everything(),
        );
        let outcomes = meshvet::scan::scan_file(&source[0], &settings);
        if outcomes.is_empty() {
            problems.push(format!("{file}: no row"));
            continue;
        }
        let errors: Vec<&str> = outcomes
            .iter()
            .filter(|o| o.row.status == Some(meshvet::rules::Status::Error))
            .map(|o| o.row.message.as_str())
            .collect();
        let faces: usize = outcomes.iter().filter_map(|o| o.row.faces).sum();
        let purpose = REFUSED_ON_PURPOSE.iter().find(|(f, _)| f == file);
        if let Some((_, reason)) = purpose {
            assert!(*ok, "{file} is listed but lib3mf refuses it too");
            if errors.is_empty() {
                problems.push(format!("{file}: listed as refused ({reason}) but read"));
            }
            refused_on_purpose.push(file.clone());
            continue;
        }
        if !ok {
            continue; // lib3mf refuses it; meshvet gave a row, whichever it is
        }
        if !errors.is_empty() {
            problems.push(format!("{file}: error {errors:?}"));
        } else if Some(faces) != *reached {
            problems.push(format!("{file}: {faces} faces, lib3mf reaches {reached:?}"));
        }
    }
    assert!(problems.is_empty(), "{problems:#?}");
    assert_eq!(refused_on_purpose.len(), REFUSED_ON_PURPOSE.len());
}

// ---------------------------------------------------------------------------------------------
// The sample assets

fn sample(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("sample_assets/print")
        .join(name)
}

/// Name, vertices, faces, volume, holes, notes and mirrored placements of a mesh.
type Facts = (String, usize, usize, Option<f64>, usize, Vec<String>, u32);

/// `plate.3mf`: a 20 mm cube (V 8, F 12, volume 20^3 = 8000) placed twice, a wedge (half a 20 mm
/// cube cut along a diagonal: V 6, F 8, volume 20 * 20 / 2 * 20 = 4000) and a 20 mm box without its
/// two top triangles (F 10, one hole of 4 edges). `bracket_pair.3mf`: an L bracket (an L of
/// 30 x 5 plus 5 x 15 mm, 10 mm tall: V 12, F 4 + 4 + 12 = 20, volume (150 + 75) * 10 = 2250)
/// placed twice by one assembly, the second copy mirrored in x.
#[test]
fn the_sample_fixtures_read_as_built() {
    let root = sample("");
    let facts = |name: &str| -> Vec<Facts> {
        read(&sample(name), Format::ThreeMf, &cx(&root))
            .unwrap()
            .iter()
            .map(|m| {
                let a = analyse(m, &Options::default());
                let holes = a.components.iter().map(|c| c.holes).sum();
                (
                    m.name.clone().unwrap(),
                    a.vertices,
                    a.faces,
                    a.volume(),
                    holes,
                    m.notes.clone(),
                    m.mirrored_instances,
                )
            })
            .collect()
    };
    let notes = |n: &str| vec!["unit millimeter".to_owned(), n.to_owned()];
    assert_eq!(
        facts("plate.3mf"),
        [
            (
                "cube".into(),
                8,
                12,
                Some(8000.0),
                0,
                notes("2 placements"),
                0
            ),
            (
                "wedge".into(),
                6,
                8,
                Some(4000.0),
                0,
                notes("1 placement"),
                0
            ),
            ("open_box".into(), 8, 10, None, 1, notes("1 placement"), 0),
        ]
    );
    assert_eq!(
        facts("bracket_pair.3mf"),
        [(
            "bracket".into(),
            12,
            20,
            Some(2250.0),
            0,
            notes("2 placements"),
            1
        )]
    );
}

/// The plate's repaired copy keeps its thumbnail and slicer config byte for byte, closes the box
/// (F 12, volume 8000) and leaves the other objects' text alone.
#[test]
fn the_sample_plate_is_repaired_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let source = sample("plate.3mf");
    let meshes = read(&source, Format::ThreeMf, &cx(&sample(""))).unwrap();
    let plans = plans(&meshes);
    assert_eq!(
        plans
            .iter()
            .map(|p| p.as_ref().map(Plan::summary))
            .collect::<Vec<_>>(),
        [None, None, Some("fill-holes:1(2 faces)".to_owned())]
    );
    let out = dir.path().join("plate.3mf");
    write_repaired(&source, Format::ThreeMf, &plans, &out, &cx(&sample(""))).unwrap();
    let (before, after) = (
        entries(&std::fs::read(&source).unwrap()),
        entries(&std::fs::read(&out).unwrap()),
    );
    assert_eq!(before.len(), after.len());
    for ((name, a), (other, b)) in before.iter().zip(&after) {
        assert_eq!(name, other);
        if name != "3D/3dmodel.model" {
            assert_eq!(a, b, "{name} changed");
        }
    }
    let again = read(&out, Format::ThreeMf, &cx(dir.path())).unwrap();
    assert_eq!(&again[..2], &meshes[..2]);
    let a = analyse(&again[2], &Options::default());
    assert_eq!((a.faces, a.border_edges, a.volume()), (12, 0, Some(8000.0)));
    assert!(self::plans(&again).iter().all(Option::is_none));
}

// ---------------------------------------------------------------------------------------------
// Hostile XML: the work and memory of a read stay in proportion to what a mesh needs

/// One tag of 100,000 attributes (300 kB), then the same tag with its first attribute again at
/// the end. The duplicate check compared each attribute with every earlier one: 5e9 compares,
/// many seconds; now it reads at once, and still finds the late duplicate.
#[test]
fn a_tag_with_a_hundred_thousand_attributes_reads_at_once() {
    let (p, t) = tetrahedron();
    let many: String = (0..100_000).map(|i| format!(" a{i}=\"1\"")).collect();
    let object = mesh_object(1, "tet", &p, &t);
    let text = |extra: &str| {
        model(
            &object.replacen("type=\"model\"", &format!("type=\"model\"{many}{extra}"), 1),
            "<item objectid=\"1\"/>",
        )
    };
    let meshes = read_ok(&package(&text("")));
    assert_eq!(meshes[0].triangles.len(), 4);
    let e = refused(&package(&text(" a0=\"2\"")), "has the attribute `a0` twice");
    assert!(e.contains("<object>"), "{e}");
}

/// 100,000 namespace declarations in scope (20,000 on each of the five elements around the
/// vertices), and 20,000 vertices the XML reader reads (`x ="..."` keeps them off the plain run),
/// each declaring a prefix of its own and using it. Resolving a prefix searched every declaration
/// in scope, and the end of each vertex filtered them all: 2e9 steps each, tens of seconds.
#[test]
fn a_hundred_thousand_namespace_declarations_in_scope_read_at_once() {
    let n = 20_000;
    let declare = |j: usize| -> String {
        (0..n)
            .map(|i| format!(" xmlns:p{j}_{i}=\"urn:{i}\""))
            .collect()
    };
    let vertices: String = (0..n)
        .map(|i| {
            format!(
                "<vertex xmlns:q=\"urn:q\" q:k=\"{i}\" x =\"{i}\" y=\"{}\" z=\"0\"/>",
                i % 2
            )
        })
        .collect();
    let triangles: String = (0..n - 2)
        .map(|i| format!("<triangle v1=\"{i}\" v2=\"{}\" v3=\"{}\"/>", i + 1, i + 2))
        .collect();
    let text = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?><model unit=\"millimeter\" xmlns=\"{CORE}\"{}><resources{}><object id=\"1\"{}><mesh{}><vertices{}>{vertices}</vertices><triangles>{triangles}</triangles></mesh></object></resources><build><item objectid=\"1\"/></build></model>",
        declare(0),
        declare(1),
        declare(2),
        declare(3),
        declare(4)
    );
    let meshes = read_ok(&package(&text));
    assert_eq!(meshes[0].positions.len(), n);
    assert_eq!(meshes[0].triangles.len(), n - 2);
    assert_eq!(meshes[0].positions[n - 1], [(n - 1) as f64, 1.0, 0.0]);
    // The declarations still end with their elements: the last prefix of <vertices> is out of
    // scope in <triangles>.
    let last = format!("p4_{}", n - 1);
    let e = refused(
        &package(&text.replacen("<triangles>", &format!("<triangles {last}:a=\"1\">"), 1)),
        "without declaring it",
    );
    assert!(e.contains(&last), "{e}");
}

/// `n` bytes of text that deflate no better than about 100 to 1 (spaces and a pseudo-random
/// letter every 101 bytes), like the filler of real parts, so that the package passes the
/// compression-ratio check and the XML reader meets it.
fn filler(n: usize) -> String {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut out = String::with_capacity(n);
    while out.len() < n {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        out.push_str(&" ".repeat(100));
        out.push(char::from(b'a' + (state % 26) as u8));
    }
    out
}

/// A comment, a text and a tag of 40 MB each: one piece of XML is held in memory whole, so each
/// took 40 MB or more (a 2 GB comment took 2.1 GB, a larger one aborted the scan). Each is
/// refused at 16 MiB, with what it is and where it begins.
#[test]
fn a_piece_of_xml_over_sixteen_mebibytes_is_refused_unbuffered() {
    let (p, t) = tetrahedron();
    let good = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>");
    let big = filler(40 << 20);
    for (piece, what) in [
        (format!("<!--{big}-->"), "a comment"),
        (format!("<metadata name=\"x\">{big}</metadata>"), "text"),
        (format!("<metadata name=\"x{big}\"/>"), "a tag"),
    ] {
        let text = good.replacen("<resources>", &format!("{piece}<resources>"), 1);
        let e = refused(&package(&text), "more than 16 MiB");
        assert!(e.contains(what), "{what}: {e}");
    }
    // Up to the bound, a long text is read past.
    let text = good.replacen(
        "<resources>",
        &format!(
            "<metadata name=\"x\">{}</metadata><resources>",
            filler(15 << 20)
        ),
        1,
    );
    assert_eq!(read_ok(&package(&text))[0].triangles.len(), 4);
}

/// Elements a `<mesh>` holds that are not checked give one note per kind, with their count:
/// 100,000 of two kinds gave 100,000 notes (240,000 made a 7.7 MB report row); past eight kinds,
/// the rest are counted together.
#[test]
fn unchecked_elements_give_one_note_per_kind() {
    let (p, t) = tetrahedron();
    let object = |inside: &str| {
        model(
            &mesh_object(1, "tet", &p, &t).replace("   </mesh>", &format!("{inside}</mesh>")),
            "<item objectid=\"1\"/>",
        )
    };
    let meshes = read_ok(&package(&object(&"<a/><b><c/></b>".repeat(50_000))));
    assert_eq!(
        meshes[0].notes,
        [
            "unit millimeter",
            "1 placement",
            "<a> in the mesh is not checked (50000 elements)",
            "<b> in the mesh is not checked (50000 elements)"
        ]
    );
    let kinds: String = (0..20).map(|k| format!("<e{k}/><e{k}/>")).collect();
    let meshes = read_ok(&package(&object(&kinds)));
    let notes = &meshes[0].notes;
    assert_eq!(notes.len(), 2 + 8 + 1, "{notes:?}");
    assert_eq!(notes[2], "<e0> in the mesh is not checked (2 elements)");
    assert_eq!(
        notes[10],
        "24 more element(s) of other kinds in the mesh are not checked"
    );
}

/// A model part is UTF-8: a name in Latin-1 (`caf\xe9`) was read as `caf\u{fffd}`. Refused,
/// wherever the bad byte is; UTF-8 characters cut by every boundary of the reader's buffer still
/// read.
#[test]
fn a_part_that_is_not_utf8_is_refused() {
    let (p, t) = tetrahedron();
    let good = model(&mesh_object(1, "tet", &p, &t), "<item objectid=\"1\"/>");
    let bytes = |text: &[u8]| {
        zip(&[
            ("[Content_Types].xml", CONTENT_TYPES.as_bytes()),
            ("_rels/.rels", ROOT_RELS.as_bytes()),
            ("3D/3dmodel.model", text),
        ])
    };
    for (from, to) in [
        (&b"name=\"tet\""[..], &b"name=\"caf\xe9\""[..]),
        (b"<build>", b"<!-- \xff --><build>"),
        (b"</model>", b"</model>\xe2\x82"),
    ] {
        let text = good.as_bytes();
        let at = text.windows(from.len()).position(|w| w == from).unwrap();
        let bad = [&text[..at], to, &text[at + from.len()..]].concat();
        let e = read_with(&bytes(&bad), limits()).unwrap_err();
        assert!(e.contains("is not UTF-8"), "{e}");
        assert!(e.contains("/3D/3dmodel.model"), "{e}");
    }
    // 200,000 characters of two, three and four bytes in a name and a comment.
    let wide = "é€😀".repeat(200_000 / 3);
    let text = good
        .replacen("name=\"tet\"", &format!("name=\"{wide}\""), 1)
        .replacen("<build>", &format!("<!--{wide}--><build>"), 1);
    let meshes = read_ok(&bytes(text.as_bytes()));
    assert_eq!(meshes[0].name.as_deref(), Some(wide.as_str()));
}

/// A model part may open with a UTF-8 byte order mark (XML allows it, and exporters on Windows
/// write one). The repair splices its new `<vertices>`/`<triangles>` in at the byte positions
/// read, so the mark counts: the copy is well formed, closed and turned, and the mark stays.
#[test]
fn a_model_part_with_a_byte_order_mark_is_repaired() {
    let dir = tempfile::tempdir().unwrap();
    let (_, text) = plate();
    let marked = format!("\u{feff}{text}");
    let source = dir.path().join("marked.3mf");
    std::fs::write(&source, package(&marked)).unwrap();
    let meshes = read(&source, Format::ThreeMf, &cx(dir.path())).unwrap();
    let plans = plans(&meshes);
    assert!(plans[0].is_some() && plans[1].is_some() && plans[2].is_none());

    let out = dir.path().join("out/marked.3mf");
    write_repaired(&source, Format::ThreeMf, &plans, &out, &cx(dir.path())).unwrap();
    let copy = entries(&std::fs::read(&out).unwrap());
    let model = &copy.iter().find(|e| e.0 == "3D/3dmodel.model").unwrap().1;
    assert!(model.starts_with("\u{feff}<?xml".as_bytes()));
    let again = read(&out, Format::ThreeMf, &cx(out.parent().unwrap())).unwrap();
    assert_eq!(again.len(), 3);
    let a = analyse(&again[0], &Options::default());
    assert_eq!((a.faces, a.border_edges), (12, 0));
    let b = analyse(&again[1], &Options::default());
    assert_eq!((b.faces, b.inconsistent_edges), (4, 0));
    assert_eq!(again[2], meshes[2]);
}

/// A package replaced after the scan read it (the open box's first vertex moved from the origin
/// to (0.5, 0, 0)) is not copied: the plans were made for what the scan read, and the copy is
/// refused saying so.
#[test]
fn a_package_changed_after_the_scan_read_it_is_not_copied() {
    let dir = tempfile::tempdir().unwrap();
    let (bytes, text) = plate();
    let source = dir.path().join("plate.3mf");
    std::fs::write(&source, &bytes).unwrap();
    let meshes = read(&source, Format::ThreeMf, &cx(dir.path())).unwrap();
    assert_eq!(meshes[0].positions[0], [0.0; 3]);
    let plans = plans(&meshes);
    let origin = "<vertex x=\"0\" y=\"0\" z=\"0\"/>";
    assert!(text.contains(origin));
    let moved = text.replacen(origin, "<vertex x=\"0.5\" y=\"0\" z=\"0\"/>", 1);
    std::fs::write(&source, package(&moved)).unwrap();
    let out = dir.path().join("out/plate.3mf");
    let scanned = meshvet::formats::write::ScanRead {
        meshes: &meshes,
        retained: None,
    };
    let refused = meshvet::formats::write::write_copy(
        &source,
        Format::ThreeMf,
        &plans,
        &out,
        &cx(dir.path()),
        Some(scanned),
    );
    assert_eq!(
        refused.map_err(|e| e.to_string()),
        Err("the file changed after the scan read it: scan it again to repair it".into())
    );
    assert!(!out.exists());
}
