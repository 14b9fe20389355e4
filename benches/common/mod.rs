//! What the benchmarks share beside `tests/shapes`: timing.

use std::time::Instant;

/// The best wall time of `runs` calls, in seconds, and the last call's result.
pub fn best<T>(runs: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut best = f64::INFINITY;
    let mut out = None;
    for _ in 0..runs {
        let start = Instant::now();
        out = Some(f());
        best = best.min(start.elapsed().as_secs_f64());
    }
    (best, out.expect("at least one run"))
}
