//! A record's body (an entry): its header, checksum, key, content hash, stamps and payload, and the
//! payload's binary codec (the rows as their CSV cells, the findings and the shells).

use std::io::{self};

use crate::report::Outcome;
use crate::report::{Row, ShellRow};
use crate::rules::{Finding, Rule, Severity};
use crate::topology::Role;

/// First line of every entry's body; bump the number when the body changes shape.
pub(super) const HEADER: &[u8] = b"meshvet-cache 6\n";

/// An entry's body: the header, a checksum of the rest, the rest (key, content hash, stamps and
/// dependencies, payload). A pack frames it ([`super::pack::record`]).
pub(super) fn body(
    key: &blake3::Hash,
    content: &blake3::Hash,
    meta: &Meta,
    payload: &[u8],
) -> Vec<u8> {
    let mut rest = Vec::with_capacity(payload.len() + 200);
    rest.extend_from_slice(key.as_bytes());
    rest.extend_from_slice(content.as_bytes());
    put_u64(&mut rest, meta.written);
    put_len(&mut rest, meta.dependencies.len());
    for d in &meta.dependencies {
        put_str(&mut rest, d);
    }
    put_len(&mut rest, meta.stamps.len());
    rest.extend_from_slice(&meta.stamps);
    rest.extend_from_slice(payload);
    let mut out = Vec::with_capacity(HEADER.len() + 32 + rest.len());
    out.extend_from_slice(HEADER);
    out.extend_from_slice(blake3::hash(&rest).as_bytes());
    out.extend_from_slice(&rest);
    out
}

/// A body whose header and checksum match, parsed (the payload is decoded only when used).
pub(super) struct Entry<'a> {
    pub(super) key: blake3::Hash,
    pub(super) content: blake3::Hash,
    pub(super) written: u64,
    pub(super) dependencies: Vec<String>,
    /// Encoded as [`put_stamps`] writes them, compared as bytes.
    pub(super) stamps: &'a [u8],
    pub(super) payload: &'a [u8],
}

impl<'a> Entry<'a> {
    /// What follows the header and checksum, if they match.
    pub(super) fn verified(body: &'a [u8]) -> Option<&'a [u8]> {
        let (sum, rest) = body.strip_prefix(HEADER)?.split_at_checked(32)?;
        (blake3::hash(rest).as_bytes()[..] == *sum).then_some(rest)
    }

    pub(super) fn parse(body: &'a [u8]) -> Option<Entry<'a>> {
        let mut r = Reader(Entry::verified(body)?);
        let key = blake3::Hash::from_bytes(r.array()?);
        let content = blake3::Hash::from_bytes(r.array()?);
        let written = r.u64()?;
        let dependencies = (0..r.len()?)
            .map(|_| r.str().map(str::to_owned))
            .collect::<Option<Vec<_>>>()?;
        let len = r.len()?;
        let stamps = r.take(len)?;
        Some(Entry {
            key,
            content,
            written,
            dependencies,
            stamps,
            payload: r.0,
        })
    }
}

/// What an entry records besides the key and the outcomes.
pub(super) struct Meta {
    /// When the entry was written (Unix seconds).
    pub(super) written: u64,
    /// The dependencies the file named (relative to its folder).
    pub(super) dependencies: Vec<String>,
    /// Stamps of the file, then of each dependency, as [`put_stamps`] writes them; empty where
    /// stamps are not available (then every run hashes the content).
    pub(super) stamps: Vec<u8>,
}

pub(super) fn put_u64(out: &mut Vec<u8>, n: u64) {
    out.extend_from_slice(&n.to_le_bytes());
}

pub(super) fn put_len(out: &mut Vec<u8>, n: usize) {
    out.extend_from_slice(&(n as u32).to_le_bytes());
}

/// 7 bits a byte, low first; a set top bit means more follow (a cell's length: mostly one byte).
pub(super) fn put_varint(out: &mut Vec<u8>, mut n: usize) {
    while n >= 0x80 {
        out.push(n as u8 | 0x80);
        n >>= 7;
    }
    out.push(n as u8);
}

pub(super) fn put_str(out: &mut Vec<u8>, s: &str) {
    put_len(out, s.len());
    out.extend_from_slice(s.as_bytes());
}

/// Reads what the `put_` functions wrote; every read is checked against the end.
pub(super) struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    pub(super) fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (taken, rest) = self.0.split_at_checked(n)?;
        self.0 = rest;
        Some(taken)
    }

    pub(super) fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        self.take(N)?.try_into().ok()
    }

    pub(super) fn u8(&mut self) -> Option<u8> {
        Some(self.array::<1>()?[0])
    }

    pub(super) fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }

    pub(super) fn usize(&mut self) -> Option<usize> {
        self.u64()?.try_into().ok()
    }

    pub(super) fn len(&mut self) -> Option<usize> {
        self.array().map(|b| u32::from_le_bytes(b) as usize)
    }

    pub(super) fn varint(&mut self) -> Option<usize> {
        let mut n = 0usize;
        for shift in (0..35).step_by(7) {
            let byte = self.u8()?;
            n |= usize::from(byte & 0x7f) << shift;
            if byte < 0x80 {
                return Some(n);
            }
        }
        None
    }

    pub(super) fn str(&mut self) -> Option<&'a str> {
        let n = self.len()?;
        std::str::from_utf8(self.take(n)?).ok()
    }
}

/// The payload: for each outcome, the row's CSV cells, the findings `(rule, severity, count,
/// message)` and the shells, volumes as their bits (so even an infinite one comes back exactly).
pub(super) fn encode(outcomes: &[Outcome]) -> io::Result<Vec<u8>> {
    let mut out = Vec::with_capacity(1024);
    put_len(&mut out, outcomes.len());
    for o in outcomes {
        let cells = o.row.cells();
        put_len(&mut out, cells.len());
        put_len(&mut out, cells.iter().map(String::len).sum());
        for cell in &cells {
            put_varint(&mut out, cell.len());
        }
        for cell in &cells {
            out.extend_from_slice(cell.as_bytes());
        }
        put_len(&mut out, o.findings.len());
        for f in &o.findings {
            put_str(&mut out, f.rule.name());
            put_str(&mut out, f.severity.name());
            put_u64(&mut out, f.count as u64);
            put_str(&mut out, &f.message);
        }
        put_len(&mut out, o.shells.len());
        for s in &o.shells {
            put_u64(&mut out, s.faces as u64);
            put_u64(&mut out, s.holes as u64);
            out.push(u8::from(s.genus.is_some()));
            put_u64(&mut out, s.genus.unwrap_or(0) as u64);
            out.push(u8::from(s.volume.is_some()));
            put_u64(&mut out, s.volume.unwrap_or(0.0).to_bits());
            put_u64(&mut out, s.depth as u64);
            out.push(match s.role {
                Role::Solid => b's',
                Role::Cavity => b'c',
                Role::Neither => b'n',
            });
            out.push(u8::from(s.inside_out));
            out.push(u8::from(s.pinched));
            put_len(&mut out, s.meets.len());
            for &m in &s.meets {
                put_u64(&mut out, m as u64);
            }
        }
    }
    Ok(out)
}

pub(super) fn decode(payload: &[u8]) -> Option<Vec<Outcome>> {
    let mut r = Reader(payload);
    let count = r.len()?;
    let mut outcomes = Vec::with_capacity(count.min(64));
    for _ in 0..count {
        let count = r.len()?;
        let size = r.len()?;
        let mut lens = Reader(r.0);
        for _ in 0..count {
            lens.varint()?;
        }
        let lens = Reader(r.take(r.0.len() - lens.0.len())?);
        let mut cells = Cells {
            text: std::str::from_utf8(r.take(size)?).ok()?,
            lens,
            left: count,
            start: 0,
        };
        let row = Row::from_cells(&mut cells).ok()?;
        if cells.left != 0 || cells.start != cells.text.len() {
            return None;
        }
        let findings = (0..r.len()?)
            .map(|_| {
                Some(Finding {
                    rule: Rule::from_name(r.str()?)?,
                    severity: Severity::from_name(r.str()?)?,
                    count: r.usize()?,
                    message: r.str()?.to_owned(),
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let shells = (0..r.len()?)
            .map(|_| {
                let faces = r.usize()?;
                let holes = r.usize()?;
                let genus = (r.u8()? == 1, r.u64()? as i64);
                let volume = (r.u8()? == 1, f64::from_bits(r.u64()?));
                Some(ShellRow {
                    faces,
                    holes,
                    genus: genus.0.then_some(genus.1),
                    volume: volume.0.then_some(volume.1),
                    depth: r.usize()?,
                    role: match r.u8()? {
                        b's' => Role::Solid,
                        b'c' => Role::Cavity,
                        b'n' => Role::Neither,
                        _ => return None,
                    },
                    inside_out: r.u8()? == 1,
                    pinched: r.u8()? == 1,
                    meets: (0..r.len()?).map(|_| r.usize()).collect::<Option<_>>()?,
                })
            })
            .collect::<Option<Vec<_>>>()?;
        outcomes.push(Outcome {
            row,
            findings,
            shells,
            ..Outcome::default()
        });
    }
    (r.0.is_empty() && !outcomes.is_empty()).then_some(outcomes)
}

/// A row's CSV cells, read in column order: one block of text and each cell's length.
pub(super) struct Cells<'a> {
    pub(super) text: &'a str,
    /// Each cell's length, as [`put_varint`] writes it.
    pub(super) lens: Reader<'a>,
    pub(super) left: usize,
    pub(super) start: usize,
}

impl<'a> Iterator for Cells<'a> {
    type Item = &'a str;

    fn next(&mut self) -> Option<&'a str> {
        self.left = self.left.checked_sub(1)?;
        let end = self.start.checked_add(self.lens.varint()?)?;
        let cell = self.text.get(self.start..end)?;
        self.start = end;
        Some(cell)
    }
}

pub(super) fn now_secs() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs())
}
