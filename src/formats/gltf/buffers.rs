//! Buffer data, resolved by meshvet and not by the gltf crate: the GLB binary chunk, `data:` URIs
//! (base64), and relative files that must lie inside the scanned tree. A URI that is absolute, uses
//! any scheme (`file:`, `http:`, ...), or climbs out of the tree is refused before anything is
//! opened: the path is checked lexically first, then again after symbolic links are resolved.

use std::borrow::Cow;
use std::collections::BTreeSet;
use std::io::Read as _;
use std::path::PathBuf;

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig};
use base64::engine::DecodePaddingMode;
use base64::Engine as _;
use gltf::json;
use rustc_hash::FxHashMap;

use super::super::contain::{self, Unresolved};
use super::super::{Limits, ReadError};

pub use super::super::contain::Location;

/// The external files the buffers of one glTF read, each read once however many buffers name it,
/// and only as far as they use it: a glTF buffer is the first `byteLength` bytes of its file, so
/// a file is read up to the longest `byteLength` among its buffers. The bytes read from all the
/// files together are held to `limits.max_file_bytes`, the limit of one file: without that, 100
/// buffers naming one 20 MB file made 100 copies of it (2 GB) from a 20 KB glTF.
#[derive(Default)]
pub struct Files {
    /// The file each buffer reads (an index into `data`), if it names one that was read.
    of_buffer: Vec<Option<usize>>,
    data: Vec<Vec<u8>>,
    /// The index in `data` of each file by its real path.
    index_of: FxHashMap<PathBuf, usize>,
}

/// A file the buffers name: its real path, how much of it they use, and whether a mesh needs it.
struct Wanted {
    path: PathBuf,
    uri: String,
    bytes: u64,
    needed: bool,
}

impl Files {
    /// Reads the files of the buffers a mesh needs (`needed`: any trouble is an error) and of
    /// those only worth reading when they can be (`optional`: a buffer that cannot be loaded, or
    /// would take the files over the limit, is left out). Data URIs and the GLB chunk are part of
    /// the file itself, already within the limit.
    ///
    /// `also`: buffers the copy writer needs besides (any trouble is an error), read in the same
    /// pass. What they add is held to the limit on its own, so that the reader's buffers meet
    /// the limit exactly as in a scan, and the writer's never less than when it read them apart.
    pub fn read(
        buffers: &[json::Buffer],
        needed: &BTreeSet<usize>,
        also: &BTreeSet<usize>,
        optional: &BTreeSet<usize>,
        location: Option<&Location>,
        limits: &Limits,
    ) -> Result<Files, ReadError> {
        let mut of_buffer = vec![None; buffers.len()];
        let mut wanted: Vec<Wanted> = Vec::new();
        let mut index_of: FxHashMap<PathBuf, usize> = FxHashMap::default();
        // Bytes charged to the reader's buffers (`needed`, then `optional`) and to the writer's.
        let mut totals = [0u64; 2];
        let uses = needed
            .iter()
            .map(|&i| (i, true, 0))
            .chain(optional.difference(needed).map(|&i| (i, false, 0)))
            .chain(also.difference(needed).map(|&i| (i, true, 1)));
        for (index, must, pool) in uses {
            let Some(buffer) = buffers.get(index) else {
                continue; // reported by whoever refers to it
            };
            let Some(uri) = buffer.uri.as_deref().filter(|uri| !has_scheme(uri, "data")) else {
                continue;
            };
            let found = location
                .ok_or_else(|| {
                    ReadError::new(format!("buffer URI \"{uri}\" cannot be resolved here"))
                })
                .and_then(|location| resolve(uri, location))
                .and_then(|path| {
                    let size = std::fs::metadata(&path)
                        .map_err(|e| ReadError::new(format!("buffer URI \"{uri}\": {e}")))?
                        .len();
                    Ok((path, size))
                });
            let (path, size) = match found {
                Ok(found) => found,
                Err(e) if must => return Err(e),
                Err(_) => continue,
            };
            // What this buffer uses of the file; a file shorter than it is reported on loading.
            let bytes = buffer.byte_length.0.min(size);
            // Found by its real path in a map: a glTF of 100,000 buffers naming as many files
            // would make a search of the list quadratic.
            let file = *index_of.entry(path.clone()).or_insert_with(|| {
                wanted.push(Wanted {
                    path,
                    uri: uri.to_owned(),
                    bytes: 0,
                    needed: false,
                });
                wanted.len() - 1
            });
            let more = bytes.saturating_sub(wanted[file].bytes);
            let total = &mut totals[pool];
            if total.saturating_add(more) > limits.max_file_bytes {
                if !must {
                    continue;
                }
                let total = total.saturating_add(more);
                let limit = limits.max_file_bytes;
                return Err(ReadError::new(if pool == 0 {
                    format!(
                        "the buffers of this file read {total} bytes from {} file(s) \
                         (\"{uri}\" is the last), over the limit of {limit} bytes for one \
                         file: raise limits.max_file_bytes in the config to scan it",
                        wanted.len()
                    )
                } else {
                    format!(
                        "the buffers the repaired copy reads besides the scan's add {total} \
                         bytes (\"{uri}\" is the last), over the limit of {limit} bytes for \
                         one file: raise limits.max_file_bytes in the config to repair it"
                    )
                }));
            }
            *total += more;
            let w = &mut wanted[file];
            w.bytes += more;
            w.needed |= must;
            of_buffer[index] = Some(file);
        }
        let mut data = Vec::with_capacity(wanted.len());
        for w in &wanted {
            // Sized from the file's size, within the limit; the file may shrink meanwhile.
            let mut bytes = Vec::with_capacity(w.bytes as usize);
            let read = crate::formats::open_regular(&w.path)
                .and_then(|f| f.take(w.bytes).read_to_end(&mut bytes));
            if let Err(e) = read {
                if w.needed {
                    return Err(ReadError::new(format!(
                        "cannot read buffer file \"{}\": {e}",
                        w.uri
                    )));
                }
                // Only optional buffers read it: they are left out.
                of_buffer
                    .iter_mut()
                    .filter(|f| **f == Some(data.len()))
                    .for_each(|f| *f = None);
            }
            data.push(bytes);
        }
        Ok(Files {
            of_buffer,
            data,
            index_of,
        })
    }

    /// What was read of the file at `path` (its real path), if it was read.
    pub fn read_of(&self, path: &std::path::Path) -> Option<&[u8]> {
        self.index_of.get(path).map(|&i| &self.data[i][..])
    }

    /// The bytes behind `loaded` (the buffers by index, as [`load`] gave them): each file read
    /// once, however many buffers share it, and the other buffers (data URIs, the GLB chunk) as
    /// loaded.
    pub fn bytes_behind(&self, loaded: &[Option<Cow<'_, [u8]>>]) -> u64 {
        let files: u64 = self.data.iter().map(|d| d.len() as u64).sum();
        let others: u64 = loaded
            .iter()
            .enumerate()
            .filter(|&(index, _)| !self.holds(index))
            .filter_map(|(_, b)| b.as_ref().map(|b| b.len() as u64))
            .sum();
        files.saturating_add(others)
    }

    /// Whether buffer `index` reads one of these files.
    pub fn holds(&self, index: usize) -> bool {
        matches!(self.of_buffer.get(index), Some(Some(_)))
    }
}

/// Loads buffer `index`: the bytes it declares (`byteLength`), never fewer. Its file, if it names
/// one, is among `files`.
pub fn load<'a>(
    index: usize,
    buffer: &json::Buffer,
    bin: Option<&'a [u8]>,
    is_glb: bool,
    files: &'a Files,
) -> Result<Cow<'a, [u8]>, ReadError> {
    let declared = buffer.byte_length.0;
    let (data, source): (Cow<'a, [u8]>, String) = match buffer.uri.as_deref() {
        None if is_glb && index == 0 => match bin {
            Some(bin) => (Cow::Borrowed(bin), "the GLB binary chunk".to_string()),
            None => {
                return Err(ReadError::new(
                    "buffer 0 refers to the GLB binary chunk, but the file has none",
                ))
            }
        },
        None => {
            return Err(ReadError::new(format!(
                "buffer {index} has no uri and is not the GLB binary chunk"
            )))
        }
        Some(uri) if has_scheme(uri, "data") => (
            Cow::Owned(decode_data_uri(uri, index)?),
            format!("buffer {index} (data URI)"),
        ),
        Some(uri) => match files.of_buffer.get(index).copied().flatten() {
            Some(file) => (
                Cow::Borrowed(files.data[file].as_slice()),
                format!("buffer file \"{uri}\""),
            ),
            None => {
                return Err(ReadError::new(format!(
                    "buffer {index} (\"{uri}\") was not loaded (internal error: please report \
                     this file)"
                )))
            }
        },
    };
    if (data.len() as u64) < declared {
        return Err(ReadError::new(format!(
            "{source} holds {} bytes but buffer {index} declares byteLength {declared}: the data is truncated or the byteLength is wrong",
            data.len()
        )));
    }
    // `declared <= data.len()`, so the cast cannot truncate.
    Ok(match data {
        Cow::Borrowed(b) => Cow::Borrowed(&b[..declared as usize]),
        Cow::Owned(mut v) => {
            v.truncate(declared as usize);
            Cow::Owned(v)
        }
    })
}

/// Whether `uri` starts with `scheme:` (case-insensitive, as URI schemes are).
fn has_scheme(uri: &str, scheme: &str) -> bool {
    uri.len() > scheme.len()
        && uri.as_bytes()[scheme.len()] == b':'
        && uri[..scheme.len()].eq_ignore_ascii_case(scheme)
}

/// The scheme of a URI (`http` in `http://...`), if it has one. One letter before `:` is a Windows
/// drive, not a scheme (and is refused as an absolute path).
fn scheme(uri: &str) -> Option<&str> {
    let colon = uri.find(':')?;
    let name = &uri[..colon];
    let mut chars = name.chars();
    let first = chars.next()?;
    (name.len() > 1
        && first.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')))
    .then_some(name)
}

fn decode_data_uri(uri: &str, index: usize) -> Result<Vec<u8>, ReadError> {
    let comma = uri
        .find(',')
        .ok_or_else(|| ReadError::new(format!("buffer {index}: malformed data URI (no comma)")))?;
    let header = &uri[..comma];
    if !header.to_ascii_lowercase().ends_with(";base64") {
        return Err(ReadError::new(format!(
            "buffer {index}: data URI is not base64-encoded ({header}), meshvet reads base64 data URIs only"
        )));
    }
    const LENIENT: GeneralPurpose = GeneralPurpose::new(
        &base64::alphabet::STANDARD,
        GeneralPurposeConfig::new().with_decode_padding_mode(DecodePaddingMode::Indifferent),
    );
    LENIENT
        .decode(uri[comma + 1..].trim_end())
        .map_err(|e| ReadError::new(format!("buffer {index}: invalid base64 in data URI: {e}")))
}

/// Decodes `%XX` escapes. Fails on a malformed escape or a result that is not UTF-8.
fn percent_decode(uri: &str) -> Result<String, ReadError> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| {
                    ReadError::new(format!("buffer URI \"{uri}\" has a malformed %-escape"))
                })?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| {
        ReadError::new(format!(
            "buffer URI \"{uri}\" is not valid UTF-8 once %-escapes are decoded"
        ))
    })
}

/// The path a relative URI names, checked lexically (no disk access): no scheme, not absolute, not
/// climbing out of the tree ([`contain::join`], the rule every reader and the cache share). Use
/// [`resolve`] before reading it.
pub fn check(uri: &str, location: &Location) -> Result<PathBuf, ReadError> {
    let refuse = |why: &str| {
        ReadError::new(format!(
            "buffer URI \"{uri}\" refused: {why}; meshvet reads only data: URIs and relative paths \
             inside the scanned tree, here {}",
            location.tree_name()
        ))
    };
    if let Some(scheme) = scheme(uri) {
        return Err(refuse(&format!("it uses the {scheme}: scheme")));
    }
    let decoded = percent_decode(uri)?;
    contain::join(&decoded, location).map_err(|why| refuse(why.describe()))
}

/// The file a relative URI names, if it is inside the tree: [`check`], then the same test on the
/// real path once symbolic links are resolved, and it must be a regular file. Never opens anything.
pub fn resolve(uri: &str, location: &Location) -> Result<PathBuf, ReadError> {
    let joined = check(uri, location)?;
    contain::resolve(&joined, location).map_err(|why| match why {
        Unresolved::Missing => ReadError::new(format!(
            "buffer file \"{uri}\" not found (looked for {}): copy the .bin next to the .gltf or fix the uri",
            joined.display()
        )),
        Unresolved::Io(e) => ReadError::new(format!("buffer URI \"{uri}\": {e}")),
        Unresolved::Outside => ReadError::new(format!(
            "buffer URI \"{uri}\" refused: it resolves, through a symbolic link, outside the \
             scanned tree, here {}",
            location.tree_name()
        )),
        Unresolved::NotAFile(real) => ReadError::new(format!(
            "buffer URI \"{uri}\" names {}, which is not a regular file",
            real.display()
        )),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemes_and_drives() {
        assert_eq!(scheme("http://x/a.bin"), Some("http"));
        assert_eq!(scheme("file:///etc/passwd"), Some("file"));
        assert_eq!(scheme("C:/a.bin"), None);
        assert_eq!(scheme("a.bin"), None);
        assert_eq!(scheme("dir/a:b.bin"), None);
        assert!(has_scheme(
            "DATA:application/octet-stream;base64,AA==",
            "data"
        ));
    }

    #[test]
    fn percent_decoding() {
        assert_eq!(percent_decode("a%20b.bin").unwrap(), "a b.bin");
        assert!(percent_decode("a%FF.bin").is_err());
        assert!(percent_decode("a%G1.bin").is_err());
        assert!(percent_decode("a%2").is_err());
    }

    #[test]
    fn data_uri_with_or_without_padding() {
        assert_eq!(
            decode_data_uri("data:application/octet-stream;base64,AAE=", 0).unwrap(),
            vec![0, 1]
        );
        assert_eq!(
            decode_data_uri("data:application/gltf-buffer;base64,AAE", 0).unwrap(),
            vec![0, 1]
        );
        assert!(decode_data_uri("data:text/plain,hello", 0).is_err());
    }
}
