//! FCLib's HDF5 files: the datasets of [`super::fclib_layout`] read from a file and written to
//! one (the HDF5 library, through `hdf5-metno`). Integers are written as FCLib's `fclib.c`
//! writes them, 32-bit.

use super::fclib_layout::{Datasets, SparseDatasets};
use super::{RawProblem, ReadError};
use hdf5_metno as hdf5;
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

fn read_matrix(file: &hdf5::File, group: &str) -> Result<SparseDatasets, ReadError> {
    let path = |name: &str| format!("{group}/{name}");
    Ok(SparseDatasets {
        m: read_int(file, &path("m"))?,
        n: read_int(file, &path("n"))?,
        nz: read_int(file, &path("nz"))?,
        p: read_vec(file, &path("p"))?,
        i: read_vec(file, &path("i"))?,
        x: read_vec(file, &path("x"))?,
    })
}

/// The datasets of a file, as stored.
pub fn read_datasets(path: &Path) -> Result<Datasets, ReadError> {
    let file = hdf5::File::open(path)?;
    if file.link_exists("fclib_local") {
        Ok(Datasets::Local {
            spacedim: read_int(&file, "fclib_local/spacedim")?,
            w: read_matrix(&file, "fclib_local/W")?,
            q: read_vec(&file, "fclib_local/vectors/q")?,
            mu: read_vec(&file, "fclib_local/vectors/mu")?,
        })
    } else if file.link_exists("fclib_global") {
        Ok(Datasets::Global {
            spacedim: read_int(&file, "fclib_global/spacedim")?,
            m: read_matrix(&file, "fclib_global/M")?,
            h: read_matrix(&file, "fclib_global/H")?,
            f: read_vec(&file, "fclib_global/vectors/f")?,
            w: read_vec(&file, "fclib_global/vectors/w")?,
            mu: read_vec(&file, "fclib_global/vectors/mu")?,
        })
    } else {
        Err(fclib_error("neither /fclib_local nor /fclib_global"))
    }
}

/// Reads a local problem, or a global one through its local reduction
/// ([`Datasets::assemble`]).
pub fn read(path: &Path) -> Result<RawProblem, ReadError> {
    read_datasets(path)?.assemble()
}

/// FCLib's 32-bit integers (`H5T_NATIVE_INT` in `fclib.c`).
fn ints(path: &str, values: &[i64]) -> Result<Vec<i32>, ReadError> {
    values
        .iter()
        .map(|&v| {
            i32::try_from(v).map_err(|_| fclib_error(format!("{path}: {v} is beyond FCLib's int")))
        })
        .collect()
}

fn write_matrix(parent: &hdf5::Group, name: &str, a: &SparseDatasets) -> Result<(), ReadError> {
    let g = parent.create_group(name)?;
    let nnz = if a.nz >= 0 { a.nz } else { a.x.len() as i64 };
    for (field, values) in [
        ("m", &[a.m][..]),
        ("n", &[a.n]),
        ("nz", &[a.nz]),
        ("nzmax", &[nnz]),
    ] {
        write_slice(&g, field, &ints(&format!("{name}/{field}"), values)?)?;
    }
    write_slice(&g, "p", &ints(&format!("{name}/p"), &a.p)?)?;
    write_slice(&g, "i", &ints(&format!("{name}/i"), &a.i)?)?;
    write_slice(&g, "x", &a.x)
}

/// Writes the datasets to a new file.
pub fn write_datasets(path: &Path, datasets: &Datasets) -> Result<(), ReadError> {
    let file = hdf5::File::create(path)?;
    match datasets {
        Datasets::Local { spacedim, w, q, mu } => {
            let local = file.create_group("fclib_local")?;
            write_slice(&local, "spacedim", &ints("spacedim", &[*spacedim])?)?;
            write_matrix(&local, "W", w)?;
            let vectors = local.create_group("vectors")?;
            write_slice(&vectors, "q", q)?;
            write_slice(&vectors, "mu", mu)
        }
        Datasets::Global {
            spacedim,
            m,
            h,
            f,
            w,
            mu,
        } => {
            let global = file.create_group("fclib_global")?;
            write_slice(&global, "spacedim", &ints("spacedim", &[*spacedim])?)?;
            write_matrix(&global, "M", m)?;
            write_matrix(&global, "H", h)?;
            let vectors = global.create_group("vectors")?;
            write_slice(&vectors, "f", f)?;
            write_slice(&vectors, "w", w)?;
            write_slice(&vectors, "mu", mu)
        }
    }
}

/// Writes a local problem (W as CSR) to a new file.
pub fn write_local(path: &Path, problem: &RawProblem) -> Result<(), ReadError> {
    write_datasets(path, &Datasets::local(problem))
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
