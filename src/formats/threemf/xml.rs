//! The XML rules every part of a 3MF package is read by, on top of quick-xml's streaming reader:
//! well-formed and namespace-well-formed (every prefix declared, no attribute twice, end tags
//! matching, one root element, nothing left open), UTF-8, and no DTD of any kind: a `<!DOCTYPE>`
//! is refused before anything it declares could be used, so no entity is ever expanded (billion
//! laughs) or fetched (XXE). Only the five predefined entities and character references are
//! understood; any other reference is an error.

use std::borrow::Cow;
use std::io::BufRead;

use quick_xml::events::{BytesStart, Event};
use quick_xml::name::{NamespaceResolver, ResolveResult};
use quick_xml::{NsReader, XmlVersion};

use super::super::ReadError;

/// A streaming reader of one part, with the checks above.
pub struct Xml<R> {
    pub reader: NsReader<R>,
    /// The part's name for messages (`/3D/3dmodel.model`).
    pub part: String,
    depth: u32,
    roots: u32,
    /// Where the last event began, in inflated bytes of the part.
    pub start: u64,
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

impl<R: BufRead> Xml<R> {
    pub fn new(source: R, part: &str) -> Xml<R> {
        let mut reader = NsReader::from_reader(source);
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
        }
    }

    /// The next event into `buf` (cleared first), refused when it breaks the rules above.
    pub fn next<'b>(&mut self, buf: &'b mut Vec<u8>) -> Result<(Step, Event<'b>), ReadError> {
        buf.clear();
        self.start = self.reader.buffer_position();
        let event = match self.reader.read_event_into(buf) {
            Ok(event) => event,
            Err(e) => return Err(self.malformed(&e)),
        };
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
                if let ResolveResult::Unknown(prefix) = self.reader.resolver().resolve_element(e.name()).0 {
                    return Err(self.undeclared(&prefix));
                }
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

    /// Reads past the rest of the element whose Start was the last event.
    pub fn skip(&mut self, buf: &mut Vec<u8>) -> Result<(), ReadError> {
        let mut depth = 1u32;
        while depth > 0 {
            let (step, event) = self.next(buf)?;
            match step {
                Step::Start => depth += 1,
                Step::End => depth -= 1,
                Step::Empty => {}
                // `next` refuses an end of part inside an open element; this is only a backstop.
                Step::Eof => return Err(self.error("ends inside an element")),
                Step::Other => {}
            }
            if let Event::Start(e) | Event::Empty(e) = &event {
                // Attributes of skipped elements are checked too: the part must be well-formed.
                each_attribute(e, self.reader.resolver(), &self.part, |_, _, _| Ok(()))?;
            }
        }
        Ok(())
    }

    pub fn error(&self, what: &str) -> ReadError {
        ReadError::new(format!("part {} {what}", self.part))
    }

    pub fn undeclared(&self, prefix: &[u8]) -> ReadError {
        self.error(&format!(
            "uses the namespace prefix `{}:` without declaring it (XML that is not namespace-well-formed): the file is damaged - re-export it",
            String::from_utf8_lossy(prefix)
        ))
    }

    fn malformed(&self, e: &quick_xml::Error) -> ReadError {
        if let quick_xml::Error::Io(io) = e {
            return ReadError::new(super::package::io_message(
                io,
                self.part.trim_start_matches('/'),
            ));
        }
        self.error(&format!(
            "is not well-formed XML near byte {} ({e}): the file is damaged - re-export it",
            self.reader.error_position()
        ))
    }
}

/// The namespace of an element, or `None` when it has none.
pub fn namespace<'r>(resolver: &'r NamespaceResolver, e: &BytesStart) -> Option<&'r [u8]> {
    match resolver.resolve_element(e.name()).0 {
        ResolveResult::Bound(ns) => Some(ns.into_inner()),
        _ => None,
    }
}

/// Calls `f(namespace, local name, value)` for every attribute of `e` but namespace declarations,
/// with its value unescaped, after checking it is well-formed, not a repeat of an earlier one, and
/// that its prefix is declared. An unprefixed attribute has no namespace.
pub fn each_attribute(
    e: &BytesStart,
    resolver: &NamespaceResolver,
    part: &str,
    mut f: impl FnMut(Option<&[u8]>, &[u8], &[u8]) -> Result<(), ReadError>,
) -> Result<(), ReadError> {
    // Names seen so far, without an allocation for the usual handful.
    let mut seen: [&[u8]; 8] = [&[]; 8];
    let mut more: Vec<&[u8]> = Vec::new();
    let bad = |what: String| {
        ReadError::new(format!(
            "part {part} {what}: the file is damaged - re-export it"
        ))
    };
    let mut attributes = e.attributes();
    attributes.with_checks(false);
    for (count, attribute) in attributes.enumerate() {
        let attribute = attribute.map_err(|err| {
            bad(format!(
                "has a malformed attribute in <{}> ({err})",
                String::from_utf8_lossy(e.name().as_ref())
            ))
        })?;
        let name = attribute.key.into_inner();
        if seen[..count.min(8)].iter().chain(&more).any(|&n| n == name) {
            return Err(bad(format!(
                "has the attribute `{}` twice in one <{}> (not well-formed XML)",
                String::from_utf8_lossy(name),
                String::from_utf8_lossy(e.name().as_ref())
            )));
        }
        if count < 8 {
            seen[count] = name;
        } else {
            more.push(name);
        }
        if attribute.key.as_namespace_binding().is_some() {
            continue;
        }
        let (ns, local) = match attribute.key.prefix() {
            None => (None, attribute.key.local_name().into_inner()),
            Some(_) => match resolver.resolve_attribute(attribute.key) {
                (ResolveResult::Bound(ns), local) => (Some(ns.into_inner()), local.into_inner()),
                (ResolveResult::Unknown(prefix), _) => {
                    return Err(ReadError::new(format!(
                        "part {part} uses the namespace prefix `{}:` without declaring it (XML that is not namespace-well-formed): the file is damaged - re-export it",
                        String::from_utf8_lossy(&prefix)
                    )))
                }
                (ResolveResult::Unbound, local) => (None, local.into_inner()),
            },
        };
        let value: Cow<'_, [u8]> = if attribute.value.contains(&b'&') {
            let text = attribute.normalized_value(XmlVersion::Explicit1_0).map_err(|err| {
                bad(format!(
                    "has an attribute value with an undefined reference ({err}; meshvet expands no entities)"
                ))
            })?;
            Cow::Owned(text.into_owned().into_bytes())
        } else {
            attribute.value
        };
        f(ns, local, &value)?;
    }
    Ok(())
}
