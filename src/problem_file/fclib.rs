//! FCLib's HDF5 layout (V. Acary, M. Brémond, T. Koziara, F. Pérignon, *FCLIB: a collection of
//! discrete 3D frictional contact problems*, INRIA technical report RT-444, 2014; the reader and
//! writer of `fclib.c`, github.com/FrictionalContactLibrary/fclib):
//!
//! ```text
//! /fclib_local/spacedim            2 or 3
//! /fclib_local/W/{m,n,nz,nzmax,p,i,x}   a sparse matrix: nz ≥ 0 triplet (p: columns, i: rows),
//!                                  nz = −1 CSC (p: n+1 column starts), nz = −2 CSR (p: m+1 row starts)
//! /fclib_local/vectors/{q,mu}
//! /fclib_global/{M,H}/…            the same sparse layout; /fclib_global/vectors/{f,w,mu}
//! /solution/{r,u}                  (and v for global problems)
//! ```
//!
//! A global problem `M v = H r + f`, `u = Hᵀ v + w` is read through its local reduction
//! `W = Hᵀ M⁻¹ H`, `q = Hᵀ M⁻¹ f + w` (Siconos' `globalFrictionContact_reformulation_FrictionContact`),
//! done here when M is diagonal (every global problem of Siconos' test set is): a non-diagonal
//! M is refused, naming it.

use super::{RawProblem, ReadError};
use hdf5_metno as hdf5;
use signorini_core::friction::BlockCsr;
use std::path::Path;

fn fclib_error(reason: impl Into<String>) -> ReadError {
    ReadError::Fclib {
        reason: reason.into(),
    }
}

fn read_vec<T: hdf5::H5Type>(file: &hdf5::File, path: &str) -> Result<Vec<T>, ReadError> {
    if !file.link_exists(path) {
        return Err(fclib_error(format!("{path} is missing")));
    }
    Ok(file.dataset(path)?.read_raw::<T>()?)
}

fn read_int(file: &hdf5::File, path: &str) -> Result<i64, ReadError> {
    read_vec::<i64>(file, path)?
        .first()
        .copied()
        .ok_or_else(|| fclib_error(format!("{path} is empty")))
}

/// A sparse matrix as entries `(row, column, value)` with its shape.
struct Sparse {
    rows: usize,
    columns: usize,
    entries: Vec<(usize, usize, f64)>,
}

fn read_matrix(file: &hdf5::File, group: &str) -> Result<Sparse, ReadError> {
    let count = |name: &str| -> Result<usize, ReadError> {
        let v = read_int(file, &format!("{group}/{name}"))?;
        usize::try_from(v).map_err(|_| fclib_error(format!("{group}/{name} is {v}")))
    };
    let (rows, columns) = (count("m")?, count("n")?);
    let nz = read_int(file, &format!("{group}/nz"))?;
    let p: Vec<i64> = read_vec(file, &format!("{group}/p"))?;
    let i: Vec<i64> = read_vec(file, &format!("{group}/i"))?;
    let x: Vec<f64> = read_vec(file, &format!("{group}/x"))?;
    let index = |v: i64, bound: usize, what: &str| {
        usize::try_from(v)
            .ok()
            .filter(|&k| k < bound)
            .ok_or_else(|| fclib_error(format!("{group}: {what} index {v} out of 0..{bound}")))
    };
    let mut entries = Vec::new();
    match nz {
        nz if nz >= 0 => {
            let nz = nz as usize;
            if p.len() < nz || i.len() < nz || x.len() < nz {
                return Err(fclib_error(format!(
                    "{group}: fewer than nz = {nz} triplets"
                )));
            }
            for k in 0..nz {
                entries.push((
                    index(i[k], rows, "row")?,
                    index(p[k], columns, "column")?,
                    x[k],
                ));
            }
        }
        -1 | -2 => {
            let (outer, inner) = if nz == -1 {
                (columns, rows)
            } else {
                (rows, columns)
            };
            if p.len() != outer + 1 {
                return Err(fclib_error(format!(
                    "{group}/p has {} entries, expected {}",
                    p.len(),
                    outer + 1
                )));
            }
            for o in 0..outer {
                let (a, b) = (p[o], p[o + 1]);
                if a < 0 || b < a || b as usize > i.len() || b as usize > x.len() {
                    return Err(fclib_error(format!("{group}/p is not increasing in range")));
                }
                for k in a as usize..b as usize {
                    let inner_index = index(i[k], inner, "inner")?;
                    entries.push(if nz == -1 {
                        (inner_index, o, x[k])
                    } else {
                        (o, inner_index, x[k])
                    });
                }
            }
        }
        other => return Err(fclib_error(format!("{group}/nz is {other}"))),
    }
    Ok(Sparse {
        rows,
        columns,
        entries,
    })
}

fn storage_name(file: &hdf5::File, group: &str) -> Result<&'static str, ReadError> {
    Ok(match read_int(file, &format!("{group}/nz"))? {
        -1 => "csc",
        -2 => "csr",
        _ => "triplet",
    })
}

/// Reads a local problem, or a global one through its local reduction (module documentation).
pub fn read(path: &Path) -> Result<RawProblem, ReadError> {
    let file = hdf5::File::open(path)?;
    if file.link_exists("fclib_local") {
        let dimension = read_int(&file, "fclib_local/spacedim")? as usize;
        let w = read_matrix(&file, "fclib_local/W")?;
        let q: Vec<f64> = read_vec(&file, "fclib_local/vectors/q")?;
        let mu: Vec<f64> = read_vec(&file, "fclib_local/vectors/mu")?;
        check_sizes(dimension, w.rows, w.columns, q.len(), mu.len())?;
        Ok(RawProblem {
            dimension,
            w: BlockCsr::from_triplets(dimension, w.rows, w.entries)?,
            q,
            mu,
            storage: storage_name(&file, "fclib_local/W")?,
        })
    } else if file.link_exists("fclib_global") {
        let dimension = read_int(&file, "fclib_global/spacedim")? as usize;
        let m = read_matrix(&file, "fclib_global/M")?;
        let h = read_matrix(&file, "fclib_global/H")?;
        let f: Vec<f64> = read_vec(&file, "fclib_global/vectors/f")?;
        let w: Vec<f64> = read_vec(&file, "fclib_global/vectors/w")?;
        let mu: Vec<f64> = read_vec(&file, "fclib_global/vectors/mu")?;
        let dofs = m.rows;
        if m.columns != dofs || h.rows != dofs || f.len() != dofs {
            return Err(fclib_error(format!(
                "M is {}×{}, H is {}×{} and f has {} entries: they do not make one global problem",
                m.rows,
                m.columns,
                h.rows,
                h.columns,
                f.len()
            )));
        }
        check_sizes(dimension, h.columns, h.columns, w.len(), mu.len())?;
        let mut diagonal = vec![0.0; dofs];
        for &(i, j, x) in &m.entries {
            if i != j && x != 0.0 {
                return Err(fclib_error(format!(
                    "M has the off-diagonal entry ({i}, {j}): the local reduction H^T M^-1 H is done for a diagonal M only"
                )));
            }
            diagonal[i] += x;
        }
        if let Some(k) = diagonal.iter().position(|&d| d.is_nan() || d <= 0.0) {
            return Err(fclib_error(format!(
                "M[{k}][{k}] = {} is not positive",
                diagonal[k]
            )));
        }
        // Rows of H: per dof the contacts' columns touching it.
        let mut by_dof: Vec<Vec<(usize, f64)>> = vec![Vec::new(); dofs];
        for &(i, j, x) in &h.entries {
            by_dof[i].push((j, x));
        }
        let mut entries = Vec::new();
        let mut q = w;
        for (k, row) in by_dof.iter().enumerate() {
            for &(a, xa) in row {
                q[a] += xa * f[k] / diagonal[k];
                for &(b, xb) in row {
                    entries.push((a, b, xa * xb / diagonal[k]));
                }
            }
        }
        Ok(RawProblem {
            dimension,
            w: BlockCsr::from_triplets(dimension, h.columns, entries)?,
            q,
            mu,
            storage: "global",
        })
    } else {
        Err(fclib_error("neither /fclib_local nor /fclib_global"))
    }
}

fn check_sizes(
    dimension: usize,
    rows: usize,
    columns: usize,
    q: usize,
    mu: usize,
) -> Result<(), ReadError> {
    if !(dimension == 2 || dimension == 3) {
        return Err(ReadError::Dimension { dimension });
    }
    let size = dimension * mu;
    if rows != size || columns != size || q != size {
        return Err(fclib_error(format!(
            "W is {rows}×{columns} and q has {q} entries, where {mu} contacts in dimension {dimension} need {size}"
        )));
    }
    Ok(())
}

/// Writes a local problem (W as CSR) to a new file.
pub fn write_local(path: &Path, problem: &RawProblem) -> Result<(), ReadError> {
    let file = hdf5::File::create(path)?;
    let local = file.create_group("fclib_local")?;
    write_slice(&local, "spacedim", &[problem.dimension as i32])?;
    let w = local.create_group("W")?;
    let size = problem.w.size();
    let mut entries: Vec<(usize, usize, f64)> = problem.w.entries().collect();
    // CSR: row by row (the block rows interleave the rows of their blocks).
    entries.sort_by_key(|&(i, j, _)| (i, j));
    let mut starts = vec![0i32];
    let mut columns = Vec::with_capacity(entries.len());
    let mut values = Vec::with_capacity(entries.len());
    let mut row = 0;
    for &(i, j, x) in &entries {
        while row < i {
            starts.push(columns.len() as i32);
            row += 1;
        }
        columns.push(j as i32);
        values.push(x);
    }
    while starts.len() < size + 1 {
        starts.push(columns.len() as i32);
    }
    let nnz = values.len() as i32;
    write_slice(&w, "m", &[size as i32])?;
    write_slice(&w, "n", &[size as i32])?;
    write_slice(&w, "nz", &[-2])?;
    write_slice(&w, "nzmax", &[nnz])?;
    write_slice(&w, "p", &starts)?;
    write_slice(&w, "i", &columns)?;
    write_slice(&w, "x", &values)?;
    let vectors = local.create_group("vectors")?;
    write_slice(&vectors, "q", &problem.q)?;
    write_slice(&vectors, "mu", &problem.mu)?;
    Ok(())
}

/// Writes a global problem with a diagonal M (its diagonal given) and H (dofs × dimension·contacts
/// entries) to a new file, H as triplets.
pub fn write_global(
    path: &Path,
    dimension: usize,
    mass: &[f64],
    h: &[(usize, usize, f64)],
    f: &[f64],
    w: &[f64],
    mu: &[f64],
) -> Result<(), ReadError> {
    let file = hdf5::File::create(path)?;
    let global = file.create_group("fclib_global")?;
    write_slice(&global, "spacedim", &[dimension as i32])?;
    let triplets = |name: &str, rows: usize, columns: usize, e: &[(usize, usize, f64)]| {
        let g = global.create_group(name)?;
        let n = e.len() as i32;
        write_slice(&g, "m", &[rows as i32])?;
        write_slice(&g, "n", &[columns as i32])?;
        write_slice(&g, "nz", &[n])?;
        write_slice(&g, "nzmax", &[n])?;
        let rows: Vec<i32> = e.iter().map(|t| t.0 as i32).collect();
        let cols: Vec<i32> = e.iter().map(|t| t.1 as i32).collect();
        let x: Vec<f64> = e.iter().map(|t| t.2).collect();
        write_slice(&g, "i", &rows)?;
        write_slice(&g, "p", &cols)?;
        write_slice(&g, "x", &x)
    };
    let diagonal: Vec<(usize, usize, f64)> =
        mass.iter().enumerate().map(|(k, &m)| (k, k, m)).collect();
    triplets("M", mass.len(), mass.len(), &diagonal)?;
    triplets("H", mass.len(), w.len(), h)?;
    let vectors = global.create_group("vectors")?;
    write_slice(&vectors, "f", f)?;
    write_slice(&vectors, "w", w)?;
    write_slice(&vectors, "mu", mu)?;
    Ok(())
}

fn write_slice<T: hdf5::H5Type>(
    group: &hdf5::Group,
    name: &str,
    data: &[T],
) -> Result<(), ReadError> {
    group
        .new_dataset::<T>()
        .shape(data.len())
        .create(name)?
        .write_raw(data)?;
    Ok(())
}

/// Writes FCLib's `/solution` (r, u; planar problems in their own `(n, t)` layout) into a copy
/// of nothing: a new file holding the problem and its solution.
pub fn write_solution(
    path: &Path,
    problem: &RawProblem,
    r: &[f64],
    u: &[f64],
) -> Result<(), ReadError> {
    write_local(path, problem)?;
    let file = hdf5::File::open_rw(path)?;
    let solution = file.create_group("solution")?;
    write_slice(&solution, "r", r)?;
    write_slice(&solution, "u", u)?;
    Ok(())
}

/// Reads `/solution/{r,u}` of a file.
pub fn read_solution(path: &Path) -> Result<(Vec<f64>, Vec<f64>), ReadError> {
    let file = hdf5::File::open(path)?;
    Ok((
        read_vec(&file, "solution/r")?,
        read_vec(&file, "solution/u")?,
    ))
}
