//! Faces that meet, through `meshvet::topology::intersections`: the hand-derived constructions of
//! the issue, invariance under exact motions and renumbering, and agreement with CGAL's exact
//! `self_intersections` on the shared corpus.

use std::collections::HashMap;
use std::path::Path;

use meshvet::formats::{self, Format, Limits, ReadContext};
use meshvet::topology::{intersections, Intersections, Search};
use meshvet::{analyse, Mesh, Options, Role};

#[path = "shapes/mod.rs"]
#[allow(dead_code)]
mod shapes;

fn meet(mesh: &Mesh) -> Intersections {
    intersections(mesh, &Options::default(), &Search::default())
}

// ---------------------------------------------------------------------------------------------
// Agreement with CGAL

/// Files whose counts differ from CGAL's, each with the reason (none so far).
const DIFFERENT: &[(&str, &str)] = &[];

/// `reference_selfx.csv` gives, per file, CGAL 6.0's exact `self_intersections` after welding by
/// exact position and dropping pairs with a zero-area face: the pairs within one component and the
/// pairs of components that meet. meshvet must give the same two numbers for every file.
#[test]
fn agrees_with_cgal_on_the_corpus() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/corpus");
    let csv_path = root.join("reference_selfx.csv");
    if !csv_path.is_file() {
        eprintln!("skip: no reference corpus at {}", root.display());
        return;
    }
    let cx = ReadContext {
        root: root.clone(),
        limits: Limits::default(),
    };
    let different: HashMap<&str, &str> = DIFFERENT.iter().copied().collect();
    let mut reader = csv::Reader::from_path(&csv_path).unwrap();
    let mut failures = Vec::new();
    let mut compared = 0;
    for record in reader.records() {
        let record = record.unwrap();
        let file = &record[0];
        let want: (usize, usize) = (record[3].parse().unwrap(), record[4].parse().unwrap());
        let path = root.join(file);
        let format = Format::of_path(&path).unwrap();
        let meshes = match formats::read(&path, format, &cx) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{file}: unreadable: {e}"));
                continue;
            }
        };
        if meshes.len() != 1 {
            failures.push(format!("{file}: {} meshes", meshes.len()));
            continue;
        }
        let found = meet(&meshes[0]);
        let got = (found.self_intersections, found.intersecting_components());
        compared += 1;
        match (got == want, different.get(file)) {
            (true, None) => {}
            (true, Some(_)) => failures.push(format!("{file}: listed as different but agrees")),
            (false, Some(_)) => {}
            (false, None) => failures.push(format!(
                "{file}: meshvet {got:?} (and {} pairs between), CGAL {want:?} ({} pairs)",
                found.pairs_between, &record[5]
            )),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    assert_eq!(compared, 165);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
