//! Readers and writers of one-step friction problem files (docs/friction_benchmark.md): Siconos' text `.dat`
//! files ([`dat`]) and FCLib's HDF5 files ([`fclib`], the layout of their datasets in
//! [`fclib_layout`]). The core takes the parsed problem
//! ([`RawProblem::to_fc3d`]); it never sees a file.

pub mod dat;
#[cfg(feature = "hdf5")]
pub mod fclib;
pub mod fclib_layout;

use signorini_core::friction::{BlockCsr, BlockCsrError, Fc3dError, Fc3dProblem};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// A local friction problem as read from a file: W (d×d blocks), q, μ.
#[derive(Debug, Clone, PartialEq)]
pub struct RawProblem {
    /// 2 (planar contacts `(n, t)`) or 3 (`(n, t1, t2)`).
    pub dimension: usize,
    /// The Delassus operator.
    pub w: BlockCsr,
    /// The free local velocity.
    pub q: Vec<f64>,
    /// Friction coefficient per contact.
    pub mu: Vec<f64>,
    /// How W was stored in the file: `dense`, `sparse_block`, `csparse`, or FCLib's `csr`,
    /// `csc`, `triplet`.
    pub storage: &'static str,
}

impl RawProblem {
    /// Contacts.
    pub fn contacts(&self) -> usize {
        self.mu.len()
    }

    /// The problem for the core's FC3D solvers (planar problems embedded exactly:
    /// [`Fc3dProblem::from_planar`]).
    pub fn to_fc3d(&self) -> Result<Fc3dProblem, Fc3dError> {
        if self.dimension == 2 {
            Fc3dProblem::from_planar(&self.w, &self.q, &self.mu)
        } else {
            Ok(Fc3dProblem {
                w: self.w.clone(),
                q: self.q.clone(),
                mu: self.mu.clone(),
            })
        }
    }
}

/// What is wrong with a problem file.
#[derive(Debug, Error)]
pub enum ReadError {
    /// The file could not be read.
    #[error("cannot read it: {0}")]
    Io(#[from] std::io::Error),
    /// The text ended early.
    #[error("it ends before {what}")]
    UnexpectedEnd {
        /// What was expected.
        what: &'static str,
    },
    /// A token is not the number expected.
    #[error("{what} should be a number, found {token:?}")]
    NotANumber {
        /// What was expected.
        what: &'static str,
        /// The token found.
        token: String,
    },
    /// The dimension is not 2 or 3.
    #[error("the dimension is {dimension}: only 2 and 3 are friction problems")]
    Dimension {
        /// The dimension read.
        dimension: usize,
    },
    /// More contacts than any problem can hold (dimension × contacts overflows).
    #[error("{contacts} contacts: dimension × contacts is beyond any problem")]
    Contacts {
        /// The number of contacts read.
        contacts: usize,
    },
    /// W is not (dimension × contacts) square.
    #[error(
        "W is {rows}×{columns} where dimension × contacts = {size} (a global problem, or a damaged file?)"
    )]
    MatrixSize {
        /// Rows read.
        rows: usize,
        /// Columns read.
        columns: usize,
        /// Expected size.
        size: usize,
    },
    /// Unknown NumericsMatrix storage.
    #[error("unknown storage {storage} of W (0 dense, 1 sparse block, 2 sparse)")]
    Storage {
        /// Storage read.
        storage: usize,
    },
    /// The sparse-block structure is inconsistent.
    #[error("the sparse-block structure of W is inconsistent: {reason}")]
    BlockStructure {
        /// What is inconsistent.
        reason: String,
    },
    /// A line of CSparse's print could not be read.
    #[error("cannot read the CSparse line {line:?}")]
    CsparseLine {
        /// The line.
        line: String,
    },
    /// W's entries do not make a matrix.
    #[error("W: {0}")]
    Matrix(#[from] BlockCsrError),
    /// The HDF5 file does not hold what FCLib's layout says.
    #[error("FCLib layout: {reason}")]
    Fclib {
        /// What is missing or wrong.
        reason: String,
    },
    /// The HDF5 library failed.
    #[cfg(feature = "hdf5")]
    #[error("HDF5: {0}")]
    Hdf5(#[from] hdf5_metno::Error),
    /// An HDF5 file, and this binary was built without HDF5 (the cargo feature `hdf5`, which
    /// links the system libhdf5).
    #[cfg(not(feature = "hdf5"))]
    #[error(
        "an HDF5 (FCLib) file: this signorini was built without HDF5; rebuild with \
         `cargo build --release --features hdf5` (needs the system libhdf5, Debian: libhdf5-dev)"
    )]
    Hdf5NotBuilt,
}

/// A problem file that could not be read: the file and the reason.
#[derive(Debug, Error)]
#[error("{}: {reason}", file.display())]
pub struct ProblemFileError {
    /// The file.
    pub file: PathBuf,
    /// Why.
    pub reason: ReadError,
}

/// HDF5's signature, the first 8 bytes of every HDF5 file.
const HDF5_SIGNATURE: &[u8; 8] = b"\x89HDF\r\n\x1a\n";

/// Reads a problem file: FCLib HDF5 when it starts with HDF5's signature (whatever its name:
/// Siconos names some `.hdf5.dat` text files), Siconos' `.dat` text otherwise.
pub fn read(file: &Path) -> Result<RawProblem, ProblemFileError> {
    let fail = |reason| ProblemFileError {
        file: file.to_path_buf(),
        reason,
    };
    let bytes = std::fs::read(file).map_err(|e| fail(e.into()))?;
    if bytes.starts_with(HDF5_SIGNATURE) {
        #[cfg(feature = "hdf5")]
        return fclib::read(file).map_err(fail);
        #[cfg(not(feature = "hdf5"))]
        return Err(fail(ReadError::Hdf5NotBuilt));
    } else {
        let text = String::from_utf8_lossy(&bytes);
        dat::parse(&text).map_err(fail)
    }
}
