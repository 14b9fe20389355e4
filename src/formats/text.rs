//! What the text readers (OBJ, OFF, ASCII PLY, ASCII STL) share: telling text from binary content
//! named as a text format, and reading numbers straight from the file's bytes.
//!
//! Binary content is judged on the first [`SAMPLE`] bytes: a well-known signature (an image, an
//! archive, another mesh format) names what the file is; otherwise a zero byte, control
//! characters making up more than a sliver of the bytes (1 in 64), or bytes that are mostly not
//! UTF-8 (a quarter), mean binary data; fewer than 4 such bytes never do. Text in a legacy 8-bit encoding (Latin-1 names and comments are common in OBJ
//! files) has neither control characters nor many invalid sequences, so it stays text; so does a
//! file with a short binary preamble before its text.
//!
//! Numbers are parsed from bytes, without UTF-8 validation, and accept exactly what the standard
//! library's `str::parse` accepts, with the same value: plain decimals (15 digits at most, an
//! exponent within 10^22) by Clinger's fast path, other floats through `fast-float2` (an exact
//! parser: the correctly rounded `f64`, `inf`, `nan` and `infinity` in any case, with a sign),
//! integers eight digits at a time (an optional sign, then ASCII digits, no overflow).

use std::borrow::Cow;

use super::ReadError;

/// How many leading bytes decide whether a file is text.
pub(crate) const SAMPLE: usize = 8192;

/// Fewer control characters (or bytes of invalid UTF-8) than this never make a file binary,
/// however short it is.
const MIN_ODD: usize = 4;

/// Signatures of formats that end up renamed to a mesh text extension: what a person would call
/// the file. A file starting with one of these is not text of any mesh format.
const SIGNATURES: [(&[u8], &str); 22] = [
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"GIF87a", "a GIF image"),
    (b"GIF89a", "a GIF image"),
    (b"II*\0", "a TIFF image"),
    (b"MM\0*", "a TIFF image"),
    (b"DDS ", "a DDS texture"),
    (b"\xabKTX ", "a KTX texture"),
    (
        b"PK\x03\x04",
        "a ZIP archive (a 3MF package or a zipped model?)",
    ),
    (b"PK\x05\x06", "an empty ZIP archive"),
    (b"\x1f\x8b", "a gzip-compressed file"),
    (b"\x28\xb5\x2f\xfd", "a Zstandard-compressed file"),
    (b"\xfd7zXZ\0", "an xz-compressed file"),
    (b"7z\xbc\xaf\x27\x1c", "a 7-Zip archive"),
    (b"Rar!\x1a\x07", "a RAR archive"),
    (b"%PDF-", "a PDF document"),
    (b"glTF", "a binary glTF (GLB) model"),
    (b"Kaydara FBX Binary", "a binary FBX model"),
    (b"BLENDER", "a Blender file"),
    (b"DRACO", "a Draco-compressed mesh"),
    (b"\x7fELF", "a program (an ELF executable)"),
    (
        b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1",
        "a Microsoft compound file (an old Office document or a 3ds Max scene?)",
    ),
];

/// Why a file's content is not text.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Binary {
    /// It starts with the signature of another format (named as a person would say it).
    Known(&'static str),
    /// It starts with a UTF-16 byte order mark.
    Utf16,
    /// A zero byte at this offset.
    Zero(usize),
    /// Many control characters, the first at this offset.
    Control(usize),
    /// Mostly bytes that are not UTF-8 text.
    NotText,
}

/// Control characters text never holds: everything below a space except tab, line feed, vertical
/// tab, form feed and carriage return, and DOS's end-of-file mark (0x1a, still found at the end of
/// old text files); and DEL.
fn is_control(b: u8) -> bool {
    (b < 0x20 && !matches!(b, b'\t' | b'\n' | 0x0b | 0x0c | b'\r' | 0x1a)) || b == 0x7f
}

impl Binary {
    /// The signature of a known format at the start of `bytes`, or a UTF-16 byte order mark.
    pub(crate) fn known(bytes: &[u8]) -> Option<Binary> {
        if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
            return Some(Binary::Utf16);
        }
        if bytes.starts_with(b"ply\n") || bytes.starts_with(b"ply\r") {
            return Some(Binary::Known("a PLY file"));
        }
        SIGNATURES
            .iter()
            .find(|(magic, _)| bytes.starts_with(magic))
            .map(|&(_, name)| Binary::Known(name))
    }

    /// Why `bytes` is not text, or `None` when it is (see the module comment for the rule).
    pub(crate) fn of(bytes: &[u8]) -> Option<Binary> {
        if let Some(known) = Binary::known(bytes) {
            return Some(known);
        }
        let sample = &bytes[..bytes.len().min(SAMPLE)];
        if let Some(at) = memchr::memchr(0, sample) {
            return Some(Binary::Zero(at));
        }
        let controls = sample.iter().filter(|&&b| is_control(b)).count();
        // Text has none (a stray escape code in a comment, at most a few); 1 in 64 is far below
        // the ~1 in 9 of compressed or random data.
        if controls >= MIN_ODD && controls * 64 >= sample.len() {
            let first = sample.iter().position(|&b| is_control(b)).unwrap_or(0);
            return Some(Binary::Control(first));
        }
        // Latin-1 names or comments make isolated invalid bytes; binary data is about half.
        if !sample.is_ascii() {
            let invalid = invalid_utf8_bytes(sample);
            if invalid >= MIN_ODD && invalid * 4 >= sample.len() {
                return Some(Binary::NotText);
            }
        }
        None
    }

    /// The error for a file of `format` ("OBJ", "OFF", "PLY", "STL") with this content.
    pub(crate) fn error(&self, format: &str) -> ReadError {
        let a = if format.starts_with(['O', 'S']) {
            "an"
        } else {
            "a"
        };
        let data = match self {
            Binary::Known(name) => {
                return ReadError::new(format!(
                    "this looks like {name}, not {a} {format} file - rename it to its real \
                     extension, or re-export the model as {format}"
                ))
            }
            Binary::Utf16 => {
                return ReadError::new(format!(
                    "the {format} file is UTF-16 text: {format} must be ASCII or UTF-8 - re-save \
                     it as UTF-8 (any text editor can convert it)"
                ))
            }
            Binary::Zero(at) => format!("a zero byte at offset {at}"),
            Binary::Control(at) => format!("control characters, the first at offset {at}"),
            Binary::NotText => "mostly bytes that are not text".to_owned(),
        };
        ReadError::new(format!(
            "not a text {format} file: binary data ({data}) - check that the file really is {a} \
             {format} (a renamed or corrupted file?)"
        ))
    }
}

/// How many bytes of `bytes` are in invalid UTF-8 sequences (a sequence cut by the end of
/// `bytes` does not count: the sample may end inside a character).
fn invalid_utf8_bytes(mut bytes: &[u8]) -> usize {
    let mut invalid = 0;
    loop {
        match std::str::from_utf8(bytes) {
            Ok(_) => return invalid,
            Err(e) => match e.error_len() {
                Some(n) => {
                    invalid += n;
                    bytes = &bytes[e.valid_up_to() + n..];
                }
                None => return invalid,
            },
        }
    }
}

/// The bytes of a text file with its line ends as the readers find them, at line feeds. Classic
/// Mac OS ended lines with a lone CR, and a file of those read as one line (OBJ and ASCII STL
/// came out `empty`, OFF "truncated"); so a file with no line feed at all but a CR is read as if
/// each CR were a line feed. Any file with a line feed (LF, CRLF, a stray CR inside a line of
/// either) is left as it is, and costs only the search up to its first line feed.
pub(crate) fn lf_line_ends(bytes: &[u8]) -> Cow<'_, [u8]> {
    if memchr::memchr(b'\n', bytes).is_some() || memchr::memchr(b'\r', bytes).is_none() {
        return Cow::Borrowed(bytes);
    }
    Cow::Owned(
        bytes
            .iter()
            .map(|&b| if b == b'\r' { b'\n' } else { b })
            .collect(),
    )
}

/// The words of a line: the runs of bytes between ASCII whitespace, as `str::split_ascii_whitespace`
/// finds them.
#[inline]
pub(crate) fn words(line: &[u8]) -> Words<'_> {
    Words { rest: line }
}

/// The iterator of [`words`].
#[derive(Clone)]
pub(crate) struct Words<'a> {
    rest: &'a [u8],
}

impl<'a> Iterator for Words<'a> {
    type Item = &'a [u8];

    #[inline]
    fn next(&mut self) -> Option<&'a [u8]> {
        let start = self.rest.iter().position(|b| !b.is_ascii_whitespace())?;
        let rest = &self.rest[start..];
        let end = rest
            .iter()
            .position(u8::is_ascii_whitespace)
            .unwrap_or(rest.len());
        self.rest = &rest[end..];
        Some(&rest[..end])
    }
}

/// Whitespace-separated tokens across lines, with the 1-based line each starts on; with
/// `COMMENTS`, `#` also ends a token and starts a comment that runs to the end of its line.
/// Numbers are read in one pass from a token's first byte ([`Tokens::number`]).
pub(crate) struct Tokens<'a, const COMMENTS: bool> {
    bytes: &'a [u8],
    pos: usize,
    /// The line of the next byte.
    pub line: u64,
}

impl<'a, const COMMENTS: bool> Tokens<'a, COMMENTS> {
    /// The tokens of `bytes`, whose first byte is on line `line`.
    pub(crate) fn new(bytes: &'a [u8], line: u64) -> Self {
        Tokens {
            bytes,
            pos: 0,
            line,
        }
    }

    #[inline]
    fn ends_token(b: u8) -> bool {
        b.is_ascii_whitespace() || (COMMENTS && b == b'#')
    }

    /// Moves to the start of the next token; false at the end of the bytes.
    #[inline]
    fn reach(&mut self) -> bool {
        while let Some(&b) = self.bytes.get(self.pos) {
            if COMMENTS && b == b'#' {
                self.skip_line();
            } else if b.is_ascii_whitespace() {
                if b == b'\n' {
                    self.line += 1;
                }
                self.pos += 1;
            } else {
                return true;
            }
        }
        false
    }

    /// The next token and its line.
    pub(crate) fn next(&mut self) -> Option<(&'a [u8], u64)> {
        if !self.reach() {
            return None;
        }
        let start = self.pos;
        while self
            .bytes
            .get(self.pos)
            .is_some_and(|&b| !Self::ends_token(b))
        {
            self.pos += 1;
        }
        Some((&self.bytes[start..self.pos], self.line))
    }

    /// The next token as a number read by `leading` (the number at the start of some bytes and
    /// its length: [`leading_f64`], [`leading_i64`], [`leading_u64`]): `Ok` when the number is the
    /// whole token (the same as parsing the token), else `Err` with the token for the caller's
    /// message. `None` at the end of the bytes.
    #[inline]
    pub(crate) fn number<T>(
        &mut self,
        leading: impl Fn(&[u8]) -> Option<(T, usize)>,
    ) -> Option<(Result<T, &'a [u8]>, u64)> {
        if !self.reach() {
            return None;
        }
        let rest = &self.bytes[self.pos..];
        if let Some((x, n)) = leading(rest) {
            if rest.get(n).is_none_or(|&b| Self::ends_token(b)) {
                self.pos += n;
                return Some((Ok(x), self.line));
            }
        }
        let (token, line) = self.next()?;
        Some((Err(token), line))
    }

    /// The `N` numbers of the line at the current position, read by `leading`, when the line is
    /// just them: blanks (spaces, tabs, `\r`, form feeds) around and between them, a line feed or
    /// the end of the bytes after them. With the bytes to [`Tokens::pass`] to go past the line;
    /// `None` for any other line. Where it reads numbers, reading them one by one with
    /// [`Tokens::number`] and then skipping the line ends at the same place.
    #[inline]
    pub(crate) fn line<T: Copy + Default, const N: usize>(
        &self,
        leading: impl Fn(&[u8]) -> Option<(T, usize)>,
    ) -> Option<([T; N], usize)> {
        let rest = self.bytes.get(self.pos..)?;
        let (out, mut at) = leading_numbers(rest, 0, blank, leading)?;
        while rest.get(at).copied().is_some_and(blank) {
            at += 1;
        }
        match rest.get(at) {
            None => Some((out, at)),
            Some(b'\n') => Some((out, at + 1)),
            Some(_) => None,
        }
    }

    /// Goes past a line [`Tokens::line`] read, `len` bytes.
    #[inline]
    pub(crate) fn pass(&mut self, len: usize) {
        self.pos += len;
        if len > 0 && self.bytes[self.pos - 1] == b'\n' {
            self.line += 1;
        }
    }

    /// The rest of the current line (without a comment and surrounding blanks), then skips it.
    pub(crate) fn rest_of_line(&mut self) -> &'a [u8] {
        let start = self.pos.min(self.bytes.len());
        let end = self.bytes[start..]
            .iter()
            .position(|&b| b == b'\n' || (COMMENTS && b == b'#'))
            .map_or(self.bytes.len(), |k| start + k);
        self.skip_line();
        self.bytes[start..end].trim_ascii()
    }

    /// Skips to the start of the next line.
    pub(crate) fn skip_line(&mut self) {
        match memchr::memchr(b'\n', &self.bytes[self.pos.min(self.bytes.len())..]) {
            Some(k) => {
                self.pos += k + 1;
                self.line += 1;
            }
            None => self.pos = self.bytes.len(),
        }
    }
}

/// The `N` numbers of a line laid out the plainest way, each read by `leading` (the number at
/// the start of some bytes and its length): a number at the line's first byte, one space after
/// each number, or a line feed straight after the last; and the line's length with that line
/// feed. `None` for any other line, which the caller's general reader then takes. Big files'
/// exporters write nearly every line so, and such a line is read here without a scan for blanks
/// or for tokens after the numbers. Where it reads a line, the general quick readers read the
/// same numbers from it and end it at the same place (they allow any blanks around the numbers
/// and check what follows them; the tests hold both to that).
#[inline(always)]
pub(crate) fn plain_line<T: Copy + Default, const N: usize>(
    rest: &[u8],
    leading: impl Fn(&[u8]) -> Option<(T, usize)>,
) -> Option<([T; N], usize)> {
    let mut out = [T::default(); N];
    let mut at = 0;
    for (k, x) in out.iter_mut().enumerate() {
        let (value, n) = leading(rest.get(at..)?)?;
        *x = value;
        at += n;
        match rest.get(at) {
            Some(b' ') => at += 1,
            Some(b'\n') if k + 1 == N => return Some((out, at + 1)),
            _ => return None,
        }
    }
    (rest.get(at) == Some(&b'\n')).then_some((out, at + 1))
}

/// ASCII whitespace other than a line feed: what separates the words of a line (of OBJ and OFF;
/// in PLY a `\r` ends the line).
#[inline(always)]
pub(crate) fn blank(b: u8) -> bool {
    matches!(b, b' ' | b'\t' | b'\r' | b'\x0c')
}

/// The `N` numbers of `rest` from `at` on, each after any bytes `blank` takes, read by `leading`
/// (the number at the start of some bytes and its length) and ended by ASCII whitespace or the
/// end of `rest`; and the place after the last. `None` where a word is not such a number. The
/// quick line readers of OBJ, OFF and ASCII PLY start with it.
#[inline(always)]
pub(crate) fn leading_numbers<T: Copy + Default, const N: usize>(
    rest: &[u8],
    mut at: usize,
    blank: impl Fn(u8) -> bool,
    leading: impl Fn(&[u8]) -> Option<(T, usize)>,
) -> Option<([T; N], usize)> {
    let mut out = [T::default(); N];
    for x in &mut out {
        while rest.get(at).is_some_and(|&b| blank(b)) {
            at += 1;
        }
        let (value, n) = leading(rest.get(at..)?)?;
        at += n;
        if rest.get(at).is_some_and(|b| !b.is_ascii_whitespace()) {
            return None;
        }
        *x = value;
    }
    Some((out, at))
}

/// The `f64` that `str::parse::<f64>` gives for these bytes, or `None` where it gives an error.
#[inline]
pub(crate) fn parse_f64(bytes: &[u8]) -> Option<f64> {
    // (Where the fast path reads a number, it ends where fast-float2's would: a shorter number
    // than the bytes is no number for either.)
    leading_f64(bytes).and_then(|(x, n)| (n == bytes.len()).then_some(x))
}

/// `str::parse::<i64>` on bytes: an optional `+` or `-`, then one or more ASCII digits, in range.
#[inline]
pub(crate) fn parse_i64(bytes: &[u8]) -> Option<i64> {
    leading_i64(bytes)
        .filter(|&(_, n)| n == bytes.len())
        .map(|(i, _)| i)
}

/// The integer at the start of `bytes` (an optional sign, then ASCII digits up to the first other
/// byte) and its length in bytes; `None` without a digit or out of range.
#[inline(always)]
pub(crate) fn leading_i64(bytes: &[u8]) -> Option<(i64, usize)> {
    let (negative, at) = match bytes.first()? {
        b'-' => (true, 1),
        b'+' => (false, 1),
        _ => (false, 0),
    };
    let (magnitude, end) = leading_digits(bytes, at)?;
    if negative {
        // i64::MIN has no positive counterpart.
        (magnitude <= i64::MIN.unsigned_abs()).then(|| (magnitude.wrapping_neg() as i64, end))
    } else {
        i64::try_from(magnitude).ok().map(|i| (i, end))
    }
}

/// The value of the ASCII digits of `bytes` from `at` to the first other byte, and where they
/// end; `None` without a digit or above `u64::MAX`.
#[inline(always)]
fn leading_digits(bytes: &[u8], at: usize) -> Option<(u64, usize)> {
    // Fewer than 8 digits followed by another byte (every index of a mesh file below 10^7):
    // the eight bytes from `at` in a few word operations, without a branch per digit; longer
    // numbers go on eight bytes at a time.
    let (digits, odd) = eight_bytes(bytes, at);
    if odd != 0 {
        let len = odd.trailing_zeros() as usize / 8;
        if len == 0 {
            return None;
        }
        return Some((eight_digits(digits << (64 - 8 * len)), at + len));
    }
    // Eight digits or more (the 17 of a double written in full): on eight bytes at a time, out of
    // line so that the short numbers' path stays small where it is inlined.
    more_digits(bytes, at, eight_digits(digits))
}

/// [`leading_digits`] past the eight digits from `at`, whose value is `value`.
#[inline(never)]
fn more_digits(bytes: &[u8], at: usize, value: u64) -> Option<(u64, usize)> {
    let (mut value, mut end) = (value, at + 8);
    loop {
        let (digits, odd) = eight_bytes(bytes, end);
        let len = (odd.trailing_zeros() / 8) as usize;
        if len == 0 {
            return Some((value, end));
        }
        let part = eight_digits(digits << (64 - 8 * len));
        let scale = 10u64.pow(len as u32);
        // 19 digits always fit a u64: only longer numbers need the checked steps.
        value = if end - at + len <= 19 {
            value * scale + part
        } else {
            value.checked_mul(scale)?.checked_add(part)?
        };
        end += len;
        if len < 8 {
            return Some((value, end));
        }
    }
}

/// The eight bytes of `bytes` from `at`, each less `'0'`, and a mask with bit 7 of each byte set
/// where the byte is not a digit. (Fewer than eight bytes left: taken with zeros after them,
/// which are not digits.)
#[inline(always)]
fn eight_bytes(bytes: &[u8], at: usize) -> (u64, u64) {
    let rest = bytes.get(at..).unwrap_or_default();
    let chunk = match rest.first_chunk::<8>() {
        Some(&chunk) => u64::from_le_bytes(chunk),
        None => (rest.iter().enumerate()).fold(0, |c, (k, &b)| c | u64::from(b) << (8 * k)),
    };
    let digits = chunk.wrapping_sub(0x3030_3030_3030_3030);
    // Bit 7 of a byte is set where the byte is not a digit: its value less `'0'` is over 9
    // (adding 0x76 reaches bit 7) or negative (wrapped: bit 7 already set). A borrow or a
    // carry only ever crosses from such a byte into the bytes after it.
    let odd = (digits.wrapping_add(0x7676_7676_7676_7676) | digits) & 0x8080_8080_8080_8080;
    (digits, odd)
}

/// The number written by eight bytes of digit values 0-9, the first (the lowest byte) the most
/// significant: pairs, then fours, then all eight combined by one multiplication each.
#[inline(always)]
fn eight_digits(digits: u64) -> u64 {
    let pairs = (digits * 10 + (digits >> 8)) & 0x00FF_00FF_00FF_00FF;
    let fours = (pairs * 100 + (pairs >> 16)) & 0x0000_FFFF_0000_FFFF;
    (fours * 10_000 + (fours >> 32)) & 0xFFFF_FFFF
}

/// `str::parse::<u64>` on bytes: an optional `+`, then one or more ASCII digits, in range.
#[inline]
pub(crate) fn parse_u64(bytes: &[u8]) -> Option<u64> {
    leading_u64(bytes)
        .filter(|&(_, n)| n == bytes.len())
        .map(|(i, _)| i)
}

/// The unsigned integer at the start of `bytes` (an optional `+`, then ASCII digits up to the
/// first other byte) and its length in bytes; `None` without a digit or out of range.
#[inline]
pub(crate) fn leading_u64(bytes: &[u8]) -> Option<(u64, usize)> {
    leading_digits(bytes, usize::from(bytes.first() == Some(&b'+')))
}

/// The `f64` at the start of `bytes` as [`parse_f64`] reads it, and its length in bytes.
#[inline]
pub(crate) fn leading_f64(bytes: &[u8]) -> Option<(f64, usize)> {
    leading_decimal(bytes).or_else(|| fast_float2::parse_partial(bytes).ok())
}

/// [`leading_f64`] for the numbers mesh files are mostly made of: a sign, digits, maybe a point
/// and digits (15 digits at most), maybe an exponent, the value within 10^±22 of those digits
/// read as an integer (`None` for anything else). Such a number is an integer below 10^15 times
/// or divided by a power of ten up to 10^22, both exact `f64`s, and one multiplication or
/// division is correctly rounded: the value is the correctly rounded one every exact parser
/// gives (Clinger's fast path, which `fast-float2` takes too, after more general work).
#[inline(always)]
pub(crate) fn leading_decimal(bytes: &[u8]) -> Option<(f64, usize)> {
    /// The powers of ten an `f64` holds exactly.
    const POWERS: [f64; 23] = [
        1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
        1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
    ];
    let at = usize::from(matches!(bytes.first(), Some(b'-' | b'+')));
    let (whole, whole_end) = leading_digits(bytes, at)?;
    let (mantissa, scale, mut end) = if bytes.get(whole_end) == Some(&b'.') {
        let (fraction, end) = leading_digits(bytes, whole_end + 1)?;
        let scale = end - whole_end - 1;
        if end - at - 1 > 15 {
            return None;
        }
        // (10^scale, at most 10^15, is exact as an `f64` and as an `i64`.)
        (
            whole * POWERS[scale] as i64 as u64 + fraction,
            scale as i64,
            end,
        )
    } else if whole_end - at > 15 {
        return None;
    } else {
        (whole, 0, whole_end)
    };
    let mut exponent = -scale;
    match bytes.get(end) {
        Some(b'e' | b'E') => {
            // An exponent that is not one (`1e`, `1e+`) ends the number before the `e`: left
            // to the general parser, as are exponents of more than four digits.
            let (e, after) = leading_i64(&bytes[end + 1..])?;
            if after > 5 {
                return None;
            }
            exponent += e;
            end += 1 + after;
        }
        Some(b'.') => return None,
        _ => {}
    }
    let x = mantissa as i64 as f64;
    let x = match exponent {
        0..=22 => x * POWERS[exponent as usize],
        -22..=-1 => x / POWERS[-exponent as usize],
        _ => return None,
    };
    Some((if bytes[0] == b'-' { -x } else { x }, end))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same answer as the standard parser: both refuse, or both give the same bits (any NaN
    /// for a NaN: only its sign could differ, and nothing reads it).
    fn same_as_std(text: &str) {
        let ours = parse_f64(text.as_bytes());
        let std = text.parse::<f64>().ok();
        match (ours, std) {
            (Some(a), Some(b)) if a.is_nan() && b.is_nan() => {}
            (Some(a), Some(b)) => assert_eq!(a.to_bits(), b.to_bits(), "`{text}`: {a} vs {b}"),
            (a, b) => assert_eq!(a, b, "`{text}`"),
        }
        assert_eq!(
            parse_i64(text.as_bytes()),
            text.parse::<i64>().ok(),
            "`{text}`"
        );
        assert_eq!(
            parse_u64(text.as_bytes()),
            text.parse::<u64>().ok(),
            "`{text}`"
        );
        // A number read from a token's first byte is the token's number when it spans the token.
        let whole = leading_f64(text.as_bytes()).filter(|&(_, n)| n == text.len());
        assert_eq!(
            whole.map(|(x, _)| x.to_bits()),
            ours.map(f64::to_bits),
            "`{text}`"
        );
        let longest = (1..=text.len())
            .rev()
            .filter(|&k| text.is_char_boundary(k))
            .find_map(|k| text[..k].parse::<u64>().ok().map(|i| (i, k)));
        let overflow =
            longest.is_some_and(|(_, k)| text[k..].starts_with(|c: char| c.is_ascii_digit()));
        if !overflow {
            assert_eq!(leading_u64(text.as_bytes()), longest, "`{text}`");
        }
    }

    /// Awkward numbers: more digits than an f64 holds (ties at the 17th digit and beyond decide
    /// the rounding), the largest and smallest normal and subnormal values and just past them,
    /// overflow to infinity and underflow to zero, signed zeros, a bare `.` or exponent, every
    /// spelling of infinity and NaN the standard parser takes, and integer limits.
    #[test]
    fn numbers_read_as_the_standard_parser_reads_them() {
        for text in [
            "0",
            "-0",
            "+0",
            "-0.0",
            "0.0e0",
            "1",
            "+3",
            "-3",
            ".5",
            "5.",
            "-.5",
            "+5.",
            ".",
            "-",
            "+",
            "",
            " 1",
            "1 ",
            "e5",
            "1e",
            "1e+",
            "1e-",
            "1e5",
            "1E5",
            "1e+5",
            "1e-5",
            "1.e5",
            ".1e5",
            "1.5e-3",
            "0.1",
            "0.2",
            "0.3",
            "123456.789",
            "3.141592653589793",
            "3.1415926535897932384626433832795028841971693993751",
            "2.2250738585072014e-308",
            "2.2250738585072011e-308",
            "4.9406564584124654e-324",
            "2.4703282292062327e-324",
            "2.4703282292062328e-324",
            "1e-400",
            "-1e-400",
            "1.7976931348623157e308",
            "1.7976931348623158e308",
            "1.7976931348623159e308",
            "1e308",
            "1e309",
            "1e400",
            "-1e400",
            "1e99999999999999999999",
            "9007199254740993",
            "9007199254740992.5",
            "9007199254740993.0000000000000000000001",
            "0.000000000000000000000000000000000000000000001e45",
            "12345678901234567890123456789",
            "00000000000000000000000000001.5",
            "1_000",
            "0x10",
            "1,5",
            "1.5.5",
            "--1",
            "+-1",
            "1e5.5",
            "inf",
            "-inf",
            "+inf",
            "INF",
            "Inf",
            "infinity",
            "-Infinity",
            "INFINITY",
            "infinit",
            "infinityy",
            "nan",
            "NaN",
            "-nan",
            "+NAN",
            "nan(1)",
            "nana",
            "in",
            "na",
            "1.#IND",
            "1.#QNAN",
            "-1.#INF",
            "9223372036854775807",
            "9223372036854775808",
            "-9223372036854775808",
            "-9223372036854775809",
            "18446744073709551615",
            "18446744073709551616",
            "-0",
            "+",
            "007",
            "١",
            "1\u{0}",
        ] {
            same_as_std(text);
        }
    }

    /// Random strings over the characters numbers are made of agree with the standard parser.
    #[test]
    fn random_numbers_read_as_the_standard_parser_reads_them() {
        const CHARS: &[u8] = b"0123456789012345678901234567890123456789..++--eEinfatyINFATY#";
        let mut random = crate::geometry::xorshift(0x9E37_79B9_7F4A_7C15);
        for _ in 0..20_000 {
            let len = 1 + random() as usize % 24;
            let text: String = (0..len)
                .map(|_| CHARS[random() as usize % CHARS.len()] as char)
                .collect();
            same_as_std(&text);
        }
        // Shortest texts of random doubles, and the same with their last digit changed.
        for _ in 0..20_000 {
            let x = f64::from_bits(random());
            let text = format!("{x:e}");
            same_as_std(&text);
            let mut bumped = text.into_bytes();
            if let Some(d) = bumped.iter_mut().rev().find(|d| d.is_ascii_digit()) {
                *d = b'0' + (*d - b'0' + 5) % 10;
            }
            same_as_std(std::str::from_utf8(&bumped).unwrap());
        }
    }

    /// Integers at the start of bytes, read a word at a time where eight bytes are left: every
    /// length of digits from 0 to 21, followed by every byte value or by the end of the bytes,
    /// and with more bytes after that, agree with the digits read one by one.
    #[test]
    fn leading_integers_read_a_word_at_a_time_agree_with_digit_by_digit() {
        // The standard parser on the sign and digits at the start.
        fn by_std<T: std::str::FromStr>(b: &[u8], signs: &[u8]) -> Option<(T, usize)> {
            let at = usize::from(b.first().is_some_and(|c| signs.contains(c)));
            let end = at + b[at..].iter().take_while(|c| c.is_ascii_digit()).count();
            let text = std::str::from_utf8(&b[..end]).unwrap();
            text.parse().ok().map(|v| (v, end))
        }
        let mut random = crate::geometry::xorshift(0x2545_F491_4F6C_DD1D);
        for len in 0..=21 {
            for next in (0..=255u8).map(Some).chain([None]) {
                for tail in [&b""[..], b"7", b"123456789", b" 1 2 3 4 5 6"] {
                    let mut digits: Vec<u8> =
                        (0..len).map(|_| b'0' + (random() % 10) as u8).collect();
                    digits.extend(next);
                    if next.is_some() {
                        digits.extend(tail);
                    }
                    for sign in [&b""[..], b"+", b"-"] {
                        let b = [sign, &digits[..]].concat();
                        let text = String::from_utf8_lossy(&b);
                        assert_eq!(leading_u64(&b), by_std(&b, b"+"), "`{text}`");
                        assert_eq!(leading_i64(&b), by_std(&b, b"+-"), "`{text}`");
                    }
                }
            }
        }
    }

    /// Decimals read by the quick path are the standard parser's value of the same bytes, and
    /// every number read at the start of bytes is what `fast-float2` alone reads there: random
    /// signs, 0-18 digits before and after a point, exponents from -40 to 40 (with and without
    /// sign and leading zeros), half-written exponents, a second point, a blank or other bytes,
    /// or the end of the bytes.
    #[test]
    fn decimals_read_quickly_are_the_standard_values() {
        let mut random = crate::geometry::xorshift(0xD1B5_4A32_D192_ED03);
        let mut quick = 0;
        for _ in 0..200_000 {
            let mut text = String::new();
            text.push_str(["", "", "-", "+"][random() as usize % 4]);
            let digits = |random: &mut dyn FnMut() -> u64, text: &mut String| {
                for _ in 0..random() % 19 {
                    // Zeros more often than the others: leading and trailing zeros, and -0.
                    let d = random() % 14;
                    text.push(char::from(b'0' + if d >= 10 { 0 } else { d as u8 }));
                }
            };
            digits(&mut random, &mut text);
            if !random().is_multiple_of(4) {
                text.push('.');
                digits(&mut random, &mut text);
            }
            let next = ["", " ", "\n", "e", "E+", "e-", ".5", "x", "#", "1.25"];
            match random() % 3 {
                0 => text.push_str(next[random() as usize % next.len()]),
                // An exponent from -40 to 40, written in any of its forms, then maybe more.
                _ => {
                    let e = (random() % 81) as i64 - 40;
                    let sign = ["", "+"][random() as usize % 2];
                    let zeros = "0".repeat(random() as usize % 3);
                    let e_ = ["e", "E"][random() as usize % 2];
                    match e < 0 {
                        true => text.push_str(&format!("{e_}-{zeros}{}", -e)),
                        false => text.push_str(&format!("{e_}{sign}{zeros}{e}")),
                    }
                    text.push_str(next[random() as usize % next.len()]);
                }
            }
            let b = text.as_bytes();
            let ours = leading_f64(b).map(|(x, n)| (x.to_bits(), n));
            let theirs = fast_float2::parse_partial::<f64, _>(b)
                .ok()
                .map(|(x, n)| (x.to_bits(), n));
            assert_eq!(ours, theirs, "`{text}`");
            if let Some((x, n)) = leading_decimal(b) {
                quick += 1;
                let std: f64 = text[..n].parse().unwrap();
                assert_eq!(x.to_bits(), std.to_bits(), "`{text}`");
            }
        }
        assert!(quick > 30_000, "{quick} read quickly");
    }

    #[test]
    fn words_are_split_at_ascii_whitespace_only() {
        let line = " v\t1 \x0c2\r\n3\x0b4  caf\u{e9}\u{a0}x ";
        let ours: Vec<&[u8]> = words(line.as_bytes()).collect();
        let std: Vec<&[u8]> = line.split_ascii_whitespace().map(str::as_bytes).collect();
        assert_eq!(ours, std);
        assert_eq!(ours.len(), 5);
        assert_eq!(words(b"  \t ").next(), None);
    }

    /// 64 bytes of text: `v 0 0 0\n` eight times.
    fn text_of(len: usize) -> Vec<u8> {
        b"v 0 0 0\n".iter().copied().cycle().take(len).collect()
    }

    #[test]
    fn signatures_are_named() {
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        png.extend(text_of(100));
        assert_eq!(Binary::of(&png), Some(Binary::Known("a PNG image")));
        let e = Binary::of(&png).unwrap().error("OBJ").0;
        assert!(e.contains("looks like a PNG image, not an OBJ file"), "{e}");
        assert_eq!(
            Binary::of(b"PK\x03\x04rest"),
            Some(Binary::Known(
                "a ZIP archive (a 3MF package or a zipped model?)"
            ))
        );
        assert!(Binary::of(b"glTF\x02")
            .unwrap()
            .error("PLY")
            .0
            .contains("not a PLY file"));
        assert_eq!(Binary::of(b"\xff\xfev\0"), Some(Binary::Utf16));
        assert!(Binary::Utf16.error("OFF").0.contains("OFF file is UTF-16"));
    }

    /// 8 KiB of text with k control bytes: 127 (under 1 in 64 of 8192) is still text, 128 is
    /// binary; the same in a 640-byte file: 9 stay text (9 * 64 < 640), 10 do not; and in any
    /// file, fewer than 4 stay text.
    #[test]
    fn control_characters_are_binary_past_one_in_sixty_four() {
        for (len, text, binary) in [(8192, 127, 128), (640, 9, 10)] {
            let mut b = text_of(len);
            for k in 0..text {
                b[8 * k + 2] = 0x01;
            }
            assert_eq!(Binary::of(&b), None, "{len} bytes, {text} controls");
            b[8 * text + 2] = 0x01;
            assert_eq!(
                Binary::of(&b),
                Some(Binary::Control(2)),
                "{binary} controls"
            );
        }
        // Three control characters in 64 bytes are not binary, four in 256 bytes are.
        let mut b = text_of(64);
        b[1] = 0x1b;
        b[9] = 0x1b;
        b[17] = 0x1b;
        assert_eq!(Binary::of(&b), None);
        let mut b = text_of(256);
        for k in [1, 9, 17, 25] {
            b[k] = 0x1b;
        }
        assert_eq!(Binary::of(&b), Some(Binary::Control(1)));
        // Past the sample nothing counts; tab, CR, FF, VT and a DOS end-of-file mark are text.
        let mut b = text_of(SAMPLE);
        b.extend([1u8; 1000]);
        assert_eq!(Binary::of(&b), None);
        assert_eq!(Binary::of(b"v\t0\x0b0\x0c0\r\n\x1a"), None);
        assert_eq!(Binary::of(b"v 0 0\0 0\n"), Some(Binary::Zero(5)));
    }

    /// Latin-1 comments (one invalid byte per accented letter) are text; bytes of which a quarter
    /// or more are invalid UTF-8 are not, if there are at least 4 of them.
    #[test]
    fn invalid_utf8_is_binary_only_when_dense() {
        let mut b = b"# caf\xe9 cr\xe8me br\xfbl\xe9e\n".to_vec();
        b.extend(text_of(64));
        assert_eq!(Binary::of(&b), None);
        // 4 invalid bytes in 16: 25%; 4 in 17 and 3 in 12 are text.
        assert_eq!(
            Binary::of(b"\xe9\xe8\xfb\xfbv 0 0 0\n 0 0"),
            Some(Binary::NotText)
        );
        assert_eq!(Binary::of(b"\xe9\xe8\xfb\xfbv 0 0 0\n 0 00"), None);
        assert_eq!(Binary::of(b"\xe9\xe8\xfbv 0 0 0\n "), None);
        // Valid UTF-8 of any density is text; a character cut by the sample's end is not invalid.
        assert_eq!(Binary::of("ééééé".as_bytes()), None);
        assert_eq!(invalid_utf8_bytes(b"ab\xc3"), 0);
        assert_eq!(invalid_utf8_bytes(b"a\xffb\xfe\xfd"), 3);
    }
}
