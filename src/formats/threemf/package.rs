//! The ZIP package around a 3MF model (Open Packaging Conventions): finding parts by name,
//! resolving relationship targets inside the package, and inflating a part with its size bounded.
//!
//! Part names are compared as OPC compares them: without the leading `/`, percent-escapes decoded,
//! ASCII case ignored. A relationship target or a production `p:path` must name a part of this
//! package: an external target, a URI with a scheme (`file:`, `http:`), a network path (`//host`),
//! a backslash, or a `..` that climbs above the package root is refused, and nothing outside the
//! ZIP is ever opened.
//!
//! Inflation is bounded twice. Before a part is opened, its declared size must fit what is left
//! of the file's budget (`limits.max_file_bytes` for all parts read together) and its declared
//! compression ratio must be one a mesh can have ([`MAX_RATIO`]; real model parts stay under
//! about 100 to 1, deflate's own ceiling is about 1,030 to 1). While it inflates, reading stops with
//! an error at the declared size, because a declared size can lie.

use std::fs::File;
use std::io::{BufRead, BufReader, Read};
use std::path::Path;

use quick_xml::events::Event;
use rustc_hash::FxHashMap;
use zip::{CompressionMethod, ZipArchive};

use super::super::{Limits, ReadError};
use super::xml::{io_message, Step, Utf8, Xml};

/// The largest declared ratio of inflated to stored bytes a part may have (over [`RATIO_FLOOR`]).
/// Mesh text compresses about 5 to 20 to 1; the most regular parts seen in published packages
/// (slice stacks, grids of equal vertices) stay under 100 to 1.
pub const MAX_RATIO: u64 = 250;

/// Parts that inflate to at most this many bytes are not held to [`MAX_RATIO`]: a tiny stored
/// size (a few hundred bytes of repeated text) may give a large ratio and cost nothing.
pub const RATIO_FLOOR: u64 = 1 << 20;

/// The relationship type of the root model part.
pub const MODEL_RELATIONSHIP: &str = "http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel";

/// The ZIP archive of a 3MF file, with a budget for the bytes inflated from it.
pub struct Package {
    archive: ZipArchive<BufReader<File>>,
    /// Part key ([`key`]) -> entry index.
    parts: FxHashMap<String, usize>,
    /// Bytes that may still be inflated from this package.
    budget: u64,
    limit: u64,
}

/// A relationship of a `.rels` part.
#[derive(Debug, Clone, PartialEq)]
pub struct Relationship {
    pub kind: String,
    /// The target as a part key.
    pub target: String,
}

impl Package {
    /// Opens the package: refuses a file that is not a ZIP archive, or whose entries' names repeat.
    pub fn open(path: &Path, limits: &Limits) -> Result<Package, ReadError> {
        let (file, _) = crate::formats::open_file(path, limits)?;
        let archive = ZipArchive::new(BufReader::new(file)).map_err(|e| {
            ReadError::new(format!(
                "not a 3MF package: the file is not a readable ZIP archive ({e}); a .3mf file is a ZIP of XML parts - re-export it from the modelling program or slicer"
            ))
        })?;
        if archive.has_duplicate_names() {
            // The ZIP reader keeps one entry per name: which of the two a reader sees differs
            // between programs, so the package has no one meaning.
            return Err(ReadError::new(
                "the package holds two parts with the same name: the file is damaged - re-export it",
            ));
        }
        let mut parts = FxHashMap::default();
        for index in 0..archive.len() {
            let entry = archive.by_index_data(index).map_err(|e| {
                ReadError::new(format!(
                    "the ZIP directory is damaged ({e}): re-export the file"
                ))
            })?;
            if entry.is_dir() {
                continue;
            }
            let name = entry_name(entry.name_raw());
            if parts.insert(key(&name), index).is_some() {
                return Err(ReadError::new(format!(
                    "the package holds two parts named `{name}` (part names ignore case): the file is damaged - re-export it"
                )));
            }
        }
        Ok(Package {
            archive,
            parts,
            budget: limits.max_file_bytes,
            limit: limits.max_file_bytes,
        })
    }

    /// Whether the package has a part with this key.
    pub fn has(&self, key: &str) -> bool {
        self.parts.contains_key(key)
    }

    /// The parts a secure-content keystore part lists as encrypted (streamed, like every part).
    pub fn keystore(&mut self, key: &str) -> Result<Vec<String>, ReadError> {
        let name = self.name(key);
        let Some(reader) = self.open_part(key)? else {
            return Ok(Vec::new());
        };
        keystore(BufReader::new(Utf8::new(reader, &name)), &name)
    }

    /// The bytes of a part, inflated within the budget; `None` if there is no such part.
    pub fn read(&mut self, part: &str) -> Result<Option<Vec<u8>>, ReadError> {
        let Some(mut reader) = self.open_part(part)? else {
            return Ok(None);
        };
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .map_err(|e| ReadError::new(io_message(&e, part)))?;
        Ok(Some(bytes))
    }

    /// A reader of a part's inflated bytes, refused before inflating when its declared size passes
    /// the budget or its ratio passes [`MAX_RATIO`], and stopping with an error past its declared
    /// size. `None` if there is no such part.
    pub fn open_part(&mut self, part: &str) -> Result<Option<PartReader<'_>>, ReadError> {
        let Some(&index) = self.parts.get(part) else {
            return Ok(None);
        };
        let entry = self
            .archive
            .by_index_data(index)
            .map_err(|e| ReadError::new(format!("part /{part}: {e}")))?;
        let name = format!("/{}", entry_name(entry.name_raw()));
        if entry.encrypted() {
            return Err(encrypted(&name));
        }
        match entry.compression() {
            CompressionMethod::Stored | CompressionMethod::Deflated => {}
            other => {
                return Err(ReadError::new(format!(
                    "part {name} is compressed with {other}, which meshvet does not read (3MF packages use deflate): re-save the file from its program"
                )))
            }
        }
        let declared = entry.size();
        let stored = entry.compressed_size();
        if declared > self.budget {
            return Err(ReadError::new(if self.budget == self.limit {
                format!(
                    "part {name} declares {declared} bytes inflated, over the limit of {} bytes: raise limits.max_file_bytes in the config to read it",
                    self.limit
                )
            } else {
                format!(
                    "part {name} declares {declared} bytes inflated, which brings the parts read from this package over the limit of {} bytes: raise limits.max_file_bytes in the config to read it",
                    self.limit
                )
            }));
        }
        if declared > RATIO_FLOOR && declared / stored.max(1) > MAX_RATIO {
            return Err(ReadError::new(format!(
                "part {name} declares {declared} bytes from {stored} stored bytes, a compression ratio over {MAX_RATIO} to 1 that no mesh needs (a ZIP bomb?): the file is refused unread"
            )));
        }
        self.budget -= declared;
        let file = self
            .archive
            .by_index(index)
            .map_err(|e| ReadError::new(format!("part {name} cannot be opened: {e}")))?;
        Ok(Some(PartReader {
            inner: Box::new(file),
            left: declared,
            name,
        }))
    }

    /// The relationships of the `.rels` part `rels` (a key); none when it does not exist. Every
    /// target is resolved against `source` (the key of the part the relationships belong to, `""`
    /// for the package) and must lie inside the package.
    pub fn relationships(
        &mut self,
        rels: &str,
        source: &str,
    ) -> Result<Vec<Relationship>, ReadError> {
        let name = self.name(rels);
        let Some(reader) = self.open_part(rels)? else {
            return Ok(Vec::new());
        };
        relationships(BufReader::new(Utf8::new(reader, &name)), &name, source)
    }

    /// The key of the `.rels` part of `part` (`3d/3dmodel.model` -> `3d/_rels/3dmodel.model.rels`).
    pub fn rels_of(part: &str) -> String {
        match part.rsplit_once('/') {
            Some((folder, name)) => format!("{folder}/_rels/{name}.rels"),
            None => format!("_rels/{part}.rels"),
        }
    }

    /// Every entry, in archive order, for the writer.
    pub fn into_archive(self) -> ZipArchive<BufReader<File>> {
        self.archive
    }

    /// The name of part `key` as the package spells it, with a leading `/` (for messages).
    pub fn name(&self, key: &str) -> String {
        let name = self
            .parts
            .get(key)
            .and_then(|&i| self.archive.by_index_data(i).ok())
            .map(|e| entry_name(e.name_raw()));
        format!("/{}", name.as_deref().unwrap_or(key))
    }

    /// The entry index of a part.
    pub fn index(&self, part: &str) -> Option<usize> {
        self.parts.get(part).copied()
    }
}

/// The inflated bytes of one part, cut off with an error past their declared size.
pub struct PartReader<'a> {
    inner: Box<dyn Read + 'a>,
    left: u64,
    name: String,
}

impl Read for PartReader<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if self.left == 0 {
            // One probe byte: a stream that goes on past its declared size is refused.
            let mut probe = [0u8; 1];
            return match self.inner.read(&mut probe)? {
                0 => Ok(0),
                _ => Err(std::io::Error::other(format!(
                    "part {} inflates to more bytes than its ZIP entry declares: the package is damaged or hostile - re-export it",
                    self.name
                ))),
            };
        }
        let room = buf
            .len()
            .min(usize::try_from(self.left).unwrap_or(usize::MAX));
        let n = self.inner.read(&mut buf[..room])?;
        self.left -= n as u64;
        Ok(n)
    }
}

/// The refusal of an encrypted part.
pub fn encrypted(name: &str) -> ReadError {
    ReadError::new(format!(
        "part {name} is encrypted (3MF secure content or a ZIP password), so its mesh cannot be checked: scan an unencrypted export of the model"
    ))
}

/// A ZIP entry's name as text: each byte that is not UTF-8 as `\xHH`, so that two names differing
/// only in such bytes stay two names (a lossy decoding would make both `U+FFFD`).
fn entry_name(raw: &[u8]) -> String {
    let mut out = String::with_capacity(raw.len());
    for chunk in raw.utf8_chunks() {
        out.push_str(chunk.valid());
        for b in chunk.invalid() {
            out.push_str(&format!("\\x{b:02X}"));
        }
    }
    out
}

/// The key of a part name: no leading `/`, percent-escapes decoded, ASCII lower case.
pub fn key(name: &str) -> String {
    let name = name.strip_prefix('/').unwrap_or(name);
    let bytes = name.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |b: u8| (b as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    entry_name(&out).to_ascii_lowercase()
}

/// Resolves `target` (a relationship target or a `p:path`) against the folder of the part `source`
/// (a key; `""` for the package root) to the key of a part inside the package, or says why it is
/// not one.
pub fn resolve(target: &str, source: &str) -> Result<String, String> {
    let outside = |why: &str| {
        Err(format!(
            "`{target}` {why}: a 3MF package may refer only to its own parts"
        ))
    };
    if target.is_empty() {
        return Err("an empty target names no part".into());
    }
    if target.starts_with("//") {
        return outside("is a network path");
    }
    if target.contains('\\') {
        return outside("holds a backslash, which no part name has");
    }
    let scheme_end = target.find(':');
    let path_start = target.find(['/', '?', '#']).unwrap_or(target.len());
    if let Some(colon) = scheme_end.filter(|&c| c < path_start) {
        let scheme = &target[..colon];
        if !scheme.is_empty()
            && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
            && scheme
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'))
        {
            return outside(&format!("is a `{scheme}:` URI"));
        }
    }
    let path = target.split(['?', '#']).next().unwrap_or_default();
    let mut segments: Vec<&str> = Vec::new();
    if !path.starts_with('/') {
        if let Some((folder, _)) = source.rsplit_once('/') {
            segments.extend(folder.split('/'));
        }
    }
    for segment in path.split('/') {
        match segment {
            "" | "." => {}
            ".." => {
                if segments.pop().is_none() {
                    return outside("climbs above the package root");
                }
            }
            s => segments.push(s),
        }
    }
    if segments.is_empty() {
        return Err(format!("`{target}` names no part"));
    }
    Ok(key(&segments.join("/")))
}

/// The namespace of a `.rels` part.
const RELATIONSHIPS: &[u8] = b"http://schemas.openxmlformats.org/package/2006/relationships";

/// The relationships of the `.rels` part named `part` (bytes), their targets resolved against
/// `source` (a key); an external target or one outside the package is refused.
pub fn relationships<R: BufRead>(
    bytes: R,
    part: &str,
    source: &str,
) -> Result<Vec<Relationship>, ReadError> {
    let mut out = Vec::new();
    each_element(bytes, part, |xml, e| {
        let ns = xml.namespace(e);
        let is_relationship =
            e.local_name().as_ref() == b"Relationship" && ns.is_none_or(|ns| ns == RELATIONSHIPS);
        let (mut kind, mut target, mut external) = (String::new(), None, false);
        xml.each_attribute(e, |ns, local, value| {
            if ns.is_none() && is_relationship {
                let text = String::from_utf8_lossy(value);
                match local {
                    b"Type" => kind = text.into_owned(),
                    b"Target" => target = Some(text.into_owned()),
                    b"TargetMode" => external = text.eq_ignore_ascii_case("external"),
                    _ => {}
                }
            }
            Ok(())
        })?;
        if !is_relationship {
            return Ok(());
        }
        let target = target.ok_or_else(|| {
            ReadError::new(format!(
                "part {part} has a relationship without a Target: the file is damaged - re-export it"
            ))
        })?;
        if external {
            return Err(ReadError::new(format!(
                "part {part} has a relationship to `{target}` outside the package (TargetMode External): meshvet reads nothing outside the 3MF file - embed the part or remove the relationship"
            )));
        }
        let target = resolve(&target, source).map_err(|why| {
            ReadError::new(format!("part {part} has a relationship whose target {why}"))
        })?;
        out.push(Relationship { kind, target });
        Ok(())
    })?;
    Ok(out)
}

/// Calls `visit` with every element (start or empty tag) of the XML part `part`, in order.
fn each_element<R: BufRead>(
    bytes: R,
    part: &str,
    mut visit: impl FnMut(&Xml<R>, &quick_xml::events::BytesStart) -> Result<(), ReadError>,
) -> Result<(), ReadError> {
    let part = part.to_owned();
    let mut xml = Xml::new(bytes, &part);
    let mut buf = Vec::new();
    loop {
        let (step, event) = xml.next(&mut buf)?;
        if step == Step::Eof {
            return Ok(());
        }
        if let Event::Start(e) | Event::Empty(e) = &event {
            visit(&xml, e)?;
        }
    }
}

/// The parts a secure-content keystore lists as encrypted (its `resourcedata` paths, as keys).
pub fn keystore<R: BufRead>(bytes: R, part: &str) -> Result<Vec<String>, ReadError> {
    let mut out = Vec::new();
    each_element(bytes, part, |xml, e| {
        let data = e.local_name().as_ref() == b"resourcedata";
        xml.each_attribute(e, |ns, local, value| {
            if data && ns.is_none() && local == b"path" {
                out.push(key(&String::from_utf8_lossy(value)));
            }
            Ok(())
        })
    })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_ignore_case_slash_and_escapes() {
        assert_eq!(key("/3D/3dmodel.model"), "3d/3dmodel.model");
        assert_eq!(key("3D/My%20Part.model"), "3d/my part.model");
        assert_eq!(key("a%2"), "a%2");
        assert_eq!(key("a%zz%41"), "a%zza");
    }

    #[test]
    fn targets_resolve_inside_the_package_only() {
        assert_eq!(
            resolve("/3D/3dmodel.model", ""),
            Ok("3d/3dmodel.model".into())
        );
        assert_eq!(resolve("3D/x.model", ""), Ok("3d/x.model".into()));
        assert_eq!(
            resolve("other.model", "3d/3dmodel.model"),
            Ok("3d/other.model".into())
        );
        assert_eq!(
            resolve("../Metadata/t.png", "3d/3dmodel.model"),
            Ok("metadata/t.png".into())
        );
        assert_eq!(resolve("/3D/./a/../b.model", ""), Ok("3d/b.model".into()));
        for bad in [
            "../x.model",
            "/3D/../../x.model",
            "file:///etc/passwd",
            "file:x.model",
            "http://example.com/x.model",
            "//server/share/x.model",
            "3D\\x.model",
            "",
            "/",
        ] {
            assert!(resolve(bad, "").is_err(), "{bad} was accepted");
        }
        // A colon after the first slash is part of a name, not a scheme.
        assert_eq!(resolve("/3D/a:b.model", ""), Ok("3d/a:b.model".into()));
    }

    /// A stream that goes on past the size its entry declares is cut off with an error; one that
    /// ends there reads whole.
    #[test]
    fn a_part_stops_at_its_declared_size() {
        let read = |data: &'static [u8], left: u64| {
            let mut reader = PartReader {
                inner: Box::new(data),
                left,
                name: "/3D/x.model".into(),
            };
            let mut out = Vec::new();
            reader.read_to_end(&mut out).map(|_| out)
        };
        assert_eq!(read(b"<model/>", 8).unwrap(), b"<model/>");
        let e = read(b"<model/>   ", 8).unwrap_err();
        assert!(
            e.to_string()
                .contains("more bytes than its ZIP entry declares"),
            "{e}"
        );
        assert_eq!(io_message(&e, "3d/x.model"), e.to_string());
    }

    #[test]
    fn rels_parts_sit_beside_their_part() {
        assert_eq!(
            Package::rels_of("3d/3dmodel.model"),
            "3d/_rels/3dmodel.model.rels"
        );
        assert_eq!(Package::rels_of("a.model"), "_rels/a.model.rels");
    }

    #[test]
    fn relationships_resolve_and_refuse_outside_targets() {
        let rels = br#"<?xml version="1.0"?><Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships"><Relationship Target="/3D/3dmodel.model" Id="r0" Type="T"/><Relationship Target="thumb.png" Id="r1" Type="U"/></Relationships>"#;
        assert_eq!(
            relationships(&rels[..], "/_rels/.rels", "").unwrap(),
            [
                Relationship {
                    kind: "T".into(),
                    target: "3d/3dmodel.model".into()
                },
                Relationship {
                    kind: "U".into(),
                    target: "thumb.png".into()
                }
            ]
        );
        let external = br#"<Relationships><Relationship Target="x.model" TargetMode="External" Type="T"/></Relationships>"#;
        let e = relationships(&external[..], "/_rels/.rels", "").unwrap_err();
        assert!(e.0.contains("External"), "{e}");
    }
}
