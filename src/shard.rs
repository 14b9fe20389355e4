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
use std::path::{Path, PathBuf};
use std::str::FromStr;

use crate::report::{Output, Target};

/// Shard `index` (1-based) of `count`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

impl Shard {
    /// Whether the file with this report path belongs to the shard.
    pub fn contains(&self, path: &str) -> bool {
        let hash = blake3::hash(path.as_bytes());
        let first = u64::from_le_bytes(hash.as_bytes()[..8].try_into().expect("8 bytes"));
        first % self.count == self.index - 1
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
}

/// Joins shard CSVs into one sorted by path then mesh, written to `target` (a file atomically).
/// Every input must have the same header with `path` and `mesh` columns, be sorted (as meshvet
/// writes it) and share no path with another input. Streams: memory does not grow with the rows.
/// Returns the number of rows written.
pub fn merge(inputs: &[PathBuf], target: &Target) -> Result<usize, MergeError> {
    let open = |name: &Path| -> Result<(csv::StringRecord, Input), MergeError> {
        let cannot = |e: &dyn fmt::Display| {
            MergeError::Input(format!("cannot read {}: {e}", name.display()))
        };
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .from_path(name)
            .map_err(|e| cannot(&e))?;
        let header = reader.headers().map_err(|e| cannot(&e))?.clone();
        Ok((
            header,
            Input {
                name: name.to_owned(),
                records: reader.into_records(),
                line: 1,
            },
        ))
    };
    let mut header: Option<(csv::StringRecord, PathBuf)> = None;
    let mut readers = Vec::new();
    for name in inputs {
        let (h, input) = open(name)?;
        match &header {
            None => header = Some((h, name.clone())),
            Some((first, first_name)) if *first != h => {
                return Err(MergeError::Input(format!(
                    "{} and {} have different columns: merge only reports of one meshvet version \
                     and one column set",
                    first_name.display(),
                    name.display()
                )))
            }
            Some(_) => {}
        }
        readers.push(input);
    }
    let Some((header, first_name)) = header else {
        return Err(MergeError::Input("no reports to merge".to_owned()));
    };
    let column = |want: &str| {
        header.iter().position(|c| c == want).ok_or_else(|| {
            MergeError::Input(format!(
                "{} has no `{want}` column: not a meshvet report",
                first_name.display()
            ))
        })
    };
    let (path_at, mesh_at) = (column("path")?, column("mesh")?);
    let key = |r: &csv::StringRecord| {
        (
            r.get(path_at).unwrap_or_default().to_owned(),
            r.get(mesh_at).unwrap_or_default().to_owned(),
        )
    };

    let next =
        |input: &mut Input| -> Result<Option<csv::StringRecord>, MergeError> {
            input.line += 1;
            input.records.next().transpose().map_err(|e| {
                MergeError::Input(format!("cannot read {}: {e}", input.name.display()))
            })
        };
    // The smallest (path, mesh) of every input first; ties broken by input order.
    let mut heap = BinaryHeap::new();
    let mut pending: Vec<Option<csv::StringRecord>> = Vec::with_capacity(readers.len());
    for (i, input) in readers.iter_mut().enumerate() {
        let record = next(input)?;
        if let Some(r) = &record {
            heap.push(Reverse((key(r), i)));
        }
        pending.push(record);
    }

    let mut writer = csv::WriterBuilder::new()
        .has_headers(false)
        .from_writer(Output::create(target).map_err(MergeError::Output)?);
    let output = |e: csv::Error| MergeError::Output(io::Error::other(e));
    writer.write_record(&header).map_err(output)?;
    let mut last: Option<((String, String), usize)> = None;
    let mut rows = 0;
    while let Some(Reverse((k, i))) = heap.pop() {
        let record = pending[i].take().expect("a queued input has a record");
        if let Some((last_key, last_input)) = &last {
            if last_key.0 == k.0 && *last_input != i {
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
        let following = next(&mut readers[i])?;
        if let Some(r) = &following {
            let following_key = key(r);
            if following_key < k {
                return Err(MergeError::Input(format!(
                    "{} is not sorted by path then mesh at row {}: merge only reports meshvet wrote",
                    readers[i].name.display(),
                    readers[i].line
                )));
            }
            heap.push(Reverse((following_key, i)));
        }
        pending[i] = following;
        last = Some((k, i));
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

    #[test]
    fn merge_sorts_and_refuses_overlaps_mismatches_and_unsorted_input() {
        let dir = tempfile::tempdir().unwrap();
        let a = write(
            dir.path(),
            "a.csv",
            "path,mesh,x\nb.obj,,1\nd.glb,m1,2\nd.glb,m2,3\n",
        );
        let b = write(dir.path(), "b.csv", "path,mesh,x\na.obj,,4\nc.obj,,5\n");
        let out = dir.path().join("all.csv");
        let n = merge(&[a.clone(), b.clone()], &Target::File(out.clone())).unwrap();
        assert_eq!(n, 5);
        assert_eq!(
            std::fs::read_to_string(&out).unwrap(),
            "path,mesh,x\na.obj,,4\nb.obj,,1\nc.obj,,5\nd.glb,m1,2\nd.glb,m2,3\n"
        );
        let overlap = write(dir.path(), "o.csv", "path,mesh,x\nc.obj,,6\n");
        let err = merge(&[a.clone(), b.clone(), overlap], &Target::File(out.clone()))
            .unwrap_err()
            .to_string();
        assert!(err.contains("both report c.obj"), "{err}");
        let other = write(dir.path(), "h.csv", "path,mesh,y\nz.obj,,6\n");
        let err = merge(&[a.clone(), other], &Target::File(out.clone()))
            .unwrap_err()
            .to_string();
        assert!(err.contains("different columns"), "{err}");
        let unsorted = write(dir.path(), "u.csv", "path,mesh,x\nz.obj,,1\ny.obj,,2\n");
        let err = merge(&[unsorted], &Target::File(out.clone()))
            .unwrap_err()
            .to_string();
        assert!(err.contains("not sorted"), "{err}");
        // A failed merge leaves the earlier output alone and no temporary file.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 6);
    }
}
