//! The `fclib` target's input: the datasets of an FCLib file (`Datasets`, the service's
//! `src/problem_file/fclib_layout.rs`) decoded from the fuzzer's bytes, and the check made of
//! them. Shared by the target (`fuzz_targets/fclib.rs`) and its corpus replay
//! (`tests/fuzz_corpus.rs`), both of which compile it from this file; the including crate root
//! has the service's reader as `problem_file`.
//!
//! The HDF5 container is not fuzzed here: it is parsed by the HDF5 C library, which is not
//! instrumented and not this project's code. What is fuzzed is everything this project does
//! with the arrays a file holds: every count, index, storage code and value, however
//! inconsistent. The replay also writes each decoded input to a real HDF5 file and reads it
//! back through the library (`tests/fuzz_corpus.rs`).
//!
//! The encoding, read front to back (missing bytes read as zero):
//! - one byte: even, a local problem (spacedim, W, q, μ); odd, a global one (spacedim, M, H,
//!   f, w, μ);
//! - an integer: one byte `b` < 255 is `b − 2` (so −2, −1 and small counts are one byte); 255
//!   is followed by 8 bytes, a little-endian i64;
//! - a float: one byte `b` < 252 is `(b − 100)/4`; 252, 253, 254 are −∞, +∞, NaN; 255 is
//!   followed by 8 bytes, a little-endian f64;
//! - an array: its length (2 bytes, little-endian, at most what is left), then its elements;
//! - a sparse matrix: m, n, nz (integers), p, i (integer arrays), x (a float array).

use super::problem_file::RawProblem;
use super::problem_file::fclib_layout::{Datasets, SparseDatasets};

struct Reader<'a> {
    data: &'a [u8],
}

impl Reader<'_> {
    fn byte(&mut self) -> u8 {
        let (&b, rest) = self.data.split_first().unwrap_or((&0, &[]));
        self.data = rest;
        b
    }

    fn eight(&mut self) -> [u8; 8] {
        let mut bytes = [0; 8];
        for b in &mut bytes {
            *b = self.byte();
        }
        bytes
    }

    fn int(&mut self) -> i64 {
        match self.byte() {
            255 => i64::from_le_bytes(self.eight()),
            b => i64::from(b) - 2,
        }
    }

    fn float(&mut self) -> f64 {
        match self.byte() {
            252 => f64::NEG_INFINITY,
            253 => f64::INFINITY,
            254 => f64::NAN,
            255 => f64::from_le_bytes(self.eight()),
            b => (f64::from(b) - 100.0) / 4.0,
        }
    }

    fn len(&mut self) -> usize {
        let n = usize::from(u16::from_le_bytes([self.byte(), self.byte()]));
        n.min(self.data.len())
    }

    fn ints(&mut self) -> Vec<i64> {
        let n = self.len();
        (0..n).map(|_| self.int()).collect()
    }

    fn floats(&mut self) -> Vec<f64> {
        let n = self.len();
        (0..n).map(|_| self.float()).collect()
    }

    fn sparse(&mut self) -> SparseDatasets {
        SparseDatasets {
            m: self.int(),
            n: self.int(),
            nz: self.int(),
            p: self.ints(),
            i: self.ints(),
            x: self.floats(),
        }
    }
}

/// The datasets the bytes encode (module documentation).
pub fn decode(data: &[u8]) -> Datasets {
    let mut r = Reader { data };
    if r.byte().is_multiple_of(2) {
        Datasets::Local {
            spacedim: r.int(),
            w: r.sparse(),
            q: r.floats(),
            mu: r.floats(),
        }
    } else {
        Datasets::Global {
            spacedim: r.int(),
            m: r.sparse(),
            h: r.sparse(),
            f: r.floats(),
            w: r.floats(),
            mu: r.floats(),
        }
    }
}

/// The bytes that decode to `datasets` (the corpus' seeds are FCLib files encoded so), or
/// `None` when an array is longer than the encoding's 65 535 elements.
pub fn encode(datasets: &Datasets) -> Option<Vec<u8>> {
    fn int(out: &mut Vec<u8>, v: i64) {
        match v.checked_add(2).and_then(|b| u8::try_from(b).ok()) {
            Some(b) if b < 255 => out.push(b),
            _ => {
                out.push(255);
                out.extend(v.to_le_bytes());
            }
        }
    }
    fn float(out: &mut Vec<u8>, x: f64) {
        let b = 4.0 * x + 100.0;
        if x.is_nan() {
            out.push(254);
        } else if x.is_infinite() {
            out.push(if x < 0.0 { 252 } else { 253 });
        } else if b.fract() == 0.0
            && (0.0..252.0).contains(&b)
            && ((b - 100.0) / 4.0).to_bits() == x.to_bits()
        {
            out.push(b as u8);
        } else {
            out.push(255);
            out.extend(x.to_le_bytes());
        }
    }
    fn array<T: Copy>(out: &mut Vec<u8>, v: &[T], put: fn(&mut Vec<u8>, T)) -> Option<()> {
        out.extend(u16::try_from(v.len()).ok()?.to_le_bytes());
        v.iter().for_each(|&x| put(out, x));
        Some(())
    }
    fn sparse(out: &mut Vec<u8>, a: &SparseDatasets) -> Option<()> {
        [a.m, a.n, a.nz].into_iter().for_each(|v| int(out, v));
        array(out, &a.p, int)?;
        array(out, &a.i, int)?;
        array(out, &a.x, float)
    }
    let mut out = Vec::new();
    match datasets {
        Datasets::Local { spacedim, w, q, mu } => {
            out.push(0);
            int(&mut out, *spacedim);
            sparse(&mut out, w)?;
            array(&mut out, q, float)?;
            array(&mut out, mu, float)?;
        }
        Datasets::Global {
            spacedim,
            m,
            h,
            f,
            w,
            mu,
        } => {
            out.push(1);
            int(&mut out, *spacedim);
            sparse(&mut out, m)?;
            sparse(&mut out, h)?;
            array(&mut out, f, float)?;
            array(&mut out, w, float)?;
            array(&mut out, mu, float)?;
        }
    }
    Some(out)
}

/// W's non-zero entries, q and μ, as bits.
type Bits = (Vec<(usize, usize, u64)>, Vec<u64>, Vec<u64>);

fn bits(p: &RawProblem) -> Bits {
    let w =
        p.w.entries()
            .filter(|&(_, _, x)| x != 0.0)
            .map(|(i, j, x)| (i, j, x.to_bits()))
            .collect();
    let of = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect();
    (w, of(&p.q), of(&p.mu))
}

/// The datasets are read into a problem or refused with a reason, never a panic; a problem
/// read is handed to the core (`to_fc3d`), and stored again as FCLib's writer stores it (W as
/// CSR, [`Datasets::local`]) it reads back to the same W, q and μ, to the bit.
pub fn check(datasets: &Datasets) -> Result<(), String> {
    let Ok(problem) = datasets.assemble() else {
        return Ok(());
    };
    let _ = problem.to_fc3d();
    let again = Datasets::local(&problem)
        .assemble()
        .map_err(|e| format!("stored as CSR, read back: {e}"))?;
    if again.dimension != problem.dimension || bits(&again) != bits(&problem) {
        return Err("stored as CSR: another problem read back".into());
    }
    Ok(())
}
