//! How the build places objects: which mesh objects the build items reach, directly or through
//! chains of components, and how many placements of each mirror it.
//!
//! Objects are nodes, components edges. One iterative depth-first walk over every node (an explicit
//! stack, so a long chain cannot overflow the thread's stack) finds a cycle (an object that is,
//! through its components, part of itself) and chains deeper than [`MAX_DEPTH`]; its post-order,
//! reversed, lists every object before its components. Placements are then counted along that order,
//! not walked one path at a time: an object reached by `a` positive and `b` negative paths passes
//! them to each component, swapped when the component's transform mirrors. So a file whose
//! components fan out ten ways on each of ten levels costs a hundred steps, not ten billion. The
//! sign of a placement is the product of the signs of the transforms along its path (the
//! determinant of a product is the product of the determinants).

use super::super::ReadError;
use super::model::Sign;

/// The deepest chain of components a build may have (build item to mesh). Real assemblies nest a
/// handful of levels; a chain this deep is broken or hostile.
pub const MAX_DEPTH: usize = 64;

/// How many paths from the build reach an object, by the sign of their transform.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Placements {
    pub positive: u64,
    pub negative: u64,
    /// Flat placements (determinant zero): neither mirrored nor not.
    pub zero: u64,
}

impl Placements {
    pub fn total(&self) -> u64 {
        self.positive
            .saturating_add(self.negative)
            .saturating_add(self.zero)
    }

    fn add(&mut self, from: &Placements, sign: Sign) {
        let (p, n, z) = match sign {
            Sign::Positive => (from.positive, from.negative, from.zero),
            Sign::Negative => (from.negative, from.positive, from.zero),
            Sign::Zero => (0, 0, from.total()),
        };
        self.positive = self.positive.saturating_add(p);
        self.negative = self.negative.saturating_add(n);
        self.zero = self.zero.saturating_add(z);
    }
}

/// The placements of every node: `children[n]` are node `n`'s components (node and sign of the
/// transform), `items` the build items. `name(n)` names a node in messages. Refuses a cycle and a
/// chain deeper than [`MAX_DEPTH`].
pub fn place(
    children: &[Vec<(usize, Sign)>],
    items: &[(usize, Sign)],
    name: &dyn Fn(usize) -> String,
) -> Result<Vec<Placements>, ReadError> {
    const NEW: u8 = 0;
    const OPEN: u8 = 1;
    const DONE: u8 = 2;
    let n = children.len();
    let mut state = vec![NEW; n];
    let mut post = Vec::with_capacity(n);
    let mut stack: Vec<(usize, usize)> = Vec::new();
    for start in 0..n {
        if state[start] != NEW {
            continue;
        }
        state[start] = OPEN;
        stack.push((start, 0));
        while let Some(&mut (node, ref mut next)) = stack.last_mut() {
            let Some(&(child, _)) = children[node].get(*next) else {
                state[node] = DONE;
                post.push(node);
                stack.pop();
                continue;
            };
            *next += 1;
            match state[child] {
                NEW => {
                    if stack.len() >= MAX_DEPTH {
                        return Err(ReadError::new(format!(
                            "{} starts a chain of components more than {MAX_DEPTH} levels deep: meshvet refuses chains this deep (broken or hostile) - flatten the assembly",
                            name(start)
                        )));
                    }
                    state[child] = OPEN;
                    stack.push((child, 0));
                }
                OPEN => {
                    let from = stack.iter().position(|&(s, _)| s == child).unwrap_or(0);
                    let chain: Vec<String> = stack[from..]
                        .iter()
                        .map(|&(s, _)| name(s))
                        .chain(std::iter::once(name(child)))
                        .collect();
                    return Err(ReadError::new(format!(
                        "the components form a cycle ({}): an object cannot contain itself - fix the file",
                        chain.join(" -> ")
                    )));
                }
                _ => {}
            }
        }
    }
    // The walk's stack bounds the chains it went down; a chain first reached by a shorter path is
    // measured here: the longest chain below each object, components first.
    let mut longest = vec![1usize; n];
    for &node in &post {
        let below = children[node]
            .iter()
            .map(|&(c, _)| longest[c])
            .max()
            .unwrap_or(0);
        longest[node] = below + 1;
        if longest[node] > MAX_DEPTH {
            return Err(ReadError::new(format!(
                "{} starts a chain of components more than {MAX_DEPTH} levels deep: meshvet refuses chains this deep (broken or hostile) - flatten the assembly",
                name(node)
            )));
        }
    }
    let mut placements = vec![Placements::default(); n];
    let root = Placements {
        positive: 1,
        ..Placements::default()
    };
    for &(node, sign) in items {
        placements[node].add(&root, sign);
    }
    for &node in post.iter().rev() {
        let from = placements[node];
        if from.total() == 0 {
            continue;
        }
        for &(child, sign) in &children[node] {
            placements[child].add(&from, sign);
        }
    }
    Ok(placements)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn name(n: usize) -> String {
        format!("object {n}")
    }

    /// Build: 0 once. 0 has components 1 (mirrored) and 2; 1 has 2 twice (once mirrored). Paths to
    /// 2: 0-2 (+), 0-1-2 (- then +: -), 0-1-2 (- then -: +). So 2 has 2 positive, 1 negative.
    #[test]
    fn placements_multiply_signs_along_every_path() {
        let children = vec![
            vec![(1, Sign::Negative), (2, Sign::Positive)],
            vec![(2, Sign::Positive), (2, Sign::Negative)],
            vec![],
            vec![(2, Sign::Positive)], // not in the build: adds nothing
        ];
        let p = place(&children, &[(0, Sign::Positive)], &name).unwrap();
        assert_eq!(
            p[0],
            Placements {
                positive: 1,
                negative: 0,
                zero: 0
            }
        );
        assert_eq!(
            p[1],
            Placements {
                positive: 0,
                negative: 1,
                zero: 0
            }
        );
        assert_eq!(
            p[2],
            Placements {
                positive: 2,
                negative: 1,
                zero: 0
            }
        );
        assert_eq!(p[3].total(), 0);
        let flat = place(&children, &[(0, Sign::Zero)], &name).unwrap();
        assert_eq!(
            flat[2],
            Placements {
                positive: 0,
                negative: 0,
                zero: 3
            }
        );
    }

    /// Ten levels of ten components each: 10^10 paths to the bottom, counted without walking them.
    #[test]
    fn a_wide_deep_assembly_is_counted_not_walked() {
        let mut children: Vec<Vec<(usize, Sign)>> =
            (0..10).map(|l| vec![(l + 1, Sign::Positive); 10]).collect();
        children.push(Vec::new());
        let p = place(&children, &[(0, Sign::Positive)], &name).unwrap();
        assert_eq!(p[10].positive, 10_000_000_000);
    }

    #[test]
    fn cycles_and_deep_chains_are_refused() {
        let cycle = vec![
            vec![(1, Sign::Positive)],
            vec![(2, Sign::Positive)],
            vec![(1, Sign::Positive)],
        ];
        let e = place(&cycle, &[(0, Sign::Positive)], &name).unwrap_err();
        assert!(e.0.contains("object 1 -> object 2 -> object 1"), "{e}");
        let own = vec![vec![(0, Sign::Positive)]];
        assert!(place(&own, &[], &name).unwrap_err().0.contains("cycle"));

        let chain = |levels: usize| -> Vec<Vec<(usize, Sign)>> {
            let mut c: Vec<Vec<(usize, Sign)>> =
                (0..levels).map(|l| vec![(l + 1, Sign::Positive)]).collect();
            c.push(Vec::new());
            c
        };
        // MAX_DEPTH objects in a chain are fine; one more is refused. A chain of a million
        // objects is refused without overflowing the stack.
        assert!(place(&chain(MAX_DEPTH - 1), &[(0, Sign::Positive)], &name).is_ok());
        let e = place(&chain(MAX_DEPTH), &[(0, Sign::Positive)], &name).unwrap_err();
        assert!(e.0.contains("levels deep"), "{e}");
        assert!(place(&chain(1_000_000), &[], &name).is_err());
        // A deep chain first reached through a short way round is measured all the same: 0 has
        // component MAX_DEPTH - 1 (the chain's second-last object) and heads the chain too.
        let mut tricky = chain(MAX_DEPTH - 1);
        tricky[0].insert(0, (MAX_DEPTH - 1, Sign::Positive));
        assert!(place(&tricky, &[], &name).is_ok());
        let mut tricky = chain(MAX_DEPTH);
        tricky[0].insert(0, (MAX_DEPTH - 1, Sign::Positive));
        assert!(place(&tricky, &[], &name).is_err());
    }
}
