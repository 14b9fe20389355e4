//! Union-find over `u32` ids, shared by the analysis (patches, holes), the flat regions of the
//! search, the places a picture marks and the repair planner. A set's root is always its lowest
//! member, so numbering sets by root numbers them in order of first appearance.

/// Union-find over `u32` ids (path halving): the root of `x`'s set.
pub(crate) fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let up = parent[parent[x as usize] as usize];
        parent[x as usize] = up;
        x = up;
    }
    x
}

/// Joins two sets, keeping the smaller root (so roots stay the lowest member).
pub(crate) fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    if ra != rb {
        parent[ra.max(rb) as usize] = ra.min(rb);
    }
}
