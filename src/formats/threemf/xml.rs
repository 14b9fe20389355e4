//! The XML rules every part of a 3MF package is read by, on top of quick-xml's streaming reader:
//! well-formed and namespace-well-formed (every prefix declared, no attribute twice, end tags
//! matching, one root element, nothing left open), UTF-8 (the bytes of a part, through [`Utf8`]),
//! and no DTD of any kind: a `<!DOCTYPE>` is refused before anything it declares could be used, so
//! no entity is ever expanded (billion laughs) or fetched (XXE). Only the five predefined entities
//! and character references are understood; any other reference is an error. No piece of XML (a
//! text, a comment, a tag) may take [`MAX_PIECE`] bytes or more: the XML reader holds each piece
//! whole in memory.
//!
//! Attributes and namespace declarations are read here, in one pass over each start tag whose
//! results the caller then iterates ([`Xml::each_attribute`]): a million-vertex part is a million
//! tags of three short attributes each, so this pass is the reader's hot loop, and it allocates
//! nothing per tag (but a tag of more than [`PAIRWISE`] attributes, which no 3MF writer makes:
//! its duplicate check takes a hash set). Its work is linear in the tag, however many attributes
//! and namespace declarations a hostile part piles up.

use std::borrow::Cow;
use std::io::{self, BufRead, Read};
use std::ops::Range;

use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use rustc_hash::{FxHashMap, FxHashSet};

use super::super::ReadError;

/// The namespace the `xml` prefix is bound to without a declaration.
const XML_NAMESPACE: &[u8] = b"http://www.w3.org/XML/1998/namespace";

/// A streaming reader of one part, with the checks above.
pub struct Xml<R> {
    reader: Reader<Capped<R>>,
    /// The part's name for messages (`/3D/3dmodel.model`).
    pub part: String,
    depth: u32,
    roots: u32,
    /// Where the last event began, in inflated bytes of the part.
    pub start: u64,
    namespaces: Namespaces,
    /// The attributes of the last start tag: (name, value) ranges into its attribute bytes.
    attributes: Vec<(Range<usize>, Range<usize>)>,
    /// Bytes [`Xml::empty_run`] took from the source past the XML reader (which counts only its own).
    taken: u64,
}

/// The bytes one piece of XML (a text, a comment, a tag, ...) must stay under. quick-xml holds
/// each piece whole in memory before it gives it, so without a bound a part's memory grew with its
/// longest piece (a 2 GB comment took 2.1 GB; a larger one aborted the whole scan on a failed
/// allocation). A 3MF model's longest pieces are a tag or a metadata text of a few kilobytes.
const MAX_PIECE: usize = 16 << 20;

/// The source of the XML reader: [`Xml::next`] lets each event take fewer than `cap` bytes from
/// it, then reading fails with [`TooLong`].
struct Capped<R> {
    inner: R,
    cap: usize,
    /// Bytes the current event may still take.
    left: usize,
    /// The first bytes the current event took, to say what it is when it is too long.
    head: [u8; 9],
    head_len: usize,
    /// The part's first bytes (up to 3), to tell whether it opens with a byte order mark.
    opening: [u8; 3],
    opening_len: usize,
}

impl<R: BufRead> Capped<R> {
    /// The bytes of a byte order mark the part opens with: the XML reader skips it without
    /// counting it in its position.
    fn mark_len(&self) -> u64 {
        if self.opening == [0xef, 0xbb, 0xbf] {
            3
        } else {
            0
        }
    }

    /// Starts an event.
    fn begin(&mut self) {
        self.left = self.cap;
        self.head_len = 0;
    }

    /// What the current event is, in words, from its first bytes.
    fn piece(&self) -> &'static str {
        let head = &self.head[..self.head_len];
        if head.starts_with(b"<!--") {
            "a comment"
        } else if head.starts_with(b"<![CDATA[") {
            "a CDATA section"
        } else if head.starts_with(b"<!") {
            "a document type declaration"
        } else if head.starts_with(b"<?") {
            "a processing instruction"
        } else if head.starts_with(b"<") {
            "a tag"
        } else {
            "text"
        }
    }
}

/// The error of an event that reached [`Capped::cap`] bytes.
#[derive(Debug)]
struct TooLong;

impl std::fmt::Display for TooLong {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a piece of XML is too long")
    }
}

impl std::error::Error for TooLong {}

impl<R: BufRead> Read for Capped<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        let bytes = self.fill_buf()?;
        let n = bytes.len().min(out.len());
        out[..n].copy_from_slice(&bytes[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl<R: BufRead> BufRead for Capped<R> {
    fn fill_buf(&mut self) -> io::Result<&[u8]> {
        if self.left == 0 {
            return Err(io::Error::other(TooLong));
        }
        let bytes = self.inner.fill_buf()?;
        Ok(&bytes[..bytes.len().min(self.left)])
    }

    fn consume(&mut self, n: usize) {
        if self.opening_len < self.opening.len() {
            if let Ok(bytes) = self.inner.fill_buf() {
                let more = n
                    .min(self.opening.len() - self.opening_len)
                    .min(bytes.len());
                self.opening[self.opening_len..self.opening_len + more]
                    .copy_from_slice(&bytes[..more]);
                self.opening_len += more;
            }
        }
        if self.head_len < self.head.len() {
            // The bytes consumed are in the buffer: this reads nothing.
            if let Ok(bytes) = self.inner.fill_buf() {
                let more = n.min(self.head.len() - self.head_len).min(bytes.len());
                self.head[self.head_len..self.head_len + more].copy_from_slice(&bytes[..more]);
                self.head_len += more;
            }
        }
        self.left -= n;
        self.inner.consume(n);
    }
}

/// Tags with at most this many attributes are checked for a repeated name pairwise.
const PAIRWISE: usize = 16;

/// At most this many attributes in a tag [`Xml::empty_run`] reads itself.
const RUN_ATTRIBUTES: usize = 8;

/// The namespace declarations in scope. A lookup costs the same however many are in scope (the
/// default namespace has a stack of its own, prefixes are found through a map), and an element's
/// end takes out only its own declarations: with one list searched from the end, a part
/// declaring 100,000 prefixes made every element search them all (1.4 MB, 40 s).
#[derive(Default)]
struct Namespaces {
    /// (nesting level of the declaring element, prefix (empty for the default namespace)), in
    /// document order: what goes out of scope when an element ends.
    declared: Vec<(u32, Vec<u8>)>,
    /// The default namespace names in scope, innermost last (empty: undeclared).
    default: Vec<Vec<u8>>,
    /// Prefix -> its namespace names in scope, innermost last; a prefix leaves the map when its
    /// last declaration goes out of scope.
    prefixes: FxHashMap<Vec<u8>, Vec<Vec<u8>>>,
}

impl Namespaces {
    /// Binds `prefix` (empty: the default namespace) to `uri` in the element at nesting `level`.
    fn declare(&mut self, level: u32, prefix: &[u8], uri: Vec<u8>) {
        self.declared.push((level, prefix.to_vec()));
        if prefix.is_empty() {
            self.default.push(uri);
        } else if let Some(uris) = self.prefixes.get_mut(prefix) {
            uris.push(uri);
        } else {
            self.prefixes.insert(prefix.to_vec(), vec![uri]);
        }
    }

    /// Takes out the declarations of elements deeper than `depth` (they have ended).
    fn end(&mut self, depth: u32) {
        while self.declared.last().is_some_and(|d| d.0 > depth) {
            let (_, prefix) = self.declared.pop().expect("a declaration is in scope");
            if prefix.is_empty() {
                self.default.pop();
            } else if let Some(uris) = self.prefixes.get_mut(&prefix) {
                uris.pop();
                if uris.is_empty() {
                    self.prefixes.remove(&prefix);
                }
            }
        }
    }

    /// The namespace of `prefix` (`None`: the element's default namespace), or why there is none:
    /// `Err(())` for a prefix nobody declared; `Ok(None)` for no default namespace.
    fn resolve(&self, prefix: Option<&[u8]>) -> Result<Option<&[u8]>, ()> {
        match prefix {
            Some(b"xml") => Ok(Some(XML_NAMESPACE)),
            Some(p) => match self.prefixes.get(p).and_then(|uris| uris.last()) {
                Some(uri) if !uri.is_empty() => Ok(Some(uri)),
                _ => Err(()),
            },
            None => Ok(self
                .default
                .last()
                .map(Vec::as_slice)
                .filter(|uri| !uri.is_empty())),
        }
    }
}

/// What kind of event [`Xml::next`] gave (the event itself stays in the caller's buffer).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    Start,
    Empty,
    End,
    Eof,
    /// Text, comments, processing instructions, the declaration: nothing a reader of meshes needs.
    Other,
}

/// `name` split at its colon: (prefix, local name).
fn split(name: &[u8]) -> (Option<&[u8]>, &[u8]) {
    match name.iter().position(|&b| b == b':') {
        Some(colon) => (Some(&name[..colon]), &name[colon + 1..]),
        None => (None, name),
    }
}

impl<R: BufRead> Xml<R> {
    pub fn new(source: R, part: &str) -> Xml<R> {
        let mut reader = Reader::from_reader(Capped {
            inner: source,
            cap: MAX_PIECE,
            left: MAX_PIECE,
            head: [0; 9],
            head_len: 0,
            opening: [0; 3],
            opening_len: 0,
        });
        let config = reader.config_mut();
        config.check_end_names = true;
        config.expand_empty_elements = false;
        config.trim_text(false);
        Xml {
            reader,
            part: part.to_owned(),
            depth: 0,
            roots: 0,
            start: 0,
            namespaces: Namespaces::default(),
            attributes: Vec::new(),
            taken: 0,
        }
    }

    /// Bytes of the part read so far.
    pub fn position(&self) -> u64 {
        self.reader.buffer_position() + self.taken + self.reader.get_ref().mark_len()
    }

    /// Reads a run of plain empty elements named `name` straight from the source, without the XML
    /// reader: the children of `<vertices>` and `<triangles>`, which are nearly all of a large part.
    /// Call it only right after a Start, Empty or End event (then the source is between markup).
    ///
    /// A tag is taken only when it is certainly well-formed and means what the XML reader would
    /// make of it: `<name` then at most [`RUN_ATTRIBUTES`] unprefixed attributes `a="v"` or
    /// `a='v'` (no references, no `<`, no `>`, no names twice, no namespace declarations) then
    /// `/>`, whole in the source's buffer, with whitespace around; and only when the default
    /// namespace is `namespace`. `f` gets its attributes as (name, value) and says whether it
    /// takes the tag (`false`: it would fail on it). Anything else stops the run before that tag,
    /// for the XML reader to read and check as usual.
    pub fn empty_run(
        &mut self,
        name: &[u8],
        namespace: &[u8],
        mut f: impl FnMut(&[(&[u8], &[u8])]) -> Result<bool, ReadError>,
    ) -> Result<(), ReadError> {
        // Declarations of an element that just ended are out of scope (`next` drops them only
        // when it reads on).
        self.namespaces.end(self.depth);
        if self.namespaces.resolve(None) != Ok(Some(namespace)) {
            return Ok(());
        }
        loop {
            let part = &self.part;
            // Past the bound of one event: a run takes only tags whole in the source's buffer.
            let source = &mut self.reader.get_mut().inner;
            let mut attributes: [(&[u8], &[u8]); RUN_ATTRIBUTES] = [(&[], &[]); RUN_ATTRIBUTES];
            let bytes = match source.fill_buf() {
                Ok(bytes) => bytes,
                Err(e) => return Err(ReadError::new(io_message(&e, part.trim_start_matches('/')))),
            };
            let space = bytes.iter().take_while(|b| b.is_ascii_whitespace()).count();
            if space == bytes.len() {
                if space == 0 {
                    return Ok(()); // the end of the part: the XML reader says what is open
                }
                source.consume(space);
                self.taken += space as u64;
                continue;
            }
            let used = {
                let tag = &bytes[space..];
                let Some(end) = tag.iter().position(|&b| b == b'>') else {
                    return Ok(()); // the tag goes on past the buffer
                };
                let tag = &tag[..=end];
                let named = tag.len() >= name.len() + 3
                    && tag[0] == b'<'
                    && same(&tag[1..=name.len()], name)
                    && tag.ends_with(b"/>");
                if !named {
                    return Ok(());
                }
                let inner = &tag[1 + name.len()..tag.len() - 2];
                let Some(count) = plain_attributes(inner, &mut attributes) else {
                    return Ok(());
                };
                if !f(&attributes[..count])? {
                    return Ok(());
                }
                space + tag.len()
            };
            source.consume(used);
            self.taken += used as u64;
        }
    }

    /// The next event into `buf` (cleared first), refused when it breaks the rules above.
    pub fn next<'b>(&mut self, buf: &'b mut Vec<u8>) -> Result<(Step, Event<'b>), ReadError> {
        buf.clear();
        // Declarations of elements that have ended (or were empty) go out of scope.
        self.namespaces.end(self.depth);
        self.start = self.position();
        self.reader.get_mut().begin();
        let event = match self.reader.read_event_into(buf) {
            Ok(event) => event,
            Err(e) => return Err(self.malformed(&e)),
        };
        if self.start == 0 {
            // The first event starts after the byte order mark, if the part has one.
            self.start = self.reader.get_ref().mark_len();
        }
        let step = match &event {
            Event::Start(e) | Event::Empty(e) => {
                if self.depth == 0 {
                    self.roots += 1;
                    if self.roots > 1 {
                        return Err(self.error(
                            "has a second root element (an XML document has exactly one; a 3MF model part one <model>)",
                        ));
                    }
                }
                self.start_tag(e, self.depth + 1)?;
                if matches!(event, Event::Start(_)) {
                    self.depth += 1;
                    Step::Start
                } else {
                    Step::Empty
                }
            }
            Event::End(_) => {
                self.depth = self.depth.saturating_sub(1);
                Step::End
            }
            Event::Eof => {
                if self.depth > 0 {
                    return Err(self.error(
                        "ends before its elements are closed (the part is cut short)",
                    ));
                }
                if self.roots == 0 {
                    return Err(self.error("holds no XML element"));
                }
                Step::Eof
            }
            Event::DocType(_) => {
                return Err(self.error(
                    "has a document type declaration (<!DOCTYPE>): 3MF parts have none, and meshvet expands no XML entities (a DTD is how billion-laughs and external-entity attacks work) - the file is refused unread",
                ))
            }
            Event::Decl(decl) => {
                if let Some(Ok(encoding)) = decl.encoding() {
                    if !encoding.eq_ignore_ascii_case(b"utf-8") {
                        return Err(self.error(&format!(
                            "declares the encoding `{}`; 3MF parts are UTF-8 - re-export the file",
                            String::from_utf8_lossy(&encoding)
                        )));
                    }
                }
                Step::Other
            }
            Event::GeneralRef(r) => {
                let name: &[u8] = r;
                let known = matches!(name, b"amp" | b"lt" | b"gt" | b"apos" | b"quot");
                if !known && !matches!(r.resolve_char_ref(), Ok(Some(_))) {
                    return Err(self.error(&format!(
                        "refers to the entity `&{};`, which is not defined (meshvet expands no entities)",
                        String::from_utf8_lossy(name)
                    )));
                }
                Step::Other
            }
            _ => Step::Other,
        };
        Ok((step, event))
    }

    /// Reads the attributes of a start tag at nesting `level`: checks their syntax and that no
    /// name repeats, takes in its namespace declarations, and checks that the element's prefix and
    /// every attribute's prefix is declared.
    fn start_tag(&mut self, e: &BytesStart, level: u32) -> Result<(), ReadError> {
        let raw = e.attributes_raw();
        self.attributes.clear();
        let mut at = 0usize;
        let tag = || String::from_utf8_lossy(e.name().into_inner()).into_owned();
        loop {
            while raw.get(at).is_some_and(u8::is_ascii_whitespace) {
                at += 1;
            }
            if at >= raw.len() {
                break;
            }
            if at > 0 && !raw[at - 1].is_ascii_whitespace() {
                return Err(self.malformed_attribute(&tag(), "attributes must be apart"));
            }
            let name_start = at;
            while raw
                .get(at)
                .is_some_and(|&b| !b.is_ascii_whitespace() && b != b'=')
            {
                if matches!(raw[at], b'"' | b'\'' | b'<' | b'>' | b'&') {
                    return Err(self.malformed_attribute(&tag(), "a name holds a quote or bracket"));
                }
                at += 1;
            }
            let name = name_start..at;
            while raw.get(at).is_some_and(u8::is_ascii_whitespace) {
                at += 1;
            }
            if name.is_empty() || raw.get(at) != Some(&b'=') {
                return Err(self.malformed_attribute(&tag(), "an attribute without `=\"value\"`"));
            }
            at += 1;
            while raw.get(at).is_some_and(u8::is_ascii_whitespace) {
                at += 1;
            }
            let quote = match raw.get(at) {
                Some(&q @ (b'"' | b'\'')) => q,
                _ => return Err(self.malformed_attribute(&tag(), "a value without quotes")),
            };
            at += 1;
            let Some(len) = raw[at..].iter().position(|&b| b == quote) else {
                return Err(self.malformed_attribute(&tag(), "a value without its closing quote"));
            };
            let value = at..at + len;
            if raw[value.clone()].contains(&b'<') {
                return Err(self.malformed_attribute(&tag(), "`<` inside a value"));
            }
            if raw[value.clone()].contains(&b'&') {
                unescape(&raw[value.clone()]).map_err(|why| self.reference(&why))?;
            }
            at += len + 1;
            let key = &raw[name.clone()];
            if key == b"xmlns" || key.starts_with(b"xmlns:") {
                let prefix = key.get(6..).unwrap_or_default();
                let uri = unescape(&raw[value.clone()]).map_err(|why| self.reference(&why))?;
                if (key.len() > 5 && prefix.is_empty()) || (!prefix.is_empty() && uri.is_empty()) {
                    return Err(self.malformed_attribute(
                        &tag(),
                        "a namespace declaration without a prefix or a name",
                    ));
                }
                self.namespaces.declare(level, prefix, uri.into_owned());
            }
            self.attributes.push((name, value));
        }
        if let Some(name) = self.repeated(raw) {
            return Err(self.error(&format!(
                "has the attribute `{}` twice in one <{}> (not well-formed XML): the file is damaged - re-export it",
                String::from_utf8_lossy(name),
                tag()
            )));
        }
        let (prefix, _) = split(e.name().into_inner());
        if prefix.is_some() && self.namespaces.resolve(prefix).is_err() {
            return Err(self.undeclared(prefix.unwrap_or_default()));
        }
        for (name, _) in &self.attributes {
            let (prefix, _) = split(&raw[name.clone()]);
            if let Some(p) = prefix.filter(|&p| p != b"xmlns") {
                if self.namespaces.resolve(Some(p)).is_err() {
                    return Err(self.undeclared(p));
                }
            }
        }
        Ok(())
    }

    /// The first attribute name of the last start tag (attribute bytes `raw`) that an earlier
    /// attribute has too, if any. Up to [`PAIRWISE`] attributes, each is compared with those
    /// before it, allocating nothing (nearly every tag has a handful); more go through a hash set,
    /// so that the check stays linear (100,000 attributes compared pairwise took 12.6 s).
    fn repeated<'r>(&self, raw: &'r [u8]) -> Option<&'r [u8]> {
        let name = |a: &(Range<usize>, Range<usize>)| &raw[a.0.clone()];
        if self.attributes.len() <= PAIRWISE {
            return self
                .attributes
                .iter()
                .enumerate()
                .find(|&(i, a)| self.attributes[..i].iter().any(|b| name(b) == name(a)))
                .map(|(_, a)| name(a));
        }
        let mut seen = FxHashSet::default();
        seen.reserve(self.attributes.len());
        self.attributes.iter().map(name).find(|n| !seen.insert(*n))
    }

    /// Reads past the rest of the element whose Start was the last event (its tags are checked as
    /// every tag is).
    pub fn skip(&mut self, buf: &mut Vec<u8>) -> Result<(), ReadError> {
        let mut depth = 1u32;
        while depth > 0 {
            match self.next(buf)?.0 {
                Step::Start => depth += 1,
                Step::End => depth -= 1,
                // `next` refuses an end of part inside an open element; this is only a backstop.
                Step::Eof => return Err(self.error("ends inside an element")),
                Step::Empty | Step::Other => {}
            }
        }
        Ok(())
    }

    /// The namespace of the element of the last start tag `e`, or `None` when it has none.
    pub fn namespace(&self, e: &BytesStart) -> Option<&[u8]> {
        self.namespaces
            .resolve(split(e.name().into_inner()).0)
            .ok()
            .flatten()
    }

    /// The namespace bound to `prefix` where the last start tag is, if any.
    pub fn prefix(&self, prefix: &[u8]) -> Option<&[u8]> {
        self.namespaces.resolve(Some(prefix)).ok().flatten()
    }

    /// Calls `f(namespace, local name, value)` for every attribute of the last start tag `e` but
    /// namespace declarations, with its value unescaped. An unprefixed attribute has no namespace.
    pub fn each_attribute(
        &self,
        e: &BytesStart,
        mut f: impl FnMut(Option<&[u8]>, &[u8], &[u8]) -> Result<(), ReadError>,
    ) -> Result<(), ReadError> {
        let raw = e.attributes_raw();
        for (name, value) in &self.attributes {
            let (prefix, local) = split(&raw[name.clone()]);
            let ns = match prefix {
                None if local == b"xmlns" => continue,
                None => None,
                Some(b"xmlns") => continue,
                Some(p) => self.namespaces.resolve(Some(p)).ok().flatten(),
            };
            let value = &raw[value.clone()];
            if value.contains(&b'&') {
                let value = unescape(value).map_err(|why| self.reference(&why))?;
                f(ns, local, &value)?;
            } else {
                f(ns, local, value)?;
            }
        }
        Ok(())
    }

    /// Calls `f(name, value)` for every attribute of the last start tag `e`, namespace
    /// declarations included, as written: the name with its prefix, the value (without its
    /// quotes) with its references not expanded.
    pub fn each_raw_attribute(&self, e: &BytesStart, mut f: impl FnMut(&[u8], &[u8])) {
        let raw = e.attributes_raw();
        for (name, value) in &self.attributes {
            f(&raw[name.clone()], &raw[value.clone()]);
        }
    }

    pub fn error(&self, what: &str) -> ReadError {
        ReadError::new(format!("part {} {what}", self.part))
    }

    fn undeclared(&self, prefix: &[u8]) -> ReadError {
        self.error(&format!(
            "uses the namespace prefix `{}:` without declaring it (XML that is not namespace-well-formed): the file is damaged - re-export it",
            String::from_utf8_lossy(prefix)
        ))
    }

    fn malformed_attribute(&self, tag: &str, what: &str) -> ReadError {
        self.error(&format!(
            "has a malformed attribute in <{tag}> ({what}): the file is damaged - re-export it"
        ))
    }

    fn reference(&self, why: &str) -> ReadError {
        self.error(&format!(
            "has an attribute value with an undefined reference ({why}; meshvet expands no entities): the file is damaged - re-export it"
        ))
    }

    fn malformed(&self, e: &quick_xml::Error) -> ReadError {
        if let quick_xml::Error::Io(io) = e {
            if io.get_ref().is_some_and(|e| e.is::<TooLong>()) {
                let source = self.reader.get_ref();
                let size = match source.cap {
                    cap if cap >= 1 << 20 => format!("{} MiB", cap >> 20),
                    cap => format!("{cap} bytes"),
                };
                return self.error(&format!(
                    "has {} of more than {size} at byte {}: a 3MF model needs none that long, and meshvet holds no piece of XML that large in memory - the file is damaged or hostile; re-export it",
                    source.piece(),
                    self.start
                ));
            }
            return ReadError::new(io_message(io, self.part.trim_start_matches('/')));
        }
        self.error(&format!(
            "is not well-formed XML near byte {} ({e}): the file is damaged - re-export it",
            self.reader.error_position() + self.taken + self.reader.get_ref().mark_len()
        ))
    }
}

/// The attributes of a tag's `inner` bytes (after its name, before `/>`) into `out`, if they are
/// plain: whitespace before each, `name="value"` or `name='value'` with no space around `=`,
/// names without `:` and values without `&`, `<` or the other quote; no name twice. Their count,
/// or `None` when they are not plain (then the XML reader reads the tag).
fn plain_attributes<'a>(
    inner: &'a [u8],
    out: &mut [(&'a [u8], &'a [u8]); RUN_ATTRIBUTES],
) -> Option<usize> {
    let mut count = 0;
    let mut at = 0;
    loop {
        let start = at;
        while inner.get(at).is_some_and(u8::is_ascii_whitespace) {
            at += 1;
        }
        if at == inner.len() {
            return Some(count);
        }
        if at == start || count == RUN_ATTRIBUTES {
            return None; // no space before the name (or right after the element's name), or too many
        }
        let name_start = at;
        while inner
            .get(at)
            .is_some_and(|&b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-' || b == b'.')
        {
            at += 1;
        }
        let name = &inner[name_start..at];
        if name.is_empty() || !name[0].is_ascii_alphabetic() || inner.get(at) != Some(&b'=') {
            return None;
        }
        let quote = *inner.get(at + 1)?;
        if quote != b'"' && quote != b'\'' {
            return None;
        }
        let value_start = at + 2;
        let len = inner.get(value_start..)?.iter().position(|&b| b == quote)?;
        let value = &inner[value_start..value_start + len];
        if value.iter().any(|&b| matches!(b, b'&' | b'<')) {
            return None;
        }
        if same(name, b"xmlns") || out[..count].iter().any(|(n, _)| same(n, name)) {
            return None;
        }
        out[count] = (name, value);
        count += 1;
        at = value_start + len + 1;
    }
}

/// Whether two short names are equal (an inline loop: a library compare call costs more than
/// the compare for names of a few bytes).
#[inline]
fn same(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x == y)
}

/// An attribute value with its references replaced: the five predefined entities and character
/// references, nothing else.
fn unescape(value: &[u8]) -> Result<Cow<'_, [u8]>, String> {
    if !value.contains(&b'&') {
        return Ok(Cow::Borrowed(value));
    }
    let mut out = Vec::with_capacity(value.len());
    let mut rest = value;
    while let Some(amp) = rest.iter().position(|&b| b == b'&') {
        out.extend_from_slice(&rest[..amp]);
        let after = &rest[amp + 1..];
        let end = after
            .iter()
            .position(|&b| b == b';')
            .ok_or_else(|| "`&` without `;`".to_owned())?;
        let name = &after[..end];
        let text = String::from_utf8_lossy(name);
        let c = match name {
            b"amp" => '&',
            b"lt" => '<',
            b"gt" => '>',
            b"apos" => '\'',
            b"quot" => '"',
            _ => {
                let number = if let Some(hex) = name.strip_prefix(b"#x") {
                    u32::from_str_radix(&String::from_utf8_lossy(hex), 16).ok()
                } else if let Some(dec) = name.strip_prefix(b"#") {
                    String::from_utf8_lossy(dec).parse::<u32>().ok()
                } else {
                    None
                };
                number
                    .and_then(char::from_u32)
                    .filter(|&c| c != '\0')
                    .ok_or_else(|| format!("`&{text};`"))?
            }
        };
        let mut utf8 = [0u8; 4];
        out.extend_from_slice(c.encode_utf8(&mut utf8).as_bytes());
        rest = &after[end + 1..];
    }
    out.extend_from_slice(rest);
    Ok(Cow::Owned(out))
}

/// The bytes of an XML part, failing from the first that is not UTF-8: 3MF parts are UTF-8, and
/// XML in bytes that are not its encoding is not well-formed (a Latin-1 name was read as U+FFFD).
/// Each block the inflater gives is checked whole, which costs far less than parsing it; a
/// character cut by the end of a block is finished with the next.
pub struct Utf8<R> {
    inner: R,
    part: String,
    /// Bytes read so far.
    read: u64,
    /// The start of a character the last block cut, and how many of its bytes came.
    cut: [u8; 4],
    cut_len: usize,
}

impl<R: Read> Utf8<R> {
    /// The bytes of `part` (named as in messages) from `inner`.
    pub fn new(inner: R, part: &str) -> Utf8<R> {
        Utf8 {
            inner,
            part: part.to_owned(),
            read: 0,
            cut: [0; 4],
            cut_len: 0,
        }
    }

    fn refuse(&self, at: u64) -> io::Error {
        io::Error::other(format!(
            "part {} is not UTF-8 (byte {at} is not part of a UTF-8 character): 3MF parts are UTF-8 XML - the file is damaged or was written in another encoding; re-export it",
            self.part
        ))
    }
}

impl<R: Read> Read for Utf8<R> {
    fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
        if out.is_empty() {
            return Ok(0);
        }
        let n = self.inner.read(out)?;
        let start = self.read;
        self.read += n as u64;
        if n == 0 && self.cut_len > 0 {
            return Err(self.refuse(start - self.cut_len as u64));
        }
        let mut bytes = &out[..n];
        let mut at = start;
        if self.cut_len > 0 {
            let size = match self.cut[0] {
                0xf0.. => 4,
                0xe0.. => 3,
                _ => 2,
            };
            let more = (size - self.cut_len).min(bytes.len());
            self.cut[self.cut_len..self.cut_len + more].copy_from_slice(&bytes[..more]);
            self.cut_len += more;
            bytes = &bytes[more..];
            at += more as u64;
            match std::str::from_utf8(&self.cut[..self.cut_len]) {
                Ok(_) => self.cut_len = 0,
                Err(e) if e.error_len().is_none() => {} // still cut: the block was that short
                Err(_) => return Err(self.refuse(start - (self.cut_len - more) as u64)),
            }
        }
        if let Err(e) = std::str::from_utf8(bytes) {
            let bad = at + e.valid_up_to() as u64;
            if e.error_len().is_some() {
                return Err(self.refuse(bad));
            }
            let tail = &bytes[e.valid_up_to()..];
            self.cut[..tail.len()].copy_from_slice(tail);
            self.cut_len = tail.len();
        }
        Ok(n)
    }
}

/// The message for an I/O error while inflating `part`.
pub fn io_message(e: &std::io::Error, part: &str) -> String {
    if e.kind() == std::io::ErrorKind::Other && e.get_ref().is_some() {
        e.to_string()
    } else {
        format!("part /{part} cannot be inflated ({e}): the package is damaged - re-export it")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every event of `text` until the end, or the first error.
    fn events(text: &str) -> Result<Vec<Step>, String> {
        let mut xml = Xml::new(text.as_bytes(), "/t.xml");
        let mut buf = Vec::new();
        let mut out = Vec::new();
        loop {
            let (step, _) = xml.next(&mut buf).map_err(|e| e.0)?;
            out.push(step);
            if step == Step::Eof {
                return Ok(out);
            }
        }
    }

    #[test]
    fn attributes_are_read_with_their_namespaces() {
        let text =
            r#"<a xmlns="urn:d" xmlns:p='urn:p' p:x = "1 &amp; &#65;&#x42;" y="2"><p:b/></a>"#;
        let mut xml = Xml::new(text.as_bytes(), "/t.xml");
        let mut buf = Vec::new();
        let (step, event) = xml.next(&mut buf).unwrap();
        assert_eq!(step, Step::Start);
        let Event::Start(e) = event else { panic!() };
        assert_eq!(xml.namespace(&e), Some(&b"urn:d"[..]));
        let mut got = Vec::new();
        xml.each_attribute(&e, |ns, local, value| {
            got.push((ns.map(<[u8]>::to_vec), local.to_vec(), value.to_vec()));
            Ok(())
        })
        .unwrap();
        assert_eq!(
            got,
            [
                (Some(b"urn:p".to_vec()), b"x".to_vec(), b"1 & AB".to_vec()),
                (None, b"y".to_vec(), b"2".to_vec())
            ]
        );
        let (_, event) = xml.next(&mut buf).unwrap();
        let Event::Empty(e) = event else { panic!() };
        assert_eq!(xml.namespace(&e), Some(&b"urn:p"[..]));
    }

    /// A run after an element that declared the run's namespace and has ended is read in the
    /// parent's namespace: `<t/>` below is in `urn:x`, so a run of `urn:core` tags takes none.
    #[test]
    fn a_run_after_an_ended_declaration_uses_the_parent_namespace() {
        let text = "<a xmlns='urn:x'><b xmlns='urn:core'></b><t/></a>";
        let mut xml = Xml::new(text.as_bytes(), "/t.xml");
        let mut buf = Vec::new();
        for _ in 0..3 {
            xml.next(&mut buf).unwrap();
        }
        let mut taken = 0;
        xml.empty_run(b"t", b"urn:core", |_| {
            taken += 1;
            Ok(true)
        })
        .unwrap();
        assert_eq!(taken, 0);
        let (_, event) = xml.next(&mut buf).unwrap();
        assert!(matches!(event, Event::Empty(_)), "{event:?}");
    }

    /// Positions count from the part's first byte, a byte order mark too: the repair splices
    /// new mesh elements in at the positions read.
    #[test]
    fn positions_count_a_byte_order_mark() {
        for text in ["<a><b/></a>", "\u{feff}<a><b/></a>"] {
            let mut xml = Xml::new(text.as_bytes(), "/t.xml");
            let mut buf = Vec::new();
            xml.next(&mut buf).unwrap();
            assert_eq!(xml.start as usize, text.find("<a>").unwrap(), "{text:?}");
            xml.next(&mut buf).unwrap();
            assert_eq!(xml.start as usize, text.find("<b/>").unwrap(), "{text:?}");
            assert_eq!(
                xml.position() as usize,
                text.find("</a>").unwrap(),
                "{text:?}"
            );
        }
    }

    #[test]
    fn declarations_end_with_their_element() {
        // `q` is declared on the first <b/> only: the second one's prefix is undeclared.
        let e = events(r#"<a><b xmlns:q="urn:q" q:x="1"/><b q:x="1"/></a>"#).unwrap_err();
        assert!(e.contains("prefix `q:` without declaring it"), "{e}");
        assert!(events(r#"<a xmlns:q="urn:q"><b q:x="1"/><q:c/></a>"#).is_ok());
        // A default namespace undeclared again with xmlns="".
        let mut xml = Xml::new(&br#"<a xmlns="urn:d"><b xmlns=""/></a>"#[..], "/t.xml");
        let mut buf = Vec::new();
        xml.next(&mut buf).unwrap();
        let (_, event) = xml.next(&mut buf).unwrap();
        let Event::Empty(e) = event else { panic!() };
        assert_eq!(xml.namespace(&e), None);
    }

    /// A repeated name is found among few attributes (compared pairwise) and many (hashed),
    /// wherever it is; the same names under different prefixes are not repeats.
    #[test]
    fn repeated_attributes_are_found_among_few_and_many() {
        for n in [2, PAIRWISE, PAIRWISE + 1, 1000] {
            let names: Vec<String> = (0..n).map(|i| format!("a{i}")).collect();
            let tag = |extra: &str| {
                let all: String = names.iter().map(|a| format!(" {a}=\"1\"")).collect();
                format!("<t xmlns:p=\"urn:p\"{all}{extra}/>")
            };
            assert!(events(&tag(" p:a0=\"1\"")).is_ok(), "{n}");
            for repeat in [&names[0], &names[n / 2], &names[n - 1]] {
                let e = events(&tag(&format!(" {repeat}=\"2\""))).unwrap_err();
                assert!(
                    e.contains(&format!("`{repeat}` twice in one <t>")),
                    "{n}: {e}"
                );
            }
        }
    }

    /// A piece of XML that reaches the bound is refused, with what it is; up to the bound it is
    /// read, and runs of plain tags are not held to it (they are many events).
    #[test]
    fn pieces_of_xml_are_bounded() {
        let read = |text: &str| {
            let mut xml = Xml::new(text.as_bytes(), "/t.xml");
            xml.reader.get_mut().cap = 64;
            let mut buf = Vec::new();
            loop {
                match xml.next(&mut buf) {
                    Ok((Step::Eof, _)) => return Ok(buf.capacity()),
                    Ok(_) => {}
                    Err(e) => return Err(e.0),
                }
            }
        };
        let long = "x".repeat(64);
        for (text, what) in [
            (
                format!("<a><!--{long}--></a>"),
                "has a comment of more than 64 bytes at byte 3",
            ),
            (format!("<a>{long}</a>"), "has text of"),
            (format!("<a><b c=\"{long}\"/></a>"), "has a tag of"),
            (format!("<a><![CDATA[{long}]]></a>"), "has a CDATA section"),
            (format!("<?pi {long}?><a/>"), "has a processing instruction"),
            (
                format!("<!DOCTYPE a [{long}]><a/>"),
                "has a document type declaration",
            ),
        ] {
            let e = read(&text).unwrap_err();
            assert!(e.contains(what), "{text}: {e}");
        }
        let short = "x".repeat(50);
        let text = format!("<a><!--{short}-->{short}<b c=\"{short}\"/>{short}</a>");
        assert!(read(&text).unwrap() < 128);
        // A run of plain tags is many events, not one piece.
        let text = format!("<a xmlns=\"urn:a\">{}</a>", "<p x=\"1\"/>\n".repeat(100));
        let mut xml = Xml::new(text.as_bytes(), "/t.xml");
        xml.reader.get_mut().cap = 64;
        let mut buf = Vec::new();
        assert_eq!(xml.next(&mut buf).unwrap().0, Step::Start);
        let mut run = 0;
        xml.empty_run(b"p", b"urn:a", |_| {
            run += 1;
            Ok(true)
        })
        .unwrap();
        assert_eq!(run, 100);
        assert_eq!(xml.next(&mut buf).unwrap().0, Step::Other); // the last line break
        assert_eq!(xml.next(&mut buf).unwrap().0, Step::End);
        assert_eq!(xml.next(&mut buf).unwrap().0, Step::Eof);
    }

    /// Valid UTF-8 passes however the blocks cut its characters; a bad byte, or a character cut
    /// by the end of the part, is refused with where it is.
    #[test]
    fn parts_are_utf8() {
        /// Gives its bytes `block` at a time.
        struct Blocks<'a>(&'a [u8], usize);
        impl Read for Blocks<'_> {
            fn read(&mut self, out: &mut [u8]) -> io::Result<usize> {
                let n = self.1.min(out.len()).min(self.0.len());
                out[..n].copy_from_slice(&self.0[..n]);
                self.0 = &self.0[n..];
                Ok(n)
            }
        }
        let read = |bytes: &[u8], block: usize| {
            let mut out = Vec::new();
            Utf8::new(Blocks(bytes, block), "/t.xml")
                .read_to_end(&mut out)
                .map(|_| out)
                .map_err(|e| e.to_string())
        };
        let good = "a é € 😀 z".as_bytes();
        for block in 1..=good.len() {
            assert_eq!(read(good, block).unwrap(), good);
        }
        for (bad, at) in [
            (&b"ab\xffc"[..], 2),
            (b"caf\xe9 ", 3),
            (b"\xe2\x82x", 0),
            (b"ok\xe2\x82", 2),
            (b"\xc0\xaf", 0),
        ] {
            for block in 1..=bad.len() {
                let e = read(bad, block).unwrap_err();
                assert!(
                    e.contains(&format!("is not UTF-8 (byte {at} ")),
                    "{block}: {e}"
                );
            }
        }
    }

    #[test]
    fn malformed_tags_are_refused() {
        for (text, words) in [
            (r#"<a x="1" x="2"/>"#, "twice"),
            (r#"<a x="1"y="2"/>"#, "apart"),
            (r#"<a x=1/>"#, "without quotes"),
            (r#"<a x/>"#, "without `=\"value\"`"),
            (r#"<a x="<"/>"#, "malformed"),
            (r#"<a x="&foo;"/>"#, "`&foo;`"),
            (r#"<a x="&#0;"/>"#, "`&#0;`"),
            (r#"<a x="&amp"/>"#, "without `;`"),
            (r#"<a xmlns:p=""/>"#, "declaration"),
            (r#"<p:a/>"#, "prefix `p:`"),
            (r#"<a>&lol;</a>"#, "entity `&lol;`"),
            (r#"<!DOCTYPE a><a/>"#, "document type declaration"),
            (r#"<a/><b/>"#, "second root"),
            (r#"<a><b></a>"#, "not well-formed"),
            (r#"<a>"#, "ends before"),
            ("", "holds no XML element"),
        ] {
            let e = events(text).unwrap_err();
            assert!(e.contains(words), "{text}: {e}");
        }
        assert!(events(r#"<?xml version="1.0" encoding="utf-8"?><a xml:lang="en" b='&lt;&quot;'>&amp;&#65;</a>"#).is_ok());
    }
}
