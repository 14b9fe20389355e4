//! Buffer data, resolved by meshvet and not by the gltf crate: the GLB binary chunk, `data:` URIs
//! (base64), and relative files that must lie inside the scanned tree. A URI that is absolute, uses
//! any scheme (`file:`, `http:`, ...), or climbs out of the tree is refused before anything is
//! opened: the path is checked lexically first, then again after symbolic links are resolved.

use std::borrow::Cow;
use std::path::PathBuf;

use base64::engine::general_purpose::{GeneralPurpose, GeneralPurposeConfig};
use base64::engine::DecodePaddingMode;
use base64::Engine as _;
use gltf::json;

use super::super::contain::{self, Unresolved};
use super::super::{Limits, ReadError};

pub use super::super::contain::Location;

/// Loads buffer `index`: the bytes it declares (`byteLength`), never fewer.
pub fn load<'a>(
    index: usize,
    buffer: &json::Buffer,
    bin: Option<&'a [u8]>,
    is_glb: bool,
    location: Option<&Location>,
    limits: &Limits,
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
        Some(uri) => {
            let location = location.ok_or_else(|| {
                ReadError::new(format!("buffer URI \"{uri}\" cannot be resolved here"))
            })?;
            let path = resolve(uri, location)?;
            let size = std::fs::metadata(&path)
                .map_err(|e| ReadError::new(format!("buffer URI \"{uri}\": {e}")))?
                .len();
            if size > limits.max_file_bytes {
                return Err(ReadError::new(format!(
                    "buffer file \"{uri}\" is {size} bytes, over the limit of {} bytes: raise limits.max_file_bytes in the config to scan it",
                    limits.max_file_bytes
                )));
            }
            let data = std::fs::read(&path)
                .map_err(|e| ReadError::new(format!("cannot read buffer file \"{uri}\": {e}")))?;
            (Cow::Owned(data), format!("buffer file \"{uri}\""))
        }
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
