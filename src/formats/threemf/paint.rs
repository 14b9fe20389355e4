//! Slicer paint on 3MF triangles: PrusaSlicer's `slic3rpe:mmu_segmentation`,
//! `slic3rpe:custom_supports`, `slic3rpe:custom_seam`, `slic3rpe:fuzzy_skin` and
//! `slic3rpe:texture_skin`, and their BambuStudio/OrcaSlicer names `paint_color`,
//! `paint_supports`, `paint_seam` and `paint_fuzzy_skin`. A repaired copy carries them verbatim;
//! only a triangle whose corners the repair reorders (a flipped triangle) needs its paint
//! re-encoded, because the encoding is relative to the corner order.
//!
//! The encoding, as PrusaSlicer's `TriangleSelector::serialize`/`deserialize`, `perform_split`
//! and `FacetsAnnotation::get_triangle_as_string`/`set_triangle_from_string` write and read it
//! (BambuStudio and OrcaSlicer share it): a triangle is a tree of 4-bit codes written depth first.
//! A code's low two bits are the number of sides split (0: a leaf); a leaf's high two bits are its
//! state, `3` meaning that the state minus 3 follows in the next code; a split triangle's high two
//! bits are its special side `s` (always 0 when all three sides are split), and its children
//! follow, the last child first. With the triangle's corners `v`, `w = (v[s], v[s+1], v[s+2])`
//! and `m(a, b)` the midpoint of a side, the children are:
//!
//! - one side split: `(w0, w1, m(w2, w1))`, `(m(w2, w1), w2, w0)`;
//! - two sides split: `(w0, m(w1, w0), m(w0, w2))`, `(m(w1, w0), w1, m(w0, w2))`,
//!   `(w1, w2, m(w0, w2))`;
//! - three sides split: `(v0, a, c)`, `(a, v1, b)`, `(b, v2, c)`, `(a, b, c)` with
//!   `a = m(v1, v0)`, `b = m(v2, v1)`, `c = m(v0, v2)`.
//!
//! The codes, first to last, are written as upper-case hexadecimal digits last to first (the
//! string reads backwards). Re-encoding for new corners splits the triangle in the new order with
//! the special side that splits the same sides, matches each new child to the old child covering
//! the same part of the triangle, and recurses: the same painted regions, described from the new
//! corners. A string that is not exactly such a tree is not re-encoded: an empty result is never
//! guessed. That includes a state continued past one extra code (a code `F` there, which
//! OrcaSlicer writes for states of 18 and up and PrusaSlicer reads as state 18).

use rustc_hash::FxHashMap;

/// The names (as written, with PrusaSlicer's prefix) of the triangle attributes that hold paint in
/// this encoding.
const PAINT: [&str; 9] = [
    "slic3rpe:mmu_segmentation",
    "slic3rpe:custom_supports",
    "slic3rpe:custom_seam",
    "slic3rpe:fuzzy_skin",
    "slic3rpe:texture_skin",
    "paint_color",
    "paint_supports",
    "paint_seam",
    "paint_fuzzy_skin",
];

/// Trees deeper than this are not re-encoded (a slicer splits a triangle down to a brush's size:
/// a few levels; 2^-64 of a triangle is far below any print's resolution).
const MAX_DEPTH: usize = 64;

/// Strings longer than this are not re-encoded. The tree read from one costs tens of bytes a code,
/// and one attribute may be as long as a whole 3MF part: a hostile file with one flipped triangle
/// would otherwise hold gigabytes. A slicer's brush strokes make strings of a few hundred codes.
const MAX_CODES: usize = 1 << 18;

/// Whether a triangle attribute, named as written, holds slicer paint in this encoding.
pub fn is_paint(name: &str) -> bool {
    PAINT.contains(&name)
}

/// A paint tree as read.
enum Node {
    /// A leaf's codes (its state, and the extension code when there is one), in stream order.
    Leaf(Vec<u8>),
    /// A split triangle: sides split (1..=3), special side, children in child order.
    Split {
        sides: u8,
        special: u8,
        children: Vec<Node>,
    },
}

/// `value`, the paint of a triangle with corners `0, 1, 2`, re-encoded for the same triangle with
/// corners `order` (new corner `k` is old corner `order[k]`); `None` when `value` is not a paint
/// string of this encoding. An empty value (no paint) stays empty.
pub fn reorder(value: &str, order: [u8; 3]) -> Option<String> {
    if value.is_empty() {
        return Some(String::new());
    }
    if order.iter().any(|&k| k > 2) || order[0] == order[1] || order[1] == order[2] {
        return None;
    }
    if value.len() > MAX_CODES {
        return None;
    }
    let codes: Vec<u8> = value
        .bytes()
        .rev()
        .map(|b| match b {
            b'0'..=b'9' => Some(b - b'0'),
            b'A'..=b'F' => Some(b - b'A' + 10),
            _ => None,
        })
        .collect::<Option<_>>()?;
    let mut at = 0;
    let tree = parse(&codes, &mut at, 0)?;
    if at != codes.len() {
        return None; // codes past the tree
    }
    let mut out = Vec::with_capacity(codes.len());
    let mut points = Points::default();
    let new = order.map(u32::from);
    encode(&tree, [0, 1, 2], new, &mut points, &mut out)?;
    Some(
        out.iter()
            .rev()
            .map(|&c| char::from(b"0123456789ABCDEF"[usize::from(c & 15)]))
            .collect(),
    )
}

/// The node whose first code is `codes[*at]`.
fn parse(codes: &[u8], at: &mut usize, depth: usize) -> Option<Node> {
    if depth > MAX_DEPTH {
        return None;
    }
    let code = *codes.get(*at)?;
    *at += 1;
    let (sides, high) = (code & 3, code >> 2);
    if sides == 0 {
        let mut leaf = vec![code];
        if high == 3 {
            let more = *codes.get(*at)?;
            if more == 15 {
                return None; // read two ways (see the module's documentation)
            }
            *at += 1;
            leaf.push(more);
        }
        return Some(Node::Leaf(leaf));
    }
    if high == 3 || (sides == 3 && high != 0) {
        return None; // PrusaSlicer asserts against both
    }
    // The children come last first.
    let mut children: Vec<Node> = (0..=sides)
        .map(|_| parse(codes, at, depth + 1))
        .collect::<Option<_>>()?;
    children.reverse();
    Some(Node::Split {
        sides,
        special: high,
        children,
    })
}

/// The corners and side midpoints of one triangle's tree, numbered: `0..3` the corners, then each
/// midpoint once, whichever way its side is named.
#[derive(Default)]
struct Points {
    midpoints: FxHashMap<(u32, u32), u32>,
}

impl Points {
    fn mid(&mut self, a: u32, b: u32) -> u32 {
        let key = (a.min(b), a.max(b));
        let next = 3 + self.midpoints.len() as u32;
        *self.midpoints.entry(key).or_insert(next)
    }
}

/// The children `perform_split` makes of triangle `v` (see the module's documentation).
fn split(v: [u32; 3], sides: u8, special: u8, points: &mut Points) -> Vec<[u32; 3]> {
    let s = usize::from(special);
    let w = [v[s % 3], v[(s + 1) % 3], v[(s + 2) % 3]];
    match sides {
        1 => {
            let m = points.mid(w[2], w[1]);
            vec![[w[0], w[1], m], [m, w[2], w[0]]]
        }
        2 => {
            let m1 = points.mid(w[1], w[0]);
            let m2 = points.mid(w[0], w[2]);
            vec![[w[0], m1, m2], [m1, w[1], m2], [w[1], w[2], m2]]
        }
        _ => {
            let a = points.mid(v[1], v[0]);
            let b = points.mid(v[2], v[1]);
            let c = points.mid(v[0], v[2]);
            vec![[v[0], a, c], [a, v[1], b], [b, v[2], c], [a, b, c]]
        }
    }
}

/// A triangle's corners as a set.
fn set(t: [u32; 3]) -> [u32; 3] {
    let mut s = t;
    s.sort_unstable();
    s
}

/// A split of triangle `v` into `sides + 1` children covering the parts of the triangle that
/// `targets` cover (compared as sets of corners), if one exists: its special side and children.
fn same_split(
    v: [u32; 3],
    sides: u8,
    targets: &[[u32; 3]],
    points: &mut Points,
) -> Option<(u8, Vec<[u32; 3]>)> {
    let mut want: Vec<[u32; 3]> = targets.iter().map(|&t| set(t)).collect();
    want.sort_unstable();
    let specials: &[u8] = if sides == 3 { &[0] } else { &[0, 1, 2] };
    specials.iter().find_map(|&s| {
        let children = split(v, sides, s, points);
        let mut got: Vec<[u32; 3]> = children.iter().map(|&t| set(t)).collect();
        got.sort_unstable();
        (got == want).then_some((s, children))
    })
}

/// Appends the codes of `node`, read for the triangle with corners `old`, written for the same
/// triangle with corners `new`.
///
/// Splitting one or all three sides cuts a triangle into the same parts from any corner order,
/// so such a node keeps its split. Splitting two sides does not: it cuts off the corner `w0`
/// where the two sides meet, `T0 = (w0, m1, m2)`, and cuts the rest along the diagonal from
/// `w1` to `m2` (`T1 = (m1, w1, m2)`, `T2 = (w1, w2, m2)`), and with the corners in the other
/// direction the diagonal would run from the other end. The same parts are then written as two
/// one-side splits: the triangle halved at `m2` into `T0 + T1 = (w0, w1, m2)` and `T2`, and that
/// half halved at `m1` into `T0` and `T1`.
fn encode(
    node: &Node,
    old: [u32; 3],
    new: [u32; 3],
    points: &mut Points,
    out: &mut Vec<u8>,
) -> Option<()> {
    let Node::Split {
        sides,
        special,
        children,
    } = node
    else {
        if let Node::Leaf(codes) = node {
            out.extend_from_slice(codes);
        }
        return Some(());
    };
    let before = split(old, *sides, *special, points);
    // The old child covering the same part as `t`.
    let find = |t: [u32; 3]| before.iter().position(|&b| set(b) == set(t));
    if let Some((s, after)) = same_split(new, *sides, &before, points) {
        out.push(sides | (s << 2));
        for child in after.iter().rev() {
            let i = find(*child)?;
            encode(&children[i], before[i], *child, points, out)?;
        }
        return Some(());
    }
    if *sides != 2 {
        return None;
    }
    let half = [before[0][0], before[1][1], before[0][2]];
    let (s, halves) = same_split(new, 1, &[half, before[2]], points)?;
    out.push(1 | (s << 2));
    for h in halves.iter().rev() {
        if set(*h) == set(before[2]) {
            encode(&children[2], before[2], *h, points, out)?;
            continue;
        }
        let (s, quarters) = same_split(*h, 1, &before[..2], points)?;
        out.push(1 | (s << 2));
        for q in quarters.iter().rev() {
            let i = find(*q)?;
            encode(&children[i], before[i], *q, points, out)?;
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const FLIP: [u8; 3] = [0, 2, 1];

    /// A tree of triangles quartered `depth` times (every leaf unpainted), as a paint string.
    fn quartered(depth: u32) -> String {
        fn codes(depth: u32, out: &mut Vec<u8>) {
            if depth == 0 {
                out.push(0);
            } else {
                out.push(3);
                for _ in 0..4 {
                    codes(depth - 1, out);
                }
            }
        }
        let mut out = Vec::new();
        codes(depth, &mut out);
        out.iter()
            .rev()
            .map(|&c| char::from(b"0123456789ABCDEF"[usize::from(c)]))
            .collect()
    }

    /// A valid string past [`MAX_CODES`] is not re-encoded (its tree would cost tens of bytes a
    /// code); one below it is. Quartered 8 times: 21,845 splits and 65,536 leaves; 9 times:
    /// 349,525 codes.
    #[test]
    fn paint_past_the_length_limit_is_not_re_encoded() {
        let below = quartered(8);
        assert_eq!(below.len(), 87_381);
        assert!(reorder(&below, FLIP).is_some_and(|s| s.len() == below.len()));
        let past = quartered(9);
        assert_eq!(past.len(), 349_525);
        assert_eq!(reorder(&past, FLIP), None);
    }

    /// One side split, special side 0: child 0 `(v0, v1, m12)` has state 1 (code 4), child 1
    /// `(m12, v2, v0)` state 2 (code 8); codes child 1 first: `1 8 4`, written backwards `481`.
    /// With corners `(v0, v2, v1)` the same side is split with special side 0, child 0 is
    /// `(v0, v2, m12)`, the old child 1 (state 2), child 1 the old child 0: codes `1 4 8`, `841`.
    #[test]
    fn a_half_split_triangle_swaps_its_halves() {
        assert_eq!(reorder("481", FLIP).as_deref(), Some("841"));
        assert_eq!(reorder("841", FLIP).as_deref(), Some("481"));
        assert_eq!(reorder("481", [0, 1, 2]).as_deref(), Some("481"));
    }

    /// All sides split: children `(v0, a, c)` state 1, `(a, v1, b)` state 2, `(b, v2, c)` state 3
    /// (`C` then `0`), `(a, b, c)` state 0; codes `3`, child 3 `0`, child 2 `C 0`, child 1 `8`,
    /// child 0 `4`: `480C03`. With corners `(v0, v2, v1)`: a' = m(v2, v0) = c, b' = b,
    /// c' = m(v0, v1) = a, children `(v0, c, a)` (old 0), `(c, v2, b)` (old 2), `(b, v1, a)`
    /// (old 1), `(c, b, a)` (old 3): codes `3 0 8 C 0 4`, `40C803`.
    #[test]
    fn a_quartered_triangle_swaps_two_corner_children() {
        assert_eq!(reorder("480C03", FLIP).as_deref(), Some("40C803"));
    }

    /// Two sides split with special side 1: `w = (v1, v2, v0)`, `m1 = m(v2, v1)`,
    /// `m2 = m(v1, v0)`; children `T0 = (v1, m12, m01)` state 1, `T1 = (m12, v2, m01)` state 2,
    /// `T2 = (v2, v0, m01)` state 0; codes `2 | 1 << 2 = 6`, `0`, `8`, `4`: `4806`. With corners
    /// `(v0, v2, v1)` no two-side split gives these parts (its diagonal would run from v0 to m12),
    /// so: one side split with special side 1 (`w = (v2, v1, v0)`, halving side v1-v0 at m01):
    /// children `(v2, v1, m01)` = T0 + T1 and `(m01, v0, v2)` = T2: code 5, then child 1 (T2,
    /// code 0), then child 0: `(v2, v1, m01)` split on one side with special side 2
    /// (`w = (m01, v2, v1)`, halving v2-v1 at m12): children `(m01, v2, m12)` = T1 and
    /// `(m12, v1, m01)` = T0: code `1 | 2 << 2 = 9`, child 1 (T0, `4`), child 0 (T1, `8`).
    /// Codes `5 0 9 4 8`, written backwards `84905`.
    #[test]
    fn a_two_side_split_is_written_as_two_halvings_when_flipped() {
        assert_eq!(reorder("4806", FLIP).as_deref(), Some("84905"));
        assert_eq!(regions("4806", [0, 1, 2]), regions("84905", [0, 2, 1]));
    }

    /// Strings PrusaSlicer would not read as one tree are not re-encoded.
    #[test]
    fn what_is_not_a_tree_is_not_re_encoded() {
        for bad in ["48", "1", "4x", "4c", "F0C", "07", "0F3", "8881"] {
            assert_eq!(reorder(bad, FLIP), None, "{bad}");
        }
        assert_eq!(reorder("", FLIP).as_deref(), Some(""));
        assert_eq!(reorder("0C", FLIP).as_deref(), Some("0C"));
        assert_eq!(reorder(&"1".repeat(100_000), FLIP), None);
    }

    /// The painted regions of `value` read for a triangle with corners `corners` (as positions of
    /// a fixed triangle): per leaf, its three points (sorted) and its codes. Exact: midpoints of
    /// midpoints of integer points scaled by 2^20.
    fn regions(value: &str, corners: [usize; 3]) -> Vec<([[i64; 2]; 3], Vec<u8>)> {
        let p = [[0i64, 0], [1 << 20, 0], [0, 1 << 20]];
        let codes: Vec<u8> = value
            .bytes()
            .rev()
            .map(|b| (b as char).to_digit(16).unwrap() as u8)
            .collect();
        let mut at = 0;
        let tree = parse(&codes, &mut at, 0).unwrap();
        let mut out = Vec::new();
        fn walk(node: &Node, t: [[i64; 2]; 3], out: &mut Vec<([[i64; 2]; 3], Vec<u8>)>) {
            match node {
                Node::Leaf(codes) => {
                    let mut s = t;
                    s.sort_unstable();
                    out.push((s, codes.clone()));
                }
                Node::Split {
                    sides,
                    special,
                    children,
                } => {
                    // The same split on positions: ids 0..3 are the corners.
                    let mut points = Points::default();
                    let kids = split([0, 1, 2], *sides, *special, &mut points);
                    let mut at = |id: u32| -> [i64; 2] {
                        if id < 3 {
                            return t[id as usize];
                        }
                        let (&(a, b), _) = points.midpoints.iter().find(|(_, &v)| v == id).unwrap();
                        let (a, b) = (t[a as usize], t[b as usize]);
                        [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2]
                    };
                    for (child, kid) in children.iter().zip(kids) {
                        walk(child, kid.map(&mut at), out);
                    }
                }
            }
        }
        walk(&tree, corners.map(|k| p[k]), &mut out);
        out.sort();
        out
    }

    /// Random trees: flipping (or turning) re-encodes to the same regions with the same states,
    /// flipping twice gives the same regions again (the string back when no two-side split was
    /// rewritten), and the identity keeps the string.
    #[test]
    fn re_encoding_keeps_every_region_and_state() {
        use proptest::prelude::*;
        fn tree(seed: &mut u64, depth: usize, out: &mut Vec<u8>) {
            let mut next = || {
                *seed ^= *seed << 13;
                *seed ^= *seed >> 7;
                *seed ^= *seed << 17;
                *seed
            };
            let r = next();
            if depth >= 4 || r % 3 == 0 {
                match r % 5 {
                    0 => out.push(0),
                    1 => out.push(4),
                    2 => out.push(8),
                    _ => {
                        out.push(12);
                        out.push(((r >> 8) % 14) as u8);
                    }
                }
                return;
            }
            let sides = (r >> 4) % 3 + 1;
            let special = if sides == 3 { 0 } else { (r >> 6) % 3 };
            out.push((sides | special << 2) as u8);
            for _ in 0..=sides {
                tree(seed, depth + 1, out);
            }
        }
        proptest!(|(seed in 1u64..u64::MAX)| {
            let mut s = seed;
            let mut codes = Vec::new();
            tree(&mut s, 0, &mut codes);
            let value: String = codes
                .iter()
                .rev()
                .map(|&c| char::from(b"0123456789ABCDEF"[c as usize]))
                .collect();
            let flipped = reorder(&value, FLIP).unwrap();
            prop_assert_eq!(regions(&value, [0, 1, 2]), regions(&flipped, [0, 2, 1]));
            let back = reorder(&flipped, FLIP).unwrap();
            prop_assert_eq!(regions(&back, [0, 1, 2]), regions(&value, [0, 1, 2]));
            if !codes.iter().any(|&c| c & 3 == 2) {
                prop_assert_eq!(back, value.clone());
            }
            prop_assert_eq!(reorder(&value, [0, 1, 2]).unwrap(), value.clone());
            let turned = reorder(&value, [1, 2, 0]).unwrap();
            prop_assert_eq!(regions(&value, [0, 1, 2]), regions(&turned, [1, 2, 0]));
        });
    }
}
