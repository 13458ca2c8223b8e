//! The `dat` target's round trip, shared by the target (`fuzz_targets/dat.rs`) and its corpus
//! replay (`tests/fuzz_corpus.rs`), both of which compile it from this file. The including crate
//! root has the service's reader as `problem_file` (compiled from its source in the target, the
//! service crate's module in the replay).

use super::problem_file::{RawProblem, dat};
use std::collections::BTreeMap;

/// Largest problem (rows of W) written back: a dense W of `size²` numbers.
const ROUND_TRIP_SIZE: usize = 48;

/// W's non-zero entries, q and μ, as bits.
type Bits = (BTreeMap<(usize, usize), u64>, Vec<u64>, Vec<u64>);

fn bits(p: &RawProblem) -> Bits {
    let w =
        p.w.entries()
            .filter(|&(_, _, x)| x != 0.0)
            .map(|(i, j, x)| ((i, j), x.to_bits()))
            .collect();
    let of = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
    (w, of(&p.q), of(&p.mu))
}

/// A problem of at most [`ROUND_TRIP_SIZE`] rows, written in each storage (dense, sparse
/// block, CSparse), must read back to the same W, q and μ, to the bit (the writer prints every
/// number so that it parses to the same bits). Larger problems are not written.
pub fn round_trip(problem: &RawProblem) -> Result<(), String> {
    if problem.w.size() > ROUND_TRIP_SIZE {
        return Ok(());
    }
    let want = bits(problem);
    for storage in ["dense", "sparse_block", "csparse"] {
        let again = dat::parse(&dat::write(problem, storage))
            .map_err(|e| format!("written as {storage}, read back: {e}"))?;
        if again.dimension != problem.dimension || bits(&again) != want {
            return Err(format!("written as {storage}: another problem read back"));
        }
    }
    Ok(())
}
