//! Sharding for libraries bigger than one machine: `--shard K/N` scans the files whose report path
//! hashes to shard K of N, and [`merge`] joins the shards' CSVs into the one an unsharded scan writes
//! (except `millis`).
//!
//! The hash is blake3 of the report path's bytes (never Rust's randomised hasher), so every machine
//! and every run puts a file in the same shard; a file stays in its shard when other files come
//! and go. K counts from 1 to N (like `cargo nextest --partition hash:K/N`).

use std::cmp::Reverse;
use std::collections::BinaryHeap;
use std::fmt;
use std::io;
use std::path::PathBuf;
use std::str::FromStr;

use crate::report::{Output, Row, Target, COLUMNS};

/// Shard `index` (1-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Shard {
    /// Whether the file with this report path belongs to the shard.
    pub fn contains(&self, path: &str) -> bool {
        *self == Shard::of(path, self.count)
    }

    /// The shard of `count` (at least 1) the file with this report path belongs to.
    pub fn of(path: &str, count: u64) -> Shard {
        let hash = blake3::hash(path.as_bytes());
        let first = u64::from_le_bytes(hash.as_bytes()[..8].try_into().expect("8 bytes"));
        Shard {
            index: first % count + 1,
            count,
        }
    }
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(text: &str) -> Result<Shard, String> {
        let bad = || format!("`{text}` is not K/N with 1 <= K <= N (e.g. 2/8)");
        let (k, n) = text.split_once('/').ok_or_else(bad)?;
        let index: u64 = k.trim().parse().map_err(|_| bad())?;
        let count: u64 = n.trim().parse().map_err(|_| bad())?;
        if index == 0 || index > count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Why shard reports could not be merged.
#[derive(Debug)]
pub enum MergeError {
    /// An input is unreadable or not a report; the message says which and why.
    Input(String),
    /// The output could not be written.
    Output(io::Error),
}

impl fmt::Display for MergeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MergeError::Input(message) => f.write_str(message),
            MergeError::Output(e) => write!(f, "cannot write the merged report: {e}"),
        }
    }
}

/// One input being read, with its next record.
struct Input {
    name: PathBuf,
    records: csv::StringRecordsIntoIter<std::fs::File>,
    /// Row number of `next` (2: the first row after the header), for messages.
    line: u64,
    /// The shard (of as many as there are inputs) its rows so far belong to, and one such path.
    shard: Option<(u64, String)>,
}

impl Input {
    /// The next record, refused unless it reads as a row of this meshvet's CSV.
    fn next(&mut self) -> Result<Option<(Key, csv::StringRecord)>, MergeError> {
        self.line += 1;
        let Some(record) =
            self.records.next().transpose().map_err(|e| {
                MergeError::Input(format!("cannot read {}: {e}", self.name.display()))
            })?
        else {
            return Ok(None);
        };
        let row = Row::from_cells(record.iter()).map_err(|e| {
            MergeError::Input(format!(
                "{} is not a meshvet CSV at row {}: {e} - merge only reports meshvet wrote",
                self.name.display(),
                self.line
            ))
        })?;
        Ok(Some(((row.path, row.mesh), record)))
    }
}

/// What merge takes, said when the inputs are not that.
const EVERY: &str = "merge takes the reports of all N shards of one --shard K/N scan, each once, \
                     and counts the reports given as N: is a shard's report missing, given twice, \
                     or scanned with another N?";

/// A row's (path, mesh): the order of every report.
type Key = (String, String);

/// Joins the CSVs of the `--shard K/N` scans of one tree, all N of them, into one sorted by path
/// then mesh, written to `target` (a file atomically). Every input must be this meshvet's CSV,
/// sorted (as meshvet writes it, no row twice) and share no path with another input; with N
/// inputs, every row of an input must belong to one shard K of N (a different K per input), so a
/// missing shard, or one scanned with another N, is an error rather than a report short of
/// rows. (A report left over from an earlier run of the same shard cannot be told apart.)
/// Streams: memory does not grow with the rows. Returns the number of rows written.
pub fn merge(inputs: &[PathBuf], target: &Target) -> Result<usize, MergeError> {
    if inputs.is_empty() {
        return Err(MergeError::Input("no reports to merge".to_owned()));
    }
    let count = inputs.len() as u64;
    let mut readers = Vec::with_capacity(inputs.len());
    for name in inputs {
        let cannot = |e: &dyn fmt::Display| {
            MergeError::Input(format!("cannot read {}: {e}", name.display()))
        };
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .from_path(name)
            .map_err(|e| cannot(&e))?;
        let header = reader.headers().map_err(|e| cannot(&e))?;
        if header.iter().ne(COLUMNS.iter().copied()) {
            return Err(MergeError::Input(format!(
                "{} has other columns than this meshvet's CSV (written by another version, or                  not a meshvet report): merge reports written by the meshvet that merges them",
                name.display()
            )));
        }
        readers.push(Input {
            name: name.clone(),
            records: reader.into_records(),
            line: 1,
            shard: None,
        });
    }
    // Every row of an input belongs to its one shard of `count`.
    let check = |input: &mut Input, path: &str| -> Result<(), MergeError> {
        let k = Shard::of(path, count).index;
        match &input.shard {
            None => input.shard = Some((k, path.to_owned())),
            Some((first, first_path)) if *first != k => {
                return Err(MergeError::Input(format!(
                    "{} holds {first_path} (shard {first}/{count}) and {path} (shard {k}/{count}): \
                     {EVERY}",
                    input.name.display()
                )))
            }
            Some(_) => {}
        }
        Ok(())
    };

    // The smallest (path, mesh) of every input first; ties broken by input order.
    let mut heap = BinaryHeap::new();
    let mut pending: Vec<Option<csv::StringRecord>> = Vec::with_capacity(readers.len());
    for (i, input) in readers.iter_mut().enumerate() {
        let record = match input.next()? {
            Some((key, record)) => {
                check(input, &key.0)?;
                heap.push(Reverse((key, i)));
                Some(record)
            }
            None => None,
        };
        pending.push(record);
    }
    let mut shards: Vec<(u64, usize)> = readers
        .iter()
        .enumerate()
        .filter_map(|(i, input)| Some((input.shard.as_ref()?.0, i)))
        .collect();
    shards.sort_unstable();
    if let Some(w) = shards.windows(2).find(|w| w[0].0 == w[1].0) {
        return Err(MergeError::Input(format!(
            "{} and {} both hold shard {}/{count}: {EVERY}",
            readers[w[0].1].name.display(),
            readers[w[1].1].name.display(),
            w[0].0
        )));
    }

    let mut writer = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(Output::create(target).map_err(MergeError::Output)?);
    let output = |e: csv::Error| MergeError::Output(io::Error::other(e));
    writer.write_record(COLUMNS).map_err(output)?;
    let mut last: Option<(String, usize)> = None;
    let mut rows = 0;
    while let Some(Reverse((k, i))) = heap.pop() {
        let record = pending[i].take().expect("a queued input has a record");
        if let Some((last_path, last_input)) = &last {
            if *last_path == k.0 && *last_input != i {
                return Err(MergeError::Input(format!(
                    "{} and {} both report {}: shards must not overlap (same --shard twice, or \
                     the same report given twice?)",
                    readers[*last_input].name.display(),
                    readers[i].name.display(),
                    k.0
                )));
            }
        }
        writer.write_record(&record).map_err(output)?;
        rows += 1;
        let input = &mut readers[i];
        let following = match input.next()? {
            Some((following_key, r)) => {
                if following_key <= k {
                    return Err(MergeError::Input(format!(
                        "{} is not sorted by path then mesh, or repeats a row, at row {}: merge \
                         only reports meshvet wrote",
                        input.name.display(),
                        input.line
                    )));
                }
                check(input, &following_key.0)?;
                heap.push(Reverse((following_key, i)));
                Some(r)
            }
            None => None,
        };
        pending[i] = following;
        last = Some((k.0, i));
    }
    let out = writer
        .into_inner()
        .map_err(|e| MergeError::Output(e.into_error()))?;
    out.finish().map_err(MergeError::Output)?;
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn shards_parse_and_partition_every_path_once() {
        assert_eq!("2/3".parse(), Ok(Shard { index: 2, count: 3 }));
        for bad in ["0/3", "4/3", "3", "a/b", "1/0"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        let shards: Vec<Shard> = (1..=3).map(|k| Shard { index: k, count: 3 }).collect();
        let mut sizes = [0; 3];
        for i in 0..3000 {
            let path = format!("models/part{i}.obj");
            let owners: Vec<usize> = (0..3).filter(|&s| shards[s].contains(&path)).collect();
            assert_eq!(owners.len(), 1, "{path}");
            sizes[owners[0]] += 1;
        }
        assert!(sizes.iter().all(|&n| n > 900), "roughly even: {sizes:?}");
        // Stable across runs and machines: a fixed path always lands in the same shard.
        assert!(Shard { index: 1, count: 1 }.contains("a.obj"));
    }

    fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        path
    }

    /// A CSV of rows with these (path, mesh) and `faces` counting from 1, in the order given.
    fn report(rows: &[(&str, &str)]) -> String {
        let mut text = COLUMNS.join(",") + "\n";
        for (i, (path, mesh)) in rows.iter().enumerate() {
            let row = Row {
                path: path.to_string(),
                mesh: mesh.to_string(),
                faces: Some(i + 1),
                ..Row::default()
            };
            text += &(row.cells().join(",") + "\n");
        }
        text
    }

    /// `n` file names of shard `k` of `count`, sorted.
    fn names_of(k: u64, count: u64, n: usize) -> Vec<String> {
        let mut names: Vec<String> = (0..)
            .map(|i| format!("f{i}.obj"))
            .filter(|p| Shard::of(p, count).index == k)
            .take(n)
            .collect();
        names.sort();
        names
    }

    /// Two shard reports merge into one sorted by path then mesh; a path in two reports, a report
    /// given twice, other columns, a bad cell, unsorted or repeated rows, and a report of a
    /// missing shard (rows of two shards of the count given) are refused, and a refused merge
    /// leaves the earlier output alone.
    #[test]
    fn merge_sorts_and_refuses_what_is_not_every_shard_of_one_scan() {
        let dir = tempfile::tempdir().unwrap();
        let one = names_of(1, 2, 2);
        let two = names_of(2, 2, 2);
        let a = write(
            dir.path(),
            "a.csv",
            &report(&[(&one[0], ""), (&one[1], "m1"), (&one[1], "m2")]),
        );
        let b = write(
            dir.path(),
            "b.csv",
            &report(&[(&two[0], ""), (&two[1], "")]),
        );
        let out = dir.path().join("all.csv");
        let n = merge(&[a.clone(), b.clone()], &Target::File(out.clone())).unwrap();
        assert_eq!(n, 5);
        let merged = std::fs::read_to_string(&out).unwrap();
        let keys: Vec<(String, String)> = merged
            .lines()
            .skip(1)
            .map(|l| {
                let cells: Vec<&str> = l.split(',').collect();
                (cells[0].to_owned(), cells[1].to_owned())
            })
            .collect();
        let mut want: Vec<(String, String)> = [
            (&one[0], ""),
            (&one[1], "m1"),
            (&one[1], "m2"),
            (&two[0], ""),
            (&two[1], ""),
        ]
        .iter()
        .map(|(p, m)| (p.to_string(), m.to_string()))
        .collect();
        want.sort();
        assert_eq!(keys, want);
        assert!(merged.starts_with(&(COLUMNS.join(",") + "\n")));

        let refused = |inputs: &[PathBuf], words: &str| {
            let err = merge(inputs, &Target::File(out.clone()))
                .unwrap_err()
                .to_string();
            assert!(err.contains(words), "{words}: {err}");
        };
        // The same path in two reports of two shards: the second's first row is of the first's
        // shard, so it is caught as a mix of shards or as an overlap.
        let overlap = write(dir.path(), "o.csv", &report(&[(&one[0], "")]));
        refused(&[a.clone(), overlap.clone()], "both hold shard 1/2");
        refused(&[a.clone(), a.clone()], "both hold shard 1/2");
        let mixed = write(
            dir.path(),
            "x.csv",
            &report(&[(&one[0], ""), (&two[0], "")]),
        );
        refused(&[mixed, b.clone()], "(shard 1/2) and");
        // Three shards scanned, one report lost: the two left are read as shards of 2.
        let three: Vec<Vec<String>> = (1..=3).map(|k| names_of(k, 3, 40)).collect();
        let of = |names: &[String]| -> String {
            report(&names.iter().map(|p| (p.as_str(), "")).collect::<Vec<_>>())
        };
        let s1 = write(dir.path(), "s1.csv", &of(&three[0]));
        let s2 = write(dir.path(), "s2.csv", &of(&three[1]));
        refused(&[s1, s2], "is a shard's report missing, given twice");
        let columns = report(&[(&one[0], "")]).replacen("path,", "where,", 1);
        let other = write(dir.path(), "h.csv", &columns);
        refused(&[other, b.clone()], "other columns");
        let cell = report(&[(&one[0], "")]).replacen(",1,", ",seven,", 1);
        let bad = write(dir.path(), "c.csv", &cell);
        refused(&[bad, b.clone()], "`seven` is not a valid `faces` cell");
        let unsorted = write(
            dir.path(),
            "u.csv",
            &report(&[(&one[1], ""), (&one[0], "")]),
        );
        refused(&[unsorted, b.clone()], "not sorted");
        let twice = write(
            dir.path(),
            "t.csv",
            &report(&[(&one[0], ""), (&one[0], "")]),
        );
        refused(&[twice, b.clone()], "repeats a row");
        // A failed merge leaves the earlier output alone and no temporary file.
        assert_eq!(std::fs::read_to_string(&out).unwrap(), merged);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 11);
    }
}
